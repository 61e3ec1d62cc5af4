//! `fdfsi check`: every check of a case that needs no solve, and a summary of the run.
//!
//! [`check`] goes beyond [`Case::validate`] (ranges and consistency of the case file alone): it
//! reads the time tables, builds the fluid mesh and the solid mesh, and checks that
//! - every boundary the case names (`[[boundary]]`, `[[output.boundary_integral]]`,
//!   `[[output.profile]]`) is a boundary of the mesh (with a solid also `gamma_f`,
//!   `gamma_f_plus`, `gamma_f_minus`; boundary conditions of an FSI run are given on the original
//!   fluid mesh, so there only its own names);
//! - the solid, at its placement, lies inside the fluid domain: every vertex of the solid mesh
//!   lies in a cell of the fluid mesh (up to a relative `1e-8` in barycentric coordinates);
//! - every velocity or pressure probe lies in the fluid mesh;
//! - the mesh can be adapted to the solid and the discretisation built.
//!
//! Errors name the case file and the table or key at fault. A valid case gets a
//! [`CheckSummary`]: unknowns per field, the number of steps and an estimate of the output size.

use super::RunError;
use crate::case::{name_of, BoundaryNames, Case, CaseError, ProbeField, RunKind, SolidBoundaryType, SolidSpec, TimeFn, TimeFunction};
use crate::discretize::flow::{Entries, FlowDiscretization};
use crate::discretize::fsi::FsiDiscretization;
use crate::discretize::solid::SolidDiscretization;
use crate::setup::{adapt_fluid, build_mesh, displacement_probes, flow_problem, fsi_model, solid_problem, SetupError, SolidMesh};
use crate::time::num_steps;
use fdfsi_fem::adapt::{CellLocator, GAMMA_F, GAMMA_F_MINUS, GAMMA_F_PLUS};
use fdfsi_fem::element::ReferenceCell;
use fdfsi_fem::gmsh::AnyMesh;
use fdfsi_fem::mesh::{bounding_box, Mesh};
use std::path::Path;

/// What `fdfsi check` reports about a valid case.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckSummary {
    /// One paragraph: the kind of run, its meshes and material.
    pub description: String,
    /// Unknowns per field, then `total`.
    pub dofs: Vec<(String, usize)>,
    /// Time steps (unsteady), load steps (solid only) or 1 (steady).
    pub steps: usize,
    /// What a step is: `"time steps"`, `"load steps"` or `"steady solve"`.
    pub step_kind: &'static str,
    /// How often the fields are written (one `.vtu` file per piece each time).
    pub field_writes: usize,
    /// Estimated size of one field write (all pieces), bytes.
    pub field_bytes: u64,
    /// Estimated size of `history.csv`, bytes.
    pub history_bytes: u64,
}

impl CheckSummary {
    /// Estimated size of everything the run writes (fields and history), bytes.
    pub fn output_bytes(&self) -> u64 {
        self.field_bytes.saturating_mul(self.field_writes as u64).saturating_add(self.history_bytes)
    }
}

impl std::fmt::Display for CheckSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "{}", self.description)?;
        let dofs: Vec<String> = self.dofs.iter().map(|(n, k)| format!("{n} {k}")).collect();
        writeln!(f, "dofs: {}", dofs.join(", "))?;
        let writes = if self.field_writes == 1 { "once".to_string() } else { format!("{} times", self.field_writes) };
        if self.step_kind == "steady solve" {
            writeln!(f, "steps: 1 (steady); fields written {writes}")?;
        } else {
            writeln!(f, "steps: {} {}; fields written {writes}", self.steps, self.step_kind)?;
        }
        write!(
            f,
            "output: about {} ({} x {} of fields, {} of history.csv; pictures and profiles not counted)",
            human_bytes(self.output_bytes()),
            self.field_writes,
            human_bytes(self.field_bytes),
            human_bytes(self.history_bytes)
        )
    }
}

