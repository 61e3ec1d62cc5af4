//! Fill, flops, time and memory of the static supernodal LU under one fill-reducing ordering.
//!
//! `cargo run --release --example lu_ordering -- SYSTEM ORDERING [REPS]`
//!
//! * `SYSTEM`: `coarse` / `medium` (Schaefer-Turek 2D-1 Jacobian after one Newton step on
//!   `meshes/dfg2d-*.msh`, as `benches/linear2d.rs`) or `boxN` (the 3D Stokes verification problem
//!   on the unit cube with N cells per side, as `benches/stokes3d.rs`), or `mtx:PATH` (a
//!   MatrixMarket `coordinate real general` file, e.g. `augmented.mtx` of
//!   `fdfsi run --export-system`, to set beside another solver's factorisation of the same file);
//! * `ORDERING`: `nd` (nested dissection) or `amd`;
//! * `REPS`: numeric factorisations timed after the first (default 3; min and median printed);
//!   0: the ordering and symbolic analysis only (fill and flops, no numeric factorisation).
//!
//! One system and ordering per process, so `VmHWM` (peak resident memory) is theirs alone.
use fdfsi::case::Case;
use fdfsi::discretize::flow::{FlowDiscretization, FlowProblem, SteadySystem};
use fdfsi::physics::fluid::Formulation;
use fdfsi::solve::linear::{FaerLu, FillOrdering, LinearSolver, LinearSolverOptions, LuMethod};
use fdfsi_fem::generate::box_tetrahedra;
use fdfsi_fem::gmsh::{read_msh, AnyMesh};
use fdfsi_fem::sparse::{CscMatrix, Pattern};
use std::path::Path;
use std::time::Instant;

/// CPU seconds of this process (all threads), from `/proc/self/stat` (10 ms resolution).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let fields: Vec<&str> = stat.rsplit(')').next().unwrap_or("").split_whitespace().collect();
    let tick = |i: usize| fields.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

fn run<const D: usize>(name: &str, disc: FlowDiscretization<D>, problem: FlowProblem<D>, newton_steps: usize, ordering: FillOrdering, reps: usize) {
    let n = disc.num_dofs();
    let (system, mut x) = SteadySystem::new(&disc, &problem).expect("dirichlet dofs");
    let mut k = CscMatrix::zeros(disc.whole_pattern());
    let mut rhs = vec![0.0; n];
    let assemble = |x: &[f64], k: &mut CscMatrix<'_>, rhs: &mut [f64]| system.assemble(x, k, rhs).expect("assembly");
    if reps == 0 {
        assemble(&x, &mut k, &mut rhs);
        let c0 = cpu_seconds();
        let s = FaerLu::analyse(&k, ordering).expect("analysis");
        let cpu = cpu_seconds() - c0;
        println!(
            "{name} {ordering:?} (analysis only): dofs={n} nnz(L+U)={} flops={:.4e} supernodes={} ordering={:.3}s symbolic={:.3}s symbolic_cpu={cpu:.2}s",
            s.nnz_lu, s.flops, s.supernodes, s.ordering_seconds, s.symbolic_seconds
        );
        return;
    }
    let opts = LinearSolverOptions { ordering, ..Default::default() };
    let mut lu = FaerLu::with_method(opts, LuMethod::Auto);
    assemble(&x, &mut k, &mut rhs);
    let t = Instant::now();
    lu.factorize(&k).expect("factorisation");
    let first = t.elapsed().as_secs_f64();
    for _ in 0..newton_steps {
        lu.solve_in_place(&k, &mut rhs).expect("solve");
        x.iter_mut().zip(&rhs).for_each(|(a, b)| *a += b);
        assemble(&x, &mut k, &mut rhs);
        lu.factorize(&k).expect("factorisation");
    }
    let mut times = Vec::new();
    let mut cpu = Vec::new();
    for _ in 0..reps {
        let (t, c) = (Instant::now(), cpu_seconds());
        lu.factorize(&k).expect("factorisation");
        times.push(t.elapsed().as_secs_f64());
        cpu.push(cpu_seconds() - c);
    }
    times.sort_by(f64::total_cmp);
    cpu.sort_by(f64::total_cmp);
    let mut buf = rhs.clone();
    let t = Instant::now();
    let stats = lu.solve_in_place(&k, &mut buf).expect("solve");
    let solve = t.elapsed().as_secs_f64();
    assert_eq!(lu.symbolic_factorizations(), 1);
    let fs = lu.factor_stats();
    println!(
        "{name} {ordering:?}: dofs={n} nnz(A)={} nnz(L+U)={} fill={:.1} flops={:.3e} supernodes={} ordering={:.3}s symbolic={:.3}s \
         first_factorize={:.3}s numeric(min/median of {reps})={:.3}/{:.3}s numeric_cpu(min)={:.2}s solve={:.3}s residual={:.1e} refinements={} VmHWM={:.1}MiB [{}]",
        disc.whole_pattern().nnz(),
        fs.as_ref().map_or(0, |s| s.nnz_lu),
        fs.as_ref().map_or(0.0, |s| s.nnz_lu as f64 / disc.whole_pattern().nnz() as f64),
        fs.as_ref().map_or(0.0, |s| s.flops),
        fs.as_ref().map_or(0, |s| s.supernodes),
        fs.as_ref().map_or(0.0, |s| s.ordering_seconds),
        fs.as_ref().map_or(0.0, |s| s.symbolic_seconds),
        first,
        times.first().copied().unwrap_or(f64::NAN),
        times.get(times.len() / 2).copied().unwrap_or(f64::NAN),
        cpu.first().copied().unwrap_or(f64::NAN),
        solve,
        stats.residual,
        stats.refinements,
        fdfsi::run::peak_resident_mib().unwrap_or(0.0),
        lu.describe(),
    );
}

