//! Per-cell values: the geometric map of one cell evaluated at a quadrature rule.
//!
//! A cell is the image of its reference cell under the isoparametric map
//! `x(xi) = sum_k x_k N_k(xi)` of its geometry element (`N_k` P1/P2 on simplices, Q1/Q2 on tensor
//! cells; P2 geometry gives curved boundary cells). With `J = dx/dxi`, basis gradients map as
//! `grad phi = J^{-T} grad_xi phi`, and `dx = det J dxi`.
//!
//! [`CellValues`] holds the reference tabulations (computed once) and is re-initialised for each
//! cell with [`CellValues::reinit`], as in Ferrite.jl's `CellValues`; [`FacetValues`] does the same
//! on a facet of a cell, giving surface measure and outward unit normal.

use crate::element::{ReferenceCell, ReferenceElement, Tabulation};
use crate::quadrature::QuadratureRule;
use thiserror::Error;

/// A failure of the geometric map.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MapError {
    /// The Jacobian determinant is zero or negative at a quadrature point: the cell is inverted
    /// or degenerate.
    #[error("inverted or degenerate cell: det J = {det:.3e} at quadrature point {point}")]
    NonPositiveJacobian { point: usize, det: f64 },
}

/// Determinant and inverse of a small `D x D` matrix `j[row][col]`.
pub fn det_inv<const D: usize>(j: &[[f64; D]; D]) -> (f64, [[f64; D]; D]) {
    let mut inv = [[0.0; D]; D];
    match D {
        1 => {
            let det = j[0][0];
            inv[0][0] = 1.0 / det;
            (det, inv)
        }
        2 => {
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            inv[0][0] = j[1][1] / det;
            inv[0][1] = -j[0][1] / det;
            inv[1][0] = -j[1][0] / det;
            inv[1][1] = j[0][0] / det;
            (det, inv)
        }
        3 => {
            let c00 = j[1][1] * j[2][2] - j[1][2] * j[2][1];
            let c01 = j[1][2] * j[2][0] - j[1][0] * j[2][2];
            let c02 = j[1][0] * j[2][1] - j[1][1] * j[2][0];
            let det = j[0][0] * c00 + j[0][1] * c01 + j[0][2] * c02;
            inv[0][0] = c00 / det;
            inv[1][0] = c01 / det;
            inv[2][0] = c02 / det;
            inv[0][1] = (j[0][2] * j[2][1] - j[0][1] * j[2][2]) / det;
            inv[1][1] = (j[0][0] * j[2][2] - j[0][2] * j[2][0]) / det;
            inv[2][1] = (j[0][1] * j[2][0] - j[0][0] * j[2][1]) / det;
            inv[0][2] = (j[0][1] * j[1][2] - j[0][2] * j[1][1]) / det;
            inv[1][2] = (j[0][2] * j[1][0] - j[0][0] * j[1][2]) / det;
            inv[2][2] = (j[0][0] * j[1][1] - j[0][1] * j[1][0]) / det;
            (det, inv)
        }
        _ => unreachable!("dimension {D} not supported"),
    }
}

/// Physical point `x(xi_q) = sum_k x_k N_k(xi_q)` and Jacobian `J[a][b] = dx_a / dxi_b` of the
/// geometry map at tabulated point `q`.
#[inline]
fn map_point<const D: usize>(geo: &Tabulation<D>, coords: &[[f64; D]], q: usize) -> ([f64; D], [[f64; D]; D]) {
    let ng = geo.num_dofs;
    let mut x = [0.0; D];
    let mut jac = [[0.0; D]; D];
    for (k, xk) in coords.iter().enumerate() {
        let nk = geo.values[q * ng + k];
        let gk = geo.grads[q * ng + k];
        for a in 0..D {
            x[a] += nk * xk[a];
            for b in 0..D {
                jac[a][b] += xk[a] * gk[b];
            }
        }
    }
    (x, jac)
}

