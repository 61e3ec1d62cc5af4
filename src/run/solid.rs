//! Solid-only runs: a case with a `[solid]` material law and no fluid mesh.
//!
//! Without `[time]` the solid is loaded quasi-statically ([`QuasiStaticStepper`]): boundary
//! values and the body force are multiplied by the load factor, ramped from 0 to 1 in
//! `solid.loading.steps` equal increments; where an increment fails it goes on in halves,
//! quarters, ..., down to 1/64 of it (the sub-increments done stand). With `[time]` it moves in
//! time from rest ([`DynamicStepper`]: inertia `solid.density`, `time.scheme` implicit Euler or
//! BDF2), its boundary values and body force evaluated at each step's time. Runs write
//! checkpoints and stop on Ctrl-C like every run.
//! Results in `--out DIR`:
//! - `solution.pvd` + `solution_solid_NNNNNN.vtu`: the deformed solid of the last step
//!   (quasi-static) or at `t = 0` and every `time.output_every` steps (see
//!   [`crate::io::fields::solid_grid`]);
//! - `history.csv`: one row per step (`time` is the load factor of a quasi-static run) with the
//!   Newton iterations, the final residual and the `displacement` probes;
//! - `summary.json` as for every run.

use super::record::{march_and_record, RunOutputs, Start};
use super::{RunError, RunObserver, RunOptions, RunSummary};
use crate::case::{Case, CaseError, ProbeField, CONTACT_QUANTITIES};
use crate::discretize::solid::{LoadState, SolidDiscretization, SolidProblem};
use crate::io::checkpoint::RestartState;
use crate::io::fields::solid_grid;
use crate::setup::{displacement_probes, solid_mesh, solid_problem, SetupError, SolidMesh};
use crate::time::march::StepDone;
use crate::time::solid::{DynamicState, DynamicStepper, QuasiStaticStepper};
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
    let spec = case.first_solid().ok_or_else(|| invalid("no [solid] table".into()))?;
    let t = Instant::now();
    let SolidMesh { mesh, cell_body } = solid_mesh::<D>(case, &options.case_dir)?;
    let cells = mesh.num_cells();
    let time = case.time.as_ref();
    let problem = solid_problem::<D>(case, cell_body, time.is_none())?;
    let disc = SolidDiscretization::build_for(mesh, &problem)?;
    disc.check_problem(&problem)?;
    let mesh_seconds = t.elapsed().as_secs_f64();
    let steps = match time {
        None => format!("{} load steps", spec.loading.steps),
        Some(ts) => {
            let densities: Vec<String> = problem.bodies.iter().map(|b| b.density.to_string()).collect();
            format!("{} time steps of {} ({:?}), density {}", crate::time::num_steps(ts.dt, ts.end), ts.dt, ts.scheme, densities.join(", "))
        }
    };
    obs.log(&format!("solid: {} on {cells} cells, {} dofs; {steps}", problem.material_names(), disc.num_dofs()));
    if let Some(p) = case.output.probe.iter().find(|p| p.field != ProbeField::Displacement) {
        return Err(invalid(format!("probe '{}': solid-only runs have displacement probes only", p.name)));
    }
    let outputs = SolidOutputs::<D> { probes: displacement_probes(case, &disc)? };
    let mut start = Start::of(options, obs, t);
    start.timings.mesh = mesh_seconds;
    let mut lu = case.solver.linear_solver(time.is_some(), case.physics.formulation);
    let newton = case.solver.newton.clone();
    let recorded = match time {
        None => {
            let at_rest = LoadState::at_rest(&disc, spec.loading.mode);
            let state = match &options.resume {
                None => at_rest,
                Some(c) => c.solid_state(&options.out_dir, &at_rest)?,
            };
            let mut stepper = QuasiStaticStepper::new(&disc, &problem, lu.as_mut(), newton, state);
            let steps = spec.loading.steps;
            let schedule = Schedule { dt: 1.0 / steps as f64, end: 1.0, max_cuts: LOAD_STEP_CUTS };
            // The fields of the last step only.
            march_and_record(case, options, obs, &mut stepper, outputs, &schedule, steps, start, false)?
        }
        Some(ts) => {
            let state = match &options.resume {
                None => DynamicState::at_rest(disc.num_dofs()),
                Some(c) => c.dynamic_solid_state(&options.out_dir, disc.num_dofs())?,
            };
            let mut stepper = DynamicStepper::new(&disc, &problem, lu.as_mut(), newton, ts.scheme, state);
            let schedule = super::schedule_of(ts);
            march_and_record(case, options, obs, &mut stepper, outputs, &schedule, ts.output_every, start, true)?
        }
    };
    let symbolic = lu.symbolic_factorizations();
    Ok(recorded.summary(case, D, cells, symbolic))
}

