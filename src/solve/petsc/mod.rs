//! Linear solves through the system's PETSc (cargo feature `petsc`; Debian: `apt install
//! petsc-dev`): the MPI + PETSc engine. [`PetscSolver`] hands each system to a PETSc `KSP` on
//! `MPI_COMM_WORLD`, configured through PETSc's options database under the prefix
//! [`OPTIONS_PREFIX`]: by default a direct solve by MUMPS ([`DEFAULT_OPTIONS`]), anything else
//! by options, as FEniCSx users are used to (`-fdfsi_ksp_type gmres -fdfsi_pc_type ilu`,
//! `-fdfsi_mat_mumps_icntl_14 50`, `-fdfsi_ksp_view`).
//!
//! One process (no `mpirun`, or `mpirun -n 1`): a sequential AIJ matrix. Several (`mpirun -n
//! N fdfsi run`): each rank gives PETSc its rows ([`Numbering::rows`]), a contiguous block of
//! PETSc's numbering of the unknowns (a level-set order of the matrix graph, [`Numbering`]: a
//! slice of the domain), as its rows of a distributed AIJ matrix (preallocated from the pattern,
//! so setting values sends nothing), and after the solve every rank gathers the whole solution
//! (`MPI_Allgatherv`) in the layout's numbering, so the Newton update is the same on all.
//!
//! Those rows come two ways. A flow without the augmented Lagrangian is a *partitioned
//! assembly* ([`RowSolver`]: [`crate::discretize::flow::FlowDiscretization::build_with`]): each
//! rank builds, assembles and holds only its rows (those of a [`Partition`], the same numbering)
//! and the cells touching them, and the residual norms are sums over the ranks
//! ([`RowSolver::sum`]); on one rank this is the whole system. Every other system (FSI, the
//! solid, the augmented Lagrangian, which transforms the whole matrix) is replicated: every rank
//! assembles the whole system and copies its rows out. [`world`]
//! tells a process its rank; [`finalize`] and [`abort`] end MPI. An error that one rank may meet
//! alone (a failed PETSc or MPI call) ends every rank at once, printed with its rank: returned, it
//! would send that rank on while the others wait for it in a collective call. Errors the ranks
//! agree on (a diverged Krylov solve, an inaccurate solve) are returned on every rank alike.
//!
//! Where the primal unknowns of a split are one vector field numbered node by node
//! ([`SaddlePointSplit::primal_components`]: the flow systems' velocity), PETSc's numbering
//! keeps each node's components together ([`Nodes`]) and the primal field of a `fieldsplit`
//! preconditioner gets their number as its block size: hypre's BoomerAMG on it then coarsens and
//! interpolates each component apart (its "unknown" approach), and PETSc's GAMG sees the block
//! size too. On the 3D Poiseuille slab of `benches/scale3d` (one V-cycle on the velocity, the
//! Schur complement by Jacobi on `selfp`): 119 Krylov iterations for its two Newton solves at
//! 56 427 unknowns, 126 at 434 259 and 136 at 2 129 253, against 196, 337 and (after 28
//! minutes) not yet one solve with scalar AMG.
//!
//! With a system's saddle-point split ([`LinearSolver::set_split`]) a `fieldsplit`
//! preconditioner gets the fields [`FIELDS`]. [`PetscSolver::augmented_lagrangian`] runs
//! fdfsi's augmented-Lagrangian preconditioner in PETSc: FGMRES on the system, its
//! preconditioner a shell (`apply_augmented_lagrangian`) that applies `T` and then a Schur
//! field split of `T K` (options prefix [`AL_OPTIONS_PREFIX`]), with the Schur block
//! preconditioned by the AL's `S_p` ([`crate::solve::augmented::TransformedSystem`]).
//!
//! PETSc is initialised on first use and finalised only by [`finalize`] (which `fdfsi run`
//! calls at the end of a run that `mpirun` started; otherwise its state lives as long as the
//! process): MPI first at the thread level `MPI_THREAD_SERIALIZED` (solvers on several threads
//! take turns), then PETSc without its signal handlers (`-no_signal_handler`: Rust's own stay).
//! PETSc is not thread-safe: every call into it holds one process-wide lock. Its options
//! database is process-wide too: every locked section that lets PETSc read options (set-up,
//! factorisation, solve) first clears it and sets its solver's options ([`DEFAULT_OPTIONS`],
//! then its own), so each `KSP` sees exactly its solver's options (and none from
//! `PETSC_OPTIONS` or `.petscrc`).

mod ffi;

use super::augmented::{AlOptions, AugmentedLagrangian, SaddlePointSplit, TransformedSystem};
use super::linear::{norm, pattern_key, LinearSolveError, LinearSolver, SolveStats};
use super::partition::{row_pattern_key, Partition, RowSolver};
pub use super::partition::{Nodes, Numbering, World};
use fdfsi_fem::sparse::{CscMatrix, Pattern, RowMatrix, RowPattern};
use ffi::PetscInt;
use std::ffi::{c_int, CStr, CString};
use std::ops::Range;
use std::ptr::{null, null_mut};
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

/// The options prefix of fdfsi's `KSP`: `-fdfsi_ksp_type`, `-fdfsi_pc_type`, ...
pub const OPTIONS_PREFIX: &str = "fdfsi_";

/// The fields a `fieldsplit` preconditioner (`-fdfsi_pc_type fieldsplit`) gets, from the
/// system's [`SaddlePointSplit`]: the primal unknowns (velocities, displacements, the few of no
/// block) and the multipliers (fluid pressure, solid pressure, coupling multiplier), in this
/// order; their solvers take the prefixes `-fdfsi_fieldsplit_primal_` and
/// `-fdfsi_fieldsplit_multiplier_` (`-fdfsi_pc_fieldsplit_type schur` makes the second the
/// Schur complement's).
pub const FIELDS: [&str; 2] = ["primal", "multiplier"];

/// The options [`PetscSolver`] starts from: a direct solve (`preonly` with an LU
/// preconditioner) by MUMPS, which pivots, as the saddle-point systems need.
pub const DEFAULT_OPTIONS: &str = "-fdfsi_ksp_type preonly -fdfsi_pc_type lu -fdfsi_pc_factor_mat_solver_type mumps";

/// The options [`PetscSolver::augmented_lagrangian`] starts from: FGMRES (right-preconditioned)
/// to `1e-10`, its Gram-Schmidt refined at every step (PETSc's default, classical Gram-Schmidt
/// without refinement, loses the basis's orthogonality with the 3D defaults' reduced-gamma groups
/// in the Schur block, and FGMRES stalls: the 3D Poiseuille slab at 56 427 unknowns, still at
/// 4e-7 of its start after 200 iterations; refined, 6), with the field split [`FIELDS`] as an
/// upper block-triangular Schur factorisation, the primal block `A_gamma` by MUMPS's LU, the
/// Schur block by `S_p` (block diagonal: block Jacobi per rank, ILU(0) within, exact on its
/// blocks but for a group that a rank boundary of [`Numbering::rows`] cuts, about one per
/// boundary; with no zero-pivot threshold: the entries of `S_p` scale as `|K| / (eta + gamma)`,
/// 2e-14 on the medium Schaefer-Turek mesh, below PETSc's absolute default of 2.2e-14); the same
/// preconditioner as `solve::augmented`'s.
pub const AUGMENTED_LAGRANGIAN_OPTIONS: &str = "-fdfsi_ksp_type fgmres -fdfsi_ksp_rtol 1e-10 -fdfsi_ksp_max_it 200 -fdfsi_ksp_gmres_restart 200 -fdfsi_ksp_gmres_cgs_refinement_type refine_always \
-fdfsi_al_pc_type fieldsplit -fdfsi_al_pc_fieldsplit_type schur -fdfsi_al_pc_fieldsplit_schur_fact_type upper \
-fdfsi_al_fieldsplit_primal_ksp_type preonly -fdfsi_al_fieldsplit_primal_pc_type lu -fdfsi_al_fieldsplit_primal_pc_factor_mat_solver_type mumps \
-fdfsi_al_fieldsplit_multiplier_ksp_type preonly -fdfsi_al_fieldsplit_multiplier_pc_type bjacobi -fdfsi_al_fieldsplit_multiplier_sub_pc_factor_zeropivot 0";

