"""The 3D aortic valve sector (cases/valve-3d-sector.toml): a parametric aortic root and leaflet,
one sixth of the valve (half a leaflet between two symmetry planes).

Lengths in mm (the case's units: mm, g, s). The root's axis is z, the flow along +z. The sector
is 0 <= theta <= 60 degrees: the plane theta = 0 (y = 0) passes through a commissure and is the
plane where the half leaflet meets its neighbour (coaptation: a contact plane for the leaflet);
the plane theta = 60 degrees passes through the middle of the leaflet and of its sinus (a mirror
plane for fluid and leaflet alike).

Dimensions (the issue's; typical adult values: Swanson & Clark, Circ. Res. 35, 1974; Reul,
Vahlbruch, Giersiepen, Schmitz-Rode, Hirtz & Effert, J. Biomech. 23, 1990; Thubrikar, The Aortic
Valve, 1990, ch. 1):
  - annulus (the left-ventricular outflow tract, LVOT) radius R_A = 12.5 (diameter 25);
  - sinus of Valsalva: maximal radius R_S = 17.5 (diameter 35, 1.4 R_A; Reul et al.'s 1.46),
    reached half way up the sinus, in the middle of each lobe;
  - sino-tubular junction (STJ) radius R_STJ = 13.75 (1.1 R_A; Reul et al. 1.0-1.2), the
    ascending aorta beyond it of the same radius;
  - sinus height H_S = 20 from the annulus (z = 0) to the STJ (0.8 of the annulus diameter;
    Reul et al.'s sinus height 0.71-0.87 D_A), the commissures at H_C = 18 (0.9 H_S, just below
    the STJ: Thubrikar's commissure height);
  - leaflet thickness 0.5 (Thubrikar: 0.2-0.6 for the belly, thicker at the free edge; one value
    here).
The sinus wall is a lobe behind each leaflet: the radius r(theta, z) = base(z) + bulge(z)
sin^2(3 theta / 2), base the straight taper R_A -> R_STJ, bulge (R_S - (R_A + R_STJ) / 2)
sin^2(pi z / H_S); so r = R_S at the lobe's middle (theta = 60) half way up, and the wall runs
straight from annulus to STJ along the commissures (theta = 0), a simple stand-in for the
three-lobed (epitrochoid-like) sections of Haj-Ali, Marom, Ben Zekry, Rosenfeld & Raanani,
J. Biomech. 45, 2012. The LVOT (radius R_A) runs from the inlet z = -15 to the annulus, the
aorta (radius R_STJ) from the STJ to the outlet z = 50 (1.1 diameters).

The half leaflet (in its unloaded, half-open shape; see `leaflet_point`) is a ruled surface between
  - the attachment curve on the wall, from the commissure (theta = 3 deg, z = H_C) down to the
    nadir at the annulus (theta = 60, z = 0) along z = H_C (1 - sin(pi s / 2)), D_WALL = 0.5
    inside the wall (radially), and continued along the leaflet's rulings to E_WALL = 0.5
    beyond the wall (radially): a band, clamped at its outer face, that embeds the leaflet in
    the rigid root, so that its ventricular face crosses the fluid's faceted wall and gamma_f
    seals along the attachment;
  - the free edge, from 3 mm inside the wall at the commissure (theta = 3, z = H_C) to the
    middle of the leaflet at R_M = 3 from the axis (theta = 60, z = Z_M = 17.6), bowed towards
    the axis, and by BOW = 1 more and RISE = 3 up between its ends (sin^2: level at both), so
    that the leaflet can close: its free edge (12.0 long) reaches from the commissure along the
    plane theta = 0 to the axis (11.7); the leaflet's middle line, nadir to free edge, is 20 long
    (0.8 of the annulus diameter; 16, the 2D valve's leaflet, until session 35; 18 with R_M = 4
    and BOW = 2 until session 44, which left a hole at the axis: see BOW below), its highest
    point at rest z = 20.7, at the sino-tubular junction;
    the 3 degrees leave the commissure open at rest (the ventricular face 0.56 mm from the
    plane theta = 0 at the free edge's corner, 0.69 at the wall), so that the leaflet touches
    its neighbour (that plane) only when it closes;
and is 0.5 thick, towards the aorta from its ventricular face (gamma_s, and the contact
boundary). Q2 hexahedra (27 nodes): N_S = 12 along the attachment (graded towards the
commissure, S_GRADING), N_XI = 11 from the wall to the free edge (the first the band in the
wall; the others graded towards the hinge: in the leaflet's middle the first free one 0.6 mm,
the last 2.1 mm; a tenth of that at the commissure), one through the thickness.

Files:
  valve-3d-sector-fluid.msh: linear tetrahedra, size H_VALVE (default 2) for z in [-4, 24]
    where the leaflet moves and the jet forms, H_FAR (3.5) elsewhere. Physical groups: volume
    "fluid"; surfaces "inlet" (z = -15), "outlet" (z = 50), "wall", "commissure_plane"
    (theta = 0: y = 0), "leaflet_plane" (theta = 60).
  valve-3d-sector-leaflet.msh: 27-node hexahedra; physical groups: volume "leaflet"; surfaces
    "ventricular" (the face towards the ventricle: gamma_s and the contact boundary), "aortic",
    "attachment" (the outer face of the band in the wall: clamped), "free_edge", "commissure"
    (the leaflet's short side at the commissure) and "symmetry" (on the plane theta = 60).

Run: python make_valve_3d.py [H_VALVE H_FAR]   (needs the `gmsh` package from PyPI)
"""
import math
import sys

