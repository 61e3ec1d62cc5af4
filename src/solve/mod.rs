//! Solvers: the linear solve of the monolithic system ([`linear`]) and Newton's method
//! ([`newton`]).
pub mod linear;
pub mod newton;
