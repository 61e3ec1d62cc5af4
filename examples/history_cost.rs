//! Output cost per step at the start and the end of a long run: `history.csv` rows appended and
//! flushed ([`History::push`]), beside the whole-file rewrite it replaced (the text so far written
//! to a temporary file, fsynced and renamed, every step).
//!
//! `cargo run --release --example history_cost [STEPS]` prints the median time of one step's
//! row around step 100 and around step STEPS (default 2000), 12 quantities per row.
use fdfsi::io::{write_atomic, History};
use std::time::Instant;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The median time of one row around step 100 and around step `steps`, writing rows with `row`.
fn row_times(steps: usize, mut row: impl FnMut(usize)) -> (f64, f64) {
    let (mut early, mut late) = (Vec::new(), Vec::new());
    for s in 1..steps + 10 {
        let t = Instant::now();
        row(s);
        let dt = t.elapsed().as_secs_f64();
        match (s.abs_diff(100) < 10, s.abs_diff(steps) < 10) {
            (true, _) => early.push(dt),
            (_, true) => late.push(dt),
            _ => {}
        }
    }
    (median(early), median(late))
}

fn main() {
    let steps: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(2000);
    let dir = tempfile::tempdir().expect("a temporary folder");
    let names: Vec<String> = (0..12).map(|k| format!("quantity_{k}")).collect();
    let values: Vec<f64> = (0..12).map(|k| 1.0 / (k as f64 + 3.0)).collect();
    // Appended rows.
    let mut history = History::new(&dir.path().join("history.csv"), &names).expect("history.csv");
    let (a, b) = row_times(steps, |s| history.push(s, s as f64 * 1e-3, (3, 0), 1e-10, &values).expect("a row"));
    println!("append  : step 100 {:8.3} ms, step {steps} {:8.3} ms", 1e3 * a, 1e3 * b);
    // The whole file rewritten each step.
    let path = dir.path().join("rewritten.csv");
    let mut text = format!("step,time,newton_iterations,residual,{}\n", names.join(","));
    let (a, b) = row_times(steps, |s| {
        text.push_str(&format!("{s},{:.12e},3,{:.6e}", s as f64 * 1e-3, 1e-10));
        for v in &values {
            text.push_str(&format!(",{v:.15e}"));
        }
        text.push('\n');
        write_atomic(&path, text.as_bytes()).expect("rewrite");
    });
    println!("rewrite : step 100 {:8.3} ms, step {steps} {:8.3} ms", 1e3 * a, 1e3 * b);
}
