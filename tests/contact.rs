//! Frictionless contact with rigid planes (issue 17; [`fdfsi::physics::contact`]).
//!
//! The patch test: a block pressed on a rigid plane by a uniform load carries it as a uniform
//! contact pressure equal to the load, to 1e-10 relative, in 2D and 3D, through the semi-smooth
//! Newton iteration's active set.

use fdfsi::discretize::solid::{solve_quasi_static, Lagrangian, LoadStepping, SolidDiscretization, SolidProblem, SolidSolution};
use fdfsi::fem::generate::{box_hexahedra, rectangle_quads};
use fdfsi::fem::mesh::{GeometryOrder, Mesh};
use fdfsi::physics::contact::RigidPlane;
use fdfsi::physics::fluid::Formulation;
use fdfsi::physics::solid::{NeoHookeanMixed, SolidMaterial};
use fdfsi::solve::linear::FaerLu;
use fdfsi::verify::solid_exact::study_newton;
use std::sync::Arc;

/// The contact pressure of every node of the first contact surface.
fn contact_pressures<const D: usize>(disc: &SolidDiscretization<D>, sol: &SolidSolution) -> Vec<f64> {
    let s = &disc.contact_surfaces()[0];
    (0..s.nodes.len()).map(|j| sol.x[s.first + j]).collect()
}

fn solve<const D: usize>(
    mesh: Mesh<D>,
    formulation: Formulation,
    problem: SolidProblem<D>,
    mode: Lagrangian,
) -> (SolidDiscretization<D>, SolidSolution) {
    assert_eq!(problem.formulation, formulation);
    let disc = SolidDiscretization::build_for(mesh, &problem).unwrap();
    let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(mode, 2), &mut FaerLu::default(), &study_newton()).unwrap();
    (disc, sol)
}

