//! Fuzzing without nightly: property tests that feed the case-file reader and the Gmsh reader
//! arbitrary bytes, token soup and mutated valid inputs (byte flips, truncations, line deletions
//! and duplications, numbers replaced by extreme ones) and require that every input gives a
//! value or an error with a non-empty message naming the file, within a time bound: no panic,
//! no hang.
//!
//! - `case_files`: `Case::from_toml_str`, then `Case::validate`, then (when the case's meshes are
//!   small) `check_case`, the whole of `fdfsi check`; a valid case must also survive the
//!   round trip through `Case::to_toml`.
//! - `gmsh_files`: `parse_msh`; a mesh it returns must pass `Mesh::check`.
//!
//! In CI each runs a few hundred inputs per strategy (a few seconds). `FDFSI_FUZZ_CASES=N`
//! sets the inputs per strategy and round; `FDFSI_FUZZ_SECONDS=S` repeats rounds with fresh
//! random seeds until `S` seconds have passed, e.g.
//! `FDFSI_FUZZ_SECONDS=600 cargo test --release --test fuzz gmsh -- --nocapture`.
//! A failing input is written to `target/tmp/fuzz-failures/` (to add to `tests/malformed/`).

use fdfsi::case::{Case, MeshSpec, SolidMeshSpec, TimeFunction};
use fdfsi::fem::gmsh::{parse_msh, AnyMesh};
use fdfsi::run::check_case;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How far the inputs got: parsed, valid, checked (cases); meshes returned (Gmsh).
static PARSED: AtomicUsize = AtomicUsize::new(0);
static VALID: AtomicUsize = AtomicUsize::new(0);
static CHECKED: AtomicUsize = AtomicUsize::new(0);
static CHECK_PASSED: AtomicUsize = AtomicUsize::new(0);
static MESHES: AtomicUsize = AtomicUsize::new(0);

const CASE_LABEL: &str = "fuzz.toml";
const MSH_LABEL: &str = "fuzz.msh";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn env_usize(name: &str) -> Option<usize> {
    std::env::var(name).ok().and_then(|v| v.trim().parse().ok())
}

/// Inputs per strategy and round.
fn cases_per_round() -> u32 {
    env_usize("FDFSI_FUZZ_CASES").unwrap_or(300) as u32
}

/// Runs `f(input)` on a worker thread; fails if it panics or takes longer than `limit`.
fn bounded<T: Send + 'static>(limit: Duration, f: impl FnOnce() -> T + Send + 'static) -> Result<T, String> {
    let (tx, rx) = mpsc::channel();
    std::thread::Builder::new()
        .name("fuzz-input".into())
        .stack_size(16 << 20)
        .spawn(move || {
            let _ = tx.send(f());
        })
        .map_err(|e| format!("cannot spawn a thread: {e}"))?;
    match rx.recv_timeout(limit) {
        Ok(v) => Ok(v),
        Err(mpsc::RecvTimeoutError::Timeout) => Err(format!("no result after {limit:?} (hang?)")),
        Err(mpsc::RecvTimeoutError::Disconnected) => Err("panicked".into()),
    }
}

/// Saves a failing input for the corpus and turns the failure into a proptest error.
fn fail(kind: &str, input: &[u8], why: &str) -> TestCaseError {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-failures");
    let _ = std::fs::create_dir_all(&dir);
    let hash = input.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3));
    let path = dir.join(format!("{kind}-{hash:016x}.{}", if kind == "case" { "toml" } else { "msh" }));
    let _ = std::fs::write(&path, input);
    TestCaseError::fail(format!("{why} (input saved to {})", path.display()))
}

// ---------------------------------------------------------------------------------------------
// Mutations
// ---------------------------------------------------------------------------------------------

/// One edit of an input: `(kind, position, argument)`; positions and arguments are reduced
/// modulo what they index.
type Op = (u8, u32, u32);

const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "0.5",
    "-0.5",
    "1e-300",
    "1e300",
    "1e999",
    "-1e999",
    "nan",
    "inf",
    "-inf",
    "4.1",
    "2.2",
    "65535",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999",
    "0x10",
    "1_000",
    "+1",
    "",
    "1.",
    ".5",
    "1e",
    "3",
];

