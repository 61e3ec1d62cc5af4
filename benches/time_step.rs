//! Benchmark of unsteady Navier-Stokes (P2+/P1disc, BDF2) at three mesh sizes in 2D and in 3D:
//!
//! * `newton_iteration`: assembly of the Jacobian and residual, numeric LU (symbolic
//!   factorisation cached, as in every step after the first) and the solve;
//! * `time_step`: one whole BDF2 step, Newton to convergence (2-3 iterations here).
//!
//! Systems, each taken after two steps from rest (so BDF2 is active and the convective terms are
//! nonzero), built from case files through the same code as `fdfsi run`:
//!
//! * 2D: `cases/cylinder-re100.toml` (Schaefer-Turek 2D-2, Re = 100, dt = 0.01) on the coarse
//!   and medium meshes of `meshes/` (36 596 and 145 157 dofs) and on the fine mesh (about 573k
//!   dofs) when `FDFSI_FINE_MESH` names it (the team's `shared/meshes/dfg2d-fine.msh`; it is
//!   not in the repository);
//! * 3D: the box [0,2] x [0,1] x [0,1] with parabolic inflow at x = 0, no-slip on y = 0, 1,
//!   slip on z = 0, 1 and a free outlet, Re = 100 on the unit height, dt = 0.01, on
//!   `2n x n x n` cubes of 6 tetrahedra each for `n` = 3, 4, 5 (see `box3d`).
//!
//! `FDFSI_BENCH_SKIP_LARGE=1` leaves out the 2D medium and the largest 3D system.
//!
//! Run: `cargo bench --bench time_step` (numbers in BENCHMARKS.md).

use criterion::{criterion_group, criterion_main, Criterion};
use fdfsi::case::Case;
use fdfsi::discretize::flow::{FlowDiscretization, FlowProblem};
use fdfsi::fem::gmsh::AnyMesh;
use fdfsi::fem::mesh::Mesh;
use fdfsi::setup::{build_mesh, flow_problem};
use fdfsi::solve::linear::{FaerLu, LinearSolver};
use fdfsi::solve::newton::NewtonOptions;
use fdfsi::time::{solve_unsteady_from, step_history, TimeLevel, TimeOptions};
use fdfsi_fem::sparse::CscMatrix;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// A system at time level `level` with solution `x`.
struct System<const D: usize> {
    disc: FlowDiscretization<D>,
    problem: FlowProblem<D>,
    options: TimeOptions,
    x: Vec<f64>,
    level: TimeLevel,
}

impl<const D: usize> System<D> {
    fn new(case: &Case, mesh: Mesh<D>, case_dir: &Path) -> Self {
        let problem = flow_problem(case, &mesh, case_dir).expect("flow problem");
        let disc = FlowDiscretization::build(mesh, case.physics.formulation).expect("discretisation");
        let ts = case.time.as_ref().expect("an unsteady case");
        let options = TimeOptions { dt: ts.dt, t_end: ts.end, scheme: ts.scheme, max_cuts: 0 };
        let mut s = System { x: vec![0.0; disc.num_dofs()], disc, problem, options, level: TimeLevel::default() };
        for _ in 0..2 {
            let (x, level) = s.step(&mut FaerLu::default());
            (s.x, s.level) = (x, level);
        }
        s
    }

    /// One step from the stored state; returns the new solution and level.
    fn step(&self, lu: &mut FaerLu) -> (Vec<f64>, TimeLevel) {
        let mut x = self.x.clone();
        let mut options = self.options.clone();
        options.t_end = (self.level.step + 1) as f64 * options.dt;
        let mut level = self.level.clone();
        solve_unsteady_from(&self.disc, &self.problem, &mut x, self.level.clone(), &options, lu, &NewtonOptions::default(), |_, _, l| {
            level = l.clone();
            Ok(())
        })
        .expect("time step");
        (x, level)
    }

