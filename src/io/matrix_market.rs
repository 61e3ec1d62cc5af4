//! MatrixMarket files (NIST's exchange format): a sparse matrix as `coordinate real general`, a
//! vector as `array real general` with one column, readable by scipy, PETSc, MUMPS drivers and
//! Matlab. Written directly: the format is a header and one line per entry.

use super::{write_atomic, OutputError};
use fdfsi_fem::sparse::CscMatrix;
use std::fmt::Write;
use std::path::Path;

/// Writes `a` (every stored entry, 1-based indices, 17 significant digits).
pub fn write_matrix(path: &Path, a: &CscMatrix<'_>) -> Result<(), OutputError> {
    let p = a.pattern;
    let mut text = String::with_capacity(40 * p.nnz() + 100);
    text.push_str("%%MatrixMarket matrix coordinate real general\n% written by fdfsi\n");
    let _ = writeln!(text, "{} {} {}", p.n, p.n, p.nnz());
    for j in 0..p.n {
        for k in p.col_ptr[j]..p.col_ptr[j + 1] {
            let _ = writeln!(text, "{} {} {:.17e}", p.row_idx[k] + 1, j + 1, a.values[k]);
        }
    }
    write_atomic(path, text.as_bytes())
}

/// Writes `v` as an `n x 1` array.
pub fn write_vector(path: &Path, v: &[f64]) -> Result<(), OutputError> {
    let mut text = String::with_capacity(26 * v.len() + 100);
    text.push_str("%%MatrixMarket matrix array real general\n% written by fdfsi\n");
    let _ = writeln!(text, "{} 1", v.len());
    for x in v {
        let _ = writeln!(text, "{x:.17e}");
    }
    write_atomic(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use fdfsi_fem::sparse::Pattern;

    #[test]
    fn writes_a_small_matrix_and_vector() {
        let p = Pattern::from_cells(2, 1, |_, b| {
            b.clear();
            b.extend([0, 1]);
        });
        let a = CscMatrix { pattern: &p, values: vec![2.0, -1.0, -1.0, 2.0] };
        let dir = tempfile::tempdir().unwrap();
        write_matrix(&dir.path().join("a.mtx"), &a).unwrap();
        write_vector(&dir.path().join("b.mtx"), &[1.0, 0.5]).unwrap();
        let text = std::fs::read_to_string(dir.path().join("a.mtx")).unwrap();
        let lines: Vec<&str> = text.lines().filter(|l| !l.starts_with('%')).collect();
        assert_eq!(lines[0], "2 2 4");
        assert_eq!(lines[2], "2 1 -1.00000000000000000e0");
        let b = std::fs::read_to_string(dir.path().join("b.mtx")).unwrap();
        assert!(b.lines().nth(2) == Some("2 1") && b.ends_with("5.00000000000000000e-1\n"), "{b}");
    }
}
