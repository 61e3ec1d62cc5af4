//! Augmented-Lagrangian (AL) block preconditioning of the monolithic saddle-point systems, inside
//! FGMRES ([`super::krylov`]).
//!
//! **The split.** The unknowns fall into the *multipliers* `Q` (fluid pressure, solid pressure,
//! coupling multiplier: all discontinuous, so each block's mass matrix `M` is block diagonal, one
//! small dense block per cell or facet, [`MultiplierBlock`]) and the *primal* rest `F` (velocities,
//! displacements, and the few unknowns of no block: kernel and trace modes; and with
//! [`Placement::Primal`] the multipliers of groups next to Dirichlet-constrained unknowns and the
//! solid's blocks, see "Groups at Dirichlet boundaries" and "The solid's blocks" below). With
//! `B = K_QF`, `B' = K_FQ` and `C = K_QQ`,
//!
//! ```text
//! K = [ A   B' ]      T = [ I   sigma gamma B' M^-1 ]      T K = [ A_gamma   B' + sigma gamma B' M^-1 C ]
//!     [ B   C  ]          [ 0   I                   ]            [ B         C                          ]
//! ```
//!
//! where `A_gamma = A + sigma gamma B' M^-1 B` is the primal block augmented by the (cell-local)
//! grad-div term and `sigma = +-1` makes `sigma B' M^-1 B` positive semi-definite (`B' = sigma B^T`
//! up to the Dirichlet rows). `T` is a row operation, so `T K x = T b` has the solution of `K x = b`.
//!
//! **The preconditioner** (right, block upper triangular, Benzi & Olshanskii 2006; Farrell,
//! Mitchell & Wechsung 2019) is `P = T^-1 [A_gamma, (T K)_FQ; 0, S]` with the Schur complement
//! `C - B A_gamma^-1 (T K)_FQ` approximated by `S^-1 = -sigma (eta + gamma) M^-1` per block. Its
//! application to `r = (r_F, r_Q)`:
//!
//! ```text
//! z_Q = S^-1 r_Q
//! z_F = A_gamma^-1 ( r_F + B' v ),   v = sigma gamma M^-1 (r_Q - C z_Q) - z_Q
//! ```
//!
//! `A_gamma^-1` is the static supernodal LU ([`super::linear::FaerLu`]) of the augmented block:
//! it has few zero diagonals (the multipliers kept primal, ordered after their neighbours), and
//! its factor is several times smaller than that of the whole system (Schaefer-Turek 2D-1 on the
//! medium mesh: 2.2e9 flops and 12.4 M entries against 3.6e10 and 64 M).
//!
//! **Scaling.** `gamma` is dimensionless: per block, `gamma_b = gamma eta_b` (times
//! [`SOLID_GAMMA_SCALE`] for the solid's blocks) with
//! `eta_b = mean diag(A) / mean diag(B' M^-1 B)` over the primal unknowns the block couples to
//! (for Stokes, the viscosity up to a constant; with inertia, `rho / dt` and convection enter it);
//! per group, `gamma_g = gamma_b` (times [`BOUNDARY_GAMMA_SCALE`] at Dirichlet boundaries), the
//! weight that enters `A_gamma`, `T` and `S^-1` above in place of `gamma`.
//!
//! **Groups at Dirichlet boundaries.** In a group coupled to a Dirichlet-constrained unknown the
//! free primal unknowns may control a multiplier mode only weakly (a corner cell: only the bubble
//! is free, and `int_K div(bubble) = 0`), so `B A^-1 B'` has eigenvalues far below `M / eta`
//! there, which `-(eta + gamma) M^-1` misses. Two treatments ([`Placement`], set by
//! [`AlOptions::boundary`]; the case files choose by dimension):
//! - `Primal` (the case files' default in 2D, and [`AlOptions::default`]'s): the group stays in
//!   the LU block, which takes it as any zero-diagonal unknown (after its neighbours). Exact; 3D
//!   Stokes cube (4^3 cells): 3 Krylov iterations, against 15 with these groups in the Schur
//!   block at the full `gamma`. In 3D most cells touch the boundary (7 104 of 12 288 pressure
//!   unknowns of the cavity at 8^3 cells), and these zero diagonals make the LU of the augmented
//!   block 4x costlier (1.27e11 flops against 3.14e10 at 8^3).
//! - `Schur` (the case files' default in 3D): the group joins the Schur block with its grad-div
//!   weight scaled by [`BOUNDARY_GAMMA_SCALE`], `gamma_g = 3e-3 gamma_b`, in the augmentation, in
//!   `T` and in `S^-1` alike (the identities above hold for any positive block-diagonal weight).
//!   With the full weight the preconditioned spectrum is still clustered at 1 (dense eigenvalues
//!   on the 3^3 Stokes cavity: all within 1e-3) but FGMRES stagnates near 1e-6 even with a
//!   pivoted dense inverse of `A_gamma`: the large `gamma` on weakly controlled modes makes the
//!   operator far from normal and the solve lose digits to cancellation. Measured Krylov
//!   iterations of the 3D Stokes cavity (3^3 cells, to 1e-8) against the factor: 15 (1),
//!   11 (1e-1), 5 (1e-2), 7 (1e-3); at 3e-3, 5-6 on 4^3 to 8^3 cells, 2-4 per Newton step for
//!   the Navier-Stokes cavity at 8^3 (11.4 s against 25.5 s with `Primal`, peak memory 650
//!   against 972 MiB; `examples/growth3d`). A local Schur complement `-B_g A_gg^-1 B'_g` of
//!   these groups in `S^-1` was tried: no fewer iterations than `-(eta + gamma_g) M^-1`.
//!
//! A constraint row of a symmetry plane of any normal (`c . du = 0`,
//! [`SaddlePointSplit::constraint_rows`]) holds its node's velocity as an identity row holds a
//! Dirichlet component: it counts as one here, so a problem turned with its symmetry planes
//! has the split of the original (the quarter pipe turned by 30 degrees: 6 and 6 Krylov
//! iterations per Newton step, as with the planes x = 0 and y = 0).
//!
//! **The solid's blocks.** An FSI system has two more multiplier blocks
//! ([`MultiplierRole`]): the solid pressure (P1disc per solid cell) and the coupling multiplier
//! (P1disc per coupling facet and component), placed by [`AlOptions::solid_pressure`] and
//! [`AlOptions::coupling`]:
//! - `Primal` ([`AlOptions::default`]'s; the case files' default for the solid pressure, and for
//!   the coupling multiplier in 2D): in the LU block with the solid displacement. Model problem
//!   3 (2D): 317 Krylov iterations in its 60 steps (4.1 s), against 791-861 (5.9-6.6 s) with both
//!   in the Schur block.
//! - `Schur` (the case files' default for the coupling multiplier in 3D): in the Schur block with
//!   the grad-div weight scaled by [`SOLID_GAMMA_SCALE`]; groups at Dirichlet boundaries (a
//!   coupling facet at a no-slip wall; with the solid pressure in the Schur block, a solid cell
//!   at the clamped rim) take [`BOUNDARY_GAMMA_SCALE`] on top, `3e-4 gamma_b`, as
//!   measured below. The coupling multiplier lives on a surface, where `B A^-1 B'` is not
//!   spectrally a mass matrix, and the full weight again makes FGMRES stall: model problem 4, its
//!   first 2 steps with fresh factors and both solid blocks in the Schur block, Krylov iterations
//!   per Newton step 2-21 at the factor 1, 3-5 at 0.1, 3-6 at 1e-2, 6-12 at 1e-3. The LU block
//!   loses the coupling multipliers, zero diagonals that the ordering must place after their
//!   neighbours: on the fine mesh of model problem 4 its factorisation falls from 1.36e12 to
//!   5.3e11 flops (both with three candidate separators; 4.6e11 with today's eight,
//!   [`super::ordering`]).
//!
//! The solid pressure stays primal because of the held factors (**Reuse**, below). Within a time
//! step the Jacobian changes little (model problem 4, first step, Newton iteration 1 to 2: the
//! fluid blocks by 5e-6 of their Frobenius norm, the solid displacement block by 5.6e-4, the
//! solid pressure's `B_s` by 1e-3, the coupling blocks not at all); in the Schur block the
//! augmentation `sigma gamma_g B_s' M^-1 B_s` multiplies the change of `B_s` by `gamma`, and the
//! held factors no longer precondition: 8 Krylov iterations left 0.6-0.8 of the residual at
//! every step's second Newton iteration (40 left 4e-4), so each step factorised twice. Primal,
//! the held factors serve the whole step (2-7 Krylov iterations per Newton step) for 7.5 % more
//! LU flops: model problem 4, 3 steps, 46.5 s to 32.8 s (one build, the placement set in the case
//! file); its fine mesh, 2 steps, 153 s to 90 s; the same forces to 7 digits.
//!
//! **Reuse.** With [`AlOptions::refactor_iterations`] `> 0`, the factorisation of `A_gamma` is
//! kept across Newton iterations and time steps (while the pattern and split are unchanged): a
//! solve tries the held factors for at most that many Krylov iterations, then factorises the
//! current matrix and goes on from the iterate reached; after such a failure the next Newton
//! iteration factorises at once (and the one after tries its factors again), after `k` failures
//! in a row the next `2^(k-1)`, at most 8 (`HeldFactorTrials`). Off by default for
//! steady solves: in 2D the Jacobian changes too much between Newton iterations for the held
//! factors to pay (Schaefer-Turek 2D-1: no faster with 3 or 6), though in 3D, where the LU
//! dominates, they do (the 3D cavity at Re 100, `n = 8`, `examples/growth3d`: 21.5 s with 6
//! against 30.1 s); time steps gain (model problem 4 with 8: one LU per step, 3 steps in 54 s
//! against 78 s with 0 and 75 s with the direct LU).
//!
//! An FSI step on a mesh adapted like the last one (the same topology, its nodes at gamma_f
//! moved) gives the same pattern and groups with other mass matrices: the split and the pattern
//! of `A_gamma` are kept (the LU, keyed by that pattern, keeps its analysis either way), the
//! inverse masses updated, but the held factors dropped. The moved nodes change `B` and `M`,
//! and `gamma` multiplies that change: on model problem 4 the factors of the last step left the
//! residual at 1.0 after 8 Krylov iterations. Model problem 4, 3 steps, two runs each in turn:
//! 27.7-30.4 s to 25.7-25.8 s, the same quantities bit for bit.
//!
//! **Tolerance.** FGMRES stops at `|b - K x| <= tol |b|` with `tol` the larger of
//! [`KrylovOptions::rel_tol`] and the forcing term a Newton solve sets
//! ([`LinearSolver::set_forcing`], [`super::newton::forcing_term`]): early Newton iterations need
//! only a loose solve (Schaefer-Turek 2D-1: 2-3 Krylov iterations per Newton step instead of 3-4,
//! with the same Newton iterations).

