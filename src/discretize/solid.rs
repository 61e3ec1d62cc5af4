//! Hyperelastic solids on one Q2 mesh: problem definition, discretisation, quasi-static load
//! stepping (total or updated Lagrangian), a dynamic step (implicit Euler or BDF2 history), and error norms.
//!
//! Data flows one way, as in [`crate::discretize::flow`]: a [`SolidProblem`] (material, boundary conditions)
//! and a reference mesh give a [`SolidDiscretization`] (topology, dof maps, pattern, colouring,
//! the material coordinates of every quadrature point, facet tabulations; built once, never
//! patched); [`solve_quasi_static`] ramps a load factor from 0 to 1 with Newton per increment
//! (kernel [`crate::physics::solid::solid_cell`]) and returns a [`SolidSolution`].
//!
//! Unknowns: the displacement (Q2, `D` components per node, field `"displacement"`), for mixed
//! laws the P1disc pressure (`D + 1` dofs per cell, field `"pressure"`), and after the layout's
//! fields a contact pressure per node of each contact surface ([`ContactSurface`];
//! [`crate::physics::contact`]).
//!
//! * **Total Lagrangian** ([`Lagrangian::Total`]): the unknown is the displacement from the
//!   reference configuration; `F = I + Grad u`.
//! * **Updated Lagrangian** ([`Lagrangian::Updated`]): each increment integrates over the
//!   configuration of the last converged step `x_n = X + u_n`; the unknown is the increment
//!   `Delta u` (`= dt u_s` of the paper's velocity form), `F = (I + grad_n Delta u) F_n` with `F_n`
//!   stored per quadrature point and updated after each converged increment. The two modes solve
//!   the same discrete equations, so they end in the same state to solver tolerance (tested).
//!
//! Boundary conditions, each on a named boundary of the mesh:
//! * [`DisplacementBc`]: prescribed *total* displacement `u(X, load)` for listed components
//!   (the increment is derived from it in updated-Lagrangian mode);
//! * [`DeadTractionBc`]: nominal traction `t_0(X, load)` per unit *reference* area (times `R`
//!   when axisymmetric), independent of the deformation;
//! * [`FollowerPressureBc`]: pressure `p(load)` on the *deformed* surface (traction `-p n`), with
//!   its exact linearisation.
//!
//! Load stepping ([`LoadStepping`]): an increment whose Newton solve fails (no convergence,
//! non-finite residual, singular system, or an inverted element: `det F <= 0` at a quadrature
//! point, reported with the element, point and step) is retried with half the increment, down to
//! `min_increment`.

use super::mortar::{self, Edge, MortarRow};
use super::symmetry::{NormalConstraints, Planarity, SymmetryBc, SymmetryError};
use super::system_cell_dofs;
use crate::physics::contact::{complementarity, complementarity_scale, RigidPlane};
use crate::physics::solid::{
    area_vector, deformation_gradient, follower_pressure_facet, solid_cell, FacetPoint, Formulation, InertiaState, Mat3, SolidCellState,
    SolidMaterial, IDENTITY,
};
use crate::solve::augmented::{MultiplierBlock, MultiplierRole};
use crate::solve::linear::LinearSolver;
use crate::solve::newton::{self, NewtonError, NewtonOptions, NewtonReport};
use fdfsi_fem::dofs::{BlockLayout, NodeMap};
use fdfsi_fem::element::{ElementFamily, ReferenceCell, ReferenceElement, MAX_DOFS};
use fdfsi_fem::mesh::{Mesh, MeshError, Topology};
use fdfsi_fem::quadrature::{self, QuadratureRule};
use fdfsi_fem::sparse::{Colouring, CscMatrix, LocalSystem, Pattern, SystemTarget, WholeSystem};
use fdfsi_fem::values::{CellValues, MapError};
use std::sync::Arc;
use thiserror::Error;

/// A vector field of material position `X` and load factor.
pub type LoadFn<const D: usize> = Arc<dyn Fn(&[f64; D], f64) -> [f64; D] + Send + Sync>;
/// A scalar of the load factor.
pub type ScalarLoadFn = Arc<dyn Fn(f64) -> f64 + Send + Sync>;

/// Total displacement `u(X, load)` prescribed on a named boundary for the listed components.
#[derive(Clone)]
pub struct DisplacementBc<const D: usize> {
    pub boundary: String,
    pub components: Vec<usize>,
    pub value: LoadFn<D>,
}

/// Dead-load nominal traction `t_0(X, load)` per unit reference area on a named boundary.
#[derive(Clone)]
pub struct DeadTractionBc<const D: usize> {
    pub boundary: String,
    pub traction: LoadFn<D>,
}

/// Follower pressure `p(load)` on a named boundary: traction `-p n` on the deformed surface.
#[derive(Clone)]
pub struct FollowerPressureBc {
    pub boundary: String,
    pub pressure: ScalarLoadFn,
}

/// What a contact boundary may touch.
#[derive(Clone, Debug, PartialEq)]
pub enum ContactTarget<const D: usize> {
    /// A rigid plane.
    Plane(RigidPlane<D>),
    /// Another boundary of the solid, the master (2D; [`super::mortar`]): the contact boundary
    /// is the slave, which carries the contact pressures.
    Boundary(String),
}

/// Frictionless contact of the named boundary with a rigid plane or another boundary
/// ([`crate::physics::contact`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ContactBc<const D: usize> {
    pub boundary: String,
    pub target: ContactTarget<D>,
}

impl<const D: usize> ContactBc<D> {
    /// The rigid plane, if the target is one.
    pub fn plane(&self) -> Option<&RigidPlane<D>> {
        match &self.target {
            ContactTarget::Plane(plane) => Some(plane),
            ContactTarget::Boundary(_) => None,
        }
    }
}

/// One body of a solid problem: its material law, density and body force. A problem with
/// several bodies (`[[solid]]` tables: two leaflets) holds them on one mesh of disjoint parts,
/// each cell in one body ([`SolidProblem::cell_body`]).
#[derive(Clone)]
pub struct SolidBody<const D: usize> {
    pub material: Arc<dyn SolidMaterial>,
    /// Reference density `rho_0` for solid inertia ([`solve_dynamic_step`]); 0 (the default of
    /// [`SolidBody::new`]) switches inertia off. Quasi-static solves ignore it.
    pub density: f64,
    /// Body force `b(X, load)` per unit reference volume (e.g. `rho_0 g`): the external work
    /// `int b . w dV_0`.
    pub body_force: Option<LoadFn<D>>,
}

impl<const D: usize> SolidBody<D> {
    /// A body of `material` without inertia or body force.
    pub fn new(material: Arc<dyn SolidMaterial>) -> Self {
        SolidBody { material, density: 0.0, body_force: None }
    }
}

/// A solid problem.
#[derive(Clone)]
pub struct SolidProblem<const D: usize> {
    pub formulation: Formulation,
    /// The bodies (at least one); with one, every cell is in it.
    pub bodies: Vec<SolidBody<D>>,
    /// The body of each cell (an index into `bodies`); empty: every cell in body 0.
    pub cell_body: Vec<usize>,
    pub dirichlet: Vec<DisplacementBc<D>>,
    pub traction: Vec<DeadTractionBc<D>>,
    pub pressure: Vec<FollowerPressureBc>,
    /// Fix the mean-value pressure dof of cell 0 to this value (needed for a mixed law when the
    /// displacement is prescribed on the whole boundary).
    pub pin_pressure: Option<f64>,
    /// Contact with rigid planes and between boundaries, in the order of the discretisation's
    /// contact surfaces ([`SolidDiscretization::build_with_contact`]).
    pub contact: Vec<ContactBc<D>>,
    /// Rollers on planes whose normal is not along a coordinate axis (`u . n = 0`; those along
    /// one are displacement conditions on one component), held by the discretisation's
    /// [`NormalConstraints`] ([`SolidDiscretization::build_for`]).
    pub symmetry: Vec<SymmetryBc<D>>,
}

impl<const D: usize> SolidProblem<D> {
    /// A problem of one body without boundary conditions, pressure pin, inertia or body force.
    pub fn new(formulation: Formulation, material: Arc<dyn SolidMaterial>) -> Self {
        Self::with_bodies(formulation, vec![SolidBody::new(material)], Vec::new())
    }

    /// A problem of several bodies, `cell_body[c]` the body of cell `c` (empty: one body).
    pub fn with_bodies(formulation: Formulation, bodies: Vec<SolidBody<D>>, cell_body: Vec<usize>) -> Self {
        SolidProblem {
            formulation,
            bodies,
            cell_body,
            dirichlet: Vec::new(),
            traction: Vec::new(),
            pressure: Vec::new(),
            pin_pressure: None,
            contact: Vec::new(),
            symmetry: Vec::new(),
        }
    }

    /// The body of cell `c`.
    pub fn body(&self, c: usize) -> &SolidBody<D> {
        &self.bodies[self.cell_body.get(c).copied().unwrap_or(0)]
    }

