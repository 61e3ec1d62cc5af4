//! Incompressible flow on one fixed mesh: problem definition, discretisation, steady solve and
//! error norms.
//!
//! Data flows one way: a [`FlowProblem`] (physics and boundary conditions) and a mesh give a
//! [`FlowDiscretization`] (everything derived from the mesh: topology, dof maps, the sparsity
//! pattern or this rank's rows of it, colouring; built once, never patched); [`solve_steady`]
//! runs Newton on it with the kernel of [`crate::physics::fluid`] and returns a
//! [`FlowSolution`].

use super::symmetry::{NormalConstraints, Planarity, SymmetryBc, SymmetryError};
use super::system_cell_dofs;
use crate::physics::fluid::{fluid_cell, traction_facet, CellState, FluidParams, Formulation, Stabilization};
use crate::solve::augmented::{MultiplierBlock, SaddlePointSplit};
use crate::solve::linear::{LinearSolveError, LinearSolver};
use crate::solve::newton::{self, NewtonError, NewtonOptions, NewtonReport};
use crate::solve::partition::{row_solver_of, Nodes, Partition, World};
use fdfsi_fem::dofs::{BlockLayout, Field, NodeMap};
use fdfsi_fem::element::{ElementFamily, ReferenceCell, ReferenceElement};
use fdfsi_fem::mesh::{Mesh, MeshError, Topology};
use fdfsi_fem::quadrature::{self, QuadratureRule};
use fdfsi_fem::sparse::{Colouring, CscMatrix, HeldRows, LocalSystem, Pattern, ResidualOnly, RowMatrix, RowPattern, SystemTarget, WholeSystem};
use fdfsi_fem::values::{p1disc_basis, p1disc_mass, CellValues, FacetValues, MapError};
use std::sync::Arc;
use thiserror::Error;

/// A vector field of position and time.
pub type VectorFn<const D: usize> = Arc<dyn Fn(&[f64; D], f64) -> [f64; D] + Send + Sync>;
/// A traction of position, outward normal and time.
pub type TractionFn<const D: usize> = Arc<dyn Fn(&[f64; D], &[f64; D], f64) -> [f64; D] + Send + Sync>;

/// Velocity prescribed on a named boundary, for the listed components.
#[derive(Clone)]
pub struct DirichletBc<const D: usize> {
    pub boundary: String,
    pub components: Vec<usize>,
    pub value: VectorFn<D>,
}

/// Traction `sigma n = t` prescribed on a named boundary.
#[derive(Clone)]
pub struct TractionBc<const D: usize> {
    pub boundary: String,
    pub traction: TractionFn<D>,
}

/// Backflow stabilisation on a traction boundary (Bazilevs, Gohean, Hughes, Moser & Zhang 2009;
/// Moghadam, Bazilevs, Hsia, Vignon-Clementel & Marsden 2011): the traction there gains
///
/// ```text
/// t_b = beta rho / 2 min(u . n, 0) u          (n the outward normal, 0 <= beta <= 1)
/// ```
///
/// which cancels (beta = 1) the kinetic energy that fluid entering through the boundary brings,
/// `-rho / 2 (u . n) |u|^2`, the term that otherwise grows without bound where vortices cross an
/// outlet. Where the fluid enters normally (`u = (u . n) n`), `t_b = beta rho / 2 |u|^2 n`:
/// with beta = 1 a pressure `p` on the boundary reads as the total pressure
/// `p_static + rho |u|^2 / 2` of a chamber at rest upstream (a ventricle feeding an inlet).
#[derive(Clone, Debug, PartialEq)]
pub struct BackflowBc {
    pub boundary: String,
    pub beta: f64,
}

/// A three-element Windkessel (RCR) outlet on a named boundary: a 0D model of the circulation
/// downstream, coupled implicitly. Its flux `Q` and capacitor pressure `P_c` are unknowns of the
/// system ([`FlowDiscretization::windkessel_dofs`]), with the equations
///
/// ```text
/// Q - s int_outlet u . n w ds = 0                         (s: Formulation::around, 2 pi or 1)
/// C dP_c/dt - Q + (P_c - P_d) / R_d = 0                   (the fluid's time scheme; steady: no C)
/// sigma n = -P n on the outlet,  P = R_p Q + P_c          (the outlet pressure)
/// ```
///
/// (`w` the formulation's weight). `R_p` is the proximal (characteristic) resistance, `C` the
/// compliance, `R_d` the distal (peripheral) resistance, `P_d` the distal (venous) pressure.
#[derive(Clone, Debug, PartialEq)]
pub struct WindkesselBc {
    pub boundary: String,
    pub proximal_resistance: f64,
    pub compliance: f64,
    pub distal_resistance: f64,
    pub distal_pressure: f64,
    /// `P_c` at the start of a run.
    pub initial_pressure: f64,
}

impl WindkesselBc {
    /// The outlet pressure `P = R_p Q + P_c`.
    pub fn outlet_pressure(&self, flux: f64, capacitor_pressure: f64) -> f64 {
        self.proximal_resistance * flux + capacitor_pressure
    }
}

/// A flow problem: formulation, fluid parameters, body force, boundary conditions.
#[derive(Clone)]
pub struct FlowProblem<const D: usize> {
    pub formulation: Formulation,
    pub params: FluidParams,
    pub body_force: Option<VectorFn<D>>,
    pub dirichlet: Vec<DirichletBc<D>>,
    pub traction: Vec<TractionBc<D>>,
    /// Windkessel outlets, in the order of the discretisation's
    /// ([`FlowDiscretization::build_with_outlets`]).
    pub windkessel: Vec<WindkesselBc>,
    /// Backflow stabilisation on traction boundaries.
    pub backflow: Vec<BackflowBc>,
    /// Symmetry planes (free slip, `u . n = 0`) whose normal is not along a coordinate axis
    /// (those are Dirichlet conditions on one component), held by the discretisation's
    /// [`NormalConstraints`] ([`FlowDiscretization::build_for`]).
    pub symmetry: Vec<SymmetryBc<D>>,
    /// Fix the pressure constant (needed when the velocity is prescribed on the whole boundary):
    /// the mean-value dof of cell 0 is set to zero and the pressure shifted to zero mean after the
    /// solve.
    pub pin_pressure: bool,
}

impl<const D: usize> FlowProblem<D> {
    /// `options` for a Newton solve of this problem: without the inexact Newton method when the
    /// problem is linear (Stokes: no convection), where a loose first solve would only cost a
    /// second one.
    pub fn newton_options(&self, options: &NewtonOptions) -> NewtonOptions {
        NewtonOptions { inexact: options.inexact && self.params.convection, ..options.clone() }
    }
}