/// A solve whose relative residual `|b - A x| / |b|` (against fdfsi's matrix) exceeds this
/// fraction of the fail tolerance is refined: `x += K^-1 (b - A x)` by the same `KSP`. FGMRES's
/// own residual estimate can run ahead of the true residual: with the AL's large `gamma`, the
/// preconditioned directions are large and cancel (model problem 4, third step: estimate
/// 1e-12, true residual 1e-5 relative); one refinement, which restarts from the true
/// residual, brings it to the Krylov tolerance again.
const REFINE_ABOVE: f64 = 0.1;

/// At most this many refinements per solve.
const MAX_REFINEMENTS: usize = 3;

/// Every call into PETSc holds this.
static PETSC: Mutex<()> = Mutex::new(());

fn lock() -> MutexGuard<'static, ()> {
    PETSC.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// `Err` with PETSc's message for a nonzero error `code` of `call`; on several ranks, every rank
/// ended ([`end_ranks_on`]).
fn check(code: ffi::PetscErrorCode, call: &str) -> Result<(), LinearSolveError> {
    if code == 0 {
        return Ok(());
    }
    let (mut text, mut specific): (*const std::ffi::c_char, *mut std::ffi::c_char) = (null(), null_mut());
    // SAFETY: PetscErrorMessage writes pointers to PETSc's own strings (or leaves them null).
    let message = unsafe {
        ffi::PetscErrorMessage(code, &mut text, &mut specific);
        [text, specific.cast_const()]
            .iter()
            .filter(|p| !p.is_null())
            .map(|&p| CStr::from_ptr(p).to_string_lossy().trim().to_string())
            .filter(|m| !m.is_empty())
            .collect::<Vec<_>>()
            .join(": ")
    };
    Err(end_ranks_on(LinearSolveError::Petsc(format!("{call}: {message} (PETSc error {code})"))))
}

/// `error`, where this process runs alone; on several ranks, `error` printed with this rank and
/// every rank ended (`MPI_Abort`, exit code 1). For an error that this rank may meet alone
/// (a failed PETSc or MPI call, a check of this rank's rows) during or just before a collective
/// call: returned, it would send this rank on (a Newton failure, a cut time step and a new
/// collective call) while the other ranks wait in the collective call it left. Errors that the
/// ranks agree on (a Krylov solve that diverged: PETSc's reason is global; a residual reduced
/// over the ranks, [`World::max`]) are returned on every rank alike, and a run may go on from
/// them (cut the step) on all ranks together.
fn end_ranks_on(error: LinearSolveError) -> LinearSolveError {
    if let Some(Ok(world)) = WORLD.get() {
        if world.size > 1 {
            eprintln!("rank {}: {error}; ending every rank (the others would wait for this one)", world.rank);
            abort(1);
        }
    }
    error
}

impl World {
    /// The largest of every rank's `value`, a NaN counting as infinite (MPI's maximum of a NaN
    /// is undefined; the caller holds the lock; collective).
    fn max(&self, value: f64) -> Result<f64, LinearSolveError> {
        let local = if value.is_nan() { f64::INFINITY } else { value };
        if self.size == 1 {
            return Ok(local);
        }
        let mut max = local;
        // SAFETY: one value of the named type each, sent and received.
        let code = unsafe {
            ffi::MPI_Allreduce((&local as *const f64).cast(), (&mut max as *mut f64).cast(), 1, ffi::mpi_double(), ffi::mpi_max(), ffi::comm_world())
        };
        if code != 0 {
            return Err(end_ranks_on(LinearSolveError::Petsc(format!("MPI_Allreduce failed (MPI error {code})"))));
        }
        Ok(max)
    }

    /// The sum of every rank's `value`, with the same bits on every rank: the values gathered
    /// and added in rank order (an `MPI_Allreduce` may add them in another order on each
    /// rank; the caller holds the lock; collective).
    fn sum(&self, value: f64) -> Result<f64, LinearSolveError> {
        if self.size == 1 {
            return Ok(value);
        }
        let mut values = vec![0.0; self.size];
        let (counts, starts): (Vec<c_int>, Vec<c_int>) = (0..self.size as c_int).map(|r| (1, r)).unzip();
        // SAFETY: one value sent, one received from each rank into its place in `values`.
        let code = unsafe {
            let double = ffi::mpi_double();
            ffi::MPI_Allgatherv(
                (&value as *const f64).cast(),
                1,
                double,
                values.as_mut_ptr().cast(),
                counts.as_ptr(),
                starts.as_ptr(),
                double,
                ffi::comm_world(),
            )
        };
        if code != 0 {
            return Err(end_ranks_on(LinearSolveError::Petsc(format!("MPI_Allgatherv failed (MPI error {code})"))));
        }
        Ok(values.iter().sum())
    }

    /// Fills all of `x` (in PETSc's `numbering`) on every rank from each rank's rows
    /// ([`Numbering::rows`]; the caller holds the lock; collective).
    fn all_gather(&self, numbering: &Numbering, x: &mut [f64]) -> Result<(), LinearSolveError> {
        if self.size == 1 {
            return Ok(());
        }
        let ranges: Vec<Range<usize>> = (0..self.size).map(|rank| numbering.rows(rank)).collect();
        let int = |v: usize| c_int::try_from(v).map_err(|_| LinearSolveError::Petsc(format!("{v} values exceed MPI's count range")));
        let counts = ranges.iter().map(|r| int(r.len())).collect::<Result<Vec<_>, _>>()?;
        let starts = ranges.iter().map(|r| int(r.start)).collect::<Result<Vec<_>, _>>()?;
        // SAFETY: `x` holds every rank's rows (counts and displacements within it); in place,
        // the send arguments are ignored.
        let code = unsafe {
            let double = ffi::mpi_double();
            ffi::MPI_Allgatherv(ffi::MPI_IN_PLACE, 0, double, x.as_mut_ptr().cast(), counts.as_ptr(), starts.as_ptr(), double, ffi::comm_world())
        };
        if code != 0 {
            return Err(end_ranks_on(LinearSolveError::Petsc(format!("MPI_Allgatherv failed (MPI error {code})"))));
        }
        Ok(())
    }
}

/// Whether [`finalize`] ran: PETSc cannot start again.
static FINALIZED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// This process's rank once MPI and PETSc are initialised ([`initialize`]).
static WORLD: OnceLock<Result<World, String>> = OnceLock::new();

