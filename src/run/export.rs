//! `fdfsi run CASE --export-system DIR`: the first Newton system of a flow or FSI case, for trying
//! other solvers on it (e.g. `../shared/peers/lu_mumps.py`):
//! - `jacobian.mtx`, `rhs.mtx`: `K(x_0)` and `-R(x_0)` (MatrixMarket), `x_0` the Dirichlet values
//!   (zero elsewhere); for a time-dependent case, the system of the first (implicit Euler) step
//!   from rest (an FSI case: on the fluid mesh adapted to the solid at rest); Dirichlet rows are
//!   identity rows with zero right-hand side;
//! - `blocks.json`: the name and index range `[start, end)` of every block of the layout;
//! - with `[solver.linear] method = "augmented-lagrangian"`, `augmented.mtx`: the augmented
//!   velocity block the preconditioner factorises (`solve::augmented`).

use super::{RunError, RunObserver};
use crate::case::{Case, LinearMethod, RunKind};
use crate::discretize::flow::{Entries, FlowDiscretization};
use crate::discretize::fsi::{FsiError, FsiState, StepStart};
use crate::io::matrix_market::{write_matrix, write_vector};
use crate::io::{write_atomic, OutputError};
use crate::setup::{build_mesh, flow_problem, fluid_mesh, fsi_model};
use crate::solve::augmented::{AugmentedLagrangian, SaddlePointSplit};
use crate::solve::newton::NewtonError;
use fdfsi_fem::gmsh::AnyMesh;
use fdfsi_fem::mesh::Mesh;
use fdfsi_fem::sparse::CscMatrix;
use std::ops::Range;
use std::path::Path;

/// Writes the first Newton system of `case` into `dir` (see the module documentation).
pub fn export_system(case: &Case, case_dir: &Path, dir: &Path, obs: &mut dyn RunObserver) -> Result<(), RunError> {
    if case.kind() == RunKind::Solid {
        return Err(RunError::Unsupported("--export-system writes flow and FSI systems; this is a solid case".into()));
    }
    std::fs::create_dir_all(dir).map_err(|source| OutputError::Io { path: dir.display().to_string(), source })?;
    // A flow case's mesh is adapted to its fixed solid; an FSI case adapts in its first step.
    let mesh = if case.kind() == RunKind::Fsi { build_mesh(case, case_dir)? } else { fluid_mesh(case, case_dir)?.0 };
    match (case.kind(), mesh) {
        (RunKind::Fsi, AnyMesh::D2(m)) => export_fsi::<2>(case, &m, case_dir, dir, obs),
        (RunKind::Fsi, AnyMesh::D3(m)) => export_fsi::<3>(case, &m, case_dir, dir, obs),
        (_, AnyMesh::D2(m)) => export_flow::<2>(case, m, case_dir, dir, obs),
        (_, AnyMesh::D3(m)) => export_flow::<3>(case, m, case_dir, dir, obs),
    }
}

fn export_flow<const D: usize>(case: &Case, mesh: Mesh<D>, case_dir: &Path, dir: &Path, obs: &mut dyn RunObserver) -> Result<(), RunError> {
    let mut problem = flow_problem(case, &mesh, case_dir)?;
    let disc = FlowDiscretization::build_for(mesh, &problem, Entries::Whole)?;
    // The first step's system: at t = dt from rest with 1/dt, or the steady one at t = 0.
    let t = case.time.as_ref().map_or(0.0, |ts| ts.dt);
    problem.params.inv_dt = if t > 0.0 { 1.0 / t } else { 0.0 };
    let n = disc.num_dofs();
    let mut x = disc.initial_state(&problem);
    let x_old = x.clone();
    let constrained = disc.impose_dirichlet(&problem, t, &mut x)?;
    let mut k = CscMatrix::zeros(disc.whole_pattern());
    let mut rhs = vec![0.0; n];
    disc.assemble_system(&problem, &x, &x_old, t, &constrained, &mut k, &mut rhs)
        .map_err(|e| crate::discretize::flow::FlowError::Map { cell: e.cell, source: e.source })?;
    let mut blocks: Vec<(String, Range<usize>)> = disc.layout.fields.iter().map(|f| (f.name.to_string(), f.range())).collect();
    if !disc.outlets().is_empty() {
        blocks.push(("windkessel".into(), disc.windkessel_dofs(0).0..n));
    }
    write_system(dir, &k, &rhs, blocks, obs)?;
    write_augmented(case, dir, &k, || Ok(disc.saddle_point_split(problem.formulation)?), obs)
}

