//! The paper's model problem 2 (section 3.2, METHOD.md section 5): a stiff plate skewed by 30
//! degrees in the middle of the channel [0, 4] x [0, 1], steady plug inflow, Re = 20 on the
//! channel height (rho = 1, eta = 0.05, inflow 1). Solved twice on the same adapted fluid mesh:
//!
//! * FSI: implicit-Euler steps of the monolithic Lagrange-multiplier method ([`fdfsi::discretize::fsi`]) to
//!   near steady state, with a very stiff incompressible neo-Hookean plate (G = 1e4, clamped on
//!   its lower face; gamma_s = its upper face) and the inflow ramped over the first two steps;
//! * pure fluid: steady Navier-Stokes with no-slip Dirichlet nodes on gamma_f.
//!
//! Compared: the force on the plate (FSI: `int lambda ds`; fluid: the consistent-residual force
//! on `gamma_f`) and the wall shear stress on both sides of the plate (relative L2 difference).
//!
//! Measured (G = 1e4, dt = 1, 13 steps to a relative velocity change < 1e-7), with the paper's
//! P1-discontinuous multiplier and with [`MultiplierSpace::P1DiscontinuousTraceMode`]:
//!
//! | mesh | multiplier | force diff | WSS rel. L2 side 0 / 1 | facet-mean WSS side 0 / 1 | max abs(u_f) on gamma_f |
//! |---|---|---|---|---|---|
//! | 64 x 16 | P1disc (paper) | 2.6e-3 | 0.276 / 0.118 | 0.107 / 0.044 | 1.6e-2 |
//! | 128 x 32 | P1disc (paper) | 5.8e-4 | 0.208 / 0.118 | 0.104 / 0.060 | 7.1e-3 |
//! | 64 x 16 | P1disc + trace mode | 7.3e-10 | 1.6e-9 / 8.2e-10 | 1.6e-9 / 8.1e-10 | 8e-14 |
//! | 128 x 32 | P1disc + trace mode | 6.7e-10 | 1.3e-9 / 8.3e-10 | 1.4e-9 / 8.3e-10 | 2e-13 |
//!
//! Cause of the paper-multiplier difference (measured): on a chain of `N` gamma_f facets the
//! continuous P2 trace has `2N + 1` values per component and the P1-discontinuous multiplier
//! `2N`; the free function is `1 - 6s + 6s^2` on every facet (vertex values c, mid-facet -c/2).
//! In the FSI run the trace of `u_f` on gamma_f is exactly that function with c = (1.4e-2,
//! -8.8e-3) on 64 x 16 (the solid is at rest: its last increment is ~1e-14), while the twin's
//! Dirichlet nodes make it zero. Its tangential derivative `~ 6 c / |facet|` is largest on the
//! short facets (0.0085 to 0.015 long against h = 0.0625, e.g. facet-mean WSS -0.41 vs -0.28 on
//! a 0.0085 facet), so the difference concentrates there. It integrates to zero on every facet,
//! which is why the force agrees far better than the shear. Adding that function to the multiplier
//! space (one multiplier per component and connected chain) makes the trace pairing square and
//! invertible: the FSI trace then vanishes and the FSI run reproduces the Dirichlet twin to the
//! steady-state tolerance on both meshes (so there is no refinement trend left to measure with
//! it). With the paper's multiplier the amplitude `c` halves with `h` and so does the force
//! difference, but the shear difference `~ 6 c / |facet|` does not shrink (facets halve too): it
//! stays at 0.1-0.3 on both meshes (before the adaptation dropped cuts at moved ends, session 4,
//! its values were 0.297 / 0.134 and 0.157 / 0.107: the short facets decide it).
//!
//! `gamma_f` (0.366) is shorter than gamma_s (0.400) in both runs alike (no node at the free ends
//! of gamma_s); it does not enter the comparison, which uses the same adapted mesh and gamma_f.
//!
//! Numbers are printed and written to `$CARGO_TARGET_TMPDIR/fsi_model_problem_2_<nx>x<ny>.json`.
//!
//! `MP2_DIAG=1` prints, per gamma_f facet, the facet-mean shear of both runs and the FSI trace.
//!
//! `CARGO_TARGET_DIR=/tmp/target-fsi cargo test --release --test fsi_model_problem_2 -- --nocapture`
//! (both meshes, both multipliers, about a minute in release).

