//! The monolithic fluid-structure discretisation and one implicit-Euler FSI step (paper sections
//! 2.1-2.2, METHOD.md sections 2-4).
//!
//! Per step, data flows one way:
//!
//! 1. the solid at `t_n` (positions `X + u_n`) gives gamma_s ([`FsiModel::gamma_s`]);
//! 2. the ORIGINAL fluid mesh (prepared once as a [`Background`]) is adapted to it
//!    ([`adapt_with`]; in 2D its corners first made fluid vertices); with
//!    [`CoveredFluid::Removed`] the fluid cells gamma_f encloses are removed; where the solid
//!    touches a contact plane that bounds the fluid, the cells in the gap between them are cut
//!    off ([`remove_closed_gaps`], held at rest on the boundary [`CLOSED_GAP`]); the facets on
//!    gamma_s (gamma_f) are tagged as the boundary `gamma_f`;
//! 3. [`FsiDiscretization::build`]: the fluid discretisation of the adapted mesh, the coupling
//!    elements (one per gamma_f facet, with their quadrature points located in a fluid cell and on
//!    the solid), the global numbering `[fluid (u, p) | solid (Delta u, p) | multiplier]` and one
//!    sparse [`Pattern`] with the coupling blocks, or this rank's rows of it
//!    ([`FsiDiscretization::build_with`]);
//! 4. the previous fluid velocity is transferred to the new velocity nodes
//!    ([`transfer_p2plus_or`]; nodes the solid uncovered since take the old velocity's extension
//!    up to a cell into the old mesh's hole and the solid's velocity farther in, or zero in a
//!    closed gap, `FluidSnapshot::transferred_to`), and the previous pressure to the new cells
//!    (`FluidSnapshot::pressure_on`, [`transfer_p1disc`]): both start Newton, with the solid's
//!    increment and the multipliers at zero;
//! 5. Newton on the monolithic residual: the fluid and solid blocks are assembled by their own
//!    discretisations ([`FlowDiscretization::assemble_into`],
//!    [`SolidDiscretization::assemble_into`], updated Lagrangian) into block matrices and
//!    scattered into the global one through position maps precomputed with the pattern; the
//!    coupling kernel ([`crate::physics::coupling`]) is assembled directly, and so is the load
//!    of the films on the sides of gamma_f a closed gap cut off ([`FilmLoad`]). With a solver of each
//!    MPI rank's rows, each rank assembles its own rows of the system instead, straight from the
//!    cells that touch them ([`FsiDiscretization::assemble_rows`], [`FsiRows`]);
//! 6. the solid is updated: `x_{n+1} = x_n + Delta u`, `F_{n+1} = (I + grad_n Delta u) F_n`.
//!
//! Time scheme: implicit Euler (the paper's) or BDF2, one formula for fluid and solid
//! ([`crate::time::step_history`]: `u' = a (u - u*)`, `a = a0 / dt`): the fluid inertia
//! `rho a (u - u*)` with the velocities of `t_n` (and `t_{n-1}`) transferred to the new mesh,
//! the solid velocity `u_s = a (Delta u - d)` in the coupling constraint, with
//! `d = u*_s - u_n` (0 for Euler), and the optional solid inertia
//! `rho_0 a^2 (Delta u - d - v* / a)` ([`SolidBody::density`](crate::discretize::solid::SolidBody::density)). Implicit Euler: `a = 1/dt`,
//! `d = 0`, `v* = v_n`. The geometry of a step (gamma_s, the adapted mesh, gamma_f) is that of
//! `t_n` for implicit Euler, as in the paper (adapt, then solve), and for BDF2 the solid
//! extrapolated to `t_{n+1}`, `u_n + omega (u_n - u_{n-1})` ([`StepStart::geometry`]), so that
//! gamma_f lags the solid by `O(dt^2)`, not `O(dt)`. The first step of a run, and a step cut into
//! sub-steps, are implicit-Euler steps.
//!
//! The solid's boundary-condition functions receive the time `t_{n+1}` as their "load" argument.
//!
//! Multiplier convention: `lambda` is the traction of the fluid on the solid (see
//! [`crate::physics::coupling`]); [`FsiDiscretization::multiplier_force`] is the force of the
//! fluid on the body.

use super::layout::{Block, SystemLayout};
pub use crate::adapt::CoveredFluid;
use crate::discretize::flow::{AssemblyError, DirichletBc, Entries, FlowDiscretization, FlowError, FlowProblem};
use crate::discretize::solid::{ContactTarget, SolidAssemblyError, SolidDiscretization, SolidError, SolidProblem};
use crate::discretize::symmetry::NormalConstraints;
use crate::discretize::time_scheme::{step_history, step_ratio, TimeScheme};
use crate::physics::coupling::{coupling_point, CouplingPoint, CouplingState};
use crate::physics::solid::{Mat3, IDENTITY};
use crate::solve::augmented::{MultiplierBlock, MultiplierRole, SaddlePointSplit};
use crate::solve::linear::{LinearSolveError, LinearSolver};
use crate::solve::newton::{self, NewtonError, NewtonOptions, NewtonReport};
use crate::solve::partition::{row_solver_of, Nodes, Partition};
use fdfsi_fem::adapt::gap::{cell_height_at, cell_size_at, layer_towards, CutSide};
use fdfsi_fem::adapt::{
    adapt_with, p1disc_value, remove_closed_gaps, transfer_p1disc, transfer_p2plus_or, AdaptError, AdaptOptions, AdaptStats, Adapted, Background,
    CellLocator, GammaFacet, GapPlane, Surface, CLOSED_GAP, GAMMA_F_REL_TOL,
};
use fdfsi_fem::dofs::NodeMap;
use fdfsi_fem::element::{ReferenceElement, MAX_DOFS};
use fdfsi_fem::locate::simplex_reference_coords;
use fdfsi_fem::mesh::{connected_components, Mesh, MeshError, NO_CELL};
use fdfsi_fem::quadrature;
use fdfsi_fem::sparse::{Colouring, CscMatrix, HeldRows, Pattern, ResidualOnly, RowMatrix, RowPattern, SystemTarget, WholeSystem};
use fdfsi_fem::values::det_inv;
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use thiserror::Error;

/// Quadrature degree on the coupling elements: P1 multiplier times the P2 fluid trace is degree
/// 3; the solid basis along a gamma_f facet is piecewise (the facet may straddle several gamma_s
/// pieces), so a few more points.
const COUPLING_DEGREE: usize = 7;

/// The tracing target of [`FsiDiscretization::trace_blocks`]'s entry per block: each block's
/// largest entry of a residual or an update, named.
const BLOCKS_TARGET: &str = "fdfsi::discretize::fsi::blocks";

