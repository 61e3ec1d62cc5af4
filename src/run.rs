//! The driver behind `fdfsi run`: case -> mesh -> discretisation -> solve -> output.
//!
//! Each phase runs inside a named timer whose seconds go to `summary.json`.

use crate::case::{BoundaryType, Case, CaseError, Expr, FlowModel, MeshSpec};
use crate::flow::{solve_steady, DirichletBc, FlowDiscretization, FlowError, FlowProblem, TractionBc, VectorFn};
use crate::output::{fluid_grid, write_atomic, History, OutputError};
use crate::physics::fluid::FluidParams;
use crate::quantities::{boundary_integral, probe};
use crate::solve::linear::FaerLu;
use fdfsi_fem::generate;
use fdfsi_fem::gmsh::{read_msh, AnyMesh, GmshError};
use fdfsi_fem::mesh::{Mesh, Topology};
use fdfsi_fem::vtk::{PvdSeries, VtkError};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;
use thiserror::Error;

/// The case built into the binary: `fdfsi run` with no case file runs it.
pub const DEFAULT_CASE: &str = include_str!("../cases/channel-stokes.toml");

/// Built-in cases: (name, TOML text). `fdfsi cases` lists them.
pub const BUILTIN_CASES: &[(&str, &str)] = &[
    ("channel-stokes", include_str!("../cases/channel-stokes.toml")),
    ("pipe-axisymmetric-stokes", include_str!("../cases/pipe-axisymmetric-stokes.toml")),
    ("quarter-pipe-3d-stokes", include_str!("../cases/quarter-pipe-3d-stokes.toml")),
    ("cylinder-stokes-gmsh", include_str!("../cases/cylinder-stokes-gmsh.toml")),
    ("schaefer-turek-2d1", include_str!("../cases/schaefer-turek-2d1.toml")),
];