    /// The material law of body 0 (the only one of a single solid).
    pub fn material(&self) -> &dyn SolidMaterial {
        self.bodies[0].material.as_ref()
    }

    /// Whether any body has inertia (a density > 0).
    pub fn has_inertia(&self) -> bool {
        self.bodies.iter().any(|b| b.density > 0.0)
    }

    /// The material laws' names, joined by `, ` (one per body).
    pub fn material_names(&self) -> String {
        self.bodies.iter().map(|b| b.material.name()).collect::<Vec<_>>().join(", ")
    }
    /// Adds a prescribed displacement.
    pub fn with_displacement(
        mut self,
        boundary: &str,
        components: &[usize],
        value: impl Fn(&[f64; D], f64) -> [f64; D] + Send + Sync + 'static,
    ) -> Self {
        self.dirichlet.push(DisplacementBc { boundary: boundary.into(), components: components.to_vec(), value: Arc::new(value) });
        self
    }
    /// Adds a dead-load traction.
    pub fn with_traction(mut self, boundary: &str, t: impl Fn(&[f64; D], f64) -> [f64; D] + Send + Sync + 'static) -> Self {
        self.traction.push(DeadTractionBc { boundary: boundary.into(), traction: Arc::new(t) });
        self
    }
    /// Adds contact of `boundary` with a rigid plane (the discretisation needs the boundary as a
    /// contact surface: [`SolidDiscretization::build_with_contact`]).
    pub fn with_contact(mut self, boundary: &str, plane: RigidPlane<D>) -> Self {
        self.contact.push(ContactBc { boundary: boundary.into(), target: ContactTarget::Plane(plane) });
        self
    }
    /// Adds contact of `boundary` (the slave) with the boundary `master` of the solid (of the
    /// same body or another)
    /// (2D; [`super::mortar`]).
    pub fn with_contact_against(mut self, boundary: &str, master: &str) -> Self {
        self.contact.push(ContactBc { boundary: boundary.into(), target: ContactTarget::Boundary(master.into()) });
        self
    }
    /// Adds a roller on a plane ([`SymmetryBc`]: `u . n = 0` on its boundary; the discretisation
    /// needs it, [`SolidDiscretization::build_for`]).
    pub fn with_symmetry(mut self, plane: SymmetryBc<D>) -> Self {
        self.symmetry.push(plane);
        self
    }
    /// Adds a follower pressure.
    pub fn with_pressure(mut self, boundary: &str, p: impl Fn(f64) -> f64 + Send + Sync + 'static) -> Self {
        self.pressure.push(FollowerPressureBc { boundary: boundary.into(), pressure: Arc::new(p) });
        self
    }
}

/// An error inside assembly.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SolidAssemblyError {
    #[error("element {cell}: {source}")]
    Map { cell: usize, source: MapError },
    #[error("element {cell} is inverted: det F = {det:.3e} at quadrature point {point}")]
    Inverted { cell: usize, point: usize, det: f64 },
}