use fdfsi::adapt::tag_gamma_f;
use fdfsi::discretize::flow::{solve_steady, DirichletBc, FlowDiscretization, FlowProblem};
use fdfsi::discretize::fsi::{step, wall_shear_stress, FsiDiscretization, FsiModel, FsiProblem, FsiState, MultiplierSpace, StepInput, WallShear};
use fdfsi::discretize::solid::SolidProblem;
use fdfsi::fem::adapt::AdaptOptions;
use fdfsi::fem::generate::{rectangle_quads, rectangle_triangles, DiagonalPattern};
use fdfsi::fem::mesh::{GeometryOrder, Mesh};
use fdfsi::fem::sparse::CscMatrix;
use fdfsi::physics::fluid::{FluidParams, Formulation, ViscousForm};
use fdfsi::physics::solid::{NeoHookeanMixed, SolidMaterial};
use fdfsi::post::quantities::{boundary_force, StepState};
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
    let params = FluidParams {
        viscosity: ETA,
        density: 1.0,
        inv_dt: 0.0,
        convection: true,
        convective_form: Default::default(),
        viscous_form: ViscousForm::Stress,
        stabilization: Default::default(),
    };
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
        windkessel: Vec::new(),
        backflow: Vec::new(),
        symmetry: Vec::new(),
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

/// Velocity of the fluid vector `x` at `p` evaluated in cell `c`.
fn eval_u(flow: &FlowDiscretization<2>, x: &[f64], c: usize, p: [f64; 2]) -> [f64; 2] {
    let vel = &flow.velocity_field();
    let nf = flow.velocity_element.num_dofs();
    let v: Vec<[f64; 2]> = flow.mesh.cell_vertices(c).iter().map(|&k| flow.mesh.points[k]).collect();
    let xi = fdfsi::fem::locate::simplex_reference_coords(&v, &p).unwrap();
    let mut vals = vec![0.0; nf];
    let mut grads = vec![[0.0; 2]; nf];
    flow.velocity_element.eval_into(&xi, &mut vals, &mut grads);
    let mut u = [0.0; 2];
    for (i, &node) in vel.nodes.cell(c).iter().enumerate() {
        for a in 0..2 {
            u[a] += vals[i] * x[vel.dof(node, a)];
        }
    }
    u
}

#[allow(clippy::too_many_arguments)]
fn diagnose(
    flow: &FlowDiscretization<2>,
    x: &[f64],
    twin: &FlowDiscretization<2>,
    xt: &[f64],
    gf: &[fdfsi::fem::adapt::GammaFacet<2>],
    w_fsi: &[WallShear],
    w_twin: &[WallShear],
    print_facets: bool,
) -> f64 {
    let mut total = 0.0;
    let mut umax: f64 = 0.0;
    let mut mode: f64 = 0.0;
    if print_facets {
        println!("facet  x0 y0  len | mean tau fsi/twin side0 | side1 | max|dtau| s0 s1 | u(0),u(.5),u(1) fsi | P2 mode");
    }
    for (e, g) in gf.iter().enumerate() {
        let [p0, p1] = g.vertices.map(|v| flow.mesh.points[v]);
        let len = ((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2)).sqrt();
        total += len;
        let c = if g.sides[0].0 != usize::MAX { g.sides[0].0 } else { g.sides[1].0 };
        let at = |s: f64| [p0[0] + s * (p1[0] - p0[0]), p0[1] + s * (p1[1] - p0[1])];
        let u: Vec<[f64; 2]> = [0.0, 0.5, 1.0].iter().map(|&s| eval_u(flow, x, c, at(s))).collect();
        let ut: Vec<[f64; 2]> = [0.0, 0.5, 1.0].iter().map(|&s| eval_u(twin, xt, c, at(s))).collect();
        assert!(ut.iter().flatten().all(|v| v.abs() < 1e-12));
        for q in &u {
            umax = umax.max(q[0].abs()).max(q[1].abs());
        }
        let m = [(u[0][0] + u[2][0] - 2.0 * u[1][0]) / 3.0, (u[0][1] + u[2][1] - 2.0 * u[1][1]) / 3.0];
        mode = mode.max(m[0].abs()).max(m[1].abs());
        let mut mean = [[0.0; 2]; 2];
        let mut dmax = [0.0f64; 2];
        for (p, q) in w_fsi.iter().zip(w_twin).filter(|(p, _)| p.facet == e) {
            mean[p.side][0] += p.weight * p.tau / len;
            mean[p.side][1] += q.weight * q.tau / len;
            dmax[p.side] = dmax[p.side].max((p.tau - q.tau).abs());
        }
        if print_facets {
            println!(
            "{e:3} {:.4} {:.4} {len:.4} | {:+.4} {:+.4} | {:+.4} {:+.4} | {:.4} {:.4} | {:+.1e},{:+.1e} {:+.1e},{:+.1e} {:+.1e},{:+.1e} | {:+.1e} {:+.1e}",
            p0[0], p0[1], mean[0][0], mean[0][1], mean[1][0], mean[1][1], dmax[0], dmax[1],
            u[0][0], u[0][1], u[1][0], u[1][1], u[2][0], u[2][1], m[0], m[1]
            );
        }
    }
    println!("gamma_f: {} facets, length {total:.4}; FSI: max |u_f| at the P2 nodes of gamma_f {umax:.3e}, largest amplitude of the trace mode orthogonal to P1 {mode:.3e}", gf.len());
    umax
}

