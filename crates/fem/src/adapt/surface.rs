//! gamma_s: the solid surface the fluid mesh is adapted to, as flat pieces (segments in 2D,
//! triangles in 3D) with a parametric link back to the solid facet each piece came from.
//!
//! A piece `i` has corners `points[pieces[i][k]]`, `k < D`, and came from local facet
//! `origin[i].1` of solid cell `origin[i].0`; `reference[i][k]` is the reference coordinate of
//! corner `k` on that facet (the facet's own reference cell: `[0, 1]` in 2D, the unit square or
//! triangle in 3D; only the first component is used in 2D). A point of the piece with
//! barycentric weights `w` lies at facet reference coordinate `eta = sum_k w_k reference[i][k]`,
//! which [`ReferenceCell::facet_point`] maps into the solid cell: that is how a point of gamma_f is
//! found on the solid ([`Surface::solid_point`]). For a curved (quadratic) facet the flat pieces
//! are its piecewise-linear interpolant through the geometry nodes, and the link is the linear
//! interpolation of `eta` on each piece: exact at the nodes, `O(h^2)` away from them.

use super::geom::{closest_on_piece, dist2, dot, piece_point, sub};
use super::AdaptError;
use crate::element::ReferenceCell;
use crate::mesh::{GeometryOrder, Mesh};
use rstar::{PointDistance, RTree, RTreeObject, AABB};
use std::collections::HashMap;

/// One flat piece in the spatial index: its number and its corners.
#[derive(Clone, Debug)]
pub(crate) struct PieceBox<const D: usize> {
    pub index: usize,
    pub corners: [[f64; D]; D],
}

impl<const D: usize> RTreeObject for PieceBox<D> {
    type Envelope = AABB<[f64; D]>;
    fn envelope(&self) -> Self::Envelope {
        AABB::from_points(self.corners.iter())
    }
}

impl<const D: usize> PointDistance for PieceBox<D> {
    fn distance_2(&self, x: &[f64; D]) -> f64 {
        let w = closest_on_piece(x, &self.corners);
        dist2(x, &piece_point(&self.corners, &w))
    }
}

/// Where a point lies on gamma_s: piece, barycentric weights of the piece's corners (`D` used),
/// the point of the piece, and the distance from the query point to it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint<const D: usize> {
    pub piece: usize,
    pub bary: [f64; 3],
    pub x: [f64; D],
    pub distance: f64,
}

/// gamma_s as flat pieces with their solid origin (see the module documentation).
#[derive(Clone, Debug)]
pub struct Surface<const D: usize> {
    /// Corner coordinates.
    pub points: Vec<[f64; D]>,
    /// Corners of each piece (a segment in 2D, a triangle in 3D).
    pub pieces: Vec<[usize; D]>,
    /// `(solid cell, local facet)` each piece came from.
    pub origin: Vec<(usize, usize)>,
    /// Reference coordinates of each piece corner on its origin facet.
    pub reference: Vec<[[f64; 2]; D]>,
    /// Cell type of the solid mesh the pieces came from (`None` for explicit pieces, whose
    /// "solid point" is the piece's own reference point).
    pub solid_cell: Option<ReferenceCell>,
    tree: RTree<PieceBox<D>>,
}

impl<const D: usize> Surface<D> {
    /// gamma_s from explicit pieces (for tests and analytic surfaces): origin `(i, 0)` for piece
    /// `i`, corner `k` at the `k`-th reference vertex of a segment / triangle. Pieces of zero
    /// measure are rejected.
    pub fn from_pieces(points: Vec<[f64; D]>, pieces: Vec<[usize; D]>) -> Result<Self, AdaptError> {
        let ref_vertex = |k: usize| -> [f64; 2] {
            match (D, k) {
                (_, 0) => [0.0, 0.0],
                (_, 1) => [1.0, 0.0],
                _ => [0.0, 1.0],
            }
        };
        let origin = (0..pieces.len()).map(|i| (i, 0)).collect();
        let reference = vec![std::array::from_fn(ref_vertex); pieces.len()];
        Self::assemble(points, pieces, origin, reference, None)
    }