/// An error inside the monolithic assembly (reported through Newton).
#[derive(Debug, Error)]
pub enum FsiAssemblyError {
    #[error("fluid: {0}")]
    Fluid(#[from] AssemblyError),
    #[error("solid: {0}")]
    Solid(#[from] SolidAssemblyError),
}

/// Errors of an FSI step.
#[derive(Debug, Error)]
pub enum FsiError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("adaptation: {0}")]
    Adapt(#[from] AdaptError),
    #[error(transparent)]
    Flow(#[from] FlowError),
    #[error(transparent)]
    Solid(#[from] SolidError),
    #[error("gamma_f is empty: gamma_s (solid boundary '{0}') cuts no fluid cell; check the solid's placement and the surface name")]
    EmptyGammaF(String),
    #[error("coupling point {point} of gamma_f facet {facet} at {x:?}: {reason}")]
    Unlocated { facet: usize, point: usize, x: Vec<f64>, reason: String },
    #[error(transparent)]
    Newton(#[from] NewtonError<FsiAssemblyError>),
    /// A zero pivot, with the unknown it was met at described ([`FsiDiscretization::describe_unknown`]).
    #[error("{error}; unknown {unknown} is {what}")]
    SingularAt { unknown: usize, what: String, error: NewtonError<FsiAssemblyError> },
    #[error("restart: {0}")]
    Restart(String),
    #[error("multiplier space: {0}")]
    Multiplier(String),
}

/// Whose pressure the film of blood in a closed gap carries ([`FilmLoad`]; in case files
/// `[solid] film_pressure`).
///
/// A gap cut off between a solid and a plane is open at its mouths: where the band of the solid
/// in the gap does not quite touch the plane, the film is a channel between them, and its pressure
/// falls to that of its lower end. Taken at the mouth nearest each facet, the films of a 3D
/// leaflet's coaptation band split by height: the upper ones took the aorta's pressure in
/// diastole and pushed the band off its plane from inside the gap, and the closed valve leaked
/// (`runs/valve-3d-sector/NOTES.md`, session 48). At the gap's lowest mouth the films carry the
/// ventricle's pressure in diastole, which presses the band on, and the aorta's at the reopening,
/// which leaves the band free for the ventricle's pressure to lift.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FilmPressure {
    /// The kept cell at the gap's mouth nearest the film's facet ([`fdfsi_fem::adapt::gap::CutSide::mouth`]).
    #[default]
    NearestMouth,
    /// Of the mouths of the film's gap ([`Adapted::gap_mouths`]), the cell whose pressure at its
    /// centroid was lowest at the step's start (the last step's pressure there; the choice is
    /// lagged by a step, the pressure it carries is the step's unknown). A gap none of whose
    /// mouths lies in the last step's mesh keeps the nearest.
    LowestMouth,
    /// The film's own pressure by Reynolds' equation `div (h^3 grad p) = 0` on the gap's cut
    /// cells, `h` the gap's height, with the mouths' pressures at its ends
    /// ([`fdfsi_fem::adapt::gap::CutSide::film`]): at each facet a mean `sum_m w_m p_m` of the
    /// pressure unknowns of the gap's mouths, its weights from the gap's geometry alone. Where
    /// the band touches its plane along a line the film is sealed there and carries each side's
    /// pressure; where it stands off the plane evenly the pressure falls along it from one end's
    /// to the other's; and no one mouth cell decides it unless the film opens to it alone (the
    /// lowest mouth was at times a cell with a pressure the flow did not explain,
    /// `runs/valve-3d-sector/NOTES.md`, session 49). A side whose gap has no film (a degenerate
    /// cell) takes the nearest mouth.
    Reynolds,
}

/// The multiplier space on gamma_f.
///
/// The paper's P1-discontinuous multiplier has `2N` functions per component on a chain of `N`
/// gamma_f facets (2D), the continuous P2 fluid trace `2N + 1` values: the weak no-slip
/// `<mu, u_f - u_s> = 0` leaves one trace function per component and connected chain free, the
/// function that is the Legendre polynomial `1 - 6s + 6s^2` on every facet (vertex values 1,
/// mid-facet values -1/2; it is orthogonal to every P1 function on every facet and continuous).
/// Its amplitude is set by the fluid alone, and on short facets its tangential derivative
/// (`~ 6 c / |facet|`) shows in the pointwise wall shear stress (model problem 2).
/// [`MultiplierSpace::P1DiscontinuousTraceMode`] adds that function to the multiplier space
/// (one multiplier per component and chain): the pairing of multipliers and the trace space on a
/// chain is then square and invertible, so the trace of `u_f` is fully determined by `u_s` (a
/// stiff body at rest gives `u_f = 0` at every P2 node of gamma_f, as Dirichlet nodes would).
/// The extra function integrates to zero on every facet, so `int lambda ds` (the force) is
/// unchanged in form. Where a chain has a fluid Dirichlet node (vertex or mid-facet) on
/// component `a`, that trace function is not free and its multiplier is fixed to zero
/// ([`FsiDiscretization::inactive_multiplier_dofs`]). 2D only: in 3D the P2+ trace on a face
/// (P2 and the face bubble) leaves more than one function free.
///
/// In both spaces the P1-discontinuous multipliers that no free fluid velocity sees are removed
/// ([`multiplier_kernel`]): with them lambda oscillated from facet to facet (a membrane from the
/// axis to the wall: +-400 on a radial traction of 0.1; in 3D, around every interior vertex of
/// gamma_f) while its integral was right.
///
/// In case files (`[solid] multiplier`): `p1-discontinuous`, `p1-discontinuous-trace-mode`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MultiplierSpace {
    /// The paper's: P1 discontinuous on each gamma_f facet.
    #[default]
    P1Discontinuous,
    /// P1 discontinuous plus, per component and connected chain of gamma_f, the trace function
    /// orthogonal to it (2D only).
    P1DiscontinuousTraceMode,
}

/// The coupled problem: fluid and solid problems, the solid boundary that is gamma_s, and the
/// adaptation knobs.
#[derive(Clone)]
pub struct FsiProblem<const D: usize> {
    /// Fluid physics and boundary conditions on the original fluid boundaries (`params.inv_dt`
    /// is set by the step).
    pub fluid: FlowProblem<D>,
    /// Solid material and boundary conditions (their load argument is the time).
    pub solid: SolidProblem<D>,
    /// Name of the solid boundary forming gamma_s.
    pub surface: String,
    pub adapt: AdaptOptions,
}

/// Everything built once for a coupled run: the problem, the prepared original fluid mesh and the
/// solid discretisation (reference configuration).
pub struct FsiModel<const D: usize> {
    pub problem: FsiProblem<D>,
    pub background: Background<D>,
    pub solid: SolidDiscretization<D>,
    /// The multiplier space on gamma_f (default: the paper's P1 discontinuous).
    pub multiplier: MultiplierSpace,
    /// The fluid cells under the solid (default: kept, the paper's).
    pub covered_fluid: CoveredFluid,
    /// Whose pressure the films in closed gaps carry (default: the nearest mouth's).
    pub film_pressure: FilmPressure,
    /// With [`FilmPressure::Reynolds`], the films' squeeze term too (default: off, the
    /// quasi-static film): see [`FilmLoad::squeeze`].
    pub film_squeeze: bool,
    /// Where the fluid is cut off once each contact of the solid closes ([`remove_closed_gaps`]),
    /// in the order of the solid problem's contacts.
    pub closed_gaps: Vec<ClosedGap<D>>,
    /// The connected part (body) of each solid cell: which side of a contact between two
    /// boundaries a piece of gamma_s is on.
    solid_part: Vec<usize>,
}

/// The fluid cut off where a contact of the solid has closed ([`fdfsi_fem::adapt::gap`]).
#[derive(Clone, Debug, PartialEq)]
pub enum ClosedGap<const D: usize> {
    /// Against a rigid plane: once the contact boundary touches it, the fluid between the solid
    /// and the plane where their gap is at most `cut_off` ([`GapPlane::layer`]).
    Plane(GapPlane<D>),
    /// Against another boundary, of another body: once a contact pressure of the boundary is
    /// positive, the fluid between the two bodies where their gap is at most `cut_off` (the
    /// pieces of each body's gamma_s and contact boundary within `cut_off` of the other's
    /// contact boundary, [`layer_towards`]). 0 cuts nothing off.
    Between { cut_off: f64 },
}

impl<const D: usize> ClosedGap<D> {
    /// The largest gap cut off.
    pub fn cut_off(&self) -> f64 {
        match self {
            ClosedGap::Plane(plane) => plane.cut_off,
            ClosedGap::Between { cut_off } => *cut_off,
        }
    }
}

impl<const D: usize> FsiModel<D> {
    /// The model with another multiplier space.
    pub fn with_multiplier(mut self, multiplier: MultiplierSpace) -> Self {
        self.multiplier = multiplier;
        self
    }

    /// The model with the covered fluid kept or removed.
    pub fn with_covered_fluid(mut self, covered_fluid: CoveredFluid) -> Self {
        self.covered_fluid = covered_fluid;
        self
    }

    /// The model with the films in closed gaps at the pressure `film_pressure` says.
    pub fn with_film_pressure(mut self, film_pressure: FilmPressure) -> Self {
        self.film_pressure = film_pressure;
        self
    }

    /// The model with the films' squeeze term on or off ([`FsiModel::film_squeeze`]).
    pub fn with_film_squeeze(mut self, film_squeeze: bool) -> Self {
        self.film_squeeze = film_squeeze;
        self
    }

    /// The model with the fluid cut-off gaps of its contacts set (`None` keeps the default, one
    /// cell of the fluid mesh where they close; see [`FsiModel::new`]).
    pub fn with_cut_offs(mut self, cut_offs: &[Option<f64>]) -> Self {
        for (gap, cut_off) in self.closed_gaps.iter_mut().zip(cut_offs) {
            match (gap, cut_off) {
                (ClosedGap::Plane(plane), Some(c)) => plane.cut_off = *c,
                (ClosedGap::Between { cut_off }, Some(c)) => *cut_off = *c,
                (_, None) => {}
            }
        }
        self
    }

    /// Prepares the original fluid mesh and discretises the solid mesh (reference configuration).
    /// Where the solid has rigid contact planes that bound the fluid (walls, symmetry lines),
    /// once it touches one the fluid between them is cut off where their gap is below the mean
    /// height of the fluid cells at the plane ([`cell_height_at`]; a plane inside the fluid cuts
    /// nothing off); where a boundary of the solid is in contact with another body's, once the
    /// contact closes the fluid between the two bodies is cut off where their gap is below the
    /// mean size of the fluid cells at the contact boundary at rest ([`cell_size_at`]).
    /// [`FsiModel::with_cut_offs`] sets other lengths. The fluid is held at rest on the boundary
    /// [`CLOSED_GAP`] this leaves.
    pub fn new(mut problem: FsiProblem<D>, fluid_mesh: &Mesh<D>, solid_mesh: Mesh<D>) -> Result<Self, FsiError> {
        let background = Background::new(fluid_mesh)?;
        let solid = SolidDiscretization::build_for(solid_mesh, &problem.solid)?;
        solid.check_problem(&problem.solid)?;
        solid.mesh.boundary_tag(&problem.surface)?;
        let closed_gaps = problem
            .solid
            .contact
            .iter()
            .map(|c| match c.plane() {
                Some(p) => {
                    let plane = GapPlane { point: p.point, normal: p.normal, cut_off: 0.0 };
                    Ok(ClosedGap::Plane(GapPlane { cut_off: cell_height_at(&background.mesh, &plane), ..plane }))
                }
                None => {
                    let boundary = Surface::from_mesh_boundary(&solid.mesh, &c.boundary)?;
                    Ok(ClosedGap::Between { cut_off: cell_size_at(&background.mesh, &boundary.points) })
                }
            })
            .collect::<Result<Vec<_>, FsiError>>()?;
        if !closed_gaps.is_empty() {
            let at_rest: crate::discretize::flow::VectorFn<D> = Arc::new(|_: &[f64; D], _: f64| [0.0; D]);
            problem.fluid.dirichlet.push(DirichletBc { boundary: CLOSED_GAP.into(), components: (0..D).collect(), value: at_rest });
        }
        let solid_part = connected_parts(&solid.mesh);
        Ok(FsiModel {
            problem,
            background,
            solid,
            multiplier: MultiplierSpace::default(),
            covered_fluid: CoveredFluid::default(),
            film_pressure: FilmPressure::default(),
            film_squeeze: false,
            closed_gaps,
            solid_part,
        })
    }

    /// The films of `adapted` (its [`Adapted::cut_sides`]) at the mouths [`FsiModel::film_pressure`]
    /// says, `last` the fluid of the step's start: the nearest as the cut leaves them, or the
    /// lowest in `last`'s pressure ([`FilmPressure::LowestMouth`]).
    pub fn choose_film_mouths(&self, last: Option<&FluidSnapshot<D>>, adapted: &mut Adapted<D>) {
        if let (FilmPressure::LowestMouth, Some(last)) = (self.film_pressure, last) {
            last.take_lowest_mouths(adapted);
        }
    }

    /// The mean whose pressure the film on `side` carries, `(kept cell, weight)` pairs whose
    /// weights sum to one ([`FsiModel::film_pressure`]): its mouth alone, or with
    /// [`FilmPressure::Reynolds`] its gap's film weights (the mouth where its gap has none);
    /// empty for a side without a mouth.
    pub fn film_weights(&self, side: &CutSide<D>) -> Vec<(usize, f64)> {
        if self.film_pressure == FilmPressure::Reynolds && !side.film.is_empty() {
            side.film.clone()
        } else {
            side.mouth.map(|m| (m, 1.0)).into_iter().collect()
        }
    }

    /// The film's squeeze resistance on `side`, `12 mu s` ([`FilmLoad::squeeze`], `s` its
    /// [`CutSide::squeeze`]): with [`FsiModel::film_squeeze`] and the films by Reynolds'
    /// equation, where the side has its gap's film; else 0.
    pub fn film_squeeze_resistance(&self, side: &CutSide<D>) -> f64 {
        let on = self.film_squeeze && self.film_pressure == FilmPressure::Reynolds && !side.film.is_empty();
        if on {
            12.0 * self.problem.fluid.params.viscosity * side.squeeze
        } else {
            0.0
        }
    }

    /// `adapted` (to gamma_s `surface` at the solid displacement `solid_x`) with the fluid cut
    /// off where a contact of the solid has closed ([`ClosedGap`], [`remove_closed_gaps`]): on a
    /// plane ([`GapPlane::is_closed`]) the gap layer below gamma_s and the contact boundary
    /// ([`GapPlane::layer`]), only on the gap's side of gamma_s where the contact boundary is
    /// part of gamma_s; against another body (a contact pressure in `solid_x` positive) the
    /// layers between the two bodies ([`FsiModel::layers_between`]); then the fluid walled in
    /// away from gamma_f and the boundaries that set the pressure ([`FsiModel::open_boundaries`]).
    /// Unchanged without contacts or while none is closed.
    pub(crate) fn cut_off_closed_gaps(&self, adapted: Adapted<D>, surface: &Surface<D>, solid_x: &[f64]) -> Result<Adapted<D>, FsiError> {
        // With contacts the boundary `closed_gap` is always named (the fluid's condition on it
        // must find it), even when nothing is cut off.
        if self.closed_gaps.is_empty() {
            return Ok(adapted);
        }
        let mesh = self.current_solid_mesh(solid_x);
        let (mut layers, mut pressed, mut pressed_on) = (Vec::new(), Vec::new(), Vec::new());
        for (k, (gap, contact)) in self.closed_gaps.iter().zip(&self.problem.solid.contact).enumerate() {
            if gap.cut_off() <= 0.0 {
                continue;
            }
            let boundary = Surface::from_mesh_boundary(&mesh, &contact.boundary)?;
            match (gap, &contact.target) {
                (ClosedGap::Plane(plane), _) if plane.is_closed(&boundary) => {
                    if self.is_part_of_gamma_s(&contact.boundary)? {
                        // gamma_s itself pressed on the plane: the fluid behind it stays.
                        pressed.extend(plane.layer(surface));
                        pressed_on.push(*plane);
                    } else {
                        layers.extend(plane.layer(surface));
                        layers.extend(plane.layer(&boundary));
                    }
                }
                (ClosedGap::Between { cut_off }, ContactTarget::Boundary(master)) => {
                    let master = Surface::from_mesh_boundary(&mesh, master)?;
                    if self.contact_closed(k, solid_x, &boundary, &master, *cut_off) {
                        layers.extend(self.layers_between(surface, &boundary, &master, *cut_off));
                    }
                }
                _ => {}
            }
        }
        let open = self.open_boundaries(&adapted.mesh);
        Ok(remove_closed_gaps(adapted, &layers, &pressed, &pressed_on, surface, &open))
    }

    /// Whether every facet of the solid's boundary `name` is a facet of gamma_s.
    fn is_part_of_gamma_s(&self, name: &str) -> Result<bool, FsiError> {
        let mesh = &self.solid.mesh;
        let gamma_s: HashSet<(usize, usize)> = mesh.boundary_facets(&self.problem.surface)?.iter().map(|b| (b.cell, b.facet)).collect();
        Ok(mesh.boundary_facets(name)?.iter().all(|b| gamma_s.contains(&(b.cell, b.facet))))
    }

    /// The tags in `mesh` (the adapted fluid mesh) of the fluid boundaries that set the level of
    /// its pressure, where its normal velocity is free: the original mesh's boundaries with a
    /// traction (pressure, free) or Windkessel condition, or none. Fluid a closed gap cuts off
    /// from them, and from gamma_f, is cut off too ([`remove_closed_gaps`]).
    fn open_boundaries(&self, mesh: &Mesh<D>) -> Vec<u32> {
        let fluid = &self.problem.fluid;
        let loaded = |name: &str| fluid.traction.iter().any(|b| b.boundary == name) || fluid.windkessel.iter().any(|b| b.boundary == name);
        let held = |name: &str| fluid.dirichlet.iter().any(|b| b.boundary == name) || fluid.symmetry.iter().any(|b| b.boundary == name);
        let open = |name: &str| loaded(name) || !held(name);
        self.background.mesh.boundary_names.iter().filter(|(name, _)| open(name)).filter_map(|(name, _)| mesh.boundary_tag(name).ok()).collect()
    }

    /// Whether the `k`-th contact (against another boundary `master`) is closed at `solid_x`: a
    /// contact pressure of its boundary positive, or a corner of the boundary `slave` within
    /// `1e-3 cut_off` of `master` (under BDF2 `solid_x` is extrapolated, contact pressures
    /// included, and a pressure falling to zero may extrapolate below it while the bodies still
    /// touch).
    fn contact_closed(&self, k: usize, solid_x: &[f64], slave: &Surface<D>, master: &Surface<D>, cut_off: f64) -> bool {
        let s = &self.solid.contact_surfaces()[k];
        debug_assert!(solid_x.len() >= s.first + s.nodes.len(), "solid_x holds the contact pressures");
        let pressed = solid_x.get(s.first..s.first + s.nodes.len()).is_some_and(|p| p.iter().any(|&v| v > 0.0));
        pressed || slave.points.iter().any(|x| master.project(x).is_some_and(|p| p.distance <= 1e-3 * cut_off))
    }

    /// The cut-off and the slave and master boundaries at `solid_x` of each contact between two
    /// boundaries that cuts fluid off (a cut-off > 0).
    fn between_boundaries(&self, solid_x: &[f64]) -> Result<Vec<(f64, Surface<D>, Surface<D>)>, FsiError> {
        let mesh = self.current_solid_mesh(solid_x);
        let mut out = Vec::new();
        for (gap, contact) in self.closed_gaps.iter().zip(&self.problem.solid.contact) {
            if let (ClosedGap::Between { cut_off }, ContactTarget::Boundary(master)) = (gap, &contact.target) {
                if *cut_off > 0.0 {
                    out.push((*cut_off, Surface::from_mesh_boundary(&mesh, &contact.boundary)?, Surface::from_mesh_boundary(&mesh, master)?));
                }
            }
        }
        Ok(out)
    }

    /// The gap layers between two bodies in contact, the `slave` boundary's and the `master`'s
    /// ([`layer_towards`]): each contact boundary towards the other, and the pieces of gamma_s
    /// (`surface`) of each body towards the other's contact boundary (the body of a boundary:
    /// that of its first piece; none when the two boundaries are of one body, whose gamma_s
    /// pieces next to its own boundaries would all be near them).
    fn layers_between(&self, surface: &Surface<D>, slave: &Surface<D>, master: &Surface<D>, cut_off: f64) -> Vec<Vec<[f64; D]>> {
        let part = |s: &Surface<D>| s.origin.first().map(|&(c, _)| self.solid_part[c]);
        let corners = |s: &Surface<D>, i: usize| s.pieces[i].map(|p| s.points[p]);
        let (slave_part, master_part) = (part(slave), part(master));
        let mut layers = layer_towards((0..slave.pieces.len()).map(|i| corners(slave, i)), master, cut_off);
        layers.extend(layer_towards((0..master.pieces.len()).map(|i| corners(master, i)), slave, cut_off));
        if slave_part == master_part {
            return layers;
        }
        let of = |which: Option<usize>| (0..surface.pieces.len()).filter(move |&i| Some(self.solid_part[surface.origin[i].0]) == which);
        layers.extend(layer_towards(of(slave_part).map(|i| corners(surface, i)), master, cut_off));
        layers.extend(layer_towards(of(master_part).map(|i| corners(surface, i)), slave, cut_off));
        layers
    }

    /// The solid mesh at the total displacement in `solid_x` (solid numbering): every geometry
    /// node is placed by interpolating the Q2 displacement of its cell. Basis values within
    /// 1e-12 of 0 or 1 are taken as exactly 0 or 1, so a geometry node that is a displacement
    /// node gets exactly its nodal position: an end of gamma_s held on the symmetry axis or a
    /// wall stays exactly on it (a round-off of 3e-17 off the axis made the adaptation miss the
    /// fluid's axis edge there, and gamma_f stopped one cell short of the axis).
    pub fn current_solid_mesh(&self, solid_x: &[f64]) -> Mesh<D> {
        let s = &self.solid;
        let mut mesh = s.mesh.clone();
        let geo = s.mesh.geometry_element();
        let tab = s.element.tabulate(geo.nodes());
        let vf = s.displacement_field();
        let nv = s.element.num_dofs();
        for c in 0..mesh.num_cells() {
            let dnodes = vf.nodes.cell(c);
            for (k, &p) in s.mesh.cell(c).iter().enumerate() {
                let mut x = [0.0; D];
                for (i, &node) in dnodes.iter().enumerate() {
                    let phi = match tab.values[k * nv + i] {
                        v if v.abs() < 1e-12 => 0.0,
                        v if (v - 1.0).abs() < 1e-12 => 1.0,
                        v => v,
                    };
                    if phi != 0.0 {
                        for d in 0..D {
                            x[d] += phi * (s.nodes_x0[node][d] + solid_x[vf.dof(node, d)]);
                        }
                    }
                }
                mesh.points[p] = x;
            }
        }
        mesh
    }

    /// gamma_s at the total displacement `solid_x`.
    pub fn gamma_s(&self, solid_x: &[f64]) -> Result<Surface<D>, FsiError> {
        Ok(Surface::from_mesh_boundary(&self.current_solid_mesh(solid_x), &self.problem.surface)?)
    }
}

/// The fluid velocity of the last step on its adapted mesh (what the next step transfers).
#[derive(Clone, Debug)]
pub struct FluidSnapshot<const D: usize> {
    /// The solid displacement `mesh` was adapted to (what a restart rebuilds it from).
    pub solid_base: Vec<f64>,
    pub mesh: Mesh<D>,
    /// P2+ velocity node map of `mesh`.
    pub nodes: NodeMap,
    /// `velocity[node * D + a]`.
    pub velocity: Vec<f64>,
    /// The Windkessel outlets' `Q` and `P_c` (two per outlet; not on the mesh).
    pub lumped: Vec<f64>,
    /// The P1-discontinuous pressure on `mesh` (`D + 1` values per cell; empty where not known:
    /// the next step's Newton solve then starts from zero pressure).
    pub pressure: Vec<f64>,
}

/// The state of an FSI run after a step (see [`crate::discretize::fsi::FsiState`]).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FsiRestart {
    pub solid_x: Vec<f64>,
    pub solid_f: Vec<[[f64; 3]; 3]>,
    pub solid_v: Vec<f64>,
    /// The fluid velocity of the last step and the solid displacement its adapted mesh was built
    /// for (the mesh is rebuilt from it); `None` while the fluid is at rest.
    pub fluid: Option<FluidRestart>,
    /// The coupling elements' solid cells of the last step's pattern (empty in checkpoints of
    /// earlier builds: the next step then starts its pattern afresh).
    #[serde(default)]
    pub coupling_pattern: CouplingPattern,
    /// The state one step back, for BDF2 (`None`: the next step is an Euler step).
    #[serde(default)]
    pub previous: Option<PreviousRestart>,
    /// The length of the last step (0: unknown).
    #[serde(default)]
    pub dt: f64,
}

/// The state one step back, as saved in a checkpoint.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PreviousRestart {
    pub solid_x: Vec<f64>,
    pub solid_v: Vec<f64>,
    pub fluid: Option<FluidRestart>,
}

/// The fluid velocity of an FSI step on the mesh adapted to `solid_base`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FluidRestart {
    pub solid_base: Vec<f64>,
    pub velocity: Vec<f64>,
    /// The Windkessel outlets' `Q` and `P_c` (absent from checkpoints of runs without them).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lumped: Vec<f64>,
    /// The fluid pressure on the rebuilt mesh (absent from checkpoints of earlier builds).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pressure: Vec<f64>,
}

/// The solid cells in the pattern of each coupling element, carried from step to step while
/// the adapted fluid mesh keeps its topology.
///
/// A coupling element couples its multipliers and the fluid velocity of its cell to the solid
/// displacement of every solid cell its points project into. As the solid deforms, a point near
/// the edge of a solid facet may project into the neighbouring cell, which changes the pattern
/// of the whole system, and with it the split and the LU's ordering and symbolic analysis of the
/// next solve (model problem 4, fine mesh: 8-13 s a step). While the adapted mesh keeps its
/// topology, the pattern keeps every cell an element coupled to since the topology was last new
/// (the extra entries hold zeros): it changes only when a point lands in a cell it never
/// touched. The cells are part of the state (and of checkpoints), so that a resumed run builds
/// the patterns of an uninterrupted one.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CouplingPattern {
    /// Fingerprint of the adapted mesh's topology (its cells' nodes and the fluid cell of each
    /// coupling element): the cells are carried only to a mesh with the same one.
    pub topology: u64,
    /// `(coupling element, solid cell)` pairs, sorted.
    pub cells: Vec<(usize, usize)>,
}

/// The state at `t_n`.
#[derive(Clone, Debug)]
pub struct FsiState<const D: usize> {
    pub time: f64,
    /// Solid total displacement from the reference configuration and pressure (solid numbering).
    pub solid_x: Vec<f64>,
    /// Deformation gradient per solid quadrature point.
    pub solid_f: Vec<Mat3>,
    /// Solid velocity of the last step (solid numbering, zero pressure part).
    pub solid_v: Vec<f64>,
    /// `None`: fluid at rest.
    pub fluid: Option<FluidSnapshot<D>>,
    /// The coupling elements' solid cells of the last step's pattern.
    pub coupling_pattern: CouplingPattern,
    /// The state at `t_{n-1}`, kept by BDF2 steps for the next one (`None` at the start, after an
    /// Euler step and after a cut step: the next step is then an Euler step).
    pub previous: Option<Box<FsiPrevious<D>>>,
    /// The length of the last step (0 at the start).
    pub dt: f64,
}

/// What BDF2 needs of `t_{n-1}`: the solid's total state and velocity and the fluid velocity on
/// its adapted mesh.
#[derive(Clone, Debug)]
pub struct FsiPrevious<const D: usize> {
    pub solid_x: Vec<f64>,
    pub solid_v: Vec<f64>,
    /// `None`: fluid at rest.
    pub fluid: Option<FluidSnapshot<D>>,
}

impl<const D: usize> FsiState<D> {
    /// Everything at rest in the reference configuration at `t = 0`.
    pub fn at_rest(model: &FsiModel<D>) -> Self {
        let n = model.solid.num_dofs();
        FsiState {
            time: 0.0,
            solid_x: vec![0.0; n],
            solid_f: vec![IDENTITY; model.solid.mesh.num_cells() * model.solid.points_per_cell()],
            solid_v: vec![0.0; n],
            fluid: None,
            coupling_pattern: CouplingPattern::default(),
            previous: None,
            dt: 0.0,
        }
    }
}

