//! Linear solves through the system's PETSc (cargo feature `petsc`; Debian: `apt install
//! petsc-dev`): the first piece of the MPI + PETSc engine. [`PetscSolver`] hands each system to
//! a PETSc `KSP` (`MatCreateSeqAIJWithArrays` over a CSR copy of the pattern, values copied in
//! at every factorisation), configured through PETSc's options database under the prefix
//! [`OPTIONS_PREFIX`]: by default a direct solve by MUMPS ([`DEFAULT_OPTIONS`]), anything else
//! by options, as FEniCSx users are used to (`-fdfsi_ksp_type gmres -fdfsi_pc_type ilu`,
//! `-fdfsi_mat_mumps_icntl_14 50`, `-fdfsi_ksp_view`). Sequential matrices on `MPI_COMM_SELF`:
//! the distributed engine (several ranks, `mpirun`) is still to come.
//!
//! PETSc is initialised on first use and not finalised (its state lives as long as the
//! process): MPI first at the thread level `MPI_THREAD_SERIALIZED` (solvers on several threads
//! take turns), then PETSc without its signal handlers (`-no_signal_handler`: Rust's own stay).
//! PETSc is not thread-safe: every call into it holds one process-wide lock. Its options
//! database is process-wide too: every locked section that lets PETSc read options (set-up,
//! factorisation, solve) first clears it and sets its solver's options ([`DEFAULT_OPTIONS`],
//! then its own), so each `KSP` sees exactly its solver's options (and none from
//! `PETSC_OPTIONS` or `.petscrc`).

mod ffi;

use super::linear::{norm, LinearSolveError, LinearSolver, SolveStats};
use fdfsi_fem::sparse::{CscMatrix, Pattern};
use ffi::PetscInt;
use std::ffi::{c_int, CStr, CString};
use std::ptr::{null, null_mut};
use std::sync::{Mutex, MutexGuard, OnceLock};

/// The options prefix of fdfsi's `KSP`: `-fdfsi_ksp_type`, `-fdfsi_pc_type`, ...
pub const OPTIONS_PREFIX: &str = "fdfsi_";

/// The options [`PetscSolver`] starts from: a direct solve (`preonly` with an LU
/// preconditioner) by MUMPS, which pivots, as the saddle-point systems need.
pub const DEFAULT_OPTIONS: &str = "-fdfsi_ksp_type preonly -fdfsi_pc_type lu -fdfsi_pc_factor_mat_solver_type mumps";

/// Every call into PETSc holds this.
static PETSC: Mutex<()> = Mutex::new(());

fn lock() -> MutexGuard<'static, ()> {
    PETSC.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// `Err` with PETSc's message for a nonzero error `code` of `call`.
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
    Err(LinearSolveError::Petsc(format!("{call}: {message} (PETSc error {code})")))
}

/// Initialises PETSc once per process (the caller holds the lock).
fn initialize() -> Result<(), LinearSolveError> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        let (mut mpi, mut provided, mut petsc): (c_int, c_int, ffi::PetscBool) = (0, 0, 0);
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
        }
        Ok(())
    })
    .clone()
    .map_err(LinearSolveError::Petsc)
}

/// Sets PETSc's options database to [`DEFAULT_OPTIONS`] and then `options` (`-name value
/// ...`, overriding them), clearing what was there (the caller holds the lock).
fn set_options(options: &str) -> Result<(), LinearSolveError> {
    let text = CString::new(format!("{DEFAULT_OPTIONS} {options}"))
        .map_err(|_| LinearSolveError::Petsc(format!("options {options:?} contain a NUL byte")))?;
    // SAFETY: null is the global database; PETSc copies the string.
    unsafe {
        check(ffi::PetscOptionsClear(null_mut()), "PetscOptionsClear")?;
        check(ffi::PetscOptionsInsertString(null_mut(), text.as_ptr()), &format!("PetscOptionsInsertString({options:?})"))
    }
}

/// A [`LinearSolver`] by PETSc (see the module documentation).
pub struct PetscSolver {
    /// Options added after [`DEFAULT_OPTIONS`] (so they override them).
    options: String,
    /// Relative residual `|b - A x| / |b|` above which a solve fails.
    fail_tolerance: f64,
    system: Option<PetscSystem>,
    symbolic: usize,
}

impl PetscSolver {
    /// A solver with PETSc `options` (`-fdfsi_...`, added after [`DEFAULT_OPTIONS`]) that fails
    /// a solve whose relative residual exceeds `fail_tolerance`.
    pub fn new(options: &str, fail_tolerance: f64) -> Self {
        PetscSolver { options: options.to_string(), fail_tolerance, system: None, symbolic: 0 }
    }
}

