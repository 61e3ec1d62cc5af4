//! Reference cells and reference finite elements.
//!
//! Every element here is *nodal*: basis function `k` is 1 at node `k` and 0 at the other nodes.
//! An element is defined by a raw spanning set of its polynomial space and its nodes; the nodal
//! basis `phi_k = sum_j C[j][k] raw_j` follows from `V C = I` with `V[i][j] = raw_j(node_i)`
//! (the construction basix uses). This keeps the enriched P2+ bases (P2 plus bubbles) free of
//! hand-derived correction coefficients.
//!
//! | element | cell | nodes | space |
//! |---|---|---|---|
//! | `p1_segment`, `p2_segment` | segment `[0,1]` | 2, 3 | P1, P2 |
//! | `p1_triangle`, `p2_triangle` | triangle | 3, 6 | P1, P2 (geometry, multiplier) |
//! | `p2plus_triangle` | triangle | 7 | P2 + cubic bubble `27 l0 l1 l2` (fluid velocity, 2D) |
//! | `p1_tetrahedron`, `p2_tetrahedron` | tetrahedron | 4, 10 | P1, P2 (geometry) |
//! | `p2plus_tetrahedron` | tetrahedron | 15 | P2 + 4 face bubbles `27 la lb lc` + volume bubble `256 l0 l1 l2 l3` |
//! | `q1_quadrilateral`, `q2_quadrilateral` | `[0,1]^2` | 4, 9 | Q1, Q2 (solid velocity, 2D) |
//! | `q1_hexahedron`, `q2_hexahedron` | `[0,1]^3` | 8, 27 | Q1, Q2 (solid velocity, 3D) |
//!
//! Node order follows VTK (and so the quadratic cells write straight to `.vtu`): vertices, then
//! edge midpoints in [`ReferenceCell::edges`] order, then face nodes in [`ReferenceCell::facet`]
//! order (tetrahedron) or VTK's face order (hexahedron), then the interior node.
//!
//! The P1-discontinuous pressure (value and gradient, `{1, x - x_c, y - y_c[, z - z_c]}` in
//! *physical* coordinates) is not a reference element: see [`crate::values::p1disc_basis`].

use serde::{Deserialize, Serialize};

/// Largest number of basis functions of any element here (the 27-node hexahedron).
pub const MAX_DOFS: usize = 27;

/// The reference cells.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReferenceCell {
    Segment,
    Triangle,
    Quadrilateral,
    Tetrahedron,
    Hexahedron,
}

const SEG_VERTS: [[f64; 3]; 2] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
const TRI_VERTS: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
const QUAD_VERTS: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
const TET_VERTS: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
const HEX_VERTS: [[f64; 3]; 8] =
    [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [0.0, 1.0, 1.0]];

/// Edges of the triangle (VTK order; edge `i` is also facet `i`).
pub const TRI_EDGES: [[usize; 2]; 3] = [[0, 1], [1, 2], [2, 0]];
/// Edges of the quadrilateral (VTK order; edge `i` is also facet `i`).
pub const QUAD_EDGES: [[usize; 2]; 4] = [[0, 1], [1, 2], [2, 3], [3, 0]];
/// Edges of the tetrahedron (VTK order of the 10-node tetrahedron's mid-edge nodes).
pub const TET_EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]];
/// Edges of the hexahedron (VTK order of the 27-node hexahedron's mid-edge nodes).
pub const HEX_EDGES: [[usize; 2]; 12] = [[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]];
/// Facets of the tetrahedron: facet `i` is opposite vertex `i`, ordered so that its normal by the
/// right-hand rule points out of a positively oriented tetrahedron.
pub const TET_FACETS: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
/// Facets of the hexahedron in VTK's face-node order (x-, x+, y-, y+, z-, z+), outward oriented.
pub const HEX_FACETS: [[usize; 4]; 6] = [[0, 4, 7, 3], [1, 2, 6, 5], [0, 1, 5, 4], [3, 7, 6, 2], [0, 3, 2, 1], [4, 5, 6, 7]];
const SEG_FACETS: [[usize; 1]; 2] = [[0], [1]];

impl ReferenceCell {
    /// Topological dimension.
    pub fn dim(self) -> usize {
        match self {
            ReferenceCell::Segment => 1,
            ReferenceCell::Triangle | ReferenceCell::Quadrilateral => 2,
            ReferenceCell::Tetrahedron | ReferenceCell::Hexahedron => 3,
        }
    }

