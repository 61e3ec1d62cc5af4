//! Solid-only runs: a case with a `[solid]` material law and no fluid mesh, loaded
//! quasi-statically ([`QuasiStaticStepper`]).
//!
//! Boundary values are multiplied by the load factor, ramped from 0 to 1 in
//! `solid.loading.steps` equal increments; an increment that fails is cut into 2, 4, ... 64
//! sub-increments. Runs write checkpoints and stop on Ctrl-C like every run. Results in
//! `--out DIR`:
//! - `solution.pvd` + `solution_solid_NNNNNN.vtu`: the deformed solid of the last step (see
//!   [`crate::io::fields::solid_grid`]);
//! - `history.csv`: one row per load step (`time` is the load factor) with the Newton
//!   iterations, the final residual and the `displacement` probes;
//! - `summary.json` as for every run.

use super::record::{march_and_record, RunOutputs, Start};
use super::{RunError, RunObserver, RunOptions, RunSummary};
use crate::case::{Case, CaseError, ProbeField};
use crate::discretize::solid::{LoadState, SolidDiscretization};
use crate::io::checkpoint::RestartState;
use crate::io::fields::solid_grid;
use crate::setup::{displacement_probes, solid_mesh, solid_problem, SetupError};
use crate::time::march::StepDone;
use crate::time::solid::QuasiStaticStepper;
use crate::time::Schedule;
use fdfsi_fem::vtk::PvdSeries;
use std::time::Instant;

/// How often a failing load increment is halved (down to 1/64 of it).
const LOAD_STEP_CUTS: usize = 6;

/// Runs a solid-only case.
pub fn run_solid(case: &Case, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    if case.dim() == 2 {
        run_dim::<2>(case, options, obs)
    } else {
        run_dim::<3>(case, options, obs)
    }
}

fn invalid(message: String) -> RunError {
    SetupError::from(CaseError::Invalid { file: "case".into(), message }).into()
}

fn run_dim<const D: usize>(case: &Case, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let spec = case.solid.as_ref().ok_or_else(|| invalid("no [solid] table".into()))?;
    let t = Instant::now();
    let mesh = solid_mesh::<D>(spec, &options.case_dir)?;
    let cells = mesh.num_cells();
    let problem = solid_problem::<D>(case, spec, true)?;
    let disc = SolidDiscretization::build(mesh, case.physics.formulation, problem.material.as_ref())?;
    disc.check_problem(&problem)?;
    let mesh_seconds = t.elapsed().as_secs_f64();
    obs.log(&format!("solid: {} on {cells} cells, {} dofs; {} load steps", problem.material.name(), disc.num_dofs(), spec.loading.steps));
    if let Some(p) = case.output.probe.iter().find(|p| p.field != ProbeField::Displacement) {
        return Err(invalid(format!("probe '{}': solid-only runs have displacement probes only", p.name)));
    }
    let outputs = SolidOutputs { probes: displacement_probes(case, &disc)? };
    let mut start = Start::of(options, obs, t);
    start.timings.mesh = mesh_seconds;
    let at_rest = LoadState::at_rest(&disc, spec.loading.mode);
    let state = match &options.resume {
        None => at_rest,
        Some(c) => c.solid_state(&options.out_dir, &at_rest)?,
    };
    let mut lu = case.solver.linear_solver(case.time.is_some(), case.physics.formulation);
    let mut stepper = QuasiStaticStepper::new(&disc, &problem, lu.as_mut(), case.solver.newton.clone(), state);
    let steps = spec.loading.steps;
    let schedule = Schedule { dt: 1.0 / steps as f64, end: 1.0, max_cuts: LOAD_STEP_CUTS };
    // The fields of the last step only.
    let recorded = march_and_record(case, options, obs, &mut stepper, outputs, &schedule, steps, start, false)?;
    let symbolic = lu.symbolic_factorizations();
    Ok(recorded.summary(case, D, cells, symbolic))
}

/// The outputs of a solid run: its displacement probes and the deformed solid.
struct SolidOutputs {
    /// (name, solid node, component).
    probes: Vec<(String, usize, usize)>,
}

impl<const D: usize> RunOutputs<QuasiStaticStepper<'_, D>> for SolidOutputs {
    fn quantities(&mut self, s: &QuasiStaticStepper<'_, D>, _done: &StepDone) -> Result<Vec<(String, f64)>, RunError> {
        Ok(self.probes.iter().map(|(name, node, a)| (name.clone(), s.disc.displacement(&s.state.x, *node)[*a])).collect())
    }

    fn write_fields(&mut self, s: &QuasiStaticStepper<'_, D>, done: &StepDone, series: &mut PvdSeries) -> Result<(), RunError> {
        series.add(done.time, "solid", &solid_grid(s.disc, s.problem.material.as_ref(), &s.state.x)?)?;
        Ok(())
    }

    fn restart(&self, s: &QuasiStaticStepper<'_, D>, _done: &StepDone) -> RestartState {
        RestartState::Solid(s.state.clone())
    }

    fn dofs(&self, s: &QuasiStaticStepper<'_, D>) -> Vec<(String, usize)> {
        solid_dofs(s.disc)
    }
}

/// The unknowns of a solid run, as `summary.json` and `fdfsi check` list them.
pub(crate) fn solid_dofs<const D: usize>(disc: &SolidDiscretization<D>) -> Vec<(String, usize)> {
    vec![("solid".into(), disc.num_dofs())]
}