/// Errors of a flow solve.
#[derive(Debug, Error)]
pub enum FlowError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("cell {cell}: {source}")]
    Map { cell: usize, source: MapError },
    #[error("the {formulation:?} formulation does not apply to {dim}D meshes")]
    Formulation { formulation: Formulation, dim: usize },
    #[error("fluid meshes must be triangles (2D) or tetrahedra (3D), got {0:?}")]
    CellType(ReferenceCell),
    #[error("{0} unknowns exceed the 2^32 column indices of a partitioned assembly")]
    TooManyUnknowns(usize),
    #[error(transparent)]
    Symmetry(#[from] SymmetryError),
    #[error(transparent)]
    Newton(#[from] NewtonError<AssemblyError>),
    /// `reached` is the smallest viscosity solved (infinite when none converged from rest).
    #[error("Newton fails from rest, and the continuation in the viscosity stopped at {reached:.4e} (target {target:.4e}) after {solves} solves: {source}; refine the mesh, or raise solver.newton.max_iterations")]
    Continuation { reached: f64, target: f64, solves: usize, source: Box<FlowError> },
}

/// An error inside assembly (reported through Newton).
#[derive(Debug, Error)]
#[error("cell {cell}: {source}")]
pub struct AssemblyError {
    pub cell: usize,
    pub source: MapError,
}

/// Everything derived from one fluid mesh.
pub struct FlowDiscretization<const D: usize> {
    pub mesh: Mesh<D>,
    pub topology: Topology,
    pub velocity_element: ReferenceElement<D>,
    pub geometry_element: ReferenceElement<D>,
    /// Fields "velocity" (D components on P2+ nodes) and "pressure" (1 component, D + 1 dofs per
    /// cell).
    pub layout: BlockLayout,
    /// Physical coordinates of the velocity nodes.
    pub velocity_nodes: Vec<[f64; D]>,
    /// The system's sparsity: the whole pattern, this rank's rows, or the number of entries
    /// ([`FlowDiscretization::build_with`]).
    sparsity: Sparsity,
    /// A colouring of all cells.
    pub colouring: Colouring,
    pub cell_rule: QuadratureRule<D>,
    facet_points: Vec<[f64; 2]>,
    facet_weights: Vec<f64>,
    /// The boundaries of the Windkessel outlets, whose unknowns follow the layout's.
    outlets: Vec<String>,
    /// The outlets' couplings as cells after the mesh's ([`FlowDiscretization::system_cell_dofs`]).
    outlet_cells: Vec<Vec<usize>>,
    /// Each outlet's [`FlowDiscretization::flux_weights`].
    outlet_weights: Vec<Vec<(usize, f64)>>,
    /// The symmetry planes of any normal it was built for ([`FlowDiscretization::build_for`]).
    symmetry: Vec<SymmetryBc<D>>,
    /// Their constraints at the velocity nodes on them.
    normal_constraints: NormalConstraints,
}

/// Which matrix entries a discretisation prepares ([`FlowDiscretization::build_with`],
/// [`crate::discretize::fsi::FsiDiscretization::build_with`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entries {
    /// The whole system's pattern, for an assembly of the whole system.
    Whole,
    /// This rank's rows, for a partitioned assembly over the ranks of the [`World`].
    Rows(World),
    /// None, only their number: a discretisation that tells its unknowns and entries but is not
    /// assembled (`fdfsi check`).
    Counted,
    /// None: a discretisation assembled only as a part of another system, into that system's
    /// target ([`FlowDiscretization::assemble_into`]: the fluid of an FSI system that is not
    /// whole), or not at all (a mesh rebuilt from a checkpoint).
    Unassembled,
}

/// Where a [`FlowDiscretization`]'s systems are assembled.
enum Sparsity {
    /// The whole system, on every process.
    Whole(Pattern),
    /// This rank's rows of a partitioned assembly.
    Rows(FlowRows),
    /// Nowhere: the whole system's number of entries only ([`Entries::Counted`]).
    Counted(usize),
    /// Nowhere on its own ([`Entries::Unassembled`]).
    Unassembled,
}

/// This rank's part of a partitioned flow assembly: the [`Partition`] of the unknowns (the
/// velocity's nodes kept whole), the pattern of this rank's rows, and the cells with an unknown in
/// them, coloured (a [`Colouring::restricted`] of all cells').
pub struct FlowRows {
    pub partition: Partition,
    pub pattern: RowPattern,
    pub colouring: Colouring,
}

/// A cell kernel's scratch: cell values, coordinates, the old velocity and the cell's unknowns.
type CellScratch<const D: usize> = (CellValues<D>, Vec<[f64; D]>, Vec<f64>, Vec<f64>);

/// The P2+ velocity element of a fluid cell type.
fn p2plus<const D: usize>(cell: ReferenceCell) -> Result<ReferenceElement<D>, FlowError> {
    ReferenceElement::new(cell, ElementFamily::P2Plus).ok_or(FlowError::CellType(cell))
}

/// Quadrature degree of the cell integrals: exact for the P2+ stiffness on affine cells
/// (bubble gradients of degree D, squared) and high enough for smooth data.
fn cell_degree(d: usize) -> usize {
    if d == 2 {
        5
    } else {
        6
    }
}

impl<const D: usize> FlowDiscretization<D> {
    /// Builds topology, dof maps, pattern and colouring for `mesh`.
    pub fn build(mesh: Mesh<D>, formulation: Formulation) -> Result<Self, FlowError> {
        Self::build_with(mesh, formulation, Entries::Whole)
    }

    /// [`FlowDiscretization::build`] with the matrix `entries` it prepares: the whole pattern,
    /// this rank's rows only for a partitioned assembly ([`FlowRows`]; the velocity's nodes kept
    /// whole in the partition), or their number only.
    pub fn build_with(mesh: Mesh<D>, formulation: Formulation, entries: Entries) -> Result<Self, FlowError> {
        Self::build_with_outlets(mesh, formulation, &[], entries)
    }

    /// The discretisation of `mesh` for `problem`: its formulation, its Windkessel outlets
    /// ([`FlowDiscretization::build_with_outlets`]) and its symmetry planes of any normal
    /// ([`FlowDiscretization::normal_constraints`]), with the matrix `entries` it prepares.
    ///
    /// Fails where a symmetry boundary's facets are not all normal to its plane's normal
    /// ([`super::symmetry::PLANAR_TOLERANCE`]).
    pub fn build_for(mesh: Mesh<D>, problem: &FlowProblem<D>, entries: Entries) -> Result<Self, FlowError> {
        let outlets: Vec<String> = problem.windkessel.iter().map(|w| w.boundary.clone()).collect();
        let mut disc = Self::build_with_outlets(mesh, problem.formulation, &outlets, entries)?;
        disc.normal_constraints = disc.symmetry_constraints(problem)?;
        disc.symmetry = problem.symmetry.clone();
        Ok(disc)
    }

    /// The constraints of the symmetry planes of `problem` at the velocity nodes on them (each
    /// with the normals of its planes), the components its Dirichlet conditions hold left out;
    /// fails on a boundary whose facet normals (at the facet quadrature points) are not all
    /// its plane's.
    fn symmetry_constraints(&self, problem: &FlowProblem<D>) -> Result<NormalConstraints, FlowError> {
        if problem.symmetry.is_empty() {
            return Ok(NormalConstraints::default());
        }
        let held: std::collections::HashSet<usize> = self.dirichlet_dofs(problem, 0.0)?.into_iter().map(|(d, _)| d).collect();
        let vel = self.velocity_field();
        let mut normals: std::collections::BTreeMap<usize, Vec<[f64; D]>> = Default::default();
        let (mut fv, mut coords) = (self.facet_values(), Vec::new());
        for plane in &problem.symmetry {
            let mut planarity = Planarity::new(plane);
            for bf in self.mesh.boundary_facets(&plane.boundary)? {
                self.mesh.cell_coords_into(bf.cell, &mut coords);
                fv.reinit(&coords, bf.facet).map_err(|source| FlowError::Map { cell: bf.cell, source })?;
                for q in 0..fv.num_points() {
                    planarity.facet_normal(bf.cell, fv.normal[q]);
                }
                let nodes = vel.nodes.cell(bf.cell);
                for k in self.velocity_element.facet_nodes(bf.facet) {
                    let list = normals.entry(nodes[k]).or_default();
                    if !list.contains(&plane.normal) {
                        list.push(plane.normal);
                    }
                }
            }
            planarity.finish()?;
        }
        let nodes = normals.into_iter().map(|(node, n)| (std::array::from_fn(|a| vel.dof(node, a)), n));
        Ok(NormalConstraints::new(nodes, |d| held.contains(&d)))
    }

