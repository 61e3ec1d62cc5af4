//! The original (background) fluid mesh, prepared once for every adaptation of a run.
//!
//! Every step adapts the same original mesh to a new gamma_s (METHOD.md 3), so everything that
//! depends only on that mesh is built here once: its vertex mesh (linear simplices, vertices
//! renumbered `0..nv` in increasing original node order, which is the identity for a linear
//! mesh), its [`Topology`], an R-tree over the bounding boxes of its edges, and the incidence
//! tables `edge -> cells`, `vertex -> cells`, `vertex -> boundary facets`. With these a step's
//! work is local to the cut: its cost grows with the number of cut elements, plus one copy of
//! the cell table. Not quite for a gamma_s with corners (its step clones the vertex positions
//! and rebuilds the edge index once: [`super::corners`]), nor in 3D with feature lines, where
//! each pass that cuts the adapted mesh again near them builds this for the whole adapted mesh.

use super::AdaptError;
use crate::element::ReferenceCell;
use crate::mesh::{GeometryOrder, Mesh, Topology};
use rstar::{RTree, RTreeObject, AABB};

/// A compressed incidence table: the items of row `i` are `items[offsets[i]..offsets[i + 1]]`.
#[derive(Clone, Debug, Default)]
pub(crate) struct Csr {
    offsets: Vec<usize>,
    items: Vec<usize>,
}

impl Csr {
    /// Builds the table with `rows` rows from `(row, item)` pairs.
    pub fn from_pairs(rows: usize, pairs: impl Iterator<Item = (usize, usize)> + Clone) -> Self {
        let mut offsets = vec![0usize; rows + 1];
        for (r, _) in pairs.clone() {
            offsets[r + 1] += 1;
        }
        for i in 0..rows {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut items = vec![0; offsets[rows]];
        for (r, it) in pairs {
            items[fill[r]] = it;
            fill[r] += 1;
        }
        Csr { offsets, items }
    }
    /// Items of row `i`.
    #[inline]
    pub fn row(&self, i: usize) -> &[usize] {
        &self.items[self.offsets[i]..self.offsets[i + 1]]
    }
}

/// An edge in the spatial index.
#[derive(Clone, Debug)]
pub(crate) struct EdgeBox<const D: usize> {
    pub edge: usize,
    pub lo: [f64; D],
    pub hi: [f64; D],
}

impl<const D: usize> RTreeObject for EdgeBox<D> {
    type Envelope = AABB<[f64; D]>;
    fn envelope(&self) -> Self::Envelope {
        AABB::from_corners(self.lo, self.hi)
    }
}

/// The original fluid mesh prepared for repeated adaptation (see the module documentation).
#[derive(Clone, Debug)]
pub struct Background<const D: usize> {
    /// The vertex mesh: linear triangles / tetrahedra, boundary tags and regions of the original.
    pub mesh: Mesh<D>,
    /// Whether the original had quadratic geometry (its curved boundary is not carried over).
    pub was_quadratic: bool,
    /// Total measure of the mesh (sum of cell measures).
    pub measure: f64,
    pub(crate) topology: Topology,
    pub(crate) edge_tree: RTree<EdgeBox<D>>,
    pub(crate) edge_cells: Csr,
    pub(crate) vertex_cells: Csr,
    pub(crate) vertex_boundary: Csr,
}

impl<const D: usize> Background<D> {
    /// Prepares `original` (triangles in 2D, tetrahedra in 3D, linear or quadratic geometry).
    pub fn new(original: &Mesh<D>) -> Result<Self, AdaptError> {
        let expected = if D == 2 { ReferenceCell::Triangle } else { ReferenceCell::Tetrahedron };
        if (D != 2 && D != 3) || original.cell_type != expected {
            return Err(AdaptError::NotSimplex(format!("adaptation needs a {expected:?} mesh in {D}D, got {:?} cells", original.cell_type)));
        }
        original.check().map_err(|e| AdaptError::BadMesh(e.to_string()))?;
        let mesh = vertex_mesh(original);
        let topology = Topology::build(&mesh);
        let nc = mesh.num_cells();
        let nv = mesh.points.len();
        let ne_local = mesh.cell_type.edges().len();
        let edge_cells = Csr::from_pairs(
            topology.edges.len(),
            (0..nc).flat_map(|c| (0..ne_local).map(move |k| (c, k))).map(|(c, k)| (topology.cell_edges[c * ne_local + k], c)),
        );
        let vertex_cells =
            Csr::from_pairs(nv, (0..nc).flat_map(|c| (0..=D).map(move |k| (c, k))).map(|(c, k)| (mesh.cell_nodes[c * (D + 1) + k], c)));
        let bnd = &mesh.boundary;
        let vertex_boundary = Csr::from_pairs(
            nv,
            (0..bnd.len()).flat_map(|i| (0..D).map(move |k| (i, k))).map(|(i, k)| {
                let b = bnd[i];
                (mesh.cell_nodes[b.cell * (D + 1) + mesh.cell_type.facet(b.facet)[k]], i)
            }),
        );
        let measure = (0..nc).map(|c| mesh.signed_vertex_measure(c)).sum();
        Ok(Background {
            was_quadratic: original.order == GeometryOrder::Quadratic,
            measure,
            edge_tree: edge_tree(&mesh, &topology),
            edge_cells,
            vertex_cells,
            vertex_boundary,
            topology,
            mesh,
        })
    }

