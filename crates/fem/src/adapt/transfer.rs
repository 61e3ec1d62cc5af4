//! Transfer of the P2+ fluid velocity from the old adapted mesh to the nodes of the new one
//! (METHOD.md 4): each new node is located in the old mesh and the old cell's nodal P2+ basis
//! is evaluated there, `u(x) = sum_i u_i phi_i(xi(x))`, `D` components per node.
//!
//! Location ([`CellLocator`]): an R-tree over the old cells' bounding boxes gives the candidate
//! cells of a point; the barycentric coordinates in each (affine map of its vertices) decide.
//! The candidate whose smallest barycentric coordinate is largest wins, so a point on a shared
//! facet (a node on gamma_f, which lies on both sides) takes either cell: the velocity is
//! continuous, both give the same value. A point outside every box, or outside every candidate
//! by round-off, takes the best of the 16 cells with the nearest boxes; farther than `1e-8` (in
//! barycentric terms) outside the mesh is an error.
//!
//! Where the old mesh had a hole that the new one fills (fluid cells under a solid removed, see
//! [`super::remove_enclosed`], and uncovered as the solid moves), [`transfer_p2plus_or`] extends
//! the velocity of an old cell near a new node (the one it is least outside of, among the 16
//! with the nearest boxes) to it, up to a given distance outside, and farther out asks the
//! caller for the value (the solid's velocity there, for an FSI step).

use super::AdaptError;
use crate::dofs::NodeMap;
use crate::element::{ElementFamily, ReferenceCell, ReferenceElement, MAX_DOFS};
use crate::locate::simplex_reference_coords;
use crate::mesh::Mesh;
use rstar::{PointDistance, RTree, RTreeObject, AABB};

/// Barycentric tolerance of a point outside the mesh.
const OUTSIDE_TOL: f64 = 1e-8;

#[derive(Clone, Debug)]
struct CellBox<const D: usize> {
    cell: usize,
    lo: [f64; D],
    hi: [f64; D],
}

impl<const D: usize> RTreeObject for CellBox<D> {
    type Envelope = AABB<[f64; D]>;
    fn envelope(&self) -> Self::Envelope {
        AABB::from_corners(self.lo, self.hi)
    }
}

impl<const D: usize> PointDistance for CellBox<D> {
    fn distance_2(&self, x: &[f64; D]) -> f64 {
        self.envelope().distance_2(x)
    }
}

/// Point location in a linear simplex mesh through an R-tree of cell bounding boxes.
#[derive(Clone, Debug)]
pub struct CellLocator<const D: usize> {
    tree: RTree<CellBox<D>>,
}

impl<const D: usize> CellLocator<D> {
    /// Indexes the cells of `mesh` (triangles or tetrahedra; the vertices are used).
    pub fn new(mesh: &Mesh<D>) -> Self {
        let boxes = (0..mesh.num_cells())
            .map(|c| {
                let mut lo = [f64::INFINITY; D];
                let mut hi = [f64::NEG_INFINITY; D];
                for &v in mesh.cell_vertices(c) {
                    for d in 0..D {
                        lo[d] = lo[d].min(mesh.points[v][d]);
                        hi[d] = hi[d].max(mesh.points[v][d]);
                    }
                }
                CellBox { cell: c, lo, hi }
            })
            .collect();
        CellLocator { tree: RTree::bulk_load(boxes) }
    }

    /// The cell of `mesh` containing `x` and the reference coordinates of `x` in it (see the
    /// module documentation), or `None` when `x` is outside the mesh.
    pub fn locate(&self, mesh: &Mesh<D>, x: &[f64; D]) -> Option<(usize, [f64; D])> {
        self.locate_within(mesh, x, OUTSIDE_TOL)
    }

