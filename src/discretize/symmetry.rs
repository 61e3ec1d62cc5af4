//! Symmetry planes of any normal: `u . n = 0` on a plane boundary, for the fluid velocity (free
//! slip) and the solid displacement (a roller), held exactly by row operations on the assembled
//! system, the unknowns kept Cartesian.
//!
//! A plane normal to a coordinate axis is a Dirichlet condition on one component (what the case
//! files' `normal_axis` and `components` give); a plane of another normal (the sector planes of
//! a valve model) constrains a combination of the components. [`NormalConstraints`] holds, for
//! every node on such planes, the row operations that replace the node's equations by
//! tangential equations and constraint rows ([`fdfsi_fem::sparse::SystemTarget::combine_rows`]),
//! and the projection of a state onto the constraints.

use fdfsi_fem::sparse::SystemTarget;
use std::collections::HashMap;
use thiserror::Error;

/// Largest sine of the angle between a facet normal of a symmetry boundary and its plane's
/// normal.
pub const PLANAR_TOLERANCE: f64 = 1e-6;

/// Sine of the angle below which a constraint normal at a node adds nothing to those before it
/// (or to the node's Dirichlet components): the same plane given by two boundaries. Each normal
/// is within [`PLANAR_TOLERANCE`] of the facets it holds, so two boundaries on one plane give
/// normals within twice that of each other; distinct planes through a node meet at angles far
/// above it.
pub const SAME_PLANE: f64 = 10.0 * PLANAR_TOLERANCE;

/// A symmetry plane on a named boundary: `u . n = 0` there, `n` of unit length.
#[derive(Clone, Debug, PartialEq)]
pub struct SymmetryBc<const D: usize> {
    pub boundary: String,
    pub normal: [f64; D],
}

impl<const D: usize> SymmetryBc<D> {
    /// The plane of `boundary` normal to `normal` (normalised); `None` for a zero or non-finite
    /// normal.
    pub fn new(boundary: &str, normal: [f64; D]) -> Option<Self> {
        let length = normal.iter().map(|v| v * v).sum::<f64>().sqrt();
        (length > 0.0 && length.is_finite()).then(|| SymmetryBc { boundary: boundary.into(), normal: normal.map(|v| v / length) })
    }

    /// The coordinate axis the plane is normal to, if it is normal to one (its normal has one
    /// non-zero entry): then `u . n = 0` is a Dirichlet condition on that component.
    pub fn axis(&self) -> Option<usize> {
        let mut nonzero = (0..D).filter(|&a| self.normal[a] != 0.0);
        match (nonzero.next(), nonzero.next()) {
            (Some(a), None) => Some(a),
            _ => None,
        }
    }
}

/// A symmetry boundary that is not a plane of its normal.
#[derive(Debug, Error)]
pub enum SymmetryError {
    #[error(
        "symmetry boundary '{boundary}': its facets are not all normal to {normal:?} (within {PLANAR_TOLERANCE:e}): the worst, on cell {cell}, has the normal {facet_normal:?}, {sine:.3e} off (the sine of the angle); give the plane's normal, or split the boundary into planes"
    )]
    NotPlanar { boundary: String, normal: Vec<f64>, facet_normal: Vec<f64>, cell: usize, sine: f64 },
}

/// The worst facet normal of a symmetry boundary against its plane's normal: fed the facet
/// normals (at points of each facet), it fails on one off by more than [`PLANAR_TOLERANCE`].
pub(crate) struct Planarity<'a, const D: usize> {
    plane: &'a SymmetryBc<D>,
    /// The largest `|m - (m . n) n|` over the normals `m` seen, with its normal and cell.
    worst: (f64, [f64; D], usize),
}

impl<'a, const D: usize> Planarity<'a, D> {
    pub(crate) fn new(plane: &'a SymmetryBc<D>) -> Self {
        Planarity { plane, worst: (0.0, plane.normal, 0) }
    }

