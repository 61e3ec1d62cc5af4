//! Flow runs: a fluid `[mesh]` (adapted to a fixed solid, if the case has one), steady or in
//! time ([`FlowStepper`]). Results in `--out DIR`:
//! - `solution.pvd` + `solution_fluid_NNNNNN.vtu` (see [`crate::io::fields::fluid_grid`]), at
//!   `t = 0` and every `time.output_every` steps;
//! - `history.csv`: a row for the initial state (step 0) and one per step;
//! - `profiles/NAME.csv` of the last step; `speed.png` in 2D;
//! - `summary.json` as for every run.

use super::record::{march_and_record, record_once, Recorded, RunOutputs, Start};
use super::{newton_lines, RunError, RunObserver, RunOptions, RunSummary};
use crate::case::Case;
use crate::discretize::flow::{solve_steady, Entries, FlowDiscretization, FlowProblem};
use crate::io::checkpoint::RestartState;
use crate::io::fields::fluid_grid;
use crate::io::picture::PictureError;
use crate::io::{write_atomic, OutputError};
use crate::post::quantities::{evaluate_all, StepState};
use crate::setup::{flow_problem, fluid_mesh};
use crate::solve::newton::NewtonReport;
use crate::time::flow::FlowStepper;
use crate::time::march::StepDone;
use crate::time::{Schedule, TimeLevel, Timings};
use fdfsi_fem::gmsh::AnyMesh;
use fdfsi_fem::mesh::Mesh;
use fdfsi_fem::vtk::PvdSeries;
use std::path::Path;
use std::time::Instant;

/// Runs a flow case.
pub fn run_flow(case: &Case, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let t = Instant::now();
    let (mesh, adapted) = fluid_mesh(case, &options.case_dir)?;
    if let Some(st) = adapted {
        obs.log(&format!(
            "adapt: {} cut edges, {} moved and {} new nodes, {} new cells, {} coupling facets, min quality {:.3}",
            st.cut_edges, st.moved_nodes, st.new_nodes, st.new_cells, st.coupling_facets, st.min_quality
        ));
    }
    let mesh_seconds = t.elapsed().as_secs_f64();
    let mut summary = match mesh {
        AnyMesh::D2(m) => run_dim::<2>(case, m, options, obs)?,
        AnyMesh::D3(m) => run_dim::<3>(case, m, options, obs)?,
    };
    summary.timings.mesh = mesh_seconds;
    Ok(summary)
}

fn run_dim<const D: usize>(case: &Case, mesh: Mesh<D>, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let part_start = Instant::now();
    let problem = flow_problem(case, &mesh, &options.case_dir)?;
    let t = Instant::now();
    let cells = mesh.num_cells();
    // A solver of each rank's rows (PETSc's, under `mpirun` or not) takes a partitioned
    // assembly: each rank then holds its rows only.
    let mut lu = case.solver.linear_solver(case.time.is_some(), case.physics.formulation);
    let world = lu.as_row_solver().map(|rows| rows.world());
    let entries = world.map_or(Entries::Whole, Entries::Rows);
    let disc = FlowDiscretization::build_for(mesh, &problem, entries)?;
    let discretize = t.elapsed().as_secs_f64();
    let dofs = flow_dofs(&disc);
    let held = disc.nnz().unwrap_or_default(); // built whole or by rows: counted
    let nnz = match world {
        Some(w) => format!("nnz {held} in rank {}'s rows of {}", w.rank, w.size),
        None => format!("nnz {held}"),
    };
    obs.log(&format!(
        "mesh: {cells} cells; dofs: velocity {}, pressure {}, total {} ({nnz}); {discretize:.2} s",
        dofs[0].1,
        dofs[1].1,
        disc.num_dofs(),
    ));
    let outputs = FlowOutputs { case, problem: &problem };
    let mut recorded = match &case.time {
        None => {
            let sol = solve_steady(&disc, &problem, lu.as_mut(), &case.solver.newton)?;
            let state = FlowStepper::new(&disc, &problem, lu.as_mut(), case.solver.newton.clone(), Default::default(), sol.x, TimeLevel::default());
            steady(state, sol.newton, outputs, options, obs)?
        }
        Some(ts) => {
            let mut start = Start::of(options, obs, part_start);
            start.timings.discretize = discretize;
            let (x, level) = match &options.resume {
                Some(c) => c.flow_state(&options.out_dir, disc.num_dofs())?,
                None => (disc.initial_state(&problem), TimeLevel::default()),
            };
            let mut stepper = FlowStepper::new(&disc, &problem, lu.as_mut(), case.solver.newton.clone(), ts.scheme, x, level);
            let schedule = Schedule { dt: ts.dt, end: ts.end, max_cuts: ts.max_cuts };
            march_and_record(case, options, obs, &mut stepper, outputs, &schedule, ts.output_every, start, true)?
        }
    };
    recorded.timings.discretize = discretize; // this part's (a steady run has no start timings)
    let symbolic = lu.symbolic_factorizations();
    Ok(recorded.summary(case, D, cells, symbolic))
}

/// The unknowns of a flow discretisation per field, as `summary.json` and `fdfsi check` list
/// them.
pub(crate) fn flow_dofs<const D: usize>(disc: &FlowDiscretization<D>) -> Vec<(String, usize)> {
    let mut dofs: Vec<(String, usize)> = disc.layout.fields.iter().map(|f| (f.name.clone(), f.num_dofs())).collect();
    if !disc.outlets().is_empty() {
        dofs.push(("windkessel".into(), 2 * disc.outlets().len()));
    }
    dofs
}

