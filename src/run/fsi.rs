//! FSI runs: a case with a fluid `[mesh]`, a `[solid]` with a material `model` and a `[time]`
//! table is run by the monolithic FSI step of [`crate::discretize::fsi`] (implicit Euler, the
//! paper's, or BDF2: `[time] scheme`), from rest or from another run's checkpoint ([`StartFrom`]).
//!
//! Each step adapts the ORIGINAL fluid mesh to the solid surface at `t_n`, transfers the fluid
//! velocity, solves fluid, solid and multiplier in one Newton solve and moves the solid. Results:
//! - `solution.pvd` with the pieces `fluid` (on each step's adapted mesh), `solid` (deformed) and
//!   `gamma_f` (the coupling elements with the multiplier lambda, the traction of the fluid on the
//!   solid: see [`crate::io::fields::gamma_f_grid`]);
//! - `history.csv`: one row per step with the requested quantities and the built-in
//!   `coupling_force_x`, `coupling_force_y` (`_z`): the force of the fluid on the solid, the
//!   integral of the multiplier over gamma_f and the load of the thin films where a closed gap
//!   cut the fluid off ([`crate::discretize::fsi::FilmLoad`]), plus `coupling_facets` (and
//!   `closed_gap_cells` and the films' part of the force, `film_force_x`, `_y` (`_z`), with
//!   contacts, `open_area` with `[output.open_area]`);
//! - `profiles/NAME.csv` of the last step (`gamma_f_minus` / `gamma_f_plus` name the two sides of
//!   gamma_f);
//! - `summary.json` as for every run.
//!
//! Solid boundary values are evaluated at the step's end time `t_{n+1}` (no load factor).

use super::flow::write_profiles;
use super::record::{march_and_record, RunOutputs, Start};
use super::{RunError, RunObserver, RunOptions, RunSummary, StartFrom};
use crate::case::{Case, RunKind};
use crate::discretize::fsi::{FsiModel, FsiState, FsiStep};
use crate::io::checkpoint::{Checkpoint, RestartState};
use crate::io::fields::{fluid_grid, gamma_f_grid, solid_grid};
use crate::io::picture::PictureError;
use crate::io::OutputError;
use crate::post::open_area::open_area;
use crate::post::quantities::{evaluate_all, StepState};
use crate::setup::{build_mesh, displacement_probes, fsi_model, SetupError};
use crate::time::fsi::FsiStepper;
use crate::time::march::StepDone;
use fdfsi_fem::gmsh::AnyMesh;
use fdfsi_fem::mesh::Mesh;
use fdfsi_fem::vtk::PvdSeries;
use std::path::Path;
use std::time::Instant;

/// Runs an FSI case.
pub fn run_fsi(case: &Case, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    match build_mesh(case, &options.case_dir)? {
        AnyMesh::D2(m) => run_dim::<2>(case, m, options, obs),
        AnyMesh::D3(m) => run_dim::<3>(case, m, options, obs),
    }
}

