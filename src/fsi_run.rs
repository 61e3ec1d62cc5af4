//! FSI runs: a case with a fluid `[mesh]`, a `[solid]` with a material `model` and a `[time]`
//! table is run by the monolithic FSI step of [`crate::fsi`] (implicit Euler, the paper's).
//!
//! Each step adapts the ORIGINAL fluid mesh to the solid surface at `t_n`, transfers the fluid
//! velocity, solves fluid, solid and multiplier in one Newton solve and moves the solid. Results:
//! - `solution.pvd` with the pieces `fluid` (on each step's adapted mesh), `solid` (deformed) and
//!   `gamma_f` (the coupling elements with the multiplier lambda, the traction of the fluid on the
//!   solid: see [`crate::output::gamma_f_grid`]);
//! - `history.csv`: one row per step with the requested quantities and the built-in
//!   `coupling_force_x`, `coupling_force_y` (`_z`): the force of the fluid on the solid, the
//!   integral of the multiplier over gamma_f, plus `coupling_facets`;
//! - `profiles/NAME.csv` of the last step (`gamma_f_minus` / `gamma_f_plus` name the two sides of
//!   gamma_f);
//! - `summary.json` as for every run.
//!
//! Solid boundary values are constant in time in FSI runs (no load factor).

use crate::case::{Case, CaseError, ProbeField, SolidModel};
use crate::checkpoint::{Checkpoint, Progress, RestartState};
use crate::fsi::{step, FsiError, FsiModel, FsiProblem, FsiState, FsiStep};
use crate::output::{fluid_grid, gamma_f_grid, History};
use crate::quantities::{evaluate_all, StepState};
use crate::run::{build_mesh, flow_problem, RunError, RunObserver, RunOptions, RunSummary, Timings};
use crate::solve::linear::LinearSolver;
use fdfsi_fem::adapt::AdaptOptions;
use fdfsi_fem::gmsh::AnyMesh;
use fdfsi_fem::mesh::Mesh;
use fdfsi_fem::vtk::PvdSeries;
use std::collections::BTreeMap;
use std::time::Instant;

/// Is this case an FSI run?
pub fn is_fsi(case: &Case) -> bool {
    case.mesh.is_some() && case.solid.as_ref().is_some_and(|s| s.model != SolidModel::Fixed)
}

/// The built-in quantities of an FSI run (they may appear in `[[output.combination]]`).
pub fn builtin_quantities(dim: usize) -> Vec<String> {
    let mut names: Vec<String> = ["x", "y", "z"][..dim].iter().map(|c| format!("coupling_force_{c}")).collect();
    names.push("coupling_facets".into());
    names
}

fn invalid(message: String) -> RunError {
    RunError::Case(CaseError::Invalid { file: "case".into(), message })
}

/// Runs an FSI case.
pub fn run_fsi(case: &Case, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    match build_mesh(case, &options.case_dir)? {
        AnyMesh::D2(m) => run_dim::<2>(case, m, options, obs),
        AnyMesh::D3(m) => run_dim::<3>(case, m, options, obs),
    }
}

/// The FSI model of a case on its (original) fluid mesh; relative paths in the case are resolved
/// against `case_dir`.
pub fn model<const D: usize>(case: &Case, fluid_mesh: &Mesh<D>, case_dir: &std::path::Path) -> Result<FsiModel<D>, RunError> {
    let spec = case.solid.as_ref().ok_or_else(|| invalid("no [solid] table".into()))?;
    let ts = case.time.as_ref().ok_or_else(|| invalid("FSI runs need a [time] table".into()))?;
    if ts.scheme != crate::time::TimeScheme::Euler {
        return Err(invalid("FSI runs use implicit Euler (the paper's scheme): set time.scheme = \"euler\"".into()));
    }
    let surface = spec.surface.clone().ok_or_else(|| invalid("solid.surface is required with a fluid".into()))?;
    let fluid = flow_problem(case, fluid_mesh, case_dir)?;
    let solid_mesh = crate::adaptation::solid_mesh::<D>(spec, case_dir)?;
    let solid = crate::solid_run::problem::<D>(case, spec, false)?;
    let problem = FsiProblem { fluid, solid, surface, adapt: AdaptOptions::new(spec.eps_hat) };
    Ok(FsiModel::new(problem, fluid_mesh, solid_mesh)?.with_multiplier(spec.multiplier))
}

