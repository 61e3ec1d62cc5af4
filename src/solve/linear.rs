//! Linear solvers for the monolithic system, behind one trait.
//!
//! The default backend is faer's sparse LU (pure Rust). The symbolic factorisation (fill-reducing
//! ordering, elimination structure) depends only on the [`Pattern`] and is computed once per
//! pattern; every Newton iteration only refactors numerically. After each solve the residual
//! `|b - A x| / |b|` is checked and the solution refined iteratively (`x += A^{-1} r`) while it is
//! above [`LinearSolverOptions::refine_tolerance`].

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuRef, NumericLu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Par};
use fdfsi_fem::sparse::{CscMatrix, Pattern};
use thiserror::Error;

/// A failure of the linear solve.
#[derive(Debug, Error)]
pub enum LinearSolveError {
    #[error("symbolic LU factorisation failed: {0}")]
    Symbolic(String),
    #[error("numeric LU factorisation failed (singular or ill-posed system: check boundary conditions): {0}")]
    Numeric(String),
    #[error("linear solve is inaccurate: relative residual {residual:.3e} after {refinements} refinement steps (tolerance {tolerance:.1e})")]
    Inaccurate { residual: f64, refinements: usize, tolerance: f64 },
    #[error("the linear solve produced a non-finite value (NaN or infinity)")]
    NonFinite,
}

/// Options of the linear solve.
#[derive(Clone, Debug)]
pub struct LinearSolverOptions {
    /// Refine while `|b - A x| / |b|` exceeds this.
    pub refine_tolerance: f64,
    /// Fail when the residual is still above this after refinement.
    pub fail_tolerance: f64,
    /// Maximum refinement steps.
    pub max_refinements: usize,
}

impl Default for LinearSolverOptions {
    fn default() -> Self {
        LinearSolverOptions { refine_tolerance: 1e-12, fail_tolerance: 1e-6, max_refinements: 3 }
    }
}

/// Statistics of the last solve.
#[derive(Clone, Debug, Default)]
pub struct SolveStats {
    pub residual: f64,
    pub refinements: usize,
}

