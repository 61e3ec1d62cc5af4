//! `animation.gif` of a time-dependent run: `fdfsi animate DIR`, and by itself at the end of
//! `fdfsi run` (unless `[output] animation = false`).
//!
//! The frames are the fields the run wrote (`DIR/solution.pvd`), at every output time on one
//! colour scale, drawn as `speed.png` is ([`super::picture`]):
//! - 2D: the speed of the fluid piece, with the solid piece (its cells, in grey) and gamma_f (in
//!   white) when the run has them. The window is the solid's box over the whole run widened by
//!   twice its size on each side (an FSI run), or the fluid mesh (a flow run).
//! - 3D: the speed on the case's `[output.slice]` (read from `DIR/case.toml`, as `speed.png`;
//!   by default normal to the fluid's thinnest axis through the middle of the solid's box over
//!   the whole run, where `speed.png` takes the box at its own time), with what the plane cuts
//!   from the solid's hexahedra (grey) and gamma_f's triangles (white). The
//!   window is the solid's section box over the whole run widened as in 2D. Beside it,
//!   `solid.gif`: the solid seen along the flow with its mirror images ([`super::view`]).

use super::picture::{grid_slice_field, window_around, write_speed_gif, Frame, PictureError, Slice, SpeedField, SpeedPicture, QUAD9_OUTLINE};
use super::view::{boundary_quads, bounding_plane, mirror_group, write_solid_gif, Isometry, Quad, SolidFrame};
use crate::case::{BoundaryType, Case};
use fdfsi_fem::element::ReferenceCell;
use fdfsi_fem::mesh::bounding_box;
use fdfsi_fem::vtk::{read_pvd, read_vtu, PvdEntry, UnstructuredGrid, VtkCellType, VtkError};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Width of the animation (pixels).
pub const ANIMATION_WIDTH: u32 = 960;
/// Time a frame is shown (milliseconds).
pub const FRAME_DELAY_MS: u32 = 100;

/// An animation failure.
#[derive(Debug, Error)]
pub enum AnimationError {
    #[error("{0}")]
    Vtk(#[from] VtkError),
    #[error("{path}: {source}")]
    Fields { path: String, source: PictureError },
    #[error("{path}: {source}")]
    Draw { path: String, source: PictureError },
    /// The run's `case.toml` (3D: the slice and the symmetry planes) does not read back.
    #[error("{0}")]
    Case(#[from] crate::case::CaseError),
}

/// What [`animate_run`] drew.
#[derive(Clone, Debug, PartialEq)]
pub struct Animated {
    /// `DIR/animation.gif`.
    pub gif: PathBuf,
    /// Its frames: one per output time.
    pub frames: usize,
    /// `DIR/solid.gif` of a 3D run with a solid.
    pub solid_gif: Option<PathBuf>,
}

/// Draws `DIR/animation.gif` (and in 3D `DIR/solid.gif`) from the fields in `DIR/solution.pvd`
/// (see the module documentation). A run with fewer than two output times, or whose fluid grid
/// is of neither 6-node triangles (2D) nor 10-node tetrahedra (3D), has nothing to animate:
/// `None`.
pub fn animate_run(dir: &Path) -> Result<Option<Animated>, AnimationError> {
    let pvd = dir.join("solution.pvd");
    let entries = read_pvd(&pvd)?;
    let mut times: Vec<f64> = entries.iter().map(|e| e.time).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    if times.len() < 2 {
        return Ok(None);
    }
    let run = Fields { pvd: &pvd, entries: &entries };
    let Some(first) = times.iter().find_map(|&t| run.part(t, "fluid")) else { return Ok(None) };
    let grid = run.read(first)?;
    let case_path = dir.join("case.toml");
    let case = match std::fs::read_to_string(&case_path) {
        Ok(text) => Some(Case::from_toml_str(&text, &case_path.display().to_string())?),
        Err(_) => None,
    };
    let (frames, solid_frames) = if grid.cell_types.iter().all(|&t| t == VtkCellType::QuadraticTriangle) && grid.points.iter().all(|p| p[2] == 0.0) {
        (frames_2d(&run, &times)?, Vec::new())
    } else if grid.cell_types.iter().all(|&t| t == VtkCellType::QuadraticTetra) {
        frames_3d(case.as_ref(), &run, &times, &grid)?
    } else {
        return Ok(None);
    };
    if frames.len() < 2 {
        return Ok(None);
    }
    let draw_error = |path: &Path, source| AnimationError::Draw { path: path.display().to_string(), source };
    let gif = dir.join("animation.gif");
    write_speed_gif(&frames, &gif, ANIMATION_WIDTH, FRAME_DELAY_MS).map_err(|e| draw_error(&gif, e))?;
    let solid_gif = if solid_frames.len() >= 2 && solid_frames.iter().all(|f| !f.faces.is_empty()) {
        let path = dir.join("solid.gif");
        let (lo, hi) = bounding_box(&grid.points);
        let flow_axis = (0..3).fold(0, |best, d| if hi[d] - lo[d] > hi[best] - lo[best] { d } else { best });
        write_solid_gif(&solid_frames, flow_axis, &path, SOLID_SIZE, FRAME_DELAY_MS).map_err(|e| draw_error(&path, e))?;
        Some(path)
    } else {
        None
    };
    Ok(Some(Animated { gif, frames: frames.len(), solid_gif }))
}

/// Side of `solid.gif` (pixels).
pub const SOLID_SIZE: u32 = 640;

/// The parts of a run's `solution.pvd` and how to read them.
struct Fields<'a> {
    pvd: &'a Path,
    entries: &'a [PvdEntry],
}

impl Fields<'_> {
    /// The part `name` (`fluid`, `solid`, `gamma_f`) written at `time` (the last, if several),
    /// if its file is there (a run resumed from its checkpoint alone lists fields whose files
    /// stayed with its earlier parts: those times are left out).
    fn part(&self, time: f64, name: &str) -> Option<&PvdEntry> {
        self.entries.iter().rfind(|e| e.time == time && e.name == name).filter(|e| e.resolve(self.pvd).exists())
    }

