//! `solve::partition`: the level-set numbering of a system's unknowns over MPI ranks, made from
//! the cells' dofs alone (no pattern, as a rank holding only its own rows will), equals the one
//! made from the pattern, on 2D and 3D flow systems, with every unknown on its own and with the
//! velocity's nodes kept whole, on 1, 2 and 3 ranks; each rank's rows of a flow's and an FSI
//! system's partitioned assembly are the whole assembly's; and the partitioned path of a flow
//! and of an FSI run on one rank is its whole path. No MPI: the numbering is plain data, and one
//! rank needs no messages.

mod common;
use common::same_rows;
use fdfsi::case::Case;
use fdfsi::discretize::flow::{solve_steady, Entries, FlowDiscretization, FlowProblem, TractionBc};
use fdfsi::discretize::fsi::{step_with, FsiDiscretization, FsiModel, FsiState, StepStart};
use fdfsi::physics::fluid::Formulation;
use fdfsi::solve::linear::{FaerLu, LinearSolver};
use fdfsi::solve::newton::NewtonOptions;
use fdfsi::solve::partition::{Nodes, Numbering, SerialRows, World};
use fdfsi::time::flow::{solve_unsteady, TimeOptions};
use fdfsi::time::TimeScheme;
use fdfsi_fem::generate::{box_tetrahedra, rectangle_triangles, DiagonalPattern};
use fdfsi_fem::gmsh::{read_msh, AnyMesh};
use fdfsi_fem::sparse::{CscMatrix, RowMatrix};
use std::path::Path;
use std::sync::Arc;

/// `Numbering::from_cells` against `Numbering::new` on `disc`'s system: the same index of every
/// unknown and the same rows per rank.
fn same_numberings<const D: usize>(disc: &FlowDiscretization<D>) {
    let pattern = disc.whole_pattern();
    let n = pattern.n;
    let velocity = disc.velocity_field().range();
    let in_pressure: Vec<bool> = (0..n).map(|i| !velocity.contains(&i)).collect();
    let by_node = Nodes::of_split(&in_pressure, n, D);
    assert_eq!(by_node, Nodes { size: D, end: velocity.end });
    let cell_dofs = |c: usize, dofs: &mut Vec<usize>| disc.layout.cell_dofs_into(c, dofs);
    for nodes in [Nodes::SCALAR, by_node] {
        for size in 1..=3 {
            let world = World { rank: 0, size };
            let (from_pattern, from_cells) =
                (Numbering::new(pattern, world, nodes), Numbering::from_cells(n, disc.mesh.num_cells(), cell_dofs, world, nodes));
            for rank in 0..size {
                assert_eq!(from_pattern.rows(rank), from_cells.rows(rank), "{D}D, {nodes:?}, rank {rank} of {size}");
            }
            assert_eq!(from_cells.rows(size - 1).end, n);
            let differ = (0..n).filter(|&i| from_pattern.to_petsc(i) != from_cells.to_petsc(i)).count();
            assert_eq!(differ, 0, "{D}D, {nodes:?}, {size} ranks: {differ} of {n} unknowns numbered otherwise");
            if size > 1 {
                let moved = (0..n).filter(|&i| from_cells.to_petsc(i) != i).count();
                assert!(moved > n / 2, "{D}D, {size} ranks: the level-set order, not the identity ({moved} of {n} moved)");
            }
        }
    }
}

#[test]
fn the_numbering_from_the_cells_is_the_numbering_from_the_pattern() {
    let mesh = rectangle_triangles(0.0, 4.0, 0.0, 1.0, 16, 4, DiagonalPattern::Alternating);
    same_numberings(&FlowDiscretization::build(mesh, Formulation::Plane).unwrap());
    let mesh = box_tetrahedra(0.0, 4.0, 0.0, 2.0, 0.0, 1.0, 8, 4, 2);
    same_numberings(&FlowDiscretization::build(mesh, Formulation::ThreeD).unwrap());
}

