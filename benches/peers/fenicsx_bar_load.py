"""The Turek-Hron bar's fluid load computed by FEniCSx on a given fluid mesh: a yardstick for
fdfsi's multiplier (BENCHMARKS.md "Turek-Hron FSI1", session 16).

Steady Stokes or Navier-Stokes (rho = 1000, mu = 1: FSI1's Re = 20) around the cylinder and a
rigid bar, with strong no-slip on both, the FSI1 inflow and the do-nothing outlet (Laplace form),
in P2+/P1disc ("cr", fdfsi's element) or Taylor-Hood ("th"); Newton with MUMPS. The mesh is read
with meshio and its vertex mesh used (straight cells, as fdfsi's adapted meshes): typically the
fluid `.vtu` of an fdfsi FSI run (`covered_fluid = "removed"`: the bar's cells are gone) or
`fdfsi adapt`'s `adapted.vtu`. Boundary facets are classified by position: x = 0 inlet, x = 2.5
outlet, y = 0 / 0.41 walls, within the cylinder's radius left of the bar's root cylinder, the
rest the bar.

Prints the forces on bar and cylinder (boundary integrals of -p n + mu grad(u) n), the obstacle's
by the residual method, and the bar's by the residual method with the test function's y-component
1 (`res_lift_bar`), `x - x0` (root moment) and the cantilever's tip-deflection weight
`(x - x0)^2 (3 L - (x - x0)) / 6` (`res_tipw_bar`, times 1e3) on the bar's facets: the tip
deflection a beam of length L clamped at x0 gets from the load, times EI.

    python3.12 -m venv /tmp/venv-fenicsx         # once: FEniCSx 0.11 with PETSc + MUMPS (the
    /tmp/venv-fenicsx/bin/pip install dolfinx-solver-real meshio   # PyPI wheel provides dolfinx_solver)
    LD_LIBRARY_PATH=/tmp/venv-fenicsx/lib OMP_NUM_THREADS=1 /tmp/venv-fenicsx/bin/python \
        benches/peers/fenicsx_bar_load.py RUN/solution_fluid_000001.vtu --element cr --rho 1000

Benchmarking only: nothing in the build, tests or CI depends on it.
"""
import argparse

import dolfinx_solver  # noqa: F401  (must come first: loads mpi4py.MPI)
import basix.ufl
import meshio
import numpy as np
import ufl
from dolfinx import fem, mesh as dmesh
from dolfinx.fem.petsc import NonlinearProblem
from mpi4py import MPI

L, H, XC, YC, R = 2.5, 0.41, 0.2, 0.2, 0.05
X0, X_TIP = 0.24899, 0.6  # the bar's root on the cylinder, its tip
INLET, OUTLET, WALL, CYL, BAR = 1, 2, 3, 4, 5

ap = argparse.ArgumentParser()
ap.add_argument("mesh")
ap.add_argument("--element", choices=["cr", "th"], default="cr")
ap.add_argument("--rho", type=float, default=1000.0, help="0: Stokes")
args = ap.parse_args()

m = meshio.read(args.mesh)
tri = [c.data for c in m.cells if c.type.startswith("triangle")][0][:, :3]
used = np.unique(tri)
renumber = -np.ones(len(m.points), int)
renumber[used] = np.arange(len(used))
x, tri = m.points[used][:, :2].copy(), renumber[tri]
msh = dmesh.create_mesh(MPI.COMM_WORLD, tri.astype(np.int64), basix.ufl.element("Lagrange", "triangle", 1, shape=(2,)), x)
msh.topology.create_connectivity(1, 2)
facets = dmesh.exterior_facet_indices(msh.topology)
mid = dmesh.compute_midpoints(msh, 1, facets)
tags = np.full(len(facets), BAR, np.int32)
tags[np.isclose(mid[:, 0], 0)] = INLET
tags[np.isclose(mid[:, 0], L)] = OUTLET
tags[np.isclose(mid[:, 1], 0) | np.isclose(mid[:, 1], H)] = WALL
tags[(tags == BAR) & (np.hypot(mid[:, 0] - XC, mid[:, 1] - YC) < R + 5e-4) & (mid[:, 0] < X0)] = CYL
order = np.argsort(facets)
ft = dmesh.meshtags(msh, 1, facets[order], tags[order])

