//! Frictionless contact of a solid with a rigid plane, by Lagrange multipliers with the
//! complementarity conditions solved in the same Newton iteration as everything else (a
//! semi-smooth Newton method, the primal-dual active set strategy of Hueber & Wohlmuth, Comput.
//! Methods Appl. Mech. Engrg. 194, 2005).
//!
//! # Weak form
//!
//! On the contact boundary `Gamma_c` of the solid, with the plane through `p` with unit normal
//! `n` (pointing to the side the solid stays on), the gap `g(x) = (x - p) . n` must stay
//! non-negative and the contact pressure `lambda` (the plane pushes along `n`) non-negative,
//! one of them zero. The multiplier is the displacement's trace space: `lambda_h = sum_i lambda_i
//! psi_i` over the nodes `i` of `Gamma_c`, `psi_i` the Q2 basis, and the surface mass matrix is
//! lumped to its row sums, the node weights `w_i = int_Gamma_c psi_i dA` on the reference
//! configuration (weight `R` axisymmetric; positive for Q2 Lagrange facets, except at a node on
//! the axis, `R = 0`, which carries no load and has no multiplier). With the current
//! positions `x_i` (in a total- or an updated-Lagrangian solve alike)
//!
//! ```text
//! g_i  = w_i (x_i - p) . n                                        (the weighted gap of node i),
//! R_u  -= lambda_i w_i n   at node i                              (the plane's push),
//! min(lambda_i, c_i g_i) = 0   for every node i                   (lambda_i >= 0, g_i >= 0, lambda_i g_i = 0),
//! ```
//!
//! the last written as the residual `R_i = -min(lambda_i, c_i g_i) / c_i`: `-g_i` where the node
//! is active (`lambda_i >= c_i g_i`; the Jacobian row `-w_i n`, the transpose of the push's
//! column, so that the system stays symmetric) and `-lambda_i / c_i` where it is not (a diagonal
//! `-1/c_i`). Lumping makes every node's gap non-negative at convergence (the consistent mass
//! matrix lets nodes at the edge of the contact zone penetrate: 1e-5 of the channel height in
//! a flap stopped by a plane), and costs no accuracy where it is checked: the loads `lambda w_i`
//! of a uniform pressure are the consistent ones, and Hertz's width and peak come out within
//! 0.03 %. `c_i > 0` weighs pressure against weighted gap; the solution does not depend on it,
//! only the path of the active set. [`complementarity_scale`] takes `c_i = G / (w_i l_i)`,
//! `l_i` the size of the node's facets, so that a strain of order one in an element of the node's
//! size weighs as a pressure of order `G`.
//!
//! A uniform contact pressure lies in the multiplier space (the `psi_i` sum to one), so a block
//! pressed on the plane by a uniform load carries it exactly (the patch test,
//! `tests/contact.rs`). `lambda` is the nominal contact pressure, per unit reference area (the
//! Cauchy pressure is `lambda dA_0 / da`), whichever configuration the solid integrates over;
//! the plane is flat and rigid, so the gaps are linear in the positions.

/// A rigid plane (a line in 2D): the points `x` with `(x - point) . normal = 0`; the solid stays
/// on the side `normal` points to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidPlane<const D: usize> {
    pub point: [f64; D],
    /// Unit normal.
    pub normal: [f64; D],
}

impl<const D: usize> RigidPlane<D> {
    /// The plane through `point` with the normal `normal` (normalised; `None` for a zero or
    /// non-finite normal).
    pub fn new(point: [f64; D], normal: [f64; D]) -> Option<Self> {
        let len = normal.iter().map(|v| v * v).sum::<f64>().sqrt();
        (len > 0.0 && len.is_finite()).then(|| RigidPlane { point, normal: normal.map(|v| v / len) })
    }

    /// The signed gap `(x - point) . normal` (negative: penetrated).
    pub fn gap(&self, x: &[f64; D]) -> f64 {
        (0..D).map(|d| (x[d] - self.point[d]) * self.normal[d]).sum()
    }
}

/// One contact node's complementarity condition `min(lambda, c g) = 0` as Newton sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Complementarity {
    /// The residual `-min(lambda, c g) / c`.
    pub residual: f64,
    /// Whether the node is in contact (`lambda >= c g`): its row is then `-g`, otherwise
    /// `-lambda / c`.
    pub active: bool,
}

/// The condition at a node with multiplier `lambda`, weighted gap `g` and scale `c > 0`. A tie
/// (`lambda = c g`, e.g. a node that touches the plane before any load) counts as contact: the
/// first Newton iteration of a body resting on the plane then holds it there.
pub fn complementarity(lambda: f64, g: f64, c: f64) -> Complementarity {
    if lambda >= c * g {
        Complementarity { residual: -g, active: true }
    } else {
        Complementarity { residual: -lambda / c, active: false }
    }
}

/// `c_i = G / (w_i l_i)` for a node of weight `w_i = int psi_i dA` (times `R` axisymmetric:
/// `radius` is the node's `R`, 1 otherwise), `l_i = (w_i / R)^(1/(D-1))` its facets' size, and the
/// shear modulus `G` (module docs).
pub fn complementarity_scale(shear_modulus: f64, weight: f64, radius: f64, dim: usize) -> f64 {
    let size = (weight / radius).abs().powf(1.0 / (dim as f64 - 1.0));
    shear_modulus / (weight * size).abs().max(f64::MIN_POSITIVE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_condition_picks_the_smaller_of_pressure_and_weighted_gap() {
        // In contact: a pressure, no gap.
        assert_eq!(complementarity(2.0, 0.0, 10.0), Complementarity { residual: -0.0, active: true });
        // Open: a gap, no pressure.
        assert_eq!(complementarity(0.0, 0.5, 10.0), Complementarity { residual: -0.0, active: false });
        // Penetrated and pulling: both wrong, the smaller one is the residual.
        let c = complementarity(-1.0, -0.2, 10.0);
        assert!(c.active && c.residual == 0.2);
        let plane = RigidPlane::new([0.0, 1.0], [0.0, -2.0]).unwrap();
        assert_eq!(plane.normal, [0.0, -1.0]);
        assert_eq!(plane.gap(&[3.0, 0.25]), 0.75);
        assert!(RigidPlane::new([0.0; 2], [0.0; 2]).is_none());
    }
}
