"""Gmsh meshes of the Turek-Hron FSI benchmark (Turek & Hron 2006).

The elastic bar: length 0.35 from x = 0.6 back to where it meets the rigid cylinder (centre
(0.2, 0.2), radius 0.05), height 0.02 (y from 0.19 to 0.21); its left end is the cylinder's
arc, where it is clamped. Point A = (0.6, 0.2), the middle of the tip, is a node of every mesh.

turek-hron-bar-N.msh: the bar in N x N/10 9-node quadrilaterals (structured, transfinite; the
clamped end curved on the arc). Physical groups: surface "bar"; curves "clamp" (the arc),
"bottom" (y = 0.19), "tip" (x = 0.6), "top" (y = 0.21).

turek-hron-cfd-N.msh: the CFD benchmarks' fluid, the channel [0, 2.5] x [0, 0.41] less the
cylinder and the bar (rigid), in second-order (curved) triangles: size h = 0.04 / 2^N in the
channel, h / 4 on the cylinder and the bar. Physical groups: surface "fluid"; curves "inlet"
(x = 0), "outlet" (x = 2.5), "walls" (y = 0 and 0.41), "obstacle" (the cylinder's free arc and
the bar's three sides: the drag and lift act on both).

turek-hron-fsi-N.msh: the FSI benchmarks' fluid mesh, the channel less the cylinder only: it
covers the bar, to which every step adapts it; the points where the bar's corners meet the
cylinder are vertices. Size h = 0.04 / 2^N in the channel, h / 4 on the
cylinder and in the box [0.24, 0.66] x [0.1, 0.3] that the bar sweeps (FSI2: the tip moves up to
0.09 from y = 0.2). Physical groups: surface "fluid"; curves "inlet", "outlet", "walls",
"cylinder". Level 2 (660 000 dofs) is written in first-order cells.

turek-hron-fsi-fitted-N.msh: the same, with the bar's outline at rest as lines of the mesh (the
fluid mesh still covers the bar: surfaces "fluid" on both sides of the outline). Where the bar
deflects little (FSI1) the adaptation then moves vertices instead of cutting cells; on the cut
meshes the bar's load depends on how the cells are cut (BENCHMARKS.md "Turek-Hron FSI1").

MSH 4.1 ASCII. Run: python make_turek_hron.py   (needs the `gmsh` package from PyPI)
"""
import math

import gmsh

XC, YC, R = 0.2, 0.2, 0.05
X_TIP, Y0, Y1 = 0.6, 0.19, 0.21
LEVELS = {"turek-hron-bar-40": 40, "turek-hron-bar-80": 80}
L, H = 2.5, 0.41
CFD_LEVELS = {"turek-hron-cfd-0": 0, "turek-hron-cfd-1": 1}
FSI_LEVELS = {"turek-hron-fsi-0": 0, "turek-hron-fsi-1": 1, "turek-hron-fsi-2": 2}
# Meshes written in first-order cells (fdfsi adapts the vertex mesh and builds its P2 nodes on the
# straight edges, so the run is the same to the bit; the file is a third of the size).
FIRST_ORDER = {"turek-hron-fsi-2"}
FITTED_LEVELS = {"turek-hron-fsi-fitted-0": 0, "turek-hron-fsi-fitted-1": 1}


