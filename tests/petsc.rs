//! The `petsc` feature's solver against fdfsi's own factorisation on identical systems
//! (`cargo test --release --features petsc --test petsc`; needs the system's PETSc).
#![cfg(feature = "petsc")]

use fdfsi::case::Case;
use fdfsi::discretize::flow::{solve_steady, Entries, FlowDiscretization, FlowProblem, SteadySystem};
use fdfsi::physics::fluid::Formulation;
use fdfsi::solve::linear::{FaerLu, LinearSolveError, LinearSolver, LinearSolverOptions};
use fdfsi::solve::petsc::PetscSolver;
use fdfsi_fem::generate::box_tetrahedra;
use fdfsi_fem::gmsh::{read_msh, AnyMesh};
use fdfsi_fem::sparse::CscMatrix;
use std::path::Path;

/// Two Newton iterations of the steady problem on `disc`, each linear system solved by fdfsi's
/// LU and by `petsc`: the solutions agree to `tol` (relative to their largest entry), PETSc's
/// residual is below 1e-10, and the second system (new values, same pattern) reuses the first
/// one's set-up (one symbolic factorisation).
fn compare<const D: usize>(label: &str, disc: &FlowDiscretization<D>, problem: &FlowProblem<D>, petsc: &mut PetscSolver, tol: f64) -> usize {
    let (system, mut x) = SteadySystem::new(disc, problem).expect("dirichlet dofs");
    let mut k = CscMatrix::zeros(disc.whole_pattern());
    let mut rhs = vec![0.0; x.len()];
    let mut lu = FaerLu::new(LinearSolverOptions::default());
    let mut iterations = 0;
    for newton in 0..2 {
        system.assemble(&x, &mut k, &mut rhs).expect("assembly");
        lu.factorize(&k).unwrap();
        let mut ours = rhs.clone();
        lu.solve_in_place(&k, &mut ours).unwrap();
        petsc.factorize(&k).unwrap_or_else(|e| panic!("{label}: {e}"));
        let mut theirs = rhs.clone();
        let stats = petsc.solve_in_place(&k, &mut theirs).unwrap_or_else(|e| panic!("{label}: {e}"));
        let scale = ours.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = ours.iter().zip(&theirs).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        println!("{label}, Newton {newton}: {} unknowns, max difference {:.2e} of {scale:.2e}, PETSc residual {:.2e}", x.len(), diff, stats.residual);
        assert!(diff <= tol * scale, "{label}: the solutions differ by {diff:e} (largest entry {scale:e})");
        assert!(stats.residual < 1e-10, "{label}: residual {}", stats.residual);
        iterations += stats.krylov_iterations;
        x.iter_mut().zip(&ours).for_each(|(a, b)| *a += b);
    }
    assert_eq!(petsc.symbolic_factorizations(), 1, "{label}: one set-up per pattern");
    iterations
}

/// Schaefer-Turek 2D-1's case, discretisation (P2+/P1disc, 36 596 unknowns) and problem on the
/// coarse mesh.
fn schaefer_turek_coarse() -> (Case, FlowDiscretization<2>, FlowProblem<2>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = Case::read(&root.join("cases/schaefer-turek-2d1.toml")).unwrap();
    let AnyMesh::D2(mesh) = read_msh(&root.join("meshes/dfg2d-coarse.msh")).unwrap() else { panic!("a 2D mesh") };
    let problem = fdfsi::setup::flow_problem(&case, &mesh, &root.join("cases")).unwrap();
    (case, FlowDiscretization::build(mesh, Formulation::Plane).unwrap(), problem)
}

/// Schaefer-Turek 2D-1 (Navier-Stokes, P2+/P1disc, 36 596 unknowns) and the 3D Stokes
/// verification problem (4^3 cubes): MUMPS through PETSc gives fdfsi's solutions; a Krylov
/// method chosen by options (GMRES preconditioned by MUMPS's LU) too, iterating. Each solver
/// sees its own options although they share PETSc's process-wide database with the other
/// tests' solvers, which run on other threads meanwhile.
#[test]
fn petsc_solves_the_systems_fdfsi_factorises() {
    let (_, disc, problem) = schaefer_turek_coarse();
    let direct = compare("Schaefer-Turek 2D-1, MUMPS", &disc, &problem, &mut PetscSolver::new("", 1e-8), 1e-9);
    assert_eq!(direct, 0, "a direct solve reports no Krylov iterations");
    let gmres = "-fdfsi_ksp_type gmres -fdfsi_ksp_rtol 1e-13";
    let krylov = compare("Schaefer-Turek 2D-1, GMRES + MUMPS", &disc, &problem, &mut PetscSolver::new(gmres, 1e-8), 1e-9);
    assert!(krylov >= 2, "GMRES iterates: {krylov}");
    let problem = fdfsi::verify::stokes_3d_problem();
    let disc = FlowDiscretization::build(box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 4, 4, 4), Formulation::ThreeD).unwrap();
    compare("3D Stokes, MUMPS", &disc, &problem, &mut PetscSolver::new("", 1e-8), 1e-9);
}

