//! A solid alone: loaded quasi-statically, [`QuasiStaticStepper`] takes one load increment per
//! step of [`super::march::march`], whose "time" is the load factor (0 to 1); with inertia,
//! [`DynamicStepper`] takes time steps of `rho_0 u'' = div P + b` (implicit Euler or BDF2).

use super::march::{Advance, Stepper};
use super::{step_history, step_ratio, TimeScheme, Timings};
use crate::discretize::solid::{solve_dynamic_step, InertiaHistory, LoadState, SolidDiscretization, SolidError, SolidProblem};
use crate::solve::linear::LinearSolver;
use crate::solve::newton::NewtonOptions;
use serde::{Deserialize, Serialize};

/// Quasi-static load stepping, one increment per step (boundary values times the load factor).
pub struct QuasiStaticStepper<'a, const D: usize> {
    pub disc: &'a SolidDiscretization<D>,
    pub problem: &'a SolidProblem<D>,
    pub solver: &'a mut dyn LinearSolver,
    pub newton: NewtonOptions,
    /// The state after the last converged increment.
    pub state: LoadState,
}

impl<'a, const D: usize> QuasiStaticStepper<'a, D> {
    pub fn new(
        disc: &'a SolidDiscretization<D>,
        problem: &'a SolidProblem<D>,
        solver: &'a mut dyn LinearSolver,
        newton: NewtonOptions,
        state: LoadState,
    ) -> Self {
        QuasiStaticStepper { disc, problem, solver, newton, state }
    }
}

impl<const D: usize> Stepper for QuasiStaticStepper<'_, D> {
    type Error = SolidError;

    fn advance(&mut self, l0: f64, l1: f64, _cut: bool) -> Result<Advance, SolidError> {
        self.state.load = l0;
        let newton = self.disc.solve_increment(self.problem, &mut self.state, l1, true, self.solver, &self.newton)?;
        Ok(Advance { newton, phases: Timings::default() })
    }
}

/// Where a dynamic solid run stands after a completed step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DynamicState {
    /// Total displacement from the reference configuration and the pressure (layout numbering).
    pub x: Vec<f64>,
    /// Velocity on the displacement unknowns (zero on the pressure unknowns).
    pub v: Vec<f64>,
    /// `(x, v)` one step back, when the next step may use BDF2 (`None` at the start and after a
    /// cut step).
    pub previous: Option<(Vec<f64>, Vec<f64>)>,
    /// The size of the step that reached this state (0 at the start): BDF2's coefficients
    /// depend on the next step's ratio to it ([`crate::time::step_ratio`]).
    #[serde(default)]
    pub dt: f64,
}

impl DynamicState {
    /// At rest in the reference configuration.
    pub fn at_rest(num_dofs: usize) -> Self {
        DynamicState { x: vec![0.0; num_dofs], v: vec![0.0; num_dofs], previous: None, dt: 0.0 }
    }
}

/// Time steps of a solid with inertia (total Lagrangian): `rho_0 a_{n+1} + R(u_{n+1}) = 0` with
/// `v` and `a` by `scheme` (see [`InertiaHistory`]). The solid's first-order form `u' = v`,
/// `rho_0 v' = div P + b` is discretised by the same formula in both equations, so BDF2 is
/// second order for both, and L-stable: it damps the unresolved high frequencies of a stiff
/// solid, while a resolved oscillation of frequency `omega` loses only a factor
/// `1 - (omega dt)^4 / 4` of its amplitude per step (FSI3's 5.3 Hz at dt = 1e-3: 6e-5 a
/// period). Like the fluid's, BDF2 starts with an Euler step, takes Euler steps in the sub-steps
/// of a cut step and the step after it, and the variable-step formula for a step of another
/// length than the last (a run's shorter last step; [`step_history`]).
pub struct DynamicStepper<'a, const D: usize> {
    pub disc: &'a SolidDiscretization<D>,
    pub problem: &'a SolidProblem<D>,
    pub solver: &'a mut dyn LinearSolver,
    pub newton: NewtonOptions,
    pub scheme: TimeScheme,
    /// The state after the last completed step.
    pub state: DynamicState,
}

impl<'a, const D: usize> DynamicStepper<'a, D> {
    pub fn new(
        disc: &'a SolidDiscretization<D>,
        problem: &'a SolidProblem<D>,
        solver: &'a mut dyn LinearSolver,
        newton: NewtonOptions,
        scheme: TimeScheme,
        state: DynamicState,
    ) -> Self {
        DynamicStepper { disc, problem, solver, newton, scheme, state }
    }
}

impl<const D: usize> Stepper for DynamicStepper<'_, D> {
    type Error = SolidError;

    fn advance(&mut self, t0: f64, t1: f64, cut: bool) -> Result<Advance, SolidError> {
        let dt = t1 - t0;
        let previous = if cut { None } else { self.state.previous.as_ref() };
        let omega = step_ratio(dt, self.state.dt);
        let (a, u_star) = step_history(self.scheme, dt, omega, &self.state.x, previous.map(|p| p.0.as_slice()));
        let (_, v_star) = step_history(self.scheme, dt, omega, &self.state.v, previous.map(|p| p.1.as_slice()));
        let history = InertiaHistory { a, u_star: &u_star, v_star: &v_star };
        let (x, v, newton) = solve_dynamic_step(self.disc, self.problem, &self.state.x, &history, t1, self.solver, &self.newton)?;
        let old = std::mem::replace(&mut self.state, DynamicState { x, v, previous: None, dt });
        if !cut {
            self.state.previous = Some((old.x, old.v));
        }
        Ok(Advance { newton, phases: Timings::default() })
    }
}
