//! Meshes: one cell type per mesh, named regions and boundary tags, and topology built once.
//!
//! A [`Mesh`] stores the *geometry nodes* of each cell in the node order of its geometry element
//! ([`crate::element`]; VTK order): 3/6-node triangles, 4/10-node tetrahedra, 4/9-node
//! quadrilaterals, 8/27-node hexahedra. The first `num_vertices` nodes of a cell are its vertices;
//! quadratic geometry nodes (curved boundary cells) follow. Cells are positively oriented
//! (`det J > 0`); the generators and readers guarantee it.
//!
//! Boundaries are lists of [`BoundaryFacet`]s `(cell, local facet)` with a tag; tags and regions
//! have names (Gmsh physical names, or the generator's names).
//!
//! [`Topology`] numbers the edges (and in 3D the faces) of the vertex mesh and maps each cell to
//! them, which is what a dof map needs for P2/P2+ (one node per edge, per face, per cell).

use crate::element::{ReferenceCell, ReferenceElement};
use std::collections::HashMap;
use thiserror::Error;

/// Errors raised when a mesh is built or checked.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MeshError {
    #[error("cell {cell} is inverted or degenerate (signed measure {measure:.3e})")]
    InvertedCell { cell: usize, measure: f64 },
    #[error("cell {cell} refers to node {node}, but the mesh has {num_nodes} nodes")]
    NodeOutOfRange { cell: usize, node: usize, num_nodes: usize },
    #[error("nodes {a} and {b} coincide at {coords:?} (duplicate nodes)")]
    DuplicateNodes { a: usize, b: usize, coords: Vec<f64> },
    #[error("unknown boundary tag '{name}'; the mesh has: {available}")]
    UnknownBoundary { name: String, available: String },
    #[error("unknown region '{name}'; the mesh has: {available}")]
    UnknownRegion { name: String, available: String },
    #[error("{0}")]
    Invalid(String),
}

/// Geometric order of the cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeometryOrder {
    Linear,
    Quadratic,
}

/// A facet of the boundary: local facet `facet` of cell `cell`, carrying tag `tag`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BoundaryFacet {
    pub cell: usize,
    pub facet: usize,
    pub tag: u32,
}

/// An unstructured mesh of one cell type in `D` dimensions.
#[derive(Clone, Debug)]
pub struct Mesh<const D: usize> {
    /// Node coordinates (vertices and quadratic geometry nodes).
    pub points: Vec<[f64; D]>,
    /// The cell type.
    pub cell_type: ReferenceCell,
    /// Linear or quadratic geometry.
    pub order: GeometryOrder,
    /// Flat cell-to-node table, `nodes_per_cell()` entries per cell.
    pub cell_nodes: Vec<usize>,
    /// Region tag of each cell.
    pub cell_tags: Vec<u32>,
    /// Region names and their tags.
    pub region_names: Vec<(String, u32)>,
    /// Tagged boundary facets.
    pub boundary: Vec<BoundaryFacet>,
    /// Boundary names and their tags.
    pub boundary_names: Vec<(String, u32)>,
}

