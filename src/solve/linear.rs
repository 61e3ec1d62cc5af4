//! Linear solvers for the monolithic system, behind one trait.
//!
//! The default backend is a supernodal LU on the symmetric structure of the pattern built on
//! faer's dense kernels and symbolic Cholesky analysis (`StaticLu`: constrained nested-dissection
//! or AMD ordering, chosen by the system's size and dimension, [`FillOrdering`]; pivoting only inside supernode diagonal blocks), validated
//! after each factorisation and backed by faer's sparse partial-pivoting LU (pure Rust). The
//! symbolic factorisation (fill-reducing ordering, elimination structure) depends only on the
//! [`Pattern`] and is computed once per pattern (or kept for a slightly changed one, with
//! [`LinearSolverOptions::reuse_analysis`]); every Newton iteration only refactors numerically.
//! After each solve the residual `|b - A x| / |b|` is checked and the solution refined iteratively (`x += A^{-1} r`) while it is
//! above [`LinearSolverOptions::refine_tolerance`].
//!
//! Why a factorisation of our own beside faer's: faer's sparse LU bounds its static structure by
//! the column elimination tree of `A^T A` (George-Ng), which for the structurally symmetric
//! finite-element saddle-point matrices here is far denser than the symmetric structure. Ours uses
//! faer's symbolic Cholesky analysis of that symmetric structure (with the pressure dofs ordered
//! after their velocity neighbours, so no pivot is structurally zero) and faer's dense kernels;
//! measured 1.3-1.6x faster numeric factorisation on the Schaefer-Turek meshes (BENCHMARKS.md).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::reborrow::{Reborrow, ReborrowMut};
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
    /// The static LU met a pivot below `1e-2 eps` times the largest entry at `unknown` (the
    /// caller's numbering), `step`-th in the elimination order; pivot and entry are those of the
    /// equilibrated matrix `R A C` (rows and columns scaled to largest entries near 1).
    #[error("numeric LU factorisation failed (singular or ill-posed system: check boundary conditions): zero pivot {pivot:.3e} (largest entry {largest:.3e}, equilibrated) in the static LU at unknown {unknown} (elimination step {step})")]
    ZeroPivot { pivot: f64, largest: f64, unknown: usize, step: usize },
    #[error("linear solve is inaccurate: relative residual {residual:.3e} after {refinements} refinement steps (tolerance {tolerance:.1e})")]
    Inaccurate { residual: f64, refinements: usize, tolerance: f64 },
    #[error("FGMRES did not converge in {iterations} iterations: relative residual {residual:.3e} (tolerance {tolerance:.1e}); raise solver.linear.krylov_max_iterations or gamma, or use method = \"direct\"")]
    KrylovNotConverged { iterations: usize, residual: f64, tolerance: f64 },
    #[error("the linear solve produced a non-finite value (NaN or infinity)")]
    NonFinite,
    /// A PETSc call failed or its solve diverged (the `petsc` feature, `solve::petsc`).
    #[error("PETSc: {0}")]
    Petsc(String),
    /// A system handed to a solver that is not set up for it (a partitioned assembly's rows on
    /// other ranks, a solve before a factorisation).
    #[error("linear solver set-up: {0}")]
    Setup(String),
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
    /// Fill-reducing ordering of the static supernodal LU ([`LuMethod::Auto`]).
    pub ordering: FillOrdering,
    /// Threads of the dense kernels of the large supernodes (the separators at the top of the
    /// elimination tree, where 3D factorisations spend most of their flops): 1 = sequential,
    /// 0 = all cores.
    pub threads: usize,
    /// Check each static factorisation by a solve of a known system, and fall back to the
    /// partial-pivoting LU when it is inaccurate. Off for the inner solve of a Krylov method,
    /// whose convergence is the check.
    pub check_accuracy: bool,
    /// For a new pattern with the held analysis's size and zero-diagonal unknowns, keep the
    /// whole analysis (with a new scatter map) when every entry lies in the held factor
    /// structure (its fill then lies there too; a failed factorisation on it analyses afresh),
    /// and otherwise keep the ordering (a new symbolic analysis, without the nested dissection)
    /// while its flops stay within 1.1x of the analysis that ordered (else it orders afresh).
    /// On for the AL solver's inner LU, whose pattern grows by a few entries from FSI step to
    /// step ([`crate::discretize::fsi::CouplingPattern`]). Off for the direct solve, whose
    /// resumed runs repeat an uninterrupted run's arithmetic bit for bit (a resumed run analyses
    /// its first pattern afresh).
    pub reuse_analysis: bool,
}

impl Default for LinearSolverOptions {
    fn default() -> Self {
        LinearSolverOptions {
            refine_tolerance: 1e-12,
            fail_tolerance: 1e-6,
            max_refinements: 3,
            ordering: FillOrdering::default(),
            threads: 1,
            check_accuracy: true,
            reuse_analysis: false,
        }
    }
}

/// Fill-reducing ordering of the static supernodal LU. Both keep every zero-diagonal dof
/// (pressure, multiplier) after all its nonzero-diagonal neighbours, so no pivot is structurally
/// zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FillOrdering {
    /// Nested dissection where it pays, AMD elsewhere: nested dissection when the graph of the
    /// nonzero-diagonal dofs has at least [`AUTO_ND_MIN_DEGREE`] entries per row on average
    /// (3D P2+ discretisations: about 100; 2D: about 26) or at least [`AUTO_ND_MIN_DOFS`] rows.
    /// Measured (BENCHMARKS.md, "Orderings"): nested dissection needs 1.7-2.8x fewer flops in
    /// 3D, 25 % fewer on the 2D Schaefer-Turek medium mesh (145k dofs), and ties on 2D systems
    /// of 30-40k dofs, where its ordering costs twice AMD's: a 2D FSI run, which analyses a new
    /// pattern whenever the adapted mesh changes its topology, is faster with AMD.
    #[default]
    Auto,
    /// Multilevel nested dissection ([`super::ordering`]) of the nonzero-diagonal dofs.
    NestedDissection,
    /// faer's approximate minimum degree of the nonzero-diagonal dofs.
    Amd,
}

/// [`FillOrdering::Auto`] uses nested dissection from this many graph entries per row on average.
pub const AUTO_ND_MIN_DEGREE: usize = 50;
/// [`FillOrdering::Auto`] uses nested dissection from this many nonzero-diagonal dofs.
pub const AUTO_ND_MIN_DOFS: usize = 100_000;

/// Size and cost of the static LU factorisation in use (deterministic for a given pattern).
#[derive(Clone, Debug)]
pub struct FactorStats {
    pub ordering: FillOrdering,
    pub supernodes: usize,
    /// Stored entries of `L + U` (diagonal blocks once).
    pub nnz_lu: usize,
    /// Floating-point operations of one numeric factorisation (dense LU of the diagonal blocks,
    /// the two triangular solves and the Schur-complement update of each supernode).
    pub flops: f64,
    /// Of which in the supernodes large enough for threaded dense kernels
    /// ([`LinearSolverOptions::threads`]).
    pub threaded_flops: f64,
    /// Seconds spent in the fill-reducing ordering and in the whole symbolic analysis.
    pub ordering_seconds: f64,
    pub symbolic_seconds: f64,
    /// Unknowns that remove multiplier modes (zero diagonal, zero-diagonal neighbours only), and
    /// of those the ones in the supernode of their last multiplier (`merge_supernodes`).
    pub mode_unknowns: usize,
    pub mode_unknowns_joined: usize,
}

/// Statistics of the last solve.
#[derive(Clone, Debug, Default)]
pub struct SolveStats {
    pub residual: f64,
    pub refinements: usize,
    /// Krylov iterations (0 for a direct solve).
    pub krylov_iterations: usize,
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
    /// Whether to try, before factorising `a`, the factorisation held from an earlier `factorize`
    /// of a matrix with the pattern of `a` (as a preconditioner: `solve_in_place` refines against
    /// `a`). A Newton solve asks once, at its start; the answer may weigh how such tries went
    /// ([`LinearSolver::held_factorization_served`]).
    fn offer_held_factorization(&mut self, _a: &CscMatrix<'_>) -> bool {
        false
    }
    /// Reports whether the held factorisation that [`LinearSolver::offer_held_factorization`]
    /// offered served (the solve reached its accuracy) or the matrix had to be factorised.
    fn held_factorization_served(&mut self, _served: bool) {}
    /// The saddle-point structure of the systems to come (block preconditioners use it; direct
    /// solvers ignore it). Called whenever the discretisation changes.
    fn set_split(&mut self, _split: super::augmented::SaddlePointSplit) {}
    /// The relative residual the next `solve_in_place` needs to reach (an inexact Newton
    /// method's forcing term); iterative solvers stop there or at their own tolerance, whichever
    /// is larger; direct solvers ignore it. `0` restores the solver's own tolerance.
    fn set_forcing(&mut self, _relative_residual: f64) {}
    /// This solver as one of a partitioned assembly's systems ([`super::partition::RowSolver`]:
    /// each rank's own rows), where it takes those; `None` (the default): the whole system on
    /// every rank only.
    fn as_row_solver(&mut self) -> Option<&mut dyn super::partition::RowSolver> {
        None
    }
}

/// Which factorisation [`FaerLu`] uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LuMethod {
    /// The static-structure supernodal LU (`StaticLu`) with a constrained symmetric ordering,
    /// falling back to faer's partial-pivoting LU when it fails or its accuracy check does.
    #[default]
    Auto,
    /// faer's sparse LU with partial pivoting (COLAMD column ordering) only.
    Pivoting,
}

/// faer's sparse LU with partial pivoting, symbolic part cached.
struct PivotingLu {
    symbolic: SymbolicLu<usize>,
    numeric: NumericLu<usize, f64>,
    workspace: MemBuffer,
}

impl PivotingLu {
    fn new(a: SparseColMatRef<'_, usize, f64>, par: Par) -> Result<Self, LinearSolveError> {
        let symbolic = factorize_symbolic_lu(a.symbolic(), Default::default()).map_err(|e| LinearSolveError::Symbolic(format!("{e:?}")))?;
        let req = symbolic.factorize_numeric_lu_scratch::<f64>(par, Default::default());
        let workspace = MemBuffer::try_new(req).map_err(|e| LinearSolveError::Symbolic(format!("workspace: {e:?}")))?;
        Ok(PivotingLu { symbolic, numeric: NumericLu::new(), workspace })
    }

