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
//!
//! For a partitioned assembly (each MPI rank its own rows), [`RowPattern`] and [`RowMatrix`] hold
//! some consecutive rows in compressed sparse *row* storage, and [`assemble_rows`] assembles
//! them from the cells that touch them; [`assemble_residual`] assembles a right-hand side alone.

use rayon::prelude::*;
use std::ops::Range;

/// A CSC sparsity pattern with sorted row indices in each column.
#[derive(Clone, Debug)]
pub struct Pattern {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
}

/// The fewest columns (or rows) [`Pattern::from_cells`] (or [`RowPattern::from_cells`]) builds
/// into one vector: 6.1e6 entries, 49 MB, in
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
        self.union_into(j, cell_dofs, buf, column);
        if column.is_empty() {
            column.push(j);
        }
    }

    /// The sorted union of the dofs of the cells around `d` into `out` (empty for a dof of no
    /// cell; `buf` is scratch).
    fn union_into<F>(&self, d: usize, cell_dofs: &F, buf: &mut Vec<usize>, out: &mut Vec<usize>)
    where
        F: Fn(usize, &mut Vec<usize>),
    {
        out.clear();
        for &c in self.of(d) {
            cell_dofs(c, buf);
            out.extend_from_slice(buf);
        }
        out.sort_unstable();
        out.dedup();
    }
}

/// The compressed lists `0..n` that `list(j, buf, out)` writes (each into `out`; `buf` is
/// scratch), as start offsets (`n + 1`) and entries converted by `convert`, built in parallel by
/// chunks of lists, each chunk's lists one after another into one vector. (A vector per list
/// would keep its capacity from before a deduplication, about 7 times the list, and the allocator
/// keeps such small blocks resident after they are freed: 0.5 GB at 434 259 unknowns. A chunk's
/// vector is large, tens of MB, given back when freed.)
fn compressed_lists<T, L>(n: usize, list: L, convert: impl Fn(usize) -> T) -> (Vec<usize>, Vec<T>)
where
    T: Send,
    L: Fn(usize, &mut Vec<usize>, &mut Vec<usize>) + Sync,
{
    let chunk = n.div_ceil(8 * rayon::current_num_threads()).max(MIN_CHUNK);
    let chunks: Vec<(Vec<usize>, Vec<usize>)> = (0..n.div_ceil(chunk))
        .into_par_iter()
        .map_init(
            || (Vec::new(), Vec::new()),
            |(buf, out), k| {
                let (mut lengths, mut entries) = (Vec::with_capacity(chunk), Vec::new());
                for j in k * chunk..((k + 1) * chunk).min(n) {
                    list(j, buf, out);
                    lengths.push(out.len());
                    entries.extend_from_slice(out);
                }
                (lengths, entries)
            },
        )
        .collect();
    let mut start = Vec::with_capacity(n + 1);
    start.push(0);
    for len in chunks.iter().flat_map(|(lengths, _)| lengths) {
        start.push(start.last().copied().unwrap_or(0) + len);
    }
    let mut entries = Vec::with_capacity(start[n]);
    for (_, chunk_entries) in chunks {
        entries.extend(chunk_entries.into_iter().map(&convert));
    }
    (start, entries)
}

