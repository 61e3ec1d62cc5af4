//! Which code and which case made a result.
//!
//! Every `summary.json` carries a `provenance` object: the fdfsi version, the git commit the
//! binary was built from and whether its code (`src`, `crates`, `meshes`, the cargo files and
//! `build.rs`; see `build.rs`) differed from that commit, the build profile, and the SHA-256 of the
//! case as used (`case.toml`). A run resumed from a checkpoint also lists the builds that wrote
//! its earlier parts, so a result made partly by older code is recognisable:
//!
//! ```json
//! "provenance": {
//!   "fdfsi_version": "0.1.0",
//!   "git_commit": "69c76b951a0dc544ef753634b6f7b1c510431bb4",
//!   "git_modified": false,
//!   "build_profile": "release",
//!   "case_sha256": "3f0c...",
//!   "earlier_parts": []
//! }
//! ```
//!
//! Tests that check finished long runs (`tests/cases.rs`) refuse a run folder whose builds are
//! not of the tested source.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// The build of fdfsi that ran (a part of) a run.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Build {
    /// The crate version (`CARGO_PKG_VERSION`).
    pub fdfsi_version: String,
    /// The git commit the binary was built from; `unknown` when built outside a git checkout.
    pub git_commit: String,
    /// Whether the source differed from `git_commit` (uncommitted changes or new files).
    pub git_modified: bool,
    /// Cargo's profile: `release` or `debug`.
    pub build_profile: String,
}

impl Build {
    /// The build of this binary.
    pub fn current() -> Build {
        Build {
            fdfsi_version: env!("CARGO_PKG_VERSION").into(),
            git_commit: env!("FDFSI_GIT_COMMIT").into(),
            git_modified: env!("FDFSI_GIT_MODIFIED") == "true",
            build_profile: env!("FDFSI_BUILD_PROFILE").into(),
        }
    }

    /// A build of which nothing is known (it wrote a checkpoint before builds were recorded).
    pub fn unknown() -> Build {
        Build { fdfsi_version: "unknown".into(), git_commit: "unknown".into(), git_modified: false, build_profile: "unknown".into() }
    }

    /// The builds of a run's earlier parts when nothing is known of them: one unknown build.
    pub fn unknown_parts() -> Vec<Build> {
        vec![Build::unknown()]
    }

    /// True when the build is of a known, unmodified commit, i.e. its source can be recovered.
    pub fn is_reproducible(&self) -> bool {
        self.git_commit != "unknown" && !self.git_modified
    }
}

/// What `summary.json` records of the code and the case behind a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The build that finished the run.
    #[serde(flatten)]
    pub build: Build,
    /// SHA-256 (hex) of the case as used, the text of `case.toml`.
    pub case_sha256: String,
    /// The other builds that ran earlier parts of a resumed run, oldest first: empty when this
    /// build ran the whole run.
    #[serde(default)]
    pub earlier_parts: Vec<Build>,
    /// The other run whose checkpoint this run started from (`fdfsi run --start-from DIR`);
    /// absent for a run that started from rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_state: Option<InitialState>,
}

/// The origin of a run's initial state when it was another run's checkpoint (`fdfsi run
/// --start-from DIR`): that run's folder, the step and time of the checkpoint, its case and the
/// builds that ran it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InitialState {
    /// The other run's output folder (absolute).
    pub run: String,
    /// The checkpoint's step (of the other run's schedule) and time.
    pub step: usize,
    pub time: f64,
    /// The steps of this run's schedule before its first: `time / dt` (its history and
    /// `summary.json`'s `steps` count from there).
    #[serde(default)]
    pub steps_before: usize,
    /// SHA-256 (hex) of the other run's case.
    pub case_sha256: String,
    /// The builds that ran the other run up to the checkpoint, oldest first.
    pub builds: Vec<Build>,
}

impl Provenance {
    /// The provenance of a run of the case `case_toml` finished by this binary, after earlier
    /// parts run by `earlier` (the builds a checkpoint lists; this build among them is not
    /// repeated).
    pub fn of_run(case_toml: &str, earlier: &[Build], initial_state: Option<InitialState>) -> Provenance {
        let build = Build::current();
        let mut earlier_parts: Vec<Build> = Vec::new();
        for b in earlier.iter().filter(|b| **b != build) {
            if !earlier_parts.contains(b) {
                earlier_parts.push(b.clone());
            }
        }
        Provenance { build, case_sha256: sha256_hex(case_toml.as_bytes()), earlier_parts, initial_state }
    }

    /// Every build that contributed to the run: the earlier parts' and the last one.
    pub fn builds(&self) -> impl Iterator<Item = &Build> {
        self.earlier_parts.iter().chain(std::iter::once(&self.build))
    }
}

/// The builds that have run a run so far, after this binary ran a part: `earlier` with the
/// current build appended unless it is already the last one.
pub fn builds_so_far(earlier: &[Build]) -> Vec<Build> {
    let mut builds = earlier.to_vec();
    let current = Build::current();
    if builds.last() != Some(&current) {
        builds.push(current);
    }
    builds
}

/// SHA-256 of `bytes` as 64 lower-case hex digits.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sha256_matches_the_standard_test_vector() {
        // FIPS 180-2, appendix B.1.
        assert_eq!(sha256_hex(b"abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    }

    #[test]
    fn the_current_build_names_its_commit_and_profile() {
        let b = Build::current();
        assert_eq!(b.fdfsi_version, env!("CARGO_PKG_VERSION"));
        assert!(b.git_commit == "unknown" || (b.git_commit.len() == 40 && b.git_commit.chars().all(|c| c.is_ascii_hexdigit())), "{}", b.git_commit);
        assert!(["release", "debug"].contains(&b.build_profile.as_str()), "{}", b.build_profile);
    }

    #[test]
    fn a_build_is_listed_once_per_run() {
        let older = Build { git_commit: "0".repeat(40), ..Build::current() };
        assert_eq!(builds_so_far(&[]), vec![Build::current()]);
        assert_eq!(builds_so_far(std::slice::from_ref(&older)), vec![older.clone(), Build::current()]);
        assert_eq!(builds_so_far(&[older.clone(), Build::current()]), vec![older.clone(), Build::current()]);
        let p = Provenance::of_run("title = \"t\"\n", &[], None);
        assert_eq!(p.builds().count(), 1);
        let resumed = Provenance::of_run("", &[older.clone(), Build::current(), older.clone()], None);
        assert_eq!(resumed.earlier_parts, vec![older.clone()]);
        assert!(!Build::unknown().is_reproducible());
        let json = serde_json::to_value(&p).unwrap();
        assert!(json["git_commit"].is_string() && json["case_sha256"].as_str().unwrap().len() == 64, "{json}");
    }
}
