//! The few PETSc calls [`super::PetscSolver`] makes, declared by hand (PETSc 3.18's
//! `petscsys.h`, `petscmat.h`, `petscvec.h`, `petscksp.h`): a thin FFI of our own rather than a
//! generated binding of the whole library, which would need libclang at build time. Everything
//! else (solver types, tolerances, MUMPS settings) goes through PETSc's options database.
//!
//! Types: `PetscInt` is 32-bit unless PETSc was built with 64-bit indices (`cfg(petsc_int64)`,
//! set by `build.rs`); `PetscScalar` is `f64` (a real build: `build.rs` refuses a complex one);
//! `MPI_Comm` is Open MPI's, a pointer (`build.rs` checks PETSc was built on Open MPI, and links
//! Open MPI for the two calls of its own made here: the thread level and `MPI_COMM_SELF`).

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

pub type Pc = *mut c_void;

/// `KSP_CONVERGED_ITS`: `preonly` (a direct solve) reports this after its one application.
pub const KSP_CONVERGED_ITS: c_int = 4;
/// Open MPI's `MPI_THREAD_SERIALIZED` (`mpi.h`: `SINGLE, FUNNELED, SERIALIZED, MULTIPLE`).
pub const MPI_THREAD_SERIALIZED: c_int = 2;

/// Open MPI's predefined communicator objects (`struct ompi_predefined_communicator_t`, opaque
/// here): `MPI_COMM_SELF` is the address of `ompi_mpi_comm_self`.
#[repr(C)]
pub struct OmpiCommunicator {
    _private: [u8; 0],
}

extern "C" {
    static ompi_mpi_comm_self: OmpiCommunicator;
    pub fn MPI_Initialized(flag: *mut c_int) -> c_int;
    pub fn MPI_Init_thread(argc: *mut c_int, argv: *mut *mut *mut c_char, required: c_int, provided: *mut c_int) -> c_int;
}

/// `MPI_COMM_SELF`: each process's own communicator, the one a sequential matrix lives on.
pub fn comm_self() -> MpiComm {
    // Only the address of the extern static is taken, never its contents.
    std::ptr::addr_of!(ompi_mpi_comm_self) as MpiComm
}

extern "C" {
    pub fn PetscInitializeNoArguments() -> PetscErrorCode;
    /// `options` null: the global database; `value` null for a flag.
    pub fn PetscOptionsSetValue(options: *mut c_void, name: *const c_char, value: *const c_char) -> PetscErrorCode;
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
    pub fn KSPGetPC(ksp: Ksp, pc: *mut Pc) -> PetscErrorCode;
    /// `PCFailedReason`: `PC_NOERROR = 0`, negative or positive codes for failures.
    pub fn PCGetFailedReason(pc: Pc, reason: *mut c_int) -> PetscErrorCode;
}