/// A run failure.
#[derive(Debug, Error)]
pub enum RunError {
    #[error(transparent)]
    Case(#[from] CaseError),
    #[error(transparent)]
    Gmsh(#[from] GmshError),
    #[error("{file}: the mesh is {found}D but physics.formulation needs {expected}D")]
    MeshDimension { file: String, found: usize, expected: usize },
    #[error(transparent)]
    Flow(#[from] FlowError),
    #[error(transparent)]
    Output(#[from] OutputError),
    #[error(transparent)]
    Vtk(#[from] VtkError),
    #[error("probe '{name}' at {point:?} lies outside the fluid mesh")]
    ProbeOutside { name: String, point: Vec<f64> },
}

/// Where a run reads and writes.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Output directory (created).
    pub out_dir: PathBuf,
    /// Directory that relative paths in the case (mesh files) are resolved against.
    pub case_dir: PathBuf,
}

/// Wall time per phase, seconds.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Timings {
    pub mesh: f64,
    pub discretize: f64,
    pub assemble: f64,
    pub factorize: f64,
    pub solve: f64,
    pub output: f64,
    pub total: f64,
}

/// What `summary.json` holds.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    pub title: String,
    pub formulation: String,
    pub dimension: usize,
    pub cells: usize,
    pub dofs: BTreeMap<String, usize>,
    pub steps: usize,
    pub newton_iterations: usize,
    pub residual_norms: Vec<f64>,
    pub symbolic_factorizations: usize,
    pub quantities: BTreeMap<String, f64>,
    pub timings: Timings,
}

/// Parses and validates a case and checks that its mesh can be built and names the boundaries
/// the case uses; returns a one-paragraph description of the problem (`fdfsi check`).
pub fn check_case(case: &Case, file: &str, case_dir: &Path) -> Result<String, RunError> {
    case.validate(file)?;
    match build_mesh(case, case_dir)? {
        AnyMesh::D2(m) => describe::<2>(case, m),
        AnyMesh::D3(m) => describe::<3>(case, m),
    }
}

fn describe<const D: usize>(case: &Case, mesh: Mesh<D>) -> Result<String, RunError> {
    for b in &case.boundary {
        mesh.boundary_tag(&b.name).map_err(FlowError::from)?;
    }
    let cells = mesh.num_cells();
    let disc = FlowDiscretization::build(mesh, case.physics.formulation)?;
    let v = disc.layout.fields[0].num_dofs();
    let p = disc.layout.fields[1].num_dofs();
    Ok(format!(
        "{}: {:?} {:?} flow, {D}D mesh of {cells} cells; dofs: velocity {v}, pressure {p}, total {}; nnz {}",
        case.title,
        case.physics.model,
        case.physics.formulation,
        v + p,
        disc.pattern.nnz()
    ))
}

/// Builds the case's mesh.
pub fn build_mesh(case: &Case, case_dir: &Path) -> Result<AnyMesh, RunError> {
    Ok(match &case.mesh {
        MeshSpec::Rectangle { x, y, n } => {
            AnyMesh::D2(generate::rectangle_triangles(x[0], x[1], y[0], y[1], n[0], n[1], generate::DiagonalPattern::Alternating))
        }
        MeshSpec::Channel { length, height, n, grading } => {
            AnyMesh::D2(generate::channel_triangles(*length, *height, n[0], n[1], *grading))
        }
        MeshSpec::Box { x, y, z, n } => {
            AnyMesh::D3(generate::box_tetrahedra(x[0], x[1], y[0], y[1], z[0], z[1], n[0], n[1], n[2]))
        }
        MeshSpec::Pipe { radius, length, n_radial, n_axial, quarter } => {
            AnyMesh::D3(generate::pipe_tetrahedra(*radius, *length, *n_radial, *n_axial, *quarter))
        }
        MeshSpec::Gmsh { file } => {
            let path = if file.is_absolute() { file.clone() } else { case_dir.join(file) };
            let mesh = read_msh(&path)?;
            let found = match &mesh {
                AnyMesh::D2(_) => 2,
                AnyMesh::D3(_) => 3,
            };
            if found != case.dim() {
                return Err(RunError::MeshDimension { file: path.display().to_string(), found, expected: case.dim() });
            }
            mesh
        }
    })
}

/// Runs a case; `log` receives one line per notable event.
pub fn run_case(case: &Case, options: &RunOptions, log: &mut dyn FnMut(&str)) -> Result<RunSummary, RunError> {
    let t0 = Instant::now();
    case.validate("case")?;
    std::fs::create_dir_all(&options.out_dir)
        .map_err(|source| OutputError::Io { path: options.out_dir.display().to_string(), source })?;
    write_atomic(&options.out_dir.join("case.toml"), case.to_toml().as_bytes())?;
    let t = Instant::now();
    let mesh = build_mesh(case, &options.case_dir)?;
    let mesh_seconds = t.elapsed().as_secs_f64();
    let mut summary = match mesh {
        AnyMesh::D2(m) => run_flow::<2>(case, m, options, log)?,
        AnyMesh::D3(m) => run_flow::<3>(case, m, options, log)?,
    };
    summary.timings.mesh = mesh_seconds;
    summary.timings.total = t0.elapsed().as_secs_f64();
    let json = serde_json::to_string_pretty(&summary).expect("summary serialises");
    write_atomic(&options.out_dir.join("summary.json"), json.as_bytes())?;
    Ok(summary)
}

/// A vector of compiled expressions as a field of position and time.
fn vector_fn<const D: usize>(exprs: Vec<Expr>) -> VectorFn<D> {
    Arc::new(move |x: &[f64; D], t: f64| std::array::from_fn(|a| exprs[a].eval(x, t)))
}

fn compile_all(values: &[crate::case::Scalar]) -> Result<Vec<Expr>, CaseError> {
    values
        .iter()
        .map(|v| Expr::compile(v).map_err(|message| CaseError::Invalid { file: "case".into(), message }))
        .collect()
}

/// The flow problem a case describes on `mesh`.
pub fn flow_problem<const D: usize>(case: &Case, mesh: &Mesh<D>) -> Result<FlowProblem<D>, RunError> {
    let mut dirichlet = Vec::new();
    let mut traction = Vec::new();
    let all: Vec<usize> = (0..D).collect();
    let zero: VectorFn<D> = Arc::new(|_: &[f64; D], _| [0.0; D]);
    // Exterior facets whose normal velocity is not prescribed fix the pressure level.
    let mut pressure_fixed = false;
    let mut covered = 0usize;
    for b in &case.boundary {
        mesh.boundary_tag(&b.name).map_err(FlowError::from)?;
        let count = mesh.boundary_facets(&b.name).map_err(FlowError::from)?.len();
        let bc = |components: Vec<usize>, value: VectorFn<D>| DirichletBc { boundary: b.name.clone(), components, value };
        match b.kind {
            BoundaryType::Velocity => {
                dirichlet.push(bc(all.clone(), vector_fn(compile_all(&b.value)?)));
                covered += count;
            }
            BoundaryType::NoSlip => {
                dirichlet.push(bc(all.clone(), zero.clone()));
                covered += count;
            }
            BoundaryType::Axis => {
                dirichlet.push(bc(vec![1], zero.clone()));
                covered += count;
            }
            BoundaryType::Symmetry => {
                dirichlet.push(bc(vec![b.normal_axis.unwrap_or(0)], zero.clone()));
                covered += count;
            }
            BoundaryType::Traction => {
                let f = vector_fn::<D>(compile_all(&b.value)?);
                traction.push(TractionBc { boundary: b.name.clone(), traction: Arc::new(move |x, _n, t| f(x, t)) });
                pressure_fixed = true;
            }
            BoundaryType::Pressure => {
                let p = compile_all(&b.value)?.remove(0);
                traction.push(TractionBc {
                    boundary: b.name.clone(),
                    traction: Arc::new(move |x: &[f64; D], n: &[f64; D], t| {
                        let pv = p.eval(x, t);
                        std::array::from_fn(|a| -pv * n[a])
                    }),
                });
                pressure_fixed = true;
            }
            BoundaryType::Free => pressure_fixed = true,
        }
    }
    let exterior = Topology::build(mesh).exterior_facets().len();
    if covered < exterior {
        pressure_fixed = true; // some boundary is traction-free by default
    }
    let body_force = match &case.body_force {
        Some(f) => Some(vector_fn::<D>(compile_all(f)?)),
        None => None,
    };
    Ok(FlowProblem {
        formulation: case.physics.formulation,
        params: FluidParams {
            viscosity: case.fluid.viscosity,
            density: case.fluid.density,
            inv_dt: 0.0,
            convection: case.physics.model == FlowModel::NavierStokes,
            viscous_form: case.fluid.viscous_form,
        },
        body_force,
        dirichlet,
        traction,
        pin_pressure: !pressure_fixed,
    })
}

fn run_flow<const D: usize>(case: &Case, mesh: Mesh<D>, options: &RunOptions, log: &mut dyn FnMut(&str)) -> Result<RunSummary, RunError> {
    let problem = flow_problem(case, &mesh)?;
    let t = Instant::now();
    let cells = mesh.num_cells();
    let disc = FlowDiscretization::build(mesh, case.physics.formulation)?;
    let discretize = t.elapsed().as_secs_f64();
    let nv = disc.layout.fields[0].num_dofs();
    let np = disc.layout.fields[1].num_dofs();
    log(&format!(
        "mesh: {cells} cells; dofs: velocity {nv}, pressure {np}, total {} (nnz {}); {:.2} s",
        nv + np,
        disc.pattern.nnz(),
        discretize
    ));
    let mut lu = FaerLu::default();
    let sol = solve_steady(&disc, &problem, &mut lu, &case.solver.newton)?;
    let rep = &sol.newton;
    for (k, r) in rep.residual_norms.iter().enumerate() {
        let du = rep.update_norms.get(k).map(|d| format!(", |du| = {d:.3e}")).unwrap_or_default();
        log(&format!("newton {k}: |R| = {r:.3e}{du}"));
    }
    let t = Instant::now();
    let mut quantities = BTreeMap::new();
    for p in &case.output.probe {
        let v = probe(&disc, &sol.x, p).ok_or_else(|| RunError::ProbeOutside { name: p.name.clone(), point: p.point.clone() })?;
        quantities.insert(p.name.clone(), v);
    }
    for b in &case.output.boundary_integral {
        quantities.insert(b.name.clone(), boundary_integral(&disc, &problem, &sol.x, b)?);
    }
    for c in &case.output.combination {
        let v = c.terms.iter().map(|(q, k)| k * quantities.get(q).copied().unwrap_or(f64::NAN)).sum();
        quantities.insert(c.name.clone(), v);
    }
    for (name, v) in &quantities {
        log(&format!("{name} = {v:.10e}"));
    }
    let names: Vec<String> = quantities.keys().cloned().collect();
    let values: Vec<f64> = quantities.values().copied().collect();
    let mut history = History::new(&options.out_dir.join("history.csv"), &names);
    history.push(0, 0.0, rep.iterations, *rep.residual_norms.last().unwrap_or(&0.0), &values)?;
    let mut series = PvdSeries::new(&options.out_dir, "solution");
    series.add(0.0, "fluid", &fluid_grid(&disc, &sol.x)?)?;
    if let Some(disc2) = (&disc as &dyn std::any::Any).downcast_ref::<FlowDiscretization<2>>() {
        let png = options.out_dir.join("speed.png");
        crate::picture::write_speed_png(disc2, &sol.x, &png, 1600).map_err(|message| OutputError::Io {
            path: png.display().to_string(),
            source: std::io::Error::other(message),
        })?;
    }
    let output = t.elapsed().as_secs_f64();
    let mut dofs = BTreeMap::new();
    dofs.insert("velocity".to_string(), nv);
    dofs.insert("pressure".to_string(), np);
    dofs.insert("total".to_string(), nv + np);
    Ok(RunSummary {
        title: case.title.clone(),
        formulation: format!("{:?}", case.physics.formulation),
        dimension: D,
        cells,
        dofs,
        steps: 1,
        newton_iterations: rep.iterations,
        residual_norms: rep.residual_norms.clone(),
        symbolic_factorizations: crate::solve::linear::LinearSolver::symbolic_factorizations(&lu),
        quantities,
        timings: Timings {
            mesh: 0.0,
            discretize,
            assemble: rep.assemble_seconds,
            factorize: rep.factorize_seconds,
            solve: rep.solve_seconds,
            output,
            total: 0.0,
        },
    })
}
