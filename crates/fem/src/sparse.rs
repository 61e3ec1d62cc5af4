//! Sparsity pattern, matrix values and parallel assembly.
//!
//! The pattern (symbolic) and the values (numeric) are separate objects: the [`Pattern`] is
//! built once per mesh from the cell dof lists and keeps every structural entry, zero or not, so a
//! sparse LU can compute its symbolic factorisation once and only refactor numerically.
//!
//! Storage is compressed sparse *column* (CSC), the layout faer's sparse LU reads without a copy.
//! Finite-element coupling is structurally symmetric (cell `c` couples all its dofs with each
//! other), so the pattern of `A` equals that of `A^T`.
//!
//! Assembly runs in parallel over cells with a colouring: cells of one colour share no vertex,
//! hence no dof, so they write disjoint matrix entries and the threads of one colour never touch
//! the same memory ([`assemble`]).

use rayon::prelude::*;

/// A CSC sparsity pattern with sorted row indices in each column.
#[derive(Clone, Debug)]
pub struct Pattern {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
}

/// The fewest columns [`Pattern::from_cells`] builds into one vector: 6.1e6 entries, 49 MB, in
/// 3D (P2+/P1disc, 93 per column), above the largest size below which the allocator may keep
/// freed memory (glibc's mmap threshold rises up to 32 MiB).
const MIN_CHUNK: usize = 1 << 16;

/// The cells around each dof (or vertex), as a CSR map: dof `d`'s cells, in increasing order,
/// are [`DofCells::of`]`(d)`.
pub struct DofCells {
    start: Vec<usize>,
    cells: Vec<usize>,
}

impl DofCells {
    /// The map of `n` dofs from the dofs of `num_cells` cells (`cell_dofs(c, out)`).
    pub fn new<F>(n: usize, num_cells: usize, cell_dofs: &F) -> Self
    where
        F: Fn(usize, &mut Vec<usize>),
    {
        let mut start = vec![0usize; n + 1];
        let mut buf = Vec::new();
        for c in 0..num_cells {
            cell_dofs(c, &mut buf);
            for &d in &buf {
                start[d + 1] += 1;
            }
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut cells = vec![0usize; start[n]];
        for c in 0..num_cells {
            cell_dofs(c, &mut buf);
            for &d in &buf {
                cells[fill[d]] = c;
                fill[d] += 1;
            }
        }
        DofCells { start, cells }
    }

    /// The cells around dof `d`.
    pub fn of(&self, d: usize) -> &[usize] {
        &self.cells[self.start[d]..self.start[d + 1]]
    }

    /// Column `j` of [`Pattern::from_cells`]'s pattern into `column`: the union of the dofs of
    /// the cells around dof `j`, sorted (`buf` is scratch); `[j]` alone for a dof of no cell
    /// (its diagonal).
    pub fn column_into<F>(&self, j: usize, cell_dofs: &F, buf: &mut Vec<usize>, column: &mut Vec<usize>)
    where
        F: Fn(usize, &mut Vec<usize>),
    {
        column.clear();
        for &c in self.of(j) {
            cell_dofs(c, buf);
            column.extend_from_slice(buf);
        }
        column.sort_unstable();
        column.dedup();
        if column.is_empty() {
            column.push(j);
        }
    }
}

impl Pattern {
    /// Pattern of a matrix in which the dofs of every cell are coupled with each other.
    /// `cell_dofs(c)` returns the global dofs of cell `c`.
    pub fn from_cells<F>(n: usize, num_cells: usize, cell_dofs: F) -> Self
    where
        F: Fn(usize, &mut Vec<usize>) + Sync,
    {
        let dof_cells = DofCells::new(n, num_cells, &cell_dofs);
        // Columns in chunks, each chunk's one after another into one vector, then the chunks
        // into `row_idx`. (A vector per column would keep its capacity from before the
        // deduplication, about 7 times the column, and the allocator keeps such small blocks
        // resident after they are freed: 0.5 GB at 434 259 unknowns. A chunk's vector is large,
        // tens of MB, given back when freed.)
        let chunk = n.div_ceil(8 * rayon::current_num_threads()).max(MIN_CHUNK);
        let chunks: Vec<(Vec<usize>, Vec<usize>)> = (0..n.div_ceil(chunk))
            .into_par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |(buf, rows), k| {
                    let (mut lengths, mut entries) = (Vec::with_capacity(chunk), Vec::new());
                    for j in k * chunk..((k + 1) * chunk).min(n) {
                        dof_cells.column_into(j, &cell_dofs, buf, rows);
                        lengths.push(rows.len());
                        entries.extend_from_slice(rows);
                    }
                    (lengths, entries)
                },
            )
            .collect();
        let mut col_ptr = Vec::with_capacity(n + 1);
        col_ptr.push(0);
        for len in chunks.iter().flat_map(|(lengths, _)| lengths) {
            col_ptr.push(col_ptr.last().copied().unwrap_or(0) + len);
        }
        let mut row_idx = Vec::with_capacity(col_ptr[n]);
        for (_, entries) in chunks {
            row_idx.extend_from_slice(&entries);
        }
        Pattern { n, col_ptr, row_idx }
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Position of entry `(row, col)` in the value array, if it is in the pattern.
    #[inline]
    pub fn find(&self, row: usize, col: usize) -> Option<usize> {
        let (a, b) = (self.col_ptr[col], self.col_ptr[col + 1]);
        self.row_idx[a..b].binary_search(&row).ok().map(|k| a + k)
    }
}

/// Values on a [`Pattern`]: a square sparse matrix in CSC storage.
#[derive(Clone, Debug)]
pub struct CscMatrix<'p> {
    pub pattern: &'p Pattern,
    pub values: Vec<f64>,
}

