//! Helpers shared by the integration tests (`mod common;`).

use fdfsi::solve::partition::Partition;
use fdfsi_fem::sparse::{CscMatrix, RowMatrix};

/// Checks that the held rows `a` and `rhs_rows` of `partition` (in its numbering) are those
/// rows of the whole system `k`, `rhs` bit for bit; returns the number of entries held.
pub fn same_rows(partition: &Partition, a: &RowMatrix<'_>, rhs_rows: &[f64], k: &CscMatrix<'_>, rhs: &[f64], label: &str) -> usize {
    let (numbering, rows) = (partition.numbering(), partition.rows());
    for p in rows.clone() {
        let i = numbering.to_fdfsi(p);
        assert_eq!(rhs_rows[p - rows.start].to_bits(), rhs[i].to_bits(), "{label}: rhs of unknown {i}");
        let (cols, start) = a.pattern.row(p);
        for (e, &q) in cols.iter().enumerate() {
            let j = numbering.to_fdfsi(q as usize);
            assert_eq!(a.values[start + e].to_bits(), k.get(i, j).to_bits(), "{label}: entry ({i}, {j})");
        }
    }
    a.pattern.nnz()
}