impl LinearSolver for PetscSolver {
    fn factorize(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
        if !self.system.as_ref().is_some_and(|s| s.is_for(a.pattern)) {
            self.system = None;
            let _petsc = lock();
            initialize()?;
            self.system = Some(PetscSystem::new(a.pattern)?);
            self.symbolic += 1;
        }
        let system = self.system.as_mut().expect("set above");
        let _petsc = lock();
        set_options(&self.options)?;
        system.factorize(&a.values)
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
        let iterations = {
            let _petsc = lock();
            set_options(&self.options)?;
            // PETSc may scale its right-hand side in place (`-ksp_diagonal_scale`): its own copy.
            system.solve(&mut b.clone(), rhs)?
        };
        let mut r = vec![0.0; b.len()];
        a.mul_vec(rhs, &mut r);
        r.iter_mut().zip(&b).for_each(|(ax, b)| *ax = b - *ax);
        let b_norm = norm(&b);
        let residual = norm(&r) / if b_norm > 0.0 { b_norm } else { 1.0 };
        if !residual.is_finite() || rhs.iter().any(|x| !x.is_finite()) {
            return Err(LinearSolveError::NonFinite);
        }
        if residual > self.fail_tolerance {
            return Err(LinearSolveError::Inaccurate { residual, refinements: 0, tolerance: self.fail_tolerance });
        }
        Ok(SolveStats { residual, refinements: 0, krylov_iterations: iterations })
    }

    fn symbolic_factorizations(&self) -> usize {
        self.symbolic
    }
}

/// PETSc's objects for one pattern: the matrix over CSR arrays of ours (PETSc uses them in
/// place, so they live as long as it), the right-hand side and solution vectors (placed over
/// the caller's arrays for each solve) and the `KSP`.
struct PetscSystem {
    /// The CSC pattern this was built for.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Position in the CSR arrays of each CSC entry.
    csr_of_csc: Vec<usize>,
    row_ptr: Vec<PetscInt>,
    col_idx: Vec<PetscInt>,
    values: Vec<f64>,
    handles: Handles,
}

/// PETSc's objects of a [`PetscSystem`].
struct Handles {
    mat: ffi::Mat,
    b: ffi::Vec,
    x: ffi::Vec,
    ksp: ffi::Ksp,
}

impl Handles {
    /// Destroys the objects (the caller holds the lock): the solver first, the matrix (over the
    /// system's arrays) last.
    fn destroy(&mut self) {
        // SAFETY: each handle is valid or null; PETSc's destroy calls accept null and set it.
        unsafe {
            ffi::KSPDestroy(&mut self.ksp);
            ffi::VecDestroy(&mut self.b);
            ffi::VecDestroy(&mut self.x);
            ffi::MatDestroy(&mut self.mat);
        }
    }
}

