//! The commands over the library: `fdfsi run` ([`run_case`]), `fdfsi check` ([`check`]) and
//! `fdfsi adapt` ([`adapt`]).
//!
//! A run checks its case (everything `fdfsi check` checks) before it writes anything, builds its
//! meshes and problems ([`crate::setup`]), and marches one of three kinds of stepper
//! ([`crate::time`]): flow ([`flow`]), FSI ([`fsi`]) or a solid alone ([`solid`]). What every
//! kind records (log, `history.csv`, fields, checkpoints, the numbers of `summary.json`) is
//! written once, in `record`. Each phase runs inside a named timer whose seconds go to
//! `summary.json`.

use crate::case::{Case, CaseError, RunKind};
use crate::discretize::flow::FlowError;
use crate::discretize::fsi::FsiError;
use crate::discretize::solid::SolidError;
use crate::io::checkpoint::{Checkpoint, CheckpointError};
use crate::io::provenance::InitialState;
use crate::io::{write_atomic, OutputError};
use crate::post::quantities::QuantityError;
use crate::setup::SetupError;
use crate::time::march::MarchError;
use crate::time::Timings;
use fdfsi_fem::vtk::VtkError;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;
use thiserror::Error;

pub mod adapt;
pub mod check;
pub mod export;
pub mod flow;
pub mod fsi;
mod record;
pub mod solid;

