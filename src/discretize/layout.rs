//! The unknowns of the monolithic FSI system in named blocks.
//!
//! One step's system is `[fluid velocity | fluid pressure | windkessel | solid displacement |
//! solid pressure | contact | multiplier | trace modes | kernel unknowns]` (see
//! [`crate::discretize::fsi`]). Every place that needs a position in it (the pattern, the
//! assembly scatter, the constraints, `describe_unknown`, the restart state, the output slices
//! and, later, the field splits of a block preconditioner) asks the [`SystemLayout`] by
//! [`Block`] instead of adding offsets.

use std::ops::Range;

/// A block of unknowns of the monolithic system.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Block {
    /// The P2+ fluid velocity, `D` components per node.
    FluidVelocity,
    /// The P1-discontinuous fluid pressure, `D + 1` per cell.
    FluidPressure,
    /// The Windkessel outlets' flux and capacitor pressure, two per outlet
    /// ([`crate::discretize::flow::WindkesselBc`]).
    Windkessel,
    /// The Q2 solid displacement increment, `D` per node.
    SolidDisplacement,
    /// The P1-discontinuous solid pressure (mixed laws).
    SolidPressure,
    /// The contact pressures of the solid's contact surfaces, one per node
    /// ([`crate::physics::contact`]).
    Contact,
    /// The P1-discontinuous Lagrange multiplier on gamma_f, `D` per facet vertex and component.
    Multiplier,
    /// The trace-mode multipliers, `D` per chain of gamma_f (trace-mode multiplier space only).
    TraceModes,
    /// One unknown per removed multiplier mode (the multiplier kernel).
    KernelUnknowns,
}

impl Block {
    /// The block's name in words.
    pub fn name(self) -> &'static str {
        match self {
            Block::FluidVelocity => "fluid velocity",
            Block::FluidPressure => "fluid pressure",
            Block::Windkessel => "windkessel",
            Block::SolidDisplacement => "solid displacement",
            Block::SolidPressure => "solid pressure",
            Block::Contact => "contact pressure",
            Block::Multiplier => "multiplier",
            Block::TraceModes => "trace modes",
            Block::KernelUnknowns => "kernel unknowns",
        }
    }

    /// The part of the problem the block belongs to: `fluid`, `solid` or `multiplier` (the
    /// unknowns per part are `summary.json`'s `dofs`).
    pub fn part(self) -> &'static str {
        match self {
            Block::FluidVelocity | Block::FluidPressure | Block::Windkessel => "fluid",
            Block::SolidDisplacement | Block::SolidPressure | Block::Contact => "solid",
            Block::Multiplier | Block::TraceModes | Block::KernelUnknowns => "multiplier",
        }
    }
}

/// Named contiguous blocks of unknowns, in the order given to [`SystemLayout::new`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SystemLayout {
    blocks: Vec<(Block, Range<usize>)>,
}

impl SystemLayout {
    /// Blocks of the given sizes, one after the other.
    pub fn new(sizes: &[(Block, usize)]) -> Self {
        let mut start = 0;
        let blocks = sizes
            .iter()
            .map(|&(b, n)| {
                let r = start..start + n;
                start += n;
                (b, r)
            })
            .collect();
        SystemLayout { blocks }
    }

    /// The unknowns of block `b` (empty, at the end, if the system has no such block).
    pub fn range(&self, b: Block) -> Range<usize> {
        self.blocks.iter().find(|(k, _)| *k == b).map_or(self.num_dofs()..self.num_dofs(), |(_, r)| r.clone())
    }

    /// The first unknown of block `b`.
    pub fn offset(&self, b: Block) -> usize {
        self.range(b).start
    }

    /// The number of unknowns of block `b`.
    pub fn len(&self, b: Block) -> usize {
        self.range(b).len()
    }

    /// The unknowns of consecutive blocks `first..=last`.
    pub fn span(&self, first: Block, last: Block) -> Range<usize> {
        self.range(first).start..self.range(last).end
    }

    /// Number of unknowns.
    pub fn num_dofs(&self) -> usize {
        self.blocks.last().map_or(0, |(_, r)| r.end)
    }

    /// The block of unknown `i` and its index within the block.
    pub fn locate(&self, i: usize) -> Option<(Block, usize)> {
        self.blocks.iter().find(|(_, r)| r.contains(&i)).map(|(b, r)| (*b, i - r.start))
    }

    /// The blocks and their unknowns, in order.
    pub fn blocks(&self) -> impl Iterator<Item = (Block, Range<usize>)> + '_ {
        self.blocks.iter().cloned()
    }

    /// Unknowns per part of the problem ([`Block::part`]), in order of first appearance.
    pub fn dofs_per_part(&self) -> Vec<(String, usize)> {
        let mut out: Vec<(String, usize)> = Vec::new();
        for (b, r) in &self.blocks {
            match out.iter_mut().find(|(n, _)| n == b.part()) {
                Some((_, k)) => *k += r.len(),
                None => out.push((b.part().to_string(), r.len())),
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_contiguous_and_found_by_name() {
        let l = SystemLayout::new(&[
            (Block::FluidVelocity, 10),
            (Block::FluidPressure, 3),
            (Block::SolidDisplacement, 8),
            (Block::SolidPressure, 0),
            (Block::Multiplier, 4),
        ]);
        assert_eq!(l.num_dofs(), 25);
        assert_eq!(l.range(Block::SolidDisplacement), 13..21);
        assert_eq!(l.span(Block::FluidVelocity, Block::FluidPressure), 0..13);
        assert_eq!(l.locate(21), Some((Block::Multiplier, 0)));
        assert_eq!(l.locate(25), None);
        assert_eq!(l.range(Block::KernelUnknowns), 25..25);
        assert_eq!(l.dofs_per_part(), vec![("fluid".into(), 13), ("solid".into(), 8), ("multiplier".into(), 4)]);
    }
}