    fn factorize(&mut self, a: SparseColMatRef<'_, usize, f64>, par: Par) -> Result<(), LinearSolveError> {
        self.symbolic
            .factorize_numeric_lu(&mut self.numeric, a, par, MemStack::new(&mut self.workspace), Default::default())
            .map(|_| ())
            .map_err(|e| LinearSolveError::Numeric(format!("{e:?}")))
    }

    fn solve(&self, x: &mut [f64], par: Par) {
        let lu = LuRef::new_unchecked(&self.symbolic, &self.numeric);
        let mut scratch = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, par));
        let n = x.len();
        lu.solve_in_place_with_conj(Conj::No, faer::MatMut::from_column_major_slice_mut(x, n, 1), par, MemStack::new(&mut scratch));
    }
}

/// Symbolic part of [`StaticLu`]: a symmetric fill-reducing permutation and the supernodal
/// structure of the Cholesky factor of the permuted pattern (`A` is structurally symmetric, so
/// `L` and `U^T` share it).
///
/// The ordering ([`FillOrdering`]: nested dissection or approximate minimum degree)
/// is computed on the dofs with a nonzero diagonal, and every zero-diagonal dof (a pressure or
/// Lagrange-multiplier dof of the saddle-point system) is then placed right after the last of its
/// nonzero-diagonal neighbours. For nested dissection the graph gets, per zero-diagonal dof, a
/// star joining its nonzero-diagonal neighbours, so that they are never split by a separator and
/// the dof's delayed elimination does not couple the two sides. Every leading block then is a
/// saddle-point matrix `[K B^T; B 0]` whose constraint rows have all their couplings eliminated,
/// nonsingular when `K` is (positive real) and `B` has full rank, so no pivot is structurally
/// zero. Where `B` lacks rank (the multiplier modes of an FSI system, which pair with no
/// velocity), the unknown that constrains a mode shares the diagonal block of the mode's last
/// multiplier (`merge_supernodes`). Pivoting is partial inside each supernode's diagonal block
/// only, so the structure is static.
struct StaticSymbolic {
    n: usize,
    /// `perm[new] = old`.
    perm: Vec<usize>,
    /// First column of each supernode (`nsup + 1` entries).
    sn_begin: Vec<usize>,
    /// Off-diagonal rows of each supernode (`rows[row_ptr[s]..row_ptr[s + 1]]`, sorted, new
    /// numbering).
    row_ptr: Vec<usize>,
    rows: Vec<usize>,
    /// Offsets in the value array of each supernode's `L` panel (`(k + r) x k`, column-major,
    /// diagonal block first) and `U^T` panel (`r x k`, after all `L` panels).
    l_ptr: Vec<usize>,
    u_ptr: Vec<usize>,
    /// Supernode of each (new) column.
    owner: Vec<usize>,
    /// Position in the value array of each stored entry of `A`.
    scatter: Vec<usize>,
    len_val: usize,
    max_r: usize,
    max_k: usize,
    /// [`zero_diagonal_key`] of the analysed matrix.
    zero_key: u64,
    /// Flops of the analysis that computed the ordering (this one's, or the earlier one's whose
    /// ordering it kept).
    ordered_flops: f64,
    stats: FactorStats,
}

/// The numeric part of [`StaticLu`].
struct StaticLu {
    sym: StaticSymbolic,
    /// Row and column scales `R`, `C` (original numbering): the factors are those of `R A C`
    /// ([`equilibration`]).
    row_scale: Vec<f64>,
    col_scale: Vec<f64>,
    val: Vec<f64>,
    /// Row permutation of each diagonal block (`piv[begin + i]` = local source row of row `i`).
    piv: Vec<usize>,
    work: Vec<f64>,
    rel: Vec<usize>,
}

/// The static LU's analysis of `a`: a fill-reducing ordering of its nonzero-diagonal unknowns
/// (or, with `kept`, theirs in that permutation of an earlier analysis with the same ones) and
/// the supernodal structure.
fn static_symbolic(a: &CscMatrix<'_>, ordering: FillOrdering, kept: Option<&[usize]>) -> Result<StaticSymbolic, LinearSolveError> {
    let t_start = std::time::Instant::now();
    use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering};
    use faer::sparse::linalg::SupernodalThreshold;
    let p = a.pattern;
    let n = p.n;
    let err = |m: String| LinearSolveError::Symbolic(m);
    // Zero-diagonal dofs.
    let zero = zero_diagonals(a);
    // Fill-reducing order of the nonzero-diagonal dofs (`pos[local]` = position).
    let regular: Vec<usize> = (0..n).filter(|&j| !zero[j]).collect();
    let mut local = vec![usize::MAX; n];
    for (i, &j) in regular.iter().enumerate() {
        local[j] = i;
    }
    let m = regular.len();
    let mut cp = Vec::with_capacity(m + 1);
    let mut ri = Vec::new();
    cp.push(0);
    for &j in &regular {
        for &i in &p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]] {
            if !zero[i] {
                ri.push(local[i]);
            }
        }
        cp.push(ri.len());
    }
    let t_order = std::time::Instant::now();
    let ordering = match ordering {
        FillOrdering::Auto if ri.len() >= AUTO_ND_MIN_DEGREE * m || m >= AUTO_ND_MIN_DOFS => FillOrdering::NestedDissection,
        FillOrdering::Auto => FillOrdering::Amd,
        other => other,
    };
    let mut pos = vec![0usize; m];
    if let Some(perm) = kept {
        for (new, &j) in perm.iter().filter(|&&j| !zero[j]).enumerate() {
            pos[local[j]] = new;
        }
    } else if m > 0 {
        match ordering {
            FillOrdering::Amd | FillOrdering::Auto => {
                let mut amd_fwd = vec![0usize; m];
                let sym = SymbolicSparseColMatRef::new_checked(m, m, &cp, None, &ri);
                let req = faer::sparse::linalg::amd::order_scratch::<usize>(m, ri.len());
                let mut mem = MemBuffer::try_new(req).map_err(|e| err(format!("amd workspace: {e:?}")))?;
                faer::sparse::linalg::amd::order(&mut amd_fwd, &mut pos, sym, Default::default(), MemStack::new(&mut mem))
                    .map_err(|e| err(format!("amd: {e:?}")))?;
            }
            FillOrdering::NestedDissection => {
                // Each zero-diagonal dof is eliminated after all its regular neighbours, which
                // couples them (fill); a star through its first regular neighbour puts that
                // coupling into the graph, so no separator splits them and the dof lands in the
                // separator block of the subtree that holds them all.
                let mut extra = Vec::new();
                for j in (0..n).filter(|&j| zero[j]) {
                    let mut nb = p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].iter().filter(|&&i| !zero[i]).map(|&i| local[i]);
                    if let Some(r0) = nb.next() {
                        extra.extend(nb.map(|r| (r0, r)));
                    }
                }
                let fwd = super::ordering::nested_dissection(m, &cp, &ri, &extra, &super::ordering::NdOptions::default())
                    .map_err(|e| err(format!("nested dissection: {e}")))?;
                for (new, &old) in fwd.iter().enumerate() {
                    pos[old] = new;
                }
            }
        }
    }
    let ordering_seconds = t_order.elapsed().as_secs_f64();
    // Sort key: regular dof -> (2 * position), zero-diagonal dof -> (2 * max neighbour position + 1).
    // A zero-diagonal dof with zero-diagonal neighbours only (an unknown `sigma` that removes a
    // multiplier mode, `fsi::multiplier_kernel`) takes the largest key of its (other)
    // neighbours: it follows the last of them (ties sort such unknowns after the others).
    let neighbours = |j: usize| p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].iter().copied().filter(move |&i| i != j);
    let mut key = vec![usize::MAX; n];
    for j in 0..n {
        if !zero[j] {
            key[j] = 2 * pos[local[j]];
        } else if let Some(q) = neighbours(j).filter(|&i| !zero[i]).map(|i| pos[local[i]]).max() {
            key[j] = 2 * q + 1;
        }
    }
    let is_mode: Vec<bool> = key.iter().map(|&k| k == usize::MAX).collect();
    let mode_unknowns: Vec<usize> = (0..n).filter(|&j| is_mode[j]).collect();
    for &j in &mode_unknowns {
        key[j] = neighbours(j).filter(|&i| !is_mode[i]).map(|i| key[i]).max().unwrap_or(2 * m + 1);
    }
    let mut perm: Vec<usize> = (0..n).collect();
    perm.sort_by_key(|&j| (key[j], is_mode[j], j));
    let perm_inv = inverse_permutation(&perm);
    // Supernodal Cholesky structure of the permuted pattern.
    let sym = SymbolicSparseColMatRef::new_checked(n, n, &p.col_ptr, None, &p.row_idx);
    // faer's default supernode relaxation; more or none changed neither fill nor time measurably.
    let params = CholeskySymbolicParams { supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL, ..Default::default() };
    let ord = faer::perm::PermRef::new_checked(&perm, &perm_inv, n);
    let chol = factorize_symbolic_cholesky(sym, faer::Side::Upper, SymmetricOrdering::Custom(ord), params)
        .map_err(|e| err(format!("symbolic cholesky: {e:?}")))?;
    let sn = match chol.raw() {
        SymbolicCholeskyRaw::Supernodal(sn) => sn,
        SymbolicCholeskyRaw::Simplicial(_) => return Err(err("expected a supernodal structure".into())),
    };
    let patterns: Vec<Vec<usize>> = (0..sn.n_supernodes())
        .map(|s| {
            let mut r = sn.supernode(s).pattern().to_vec();
            r.sort_unstable();
            r
        })
        .collect();
    let mut begin: Vec<usize> = sn.supernode_begin().to_vec();
    begin.push(n);
    // Each such unknown joins the supernode of the last multiplier it couples to (see
    // `merge_supernodes`).
    let mode_spans: Vec<(usize, usize)> = mode_unknowns
        .iter()
        .map(|&j| (neighbours(j).filter(|&i| !is_mode[i]).map(|i| perm_inv[i]).max().unwrap_or(perm_inv[j]).min(perm_inv[j]), perm_inv[j]))
        .collect();
    let (sn_begin, supernode_rows) = merge_supernodes(&begin, &patterns, &mode_spans);
    let nsup = sn_begin.len() - 1;
    let mut row_ptr = Vec::with_capacity(nsup + 1);
    let mut rows = Vec::new();
    row_ptr.push(0);
    for r in &supernode_rows {
        rows.extend_from_slice(r);
        row_ptr.push(rows.len());
    }
    let mut owner = vec![0usize; n];
    let (mut l_ptr, mut u_ptr) = (vec![0usize; nsup + 1], vec![0usize; nsup + 1]);
    let (mut max_r, mut max_k) = (0, 0);
    let (mut flops, mut threaded_flops) = (0.0f64, 0.0f64);
    for s in 0..nsup {
        let k = sn_begin[s + 1] - sn_begin[s];
        let r = row_ptr[s + 1] - row_ptr[s];
        let (kf, rf) = (k as f64, r as f64);
        let f = 2.0 / 3.0 * kf * kf * kf + 2.0 * kf * kf * rf + 2.0 * kf * rf * rf;
        flops += f;
        if is_large_block(k, r) {
            threaded_flops += f;
        }
        owner[sn_begin[s]..sn_begin[s + 1]].fill(s);
        l_ptr[s + 1] = l_ptr[s] + (k + r) * k;
        u_ptr[s + 1] = u_ptr[s] + r * k;
        max_r = max_r.max(r);
        max_k = max_k.max(k);
    }
    let l_len = l_ptr[nsup];
    for u in u_ptr.iter_mut() {
        *u += l_len;
    }
    let len_val = u_ptr[nsup];
    let zero_key = zero_diagonal_key(&zero);
    let mut sym = StaticSymbolic {
        n,
        perm,
        sn_begin,
        row_ptr,
        rows,
        l_ptr,
        u_ptr,
        owner,
        scatter: Vec::new(),
        len_val,
        max_r,
        max_k,
        zero_key,
        ordered_flops: flops,
        stats: FactorStats {
            ordering,
            supernodes: nsup,
            nnz_lu: len_val,
            flops,
            threaded_flops,
            ordering_seconds,
            symbolic_seconds: 0.0,
            mode_unknowns: mode_spans.len(),
            mode_unknowns_joined: 0,
        },
    };
    sym.scatter = sym.scatter_map(p, &perm_inv)?;
    sym.stats.mode_unknowns_joined = mode_spans.iter().filter(|&&(first, last)| sym.owner[first] == sym.owner[last]).count();
    sym.stats.symbolic_seconds = t_start.elapsed().as_secs_f64();
    Ok(sym)
}