fn run_dim<const D: usize>(case: &Case, fluid_mesh: Mesh<D>, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let ts = case
        .time
        .as_ref()
        .ok_or_else(|| SetupError::from(crate::case::CaseError::Invalid { file: "case".into(), message: "FSI runs need a [time] table".into() }))?;
    let t = Instant::now();
    let model = fsi_model(case, &fluid_mesh, &options.case_dir)?;
    let mesh_seconds = t.elapsed().as_secs_f64();
    let outputs = FsiOutputs {
        case,
        out_dir: &options.out_dir,
        model: &model,
        solid_probes: displacement_probes(case, &model.solid)?,
        pictures_not_drawn: Vec::new(),
    };
    let mut lu = case.solver.linear_solver(case.time.is_some(), case.physics.formulation);
    // A solver of each rank's rows (PETSc's, unless it runs the augmented Lagrangian) takes a
    // partitioned assembly (`discretize::fsi::step_with`).
    if let Some(world) = lu.as_row_solver().map(|rows| rows.world()) {
        obs.log(&format!("assembly: each rank its own rows of every step's system (this is rank {} of {})", world.rank, world.size));
    }
    let mut start = Start::of(options, obs, t);
    start.timings.mesh = mesh_seconds;
    let schedule = super::schedule_of(ts);
    let state = match (&options.resume, &options.start_from) {
        (Some(c), _) => FsiState::from_restart(&model, c.time, c.fsi_state(&options.out_dir, model.solid.num_dofs())?)?,
        (None, Some(from)) => {
            // `run_case` has checked it against this schedule and output folder.
            let steps_done = from.steps_before(schedule.dt);
            let state = state_started_from(from, &model)?;
            obs.log(&format!(
                "starting after step {steps_done} (t = {:.6e}) from the state of {} (its step {})",
                state.time,
                Checkpoint::path(&from.dir).display(),
                from.checkpoint.step
            ));
            start.first = steps_done + 1;
            state
        }
        (None, None) => FsiState::at_rest(&model),
    };
    let mut stepper = FsiStepper::new(&model, lu.as_mut(), case.solver.newton.clone(), ts.scheme, state);
    let recorded = march_and_record(case, options, obs, &mut stepper, outputs, &schedule, ts.output_every, start, false)?;
    let symbolic = lu.symbolic_factorizations();
    Ok(recorded.summary(case, D, fluid_mesh.num_cells(), symbolic))
}

/// The state of another run's checkpoint as the initial state of a run of `model` (see
/// [`StartFrom`]): the solid's state as saved (the same solid mesh is required), the fluid's
/// velocity on the other run's adapted mesh, rebuilt from that run's own fluid mesh (the first
/// step transfers it to this run's adapted mesh, as every step does from the last one).
fn state_started_from<const D: usize>(from: &StartFrom, model: &FsiModel<D>) -> Result<FsiState<D>, RunError> {
    let case = from.case()?;
    if case.kind() != RunKind::Fsi {
        return Err(from.error("its checkpoint is not of an FSI run".into()));
    }
    let c = &from.checkpoint;
    let rebuilt = |e: RunError| from.error(format!("its fluid mesh could not be rebuilt: {e}"));
    let fluid_mesh = build_mesh(&case, &c.case_dir)
        .map_err(|e| rebuilt(e.into()))?
        .into_dim::<D>()
        .ok_or_else(|| from.error(format!("its fluid mesh is not {D}D")))?;
    let other = fsi_model(&case, &fluid_mesh, &c.case_dir).map_err(|e| rebuilt(e.into()))?;
    let (a, b) = (&other.solid.mesh, &model.solid.mesh);
    if a.points != b.points || a.cell_nodes != b.cell_nodes || a.cell_type != b.cell_type {
        return Err(from.error(format!(
            "its solid mesh ({} nodes, {} cells) is not this case's ({} nodes, {} cells): the solid mesh must be the same",
            a.points.len(),
            a.num_cells(),
            b.points.len(),
            b.num_cells()
        )));
    }
    let restart = c.fsi_state(&from.dir, model.solid.num_dofs()).map_err(|e| from.error(e.to_string()))?;
    // The coupling pattern goes with the state: a first step on another fluid mesh (another
    // topology) starts its pattern afresh.
    FsiState::from_restart(&other, c.time, restart).map_err(|e| rebuilt(e.into()))
}

/// The outputs of an FSI run: the fluid's quantities on the step's adapted mesh, the solid's
/// displacement probes, the built-in coupling quantities; the fluid, solid and gamma_f fields.
struct FsiOutputs<'a, const D: usize> {
    case: &'a Case,
    out_dir: &'a Path,
    model: &'a FsiModel<D>,
    /// Displacement probes: (name, solid node, component).
    solid_probes: Vec<(String, usize, usize)>,
    /// Pictures of the coupling surfaces not drawn (3D), logged at the end: a picture that
    /// cannot be drawn is not an error of the run.
    pictures_not_drawn: Vec<String>,
}

