"""Gmsh meshes of the fluid-film test: a rigid cylinder approaching a wall in Stokes flow.

film-fluid.msh: the box [-4, 4] x [0, 4] in first-order triangles, size 0.005 in the gap box
[-0.4, 0.4] x [0, 0.08] under the cylinder (a gap of 0.02 spans 4 cells; the lubrication
region is about sqrt(2 R h) = 0.2 wide there), 0.04 around the cylinder
[-1.2, 1.2] x [0, 2.4], growing to 0.4 far away. Physical groups: surface "fluid"; curves
"wall" (y = 0), "sides" (x = -4 and 4), "top" (y = 4).

film-ring.msh: the cylinder of radius 1 centred at the origin, as a ring 1 - 0.05 <= r <= 1 of
256 x 2 9-node quadrilaterals (structured): its outer circle is gamma_s and carries the
prescribed rigid motion; the Q2 pieces of the circle are 0.012 long, their sag 2e-5 (0.1 % of
the smallest gap tested). Physical groups: surface "ring"; curves "outer", "inner".

MSH 4.1 ASCII. Run: python make_film.py   (needs the `gmsh` package from PyPI)
"""
import math

import gmsh


def fluid():
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("film-fluid")
    occ = gmsh.model.occ
    box = occ.addRectangle(-4.0, 0.0, 0.0, 8.0, 4.0)
    occ.synchronize()
    gmsh.model.addPhysicalGroup(2, [box], 1, name="fluid")
    groups = {"wall": [], "sides": [], "top": []}
    for _, tag in gmsh.model.getBoundary([(2, box)], oriented=False):
        cx, cy, _ = occ.getCenterOfMass(1, tag)
        if abs(cy) < 1e-9:
            groups["wall"].append(tag)
        elif abs(cy - 4.0) < 1e-9:
            groups["top"].append(tag)
        else:
            groups["sides"].append(tag)
    for k, (name, tags) in enumerate(groups.items()):
        gmsh.model.addPhysicalGroup(1, tags, 10 + k, name=name)
    field = gmsh.model.mesh.field
    gap = field.add("Box")
    for key, value in [("VIn", 0.005), ("VOut", 0.4), ("XMin", -0.4), ("XMax", 0.4), ("YMin", 0.0), ("YMax", 0.08), ("Thickness", 0.15)]:
        field.setNumber(gap, key, value)
    path = field.add("Box")
    for key, value in [("VIn", 0.04), ("VOut", 0.4), ("XMin", -1.2), ("XMax", 1.2), ("YMin", 0.0), ("YMax", 2.4), ("Thickness", 1.0)]:
        field.setNumber(path, key, value)
    size = field.add("Min")
    field.setNumbers(size, "FieldsList", [gap, path])
    field.setAsBackgroundMesh(size)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write("film-fluid.msh")
    gmsh.finalize()


def ring():
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("film-ring")
    geo = gmsh.model.geo
    r0, r1, n_around, n_through = 0.95, 1.0, 256, 2
    centre = geo.addPoint(0.0, 0.0, 0.0)
    # Four quarter arcs per circle: a structured (transfinite) ring of four patches.
    inner = [geo.addPoint(r0 * math.cos(k * math.pi / 2), r0 * math.sin(k * math.pi / 2), 0.0) for k in range(4)]
    outer = [geo.addPoint(r1 * math.cos(k * math.pi / 2), r1 * math.sin(k * math.pi / 2), 0.0) for k in range(4)]
    inner_arcs = [geo.addCircleArc(inner[k], centre, inner[(k + 1) % 4]) for k in range(4)]
    outer_arcs = [geo.addCircleArc(outer[k], centre, outer[(k + 1) % 4]) for k in range(4)]
    spokes = [geo.addLine(inner[k], outer[k]) for k in range(4)]
    surfaces = []
    for k in range(4):
        loop = geo.addCurveLoop([inner_arcs[k], spokes[(k + 1) % 4], -outer_arcs[k], -spokes[k]])
        surfaces.append(geo.addPlaneSurface([loop]))
    geo.synchronize()
    for arc in inner_arcs + outer_arcs:
        gmsh.model.mesh.setTransfiniteCurve(arc, n_around // 4 + 1)
    for spoke in spokes:
        gmsh.model.mesh.setTransfiniteCurve(spoke, n_through + 1)
    for s in surfaces:
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
    gmsh.model.addPhysicalGroup(2, surfaces, 1, name="ring")
    gmsh.model.addPhysicalGroup(1, outer_arcs, 10, name="outer")
    gmsh.model.addPhysicalGroup(1, inner_arcs, 11, name="inner")
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 0)
    gmsh.model.mesh.setOrder(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write("film-ring.msh")
    gmsh.finalize()


if __name__ == "__main__":
    fluid()
    ring()
    print("film-fluid.msh, film-ring.msh written")