use super::krylov::{fgmres, KrylovOptions, KrylovReport};
use super::linear::{FaerLu, LinearSolveError, LinearSolver, LinearSolverOptions, SolveStats};
use fdfsi_fem::sparse::{CscMatrix, Pattern};
use std::cell::RefCell;

/// Multipliers whose mass matrix is block diagonal: one dense block per group (a cell of a
/// discontinuous pressure, a facet of the coupling multiplier).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MultiplierBlock {
    pub name: String,
    /// Dofs of group `g`: `dofs[offsets[g]..offsets[g + 1]]`.
    pub dofs: Vec<usize>,
    pub offsets: Vec<usize>,
    /// The mass matrices of the groups, row-major, one after the other.
    pub mass: Vec<f64>,
    /// What the multipliers are: it decides where they go ([`AlOptions::solid_pressure`],
    /// [`AlOptions::coupling`]) and their weight in the Schur block.
    pub role: MultiplierRole,
}

/// What the multipliers of a [`MultiplierBlock`] are.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MultiplierRole {
    /// The fluid pressure: always in the Schur block (those at Dirichlet boundaries placed by
    /// [`AlOptions::boundary`]).
    #[default]
    FluidPressure,
    /// The solid pressure (mixed laws): placed by [`AlOptions::solid_pressure`], its weight
    /// scaled by [`SOLID_GAMMA_SCALE`] in the Schur block.
    SolidPressure,
    /// The coupling multiplier on gamma_f: placed by [`AlOptions::coupling`], its weight scaled
    /// by [`SOLID_GAMMA_SCALE`] in the Schur block.
    Coupling,
}

impl MultiplierRole {
    /// Whether the block belongs to the solid (the solid pressure, the coupling multiplier): its
    /// grad-div weight in the Schur block is scaled by [`SOLID_GAMMA_SCALE`] (and its groups at
    /// Dirichlet boundaries by [`BOUNDARY_GAMMA_SCALE`] too).
    pub fn is_solid(self) -> bool {
        self != MultiplierRole::FluidPressure
    }
}

impl MultiplierBlock {
    /// An empty block.
    pub fn new(name: &str) -> Self {
        MultiplierBlock { name: name.into(), dofs: Vec::new(), offsets: vec![0], mass: Vec::new(), role: MultiplierRole::FluidPressure }
    }

    /// Appends a group: its dofs and its (row-major, `n x n`) mass matrix.
    pub fn push_group(&mut self, dofs: &[usize], mass: &[f64]) {
        debug_assert_eq!(mass.len(), dofs.len() * dofs.len());
        self.dofs.extend_from_slice(dofs);
        self.offsets.push(self.dofs.len());
        self.mass.extend_from_slice(mass);
    }

    /// Number of groups.
    pub fn num_groups(&self) -> usize {
        self.offsets.len() - 1
    }
}

/// The multiplier blocks of a monolithic system (every other unknown is primal).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SaddlePointSplit {
    pub multipliers: Vec<MultiplierBlock>,
    /// The components per node of the primal unknowns where they are one vector field numbered
    /// node by node from unknown 0, a node's components consecutive (the flow system: the
    /// velocity, `D` per node, then the pressure); 1 (or 0, the default) where they are of
    /// several fields (FSI). A preconditioner may treat them node by node: PETSc's field split
    /// gives its primal field this block size, and hypre's BoomerAMG then coarsens and
    /// interpolates each component apart (`crate::solve::petsc`).
    pub primal_components: usize,
    /// Rows that hold a primal unknown as a Dirichlet condition's identity row does, but are
    /// not identity rows: the constraint rows `c . du = 0` of nodes on symmetry planes of any
    /// normal ([`crate::discretize::symmetry::NormalConstraints`]). The groups coupled to them
    /// are at a Dirichlet boundary (see the module documentation).
    pub constraint_rows: Vec<usize>,
}

/// Options of the AL solver (`[solver.linear]`).
#[derive(Clone, Debug)]
pub struct AlOptions {
    /// Dimensionless weight of the grad-div augmentation (see the module documentation).
    pub gamma: f64,
    pub krylov: KrylovOptions,
    /// Keep the factorisation of the augmented block while solves take at most this many Krylov
    /// iterations (0: refactorise at every Newton iteration).
    pub refactor_iterations: usize,
    /// Options of the LU of the augmented block (and of the direct solve of systems without a
    /// split).
    pub lu: LinearSolverOptions,
    /// Where the groups coupled to a Dirichlet-constrained unknown go.
    pub boundary: Placement,
    /// Where the solid pressure of an FSI system goes ([`MultiplierRole::SolidPressure`]).
    pub solid_pressure: Placement,
    /// Where the coupling multiplier of an FSI system goes ([`MultiplierRole::Coupling`]).
    pub coupling: Placement,
}