/// `inv[perm[new]] = new`.
fn inverse_permutation(perm: &[usize]) -> Vec<usize> {
    let mut inv = vec![0usize; perm.len()];
    for (new, &old) in perm.iter().enumerate() {
        inv[old] = new;
    }
    inv
}

/// A fingerprint of the zero-diagonal unknowns.
fn zero_diagonal_key(zero: &[bool]) -> u64 {
    fnv1a(zero.iter().enumerate().filter(|(_, &z)| z).map(|(j, _)| j as u64))
}

/// The zero-diagonal unknowns of `a` (no stored diagonal, or a stored zero).
fn zero_diagonals(a: &CscMatrix<'_>) -> Vec<bool> {
    let p = a.pattern;
    (0..p.n).map(|j| p.find(j, j).map(|k| a.values[k] == 0.0).unwrap_or(true)).collect()
}

impl StaticSymbolic {
    /// Position in the value array of each stored entry of `p` (`perm_inv[old] = new`); an
    /// error names an entry outside the factor structure.
    fn scatter_map(&self, p: &Pattern, perm_inv: &[usize]) -> Result<Vec<usize>, LinearSolveError> {
        let err = |m: String| LinearSolveError::Symbolic(m);
        let (sn_begin, row_ptr, rows, owner, l_ptr, u_ptr) = (&self.sn_begin, &self.row_ptr, &self.rows, &self.owner, &self.l_ptr, &self.u_ptr);
        let n = self.n;
        let mut scatter = vec![0usize; p.nnz()];
        let pos_in = |s: usize, i: usize| -> Option<usize> {
            let (b, e) = (sn_begin[s], sn_begin[s + 1]);
            if i >= b && i < e {
                Some(i - b)
            } else {
                rows[row_ptr[s]..row_ptr[s + 1]].binary_search(&i).ok().map(|q| e - b + q)
            }
        };
        for jo in 0..n {
            let j = perm_inv[jo];
            for idx in p.col_ptr[jo]..p.col_ptr[jo + 1] {
                let i = perm_inv[p.row_idx[idx]];
                scatter[idx] = if i >= j {
                    let s = owner[j];
                    let (b, e) = (sn_begin[s], sn_begin[s + 1]);
                    let ld = e - b + row_ptr[s + 1] - row_ptr[s];
                    let q = pos_in(s, i).ok_or_else(|| err(format!("entry ({i}, {j}) outside the factor structure")))?;
                    l_ptr[s] + (j - b) * ld + q
                } else {
                    let s = owner[i];
                    let (b, e) = (sn_begin[s], sn_begin[s + 1]);
                    let k = e - b;
                    let r = row_ptr[s + 1] - row_ptr[s];
                    let q = pos_in(s, j).ok_or_else(|| err(format!("entry ({i}, {j}) outside the factor structure")))?;
                    if q < k {
                        l_ptr[s] + q * (k + r) + (i - b)
                    } else {
                        u_ptr[s] + (i - b) * r + (q - k)
                    }
                };
            }
        }
        Ok(scatter)
    }

    /// Whether `a` has the analysed matrix's size and zero-diagonal unknowns `zero` (then the
    /// ordering may serve it).
    fn same_unknowns(&self, a: &CscMatrix<'_>, zero: &[bool]) -> bool {
        a.pattern.n == self.n && zero_diagonal_key(zero) == self.zero_key
    }

    /// The scatter map of `a` (zero-diagonal unknowns `zero`) if this analysis serves it: the
    /// same size and zero-diagonal unknowns, every entry inside the factor structure, and every
    /// zero-diagonal unknown after its nonzero-diagonal neighbours, as [`static_symbolic`] orders
    /// them (none without such neighbours: those also need their supernode, `merge_supernodes`).
    fn serves(&self, a: &CscMatrix<'_>, zero: &[bool]) -> Option<Vec<usize>> {
        if !self.same_unknowns(a, zero) {
            return None;
        }
        let p = a.pattern;
        let perm_inv = inverse_permutation(&self.perm);
        let ordered = (0..self.n).filter(|&j| zero[j]).all(|j| {
            let mut regular = p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].iter().filter(|&&i| !zero[i]).peekable();
            regular.peek().is_some() && regular.all(|&i| perm_inv[i] < perm_inv[j])
        });
        if !ordered {
            return None;
        }
        self.scatter_map(p, &perm_inv).ok()
    }
}

/// Merges consecutive supernodes (first columns `begin`, `nsup + 1` entries; sorted off-diagonal
/// rows `patterns`) so that each column span `(first, last)` of `spans` lies in one supernode,
/// where that is possible; returns the new first columns and sorted off-diagonal rows.
///
/// The spans join each unknown `sigma` that removes a multiplier mode to the last multiplier it
/// couples to (it follows that multiplier in the order, after at most a few others). On a mode `z`
/// the pairing of the multipliers with the velocities (nearly) vanishes, so the Schur complement
/// of the multipliers is (nearly) singular in the direction `z` until `sigma`, whose equation is
/// `(M z) . lambda = 0`, is eliminated with them: in one diagonal block the partial pivoting
/// finds the nonsingular `[S (M z); (M z)^T 0]`, in separate blocks the last multiplier of the
/// mode had a zero pivot (model problem 4, fine mesh: 3e-16 against entries of 582). (All `D x D`
/// multipliers of a gamma_f facet share a key, so the mode's last facet is in that block. Should
/// a combination of several modes vanish on it, the zero pivot would come earlier.)
///
/// Supernode `s` joins `s + 1` only where its rows outside `s + 1`'s columns are rows of `s + 1`
/// (as along a path of the elimination tree, which the columns between a multiplier and `sigma`
/// form: they all follow the same regular dof): the merged block then has `s + 1`'s rows, and every
/// update it makes lands inside the factor structure. Elsewhere merging would add update entries
/// (zero, but outside the structure), so those spans stay split.
fn merge_supernodes(begin: &[usize], patterns: &[Vec<usize>], spans: &[(usize, usize)]) -> (Vec<usize>, Vec<Vec<usize>>) {
    let nsup = patterns.len();
    let n = begin[nsup];
    let mut owner = vec![0usize; n];
    for s in 0..nsup {
        owner[begin[s]..begin[s + 1]].fill(s);
    }
    // joined[s]: supernode s continues into s + 1.
    let mut joined = vec![false; nsup];
    for &(first, last) in spans {
        joined[owner[first]..owner[last]].fill(true);
    }
    let chain = |s: usize| patterns[s].iter().filter(|&&i| i >= begin[s + 2]).all(|i| patterns[s + 1].binary_search(i).is_ok());
    let (mut sn_begin, mut rows) = (vec![0usize], Vec::new());
    let mut acc: Vec<usize> = Vec::new();
    for s in 0..nsup {
        acc.extend_from_slice(&patterns[s]);
        if !(joined[s] && chain(s)) {
            let end = begin[s + 1];
            acc.retain(|&i| i >= end);
            acc.sort_unstable();
            acc.dedup();
            rows.push(std::mem::take(&mut acc));
            sn_begin.push(end);
        }
    }
    (sn_begin, rows)
}

/// Is a supernode of `k` columns and `r` off-diagonal rows worth threaded dense kernels (more
/// than about 4M flops)?
fn is_large_block(k: usize, r: usize) -> bool {
    k * k * (k + r) + k * r * r > 1 << 22
}

impl StaticLu {
    fn new(sym: StaticSymbolic) -> Self {
        let n = sym.n;
        let (max_r, max_k) = (sym.max_r, sym.max_k);
        StaticLu {
            sym,
            row_scale: vec![1.0; n],
            col_scale: vec![1.0; n],
            val: Vec::new(),
            piv: vec![0; n],
            work: vec![0.0; max_r * max_r + max_r * max_k],
            rel: vec![0; max_r],
        }
    }

