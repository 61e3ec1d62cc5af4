//! FSI runs: a case with a fluid `[mesh]`, a `[solid]` with a material `model` and a `[time]`
//! table is run by the monolithic FSI step of [`crate::fsi`] (implicit Euler, the paper's).
//!
//! Each step adapts the ORIGINAL fluid mesh to the solid surface at `t_n`, transfers the fluid
//! velocity, solves fluid, solid and multiplier in one Newton solve and moves the solid. Results:
//! - `solution.pvd` with the pieces `fluid` (on each step's adapted mesh) and `solid` (deformed);
//! - `history.csv`: one row per step with the requested quantities and the built-in
//!   `coupling_force_x`, `coupling_force_y` (`_z`): the force of the fluid on the solid, the
//!   integral of the multiplier over gamma_f, plus `coupling_facets`;
//! - `profiles/NAME.csv` of the last step (`gamma_f_minus` / `gamma_f_plus` name the two sides of
//!   gamma_f);
//! - `summary.json` as for every run.
//!
//! Solid boundary values are constant in time in FSI runs (no load factor).

use crate::case::{Case, CaseError, SolidModel};
use crate::fsi::{step, FsiError, FsiModel, FsiProblem, FsiState};
use crate::output::{fluid_grid, History};
use crate::quantities::{evaluate_all, QuantityError, StepState};
use crate::run::{build_mesh, flow_problem, RunError, RunObserver, RunOptions, RunSummary, Timings};
use crate::solve::linear::{FaerLu, LinearSolver};
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

fn run_dim<const D: usize>(case: &Case, fluid_mesh: Mesh<D>, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let spec = case.solid.as_ref().ok_or_else(|| invalid("no [solid] table".into()))?;
    let ts = case.time.as_ref().ok_or_else(|| invalid("FSI runs need a [time] table".into()))?;
    if ts.scheme != crate::time::TimeScheme::Euler {
        return Err(invalid("FSI runs use implicit Euler (the paper's scheme): set time.scheme = \"euler\"".into()));
    }
    let surface = spec.surface.clone().ok_or_else(|| invalid("solid.surface is required with a fluid".into()))?;
    let t = Instant::now();
    let fluid = flow_problem(case, &fluid_mesh, &options.case_dir)?;
    let solid_mesh = crate::adaptation::solid_mesh::<D>(spec, &options.case_dir)?;
    let solid = crate::solid_run::problem::<D>(case, spec, false)?;
    let material = solid.material.clone();
    let problem = FsiProblem { fluid, solid, surface, adapt: AdaptOptions::new(spec.eps_hat) };
    let model = FsiModel::new(problem, &fluid_mesh, solid_mesh)?;
    let mut timings = Timings { mesh: t.elapsed().as_secs_f64(), ..Default::default() };
    let mut state = FsiState::at_rest(&model);
    let mut lu = FaerLu::default();
    let total = (ts.end / ts.dt - 1e-9).ceil() as usize;
    let mut series = PvdSeries::new(&options.out_dir, "solution");
    let mut history: Option<History> = None;
    let mut last: Vec<(String, f64)> = Vec::new();
    let (mut iterations, mut residuals) = (0usize, Vec::new());
    let mut dofs = BTreeMap::new();
    let clock = Instant::now();
    for k in 1..=total {
        let dt = (ts.end - state.time).min(ts.dt);
        let (next, st) = step(&model, &state, dt, &mut lu, &case.solver.newton).map_err(|e| match e {
            FsiError::Newton(n) => invalid(format!("step {k} (t = {:.6e}): {n}", state.time + dt)),
            other => RunError::Fsi(other),
        })?;
        let r = &st.report;
        iterations += r.newton.iterations;
        let residual = *r.newton.residual_norms.last().unwrap_or(&0.0);
        residuals.push(residual);
        timings.assemble += r.newton.assemble_seconds;
        timings.factorize += r.newton.factorize_seconds;
        timings.solve += r.newton.solve_seconds;
        timings.discretize += r.seconds.build;
        let out_t = Instant::now();
        let fluid_x = &st.x[..st.disc.fluid_dofs];
        let step_state = StepState { time: r.time, inv_dt: 1.0 / dt, u_star: Some(&st.u_old[..st.disc.fluid_dofs]) };
        let mut values = evaluate_all(&case.output, &st.disc.flow, &st.fluid_problem, fluid_x, &step_state).map_err(|e| match e {
            QuantityError::ProbeOutside { name, point } => RunError::ProbeOutside { name, point },
            QuantityError::Flow(f) => RunError::Flow(f),
        })?;
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
        let hist = history.get_or_insert_with(|| {
            History::new(&options.out_dir.join("history.csv"), &values.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>())
        });
        hist.push(k, r.time, r.newton.iterations, residual, &values.iter().map(|(_, v)| *v).collect::<Vec<_>>())?;
        if k == total {
            crate::run::write_profiles(case, &st.disc.flow, &st.fluid_problem, fluid_x, &options.out_dir, obs)?;
        }
        if k % ts.output_every == 0 || k == total {
            series.add(r.time, "fluid", &fluid_grid(&st.disc.flow, fluid_x)?)?;
            series.add(r.time, "solid", &crate::solid_run::solid_grid(&model.solid, material.as_ref(), &next.solid_x)?)?;
        }
        timings.output += out_t.elapsed().as_secs_f64();
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
        obs.step(k, total, r.time);
        dofs = BTreeMap::from([
            ("fluid".to_string(), r.fluid_dofs),
            ("solid".to_string(), r.solid_dofs),
            ("multiplier".to_string(), r.multiplier_dofs),
            ("total".to_string(), r.fluid_dofs + r.solid_dofs + r.multiplier_dofs),
        ]);
        last = values;
        state = next;
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
    })
}