impl<const D: usize> FsiState<D> {
    /// The state as saved in a checkpoint.
    pub fn to_restart(&self) -> FsiRestart {
        FsiRestart {
            solid_x: self.solid_x.clone(),
            solid_f: self.solid_f.clone(),
            solid_v: self.solid_v.clone(),
            fluid: self.fluid.as_ref().map(FluidSnapshot::to_restart),
            coupling_pattern: self.coupling_pattern.clone(),
            previous: self.previous.as_ref().map(|p| PreviousRestart {
                solid_x: p.solid_x.clone(),
                solid_v: p.solid_v.clone(),
                fluid: p.fluid.as_ref().map(FluidSnapshot::to_restart),
            }),
            dt: self.dt,
        }
    }

    /// The state at `time` from a checkpoint; the fluid's adapted mesh is rebuilt from the solid
    /// position it was made for, which reproduces it exactly (the adaptation is deterministic).
    pub fn from_restart(model: &FsiModel<D>, time: f64, r: &FsiRestart) -> Result<Self, FsiError> {
        let fluid = r.fluid_snapshot(model)?;
        let previous = match &r.previous {
            None => None,
            Some(p) => Some(Box::new(FsiPrevious {
                solid_x: p.solid_x.clone(),
                solid_v: p.solid_v.clone(),
                fluid: p.fluid.as_ref().map(|f| FluidSnapshot::from_restart(model, f)).transpose()?,
            })),
        };
        Ok(FsiState {
            time,
            solid_x: r.solid_x.clone(),
            solid_f: r.solid_f.clone(),
            solid_v: r.solid_v.clone(),
            fluid,
            coupling_pattern: r.coupling_pattern.clone(),
            previous,
            dt: r.dt,
        })
    }
}

impl<const D: usize> FluidSnapshot<D> {
    fn to_restart(&self) -> FluidRestart {
        FluidRestart {
            solid_base: self.solid_base.clone(),
            velocity: self.velocity.clone(),
            lumped: self.lumped.clone(),
            pressure: self.pressure.clone(),
        }
    }

    /// The snapshot of a checkpoint: its adapted mesh rebuilt from the solid position it was
    /// made for, which reproduces it exactly (the adaptation is deterministic).
    fn from_restart(model: &FsiModel<D>, f: &FluidRestart) -> Result<Self, FsiError> {
        let disc = FsiDiscretization::build_with(model, &f.solid_base, &CouplingPattern::default(), Entries::Unassembled)?;
        let vel = &disc.flow.velocity_field();
        if vel.num_dofs() != f.velocity.len() {
            return Err(FsiError::Restart(format!(
                "the checkpoint's fluid velocity has {} values but the rebuilt mesh has {}",
                f.velocity.len(),
                vel.num_dofs()
            )));
        }
        let lumped = disc.layout.len(Block::Windkessel);
        if f.lumped.len() != lumped {
            return Err(FsiError::Restart(format!("the checkpoint has {} Windkessel values but the case has {lumped}", f.lumped.len())));
        }
        let pressure = disc.flow.pressure_field().num_dofs();
        if !f.pressure.is_empty() && f.pressure.len() != pressure {
            return Err(FsiError::Restart(format!(
                "the checkpoint's fluid pressure has {} values but the rebuilt mesh has {pressure}",
                f.pressure.len()
            )));
        }
        Ok(FluidSnapshot {
            solid_base: f.solid_base.clone(),
            mesh: disc.flow.mesh.clone(),
            nodes: vel.nodes.clone(),
            velocity: f.velocity.clone(),
            lumped: f.lumped.clone(),
            pressure: f.pressure.clone(),
        })
    }

    /// The pressure transferred to the cells of `disc` ([`transfer_p1disc`]; fluid pressure
    /// numbering), the initial iterate of the next step's pressure: zero where the snapshot holds
    /// none, and in cells whose centroid lies outside the old mesh (in a hole it had).
    fn pressure_on(&self, disc: &FsiDiscretization<D>) -> Result<Vec<f64>, FsiError> {
        let n = disc.flow.pressure_field().num_dofs();
        if self.pressure.is_empty() {
            return Ok(vec![0.0; n]);
        }
        Ok(transfer_p1disc(&self.mesh, &self.pressure, &disc.flow.mesh, 0.0)?)
    }

    /// Each film of `adapted` at the mouth of its closed gap whose pressure in this snapshot, at
    /// the mouth cell's centroid, is lowest ([`FilmPressure::LowestMouth`]). A mouth whose centroid
    /// lies outside this snapshot's mesh (in the hole of a gap cut off then) has no pressure to
    /// compare; a gap without any, or a snapshot without pressure, leaves its films at the nearest
    /// mouth.
    fn take_lowest_mouths(&self, adapted: &mut Adapted<D>) {
        if self.pressure.is_empty() || adapted.cut_sides.is_empty() {
            return;
        }
        let probe = self.pressure_probe();
        let pressure_at = |cell: usize| probe(&adapted.mesh.vertex_centroid(cell));
        let lowest: Vec<Option<(f64, usize)>> = adapted
            .gap_mouths
            .iter()
            .enumerate()
            .map(|(g, mouths)| {
                let pressures = mouths.iter().filter_map(|&m| Some((pressure_at(m)?, m)));
                let pressures =
                    pressures.inspect(|(p, m)| tracing::trace!("closed gap {g}: mouth at {:?}, pressure {p:.6e}", adapted.mesh.vertex_centroid(*m)));
                let low = pressures.min_by(|a, b| a.0.total_cmp(&b.0));
                if let Some((p, m)) = low {
                    let at = adapted.mesh.vertex_centroid(m);
                    tracing::debug!("closed gap {g}: {} mouths, the lowest pressure {p:.6e} at {at:?}", mouths.len());
                }
                low
            })
            .collect();
        for side in &mut adapted.cut_sides {
            if let Some((_, m)) = side.gap.and_then(|g| lowest[g]) {
                side.mouth = Some(m);
            }
        }
    }

    /// The snapshot's pressure at a point (`None` outside its mesh, or without a pressure).
    pub fn pressure_probe(&self) -> impl Fn(&[f64; D]) -> Option<f64> + '_ {
        let locator = (!self.pressure.is_empty()).then(|| CellLocator::new(&self.mesh));
        move |x| {
            let (old, _) = locator.as_ref()?.locate(&self.mesh, x)?;
            Some(p1disc_value(&self.mesh, &self.pressure, old, x))
        }
    }

    /// The velocity transferred to the velocity nodes of `disc` (fluid numbering, zero pressure).
    ///
    /// With the covered fluid removed, the old mesh has a hole where the solid was (at
    /// `solid_base`); the new nodes in it, which the solid uncovered since, lie within one
    /// step's motion of the solid from the hole's boundary (gamma_s at `solid_base`). Up to one
    /// cell height into the hole, a node takes the old fluid velocity's extension (the nearest
    /// old cell's polynomial: BDF2's history stays smooth in time there); farther in, where a
    /// polynomial's extension is not to be trusted, the solid's velocity `solid_v` (solid
    /// numbering, of the snapshot's time) at the point of the hole's boundary nearest to it,
    /// the velocity of the material that was there; a node outside the old mesh but not on the
    /// solid's side of that boundary is an error. (On the swinging block of
    /// `tests/fsi_thick_solid.rs` the solid's velocity everywhere in the hole left BDF2's error
    /// at dt = 0.025 28 % larger than with the extension.) Without a hole every new node must
    /// lie in the old mesh.
    fn transferred_to(&self, model: &FsiModel<D>, disc: &FsiDiscretization<D>, solid_v: &[f64]) -> Result<Vec<f64>, FsiError> {
        let covered_hole = model.covered_fluid == CoveredFluid::Removed;
        // Cells cut off in closed gaps leave a hole too (the old mesh's boundary `closed_gap`).
        let gap_hole = self.mesh.boundary_facets(CLOSED_GAP).is_ok_and(|f| !f.is_empty());
        let has_hole = covered_hole || gap_hole;
        // gamma_s at `solid_base`, built for the first node that needs it (most steps have none).
        let mut hole: Option<Surface<D>> = None;
        // The contact boundaries at `solid_base` of the contacts between two bodies, likewise.
        let mut contact_boundaries: Option<Vec<(f64, Surface<D>, Surface<D>)>> = None;
        let solid_velocity = |i: usize, x: &[f64; D]| {
            let outside = || AdaptError::Transfer(format!("new node {i} at {x:?} lies outside the old mesh, and not in the solid's place"));
            // In a gap the solid closed on a rigid plane, or between two bodies (within the cut-off
            // of both contact boundaries): the fluid was at rest there.
            if gap_hole {
                if model.closed_gaps.iter().any(|g| matches!(g, ClosedGap::Plane(p) if (0.0..=p.cut_off).contains(&p.distance(x)))) {
                    return Ok([0.0; D]);
                }
                if contact_boundaries.is_none() {
                    let boundaries = model.between_boundaries(&self.solid_base);
                    contact_boundaries =
                        Some(boundaries.map_err(|e| AdaptError::Transfer(format!("the contact boundaries of the old mesh's gap: {e}")))?);
                }
                let near = |s: &Surface<D>, cut_off: f64| s.project(x).is_some_and(|p| p.distance <= cut_off);
                let boundaries = contact_boundaries.as_ref().expect("built above");
                if boundaries.iter().any(|(cut_off, slave, master)| near(slave, *cut_off) && near(master, *cut_off)) {
                    return Ok([0.0; D]);
                }
            }
            if !covered_hole {
                return Err(outside());
            }
            if hole.is_none() {
                hole = Some(model.gamma_s(&self.solid_base).map_err(|e| AdaptError::Transfer(format!("gamma_s of the old mesh's hole: {e}")))?);
            }
            let h = hole.as_ref().expect("built above");
            let sp = h.project(x).ok_or_else(outside)?;
            // In the hole: on the solid's side of gamma_s (its normals point out of the solid).
            let n = h.normal(sp.piece);
            let out_of_solid: f64 = (0..D).map(|d| (x[d] - sp.x[d]) * n[d]).sum();
            if out_of_solid > 1e-3 * sp.distance {
                return Err(outside());
            }
            let (c, xi) = h.solid_point(&sp);
            Ok(model.solid.interpolate(solid_v, c, &xi))
        };
        let extend = if has_hole { 1.0 } else { 0.0 };
        let mut u = vec![0.0; disc.fluid_dofs()];
        let v = transfer_p2plus_or(&self.mesh, &self.nodes, &self.velocity, &disc.flow.velocity_nodes, extend, solid_velocity)?;
        u[disc.flow.velocity_field().range()].copy_from_slice(&v);
        // The Windkessel state is not on the mesh: carried as it is.
        u[disc.layout.range(Block::Windkessel)].copy_from_slice(&self.lumped);
        Ok(u)
    }
}

/// The films on the sides of gamma_f the closed gaps of `adapted` cut off that have a mouth
/// ([`Adapted::cut_sides`]), at the mean of mouth cells' pressures the model's rule says
/// ([`FsiModel::film_weights`]), each the unknown of the cell's pressure at its centroid in
/// `pressure` (the fluid's P1-discontinuous field, whose first unknown of a cell is that value).
fn film_loads<const D: usize>(model: &FsiModel<D>, adapted: &Adapted<D>, pressure: &fdfsi_fem::dofs::Field) -> Vec<FilmLoad<D>> {
    let unknown = |m: usize| pressure.dof(pressure.nodes.cell(m)[0], 0);
    let films: Vec<FilmLoad<D>> = adapted
        .cut_sides
        .iter()
        .map(|side| FilmLoad {
            element: side.facet,
            normal: side.normal,
            pressure: model.film_weights(side).iter().map(|&(m, w)| (unknown(m), w)).collect(),
            squeeze: model.film_squeeze_resistance(side),
        })
        .filter(|film| !film.pressure.is_empty())
        .collect();
    if !adapted.cut_sides.is_empty() {
        let at_one = films.iter().filter(|f| f.pressure.len() == 1).count();
        tracing::debug!("films on {} of the {} sides of gamma_f cut off, {at_one} of them at one mouth", films.len(), adapted.cut_sides.len());
    }
    films
}

/// The connected part of each cell of `mesh` (cells sharing a vertex are connected): the bodies
/// of a solid of several. The parts are numbers to compare, not counted from the first cell.
fn connected_parts<const D: usize>(mesh: &Mesh<D>) -> Vec<usize> {
    let joined = (0..mesh.num_cells()).flat_map(|c| {
        let v = mesh.cell_vertices(c);
        v[1..].iter().map(move |&w| (v[0], w))
    });
    let vertex_part = connected_components(mesh.points.len(), joined);
    (0..mesh.num_cells()).map(|c| vertex_part[mesh.cell_vertices(c)[0]]).collect()
}

/// The coupling elements (one per gamma_f facet) and their quadrature points, point-major flat
/// arrays.
#[derive(Clone, Debug, Default)]
pub struct CouplingElements<const D: usize> {
    /// Fluid cell the velocity trace of each element is taken from.
    pub fluid_cell: Vec<usize>,
    /// Points of element `e`: `point_start[e]..point_start[e + 1]`.
    pub point_start: Vec<usize>,
    pub x: Vec<[f64; D]>,
    /// `ds` (times `r` when axisymmetric) times the rule weight.
    pub weight: Vec<f64>,
    /// Solid cell each point lies in.
    pub solid_cell: Vec<usize>,
    /// Multiplier basis (`D` per point), fluid P2+ basis (`nf`), solid Q2 basis (`ns`).
    pub mu: Vec<f64>,
    pub phi_f: Vec<f64>,
    pub phi_s: Vec<f64>,
    pub nf: usize,
    pub ns: usize,
    /// [`MultiplierSpace::P1DiscontinuousTraceMode`]: the trace function orthogonal to P1 at each
    /// point (`1 - 6s + 6s^2`), and the connected chain of gamma_f each element belongs to;
    /// empty otherwise.
    pub mode: Vec<f64>,
    pub chain: Vec<usize>,
    pub num_chains: usize,
    /// Largest distance of a coupling point from gamma_s.
    pub max_distance: f64,
    /// Largest distance of a coupling point from gamma_s over its facet's diameter (at most
    /// [`COUPLING_REL_TOL`]).
    pub max_relative_distance: f64,
}

impl<const D: usize> CouplingElements<D> {
    pub fn num_elements(&self) -> usize {
        self.fluid_cell.len()
    }
    pub fn num_points(&self) -> usize {
        self.weight.len()
    }
}

/// The multiplier's reference rule on a coupling element: P1 basis values (point-major, `D` per
/// point, node `k` at the facet's vertex `k`), weights, and the reference measure.
fn multiplier_rule<const D: usize>() -> (Vec<f64>, Vec<f64>, f64) {
    if D == 2 {
        let q = quadrature::segment(COUPLING_DEGREE);
        (ReferenceElement::<1>::p1_segment().tabulate(&q.points).values, q.weights, 1.0)
    } else {
        let q = quadrature::triangle(COUPLING_DEGREE);
        (ReferenceElement::<2>::p1_triangle().tabulate(&q.points).values, q.weights, 0.5)
    }
}

fn measure<const D: usize>(p: &[[f64; D]; D]) -> f64 {
    let e = |k: usize, d: usize| p[k][d] - p[0][d];
    if D == 2 {
        (e(1, 0).powi(2) + e(1, 1).powi(2)).sqrt()
    } else {
        let c = [e(1, 1) * e(2, 2) - e(1, 2) * e(2, 1), e(1, 2) * e(2, 0) - e(1, 0) * e(2, 2), e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0)];
        0.5 * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
    }
}

/// What one step's assembly needs besides the unknowns.
pub struct StepInput<'a, const D: usize> {
    /// The fluid problem with `params.inv_dt = a` (the scheme's; `1/dt` for implicit Euler).
    pub fluid: &'a FlowProblem<D>,
    /// `t_{n+1}`.
    pub time: f64,
    /// `a = a0 / dt` of the step's scheme (implicit Euler: `1/dt`; see the module doc).
    pub a: f64,
    /// The fluid history `u*` on the new velocity nodes (fluid numbering; implicit Euler: the
    /// transferred velocity of `t_n`).
    pub u_old: &'a [f64],
    /// Solid total state at `t_n` (solid numbering) and `F_n` per quadrature point.
    pub solid_base: &'a [f64],
    pub solid_f: &'a [Mat3],
    /// `d = u* - u_n` of the solid (solid numbering); `None`: 0 (implicit Euler).
    pub solid_shift: Option<&'a [f64]>,
    /// `d + v* / a` (solid numbering) when the solid has inertia (implicit Euler: `dt v_n`).
    pub solid_target: Option<&'a [f64]>,
}

/// Everything derived from one adapted fluid mesh and one solid position: built once per step,
/// never patched.
pub struct FsiDiscretization<const D: usize> {
    pub surface: Surface<D>,
    pub adapted: Adapted<D>,
    /// Fluid discretisation of the adapted mesh (boundary `gamma_f` tagged).
    pub flow: FlowDiscretization<D>,
    pub coupling: CouplingElements<D>,
    /// The blocks of the system's unknowns.
    pub layout: SystemLayout,
    /// Multiplier dofs fixed to zero (trace-mode multipliers of chains with a fluid Dirichlet
    /// node, see [`MultiplierSpace`]); [`step`] constrains them.
    pub inactive_multiplier_dofs: Vec<usize>,
    /// The multipliers the fluid cannot see, removed from the multiplier space (see
    /// [`multiplier_kernel`]): for each, its support `(P1 multiplier index (e * D + k) * D + a,
    /// value of M z)`, `M` the multiplier mass matrix on gamma_f. Each has one extra unknown
    /// `sigma_j` (after the other multipliers) with the equations `R_lambda += (M z_j) sigma_j`
    /// and `(M z_j) . lambda = 0`: lambda is M-orthogonal to the kernel and the constraints are
    /// tested only with its M-orthogonal complement.
    pub kernel: Vec<Vec<(usize, f64)>>,
    /// The coupling elements' solid cells in the system's pattern.
    pub coupling_pattern: CouplingPattern,
    /// The constraints of the symmetry planes of any normal, the fluid's and the solid's, by the
    /// system's unknowns: every assembly of the system ends with them (after the coupling, which
    /// adds to the velocity and displacement rows).
    pub normal_constraints: NormalConstraints,
    /// The system's sparsity: the whole pattern, this rank's rows, or the number of entries
    /// ([`FsiDiscretization::build_with`]).
    sparsity: Sparsity,
    /// Seconds spent on gamma_s and the adaptation in [`Self::build`].
    pub adapt_seconds: f64,
    /// The loads of the thin films on the sides of gamma_f a closed gap cut off ([`FilmLoad`]).
    pub films: Vec<FilmLoad<D>>,
}