/// With `-fdfsi_pc_type fieldsplit` the preconditioner gets the system's two fields, primal and
/// multiplier, from its saddle-point split (`solve::petsc::FIELDS`; without them PETSc refuses
/// a field split of a matrix with no block size): a Schur-complement factorisation (the velocity
/// block by MUMPS, the Schur complement `-B A^-1 B'` by GMRES to 1e-6, preconditioned by an LU of
/// `selfp`, `-B diag(A)^-1 B'`) inside FGMRES solves Schaefer-Turek 2D-1's Jacobians to fdfsi's
/// LU solutions.
#[test]
fn a_fieldsplit_preconditioner_gets_the_saddle_point_fields() {
    let (_, disc, problem) = schaefer_turek_coarse();
    let options = "-fdfsi_ksp_type fgmres -fdfsi_ksp_rtol 1e-12 -fdfsi_ksp_max_it 50 -fdfsi_pc_type fieldsplit \
        -fdfsi_pc_fieldsplit_type schur -fdfsi_pc_fieldsplit_schur_fact_type full -fdfsi_pc_fieldsplit_schur_precondition selfp \
        -fdfsi_fieldsplit_primal_ksp_type preonly -fdfsi_fieldsplit_primal_pc_type lu -fdfsi_fieldsplit_primal_pc_factor_mat_solver_type mumps \
        -fdfsi_fieldsplit_multiplier_ksp_type gmres -fdfsi_fieldsplit_multiplier_ksp_rtol 1e-6 -fdfsi_fieldsplit_multiplier_ksp_gmres_restart 200 \
        -fdfsi_fieldsplit_multiplier_pc_type lu";
    let mut solver = PetscSolver::new(options, 1e-8);
    let mut unsplit = PetscSolver::new(options, 1e-8);
    let mut k = CscMatrix::zeros(disc.whole_pattern());
    let (system, x) = SteadySystem::new(&disc, &problem).unwrap();
    let mut rhs = vec![0.0; x.len()];
    system.assemble(&x, &mut k, &mut rhs).unwrap();
    let e = unsplit.factorize(&k).unwrap_err();
    println!("no split: {e}");
    solver.set_split(disc.saddle_point_split(Formulation::Plane).unwrap());
    let iterations = compare("Schaefer-Turek 2D-1, FGMRES + Schur field split", &disc, &problem, &mut solver, 1e-8);
    assert!(iterations >= 2, "the field split iterates: {iterations}");
}

/// The augmented-Lagrangian preconditioner through PETSc (a shell applying `T`, then the field
/// split of `T K`, `solve::augmented::TransformedSystem`) solves Schaefer-Turek 2D-1's Jacobians
/// to fdfsi's LU solutions in a few FGMRES iterations, as fdfsi's own AL does (3-4 per Newton
/// step on this mesh, BENCHMARKS.md).
#[test]
fn the_augmented_lagrangian_through_petsc_solves_as_fdfsis() {
    let (case, disc, problem) = schaefer_turek_coarse();
    let al = case.solver.linear.al_options(false, Formulation::Plane);
    let mut solver = PetscSolver::augmented_lagrangian(al, "-fdfsi_ksp_rtol 1e-13", 1e-8);
    solver.set_split(disc.saddle_point_split(Formulation::Plane).unwrap());
    let iterations = compare("Schaefer-Turek 2D-1, FGMRES + AL field split", &disc, &problem, &mut solver, 1e-8);
    assert!((2..=20).contains(&iterations), "two solves, a few FGMRES iterations each: {iterations}");
}

