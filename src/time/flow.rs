//! A flow on one mesh, stepped in time: [`FlowStepper`], and [`solve_unsteady`] for studies
//! that integrate a flow problem without a case (convergence studies, benchmarks).

use super::march::{march, Advance, MarchError, MarchOptions, Schedule, StepDone, Stepper, Watch};
use super::{step_history, step_ratio, TimeLevel, TimeScheme, Timings};
use crate::discretize::flow::{FlowDiscretization, FlowError, FlowProblem};
use crate::solve::linear::LinearSolver;
use crate::solve::newton::{NewtonOptions, NewtonReport};
use thiserror::Error;

/// A flow advanced step by step: the solution `x` and, for BDF2, the one before it.
pub struct FlowStepper<'a, const D: usize> {
    pub disc: &'a FlowDiscretization<D>,
    pub problem: &'a FlowProblem<D>,
    pub solver: &'a mut dyn LinearSolver,
    pub newton: NewtonOptions,
    pub scheme: TimeScheme,
    /// The solution at the last completed (sub)step.
    pub x: Vec<f64>,
    /// `u^{n-1}`, when the next step may use BDF2.
    pub x_prev: Option<Vec<f64>>,
    /// The length of the last step (0 at the start).
    pub last_dt: f64,
    /// `a0/dt` of the last (sub)step and its history `u*` (see [`crate::time`]): what the
    /// residual of the step needs, e.g. for consistent boundary forces.
    pub inv_dt: f64,
    pub u_star: Vec<f64>,
    /// Whether the solver has the discretisation's saddle-point split.
    split_given: bool,
}

impl<'a, const D: usize> FlowStepper<'a, D> {
    /// The stepper at the time level `level` with solution `x` (zero and the default level for a
    /// new run).
    pub fn new(
        disc: &'a FlowDiscretization<D>,
        problem: &'a FlowProblem<D>,
        solver: &'a mut dyn LinearSolver,
        newton: NewtonOptions,
        scheme: TimeScheme,
        x: Vec<f64>,
        level: TimeLevel,
    ) -> Self {
        FlowStepper {
            disc,
            problem,
            solver,
            newton,
            scheme,
            x,
            x_prev: level.x_prev,
            last_dt: level.dt,
            inv_dt: 0.0,
            u_star: Vec::new(),
            split_given: false,
        }
    }

    /// The time level after step `step` at `time` (what a restart needs besides `x`).
    pub fn level(&self, step: usize, time: f64) -> TimeLevel {
        TimeLevel { step, time, x_prev: self.x_prev.clone(), dt: self.last_dt }
    }
}

impl<const D: usize> Stepper for FlowStepper<'_, D> {
    type Error = FlowError;

    fn advance(&mut self, t0: f64, t1: f64, cut: bool) -> Result<Advance, FlowError> {
        if !self.split_given {
            self.solver.set_split(self.disc.saddle_point_split(self.problem.formulation)?);
            self.split_given = true;
        }
        let dt = t1 - t0;
        let x_n = self.x.clone();
        let omega = step_ratio(dt, self.last_dt);
        let (inv_dt, u_star) = if cut { (1.0 / dt, x_n.clone()) } else { step_history(self.scheme, dt, omega, &x_n, self.x_prev.as_deref()) };
        let newton = match solve_step(self.disc, self.problem, &mut self.x, &u_star, inv_dt, t1, self.solver, &self.newton) {
            Ok(r) => r,
            Err(e) => {
                self.x = x_n; // the state at t0 again
                return Err(e);
            }
        };
        // After a cut step BDF2 restarts with an Euler step.
        self.x_prev = if cut { None } else { Some(x_n) };
        self.last_dt = dt;
        (self.inv_dt, self.u_star) = (inv_dt, u_star);
        Ok(Advance { newton, phases: Timings::default() })
    }
}

/// Solves one implicit step from the history `u_star` (see [`crate::time`]) to time `t`, with
/// `inv_dt = a0/dt`, starting Newton from `x` (which holds the previous solution).
#[allow(clippy::too_many_arguments)]
fn solve_step<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &mut [f64],
    u_star: &[f64],
    inv_dt: f64,
    t: f64,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
) -> Result<NewtonReport, FlowError> {
    let mut step_problem = problem.clone();
    step_problem.params.inv_dt = inv_dt;
    let constrained = disc.impose_dirichlet(&step_problem, t, x)?;
    let options = &step_problem.newton_options(options);
    Ok(disc.solve_newton(&step_problem, x, u_star, t, &constrained, solver, options)?)
}

/// Options of [`solve_unsteady`].
#[derive(Clone, Debug)]
pub struct TimeOptions {
    pub dt: f64,
    pub t_end: f64,
    pub scheme: TimeScheme,
    /// Maximum number of halvings of a failing step.
    pub max_cuts: usize,
}