    /// A normal (any length) of a facet of cell `cell`.
    pub(crate) fn facet_normal(&mut self, cell: usize, m: [f64; D]) {
        let length = m.iter().map(|v| v * v).sum::<f64>().sqrt();
        let m = m.map(|v| v / length);
        let along: f64 = (0..D).map(|a| m[a] * self.plane.normal[a]).sum();
        let sine = (0..D).map(|a| (m[a] - along * self.plane.normal[a]).powi(2)).sum::<f64>().sqrt();
        // A degenerate facet (no normal) counts as off.
        let sine = if sine.is_nan() { f64::INFINITY } else { sine };
        if sine > self.worst.0 {
            self.worst = (sine, m, cell);
        }
    }

    /// Whether every normal seen is within [`PLANAR_TOLERANCE`] of the plane's.
    pub(crate) fn finish(self) -> Result<(), SymmetryError> {
        let (sine, m, cell) = self.worst;
        if sine <= PLANAR_TOLERANCE {
            return Ok(());
        }
        Err(SymmetryError::NotPlanar {
            boundary: self.plane.boundary.clone(),
            normal: self.plane.normal.to_vec(),
            facet_normal: m.to_vec(),
            cell,
            sine,
        })
    }
}

/// The constraint `u . n = 0` of the symmetry planes at the nodes on them, exactly, by row
/// operations on the assembled system (no penalty), the unknowns kept Cartesian.
///
/// At a node with the unknowns `d_0..d_{D-1}`, let `F` be its components that no Dirichlet
/// condition holds and `n_1, n_2, ...` the unit normals of the planes through it (two on the
/// line where two planes meet). Restricted to `F` and orthonormalised (Gram-Schmidt; one that
/// vanishes, within [`SAME_PLANE`], is dropped: a plane normal to a Dirichlet component, or
/// the same plane twice) they are the constraint normals `c_1..c_k`; `t_1..t_m`
/// (`m = |F| - k`) is an orthonormal basis of the rest of `F`. The node's rows `F` become
///
/// ```text
/// m rows   t_j . (rows of F)        the tangential equations (matrix and right-hand side)
/// k rows   c_i . du_F = 0           constraint rows: nothing else, right-hand side 0
/// ```
///
/// and a state is projected onto the constraints, `u_F <- u_F - sum_i (c_i . u_F) c_i`
/// ([`NormalConstraints::project`]), where the Dirichlet values are imposed: then a Newton
/// update of zero constraint right-hand side keeps it on them. (The Dirichlet components keep
/// their values: the constraint is `u . n = 0` where they are 0 along `n`, as at a no-slip
/// wall or a zero normal component.) A node whose components are all Dirichlet-held keeps its
/// identity rows.
///
/// Which row takes which equation (the LU's pivots are the diagonal entries): the constraint
/// `c_i` goes to the row of its pivot component (Gaussian elimination with the largest entry of
/// each `c_i` among the components not yet taken), and the tangent built from the unit vector
/// `e_b` of a remaining component `b` (Gram-Schmidt against the `c_i` and the tangents before)
/// to row `b`. A plane normal to a coordinate axis so gives that component's identity row and
/// leaves the other rows as they are.
///
/// The rows of a node share their columns (every system cell lists all the components of the
/// nodes it holds: the fluid's and the solid's cells, the Windkessel outlets', the coupling
/// elements' and the contact nodes'), so the combinations need no new entries; the targets
/// check it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NormalConstraints {
    nodes: Vec<ConstrainedNode>,
}

/// One node's row operations ([`NormalConstraints`]).
#[derive(Clone, Debug, PartialEq)]
struct ConstrainedNode {
    /// The rows of `F`: those taking the tangential equations, then the constraint rows.
    rows: Vec<usize>,
    /// The component of each row.
    components: Vec<usize>,
    /// `[t_1; ..; t_m; c_1; ..; c_k]` (row-major, `rows.len()` square) in the components of
    /// `rows`.
    q: Vec<f64>,
    /// `m`.
    tangential: usize,
}