impl<const D: usize> FsiOutputs<'_, D> {
    /// `[output.open_area]`: the part of the original fluid mesh's section that gamma_s at the
    /// displacement `solid_x` leaves open ([`crate::post::open_area`]), scaled.
    fn open_area(&self, solid_x: &[f64]) -> Result<Option<f64>, RunError> {
        let Some(spec) = &self.case.output.open_area else {
            return Ok(None);
        };
        let gamma_s = self.model.gamma_s(solid_x)?;
        let pieces = (0..gamma_s.num_pieces()).map(|i| gamma_s.corners(i));
        Ok(Some(spec.scale * open_area(&self.model.background.mesh, pieces, spec.axis.index(), spec.at)))
    }
}

/// The last (sub)step of an FSI stepper: there is one once a step is done.
fn last_step<'s, const D: usize>(s: &'s FsiStepper<'_, D>) -> &'s FsiStep<D> {
    s.last.as_ref().expect("outputs are read after a completed step")
}

impl<const D: usize> RunOutputs<FsiStepper<'_, D>> for FsiOutputs<'_, D> {
    fn quantities(&mut self, s: &FsiStepper<'_, D>, done: &StepDone) -> Result<Vec<(String, f64)>, RunError> {
        let st = last_step(s);
        let r = &st.report;
        let mut known: Vec<(String, f64)> =
            self.solid_probes.iter().map(|(name, node, a)| (name.clone(), self.model.solid.displacement(&s.state.solid_x, *node)[*a])).collect();
        let open_area = self.open_area(&s.state.solid_x)?;
        let with_contacts = self.case.solid.iter().any(|s| !s.contact.is_empty());
        let closed_gap =
            with_contacts.then(|| std::iter::once(r.adapt.closed_gap_cells as f64).chain(r.film_force.iter().copied())).into_iter().flatten();
        let builtin = r.fluid_force().into_iter().chain([r.coupling_elements as f64]).chain(closed_gap).chain(open_area);
        let (names, values): (Vec<String>, Vec<f64>) = (self.case.builtin_quantities(), builtin.collect());
        debug_assert_eq!(names.len(), values.len(), "a value for every built-in quantity: {names:?}");
        known.extend(names.into_iter().zip(values));
        known.extend(super::solid::contact_quantities(&self.model.solid, &self.model.problem.solid, &s.state.solid_x));
        let fluid = st.disc.fluid_dofs();
        // The step's inertia as solved: `a (u - u*)` with the scheme's `a` (BDF2: `1.5 / dt` at
        // equal steps) and history `u*`.
        let state = StepState { time: done.time, inv_dt: st.fluid_problem.params.inv_dt, u_star: Some(&st.u_old[..fluid]) };
        let mut values = evaluate_all(&self.case.output, &st.disc.flow, &st.fluid_problem, &st.x[..fluid], &state, &known)?;
        values.extend(known);
        Ok(values)
    }

    fn write_fields(&mut self, s: &FsiStepper<'_, D>, done: &StepDone, series: &mut PvdSeries) -> Result<(), RunError> {
        let (st, time) = (last_step(s), done.time);
        if let Err(e) = write_surfaces_picture(st, done.step, self.out_dir) {
            self.pictures_not_drawn.push(e.to_string());
        }
        series.add(time, "fluid", &fluid_grid(&st.disc.flow, &st.x[..st.disc.fluid_dofs()])?)?;
        series.add(time, "solid", &solid_grid(&self.model.solid, &self.model.problem.solid, &s.state.solid_x)?)?;
        series.add(time, "gamma_f", &gamma_f_grid(&st.disc, &st.x)?)?;
        Ok(())
    }

    fn restart(&self, s: &FsiStepper<'_, D>, _done: &StepDone) -> RestartState {
        RestartState::Fsi(Box::new(s.state.to_restart()))
    }

    fn dofs(&self, s: &FsiStepper<'_, D>) -> Vec<(String, usize)> {
        s.last.as_ref().map(|st| st.disc.layout.dofs_per_part()).unwrap_or_default()
    }

