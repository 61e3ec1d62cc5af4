//! What every time-dependent run records, written once for all kinds: the log, a `history.csv`
//! row per step, the fields every `output_every` steps, checkpoints, and the numbers of
//! `summary.json`.
//!
//! [`march_and_record`] drives a [`Stepper`] with [`march`]; what differs between flow, FSI and
//! solid runs (their quantities, fields, restart state and dofs) is their [`RunOutputs`].

use super::{log_newton, RunError, RunObserver, RunOptions, RunSummary};
use crate::case::Case;
use crate::io::checkpoint::{Checkpoint, Progress, RestartState, CHECKPOINT_VERSION};
use crate::io::plot::Table;
use crate::io::History;
use crate::post::cycles::{cycles, CycleQuantities};
use crate::post::oscillation::last_period;
use crate::time::march::{march, MarchOptions, Schedule, StepDone, Stepper, Watch};
use crate::time::Timings;
use fdfsi_fem::vtk::PvdSeries;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// The outputs of one kind of run, read from its stepper `S`.
pub(crate) trait RunOutputs<S> {
    /// The quantities after a completed step: its `history.csv` row (and `summary.json`'s after
    /// the last step).
    fn quantities(&mut self, stepper: &S, done: &StepDone) -> Result<Vec<(String, f64)>, RunError>;
    /// Adds the state's fields after `done` to the series.
    fn write_fields(&mut self, stepper: &S, done: &StepDone, series: &mut PvdSeries) -> Result<(), RunError>;
    /// What a checkpoint saves of the state after `done`.
    fn restart(&self, stepper: &S, done: &StepDone) -> RestartState;
    /// Unknowns per block of the system (of the last step), without the total.
    fn dofs(&self, stepper: &S) -> Vec<(String, usize)>;
    /// The end of the step's log line (after the Newton summary), and detail lines.
    fn describe_step(&self, _stepper: &S, _done: &StepDone, _obs: &mut dyn RunObserver) -> String {
        String::new()
    }
    /// At the last step (before its checkpoint): profiles and pictures.
    fn finish(&mut self, _stepper: &S, _out_dir: &Path, _obs: &mut dyn RunObserver) -> Result<(), RunError> {
        Ok(())
    }
}

/// A run part's starting point: what a new run starts from, or what a checkpoint restores.
pub(crate) struct Start {
    /// When this part began (its setup included): its wall time is counted from here.
    pub part_start: Instant,
    /// The first step to take.
    pub first: usize,
    /// Phase times so far (of the earlier parts; `total` their wall time).
    pub timings: Timings,
    pub newton_iterations: usize,
    pub krylov_iterations: usize,
    pub residual_norms: Vec<f64>,
}

impl Start {
    /// The start of the run, or after the checkpoint of `options` (its history and field series
    /// are then cut back to its step by [`march_and_record`]), for a part that began at
    /// `part_start`.
    pub fn of(options: &RunOptions, obs: &mut dyn RunObserver, part_start: Instant) -> Self {
        match &options.resume {
            None => {
                Start { part_start, first: 1, timings: Timings::default(), newton_iterations: 0, krylov_iterations: 0, residual_norms: Vec::new() }
            }
            Some(c) => {
                obs.log(&format!("resuming after step {} (t = {:.6e}) from {}", c.step, c.time, Checkpoint::path(&options.out_dir).display()));
                let p = &c.progress;
                let (timings, residual_norms) = (p.timings.clone(), p.residual_norms.clone());
                Start {
                    part_start,
                    first: c.step + 1,
                    timings,
                    newton_iterations: p.newton_iterations,
                    krylov_iterations: p.krylov_iterations,
                    residual_norms,
                }
            }
        }
    }
}

/// The run's records, as the [`Watch`] of its march.
struct Recorder<'a, O> {
    outputs: O,
    obs: &'a mut dyn RunObserver,
    options: &'a RunOptions,
    case_toml: String,
    history: Option<History>,
    series: PvdSeries,
    output_every: usize,
    last: Vec<(String, f64)>,
    newton_iterations: usize,
    krylov_iterations: usize,
    residual_norms: Vec<f64>,
    part_start: Instant,
    /// Where the run's initial state came from (a run started from another's checkpoint), for
    /// its checkpoints.
    initial_state: Option<crate::io::provenance::InitialState>,
}