/// Where multipliers go: the groups coupled to a Dirichlet-constrained unknown
/// ([`AlOptions::boundary`]) or the solid's blocks ([`AlOptions::solid_pressure`],
/// [`AlOptions::coupling`]); see the module documentation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Placement {
    /// Kept primal: in the LU block, ordered after their neighbours. Exact, and cheap where such
    /// multipliers are few (2D).
    #[default]
    Primal,
    /// In the Schur block, with a reduced grad-div weight ([`BOUNDARY_GAMMA_SCALE`],
    /// [`SOLID_GAMMA_SCALE`]): in 3D, a several times cheaper LU of the augmented block.
    Schur,
}

/// The factor on `gamma` of the groups at Dirichlet boundaries with
/// [`Placement::Schur`]: FGMRES stagnates with the full weight there (see the module
/// documentation).
pub const BOUNDARY_GAMMA_SCALE: f64 = 3e-3;

/// The factor on `gamma` of the solid's blocks ([`MultiplierRole::is_solid`]) in the Schur block
/// (see the module documentation, "The solid's blocks").
pub const SOLID_GAMMA_SCALE: f64 = 0.1;

impl Default for AlOptions {
    fn default() -> Self {
        AlOptions {
            gamma: 1e5,
            krylov: KrylovOptions::default(),
            refactor_iterations: 0,
            lu: LinearSolverOptions::default(),
            boundary: Placement::default(),
            solid_pressure: Placement::default(),
            coupling: Placement::default(),
        }
    }
}

/// One group of free multiplier dofs, in the solver's numbering.
#[derive(Clone, Debug)]
struct Group {
    block: usize,
    /// Its dofs (global): `q_dofs[start..end]`.
    start: usize,
    end: usize,
    /// Offset of its mass matrix in the split block's `mass`, and the positions of its free dofs
    /// in the original group (pinned dofs dropped).
    mass_offset: usize,
    size: usize,
    local: Vec<usize>,
    /// The primal unknowns its rows couple to (`F` numbering, sorted).
    coupled: Vec<usize>,
    /// Positions in `K` of `B'_g` (`coupled x dofs`, row-major) and `B_g` (`dofs x coupled`);
    /// `usize::MAX` where the pattern has no entry.
    bt_pos: Vec<usize>,
    b_pos: Vec<usize>,
    /// Positions in `K` of the diagonal entries of the coupled unknowns (`usize::MAX`: none).
    diag_pos: Vec<usize>,
    /// Where the positions in `A_gamma` of its grad-div block (`coupled x coupled`,
    /// column-major) start in [`Structure::aug_pos`].
    aug_start: usize,
    /// The factor on its block's `gamma_b`: [`BOUNDARY_GAMMA_SCALE`] for a group at a Dirichlet
    /// boundary in the Schur block, 1 otherwise.
    gamma_scale: f64,
}

/// One group's blocks of the Jacobian: `B'_g` (`coupled x m`, row-major), `B_g` and
/// `M_g^-1 B_g` (`m x coupled`); buffers reused from group to group.
#[derive(Default)]
struct GroupOperators {
    bt: Vec<f64>,
    b: Vec<f64>,
    mb: Vec<f64>,
}

impl GroupOperators {
    /// Loads the blocks of group `g` of `a`, with `minv` starting at its inverse mass matrix.
    fn load(&mut self, a: &CscMatrix<'_>, g: &Group, minv: &[f64]) {
        let (m, c) = (g.local.len(), g.coupled.len());
        let value = |&k: &usize| value_at(a, k);
        self.bt.clear();
        self.bt.extend(g.bt_pos.iter().map(value));
        self.b.clear();
        self.b.extend(g.b_pos.iter().map(value));
        self.mb.clear();
        self.mb.resize(m * c, 0.0);
        for ai in 0..m {
            for bi in 0..m {
                let w = minv[ai * m + bi];
                for ii in 0..c {
                    self.mb[ai * c + ii] += w * self.b[bi * c + ii];
                }
            }
        }
    }
}

/// Everything derived from the pattern and the split: index maps and the pattern of `A_gamma`.
struct Structure {
    key: u64,
    groups_at: GroupsAtDirichlet,
    /// `F` numbering: `f_dofs[i]` global, `f_local[global]` or `usize::MAX` for multipliers.
    f_dofs: Vec<usize>,
    f_local: Vec<usize>,
    /// Free multiplier dofs (group by group) and their groups.
    q_dofs: Vec<usize>,
    groups: Vec<Group>,
    pattern: Pattern,
    /// Position in `A_gamma` of each entry of `K` in `F x F` (`usize::MAX` elsewhere).
    ff_pos: Vec<usize>,
    /// Positions in `A_gamma` of the groups' grad-div blocks ([`Group::aug_start`]).
    aug_pos: Vec<usize>,
    /// Inverse mass matrices of the groups (free dofs), concatenated, and where each starts.
    minv: Vec<f64>,
    minv_offsets: Vec<usize>,
}

/// The multipliers kept primal and the groups at Dirichlet boundaries in the Schur block (their
/// first dofs), both sorted.
#[derive(Clone, Debug, PartialEq)]
struct GroupsAtDirichlet {
    pinned: Vec<usize>,
    boundary: Vec<usize>,
}

/// The numeric state: the factorised augmented block and the per-group operators.
struct Numeric {
    lu: FaerLu,
    /// Per block: `sigma`, `gamma_b`, `eta_b` of the held factors
    /// ([`AugmentedLagrangian::block_scales`]).
    scales: Vec<(f64, f64, f64)>,
    /// The values of `A_gamma` (kept for their allocation).
    values: Vec<f64>,
    factorized: bool,
    /// A fingerprint of the values of the matrix the held factors are of: a solve with another
    /// matrix (Newton's `reuse_factorization` skips `factorize`) treats them as held factors.
    factored: u64,
    /// When held factors are tried again after failing ([`HeldFactorTrials`]).
    trials: HeldFactorTrials,
    factorizations: usize,
}

/// Most Newton iterations that factorise at once after held factors failed in a row
/// ([`HeldFactorTrials`]).
const MOST_ITERATIONS_WITHOUT_TRIAL: usize = 8;

/// When to try held factors again: after `k` failed tries in a row (each `refactor_iterations`
/// Krylov iterations lost), the next `2^(k-1)` Newton iterations that could try them, at most
/// [`MOST_ITERATIONS_WITHOUT_TRIAL`], factorise at once instead; a try that serves resets it, so
/// an isolated failure costs what it did before (the next iteration factorises). Where the
/// Jacobian changes too much from one Newton iteration to the next for the held factors to serve
/// (the closed 3D valve, whose contact set changes and whose fibres cross their kink between
/// iterations: 30 Krylov iterations left the residual at 0.78-0.98 in 9 of 14 tries), they are
/// tried ever more seldom, not every other iteration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct HeldFactorTrials {
    /// Tries that failed since the last that served.
    failures: u32,
    /// Factorisations still to be done at once before the next try.
    wait: usize,
}

impl HeldFactorTrials {
    /// Whether this Newton iteration may try the held factors (else it factorises; counted).
    fn may_try(&mut self) -> bool {
        if self.wait > 0 {
            self.wait -= 1;
            false
        } else {
            true
        }
    }

    /// A try that served (`true`) or failed.
    fn record(&mut self, served: bool) {
        if served {
            *self = HeldFactorTrials::default();
        } else {
            self.failures += 1;
            self.wait = (1usize << (self.failures - 1).min(usize::BITS - 1)).min(MOST_ITERATIONS_WITHOUT_TRIAL);
        }
    }
}

