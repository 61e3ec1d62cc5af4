//! Build script: records which source the binary is built from, for the provenance of every
//! result (`summary.json`'s `provenance`, see `src/provenance.rs`).
//!
//! Sets `FDFSI_GIT_COMMIT` (the commit checked out, or `unknown` outside a git checkout),
//! `FDFSI_GIT_MODIFIED` (`true` when the code paths below differ from that commit, untracked
//! files included) and `FDFSI_BUILD_PROFILE` (cargo's `PROFILE`: `release` or `debug`).
use std::process::Command;

/// The paths whose content decides the binary's results: the code, the meshes, the locked
/// dependencies (a case is recorded by its own hash, so `cases/` is left out; the long-run tests
/// in `tests/cases.rs` compare the same paths).
const SOURCE_PATHS: &[&str] = &["src", "crates", "meshes", "Cargo.toml", "Cargo.lock", "build.rs"];

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    for path in SOURCE_PATHS {
        println!("cargo:rerun-if-changed={path}");
    }
    // A new commit changes what the code is compared with (a change of the code itself reruns
    // the script through the paths above).
    for what in ["HEAD", "packed-refs"] {
        if let Some(p) = git(&["rev-parse", "--git-path", what]) {
            println!("cargo:rerun-if-changed={p}");
        }
    }
    if let Some(head_ref) = git(&["symbolic-ref", "-q", "HEAD"]) {
        if let Some(p) = git(&["rev-parse", "--git-path", &head_ref]) {
            println!("cargo:rerun-if-changed={p}");
        }
    }
    let commit = git(&["rev-parse", "HEAD"]).unwrap_or_else(|| "unknown".into());
    let mut status = vec!["status", "--porcelain", "--untracked-files=normal", "--"];
    status.extend_from_slice(SOURCE_PATHS);
    let modified = match git(&status) {
        Some(s) => !s.is_empty(),
        None => commit != "unknown",
    };
    println!("cargo:rustc-env=FDFSI_GIT_COMMIT={commit}");
    println!("cargo:rustc-env=FDFSI_GIT_MODIFIED={modified}");
    println!("cargo:rustc-env=FDFSI_BUILD_PROFILE={}", std::env::var("PROFILE").unwrap_or_else(|_| "unknown".into()));
}
