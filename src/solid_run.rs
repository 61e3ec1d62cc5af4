//! Solid-only runs: a case with a `[solid]` material law and no fluid mesh, solved quasi-statically
//! by load stepping ([`crate::solid::solve_quasi_static`]).
//!
//! Boundary values are multiplied by the load factor, ramped from 0 to 1 in
//! `solid.loading.steps` equal increments (halved on failure). Results in `--out DIR`:
//! - `solution.pvd` + `solution_solid_NNNNNN.vtu`: the deformed solid (9-node quadrilaterals /
//!   27-node hexahedra) with point data `displacement` and cell data `pressure` (the mixed laws'
//!   pressure at the cell centre) and `cauchy_stress` (the cell mean of
//!   `sigma = P F^T / J - p I` over its quadrature points, 9 components);
//! - `history.csv`: one row per converged load increment (`time` is the load factor) with the
//!   Newton iterations, the final residual and the `displacement` probes;
//! - `summary.json` as for every run.

use crate::adaptation::solid_mesh;
use crate::case::{Case, CaseError, Expr, ProbeField, SolidBoundaryType, SolidModel, SolidSpec};
use crate::output::{History, OutputError};
use crate::physics::solid::{det3, matmul, transpose, NeoHookeanCompressible, NeoHookeanMixed, SaintVenantKirchhoff, SolidMaterial};
use crate::run::{RunError, RunObserver, RunOptions, RunSummary, Timings};
use crate::solid::{pressure_at, solve_quasi_static_with, LoadStepping, SolidDiscretization, SolidProblem};
use crate::solve::linear::LinearSolver;
use fdfsi_fem::vtk::{PvdSeries, UnstructuredGrid, VtkCellType};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

fn invalid(message: String) -> RunError {
    RunError::Case(CaseError::Invalid { file: "case".into(), message })
}

/// The material law of a solid spec.
pub fn material(spec: &SolidSpec) -> Result<Arc<dyn SolidMaterial>, RunError> {
    let g = spec.shear_modulus.ok_or_else(|| invalid("solid.shear_modulus is required".into()))?;
    let k = spec.bulk_modulus;
    let need_k = || k.ok_or_else(|| invalid(format!("solid.model = {:?} needs bulk_modulus", spec.model)));
    Ok(match spec.model {
        SolidModel::Fixed => return Err(invalid("solid.model = \"fixed\" has no material law to solve".into())),
        SolidModel::NeoHookean => match k {
            None => Arc::new(NeoHookeanMixed::incompressible(g)),
            Some(k) => Arc::new(NeoHookeanMixed { shear_modulus: g, bulk_modulus: k }),
        },
        SolidModel::NeoHookeanCompressible => Arc::new(NeoHookeanCompressible::from_shear_bulk(g, need_k()?)),
        SolidModel::SaintVenantKirchhoff => {
            let k = need_k()?;
            Arc::new(SaintVenantKirchhoff { mu: g, lambda: k - 2.0 * g / 3.0 })
        }
    })
}

fn compile(values: &[crate::case::Scalar]) -> Result<Vec<Expr>, RunError> {
    values.iter().map(|v| Expr::compile(v).map_err(invalid)).collect()
}

/// The solid problem of a case: boundary values times the load factor when `ramp` (quasi-static
/// runs), constant otherwise (FSI runs, where the solver passes the time in the load argument).
pub(crate) fn problem<const D: usize>(case: &Case, spec: &SolidSpec, ramp: bool) -> Result<SolidProblem<D>, RunError> {
    let scale = move |load: f64| if ramp { load } else { 1.0 };
    let mut p = SolidProblem::new(case.physics.formulation, material(spec)?);
    for b in &spec.boundary {
        let exprs = compile(&b.value)?;
        match b.kind {
            SolidBoundaryType::Displacement => {
                let comps: Vec<usize> = b.components.clone().unwrap_or_else(|| (0..D).collect());
                p = p.with_displacement(&b.name, &comps, move |x, load| std::array::from_fn(|a| scale(load) * exprs[a].eval(x, 0.0)));
            }
            SolidBoundaryType::Traction => {
                p = p.with_traction(&b.name, move |x, load| std::array::from_fn(|a| scale(load) * exprs[a].eval(x, 0.0)));
            }
            SolidBoundaryType::Pressure => {
                let value = exprs[0].eval(&[0.0; 3], 0.0);
                p = p.with_pressure(&b.name, move |load| scale(load) * value);
            }
        }
    }
    Ok(p)
}

