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
//! implicit Euler (the paper's) or BDF2, fluid and solid alike.
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

pub use crate::discretize::time_scheme::{step_history, step_ratio, TimeScheme};
pub use flow::{solve_unsteady, solve_unsteady_from, StepReport, TimeError, TimeOptions};
pub use march::{march, num_steps, Schedule};
pub use timings::Timings;

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
