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
//!
//! # One FSI step, as in the paper's section 2
//!
//! A step from `t_n` to `t_{n+1}` ([`discretize::fsi::step_with`]) goes through these stages;
//! `docs/METHOD.md` in the repository gives the equations and the choices the paper leaves open.
//!
//! 1. **gamma_s**: the solid's wetted surface in its current (updated-Lagrangian) configuration,
//!    cut into flat pieces: [`discretize::fsi::FsiModel::gamma_s`] ([`fem::adapt::Surface`]).
//! 2. **Adaptation** (section 2.2.1): the original fluid mesh adapted to gamma_s, vertices within
//!    `eps_hat` of it moved onto it and the cells it cuts split
//!    ([`fem::adapt::adapt_with`]); the fluid the solid covers removed or kept
//!    ([`adapt::CoveredFluid`]). gamma_f is the adapted mesh's facets on gamma_s.
//! 3. **Transfer**: the fluid velocity of `t_n` moved onto the new mesh
//!    ([`discretize::fsi::FluidSnapshot`]; nodes the solid uncovered take its velocity).
//! 4. **Discretisation** (sections 2.1-2.2): [`discretize::fsi::FsiDiscretization::build`]:
//!    P2+/P1disc fluid on the adapted mesh ([`discretize::flow::FlowDiscretization`]), the
//!    Q2/P1disc solid ([`discretize::solid::SolidDiscretization`]), the Lagrange multiplier on
//!    gamma_f's coupling elements; the unknowns in named blocks
//!    ([`discretize::layout::SystemLayout`]).
//! 5. **One monolithic Newton solve** for fluid, solid and multiplier ([`solve::newton::solve`]):
//!    residual and Jacobian by [`discretize::fsi::FsiDiscretization::assemble`] from the element
//!    kernels ([`physics::fluid`], [`physics::solid`], [`physics::coupling`]), each linear system
//!    by sparse LU ([`solve::linear`]) or FGMRES with the augmented-Lagrangian preconditioner
//!    ([`solve::augmented`]), or by PETSc's `KSP` in a build with the `petsc` feature
//!    (`solve::petsc`); the time scheme's weights from [`discretize::time_scheme`].
//! 6. **Update**: the solid's displacement, deformation gradient and velocity at `t_{n+1}`
//!    (updated Lagrangian), and the fluid kept for the next transfer.
//!
//! The time loop is written once: [`time::march::march`] drives any [`time::march::Stepper`]
//! (an FSI run's is [`time::fsi::FsiStepper`]), cuts a failed step into smaller ones and hands
//! each finished step to the run's outputs ([`io::fields`], [`io::history`],
//! [`io::checkpoint`], [`post::quantities`]).
//!
//! # Running a case from Rust
//!
//! What `fdfsi run` does, without the command line:
//!
//! ```no_run
//! use fdfsi::case::{builtin::DEFAULT_CASE, Case};
//! use fdfsi::run::{run_case, RunOptions};
//!
//! let case = Case::from_toml_str(DEFAULT_CASE, "slab-one-beat.toml")?;
//! let options = RunOptions::new("out", ".");
//! let summary = run_case(&case, &options, &mut |line: &str| println!("{line}"))?;
//! println!("{} steps; quantities {:?}", summary.steps, summary.quantities);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
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
