//! How a system's unknowns are split over MPI ranks: [`World`] (this process's rank and the
//! number of ranks), [`Numbering`] (the engine's numbering of the unknowns, a level-set order of
//! the matrix graph, and each rank's contiguous rows in it) and [`Nodes`] (the unknowns kept
//! together in it). Plain data and graph algorithms, no MPI: the `petsc` feature's engine
//! (`solve::petsc`) hands them to PETSc, and a partitioned assembly can ask them which rows are
//! its own (`docs/design/partitioned-assembly.md`).
//!
//! A partitioned assembly: each rank assembles the rows of its [`Partition`] (a
//! [`fdfsi_fem::sparse::RowMatrix`]) and solves through a [`RowSolver`]; [`SerialRows`] is one on
//! a single rank over any [`LinearSolver`], which shows the partitioned path without MPI.

use super::linear::{LinearSolveError, LinearSolver, SolveStats};
use fdfsi_fem::sparse::{CscMatrix, DofCells, Pattern, RowMatrix, RowPattern};
use std::ops::Range;
use std::sync::Arc;

/// This process among the MPI ranks of `MPI_COMM_WORLD` (those `mpirun` started; one alone
/// without it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct World {
    /// This process's rank, `0..size`.
    pub rank: usize,
    /// The number of ranks.
    pub size: usize,
}

/// Consecutive unknowns that PETSc's numbering keeps together and in order, on one rank: the
/// components of a node. Unknowns `0..end` form nodes of `size` each, every later unknown a
/// node of its own. A node's components couple to the same unknowns (they have the same
/// columns in the matrix pattern), as the components of a vector field's node do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Nodes {
    pub size: usize,
    pub end: usize,
}

impl Nodes {
    /// Every unknown a node of its own.
    pub const SCALAR: Nodes = Nodes { size: 1, end: 0 };

    /// The nodes of a split's primal unknowns with `components` each
    /// ([`crate::solve::augmented::SaddlePointSplit::primal_components`]), where they are
    /// `0..end` and the unknowns in the second field (`in_second`, by unknown; missing at the
    /// end: not in it) are `end..n`, with `end` a multiple of `components`; [`Nodes::SCALAR`]
    /// otherwise.
    pub fn of_split(in_second: &[bool], n: usize, components: usize) -> Nodes {
        let second = |i: usize| in_second.get(i).copied().unwrap_or(false);
        let end = (0..n).find(|&i| second(i)).unwrap_or(n);
        if components > 1 && end > 0 && end.is_multiple_of(components) && (end..n).all(second) {
            Nodes { size: components, end }
        } else {
            Nodes::SCALAR
        }
    }

    /// The first unknown of unknown `i`'s node, and the node's size.
    fn node_of(&self, i: usize) -> (usize, usize) {
        match i < self.end {
            true => (i - i % self.size, self.size),
            false => (i, 1),
        }
    }
}

/// PETSc's numbering of a system's unknowns, and fdfsi's (the system layout's,
/// `crate::discretize::layout`). PETSc gives each rank a contiguous block of its numbering
/// ([`Numbering::rows`]); in the layout's numbering such a block would be scattered over the
/// domain (the velocity's vertex nodes first, then its edge, face and cell nodes, then the
/// pressure), so every rank's rows would couple to every other's, and a rank-local smoother
/// (hypre's hybrid Gauss-Seidel, block Jacobi) would see little of the operator. On several
/// ranks PETSc's numbering is therefore a *level-set order* of the matrix graph: breadth-first
/// from a pseudo-peripheral unknown (per connected part), so consecutive unknowns lie close
/// together and the ranks' rows are slices of the domain across its longest extent, each coupled
/// to its neighbours only. A sound partition for a few ranks on elongated domains (vessels,
/// channels); for many ranks a graph partitioner (METIS through PETSc's `MatPartitioning`)
/// would cut less. On one rank it is the identity (no copy).
///
/// The level-set order keeps the [`Nodes`] whole, each node's components consecutive and in
/// order, and each rank's rows whole nodes: about `n / size` rows each, a rank's first row at a
/// node's first component.
#[derive(Clone, Debug)]
pub struct Numbering {
    /// `petsc[i]`: PETSc's index of fdfsi's unknown `i`; empty for the identity.
    petsc: Vec<usize>,
    /// `fdfsi[p]`: fdfsi's unknown of PETSc's index `p`; empty for the identity.
    fdfsi: Vec<usize>,
    /// Rank `r`'s rows are `bounds[r]..bounds[r + 1]`.
    bounds: Vec<usize>,
}

