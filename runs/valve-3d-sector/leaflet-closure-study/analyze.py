"""Measures a closed (or unloaded) valve-sector leaflet.

python3 analyze.py MESH.msh [RUN_DIR]   (RUN_DIR: the last solution_solid_*.vtu; without it the mesh at rest)

Prints: the ventricular face's smallest distance to the axis (current positions), the nodes on
y = 0 (contact plane, |y| < 1e-6) nearest the axis, the free edge's middle (node i = 2 N_S,
j = 2 N_XI, k = 0) radius and height, the area left open seen along the axis in the annulus
sector r < 12.5, 0 <= theta <= 60 (rasterised; x 6 for the whole valve), and with a run the
largest stresses (max principal Cauchy, von Mises) and fibre stretch, with where.
"""
import glob
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gmsh
import vtu

N_S, N_XI = int(os.environ.get("N_S", 12)), int(os.environ.get("N_XI", 11))
NI, NJ = 2 * N_S + 1, 2 * N_XI + 1
R_A = 12.5
SECTOR = math.radians(60.0)


def tag(i, j, k):
    return 1 + i + NI * (j + NJ * k)


def read_mesh(path):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(path)
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    pts = {int(t): tuple(xyz[3 * k:3 * k + 3]) for k, t in enumerate(tags)}
    gmsh.finalize()
    return pts


def eig_sym3(a):
    """Eigenvalues of a symmetric 3x3 (analytic)."""
    p1 = a[0][1] ** 2 + a[0][2] ** 2 + a[1][2] ** 2
    q = (a[0][0] + a[1][1] + a[2][2]) / 3
    if p1 < 1e-30:
        return sorted([a[0][0], a[1][1], a[2][2]])
    p2 = sum((a[i][i] - q) ** 2 for i in range(3)) + 2 * p1
    p = math.sqrt(p2 / 6)
    b = [[(a[i][j] - (q if i == j else 0)) / p for j in range(3)] for i in range(3)]
    det = (b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1]) - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
           + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]))
    r = max(-1.0, min(1.0, det / 2))
    phi = math.acos(r) / 3
    e1 = q + 2 * p * math.cos(phi)
    e3 = q + 2 * p * math.cos(phi + 2 * math.pi / 3)
    return sorted([e3, 3 * q - e1 - e3, e1])


def open_area(cur, h=0.01):
    """Area of the sector r < R_A, 0 <= theta <= 60 deg not covered by the ventricular face's
    projection along z (each Q2 face as 8 triangles through its 9 nodes)."""
    nx, ny = int(R_A / h) + 1, int(R_A * math.sin(SECTOR) / h) + 1
    covered = bytearray(nx * ny)
    tris = []
    for ci in range(N_S):
        for cj in range(N_XI):
            g = [[cur[tag(2 * ci + a, 2 * cj + b, 0)][:2] for b in range(3)] for a in range(3)]
            for a in range(2):
                for b in range(2):
                    p00, p10, p01, p11 = g[a][b], g[a + 1][b], g[a][b + 1], g[a + 1][b + 1]
                    tris += [(p00, p10, p11), (p00, p11, p01)]
    for (ax, ay), (bx, by), (cx, cy) in tris:
        d = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
        if abs(d) < 1e-14:
            continue
        i0, i1 = max(0, int(min(ax, bx, cx) / h)), min(nx - 1, int(max(ax, bx, cx) / h) + 1)
        j0, j1 = max(0, int(min(ay, by, cy) / h)), min(ny - 1, int(max(ay, by, cy) / h) + 1)
        for i in range(i0, i1 + 1):
            x = (i + 0.5) * h
            for j in range(j0, j1 + 1):
                y = (j + 0.5) * h
                l1 = ((bx - x) * (cy - y) - (cx - x) * (by - y)) / d
                l2 = ((cx - x) * (ay - y) - (ax - x) * (cy - y)) / d
                if l1 >= -1e-12 and l2 >= -1e-12 and 1 - l1 - l2 >= -1e-12:
                    covered[i * ny + j] = 1
    area, holes = 0.0, []
    for i in range(nx):
        x = (i + 0.5) * h
        for j in range(ny):
            y = (j + 0.5) * h
            if x * x + y * y < R_A * R_A and math.atan2(y, x) <= SECTOR and not covered[i * ny + j]:
                area += h * h
                holes.append(math.hypot(x, y))
    centre = sum(h * h for r in holes if r < 6.0)
    near = max([r for r in holes if r < 6.0], default=0.0)
    return area, centre, near