/// Initialises MPI and PETSc once per process (the caller holds the lock); returns this rank.
fn initialize() -> Result<World, LinearSolveError> {
    if FINALIZED.load(std::sync::atomic::Ordering::SeqCst) {
        return Err(LinearSolveError::Petsc("PETSc was finalised (solve::petsc::finalize)".into()));
    }
    WORLD
        .get_or_init(|| {
            let (mut mpi, mut provided, mut petsc): (c_int, c_int, ffi::PetscBool) = (0, 0, 0);
            let (mut rank, mut size): (c_int, c_int) = (0, 1);
            let flag = CString::new("-no_signal_handler").expect("no NUL");
            // SAFETY: plain calls; null argc/argv are allowed by MPI_Init_thread.
            unsafe {
                ffi::MPI_Initialized(&mut mpi);
                if mpi == 0 && ffi::MPI_Init_thread(null_mut(), null_mut(), ffi::MPI_THREAD_SERIALIZED, &mut provided) != 0 {
                    return Err("MPI_Init_thread failed".to_string());
                }
                check(ffi::PetscInitialized(&mut petsc), "PetscInitialized").map_err(|e| e.to_string())?;
                if petsc == 0 {
                    check(ffi::PetscOptionsSetValue(null_mut(), flag.as_ptr(), null()), "PetscOptionsSetValue").map_err(|e| e.to_string())?;
                    check(ffi::PetscInitializeNoArguments(), "PetscInitializeNoArguments").map_err(|e| e.to_string())?;
                }
                if ffi::MPI_Comm_rank(ffi::comm_world(), &mut rank) != 0 || ffi::MPI_Comm_size(ffi::comm_world(), &mut size) != 0 {
                    return Err("MPI_Comm_rank or MPI_Comm_size failed".to_string());
                }
            }
            Ok(World { rank: rank as usize, size: size as usize })
        })
        .clone()
        .map_err(LinearSolveError::Petsc)
}

/// This process's rank and the number of ranks, initialising MPI and PETSc if they are not yet.
pub fn world() -> Result<World, LinearSolveError> {
    let _petsc = lock();
    initialize()
}

/// Ends PETSc and MPI, if they were started (after which no [`PetscSolver`] works): a process
/// that `mpirun` started calls this before it exits, after its solvers are dropped.
pub fn finalize() {
    let _petsc = lock();
    if FINALIZED.swap(true, std::sync::atomic::Ordering::SeqCst) {
        return;
    }
    let (mut petsc, mut mpi, mut ended): (ffi::PetscBool, c_int, c_int) = (0, 0, 0);
    // SAFETY: plain calls, each only when what it ends was started and not yet ended.
    unsafe {
        if ffi::PetscInitialized(&mut petsc) == 0 && petsc != 0 {
            ffi::PetscFinalize();
        }
        ffi::MPI_Initialized(&mut mpi);
        ffi::MPI_Finalized(&mut ended);
        if mpi != 0 && ended == 0 {
            ffi::MPI_Finalize();
        }
    }
}

/// Ends every rank with exit `code` (`MPI_Abort`): for an error on some ranks only, which would
/// leave the others waiting in their next collective call. Returns only if MPI is not running.
pub fn abort(code: i32) {
    let (mut mpi, mut ended): (c_int, c_int) = (0, 0);
    // SAFETY: plain calls; MPI_Abort only while MPI runs.
    unsafe {
        ffi::MPI_Initialized(&mut mpi);
        ffi::MPI_Finalized(&mut ended);
        if mpi != 0 && ended == 0 {
            ffi::MPI_Abort(ffi::comm_world(), code);
        }
    }
}

/// The options a system starts from: [`AUGMENTED_LAGRANGIAN_OPTIONS`] for an augmented
/// Lagrangian's, [`DEFAULT_OPTIONS`] for any other.
fn defaults(augmented: bool) -> &'static str {
    if augmented {
        AUGMENTED_LAGRANGIAN_OPTIONS
    } else {
        DEFAULT_OPTIONS
    }
}

/// Sets PETSc's options database to `defaults` and then `options` (`-name value ...`,
/// overriding them), clearing what was there (the caller holds the lock).
fn set_options(defaults: &str, options: &str) -> Result<(), LinearSolveError> {
    let text =
        CString::new(format!("{defaults} {options}")).map_err(|_| LinearSolveError::Petsc(format!("options {options:?} contain a NUL byte")))?;
    // SAFETY: null is the global database; PETSc copies the string.
    unsafe {
        check(ffi::PetscOptionsClear(null_mut()), "PetscOptionsClear")?;
        check(ffi::PetscOptionsInsertString(null_mut(), text.as_ptr()), &format!("PetscOptionsInsertString({options:?})"))
    }
}

/// A [`LinearSolver`] by PETSc (see the module documentation). On several ranks, every rank
/// calls it alike with the same system: each call is collective.
pub struct PetscSolver {
    /// Options added after [`DEFAULT_OPTIONS`] (so they override them).
    options: String,
    /// Which unknowns are multipliers (the [`SaddlePointSplit`] of [`LinearSolver::set_split`]):
    /// the fields of a `fieldsplit` preconditioner ([`FIELDS`]).
    multipliers: Option<Vec<bool>>,
    /// The split's [`SaddlePointSplit::primal_components`].
    primal_components: usize,
    /// With [`PetscSolver::augmented_lagrangian`]: what transforms each system for the field
    /// split.
    al: Option<AugmentedLagrangian>,
    /// Relative residual `|b - A x| / |b|` above which a solve fails.
    fail_tolerance: f64,
    system: Option<PetscSystem>,
    symbolic: usize,
}

impl PetscSolver {
    /// A solver with PETSc `options` (`-fdfsi_...`, added after [`DEFAULT_OPTIONS`]) that fails
    /// a solve whose relative residual exceeds `fail_tolerance`.
    pub fn new(options: &str, fail_tolerance: f64) -> Self {
        PetscSolver { options: options.to_string(), multipliers: None, primal_components: 1, al: None, fail_tolerance, system: None, symbolic: 0 }
    }

    /// The augmented-Lagrangian preconditioner of `solve::augmented` (with `al`'s weight and
    /// placements) in PETSc: for each system with a split, FGMRES on `K y = b`, right-
    /// preconditioned by a shell that applies `T` and then the Schur field split of `T K`
    /// ([`crate::solve::augmented::TransformedSystem`]: fields [`FIELDS`], the primal unknowns
    /// with the multipliers kept primal and the multipliers of the Schur block, and the Schur
    /// block's matrix `S_p`), under [`AUGMENTED_LAGRANGIAN_OPTIONS`] and then `options`. A system
    /// without a split (a solid alone) is solved as by [`PetscSolver::new`] (MUMPS, then
    /// `options`).
    pub fn augmented_lagrangian(al: AlOptions, options: &str, fail_tolerance: f64) -> Self {
        PetscSolver { al: Some(AugmentedLagrangian::new(al)), ..Self::new(options, fail_tolerance) }
    }

    /// `x = K^-1 b` by `system`'s `KSP` under this solver's options, `b` this rank's rows and
    /// `x` all unknowns, both in PETSc's numbering; the Krylov iterations.
    fn petsc_solve(&self, system: &PetscSystem, b: &[f64], x: &mut [f64]) -> Result<usize, LinearSolveError> {
        let _petsc = lock();
        set_options(defaults(system.is_augmented()), &self.options)?;
        system.solve(b, x)
    }

    /// The nodes whose components PETSc's `fieldsplit` takes as the primal field's block size
    /// for a system of `n` unknowns with `fields` (the split's, or the augmented Lagrangian's):
    /// the nodes of the split's primal unknowns (`multipliers`, `primal_components`), where
    /// the fields' first is exactly those (the augmented Lagrangian's may hold multipliers kept
    /// primal too); every unknown on its own otherwise.
    fn block_nodes(multipliers: Option<&[bool]>, primal_components: usize, fields: Option<&[bool]>, n: usize) -> Nodes {
        let split = multipliers.map(|m| Nodes::of_split(m, n, primal_components));
        match fields.map(|m| Nodes::of_split(m, n, primal_components)) {
            Some(of_fields) if Some(of_fields) == split => of_fields,
            _ => Nodes::SCALAR,
        }
    }
}

