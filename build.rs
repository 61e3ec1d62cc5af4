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
    // the script through the paths above): HEAD, and the branch refs (loose in `refs/heads`, a
    // folder whose files cargo scans, or packed). Only paths that exist are watched: cargo reruns
    // the script on every build for a missing one (`packed-refs` is absent until git packs refs).
    for what in ["HEAD", "refs/heads", "packed-refs"] {
        if let Some(p) = git(&["rev-parse", "--git-path", what]).filter(|p| std::path::Path::new(p).exists()) {
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
    println!("cargo::rustc-check-cfg=cfg(petsc_int64)");
    #[cfg(feature = "petsc")]
    petsc::link();
}

/// The `petsc` feature: links the system's PETSc (found by pkg-config as `PETSc`) and tells the
/// FFI (`src/solve/petsc/ffi.rs`) its integer width (`cfg(petsc_int64)` for a build with 64-bit
/// indices); links Open MPI too (found as `ompi-c`). Only real double-precision PETSc built on
/// Open MPI (whose `MPI_Comm` is a pointer) is supported: Debian's `petsc-dev`.
#[cfg(feature = "petsc")]
mod petsc {
    pub fn link() {
        let lib = pkg_config::Config::new()
            .probe("PETSc")
            .unwrap_or_else(|e| panic!("the petsc feature needs the system's PETSc (Debian: apt install petsc-dev): {e}"));
        // Open MPI itself, for MPI_Init_thread and MPI_COMM_SELF.
        pkg_config::Config::new()
            .probe("ompi-c")
            .unwrap_or_else(|e| panic!("the petsc feature needs Open MPI's ompi-c.pc (Debian: libopenmpi-dev): {e}"));
        let (path, conf) = lib
            .include_paths
            .iter()
            .map(|dir| dir.join("petscconf.h"))
            .find_map(|path| std::fs::read_to_string(&path).ok().map(|text| (path, text)))
            .expect("petscconf.h in PETSc's include path");
        println!("cargo:rerun-if-changed={}", path.display());
        let defined = |name: &str| conf.lines().any(|l| l.split_whitespace().take(2).eq(["#define", name]));
        assert!(!defined("PETSC_USE_COMPLEX") && defined("PETSC_USE_REAL_DOUBLE"), "the petsc feature needs a real double-precision PETSc build");
        assert!(defined("PETSC_HAVE_OMPI_MAJOR_VERSION"), "the petsc feature needs PETSc built on Open MPI (Debian's petsc-dev)");
        if defined("PETSC_USE_64BIT_INDICES") {
            println!("cargo:rustc-cfg=petsc_int64");
        }
    }
}
