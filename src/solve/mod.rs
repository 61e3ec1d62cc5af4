//! Solvers: the linear solve of the monolithic system ([`linear`]: the sparse LU;
//! [`augmented`]: the augmented-Lagrangian block preconditioner inside FGMRES, [`krylov`]),
//! Newton's method ([`newton`]), and the nested-dissection fill-reducing ordering of the direct
//! solver ([`ordering`]); how the unknowns are split over MPI ranks ([`partition`]).
pub mod augmented;
pub mod krylov;
pub mod linear;
pub mod newton;
pub mod ordering;
pub mod partition;
#[cfg(feature = "petsc")]
pub mod petsc;