impl PetscSolver {
    /// `x` from `b` by `solve(v, x)` (`x = K^-1 v`; its Krylov iterations), then refined while
    /// `relative_residual(x, r)` (`r = b - A x`, of `b`'s length, and `|r| / |b|`, the same on
    /// every rank) is above [`REFINE_ABOVE`] times the fail tolerance, at most
    /// [`MAX_REFINEMENTS`] times: the last relative residual, the refinements and the
    /// iterations.
    fn refined(
        &self,
        b: &[f64],
        x: &mut [f64],
        solve: impl Fn(&[f64], &mut [f64]) -> Result<usize, LinearSolveError>,
        relative_residual: impl Fn(&[f64], &mut [f64]) -> Result<f64, LinearSolveError>,
    ) -> Result<(f64, usize, usize), LinearSolveError> {
        let mut iterations = solve(b, x)?;
        let mut r = vec![0.0; b.len()];
        let mut residual = relative_residual(x, &mut r)?;
        let mut refinements = 0;
        while residual > REFINE_ABOVE * self.fail_tolerance && refinements < MAX_REFINEMENTS && residual.is_finite() {
            let mut correction = vec![0.0; x.len()];
            iterations += solve(&r, &mut correction)?;
            x.iter_mut().zip(&correction).for_each(|(x, d)| *x += d);
            residual = relative_residual(x, &mut r)?;
            refinements += 1;
        }
        Ok((residual, refinements, iterations))
    }

    /// The stats of a solve that ended at relative `residual` with the solution `x`, or why it
    /// failed (the ranks agree on both).
    fn accept(&self, residual: f64, refinements: usize, iterations: usize, x: &[f64]) -> Result<SolveStats, LinearSolveError> {
        if !residual.is_finite() || x.iter().any(|v| !v.is_finite()) {
            return Err(LinearSolveError::NonFinite);
        }
        if residual > self.fail_tolerance {
            return Err(LinearSolveError::Inaccurate { residual, refinements, tolerance: self.fail_tolerance });
        }
        Ok(SolveStats { residual, refinements, krylov_iterations: iterations })
    }
}

impl LinearSolver for PetscSolver {
    fn factorize(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
        let transformed = match self.al.as_mut() {
            Some(al) => al.transformed_system(a)?,
            None => None,
        };
        let (pattern, fields) = match &transformed {
            Some(t) => (t.pattern, Some(t.in_schur)),
            None => (a.pattern, self.multipliers.as_deref()),
        };
        let augmented = transformed.is_some();
        let nodes = Self::block_nodes(self.multipliers.as_deref(), self.primal_components, fields, pattern.n);
        if !self.system.as_ref().is_some_and(|s| s.is_for(pattern, fields, nodes, augmented)) {
            self.system = None;
            let _petsc = lock();
            let world = initialize()?;
            self.system = Some(PetscSystem::new(pattern, world, fields, nodes, augmented)?);
            self.symbolic += 1;
        }
        let system = self.system.as_mut().expect("set above");
        let _petsc = lock();
        set_options(defaults(augmented), &self.options)?;
        system.factorize(Values::Csc(&a.values), transformed.as_ref())
    }

    fn solve_in_place(&self, a: &CscMatrix<'_>, rhs: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        let system = self.system.as_ref().ok_or_else(|| LinearSolveError::Petsc("solve before factorize".into()))?;
        if rhs.len() != system.n() || a.pattern.n != system.n() {
            return Err(LinearSolveError::Petsc(format!(
                "a system of {} unknowns (right-hand side of {}) given to a solver set up for {}",
                a.pattern.n,
                rhs.len(),
                system.n()
            )));
        }
        let b = rhs.to_vec();
        let b_norm = match norm(&b) {
            0.0 => 1.0,
            b_norm => b_norm,
        };
        // `b - A x` (into `r`) relative to `|b|`, against the caller's matrix.
        // The largest over the ranks (each rank's `a` and `b` are its own copies), so that all
        // take the same branch: each refinement is a collective solve.
        let relative_residual = |x: &[f64], r: &mut [f64]| {
            a.mul_vec(x, r);
            r.iter_mut().zip(&b).for_each(|(ax, b)| *ax = b - *ax);
            let _petsc = lock();
            system.world.max(norm(r) / b_norm)
        };
        // `K^-1 v` into `x`, both in fdfsi's numbering.
        let numbering = &system.numbering;
        let solve = |v: &[f64], x: &mut [f64]| {
            let v_rows: Vec<f64> = system.rows().map(|p| v[numbering.to_fdfsi(p)]).collect();
            let mut x_petsc = vec![0.0; system.n];
            let iterations = self.petsc_solve(system, &v_rows, &mut x_petsc)?;
            x_petsc.into_iter().enumerate().for_each(|(p, value)| x[numbering.to_fdfsi(p)] = value);
            Ok::<_, LinearSolveError>(iterations)
        };
        let (residual, refinements, iterations) = self.refined(&b, rhs, solve, relative_residual)?;
        self.accept(residual, refinements, iterations, rhs)
    }

    fn symbolic_factorizations(&self) -> usize {
        self.symbolic
    }

    /// This solver for a partitioned assembly, on one rank or several, unless it runs the
    /// augmented Lagrangian (whose transformation needs the whole matrix) or PETSc does not start.
    fn as_row_solver(&mut self) -> Option<&mut dyn RowSolver> {
        if self.al.is_some() {
            return None;
        }
        world().ok()?;
        Some(self)
    }

    /// Keeps the split's multipliers for the fields of a `fieldsplit` preconditioner (a system
    /// set up with other fields is set up again at the next factorisation), and gives the split
    /// to the augmented Lagrangian, if any.
    fn set_split(&mut self, split: SaddlePointSplit) {
        let n = split.multipliers.iter().flat_map(|b| b.dofs.iter().map(|&d| d + 1)).max().unwrap_or(0);
        let mut multipliers = vec![false; n];
        for &d in split.multipliers.iter().flat_map(|b| &b.dofs) {
            multipliers[d] = true;
        }
        self.multipliers = Some(multipliers);
        self.primal_components = split.primal_components.max(1);
        if let Some(al) = self.al.as_mut() {
            al.set_split(split);
        }
    }
}

impl RowSolver for PetscSolver {
    /// The ranks, once PETSc runs (one rank where it cannot start: then every solve fails).
    fn world(&self) -> World {
        world().unwrap_or(World { rank: 0, size: 1 })
    }

    fn sum(&self, value: f64) -> Result<f64, LinearSolveError> {
        let _petsc = lock();
        initialize()?.sum(value)
    }

    /// Sets PETSc's system up from this rank's rows (again where their pattern, the split or the
    /// nodes changed on any rank) and loads `a` straight into its matrix.
    fn factorize_rows(&mut self, partition: &Partition, a: &RowMatrix<'_>) -> Result<(), LinearSolveError> {
        if self.al.is_some() {
            return Err(LinearSolveError::Petsc("the augmented Lagrangian needs the whole matrix, not a partitioned assembly's rows".into()));
        }
        let n = partition.n();
        let fields = self.multipliers.as_deref();
        // The block size where the partition kept the split's nodes whole.
        let nodes = match fields.map(|m| Nodes::of_split(m, n, self.primal_components)) {
            Some(nodes) if nodes == partition.nodes() => nodes,
            _ => Nodes::SCALAR,
        };
        let key = row_pattern_key(a.pattern);
        let current = self.system.as_ref().is_some_and(|s| s.is_for_rows(key, n, fields, nodes));
        let rebuild = {
            let _petsc = lock();
            let world = initialize()?;
            if world != partition.world() {
                // Every rank's own check, before collective calls.
                let message = format!("rows partitioned over {:?} given to PETSc on {world:?}", partition.world());
                return Err(end_ranks_on(LinearSolveError::Setup(message)));
            }
            world.max(f64::from(u8::from(!current)))? > 0.0
        };
        if rebuild {
            self.system = None;
            let _petsc = lock();
            self.system = Some(PetscSystem::from_rows(partition, a.pattern, key, fields, nodes)?);
            self.symbolic += 1;
        }
        let system = self.system.as_mut().expect("set above");
        let _petsc = lock();
        set_options(defaults(false), &self.options)?;
        system.factorize(Values::Rows(a), None)
    }