/// The load of a thin film of fluid on a side of a gamma_f facet whose fluid a closed gap cut off
/// ([`fdfsi_fem::adapt::gap::CutSide`]): the traction `t = -p n` on the solid, `n` the facet's
/// normal into the film and `p = sum_k w_k p_k` the film's pressure, a mean of the pressures of
/// kept cells at the gap's mouths, each its value at the cell's centroid (the first of its
/// P1-discontinuous unknowns; one mouth with weight one but for [`FilmPressure::Reynolds`]):
/// `R_s -= int_e t . w ds`, that is `R_s += int_e p n . w ds`, over the facet's coupling points,
/// with its Jacobian `w_k int_e (n . w) ds` in the column of each `p_k` (the coupling element's
/// unknowns include them). Unknowns of the step, not the last step's pressure: lagged by a step,
/// the film's load was an explicit coupling of the leaflet to the fluid at the mouth, whose
/// pressure swung by up to 1e4 Pa from one sub-step to the next as the 3D valve's gap opened
/// (session 47).
#[derive(Clone, Debug, PartialEq)]
pub struct FilmLoad<const D: usize> {
    /// The coupling element (gamma_f facet).
    pub element: usize,
    /// The facet's unit normal into the film.
    pub normal: [f64; D],
    /// The film's pressure, `(unknown, weight)` pairs whose weights sum to one: the unknowns of
    /// mouth cells' pressures at their centroids.
    pub pressure: Vec<(usize, f64)>,
    /// The squeeze resistance `r = 12 mu s` (0: the quasi-static film): the film's pressure
    /// rises by `r v_n`, `v_n` the solid's velocity into the film averaged over the facet,
    /// `v_n = n . (int_e v ds) / |e|` (Reynolds' squeeze term taken at the facet alone: see
    /// [`CutSide::squeeze`]). With `v = a (Delta u - d)` of the step's scheme the load's Jacobian
    /// in the solid's columns is `r a (int_e phi_i n ds) (int_e phi_j n ds) / |e|` (symmetric,
    /// positive semi-definite: a damper on the film's facet).
    pub squeeze: f64,
}

impl<const D: usize> FilmLoad<D> {
    /// The film's pressure `sum_k w_k p_k` at the iterate `x`.
    pub fn pressure_at(&self, x: &[f64]) -> f64 {
        self.pressure.iter().map(|&(k, w)| w * x[k]).sum()
    }
}

/// Where an [`FsiDiscretization`]'s systems are assembled.
enum Sparsity {
    /// The whole system, on every process: its pattern, the positions in it of the fluid's and
    /// the solid's block entries (`flow_map`, `solid_map`), and the values of those blocks,
    /// reused by every assembly.
    Whole { pattern: Pattern, flow_map: Vec<usize>, solid_map: Vec<usize>, block_values: [Mutex<Vec<f64>>; 2] },
    /// This rank's rows of a partitioned assembly.
    Rows(FsiRows),
    /// Nowhere: the whole system's number of entries only ([`Entries::Counted`]).
    Counted(usize),
    /// Nowhere ([`Entries::Unassembled`]).
    Unassembled,
}

/// This rank's part of a partitioned FSI assembly: the [`Partition`] of the unknowns (the fluid
/// velocity's nodes kept whole), the pattern of this rank's rows, and the fluid and the solid
/// cells with an unknown in them, coloured (restrictions of the fluid's and the solid's
/// colourings). The fluid and the solid assemble straight into the rows, the coupling and the
/// kernel of the multiplier space their terms of the held rows.
pub struct FsiRows {
    pub partition: Partition,
    pub pattern: RowPattern,
    fluid_colouring: Colouring,
    solid_colouring: Colouring,
}