    fn read(&self, entry: &PvdEntry) -> Result<UnstructuredGrid, AnimationError> {
        Ok(read_vtu(&entry.resolve(self.pvd))?)
    }

    /// The part `name` at `time`, read, if the run wrote it.
    fn read_part(&self, time: f64, name: &str) -> Result<Option<UnstructuredGrid>, AnimationError> {
        self.part(time, name).map(|e| self.read(e)).transpose()
    }

    fn fields_error(&self, entry: &PvdEntry, source: PictureError) -> AnimationError {
        AnimationError::Fields { path: entry.resolve(self.pvd).display().to_string(), source }
    }
}

/// The frames of a 2D run (see the module documentation).
fn frames_2d(run: &Fields, times: &[f64]) -> Result<Vec<Frame>, AnimationError> {
    let mut frames = Vec::with_capacity(times.len());
    for &time in times {
        let Some(fluid) = run.part(time, "fluid") else { continue };
        let field = SpeedField::of_grid(&run.read(fluid)?).map_err(|source| run.fields_error(fluid, source))?;
        let solid = run.read_part(time, "solid")?.map(|g| solid_cells(&g)).unwrap_or_default();
        let outlines = run.read_part(time, "gamma_f")?.map(|g| lines(&g)).unwrap_or_default();
        frames.push(Frame {
            field,
            picture: SpeedPicture { title: format!("speed |u| at t = {time:.4}"), window: None, solid, outlines, axis_labels: None },
        });
    }
    let solid_points: Vec<[f64; 2]> = frames.iter().flat_map(|f| f.picture.solid.iter().flatten().copied()).collect();
    if let (false, Some(first)) = (solid_points.is_empty(), frames.first_mut()) {
        let (lo, hi) = bounding_box(&solid_points);
        first.picture.window = Some(window_around(lo, hi));
    }
    Ok(frames)
}

/// The frames of a 3D run whose first fluid grid is `first`, of `animation.gif` and of
/// `solid.gif` (see the module documentation).
fn frames_3d(case: Option<&Case>, run: &Fields, times: &[f64], first: &UnstructuredGrid) -> Result<(Vec<Frame>, Vec<SolidFrame>), AnimationError> {
    let (flo, fhi) = bounding_box(&first.points);
    // The solid at every time, read once, and its box over the whole run (its corner nodes).
    let solids = times.iter().map(|&time| run.read_part(time, "solid")).collect::<Result<Vec<_>, _>>()?;
    let solid_points: Vec<[f64; 3]> = solids.iter().flatten().flat_map(|g| (0..g.num_cells()).filter_map(|c| corners(g, c)).flatten()).collect();
    let centre = if solid_points.is_empty() { (flo, fhi) } else { bounding_box(&solid_points) };
    let spec = case.and_then(|c| c.output.slice);
    let images = mirror_group(&mirrors(case, first), 1e-9 * lo_hi_scale(flo, fhi));
    let plane = Slice::through(spec.map(|s| s.normal.index()), spec.and_then(|s| s.at), (flo, fhi), centre);
    let bounds = plane.project_box(flo, fhi);
    let window = (!solid_points.is_empty()).then(|| {
        let [a, b] = plane.project_box(centre.0, centre.1);
        window_around(a, b)
    });
    let tri = ReferenceCell::Triangle.edges();
    let hex = ReferenceCell::Hexahedron.edges();
    let (mut frames, mut solid_frames) = (Vec::with_capacity(times.len()), Vec::new());
    for (&time, solid_grid) in times.iter().zip(&solids) {
        let Some(fluid) = run.part(time, "fluid") else { continue };
        let field = grid_slice_field(&run.read(fluid)?, &plane, bounds, window, ANIMATION_WIDTH).map_err(|source| run.fields_error(fluid, source))?;
        let solid = solid_grid.as_ref().map(|g| sections(g, &plane, hex, 3)).unwrap_or_default();
        if let Some(g) = solid_grid {
            let faces = boundary_quads(g);
            let faces: Vec<Quad> = images.iter().flat_map(|m| faces.iter().map(move |q| q.map(|p| m.apply(&p)))).collect();
            let whole = if images.len() > 1 { format!(" and its {} mirror images", images.len() - 1) } else { String::new() };
            solid_frames.push(SolidFrame { title: format!("the solid{whole} at t = {time:.4}"), faces });
        }
        let outlines = run.read_part(time, "gamma_f")?.map(|g| sections(&g, &plane, tri, 2)).unwrap_or_default();
        let title = format!("speed |u| on {} at t = {time:.4}", plane.describe());
        frames.push(Frame { field, picture: SpeedPicture { title, window, solid, outlines, axis_labels: Some(plane.axis_labels()) } });
    }
    Ok((frames, solid_frames))
}