/// Physical gradient `J^{-T} g` of a reference gradient `g`, given `inv = J^{-1}`.
#[inline]
fn push_forward<const D: usize>(inv: &[[f64; D]; D], g: &[f64; D]) -> [f64; D] {
    std::array::from_fn(|a| (0..D).map(|b| inv[b][a] * g[b]).sum())
}

/// The P1-discontinuous pressure basis `{1, x_1 - c_1, ..., x_D - c_D}` at physical point `x`,
/// with `c` the cell's centroid: the dofs are the pressure at the centroid and its gradient.
/// Written into `out[..D + 1]`.
#[inline]
pub fn p1disc_basis<const D: usize>(x: &[f64; D], centroid: &[f64; D], out: &mut [f64]) {
    out[0] = 1.0;
    for d in 0..D {
        out[d + 1] = x[d] - centroid[d];
    }
}

/// The mass matrix `int_K psi_k psi_l w(x) dx` of the P1disc basis ([`p1disc_basis`]) on the cell
/// `cv` was last reinitialised for, with the weight `w` (e.g. `r` when axisymmetric): written
/// row-major into `mass`, `(D + 1) x (D + 1)`.
pub fn p1disc_mass<const D: usize>(cv: &CellValues<D>, weight: impl Fn(&[f64; D]) -> f64, mass: &mut [f64]) {
    let n = D + 1;
    mass[..n * n].iter_mut().for_each(|m| *m = 0.0);
    let mut psi = [0.0; 4];
    for q in 0..cv.num_points() {
        let w = cv.jxw[q] * weight(&cv.x[q]);
        p1disc_basis(&cv.x[q], &cv.centroid, &mut psi);
        for k in 0..n {
            for l in 0..n {
                mass[k * n + l] += w * psi[k] * psi[l];
            }
        }
    }
}

/// Geometric map and function-space values of one cell at the points of a quadrature rule.
#[derive(Clone, Debug)]
pub struct CellValues<const D: usize> {
    qr: QuadratureRule<D>,
    geo: Tabulation<D>,
    geo_at_centroid: Vec<f64>,
    fun: Tabulation<D>,
    /// Physical coordinates of the quadrature points.
    pub x: Vec<[f64; D]>,
    /// `|det J| * weight` at each quadrature point.
    pub jxw: Vec<f64>,
    /// Physical gradients of the function basis: `dphi[q * n + i]`.
    pub dphi: Vec<[f64; D]>,
    /// Physical centroid (image of the reference centroid).
    pub centroid: [f64; D],
    /// Second derivatives of the function basis, when asked for ([`CellValues::with_hessians`]).
    hessians: Option<Hessians<D>>,
}

/// The second derivatives of a cell's function basis: in reference coordinates (computed once),
/// with those of the geometry basis, and in physical coordinates (after each reinit).
#[derive(Clone, Debug)]
struct Hessians<const D: usize> {
    /// `d^2 phi_i / dxi_a dxi_b` at point `q`: `function[q * n + i][a][b]`.
    function: Vec<[[f64; D]; D]>,
    /// `d^2 N_k / dxi_a dxi_b` of the geometry basis, likewise.
    geometry: Vec<[[f64; D]; D]>,
    /// `d^2 phi_i / dx_a dx_b` at point `q`, likewise.
    physical: Vec<[[f64; D]; D]>,
}

/// The reference second derivatives of `element`'s basis at `points`, `[q * n + i][a][b]`: the
/// derivatives of the tabulated gradients by the fourth-order central difference
/// `(-g(xi + 2h) + 8 g(xi + h) - 8 g(xi - h) + g(xi - 2h)) / (12 h)`, exact for gradients of
/// degree up to 4 (the bases here are polynomials of degree at most 4: P2+ tetrahedra have a
/// quartic bubble), so only round-off, about `1e-16 / h`, remains. The bases are polynomials,
/// defined outside the reference cell too.
fn reference_hessians<const D: usize>(element: &ReferenceElement<D>, points: &[[f64; D]]) -> Vec<[[f64; D]; D]> {
    const H: f64 = 1e-2;
    let n = element.num_dofs();
    let mut out = vec![[[0.0; D]; D]; points.len() * n];
    for b in 0..D {
        for (step, weight) in [(2.0, -1.0), (1.0, 8.0), (-1.0, -8.0), (-2.0, 1.0)] {
            let shifted: Vec<[f64; D]> = points.iter().map(|p| std::array::from_fn(|d| p[d] + if d == b { step * H } else { 0.0 })).collect();
            let tab = element.tabulate(&shifted);
            for (o, g) in out.iter_mut().zip(&tab.grads) {
                for a in 0..D {
                    o[a][b] += weight * g[a] / (12.0 * H);
                }
            }
        }
    }
    out
}