/// `fdfsi check` for a solid-only case.
pub fn describe(case: &Case, case_dir: &Path) -> Result<String, RunError> {
    fn go<const D: usize>(case: &Case, spec: &SolidSpec, dir: &Path) -> Result<String, RunError> {
        let mesh = solid_mesh::<D>(spec, dir)?;
        let cells = mesh.num_cells();
        let problem = problem::<D>(case, spec, true)?;
        let disc = SolidDiscretization::build(mesh, case.physics.formulation, problem.material.as_ref())?;
        disc.check_problem(&problem)?;
        Ok(format!(
            "{}: solid-only ({}), {D}D mesh of {cells} cells; {} dofs, nnz {}; {} load steps ({:?} Lagrangian)",
            case.title,
            problem.material.name(),
            disc.num_dofs(),
            disc.pattern.nnz(),
            spec.loading.steps,
            spec.loading.mode
        ))
    }
    let spec = case.solid.as_ref().ok_or_else(|| invalid("no [solid] table".into()))?;
    if case.dim() == 2 {
        go::<2>(case, spec, case_dir)
    } else {
        go::<3>(case, spec, case_dir)
    }
}

/// The case's `displacement` probes as (name, solid node, component): each probe point must
/// be a node of the solid mesh (reference configuration).
pub fn displacement_probes<const D: usize>(case: &Case, disc: &SolidDiscretization<D>) -> Result<Vec<(String, usize, usize)>, RunError> {
    let mut out = Vec::new();
    for p in case.output.probe.iter().filter(|p| p.field == ProbeField::Displacement) {
        let x0: [f64; D] = std::array::from_fn(|d| p.point.get(d).copied().unwrap_or(0.0));
        let node = disc.node_near(&x0);
        let dist: f64 = (0..D).map(|d| (disc.nodes_x0[node][d] - x0[d]).powi(2)).sum::<f64>().sqrt();
        if dist > 1e-9 * (1.0 + x0.iter().map(|v| v.abs()).fold(0.0, f64::max)) {
            return Err(invalid(format!("probe '{}': {:?} is not a node of the solid mesh (nearest is {dist:.3e} away)", p.name, p.point)));
        }
        out.push((p.name.clone(), node, p.component));
    }
    Ok(out)
}

/// Runs a solid-only case.
pub fn run_solid(case: &Case, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    if case.dim() == 2 {
        run_dim::<2>(case, options, obs)
    } else {
        run_dim::<3>(case, options, obs)
    }
}

fn run_dim<const D: usize>(case: &Case, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let spec = case.solid.as_ref().ok_or_else(|| invalid("no [solid] table".into()))?;
    let t = Instant::now();
    let mesh = solid_mesh::<D>(spec, &options.case_dir)?;
    let cells = mesh.num_cells();
    let problem = problem::<D>(case, spec, true)?;
    let disc = SolidDiscretization::build(mesh, case.physics.formulation, problem.material.as_ref())?;
    disc.check_problem(&problem)?;
    let mut timings = Timings { mesh: t.elapsed().as_secs_f64(), ..Default::default() };
    obs.log(&format!("solid: {} on {cells} cells, {} dofs; {} load steps", problem.material.name(), disc.num_dofs(), spec.loading.steps));
    let stepping = LoadStepping::uniform(spec.loading.mode, spec.loading.steps);
    if let Some(p) = case.output.probe.iter().find(|p| p.field != ProbeField::Displacement) {
        return Err(invalid(format!("probe '{}': solid-only runs have displacement probes only", p.name)));
    }
    let probe_nodes = displacement_probes(case, &disc)?;
    let names: Vec<String> = probe_nodes.iter().map(|(n, _, _)| n.clone()).collect();
    let mut history = History::new(&options.out_dir.join("history.csv"), &names)?;
    let mut converged = 0usize;
    let mut lu = case.solver.linear_solver();
    let sol = solve_quasi_static_with(&disc, &problem, &stepping, &mut lu, &case.solver.newton, |rec, x| {
        converged += 1;
        let r = rec.newton.as_ref().expect("a converged increment has its Newton report");
        let values: Vec<f64> = probe_nodes.iter().map(|&(_, node, a)| disc.displacement(x, node)[a]).collect();
        history.push(converged, rec.load, r.iterations, *r.residual_norms.last().unwrap_or(&0.0), &values).map_err(|e| e.to_string())
    })?;
    let converged: Vec<_> = sol.steps.iter().filter(|s| s.failure.is_none() && s.newton.is_some()).collect();
    for s in &sol.steps {
        let n = s.newton.as_ref();
        match &s.failure {
            None => obs.log(&format!(
                "load step {} (load {:.4}): newton {} |R| {}",
                s.step,
                s.load,
                n.map(|r| r.iterations).unwrap_or(0),
                n.map(|r| r.residual_norms.iter().map(|v| format!("{v:.2e}")).collect::<Vec<_>>().join(" ")).unwrap_or_default()
            )),
            Some(why) => obs.log(&format!("load step {} (load {:.4}) cut: {why}", s.step, s.load)),
        }
        if let Some(r) = n {
            timings.assemble += r.assemble_seconds;
            timings.factorize += r.factorize_seconds;
            timings.solve += r.solve_seconds;
        }
    }
    let t = Instant::now();
    let quantities: BTreeMap<String, f64> = probe_nodes.iter().map(|(name, node, a)| (name.clone(), disc.displacement(&sol.x, *node)[*a])).collect();
    let mut series = PvdSeries::new(&options.out_dir, "solution");
    series.add(sol.load, "solid", &solid_grid(&disc, problem.material.as_ref(), &sol.x)?)?;
    timings.output = t.elapsed().as_secs_f64();
    for (name, v) in &quantities {
        obs.log(&format!("{name} = {v:.10e}"));
    }
    let mut dofs = BTreeMap::new();
    dofs.insert("solid".to_string(), disc.num_dofs());
    dofs.insert("total".to_string(), disc.num_dofs());
    Ok(RunSummary {
        title: case.title.clone(),
        formulation: format!("{:?}", case.physics.formulation),
        dimension: D,
        cells,
        dofs,
        steps: converged.len(),
        newton_iterations: converged.iter().filter_map(|s| s.newton.as_ref()).map(|r| r.iterations).sum(),
        residual_norms: converged.iter().filter_map(|s| s.newton.as_ref()?.residual_norms.last().copied()).collect(),
        symbolic_factorizations: lu.symbolic_factorizations(),
        quantities,
        timings,
        timings_per_step: None,
        peak_memory_mib: None,
        provenance: None,
    })
}