import gmsh

R_A, R_S, R_STJ = 12.5, 17.5, 13.75
H_S, H_C = 20.0, 18.0
Z_IN, Z_OUT = -15.0, 50.0
THICKNESS = 0.5
SECTOR = math.radians(60.0)
THETA_C = math.radians(3.0)
E_WALL = 0.5
D_WALL = 0.5
L_COMMISSURE = 3.0
R_M = 3.0
MIDLINE = 20.0
# Until session 35 the middle line was 16 and the free edge 10.3 long with neither BOW nor RISE:
# the leaflet closed on its plane from the commissure but could not reach the axis (a hole of
# about 4 mm radius stayed there, 20 ml/s of regurgitation at 83 mmHg): the way from the
# commissure corner along the plane to the axis was 13.0, and the rulings up to 0.8 short of it.
BOW, RISE = 1.0, 3.0
# Until session 44 R_M was 4, MIDLINE 18 and BOW 2: the leaflet closed on its plane but not at the
# centre. Under the diastolic load (80 mmHg) the hoop tension of its fibres kept the sheet straight
# across the corner between the plane and the mirror plane: the free edge's middle stopped at
# r = 1.05 mm and the face lay on the plane only from r = 1.47, and 10 ml/s leaked down the axis
# (runs/valve-3d-sector/NOTES.md). A solid-only closure under 80 mmHg (session 44's helper; the
# same leaflet there stopped at 0.96 and 1.32) showed that length alone does not close it (MIDLINE
# 22: 0.42 mm): bringing the free edge's middle nearer the axis at rest (R_M 3) and bowing the edge
# less (BOW 1, which also opens the leaflet wider at rest) does, with MIDLINE 20: the face 0.08 mm
# from the axis, 0.055 mm^2 left open at the centre (whole valve), the open area at rest 125.1
# mm^2 (127.4 before).
# MIRROR_BLEND: over the last MIRROR_BLEND of s, the thickness offset's component across the
# mirror plane is faded out (by w = (1 - (1 - s) / MIRROR_BLEND)^2), so that a leaflet meeting its
# mirror plane obliquely (R_M 3 with BOW 1 here) does not put its aortic face across the plane and
# turn the cells next to it inside out. The ventricular face is unchanged.
MIRROR_BLEND = 0.4
N_S, N_XI = 12, 11
XI_GRADING = 1.4
# The cells along s graded towards the commissure, s = u - S_GRADING u (1 - u) for the grid's u
# in [0, 1] (cells 0.7 times the even size there, 1.3 times at the mirror plane): the ventricular
# face twists fastest by the free edge's corner at the commissure, and with session 44's leaflet
# its facets there turned by 32 degrees from one to the next, above the adaptation's corner angle
# (30): a feature line no fluid edge chain could follow, and the run's step 8 failed.
S_GRADING = 0.3


