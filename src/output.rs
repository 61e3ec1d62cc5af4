//! Results on disk: the contract tests and users read.
//!
//! In `--out DIR`:
//! - `solution.pvd` + `solution_fluid_NNNNNN.vtu`: the fluid piece (quadratic cells: 6-node
//!   triangles / 10-node tetrahedra through the P2 nodes of the P2+ velocity; point data
//!   `velocity`; cell data `pressure` (value at the centroid) and `pressure_gradient`);
//! - `history.csv`: one row per step, `step,time,newton_iterations,residual,<quantities...>`;
//! - `summary.json`: `{"quantities": {NAME: final value}, "dofs": ..., "steps": ..., "timings": ...}`;
//! - `case.toml`: the case as used.
//!
//! Every file is written to a temporary name and renamed, so an interrupted run never leaves a
//! truncated file.

use crate::flow::FlowDiscretization;
use fdfsi_fem::vtk::{UnstructuredGrid, VtkCellType, VtkError};
use std::io::Write;
use std::path::Path;
use thiserror::Error;

/// An output failure.
#[derive(Debug, Error)]
pub enum OutputError {
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error(transparent)]
    Vtk(#[from] VtkError),
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

/// The fluid solution as a VTK grid of quadratic cells.
pub fn fluid_grid<const D: usize>(disc: &FlowDiscretization<D>, x: &[f64]) -> Result<UnstructuredGrid, VtkError> {
    let vf = &disc.layout.fields[0];
    let pf = &disc.layout.fields[1];
    let (cell_type, corner_nodes) = if D == 2 { (VtkCellType::QuadraticTriangle, 6) } else { (VtkCellType::QuadraticTetra, 10) };
    // The P2 nodes (vertices and edges) come first in the velocity numbering.
    let num_p2 = disc.topology.num_vertices + disc.topology.edges.len();
    let points: Vec<[f64; 3]> = disc.velocity_nodes[..num_p2].iter().map(|p| std::array::from_fn(|d| if d < D { p[d] } else { 0.0 })).collect();
    let mut grid = UnstructuredGrid::new(points);
    for c in 0..disc.mesh.num_cells() {
        grid.push_cell(cell_type, &vf.nodes.cell(c)[..corner_nodes])?;
    }
    let mut vel = Vec::with_capacity(num_p2 * 3);
    for node in 0..num_p2 {
        for a in 0..3 {
            vel.push(if a < D { x[vf.dof(node, a)] } else { 0.0 });
        }
    }
    grid.add_point_data("velocity", 3, vel)?;
    let nc = disc.mesh.num_cells();
    let mut p = Vec::with_capacity(nc);
    let mut gp = Vec::with_capacity(nc * 3);
    for c in 0..nc {
        let dofs = &x[pf.dof(c * (D + 1), 0)..pf.dof(c * (D + 1), 0) + D + 1];
        p.push(dofs[0]);
        for a in 0..3 {
            gp.push(if a < D { dofs[a + 1] } else { 0.0 });
        }
    }
    grid.add_cell_data("pressure", 1, p)?;
    grid.add_cell_data("pressure_gradient", 3, gp)?;
    grid.add_cell_data("region", 1, disc.mesh.cell_tags.iter().map(|&t| t as f64).collect())?;
    Ok(grid)
}

/// gamma_f of an FSI step as a VTK grid: one line (2D) or triangle (3D) per coupling element,
/// with its own vertices because the multiplier is discontinuous between elements. Point data
/// `multiplier`: the P1 part of lambda (all of it with the paper's multiplier; with the
/// trace-mode multiplier its L2 projection onto P1 per element, and the mode's amplitude is cell
/// data `multiplier_trace_mode`), the traction of the fluid on the solid (force per unit length in 2D, per
/// unit area in 3D and per radian-length in axisymmetric runs); cell data `element`: the coupling
/// element's index.
pub fn gamma_f_grid<const D: usize>(disc: &crate::fsi::FsiDiscretization<D>, x: &[f64]) -> Result<UnstructuredGrid, VtkError> {
    let gamma_f = &disc.adapted.gamma_f;
    let points: Vec<[f64; 3]> = gamma_f
        .iter()
        .flat_map(|g| g.vertices.map(|v| disc.flow.mesh.points[v]))
        .map(|p| std::array::from_fn(|d| if d < D { p[d] } else { 0.0 }))
        .collect();
    let mut grid = UnstructuredGrid::new(points);
    let cell_type = if D == 2 { VtkCellType::Line } else { VtkCellType::Triangle };
    for e in 0..gamma_f.len() {
        grid.push_cell(cell_type, &(e * D..(e + 1) * D).collect::<Vec<_>>())?;
    }
    let mut lambda = Vec::with_capacity(gamma_f.len() * D * 3);
    for e in 0..gamma_f.len() {
        for k in 0..D {
            lambda.extend((0..3).map(|a| if a < D { x[disc.multiplier_dof(e, k, a)] } else { 0.0 }));
        }
    }
    grid.add_point_data("multiplier", 3, lambda)?;
    if !disc.coupling.mode.is_empty() {
        // The trace-mode multiplier's amplitude per element (its function is 1 at the vertices
        // and -1/2 mid-facet, and integrates to zero).
        let mode = (0..gamma_f.len())
            .flat_map(|e| (0..3).map(move |a| if a < D { x[disc.mode_multiplier_dof(disc.coupling.chain[e], a)] } else { 0.0 }))
            .collect();
        grid.add_cell_data("multiplier_trace_mode", 3, mode)?;
    }
    grid.add_cell_data("element", 1, (0..gamma_f.len()).map(|e| e as f64).collect())?;
    Ok(grid)
}

/// A `history.csv` being written row by row: each row is appended and flushed to disk when its
/// step completes, so the cost of a step's output does not grow with the length of the run.
///
/// A run killed while writing a row leaves a torn last line; [`History::resume`] cuts it away.
pub struct History {
    path: std::path::PathBuf,
    file: std::fs::File,
    /// Fields per row (the header's).
    columns: usize,
}

impl History {
    /// Starts a history (replacing any file at `path`) with the quantity names as columns after
    /// `step,time,newton_iterations,residual`; the header is written at once.
    pub fn new(path: &Path, quantities: &[String]) -> Result<Self, OutputError> {
        let mut header = String::from("step,time,newton_iterations,residual");
        for q in quantities {
            header.push(',');
            header.push_str(q);
        }
        header.push('\n');
        write_atomic(path, header.as_bytes())?;
        Self::append_to(path, 4 + quantities.len())
    }

    fn append_to(path: &Path, columns: usize) -> Result<Self, OutputError> {
        let io = |source| OutputError::Io { path: path.display().to_string(), source };
        let file = std::fs::OpenOptions::new().append(true).open(path).map_err(io)?;
        Ok(History { path: path.to_path_buf(), file, columns })
    }

    /// Continues the `history.csv` of an interrupted run: keeps its header and the whole rows of
    /// steps up to `until_step` (a row torn by a kill, without its line end or with missing
    /// fields, is dropped), rewrites the file with them once and appends after them.
    pub fn resume(path: &Path, until_step: usize) -> Result<Self, OutputError> {
        let io = |source| OutputError::Io { path: path.display().to_string(), source };
        let old = std::fs::read_to_string(path).map_err(io)?;
        let mut lines = old.split_inclusive('\n').filter(|l| l.ends_with('\n'));
        let header = lines.next().unwrap_or("step,time,newton_iterations,residual\n");
        let columns = header.split(',').count();
        let mut text = header.to_string();
        for line in lines {
            let whole = line.trim_end().split(',').count() == columns;
            let step = line.split(',').next().and_then(|s| s.parse::<usize>().ok());
            if whole && step.is_some_and(|s| s <= until_step) {
                text.push_str(line);
            }
        }
        write_atomic(path, text.as_bytes())?;
        Self::append_to(path, columns)
    }

    /// Appends the row of a completed step and flushes it to disk.
    pub fn push(&mut self, step: usize, time: f64, iterations: usize, residual: f64, values: &[f64]) -> Result<(), OutputError> {
        let io = |source| OutputError::Io { path: self.path.display().to_string(), source };
        if 4 + values.len() != self.columns {
            let message = format!("a row of {} values for {} columns", 4 + values.len(), self.columns);
            return Err(io(std::io::Error::other(message)));
        }
        let mut row = format!("{step},{time:.12e},{iterations},{residual:.6e}");
        for v in values {
            row.push_str(&format!(",{v:.15e}"));
        }
        row.push('\n');
        // One write per row: a kill tears at most this row, which `resume` cuts away.
        self.file.write_all(row.as_bytes()).map_err(io)?;
        self.file.sync_data().map_err(io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn history_rows_are_appended_and_a_torn_row_is_cut_on_resume() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("history.csv");
        let mut h = History::new(&path, &names(&["a", "b"])).unwrap();
        for k in 1..=3 {
            h.push(k, 0.1 * k as f64, 2, 1e-9, &[k as f64, -(k as f64)]).unwrap();
        }
        assert!(h.push(4, 0.4, 2, 1e-9, &[1.0]).is_err(), "a row with a missing value is refused");
        drop(h);
        let whole = std::fs::read_to_string(&path).unwrap();
        assert_eq!(whole.lines().count(), 4);
        assert!(whole.starts_with("step,time,newton_iterations,residual,a,b\n1,") && whole.lines().nth(3).unwrap().starts_with("3,"));
        // A kill in the middle of row 4: the last line has neither all its fields nor its end.
        std::fs::write(&path, format!("{whole}4,4.000000000000e-1,2,1.0e-9,4.0")).unwrap();
        // Cut for being torn, even where the checkpoint is at its step.
        let mut h = History::resume(&path, 4).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), whole, "the torn row is cut away");
        h.push(4, 0.4, 2, 1e-9, &[4.0, -4.0]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().count(), 5);
        assert!(text.lines().all(|l| l.split(',').count() == 6));
        // Resuming from an earlier checkpoint drops the later rows.
        History::resume(&path, 2).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap().lines().count(), 3);
    }
}