    fn factorize(&mut self, a: &CscMatrix<'_>, par: Par) -> Result<(), LinearSolveError> {
        use faer::linalg::matmul::matmul;
        use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_unit_lower_triangular_in_place};
        use faer::{Accum, MatMut, MatRef};
        (self.row_scale, self.col_scale) = equilibration(a);
        let sym = &self.sym;
        self.val.clear();
        self.val.resize(sym.len_val, 0.0);
        let val = &mut self.val;
        let (rs, cs) = (&self.row_scale, &self.col_scale);
        let mut amax = 0.0f64;
        for j in 0..a.pattern.n {
            for p in a.pattern.col_ptr[j]..a.pattern.col_ptr[j + 1] {
                let v = a.values[p] * rs[a.pattern.row_idx[p]] * cs[j];
                val[sym.scatter[p]] += v;
                amax = amax.max(v.abs());
            }
        }
        let tiny = amax * f64::EPSILON * 1e-2;
        let nsup = sym.sn_begin.len() - 1;
        let mut perm = vec![0usize; sym.max_k];
        let mut perm_inv = vec![0usize; sym.max_k];
        let mut lu_mem = MemBuffer::new(faer::linalg::lu::partial_pivoting::factor::lu_in_place_scratch::<usize, f64>(
            sym.max_k,
            sym.max_k,
            Par::Seq,
            Default::default(),
        ));
        let (wbuf, tmp) = self.work.split_at_mut(sym.max_r * sym.max_r);
        for s in 0..nsup {
            let (b, e) = (sym.sn_begin[s], sym.sn_begin[s + 1]);
            let k = e - b;
            let rows = &sym.rows[sym.row_ptr[s]..sym.row_ptr[s + 1]];
            let r = rows.len();
            let (lo, uo) = (sym.l_ptr[s], sym.u_ptr[s]);
            let par_s = if is_large_block(k, r) { par } else { Par::Seq };
            {
                let (lpart, upart) = val.split_at_mut(uo);
                let lpanel = &mut lpart[lo..lo + (k + r) * k];
                let upanel = &mut upart[..r * k];
                let mut lmat = MatMut::from_column_major_slice_mut(lpanel, k + r, k);
                let (mut d, mut l21) = lmat.rb_mut().split_at_row_mut(k);
                faer::linalg::lu::partial_pivoting::factor::lu_in_place(
                    d.rb_mut(),
                    &mut perm[..k],
                    &mut perm_inv[..k],
                    Par::Seq,
                    MemStack::new(&mut lu_mem),
                    Default::default(),
                );
                for i in 0..k {
                    let piv = d[(i, i)];
                    if !(piv.abs() > tiny) || !piv.is_finite() {
                        return Err(LinearSolveError::ZeroPivot { pivot: piv, largest: amax, unknown: sym.perm[b + i], step: b + i });
                    }
                }
                self.piv[b..e].copy_from_slice(&perm[..k]);
                let mut up = MatMut::from_column_major_slice_mut(upanel, r, k);
                if r > 0 {
                    // Row permutation of the diagonal block applied to U12 (columns of U^T).
                    let t = &mut tmp[..r * k];
                    for c in 0..k {
                        let src = perm[c];
                        for a_ in 0..r {
                            t[c * r + a_] = up[(a_, src)];
                        }
                    }
                    for c in 0..k {
                        for a_ in 0..r {
                            up[(a_, c)] = t[c * r + a_];
                        }
                    }
                    // U12 = L11^{-1} P F12.
                    solve_unit_lower_triangular_in_place(d.rb(), up.rb_mut().transpose_mut(), par_s);
                    // L21 = F21 U11^{-1}.
                    solve_lower_triangular_in_place(d.rb().transpose(), l21.rb_mut().transpose_mut(), par_s);
                    let mut w = MatMut::from_column_major_slice_mut(&mut wbuf[..r * r], r, r);
                    matmul(w.rb_mut(), Accum::Replace, l21.rb(), up.rb().transpose(), 1.0, par_s);
                }
            }
            if r == 0 {
                continue;
            }
            let w = MatRef::from_column_major_slice(&wbuf[..r * r], r, r);
            let mut bb = 0;
            while bb < r {
                let t = sym.owner[rows[bb]];
                let (tb, te) = (sym.sn_begin[t], sym.sn_begin[t + 1]);
                let tk = te - tb;
                let trows = &sym.rows[sym.row_ptr[t]..sym.row_ptr[t + 1]];
                let tr = trows.len();
                let mut run_end = bb;
                while run_end < r && rows[run_end] < te {
                    run_end += 1;
                }
                // Relative positions of rows[bb..] in t's row list.
                let mut q = 0;
                for a_ in bb..r {
                    let i = rows[a_];
                    self.rel[a_] = if i < te {
                        i - tb
                    } else {
                        while q < tr && trows[q] < i {
                            q += 1;
                        }
                        if q == tr || trows[q] != i {
                            return Err(LinearSolveError::Numeric("static LU: update outside the factor structure".into()));
                        }
                        tk + q
                    };
                }
                let (tlo, tuo) = (sym.l_ptr[t], sym.u_ptr[t]);
                let ld = tk + tr;
                for c_ in bb..run_end {
                    let cc = rows[c_] - tb;
                    let lcol = tlo + cc * ld;
                    for a_ in c_..r {
                        val[lcol + self.rel[a_]] -= w[(a_, c_)];
                    }
                    for a_ in c_ + 1..r {
                        let ra = self.rel[a_];
                        if ra < tk {
                            val[tlo + ra * ld + cc] -= w[(c_, a_)];
                        } else {
                            val[tuo + cc * tr + (ra - tk)] -= w[(c_, a_)];
                        }
                    }
                }
                bb = run_end;
            }
        }
        Ok(())
    }

    /// Solves `A x = b` in place. Per supernode, the off-diagonal rows are gathered once into a
    /// dense work vector and updated by dense column operations (`w -= L_21 y_b` forward,
    /// `y_b -= U_12 w` backward), so the indirect row accesses happen once per supernode rather
    /// than once per column (Schaefer-Turek 2D-1 medium, the AL solver's augmented block: 19.3 ms
    /// per solve against 22.0 ms column by column; the solve streams the factors from memory).
    fn solve(&self, x: &mut [f64], y: &mut Vec<f64>) {
        let sym = &self.sym;
        let n = sym.n;
        y.clear();
        y.extend(sym.perm.iter().map(|&o| x[o] * self.row_scale[o]));
        let val = &self.val;
        let nsup = sym.sn_begin.len() - 1;
        let mut t = vec![0.0; sym.max_k];
        let mut w = vec![0.0; sym.max_r];
        for s in 0..nsup {
            let (b, e) = (sym.sn_begin[s], sym.sn_begin[s + 1]);
            let k = e - b;
            let rows = &sym.rows[sym.row_ptr[s]..sym.row_ptr[s + 1]];
            let r = rows.len();
            let ld = k + r;
            let l = &val[sym.l_ptr[s]..sym.l_ptr[s] + ld * k];
            for c in 0..k {
                t[c] = y[b + self.piv[b + c]];
            }
            // Unit lower triangular diagonal block.
            for c in 0..k {
                let tc = t[c];
                if tc != 0.0 {
                    let col = &l[c * ld + c + 1..c * ld + k];
                    t[c + 1..k].iter_mut().zip(col).for_each(|(ti, li)| *ti -= li * tc);
                }
            }
            y[b..e].copy_from_slice(&t[..k]);
            if r > 0 {
                let w = &mut w[..r];
                w.iter_mut().for_each(|wi| *wi = 0.0);
                for c in 0..k {
                    let tc = t[c];
                    if tc != 0.0 {
                        let col = &l[c * ld + k..(c + 1) * ld];
                        w.iter_mut().zip(col).for_each(|(wi, li)| *wi += li * tc);
                    }
                }
                for (&row, wi) in rows.iter().zip(w.iter()) {
                    y[row] -= wi;
                }
            }
        }
        for s in (0..nsup).rev() {
            let (b, e) = (sym.sn_begin[s], sym.sn_begin[s + 1]);
            let k = e - b;
            let rows = &sym.rows[sym.row_ptr[s]..sym.row_ptr[s + 1]];
            let r = rows.len();
            let ld = k + r;
            let l = &val[sym.l_ptr[s]..sym.l_ptr[s] + ld * k];
            let u = &val[sym.u_ptr[s]..sym.u_ptr[s] + r * k];
            if r > 0 {
                let w = &mut w[..r];
                w.iter_mut().zip(rows).for_each(|(wi, &row)| *wi = y[row]);
                for c in 0..k {
                    y[b + c] -= dot4(&u[c * r..(c + 1) * r], w);
                }
            }
            for c in (0..k).rev() {
                let yc = y[b + c] / l[c * ld + c];
                y[b + c] = yc;
                if yc != 0.0 {
                    let col = &l[c * ld..c * ld + c];
                    y[b..b + c].iter_mut().zip(col).for_each(|(yi, li)| *yi -= li * yc);
                }
            }
        }
        for (new, &old) in sym.perm.iter().enumerate() {
            x[old] = y[new] * self.col_scale[old];
        }
        debug_assert_eq!(n, x.len());
    }
}

