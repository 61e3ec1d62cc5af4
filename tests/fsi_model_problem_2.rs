//! The paper's model problem 2 (section 3.2, METHOD.md section 5): a stiff plate skewed by 30
//! degrees in the middle of the channel [0, 4] x [0, 1], steady plug inflow, Re = 20 on the
//! channel height (rho = 1, eta = 0.05, inflow 1). Solved twice on the same adapted fluid mesh:
//!
//! * FSI: implicit-Euler steps of the monolithic Lagrange-multiplier method ([`fdfsi::fsi`]) to
//!   near steady state, with a very stiff incompressible neo-Hookean plate (G = 1e4, clamped on
//!   its lower face; gamma_s = its upper face) and the inflow ramped over the first two steps;
//! * pure fluid: steady Navier-Stokes with no-slip Dirichlet nodes on gamma_f.
//!
//! Compared: the force on the plate (FSI: `int lambda ds`; fluid: the consistent-residual force
//! on `gamma_f`) and the wall shear stress on both sides of the plate (relative L2 difference).
//!
//! Measured (G = 1e4, dt = 1, 13 steps to a relative velocity change < 1e-7):
//!
//! | mesh | force diff | WSS rel. L2 side 0 / 1 | facet-mean WSS side 0 / 1 |
//! |---|---|---|---|
//! | 64 x 16 | 2.3e-3 | 0.297 / 0.134 | 0.132 / 0.052 |
//! | 128 x 32 | 5.0e-4 | 0.157 / 0.107 | 0.085 / 0.049 |
//!
//! The force meets the 1 % target. The wall shear stress does NOT meet the 3 % target: the weak
//! (P1disc multiplier) no-slip leaves the continuous P2 trace one mode per component that is
//! orthogonal to every multiplier (vertex values c, mid-facet values -c/2), and short gamma_f
//! facets give oscillating pointwise shear within a facet; the difference decreases with h.
//! The test asserts what the method does deliver: the force within 1 % on both meshes, and the
//! shear-stress difference shrinking under refinement on both sides of the plate (issue 6 asks
//! for that beside the 3 % target, which stays open).
//!
//! Numbers are printed and written to `$CARGO_TARGET_TMPDIR/fsi_model_problem_2_<nx>x<ny>.json`.
//!
//! `CARGO_TARGET_DIR=/tmp/target-fsi cargo test --release --test fsi_model_problem_2 -- --nocapture`
//! (both meshes, about a minute in release).

use fdfsi::fem::adapt::AdaptOptions;
use fdfsi::fem::generate::{rectangle_quads, rectangle_triangles, DiagonalPattern};
use fdfsi::fem::mesh::{GeometryOrder, Mesh};
use fdfsi::flow::{solve_steady, DirichletBc, FlowDiscretization, FlowProblem};
use fdfsi::fsi::{step, tag_gamma_f, wall_shear_stress, FsiModel, FsiProblem, FsiState, WallShear};
use fdfsi::physics::fluid::{FluidParams, Formulation, ViscousForm};
use fdfsi::physics::solid::{NeoHookeanMixed, SolidMaterial};
use fdfsi::quantities::{boundary_force, StepState};
use fdfsi::solid::SolidProblem;
use fdfsi::solve::linear::{FaerLu, LinearSolver};
use fdfsi::solve::newton::NewtonOptions;
use std::sync::Arc;
use std::time::Instant;

const ETA: f64 = 0.05;
const G: f64 = 1e4;

fn rotated(mut m: Mesh<2>, deg: f64, pivot: [f64; 2]) -> Mesh<2> {
    let (s, c) = deg.to_radians().sin_cos();
    for p in m.points.iter_mut() {
        let (dx, dy) = (p[0] - pivot[0], p[1] - pivot[1]);
        *p = [pivot[0] + c * dx - s * dy, pivot[1] + s * dx + c * dy];
    }
    m
}

/// The channel flow problem; the inflow is ramped linearly to 1 over `[0, t_ramp]` (`t_ramp = 0`:
/// steady inflow 1).
fn channel(t_ramp: f64) -> FlowProblem<2> {
    let params = FluidParams { viscosity: ETA, density: 1.0, inv_dt: 0.0, convection: true, viscous_form: ViscousForm::Stress };
    let wall = |name: &str| DirichletBc { boundary: name.into(), components: vec![0, 1], value: Arc::new(|_: &[f64; 2], _| [0.0; 2]) };
    let inflow = DirichletBc {
        boundary: "left".into(),
        components: vec![0, 1],
        value: Arc::new(move |_: &[f64; 2], t| [if t_ramp > 0.0 { (t / t_ramp).min(1.0) } else { 1.0 }, 0.0]),
    };
    FlowProblem {
        formulation: Formulation::Plane,
        params,
        body_force: None,
        dirichlet: vec![inflow, wall("bottom"), wall("top")],
        traction: vec![],
        pin_pressure: false,
    }
}

