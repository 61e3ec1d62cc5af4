//! The driver behind `fdfsi run`: case -> mesh -> discretisation -> solve -> output.
//!
//! Each phase runs inside a named timer whose seconds go to `summary.json`.

use crate::case::{BoundaryType, Case, CaseError, Expr, FlowModel, MeshSpec, TimeFn};
use crate::checkpoint::{Checkpoint, CheckpointError, Progress, RestartState, CHECKPOINT_VERSION};
use crate::flow::{solve_steady, DirichletBc, FlowDiscretization, FlowError, FlowProblem, TractionBc, VectorFn};
use crate::output::{fluid_grid, write_atomic, History, OutputError};
use crate::physics::fluid::FluidParams;
use crate::quantities::{evaluate_all, QuantityError, StepState};
use crate::time::{solve_unsteady_from, TimeOptions};
use fdfsi_fem::generate;
use fdfsi_fem::gmsh::{read_msh, AnyMesh, GmshError};
use fdfsi_fem::mesh::{Mesh, Topology};
use fdfsi_fem::vtk::{PvdSeries, VtkError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
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
    ("womersley-axisymmetric", include_str!("../cases/womersley-axisymmetric.toml")),
    ("skewed-plate-dirichlet", include_str!("../cases/skewed-plate-dirichlet.toml")),
    ("model-problem-1", include_str!("../cases/model-problem-1.toml")),
    ("model-problem-2", include_str!("../cases/model-problem-2.toml")),
    ("model-problem-3", include_str!("../cases/model-problem-3.toml")),
    ("model-problem-4", include_str!("../cases/model-problem-4.toml")),
    ("model-problem-4-fine", include_str!("../cases/model-problem-4-fine.toml")),
    ("cylinder-re100", include_str!("../cases/cylinder-re100.toml")),
    ("slab-3d-poiseuille", include_str!("../cases/slab-3d-poiseuille.toml")),
    ("cook-membrane", include_str!("../cases/cook-membrane.toml")),
    ("cylinder-inflation-axisymmetric", include_str!("../cases/cylinder-inflation-axisymmetric.toml")),
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
    #[error(transparent)]
    Time(#[from] crate::time::TimeError),
    #[error(transparent)]
    Adaptation(#[from] crate::adaptation::AdaptationError),
    #[error(transparent)]
    Solid(#[from] crate::solid::SolidError),
    #[error(transparent)]
    Fsi(#[from] crate::fsi::FsiError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error("{out_dir}: the run will write about {needed} but only {available} are free; free some space, choose another --out or write the fields less often (time.output_every)")]
    DiskFull { out_dir: String, needed: String, available: String },
    #[error("interrupted after step {step} (t = {time:.6e}); a checkpoint is in {out_dir}: continue with `fdfsi run --resume {out_dir}`")]
    Interrupted { step: usize, time: f64, out_dir: String },
}

impl From<QuantityError> for RunError {
    fn from(e: QuantityError) -> Self {
        match e {
            QuantityError::ProbeOutside { name, point } => RunError::ProbeOutside { name, point },
            QuantityError::Flow(f) => RunError::Flow(f),
        }
    }
}

/// Receives what a run reports: log lines and step progress.
pub trait RunObserver {
    /// One line of the run's log.
    fn log(&mut self, line: &str);
    /// Called after step `step` of `total` completed at time `time`.
    fn step(&mut self, _step: usize, _total: usize, _time: f64) {}
    /// A line of detail (every Newton iteration, the phases of a step): shown with `--verbose`.
    fn detail(&mut self, _line: &str) {}
}

/// One line per Newton iteration of `report`: `newton k: |R| = ..., |du| = ...`.
fn newton_lines(report: &crate::solve::newton::NewtonReport) -> impl Iterator<Item = String> + '_ {
    report.residual_norms.iter().enumerate().map(|(k, r)| {
        let du = report.update_norms.get(k).map(|d| format!(", |du| = {d:.3e}")).unwrap_or_default();
        format!("newton {k}: |R| = {r:.3e}{du}")
    })
}

/// The Newton iterations of `report` as detail lines.
pub(crate) fn log_newton(obs: &mut dyn RunObserver, report: &crate::solve::newton::NewtonReport) {
    for line in newton_lines(report) {
        obs.detail(&format!("  {line}"));
    }
    obs.detail(&format!(
        "  assemble {:.3} s, factorize {:.3} s ({} numeric factorisations), solve {:.3} s",
        report.assemble_seconds, report.factorize_seconds, report.factorizations, report.solve_seconds
    ));
}

impl<F: FnMut(&str)> RunObserver for F {
    fn log(&mut self, line: &str) {
        self(line)
    }
}

/// Where a run reads and writes, and how it saves restart points.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Output directory (created).
    pub out_dir: PathBuf,
    /// Directory that relative paths in the case (mesh files) are resolved against.
    pub case_dir: PathBuf,
    /// Write `out_dir/checkpoint.json` after every this many steps (time-dependent runs).
    pub checkpoint_every: Option<usize>,
    /// Continue from this checkpoint (read from `out_dir`) instead of starting at `t = 0`.
    pub resume: Option<Checkpoint>,
    /// When set (e.g. by a Ctrl-C handler), the run stops after the current step, writes a
    /// checkpoint and returns [`RunError::Interrupted`].
    pub stop: Option<Arc<AtomicBool>>,
}

impl RunOptions {
    /// Options writing into `out_dir`, resolving case paths against `case_dir`, without
    /// checkpoints.
    pub fn new(out_dir: impl Into<PathBuf>, case_dir: impl Into<PathBuf>) -> Self {
        RunOptions { out_dir: out_dir.into(), case_dir: case_dir.into(), ..Default::default() }
    }

    /// Options that continue the run whose output (and checkpoint) is in `out_dir`; returns them
    /// with the case stored in the checkpoint.
    pub fn resume(out_dir: impl Into<PathBuf>) -> Result<(Case, Self), RunError> {
        let out_dir = out_dir.into();
        let checkpoint = Checkpoint::read(&out_dir)?;
        let file = Checkpoint::path(&out_dir).display().to_string();
        let case = Case::from_toml_str(&checkpoint.case, &file)?;
        let options = RunOptions { out_dir, case_dir: checkpoint.case_dir.clone(), resume: Some(checkpoint), ..Default::default() };
        Ok((case, options))
    }

    /// Has a stop been requested?
    fn stop_requested(&self) -> bool {
        self.stop.as_ref().is_some_and(|s| s.load(Ordering::SeqCst))
    }

    /// Saves a checkpoint after `step` if one is due (every `checkpoint_every` steps, or a stop
    /// was requested); returns `Err` with the interruption message when the run must stop.
    pub(crate) fn after_step(&self, case: &Case, step: usize, time: f64, state: impl FnOnce() -> (RestartState, Progress)) -> Result<(), RunError> {
        let stop = self.stop_requested();
        let due = self.checkpoint_every.is_some_and(|n| n > 0 && step % n == 0);
        if stop || due {
            let (state, progress) = state();
            let case_dir = std::path::absolute(&self.case_dir).unwrap_or_else(|_| self.case_dir.clone());
            let builds = crate::provenance::builds_so_far(self.resume.as_ref().map_or(&[], |c| &c.builds));
            let c = Checkpoint { version: CHECKPOINT_VERSION, case: case.to_toml(), case_dir, step, time, state, progress, builds };
            c.write(&self.out_dir)?;
        }
        if stop {
            return Err(RunError::Interrupted { step, time, out_dir: self.out_dir.display().to_string() });
        }
        Ok(())
    }
}

/// Wall time per phase, seconds.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Timings {
    /// Building (and, with a solid, adapting) the initial mesh.
    pub mesh: f64,
    /// Adapting the fluid mesh to gamma_s in the steps of an FSI run.
    #[serde(default)]
    pub adapt: f64,
    /// Dof maps, sparsity patterns and coupling elements.
    pub discretize: f64,
    /// Mapping the fluid velocity onto each step's adapted mesh (FSI).
    #[serde(default)]
    pub transfer: f64,
    pub assemble: f64,
    pub factorize: f64,
    pub solve: f64,
    /// Quantities, history, fields and checkpoints.
    pub output: f64,
    /// Wall time of the whole run; for a resumed run, of all its parts (each earlier part counted
    /// from the setup of its time loop: its case check and mesh reading, a few seconds, are not
    /// carried). The step phases (adapt, transfer, assemble, factorize, solve, output, and an
    /// FSI run's discretize) are summed over the parts; `mesh` and a flow run's `discretize` are
    /// the last part's.
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
    /// `timings` divided by the number of steps (time-dependent runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub timings_per_step: Option<Timings>,
    /// Peak resident memory of the process, MiB ([`peak_resident_mib`]; for a resumed run, of
    /// its last part). Absent where the system does not report it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_memory_mib: Option<f64>,
    /// The code and case behind the results ([`crate::provenance`]); filled by [`run_case`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub provenance: Option<crate::provenance::Provenance>,
}

/// Peak resident memory (`VmHWM` of `/proc/self/status`) of this process in MiB; `None` where
/// the system has no such file (not Linux).
pub fn peak_resident_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kib: f64 = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?.trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kib / 1024.0)
}