    /// Vertex coordinates (padded to 3 components).
    pub fn vertices(self) -> &'static [[f64; 3]] {
        match self {
            ReferenceCell::Segment => &SEG_VERTS,
            ReferenceCell::Triangle => &TRI_VERTS,
            ReferenceCell::Quadrilateral => &QUAD_VERTS,
            ReferenceCell::Tetrahedron => &TET_VERTS,
            ReferenceCell::Hexahedron => &HEX_VERTS,
        }
    }

    /// Number of vertices.
    pub fn num_vertices(self) -> usize {
        self.vertices().len()
    }

    /// Edges as pairs of local vertices.
    pub fn edges(self) -> &'static [[usize; 2]] {
        match self {
            ReferenceCell::Segment => &[[0, 1]],
            ReferenceCell::Triangle => &TRI_EDGES,
            ReferenceCell::Quadrilateral => &QUAD_EDGES,
            ReferenceCell::Tetrahedron => &TET_EDGES,
            ReferenceCell::Hexahedron => &HEX_EDGES,
        }
    }

    /// Number of facets (cells of dimension `dim - 1` on the boundary).
    pub fn num_facets(self) -> usize {
        match self {
            ReferenceCell::Segment => 2,
            ReferenceCell::Triangle => 3,
            ReferenceCell::Quadrilateral | ReferenceCell::Tetrahedron => 4,
            ReferenceCell::Hexahedron => 6,
        }
    }

    /// Local vertices of facet `f`, outward oriented (counter-clockwise seen from outside).
    pub fn facet(self, f: usize) -> &'static [usize] {
        match self {
            ReferenceCell::Segment => &SEG_FACETS[f],
            ReferenceCell::Triangle => &TRI_EDGES[f],
            ReferenceCell::Quadrilateral => &QUAD_EDGES[f],
            ReferenceCell::Tetrahedron => &TET_FACETS[f],
            ReferenceCell::Hexahedron => &HEX_FACETS[f],
        }
    }

    /// The reference cell of the facets.
    pub fn facet_cell(self) -> ReferenceCell {
        match self {
            ReferenceCell::Segment => ReferenceCell::Segment, // points; unused
            ReferenceCell::Triangle | ReferenceCell::Quadrilateral => ReferenceCell::Segment,
            ReferenceCell::Tetrahedron => ReferenceCell::Triangle,
            ReferenceCell::Hexahedron => ReferenceCell::Quadrilateral,
        }
    }

    /// Measure (length, area, volume) of the reference cell.
    pub fn measure(self) -> f64 {
        match self {
            ReferenceCell::Triangle => 0.5,
            ReferenceCell::Tetrahedron => 1.0 / 6.0,
            _ => 1.0,
        }
    }

    /// Reference centroid.
    pub fn centroid<const D: usize>(self) -> [f64; D] {
        let v = self.vertices();
        let mut c = [0.0; D];
        for p in v {
            for d in 0..D {
                c[d] += p[d] / v.len() as f64;
            }
        }
        c
    }

    /// Maps a point `eta` of the reference facet cell onto facet `f` of this cell, in this
    /// cell's reference coordinates. Facets are flat in the reference cell, so the map is the
    /// facet cell's own (multi)linear vertex interpolation.
    pub fn facet_point<const D: usize>(self, f: usize, eta: &[f64]) -> [f64; D] {
        let verts = self.vertices();
        let fv = self.facet(f);
        let weights: Vec<f64> = match self.facet_cell() {
            ReferenceCell::Segment if self.dim() == 2 => vec![1.0 - eta[0], eta[0]],
            ReferenceCell::Triangle => vec![1.0 - eta[0] - eta[1], eta[0], eta[1]],
            ReferenceCell::Quadrilateral => vec![(1.0 - eta[0]) * (1.0 - eta[1]), eta[0] * (1.0 - eta[1]), eta[0] * eta[1], (1.0 - eta[0]) * eta[1]],
            _ => vec![1.0],
        };
        let mut x = [0.0; D];
        for (w, &v) in weights.iter().zip(fv) {
            for d in 0..D {
                x[d] += w * verts[v][d];
            }
        }
        x
    }
}

/// Which polynomial family an element spans.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ElementFamily {
    /// Complete polynomials of degree 1.
    P1,
    /// Complete polynomials of degree 2.
    P2,
    /// P2 enriched with bubbles (Crouzeix-Raviart velocity).
    P2Plus,
    /// Tensor-product polynomials of degree 1 in each variable.
    Q1,
    /// Tensor-product polynomials of degree 2 in each variable.
    Q2,
}

/// The mesh entity a basis function (node) belongs to: `dim` 0 vertex, 1 edge, 2 face, 3 cell
/// interior; `index` the local entity number in the cell ([`ReferenceCell::edges`],
/// [`ReferenceCell::facet`]). In a 2D cell the interior has `dim` 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DofEntity {
    pub dim: u8,
    pub index: u8,
}

/// A nodal reference element in `D` reference dimensions.
#[derive(Clone)]
pub struct ReferenceElement<const D: usize> {
    cell: ReferenceCell,
    family: ElementFamily,
    nodes: Vec<[f64; D]>,
    entities: Vec<DofEntity>,
    /// `coeffs[j * n + k]`: weight of raw function `j` in basis function `k`; empty when the raw
    /// set is already nodal.
    coeffs: Vec<f64>,
}

