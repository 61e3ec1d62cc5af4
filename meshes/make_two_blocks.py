"""A Gmsh mesh of two bodies for the contact patch test between non-matching meshes.

two-blocks.msh: the lower block [0, 1] x [0, 0.5] in 3 x 2 and the upper block [0, 1] x [0.5, 1]
in 4 x 2 9-node quadrilaterals (structured); the two are separate bodies whose nodes do not
match along y = 0.5. Physical groups: surfaces "lower", "upper"; curves "lower_bottom",
"lower_left", "lower_top", "upper_bottom", "upper_left", "upper_top" (the right sides unnamed).

MSH 4.1 ASCII. Run: python make_two_blocks.py   (needs the `gmsh` package from PyPI)
"""
import gmsh


def block(geo, y0, y1):
    """The block [0, 1] x [y0, y1]: its surface and its bottom, right, top and left curves."""
    p = [geo.addPoint(x, y, 0.0) for x, y in [(0.0, y0), (1.0, y0), (1.0, y1), (0.0, y1)]]
    c = [geo.addLine(p[k], p[(k + 1) % 4]) for k in range(4)]
    return geo.addPlaneSurface([geo.addCurveLoop(c)]), c


def structured(s, c, nx, ny):
    """Makes block `s` (curves `c`) nx x ny quadrilaterals (after the model's synchronisation)."""
    for k, n in zip(range(4), [nx, ny, nx, ny]):
        gmsh.model.mesh.setTransfiniteCurve(c[k], n + 1)
    gmsh.model.mesh.setTransfiniteSurface(s)
    gmsh.model.mesh.setRecombine(2, s)


if __name__ == "__main__":
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("two-blocks")
    geo = gmsh.model.geo
    lower, lc = block(geo, 0.0, 0.5)
    upper, uc = block(geo, 0.5, 1.0)
    geo.synchronize()
    structured(lower, lc, 3, 2)
    structured(upper, uc, 4, 2)
    gmsh.model.addPhysicalGroup(2, [lower], 1, name="lower")
    gmsh.model.addPhysicalGroup(2, [upper], 2, name="upper")
    for tag, (name, curve) in enumerate(
        [("lower_bottom", lc[0]), ("lower_top", lc[2]), ("lower_left", lc[3]), ("upper_bottom", uc[0]), ("upper_top", uc[2]), ("upper_left", uc[3])]
    ):
        gmsh.model.addPhysicalGroup(1, [curve], 10 + tag, name=name)
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 0)
    gmsh.model.mesh.setOrder(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.write("two-blocks.msh")
    gmsh.finalize()
    print("two-blocks.msh written")