impl NormalConstraints {
    /// The constraints at `nodes`, each its unknowns (one per component) with the unit normals
    /// of the planes through it; `held(d)`: whether a Dirichlet condition holds unknown `d`.
    pub fn new<const D: usize>(nodes: impl IntoIterator<Item = ([usize; D], Vec<[f64; D]>)>, held: impl Fn(usize) -> bool) -> Self {
        let nodes = nodes.into_iter().filter_map(|(dofs, normals)| ConstrainedNode::new(&dofs, &normals, &held)).collect();
        NormalConstraints { nodes }
    }

    /// Whether no node is constrained.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The number of constrained nodes.
    pub fn num_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// The constraints with every unknown shifted by `offset` (a block of a larger system).
    pub fn shifted(&self, offset: usize) -> Self {
        let mut out = self.clone();
        out.nodes.iter_mut().for_each(|n| n.rows.iter_mut().for_each(|r| *r += offset));
        out
    }

    /// These constraints and `other`'s (of other unknowns).
    pub fn joined(mut self, other: NormalConstraints) -> Self {
        self.nodes.extend(other.nodes);
        self
    }

    /// The row operations on an assembled system ([`SystemTarget::combine_rows`] per node), after
    /// every contribution to the nodes' rows.
    pub fn apply(&self, target: &mut impl SystemTarget) {
        for node in &self.nodes {
            target.combine_rows(&node.rows, &node.q, node.tangential);
        }
    }

    /// Projects the state `x` onto the constraints: `u_F <- u_F - sum_i (c_i . u_F) c_i`.
    pub fn project(&self, x: &mut [f64]) {
        for node in &self.nodes {
            let n = node.rows.len();
            for i in node.tangential..n {
                let c = &node.q[i * n..(i + 1) * n];
                let along: f64 = c.iter().zip(&node.rows).map(|(ci, &r)| ci * x[r]).sum();
                for (ci, &r) in c.iter().zip(&node.rows) {
                    x[r] -= along * ci;
                }
            }
        }
    }

    /// The constraint rows (`c_i . du_F = 0`): rows that hold an unknown like a Dirichlet
    /// condition's identity rows, but are not identity rows.
    pub fn constraint_rows(&self) -> impl Iterator<Item = usize> + '_ {
        self.nodes.iter().flat_map(|n| n.rows[n.tangential..].iter().copied())
    }

    /// Checks that no row these constraints combine is a `constrained` (identity) row.
    ///
    /// # Panics
    /// If one is: the constraints were built for other Dirichlet conditions.
    pub fn check_free(&self, constrained: &[bool]) {
        for node in &self.nodes {
            assert!(
                node.rows.iter().all(|&r| !constrained[r]),
                "the rows {:?} of a node on a symmetry plane are free of Dirichlet conditions (the constraints were built for the problem's)",
                node.rows
            );
        }
    }

    /// The tangents `t_1..t_m` of each constrained node (components a Dirichlet condition holds
    /// are 0 in them), under each of the node's free unknowns: the directions in which the node
    /// may move.
    pub fn tangents<const D: usize>(&self) -> HashMap<usize, Vec<[f64; D]>> {
        let mut out = HashMap::new();
        for node in &self.nodes {
            let n = node.rows.len();
            let tangents: Vec<[f64; D]> = (0..node.tangential)
                .map(|j| {
                    let mut t = [0.0; D];
                    for (l, &a) in node.components.iter().enumerate() {
                        t[a] = node.q[j * n + l];
                    }
                    t
                })
                .collect();
            for &r in &node.rows {
                out.insert(r, tangents.clone());
            }
        }
        out
    }
}