impl<const D: usize> CellValues<D> {
    /// Tabulates `function` (e.g. the P2+ velocity) and `geometry` (P1 or P2) at `qr`.
    pub fn new(qr: QuadratureRule<D>, function: &ReferenceElement<D>, geometry: &ReferenceElement<D>) -> Self {
        let geo = geometry.tabulate(&qr.points);
        let fun = function.tabulate(&qr.points);
        let c: [f64; D] = geometry.cell().centroid();
        let geo_at_centroid = geometry.tabulate(&[c]).values;
        let nq = qr.len();
        let n = function.num_dofs();
        CellValues {
            qr,
            geo,
            geo_at_centroid,
            fun,
            x: vec![[0.0; D]; nq],
            jxw: vec![0.0; nq],
            dphi: vec![[0.0; D]; nq * n],
            centroid: [0.0; D],
            hessians: None,
        }
    }

    /// The same values with the second derivatives of the function basis as well
    /// ([`CellValues::hessian_phi`]); `function` and `geometry` are the elements given to
    /// [`CellValues::new`].
    pub fn with_hessians(mut self, function: &ReferenceElement<D>, geometry: &ReferenceElement<D>) -> Self {
        let (points, n) = (&self.qr.points, self.fun.num_dofs);
        debug_assert_eq!((function.num_dofs(), geometry.num_dofs()), (n, self.geo.num_dofs), "the elements given to CellValues::new");
        self.hessians = Some(Hessians {
            function: reference_hessians(function, points),
            geometry: reference_hessians(geometry, points),
            physical: vec![[[0.0; D]; D]; points.len() * n],
        });
        self
    }

    /// Physical second derivatives `d^2 phi_i / dx_a dx_b` of the basis at point `q`, `[i][a][b]`
    /// (valid after [`Self::reinit`]). With `x(xi)` the geometry map,
    /// `d^2 phi / dxi_i dxi_j = sum_ab d^2 phi / dx_a dx_b J_ai J_bj + sum_c dphi/dx_c d^2 x_c /
    /// dxi_i dxi_j`, solved for the physical ones: exact on curved (isoparametric) cells too.
    ///
    /// # Panics
    /// Unless the values were made [`CellValues::with_hessians`].
    #[inline]
    pub fn hessian_phi(&self, q: usize) -> &[[[f64; D]; D]] {
        let n = self.fun.num_dofs;
        let h = self.hessians.as_ref().expect("CellValues::with_hessians was not called");
        &h.physical[q * n..(q + 1) * n]
    }

    /// Number of quadrature points.
    pub fn num_points(&self) -> usize {
        self.qr.len()
    }
    /// Number of function basis functions.
    pub fn num_dofs(&self) -> usize {
        self.fun.num_dofs
    }
    /// The quadrature rule.
    pub fn rule(&self) -> &QuadratureRule<D> {
        &self.qr
    }
    /// Basis function values at point `q` (they do not depend on the cell).
    #[inline]
    pub fn phi(&self, q: usize) -> &[f64] {
        let n = self.fun.num_dofs;
        &self.fun.values[q * n..(q + 1) * n]
    }
    /// Physical basis gradients at point `q` (valid after [`Self::reinit`]).
    #[inline]
    pub fn grad_phi(&self, q: usize) -> &[[f64; D]] {
        let n = self.fun.num_dofs;
        &self.dphi[q * n..(q + 1) * n]
    }