/// What one (completed) step did.
#[derive(Clone, Debug)]
pub struct StepReport {
    /// Step number (1-based).
    pub step: usize,
    /// Time at the end of the step.
    pub time: f64,
    /// Step size used (the last sub-step's when the step was cut).
    pub dt: f64,
    /// Number of halvings the step needed.
    pub cuts: usize,
    /// Newton reports of the (sub)steps.
    pub newton: Vec<NewtonReport>,
    /// `a0/dt` of the last (sub)step, and its history `u*` (see [`crate::time`]).
    pub inv_dt: f64,
    pub u_star: Vec<f64>,
}

impl StepReport {
    /// Total Newton iterations of the step.
    pub fn iterations(&self) -> usize {
        self.newton.iter().map(|r| r.iterations).sum()
    }
    /// Final residual norm.
    pub fn residual(&self) -> f64 {
        self.newton.last().and_then(|r| r.residual_norms.last().copied()).unwrap_or(0.0)
    }
}

/// What a step callback of [`solve_unsteady`] may fail with.
pub type CallbackError = Box<dyn std::error::Error + Send + Sync>;

/// A failure of [`solve_unsteady`].
#[derive(Debug, Error)]
pub enum TimeError {
    #[error("step {step} (t = {time:.6e}) failed after {cuts} time-step cuts: {source}")]
    StepFailed { step: usize, time: f64, cuts: usize, source: FlowError },
    #[error(transparent)]
    Flow(#[from] FlowError),
    #[error("time step must be positive and end time after start, got dt = {dt}, end = {t_end}")]
    BadOptions { dt: f64, t_end: f64 },
    #[error("stopped by the step callback at step {step}: {source}")]
    Callback { step: usize, source: CallbackError },
}

/// Integrates from `x` at time 0 to `options.t_end`. `on_step(report, x)` is called after every
/// completed step; an `Err` stops the loop.
pub fn solve_unsteady<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &mut Vec<f64>,
    options: &TimeOptions,
    solver: &mut dyn LinearSolver,
    newton_options: &NewtonOptions,
    mut on_step: impl FnMut(&StepReport, &[f64]) -> Result<(), CallbackError>,
) -> Result<(), TimeError> {
    solve_unsteady_from(disc, problem, x, TimeLevel::default(), options, solver, newton_options, |r, x, _| on_step(r, x))
}

/// Integrates from `x` at the time level `start` (a restart, or [`TimeLevel::default`] for
/// `t = 0`) to `options.t_end` by [`march`]. `on_step(report, x, level)` is called after every
/// completed step with the level reached; an `Err` stops the loop.
#[allow(clippy::too_many_arguments)]
pub fn solve_unsteady_from<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &mut Vec<f64>,
    start: TimeLevel,
    options: &TimeOptions,
    solver: &mut dyn LinearSolver,
    newton_options: &NewtonOptions,
    on_step: impl FnMut(&StepReport, &[f64], &TimeLevel) -> Result<(), CallbackError>,
) -> Result<(), TimeError> {
    let schedule = Schedule { dt: options.dt, end: options.t_end, max_cuts: options.max_cuts };
    let first = start.step + 1;
    let mut stepper = FlowStepper::new(disc, problem, solver, newton_options.clone(), options.scheme, std::mem::take(x), start);
    let mut watch = Callback(on_step);
    let result = march(&mut stepper, &schedule, first, &MarchOptions::default(), &mut Timings::default(), &mut watch);
    *x = std::mem::take(&mut stepper.x);
    result.map_err(|e| match e {
        MarchError::StepFailed { step, time, cuts, source } => TimeError::StepFailed { step, time, cuts, source },
        MarchError::Watch(CallbackFailed { step, source }) => TimeError::Callback { step, source },
        MarchError::BadSchedule { dt, end } => TimeError::BadOptions { dt, t_end: end },
        MarchError::Interrupted { .. } => unreachable!("no stop flag is set"),
    })
}

/// The step callback of [`solve_unsteady_from`] as a [`Watch`].
struct Callback<F>(F);

#[derive(Debug, Error)]
#[error("step {step}: {source}")]
struct CallbackFailed {
    step: usize,
    source: CallbackError,
}

impl<const D: usize, F> Watch<FlowStepper<'_, D>> for Callback<F>
where
    F: FnMut(&StepReport, &[f64], &TimeLevel) -> Result<(), CallbackError>,
{
    type Error = CallbackFailed;

    fn step_done(&mut self, s: &FlowStepper<'_, D>, done: &StepDone, _: &Timings) -> Result<(), CallbackFailed> {
        let report = StepReport {
            step: done.step,
            time: done.time,
            dt: done.dt,
            cuts: done.cuts,
            newton: done.newton.clone(),
            inv_dt: s.inv_dt,
            u_star: s.u_star.clone(),
        };
        (self.0)(&report, &s.x, &s.level(done.step, done.time)).map_err(|source| CallbackFailed { step: done.step, source })
    }

    fn checkpoint(&mut self, _: &FlowStepper<'_, D>, _: &StepDone, _: &Timings) -> Result<(), CallbackFailed> {
        Ok(())
    }
}