/// `1234567` -> `"1.2 MB"`.
pub fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["kB", "MB", "GB", "TB", "PB"];
    if n < 1000 {
        return format!("{n} B");
    }
    let mut v = n as f64 / 1000.0;
    let mut unit = 0;
    while v >= 999.95 && unit + 1 < UNITS.len() {
        v /= 1000.0;
        unit += 1;
    }
    format!("{v:.1} {}", UNITS[unit])
}

/// Everything `fdfsi check` checks (see the module documentation); `file` names the case in
/// errors, relative paths are resolved against `case_dir`.
pub fn check(case: &Case, file: &str, case_dir: &Path) -> Result<CheckSummary, RunError> {
    case.validate(file)?;
    // Every error names the case file.
    check_unlabelled(case, file, case_dir).map_err(|e| match e {
        RunError::Case(CaseError::Invalid { .. } | CaseError::Parse { .. }) | RunError::Setup(SetupError::Case(_))
            if e.to_string().contains(file) =>
        {
            e
        }
        other => RunError::Case(CaseError::Invalid { file: file.to_string(), message: other.to_string() }),
    })
}

fn check_unlabelled(case: &Case, file: &str, case_dir: &Path) -> Result<CheckSummary, RunError> {
    let ctx = Ctx { case, file, dir: case_dir };
    ctx.check_tables()?;
    if case.mesh.is_none() {
        return if case.dim() == 2 { ctx.solid_only::<2>() } else { ctx.solid_only::<3>() };
    }
    let mesh = build_mesh(case, case_dir).map_err(|e| ctx.invalid(format!("[mesh]: {e}")))?;
    match mesh {
        AnyMesh::D2(m) => ctx.with_fluid::<2>(m),
        AnyMesh::D3(m) => ctx.with_fluid::<3>(m),
    }
}

struct Ctx<'a> {
    case: &'a Case,
    file: &'a str,
    dir: &'a Path,
}

