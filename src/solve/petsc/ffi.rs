//! The few PETSc calls [`super::PetscSolver`] makes, declared by hand (PETSc 3.18's
//! `petscsys.h`, `petscmat.h`, `petscvec.h`, `petscksp.h`): a thin FFI of our own rather than a
//! generated binding of the whole library, which would need libclang at build time. Everything
//! else (solver types, tolerances, MUMPS settings) goes through PETSc's options database.
//!
//! Types: `PetscInt` is 32-bit unless PETSc was built with 64-bit indices (`cfg(petsc_int64)`,
//! set by `build.rs`); `PetscScalar` is `f64` (a real build: `build.rs` refuses a complex one);
//! `MPI_Comm` is Open MPI's, a pointer (`build.rs` checks PETSc was built on Open MPI, and links
//! Open MPI for the MPI calls of its own made here: start and end, rank and size, the gather of
//! the solution and the reduction of failures on `MPI_COMM_WORLD`).

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
pub type Is = *mut c_void;

/// `PC_FIELDSPLIT_SCHUR_PRE_USER` of `PCFieldSplitSchurPreType` (`SELF, SELFP, A11, USER,
/// FULL`).
pub const PC_FIELDSPLIT_SCHUR_PRE_USER: c_int = 3;
/// `PETSC_COPY_VALUES` of `PetscCopyMode`.
pub const PETSC_COPY_VALUES: c_int = 0;

/// `KSP_CONVERGED_ITS`: `preonly` (a direct solve) reports this after its one application.
pub const KSP_CONVERGED_ITS: c_int = 4;
/// Open MPI's `MPI_THREAD_SERIALIZED` (`mpi.h`: `SINGLE, FUNNELED, SERIALIZED, MULTIPLE`).
pub const MPI_THREAD_SERIALIZED: c_int = 2;
/// `INSERT_VALUES` of PETSc's `InsertMode` (`NOT_SET_VALUES, INSERT_VALUES, ...`).
pub const INSERT_VALUES: c_int = 1;
/// `MAT_FINAL_ASSEMBLY` of `MatAssemblyType`.
pub const MAT_FINAL_ASSEMBLY: c_int = 0;
/// `MAT_NO_OFF_PROC_ENTRIES` of `MatOption`: each rank sets only its own rows, so assembly
/// sends nothing.
pub const MAT_NO_OFF_PROC_ENTRIES: c_int = 17;
/// Open MPI's `MPI_IN_PLACE` (`(void *) 1`).
pub const MPI_IN_PLACE: *const c_void = std::ptr::without_provenance(1);

/// Open MPI's predefined objects (`struct ompi_predefined_communicator_t`, `..._datatype_t`;
/// opaque here): `MPI_COMM_WORLD` is the address of `ompi_mpi_comm_world`, `MPI_DOUBLE` of
/// `ompi_mpi_double`, `MPI_MAX` of `ompi_mpi_op_max`.
#[repr(C)]
pub struct OmpiObject {
    _private: [u8; 0],
}

extern "C" {
    static ompi_mpi_comm_world: OmpiObject;
    static ompi_mpi_double: OmpiObject;
    static ompi_mpi_op_max: OmpiObject;
    pub fn MPI_Initialized(flag: *mut c_int) -> c_int;
    pub fn MPI_Finalized(flag: *mut c_int) -> c_int;
    pub fn MPI_Init_thread(argc: *mut c_int, argv: *mut *mut *mut c_char, required: c_int, provided: *mut c_int) -> c_int;
    pub fn MPI_Finalize() -> c_int;
    pub fn MPI_Abort(comm: MpiComm, code: c_int) -> c_int;
    pub fn MPI_Comm_rank(comm: MpiComm, rank: *mut c_int) -> c_int;
    pub fn MPI_Comm_size(comm: MpiComm, size: *mut c_int) -> c_int;
    pub fn MPI_Allreduce(send: *const c_void, receive: *mut c_void, count: c_int, datatype: MpiDatatype, op: MpiOp, comm: MpiComm) -> c_int;
    pub fn MPI_Allgatherv(
        send: *const c_void,
        send_count: c_int,
        send_type: MpiDatatype,
        receive: *mut c_void,
        receive_counts: *const c_int,
        displacements: *const c_int,
        receive_type: MpiDatatype,
        comm: MpiComm,
    ) -> c_int;
}

/// Open MPI's `MPI_Datatype` and `MPI_Op` (pointers).
pub type MpiDatatype = *mut c_void;
pub type MpiOp = *mut c_void;

/// `MPI_COMM_WORLD`: all the ranks `mpirun` started (one alone without it).
pub fn comm_world() -> MpiComm {
    // Only the addresses of the extern statics are taken, never their contents.
    std::ptr::addr_of!(ompi_mpi_comm_world) as MpiComm
}

/// `MPI_DOUBLE`.
pub fn mpi_double() -> MpiDatatype {
    std::ptr::addr_of!(ompi_mpi_double) as MpiDatatype
}

