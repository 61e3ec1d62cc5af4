//! Discretisation (paper sections 2.1-2.2): dof maps, sparsity patterns and assembly.
//!
//! - [`flow`]: the P2+/P1disc fluid on one mesh;
//! - [`solid`]: the Q2/P1disc (or Q2) solid, total or updated Lagrangian;
//! - [`fsi`]: the monolithic system of one FSI step and its coupling elements;
//! - [`layout`]: the named blocks of the monolithic system's unknowns;
//! - [`time_scheme`]: implicit Euler and BDF2 as one formula, for the steppers and the FSI step.
pub mod flow;
pub mod fsi;
pub mod layout;
pub mod solid;
pub mod time_scheme;