/// Errors of a solid solve.
#[derive(Debug, Error)]
pub enum SolidError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("the {formulation:?} formulation does not apply to {dim}D meshes")]
    Formulation { formulation: Formulation, dim: usize },
    #[error("solid meshes must be quadrilaterals (2D) or hexahedra (3D) for Q2 elements, got {0:?}")]
    CellType(ReferenceCell),
    #[error("solid.contact '{boundary}': {source}")]
    ContactBoundary { boundary: String, source: MeshError },
    #[error("solid.contact '{first}' and '{second}' share nodes against the same plane or boundary: give their union as one boundary")]
    ContactOverlap { first: String, second: String },
    #[error("solid.contact '{boundary}': {reason}")]
    ContactPair { boundary: String, reason: String },
    #[error(transparent)]
    Assembly(#[from] SolidAssemblyError),
    #[error(transparent)]
    Newton(#[from] NewtonError<SolidAssemblyError>),
    #[error("the bodies of the solid: {0}")]
    Bodies(String),
    #[error("load step {step} to load factor {load:.6} failed with the smallest increment {increment:.3e}: {reason}; lower stepping.min_increment or refine the mesh")]
    StepFailed { step: usize, load: f64, increment: f64, reason: String },
    #[error("solid: {0}")]
    Symmetry(#[from] SymmetryError),
}

/// Per local facet of the reference cell: the cell basis and its tangential derivatives at the
/// facet quadrature points.
struct FacetTab {
    values: Vec<f64>,
    dphi_t: Vec<[f64; 2]>,
}

/// Everything derived from one solid mesh.
pub struct SolidDiscretization<const D: usize> {
    pub mesh: Mesh<D>,
    pub formulation: Formulation,
    pub topology: Topology,
    /// Q2 displacement element; also the geometry of every configuration (isoparametric).
    pub element: ReferenceElement<D>,
    /// Fields `"displacement"` and, for mixed laws, `"pressure"`.
    pub layout: BlockLayout,
    /// Reference coordinates of the displacement nodes.
    pub nodes_x0: Vec<[f64; D]>,
    pub pattern: Pattern,
    pub colouring: Colouring,
    pub cell_rule: QuadratureRule<D>,
    /// Whether a pressure field is present.
    pub mixed: bool,
    /// Material coordinates of the quadrature points, `qp_x0[c * nq + q]`.
    pub qp_x0: Vec<[f64; D]>,
    /// Reference centroid of each cell.
    pub centroid_x0: Vec<[f64; D]>,
    facet_tabs: Vec<FacetTab>,
    facet_weights: Vec<f64>,
    /// The contact surfaces, whose multipliers follow the layout's unknowns.
    contact: Vec<ContactSurface>,
    /// The contact couplings as cells after the mesh's ([`SolidDiscretization::system_cell_dofs`]).
    contact_cells: Vec<Vec<usize>>,
    /// The rollers of any normal it was built for ([`SolidDiscretization::build_for`]).
    symmetry: Vec<SymmetryBc<D>>,
    /// Their constraints at the displacement nodes on them.
    normal_constraints: NormalConstraints,
}

/// A boundary of the solid that may touch a rigid plane: its nodes, each with a contact
/// multiplier ([`crate::physics::contact`]).
#[derive(Clone, Debug)]
pub struct ContactSurface {
    pub boundary: String,
    /// The displacement nodes on the boundary that carry load, sorted; node `nodes[j]` has the
    /// multiplier `first + j`.
    pub nodes: Vec<usize>,
    /// Their weights `w_j = int psi_j dA_0` on the reference configuration (times `R`
    /// axisymmetric): the row sums of the surface mass matrix.
    pub weights: Vec<f64>,
    pub first: usize,
    /// Against another boundary: the slave's and the master's quadratic edges ([`super::mortar`]).
    pub mortar: Option<MortarEdges>,
}

/// One contact node's row at the current positions: `n`, the weighted gap, the node's weight
/// and the master nodes' (see [`super::mortar`]).
struct ContactRow<const D: usize> {
    normal: [f64; D],
    gap: f64,
    weight: f64,
    master: Vec<(usize, f64)>,
}

/// The edges of a slave contact boundary and of its master, and the master's nodes (sorted).
#[derive(Clone, Debug)]
pub struct MortarEdges {
    pub slave_edges: Vec<Edge>,
    pub master_edges: Vec<Edge>,
    pub master_nodes: Vec<usize>,
}

/// Quadrature degree of the cell integrals (3 Gauss points per direction).
const CELL_DEGREE: usize = 5;

fn q2_element<const D: usize>(cell: ReferenceCell) -> Result<ReferenceElement<D>, SolidError> {
    ReferenceElement::new(cell, ElementFamily::Q2).ok_or(SolidError::CellType(cell))
}

impl<const D: usize> SolidDiscretization<D> {
    /// Builds the discretisation of `mesh` for a material (mixed laws get a pressure field).
    pub fn build(mesh: Mesh<D>, formulation: Formulation, material: &dyn SolidMaterial) -> Result<Self, SolidError> {
        Self::build_with_contact(mesh, formulation, material, &[])
    }

    /// The discretisation of `mesh` for `problem`: its material, and its contact boundaries as
    /// contact surfaces.
    ///
    /// Fails when two contact boundaries against the same plane share a node (its two
    /// conditions would be one: give their union as one boundary), and when the facets of a
    /// roller's boundary are not all normal to its plane ([`super::symmetry::PLANAR_TOLERANCE`],
    /// in the reference configuration).
    pub fn build_for(mesh: Mesh<D>, problem: &SolidProblem<D>) -> Result<Self, SolidError> {
        Self::check_bodies(&mesh, problem)?;
        let mut disc = Self::build_with_contact(mesh, problem.formulation, problem.material(), &problem.contact)?;
        disc.normal_constraints = disc.symmetry_constraints(problem)?;
        disc.symmetry = problem.symmetry.clone();
        for (i, a) in problem.contact.iter().enumerate() {
            for (j, b) in problem.contact.iter().enumerate().skip(i + 1) {
                let shared = disc.contact[i].nodes.iter().any(|n| disc.contact[j].nodes.binary_search(n).is_ok());
                if a.target == b.target && shared {
                    return Err(SolidError::ContactOverlap { first: a.boundary.clone(), second: b.boundary.clone() });
                }
            }
        }
        Ok(disc)
    }

    /// The constraints of the rollers of `problem` at the displacement nodes on them (each with
    /// the normals of its planes), the components its displacement conditions hold left out;
    /// fails on a boundary whose facet normals (at the facet quadrature points, reference
    /// configuration) are not all its plane's.
    fn symmetry_constraints(&self, problem: &SolidProblem<D>) -> Result<NormalConstraints, SolidError> {
        if problem.symmetry.is_empty() {
            return Ok(NormalConstraints::default());
        }
        let held: std::collections::HashSet<usize> = self.dirichlet_values(problem, 0.0)?.into_iter().map(|(d, _)| d).collect();
        let vf = self.displacement_field();
        let nv = self.element.num_dofs();
        let mut normals: std::collections::BTreeMap<usize, Vec<[f64; D]>> = Default::default();
        let mut x_ref = Vec::new();
        for plane in &problem.symmetry {
            let mut planarity = Planarity::new(plane);
            for bf in self.mesh.boundary_facets(&plane.boundary)? {
                self.cell_positions(bf.cell, None, &mut x_ref);
                let tab = &self.facet_tabs[bf.facet];
                for q in 0..self.facet_weights.len() {
                    let pt = FacetPoint { phi: &tab.values[q * nv..(q + 1) * nv], dphi_t: &tab.dphi_t[q * nv..(q + 1) * nv], weight: 1.0 };
                    let area = area_vector(&x_ref, &pt, 1.0);
                    planarity.facet_normal(bf.cell, std::array::from_fn(|a| area[a]));
                }
                let nodes = vf.nodes.cell(bf.cell);
                for k in self.element.facet_nodes(bf.facet) {
                    let list = normals.entry(nodes[k]).or_default();
                    if !list.contains(&plane.normal) {
                        list.push(plane.normal);
                    }
                }
            }
            planarity.finish()?;
        }
        let nodes = normals.into_iter().map(|(node, n)| (std::array::from_fn(|a| vf.dof(node, a)), n));
        Ok(NormalConstraints::new(nodes, |d| held.contains(&d)))
    }

    /// The constraints `u . n = 0` of the rollers of any normal at the displacement nodes on
    /// them ([`SolidDiscretization::build_for`]): the row operations every assembly of the
    /// solid's system ends with (a coupled system: its own, [`NormalConstraints::shifted`]), and
    /// the projection of the state.
    pub fn normal_constraints(&self) -> &NormalConstraints {
        &self.normal_constraints
    }

    /// Checks that `problem`'s rollers are those this discretisation was built for.
    ///
    /// # Panics
    /// If they are not.
    fn check_symmetry(&self, problem: &SolidProblem<D>) {
        assert_eq!(problem.symmetry, self.symmetry, "the problem's symmetry planes are the discretisation's (SolidDiscretization::build_for)");
    }

    /// The bodies of `problem` on `mesh`: at least one, a body for each cell (or none given, with
    /// one body), and all of one kind of law (mixed or displacement-based: the pressure field is
    /// the whole mesh's).
    fn check_bodies(mesh: &Mesh<D>, problem: &SolidProblem<D>) -> Result<(), SolidError> {
        let n = problem.bodies.len();
        if n == 0 {
            return Err(SolidError::Bodies("the problem has no body".into()));
        }
        let cells = &problem.cell_body;
        if cells.is_empty() && n > 1 {
            return Err(SolidError::Bodies(format!("{n} bodies and no body given per cell")));
        }
        if !cells.is_empty() && cells.len() != mesh.num_cells() {
            return Err(SolidError::Bodies(format!("a body is given for {} cells of {}", cells.len(), mesh.num_cells())));
        }
        if let Some(c) = cells.iter().position(|&b| b >= n) {
            return Err(SolidError::Bodies(format!("cell {c} is in body {}, of {n}", cells[c])));
        }
        let mixed = |b: &SolidBody<D>| b.material.pressure_compliance().is_some();
        if let Some(b) = problem.bodies.iter().position(|b| mixed(b) != mixed(&problem.bodies[0])) {
            return Err(SolidError::Bodies(format!(
                "body {b} ({}) and body 0 ({}) are not both mixed (with a pressure field) or both displacement-based",
                problem.bodies[b].material.name(),
                problem.bodies[0].material.name()
            )));
        }
        Ok(())
    }

    /// [`SolidDiscretization::build`] with the boundaries of `contact` (the problem's, in order)
    /// as contact surfaces: a contact multiplier per node of each (but nodes of no weight), after
    /// the layout's unknowns, coupled to its node's displacement (and, against another boundary,
    /// to that boundary's displacements).
    pub fn build_with_contact(
        mesh: Mesh<D>,
        formulation: Formulation,
        material: &dyn SolidMaterial,
        contact: &[ContactBc<D>],
    ) -> Result<Self, SolidError> {
        if (formulation == Formulation::ThreeD) != (D == 3) {
            return Err(SolidError::Formulation { formulation, dim: D });
        }
        mesh.check()?;
        let element = q2_element::<D>(mesh.cell_type)?;
        let topology = Topology::build(&mesh);
        let vmap = NodeMap::continuous(&mesh, &topology, &element);
        let nodes_x0 = vmap.coordinates(&mesh, &element);
        let mixed = material.pressure_compliance().is_some();
        let mut layout = BlockLayout::default();
        layout.push("displacement", D, vmap);
        if mixed {
            layout.push("pressure", 1, NodeMap::discontinuous(mesh.num_cells(), D + 1));
        }
        let pattern = Pattern::from_cells(layout.num_dofs(), mesh.num_cells(), |c, buf| layout.cell_dofs_into(c, buf));
        let colouring = Colouring::greedy(mesh.points.len(), mesh.num_cells(), |c| mesh.cell_vertices(c));
        let cell_rule = fdfsi_fem::quadrature::for_cell::<D>(mesh.cell_type, CELL_DEGREE);
        // Facet rule and tabulations.
        let (facet_points, facet_weights) = quadrature::for_facets(mesh.cell_type, CELL_DEGREE);
        let cell = mesh.cell_type;
        let nv = element.num_dofs();
        let facet_tabs = (0..cell.num_facets())
            .map(|f| {
                let pts: Vec<[f64; D]> = facet_points.iter().map(|eta| cell.facet_point(f, eta)).collect();
                let p0: [f64; D] = cell.facet_point(f, &[0.0, 0.0]);
                let p1: [f64; D] = cell.facet_point(f, &[1.0, 0.0]);
                let p2: [f64; D] = cell.facet_point(f, &[0.0, 1.0]);
                let t1: [f64; D] = std::array::from_fn(|d| p1[d] - p0[d]);
                let t2: [f64; D] = std::array::from_fn(|d| if D == 3 { p2[d] - p0[d] } else { 0.0 });
                let tab = element.tabulate(&pts);
                let dphi_t = tab.grads.iter().map(|g| [(0..D).map(|d| g[d] * t1[d]).sum(), (0..D).map(|d| g[d] * t2[d]).sum()]).collect();
                debug_assert_eq!(tab.values.len(), pts.len() * nv);
                FacetTab { values: tab.values, dphi_t }
            })
            .collect();
        let mut disc = SolidDiscretization {
            mesh,
            formulation,
            topology,
            element,
            layout,
            nodes_x0,
            pattern,
            colouring,
            cell_rule,
            mixed,
            qp_x0: Vec::new(),
            centroid_x0: Vec::new(),
            facet_tabs,
            facet_weights,
            contact: Vec::new(),
            contact_cells: Vec::new(),
            symmetry: Vec::new(),
            normal_constraints: NormalConstraints::default(),
        };
        let mut cv = disc.cell_values();
        let mut coords = Vec::new();
        for c in 0..disc.mesh.num_cells() {
            disc.cell_positions(c, None, &mut coords);
            cv.reinit(&coords).map_err(|source| SolidAssemblyError::Map { cell: c, source })?;
            disc.qp_x0.extend_from_slice(&cv.x);
            disc.centroid_x0.push(cv.centroid);
        }
        if !contact.is_empty() {
            disc.add_contact_surfaces(contact)?;
        }
        Ok(disc)
    }

    /// Makes the boundaries `contact` contact surfaces: a multiplier per node of each (after the
    /// layout's unknowns) and a "cell" per node (its displacement and multiplier) after the mesh's
    /// cells in the pattern. A node of no weight (`w_i = int psi_i dA_0 = 0`: the end of an
    /// axisymmetric surface on the axis, where `R = 0`) carries no load and gets no multiplier.
    fn add_contact_surfaces(&mut self, contact: &[ContactBc<D>]) -> Result<(), SolidError> {
        let mut first = self.layout.num_dofs();
        for bc in contact {
            let name = &bc.boundary;
            let facets = self.mesh.boundary_facets(name).map_err(|source| SolidError::ContactBoundary { boundary: name.clone(), source })?;
            let vf = self.displacement_field();
            let mut nodes: Vec<usize> =
                facets.iter().flat_map(|bf| self.element.facet_nodes(bf.facet).into_iter().map(|k| vf.nodes.cell(bf.cell)[k])).collect();
            nodes.sort_unstable();
            nodes.dedup();
            let weights = self.node_weights(name, &nodes);
            let largest = weights.iter().fold(0.0f64, |m, w| m.max(w.abs()));
            let (nodes, weights): (Vec<usize>, Vec<f64>) = nodes.into_iter().zip(weights).filter(|(_, w)| *w > 1e-12 * largest).unzip();
            let mortar = match &bc.target {
                ContactTarget::Plane(_) => None,
                ContactTarget::Boundary(master) => Some(self.mortar_edges(name, master)?),
            };
            // Each node's cell: its displacement and multiplier (against a boundary, with every
            // master displacement: the node may slide over any part of it).
            let master_dofs: Vec<usize> =
                mortar.iter().flat_map(|m| m.master_nodes.iter().flat_map(|&k| (0..D).map(move |a| vf.dof(k, a)))).collect();
            let cells: Vec<Vec<usize>> = nodes
                .iter()
                .enumerate()
                .map(|(j, &node)| (0..D).map(|a| vf.dof(node, a)).chain([first + j]).chain(master_dofs.iter().copied()).collect())
                .collect();
            self.contact_cells.extend(cells);
            let n = nodes.len();
            self.contact.push(ContactSurface { boundary: name.clone(), nodes, weights, first, mortar });
            first += n;
        }
        let (layout, nc, cells) = (&self.layout, self.mesh.num_cells(), &self.contact_cells);
        self.pattern = Pattern::from_cells(first, nc + cells.len(), |c, buf| system_cell_dofs(layout, nc, cells, c, buf));
        Ok(())
    }

    /// The edges of the slave boundary `slave` and of the master boundary `master` (2D only).
    fn mortar_edges(&self, slave: &str, master: &str) -> Result<MortarEdges, SolidError> {
        let pair = |reason: &str| SolidError::ContactPair { boundary: slave.into(), reason: reason.into() };
        if D != 2 {
            return Err(pair("contact between two boundaries is implemented in 2D (plane and axisymmetric) only"));
        }
        if slave == master {
            return Err(pair("a boundary cannot touch itself: name another boundary in 'against'"));
        }
        let vf = self.displacement_field();
        let node_of = |cell: usize, local: usize| vf.nodes.cell(cell)[local];
        let slave_edges = mortar::boundary_edges(&self.mesh, &self.element, slave, node_of)?;
        let master_edges = mortar::boundary_edges(&self.mesh, &self.element, master, node_of).map_err(|e| match e {
            SolidError::ContactBoundary { source, .. } => pair(&format!("against '{master}': {source}")),
            e => e,
        })?;
        let mut master_nodes: Vec<usize> = master_edges.iter().flat_map(|e| e.nodes).collect();
        master_nodes.sort_unstable();
        master_nodes.dedup();
        if slave_edges.iter().flat_map(|e| e.nodes).any(|n| master_nodes.binary_search(&n).is_ok()) {
            return Err(pair(&format!("the boundary shares nodes with '{master}', the boundary it may touch")));
        }
        Ok(MortarEdges { slave_edges, master_edges, master_nodes })
    }

    /// Number of unknowns: the layout's, then the contact multipliers.
    pub fn num_dofs(&self) -> usize {
        self.layout.num_dofs() + self.contact.iter().map(|s| s.nodes.len()).sum::<usize>()
    }

    /// The system's "cells", whose unknowns are coupled: the mesh's cells, then one per node of
    /// each contact surface (its displacement and contact multiplier).
    pub fn num_system_cells(&self) -> usize {
        self.mesh.num_cells() + self.contact_cells.len()
    }

    /// The unknowns of system cell `c` ([`SolidDiscretization::num_system_cells`]) into `buf`.
    pub fn system_cell_dofs(&self, c: usize, buf: &mut Vec<usize>) {
        system_cell_dofs(&self.layout, self.mesh.num_cells(), &self.contact_cells, c, buf)
    }

    /// The number of contact multipliers (the unknowns after the layout's).
    pub fn num_contact_dofs(&self) -> usize {
        self.num_dofs() - self.layout.num_dofs()
    }

    /// The contact surfaces ([`SolidDiscretization::build_with_contact`]).
    pub fn contact_surfaces(&self) -> &[ContactSurface] {
        &self.contact
    }
    /// Number of quadrature points per cell.
    pub fn points_per_cell(&self) -> usize {
        self.cell_rule.len()
    }
    /// Fresh cell values (Q2 function and geometry) at the cell rule.
    pub fn cell_values(&self) -> CellValues<D> {
        CellValues::new(self.cell_rule.clone(), &self.element, &self.element)
    }
    /// The displacement field.
    pub fn displacement_field(&self) -> &fdfsi_fem::dofs::Field {
        &self.layout.fields[0]
    }

    /// The pressure field (P1 discontinuous; mixed laws only).
    pub fn pressure_field(&self) -> &fdfsi_fem::dofs::Field {
        &self.layout.fields[1]
    }

    /// The pressure as a multiplier block of the block preconditioners
    /// ([`crate::solve::augmented`]): one group per cell, its dofs shifted by `offset` (the
    /// solid's first unknown in a coupled system) and its mass matrix `int_K psi_k psi_l (r) dX`
    /// on the reference cell, `psi = (1, X - X_c)` the kernel's P1disc basis. `None` without a
    /// pressure field.
    pub fn pressure_block(&self, offset: usize) -> Result<Option<MultiplierBlock>, SolidError> {
        if !self.mixed {
            return Ok(None);
        }
        let mut block = MultiplierBlock { role: MultiplierRole::SolidPressure, ..MultiplierBlock::new("solid pressure") };
        let (mut cv, mut coords, mut mass) = (self.cell_values(), Vec::new(), vec![0.0; (D + 1) * (D + 1)]);
        let pf = self.pressure_field();
        for c in 0..self.mesh.num_cells() {
            self.cell_positions(c, None, &mut coords);
            cv.reinit(&coords).map_err(|source| SolidAssemblyError::Map { cell: c, source })?;
            fdfsi_fem::values::p1disc_mass(&cv, |x| self.formulation.weight(x), &mut mass);
            let dofs: Vec<usize> = (0..=D).map(|k| offset + pf.dof(c * (D + 1) + k, 0)).collect();
            block.push_group(&dofs, &mass);
        }
        Ok(Some(block))
    }

    /// Nodal positions of cell `c` in the configuration `X + base` (`base` a global vector whose
    /// displacement part is used; `None` = reference).
    pub fn cell_positions(&self, c: usize, base: Option<&[f64]>, out: &mut Vec<[f64; D]>) {
        let vf = &self.displacement_field();
        out.clear();
        out.extend(vf.nodes.cell(c).iter().map(|&node| {
            let x0 = self.nodes_x0[node];
            match base {
                Some(b) => std::array::from_fn(|d| x0[d] + b[vf.dof(node, d)]),
                None => x0,
            }
        }));
    }

    /// The displacement node closest to `x0` (reference coordinates).
    pub fn node_near(&self, x0: &[f64; D]) -> usize {
        let dist = |p: &[f64; D]| (0..D).map(|d| (p[d] - x0[d]).powi(2)).sum::<f64>();
        (0..self.nodes_x0.len()).min_by(|&a, &b| dist(&self.nodes_x0[a]).total_cmp(&dist(&self.nodes_x0[b]))).expect("mesh has nodes")
    }

    /// The displacement-field interpolant of the global vector `x` (a displacement, or a
    /// velocity) at the reference point `xi` of cell `c`: `sum_i x_i phi_i(xi)`.
    pub fn interpolate(&self, x: &[f64], c: usize, xi: &[f64; D]) -> [f64; D] {
        let vf = &self.displacement_field();
        let n = self.element.num_dofs();
        let (mut phi, mut grad) = ([0.0; MAX_DOFS], [[0.0; D]; MAX_DOFS]);
        self.element.eval_into(xi, &mut phi[..n], &mut grad[..n]);
        let nodes = vf.nodes.cell(c);
        std::array::from_fn(|a| (0..n).map(|i| phi[i] * x[vf.dof(nodes[i], a)]).sum())
    }

    /// The position `X + u` of node `node` for the total displacement in `x`.
    pub fn current_position(&self, x: &[f64], node: usize) -> [f64; D] {
        let u = self.displacement(x, node);
        std::array::from_fn(|d| self.nodes_x0[node][d] + u[d])
    }

    /// Displacement of node `node` in the global vector `x`.
    pub fn displacement(&self, x: &[f64], node: usize) -> [f64; D] {
        let vf = &self.displacement_field();
        std::array::from_fn(|a| x[vf.dof(node, a)])
    }

    /// Checks that every boundary the problem names exists in the mesh.
    pub fn check_problem(&self, problem: &SolidProblem<D>) -> Result<(), SolidError> {
        let names = problem
            .dirichlet
            .iter()
            .map(|b| &b.boundary)
            .chain(problem.traction.iter().map(|b| &b.boundary))
            .chain(problem.pressure.iter().map(|b| &b.boundary))
            .chain(problem.contact.iter().map(|b| &b.boundary))
            .chain(problem.symmetry.iter().map(|b| &b.boundary));
        for name in names {
            self.mesh.boundary_tag(name)?;
        }
        Ok(())
    }

    /// Prescribed values (total displacement, or pressure pin) of the constrained dofs at `load`.
    pub fn dirichlet_values(&self, problem: &SolidProblem<D>, load: f64) -> Result<Vec<(usize, f64)>, SolidError> {
        let vf = &self.displacement_field();
        let mut out = Vec::new();
        let mut seen = vec![false; self.num_dofs()];
        for bc in &problem.dirichlet {
            for bf in self.mesh.boundary_facets(&bc.boundary)? {
                let nodes = vf.nodes.cell(bf.cell);
                for k in self.element.facet_nodes(bf.facet) {
                    let node = nodes[k];
                    let value = (bc.value)(&self.nodes_x0[node], load);
                    for &a in &bc.components {
                        let dof = vf.dof(node, a);
                        if !seen[dof] {
                            seen[dof] = true;
                            out.push((dof, value[a]));
                        }
                    }
                }
            }
        }
        if let (Some(v), true) = (problem.pin_pressure, self.mixed) {
            out.push((self.pressure_field().dof(0, 0), v));
        }
        Ok(out)
    }

    /// Assembles the Jacobian `k` and `rhs = -R` at load factor `load`.
    ///
    /// `x` holds the unknowns: the displacement from the integration configuration `X + base`
    /// (`base = None`: reference, total Lagrangian) and the pressure. `f_prev[c * nq + q]` is the
    /// deformation gradient of the integration configuration (`None`: identity). `inertia =
    /// (a^2, x*)` adds `rho_0 a^2 (x - x*)` per unit reference volume (the time scheme's
    /// acceleration; `rho_0` the density of each cell's body). Rows of constrained dofs become
    /// identity rows with zero right-hand side, and the rows of the nodes on rollers of any
    /// normal the tangential equations and constraint rows of [`NormalConstraints`].
    #[allow(clippy::too_many_arguments)]
    pub fn assemble_system(
        &self,
        problem: &SolidProblem<D>,
        load: f64,
        base: Option<&[f64]>,
        f_prev: Option<&[Mat3]>,
        inertia: Option<(f64, &[f64])>,
        x: &[f64],
        constrained: &[bool],
        k: &mut CscMatrix<'_>,
        rhs: &mut [f64],
    ) -> Result<(), SolidAssemblyError> {
        self.check_symmetry(problem);
        self.normal_constraints.check_free(constrained);
        let target = &mut WholeSystem { k, rhs };
        self.assemble_into(problem, load, base, f_prev, inertia, x, constrained, &self.colouring, target)?;
        self.normal_constraints.apply(target);
        Ok(())
    }

    /// [`SolidDiscretization::assemble_system`] into `target`, from the cells of `colouring` (all
    /// of them, or those with an unknown in the target's rows), the boundary terms and the
    /// constrained unknowns' identity rows; the rows of the rollers' nodes are left as assembled
    /// (the system that holds them ends its assembly with [`NormalConstraints::apply`]).
    #[allow(clippy::too_many_arguments, reason = "the problem, the integration configuration, the state, the constraints and where they go")]
    pub fn assemble_into(
        &self,
        problem: &SolidProblem<D>,
        load: f64,
        base: Option<&[f64]>,
        f_prev: Option<&[Mat3]>,
        inertia: Option<(f64, &[f64])>,
        x: &[f64],
        constrained: &[bool],
        colouring: &Colouring,
        target: &mut impl SystemTarget,
    ) -> Result<(), SolidAssemblyError> {
        let nv = self.element.num_dofs();
        let nu = nv * D;
        let n = self.layout.dofs_per_cell();
        let nq = self.points_per_cell();
        let formulation = self.formulation;
        target.add_cells(
            colouring,
            constrained,
            || (self.cell_values(), Vec::new(), vec![0.0; n], vec![0.0; nu], vec![[0.0; D]; nq]),
            |c, (cv, coords, loc, tgt, bf), local: &mut LocalSystem| {
                self.cell_positions(c, base, coords);
                cv.reinit(coords).map_err(|source| SolidAssemblyError::Map { cell: c, source })?;
                self.layout.cell_dofs_into(c, &mut local.dofs);
                local.reset(n);
                for (i, &d) in local.dofs.iter().enumerate() {
                    loc[i] = x[d];
                }
                let body = problem.body(c);
                let inert = inertia.filter(|_| body.density > 0.0).map(|(a2, target)| {
                    for (i, &d) in local.dofs[..nu].iter().enumerate() {
                        tgt[i] = target[d];
                    }
                    body.density * a2
                });
                let x0 = &self.qp_x0[c * nq..(c + 1) * nq];
                if let Some(b) = &body.body_force {
                    for (v, x) in bf.iter_mut().zip(x0) {
                        *v = b(x, load);
                    }
                }
                let state = SolidCellState {
                    u: &loc[..nu],
                    p: &loc[nu..],
                    f_prev: f_prev.map(|f| &f[c * nq..(c + 1) * nq]),
                    x0,
                    x0_centroid: self.centroid_x0[c],
                    inertia: inert.map(|coefficient| InertiaState { coefficient, target: &tgt[..] }),
                    body_force: body.body_force.as_ref().map(|_| &bf[..]),
                };
                solid_cell(cv, formulation, body.material.as_ref(), &state, &mut local.ke, &mut local.fe)
                    .map_err(|e| SolidAssemblyError::Inverted { cell: c, point: e.point, det: e.det })?;
                local.fe.iter_mut().for_each(|v| *v = -*v);
                Ok(())
            },
        )?;
        // Boundary terms (few facets: serial).
        let vf = &self.displacement_field();
        let nf = self.facet_weights.len();
        let mut x_ref = Vec::new();
        let mut x_cur: Vec<[f64; D]> = Vec::new();
        let mut re = vec![0.0; nu];
        let mut ke = vec![0.0; nu * nu];
        for bc in &problem.traction {
            for bf in self.mesh.boundary_facets(&bc.boundary).unwrap_or_default() {
                self.cell_positions(bf.cell, None, &mut x_ref);
                let tab = &self.facet_tabs[bf.facet];
                re.iter_mut().for_each(|v| *v = 0.0);
                for q in 0..nf {
                    let pt = FacetPoint {
                        phi: &tab.values[q * nv..(q + 1) * nv],
                        dphi_t: &tab.dphi_t[q * nv..(q + 1) * nv],
                        weight: self.facet_weights[q],
                    };
                    let nda = area_vector(&x_ref, &pt, 1.0);
                    let da = nda.iter().map(|v| v * v).sum::<f64>().sqrt();
                    let mut xq = [0.0; D];
                    for (kk, xk) in x_ref.iter().enumerate() {
                        for d in 0..D {
                            xq[d] += pt.phi[kk] * xk[d];
                        }
                    }
                    let w = pt.weight * da * formulation.weight(&xq);
                    let t = (bc.traction)(&xq, load);
                    for i in 0..nv {
                        for a in 0..D {
                            re[i * D + a] -= w * t[a] * pt.phi[i];
                        }
                    }
                }
                for (i, &node) in vf.nodes.cell(bf.cell).iter().enumerate() {
                    for a in 0..D {
                        let dof = vf.dof(node, a);
                        if !constrained[dof] {
                            target.add_rhs(dof, -re[i * D + a]);
                        }
                    }
                }
            }
        }
        for bc in &problem.pressure {
            let pval = (bc.pressure)(load);
            for bf in self.mesh.boundary_facets(&bc.boundary).unwrap_or_default() {
                self.cell_positions(bf.cell, None, &mut x_ref);
                let tab = &self.facet_tabs[bf.facet];
                // Orientation from the reference configuration: outward from the cell centre.
                let pt0 = FacetPoint { phi: &tab.values[..nv], dphi_t: &tab.dphi_t[..nv], weight: 1.0 };
                let nda = area_vector(&x_ref, &pt0, 1.0);
                let centre: [f64; D] = self.centroid_x0[bf.cell];
                let mut out = 0.0;
                for d in 0..D {
                    let xq: f64 = (0..nv).map(|kk| pt0.phi[kk] * x_ref[kk][d]).sum();
                    out += (xq - centre[d]) * nda[d];
                }
                let orientation = if out < 0.0 { -1.0 } else { 1.0 };
                // Current positions: X + base + x.
                x_cur.clear();
                for (i, &node) in vf.nodes.cell(bf.cell).iter().enumerate() {
                    x_cur.push(std::array::from_fn(|d| {
                        let dof = vf.dof(node, d);
                        x_ref[i][d] + base.map(|b| b[dof]).unwrap_or(0.0) + x[dof]
                    }));
                }
                re.iter_mut().for_each(|v| *v = 0.0);
                ke.iter_mut().for_each(|v| *v = 0.0);
                let pts: Vec<FacetPoint> = (0..nf)
                    .map(|q| FacetPoint {
                        phi: &tab.values[q * nv..(q + 1) * nv],
                        dphi_t: &tab.dphi_t[q * nv..(q + 1) * nv],
                        weight: self.facet_weights[q],
                    })
                    .collect();
                follower_pressure_facet(formulation, &x_cur, &pts, orientation, pval, &mut ke, nu, &mut re);
                let nodes = vf.nodes.cell(bf.cell);
                for i in 0..nv {
                    for a in 0..D {
                        let row = vf.dof(nodes[i], a);
                        if constrained[row] {
                            continue;
                        }
                        target.add_rhs(row, -re[i * D + a]);
                        for j in 0..nv {
                            for b in 0..D {
                                target.add_matrix(row, vf.dof(nodes[j], b), ke[(i * D + a) * nu + j * D + b]);
                            }
                        }
                    }
                }
            }
        }
        self.add_contact(problem, base, x, constrained, target);
        for (dof, _) in constrained.iter().enumerate().filter(|(_, &c)| c) {
            target.identity_row(dof);
        }
        Ok(())
    }

    /// The contact terms at `x` (positions `X + base + x`; [`crate::physics::contact`]): the
    /// push of the planes and of the master boundaries in the displacement rows, and each contact
    /// node's complementarity row.
    fn add_contact(&self, problem: &SolidProblem<D>, base: Option<&[f64]>, x: &[f64], constrained: &[bool], target: &mut impl SystemTarget) {
        assert_eq!(
            problem.contact.iter().map(|c| &c.boundary).collect::<Vec<_>>(),
            self.contact.iter().map(|s| &s.boundary).collect::<Vec<_>>(),
            "the problem's contact boundaries are the discretisation's contact surfaces"
        );
        let vf = self.displacement_field();
        // The stiffest body's shear modulus scales every complementarity row.
        let shear = problem.bodies.iter().map(|b| b.material.shear_modulus()).fold(0.0, f64::max);
        for (surface, bc) in self.contact.iter().zip(&problem.contact) {
            let rows = self.contact_rows(surface, bc, base, x);
            for (j, (&node, &w)) in surface.nodes.iter().zip(&surface.weights).enumerate() {
                let l = surface.first + j;
                let c = complementarity_scale(shear, w, self.formulation.weight(&self.nodes_x0[node]), D);
                // A node whose motion along n is held by Dirichlet conditions, like every master
                // node of its row, cannot close a gap: it stays off contact (its multiplier 0),
                // or its row would be empty; so does a node with no master under it.
                let held = |k: usize, n: &[f64; D]| (0..D).all(|a| n[a] == 0.0 || constrained[vf.dof(k, a)]);
                let row = rows[j].as_ref().filter(|r| !(held(node, &r.normal) && r.master.iter().all(|&(k, _)| held(k, &r.normal))));
                let cond = complementarity(x[l], row.map_or(f64::INFINITY, |r| r.gap), c);
                target.add_rhs(l, -cond.residual);
                if !cond.active {
                    target.add_matrix(l, l, -1.0 / c);
                }
                let Some(row) = row else { continue };
                let n = row.normal;
                // The slave's push `m_j lambda_j n` and the master's `-M_jk lambda_j n`.
                for (k, m) in std::iter::once((node, row.weight)).chain(row.master.iter().map(|&(k, m)| (k, -m))) {
                    for a in 0..D {
                        let dof = vf.dof(k, a);
                        if cond.active {
                            target.add_matrix(l, dof, -m * n[a]);
                        }
                        if !constrained[dof] {
                            target.add_rhs(dof, m * x[l] * n[a]);
                            target.add_matrix(dof, l, -m * n[a]);
                        }
                    }
                }
            }
        }
    }

    /// The position `X + base + x` of displacement node `node`.
    fn position_of(&self, base: Option<&[f64]>, x: &[f64], node: usize) -> [f64; D] {
        let vf = self.displacement_field();
        std::array::from_fn(|d| {
            let dof = vf.dof(node, d);
            self.nodes_x0[node][d] + base.map_or(0.0, |b| b[dof]) + x[dof]
        })
    }

    /// Each node's contact row of `surface` at the positions `X + base + x`: the normal `n`
    /// (pointing to where the node stays), the weighted gap and the weights of the node (`m_j`;
    /// the plane's `w_j`) and of the master's nodes (`M_jk`, none against a plane); `None` where
    /// no master lies under the node.
    fn contact_rows(&self, surface: &ContactSurface, bc: &ContactBc<D>, base: Option<&[f64]>, x: &[f64]) -> Vec<Option<ContactRow<D>>> {
        let position = |node: usize| self.position_of(base, x, node);
        match (&bc.target, &surface.mortar) {
            (ContactTarget::Plane(plane), _) => surface
                .nodes
                .iter()
                .zip(&surface.weights)
                .map(|(&node, &w)| Some(ContactRow { normal: plane.normal, gap: w * plane.gap(&position(node)), weight: w, master: Vec::new() }))
                .collect(),
            (ContactTarget::Boundary(_), Some(m)) => {
                let flat = |p: [f64; D]| [p[0], p[1]];
                // A point inside each master edge's cell: the mean of its nodes' positions.
                let vf = self.displacement_field();
                let inside: Vec<[f64; 2]> = m
                    .master_edges
                    .iter()
                    .map(|e| {
                        let nodes = vf.nodes.cell(e.cell);
                        let sum = nodes.iter().map(|&k| flat(position(k))).fold([0.0; 2], |a, p| [a[0] + p[0], a[1] + p[1]]);
                        [sum[0] / nodes.len() as f64, sum[1] / nodes.len() as f64]
                    })
                    .collect();
                let rows = mortar::mortar_rows(
                    &surface.nodes,
                    &m.slave_edges,
                    &m.master_edges,
                    &inside,
                    |k| flat(self.nodes_x0[k]),
                    |k| flat(position(k)),
                    |p| self.formulation.weight(p),
                );
                surface
                    .nodes
                    .iter()
                    .zip(&surface.weights)
                    .zip(rows)
                    .map(|((&node, &w), row)| {
                        let MortarRow { normal, master } = row?;
                        // A node the master covers by (next to) nothing has no row: its weight
                        // would leave the row empty, or of the wrong sign where only the
                        // negative part of its basis function lies over the master.
                        let weight: f64 = master.iter().map(|(_, mk)| mk).sum();
                        if weight <= 1e-9 * w {
                            return None;
                        }
                        let n: [f64; D] = std::array::from_fn(|d| if d < 2 { normal[d] } else { 0.0 });
                        let xj = position(node);
                        let gap = master.iter().map(|&(k, mk)| mk * (0..D).map(|d| (xj[d] - position(k)[d]) * n[d]).sum::<f64>()).sum();
                        Some(ContactRow { normal: n, gap, weight, master })
                    })
                    .collect()
            }
            (ContactTarget::Boundary(_), None) => unreachable!("a contact surface against a boundary has its mortar edges"),
        }
    }

    /// The gap and the weight of every node of each contact surface at `x` (the displacement
    /// after the step's), from one evaluation of the contact rows:
    /// - the gap (negative: penetrated): the distance to the plane, or against a boundary the
    ///   weighted gap over the node's weight (`g_j / m_j`); infinite where no master lies under
    ///   the node;
    /// - the weight, what its pressure is multiplied by for its force: `w_j` against a plane;
    ///   against a boundary `m_j = sum_k M_jk`, the part of `w_j` the master covers (0 where it
    ///   covers none).
    pub fn contact_gaps_and_weights(&self, problem: &SolidProblem<D>, x: &[f64]) -> Vec<Vec<(f64, f64)>> {
        self.contact
            .iter()
            .zip(&problem.contact)
            .map(|(surface, bc)| {
                self.contact_rows(surface, bc, None, x)
                    .into_iter()
                    .map(|row| row.filter(|r| r.weight > 0.0).map_or((f64::INFINITY, 0.0), |r| (r.gap / r.weight, r.weight)))
                    .collect()
            })
            .collect()
    }

    /// The weights `w_j = int psi_j dA_0` (times `R` axisymmetric) of the `nodes` (sorted; every
    /// node of the boundary's facets) of boundary `boundary` on the reference configuration.
    fn node_weights(&self, boundary: &str, nodes: &[usize]) -> Vec<f64> {
        let vf = self.displacement_field();
        let (nv, nf) = (self.element.num_dofs(), self.facet_weights.len());
        let mut weight = vec![0.0; nodes.len()];
        let mut x_ref = Vec::new();
        for bf in self.mesh.boundary_facets(boundary).unwrap_or_default() {
            self.cell_positions(bf.cell, None, &mut x_ref);
            let tab = &self.facet_tabs[bf.facet];
            let cell_nodes = vf.nodes.cell(bf.cell);
            for q in 0..nf {
                let pt =
                    FacetPoint { phi: &tab.values[q * nv..(q + 1) * nv], dphi_t: &tab.dphi_t[q * nv..(q + 1) * nv], weight: self.facet_weights[q] };
                let da = area_vector(&x_ref, &pt, 1.0).iter().map(|v| v * v).sum::<f64>().sqrt();
                let xq: [f64; D] = std::array::from_fn(|d| (0..nv).map(|i| pt.phi[i] * x_ref[i][d]).sum());
                let w = pt.weight * da * self.formulation.weight(&xq);
                for i in self.element.facet_nodes(bf.facet) {
                    let j = nodes.binary_search(&cell_nodes[i]).expect("a facet node of the boundary");
                    weight[j] += w * pt.phi[i];
                }
            }
        }
        weight
    }

    /// Updates the stored deformation gradients after a converged updated-Lagrangian increment:
    /// `F_n <- (I + grad_n Delta u) F_n`, on the configuration `X + base` before the update.
    pub fn update_deformation(&self, base: &[f64], increment: &[f64], f_qp: &mut [Mat3]) -> Result<(), SolidAssemblyError> {
        let nq = self.points_per_cell();
        let nv = self.element.num_dofs();
        let vf = &self.displacement_field();
        let mut cv = self.cell_values();
        let mut coords = Vec::new();
        let mut u = vec![0.0; nv * D];
        for c in 0..self.mesh.num_cells() {
            self.cell_positions(c, Some(base), &mut coords);
            cv.reinit(&coords).map_err(|source| SolidAssemblyError::Map { cell: c, source })?;
            for (i, &node) in vf.nodes.cell(c).iter().enumerate() {
                for a in 0..D {
                    u[i * D + a] = increment[vf.dof(node, a)];
                }
            }
            for q in 0..nq {
                let f = deformation_gradient(&cv, self.formulation, &u, &f_qp[c * nq + q], q);
                f_qp[c * nq + q] = f;
            }
        }
        Ok(())
    }

    /// Deformation gradient at every quadrature point for the total displacement in `x`.
    pub fn deformation_gradients(&self, x: &[f64]) -> Result<Vec<Mat3>, SolidAssemblyError> {
        let mut f = vec![IDENTITY; self.mesh.num_cells() * self.points_per_cell()];
        let zero = vec![0.0; self.num_dofs()];
        self.update_deformation(&zero, x, &mut f)?;
        Ok(f)
    }
}

/// Which configuration each increment integrates over.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Lagrangian {
    /// Reference configuration, unknown = total displacement.
    Total,
    /// Configuration of the last converged increment, unknown = displacement increment, `F_n`
    /// stored per quadrature point.
    Updated,
}

/// Load-factor ramp from 0 to `final_load`.
#[derive(Clone, Debug)]
pub struct LoadStepping {
    pub mode: Lagrangian,
    pub final_load: f64,
    pub initial_increment: f64,
    pub max_increment: f64,
    /// Smallest increment tried after cuts before giving up.
    pub min_increment: f64,
    /// Factor applied to the increment after a converged step (1 = fixed increments).
    pub growth: f64,
    /// Start each increment from the linear extrapolation of the previous converged increment
    /// (the Dirichlet values are exact either way).
    pub predictor: bool,
}

impl Default for LoadStepping {
    fn default() -> Self {
        LoadStepping {
            mode: Lagrangian::Total,
            final_load: 1.0,
            initial_increment: 1.0,
            max_increment: 1.0,
            min_increment: 1e-4,
            growth: 2.0,
            predictor: true,
        }
    }
}

impl LoadStepping {
    /// `n` equal increments, no growth.
    pub fn uniform(mode: Lagrangian, n: usize) -> Self {
        let h = 1.0 / n as f64;
        LoadStepping { mode, final_load: 1.0, initial_increment: h, max_increment: h, min_increment: h / 64.0, growth: 1.0, predictor: true }
    }
}

/// One attempted load increment.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StepRecord {
    /// Number of the converged step this attempt tried to reach (1-based).
    pub step: usize,
    /// Load factor at the end of the increment.
    pub load: f64,
    pub increment: f64,
    /// `None` when converged, otherwise why it failed.
    pub failure: Option<String>,
    pub newton: Option<NewtonReport>,
}