/// The AL-preconditioned FGMRES solver; a plain LU ([`FaerLu`]) for systems without a split.
pub struct AugmentedLagrangian {
    options: AlOptions,
    split: SaddlePointSplit,
    structure: Option<Structure>,
    numeric: RefCell<Numeric>,
    direct: FaerLu,
    symbolic_count: usize,
    /// The forcing term of the next solve ([`LinearSolver::set_forcing`]).
    forcing: f64,
    /// The split's mass matrices changed, its groups did not: the structure's inverse masses
    /// are recomputed before the next use.
    masses_changed: bool,
    /// The pattern of `T K` for [`AugmentedLagrangian::transformed_system`].
    transformed: Option<TransformedPattern>,
}

impl AugmentedLagrangian {
    /// A solver with the given options; it is the direct LU until a split is given
    /// ([`LinearSolver::set_split`]).
    pub fn new(options: AlOptions) -> Self {
        let inner = LinearSolverOptions { check_accuracy: false, reuse_analysis: true, ..options.lu.clone() };
        let numeric = Numeric {
            lu: FaerLu::new(inner),
            scales: Vec::new(),
            values: Vec::new(),
            factorized: false,
            factored: 0,
            trials: HeldFactorTrials::default(),
            factorizations: 0,
        };
        AugmentedLagrangian {
            direct: FaerLu::new(options.lu.clone()),
            options,
            split: SaddlePointSplit::default(),
            structure: None,
            numeric: RefCell::new(numeric),
            symbolic_count: 0,
            forcing: 0.0,
            masses_changed: false,
            transformed: None,
        }
    }

    /// Numeric factorisations of the augmented block so far.
    pub fn factorizations(&self) -> usize {
        self.numeric.borrow().factorizations
    }

    /// Size and cost of the LU in use: that of the augmented block, or of the whole system
    /// without a split.
    pub fn factor_stats(&self) -> Option<super::linear::FactorStats> {
        if self.without_split() {
            self.direct.factor_stats()
        } else {
            self.numeric.borrow().lu.factor_stats()
        }
    }

    /// Whether the split has no multipliers: then the solver is the direct LU.
    fn without_split(&self) -> bool {
        self.split.multipliers.iter().all(|b| b.dofs.is_empty())
    }