    /// Re-initialises for the cell with geometry nodes `coords` (in the geometry element's node
    /// order). Fails when `det J <= 0` at a quadrature point.
    pub fn reinit(&mut self, coords: &[[f64; D]]) -> Result<(), MapError> {
        let ng = self.geo.num_dofs;
        debug_assert_eq!(coords.len(), ng);
        let n = self.fun.num_dofs;
        let mut c = [0.0; D];
        for (k, xk) in coords.iter().enumerate() {
            for d in 0..D {
                c[d] += self.geo_at_centroid[k] * xk[d];
            }
        }
        self.centroid = c;
        for q in 0..self.qr.len() {
            let (x, jac) = map_point(&self.geo, coords, q);
            let (det, inv) = det_inv(&jac);
            if !(det > 0.0) {
                return Err(MapError::NonPositiveJacobian { point: q, det });
            }
            self.x[q] = x;
            self.jxw[q] = det * self.qr.weights[q];
            // grad phi = J^{-T} grad_xi phi:  (grad phi)_a = sum_b inv[b][a] (grad_xi phi)_b
            for i in 0..n {
                self.dphi[q * n + i] = push_forward(&inv, &self.fun.grads[q * n + i]);
            }
            if let Some(h) = &mut self.hessians {
                physical_hessians(h, coords, &inv, &self.dphi[q * n..(q + 1) * n], q, self.geo.num_dofs);
            }
        }
        Ok(())
    }
}

/// The physical second derivatives at point `q` ([`CellValues::hessian_phi`]): `H = J^{-T} (H_ref
/// - sum_c (dphi/dx_c) G_c) J^{-1}`, `G_c` the reference second derivatives of the map's
/// component `c`; `inv = J^{-1}`, `dphi` the physical gradients there.
fn physical_hessians<const D: usize>(h: &mut Hessians<D>, coords: &[[f64; D]], inv: &[[f64; D]; D], dphi: &[[f64; D]], q: usize, ng: usize) {
    let mut g = [[[0.0; D]; D]; D];
    for (k, xk) in coords.iter().enumerate() {
        let nk = &h.geometry[q * ng + k];
        for c in 0..D {
            for i in 0..D {
                for j in 0..D {
                    g[c][i][j] += xk[c] * nk[i][j];
                }
            }
        }
    }
    let n = dphi.len();
    for (i, grad) in dphi.iter().enumerate() {
        let mut m = h.function[q * n + i];
        for c in 0..D {
            for a in 0..D {
                for b in 0..D {
                    m[a][b] -= grad[c] * g[c][a][b];
                }
            }
        }
        h.physical[q * n + i] =
            std::array::from_fn(|a| std::array::from_fn(|b| (0..D).map(|r| (0..D).map(|s| inv[r][a] * m[r][s] * inv[s][b]).sum::<f64>()).sum()));
    }
}

/// Values on facet `f` of a cell: the facet rule mapped into the cell, surface measure
/// `|J t_1|` (2D) or `|J t_1 x J t_2|` (3D) times the weight, and the outward unit normal.
#[derive(Clone, Debug)]
pub struct FacetValues<const D: usize> {
    /// Per facet of the reference cell: tabulations of geometry and function at the mapped points.
    per_facet: Vec<(Tabulation<D>, Tabulation<D>)>,
    weights: Vec<f64>,
    tangents: Vec<[[f64; D]; 2]>,
    /// Physical coordinates of the quadrature points on the current facet.
    pub x: Vec<[f64; D]>,
    /// Surface measure times weight.
    pub jxw: Vec<f64>,
    /// Outward unit normal at each point.
    pub normal: Vec<[f64; D]>,
    /// Physical gradients of the function basis, `dphi[q * n + i]`.
    pub dphi: Vec<[f64; D]>,
    current: usize,
}