/// A MatrixMarket `coordinate real general` square matrix, its pattern made structurally
/// symmetric (explicit zeros where only the transposed entry is stored), as the static LU needs.
fn read_matrix_market(path: &str) -> (Pattern, Vec<f64>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let banner = text.lines().next().unwrap_or("").to_lowercase();
    assert!(banner.starts_with("%%matrixmarket matrix coordinate real general"), "{path}: not a coordinate real general matrix: {banner}");
    let mut lines = text.lines().filter(|l| !l.starts_with('%'));
    let size: Vec<usize> = lines.next().expect("size line").split_whitespace().map(|v| v.parse().expect("size")).collect();
    let n = size[0];
    assert_eq!(size[0], size[1], "{path}: a square matrix");
    let mut entries: Vec<(usize, usize, f64)> = Vec::with_capacity(2 * size[2]);
    for l in lines {
        let f: Vec<&str> = l.split_whitespace().collect();
        let (i, j, v) = (f[0].parse::<usize>().expect("row") - 1, f[1].parse::<usize>().expect("column") - 1, f[2].parse().expect("value"));
        entries.push((j, i, v));
        entries.push((i, j, 0.0));
    }
    entries.sort_by_key(|&(j, i, _)| (j, i));
    let (mut col_ptr, mut row_idx, mut values) = (vec![0; n + 1], Vec::new(), Vec::<f64>::new());
    let mut last = None;
    for (j, i, v) in entries {
        if last == Some((j, i)) {
            *values.last_mut().expect("entry") += v;
        } else {
            row_idx.push(i);
            values.push(v);
            last = Some((j, i));
        }
        col_ptr[j + 1] = row_idx.len();
    }
    for j in 0..n {
        col_ptr[j + 1] = col_ptr[j + 1].max(col_ptr[j]);
    }
    (Pattern { n, col_ptr, row_idx }, values)
}