def start(name):
    """A new Gmsh model `name`."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)


def finish(name):
    """Meshes the model in second-order cells (first-order for the names in FIRST_ORDER) and
    writes `name`.msh (MSH 4.1)."""
    gmsh.model.mesh.generate(2)
    if name not in FIRST_ORDER:
        gmsh.model.mesh.setOrder(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write(f"{name}.msh")
    gmsh.finalize()
    print(name, "written")


def channel_groups(obstacle):
    """Synchronises the OCC model and names its surfaces "fluid" and its boundary curves
    "inlet" (x = 0), "outlet" (x = L), "walls" (y = 0 and H) and `obstacle` (the rest); returns
    the curve tags of each group."""
    occ = gmsh.model.occ
    occ.synchronize()
    surfaces = gmsh.model.getEntities(2)
    gmsh.model.addPhysicalGroup(2, [s[1] for s in surfaces], 1, name="fluid")
    groups = {"inlet": [], "outlet": [], "walls": [], obstacle: []}
    for dim, tag in gmsh.model.getBoundary(surfaces, oriented=False):
        cx, cy, _ = occ.getCenterOfMass(dim, tag)
        if abs(cx) < 1e-9:
            groups["inlet"].append(tag)
        elif abs(cx - L) < 1e-9:
            groups["outlet"].append(tag)
        elif abs(cy) < 1e-9 or abs(cy - H) < 1e-9:
            groups["walls"].append(tag)
        else:
            groups[obstacle].append(tag)
    for k, (group, tags) in enumerate(groups.items(), start=2):
        gmsh.model.addPhysicalGroup(1, tags, k, name=group)
    return groups


def bar(name, n_long):
    """The bar in n_long x n_long / 10 quadrilaterals (n_long a multiple of 20, so that A is a
    vertex)."""
    n_thick = n_long // 10
    x_arc = XC + math.sqrt(R * R - (Y0 - YC) ** 2)
    start(name)
    geo = gmsh.model.geo
    c = geo.addPoint(XC, YC, 0)
    p1, p2 = geo.addPoint(x_arc, Y0, 0), geo.addPoint(X_TIP, Y0, 0)
    p3, p4 = geo.addPoint(X_TIP, Y1, 0), geo.addPoint(x_arc, Y1, 0)
    bottom, tip, top = geo.addLine(p1, p2), geo.addLine(p2, p3), geo.addLine(p3, p4)
    clamp = geo.addCircleArc(p4, c, p1)
    surface = geo.addPlaneSurface([geo.addCurveLoop([bottom, tip, top, clamp])])
    for curve, n in ((bottom, n_long), (top, n_long), (tip, n_thick), (clamp, n_thick)):
        geo.mesh.setTransfiniteCurve(curve, n + 1)
    geo.mesh.setTransfiniteSurface(surface, cornerTags=[p1, p2, p3, p4])
    geo.mesh.setRecombine(2, surface)
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [surface], 1, name="bar")
    for k, (group, curve) in enumerate((("clamp", clamp), ("bottom", bottom), ("tip", tip), ("top", top)), start=2):
        gmsh.model.addPhysicalGroup(1, [curve], k, name=group)
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 0)
    finish(name)


def cfd(name, level):
    """The channel less cylinder and bar, h = 0.04 / 2^level in the channel, h / 4 at the
    obstacle."""
    h = 0.04 / 2**level
    start(name)
    occ = gmsh.model.occ
    x_arc = XC + math.sqrt(R * R - (Y0 - YC) ** 2)
    channel = occ.addRectangle(0, 0, 0, L, H)
    obstacle, _ = occ.fuse([(2, occ.addDisk(XC, YC, 0, R, R))], [(2, occ.addRectangle(x_arc - 0.001, Y0, 0, X_TIP - x_arc + 0.001, Y1 - Y0))])
    occ.cut([(2, channel)], obstacle)
    groups = channel_groups("obstacle")
    dist = gmsh.model.mesh.field.add("Distance")
    gmsh.model.mesh.field.setNumbers(dist, "CurvesList", groups["obstacle"])
    gmsh.model.mesh.field.setNumber(dist, "Sampling", 200)
    thr = gmsh.model.mesh.field.add("Threshold")
    gmsh.model.mesh.field.setNumber(thr, "InField", dist)
    gmsh.model.mesh.field.setNumber(thr, "SizeMin", h / 4)
    gmsh.model.mesh.field.setNumber(thr, "SizeMax", h)
    gmsh.model.mesh.field.setNumber(thr, "DistMin", 0.01)
    gmsh.model.mesh.field.setNumber(thr, "DistMax", 0.3)
    gmsh.model.mesh.field.setAsBackgroundMesh(thr)
    for opt in ("Mesh.MeshSizeExtendFromBoundary", "Mesh.MeshSizeFromPoints", "Mesh.MeshSizeFromCurvature"):
        gmsh.option.setNumber(opt, 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    finish(name)


def fsi(name, level, fitted=False):
    """The channel less the cylinder, h = 0.04 / 2^level in the channel, h / 4 on the cylinder and
    where the bar moves; `fitted`: with the bar's outline at rest as mesh lines."""
    h = 0.04 / 2**level
    start(name)
    occ = gmsh.model.occ
    # The cylinder in two arcs, split where the bar's corners meet it: those points are then
    # vertices of the fluid mesh, and gamma_s (the bar's free sides) ends on the fluid boundary.
    a = math.asin((Y1 - YC) / R)
    arcs = [occ.addCircle(XC, YC, 0, R, angle1=-a, angle2=a), occ.addCircle(XC, YC, 0, R, angle1=a, angle2=2 * math.pi - a)]
    disk = occ.addPlaneSurface([occ.addCurveLoop(arcs)])
    channel, _ = occ.cut([(2, occ.addRectangle(0, 0, 0, L, H))], [(2, disk)])
    if fitted:
        # The bar's rectangle, started inside the cylinder, splits the channel; the piece inside
        # the cylinder is dropped.
        x_arc = XC + math.sqrt(R * R - (Y0 - YC) ** 2)
        bar = occ.addRectangle(x_arc - 0.002, Y0, 0, X_TIP - x_arc + 0.002, Y1 - Y0)
        pieces, _ = occ.fragment(channel, [(2, bar)])
        occ.synchronize()
        for dim, tag in pieces:
            cx, cy, _ = occ.getCenterOfMass(dim, tag)
            if (cx - XC) ** 2 + (cy - YC) ** 2 < R * R:
                occ.remove([(dim, tag)], recursive=True)
    groups = channel_groups("cylinder")
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "CurvesList", groups["cylinder"])
    field.setNumber(dist, "Sampling", 200)
    near_cylinder = field.add("Threshold")
    field.setNumber(near_cylinder, "InField", dist)
    field.setNumber(near_cylinder, "SizeMin", h / 4)
    field.setNumber(near_cylinder, "SizeMax", h)
    field.setNumber(near_cylinder, "DistMin", 0.01)
    field.setNumber(near_cylinder, "DistMax", 0.3)
    box = field.add("Box")
    for key, value in (("VIn", h / 4), ("VOut", h), ("XMin", 0.24), ("XMax", 0.66), ("YMin", 0.1), ("YMax", 0.3), ("Thickness", 0.15)):
        field.setNumber(box, key, value)
    size = field.add("Min")
    field.setNumbers(size, "FieldsList", [near_cylinder, box])
    field.setAsBackgroundMesh(size)
    for opt in ("Mesh.MeshSizeExtendFromBoundary", "Mesh.MeshSizeFromPoints", "Mesh.MeshSizeFromCurvature"):
        gmsh.option.setNumber(opt, 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    finish(name)


for name, n in LEVELS.items():
    bar(name, n)
for name, level in CFD_LEVELS.items():
    cfd(name, level)
for name, level in FSI_LEVELS.items():
    fsi(name, level)
for name, level in FITTED_LEVELS.items():
    fsi(name, level, fitted=True)
