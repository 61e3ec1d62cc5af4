//! The solid's surface and the adapted fluid mesh of a case (paper section 2.2.1).
//!
//! Per step (and for `fdfsi adapt`): the solid mesh at its current position gives gamma_s
//! ([`fdfsi_fem::adapt::Surface`]); the ORIGINAL fluid mesh is adapted to it
//! ([`fdfsi_fem::adapt::adapt`]); the fluid facets on gamma_s become the boundary `gamma_f` of
//! the adapted mesh, so boundary conditions and quantities can name it; `gamma_f_minus` and
//! `gamma_f_plus` are the same facets seen from the fluid cells on either side (for one-sided
//! quantities such as the wall shear stress on both faces of a thin plate).
//!
//! `fdfsi adapt CASE --out DIR` writes `original.vtu` and `adapted.vtu` (the fluid mesh before and
//! after, as linear cells), `gamma_s.vtu`, `gamma_f.vtu` and `summary.json` (the counts of
//! [`AdaptStats`] and the measures of gamma_s and gamma_f).

use crate::case::{Case, CaseError, SolidMeshSpec, SolidSpec};
use crate::output::{write_atomic, OutputError};
use fdfsi_fem::adapt::{adapt_with, AdaptError, AdaptOptions, AdaptStats, Adapted, Background, Surface};
use fdfsi_fem::element::ReferenceCell;
use fdfsi_fem::generate;
use fdfsi_fem::gmsh::{read_msh, AnyMesh, GmshError};
use fdfsi_fem::mesh::{GeometryOrder, Mesh};
use fdfsi_fem::vtk::{write_vtu, UnstructuredGrid, VtkCellType, VtkError};
use serde::Serialize;
use std::path::Path;
use thiserror::Error;

pub use fdfsi_fem::adapt::{GAMMA_F, GAMMA_F_MINUS, GAMMA_F_PLUS};