/// What the outputs of a solid run read from its stepper.
trait SolidStepper<const D: usize> {
    fn disc(&self) -> &SolidDiscretization<D>;
    fn problem(&self) -> &SolidProblem<D>;
    /// The unknowns: total displacement and pressure.
    fn x(&self) -> &[f64];
    /// What a checkpoint saves.
    fn restart(&self) -> RestartState;
}

/// [`SolidStepper`] for a stepper with fields `disc`, `problem` and `state.x`, whose state a
/// checkpoint saves as `RestartState::$variant`.
macro_rules! solid_stepper {
    ($stepper:ident, $variant:ident) => {
        impl<const D: usize> SolidStepper<D> for $stepper<'_, D> {
            fn disc(&self) -> &SolidDiscretization<D> {
                self.disc
            }
            fn problem(&self) -> &SolidProblem<D> {
                self.problem
            }
            fn x(&self) -> &[f64] {
                &self.state.x
            }
            fn restart(&self) -> RestartState {
                RestartState::$variant(self.state.clone())
            }
        }
    };
}

solid_stepper!(QuasiStaticStepper, Solid);
solid_stepper!(DynamicStepper, SolidDynamic);

/// The outputs of a solid run in `D` dimensions: its displacement probes and the deformed solid.
struct SolidOutputs<const D: usize> {
    /// (name, solid node, component).
    probes: Vec<(String, usize, usize)>,
}

impl<const D: usize, S: SolidStepper<D>> RunOutputs<S> for SolidOutputs<D> {
    fn quantities(&mut self, s: &S, _done: &StepDone) -> Result<Vec<(String, f64)>, RunError> {
        let mut out: Vec<(String, f64)> = self.probes.iter().map(|(name, node, a)| (name.clone(), s.disc().displacement(s.x(), *node)[*a])).collect();
        out.extend(contact_quantities(s.disc(), s.problem(), s.x()));
        Ok(out)
    }

    fn write_fields(&mut self, s: &S, done: &StepDone, series: &mut PvdSeries) -> Result<(), RunError> {
        series.add(done.time, "solid", &solid_grid(s.disc(), s.problem(), s.x())?)?;
        Ok(())
    }

    fn restart(&self, s: &S, _done: &StepDone) -> RestartState {
        s.restart()
    }

    fn dofs(&self, s: &S) -> Vec<(String, usize)> {
        solid_dofs(s.disc())
    }
}

/// Each contact boundary `NAME`'s `NAME_contact_force` (`int lambda dA` over the reference
/// surface, against another boundary over the part of it that boundary covers: per unit depth
/// in plane runs, over the whole circumference when axisymmetric),
/// `NAME_contact_pressure_max` and `NAME_gap_min` (the smallest gap of its nodes; negative:
/// penetrated; against another boundary, of the nodes with a master under them, NaN where none
/// has).
pub(crate) fn contact_quantities<const D: usize>(disc: &SolidDiscretization<D>, problem: &SolidProblem<D>, x: &[f64]) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    let around = disc.formulation.around();
    for (surface, nodes) in disc.contact_surfaces().iter().zip(disc.contact_gaps_and_weights(problem, x)) {
        let lambda = |j: usize| x[surface.first + j];
        let force: f64 = nodes.iter().enumerate().map(|(j, (_, w))| w * lambda(j)).sum();
        let peak = (0..surface.nodes.len()).map(lambda).fold(f64::NEG_INFINITY, f64::max);
        // NaN where no node has a master boundary under it (against a boundary).
        let gap = match nodes.iter().map(|(g, _)| *g).fold(f64::INFINITY, f64::min) {
            g if g.is_finite() => g,
            _ => f64::NAN,
        };
        let name = &surface.boundary;
        out.extend(CONTACT_QUANTITIES.iter().zip([around * force, peak, gap]).map(|(q, v)| (format!("{name}_{q}"), v)));
    }
    out
}

/// The unknowns of a solid run, as `summary.json` and `fdfsi check` list them.
pub(crate) fn solid_dofs<const D: usize>(disc: &SolidDiscretization<D>) -> Vec<(String, usize)> {
    vec![("solid".into(), disc.num_dofs())]
}
