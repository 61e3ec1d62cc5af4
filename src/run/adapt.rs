//! `fdfsi adapt`: the case's fluid mesh adapted to its solid (paper section 2.2.1), written for
//! inspection.
//!
//! `fdfsi adapt CASE --out DIR` writes `original.vtu` and `adapted.vtu` (the fluid mesh before and
//! after, as linear cells), `gamma_s.vtu`, `gamma_f.vtu` and `summary.json` (the counts of
//! [`AdaptStats`] and the measures of gamma_s and gamma_f). With `--at RUN_DIR`, the mesh of the
//! next step of an FSI run from its checkpoint; where a closed gap's cells are cut off there,
//! also `films.vtu`: the facets of gamma_f that carry a film
//! ([`fdfsi_fem::adapt::gap::CutSide`]), with the facet's normal into the film, the closed gap
//! (a connected region of cut cells) it opens to, and the centroid of the kept cell at the gap's
//! mouth whose pressure the film carries (NaN where there is none;
//! with `film_pressure = "lowest-mouth"`, chosen from the checkpoint's pressure as the run's next
//! step would), the number of mouths whose mean it carries (`mouths`: one but for
//! `film_pressure = "reynolds"`) and that mean in the checkpoint's pressure (`pressure`: the
//! mouth cells' pressures at their centroids, over those that lie in the checkpoint's mesh, whose
//! share of the weights is `located`).
//! Where the covered fluid is to be removed and gamma_f does not enclose it, the files show the
//! adaptation with it kept, and the command fails.

use super::{RunError, RunOptions};
use crate::adapt::{AdaptedFluid, CoveredFluid};
use crate::case::{Case, CaseError, RunKind};
use crate::discretize::fsi::FsiError;
use crate::io::checkpoint::Checkpoint;
use crate::io::{write_atomic, OutputError};
use crate::setup::{adapt_fluid_with, build_mesh, fsi_model};
use crate::time::Schedule;
use fdfsi_fem::adapt::{AdaptError, AdaptStats};
use fdfsi_fem::gmsh::AnyMesh;
use fdfsi_fem::mesh::Mesh;
use fdfsi_fem::vtk::{write_vtu, UnstructuredGrid, VtkCellType, VtkError};
use serde::Serialize;
use std::path::Path;

/// `fdfsi adapt`: adapts the case's fluid mesh to its solid and writes the mesh files and
/// counts into `out_dir` (see [`crate::adapt`]).
pub fn adapt_case(case: &Case, case_dir: &Path, out_dir: &Path) -> Result<AdaptSummary, RunError> {
    let covered = case.covered_fluid();
    match build_mesh(case, case_dir)? {
        AnyMesh::D2(m) => report_or_leak(|c| Ok(AdaptReport::of(adapt_fluid_with(case, m.clone(), case_dir, c)?)), covered, out_dir),
        AnyMesh::D3(m) => report_or_leak(|c| Ok(AdaptReport::of(adapt_fluid_with(case, m.clone(), case_dir, c)?)), covered, out_dir),
    }
}

/// Is `e` (through its sources) the adaptation's "gamma_f does not enclose the solid"?
fn is_not_enclosed(e: &RunError) -> bool {
    let mut source: Option<&dyn std::error::Error> = Some(e);
    while let Some(err) = source {
        if matches!(err.downcast_ref::<AdaptError>(), Some(AdaptError::NotEnclosed(_))) {
            return true;
        }
        source = err.source();
    }
    false
}

/// Writes the report of `adapt(covered)`. Where removing the covered cells fails (gamma_f does
/// not enclose them), the adaptation with them kept is written, to show where gamma_f is open,
/// and the error returned.
fn report_or_leak<const D: usize>(
    adapt: impl Fn(CoveredFluid) -> Result<AdaptReport<D>, RunError>,
    covered: CoveredFluid,
    out_dir: &Path,
) -> Result<AdaptSummary, RunError> {
    match adapt(covered) {
        Err(e) if covered == CoveredFluid::Removed && is_not_enclosed(&e) => {
            if let Ok(kept) = adapt(CoveredFluid::Kept) {
                write_adapt_report(&kept, out_dir)?;
            }
            Err(e)
        }
        adapted => write_adapt_report(&adapted?, out_dir),
    }
}