    /// The constraints `u . n = 0` of the symmetry planes of any normal at the velocity nodes
    /// on them ([`FlowDiscretization::build_for`]): the row operations every assembly of the
    /// system ends with, and the projection of the state.
    pub fn normal_constraints(&self) -> &NormalConstraints {
        &self.normal_constraints
    }

    /// Checks that `problem`'s symmetry planes are those this discretisation was built for.
    ///
    /// # Panics
    /// If they are not.
    fn check_symmetry(&self, problem: &FlowProblem<D>) {
        assert_eq!(problem.symmetry, self.symmetry, "the problem's symmetry planes are the discretisation's (FlowDiscretization::build_for)");
    }

    /// [`FlowDiscretization::build_with`] with Windkessel outlets on the boundaries `outlets`
    /// (those of the problem's [`WindkesselBc`]s, in order): two unknowns each after the
    /// layout's, `Q` and `P_c` ([`FlowDiscretization::windkessel_dofs`]), coupled to the velocity
    /// on the outlet's facets.
    pub fn build_with_outlets(mesh: Mesh<D>, formulation: Formulation, outlets: &[String], entries: Entries) -> Result<Self, FlowError> {
        if (formulation == Formulation::ThreeD) != (D == 3) {
            return Err(FlowError::Formulation { formulation, dim: D });
        }
        mesh.check()?;
        let velocity_element = p2plus::<D>(mesh.cell_type)?;
        let geometry_element = mesh.geometry_element();
        let topology = Topology::build(&mesh);
        let vmap = NodeMap::continuous(&mesh, &topology, &velocity_element);
        let velocity_nodes = vmap.coordinates(&mesh, &velocity_element);
        let mut layout = BlockLayout::default();
        layout.push("velocity", D, vmap);
        layout.push("pressure", 1, NodeMap::discontinuous(mesh.num_cells(), D + 1));
        let colouring = Colouring::greedy(mesh.points.len(), mesh.num_cells(), |c| mesh.cell_vertices(c));
        // The outlets' couplings, as cells after the mesh's: each outlet facet's velocity dofs
        // with the outlet's two unknowns.
        let mut outlet_cells: Vec<Vec<usize>> = Vec::new();
        let vel = &layout.fields[0];
        for (k, name) in outlets.iter().enumerate() {
            let (q, pc) = (layout.num_dofs() + 2 * k, layout.num_dofs() + 2 * k + 1);
            for bf in mesh.boundary_facets(name)? {
                let nodes = vel.nodes.cell(bf.cell);
                let mut dofs: Vec<usize> =
                    velocity_element.facet_nodes(bf.facet).iter().flat_map(|&i| (0..D).map(move |a| vel.dof(nodes[i], a))).collect();
                dofs.extend([q, pc]);
                outlet_cells.push(dofs);
            }
            // Q and P_c with each other, whatever the outlet's facets.
            outlet_cells.push(vec![q, pc]);
        }
        let (nc, n) = (mesh.num_cells(), layout.num_dofs() + 2 * outlets.len());
        let cell_dofs = |c: usize, buf: &mut Vec<usize>| system_cell_dofs(&layout, nc, &outlet_cells, c, buf);
        let all_cells = nc + outlet_cells.len();
        let sparsity = match entries {
            Entries::Whole => Sparsity::Whole(Pattern::from_cells(n, all_cells, cell_dofs)),
            Entries::Counted => Sparsity::Counted(Pattern::count_from_cells(n, all_cells, cell_dofs)),
            Entries::Unassembled => Sparsity::Unassembled,
            Entries::Rows(_) if u32::try_from(n).is_err() => return Err(FlowError::TooManyUnknowns(n)),
            Entries::Rows(world) => {
                let nodes = Nodes { size: D, end: layout.fields[0].num_dofs() };
                let partition = Partition::from_cells(n, all_cells, cell_dofs, world, nodes);
                let cells = partition.cells_of_rows(all_cells, cell_dofs);
                let pattern = partition.row_pattern(&cells, cell_dofs);
                let colouring = colouring.restricted(|c| cells.binary_search(&c).is_ok());
                Sparsity::Rows(FlowRows { partition, pattern, colouring })
            }
        };
        let cell_rule = quadrature::for_cell::<D>(mesh.cell_type, cell_degree(D));
        let (facet_points, facet_weights) = quadrature::for_facets(mesh.cell_type, 6);
        let mut disc = FlowDiscretization {
            mesh,
            topology,
            velocity_element,
            geometry_element,
            layout,
            velocity_nodes,
            sparsity,
            colouring,
            cell_rule,
            facet_points,
            facet_weights,
            outlets: outlets.to_vec(),
            outlet_cells,
            outlet_weights: Vec::new(),
            symmetry: Vec::new(),
            normal_constraints: NormalConstraints::default(),
        };
        for name in outlets {
            let weights = disc.flux_weights(formulation, name).map_err(|e| FlowError::Map { cell: e.cell, source: e.source })?;
            disc.outlet_weights.push(weights);
        }
        Ok(disc)
    }

    /// The system's "cells", whose unknowns are coupled: the mesh's cells, then one per facet of
    /// each Windkessel outlet (its velocity dofs with the outlet's `Q` and `P_c`).
    pub fn num_system_cells(&self) -> usize {
        self.mesh.num_cells() + self.outlet_cells.len()
    }

    /// The unknowns of system cell `c` ([`FlowDiscretization::num_system_cells`]) into `buf`.
    pub fn system_cell_dofs(&self, c: usize, buf: &mut Vec<usize>) {
        system_cell_dofs(&self.layout, self.mesh.num_cells(), &self.outlet_cells, c, buf)
    }

    /// Number of unknowns: the layout's, then two per Windkessel outlet.
    pub fn num_dofs(&self) -> usize {
        self.layout.num_dofs() + 2 * self.outlets.len()
    }

    /// The unknowns `(Q, P_c)` of Windkessel outlet `k`: its flux and capacitor pressure.
    pub fn windkessel_dofs(&self, k: usize) -> (usize, usize) {
        let base = self.layout.num_dofs() + 2 * k;
        (base, base + 1)
    }

    /// The boundaries of the Windkessel outlets, in the order of their unknowns.
    pub fn outlets(&self) -> &[String] {
        &self.outlets
    }

    /// The state a run starts from: zero velocity and pressure, and each Windkessel's
    /// capacitor pressure at its `initial_pressure`.
    pub fn initial_state(&self, problem: &FlowProblem<D>) -> Vec<f64> {
        let mut x = vec![0.0; self.num_dofs()];
        for (k, wk) in problem.windkessel.iter().enumerate() {
            x[self.windkessel_dofs(k).1] = wk.initial_pressure;
        }
        x
    }

