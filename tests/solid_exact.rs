//! Incompressible neo-Hookean Q2/P1disc against exact solutions (EXACT-SOLUTIONS.md section 1):
//! homogeneous states to round-off (plane strain, axisymmetric, 3D), Rivlin bending and cylinder
//! inflation at third order, follower-pressure inflation, quadratic Newton convergence.

use fdfsi::fem::generate::{box_hexahedra, rectangle_quads};
use fdfsi::fem::mesh::GeometryOrder;
use fdfsi::physics::fluid::Formulation;
use fdfsi::physics::solid::{NeoHookeanMixed, SolidMaterial};
use fdfsi::solid::{pressure_at, solve_quasi_static, Lagrangian, LoadStepping, SolidDiscretization, SolidProblem};
use fdfsi::solve::linear::FaerLu;
use fdfsi::verify::solid_exact::{
    cylinder_inflation, quarter_annulus, rivlin_bending, study_newton, CylinderInflation, SimpleShear,
    SolidRun, Uniaxial3d, UniaxialPlaneStrain,
};
use fdfsi::verify::Effort;
use std::sync::Arc;

fn paper_solid(g: f64) -> Arc<dyn SolidMaterial> {
    Arc::new(NeoHookeanMixed::incompressible(g))
}

/// Largest nodal displacement error and pressure error (all cells, several points).
fn homogeneous_errors<const D: usize>(
    disc: &SolidDiscretization<D>,
    x: &[f64],
    u: impl Fn(&[f64; D]) -> [f64; D],
    p: f64,
) -> (f64, f64) {
    let mut eu: f64 = 0.0;
    for (node, x0) in disc.nodes_x0.iter().enumerate() {
        let ue = u(x0);
        let uh = disc.displacement(x, node);
        for d in 0..D {
            eu = eu.max((uh[d] - ue[d]).abs());
        }
    }
    let mut ep: f64 = 0.0;
    let nq = disc.points_per_cell();
    for c in 0..disc.mesh.num_cells() {
        for q in 0..nq {
            ep = ep.max((pressure_at(disc, x, c, &disc.qp_x0[c * nq + q]) - p).abs());
        }
    }
    (eu, ep)
}

#[test]
fn uniaxial_plane_strain_is_exact_and_pressure_follows_the_paper_convention() {
    let g = 2.0;
    let ex = UniaxialPlaneStrain { shear_modulus: g, stretch: 1.5 };
    let mat = paper_solid(g);
    let mesh = rectangle_quads(0.0, 1.0, 0.0, 1.0, 3, 2, GeometryOrder::Linear);
    let disc = SolidDiscretization::build(mesh, Formulation::Plane, mat.as_ref()).unwrap();
    let problem = SolidProblem::new(Formulation::Plane, mat)
        .with_displacement("left", &[0], |_: &[f64; 2], _| [0.0; 2])
        .with_displacement("bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
        .with_displacement("right", &[0], |_: &[f64; 2], l| [0.5 * l, 0.0]);
    let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(Lagrangian::Total, 2), &mut FaerLu::default(), &study_newton()).unwrap();
    let (eu, ep) = homogeneous_errors(&disc, &sol.x, |x| ex.displacement(x), ex.pressure());
    println!("uniaxial plane strain: max |u - u_ex| = {eu:.2e}, max |p - p_ex| = {ep:.2e}, p = {}", ex.pressure());
    assert!(eu < 1e-12 && ep < 1e-11);
    // EXACT-SOLUTIONS convention p' = G lambda^-2 = p + G.
    assert!((ex.pressure() + g - g / 2.25).abs() < 1e-15);
}

#[test]
fn uniaxial_axisymmetric_and_3d_are_exact() {
    let g = 1.0;
    let ex = Uniaxial3d { shear_modulus: g, stretch: 1.5 };
    let mat = paper_solid(g);
    // Axisymmetric (z, r): stretch along the axis z = x[0]; the axis r = 0 is "bottom".
    let mesh = rectangle_quads(0.0, 1.0, 0.0, 1.0, 2, 2, GeometryOrder::Quadratic);
    let disc = SolidDiscretization::build(mesh, Formulation::Axisymmetric, mat.as_ref()).unwrap();
    let problem = SolidProblem::new(Formulation::Axisymmetric, mat.clone())
        .with_displacement("left", &[0], |_: &[f64; 2], _| [0.0; 2])
        .with_displacement("bottom", &[1], |_: &[f64; 2], _| [0.0; 2])
        .with_displacement("right", &[0], |_: &[f64; 2], l| [0.5 * l, 0.0]);
    let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(Lagrangian::Total, 2), &mut FaerLu::default(), &study_newton()).unwrap();
    let (eu, ep) = homogeneous_errors(&disc, &sol.x, |x| ex.displacement(x), ex.pressure());
    println!("uniaxial axisymmetric: {eu:.2e} {ep:.2e}");
    // Round-off up to the Newton tolerance (1e-11 on the residual).
    assert!(eu < 1e-10 && ep < 1e-9);
    // 3D, 27-node hexahedra.
    let mesh = box_hexahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 2, 1, 1, GeometryOrder::Quadratic);
    let disc = SolidDiscretization::build(mesh, Formulation::ThreeD, mat.as_ref()).unwrap();
    let problem = SolidProblem::new(Formulation::ThreeD, mat)
        .with_displacement("xmin", &[0], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("ymin", &[1], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("zmin", &[2], |_: &[f64; 3], _| [0.0; 3])
        .with_displacement("xmax", &[0], |_: &[f64; 3], l| [0.5 * l, 0.0, 0.0]);
    let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(Lagrangian::Total, 2), &mut FaerLu::default(), &study_newton()).unwrap();
    let (eu, ep) = homogeneous_errors(&disc, &sol.x, |x| ex.displacement(x), ex.pressure());
    println!("uniaxial 3D: {eu:.2e} {ep:.2e}");
    assert!(eu < 1e-10 && ep < 1e-9);
}

