//! Newton's method on an assembled residual `R(x)` and Jacobian `K(x) = dR/dx`.
//!
//! Each iteration assembles `K` and `-R` at the current iterate, factorises `K` numerically (the
//! symbolic factorisation is reused through [`LinearSolver`]), solves `K dx = -R` and updates
//! `x += dx`. Convergence: `|R| <= abs_tol` or `|R| <= rel_tol |R_0|`, checked after assembly,
//! so a linear problem stops after one solve and one confirming assembly.
//!
//! With `reuse_factorization`, iterations after the first (and the first too, when the solver
//! still holds a factorisation of a matrix with the same pattern, e.g. from the previous time
//! step on an unchanged mesh, and offers it: [`LinearSolver::offer_held_factorization`]) solve
//! `K(x_k) dx = -R(x_k)` with the factors of an earlier `K` as a preconditioner: the linear
//! solver's iterative refinement
//! against the current `K` (see [`LinearSolver::solve_in_place`]) either reaches its accuracy
//! (then the step is a Newton step up to that linear residual, and no numeric factorisation is
//! paid) or fails, and `K(x_k)` is factorised after all. An iteration whose residual is not at
//! most a quarter of the one before factorises. In 3D FSI runs the
//! numeric factorisation is over 90 % of a step, so this saves most of the second and third
//! factorisations of a step.
//!
//! With `line_search`, a step after which `|R|` did not decrease is halved and `R` assembled
//! again there, until it does (Armijo) or [`MAX_HALVINGS`] halvings found no decrease
//! ([`NewtonError::LineSearch`]). A step to a point where the assembly fails (an inverted solid
//! element: `R` is not defined there) is halved alike.

use super::linear::{LinearSolveError, LinearSolver, SolveStats};
use super::partition::{Partition, RowSolver};
use fdfsi_fem::sparse::{CscMatrix, Pattern, RowMatrix, RowPattern};
use thiserror::Error;

/// Newton options.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NewtonOptions {
    /// Maximum number of linear solves (but see `grace_iterations`).
    pub max_iterations: usize,
    /// Linear solves past `max_iterations` a solve may take while it converges fast: each only
    /// after an iteration that cut `|R|` at least tenfold ([`GRACE_CONTRACTION`]); default 3. A
    /// time step's solve that reaches the cap quadratically converging (the closed 3D valve:
    /// `|R|` 2.5e3, 2.6e2, 2.3 at its 10th-12th iterations, the tolerance 0.2) is a step away
    /// from converging, where failing it cuts the step and solves it twice over; one that
    /// stalls (`|R|` 1.0e3, 9.3e2, 8.6e2) fails at the cap as before.
    pub grace_iterations: usize,
    /// Absolute tolerance on the Euclidean norm of the residual.
    pub abs_tol: f64,
    /// Tolerance relative to the first residual.
    pub rel_tol: f64,
    /// Reuse the last factorisation in later iterations while it is accurate enough (see the
    /// module documentation); default false (full Newton).
    pub reuse_factorization: bool,
    /// Backtracking line search: a step after which `|R|` did not decrease (Armijo:
    /// `|R(x + l dx)| <= (1 - 1e-4 l) |R(x)|`), or to where the assembly fails (an inverted
    /// element), is halved, up to [`MAX_HALVINGS`] times. Unset
    /// (the default): on for steady flows, off for time steps, where a non-monotone residual is
    /// common on the way to convergence (model problem 1: 3-4 iterations per step without, up to
    /// 8 with) and a failing step is cut instead.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub line_search: Option<bool>,
    /// Steady flows: when Newton fails from rest, solve at a larger viscosity first and
    /// continue in it to the case's own (see `discretize::flow::solve_steady`); default true.
    pub continuation: bool,
    /// Inexact Newton: with a Krylov linear solver, each iteration's linear solve stops at the
    /// forcing term of [`forcing_term`] (at most [`MAX_FORCING`]) rather than at the solver's
    /// own tolerance; default true. Direct solvers are unaffected; the flow solves turn it off
    /// for linear (Stokes) problems, where a loose first solve would only cost a second one.
    pub inexact: bool,
}

/// The contraction `|R_k| / |R_k-1|` at most of the iteration before each of the
/// [`NewtonOptions::grace_iterations`].
pub const GRACE_CONTRACTION: f64 = 0.1;