struct Outcome {
    force_rel: f64,
    wss_rel: [f64; 2],
    /// Largest |u_f| at the P2 nodes (vertices, mid-facets) of gamma_f in the FSI run.
    trace_max: f64,
}

fn model_problem_2(nx: usize, ny: usize, multiplier: MultiplierSpace) -> Outcome {
    let fluid_mesh = rectangle_triangles(0.0, 4.0, 0.0, 1.0, nx, ny, DiagonalPattern::Alternating);
    let plate = rotated(rectangle_quads(1.8, 2.2, 0.49, 0.51, 8, 1, GeometryOrder::Quadratic), 30.0, [2.0, 0.5]);
    let dt = 1.0;
    let mat: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(G));
    let solid = SolidProblem::new(Formulation::Plane, mat).with_displacement("bottom", &[0, 1], |_: &[f64; 2], _| [0.0; 2]);
    let problem = FsiProblem { fluid: channel(2.0 * dt), solid, surface: "top".into(), adapt: AdaptOptions::new(0.2) };
    let model = FsiModel::new(problem, &fluid_mesh, plate).unwrap().with_multiplier(multiplier);
    let mut state = FsiState::at_rest(&model);
    let mut lu = FaerLu::default();
    let newton = NewtonOptions { max_iterations: 15, abs_tol: 1e-10, rel_tol: 1e-11, ..Default::default() };
    let mut last = None;
    let mut log = Vec::new();
    for k in 1..=20 {
        let clock = Instant::now();
        let (next, st) = step(&model, &state, dt, &mut lu, &newton).unwrap();
        let r = &st.report;
        // Relative change of the fluid velocity over the step (same node numbering when the
        // adapted mesh is the same).
        let vel = st.disc.flow.velocity_field().range();
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
    let x_f = &st.x[..st.disc.fluid_dofs()];
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
    println!(
        "force on the plate: FSI int lambda = [{:.6}, {:.6}], FSI fluid residual = [{:.6}, {:.6}], Dirichlet twin = [{:.6}, {:.6}]",
        f_lambda[0], f_lambda[1], f_residual[0], f_residual[1], f_twin[0], f_twin[1]
    );
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
    let trace_max = diagnose(&st.disc.flow, x_f, &twin_disc, &sol.x, gf, &w_fsi, &w_twin, std::env::var("MP2_DIAG").is_ok());
    let summary = serde_json::json!({
        "mesh": [nx, ny], "multiplier": multiplier, "trace_max": trace_max, "G": G, "dt": dt, "eta": ETA,
        "force_lambda": f_lambda, "force_fluid_residual": f_residual, "force_twin": f_twin,
        "force_relative_difference": force_rel, "force_consistency": consistency,
        "wss_relative_l2": [e0, e1], "wss_facet_mean_relative_l2": [m0, m1], "wss_l2_norm_twin": [n0, n1],
        "wss_fsi": w_fsi.iter().map(|w| [w.side as f64, w.facet as f64, w.x[0], w.x[1], w.weight, w.tau]).collect::<Vec<_>>(),
        "wss_twin": w_twin.iter().map(|w| [w.side as f64, w.facet as f64, w.x[0], w.x[1], w.weight, w.tau]).collect::<Vec<_>>(),
        "twin_dofs": twin_disc.num_dofs(), "twin_newton": sol.newton.residual_norms,
        "steps": log,
    });
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("fsi_model_problem_2_{nx}x{ny}_{multiplier:?}.json"));
    std::fs::write(&path, serde_json::to_string_pretty(&summary).unwrap()).unwrap();
    println!("wrote {}", path.display());
    assert!(consistency < 1e-6, "int lambda must equal the fluid's consistent-residual force: {consistency:e}");
    Outcome { force_rel, wss_rel: [e0, e1], trace_max }
}