    /// gamma_s from the boundary facets named `boundary_name` of a (solid) mesh, each split into
    /// flat pieces through its geometry nodes: a 2-node edge gives 1 segment, a 3-node quadratic
    /// edge 2; a 4-node quad face 2 triangles, a 9-node one 8 (each of the 4 sub-quads into 2
    /// triangles by the diagonal through the face centre); a 3-node triangle face 1, a 6-node one
    /// 4. Pieces keep the facet's outward orientation. Corners are shared through the mesh nodes.
    pub fn from_mesh_boundary(mesh: &Mesh<D>, boundary_name: &str) -> Result<Self, AdaptError> {
        let facets = mesh.boundary_facets(boundary_name).map_err(|e| AdaptError::Surface(e.to_string()))?;
        let mut node_to_point: HashMap<usize, usize> = HashMap::new();
        let mut points = Vec::new();
        let (mut pieces, mut origin, mut reference) = (Vec::new(), Vec::new(), Vec::new());
        for bf in &facets {
            let local = mesh.facet_local_nodes(bf.facet);
            let nodes: Vec<usize> = local.iter().map(|&l| mesh.cell(bf.cell)[l]).collect();
            let pattern = facet_pattern(mesh.cell_type, mesh.order, nodes.len())?;
            for (corners, etas) in pattern {
                let ids: [usize; D] = std::array::from_fn(|k| {
                    let n = nodes[corners[k]];
                    *node_to_point.entry(n).or_insert_with(|| {
                        points.push(mesh.points[n]);
                        points.len() - 1
                    })
                });
                pieces.push(ids);
                origin.push((bf.cell, bf.facet));
                reference.push(std::array::from_fn(|k| etas[k]));
            }
        }
        Self::assemble(points, pieces, origin, reference, Some(mesh.cell_type))
    }

    fn assemble(
        points: Vec<[f64; D]>,
        pieces: Vec<[usize; D]>,
        origin: Vec<(usize, usize)>,
        reference: Vec<[[f64; 2]; D]>,
        solid_cell: Option<ReferenceCell>,
    ) -> Result<Self, AdaptError> {
        if D != 2 && D != 3 {
            return Err(AdaptError::Surface(format!("surfaces exist in 2D and 3D, not {D}D")));
        }
        let mut boxes = Vec::with_capacity(pieces.len());
        for (i, p) in pieces.iter().enumerate() {
            if p.iter().any(|&k| k >= points.len()) {
                return Err(AdaptError::Surface(format!("piece {i} refers to a missing point")));
            }
            let corners: [[f64; D]; D] = std::array::from_fn(|k| points[p[k]]);
            if corners.iter().flatten().any(|v| !v.is_finite()) || piece_measure(&corners) <= 0.0 {
                return Err(AdaptError::Surface(format!("piece {i} is degenerate (zero measure or not finite)")));
            }
            boxes.push(PieceBox { index: i, corners });
        }
        Ok(Surface { points, pieces, origin, reference, solid_cell, tree: RTree::bulk_load(boxes) })
    }

    /// Number of pieces.
    pub fn num_pieces(&self) -> usize {
        self.pieces.len()
    }

    /// Corners of piece `i`.
    pub fn corners(&self, i: usize) -> [[f64; D]; D] {
        std::array::from_fn(|k| self.points[self.pieces[i][k]])
    }

    /// Measure (length, area) of gamma_s.
    pub fn measure(&self) -> f64 {
        (0..self.num_pieces()).map(|i| piece_measure(&self.corners(i))).sum()
    }

    /// Unit normal of piece `i`: the tangent turned clockwise in 2D (`(t_y, -t_x)`), the
    /// right-hand-rule normal of its corners in 3D (outward for pieces of a solid's boundary).
    pub fn normal(&self, i: usize) -> [f64; D] {
        piece_normal(&self.corners(i))
    }

