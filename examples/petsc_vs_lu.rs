//! PETSc + MUMPS against fdfsi's own LU on identical systems (the `petsc` feature): for each
//! system, the first factorisation (analysis + numeric), a second numeric factorisation of the
//! same pattern and one solve, by `FaerLu` (the direct solver of `method = "direct"`) and by
//! `PetscSolver` with its defaults (MUMPS), with the largest difference of the solutions.
//!
//! Systems: the Jacobian of Schaefer-Turek 2D-1 after one Newton step on `dfg2d-coarse.msh`
//! and `dfg2d-medium.msh` (P2+/P1disc, 36 596 and 145 157 unknowns) and the 3D Stokes
//! verification problem on `n^3` cubes for `n` in `FDFSI_PETSC_3D` (default `6,8,10`).
//!
//! Run: `cargo run --release --features petsc --example petsc_vs_lu`.

use fdfsi::case::Case;
use fdfsi::discretize::flow::{FlowDiscretization, FlowProblem, SteadySystem};
use fdfsi::physics::fluid::Formulation;
use fdfsi::solve::linear::{FaerLu, LinearSolver, LinearSolverOptions};
use fdfsi::solve::petsc::PetscSolver;
use fdfsi_fem::generate::box_tetrahedra;
use fdfsi_fem::gmsh::{read_msh, AnyMesh};
use fdfsi_fem::sparse::CscMatrix;
use std::path::Path;
use std::time::Instant;

/// Times of one solver on one system, in seconds, and its solution.
fn time(solver: &mut dyn LinearSolver, k: &CscMatrix<'_>, rhs: &[f64]) -> ([f64; 3], Vec<f64>) {
    let t = Instant::now();
    solver.factorize(k).expect("factorisation");
    let first = t.elapsed().as_secs_f64();
    let t = Instant::now();
    solver.factorize(k).expect("factorisation");
    let numeric = t.elapsed().as_secs_f64();
    let mut x = rhs.to_vec();
    let t = Instant::now();
    solver.solve_in_place(k, &mut x).expect("solve");
    ([first, numeric, t.elapsed().as_secs_f64()], x)
}

fn compare<const D: usize>(name: &str, disc: FlowDiscretization<D>, problem: FlowProblem<D>, newton_steps: usize) {
    let (system, mut x) = SteadySystem::new(&disc, &problem).expect("dirichlet dofs");
    let mut k = CscMatrix::zeros(disc.whole_pattern());
    let mut rhs = vec![0.0; x.len()];
    for _ in 0..newton_steps {
        system.assemble(&x, &mut k, &mut rhs).expect("assembly");
        let mut lu = FaerLu::new(LinearSolverOptions::default());
        lu.factorize(&k).expect("factorisation");
        lu.solve_in_place(&k, &mut rhs).expect("solve");
        x.iter_mut().zip(&rhs).for_each(|(a, b)| *a += b);
    }
    system.assemble(&x, &mut k, &mut rhs).expect("assembly");
    let (ours, x_ours) = time(&mut FaerLu::new(LinearSolverOptions::default()), &k, &rhs);
    let (petsc, x_petsc) = time(&mut PetscSolver::new("", 1e-8), &k, &rhs);
    let scale = x_ours.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = x_ours.iter().zip(&x_petsc).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    println!(
        "| {name} | {} | {} | {:.3} / {:.3} / {:.4} | {:.3} / {:.3} / {:.4} | {:.2} | {:.1e} |",
        x.len(),
        disc.whole_pattern().nnz(),
        ours[0],
        ours[1],
        ours[2],
        petsc[0],
        petsc[1],
        petsc[2],
        petsc[1] / ours[1],
        diff / scale
    );
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    println!("| system | unknowns | entries | fdfsi LU: first / numeric / solve (s) | PETSc + MUMPS: first / numeric / solve (s) | numeric ratio | difference |");
    println!("|---|---|---|---|---|---|---|");
    let case = Case::read(&root.join("cases/schaefer-turek-2d1.toml")).expect("case");
    for (name, file) in [("st2d1-coarse", "meshes/dfg2d-coarse.msh"), ("st2d1-medium", "meshes/dfg2d-medium.msh")] {
        let AnyMesh::D2(mesh) = read_msh(&root.join(file)).expect("mesh") else { panic!("{file}: a 2D mesh") };
        let problem = fdfsi::setup::flow_problem(&case, &mesh, &root.join("cases")).expect("problem");
        compare(name, FlowDiscretization::build(mesh, Formulation::Plane).expect("discretisation"), problem, 1);
    }
    let sizes = std::env::var("FDFSI_PETSC_3D").unwrap_or_else(|_| "6,8,10".into());
    for n in sizes.split(',').map(|s| s.trim().parse::<usize>().expect("FDFSI_PETSC_3D: sizes like 6,8,10")) {
        let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n, n, n);
        let disc = FlowDiscretization::build(mesh, Formulation::ThreeD).expect("discretisation");
        compare(&format!("stokes3d-box{n}"), disc, fdfsi::verify::stokes_3d_problem(), 0);
    }
}