#[test]
fn simple_shear_is_exact_with_uniform_pressure() {
    let ex = SimpleShear { gamma: 0.5 };
    let mat = paper_solid(1.0);
    let mesh = rectangle_quads(0.0, 1.0, 0.0, 1.0, 3, 3, GeometryOrder::Quadratic);
    let disc = SolidDiscretization::build(mesh, Formulation::Plane, mat.as_ref()).unwrap();
    let mut problem = SolidProblem::new(Formulation::Plane, mat);
    for b in ["left", "right", "bottom", "top"] {
        problem = problem.with_displacement(b, &[0, 1], move |x: &[f64; 2], l| [l * ex.gamma * x[1], 0.0]);
    }
    // Fully Dirichlet: the pressure is fixed by a pin; it must come out uniform.
    problem.pin_pressure = Some(0.3);
    let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(Lagrangian::Total, 1), &mut FaerLu::default(), &study_newton()).unwrap();
    let (eu, ep) = homogeneous_errors(&disc, &sol.x, |x| ex.displacement(x), 0.3);
    println!("simple shear: {eu:.2e} {ep:.2e}");
    assert!(eu < 1e-12 && ep < 1e-11);
}

fn check_rates(run: &SolidRun) {
    for s in &run.studies {
        println!("{} {}: errors {:?} rate {:.3}", s.name, s.quantity, s.errors, s.observed_rate);
    }
    println!("dofs {:?}", run.dofs);
    let l2 = run.studies.iter().find(|s| s.quantity == "displacement_l2").unwrap();
    assert!(l2.observed_rate >= 2.8, "{}: displacement L2 rate {:.3}", l2.name, l2.observed_rate);
    let h1 = run.studies.iter().find(|s| s.quantity == "displacement_h1").unwrap();
    assert!(h1.observed_rate >= 1.8, "{}: H1 rate {:.3}", h1.name, h1.observed_rate);
}

#[test]
fn rivlin_bending_converges_at_third_order_and_newton_is_quadratic() {
    let run = rivlin_bending(Effort::Quick).unwrap();
    check_rates(&run);
    // Quadratic convergence: once |R| is small, each iteration roughly squares the relative
    // residual (log ratio close to 2) until round-off.
    for (k, r) in run.residuals_finest.iter().enumerate() {
        println!("increment {k}: residual norms {r:?}");
    }
    let r = &run.residuals_finest[run.residuals_finest.len() - 1];
    let rel: Vec<f64> = r.iter().map(|v| v / r[0]).collect();
    let mut checked = 0;
    for i in 1..rel.len() - 1 {
        if rel[i] < 1e-2 && rel[i + 1] > 1e-13 {
            let order = rel[i + 1].ln() / rel[i].ln();
            println!("order estimate at iteration {i}: {order:.2}");
            assert!(order > 1.7, "Newton not quadratic: {rel:?}");
            checked += 1;
        }
    }
    assert!(checked >= 1, "no iteration in the quadratic regime: {rel:?}");
}

#[test]
fn cylinder_inflation_converges_at_third_order_plane_and_axisymmetric() {
    check_rates(&cylinder_inflation(Formulation::Plane, Effort::Quick).unwrap());
    check_rates(&cylinder_inflation(Formulation::Axisymmetric, Effort::Quick).unwrap());
}

/// The exact internal pressure as a follower load inflates the quarter annulus to `a = 1.3`.
#[test]
fn follower_pressure_inflates_the_cylinder_to_the_exact_radius() {
    let ex = CylinderInflation::worked_example();
    let pi = ex.internal_pressure();
    let mat = paper_solid(ex.mu);
    let mesh = quarter_annulus(ex.inner, ex.outer, 4, 6);
    let disc = SolidDiscretization::build(mesh, Formulation::Plane, mat.as_ref()).unwrap();
    let problem = SolidProblem::new(Formulation::Plane, mat)
        .with_displacement("symmetry_y", &[1], |_: &[f64; 2], _| [0.0; 2])
        .with_displacement("symmetry_x", &[0], |_: &[f64; 2], _| [0.0; 2])
        .with_pressure("inner", move |l| pi * l);
    let sol = solve_quasi_static(&disc, &problem, &LoadStepping::uniform(Lagrangian::Total, 4), &mut FaerLu::default(), &study_newton()).unwrap();
    let node = disc.node_near(&[1.0, 0.0]);
    let a = 1.0 + disc.displacement(&sol.x, node)[0];
    let node_b = disc.node_near(&[0.0, 1.5]);
    let b = 1.5 + disc.displacement(&sol.x, node_b)[1];
    println!("follower pressure P_i = {pi}: a = {a:.10} (exact 1.3), b = {b:.10} (exact {:.10})", ex.b());
    assert!((a - 1.3).abs() < 1e-4);
    assert!((b - ex.b()).abs() < 1e-4);
}
