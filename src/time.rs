//! The time loop: implicit Euler (the paper's) and BDF2, with Newton per step and time-step cuts.
//!
//! Both schemes are written as `rho a0/dt (u^{n+1} - u*)`:
//! - implicit Euler: `a0 = 1`, `u* = u^n`;
//! - BDF2: `(3 u^{n+1} - 4 u^n + u^{n-1}) / (2 dt)`, so `a0 = 3/2`, `u* = (4 u^n - u^{n-1}) / 3`;
//!
//! so the fluid kernel's `inv_dt (u - u_old)` term serves both with `inv_dt = a0/dt`,
//! `u_old = u*`. BDF2 starts with one Euler step (it needs two time levels).
//!
//! When Newton fails in a step, the step is retried as two half steps (implicit Euler), up to
//! `max_cuts` times; a step that still fails is an error naming the step and time. After a cut,
//! BDF2 restarts with an Euler step, since its formula assumes equal steps.

use crate::flow::{FlowDiscretization, FlowError, FlowProblem};
use crate::solve::linear::LinearSolver;
use crate::solve::newton::{self, NewtonOptions, NewtonReport};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Time-integration scheme.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeScheme {
    /// Implicit (backward) Euler, first order: the paper's scheme.
    #[default]
    Euler,
    /// Second-order backward differentiation.
    Bdf2,
}

/// Options of the time loop.
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
    /// `a0/dt` of the last (sub)step, and its history `u*` (see the module doc): what the
    /// residual of the step needs, e.g. for consistent boundary forces.
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

/// A failure of the time loop.
#[derive(Debug, Error)]
pub enum TimeError {
    #[error("step {step} (t = {time:.6e}) failed after {cuts} time-step cuts: {source}")]
    StepFailed { step: usize, time: f64, cuts: usize, source: FlowError },
    #[error(transparent)]
    Flow(#[from] FlowError),
    #[error("time step must be positive and end time after start, got dt = {dt}, end = {t_end}")]
    BadOptions { dt: f64, t_end: f64 },
    #[error("stopped by the step observer at step {step}: {message}")]
    Observer { step: usize, message: String },
}

/// Solves one implicit step from the history `u_star` (see the module doc) to time `t`, with
/// `inv_dt = a0/dt`, starting Newton from `x` (which holds the previous solution).
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
    let report =
        newton::solve(x, &disc.pattern, solver, options, |x, k, rhs| disc.assemble_system(&step_problem, x, u_star, t, &constrained, k, rhs))?;
    Ok(report)
}

/// Where the time loop stands after a completed step: what a restart needs besides the
/// solution itself.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TimeLevel {
    /// Completed steps (0 at the start).
    pub step: usize,
    /// Time reached.
    pub time: f64,
    /// The solution one step back, `u^{n-1}`, when the next step may use BDF2 (`None` at the
    /// start and after a cut step).
    pub x_prev: Option<Vec<f64>>,
}

/// `(a0 / dt, u*)` of a step of size `dt` from `x_n` (see the module doc): BDF2 when `scheme` is
/// BDF2 and the previous level `x_prev` is known, implicit Euler otherwise.
pub fn step_history(scheme: TimeScheme, dt: f64, x_n: &[f64], x_prev: Option<&[f64]>) -> (f64, Vec<f64>) {
    match (scheme, x_prev) {
        (TimeScheme::Bdf2, Some(xp)) => (1.5 / dt, x_n.iter().zip(xp).map(|(a, b)| (4.0 * a - b) / 3.0).collect()),
        _ => (1.0 / dt, x_n.to_vec()),
    }
}

/// Number of steps of size `dt` to reach `t_end` (the last one may be shorter).
pub fn num_steps(dt: f64, t_end: f64) -> usize {
    (t_end / dt - 1e-9).ceil() as usize
}

/// Integrates from `x` at time 0 to `options.t_end`. `on_step(report, x)` is called after every
/// completed step; returning `Err(message)` stops the loop.
pub fn solve_unsteady<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &mut Vec<f64>,
    options: &TimeOptions,
    solver: &mut dyn LinearSolver,
    newton_options: &NewtonOptions,
    mut on_step: impl FnMut(&StepReport, &[f64]) -> Result<(), String>,
) -> Result<(), TimeError> {
    solve_unsteady_from(disc, problem, x, TimeLevel::default(), options, solver, newton_options, |r, x, _| on_step(r, x))
}

/// Integrates from `x` at the time level `start` (a restart, or [`TimeLevel::default`] for
/// `t = 0`) to `options.t_end`. `on_step(report, x, level)` is called after every completed step
/// with the level reached; returning `Err(message)` stops the loop. Steps are numbered from the
/// start of the run, and step `k` ends at `min(k dt, t_end)` whether or not the run was
/// restarted, so a restarted run repeats the arithmetic of an uninterrupted one.
#[allow(clippy::too_many_arguments)]
pub fn solve_unsteady_from<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &mut Vec<f64>,
    start: TimeLevel,
    options: &TimeOptions,
    solver: &mut dyn LinearSolver,
    newton_options: &NewtonOptions,
    mut on_step: impl FnMut(&StepReport, &[f64], &TimeLevel) -> Result<(), String>,
) -> Result<(), TimeError> {
    if !(options.dt > 0.0 && options.t_end > 0.0) {
        return Err(TimeError::BadOptions { dt: options.dt, t_end: options.t_end });
    }
    let num_steps = num_steps(options.dt, options.t_end);
    let mut x_prev: Option<Vec<f64>> = start.x_prev; // u^{n-1} for BDF2
    let mut t = start.time;
    for step in start.step + 1..=num_steps {
        let t_next = (step as f64 * options.dt).min(options.t_end);
        let dt = t_next - t;
        let x_n = x.clone();
        let (inv_dt, u_star) = step_history(options.scheme, dt, &x_n, x_prev.as_deref());
        let mut report = StepReport { step, time: t_next, dt, cuts: 0, newton: Vec::new(), inv_dt, u_star: Vec::new() };
        match solve_step(disc, problem, x, &u_star, inv_dt, t_next, solver, newton_options) {
            Ok(r) => {
                report.newton.push(r);
                report.u_star = u_star;
                x_prev = Some(x_n);
            }
            Err(first) => {
                // Retry the interval with 2^k implicit Euler sub-steps.
                let mut last_err = first;
                let mut done = false;
                for cuts in 1..=options.max_cuts {
                    x.copy_from_slice(&x_n);
                    let parts = 1usize << cuts;
                    let h = dt / parts as f64;
                    report.newton.clear();
                    report.cuts = cuts;
                    report.dt = h;
                    let mut ok = true;
                    for k in 1..=parts {
                        let u_old = x.clone();
                        match solve_step(disc, problem, x, &u_old, 1.0 / h, t + k as f64 * h, solver, newton_options) {
                            Ok(r) => {
                                report.newton.push(r);
                                report.inv_dt = 1.0 / h;
                                report.u_star = u_old;
                            }
                            Err(e) => {
                                last_err = e;
                                ok = false;
                                break;
                            }
                        }
                    }
                    if ok {
                        done = true;
                        break;
                    }
                }
                if !done {
                    return Err(TimeError::StepFailed { step, time: t_next, cuts: options.max_cuts, source: last_err });
                }
                x_prev = None; // restart BDF2 with an Euler step
            }
        }
        t = t_next;
        let level = TimeLevel { step, time: t, x_prev: x_prev.clone() };
        on_step(&report, x, &level).map_err(|message| TimeError::Observer { step, message })?;
    }
    Ok(())
}