/// A singular system, an unknown option or a right-hand side of the wrong length is an error
/// naming the cause, not a crash; a solver made after them works.
#[test]
fn petsc_errors_are_errors() {
    let pattern = fdfsi_fem::sparse::Pattern::from_cells(2, 1, |_, dofs| {
        dofs.clear();
        dofs.extend([0, 1])
    });
    let mut singular = CscMatrix::zeros(&pattern);
    singular.values.iter_mut().for_each(|v| *v = 1.0);
    let mut solver = PetscSolver::new("", 1e-8);
    let e = solver.factorize(&singular).unwrap_err();
    println!("singular: {e}");
    assert!(matches!(&e, LinearSolveError::Numeric(m) if m.contains("PCFailedReason")), "{e}");
    let mut regular = singular.clone();
    regular.values = vec![2.0, 1.0, 1.0, 2.0];
    let e = PetscSolver::new("-fdfsi_ksp_type no-such-method", 1e-8).factorize(&regular).unwrap_err();
    println!("bad option: {e}");
    assert!(matches!(&e, LinearSolveError::Petsc(m) if m.contains("KSPSetFromOptions")), "{e}");
    let mut solver = PetscSolver::new("", 1e-8);
    solver.factorize(&regular).unwrap();
    let mut x = [1.0, 2.0];
    solver.solve_in_place(&regular, &mut x).unwrap();
    assert!((x[0] - 0.0).abs() < 1e-15 && (x[1] - 1.0).abs() < 1e-15, "{x:?}");
    let e = solver.solve_in_place(&regular, &mut [1.0]).unwrap_err();
    assert!(e.to_string().contains("right-hand side of 1"), "{e}");
    // Without a split (a solid alone) the augmented-Lagrangian solver solves as the default
    // one: MUMPS, directly (FGMRES would report an iteration).
    let mut al = PetscSolver::augmented_lagrangian(fdfsi::solve::augmented::AlOptions::default(), "", 1e-8);
    al.factorize(&regular).unwrap();
    let mut x = [1.0, 2.0];
    let stats = al.solve_in_place(&regular, &mut x).unwrap();
    assert_eq!(stats.krylov_iterations, 0, "a direct solve");
    assert!((x[0] - 0.0).abs() < 1e-15 && (x[1] - 1.0).abs() < 1e-15, "{x:?}");
}

/// Runs with `[solver.linear] method = "petsc"` (MUMPS through PETSc) give the direct solve's
/// quantities to 1e-9 relative: Schaefer-Turek 2D-1 (steady Navier-Stokes) and model problem 2
/// (2D FSI, 12 steps: the adapted mesh, so the pattern, changes from step to step).
#[test]
fn runs_with_petsc_match_the_direct_solve() {
    use fdfsi::case::LinearMethod;
    use fdfsi::run::{run_case, RunOptions};
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    for name in ["schaefer-turek-2d1", "model-problem-2"] {
        let run = |method: LinearMethod| {
            let mut case = Case::read(&dir.join(format!("{name}.toml"))).unwrap();
            case.solver.linear.method = method;
            case.validate(name).unwrap();
            let out = std::env::temp_dir().join(format!("fdfsi-test-petsc-{name}-{method:?}-{}", std::process::id()));
            let summary = run_case(&case, &RunOptions::new(out.clone(), dir.clone()), &mut |_: &str| {}).unwrap();
            let _ = std::fs::remove_dir_all(&out);
            summary
        };
        let (direct, petsc) = (run(LinearMethod::Direct), run(LinearMethod::Petsc));
        assert_eq!(petsc.steps, direct.steps, "{name}");
        assert!(!direct.quantities.is_empty());
        for (q, v) in &direct.quantities {
            let w = petsc.quantities[q];
            println!("{name}: {q} direct {v:.12e}, PETSc {w:.12e}");
            assert!((w - v).abs() <= 1e-9 * v.abs().max(1e-12), "{name}: {q}: direct {v}, PETSc {w}");
        }
    }
}