/// Assembles a block on `pattern` into `values` (reused from call to call: no allocation after
/// the first) and adds it into `k` at the positions `map`.
fn add_block<E>(
    values: &Mutex<Vec<f64>>,
    pattern: &Pattern,
    map: &[usize],
    k: &mut CscMatrix<'_>,
    assemble: impl FnOnce(&mut CscMatrix<'_>) -> Result<(), E>,
) -> Result<(), E> {
    let mut kb = CscMatrix { pattern, values: values.lock().map(|mut v| std::mem::take(&mut *v)).unwrap_or_default() };
    kb.values.clear();
    kb.values.resize(pattern.nnz(), 0.0);
    let result = assemble(&mut kb);
    if result.is_ok() {
        for (v, &pos) in kb.values.iter().zip(map) {
            k.values[pos] += v;
        }
    }
    if let Ok(mut v) = values.lock() {
        *v = kb.values;
    }
    result
}

/// Positions in `global` of the entries of `local` shifted by `offset` on both indices.
fn position_map(local: &Pattern, global: &Pattern, offset: usize) -> Vec<usize> {
    let mut out = Vec::with_capacity(local.nnz());
    for j in 0..local.n {
        for k in local.col_ptr[j]..local.col_ptr[j + 1] {
            out.push(global.find(local.row_idx[k] + offset, j + offset).expect("block entries are in the global pattern"));
        }
    }
    out
}

/// The coupling elements' solid cells of the pattern: those their points lie in, with the cells
/// of `carried` if the adapted mesh (`mesh`, the elements' fluid cells) has its topology.
fn coupling_pattern<const D: usize>(mesh: &Mesh<D>, coupling: &CouplingElements<D>, carried: &CouplingPattern) -> CouplingPattern {
    let words = std::iter::once(mesh.cell_nodes.len()).chain(mesh.cell_nodes.iter().copied()).chain(coupling.fluid_cell.iter().copied());
    let topology = crate::solve::linear::fnv1a(words.map(|w| w as u64));
    let mut cells: Vec<(usize, usize)> = (0..coupling.num_elements())
        .flat_map(|e| coupling.solid_cell[coupling.point_start[e]..coupling.point_start[e + 1]].iter().map(move |&sc| (e, sc)))
        .collect();
    cells.sort_unstable();
    cells.dedup();
    let own = cells.len();
    let same = carried.topology == topology;
    if same {
        cells.extend_from_slice(&carried.cells);
        cells.sort_unstable();
        cells.dedup();
    }
    tracing::debug!(
        "coupling pattern: {} (element, solid cell) pairs, {own} of this step's points, {} new to the carried ones{}",
        cells.len(),
        cells.len() - if same { carried.cells.len() } else { 0 },
        if same { "" } else { " (the mesh's topology is new)" }
    );
    CouplingPattern { topology, cells }
}

impl<const D: usize> FsiDiscretization<D> {
    /// Adapts the original fluid mesh of `model` to gamma_s at the solid displacement `solid_x`
    /// and builds the monolithic discretisation; its pattern keeps the coupling cells of
    /// `carried` if the adapted mesh has their topology ([`CouplingPattern`]).
    pub fn build(model: &FsiModel<D>, solid_x: &[f64], carried: &CouplingPattern) -> Result<Self, FsiError> {
        Self::build_with(model, solid_x, carried, Entries::Whole)
    }

    /// [`FsiDiscretization::build`] with the matrix `entries` it prepares: the whole pattern,
    /// this rank's rows only for a partitioned assembly ([`FsiRows`]), their number only, or
    /// none. The fluid's own discretisation has its pattern for the whole system only (it is
    /// assembled into it as a block); otherwise it prepares none.
    pub fn build_with(model: &FsiModel<D>, solid_x: &[f64], carried: &CouplingPattern, entries: Entries) -> Result<Self, FsiError> {
        Self::build_after(model, solid_x, carried, entries, None)
    }

    /// [`FsiDiscretization::build_with`] for the step after `last` (the fluid of the step's
    /// start), which chooses the films' mouths where the model's [`FilmPressure`] asks for the
    /// pressure there.
    fn build_after(
        model: &FsiModel<D>,
        solid_x: &[f64],
        carried: &CouplingPattern,
        entries: Entries,
        last: Option<&FluidSnapshot<D>>,
    ) -> Result<Self, FsiError> {
        let clock = Instant::now();
        let surface = model.gamma_s(solid_x)?;
        let adapted = model.covered_fluid.apply(adapt_with(&model.background, &surface, &model.problem.adapt)?, &surface)?;
        let mut adapted = model.cut_off_closed_gaps(adapted, &surface, solid_x)?;
        model.choose_film_mouths(last, &mut adapted);
        let adapt_seconds = clock.elapsed().as_secs_f64();
        if adapted.gamma_f.is_empty() {
            return Err(FsiError::EmptyGammaF(model.problem.surface.clone()));
        }
        let flow_entries = if entries == Entries::Whole { Entries::Whole } else { Entries::Unassembled };
        let flow = FlowDiscretization::build_for(crate::adapt::tag_gamma_f(&adapted), &model.problem.fluid, flow_entries)?;
        let mut coupling = Self::coupling_elements(model, &surface, &adapted.gamma_f, &flow)?;
        let fluid_dofs = flow.num_dofs();
        let solid_dofs = model.solid.num_dofs();
        let ne = coupling.num_elements();
        let vel = &flow.velocity_field();
        let mut inactive_multiplier_dofs = Vec::new();
        // Fluid velocity dofs held by Dirichlet conditions: the trace they leave free decides the
        // trace-mode multipliers and the multiplier kernel.
        let fixed: std::collections::HashSet<usize> = flow.dirichlet_dofs(&model.problem.fluid, 0.0)?.into_iter().map(|(d, _)| d).collect();
        let tangents = flow.normal_constraints().tangents::<D>();
        if model.multiplier == MultiplierSpace::P1DiscontinuousTraceMode {
            if D != 2 {
                return Err(FsiError::Multiplier("the trace-mode multiplier is implemented in 2D only".into()));
            }
            Self::trace_mode(&mut coupling, &adapted.gamma_f);
            // A (chain, component) whose trace has a fluid Dirichlet node has no free trace mode.
            let first = fluid_dofs + solid_dofs + ne * D * D; // the first trace-mode multiplier
            let mut inactive = vec![false; coupling.num_chains * D];
            let nf = coupling.nf;
            for e in 0..ne {
                let pts = coupling.point_start[e]..coupling.point_start[e + 1];
                for (i, &node) in vel.nodes.cell(coupling.fluid_cell[e]).iter().enumerate() {
                    let on_trace = pts.clone().any(|q| coupling.phi_f[q * nf + i].abs() >= ON_TRACE);
                    if on_trace && (0..D).any(|a| tangents.contains_key(&vel.dof(node, a))) {
                        return Err(FsiError::Multiplier(
                            "the trace-mode multiplier where gamma_f meets a symmetry line of inclined normal is not implemented: use p1-discontinuous".into(),
                        ));
                    }
                    for a in 0..D {
                        if on_trace && fixed.contains(&vel.dof(node, a)) {
                            inactive[coupling.chain[e] * D + a] = true;
                        }
                    }
                }
            }
            inactive_multiplier_dofs = (0..inactive.len()).filter(|&k| inactive[k]).map(|k| first + k).collect();
        }
        let kernel = multiplier_kernel(&coupling, &adapted.gamma_f, vel, &fixed, &tangents);
        let layout = SystemLayout::new(&[
            (Block::FluidVelocity, vel.num_dofs()),
            (Block::FluidPressure, flow.pressure_field().num_dofs()),
            (Block::Windkessel, 2 * flow.outlets().len()),
            (Block::SolidDisplacement, model.solid.displacement_field().num_dofs()),
            (Block::SolidPressure, model.solid.layout.num_dofs() - model.solid.displacement_field().num_dofs()),
            (Block::Contact, model.solid.num_contact_dofs()),
            (Block::Multiplier, ne * D * D),
            (Block::TraceModes, coupling.num_chains * D),
            (Block::KernelUnknowns, kernel.len()),
        ]);
        let (os, ol, n) = (layout.offset(Block::SolidDisplacement), layout.offset(Block::Multiplier), layout.num_dofs());
        let normal_constraints = flow.normal_constraints().clone().joined(model.solid.normal_constraints().shifted(os));
        let kernel_first = layout.offset(Block::KernelUnknowns) - ol;
        // Dofs of each coupling element: multiplier, fluid velocity of its cell, solid
        // displacement of every solid cell its points land in (and of the carried ones).
        let sf = model.solid.displacement_field();
        let films = film_loads(model, &adapted, flow.pressure_field());
        let coupling_pattern = coupling_pattern(&flow.mesh, &coupling, carried);
        let mut coupling_dofs: Vec<Vec<usize>> = (0..ne)
            .map(|e| {
                let mut d: Vec<usize> = (0..D * D).map(|k| ol + e * D * D + k).collect();
                if let Some(&ch) = coupling.chain.get(e) {
                    d.extend((0..D).map(|a| ol + ne * D * D + ch * D + a));
                }
                for &node in vel.nodes.cell(coupling.fluid_cell[e]) {
                    d.extend((0..D).map(|a| vel.dof(node, a)));
                }
                let first = coupling_pattern.cells.partition_point(|&(f, _)| f < e);
                let cells = coupling_pattern.cells[first..].iter().take_while(|&&(f, _)| f == e).map(|&(_, sc)| sc);
                for sc in cells {
                    for &node in sf.nodes.cell(sc) {
                        d.extend((0..D).map(|a| os + sf.dof(node, a)));
                    }
                }
                d.sort_unstable();
                d.dedup();
                d
            })
            .collect();
        // A film's pressure unknowns join its element's.
        for film in &films {
            let d = &mut coupling_dofs[film.element];
            for &(k, _) in &film.pressure {
                if let Err(at) = d.binary_search(&k) {
                    d.insert(at, k);
                }
            }
        }
        // The system's "cells", whose unknowns are coupled: the fluid's (its cells and Windkessel
        // outlets), the solid cells, the coupling elements and the kernel's columns (each kernel
        // unknown with its multipliers).
        let (nfc, nsc) = (flow.num_system_cells(), model.solid.num_system_cells());
        let num_cells = nfc + nsc + ne + kernel.len();
        let cell_dofs = |c: usize, buf: &mut Vec<usize>| {
            if c >= nfc + nsc + ne {
                let j = c - nfc - nsc - ne;
                buf.clear();
                buf.extend(kernel[j].iter().map(|&(i, _)| ol + i));
                buf.push(ol + kernel_first + j);
            } else if c < nfc {
                flow.system_cell_dofs(c, buf);
            } else if c < nfc + nsc {
                model.solid.system_cell_dofs(c - nfc, buf);
                buf.iter_mut().for_each(|d| *d += os);
            } else {
                buf.clear();
                buf.extend_from_slice(&coupling_dofs[c - nfc - nsc]);
            }
        };
        let sparsity = match entries {
            Entries::Whole => {
                let pattern = Pattern::from_cells(n, num_cells, cell_dofs);
                let flow_map = position_map(flow.whole_pattern(), &pattern, 0);
                let solid_map = position_map(&model.solid.pattern, &pattern, os);
                Sparsity::Whole { pattern, flow_map, solid_map, block_values: Default::default() }
            }
            Entries::Counted => Sparsity::Counted(Pattern::count_from_cells(n, num_cells, cell_dofs)),
            Entries::Unassembled => Sparsity::Unassembled,
            Entries::Rows(_) if u32::try_from(n).is_err() => return Err(FlowError::TooManyUnknowns(n).into()),
            Entries::Rows(world) => {
                let nodes = Nodes { size: D, end: vel.num_dofs() };
                let partition = Partition::from_cells(n, num_cells, cell_dofs, world, nodes);
                let cells = partition.cells_of_rows(num_cells, cell_dofs);
                let pattern = partition.row_pattern(&cells, cell_dofs);
                let held = |c: usize| cells.binary_search(&c).is_ok();
                let fluid_colouring = flow.colouring.restricted(held);
                let solid_colouring = model.solid.colouring.restricted(|c| held(nfc + c));
                Sparsity::Rows(FsiRows { partition, pattern, fluid_colouring, solid_colouring })
            }
        };
        Ok(FsiDiscretization {
            surface,
            adapted,
            flow,
            coupling,
            layout,
            inactive_multiplier_dofs,
            kernel,
            coupling_pattern,
            normal_constraints,
            sparsity,
            adapt_seconds,
            films,
        })
    }

    /// Fills the trace function orthogonal to P1 (`1 - 6s + 6s^2`, `s = mu_1`) at every coupling
    /// point and the connected chains of gamma_f (facets sharing a vertex), 2D.
    fn trace_mode(c: &mut CouplingElements<D>, gamma_f: &[GammaFacet<D>]) {
        c.mode = (0..c.num_points())
            .map(|q| {
                let s = c.mu[q * D + 1];
                1.0 - 6.0 * s + 6.0 * s * s
            })
            .collect();
        (c.chain, c.num_chains) = connected_pieces(gamma_f);
    }

    /// Locates the quadrature points of every gamma_f facet in its fluid cell (the minus side, or
    /// the plus side where gamma_f lies on the domain boundary or the minus side's cells were
    /// removed) and on the solid.
    fn coupling_elements(
        model: &FsiModel<D>,
        surface: &Surface<D>,
        gamma_f: &[GammaFacet<D>],
        flow: &FlowDiscretization<D>,
    ) -> Result<CouplingElements<D>, FsiError> {
        let (mu_tab, weights, ref_measure) = multiplier_rule::<D>();
        let nq = weights.len();
        let nf = flow.velocity_element.num_dofs();
        let ns = model.solid.element.num_dofs();
        let mut out = CouplingElements { nf, ns, point_start: vec![0], ..Default::default() };
        let mut vals = [0.0; MAX_DOFS];
        let mut grads = [[0.0; D]; MAX_DOFS];
        let formulation = model.problem.fluid.formulation;
        for (e, g) in gamma_f.iter().enumerate() {
            let side = if g.sides[0] != NO_CELL { g.sides[0] } else { g.sides[1] };
            let fc = side.0;
            let cell_vertices: Vec<[f64; D]> = flow.mesh.cell_vertices(fc).iter().map(|&v| flow.mesh.points[v]).collect();
            let corners: [[f64; D]; D] = g.vertices.map(|v| flow.mesh.points[v]);
            let m = measure(&corners);
            let diam = (0..D)
                .flat_map(|i| (0..D).map(move |j| (i, j)))
                .map(|(i, j)| (0..D).map(|d| (corners[i][d] - corners[j][d]).powi(2)).sum::<f64>().sqrt());
            let diam = diam.fold(0.0, f64::max);
            out.fluid_cell.push(fc);
            for q in 0..nq {
                let mu = &mu_tab[q * D..(q + 1) * D];
                let x: [f64; D] = std::array::from_fn(|d| (0..D).map(|k| mu[k] * corners[k][d]).sum());
                let fail = |reason: String| FsiError::Unlocated { facet: e, point: q, x: x.to_vec(), reason };
                let xi_f = simplex_reference_coords(&cell_vertices, &x).ok_or_else(|| fail(format!("degenerate fluid cell {fc}")))?;
                flow.velocity_element.eval_into(&xi_f, &mut vals[..nf], &mut grads[..nf]);
                out.phi_f.extend_from_slice(&vals[..nf]);
                let sp = surface.project(&x).ok_or_else(|| fail("gamma_s is empty".into()))?;
                if sp.distance > COUPLING_REL_TOL * diam {
                    return Err(fail(format!(
                        "{:.3e} from gamma_s, more than {COUPLING_REL_TOL} times the facet size {diam:.3e}: gamma_f and gamma_s disagree; refine the solid or the fluid mesh",
                        sp.distance
                    )));
                }
                out.max_distance = out.max_distance.max(sp.distance);
                out.max_relative_distance = out.max_relative_distance.max(sp.distance / diam);
                let (sc, xi_s) = surface.solid_point(&sp);
                model.solid.element.eval_into(&xi_s, &mut vals[..ns], &mut grads[..ns]);
                out.phi_s.extend_from_slice(&vals[..ns]);
                out.mu.extend_from_slice(mu);
                out.x.push(x);
                out.weight.push(weights[q] * m / ref_measure * formulation.weight(&x));
                out.solid_cell.push(sc);
            }
            out.point_start.push(out.weight.len());
        }
        Ok(out)
    }

    /// Number of unknowns.
    pub fn num_dofs(&self) -> usize {
        self.layout.num_dofs()
    }
    /// Number of fluid unknowns (velocity, pressure and the Windkessel outlets' `Q`, `P_c`): the
    /// fluid is the first part.
    pub fn fluid_dofs(&self) -> usize {
        self.layout.span(Block::FluidVelocity, Block::Windkessel).len()
    }
    /// Number of solid unknowns (displacement, pressure and contact pressures).
    pub fn solid_dofs(&self) -> usize {
        self.layout.span(Block::SolidDisplacement, Block::Contact).len()
    }
    /// Number of multiplier unknowns (with the trace modes and the kernel unknowns).
    pub fn multiplier_dofs(&self) -> usize {
        self.layout.span(Block::Multiplier, Block::KernelUnknowns).len()
    }
    /// First solid dof.
    pub fn solid_offset(&self) -> usize {
        self.layout.offset(Block::SolidDisplacement)
    }
    /// First multiplier dof.
    pub fn multiplier_offset(&self) -> usize {
        self.layout.offset(Block::Multiplier)
    }
    /// Global dof of multiplier component `a` at node `k` of coupling element `e`.
    pub fn multiplier_dof(&self, e: usize, k: usize, a: usize) -> usize {
        self.multiplier_offset() + (e * D + k) * D + a
    }

    /// The multiplier blocks of the coupled system for the block preconditioners
    /// ([`crate::solve::augmented`]): the fluid pressure, and the solid's blocks
    /// ([`MultiplierRole`]) the solid pressure (mixed laws) and the coupling multiplier,
    /// one group per coupling element and component (its `D` nodal values, mass matrix
    /// `int_e mu_k mu_l (r) ds`). The trace modes and the kernel unknowns have no block: they
    /// stay primal.
    pub fn saddle_point_split(&self, model: &FsiModel<D>) -> Result<SaddlePointSplit, FsiError> {
        let mut split = self.flow.saddle_point_split(model.problem.fluid.formulation)?;
        // The primal unknowns: velocity, displacement and the unknowns of no block.
        split.primal_components = 1;
        split.constraint_rows = self.normal_constraints.constraint_rows().collect();
        split.multipliers.extend(model.solid.pressure_block(self.solid_offset())?);
        let c = &self.coupling;
        let mut block = MultiplierBlock { role: MultiplierRole::Coupling, ..MultiplierBlock::new("coupling multiplier") };
        let mut mass = vec![0.0; D * D];
        for e in 0..c.num_elements() {
            mass.iter_mut().for_each(|m| *m = 0.0);
            for q in c.point_start[e]..c.point_start[e + 1] {
                let mu = &c.mu[q * D..(q + 1) * D];
                for k in 0..D {
                    for l in 0..D {
                        mass[k * D + l] += c.weight[q] * mu[k] * mu[l];
                    }
                }
            }
            for a in 0..D {
                let dofs: Vec<usize> = (0..D).map(|k| self.multiplier_dof(e, k, a)).collect();
                block.push_group(&dofs, &mass);
            }
        }
        split.multipliers.push(block);
        Ok(split)
    }

    /// Global dof of component `a` of the trace-mode multiplier of chain `ch`
    /// ([`MultiplierSpace::P1DiscontinuousTraceMode`]).
    pub fn mode_multiplier_dof(&self, ch: usize, a: usize) -> usize {
        self.layout.offset(Block::TraceModes) + ch * D + a
    }

    /// The whole system's pattern; `None` for a partitioned assembly
    /// ([`FsiDiscretization::rows`]) or a discretisation of counted entries.
    pub fn pattern(&self) -> Option<&Pattern> {
        match &self.sparsity {
            Sparsity::Whole { pattern, .. } => Some(pattern),
            Sparsity::Rows(_) | Sparsity::Counted(_) | Sparsity::Unassembled => None,
        }
    }

    /// The whole system's pattern of a discretisation that [`FsiDiscretization::build`] (or
    /// `build_with` and [`Entries::Whole`]) made.
    ///
    /// # Panics
    /// For another one.
    pub fn whole_pattern(&self) -> &Pattern {
        self.pattern().expect("an FSI discretisation built whole (FsiDiscretization::build)")
    }

    /// This rank's part of a partitioned assembly ([`FsiDiscretization::build_with`]).
    pub fn rows(&self) -> Option<&FsiRows> {
        match &self.sparsity {
            Sparsity::Rows(rows) => Some(rows),
            Sparsity::Whole { .. } | Sparsity::Counted(_) | Sparsity::Unassembled => None,
        }
    }

    /// The number of matrix entries: the whole pattern's, or this rank's rows' for a partitioned
    /// assembly; `None` for [`Entries::Unassembled`].
    pub fn nnz(&self) -> Option<usize> {
        match &self.sparsity {
            Sparsity::Whole { pattern, .. } => Some(pattern.nnz()),
            Sparsity::Rows(rows) => Some(rows.pattern.nnz()),
            Sparsity::Counted(nnz) => Some(*nnz),
            Sparsity::Unassembled => None,
        }
    }

    /// Assembles the Jacobian `k` and `rhs = -R(x)` of the coupled problem; rows of constrained
    /// dofs become identity rows with zero right-hand side, and the rows of the nodes on
    /// symmetry planes of any normal the tangential equations and constraint rows of
    /// [`NormalConstraints`] (after the coupling terms). The fluid and the solid are
    /// assembled as blocks on their own patterns and added into `k`.
    ///
    /// # Panics
    /// If this discretisation is not whole ([`FsiDiscretization::whole_pattern`]).
    pub fn assemble(
        &self,
        model: &FsiModel<D>,
        input: &StepInput<'_, D>,
        x: &[f64],
        constrained: &[bool],
        k: &mut CscMatrix<'_>,
        rhs: &mut [f64],
    ) -> Result<(), FsiAssemblyError> {
        let Sparsity::Whole { flow_map, solid_map, block_values, .. } = &self.sparsity else {
            panic!("FsiDiscretization::assemble of a discretisation not built whole");
        };
        let (os, ol) = (self.solid_offset(), self.multiplier_offset());
        self.normal_constraints.check_free(constrained);
        add_block(&block_values[0], self.flow.whole_pattern(), flow_map, k, |kb| {
            self.add_fluid(input, x, constrained, &self.flow.colouring, &mut WholeSystem { k: kb, rhs: &mut rhs[..os] })
        })?;
        add_block(&block_values[1], &model.solid.pattern, solid_map, k, |kb| {
            self.add_solid(model, input, x, constrained, &model.solid.colouring, &mut WholeSystem { k: kb, rhs: &mut rhs[os..ol] })
        })?;
        let target = &mut WholeSystem { k, rhs };
        self.add_coupling(model, input, x, constrained, target);
        self.normal_constraints.apply(target);
        Ok(())
    }

    /// [`FsiDiscretization::assemble`] into this rank's rows of a partitioned assembly (`k` on
    /// [`FsiRows::pattern`], `rhs` of the rows, in the partition's numbering; `x` and
    /// `constrained` of all unknowns): those rows of that assembly, bit for bit.
    ///
    /// # Panics
    /// If this discretisation is not partitioned ([`FsiDiscretization::rows`] is `None`).
    pub fn assemble_rows(
        &self,
        model: &FsiModel<D>,
        input: &StepInput<'_, D>,
        x: &[f64],
        constrained: &[bool],
        k: &mut RowMatrix<'_>,
        rhs: &mut [f64],
    ) -> Result<(), FsiAssemblyError> {
        let part = self.rows().expect("assemble_rows of a partitioned discretisation");
        let (numbering, os) = (part.partition.numbering(), self.solid_offset());
        let of_system = |d: usize| numbering.to_petsc(d);
        let of_solid = |d: usize| numbering.to_petsc(os + d);
        // SAFETY (the three targets): the partition's numbering is a permutation of the unknowns,
        // and the solid's unknowns are those after `os`.
        self.add_fluid(input, x, constrained, &part.fluid_colouring, &mut unsafe { HeldRows::new(k, rhs, &of_system) })?;
        self.add_solid(model, input, x, constrained, &part.solid_colouring, &mut unsafe { HeldRows::new(k, rhs, &of_solid) })?;
        self.normal_constraints.check_free(constrained);
        let target = &mut unsafe { HeldRows::new(k, rhs, &of_system) };
        self.add_coupling(model, input, x, constrained, target);
        // The rows of a node are held together: the partition keeps the fluid velocity's nodes
        // whole, and `HeldRows` checks the solid's.
        self.normal_constraints.apply(target);
        Ok(())
    }

    /// The residual `R(x)` with no row constrained and none combined (the symmetry planes'
    /// nodes' rows as assembled): all of it, on every process (no matrix).
    pub fn residual(&self, model: &FsiModel<D>, input: &StepInput<'_, D>, x: &[f64]) -> Result<Vec<f64>, FsiAssemblyError> {
        let (os, ol) = (self.solid_offset(), self.multiplier_offset());
        let mut rhs = vec![0.0; self.num_dofs()];
        let free = vec![false; self.num_dofs()];
        self.add_fluid(input, x, &free, &self.flow.colouring, &mut ResidualOnly { rhs: &mut rhs[..os] })?;
        self.add_solid(model, input, x, &free, &model.solid.colouring, &mut ResidualOnly { rhs: &mut rhs[os..ol] })?;
        self.add_coupling(model, input, x, &free, &mut ResidualOnly { rhs: &mut rhs });
        rhs.iter_mut().for_each(|v| *v = -*v);
        Ok(rhs)
    }

    /// The fluid's part of the system, from the fluid cells of `colouring`, into `target` (by
    /// fluid unknowns, the first of the system's).
    fn add_fluid(
        &self,
        input: &StepInput<'_, D>,
        x: &[f64],
        constrained: &[bool],
        colouring: &Colouring,
        target: &mut impl SystemTarget,
    ) -> Result<(), FsiAssemblyError> {
        let os = self.solid_offset();
        Ok(self.flow.assemble_into(input.fluid, &x[..os], input.u_old, input.time, &constrained[..os], colouring, target)?)
    }

    /// The solid's part of the system (updated Lagrangian: the increment from `X + u_n`, `F_n`
    /// per point), from the solid cells of `colouring`, into `target` (by solid unknowns).
    fn add_solid(
        &self,
        model: &FsiModel<D>,
        input: &StepInput<'_, D>,
        x: &[f64],
        constrained: &[bool],
        colouring: &Colouring,
        target: &mut impl SystemTarget,
    ) -> Result<(), FsiAssemblyError> {
        let (os, ol) = (self.solid_offset(), self.multiplier_offset());
        let solid = &model.problem.solid;
        let inertia = input.solid_target.filter(|_| solid.has_inertia()).map(|t| (input.a * input.a, t));
        let (base, f) = (Some(input.solid_base), Some(input.solid_f));
        Ok(model.solid.assemble_into(solid, input.time, base, f, inertia, &x[os..ol], &constrained[os..ol], colouring, target)?)
    }

    /// The coupling terms (every coupling point), the kernel of the multiplier space (see
    /// [`FsiDiscretization::kernel`]) and the identity rows of the constrained multipliers, into
    /// `target` (by the system's unknowns).
    fn add_coupling(&self, model: &FsiModel<D>, input: &StepInput<'_, D>, x: &[f64], constrained: &[bool], target: &mut impl SystemTarget) {
        let (os, ol) = (self.solid_offset(), self.multiplier_offset());
        let c = &self.coupling;
        let with_mode = !c.mode.is_empty();
        let (nm, nf, ns) = (D + usize::from(with_mode), c.nf, c.ns);
        let nloc = (nm + nf + ns) * D;
        let mut mu = [0.0; 4];
        let mut ke = vec![0.0; nloc * nloc];
        let mut re = vec![0.0; nloc];
        let mut dofs = vec![0usize; nloc];
        let mut loc = vec![0.0; nloc];
        let vel = &self.flow.velocity_field();
        let sf = model.solid.displacement_field();
        let inv_dt = input.a;
        for e in 0..c.num_elements() {
            for kk in 0..D {
                for a in 0..D {
                    dofs[kk * D + a] = self.multiplier_dof(e, kk, a);
                }
            }
            if with_mode {
                for a in 0..D {
                    dofs[D * D + a] = self.mode_multiplier_dof(c.chain[e], a);
                }
            }
            for (i, &node) in vel.nodes.cell(c.fluid_cell[e]).iter().enumerate() {
                for a in 0..D {
                    dofs[(nm + i) * D + a] = vel.dof(node, a);
                }
            }
            for q in c.point_start[e]..c.point_start[e + 1] {
                for (i, &node) in sf.nodes.cell(c.solid_cell[q]).iter().enumerate() {
                    for a in 0..D {
                        dofs[(nm + nf + i) * D + a] = os + sf.dof(node, a);
                    }
                }
                for i in 0..nloc {
                    loc[i] = x[dofs[i]];
                }
                // The solid velocity a (Delta u - d): the coupling kernel sees Delta u - d.
                if let Some(d) = input.solid_shift {
                    for i in (nm + nf) * D..nloc {
                        loc[i] -= d[dofs[i] - os];
                    }
                }
                ke.iter_mut().for_each(|v| *v = 0.0);
                re.iter_mut().for_each(|v| *v = 0.0);
                mu[..D].copy_from_slice(&c.mu[q * D..(q + 1) * D]);
                if with_mode {
                    mu[D] = c.mode[q];
                }
                let pt = CouplingPoint {
                    weight: c.weight[q],
                    mu: &mu[..nm],
                    phi_f: &c.phi_f[q * nf..(q + 1) * nf],
                    phi_s: &c.phi_s[q * ns..(q + 1) * ns],
                };
                let state = CouplingState { lambda: &loc[..nm * D], u_f: &loc[nm * D..(nm + nf) * D], du_s: &loc[(nm + nf) * D..] };
                coupling_point::<D>(&pt, inv_dt, &state, &mut ke, &mut re);
                for i in 0..nloc {
                    let row = dofs[i];
                    if constrained[row] || !target.holds(row) {
                        continue;
                    }
                    target.add_rhs(row, -re[i]);
                    for j in 0..nloc {
                        let v = ke[i * nloc + j];
                        if v != 0.0 {
                            target.add_matrix(row, dofs[j], v);
                        }
                    }
                }
            }
        }
        // The films' loads on the solid: `R_s += int p n . w ds`, linear in the mouths' `p_k`
        // and, with the squeeze, in the solid's velocity on the facet.
        let mut squeeze_columns = Vec::new();
        for film in &self.films {
            let e = film.element;
            let p = self.film_pressure(model, film, x, input.a, input.solid_shift, &mut squeeze_columns);
            // The squeeze's damper `r a g_i g_j / |e|`, `g = int_e phi n ds`, by each dof once.
            if !squeeze_columns.is_empty() {
                let scale = film.squeeze * input.a / self.film_area(film);
                for &(row, gi) in &squeeze_columns {
                    if constrained[row] || !target.holds(row) {
                        continue;
                    }
                    for &(col, gj) in &squeeze_columns {
                        target.add_matrix(row, col, scale * gi * gj);
                    }
                }
            }
            for q in c.point_start[e]..c.point_start[e + 1] {
                for (i, &node) in sf.nodes.cell(c.solid_cell[q]).iter().enumerate() {
                    for a in 0..D {
                        let row = os + sf.dof(node, a);
                        if !constrained[row] && target.holds(row) {
                            let v = c.weight[q] * c.phi_s[q * ns + i] * film.normal[a];
                            target.add_rhs(row, -v * p);
                            for &(k, w) in &film.pressure {
                                target.add_matrix(row, k, v * w);
                            }
                        }
                    }
                }
            }
        }
        // The kernel of the multiplier space (see `kernel`).
        let first = self.kernel_dof(0);
        for (j, y) in self.kernel.iter().enumerate() {
            let sj = first + j;
            let mut r = 0.0;
            for &(i, v) in y {
                let li = ol + i;
                r += v * x[li];
                target.add_rhs(li, -(v * x[sj]));
                target.add_matrix(li, sj, v);
                target.add_matrix(sj, li, v);
            }
            target.add_rhs(sj, -r);
        }
        for (dof, _) in constrained.iter().enumerate().skip(ol).filter(|(_, &cn)| cn) {
            target.identity_row(dof);
        }
    }

    /// Solves the step's `R(x) = 0` by Newton from `x` (constrained unknowns `constrained`):
    /// with `solver` on the whole system, or, for a partitioned assembly, through its
    /// [`crate::solve::partition::RowSolver`] on this rank's rows ([`newton::solve_rows`]).
    pub fn solve_newton(
        &self,
        model: &FsiModel<D>,
        input: &StepInput<'_, D>,
        x: &mut [f64],
        constrained: &[bool],
        solver: &mut dyn LinearSolver,
        options: &NewtonOptions,
    ) -> Result<NewtonReport, NewtonError<FsiAssemblyError>> {
        match &self.sparsity {
            Sparsity::Whole { pattern, .. } => {
                let mut previous: Option<Vec<f64>> = None;
                let mut linearised: Option<Linearisation> = None;
                newton::solve(x, pattern, solver, options, |x, k, rhs| {
                    self.assemble(model, input, x, constrained, k, rhs)?;
                    if tracing::enabled!(tracing::Level::TRACE) {
                        if let Some(last) = linearised.take() {
                            self.trace_linearisation(model, input, constrained, last, x, rhs)?;
                        }
                        linearised = Some(Linearisation { x: x.to_vec(), k: k.values.clone(), rhs: rhs.to_vec() });
                    }
                    // The blocks' norms at this module's debug level, or each block's largest
                    // entry alone at trace level of its own target (`FDFSI_LOG=
                    // fdfsi::discretize::fsi::blocks=trace`).
                    if tracing::enabled!(tracing::Level::DEBUG) || tracing::enabled!(target: BLOCKS_TARGET, tracing::Level::TRACE) {
                        if let Some(prev) = &previous {
                            let dx: Vec<f64> = x.iter().zip(prev).map(|(a, b)| a - b).collect();
                            self.trace_blocks(model, "change since the last assembly", &dx);
                        }
                        previous = Some(x.to_vec());
                        self.trace_blocks(model, "residual", rhs);
                    }
                    Ok(())
                })
            }
            Sparsity::Counted(_) | Sparsity::Unassembled => {
                Err(LinearSolveError::Setup("an FSI discretisation without its pattern or rows (Entries::Counted, Unassembled) is not solved".into())
                    .into())
            }
            Sparsity::Rows(part) => {
                let rows = row_solver_of(solver, &part.partition)?;
                newton::solve_rows(x, &part.partition, &part.pattern, rows, options, |x, k, rhs| {
                    self.assemble_rows(model, input, x, constrained, k, rhs)
                })
            }
        }
    }

    /// Logs (at trace level) how well the last Newton iteration's linearisation `last` (its
    /// point `x_0`, matrix `K` and `rhs = -R(x_0)`) predicted the residual at the new point `x`
    /// (`rhs` there), along the update `d = x - x_0`: the Jacobian's error along `d`, `-K d`
    /// against the finite difference `(rhs(x_0 + eps d) - rhs(x_0)) / eps` (one more assembly),
    /// and the whole step's, `rhs(x) - rhs(x_0) + K d`, which adds the nonlinearity's
    /// `O(|d|^2)`. A large first names a Jacobian that is not the residual's derivative; a large
    /// second with a small first, a step too long for the nonlinearity.
    fn trace_linearisation(
        &self,
        model: &FsiModel<D>,
        input: &StepInput<'_, D>,
        constrained: &[bool],
        last: Linearisation,
        x: &[f64],
        rhs: &[f64],
    ) -> Result<(), FsiAssemblyError> {
        let Sparsity::Whole { pattern, .. } = &self.sparsity else { return Ok(()) };
        let d: Vec<f64> = x.iter().zip(&last.x).map(|(a, b)| a - b).collect();
        let k0 = CscMatrix { pattern, values: last.k };
        let mut kd = vec![0.0; d.len()];
        k0.mul_vec(&d, &mut kd);
        let eps = 1e-6;
        let xe: Vec<f64> = last.x.iter().zip(&d).map(|(a, b)| a + eps * b).collect();
        let (mut ke, mut re) = (CscMatrix::zeros(pattern), vec![0.0; d.len()]);
        self.assemble(model, input, &xe, constrained, &mut ke, &mut re)?;
        let jacobian_error: Vec<f64> = (0..d.len()).map(|i| (re[i] - last.rhs[i]) / eps + kd[i]).collect();
        let step_error: Vec<f64> = (0..d.len()).map(|i| rhs[i] - last.rhs[i] + kd[i]).collect();
        self.trace_blocks_at(model, tracing::Level::TRACE, "Jacobian along the update, K d less its finite difference", &jacobian_error);
        self.trace_blocks_at(model, tracing::Level::TRACE, "residual less its linear prediction", &step_error);
        Ok(())
    }

    /// Logs (at debug level) the norm per block of `v` (a residual, an update) and its largest
    /// entry, named: where a Newton solve stalls; with the target [`BLOCKS_TARGET`] at trace
    /// level, each block's largest entry too.
    fn trace_blocks(&self, model: &FsiModel<D>, what: &str, v: &[f64]) {
        self.trace_blocks_at(model, tracing::Level::DEBUG, what, v);
    }

    /// [`Self::trace_blocks`] at `level`.
    fn trace_blocks_at(&self, model: &FsiModel<D>, level: tracing::Level, what: &str, v: &[f64]) {
        let blocks: Vec<String> = self
            .layout
            .blocks()
            .filter(|(_, r)| !r.is_empty())
            .map(|(b, r)| format!("{} {:.3e}", b.name(), v[r].iter().map(|v| v * v).sum::<f64>().sqrt()))
            .collect();
        let largest = |r: std::ops::Range<usize>| r.max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs()));
        let worst = largest(0..v.len()).map_or(String::new(), |i| format!("; largest {:.3e}: {}", v[i], self.describe_unknown(model, i)));
        // Each block's largest entry, named, at trace level of its own target (`FDFSI_LOG=
        // fdfsi::discretize::fsi::blocks=trace`): where a stalled solve's updates are wild.
        if tracing::enabled!(target: BLOCKS_TARGET, tracing::Level::TRACE) {
            for (b, r) in self.layout.blocks().filter(|(_, r)| !r.is_empty()) {
                if let Some(i) = largest(r) {
                    tracing::trace!(target: BLOCKS_TARGET, "{what}: {} largest {:.3e}: {}", b.name(), v[i], self.describe_unknown(model, i));
                }
            }
        }
        if level == tracing::Level::TRACE {
            tracing::trace!("{what}: {}{worst}", blocks.join(", "));
        } else {
            tracing::debug!("{what}: {}{worst}", blocks.join(", "));
        }
    }

    /// `lambda` at coupling point `q` (of element `e`).
    pub fn multiplier_at(&self, x: &[f64], e: usize, q: usize) -> [f64; D] {
        let c = &self.coupling;
        let mu = &c.mu[q * D..(q + 1) * D];
        std::array::from_fn(|a| {
            let mode = if c.mode.is_empty() { 0.0 } else { c.mode[q] * x[self.mode_multiplier_dof(c.chain[e], a)] };
            (0..D).map(|k| mu[k] * x[self.multiplier_dof(e, k, a)]).sum::<f64>() + mode
        })
    }

    /// Global unknown `sigma_j` of the `j`-th removed multiplier mode (see [`Self::kernel`]).
    pub fn kernel_dof(&self, j: usize) -> usize {
        self.layout.offset(Block::KernelUnknowns) + j
    }

    /// What the global unknown `i` is, in words with a position (for error messages): a fluid
    /// velocity component at a node, a fluid pressure dof of a cell, a solid displacement component
    /// at a node (reference position) or a solid pressure dof of a cell, a multiplier component at
    /// a vertex of a gamma_f facet, a trace-mode multiplier, the unknown that removes a
    /// multiplier mode, a Windkessel outlet's flux or capacitor pressure, or a contact pressure.
    /// Components are named `x, y, z`, or `z, r` when axisymmetric.
    pub fn describe_unknown(&self, model: &FsiModel<D>, i: usize) -> String {
        let axes: [&str; 3] = match model.problem.fluid.formulation {
            crate::physics::fluid::Formulation::Axisymmetric => ["z", "r", "?"],
            _ => ["x", "y", "z"],
        };
        let at = |p: &[f64; D]| format!("({})", p.iter().map(|v| format!("{v:.6}")).collect::<Vec<_>>().join(", "));
        let node_and_component = |f: &fdfsi_fem::dofs::Field, i: usize| ((i - f.offset) / f.components, (i - f.offset) % f.components);
        let cell_dof = |f: &fdfsi_fem::dofs::Field, i: usize, side: &str| {
            let (node, _) = node_and_component(f, i);
            format!("{side} pressure dof {} of cell {}", node % f.nodes.per_cell, node / f.nodes.per_cell)
        };
        let Some((block, k)) = self.layout.locate(i) else {
            return format!("out of range (the system has {} unknowns)", self.num_dofs());
        };
        // Field offsets are within the fluid's or the solid's own numbering.
        let solid_i = || i - self.solid_offset();
        match block {
            Block::FluidVelocity => {
                let (node, a) = node_and_component(self.flow.velocity_field(), i);
                format!("the fluid velocity {} at {}", axes[a], at(&self.flow.velocity_nodes[node]))
            }
            Block::FluidPressure => {
                let (node, _) = node_and_component(self.flow.pressure_field(), i);
                let cell = node / self.flow.pressure_field().nodes.per_cell;
                format!("{} (centroid {})", cell_dof(self.flow.pressure_field(), i, "fluid"), at(&self.flow.mesh.vertex_centroid(cell)))
            }
            Block::Windkessel => {
                let what = if k % 2 == 0 { "flux" } else { "capacitor pressure" };
                format!("the {what} of the Windkessel outlet '{}'", self.flow.outlets()[k / 2])
            }
            Block::SolidDisplacement => {
                let (node, a) = node_and_component(model.solid.displacement_field(), solid_i());
                format!("the solid displacement {} at reference position {}", axes[a], at(&model.solid.nodes_x0[node]))
            }
            Block::SolidPressure => cell_dof(model.solid.pressure_field(), solid_i(), "solid"),
            Block::Contact => {
                let surfaces = model.solid.contact_surfaces();
                match surfaces.iter().find(|s| (s.first..s.first + s.nodes.len()).contains(&solid_i())) {
                    Some(s) => {
                        let node = s.nodes[solid_i() - s.first];
                        format!("the contact pressure of contact boundary '{}' at reference position {}", s.boundary, at(&model.solid.nodes_x0[node]))
                    }
                    None => format!("the contact pressure {k}"),
                }
            }
            Block::Multiplier => {
                let (e, v, a) = (k / (D * D), k / D % D, k % D);
                let vertex = self.adapted.gamma_f[e].vertices[v];
                format!("the multiplier {} at vertex {v} of gamma_f facet {e}, {}", axes[a], at(&self.adapted.mesh.points[vertex]))
            }
            Block::TraceModes => format!("the trace-mode multiplier {} of gamma_f chain {}", axes[k % D], k / D),
            Block::KernelUnknowns => match self.kernel.get(k).and_then(|y| y.first()) {
                Some(&(q, _)) => format!("the unknown removing multiplier mode {k} (around gamma_f facet {})", q / (D * D)),
                None => format!("the unknown removing multiplier mode {k}"),
            },
        }
    }

    /// The measure `|e|` of a film's facet (the sum of its coupling points' weights).
    fn film_area(&self, film: &FilmLoad<D>) -> f64 {
        let c = &self.coupling;
        c.weight[c.point_start[film.element]..c.point_start[film.element + 1]].iter().sum()
    }

    /// The pressure of `film` at `x` ([`FilmLoad`]): its mouths' mean `sum_k w_k p_k` and, with
    /// its squeeze, `r v_n`, `v_n = (g . v) / |e|` the solid's velocity `v = a (Delta u - d)`
    /// (`d` the scheme's `shift`, none: 0) into the film averaged over the facet. `columns` is
    /// set to `g`, `int_e phi_j n ds` at each of the solid's displacement unknowns `j` under the
    /// facet (`(unknown, g_j)`, each once, ascending; none without the squeeze): `dp/dx_j = r a
    /// g_j / |e|`.
    pub fn film_pressure(
        &self,
        model: &FsiModel<D>,
        film: &FilmLoad<D>,
        x: &[f64],
        a: f64,
        shift: Option<&[f64]>,
        columns: &mut Vec<(usize, f64)>,
    ) -> f64 {
        columns.clear();
        let p = film.pressure_at(x);
        if film.squeeze == 0.0 {
            return p;
        }
        let (c, sf, os) = (&self.coupling, model.solid.displacement_field(), self.solid_offset());
        for q in c.point_start[film.element]..c.point_start[film.element + 1] {
            for (j, &node) in sf.nodes.cell(c.solid_cell[q]).iter().enumerate() {
                for b in 0..D {
                    columns.push((os + sf.dof(node, b), c.weight[q] * c.phi_s[q * c.ns + j] * film.normal[b]));
                }
            }
        }
        fdfsi_fem::sparse::sum_duplicates(columns);
        let flux: f64 = columns.iter().map(|&(j, g)| g * (x[j] - shift.map_or(0.0, |d| d[j - os]))).sum();
        p + film.squeeze * a * flux / self.film_area(film)
    }

    /// Force of the films on the body at `x`, `int -p n ds` over their facets ([`FilmLoad`],
    /// their squeeze with the step's `a` and `shift`: [`Self::film_pressure`]; axisymmetric:
    /// times `2 pi`).
    pub fn film_force(
        &self,
        model: &FsiModel<D>,
        x: &[f64],
        a: f64,
        shift: Option<&[f64]>,
        formulation: crate::physics::fluid::Formulation,
    ) -> [f64; D] {
        let mut f = [0.0; D];
        let mut columns = Vec::new();
        for film in &self.films {
            let area = self.film_area(film);
            let p = self.film_pressure(model, film, x, a, shift, &mut columns);
            for a in 0..D {
                f[a] -= area * p * film.normal[a];
            }
        }
        f.map(|v| v * formulation.around())
    }

    /// Force of the fluid on the body, `int_gamma_f lambda ds` (axisymmetric: times `2 pi`).
    pub fn multiplier_force(&self, x: &[f64], formulation: crate::physics::fluid::Formulation) -> [f64; D] {
        let c = &self.coupling;
        let mut f = [0.0; D];
        for e in 0..c.num_elements() {
            for q in c.point_start[e]..c.point_start[e + 1] {
                let l = self.multiplier_at(x, e, q);
                for a in 0..D {
                    f[a] += c.weight[q] * l[a];
                }
            }
        }
        f.iter_mut().for_each(|v| *v *= formulation.around());
        f
    }
}

