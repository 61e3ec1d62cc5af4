//! Restart files: `DIR/checkpoint.json` holds what a time loop needs to go on exactly where it
//! stopped.
//!
//! A checkpoint is written after step `k` (every `N` steps with `--checkpoint-every N`, and when a
//! run is interrupted). It holds:
//! - the case as used (TOML text) and the folder its relative paths are resolved against;
//! - the step number `k` and time `t_k`;
//! - the state: for a flow run the solution `x^k` and, for BDF2, `x^{k-1}` and the last step's
//!   length; for an FSI run the solid displacement, deformation gradients and velocity, the fluid
//!   velocity and the solid position its (adapted) mesh was built for, the coupling cells of its
//!   pattern ([`crate::discretize::fsi::CouplingPattern`]); for a quasi-static solid run the load
//!   factor, the solution, the deformation gradients (updated Lagrangian) and the predictor; for
//!   a dynamic solid run the solution, the velocity, both one step back, and the last step's
//!   length;
//! - the run's running totals (Newton iterations, residuals, phase timings) for `summary.json`;
//! - the builds of fdfsi that ran it so far (see [`crate::io::provenance`]).
//!
//! Floating-point values are written in their shortest round-trip decimal form and read back
//! exactly (serde_json's `float_roundtrip`), so a resumed run repeats the arithmetic of an
//! uninterrupted one bit for bit (with the direct solver; the AL solver's held factors and kept
//! LU ordering are not saved, so its resumed runs agree to the Krylov tolerance). On resume,
//! `history.csv` and `solution.pvd` are cut back to step `k` (rows and entries written after the
//! checkpoint by the interrupted run are dropped).
//!
//! The file is written to a temporary name and renamed, so a run killed while writing leaves the
//! previous checkpoint intact.

use crate::discretize::fsi::FsiRestart;
use crate::discretize::solid::LoadState;
use crate::io::{write_atomic, OutputError};
use crate::time::solid::DynamicState;
use crate::time::Timings;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;
use thiserror::Error;

/// File name of the checkpoint inside the output folder.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";

/// Format version; a checkpoint of another version is refused.
pub const CHECKPOINT_VERSION: u32 = 2;

/// A checkpoint failure.
#[derive(Debug, Error)]
pub enum CheckpointError {
    #[error("{path}: no checkpoint to resume from (run with --checkpoint-every N to write one)")]
    Missing { path: String },
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("{path}: not a valid fdfsi checkpoint: {message}")]
    Invalid { path: String, message: String },
    #[error("{path}: checkpoint format version {found}, this fdfsi reads version {CHECKPOINT_VERSION}")]
    Version { path: String, found: u32 },
    #[error("{path}: the checkpoint is of a {found} run but the case is a {expected} run")]
    Kind { path: String, found: &'static str, expected: &'static str },
    #[error("{path}: the checkpoint holds {found} values for {what} but the case has {expected}: was the case or its mesh changed?")]
    Size { path: String, what: &'static str, found: usize, expected: usize },
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// What is saved of a run's state.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum RestartState {
    /// A flow run: the solution and the time level (with `x^{k-1}` for BDF2).
    Flow { x: Vec<f64>, level: crate::time::TimeLevel },
    /// An FSI run.
    Fsi(Box<FsiRestart>),
    /// A solid run: the state after the last load step.
    Solid(LoadState),
    /// A solid run with inertia: the state after the last time step.
    #[serde(rename = "solid-dynamic")]
    SolidDynamic(DynamicState),
}

impl RestartState {
    fn kind(&self) -> &'static str {
        match self {
            RestartState::Flow { .. } => "flow",
            RestartState::Fsi(_) => "FSI",
            RestartState::Solid(_) => "solid",
            RestartState::SolidDynamic(_) => "dynamic solid",
        }
    }
}

/// Running totals of a run, carried over a restart into `summary.json`.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Progress {
    pub newton_iterations: usize,
    pub krylov_iterations: usize,
    pub residual_norms: Vec<f64>,
    /// Phase times summed over the steps so far; `total` is the run's wall time up to the
    /// checkpoint, over all its parts.
    pub timings: Timings,
}