impl Ctx<'_> {
    fn invalid(&self, message: String) -> RunError {
        RunError::Case(CaseError::Invalid { file: self.file.to_string(), message })
    }

    /// Reads every `time_function = { kind = "table" }` file.
    fn check_tables(&self) -> Result<(), RunError> {
        for b in &self.case.boundary {
            if let Some(f @ TimeFunction::Table { .. }) = &b.time_function {
                TimeFn::load(f, self.dir).map_err(|e| self.invalid(format!("boundary '{}': time_function table: {e}", b.name)))?;
            }
        }
        Ok(())
    }

    /// `name` must be one of `known`, the boundaries of the fluid mesh; `what` says where the
    /// case uses it.
    fn known_boundary(&self, known: &[String], name: &str, what: &str) -> Result<(), RunError> {
        self.known_name(known, name, what, "the mesh")
    }

    /// `name` must be one of `known`, the boundaries of `whose` (the error suggests the nearest).
    fn known_name(&self, known: &[String], name: &str, what: &str, whose: &str) -> Result<(), RunError> {
        if known.iter().any(|k| k == name) {
            return Ok(());
        }
        let hint = crate::case::nearest_name(known.iter().map(String::as_str), name).map(|n| format!(" (did you mean `{n}`?)")).unwrap_or_default();
        let list = if known.is_empty() { "none".to_string() } else { known.join(", ") };
        Err(self.invalid(format!("{what}: {whose} has no boundary '{name}'{hint}; its boundaries: {list}")))
    }

    fn solid_spec(&self) -> Result<&SolidSpec, RunError> {
        self.case.first_solid().ok_or_else(|| self.invalid("no [solid] table".into()))
    }

    /// The placed solid mesh, several solids joined ([`crate::setup::solid_mesh`]); each
    /// solid's `surface` and `[[solid.boundary]]` names must be boundaries of its own mesh.
    fn solid_mesh<const D: usize>(&self) -> Result<SolidMesh<D>, RunError> {
        for spec in &self.case.solid {
            let whose = match (&spec.name, self.case.solid.len() > 1) {
                (Some(name), true) => format!("solid '{name}': "),
                _ => String::new(),
            };
            self.solid_names::<D>(spec, &whose)?;
        }
        Ok(crate::setup::solid_mesh::<D>(self.case, self.dir)?)
    }

    /// `solid.surface` and the `[[solid.boundary]]` names of `spec` must be boundaries of its
    /// placed mesh; `whose` starts each message (the solid's name, when there are several).
    fn solid_names<const D: usize>(&self, spec: &SolidSpec, whose: &str) -> Result<(), RunError> {
        let mesh = crate::setup::placed_solid_mesh::<D>(spec, self.dir).map_err(|e| self.invalid(format!("{whose}[solid] mesh: {e}")))?;
        let names: Vec<String> = mesh.boundary_names.iter().map(|(n, _)| n.clone()).collect();
        match &spec.surface {
            Some(BoundaryNames::One(s)) => self.known_name(&names, s, &format!("{whose}solid.surface = \"{s}\""), "the solid mesh")?,
            Some(BoundaryNames::Several(list)) => {
                for s in list {
                    self.known_name(&names, s, &format!("{whose}solid.surface = {list:?}: \"{s}\""), "the solid mesh")?;
                }
            }
            None => {}
        }
        if spec.model != crate::case::SolidModel::Fixed {
            for b in &spec.boundary {
                self.known_name(&names, &b.name, &format!("{whose}[[solid.boundary]] name = \"{}\"", b.name), "the solid mesh")?;
            }
        }
        Ok(())
    }

    /// A solid-only run.
    fn solid_only<const D: usize>(&self) -> Result<CheckSummary, RunError> {
        let case = self.case;
        let spec = self.solid_spec()?;
        let SolidMesh { mesh, cell_body } = self.solid_mesh::<D>()?;
        let cells = mesh.num_cells();
        // As `fdfsi run` builds it: loads ramped without [time], evaluated in time with it.
        let problem = solid_problem::<D>(case, cell_body, case.time.is_none())?;
        let disc = SolidDiscretization::build_for(mesh, &problem)?;
        disc.check_problem(&problem)?;
        // Each displacement probe at a node of the solid mesh, as the run requires.
        displacement_probes(case, &disc)?;
        let lagrangian = if case.time.is_some() { crate::discretize::solid::Lagrangian::Total } else { spec.loading.mode };
        let description = format!(
            "{}: solid-only ({}), {D}D mesh of {cells} cells; {}; nnz {}; {:?} Lagrangian",
            case.title,
            problem.material_names(),
            disc.layout
                .fields
                .iter()
                .map(|f| (f.name.as_str(), f.num_dofs()))
                .chain((disc.num_contact_dofs() > 0).then(|| ("contact pressure", disc.num_contact_dofs())))
                .map(|(name, n)| format!("{name} {n}"))
                .collect::<Vec<_>>()
                .join(", "),
            disc.pattern.nnz(),
            lagrangian
        );
        let (steps, step_kind, field_writes, rows) = time_steps(case).unwrap_or((spec.loading.steps, "load steps", 1, spec.loading.steps));
        Ok(CheckSummary {
            description,
            dofs: with_total(super::solid::solid_dofs(&disc)),
            steps,
            step_kind,
            field_writes,
            field_bytes: solid_vtu_bytes(&disc),
            history_bytes: history_bytes(rows, case.output.probe.len() + case.output.combination.len()),
        })
    }

    /// A flow run (with a fixed solid, if any) or an FSI run on the fluid mesh `mesh`.
    fn with_fluid<const D: usize>(&self, mesh: Mesh<D>) -> Result<CheckSummary, RunError> {
        let case = self.case;
        if !matches!(mesh.cell_type, ReferenceCell::Triangle | ReferenceCell::Tetrahedron) {
            return Err(self.invalid(format!("[mesh]: fluid meshes must be triangles (2D) or tetrahedra (3D), got {:?} cells", mesh.cell_type)));
        }
        let fsi = case.kind() == RunKind::Fsi;
        let own: Vec<String> = mesh.boundary_names.iter().map(|(n, _)| n.clone()).collect();
        let mut adapted_names = own.clone();
        if !case.solid.is_empty() {
            adapted_names.extend([GAMMA_F, GAMMA_F_PLUS, GAMMA_F_MINUS].map(String::from));
        }
        for b in &case.boundary {
            let names = if fsi { &own } else { &adapted_names };
            self.known_boundary(names, &b.name, &format!("[[boundary]] name = \"{}\"", b.name))?;
        }
        for b in &case.output.boundary_integral {
            self.known_boundary(&adapted_names, &b.boundary, &format!("[[output.boundary_integral]] '{}'", b.name))?;
        }
        for p in &case.output.profile {
            self.known_boundary(&adapted_names, &p.boundary, &format!("[[output.profile]] '{}'", p.name))?;
        }
        if !case.solid.is_empty() {
            let solid = self.solid_mesh::<D>()?.mesh;
            self.solid_inside(&mesh, &solid)?;
        }
        let cells = mesh.num_cells();
        let quantities = case.output.probe.len() + case.output.boundary_integral.len() + case.output.domain.len() + case.output.combination.len();
        if fsi {
            let surface = case.solid_surface().ok_or_else(|| self.invalid("solid.surface is required with a fluid".into()))?;
            // The model `fdfsi run` builds, at t = 0: the same unknowns as its first step.
            let model = fsi_model(case, &mesh, self.dir)?;
            let material = model.problem.solid.material_names();
            let disc = FsiDiscretization::build_with(&model, &vec![0.0; model.solid.num_dofs()], &Default::default(), Entries::Counted)?;
            self.probes_inside(&disc.flow.mesh)?;
            displacement_probes(case, &model.solid)?;
            let dofs = disc.layout.dofs_per_part();
            let ts = case.time.as_ref().ok_or_else(|| self.invalid("an FSI run needs a [time] table".into()))?;
            let steps = num_steps(ts.dt, ts.end);
            let field_writes = (1..=steps).filter(|k| k % ts.output_every.max(1) == 0 || *k == steps).count();
            let description = format!(
                "{}: FSI run, {} flow ({}) on a {D}D mesh of {cells} cells ({} after adaptation to the solid at t = 0); \
                 solid {} on {} cells, coupled on '{surface}' by {} coupling elements of the Lagrange multiplier; \
                 unknowns by block: {}; nnz {}",
                case.title,
                name_of(&case.physics.model),
                name_of(&case.physics.formulation),
                disc.flow.mesh.num_cells(),
                material,
                model.solid.mesh.num_cells(),
                disc.coupling.num_elements(),
                disc.layout.blocks().filter(|(_, r)| !r.is_empty()).map(|(b, r)| format!("{} {}", b.name(), r.len())).collect::<Vec<_>>().join(", "),
                disc.nnz().unwrap_or_default() // counted
            );
            return Ok(CheckSummary {
                description,
                dofs: with_total(dofs),
                steps,
                step_kind: "time steps",
                field_writes,
                field_bytes: fluid_vtu_bytes(&disc.flow) + solid_vtu_bytes(&model.solid),
                history_bytes: history_bytes(steps, quantities + D + 1),
            });
        }
        let adapted = if case.solid.is_empty() { mesh } else { adapt_fluid(case, mesh, self.dir)?.adapted.mesh };
        self.probes_inside(&adapted)?;
        let problem = flow_problem(case, &adapted, self.dir)?;
        let adapted_cells = adapted.num_cells();
        // The entries counted, not stored: a run may hold only its rows of them.
        let disc = FlowDiscretization::build_for(adapted, &problem, Entries::Counted)?;
        let dofs = with_total(super::flow::flow_dofs(&disc));
        let solid_text = if case.solid.is_empty() {
            String::new()
        } else {
            format!(
                "; fixed solid, the mesh adapted to its surface '{}' has {adapted_cells} cells",
                case.solid_surface().unwrap_or_else(|| "?".into())
            )
        };
        let description = format!(
            "{}: {} flow ({}), {D}D mesh of {cells} cells{solid_text}; nnz {}",
            case.title,
            name_of(&case.physics.model),
            name_of(&case.physics.formulation),
            disc.nnz().unwrap_or_default() // counted
        );
        let (steps, step_kind, field_writes, rows) = time_steps(case).unwrap_or((1, "steady solve", 1, 1));
        Ok(CheckSummary {
            description,
            dofs,
            steps,
            step_kind,
            field_writes,
            field_bytes: fluid_vtu_bytes(&disc),
            history_bytes: history_bytes(rows, quantities),
        })
    }

    /// Every vertex of the (placed) solid mesh must lie in the fluid mesh, except those of cells
    /// held in place: cells with a facet on a boundary whose displacement is prescribed in every
    /// component may reach into the fluid's wall (a leaflet embedded in a rigid root, so that its
    /// surface crosses the wall and gamma_f closes along it).
    fn solid_inside<const D: usize>(&self, fluid: &Mesh<D>, solid: &Mesh<D>) -> Result<(), RunError> {
        let locator = CellLocator::new(fluid);
        let held = self.held_cells(solid);
        let mut seen = vec![false; solid.points.len()];
        let (mut total, mut outside, mut first) = (0usize, 0usize, None);
        for c in (0..solid.num_cells()).filter(|&c| !held[c]) {
            for &v in solid.cell_vertices(c) {
                if std::mem::replace(&mut seen[v], true) {
                    continue;
                }
                total += 1;
                let x = &solid.points[v];
                if !x.iter().all(|c| c.is_finite()) || locator.locate(fluid, x).is_none() {
                    outside += 1;
                    first.get_or_insert(*x);
                }
            }
        }
        if let Some(x) = first {
            let (lo, hi) = bounding_box(&fluid.points);
            let span: Vec<String> = (0..D).map(|d| format!("[{}, {}]", lo[d], hi[d])).collect();
            let placed =
                if self.case.solid.iter().any(|s| s.rotate_deg != 0.0 || s.translate.is_some()) { " (placed by rotate_deg/translate)" } else { "" };
            let which = if outside == total { "all".to_string() } else { format!("{outside} of {total}") };
            return Err(self.invalid(format!(
                "solid: {which} vertices of the solid mesh{placed} lie outside the fluid mesh, the first at {}; \
                 the solid must lie inside the fluid domain (the fluid mesh spans {})",
                point_text(&x),
                span.join(" x ")
            )));
        }
        Ok(())
    }

    /// The solid cells with a facet on a boundary whose displacement is prescribed in every
    /// component.
    fn held_cells<const D: usize>(&self, solid: &Mesh<D>) -> Vec<bool> {
        let mut held = vec![false; solid.num_cells()];
        for (k, spec) in self.case.solid.iter().enumerate() {
            let every = |c: &Vec<usize>| (0..D).all(|a| c.contains(&a));
            let clamped = spec.boundary.iter().filter(|b| b.kind == SolidBoundaryType::Displacement && b.components.as_ref().is_none_or(every));
            for b in clamped {
                for f in solid.boundary_facets(&self.case.solid_boundary(k, &b.name)).unwrap_or_default() {
                    held[f.cell] = true;
                }
            }
        }
        held
    }

    /// Every velocity or pressure probe must lie in the fluid mesh.
    fn probes_inside<const D: usize>(&self, fluid: &Mesh<D>) -> Result<(), RunError> {
        let locator = CellLocator::new(fluid);
        for p in &self.case.output.probe {
            if p.field == ProbeField::Displacement || p.point.len() != D {
                continue;
            }
            let x: [f64; D] = std::array::from_fn(|d| p.point[d]);
            if locator.locate(fluid, &x).is_none() {
                let (lo, hi) = bounding_box(&fluid.points);
                let span: Vec<String> = (0..D).map(|d| format!("[{}, {}]", lo[d], hi[d])).collect();
                let removed = self.case.covered_fluid() == crate::adapt::CoveredFluid::Removed;
                let inside_box = (0..D).all(|d| lo[d] <= x[d] && x[d] <= hi[d]);
                let hint = if removed && inside_box { " or in the fluid the solid covers (covered_fluid = \"removed\")" } else { "" };
                return Err(self.invalid(format!(
                    "[[output.probe]] '{}': the point {} lies outside the fluid mesh (which spans {}){hint}",
                    p.name,
                    point_text(&x),
                    span.join(" x ")
                )));
            }
        }
        Ok(())
    }
}

