//! Dof maps: a flat `cell -> dofs` table per field, numbered independently of the mesh nodes.
//!
//! A continuous nodal field (P2, P2+, Q2) has one scalar node per mesh entity its element puts a
//! node on (vertex, edge, face, cell interior); [`NodeMap::continuous`] numbers them entity by
//! entity: all vertex nodes, then edge nodes, then face nodes, then interior nodes. A
//! discontinuous field (the P1disc pressure, the multiplier) owns its dofs per cell
//! ([`NodeMap::discontinuous`]).
//!
//! [`BlockLayout`] stacks fields into one global vector (velocity components interleaved per node,
//! `dof = offset + node * components + component`), which is the layout of the monolithic system.

use crate::element::ReferenceElement;
use crate::mesh::{Mesh, Topology};

/// Scalar node numbering of one field: `cell_nodes[c * per_cell + i]` is the global node of local
/// basis function `i` of cell `c`.
#[derive(Clone, Debug)]
pub struct NodeMap {
    pub num_nodes: usize,
    pub per_cell: usize,
    pub cell_nodes: Vec<usize>,
}

impl NodeMap {
    /// Continuous numbering for `element` on `mesh`, shared across cells through `topology`.
    pub fn continuous<const D: usize>(mesh: &Mesh<D>, topology: &Topology, element: &ReferenceElement<D>) -> Self {
        let nc = mesh.num_cells();
        let ents = element.entities();
        let per_cell = ents.len();
        let uses = |dim: usize| ents.iter().any(|e| e.dim as usize == dim);
        let ne_local = mesh.cell_type.edges().len();
        let nf_local = mesh.cell_type.num_facets();
        let nv = if uses(0) { topology.num_vertices } else { 0 };
        let ne = if uses(1) && D > 1 { topology.edges.len() } else { 0 };
        let nf = if D == 3 && uses(2) { topology.faces.len() } else { 0 };
        let ni = if uses(D) { nc } else { 0 };
        let (off_e, off_f, off_i) = (nv, nv + ne, nv + ne + nf);
        let mut cell_nodes = Vec::with_capacity(nc * per_cell);
        for c in 0..nc {
            let verts = mesh.cell_vertices(c);
            for e in ents {
                let i = e.index as usize;
                let node = match e.dim as usize {
                    0 => topology.node_to_vertex[verts[i]],
                    d if d == D => off_i + c,
                    1 => off_e + topology.cell_edges[c * ne_local + i],
                    2 => off_f + topology.cell_faces[c * nf_local + i],
                    _ => unreachable!(),
                };
                cell_nodes.push(node);
            }
        }
        NodeMap { num_nodes: nv + ne + nf + ni, per_cell, cell_nodes }
    }

    /// Cell-wise (discontinuous) numbering: cell `c` owns nodes `c * per_cell ..`.
    pub fn discontinuous(num_cells: usize, per_cell: usize) -> Self {
        NodeMap { num_nodes: num_cells * per_cell, per_cell, cell_nodes: (0..num_cells * per_cell).collect() }
    }

    /// Global nodes of cell `c`.
    #[inline]
    pub fn cell(&self, c: usize) -> &[usize] {
        &self.cell_nodes[c * self.per_cell..(c + 1) * self.per_cell]
    }

    /// Physical coordinates of every node: the geometry map of a cell containing it, evaluated at
    /// the node's reference coordinates.
    pub fn coordinates<const D: usize>(&self, mesh: &Mesh<D>, element: &ReferenceElement<D>) -> Vec<[f64; D]> {
        let geo = mesh.geometry_element();
        let tab = geo.tabulate(element.nodes());
        let ng = geo.num_dofs();
        let mut x = vec![[0.0; D]; self.num_nodes];
        for c in 0..mesh.num_cells() {
            let g = mesh.cell(c);
            for (i, &node) in self.cell(c).iter().enumerate() {
                let mut p = [0.0; D];
                for (k, &gk) in g.iter().enumerate() {
                    let w = tab.values[i * ng + k];
                    for d in 0..D {
                        p[d] += w * mesh.points[gk][d];
                    }
                }
                x[node] = p;
            }
        }
        x
    }
}

