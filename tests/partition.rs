//! `solve::partition`: the level-set numbering of a system's unknowns over MPI ranks, made from
//! the cells' dofs alone (no pattern, as a rank holding only its own rows will), equals the one
//! made from the pattern, on 2D and 3D flow systems, with every unknown on its own and with the
//! velocity's nodes kept whole, on 1, 2 and 3 ranks. No MPI: the numbering is plain data.

use fdfsi::discretize::flow::FlowDiscretization;
use fdfsi::physics::fluid::Formulation;
use fdfsi::solve::partition::{Nodes, Numbering, World};
use fdfsi_fem::generate::{box_tetrahedra, rectangle_triangles, DiagonalPattern};

/// `Numbering::from_cells` against `Numbering::new` on `disc`'s system: the same index of every
/// unknown and the same rows per rank.
fn same_numberings<const D: usize>(disc: &FlowDiscretization<D>) {
    let pattern = &disc.pattern;
    let n = pattern.n;
    let velocity = disc.velocity_field().range();
    let in_pressure: Vec<bool> = (0..n).map(|i| !velocity.contains(&i)).collect();
    let by_node = Nodes::of_split(&in_pressure, n, D);
    assert_eq!(by_node, Nodes { size: D, end: velocity.end });
    let cell_dofs = |c: usize, dofs: &mut Vec<usize>| disc.layout.cell_dofs_into(c, dofs);
    for nodes in [Nodes::SCALAR, by_node] {
        for size in 1..=3 {
            let world = World { rank: 0, size };
            let (from_pattern, from_cells) =
                (Numbering::new(pattern, world, nodes), Numbering::from_cells(n, disc.mesh.num_cells(), cell_dofs, world, nodes));
            for rank in 0..size {
                assert_eq!(from_pattern.rows(rank), from_cells.rows(rank), "{D}D, {nodes:?}, rank {rank} of {size}");
            }
            assert_eq!(from_cells.rows(size - 1).end, n);
            let differ = (0..n).filter(|&i| from_pattern.to_petsc(i) != from_cells.to_petsc(i)).count();
            assert_eq!(differ, 0, "{D}D, {nodes:?}, {size} ranks: {differ} of {n} unknowns numbered otherwise");
            if size > 1 {
                let moved = (0..n).filter(|&i| from_cells.to_petsc(i) != i).count();
                assert!(moved > n / 2, "{D}D, {size} ranks: the level-set order, not the identity ({moved} of {n} moved)");
            }
        }
    }
}

#[test]
fn the_numbering_from_the_cells_is_the_numbering_from_the_pattern() {
    let mesh = rectangle_triangles(0.0, 4.0, 0.0, 1.0, 16, 4, DiagonalPattern::Alternating);
    same_numberings(&FlowDiscretization::build(mesh, Formulation::Plane).unwrap());
    let mesh = box_tetrahedra(0.0, 4.0, 0.0, 2.0, 0.0, 1.0, 8, 4, 2);
    same_numberings(&FlowDiscretization::build(mesh, Formulation::ThreeD).unwrap());
}
