//! Checkpoints and resume: an interrupted run (stopped through `RunOptions::stop`, as Ctrl-C
//! does, or killed with SIGKILL) continued with `--resume` gives the history of an uninterrupted
//! run, and no output file is ever left truncated.

use fdfsi::case::builtin::BUILTIN_CASES;
use fdfsi::case::Case;
use fdfsi::io::checkpoint::Checkpoint;
use fdfsi::run::{run_case, RunError, RunObserver, RunOptions, StartFrom};
use fdfsi_fem::vtk::{read_pvd, read_vtu};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A small unsteady Navier-Stokes case: an impulsively started channel flow with BDF2, probes
/// and a flux, `steps` steps, with the direct solver (whose resumed runs repeat the history
/// exactly).
fn channel_case(steps: usize) -> String {
    channel_case_with(steps, "direct")
}

/// A case text with the direct linear solver (the exact repeats are the direct solve's; the AL
/// solver's resumed runs agree to its tolerances: see below). The text has no `[solver.linear]`.
fn direct(text: &str) -> String {
    assert!(!text.contains("[solver.linear]"));
    format!("{text}\n[solver.linear]\nmethod = \"direct\"\n")
}

/// [`channel_case`] with the linear solver `method`.
fn channel_case_with(steps: usize, method: &str) -> String {
    format!(
        r#"title = "checkpoint test: impulsive channel flow"
[mesh]
kind = "rectangle"
x = [0.0, 2.0]
y = [0.0, 1.0]
n = [16, 8]
[physics]
formulation = "plane"
model = "navier-stokes"
[fluid]
density = 1.0
viscosity = 0.01
[time]
dt = 0.05
end = {}
scheme = "bdf2"
output_every = 2
[[boundary]]
name = "left"
type = "velocity"
value = ["4*y*(1-y)", 0.0]
time_function = {{ kind = "sine", period = 2.0 }}
[[boundary]]
name = "top"
type = "no-slip"
[[boundary]]
name = "bottom"
type = "no-slip"
[[boundary]]
name = "right"
type = "free"
[[output.probe]]
name = "u_mid"
field = "velocity"
component = 0
point = [1.0, 0.5]
[[output.probe]]
name = "p_mid"
field = "pressure"
point = [1.0, 0.5]
[[output.boundary_integral]]
name = "outlet_flux"
boundary = "right"
kind = "flux"
[solver.linear]
method = "{method}"
"#,
        0.05 * steps as f64
    )
}

/// The numbers of `history.csv`: one row of values per step.
fn history(dir: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    text.lines().skip(1).map(|l| l.split(',').map(|v| v.parse::<f64>().unwrap()).collect()).collect()
}

/// The index of column `name` in `dir`'s history.csv.
fn history_column(dir: &Path, name: &str) -> usize {
    let text = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    text.lines().next().unwrap().split(',').position(|c| c == name).unwrap_or_else(|| panic!("no column {name}"))
}

/// Asserts two histories agree to `tol` (relative to the column's scale), row by row; `tol = 0`:
/// the same numbers (the README's "exactly"), the final Newton residuals included.
fn assert_same_history(a: &[Vec<f64>], b: &[Vec<f64>], tol: f64) {
    assert_eq!(a.len(), b.len(), "number of history rows");
    for (ra, rb) in a.iter().zip(b) {
        assert_eq!(ra.len(), rb.len());
        // Column 3 is the final Newton residual: round-off, compared only when exact.
        for (c, (x, y)) in ra.iter().zip(rb).enumerate().filter(|(c, _)| tol == 0.0 || *c != 3) {
            let scale = a.iter().map(|r| r[c].abs()).fold(1e-300, f64::max);
            assert!((x - y).abs() <= tol * scale, "step {}: column {c}: {x} vs {y}", ra[0]);
        }
    }
}

/// Every `.vtu` the `.pvd` lists reads back, and `summary.json` parses.
fn assert_outputs_whole(dir: &Path) {
    let pvd = dir.join("solution.pvd");
    for e in read_pvd(&pvd).unwrap() {
        read_vtu(&e.resolve(&pvd)).unwrap_or_else(|err| panic!("{}: {err}", e.file));
    }
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert!(summary["quantities"].is_object());
}

