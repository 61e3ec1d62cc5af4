//! Malformed inputs and the errors they must give (issue 8).
//!
//! The corpus is `tests/malformed/`: every `NAME.expect` goes with one input, `NAME.toml` (a
//! case file, checked as `fdfsi check` does: read, parse, validate, build the mesh, load the
//! tables, locate the solid and the probes) or `NAME.msh` (a Gmsh file, read by `read_msh`).
//! Each line of the `.expect` file that is not empty and does not start with `#` is a piece the
//! error message must contain: the file, the line and column or the element, the offending key,
//! the cause. Inputs named `ok-*` are valid (the malformed ones are variations of them) and must
//! pass; other files (`*.csv`, meshes a case refers to) support the cases.
//!
//! `FDFSI_MALFORMED_PRINT=1 cargo test --test malformed -- --nocapture` prints every message.

use fdfsi::case::Case;
use fdfsi::fem::gmsh::read_msh;
use fdfsi::run::check_case;
use std::path::{Path, PathBuf};

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/malformed")
}

/// What `fdfsi check` says about the case file at `path`: its summary or its error.
fn check_file(path: &Path) -> Result<String, String> {
    let label = path.display().to_string();
    let dir = path.parent().unwrap_or(Path::new("."));
    let case = Case::read(path).map_err(|e| e.to_string())?;
    check_case(&case, &label, dir).map_err(|e| e.to_string())
}

/// The outcome of reading one corpus input.
fn outcome(path: &Path) -> Result<String, String> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("toml") => check_file(path),
        Some("msh") => read_msh(path).map(|m| format!("a {}D mesh", m.dim())).map_err(|e| e.to_string()),
        _ => panic!("{}: unknown kind of input", path.display()),
    }
}

/// The input that `NAME.expect` describes.
fn input_of(expect: &Path) -> PathBuf {
    let found: Vec<PathBuf> = ["toml", "msh"].iter().map(|e| expect.with_extension(e)).filter(|p| p.exists()).collect();
    assert_eq!(found.len(), 1, "{}: needs exactly one NAME.toml or NAME.msh beside it", expect.display());
    found[0].clone()
}

fn files(ext: &str) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(corpus())
        .expect("the corpus directory")
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    out.sort();
    out
}

#[test]
fn every_malformed_input_gives_its_message() {
    let print = std::env::var_os("FDFSI_MALFORMED_PRINT").is_some();
    let mut failures = Vec::new();
    let expects = files("expect");
    for expect in &expects {
        let input = input_of(expect);
        let name = input.file_name().unwrap().to_string_lossy().into_owned();
        let wanted: Vec<String> = std::fs::read_to_string(expect)
            .unwrap()
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
            .map(String::from)
            .collect();
        assert!(!wanted.is_empty(), "{}: expects nothing", expect.display());
        match outcome(&input) {
            Ok(summary) => failures.push(format!("{name}: accepted, but should fail\n  {summary}")),
            Err(message) => {
                if print {
                    println!("--- {name}\n{message}");
                }
                for w in &wanted {
                    if !message.contains(w.as_str()) {
                        failures.push(format!("{name}: the message lacks `{w}`:\n  {message}"));
                    }
                }
                if message.trim().is_empty() {
                    failures.push(format!("{name}: empty message"));
                }
            }
        }
    }
    assert!(expects.len() >= 30, "the corpus has {} entries", expects.len());
    assert!(failures.is_empty(), "{} of {} inputs:\n{}", failures.len(), expects.len(), failures.join("\n"));
}

#[test]
fn the_valid_inputs_pass() {
    for input in files("toml").into_iter().chain(files("msh")) {
        let name = input.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("ok-") {
            match outcome(&input) {
                Ok(summary) => {
                    if std::env::var_os("FDFSI_MALFORMED_PRINT").is_some() {
                        println!("--- {name}\n{summary}");
                    }
                }
                Err(e) => panic!("{name} should pass: {e}"),
            }
        } else {
            assert!(input.with_extension("expect").exists(), "{name}: no .expect beside it (name valid inputs ok-*)");
        }
    }
}