impl<O> Recorder<'_, O> {
    /// Logs the last step's quantities, `NAME = value` (the run's results).
    fn log_quantities(&mut self) {
        for (name, v) in &self.last {
            self.obs.log(&format!("{name} = {v:.10e}"));
        }
    }

    /// Evaluates the quantities after `done`, appends the history row and (when due) the fields.
    fn record<S>(&mut self, stepper: &S, done: &StepDone, fields: bool) -> Result<(), RunError>
    where
        O: RunOutputs<S>,
    {
        let values = self.outputs.quantities(stepper, done)?;
        if self.history.is_none() {
            let names: Vec<String> = values.iter().map(|(n, _)| n.clone()).collect();
            self.history = Some(History::new(&self.options.out_dir.join("history.csv"), &names)?);
        }
        let row: Vec<f64> = values.iter().map(|(_, v)| *v).collect();
        self.history.as_mut().expect("created above").push(
            done.step,
            done.time,
            (done.iterations(), done.krylov_iterations()),
            done.residual(),
            &row,
        )?;
        if fields {
            self.outputs.write_fields(stepper, done, &mut self.series)?;
        }
        self.last = values;
        Ok(())
    }
}

impl<S: Stepper, O: RunOutputs<S>> Watch<S> for Recorder<'_, O> {
    type Error = RunError;

    fn step_done(&mut self, stepper: &S, done: &StepDone, _timings: &Timings) -> Result<(), RunError> {
        for n in &done.newton {
            log_newton(self.obs, n);
        }
        let tail = self.outputs.describe_step(stepper, done, self.obs);
        self.newton_iterations += done.iterations();
        self.krylov_iterations += done.krylov_iterations();
        self.residual_norms.push(done.residual());
        let due = done.step.is_multiple_of(self.output_every) || done.step == done.total;
        self.record(stepper, done, due)?;
        let cut = if done.cuts > 0 { format!(" ({} cuts, dt = {:.3e})", done.cuts, done.dt) } else { String::new() };
        let krylov = match done.krylov_iterations() {
            0 => String::new(),
            k => format!(" (krylov {k})"),
        };
        self.obs.log(&format!(
            "step {}/{} t = {:.6e}: newton {}{krylov} |R| = {:.2e}{cut}{tail}; {:.2} s elapsed",
            done.step,
            done.total,
            done.time,
            done.iterations(),
            done.residual(),
            self.part_start.elapsed().as_secs_f64()
        ));
        if done.step == done.total {
            self.outputs.finish(stepper, &self.options.out_dir, self.obs)?;
        }
        Ok(())
    }

    fn step_end(&mut self, done: &StepDone) {
        self.obs.step(done.step, done.total, done.time);
    }

    fn step_cut(&mut self, step: usize, cuts: usize, from: f64, error: &S::Error) {
        self.obs.log(&format!("step {step}: {error}; from t = {from:.6e} on in sub-steps of 1/{} of the step", 1usize << cuts));
    }

    fn checkpoint(&mut self, stepper: &S, done: &StepDone, timings: &Timings) -> Result<(), RunError> {
        let options = self.options;
        let case_dir = std::path::absolute(&options.case_dir).unwrap_or_else(|_| options.case_dir.clone());
        let builds = crate::io::provenance::builds_so_far(options.resume.as_ref().map_or(&[], |c| &c.builds));
        let progress = Progress::after_step((self.newton_iterations, self.krylov_iterations), &self.residual_norms, timings, self.part_start);
        let state = self.outputs.restart(stepper, done);
        let c = Checkpoint {
            version: CHECKPOINT_VERSION,
            case: self.case_toml.clone(),
            case_dir,
            step: done.step,
            time: done.time,
            state,
            progress,
            builds,
            initial_state: self.initial_state.clone(),
        };
        Ok(c.write(&options.out_dir)?)
    }
}

/// What a run part measured, for its [`RunSummary`].
pub(crate) struct Recorded {
    pub steps: usize,
    pub newton_iterations: usize,
    pub krylov_iterations: usize,
    pub residual_norms: Vec<f64>,
    pub quantities: Vec<(String, f64)>,
    pub timings: Timings,
    pub dofs: Vec<(String, usize)>,
}