    /// The nearest point of gamma_s to `x` (R-tree nearest-neighbour query), or `None` for an
    /// empty surface.
    pub fn project(&self, x: &[f64; D]) -> Option<SurfacePoint<D>> {
        let pb = self.tree.nearest_neighbor(*x)?;
        let bary = closest_on_piece(x, &pb.corners);
        let p = piece_point(&pb.corners, &bary);
        Some(SurfacePoint { piece: pb.index, bary, x: p, distance: dist2(x, &p).sqrt() })
    }

    /// Which side of gamma_s `x` lies on: `(x - p) . n` for its nearest point `p` and the unit
    /// normal `n` there, positive on the side the normals point to (outside a solid whose
    /// pieces are oriented outward), `None` for an empty surface. Where several pieces are
    /// nearest (`p` on an edge or a corner they share, or `x` as near two pieces at different
    /// points), the one whose plane `x` lies farthest from decides: facing an edge (or a 2D
    /// corner), `x - p` lies in the cone of the two pieces' normals, so that piece's normal has
    /// the sign of the edge's. Facing a 3D corner where three or more pieces meet that rule can
    /// fail when their normals differ by more than about 110 degrees (a sharp spike; the
    /// angle-weighted pseudonormal would not); a block's corners are far from that.
    pub fn side(&self, x: &[f64; D]) -> Option<f64> {
        let scale = 1.0 + x.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        let mut nearest = self.tree.nearest_neighbor_iter_with_distance_2(*x);
        let (first, d2_min) = nearest.next()?;
        let signed = |pb: &PieceBox<D>| {
            let p = piece_point(&pb.corners, &closest_on_piece(x, &pb.corners));
            dot(&sub(x, &p), &piece_normal(&pb.corners))
        };
        let mut best = signed(first);
        // Pieces as near as the nearest up to round-off.
        let tie = d2_min * (1.0 + 1e-9) + (1e-12 * scale).powi(2);
        for (pb, _) in nearest.take_while(|&(_, d2)| d2 <= tie) {
            let s = signed(pb);
            if s.abs() > best.abs() {
                best = s;
            }
        }
        Some(best)
    }

    /// The solid cell and its reference coordinates of a point of gamma_s (see the module
    /// documentation for the accuracy on curved facets).
    pub fn solid_point(&self, sp: &SurfacePoint<D>) -> (usize, [f64; D]) {
        let (cell, facet) = self.origin[sp.piece];
        let r = &self.reference[sp.piece];
        let eta: [f64; 2] = std::array::from_fn(|j| (0..D).map(|k| sp.bary[k] * r[k][j]).sum());
        match self.solid_cell {
            Some(ct) => (cell, ct.facet_point::<D>(facet, &eta[..D - 1])),
            None => (cell, std::array::from_fn(|d| if d < 2 { eta[d] } else { 0.0 })),
        }
    }

    /// The spatial index of the pieces.
    pub(crate) fn tree(&self) -> &RTree<PieceBox<D>> {
        &self.tree
    }
}

impl Surface<2> {
    /// An open polyline through `points` (one segment between consecutive points).
    pub fn from_polyline(points: Vec<[f64; 2]>) -> Result<Self, AdaptError> {
        let pieces = (1..points.len()).map(|i| [i - 1, i]).collect();
        Self::from_pieces(points, pieces)
    }
}

/// Length or area of a flat piece.
pub(crate) fn piece_measure<const D: usize>(c: &[[f64; D]; D]) -> f64 {
    if D == 2 {
        dist2(&c[0], &c[1]).sqrt()
    } else {
        let n = super::geom::cross(&super::geom::pad3(&sub(&c[1], &c[0])), &super::geom::pad3(&sub(&c[2], &c[0])));
        0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
    }
}

/// Unit normal of a flat piece (see [`Surface::normal`]).
pub(crate) fn piece_normal<const D: usize>(c: &[[f64; D]; D]) -> [f64; D] {
    let t = sub(&c[1], &c[0]);
    let n: [f64; 3] = if D == 2 { [t[1], -t[0], 0.0] } else { super::geom::cross(&super::geom::pad3(&t), &super::geom::pad3(&sub(&c[2], &c[0]))) };
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    std::array::from_fn(|d| n[d] / l)
}