    /// As [`Self::locate`], but a point up to `outside` (in barycentric terms: 1 is a cell's height)
    /// outside the mesh takes the best of the cells near it.
    pub fn locate_within(&self, mesh: &Mesh<D>, x: &[f64; D], outside: f64) -> Option<(usize, [f64; D])> {
        let score = |c: usize| -> Option<(f64, usize, [f64; D])> {
            let v: Vec<[f64; D]> = mesh.cell_vertices(c).iter().map(|&n| mesh.points[n]).collect();
            let xi = simplex_reference_coords(&v, x)?;
            Some((xi.iter().fold(1.0 - xi.iter().sum::<f64>(), |m, &l| m.min(l)), c, xi))
        };
        let better = |a: Option<(f64, usize, [f64; D])>, b: Option<(f64, usize, [f64; D])>| match (a, b) {
            (Some(p), Some(q)) => Some(if q.0 > p.0 { q } else { p }),
            (p, q) => p.or(q),
        };
        let mut best = self.tree.locate_all_at_point(*x).fold(None, |acc, cb| better(acc, score(cb.cell)));
        if best.is_none_or(|b| b.0 < 0.0) {
            best = self.tree.nearest_neighbor_iter(*x).take(16).fold(best, |acc, cb| better(acc, score(cb.cell)));
        }
        best.filter(|b| b.0 >= -outside.max(OUTSIDE_TOL)).map(|b| (b.1, b.2))
    }
}

/// The P1-discontinuous field of `old_mesh` (`D + 1` values per cell: the value at the centroid,
/// then the gradient; [`crate::values::p1disc_basis`]) on the cells of `new_mesh`, linear
/// simplices both: each new cell takes the linear function of the old cell that holds its
/// centroid (or that it is least outside of, up to `extend` outside as in
/// [`transfer_p2plus_or`]); a cell whose centroid lies farther out of the old mesh takes zero.
/// The pressure is discontinuous, across gamma_f above all, and a new cell beside gamma_f may
/// take the function of the old cell on its other side: the result serves as an initial iterate,
/// not as an interpolant.
pub fn transfer_p1disc<const D: usize>(old_mesh: &Mesh<D>, old_values: &[f64], new_mesh: &Mesh<D>, extend: f64) -> Result<Vec<f64>, AdaptError> {
    let want = if D == 2 { ReferenceCell::Triangle } else { ReferenceCell::Tetrahedron };
    if let Some(m) = [old_mesh, new_mesh].into_iter().find(|m| m.cell_type != want || m.nodes_per_cell() != D + 1) {
        return Err(AdaptError::Transfer(format!(
            "the meshes must have linear {want:?} cells, one has {:?} with {} nodes",
            m.cell_type,
            m.nodes_per_cell()
        )));
    }
    if old_values.len() != old_mesh.num_cells() * (D + 1) {
        return Err(AdaptError::Transfer(format!("{} old values for {} cells x {} dofs", old_values.len(), old_mesh.num_cells(), D + 1)));
    }
    // Of a linear simplex, the vertex mean is the centroid of `p1disc_basis`.
    let locator = CellLocator::new(old_mesh);
    let mut out = vec![0.0; new_mesh.num_cells() * (D + 1)];
    for (c, values) in out.chunks_exact_mut(D + 1).enumerate() {
        let x = new_mesh.vertex_centroid(c);
        let Some((old, _)) = locator.locate_within(old_mesh, &x, extend) else { continue };
        values[0] = p1disc_value(old_mesh, old_values, old, &x);
        values[1..].copy_from_slice(&old_values[old * (D + 1) + 1..(old + 1) * (D + 1)]);
    }
    Ok(out)
}

/// The value at `x` of cell `cell`'s linear function in the P1-discontinuous field `values` of
/// `mesh` (linear simplices; `D + 1` values per cell, the value at the centroid, then the
/// gradient): `p(x) = p_c + grad p . (x - x_c)`.
pub fn p1disc_value<const D: usize>(mesh: &Mesh<D>, values: &[f64], cell: usize, x: &[f64; D]) -> f64 {
    let (x_c, p) = (mesh.vertex_centroid(cell), &values[cell * (D + 1)..(cell + 1) * (D + 1)]);
    p[0] + (0..D).map(|d| p[d + 1] * (x[d] - x_c[d])).sum::<f64>()
}