cell = msh.basix_cell()
if args.element == "cr":
    p2b = basix.ufl.enriched_element([basix.ufl.element("Lagrange", cell, 2), basix.ufl.element("Bubble", cell, 3)])
    vel, pre = basix.ufl.blocked_element(p2b, shape=(2,)), basix.ufl.element("DG", cell, 1)
else:
    vel, pre = basix.ufl.element("Lagrange", cell, 2, shape=(2,)), basix.ufl.element("Lagrange", cell, 1)
W = fem.functionspace(msh, basix.ufl.mixed_element([vel, pre]))
V, _ = W.sub(0).collapse()
inflow, zero = fem.Function(V), fem.Function(V)
inflow.interpolate(lambda p: np.vstack((1.5 * 0.2 * p[1] * (H - p[1]) / (H / 2) ** 2, 0 * p[0])))
bcs = [fem.dirichletbc(g, fem.locate_dofs_topological((W.sub(0), V), 1, ft.find(t)), W.sub(0)) for t, g in ((INLET, inflow), (WALL, zero), (CYL, zero), (BAR, zero))]
w = fem.Function(W)
u, p = ufl.split(w)
v, q = ufl.TestFunctions(W)
F = (ufl.inner(ufl.grad(u), ufl.grad(v)) + args.rho * ufl.inner(ufl.grad(u) * u, v) - p * ufl.div(v) - q * ufl.div(u)) * ufl.dx
opts = {"snes_type": "newtonls", "snes_linesearch_type": "basic", "snes_rtol": 1e-10, "snes_atol": 1e-11, "snes_max_it": 30,
        "ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps"}
NonlinearProblem(F, w, bcs=bcs, petsc_options=opts, petsc_options_prefix="bar_").solve()

out = {}
n, ds = ufl.FacetNormal(msh), ufl.Measure("ds", domain=msh, subdomain_data=ft)
traction = -p * n + ufl.grad(u) * n  # of the body on the fluid; the fluid's force on the body is minus its integral
for name, t in (("bar", BAR), ("cyl", CYL)):
    for what, c in (("drag", 0), ("lift", 1)):
        out[f"{what}_{name}"] = -fem.assemble_scalar(fem.form(traction[c] * ds(t)))


def reaction(component, facet_dofs, weight):
    """-F(w; test) with the test function's `component` equal to `weight` at `facet_dofs`."""
    wt, g = fem.Function(W), fem.Function(W.sub(0).sub(component).collapse()[0])
    g.interpolate(weight)
    fem.dirichletbc(g, facet_dofs, W.sub(0).sub(component)).set(wt.x.array)
    return -fem.assemble_scalar(fem.form(ufl.replace(F, {v: ufl.split(wt)[0], q: ufl.split(wt)[1]})))


one = lambda X: 1.0 + 0 * X[0]  # noqa: E731
for what, c in (("drag", 0), ("lift", 1)):
    Vc = W.sub(0).sub(c).collapse()[0]
    obstacle = fem.locate_dofs_topological((W.sub(0).sub(c), Vc), 1, np.r_[ft.find(CYL), ft.find(BAR)])
    out[f"{what}_obstacle_residual"] = reaction(c, obstacle, one)
Vy = W.sub(0).sub(1).collapse()[0]
bar = fem.locate_dofs_topological((W.sub(0).sub(1), Vy), 1, ft.find(BAR))
cyl = fem.locate_dofs_topological((W.sub(0).sub(1), Vy), 1, ft.find(CYL))
keep = ~np.isin(bar[1], cyl[1])  # the root corners belong to the cylinder
bar = [bar[0][keep], bar[1][keep]]
length = X_TIP - X0
for name, weight in (("res_lift_bar", one), ("res_moment_bar", lambda X: X[0] - X0),
                     ("res_tipw_bar", lambda X: (X[0] - X0) ** 2 * (3 * length - (X[0] - X0)) / 6 * 1e3)):
    out[name] = reaction(1, bar, weight)
print(args.mesh, args.element, f"rho={args.rho}", "cells", len(tri), "bar facets", len(ft.find(BAR)), " ".join(f"{k}={val:.6f}" for k, val in out.items()))