impl ConstrainedNode {
    /// The node of unknowns `dofs` on the planes of unit normals `normals` (see
    /// [`NormalConstraints`]); `None` when nothing constrains it further.
    fn new<const D: usize>(dofs: &[usize; D], normals: &[[f64; D]], held: &impl Fn(usize) -> bool) -> Option<Self> {
        let free: Vec<usize> = (0..D).filter(|&a| !held(dofs[a])).collect();
        let f = free.len();
        // The constraint normals c_i: the normals restricted to F, orthonormalised.
        let mut c: Vec<Vec<f64>> = Vec::new();
        for n in normals {
            let mut v: Vec<f64> = free.iter().map(|&a| n[a]).collect();
            orthogonalise(&mut v, &c);
            if normalise(&mut v, SAME_PLANE) {
                c.push(v);
            }
        }
        if c.is_empty() {
            return None;
        }
        let pivots = pivots(&c);
        // The tangents: e_b of each other component, against the c_i and the tangents before.
        let mut basis = c.clone();
        let mut tangents = Vec::new();
        let others: Vec<usize> = (0..f).filter(|b| !pivots.contains(b)).collect();
        for &b in &others {
            let mut t: Vec<f64> = (0..f).map(|l| if l == b { 1.0 } else { 0.0 }).collect();
            orthogonalise(&mut t, &basis);
            // Twice, for orthogonality to round-off.
            orthogonalise(&mut t, &basis);
            assert!(normalise(&mut t, 1e-8), "the unit vectors of the components other than the pivots complete the constraint normals");
            basis.push(t.clone());
            tangents.push(t);
        }
        // Rows: the tangential ones (components `others`), then the constraint rows (`pivots`).
        let order: Vec<usize> = others.iter().chain(&pivots).copied().collect();
        let q: Vec<f64> = tangents.iter().chain(&c).flat_map(|v| order.iter().map(|&l| v[l])).collect();
        Some(ConstrainedNode {
            rows: order.iter().map(|&l| dofs[free[l]]).collect(),
            components: order.iter().map(|&l| free[l]).collect(),
            q,
            tangential: tangents.len(),
        })
    }
}

/// `v` minus its components along the orthonormal vectors `basis`.
fn orthogonalise(v: &mut [f64], basis: &[Vec<f64>]) {
    for b in basis {
        let along: f64 = b.iter().zip(v.iter()).map(|(x, y)| x * y).sum();
        v.iter_mut().zip(b).for_each(|(x, y)| *x -= along * y);
    }
}

/// Scales `v` to unit length; false (and `v` unchanged) when its length is at most `tolerance`.
fn normalise(v: &mut [f64], tolerance: f64) -> bool {
    let length = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(length > tolerance) {
        return false;
    }
    v.iter_mut().for_each(|x| *x /= length);
    true
}