#[test]
fn model_problem_2_paper_multiplier_force_and_free_trace_converge_shear_does_not() {
    let coarse = model_problem_2(64, 16, MultiplierSpace::P1Discontinuous);
    let fine = model_problem_2(128, 32, MultiplierSpace::P1Discontinuous);
    // Regression values (fdfsi at 2ad5061; README, cases/model-problem-2.toml and the table
    // above): force 2.6e-3 / 5.8e-4, shear stress 28 % / 12 % and 21 % / 12 % (the two faces, on
    // the two meshes), held to their printed digits.
    for (o, force, wss) in [(&coarse, 2.6e-3, [0.276, 0.118]), (&fine, 5.8e-4, [0.208, 0.118])] {
        assert!((o.force_rel - force).abs() < 0.05 * force, "force differs by {:.3e}, not {force:.1e}", o.force_rel);
        for side in 0..2 {
            assert!((o.wss_rel[side] - wss[side]).abs() < 0.006, "wall shear stress differences {:?}, not {wss:?}", o.wss_rel);
        }
    }
    // The force difference and the free trace's amplitude are O(h): halving h at least halves
    // them (measured 4.4x and 2.2x).
    assert!(fine.force_rel < 0.5 * coarse.force_rel, "force difference shrinks: {} -> {}", coarse.force_rel, fine.force_rel);
    assert!(fine.trace_max < 0.55 * coarse.trace_max, "free trace amplitude: {} -> {}", coarse.trace_max, fine.trace_max);
    // The shear difference, ~ 6 c / |facet|, is O(1): it stays between 5 % and 40 % (this is what
    // the trace-mode multiplier removes, see the next test).
    for o in [&coarse, &fine] {
        assert!(o.wss_rel.iter().all(|&e| (0.05..0.4).contains(&e)), "wall shear stress differences {:?}", o.wss_rel);
    }
}

/// README: with the trace-mode multiplier the force and the wall shear stress on both faces
/// match the Dirichlet twin to 2e-9 (measured at most 1.6e-9, the steady-state tolerance, on both
/// meshes); held at 2e-8. Independent reference: the twin, a separate pure-fluid solve.
#[test]
fn model_problem_2_trace_mode_multiplier_matches_the_dirichlet_twin_to_2e_9() {
    for (nx, ny) in [(64, 16), (128, 32)] {
        let o = model_problem_2(nx, ny, MultiplierSpace::P1DiscontinuousTraceMode);
        // The stiff plate is at rest: the fully controlled trace must vanish like the twin's
        // Dirichlet nodes (measured 3.6e-14 and 1.2e-13: round-off).
        assert!(o.trace_max < 1e-12, "{nx}x{ny}: |u_f| on gamma_f = {:e}", o.trace_max);
        assert!(o.force_rel < 2e-8, "{nx}x{ny}: force differs by {:.3e}", o.force_rel);
        for side in 0..2 {
            assert!(o.wss_rel[side] < 2e-8, "{nx}x{ny}: wall shear stress differs by {:?}", o.wss_rel);
        }
    }
}

