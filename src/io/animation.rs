//! `animation.gif` of a 2D time-dependent run: `fdfsi animate DIR`, and by itself at the end of
//! `fdfsi run` (unless `[output] animation = false`).
//!
//! The frames are the fields the run wrote (`DIR/solution.pvd`): at every output time the speed
//! of the fluid piece, with the solid piece (its cells, in grey) and gamma_f (in white) when the
//! run has them, drawn as `speed.png` is ([`super::picture`]) on one colour scale. The window is
//! the solid's box over the whole run widened by twice its size on each side (an FSI run), or
//! the fluid mesh (a flow run).

use super::picture::{window_around, write_speed_gif, Frame, PictureError, SpeedField, SpeedPicture, QUAD9_OUTLINE};
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
}

/// Draws `DIR/animation.gif` from the fields in `DIR/solution.pvd` (see the module
/// documentation); returns its path and the number of frames. A run with fewer than two output
/// times, or a 3D run, has nothing to animate: `None`.
pub fn animate_run(dir: &Path) -> Result<Option<(PathBuf, usize)>, AnimationError> {
    let pvd = dir.join("solution.pvd");
    let entries = read_pvd(&pvd)?;
    let mut times: Vec<f64> = entries.iter().map(|e| e.time).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    if times.len() < 2 {
        return Ok(None);
    }
    let part = |time: f64, name: &str| entries.iter().rfind(|e| e.time == time && e.name == name);
    let read = |e: &PvdEntry| read_vtu(&e.resolve(&pvd));
    let mut frames = Vec::with_capacity(times.len());
    for &time in &times {
        let Some(fluid) = part(time, "fluid") else { continue };
        let grid = read(fluid)?;
        if grid.points.iter().any(|p| p[2] != 0.0) || grid.cell_types.iter().any(|&t| t != VtkCellType::QuadraticTriangle) {
            return Ok(None); // 3D (or not a fluid of 6-node triangles): no animation
        }
        let field =
            SpeedField::of_grid(&grid).map_err(|source| AnimationError::Fields { path: fluid.resolve(&pvd).display().to_string(), source })?;
        let solid = part(time, "solid").map(read).transpose()?.map(|g| solid_cells(&g)).unwrap_or_default();
        let outlines = part(time, "gamma_f").map(read).transpose()?.map(|g| lines(&g)).unwrap_or_default();
        frames.push(Frame {
            field,
            picture: SpeedPicture { title: format!("speed |u| at t = {time:.4}"), window: None, solid, outlines, axis_labels: None },
        });
    }
    if frames.len() < 2 {
        return Ok(None);
    }
    let solid_points: Vec<[f64; 2]> = frames.iter().flat_map(|f| f.picture.solid.iter().flatten().copied()).collect();
    if !solid_points.is_empty() {
        let (lo, hi) = bounding_box(&solid_points);
        frames[0].picture.window = Some(window_around(lo, hi));
    }
    let gif = dir.join("animation.gif");
    write_speed_gif(&frames, &gif, ANIMATION_WIDTH, FRAME_DELAY_MS)
        .map_err(|source| AnimationError::Draw { path: gif.display().to_string(), source })?;
    Ok(Some((gif, frames.len())))
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
