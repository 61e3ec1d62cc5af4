//! Every kind of run cuts a step whose Newton solve fails: here an FSI step (model problem 2's
//! first step with Newton limited to three iterations at a tolerance that a step of dt = 1 does
//! not reach and a step of dt = 1/2 does) fails whole, passes in two halves, and then equals a
//! run made with half the step; the failed attempt's time is reported apart.

use fdfsi::case::builtin::BUILTIN_CASES;
use fdfsi::case::Case;
use fdfsi::run::{run_case, RunError, RunOptions};
use std::path::Path;

/// Model problem 2 up to `end`, steps of `dt`, at most `max_cuts` cuts, Newton limited to three
/// iterations (no grace iterations) to an absolute residual of 1e-9.
fn tight_model_problem_2(dt: f64, end: f64, max_cuts: usize) -> Case {
    let text = BUILTIN_CASES.iter().find(|(n, _)| *n == "model-problem-2").unwrap().1;
    let text = text.replace("[time]\n", "[solver.newton]\nmax_iterations = 3\ngrace_iterations = 0\nabs_tol = 1e-9\n\n[time]\n");
    let mut case = Case::from_toml_str(&text, "model-problem-2").unwrap();
    let t = case.time.as_mut().unwrap();
    (t.dt, t.end, t.max_cuts) = (dt, end, max_cuts);
    case
}

fn run(case: &Case, out: &Path, log: &mut Vec<String>) -> Result<fdfsi::run::RunSummary, RunError> {
    let cases = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    run_case(case, &RunOptions::new(out, &cases), &mut |l: &str| log.push(l.to_string()))
}

#[test]
fn an_fsi_step_that_fails_whole_is_cut_and_passes_in_halves() {
    let dir = tempfile::tempdir().unwrap();
    // Uncut, the step fails, and the error names it.
    let err = run(&tight_model_problem_2(1.0, 1.0, 0), &dir.path().join("uncut"), &mut Vec::new()).unwrap_err();
    assert!(matches!(err, RunError::StepFailed { step: 1, cuts: 0, .. }), "{err}");
    assert!(err.to_string().contains("step 1 (t = 1.000000e0)"), "{err}");
    // With one cut allowed it passes in two halves...
    let mut log = Vec::new();
    let cut = run(&tight_model_problem_2(1.0, 1.0, 1), &dir.path().join("cut"), &mut log).unwrap();
    assert!(log.iter().any(|l| l.starts_with("step 1/1") && l.contains("(1 cuts, dt = 5.000e-1)")), "{log:#?}");
    // The failure that caused the cut is logged.
    assert!(log.iter().any(|l| l.starts_with("step 1: ") && l.ends_with("; from t = 0.000000e0 on in sub-steps of 1/2 of the step")), "{log:#?}");
    assert_eq!(cut.steps, 1);
    // The failed attempt's time is reported apart (a run that is not cut has none).
    assert!(cut.timings.failed_attempts > 0.0, "{:?}", cut.timings);
    // ...which are the two steps of a run with dt = 1/2.
    let halves = run(&tight_model_problem_2(0.5, 1.0, 0), &dir.path().join("halves"), &mut Vec::new()).unwrap();
    for name in ["plate_force_x", "plate_force_y", "inlet_flux"] {
        let (a, b) = (cut.quantities[name], halves.quantities[name]);
        assert!((a - b).abs() <= 1e-12 * b.abs().max(1e-300), "{name}: {a} after a cut step, {b} in two steps");
    }
    assert_eq!(halves.timings.failed_attempts, 0.0);
}