    fn bench(&self, c: &mut Criterion, name: &str) {
        let n = self.disc.num_dofs();
        let t = (self.level.step + 1) as f64 * self.options.dt;
        let mut problem = self.problem.clone();
        let (inv_dt, u_star) = step_history(self.options.scheme, self.options.dt, 1.0, &self.x, self.level.x_prev.as_deref());
        problem.params.inv_dt = inv_dt;
        let mut constrained = vec![false; n];
        for (d, _) in self.disc.dirichlet_dofs(&problem, t).expect("dirichlet dofs") {
            constrained[d] = true;
        }
        let mut k = CscMatrix::zeros(self.disc.whole_pattern());
        let mut rhs = vec![0.0; n];
        let mut lu = FaerLu::default();
        let assemble = |k: &mut CscMatrix<'_>, rhs: &mut [f64]| {
            k.values.iter_mut().for_each(|v| *v = 0.0);
            rhs.iter_mut().for_each(|v| *v = 0.0);
            self.disc.assemble_system(&problem, &self.x, &u_star, t, &constrained, k, rhs).expect("assembly");
        };
        assemble(&mut k, &mut rhs);
        lu.factorize(&k).expect("first factorisation");
        eprintln!("{name}: {n} dofs, nnz {}, the step from t = {:.3} to {t:.3}", self.disc.whole_pattern().nnz(), self.level.time);
        let mut group = c.benchmark_group(name);
        group.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(20));
        group.bench_function("newton_iteration", |b| {
            b.iter(|| {
                assemble(&mut k, &mut rhs);
                lu.factorize(&k).expect("factorisation");
                lu.solve_in_place(&k, &mut rhs).expect("solve");
                black_box(&rhs);
            })
        });
        // The step's own solver keeps its symbolic factorisation between samples, as a run does
        // between steps on a fixed mesh.
        let mut step_lu = FaerLu::default();
        group.bench_function("time_step", |b| b.iter(|| black_box(self.step(&mut step_lu))));
        group.finish();
    }
}

fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("cases")
}

fn cylinder(c: &mut Criterion, name: &str, mesh_file: &Path) {
    let text = include_str!("../cases/cylinder-re100.toml").replace("../meshes/dfg2d-coarse.msh", &mesh_file.display().to_string());
    let case = Case::from_toml_str(&text, "cylinder-re100").expect("case");
    let AnyMesh::D2(mesh) = build_mesh(&case, &cases_dir()).expect("mesh") else { panic!("2D mesh expected") };
    System::<2>::new(&case, mesh, &cases_dir()).bench(c, name);
}

/// The 3D box case with `n` cells per unit length.
fn box3d(c: &mut Criterion, n: usize) {
    let text = format!(
        r#"title = "3D box, Re = 100"
[mesh]
kind = "box"
x = [0.0, 2.0]
y = [0.0, 1.0]
z = [0.0, 1.0]
n = [{}, {n}, {n}]
[physics]
formulation = "3d"
model = "navier-stokes"
[fluid]
density = 1.0
viscosity = 0.01
[time]
dt = 0.01
end = 1.0
scheme = "bdf2"
[[boundary]]
name = "xmin"
type = "velocity"
value = ["4*y*(1-y)", 0.0, 0.0]
time_function = {{ kind = "ramp", duration = 0.1 }}
[[boundary]]
name = "ymin"
type = "no-slip"
[[boundary]]
name = "ymax"
type = "no-slip"
[[boundary]]
name = "zmin"
type = "symmetry"
normal_axis = 2
[[boundary]]
name = "zmax"
type = "symmetry"
normal_axis = 2
[[boundary]]
name = "xmax"
type = "free"
"#,
        2 * n
    );
    let case = Case::from_toml_str(&text, "box3d").expect("case");
    let AnyMesh::D3(mesh) = build_mesh(&case, &cases_dir()).expect("mesh") else { panic!("3D mesh expected") };
    System::<3>::new(&case, mesh, &cases_dir()).bench(c, &format!("box3d-n{n}"));
}

fn benches(c: &mut Criterion) {
    let skip_large = std::env::var("FDFSI_BENCH_SKIP_LARGE").is_ok_and(|v| v == "1");
    let meshes = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
    cylinder(c, "st2d2-coarse", &meshes.join("dfg2d-coarse.msh"));
    if !skip_large {
        cylinder(c, "st2d2-medium", &meshes.join("dfg2d-medium.msh"));
    }
    if let Ok(fine) = std::env::var("FDFSI_FINE_MESH") {
        cylinder(c, "st2d2-fine", Path::new(&fine));
    }
    box3d(c, 3);
    box3d(c, 4);
    if !skip_large {
        box3d(c, 5);
    }
}

criterion_group!(time_step, benches);
criterion_main!(time_step);