/// Pieces of one boundary facet with `n` geometry nodes (in [`Mesh::facet_local_nodes`] order):
/// for each piece, the positions of its corners in that node list and their facet reference
/// coordinates.
type FacetPattern = Vec<(Vec<usize>, Vec<[f64; 2]>)>;

fn facet_pattern(cell: ReferenceCell, order: GeometryOrder, n: usize) -> Result<FacetPattern, AdaptError> {
    let e = |a: f64, b: f64| [a, b];
    let piece = |c: &[usize], r: &[[f64; 2]]| (c.to_vec(), r.to_vec());
    Ok(match (cell.facet_cell(), order, n) {
        (ReferenceCell::Segment, GeometryOrder::Linear, 2) => vec![piece(&[0, 1], &[e(0.0, 0.0), e(1.0, 0.0)])],
        (ReferenceCell::Segment, GeometryOrder::Quadratic, 3) => {
            vec![piece(&[0, 2], &[e(0.0, 0.0), e(0.5, 0.0)]), piece(&[2, 1], &[e(0.5, 0.0), e(1.0, 0.0)])]
        }
        (ReferenceCell::Triangle, GeometryOrder::Linear, 3) => {
            vec![piece(&[0, 1, 2], &[e(0.0, 0.0), e(1.0, 0.0), e(0.0, 1.0)])]
        }
        (ReferenceCell::Triangle, GeometryOrder::Quadratic, 6) => {
            let r = [e(0.0, 0.0), e(1.0, 0.0), e(0.0, 1.0), e(0.5, 0.0), e(0.5, 0.5), e(0.0, 0.5)];
            [[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]].iter().map(|t| (t.to_vec(), t.iter().map(|&k| r[k]).collect())).collect()
        }
        (ReferenceCell::Quadrilateral, GeometryOrder::Linear, 4) => {
            let r = [e(0.0, 0.0), e(1.0, 0.0), e(1.0, 1.0), e(0.0, 1.0)];
            [[0, 1, 2], [0, 2, 3]].iter().map(|t| (t.to_vec(), t.iter().map(|&k| r[k]).collect())).collect()
        }
        (ReferenceCell::Quadrilateral, GeometryOrder::Quadratic, 9) => quad9_pattern(),
        _ => return Err(AdaptError::Surface(format!("cannot split a {:?} facet with {n} nodes into flat pieces", cell.facet_cell()))),
    })
}