    /// The whole system's pattern; `None` for a partitioned assembly
    /// ([`FlowDiscretization::rows`]) or a discretisation of counted entries.
    pub fn pattern(&self) -> Option<&Pattern> {
        match &self.sparsity {
            Sparsity::Whole(pattern) => Some(pattern),
            Sparsity::Rows(_) | Sparsity::Counted(_) | Sparsity::Unassembled => None,
        }
    }

    /// The whole system's pattern of a discretisation that [`FlowDiscretization::build`] (or
    /// `build_with` and [`Entries::Whole`]) made.
    ///
    /// # Panics
    /// For another one.
    pub fn whole_pattern(&self) -> &Pattern {
        self.pattern().expect("a flow discretisation built whole (FlowDiscretization::build)")
    }

    /// This rank's part of a partitioned assembly ([`FlowDiscretization::build_with`]).
    pub fn rows(&self) -> Option<&FlowRows> {
        match &self.sparsity {
            Sparsity::Rows(rows) => Some(rows),
            Sparsity::Whole(_) | Sparsity::Counted(_) | Sparsity::Unassembled => None,
        }
    }

    /// The number of matrix entries: the whole pattern's, or this rank's rows' for a partitioned
    /// assembly; `None` for [`Entries::Unassembled`].
    pub fn nnz(&self) -> Option<usize> {
        match &self.sparsity {
            Sparsity::Whole(pattern) => Some(pattern.nnz()),
            Sparsity::Rows(rows) => Some(rows.pattern.nnz()),
            Sparsity::Counted(nnz) => Some(*nnz),
            Sparsity::Unassembled => None,
        }
    }

    /// The velocity field (P2+, `D` components per node): the first block of the layout.
    pub fn velocity_field(&self) -> &Field {
        &self.layout.fields[0]
    }

    /// The pressure field (P1 discontinuous: `D + 1` dofs per cell): the second block.
    pub fn pressure_field(&self) -> &Field {
        &self.layout.fields[1]
    }

    /// Fresh cell values for this discretisation at a rule.
    pub fn cell_values(&self, rule: QuadratureRule<D>) -> CellValues<D> {
        CellValues::new(rule, &self.velocity_element, &self.geometry_element)
    }

    /// Fresh facet values.
    pub fn facet_values(&self) -> FacetValues<D> {
        FacetValues::new(self.mesh.cell_type, &self.facet_points, &self.facet_weights, &self.velocity_element, &self.geometry_element)
    }

    /// The saddle-point split of the flow system for block preconditioners: the pressure as the
    /// one multiplier block, with its cell mass matrices `M_K = int_K psi_k psi_l w dx` (`w` the
    /// formulation's weight).
    pub fn saddle_point_split(&self, formulation: Formulation) -> Result<SaddlePointSplit, FlowError> {
        let mut block = MultiplierBlock::new("pressure");
        let mut cv = self.cell_values(self.cell_rule.clone());
        let (mut coords, mut mass) = (Vec::new(), vec![0.0; (D + 1) * (D + 1)]);
        let pf = self.pressure_field();
        for c in 0..self.mesh.num_cells() {
            self.mesh.cell_coords_into(c, &mut coords);
            cv.reinit(&coords).map_err(|source| FlowError::Map { cell: c, source })?;
            p1disc_mass(&cv, |x| formulation.weight(x), &mut mass);
            let dofs: Vec<usize> = (0..=D).map(|k| pf.dof(c * (D + 1) + k, 0)).collect();
            block.push_group(&dofs, &mass);
        }
        // The Windkessel unknowns after the pressure are primal too: then the primal unknowns
        // are not one vector field.
        let primal_components = if self.outlets.is_empty() { D } else { 1 };
        let constraint_rows = self.normal_constraints.constraint_rows().collect();
        Ok(SaddlePointSplit { multipliers: vec![block], primal_components, constraint_rows })
    }

    /// Sets the Dirichlet values at time `t` in `x`, projects the velocity onto the symmetry
    /// planes' constraints ([`NormalConstraints::project`]) and returns which dofs the Dirichlet
    /// values constrain (the mask the assembly takes).
    pub fn impose_dirichlet(&self, problem: &FlowProblem<D>, t: f64, x: &mut [f64]) -> Result<Vec<bool>, FlowError> {
        self.check_symmetry(problem);
        let mut constrained = vec![false; self.num_dofs()];
        for (d, v) in self.dirichlet_dofs(problem, t)? {
            constrained[d] = true;
            x[d] = v;
        }
        self.normal_constraints.project(x);
        Ok(constrained)
    }

    /// Global dofs constrained by the Dirichlet conditions and their values at time `t`.
    pub fn dirichlet_dofs(&self, problem: &FlowProblem<D>, t: f64) -> Result<Vec<(usize, f64)>, FlowError> {
        let vel = &self.velocity_field();
        let mut out: Vec<(usize, f64)> = Vec::new();
        let mut seen = vec![false; self.num_dofs()];
        for bc in &problem.dirichlet {
            for bf in self.mesh.boundary_facets(&bc.boundary)? {
                let nodes = vel.nodes.cell(bf.cell);
                for k in self.velocity_element.facet_nodes(bf.facet) {
                    let node = nodes[k];
                    let value = (bc.value)(&self.velocity_nodes[node], t);
                    for &a in &bc.components {
                        let dof = vel.dof(node, a);
                        if !seen[dof] {
                            seen[dof] = true;
                            out.push((dof, value[a]));
                        }
                    }
                }
            }
        }
        if problem.pin_pressure {
            let p = &self.pressure_field();
            out.push((p.dof(0, 0), 0.0));
        }
        Ok(out)
    }

    /// The residual `R(x)` with no rows constrained (Dirichlet rows included) and none combined
    /// (the symmetry planes' nodes' rows as assembled), for reaction forces: all of it, from all
    /// cells, on every process (no matrix), equal to [`FlowDiscretization::assemble_system`]'s
    /// `-rhs` with nothing constrained and no symmetry plane of any normal.
    pub fn raw_residual(&self, problem: &FlowProblem<D>, x: &[f64], x_old: &[f64], t: f64) -> Result<Vec<f64>, FlowError> {
        let mut rhs = vec![0.0; self.num_dofs()];
        let free = vec![false; self.num_dofs()];
        let target = &mut ResidualOnly { rhs: &mut rhs };
        self.assemble_into(problem, x, x_old, t, &free, &self.colouring, target).map_err(|e| FlowError::Map { cell: e.cell, source: e.source })?;
        rhs.iter_mut().for_each(|v| *v = -*v);
        Ok(rhs)
    }

    /// Assembles the Jacobian `k` and `rhs = -R(x)` of the flow problem at time `t`; rows of the
    /// constrained dofs become identity rows with zero right-hand side, and the rows of the
    /// nodes on symmetry planes of any normal the tangential equations and constraint rows of
    /// [`NormalConstraints`].
    #[allow(clippy::too_many_arguments, reason = "the state, the history, the time and the constraints of one system")]
    pub fn assemble_system(
        &self,
        problem: &FlowProblem<D>,
        x: &[f64],
        x_old: &[f64],
        t: f64,
        constrained: &[bool],
        k: &mut CscMatrix<'_>,
        rhs: &mut [f64],
    ) -> Result<(), AssemblyError> {
        self.check_symmetry(problem);
        self.normal_constraints.check_free(constrained);
        let target = &mut WholeSystem { k, rhs };
        self.assemble_into(problem, x, x_old, t, constrained, &self.colouring, target)?;
        self.normal_constraints.apply(target);
        Ok(())
    }