/// The original fluid mesh adapted to the solid of a checkpoint written in `run_dir` (what the
/// run's next step starts from), with gamma_f tagged.
pub fn adapted_at<const D: usize>(
    case: &Case,
    fluid_mesh: Mesh<D>,
    case_dir: &std::path::Path,
    checkpoint: &Checkpoint,
    run_dir: &std::path::Path,
) -> Result<crate::adaptation::AdaptedFluid<D>, RunError> {
    let model = model(case, &fluid_mesh, case_dir)?;
    let restart = checkpoint.fsi_state(run_dir, model.solid.num_dofs())?;
    let solid = model.current_solid_mesh(&restart.solid_x);
    let surface = model.gamma_s(&restart.solid_x)?;
    let adapted = crate::adaptation::AdaptedFluid::new(fluid_mesh, &model.background, solid, surface, &model.problem.adapt);
    Ok(adapted.map_err(FsiError::from)?)
}

fn run_dim<const D: usize>(case: &Case, fluid_mesh: Mesh<D>, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let ts = case.time.as_ref().ok_or_else(|| invalid("FSI runs need a [time] table".into()))?;
    let t = Instant::now();
    let model = model(case, &fluid_mesh, &options.case_dir)?;
    let material = model.problem.solid.material.clone();
    let mesh_seconds = t.elapsed().as_secs_f64();
    // Displacement probes read the solid; the rest are fluid quantities.
    let solid_probes = crate::solid_run::displacement_probes(case, &model.solid)?;
    let mut fluid_output = case.output.clone();
    fluid_output.probe.retain(|p| p.field != ProbeField::Displacement);
    let mut lu = case.solver.linear_solver();
    let total = crate::time::num_steps(ts.dt, ts.end);
    let (mut state, mut series, mut history, mut timings, mut iterations, mut residuals, first) = match &options.resume {
        None => (FsiState::at_rest(&model), PvdSeries::new(&options.out_dir, "solution"), None, Timings::default(), 0, Vec::new(), 1),
        Some(c) => {
            let restart = c.fsi_state(&options.out_dir, model.solid.num_dofs())?;
            let state = FsiState::from_restart(&model, c.time, restart)?;
            let series = PvdSeries::resume(&options.out_dir, "solution", c.time)?;
            let history = History::resume(&options.out_dir.join("history.csv"), c.step)?;
            let p = &c.progress;
            obs.log(&format!("resuming after step {} (t = {:.6e}) from {}", c.step, c.time, Checkpoint::path(&options.out_dir).display()));
            (state, series, Some(history), p.timings.clone(), p.newton_iterations, p.residual_norms.clone(), c.step + 1)
        }
    };
    timings.mesh = mesh_seconds;
    let mut last: Vec<(String, f64)> = Vec::new();
    let mut dofs = BTreeMap::new();
    let clock = Instant::now();
    for k in first..=total {
        let dt = (ts.end - state.time).min(ts.dt);
        let (next, st) = step(&model, &state, dt, &mut lu, &case.solver.newton).map_err(|e| match e {
            e @ (FsiError::Newton(_) | FsiError::SingularAt { .. }) => invalid(format!("step {k} (t = {:.6e}): {e}", state.time + dt)),
            other => RunError::Fsi(other),
        })?;
        let r = &st.report;
        crate::run::log_newton(obs, &r.newton);
        let (a, sec) = (&r.adapt, &r.seconds);
        obs.detail(&format!(
            "  adapt: {} cut edges, {} moved and {} new nodes, {} new cells; {} coupling points, max distance to gamma_s {:.2e}",
            a.cut_edges, a.moved_nodes, a.new_nodes, a.new_cells, r.coupling_points, r.max_coupling_distance
        ));
        obs.detail(&format!(
            "  phases: adapt {:.3} s, build {:.3} s, transfer {:.3} s, newton {:.3} s, update {:.3} s",
            sec.adapt, sec.build, sec.transfer, sec.newton, sec.update
        ));
        iterations += r.newton.iterations;
        let residual = *r.newton.residual_norms.last().unwrap_or(&0.0);
        residuals.push(residual);
        timings.assemble += r.newton.assemble_seconds;
        timings.factorize += r.newton.factorize_seconds;
        timings.solve += r.newton.solve_seconds;
        timings.adapt += r.seconds.adapt;
        timings.discretize += r.seconds.build;
        timings.transfer += r.seconds.transfer;
        let out_t = Instant::now();
        let fluid_x = &st.x[..st.disc.fluid_dofs];
        let step_state = StepState { time: r.time, inv_dt: 1.0 / dt, u_star: Some(&st.u_old[..st.disc.fluid_dofs]) };
        let mut values = evaluate_all(&fluid_output, &st.disc.flow, &st.fluid_problem, fluid_x, &step_state)?;
        for (name, node, a) in &solid_probes {
            values.push((name.clone(), model.solid.displacement(&next.solid_x, *node)[*a]));
        }
        for (name, v) in builtin_quantities(D).into_iter().zip(r.multiplier_force.iter().copied().chain([r.coupling_elements as f64])) {
            values.push((name, v));
        }
        // Combinations may use the built-in quantities: evaluate them again with all values known.
        for c in &case.output.combination {
            let v: f64 = c.terms.iter().map(|(q, w)| w * values.iter().find(|(n, _)| n == q).map(|(_, v)| *v).unwrap_or(f64::NAN)).sum();
            if let Some(entry) = values.iter_mut().find(|(n, _)| *n == c.name) {
                entry.1 = v;
            }
        }
        if history.is_none() {
            let names: Vec<String> = values.iter().map(|(n, _)| n.clone()).collect();
            history = Some(History::new(&options.out_dir.join("history.csv"), &names)?);
        }
        let hist = history.as_mut().expect("created above");
        hist.push(k, r.time, r.newton.iterations, residual, &values.iter().map(|(_, v)| *v).collect::<Vec<_>>())?;
        if k == total {
            crate::run::write_profiles(case, &st.disc.flow, &st.fluid_problem, fluid_x, &options.out_dir, obs)?;
        }
        if k == total {
            write_speed_picture(&model, &st, &next.solid_x, &options.out_dir)?;
        }
        if k % ts.output_every == 0 || k == total {
            write_surfaces_picture(&st, k, &options.out_dir)?;
            series.add(r.time, "fluid", &fluid_grid(&st.disc.flow, fluid_x)?)?;
            series.add(r.time, "solid", &crate::solid_run::solid_grid(&model.solid, material.as_ref(), &next.solid_x)?)?;
            series.add(r.time, "gamma_f", &gamma_f_grid(&st.disc, &st.x)?)?;
        }
        // Output time is added before the checkpoint (so the checkpoint's totals include this
        // step's) and the checkpoint's own write after it.
        let out_seconds = out_t.elapsed().as_secs_f64();
        timings.output += out_seconds;
        obs.log(&format!(
            "step {k}/{total} t = {:.6e}: newton {} |R| = {residual:.2e}; {} coupling facets, dofs {} + {} + {}; force [{}]; {:.2} s elapsed",
            r.time,
            r.newton.iterations,
            r.coupling_elements,
            r.fluid_dofs,
            r.solid_dofs,
            r.multiplier_dofs,
            r.multiplier_force.iter().map(|f| format!("{f:.6e}")).collect::<Vec<_>>().join(", "),
            clock.elapsed().as_secs_f64()
        ));
        dofs = BTreeMap::from([
            ("fluid".to_string(), r.fluid_dofs),
            ("solid".to_string(), r.solid_dofs),
            ("multiplier".to_string(), r.multiplier_dofs),
            ("total".to_string(), r.fluid_dofs + r.solid_dofs + r.multiplier_dofs),
        ]);
        last = values;
        state = next;
        options
            .after_step(case, k, state.time, || (RestartState::Fsi(state.to_restart()), Progress::after_step(iterations, &residuals, &timings, t)))?;
        timings.output += out_t.elapsed().as_secs_f64() - out_seconds;
        obs.step(k, total, state.time);
    }
    for (name, v) in &last {
        obs.log(&format!("{name} = {v:.10e}"));
    }
    Ok(RunSummary {
        title: case.title.clone(),
        formulation: format!("{:?}", case.physics.formulation),
        dimension: D,
        cells: fluid_mesh.num_cells(),
        dofs,
        steps: total,
        newton_iterations: iterations,
        residual_norms: residuals,
        symbolic_factorizations: lu.symbolic_factorizations(),
        quantities: last.into_iter().collect(),
        timings,
        timings_per_step: None,
        peak_memory_mib: None,
        provenance: None,
    })
}