fn rel_l2(a: &[WallShear], b: &[WallShear], side: usize) -> (f64, f64) {
    let (mut num, mut den) = (0.0, 0.0);
    for (p, q) in a.iter().zip(b).filter(|(p, _)| p.side == side) {
        assert_eq!((p.facet, p.side), (q.facet, q.side));
        num += p.weight * (p.tau - q.tau).powi(2);
        den += p.weight * q.tau.powi(2);
    }
    ((num / den).sqrt(), den.sqrt())
}

/// Relative L2 difference of the facet means of the wall shear stress on one side.
fn rel_l2_facet_means(a: &[WallShear], b: &[WallShear], side: usize) -> f64 {
    let mut sums: std::collections::BTreeMap<usize, [f64; 3]> = Default::default();
    for (p, q) in a.iter().zip(b).filter(|(p, _)| p.side == side) {
        let s = sums.entry(p.facet).or_default();
        s[0] += p.weight * p.tau;
        s[1] += q.weight * q.tau;
        s[2] += p.weight;
    }
    let num: f64 = sums.values().map(|s| (s[0] - s[1]).powi(2) / s[2]).sum();
    let den: f64 = sums.values().map(|s| s[1].powi(2) / s[2]).sum();
    (num / den).sqrt()
}

struct Outcome {
    force_rel: f64,
    wss_rel: [f64; 2],
}