    /// [`FlowDiscretization::assemble_system`] into this rank's rows of a partitioned assembly
    /// (`k` on [`FlowRows::pattern`], `rhs` of the rows, in the partition's numbering; `x`,
    /// `x_old` and `constrained` of all unknowns): those rows of that assembly, bit for bit.
    ///
    /// # Panics
    /// If this discretisation is not partitioned ([`FlowDiscretization::rows`] is `None`).
    #[allow(clippy::too_many_arguments, reason = "the state, the history, the time and the constraints of one system")]
    pub fn assemble_rows(
        &self,
        problem: &FlowProblem<D>,
        x: &[f64],
        x_old: &[f64],
        t: f64,
        constrained: &[bool],
        k: &mut RowMatrix<'_>,
        rhs: &mut [f64],
    ) -> Result<(), AssemblyError> {
        let part = self.rows().expect("assemble_rows of a partitioned discretisation");
        self.check_symmetry(problem);
        self.normal_constraints.check_free(constrained);
        let numbering = part.partition.numbering();
        let to_global = |d: usize| numbering.to_petsc(d);
        // SAFETY: the partition's numbering is a permutation of the unknowns.
        let target = &mut unsafe { HeldRows::new(k, rhs, &to_global) };
        self.assemble_into(problem, x, x_old, t, constrained, &part.colouring, target)?;
        // The partition keeps the velocity's nodes whole: a node's rows are held together.
        self.normal_constraints.apply(target);
        Ok(())
    }

    /// The flow system at `x` (history `x_old`, time `t`) assembled into `target` from the cells
    /// of `colouring` (all of them, or those with an unknown in the target's rows), the traction
    /// boundaries, and identity rows with a zero right-hand side for the `constrained` unknowns
    /// (whose rows the cells and tractions leave out): `K = dR/dx` and `rhs = -R(x)`. The rows of
    /// the symmetry planes' nodes are left as assembled: the system that holds them ends its
    /// assembly with [`NormalConstraints::apply`], after every contribution to them.
    #[allow(clippy::too_many_arguments, reason = "the state, the history, the time, the constraints and where they go")]
    pub fn assemble_into(
        &self,
        problem: &FlowProblem<D>,
        x: &[f64],
        x_old: &[f64],
        t: f64,
        constrained: &[bool],
        colouring: &Colouring,
        target: &mut impl SystemTarget,
    ) -> Result<(), AssemblyError> {
        target.add_cells(colouring, constrained, self.cell_scratch(problem.params.stabilization), self.cell_kernel(problem, x, x_old, t))?;
        self.add_tractions(problem, t, |dof, v| {
            if !constrained[dof] {
                target.add_rhs(dof, -v);
            }
        })?;
        self.add_windkessels(problem, x, x_old, constrained, target);
        self.add_backflow(problem, x, constrained, target)?;
        for (dof, _) in constrained.iter().enumerate().filter(|(_, &c)| c) {
            target.identity_row(dof);
        }
        Ok(())
    }