/// Schaefer-Turek 2D-1's problem on the coarse mesh (Navier-Stokes, P2+/P1disc, 36 596
/// unknowns), discretised whole and for a partitioned assembly on one rank.
fn schaefer_turek_coarse() -> (FlowDiscretization<2>, FlowDiscretization<2>, FlowProblem<2>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = Case::read(&root.join("cases/schaefer-turek-2d1.toml")).unwrap();
    let AnyMesh::D2(mesh) = read_msh(&root.join("meshes/dfg2d-coarse.msh")).unwrap() else { panic!("a 2D mesh") };
    let problem = fdfsi::setup::flow_problem(&case, &mesh, &root.join("cases")).unwrap();
    let whole = FlowDiscretization::build(mesh.clone(), Formulation::Plane).unwrap();
    let rows = FlowDiscretization::build_with(mesh, Formulation::Plane, Entries::Rows(World { rank: 0, size: 1 })).unwrap();
    (whole, rows, problem)
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

/// The partitioned path of a flow (each rank's rows assembled, `newton::solve_rows`, a
/// `RowSolver`) on one rank, through `SerialRows` over fdfsi's LU: Schaefer-Turek 2D-1's steady
/// solve (Newton with its line search) and two BDF2 steps from rest give the whole system's
/// iterates bit for bit, and so does the residual of the boundary forces.
#[test]
fn a_partitioned_flow_on_one_rank_is_the_whole_one() {
    let (whole, rows, problem) = schaefer_turek_coarse();
    assert!(rows.pattern().is_none() && rows.rows().is_some());
    assert_eq!(rows.nnz(), whole.nnz());
    let options = NewtonOptions::default();
    let expected = solve_steady(&whole, &problem, &mut FaerLu::default(), &options).unwrap();
    let got = solve_steady(&rows, &problem, &mut SerialRows::new(FaerLu::default()), &options).unwrap();
    assert!(expected.newton.iterations >= 3, "{} Newton iterations", expected.newton.iterations);
    assert_eq!(got.newton.residual_norms, expected.newton.residual_norms);
    assert_eq!(bits(&got.x), bits(&expected.x));
    let residual = |disc: &FlowDiscretization<2>| disc.raw_residual(&problem, &expected.x, &expected.x, 0.0).unwrap();
    assert_eq!(bits(&residual(&rows)), bits(&residual(&whole)));

    let time = TimeOptions { dt: 0.05, t_end: 0.1, scheme: TimeScheme::Bdf2, max_cuts: 0 };
    let march = |disc: &FlowDiscretization<2>, solver: &mut dyn LinearSolver| {
        let (mut x, mut norms) = (vec![0.0; disc.num_dofs()], Vec::new());
        solve_unsteady(disc, &problem, &mut x, &time, solver, &options, |report, _| {
            norms.extend(report.newton.iter().flat_map(|r| r.residual_norms.clone()));
            Ok(())
        })
        .unwrap();
        (x, norms)
    };
    let (x_whole, norms_whole) = march(&whole, &mut FaerLu::default());
    let (x_rows, norms_rows) = march(&rows, &mut SerialRows::new(FaerLu::default()));
    assert!(norms_whole.len() >= 4, "{norms_whole:?}");
    assert_eq!(norms_rows, norms_whole);
    assert_eq!(bits(&x_rows), bits(&x_whole));
}

/// Each rank's rows of a flow's partitioned assembly (`FlowDiscretization::assemble_rows` with
/// `Entries::Rows` of 2 and 3 ranks: the level-set numbering, no MPI needed to assemble) are the
/// whole assembly's rows bit for bit: Schaefer-Turek 2D-1 on the coarse mesh with a traction on
/// its outlet, at a state with every unknown nonzero, its Dirichlet rows identity rows.
#[test]
fn each_ranks_rows_of_a_flow_are_the_whole_assemblys() {
    let (whole, _, mut problem) = schaefer_turek_coarse();
    problem
        .traction
        .push(TractionBc { boundary: "outlet".into(), traction: Arc::new(|x: &[f64; 2], n: &[f64; 2], t| [x[1] * n[0] + t, x[0] * n[1]]) });
    let n = whole.num_dofs();
    let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let x_old: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos()).collect();
    let mut state = x.clone();
    let constrained = whole.impose_dirichlet(&problem, 0.5, &mut state).unwrap();
    let mut k = CscMatrix::zeros(whole.whole_pattern());
    let mut rhs = vec![0.0; n];
    whole.assemble_system(&problem, &state, &x_old, 0.5, &constrained, &mut k, &mut rhs).unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let AnyMesh::D2(mesh) = read_msh(&root.join("meshes/dfg2d-coarse.msh")).unwrap() else { panic!("a 2D mesh") };
    for size in [2, 3] {
        let mut covered = 0;
        for rank in 0..size {
            let disc = FlowDiscretization::build_with(mesh.clone(), Formulation::Plane, Entries::Rows(World { rank, size })).unwrap();
            let part = disc.rows().unwrap();
            let mut a = RowMatrix::zeros(&part.pattern);
            let mut rhs_rows = vec![0.0; part.pattern.rows.len()];
            disc.assemble_rows(&problem, &state, &x_old, 0.5, &constrained, &mut a, &mut rhs_rows).unwrap();
            covered += same_rows(&part.partition, &a, &rhs_rows, &k, &rhs, &format!("rank {rank} of {size}"));
        }
        assert_eq!(Some(covered), whole.nnz(), "{size} ranks' rows cover the pattern");
    }
}

/// A case's FSI model (`cases/NAME.toml`) and its time step.
fn fsi_case(name: &str) -> (FsiModel<2>, f64) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let case = Case::read(&dir.join(format!("{name}.toml"))).unwrap();
    let AnyMesh::D2(mesh) = fdfsi::setup::build_mesh(&case, &dir).unwrap() else { panic!("a 2D case") };
    (fdfsi::setup::fsi_model(&case, &mesh, &dir).unwrap(), case.time.unwrap().dt)
}