/// Applies `ops` to `input`; `tokens` are the pieces insertions draw from.
fn mutate(input: &[u8], ops: &[Op], tokens: &[&str]) -> Vec<u8> {
    let mut b = input.to_vec();
    for &(kind, pos, arg) in ops {
        let at = |len: usize| if len == 0 { 0 } else { pos as usize % len };
        match kind % 9 {
            // Flip bits of one byte.
            0 if !b.is_empty() => {
                let i = at(b.len());
                b[i] ^= (arg as u8).max(1);
            }
            // Truncate.
            1 => b.truncate(at(b.len() + 1)),
            // Delete a line.
            2 | 3 => {
                let lines = split_lines(&b);
                if !lines.is_empty() {
                    let k = at(lines.len());
                    b = [&b[..lines[k].0], &b[lines[k].1..]].concat();
                }
            }
            // Duplicate a line (in place or elsewhere).
            4 => {
                let lines = split_lines(&b);
                if !lines.is_empty() {
                    let (s, e) = lines[at(lines.len())];
                    let line = b[s..e].to_vec();
                    let dest = lines[arg as usize % lines.len()].0;
                    b.splice(dest..dest, line);
                }
            }
            // Insert a token.
            5 => {
                let i = at(b.len() + 1);
                let t = tokens[arg as usize % tokens.len()].as_bytes();
                b.splice(i..i, t.iter().copied());
            }
            // Replace a number by an extreme one.
            6 | 7 => {
                let nums = number_spans(&b);
                if !nums.is_empty() {
                    let (s, e) = nums[at(nums.len())];
                    let n = NUMBERS[arg as usize % NUMBERS.len()].as_bytes();
                    b.splice(s..e, n.iter().copied());
                }
            }
            // Delete a byte range.
            _ => {
                let i = at(b.len() + 1);
                let j = (i + 1 + arg as usize % 64).min(b.len());
                if i < j {
                    b.drain(i..j);
                }
            }
        }
    }
    b
}

/// `(start, end)` of every line, the newline included.
fn split_lines(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &c) in b.iter().enumerate() {
        if c == b'\n' {
            out.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < b.len() {
        out.push((start, b.len()));
    }
    out
}

/// `(start, end)` of every run of digits, `.`, `e`, `-` starting with a digit.
fn number_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit() {
            let s = i;
            while i < b.len() && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b'e' | b'E' | b'-' | b'+')) {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

fn ops(max: usize) -> impl Strategy<Value = Vec<Op>> {
    proptest::collection::vec((any::<u8>(), any::<u32>(), any::<u32>()), 1..max)
}

/// Named strategies of inputs `(bytes, k)`.
type Strategies = Vec<(&'static str, BoxedStrategy<(Vec<u8>, usize)>)>;

/// Inputs `(bytes, k)`: arbitrary bytes and soups of `tokens` (`k = usize::MAX`), and
/// mutations of `seeds` (`k` the seed's index): of the valid ones (the first `valid`; one to
/// three edits, so that many stay close to valid and reach the later checks), and of all
/// (malformed corpus entries; up to five edits).
fn inputs(seeds: Vec<Vec<u8>>, valid: usize, tokens: &'static [&'static str]) -> Strategies {
    let bytes = proptest::collection::vec(any::<u8>(), 0..1024).prop_map(|b| (b, usize::MAX)).boxed();
    let soup = proptest::collection::vec(proptest::sample::select(tokens), 0..200).prop_map(|t| (t.concat().into_bytes(), usize::MAX)).boxed();
    let n = seeds.len();
    let seeds = std::sync::Arc::new(seeds);
    let all = seeds.clone();
    let mutated = (0..valid, ops(4)).prop_map(move |(k, ops)| (mutate(&seeds[k], &ops, tokens), k)).boxed();
    let corpus = (0..n, ops(6)).prop_map(move |(k, ops)| (mutate(&all[k], &ops, tokens), k)).boxed();
    vec![("arbitrary bytes", bytes), ("token soup", soup), ("mutated valid inputs", mutated), ("mutated corpus inputs", corpus)]
}

/// Runs `check` on the inputs of every strategy: one round of [`cases_per_round`] each with a
/// fixed seed, then, while `FDFSI_FUZZ_SECONDS` lasts, rounds with fresh seeds. Returns the
/// number of inputs run.
fn fuzz(name: &str, strategies: Strategies, check: impl Fn(&[u8], usize) -> Result<(), TestCaseError>) -> usize {
    let seconds = env_usize("FDFSI_FUZZ_SECONDS").unwrap_or(0);
    let start = Instant::now();
    let mut total = 0usize;
    let mut round = 0u64;
    loop {
        for (what, strategy) in &strategies {
            let config =
                Config { cases: cases_per_round(), failure_persistence: None, max_shrink_iters: 500, max_shrink_time: 60_000, ..Config::default() };
            let mut seed = [0u8; 32];
            let salt = if round == 0 { 0x5eed } else { start.elapsed().as_nanos() as u64 ^ (round << 32) };
            seed[..8].copy_from_slice(&salt.to_le_bytes());
            seed[8..16].copy_from_slice(&(what.len() as u64).to_le_bytes());
            let mut runner = TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &seed));
            let count = std::cell::Cell::new(0usize);
            let result = runner.run(strategy, |(input, k)| {
                count.set(count.get() + 1);
                check(&input, k)
            });
            total += count.get();
            if let Err(e) = result {
                panic!("{name} fuzzer, {what}, round {round} (seed {salt:#x}): {e}");
            }
        }
        round += 1;
        if start.elapsed().as_secs() >= seconds as u64 {
            break;
        }
    }
    println!("{name} fuzzer: {total} inputs in {round} rounds, {:.1} s, no failure", start.elapsed().as_secs_f64());
    total
}