impl Pattern {
    /// Pattern of a matrix in which the dofs of every cell are coupled with each other.
    /// `cell_dofs(c)` returns the global dofs of cell `c`.
    pub fn from_cells<F>(n: usize, num_cells: usize, cell_dofs: F) -> Self
    where
        F: Fn(usize, &mut Vec<usize>) + Sync,
    {
        let dof_cells = DofCells::new(n, num_cells, &cell_dofs);
        let (col_ptr, row_idx) = compressed_lists(n, |j, buf, column| dof_cells.column_into(j, &cell_dofs, buf, column), |i| i);
        Pattern { n, col_ptr, row_idx }
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// The number of entries of [`Pattern::from_cells`]'s pattern, counted column by column
    /// without storing it (memory: the dof-to-cells map).
    pub fn count_from_cells<F>(n: usize, num_cells: usize, cell_dofs: F) -> usize
    where
        F: Fn(usize, &mut Vec<usize>) + Sync,
    {
        let dof_cells = DofCells::new(n, num_cells, &cell_dofs);
        (0..n)
            .into_par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |(buf, column), j| {
                    dof_cells.column_into(j, &cell_dofs, buf, column);
                    column.len()
                },
            )
            .sum()
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

/// Some consecutive rows of a pattern like [`Pattern::from_cells`]'s, in compressed sparse *row*
/// storage with sorted column indices: the rows one MPI rank assembles and owns (a partitioned
/// assembly; the numbering is the partition's, in which each rank's rows are consecutive). Column
/// indices are `u32` (half the memory of `usize`).
#[derive(Clone, Debug)]
pub struct RowPattern {
    /// The number of unknowns (of columns).
    pub n: usize,
    /// The rows held, `row_ptr.len() - 1` of them.
    pub rows: Range<usize>,
    /// Row `rows.start + i` has the columns `cols[row_ptr[i]..row_ptr[i + 1]]`, increasing.
    pub row_ptr: Vec<usize>,
    pub cols: Vec<u32>,
}

impl RowPattern {
    /// The `rows` of the pattern of `n` unknowns in which the dofs of every cell are coupled
    /// with each other: row `p` has the union of the dofs of the cells around `p`, or `p` alone
    /// for a dof of no cell (as [`Pattern::from_cells`]'s column `p`). `cells` must hold every
    /// cell with a dof in `rows` (others are allowed); `cell_dofs(c, out)` lists cell `c`'s dofs.
    ///
    /// # Panics
    /// If `n` exceeds the `u32` range.
    pub fn from_cells<F>(n: usize, rows: Range<usize>, cells: &[usize], cell_dofs: F) -> Self
    where
        F: Fn(usize, &mut Vec<usize>) + Sync,
    {
        assert!(u32::try_from(n).is_ok(), "{n} unknowns exceed the u32 column indices of a RowPattern");
        let lo = rows.start;
        let cell = |k: usize, out: &mut Vec<usize>| cell_dofs(cells[k], out);
        let row_cells = DofCells::new(rows.len(), cells.len(), &|k, out: &mut Vec<usize>| {
            cell(k, out);
            out.retain(|d| rows.contains(d));
            out.iter_mut().for_each(|d| *d -= lo);
        });
        let (row_ptr, cols) = compressed_lists(
            rows.len(),
            |i, buf, row| {
                row_cells.union_into(i, &cell, buf, row);
                if row.is_empty() {
                    row.push(lo + i);
                }
            },
            |j| j as u32,
        );
        RowPattern { n, rows, row_ptr, cols }
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.cols.len()
    }

    /// The columns of row `row` (in [`RowPattern::rows`]) and their first position in the value
    /// array.
    #[inline]
    pub fn row(&self, row: usize) -> (&[u32], usize) {
        let i = row - self.rows.start;
        let start = self.row_ptr[i];
        (&self.cols[start..self.row_ptr[i + 1]], start)
    }

    /// Position of entry `(row, col)` in the value array, if `row` is held and the entry is in
    /// the pattern.
    pub fn find(&self, row: usize, col: usize) -> Option<usize> {
        if !self.rows.contains(&row) {
            return None;
        }
        let (cols, start) = self.row(row);
        cols.binary_search(&u32::try_from(col).ok()?).ok().map(|k| start + k)
    }
}

/// Values on a [`RowPattern`]: the held rows of a square sparse matrix.
#[derive(Clone, Debug)]
pub struct RowMatrix<'p> {
    pub pattern: &'p RowPattern,
    pub values: Vec<f64>,
}

impl<'p> RowMatrix<'p> {
    /// All-zero rows on `pattern`.
    pub fn zeros(pattern: &'p RowPattern) -> Self {
        RowMatrix { pattern, values: vec![0.0; pattern.nnz()] }
    }

    /// `y = A x` in the held rows: `x` of all `n` unknowns, `y` of the held rows.
    pub fn mul_rows(&self, x: &[f64], y: &mut [f64]) {
        let p = self.pattern;
        assert!(x.len() == p.n && y.len() == p.rows.len(), "x of {} unknowns, y of {} rows", p.n, p.rows.len());
        for (i, yi) in y.iter_mut().enumerate() {
            let range = p.row_ptr[i]..p.row_ptr[i + 1];
            *yi = p.cols[range.clone()].iter().zip(&self.values[range]).map(|(&j, v)| v * x[j as usize]).sum();
        }
    }
}

/// A colouring of the cells such that two cells of one colour share no vertex.
#[derive(Clone, Debug)]
pub struct Colouring {
    /// Cells of each colour (private: the parallel assemblies write the cells of one colour at
    /// once, so a colouring is made only by [`Colouring::greedy`] and restricted from one).
    colours: Vec<Vec<usize>>,
}

impl Colouring {
    /// The cells of each colour.
    pub fn colours(&self) -> &[Vec<usize>] {
        &self.colours
    }

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