/// A direct or iterative solver for `A x = b` on a fixed pattern.
pub trait LinearSolver {
    /// Factorises `a` (symbolic work only when the pattern changed).
    fn factorize(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError>;
    /// Solves with the last factorisation, overwriting `rhs` with `x`; `a` is the matrix that
    /// was factorised (used for the residual check).
    fn solve_in_place(&self, a: &CscMatrix<'_>, rhs: &mut [f64]) -> Result<SolveStats, LinearSolveError>;
    /// Number of symbolic factorisations done so far.
    fn symbolic_factorizations(&self) -> usize;
}

/// faer's sparse LU with the symbolic factorisation cached per pattern. The numeric factors and
/// the factorisation workspace are kept between factorisations, so a Newton iteration allocates
/// nothing large.
pub struct FaerLu {
    options: LinearSolverOptions,
    symbolic: Option<(u64, SymbolicLu<usize>)>,
    numeric: NumericLu<usize, f64>,
    workspace: MemBuffer,
    factorized: bool,
    symbolic_count: usize,
}

impl FaerLu {
    /// A solver with the given options.
    pub fn new(options: LinearSolverOptions) -> Self {
        FaerLu {
            options,
            symbolic: None,
            numeric: NumericLu::new(),
            workspace: MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
            factorized: false,
            symbolic_count: 0,
        }
    }

    fn par() -> Par {
        faer::get_global_parallelism()
    }
}

impl Default for FaerLu {
    fn default() -> Self {
        Self::new(LinearSolverOptions::default())
    }
}

/// Identity of a pattern by content: a hash of its index arrays (O(nnz), negligible next to a
/// factorisation), so a symbolic factorisation is reused exactly when the structure is the same.
fn pattern_key(p: &Pattern) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    p.n.hash(&mut h);
    p.col_ptr.hash(&mut h);
    p.row_idx.hash(&mut h);
    h.finish()
}

fn faer_view<'a>(a: &'a CscMatrix<'_>) -> SparseColMatRef<'a, usize, f64> {
    let p = a.pattern;
    // SAFETY: `Pattern` stores sorted, in-range row indices per column and monotone column
    // pointers; its construction guarantees the invariants faer requires.
    let sym = unsafe { SymbolicSparseColMatRef::new_unchecked(p.n, p.n, &p.col_ptr, None, &p.row_idx) };
    SparseColMatRef::new(sym, &a.values)
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

impl LinearSolver for FaerLu {
    fn factorize(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
        let key = pattern_key(a.pattern);
        let view = faer_view(a);
        let par = Self::par();
        self.factorized = false;
        if self.symbolic.as_ref().map(|(k, _)| *k) != Some(key) {
            let s = factorize_symbolic_lu(view.symbolic(), Default::default())
                .map_err(|e| LinearSolveError::Symbolic(format!("{e:?}")))?;
            let req = s.factorize_numeric_lu_scratch::<f64>(par, Default::default());
            self.workspace = MemBuffer::try_new(req).map_err(|e| LinearSolveError::Symbolic(format!("workspace: {e:?}")))?;
            self.symbolic = Some((key, s));
            self.symbolic_count += 1;
        }
        let symbolic = &self.symbolic.as_ref().expect("set above").1;
        symbolic
            .factorize_numeric_lu(&mut self.numeric, view, par, MemStack::new(&mut self.workspace), Default::default())
            .map_err(|e| LinearSolveError::Numeric(format!("{e:?}")))?;
        self.factorized = true;
        Ok(())
    }

    fn solve_in_place(&self, a: &CscMatrix<'_>, rhs: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        let symbolic = match (&self.symbolic, self.factorized) {
            (Some((_, s)), true) => s,
            _ => return Err(LinearSolveError::Numeric("solve before a successful factorisation".into())),
        };
        let par = Self::par();
        let lu = LuRef::new_unchecked(symbolic, &self.numeric);
        let mut scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, par));
        let n = rhs.len();
        let b = rhs.to_vec();
        let bnorm = norm(&b).max(f64::MIN_POSITIVE);
        lu.solve_in_place_with_conj(Conj::No, faer::MatMut::from_column_major_slice_mut(rhs, n, 1), par, MemStack::new(&mut scratch));
        let mut r = vec![0.0; n];
        let residual = |x: &[f64], r: &mut Vec<f64>| -> f64 {
            a.mul_vec(x, r);
            for (ri, bi) in r.iter_mut().zip(&b) {
                *ri = bi - *ri;
            }
            norm(r) / bnorm
        };
        let mut res = residual(rhs, &mut r);
        let mut refinements = 0;
        while res > self.options.refine_tolerance && refinements < self.options.max_refinements && res.is_finite() {
            lu.solve_in_place_with_conj(Conj::No, faer::MatMut::from_column_major_slice_mut(&mut r, n, 1), par, MemStack::new(&mut scratch));
            for (x, d) in rhs.iter_mut().zip(&r) {
                *x += d;
            }
            refinements += 1;
            res = residual(rhs, &mut r);
        }
        if !res.is_finite() || rhs.iter().any(|x| !x.is_finite()) {
            return Err(LinearSolveError::NonFinite);
        }
        if res > self.options.fail_tolerance {
            return Err(LinearSolveError::Inaccurate { residual: res, refinements, tolerance: self.options.fail_tolerance });
        }
        Ok(SolveStats { residual: res, refinements })
    }

    fn symbolic_factorizations(&self) -> usize {
        self.symbolic_count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_small_nonsymmetric_system_and_caches_symbolic() {
        // 1D convection-diffusion-like chain, nonsymmetric.
        let n = 50;
        let cells: Vec<[usize; 2]> = (0..n - 1).map(|i| [i, i + 1]).collect();
        let p = Pattern::from_cells(n, n - 1, |c, b| {
            b.clear();
            b.extend_from_slice(&cells[c]);
        });
        let mut a = CscMatrix::zeros(&p);
        for (c, e) in cells.iter().enumerate() {
            let w = 1.0 + c as f64 * 0.01;
            let ke = [[2.0 * w, -w - 0.3], [-w + 0.3, 2.0 * w]];
            for i in 0..2 {
                for j in 0..2 {
                    let k = p.find(e[i], e[j]).unwrap();
                    a.values[k] += ke[i][j];
                }
            }
        }
        let x_exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut b = vec![0.0; n];
        a.mul_vec(&x_exact, &mut b);
        let mut lu = FaerLu::default();
        lu.factorize(&a).unwrap();
        let stats = lu.solve_in_place(&a, &mut b).unwrap();
        assert!(stats.residual < 1e-13);
        for i in 0..n {
            assert!((b[i] - x_exact[i]).abs() < 1e-10);
        }
        // New values, same pattern: numeric only.
        for v in a.values.iter_mut() {
            *v *= 1.5;
        }
        lu.factorize(&a).unwrap();
        assert_eq!(lu.symbolic_factorizations(), 1);
    }

    #[test]
    fn singular_system_is_an_error_not_a_panic() {
        let p = Pattern::from_cells(2, 1, |_, b| {
            b.clear();
            b.extend_from_slice(&[0, 1]);
        });
        let a = CscMatrix::zeros(&p);
        let mut lu = FaerLu::default();
        let r = lu.factorize(&a).and_then(|_| lu.solve_in_place(&a, &mut [1.0, 1.0]).map(|_| ()));
        assert!(r.is_err());
    }
}