impl<const D: usize> std::fmt::Debug for ReferenceElement<D> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}({:?}, {} nodes)", self.family, self.cell, self.nodes.len())
    }
}

/// Values and reference gradients of an element's basis at a set of points:
/// `values[q * n + i]`, `grads[q * n + i]` for point `q`, basis function `i`.
#[derive(Clone, Debug)]
pub struct Tabulation<const D: usize> {
    pub num_points: usize,
    pub num_dofs: usize,
    pub values: Vec<f64>,
    pub grads: Vec<[f64; D]>,
}

impl<const D: usize> ReferenceElement<D> {
    /// The element of `family` on `cell`, in `D` reference dimensions: `None` when `cell` is not
    /// `D`-dimensional or has no such element (P on simplices, Q on quadrilaterals and
    /// hexahedra, P2+ on triangles and tetrahedra). Code generic over `D` builds its elements here;
    /// the named constructors below are these with the dimension fixed.
    pub fn new(cell: ReferenceCell, family: ElementFamily) -> Option<Self> {
        use ElementFamily::*;
        use ReferenceCell::*;
        if cell.dim() != D {
            return None;
        }
        let (nv, ne) = (cell.vertices().len(), cell.edges().len());
        let vertices = || vertex_entities(nv);
        let interior = || std::iter::once(interior_entity(D));
        let (nodes, entities): (Vec<[f64; D]>, Vec<DofEntity>) = match (cell, family) {
            (Segment | Triangle | Tetrahedron, P1) | (Quadrilateral | Hexahedron, Q1) => (vertex_nodes(cell), vertices().collect()),
            (Segment, P2) => ([vertex_nodes(cell), vec![cell.centroid()]].concat(), vertices().chain(interior()).collect()),
            (Triangle | Tetrahedron, P2) => ([vertex_nodes(cell), edge_nodes(cell)].concat(), vertices().chain(edge_entities(ne)).collect()),
            (Triangle, P2Plus) => (
                [vertex_nodes(cell), edge_nodes(cell), vec![cell.centroid()]].concat(),
                vertices().chain(edge_entities(ne)).chain(interior()).collect(),
            ),
            (Tetrahedron, P2Plus) => {
                let v = cell.vertices();
                let faces: Vec<[f64; D]> = TET_FACETS.iter().map(|f| std::array::from_fn(|d| (v[f[0]][d] + v[f[1]][d] + v[f[2]][d]) / 3.0)).collect();
                let entities = vertices().chain(edge_entities(ne)).chain(face_entities(4)).chain(interior()).collect();
                ([vertex_nodes(cell), edge_nodes(cell), faces, vec![cell.centroid()]].concat(), entities)
            }
            (Quadrilateral | Hexahedron, Q2) => {
                let table: &[[f64; 3]] = if cell == Quadrilateral { &Q2_QUAD_NODES } else { &Q2_HEX_NODES };
                let faces = face_entities(if cell == Quadrilateral { 0 } else { 6 });
                (
                    table.iter().map(|p| std::array::from_fn(|d| p[d])).collect(),
                    vertices().chain(edge_entities(ne)).chain(faces).chain(interior()).collect(),
                )
            }
            _ => return None,
        };
        Some(Self::build(cell, family, nodes, entities))
    }

    fn build(cell: ReferenceCell, family: ElementFamily, nodes: Vec<[f64; D]>, entities: Vec<DofEntity>) -> Self {
        let n = nodes.len();
        assert!(n <= MAX_DOFS && entities.len() == n);
        let mut element = ReferenceElement { cell, family, nodes, entities, coeffs: Vec::new() };
        // The raw sets are nodal except P2+'s (P2 and bubbles).
        if family == ElementFamily::P2Plus {
            // V[i][j] = raw_j(node_i); solve V C = I.
            let mut v = vec![0.0; n * n];
            let mut vals = [0.0; MAX_DOFS];
            let mut grads = [[0.0; D]; MAX_DOFS];
            for i in 0..n {
                element.raw(&element.nodes[i], &mut vals[..n], &mut grads[..n]);
                v[i * n..(i + 1) * n].copy_from_slice(&vals[..n]);
            }
            element.coeffs = invert_small(&v, n);
        }
        element
    }