/// PETSc's numbering on two ranks (the level-set order, `solve::petsc::Numbering`) is a
/// permutation of the unknowns whose two halves ([`Numbering::rows`]) couple through a thin
/// slice of the domain: on the Stokes system of an 8 x 4 x 2 box, the entries between the halves
/// fall from 44 % of all (the layout's numbering: vertex nodes, edge, face and cell nodes, then
/// the pressure, so each half is spread over the whole box) to 4.6 %. With the velocity's nodes
/// kept whole ([`Nodes`], as for PETSc's block size 3), each node's components stay
/// consecutive and in order, each half holds whole nodes, and the halves couple as little.
#[test]
fn two_ranks_own_two_slices_of_the_domain() {
    use fdfsi::solve::petsc::{Nodes, Numbering, World};
    let disc = FlowDiscretization::build(box_tetrahedra(0.0, 4.0, 0.0, 2.0, 0.0, 1.0, 8, 4, 2), Formulation::ThreeD).unwrap();
    let pattern = disc.whole_pattern();
    let n = pattern.n;
    let two = World { rank: 0, size: 2 };
    // The share of the entries that couple the two halves under a numbering.
    let coupling = |numbering: &Numbering, first: &std::ops::Range<usize>| {
        let mut between = 0;
        for j in 0..n {
            for &i in &pattern.row_idx[pattern.col_ptr[j]..pattern.col_ptr[j + 1]] {
                between += usize::from(first.contains(&numbering.to_petsc(i)) != first.contains(&numbering.to_petsc(j)));
            }
        }
        between as f64 / pattern.nnz() as f64
    };
    let is_permutation = |numbering: &Numbering| {
        let mut seen = vec![false; n];
        for i in 0..n {
            let p = numbering.to_petsc(i);
            assert!(!seen[p], "PETSc index {p} given twice");
            seen[p] = true;
            assert_eq!(numbering.to_fdfsi(p), i);
        }
        assert_eq!((numbering.rows(0).start, numbering.rows(0).end, numbering.rows(1).end), (0, numbering.rows(1).start, n));
    };
    let numbering = Numbering::new(pattern, two, Nodes::SCALAR);
    is_permutation(&numbering);
    assert_eq!(numbering.rows(0), 0..n / 2);
    let identity = Numbering::new(pattern, World { rank: 0, size: 1 }, Nodes::SCALAR);
    assert_eq!((identity.to_petsc(7), identity.to_fdfsi(7), identity.rows(0)), (7, 7, 0..n));
    let (layout, level_set) = (coupling(&identity, &(0..n / 2)), coupling(&numbering, &numbering.rows(0)));
    println!("entries between the two halves: layout's numbering {layout:.3}, level-set order {level_set:.3}");
    assert!(layout > 0.2, "{layout}");
    assert!(level_set < 0.1, "{level_set}");

    let velocity = disc.velocity_field().range();
    assert_eq!(velocity.start, 0);
    let in_pressure: Vec<bool> = (0..n).map(|i| !velocity.contains(&i)).collect();
    let nodes = Nodes::of_split(&in_pressure, n, 3);
    assert_eq!(nodes, Nodes { size: 3, end: velocity.end });
    let by_node = Numbering::new(pattern, two, nodes);
    is_permutation(&by_node);
    for node in (0..velocity.end).step_by(3) {
        let p = by_node.to_petsc(node);
        assert_eq!((by_node.to_petsc(node + 1), by_node.to_petsc(node + 2)), (p + 1, p + 2), "the components of node {}", node / 3);
    }
    let second = by_node.rows(1).start;
    let first_of_second = by_node.to_fdfsi(second);
    assert!(first_of_second >= velocity.end || first_of_second.is_multiple_of(3), "rank 1 starts within a node");
    assert!(second.abs_diff(n / 2) < 3, "{second} rows of {n} on rank 0");
    let by_nodes = coupling(&by_node, &by_node.rows(0));
    println!("entries between the two halves, nodes kept whole: {by_nodes:.3}");
    assert!(by_nodes < 0.1, "{by_nodes}");
    // Not a prefix of whole nodes: every unknown a node of its own.
    assert_eq!(Nodes::of_split(&in_pressure, n, 4), Nodes::SCALAR);
    let mut shuffled = in_pressure.clone();
    shuffled.swap(0, n - 1);
    assert_eq!(Nodes::of_split(&shuffled, n, 3), Nodes::SCALAR);
    assert_eq!(Nodes::of_split(&vec![true; n], n, 3), Nodes::SCALAR, "no primal unknowns");
}

/// A partitioned assembly through PETSc on this process's rank(s) (`PetscSolver` as a
/// `RowSolver`: the discretisation holds only its rows, which PETSc loads as they are):
/// Schaefer-Turek 2D-1's steady solve gives fdfsi's whole-system solution to 1e-10 of its
/// largest entry, with one PETSc set-up for all Newton iterations.
#[test]
fn a_partitioned_flow_through_petsc_solves_as_the_whole_one() {
    let (case, whole, problem) = schaefer_turek_coarse();
    let mut petsc = PetscSolver::new("", 1e-8);
    let world = petsc.as_row_solver().map(|rows| rows.world()).expect("PETSc takes rows");
    let AnyMesh::D2(mesh) = read_msh(&Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/dfg2d-coarse.msh")).unwrap() else { panic!("a 2D mesh") };
    let rows = FlowDiscretization::build_with(mesh, Formulation::Plane, Entries::Rows(world)).unwrap();
    assert!(rows.pattern().is_none());
    let expected = solve_steady(&whole, &problem, &mut FaerLu::default(), &case.solver.newton).unwrap();
    let got = solve_steady(&rows, &problem, &mut petsc, &case.solver.newton).unwrap();
    let scale = expected.x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = expected.x.iter().zip(&got.x).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    println!("partitioned through PETSc: {} Newton iterations, max difference {diff:.2e} of {scale:.2e}", got.newton.iterations);
    assert!(diff <= 1e-10 * scale, "the solutions differ by {diff:e} (largest entry {scale:e})");
    assert!(got.newton.iterations >= 3);
    assert_eq!(petsc.symbolic_factorizations(), 1, "one set-up for the rows' pattern");
}