/// The largest coordinate of the box `[lo, hi]` in size, at least 1: the scale of tolerances.
fn lo_hi_scale(lo: [f64; 3], hi: [f64; 3]) -> f64 {
    lo.iter().chain(&hi).fold(1.0, |m: f64, v| m.max(v.abs()))
}

/// The reflections in the fluid's symmetry planes of `case` (see the module documentation), each
/// plane where the fluid grid `fluid` ends along its normal.
fn mirrors(case: Option<&Case>, fluid: &UnstructuredGrid) -> Vec<Isometry> {
    let Some(case) = case else { return Vec::new() };
    let (lo, hi) = bounding_box(&fluid.points);
    let tol = 1e-6 * lo_hi_scale(lo, hi);
    case.boundary
        .iter()
        .filter(|b| b.kind == BoundaryType::Symmetry)
        .filter_map(|b| match (b.normal_axis, &b.normal) {
            (Some(axis), _) if axis < 3 => Some(std::array::from_fn(|d| if d == axis { 1.0 } else { 0.0 })),
            (_, Some(n)) if n.len() == 3 => Some([n[0], n[1], n[2]]),
            _ => None,
        })
        .filter_map(|n: [f64; 3]| {
            let n = n.map(|c| c / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt());
            bounding_plane(&fluid.points, n, tol).map(|c| Isometry::reflection(n, c))
        })
        .collect()
}

/// The corner nodes of cell `c` of a 3D grid: the 8 of a hexahedron (27-node or 8-node), the 3
/// of a triangle; none for another cell.
fn corners(grid: &UnstructuredGrid, c: usize) -> Option<Vec<[f64; 3]>> {
    let n = match grid.cell_types[c] {
        VtkCellType::TriquadraticHexahedron | VtkCellType::Hexahedron => 8,
        VtkCellType::Triangle | VtkCellType::QuadraticTriangle => 3,
        _ => return None,
    };
    Some(grid.cell(c)[..n].iter().map(|&k| grid.points[k]).collect())
}

/// The polygons where `plane` cuts the cells of `grid` with `edges` (hexahedra, or triangles),
/// those of at least `least` points.
fn sections(grid: &UnstructuredGrid, plane: &Slice, edges: &[[usize; 2]], least: usize) -> Vec<Vec<[f64; 2]>> {
    let num_corners = edges.iter().flatten().max().map_or(0, |m| m + 1);
    (0..grid.num_cells())
        .filter_map(|c| corners(grid, c).filter(|v| v.len() == num_corners))
        .map(|v| plane.cut(&v, edges))
        .filter(|p| p.len() >= least)
        .collect()
}

/// The outlines of the 9-node quadrilaterals of a solid grid ([`QUAD9_OUTLINE`]).
fn solid_cells(grid: &UnstructuredGrid) -> Vec<Vec<[f64; 2]>> {
    (0..grid.num_cells())
        .filter(|&c| grid.cell_types[c] == VtkCellType::BiquadraticQuad)
        .map(|c| QUAD9_OUTLINE.iter().map(|&k| grid.points[grid.cell(c)[k]]).map(|p| [p[0], p[1]]).collect())
        .collect()
}

/// The segments of a grid of line cells (gamma_f in 2D).
fn lines(grid: &UnstructuredGrid) -> Vec<Vec<[f64; 2]>> {
    (0..grid.num_cells())
        .filter(|&c| grid.cell_types[c] == VtkCellType::Line)
        .map(|c| grid.cell(c).iter().map(|&n| [grid.points[n][0], grid.points[n][1]]).collect())
        .collect()
}