/// Sets the stop flag once step `at` has completed, as a Ctrl-C handler would.
struct StopAt {
    at: usize,
    flag: Arc<AtomicBool>,
}

impl RunObserver for StopAt {
    fn log(&mut self, _line: &str) {}
    fn step(&mut self, step: usize, _total: usize, _time: f64) {
        if step == self.at {
            self.flag.store(true, Ordering::SeqCst);
        }
    }
}

/// A run killed while appending a row of `history.csv` leaves a torn last line (here: a row
/// without all its values and without its line end, after the checkpoint's step); the resumed
/// run cuts it away and its history is whole and equal to the uninterrupted run's.
#[test]
fn a_torn_history_row_is_cut_away_on_resume() {
    let (full, parts, dir) = interrupted_and_resumed_after(&channel_case(8), Path::new("."), 3, |dir| {
        let path = dir.join("history.csv");
        let mut text = std::fs::read_to_string(&path).unwrap();
        text.push_str("5,2.500000000000e-1,3,1.2");
        std::fs::write(&path, text).unwrap();
    });
    let text = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    assert!(text.ends_with('\n'));
    assert_same_history(&full, &parts, 0.0);
}

/// Runs `case` uninterrupted into `full`, and interrupted after step `stop_after` (+1, since the
/// flag is seen at the end of the next step) then resumed into `parts`; returns both histories.
fn interrupted_and_resumed(case_text: &str, case_dir: &Path, stop_after: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>, PathBuf) {
    interrupted_and_resumed_after(case_text, case_dir, stop_after, |_| {})
}

/// [`interrupted_and_resumed`] with `damage(run_dir)` done to the interrupted run's files before
/// it is resumed.
fn interrupted_and_resumed_after(
    case_text: &str,
    case_dir: &Path,
    stop_after: usize,
    damage: impl FnOnce(&Path),
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>, PathBuf) {
    let case = Case::from_toml_str(case_text, "test").unwrap();
    let tmp = tempfile::tempdir().unwrap().keep();
    let (full, parts) = (tmp.join("full"), tmp.join("parts"));
    run_case(&case, &RunOptions::new(&full, case_dir), &mut |_: &str| {}).unwrap();
    let flag = Arc::new(AtomicBool::new(false));
    let options = RunOptions { checkpoint_every: Some(1000), stop: Some(flag.clone()), ..RunOptions::new(&parts, case_dir) };
    let err = run_case(&case, &options, &mut StopAt { at: stop_after, flag }).unwrap_err();
    let RunError::Interrupted { step, .. } = err else { panic!("expected an interruption, got {err}") };
    assert_eq!(step, stop_after + 1);
    assert!(err.to_string().contains("fdfsi run --resume"), "{err}");
    // Flow runs and dynamic solid runs record the initial state too.
    let records_start = case.solid.is_empty() || (case.mesh.is_none() && case.time.is_some());
    assert_eq!(history(&parts).len(), if records_start { step + 1 } else { step });
    damage(&parts);
    let (resumed_case, resume) = RunOptions::resume(&parts).unwrap();
    let checkpoint = Checkpoint::read(&parts).unwrap();
    assert_eq!(checkpoint.step, step);
    let summary = run_case(&resumed_case, &resume, &mut |_: &str| {}).unwrap();
    assert_outputs_whole(&parts);
    // The summary's wall time covers both parts: at least the interrupted part's (which the
    // checkpoint holds) and at least the phases summed over both parts.
    let (before, t) = (checkpoint.progress.timings.total, &summary.timings);
    assert!(before > 0.0 && t.total > before, "total {} after a first part of {before} s", t.total);
    let phases = t.mesh + t.adapt + t.discretize + t.transfer + t.assemble + t.factorize + t.solve + t.output + t.failed_attempts;
    assert!(t.total >= phases, "total {} < phases {phases}", t.total);
    (history(&full), history(&parts), parts)
}