    fn build_structure(&self, a: &CscMatrix<'_>, key: u64, groups_at: GroupsAtDirichlet) -> Result<Structure, LinearSolveError> {
        let GroupsAtDirichlet { pinned, boundary } = groups_at;
        let p = a.pattern;
        let n = p.n;
        let mut is_q = vec![false; n];
        let mut q_dofs = Vec::new();
        let mut groups = Vec::new();
        for (b, block) in self.split.multipliers.iter().enumerate() {
            let mut mass_offset = 0;
            for g in 0..block.num_groups() {
                let dofs = &block.dofs[block.offsets[g]..block.offsets[g + 1]];
                let start = q_dofs.len();
                let mut local = Vec::new();
                for (i, &d) in dofs.iter().enumerate() {
                    if pinned.binary_search(&d).is_err() && d < n && !is_q[d] {
                        is_q[d] = true;
                        q_dofs.push(d);
                        local.push(i);
                    }
                }
                if !local.is_empty() {
                    groups.push(Group {
                        block: b,
                        start,
                        end: q_dofs.len(),
                        mass_offset,
                        size: dofs.len(),
                        local,
                        coupled: Vec::new(),
                        bt_pos: Vec::new(),
                        b_pos: Vec::new(),
                        diag_pos: Vec::new(),
                        aug_start: 0,
                        gamma_scale: if boundary.binary_search(&dofs[0]).is_ok() { BOUNDARY_GAMMA_SCALE } else { 1.0 },
                    });
                }
                mass_offset += dofs.len() * dofs.len();
            }
        }
        let f_dofs: Vec<usize> = (0..n).filter(|&i| !is_q[i]).collect();
        let mut f_local = vec![usize::MAX; n];
        for (i, &d) in f_dofs.iter().enumerate() {
            f_local[d] = i;
        }
        for g in &mut groups {
            let mut c: Vec<usize> = q_dofs[g.start..g.end]
                .iter()
                .flat_map(|&q| p.row_idx[p.col_ptr[q]..p.col_ptr[q + 1]].iter().map(|&i| f_local[i]))
                .filter(|&i| i != usize::MAX)
                .collect();
            c.sort_unstable();
            c.dedup();
            let qs = &q_dofs[g.start..g.end];
            let at = |i: usize, j: usize| p.find(i, j).unwrap_or(usize::MAX);
            let f_dofs = &f_dofs;
            g.bt_pos = c.iter().flat_map(|&fi| qs.iter().map(move |&q| (f_dofs[fi], q))).map(|(i, q)| at(i, q)).collect();
            g.b_pos = qs.iter().flat_map(|&q| c.iter().map(move |&fi| (q, f_dofs[fi]))).map(|(q, i)| at(q, i)).collect();
            g.diag_pos = c.iter().map(|&fi| at(f_dofs[fi], f_dofs[fi])).collect();
            g.coupled = c;
        }
        // Columns of `A_gamma`: those of `K_FF`, plus the couplings of each group's grad-div
        // term where `K_FF` lacks them (none for a pressure of the fluid's own cells).
        let mut cols: Vec<Vec<usize>> = f_dofs
            .iter()
            .map(|&j| p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].iter().map(|&i| f_local[i]).filter(|&i| i != usize::MAX).collect())
            .collect();
        // The groups that couple to each primal column; a column's rows marked by its index.
        let mut groups_of: Vec<Vec<usize>> = vec![Vec::new(); f_dofs.len()];
        for (gi, g) in groups.iter().enumerate() {
            g.coupled.iter().for_each(|&j| groups_of[j].push(gi));
        }
        let mut mark = vec![usize::MAX; f_dofs.len()];
        for (j, col) in cols.iter_mut().enumerate() {
            col.iter().for_each(|&i| mark[i] = j);
            let before = col.len();
            for &gi in &groups_of[j] {
                for &i in &groups[gi].coupled {
                    if mark[i] != j {
                        mark[i] = j;
                        col.push(i);
                    }
                }
            }
            if col.len() > before {
                col.sort_unstable();
            }
        }
        drop(groups_of);
        let mut col_ptr = Vec::with_capacity(f_dofs.len() + 1);
        col_ptr.push(0);
        let mut row_idx = Vec::with_capacity(cols.iter().map(Vec::len).sum());
        for c in &cols {
            row_idx.extend_from_slice(c);
            col_ptr.push(row_idx.len());
        }
        drop(cols);
        let pattern = Pattern { n: f_dofs.len(), col_ptr, row_idx };
        // Both columns are sorted (`f_local` is increasing), so one merge finds the positions.
        let mut ff_pos = vec![usize::MAX; p.nnz()];
        for (jl, &j) in f_dofs.iter().enumerate() {
            let mut pos = pattern.col_ptr[jl];
            for k in p.col_ptr[j]..p.col_ptr[j + 1] {
                let il = f_local[p.row_idx[k]];
                if il != usize::MAX {
                    while pattern.row_idx[pos] < il {
                        pos += 1;
                    }
                    debug_assert_eq!(pattern.row_idx[pos], il);
                    ff_pos[k] = pos;
                }
            }
        }
        let mut aug_pos = Vec::with_capacity(groups.iter().map(|g| g.coupled.len().pow(2)).sum());
        for g in &mut groups {
            g.aug_start = aug_pos.len();
            for &j in &g.coupled {
                let (base, end) = (pattern.col_ptr[j], pattern.col_ptr[j + 1]);
                let rows = &pattern.row_idx[base..end];
                let mut k = 0;
                for &i in &g.coupled {
                    while rows[k] < i {
                        k += 1;
                    }
                    aug_pos.push(base + k);
                }
            }
        }
        let minv = self.inverse_masses(&groups, &q_dofs)?;
        let minv_offsets = groups.iter().scan(0, |o, g| Some(std::mem::replace(o, *o + g.local.len().pow(2)))).collect();
        Ok(Structure {
            key,
            groups_at: GroupsAtDirichlet { pinned, boundary },
            f_dofs,
            f_local,
            q_dofs,
            groups,
            pattern,
            ff_pos,
            aug_pos,
            minv,
            minv_offsets,
        })
    }

    /// Multiplier dofs that stay primal, and the groups at Dirichlet boundaries in the Schur
    /// block (see the module documentation): multipliers with identity rows (a pinned pressure)
    /// stay primal; the groups coupled to a Dirichlet-constrained unknown (an identity row, or
    /// one of the split's [`SaddlePointSplit::constraint_rows`]) stay primal with
    /// [`Placement::Primal`] and are listed in `boundary` with
    /// [`Placement::Schur`].
    fn groups_at_dirichlet(&self, a: &CscMatrix<'_>) -> GroupsAtDirichlet {
        let mut identity = identity_rows(a);
        let p = a.pattern;
        self.split.constraint_rows.iter().filter(|&&r| r < p.n).for_each(|&r| identity[r] = true);
        let mut multiplier = vec![false; p.n];
        self.split.multipliers.iter().flat_map(|b| &b.dofs).filter(|&&q| q < p.n).for_each(|&q| multiplier[q] = true);
        let (mut pinned, mut boundary) = (Vec::new(), Vec::new());
        let primal = self.options.boundary == Placement::Primal;
        for b in &self.split.multipliers {
            for g in 0..b.num_groups() {
                let dofs: Vec<usize> = b.dofs[b.offsets[g]..b.offsets[g + 1]].iter().copied().filter(|&q| q < p.n).collect();
                let at_dirichlet = dofs.iter().any(|&q| p.row_idx[p.col_ptr[q]..p.col_ptr[q + 1]].iter().any(|&i| identity[i] && !multiplier[i]));
                pinned.extend(dofs.iter().copied().filter(|&q| (at_dirichlet && primal) || identity[q]));
                if at_dirichlet && !primal {
                    boundary.push(b.dofs[b.offsets[g]]);
                }
            }
        }
        pinned.sort_unstable();
        pinned.dedup();
        boundary.sort_unstable();
        GroupsAtDirichlet { pinned, boundary }
    }

    /// The inverse mass matrices of the groups' free dofs, concatenated (with each structure, and
    /// again when the split's masses change: they do not change with the Newton iterate).
    fn inverse_masses(&self, groups: &[Group], q_dofs: &[usize]) -> Result<Vec<f64>, LinearSolveError> {
        let mut minv = Vec::new();
        for g in groups {
            let block = &self.split.multipliers[g.block];
            let m = g.local.len();
            let full = &block.mass[g.mass_offset..g.mass_offset + g.size * g.size];
            let sub: Vec<f64> = (0..m * m).map(|k| full[g.local[k / m] * g.size + g.local[k % m]]).collect();
            let inv = invert_dense(&sub, m)
                .ok_or_else(|| LinearSolveError::Numeric(format!("{}: singular mass matrix of the group of dof {}", block.name, q_dofs[g.start])))?;
            minv.extend_from_slice(&inv);
        }
        Ok(minv)
    }

    /// Per block: `sigma` (the sign that makes `sigma B' M^-1 B` positive semi-definite), and
    /// `eta_b = mean diag(A) / mean diag(B' M^-1 B)` over the primal unknowns the block couples
    /// to; returns `(sigma, gamma_b, eta_b)`, `gamma_b = gamma eta_b` (times
    /// [`SOLID_GAMMA_SCALE`] for the solid's blocks).
    fn block_scales(&self, a: &CscMatrix<'_>, s: &Structure, ops: &mut GroupOperators) -> Vec<(f64, f64, f64)> {
        let nb = self.split.multipliers.len();
        // (sum of K_iq K_qi, sum of diag A, sum of diag G, count) per block.
        let mut sums = vec![(0.0, 0.0, 0.0, 0usize); nb];
        let mut seen = vec![vec![false; s.f_dofs.len()]; nb];
        for (g, offset) in s.groups.iter().zip(&s.minv_offsets) {
            ops.load(a, g, &s.minv[*offset..]);
            let (m, c) = (g.local.len(), g.coupled.len());
            let sum = &mut sums[g.block];
            for (ii, &fi) in g.coupled.iter().enumerate() {
                let row = &ops.bt[ii * m..(ii + 1) * m];
                sum.0 += (0..m).map(|ai| row[ai] * ops.b[ai * c + ii]).sum::<f64>();
                sum.2 += (0..m).map(|ai| row[ai] * ops.mb[ai * c + ii]).sum::<f64>().abs();
                if row.iter().any(|&v| v != 0.0) && !seen[g.block][fi] {
                    seen[g.block][fi] = true;
                    sum.1 += value_at(a, g.diag_pos[ii]).abs();
                    sum.3 += 1;
                }
            }
        }
        sums.iter()
            .enumerate()
            .map(|(bi, &(kk, diag_a, diag_g, count))| {
                let sigma = if kk >= 0.0 { 1.0 } else { -1.0 };
                let eta = if diag_g > 0.0 && count > 0 { diag_a / diag_g } else { 1.0 };
                let scale = if self.split.multipliers[bi].role.is_solid() { SOLID_GAMMA_SCALE } else { 1.0 };
                (sigma, self.options.gamma * scale * eta, eta)
            })
            .collect()
    }

    /// Rebuilds the structure when the pattern of `a`, its pinned multipliers or its groups at
    /// Dirichlet boundaries changed.
    fn update_structure(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
        let t0 = std::time::Instant::now();
        let key = super::linear::pattern_key(a.pattern);
        let groups_at = self.groups_at_dirichlet(a);
        tracing::debug!("pattern key and groups at Dirichlet boundaries in {:.3} s", t0.elapsed().as_secs_f64());
        if self.structure.as_ref().is_some_and(|s| s.key == key && s.groups_at == groups_at) {
            if self.masses_changed {
                let s = self.structure.as_ref().expect("structure");
                let minv = self.inverse_masses(&s.groups, &s.q_dofs)?;
                self.structure.as_mut().expect("structure").minv = minv;
                self.masses_changed = false;
            }
            return Ok(());
        }
        self.masses_changed = false;
        let num = self.numeric.get_mut();
        num.factorized = false;
        num.scales.clear();
        self.structure = None;
        self.transformed = None;
        self.symbolic_count += 1;
        let t = std::time::Instant::now();
        self.structure = Some(self.build_structure(a, key, groups_at)?);
        let s = self.structure.as_ref().expect("structure");
        tracing::debug!(
            "split of the saddle-point system in {:.3} s: {} primal unknowns (of which {} multipliers kept primal), {} multipliers in {} groups ({} at Dirichlet boundaries)",
            t.elapsed().as_secs_f64(),
            s.f_dofs.len(),
            s.groups_at.pinned.len(),
            s.q_dofs.len(),
            s.groups.len(),
            s.groups_at.boundary.len()
        );
        Ok(())
    }

    /// The augmented primal block `A_gamma` of `a` (with the split given), unfactorised: what
    /// the preconditioner factorises, e.g. to try another solver on it. `None` without a split.
    pub fn augmented_block(&mut self, a: &CscMatrix<'_>) -> Result<Option<(Pattern, Vec<f64>)>, LinearSolveError> {
        if self.without_split() {
            return Ok(None);
        }
        self.update_structure(a)?;
        let values = self.assemble_augmented(a, &mut self.numeric.borrow_mut());
        Ok(self.structure.as_ref().map(|s| (s.pattern.clone(), values)))
    }

    /// The transformed system `T K` of `a` with the split given ([`TransformedSystem`]); `None`
    /// without a split.
    pub fn transformed_system(&mut self, a: &CscMatrix<'_>) -> Result<Option<TransformedSystem<'_>>, LinearSolveError> {
        if self.without_split() {
            return Ok(None);
        }
        self.update_structure(a)?;
        let (augmented, scales) = {
            let mut num = self.numeric.borrow_mut();
            let augmented = self.assemble_augmented(a, &mut num);
            (augmented, num.scales.clone())
        };
        let s = self.structure.as_ref().expect("structure");
        if self.transformed.is_none() {
            self.transformed = Some(TransformedPattern::new(a.pattern, s));
        }
        let t = self.transformed.as_ref().expect("set above");
        let mut values = vec![0.0; t.pattern.nnz()];
        let mut k_values = vec![0.0; t.pattern.nnz()];
        for (v, &pos) in a.values.iter().zip(&t.k_pos) {
            k_values[pos] = *v;
        }
        // K outside `F x F`, then `A_gamma` in it.
        let p = a.pattern;
        for j in 0..p.n {
            let column_in_f = s.f_local[j] != usize::MAX;
            for k in p.col_ptr[j]..p.col_ptr[j + 1] {
                if !(column_in_f && s.f_local[p.row_idx[k]] != usize::MAX) {
                    values[t.k_pos[k]] += a.values[k];
                }
            }
        }
        for (v, &pos) in augmented.iter().zip(&t.aug_pos) {
            values[pos] += v;
        }
        // (T K)_FQ = B' + sigma gamma_g B'_g M_g^-1 C_g, and S_p's blocks.
        let mut ops = GroupOperators::default();
        let mut schur_blocks = Vec::with_capacity(s.groups.len());
        let mut transform = Vec::new();
        for (gi, (g, &offset)) in s.groups.iter().zip(&s.minv_offsets).enumerate() {
            ops.load(a, g, &s.minv[offset..]);
            let (sigma, gamma_b, eta) = scales[g.block];
            let gamma_g = gamma_b * g.gamma_scale;
            let qs = &s.q_dofs[g.start..g.end];
            let m = qs.len();
            let minv = &s.minv[offset..offset + m * m];
            // T - I: sigma gamma_g B'_g M_g^-1.
            // C_g (m x the columns its rows reach, row-major) from K.
            let columns = &t.group_columns[gi];
            let nc = columns.len();
            let c: Vec<f64> = (0..m * nc).map(|k| a.get(qs[k / nc], columns[k % nc])).collect();
            let with_c = c.iter().any(|&v| v != 0.0);
            for (ii, &fi) in g.coupled.iter().enumerate() {
                let bt = &ops.bt[ii * m..(ii + 1) * m];
                // Row ii of sigma gamma_g B'_g M_g^-1: of T - I, and times C_g of (T K)_FQ.
                let w: Vec<f64> = (0..m).map(|b| sigma * gamma_g * (0..m).map(|a| bt[a] * minv[a * m + b]).sum::<f64>()).collect();
                transform.extend(qs.iter().zip(&w).map(|(&q, &v)| (s.f_dofs[fi], q, v)));
                if with_c {
                    for (cj, &q) in columns.iter().enumerate() {
                        let add = (0..m).map(|b| w[b] * c[b * nc + cj]).sum::<f64>();
                        if add != 0.0 {
                            values[t.pattern.find(s.f_dofs[fi], q).expect("merged in")] += add;
                        }
                    }
                }
            }
            let mass =
                invert_dense(minv, m).ok_or_else(|| LinearSolveError::Numeric(format!("singular inverse mass of the group of dof {}", qs[0])))?;
            let scale = -1.0 / (sigma * (eta + gamma_g));
            let mut order: Vec<usize> = (0..m).collect();
            order.sort_unstable_by_key(|&k| qs[k]);
            let dofs: Vec<usize> = order.iter().map(|&k| qs[k]).collect();
            let block: Vec<f64> = (0..m * m).map(|k| scale * mass[order[k / m] * m + order[k % m]]).collect();
            schur_blocks.push((dofs, block));
        }
        Ok(Some(TransformedSystem { pattern: &t.pattern, values, k_values, transform, in_schur: &t.in_schur, schur_blocks }))
    }

    /// Builds `A_gamma = K_FF + sum_g sigma gamma_g B'_g M_g^-1 B_g` from `a` and factorises it.
    fn factorize_augmented(&self, a: &CscMatrix<'_>, num: &mut Numeric) -> Result<(), LinearSolveError> {
        let t0 = std::time::Instant::now();
        let values = self.assemble_augmented(a, num);
        let s = self.structure.as_ref().expect("structure");
        let ag = CscMatrix { pattern: &s.pattern, values };
        tracing::debug!("augmented block assembled in {:.3} s", t0.elapsed().as_secs_f64());
        let t = std::time::Instant::now();
        // Until the LU succeeds: failed factors are never held.
        num.factorized = false;
        // The LU names its unknowns in the `F` numbering; the caller knows the global one.
        num.lu.factorize(&ag).map_err(|e| match e {
            LinearSolveError::ZeroPivot { pivot, largest, unknown, step } => {
                LinearSolveError::ZeroPivot { pivot, largest, unknown: s.f_dofs[unknown], step }
            }
            other => other,
        })?;
        num.values = ag.values;
        tracing::debug!("factorised the augmented block in {:.3} s: {}", t.elapsed().as_secs_f64(), num.lu.describe());
        num.factorized = true;
        num.factored = values_key(a);
        num.factorizations += 1;
        Ok(())
    }

    /// The values of `A_gamma` on the structure's pattern, with the block scales set from `a`.
    fn assemble_augmented(&self, a: &CscMatrix<'_>, num: &mut Numeric) -> Vec<f64> {
        let s = self.structure.as_ref().expect("structure");
        let mut ops = GroupOperators::default();
        // With each factorisation (kept with it): the matrix may have changed its scale (a
        // continuation in the viscosity, another time step).
        num.scales = self.block_scales(a, s, &mut ops);
        let mut values = std::mem::take(&mut num.values);
        values.clear();
        values.resize(s.pattern.nnz(), 0.0);
        for (k, &pos) in s.ff_pos.iter().enumerate() {
            if pos != usize::MAX {
                values[pos] += a.values[k];
            }
        }
        for (g, offset) in s.groups.iter().zip(&s.minv_offsets) {
            ops.load(a, g, &s.minv[*offset..]);
            let (sigma, gamma_b, _) = num.scales[g.block];
            let gamma_g = gamma_b * g.gamma_scale;
            let (m, c) = (g.local.len(), g.coupled.len());
            // Column jj of sigma gamma_g B'_g (M^-1 B_g).
            let pos = &s.aug_pos[g.aug_start..g.aug_start + c * c];
            for jj in 0..c {
                for ii in 0..c {
                    let bt = &ops.bt[ii * m..(ii + 1) * m];
                    values[pos[jj * c + ii]] += sigma * gamma_g * (0..m).map(|ai| bt[ai] * ops.mb[ai * c + jj]).sum::<f64>();
                }
            }
        }
        values
    }

    /// `z = P^-1 r` (see the module documentation).
    fn precondition(&self, a: &CscMatrix<'_>, num: &Numeric, r: &[f64], z: &mut [f64], v: &mut [f64], y: &mut [f64]) {
        let s = self.structure.as_ref().expect("structure");
        let p = a.pattern;
        let apply_minv = |g: &Group, offset: usize, scale: f64, src: &[f64], dst: &mut [f64]| {
            let m = g.end - g.start;
            let qs = &s.q_dofs[g.start..g.end];
            for (ai, &qa) in qs.iter().enumerate() {
                dst[qa] = scale * (0..m).map(|bi| s.minv[offset + ai * m + bi] * src[qs[bi]]).sum::<f64>();
            }
        };
        // z_Q = -sigma (eta + gamma_g) M^-1 r_Q.
        for (g, &offset) in s.groups.iter().zip(&s.minv_offsets) {
            let (sigma, gamma_b, eta) = num.scales[g.block];
            apply_minv(g, offset, -sigma * (eta + gamma_b * g.gamma_scale), r, z);
        }
        // v_Q = sigma gamma_g M^-1 (r_Q - C z_Q) - z_Q, with w = r_Q - C z_Q in y.
        for &q in &s.q_dofs {
            y[q] = r[q];
        }
        for &q in &s.q_dofs {
            for k in p.col_ptr[q]..p.col_ptr[q + 1] {
                let i = p.row_idx[k];
                if s.f_local[i] == usize::MAX {
                    y[i] -= a.values[k] * z[q];
                }
            }
        }
        for (g, &offset) in s.groups.iter().zip(&s.minv_offsets) {
            let (sigma, gamma_b, _) = num.scales[g.block];
            apply_minv(g, offset, sigma * gamma_b * g.gamma_scale, y, v);
        }
        for &q in &s.q_dofs {
            v[q] -= z[q];
        }
        // z_F = A_gamma^-1 (r_F + B' v).
        let mut yf: Vec<f64> = s.f_dofs.iter().map(|&i| r[i]).collect();
        for &q in &s.q_dofs {
            for k in p.col_ptr[q]..p.col_ptr[q + 1] {
                let il = s.f_local[p.row_idx[k]];
                if il != usize::MAX {
                    yf[il] += a.values[k] * v[q];
                }
            }
        }
        num.lu.solve_unrefined(&mut yf);
        for (il, &i) in s.f_dofs.iter().enumerate() {
            z[i] = yf[il];
        }
    }

    /// FGMRES from the guess in `x`, with at most `max_iterations` iterations.
    fn krylov_solve(&self, a: &CscMatrix<'_>, num: &Numeric, rhs: &[f64], x: &mut [f64], max_iterations: usize) -> KrylovReport {
        let n = rhs.len();
        let (mut v, mut y) = (vec![0.0; n], vec![0.0; n]);
        let options = KrylovOptions { max_iterations, rel_tol: self.options.krylov.rel_tol.max(self.forcing), ..self.options.krylov };
        fgmres(|u, out| a.mul_vec(u, out), |r, z| self.precondition(a, num, r, z, &mut v, &mut y), rhs, x, &options)
    }
}