/// The connected pieces of gamma_f (facets sharing a vertex are connected): the piece of each
/// facet, numbered in order of first appearance, and their number.
fn connected_pieces<const D: usize>(gamma_f: &[GammaFacet<D>]) -> (Vec<usize>, usize) {
    // Each facet joined to the first facet seen at each of its vertices.
    let mut owner: std::collections::HashMap<usize, usize> = Default::default();
    let mut joined = Vec::new();
    for (e, g) in gamma_f.iter().enumerate() {
        for &v in &g.vertices {
            joined.push((e, *owner.entry(v).or_insert(e)));
        }
    }
    let piece = connected_components(gamma_f.len(), joined);
    let count = piece.iter().max().map_or(0, |m| m + 1);
    (piece, count)
}

/// A Newton iteration's point, Jacobian values and `-R` there, kept for the next iteration's
/// check of the linearisation ([`FsiDiscretization::trace_linearisation`]).
struct Linearisation {
    x: Vec<f64>,
    k: Vec<f64>,
    rhs: Vec<f64>,
}

/// A coupling point of a gamma_f facet may lie up to this times the facet's diameter from
/// gamma_s; farther, gamma_f and gamma_s disagree (a facet not on gamma_s: an error). The gamma_f
/// rule ([`GAMMA_F_REL_TOL`], 0.1) bounds the distance of a facet's centroid only: on a surface
/// curved both ways (a saddle) the quadrature points of a chord lie farther than its centroid,
/// without bound in their ratio (the 3D valve's leaflet with G = 0.3 MPa at t = 0.039: 0.103
/// times the diameter of a facet of 3.2 mm, its centroid within 0.1). Twice the rule's bound
/// leaves room for those and still refuses a facet across a fold or off gamma_s.
pub const COUPLING_REL_TOL: f64 = 2.0 * GAMMA_F_REL_TOL;