    /// The raw spanning set of the element's space at `xi` (see the module documentation).
    fn raw(&self, xi: &[f64; D], v: &mut [f64], g: &mut [[f64; D]]) {
        match (self.family, D) {
            (ElementFamily::P1, _) => raw_p1_simplex(xi, v, g),
            (ElementFamily::P2, 1) => raw_p2_segment(xi, v, g),
            (ElementFamily::P2, _) => raw_p2_simplex(xi, v, g),
            (ElementFamily::P2Plus, _) => raw_p2plus(xi, v, g),
            (ElementFamily::Q1, 2) => raw_tensor(1, &QUAD_VERTS, xi, v, g),
            (ElementFamily::Q1, _) => raw_tensor(1, &HEX_VERTS, xi, v, g),
            (ElementFamily::Q2, 2) => raw_tensor(2, &Q2_QUAD_NODES, xi, v, g),
            (ElementFamily::Q2, _) => raw_tensor(2, &Q2_HEX_NODES, xi, v, g),
        }
    }

    /// The reference cell.
    pub fn cell(&self) -> ReferenceCell {
        self.cell
    }
    /// The polynomial family.
    pub fn family(&self) -> ElementFamily {
        self.family
    }
    /// Number of basis functions.
    pub fn num_dofs(&self) -> usize {
        self.nodes.len()
    }
    /// Reference coordinates of the nodes.
    pub fn nodes(&self) -> &[[f64; D]] {
        &self.nodes
    }
    /// Mesh entity of each node.
    pub fn entities(&self) -> &[DofEntity] {
        &self.entities
    }

    /// Local nodes that lie on facet `f` of the cell: the facet's vertices, the edges with both
    /// ends in the facet, and (3D) the face itself. Interior nodes never do.
    pub fn facet_nodes(&self, f: usize) -> Vec<usize> {
        let fv = self.cell.facet(f);
        let dim = self.cell.dim();
        let edges = self.cell.edges();
        (0..self.num_dofs())
            .filter(|&k| {
                let e = self.entities[k];
                let i = e.index as usize;
                match e.dim as usize {
                    d if d == dim => false,
                    0 => fv.contains(&i),
                    1 => fv.contains(&edges[i][0]) && fv.contains(&edges[i][1]),
                    2 => i == f,
                    _ => false,
                }
            })
            .collect()
    }

    /// Evaluates all basis functions and their reference gradients at `xi`, writing into
    /// `values[..n]` and `grads[..n]`. Allocation-free.
    pub fn eval_into(&self, xi: &[f64; D], values: &mut [f64], grads: &mut [[f64; D]]) {
        let n = self.num_dofs();
        if self.coeffs.is_empty() {
            self.raw(xi, &mut values[..n], &mut grads[..n]);
            return;
        }
        let mut rv = [0.0; MAX_DOFS];
        let mut rg = [[0.0; D]; MAX_DOFS];
        self.raw(xi, &mut rv[..n], &mut rg[..n]);
        for k in 0..n {
            let mut v = 0.0;
            let mut g = [0.0; D];
            for j in 0..n {
                let c = self.coeffs[j * n + k];
                if c != 0.0 {
                    v += c * rv[j];
                    for d in 0..D {
                        g[d] += c * rg[j][d];
                    }
                }
            }
            values[k] = v;
            grads[k] = g;
        }
    }

    /// Tabulates the basis and its reference gradients at `points`.
    pub fn tabulate(&self, points: &[[f64; D]]) -> Tabulation<D> {
        let n = self.num_dofs();
        let mut values = vec![0.0; points.len() * n];
        let mut grads = vec![[0.0; D]; points.len() * n];
        for (q, xi) in points.iter().enumerate() {
            self.eval_into(xi, &mut values[q * n..(q + 1) * n], &mut grads[q * n..(q + 1) * n]);
        }
        Tabulation { num_points: points.len(), num_dofs: n, values, grads }
    }
}

/// Inverse of a small dense `n x n` matrix (row-major) by Gauss-Jordan elimination with partial
/// pivoting. Used once per element type at construction (n <= 27); a dense-LA crate would be a
/// heavy dependency of this physics-free crate for this one call.
fn invert_small(a: &[f64], n: usize) -> Vec<f64> {
    let mut m = a.to_vec();
    let mut inv = vec![0.0; n * n];
    for i in 0..n {
        inv[i * n + i] = 1.0;
    }
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| m[i * n + col].abs().total_cmp(&m[j * n + col].abs())).expect("non-empty range");
        assert!(m[piv * n + col].abs() > 1e-12, "singular nodal matrix: element nodes not unisolvent");
        for k in 0..n {
            m.swap(col * n + k, piv * n + k);
            inv.swap(col * n + k, piv * n + k);
        }
        let p = m[col * n + col];
        for k in 0..n {
            m[col * n + k] /= p;
            inv[col * n + k] /= p;
        }
        for r in 0..n {
            if r != col {
                let f = m[r * n + col];
                if f != 0.0 {
                    for k in 0..n {
                        m[r * n + k] -= f * m[col * n + k];
                        inv[r * n + k] -= f * inv[col * n + k];
                    }
                }
            }
        }
    }
    inv
}