/// The AL's transformed system `T K` for a solver outside fdfsi (PETSc's field split,
/// `solve::petsc`): its pattern (that of `K` with the grad-div couplings of `A_gamma` added, and
/// the couplings of `B'_g M_g^-1 C_g`), `T K`, `K` and `T - I` on it, the fields and the Schur
/// block's preconditioning matrix. With `U = [A_gamma, (T K)_FQ; 0, S_p]` (the upper
/// block-triangular factorisation of `T K`, `S_p^-1 = -sigma (eta_b + gamma_g) M_g^-1` per
/// group), `P^-1 = U^-1 T` is the preconditioner of the module documentation: a Krylov method
/// on `K y = b` right-preconditioned by it iterates as [`AugmentedLagrangian`]'s FGMRES, on the
/// true residual. (Solving `T K y = T b` instead converges on `T r`: `T`'s `gamma`-sized
/// entries then hide residuals of `K` up to 1e5 times larger, model problem 3.)
pub struct TransformedSystem<'a> {
    pub pattern: &'a Pattern,
    /// `T K` and `K` on the pattern.
    pub values: Vec<f64>,
    pub k_values: Vec<f64>,
    /// `T - I`: `(row, column, value)`, rows primal, columns in the Schur block.
    pub transform: Vec<(usize, usize, f64)>,
    /// Whether each unknown is in the Schur block (`Q`: the multipliers there); the others, the
    /// multipliers kept primal with them, form `A_gamma`.
    pub in_schur: &'a [bool],
    /// Per group of the Schur block: its unknowns (increasing) and `S_p`'s dense block on them
    /// (row-major), `-M_g / (sigma (eta_b + gamma_g))`.
    pub schur_blocks: Vec<(Vec<usize>, Vec<f64>)>,
}

