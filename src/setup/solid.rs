//! The solid of a case: its placed mesh, material law, boundary conditions and probes.

use super::{invalid, SetupError};
use crate::case::{Case, Expr, ProbeField, SolidBoundaryType, SolidMeshSpec, SolidModel, SolidSpec};
use crate::discretize::solid::{SolidBody, SolidDiscretization, SolidProblem};
use crate::physics::contact::RigidPlane;
use crate::physics::solid::{FibreField, FibreReinforced, NeoHookeanCompressible, NeoHookeanMixed, SaintVenantKirchhoff, SolidMaterial};
use fdfsi_fem::element::ReferenceCell;
use fdfsi_fem::generate;
use fdfsi_fem::gmsh::{read_msh, AnyMesh};
use fdfsi_fem::mesh::{GeometryOrder, Mesh};
use std::path::Path;
use std::sync::Arc;

/// The solid mesh of a case, and the body of each of its cells.
pub struct SolidMesh<const D: usize> {
    pub mesh: Mesh<D>,
    /// The body (the index of its `[[solid]]` table) of each cell; empty with one solid.
    pub cell_body: Vec<usize>,
}

/// Builds the solid mesh of a case at its placed position, with the union of the boundaries of a
/// `surface` of several names added under their joined name ([`crate::case::BoundaryNames`]).
/// Several solids (`[[solid]]`) are joined into one mesh of disjoint parts, solid after solid,
/// their boundaries named as [`Case::solid_boundary`] says, and gamma_s, the union of their
/// surfaces, added as [`Case::solid_surface`].
pub fn solid_mesh<const D: usize>(case: &Case, case_dir: &Path) -> Result<SolidMesh<D>, SetupError> {
    let parts = case
        .solid
        .iter()
        .map(|spec| {
            let mut mesh = placed_solid_mesh(spec, case_dir)?;
            merge_surface(&mut mesh, spec)?;
            Ok(mesh)
        })
        .collect::<Result<Vec<Mesh<D>>, SetupError>>()?;
    if parts.len() < 2 {
        let mesh = parts.into_iter().next().ok_or_else(|| SetupError::SolidMesh("the case has no [solid] table".into()))?;
        return Ok(SolidMesh { mesh, cell_body: Vec::new() });
    }
    let named: Vec<(&str, &Mesh<D>)> = case.solid.iter().map(|s| s.name.as_deref().unwrap_or_default()).zip(&parts).collect();
    let mut mesh = Mesh::disjoint_union(&named).map_err(|e| SetupError::SolidMesh(format!("the solids' meshes: {e}")))?;
    if let (Some(surfaces), Some(gamma_s)) = (case.solid_surfaces(), case.solid_surface()) {
        mesh.merge_boundaries(&surfaces, &gamma_s).map_err(|e| SetupError::SolidMesh(format!("gamma_s, the union of the solids' surfaces: {e}")))?;
    }
    let cell_body = parts.iter().enumerate().flat_map(|(k, m)| std::iter::repeat_n(k, m.num_cells())).collect();
    Ok(SolidMesh { mesh, cell_body })
}

/// Adds the union of the boundaries `solid.surface` names, if it names several, under their
/// joined name.
pub fn merge_surface<const D: usize>(mesh: &mut Mesh<D>, solid: &SolidSpec) -> Result<(), SetupError> {
    match &solid.surface {
        Some(surface) if surface.names().len() > 1 => mesh
            .merge_boundaries(surface.names(), &surface.joined())
            .map_err(|e| SetupError::SolidMesh(format!("solid.surface = {:?}: {e}", surface.names()))),
        _ => Ok(()),
    }
}