/// Parses and validates a case and checks everything that needs no solve (see
/// [`crate::check`]): the mesh can be built and names the boundaries the case uses, the tables
/// can be read, the solid and the probes lie in the fluid. Returns a description of the problem
/// and a summary: dofs per field, the number of steps, an estimate of the output size
/// (`fdfsi check`).
pub fn check_case(case: &Case, file: &str, case_dir: &Path) -> Result<String, RunError> {
    Ok(crate::check::check(case, file, case_dir)?.to_string())
}

/// Builds the case's fluid mesh.
pub fn build_mesh(case: &Case, case_dir: &Path) -> Result<AnyMesh, RunError> {
    let spec = case.mesh.as_ref().ok_or_else(|| CaseError::Invalid { file: "case".into(), message: "the case has no fluid [mesh]".into() })?;
    Ok(match spec {
        MeshSpec::Rectangle { x, y, n } => {
            AnyMesh::D2(generate::rectangle_triangles(x[0], x[1], y[0], y[1], n[0], n[1], generate::DiagonalPattern::Alternating))
        }
        MeshSpec::Channel { length, height, n, grading } => AnyMesh::D2(generate::channel_triangles(*length, *height, n[0], n[1], *grading)),
        MeshSpec::Box { x, y, z, n } => AnyMesh::D3(generate::box_tetrahedra(x[0], x[1], y[0], y[1], z[0], z[1], n[0], n[1], n[2])),
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

/// The fluid mesh of a case: built, and adapted to the solid's surface when the case has one
/// (the facets on gamma_s then form the boundary `gamma_f`).
pub fn fluid_mesh(case: &Case, case_dir: &Path, obs: &mut dyn RunObserver) -> Result<AnyMesh, RunError> {
    let mesh = build_mesh(case, case_dir)?;
    if case.solid.is_none() {
        return Ok(mesh);
    }
    fn adapt<const D: usize>(case: &Case, m: Mesh<D>, dir: &Path, obs: &mut dyn RunObserver) -> Result<Mesh<D>, RunError> {
        let a = crate::adaptation::adapt_fluid(case, m, dir)?;
        let st = &a.adapted.stats;
        obs.log(&format!(
            "adapt: {} cut edges, {} moved and {} new nodes, {} new cells, {} coupling facets, min quality {:.3}",
            st.cut_edges, st.moved_nodes, st.new_nodes, st.new_cells, st.coupling_facets, st.min_quality
        ));
        Ok(a.adapted.mesh)
    }
    Ok(match mesh {
        AnyMesh::D2(m) => AnyMesh::D2(adapt(case, m, case_dir, obs)?),
        AnyMesh::D3(m) => AnyMesh::D3(adapt(case, m, case_dir, obs)?),
    })
}

/// `fdfsi adapt`: adapts the case's fluid mesh to its solid and writes the mesh files and
/// counts into `out_dir` (see [`crate::adaptation`]).
pub fn adapt_case(case: &Case, case_dir: &Path, out_dir: &Path) -> Result<crate::adaptation::AdaptSummary, RunError> {
    use crate::adaptation::{adapt_fluid, write_adapt_report};
    Ok(match build_mesh(case, case_dir)? {
        AnyMesh::D2(m) => write_adapt_report(&adapt_fluid(case, m, case_dir)?, out_dir)?,
        AnyMesh::D3(m) => write_adapt_report(&adapt_fluid(case, m, case_dir)?, out_dir)?,
    })
}

/// `fdfsi adapt --at RUN_DIR`: the fluid mesh of an FSI run adapted to the solid of its
/// checkpoint (the mesh the run's next step starts from), written like [`adapt_case`]. To look
/// at the adaptation of a step that failed: the files show the cut cells, gamma_s and gamma_f,
/// and `stats.min_quality` the worst cell.
pub fn adapt_checkpoint(run_dir: &Path, out_dir: &Path) -> Result<crate::adaptation::AdaptSummary, RunError> {
    use crate::adaptation::write_adapt_report;
    let (case, options) = RunOptions::resume(run_dir)?;
    let checkpoint = options.resume.as_ref().expect("resume options hold the checkpoint");
    if !crate::fsi_run::is_fsi(&case) {
        return Err(RunError::Case(CaseError::Invalid {
            file: Checkpoint::path(run_dir).display().to_string(),
            message: "`fdfsi adapt --at` needs the checkpoint of an FSI run (a case with a fluid mesh and a solid surface)".into(),
        }));
    }
    Ok(match build_mesh(&case, &options.case_dir)? {
        AnyMesh::D2(m) => write_adapt_report(&crate::fsi_run::adapted_at(&case, m, &options.case_dir, checkpoint, run_dir)?, out_dir)?,
        AnyMesh::D3(m) => write_adapt_report(&crate::fsi_run::adapted_at(&case, m, &options.case_dir, checkpoint, run_dir)?, out_dir)?,
    })
}

/// Runs a case; `log` receives one line per notable event.
pub fn run_case(case: &Case, options: &RunOptions, log: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let t0 = Instant::now();
    // The checks of `fdfsi check` (names, ranges, meshes, solid placement, probes), before
    // anything is written.
    let expected = crate::check::check(case, "case", &options.case_dir)?;
    if let Some(c) = &options.resume {
        if c.case != case.to_toml() {
            return Err(RunError::Case(CaseError::Invalid {
                file: Checkpoint::path(&options.out_dir).display().to_string(),
                message:
                    "the case differs from the one the checkpoint was written for; resume with the checkpoint's own case (`fdfsi run --resume DIR`)"
                        .into(),
            }));
        }
    }
    std::fs::create_dir_all(&options.out_dir).map_err(|source| OutputError::Io { path: options.out_dir.display().to_string(), source })?;
    write_atomic(&options.out_dir.join("case.toml"), case.to_toml().as_bytes())?;
    check_free_space(&options.out_dir, expected.output_bytes())?;
    // Three kinds of run: solid only, FSI, or flow (with a fixed solid, if any).
    let mut summary = if case.mesh.is_none() {
        crate::solid_run::run_solid(case, options, log)?
    } else if crate::fsi_run::is_fsi(case) {
        crate::fsi_run::run_fsi(case, options, log)?
    } else {
        let t = Instant::now();
        let mesh = fluid_mesh(case, &options.case_dir, log)?;
        let mesh_seconds = t.elapsed().as_secs_f64();
        let mut summary = match mesh {
            AnyMesh::D2(m) => run_flow::<2>(case, m, options, log)?,
            AnyMesh::D3(m) => run_flow::<3>(case, m, options, log)?,
        };
        summary.timings.mesh = mesh_seconds;
        summary
    };
    // A resumed run's summary carries the earlier parts' wall time in `total`.
    summary.timings.total += t0.elapsed().as_secs_f64();
    if case.time.is_some() && summary.steps > 0 {
        summary.timings_per_step = Some(summary.timings.scaled(1.0 / summary.steps as f64));
    }
    summary.peak_memory_mib = peak_resident_mib();
    let earlier = options.resume.as_ref().map_or(&[][..], |c| &c.builds);
    summary.provenance = Some(crate::provenance::Provenance::of_run(&case.to_toml(), earlier));
    let json = serde_json::to_string_pretty(&summary).expect("summary serialises");
    write_atomic(&options.out_dir.join("summary.json"), json.as_bytes())?;
    // The results are written: a failing plot is reported, not an error of the run.
    match crate::plot::plot_results(&options.out_dir) {
        Ok(files) if !files.is_empty() => log.log(&format!("plots: {} PNG files in {}", files.len(), options.out_dir.join("plots").display())),
        Ok(_) => {}
        Err(e) => log.log(&format!("warning: plots not made: {e}")),
    }
    Ok(summary)
}

/// Refuses to start when the file system of `out_dir` has less room than the run's expected
/// output (`fdfsi check`'s estimate) plus a margin of 10 % and 16 MB for checkpoints, pictures
/// and temporary files: a full disk is an error before the first step, not after an hour.
fn check_free_space(out_dir: &Path, expected: u64) -> Result<(), RunError> {
    let Ok(available) = fs4::available_space(out_dir) else {
        return Ok(()); // unknown (an unusual file system): do not block the run on a guess
    };
    let needed = expected.saturating_add(expected / 10).saturating_add(16_000_000);
    if available < needed {
        return Err(RunError::DiskFull {
            out_dir: out_dir.display().to_string(),
            needed: crate::check::human_bytes(needed),
            available: crate::check::human_bytes(available),
        });
    }
    Ok(())
}

/// A vector of compiled expressions, times a time function, as a field of position and time.
fn vector_fn<const D: usize>(exprs: Vec<Expr>, time: TimeFn) -> VectorFn<D> {
    Arc::new(move |x: &[f64; D], t: f64| {
        let s = time.eval(t);
        std::array::from_fn(|a| s * exprs[a].eval(x, t))
    })
}

fn compile_all(values: &[crate::case::Scalar]) -> Result<Vec<Expr>, CaseError> {
    values.iter().map(|v| Expr::compile(v).map_err(|message| CaseError::Invalid { file: "case".into(), message })).collect()
}

/// The flow problem a case describes on `mesh`; time-function tables are read relative to
/// `case_dir`.
pub fn flow_problem<const D: usize>(case: &Case, mesh: &Mesh<D>, case_dir: &Path) -> Result<FlowProblem<D>, RunError> {
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
        let time = match &b.time_function {
            Some(f) => TimeFn::load(f, case_dir)?,
            None => TimeFn::Constant,
        };
        match b.kind {
            BoundaryType::Velocity => {
                dirichlet.push(bc(all.clone(), vector_fn(compile_all(&b.value)?, time)));
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
                let f = vector_fn::<D>(compile_all(&b.value)?, time);
                traction.push(TractionBc { boundary: b.name.clone(), traction: Arc::new(move |x, _n, t| f(x, t)) });
                pressure_fixed = true;
            }
            BoundaryType::Pressure => {
                let p = compile_all(&b.value)?.remove(0);
                traction.push(TractionBc {
                    boundary: b.name.clone(),
                    traction: Arc::new(move |x: &[f64; D], n: &[f64; D], t| {
                        let pv = time.eval(t) * p.eval(x, t);
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
        Some(f) => Some(vector_fn::<D>(compile_all(f)?, TimeFn::Constant)),
        None => None,
    };
    let fluid = case.fluid.as_ref().ok_or_else(|| CaseError::Invalid { file: "case".into(), message: "the case has no [fluid] table".into() })?;
    Ok(FlowProblem {
        formulation: case.physics.formulation,
        params: FluidParams {
            viscosity: fluid.viscosity,
            density: fluid.density,
            inv_dt: 0.0,
            convection: case.physics.model == FlowModel::NavierStokes,
            viscous_form: fluid.viscous_form,
        },
        body_force,
        dirichlet,
        traction,
        pin_pressure: !pressure_fixed,
    })
}

fn run_flow<const D: usize>(case: &Case, mesh: Mesh<D>, options: &RunOptions, obs: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let part_start = Instant::now();
    let problem = flow_problem(case, &mesh, &options.case_dir)?;
    let t = Instant::now();
    let cells = mesh.num_cells();
    let disc = FlowDiscretization::build(mesh, case.physics.formulation)?;
    let discretize = t.elapsed().as_secs_f64();
    let nv = disc.layout.fields[0].num_dofs();
    let np = disc.layout.fields[1].num_dofs();
    obs.log(&format!("mesh: {cells} cells; dofs: velocity {nv}, pressure {np}, total {} (nnz {}); {:.2} s", nv + np, disc.pattern.nnz(), discretize));
    let mut lu = case.solver.linear_solver();
    let mut out = Outputs::new(case, options)?;
    let mut timings = Timings { discretize, ..Default::default() };
    let mut residual_norms = Vec::new();
    let mut newton_iterations = 0;
    let steps;
    let x = match &case.time {
        None => {
            let sol = solve_steady(&disc, &problem, &mut lu, &case.solver.newton)?;
            let rep = &sol.newton;
            for line in newton_lines(rep) {
                obs.log(&line);
            }
            timings.add_newton(rep);
            residual_norms.clone_from(&rep.residual_norms);
            newton_iterations = rep.iterations;
            out.record(&disc, &problem, &sol.x, &StepState::default(), 0, rep.iterations, *rep.residual_norms.last().unwrap_or(&0.0), true, obs)?;
            steps = 1;
            sol.x
        }
        Some(ts) => {
            let topts = TimeOptions { dt: ts.dt, t_end: ts.end, scheme: ts.scheme, max_cuts: ts.max_cuts };
            let total = crate::time::num_steps(ts.dt, ts.end);
            let (mut x, start) = match &options.resume {
                Some(c) => {
                    let (x, level) = c.flow_state(&options.out_dir, disc.num_dofs())?;
                    out.resume(c.step, c.time)?;
                    out.seconds = c.progress.timings.output;
                    newton_iterations = c.progress.newton_iterations;
                    residual_norms.clone_from(&c.progress.residual_norms);
                    timings = Timings { discretize, ..c.progress.timings.clone() };
                    obs.log(&format!("resuming after step {} (t = {:.6e}) from {}", c.step, c.time, Checkpoint::path(&options.out_dir).display()));
                    (x, level)
                }
                None => {
                    let x = vec![0.0; disc.num_dofs()];
                    out.record(&disc, &problem, &x, &StepState::default(), 0, 0, 0.0, true, obs)?;
                    (x, crate::time::TimeLevel::default())
                }
            };
            let mut failure: Option<RunError> = None;
            let step_t = Instant::now();
            let result = solve_unsteady_from(&disc, &problem, &mut x, start, &topts, &mut lu, &case.solver.newton, |rep, x, level| {
                for n in &rep.newton {
                    timings.add_newton(n);
                    log_newton(obs, n);
                }
                newton_iterations += rep.iterations();
                residual_norms.push(rep.residual());
                let cut = if rep.cuts > 0 { format!(" ({} cuts, dt = {:.3e})", rep.cuts, rep.dt) } else { String::new() };
                obs.log(&format!(
                    "step {}/{total} t = {:.6e}: newton {} |R| = {:.2e}{cut}; {:.2} s elapsed",
                    rep.step,
                    rep.time,
                    rep.iterations(),
                    rep.residual(),
                    step_t.elapsed().as_secs_f64()
                ));
                let state = StepState { time: rep.time, inv_dt: rep.inv_dt, u_star: Some(&rep.u_star) };
                let write = rep.step % ts.output_every == 0 || rep.step == total;
                let saved = out.record(&disc, &problem, x, &state, rep.step, rep.iterations(), rep.residual(), write, obs).and_then(|()| {
                    let clock = Instant::now();
                    timings.output = out.seconds;
                    let r = options.after_step(case, rep.step, rep.time, || {
                        (
                            RestartState::Flow { x: x.to_vec(), level: level.clone() },
                            Progress::after_step(newton_iterations, &residual_norms, &timings, part_start),
                        )
                    });
                    out.seconds += clock.elapsed().as_secs_f64();
                    r
                });
                if let Err(e) = saved {
                    let msg = e.to_string();
                    failure = Some(e);
                    return Err(msg);
                }
                obs.step(rep.step, total, rep.time);
                Ok(())
            });
            if let Some(e) = failure {
                return Err(e);
            }
            result?;
            steps = total;
            x
        }
    };
    if let Some(disc2) = (&disc as &dyn std::any::Any).downcast_ref::<FlowDiscretization<2>>() {
        let t = Instant::now();
        let png = options.out_dir.join("speed.png");
        crate::picture::write_speed_png(disc2, &x, &png, 1600)
            .map_err(|message| OutputError::Io { path: png.display().to_string(), source: std::io::Error::other(message) })?;
        out.seconds += t.elapsed().as_secs_f64();
    }
    for (name, v) in &out.last {
        obs.log(&format!("{name} = {v:.10e}"));
    }
    write_profiles(case, &disc, &problem, &x, &options.out_dir, obs)?;
    timings.output = out.seconds;
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
        steps,
        newton_iterations,
        residual_norms,
        symbolic_factorizations: crate::solve::linear::LinearSolver::symbolic_factorizations(&lu),
        quantities: out.last.into_iter().collect(),
        timings,
        timings_per_step: None,
        peak_memory_mib: None,
        provenance: None,
    })
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
        let pts = crate::quantities::profile(disc, problem, x, spec)?;
        write_atomic(&dir.join(format!("{}.csv", spec.name)), crate::quantities::profile_csv(&pts).as_bytes())?;
        obs.log(&format!("profile {}: {} points along '{}'", spec.name, pts.len(), spec.boundary));
    }
    Ok(())
}

impl Timings {
    /// Every phase times `factor`.
    pub fn scaled(&self, factor: f64) -> Timings {
        let t = self;
        Timings {
            mesh: t.mesh * factor,
            adapt: t.adapt * factor,
            discretize: t.discretize * factor,
            transfer: t.transfer * factor,
            assemble: t.assemble * factor,
            factorize: t.factorize * factor,
            solve: t.solve * factor,
            output: t.output * factor,
            total: t.total * factor,
        }
    }

    fn add_newton(&mut self, r: &crate::solve::newton::NewtonReport) {
        self.assemble += r.assemble_seconds;
        self.factorize += r.factorize_seconds;
        self.solve += r.solve_seconds;
    }
}

/// The per-step outputs of a run: quantities into `history.csv`, fields into the `.pvd` series.
struct Outputs {
    history: Option<History>,
    series: PvdSeries,
    out_dir: PathBuf,
    spec: crate::case::OutputSpec,
    last: Vec<(String, f64)>,
    seconds: f64,
}

impl Outputs {
    fn new(case: &Case, options: &RunOptions) -> Result<Self, RunError> {
        Ok(Outputs {
            history: None,
            series: PvdSeries::new(&options.out_dir, "solution"),
            out_dir: options.out_dir.clone(),
            spec: case.output.clone(),
            last: Vec::new(),
            seconds: 0.0,
        })
    }

    /// Continues the history and the field series of an interrupted run after `step` (time
    /// `time`), dropping what it wrote later.
    fn resume(&mut self, step: usize, time: f64) -> Result<(), RunError> {
        self.history = Some(History::resume(&self.out_dir.join("history.csv"), step)?);
        self.series = PvdSeries::resume(&self.out_dir, "solution", time)?;
        Ok(())
    }

    /// Evaluates the quantities, appends a history row and (when `write_fields`) the fields.
    #[allow(clippy::too_many_arguments)]
    fn record<const D: usize>(
        &mut self,
        disc: &FlowDiscretization<D>,
        problem: &FlowProblem<D>,
        x: &[f64],
        state: &StepState<'_>,
        step: usize,
        iterations: usize,
        residual: f64,
        write_fields: bool,
        _obs: &mut dyn RunObserver,
    ) -> Result<(), RunError> {
        let t = Instant::now();
        let values = evaluate_all(&self.spec, disc, problem, x, state)?;
        if self.history.is_none() {
            let names: Vec<String> = values.iter().map(|(n, _)| n.clone()).collect();
            self.history = Some(History::new(&self.out_dir.join("history.csv"), &names)?);
        }
        let history = self.history.as_mut().expect("created above");
        let vals: Vec<f64> = values.iter().map(|(_, v)| *v).collect();
        history.push(step, state.time, iterations, residual, &vals)?;
        if write_fields {
            self.series.add(state.time, "fluid", &fluid_grid(disc, x)?)?;
        }
        self.last = values;
        self.seconds += t.elapsed().as_secs_f64();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_whose_output_cannot_fit_is_refused_before_it_starts() {
        let dir = tempfile::tempdir().unwrap();
        check_free_space(dir.path(), 1_000_000).unwrap();
        let e = check_free_space(dir.path(), u64::MAX / 4).unwrap_err().to_string();
        assert!(e.contains("the run will write about") && e.contains("are free"), "{e}");
    }
}