/// The pivot component of each of the independent vectors `c` (Gaussian elimination, the largest
/// entry of each among the components not yet taken): `c` restricted to them is invertible.
fn pivots(c: &[Vec<f64>]) -> Vec<usize> {
    let mut rows: Vec<Vec<f64>> = c.to_vec();
    let mut taken: Vec<usize> = Vec::new();
    for i in 0..rows.len() {
        let p = (0..rows[i].len())
            .filter(|l| !taken.contains(l))
            .max_by(|&a, &b| rows[i][a].abs().total_cmp(&rows[i][b].abs()))
            .expect("fewer constraints than components");
        for k in i + 1..rows.len() {
            let factor = rows[k][p] / rows[i][p];
            let pivot_row = rows[i].clone();
            rows[k].iter_mut().zip(&pivot_row).for_each(|(x, y)| *x -= factor * y);
        }
        taken.push(p);
    }
    taken
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane normal to an axis gives that component's identity row and leaves the others; an
    /// inclined plane a tangent and a constraint whose pivot is its largest component; two
    /// planes through a node (the line they meet on) two constraints and the line's direction;
    /// a plane normal to a Dirichlet component nothing; with one component held, the normal
    /// restricted to the others. The projection leaves `c . u = 0`.
    #[test]
    fn the_rows_of_a_node_on_planes() {
        let free = |_: usize| false;
        let axis = NormalConstraints::new([([0, 1, 2], vec![[0.0, 1.0, 0.0]])], free);
        assert_eq!(axis.nodes[0].rows, vec![0, 2, 1]);
        assert_eq!(axis.nodes[0].q, vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        assert_eq!(axis.nodes[0].tangential, 2);
        let (s, c) = (60f64.to_radians().sin(), 60f64.to_radians().cos());
        let n60 = [-s, c, 0.0];
        let inclined = NormalConstraints::new([([10, 11, 12], vec![n60])], free);
        let node = &inclined.nodes[0];
        assert_eq!((node.rows.clone(), node.tangential), (vec![11, 12, 10], 2));
        let rows: Vec<&[f64]> = node.q.chunks(3).collect();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        for i in 0..3 {
            for j in 0..3 {
                assert!((dot(rows[i], rows[j]) - if i == j { 1.0 } else { 0.0 }).abs() < 1e-15, "orthonormal");
            }
        }
        // The constraint row in the components (y, z, x) of the rows: n60.
        assert!((rows[2][0] - c).abs() < 1e-15 && rows[2][1] == 0.0 && (rows[2][2] + s).abs() < 1e-15);
        let mut x = vec![0.0; 13];
        x[10..].copy_from_slice(&[1.0, 2.0, 3.0]);
        inclined.project(&mut x);
        assert!((x[10] * n60[0] + x[11] * n60[1]).abs() < 1e-15 && x[12] == 3.0);
        let line = NormalConstraints::new([([0, 1, 2], vec![[0.0, -1.0, 0.0], n60])], free);
        let node = &line.nodes[0];
        assert_eq!((node.rows.clone(), node.tangential), (vec![2, 1, 0], 1));
        assert_eq!(&node.q[..3], &[1.0, 0.0, 0.0]);
        assert_eq!(line.constraint_rows().collect::<Vec<_>>(), vec![1, 0]);
        // The same plane twice adds nothing.
        let twice = NormalConstraints::new([([0, 1, 2], vec![n60, [-s * (1.0 + 1e-7), c, 0.0]])], free);
        assert_eq!(twice.nodes[0].tangential, 2);
        let held_y = |d: usize| d == 1;
        assert!(NormalConstraints::new([([0, 1, 2], vec![[0.0, 1.0, 0.0]])], held_y).is_empty());
        let mixed = NormalConstraints::new([([0, 1, 2], vec![n60])], held_y);
        assert_eq!((mixed.nodes[0].rows.clone(), mixed.nodes[0].tangential), (vec![2, 0], 1));
        assert_eq!(mixed.nodes[0].q, vec![1.0, 0.0, 0.0, -1.0]);
        let tangents = line.tangents::<3>();
        assert_eq!(tangents[&0], vec![[0.0, 0.0, 1.0]]);
        let shifted = line.shifted(5);
        assert_eq!(shifted.constraint_rows().collect::<Vec<_>>(), vec![6, 5]);
    }

    /// Facet normals within the tolerance pass; one beyond it is named with its cell.
    #[test]
    fn a_boundary_off_its_plane_is_named() {
        let plane = SymmetryBc::new("sym", [1.0, 1.0]).unwrap();
        let mut check = Planarity::new(&plane);
        check.facet_normal(3, [2.0, 2.0 + 1e-7]);
        check.facet_normal(4, [-1.0, -1.0]);
        assert!(check.finish().is_ok());
        let mut check = Planarity::new(&plane);
        check.facet_normal(3, [1.0, 1.0]);
        check.facet_normal(7, [0.0, 1.0]);
        let e = check.finish().unwrap_err().to_string();
        assert!(e.contains("'sym'") && e.contains("cell 7") && e.contains("[0.0, 1.0]"), "{e}");
        assert!(SymmetryBc::<2>::new("z", [0.0, 0.0]).is_none() && SymmetryBc::new("a", [0.0, -2.0]).unwrap().axis() == Some(1));
    }
}