impl Numbering {
    /// The numbering of `pattern`'s unknowns, with `nodes` kept whole, for `world`: the
    /// identity on one rank, the level-set order on several.
    pub fn new(pattern: &Pattern, world: World, nodes: Nodes) -> Self {
        let n = pattern.n;
        Self::level_set(n, world, nodes, |j, column| {
            column.clear();
            column.extend_from_slice(&pattern.row_idx[pattern.col_ptr[j]..pattern.col_ptr[j + 1]]);
        })
    }

    /// The numbering that [`Numbering::new`] gives the pattern of `num_cells` cells whose dofs
    /// `cell_dofs` lists ([`Pattern::from_cells`]) without that pattern: each of its columns, the
    /// union of the dofs of the cells around an unknown, made when the level-set order reaches
    /// the unknown. For a rank that holds only its own rows (memory: the dof-to-cells map, an
    /// index per cell dof, instead of the pattern's index per entry).
    pub fn from_cells<F>(n: usize, num_cells: usize, cell_dofs: F, world: World, nodes: Nodes) -> Self
    where
        F: Fn(usize, &mut Vec<usize>),
    {
        if world.size == 1 {
            return Self::level_set(n, world, nodes, |_, _| unreachable!("the identity on one rank"));
        }
        let dof_cells = DofCells::new(n, num_cells, &cell_dofs);
        let mut buf = Vec::new();
        Self::level_set(n, world, nodes, |j, column| dof_cells.column_into(j, &cell_dofs, &mut buf, column))
    }

    /// The numbering of `n` unknowns for `world` with the graph's neighbours of each unknown
    /// (`neighbours(j, out)`, sorted into `out`): the identity on one rank, else the level-set
    /// order with `nodes` kept whole and the ranks' rows an even split at nodes' first components.
    fn level_set(n: usize, world: World, nodes: Nodes, neighbours: impl FnMut(usize, &mut Vec<usize>)) -> Self {
        assert!(nodes.size >= 1 && nodes.end <= n && nodes.end.is_multiple_of(nodes.size), "{nodes:?} of {n} unknowns");
        if world.size == 1 {
            return Numbering { petsc: Vec::new(), fdfsi: Vec::new(), bounds: vec![0, n] };
        }
        let fdfsi = level_set_order(n, nodes, neighbours);
        let mut petsc = vec![0; fdfsi.len()];
        for (p, &i) in fdfsi.iter().enumerate() {
            petsc[i] = p;
        }
        // An even split, each bound moved up to the next node's first component.
        let bounds = (0..=world.size)
            .map(|r| {
                let mut bound = n * r / world.size;
                while bound < n && nodes.node_of(fdfsi[bound]).0 != fdfsi[bound] {
                    bound += 1;
                }
                bound
            })
            .collect();
        Numbering { petsc, fdfsi, bounds }
    }

    /// The rows of `rank` in PETSc's numbering: contiguous, in rank order.
    pub fn rows(&self, rank: usize) -> Range<usize> {
        self.bounds[rank]..self.bounds[rank + 1]
    }

    /// PETSc's index of fdfsi's unknown `i`.
    pub fn to_petsc(&self, i: usize) -> usize {
        debug_assert!(self.petsc.is_empty() || i < self.petsc.len(), "unknown {i} of {}", self.petsc.len());
        self.petsc.get(i).copied().unwrap_or(i)
    }

    /// fdfsi's unknown of PETSc's index `p`.
    pub fn to_fdfsi(&self, p: usize) -> usize {
        debug_assert!(self.fdfsi.is_empty() || p < self.fdfsi.len(), "index {p} of {}", self.fdfsi.len());
        self.fdfsi.get(p).copied().unwrap_or(p)
    }
}

