//! Benchmark of one Newton iteration of the steady Navier-Stokes solve (P2+/P1disc): assembly,
//! numeric LU (symbolic cached) and solve, through [`FaerLu`] as `solve_steady` uses it.
//!
//! Systems:
//!
//! * `st2d1-coarse`: Schaefer-Turek 2D-1 on `meshes/dfg2d-coarse.msh` (36 596 dofs);
//! * `st2d1-medium`: the same on `meshes/dfg2d-medium.msh` (145 157 dofs; skipped with
//!   `FDFSI_BENCH_SKIP_MEDIUM=1`);
//! * `stokes3d-box5`: the 3D Stokes verification problem on the unit cube, 5 cells per side.
//!
//! The 2D Jacobians are taken at the state after one Newton step from the Dirichlet data (a
//! nonzero velocity, so the convective terms are present). Per system criterion measures
//! `assembly`, `lu_numeric` (`FaerLu::factorize` with the symbolic factorisation cached) and
//! `lu_solve` (one `solve_in_place`, residual check and refinement included), and the sum of the
//! three as `newton_iteration`. Outside the timing it prints dofs, nnz, the factorisation in use
//! and its fill, and the first (symbolic + numeric) factorisation time.
//!
//! `FDFSI_BENCH_ORDERING=amd` selects the AMD ordering of the static LU instead of the default
//! nested dissection.
//!
//! Run: `CARGO_TARGET_DIR=/tmp/target-bench cargo bench --bench linear2d`.

use criterion::{criterion_group, criterion_main, Criterion};
use fdfsi::case::Case;
use fdfsi::discretize::flow::{FlowDiscretization, FlowProblem, SteadySystem};
use fdfsi::physics::fluid::Formulation;
use fdfsi::solve::linear::{FaerLu, FillOrdering, LinearSolver, LinearSolverOptions};
use fdfsi_fem::generate::box_tetrahedra;
use fdfsi_fem::gmsh::{read_msh, AnyMesh};
use fdfsi_fem::sparse::CscMatrix;
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

/// The solver: `FaerLu` with the ordering from `FDFSI_BENCH_ORDERING` (`nd`, the default, or
/// `amd`).
fn solver() -> FaerLu {
    let ordering = match std::env::var("FDFSI_BENCH_ORDERING").as_deref() {
        Ok("amd") => FillOrdering::Amd,
        Ok("nd") | Err(_) => FillOrdering::NestedDissection,
        Ok(other) => panic!("FDFSI_BENCH_ORDERING: expected nd or amd, got {other}"),
    };
    FaerLu::new(LinearSolverOptions { ordering, ..Default::default() })
}

/// One benchmarked system: discretisation, problem, state and reusable buffers.
struct System<const D: usize> {
    disc: FlowDiscretization<D>,
    problem: FlowProblem<D>,
    /// The iterate the Jacobian is taken at.
    x: Vec<f64>,
}

impl<const D: usize> System<D> {
    fn new(disc: FlowDiscretization<D>, problem: FlowProblem<D>, newton_steps: usize) -> Self {
        let (system, mut x) = SteadySystem::new(&disc, &problem).expect("dirichlet dofs");
        let mut k = CscMatrix::zeros(disc.whole_pattern());
        let mut rhs = vec![0.0; x.len()];
        let mut lu = solver();
        for _ in 0..newton_steps {
            system.assemble(&x, &mut k, &mut rhs).expect("assembly");
            lu.factorize(&k).expect("factorisation");
            lu.solve_in_place(&k, &mut rhs).expect("solve");
            x.iter_mut().zip(&rhs).for_each(|(a, b)| *a += b);
        }
        System { disc, problem, x }
    }

    fn bench(&self, c: &mut Criterion, name: &str) {
        let n = self.disc.num_dofs();
        let (system, _) = SteadySystem::new(&self.disc, &self.problem).expect("dirichlet dofs");
        let assemble = |k: &mut CscMatrix<'_>, rhs: &mut [f64]| system.assemble(&self.x, k, rhs).expect("assembly");
        let mut k = CscMatrix::zeros(self.disc.whole_pattern());
        let mut rhs = vec![0.0; n];
        assemble(&mut k, &mut rhs);
        let mut lu = solver();
        let t = Instant::now();
        lu.factorize(&k).expect("first factorisation");
        let first = t.elapsed();
        let mut buf = rhs.clone();
        let stats = lu.solve_in_place(&k, &mut buf).expect("solve");
        eprintln!(
            "[linear2d] {name}: dofs={n} nnz={} first_factorize(symbolic+numeric)={:.3}s residual={:.2e} refinements={} ; {}",
            self.disc.whole_pattern().nnz(),
            first.as_secs_f64(),
            stats.residual,
            stats.refinements,
            lu.describe()
        );

        let mut group = c.benchmark_group(name);
        group.sample_size(10);
        group.warm_up_time(Duration::from_millis(500));
        group.measurement_time(Duration::from_secs(5));
        group.bench_function("assembly", |b| b.iter(|| assemble(&mut k, &mut rhs)));
        group.bench_function("lu_numeric", |b| b.iter(|| lu.factorize(black_box(&k)).expect("factorisation")));
        group.bench_function("lu_solve", |b| {
            b.iter(|| {
                buf.copy_from_slice(&rhs);
                black_box(lu.solve_in_place(&k, &mut buf).expect("solve"));
            })
        });
        group.bench_function("newton_iteration", |b| {
            b.iter(|| {
                assemble(&mut k, &mut rhs);
                lu.factorize(&k).expect("factorisation");
                buf.copy_from_slice(&rhs);
                black_box(lu.solve_in_place(&k, &mut buf).expect("solve"));
            })
        });
        group.finish();
        assert_eq!(lu.symbolic_factorizations(), 1, "the symbolic factorisation must be reused");
    }
}

fn schaefer_turek(mesh_file: &str) -> System<2> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = Case::read(&root.join("cases/schaefer-turek-2d1.toml")).expect("case");
    let mesh = match read_msh(&root.join(mesh_file)).expect("mesh") {
        AnyMesh::D2(m) => m,
        AnyMesh::D3(_) => panic!("{mesh_file}: expected a 2D mesh"),
    };
    let problem = fdfsi::setup::flow_problem(&case, &mesh, &root.join("cases")).expect("problem");
    let disc = FlowDiscretization::build(mesh, Formulation::Plane).expect("discretisation");
    System::new(disc, problem, 1)
}

/// The `stokes-3d` verification problem (manufactured solution, velocity on five faces, traction
/// on `xmax`) on the unit cube with `n` cells per side.
fn stokes3d(n: usize) -> System<3> {
    let problem = fdfsi::verify::stokes_3d_problem();
    let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n, n, n);
    let disc = FlowDiscretization::build(mesh, Formulation::ThreeD).expect("discretisation");
    System::new(disc, problem, 0)
}

fn linear2d(c: &mut Criterion) {
    schaefer_turek("meshes/dfg2d-coarse.msh").bench(c, "st2d1-coarse");
    if std::env::var("FDFSI_BENCH_SKIP_MEDIUM").is_err() {
        schaefer_turek("meshes/dfg2d-medium.msh").bench(c, "st2d1-medium");
    }
    stokes3d(5).bench(c, "stokes3d-box5");
}

criterion_group!(benches, linear2d);
criterion_main!(benches);