    fn describe_step(&self, s: &FsiStepper<'_, D>, done: &StepDone, obs: &mut dyn RunObserver) -> String {
        let r = &last_step(s).report;
        let (a, sec) = (&r.adapt, &r.seconds);
        obs.detail(&format!(
            "  adapt: {} cut edges, {} moved and {} new nodes, {} new cells, {} corner nodes, {} covered cells removed, {} cut off in closed gaps ({} pieces of the solid's surface); worst cell quality {:.1e} ({} moves refused); {} coupling points, max distance to gamma_s {:.2e} ({:.3} of its facet's size)",
            a.cut_edges, a.moved_nodes, a.new_nodes, a.new_cells, a.corner_nodes, a.removed_cells, a.closed_gap_cells, a.closed_gap_pieces, a.min_quality, a.refused_moves, r.coupling_points, r.max_coupling_distance,
            r.max_relative_coupling_distance
        ));
        if a.cells_by_side > 0 {
            obs.detail(&format!(
                "  gamma_f had a hole the mesh closes: rebuilt between the cells on either side of gamma_s ({} cells told by their side)",
                a.cells_by_side
            ));
        }
        if a.unplaced_corners > 0 {
            obs.log(&format!(
                "step {}: {} corners of gamma_s could not be made fluid vertices (no vertex near them can move there): gamma_f cuts them off; refine the fluid mesh there",
                done.step, a.unplaced_corners
            ));
        }
        obs.detail(&format!(
            "  phases: adapt {:.3} s, build {:.3} s, transfer {:.3} s, newton {:.3} s, update {:.3} s",
            sec.adapt, sec.build, sec.transfer, sec.newton, sec.update
        ));
        format!(
            "; {} coupling facets, dofs {} + {} + {}; force [{}]{}",
            r.coupling_elements,
            r.fluid_dofs,
            r.solid_dofs,
            r.multiplier_dofs,
            r.fluid_force().iter().map(|f| format!("{f:.6e}")).collect::<Vec<_>>().join(", "),
            if r.films > 0 { format!(" ({} films)", r.films) } else { String::new() }
        )
    }

    fn finish(&mut self, s: &FsiStepper<'_, D>, out_dir: &Path, obs: &mut dyn RunObserver) -> Result<(), RunError> {
        let st = last_step(s);
        write_profiles(self.case, &st.disc.flow, &st.fluid_problem, &st.x[..st.disc.fluid_dofs()], out_dir, obs)?;
        for failure in self.pictures_not_drawn.drain(..) {
            obs.log(&format!("picture not drawn: {failure}"));
        }
        let png = out_dir.join("speed.png");
        // A picture that cannot be drawn is reported, not an error of the run (as the plots).
        if let Err(e) = write_speed_picture(self.model, st, &s.state.solid_x, s.state.time, self.case.output.slice, &png) {
            obs.log(&format!("{} not drawn: {e}", png.display()));
        }
        Ok(())
    }
}