def main():
    report(*load(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else None))


def load(mesh, run=None):
    ref = read_mesh(mesh)
    cur, disp, extra = dict(ref), None, None
    if run:
        files = sorted(glob.glob(os.path.join(run, "solution_solid_*.vtu")))
        d = vtu.read(files[-1])
        pts, u = d["Points"], d["displacement"]
        assert len(pts) == len(ref)
        # the output's nodes matched to the mesh's by their reference positions
        key = lambda q: tuple(round(c * 1e6) for c in q)
        index = {key(q): t for t, q in ref.items()}
        cur = {}
        for n in range(len(pts)):
            x0 = tuple(pts[n][c] - u[n][c] for c in range(3))
            t = index.get(key(x0))
            if t is None:
                t = min(ref, key=lambda t: sum((ref[t][c] - x0[c]) ** 2 for c in range(3)))
                assert sum((ref[t][c] - x0[c]) ** 2 for c in range(3)) < 1e-12
            cur[t] = tuple(pts[n])
        assert len(cur) == len(ref)
        extra = d
    return ref, cur, extra


def report(ref, cur, extra):
    vent = [(i, j) for i in range(NI) for j in range(NJ)]
    rr = lambda p: math.hypot(p[0], p[1])
    i, j = min(vent, key=lambda ij: rr(cur[tag(*ij, 0)]))
    p = cur[tag(i, j, 0)]
    print(f"min r ventricular: {rr(p):.4f} at node i={i} j={j} (z={p[2]:.3f}, theta={math.degrees(math.atan2(p[1], p[0])):.2f})")
    on = [(i, j) for (i, j) in vent if abs(cur[tag(i, j, 0)][1]) < 1e-6]
    if on:
        i, j = min(on, key=lambda ij: rr(cur[tag(*ij, 0)]))
        p = cur[tag(i, j, 0)]
        print(f"on y=0: {len(on)} ventricular nodes; nearest the axis r={rr(p):.4f} at i={i} j={j} z={p[2]:.3f}")
        fe = [i for i in range(NI) if abs(cur[tag(i, NJ - 1, 0)][1]) < 1e-6]
        print(f"  free-edge nodes on y=0: i={fe}")
    else:
        print("on y=0: none")
    tip = cur[tag(NI - 1, NJ - 1, 0)]
    print(f"free edge middle (ventricular): r={rr(tip):.4f} z={tip[2]:.3f}")
    # free edge: radius along it
    fe = [cur[tag(i, NJ - 1, 0)] for i in range(NI)]
    print("free edge (r, theta deg, z) every 4th node: " + "; ".join(f"{rr(q):.2f},{math.degrees(math.atan2(q[1], q[0])):.1f},{q[2]:.2f}" for q in fe[::4]))
    area, centre, near = open_area(cur)
    print(f"open area along the axis: sector {area:.3f} mm^2, whole valve {6 * area:.3f} mm^2; of it within r < 6 (the centre): sector {centre:.4f}, whole {6 * centre:.3f} mm^2 (out to r={near:.3f}); by the commissure (r >= 6): whole {6 * (area - centre):.3f} mm^2")
    if extra:
        s = extra["cauchy_stress"]
        best = []
        for c, sig in enumerate(s):
            a = [[sig[3 * r + q] for q in range(3)] for r in range(3)]
            e = eig_sym3([[0.5 * (a[r][q] + a[q][r]) for q in range(3)] for r in range(3)])
            vm = math.sqrt(0.5 * ((e[0] - e[1]) ** 2 + (e[1] - e[2]) ** 2 + (e[2] - e[0]) ** 2))
            cj, ci = divmod(c, N_S)
            best.append((e[2], vm, ci, cj, extra["fibre_stretch"][c]))
        for label, pool in [("all cells", best), ("outside the band (cj >= 1)", [b for b in best if b[3] >= 1])]:
            m = max(pool, key=lambda b: b[0])
            v = max(pool, key=lambda b: b[1])
            f = max(pool, key=lambda b: b[4])
            print(f"  {label}: max principal {m[0] / 1e3:.0f} kPa at cell ci={m[2]} cj={m[3]}; von Mises {v[1] / 1e3:.0f} kPa at ci={v[2]} cj={v[3]}; fibre stretch {f[4]:.3f} at ci={f[2]} cj={f[3]}")
        cp = extra["contact_pressure"]
        print(f"  contact pressure max {max(cp) / 1e3:.0f} kPa; contact nodes {sum(1 for c in cp if c > 0)}")


if __name__ == "__main__":
    main()