/// The pattern of `T K` ([`TransformedSystem`]) and where the values go, per structure (made
/// again with each new structure).
struct TransformedPattern {
    pattern: Pattern,
    in_schur: Vec<bool>,
    /// Position in `T K` of each entry of `K` (all of them) and of `A_gamma`.
    k_pos: Vec<usize>,
    aug_pos: Vec<usize>,
    /// Per group, the columns of `C = K_QQ` its rows reach (increasing).
    group_columns: Vec<Vec<usize>>,
}

impl TransformedPattern {
    /// `K`'s pattern `p` with `A_gamma`'s (`s.pattern`, in the `F` numbering) merged in, and
    /// the entries of `B'_g M_g^-1 C_g` where a group's rows of `C = K_QQ` reach other groups.
    fn new(p: &Pattern, s: &Structure) -> Self {
        let n = p.n;
        let mut in_schur = vec![false; n];
        let mut group_of = vec![usize::MAX; n];
        for (gi, g) in s.groups.iter().enumerate() {
            for &q in &s.q_dofs[g.start..g.end] {
                in_schur[q] = true;
                group_of[q] = gi;
            }
        }
        // The columns of `C` each group's rows reach.
        let mut group_columns: Vec<Vec<usize>> = vec![Vec::new(); s.groups.len()];
        for &q in &s.q_dofs {
            for k in p.col_ptr[q]..p.col_ptr[q + 1] {
                let i = p.row_idx[k];
                if in_schur[i] && group_columns[group_of[i]].last() != Some(&q) {
                    group_columns[group_of[i]].push(q);
                }
            }
        }
        for c in &mut group_columns {
            c.sort_unstable();
            c.dedup();
        }
        // Extra rows per column `q` of `Q`: the primal unknowns coupled to the groups reaching it.
        let mut extra: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (gi, g) in s.groups.iter().enumerate() {
            for &q in &group_columns[gi] {
                extra[q].extend(g.coupled.iter().map(|&fi| s.f_dofs[fi]));
            }
        }
        let mut col_ptr = vec![0];
        let mut row_idx = Vec::with_capacity(p.nnz() + s.pattern.nnz() - s.ff_pos.iter().filter(|&&k| k != usize::MAX).count());
        for j in 0..n {
            let mut column = p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].to_vec();
            let jl = s.f_local[j];
            if jl != usize::MAX {
                column.extend(s.pattern.row_idx[s.pattern.col_ptr[jl]..s.pattern.col_ptr[jl + 1]].iter().map(|&il| s.f_dofs[il]));
            }
            column.extend_from_slice(&extra[j]);
            column.sort_unstable();
            column.dedup();
            row_idx.extend(column);
            col_ptr.push(row_idx.len());
        }
        let pattern = Pattern { n, col_ptr, row_idx };
        let position = |i: usize, j: usize| pattern.find(i, j).expect("merged in");
        let mut k_pos = Vec::with_capacity(p.nnz());
        for j in 0..n {
            k_pos.extend(p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].iter().map(|&i| position(i, j)));
        }
        let mut aug_pos = Vec::with_capacity(s.pattern.nnz());
        for jl in 0..s.pattern.n {
            let j = s.f_dofs[jl];
            aug_pos.extend(s.pattern.row_idx[s.pattern.col_ptr[jl]..s.pattern.col_ptr[jl + 1]].iter().map(|&il| position(s.f_dofs[il], j)));
        }
        TransformedPattern { pattern, in_schur, k_pos, aug_pos, group_columns }
    }
}

