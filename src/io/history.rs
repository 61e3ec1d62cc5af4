//! `history.csv`: one row per step,
//! `step,time,newton_iterations,residual,krylov_iterations,<quantities...>`.

use super::{write_atomic, OutputError};
use std::io::Write;
use std::path::Path;

/// The columns before the quantities.
const HEADER: &str = "step,time,newton_iterations,residual,krylov_iterations";

/// The number of columns of [`HEADER`].
fn fixed_columns() -> usize {
    HEADER.split(',').count()
}

/// A `history.csv` being written row by row: each row is appended and flushed to disk when its
/// step completes, so the cost of a step's output does not grow with the length of the run.
///
/// A run killed while writing a row leaves a torn last line; [`History::resume`] cuts it away.
pub struct History {
    path: std::path::PathBuf,
    file: std::fs::File,
    /// Fields per row (the header's).
    columns: usize,
}

impl History {
    /// Starts a history (replacing any file at `path`) with the quantity names as columns after
    /// `step,time,newton_iterations,residual,krylov_iterations`; the header is written at once.
    pub fn new(path: &Path, quantities: &[String]) -> Result<Self, OutputError> {
        let mut header = String::from(HEADER);
        for q in quantities {
            header.push(',');
            header.push_str(q);
        }
        header.push('\n');
        write_atomic(path, header.as_bytes())?;
        Self::append_to(path, fixed_columns() + quantities.len())
    }

    fn append_to(path: &Path, columns: usize) -> Result<Self, OutputError> {
        let io = |source| OutputError::Io { path: path.display().to_string(), source };
        let file = std::fs::OpenOptions::new().append(true).open(path).map_err(io)?;
        Ok(History { path: path.to_path_buf(), file, columns })
    }

    /// Continues the `history.csv` of an interrupted run: keeps its header and the whole rows of
    /// steps up to `until_step` (a row torn by a kill, without its line end or with missing
    /// fields, is dropped), rewrites the file with them once and appends after them.
    pub fn resume(path: &Path, until_step: usize) -> Result<Self, OutputError> {
        let io = |source| OutputError::Io { path: path.display().to_string(), source };
        let old = std::fs::read_to_string(path).map_err(io)?;
        let mut lines = old.split_inclusive('\n').filter(|l| l.ends_with('\n'));
        let default_header = format!("{HEADER}\n");
        let header = lines.next().unwrap_or(&default_header);
        let columns = header.split(',').count();
        let mut text = header.to_string();
        for line in lines {
            let whole = line.trim_end().split(',').count() == columns;
            let step = line.split(',').next().and_then(|s| s.parse::<usize>().ok());
            if whole && step.is_some_and(|s| s <= until_step) {
                text.push_str(line);
            }
        }
        write_atomic(path, text.as_bytes())?;
        Self::append_to(path, columns)
    }

    /// Appends the row of a completed step (its Newton and Krylov iterations, final residual and
    /// quantities) and flushes it to disk.
    pub fn push(&mut self, step: usize, time: f64, iterations: (usize, usize), residual: f64, values: &[f64]) -> Result<(), OutputError> {
        let io = |source| OutputError::Io { path: self.path.display().to_string(), source };
        if fixed_columns() + values.len() != self.columns {
            let message = format!("a row of {} values for {} columns", fixed_columns() + values.len(), self.columns);
            return Err(io(std::io::Error::other(message)));
        }
        let (newton, krylov) = iterations;
        let mut row = format!("{step},{time:.12e},{newton},{residual:.6e},{krylov}");
        for v in values {
            row.push_str(&format!(",{v:.15e}"));
        }
        row.push('\n');
        // One write per row: a kill tears at most this row, which `resume` cuts away.
        self.file.write_all(row.as_bytes()).map_err(io)?;
        self.file.sync_data().map_err(io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn history_rows_are_appended_and_a_torn_row_is_cut_on_resume() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("history.csv");
        let mut h = History::new(&path, &names(&["a", "b"])).unwrap();
        for k in 1..=3 {
            h.push(k, 0.1 * k as f64, (2, 5), 1e-9, &[k as f64, -(k as f64)]).unwrap();
        }
        assert!(h.push(4, 0.4, (2, 5), 1e-9, &[1.0]).is_err(), "a row with a missing value is refused");
        drop(h);
        let whole = std::fs::read_to_string(&path).unwrap();
        assert_eq!(whole.lines().count(), 4);
        assert!(
            whole.starts_with("step,time,newton_iterations,residual,krylov_iterations,a,b\n1,") && whole.lines().nth(3).unwrap().starts_with("3,")
        );
        // A kill in the middle of row 4: the last line has neither all its fields nor its end.
        std::fs::write(&path, format!("{whole}4,4.000000000000e-1,2,1.0e-9,5,4.0")).unwrap();
        // Cut for being torn, even where the checkpoint is at its step.
        let mut h = History::resume(&path, 4).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), whole, "the torn row is cut away");
        h.push(4, 0.4, (2, 5), 1e-9, &[4.0, -4.0]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().count(), 5);
        assert!(text.lines().all(|l| l.split(',').count() == 7));
        // Resuming from an earlier checkpoint drops the later rows.
        History::resume(&path, 2).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap().lines().count(), 3);
    }
}