/// The trace-mode multiplier on a tiny problem: the P1-discontinuous rows do not see the trace
/// function `1 - 6s + 6s^2` (vertex 1, mid-facet -1/2) and its own row does
/// (`int mode^2 = |gamma_f| / 5`); constants are reproduced; the assembled Jacobian equals a
/// finite difference of the residual.
#[test]
fn trace_mode_multiplier_sees_the_free_trace_function_and_has_a_consistent_jacobian() {
    let fluid_mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 4, 4, DiagonalPattern::Alternating);
    let plate = rotated(rectangle_quads(0.3, 0.7, 0.47, 0.53, 2, 1, GeometryOrder::Quadratic), 20.0, [0.5, 0.5]);
    let params = FluidParams {
        viscosity: 0.1,
        density: 1.0,
        inv_dt: 0.0,
        convection: true,
        convective_form: Default::default(),
        viscous_form: ViscousForm::Stress,
        stabilization: Default::default(),
    };
    let flow = FlowProblem {
        formulation: Formulation::Plane,
        params,
        body_force: None,
        dirichlet: vec![],
        traction: vec![],
        windkessel: vec![],
        backflow: Vec::new(),
        symmetry: Vec::new(),
        pin_pressure: false,
    };
    let mat: Arc<dyn SolidMaterial> = Arc::new(NeoHookeanMixed::incompressible(5.0));
    let solid = SolidProblem::new(Formulation::Plane, mat).with_displacement("bottom", &[0, 1], |_: &[f64; 2], _| [0.0; 2]);
    let problem = FsiProblem { fluid: flow, solid, surface: "top".into(), adapt: AdaptOptions::new(0.2) };
    let model = FsiModel::new(problem, &fluid_mesh, plate).unwrap().with_multiplier(MultiplierSpace::P1DiscontinuousTraceMode);
    let nus = model.solid.displacement_field().num_dofs();
    let mut seed = 17u64;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut base = vec![0.0; model.solid.num_dofs()];
    for v in base[..nus].iter_mut() {
        *v = 2e-3 * rnd();
    }
    let f = model.solid.deformation_gradients(&base).unwrap();
    let disc = FsiDiscretization::build(&model, &base, &Default::default()).unwrap();
    let ne = disc.coupling.num_elements();
    assert_eq!(disc.coupling.num_chains, 1);
    assert_eq!(disc.multiplier_dofs(), ne * 4 + 2);
    assert!(disc.inactive_multiplier_dofs.is_empty());
    // A fluid Dirichlet condition on the trace (here on gamma_f itself, component 0) removes the
    // free trace function of that component: its multiplier is fixed.
    let mut pinned = model.problem.clone();
    pinned.fluid.dirichlet.push(DirichletBc { boundary: "gamma_f".into(), components: vec![0], value: Arc::new(|_: &[f64; 2], _| [0.0; 2]) });
    let pinned = FsiModel::new(pinned, &fluid_mesh, model.solid.mesh.clone()).unwrap().with_multiplier(MultiplierSpace::P1DiscontinuousTraceMode);
    let pd = FsiDiscretization::build(&pinned, &base, &Default::default()).unwrap();
    assert_eq!(pd.inactive_multiplier_dofs, vec![pd.mode_multiplier_dof(0, 0)]);
    let mut fluid = model.problem.fluid.clone();
    let dt = 0.1;
    fluid.params.inv_dt = 1.0 / dt;
    let zero_old = vec![0.0; disc.fluid_dofs()];
    let input =
        StepInput { fluid: &fluid, time: dt, a: 1.0 / dt, u_old: &zero_old, solid_base: &base, solid_f: &f, solid_shift: None, solid_target: None };
    let (os, ol, n) = (disc.solid_offset(), disc.multiplier_offset(), disc.num_dofs());
    let vel = disc.flow.velocity_field().clone();
    let sf = model.solid.displacement_field().clone();
    let gamma_f = disc.adapted.gamma_f_measure();
    // The trace function: 1 at the gamma_f vertices, -1/2 at the mid-facet nodes (component 0).
    let mut x = vec![0.0; n];
    let near = |p: [f64; 2], q: [f64; 2]| (p[0] - q[0]).abs() + (p[1] - q[1]).abs() < 1e-12;
    for g in &disc.adapted.gamma_f {
        let [p0, p1] = g.vertices.map(|v| disc.flow.mesh.points[v]);
        let mid = [0.5 * (p0[0] + p1[0]), 0.5 * (p0[1] + p1[1])];
        for (node, &y) in disc.flow.velocity_nodes.iter().enumerate() {
            if near(y, p0) || near(y, p1) {
                x[vel.dof(node, 0)] = 1.0;
            } else if near(y, mid) {
                x[vel.dof(node, 0)] = -0.5;
            }
        }
    }
    let r = disc.residual(&model, &input, &x).unwrap();
    let p1_rows = (0..ne).flat_map(|e| (0..2).flat_map(move |k| (0..2).map(move |a| (e, k, a))));
    let worst_p1 = p1_rows.map(|(e, k, a)| r[disc.multiplier_dof(e, k, a)].abs()).fold(0.0, f64::max);
    let mode_row = r[disc.mode_multiplier_dof(0, 0)];
    println!("trace function: max |P1 rows| = {worst_p1:.2e}, mode row {mode_row:.6} vs |gamma_f| / 5 = {:.6}", gamma_f / 5.0);
    assert!(worst_p1 < 1e-14, "{worst_p1:e}");
    assert!((mode_row - gamma_f / 5.0).abs() < 1e-13);
    // u_f = c, u_s = 0: the mode rows vanish (the function integrates to 0 on every facet);
    // u_f = u_s = c: every constraint row vanishes.
    let c = [0.8, -1.3];
    let mut x = vec![0.0; n];
    for node in 0..vel.nodes.num_nodes {
        for a in 0..2 {
            x[vel.dof(node, a)] = c[a];
        }
    }
    let r = disc.residual(&model, &input, &x).unwrap();
    for a in 0..2 {
        assert!(r[disc.mode_multiplier_dof(0, a)].abs() < 1e-14);
    }
    for node in 0..sf.nodes.num_nodes {
        for a in 0..2 {
            x[os + sf.dof(node, a)] = c[a] * dt;
        }
    }
    let r = disc.residual(&model, &input, &x).unwrap();
    let worst = r[ol..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(worst < 1e-14, "{worst:e}");
    // Jacobian vs central differences at a random state.
    let u_old: Vec<f64> = (0..disc.fluid_dofs()).map(|_| rnd()).collect();
    let input = StepInput { u_old: &u_old, ..input };
    let mut x: Vec<f64> = (0..n).map(|_| rnd()).collect();
    for v in x[os..os + nus].iter_mut() {
        *v *= 2e-3;
    }
    let mut k = CscMatrix::zeros(disc.whole_pattern());
    let mut rhs = vec![0.0; n];
    disc.assemble(&model, &input, &x, &vec![false; n], &mut k, &mut rhs).unwrap();
    let mode_dofs: Vec<usize> = (0..2).map(|a| disc.mode_multiplier_dof(0, a)).collect();
    let (mut worst, mut mode_checked) = (0.0f64, 0);
    for j in 0..n {
        let h = 1e-6 * (1.0 + x[j].abs()) * if (os..os + nus).contains(&j) { 1e-2 } else { 1.0 };
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[j] += h;
        xm[j] -= h;
        let rp = disc.residual(&model, &input, &xp).unwrap();
        let rm = disc.residual(&model, &input, &xm).unwrap();
        for i in 0..n {
            let fd = (rp[i] - rm[i]) / (2.0 * h);
            let kij = k.get(i, j);
            assert!(fd == 0.0 || disc.whole_pattern().find(i, j).is_some(), "R[{i}] depends on x[{j}] outside the pattern");
            if (mode_dofs.contains(&i) || mode_dofs.contains(&j)) && kij != 0.0 {
                mode_checked += 1;
            }
            worst = worst.max((fd - kij).abs() / (1.0 + kij.abs()));
        }
    }
    println!("max |K - FD| / (1 + |K|) = {worst:.2e}; {mode_checked} nonzero trace-mode entries checked");
    assert!(mode_checked > 0);
    assert!(worst < 1e-5, "Jacobian mismatch {worst:.3e}");
}
