//! Results on disk: the contract tests and users read.
//!
//! In `--out DIR`:
//! - `solution.pvd` + `solution_fluid_NNNNNN.vtu`: the fluid piece (quadratic cells: 6-node
//!   triangles / 10-node tetrahedra through the P2 nodes of the P2+ velocity; point data
//!   `velocity`; cell data `pressure` (value at the centroid) and `pressure_gradient`);
//! - `history.csv`: one row per step, `step,time,newton_iterations,residual,<quantities...>`;
//! - `summary.json`: `{"quantities": {NAME: final value}, "dofs": ..., "steps": ..., "timings": ...}`;
//! - `case.toml`: the case as used;
//! - `speed.png` (2D), `plots/`, and `animation.gif` of a 2D time-dependent run ([`animation`]).
//!
//! Every file is written to a temporary name and renamed, so an interrupted run never leaves a
//! truncated file.

use fdfsi_fem::vtk::VtkError;
use std::io::Write;
use std::path::Path;
use thiserror::Error;

pub mod animation;
pub mod checkpoint;
pub mod fields;
pub mod history;
pub mod matrix_market;
pub mod picture;
pub mod plot;
pub mod provenance;
pub mod view;

pub use history::History;

/// An output failure.
#[derive(Debug, Error)]
pub enum OutputError {
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error(transparent)]
    Vtk(#[from] VtkError),
    #[error("solid fields: {0}")]
    SolidFields(#[from] crate::discretize::solid::SolidAssemblyError),
    #[error("{path}: {source}")]
    Picture { path: String, source: picture::PictureError },
}

/// Writes `contents` to `path` atomically (temporary file in the same folder, then rename).
pub fn write_atomic(path: &Path, contents: &[u8]) -> Result<(), OutputError> {
    let io = |source| OutputError::Io { path: path.display().to_string(), source };
    let tmp = path.with_extension(format!("{}.tmp", path.extension().and_then(|e| e.to_str()).unwrap_or("")));
    let mut f = std::fs::File::create(&tmp).map_err(io)?;
    f.write_all(contents).map_err(io)?;
    f.sync_all().map_err(io)?;
    drop(f);
    std::fs::rename(&tmp, path).map_err(io)
}