/// A solid solution.
#[derive(Clone, Debug)]
pub struct SolidSolution {
    /// Total displacement from the reference configuration and the pressure, in the layout's
    /// numbering.
    pub x: Vec<f64>,
    /// Load factor reached.
    pub load: f64,
    /// Every attempted increment, including the cut ones.
    pub steps: Vec<StepRecord>,
    /// Deformation gradient per quadrature point (updated-Lagrangian mode only).
    pub f_qp: Option<Vec<Mat3>>,
}

impl SolidSolution {
    /// Newton residual norms of all converged increments, in order.
    pub fn residual_history(&self) -> Vec<Vec<f64>> {
        self.steps.iter().filter_map(|s| s.newton.as_ref().map(|n| n.residual_norms.clone())).collect()
    }
}

/// Quasi-static load stepping with Newton per increment ([`SolidDiscretization::solve_increment`]):
/// increments grow by `stepping.growth` after a converged one and are halved after a failed
/// one, down to `stepping.min_increment`. (Case-file solid runs take equal increments through
/// [`crate::time::solid::QuasiStaticStepper`] instead.)
pub fn solve_quasi_static<const D: usize>(
    disc: &SolidDiscretization<D>,
    problem: &SolidProblem<D>,
    stepping: &LoadStepping,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
) -> Result<SolidSolution, SolidError> {
    disc.check_problem(problem)?;
    let mut state = LoadState::at_rest(disc, stepping.mode);
    let mut inc = stepping.initial_increment.min(stepping.final_load);
    let mut steps = Vec::new();
    let mut step = 1;
    while state.load < stepping.final_load - 1e-14 * stepping.final_load.abs().max(1.0) {
        let (load, target) = (state.load, (state.load + inc).min(stepping.final_load));
        match disc.solve_increment(problem, &mut state, target, stepping.predictor, solver, options) {
            Ok(report) => {
                steps.push(StepRecord { step, load: target, increment: target - load, failure: None, newton: Some(report) });
                step += 1;
                inc = (inc * stepping.growth).min(stepping.max_increment);
            }
            Err(e) => {
                let reason = match &e {
                    SolidError::Newton(NewtonError::Assembly(SolidAssemblyError::Inverted { cell, point, det })) => {
                        format!("element {cell} inverted (det F = {det:.3e} at quadrature point {point}) in step {step}")
                    }
                    SolidError::Newton(other) => format!("{other} (step {step})"),
                    _ => return Err(e),
                };
                let increment = target - load;
                steps.push(StepRecord { step, load: target, increment, failure: Some(reason.clone()), newton: None });
                if increment * 0.5 < stepping.min_increment {
                    return Err(SolidError::StepFailed { step, load: target, increment, reason });
                }
                inc = increment * 0.5;
            }
        }
    }
    Ok(SolidSolution { x: state.x, load: state.load, steps, f_qp: state.f_qp })
}