/// 2D: `speed.png` of the last step around the solid (its bounding box widened by twice its size
/// on each side, clipped to the fluid mesh), with gamma_f drawn in white.
fn write_speed_picture<const D: usize>(model: &FsiModel<D>, st: &FsiStep<D>, solid_x: &[f64], out_dir: &std::path::Path) -> Result<(), RunError> {
    let Some(flow) = (&st.disc.flow as &dyn std::any::Any).downcast_ref::<crate::flow::FlowDiscretization<2>>() else {
        return Ok(());
    };
    let solid = model.current_solid_mesh(solid_x);
    let (lo, hi) = fdfsi_fem::mesh::bounding_box(&solid.points);
    let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let window = [[lo[0] - 2.0 * size, lo[1] - 2.0 * size], [hi[0] + 2.0 * size, hi[1] + 2.0 * size]];
    let outlines: Vec<Vec<[f64; 2]>> =
        st.disc.adapted.gamma_f.iter().map(|g| g.vertices.iter().map(|&v| std::array::from_fn(|d| flow.mesh.points[v][d])).collect()).collect();
    let png = out_dir.join("speed.png");
    crate::picture::write_speed_png_window(flow, &st.x[..st.disc.fluid_dofs], &png, 1600, Some(window), &outlines)
        .map_err(|message| crate::output::OutputError::Io { path: png.display().to_string(), source: std::io::Error::other(message) }.into())
}