// ---------------------------------------------------------------------------------------------
// Case files
// ---------------------------------------------------------------------------------------------

const TOML_TOKENS: &[&str] = &[
    "\n",
    " ",
    "=",
    "\"",
    "'",
    "[",
    "]",
    "[[",
    "]]",
    "{",
    "}",
    ",",
    ".",
    "#",
    "\"\"\"",
    "-",
    "+",
    "\r\n",
    "\t",
    "\\",
    "title",
    "mesh",
    "kind",
    "\"rectangle\"",
    "\"gmsh\"",
    "\"box\"",
    "\"pipe\"",
    "\"channel\"",
    "file",
    "\"ok-square.msh\"",
    "\"ok-table.csv\"",
    "x",
    "y",
    "z",
    "n",
    "[0.0, 1.0]",
    "[2, 2]",
    "[1, 1, 1]",
    "physics",
    "formulation",
    "\"plane\"",
    "\"3d\"",
    "\"axisymmetric\"",
    "fluid",
    "density",
    "viscosity",
    "boundary",
    "name",
    "type",
    "\"velocity\"",
    "\"no-slip\"",
    "value",
    "[\"x*y\", 0]",
    "time",
    "dt",
    "end",
    "output_every",
    "solid",
    "surface",
    "\"top\"",
    "model",
    "\"neo-hookean\"",
    "shear_modulus",
    "eps_hat",
    "min_move_quality",
    "min_cut_quality",
    "boundary_cuts",
    "\"touch\"",
    "\"split\"",
    "rotate_deg",
    "translate",
    "time_function",
    "{ kind = \"table\", file = \"ok-table.csv\" }",
    "{ kind = \"ramp\", duration = 1 }",
    "output",
    "probe",
    "point",
    "[0.5, 0.5]",
    "field",
    "component",
    "0",
    "1",
    "-1",
    "0.5",
    "1e308",
    "nan",
    "inf",
    "true",
    "1979-05-27",
    "\u{0}",
    "é",
    "\u{feff}",
    "[mesh]\n",
    "[physics]\n",
    "[fluid]\n",
    "[[boundary]]\n",
    "[time]\n",
    "[solid]\n",
    "[[output.probe]]\n",
    "[solver.newton]\n",
];

/// The files `dir/*.ext`, valid ones (`ok-*` in the corpus, all elsewhere) first; returns them
/// and the number of valid ones.
fn seeds(dirs: &[PathBuf], ext: &str) -> (Vec<PathBuf>, usize) {
    let mut paths: Vec<PathBuf> = dirs
        .iter()
        .flat_map(|d| std::fs::read_dir(d).unwrap().map(|e| e.unwrap().path()))
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    let malformed = |p: &PathBuf| p.starts_with(root().join("tests/malformed")) && !p.file_name().unwrap().to_string_lossy().starts_with("ok-");
    paths.sort_by_key(|p| (malformed(p), p.clone()));
    let valid = paths.iter().filter(|p| !malformed(p)).count();
    (paths, valid)
}