/// Most halvings of one Newton step by the line search.
pub const MAX_HALVINGS: usize = 10;
/// The line search leaves steps from residuals below this many times the tolerance alone: there
/// the residual is round-off, and need not decrease.
const LINE_SEARCH_FLOOR: f64 = 100.0;

impl Default for NewtonOptions {
    fn default() -> Self {
        NewtonOptions {
            max_iterations: 20,
            grace_iterations: 3,
            abs_tol: 1e-10,
            rel_tol: 1e-10,
            reuse_factorization: false,
            line_search: None,
            continuation: true,
            inexact: true,
        }
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
    /// Krylov iterations of each linear solve (zeros for a direct solver).
    pub krylov_iterations: Vec<usize>,
    /// Halvings of Newton steps by the line search.
    pub halvings: usize,
    /// Numeric factorisations done (one per iteration without `reuse_factorization`).
    pub factorizations: usize,
    /// Whether the factorisation held from an earlier solve was tried first and served (`None`:
    /// not tried, see [`LinearSolver::offer_held_factorization`]).
    pub held_factorization: Option<bool>,
    /// Seconds spent assembling, factorising and solving.
    pub assemble_seconds: f64,
    pub factorize_seconds: f64,
    pub solve_seconds: f64,
}

impl NewtonReport {
    /// Adds the work of `other` (iterations, Krylov iterations, halvings, factorisations,
    /// seconds) to this report; residual histories are left alone.
    pub fn add(&mut self, other: &NewtonReport) {
        self.iterations += other.iterations;
        self.krylov_iterations.extend_from_slice(&other.krylov_iterations);
        self.halvings += other.halvings;
        self.factorizations += other.factorizations;
        self.assemble_seconds += other.assemble_seconds;
        self.factorize_seconds += other.factorize_seconds;
        self.solve_seconds += other.solve_seconds;
    }
}

/// A Newton failure.
#[derive(Debug, Error)]
pub enum NewtonError<E: std::error::Error + 'static> {
    #[error("assembly failed: {0}")]
    Assembly(#[source] E),
    /// A partitioned assembly failed on another MPI rank (which reports the cause).
    #[error("assembly failed on another MPI rank (its error tells the cause)")]
    AssemblyOnAnotherRank,
    #[error(transparent)]
    Linear(#[from] LinearSolveError),
    #[error("Newton did not converge in {iterations} iterations: residual {residual:.3e} (tolerance {tolerance:.1e}); raise solver.newton.max_iterations, or reduce the time step (time-dependent runs)")]
    NotConverged { iterations: usize, residual: f64, tolerance: f64 },
    #[error("Newton iteration {iteration} found no decrease of the residual {residual:.3e} along its direction (the step halved {MAX_HALVINGS} times): the start is too far from a solution; reduce the time step (time-dependent runs)")]
    LineSearch { iteration: usize, residual: f64 },
    #[error("the residual became non-finite (NaN or infinity) at Newton iteration {iteration}")]
    NonFinite { iteration: usize },
}

/// The largest forcing term of the inexact Newton method ([`forcing_term`]).
pub const MAX_FORCING: f64 = 1e-2;

/// The relative linear residual `eta_k` that the solve of Newton iteration `k` needs, from the
/// residual norms `|R_0|, ..., |R_k|` so far and the Newton tolerance (Eisenstat & Walker, SISC
/// 17, 1996, choice 2 with `gamma = 0.9`, `alpha = 2`; their safeguard `0.9 eta_k-1^2`, which
/// acts only above 0.1, never does under `eta_max` = [`MAX_FORCING`]):
///
/// ```text
/// eta_0 = eta_max,   eta_k = min(eta_max, max(0.9 (|R_k| / |R_k-1|)^2, 0.5 tol / |R_k|))
/// ```
///
/// Far from the solution a loose solve serves as well as an exact one; as Newton converges
/// quadratically, `eta_k` shrinks like the residual, so the quadratic convergence is kept. The
/// last term (Kelley) stops the final iteration from solving more accurately than the tolerance
/// needs. `eta_max` is small because here a Newton iteration (assembly and factorisation) costs
/// several Krylov iterations. Non-finite values give `eta_max`.
pub fn forcing_term(norms: &[f64], tol: f64) -> f64 {
    let r = norms.last().copied().unwrap_or(0.0);
    let eta = match norms.len() {
        n if n >= 2 => 0.9 * (r / norms[n - 2]).powi(2),
        _ => MAX_FORCING,
    };
    let eta = if r > 0.0 { eta.max(0.5 * tol / r) } else { eta };
    if eta.is_finite() {
        eta.min(MAX_FORCING)
    } else {
        MAX_FORCING
    }
}

/// Whether a solve `past` iterations beyond its cap may take another: fewer than
/// [`NewtonOptions::grace_iterations`] past, and the last iteration cut `|R|` by
/// [`GRACE_CONTRACTION`] or more (`norms` the residual norms so far).
fn in_grace(norms: &[f64], past: usize, options: &NewtonOptions) -> bool {
    let n = norms.len();
    past < options.grace_iterations && n >= 2 && norms[n - 1] <= GRACE_CONTRACTION * norms[n - 2]
}

fn norm(v: &[f64]) -> f64 {
    sum_of_squares(v).sqrt()
}

/// Solves `R(x) = 0` from the initial iterate `x`. `assemble(x, K, rhs)` must fill the Jacobian
/// `K` and `rhs = -R(x)` (both given zeroed). The solver's forcing term
/// ([`LinearSolver::set_forcing`]) is reset when it returns, so later solves outside Newton use
/// the solver's own tolerance.
pub fn solve<E, F>(
    x: &mut [f64],
    pattern: &Pattern,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
    assemble: F,
) -> Result<NewtonReport, NewtonError<E>>
where
    E: std::error::Error + 'static,
    F: FnMut(&[f64], &mut CscMatrix<'_>, &mut [f64]) -> Result<(), E>,
{
    let mut system = Replicated { k: CscMatrix::zeros(pattern), solver };
    let result = iterate(x, &mut system, options, assemble);
    system.solver.set_forcing(0.0);
    result
}

/// [`solve`] with a partitioned assembly: `assemble(x, K, rhs)` fills this rank's rows of the
/// Jacobian and of `rhs = -R(x)` (those of `partition`, on `pattern`), from all of `x` (the
/// system's numbering, alike on every rank). Every rank calls this alike; the residual norms are
/// sums over the ranks ([`RowSolver::sum`]), so every rank takes the same branches, and each
/// update is the whole `dx` on every rank. On one rank it does the arithmetic of [`solve`],
/// except that no held factorisation is offered ([`LinearSolver::offer_held_factorization`]
/// takes a whole matrix).
pub fn solve_rows<E, F>(
    x: &mut [f64],
    partition: &Partition,
    pattern: &RowPattern,
    solver: &mut dyn RowSolver,
    options: &NewtonOptions,
    assemble: F,
) -> Result<NewtonReport, NewtonError<E>>
where
    E: std::error::Error + 'static,
    F: FnMut(&[f64], &mut RowMatrix<'_>, &mut [f64]) -> Result<(), E>,
{
    let mut system = Rows { k: RowMatrix::zeros(pattern), solver, partition };
    let result = iterate(x, &mut system, options, assemble);
    system.solver.set_forcing(0.0);
    result
}

/// The Jacobians and right-hand sides of one Newton solve: where they are held (whole on every
/// process, or each rank's rows) and how they are solved.
trait NewtonSystem {
    type Matrix;
    /// The Jacobian, zeroed.
    fn zeroed_matrix(&mut self) -> &mut Self::Matrix;
    /// The length of the right-hand side.
    fn rhs_len(&self) -> usize;
    /// The Euclidean norm of the right-hand side `rhs`.
    fn norm(&self, rhs: &[f64]) -> Result<f64, LinearSolveError>;
    /// Whether any rank's assembly `failed`.
    fn any_failed(&self, failed: bool) -> Result<bool, LinearSolveError>;
    fn solver(&mut self) -> &mut dyn LinearSolver;
    /// [`LinearSolver::offer_held_factorization`] for this system's matrix.
    fn offer_held_factorization(&mut self) -> bool;
    fn factorize(&mut self) -> Result<(), LinearSolveError>;
    /// `dx` (all unknowns) from the right-hand side `rhs`.
    fn solve(&self, rhs: &[f64], dx: &mut [f64]) -> Result<SolveStats, LinearSolveError>;
}

/// The whole system on every process, solved by a [`LinearSolver`].
struct Replicated<'p, 's> {
    k: CscMatrix<'p>,
    solver: &'s mut dyn LinearSolver,
}

impl<'p> NewtonSystem for Replicated<'p, '_> {
    type Matrix = CscMatrix<'p>;
    fn zeroed_matrix(&mut self) -> &mut CscMatrix<'p> {
        self.k.values.iter_mut().for_each(|v| *v = 0.0);
        &mut self.k
    }
    fn rhs_len(&self) -> usize {
        self.k.pattern.n
    }
    fn norm(&self, rhs: &[f64]) -> Result<f64, LinearSolveError> {
        Ok(sum_of_squares(rhs).sqrt())
    }
    fn any_failed(&self, failed: bool) -> Result<bool, LinearSolveError> {
        Ok(failed)
    }
    fn solver(&mut self) -> &mut dyn LinearSolver {
        self.solver
    }
    fn offer_held_factorization(&mut self) -> bool {
        self.solver.offer_held_factorization(&self.k)
    }
    fn factorize(&mut self) -> Result<(), LinearSolveError> {
        self.solver.factorize(&self.k)
    }
    fn solve(&self, rhs: &[f64], dx: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        dx.copy_from_slice(rhs);
        self.solver.solve_in_place(&self.k, dx)
    }
}

/// Each rank's rows of the system, solved by a [`RowSolver`].
struct Rows<'p, 's> {
    k: RowMatrix<'p>,
    solver: &'s mut dyn RowSolver,
    partition: &'p Partition,
}

impl<'p> NewtonSystem for Rows<'p, '_> {
    type Matrix = RowMatrix<'p>;
    fn zeroed_matrix(&mut self) -> &mut RowMatrix<'p> {
        self.k.values.iter_mut().for_each(|v| *v = 0.0);
        &mut self.k
    }
    fn rhs_len(&self) -> usize {
        self.k.pattern.rows.len()
    }
    fn norm(&self, rhs: &[f64]) -> Result<f64, LinearSolveError> {
        Ok(self.solver.sum(sum_of_squares(rhs))?.sqrt())
    }
    fn any_failed(&self, failed: bool) -> Result<bool, LinearSolveError> {
        Ok(self.solver.sum(f64::from(u8::from(failed)))? > 0.0)
    }
    fn solver(&mut self) -> &mut dyn LinearSolver {
        self.solver
    }
    /// A held factorisation is a [`LinearSolver`]'s of a whole matrix: none here.
    fn offer_held_factorization(&mut self) -> bool {
        false
    }
    fn factorize(&mut self) -> Result<(), LinearSolveError> {
        self.solver.factorize_rows(self.partition, &self.k)
    }
    fn solve(&self, rhs: &[f64], dx: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        self.solver.solve_rows(self.partition, &self.k, rhs, dx)
    }
}