/// Where quasi-static load stepping stands after a converged increment: what the next increment
/// starts from, and what a restart restores.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LoadState {
    /// The load factor reached.
    pub load: f64,
    /// Total displacement from the reference configuration and the pressure (layout numbering).
    pub x: Vec<f64>,
    /// Deformation gradient per quadrature point (updated-Lagrangian mode only).
    pub f_qp: Option<Vec<Mat3>>,
    /// The displacement change of the last converged increment and its load change (the
    /// predictor of the next increment), when the predictor is on.
    pub last_change: Option<(Vec<f64>, f64)>,
}

impl LoadState {
    /// The unloaded reference configuration.
    pub fn at_rest<const D: usize>(disc: &SolidDiscretization<D>, mode: Lagrangian) -> Self {
        let f_qp = (mode == Lagrangian::Updated).then(|| vec![IDENTITY; disc.mesh.num_cells() * disc.points_per_cell()]);
        LoadState { load: 0.0, x: vec![0.0; disc.num_dofs()], f_qp, last_change: None }
    }
}

impl<const D: usize> SolidDiscretization<D> {
    /// One load increment from `state` to the load factor `target`: Newton from the predictor
    /// (the last increment's displacement change, scaled, when `predictor`) with the Dirichlet
    /// values at `target`. Updated-Lagrangian when `state` holds deformation gradients (the
    /// unknowns are then increments from `X + u_n`, and `F` is updated), total otherwise. On
    /// failure `state` is unchanged.
    pub fn solve_increment(
        &self,
        problem: &SolidProblem<D>,
        state: &mut LoadState,
        target: f64,
        predictor: bool,
        solver: &mut dyn LinearSolver,
        options: &NewtonOptions,
    ) -> Result<NewtonReport, SolidError> {
        let nu = self.displacement_field().num_dofs();
        let updated = state.f_qp.is_some();
        let mut constrained = vec![false; self.num_dofs()];
        let bcs = self.dirichlet_values(problem, target)?;
        for &(d, _) in &bcs {
            constrained[d] = true;
        }
        let mut trial = state.x.clone();
        if updated {
            trial[..nu].iter_mut().for_each(|v| *v = 0.0);
        }
        // Predictor: extrapolate the displacement change of the last converged increment.
        if let Some((delta, h)) = &state.last_change {
            let s = (target - state.load) / h;
            for i in 0..nu {
                trial[i] += s * delta[i];
            }
        }
        for &(d, v) in &bcs {
            // Pressure pins are absolute; displacements are increments in updated mode.
            trial[d] = if updated && d < nu { v - state.x[d] } else { v };
        }
        // On the rollers: the total displacement, or the increment, along them.
        self.normal_constraints.project(&mut trial);
        let base = if updated { Some(state.x.as_slice()) } else { None };
        let report = newton::solve(&mut trial, &self.pattern, solver, options, |x, k, rhs| {
            self.assemble_system(problem, target, base, state.f_qp.as_deref(), None, x, &constrained, k, rhs)
        })?;
        let delta: Vec<f64> = if updated { trial[..nu].to_vec() } else { (0..nu).map(|i| trial[i] - state.x[i]).collect() };
        if let Some(f) = &state.f_qp {
            let mut f = f.clone();
            self.update_deformation(&state.x, &trial, &mut f)?;
            state.f_qp = Some(f);
        }
        state.last_change = if predictor { Some((delta, target - state.load)) } else { None };
        if updated {
            for i in 0..nu {
                state.x[i] += trial[i];
            }
            state.x[nu..].copy_from_slice(&trial[nu..]);
        } else {
            state.x = trial;
        }
        state.load = target;
        Ok(report)
    }
}