/// `MPI_MAX`.
pub fn mpi_max() -> MpiOp {
    std::ptr::addr_of!(ompi_mpi_op_max) as MpiOp
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

    pub fn PetscFinalize() -> PetscErrorCode;

    pub fn MatCreate(comm: MpiComm, mat: *mut Mat) -> PetscErrorCode;
    pub fn MatSetSizes(mat: Mat, local_rows: PetscInt, local_cols: PetscInt, rows: PetscInt, cols: PetscInt) -> PetscErrorCode;
    /// `kind`: a `MatType` string (`"aij"`).
    pub fn MatSetType(mat: Mat, kind: *const c_char) -> PetscErrorCode;
    /// The matrix's rows on this rank in CSR (global column indices); a no-op unless the
    /// matrix is sequential (resp. parallel) AIJ.
    pub fn MatSeqAIJSetPreallocationCSR(mat: Mat, row_ptr: *const PetscInt, col_idx: *const PetscInt, values: *const f64) -> PetscErrorCode;
    pub fn MatMPIAIJSetPreallocationCSR(mat: Mat, row_ptr: *const PetscInt, col_idx: *const PetscInt, values: *const f64) -> PetscErrorCode;
    pub fn MatSetOption(mat: Mat, option: c_int, flag: PetscBool) -> PetscErrorCode;
    pub fn MatSetValues(
        mat: Mat,
        num_rows: PetscInt,
        rows: *const PetscInt,
        num_cols: PetscInt,
        cols: *const PetscInt,
        values: *const f64,
        mode: c_int,
    ) -> PetscErrorCode;
    pub fn MatAssemblyBegin(mat: Mat, kind: c_int) -> PetscErrorCode;
    pub fn MatAssemblyEnd(mat: Mat, kind: c_int) -> PetscErrorCode;
    pub fn MatDestroy(mat: *mut Mat) -> PetscErrorCode;

    pub fn VecCreateMPIWithArray(
        comm: MpiComm,
        block_size: PetscInt,
        local: PetscInt,
        global: PetscInt,
        values: *const f64,
        vec: *mut Vec,
    ) -> PetscErrorCode;
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
    pub fn PCCreate(comm: MpiComm, pc: *mut Pc) -> PetscErrorCode;
    pub fn PCSetOperators(pc: Pc, a: Mat, p: Mat) -> PetscErrorCode;
    pub fn PCSetOptionsPrefix(pc: Pc, prefix: *const c_char) -> PetscErrorCode;
    pub fn PCSetFromOptions(pc: Pc) -> PetscErrorCode;
    pub fn PCSetUp(pc: Pc) -> PetscErrorCode;
    pub fn PCSetUpOnBlocks(pc: Pc) -> PetscErrorCode;
    pub fn PCApply(pc: Pc, x: Vec, y: Vec) -> PetscErrorCode;
    pub fn PCDestroy(pc: *mut Pc) -> PetscErrorCode;
    /// `kind`: a `PCType` string (`"shell"`).
    pub fn PCSetType(pc: Pc, kind: *const c_char) -> PetscErrorCode;
    pub fn PCShellSetApply(pc: Pc, apply: extern "C" fn(Pc, Vec, Vec) -> PetscErrorCode) -> PetscErrorCode;
    pub fn PCShellSetContext(pc: Pc, context: *mut c_void) -> PetscErrorCode;
    /// `context`: where to write the context pointer.
    pub fn PCShellGetContext(pc: Pc, context: *mut c_void) -> PetscErrorCode;
    pub fn MatMult(mat: Mat, x: Vec, y: Vec) -> PetscErrorCode;
    pub fn VecCreateMPI(comm: MpiComm, local: PetscInt, global: PetscInt, vec: *mut Vec) -> PetscErrorCode;
    pub fn ISCreateGeneral(comm: MpiComm, n: PetscInt, indices: *const PetscInt, mode: c_int, is: *mut Is) -> PetscErrorCode;
    pub fn ISDestroy(is: *mut Is) -> PetscErrorCode;
    pub fn ISSetBlockSize(is: Is, bs: PetscInt) -> PetscErrorCode;
    /// A no-op unless the preconditioner is `fieldsplit`.
    pub fn PCFieldSplitSetIS(pc: Pc, name: *const c_char, is: Is) -> PetscErrorCode;
    /// `kind`: a `PCFieldSplitSchurPreType` ([`PC_FIELDSPLIT_SCHUR_PRE_USER`]); the
    /// preconditioner keeps its own reference to `pre`. A no-op unless it is `fieldsplit`.
    pub fn PCFieldSplitSetSchurPre(pc: Pc, kind: c_int, pre: Mat) -> PetscErrorCode;
    /// `PCFailedReason`: `PC_NOERROR = 0`, negative or positive codes for failures.
    pub fn PCGetFailedReason(pc: Pc, reason: *mut c_int) -> PetscErrorCode;
}