fn sum_of_squares(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>()
}

fn iterate<S, E, F>(x: &mut [f64], system: &mut S, options: &NewtonOptions, mut assemble: F) -> Result<NewtonReport, NewtonError<E>>
where
    S: NewtonSystem,
    E: std::error::Error + 'static,
    F: FnMut(&[f64], &mut S::Matrix, &mut [f64]) -> Result<(), E>,
{
    let mut rhs = vec![0.0; system.rhs_len()];
    let mut dx = vec![0.0; x.len()];
    let mut report = NewtonReport::default();
    let mut r0 = None;
    // Whether the solver's factorisation may serve the next iteration: at first, one it holds
    // for this pattern (an earlier solve's), if it offers it.
    let mut reusable = options.reuse_factorization && system.offer_held_factorization();
    let mut held_trial = reusable;
    // The last update and the fraction `l` of it taken, for the line search.
    let mut last_step: Option<(Vec<f64>, f64)> = None;
    loop {
        let t = std::time::Instant::now();
        rhs.iter_mut().for_each(|v| *v = 0.0);
        let assembled = assemble(x, system.zeroed_matrix(), &mut rhs);
        // Every rank sees an error where any failed (else the others would go on alone).
        let failed = system.any_failed(assembled.is_err())?;
        let assembly_error = |assembled: Result<(), E>| assembled.err().map_or(NewtonError::AssemblyOnAnotherRank, NewtonError::Assembly);
        // A trial point of the line search where the residual is not defined (an element
        // turned inside out) is a step without decrease: halved like one (the domain error of
        // PETSc's line searches). At the first point, or without the search, the error stands.
        let searching = options.line_search == Some(true) && last_step.is_some();
        if failed && !searching {
            return Err(assembly_error(assembled));
        }
        report.assemble_seconds += t.elapsed().as_secs_f64();
        let r = if failed { f64::NAN } else { system.norm(&rhs)? };
        if let (Some((dx, l)), Some(&previous), Some(&first)) = (last_step.as_mut(), report.residual_norms.last(), report.residual_norms.first()) {
            // Sufficient decrease (Armijo, c = 1e-4); false for a failed assembly's NaN.
            let decreased = r <= (1.0 - 1e-4 * *l) * previous;
            // Near the tolerance the residual is round-off: no search there.
            let near_tolerance = previous <= LINE_SEARCH_FLOOR * options.abs_tol.max(options.rel_tol * first);
            // A failed assembly is no round-off: halved near the tolerance too.
            if options.line_search == Some(true) && !decreased && (failed || !near_tolerance) {
                if *l <= 0.5f64.powi(MAX_HALVINGS as i32) {
                    // No decrease along the Newton direction: more iterations will not help.
                    let back = *l;
                    x.iter_mut().zip(dx.iter()).for_each(|(xi, d)| *xi -= back * d); // x_k again
                    return Err(if failed {
                        assembly_error(assembled)
                    } else {
                        NewtonError::LineSearch { iteration: report.iterations, residual: previous }
                    });
                }
                // Back from x_k + l dx to x_k + l/2 dx, and assemble there.
                *l *= 0.5;
                let back = *l;
                x.iter_mut().zip(dx.iter()).for_each(|(xi, d)| *xi -= back * d);
                report.halvings += 1;
                match &assembled {
                    Err(e) => {
                        tracing::debug!("newton {}: assembly failed after {} of the Newton step ({e}): back to {back}", report.iterations, 2.0 * back)
                    }
                    Ok(()) => tracing::debug!("newton {}: |R| = {r:.4e} after {} of the Newton step: back to {back}", report.iterations, 2.0 * back),
                }
                continue;
            }
        }
        if !r.is_finite() {
            return Err(NewtonError::NonFinite { iteration: report.iterations });
        }
        report.residual_norms.push(r);
        // Every iteration, failed solves' included (the report of a failed solve is not kept).
        tracing::debug!("newton {}: |R| = {r:.4e}", report.iterations);
        let r0v = *r0.get_or_insert(r);
        let tol = options.abs_tol.max(options.rel_tol * r0v);
        if r <= tol && (report.iterations > 0 || r <= options.abs_tol) {
            return Ok(report);
        }
        if report.iterations >= options.max_iterations && !in_grace(&report.residual_norms, report.iterations - options.max_iterations, options) {
            return Err(NewtonError::NotConverged { iterations: report.iterations, residual: r, tolerance: tol });
        }
        let forcing = if options.inexact { forcing_term(&report.residual_norms, tol) } else { 0.0 };
        system.solver().set_forcing(forcing);
        let mut solved = false;
        // A reused factorisation must have contracted the residual well, or this step refactorises.
        let n = report.residual_norms.len();
        let contracting = n < 2 || report.residual_norms[n - 1] <= 0.25 * report.residual_norms[n - 2];
        if options.reuse_factorization && reusable && contracting {
            let t = std::time::Instant::now();
            // Any failure of the reused factors (inaccurate, or not finite) means: factorise.
            if let Ok(stats) = system.solve(&rhs, &mut dx) {
                solved = true;
                report.krylov_iterations.push(stats.krylov_iterations);
            }
            report.solve_seconds += t.elapsed().as_secs_f64();
            if held_trial {
                report.held_factorization = Some(solved);
                system.solver().held_factorization_served(solved);
            }
        }
        held_trial = false;
        if !solved {
            let t = std::time::Instant::now();
            system.factorize()?;
            report.factorize_seconds += t.elapsed().as_secs_f64();
            report.factorizations += 1;
            let t = std::time::Instant::now();
            let stats = system.solve(&rhs, &mut dx)?;
            report.krylov_iterations.push(stats.krylov_iterations);
            report.solve_seconds += t.elapsed().as_secs_f64();
            reusable = true;
        }
        for (xi, d) in x.iter_mut().zip(&dx) {
            *xi += d;
        }
        if options.line_search == Some(true) {
            last_step = Some((dx.clone(), 1.0));
        }
        report.update_norms.push(norm(&dx));
        report.iterations += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::linear::FaerLu;
    use std::convert::Infallible;

    #[test]
    fn forcing_terms_follow_the_residual_and_stay_bounded() {
        // The first solve, and any step from a vanishing or non-finite residual: the largest term.
        assert_eq!(forcing_term(&[1.0], 1e-10), MAX_FORCING);
        assert_eq!(forcing_term(&[1.0, f64::NAN], 1e-10), MAX_FORCING);
        // Quadratic convergence: 0.9 (|R_k| / |R_k-1|)^2.
        assert!((forcing_term(&[1.0, 1e-2], 1e-12) - 0.9e-4).abs() < 1e-16);
        // A slow contraction is capped.
        assert_eq!(forcing_term(&[1.0, 0.5], 1e-12), MAX_FORCING);
        // Near the tolerance: no more accuracy than it needs (0.5 tol / |R_k|).
        assert!((forcing_term(&[1.0, 1e-6, 1e-9], 1e-10) - 0.05f64.min(MAX_FORCING)).abs() < 1e-16);
        assert!((forcing_term(&[1.0, 1e-4, 1e-8], 1e-12) - 5e-5).abs() < 1e-16);
    }

    /// The chain's Jacobian (added into `values` at the positions `find(i, j)`) and `-R(x)`
    /// (into `rhs`; see [`solve_chain`]) for the right-hand side `b`.
    fn chain_system(x: &[f64], b: &[f64], find: impl Fn(usize, usize) -> usize, values: &mut [f64], rhs: &mut [f64]) {
        let n = x.len();
        for i in 0..n {
            let mut r = 2.0 * x[i] + 0.5 * x[i].powi(3) - b[i];
            values[find(i, i)] += 2.0 + 1.5 * x[i] * x[i];
            for j in [i.wrapping_sub(1), i + 1].into_iter().filter(|&j| j < n) {
                r -= x[j];
                values[find(i, j)] -= 1.0;
            }
            rhs[i] = -r;
        }
    }

    /// `R(x)_i = 2 x_i - x_{i-1} - x_{i+1} + 0.5 x_i^3 - b_i` on a chain: nonlinear, with a
    /// Jacobian that changes from iteration to iteration.
    fn solve_chain(reuse: bool) -> (Vec<f64>, NewtonReport) {
        solve_chain_with(reuse, &mut FaerLu::default(), 1.0, vec![0.0; 40])
    }

    /// The chain with right-hand side `scale * b`, solved from `x` with `lu`.
    fn solve_chain_with(reuse: bool, lu: &mut FaerLu, scale: f64, mut x: Vec<f64>) -> (Vec<f64>, NewtonReport) {
        let n = 40;
        let p = Pattern::from_cells(n, n - 1, |c, b| {
            b.clear();
            b.extend([c, c + 1]);
        });
        let b: Vec<f64> = (0..n).map(|i| scale * (1.0 + (i as f64 * 0.4).sin())).collect();
        let options = NewtonOptions { abs_tol: 1e-12, rel_tol: 1e-14, reuse_factorization: reuse, ..Default::default() };
        let report = solve(&mut x, &p, lu, &options, |x, k, rhs| {
            chain_system(x, &b, |i, j| p.find(i, j).unwrap(), &mut k.values, rhs);
            Ok::<(), Infallible>(())
        })
        .unwrap();
        (x, report)
    }

    /// The chain through a partitioned assembly on one rank ([`solve_rows`] with
    /// [`SerialRows`]): the same iterates and residuals as [`solve`], bit for bit, with and
    /// without reused factorisations.
    #[test]
    fn a_partitioned_newton_on_one_rank_is_the_replicated_one() {
        use crate::solve::partition::{Nodes, SerialRows, World};
        let n = 40;
        let chain = |c: usize, b: &mut Vec<usize>| {
            b.clear();
            b.extend([c, c + 1]);
        };
        let partition = Partition::from_cells(n, n - 1, chain, World { rank: 0, size: 1 }, Nodes::SCALAR);
        let cells = partition.cells_of_rows(n - 1, chain);
        let p = partition.row_pattern(&cells, chain);
        let b: Vec<f64> = (0..n).map(|i| 1.0 + (i as f64 * 0.4).sin()).collect();
        for reuse in [false, true] {
            let options = NewtonOptions { abs_tol: 1e-12, rel_tol: 1e-14, reuse_factorization: reuse, ..Default::default() };
            let mut x = vec![0.0; n];
            let mut rows = SerialRows::new(FaerLu::default());
            let report = solve_rows(&mut x, &partition, &p, &mut rows, &options, |x, k, rhs| {
                chain_system(x, &b, |i, j| p.find(i, j).unwrap(), &mut k.values, rhs);
                Ok::<(), Infallible>(())
            })
            .unwrap();
            let (expected, replicated) = solve_chain(reuse);
            assert_eq!(x.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), expected.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
            assert_eq!(report.residual_norms, replicated.residual_norms);
            assert_eq!(report.factorizations, replicated.factorizations);
        }
    }

    /// `R(x) = x^2 - 2` from `x = 64` halves `x` for five iterations before converging
    /// quadratically, in 10: with a cap of 8 it fails without grace iterations and converges with
    /// them (the 8th cut `|R|` 290-fold). `R(x) = x^2 + 1` has no root: its iterates never
    /// cut `|R|` tenfold, and the solve fails at the cap, grace or not.
    #[test]
    fn a_solve_still_converging_fast_at_its_cap_takes_grace_iterations() {
        let p = Pattern::from_cells(1, 1, |_, b| {
            b.clear();
            b.push(0);
        });
        let square = |c: f64| {
            move |x: &[f64], k: &mut CscMatrix<'_>, rhs: &mut [f64]| {
                k.values[0] = 2.0 * x[0];
                rhs[0] = -(x[0] * x[0] + c);
                Ok::<(), Infallible>(())
            }
        };
        let capped = |max_iterations, grace_iterations| NewtonOptions {
            max_iterations,
            grace_iterations,
            rel_tol: 1e-20,
            line_search: Some(false),
            ..Default::default()
        };
        let mut x = vec![64.0];
        let full = solve(&mut x, &p, &mut FaerLu::default(), &capped(20, 0), square(-2.0)).unwrap();
        assert_eq!(full.iterations, 10);
        let mut x = vec![64.0];
        assert!(matches!(
            solve(&mut x, &p, &mut FaerLu::default(), &capped(8, 0), square(-2.0)),
            Err(NewtonError::NotConverged { iterations: 8, .. })
        ));
        let mut x = vec![64.0];
        let graced = solve(&mut x, &p, &mut FaerLu::default(), &capped(8, 3), square(-2.0)).unwrap();
        assert_eq!(graced.iterations, 10);
        assert!((x[0] - 2f64.sqrt()).abs() < 1e-12);
        let mut x = vec![3.0];
        assert!(matches!(
            solve(&mut x, &p, &mut FaerLu::default(), &capped(8, 3), square(1.0)),
            Err(NewtonError::NotConverged { iterations: 8, .. })
        ));
    }

    /// `R(x) = atan(x)` from `x = 2`: full Newton steps overshoot further each time and diverge;
    /// with the line search they are halved until `|R|` decreases, and Newton converges to 0.
    #[test]
    fn the_line_search_turns_a_diverging_newton_into_a_converging_one() {
        let p = Pattern::from_cells(1, 1, |_, b| {
            b.clear();
            b.push(0);
        });
        let atan = |x: &[f64], k: &mut CscMatrix<'_>, rhs: &mut [f64]| {
            k.values[0] = 1.0 / (1.0 + x[0] * x[0]);
            rhs[0] = -x[0].atan();
            Ok::<(), Infallible>(())
        };
        let plain = NewtonOptions { line_search: Some(false), max_iterations: 8, ..Default::default() };
        let mut x = vec![2.0];
        assert!(solve(&mut x, &p, &mut FaerLu::default(), &plain, atan).is_err(), "plain Newton diverges: x = {x:?}");
        let damped = NewtonOptions { line_search: Some(true), ..Default::default() };
        let mut x = vec![2.0];
        let report = solve(&mut x, &p, &mut FaerLu::default(), &damped, atan).unwrap();
        assert!(x[0].abs() < 1e-10 && report.halvings > 0, "x = {x:?}, {} halvings", report.halvings);
    }

    /// `R(x) = ln x` from `x = 3`: the full Newton step lands at `x = -0.30`, where `R` is not
    /// defined (as an inverted element's stress); the line search halves it like a step without
    /// decrease, and Newton converges to 1. Without the search, the assembly's error stands.
    #[test]
    fn the_line_search_halves_a_step_to_where_the_assembly_fails() {
        #[derive(Debug, Error)]
        #[error("ln x at x = {0} <= 0")]
        struct Domain(f64);
        let p = Pattern::from_cells(1, 1, |_, b| {
            b.clear();
            b.push(0);
        });
        let ln = |x: &[f64], k: &mut CscMatrix<'_>, rhs: &mut [f64]| {
            if x[0] <= 0.0 {
                return Err(Domain(x[0]));
            }
            k.values[0] = 1.0 / x[0];
            rhs[0] = -x[0].ln();
            Ok(())
        };
        let plain = NewtonOptions { line_search: Some(false), ..Default::default() };
        let mut x = vec![3.0];
        let err = solve(&mut x, &p, &mut FaerLu::default(), &plain, ln).unwrap_err();
        assert!(matches!(err, NewtonError::Assembly(Domain(v)) if v < 0.0), "{err}");
        let damped = NewtonOptions { line_search: Some(true), ..Default::default() };
        let mut x = vec![3.0];
        let report = solve(&mut x, &p, &mut FaerLu::default(), &damped, ln).unwrap();
        assert!((x[0] - 1.0).abs() < 1e-10 && report.halvings == 1, "x = {x:?}, {} halvings", report.halvings);
    }

    #[test]
    fn reusing_the_factorisation_reaches_the_same_root_with_fewer_factorisations() {
        let (full, rf) = solve_chain(false);
        let (reused, rr) = solve_chain(true);
        assert_eq!(rf.factorizations, rf.iterations);
        assert!(rr.factorizations < rr.iterations, "{} factorisations in {} iterations", rr.factorizations, rr.iterations);
        assert!(*rr.residual_norms.last().unwrap() <= 1e-12);
        let diff = full.iter().zip(&reused).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(diff < 1e-11, "{diff}");
    }

    #[test]
    fn held_factorisations_that_fail_are_offered_less_often() {
        // Solves from x = 3 and x = 0 in turn: the held factors (of the Jacobian at the last
        // solve's start, 2 + 13.5 or 2 on the diagonal) do not serve the next. After k failures
        // in a row the next 2^k - 1 solves factorise without trying.
        let mut lu = FaerLu::default();
        let mut tries = Vec::new();
        for k in 0..8 {
            let (_, r) = solve_chain_with(true, &mut lu, 1.0, vec![if k % 2 == 0 { 3.0 } else { 0.0 }; 40]);
            tries.push(r.held_factorization);
        }
        let f = Some(false);
        assert_eq!(tries, vec![None, f, None, f, None, None, None, f]);
    }

    #[test]
    fn a_held_factorisation_of_the_same_pattern_serves_the_next_solve() {
        // As the next time step on an unchanged mesh: a nearby system, same pattern.
        let mut lu = FaerLu::default();
        let (x1, first) = solve_chain_with(true, &mut lu, 1.0, vec![0.0; 40]);
        let (x, next) = solve_chain_with(true, &mut lu, 1.001, x1.clone());
        assert!(first.factorizations >= 1);
        assert_eq!(next.factorizations, 0, "the held factorisation preconditions the next solve");
        assert_eq!(next.held_factorization, Some(true));
        let (full, _) = solve_chain_with(false, &mut FaerLu::default(), 1.001, x1);
        let diff = full.iter().zip(&x).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(diff < 1e-11, "{diff}");
    }
}
