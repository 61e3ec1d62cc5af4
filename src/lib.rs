//! fdfsi: fluid-structure interaction for heart-valve modelling.
//!
//! The library behind the `fdfsi` command line. The finite-element toolbox lives in the
//! [`fdfsi_fem`] crate (re-exported as [`fem`]); this crate holds the method and the drivers.
//!
//! The modules are listed in dependency order: each uses only those above it (a test,
//! `tests/architecture.rs`, holds this). The numerical layers know nothing of case files:
//!
//! - [`physics`]: the element kernels (weak forms, sign conventions) of the fluid, the solid and
//!   the coupling;
//! - [`solve`]: sparse LU, fill-reducing orderings and Newton's method;
//! - [`adapt`]: the fluid mesh adapted to the solid surface (paper section 2.2.1);
//! - [`discretize`]: dof maps, patterns and assembly of the flow, the solid and the monolithic
//!   FSI system with its named block layout (sections 2.1-2.2);
//! - [`time`]: time schemes, the steppers of each kind of run and the one time loop that drives
//!   them ([`time::march::march`]);
//! - [`verify`]: convergence studies against exact solutions.
//!
//! A run then goes case -> setup -> (adapt, discretize, solve, time) -> post/io:
//!
//! - [`case`]: the case-file schema, parsed and validated;
//! - [`setup`]: meshes, problems and models built from a case (for `check`, `run` and `adapt`
//!   alike);
//! - [`post`]: quantities and profiles evaluated from a solution;
//! - [`io`]: atomic files, `history.csv`, VTK fields, checkpoints, provenance, pictures and plots;
//! - [`run`]: the commands (`run`, `check`, `adapt`): observers, summaries, dispatch.
pub use fdfsi_fem as fem;

pub mod physics;
pub mod solve;
pub mod adapt;
pub mod discretize;
pub mod time;
pub mod verify;
pub mod case;
pub mod setup;
pub mod post;
pub mod io;
pub mod run;