#[test]
fn flow_run_stopped_and_resumed_repeats_the_history() {
    let (full, parts, dir) = interrupted_and_resumed(&channel_case(8), Path::new("."), 3);
    assert_same_history(&full, &parts, 0.0);
    // The series lists each written step once: output_every = 2 over 8 steps, plus t = 0.
    assert_eq!(read_pvd(&dir.join("solution.pvd")).unwrap().len(), 5);
}

/// A Windkessel outlet's state (its capacitor pressure, an unknown of the system) is in the
/// checkpoint: the resumed run repeats the uninterrupted one's outlet pressures exactly.
#[test]
fn a_windkessel_outlet_resumes_from_its_checkpointed_state() {
    let text = channel_case(8).replace(
        "name = \"right\"\ntype = \"free\"",
        "name = \"right\"\ntype = \"windkessel\"\nwindkessel = { proximal_resistance = 0.2, compliance = 0.5, distal_resistance = 3.0, initial_pressure = 0.7 }",
    );
    assert!(text.contains("windkessel"));
    let (full, parts, dir) = interrupted_and_resumed(&text, Path::new("."), 3);
    assert_same_history(&full, &parts, 0.0);
    let pc = history_column(&dir, "right_capacitor_pressure");
    // The capacitor charges from 0.7 and keeps its history across the resume.
    assert_eq!(full[0][pc], 0.7);
    assert!(full.iter().skip(1).all(|r| r[pc] != 0.7));
}

/// With the augmented-Lagrangian solver a resumed run repeats the history to the solver's
/// tolerances, not exactly: its held factors are not part of the checkpoint, so the steps after
/// the resume start from fresh ones, and take other Newton and Krylov iterations (README). The
/// quantities (columns 5 on) agree to the Krylov tolerance, 1e-8 (measured: 1.4e-11).
#[test]
fn augmented_lagrangian_flow_run_resumes_to_its_tolerances() {
    let (full, parts, _) = interrupted_and_resumed(&channel_case_with(8, "augmented-lagrangian"), Path::new("."), 3);
    assert_eq!(full.len(), parts.len(), "number of history rows");
    let worst = full
        .iter()
        .zip(&parts)
        .flat_map(|(a, b)| {
            a.iter().zip(b).enumerate().skip(5).map(|(c, (x, y))| (x - y).abs() / full.iter().map(|r| r[c].abs()).fold(1e-300, f64::max))
        })
        .fold(0.0, f64::max);
    println!("largest difference of a quantity, relative to its largest value: {worst:.2e}");
    assert!(worst <= 1e-8, "{worst:.2e}");
}

/// A solid run (quasi-static load steps) stopped as by Ctrl-C and resumed from its checkpoint
/// repeats the uninterrupted run's history exactly.
#[test]
fn solid_run_stopped_and_resumed_repeats_the_history() {
    let text = BUILTIN_CASES.iter().find(|(n, _)| *n == "cook-membrane").unwrap().1.replace("steps = 2,", "steps = 4,");
    assert!(text.contains("steps = 4,"));
    let (full, parts, _) = interrupted_and_resumed(&text, Path::new("."), 1);
    assert_eq!(full.len(), 4);
    assert_same_history(&full, &parts, 0.0);
}

/// A dynamic solid run (Turek-Hron CSM3's bar, BDF2: the checkpoint holds the velocity and the
/// previous step) stopped and resumed repeats the uninterrupted run's history exactly.
#[test]
fn dynamic_solid_run_stopped_and_resumed_repeats_the_history() {
    let text = BUILTIN_CASES.iter().find(|(n, _)| *n == "turek-hron-csm3").unwrap().1.replace("end = 10.0", "end = 0.05");
    assert!(text.contains("end = 0.05"));
    let cases = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let (full, parts, _) = interrupted_and_resumed(&text, &cases, 4);
    assert_eq!(full.len(), 11, "the initial state and 10 steps");
    assert_same_history(&full, &parts, 0.0);
}

