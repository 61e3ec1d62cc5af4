//! The one time loop: [`march`] advances a [`Stepper`] (a flow, FSI or solid run) from step to
//! step and owns what every kind of run shares.
//!
//! - The schedule: step `k` ends at `t_k = min(k dt, end)`, whether or not the run was resumed,
//!   so a resumed run repeats the arithmetic of an uninterrupted one.
//! - Step cuts: where a step fails, it goes on from there in halves, and where a half fails, in
//!   quarters, and so on, down to `dt / 2^max_cuts`; the sub-steps done before a failing one
//!   stand (a failed (sub)step leaves the state at its start), and the rest of the step keeps the
//!   shortest length reached. Sub-steps are marked as such (multistep schemes take an Euler step
//!   there); a sub-step of `dt / 2^max_cuts` that fails is [`MarchError::StepFailed`], naming the
//!   step and its time.
//! - The Ctrl-C stop and checkpoints: after a step, [`Watch::checkpoint`] is called every
//!   `checkpoint_every` steps and when a stop was requested; a requested stop then ends the march
//!   with [`MarchError::Interrupted`].
//! - Phase timers: the phases a stepper reports per step (assembly, factorisation and solve from
//!   Newton, adaptation, discretisation and transfer), and the time its watch takes (output), are
//!   summed into [`Timings`].
//!
//! What a step means and what is written after it belong to the stepper and the [`Watch`].

use super::Timings;
use crate::solve::newton::NewtonReport;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;
use thiserror::Error;

/// What one solved (sub)step reports.
#[derive(Clone, Debug, Default)]
pub struct Advance {
    /// The Newton solve of the (sub)step.
    pub newton: NewtonReport,
    /// Time of the phases besides Newton's (adapt, discretize, transfer); the Newton phases are
    /// taken from `newton`.
    pub phases: Timings,
}

/// A kind of run, advanced one (sub)step at a time by [`march`].
pub trait Stepper {
    /// Why a (sub)step failed.
    type Error: std::error::Error + 'static;

    /// Solves the (sub)step from `t0` to `t1` from the current state and makes its solution the
    /// current state. `cut` marks the sub-steps of a cut step. After an `Err` the state is that
    /// at `t0` again (the step cuts go on from it).
    fn advance(&mut self, t0: f64, t1: f64, cut: bool) -> Result<Advance, Self::Error>;
}

/// The steps of a march: size `dt` up to `end`, and how often a failing step may be cut.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schedule {
    pub dt: f64,
    pub end: f64,
    /// A failing (sub)step is halved, down to sub-steps of `dt / 2^max_cuts`.
    pub max_cuts: usize,
}

impl Schedule {
    /// Number of steps to reach `end` (the last one may be shorter).
    pub fn num_steps(&self) -> usize {
        num_steps(self.dt, self.end)
    }

    /// The time at the end of step `k`: `min(k dt, end)`.
    pub fn time(&self, k: usize) -> f64 {
        (k as f64 * self.dt).min(self.end)
    }
}

/// Number of steps of size `dt` to reach `t_end` (the last one may be shorter).
pub fn num_steps(dt: f64, t_end: f64) -> usize {
    (t_end / dt - 1e-9).ceil() as usize
}

/// A completed step, as the [`Watch`] sees it.
#[derive(Clone, Debug)]
pub struct StepDone {
    /// Step number (1-based, counted from the start of the run).
    pub step: usize,
    /// Number of steps of the run.
    pub total: usize,
    /// Time at the end of the step.
    pub time: f64,
    /// Size of the step's last (sub)step, its shortest.
    pub dt: f64,
    /// How often the step was halved (0: done whole; its last sub-steps are `1 / 2^cuts` of it).
    pub cuts: usize,
    /// The Newton solves of its (sub)steps.
    pub newton: Vec<NewtonReport>,
    /// Its phase times (summed over the sub-steps; those of the attempts that failed in
    /// `failed_attempts`).
    pub phases: Timings,
}

impl StepDone {
    /// Newton iterations of the step, summed over its sub-steps.
    pub fn iterations(&self) -> usize {
        self.newton.iter().map(|r| r.iterations).sum()
    }

    /// Krylov iterations of the step's linear solves (0 with a direct solver).
    pub fn krylov_iterations(&self) -> usize {
        self.newton.iter().flat_map(|r| &r.krylov_iterations).sum()
    }

    /// The final residual norm of the step.
    pub fn residual(&self) -> f64 {
        self.newton.last().and_then(|r| r.residual_norms.last().copied()).unwrap_or(0.0)
    }
}