    /// A fresh scratch of [`FlowDiscretization::cell_kernel`], per thread.
    /// With SUPG the cell values carry the basis' second derivatives. The values are tabulated
    /// once here and copied into each scratch (the assembly may make many).
    fn cell_scratch(&self, stabilization: Stabilization) -> impl Fn() -> CellScratch<D> + Sync + Send + '_ {
        let n = self.layout.dofs_per_cell();
        let cv = self.cell_values(self.cell_rule.clone());
        let cv = match stabilization {
            Stabilization::None => cv,
            Stabilization::Supg => cv.with_hessians(&self.velocity_element, &self.geometry_element),
        };
        move || (cv.clone(), Vec::new(), Vec::new(), vec![0.0; n])
    }

    /// The flow's cell kernel at `x` (history `x_old`, time `t`): the cell's unknowns, its
    /// Jacobian and `-R` ([`fluid_cell`]).
    fn cell_kernel<'a>(
        &'a self,
        problem: &'a FlowProblem<D>,
        x: &'a [f64],
        x_old: &'a [f64],
        t: f64,
    ) -> impl Fn(usize, &mut CellScratch<D>, &mut LocalSystem) -> Result<(), AssemblyError> + Sync + 'a {
        let nu = self.velocity_element.num_dofs() * D;
        let n = self.layout.dofs_per_cell();
        move |c, (cv, coords, u_old, u_loc), local| {
            self.mesh.cell_coords_into(c, coords);
            cv.reinit(coords).map_err(|source| AssemblyError { cell: c, source })?;
            self.layout.cell_dofs_into(c, &mut local.dofs);
            local.reset(n);
            for (i, &d) in local.dofs.iter().enumerate() {
                u_loc[i] = x[d];
            }
            u_old.clear();
            u_old.extend(local.dofs[..nu].iter().map(|&d| x_old[d]));
            let state = CellState { u: &u_loc[..nu], u_old, p: &u_loc[nu..] };
            let zero = [0.0; D];
            let f = |p: &[f64; D]| problem.body_force.as_ref().map_or(zero, |force| force(p, t));
            fluid_cell(cv, problem.formulation, &problem.params, &state, &f, &mut local.ke, &mut local.fe);
            local.fe.iter_mut().for_each(|v| *v = -*v);
            Ok(())
        }
    }

    /// The traction boundaries' terms of `R` at time `t`: `add(dof, term)` for each (few facets:
    /// serial, in facet order).
    fn add_tractions(&self, problem: &FlowProblem<D>, t: f64, mut add: impl FnMut(usize, f64)) -> Result<(), AssemblyError> {
        let mut fv = self.facet_values();
        let mut coords = Vec::new();
        let mut re = vec![0.0; self.velocity_element.num_dofs() * D];
        let vel = &self.velocity_field();
        for bc in &problem.traction {
            let facets = self.mesh.boundary_facets(&bc.boundary).unwrap_or_default();
            for bf in facets {
                self.mesh.cell_coords_into(bf.cell, &mut coords);
                fv.reinit(&coords, bf.facet).map_err(|source| AssemblyError { cell: bf.cell, source })?;
                re.iter_mut().for_each(|v| *v = 0.0);
                let tr = |p: &[f64; D], nrm: &[f64; D]| (bc.traction)(p, nrm, t);
                traction_facet(&fv, problem.formulation, &tr, &mut re);
                for (i, &node) in vel.nodes.cell(bf.cell).iter().enumerate() {
                    for a in 0..D {
                        add(vel.dof(node, a), re[i * D + a]);
                    }
                }
            }
        }
        Ok(())
    }

    /// The backflow stabilisation's terms at `x` ([`BackflowBc`]; with convection only):
    /// `-int t_b . v w ds` in `R` and its derivative,
    /// `dt_b/du = beta rho / 2 (min(u . n, 0) I + [u . n < 0] u n^T)`.
    fn add_backflow(&self, problem: &FlowProblem<D>, x: &[f64], constrained: &[bool], target: &mut impl SystemTarget) -> Result<(), AssemblyError> {
        let mut fv = self.facet_values();
        let mut coords = Vec::new();
        let vel = &self.velocity_field();
        let mut dofs = Vec::new();
        for bc in problem.backflow.iter().filter(|_| problem.params.convection) {
            let scale = 0.5 * bc.beta * problem.params.density;
            for bf in self.mesh.boundary_facets(&bc.boundary).unwrap_or_default() {
                self.mesh.cell_coords_into(bf.cell, &mut coords);
                fv.reinit(&coords, bf.facet).map_err(|source| AssemblyError { cell: bf.cell, source })?;
                dofs.clear();
                dofs.extend(vel.nodes.cell(bf.cell).iter().map(|&node| std::array::from_fn::<usize, D, _>(|a| vel.dof(node, a))));
                for q in 0..fv.num_points() {
                    let phi = fv.phi(q);
                    let u: [f64; D] = std::array::from_fn(|a| phi.iter().zip(&dofs).map(|(f, d)| f * x[d[a]]).sum());
                    let n = fv.normal[q];
                    let un: f64 = (0..D).map(|a| u[a] * n[a]).sum();
                    if un >= 0.0 {
                        continue;
                    }
                    let w = scale * fv.jxw[q] * problem.formulation.weight(&fv.x[q]);
                    for (i, di) in dofs.iter().enumerate() {
                        for a in (0..D).filter(|&a| !constrained[di[a]]) {
                            target.add_rhs(di[a], w * un * u[a] * phi[i]);
                            for (j, dj) in dofs.iter().enumerate() {
                                for b in 0..D {
                                    let d = if a == b { un } else { 0.0 } + u[a] * n[b];
                                    target.add_matrix(di[a], dj[b], -w * phi[i] * d * phi[j]);
                                }
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// `b_i = int_outlet phi_i n_a w ds` of the velocity dofs on boundary `name`, in dof order:
    /// the outlet flux is `s sum_i b_i u_i` ([`WindkesselBc`]).
    pub fn flux_weights(&self, formulation: Formulation, name: &str) -> Result<Vec<(usize, f64)>, AssemblyError> {
        let mut fv = self.facet_values();
        let mut coords = Vec::new();
        let vel = &self.velocity_field();
        let mut weights = std::collections::BTreeMap::new();
        for bf in self.mesh.boundary_facets(name).unwrap_or_default() {
            self.mesh.cell_coords_into(bf.cell, &mut coords);
            fv.reinit(&coords, bf.facet).map_err(|source| AssemblyError { cell: bf.cell, source })?;
            let nodes = vel.nodes.cell(bf.cell);
            for q in 0..fv.num_points() {
                let w = fv.jxw[q] * formulation.weight(&fv.x[q]);
                let phi = fv.phi(q);
                for i in self.velocity_element.facet_nodes(bf.facet) {
                    for a in 0..D {
                        *weights.entry(vel.dof(nodes[i], a)).or_insert(0.0) += w * phi[i] * fv.normal[q][a];
                    }
                }
            }
        }
        Ok(weights.into_iter().collect())
    }

    /// The Windkessel outlets' terms at `x` (history `x_old`, `a0/dt` in the problem's
    /// parameters): the outlet pressure's traction in the velocity rows, and the rows of `Q` and
    /// `P_c` ([`WindkesselBc`]), with the outlets' flux weights of the formulation the
    /// discretisation was built for.
    fn add_windkessels(&self, problem: &FlowProblem<D>, x: &[f64], x_old: &[f64], constrained: &[bool], target: &mut impl SystemTarget) {
        assert_eq!(
            problem.windkessel.iter().map(|w| &w.boundary).collect::<Vec<_>>(),
            self.outlets.iter().collect::<Vec<_>>(),
            "the problem's Windkessel outlets are the discretisation's"
        );
        let s = problem.formulation.around();
        let inv_dt = problem.params.inv_dt;
        for (k, wk) in problem.windkessel.iter().enumerate() {
            let (iq, ic) = self.windkessel_dofs(k);
            let b = &self.outlet_weights[k];
            let (q, pc) = (x[iq], x[ic]);
            let pressure = wk.outlet_pressure(q, pc);
            for &(dof, bi) in b.iter().filter(|(dof, _)| !constrained[*dof]) {
                target.add_rhs(dof, -pressure * bi);
                target.add_matrix(dof, iq, wk.proximal_resistance * bi);
                target.add_matrix(dof, ic, bi);
            }
            let flux: f64 = s * b.iter().map(|&(dof, bi)| bi * x[dof]).sum::<f64>();
            target.add_rhs(iq, -(q - flux));
            target.add_matrix(iq, iq, 1.0);
            for &(dof, bi) in b {
                target.add_matrix(iq, dof, -s * bi);
            }
            let storage = wk.compliance * inv_dt;
            target.add_rhs(ic, -(storage * (pc - x_old[ic]) - q + (pc - wk.distal_pressure) / wk.distal_resistance));
            target.add_matrix(ic, ic, storage + 1.0 / wk.distal_resistance);
            target.add_matrix(ic, iq, -1.0);
        }
    }

    /// Solves `R(x) = 0` by Newton from `x` for the problem at time `t` (history `x_old`,
    /// Dirichlet rows `constrained`): with `solver` on the whole system, or, for a partitioned
    /// assembly, through its [`crate::solve::partition::RowSolver`] on this rank's rows
    /// ([`newton::solve_rows`]).
    #[allow(clippy::too_many_arguments, reason = "the state, the history, the time, the constraints, the solver and its options")]
    pub fn solve_newton(
        &self,
        problem: &FlowProblem<D>,
        x: &mut [f64],
        x_old: &[f64],
        t: f64,
        constrained: &[bool],
        solver: &mut dyn LinearSolver,
        options: &NewtonOptions,
    ) -> Result<NewtonReport, NewtonError<AssemblyError>> {
        match &self.sparsity {
            Sparsity::Whole(pattern) => {
                newton::solve(x, pattern, solver, options, |x, k, rhs| self.assemble_system(problem, x, x_old, t, constrained, k, rhs))
            }
            Sparsity::Counted(_) | Sparsity::Unassembled => {
                Err(LinearSolveError::Setup("a flow discretisation without its pattern or rows (Entries::Counted, Unassembled) is not solved".into())
                    .into())
            }
            Sparsity::Rows(part) => {
                let rows = row_solver_of(solver, &part.partition)?;
                newton::solve_rows(x, &part.partition, &part.pattern, rows, options, |x, k, rhs| {
                    self.assemble_rows(problem, x, x_old, t, constrained, k, rhs)
                })
            }
        }
    }
}

/// A flow solution on a discretisation: the global vector in the layout's numbering.
#[derive(Clone, Debug)]
pub struct FlowSolution {
    pub x: Vec<f64>,
    pub newton: NewtonReport,
}

impl FlowSolution {
    /// Velocity at velocity node `node`.
    pub fn velocity<const D: usize>(&self, disc: &FlowDiscretization<D>, node: usize) -> [f64; D] {
        let f = &disc.velocity_field();
        std::array::from_fn(|a| self.x[f.dof(node, a)])
    }
    /// Pressure dofs of cell `c`: value at the centroid, then the gradient.
    pub fn pressure_dofs<'a, const D: usize>(&'a self, disc: &FlowDiscretization<D>, c: usize) -> &'a [f64] {
        let f = &disc.pressure_field();
        let s = f.dof(c * (D + 1), 0);
        &self.x[s..s + D + 1]
    }
}

/// The Newton system of the steady problem at `t = 0`: `K(x) = dR/dx` and `-R(x)` for any
/// iterate `x`, with the Dirichlet rows of [`FlowDiscretization::impose_dirichlet`].
pub struct SteadySystem<'a, const D: usize> {
    pub disc: &'a FlowDiscretization<D>,
    pub problem: &'a FlowProblem<D>,
    /// Dofs whose values the Dirichlet conditions fix.
    pub constrained: Vec<bool>,
    /// The previous time level of the unsteady assembly: unused at steady state (zero).
    x_old: Vec<f64>,
}

impl<'a, const D: usize> SteadySystem<'a, D> {
    /// The system and the starting iterate: the Dirichlet values, zero elsewhere.
    pub fn new(disc: &'a FlowDiscretization<D>, problem: &'a FlowProblem<D>) -> Result<(Self, Vec<f64>), FlowError> {
        let mut x = vec![0.0; disc.num_dofs()];
        let constrained = disc.impose_dirichlet(problem, 0.0, &mut x)?;
        Ok((SteadySystem { disc, problem, constrained, x_old: vec![0.0; x.len()] }, x))
    }

    /// Overwrites `k` with `K(x)` and `rhs` with `-R(x)`.
    pub fn assemble(&self, x: &[f64], k: &mut CscMatrix<'_>, rhs: &mut [f64]) -> Result<(), AssemblyError> {
        k.values.iter_mut().for_each(|v| *v = 0.0);
        rhs.iter_mut().for_each(|v| *v = 0.0);
        self.disc.assemble_system(self.problem, x, &self.x_old, 0.0, &self.constrained, k, rhs)
    }

    /// Newton from `x` on this system ([`FlowDiscretization::solve_newton`]).
    pub fn solve(&self, x: &mut [f64], solver: &mut dyn LinearSolver, options: &NewtonOptions) -> Result<NewtonReport, NewtonError<AssemblyError>> {
        self.disc.solve_newton(self.problem, x, &self.x_old, 0.0, &self.constrained, solver, options)
    }
}

/// Solves the steady problem (`params.inv_dt` must be 0) with Newton from the Dirichlet values
/// (zero elsewhere).
///
/// With `options.continuation`, a Navier-Stokes problem on which Newton fails from rest (not
/// converged, or not finite) is solved by continuation in the viscosity: first at
/// `eta_0 = 4^k eta` for the smallest `k` at which Newton converges from rest, then at viscosities
/// that approach `eta` geometrically, each from the solution before; a failed stage halves the
/// logarithmic step (at most [`MAX_CONTINUATION_SOLVES`] solves in all). The report has the last
/// solve's residuals and the work of all converged stages summed.
pub fn solve_steady<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
) -> Result<FlowSolution, FlowError> {
    let (system, mut x) = SteadySystem::new(disc, problem)?;
    solver.set_split(disc.saddle_point_split(problem.formulation)?);
    let options = &NewtonOptions { line_search: Some(options.line_search.unwrap_or(true)), ..problem.newton_options(options) };
    let x0 = x.clone();
    let report = match system.solve(&mut x, solver, options) {
        Ok(report) => report,
        Err(NewtonError::NotConverged { .. } | NewtonError::NonFinite { .. } | NewtonError::LineSearch { .. })
            if options.continuation && problem.params.convection =>
        {
            x = x0;
            continue_in_viscosity(disc, problem, solver, options, &mut x)?
        }
        Err(e) => return Err(e.into()),
    };
    if problem.pin_pressure {
        shift_pressure_to_zero_mean(disc, problem.formulation, &mut x)?;
    }
    Ok(FlowSolution { x, newton: report })
}

/// Most Newton solves of a viscosity continuation ([`solve_steady`]).
pub const MAX_CONTINUATION_SOLVES: usize = 24;
/// Most Newton iterations of one continuation stage.
const STAGE_MAX_ITERATIONS: usize = 10;

/// The continuation of [`solve_steady`], from the rest state `x` (overwritten with the solution).
fn continue_in_viscosity<const D: usize>(
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    solver: &mut dyn LinearSolver,
    options: &NewtonOptions,
    x: &mut Vec<f64>,
) -> Result<NewtonReport, FlowError> {
    let target = problem.params.viscosity;
    let mut stage = problem.clone();
    // A stage starts near its solution: one that needs many iterations is failing.
    let options = &NewtonOptions { max_iterations: options.max_iterations.min(STAGE_MAX_ITERATIONS), ..options.clone() };
    let mut total = NewtonReport::default();
    let mut solves = 0;
    // One stage at viscosity `eta` from `x`; `x` takes its solution when it converges.
    let mut solve_at = |eta: f64, x: &mut Vec<f64>, total: &mut NewtonReport| -> Result<NewtonReport, FlowError> {
        stage.params.viscosity = eta;
        let (system, _) = SteadySystem::new(disc, &stage)?;
        tracing::debug!("continuation: viscosity {eta:.4e} (target {target:.4e})");
        let mut trial = x.clone();
        let report = system.solve(&mut trial, solver, options)?;
        total.add(&report);
        *x = trial;
        Ok(report)
    };
    let failed = |reached: f64, solves: usize, e: FlowError| FlowError::Continuation { reached, target, solves, source: Box::new(e) };
    // A viscosity at which Newton converges from rest.
    let mut eta = target;
    let mut last = loop {
        eta *= 4.0;
        solves += 1;
        match solve_at(eta, x, &mut total) {
            Ok(report) => break report,
            Err(e) if solves >= MAX_CONTINUATION_SOLVES => return Err(failed(f64::INFINITY, solves, e)),
            Err(_) => {} // x is still the rest state
        }
    };
    // Towards the target: ratio `eta / eta_next`, halved in the logarithm after a failure.
    let mut ratio: f64 = 4.0;
    while eta > target {
        let next = (eta / ratio).max(target);
        solves += 1;
        match solve_at(next, x, &mut total) {
            Ok(report) => (eta, last) = (next, report),
            Err(e) if solves >= MAX_CONTINUATION_SOLVES || ratio < 1.01 => return Err(failed(eta, solves, e)),
            Err(_) => ratio = ratio.sqrt(),
        }
    }
    // The last stage's residuals, the work of all converged stages.
    Ok(NewtonReport { residual_norms: last.residual_norms, update_norms: last.update_norms, ..total })
}

/// Adds a constant to the pressure so that its (weighted) mean over the domain is zero.
fn shift_pressure_to_zero_mean<const D: usize>(disc: &FlowDiscretization<D>, formulation: Formulation, x: &mut [f64]) -> Result<(), FlowError> {
    let mut cv = disc.cell_values(disc.cell_rule.clone());
    let mut coords = Vec::new();
    let (mut int_p, mut vol) = (0.0, 0.0);
    let pf = &disc.pressure_field();
    let mut psi = [0.0; 4];
    for c in 0..disc.mesh.num_cells() {
        disc.mesh.cell_coords_into(c, &mut coords);
        cv.reinit(&coords).map_err(|source| FlowError::Map { cell: c, source })?;
        for q in 0..cv.num_points() {
            let w = cv.jxw[q] * formulation.weight(&cv.x[q]);
            p1disc_basis(&cv.x[q], &cv.centroid, &mut psi);
            let p: f64 = (0..=D).map(|k| x[pf.dof(c * (D + 1) + k, 0)] * psi[k]).sum();
            int_p += w * p;
            vol += w;
        }
    }
    let mean = int_p / vol;
    for c in 0..disc.mesh.num_cells() {
        x[pf.dof(c * (D + 1), 0)] -= mean;
    }
    Ok(())
}

/// Exact solution for error norms: velocity, velocity gradient `g[a][b] = du_a/dx_b`, pressure.
pub struct ExactFlow<'a, const D: usize> {
    pub velocity: &'a dyn Fn(&[f64; D]) -> [f64; D],
    pub gradient: &'a dyn Fn(&[f64; D]) -> [[f64; D]; D],
    pub pressure: &'a dyn Fn(&[f64; D]) -> f64,
}

/// Errors of a discrete flow against an exact one (weighted by `r` when axisymmetric).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct FlowErrors {
    pub velocity_l2: f64,
    pub velocity_h1: f64,
    pub pressure_l2: f64,
    /// `max_K |int_K div u_h|` (weighted): zero to round-off for P2+/P1disc.
    pub max_cell_divergence: f64,
}