/// The `n` unknowns in breadth-first (level-set) order, each connected part from a
/// pseudo-peripheral unknown: the last one reached by a first sweep from its lowest unknown (one
/// step of George & Liu's search), the parts one after another. The graph is a matrix pattern's
/// columns (`i` a neighbour of `j` where `(i, j)` is an entry; `neighbours(j, out)` lists them,
/// sorted), symmetric for finite-element systems; neighbours are visited in index order (no
/// sorting by degree, as Cuthill-McKee's). An unknown reached brings its whole node (`nodes`),
/// its components in order; a node's neighbours are listed once, for its first component (its
/// other components have the same).
fn level_set_order(n: usize, nodes: Nodes, mut neighbours: impl FnMut(usize, &mut Vec<usize>)) -> Vec<usize> {
    let reach = |i: usize, seen: &mut [bool], order: &mut Vec<usize>| {
        let (first, size) = nodes.node_of(i);
        for k in first..first + size {
            seen[k] = true;
            order.push(k);
        }
    };
    let mut column = Vec::new();
    let mut breadth_first = |start: usize, seen: &mut [bool], order: &mut Vec<usize>| {
        let mut head = order.len();
        reach(start, seen, order);
        while head < order.len() {
            let j = order[head];
            head += 1;
            if nodes.node_of(j).0 != j {
                continue; // a later component of a node: its neighbours are the first one's, reached
            }
            neighbours(j, &mut column);
            for &i in &column {
                if !seen[i] {
                    reach(i, seen, order);
                }
            }
        }
    };
    let mut order = Vec::with_capacity(n);
    let mut seen = vec![false; n];
    for i in 0..n {
        if seen[i] {
            continue;
        }
        // The first sweep finds the part and its far end; the second orders it from there.
        let first = order.len();
        breadth_first(i, &mut seen, &mut order);
        let far = *order.last().expect("the sweep's start at least");
        order[first..].iter().for_each(|&j| seen[j] = false);
        order.truncate(first);
        breadth_first(far, &mut seen, &mut order);
    }
    order
}

/// How a system's `n` unknowns are split over the ranks of a [`World`] for a partitioned assembly:
/// the [`Numbering`] of the unknowns by [`Numbering::from_cells`] (a rank's rows are consecutive
/// in it), and this rank's rows.
#[derive(Clone, Debug)]
pub struct Partition {
    world: World,
    /// The unknowns kept together (the velocity's nodes).
    nodes: Nodes,
    /// Shared with the solver's system, which numbers its unknowns alike.
    numbering: Arc<Numbering>,
    n: usize,
}

impl Partition {
    /// The partition of the `n` unknowns of `num_cells` cells (`cell_dofs(c, out)` lists cell
    /// `c`'s) over `world`, with `nodes` kept whole.
    pub fn from_cells<F>(n: usize, num_cells: usize, cell_dofs: F, world: World, nodes: Nodes) -> Self
    where
        F: Fn(usize, &mut Vec<usize>),
    {
        Partition { world, nodes, numbering: Arc::new(Numbering::from_cells(n, num_cells, cell_dofs, world, nodes)), n }
    }

    /// The ranks.
    pub fn world(&self) -> World {
        self.world
    }

    /// The unknowns kept together.
    pub fn nodes(&self) -> Nodes {
        self.nodes
    }

    /// The numbering, shared.
    pub fn shared_numbering(&self) -> Arc<Numbering> {
        Arc::clone(&self.numbering)
    }

    /// The number of unknowns.
    pub fn n(&self) -> usize {
        self.n
    }

    /// The numbering of the unknowns (the partition's, PETSc's).
    pub fn numbering(&self) -> &Numbering {
        &self.numbering
    }

    /// This rank's rows, in the partition's numbering.
    pub fn rows(&self) -> Range<usize> {
        self.numbering.rows(self.world.rank)
    }