/// What [`march`] reports to after each step: log, `history.csv`, fields, checkpoints.
pub trait Watch<S: Stepper> {
    /// Why writing the results of a step failed.
    type Error: std::error::Error + 'static;

    /// Called after every completed step, with the stepper at the step's end.
    fn step_done(&mut self, stepper: &S, done: &StepDone, timings: &Timings) -> Result<(), Self::Error>;

    /// Saves a restart point after `done` (after [`Watch::step_done`]); `timings` are the run's
    /// phase times so far (output included).
    fn checkpoint(&mut self, stepper: &S, done: &StepDone, timings: &Timings) -> Result<(), Self::Error>;

    /// Called last for a step the march goes on from (not for one it stops after): progress.
    fn step_end(&mut self, _done: &StepDone) {}

    /// A (sub)step of step `step` from time `from` failed with `error`; the step goes on from
    /// there in sub-steps of `1 / 2^cuts` of it.
    fn step_cut(&mut self, _step: usize, _cuts: usize, _from: f64, _error: &S::Error) {}
}

/// Checkpoints and the stop request of a march.
#[derive(Clone, Debug, Default)]
pub struct MarchOptions {
    /// Call [`Watch::checkpoint`] after every this many steps.
    pub checkpoint_every: Option<usize>,
    /// When set (e.g. by a Ctrl-C handler), the march stops after the current step, with a
    /// checkpoint.
    pub stop: Option<Arc<AtomicBool>>,
}

impl MarchOptions {
    fn stop_requested(&self) -> bool {
        self.stop.as_ref().is_some_and(|s| s.load(Ordering::SeqCst))
    }
}

/// Why a march ended early.
#[derive(Debug, Error)]
pub enum MarchError<E: std::error::Error + 'static, W: std::error::Error + 'static> {
    #[error("step {step} (t = {time:.6e}) failed after {cuts} time-step cuts: {source}")]
    StepFailed {
        step: usize,
        time: f64,
        cuts: usize,
        #[source]
        source: E,
    },
    #[error(transparent)]
    Watch(W),
    #[error("stopped after step {step} (t = {time:.6e})")]
    Interrupted { step: usize, time: f64 },
    #[error("time step must be positive and end time after start, got dt = {dt}, end = {end}")]
    BadSchedule { dt: f64, end: f64 },
}

/// Advances `stepper` from the end of step `first - 1` (time `schedule.time(first - 1)`; `first =
/// 1` for a new run) to the end of the schedule (see the module documentation). `timings` holds
/// the phase times so far and receives each step's.
pub fn march<S: Stepper, W: Watch<S>>(
    stepper: &mut S,
    schedule: &Schedule,
    first: usize,
    options: &MarchOptions,
    timings: &mut Timings,
    watch: &mut W,
) -> Result<(), MarchError<S::Error, W::Error>> {
    if !(schedule.dt > 0.0 && schedule.end > 0.0) {
        return Err(MarchError::BadSchedule { dt: schedule.dt, end: schedule.end });
    }
    let total = schedule.num_steps();
    for step in first.max(1)..=total {
        let (t0, t1) = (schedule.time(step - 1), schedule.time(step));
        let done = advance_step(stepper, step, total, t0, t1, schedule.max_cuts, watch)?;
        timings.add(&done.phases);
        let clock = Instant::now();
        watch.step_done(stepper, &done, timings).map_err(MarchError::Watch)?;
        timings.output += clock.elapsed().as_secs_f64();
        let stop = options.stop_requested();
        if stop || options.checkpoint_every.is_some_and(|n| n > 0 && step % n == 0) {
            let clock = Instant::now();
            watch.checkpoint(stepper, &done, timings).map_err(MarchError::Watch)?;
            timings.output += clock.elapsed().as_secs_f64();
        }
        if stop {
            return Err(MarchError::Interrupted { step, time: t1 });
        }
        watch.step_end(&done);
    }
    Ok(())
}