/// The solid mesh of a case at its placed position, as its file or generator gives it.
pub fn placed_solid_mesh<const D: usize>(solid: &SolidSpec, case_dir: &Path) -> Result<Mesh<D>, SetupError> {
    let any = match &solid.mesh {
        SolidMeshSpec::Rectangle { x, y, n } => AnyMesh::D2(generate::rectangle_quads(x[0], x[1], y[0], y[1], n[0], n[1], GeometryOrder::Quadratic)),
        SolidMeshSpec::Quadrilateral { corners: c, n } => {
            // Bilinear image of the unit square: x(s, t) = sum of corners times (1-s)(1-t), s(1-t), st, (1-s)t.
            let mut m = generate::rectangle_quads(0.0, 1.0, 0.0, 1.0, n[0], n[1], GeometryOrder::Quadratic);
            for p in m.points.iter_mut() {
                let (s, t) = (p[0], p[1]);
                let w = [(1.0 - s) * (1.0 - t), s * (1.0 - t), s * t, (1.0 - s) * t];
                *p = std::array::from_fn(|d| (0..4).map(|k| w[k] * c[k][d]).sum());
            }
            m.check().map_err(|e| SetupError::SolidMesh(format!("solid.mesh corners: {e} (give them counter-clockwise)")))?;
            AnyMesh::D2(m)
        }
        SolidMeshSpec::Box { x, y, z, n } => {
            AnyMesh::D3(generate::box_hexahedra(x[0], x[1], y[0], y[1], z[0], z[1], n[0], n[1], n[2], GeometryOrder::Quadratic))
        }
        SolidMeshSpec::QuarterDisc { radius, z, n_core, n_ring, n_layers } => {
            AnyMesh::D3(generate::quarter_disc_hexahedra(*radius, z[0], z[1], *n_core, *n_ring, *n_layers))
        }
        SolidMeshSpec::Gmsh { file } => read_msh(&case_dir.join(file))?,
    };
    let mut mesh = any.into_dim::<D>().ok_or_else(|| SetupError::SolidMesh(format!("the solid mesh is not {D}D")))?;
    if !matches!(mesh.cell_type, ReferenceCell::Quadrilateral | ReferenceCell::Hexahedron) {
        return Err(SetupError::SolidMesh(format!("solid meshes must be quadrilaterals or hexahedra, got {:?}", mesh.cell_type)));
    }
    place(&mut mesh, solid);
    Ok(mesh)
}

/// Applies the case's placement: rotation by `rotate_deg` about `pivot` (2D), then `translate`.
fn place<const D: usize>(mesh: &mut Mesh<D>, solid: &SolidSpec) {
    let pivot: [f64; D] = std::array::from_fn(|d| solid.pivot.as_ref().and_then(|p| p.get(d).copied()).unwrap_or(0.0));
    let shift: [f64; D] = std::array::from_fn(|d| solid.translate.as_ref().and_then(|p| p.get(d).copied()).unwrap_or(0.0));
    let (s, c) = solid.rotate_deg.to_radians().sin_cos();
    for p in mesh.points.iter_mut() {
        if D == 2 && solid.rotate_deg != 0.0 {
            let (dx, dy) = (p[0] - pivot[0], p[1] - pivot[1]);
            p[0] = pivot[0] + c * dx - s * dy;
            p[1] = pivot[1] + s * dx + c * dy;
        }
        for d in 0..D {
            p[d] += shift[d];
        }
    }
}

/// The material law of a solid spec.
pub fn material(spec: &SolidSpec) -> Result<Arc<dyn SolidMaterial>, SetupError> {
    let moduli = spec.moduli().map_err(invalid)?;
    let (g, k) = (moduli.shear, moduli.bulk);
    let need_k = || k.ok_or_else(|| invalid(format!("solid.model = {} needs bulk_modulus", crate::case::name_of(&spec.model))));
    let matrix: Arc<dyn SolidMaterial> = match spec.model {
        SolidModel::Fixed => return Err(invalid("solid.model = \"fixed\" has no material law to solve".into())),
        SolidModel::NeoHookean => match k {
            None => Arc::new(NeoHookeanMixed::incompressible(g)),
            Some(k) => Arc::new(NeoHookeanMixed { shear_modulus: g, bulk_modulus: k }),
        },
        SolidModel::NeoHookeanCompressible => Arc::new(NeoHookeanCompressible::from_shear_bulk(g, need_k()?)),
        SolidModel::SaintVenantKirchhoff => {
            let k = need_k()?;
            Arc::new(SaintVenantKirchhoff { mu: g, lambda: k - 2.0 * g / 3.0 })
        }
    };
    let Some(fibres) = &spec.fibres else { return Ok(matrix) };
    let exprs = compile(&fibres.direction)?;
    let direction: FibreField = Arc::new(move |x: &[f64; 3]| std::array::from_fn(|a| exprs.get(a).map_or(0.0, |e| e.eval(x, 0.0))));
    Ok(Arc::new(FibreReinforced { matrix, k1: fibres.k1, k2: fibres.k2, onset: fibres.onset.unwrap_or(0.0), direction }))
}

fn compile(values: &[crate::case::Scalar]) -> Result<Vec<Expr>, SetupError> {
    values.iter().map(|v| Expr::compile(v).map_err(invalid)).collect()
}