impl<const D: usize> Mesh<D> {
    /// Number of geometry nodes per cell.
    pub fn nodes_per_cell(&self) -> usize {
        geometry_nodes(self.cell_type, self.order)
    }
    /// Number of cells.
    pub fn num_cells(&self) -> usize {
        self.cell_tags.len()
    }
    /// Geometry nodes of cell `c`.
    #[inline]
    pub fn cell(&self, c: usize) -> &[usize] {
        let n = self.nodes_per_cell();
        &self.cell_nodes[c * n..(c + 1) * n]
    }
    /// Vertices of cell `c`.
    #[inline]
    pub fn cell_vertices(&self, c: usize) -> &[usize] {
        &self.cell(c)[..self.cell_type.num_vertices()]
    }
    /// The mean of the vertices of cell `c` (a linear simplex's centroid).
    pub fn vertex_centroid(&self, c: usize) -> [f64; D] {
        let v = self.cell_vertices(c);
        std::array::from_fn(|d| v.iter().map(|&n| self.points[n][d]).sum::<f64>() / v.len() as f64)
    }
    /// Coordinates of the geometry nodes of cell `c`, written into `out`.
    pub fn cell_coords_into(&self, c: usize, out: &mut Vec<[f64; D]>) {
        out.clear();
        out.extend(self.cell(c).iter().map(|&n| self.points[n]));
    }
    /// The geometry element of the cells.
    pub fn geometry_element(&self) -> ReferenceElement<D> {
        geometry_element::<D>(self.cell_type, self.order)
    }
    /// Tag of the boundary named `name`, or an error listing the names there are.
    pub fn boundary_tag(&self, name: &str) -> Result<u32, MeshError> {
        self.boundary_names
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, t)| *t)
            .ok_or_else(|| MeshError::UnknownBoundary { name: name.to_string(), available: names(&self.boundary_names) })
    }
    /// Tag of the region named `name`.
    pub fn region_tag(&self, name: &str) -> Result<u32, MeshError> {
        self.region_names
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, t)| *t)
            .ok_or_else(|| MeshError::UnknownRegion { name: name.to_string(), available: names(&self.region_names) })
    }
    /// Boundary facets carrying the tag of `name`.
    pub fn boundary_facets(&self, name: &str) -> Result<Vec<BoundaryFacet>, MeshError> {
        let tag = self.boundary_tag(name)?;
        Ok(self.boundary.iter().copied().filter(|b| b.tag == tag).collect())
    }
    /// Local geometry-node indices (into `cell(c)`) of facet `f`: the facet's vertices, then, for
    /// quadratic geometry, its mid-edge nodes (and for a 9/27-node cell its face-centre node).
    pub fn facet_local_nodes(&self, f: usize) -> Vec<usize> {
        facet_local_nodes(self.cell_type, self.order, f)
    }
    /// Is every cell straight-sided (quadratic nodes, if any, at the midpoints of straight edges)?
    pub fn is_affine_cell(&self, c: usize) -> bool {
        if self.order == GeometryOrder::Linear {
            return matches!(self.cell_type, ReferenceCell::Triangle | ReferenceCell::Tetrahedron);
        }
        if !matches!(self.cell_type, ReferenceCell::Triangle | ReferenceCell::Tetrahedron) {
            return false;
        }
        let nodes = self.cell(c);
        let nv = self.cell_type.num_vertices();
        self.cell_type.edges().iter().enumerate().all(|(k, e)| {
            let a = self.points[nodes[e[0]]];
            let b = self.points[nodes[e[1]]];
            let m = self.points[nodes[nv + k]];
            let scale: f64 = (0..D).map(|d| (a[d] - b[d]).abs()).fold(0.0, f64::max);
            (0..D).all(|d| (m[d] - 0.5 * (a[d] + b[d])).abs() <= 1e-12 * scale)
        })
    }
    /// Signed measure (area, volume) of the straight cell through the vertices of cell `c`
    /// (simplices exactly; tensor cells by their first corner's Jacobian times the cell measure).
    pub fn signed_vertex_measure(&self, c: usize) -> f64 {
        let v = self.cell_vertices(c);
        let p = |i: usize| self.points[v[i]];
        let sub = |a: [f64; D], b: [f64; D]| -> [f64; D] { std::array::from_fn(|d| a[d] - b[d]) };
        match self.cell_type {
            ReferenceCell::Triangle => {
                let (a, b) = (sub(p(1), p(0)), sub(p(2), p(0)));
                0.5 * (a[0] * b[1] - a[1] * b[0])
            }
            ReferenceCell::Quadrilateral => {
                let (a, b) = (sub(p(1), p(0)), sub(p(3), p(0)));
                a[0] * b[1] - a[1] * b[0]
            }
            ReferenceCell::Tetrahedron | ReferenceCell::Hexahedron => {
                let (i1, i2, i3) = if self.cell_type == ReferenceCell::Tetrahedron { (1, 2, 3) } else { (1, 3, 4) };
                let (a, b, c3) = (sub(p(i1), p(0)), sub(p(i2), p(0)), sub(p(i3), p(0)));
                let det = a[0] * (b[1] * c3[2] - b[2] * c3[1]) - a[1] * (b[0] * c3[2] - b[2] * c3[0]) + a[2] * (b[0] * c3[1] - b[1] * c3[0]);
                if self.cell_type == ReferenceCell::Tetrahedron {
                    det / 6.0
                } else {
                    det
                }
            }
            ReferenceCell::Segment => unreachable!(),
        }
    }
    /// Checks node indices and orientation of every cell.
    pub fn check(&self) -> Result<(), MeshError> {
        let n = self.points.len();
        for c in 0..self.num_cells() {
            for &node in self.cell(c) {
                if node >= n {
                    return Err(MeshError::NodeOutOfRange { cell: c, node, num_nodes: n });
                }
            }
            let m = self.signed_vertex_measure(c);
            if !(m > 0.0) {
                return Err(MeshError::InvertedCell { cell: c, measure: m });
            }
        }
        Ok(())
    }
    /// Sets the boundary names, replacing the tag of an existing name.
    pub fn add_boundary_name(&mut self, name: &str, tag: u32) {
        self.boundary_names.retain(|(n, _)| n != name);
        self.boundary_names.push((name.to_string(), tag));
    }
    /// Adds the boundary `merged`, the union of the boundaries `names` (which keep their own
    /// tags): every facet of theirs again (once), under a new tag. An existing boundary named
    /// `merged` is replaced.
    pub fn merge_boundaries(&mut self, names: &[String], merged: &str) -> Result<(), MeshError> {
        let tags = names.iter().map(|n| self.boundary_tag(n)).collect::<Result<Vec<u32>, _>>()?;
        let tag = self.boundary_names.iter().map(|(_, t)| *t).chain(self.boundary.iter().map(|b| b.tag)).max().unwrap_or(0) + 1;
        let mut union: Vec<BoundaryFacet> = self.boundary.iter().filter(|b| tags.contains(&b.tag)).map(|b| BoundaryFacet { tag, ..*b }).collect();
        // A facet in two of the boundaries (overlapping groups) once.
        union.sort_by_key(|b| (b.cell, b.facet));
        union.dedup_by_key(|b| (b.cell, b.facet));
        self.boundary.extend(union);
        self.add_boundary_name(merged, tag);
        Ok(())
    }

    /// The meshes `parts` side by side as one mesh of disjoint parts (no nodes shared), in
    /// order: part `k`'s nodes and cells follow those of parts `0..k`. Its boundary `B` and
    /// region `R` become `NAME/B` and `NAME/R` (`NAME` the part's name), each under a tag of its
    /// own (tags without a name too, unnamed). The parts must be of one cell type and geometric
    /// order.
    pub fn disjoint_union(parts: &[(&str, &Mesh<D>)]) -> Result<Mesh<D>, MeshError> {
        let Some((_, first)) = parts.first() else { return Err(MeshError::Invalid("a union of no meshes".into())) };
        let mut union = Mesh {
            points: Vec::new(),
            cell_type: first.cell_type,
            order: first.order,
            cell_nodes: Vec::new(),
            cell_tags: Vec::new(),
            region_names: Vec::new(),
            boundary: Vec::new(),
            boundary_names: Vec::new(),
        };
        let (mut next_boundary, mut next_region) = (0u32, 0u32);
        for (name, part) in parts {
            if (part.cell_type, part.order) != (first.cell_type, first.order) {
                return Err(MeshError::Invalid(format!(
                    "part '{name}' has {:?} {:?} cells, the first part {:?} {:?}: the parts must be of one kind",
                    part.order, part.cell_type, first.order, first.cell_type
                )));
            }
            let (nodes, cells) = (union.points.len(), union.num_cells());
            union.points.extend_from_slice(&part.points);
            union.cell_nodes.extend(part.cell_nodes.iter().map(|&n| n + nodes));
            let regions = retag(&part.cell_tags, &part.region_names, name, &mut next_region, &mut union.region_names);
            union.cell_tags.extend(part.cell_tags.iter().map(|t| regions[t]));
            let boundary_tags: Vec<u32> = part.boundary.iter().map(|b| b.tag).collect();
            let boundaries = retag(&boundary_tags, &part.boundary_names, name, &mut next_boundary, &mut union.boundary_names);
            union.boundary.extend(part.boundary.iter().map(|b| BoundaryFacet { cell: b.cell + cells, facet: b.facet, tag: boundaries[&b.tag] }));
        }
        Ok(union)
    }
}

