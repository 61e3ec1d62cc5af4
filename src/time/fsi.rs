//! FSI runs stepped in time: [`FsiStepper`] takes the monolithic step of
//! [`crate::discretize::fsi::step_with`] (adapt, discretise, transfer, Newton, move the solid) per
//! (sub)step, by implicit Euler or BDF2 (Euler at the start, in the sub-steps of a cut step and
//! the step after it).

use super::march::{Advance, Stepper};
use super::{TimeScheme, Timings};
use crate::discretize::fsi::{step_with, FsiError, FsiModel, FsiState, FsiStep};
use crate::solve::linear::LinearSolver;
use crate::solve::newton::NewtonOptions;

/// A coupled fluid and solid, advanced step by step.
pub struct FsiStepper<'a, const D: usize> {
    pub model: &'a FsiModel<D>,
    pub solver: &'a mut dyn LinearSolver,
    pub newton: NewtonOptions,
    pub scheme: TimeScheme,
    /// The state at the end of the last (sub)step.
    pub state: FsiState<D>,
    /// The last (sub)step: its discretisation, solution and report (`None` before the first).
    pub last: Option<FsiStep<D>>,
}

impl<'a, const D: usize> FsiStepper<'a, D> {
    pub fn new(model: &'a FsiModel<D>, solver: &'a mut dyn LinearSolver, newton: NewtonOptions, scheme: TimeScheme, state: FsiState<D>) -> Self {
        FsiStepper { model, solver, newton, scheme, state, last: None }
    }
}

impl<const D: usize> Stepper for FsiStepper<'_, D> {
    type Error = FsiError;

    fn advance(&mut self, t0: f64, t1: f64, cut: bool) -> Result<Advance, FsiError> {
        self.state.time = t0;
        // The last step's discretisation is not kept beside the new one.
        self.last = None;
        // A cut step's sub-steps are Euler steps, and keep no t_{n-1}: the step after is Euler too.
        let scheme = if cut { TimeScheme::Euler } else { self.scheme };
        let (mut next, st) = step_with(self.model, &self.state, t1 - t0, scheme, self.solver, &self.newton)?;
        next.time = t1;
        let s = &st.report.seconds;
        let phases = Timings { adapt: s.adapt, discretize: s.build, transfer: s.transfer, ..Default::default() };
        let newton = st.report.newton.clone();
        self.state = next;
        self.last = Some(st);
        Ok(Advance { newton, phases })
    }
}