impl<const D: usize> FacetValues<D> {
    /// `facet_points`/`facet_weights`: a rule on the reference facet cell (points with `D - 1`
    /// components, padded in a `[f64; 2]`).
    pub fn new(
        cell: ReferenceCell,
        facet_points: &[[f64; 2]],
        facet_weights: &[f64],
        function: &ReferenceElement<D>,
        geometry: &ReferenceElement<D>,
    ) -> Self {
        let mut per_facet = Vec::new();
        let mut tangents = Vec::new();
        for f in 0..cell.num_facets() {
            let pts: Vec<[f64; D]> = facet_points.iter().map(|eta| cell.facet_point(f, eta)).collect();
            per_facet.push((geometry.tabulate(&pts), function.tabulate(&pts)));
            // Reference tangents of the facet parameterisation (constant: facets are flat).
            let p0: [f64; D] = cell.facet_point(f, &[0.0, 0.0]);
            let p1: [f64; D] = cell.facet_point(f, &[1.0, 0.0]);
            let p2: [f64; D] = cell.facet_point(f, &[0.0, 1.0]);
            let t1 = std::array::from_fn(|d| p1[d] - p0[d]);
            let t2 = std::array::from_fn(|d| p2[d] - p0[d]);
            tangents.push([t1, t2]);
        }
        let nq = facet_weights.len();
        let n = function.num_dofs();
        FacetValues {
            per_facet,
            weights: facet_weights.to_vec(),
            tangents,
            x: vec![[0.0; D]; nq],
            jxw: vec![0.0; nq],
            normal: vec![[0.0; D]; nq],
            dphi: vec![[0.0; D]; nq * n],
            current: 0,
        }
    }

    /// Number of quadrature points.
    pub fn num_points(&self) -> usize {
        self.weights.len()
    }
    /// Basis values at point `q` of the current facet.
    #[inline]
    pub fn phi(&self, q: usize) -> &[f64] {
        let t = &self.per_facet[self.current].1;
        &t.values[q * t.num_dofs..(q + 1) * t.num_dofs]
    }
    /// Physical basis gradients at point `q` of the current facet.
    #[inline]
    pub fn grad_phi(&self, q: usize) -> &[[f64; D]] {
        let n = self.per_facet[self.current].1.num_dofs;
        &self.dphi[q * n..(q + 1) * n]
    }