/// Marches `stepper` through `schedule` from `start` and records every step (see the module
/// documentation). With `record_start`, a new run also records its initial state as step 0.
#[allow(clippy::too_many_arguments)]
pub(crate) fn march_and_record<S, O>(
    case: &Case,
    options: &RunOptions,
    obs: &mut dyn RunObserver,
    stepper: &mut S,
    outputs: O,
    schedule: &Schedule,
    output_every: usize,
    start: Start,
    record_start: bool,
) -> Result<Recorded, RunError>
where
    S: Stepper,
    S::Error: Into<super::StepFailure>,
    O: RunOutputs<S>,
{
    let part_start = start.part_start;
    let (history, series) = match &options.resume {
        Some(c) => (Some(History::resume(&options.out_dir.join("history.csv"), c.step)?), PvdSeries::resume(&options.out_dir, "solution", c.time)?),
        None => (None, PvdSeries::new(&options.out_dir, "solution")),
    };
    let mut recorder = Recorder {
        outputs,
        obs,
        options,
        case_toml: case.to_toml(),
        history,
        series,
        output_every: output_every.max(1),
        last: Vec::new(),
        newton_iterations: start.newton_iterations,
        krylov_iterations: start.krylov_iterations,
        residual_norms: start.residual_norms,
        part_start,
        initial_state: options.initial_state(schedule.dt),
    };
    let mut timings = start.timings;
    if record_start && options.resume.is_none() {
        let clock = Instant::now();
        let done = StepDone { step: 0, total: schedule.num_steps(), time: 0.0, dt: 0.0, cuts: 0, newton: Vec::new(), phases: Timings::default() };
        recorder.record(stepper, &done, true)?;
        timings.output += clock.elapsed().as_secs_f64();
    }
    let march_options = MarchOptions { checkpoint_every: options.checkpoint_every, stop: options.stop.clone() };
    march(stepper, schedule, start.first, &march_options, &mut timings, &mut recorder).map_err(|e| RunError::from_march(e, &options.out_dir))?;
    let statistics = oscillations(case, &options.out_dir, recorder.obs)?;
    recorder.last.extend(statistics);
    recorder.last.extend(cycle_statistics(case, &options.out_dir)?);
    recorder.log_quantities();
    Ok(Recorded {
        steps: schedule.num_steps() - recorder.initial_state.as_ref().map_or(0, |i| i.steps_before),
        newton_iterations: recorder.newton_iterations,
        krylov_iterations: recorder.krylov_iterations,
        residual_norms: recorder.residual_norms,
        quantities: recorder.last,
        timings,
        dofs: recorder.outputs.dofs(stepper),
    })
}

/// The `[[output.oscillation]]` statistics ([`last_period`]) of the run's whole `history.csv`
/// (all parts of a resumed run): `QUANTITY_mean`, `_amplitude` and `_frequency`. A quantity
/// with less than one whole period after its `from` gets none, and a log line says so.
fn oscillations(case: &Case, out_dir: &Path, obs: &mut dyn RunObserver) -> Result<Vec<(String, f64)>, RunError> {
    let mut out = Vec::new();
    if case.output.oscillation.is_empty() {
        return Ok(out);
    }
    let table = Table::read(&out_dir.join("history.csv"))?;
    let column = |name: &str| table.column(name).ok_or_else(|| RunError::Unsupported(format!("oscillation: history.csv has no column '{name}'")));
    let t = column("time")?;
    for o in &case.output.oscillation {
        match last_period(&t, &column(&o.quantity)?, o.from) {
            Some(s) => {
                obs.log(&format!("oscillation of {}: the last of {} whole periods after t = {}", o.quantity, s.periods, o.from));
                out.extend(
                    [("mean", s.mean), ("amplitude", s.amplitude), ("frequency", s.frequency)].map(|(k, v)| (format!("{}_{k}", o.quantity), v)),
                );
            }
            None => obs.log(&format!(
                "oscillation of {}: no whole period after t = {} (or a non-finite value): no mean, amplitude or frequency",
                o.quantity, o.from
            )),
        }
    }
    Ok(out)
}