impl Progress {
    /// The totals after a step of a run part that began at `part_start`: `timings.total` holds the
    /// wall time of the earlier parts (carried over restarts, 0 in a fresh run) and becomes that
    /// plus this part's time so far.
    pub fn after_step(iterations: (usize, usize), residual_norms: &[f64], timings: &Timings, part_start: Instant) -> Progress {
        let timings = Timings { total: timings.total + part_start.elapsed().as_secs_f64(), ..timings.clone() };
        let (newton_iterations, krylov_iterations) = iterations;
        Progress { newton_iterations, krylov_iterations, residual_norms: residual_norms.to_vec(), timings }
    }
}

/// A restart point: see the module documentation.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Checkpoint {
    pub version: u32,
    /// The case as used, TOML.
    pub case: String,
    /// Folder that relative paths in the case are resolved against.
    pub case_dir: PathBuf,
    /// Completed steps.
    pub step: usize,
    /// Time reached.
    pub time: f64,
    pub state: RestartState,
    pub progress: Progress,
    /// The builds of fdfsi that ran the steps so far, oldest first. A checkpoint written before
    /// builds were recorded reads as one unknown build ([`crate::io::provenance::Build::unknown`]), so
    /// that a run resumed from it is not taken for one made by known code.
    #[serde(default = "crate::io::provenance::Build::unknown_parts")]
    pub builds: Vec<crate::io::provenance::Build>,
    /// For a run started from another run's checkpoint (`fdfsi run --start-from DIR`), where its
    /// initial state came from; carried to the summary of every later part.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_state: Option<crate::io::provenance::InitialState>,
}

impl Checkpoint {
    /// Path of the checkpoint in the output folder `out_dir`.
    pub fn path(out_dir: &Path) -> PathBuf {
        out_dir.join(CHECKPOINT_FILE)
    }

    /// Writes the checkpoint into `out_dir` (atomically).
    pub fn write(&self, out_dir: &Path) -> Result<(), CheckpointError> {
        let text = serde_json::to_string(self)
            .map_err(|e| CheckpointError::Invalid { path: Self::path(out_dir).display().to_string(), message: e.to_string() })?;
        Ok(write_atomic(&Self::path(out_dir), text.as_bytes())?)
    }