/// The 8 triangles of a 9-node quadrilateral face: the 3 x 3 node grid `g(i, j)` (reference
/// `(i/2, j/2)`), each sub-quad cut by its diagonal through the centre node `g(1, 1)`.
fn quad9_pattern() -> FacetPattern {
    // Positions in facet_local_nodes order: 4 vertices, mid-edges (v0v1, v1v2, v2v3, v3v0), centre.
    let g = |i: usize, j: usize| -> usize {
        match (i, j) {
            (0, 0) => 0,
            (2, 0) => 1,
            (2, 2) => 2,
            (0, 2) => 3,
            (1, 0) => 4,
            (2, 1) => 5,
            (1, 2) => 6,
            (0, 1) => 7,
            _ => 8,
        }
    };
    let mut out = Vec::new();
    for (i, j) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
        let (c00, c10, c11, c01) = ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1));
        let through_centre_00_11 = (i, j) == (0, 0) || (i, j) == (1, 1);
        let tris = if through_centre_00_11 { [[c00, c10, c11], [c00, c11, c01]] } else { [[c00, c10, c01], [c10, c11, c01]] };
        for t in tris {
            let idx = t.iter().map(|&(a, b)| g(a, b)).collect();
            let r = t.iter().map(|&(a, b)| [a as f64 * 0.5, b as f64 * 0.5]).collect();
            out.push((idx, r));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{box_hexahedra, rectangle_quads};

    #[test]
    fn quadratic_quad_boundary_gives_two_segments_per_edge() {
        let m = rectangle_quads(0.0, 2.0, 0.0, 1.0, 4, 2, GeometryOrder::Quadratic);
        let s = Surface::from_mesh_boundary(&m, "top").unwrap();
        assert_eq!(s.num_pieces(), 8);
        assert!((s.measure() - 2.0).abs() < 1e-14);
        let sp = s.project(&[0.3, 1.2]).unwrap();
        assert!((sp.distance - 0.2).abs() < 1e-14);
        let (cell, xi) = s.solid_point(&sp);
        let v: Vec<[f64; 2]> = m.cell_vertices(cell).iter().map(|&n| m.points[n]).collect();
        // Bilinear map of the (affine) cell at xi.
        let x = [v[0][0] + xi[0] * (v[1][0] - v[0][0]), v[0][1] + xi[1] * (v[3][1] - v[0][1])];
        assert!((x[0] - 0.3).abs() < 1e-14 && (x[1] - 1.0).abs() < 1e-14);
    }

    /// Inside a closed surface `side` is negative, outside positive, also where the nearest
    /// point is an edge or a corner of it. At the sharp tip of a triangle the nearer piece alone
    /// would not do: outside the tip, beside it, the point lies behind the plane of one of the
    /// two segments that meet there.
    #[test]
    fn side_tells_inside_from_outside_at_faces_edges_and_corners() {
        let p = |i: usize| [(i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64];
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [1, 3, 7, 5], [3, 2, 6, 7], [2, 0, 4, 6]];
        let pieces: Vec<[usize; 3]> = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        let cube = Surface::from_pieces((0..8).map(p).collect(), pieces).unwrap();
        for i in 0..cube.num_pieces() {
            let c = cube.corners(i);
            let middle: [f64; 3] = std::array::from_fn(|d| (c[0][d] + c[1][d] + c[2][d]) / 3.0 - 0.5);
            assert!(dot(&cube.normal(i), &middle) > 0.0, "piece {i} points outward");
        }
        let side = |x: [f64; 3]| cube.side(&x).unwrap();
        assert!((side([0.5, 0.4, 0.9]) + 0.1).abs() < 1e-14, "inside, below the top");
        assert!((side([0.9, 0.5, 0.9]) + 0.1).abs() < 1e-14, "inside, as near two faces");
        assert!((side([1.2, 0.5, 1.1]) - 0.2).abs() < 1e-14, "outside, facing an edge");
        assert!((side([1.1, 1.2, 1.3]) - 0.3).abs() < 1e-14, "outside, facing a corner");
        assert!(side([0.5, 0.5, 0.5]) < 0.0 && side([0.5, 0.5, 1.0 + 1e-9]) > 0.0);
        let spike = Surface::from_pieces(vec![[0.0, 0.0], [1.0, 0.0], [0.5, 5.0]], vec![[0, 1], [1, 2], [2, 0]]).unwrap();
        let beside_the_tip = [0.59, 5.02];
        assert!(dot(&spike.normal(2), &sub(&beside_the_tip, &[0.5, 5.0])) < 0.0, "behind the plane of one segment");
        assert!(spike.side(&beside_the_tip).unwrap() > 0.0);
        assert!(spike.side(&[0.5, 4.9]).unwrap() < 0.0);
    }

    #[test]
    fn hex27_face_gives_eight_triangles() {
        let m = box_hexahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 2, 2, 1, GeometryOrder::Quadratic);
        let s = Surface::from_mesh_boundary(&m, "zmax").unwrap();
        assert_eq!(s.num_pieces(), 32);
        assert!((s.measure() - 1.0).abs() < 1e-14);
        for i in 0..s.num_pieces() {
            assert!(s.normal(i)[2] > 0.99, "outward normal");
        }
        let sp = s.project(&[0.3, 0.6, 1.5]).unwrap();
        let (cell, xi) = s.solid_point(&sp);
        let v: Vec<[f64; 3]> = m.cell_vertices(cell).iter().map(|&n| m.points[n]).collect();
        let x: [f64; 3] = std::array::from_fn(|d| v[0][d] + xi[d] * (v[6][d] - v[0][d]));
        assert!((x[0] - 0.3).abs() < 1e-14 && (x[1] - 0.6).abs() < 1e-14 && (x[2] - 1.0).abs() < 1e-14);
    }
}