#[test]
fn fsi_run_stopped_and_resumed_repeats_the_history() {
    let text = BUILTIN_CASES.iter().find(|(n, _)| *n == "model-problem-2").unwrap().1;
    let text = text.replace("end = 12.0", "end = 4.0").replace("n = [64, 16]", "n = [32, 8]").replace("output_every = 6", "output_every = 1");
    let text = direct(&text);
    let (full, parts, dir) = interrupted_and_resumed(&text, &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases"), 1);
    assert_same_history(&full, &parts, 0.0);
    // Fluid, solid and gamma_f pieces at each of the 4 steps.
    assert_eq!(read_pvd(&dir.join("solution.pvd")).unwrap().len(), 12);
}

/// An FSI run's Windkessel outlet (its `Q` and `P_c` carried from mesh to mesh, not on them) is
/// in the checkpoint: the resumed run repeats the uninterrupted one exactly.
#[test]
fn fsi_run_with_a_windkessel_outlet_resumes_its_state() {
    let text = BUILTIN_CASES.iter().find(|(n, _)| *n == "model-problem-2").unwrap().1;
    let outlet = "name = \"right\"\ntype = \"windkessel\"\nwindkessel = { proximal_resistance = 0.5, compliance = 0.2, distal_resistance = 2.0, initial_pressure = 0.4 }";
    let text = text.replace("end = 12.0", "end = 4.0").replace("n = [64, 16]", "n = [32, 8]").replace("name = \"right\"\ntype = \"free\"", outlet);
    assert!(text.contains("windkessel"));
    let (full, parts, dir) = interrupted_and_resumed(&direct(&text), &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases"), 1);
    assert_same_history(&full, &parts, 0.0);
    let pc = history_column(&dir, "right_capacitor_pressure");
    assert!(full.iter().all(|r| r[pc] > 0.4), "the capacitor charges from 0.4");
}

/// The compressible block of `tests/fsi_thick_solid.rs` with inertia settling in fluid, coupled on
/// three sides with its covered fluid removed: BDF2, dt = 0.1 to t = 0.5, the direct solver.
fn bdf2_block() -> String {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fsi_thick_solid.rs")).unwrap();
    let block = &text[text.find("r#\"").unwrap() + 3..text.find("\"#;").unwrap()];
    let text = direct(
        &block
            .replace("end = 6.0", "end = 0.5")
            .replace("dt = 1.0", "dt = 0.1")
            .replace("scheme = \"euler\"", "scheme = \"bdf2\"")
            .replace("body_force = [0.0, -0.3]", "body_force = [0.0, -0.3]\ndensity = 1.0"),
    );
    assert!(text.contains("bdf2") && text.contains("density = 1.0") && text.contains("end = 0.5"));
    text
}

/// A BDF2 FSI run (the checkpoint holds t_{n-1}: solid state and velocity, the fluid on its
/// adapted mesh, the last step's length) stopped after its second step and resumed repeats the
/// uninterrupted run's history exactly.
#[test]
fn bdf2_fsi_run_stopped_and_resumed_repeats_the_history() {
    let (full, parts, _) = interrupted_and_resumed(&bdf2_block(), Path::new("."), 2);
    assert_eq!(full.len(), 5);
    assert_same_history(&full, &parts, 0.0);
}

/// `--start-from DIR` ([`StartFrom`]): a run started from another run's checkpoint at t = 0.2
/// with the same case repeats that run's later steps exactly; on a finer fluid mesh with half the
/// time step (BDF2's first step then of the variable-step formula) it starts after t = 0.2 and
/// its summary names the run it started from and counts the steps it took. A time step that does
/// not divide 0.2, another solid mesh, no step left, the folder it starts from as output, a
/// folder without a checkpoint and a flow case are refused with the reason, before a step.
#[test]
fn fsi_run_started_from_another_runs_checkpoint() {
    let text = bdf2_block();
    let run = |text: &str, out: &Path, start_from: Option<&Path>| {
        let case = Case::from_toml_str(text, "test").unwrap();
        let start_from = start_from.map(|d| StartFrom::read(d).unwrap());
        let options = RunOptions { checkpoint_every: Some(1), start_from, ..RunOptions::new(out, ".") };
        run_case(&case, &options, &mut |_: &str| {})
    };
    let tmp = tempfile::tempdir().unwrap();
    let [full, first, same, finer] = ["full", "first", "same", "finer"].map(|d| tmp.path().join(d));
    run(&text, &full, None).unwrap();
    run(&text.replace("end = 0.5", "end = 0.2"), &first, None).unwrap();
    run(&text, &same, Some(&first)).unwrap();
    assert_same_history(&history(&full)[2..], &history(&same), 0.0);

    let finer_text = text.replace("n = [10, 10]", "n = [20, 20]").replace("dt = 0.1", "dt = 0.05");
    let summary = run(&finer_text, &finer, Some(&first)).unwrap();
    assert_eq!(summary.steps, 6, "the steps taken");
    let same_summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(same.join("summary.json")).unwrap()).unwrap();
    assert!(summary.cells > same_summary["cells"].as_u64().unwrap() as usize, "the finer fluid mesh was used");
    let rows = history(&finer);
    assert_eq!(rows.iter().map(|r| r[0] as usize).collect::<Vec<_>>(), vec![5, 6, 7, 8, 9, 10]);
    assert!((rows[0][1] - 0.25).abs() < 1e-12 && (rows[5][1] - 0.5).abs() < 1e-12);
    let initial = summary.provenance.as_ref().and_then(|p| p.initial_state.clone()).expect("the summary names the initial state");
    assert_eq!((initial.step, initial.time), (2, history(&first)[1][1]));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(finer.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["provenance"]["initial_state"]["step"], 2, "{json}");
    // Its checkpoints carry the origin on, for the summary of a resumed part.
    assert_eq!(Checkpoint::read(&finer).unwrap().initial_state, Some(initial));
    // The block's settling at t = 0.5 on either mesh and step: the same to the discretisation
    // error.
    let uy = |rows: &[Vec<f64>]| rows.last().unwrap()[history_column(&full, "uy_top")];
    let (a, b) = (uy(&history(&full)), uy(&rows));
    println!("uy_top at t = 0.5: {a:.6e} (from rest), {b:.6e} (finer, from t = 0.2)");
    assert!((a - b).abs() <= 0.05 * a.abs(), "{a} vs {b}");

    let refused = |text: &str, expected: &str| {
        let out = tmp.path().join("refused");
        let e = run(text, &out, Some(&first)).unwrap_err().to_string();
        assert!(e.contains(expected), "{e}");
        assert!(!out.join("history.csv").exists(), "a refused run wrote its history");
    };
    refused(&text.replace("dt = 0.1", "dt = 0.15"), "is not a whole number of steps dt = 0.15");
    refused(&text.replace("n = [2, 2]", "n = [2, 3]"), "its solid mesh (25 nodes, 4 cells) is not this case's (35 nodes, 6 cells)");
    refused(&text.replace("end = 0.5", "end = 0.2"), "leaves no step of dt = 0.1 before the case's end = 0.2");
    refused(&channel_case(4), "--start-from is not for this case");
    let e = run(&text, &first, Some(&first)).unwrap_err().to_string();
    assert!(e.contains("would write into the folder it starts from"), "{e}");
    let e = StartFrom::read(tmp.path().join("nothing-here")).unwrap_err().to_string();
    assert!(e.starts_with("--start-from ") && e.contains("no checkpoint"), "{e}");
    assert_eq!(StartFrom::read(first.join("checkpoint.json")).unwrap().dir, StartFrom::read(&first).unwrap().dir);
}

/// A run stopped after its last step (its checkpoint is at the end) resumes with no step left to
/// take and finishes: the same history, whole outputs, the last step's profiles and picture.
#[test]
fn fsi_run_stopped_after_its_last_step_resumes_and_finishes() {
    let text = BUILTIN_CASES.iter().find(|(n, _)| *n == "model-problem-2").unwrap().1;
    let text = direct(&text.replace("end = 12.0", "end = 2.0").replace("n = [64, 16]", "n = [32, 8]"));
    let (full, parts, dir) = interrupted_and_resumed(&text, &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases"), 1);
    assert_eq!(full.len(), 2);
    assert_same_history(&full, &parts, 0.0);
    // The last step's outputs were written before the stop.
    for file in ["profiles/wss_upstream_side.csv", "profiles/wss_downstream_side.csv", "speed.png"] {
        assert!(dir.join(file).exists(), "{file} missing");
    }
}

/// With `reuse_factorization = true` (model problems 3 and 4) an uninterrupted run may start a
/// step from the previous step's LU, which a checkpoint does not keep: the resumed run
/// factorises afresh, and its history repeats the uninterrupted one to round-off (README),
/// held at 1e-12 of each column's scale.
#[test]
fn fsi_run_with_reused_factorisations_resumes_to_round_off() {
    let text = BUILTIN_CASES.iter().find(|(n, _)| *n == "model-problem-3").unwrap().1;
    assert!(text.contains("reuse_factorization = true"));
    let text = direct(&text.replace("end = 6.0", "end = 1.0"));
    let (full, parts, _) = interrupted_and_resumed(&text, &Path::new(env!("CARGO_MANIFEST_DIR")).join("cases"), 4);
    assert_eq!(full.len(), 10);
    assert_same_history(&full, &parts, 1e-12);
}

/// A run resumed by another build records it: the checkpoint lists the builds that ran the steps
/// so far, and summary.json's provenance names the earlier parts' other builds.
#[test]
fn a_resumed_run_names_the_builds_of_its_earlier_parts() {
    use fdfsi::io::provenance::Build;
    let case = Case::from_toml_str(&channel_case(4), "test").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let flag = Arc::new(AtomicBool::new(false));
    let options = RunOptions { checkpoint_every: Some(1000), stop: Some(flag.clone()), ..RunOptions::new(dir.path(), ".") };
    assert!(run_case(&case, &options, &mut StopAt { at: 1, flag }).is_err());
    let mut checkpoint = Checkpoint::read(dir.path()).unwrap();
    assert_eq!(checkpoint.builds, vec![Build::current()]);
    // As if an older build had run the first part.
    let older = Build { git_commit: "0123456789abcdef0123456789abcdef01234567".into(), ..Build::current() };
    checkpoint.builds = vec![older.clone()];
    checkpoint.write(dir.path()).unwrap();
    let (case, resume) = RunOptions::resume(dir.path()).unwrap();
    let summary = run_case(&case, &resume, &mut |_: &str| {}).unwrap();
    let p = summary.provenance.unwrap();
    assert_eq!((p.build, p.earlier_parts), (Build::current(), vec![older]));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["provenance"]["earlier_parts"][0]["git_commit"], "0123456789abcdef0123456789abcdef01234567");
    // A checkpoint written before builds were recorded reads as one unknown build.
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(Checkpoint::path(dir.path())).unwrap()).unwrap();
    json.as_object_mut().unwrap().remove("builds");
    std::fs::write(Checkpoint::path(dir.path()), json.to_string()).unwrap();
    let old = Checkpoint::read(dir.path()).unwrap();
    assert_eq!(old.builds, vec![Build::unknown()]);
    assert!(!old.builds[0].is_reproducible());
}