/// The smallest value of a fluid basis function at a coupling point of a gamma_f facet that
/// counts as the function's being on the facet's trace. The points lie on the facet, so the
/// functions of the nodes off it vanish there but for the rounding of the point's reference
/// coordinates, which a sliver cell amplifies: up to 9e-14 in the 3D valve's cells flattened
/// against its plane of coaptation, where, counted as seen, they hid the multipliers that only
/// held fluid-Dirichlet velocities (a null mode of the system with the leaflet in contact).
/// The functions on the trace are of order one at some point of every facet.
const ON_TRACE: f64 = 1e-10;

/// The multipliers the fluid cannot see: the P1-discontinuous `mu` with `<mu, v> = 0` for every
/// free (non-Dirichlet) fluid velocity `v`, returned as `M z` (see
/// [`FsiDiscretization::kernel`]), one vector per mode, each supported on a few facets.
///
/// Pairing P1-discontinuous multipliers with the continuous P2(+) trace leaves such modes: per
/// component they are the cycles of the graph whose nodes are the gamma_f facets (plus one
/// "ground" node) and whose edges are the interior edges of gamma_f (plus its boundary edges
/// whose trace is fluid-Dirichlet in that component, joined to ground). On a mode the nodal
/// values are `+-1/|F|` at the two corners of a facet facing the cycle's edges. In 3D: one mode
/// around every interior vertex of gamma_f and one around every boundary vertex whose two boundary
/// edges are Dirichlet; in 2D: one along a chain whose two ends are Dirichlet (the radial
/// component of an axisymmetric membrane from the axis to the wall). Such a `mu` tests only the
/// solid (`<mu, u_s> = 0`, a constraint the continuous problem does not have) and its multiplier
/// is the solid's reaction to it: lambda oscillates from facet to facet with an amplitude set by
/// the solid's stiffness, while `int lambda` (the modes integrate to zero on every facet) is right.
///
/// Found numerically: per component, the null space of the pairing restricted to the facets of a
/// vertex star (3D) or of a chain (2D); the union is kept linearly independent.
///
/// On a symmetry plane of any normal (`tangents`: the directions a node there may move in,
/// [`NormalConstraints::tangents`]) a node's free velocity is not a set of components, and the
/// components of the multiplier are coupled: a group with such a node is searched for modes of
/// all components at once (the pairing with the node's tangents, the other nodes' free
/// components), after the groups of plain nodes, against the union of every mode found. The
/// null space is then covariant with a rotation of the problem, as the modes of a plane normal
/// to an axis (a Dirichlet component) are.
pub fn multiplier_kernel<const D: usize>(
    c: &CouplingElements<D>,
    gamma_f: &[GammaFacet<D>],
    vel: &fdfsi_fem::dofs::Field,
    fixed: &std::collections::HashSet<usize>,
    tangents: &std::collections::HashMap<usize, Vec<[f64; D]>>,
) -> Vec<Vec<(usize, f64)>> {
    let ne = c.num_elements();
    let nf = c.nf;
    let area: Vec<f64> = (0..ne).map(|e| (c.point_start[e]..c.point_start[e + 1]).map(|q| c.weight[q]).sum()).collect();
    // Groups of facets: vertex stars (3D), connected chains (2D).
    let mut groups: Vec<Vec<usize>> = Vec::new();
    if D == 3 {
        let mut star: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
        for (e, g) in gamma_f.iter().enumerate() {
            for &v in &g.vertices {
                star.entry(v).or_default().push(e);
            }
        }
        groups.extend(star.into_values());
    } else {
        let (piece, count) = connected_pieces(gamma_f);
        let mut by_piece = vec![Vec::new(); count];
        for (e, &k) in piece.iter().enumerate() {
            by_piece[k].push(e);
        }
        groups.extend(by_piece);
    }
    // The tangents of velocity node `node`, if it is on a symmetry plane of any normal.
    let node_tangents = |node: usize| (0..D).find_map(|a| tangents.get(&vel.dof(node, a)));
    // The directions node `node` may move in: its tangents, or its free components.
    let unit = |a: usize| std::array::from_fn::<f64, D, _>(|b| if a == b { 1.0 } else { 0.0 });
    let directions =
        |node: usize| node_tangents(node).cloned().unwrap_or_else(|| (0..D).filter(|&a| !fixed.contains(&vel.dof(node, a))).map(unit).collect());
    // The groups whose points see a node on such a plane.
    let coupled: Vec<bool> = groups
        .iter()
        .map(|group| {
            group.iter().any(|&e| {
                let cell = vel.nodes.cell(c.fluid_cell[e]);
                let seen =
                    |q: usize| cell.iter().enumerate().any(|(i, &node)| c.phi_f[q * nf + i].abs() >= ON_TRACE && node_tangents(node).is_some());
                (c.point_start[e]..c.point_start[e + 1]).any(seen)
            })
        })
        .collect();
    let mut out = Vec::new();
    // Every accepted mode, dense over all multiplier dofs ((e * D + k) * D + a), for the
    // coupled groups' independence test.
    let mut all: Vec<Vec<f64>> = Vec::new();
    for a in 0..D {
        let plain = groups.iter().zip(&coupled).filter(|(_, &k)| !k).map(|(g, _)| g.as_slice());
        let basis = component_modes(c, vel, fixed, &area, a, plain, &mut out);
        if coupled.contains(&true) {
            all.extend(basis.iter().map(|b| (0..ne * D * D).map(|i| if i % D == a { b[i / D] } else { 0.0 }).collect()));
        }
    }
    for group in groups.iter().zip(&coupled).filter(|(_, &k)| k).map(|(g, _)| g) {
        coupled_modes(c, vel, &area, group, &directions, &mut all, &mut out);
    }
    out
}

/// The modes of all components of [`multiplier_kernel`] on a `group` of facets that sees a node
/// on a symmetry plane of any normal (`directions(node)`: the orthonormal directions the node
/// may move in), independent of `all` (the modes found before, dense over all multipliers,
/// orthonormalised; the new ones join it), pushed to `out` as `M z`.
fn coupled_modes<const D: usize>(
    c: &CouplingElements<D>,
    vel: &fdfsi_fem::dofs::Field,
    area: &[f64],
    group: &[usize],
    directions: &dyn Fn(usize) -> Vec<[f64; D]>,
    all: &mut Vec<Vec<f64>>,
    out: &mut Vec<Vec<(usize, f64)>>,
) {
    let (ne, nf) = (c.num_elements(), c.nf);
    // A free direction's row of the pairing, by (node, direction); columns (gi * D + k) * D + a.
    let mut rows: std::collections::BTreeMap<(usize, usize), Vec<f64>> = Default::default();
    let ncol = group.len() * D * D;
    for (gi, &e) in group.iter().enumerate() {
        let cell = vel.nodes.cell(c.fluid_cell[e]);
        for q in c.point_start[e]..c.point_start[e + 1] {
            for (i, &node) in cell.iter().enumerate() {
                let phi = c.phi_f[q * nf + i];
                if phi.abs() < ON_TRACE {
                    continue;
                }
                for (j, t) in directions(node).iter().enumerate() {
                    let row = rows.entry((node, j)).or_insert_with(|| vec![0.0; ncol]);
                    for k in 0..D {
                        // Columns scaled by 1/|F|, as in `component_modes`.
                        let w = c.weight[q] * c.mu[q * D + k] * phi / area[e];
                        for a in 0..D {
                            row[(gi * D + k) * D + a] += w * t[a];
                        }
                    }
                }
            }
        }
    }
    for mode in null_modes(rows.values(), ncol) {
        let mut z = vec![0.0; ne * D * D];
        for (gi, &e) in group.iter().enumerate() {
            for k in 0..D * D {
                z[e * D * D + k] = mode[gi * D * D + k] / area[e];
            }
        }
        if !independent(&z, all) {
            continue;
        }
        // M z on the support, with z scaled to unit largest value.
        let zmax = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut y = Vec::new();
        for &e in group {
            for k in 0..D {
                for a in 0..D {
                    let v: f64 = (c.point_start[e]..c.point_start[e + 1])
                        .map(|q| c.weight[q] * c.mu[q * D + k] * (0..D).map(|l| c.mu[q * D + l] * z[(e * D + l) * D + a]).sum::<f64>())
                        .sum();
                    if v != 0.0 {
                        y.push(((e * D + k) * D + a, v / zmax));
                    }
                }
            }
        }
        out.push(y);
    }
}

/// The modes of component `a` of [`multiplier_kernel`] on the `groups` of facets (their nodes
/// each free or fixed per component), pushed to `out` as `M z`; returns the accepted modes,
/// orthonormalised, dense over the multipliers of component `a` (`e * D + k`).
fn component_modes<'g, const D: usize>(
    c: &CouplingElements<D>,
    vel: &fdfsi_fem::dofs::Field,
    fixed: &std::collections::HashSet<usize>,
    area: &[f64],
    a: usize,
    groups: impl Iterator<Item = &'g [usize]>,
    out: &mut Vec<Vec<(usize, f64)>>,
) -> Vec<Vec<f64>> {
    let (ne, nf) = (c.num_elements(), c.nf);
    // Accepted modes of this component, orthonormalised densely (for the independence test).
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for group in groups {
        let ncol = group.len() * D;
        let mut rows: std::collections::BTreeMap<usize, Vec<f64>> = Default::default();
        for (gi, &e) in group.iter().enumerate() {
            let cell = vel.nodes.cell(c.fluid_cell[e]);
            for q in c.point_start[e]..c.point_start[e + 1] {
                for (i, &node) in cell.iter().enumerate() {
                    let phi = c.phi_f[q * nf + i];
                    let dof = vel.dof(node, a);
                    if phi.abs() < ON_TRACE || fixed.contains(&dof) {
                        continue;
                    }
                    let row = rows.entry(dof).or_insert_with(|| vec![0.0; ncol]);
                    for k in 0..D {
                        // Columns scaled by 1/|F|: the Gram matrix is independent of the facet sizes.
                        row[gi * D + k] += c.weight[q] * c.mu[q * D + k] * phi / area[e];
                    }
                }
            }
        }
        for mode in null_modes(rows.values(), ncol) {
            // Nodal values of the mode, dense over the multiplier dofs of component a.
            let mut z = vec![0.0; ne * D];
            for (gi, &e) in group.iter().enumerate() {
                for k in 0..D {
                    z[e * D + k] = mode[gi * D + k] / area[e];
                }
            }
            if !independent(&z, &mut basis) {
                continue; // already spanned (a mode found from another star)
            }
            // M z on the support, with z scaled to unit largest value.
            let zmax = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let mut y = Vec::new();
            for &e in group {
                for k in 0..D {
                    let v: f64 = (c.point_start[e]..c.point_start[e + 1])
                        .map(|q| c.weight[q] * c.mu[q * D + k] * (0..D).map(|l| c.mu[q * D + l] * z[e * D + l]).sum::<f64>())
                        .sum();
                    if v != 0.0 {
                        y.push(((e * D + k) * D + a, v / zmax));
                    }
                }
            }
            out.push(y);
        }
    }
    basis
}

/// The null space of the Gram matrix `sum r r^T` of the `ncol`-long `rows`: its eigenvectors of
/// eigenvalue at most `1e-10` of the largest.
fn null_modes<'r>(rows: impl Iterator<Item = &'r Vec<f64>>, ncol: usize) -> Vec<Vec<f64>> {
    use faer::{Mat, Side};
    let mut g = Mat::<f64>::zeros(ncol, ncol);
    for r in rows {
        for i in 0..ncol {
            for j in 0..ncol {
                g[(i, j)] += r[i] * r[j];
            }
        }
    }
    let Ok(eig) = g.self_adjoint_eigen(Side::Lower) else { return Vec::new() };
    let s = eig.S();
    let max = (0..ncol).map(|i| s[i]).fold(0.0f64, f64::max);
    (0..ncol).filter(|&m| s[m] <= 1e-10 * max).map(|m| (0..ncol).map(|i| eig.U()[(i, m)]).collect()).collect()
}

/// Whether `z` is independent of the orthonormal `basis` (its part outside the span at least
/// `1e-6 |z|`); if so, that part, normalised, joins the basis.
fn independent(z: &[f64], basis: &mut Vec<Vec<f64>>) -> bool {
    let mut r = z.to_vec();
    for b in basis.iter() {
        let d: f64 = b.iter().zip(&r).map(|(x, y)| x * y).sum();
        r.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
    }
    let (nz, nr) = (z.iter().map(|v| v * v).sum::<f64>().sqrt(), r.iter().map(|v| v * v).sum::<f64>().sqrt());
    if nr < 1e-6 * nz {
        return false;
    }
    r.iter_mut().for_each(|v| *v /= nr);
    basis.push(r);
    true
}

/// Wall-clock seconds of the phases of a step.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StepTimings {
    /// gamma_s and the adaptation of the fluid mesh to it.
    pub adapt: f64,
    /// Fluid discretisation, coupling elements, pattern.
    pub build: f64,
    /// The velocities (and the pressure) of the last step moved to the new mesh.
    pub transfer: f64,
    pub newton: f64,
    pub update: f64,
}

/// What one FSI step did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FsiStepReport {
    pub time: f64,
    pub dt: f64,
    pub newton: NewtonReport,
    pub adapt: AdaptStats,
    pub fluid_dofs: usize,
    pub solid_dofs: usize,
    pub multiplier_dofs: usize,
    pub coupling_elements: usize,
    pub coupling_points: usize,
    /// The system's matrix entries: the whole pattern's, or this rank's rows' for a partitioned
    /// assembly.
    pub pattern_nnz: usize,
    /// Largest distance of a coupling point from gamma_s.
    pub max_coupling_distance: f64,
    /// ... over its facet's diameter (at most [`COUPLING_REL_TOL`]).
    pub max_relative_coupling_distance: f64,
    /// `int_gamma_f lambda ds`: the force of the fluid on the body (but for the films').
    pub multiplier_force: Vec<f64>,
    /// The force of the thin films on the sides of gamma_f the closed gaps cut off
    /// ([`FsiDiscretization::film_force`]; zero without them).
    pub film_force: Vec<f64>,
    /// The number of films ([`FilmLoad`]).
    pub films: usize,
    /// Largest nodal displacement increment of the solid.
    pub max_solid_increment: f64,
    pub seconds: StepTimings,
}

impl FsiStepReport {
    /// The force of the fluid on the body: the multiplier's and the films'.
    pub fn fluid_force(&self) -> Vec<f64> {
        self.multiplier_force.iter().zip(&self.film_force).map(|(m, f)| m + f).collect()
    }
}

/// A completed step: its discretisation, the converged global vector and the transferred fluid
/// velocity (the history of the step, for consistent residual forces), with the report.
pub struct FsiStep<const D: usize> {
    pub disc: FsiDiscretization<D>,
    pub x: Vec<f64>,
    pub u_old: Vec<f64>,
    /// The fluid problem of the step (`inv_dt = a`, the scheme's; `1/dt` for implicit Euler).
    pub fluid_problem: FlowProblem<D>,
    pub report: FsiStepReport,
}

/// The Newton problem of one step before its solve: the discretisation on the mesh adapted to
/// the solid at `t_n`, the fluid problem with `1/dt`, the transferred velocity, the initial
/// iterate and its constraints. [`step`] solves it; `fdfsi run --export-system` writes its first
/// system.
pub struct StepStart<const D: usize> {
    pub disc: FsiDiscretization<D>,
    /// The solid position (total, solid numbering) the step's mesh is adapted to: `u_n` for
    /// implicit Euler (the paper's: adapt, then solve), the extrapolation
    /// `u_n + omega (u_n - u_{n-1})` for BDF2, so that gamma_f lags the solid by `O(dt^2)`.
    pub geometry: Vec<f64>,
    /// The fluid problem of the step (`inv_dt = a`, the scheme's; `1/dt` for implicit Euler).
    pub fluid: FlowProblem<D>,
    /// `t_{n+1}`.
    pub time: f64,
    pub dt: f64,
    /// The step's scheme: BDF2 when asked for and the state holds `t_{n-1}`.
    pub scheme: TimeScheme,
    /// `a = a0 / dt` of the scheme (see the module doc).
    pub a: f64,
    /// The fluid history `u*` on the new velocity nodes (fluid numbering): the velocity of `t_n`
    /// (and `t_{n-1}`) transferred.
    pub u_old: Vec<f64>,
    /// The initial iterate: `u_old`, the fluid pressure of `t_n` transferred, the Dirichlet
    /// values, the solid pressures of `t_n`, projected onto the symmetry planes of any normal
    /// ([`NormalConstraints::project`]).
    pub x: Vec<f64>,
    /// The constrained unknowns (identity rows of the Jacobian).
    pub constrained: Vec<bool>,
    /// Constrained values, set again after Newton: the linear solves (with iterative
    /// refinement) may leave round-off on them, and a solid end held on an axis must stay
    /// exactly on it.
    fixed: Vec<(usize, f64)>,
    /// The solid's Dirichlet values at `t_{n+1}` (solid numbering, total displacement).
    solid_fixed: Vec<(usize, f64)>,
    /// `d = u* - u_n` of the solid (BDF2 only).
    solid_shift: Option<Vec<f64>>,
    /// `d + v* / a` (solid numbering) when the solid has inertia.
    solid_target: Option<Vec<f64>>,
    seconds: StepTimings,
}

/// The solid extrapolated from `t_{n-1}` and `t_n` to `t_{n+1}`: `x_n + omega (x_n - x_{n-1})`,
/// `omega = dt_{n+1} / dt_n`.
fn extrapolated(x_n: &[f64], x_prev: &[f64], omega: f64) -> Vec<f64> {
    x_n.iter().zip(x_prev).map(|(a, b)| a + omega * (a - b)).collect()
}

/// The solid displacement a step adapts the fluid mesh to ([`StepStart::geometry`]): `x_n`,
/// or with `x_{n-1}` (BDF2) the solid extrapolated to the step's end.
fn step_geometry(x_n: &[f64], x_prev: Option<&[f64]>, omega: f64) -> Vec<f64> {
    match x_prev {
        Some(p) => extrapolated(x_n, p, omega),
        None => x_n.to_vec(),
    }
}

