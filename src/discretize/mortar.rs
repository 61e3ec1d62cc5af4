//! Mortar coupling of two contact boundaries in 2D (plane and axisymmetric): the weighted gaps
//! and the force transfer between a slave boundary, which carries the contact pressures, and a
//! master boundary, whose meshes need not match.
//!
//! With `N_j` the slave's Q2 trace basis and `N_k` the master's, the mortar matrix is
//!
//! ```text
//! M_jk = int_{Gamma_s} N_j(s) N_k(pi(s)) w dA_0,
//! ```
//!
//! over the slave's reference surface (`w = R` axisymmetric), `pi` the closest-point projection
//! of the slave's current position onto the master's. With `m_j = sum_k M_jk` (the slave weight
//! `int N_j dA_0` where the master lies under all of it) and `n_j` the master's outward normal at
//! the projection of slave node `j`, the weighted gap and the forces of the pressure `lambda_j` are
//!
//! ```text
//! g_j = sum_k M_jk (x_j - x_k) . n_j,    f_j = m_j lambda_j n_j,    f_k = -M_jk lambda_j n_j,
//! ```
//!
//! so a uniform pressure loads both sides with their consistent nodal forces `lambda int N dA_0`
//! (`sum_j N_j = 1` on the slave, `sum_k N_k = 1` on the master) and a flat interface's gap is
//! exact: the non-matching patch test holds to round-off. The integrals are split where the
//! master's facet ends project onto the slave's facet and taken by 5-point Gauss rules on each
//! piece (exact for straight facets). The Newton matrix holds `M` and `n` fixed in an iteration
//! (they are recomputed at every assembly): exact where the surfaces do not slide or turn, a
//! linearly converging Newton where they do.

use super::solid::SolidError;
use fdfsi_fem::element::ReferenceElement;
use fdfsi_fem::mesh::Mesh;

/// A Q2 boundary facet (a quadratic edge): its displacement nodes at the parameters 0, 1 and
/// 1/2, and the cell it bounds.
#[derive(Clone, Copy, Debug)]
pub struct Edge {
    pub nodes: [usize; 3],
    pub cell: usize,
}

/// The quadratic edges of boundary `name` (`node_of(cell, local)` numbers the nodes).
pub fn boundary_edges<const D: usize>(
    mesh: &Mesh<D>,
    element: &ReferenceElement<D>,
    name: &str,
    node_of: impl Fn(usize, usize) -> usize,
) -> Result<Vec<Edge>, SolidError> {
    let facets = mesh.boundary_facets(name).map_err(|source| SolidError::ContactBoundary { boundary: name.into(), source })?;
    Ok(facets
        .iter()
        .map(|bf| {
            let local = element.facet_nodes(bf.facet);
            let (ends, mid): (Vec<usize>, Vec<usize>) = local.iter().partition(|&&k| element.entities()[k].dim == 0);
            Edge { nodes: [node_of(bf.cell, ends[0]), node_of(bf.cell, ends[1]), node_of(bf.cell, mid[0])], cell: bf.cell }
        })
        .collect())
}

/// The quadratic Lagrange basis on `[0, 1]` at the nodes 0, 1, 1/2 and its derivative.
fn basis(s: f64) -> ([f64; 3], [f64; 3]) {
    ([(1.0 - s) * (1.0 - 2.0 * s), s * (2.0 * s - 1.0), 4.0 * s * (1.0 - s)], [4.0 * s - 3.0, 4.0 * s - 1.0, 4.0 - 8.0 * s])
}

fn point(e: &Edge, s: f64, x: &impl Fn(usize) -> [f64; 2]) -> ([f64; 2], [f64; 2]) {
    let (phi, dphi) = basis(s);
    let mut p = [0.0; 2];
    let mut t = [0.0; 2];
    for (k, &node) in e.nodes.iter().enumerate() {
        let xk = x(node);
        for d in 0..2 {
            p[d] += phi[k] * xk[d];
            t[d] += dphi[k] * xk[d];
        }
    }
    (p, t)
}

/// How far beyond a master edge's ends (in its parameter) a point still projects onto the end:
/// where the two surfaces end together (blocks of one width), Newton's iterates would otherwise
/// take an end node on and off the master from one iteration to the next.
const END_TOLERANCE: f64 = 0.05;

