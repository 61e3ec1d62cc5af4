//! Solvers: the linear solve of the monolithic system ([`linear`]) and Newton's method
//! ([`newton`]), and the nested-dissection fill-reducing ordering of the direct solver
//! ([`ordering`]).
pub mod linear;
pub mod newton;
pub mod ordering;