/// The connected components of the items `0..n` joined by `pairs`: the component of each item,
/// numbered from 0 in the order of the items' first appearance (union-find with path halving).
pub fn connected_components(n: usize, pairs: impl IntoIterator<Item = (usize, usize)>) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (a, b) in pairs {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        parent[ra.max(rb)] = ra.min(rb);
    }
    let mut number = std::collections::HashMap::new();
    (0..n)
        .map(|i| {
            let r = root(&mut parent, i);
            let next = number.len();
            *number.entry(r).or_insert(next)
        })
        .collect()
}

/// New tags, from `*next + 1` on, for the tags `used` and those of `names`, the names prefixed by
/// `part/` and added to `union_names`: the map from old tags to new.
fn retag(
    used: &[u32],
    names: &[(String, u32)],
    part: &str,
    next: &mut u32,
    union_names: &mut Vec<(String, u32)>,
) -> std::collections::HashMap<u32, u32> {
    let mut old: Vec<u32> = used.iter().copied().chain(names.iter().map(|(_, t)| *t)).collect();
    old.sort_unstable();
    old.dedup();
    let map: std::collections::HashMap<u32, u32> = old
        .into_iter()
        .map(|t| {
            *next += 1;
            (t, *next)
        })
        .collect();
    union_names.extend(names.iter().map(|(n, t)| (format!("{part}/{n}"), map[t])));
    map
}