/// The closest point to `y` on the edge `e` (positions `x`): its parameter (clamped to the
/// edge) and distance, by Newton from the chord's projection; `None` off the edge (beyond its
/// ends by more than [`END_TOLERANCE`]).
fn project(e: &Edge, y: &[f64; 2], x: &impl Fn(usize) -> [f64; 2]) -> Option<(f64, f64)> {
    let (a, b) = (x(e.nodes[0]), x(e.nodes[1]));
    let ab = [b[0] - a[0], b[1] - a[1]];
    let mut s = ((y[0] - a[0]) * ab[0] + (y[1] - a[1]) * ab[1]) / (ab[0] * ab[0] + ab[1] * ab[1]);
    for _ in 0..8 {
        let (p, t) = point(e, s, x);
        // f(s) = (p - y) . t, f'(s) = t . t + (p - y) . t', t' = sum 4 [1, 1, -2] x_k.
        let r = [p[0] - y[0], p[1] - y[1]];
        let tt: [f64; 2] = std::array::from_fn(|d| 4.0 * (x(e.nodes[0])[d] + x(e.nodes[1])[d] - 2.0 * x(e.nodes[2])[d]));
        let f = r[0] * t[0] + r[1] * t[1];
        let df = t[0] * t[0] + t[1] * t[1] + r[0] * tt[0] + r[1] * tt[1];
        if df <= 0.0 {
            break;
        }
        let step = f / df;
        s -= step;
        if step.abs() < 1e-15 {
            break;
        }
    }
    if !(-END_TOLERANCE..=1.0 + END_TOLERANCE).contains(&s) {
        return None;
    }
    let s = s.clamp(0.0, 1.0);
    let (p, _) = point(e, s, x);
    Some((s, ((p[0] - y[0]).powi(2) + (p[1] - y[1]).powi(2)).sqrt()))
}

/// The closest point to `y` on the master edges: `(edge, parameter)`.
fn closest(master: &[Edge], y: &[f64; 2], x: &impl Fn(usize) -> [f64; 2]) -> Option<(usize, f64)> {
    master
        .iter()
        .enumerate()
        .filter_map(|(i, e)| project(e, y, x).map(|(s, dist)| (i, s, dist)))
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .map(|(i, s, _)| (i, s))
}

/// The outward unit normal of master edge `e` at `s`: the tangent turned to point away from
/// `inside` (a point of the cell it bounds).
fn outward_normal(e: &Edge, s: f64, inside: &[f64; 2], x: &impl Fn(usize) -> [f64; 2]) -> [f64; 2] {
    let (p, t) = point(e, s, x);
    let len = (t[0] * t[0] + t[1] * t[1]).sqrt();
    let n = [t[1] / len, -t[0] / len];
    if (inside[0] - p[0]) * n[0] + (inside[1] - p[1]) * n[1] > 0.0 {
        [-n[0], -n[1]]
    } else {
        n
    }
}

/// One slave node's mortar row: the master's outward normal at the node's projection and its
/// entries `(master node, M_jk)`.
#[derive(Clone, Debug)]
pub struct MortarRow {
    pub normal: [f64; 2],
    pub master: Vec<(usize, f64)>,
}

impl MortarRow {
    /// `m_j = sum_k M_jk`.
    pub fn weight(&self) -> f64 {
        self.master.iter().map(|(_, m)| m).sum()
    }
}

/// Gauss-Legendre points and weights on `[0, 1]` (5 points: exact to degree 9).
const GAUSS5: [(f64, f64); 5] = [
    (0.046_910_077_030_668_004, 0.118_463_442_528_094_54),
    (0.230_765_344_947_158_45, 0.239_314_335_249_683_23),
    (0.5, 0.284_444_444_444_444_45),
    (0.769_234_655_052_841_6, 0.239_314_335_249_683_23),
    (0.953_089_922_969_332, 0.118_463_442_528_094_54),
];