/// Computes [`FlowErrors`] with a quadrature rule of degree `degree`.
pub fn flow_errors<const D: usize>(
    disc: &FlowDiscretization<D>,
    formulation: Formulation,
    x: &[f64],
    exact: &ExactFlow<'_, D>,
    degree: usize,
) -> Result<FlowErrors, FlowError> {
    let mut cv = disc.cell_values(quadrature::for_cell(disc.mesh.cell_type, degree));
    let vf = &disc.velocity_field();
    let pf = &disc.pressure_field();
    let mut coords = Vec::new();
    let mut e = FlowErrors::default();
    let mut psi = [0.0; 4];
    for c in 0..disc.mesh.num_cells() {
        disc.mesh.cell_coords_into(c, &mut coords);
        cv.reinit(&coords).map_err(|source| FlowError::Map { cell: c, source })?;
        let nodes = vf.nodes.cell(c);
        let mut cell_div = 0.0;
        for q in 0..cv.num_points() {
            let xq = cv.x[q];
            let r = formulation.weight(&xq);
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
            p1disc_basis(&xq, &cv.centroid, &mut psi);
            let p: f64 = (0..=D).map(|k| x[pf.dof(c * (D + 1) + k, 0)] * psi[k]).sum();
            let (ue, ge, pe) = ((exact.velocity)(&xq), (exact.gradient)(&xq), (exact.pressure)(&xq));
            for a in 0..D {
                e.velocity_l2 += w * (u[a] - ue[a]).powi(2);
                for b in 0..D {
                    e.velocity_h1 += w * (g[a][b] - ge[a][b]).powi(2);
                }
            }
            if formulation == Formulation::Axisymmetric {
                e.velocity_h1 += w * ((u[1] - ue[1]) / r).powi(2);
            }
            e.pressure_l2 += w * (p - pe).powi(2);
            let mut div: f64 = (0..D).map(|a| g[a][a]).sum();
            if formulation == Formulation::Axisymmetric {
                div += u[1] / r;
            }
            cell_div += w * div;
        }
        e.max_cell_divergence = e.max_cell_divergence.max(cell_div.abs());
    }
    e.velocity_l2 = e.velocity_l2.sqrt();
    e.velocity_h1 = e.velocity_h1.sqrt();
    e.pressure_l2 = e.pressure_l2.sqrt();
    Ok(e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use fdfsi_fem::generate::{rectangle_triangles, DiagonalPattern};

    /// The backflow stabilisation's Jacobian equals a central finite difference of its residual,
    /// on an outlet where the fluid leaves through some facets and enters through others, plane
    /// and axisymmetric; where all of it leaves, the term is zero.
    #[test]
    fn backflow_jacobian_matches_finite_differences() {
        for formulation in [Formulation::Plane, Formulation::Axisymmetric] {
            let mesh = rectangle_triangles(0.0, 2.0, 0.5, 1.5, 3, 2, DiagonalPattern::Right);
            let disc = FlowDiscretization::build(mesh, formulation).unwrap();
            let params = FluidParams {
                viscosity: 0.0,
                density: 1.7,
                inv_dt: 0.0,
                convection: true,
                convective_form: Default::default(),
                viscous_form: Default::default(),
                stabilization: Default::default(),
            };
            let backflow = vec![BackflowBc { boundary: "right".into(), beta: 0.8 }];
            let problem = FlowProblem {
                formulation,
                params,
                body_force: None,
                dirichlet: vec![],
                traction: vec![],
                windkessel: vec![],
                backflow,
                symmetry: vec![],
                pin_pressure: false,
            };
            let n = disc.num_dofs();
            // u = (y - 1 + 0.3 sin(5 k), 0.5 cos(3 k)) at dof pair k: the fluid enters the
            // right side below y = 1 and leaves above it.
            let vel = disc.velocity_field();
            let mut x = vec![0.0; n];
            for (node, p) in vel.nodes.coordinates(&disc.mesh, &disc.velocity_element).iter().enumerate() {
                x[vel.dof(node, 0)] = p[1] - 1.0 + 0.3 * (5.0 * node as f64).sin();
                x[vel.dof(node, 1)] = 0.5 * (3.0 * node as f64).cos();
            }
            let free = vec![false; n];
            let mut k = CscMatrix::zeros(disc.whole_pattern());
            let mut rhs = vec![0.0; n];
            disc.assemble_system(&problem, &x, &x, 0.0, &free, &mut k, &mut rhs).unwrap();
            let without = FlowProblem { backflow: vec![], ..problem.clone() };
            let mut k0 = CscMatrix::zeros(disc.whole_pattern());
            let mut rhs0 = vec![0.0; n];
            disc.assemble_system(&without, &x, &x, 0.0, &free, &mut k0, &mut rhs0).unwrap();
            assert!(rhs.iter().zip(&rhs0).any(|(a, b)| (a - b).abs() > 1e-3), "the term acts where fluid enters");
            let h = 1e-6;
            let mut checked = 0;
            for j in (0..vel.num_dofs()).step_by(3) {
                let (mut xp, mut xm) = (x.clone(), x.clone());
                xp[j] += h;
                xm[j] -= h;
                let (rp, rm) = (disc.raw_residual(&problem, &xp, &xp, 0.0).unwrap(), disc.raw_residual(&problem, &xm, &xm, 0.0).unwrap());
                for i in 0..n {
                    let fd = (rp[i] - rm[i]) / (2.0 * h);
                    assert!((fd - k.get(i, j)).abs() < 1e-6 * (1.0 + fd.abs()), "{formulation:?} K[{i}][{j}] = {} vs FD {fd}", k.get(i, j));
                }
                checked += 1;
            }
            assert!(checked > 10);
            // All of the fluid leaving: no term.
            let leaving: Vec<f64> = (0..n).map(|d| if d < vel.num_dofs() && d % 2 == 0 { 1.0 } else { 0.0 }).collect();
            let (r1, r0) =
                (disc.raw_residual(&problem, &leaving, &leaving, 0.0).unwrap(), disc.raw_residual(&without, &leaving, &leaving, 0.0).unwrap());
            assert_eq!(r1, r0);
        }
    }
}