    /// Re-initialises for facet `facet` of the cell with geometry nodes `coords`.
    pub fn reinit(&mut self, coords: &[[f64; D]], facet: usize) -> Result<(), MapError> {
        self.current = facet;
        let (geo, fun) = &self.per_facet[facet];
        let n = fun.num_dofs;
        let [t1, t2] = self.tangents[facet];
        for q in 0..self.weights.len() {
            let (x, jac) = map_point(geo, coords, q);
            let (det, inv) = det_inv(&jac);
            if !(det > 0.0) {
                return Err(MapError::NonPositiveJacobian { point: q, det });
            }
            let jt = |t: &[f64; D]| -> [f64; D] { std::array::from_fn(|a| (0..D).map(|b| jac[a][b] * t[b]).sum()) };
            let (measure, mut nrm) = match D {
                2 => {
                    let a = jt(&t1);
                    let len = (a[0] * a[0] + a[1] * a[1]).sqrt();
                    let mut nv = [0.0; D];
                    nv[0] = a[1] / len;
                    nv[1] = -a[0] / len;
                    (len, nv)
                }
                3 => {
                    let a = jt(&t1);
                    let b = jt(&t2);
                    let c = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
                    let len = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                    let mut nv = [0.0; D];
                    for d in 0..3 {
                        nv[d] = c[d] / len;
                    }
                    (len, nv)
                }
                _ => unreachable!(),
            };
            // The reference facets are outward oriented for positively oriented cells; a 2D edge
            // (a -> b) traversed counter-clockwise has outward normal (dy, -dx). Guard anyway by
            // the direction from the cell centre, cheap and robust for curved cells.
            let centre: [f64; D] = {
                let mut c = [0.0; D];
                for xk in coords {
                    for d in 0..D {
                        c[d] += xk[d] / coords.len() as f64;
                    }
                }
                c
            };
            let outward: f64 = (0..D).map(|d| (x[d] - centre[d]) * nrm[d]).sum();
            if outward < 0.0 {
                for v in nrm.iter_mut() {
                    *v = -*v;
                }
            }
            self.x[q] = x;
            self.jxw[q] = measure * self.weights[q];
            self.normal[q] = nrm;
            for i in 0..n {
                self.dphi[q * n + i] = push_forward(&inv, &fun.grads[q * n + i]);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature;

    /// The physical second derivatives of the basis: a quadratic interpolated on an affine P2+
    /// triangle and tetrahedron has its own (constant) Hessian at every point; on a curved P2
    /// triangle the coordinate functions, `x = sum_k x_k phi_k` in the isoparametric basis, have
    /// none (the geometry's own second derivatives are taken out), to round-off.
    #[test]
    fn hessians_of_interpolated_quadratics_and_of_a_curved_cells_coordinates() {
        // f = x^2 + 3 x y - 2 y^2 (+ z^2 - x z in 3D).
        let fun = ReferenceElement::p2plus_triangle();
        let geo = ReferenceElement::p1_triangle();
        let mut cv = CellValues::new(quadrature::triangle(5), &fun, &geo).with_hessians(&fun, &geo);
        let coords = [[1.0, 1.0], [3.0, 1.5], [1.5, 4.0]];
        cv.reinit(&coords).unwrap();
        let at = |xi: &[f64; 2]| -> [f64; 2] {
            let l = [1.0 - xi[0] - xi[1], xi[0], xi[1]];
            std::array::from_fn(|d| (0..3).map(|k| l[k] * coords[k][d]).sum())
        };
        let f: Vec<f64> = fun.nodes().iter().map(at).map(|[x, y]| x * x + 3.0 * x * y - 2.0 * y * y).collect();
        for q in 0..cv.num_points() {
            let h: [[f64; 2]; 2] = std::array::from_fn(|a| std::array::from_fn(|b| (0..7).map(|i| f[i] * cv.hessian_phi(q)[i][a][b]).sum()));
            assert!(
                (h[0][0] - 2.0).abs() < 1e-10 && (h[0][1] - 3.0).abs() < 1e-10 && (h[1][0] - 3.0).abs() < 1e-10 && (h[1][1] + 4.0).abs() < 1e-10,
                "{h:?}"
            );
        }
        let fun3 = ReferenceElement::p2plus_tetrahedron();
        let geo3 = ReferenceElement::p1_tetrahedron();
        let mut cv3 = CellValues::new(quadrature::tetrahedron(4), &fun3, &geo3).with_hessians(&fun3, &geo3);
        let c3 = [[0.1, 0.0, 0.2], [1.2, 0.1, 0.0], [0.3, 0.9, 0.1], [0.2, 0.3, 1.1]];
        cv3.reinit(&c3).unwrap();
        let f3: Vec<f64> = fun3
            .nodes()
            .iter()
            .map(|xi| {
                let l = [1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]];
                let p: [f64; 3] = std::array::from_fn(|d| (0..4).map(|k| l[k] * c3[k][d]).sum());
                p[0] * p[0] + 3.0 * p[0] * p[1] - 2.0 * p[1] * p[1] + p[2] * p[2] - p[0] * p[2]
            })
            .collect();
        let exact = [[2.0, 3.0, -1.0], [3.0, -4.0, 0.0], [-1.0, 0.0, 2.0]];
        for q in 0..cv3.num_points() {
            for a in 0..3 {
                for b in 0..3 {
                    let h: f64 = (0..15).map(|i| f3[i] * cv3.hessian_phi(q)[i][a][b]).sum();
                    assert!((h - exact[a][b]).abs() < 1e-9, "3D H[{a}][{b}] = {h}");
                }
            }
        }
        // A curved P2 triangle, its third edge bowed out; the isoparametric P2 basis.
        let p2 = ReferenceElement::p2_triangle();
        let mut curved = CellValues::new(quadrature::triangle(5), &p2, &p2).with_hessians(&p2, &p2);
        let nodes = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [0.62, 0.62], [0.0, 0.5]];
        curved.reinit(&nodes).unwrap();
        let mut bowed = 0.0f64;
        for q in 0..curved.num_points() {
            for c in 0..2 {
                for a in 0..2 {
                    for b in 0..2 {
                        let h: f64 = (0..6).map(|k| nodes[k][c] * curved.hessian_phi(q)[k][a][b]).sum();
                        assert!(h.abs() < 1e-10, "curved: d2 x_{c} / dx_{a} dx_{b} = {h}");
                        bowed = bowed.max(curved.hessian_phi(q)[4][a][b].abs());
                    }
                }
            }
        }
        assert!(bowed > 1.0, "the basis itself has second derivatives");
        // P2+ on the curved P2 cell (the fluid's pairing): the second derivatives against a
        // central difference of the physical gradients at points shifted in physical space. A
        // shifted point's reference coordinates are found by Newton on the map; its gradients
        // by reinitialising a one-point rule there.
        let p2plus = ReferenceElement::p2plus_triangle();
        let mut cv = CellValues::new(quadrature::triangle(3), &p2plus, &p2).with_hessians(&p2plus, &p2);
        cv.reinit(&nodes).unwrap();
        let gradients_at = |xi: [f64; 2]| {
            let rule = QuadratureRule { cell: ReferenceCell::Triangle, degree: 0, points: vec![xi], weights: vec![1.0] };
            let mut one = CellValues::new(rule, &p2plus, &p2);
            one.reinit(&nodes).unwrap();
            (one.x[0], one.grad_phi(0).to_vec())
        };
        let reference_of = |x: [f64; 2], mut xi: [f64; 2]| {
            for _ in 0..30 {
                let tab = p2.tabulate(&[xi]);
                let (mut y, mut j) = ([0.0; 2], [[0.0; 2]; 2]);
                for k in 0..6 {
                    for a in 0..2 {
                        y[a] += tab.values[k] * nodes[k][a];
                        for b in 0..2 {
                            j[a][b] += nodes[k][a] * tab.grads[k][b];
                        }
                    }
                }
                let (_, inv) = det_inv(&j);
                let r = [x[0] - y[0], x[1] - y[1]];
                xi = std::array::from_fn(|a| xi[a] + inv[a][0] * r[0] + inv[a][1] * r[1]);
            }
            xi
        };
        let h = 1e-5;
        for q in 0..cv.num_points() {
            let xi0 = cv.rule().points[q];
            let x0 = cv.x[q];
            for b in 0..2 {
                let shifted = |sign: f64| {
                    let x: [f64; 2] = std::array::from_fn(|d| x0[d] + if d == b { sign * h } else { 0.0 });
                    gradients_at(reference_of(x, xi0)).1
                };
                let (plus, minus) = (shifted(1.0), shifted(-1.0));
                for i in 0..7 {
                    for a in 0..2 {
                        let fd = (plus[i][a] - minus[i][a]) / (2.0 * h);
                        let exact = cv.hessian_phi(q)[i][a][b];
                        assert!((fd - exact).abs() < 1e-5 * (1.0 + exact.abs()), "P2+ on curved P2: d2 phi_{i} / dx_{a} dx_{b} = {exact} vs FD {fd}");
                    }
                }
            }
        }
    }

    #[test]
    fn affine_triangle_area_and_gradients() {
        let fun = ReferenceElement::p2plus_triangle();
        let geo = ReferenceElement::p1_triangle();
        let mut cv = CellValues::new(quadrature::triangle(5), &fun, &geo);
        let coords = [[1.0, 1.0], [3.0, 1.5], [1.5, 4.0]];
        cv.reinit(&coords).unwrap();
        let area: f64 = cv.jxw.iter().sum();
        let exact = 0.5 * ((2.0f64) * 3.0 - 0.5 * 0.5);
        assert!((area - exact).abs() < 1e-13);
        // Interpolate f(x, y) = x^2 - 3xy: gradients (2x - 3y, -3x) reproduced.
        let nodes: Vec<[f64; 2]> = fun
            .nodes()
            .iter()
            .map(|xi| {
                let l = [1.0 - xi[0] - xi[1], xi[0], xi[1]];
                std::array::from_fn(|d| (0..3).map(|k| l[k] * coords[k][d]).sum())
            })
            .collect();
        let f: Vec<f64> = nodes.iter().map(|p| p[0] * p[0] - 3.0 * p[0] * p[1]).collect();
        for q in 0..cv.num_points() {
            let mut g = [0.0; 2];
            for (i, gi) in cv.grad_phi(q).iter().enumerate() {
                g[0] += f[i] * gi[0];
                g[1] += f[i] * gi[1];
            }
            let [x, y] = cv.x[q];
            assert!((g[0] - (2.0 * x - 3.0 * y)).abs() < 1e-12);
            assert!((g[1] + 3.0 * x).abs() < 1e-12);
        }
    }

    #[test]
    fn inverted_cell_is_refused() {
        let fun = ReferenceElement::p1_triangle();
        let mut cv = CellValues::new(quadrature::triangle(2), &fun, &fun);
        let err = cv.reinit(&[[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]]).unwrap_err();
        assert!(matches!(err, MapError::NonPositiveJacobian { .. }));
    }

    #[test]
    fn curved_p2_triangle_area_matches_circle_sector() {
        // Quarter disc of radius 1 as one P2 triangle: the curved edge's midpoint on the circle.
        let fun = ReferenceElement::p2_triangle();
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let coords = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [s, s], [0.0, 0.5]];
        let mut cv = CellValues::new(quadrature::triangle(8), &fun, &fun);
        cv.reinit(&coords).unwrap();
        let area: f64 = cv.jxw.iter().sum();
        // The curved side is the parabola through (1,0), (s,s), (0,1): area = triangle 1/2 plus
        // the parabolic segment 2/3 * chord * sagitta = (2/3) sqrt(2) (s - 1/2) sqrt(2).
        let exact = 0.5 + 4.0 / 3.0 * (s - 0.5);
        assert!((area - exact).abs() < 1e-14, "{area} vs {exact}");
    }