/// `a . b` with four partial sums (so that the loop vectorises).
fn dot4(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    let (ac, bc) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ac.remainder().iter().zip(bc.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in ac.zip(bc) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

enum Active {
    None,
    Static,
    Pivoting,
}

/// The sparse LU behind [`LinearSolver`], with the symbolic factorisation cached per pattern.
///
/// [`LuMethod::Auto`] (the default) uses `StaticLu`: a supernodal LU on the symmetric structure
/// of the pattern with a constrained fill-reducing ordering ([`LinearSolverOptions::ordering`],
/// nested dissection by default; pressure and multiplier dofs after their velocity neighbours)
/// and pivoting inside supernode diagonal blocks. Its fill is that of a Cholesky factor of `A`,
/// much smaller than the `A^T A` bound of the partial-pivoting LU. After each numeric
/// factorisation one solve of a known system checks its accuracy; when the check or the
/// factorisation fails, faer's partial-pivoting LU (COLAMD) is used for this pattern from then on.
pub struct FaerLu {
    options: LinearSolverOptions,
    method: LuMethod,
    key: Option<u64>,
    static_lu: Option<StaticLu>,
    pivoting: Option<PivotingLu>,
    active: Active,
    symbolic_count: usize,
    scratch: std::cell::RefCell<Vec<f64>>,
    /// Tries of a held factorisation that failed in a row, and offers still to decline
    /// ([`LinearSolver::offer_held_factorization`]).
    held_failures: u32,
    held_declines: u32,
}

impl FaerLu {
    /// A solver with the given options.
    pub fn new(options: LinearSolverOptions) -> Self {
        Self::with_method(options, LuMethod::Auto)
    }

    /// A solver with the given options and method.
    pub fn with_method(options: LinearSolverOptions, method: LuMethod) -> Self {
        FaerLu {
            options,
            method,
            key: None,
            static_lu: None,
            pivoting: None,
            active: Active::None,
            symbolic_count: 0,
            scratch: std::cell::RefCell::new(Vec::new()),
            held_failures: 0,
            held_declines: 0,
        }
    }

    fn par(&self) -> Par {
        // Sequential by default: on the 2-core reference machine (shared, loaded) faer's rayon
        // kernels made both factorisations of 2D systems slower (faer LU numeric on 145k dofs
        // 2.1 s seq vs 2.9 s rayon(2), static LU 1.6 s vs 1.9 s user time).
        match self.options.threads {
            1 => Par::Seq,
            n => Par::rayon(n),
        }
    }

    /// Symbolic analysis of the static LU alone (ordering, supernodes, fill and flop count),
    /// without any numeric work: to compare orderings on a pattern.
    pub fn analyse(a: &CscMatrix<'_>, ordering: FillOrdering) -> Result<FactorStats, LinearSolveError> {
        static_symbolic(a, ordering, None).map(|s| s.stats)
    }

    /// Size and cost of the static LU in use (`None` when faer's pivoting LU is active or
    /// nothing is factorised).
    pub fn factor_stats(&self) -> Option<FactorStats> {
        match self.active {
            Active::Static => self.static_lu.as_ref().map(|s| s.sym.stats.clone()),
            _ => None,
        }
    }

    /// A one-line description of the factorisation in use.
    pub fn describe(&self) -> String {
        match self.active {
            Active::None => "not factorised".into(),
            Active::Static => {
                let s = &self.static_lu.as_ref().expect("active").sym.stats;
                format!(
                    "static supernodal LU ({:?} ordering): {} supernodes, nnz(L+U) {}, {:.3e} flops, ordering {:.3}s, symbolic {:.3}s; {} of {} mode unknowns in their last multiplier's supernode",
                    s.ordering, s.supernodes, s.nnz_lu, s.flops, s.ordering_seconds, s.symbolic_seconds, s.mode_unknowns_joined, s.mode_unknowns
                )
            }
            Active::Pivoting => "faer partial-pivoting LU (COLAMD)".into(),
        }
    }

    /// Solves with the current factorisation, without refinement or checks (an inner solve of a
    /// preconditioner).
    pub(super) fn solve_unrefined(&self, x: &mut [f64]) {
        self.raw_solve(x);
    }

    fn raw_solve(&self, x: &mut [f64]) {
        match self.active {
            Active::Static => self.static_lu.as_ref().expect("active").solve(x, &mut self.scratch.borrow_mut()),
            Active::Pivoting => self.pivoting.as_ref().expect("active").solve(x, self.par()),
            Active::None => {}
        }
    }

    /// Relative residual of a solve of `A x = A e` (a fixed `e`) with the current
    /// factorisation, refined as [`LinearSolver::solve_in_place`] refines (up to
    /// `max_refinements` steps while above [`STATIC_CHECK_TOLERANCE`]), to validate a
    /// factorisation without pivoting. Costs a few solves and matrix-vector products, a few percent
    /// of the factorisation.
    fn check_accuracy(&self, a: &CscMatrix<'_>) -> f64 {
        let n = a.pattern.n;
        let e: Vec<f64> = (0..n).map(|i| 1.0 + 0.5 * ((i * 7919) % 13) as f64 / 13.0).collect();
        let mut x = vec![0.0; n];
        a.mul_vec(&e, &mut x);
        let (res, _) = self.refined_solve(a, &mut x, STATIC_CHECK_TOLERANCE);
        if res.is_finite() {
            res
        } else {
            f64::INFINITY
        }
    }

    /// Solves `A x = b` in place (`x` holds `b` on entry) with the current factorisation and
    /// iterative refinement against `a` (up to `max_refinements` steps while the relative
    /// residual is above `tolerance`); returns that residual and the refinement count.
    fn refined_solve(&self, a: &CscMatrix<'_>, x: &mut [f64], tolerance: f64) -> (f64, usize) {
        let b = x.to_vec();
        let bnorm = norm(&b).max(f64::MIN_POSITIVE);
        self.raw_solve(x);
        let mut r = vec![0.0; x.len()];
        let residual = |x: &[f64], r: &mut Vec<f64>| -> f64 {
            a.mul_vec(x, r);
            for (ri, bi) in r.iter_mut().zip(&b) {
                *ri = bi - *ri;
            }
            norm(r) / bnorm
        };
        let mut res = residual(x, &mut r);
        let mut refinements = 0;
        while res > tolerance && refinements < self.options.max_refinements && res.is_finite() {
            self.raw_solve(&mut r);
            for (xi, d) in x.iter_mut().zip(&r) {
                *xi += d;
            }
            refinements += 1;
            res = residual(x, &mut r);
        }
        (res, refinements)
    }

    /// A symbolic analysis for the pattern of `a`, with a new ordering or the permutation
    /// `kept` of an earlier analysis of the same unknowns.
    fn analyse_pattern(&mut self, a: &CscMatrix<'_>, kept: Option<&[usize]>) {
        self.static_lu = None;
        self.pivoting = None;
        if self.method == LuMethod::Auto {
            // A failed static analysis (cannot happen for a valid pattern) just means pivoting.
            self.static_lu = static_symbolic(a, self.options.ordering, kept).ok().map(StaticLu::new);
        }
        self.symbolic_count += 1;
    }

    /// For a new pattern, or new zero diagonals, with [`LinearSolverOptions::reuse_analysis`]:
    /// keeps the held analysis if it serves `a` (returns true: a new scatter map only), else
    /// analyses with the held ordering if `a` has as many unknowns (those with a zero diagonal
    /// now placed after their neighbours anew: a contact node's moves in and out of contact
    /// need no new ordering) and the fill stays within [`KEPT_ORDERING_MAX_FLOPS`] of the
    /// analysis that ordered, else afresh.
    fn reanalyse(&mut self, a: &CscMatrix<'_>) -> bool {
        let zero = zero_diagonals(a);
        let Some(held) = self.static_lu.as_mut().filter(|s| s.sym.n == a.pattern.n) else {
            self.analyse_pattern(a, None);
            return false;
        };
        if let Some(scatter) = held.sym.serves(a, &zero) {
            tracing::debug!("new pattern inside the held factor structure: ordering and symbolic analysis kept");
            held.sym.scatter = scatter;
            return true;
        }
        let (perm, ordered_flops) = (std::mem::take(&mut held.sym.perm), held.sym.ordered_flops);
        self.analyse_pattern(a, Some(&perm));
        match self.static_lu.as_mut() {
            Some(s) if s.sym.stats.flops <= KEPT_ORDERING_MAX_FLOPS * ordered_flops => {
                s.sym.ordered_flops = ordered_flops;
                s.sym.stats.ordering_seconds = 0.0;
                tracing::debug!("new pattern with the held unknowns: ordering kept ({:.3e} flops)", s.sym.stats.flops);
            }
            kept => {
                tracing::debug!(
                    "new pattern with the held unknowns: the held ordering needs {:.3e} flops against {ordered_flops:.3e}: ordering afresh",
                    kept.map_or(f64::NAN, |s| s.sym.stats.flops)
                );
                self.analyse_pattern(a, None);
            }
        }
        false
    }

    fn factorize_pivoting(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
        let view = faer_view(a);
        let par = self.par();
        if self.pivoting.is_none() {
            self.pivoting = Some(PivotingLu::new(view, par)?);
            self.symbolic_count += 1;
        }
        self.pivoting.as_mut().expect("set").factorize(view, par)?;
        self.active = Active::Pivoting;
        Ok(())
    }
}

impl Default for FaerLu {
    fn default() -> Self {
        Self::new(LinearSolverOptions::default())
    }
}

/// Identity of a pattern by content: a hash of its index arrays (O(nnz), negligible next to a
/// factorisation), so a symbolic factorisation is reused exactly when the structure is the same.
pub(super) fn pattern_key(p: &Pattern) -> u64 {
    fnv1a(std::iter::once(&p.n).chain(&p.col_ptr).chain(&p.row_idx).map(|&w| w as u64))
}

/// FNV-1a over whole words: a few milliseconds for millions of entries, where the default
/// SipHash took 1.7 % of a Schaefer-Turek 2D-1 solve; no adversary chooses the inputs.
pub(crate) fn fnv1a(words: impl IntoIterator<Item = u64>) -> u64 {
    words.into_iter().fold(0xcbf2_9ce4_8422_2325, |h, w| (h ^ w).wrapping_mul(0x0100_0000_01b3))
}

fn faer_view<'a>(a: &'a CscMatrix<'_>) -> SparseColMatRef<'a, usize, f64> {
    let p = a.pattern;
    // SAFETY: `Pattern` stores sorted, in-range row indices per column and monotone column
    // pointers; its construction guarantees the invariants faer requires.
    let sym = unsafe { SymbolicSparseColMatRef::new_unchecked(p.n, p.n, &p.col_ptr, None, &p.row_idx) };
    SparseColMatRef::new(sym, &a.values)
}

/// Euclidean norm.
pub(super) fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Row and column scales `r_i = 1 / sqrt(max_j |a_ij|)`, `c_j = 1 / sqrt(max_i |a_ij|)` (one
/// sweep of Ruiz's equilibration; 1 for an empty row or column). The static LU factors `R A C`:
/// its zero-pivot test compares each pivot with the largest entry, and the unknowns of a coupled
/// system differ in scale by many orders (a stiff solid's displacements against a fine cell's
/// pressure gradient: on the Turek-Hron FSI1 mesh with the cylinder at h/16, a pivot of -1.6e-10
/// against entries of 1.6e10 was taken for zero); scaled, each row and column has largest entry
/// 1 up to a factor of the other sweep.
fn equilibration(a: &CscMatrix<'_>) -> (Vec<f64>, Vec<f64>) {
    let n = a.pattern.n;
    let (mut row_max, mut col_max) = (vec![0.0f64; n], vec![0.0f64; n]);
    for j in 0..n {
        for p in a.pattern.col_ptr[j]..a.pattern.col_ptr[j + 1] {
            let v = a.values[p].abs();
            row_max[a.pattern.row_idx[p]] = row_max[a.pattern.row_idx[p]].max(v);
            col_max[j] = col_max[j].max(v);
        }
    }
    let scale = |m: f64| if m > 0.0 && m.is_finite() { 1.0 / m.sqrt() } else { 1.0 };
    (row_max.into_iter().map(scale).collect(), col_max.into_iter().map(scale).collect())
}

/// Largest growth of the LU's flops under a kept ordering ([`LinearSolverOptions::reuse_analysis`])
/// against the analysis that computed it, before the pattern is ordered afresh: a mesh whose
/// topology changed at the same number of unknowns would otherwise carry an ordering of another
/// graph, and its fill would grow from step to step.
const KEPT_ORDERING_MAX_FLOPS: f64 = 1.1;

/// Accuracy a static-pivoting factorisation must reach on its check system (with the iterative
/// refinement every solve gets) to be used; otherwise the partial-pivoting LU takes over.
const STATIC_CHECK_TOLERANCE: f64 = 1e-8;

/// Largest system (stored entries) for which a failed static LU falls back to faer's
/// partial-pivoting LU: its column ordering works on `A^T A`, and on a 3D FSI system of 106 000
/// unknowns and about 11 million entries (model problem 4 with sliver cells) it grew past 20 GB
/// and was killed. Larger systems report the static LU's error instead (which names the unknown).
const PIVOTING_FALLBACK_MAX_NNZ: usize = 4_000_000;

impl LinearSolver for FaerLu {
    fn factorize(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
        let key = pattern_key(a.pattern);
        self.active = Active::None;
        let mut reused = false;
        // The held analysis ordered the zero-diagonal unknowns of its matrix after their
        // neighbours; where others have a zero diagonal now (a contact node that came into
        // contact: its row is its gap, no longer `-lambda / c`), it may eliminate one first, on
        // a pivot of exactly zero (the 3D valve at its first closure).
        let zeros_moved = self.static_lu.as_ref().is_some_and(|s| !s.sym.same_unknowns(a, &zero_diagonals(a)));
        if self.key != Some(key) || zeros_moved {
            reused = self.options.reuse_analysis && self.reanalyse(a);
            if !self.options.reuse_analysis {
                self.analyse_pattern(a, None);
            }
            self.key = Some(key);
        }
        let par = self.par();
        let mut factorized = false;
        if reused {
            match self.static_lu.as_mut().expect("held").factorize(a, par) {
                Ok(()) => factorized = true,
                Err(e) => {
                    tracing::debug!("the kept analysis failed on the new pattern ({e}): analysing afresh");
                    self.analyse_pattern(a, None);
                }
            }
        }
        if let Some(s) = self.static_lu.as_mut() {
            let static_result = if factorized { Ok(()) } else { s.factorize(a, par) };
            if static_result.is_ok() {
                self.active = Active::Static;
                if !self.options.check_accuracy || self.check_accuracy(a) <= STATIC_CHECK_TOLERANCE {
                    return Ok(());
                }
            }
            // Inaccurate or failed without pivoting: use partial pivoting for this pattern, unless
            // the system is so large that its fill would exhaust the memory.
            if a.pattern.nnz() > PIVOTING_FALLBACK_MAX_NNZ {
                self.active = Active::None;
                return Err(match static_result {
                    Err(e) => e,
                    Ok(()) => LinearSolveError::Numeric(format!("the static LU is inaccurate (check residual {:.1e})", self.check_accuracy(a))),
                });
            }
            match &static_result {
                Err(e) => tracing::debug!("the static LU failed ({e}): faer's partial-pivoting LU for this pattern"),
                Ok(()) => tracing::debug!("the static LU is inaccurate: faer's partial-pivoting LU for this pattern"),
            }
            self.static_lu = None;
            self.active = Active::None;
        }
        self.factorize_pivoting(a)
    }

    fn solve_in_place(&self, a: &CscMatrix<'_>, rhs: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        if matches!(self.active, Active::None) {
            return Err(LinearSolveError::Numeric("solve before a successful factorisation".into()));
        }
        let (res, refinements) = self.refined_solve(a, rhs, self.options.refine_tolerance);
        if !res.is_finite() || rhs.iter().any(|x| !x.is_finite()) {
            return Err(LinearSolveError::NonFinite);
        }
        if res > self.options.fail_tolerance {
            return Err(LinearSolveError::Inaccurate { residual: res, refinements, tolerance: self.options.fail_tolerance });
        }
        Ok(SolveStats { residual: res, refinements, krylov_iterations: 0 })
    }

    fn symbolic_factorizations(&self) -> usize {
        self.symbolic_count
    }

    /// Offers a held factorisation of the same pattern unless recent tries failed: after `k`
    /// failures in a row the next `2^k - 1` offers (at most 31) are declined. In 3D FSI the
    /// adapted mesh keeps its pattern in many steps but its values change too much near gamma_f
    /// for the previous step's factors to serve (model problem 4: never), and each try cost a
    /// few refinement solves.
    fn offer_held_factorization(&mut self, a: &CscMatrix<'_>) -> bool {
        if matches!(self.active, Active::None) || self.key != Some(pattern_key(a.pattern)) {
            return false;
        }
        if self.held_declines > 0 {
            self.held_declines -= 1;
            return false;
        }
        true
    }

    fn held_factorization_served(&mut self, served: bool) {
        if served {
            self.held_failures = 0;
        } else {
            self.held_failures += 1;
            self.held_declines = (1 << self.held_failures.min(5)) - 1;
        }
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
    fn saddle_point_system_uses_the_static_lu() {
        // Chain of "cells" [u_i, u_{i+1}, p_i]: nonsymmetric velocity block, one constraint
        // u_i - u_{i+1} per cell with a zero pressure diagonal.
        let nu = 60;
        let nc = nu - 1;
        let n = nu + nc;
        let cell = |c: usize| [c, c + 1, nu + c];
        let p = Pattern::from_cells(n, nc, |c, b| {
            b.clear();
            b.extend_from_slice(&cell(c));
        });
        let mut a = CscMatrix::zeros(&p);
        for c in 0..nc {
            let d = cell(c);
            let w = 1.0 + 0.02 * c as f64;
            let ke = [[2.0 * w + 0.1, -w + 0.4, 1.0], [-w - 0.4, 2.0 * w + 0.1, -1.0], [1.0, -1.0, 0.0]];
            for i in 0..3 {
                for j in 0..3 {
                    a.values[p.find(d[i], d[j]).unwrap()] += ke[i][j];
                }
            }
        }
        let x_exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).cos()).collect();
        let mut b = vec![0.0; n];
        a.mul_vec(&x_exact, &mut b);
        let mut lu = FaerLu::default();
        lu.factorize(&a).unwrap();
        assert!(lu.describe().starts_with("static"), "{}", lu.describe());
        let stats = lu.solve_in_place(&a, &mut b).unwrap();
        assert!(stats.residual < 1e-12);
        for i in 0..n {
            assert!((b[i] - x_exact[i]).abs() < 1e-9);
        }
        let mut piv = FaerLu::with_method(LinearSolverOptions::default(), LuMethod::Pivoting);
        let mut b2 = vec![0.0; n];
        a.mul_vec(&x_exact, &mut b2);
        piv.factorize(&a).unwrap();
        assert!(piv.describe().starts_with("faer"));
        piv.solve_in_place(&a, &mut b2).unwrap();
        for i in 0..n {
            assert!((b2[i] - x_exact[i]).abs() < 1e-9);
        }
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

    /// A multiplier whose diagonal turns zero on a matrix of the same pattern (a contact node
    /// coming into contact: `-1 / c` becomes its gap row) is ordered after its neighbour anew:
    /// the analysis of the first matrix eliminated it first (its degree is the least), on what
    /// is now a zero pivot (without the new analysis the static LU fails and the pivoting
    /// fallback takes over). The static LU solves every matrix, and the one after, out of
    /// contact again.
    #[test]
    fn a_diagonal_turned_zero_is_ordered_afresh() {
        // u0..u3 all coupled, u1 also to the multiplier 4.
        let p = Pattern::from_cells(5, 2, |c, b| {
            b.clear();
            b.extend_from_slice(if c == 0 { &[0, 1, 2, 3] } else { &[1, 4] });
        });
        let matrix = |d: f64| {
            let mut a = CscMatrix::zeros(&p);
            for j in 0..5 {
                for k in p.col_ptr[j]..p.col_ptr[j + 1] {
                    let i = p.row_idx[k];
                    a.values[k] = match (i, j) {
                        (4, 4) => d,
                        (4, _) | (_, 4) => -0.5,
                        _ if i == j => 4.0,
                        _ => -1.0,
                    };
                }
            }
            a
        };
        // Afresh, and (with `reuse_analysis`) with the held ordering; and back out of contact.
        for reuse_analysis in [false, true] {
            let mut lu = FaerLu::new(LinearSolverOptions { reuse_analysis, ..Default::default() });
            for d in [-1e-8, 0.0, -1e-8] {
                let a = matrix(d);
                lu.factorize(&a).unwrap();
                assert!(lu.factor_stats().is_some(), "d = {d}: the static LU is in use");
                let want = [1.0, -2.0, 0.5, 3.0, 1.5];
                let mut x = vec![0.0; 5];
                a.mul_vec(&want, &mut x);
                lu.solve_in_place(&a, &mut x).unwrap();
                assert!(x.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-10), "d = {d}: {x:?}");
            }
            // With `reuse_analysis` the held ordering may cost too much fill and be replaced.
            assert!(lu.symbolic_factorizations() >= 3, "reuse_analysis {reuse_analysis}: {}", lu.symbolic_factorizations());
            if !reuse_analysis {
                assert_eq!(lu.symbolic_factorizations(), 3);
            }
        }
    }

    /// Pseudo-random value in [-1, 1) from an index (deterministic).
    fn hash01(k: usize) -> f64 {
        let mut x = (k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x1234_5678;
        x = (x ^ (x >> 31)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x ^= x >> 29;
        (x % 2_000_000) as f64 / 1_000_000.0 - 1.0
    }

    /// An FSI-like saddle-point system: a fluid grid of `nx x ny` quadrilateral cells with two
    /// velocity dofs per node (nonsymmetric, diagonally dominant block) and one pressure per cell
    /// (zero diagonal, random divergence-like coupling), a solid chain of `ns` nodes (one dof
    /// each), and one Lagrange multiplier per solid node coupling it to a fluid velocity dof
    /// (zero diagonal). Returns the pattern, the values and the zero-diagonal dofs.
    fn fsi_like(nx: usize, ny: usize, ns: usize) -> (Pattern, Vec<f64>, Vec<bool>) {
        let nodes = (nx + 1) * (ny + 1);
        let nu = 2 * nodes;
        let np = nx * ny;
        let solid0 = nu + np;
        let mult0 = solid0 + ns;
        let n = mult0 + ns;
        let mut cells: Vec<Vec<usize>> = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let nd = [j * (nx + 1) + i, j * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i];
                let mut c: Vec<usize> = nd.iter().flat_map(|&v| [2 * v, 2 * v + 1]).collect();
                c.push(nu + j * nx + i);
                cells.push(c);
            }
        }
        for k in 0..ns.saturating_sub(1) {
            cells.push(vec![solid0 + k, solid0 + k + 1]);
        }
        // Multiplier k couples solid node k with the x-velocity of fluid node (k, ny / 2).
        for k in 0..ns {
            let f = 2 * ((ny / 2) * (nx + 1) + (k % (nx + 1)));
            cells.push(vec![f, solid0 + k, mult0 + k]);
        }
        let p = Pattern::from_cells(n, cells.len(), |c, b| {
            b.clear();
            b.extend_from_slice(&cells[c]);
        });
        let mut v = vec![0.0; p.nnz()];
        let zero: Vec<bool> = (0..n).map(|d| d >= nu && d < solid0 || d >= mult0).collect();
        for (c, dofs) in cells.iter().enumerate() {
            for (a, &i) in dofs.iter().enumerate() {
                for (b, &j) in dofs.iter().enumerate() {
                    let val = if zero[i] && zero[j] {
                        0.0
                    } else if zero[i] || zero[j] {
                        if dofs.len() == 3 {
                            // Multiplier row/column: u_f - u_s (position 0 is the fluid dof).
                            let regular = if zero[i] { b } else { a };
                            if regular == 0 {
                                1.0
                            } else {
                                -1.0
                            }
                        } else {
                            hash01(1000 * c + 10 * a.min(b) + a.max(b)) + 0.1
                        }
                    } else if i == j {
                        6.0 + hash01(7 * c + a).abs()
                    } else {
                        0.5 * hash01(100_000 + 97 * c + 11 * a + b)
                    };
                    v[p.find(i, j).unwrap()] += val;
                }
            }
        }
        (p, v, zero)
    }

    /// Keeps `(i, j)` entries of `p` with `keep(i, j)`, adds `extra` (both orders), values from `v`
    /// (new entries `value`).
    fn edited(p: &Pattern, v: &[f64], keep: impl Fn(usize, usize) -> bool, extra: &[(usize, usize)], value: f64) -> (Pattern, Vec<f64>) {
        let mut cols: Vec<Vec<(usize, f64)>> =
            (0..p.n).map(|j| (p.col_ptr[j]..p.col_ptr[j + 1]).filter(|&k| keep(p.row_idx[k], j)).map(|k| (p.row_idx[k], v[k])).collect()).collect();
        for &(i, j) in extra {
            cols[j].push((i, value));
            cols[i].push((j, value));
        }
        from_columns(cols)
    }

    /// The pattern and values of columns given as unsorted `(row, value)` lists.
    fn from_columns(cols: Vec<Vec<(usize, f64)>>) -> (Pattern, Vec<f64>) {
        let n = cols.len();
        let (mut col_ptr, mut row_idx, mut values) = (vec![0], Vec::new(), Vec::new());
        for mut c in cols {
            c.sort_by_key(|e| e.0);
            row_idx.extend(c.iter().map(|e| e.0));
            values.extend(c.iter().map(|e| e.1));
            col_ptr.push(row_idx.len());
        }
        (Pattern { n, col_ptr, row_idx }, values)
    }

    /// With `reuse_analysis`, a pattern inside the held factor structure keeps the analysis, one
    /// outside it with the same unknowns keeps the ordering (a new symbolic analysis), and one
    /// whose fill would grow past `KEPT_ORDERING_MAX_FLOPS` under it (the same graph with its
    /// nonzero-diagonal unknowns renumbered) is ordered afresh; the solves stay exact throughout.
    #[test]
    fn held_analysis_serves_patterns_inside_its_factor_structure() {
        let (p, v, zero) = fsi_like(12, 8, 6);
        let n = p.n;
        let mut lu = FaerLu::new(LinearSolverOptions { reuse_analysis: true, ..Default::default() });
        let solve = |lu: &mut FaerLu, pattern: &Pattern, values: Vec<f64>| {
            let a = CscMatrix { pattern, values };
            lu.factorize(&a).unwrap();
            let x: Vec<f64> = (0..n).map(|i| hash01(3 * i + 1)).collect();
            let mut b = vec![0.0; n];
            a.mul_vec(&x, &mut b);
            lu.solve_in_place(&a, &mut b).unwrap();
            b.iter().zip(&x).map(|(y, x)| (y - x).abs()).fold(0.0, f64::max)
        };
        assert!(solve(&mut lu, &p, v.clone()) < 1e-10);
        assert_eq!(lu.symbolic_factorizations(), 1);
        // Drop one off-diagonal pair between velocity dofs: inside the structure.
        let (i0, j0) = (0..n)
            .flat_map(|j| (p.col_ptr[j]..p.col_ptr[j + 1]).map(move |k| (k, j)))
            .map(|(k, j)| (p.row_idx[k], j))
            .find(|&(i, j)| i > j && !zero[i] && !zero[j])
            .unwrap();
        let (p2, v2) = edited(&p, &v, |i, j| (i, j) != (i0, j0) && (j, i) != (i0, j0), &[], 0.0);
        assert!(p2.nnz() == p.nnz() - 2);
        assert!(solve(&mut lu, &p2, v2) < 1e-10);
        assert_eq!(lu.symbolic_factorizations(), 1, "a pattern inside the factor structure keeps the analysis");
        // Couple two velocity dofs two apart in the graph, outside the factor structure: the same
        // unknowns, a little more fill.
        let regular_order = |lu: &FaerLu| -> Vec<usize> { lu.static_lu.as_ref().unwrap().sym.perm.iter().copied().filter(|&j| !zero[j]).collect() };
        let held = regular_order(&lu);
        let column = |j: usize| p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].to_vec();
        let (p3, v3) = (0..n)
            .filter(|&k| !zero[k])
            .flat_map(|k| column(k).into_iter().flat_map(move |i| column(k).into_iter().map(move |j| (i, j))))
            .filter(|&(i, j)| i < j && !zero[i] && !zero[j] && p.find(i, j).is_none())
            .map(|pair| edited(&p, &v, |_, _| true, &[pair], 0.3))
            .find(|(pe, ve)| {
                let ae = CscMatrix { pattern: pe, values: ve.clone() };
                lu.static_lu.as_ref().unwrap().sym.serves(&ae, &zero_diagonals(&ae)).is_none()
            })
            .expect("a pair outside the factor structure");
        assert!(solve(&mut lu, &p3, v3) < 1e-10);
        assert_eq!(lu.symbolic_factorizations(), 2);
        assert_eq!(regular_order(&lu), held, "the ordering is kept");
        // The nonzero-diagonal unknowns shuffled among themselves: the held ordering is of
        // another graph.
        let regular: Vec<usize> = (0..n).filter(|&j| !zero[j]).collect();
        let mut shuffled = regular.clone();
        shuffled.sort_by(|&a, &b| hash01(5 * a + 3).total_cmp(&hash01(5 * b + 3)));
        let mut relabel: Vec<usize> = (0..n).collect();
        regular.iter().zip(&shuffled).for_each(|(&from, &to)| relabel[from] = to);
        let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        for j in 0..n {
            for k in p.col_ptr[j]..p.col_ptr[j + 1] {
                cols[relabel[j]].push((relabel[p.row_idx[k]], v[k]));
            }
        }
        let (p4, v4) = from_columns(cols);
        let fresh = FaerLu::analyse(&CscMatrix { pattern: &p4, values: v4.clone() }, FillOrdering::default()).unwrap().flops;
        assert!(solve(&mut lu, &p4, v4) < 1e-10);
        let stats = lu.factor_stats().unwrap();
        assert_ne!(regular_order(&lu), held, "ordered afresh");
        assert!(stats.flops <= KEPT_ORDERING_MAX_FLOPS * fresh, "{} flops against {fresh} fresh", stats.flops);
    }

    #[test]
    fn auto_ordering_picks_by_degree_and_size() {
        // A sparse 2D-like system (about 5 entries per row) gets AMD ...
        let (p, v, _) = fsi_like(40, 30, 25);
        let a = CscMatrix { pattern: &p, values: v };
        assert_eq!(FaerLu::analyse(&a, FillOrdering::Auto).unwrap().ordering, FillOrdering::Amd);
        // ... and a dense-ish one (cells of 60 dofs, like 3D P2+ rows) nested dissection.
        let n = 600;
        let p = Pattern::from_cells(n, 19, |c, b| {
            b.clear();
            b.extend(30 * c..(30 * c + 60).min(n));
        });
        let v: Vec<f64> = (0..p.nnz()).map(|k| if p.row_idx[k] == col_of(&p, k) { 100.0 } else { 0.1 }).collect();
        let a = CscMatrix { pattern: &p, values: v };
        assert!(p.nnz() >= AUTO_ND_MIN_DEGREE * n);
        assert_eq!(FaerLu::analyse(&a, FillOrdering::Auto).unwrap().ordering, FillOrdering::NestedDissection);
    }

    /// Column of the `k`-th stored entry.
    fn col_of(p: &Pattern, k: usize) -> usize {
        p.col_ptr.partition_point(|&s| s <= k) - 1
    }

    #[test]
    fn nested_dissection_keeps_zero_diagonal_dofs_after_their_neighbours() {
        let (p, v, zero) = fsi_like(40, 30, 25);
        let a = CscMatrix { pattern: &p, values: v };
        for ordering in [FillOrdering::NestedDissection, FillOrdering::Amd] {
            let sym = static_symbolic(&a, ordering, None).unwrap();
            let n = p.n;
            let mut pos = vec![0; n];
            let mut seen = vec![false; n];
            for (new, &old) in sym.perm.iter().enumerate() {
                assert!(!seen[old], "{ordering:?}: not a permutation");
                seen[old] = true;
                pos[old] = new;
            }
            for j in (0..n).filter(|&j| zero[j]) {
                for &i in &p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]] {
                    if !zero[i] {
                        assert!(pos[j] > pos[i], "{ordering:?}: zero-diagonal dof {j} before its neighbour {i}");
                    }
                }
            }
        }
    }

    /// The threaded dense kernels of the large supernodes give the sequential solution: 3D Stokes
    /// on 4 x 4 x 4 cubes of P2+ tetrahedra (14 595 unknowns), whose top separators are large.
    #[test]
    fn threaded_large_blocks_give_the_sequential_solution() {
        use crate::discretize::flow::FlowDiscretization;
        use crate::physics::fluid::Formulation;
        let problem = crate::verify::stokes_3d_problem();
        let mesh = fdfsi_fem::generate::box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 4, 4, 4);
        let disc = FlowDiscretization::build(mesh, Formulation::ThreeD).unwrap();
        let (system, x0) = crate::discretize::flow::SteadySystem::new(&disc, &problem).unwrap();
        let mut k = CscMatrix::zeros(disc.whole_pattern());
        let mut rhs = vec![0.0; x0.len()];
        system.assemble(&x0, &mut k, &mut rhs).unwrap();
        let mut sols = Vec::new();
        for threads in [1, 2] {
            let mut lu = FaerLu::new(LinearSolverOptions { threads, ..Default::default() });
            lu.factorize(&k).unwrap();
            let st = lu.factor_stats().expect("the static LU");
            assert!(st.threaded_flops > 0.5 * st.flops, "large blocks hold most flops: {} of {}", st.threaded_flops, st.flops);
            let mut x = rhs.clone();
            let stats = lu.solve_in_place(&k, &mut x).unwrap();
            assert!(stats.residual < 1e-12, "threads {threads}: residual {}", stats.residual);
            sols.push(x);
        }
        let diff = norm(&sols[0].iter().zip(&sols[1]).map(|(p, q)| p - q).collect::<Vec<_>>());
        assert!(diff <= 1e-10 * norm(&sols[0]), "threaded and sequential solutions differ by {diff:e}");
    }

    #[test]
    fn fsi_like_saddle_system_nd_matches_amd() {
        let (p, v, _) = fsi_like(40, 30, 25);
        let n = p.n;
        let a = CscMatrix { pattern: &p, values: v };
        let x_exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin() + 0.5).collect();
        let mut b = vec![0.0; n];
        a.mul_vec(&x_exact, &mut b);
        let mut sols = Vec::new();
        for ordering in [FillOrdering::NestedDissection, FillOrdering::Amd] {
            let mut lu = FaerLu::new(LinearSolverOptions { ordering, ..Default::default() });
            lu.factorize(&a).unwrap();
            let st = lu.factor_stats().unwrap_or_else(|| panic!("{ordering:?}: fell back to pivoting: {}", lu.describe()));
            assert_eq!(st.ordering, ordering);
            let mut x = b.clone();
            let stats = lu.solve_in_place(&a, &mut x).unwrap();
            assert!(stats.residual < 1e-12, "{ordering:?}: residual {}", stats.residual);
            sols.push(x);
        }
        let xn = norm(&sols[1]);
        let diff = norm(&sols[0].iter().zip(&sols[1]).map(|(p, q)| p - q).collect::<Vec<_>>());
        assert!(diff <= 1e-10 * xn, "ND and AMD solutions differ by {diff:e} (|x| = {xn:e})");
        let err = norm(&sols[0].iter().zip(&x_exact).map(|(p, q)| p - q).collect::<Vec<_>>());
        assert!(err <= 1e-9 * norm(&x_exact));
    }

    /// A chain of `nr` regular dofs (4 on the diagonal, -1 beside it) and unknowns `nr..n` with a
    /// zero diagonal, joined by the symmetric `couplings` `(i, j, value)`; checks that the static
    /// LU (no fallback to pivoting) solves it with each ordering.
    fn assert_static_lu_solves_chain_saddle(nr: usize, n: usize, couplings: &[(usize, usize, f64)]) {
        let mut cells: Vec<Vec<usize>> = (0..nr - 1).map(|i| vec![i, i + 1]).collect();
        cells.extend(couplings.iter().map(|&(i, j, _)| vec![i, j]));
        let p = Pattern::from_cells(n, cells.len(), |c, b| {
            b.clear();
            b.extend_from_slice(&cells[c]);
        });
        let mut a = CscMatrix::zeros(&p);
        let mut add = |i: usize, j: usize, v: f64| a.values[p.find(i, j).unwrap()] += v;
        for i in 0..nr {
            add(i, i, 4.0);
            if i + 1 < nr {
                add(i, i + 1, -1.0);
                add(i + 1, i, -1.0);
            }
        }
        for &(i, j, v) in couplings {
            add(i, j, v);
            add(j, i, v);
        }
        let x_exact: Vec<f64> = (0..n).map(|i| 1.0 + i as f64).collect();
        let mut b = vec![0.0; n];
        a.mul_vec(&x_exact, &mut b);
        for ordering in [FillOrdering::NestedDissection, FillOrdering::Amd] {
            let mut lu = FaerLu::new(LinearSolverOptions { ordering, ..Default::default() });
            lu.factorize(&a).unwrap();
            let st = lu.factor_stats().unwrap_or_else(|| panic!("{ordering:?}: the static LU is used, no fallback: {}", lu.describe()));
            assert_eq!(st.mode_unknowns_joined, st.mode_unknowns, "{ordering:?}: {}", lu.describe());
            let mut x = b.clone();
            lu.solve_in_place(&a, &mut x).unwrap();
            for i in 0..n {
                assert!((x[i] - x_exact[i]).abs() < 1e-10, "{ordering:?} {i}: {} vs {}", x[i], x_exact[i]);
            }
        }
    }

    #[test]
    fn a_constraint_on_multipliers_is_eliminated_after_them_by_the_static_lu() {
        // [[A, B^T, 0], [B, 0, c], [0, c^T, 0]]: a chain of regular dofs, multipliers on pairs of
        // them and one unknown coupled to the multipliers only (as the removed multiplier modes
        // of an FSI system); it must come after them, not first with its zero pivot.
        let (nr, nm) = (6, 3);
        let n = nr + nm + 1;
        let mut couplings = Vec::new();
        for k in 0..nm {
            couplings.extend([(2 * k, nr + k, 1.0), (2 * k + 1, nr + k, -0.5), (nr + k, n - 1, 1.0 + k as f64)]);
        }
        assert_static_lu_solves_chain_saddle(nr, n, &couplings);
    }

    #[test]
    fn a_multiplier_mode_and_its_constraint_share_a_diagonal_block() {
        // Two multipliers with the same pairing (the mode z = (1, -1) pairs with nothing, as the
        // multiplier modes of a 3D FSI system pair with no velocity) and the unknown sigma with
        // (M z) . lambda = 0: nonsingular, but eliminating both multipliers before sigma meets a
        // zero pivot; the static LU must take sigma into their block instead of falling back.
        let nr = 6;
        let (m1, m2, m3, sigma) = (nr, nr + 1, nr + 2, nr + 3);
        let couplings = [(m1, 2, 1.0), (m1, 3, -0.5), (m2, 2, 1.0), (m2, 3, -0.5), (m3, 4, 0.7), (m3, 5, 0.3), (sigma, m1, 1.0), (sigma, m2, -1.0)];
        assert_static_lu_solves_chain_saddle(nr, nr + 4, &couplings);
    }

    #[test]
    fn supernodes_merge_along_a_path_of_the_elimination_tree_only() {
        // Supernodes {0, 1} (rows 2, 5), {2} (rows 4, 5), {3} (row 4), {4, 5}: joining columns
        // 1..=2 merges the first two (the first's rows beyond column 2 are rows of the second),
        // whose rows are then 4 and 5.
        let begin = [0, 2, 3, 4, 6];
        let patterns = vec![vec![2, 5], vec![4, 5], vec![4], vec![]];
        let (b, rows) = merge_supernodes(&begin, &patterns, &[(1, 2)]);
        assert_eq!(b, vec![0, 3, 4, 6]);
        assert_eq!(rows, vec![vec![4, 5], vec![4], vec![]]);
        let (b, _) = merge_supernodes(&begin, &patterns, &[]);
        assert_eq!(b, begin.to_vec());
        // {2} and {3} are siblings ({2}'s row 5 is no row of {3}): joining 2..=3 is refused.
        let (b, rows) = merge_supernodes(&begin, &patterns, &[(2, 3)]);
        assert_eq!(b, begin.to_vec());
        assert_eq!(rows, patterns);
    }

    #[test]
    fn tiny_and_empty_systems_do_not_panic() {
        for ordering in [FillOrdering::NestedDissection, FillOrdering::Amd] {
            let opts = LinearSolverOptions { ordering, ..Default::default() };
            // 0 x 0: an error or a trivial success, never a panic.
            let p0 = Pattern::from_cells(0, 0, |_, b| b.clear());
            let a0 = CscMatrix::zeros(&p0);
            let mut lu = FaerLu::new(opts.clone());
            if lu.factorize(&a0).is_ok() {
                let _ = lu.solve_in_place(&a0, &mut []);
            }
            // 1 x 1.
            let p1 = Pattern::from_cells(1, 1, |_, b| {
                b.clear();
                b.push(0);
            });
            let mut a1 = CscMatrix::zeros(&p1);
            a1.values[0] = 4.0;
            let mut lu = FaerLu::new(opts.clone());
            lu.factorize(&a1).unwrap();
            let mut x = [2.0];
            lu.solve_in_place(&a1, &mut x).unwrap();
            assert!((x[0] - 0.5).abs() < 1e-15);
            // Two disconnected blocks.
            let p2 = Pattern::from_cells(4, 2, |c, b| {
                b.clear();
                b.extend_from_slice(if c == 0 { &[0, 1] } else { &[2, 3] });
            });
            let mut a2 = CscMatrix::zeros(&p2);
            for (i, j, v) in [(0, 0, 2.0), (0, 1, 1.0), (1, 0, -1.0), (1, 1, 3.0), (2, 2, 1.0), (3, 3, 5.0), (2, 3, 0.5)] {
                a2.values[p2.find(i, j).unwrap()] = v;
            }
            let mut lu = FaerLu::new(opts);
            lu.factorize(&a2).unwrap();
            let x_exact = [1.0, -2.0, 3.0, 0.25];
            let mut b = vec![0.0; 4];
            a2.mul_vec(&x_exact, &mut b);
            lu.solve_in_place(&a2, &mut b).unwrap();
            for i in 0..4 {
                assert!((b[i] - x_exact[i]).abs() < 1e-13);
            }
        }
    }
}