impl FsiRestart {
    /// The fluid of the state, its adapted mesh rebuilt (as [`FsiState::from_restart`] does, without
    /// the state one step back); `None` while the fluid is at rest.
    pub fn fluid_snapshot<const D: usize>(&self, model: &FsiModel<D>) -> Result<Option<FluidSnapshot<D>>, FsiError> {
        self.fluid.as_ref().map(|f| FluidSnapshot::from_restart(model, f)).transpose()
    }

    /// The solid displacement the step of size `dt` from this state adapts the fluid mesh to
    /// (as [`StepStart::with_scheme`] does; `fdfsi adapt --at`).
    pub fn next_geometry(&self, dt: f64, scheme: TimeScheme) -> Vec<f64> {
        let previous = self.previous.as_ref().filter(|_| scheme == TimeScheme::Bdf2);
        step_geometry(&self.solid_x, previous.map(|p| p.solid_x.as_slice()), step_ratio(dt, self.dt))
    }
}

impl<const D: usize> StepStart<D> {
    /// Adapts, discretises and transfers for the implicit-Euler step from `state` (at `t_n`) to
    /// `t_n + dt`.
    pub fn new(model: &FsiModel<D>, state: &FsiState<D>, dt: f64) -> Result<Self, FsiError> {
        Self::with_scheme(model, state, dt, TimeScheme::Euler, Entries::Whole)
    }

    /// [`Self::new`] with the time scheme `scheme` (BDF2 when the state holds `t_{n-1}`, else
    /// implicit Euler) and the matrix `entries` of its discretisation
    /// ([`FsiDiscretization::build_with`]).
    pub fn with_scheme(model: &FsiModel<D>, state: &FsiState<D>, dt: f64, scheme: TimeScheme, entries: Entries) -> Result<Self, FsiError> {
        let previous = state.previous.as_deref().filter(|_| scheme == TimeScheme::Bdf2);
        let scheme = if previous.is_some() { TimeScheme::Bdf2 } else { TimeScheme::Euler };
        let omega = step_ratio(dt, state.dt);
        let geometry = step_geometry(&state.solid_x, previous.map(|p| p.solid_x.as_slice()), omega);
        let clock = Instant::now();
        let disc = FsiDiscretization::build_after(model, &geometry, &state.coupling_pattern, entries, state.fluid.as_ref())?;
        let build = clock.elapsed().as_secs_f64();
        let mut seconds = StepTimings { adapt: disc.adapt_seconds, build: build - disc.adapt_seconds, ..Default::default() };
        let time = state.time + dt;
        // Transfer the velocities of t_n (and t_{n-1}) to the new velocity nodes.
        let clock = Instant::now();
        let (os, ol, n) = (disc.solid_offset(), disc.multiplier_offset(), disc.num_dofs());
        let transferred = |f: Option<&FluidSnapshot<D>>, solid_v: &[f64]| {
            f.map_or_else(|| Ok(disc.flow.initial_state(&model.problem.fluid)), |f| f.transferred_to(model, &disc, solid_v))
        };
        let u_n = transferred(state.fluid.as_ref(), &state.solid_v)?;
        let p_n = state.fluid.as_ref().map(|f| f.pressure_on(&disc)).transpose()?;
        let u_prev = previous.map(|p| transferred(p.fluid.as_ref(), &p.solid_v)).transpose()?;
        let (a, u_old) = step_history(scheme, dt, omega, &u_n, u_prev.as_deref());
        seconds.transfer = clock.elapsed().as_secs_f64();
        let mut fluid = model.problem.fluid.clone();
        fluid.params.inv_dt = a;
        // Initial iterate and constraints.
        let mut x = vec![0.0; n];
        x[..disc.fluid_dofs()].copy_from_slice(&u_n);
        // The last step's pressure: nearer the solution than zero (the pressure loads on the
        // boundaries are balanced from the start).
        if let Some(p) = &p_n {
            x[disc.flow.pressure_field().range()].copy_from_slice(p);
        }
        let nus = model.solid.displacement_field().num_dofs();
        let mut constrained = vec![false; n];
        let mut fixed: Vec<(usize, f64)> = Vec::new();
        for (d, v) in disc.flow.dirichlet_dofs(&fluid, time)? {
            constrained[d] = true;
            x[d] = v;
            fixed.push((d, v));
        }
        for &d in &disc.inactive_multiplier_dofs {
            constrained[d] = true;
        }
        x[os + nus..ol].copy_from_slice(&state.solid_x[nus..]);
        let solid_fixed = model.solid.dirichlet_values(&model.problem.solid, time)?;
        for &(d, v) in &solid_fixed {
            constrained[os + d] = true;
            x[os + d] = if d < nus { v - state.solid_x[d] } else { v };
            fixed.push((os + d, x[os + d]));
        }
        // The transferred velocity (and the solid's increment) onto the symmetry planes.
        disc.normal_constraints.project(&mut x);
        // The solid's history: u* = u_n + d, v*.
        let (_, u_star) = step_history(scheme, dt, omega, &state.solid_x, previous.map(|p| p.solid_x.as_slice()));
        let (_, v_star) = step_history(scheme, dt, omega, &state.solid_v, previous.map(|p| p.solid_v.as_slice()));
        let shift: Vec<f64> = (0..u_star.len()).map(|i| if i < nus { u_star[i] - state.solid_x[i] } else { 0.0 }).collect();
        let solid_target = model.problem.solid.has_inertia().then(|| (0..shift.len()).map(|i| shift[i] + v_star[i] / a).collect());
        let solid_shift = (scheme == TimeScheme::Bdf2).then_some(shift);
        Ok(StepStart { disc, geometry, fluid, time, dt, scheme, a, u_old, x, constrained, fixed, solid_fixed, solid_shift, solid_target, seconds })
    }

    /// What the assembly needs besides the unknowns, `state` being the one given to [`Self::new`].
    pub fn input<'a>(&'a self, state: &'a FsiState<D>) -> StepInput<'a, D> {
        StepInput {
            fluid: &self.fluid,
            time: self.time,
            a: self.a,
            u_old: &self.u_old,
            solid_base: &state.solid_x,
            solid_f: &state.solid_f,
            solid_shift: self.solid_shift.as_deref(),
            solid_target: self.solid_target.as_deref(),
        }
    }
}

/// One implicit-Euler FSI step from `state` (at `t_n`) to `t_n + dt` (see the module
/// documentation); returns the new state and the step.
pub fn step<const D: usize>(
    model: &FsiModel<D>,
    state: &FsiState<D>,
    dt: f64,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
) -> Result<(FsiState<D>, FsiStep<D>), FsiError> {
    step_with(model, state, dt, TimeScheme::Euler, solver, options)
}

/// [`step`] with the time scheme `scheme`: BDF2 when `state` holds `t_{n-1}` (else implicit
/// Euler). A BDF2 run's new state keeps `state` as its `t_{n-1}`.
pub fn step_with<const D: usize>(
    model: &FsiModel<D>,
    state: &FsiState<D>,
    dt: f64,
    scheme: TimeScheme,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
) -> Result<(FsiState<D>, FsiStep<D>), FsiError> {
    // A solver of each rank's rows (PETSc's, under `mpirun` or not, unless it runs the augmented
    // Lagrangian) takes a partitioned assembly: each rank then holds its rows only.
    let entries = solver.as_row_solver().map_or(Entries::Whole, |rows| Entries::Rows(rows.world()));
    let mut start = StepStart::with_scheme(model, state, dt, scheme, entries)?;
    let mut x = std::mem::take(&mut start.x);
    let clock = Instant::now();
    let solved = {
        let (disc, input) = (&start.disc, start.input(state));
        solver.set_split(disc.saddle_point_split(model)?);
        disc.solve_newton(model, &input, &mut x, &start.constrained, solver, options)
    };
    let report = solved.map_err(|e| match e {
        NewtonError::Linear(LinearSolveError::ZeroPivot { unknown, .. }) => {
            FsiError::SingularAt { unknown, what: start.disc.describe_unknown(model, unknown), error: e }
        }
        other => FsiError::Newton(other),
    })?;
    let StepStart { disc, geometry, fluid, time: t_new, a, u_old, fixed, solid_fixed, solid_shift, mut seconds, .. } = start;
    for &(d, v) in &fixed {
        x[d] = v;
    }
    // Likewise on the symmetry planes: the velocity and the solid's increment along them.
    disc.normal_constraints.project(&mut x);
    seconds.newton = clock.elapsed().as_secs_f64();
    // Update the solid (updated Lagrangian) and keep the fluid for the next transfer.
    let clock = Instant::now();
    let (os, ol) = (disc.solid_offset(), disc.multiplier_offset());
    let nus = model.solid.displacement_field().num_dofs();
    let inc = &x[os..ol];
    let mut solid_f = state.solid_f.clone();
    model.solid.update_deformation(&state.solid_x, inc, &mut solid_f).map_err(SolidError::from)?;
    let mut solid_x = state.solid_x.clone();
    for i in 0..nus {
        solid_x[i] += inc[i];
    }
    solid_x[nus..].copy_from_slice(&inc[nus..]);
    for &(d, v) in solid_fixed.iter().filter(|(d, _)| *d < nus) {
        solid_x[d] = v; // exactly the prescribed displacement (u_n + (v - u_n) may round)
    }
    // v_{n+1} = a (Delta u - d).
    let shift = |i: usize| solid_shift.as_ref().map_or(0.0, |d| d[i]);
    let solid_v: Vec<f64> = (0..inc.len()).map(|i| if i < nus { a * (inc[i] - shift(i)) } else { 0.0 }).collect();
    let max_solid_increment = inc[..nus].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let vel = &disc.flow.velocity_field();
    let lumped = x[disc.layout.range(Block::Windkessel)].to_vec();
    let pressure = x[disc.flow.pressure_field().range()].to_vec();
    let snapshot = FluidSnapshot {
        solid_base: geometry,
        mesh: disc.flow.mesh.clone(),
        nodes: vel.nodes.clone(),
        velocity: x[vel.range()].to_vec(),
        lumped,
        pressure,
    };
    seconds.update = clock.elapsed().as_secs_f64();
    let report = FsiStepReport {
        time: t_new,
        dt,
        newton: report,
        adapt: disc.adapted.stats.clone(),
        fluid_dofs: disc.fluid_dofs(),
        solid_dofs: disc.solid_dofs(),
        multiplier_dofs: disc.multiplier_dofs(),
        coupling_elements: disc.coupling.num_elements(),
        coupling_points: disc.coupling.num_points(),
        pattern_nnz: disc.nnz().unwrap_or_default(),
        max_coupling_distance: disc.coupling.max_distance,
        max_relative_coupling_distance: disc.coupling.max_relative_distance,
        multiplier_force: disc.multiplier_force(&x, fluid.formulation).to_vec(),
        film_force: disc.film_force(model, &x, a, solid_shift.as_deref(), fluid.formulation).to_vec(),
        films: disc.films.len(),
        max_solid_increment,
        seconds,
    };
    let coupling_pattern = disc.coupling_pattern.clone();
    let previous = (scheme == TimeScheme::Bdf2)
        .then(|| Box::new(FsiPrevious { solid_x: state.solid_x.clone(), solid_v: state.solid_v.clone(), fluid: state.fluid.clone() }));
    let new_state = FsiState { time: t_new, solid_x, solid_f, solid_v, fluid: Some(snapshot), coupling_pattern, previous, dt };
    Ok((new_state, FsiStep { disc, x, u_old, fluid_problem: fluid, report }))
}

/// Wall shear stress at one point of one side of gamma_f (2D).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct WallShear {
    /// 0: the minus side (the facet normal points out of it), 1: the plus side.
    pub side: usize,
    pub facet: usize,
    pub x: [f64; 2],
    /// Quadrature weight (`ds` times the rule weight).
    pub weight: f64,
    /// `t . (2 eta D(u)) n`, `t` the facet tangent (vertex 0 to vertex 1), `n` the unit normal
    /// pointing into the fluid of that side.
    pub tau: f64,
}

/// Wall shear stress on both sides of every gamma_f facet (2D), from the velocity gradient of the
/// cell on each side, at a Gauss rule of `degree` on each facet. `x` is the fluid vector.
pub fn wall_shear_stress(flow: &FlowDiscretization<2>, x: &[f64], gamma_f: &[GammaFacet<2>], viscosity: f64, degree: usize) -> Vec<WallShear> {
    let rule = quadrature::segment(degree);
    let vel = &flow.velocity_field();
    let nf = flow.velocity_element.num_dofs();
    let mut vals = [0.0; MAX_DOFS];
    let mut grads = [[0.0; 2]; MAX_DOFS];
    let mut out = Vec::new();
    for (e, g) in gamma_f.iter().enumerate() {
        let [p0, p1] = g.vertices.map(|v| flow.mesh.points[v]);
        let len = ((p1[0] - p0[0]).powi(2) + (p1[1] - p0[1]).powi(2)).sqrt();
        let t = [(p1[0] - p0[0]) / len, (p1[1] - p0[1]) / len];
        let n_plus = [t[1], -t[0]];
        for (side, &(c, _)) in g.sides.iter().enumerate() {
            if c == usize::MAX {
                continue;
            }
            let v: Vec<[f64; 2]> = flow.mesh.cell_vertices(c).iter().map(|&k| flow.mesh.points[k]).collect();
            let jac = [[v[1][0] - v[0][0], v[2][0] - v[0][0]], [v[1][1] - v[0][1], v[2][1] - v[0][1]]];
            let (_, inv) = det_inv(&jac);
            let n_in = if side == 0 { [-n_plus[0], -n_plus[1]] } else { n_plus };
            for (q, s) in rule.points.iter().enumerate() {
                let xq = [p0[0] + s[0] * (p1[0] - p0[0]), p0[1] + s[0] * (p1[1] - p0[1])];
                let Some(xi) = simplex_reference_coords(&v, &xq) else { continue };
                flow.velocity_element.eval_into(&xi, &mut vals[..nf], &mut grads[..nf]);
                let mut gu = [[0.0; 2]; 2];
                for (i, &node) in vel.nodes.cell(c).iter().enumerate() {
                    let gx = [grads[i][0] * inv[0][0] + grads[i][1] * inv[1][0], grads[i][0] * inv[0][1] + grads[i][1] * inv[1][1]];
                    for a in 0..2 {
                        let ua = x[vel.dof(node, a)];
                        for b in 0..2 {
                            gu[a][b] += ua * gx[b];
                        }
                    }
                }
                let mut tau = 0.0;
                for a in 0..2 {
                    for b in 0..2 {
                        tau += t[a] * viscosity * (gu[a][b] + gu[b][a]) * n_in[b];
                    }
                }
                out.push(WallShear { side, facet: e, x: xq, weight: rule.weights[q] * len, tau });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A gamma_f facet on a plane where the fluid's y-velocity is held (a leaflet pressed on a
    /// symmetry plane), in a cell whose off-facet basis functions are not exactly zero at the
    /// facet's points (the rounding of a sliver cell's reference coordinates, up to 9e-14 in the
    /// 3D valve): the facet's y-multipliers test no free fluid velocity, so all three are removed.
    #[test]
    fn multipliers_of_a_held_facet_are_removed_despite_rounding_in_its_cell() {
        const D: usize = 3;
        let element = ReferenceElement::<D>::p2plus_tetrahedron();
        let nf = element.num_dofs();
        let on_facet = element.facet_nodes(0); // opposite vertex 0: reference vertices 1, 2, 3
        let (mu_tab, weights, _) = multiplier_rule::<D>();
        let mut c = CouplingElements::<D> { nf, fluid_cell: vec![0], point_start: vec![0], ..Default::default() };
        let (mut vals, mut grads) = ([0.0; MAX_DOFS], [[0.0; D]; MAX_DOFS]);
        for (q, &w) in weights.iter().enumerate() {
            let mu = &mu_tab[q * D..(q + 1) * D];
            let xi = [mu[0], mu[1], mu[2]]; // mu_0 (1,0,0) + mu_1 (0,1,0) + mu_2 (0,0,1)
            element.eval_into(&xi, &mut vals[..nf], &mut grads[..nf]);
            // Rounding that differs from node to node and point to point, as in the valve's
            // cells (rows of full rank: the Gram matrix of the facet's columns is all rounding).
            for (i, v) in vals[..nf].iter_mut().enumerate() {
                if !on_facet.contains(&i) {
                    *v = 1e-14 * (1 + (3 * i + 7 * q) % 9) as f64;
                }
            }
            c.phi_f.extend_from_slice(&vals[..nf]);
            c.mu.extend_from_slice(mu);
            c.weight.push(w);
            c.x.push(xi);
        }
        c.point_start.push(c.weight.len());
        let vel = fdfsi_fem::dofs::Field {
            name: "velocity".into(),
            components: D,
            nodes: NodeMap { num_nodes: nf, per_cell: nf, cell_nodes: (0..nf).collect() },
            offset: 0,
        };
        let at = fdfsi_fem::adapt::surface::SurfacePoint { piece: 0, bary: [1.0, 0.0, 0.0], x: [0.0; D], distance: 0.0 };
        let gamma_f = [GammaFacet { vertices: [1, 2, 3], sides: [(0, 0), NO_CELL], location: [at; D] }];
        let fixed = on_facet.iter().map(|&i| vel.dof(i, 1)).collect();
        let kernel = multiplier_kernel(&c, &gamma_f, &vel, &fixed, &Default::default());
        // Multiplier dofs (e * D + k) * D + a: component a = 1 only, at all three nodes k.
        assert_eq!(kernel.len(), 3, "{kernel:?}");
        assert!(kernel.iter().flatten().all(|&(i, _)| i % D == 1), "{kernel:?}");
    }
}