    /// The cells of this colouring that `keep` keeps, in their colours (the colours and the
    /// order within each kept): an assembly over them sums each entry in the order of an
    /// assembly over all cells.
    pub fn restricted(&self, keep: impl Fn(usize) -> bool) -> Colouring {
        Colouring { colours: self.colours.iter().map(|cells| cells.iter().copied().filter(|&c| keep(c)).collect()).collect() }
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

/// Scratch of one thread's scatter: the cell's dofs in column order, and their indices in the
/// matrix's numbering.
#[derive(Default)]
struct ScatterScratch {
    order: Vec<usize>,
    global: Vec<usize>,
}

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
    assert!(matrix.values.len() == pattern.nnz() && rhs.len() == pattern.n, "a matrix and a right-hand side of the pattern");
    let out = SharedOut { values: matrix.values.as_mut_ptr(), rhs: rhs.as_mut_ptr() };
    // SAFETY: `for_each_cell` writes the cells of one colour at once only, which share no row.
    for_each_cell(colouring, make_scratch, kernel, |local, scratch| unsafe { scatter(local, &mut scratch.order, pattern, skip_row, &out) })
}

/// [`assemble`] into the held rows of a partitioned matrix: `matrix` and `rhs` (the held rows,
/// `matrix.pattern.rows`) in the partition's numbering, to which `to_global` maps the kernel's
/// dofs; `skip_row` is by the kernel's dofs. The cells of `colouring` must be those with a dof
/// in the held rows ([`Colouring::restricted`]): then each held entry is the sum of the same
/// terms in the same order as in [`assemble`] over all cells, so the held rows equal that
/// assembly's bit for bit.
///
/// # Safety
/// `to_global` must be one-to-one on the kernel's dofs: the cells of one colour are scattered by
/// several threads at once, each into the rows of its own dofs, which a map that sends two dofs
/// to one row would make the same memory.
pub unsafe fn assemble_rows<S, E, K>(
    matrix: &mut RowMatrix<'_>,
    rhs: &mut [f64],
    colouring: &Colouring,
    skip_row: &[bool],
    to_global: &(dyn Fn(usize) -> usize + Sync),
    make_scratch: impl Fn() -> S + Sync + Send,
    kernel: K,
) -> Result<(), E>
where
    E: Send,
    K: Fn(usize, &mut S, &mut LocalSystem) -> Result<(), E> + Sync,
{
    let pattern = matrix.pattern;
    assert!(matrix.values.len() == pattern.nnz() && rhs.len() == pattern.rows.len(), "a matrix and a right-hand side of the held rows");
    let out = SharedOut { values: matrix.values.as_mut_ptr(), rhs: rhs.as_mut_ptr() };
    // SAFETY: as in `assemble`, `to_global` one-to-one (the caller's promise).
    for_each_cell(colouring, make_scratch, kernel, |local, scratch| unsafe { scatter_rows(local, scratch, pattern, skip_row, to_global, &out) })
}

/// [`assemble`]'s right-hand side alone (the kernel's `ke` unused): `rhs` equals that
/// assembly's, bit for bit.
pub fn assemble_residual<S, E, K>(
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
    let n = rhs.len();
    let out = &SharedOut { values: std::ptr::null_mut(), rhs: rhs.as_mut_ptr() };
    for_each_cell(colouring, make_scratch, kernel, |local, _| {
        for (i, &row) in local.dofs.iter().enumerate() {
            assert!(row < n, "dof {row} of {n}");
            if !skip_row[row] {
                // SAFETY: as in `assemble`; `row` is in `rhs`.
                unsafe { *out.rhs.add(row) += local.fe[i] };
            }
        }
    })
}

/// Where a discretisation assembles its part of a system `K dx = rhs`, addressed by its own
/// unknowns: all of it ([`WholeSystem`]), the held rows of a partitioned one ([`HeldRows`]), or
/// the right-hand side alone ([`ResidualOnly`]). Terms of rows a target does not hold, and
/// matrix terms of [`ResidualOnly`], are dropped; the terms it keeps are summed in the order
/// they are added, so one assembly written against this trait gives every target the same
/// bits in the entries they share.
pub trait SystemTarget {
    /// The cells of `colouring` assembled as [`assemble`] does (rows with `skip_row` left out).
    fn add_cells<S, E, K>(
        &mut self,
        colouring: &Colouring,
        skip_row: &[bool],
        make_scratch: impl Fn() -> S + Sync + Send,
        kernel: K,
    ) -> Result<(), E>
    where
        E: Send,
        K: Fn(usize, &mut S, &mut LocalSystem) -> Result<(), E> + Sync;
    /// `rhs[row] += v`.
    fn add_rhs(&mut self, row: usize, v: f64);
    /// `K[row][col] += v`.
    ///
    /// # Panics
    /// If a held entry is not in the target's pattern.
    fn add_matrix(&mut self, row: usize, col: usize, v: f64);
    /// The diagonal entry of row `row` becomes 1 and its right-hand side 0 (the assembler
    /// leaves the row's other terms out).
    fn identity_row(&mut self, row: usize);
    /// Whether the target holds row `row` (terms of other rows are dropped).
    fn holds(&self, row: usize) -> bool {
        let _ = row;
        true
    }
    /// Row operations on the rows `rows` of one node, whose columns are the same (the cells
    /// that couple a node list all its unknowns). With `n = rows.len()` and `Q = q` (`n x n`,
    /// row-major), row `rows[i]` becomes
    ///
    /// ```text
    /// i <  m:  sum_l Q[i][l] (row rows[l])          matrix and right-hand side alike
    /// i >= m:  sum_l Q[i][l] dx[rows[l]] = 0         its other entries 0, right-hand side 0
    /// ```
    ///
    /// (`m = combined`): combinations of the rows, then constraints on the node's unknowns. A
    /// target that holds none of the rows leaves them; one that holds some must hold all.
    ///
    /// # Panics
    /// If the rows do not share their columns, `q` is not `n x n` or `combined > n`.
    fn combine_rows(&mut self, rows: &[usize], q: &[f64], combined: usize);
}

/// The new values of the entries `v` (one per row of `rows`, in their order) of one column
/// `col` under [`SystemTarget::combine_rows`], into `out`.
fn combined_entries(rows: &[usize], q: &[f64], combined: usize, col: Option<usize>, v: &[f64], out: &mut [f64]) {
    let n = rows.len();
    for i in 0..n {
        let qi = &q[i * n..(i + 1) * n];
        out[i] = if i < combined {
            qi.iter().zip(v).map(|(a, b)| a * b).sum()
        } else {
            col.and_then(|c| rows.iter().position(|&r| r == c)).map_or(0.0, |l| qi[l])
        };
    }
}

/// Checks the arguments of [`SystemTarget::combine_rows`].
fn check_combination(rows: &[usize], q: &[f64], combined: usize) {
    assert!(
        !rows.is_empty() && q.len() == rows.len() * rows.len() && combined <= rows.len(),
        "rows {rows:?}, {} coefficients, {combined} combined",
        q.len()
    );
}

/// The whole system: a matrix on a [`Pattern`] of the assembler's unknowns and its right-hand
/// side.
pub struct WholeSystem<'a, 'p> {
    pub k: &'a mut CscMatrix<'p>,
    pub rhs: &'a mut [f64],
}

impl SystemTarget for WholeSystem<'_, '_> {
    fn add_cells<S, E, K>(&mut self, colouring: &Colouring, skip_row: &[bool], make_scratch: impl Fn() -> S + Sync + Send, kernel: K) -> Result<(), E>
    where
        E: Send,
        K: Fn(usize, &mut S, &mut LocalSystem) -> Result<(), E> + Sync,
    {
        assemble(self.k, self.rhs, colouring, skip_row, make_scratch, kernel)
    }
    fn add_rhs(&mut self, row: usize, v: f64) {
        self.rhs[row] += v;
    }
    fn add_matrix(&mut self, row: usize, col: usize, v: f64) {
        self.k.values[self.k.pattern.find(row, col).expect("the entry is in the pattern")] += v;
    }
    fn identity_row(&mut self, row: usize) {
        self.k.values[self.k.pattern.find(row, row).expect("the diagonal is in the pattern")] = 1.0;
        self.rhs[row] = 0.0;
    }
    /// The pattern is structurally symmetric: row `r`'s columns are column `r`'s rows.
    fn combine_rows(&mut self, rows: &[usize], q: &[f64], combined: usize) {
        check_combination(rows, q, combined);
        let n = rows.len();
        let p = self.k.pattern;
        let column = |j: usize| &p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]];
        let cols = column(rows[0]);
        for &r in &rows[1..] {
            assert_eq!(column(r), cols, "the rows {rows:?} of one node share their columns");
        }
        let (mut pos, mut v, mut out) = (vec![0; n], vec![0.0; n], vec![0.0; n]);
        for &j in cols {
            for (i, &r) in rows.iter().enumerate() {
                pos[i] = p.col_ptr[j] + column(j).binary_search(&r).expect("a symmetric pattern");
                v[i] = self.k.values[pos[i]];
            }
            combined_entries(rows, q, combined, Some(j), &v, &mut out);
            for i in 0..n {
                self.k.values[pos[i]] = out[i];
            }
        }
        let v: Vec<f64> = rows.iter().map(|&r| self.rhs[r]).collect();
        combined_entries(rows, q, combined, None, &v, &mut out);
        for (i, &r) in rows.iter().enumerate() {
            self.rhs[r] = out[i];
        }
    }
}