/// A run failure.
#[derive(Debug, Error)]
pub enum RunError {
    #[error(transparent)]
    Case(#[from] CaseError),
    #[error(transparent)]
    Setup(#[from] SetupError),
    #[error(transparent)]
    Flow(#[from] FlowError),
    #[error(transparent)]
    Output(#[from] OutputError),
    #[error(transparent)]
    Vtk(#[from] VtkError),
    #[error("probe '{name}' at {point:?} lies outside the fluid mesh")]
    ProbeOutside { name: String, point: Vec<f64> },
    #[error(transparent)]
    Solid(#[from] SolidError),
    #[error(transparent)]
    Fsi(#[from] FsiError),
    #[error("step {step} (t = {time:.6e}) failed after {cuts} time-step cuts: {source}")]
    StepFailed { step: usize, time: f64, cuts: usize, source: StepFailure },
    #[error("time step must be positive and end time after start, got dt = {dt}, end = {end}")]
    BadSchedule { dt: f64, end: f64 },
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error(transparent)]
    Plot(#[from] crate::io::plot::PlotError),
    #[error("{out_dir}: the run will write about {needed} but only {available} are free; free some space, choose another --out or write the fields less often (time.output_every)")]
    DiskFull { out_dir: String, needed: String, available: String },
    #[error("{0}")]
    Unsupported(String),
    #[error("--start-from {dir}: {message}")]
    StartFrom { dir: String, message: String },
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

/// Why a step of a run failed: the error of its kind of stepper.
#[derive(Debug, Error)]
pub enum StepFailure {
    #[error(transparent)]
    Flow(#[from] FlowError),
    #[error(transparent)]
    Fsi(#[from] FsiError),
    #[error(transparent)]
    Solid(#[from] SolidError),
}

impl RunError {
    /// The error of a run's march; an interruption names the folder to resume from.
    fn from_march<E: Into<StepFailure> + std::error::Error>(e: MarchError<E, RunError>, out_dir: &Path) -> Self {
        match e {
            MarchError::StepFailed { step, time, cuts, source } => RunError::StepFailed { step, time, cuts, source: source.into() },
            MarchError::Watch(e) => e,
            MarchError::Interrupted { step, time } => RunError::Interrupted { step, time, out_dir: out_dir.display().to_string() },
            MarchError::BadSchedule { dt, end } => RunError::BadSchedule { dt, end },
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
pub(crate) fn newton_lines(report: &crate::solve::newton::NewtonReport) -> impl Iterator<Item = String> + '_ {
    report.residual_norms.iter().enumerate().map(|(k, r)| {
        let du = report.update_norms.get(k).map(|d| format!(", |du| = {d:.3e}")).unwrap_or_default();
        let krylov = report.krylov_iterations.get(k).filter(|&&n| n > 0).map(|n| format!(", krylov {n}")).unwrap_or_default();
        format!("newton {k}: |R| = {r:.3e}{du}{krylov}")
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
    /// Start a new run from another run's checkpoint instead of from rest (FSI runs).
    pub start_from: Option<StartFrom>,
    /// When set (e.g. by a Ctrl-C handler), the run stops after the current step, writes a
    /// checkpoint and returns [`RunError::Interrupted`].
    pub stop: Option<Arc<AtomicBool>>,
    /// The number of MPI ranks running this case alike (`fdfsi run` under `mpirun`, the linear
    /// solves shared through PETSc); 0 or 1: one. Recorded in `summary.json` (`ranks`).
    pub ranks: usize,
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

    /// Where the run's initial state came from, for a run whose steps are `dt` long: the run
    /// started from (see [`StartFrom`]), or, for a resumed run, what its checkpoint recorded.
    pub fn initial_state(&self, dt: f64) -> Option<InitialState> {
        match (&self.start_from, &self.resume) {
            (Some(s), _) => Some(s.origin(dt)),
            (None, Some(c)) => c.initial_state.clone(),
            (None, None) => None,
        }
    }
}

/// The time steps of a case's `[time]` table.
pub(crate) fn schedule_of(ts: &crate::case::TimeSpec) -> crate::time::Schedule {
    crate::time::Schedule { dt: ts.dt, end: ts.end, max_cuts: ts.max_cuts }
}

/// Another run's checkpoint as a new run's initial state (`fdfsi run CASE --start-from DIR`):
/// the new run begins at the checkpoint's time `t_k` from its state, with its own case. The case
/// may differ in its fluid mesh (the fluid velocity is transferred to the new mesh, as from step
/// to step), its time step (which must divide `t_k`; with BDF2 the first step uses the
/// variable-step formula where the checkpoint holds the level before, an Euler step where not),
/// its end, outputs and solver; the solid mesh must be the same. The rest of the case (physics,
/// materials, boundary values) is not compared: a run that changes it starts from a state of
/// another problem, on purpose. It serves mesh and time-step studies of periodic flows, whose
/// finer runs need not repeat the transient from rest. The new run's history starts after `t_k`
/// and it writes into another folder than the one it starts from; `summary.json`'s provenance
/// names the run it started from.
#[derive(Clone, Debug)]
pub struct StartFrom {
    /// The other run's output folder.
    pub dir: PathBuf,
    pub checkpoint: Checkpoint,
}

impl StartFrom {
    /// The checkpoint of the run in `dir` (or of the file `dir/checkpoint.json` named itself).
    pub fn read(dir: impl Into<PathBuf>) -> Result<Self, RunError> {
        let mut dir: PathBuf = dir.into();
        if dir.file_name().is_some_and(|n| n == crate::io::checkpoint::CHECKPOINT_FILE) && dir.is_file() {
            dir = dir.parent().map(Path::to_path_buf).unwrap_or_default();
        }
        let dir = std::path::absolute(&dir).unwrap_or(dir);
        let checkpoint = Checkpoint::read(&dir).map_err(|e| StartFrom::error_in(&dir, e.to_string()))?;
        Ok(StartFrom { dir, checkpoint })
    }

    /// The error `message` about the run started from `dir`.
    fn error_in(dir: &Path, message: String) -> RunError {
        RunError::StartFrom { dir: dir.display().to_string(), message }
    }

    /// The error `message` about this run.
    pub fn error(&self, message: String) -> RunError {
        StartFrom::error_in(&self.dir, message)
    }

    /// The checkpoint's case (as the other run used it).
    pub fn case(&self) -> Result<Case, RunError> {
        Case::from_toml_str(&self.checkpoint.case, &Checkpoint::path(&self.dir).display().to_string()).map_err(|e| self.error(e.to_string()))
    }

    /// What the provenance of a new run with steps `dt` long records of it.
    pub fn origin(&self, dt: f64) -> InitialState {
        let c = &self.checkpoint;
        InitialState {
            run: self.dir.display().to_string(),
            step: c.step,
            time: c.time,
            steps_before: self.steps_before(dt),
            case_sha256: crate::io::provenance::sha256_hex(c.case.as_bytes()),
            builds: c.builds.clone(),
        }
    }

    /// The steps of `dt` to the checkpoint's time, rounded (a whole number for a run that passed
    /// [`StartFrom::check`]).
    pub fn steps_before(&self, dt: f64) -> usize {
        (self.checkpoint.time / dt).round() as usize
    }

    /// Checks that a run with `schedule` writing into `out_dir` can start from it: another
    /// folder, a whole number of steps (to 1e-6 of a step) to the checkpoint's time, and a step
    /// left to take. Returns the number of steps before the run's first.
    pub fn check(&self, schedule: &crate::time::Schedule, out_dir: &Path) -> Result<usize, RunError> {
        let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        };
        if same(&self.dir, out_dir) {
            return Err(self.error(format!("the run would write into the folder it starts from ({}); choose another --out", out_dir.display())));
        }
        let (t, k) = (self.checkpoint.time, self.steps_before(schedule.dt));
        if (t / schedule.dt - k as f64).abs() > 1e-6 {
            return Err(self.error(format!("its time t = {t} is not a whole number of steps dt = {}: choose a dt that divides it", schedule.dt)));
        }
        if k >= schedule.num_steps() {
            return Err(self.error(format!("its time t = {t} leaves no step of dt = {} before the case's end = {}", schedule.dt, schedule.end)));
        }
        Ok(k)
    }
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
    /// Krylov iterations of all linear solves (0 with the direct solver).
    pub krylov_iterations: usize,
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
    /// The MPI ranks the run ran on ([`RunOptions::ranks`]; 1 without `mpirun`); the other
    /// numbers, `peak_memory_mib` included, are rank 0's.
    pub ranks: usize,
    /// The code and case behind the results ([`crate::io::provenance`]); filled by [`run_case`].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub provenance: Option<crate::io::provenance::Provenance>,
}

/// Peak resident memory (`VmHWM` of `/proc/self/status`) of this process in MiB; `None` where
/// the system has no such file (not Linux).
pub fn peak_resident_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kib: f64 = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?.trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kib / 1024.0)
}

/// Parses and validates a case and checks everything that needs no solve (see
/// [`crate::run::check`]): the mesh can be built and names the boundaries the case uses, the tables
/// can be read, the solid and the probes lie in the fluid. Returns a description of the problem
/// and a summary: dofs per field, the number of steps, an estimate of the output size
/// (`fdfsi check`).
pub fn check_case(case: &Case, file: &str, case_dir: &Path) -> Result<String, RunError> {
    Ok(check::check(case, file, case_dir)?.to_string())
}

/// Runs a case; `log` receives one line per notable event.
pub fn run_case(case: &Case, options: &RunOptions, log: &mut dyn RunObserver) -> Result<RunSummary, RunError> {
    let t0 = Instant::now();
    // The checks of `fdfsi check` (names, ranges, meshes, solid placement, probes), before
    // anything is written.
    let expected = check::check(case, "case", &options.case_dir)?;
    if let Some(from) = &options.start_from {
        if options.resume.is_some() || case.kind() != RunKind::Fsi {
            let what = if options.resume.is_some() { "a resumed run" } else { "this case: only FSI runs start from another run's state" };
            return Err(RunError::Unsupported(format!("--start-from is not for {what}")));
        }
        if let Some(ts) = &case.time {
            from.check(&schedule_of(ts), &options.out_dir)?;
        }
    }
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
    let mut summary = match case.kind() {
        RunKind::Solid => solid::run_solid(case, options, log)?,
        RunKind::Fsi => fsi::run_fsi(case, options, log)?,
        RunKind::Flow => flow::run_flow(case, options, log)?,
    };
    // A resumed run's summary carries the earlier parts' wall time in `total`.
    summary.timings.total += t0.elapsed().as_secs_f64();
    if case.time.is_some() && summary.steps > 0 {
        summary.timings_per_step = Some(summary.timings.scaled(1.0 / summary.steps as f64));
    }
    summary.peak_memory_mib = peak_resident_mib();
    summary.ranks = options.ranks.max(1);
    let earlier = options.resume.as_ref().map_or(&[][..], |c| &c.builds);
    let dt = case.time.as_ref().map_or(1.0, |t| t.dt);
    summary.provenance = Some(crate::io::provenance::Provenance::of_run(&case.to_toml(), earlier, options.initial_state(dt)));
    let json = serde_json::to_string_pretty(&summary).expect("summary serialises");
    write_atomic(&options.out_dir.join("summary.json"), json.as_bytes())?;
    // The results are written: a failing plot is reported, not an error of the run.
    match crate::io::plot::plot_results(&options.out_dir) {
        Ok(files) if !files.is_empty() => log.log(&format!("plots: {} PNG files in {}", files.len(), options.out_dir.join("plots").display())),
        Ok(_) => {}
        Err(e) => log.log(&format!("warning: plots not made: {e}")),
    }
    if case.time.is_some() && case.output.animation != Some(false) {
        match crate::io::animation::animate_run(&options.out_dir) {
            Ok(Some(a)) => {
                log.log(&format!("animation: {} frames in {}", a.frames, a.gif.display()));
                if let Some(solid) = a.solid_gif {
                    log.log(&format!("the solid seen along the flow: {}", solid.display()));
                }
            }
            Ok(None) => {}
            Err(e) => log.log(&format!("warning: animation not made: {e}")),
        }
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
            needed: crate::run::check::human_bytes(needed),
            available: crate::run::check::human_bytes(available),
        });
    }
    Ok(())
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