/// The solid problem of a case, on its solid mesh whose cells are in the bodies `cell_body`
/// ([`solid_mesh`]): one body per `[[solid]]` table, with its material, density and body force,
/// and each table's boundary conditions and contacts on its boundaries (named as
/// [`Case::solid_boundary`] says). When `ramp` (quasi-static runs) the boundary values and the
/// body force are multiplied by the load factor and their expressions see `t = 0`; otherwise
/// (time-dependent solid-only and FSI runs, whose solvers pass the time in the load argument)
/// they are evaluated at `t` = that time.
pub fn solid_problem<const D: usize>(case: &Case, cell_body: Vec<usize>, ramp: bool) -> Result<SolidProblem<D>, SetupError> {
    let at = move |load: f64| scale_and_time(ramp, load);
    let bodies = case.solid.iter().map(|spec| body(spec, ramp)).collect::<Result<Vec<SolidBody<D>>, SetupError>>()?;
    let mut p = SolidProblem::with_bodies(case.physics.formulation, bodies, cell_body);
    for (k, spec) in case.solid.iter().enumerate() {
        let name = |local: &str| case.solid_boundary(k, local);
        for c in &spec.contact {
            if let Some(master) = &c.against {
                p = p.with_contact_against(&name(&c.boundary), &name(master));
                continue;
            }
            let (point, normal) =
                (std::array::from_fn(|d| c.point.get(d).copied().unwrap_or(0.0)), std::array::from_fn(|d| c.normal.get(d).copied().unwrap_or(0.0)));
            let plane = RigidPlane::new(point, normal)
                .ok_or_else(|| invalid(format!("solid.contact '{}': the normal {:?} is not a direction", c.boundary, c.normal)))?;
            p = p.with_contact(&name(&c.boundary), plane);
        }
        for b in &spec.boundary {
            let exprs = compile(&b.value)?;
            let boundary = name(&b.name);
            match b.kind {
                SolidBoundaryType::Displacement => {
                    let comps: Vec<usize> = b.components.clone().unwrap_or_else(|| (0..D).collect());
                    p = p.with_displacement(&boundary, &comps, move |x, load| vector_at(&exprs, x, at(load)));
                }
                SolidBoundaryType::Traction => {
                    p = p.with_traction(&boundary, move |x, load| vector_at(&exprs, x, at(load)));
                }
                SolidBoundaryType::Pressure => {
                    p = p.with_pressure(&boundary, move |load| {
                        let (scale, t) = at(load);
                        scale * exprs[0].eval(&[0.0; 3], t)
                    });
                }
                SolidBoundaryType::Symmetry => {
                    // A roller normal to an axis holds that component; any other, `u . n = 0`.
                    let plane = super::symmetry_plane::<D>(&boundary, b.normal.as_deref().unwrap_or_default())?;
                    p = match plane.axis() {
                        Some(axis) => p.with_displacement(&boundary, &[axis], |_, _| [0.0; D]),
                        None => p.with_symmetry(plane),
                    };
                }
            }
        }
    }
    Ok(p)
}

/// The body of a solid spec: its material, density and body force (see [`solid_problem`] for
/// `ramp`).
fn body<const D: usize>(spec: &SolidSpec, ramp: bool) -> Result<SolidBody<D>, SetupError> {
    let at = move |load: f64| scale_and_time(ramp, load);
    let mut body = SolidBody::new(material(spec)?);
    body.density = spec.density;
    if let Some(f) = &spec.body_force {
        let exprs = compile(f)?;
        body.body_force = Some(Arc::new(move |x, load| vector_at(&exprs, x, at(load))));
    }
    Ok(body)
}

/// The `(scale, t)` of a load argument: `(load, 0)` when the loads are ramped (`ramp`), else
/// `(1, load)`, the load argument being the time.
fn scale_and_time(ramp: bool, load: f64) -> (f64, f64) {
    if ramp {
        (load, 0.0)
    } else {
        (1.0, load)
    }
}

/// `scale * e_a(x, t)` for each component `a`.
fn vector_at<const D: usize>(exprs: &[Expr], x: &[f64; D], (scale, t): (f64, f64)) -> [f64; D] {
    std::array::from_fn(|a| scale * exprs[a].eval(x, t))
}

/// The case's `displacement` probes as (name, solid node, component): each probe point must
/// be a node of the solid mesh (reference configuration).
pub fn displacement_probes<const D: usize>(case: &Case, disc: &SolidDiscretization<D>) -> Result<Vec<(String, usize, usize)>, SetupError> {
    let mut out = Vec::new();
    for p in case.output.probe.iter().filter(|p| p.field == ProbeField::Displacement) {
        let x0: [f64; D] = std::array::from_fn(|d| p.point.get(d).copied().unwrap_or(0.0));
        let node = disc.node_near(&x0);
        let dist: f64 = (0..D).map(|d| (disc.nodes_x0[node][d] - x0[d]).powi(2)).sum::<f64>().sqrt();
        if dist > 1e-9 * (1.0 + x0.iter().map(|v| v.abs()).fold(0.0, f64::max)) {
            return Err(invalid(format!("probe '{}': {:?} is not a node of the solid mesh (nearest is {dist:.3e} away)", p.name, p.point)));
        }
        out.push((p.name.clone(), node, p.component));
    }
    Ok(out)
}