    /// The cells of `num_cells` (`cell_dofs(c, out)` lists cell `c`'s unknowns) with an unknown
    /// in this rank's rows, increasing: those this rank assembles (the cells along a cut between
    /// two ranks' rows are assembled by both).
    pub fn cells_of_rows<F>(&self, num_cells: usize, cell_dofs: F) -> Vec<usize>
    where
        F: Fn(usize, &mut Vec<usize>),
    {
        let (rows, mut dofs) = (self.rows(), Vec::new());
        (0..num_cells)
            .filter(|&c| {
                cell_dofs(c, &mut dofs);
                dofs.iter().any(|&d| rows.contains(&self.numbering.to_petsc(d)))
            })
            .collect()
    }

    /// The pattern of this rank's rows (in the partition's numbering) of the system whose
    /// `cells` (those of [`Partition::cells_of_rows`]) couple their unknowns
    /// ([`Pattern::from_cells`]).
    pub fn row_pattern<F>(&self, cells: &[usize], cell_dofs: F) -> RowPattern
    where
        F: Fn(usize, &mut Vec<usize>) + Sync,
    {
        RowPattern::from_cells(self.n, self.rows(), cells, |c, out| {
            cell_dofs(c, out);
            out.iter_mut().for_each(|d| *d = self.numbering.to_petsc(*d));
        })
    }
}

/// A linear solver of systems assembled by rows (a partitioned assembly): every rank holds its
/// own rows of the matrix and of the right-hand side (those of a [`Partition`]) and gets the
/// whole solution. Each call is collective: every rank calls it alike.
pub trait RowSolver: LinearSolver {
    /// The ranks this solver runs on.
    fn world(&self) -> World;
    /// The sum of every rank's `value`, with the same bits on every rank (the partial sums added
    /// in rank order), so that the ranks take the same branches on it.
    fn sum(&self, value: f64) -> Result<f64, LinearSolveError>;
    /// Factorises (or sets up the preconditioner of) the matrix whose rows on this rank are `a`,
    /// in `partition`'s numbering.
    fn factorize_rows(&mut self, partition: &Partition, a: &RowMatrix<'_>) -> Result<(), LinearSolveError>;
    /// Solves with the last factorisation, refined against `a` (the matrix of this system, which
    /// may be newer than the one factorised): `b` is this rank's rows of the right-hand side (the
    /// partition's numbering), `x` all the unknowns (the system's own numbering), alike on every
    /// rank on return.
    fn solve_rows(&self, partition: &Partition, a: &RowMatrix<'_>, b: &[f64], x: &mut [f64]) -> Result<SolveStats, LinearSolveError>;
}

/// `solver` as a [`RowSolver`] of the ranks of `partition`, for a partitioned assembly's Newton
/// solve; an error if it solves whole systems only, or on other ranks.
pub fn row_solver_of<'s>(solver: &'s mut dyn LinearSolver, partition: &Partition) -> Result<&'s mut dyn RowSolver, LinearSolveError> {
    let world = partition.world();
    solver
        .as_row_solver()
        .filter(|r| r.world() == world)
        .ok_or_else(|| LinearSolveError::Setup(format!("a system partitioned over {world:?} needs a linear solver of its rows on those ranks")))
}

/// A [`RowSolver`] on one rank over any [`LinearSolver`]: the rows (all of them) copied into a
/// CSC matrix for it. For tests and checks of a partitioned assembly without MPI: its results
/// equal the solver's on the whole system, except that a factorisation held from an earlier
/// Newton solve is never offered ([`LinearSolver::offer_held_factorization`] takes a whole
/// matrix), so with `reuse_factorization` the first iteration of each solve factorises.
pub struct SerialRows<S> {
    pub solver: S,
    /// The CSC form of the last rows' pattern.
    csc: Option<CscOfRows>,
}

/// The CSC pattern of a [`RowPattern`] that holds all rows, its key, and the CSC position of
/// each of its entries.
struct CscOfRows {
    pattern: Pattern,
    key: u64,
    position: Vec<usize>,
}