#[test]
fn resume_refuses_a_changed_case() {
    let case = Case::from_toml_str(&channel_case(2), "test").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = RunOptions { checkpoint_every: Some(1), ..RunOptions::new(dir.path(), ".") };
    run_case(&case, &options, &mut |_: &str| {}).unwrap();
    let (_, resume) = RunOptions::resume(dir.path()).unwrap();
    let other = Case::from_toml_str(&channel_case(3), "test").unwrap();
    let e = run_case(&other, &resume, &mut |_: &str| {}).unwrap_err().to_string();
    assert!(e.contains("differs from the one the checkpoint was written for"), "{e}");
    let e = RunOptions::resume(dir.path().join("nowhere")).unwrap_err().to_string();
    assert!(e.contains("no checkpoint to resume from"), "{e}");
}

/// The binary killed with SIGKILL in the middle of a run, then `fdfsi run --resume DIR`: the
/// history equals the uninterrupted run's and every output file reads back whole.
#[test]
fn killed_run_resumes_to_the_same_history() {
    let exe = env!("CARGO_BIN_EXE_fdfsi");
    let tmp = tempfile::tempdir().unwrap();
    let case_file = tmp.path().join("channel.toml");
    std::fs::write(&case_file, channel_case(40)).unwrap();
    let (full, killed) = (tmp.path().join("full"), tmp.path().join("killed"));
    let ok = Command::new(exe).args(["-q", "run"]).arg(&case_file).arg("--out").arg(&full).status().unwrap();
    assert!(ok.success());
    let mut child =
        Command::new(exe).args(["-q", "run"]).arg(&case_file).arg("--out").arg(&killed).args(["--checkpoint-every", "1"]).spawn().unwrap();
    // Kill it once a few checkpoints exist, mid-way through a later step.
    let start = Instant::now();
    loop {
        let step = Checkpoint::read(&killed).map(|c| c.step).unwrap_or(0);
        if step >= 5 {
            break;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint written");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let at_kill = Checkpoint::read(&killed).unwrap().step;
    assert!(at_kill < 40, "the run finished before it was killed; make the case longer");
    let out = Command::new(exe).args(["-q", "run", "--resume"]).arg(&killed).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_outputs_whole(&killed);
    assert_same_history(&history(&full), &history(&killed), 0.0);
}

/// `fdfsi adapt --at DIR` adapts the run's fluid mesh to the solid of its checkpoint: gamma_s
/// lies on the deformed solid the run wrote at that step (not the step before), and gamma_f has the
/// facets the run's next step used.
#[test]
fn adapt_at_a_checkpoint_is_the_next_steps_mesh() {
    let text = BUILTIN_CASES.iter().find(|(n, _)| *n == "model-problem-1").unwrap().1;
    let text = text.replace("end = 18.0", "end = 0.15").replace("output_every = 10", "output_every = 1");
    let case = Case::from_toml_str(&text, "test").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = RunOptions { checkpoint_every: Some(2), ..RunOptions::new(dir.path(), Path::new(env!("CARGO_MANIFEST_DIR")).join("cases")) };
    run_case(&case, &options, &mut |_: &str| {}).unwrap();
    assert_eq!(Checkpoint::read(dir.path()).unwrap().step, 2);
    let s = fdfsi::run::adapt::adapt_checkpoint(dir.path(), &dir.path().join("adapt")).unwrap();
    let h = history(dir.path());
    let facets_col = std::fs::read_to_string(dir.path().join("history.csv"))
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|c| c == "coupling_facets")
        .unwrap();
    assert_eq!(s.stats.coupling_facets as f64, h[2][facets_col], "step 3 was adapted to the solid after step 2");
    let gamma_s = read_vtu(&dir.path().join("adapt/gamma_s.vtu")).unwrap().points;
    let solid_at = |time: f64| {
        let entries = read_pvd(&dir.path().join("solution.pvd")).unwrap();
        let e = entries
            .iter()
            .find(|e| e.name == "solid" && (e.time - time).abs() < 1e-9)
            .unwrap_or_else(|| panic!("no solid at t = {time}: {entries:?}"));
        read_vtu(&dir.path().join(&e.file)).unwrap().points
    };
    let distance =
        |p: &[f64; 3], pts: &[[f64; 3]]| pts.iter().map(|q| (0..3).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>().sqrt()).fold(f64::INFINITY, f64::min);
    let (at_step_2, at_step_1) = (solid_at(0.1), solid_at(0.05));
    assert!(gamma_s.iter().all(|p| distance(p, &at_step_2) < 1e-12), "gamma_s lies on the solid of step 2");
    let moved = gamma_s.iter().map(|p| distance(p, &at_step_1)).fold(0.0, f64::max);
    assert!(moved > 1e-6, "the solid has moved since step 1: {moved:e}");
    // A flow run's checkpoint has no solid.
    let flow = tempfile::tempdir().unwrap();
    let case = Case::from_toml_str(&channel_case(2), "test").unwrap();
    run_case(&case, &RunOptions { checkpoint_every: Some(1), ..RunOptions::new(flow.path(), ".") }, &mut |_: &str| {}).unwrap();
    let e = fdfsi::run::adapt::adapt_checkpoint(flow.path(), &flow.path().join("adapt")).unwrap_err().to_string();
    assert!(e.contains("needs the checkpoint of an FSI run"), "{e}");
}