/// The time discretisation of a dynamic step, `v_{n+1} = a (u_{n+1} - u*)` and
/// `a_{n+1} = a (v_{n+1} - v*)` with `a = a0 / dt`: implicit Euler `a0 = 1`, `u* = u_n`,
/// `v* = v_n`; BDF2 `a0 = 3/2`, `u* = (4 u_n - u_{n-1}) / 3`, `v* = (4 v_n - v_{n-1}) / 3`
/// ([`crate::time::step_history`] gives both). The inertia `rho_0 a_{n+1}` is then
/// `rho_0 a^2 (u_{n+1} - u* - v* / a)`.
#[derive(Clone, Copy, Debug)]
pub struct InertiaHistory<'a> {
    /// `a0 / dt`.
    pub a: f64,
    /// `u*`, on the layout's unknowns (the pressure entries are not used).
    pub u_star: &'a [f64],
    /// `v*`, likewise.
    pub v_star: &'a [f64],
}

/// One step of the solid with inertia (total Lagrangian), `rho_0 a_{n+1} + div-terms = loads` at
/// `load` (the time `t_{n+1}` when the problem was set up without a load ramp), with the time
/// discretisation `history`. `x_n` holds `u_n` and the last pressure: the initial guess. Returns
/// `(x_{n+1}, v_{n+1})` (`v` zero on the pressure unknowns). Without a density it is a static
/// solve at `load`.
pub fn solve_dynamic_step<const D: usize>(
    disc: &SolidDiscretization<D>,
    problem: &SolidProblem<D>,
    x_n: &[f64],
    history: &InertiaHistory<'_>,
    load: f64,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
) -> Result<(Vec<f64>, Vec<f64>, NewtonReport), SolidError> {
    disc.check_problem(problem)?;
    let n = disc.num_dofs();
    let nu_global = disc.displacement_field().num_dofs();
    let mut x = x_n.to_vec();
    let mut constrained = vec![false; n];
    for (d, v) in disc.dirichlet_values(problem, load)? {
        constrained[d] = true;
        x[d] = v;
    }
    disc.normal_constraints.project(&mut x);
    let a = history.a;
    let target: Vec<f64> = (0..n).map(|i| if i < nu_global { history.u_star[i] + history.v_star[i] / a } else { 0.0 }).collect();
    let inertia = problem.has_inertia().then_some((a * a, target.as_slice()));
    let report = newton::solve(&mut x, &disc.pattern, solver, options, |xx, k, rhs| {
        disc.assemble_system(problem, load, None, None, inertia, xx, &constrained, k, rhs)
    })?;
    let v: Vec<f64> = (0..n).map(|i| if i < nu_global { a * (x[i] - history.u_star[i]) } else { 0.0 }).collect();
    Ok((x, v, report))
}

