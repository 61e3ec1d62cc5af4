//! `fdfsi check` and `fdfsi run` build a case by the same code: for every shipped case they
//! report the same unknowns. Time-dependent cases are cut to their first step (FSI meshes are
//! adapted to the solid of each step, and `check` builds the first).

use fdfsi::case::builtin::BUILTIN_CASES;
use fdfsi::case::Case;
use fdfsi::run::check::check;
use fdfsi::run::{run_case, RunOptions};
use std::collections::BTreeMap;
use std::path::Path;

/// The fine mesh of model problem 4 (its first step alone takes about three minutes here) and the
/// whole 3D valve (380 810 unknowns, for a large machine).
const SLOW: [&str; 2] = ["model-problem-4-fine", "valve-3d"];

/// Checks and runs the first step of each case in `names`; asserts both report the same dofs.
fn check_and_run_agree(names: &[&str]) {
    let cases_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let out = tempfile::tempdir().unwrap();
    for (name, text) in BUILTIN_CASES.iter().filter(|(n, _)| names.contains(n)) {
        let mut case = Case::from_toml_str(text, name).unwrap();
        if let Some(t) = case.time.as_mut() {
            t.end = t.dt;
        }
        let checked: BTreeMap<String, usize> = check(&case, name, &cases_dir).unwrap().dofs.into_iter().collect();
        let options = RunOptions::new(out.path().join(name), &cases_dir);
        let summary = run_case(&case, &options, &mut |_: &str| {}).unwrap_or_else(|e| panic!("{name}: {e}"));
        println!("{name}: {checked:?}");
        assert_eq!(checked, summary.dofs, "{name}: check and run disagree");
        assert!(checked["total"] > 0);
    }
}

#[test]
fn check_and_run_report_the_same_dofs_for_every_shipped_case() {
    let names: Vec<&str> = BUILTIN_CASES.iter().map(|(n, _)| *n).filter(|n| !SLOW.contains(n)).collect();
    assert!(names.len() >= 15);
    check_and_run_agree(&names);
}

#[test]
#[ignore = "model problem 4's fine mesh (about 3 minutes) and the whole 3D valve (for a large machine); run with --ignored"]
fn check_and_run_report_the_same_dofs_for_the_slow_cases() {
    check_and_run_agree(&SLOW);
}