fn names(list: &[(String, u32)]) -> String {
    if list.is_empty() {
        return "(none)".to_string();
    }
    list.iter().map(|(n, _)| format!("'{n}'")).collect::<Vec<_>>().join(", ")
}

/// The axis-aligned bounding box `(lo, hi)` of `points` (infinite bounds for no points).
pub fn bounding_box<const D: usize>(points: &[[f64; D]]) -> ([f64; D], [f64; D]) {
    let mut lo = [f64::INFINITY; D];
    let mut hi = [f64::NEG_INFINITY; D];
    for p in points {
        for d in 0..D {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

/// Number of geometry nodes of a cell type at a geometric order.
pub fn geometry_nodes(cell: ReferenceCell, order: GeometryOrder) -> usize {
    use GeometryOrder::*;
    use ReferenceCell::*;
    match (cell, order) {
        (Segment, Linear) => 2,
        (Segment, Quadratic) => 3,
        (Triangle, Linear) => 3,
        (Triangle, Quadratic) => 6,
        (Quadrilateral, Linear) => 4,
        (Quadrilateral, Quadratic) => 9,
        (Tetrahedron, Linear) => 4,
        (Tetrahedron, Quadratic) => 10,
        (Hexahedron, Linear) => 8,
        (Hexahedron, Quadratic) => 27,
    }
}

/// The geometry element of a cell type and order, in dimension `D` (which must match the cell).
pub fn geometry_element<const D: usize>(cell: ReferenceCell, order: GeometryOrder) -> ReferenceElement<D> {
    use crate::element::ElementFamily::*;
    use ReferenceCell::*;
    let family = match (cell, order) {
        (Segment | Triangle | Tetrahedron, GeometryOrder::Linear) => P1,
        (Segment | Triangle | Tetrahedron, GeometryOrder::Quadratic) => P2,
        (Quadrilateral | Hexahedron, GeometryOrder::Linear) => Q1,
        (Quadrilateral | Hexahedron, GeometryOrder::Quadratic) => Q2,
    };
    ReferenceElement::new(cell, family).unwrap_or_else(|| panic!("{cell:?} is not a {D}D cell"))
}

/// Local geometry nodes of facet `f` (vertices first, then quadratic facet nodes).
pub fn facet_local_nodes(cell: ReferenceCell, order: GeometryOrder, f: usize) -> Vec<usize> {
    let verts = cell.facet(f);
    let mut out: Vec<usize> = verts.to_vec();
    if order == GeometryOrder::Quadratic {
        let nv = cell.num_vertices();
        let edges = cell.edges();
        let nf = verts.len();
        let facet_edges: Vec<[usize; 2]> =
            if cell.dim() == 2 { vec![[verts[0], verts[1]]] } else { (0..nf).map(|i| [verts[i], verts[(i + 1) % nf]]).collect() };
        for fe in facet_edges {
            let k =
                edges.iter().position(|e| (e[0] == fe[0] && e[1] == fe[1]) || (e[0] == fe[1] && e[1] == fe[0])).expect("facet edge is a cell edge");
            out.push(nv + k);
        }
        match cell {
            ReferenceCell::Quadrilateral => {}
            ReferenceCell::Hexahedron => out.push(nv + edges.len() + f),
            _ => {}
        }
    }
    out
}

/// Edges and (3D) faces of the vertex mesh, numbered once, and the cell-to-entity maps.
#[derive(Clone, Debug)]
pub struct Topology {
    /// Number of mesh vertices (nodes that are a vertex of some cell).
    pub num_vertices: usize,
    /// Mesh node index of each vertex, and the inverse map (`usize::MAX` for non-vertex nodes).
    pub vertex_to_node: Vec<usize>,
    pub node_to_vertex: Vec<usize>,
    /// Edges as sorted vertex-node pairs.
    pub edges: Vec<[usize; 2]>,
    /// `cell_edges[c * ne + k]`: global edge of local edge `k` of cell `c`.
    pub cell_edges: Vec<usize>,
    /// Faces (3D) as sorted vertex-node triples/quads (quads padded with `usize::MAX`).
    pub faces: Vec<[usize; 4]>,
    /// `cell_faces[c * nf + k]`: global face of local facet `k` of cell `c` (3D only).
    pub cell_faces: Vec<usize>,
    /// Facet-to-cell map: for each facet (edges in 2D, faces in 3D) the one or two
    /// `(cell, local facet)` pairs that share it.
    pub facet_cells: Vec<[(usize, usize); 2]>,
}

/// Marker for "no cell" in [`Topology::facet_cells`].
pub const NO_CELL: (usize, usize) = (usize::MAX, usize::MAX);

impl Topology {
    /// Builds the topology of a mesh.
    pub fn build<const D: usize>(mesh: &Mesh<D>) -> Self {
        let ct = mesh.cell_type;
        let nc = mesh.num_cells();
        let mut node_to_vertex = vec![usize::MAX; mesh.points.len()];
        let mut vertex_to_node = Vec::new();
        for c in 0..nc {
            for &v in mesh.cell_vertices(c) {
                if node_to_vertex[v] == usize::MAX {
                    node_to_vertex[v] = vertex_to_node.len();
                    vertex_to_node.push(v);
                }
            }
        }
        let ne_local = ct.edges().len();
        let mut edge_index: HashMap<[usize; 2], usize> = HashMap::with_capacity(nc * ne_local / 2);
        let mut edges = Vec::new();
        let mut cell_edges = Vec::with_capacity(nc * ne_local);
        for c in 0..nc {
            let v = mesh.cell_vertices(c);
            for e in ct.edges() {
                let key = sorted2(v[e[0]], v[e[1]]);
                let id = *edge_index.entry(key).or_insert_with(|| {
                    edges.push(key);
                    edges.len() - 1
                });
                cell_edges.push(id);
            }
        }
        let mut faces = Vec::new();
        let mut cell_faces = Vec::new();
        let nfac = ct.num_facets();
        let mut facet_cells: Vec<[(usize, usize); 2]>;
        if ct.dim() == 3 {
            let mut face_index: HashMap<[usize; 4], usize> = HashMap::with_capacity(nc * nfac / 2);
            facet_cells = Vec::new();
            for c in 0..nc {
                let v = mesh.cell_vertices(c);
                for f in 0..nfac {
                    let key = sorted_face(ct.facet(f).iter().map(|&i| v[i]));
                    let id = *face_index.entry(key).or_insert_with(|| {
                        faces.push(key);
                        facet_cells.push([NO_CELL, NO_CELL]);
                        faces.len() - 1
                    });
                    cell_faces.push(id);
                    let slot = if facet_cells[id][0] == NO_CELL { 0 } else { 1 };
                    facet_cells[id][slot] = (c, f);
                }
            }
        } else {
            facet_cells = vec![[NO_CELL, NO_CELL]; edges.len()];
            for c in 0..nc {
                for f in 0..nfac {
                    let id = cell_edges[c * ne_local + f];
                    let slot = if facet_cells[id][0] == NO_CELL { 0 } else { 1 };
                    facet_cells[id][slot] = (c, f);
                }
            }
        }
        Topology { num_vertices: vertex_to_node.len(), vertex_to_node, node_to_vertex, edges, cell_edges, faces, cell_faces, facet_cells }
    }

    /// Number of facets (edges in 2D, faces in 3D).
    pub fn num_facets(&self) -> usize {
        self.facet_cells.len()
    }

    /// Facets with only one neighbouring cell, as `(cell, local facet)`.
    pub fn exterior_facets(&self) -> Vec<(usize, usize)> {
        self.facet_cells.iter().filter(|fc| fc[1] == NO_CELL).map(|fc| fc[0]).collect()
    }

    /// The facet (index into [`Topology::facet_cells`]) that is local facet `f` of cell `c`.
    pub fn facet(&self, cell_type: ReferenceCell, c: usize, f: usize) -> usize {
        if cell_type.dim() == 3 {
            self.cell_faces[c * cell_type.num_facets() + f]
        } else {
            self.cell_edges[c * cell_type.edges().len() + f]
        }
    }

    /// Cell across local facet `f` of cell `c`, if any.
    pub fn neighbour(&self, cell_type: ReferenceCell, c: usize, f: usize) -> Option<usize> {
        let [a, b] = self.facet_cells[self.facet(cell_type, c, f)];
        if a.0 == c {
            (b != NO_CELL).then_some(b.0)
        } else {
            Some(a.0)
        }
    }
}

fn sorted2(a: usize, b: usize) -> [usize; 2] {
    if a < b {
        [a, b]
    } else {
        [b, a]
    }
}

fn sorted_face(it: impl Iterator<Item = usize>) -> [usize; 4] {
    let mut k = [usize::MAX; 4];
    for (i, v) in it.enumerate() {
        k[i] = v;
    }
    k.sort_unstable();
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles forming the unit square.
    pub(crate) fn two_triangles() -> Mesh<2> {
        Mesh {
            points: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            cell_type: ReferenceCell::Triangle,
            order: GeometryOrder::Linear,
            cell_nodes: vec![0, 1, 2, 0, 2, 3],
            cell_tags: vec![1, 1],
            region_names: vec![("fluid".into(), 1)],
            boundary: vec![],
            boundary_names: vec![],
        }
    }

    #[test]
    fn topology_of_two_triangles() {
        let m = two_triangles();
        let t = Topology::build(&m);
        assert_eq!(t.num_vertices, 4);
        assert_eq!(t.edges.len(), 5);
        assert_eq!(t.exterior_facets().len(), 4);
        assert_eq!(t.neighbour(m.cell_type, 0, 2), Some(1)); // the diagonal (2, 0)
        assert_eq!(t.neighbour(m.cell_type, 1, 0), Some(0));
        assert_eq!(t.neighbour(m.cell_type, 0, 0), None);
        m.check().unwrap();
    }

    #[test]
    fn inverted_cell_detected() {
        let mut m = two_triangles();
        m.cell_nodes.swap(1, 2);
        assert!(matches!(m.check(), Err(MeshError::InvertedCell { cell: 0, .. })));
    }

    #[test]
    fn disjoint_union_keeps_each_part_under_its_name() {
        let a = crate::generate::rectangle_quads(0.0, 1.0, 0.0, 1.0, 2, 1, GeometryOrder::Quadratic);
        let b = crate::generate::rectangle_quads(2.0, 3.0, 0.0, 2.0, 1, 3, GeometryOrder::Quadratic);
        let u = Mesh::disjoint_union(&[("a", &a), ("b", &b)]).unwrap();
        u.check().unwrap();
        assert_eq!((u.points.len(), u.num_cells()), (a.points.len() + b.points.len(), 5));
        assert_eq!(u.points[a.points.len()], b.points[0]);
        assert_eq!(u.cell(2), b.cell(0).iter().map(|n| n + a.points.len()).collect::<Vec<_>>());
        for (part, name, mesh, cells) in [("a", "left", &a, 0), ("b", "top", &b, 2)] {
            let facets = u.boundary_facets(&format!("{part}/{name}")).unwrap();
            let own = mesh.boundary_facets(name).unwrap();
            assert_eq!(facets.len(), own.len());
            assert!(facets.iter().zip(&own).all(|(f, o)| f.cell == o.cell + cells && f.facet == o.facet));
        }
        assert!(u.boundary_tag("left").is_err(), "names are prefixed by their part's");
        let tags: std::collections::HashSet<u32> = u.boundary_names.iter().map(|(_, t)| *t).collect();
        assert_eq!(tags.len(), u.boundary_names.len(), "a tag of its own for each boundary");
        let tri = two_triangles();
        assert!(Mesh::disjoint_union(&[("a", &a), ("t", &tri)]).is_err(), "one kind of cell");
    }

    #[test]
    fn unknown_boundary_lists_names() {
        let mut m = two_triangles();
        m.boundary_names.push(("inlet".into(), 3));
        let e = m.boundary_tag("outlet").unwrap_err();
        assert!(e.to_string().contains("'inlet'"));
    }
}
