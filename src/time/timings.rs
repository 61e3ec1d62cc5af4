//! Wall time per phase of a run, the numbers of `summary.json`'s `timings`.

use crate::solve::newton::NewtonReport;
use serde::{Deserialize, Serialize};

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
    /// The (sub)step attempts that failed and were cut (all their phases; the phases above are
    /// those of the (sub)steps done).
    #[serde(default)]
    pub failed_attempts: f64,
    /// Wall time of the whole run; for a resumed run, of all its parts (each earlier part counted
    /// from the setup of its time loop: its case check and mesh reading, a few seconds, are not
    /// carried). The step phases (adapt, transfer, assemble, factorize, solve, output,
    /// failed_attempts, and an FSI run's discretize) are summed over the parts; `mesh` and a flow run's `discretize` are
    /// the last part's.
    pub total: f64,
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
            failed_attempts: t.failed_attempts * factor,
            total: t.total * factor,
        }
    }

    /// Adds the phase times of `other` (all but `total`).
    pub fn add(&mut self, other: &Timings) {
        self.mesh += other.mesh;
        self.adapt += other.adapt;
        self.discretize += other.discretize;
        self.transfer += other.transfer;
        self.assemble += other.assemble;
        self.factorize += other.factorize;
        self.solve += other.solve;
        self.output += other.output;
        self.failed_attempts += other.failed_attempts;
    }

    /// Adds the assembly, factorisation and solve times of a Newton solve.
    pub fn add_newton(&mut self, r: &NewtonReport) {
        self.assemble += r.assemble_seconds;
        self.factorize += r.factorize_seconds;
        self.solve += r.solve_seconds;
    }
}
