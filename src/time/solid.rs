//! A solid alone, loaded quasi-statically: [`QuasiStaticStepper`] takes one load increment per
//! step of [`super::march::march`], whose "time" is the load factor (0 to 1).

use super::march::{Advance, Stepper};
use super::Timings;
use crate::discretize::solid::{LoadState, SolidDiscretization, SolidError, SolidProblem};
use crate::solve::linear::LinearSolver;
use crate::solve::newton::NewtonOptions;

/// Quasi-static load stepping, one increment per step (boundary values times the load factor).
pub struct QuasiStaticStepper<'a, const D: usize> {
    pub disc: &'a SolidDiscretization<D>,
    pub problem: &'a SolidProblem<D>,
    pub solver: &'a mut dyn LinearSolver,
    pub newton: NewtonOptions,
    /// The state after the last converged increment.
    pub state: LoadState,
    marked: Option<LoadState>,
}

impl<'a, const D: usize> QuasiStaticStepper<'a, D> {
    pub fn new(
        disc: &'a SolidDiscretization<D>,
        problem: &'a SolidProblem<D>,
        solver: &'a mut dyn LinearSolver,
        newton: NewtonOptions,
        state: LoadState,
    ) -> Self {
        QuasiStaticStepper { disc, problem, solver, newton, state, marked: None }
    }
}

impl<const D: usize> Stepper for QuasiStaticStepper<'_, D> {
    type Error = SolidError;

    fn advance(&mut self, l0: f64, l1: f64, _cut: bool) -> Result<Advance, SolidError> {
        self.state.load = l0;
        let newton = self.disc.solve_increment(self.problem, &mut self.state, l1, true, self.solver, &self.newton)?;
        Ok(Advance { newton, phases: Timings::default() })
    }

    fn mark(&mut self) {
        self.marked = Some(self.state.clone());
    }

    fn rewind(&mut self) {
        if let Some(m) = &self.marked {
            self.state = m.clone();
        }
    }
}