/// Errors of a discrete solution against an exact one, in the reference configuration (weighted
/// by `R` when axisymmetric).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct SolidErrors {
    pub displacement_l2: f64,
    /// `|Grad (u - u_ex)|` in L2 (plus the hoop term `(u_R - u_R,ex)/R` when axisymmetric).
    pub displacement_h1: f64,
    /// Pressure L2 error (0 when no exact pressure or no pressure field).
    pub pressure_l2: f64,
}

/// Exact fields for [`solid_errors`]: displacement `u(X)` and gradient `Grad u`, and optionally
/// the pressure `p(X)` in the kernel's convention.
#[allow(clippy::type_complexity, reason = "the exact fields as functions of position, written out")]
pub struct ExactSolid<'a, const D: usize> {
    pub displacement: &'a dyn Fn(&[f64; D]) -> [f64; D],
    pub gradient: &'a dyn Fn(&[f64; D]) -> [[f64; D]; D],
    pub pressure: Option<&'a dyn Fn(&[f64; D]) -> f64>,
}

/// Computes [`SolidErrors`] with a tensor Gauss rule of degree `degree`.
pub fn solid_errors<const D: usize>(
    disc: &SolidDiscretization<D>,
    x: &[f64],
    exact: &ExactSolid<'_, D>,
    degree: usize,
) -> Result<SolidErrors, SolidError> {
    let mut cv = CellValues::new(fdfsi_fem::quadrature::for_cell(disc.mesh.cell_type, degree), &disc.element, &disc.element);
    let vf = &disc.displacement_field();
    let axi = disc.formulation == Formulation::Axisymmetric;
    let mut coords = Vec::new();
    let mut e = SolidErrors::default();
    for c in 0..disc.mesh.num_cells() {
        disc.cell_positions(c, None, &mut coords);
        cv.reinit(&coords).map_err(|source| SolidAssemblyError::Map { cell: c, source })?;
        let nodes = vf.nodes.cell(c);
        for q in 0..cv.num_points() {
            let xq = cv.x[q];
            let r = disc.formulation.weight(&xq);
            let w = cv.jxw[q] * r;
            let (phi, dphi) = (cv.phi(q), cv.grad_phi(q));
            let mut u = [0.0; D];
            let mut g = [[0.0; D]; D];
            for (i, &node) in nodes.iter().enumerate() {
                for a in 0..D {
                    let ua = x[vf.dof(node, a)];
                    u[a] += ua * phi[i];
                    for b in 0..D {
                        g[a][b] += ua * dphi[i][b];
                    }
                }
            }
            let ue = (exact.displacement)(&xq);
            let ge = (exact.gradient)(&xq);
            for a in 0..D {
                e.displacement_l2 += w * (u[a] - ue[a]).powi(2);
                for b in 0..D {
                    e.displacement_h1 += w * (g[a][b] - ge[a][b]).powi(2);
                }
            }
            if axi {
                e.displacement_h1 += w * ((u[1] - ue[1]) / r).powi(2);
            }
            if let (Some(pe), true) = (exact.pressure, disc.mixed) {
                let pf = &disc.pressure_field();
                let xc = disc.centroid_x0[c];
                let mut p = x[pf.dof(c * (D + 1), 0)];
                for d in 0..D {
                    p += x[pf.dof(c * (D + 1) + 1 + d, 0)] * (xq[d] - xc[d]);
                }
                e.pressure_l2 += w * (p - pe(&xq)).powi(2);
            }
        }
    }
    e.displacement_l2 = e.displacement_l2.sqrt();
    e.displacement_h1 = e.displacement_h1.sqrt();
    e.pressure_l2 = e.pressure_l2.sqrt();
    Ok(e)
}

/// Pressure of a mixed solution at material point `x0` of cell `c`.
pub fn pressure_at<const D: usize>(disc: &SolidDiscretization<D>, x: &[f64], c: usize, x0: &[f64; D]) -> f64 {
    let pf = &disc.pressure_field();
    let xc = disc.centroid_x0[c];
    let mut p = x[pf.dof(c * (D + 1), 0)];
    for d in 0..D {
        p += x[pf.dof(c * (D + 1) + 1 + d, 0)] * (x0[d] - xc[d]);
    }
    p
}