impl CscOfRows {
    /// The CSC arrays of `p` (all rows): a counting sort of its entries by column.
    fn new(p: &RowPattern, key: u64) -> Self {
        let mut col_ptr = vec![0; p.n + 1];
        p.cols.iter().for_each(|&j| col_ptr[j as usize + 1] += 1);
        (0..p.n).for_each(|j| col_ptr[j + 1] += col_ptr[j]);
        let (mut next, mut row_idx, mut position) = (col_ptr.clone(), vec![0; p.nnz()], vec![0; p.nnz()]);
        for i in 0..p.n {
            for k in p.row_ptr[i]..p.row_ptr[i + 1] {
                let at = &mut next[p.cols[k] as usize];
                (row_idx[*at], position[k]) = (i, *at);
                *at += 1;
            }
        }
        CscOfRows { pattern: Pattern { n: p.n, col_ptr, row_idx }, key, position }
    }

    /// `a` (on the pattern this was made of) as a CSC matrix.
    fn matrix(&self, a: &RowMatrix<'_>) -> Result<CscMatrix<'_>, LinearSolveError> {
        if a.values.len() != self.position.len() || a.pattern.n != self.pattern.n {
            return Err(LinearSolveError::Setup(format!(
                "rows of {} entries given to SerialRows set up for {}",
                a.values.len(),
                self.position.len()
            )));
        }
        let mut values = vec![0.0; a.values.len()];
        self.position.iter().zip(&a.values).for_each(|(&at, &v)| values[at] = v);
        Ok(CscMatrix { pattern: &self.pattern, values })
    }
}

impl<S: LinearSolver> SerialRows<S> {
    pub fn new(solver: S) -> Self {
        SerialRows { solver, csc: None }
    }

    /// `a` as a CSC matrix on the pattern of the last factorisation.
    fn csc_of<'s>(csc: &'s Option<CscOfRows>, a: &RowMatrix<'_>) -> Result<CscMatrix<'s>, LinearSolveError> {
        csc.as_ref().ok_or_else(|| LinearSolveError::Setup("solve before factorize".into()))?.matrix(a)
    }
}

/// A key of a row pattern's structure (FNV-1a of its words).
pub(crate) fn row_pattern_key(p: &RowPattern) -> u64 {
    super::linear::fnv1a(
        [p.n, p.rows.start, p.rows.end].into_iter().chain(p.row_ptr.iter().copied()).map(|w| w as u64).chain(p.cols.iter().map(|&c| u64::from(c))),
    )
}

impl<S: LinearSolver> LinearSolver for SerialRows<S> {
    fn factorize(&mut self, a: &CscMatrix<'_>) -> Result<(), LinearSolveError> {
        self.solver.factorize(a)
    }
    fn solve_in_place(&self, a: &CscMatrix<'_>, rhs: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        self.solver.solve_in_place(a, rhs)
    }
    fn symbolic_factorizations(&self) -> usize {
        self.solver.symbolic_factorizations()
    }
    fn set_split(&mut self, split: super::augmented::SaddlePointSplit) {
        self.solver.set_split(split)
    }
    fn set_forcing(&mut self, relative_residual: f64) {
        self.solver.set_forcing(relative_residual)
    }
    fn as_row_solver(&mut self) -> Option<&mut dyn RowSolver> {
        Some(self)
    }
}

impl<S: LinearSolver> RowSolver for SerialRows<S> {
    fn world(&self) -> World {
        World { rank: 0, size: 1 }
    }
    fn sum(&self, value: f64) -> Result<f64, LinearSolveError> {
        Ok(value)
    }
    fn factorize_rows(&mut self, partition: &Partition, a: &RowMatrix<'_>) -> Result<(), LinearSolveError> {
        let p = a.pattern;
        if partition.world.size != 1 || p.rows != (0..p.n) {
            return Err(LinearSolveError::Setup(format!(
                "SerialRows takes all {} rows on one rank, not {:?} of rank {:?}",
                p.n, p.rows, partition.world
            )));
        }
        let key = row_pattern_key(p);
        if self.csc.as_ref().is_none_or(|c| c.key != key) {
            self.csc = Some(CscOfRows::new(p, key));
        }
        let matrix = Self::csc_of(&self.csc, a)?;
        self.solver.factorize(&matrix)
    }
    fn solve_rows(&self, _: &Partition, a: &RowMatrix<'_>, b: &[f64], x: &mut [f64]) -> Result<SolveStats, LinearSolveError> {
        x.copy_from_slice(b);
        self.solver.solve_in_place(&Self::csc_of(&self.csc, a)?, x)
    }
}