/// The held rows of a partitioned system ([`assemble_rows`]): the matrix's and right-hand
/// side's rows `k.pattern.rows` in the partition's numbering, to which `to_global` maps the
/// assembler's unknowns.
pub struct HeldRows<'a, 'p> {
    k: &'a mut RowMatrix<'p>,
    rhs: &'a mut [f64],
    to_global: &'a (dyn Fn(usize) -> usize + Sync),
}

impl<'a, 'p> HeldRows<'a, 'p> {
    /// The held rows `k` and `rhs` (of `k.pattern.rows`), the assembler's unknown `d` being
    /// `to_global(d)` in them.
    ///
    /// # Safety
    /// `to_global` must be one-to-one (see [`assemble_rows`]).
    pub unsafe fn new(k: &'a mut RowMatrix<'p>, rhs: &'a mut [f64], to_global: &'a (dyn Fn(usize) -> usize + Sync)) -> Self {
        assert_eq!(rhs.len(), k.pattern.rows.len(), "a right-hand side of the held rows");
        HeldRows { k, rhs, to_global }
    }

    /// The row of the assembler's unknown `row` in the partition's numbering, if held.
    fn held(&self, row: usize) -> Option<usize> {
        let p = (self.to_global)(row);
        self.k.pattern.rows.contains(&p).then_some(p)
    }
}