/// A steady solution `state` (Newton's `report`), recorded as step 0 of a run of one step.
fn steady<const D: usize>(
    state: FlowStepper<'_, D>,
    report: NewtonReport,
    outputs: FlowOutputs<'_, D>,
    options: &RunOptions,
    obs: &mut dyn RunObserver,
) -> Result<Recorded, RunError> {
    for line in newton_lines(&report) {
        obs.log(&line);
    }
    let mut timings = Timings::default();
    timings.add_newton(&report);
    let clock = Instant::now();
    let done = StepDone { step: 0, total: 1, time: 0.0, dt: 0.0, cuts: 0, newton: vec![report], phases: Timings::default() };
    let quantities = record_once(outputs.case, options, obs, &state, outputs, &done)?;
    timings.output = clock.elapsed().as_secs_f64();
    let residual_norms = done.newton[0].residual_norms.clone();
    Ok(Recorded {
        steps: 1,
        newton_iterations: done.iterations(),
        krylov_iterations: done.krylov_iterations(),
        residual_norms,
        quantities,
        timings,
        dofs: flow_dofs(state.disc),
    })
}

/// The outputs of a flow run: the case's quantities, the fluid fields, profiles and `speed.png`.
struct FlowOutputs<'a, const D: usize> {
    case: &'a Case,
    problem: &'a FlowProblem<D>,
}

impl<const D: usize> RunOutputs<FlowStepper<'_, D>> for FlowOutputs<'_, D> {
    fn quantities(&mut self, s: &FlowStepper<'_, D>, done: &StepDone) -> Result<Vec<(String, f64)>, RunError> {
        // Consistent boundary forces need the step's history; there is none before the first
        // step (the initial row) and in a steady solve.
        let u_star = (!s.u_star.is_empty()).then_some(s.u_star.as_slice());
        let state = StepState { time: done.time, inv_dt: if u_star.is_some() { s.inv_dt } else { 0.0 }, u_star };
        Ok(evaluate_all(&self.case.output, s.disc, self.problem, &s.x, &state, &[])?)
    }

    fn write_fields(&mut self, s: &FlowStepper<'_, D>, done: &StepDone, series: &mut PvdSeries) -> Result<(), RunError> {
        series.add(done.time, "fluid", &fluid_grid(s.disc, &s.x)?)?;
        Ok(())
    }

    fn restart(&self, s: &FlowStepper<'_, D>, done: &StepDone) -> RestartState {
        RestartState::Flow { x: s.x.clone(), level: s.level(done.step, done.time) }
    }

    fn dofs(&self, s: &FlowStepper<'_, D>) -> Vec<(String, usize)> {
        flow_dofs(s.disc)
    }

    fn finish(&mut self, s: &FlowStepper<'_, D>, out_dir: &Path, obs: &mut dyn RunObserver) -> Result<(), RunError> {
        let png = out_dir.join("speed.png");
        // A picture that cannot be drawn is reported, not an error of the run (as the plots).
        if let Err(e) = write_speed_picture(self.case, s, &png) {
            obs.log(&format!("{} not drawn: {e}", png.display()));
        }
        write_profiles(self.case, s.disc, self.problem, &s.x, out_dir, obs)
    }
}

/// `png` (`speed.png`) of the last step: the whole 2D flow, or a 3D flow on the plane of
/// `[output.slice]`, else through the middle of the fluid mesh (see [`crate::case::SliceSpec`]).
fn write_speed_picture<const D: usize>(case: &Case, s: &FlowStepper<'_, D>, png: &Path) -> Result<(), PictureError> {
    use crate::io::picture::{lift, write_slice_png, write_speed_png, Slice, SpeedPicture};
    let time = case.time.as_ref().map(|t| format!(" at t = {:.4}", t.end)).unwrap_or_default();
    if D == 2 {
        return write_speed_png(s.disc, &s.x, png, 1600, &SpeedPicture { title: format!("speed |u|{time}"), ..Default::default() });
    }
    let (lo, hi) = fdfsi_fem::mesh::bounding_box(&s.disc.mesh.points);
    let fluid = (lift(&lo), lift(&hi));
    let spec = case.output.slice;
    let plane = Slice::through(spec.map(|s| s.normal.index()), spec.and_then(|s| s.at), fluid, fluid);
    let picture =
        SpeedPicture { title: format!("speed |u| on {}{time}", plane.describe()), axis_labels: Some(plane.axis_labels()), ..Default::default() };
    write_slice_png(s.disc, &s.x, &plane, png, 1600, &picture)
}

/// Writes the case's `[[output.profile]]`s of the flow `x` to `out_dir/profiles/NAME.csv`.
pub(crate) fn write_profiles<const D: usize>(
    case: &Case,
    disc: &FlowDiscretization<D>,
    problem: &FlowProblem<D>,
    x: &[f64],
    out_dir: &Path,
    obs: &mut dyn RunObserver,
) -> Result<(), RunError> {
    if case.output.profile.is_empty() {
        return Ok(());
    }
    let dir = out_dir.join("profiles");
    std::fs::create_dir_all(&dir).map_err(|source| OutputError::Io { path: dir.display().to_string(), source })?;
    for spec in &case.output.profile {
        let pts = crate::post::quantities::profile(disc, problem, x, spec)?;
        write_atomic(&dir.join(format!("{}.csv", spec.name)), crate::post::quantities::profile_csv(&pts).as_bytes())?;
        obs.log(&format!("profile {}: {} points along '{}'", spec.name, pts.len(), spec.boundary));
    }
    Ok(())
}