    /// Solves with PETSc and refines against `a` (each rank's rows of the residual, their norm
    /// summed over the ranks), then takes the whole solution to fdfsi's numbering.
    fn solve_rows(&self, _: &Partition, a: &RowMatrix<'_>, b: &[f64], x: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        let system = self.system.as_ref().ok_or_else(|| LinearSolveError::Petsc("solve before factorize".into()))?;
        if b.len() != system.rows().len() || x.len() != system.n || a.pattern.rows != system.rows() {
            // This rank's check, before collective calls.
            return Err(end_ranks_on(LinearSolveError::Setup(format!(
                "rows {:?} (right-hand side of {}, solution of {}) given to a solver set up for rows {:?} of {}",
                a.pattern.rows,
                b.len(),
                x.len(),
                system.rows(),
                system.n
            ))));
        }
        let norm = |v: &[f64]| -> Result<f64, LinearSolveError> { Ok(self.sum(v.iter().map(|x| x * x).sum())?.sqrt()) };
        let b_norm = match norm(b)? {
            0.0 => 1.0,
            b_norm => b_norm,
        };
        let relative_residual = |x: &[f64], r: &mut [f64]| {
            a.mul_rows(x, r);
            r.iter_mut().zip(b).for_each(|(ax, b)| *ax = b - *ax);
            Ok::<_, LinearSolveError>(norm(r)? / b_norm)
        };
        let mut x_petsc = vec![0.0; system.n];
        let solve = |v: &[f64], x: &mut [f64]| self.petsc_solve(system, v, x);
        let (residual, refinements, iterations) = self.refined(b, &mut x_petsc, solve, relative_residual)?;
        x_petsc.iter().enumerate().for_each(|(p, &value)| x[system.numbering.to_fdfsi(p)] = value);
        self.accept(residual, refinements, iterations, x)
    }
}

/// The values of a system's matrix, as a [`PetscSystem`] loads them.
enum Values<'a> {
    /// A whole matrix's, in its pattern's CSC order.
    Csc(&'a [f64]),
    /// This rank's rows of a partitioned assembly.
    Rows(&'a RowMatrix<'a>),
}

/// PETSc's objects for one pattern: the matrix (this rank's rows, [`Numbering::rows`], of the
/// AIJ matrix on `MPI_COMM_WORLD`: sequential on one rank, distributed on several, in PETSc's
/// [`Numbering`]), the right-hand side and solution vectors (their arrays placed for each
/// solve) and the `KSP`.
struct PetscSystem {
    /// The CSC pattern this was built for: its size, entries and key
    /// (`crate::solve::linear::pattern_key`; not a copy, which would cost as much as the matrix).
    n: usize,
    nnz: usize,
    key: u64,
    /// PETSc's numbering of the unknowns, and the nodes it keeps whole (the primal field's
    /// block size).
    numbering: Arc<Numbering>,
    nodes: Nodes,
    /// The CSR arrays of those rows (global column indices) and the CSC position of each entry
    /// (below the pattern's entry count, which fits a `PetscInt`); for a partitioned assembly's
    /// rows only `row_ptr` (the columns are the rows' own, [`Values::Rows`]).
    row_ptr: Vec<PetscInt>,
    col_idx: Vec<PetscInt>,
    csc_of_csr: Vec<PetscInt>,
    /// Whether the rows are a partitioned assembly's ([`PetscSystem::from_rows`]).
    partitioned: bool,
    world: World,
    /// Which unknowns are in the second of [`FIELDS`] (as given; none without a split), and this
    /// rank's rows of each field, given to the preconditioner at the first factorisation.
    field_mask: Option<Vec<bool>>,
    fields: Option<[Vec<PetscInt>; 2]>,
    fields_set: bool,
    handles: Handles,
    /// The shell preconditioner's context: a copy of `handles.shell` at a fixed address.
    shell_context: Box<Shell>,
}

/// PETSc's objects of a [`PetscSystem`]; with the augmented Lagrangian also `T K`, `T`, the
/// field split on `T K` and a work vector, which the `KSP`'s shell preconditioner
/// ([`apply_augmented_lagrangian`]) uses (null otherwise).
struct Handles {
    mat: ffi::Mat,
    b: ffi::Vec,
    x: ffi::Vec,
    ksp: ffi::Ksp,
    shell: Shell,
}

/// What the shell preconditioner [`apply_augmented_lagrangian`] applies: `z = U^-1 T r`.
#[derive(Clone, Copy)]
struct Shell {
    tk: ffi::Mat,
    t: ffi::Mat,
    inner: ffi::Pc,
    work: ffi::Vec,
}

impl Shell {
    const NONE: Shell = Shell { tk: null_mut(), t: null_mut(), inner: null_mut(), work: null_mut() };
}

impl Handles {
    const NONE: Handles = Handles { mat: null_mut(), b: null_mut(), x: null_mut(), ksp: null_mut(), shell: Shell::NONE };

    /// Destroys the objects (the caller holds the lock): the solvers first, the matrices last.
    fn destroy(&mut self) {
        // SAFETY: each handle is valid or null; PETSc's destroy calls accept null and set it.
        unsafe {
            ffi::KSPDestroy(&mut self.ksp);
            ffi::PCDestroy(&mut self.shell.inner);
            ffi::VecDestroy(&mut self.shell.work);
            ffi::MatDestroy(&mut self.shell.t);
            ffi::MatDestroy(&mut self.shell.tk);
            ffi::VecDestroy(&mut self.b);
            ffi::VecDestroy(&mut self.x);
            ffi::MatDestroy(&mut self.mat);
        }
    }
}

/// The options prefix of the augmented Lagrangian's field split (the shell's inner
/// preconditioner): `-fdfsi_al_pc_fieldsplit_type`, `-fdfsi_al_fieldsplit_primal_pc_type`, ...
pub const AL_OPTIONS_PREFIX: &str = "fdfsi_al_";

/// The shell preconditioner of [`PetscSolver::augmented_lagrangian`]: `y = U^-1 (T x)`, `T` by a
/// matrix product and `U^-1` by the field split on `T K` (PETSc calls this inside `KSPSolve`,
/// under the caller's lock; no panic can cross it).
extern "C" fn apply_augmented_lagrangian(pc: ffi::Pc, x: ffi::Vec, y: ffi::Vec) -> ffi::PetscErrorCode {
    let mut context: *mut std::ffi::c_void = null_mut();
    // SAFETY: the context is the `Shell` of a live `PetscSystem` (set with this callback, and
    // the system outlives its KSP); its handles are valid.
    unsafe {
        let code = ffi::PCShellGetContext(pc, (&mut context as *mut *mut std::ffi::c_void).cast());
        if code != 0 || context.is_null() {
            return if code != 0 { code } else { 1 };
        }
        let shell = *(context as *const Shell);
        let code = ffi::MatMult(shell.t, x, shell.work);
        if code != 0 {
            return code;
        }
        ffi::PCApply(shell.inner, shell.work, y)
    }
}