def wall_radius(theta, z):
    """The root's radius at angle theta (radians, 0 at the commissure) and height z."""
    if z <= 0.0:
        return R_A
    if z >= H_S:
        return R_STJ
    s = z / H_S
    base = R_A + (R_STJ - R_A) * s
    bulge = (R_S - (R_A + R_STJ) / 2.0) * math.sin(math.pi * s) ** 2
    return base + bulge * math.sin(1.5 * theta) ** 2


def cylindrical(r, theta, z):
    return (r * math.cos(theta), r * math.sin(theta), z)


# ---------------------------------------------------------------------------------------------
# The fluid


def section_wire(occ, z, n_theta=13):
    """The closed wire of the sector at height z: axis -> wall at theta = 0 -> along the wall ->
    wall at theta = 60 -> axis."""
    o = occ.addPoint(0.0, 0.0, z)
    pts = [occ.addPoint(*cylindrical(wall_radius(t, z), t, z)) for t in (SECTOR * k / (n_theta - 1) for k in range(n_theta))]
    first = occ.addLine(o, pts[0])
    arc = occ.addSpline(pts)  # through the points (a B-spline would take them as its control points)
    last = occ.addLine(pts[-1], o)
    return occ.addWire([first, arc, last])


def fluid(h_valve, h_far, name):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("valve-3d-sector-fluid")
    occ = gmsh.model.occ
    # Three lofts: the LVOT and the aorta (two sections: cylinder sectors), the sinus (a section
    # every mm, the lobe a spline through 13 points of the wall).
    lvot = occ.addThruSections([section_wire(occ, Z_IN), section_wire(occ, 0.0)], makeSolid=True, makeRuled=True)
    sinus_z = [H_S * k / 20 for k in range(21)]
    sinus = occ.addThruSections([section_wire(occ, z) for z in sinus_z], makeSolid=True, makeRuled=False)
    aorta = occ.addThruSections([section_wire(occ, H_S), section_wire(occ, Z_OUT)], makeSolid=True, makeRuled=True)
    occ.fragment(lvot + sinus, aorta)
    occ.removeAllDuplicates()
    occ.synchronize()
    volumes = [t for (_, t) in gmsh.model.getEntities(3)]
    gmsh.model.addPhysicalGroup(3, volumes, 1, name="fluid")
    groups = {"inlet": [], "outlet": [], "wall": [], "commissure_plane": [], "leaflet_plane": []}
    n60 = (-math.sin(SECTOR), math.cos(SECTOR))
    for (_, tag) in gmsh.model.getEntities(2):
        if len(gmsh.model.getAdjacencies(2, tag)[0]) > 1:
            continue  # an interface between two of the lofts
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(2, tag)
        cx, cy, cz = gmsh.model.occ.getCenterOfMass(2, tag)
        if abs(z1 - z0) < 1e-6 and abs(z0 - Z_IN) < 1e-6:
            groups["inlet"].append(tag)
        elif abs(z1 - z0) < 1e-6 and abs(z0 - Z_OUT) < 1e-6:
            groups["outlet"].append(tag)
        elif abs(y1) < 1e-6 and abs(y0) < 1e-6:
            groups["commissure_plane"].append(tag)
        elif abs(n60[0] * cx + n60[1] * cy) < 1e-6:
            groups["leaflet_plane"].append(tag)
        else:
            groups["wall"].append(tag)
    for k, (group, tags) in enumerate(groups.items()):
        assert tags, f"no surface for {group}"
        gmsh.model.addPhysicalGroup(2, tags, 10 + k, name=group)
    field = gmsh.model.mesh.field
    box = field.add("Box")
    for key, value in [("VIn", h_valve), ("VOut", h_far), ("XMin", -1.0), ("XMax", R_S + 1.0), ("YMin", -1.0), ("YMax", R_S + 1.0),
                       ("ZMin", -4.0), ("ZMax", 24.0), ("Thickness", 6.0)]:
        field.setNumber(box, key, value)
    field.setAsBackgroundMesh(box)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.Algorithm3D", 10)  # HXT
    gmsh.option.setNumber("Mesh.Optimize", 1)
    gmsh.model.mesh.generate(3)
    snap_to_planes(groups, n60)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.write(name)
    n_tets = sum(len(t) for t in gmsh.model.mesh.getElementsByType(4)[0:1])
    gmsh.finalize()
    return n_tets