/// The deformed solid as a VTK grid (see the module doc for its arrays).
pub(crate) fn solid_grid<const D: usize>(
    disc: &SolidDiscretization<D>,
    material: &dyn SolidMaterial,
    x: &[f64],
) -> Result<UnstructuredGrid, RunError> {
    let field = disc.displacement_field();
    let n = field.nodes.num_nodes;
    let points: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let u = disc.displacement(x, i);
            std::array::from_fn(|d| if d < D { disc.nodes_x0[i][d] + u[d] } else { 0.0 })
        })
        .collect();
    let mut grid = UnstructuredGrid::new(points);
    let ty = if D == 2 { VtkCellType::BiquadraticQuad } else { VtkCellType::TriquadraticHexahedron };
    let nc = disc.mesh.num_cells();
    for c in 0..nc {
        grid.push_cell(ty, field.nodes.cell(c)).map_err(OutputError::from)?;
    }
    let disp: Vec<f64> = (0..n)
        .flat_map(|i| {
            let u = disc.displacement(x, i);
            (0..3).map(move |d| if d < D { u[d] } else { 0.0 })
        })
        .collect();
    grid.add_point_data("displacement", 3, disp).map_err(OutputError::from)?;
    let f = disc.deformation_gradients(x).map_err(|e| invalid(format!("stress output: {e}")))?;
    let nq = disc.points_per_cell();
    let (mut pressure, mut stress) = (Vec::with_capacity(nc), Vec::with_capacity(nc * 9));
    let (mut p_mat, mut tangent) = ([[0.0; 3]; 3], [[[[0.0; 3]; 3]; 3]; 3]);
    for c in 0..nc {
        let p_c = if disc.mixed { pressure_at(disc, x, c, &disc.centroid_x0[c]) } else { 0.0 };
        pressure.push(p_c);
        let mut mean = [[0.0; 3]; 3];
        for q in 0..nq {
            let fq = &f[c * nq + q];
            material.stress_tangent(fq, &mut p_mat, &mut tangent);
            let j = det3(fq);
            let p_q = if disc.mixed { pressure_at(disc, x, c, &disc.qp_x0[c * nq + q]) } else { 0.0 };
            let sigma = matmul(&p_mat, &transpose(fq));
            for a in 0..3 {
                for b in 0..3 {
                    mean[a][b] += (sigma[a][b] / j - if a == b { p_q } else { 0.0 }) / nq as f64;
                }
            }
        }
        stress.extend(mean.iter().flatten());
    }
    grid.add_cell_data("pressure", 1, pressure).map_err(OutputError::from)?;
    grid.add_cell_data("cauchy_stress", 9, stress).map_err(OutputError::from)?;
    Ok(grid)
}