#[test]
fn a_block_pressed_on_a_plane_carries_the_load_as_a_uniform_contact_pressure() {
    let g = 1.0;
    let p = 0.2;
    let material: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(g));
    // 2D, plane strain: the block [0, 1] x [0, 0.5] on the line y = 0, pressed by a dead load
    // on its top; the left side on rollers.
    let plane = RigidPlane::new([0.0, 0.0], [0.0, 1.0]).unwrap();
    let problem = SolidProblem::new(Formulation::Plane, material.clone())
        .with_displacement("left", &[0], |_: &[f64; 2], _| [0.0; 2])
        .with_traction("top", move |_: &[f64; 2], l| [0.0, -p * l])
        .with_contact("bottom", plane);
    let mesh = rectangle_quads(0.0, 1.0, 0.0, 0.5, 4, 2, GeometryOrder::Quadratic);
    let (disc, sol) = solve(mesh, Formulation::Plane, problem, Lagrangian::Total);
    let lambda = contact_pressures(&disc, &sol);
    let worst = lambda.iter().fold(0.0f64, |m, l| m.max((l - p).abs())) / p;
    println!("2D: contact pressures {lambda:?}: worst relative error {worst:.2e}");
    assert_eq!(lambda.len(), 9);
    // Measured 1.8e-15.
    assert!(worst < 1e-13, "{lambda:?}");
    // No penetration: the bottom nodes stay on the plane.
    for &node in &disc.contact_surfaces()[0].nodes {
        assert!(disc.displacement(&sol.x, node)[1].abs() < 1e-12);
    }
    // 3D: the box [0, 1] x [0, 1] x [0, 0.5] on the plane z = 0, rollers on x = 0 and y = 0.
    let plane = RigidPlane::new([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).unwrap();
    let problem = SolidProblem::new(Formulation::ThreeD, material)
        .with_displacement("xmin", &[0], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("ymin", &[1], |_: &[f64; 3], _| [0.0; 3])
        .with_traction("zmax", move |_: &[f64; 3], l| [0.0, 0.0, -p * l])
        .with_contact("zmin", plane);
    let mesh = box_hexahedra(0.0, 1.0, 0.0, 1.0, 0.0, 0.5, 2, 2, 1, GeometryOrder::Quadratic);
    let (disc, sol) = solve(mesh, Formulation::ThreeD, problem, Lagrangian::Total);
    let lambda = contact_pressures(&disc, &sol);
    let worst = lambda.iter().fold(0.0f64, |m, l| m.max((l - p).abs())) / p;
    println!("3D: {} contact nodes, worst relative error {worst:.2e}", lambda.len());
    assert_eq!(lambda.len(), 25);
    assert!(worst < 1e-13, "{lambda:?}");
    // Axisymmetric: the cylinder r <= 1, 0 <= z <= 0.5 (x = (z, r)) pressed on the plane z = 0.
    // The node on the axis has no weight (R = 0) and no multiplier; the others carry the load.
    let plane = RigidPlane::new([0.0, 0.0], [1.0, 0.0]).unwrap();
    let material: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(g));
    let problem = SolidProblem::new(Formulation::Axisymmetric, material)
        .with_displacement("bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
        .with_traction("right", move |_: &[f64; 2], l| [-p * l, 0.0])
        .with_contact("left", plane);
    let mesh = rectangle_quads(0.0, 0.5, 0.0, 1.0, 2, 4, GeometryOrder::Quadratic);
    let (disc, sol) = solve(mesh, Formulation::Axisymmetric, problem, Lagrangian::Updated);
    let lambda = contact_pressures(&disc, &sol);
    let worst = lambda.iter().fold(0.0f64, |m, l| m.max((l - p).abs())) / p;
    println!("axisymmetric: {} contact nodes, worst relative error {worst:.2e}", lambda.len());
    assert_eq!(lambda.len(), 8, "the 9 nodes of the face but the one on the axis");
    assert!(worst < 1e-13, "{lambda:?}");
}

/// The quarter disc `x, y >= 0`, `x^2 + y^2 <= 1` in `n x n` 9-node cells, refined toward
/// `(1, 0)`: the unit square graded (`u = 1 - (1 - s)^1.5`, `v = t^1.5`) and mapped by the
/// elliptical square-to-disc map `(u sqrt(1 - v^2/2), v sqrt(1 - u^2/2))`, which takes the side
/// `u = 1` ("right") onto the arc. The other sides: "left" (`x = 0`), "bottom" (`y = 0`), "top"
/// (the arc's other half, `v = 1`).
fn quarter_disc(n: usize) -> Mesh<2> {
    let mut mesh = rectangle_quads(0.0, 1.0, 0.0, 1.0, n, n, GeometryOrder::Quadratic);
    for p in mesh.points.iter_mut() {
        let (u, v) = (1.0 - (1.0 - p[0]).powf(1.5), p[1].powf(1.5));
        *p = [u * (1.0 - v * v / 2.0).sqrt(), v * (1.0 - u * u / 2.0).sqrt()];
    }
    mesh
}

/// Hertz: a cylinder (radius R = 1, incompressible neo-Hookean G = 1, plane strain: E* = 4 G)
/// pressed on a rigid plane by P = 0.01 per unit length. The quarter model: the quarter disc
/// touching the line x = 1 at (1, 0), symmetric about y = 0, loaded by the dead traction P/2 on
/// its side x = 0. Hertz's half-width a = sqrt(P R / (pi G)) = 0.05642 and peak pressure
/// 2P / (pi a) = 0.11284 (issue 17 asks for 3 %; measured 0.02 % for both, held at 0.1 %), with
/// at least 10 facets across the contact (2a).
/// The half-width is measured from the pressure's moments, `a^2 = 4 int p y^2 / int p` for the
/// elliptical distribution `p0 sqrt(1 - y^2/a^2)`.
#[test]
fn a_cylinder_on_a_plane_has_hertz_contact_width_and_peak_pressure() {
    let (g, p_load, r) = (1.0, 0.01, 1.0);
    let a_hertz = (p_load * r / (std::f64::consts::PI * g)).sqrt();
    let p0_hertz = 2.0 * p_load / (std::f64::consts::PI * a_hertz);
    let material: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(g));
    let plane = RigidPlane::new([1.0, 0.0], [-1.0, 0.0]).unwrap();
    let problem = SolidProblem::new(Formulation::Plane, material)
        .with_displacement("bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
        .with_traction("left", move |_: &[f64; 2], l| [0.5 * p_load * l, 0.0])
        .with_contact("right", plane);
    let (disc, sol) = solve(quarter_disc(32), Formulation::Plane, problem, Lagrangian::Total);
    let surface = &disc.contact_surfaces()[0];
    let weight = &surface.weights;
    let (mut force, mut moment, mut peak, mut nodes_inside) = (0.0, 0.0, 0.0f64, 0);
    for (j, &node) in surface.nodes.iter().enumerate() {
        let (lambda, y) = (sol.x[surface.first + j], disc.nodes_x0[node][1]);
        force += lambda * weight[j];
        moment += lambda * weight[j] * y * y;
        peak = peak.max(lambda);
        // Two nodes per facet (a vertex and a mid-side node) in [0, a).
        if y < a_hertz {
            nodes_inside += 1;
        }
    }
    let facets = nodes_inside / 2;
    let a = (4.0 * moment / force).sqrt();
    println!(
        "contact force {force:.6e} (P/2 = {:.6e}); half-width {a:.5} (Hertz {a_hertz:.5}); peak {peak:.5} (Hertz {p0_hertz:.5}); {facets} facets in [0, a)",
        p_load / 2.0
    );
    assert!((force - p_load / 2.0).abs() < 1e-9 * p_load, "equilibrium: {force}");
    // No node penetrates the plane.
    let gap_min = surface.nodes.iter().map(|&k| 1.0 - disc.current_position(&sol.x, k)[0]).fold(f64::INFINITY, f64::min);
    assert!(gap_min > -1e-12, "penetration {gap_min:e}");
    assert!(2 * facets >= 10, "{facets} facets in the half-width");
    assert!((a / a_hertz - 1.0).abs() < 1e-3, "half-width {a} vs {a_hertz}");
    assert!((peak / p0_hertz - 1.0).abs() < 1e-3, "peak {peak} vs {p0_hertz}");
}

/// `[[solid.contact]]` through the case file, with the direct and the augmented-Lagrangian
/// solvers and in total and updated Lagrangian load steps: the patch test's quantities
/// (`bottom_contact_force` = the load, `bottom_contact_pressure_max` = its pressure, no gap) and
/// the solid output's `contact_pressure`.
#[test]
fn a_contact_case_file_reports_force_pressure_and_gap() {
    use fdfsi::case::Case;
    use fdfsi::fem::vtk::read_vtu;
    use fdfsi::run::{run_case, RunOptions};
    for method in ["direct", "augmented-lagrangian"] {
        for mode in ["total", "updated"] {
            let text = format!(
                r#"title = "contact patch test"
[physics]
formulation = "plane"
[solid]
mesh = {{ kind = "rectangle", x = [0.0, 1.0], y = [0.0, 0.5], n = [4, 2] }}
model = "neo-hookean"
shear_modulus = 1.0
loading = {{ steps = 2, mode = "{mode}" }}
[[solid.boundary]]
name = "left"
type = "displacement"
components = [0]
value = [0.0, 0.0]
[[solid.boundary]]
name = "top"
type = "traction"
value = [0.0, -0.2]
[[solid.contact]]
boundary = "bottom"
point = [0.0, 0.0]
normal = [0.0, 2.0]
[solver.linear]
method = "{method}"
"#
            );
            let case = Case::from_toml_str(&text, "contact.toml").unwrap();
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().join("out");
            let s = run_case(&case, &RunOptions::new(&out, dir.path()), &mut |_: &str| {}).unwrap();
            let q = |name: &str| s.quantities[name];
            println!("{method} {mode}: {:?}", s.quantities);
            assert!((q("bottom_contact_force") - 0.2).abs() < 1e-12, "{method} {mode}");
            assert!((q("bottom_contact_pressure_max") - 0.2).abs() < 1e-12, "{method} {mode}");
            assert!(q("bottom_gap_min").abs() < 1e-12, "{method} {mode}");
            let grid = read_vtu(&out.join("solution_solid_000000.vtu")).unwrap();
            let pressure = &grid.point_array("contact_pressure").unwrap().values;
            assert_eq!(pressure.iter().filter(|&&p| (p - 0.2).abs() < 1e-12).count(), 9, "{pressure:?}");
            assert!(grid.point_array("contact_gap").is_some());
        }
    }
}

/// The two-body patch test from a case file: `meshes/two-blocks.msh` (two bodies, 4 x 2 cells
/// on 3 x 2, non-matching at y = 0.5; `meshes/make_two_blocks.py`), `against` the lower block.
#[test]
fn a_two_body_contact_case_file_reports_a_uniform_pressure() {
    use fdfsi::case::Case;
    use fdfsi::run::{run_case, RunOptions};
    let text = r#"title = "two blocks"
[physics]
formulation = "plane"
[solid]
mesh = { kind = "gmsh", file = "two-blocks.msh" }
model = "neo-hookean"
shear_modulus = 1.0
[[solid.boundary]]
name = "lower_bottom"
type = "displacement"
components = [1]
value = [0.0, 0.0]
[[solid.boundary]]
name = "lower_left"
type = "displacement"
components = [0]
value = [0.0, 0.0]
[[solid.boundary]]
name = "upper_left"
type = "displacement"
components = [0]
value = [0.0, 0.0]
[[solid.boundary]]
name = "upper_top"
type = "traction"
value = [0.0, -0.2]
[[solid.contact]]
boundary = "upper_bottom"
against = "lower_top"
[solver.newton]
abs_tol = 1e-14
rel_tol = 1e-14
"#;
    let meshes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
    let case = Case::from_toml_str(text, "two-blocks.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let s = run_case(&case, &RunOptions::new(dir.path().join("out"), &meshes), &mut |_: &str| {}).unwrap();
    let q = |name: &str| s.quantities[name];
    println!("two blocks: {:?}", s.quantities);
    assert!((q("upper_bottom_contact_force") - 0.2).abs() < 1e-12);
    assert!((q("upper_bottom_contact_pressure_max") - 0.2).abs() < 1e-12);
    assert!(q("upper_bottom_gap_min").abs() < 1e-12);
}

/// Contact in an FSI run: model problem 1's slab (clamped at the upper wall, pushed downstream
/// by the pulsatile flow; 40 x 10 cells, dt = 0.1, to the peak inflow at t = 2) with a rigid stop,
/// the plane x = 10.125, 0.1 downstream of its right face. Free, the slab's tip swings 0.34
/// downstream; stopped, it rests on the plane: the tip's x displacement is 0.100 (its right
/// corner touches), no node penetrates, and the stop pushes back. The contact pressures are a
/// block of the monolithic FSI system, solved with the fluid, the solid and the multiplier.
#[test]
fn a_slab_in_flow_comes_to_rest_on_a_stop() {
    let cases = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let text = std::fs::read_to_string(cases.join("model-problem-1.toml")).unwrap();
    let text = text.replace("n = [80, 20]", "n = [40, 10]").replace("end = 18.0", "end = 2.0").replace("dt = 0.05", "dt = 0.1");
    let stop = "[[solid.contact]]\nboundary = \"right\"\npoint = [10.125, 0.0]\nnormal = [-1.0, 0.0]\n\n[time]";
    let stopped = text.replace("[time]", stop);
    assert!(stopped.contains("solid.contact") && text.contains("end = 2.0"));
    let (free, _, _) = run_history(&text, "slab.toml");
    let (stopped, header, rows) = run_history(&stopped, "slab.toml");
    let (tip_free, tip) = (free.quantities["tip_displacement_x"], stopped.quantities["tip_displacement_x"]);
    println!("tip x displacement: free {tip_free:.5}, stopped {tip:.5}; contact force {:.4}", stopped.quantities["right_contact_force"]);
    assert!(tip_free > 0.3, "the free slab swings past the stop: {tip_free}");
    assert!((tip - 0.1).abs() < 2e-3, "the stopped slab rests on the plane: {tip}");
    let gap = header.iter().position(|c| c == "right_gap_min").unwrap();
    assert!(rows.iter().all(|r| r[gap] >= -1e-12), "no penetration in any step");
    assert!(stopped.quantities["right_contact_force"] > 0.0 && stopped.quantities["right_contact_pressure_max"] > 0.0);
    // A contact pressure per node of the slab's right face (2 x 10 cells: 21 nodes), in the
    // solid's part of the system.
    assert_eq!(stopped.dofs["solid"], free.dofs["solid"] + 21);
}

/// A leaflet hinged at the top wall of a channel (height 1, kept covered fluid, coupled on its
/// upstream face) closes against the symmetry line y = 0 under a reversed pressure difference
/// of 1.5, holds it until it settles, and reopens when the difference turns forward at t = 12
/// (`[[solid.contact]]` on its tip; the fluid cut off between the tip and the line once it
/// touches, `fdfsi_fem::adapt::gap`). The issue's checks: no penetration (gap >= -1e-6 of the
/// channel height), the jump across the closed leaflet equal to the applied one within 0.1 %,
/// the flux through the valve below 1e-6 of the peak flux once settled, and reopening without a
/// pressure spike above 10 % of the jump.
#[test]
fn a_leaflet_closes_on_the_symmetry_line_seals_and_reopens() {
    let text = r#"
title = "a leaflet closing on the symmetry line and reopening"
[mesh]
kind = "channel"
length = 6.0
height = 1.0
n = [48, 16]
grading = 4.0
[physics]
formulation = "plane"
model = "navier-stokes"
[fluid]
density = 1.0
viscosity = 0.25
[solid]
mesh = { kind = "quadrilateral", corners = [[2.6, 0.1], [2.7, 0.1], [2.05, 1.0], [1.95, 1.0]], n = [2, 22] }
surface = "left"
model = "neo-hookean"
shear_modulus = 3000.0
[[solid.boundary]]
name = "top"
type = "displacement"
value = [0.0, 0.0]
[[solid.contact]]
boundary = "bottom"
point = [0.0, 0.0]
normal = [0.0, 1.0]
[time]
dt = 0.05
end = 15.0
output_every = 1000
[solver.linear]
method = "direct"
[[boundary]]
name = "inlet"
type = "pressure"
value = ["1.5*min(max(t - 12, 0), 1)"]
[[boundary]]
name = "bottom"
type = "symmetry"
normal_axis = 1
[[boundary]]
name = "top"
type = "no-slip"
[[boundary]]
name = "outlet"
type = "pressure"
value = ["1.5*min(t, 1) - 1.5*min(max(t - 12, 0), 1)"]
[output]
animation = false
[[output.boundary_integral]]
name = "inlet_flux"
boundary = "inlet"
kind = "flux"
[[output.boundary_integral]]
name = "outlet_flux"
boundary = "outlet"
kind = "flux"
[[output.probe]]
name = "p_up"
field = "pressure"
point = [1.0, 0.5]
[[output.probe]]
name = "p_down"
field = "pressure"
point = [4.5, 0.5]
"#;
    let (_, header, rows) = run_history(text, "leaflet.toml");
    assert_eq!(rows.len(), 300, "every step done, none cut");
    let col = |name: &str| {
        let i = header.iter().position(|c| c == name).unwrap_or_else(|| panic!("no column {name}"));
        rows.iter().map(|r| (r[1], r[i])).collect::<Vec<_>>()
    };
    let (q_in, q_out, gap, force) = (col("inlet_flux"), col("outlet_flux"), col("bottom_gap_min"), col("bottom_contact_force"));
    let (p_up, p_down, cut) = (col("p_up"), col("p_down"), col("closed_gap_cells"));
    let (jump, reversal) = (1.5, 12.0);
    let at = |series: &[(f64, f64)], t: f64| series.iter().find(|s| s.0 >= t - 1e-9).unwrap().1;
    let closed = |t: f64| at(&force, t) > 0.0;
    // The peak flux while the valve closes.
    let peak = q_in.iter().filter(|q| q.0 < reversal).map(|q| q.1.abs()).fold(0.0, f64::max);
    let worst_gap = gap.iter().map(|g| g.1).fold(f64::INFINITY, f64::min);
    // The fluid is cut off in a step exactly when the tip touched the line at the step's start
    // (each step adapts the mesh to the solid's last position), or came within `CLOSED_WITHIN`
    // of the cut-off of it (one cell at the line: 1/16).
    let touching = |g: f64| g <= fdfsi_fem::adapt::gap::CLOSED_WITHIN / 16.0;
    assert!(gap.windows(2).zip(&cut[1..]).all(|(g, c)| touching(g[0].1) == (c.1 > 0.0)), "cells are cut off while, and only while, the tip touches");
    // Global flux balance every step: what enters leaves (the cut cells' walls hold the fluid).
    let balance = q_in.iter().zip(&q_out).map(|(a, b)| (a.1 + b.1).abs()).fold(0.0, f64::max) / peak;
    // Settled before the reversal.
    let jump_error = (at(&p_down, reversal) - at(&p_up, reversal) - jump).abs() / jump;
    let settled_flux = at(&q_in, reversal).abs() / peak;
    // Reopening: the probes stay within the applied pressures 0 and 1.5, up to 10 % of the jump.
    let spike =
        p_up.iter().zip(&p_down).filter(|(u, _)| u.0 > reversal).map(|(u, d)| (u.1 - jump).max(-d.1).max(-u.1).max(d.1 - jump)).fold(0.0, f64::max)
            / jump;
    println!(
        "leaflet: gap min {worst_gap:.2e}, flux balance {balance:.2e} of the peak flux {peak:.4}, at t = {reversal}: jump error \
         {jump_error:.2e}, flux {settled_flux:.2e} of the peak, {} cells cut off; reopening overshoot {spike:.3} of the jump",
        at(&cut, reversal)
    );
    assert!(worst_gap >= -1e-6, "penetration {worst_gap}");
    assert!(balance < 1e-13, "flux balance {balance}");
    assert!((0..=18).map(|k| 3.0 + 0.5 * k as f64).all(closed), "closed from t = 3 to 12");
    assert!(at(&cut, reversal) > 0.0);
    assert!(jump_error < 1e-6, "jump {jump_error}");
    assert!(settled_flux < 1e-6, "the flux through the closed valve once settled: {settled_flux}");
    assert!(!closed(15.0) && at(&gap, 15.0) > 0.0 && at(&cut, 15.0) == 0.0, "reopened, the cells back");
    assert!(spike < 0.1, "reopening overshoot {spike}");
}

/// Runs the case `text` (named `name`, its files relative to the repository's `cases/`) into a
/// temporary folder and reads its `history.csv`: the run's summary, the header and the rows.
fn run_history(text: &str, name: &str) -> (fdfsi::run::RunSummary, Vec<String>, Vec<Vec<f64>>) {
    use fdfsi::case::Case;
    use fdfsi::run::{run_case, RunOptions};
    let cases = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let case = Case::from_toml_str(text, name).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let summary = run_case(&case, &RunOptions::new(&out, &cases), &mut |_: &str| {}).unwrap();
    let csv = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    (summary, header, rows)
}

/// Two meshes as one solid mesh of two bodies: the boundaries of `a` named `A/NAME`, those of
/// `b` `B/NAME` (`names` = (`A`, `B`)).
fn two_bodies(a: Mesh<2>, b: Mesh<2>, names: (&str, &str)) -> Mesh<2> {
    Mesh::disjoint_union(&[(names.0, &a), (names.1, &b)]).unwrap()
}

/// The issue's patch test with two bodies: an upper block of 4 x 2 cells pressed by a dead load
/// on a lower block of 3 x 2 cells held on rollers; their meshes do not match along the
/// interface. The mortar coupling ([`fdfsi::discretize::mortar`]) carries the load as a uniform
/// contact pressure. Plane strain: the blocks stacked along y (rollers on x = 0 and y = 0).
/// Axisymmetric (x = (z, r)): two cylinders r <= 1 stacked along the axis, the interface
/// z = 0.5 through the axis (its node there has no weight and no multiplier).
#[test]
fn two_blocks_with_non_matching_meshes_carry_a_uniform_contact_pressure() {
    let p = 0.2;
    let material: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(1.0));
    let plane = || {
        let lower = rectangle_quads(0.0, 1.0, 0.0, 0.5, 3, 2, GeometryOrder::Quadratic);
        let upper = rectangle_quads(0.0, 1.0, 0.5, 1.0, 4, 2, GeometryOrder::Quadratic);
        let problem = SolidProblem::new(Formulation::Plane, material.clone())
            .with_displacement("lower/bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
            .with_displacement("lower/left", &[0], |_: &[f64; 2], _| [0.0; 2])
            .with_displacement("upper/left", &[0], |_: &[f64; 2], _| [0.0; 2])
            .with_traction("upper/top", move |_: &[f64; 2], l| [0.0, -p * l])
            .with_contact_against("upper/bottom", "lower/top");
        (two_bodies(lower, upper, ("lower", "upper")), problem, 9)
    };
    let axisymmetric = || {
        let lower = rectangle_quads(0.0, 0.5, 0.0, 1.0, 2, 3, GeometryOrder::Quadratic);
        let upper = rectangle_quads(0.5, 1.0, 0.0, 1.0, 2, 4, GeometryOrder::Quadratic);
        let problem = SolidProblem::new(Formulation::Axisymmetric, material.clone())
            .with_displacement("lower/bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
            .with_displacement("upper/bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
            .with_displacement("lower/left", &[0], |_: &[f64; 2], _| [0.0; 2])
            .with_traction("upper/right", move |_: &[f64; 2], l| [-p * l, 0.0])
            .with_contact_against("upper/left", "lower/right");
        (two_bodies(lower, upper, ("lower", "upper")), problem, 8)
    };
    for (mesh, problem, nodes) in [plane(), axisymmetric()] {
        let formulation = problem.formulation;
        let (disc, sol) = solve(mesh, formulation, problem, Lagrangian::Updated);
        let lambda = contact_pressures(&disc, &sol);
        let worst = lambda.iter().fold(0.0f64, |m, l| m.max((l - p).abs())) / p;
        println!("{formulation:?}: contact pressures {lambda:?}: worst relative error {worst:.2e}");
        assert_eq!(lambda.len(), nodes, "the upper block's interface nodes with weight");
        assert!(worst < 1e-12, "{lambda:?}");
    }
}

/// A stiff strip touching the symmetry line y = 0 in fluid at a uniform pressure 1, the wedge
/// below it within the cut-off (0.1) of the line cut off: the case of the films' tests.
const FILM_CASE: &str = r#"
title = "a strip touching the symmetry line in fluid at a uniform pressure"
[mesh]
kind = "channel"
length = 1.0
height = 0.5
n = [32, 16]
[physics]
formulation = "plane"
model = "stokes"
[fluid]
density = 1.0
viscosity = 1.0
[solid]
mesh = { kind = "quadrilateral", corners = [[0.3, 0.0], [0.7, 0.2], [0.68, 0.24], [0.28, 0.04]], n = [16, 2] }
surface = "bottom"
model = "neo-hookean"
shear_modulus = 1e6
[[solid.boundary]]
name = "right"
type = "displacement"
value = [0.0, 0.0]
[[solid.contact]]
boundary = "bottom"
point = [0.0, 0.0]
normal = [0.0, 1.0]
fluid_cut_off = 0.1
[time]
dt = 0.1
end = 0.3
[solver.linear]
method = "direct"
[solver.newton]
abs_tol = 1e-8
[[boundary]]
name = "inlet"
type = "pressure"
value = [1.0]
[[boundary]]
name = "outlet"
type = "pressure"
value = [1.0]
[[boundary]]
name = "bottom"
type = "symmetry"
normal_axis = 1
[[boundary]]
name = "top"
type = "no-slip"
[output]
animation = false
"#;

/// A film where a closed gap cuts the fluid off (`fdfsi_fem::adapt::gap::CutSide`,
/// `fdfsi::discretize::fsi::FilmLoad`): a stiff strip in a channel of fluid at a uniform
/// pressure `p0`, coupled on its lower face, which is also its contact boundary and touches the
/// symmetry line y = 0 at its left end, rising from it at a slope of 1/2 (as a 3D leaflet rises
/// from its plane of coaptation). The fluid in the wedge below it, within `fluid_cut_off` of the
/// line, is cut off; the fluid behind the strip keeps its pressure, which on the wedge presses
/// the strip onto the line with the force `p0 L n` (L the wedge's length along the strip, `n` its
/// lower face's normal). The films carry the pressure at the wedge's mouth, `p0`: their force is
/// `-p0 L n` to 10 % (the cut cells cover the wedge up to a cell), the fluid's force on the strip
/// (the multiplier's and the films') is zero to round-off every step, and so is the contact force:
/// the strip is loaded as with the fluid on both sides. So too with the films at the mean of the
/// gap's mouths by Reynolds' equation (`film_pressure = "reynolds"`): the mean of a uniform
/// pressure is that pressure.
#[test]
fn a_film_carries_the_pressure_at_the_mouth_of_a_closed_gap() {
    for rule in ["nearest-mouth", "reynolds"] {
        println!("film_pressure = {rule}");
        let case = FILM_CASE.replace("surface = \"bottom\"", &format!("surface = \"bottom\"\nfilm_pressure = \"{rule}\""));
        films_carry_the_pressure_of_a_uniform_fluid(&case);
    }
}

fn films_carry_the_pressure_of_a_uniform_fluid(case: &str) {
    let (_, header, rows) = run_history(case, "film.toml");
    assert_eq!(rows.len(), 3);
    let col = |name: &str| {
        let i = header.iter().position(|c| c == name).unwrap_or_else(|| panic!("no column {name}"));
        rows.iter().map(|r| r[i]).collect::<Vec<_>>()
    };
    let (fx, fy, contact, cut) = (col("coupling_force_x"), col("coupling_force_y"), col("bottom_contact_force"), col("closed_gap_cells"));
    let (film_x, film_y) = (col("film_force_x"), col("film_force_y"));
    let force: Vec<f64> = fx.iter().zip(&fy).map(|(x, y)| x.hypot(*y)).collect();
    // The wedge within the cut-off (0.1) of the line: 0.2 along x at the slope 1/2, its length
    // along the strip 0.1 sqrt(5); the lower face's normal (1, -2) / sqrt(5).
    let (p0, length) = (1.0, 0.1 * 5f64.sqrt());
    let n = [1.0 / 5f64.sqrt(), -2.0 / 5f64.sqrt()];
    println!(
        "film: the films' force [{:.4}, {:.4}] against -p0 L n [{:.4}, {:.4}]; the fluid's force on the strip {force:?}, contact force {contact:?}",
        film_x[0],
        film_y[0],
        -p0 * length * n[0],
        -p0 * length * n[1]
    );
    assert!(cut.iter().all(|&c| c > 0.0), "the wedge is cut off every step");
    for k in 0..rows.len() {
        let off = (film_x[k] + p0 * length * n[0]).hypot(film_y[k] + p0 * length * n[1]);
        assert!(off < 0.1 * p0 * length, "step {}: the films carry -p0 L n: [{}, {}]", k + 1, film_x[k], film_y[k]);
        assert!(force[k] < 1e-12 * p0 * length && contact[k].abs() < 1e-12 * p0 * length, "step {}: {} {}", k + 1, force[k], contact[k]);
    }
}

/// [`FILM_CASE`]'s strip lowered flat onto a stop at y = 0.02 (a contact plane inside the fluid,
/// with the cut-off given) over x = 0.3-0.7, its films at the mouths `film_pressure` says.
fn flat_film_case(film_pressure: &str) -> String {
    FILM_CASE
        .replace("[[0.3, 0.0], [0.7, 0.2], [0.68, 0.24], [0.28, 0.04]]", "[[0.3, 0.02], [0.7, 0.02], [0.7, 0.06], [0.3, 0.06]]")
        .replace("point = [0.0, 0.0]", "point = [0.0, 0.02]")
        .replace("surface = \"bottom\"", &format!("surface = \"bottom\"\nfilm_pressure = \"{film_pressure}\""))
}

/// The films of a gap at its lowest mouth (`[solid] film_pressure = "lowest-mouth"`,
/// `fdfsi::discretize::fsi::FilmPressure`). [`FILM_CASE`]'s strip lowered flat onto a stop at y =
/// 0.02 (a contact plane inside the fluid, with the cut-off given) over x = 0.3-0.7: the fluid
/// below it is cut off, one gap open at both ends of the strip. The first step from a last step
/// whose pressure is `p = s x` takes every film to the mouth of the gap (`Adapted::gap_mouths`)
/// whose centroid has the least (`s = 1`) or the greatest (`s = -1`) x, within a cell (1/32) of
/// the strip's left or right end, and the film's pressure unknown is that cell's. With
/// `nearest-mouth` the films keep the mouths nearest them, at both ends, whatever the pressure.
#[test]
fn films_take_the_lowest_mouth_of_their_gap_from_the_last_pressure() {
    use fdfsi::case::Case;
    use fdfsi::discretize::fsi::{FluidSnapshot, FsiState, StepStart};
    use fdfsi::fem::gmsh::AnyMesh;
    let cases = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    // (mouth, gap, the mouth nearest) of each film, the gaps' mouths and the mesh.
    let chosen = |rule: &str, s: f64| {
        let text = flat_film_case(rule);
        let case = Case::from_toml_str(&text, "film.toml").unwrap();
        let AnyMesh::D2(mesh) = fdfsi::setup::build_mesh(&case, &cases).unwrap() else { panic!("a 2D mesh") };
        let model = fdfsi::setup::fsi_model::<2>(&case, &mesh, &cases).unwrap();
        let rest = StepStart::new(&model, &FsiState::at_rest(&model), 0.1).unwrap();
        // The last step's fluid: at rest on the same mesh, its pressure s x (centroid value, gradient).
        let m = &rest.disc.flow.mesh;
        let pressure = (0..m.num_cells()).flat_map(|c| [s * m.vertex_centroid(c)[0], s, 0.0]).collect();
        let vel = rest.disc.flow.velocity_field();
        let fluid = FluidSnapshot {
            solid_base: vec![0.0; model.solid.num_dofs()],
            mesh: m.clone(),
            nodes: vel.nodes.clone(),
            velocity: vec![0.0; vel.num_dofs()],
            lumped: Vec::new(),
            pressure,
        };
        let state = FsiState { fluid: Some(fluid), ..FsiState::at_rest(&model) };
        let start = StepStart::new(&model, &state, 0.1).unwrap();
        let (disc, pf) = (&start.disc, start.disc.flow.pressure_field());
        assert_eq!(disc.films.len(), disc.adapted.cut_sides.len());
        let films: Vec<(usize, usize, usize)> = disc
            .films
            .iter()
            .zip(&disc.adapted.cut_sides)
            .map(|(film, side)| {
                let m = side.mouth.expect("a mouth");
                assert_eq!(film.pressure, vec![(pf.dof(pf.nodes.cell(m)[0], 0), 1.0)], "the film carries its mouth's pressure");
                let nearest = rest.disc.adapted.cut_sides.iter().find(|r| r.facet == side.facet).and_then(|r| r.mouth).unwrap();
                (m, side.gap.expect("in a gap"), nearest)
            })
            .collect();
        (films, disc.adapted.gap_mouths.clone(), disc.adapted.mesh.clone())
    };
    for s in [1.0, -1.0] {
        let (films, gaps, mesh) = chosen("lowest-mouth", s);
        assert_eq!(gaps.len(), 1, "one gap under the strip");
        assert!(films.len() > 8, "{} films", films.len());
        let x = |c: usize| mesh.vertex_centroid(c)[0];
        let lowest = gaps[0].iter().copied().min_by(|a, b| (s * x(*a)).total_cmp(&(s * x(*b)))).unwrap();
        let end = if s > 0.0 { 0.3 } else { 0.7 };
        assert!((x(lowest) - end).abs() < 1.0 / 32.0, "s = {s}: the gap's lowest mouth at x = {}", x(lowest));
        assert!(films.iter().all(|&(m, _, _)| m == lowest), "s = {s}: every film at the lowest mouth");
        let (nearest, _, _) = chosen("nearest-mouth", s);
        assert!(nearest.iter().all(|&(m, _, first)| m == first), "nearest-mouth keeps the nearest");
        let ends = nearest.iter().map(|&(m, _, _)| x(m) < 0.5);
        assert!(ends.clone().any(|left| left) && ends.clone().any(|left| !left), "the nearest mouths at both ends");
    }
}

/// The films of a gap at the mean of its mouths by Reynolds' equation (`[solid] film_pressure =
/// "reynolds"`, `fdfsi::discretize::fsi::FilmPressure`): [`flat_film_case`]'s strip on its stop,
/// the gap below it even. Every cut side carries a film whose pressure is its gap's film weights
/// (`CutSide::film`: positive, summing to one, over the gap's mouths) on the mouth cells' pressure
/// unknowns; films away from the ends take several mouths, and the weights give back `p = x`
/// at the mouths at each facet within 0.02 (cells 1/32 wide; the strip lies on the stop, so the
/// gap layer is flat, `h = 0` at every cut cell it reaches, and the film is sealed evenly, by the
/// permeability's floor): a film that falls linearly from one end to the other, where one mouth
/// per film would be up to 0.2 off. The films' columns of the Jacobian (each mouth's pressure
/// unknown, `w_k int (n . w) ds` in the solid's rows) match central differences of the residual.
#[test]
fn reynolds_films_carry_the_mean_of_their_gaps_mouths() {
    use fdfsi::case::Case;
    use fdfsi::discretize::fsi::{FsiState, StepStart};
    use fdfsi::fem::gmsh::AnyMesh;
    let cases = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let case = Case::from_toml_str(&flat_film_case("reynolds"), "film.toml").unwrap();
    let AnyMesh::D2(mesh) = fdfsi::setup::build_mesh(&case, &cases).unwrap() else { panic!("a 2D mesh") };
    let model = fdfsi::setup::fsi_model::<2>(&case, &mesh, &cases).unwrap();
    let start = StepStart::new(&model, &FsiState::at_rest(&model), 0.1).unwrap();
    let (disc, pf) = (&start.disc, start.disc.flow.pressure_field());
    let (adapted, m) = (&disc.adapted, &disc.flow.mesh);
    assert_eq!(adapted.gap_mouths.len(), 1, "one gap under the strip");
    assert!(disc.films.len() > 8 && disc.films.len() == adapted.cut_sides.len(), "{} films", disc.films.len());
    let mut worst: f64 = 0.0;
    for (film, side) in disc.films.iter().zip(&adapted.cut_sides) {
        let expected: Vec<(usize, f64)> = side.film.iter().map(|&(c, w)| (pf.dof(pf.nodes.cell(c)[0], 0), w)).collect();
        assert_eq!(film.pressure, expected, "the film carries its gap's mean");
        assert!(side.film.iter().all(|&(c, w)| w > 0.0 && adapted.gap_mouths[0].binary_search(&c).is_ok()));
        assert!((side.film.iter().map(|(_, w)| w).sum::<f64>() - 1.0).abs() < 1e-12);
        let g = &adapted.gamma_f[side.facet];
        let x = 0.5 * (m.points[g.vertices[0]][0] + m.points[g.vertices[1]][0]);
        let p: f64 = side.film.iter().map(|&(c, w)| w * m.vertex_centroid(c)[0]).sum();
        worst = worst.max((p - x).abs());
    }
    println!("reynolds films: p = x off by at most {worst:.4}");
    assert!(disc.films.iter().filter(|f| f.pressure.len() > 1).count() > disc.films.len() / 2, "films away from the ends take several mouths");
    assert!(worst < 0.02, "{worst}");
    // The Jacobian in the columns of the films' pressure unknowns against central differences
    // (the load is linear in them: the differences are exact but for round-off).
    let state = FsiState::at_rest(&model);
    let input = start.input(&state);
    let n = disc.num_dofs();
    let x = &start.x;
    let mut k = fdfsi::fem::sparse::CscMatrix::zeros(disc.whole_pattern());
    let mut rhs = vec![0.0; n];
    disc.assemble(&model, &input, x, &vec![false; n], &mut k, &mut rhs).unwrap();
    let mut columns: Vec<usize> = disc.films.iter().flat_map(|f| f.pressure.iter().map(|&(j, _)| j)).collect();
    columns.sort_unstable();
    columns.dedup();
    let (os, ol) = (disc.solid_offset(), disc.multiplier_offset());
    let (mut worst, mut solid_entries) = (0.0f64, 0);
    for &j in &columns {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[j] += 1e-3;
        xm[j] -= 1e-3;
        let (rp, rm) = (disc.residual(&model, &input, &xp).unwrap(), disc.residual(&model, &input, &xm).unwrap());
        for i in 0..n {
            let (fd, kij) = ((rp[i] - rm[i]) / 2e-3, k.get(i, j));
            solid_entries += usize::from((os..ol).contains(&i) && kij != 0.0);
            worst = worst.max((fd - kij).abs() / (1.0 + kij.abs()));
        }
    }
    println!("the films' {} columns: max |K - FD| / (1 + |K|) = {worst:.2e}, {solid_entries} solid entries", columns.len());
    assert!(solid_entries > 0 && worst < 1e-6, "{worst}");
}

/// The films' squeeze (`[solid] film_squeeze = true`, with `film_pressure = "reynolds"` only):
/// [`flat_film_case`]'s strip on its stop. Every film's resistance is `12 mu s` (`s` its cut
/// side's squeeze, positive); the strip moved down into its films by `delta` raises each film's
/// pressure by `r a delta` over its mouths' mean (`v_n = a delta`, the step's `a = 1 / dt`);
/// and the squeeze's part of the Jacobian (the system with the squeeze less the one without)
/// matches central differences of its part of the residual in the solid's columns, where it
/// puts entries. (A facet's velocity summed over its components in place of `v . n` fails the
/// rise; the squeeze's columns left out of the assembly fail the Jacobian's.) Asked for with
/// another `film_pressure`, the squeeze is refused.
#[test]
fn squeezed_films_resist_the_solid_moving_into_them() {
    use fdfsi::case::Case;
    use fdfsi::discretize::fsi::{FsiState, StepStart};
    use fdfsi::fem::gmsh::AnyMesh;
    let squeezed = |rule: &str, on: bool| {
        let text = flat_film_case(rule);
        text.replace(&format!("film_pressure = \"{rule}\""), &format!("film_pressure = \"{rule}\"\nfilm_squeeze = {on}"))
    };
    let refused = Case::from_toml_str(&squeezed("nearest-mouth", true), "film.toml").unwrap().validate("film.toml").unwrap_err().to_string();
    assert!(refused.contains("film_squeeze") && refused.contains("reynolds"), "{refused}");
    let cases = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let model_of = |on: bool| {
        let case = Case::from_toml_str(&squeezed("reynolds", on), "film.toml").unwrap();
        let AnyMesh::D2(mesh) = fdfsi::setup::build_mesh(&case, &cases).unwrap() else { panic!("a 2D mesh") };
        fdfsi::setup::fsi_model::<2>(&case, &mesh, &cases).unwrap()
    };
    let (model, plain) = (model_of(true), model_of(false));
    let state = FsiState::at_rest(&model);
    let (start, start0) = (StepStart::new(&model, &state, 0.1).unwrap(), StepStart::new(&plain, &state, 0.1).unwrap());
    let (disc, disc0) = (&start.disc, &start0.disc);
    assert!(disc.films.len() > 8 && disc.films.len() == disc.adapted.cut_sides.len(), "{} films", disc.films.len());
    for (film, side) in disc.films.iter().zip(&disc.adapted.cut_sides) {
        assert!(side.squeeze > 0.0 && film.squeeze == 12.0 * side.squeeze, "viscosity 1: r = 12 s, {} {}", film.squeeze, side.squeeze);
    }
    assert!(disc0.films.iter().all(|f| f.squeeze == 0.0), "no squeeze unless asked");
    // The strip moved down by delta, into the films below it.
    let input = start.input(&state);
    let (os, n) = (disc.solid_offset(), disc.num_dofs());
    let sf = model.solid.displacement_field();
    let delta = 1e-3;
    let mut x = start.x.clone();
    for node in 0..sf.nodes.num_nodes {
        x[os + sf.dof(node, 1)] -= delta;
    }
    let mut columns = Vec::new();
    let mut worst: f64 = 0.0;
    for film in &disc.films {
        let rise = disc.film_pressure(&model, film, &x, input.a, None, &mut columns) - film.pressure_at(&x);
        assert!(film.normal[1] < -0.99, "the films lie below the strip: {:?}", film.normal);
        let expected = film.squeeze * input.a * delta * -film.normal[1];
        worst = worst.max((rise - expected).abs() / expected.abs());
    }
    println!("squeeze: the films' rise off r a delta by {worst:.2e} (relative)");
    assert!(worst < 1e-9, "{worst}");
    // The squeeze's Jacobian against central differences of its residual.
    let part = |x: &[f64]| -> Vec<f64> {
        let (r, r0) = (disc.residual(&model, &input, x).unwrap(), disc0.residual(&plain, &start0.input(&state), x).unwrap());
        r.iter().zip(&r0).map(|(a, b)| a - b).collect()
    };
    let (mut k, mut k0) = (fdfsi::fem::sparse::CscMatrix::zeros(disc.whole_pattern()), fdfsi::fem::sparse::CscMatrix::zeros(disc0.whole_pattern()));
    let mut rhs = vec![0.0; n];
    disc.assemble(&model, &input, &x, &vec![false; n], &mut k, &mut rhs).unwrap();
    disc0.assemble(&plain, &start0.input(&state), &x, &vec![false; n], &mut k0, &mut rhs).unwrap();
    let mut cols: Vec<usize> = Vec::new();
    for film in &disc.films {
        disc.film_pressure(&model, film, &x, input.a, None, &mut columns);
        cols.extend(columns.iter().map(|&(j, _)| j));
    }
    cols.sort_unstable();
    cols.dedup();
    let (mut worst, mut entries, mut largest) = (0.0f64, 0, 0.0f64);
    for &j in &cols {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[j] += 1e-4;
        xm[j] -= 1e-4;
        let (rp, rm) = (part(&xp), part(&xm));
        for i in 0..n {
            let (fd, kij) = ((rp[i] - rm[i]) / 2e-4, k.get(i, j) - k0.get(i, j));
            entries += usize::from(kij != 0.0);
            largest = largest.max(kij.abs());
            worst = worst.max((fd - kij).abs() / (1.0 + kij.abs()));
        }
    }
    println!("the squeeze's {} columns: max |K - FD| / (1 + |K|) = {worst:.2e}, entries up to {largest:.2e}, {entries} entries", cols.len());
    assert!(entries > 0 && worst < 1e-7, "{worst} {largest}");
}

/// `films.vtu` of `fdfsi adapt --at` the checkpoint after one step of [`flat_film_case`] (films at
/// `film_pressure = rule`) in a flow from the inlet's pressure 2 to the outlet's 1.
fn films_in_a_drop_at_a_checkpoint(rule: &str) -> fdfsi::fem::vtk::UnstructuredGrid {
    use fdfsi::case::Case;
    use fdfsi::run::{run_case, RunOptions};
    let cases = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let text = flat_film_case(rule).replace("end = 0.3", "end = 0.1").replacen("value = [1.0]", "value = [2.0]", 1);
    let case = Case::from_toml_str(&text, "film.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    run_case(&case, &RunOptions { checkpoint_every: Some(1), ..RunOptions::new(&out, &cases) }, &mut |_: &str| {}).unwrap();
    fdfsi::run::adapt::adapt_checkpoint(&out, &dir.path().join("adapt")).unwrap();
    fdfsi::fem::vtk::read_vtu(&dir.path().join("adapt/films.vtu")).unwrap()
}

/// `fdfsi adapt --at` chooses the films' mouths as the run's next step would: with
/// [`flat_film_case`]'s strip in a flow from the inlet's pressure 2 (x = 0) to the outlet's 1 (x =
/// 1), after one step the gap's lowest mouth is by the strip's downstream end (x = 0.7), and
/// `films.vtu` puts every film's mouth there (within 0.1 along x); at the nearest mouths the films
/// split between the two ends.
#[test]
fn adapt_at_a_checkpoint_puts_the_films_at_the_lowest_mouth() {
    let mouths_x = |rule: &str| {
        let films = films_in_a_drop_at_a_checkpoint(rule);
        assert!(films.cell_array("gap").unwrap().values.iter().all(|&g| g == 0.0), "one gap under the strip");
        films.cell_array("mouth").unwrap().values.chunks(3).map(|m| m[0]).collect::<Vec<f64>>()
    };
    let lowest = mouths_x("lowest-mouth");
    assert!(lowest.len() > 8 && lowest.iter().all(|x| (x - 0.7).abs() < 0.1), "lowest-mouth: the mouths at x = {lowest:?}");
    let nearest = mouths_x("nearest-mouth");
    assert!(nearest.iter().any(|x| (x - 0.3).abs() < 0.1) && nearest.iter().any(|x| (x - 0.7).abs() < 0.1), "nearest-mouth: {nearest:?}");
}

/// `fdfsi adapt --at` writes each film's pressure in the checkpoint's fluid (`films.vtu`,
/// `pressure`, and the number of mouths it is a mean of, `mouths`). In [`flat_film_case`]'s flow
/// from the inlet's pressure 2 to the outlet's 1, after one step (a run for each rule): at the
/// nearest mouths each film carries one mouth's pressure, and they differ (by more than 0.1); at
/// the lowest mouth every film carries the same; with `film_pressure = "reynolds"` most films
/// carry a mean of several mouths. Every mouth lies in the checkpoint's mesh (`located` 1).
#[test]
fn adapt_at_a_checkpoint_writes_the_pressure_each_film_carries() {
    // (mouths, pressure) of each film.
    let films = |rule: &str| {
        let grid = films_in_a_drop_at_a_checkpoint(rule);
        let (mouths, pressure) = (&grid.cell_array("mouths").unwrap().values, &grid.cell_array("pressure").unwrap().values);
        assert!(grid.cell_array("located").unwrap().values.iter().all(|&l| (l - 1.0).abs() < 1e-12), "{rule}: every mouth in the checkpoint's mesh");
        let films: Vec<(f64, f64)> = mouths.iter().copied().zip(pressure.iter().copied()).collect();
        assert!(films.len() > 8 && films.iter().all(|f| f.1.is_finite()), "{rule}: {films:?}");
        films
    };
    let nearest = films("nearest-mouth");
    assert!(nearest.iter().all(|f| f.0 == 1.0), "{nearest:?}");
    let (high, low) = nearest.iter().fold((f64::NEG_INFINITY, f64::INFINITY), |(h, l), f| (h.max(f.1), l.min(f.1)));
    assert!(high - low > 0.1, "the nearest mouths' pressures {low} to {high}");
    let lowest = films("lowest-mouth");
    let p_low = lowest[0].1;
    assert!(lowest.iter().all(|f| f.0 == 1.0 && f.1 == p_low), "lowest-mouth: {lowest:?}");
    let reynolds = films("reynolds");
    println!("reynolds films (mouths, pressure): {reynolds:?}; the nearest mouths' {low:.4} to {high:.4}, the lowest {p_low:.4}");
    assert!(reynolds.iter().filter(|f| f.0 > 1.0).count() > reynolds.len() / 2, "films take several mouths");
}

/// `fdfsi adapt --at` a checkpoint of [`FILM_CASE`] writes `films.vtu`: the facets of gamma_f
/// over the cut wedge, each with its normal into the film (below the strip: a unit normal with
/// y < 0) and its mouth, the centroid of a kept cell beside the wedge's open end (x = 0.5, where
/// the strip's lower face rises to the cut-off, 0.1 above the line): within 0.05 of it along x
/// (the cells are 1/32 wide), below y = 0.2.
#[test]
fn adapt_at_a_checkpoint_writes_each_film_with_its_mouth() {
    use fdfsi::case::Case;
    use fdfsi::run::{run_case, RunOptions};
    let cases = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let case = Case::from_toml_str(&FILM_CASE.replace("end = 0.3", "end = 0.1"), "film.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    run_case(&case, &RunOptions { checkpoint_every: Some(1), ..RunOptions::new(&out, &cases) }, &mut |_: &str| {}).unwrap();
    fdfsi::run::adapt::adapt_checkpoint(&out, &dir.path().join("adapt")).unwrap();
    let films = fdfsi::fem::vtk::read_vtu(&dir.path().join("adapt/films.vtu")).unwrap();
    let (normals, mouths) = (&films.cell_array("normal").unwrap().values, &films.cell_array("mouth").unwrap().values);
    let cells = normals.len() / 3;
    assert!(cells > 0 && mouths.len() == 3 * cells, "{cells} films");
    // The wedge: the strip's lower face y = (x - 0.3) / 2 within y < 0.1, so x < 0.5.
    for k in 0..cells {
        let (n, m) = (&normals[3 * k..3 * k + 3], &mouths[3 * k..3 * k + 3]);
        assert!(((n[0] * n[0] + n[1] * n[1]).sqrt() - 1.0).abs() < 1e-12 && n[1] < 0.0, "film {k}: normal {n:?}");
        assert!(m[0] > 0.45 && m[0] < 0.55 && m[1] > 0.0 && m[1] < 0.2, "film {k}: mouth {m:?}");
    }
}