/// Case files to mutate (valid ones first), with the directory their paths are relative to,
/// and the number of valid ones.
fn case_seeds() -> (Vec<(Vec<u8>, PathBuf)>, usize) {
    let (paths, valid) = seeds(&[root().join("cases"), root().join("tests/malformed")], "toml");
    (paths.iter().map(|p| (std::fs::read(p).unwrap(), p.parent().unwrap().to_path_buf())).collect(), valid)
}

/// A regular file of at most `max` bytes.
fn small_file(path: &Path, max: u64) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file() && m.len() <= max)
}

/// Whether `check_case` on this (valid) case is quick: small generated meshes, small files.
fn cheap_to_check(case: &Case, dir: &Path) -> bool {
    let prod = |n: &[usize], k: usize| n.iter().try_fold(k, |a, &b| a.checked_mul(b)).unwrap_or(usize::MAX);
    let fluid = match &case.mesh {
        None => 0,
        Some(MeshSpec::Rectangle { n, .. }) | Some(MeshSpec::Channel { n, .. }) => prod(n, 2),
        Some(MeshSpec::Box { n, .. }) => prod(n, 6),
        Some(MeshSpec::Pipe { n_radial, n_axial, .. }) => prod(&[*n_radial, *n_radial, *n_axial], 6),
        Some(MeshSpec::Gmsh { file }) => {
            if small_file(&dir.join(file), 20_000) {
                0
            } else {
                usize::MAX
            }
        }
    };
    let solid = match case.solid.first().map(|s| &s.mesh) {
        None => 0,
        Some(SolidMeshSpec::Rectangle { n, .. }) | Some(SolidMeshSpec::Quadrilateral { n, .. }) => prod(n, 1),
        Some(SolidMeshSpec::Box { n, .. }) => prod(n, 1),
        Some(SolidMeshSpec::QuarterDisc { n_core, n_ring, n_layers, .. }) => {
            prod(&[*n_core, n_core.saturating_add(n_ring.saturating_mul(2)), *n_layers], 1)
        }
        Some(SolidMeshSpec::Gmsh { file }) => {
            if small_file(&dir.join(file), 20_000) {
                0
            } else {
                usize::MAX
            }
        }
    };
    let tables = case.boundary.iter().all(|b| match &b.time_function {
        Some(TimeFunction::Table { file, .. }) => small_file(&dir.join(file), 20_000),
        _ => true,
    });
    fluid <= 4000 && solid <= 200 && tables
}

/// An error message must say something and name the file.
fn message_ok(message: &str, label: &str) -> Result<(), String> {
    if message.trim().is_empty() {
        return Err("an empty error message".into());
    }
    if !message.contains(label) {
        return Err(format!("the message does not name the file: {message}"));
    }
    Ok(())
}

