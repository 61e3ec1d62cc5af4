//! Newton's method on an assembled residual `R(x)` and Jacobian `K(x) = dR/dx`.
//!
//! Each iteration assembles `K` and `-R` at the current iterate, factorises `K` numerically (the
//! symbolic factorisation is reused through [`LinearSolver`]), solves `K dx = -R` and updates
//! `x += dx`. Convergence: `|R| <= abs_tol` or `|R| <= rel_tol |R_0|`, checked after assembly,
//! so a linear problem stops after one solve and one confirming assembly.

use super::linear::{LinearSolveError, LinearSolver};
use fdfsi_fem::sparse::{CscMatrix, Pattern};
use thiserror::Error;

/// Newton options.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NewtonOptions {
    /// Maximum number of linear solves.
    pub max_iterations: usize,
    /// Absolute tolerance on the Euclidean norm of the residual.
    pub abs_tol: f64,
    /// Tolerance relative to the first residual.
    pub rel_tol: f64,
}

impl Default for NewtonOptions {
    fn default() -> Self {
        NewtonOptions { max_iterations: 20, abs_tol: 1e-10, rel_tol: 1e-10 }
    }
}

/// What one Newton solve did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct NewtonReport {
    pub iterations: usize,
    /// Residual norm before each solve, and the final one.
    pub residual_norms: Vec<f64>,
    /// Norm of each update.
    pub update_norms: Vec<f64>,
    /// Seconds spent assembling, factorising and solving.
    pub assemble_seconds: f64,
    pub factorize_seconds: f64,
    pub solve_seconds: f64,
}

/// A Newton failure.
#[derive(Debug, Error)]
pub enum NewtonError<E: std::error::Error + 'static> {
    #[error("assembly failed: {0}")]
    Assembly(#[source] E),
    #[error(transparent)]
    Linear(#[from] LinearSolveError),
    #[error("Newton did not converge in {iterations} iterations: residual {residual:.3e} (tolerance {tolerance:.1e}); raise solver.newton.max_iterations or reduce the time step")]
    NotConverged { iterations: usize, residual: f64, tolerance: f64 },
    #[error("the residual became non-finite (NaN or infinity) at Newton iteration {iteration}")]
    NonFinite { iteration: usize },
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Solves `R(x) = 0` from the initial iterate `x`. `assemble(x, K, rhs)` must zero and fill the
/// Jacobian `K` and `rhs = -R(x)`.
pub fn solve<E, F>(
    x: &mut [f64],
    pattern: &Pattern,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
    mut assemble: F,
) -> Result<NewtonReport, NewtonError<E>>
where
    E: std::error::Error + 'static,
    F: FnMut(&[f64], &mut CscMatrix<'_>, &mut [f64]) -> Result<(), E>,
{
    let mut k = CscMatrix::zeros(pattern);
    let mut rhs = vec![0.0; x.len()];
    let mut report = NewtonReport::default();
    let mut r0 = None;
    loop {
        let t = std::time::Instant::now();
        k.values.iter_mut().for_each(|v| *v = 0.0);
        rhs.iter_mut().for_each(|v| *v = 0.0);
        assemble(x, &mut k, &mut rhs).map_err(NewtonError::Assembly)?;
        report.assemble_seconds += t.elapsed().as_secs_f64();
        let r = norm(&rhs);
        if !r.is_finite() {
            return Err(NewtonError::NonFinite { iteration: report.iterations });
        }
        report.residual_norms.push(r);
        let r0v = *r0.get_or_insert(r);
        let tol = options.abs_tol.max(options.rel_tol * r0v);
        if r <= tol && (report.iterations > 0 || r <= options.abs_tol) {
            return Ok(report);
        }
        if report.iterations >= options.max_iterations {
            return Err(NewtonError::NotConverged { iterations: report.iterations, residual: r, tolerance: tol });
        }
        let t = std::time::Instant::now();
        solver.factorize(&k)?;
        report.factorize_seconds += t.elapsed().as_secs_f64();
        let t = std::time::Instant::now();
        solver.solve_in_place(&k, &mut rhs)?;
        report.solve_seconds += t.elapsed().as_secs_f64();
        for (xi, d) in x.iter_mut().zip(&rhs) {
            *xi += d;
        }
        report.update_norms.push(norm(&rhs));
        report.iterations += 1;
    }
}