    /// Reads the checkpoint of `out_dir`.
    pub fn read(out_dir: &Path) -> Result<Self, CheckpointError> {
        let path = Self::path(out_dir);
        let shown = path.display().to_string();
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(CheckpointError::Missing { path: shown }),
            Err(source) => return Err(CheckpointError::Io { path: shown, source }),
        };
        let c: Checkpoint = serde_json::from_str(&text).map_err(|e| CheckpointError::Invalid { path: shown.clone(), message: e.to_string() })?;
        if c.version != CHECKPOINT_VERSION {
            return Err(CheckpointError::Version { path: shown, found: c.version });
        }
        Ok(c)
    }

    /// The flow state, checked against the run's dof count.
    pub fn flow_state(&self, out_dir: &Path, num_dofs: usize) -> Result<(Vec<f64>, crate::time::TimeLevel), CheckpointError> {
        let path = Self::path(out_dir).display().to_string();
        match &self.state {
            RestartState::Flow { x, level } => {
                let prev = level.x_prev.as_ref().map_or(num_dofs, Vec::len);
                for (what, found) in [("the solution", x.len()), ("the previous solution", prev)] {
                    if found != num_dofs {
                        return Err(CheckpointError::Size { path, what, found, expected: num_dofs });
                    }
                }
                Ok((x.clone(), level.clone()))
            }
            other => Err(CheckpointError::Kind { path, found: other.kind(), expected: "flow" }),
        }
    }

    /// The state of a solid run, checked against the shape of the run's unloaded state
    /// `at_rest`: its unknowns, its deformation gradients (one per quadrature point, updated
    /// Lagrangian), a predictor no longer than the unknowns.
    pub fn solid_state(&self, out_dir: &Path, at_rest: &LoadState) -> Result<LoadState, CheckpointError> {
        let path = Self::path(out_dir).display().to_string();
        let s = match &self.state {
            RestartState::Solid(s) => s,
            other => return Err(CheckpointError::Kind { path, found: other.kind(), expected: "solid" }),
        };
        let gradients = |f: &Option<Vec<_>>| f.as_ref().map_or(0, Vec::len);
        let n = at_rest.x.len();
        let predictor = s.last_change.as_ref().map_or(0, |(d, _)| d.len());
        for (what, found, expected) in [
            ("the solid state", s.x.len(), n),
            ("the deformation gradients", gradients(&s.f_qp), gradients(&at_rest.f_qp)),
            ("the predictor", predictor, predictor.min(n)),
        ] {
            if found != expected {
                return Err(CheckpointError::Size { path, what, found, expected });
            }
        }
        Ok(s.clone())
    }

    /// The state of a dynamic solid run, checked against the run's number of unknowns.
    pub fn dynamic_solid_state(&self, out_dir: &Path, num_dofs: usize) -> Result<DynamicState, CheckpointError> {
        let path = Self::path(out_dir).display().to_string();
        let s = match &self.state {
            RestartState::SolidDynamic(s) => s,
            other => return Err(CheckpointError::Kind { path, found: other.kind(), expected: "dynamic solid" }),
        };
        let (xp, vp) = s.previous.as_ref().map_or((num_dofs, num_dofs), |(x, v)| (x.len(), v.len()));
        for (what, found) in [("the solid state", s.x.len()), ("the velocity", s.v.len()), ("the previous state", xp), ("the previous velocity", vp)]
        {
            if found != num_dofs {
                return Err(CheckpointError::Size { path, what, found, expected: num_dofs });
            }
        }
        Ok(s.clone())
    }

    /// The FSI state, checked against the solid's dof count.
    pub fn fsi_state(&self, out_dir: &Path, solid_dofs: usize) -> Result<&FsiRestart, CheckpointError> {
        let path = Self::path(out_dir).display().to_string();
        match &self.state {
            RestartState::Fsi(s) => {
                let base = s.fluid.as_ref().map_or(solid_dofs, |f| f.solid_base.len());
                for (what, found) in
                    [("the solid displacement", s.solid_x.len()), ("the solid velocity", s.solid_v.len()), ("the fluid's solid position", base)]
                {
                    if found != solid_dofs {
                        return Err(CheckpointError::Size { path, what, found, expected: solid_dofs });
                    }
                }
                Ok(s)
            }
            other => Err(CheckpointError::Kind { path, found: other.kind(), expected: "FSI" }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let awkward = [0.1 + 0.2, 1.0 / 3.0, 2.0f64.sqrt() * 1e-300, -7.123456789012345e17, f64::MIN_POSITIVE, 5e-324];
        let c = Checkpoint {
            version: CHECKPOINT_VERSION,
            case: "title = \"t\"".into(),
            case_dir: PathBuf::from("."),
            step: 3,
            time: 0.30000000000000004,
            state: RestartState::Flow {
                x: awkward.to_vec(),
                level: crate::time::TimeLevel { step: 3, time: 0.30000000000000004, x_prev: Some(awkward.iter().map(|v| -v).collect()), dt: 0.1 },
            },
            progress: Progress { newton_iterations: 7, krylov_iterations: 0, residual_norms: vec![1e-11], timings: Timings::default() },
            builds: vec![crate::io::provenance::Build::current()],
            initial_state: None,
        };
        c.write(dir.path()).unwrap();
        let back = Checkpoint::read(dir.path()).unwrap();
        let (x, level) = back.flow_state(dir.path(), awkward.len()).unwrap();
        assert_eq!(x.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), awkward.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
        assert_eq!(back.builds, c.builds);
        assert_eq!(level, crate::time::TimeLevel { step: 3, time: 0.30000000000000004, x_prev: Some(awkward.iter().map(|v| -v).collect()), dt: 0.1 });
        let e = back.flow_state(dir.path(), 5).unwrap_err().to_string();
        assert!(e.contains("holds 6 values for the solution but the case has 5"), "{e}");
        assert!(back.fsi_state(dir.path(), 6).unwrap_err().to_string().contains("checkpoint is of a flow run"));
    }

    #[test]
    fn missing_and_corrupt_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let e = Checkpoint::read(dir.path()).unwrap_err().to_string();
        assert!(e.contains("no checkpoint to resume from"), "{e}");
        std::fs::write(Checkpoint::path(dir.path()), "{\"version\": 1, \"case\": ").unwrap();
        let e = Checkpoint::read(dir.path()).unwrap_err().to_string();
        assert!(e.contains("checkpoint.json: not a valid fdfsi checkpoint"), "{e}");
    }
}