/// `fdfsi adapt --at RUN_DIR`: the fluid mesh of an FSI run adapted to the solid of its
/// checkpoint (the mesh the run's next step starts from: with BDF2, to the solid extrapolated to
/// that step's end), written like [`adapt_case`]. To look
/// at the adaptation of a step that failed: the files show the cut cells, gamma_s and gamma_f,
/// and `stats.min_quality` the worst cell.
pub fn adapt_checkpoint(run_dir: &Path, out_dir: &Path) -> Result<AdaptSummary, RunError> {
    let (case, options) = RunOptions::resume(run_dir)?;
    let checkpoint = options.resume.as_ref().expect("resume options hold the checkpoint");
    if case.kind() != RunKind::Fsi {
        return Err(RunError::Case(CaseError::Invalid {
            file: Checkpoint::path(run_dir).display().to_string(),
            message: "`fdfsi adapt --at` needs the checkpoint of an FSI run (a case with a fluid mesh and a solid surface)".into(),
        }));
    }
    let covered = case.covered_fluid();
    match build_mesh(&case, &options.case_dir)? {
        AnyMesh::D2(m) => report_or_leak(|c| adapted_at(&case, m.clone(), &options.case_dir, checkpoint, run_dir, c), covered, out_dir),
        AnyMesh::D3(m) => report_or_leak(|c| adapted_at(&case, m.clone(), &options.case_dir, checkpoint, run_dir, c), covered, out_dir),
    }
}

/// The original fluid mesh adapted to the solid of a checkpoint written in `run_dir` (what the
/// run's next step starts from), with gamma_f tagged, and its films' pressures in the
/// checkpoint's fluid.
fn adapted_at<const D: usize>(
    case: &Case,
    fluid_mesh: Mesh<D>,
    case_dir: &std::path::Path,
    checkpoint: &Checkpoint,
    run_dir: &std::path::Path,
    covered: CoveredFluid,
) -> Result<AdaptReport<D>, RunError> {
    let model = fsi_model(case, &fluid_mesh, case_dir)?;
    let restart = checkpoint.fsi_state(run_dir, model.solid.num_dofs())?;
    // The solid the next step (of the run's schedule) adapts to: extrapolated to its end when
    // the run steps by BDF2.
    let time = case.time.as_ref().expect("an FSI case has [time]");
    let schedule = Schedule { dt: time.dt, end: time.end, max_cuts: time.max_cuts };
    let dt = schedule.time(checkpoint.step + 1) - schedule.time(checkpoint.step);
    let geometry = restart.next_geometry(dt, time.scheme);
    let solid = model.current_solid_mesh(&geometry);
    let surface = model.gamma_s(&geometry)?;
    let mut adapted = AdaptedFluid::new(fluid_mesh, &model.background, solid, surface, &model.problem.adapt, covered).map_err(FsiError::from)?;
    // Where the solid has closed on a contact plane, the run cuts the gap's cells off too, and
    // its films take the mouths the case's `film_pressure` says, from the checkpoint's fluid.
    adapted.adapted = model.cut_off_closed_gaps(adapted.adapted, &adapted.surface, &geometry)?;
    if adapted.adapted.cut_sides.is_empty() {
        return Ok(AdaptReport::of(adapted));
    }
    let fluid = restart.fluid_snapshot(&model)?;
    model.choose_film_mouths(fluid.as_ref(), &mut adapted.adapted);
    let probe = fluid.as_ref().map(|f| f.pressure_probe());
    let cells = &adapted.adapted.mesh;
    let pressure_of = |m: usize| probe.as_ref().and_then(|p| p(&cells.vertex_centroid(m)));
    let films = adapted
        .adapted
        .cut_sides
        .iter()
        .map(|side| {
            let weights = model.film_weights(side);
            let located: Vec<(f64, f64)> = weights.iter().filter_map(|&(m, w)| Some((w, pressure_of(m)?))).collect();
            let share: f64 = located.iter().map(|(w, _)| w).sum();
            let mean = if share > 0.0 { located.iter().map(|(w, p)| w * p).sum::<f64>() / share } else { 0.0 };
            FilmReport { mouths: weights.len(), pressure: mean, located: share }
        })
        .collect();
    Ok(AdaptReport { fluid: adapted, films })
}

