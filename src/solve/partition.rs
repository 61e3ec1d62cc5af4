//! How a system's unknowns are split over MPI ranks: [`World`] (this process's rank and the
//! number of ranks), [`Numbering`] (the engine's numbering of the unknowns, a level-set order of
//! the matrix graph, and each rank's contiguous rows in it) and [`Nodes`] (the unknowns kept
//! together in it). Plain data and graph algorithms, no MPI: the `petsc` feature's engine
//! (`solve::petsc`) hands them to PETSc, and a partitioned assembly can ask them which rows are
//! its own (`docs/design/partitioned-assembly.md`).

use fdfsi_fem::sparse::{DofCells, Pattern};
use std::ops::Range;

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
/// node of its own.
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
/// its components in order.
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