/// The P2+ element of dimension `D` (2 or 3).
fn p2plus<const D: usize>() -> Option<ReferenceElement<D>> {
    let cell = if D == 2 { ReferenceCell::Triangle } else { ReferenceCell::Tetrahedron };
    ReferenceElement::new(cell, ElementFamily::P2Plus)
}

/// Evaluates the old P2+ velocity (`old_values[node * D + k]`, nodes numbered by `old_nodes`, a
/// [`NodeMap::continuous`] map of the P2+ element on `old_mesh`) at each of `new_points`;
/// returns `D` values per point, point-major. See the module documentation.
pub fn transfer_p2plus<const D: usize>(
    old_mesh: &Mesh<D>,
    old_nodes: &NodeMap,
    old_values: &[f64],
    new_points: &[[f64; D]],
) -> Result<Vec<f64>, AdaptError> {
    transfer_p2plus_or(old_mesh, old_nodes, old_values, new_points, OUTSIDE_TOL, |i, x| {
        Err(AdaptError::Transfer(format!("new node {i} at {x:?} lies outside the old mesh")))
    })
}

/// As [`transfer_p2plus`], but a new point up to `extend` (barycentric: 1 is a cell's height)
/// outside the old mesh takes the value there of the polynomial of the old cell it is least
/// outside of, and a point farther out `outside_value(i, x)` (`i` its index in `new_points`),
/// whose error is returned.
pub fn transfer_p2plus_or<const D: usize>(
    old_mesh: &Mesh<D>,
    old_nodes: &NodeMap,
    old_values: &[f64],
    new_points: &[[f64; D]],
    extend: f64,
    mut outside_value: impl FnMut(usize, &[f64; D]) -> Result<[f64; D], AdaptError>,
) -> Result<Vec<f64>, AdaptError> {
    let element = p2plus::<D>().ok_or_else(|| AdaptError::Transfer(format!("no P2+ element in {D}D")))?;
    let want = if D == 2 { ReferenceCell::Triangle } else { ReferenceCell::Tetrahedron };
    if old_mesh.cell_type != want {
        return Err(AdaptError::Transfer(format!("the old mesh must have {want:?} cells, has {:?}", old_mesh.cell_type)));
    }
    if old_nodes.per_cell != element.num_dofs() || old_nodes.cell_nodes.len() != old_mesh.num_cells() * old_nodes.per_cell {
        return Err(AdaptError::Transfer(format!(
            "the node map has {} nodes per cell for {} cells; P2+ needs {} per cell of the old mesh ({} cells)",
            old_nodes.per_cell,
            old_nodes.cell_nodes.len() / old_nodes.per_cell.max(1),
            element.num_dofs(),
            old_mesh.num_cells()
        )));
    }
    if old_values.len() != old_nodes.num_nodes * D {
        return Err(AdaptError::Transfer(format!("{} old values for {} nodes x {D} components", old_values.len(), old_nodes.num_nodes)));
    }
    let locator = CellLocator::new(old_mesh);
    let n = element.num_dofs();
    let mut phi = [0.0; MAX_DOFS];
    let mut grad = [[0.0; D]; MAX_DOFS];
    let mut out = Vec::with_capacity(new_points.len() * D);
    for (i, x) in new_points.iter().enumerate() {
        let Some((c, xi)) = locator.locate_within(old_mesh, x, extend) else {
            out.extend_from_slice(&outside_value(i, x)?);
            continue;
        };
        element.eval_into(&xi, &mut phi[..n], &mut grad[..n]);
        let nodes = old_nodes.cell(c);
        for k in 0..D {
            out.push((0..n).map(|j| phi[j] * old_values[nodes[j] * D + k]).sum());
        }
    }
    Ok(out)
}