fn vertex_entities(n: usize) -> impl Iterator<Item = DofEntity> {
    (0..n).map(|i| DofEntity { dim: 0, index: i as u8 })
}
fn edge_entities(n: usize) -> impl Iterator<Item = DofEntity> {
    (0..n).map(|i| DofEntity { dim: 1, index: i as u8 })
}
fn face_entities(n: usize) -> impl Iterator<Item = DofEntity> {
    (0..n).map(|i| DofEntity { dim: 2, index: i as u8 })
}
fn interior_entity(dim: usize) -> DofEntity {
    DofEntity { dim: dim as u8, index: 0 }
}

fn midpoint<const D: usize>(a: &[f64; 3], b: &[f64; 3]) -> [f64; D] {
    std::array::from_fn(|d| 0.5 * (a[d] + b[d]))
}

fn vertex_nodes<const D: usize>(cell: ReferenceCell) -> Vec<[f64; D]> {
    cell.vertices().iter().map(|v| std::array::from_fn(|d| v[d])).collect()
}

fn edge_nodes<const D: usize>(cell: ReferenceCell) -> Vec<[f64; D]> {
    let v = cell.vertices();
    cell.edges().iter().map(|e| midpoint(&v[e[0]], &v[e[1]])).collect()
}

// ---------------------------------------------------------------------------------------------
// Raw spanning sets. Barycentric coordinates on simplices: l0 = 1 - sum(x), l_i = x_{i-1}.

fn bary<const D: usize>(xi: &[f64; D]) -> ([f64; 4], [[f64; D]; 4]) {
    let mut l = [0.0; 4];
    let mut dl = [[0.0; D]; 4];
    l[0] = 1.0 - xi.iter().sum::<f64>();
    for d in 0..D {
        l[d + 1] = xi[d];
        dl[0][d] = -1.0;
        dl[d + 1][d] = 1.0;
    }
    (l, dl)
}

fn raw_p1_simplex<const D: usize>(xi: &[f64; D], v: &mut [f64], g: &mut [[f64; D]]) {
    let (l, dl) = bary(xi);
    v[..=D].copy_from_slice(&l[..=D]);
    g[..=D].copy_from_slice(&dl[..=D]);
}

/// P2 on a simplex in Lagrange form: vertex `l_i (2 l_i - 1)`, edge `4 l_a l_b`.
fn raw_p2_simplex<const D: usize>(xi: &[f64; D], v: &mut [f64], g: &mut [[f64; D]]) {
    let (l, dl) = bary(xi);
    let edges: &[[usize; 2]] = match D {
        1 => &[[0, 1]],
        2 => &TRI_EDGES,
        _ => &TET_EDGES,
    };
    for i in 0..=D {
        v[i] = l[i] * (2.0 * l[i] - 1.0);
        for d in 0..D {
            g[i][d] = (4.0 * l[i] - 1.0) * dl[i][d];
        }
    }
    for (k, e) in edges.iter().enumerate() {
        let (a, b) = (e[0], e[1]);
        v[D + 1 + k] = 4.0 * l[a] * l[b];
        for d in 0..D {
            g[D + 1 + k][d] = 4.0 * (l[b] * dl[a][d] + l[a] * dl[b][d]);
        }
    }
}

/// Product of barycentrics `prod_{i in idx} l_i` times `scale`, with its gradient.
fn bubble<const D: usize>(l: &[f64; 4], dl: &[[f64; D]; 4], idx: &[usize], scale: f64) -> (f64, [f64; D]) {
    let mut v = scale;
    for &i in idx {
        v *= l[i];
    }
    let mut g = [0.0; D];
    for (k, &i) in idx.iter().enumerate() {
        let mut p = scale;
        for (m, &j) in idx.iter().enumerate() {
            if m != k {
                p *= l[j];
            }
        }
        for d in 0..D {
            g[d] += p * dl[i][d];
        }
    }
    (v, g)
}

/// P2 plus bubbles on a simplex: the cubic bubble `27 l0 l1 l2` of the triangle; on the
/// tetrahedron the face bubbles `27 la lb lc` ([`TET_FACETS`] order) and the volume bubble
/// `256 l0 l1 l2 l3`.
fn raw_p2plus<const D: usize>(xi: &[f64; D], v: &mut [f64], g: &mut [[f64; D]]) {
    let p2 = (D + 1) * (D + 2) / 2;
    raw_p2_simplex(xi, &mut v[..p2], &mut g[..p2]);
    let (l, dl) = bary(xi);
    let faces: &[[usize; 3]] = if D == 3 { &TET_FACETS } else { &[] };
    for (f, face) in faces.iter().enumerate() {
        (v[p2 + f], g[p2 + f]) = bubble(&l, &dl, face, 27.0);
    }
    let (all, scale) = if D == 3 { (&[0, 1, 2, 3][..], 256.0) } else { (&[0, 1, 2][..], 27.0) };
    (v[p2 + faces.len()], g[p2 + faces.len()]) = bubble(&l, &dl, all, scale);
}