impl SystemTarget for HeldRows<'_, '_> {
    fn add_cells<S, E, K>(&mut self, colouring: &Colouring, skip_row: &[bool], make_scratch: impl Fn() -> S + Sync + Send, kernel: K) -> Result<(), E>
    where
        E: Send,
        K: Fn(usize, &mut S, &mut LocalSystem) -> Result<(), E> + Sync,
    {
        // SAFETY: `to_global` is one-to-one (`HeldRows::new`'s contract).
        unsafe { assemble_rows(self.k, self.rhs, colouring, skip_row, self.to_global, make_scratch, kernel) }
    }
    fn add_rhs(&mut self, row: usize, v: f64) {
        if let Some(p) = self.held(row) {
            self.rhs[p - self.k.pattern.rows.start] += v;
        }
    }
    fn add_matrix(&mut self, row: usize, col: usize, v: f64) {
        if let Some(p) = self.held(row) {
            let q = (self.to_global)(col);
            self.k.values[self.k.pattern.find(p, q).expect("the entry is in the rows' pattern")] += v;
        }
    }
    fn identity_row(&mut self, row: usize) {
        if let Some(p) = self.held(row) {
            self.k.values[self.k.pattern.find(p, p).expect("the diagonal is in the rows' pattern")] = 1.0;
            self.rhs[p - self.k.pattern.rows.start] = 0.0;
        }
    }
    fn holds(&self, row: usize) -> bool {
        self.held(row).is_some()
    }
    fn combine_rows(&mut self, rows: &[usize], q: &[f64], combined: usize) {
        check_combination(rows, q, combined);
        let held: Vec<Option<usize>> = rows.iter().map(|&r| self.held(r)).collect();
        if held.iter().all(Option::is_none) {
            return;
        }
        let global: Vec<usize> = held.iter().map(|p| p.expect("the rows of one node are held together (a partition keeps nodes whole)")).collect();
        let n = rows.len();
        let p = self.k.pattern;
        let (cols, _) = p.row(global[0]);
        let starts: Vec<usize> = global
            .iter()
            .map(|&g| {
                let (other, start) = p.row(g);
                assert_eq!(other, cols, "the rows {rows:?} of one node share their columns");
                start
            })
            .collect();
        // The constraints' columns in the held rows' numbering.
        let rows_global: Vec<usize> = rows.iter().map(|&r| (self.to_global)(r)).collect();
        let (mut v, mut out) = (vec![0.0; n], vec![0.0; n]);
        for (k, &col) in cols.iter().enumerate() {
            for i in 0..n {
                v[i] = self.k.values[starts[i] + k];
            }
            combined_entries(&rows_global, q, combined, Some(col as usize), &v, &mut out);
            for i in 0..n {
                self.k.values[starts[i] + k] = out[i];
            }
        }
        let lo = p.rows.start;
        let v: Vec<f64> = global.iter().map(|&g| self.rhs[g - lo]).collect();
        combined_entries(&rows_global, q, combined, None, &v, &mut out);
        for (i, &g) in global.iter().enumerate() {
            self.rhs[g - lo] = out[i];
        }
    }
}

/// The right-hand side alone ([`assemble_residual`]), of all the assembler's unknowns.
pub struct ResidualOnly<'a> {
    pub rhs: &'a mut [f64],
}

impl SystemTarget for ResidualOnly<'_> {
    fn add_cells<S, E, K>(&mut self, colouring: &Colouring, skip_row: &[bool], make_scratch: impl Fn() -> S + Sync + Send, kernel: K) -> Result<(), E>
    where
        E: Send,
        K: Fn(usize, &mut S, &mut LocalSystem) -> Result<(), E> + Sync,
    {
        assemble_residual(self.rhs, colouring, skip_row, make_scratch, kernel)
    }
    fn add_rhs(&mut self, row: usize, v: f64) {
        self.rhs[row] += v;
    }
    fn add_matrix(&mut self, _: usize, _: usize, _: f64) {}
    fn identity_row(&mut self, row: usize) {
        self.rhs[row] = 0.0;
    }
    fn combine_rows(&mut self, rows: &[usize], q: &[f64], combined: usize) {
        check_combination(rows, q, combined);
        let v: Vec<f64> = rows.iter().map(|&r| self.rhs[r]).collect();
        let mut out = vec![0.0; rows.len()];
        combined_entries(rows, q, combined, None, &v, &mut out);
        for (i, &r) in rows.iter().enumerate() {
            self.rhs[r] = out[i];
        }
    }
}