/// A failure while building the solid surface or adapting.
#[derive(Debug, Error)]
pub enum AdaptationError {
    #[error(transparent)]
    Case(#[from] CaseError),
    #[error(transparent)]
    Gmsh(#[from] GmshError),
    #[error("solid: {0}")]
    Adapt(#[from] AdaptError),
    #[error("solid: {0}")]
    Solid(String),
    #[error(transparent)]
    Output(#[from] OutputError),
    #[error(transparent)]
    Vtk(#[from] VtkError),
}

/// Builds the solid mesh of a case at its placed position.
pub fn solid_mesh<const D: usize>(solid: &SolidSpec, case_dir: &Path) -> Result<Mesh<D>, AdaptationError> {
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
            m.check().map_err(|e| AdaptationError::Solid(format!("solid.mesh corners: {e} (give them counter-clockwise)")))?;
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
    let boxed: Box<dyn std::any::Any> = match any {
        AnyMesh::D2(m) => Box::new(m),
        AnyMesh::D3(m) => Box::new(m),
    };
    let mut mesh = *boxed.downcast::<Mesh<D>>().map_err(|_| AdaptationError::Solid(format!("the solid mesh is not {D}D")))?;
    if !matches!(mesh.cell_type, ReferenceCell::Quadrilateral | ReferenceCell::Hexahedron) {
        return Err(AdaptationError::Solid(format!("solid meshes must be quadrilaterals or hexahedra, got {:?}", mesh.cell_type)));
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

/// The fluid mesh adapted to the case's solid, with the facets on gamma_s tagged `gamma_f`.
pub struct AdaptedFluid<const D: usize> {
    pub original: Mesh<D>,
    pub solid: Mesh<D>,
    pub surface: Surface<D>,
    pub adapted: Adapted<D>,
}

/// Adapts `fluid` to the case's solid and tags gamma_f on the adapted mesh (which then replaces
/// `adapted.mesh`'s boundary list with the parent's tags plus `gamma_f`).
pub fn adapt_fluid<const D: usize>(case: &Case, fluid: Mesh<D>, case_dir: &Path) -> Result<AdaptedFluid<D>, AdaptationError> {
    let spec = case.solid.as_ref().ok_or_else(|| AdaptationError::Solid("the case has no [solid] table".into()))?;
    let solid = solid_mesh::<D>(spec, case_dir)?;
    let name = spec.surface.as_deref().ok_or_else(|| AdaptationError::Solid("solid.surface is not set".into()))?;
    let surface = Surface::from_mesh_boundary(&solid, name)?;
    let background = Background::new(&fluid)?;
    Ok(AdaptedFluid::new(fluid, &background, solid, surface, &AdaptOptions::new(spec.eps_hat))?)
}

impl<const D: usize> AdaptedFluid<D> {
    /// `original` (prepared as `background`) adapted to `surface`, the surface of `solid`, with
    /// gamma_f tagged on the adapted mesh.
    pub fn new(
        original: Mesh<D>,
        background: &Background<D>,
        solid: Mesh<D>,
        surface: Surface<D>,
        options: &AdaptOptions,
    ) -> Result<Self, AdaptError> {
        let mut adapted = adapt_with(background, &surface, options)?;
        fdfsi_fem::adapt::tag_gamma_f(&mut adapted.mesh, &adapted.gamma_f);
        Ok(AdaptedFluid { original, solid, surface, adapted })
    }
}

/// What `fdfsi adapt` writes to `summary.json`.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptSummary {
    pub original_cells: usize,
    pub adapted_cells: usize,
    pub gamma_s_pieces: usize,
    pub gamma_s_measure: f64,
    pub gamma_f_measure: f64,
    pub stats: AdaptStats,
}

/// The vertex mesh of `mesh` as linear VTK cells.
fn linear_grid<const D: usize>(mesh: &Mesh<D>) -> Result<UnstructuredGrid, VtkError> {
    let mut grid = UnstructuredGrid::new(pad(&mesh.points));
    let ty = if D == 2 { VtkCellType::Triangle } else { VtkCellType::Tetra };
    for c in 0..mesh.num_cells() {
        grid.push_cell(ty, mesh.cell_vertices(c))?;
    }
    grid.add_cell_data("region", 1, mesh.cell_tags.iter().map(|&t| t as f64).collect())?;
    Ok(grid)
}

fn pad<const D: usize>(points: &[[f64; D]]) -> Vec<[f64; 3]> {
    points.iter().map(|p| std::array::from_fn(|d| if d < D { p[d] } else { 0.0 })).collect()
}

/// Segments (2D) or triangles (3D) as a VTK grid.
fn piece_grid<const D: usize>(points: &[[f64; D]], pieces: &[[usize; D]]) -> Result<UnstructuredGrid, VtkError> {
    let mut grid = UnstructuredGrid::new(pad(points));
    let ty = if D == 2 { VtkCellType::Line } else { VtkCellType::Triangle };
    for p in pieces {
        grid.push_cell(ty, p)?;
    }
    Ok(grid)
}

/// `fdfsi adapt`: adapts the case's fluid mesh to its solid and writes the files listed in the
/// module documentation.
pub fn write_adapt_report<const D: usize>(a: &AdaptedFluid<D>, out_dir: &Path) -> Result<AdaptSummary, AdaptationError> {
    std::fs::create_dir_all(out_dir).map_err(|source| OutputError::Io { path: out_dir.display().to_string(), source })?;
    write_vtu(&out_dir.join("original.vtu"), &linear_grid(&a.original)?)?;
    write_vtu(&out_dir.join("adapted.vtu"), &linear_grid(&a.adapted.mesh)?)?;
    write_vtu(&out_dir.join("gamma_s.vtu"), &piece_grid(&a.surface.points, &a.surface.pieces)?)?;
    let gf: Vec<[usize; D]> = a.adapted.gamma_f.iter().map(|g| g.vertices).collect();
    write_vtu(&out_dir.join("gamma_f.vtu"), &piece_grid(&a.adapted.mesh.points, &gf)?)?;
    let summary = AdaptSummary {
        original_cells: a.original.num_cells(),
        adapted_cells: a.adapted.mesh.num_cells(),
        gamma_s_pieces: a.surface.num_pieces(),
        gamma_s_measure: a.surface.measure(),
        gamma_f_measure: a.adapted.gamma_f_measure(),
        stats: a.adapted.stats.clone(),
    };
    let json = serde_json::to_string_pretty(&summary).expect("summary serialises");
    write_atomic(&out_dir.join("summary.json"), json.as_bytes())?;
    Ok(summary)
}