fn with_total(mut dofs: Vec<(String, usize)>) -> Vec<(String, usize)> {
    let total = dofs.iter().map(|(_, k)| k).sum();
    dofs.push(("total".into(), total));
    dofs
}

fn point_text(x: &[f64]) -> String {
    let parts: Vec<String> = x.iter().map(|v| format!("{v}")).collect();
    format!("({})", parts.join(", "))
}

/// Size of an inline-binary VTU file: base64 of the coordinates, the connectivity, offsets and
/// types, `point_values` Float64 values per point and `cell_values` per cell, plus the XML.
fn vtu_bytes(points: usize, cells: usize, nodes_per_cell: usize, point_values: usize, cell_values: usize) -> u64 {
    let raw = points as u64 * (3 + point_values as u64) * 8 + cells as u64 * (nodes_per_cell as u64 * 8 + 9 + cell_values as u64 * 8);
    raw * 4 / 3 + 2000
}

/// One fluid `.vtu`: P2 nodes with the velocity; pressure, its gradient and the region per cell.
fn fluid_vtu_bytes<const D: usize>(disc: &FlowDiscretization<D>) -> u64 {
    let points = disc.topology.num_vertices + disc.topology.edges.len();
    vtu_bytes(points, disc.mesh.num_cells(), if D == 2 { 6 } else { 10 }, 3, 5)
}