/// Runs `kernel` on every cell of `colouring` and `write`s each cell's system: in cell order on
/// one rayon thread, colour by colour in parallel on several (so `write` runs concurrently for
/// cells of one colour only, which share no dof). Returns the first kernel error, if any.
fn for_each_cell<S, E, K, W>(colouring: &Colouring, make_scratch: impl Fn() -> S + Sync + Send, kernel: K, write: W) -> Result<(), E>
where
    E: Send,
    K: Fn(usize, &mut S, &mut LocalSystem) -> Result<(), E> + Sync,
    W: Fn(&LocalSystem, &mut ScatterScratch) + Sync,
{
    if rayon::current_num_threads() == 1 {
        // One thread: the cells in their own (mesh) order, so that neighbouring cells find their
        // shared columns in cache; the colours scatter them over the mesh (Schaefer-Turek 2D-1,
        // 16 000 P2+ triangles: assembly 0.14 s in colour order, 0.10 s in cell order). The sums
        // then differ from the threaded ones by round-off (another order of the same terms).
        let mut cells = colouring.colours.concat();
        cells.sort_unstable();
        let (mut scratch, mut local, mut order) = (make_scratch(), LocalSystem::default(), ScatterScratch::default());
        for c in cells {
            kernel(c, &mut scratch, &mut local)?;
            write(&local, &mut order);
        }
        return Ok(());
    }
    for cells in &colouring.colours {
        cells.par_iter().with_min_len(64).try_for_each_init(
            || (make_scratch(), LocalSystem::default(), ScatterScratch::default()),
            |(scratch, local, order), &c| -> Result<(), E> {
                kernel(c, scratch, local)?;
                write(local, order);
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

/// Adds the held rows of one cell's `local` system into `out` (rows with `skip_row` left out):
/// [`scatter`] by rows, each held row's columns walked forward once, the cell's columns in
/// ascending order of the matrix's numbering (`to_global`).
///
/// # Safety
/// No other thread may write the rows of `local.dofs` meanwhile (see `SharedOut`).
unsafe fn scatter_rows(
    local: &LocalSystem,
    scratch: &mut ScatterScratch,
    pattern: &RowPattern,
    skip_row: &[bool],
    to_global: &(dyn Fn(usize) -> usize + Sync),
    out: &SharedOut,
) {
    let n = local.dofs.len();
    let ScatterScratch { order, global } = scratch;
    global.clear();
    global.extend(local.dofs.iter().map(|&d| to_global(d)));
    order.clear();
    order.extend(0..n);
    order.sort_unstable_by_key(|&j| global[j]);
    for (i, &dof) in local.dofs.iter().enumerate() {
        if skip_row[dof] || !pattern.rows.contains(&global[i]) {
            continue;
        }
        let (cols, start) = pattern.row(global[i]);
        unsafe { *out.rhs.add(global[i] - pattern.rows.start) += local.fe[i] };
        let mut k = 0;
        for &j in order.iter() {
            let col = global[j] as u32;
            while cols[k] < col {
                k += 1;
            }
            assert_eq!(cols[k], col, "cell dofs are in the pattern");
            unsafe { *out.values.add(start + k) += local.ke[i * n + j] };
        }
    }
}

/// Sorts the `(index, value)` entries of a sparse vector by index and sums the values of equal
/// indices into one entry each.
pub fn sum_duplicates(entries: &mut Vec<(usize, f64)>) {
    entries.sort_unstable_by_key(|&(i, _)| i);
    entries.dedup_by(|later, kept| {
        let same = later.0 == kept.0;
        if same {
            kept.1 += later.1;
        }
        same
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pattern built by chunks of columns equals the union of the cells' dofs per column, on
    /// several chunks (a chain of 3 x 10^5 dofs), with unused dofs (their diagonal only), and on
    /// no dofs.
    #[test]
    fn duplicates_sum_into_one_entry_each() {
        let mut v = vec![(3, 1.0), (1, 2.0), (3, 0.5), (0, 1.0), (1, -2.0)];
        sum_duplicates(&mut v);
        assert_eq!(v, vec![(0, 1.0), (1, 0.0), (3, 1.5)]);
    }

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
        let cell_dofs = |c: usize, buf: &mut Vec<usize>| {
            buf.clear();
            buf.extend_from_slice(&cells[c]);
        };
        assert_eq!(Pattern::count_from_cells(n, cells.len(), cell_dofs), p.nnz());
        for (j, column) in columns.iter().enumerate() {
            assert!(p.row_idx[p.col_ptr[j]..p.col_ptr[j + 1]].iter().eq(column.iter()), "column {j}");
        }
        let empty = Pattern::from_cells(0, 0, |_, buf| buf.clear());
        assert_eq!((empty.nnz(), &empty.col_ptr[..]), (0, &[0][..]));
    }

    /// Each rank's rows of a partitioned assembly ([`assemble_rows`] over the cells touching
    /// them, in a permuted numbering) are bit for bit the full assembly's rows, and they cover
    /// its pattern, for 1-3 ranks on one and on three threads: triangles with a dof per vertex
    /// and one per cell, some rows skipped, element values whose sums depend on their order.
    #[test]
    fn partitioned_rows_equal_the_full_assembly() {
        let mesh = crate::generate::rectangle_triangles(0.0, 1.0, 0.0, 1.0, 9, 7, crate::generate::DiagonalPattern::Alternating);
        let nv = mesh.points.len();
        let n = nv + mesh.num_cells();
        let cell_dofs = |c: usize, out: &mut Vec<usize>| {
            out.clear();
            out.extend_from_slice(mesh.cell_vertices(c));
            out.push(nv + c);
        };
        // A permutation of the dofs: the partition's numbering.
        let mut by_key: Vec<usize> = (0..n).collect();
        by_key.sort_by_key(|&i| (i * 7919) % 1009 * n + i);
        let mut to_global = vec![0; n];
        for (p, &i) in by_key.iter().enumerate() {
            to_global[i] = p;
        }
        let skip: Vec<bool> = (0..n).map(|i| i % 11 == 3).collect();
        let colouring = Colouring::greedy(nv, mesh.num_cells(), |c| mesh.cell_vertices(c));
        let kernel = |c: usize, _: &mut (), l: &mut LocalSystem| -> Result<(), ()> {
            cell_dofs(c, &mut l.dofs);
            let m = l.dofs.len();
            l.reset(m);
            for i in 0..m {
                l.fe[i] = ((c * 13 + i) as f64 * 0.71).sin() * 1e3;
                for j in 0..m {
                    l.ke[i * m + j] = ((c * 31 + i * 7 + j * 3) as f64 * 0.37).sin() * 10f64.powi((c % 5) as i32);
                }
            }
            Ok(())
        };
        let pattern = Pattern::from_cells(n, mesh.num_cells(), cell_dofs);
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let (mut full, mut full_rhs) = (CscMatrix::zeros(&pattern), vec![0.0; n]);
                assemble(&mut full, &mut full_rhs, &colouring, &skip, || (), kernel).unwrap();
                for ranks in 1..=3 {
                    let mut covered = 0;
                    for rank in 0..ranks {
                        let rows = n * rank / ranks..n * (rank + 1) / ranks;
                        let touches = |c: usize| {
                            let mut dofs = Vec::new();
                            cell_dofs(c, &mut dofs);
                            dofs.iter().any(|&d| rows.contains(&to_global[d]))
                        };
                        let cells: Vec<usize> = (0..mesh.num_cells()).filter(|&c| touches(c)).collect();
                        let global_dofs = |c: usize, out: &mut Vec<usize>| {
                            cell_dofs(c, out);
                            out.iter_mut().for_each(|d| *d = to_global[*d]);
                        };
                        let rp = RowPattern::from_cells(n, rows.clone(), &cells, global_dofs);
                        let (mut a, mut rhs) = (RowMatrix::zeros(&rp), vec![0.0; rows.len()]);
                        let restricted = colouring.restricted(|c| cells.binary_search(&c).is_ok());
                        // SAFETY: `to_global` is a permutation.
                        unsafe { assemble_rows(&mut a, &mut rhs, &restricted, &skip, &|d| to_global[d], || (), kernel) }.unwrap();
                        // `A x` in the held rows, `x` in the partition's numbering.
                        let x: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
                        let (mut y, mut y_rows) = (vec![0.0; n], vec![0.0; rows.len()]);
                        full.mul_vec(&x, &mut y);
                        let x_global: Vec<f64> = (0..n).map(|p| x[by_key[p]]).collect();
                        a.mul_rows(&x_global, &mut y_rows);
                        for p in rows.clone() {
                            assert!((y_rows[p - rows.start] - y[by_key[p]]).abs() <= 1e-12 * (1.0 + y[by_key[p]].abs()), "A x in row {p}");
                        }
                        for p in rows.clone() {
                            let i = by_key[p];
                            assert_eq!(rhs[p - rows.start].to_bits(), full_rhs[i].to_bits(), "rhs row {p}, {ranks} ranks, {threads} threads");
                            let (cols, start) = rp.row(p);
                            let mut expected: Vec<usize> = (0..n).filter(|&j| pattern.find(i, j).is_some()).map(|j| to_global[j]).collect();
                            expected.sort_unstable();
                            assert!(cols.iter().map(|&q| q as usize).eq(expected.iter().copied()), "row {p}'s columns");
                            for (k, &q) in cols.iter().enumerate() {
                                let v = full.get(i, by_key[q as usize]);
                                assert_eq!(a.values[start + k].to_bits(), v.to_bits(), "entry ({p}, {q}), {ranks} ranks, {threads} threads");
                            }
                            covered += cols.len();
                        }
                    }
                    assert_eq!(covered, pattern.nnz());
                }
            });
        }
    }

    /// [`SystemTarget::combine_rows`] on the rows of a node (two unknowns per vertex): the
    /// whole system's rows become the combinations and constraints a dense computation gives,
    /// and the held rows of two ranks in a permuted numbering equal them bit for bit; the
    /// right-hand side alone likewise.
    #[test]
    fn combined_rows_are_the_combinations_of_the_rows() {
        let mesh = crate::generate::rectangle_triangles(0.0, 1.0, 0.0, 1.0, 4, 3, crate::generate::DiagonalPattern::Alternating);
        let nv = mesh.points.len();
        let n = 2 * nv;
        let cell_dofs = |c: usize, out: &mut Vec<usize>| {
            out.clear();
            out.extend(mesh.cell_vertices(c).iter().flat_map(|&v| [2 * v, 2 * v + 1]));
        };
        let colouring = Colouring::greedy(nv, mesh.num_cells(), |c| mesh.cell_vertices(c));
        let kernel = |c: usize, _: &mut (), l: &mut LocalSystem| -> Result<(), ()> {
            cell_dofs(c, &mut l.dofs);
            let m = l.dofs.len();
            l.reset(m);
            for i in 0..m {
                l.fe[i] = ((c * 13 + i) as f64 * 0.71).sin();
                for j in 0..m {
                    l.ke[i * m + j] = ((c * 31 + i * 7 + j * 3) as f64 * 0.37).sin();
                }
            }
            Ok(())
        };
        let pattern = Pattern::from_cells(n, mesh.num_cells(), cell_dofs);
        let skip = vec![false; n];
        let (mut k, mut rhs) = (CscMatrix::zeros(&pattern), vec![0.0; n]);
        assemble(&mut k, &mut rhs, &colouring, &skip, || (), kernel).unwrap();
        let (k0, rhs0) = (k.clone(), rhs.clone());
        // A tangential row and a constraint row at vertex 5 (rows in the order [y, x]), two
        // constraint rows at vertex 7.
        let (c, s) = (0.6, 0.8);
        let ops: [(Vec<usize>, Vec<f64>, usize); 2] = [(vec![11, 10], vec![c, s, -s, c], 1), (vec![14, 15], vec![c, s, -s, c], 0)];
        let mut whole = WholeSystem { k: &mut k, rhs: &mut rhs };
        for (rows, q, m) in &ops {
            whole.combine_rows(rows, q, *m);
        }
        let dense = |a: &CscMatrix<'_>, i: usize, j: usize| a.get(i, j);
        for (rows, q, m) in &ops {
            for (i, &r) in rows.iter().enumerate() {
                for j in 0..n {
                    let expected = if i < *m {
                        (0..rows.len()).map(|l| q[i * rows.len() + l] * dense(&k0, rows[l], j)).sum()
                    } else {
                        rows.iter().position(|&x| x == j).map_or(0.0, |l| q[i * rows.len() + l])
                    };
                    assert!((k.get(r, j) - expected).abs() < 1e-15, "row {r}, column {j}");
                }
                let expected = if i < *m { (0..rows.len()).map(|l| q[i * rows.len() + l] * rhs0[rows[l]]).sum() } else { 0.0 };
                assert!((rhs[r] - expected).abs() < 1e-15, "rhs {r}");
            }
        }
        let untouched = (0..n).filter(|r| ![10, 11, 14, 15].contains(r));
        for r in untouched {
            assert!((0..n).all(|j| k.get(r, j) == k0.get(r, j)) && rhs[r] == rhs0[r], "row {r} unchanged");
        }
        // Two ranks of a numbering that keeps each vertex's unknowns together.
        let perm: Vec<usize> = (0..nv).map(|v| (v * 7) % nv).collect();
        assert!({
            let mut p = perm.clone();
            p.sort_unstable();
            p.dedup();
            p.len() == nv
        });
        let to_global = |d: usize| 2 * perm[d / 2] + d % 2;
        for rank in 0..2 {
            let held = n * rank / 2..n * (rank + 1) / 2;
            let cells: Vec<usize> = (0..mesh.num_cells())
                .filter(|&c| {
                    let mut d = Vec::new();
                    cell_dofs(c, &mut d);
                    d.iter().any(|&x| held.contains(&to_global(x)))
                })
                .collect();
            let global_dofs = |c: usize, out: &mut Vec<usize>| {
                cell_dofs(c, out);
                out.iter_mut().for_each(|d| *d = to_global(*d));
            };
            let rp = RowPattern::from_cells(n, held.clone(), &cells, global_dofs);
            let (mut a, mut r) = (RowMatrix::zeros(&rp), vec![0.0; held.len()]);
            let restricted = colouring.restricted(|c| cells.binary_search(&c).is_ok());
            // SAFETY: `to_global` is a permutation.
            unsafe { assemble_rows(&mut a, &mut r, &restricted, &skip, &to_global, || (), kernel) }.unwrap();
            // SAFETY: as above.
            let mut target = unsafe { HeldRows::new(&mut a, &mut r, &to_global) };
            for (rows, q, m) in &ops {
                target.combine_rows(rows, q, *m);
            }
            for d in 0..n {
                let g = to_global(d);
                if !held.contains(&g) {
                    continue;
                }
                assert_eq!(r[g - held.start].to_bits(), rhs[d].to_bits(), "rhs of {d}");
                for j in 0..n {
                    let v = rp.find(g, to_global(j)).map_or(0.0, |pos| a.values[pos]);
                    assert_eq!(v.to_bits(), k.get(d, j).to_bits(), "entry ({d}, {j})");
                }
            }
        }
        let mut alone = rhs0.clone();
        let mut residual = ResidualOnly { rhs: &mut alone };
        for (rows, q, m) in &ops {
            residual.combine_rows(rows, q, *m);
        }
        assert_eq!(alone, rhs);
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