/// A new AIJ matrix on `MPI_COMM_WORLD` of `size` unknowns, this rank's `local` rows given in
/// CSR (global, increasing column indices), preallocated exactly and filled with `vals` (zeros
/// without; the caller holds the lock; collective).
fn create_aij(local: PetscInt, size: PetscInt, row_ptr: &[PetscInt], cols: &[PetscInt], vals: Option<&[f64]>) -> Result<ffi::Mat, LinearSolveError> {
    let aij = CString::new("aij").expect("no NUL");
    let mut mat = null_mut();
    // SAFETY: PETSc copies the CSR arrays; on failure the matrix is destroyed here.
    unsafe {
        let (r, c, v) = (row_ptr.as_ptr(), cols.as_ptr(), vals.map_or(null(), <[f64]>::as_ptr));
        let made = check(ffi::MatCreate(ffi::comm_world(), &mut mat), "MatCreate")
            .and_then(|_| check(ffi::MatSetSizes(mat, local, local, size, size), "MatSetSizes"))
            .and_then(|_| check(ffi::MatSetType(mat, aij.as_ptr()), "MatSetType"))
            .and_then(|_| check(ffi::MatSeqAIJSetPreallocationCSR(mat, r, c, v), "MatSeqAIJSetPreallocationCSR"))
            .and_then(|_| check(ffi::MatMPIAIJSetPreallocationCSR(mat, r, c, v), "MatMPIAIJSetPreallocationCSR"))
            .and_then(|_| check(ffi::MatSetOption(mat, ffi::MAT_NO_OFF_PROC_ENTRIES, 1), "MatSetOption"));
        if let Err(e) = made {
            ffi::MatDestroy(&mut mat);
            return Err(e);
        }
    }
    Ok(mat)
}

impl PetscSystem {
    /// The CSR copy of this rank's rows of `pattern` (in increasing column order, as PETSc
    /// requires), the matrix preallocated from it and the `KSP` on it, its options read at each
    /// factorisation (the caller holds the lock; collective over the ranks).
    fn new(pattern: &Pattern, world: World, multipliers: Option<&[bool]>, nodes: Nodes, augmented: bool) -> Result<Self, LinearSolveError> {
        let n = pattern.n;
        let too_big = || LinearSolveError::Petsc(format!("{n} unknowns with {} entries exceed PETSc's integer range", pattern.nnz()));
        let int = |v: usize| PetscInt::try_from(v).map_err(|_| too_big());
        int(n)?;
        int(pattern.nnz())?;
        let numbering = Numbering::new(pattern, world, nodes);
        let rows = numbering.rows(world.rank);
        let mut row_ptr = vec![0; rows.len() + 1];
        for p in pattern.row_idx.iter().map(|&i| numbering.to_petsc(i)).filter(|p| rows.contains(p)) {
            row_ptr[p - rows.start + 1] += 1;
        }
        for i in 0..rows.len() {
            row_ptr[i + 1] += row_ptr[i];
        }
        let mut next = row_ptr.clone();
        let nnz = row_ptr[rows.len()];
        let (mut col_idx, mut csc_of_csr) = (vec![0; nnz], vec![0; nnz]);
        // Columns in PETSc's order, so that each row's columns increase.
        for q in 0..n {
            let j = numbering.to_fdfsi(q);
            for k in pattern.col_ptr[j]..pattern.col_ptr[j + 1] {
                let p = numbering.to_petsc(pattern.row_idx[k]);
                if rows.contains(&p) {
                    let at = &mut next[p - rows.start];
                    csc_of_csr[*at] = k as PetscInt;
                    col_idx[*at] = int(q)?;
                    *at += 1;
                }
            }
        }
        let row_ptr = row_ptr.into_iter().map(int).collect::<Result<Vec<_>, _>>()?;
        let csr = Csr { row_ptr, col_idx, csc_of_csr };
        Self::create(Arc::new(numbering), world, nodes, (n, pattern.nnz(), pattern_key(pattern)), csr, None, multipliers, augmented)
    }

    /// The system of a partitioned assembly's rows on this rank (`pattern`, with `key`), in
    /// `partition`'s numbering, for the `multipliers`' fields (the primal one with `nodes`'
    /// block size; the caller holds the lock; collective over the ranks).
    fn from_rows(
        partition: &Partition,
        pattern: &RowPattern,
        key: u64,
        multipliers: Option<&[bool]>,
        nodes: Nodes,
    ) -> Result<Self, LinearSolveError> {
        let (n, nnz) = (partition.n(), pattern.nnz());
        // This rank's entries alone may not fit: its check ends every rank (the others would
        // wait in the creation of the matrix).
        let too_big = || end_ranks_on(LinearSolveError::Petsc(format!("{n} unknowns with {nnz} entries on this rank exceed PETSc's integer range")));
        let int = |v: usize| PetscInt::try_from(v).map_err(|_| too_big());
        int(n)?;
        let row_ptr = pattern.row_ptr.iter().map(|&k| int(k)).collect::<Result<Vec<_>, _>>()?;
        // The columns as PETSc's integers for the preallocation only (PETSc keeps its own copy).
        let cols: Vec<PetscInt> = pattern.cols.iter().map(|&j| j as PetscInt).collect();
        let csr = Csr { row_ptr, col_idx: Vec::new(), csc_of_csr: Vec::new() };
        Self::create(partition.shared_numbering(), partition.world(), nodes, (n, nnz, key), csr, Some(&cols), multipliers, false)
    }

    /// The system of this rank's rows in `csr` (columns `cols`, or `csr.col_idx`) of the
    /// `numbering` of `(n, nnz, key)` (its size, entries and pattern key) over `world`: the
    /// matrix preallocated, the vectors and the `KSP` (the caller holds the lock; collective).
    #[allow(clippy::too_many_arguments, reason = "the parts of a PetscSystem")]
    fn create(
        numbering: Arc<Numbering>,
        world: World,
        nodes: Nodes,
        (n, nnz, key): (usize, usize, u64),
        csr: Csr,
        cols: Option<&[PetscInt]>,
        multipliers: Option<&[bool]>,
        augmented: bool,
    ) -> Result<Self, LinearSolveError> {
        let rows = numbering.rows(world.rank);
        let (size, local) = (n as PetscInt, rows.len() as PetscInt);
        let fields = multipliers.map(|m| {
            let of = |multiplier: bool| {
                rows.clone().filter(|&p| m.get(numbering.to_fdfsi(p)).copied().unwrap_or(false) == multiplier).map(|p| p as PetscInt).collect()
            };
            [of(false), of(true)]
        });
        let partitioned = cols.is_some();
        let Csr { row_ptr, col_idx, csc_of_csr } = csr;
        let mut system = PetscSystem {
            n,
            nnz,
            key,
            numbering,
            nodes,
            row_ptr,
            col_idx,
            csc_of_csr,
            partitioned,
            world,
            field_mask: multipliers.map(<[bool]>::to_vec),
            fields,
            fields_set: false,
            handles: Handles::NONE,
            shell_context: Box::new(Shell::NONE),
        };
        let cols = cols.unwrap_or(&system.col_idx);
        let prefix = CString::new(OPTIONS_PREFIX).expect("no NUL");
        let al_prefix = CString::new(AL_OPTIONS_PREFIX).expect("no NUL");
        let s = &system;
        let mut h = Handles::NONE;
        // SAFETY: PETSc copies the CSR arrays; the handles start null; the vectors get their
        // arrays placed for each solve.
        let created = unsafe {
            let comm = ffi::comm_world();
            create_aij(local, size, &s.row_ptr, cols, None)
                .map(|m| h.mat = m)
                .and_then(|_| match augmented {
                    true => create_aij(local, size, &s.row_ptr, cols, None).map(|m| h.shell.tk = m),
                    false => Ok(()),
                })
                .and_then(|_| match augmented {
                    true => check(ffi::PCCreate(comm, &mut h.shell.inner), "PCCreate")
                        .and_then(|_| check(ffi::PCSetOptionsPrefix(h.shell.inner, al_prefix.as_ptr()), "PCSetOptionsPrefix"))
                        .and_then(|_| check(ffi::VecCreateMPI(comm, local, size, &mut h.shell.work), "VecCreateMPI")),
                    false => Ok(()),
                })
                .and_then(|_| check(ffi::VecCreateMPIWithArray(comm, 1, local, size, null(), &mut h.b), "VecCreateMPIWithArray"))
                .and_then(|_| check(ffi::VecCreateMPIWithArray(comm, 1, local, size, null(), &mut h.x), "VecCreateMPIWithArray"))
                .and_then(|_| check(ffi::KSPCreate(comm, &mut h.ksp), "KSPCreate"))
                .and_then(|_| check(ffi::KSPSetOptionsPrefix(h.ksp, prefix.as_ptr()), "KSPSetOptionsPrefix"))
                .and_then(|_| check(ffi::KSPSetOperators(h.ksp, h.mat, h.mat), "KSPSetOperators"))
        };
        match created {
            Ok(()) => {
                system.handles = h;
                Ok(system)
            }
            Err(e) => {
                // Destroyed here, under the caller's lock (`Drop` would take it again).
                h.destroy();
                Err(e)
            }
        }
    }