def snap_to_planes(groups, n60):
    """Puts the nodes of the two symmetry planes exactly on them (the loft's faces are planar to
    round-off; the solver checks planarity)."""
    for group, project in [("commissure_plane", lambda x, y: (x, 0.0)),
                           ("leaflet_plane", lambda x, y: (x - (n60[0] * x + n60[1] * y) * n60[0], y - (n60[0] * x + n60[1] * y) * n60[1]))]:
        for tag in groups[group]:
            nodes, coords, params = gmsh.model.mesh.getNodes(2, tag, includeBoundary=True)
            for k, node in enumerate(nodes):
                x, y, z = coords[3 * k:3 * k + 3]
                px, py = project(x, y)
                if (px, py) != (x, y):
                    gmsh.model.mesh.setNode(node, [px, py, z], [])


# ---------------------------------------------------------------------------------------------
# The leaflet


def attachment(s):
    """The attachment curve on the wall, s = 0 at the commissure, 1 at the nadir."""
    theta = THETA_C + (SECTOR - THETA_C) * s
    z = H_C * (1.0 - math.sin(0.5 * math.pi * s))
    return theta, z


def attachment_point(s):
    """The point of the attachment curve at s, D_WALL inside the wall (radially): the first
    vertices off the clamped band lie in the fluid's faceted wall."""
    theta, z = attachment(s)
    return cylindrical(wall_radius(theta, z) - D_WALL, theta, z)


def middle_tip_height():
    """Z_M: the free edge's middle at R_M from the axis, MIDLINE from the nadir (at the wall)."""
    return math.sqrt(MIDLINE**2 - (R_A - R_M) ** 2)


def free_edge(s):
    """The free edge: from L_COMMISSURE inside the wall at the commissure to R_M from the axis
    on the plane theta = 60, its height from H_C down to Z_M, bowed towards the axis (by BOW
    more between its ends) and raised by RISE between them."""
    theta = THETA_C + (SECTOR - THETA_C) * s
    r0 = wall_radius(THETA_C, H_C) - L_COMMISSURE
    between = math.sin(math.pi * s) ** 2
    r = r0 + (R_M - r0) * math.sin(0.5 * math.pi * s) - BOW * between
    z = H_C + (middle_tip_height() - H_C) * math.sin(0.5 * math.pi * s) + RISE * between
    return r, theta, z


def mid_surface(s, xi):
    """The leaflet's ventricular face at (s, xi): the ruled surface from the attachment (xi = 0,
    on the wall) to the free edge (xi = 1); xi < 0 continues into the wall."""
    a, f = attachment_point(s), cylindrical(*free_edge(s))
    return tuple(a[d] + xi * (f[d] - a[d]) for d in range(3))


def band_start(s):
    """The xi of the band's outer face: along the ruling from the attachment point (D_WALL inside
    the wall) until it lies E_WALL beyond the wall radially, wherever the ruling meets the wall
    at a slant (about 59 degrees from radial at the nadir)."""
    a, f = attachment_point(s), cylindrical(*free_edge(s))
    r_a, r_f = math.hypot(a[0], a[1]), math.hypot(f[0], f[1])
    # The radius falls by r_a - r_f from xi = 0 to 1; xi < 0 continues outwards.
    return -(D_WALL + E_WALL) / (r_a - r_f)


def unit_normal(s, xi, h=1e-6):
    """The unit normal of the ventricular face, towards the aorta (+theta, +z side)."""
    p = [mid_surface(s + h, xi), mid_surface(s - h, xi), mid_surface(s, xi + h), mid_surface(s, xi - h)]
    ds = [(p[0][d] - p[1][d]) / (2 * h) for d in range(3)]
    dxi = [(p[2][d] - p[3][d]) / (2 * h) for d in range(3)]
    n = [ds[1] * dxi[2] - ds[2] * dxi[1], ds[2] * dxi[0] - ds[0] * dxi[2], ds[0] * dxi[1] - ds[1] * dxi[0]]
    norm = math.sqrt(sum(c * c for c in n))
    # ds x dxi (s from the commissure to the middle, xi from the wall to the free edge) points
    # towards the aorta all over the leaflet (and up the axis all over this one: the same normals
    # as by orienting them up the axis, which near the free edge of a leaflet closer to closed
    # point down, and turn the cells through the thickness over there).
    return [c / norm for c in n]