impl<'p> CscMatrix<'p> {
    /// All-zero matrix on `pattern`.
    pub fn zeros(pattern: &'p Pattern) -> Self {
        CscMatrix { pattern, values: vec![0.0; pattern.nnz()] }
    }
    /// `y = A x`.
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        let p = self.pattern;
        for j in 0..p.n {
            let xj = x[j];
            if xj != 0.0 {
                for k in p.col_ptr[j]..p.col_ptr[j + 1] {
                    y[p.row_idx[k]] += self.values[k] * xj;
                }
            }
        }
    }
    /// Entry `(row, col)`, zero when outside the pattern.
    pub fn get(&self, row: usize, col: usize) -> f64 {
        self.pattern.find(row, col).map(|k| self.values[k]).unwrap_or(0.0)
    }
}

/// A colouring of the cells such that two cells of one colour share no vertex.
#[derive(Clone, Debug)]
pub struct Colouring {
    /// Cells of each colour.
    pub colours: Vec<Vec<usize>>,
}

impl Colouring {
    /// Greedy colouring; `cell_vertices(c)` lists the vertices of cell `c`.
    pub fn greedy<'a, F>(num_vertices: usize, num_cells: usize, cell_vertices: F) -> Self
    where
        F: Fn(usize) -> &'a [usize],
    {
        let vertex_cells = DofCells::new(num_vertices, num_cells, &|c, out: &mut Vec<usize>| {
            out.clear();
            out.extend_from_slice(cell_vertices(c));
        });
        let mut colour = vec![usize::MAX; num_cells];
        let mut stamp: Vec<usize> = Vec::new(); // stamp[k] == c + 1: colour k is taken for cell c
        let mut colours: Vec<Vec<usize>> = Vec::new();
        for c in 0..num_cells {
            for &v in cell_vertices(c) {
                for &other in vertex_cells.of(v) {
                    let k = colour[other];
                    if k != usize::MAX {
                        stamp[k] = c + 1;
                    }
                }
            }
            let k = (0..stamp.len()).find(|&k| stamp[k] != c + 1).unwrap_or(stamp.len());
            if k == stamp.len() {
                stamp.push(0);
                colours.push(Vec::new());
            }
            colour[c] = k;
            colours[k].push(c);
        }
        Colouring { colours }
    }
}