/// Step `step` from `t0` to `t1`: whole, or, from where a (sub)step fails, in sub-steps half as
/// long, down to `(t1 - t0) / 2^max_cuts`. A failed (sub)step leaves the state at its start, so
/// the sub-steps done before it stand; the rest of the step keeps the shortest length reached
/// (a step hard all along fails once per halving, `max_cuts` times at most).
fn advance_step<S: Stepper, W: Watch<S>>(
    stepper: &mut S,
    step: usize,
    total: usize,
    t0: f64,
    t1: f64,
    max_cuts: usize,
    watch: &mut W,
) -> Result<StepDone, MarchError<S::Error, W::Error>> {
    let mut done = StepDone { step, total, time: t1, dt: t1 - t0, cuts: 0, newton: Vec::new(), phases: Timings::default() };
    // Sub-step `k` of `2^cuts` runs from `at(k)` to `at(k + 1)`.
    let (mut k, mut cuts) = (0usize, 0usize);
    let at = |k: usize, cuts: usize| if k == 1 << cuts { t1 } else { t0 + k as f64 * (t1 - t0) / (1usize << cuts) as f64 };
    while k < 1 << cuts {
        let (a, b) = (at(k, cuts), at(k + 1, cuts));
        let clock = Instant::now();
        match stepper.advance(a, b, cuts > 0) {
            Ok(adv) => {
                (done.dt, done.cuts) = (b - a, cuts);
                done.record(adv);
                k += 1;
            }
            Err(source) if cuts == max_cuts => return Err(MarchError::StepFailed { step, time: t1, cuts, source }),
            Err(e) => {
                done.phases.failed_attempts += clock.elapsed().as_secs_f64();
                cuts += 1;
                k *= 2;
                watch.step_cut(step, cuts, a, &e);
            }
        }
    }
    Ok(done)
}

impl StepDone {
    fn record(&mut self, a: Advance) {
        self.phases.add(&a.phases);
        self.phases.add_newton(&a.newton);
        self.newton.push(a.newton);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stepper whose (sub)steps fail while longer than `longest` and across `hard` (a valve
    /// closing, say); it records the (sub)steps done and whether they were marked as cut.
    struct Closing {
        hard: f64,
        longest: f64,
        done: Vec<(f64, f64, bool)>,
    }

    #[derive(Debug, Error)]
    #[error("too long across the hard point")]
    struct TooLong;

    impl Stepper for Closing {
        type Error = TooLong;
        fn advance(&mut self, t0: f64, t1: f64, cut: bool) -> Result<Advance, TooLong> {
            if t1 - t0 > self.longest && t0 <= self.hard && self.hard < t1 {
                return Err(TooLong);
            }
            self.done.push((t0, t1, cut));
            Ok(Advance::default())
        }
    }

    #[derive(Default)]
    struct Cuts(Vec<(usize, usize, f64)>);

    impl Watch<Closing> for Cuts {
        type Error = TooLong;
        fn step_done(&mut self, _: &Closing, _: &StepDone, _: &Timings) -> Result<(), TooLong> {
            Ok(())
        }
        fn checkpoint(&mut self, _: &Closing, _: &StepDone, _: &Timings) -> Result<(), TooLong> {
            Ok(())
        }
        fn step_cut(&mut self, step: usize, cuts: usize, from: f64, _: &TooLong) {
            self.0.push((step, cuts, from));
        }
    }

    #[test]
    fn a_failing_step_goes_on_in_shorter_sub_steps_from_where_it_failed() {
        let mut s = Closing { hard: 0.6, longest: 0.2, done: Vec::new() };
        let mut cuts = Cuts::default();
        let done = advance_step(&mut s, 1, 1, 0.0, 1.0, 4, &mut cuts).unwrap();
        // [0, 1] fails; [0, 1/2] passes; [1/2, 1] and [1/2, 3/4] fail; eighths from 1/2 on.
        let expected = [(0.0, 0.5, true), (0.5, 0.625, true), (0.625, 0.75, true), (0.75, 0.875, true), (0.875, 1.0, true)];
        assert_eq!(s.done, expected);
        assert_eq!(cuts.0, [(1, 1, 0.0), (1, 2, 0.5), (1, 3, 0.5)]);
        assert_eq!((done.cuts, done.dt, done.newton.len()), (3, 0.125, 5));
        // A step that passes whole is not marked as cut.
        let mut s = Closing { hard: 2.0, ..s };
        s.done.clear();
        let done = advance_step(&mut s, 1, 1, 0.0, 1.0, 4, &mut Cuts::default()).unwrap();
        assert_eq!((s.done.as_slice(), done.cuts), (&[(0.0, 1.0, false)][..], 0));
        // Two cuts allowed: the quarter across the hard point fails, and with it the step.
        let mut s = Closing { hard: 0.6, ..s };
        let err = advance_step(&mut s, 7, 9, 0.0, 1.0, 2, &mut Cuts::default()).unwrap_err();
        assert!(matches!(err, MarchError::StepFailed { step: 7, cuts: 2, .. }), "{err}");
    }
}