/// 1D Lagrange basis on `[0,1]`: linear at nodes (0, 1), quadratic at nodes (0, 1, 1/2).
fn lagrange_1d(order: usize, t: f64) -> ([f64; 3], [f64; 3]) {
    if order == 1 {
        ([1.0 - t, t, 0.0], [-1.0, 1.0, 0.0])
    } else {
        ([(1.0 - t) * (1.0 - 2.0 * t), t * (2.0 * t - 1.0), 4.0 * t * (1.0 - t)], [4.0 * t - 3.0, 4.0 * t - 1.0, 4.0 - 8.0 * t])
    }
}

/// 1D node index of a reference coordinate in {0, 1, 1/2}.
fn index_1d(c: f64) -> usize {
    if c == 0.0 {
        0
    } else if c == 1.0 {
        1
    } else {
        2
    }
}

fn raw_tensor<const D: usize>(order: usize, nodes: &[[f64; 3]], xi: &[f64; D], v: &mut [f64], g: &mut [[f64; D]]) {
    let tabs: [([f64; 3], [f64; 3]); D] = std::array::from_fn(|d| lagrange_1d(order, xi[d]));
    for (k, node) in nodes.iter().enumerate() {
        let idx: [usize; D] = std::array::from_fn(|d| index_1d(node[d]));
        let mut val = 1.0;
        for d in 0..D {
            val *= tabs[d].0[idx[d]];
        }
        v[k] = val;
        for d in 0..D {
            let mut p = tabs[d].1[idx[d]];
            for e in 0..D {
                if e != d {
                    p *= tabs[e].0[idx[e]];
                }
            }
            g[k][d] = p;
        }
    }
}

/// The 9 nodes of the biquadratic quadrilateral in VTK order.
const Q2_QUAD_NODES: [[f64; 3]; 9] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.5, 0.0, 0.0],
    [1.0, 0.5, 0.0],
    [0.5, 1.0, 0.0],
    [0.0, 0.5, 0.0],
    [0.5, 0.5, 0.0],
];

/// The 27 nodes of the triquadratic hexahedron in VTK order.
const Q2_HEX_NODES: [[f64; 3]; 27] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [1.0, 1.0, 1.0],
    [0.0, 1.0, 1.0],
    [0.5, 0.0, 0.0],
    [1.0, 0.5, 0.0],
    [0.5, 1.0, 0.0],
    [0.0, 0.5, 0.0],
    [0.5, 0.0, 1.0],
    [1.0, 0.5, 1.0],
    [0.5, 1.0, 1.0],
    [0.0, 0.5, 1.0],
    [0.0, 0.0, 0.5],
    [1.0, 0.0, 0.5],
    [1.0, 1.0, 0.5],
    [0.0, 1.0, 0.5],
    [0.0, 0.5, 0.5],
    [1.0, 0.5, 0.5],
    [0.5, 0.0, 0.5],
    [0.5, 1.0, 0.5],
    [0.5, 0.5, 0.0],
    [0.5, 0.5, 1.0],
    [0.5, 0.5, 0.5],
];

fn raw_p2_segment<const D: usize>(xi: &[f64; D], v: &mut [f64], g: &mut [[f64; D]]) {
    let (l, dl) = lagrange_1d(2, xi[0]);
    for k in 0..3 {
        v[k] = l[k];
        g[k][0] = dl[k];
    }
}