/// Parse, validate, round trip and (if cheap) check one case file.
fn case_input(bytes: Vec<u8>, dir: PathBuf) -> Result<(), String> {
    let text = String::from_utf8_lossy(&bytes);
    let case = match Case::from_toml_str(&text, CASE_LABEL) {
        Ok(c) => c,
        Err(e) => return message_ok(&e.to_string(), CASE_LABEL),
    };
    PARSED.fetch_add(1, Ordering::Relaxed);
    if let Err(e) = case.validate(CASE_LABEL) {
        return message_ok(&e.to_string(), CASE_LABEL);
    }
    VALID.fetch_add(1, Ordering::Relaxed);
    let again = case.to_toml();
    if let Err(e) = Case::from_toml_str(&again, "round-trip.toml").and_then(|c| c.validate("round-trip.toml")) {
        return Err(format!("a valid case does not survive its round trip through to_toml: {e}\n{again}"));
    }
    if cheap_to_check(&case, &dir) {
        CHECKED.fetch_add(1, Ordering::Relaxed);
        match check_case(&case, CASE_LABEL, &dir) {
            Ok(_) => {
                CHECK_PASSED.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => message_ok(&e.to_string(), CASE_LABEL).map_err(|m| format!("check_case: {m}"))?,
        }
    }
    Ok(())
}

#[test]
fn case_files() {
    let (seeds, valid) = case_seeds();
    let (texts, dirs): (Vec<Vec<u8>>, Vec<PathBuf>) = seeds.into_iter().unzip();
    let corpus = root().join("tests/malformed");
    let strategies = inputs(texts, valid, TOML_TOKENS);
    let check = |input: &[u8], k: usize| -> Result<(), TestCaseError> {
        // Paths in a mutated case are relative to its seed's directory; other inputs to the corpus.
        let dir = dirs.get(k).unwrap_or(&corpus).clone();
        let copy = input.to_vec();
        match bounded(Duration::from_secs(20), move || case_input(copy, dir)) {
            Ok(Ok(())) => Ok(()),
            Ok(Err(why)) | Err(why) => Err(fail("case", input, &why)),
        }
    };
    let total = fuzz("case-file", strategies, check);
    println!(
        "case-file fuzzer: {} parsed, {} valid, {} checked ({} passed the check)",
        PARSED.load(Ordering::Relaxed),
        VALID.load(Ordering::Relaxed),
        CHECKED.load(Ordering::Relaxed),
        CHECK_PASSED.load(Ordering::Relaxed)
    );
    assert!(total >= 4 * cases_per_round() as usize);
}

// ---------------------------------------------------------------------------------------------
// Gmsh files
// ---------------------------------------------------------------------------------------------

const MSH_TOKENS: &[&str] = &[
    "\n",
    " ",
    "\r\n",
    "$MeshFormat\n",
    "4.1 0 8\n",
    "4.1 1 8\n",
    "$EndMeshFormat\n",
    "$PhysicalNames\n",
    "$EndPhysicalNames\n",
    "$Entities\n",
    "$EndEntities\n",
    "$Nodes\n",
    "$EndNodes\n",
    "$Elements\n",
    "$EndElements\n",
    "$Periodic\n",
    "$NodeData\n",
    "\"",
    "1 2 \"a\"\n",
    "0",
    "1",
    "2",
    "3",
    "4",
    "5",
    "-1",
    "0.5",
    "nan",
    "inf",
    "1e308",
    "9",
    "11",
    "15",
    "200",
    "18446744073709551615",
    "4294967295",
    "2147483648",
    "$",
    "\u{0}",
    "\u{ff}",
    "\t",
    "1 1 2\n",
    "2 1 2 4\n",
    "1 2 3\n",
];

/// Gmsh files to mutate (valid ones first) and the number of valid ones.
fn msh_seeds() -> (Vec<Vec<u8>>, usize) {
    let (paths, valid) = seeds(&[root().join("tests/malformed")], "msh");
    (paths.iter().map(|p| std::fs::read(p).unwrap()).collect(), valid)
}

fn msh_input(bytes: Vec<u8>) -> Result<(), String> {
    let result = parse_msh(&bytes, MSH_LABEL);
    if result.is_ok() {
        MESHES.fetch_add(1, Ordering::Relaxed);
    }
    match result {
        Ok(AnyMesh::D2(m)) => m.check().map_err(|e| format!("parse_msh returned a mesh that fails Mesh::check: {e}")),
        Ok(AnyMesh::D3(m)) => m.check().map_err(|e| format!("parse_msh returned a mesh that fails Mesh::check: {e}")),
        Err(e) => message_ok(&e.to_string(), MSH_LABEL),
    }
}

#[test]
fn gmsh_files() {
    let (seeds, valid) = msh_seeds();
    let strategies = inputs(seeds, valid, MSH_TOKENS);
    let check = |input: &[u8], _: usize| -> Result<(), TestCaseError> {
        let copy = input.to_vec();
        match bounded(Duration::from_secs(10), move || msh_input(copy)) {
            Ok(Ok(())) => Ok(()),
            Ok(Err(why)) | Err(why) => Err(fail("msh", input, &why)),
        }
    };
    let total = fuzz("gmsh", strategies, check);
    println!("gmsh fuzzer: {} inputs gave a mesh", MESHES.load(Ordering::Relaxed));
    assert!(total >= 4 * cases_per_round() as usize);
}

#[test]
fn mutations_do_what_they_say() {
    let text = b"a = 1\nb = 2.5\n";
    assert_eq!(mutate(text, &[(1, 5, 0)], &["x"]), b"a = 1");
    assert_eq!(mutate(text, &[(2, 1, 0)], &["x"]), b"a = 1\n");
    assert_eq!(mutate(text, &[(4, 0, 1)], &["x"]), b"a = 1\na = 1\nb = 2.5\n");
    assert_eq!(mutate(text, &[(5, 0, 0)], &["x"]), b"xa = 1\nb = 2.5\n");
    assert_eq!(mutate(text, &[(6, 1, 12)], &["x"]), b"a = 1\nb = inf\n");
    assert_eq!(number_spans(b"x 12 3.5e-3"), vec![(2, 4), (5, 11)]);
}
