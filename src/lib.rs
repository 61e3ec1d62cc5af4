//! fdfsi: fluid-structure interaction for heart-valve modelling.
//!
//! The library behind the `fdfsi` command line. The finite-element toolbox lives in the
//! [`fdfsi_fem`] crate (re-exported as [`fem`]); this crate holds the physics and the drivers.
//!
//! Per solve, data flows one way: mesh -> [`flow::FlowDiscretization`] (dof maps, pattern)
//! -> assembly with the kernels of [`physics`] -> [`solve::newton`] / [`solve::linear`]
//! -> output.
pub use fdfsi_fem as fem;

pub mod adaptation;
pub mod case;
pub mod check;
pub mod checkpoint;
pub mod flow;
pub mod fsi;
pub mod fsi_run;
pub mod output;
pub mod physics;
pub mod picture;
pub mod plot;
pub mod provenance;
pub mod quantities;
pub mod run;
pub mod solid;
pub mod solid_run;
pub mod solve;
pub mod time;
pub mod verify;