    fn is_for(&self, pattern: &Pattern, fields: Option<&[bool]>, nodes: Nodes, augmented: bool) -> bool {
        !self.partitioned
            && self.n == pattern.n
            && self.nodes == nodes
            && self.nnz == pattern.nnz()
            && self.key == pattern_key(pattern)
            && self.field_mask.as_deref() == fields
            && self.is_augmented() == augmented
    }

    /// Whether this is the system of a partitioned assembly's rows with pattern `key` of `n`
    /// unknowns, `fields` and `nodes`.
    fn is_for_rows(&self, key: u64, n: usize, fields: Option<&[bool]>, nodes: Nodes) -> bool {
        self.partitioned && self.key == key && self.n == n && self.nodes == nodes && self.field_mask.as_deref() == fields && !self.is_augmented()
    }

    /// Whether this is an augmented Lagrangian's system ([`PetscSolver::augmented_lagrangian`]).
    fn is_augmented(&self) -> bool {
        !self.handles.shell.tk.is_null()
    }

    /// Number of unknowns.
    fn n(&self) -> usize {
        self.n
    }

    /// This rank's rows (in PETSc's numbering).
    fn rows(&self) -> Range<usize> {
        self.numbering.rows(self.world.rank)
    }

    /// Copies this rank's rows of `values` into `mat` (the caller holds the lock; collective).
    fn load(&self, mat: ffi::Mat, values: Values<'_>) -> Result<(), LinearSolveError> {
        let (mut row_values, mut row_cols) = (Vec::new(), Vec::new());
        // SAFETY: the matrix is valid and was preallocated with exactly these rows and columns;
        // each row's slice of the CSR arrays lies within them.
        unsafe {
            for (i, row) in self.rows().enumerate() {
                let (start, end) = (self.row_ptr[i] as usize, self.row_ptr[i + 1] as usize);
                let (cols, vals) = match values {
                    Values::Csc(values) => {
                        row_values.clear();
                        row_values.extend(self.csc_of_csr[start..end].iter().map(|&k| values[k as usize]));
                        (&self.col_idx[start..end], &row_values[..])
                    }
                    Values::Rows(a) => {
                        row_cols.clear();
                        row_cols.extend(a.pattern.cols[start..end].iter().map(|&j| j as PetscInt));
                        (&row_cols[..], &a.values[start..end])
                    }
                };
                let row = row as PetscInt;
                check(ffi::MatSetValues(mat, 1, &row, (end - start) as PetscInt, cols.as_ptr(), vals.as_ptr(), ffi::INSERT_VALUES), "MatSetValues")?;
            }
            check(ffi::MatAssemblyBegin(mat, ffi::MAT_FINAL_ASSEMBLY), "MatAssemblyBegin")?;
            check(ffi::MatAssemblyEnd(mat, ffi::MAT_FINAL_ASSEMBLY), "MatAssemblyEnd")
        }
    }

    /// Copies this rank's rows of `values` (in CSC order) into the matrix and sets the `KSP` up
    /// from the options database: for the default options, MUMPS's factorisation. With `al`
    /// (the augmented Lagrangian's transformed system, on this system's pattern), `values` are
    /// ignored: the matrix is `K`, and its preconditioner a shell ([`apply_augmented_lagrangian`])
    /// around the field split of `T K`, whose Schur complement is preconditioned by the
    /// block-diagonal `S_p` (the caller holds the lock and has set the solver's options;
    /// collective).
    fn factorize(&mut self, values: Values<'_>, al: Option<&TransformedSystem<'_>>) -> Result<(), LinearSolveError> {
        let (mat, tk, ksp) = (self.handles.mat, self.handles.shell.tk, self.handles.ksp);
        self.load(mat, al.map_or(values, |t| Values::Csc(&t.k_values)))?;
        let (mut pc, mut failed) = (null_mut(), 0);
        let shell_type = CString::new("shell").expect("no NUL");
        // SAFETY: the handles are valid (`tk` and the shell's with `al` only); the shell's
        // context is boxed in `self`, which outlives the KSP.
        unsafe {
            check(ffi::KSPSetOperators(ksp, mat, mat), "KSPSetOperators")?;
            check(ffi::KSPSetFromOptions(ksp), "KSPSetFromOptions")?;
            check(ffi::KSPGetPC(ksp, &mut pc), "KSPGetPC")?;
            let split = match al {
                Some(t) => {
                    self.load(tk, Values::Csc(&t.values))?;
                    let mut transform = self.transform_matrix(&t.transform)?;
                    std::mem::swap(&mut self.handles.shell.t, &mut transform);
                    ffi::MatDestroy(&mut transform);
                    *self.shell_context = self.handles.shell;
                    check(ffi::PCSetType(pc, shell_type.as_ptr()), "PCSetType")?;
                    check(ffi::PCShellSetApply(pc, apply_augmented_lagrangian), "PCShellSetApply")?;
                    check(ffi::PCShellSetContext(pc, (&mut *self.shell_context as *mut Shell).cast()), "PCShellSetContext")?;
                    let inner = self.handles.shell.inner;
                    check(ffi::PCSetOperators(inner, tk, tk), "PCSetOperators")?;
                    check(ffi::PCSetFromOptions(inner), "PCSetFromOptions")?;
                    inner
                }
                None => pc,
            };
            if !self.fields_set {
                if let Some(fields) = &self.fields {
                    set_fields(split, fields, self.nodes.size)?;
                }
                self.fields_set = true;
            }
            if let Some(t) = al {
                let mut sp = self.schur_matrix(&t.schur_blocks)?;
                let set = check(ffi::PCFieldSplitSetSchurPre(split, ffi::PC_FIELDSPLIT_SCHUR_PRE_USER, sp), "PCFieldSplitSetSchurPre");
                ffi::MatDestroy(&mut sp);
                set?;
                check(ffi::PCSetUp(split), "PCSetUp (the augmented Lagrangian's field split)")?;
                check(ffi::PCSetUpOnBlocks(split), "PCSetUpOnBlocks (the factorisation of the augmented block)")?;
            }
            check(ffi::KSPSetUp(ksp), "KSPSetUp (the factorisation)")?;
            check(ffi::PCGetFailedReason(split, &mut failed), "PCGetFailedReason")?;
        }
        // A failure on one rank fails every rank (else their Newton solves would part and wait
        // for each other); the reason reported is this rank's (0 where another rank failed;
        // PETSc's reasons include -1, so the ranks agree on whether any failed, not on a
        // largest reason).
        if self.world.max(f64::from(u8::from(failed != 0)))? != 0.0 {
            return Err(LinearSolveError::Numeric(format!(
                "PETSc's preconditioner set-up failed (PCFailedReason {failed}; for the default MUMPS LU: a singular matrix)"
            )));
        }
        Ok(())
    }