/// Element matrix and vector of one cell, filled by a kernel: `ke` row-major `n x n`.
#[derive(Clone, Debug, Default)]
pub struct LocalSystem {
    pub dofs: Vec<usize>,
    pub ke: Vec<f64>,
    pub fe: Vec<f64>,
}

impl LocalSystem {
    /// Resizes to `n` dofs and zeroes the tensors.
    pub fn reset(&mut self, n: usize) {
        self.ke.clear();
        self.ke.resize(n * n, 0.0);
        self.fe.clear();
        self.fe.resize(n, 0.0);
    }
}

/// Raw pointers shared by the threads of one colour.
struct SharedOut {
    values: *mut f64,
    rhs: *mut f64,
}
// SAFETY: threads only write entries of rows owned by the dofs of their own cell; within one
// colour no two cells share a dof (see `Colouring`), so the writes are disjoint.
unsafe impl Sync for SharedOut {}
unsafe impl Send for SharedOut {}

/// Assembles `sum_c P_c^T ke_c P_c` into `matrix` and `sum_c P_c^T fe_c` into `rhs`, in parallel
/// over the cells of each colour. `kernel(c, scratch, local)` fills `local.dofs`, `local.ke`,
/// `local.fe` for cell `c` (the loop stays visible in the caller's kernel; the kernel is pure).
/// Rows of dofs with `skip_row[dof] == true` are not assembled (constrained dofs).
///
/// Returns the first kernel error, if any.
pub fn assemble<S, E, K>(
    matrix: &mut CscMatrix<'_>,
    rhs: &mut [f64],
    colouring: &Colouring,
    skip_row: &[bool],
    make_scratch: impl Fn() -> S + Sync + Send,
    kernel: K,
) -> Result<(), E>
where
    E: Send,
    K: Fn(usize, &mut S, &mut LocalSystem) -> Result<(), E> + Sync,
{
    let pattern = matrix.pattern;
    let out = SharedOut { values: matrix.values.as_mut_ptr(), rhs: rhs.as_mut_ptr() };
    let out = &out;
    if rayon::current_num_threads() == 1 {
        // One thread: the cells in their own (mesh) order, so that neighbouring cells find their
        // shared columns in cache; the colours scatter them over the mesh (Schaefer-Turek 2D-1,
        // 16 000 P2+ triangles: assembly 0.14 s in colour order, 0.10 s in cell order). The sums
        // then differ from the threaded ones by round-off (another order of the same terms).
        let mut cells = colouring.colours.concat();
        cells.sort_unstable();
        let (mut scratch, mut local, mut order) = (make_scratch(), LocalSystem::default(), Vec::new());
        for c in cells {
            kernel(c, &mut scratch, &mut local)?;
            // SAFETY: one thread writes.
            unsafe { scatter(&local, &mut order, pattern, skip_row, out) };
        }
        return Ok(());
    }
    for cells in &colouring.colours {
        cells.par_iter().with_min_len(64).try_for_each_init(
            || (make_scratch(), LocalSystem::default(), Vec::new()),
            |(scratch, local, order), &c| -> Result<(), E> {
                kernel(c, scratch, local)?;
                // SAFETY: see `SharedOut`.
                unsafe { scatter(local, order, pattern, skip_row, out) };
                Ok(())
            },
        )?;
    }
    Ok(())
}