/// The mortar rows of the slave nodes `slave_nodes` (sorted; `None` where the node's projection
/// misses the master), from the slave and master edges, the reference and current positions of
/// the nodes, the inside point of each master edge's cell, and the measure weight (`R`
/// axisymmetric, else 1) at a reference point.
pub fn mortar_rows(
    slave_nodes: &[usize],
    slave: &[Edge],
    master: &[Edge],
    master_inside: &[[f64; 2]],
    x_ref: impl Fn(usize) -> [f64; 2],
    x: impl Fn(usize) -> [f64; 2],
    weight: impl Fn(&[f64; 2]) -> f64,
) -> Vec<Option<MortarRow>> {
    let mut rows: Vec<Option<MortarRow>> = slave_nodes
        .iter()
        .map(|&node| {
            closest(master, &x(node), &x).map(|(i, s)| MortarRow { normal: outward_normal(&master[i], s, &master_inside[i], &x), master: Vec::new() })
        })
        .collect();
    for e in slave {
        // Split at the projections of the master edges' ends onto the slave edge's chord.
        let (a, b) = (x(e.nodes[0]), x(e.nodes[1]));
        let ab = [b[0] - a[0], b[1] - a[1]];
        let len2 = ab[0] * ab[0] + ab[1] * ab[1];
        let mut cuts: Vec<f64> = master
            .iter()
            .flat_map(|m| [m.nodes[0], m.nodes[1]])
            .map(|node| {
                let p = x(node);
                ((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / len2
            })
            .filter(|s| *s > 1e-12 && *s < 1.0 - 1e-12)
            .chain([0.0, 1.0])
            .collect();
        cuts.sort_by(f64::total_cmp);
        cuts.dedup_by(|p, q| (*p - *q).abs() < 1e-12);
        for piece in cuts.windows(2) {
            let (s0, s1) = (piece[0], piece[1]);
            for &(g, gw) in &GAUSS5 {
                let s = s0 + (s1 - s0) * g;
                let (xr, tr) = point(e, s, &x_ref);
                let da = (tr[0] * tr[0] + tr[1] * tr[1]).sqrt() * (s1 - s0) * gw * weight(&xr);
                let (y, _) = point(e, s, &x);
                let Some((i, eta)) = closest(master, &y, &x) else { continue };
                let (phi_s, _) = basis(s);
                let (phi_m, _) = basis(eta);
                // A slave node without a multiplier (on the axis, of weight 0) passes its basis
                // function to the edge's other nodes, so that the multipliers' basis still sums
                // to 1 and the master takes the whole load (their weights do not change: its
                // basis function integrates to 0 against R).
                let present: Vec<Option<usize>> = e.nodes.iter().map(|js| slave_nodes.binary_search(js).ok()).collect();
                let count = present.iter().flatten().count() as f64;
                let absent: f64 = phi_s.iter().zip(&present).filter(|(_, p)| p.is_none()).map(|(v, _)| v).sum();
                for (a, slot) in present.iter().enumerate() {
                    let Some(j) = *slot else { continue };
                    let Some(row) = rows[j].as_mut() else { continue };
                    let psi = phi_s[a] + absent / count;
                    for (b, &km) in master[i].nodes.iter().enumerate() {
                        let value = psi * phi_m[b] * da;
                        match row.master.iter_mut().find(|(k, _)| *k == km) {
                            Some(entry) => entry.1 += value,
                            None => row.master.push((km, value)),
                        }
                    }
                }
            }
        }
    }
    for row in rows.iter_mut().flatten() {
        row.master.sort_by_key(|(k, _)| *k);
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two flat non-matching edges of the line y = 0: the master [0, 1] in one edge, the slave
    /// [0, 1] in two; each slave row sums to the node's weight and the force transfer of a
    /// uniform pressure is the master's consistent load (1/6, 1/6, 2/3).
    #[test]
    fn uniform_pressure_transfers_consistently_across_non_matching_edges() {
        let points = [[0.0, 0.0], [1.0, 0.0], [0.5, 0.0], [0.0, 0.0], [0.5, 0.0], [0.25, 0.0], [1.0, 0.0], [0.75, 0.0]];
        let x = |n: usize| points[n];
        let master = [Edge { nodes: [0, 1, 2], cell: 0 }];
        let slave = [Edge { nodes: [3, 4, 5], cell: 1 }, Edge { nodes: [4, 6, 7], cell: 2 }];
        let rows = mortar_rows(&[3, 4, 5, 6, 7], &slave, &master, &[[0.5, -1.0]], x, x, |_| 1.0);
        let weights: Vec<f64> = rows.iter().map(|r| r.as_ref().unwrap().weight()).collect();
        for (w, expected) in weights.iter().zip([1.0 / 12.0, 1.0 / 6.0, 1.0 / 3.0, 1.0 / 12.0, 1.0 / 3.0]) {
            assert!((w - expected).abs() < 1e-15, "{weights:?}");
        }
        let mut load = [0.0; 3];
        for row in rows.iter().flatten() {
            assert_eq!(row.normal, [0.0, 1.0]);
            for &(k, m) in &row.master {
                load[k] += m;
            }
        }
        for (l, expected) in load.iter().zip([1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0]) {
            assert!((l - expected).abs() < 1e-15, "{load:?}");
        }
    }
}