    #[test]
    fn facet_normals_point_outward_and_measure_is_exact() {
        let fun = ReferenceElement::p1_tetrahedron();
        let q = quadrature::triangle(2);
        let pts: Vec<[f64; 2]> = q.points.clone();
        let mut fv = FacetValues::new(ReferenceCell::Tetrahedron, &pts, &q.weights, &fun, &fun);
        let coords = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]];
        let mut total = [0.0; 3];
        for f in 0..4 {
            fv.reinit(&coords, f).unwrap();
            for qq in 0..fv.num_points() {
                for d in 0..3 {
                    total[d] += fv.jxw[qq] * fv.normal[qq][d];
                }
            }
        }
        // Closed surface: integral of the normal vanishes.
        for t in total {
            assert!(t.abs() < 1e-13);
        }
        fv.reinit(&coords, 3).unwrap(); // z = 0 face, area 2
        let a: f64 = fv.jxw.iter().sum();
        assert!((a - 2.0).abs() < 1e-13);
        assert!((fv.normal[0][2] + 1.0).abs() < 1e-14);
        let _ = [[0.0f64; 2]; 0];
        let seg = quadrature::segment(3);
        let pts2: Vec<[f64; 2]> = seg.points.iter().map(|p| [p[0], 0.0]).collect();
        let tri = ReferenceElement::p1_triangle();
        let mut fv2 = FacetValues::new(ReferenceCell::Triangle, &pts2, &seg.weights, &tri, &tri);
        fv2.reinit(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], 0).unwrap();
        assert!((fv2.normal[0][1] + 1.0).abs() < 1e-14);
    }
}