/// One field of a block system.
#[derive(Clone, Debug)]
pub struct Field {
    pub name: String,
    pub components: usize,
    pub nodes: NodeMap,
    pub offset: usize,
}

impl Field {
    /// Number of global dofs of this field.
    pub fn num_dofs(&self) -> usize {
        self.nodes.num_nodes * self.components
    }
    /// Global dof of `component` at `node`.
    #[inline]
    pub fn dof(&self, node: usize, component: usize) -> usize {
        self.offset + node * self.components + component
    }
    /// Range of global dofs of this field.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.offset..self.offset + self.num_dofs()
    }
}

/// Fields stacked into one global numbering.
#[derive(Clone, Debug, Default)]
pub struct BlockLayout {
    pub fields: Vec<Field>,
}

impl BlockLayout {
    /// Appends a field after the existing ones; returns its index.
    pub fn push(&mut self, name: &str, components: usize, nodes: NodeMap) -> usize {
        let offset = self.num_dofs();
        self.fields.push(Field { name: name.to_string(), components, nodes, offset });
        self.fields.len() - 1
    }
    /// Total number of dofs.
    pub fn num_dofs(&self) -> usize {
        self.fields.last().map(|f| f.offset + f.num_dofs()).unwrap_or(0)
    }
    /// The field named `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }
    /// Global dofs of cell `c` over all fields (node-major within a field), written into `out`.
    pub fn cell_dofs_into(&self, c: usize, out: &mut Vec<usize>) {
        out.clear();
        for f in &self.fields {
            for &n in f.nodes.cell(c) {
                for k in 0..f.components {
                    out.push(f.dof(n, k));
                }
            }
        }
    }
    /// Number of dofs per cell over all fields.
    pub fn dofs_per_cell(&self) -> usize {
        self.fields.iter().map(|f| f.nodes.per_cell * f.components).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::ReferenceCell;
    use crate::mesh::GeometryOrder;

    fn square() -> Mesh<2> {
        Mesh {
            points: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            cell_type: ReferenceCell::Triangle,
            order: GeometryOrder::Linear,
            cell_nodes: vec![0, 1, 2, 0, 2, 3],
            cell_tags: vec![1, 1],
            region_names: vec![],
            boundary: vec![],
            boundary_names: vec![],
        }
    }

    #[test]
    fn p2plus_numbering_on_two_triangles() {
        let m = square();
        let t = Topology::build(&m);
        let e = ReferenceElement::p2plus_triangle();
        let map = NodeMap::continuous(&m, &t, &e);
        // 4 vertices + 5 edges + 2 bubbles.
        assert_eq!(map.num_nodes, 11);
        let x = map.coordinates(&m, &e);
        // The shared diagonal's node is shared and lies at (0.5, 0.5).
        let c0 = map.cell(0);
        let c1 = map.cell(1);
        assert_eq!(c0[5], c1[3]); // cell 0 edge (2,0) == cell 1 edge (0,2)
        assert_eq!(x[c0[5]], [0.5, 0.5]);
        // Bubbles at centroids.
        assert!((x[c0[6]][0] - 2.0 / 3.0).abs() < 1e-15 && (x[c0[6]][1] - 1.0 / 3.0).abs() < 1e-15);
        let mut layout = BlockLayout::default();
        layout.push("velocity", 2, map);
        layout.push("pressure", 1, NodeMap::discontinuous(2, 3));
        assert_eq!(layout.num_dofs(), 22 + 6);
        let mut dofs = Vec::new();
        layout.cell_dofs_into(1, &mut dofs);
        assert_eq!(dofs.len(), 14 + 3);
        assert_eq!(&dofs[14..], &[25, 26, 27]);
    }
}