/// The `[output.cycles]` statistics ([`cycles`]) of the run's whole `history.csv`: for each
/// whole cycle `K`, `cycle_K_forward_volume`, `_backward_volume`, `_leak_volume`,
/// `_closing_time`, `_opening_time`, `_peak_QUANTITY`, `_forward_peak_QUANTITY` and
/// `_forward_mean_QUANTITY`.
fn cycle_statistics(case: &Case, out_dir: &Path) -> Result<Vec<(String, f64)>, RunError> {
    let Some(spec) = &case.output.cycles else { return Ok(Vec::new()) };
    let table = Table::read(&out_dir.join("history.csv"))?;
    let column = |name: &str| table.column(name).ok_or_else(|| RunError::Unsupported(format!("output.cycles: history.csv has no column '{name}'")));
    let (t, q) = (column("time")?, column(&spec.flux)?);
    let force = spec.contact_force.as_deref().map(column).transpose()?;
    let columns = |names: &[String]| names.iter().map(|p| column(p)).collect::<Result<Vec<_>, _>>();
    fn slices(columns: &[Vec<f64>]) -> Vec<&[f64]> {
        columns.iter().map(Vec::as_slice).collect()
    }
    let (peaks, forward_peaks, means) = (columns(&spec.peak)?, columns(&spec.forward_peak)?, columns(&spec.forward_mean)?);
    let (peak_refs, forward_peak_refs, mean_refs) = (slices(&peaks), slices(&forward_peaks), slices(&means));
    let quantities = CycleQuantities { peaks: &peak_refs, forward_peaks: &forward_peak_refs, forward_means: &mean_refs };
    let mut out = Vec::new();
    for c in cycles(&t, &q, force.as_deref(), &quantities, spec.period, spec.start) {
        let k = c.index;
        out.extend([
            (format!("cycle_{k}_forward_volume"), c.forward_volume),
            (format!("cycle_{k}_backward_volume"), c.backward_volume),
            (format!("cycle_{k}_leak_volume"), c.leak_volume),
            (format!("cycle_{k}_closing_time"), c.closing_time),
            (format!("cycle_{k}_opening_time"), c.opening_time),
        ]);
        for (kind, names, values) in [
            ("peak", &spec.peak, &c.peaks),
            ("forward_peak", &spec.forward_peak, &c.forward_peaks),
            ("forward_mean", &spec.forward_mean, &c.forward_means),
        ] {
            out.extend(names.iter().zip(values).map(|(name, v)| (format!("cycle_{k}_{kind}_{name}"), *v)));
        }
    }
    Ok(out)
}

/// Records the state of a solve without time steps (a steady flow) as step 0 `done` of a run of
/// one step, as [`march_and_record`] records a step: its `history.csv` row, its fields and the
/// final outputs. Returns the quantities.
pub(crate) fn record_once<S, O: RunOutputs<S>>(
    case: &Case,
    options: &RunOptions,
    obs: &mut dyn RunObserver,
    state: &S,
    outputs: O,
    done: &StepDone,
) -> Result<Vec<(String, f64)>, RunError> {
    let mut recorder = Recorder {
        outputs,
        obs,
        options,
        case_toml: case.to_toml(),
        history: None,
        series: PvdSeries::new(&options.out_dir, "solution"),
        output_every: 1,
        last: Vec::new(),
        newton_iterations: 0,
        krylov_iterations: 0,
        residual_norms: Vec::new(),
        part_start: Instant::now(),
        initial_state: None,
    };
    recorder.record(state, done, true)?;
    recorder.outputs.finish(state, &options.out_dir, recorder.obs)?;
    recorder.log_quantities();
    Ok(recorder.last)
}

impl Recorded {
    /// The summary of a run on `cells` cells of a `dim`-dimensional mesh whose solver did
    /// `symbolic_factorizations`; dofs get their `total`.
    pub fn summary(self, case: &Case, dim: usize, cells: usize, symbolic_factorizations: usize) -> RunSummary {
        let total: usize = self.dofs.iter().map(|(_, n)| n).sum();
        let mut dofs: BTreeMap<String, usize> = self.dofs.into_iter().collect();
        dofs.insert("total".into(), total);
        RunSummary {
            title: case.title.clone(),
            formulation: format!("{:?}", case.physics.formulation),
            dimension: dim,
            cells,
            dofs,
            steps: self.steps,
            newton_iterations: self.newton_iterations,
            krylov_iterations: self.krylov_iterations,
            residual_norms: self.residual_norms,
            symbolic_factorizations,
            quantities: self.quantities.into_iter().collect(),
            timings: self.timings,
            timings_per_step: None,
            peak_memory_mib: None,
            ranks: 1,
            provenance: None,
        }
    }
}