fn export_fsi<const D: usize>(case: &Case, fluid_mesh: &Mesh<D>, case_dir: &Path, dir: &Path, obs: &mut dyn RunObserver) -> Result<(), RunError> {
    let model = fsi_model(case, fluid_mesh, case_dir)?;
    let dt = case.time.as_ref().expect("fsi_model refuses a case without [time]").dt;
    let state = FsiState::at_rest(&model);
    let start = StepStart::new(&model, &state, dt)?;
    let disc = &start.disc;
    let mut k = CscMatrix::zeros(disc.whole_pattern());
    let mut rhs = vec![0.0; disc.num_dofs()];
    disc.assemble(&model, &start.input(&state), &start.x, &start.constrained, &mut k, &mut rhs)
        .map_err(|e| FsiError::Newton(NewtonError::Assembly(e)))?;
    let blocks = disc.layout.blocks().map(|(b, r)| (b.name().to_string(), r)).collect();
    write_system(dir, &k, &rhs, blocks, obs)?;
    write_augmented(case, dir, &k, || Ok(disc.saddle_point_split(&model)?), obs)
}

/// Writes `jacobian.mtx`, `rhs.mtx` and `blocks.json` (every block of the layout, empty ones
/// included, e.g. the solid pressure of a compressible law).
fn write_system(dir: &Path, k: &CscMatrix<'_>, rhs: &[f64], blocks: Vec<(String, Range<usize>)>, obs: &mut dyn RunObserver) -> Result<(), RunError> {
    write_matrix(&dir.join("jacobian.mtx"), k)?;
    write_vector(&dir.join("rhs.mtx"), rhs)?;
    let n = rhs.len();
    let blocks: Vec<serde_json::Value> = blocks.iter().map(|(name, r)| serde_json::json!({ "name": name, "start": r.start, "end": r.end })).collect();
    let json = serde_json::to_string_pretty(&serde_json::json!({ "dofs": n, "blocks": blocks })).expect("JSON of numbers and names");
    write_atomic(&dir.join("blocks.json"), json.as_bytes())?;
    obs.log(&format!("exported the first Newton system ({n} unknowns, {} entries) to {}", k.pattern.nnz(), dir.display()));
    Ok(())
}

/// With the AL solver, writes `augmented.mtx`: the augmented block of `k` under the split that
/// `split` builds (only then).
fn write_augmented(
    case: &Case,
    dir: &Path,
    k: &CscMatrix<'_>,
    split: impl FnOnce() -> Result<SaddlePointSplit, RunError>,
    obs: &mut dyn RunObserver,
) -> Result<(), RunError> {
    if case.solver.linear.method == LinearMethod::AugmentedLagrangian {
        let mut al = AugmentedLagrangian::new(case.solver.linear.al_options(case.time.is_some(), case.physics.formulation));
        crate::solve::linear::LinearSolver::set_split(&mut al, split()?);
        if let Some((pattern, values)) = al.augmented_block(k).map_err(|e| RunError::Unsupported(e.to_string()))? {
            write_matrix(&dir.join("augmented.mtx"), &CscMatrix { pattern: &pattern, values })?;
            obs.log(&format!("and its augmented block ({} unknowns, {} entries)", pattern.n, pattern.nnz()));
        }
    }
    Ok(())
}
