//! Cost of a steady 3D Navier-Stokes solve against the number of unknowns: the lid-driven cavity
//! in the unit cube at Re = 100 (lid `z = 1` moving with unit speed along `x`, no slip elsewhere,
//! the pressure pinned in cell 0), P2+/P1disc on `box_tetrahedra` with `n` cells per side, from
//! rest to `|R| <= 1e-10`.
//!
//! `cargo run --release --example growth3d -- N [al|direct] [stokes|navier-stokes] [REFACTOR]
//! [schur|primal]` (`stokes`: without convection, the linear Stokes problem; `REFACTOR`: the AL solver's
//! `refactor_iterations`, default 0; `schur|primal`: its `boundary` groups, default `schur`, the
//! 3D default of the case files)
//!
//! One size per process, so that the peak resident memory (`VmHWM`) is that size's alone; prints
//! one JSON line: unknowns, Newton and Krylov iterations, the phase times of the Newton solve,
//! the LU's fill and flops, and the peak memory. BENCHMARKS.md ("3D growth") fits exponents to
//! a series of sizes.
use fdfsi::discretize::flow::{solve_steady, DirichletBc, FlowDiscretization, FlowProblem};
use fdfsi::physics::fluid::{FluidParams, Formulation};
use fdfsi::solve::augmented::{AlOptions, AugmentedLagrangian, Placement};
use fdfsi::solve::linear::{FaerLu, LinearSolver};
use fdfsi::solve::newton::NewtonOptions;
use fdfsi_fem::generate::box_tetrahedra;
use std::sync::Arc;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map(|v| v.parse().expect("N: cells per side")).unwrap_or(4);
    let method = if args.get(2).map(String::as_str) == Some("direct") { "direct" } else { "al" };
    let convection = args.get(3).map(String::as_str) != Some("stokes");
    let refactor_iterations: usize = args.get(4).map(|v| v.parse().expect("REFACTOR: Krylov iterations")).unwrap_or(0);
    let boundary = if args.get(5).map(String::as_str) == Some("primal") { Placement::Primal } else { Placement::Schur };
    let t = Instant::now();
    let disc = FlowDiscretization::build(box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n, n, n), Formulation::ThreeD).expect("discretisation");
    let setup = t.elapsed().as_secs_f64();
    let wall = |name: &str, u: f64| DirichletBc::<3> { boundary: name.into(), components: vec![0, 1, 2], value: Arc::new(move |_, _| [u, 0.0, 0.0]) };
    let problem = FlowProblem {
        formulation: Formulation::ThreeD,
        params: FluidParams {
            viscosity: 0.01,
            density: 1.0,
            inv_dt: 0.0,
            convection,
            convective_form: Default::default(),
            viscous_form: Default::default(),
            stabilization: Default::default(),
        },
        body_force: None,
        dirichlet: ["xmin", "xmax", "ymin", "ymax", "zmin"].iter().map(|b| wall(b, 0.0)).chain([wall("zmax", 1.0)]).collect(),
        traction: vec![],
        pin_pressure: true,
        windkessel: Vec::new(),
        backflow: Vec::new(),
        symmetry: Vec::new(),
    };
    let (mut al, mut lu) = (AugmentedLagrangian::new(AlOptions { refactor_iterations, boundary, ..Default::default() }), FaerLu::default());
    let solver: &mut dyn LinearSolver = if method == "direct" { &mut lu } else { &mut al };
    let t = Instant::now();
    let sol = solve_steady(&disc, &problem, solver, &NewtonOptions::default()).expect("Newton solve");
    let total = t.elapsed().as_secs_f64();
    let stats = if method == "direct" { lu.factor_stats() } else { al.factor_stats() };
    let r = &sol.newton;
    println!(
        "{{\"n\": {n}, \"method\": \"{method}\", \"unknowns\": {}, \"convection\": {convection}, \"refactor\": {refactor_iterations}, \"boundary\": \"{boundary:?}\", \"newton\": {}, \"krylov\": {:?}, \"setup_s\": {setup:.3}, \
         \"solve_s\": {total:.3}, \"assemble_s\": {:.3}, \"factorize_s\": {:.3}, \"solve_phase_s\": {:.3}, \"lu_entries\": {}, \"lu_flops\": {:.4e}, \
         \"symbolic_s\": {:.3}, \"peak_mib\": {:.0}}}",
        disc.num_dofs(),
        r.iterations,
        r.krylov_iterations,
        r.assemble_seconds,
        r.factorize_seconds,
        r.solve_seconds,
        stats.as_ref().map_or(0, |s| s.nnz_lu),
        stats.as_ref().map_or(0.0, |s| s.flops),
        stats.as_ref().map_or(0.0, |s| s.symbolic_seconds),
        fdfsi::run::peak_resident_mib().unwrap_or(0.0),
    );
}