    /// The same mesh with the vertices `moves` at new positions (same topology; the edge index is
    /// rebuilt).
    pub(crate) fn with_moved_vertices(&self, moves: &[(usize, [f64; D])]) -> Self {
        let mut moved = self.clone();
        for &(v, x) in moves {
            moved.mesh.points[v] = x;
        }
        moved.edge_tree = edge_tree(&moved.mesh, &moved.topology);
        moved
    }

    /// Number of cells.
    pub fn num_cells(&self) -> usize {
        self.mesh.num_cells()
    }

    /// Vertices of cell `c`.
    #[inline]
    pub(crate) fn cell(&self, c: usize) -> &[usize] {
        &self.mesh.cell_nodes[c * (D + 1)..(c + 1) * (D + 1)]
    }

    /// Global edge of local edge `k` of cell `c`.
    #[inline]
    pub(crate) fn cell_edge(&self, c: usize, k: usize) -> usize {
        self.topology.cell_edges[c * self.mesh.cell_type.edges().len() + k]
    }
}

/// The linear vertex mesh of `m`: vertices renumbered in increasing node order (identity when
/// every node is a vertex), boundary, tags and names kept.
fn vertex_mesh<const D: usize>(m: &Mesh<D>) -> Mesh<D> {
    let nv_local = D + 1;
    let mut is_vertex = vec![false; m.points.len()];
    for c in 0..m.num_cells() {
        for &v in m.cell_vertices(c) {
            is_vertex[v] = true;
        }
    }
    let mut new_id = vec![usize::MAX; m.points.len()];
    let mut points = Vec::new();
    for (n, &iv) in is_vertex.iter().enumerate() {
        if iv {
            new_id[n] = points.len();
            points.push(m.points[n]);
        }
    }
    let mut cell_nodes = Vec::with_capacity(m.num_cells() * nv_local);
    for c in 0..m.num_cells() {
        cell_nodes.extend(m.cell_vertices(c).iter().map(|&v| new_id[v]));
    }
    Mesh {
        points,
        cell_type: m.cell_type,
        order: GeometryOrder::Linear,
        cell_nodes,
        cell_tags: m.cell_tags.clone(),
        region_names: m.region_names.clone(),
        boundary: m.boundary.clone(),
        boundary_names: m.boundary_names.clone(),
    }
}

/// The R-tree of the bounding boxes of the edges of `mesh`.
fn edge_tree<const D: usize>(mesh: &Mesh<D>, topology: &Topology) -> RTree<EdgeBox<D>> {
    let boxes = topology
        .edges
        .iter()
        .enumerate()
        .map(|(e, &[a, b])| {
            let (pa, pb) = (mesh.points[a], mesh.points[b]);
            EdgeBox { edge: e, lo: std::array::from_fn(|d| pa[d].min(pb[d])), hi: std::array::from_fn(|d| pa[d].max(pb[d])) }
        })
        .collect();
    RTree::bulk_load(boxes)
}
