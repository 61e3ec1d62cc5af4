//! Benchmark of the 3D Stokes problem (P2+/P1disc, 15-node tetrahedra) on the unit cube.
//!
//! Per mesh size (`box_tetrahedra` with `n` cells per side, sizes in increasing order) criterion
//! measures separately:
//!
//! * `assembly/n`: zeroing the reused matrix and right-hand side plus
//!   [`FlowDiscretization::assemble_system`] (Jacobian and residual);
//! * `lu_numeric/n`: [`FaerLu::factorize`] after a first call, so only the numeric factorisation
//!   runs (the symbolic one is cached; asserted through `symbolic_factorizations() == 1`);
//! * `lu_solve/n`: one [`LinearSolver::solve_in_place`] with that factorisation (includes the
//!   residual check and iterative refinement the solver does).
//!
//! Outside criterion's timing, once per size, it prints to stderr: dofs, nnz of the pattern, the
//! factorisation in use and its fill (`FaerLu::describe`), the time of the first `factorize` of a
//! fresh solver (symbolic + numeric) and of the second (numeric only), whose difference is the
//! symbolic factorisation time, the discretisation setup time, the solution error against the
//! manufactured solution (a sanity check that the benchmarked system is the right one) and the
//! peak resident memory `VmHWM` from `/proc/self/status`. `VmHWM` is process-wide and monotone,
//! so the sizes run in increasing order and the growth per size is reported.
//!
//! The LU method is `FaerLu`'s default (`LuMethod::Auto`); `FDFSI_BENCH_LU=pivoting` selects
//! faer's partial-pivoting LU (`LuMethod::Pivoting`, criterion group `stokes3d-pivoting`), for
//! which faer's `factorize_symbolic_lu` is also timed on its own.
//!
//! `FDFSI_BENCH_ORDERING=amd` selects the AMD ordering of the static LU instead of the default
//! nested dissection.
//!
//! Run: `CARGO_TARGET_DIR=/tmp/target-bench cargo bench --bench stokes3d`.
//! Sizes can be overridden with `FDFSI_BENCH_SIZES=4,6,8` (always in increasing order).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use faer::sparse::linalg::lu::factorize_symbolic_lu;
use faer::sparse::SymbolicSparseColMatRef;
use fdfsi::discretize::flow::{flow_errors, ExactFlow, FlowDiscretization, SteadySystem};
use fdfsi::physics::fluid::Formulation;
use fdfsi::run::peak_resident_mib;
use fdfsi::solve::linear::{FaerLu, FillOrdering, LinearSolver, LinearSolverOptions, LuMethod};
use fdfsi::verify::manufactured::{Manufactured, Stokes3d};
use fdfsi_fem::generate::box_tetrahedra;
use fdfsi_fem::sparse::{CscMatrix, Pattern};
use std::hint::black_box;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Default mesh sizes (cells per side of the unit cube). With the default static supernodal LU one
/// numeric factorisation at `n = 8` (55 827 dofs) takes about 19 s on the 2-core reference machine,
/// so the whole benchmark runs in about 5 minutes (BENCHMARKS.md). faer's partial-pivoting LU
/// took 33-49 s there: use `FDFSI_BENCH_SIZES=3,5,7` with `FDFSI_BENCH_LU=pivoting`.
const SIZES: [usize; 3] = [4, 6, 8];

/// The LU method from `FDFSI_BENCH_LU` (`auto`, the default, or `pivoting`).
fn lu_method() -> LuMethod {
    match std::env::var("FDFSI_BENCH_LU").as_deref() {
        Ok("pivoting") => LuMethod::Pivoting,
        Ok("auto") | Err(_) => LuMethod::Auto,
        Ok(other) => panic!("FDFSI_BENCH_LU: expected auto or pivoting, got {other}"),
    }
}

/// The fill-reducing ordering of the static LU from `FDFSI_BENCH_ORDERING` (`nd`, the default,
/// or `amd`).
fn ordering() -> FillOrdering {
    match std::env::var("FDFSI_BENCH_ORDERING").as_deref() {
        Ok("amd") => FillOrdering::Amd,
        Ok("nd") | Err(_) => FillOrdering::NestedDissection,
        Ok(other) => panic!("FDFSI_BENCH_ORDERING: expected nd or amd, got {other}"),
    }
}

fn sizes() -> Vec<usize> {
    match std::env::var("FDFSI_BENCH_SIZES") {
        Ok(s) => s.split(',').map(|t| t.trim().parse().expect("FDFSI_BENCH_SIZES: comma-separated integers")).collect(),
        Err(_) => SIZES.to_vec(),
    }
}

/// Peak resident set size (`VmHWM`) of this process in MiB (0 where not reported).
fn vm_hwm_mib() -> f64 {
    peak_resident_mib().unwrap_or(0.0)
}

/// faer's partial-pivoting symbolic LU of `pattern`, as `FaerLu` builds it for
/// `LuMethod::Pivoting`; returns the time.
fn time_faer_symbolic(pattern: &Pattern) -> Duration {
    // SAFETY: `Pattern` keeps sorted, in-range row indices and monotone column pointers (the same
    // view `FaerLu` hands to faer).
    let sym = unsafe { SymbolicSparseColMatRef::new_unchecked(pattern.n, pattern.n, &pattern.col_ptr, None, &pattern.row_idx) };
    let t = Instant::now();
    let s = factorize_symbolic_lu(sym, Default::default()).expect("symbolic LU");
    let dt = t.elapsed();
    drop(black_box(s));
    dt
}