/// 3D: `pictures/gamma_step_NNNN.png`, gamma_s (at the start of step `k`, the surface the fluid
/// mesh was adapted to) and gamma_f of step `k` (see [`crate::picture::write_surfaces_png`]).
fn write_surfaces_picture<const D: usize>(st: &FsiStep<D>, k: usize, out_dir: &std::path::Path) -> Result<(), RunError> {
    if D != 3 {
        return Ok(());
    }
    let lift = |p: &[f64; D]| -> [f64; 3] { std::array::from_fn(|d| p[d]) };
    let surface = &st.disc.surface;
    let gamma_s: Vec<[[f64; 3]; 3]> = (0..surface.num_pieces()).map(|i| std::array::from_fn(|k| lift(&surface.corners(i)[k]))).collect();
    let points = &st.disc.flow.mesh.points;
    let gamma_f: Vec<[[f64; 3]; 3]> = st.disc.adapted.gamma_f.iter().map(|g| std::array::from_fn(|k| lift(&points[g.vertices[k]]))).collect();
    let dir = out_dir.join("pictures");
    let png = dir.join(format!("gamma_step_{k:04}.png"));
    let io = |e: std::io::Error| RunError::from(crate::output::OutputError::Io { path: png.display().to_string(), source: e });
    std::fs::create_dir_all(&dir).map_err(io)?;
    crate::picture::write_surfaces_png(&png, &gamma_s, &gamma_f, 700).map_err(|m| io(std::io::Error::other(m)))
}