/// Adds one cell's `local` system into `out` (rows with `skip_row` left out).
///
/// Column by column, the cell's rows in ascending order (`order` is scratch): one forward walk
/// through each column's sorted row indices and values, where a binary search per entry took
/// most of the scatter's time.
///
/// # Safety
/// No other thread may write the rows of `local.dofs` meanwhile (see `SharedOut`).
unsafe fn scatter(local: &LocalSystem, order: &mut Vec<usize>, pattern: &Pattern, skip_row: &[bool], out: &SharedOut) {
    let n = local.dofs.len();
    for (i, &row) in local.dofs.iter().enumerate() {
        if !skip_row[row] {
            unsafe { *out.rhs.add(row) += local.fe[i] };
        }
    }
    order.clear();
    order.extend(0..n);
    order.sort_unstable_by_key(|&i| local.dofs[i]);
    for (j, &col) in local.dofs.iter().enumerate() {
        let start = pattern.col_ptr[col];
        let rows = &pattern.row_idx[start..pattern.col_ptr[col + 1]];
        let mut k = 0;
        for &i in order.iter() {
            let row = local.dofs[i];
            if skip_row[row] {
                continue;
            }
            while rows[k] < row {
                k += 1;
            }
            assert_eq!(rows[k], row, "cell dofs are in the pattern");
            // `rows[k] == row`: an entry of this column.
            unsafe { *out.values.add(start + k) += local.ke[i * n + j] };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pattern built by chunks of columns equals the union of the cells' dofs per column, on
    /// several chunks (a chain of 3 x 10^5 dofs), with unused dofs (their diagonal only), and on
    /// no dofs.
    #[test]
    fn pattern_from_cells_is_the_union_of_the_cells_dofs() {
        let n = 3 * MIN_CHUNK + 7;
        // Cells [i, i + 2, i + 5] for i in 0..n - 5, every 4th skipped: dofs 1, 2 and 3 mod 4
        // are used, some not at all (dof 4, 8, ... reached only by skipped cells).
        let cells: Vec<[usize; 3]> = (0..n - 5).filter(|i| i % 4 != 0).map(|i| [i + 5, i, i + 2]).collect();
        let p = Pattern::from_cells(n, cells.len(), |c, buf| {
            buf.clear();
            buf.extend_from_slice(&cells[c]);
        });
        let mut columns: Vec<std::collections::BTreeSet<usize>> = vec![Default::default(); n];
        for cell in &cells {
            for &j in cell {
                columns[j].extend(cell);
            }
        }
        let unused = columns.iter().filter(|c| c.is_empty()).count();
        assert!(unused > 0);
        for (j, column) in columns.iter_mut().enumerate() {
            if column.is_empty() {
                column.insert(j);
            }
        }
        assert_eq!(p.col_ptr.len(), n + 1);
        for (j, column) in columns.iter().enumerate() {
            assert!(p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].iter().eq(column.iter()), "column {j}");
        }
        let empty = Pattern::from_cells(0, 0, |_, buf| buf.clear());
        assert_eq!((empty.nnz(), &empty.col_ptr[..]), (0, &[0][..]));
    }

    #[test]
    fn pattern_and_assembly_of_a_1d_chain() {
        // Cells [i, i+1] for i in 0..5: tridiagonal.
        let n = 6;
        let cells: Vec<[usize; 2]> = (0..5).map(|i| [i, i + 1]).collect();
        let p = Pattern::from_cells(n, 5, |c, buf| {
            buf.clear();
            buf.extend_from_slice(&cells[c]);
        });
        assert_eq!(p.nnz(), 6 + 2 * 5);
        let col = Colouring::greedy(n, 5, |c| &cells[c][..]);
        assert_eq!(col.colours.len(), 2);
        let mut m = CscMatrix::zeros(&p);
        let mut rhs = vec![0.0; n];
        let skip = vec![false; n];
        assemble(
            &mut m,
            &mut rhs,
            &col,
            &skip,
            || (),
            |c, _, l: &mut LocalSystem| -> Result<(), ()> {
                l.dofs.clear();
                l.dofs.extend_from_slice(&cells[c]);
                l.reset(2);
                l.ke.copy_from_slice(&[1.0, -1.0, -1.0, 1.0]);
                l.fe.copy_from_slice(&[0.5, 0.5]);
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(m.get(0, 0), 1.0);
        assert_eq!(m.get(2, 2), 2.0);
        assert_eq!(m.get(2, 3), -1.0);
        assert_eq!(m.get(0, 3), 0.0);
        assert_eq!(rhs, vec![0.5, 1.0, 1.0, 1.0, 1.0, 0.5]);
        let mut y = vec![0.0; n];
        m.mul_vec(&[1.0; 6], &mut y);
        assert!(y.iter().all(|v| v.abs() < 1e-15));
    }
}