impl PetscSystem {
    /// The CSR copy of `pattern` (rows in increasing column order, as PETSc requires), the
    /// matrix over it and the `KSP` on it, its options read at each factorisation (the caller
    /// holds the lock).
    fn new(pattern: &Pattern) -> Result<Self, LinearSolveError> {
        let n = pattern.n;
        let too_big = || LinearSolveError::Petsc(format!("{n} unknowns with {} entries exceed PETSc's integer range", pattern.nnz()));
        let int = |v: usize| PetscInt::try_from(v).map_err(|_| too_big());
        let size = int(n)?;
        int(pattern.nnz())?;
        let mut row_ptr = vec![0; n + 1];
        for &i in &pattern.row_idx {
            row_ptr[i + 1] += 1;
        }
        for i in 0..n {
            row_ptr[i + 1] += row_ptr[i];
        }
        let mut next = row_ptr.clone();
        let mut col_idx = vec![0; pattern.nnz()];
        let mut csr_of_csc = vec![0; pattern.nnz()];
        for j in 0..n {
            for k in pattern.col_ptr[j]..pattern.col_ptr[j + 1] {
                let i = pattern.row_idx[k];
                csr_of_csc[k] = next[i];
                col_idx[next[i]] = int(j)?;
                next[i] += 1;
            }
        }
        let row_ptr = row_ptr.into_iter().map(int).collect::<Result<Vec<_>, _>>()?;
        let mut system = PetscSystem {
            col_ptr: pattern.col_ptr.clone(),
            row_idx: pattern.row_idx.clone(),
            csr_of_csc,
            row_ptr,
            col_idx,
            values: vec![0.0; pattern.nnz()],
            handles: Handles { mat: null_mut(), b: null_mut(), x: null_mut(), ksp: null_mut() },
        };
        let n = size;
        let prefix = CString::new(OPTIONS_PREFIX).expect("no NUL");
        let h = &mut system.handles;
        // SAFETY: the arrays handed to PETSc live in `system` (their heap buffers do not move)
        // until the objects that use them are destroyed; the handles start null.
        let created = unsafe {
            let comm = ffi::comm_self();
            let (rows, cols, vals) = (system.row_ptr.as_mut_ptr(), system.col_idx.as_mut_ptr(), system.values.as_mut_ptr());
            check(ffi::MatCreateSeqAIJWithArrays(comm, n, n, rows, cols, vals, &mut h.mat), "MatCreateSeqAIJWithArrays")
                .and_then(|_| check(ffi::VecCreateSeqWithArray(comm, 1, n, null(), &mut h.b), "VecCreateSeqWithArray"))
                .and_then(|_| check(ffi::VecCreateSeqWithArray(comm, 1, n, null(), &mut h.x), "VecCreateSeqWithArray"))
                .and_then(|_| check(ffi::KSPCreate(comm, &mut h.ksp), "KSPCreate"))
                .and_then(|_| check(ffi::KSPSetOptionsPrefix(h.ksp, prefix.as_ptr()), "KSPSetOptionsPrefix"))
                .and_then(|_| check(ffi::KSPSetOperators(h.ksp, h.mat, h.mat), "KSPSetOperators"))
        };
        match created {
            Ok(()) => Ok(system),
            Err(e) => {
                // Destroyed here, under the caller's lock (`Drop` would take it again); the
                // arrays are freed, the emptied system forgotten.
                system.handles.destroy();
                let arrays = std::mem::take(&mut system.row_ptr);
                let indices = std::mem::take(&mut system.col_idx);
                let values = std::mem::take(&mut system.values);
                let maps = [std::mem::take(&mut system.col_ptr), std::mem::take(&mut system.row_idx), std::mem::take(&mut system.csr_of_csc)];
                std::mem::forget(system);
                drop((arrays, indices, values, maps));
                Err(e)
            }
        }
    }

    fn is_for(&self, pattern: &Pattern) -> bool {
        self.col_ptr == pattern.col_ptr && self.row_idx == pattern.row_idx
    }

    /// Number of unknowns.
    fn n(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Copies `values` (in CSC order) into the matrix and sets the `KSP` up from the options
    /// database: for the default options, MUMPS's factorisation (the caller holds the lock and
    /// has set the solver's options).
    fn factorize(&mut self, values: &[f64]) -> Result<(), LinearSolveError> {
        for (&v, &at) in values.iter().zip(&self.csr_of_csc) {
            self.values[at] = v;
        }
        let (mut array, mut pc, mut failed) = (null_mut(), null_mut(), 0);
        // SAFETY: the matrix is valid; getting and restoring its array (ours) marks its values
        // changed, so the set-up factorises again.
        let h = &self.handles;
        unsafe {
            check(ffi::MatSeqAIJGetArray(h.mat, &mut array), "MatSeqAIJGetArray")?;
            check(ffi::MatSeqAIJRestoreArray(h.mat, &mut array), "MatSeqAIJRestoreArray")?;
            check(ffi::KSPSetOperators(h.ksp, h.mat, h.mat), "KSPSetOperators")?;
            check(ffi::KSPSetFromOptions(h.ksp), "KSPSetFromOptions")?;
            check(ffi::KSPSetUp(h.ksp), "KSPSetUp (the factorisation)")?;
            check(ffi::KSPGetPC(h.ksp, &mut pc), "KSPGetPC")?;
            check(ffi::PCGetFailedReason(pc, &mut failed), "PCGetFailedReason")?;
        }
        if failed != 0 {
            return Err(LinearSolveError::Numeric(format!(
                "PETSc's preconditioner set-up failed (PCFailedReason {failed}; for the default MUMPS LU: a singular matrix)"
            )));
        }
        Ok(())
    }

    /// Solves for `x` with right-hand side `b`; returns PETSc's iteration count (the caller holds
    /// the lock).
    fn solve(&self, b: &mut [f64], x: &mut [f64]) -> Result<usize, LinearSolveError> {
        let (mut iterations, mut reason): (PetscInt, c_int) = (0, 0);
        // SAFETY: `b` and `x` have the system's size (checked by the caller) and outlive the
        // solve; whatever was placed is reset to no array before returning.
        let h = &self.handles;
        unsafe {
            check(ffi::VecPlaceArray(h.b, b.as_mut_ptr()), "VecPlaceArray")?;
            if let Err(e) = check(ffi::VecPlaceArray(h.x, x.as_mut_ptr()), "VecPlaceArray") {
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
        Ok(if reason == ffi::KSP_CONVERGED_ITS { 0 } else { iterations as usize })
    }
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