    /// `T = I + (T - I)` from the entries of `T - I` (`(row, column, value)`), this rank's rows
    /// (the caller holds the lock and destroys it; collective).
    fn transform_matrix(&self, off_diagonal: &[(usize, usize, f64)]) -> Result<ffi::Mat, LinearSolveError> {
        let (to_petsc, rows) = (|i| self.numbering.to_petsc(i), self.rows());
        let mut entries: Vec<(usize, usize, f64)> =
            off_diagonal.iter().map(|&(i, j, v)| (to_petsc(i), to_petsc(j), v)).filter(|(p, _, _)| rows.contains(p)).collect();
        entries.extend(rows.clone().map(|i| (i, i, 1.0)));
        entries.sort_unstable_by_key(|&(i, j, _)| (i, j));
        let mut row_ptr: Vec<PetscInt> = vec![0; rows.len() + 1];
        let (mut cols, mut vals): (Vec<PetscInt>, Vec<f64>) = (Vec::with_capacity(entries.len()), Vec::with_capacity(entries.len()));
        let mut last = None;
        for (i, j, v) in entries {
            if last == Some((i, j)) {
                *vals.last_mut().expect("an entry before") += v;
                continue;
            }
            last = Some((i, j));
            cols.push(j as PetscInt);
            vals.push(v);
            row_ptr[i - rows.start + 1] = cols.len() as PetscInt;
        }
        for k in 1..row_ptr.len() {
            row_ptr[k] = row_ptr[k].max(row_ptr[k - 1]);
        }
        create_aij(rows.len() as PetscInt, self.n() as PetscInt, &row_ptr, &cols, Some(&vals))
    }

    /// Solves for `x_petsc` (all of it on every rank) with right-hand side `b` (this rank's
    /// rows; PETSc gets a copy, which it may scale: `-ksp_diagonal_scale`), both in PETSc's
    /// numbering; returns PETSc's iteration count (the caller holds the lock; collective).
    fn solve(&self, b: &[f64], x_petsc: &mut [f64]) -> Result<usize, LinearSolveError> {
        let (mut iterations, mut reason): (PetscInt, c_int) = (0, 0);
        let h = &self.handles;
        let lo = self.rows().start;
        let mut b_petsc = b.to_vec();
        // SAFETY: `b_petsc` holds this rank's rows and `x_petsc` all, both outlive the solve;
        // whatever was placed is reset to no array before returning.
        unsafe {
            check(ffi::VecPlaceArray(h.b, b_petsc.as_mut_ptr()), "VecPlaceArray")?;
            if let Err(e) = check(ffi::VecPlaceArray(h.x, x_petsc.as_mut_ptr().add(lo)), "VecPlaceArray") {
                ffi::VecResetArray(h.b);
                return Err(e);
            }
            let solved = check(ffi::KSPSolve(h.ksp, h.b, h.x), "KSPSolve");
            let reset = [ffi::VecResetArray(h.b), ffi::VecResetArray(h.x)];
            solved?;
            reset.iter().try_for_each(|&code| check(code, "VecResetArray"))?;
            check(ffi::KSPGetIterationNumber(h.ksp, &mut iterations), "KSPGetIterationNumber")?;
            check(ffi::KSPGetConvergedReason(h.ksp, &mut reason), "KSPGetConvergedReason")?;
        }
        if reason < 0 {
            return Err(LinearSolveError::Petsc(format!(
                "KSPSolve diverged (KSPConvergedReason {reason}, after {iterations} iterations; -{OPTIONS_PREFIX}ksp_converged_reason tells more)"
            )));
        }
        self.world.all_gather(&self.numbering, x_petsc)?;
        Ok(if reason == ffi::KSP_CONVERGED_ITS { 0 } else { iterations as usize })
    }

    /// The block-diagonal matrix of `blocks` (unknowns of the second field, increasing, and
    /// their dense blocks, row-major) in the second field's numbering, this rank's rows (the
    /// caller holds the lock and destroys it; collective).
    fn schur_matrix(&self, blocks: &[(Vec<usize>, Vec<f64>)]) -> Result<ffi::Mat, LinearSolveError> {
        let owned = self.fields.as_ref().map_or(&[][..], |f| &f[1][..]);
        // Each unknown's index in the second field: its rank's rows after the lower ranks'.
        let mut total = 0;
        let second_index: Vec<PetscInt> = (0..self.n())
            .map(|p| match self.field_mask.as_ref().and_then(|m| m.get(self.numbering.to_fdfsi(p))) {
                Some(true) => {
                    total += 1;
                    total - 1
                }
                _ => -1,
            })
            .collect();
        // This rank's rows: (PETSc's index, block, row in it), by index.
        let (to_petsc, owned_rows) = (|d| self.numbering.to_petsc(d), self.rows());
        let mut rows: Vec<(usize, usize, usize)> = blocks
            .iter()
            .enumerate()
            .flat_map(|(b, (dofs, _))| dofs.iter().enumerate().map(move |(r, &d)| (to_petsc(d), b, r)))
            .filter(|(p, _, _)| owned_rows.contains(p))
            .collect();
        rows.sort_unstable();
        if rows.len() != owned.len() || rows.iter().zip(owned).any(|(r, &o)| r.0 as PetscInt != o) {
            // This rank's check, before the collective creation of the matrix.
            return Err(end_ranks_on(LinearSolveError::Petsc("the Schur blocks do not cover the second field's unknowns once each".into())));
        }
        let mut row_ptr: Vec<PetscInt> = vec![0];
        let (mut cols, mut vals) = (Vec::new(), Vec::new());
        for &(_, b, r) in &rows {
            let (dofs, block) = &blocks[b];
            let m = dofs.len();
            let mut row: Vec<(PetscInt, f64)> = dofs.iter().zip(&block[r * m..(r + 1) * m]).map(|(&d, &v)| (second_index[to_petsc(d)], v)).collect();
            row.sort_unstable_by_key(|&(c, _)| c);
            cols.extend(row.iter().map(|&(c, _)| c));
            vals.extend(row.iter().map(|&(_, v)| v));
            row_ptr.push(cols.len() as PetscInt);
        }
        create_aij(owned.len() as PetscInt, total, &row_ptr, &cols, Some(&vals))
    }
}

/// Gives a `fieldsplit` preconditioner `pc` the fields [`FIELDS`] (this rank's rows of each,
/// the first in whole nodes of `node_size`, its block size; a no-op for another preconditioner;
/// the caller holds the lock; collective).
fn set_fields(pc: ffi::Pc, fields: &[Vec<PetscInt>; 2], node_size: usize) -> Result<(), LinearSolveError> {
    for ((name, rows), block_size) in FIELDS.iter().zip(fields).zip([node_size, 1]) {
        let name = CString::new(*name).expect("no NUL");
        let mut is = null_mut();
        // SAFETY: PETSc copies the indices (PETSC_COPY_VALUES) and keeps its own reference to
        // the index set, so ours is destroyed here.
        unsafe {
            check(
                ffi::ISCreateGeneral(ffi::comm_world(), rows.len() as PetscInt, rows.as_ptr(), ffi::PETSC_COPY_VALUES, &mut is),
                "ISCreateGeneral",
            )?;
            let set = check(ffi::ISSetBlockSize(is, block_size as PetscInt), "ISSetBlockSize")
                .and_then(|_| check(ffi::PCFieldSplitSetIS(pc, name.as_ptr(), is), "PCFieldSplitSetIS"));
            ffi::ISDestroy(&mut is);
            set?;
        }
    }
    Ok(())
}

/// The CSR arrays of a [`PetscSystem`].
struct Csr {
    row_ptr: Vec<PetscInt>,
    col_idx: Vec<PetscInt>,
    csc_of_csr: Vec<PetscInt>,
}

impl Drop for PetscSystem {
    fn drop(&mut self) {
        let h = &self.handles;
        if [h.mat, h.b, h.x, h.ksp].iter().all(|p| p.is_null()) {
            return;
        }
        let _petsc = lock();
        self.handles.destroy();
    }
}