/// Whether two splits have the same blocks and groups (their mass matrices aside).
fn same_groups(a: &SaddlePointSplit, b: &SaddlePointSplit) -> bool {
    a.multipliers.len() == b.multipliers.len()
        && a.multipliers.iter().zip(&b.multipliers).all(|(x, y)| x.name == y.name && x.role == y.role && x.dofs == y.dofs && x.offsets == y.offsets)
}

/// The value at position `k` of `a`, 0 for `usize::MAX` (an entry the pattern lacks).
fn value_at(a: &CscMatrix<'_>, k: usize) -> f64 {
    a.values.get(k).copied().unwrap_or(0.0)
}

/// A fingerprint of the values of `a` (FNV-1a over their bits).
fn values_key(a: &CscMatrix<'_>) -> u64 {
    super::linear::fnv1a(a.values.iter().map(|v| v.to_bits()))
}

/// Rows of `a` whose only nonzero is on the diagonal (Dirichlet-constrained unknowns).
fn identity_rows(a: &CscMatrix<'_>) -> Vec<bool> {
    let p = a.pattern;
    let mut off = vec![false; p.n];
    for j in 0..p.n {
        for k in p.col_ptr[j]..p.col_ptr[j + 1] {
            if p.row_idx[k] != j && a.values[k] != 0.0 {
                off[p.row_idx[k]] = true;
            }
        }
    }
    (0..p.n).map(|i| !off[i] && a.get(i, i) != 0.0).collect()
}

/// Inverse of a small dense row-major matrix by Gauss-Jordan elimination with partial pivoting.
fn invert_dense(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut m = a.to_vec();
    let mut inv: Vec<f64> = (0..n * n).map(|k| if k / n == k % n { 1.0 } else { 0.0 }).collect();
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for c in 0..n {
        let piv = (c..n).max_by(|&i, &j| m[i * n + c].abs().total_cmp(&m[j * n + c].abs()))?;
        if m[piv * n + c].abs() <= 1e-14 * scale {
            return None;
        }
        for k in 0..n {
            m.swap(c * n + k, piv * n + k);
            inv.swap(c * n + k, piv * n + k);
        }
        let d = 1.0 / m[c * n + c];
        for k in 0..n {
            m[c * n + k] *= d;
            inv[c * n + k] *= d;
        }
        for i in (0..n).filter(|&i| i != c) {
            let f = m[i * n + c];
            if f != 0.0 {
                for k in 0..n {
                    m[i * n + k] -= f * m[c * n + k];
                    inv[i * n + k] -= f * inv[c * n + k];
                }
            }
        }
    }
    Some(inv)
}

impl LinearSolver for AugmentedLagrangian {
    fn factorize(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
        if self.without_split() {
            return self.direct.factorize(a);
        }
        self.update_structure(a)?;
        let num = self.numeric.get_mut();
        let keep = num.factorized && self.options.refactor_iterations > 0 && num.trials.may_try();
        if keep {
            return Ok(());
        }
        self.factorize_augmented(a, &mut self.numeric.borrow_mut())
    }

    fn solve_in_place(&self, a: &CscMatrix<'_>, rhs: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        if self.without_split() {
            return self.direct.solve_in_place(a, rhs);
        }
        let mut num = self.numeric.borrow_mut();
        if !num.factorized {
            return Err(LinearSolveError::Numeric("solve before a successful factorisation".into()));
        }
        let b = rhs.to_vec();
        rhs.iter_mut().for_each(|x| *x = 0.0);
        let mut iterations = 0;
        if num.factored != values_key(a) {
            // Held factors: at most `refactor_iterations` iterations, then factorise this matrix
            // and go on from where they got.
            let report = self.krylov_solve(a, &num, &b, rhs, self.options.refactor_iterations);
            iterations += report.iterations;
            num.trials.record(report.converged);
            if report.converged {
                return Ok(SolveStats { residual: report.residual, refinements: 0, krylov_iterations: iterations });
            }
            tracing::debug!(
                "held factors of the augmented block: not converged in {} Krylov iterations (residual {:.1e}): factorising",
                report.iterations,
                report.residual
            );
            self.factorize_augmented(a, &mut num)?;
        }
        let report = self.krylov_solve(a, &num, &b, rhs, self.options.krylov.max_iterations);
        iterations += report.iterations;
        if rhs.iter().any(|x| !x.is_finite()) {
            return Err(LinearSolveError::NonFinite);
        }
        if !report.converged {
            return Err(LinearSolveError::KrylovNotConverged {
                iterations,
                residual: report.residual,
                tolerance: self.options.krylov.rel_tol.max(self.forcing),
            });
        }
        Ok(SolveStats { residual: report.residual, refinements: 0, krylov_iterations: iterations })
    }

    /// The splits of the system and the analyses of the LU (of the augmented block, or of the
    /// whole system without a split).
    fn symbolic_factorizations(&self) -> usize {
        self.symbolic_count + self.numeric.borrow().lu.symbolic_factorizations() + self.direct.symbolic_factorizations()
    }

    fn offer_held_factorization(&mut self, a: &CscMatrix<'_>) -> bool {
        self.without_split() && self.direct.offer_held_factorization(a)
    }

    fn held_factorization_served(&mut self, served: bool) {
        if self.without_split() {
            self.direct.held_factorization_served(served);
        }
    }

    fn set_forcing(&mut self, relative_residual: f64) {
        self.forcing = relative_residual;
    }

    fn set_split(&mut self, mut split: SaddlePointSplit) {
        let (solid_pressure, coupling) = (self.options.solid_pressure, self.options.coupling);
        split.multipliers.retain(|b| match b.role {
            MultiplierRole::FluidPressure => true,
            MultiplierRole::SolidPressure => solid_pressure == Placement::Schur,
            MultiplierRole::Coupling => coupling == Placement::Schur,
        });
        if split == self.split {
            return;
        }
        if same_groups(&split, &self.split) {
            // The mesh moved but kept its topology (an FSI step adapted like the last one): the
            // structure stays, the inverse masses follow. The held factors go: gamma multiplies
            // the change of `B` and `M` (model problem 4: held factors of the last step left the
            // residual at 1.0 after 8 Krylov iterations).
            self.masses_changed = true;
        } else {
            self.structure = None;
            self.transformed = None;
        }
        self.numeric.get_mut().factorized = false;
        self.split = split;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Newton iterations that may try held factors, of `n`, after `trials`.
    fn tries(trials: &mut HeldFactorTrials, n: usize) -> Vec<bool> {
        (0..n).map(|_| trials.may_try()).collect()
    }

    #[test]
    fn held_factors_that_fail_in_a_row_are_tried_ever_more_seldom() {
        let mut trials = HeldFactorTrials::default();
        assert_eq!(tries(&mut trials, 2), [true, true], "tried while none failed");
        // Failures in a row: 1, 2, 4, 8, 8 iterations factorise at once before the next try.
        for wait in [1, 2, 4, 8, 8] {
            trials.record(false);
            let mut expected = vec![false; wait];
            expected.push(true);
            assert_eq!(tries(&mut trials, wait + 1), expected, "after {} failures", trials.failures);
        }
        // A try that serves: the next failure waits one iteration again.
        trials.record(true);
        assert_eq!(trials, HeldFactorTrials::default());
        trials.record(false);
        assert_eq!(tries(&mut trials, 2), [false, true]);
    }
}