/// One solid `.vtu`: Q2 nodes with the displacement; pressure and Cauchy stress per cell.
fn solid_vtu_bytes<const D: usize>(disc: &SolidDiscretization<D>) -> u64 {
    let f = disc.displacement_field();
    vtu_bytes(f.nodes.num_nodes, disc.mesh.num_cells(), f.nodes.per_cell, 3, 10)
}

/// `history.csv`: a header and `rows` rows of step, time, iterations, residual and the
/// quantities (about 23 characters each).
fn history_bytes(rows: usize, quantities: usize) -> u64 {
    let row = 48 + 23 * quantities as u64;
    (rows as u64 + 1).saturating_mul(row)
}

/// `(steps, "time steps", field writes, history rows)` of a time-dependent run (the initial state
/// written and recorded too); `None` without `[time]`.
fn time_steps(case: &Case) -> Option<(usize, &'static str, usize, usize)> {
    let ts = case.time.as_ref()?;
    let steps = num_steps(ts.dt, ts.end);
    let every = ts.output_every.max(1);
    Some((steps, "time steps", 1 + steps / every + usize::from(!steps.is_multiple_of(every)), steps + 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_well() {
        assert_eq!(human_bytes(999), "999 B");
        assert_eq!(human_bytes(1234), "1.2 kB");
        assert_eq!(human_bytes(12_345_678), "12.3 MB");
        assert_eq!(human_bytes(999_990), "1.0 MB");
        // Steps as the run counts them (the last one may be shorter).
        assert_eq!(num_steps(0.1, 1.0), 10);
        assert_eq!(num_steps(0.3, 1.0), 4);
        assert_eq!(num_steps(1.0, 0.1), 1);
    }
}
