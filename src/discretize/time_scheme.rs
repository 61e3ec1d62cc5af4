//! The time discretisation shared by fluid and solid: a step's derivative is
//! `u' = a (u^{n+1} - u*)` with `a = a0 / dt` (see [`crate::time`] for the schemes' formulas).
//! It lives below the steppers so that the FSI discretisation, which needs it inside one step,
//! can use it too.

use serde::{Deserialize, Serialize};

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