/// Each rank's rows of an FSI system's partitioned assembly (`FsiDiscretization::assemble_rows`
/// with `Entries::Rows` of 2 and 3 ranks) are the whole assembly's rows bit for bit: the first
/// step of model problem 2 (the trace-mode multiplier; fluid and solid Dirichlet rows) and of
/// model problem 3 (axisymmetric, with an unknown of the multiplier kernel), at a state with
/// every free unknown nonzero; and the residual alone, with no matrix, is the assembled one.
#[test]
fn each_ranks_rows_of_an_fsi_system_are_the_whole_assemblys() {
    let mut kernels = 0;
    for name in ["model-problem-2", "model-problem-3"] {
        let (model, dt) = fsi_case(name);
        let state = FsiState::at_rest(&model);
        let start = StepStart::new(&model, &state, dt).unwrap();
        let (disc, input) = (&start.disc, start.input(&state));
        let n = disc.num_dofs();
        println!(
            "{name}: {n} unknowns, {} entries, {} constrained, {} kernel unknowns, {} trace modes",
            disc.whole_pattern().nnz(),
            start.constrained.iter().filter(|&&c| c).count(),
            disc.kernel.len(),
            disc.coupling.num_chains
        );
        kernels += disc.kernel.len();
        let x: Vec<f64> =
            start.x.iter().enumerate().map(|(i, &v)| if start.constrained[i] { v } else { 1e-3 * ((i + 1) as f64 * 0.37).sin() }).collect();
        let mut k = CscMatrix::zeros(disc.whole_pattern());
        let mut rhs = vec![0.0; n];
        disc.assemble(&model, &input, &x, &start.constrained, &mut k, &mut rhs).unwrap();
        let residual = disc.residual(&model, &input, &x).unwrap();
        let mut unconstrained = CscMatrix::zeros(disc.whole_pattern());
        let mut minus_r = vec![0.0; n];
        disc.assemble(&model, &input, &x, &vec![false; n], &mut unconstrained, &mut minus_r).unwrap();
        assert_eq!(bits(&residual), bits(&minus_r.iter().map(|v| -v).collect::<Vec<_>>()), "{name}: the residual alone");
        for size in [2, 3] {
            let mut covered = 0;
            for rank in 0..size {
                let rows_disc =
                    FsiDiscretization::build_with(&model, &start.geometry, &state.coupling_pattern, Entries::Rows(World { rank, size })).unwrap();
                assert_eq!(rows_disc.num_dofs(), n);
                assert!(rows_disc.pattern().is_none());
                let part = rows_disc.rows().unwrap();
                let mut a = RowMatrix::zeros(&part.pattern);
                let mut rhs_rows = vec![0.0; part.pattern.rows.len()];
                rows_disc.assemble_rows(&model, &input, &x, &start.constrained, &mut a, &mut rhs_rows).unwrap();
                covered += same_rows(&part.partition, &a, &rhs_rows, &k, &rhs, &format!("{name}, rank {rank} of {size}"));
            }
            assert_eq!(Some(covered), disc.nnz(), "{name}: {size} ranks' rows cover the pattern");
        }
    }
    assert!(kernels > 0, "the multiplier kernel's unknowns are exercised");
}

/// The partitioned path of an FSI run on one rank, through `SerialRows` over fdfsi's LU: three
/// steps of model problem 2 (implicit Euler; the adapted mesh, the pattern and the partition
/// rebuilt every step) give the whole system's Newton residuals, solutions and solid states bit
/// for bit.
#[test]
fn a_partitioned_fsi_run_on_one_rank_is_the_whole_one() {
    let (model, dt) = fsi_case("model-problem-2");
    let options = NewtonOptions::default();
    let march = |solver: &mut dyn LinearSolver| {
        let (mut state, mut norms, mut last) = (FsiState::at_rest(&model), Vec::new(), Vec::new());
        for _ in 0..3 {
            let (next, step) = step_with(&model, &state, dt, TimeScheme::Euler, solver, &options).unwrap();
            norms.extend(step.report.newton.residual_norms.clone());
            (state, last) = (next, step.x);
        }
        (state.solid_x, last, norms)
    };
    let (solid_whole, x_whole, norms_whole) = march(&mut FaerLu::default());
    let (solid_rows, x_rows, norms_rows) = march(&mut SerialRows::new(FaerLu::default()));
    assert!(norms_whole.len() >= 6, "{norms_whole:?}");
    assert_eq!(norms_rows, norms_whole);
    assert_eq!(bits(&x_rows), bits(&x_whole));
    assert_eq!(bits(&solid_rows), bits(&solid_whole));
}