/// `ReferenceElement::new` of a (cell, family) pair that exists.
macro_rules! named {
    ($($(#[$doc:meta])* $name:ident: $cell:ident, $family:ident;)*) => {
        $($(#[$doc])* pub fn $name() -> Self {
            Self::new(ReferenceCell::$cell, ElementFamily::$family).expect("the element exists")
        })*
    };
}

impl ReferenceElement<1> {
    named! {
        /// Linear segment (P1-discontinuous multiplier in 2D, straight boundary geometry).
        p1_segment: Segment, P1;
        /// Quadratic segment (curved boundary geometry in 2D); nodes 0, 1, 1/2.
        p2_segment: Segment, P2;
    }
}

impl ReferenceElement<2> {
    named! {
        /// Linear triangle.
        p1_triangle: Triangle, P1;
        /// Quadratic triangle (6 nodes).
        p2_triangle: Triangle, P2;
        /// The 7-node P2+ triangle of the Crouzeix-Raviart pair: P2 plus the cubic bubble.
        p2plus_triangle: Triangle, P2Plus;
        /// Bilinear quadrilateral.
        q1_quadrilateral: Quadrilateral, Q1;
        /// Biquadratic 9-node quadrilateral.
        q2_quadrilateral: Quadrilateral, Q2;
    }
}

impl ReferenceElement<3> {
    named! {
        /// Linear tetrahedron.
        p1_tetrahedron: Tetrahedron, P1;
        /// Quadratic tetrahedron (10 nodes, VTK order).
        p2_tetrahedron: Tetrahedron, P2;
        /// The 15-node P2+ tetrahedron: P2, a bubble on each face (node at the face centroid, in
        /// [`TET_FACETS`] order) and a volume bubble (node at the centroid).
        p2plus_tetrahedron: Tetrahedron, P2Plus;
        /// Trilinear hexahedron.
        q1_hexahedron: Hexahedron, Q1;
        /// Triquadratic 27-node hexahedron (VTK order).
        q2_hexahedron: Hexahedron, Q2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature;

    fn all_1d() -> Vec<ReferenceElement<1>> {
        vec![ReferenceElement::p1_segment(), ReferenceElement::p2_segment()]
    }
    fn all_2d() -> Vec<ReferenceElement<2>> {
        vec![
            ReferenceElement::p1_triangle(),
            ReferenceElement::p2_triangle(),
            ReferenceElement::p2plus_triangle(),
            ReferenceElement::q1_quadrilateral(),
            ReferenceElement::q2_quadrilateral(),
        ]
    }
    fn all_3d() -> Vec<ReferenceElement<3>> {
        vec![
            ReferenceElement::p1_tetrahedron(),
            ReferenceElement::p2_tetrahedron(),
            ReferenceElement::p2plus_tetrahedron(),
            ReferenceElement::q1_hexahedron(),
            ReferenceElement::q2_hexahedron(),
        ]
    }

    /// Deterministic pseudo-random points inside a reference cell.
    fn sample_points<const D: usize>(cell: ReferenceCell, n: usize) -> Vec<[f64; D]> {
        let mut s = 12345u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut pts = Vec::new();
        while pts.len() < n {
            let p: [f64; D] = std::array::from_fn(|_| rnd());
            let inside = match cell {
                ReferenceCell::Triangle | ReferenceCell::Tetrahedron => p.iter().sum::<f64>() <= 1.0,
                _ => true,
            };
            if inside {
                pts.push(p);
            }
        }
        pts
    }

    fn check_element<const D: usize>(e: &ReferenceElement<D>) {
        let n = e.num_dofs();
        // Kronecker property at the nodes.
        let tab = e.tabulate(e.nodes());
        for i in 0..n {
            for k in 0..n {
                let expect = if i == k { 1.0 } else { 0.0 };
                assert!((tab.values[i * n + k] - expect).abs() < 1e-13, "{e:?}: phi_{k}(node_{i})");
            }
        }
        // Partition of unity and zero gradient sum at random points.
        let pts = sample_points::<D>(e.cell(), 50);
        let tab = e.tabulate(&pts);
        for q in 0..pts.len() {
            let s: f64 = tab.values[q * n..(q + 1) * n].iter().sum();
            assert!((s - 1.0).abs() < 1e-13, "{e:?}: partition of unity");
            for d in 0..D {
                let g: f64 = tab.grads[q * n..(q + 1) * n].iter().map(|g| g[d]).sum();
                assert!(g.abs() < 1e-12, "{e:?}: gradient sum");
            }
        }
        // Gradients agree with central finite differences of the values.
        let h = 1e-6;
        for xi in pts.iter().take(10) {
            let mut v0 = vec![0.0; n];
            let mut g0 = vec![[0.0; D]; n];
            e.eval_into(xi, &mut v0, &mut g0);
            for d in 0..D {
                let mut xp = *xi;
                let mut xm = *xi;
                xp[d] += h;
                xm[d] -= h;
                let (mut vp, mut vm) = (vec![0.0; n], vec![0.0; n]);
                let mut gg = vec![[0.0; D]; n];
                e.eval_into(&xp, &mut vp, &mut gg);
                e.eval_into(&xm, &mut vm, &mut gg);
                for k in 0..n {
                    let fd = (vp[k] - vm[k]) / (2.0 * h);
                    assert!((fd - g0[k][d]).abs() < 1e-6, "{e:?}: d phi_{k} / d xi_{d}");
                }
            }
        }
    }

    /// Interpolation at the nodes reproduces every polynomial of the element's degree.
    fn check_reproduction<const D: usize>(e: &ReferenceElement<D>) {
        let degree: usize = match e.family() {
            ElementFamily::P1 | ElementFamily::Q1 => 1,
            ElementFamily::P2 => 2,
            ElementFamily::P2Plus => 2,
            ElementFamily::Q2 => 2,
        };
        let tensor = matches!(e.family(), ElementFamily::Q1 | ElementFamily::Q2);
        // All exponent tuples of the space.
        let mut exps: Vec<[usize; D]> = Vec::new();
        let max = degree + 1;
        let total = max.pow(D as u32);
        for code in 0..total {
            let mut c = code;
            let ex: [usize; D] = std::array::from_fn(|_| {
                let v = c % max;
                c /= max;
                v
            });
            if tensor || ex.iter().sum::<usize>() <= degree {
                exps.push(ex);
            }
        }
        // P2+ also holds the cubic bubble x*y*(1-x-y) (and in 3D the face bubbles).
        let pts = sample_points::<D>(e.cell(), 20);
        let n = e.num_dofs();
        let tab = e.tabulate(&pts);
        for ex in &exps {
            let f = |x: &[f64; D]| -> f64 { (0..D).map(|d| x[d].powi(ex[d] as i32)).product() };
            let nodal: Vec<f64> = e.nodes().iter().map(f).collect();
            for (q, x) in pts.iter().enumerate() {
                let interp: f64 = (0..n).map(|k| nodal[k] * tab.values[q * n + k]).sum();
                assert!((interp - f(x)).abs() < 1e-12, "{e:?} fails to reproduce x^{ex:?}");
            }
        }
        if e.family() == ElementFamily::P2Plus {
            let f = |x: &[f64; D]| -> f64 {
                let l0 = 1.0 - x.iter().sum::<f64>();
                l0 * x.iter().product::<f64>()
            };
            let nodal: Vec<f64> = e.nodes().iter().map(f).collect();
            for (q, x) in pts.iter().enumerate() {
                let interp: f64 = (0..n).map(|k| nodal[k] * tab.values[q * n + k]).sum();
                assert!((interp - f(x)).abs() < 1e-12, "{e:?} fails to reproduce its bubble");
            }
        }
    }

    #[test]
    fn basis_identities_hold_for_all_elements() {
        for e in all_1d() {
            check_element(&e);
            check_reproduction(&e);
        }
        for e in all_2d() {
            check_element(&e);
            check_reproduction(&e);
        }
        for e in all_3d() {
            check_element(&e);
            check_reproduction(&e);
        }
    }

    #[test]
    fn p2plus_basis_integrates_to_known_values() {
        // With A the area: int(27 l0 l1 l2) = 9A/20, so the nodal vertex functions integrate
        // to 0 + (1/9)(9A/20) = A/20, the edge functions to A/3 - (4/9)(9A/20) = 2A/15.
        let e = ReferenceElement::p2plus_triangle();
        let q5 = quadrature::triangle(5);
        let q12 = quadrature::triangle(12);
        let ints = |qr: &quadrature::QuadratureRule<2>| -> Vec<f64> {
            let t = e.tabulate(&qr.points);
            (0..7).map(|k| (0..qr.len()).map(|q| qr.weights[q] * t.values[q * 7 + k]).sum()).collect()
        };
        let a = ints(&q5);
        let b = ints(&q12);
        for k in 0..7 {
            assert!((a[k] - b[k]).abs() < 1e-14);
        }
        assert!((a.iter().sum::<f64>() - 0.5).abs() < 1e-14);
        for k in 0..3 {
            assert!((a[k] - 0.5 / 20.0).abs() < 1e-14, "vertex {k}: {}", a[k]);
            assert!((a[3 + k] - 0.5 * 2.0 / 15.0).abs() < 1e-14, "edge {k}: {}", a[3 + k]);
        }
        assert!((a[6] - 0.5 * 9.0 / 20.0).abs() < 1e-14, "bubble: {}", a[6]);
    }

    #[test]
    fn facet_nodes_are_the_nodes_on_the_facet() {
        let t = ReferenceElement::p2plus_tetrahedron();
        for f in 0..4 {
            let nodes = t.facet_nodes(f);
            assert_eq!(nodes.len(), 7, "3 vertices, 3 edges, 1 face bubble");
            // Facet f is opposite vertex f: barycentric l_f = 0 at its nodes.
            for &k in &nodes {
                let x = t.nodes()[k];
                let l = [1.0 - x[0] - x[1] - x[2], x[0], x[1], x[2]];
                assert!(l[f].abs() < 1e-15);
            }
        }
        let tri = ReferenceElement::p2plus_triangle();
        assert_eq!(tri.facet_nodes(1), vec![1, 2, 4]);
        let q = ReferenceElement::q2_hexahedron();
        assert_eq!(q.facet_nodes(0).len(), 9);
    }

    #[test]
    fn facet_points_lie_on_the_facet() {
        for cell in [ReferenceCell::Triangle, ReferenceCell::Quadrilateral] {
            for f in 0..cell.num_facets() {
                let p: [f64; 2] = cell.facet_point(f, &[0.0]);
                let v = cell.vertices()[cell.facet(f)[0]];
                assert_eq!(p, [v[0], v[1]]);
            }
        }
        let p: [f64; 3] = ReferenceCell::Tetrahedron.facet_point(0, &[1.0 / 3.0, 1.0 / 3.0]);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }
}