/// What `fdfsi adapt` writes: the adapted fluid and, at a checkpoint, each film's
/// ([`fdfsi_fem::adapt::Adapted::cut_sides`]' order).
struct AdaptReport<const D: usize> {
    fluid: AdaptedFluid<D>,
    films: Vec<FilmReport>,
}

impl<const D: usize> AdaptReport<D> {
    fn of(fluid: AdaptedFluid<D>) -> Self {
        AdaptReport { fluid, films: Vec::new() }
    }
}

/// A film at a checkpoint: the number of mouths whose mean it carries, that mean in the
/// checkpoint's pressure over the mouths whose centroids lie in its mesh (the weights scaled back
/// to one; 0 where none does), and the share of the weight they hold (`located`: 0 where the
/// checkpoint holds no fluid).
struct FilmReport {
    mouths: usize,
    pressure: f64,
    located: f64,
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
    points.iter().map(|&p| padded(p)).collect()
}

/// `v` in 3D (zero beyond its `D` components).
fn padded<const D: usize>(v: [f64; D]) -> [f64; 3] {
    std::array::from_fn(|d| if d < D { v[d] } else { 0.0 })
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

/// The facets of gamma_f that carry a film in a closed gap, with cell data `normal` (into the
/// film), `mouth` (the centroid of the kept cell whose pressure the film carries; NaN where
/// there is none), `gap` (the closed gap the film opens to, [`fdfsi_fem::adapt::gap::CutSide::gap`];
/// -1 where there is none) and, where `films` reports them, `mouths`, `pressure` and `located`
/// ([`FilmReport`]).
fn film_grid<const D: usize>(a: &fdfsi_fem::adapt::Adapted<D>, films: &[FilmReport]) -> Result<UnstructuredGrid, VtkError> {
    let facets: Vec<[usize; D]> = a.cut_sides.iter().map(|s| a.gamma_f[s.facet].vertices).collect();
    let mut grid = piece_grid(&a.mesh.points, &facets)?;
    grid.add_cell_data("normal", 3, a.cut_sides.iter().flat_map(|s| padded(s.normal)).collect())?;
    let mouths = a.cut_sides.iter().flat_map(|s| s.mouth.map_or([f64::NAN; 3], |c| padded(a.mesh.vertex_centroid(c))));
    grid.add_cell_data("mouth", 3, mouths.collect())?;
    grid.add_cell_data("gap", 1, a.cut_sides.iter().map(|s| s.gap.map_or(-1.0, |g| g as f64)).collect())?;
    if films.len() == a.cut_sides.len() {
        grid.add_cell_data("mouths", 1, films.iter().map(|f| f.mouths as f64).collect())?;
        grid.add_cell_data("pressure", 1, films.iter().map(|f| f.pressure).collect())?;
        grid.add_cell_data("located", 1, films.iter().map(|f| f.located).collect())?;
    }
    Ok(grid)
}

/// `fdfsi adapt`: adapts the case's fluid mesh to its solid and writes the files listed in the
/// module documentation.
fn write_adapt_report<const D: usize>(report: &AdaptReport<D>, out_dir: &Path) -> Result<AdaptSummary, RunError> {
    let a = &report.fluid;
    std::fs::create_dir_all(out_dir).map_err(|source| OutputError::Io { path: out_dir.display().to_string(), source })?;
    write_vtu(&out_dir.join("original.vtu"), &linear_grid(&a.original)?)?;
    write_vtu(&out_dir.join("adapted.vtu"), &linear_grid(&a.adapted.mesh)?)?;
    write_vtu(&out_dir.join("gamma_s.vtu"), &piece_grid(&a.surface.points, &a.surface.pieces)?)?;
    let gf: Vec<[usize; D]> = a.adapted.gamma_f.iter().map(|g| g.vertices).collect();
    write_vtu(&out_dir.join("gamma_f.vtu"), &piece_grid(&a.adapted.mesh.points, &gf)?)?;
    if !a.adapted.cut_sides.is_empty() {
        write_vtu(&out_dir.join("films.vtu"), &film_grid(&a.adapted, &report.films)?)?;
    }
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