/// Analysis, first and repeated numeric factorisations and one solve of the matrix in `path`.
fn run_file(path: &str, ordering: FillOrdering, reps: usize) {
    let (pattern, values) = read_matrix_market(path);
    let k = CscMatrix { pattern: &pattern, values };
    if reps == 0 {
        let s = FaerLu::analyse(&k, ordering).expect("analysis");
        println!(
            "{path} {ordering:?} (analysis only): n={} nnz(A)={} nnz(L+U)={} flops={:.4e} supernodes={} ordering={:.3}s symbolic={:.3}s",
            pattern.n,
            pattern.nnz(),
            s.nnz_lu,
            s.flops,
            s.supernodes,
            s.ordering_seconds,
            s.symbolic_seconds
        );
        return;
    }
    let mut lu = FaerLu::with_method(LinearSolverOptions { ordering, ..Default::default() }, LuMethod::Auto);
    let t = Instant::now();
    lu.factorize(&k).expect("factorisation");
    let first = t.elapsed().as_secs_f64();
    let mut times: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            lu.factorize(&k).expect("factorisation");
            t.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let mut rhs = vec![1.0; pattern.n];
    let t = Instant::now();
    // An ill-conditioned block (an augmented one with a large gamma) may miss the solver's
    // accuracy check: its residual is reported, as lu_mumps.py reports MUMPS's.
    let residual = match lu.solve_in_place(&k, &mut rhs) {
        Ok(stats) => stats.residual,
        Err(fdfsi::solve::linear::LinearSolveError::Inaccurate { residual, .. }) => residual,
        Err(e) => panic!("solve: {e}"),
    };
    let solve = t.elapsed().as_secs_f64();
    let fs = lu.factor_stats().expect("factorised");
    println!(
        "{path} {ordering:?}: n={} nnz(A)={} nnz(L+U)={} flops={:.3e} first_factorize={first:.3}s numeric(min/median of {reps})={:.3}/{:.3}s solve={solve:.3}s \
         residual={:.1e} VmHWM={:.1}MiB [{}]",
        pattern.n,
        pattern.nnz(),
        fs.nnz_lu,
        fs.flops,
        times.first().copied().unwrap_or(f64::NAN),
        times.get(times.len() / 2).copied().unwrap_or(f64::NAN),
        residual,
        fdfsi::run::peak_resident_mib().unwrap_or(0.0),
        lu.describe(),
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let system = args.get(1).map(String::as_str).unwrap_or("coarse");
    let ordering = match args.get(2).map(String::as_str).unwrap_or("nd") {
        "amd" => FillOrdering::Amd,
        "nd" => FillOrdering::NestedDissection,
        o => panic!("ordering: nd or amd, got {o}"),
    };
    let reps: usize = args.get(3).map(|r| r.parse().expect("REPS")).unwrap_or(3);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    if let Some(path) = system.strip_prefix("mtx:") {
        run_file(path, ordering, reps);
    } else if let Some(cells) = system.strip_prefix("box") {
        let nc: usize = cells.parse().expect("boxN");
        let problem = fdfsi::verify::stokes_3d_problem();
        let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, nc, nc, nc);
        let disc = FlowDiscretization::build(mesh, Formulation::ThreeD).expect("discretisation");
        run(system, disc, problem, 0, ordering, reps);
    } else {
        let file = format!("meshes/dfg2d-{system}.msh");
        let case = Case::read(&root.join("cases/schaefer-turek-2d1.toml")).expect("case");
        let mesh = match read_msh(&root.join(&file)).expect("mesh") {
            AnyMesh::D2(m) => m,
            AnyMesh::D3(_) => panic!("{file}: expected a 2D mesh"),
        };
        let problem = fdfsi::setup::flow_problem(&case, &mesh, &root.join("cases")).expect("problem");
        let disc = FlowDiscretization::build(mesh, Formulation::Plane).expect("discretisation");
        run(system, disc, problem, 1, ordering, reps);
    }
}