def leaflet_point(i, j, k):
    """Node (i, j, k) of the Q2 grid: i along s (0..2 N_S), j along xi (0..2 N_XI: j <= 2 the
    band in the wall), k through the thickness (0..2)."""
    u = i / (2 * N_S)
    s = u - S_GRADING * u * (1.0 - u)
    if j <= 2:
        xi = band_start(s) * (1.0 - j / 2.0)
    else:
        # Cells graded towards the hinge, where the leaflet bends most as it opens: the cell
        # boundaries at (k / (N_XI - 1))^XI_GRADING, the mid-nodes half way between.
        cell, mid = divmod(j - 2, 2)
        b = lambda c: (c / (N_XI - 1)) ** XI_GRADING
        xi = b(cell) if mid == 0 else 0.5 * (b(cell) + b(cell + 1))
    x = mid_surface(s, xi)
    n = unit_normal(s, xi)
    if 1.0 - s < MIRROR_BLEND:
        w = (1.0 - (1.0 - s) / MIRROR_BLEND) ** 2
        m = (-math.sin(SECTOR), math.cos(SECTOR), 0.0)
        across = sum(n[d] * m[d] for d in range(3))
        n = [n[d] - w * across * m[d] for d in range(3)]
        norm = math.sqrt(sum(c * c for c in n))
        n = [c / norm for c in n]
    t = THICKNESS * k / 2.0
    p = [x[d] + t * n[d] for d in range(3)]
    if i == 2 * N_S:
        # On the mirror plane theta = 60 (to round-off already; exactly).
        m = (-math.sin(SECTOR), math.cos(SECTOR))
        off = m[0] * p[0] + m[1] * p[1]
        p[0], p[1] = p[0] - off * m[0], p[1] - off * m[1]
    return tuple(p)


# Gmsh's 27-node hexahedron: reference coordinates of its nodes in [-1, 1]^3 (the Gmsh manual,
# "Node ordering"), and its 9-node quadrilateral.
HEX27 = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1),
         (0, -1, -1), (-1, 0, -1), (-1, -1, 0), (1, 0, -1), (1, -1, 0), (0, 1, -1), (1, 1, 0), (-1, 1, 0),
         (0, -1, 1), (-1, 0, 1), (1, 0, 1), (0, 1, 1), (0, 0, -1), (0, -1, 0), (-1, 0, 0), (1, 0, 0), (0, 1, 0),
         (0, 0, 1), (0, 0, 0)]
QUAD9 = [(-1, -1), (1, -1), (1, 1), (-1, 1), (0, -1), (1, 0), (0, 1), (-1, 0), (0, 0)]


def write_leaflet_grid(model, cells_s, point, faces, name):
    """Writes a leaflet's grid of cells_s x N_XI x 1 Q2 cells, node (i, j, k) at point(i, j, k)
    (i along the free edge, j from the band to the free edge, k through the thickness from the
    ventricular face), as 27-node hexahedra with the physical surfaces faces(tag): (group, cells,
    node) triples, node(cell, a, b) the grid node at the cell's face coordinates (a, b) in
    [-1, 1]^2 and tag(i, j, k) a grid node's number."""
    ni, nj, nk = 2 * cells_s + 1, 2 * N_XI + 1, 3
    tag = lambda i, j, k: 1 + i + ni * (j + nj * k)
    coords = [c for k in range(nk) for j in range(nj) for i in range(ni) for c in point(i, j, k)]
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(model)
    volume = gmsh.model.addDiscreteEntity(3)
    gmsh.model.mesh.addNodes(3, volume, list(range(1, ni * nj * nk + 1)), coords)
    hexes = []
    for cj in range(N_XI):
        for ci in range(cells_s):
            for (a, b, c) in HEX27:
                hexes.append(tag(2 * ci + 1 + a, 2 * cj + 1 + b, 1 + c))
    gmsh.model.mesh.addElementsByType(volume, 12, [], hexes)
    gmsh.model.addPhysicalGroup(3, [volume], 1, name="leaflet")
    surfaces = []
    for group, cells, node in faces(tag):
        surface = gmsh.model.addDiscreteEntity(2)
        gmsh.model.mesh.addElementsByType(surface, 10, [], [node(cell, a, b) for cell in cells for (a, b) in QUAD9])
        surfaces.append((group, surface))
    for k, (group, surface) in enumerate(surfaces):
        gmsh.model.addPhysicalGroup(2, [surface], 10 + k, name=group)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(name)
    gmsh.finalize()