fn stokes3d(c: &mut Criterion) {
    let exact = Arc::new(Stokes3d { eta: 1.0 });
    let problem = fdfsi::verify::stokes_3d_problem();
    let method = lu_method();
    let mut group = c.benchmark_group(if method == LuMethod::Pivoting { "stokes3d-pivoting" } else { "stokes3d" });
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(500));
    group.measurement_time(Duration::from_secs(3));

    let start_hwm = vm_hwm_mib();
    eprintln!("[stokes3d] LU method {method:?}; VmHWM at start: {:.1} MiB", start_hwm);
    let mut prev_hwm = start_hwm;
    for n in sizes() {
        let hwm_before = vm_hwm_mib();
        // --- Setup (not timed by criterion) ---
        let t = Instant::now();
        let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n, n, n);
        let cells = mesh.num_cells();
        let disc = FlowDiscretization::build(mesh, Formulation::ThreeD).expect("discretisation");
        let setup = t.elapsed();
        let ndofs = disc.num_dofs();
        let nnz = disc.whole_pattern().nnz();

        let (system, x) = SteadySystem::new(&disc, &problem).expect("dirichlet dofs");
        let mut k = CscMatrix::zeros(disc.whole_pattern());
        let mut rhs = vec![0.0; ndofs];

        let t = Instant::now();
        system.assemble(&x, &mut k, &mut rhs).expect("assembly");
        let first_assembly = t.elapsed();

        let faer_symbolic = if method == LuMethod::Pivoting {
            let t: Vec<Duration> = (0..3).map(|_| time_faer_symbolic(disc.whole_pattern())).collect();
            format!(" faer_symbolic_lu(min of 3)={:.3}s", t.iter().min().copied().unwrap_or_default().as_secs_f64())
        } else {
            String::new()
        };

        let mut lu = FaerLu::with_method(LinearSolverOptions { ordering: ordering(), ..Default::default() }, method);
        let t = Instant::now();
        lu.factorize(&k).expect("first factorisation");
        let first_factorize = t.elapsed();
        let t = Instant::now();
        lu.factorize(&k).expect("second factorisation");
        let second_factorize = t.elapsed();
        assert_eq!(lu.symbolic_factorizations(), 1);
        let symbolic = first_factorize.saturating_sub(second_factorize);

        // Stokes is linear: one Newton step from x (Dirichlet values set) is the solution.
        let mut dx = rhs.clone();
        let t = Instant::now();
        let stats = lu.solve_in_place(&k, &mut dx).expect("solve");
        let first_solve = t.elapsed();
        let sol: Vec<f64> = x.iter().zip(&dx).map(|(a, b)| a + b).collect();
        let (u, g, p) = (|x: &[f64; 3]| exact.velocity(x), |x: &[f64; 3]| exact.gradient(x), |x: &[f64; 3]| exact.pressure(x));
        let errs = flow_errors(&disc, Formulation::ThreeD, &sol, &ExactFlow { velocity: &u, gradient: &g, pressure: &p }, 8).expect("errors");
        let hwm_setup = vm_hwm_mib();

        eprintln!(
            "[stokes3d] n={n}: cells={cells} dofs={ndofs} nnz={nnz} (nnz/dof {:.1}) constrained={} setup(build)={:.3}s \
             first_assembly={:.3}s first_factorize(symbolic+numeric)={:.3}s second_factorize(numeric)={:.3}s \
             symbolic(first-second)={:.3}s{faer_symbolic} first_solve={:.3}s residual={:.2e} refinements={} \
             |u-u_h|_L2={:.3e} |p-p_h|_L2={:.3e} lu=[{}]",
            nnz as f64 / ndofs as f64,
            system.constrained.iter().filter(|&&c| c).count(),
            setup.as_secs_f64(),
            first_assembly.as_secs_f64(),
            first_factorize.as_secs_f64(),
            second_factorize.as_secs_f64(),
            symbolic.as_secs_f64(),
            first_solve.as_secs_f64(),
            stats.residual,
            stats.refinements,
            errs.velocity_l2,
            errs.pressure_l2,
            lu.describe(),
        );
        eprintln!(
            "[stokes3d] n={n}: VmHWM before={:.1} MiB, after setup+assembly+first LU+solve={:.1} MiB (growth {:.1} MiB)",
            hwm_before,
            hwm_setup,
            (hwm_setup - hwm_before).max(0.0),
        );

        // --- (a) assembly into the reused matrix, zeroed inside the iteration ---
        group.bench_with_input(BenchmarkId::new("assembly", n), &n, |b, _| {
            b.iter(|| {
                system.assemble(&x, &mut k, &mut rhs).expect("assembly");
                black_box(&k.values);
            })
        });

        // --- (b) numeric LU (symbolic cached) ---
        group.bench_with_input(BenchmarkId::new("lu_numeric", n), &n, |b, _| b.iter(|| lu.factorize(black_box(&k)).expect("factorisation")));
        assert_eq!(lu.symbolic_factorizations(), 1, "the symbolic factorisation must be reused");

        // --- (c) one solve with the factorisation ---
        let mut buf = vec![0.0; ndofs];
        group.bench_with_input(BenchmarkId::new("lu_solve", n), &n, |b, _| {
            b.iter(|| {
                buf.copy_from_slice(&rhs);
                black_box(lu.solve_in_place(&k, &mut buf).expect("solve"));
            })
        });

        let hwm_after = vm_hwm_mib();
        eprintln!(
            "[stokes3d] n={n}: symbolic_factorizations={} ; VmHWM after the benchmark loops={:.1} MiB \
             (growth over previous size's peak {:.1} MiB)",
            lu.symbolic_factorizations(),
            hwm_after,
            (hwm_after - prev_hwm).max(0.0),
        );
        prev_hwm = hwm_after;
    }
    group.finish();
}

criterion_group!(benches, stokes3d);
criterion_main!(benches);