/// `png` (`speed.png`) of the last step around the solid (its bounding box widened by twice its
/// size on each side, clipped to the fluid mesh), with the solid in grey and gamma_f in white: in
/// 2D the plane of the model, in 3D the plane `slice` (default: see [`crate::case::SliceSpec`])
/// with what it cuts from the solid's cells and gamma_f.
fn write_speed_picture<const D: usize>(
    model: &FsiModel<D>,
    st: &FsiStep<D>,
    solid_x: &[f64],
    time: f64,
    slice: Option<crate::case::SliceSpec>,
    png: &Path,
) -> Result<(), PictureError> {
    use crate::io::picture::{lift, window_around, write_slice_png, write_speed_png, Slice, SpeedPicture};
    let flow = &st.disc.flow;
    let solid = model.current_solid_mesh(solid_x);
    let (lo, hi) = fdfsi_fem::mesh::bounding_box(&solid.points);
    let x = &st.x[..st.disc.fluid_dofs()];
    if D == 2 {
        let xy = |p: &[f64; D]| [p[0], p[1]];
        let outlines = st.disc.adapted.gamma_f.iter().map(|g| g.vertices.iter().map(|&v| xy(&flow.mesh.points[v])).collect()).collect();
        let picture = SpeedPicture {
            title: format!("speed |u| at t = {time:.4}"),
            window: Some(window_around(xy(&lo), xy(&hi))),
            solid: (0..solid.num_cells()).map(|c| cell_outline(&solid, c).iter().map(|&n| xy(&solid.points[n])).collect()).collect(),
            outlines,
            axis_labels: None,
        };
        write_speed_png(flow, x, png, 1600, &picture)
    } else {
        let (flo, fhi) = fdfsi_fem::mesh::bounding_box(&flow.mesh.points);
        let plane = Slice::through(slice.map(|s| s.normal.index()), slice.and_then(|s| s.at), (lift(&flo), lift(&fhi)), (lift(&lo), lift(&hi)));
        let [a, b] = plane.project_box(lift(&lo), lift(&hi));
        let edges = solid.cell_type.edges();
        let cuts_of_solid =
            (0..solid.num_cells()).map(|c| plane.cut(&solid.cell_vertices(c).iter().map(|&v| lift(&solid.points[v])).collect::<Vec<_>>(), edges));
        let tri = fdfsi_fem::element::ReferenceCell::Triangle.edges();
        let cuts_of_gamma_f =
            st.disc.adapted.gamma_f.iter().map(|g| plane.cut(&g.vertices.iter().map(|&v| lift(&flow.mesh.points[v])).collect::<Vec<_>>(), tri));
        let picture = SpeedPicture {
            title: format!("speed |u| on {} at t = {time:.4}", plane.describe()),
            window: Some(window_around(a, b)),
            solid: cuts_of_solid.filter(|p| p.len() >= 3).collect(),
            outlines: cuts_of_gamma_f.filter(|p| p.len() >= 2).map(closed).collect(),
            axis_labels: Some(plane.axis_labels()),
        };
        write_slice_png(flow, x, &plane, png, 1600, &picture)
    }
}

/// A polyline of three or more points closed (a facet in the plane of a slice), else as it is.
fn closed(mut line: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    if line.len() >= 3 {
        line.push(line[0]);
    }
    line
}

/// The nodes around a 2D cell's boundary in order: those of a 9-node quadrilateral
/// ([`crate::io::picture::QUAD9_OUTLINE`]), the corners of another cell.
fn cell_outline<const D: usize>(mesh: &fdfsi_fem::mesh::Mesh<D>, c: usize) -> Vec<usize> {
    let nodes = mesh.cell(c);
    if nodes.len() >= 8 && mesh.cell_vertices(c).len() == 4 {
        crate::io::picture::QUAD9_OUTLINE.iter().map(|&k| nodes[k]).collect()
    } else {
        mesh.cell_vertices(c).to_vec()
    }
}

/// 3D: `pictures/gamma_step_NNNN.png`, gamma_s (at the start of step `k`, the surface the fluid
/// mesh was adapted to) and gamma_f of step `k` (see [`crate::io::picture::write_surfaces_png`]).
fn write_surfaces_picture<const D: usize>(st: &FsiStep<D>, k: usize, out_dir: &Path) -> Result<(), RunError> {
    if D != 3 {
        return Ok(());
    }
    use crate::io::picture::lift;
    let surface = &st.disc.surface;
    let gamma_s: Vec<[[f64; 3]; 3]> = (0..surface.num_pieces()).map(|i| std::array::from_fn(|k| lift(&surface.corners(i)[k]))).collect();
    let points = &st.disc.flow.mesh.points;
    let gamma_f: Vec<[[f64; 3]; 3]> = st.disc.adapted.gamma_f.iter().map(|g| std::array::from_fn(|k| lift(&points[g.vertices[k]]))).collect();
    let dir = out_dir.join("pictures");
    let png = dir.join(format!("gamma_step_{k:04}.png"));
    let io = |e: std::io::Error| RunError::from(OutputError::Io { path: png.display().to_string(), source: e });
    std::fs::create_dir_all(&dir).map_err(io)?;
    let title = format!("gamma_s (blue) and gamma_f (red) at step {k}, t = {:.4}", st.report.time);
    crate::io::picture::write_surfaces_png(&png, &title, &gamma_s, &gamma_f, 700)
        .map_err(|source| OutputError::Picture { path: png.display().to_string(), source }.into())
}
