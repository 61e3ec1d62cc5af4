//! Time integration: the schemes, the steppers of each kind of run and the one time loop,
//! [`march::march`], that drives them.
//!
//! The schemes are written as `u' = a0/dt (u^{n+1} - u*)`:
//! - implicit Euler: `a0 = 1`, `u* = u^n`;
//! - BDF2: `(3 u^{n+1} - 4 u^n + u^{n-1}) / (2 dt)`, so `a0 = 3/2`, `u* = (4 u^n - u^{n-1}) / 3`;
//!
//! so the fluid kernel's `inv_dt (u - u_old)` term serves both with `inv_dt = a0/dt`,
//! `u_old = u*`, and a solid applies the same formula to its displacement and its velocity. BDF2
//! starts with one Euler step (it needs two time levels), and takes Euler steps again in the
//! sub-steps of a cut step and the step after it; a step of another length than the last (a
//! run's shorter last step) takes the variable-step BDF2 of [`step_history`]. FSI runs use
//! implicit Euler throughout (the paper's).
//!
//! The steppers: [`flow::FlowStepper`] (a flow on one mesh), [`fsi::FsiStepper`] (the monolithic
//! FSI step of [`crate::discretize::fsi`]), [`solid::QuasiStaticStepper`] (load increments of
//! a solid; the "time" is the load factor) and [`solid::DynamicStepper`] (a solid with inertia).

use serde::{Deserialize, Serialize};

pub mod flow;
pub mod fsi;
pub mod march;
pub mod solid;
mod timings;

pub use flow::{solve_unsteady, solve_unsteady_from, StepReport, TimeError, TimeOptions};
pub use march::{march, num_steps, Schedule};
pub use timings::Timings;

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

/// Where a flow's time loop stands after a completed step: what a restart needs besides the
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
    /// The length of the step that reached this level (0: unknown, as in checkpoints written
    /// before it was kept; the next step is then taken to be as long: [`step_ratio`]).
    #[serde(default)]
    pub dt: f64,
}

/// The ratio `omega = dt / last_dt` of a step to the last one (1 when `last_dt` is unknown, 0,
/// or equal to `dt` but for round-off).
pub fn step_ratio(dt: f64, last_dt: f64) -> f64 {
    if last_dt == 0.0 || (dt - last_dt).abs() <= 1e-9 * dt {
        1.0
    } else {
        dt / last_dt
    }
}

/// `(a0 / dt, u*)` of a step of size `dt` from `x_n` (see the module doc): BDF2 when `scheme` is
/// BDF2 and the previous level `x_prev` is known, implicit Euler otherwise. BDF2 with a step
/// `omega` times the last one (a run's shorter last step) is the variable-step formula
/// `u' = ((1 + 2 omega)/(1 + omega) u^{n+1} - (1 + omega) u^n + omega^2/(1 + omega) u^{n-1}) / dt`,
/// second order too; `omega = 1` is the constant-step formula, evaluated as such.
pub fn step_history(scheme: TimeScheme, dt: f64, omega: f64, x_n: &[f64], x_prev: Option<&[f64]>) -> (f64, Vec<f64>) {
    match (scheme, x_prev) {
        (TimeScheme::Bdf2, Some(xp)) if omega == 1.0 => (1.5 / dt, x_n.iter().zip(xp).map(|(a, b)| (4.0 * a - b) / 3.0).collect()),
        (TimeScheme::Bdf2, Some(xp)) => {
            let a0 = (1.0 + 2.0 * omega) / (1.0 + omega);
            let (cn, cp) = (1.0 + omega, omega * omega / (1.0 + omega));
            (a0 / dt, x_n.iter().zip(xp).map(|(a, b)| (cn * a - cp * b) / a0).collect())
        }
        _ => (1.0 / dt, x_n.to_vec()),
    }
}
