//! The few PETSc calls [`super::PetscSolver`] makes, declared by hand (PETSc 3.18's
//! `petscsys.h`, `petscmat.h`, `petscvec.h`, `petscksp.h`): a thin FFI of our own rather than a
//! generated binding of the whole library, which would need libclang at build time. Everything
//! else (solver types, tolerances, MUMPS settings) goes through PETSc's options database.
//!
//! Types: `PetscInt` is 32-bit unless PETSc was built with 64-bit indices (`cfg(petsc_int64)`,
//! set by `build.rs`); `PetscScalar` is `f64` (a real build: `build.rs` refuses a complex one);
//! `MPI_Comm` is Open MPI's, a pointer (`build.rs` checks PETSc was built on Open MPI).

use std::ffi::{c_char, c_int, c_void};

#[cfg(not(petsc_int64))]
pub type PetscInt = i32;
#[cfg(petsc_int64)]
pub type PetscInt = i64;
pub type PetscErrorCode = c_int;
/// `PetscBool`: a C enum, `PETSC_FALSE = 0`, `PETSC_TRUE = 1`.
pub type PetscBool = c_int;
/// Open MPI's `MPI_Comm` (`struct ompi_communicator_t *`).
pub type MpiComm = *mut c_void;

/// Opaque handles (pointers to PETSc's structs).
pub type Mat = *mut c_void;
pub type Vec = *mut c_void;
pub type Ksp = *mut c_void;

/// `KSP_CONVERGED_ITS`: `preonly` (a direct solve) reports this after its one application.
pub const KSP_CONVERGED_ITS: c_int = 4;

#[link(name = "petsc_real")]
extern "C" {
    pub static PETSC_COMM_WORLD: MpiComm;

    pub fn PetscInitializeNoArguments() -> PetscErrorCode;
    pub fn PetscInitialized(done: *mut PetscBool) -> PetscErrorCode;
    pub fn PetscErrorMessage(code: c_int, text: *mut *const c_char, specific: *mut *mut c_char) -> PetscErrorCode;
    /// `options` null: the global database.
    pub fn PetscOptionsInsertString(options: *mut c_void, text: *const c_char) -> PetscErrorCode;
    pub fn PetscOptionsClear(options: *mut c_void) -> PetscErrorCode;

    pub fn MatCreateSeqAIJWithArrays(
        comm: MpiComm,
        rows: PetscInt,
        cols: PetscInt,
        row_ptr: *mut PetscInt,
        col_idx: *mut PetscInt,
        values: *mut f64,
        mat: *mut Mat,
    ) -> PetscErrorCode;
    pub fn MatSeqAIJGetArray(mat: Mat, values: *mut *mut f64) -> PetscErrorCode;
    pub fn MatSeqAIJRestoreArray(mat: Mat, values: *mut *mut f64) -> PetscErrorCode;
    pub fn MatDestroy(mat: *mut Mat) -> PetscErrorCode;

    pub fn VecCreateSeqWithArray(comm: MpiComm, block_size: PetscInt, n: PetscInt, values: *const f64, vec: *mut Vec) -> PetscErrorCode;
    pub fn VecPlaceArray(vec: Vec, values: *const f64) -> PetscErrorCode;
    pub fn VecResetArray(vec: Vec) -> PetscErrorCode;
    pub fn VecDestroy(vec: *mut Vec) -> PetscErrorCode;

    pub fn KSPCreate(comm: MpiComm, ksp: *mut Ksp) -> PetscErrorCode;
    pub fn KSPSetOptionsPrefix(ksp: Ksp, prefix: *const c_char) -> PetscErrorCode;
    pub fn KSPSetOperators(ksp: Ksp, a: Mat, p: Mat) -> PetscErrorCode;
    pub fn KSPSetFromOptions(ksp: Ksp) -> PetscErrorCode;
    pub fn KSPSetUp(ksp: Ksp) -> PetscErrorCode;
    pub fn KSPSolve(ksp: Ksp, b: Vec, x: Vec) -> PetscErrorCode;
    pub fn KSPGetIterationNumber(ksp: Ksp, iterations: *mut PetscInt) -> PetscErrorCode;
    pub fn KSPGetConvergedReason(ksp: Ksp, reason: *mut c_int) -> PetscErrorCode;
    pub fn KSPDestroy(ksp: *mut Ksp) -> PetscErrorCode;
}