def leaflet_faces(tag, cells_s, ventricular_halves):
    """The faces of a leaflet grid of cells_s cells along the free edge: its ventricular face
    (whole, or in its two halves), aortic face, attachment (the band's outer face), free edge and
    the two short sides (i = 0 and i = 2 cells_s), as write_leaflet_grid takes them."""
    ni, nj = 2 * cells_s + 1, 2 * N_XI + 1
    across = lambda k: lambda c, a, b: tag(2 * c[0] + 1 + a, 2 * c[1] + 1 + b, k)
    side = lambda i: lambda c, a, b: tag(i, 2 * c + 1 + a, 1 + b)
    band = lambda j: lambda c, a, b: tag(2 * c + 1 + a, j, 1 + b)
    cells = lambda first, last: [(ci, cj) for cj in range(N_XI) for ci in range(first, last)]
    if ventricular_halves:
        ventricular = [("ventricular_a", cells(0, cells_s // 2), across(0)), ("ventricular_b", cells(cells_s // 2, cells_s), across(0))]
    else:
        ventricular = [("ventricular", cells(0, cells_s), across(0))]
    return ventricular + [
        ("aortic", cells(0, cells_s), across(2)),
        ("attachment", range(cells_s), band(0)),
        ("free_edge", range(cells_s), band(nj - 1)),
        ("commissure", range(N_XI), side(0)),
        ("symmetry" if not ventricular_halves else "commissure_end", range(N_XI), side(ni - 1)),
    ]


def leaflet(name):
    """The sector's half leaflet: from the commissure (i = 0) to the mirror plane theta = 60."""
    write_leaflet_grid("valve-3d-sector-leaflet", N_S, leaflet_point, lambda tag: leaflet_faces(tag, N_S, False), name)


# ---------------------------------------------------------------------------------------------
# The whole valve: the sector's meshes turned and mirrored


def sector_images():
    """The six maps of the sector onto the whole root: turns by 0, 120 and 240 degrees of the
    sector and of its mirror image in the plane theta = 60 (each a 3x3 matrix of (x, y); z
    kept), with whether it mirrors (and so turns cells inside out)."""
    maps = []
    for k in range(3):
        c, s = math.cos(2 * SECTOR * k), math.sin(2 * SECTOR * k)
        turn = ((c, -s), (s, c))
        # The mirror in the line at 60 degrees: (x, y) -> (cos 120 x + sin 120 y, sin 120 x - cos 120 y).
        c2, s2 = math.cos(2 * SECTOR), math.sin(2 * SECTOR)
        mirror = ((c2, s2), (s2, -c2))
        both = tuple(tuple(sum(turn[i][m] * mirror[m][j] for m in range(2)) for j in range(2)) for i in range(2))
        maps += [(turn, False), (both, True)]
    return maps


def apply(m, p):
    return (m[0][0] * p[0] + m[0][1] * p[1], m[1][0] * p[0] + m[1][1] * p[1], p[2])


class NodeSet:
    """Nodes merged where they coincide to 1e-9 mm (the sector's planes were snapped exactly, so
    a node on a plane and its image in the neighbouring sector agree to round-off)."""

    def __init__(self):
        self.coords, self.index = [], {}

    def add(self, p):
        key = tuple(round(c * 1e8) for c in p)
        for dk in ((a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)):
            near = tuple(k + d for k, d in zip(key, dk))
            if near in self.index and max(abs(a - b) for a, b in zip(self.coords[self.index[near] - 1], p)) < 1e-9:
                return self.index[near]
        self.coords.append(p)
        self.index[key] = len(self.coords)
        return self.index[key]


def full_fluid(sector_file, name):
    """The whole root's fluid mesh: the sector's tetrahedra and its inlet, outlet and wall
    triangles in six images; the symmetry planes become interior."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(sector_file)
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    point = {int(t): tuple(xyz[3 * k:3 * k + 3]) for k, t in enumerate(tags)}
    tets = [int(v) for (_, e) in gmsh.model.getEntities(3) for v in gmsh.model.mesh.getElementsByType(4, e)[1]]
    groups = {}
    for group in ("inlet", "outlet", "wall"):
        tag = [t for (d, t) in gmsh.model.getPhysicalGroups(2) if gmsh.model.getPhysicalName(2, t) == group][0]
        groups[group] = [int(v) for e in gmsh.model.getEntitiesForPhysicalGroup(2, tag) for v in gmsh.model.mesh.getElementsByType(2, e)[1]]
    gmsh.finalize()
    nodes = NodeSet()
    out_tets, out_tris = [], {g: [] for g in groups}
    for m, mirrored in sector_images():
        image = {t: nodes.add(apply(m, p)) for t, p in point.items()}
        for k in range(0, len(tets), 4):
            v = [image[t] for t in tets[k:k + 4]]
            out_tets += [v[1], v[0], v[2], v[3]] if mirrored else v
        for g, tris in groups.items():
            for k in range(0, len(tris), 3):
                v = [image[t] for t in tris[k:k + 3]]
                out_tris[g] += [v[1], v[0], v[2]] if mirrored else v
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("valve-3d-fluid")
    volume = gmsh.model.addDiscreteEntity(3)
    gmsh.model.mesh.addNodes(3, volume, list(range(1, len(nodes.coords) + 1)), [c for p in nodes.coords for c in p])
    gmsh.model.mesh.addElementsByType(volume, 4, [], out_tets)
    gmsh.model.addPhysicalGroup(3, [volume], 1, name="fluid")
    for k, (g, tris) in enumerate(out_tris.items()):
        surface = gmsh.model.addDiscreteEntity(2)
        gmsh.model.mesh.addElementsByType(surface, 2, [], tris)
        gmsh.model.addPhysicalGroup(2, [surface], 10 + k, name=g)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(name)
    gmsh.finalize()
    return len(out_tets) // 4


def full_leaflet(k, name):
    """Leaflet k (0, 1, 2) of the whole valve: the sector's half leaflet and its mirror image in
    the plane theta = 60, one grid of 2 N_S x N_XI cells from commissure to commissure, turned
    by 120 k degrees. Its faces are named as the half leaflet's, less `symmetry` (now inside):
    `commissure` and `commissure_end` at its two ends, and the ventricular face in two halves,
    `ventricular_a` from the commissure at 120 k degrees to the middle and `ventricular_b` on to
    the next (each half's contact plane is its own commissure's)."""
    turn, _ = sector_images()[2 * k]
    mirror, _ = sector_images()[1]

    def point(i, j, kk):
        p = leaflet_point(i, j, kk) if i <= 2 * N_S else apply(mirror, leaflet_point(4 * N_S - i, j, kk))
        return apply(turn, p)

    write_leaflet_grid(f"valve-3d-leaflet-{k + 1}", 2 * N_S, point, lambda tag: leaflet_faces(tag, 2 * N_S, True), name)


if __name__ == "__main__":
    h_valve, h_far = (float(sys.argv[1]), float(sys.argv[2])) if len(sys.argv) > 2 else (2.0, 3.5)
    n = fluid(h_valve, h_far, "valve-3d-sector-fluid.msh")
    leaflet("valve-3d-sector-leaflet.msh")
    print(f"valve-3d-sector-fluid.msh ({n} tetrahedra), valve-3d-sector-leaflet.msh written")
    n = full_fluid("valve-3d-sector-fluid.msh", "valve-3d-fluid.msh")
    for k in range(3):
        full_leaflet(k, f"valve-3d-leaflet-{k + 1}.msh")
    print(f"valve-3d-fluid.msh ({n} tetrahedra), valve-3d-leaflet-1.msh, -2.msh, -3.msh written")