fn model_problem_2(nx: usize, ny: usize) -> Outcome {
    let fluid_mesh = rectangle_triangles(0.0, 4.0, 0.0, 1.0, nx, ny, DiagonalPattern::Alternating);
    let plate = rotated(rectangle_quads(1.8, 2.2, 0.49, 0.51, 8, 1, GeometryOrder::Quadratic), 30.0, [2.0, 0.5]);
    let dt = 1.0;
    let mat: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(G));
    let solid = SolidProblem::new(Formulation::Plane, mat).with_displacement("bottom", &[0, 1], |_: &[f64; 2], _| [0.0; 2]);
    let problem = FsiProblem { fluid: channel(2.0 * dt), solid, surface: "top".into(), adapt: AdaptOptions::new(0.2) };
    let model = FsiModel::new(problem, &fluid_mesh, plate).unwrap();
    let mut state = FsiState::at_rest(&model);
    let mut lu = FaerLu::default();
    let newton = NewtonOptions { max_iterations: 15, abs_tol: 1e-10, rel_tol: 1e-11 };
    let mut last = None;
    let mut log = Vec::new();
    for k in 1..=20 {
        let clock = Instant::now();
        let (next, st) = step(&model, &state, dt, &mut lu, &newton).unwrap();
        let r = &st.report;
        // Relative change of the fluid velocity over the step (same node numbering when the
        // adapted mesh is the same).
        let vel = st.disc.flow.layout.fields[0].range();
        let du: f64 = st.x[vel.clone()].iter().zip(&st.u_old[vel.clone()]).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        let un: f64 = st.x[vel].iter().map(|a| a * a).sum::<f64>().sqrt();
        println!(
            "step {k} t = {:.1}: Newton {} its, |R| = {:?}; dofs {} + {} + {} (coupling elements {}, points {}, nnz {}); lambda force = [{:.6}, {:.6}]; |du|/|u| = {:.2e}; max solid increment {:.2e}; max coupling distance {:.1e}; build {:.2}s newton {:.2}s (total {:.2}s)",
            r.time,
            r.newton.iterations,
            r.newton.residual_norms.iter().map(|v| format!("{v:.1e}")).collect::<Vec<_>>(),
            r.fluid_dofs,
            r.solid_dofs,
            r.multiplier_dofs,
            r.coupling_elements,
            r.coupling_points,
            r.pattern_nnz,
            r.multiplier_force[0],
            r.multiplier_force[1],
            du / un,
            r.max_solid_increment,
            r.max_coupling_distance,
            r.seconds.build,
            r.seconds.newton,
            clock.elapsed().as_secs_f64()
        );
        log.push(serde_json::json!({ "step": k, "report": r, "relative_change": du / un }));
        state = next;
        let done = k > 2 && du / un < 1e-7;
        last = Some(st);
        if done {
            break;
        }
    }
    let st = last.unwrap();
    assert!(lu.symbolic_factorizations() <= log.len(), "one symbolic factorisation per step at most");
    // FSI force from lambda, and the fluid's own consistent-residual force on gamma_f.
    let f_lambda = st.disc.multiplier_force(&st.x, Formulation::Plane);
    let x_f = &st.x[..st.disc.fluid_dofs];
    let step_state = StepState { time: st.report.time, inv_dt: 1.0 / dt, u_star: Some(&st.u_old) };
    let f_residual = boundary_force(&st.disc.flow, &st.fluid_problem, x_f, &step_state, "gamma_f").unwrap();
    // Pure-fluid twin on the same adapted mesh: no-slip on gamma_f, steady Navier-Stokes.
    let clock = Instant::now();
    let mut twin = channel(0.0);
    twin.dirichlet.push(DirichletBc { boundary: "gamma_f".into(), components: vec![0, 1], value: Arc::new(|_: &[f64; 2], _| [0.0; 2]) });
    let twin_disc = FlowDiscretization::build(tag_gamma_f(&st.disc.adapted), Formulation::Plane).unwrap();
    let sol = solve_steady(&twin_disc, &twin, &mut FaerLu::default(), &newton).unwrap();
    let f_twin = boundary_force(&twin_disc, &twin, &sol.x, &StepState::default(), "gamma_f").unwrap();
    println!(
        "Dirichlet twin: {} dofs, Newton |R| = {:?} ({:.2}s)",
        twin_disc.num_dofs(),
        sol.newton.residual_norms.iter().map(|v| format!("{v:.1e}")).collect::<Vec<_>>(),
        clock.elapsed().as_secs_f64()
    );
    let fmag = (f_twin[0].powi(2) + f_twin[1].powi(2)).sqrt();
    let force_rel = ((f_lambda[0] - f_twin[0]).powi(2) + (f_lambda[1] - f_twin[1]).powi(2)).sqrt() / fmag;
    let consistency = ((f_lambda[0] - f_residual[0]).powi(2) + (f_lambda[1] - f_residual[1]).powi(2)).sqrt() / fmag;
    println!("force on the plate: FSI int lambda = [{:.6}, {:.6}], FSI fluid residual = [{:.6}, {:.6}], Dirichlet twin = [{:.6}, {:.6}]", f_lambda[0], f_lambda[1], f_residual[0], f_residual[1], f_twin[0], f_twin[1]);
    println!("relative force difference FSI vs twin: {force_rel:.3e}; |int lambda - fluid residual force| / |F| = {consistency:.1e}");
    // Wall shear stress on both sides of the plate.
    let gf = &st.disc.adapted.gamma_f;
    let w_fsi = wall_shear_stress(&st.disc.flow, x_f, gf, ETA, 5);
    let w_twin = wall_shear_stress(&twin_disc, &sol.x, gf, ETA, 5);
    let (e0, n0) = rel_l2(&w_fsi, &w_twin, 0);
    let (e1, n1) = rel_l2(&w_fsi, &w_twin, 1);
    println!("wall shear stress, relative L2 difference FSI vs twin: side 0 (below gamma_f) {e0:.3e} (|tau| = {n0:.4}), side 1 (above) {e1:.3e} (|tau| = {n1:.4})");
    let m0 = rel_l2_facet_means(&w_fsi, &w_twin, 0);
    let m1 = rel_l2_facet_means(&w_fsi, &w_twin, 1);
    println!("wall shear stress facet means, relative L2 difference: side 0 {m0:.3e}, side 1 {m1:.3e}");
    let summary = serde_json::json!({
        "mesh": [nx, ny], "G": G, "dt": dt, "eta": ETA,
        "force_lambda": f_lambda, "force_fluid_residual": f_residual, "force_twin": f_twin,
        "force_relative_difference": force_rel, "force_consistency": consistency,
        "wss_relative_l2": [e0, e1], "wss_facet_mean_relative_l2": [m0, m1], "wss_l2_norm_twin": [n0, n1],
        "wss_fsi": w_fsi.iter().map(|w| [w.side as f64, w.facet as f64, w.x[0], w.x[1], w.weight, w.tau]).collect::<Vec<_>>(),
        "wss_twin": w_twin.iter().map(|w| [w.side as f64, w.facet as f64, w.x[0], w.x[1], w.weight, w.tau]).collect::<Vec<_>>(),
        "twin_dofs": twin_disc.num_dofs(), "twin_newton": sol.newton.residual_norms,
        "steps": log,
    });
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("fsi_model_problem_2_{nx}x{ny}.json"));
    std::fs::write(&path, serde_json::to_string_pretty(&summary).unwrap()).unwrap();
    println!("wrote {}", path.display());
    assert!(consistency < 1e-6, "int lambda must equal the fluid's consistent-residual force: {consistency:e}");
    Outcome { force_rel, wss_rel: [e0, e1] }
}

#[test]
fn model_problem_2_fsi_force_matches_the_dirichlet_twin_and_shear_converges() {
    let coarse = model_problem_2(64, 16);
    let fine = model_problem_2(128, 32);
    for o in [&coarse, &fine] {
        assert!(o.force_rel < 0.01, "force differs by {:.3e}", o.force_rel);
    }
    assert!(fine.force_rel < coarse.force_rel, "force difference shrinks: {} -> {}", coarse.force_rel, fine.force_rel);
    for side in 0..2 {
        assert!(
            fine.wss_rel[side] < coarse.wss_rel[side],
            "wall shear stress difference shrinks on side {side}: {:?} -> {:?}",
            coarse.wss_rel,
            fine.wss_rel
        );
    }
}
