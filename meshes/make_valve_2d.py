"""The 2D aortic valve (cases/valve-2d.toml): the fluid mesh of a half model of the aortic root
and the left-ventricular pressure waveform.

Lengths in mm (the case's units: mm, g, s, so that pressures and stresses are in Pa).

valve-2d-fluid.msh: the half plane y >= 0 of a longitudinal section through the root, the flow
along +x, the symmetry line y = 0 (where the neighbouring leaflet's mirror image lies):
  - the left-ventricular outflow tract, radius 12.5 (the annulus radius of issue 19), from the
    inlet x = -15 to the annulus x = 2, where the leaflet hangs from the wall (its hinge from x = -0.12 to 0.82);
  - the sinus of Valsalva from x = 2 to x = 22, bulging to radius 17.5 near x = 12.3 (the
    sinus radius of issue 19), ending at the sino-tubular junction, radius 13.75 (issue 19);
  - the ascending aorta, radius 13.75, to the outlet x = 62 (40 mm, about 1.5 diameters).
First-order triangles: size H_VALVE (default 0.75) in the box [-14, 26] x [0, 17.5] where the
leaflet moves and the jet forms, H_FAR (1.5) elsewhere. Physical groups: surface "fluid"; curves
"inlet", "outlet", "wall", "symmetry".

valve-2d-lv-pressure.csv: the left-ventricular pressure over one beat of 0.8 s (75 beats per
minute), in mmHg, t = 0 at the opening of the aortic valve (the ventricle's pressure rising
through the aortic diastolic pressure, 80 mmHg). A monotone cubic (Fritsch-Carlson) through the
textbook values of the Wiggers diagram (e.g. Guyton & Hall, Textbook of Medical Physiology,
ch. 9; Klabunde, Cardiovascular Physiology Concepts, ch. 4): end-diastolic 10 mmHg, isovolumic
contraction to 80 mmHg in 0.05 s, systolic peak 120 mmHg 0.1 s after opening, 95 mmHg at the end
of ejection (0.27 s after opening), isovolumic relaxation to 8 mmHg in 0.08 s, filling at 4-7
mmHg and the atrial kick to 11 mmHg just before the next contraction.

Run: python make_valve_2d.py [H_VALVE H_FAR]   (needs the `gmsh` package from PyPI)
"""
import math
import sys

import gmsh

R_ANNULUS, R_SINUS, R_STJ = 12.5, 17.5, 13.75
X_INLET, X_SINUS, X_STJ, X_OUTLET = -15.0, 2.0, 22.0, 62.0


def sinus_radius(x):
    """The wall of the sinus: a linear taper from the annulus to the sino-tubular junction plus
    a sin^2 bulge, tangent to the straight walls at both ends, peaking at 17.5 near x = 12.3."""
    s = (x - X_SINUS) / (X_STJ - X_SINUS)
    base = R_ANNULUS + (R_STJ - R_ANNULUS) * s
    bulge = R_SINUS - (R_ANNULUS + R_STJ) / 2.0
    return base + bulge * math.sin(math.pi * s) ** 2


def fluid(h_valve, h_far, name):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("valve-2d-fluid")
    geo = gmsh.model.geo
    p_in0 = geo.addPoint(X_INLET, 0.0, 0.0)
    p_out0 = geo.addPoint(X_OUTLET, 0.0, 0.0)
    p_out1 = geo.addPoint(X_OUTLET, R_STJ, 0.0)
    p_stj = geo.addPoint(X_STJ, R_STJ, 0.0)
    n_sinus = 41
    # The sinus wall through 41 points, from the junction back to the annulus.
    xs = [X_STJ - (X_STJ - X_SINUS) * k / (n_sinus - 1) for k in range(n_sinus)]
    sinus = [p_stj] + [geo.addPoint(x, sinus_radius(x), 0.0) for x in xs[1:]]
    p_in1 = geo.addPoint(X_INLET, R_ANNULUS, 0.0)
    symmetry = geo.addLine(p_in0, p_out0)
    outlet = geo.addLine(p_out0, p_out1)
    aorta = geo.addLine(p_out1, p_stj)
    sinus_wall = geo.addSpline(sinus)
    lvot = geo.addLine(sinus[-1], p_in1)
    inlet = geo.addLine(p_in1, p_in0)
    loop = geo.addCurveLoop([symmetry, outlet, aorta, sinus_wall, lvot, inlet])
    surface = geo.addPlaneSurface([loop])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [surface], 1, name="fluid")
    for k, (group, tags) in enumerate([("inlet", [inlet]), ("outlet", [outlet]), ("wall", [aorta, sinus_wall, lvot]), ("symmetry", [symmetry])]):
        gmsh.model.addPhysicalGroup(1, tags, 10 + k, name=group)
    field = gmsh.model.mesh.field
    box = field.add("Box")
    for key, value in [("VIn", h_valve), ("VOut", h_far), ("XMin", -14.0), ("XMax", 26.0), ("YMin", 0.0), ("YMax", R_SINUS), ("Thickness", 6.0)]:
        field.setNumber(box, key, value)
    field.setAsBackgroundMesh(box)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(name)
    gmsh.finalize()


def pchip(xs, ys, x):
    """Monotone piecewise cubic Hermite interpolation (Fritsch & Carlson 1980)."""
    n = len(xs)
    h = [xs[k + 1] - xs[k] for k in range(n - 1)]
    delta = [(ys[k + 1] - ys[k]) / h[k] for k in range(n - 1)]
    m = [0.0] * n
    m[0], m[-1] = delta[0], delta[-1]
    for k in range(1, n - 1):
        if delta[k - 1] * delta[k] > 0:
            w1, w2 = 2 * h[k] + h[k - 1], h[k] + 2 * h[k - 1]
            m[k] = (w1 + w2) / (w1 / delta[k - 1] + w2 / delta[k])
    k = max(0, min(n - 2, max(i for i in range(n - 1) if xs[i] <= x)))
    t = (x - xs[k]) / h[k]
    h00, h10, h01, h11 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t, -2 * t**3 + 3 * t**2, t**3 - t**2
    return h00 * ys[k] + h10 * h[k] * m[k] + h01 * ys[k + 1] + h11 * h[k] * m[k + 1]


def lv_pressure(name, period=0.8, dt=0.005):
    # (time after the start of isovolumic contraction, mmHg); the valve opens at 0.05.
    knots = [
        (0.00, 10.0), (0.05, 80.0), (0.10, 110.0), (0.15, 120.0), (0.20, 117.0), (0.25, 108.0),
        (0.32, 95.0), (0.36, 45.0), (0.40, 8.0), (0.45, 4.0), (0.55, 5.0), (0.65, 6.0),
        (0.72, 7.0), (0.76, 11.0), (0.80, 10.0),
    ]
    xs, ys = [k[0] for k in knots], [k[1] for k in knots]
    opening = 0.05
    with open(name, "w") as f:
        f.write("t,lv_pressure_mmhg\n")
        for k in range(int(round(period / dt)) + 1):
            t = k * dt
            tau = (t + opening) % period if k < round(period / dt) else opening
            f.write(f"{t:.3f},{pchip(xs, ys, tau):.4f}\n")


if __name__ == "__main__":
    h_valve, h_far = (float(sys.argv[1]), float(sys.argv[2])) if len(sys.argv) > 2 else (0.75, 1.5)
    fluid(h_valve, h_far, "valve-2d-fluid.msh")
    lv_pressure("../cases/valve-2d-lv-pressure.csv")
    print("valve-2d-fluid.msh, ../cases/valve-2d-lv-pressure.csv written")
