//! Hyperelastic solids on Q2 (9-node quadrilateral / 27-node hexahedron) elements, optionally
//! mixed with a P1-discontinuous pressure (Q2/P1disc): material laws and the pure cell kernels.
//!
//! # Kinematics
//!
//! The deformation gradient is always a full 3x3 matrix `F`: plane strain has `F_33 = 1`,
//! axisymmetric problems (coordinates `x = (z, r)`, no swirl) have the hoop stretch
//! `F_33 = r / R`, 3D uses all nine entries.
//!
//! The kernel integrates over an *integration configuration* `Omega_n` (the reference
//! configuration for a total-Lagrangian solve, the configuration of the last converged step for
//! an updated-Lagrangian one). The unknown `u` is the displacement from `Omega_n`, the stored
//! deformation gradient of `Omega_n` is `F_n` (identity for total Lagrangian), and
//!
//! ```text
//! F = (I + grad_n u) F_n,        dV_0 = dV_n / J_n,        J_n = det F_n,
//! ```
//!
//! with the hoop entry `(grad_n u)_33 = u_r / r_n` when axisymmetric. Both modes discretise the
//! *same* equations on the same reference quadrature points, so an updated-Lagrangian load path
//! ends in the total-Lagrangian solution to solver tolerance.
//!
//! # Weak form
//!
//! For every displacement test function `w` and pressure test function `q` (integrals over the
//! reference configuration written in the integration configuration; weight `r_n` when
//! axisymmetric):
//!
//! ```text
//! R_u(w) = int_{Omega_n} P_n : grad_n w dV_n  + int rho_0 a^2 (u - u_target) . w dV_0
//!          - int b . w dV_0 - <t_0, w>_{Gamma_0} + <p_f n, w>_{gamma}    (boundary terms: solid.rs)
//! R_p(q) = - int_{Omega_n} q (J - 1 + p / K) / J_n dV_n                   (mixed materials only)
//! P_n    = (P_dev(F) - p J F^{-T}) F_n^T / J_n
//! ```
//!
//! `P_dev` is the first Piola-Kirchhoff stress of the material's displacement part
//! ([`SolidMaterial::stress_tangent`]); `p` is the P1disc pressure (absent for displacement-based
//! laws), `1/K` its compliance ([`SolidMaterial::pressure_compliance`], 0 for the exactly
//! incompressible law of the paper, where `p` is the Lagrange multiplier of `det F = 1`). The sign
//! of `R_p` makes the Jacobian symmetric.
//!
//! The pressure basis is P1 discontinuous in the *material* coordinates,
//! `p|_K = p_0 + g . (X - X_c)` with `X_c` the reference centroid of the cell, so it is the same
//! space in every configuration (what makes total and updated Lagrangian agree exactly).
//!
//! # Paper's law and its pressure
//!
//! The paper's solid is `sigma = G (F F^T - I) - p I` with `det F = 1`
//! ([`NeoHookeanMixed::incompressible`]). Its pressure `p` differs from the convention
//! `sigma = -p' I + G B` of EXACT-SOLUTIONS.md by `p = p' - G`.

use fdfsi_fem::element::MAX_DOFS;
use fdfsi_fem::values::CellValues;
use std::sync::Arc;

pub use crate::physics::fluid::Formulation;

/// A 3x3 matrix, `m[row][col]`.
pub type Mat3 = [[f64; 3]; 3];
/// A fourth-order tensor `A[i][J][k][L] = dP_iJ / dF_kL`.
pub type Tangent = [[[[f64; 3]; 3]; 3]; 3];

/// The identity.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Determinant of a 3x3 matrix.
#[inline]
pub fn det3(m: &Mat3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// `J F^{-T}` (the cofactor matrix) and `F^{-T}`.
#[inline]
pub fn cofactor(m: &Mat3) -> (Mat3, Mat3) {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
            let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
            c[i][j] = m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1];
        }
    }
    let det = det3(m);
    let mut inv_t = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            inv_t[i][j] = c[i][j] / det;
        }
    }
    (c, inv_t)
}

/// `a b`.
#[inline]
pub fn matmul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// A hyperelastic law written in the first Piola-Kirchhoff stress.
///
/// A law is either *displacement-based* (`pressure_compliance() == None`: the full stress comes
/// from [`Self::stress_tangent`]) or *mixed* (`Some(1/K)`): the kernel adds `-p J F^{-T}` with the
/// independent P1disc pressure `p` and the constraint `J - 1 + p/K = 0`.
///
/// A law may vary with the material point `x0` (the reference position, zero-padded to three
/// coordinates): the fibre-reinforced law ([`FibreReinforced`]) reads its fibre direction there.
pub trait SolidMaterial: Send + Sync + std::fmt::Debug {
    /// A short name for logs.
    fn name(&self) -> &'static str;
    /// First Piola-Kirchhoff stress `p` of the displacement part at `f` and the material point
    /// `x0`, and its tangent `a = dP/dF`.
    fn stress_tangent(&self, f: &Mat3, x0: &[f64; 3], p: &mut Mat3, a: &mut Tangent);
    /// `None`: displacement-based; `Some(c)`: mixed with pressure compliance `c = 1/K`
    /// (0 = incompressible).
    fn pressure_compliance(&self) -> Option<f64>;
    /// Shear modulus (small-strain), for scaling and reports.
    fn shear_modulus(&self) -> f64;
    /// The unit fibre direction `a_0` at the material point `x0` of a fibre-reinforced law
    /// (`None`: isotropic, or no fibre there).
    fn fibre_direction(&self, _x0: &[f64; 3]) -> Option<[f64; 3]> {
        None
    }
}

/// Neo-Hookean, mixed u/p (Q2/P1disc): `Psi = G/2 (I_1 - 3) - G ln J` plus the pressure term,
/// `P = G (F - F^{-T}) - p J F^{-T}`, `sigma = (G/J)(B - I) - p I`; at `J = 1` this is the
/// paper's `sigma = G (B - I) - p I`. `bulk_modulus = inf` is the incompressible law
/// (`det F = 1`); a finite `K` gives the nearly incompressible law with `p = -K (J - 1)`.
#[derive(Clone, Copy, Debug)]
pub struct NeoHookeanMixed {
    pub shear_modulus: f64,
    pub bulk_modulus: f64,
}

impl NeoHookeanMixed {
    /// The paper's incompressible neo-Hookean solid.
    pub fn incompressible(shear_modulus: f64) -> Self {
        NeoHookeanMixed { shear_modulus, bulk_modulus: f64::INFINITY }
    }
}

/// Adds `G (F - F^{-T})` and its tangent `G (d_ik d_JL + F^{-T}_iL F^{-T}_kJ)` (times `scale_inv`
/// for the second term).
fn neo_hookean_base(g: f64, c2: f64, f: &Mat3, inv_t: &Mat3, p: &mut Mat3, a: &mut Tangent) {
    for i in 0..3 {
        for jj in 0..3 {
            p[i][jj] = g * (f[i][jj] - inv_t[i][jj]);
            for k in 0..3 {
                for l in 0..3 {
                    let mut v = c2 * inv_t[i][l] * inv_t[k][jj];
                    if i == k && jj == l {
                        v += g;
                    }
                    a[i][jj][k][l] = v;
                }
            }
        }
    }
}

impl SolidMaterial for NeoHookeanMixed {
    fn name(&self) -> &'static str {
        if self.bulk_modulus.is_infinite() {
            "incompressible neo-Hookean (mixed)"
        } else {
            "nearly incompressible neo-Hookean (mixed)"
        }
    }
    fn stress_tangent(&self, f: &Mat3, _x0: &[f64; 3], p: &mut Mat3, a: &mut Tangent) {
        let (_, inv_t) = cofactor(f);
        let g = self.shear_modulus;
        neo_hookean_base(g, g, f, &inv_t, p, a);
    }
    fn pressure_compliance(&self) -> Option<f64> {
        Some(1.0 / self.bulk_modulus)
    }
    fn shear_modulus(&self) -> f64 {
        self.shear_modulus
    }
}

/// Compressible neo-Hookean, displacement-based (Q2 only):
/// `Psi = mu/2 (I_1 - 3) - mu ln J + lambda/2 (ln J)^2`,
/// `P = mu (F - F^{-T}) + lambda ln J F^{-T}`.
#[derive(Clone, Copy, Debug)]
pub struct NeoHookeanCompressible {
    pub mu: f64,
    pub lambda: f64,
}

impl NeoHookeanCompressible {
    /// From the shear and bulk moduli (`lambda = K - 2G/3`).
    pub fn from_shear_bulk(g: f64, k: f64) -> Self {
        NeoHookeanCompressible { mu: g, lambda: k - 2.0 * g / 3.0 }
    }
}

impl SolidMaterial for NeoHookeanCompressible {
    fn name(&self) -> &'static str {
        "compressible neo-Hookean (displacement)"
    }
    fn stress_tangent(&self, f: &Mat3, _x0: &[f64; 3], p: &mut Mat3, a: &mut Tangent) {
        let (_, inv_t) = cofactor(f);
        let lnj = det3(f).ln();
        neo_hookean_base(self.mu, self.mu - self.lambda * lnj, f, &inv_t, p, a);
        for i in 0..3 {
            for jj in 0..3 {
                p[i][jj] += self.lambda * lnj * inv_t[i][jj];
                for k in 0..3 {
                    for l in 0..3 {
                        a[i][jj][k][l] += self.lambda * inv_t[i][jj] * inv_t[k][l];
                    }
                }
            }
        }
    }
    fn pressure_compliance(&self) -> Option<f64> {
        None
    }
    fn shear_modulus(&self) -> f64 {
        self.mu
    }
}

/// Saint Venant-Kirchhoff, displacement-based: `S = lambda tr(E) I + 2 mu E`, `P = F S`,
/// `E = (F^T F - I)/2` (the law of the Turek-Hron FSI benchmarks; not stable in strong
/// compression).
#[derive(Clone, Copy, Debug)]
pub struct SaintVenantKirchhoff {
    pub mu: f64,
    pub lambda: f64,
}

impl SolidMaterial for SaintVenantKirchhoff {
    fn name(&self) -> &'static str {
        "Saint Venant-Kirchhoff (displacement)"
    }
    fn stress_tangent(&self, f: &Mat3, _x0: &[f64; 3], p: &mut Mat3, a: &mut Tangent) {
        let mut e = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                e[i][j] = 0.5 * ((0..3).map(|k| f[k][i] * f[k][j]).sum::<f64>() - if i == j { 1.0 } else { 0.0 });
            }
        }
        let tr = e[0][0] + e[1][1] + e[2][2];
        let mut s = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] = 2.0 * self.mu * e[i][j] + if i == j { self.lambda * tr } else { 0.0 };
            }
        }
        *p = matmul(f, &s);
        let ff_t = matmul(f, &transpose(f));
        for i in 0..3 {
            for jj in 0..3 {
                for k in 0..3 {
                    for l in 0..3 {
                        let mut v = self.lambda * f[i][jj] * f[k][l] + self.mu * f[i][l] * f[k][jj];
                        if jj == l {
                            v += self.mu * ff_t[i][k];
                        }
                        if i == k {
                            v += s[jj][l];
                        }
                        a[i][jj][k][l] = v;
                    }
                }
            }
        }
    }
    fn pressure_compliance(&self) -> Option<f64> {
        None
    }
    fn shear_modulus(&self) -> f64 {
        self.mu
    }
}

/// A fibre direction field `a_0(X)` in the reference configuration, of the reference position
/// (zero-padded to three coordinates). It need not be of unit length: the law normalises it; a
/// zero vector means no fibre at `X`.
pub type FibreField = Arc<dyn Fn(&[f64; 3]) -> [f64; 3] + Send + Sync>;

/// A fibre-reinforced law: an isotropic matrix law plus one family of fibres along `a_0(X)` in
/// the Holzapfel-Gasser-Ogden form (Holzapfel, Gasser & Ogden, J. Elasticity 61, 2000; the
/// exponential fibre response of collagen in valve leaflets):
///
/// ```text
/// Psi   = Psi_matrix(F) + k1 / (2 k2) (exp(k2 E^2) - 1),   E = I4 - 1 > 0,  I4 = a_0 . C a_0
/// P     = P_matrix + 2 psi' (F a_0) (x) a_0,               psi'  = k1 E exp(k2 E^2)
/// dP/dF = A_matrix + 2 psi' d_ik a_J a_L + 4 psi'' (F a_0)_i a_J (F a_0)_k a_L,
///                                                           psi'' = k1 (1 + 2 k2 E^2) exp(k2 E^2)
/// ```
///
/// and nothing where `I4 <= 1`: fibres bear no compression. With an onset `delta > 0` the fibres
/// engage smoothly over `0 < E < delta` ([`FibreReinforced::fibre_derivatives`]): `psi''` rises
/// from 0 to its value at `delta` instead of jumping to `k1` at `E = 0`, so that the tangent is
/// continuous. `k2 -> 0` is the quadratic fibre
/// `k1 / 2 E^2`. `I4` is that of the full `F`, not of its isochoric part: with the
/// incompressible matrix (`det F = 1`) they are the same, and for compressible matrices the
/// isochoric split of the fibre term is known to give unphysical responses (Sansour, Eur. J.
/// Mech. A 27, 2008; Helfenstein et al., Int. J. Solids Struct. 47, 2010). Small-strain fibre
/// stiffness: `E_f = 4 k1` along `a_0` on top of the matrix's. The matrix's pressure, if any, is
/// the law's.
#[derive(Clone)]
pub struct FibreReinforced {
    /// The isotropic matrix.
    pub matrix: Arc<dyn SolidMaterial>,
    /// Fibre stiffness `k1` (a stress, >= 0).
    pub k1: f64,
    /// Fibre exponent `k2` (dimensionless, >= 0).
    pub k2: f64,
    /// The onset `delta >= 0` of `E = I4 - 1` over which the fibres engage smoothly (0: at once,
    /// the law as published).
    pub onset: f64,
    /// Fibre direction field.
    pub direction: FibreField,
}

impl std::fmt::Debug for FibreReinforced {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FibreReinforced")
            .field("matrix", &self.matrix)
            .field("k1", &self.k1)
            .field("k2", &self.k2)
            .field("onset", &self.onset)
            .finish_non_exhaustive()
    }
}

impl FibreReinforced {
    /// `psi'(I4)` and `psi''(I4)` (both 0 where `I4 <= 1`). Within the onset, `0 < E < delta`,
    /// `psi''` is the quadratic `a E + b E^2` that is 0 at `E = 0`, the law's `h2 = psi''(delta)`
    /// at `delta`, and integrates to the law's `h1 = psi'(delta)` over the onset:
    ///
    /// ```text
    /// a = (6 h1 - 2 h2 delta) / delta^2,   b = (3 h2 delta - 6 h1) / delta^3,   psi' = a E^2 / 2 + b E^3 / 3
    /// ```
    ///
    /// so that `psi'` and `psi''` are continuous everywhere (the strain energy `C^2`), and the law
    /// is the published one from `E = delta` on. (Small `delta`: `psi'' = k1 (4 E / delta - 3 E^2 /
    /// delta^2) >= 0`, convex.) At `E = 0` the published law's tangent jumps by `4 k1` along the
    /// fibres; where fibres hang slack at the kink, Newton's steps cross it back and forth (the
    /// closed 3D valve's band, a third of its quadrature points within 0.01 of `I4 = 1`).
    pub fn fibre_derivatives(&self, i4: f64) -> (f64, f64) {
        let e = i4 - 1.0;
        if !(e > 0.0) {
            return (0.0, 0.0);
        }
        let published = |e: f64| {
            let x = (self.k2 * e * e).exp();
            (self.k1 * e * x, self.k1 * (1.0 + 2.0 * self.k2 * e * e) * x)
        };
        let delta = self.onset;
        if e >= delta {
            return published(e);
        }
        let (h1, h2) = published(delta);
        let a = (6.0 * h1 - 2.0 * h2 * delta) / (delta * delta);
        let b = (3.0 * h2 * delta - 6.0 * h1) / (delta * delta * delta);
        (a * e * e / 2.0 + b * e * e * e / 3.0, a * e + b * e * e)
    }
}

impl SolidMaterial for FibreReinforced {
    fn name(&self) -> &'static str {
        "fibre-reinforced (Holzapfel-Gasser-Ogden fibres on an isotropic matrix)"
    }
    fn stress_tangent(&self, f: &Mat3, x0: &[f64; 3], p: &mut Mat3, a: &mut Tangent) {
        self.matrix.stress_tangent(f, x0, p, a);
        let Some(a0) = self.fibre_direction(x0) else { return };
        let fa: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| f[i][j] * a0[j]).sum());
        let i4: f64 = fa.iter().map(|v| v * v).sum();
        let (d1, d2) = self.fibre_derivatives(i4);
        if d1 == 0.0 && d2 == 0.0 {
            return;
        }
        for i in 0..3 {
            for jj in 0..3 {
                p[i][jj] += 2.0 * d1 * fa[i] * a0[jj];
                for k in 0..3 {
                    for l in 0..3 {
                        let mut v = 4.0 * d2 * fa[i] * a0[jj] * fa[k] * a0[l];
                        if i == k {
                            v += 2.0 * d1 * a0[jj] * a0[l];
                        }
                        a[i][jj][k][l] += v;
                    }
                }
            }
        }
    }
    fn pressure_compliance(&self) -> Option<f64> {
        self.matrix.pressure_compliance()
    }
    fn shear_modulus(&self) -> f64 {
        self.matrix.shear_modulus()
    }
    fn fibre_direction(&self, x0: &[f64; 3]) -> Option<[f64; 3]> {
        let a = (self.direction)(x0);
        let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
        (norm > 0.0 && norm.is_finite()).then(|| a.map(|v| v / norm))
    }
}

/// Transpose.
#[inline]
pub fn transpose(m: &Mat3) -> Mat3 {
    std::array::from_fn(|i| std::array::from_fn(|j| m[j][i]))
}

/// Solid inertia: the term `coefficient (u - target) . w` per reference volume, with
/// `coefficient = rho_0 a^2` and `target = u* + v* / a` for a time scheme `v_{n+1} = a (u - u*)`,
/// `a_{n+1} = a (v_{n+1} - v*)` ([`crate::discretize::solid::InertiaHistory`]; implicit Euler:
/// `a = 1/dt`, target `u_n + dt v_n` in total Lagrangian, `dt v_n` for an increment).
#[derive(Clone, Copy)]
pub struct InertiaState<'a> {
    pub coefficient: f64,
    pub target: &'a [f64],
}

/// Local data of one cell for [`solid_cell`].
#[derive(Clone, Copy)]
pub struct SolidCellState<'a, const D: usize> {
    /// Displacement from the integration configuration, `u[i * D + a]`.
    pub u: &'a [f64],
    /// P1disc pressure dofs (`D + 1`: value at the reference centroid, then the material
    /// gradient); empty for displacement-based laws.
    pub p: &'a [f64],
    /// Deformation gradient of the integration configuration at each quadrature point; `None`
    /// is the identity (total Lagrangian).
    pub f_prev: Option<&'a [Mat3]>,
    /// Material (reference) coordinates of the quadrature points.
    pub x0: &'a [[f64; D]],
    /// Reference centroid of the cell.
    pub x0_centroid: [f64; D],
    /// Optional inertia.
    pub inertia: Option<InertiaState<'a>>,
    /// Optional body force per unit reference volume at each quadrature point.
    pub body_force: Option<&'a [[f64; D]]>,
}

/// `det F <= 0` at a quadrature point: the element is inverted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InvertedPoint {
    pub point: usize,
    pub det: f64,
}

/// Deformation gradient at quadrature point `q` of a cell (see the module docs); `cv` is
/// re-initialised on the integration configuration.
#[inline]
pub fn deformation_gradient<const D: usize>(cv: &CellValues<D>, formulation: Formulation, u: &[f64], f_prev: &Mat3, q: usize) -> Mat3 {
    let phi = cv.phi(q);
    let dphi = cv.grad_phi(q);
    let mut h = [[0.0; 3]; 3];
    let mut ur = 0.0;
    for i in 0..cv.num_dofs() {
        for a in 0..D {
            let ua = u[i * D + a];
            for b in 0..D {
                h[a][b] += ua * dphi[i][b];
            }
        }
        if D == 2 {
            ur += u[i * D + 1] * phi[i];
        }
    }
    if formulation == Formulation::Axisymmetric {
        h[2][2] = ur / cv.x[q][1];
    }
    for d in 0..3 {
        h[d][d] += 1.0;
    }
    matmul(&h, f_prev)
}

/// Solid cell kernel: adds the element residual to `re` and the Jacobian to `ke` (row-major;
/// local order: displacement dofs `i * D + a`, then the `D + 1` pressure dofs when the material
/// is mixed). `cv` must be re-initialised on the integration configuration. Allocation-free.
/// Fails at the first quadrature point with `det F <= 0`.
pub fn solid_cell<const D: usize>(
    cv: &CellValues<D>,
    formulation: Formulation,
    material: &dyn SolidMaterial,
    state: &SolidCellState<'_, D>,
    ke: &mut [f64],
    re: &mut [f64],
) -> Result<(), InvertedPoint> {
    let nv = cv.num_dofs();
    let nu = nv * D;
    let compliance = material.pressure_compliance();
    let np = if compliance.is_some() { D + 1 } else { 0 };
    let n = nu + np;
    debug_assert_eq!(ke.len(), n * n);
    debug_assert_eq!(re.len(), n);
    let axi = formulation == Formulation::Axisymmetric;
    let mut p_dev = [[0.0; 3]; 3];
    let mut a = [[[[0.0; 3]; 3]; 3]; 3];
    let mut ag = [[[0.0; 3]; 3]; 3 * MAX_DOFS];
    let mut psi = [0.0; 4];
    for q in 0..cv.num_points() {
        let fp = state.f_prev.map(|f| f[q]).unwrap_or(IDENTITY);
        let jp = det3(&fp);
        let f = deformation_gradient(cv, formulation, state.u, &fp, q);
        let j = det3(&f);
        if !(j > 0.0) {
            return Err(InvertedPoint { point: q, det: j });
        }
        let (cof, inv_t) = cofactor(&f);
        let x0: [f64; 3] = std::array::from_fn(|d| if d < D { state.x0[q][d] } else { 0.0 });
        material.stress_tangent(&f, &x0, &mut p_dev, &mut a);
        // Pressure part.
        let mut pres = 0.0;
        if let Some(_c) = compliance {
            psi[0] = 1.0;
            for d in 0..D {
                psi[d + 1] = state.x0[q][d] - state.x0_centroid[d];
            }
            pres = (0..np).map(|k| state.p[k] * psi[k]).sum();
            for i in 0..3 {
                for jj in 0..3 {
                    p_dev[i][jj] -= pres * cof[i][jj];
                    for k in 0..3 {
                        for l in 0..3 {
                            a[i][jj][k][l] -= pres * j * (inv_t[i][jj] * inv_t[k][l] - inv_t[i][l] * inv_t[k][jj]);
                        }
                    }
                }
            }
        }
        // Map to the integration configuration: P_n = P F_n^T / J_n, G_n = cof F_n^T / J_n,
        // A_n[i][J][k][L] = A[i][M][k][N] F_n[J][M] F_n[L][N] / J_n.
        let fpt = transpose(&fp);
        let mut pn = matmul(&p_dev, &fpt);
        let mut gn = matmul(&cof, &fpt);
        for i in 0..3 {
            for jj in 0..3 {
                pn[i][jj] /= jp;
                gn[i][jj] /= jp;
            }
        }
        let mut an = [[[[0.0; 3]; 3]; 3]; 3];
        for i in 0..3 {
            for k in 0..3 {
                // t[M][L] = sum_N A[i][M][k][N] F_n[L][N]
                let mut t = [[0.0; 3]; 3];
                for m in 0..3 {
                    for l in 0..3 {
                        t[m][l] = (0..3).map(|nn| a[i][m][k][nn] * fp[l][nn]).sum();
                    }
                }
                for jj in 0..3 {
                    for l in 0..3 {
                        an[i][jj][k][l] = (0..3).map(|m| fp[jj][m] * t[m][l]).sum::<f64>() / jp;
                    }
                }
            }
        }
        let x = cv.x[q];
        let r = if axi { x[1] } else { 1.0 };
        let w = cv.jxw[q] * r;
        let phi = cv.phi(q);
        let dphi = cv.grad_phi(q);
        // Displacement at the point (inertia).
        let mut u_pt = [0.0; D];
        let mut target = [0.0; D];
        if let Some(inert) = &state.inertia {
            for i in 0..nv {
                for d in 0..D {
                    u_pt[d] += phi[i] * state.u[i * D + d];
                    target[d] += phi[i] * inert.target[i * D + d];
                }
            }
        }
        // AG_l = A_n : G_l for every displacement dof l = (j, b).
        for jn in 0..nv {
            for b in 0..D {
                let l = jn * D + b;
                let hoop = if axi && b == 1 { phi[jn] / r } else { 0.0 };
                for i in 0..3 {
                    for jj in 0..3 {
                        let mut s: f64 = (0..D).map(|c| an[i][jj][b][c] * dphi[jn][c]).sum();
                        if hoop != 0.0 {
                            s += an[i][jj][2][2] * hoop;
                        }
                        ag[l][i][jj] = s;
                    }
                }
            }
        }
        for i in 0..nv {
            for aa in 0..D {
                let k = i * D + aa;
                let hoop = if axi && aa == 1 { phi[i] / r } else { 0.0 };
                let mut s: f64 = (0..D).map(|c| pn[aa][c] * dphi[i][c]).sum();
                s += pn[2][2] * hoop;
                let mut gw: f64 = (0..D).map(|c| gn[aa][c] * dphi[i][c]).sum();
                gw += gn[2][2] * hoop;
                let mut inertial = 0.0;
                if let Some(inert) = &state.inertia {
                    inertial = inert.coefficient * (u_pt[aa] - target[aa]) * phi[i] / jp;
                }
                let external = state.body_force.map_or(0.0, |b| b[q][aa] * phi[i] / jp);
                re[k] += w * (s + inertial - external);
                let row = k * n;
                for l in 0..nu {
                    let agl = &ag[l];
                    let mut v: f64 = (0..D).map(|c| dphi[i][c] * agl[aa][c]).sum();
                    v += hoop * agl[2][2];
                    ke[row + l] += w * v;
                }
                if let Some(inert) = &state.inertia {
                    for jn in 0..nv {
                        ke[row + jn * D + aa] += w * inert.coefficient * phi[i] * phi[jn] / jp;
                    }
                }
                for kp in 0..np {
                    let v = -w * psi[kp] * gw;
                    ke[row + nu + kp] += v;
                    ke[(nu + kp) * n + k] += v;
                }
            }
        }
        if let Some(c) = compliance {
            let g = j - 1.0 + c * pres;
            for kp in 0..np {
                re[nu + kp] -= w * psi[kp] * g / jp;
                for lp in 0..np {
                    ke[(nu + kp) * n + nu + lp] -= w * psi[kp] * psi[lp] * c / jp;
                }
            }
        }
    }
    Ok(())
}

/// Basis data of one boundary facet at one quadrature point: the cell's basis values `phi` and
/// their derivatives along the facet's reference tangents, `dphi_t[i] = [dN_i/dt_1, dN_i/dt_2]`
/// (`dN_i/dt_2` unused in 2D).
pub struct FacetPoint<'a> {
    pub phi: &'a [f64],
    pub dphi_t: &'a [[f64; 2]],
    /// Quadrature weight on the reference facet.
    pub weight: f64,
}

/// The facet tangents `t_1 = dx/d eta_1`, `t_2 = dx/d eta_2` at a point, from the nodal
/// positions `x` of the cell (`t_2` is zero on the segments of a 2D cell).
#[inline]
fn facet_tangents<const D: usize>(x: &[[f64; D]], pt: &FacetPoint<'_>) -> ([f64; 3], [f64; 3]) {
    let mut t1 = [0.0; 3];
    let mut t2 = [0.0; 3];
    for (k, xk) in x.iter().enumerate() {
        for d in 0..D {
            t1[d] += xk[d] * pt.dphi_t[k][0];
            t2[d] += xk[d] * pt.dphi_t[k][1];
        }
    }
    (t1, t2)
}

/// `n da / d(eta)` from the facet tangents: `(t1_y, -t1_x)` in 2D, `t1 x t2` in 3D, times
/// `orientation`.
#[inline]
fn area_from_tangents<const D: usize>(t1: &[f64; 3], t2: &[f64; 3], orientation: f64) -> [f64; 3] {
    if D == 2 {
        [orientation * t1[1], -orientation * t1[0], 0.0]
    } else {
        [orientation * (t1[1] * t2[2] - t1[2] * t2[1]), orientation * (t1[2] * t2[0] - t1[0] * t2[2]), orientation * (t1[0] * t2[1] - t1[1] * t2[0])]
    }
}

/// The area vector `n da / d(eta)` of a facet at a point, from the nodal positions `x` of the
/// cell, times `orientation` (+1 or -1 so that it points out of the body).
#[inline]
pub fn area_vector<const D: usize>(x: &[[f64; D]], pt: &FacetPoint<'_>, orientation: f64) -> [f64; 3] {
    let (t1, t2) = facet_tangents(x, pt);
    area_from_tangents::<D>(&t1, &t2, orientation)
}

/// Follower pressure on a facet in the *current* configuration, nodal positions `x` (all nodes
/// of the cell):
///
/// ```text
/// R_u(w) += int_gamma p n . w da  (times r when axisymmetric),
/// ```
///
/// i.e. the traction `-p n` on the deformed surface. Adds the residual to `re` (`nu` entries)
/// and its exact derivative with respect to the nodal positions to `ke` (`nu x nu`, row stride
/// `stride`). Allocation-free.
#[allow(clippy::too_many_arguments, reason = "a kernel: its inputs are the facet's data, as in the formula")]
pub fn follower_pressure_facet<const D: usize>(
    formulation: Formulation,
    x: &[[f64; D]],
    points: &[FacetPoint<'_>],
    orientation: f64,
    pressure: f64,
    ke: &mut [f64],
    stride: usize,
    re: &mut [f64],
) {
    let nv = x.len();
    let axi = formulation == Formulation::Axisymmetric;
    for pt in points {
        let (t1, t2) = facet_tangents(x, pt);
        let nda = area_from_tangents::<D>(&t1, &t2, orientation);
        let r: f64 = if axi { (0..nv).map(|k| x[k][1] * pt.phi[k]).sum() } else { 1.0 };
        let s = pressure * pt.weight;
        for i in 0..nv {
            for a in 0..D {
                re[i * D + a] += s * nda[a] * pt.phi[i] * r;
            }
        }
        // d(nda)/d x_{j,b}.
        for j in 0..nv {
            for b in 0..D {
                let mut dn = [0.0; 3];
                let (d1, d2) = (pt.dphi_t[j][0], pt.dphi_t[j][1]);
                if D == 2 {
                    // nda = o (t1_y, -t1_x)
                    if b == 1 {
                        dn[0] = orientation * d1;
                    } else {
                        dn[1] = -orientation * d1;
                    }
                } else {
                    // d(t1 x t2) = (e_b d1) x t2 + t1 x (e_b d2)
                    let mut e = [0.0; 3];
                    e[b] = 1.0;
                    let c1 = [e[1] * t2[2] - e[2] * t2[1], e[2] * t2[0] - e[0] * t2[2], e[0] * t2[1] - e[1] * t2[0]];
                    let c2 = [t1[1] * e[2] - t1[2] * e[1], t1[2] * e[0] - t1[0] * e[2], t1[0] * e[1] - t1[1] * e[0]];
                    for m in 0..3 {
                        dn[m] = orientation * (d1 * c1[m] + d2 * c2[m]);
                    }
                }
                let dr = if axi && b == 1 { pt.phi[j] } else { 0.0 };
                for i in 0..nv {
                    for a in 0..D {
                        ke[(i * D + a) * stride + j * D + b] += s * pt.phi[i] * (dn[a] * r + nda[a] * dr);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fdfsi_fem::element::ReferenceElement;
    use fdfsi_fem::quadrature;

    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// `dP/dF` of every material equals a central difference of `P`.
    #[test]
    fn material_tangents_match_finite_differences() {
        let mut rnd = rng(3);
        let mats = materials();
        let f0: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| if i == j { 1.0 } else { 0.0 } + 0.3 * rnd()));
        // Two material points: the fibres stretched (I4 > 1) at one, shortened at the other.
        let i4 = |x0: &[f64; 3]| {
            let a = fibres().fibre_direction(x0).unwrap();
            (0..3).map(|i| (0..3).map(|j| f0[i][j] * a[j]).sum::<f64>().powi(2)).sum::<f64>()
        };
        let points: Vec<[f64; 3]> = (0..64).map(|_| [rnd(), rnd(), rnd()]).collect();
        let stretched = *points.iter().find(|x| i4(x) > 1.05).unwrap();
        let shortened = *points.iter().find(|x| i4(x) < 0.95).unwrap();
        for (m, x0) in mats.iter().flat_map(|m| [(m, stretched), (m, shortened)]) {
            let (mut p, mut a) = ([[0.0; 3]; 3], [[[[0.0; 3]; 3]; 3]; 3]);
            m.stress_tangent(&f0, &x0, &mut p, &mut a);
            let h = 1e-6;
            for k in 0..3 {
                for l in 0..3 {
                    let (mut fp, mut fm) = (f0, f0);
                    fp[k][l] += h;
                    fm[k][l] -= h;
                    let (mut pp, mut pm, mut aa) = ([[0.0; 3]; 3], [[0.0; 3]; 3], [[[[0.0; 3]; 3]; 3]; 3]);
                    m.stress_tangent(&fp, &x0, &mut pp, &mut aa);
                    m.stress_tangent(&fm, &x0, &mut pm, &mut aa);
                    for i in 0..3 {
                        for jj in 0..3 {
                            let fd = (pp[i][jj] - pm[i][jj]) / (2.0 * h);
                            assert!((fd - a[i][jj][k][l]).abs() < 1e-7 * (1.0 + fd.abs()), "{}: A[{i}][{jj}][{k}][{l}]", m.name());
                        }
                    }
                }
            }
        }
    }

    fn check_kernel_fd<const D: usize>(
        cv: &CellValues<D>,
        formulation: Formulation,
        material: &dyn SolidMaterial,
        f_prev: Option<&[Mat3]>,
        inertia: bool,
        seed: u64,
    ) {
        let nv = cv.num_dofs();
        let nu = nv * D;
        let np = if material.pressure_compliance().is_some() { D + 1 } else { 0 };
        let n = nu + np;
        let mut rnd = rng(seed);
        let x0: Vec<f64> = (0..n).map(|i| if i < nu { 0.08 * rnd() } else { rnd() }).collect();
        let target: Vec<f64> = (0..nu).map(|_| 0.05 * rnd()).collect();
        let xq0: Vec<[f64; D]> = cv.x.iter().map(|x| std::array::from_fn(|d| x[d] * 0.9 + 0.01)).collect();
        // A body force (with the inertia) does not depend on the unknowns: the tangent is unchanged.
        let bf: Vec<[f64; D]> = cv.x.iter().map(|x| std::array::from_fn(|d| 2.0 * x[d] - 0.5)).collect();
        let eval = |xs: &[f64], ke: &mut Vec<f64>, re: &mut Vec<f64>| {
            ke.iter_mut().for_each(|v| *v = 0.0);
            re.iter_mut().for_each(|v| *v = 0.0);
            let st = SolidCellState {
                u: &xs[..nu],
                p: &xs[nu..],
                f_prev,
                x0: &xq0,
                x0_centroid: cv.centroid,
                inertia: if inertia { Some(InertiaState { coefficient: 3.7, target: &target }) } else { None },
                body_force: inertia.then_some(&bf[..]),
            };
            solid_cell(cv, formulation, material, &st, ke, re).unwrap();
        };
        let mut ke = vec![0.0; n * n];
        let mut re = vec![0.0; n];
        eval(&x0, &mut ke, &mut re);
        let h = 1e-6;
        let scale = ke.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for jcol in 0..n {
            let (mut xp, mut xm) = (x0.clone(), x0.clone());
            xp[jcol] += h;
            xm[jcol] -= h;
            let (mut kp, mut rp, mut rm) = (vec![0.0; n * n], vec![0.0; n], vec![0.0; n]);
            eval(&xp, &mut kp, &mut rp);
            eval(&xm, &mut kp, &mut rm);
            for i in 0..n {
                let fd = (rp[i] - rm[i]) / (2.0 * h);
                assert!(
                    (fd - ke[i * n + jcol]).abs() < 1e-6 * scale,
                    "{} {formulation:?}: K[{i}][{jcol}] = {} vs FD {fd}",
                    material.name(),
                    ke[i * n + jcol]
                );
            }
        }
        // Symmetry (hyperelastic laws, no follower load).
        for i in 0..n {
            for jcol in 0..n {
                assert!((ke[i * n + jcol] - ke[jcol * n + i]).abs() < 1e-10 * scale, "{}: K not symmetric", material.name());
            }
        }
    }

    /// Fibres on the incompressible matrix, their direction turning with the material point.
    fn fibres() -> FibreReinforced {
        let direction: FibreField = Arc::new(|x: &[f64; 3]| [1.0 + 2.0 * x[0], 0.5 - x[1] + x[0], 0.4 + x[2]]);
        FibreReinforced { matrix: Arc::new(NeoHookeanMixed::incompressible(1.3)), k1: 2.0, k2: 1.5, onset: 0.0, direction }
    }

    fn materials() -> Vec<Box<dyn SolidMaterial>> {
        let on_compressible = FibreReinforced { matrix: Arc::new(NeoHookeanCompressible { mu: 0.8, lambda: 2.1 }), k2: 0.0, ..fibres() };
        vec![
            Box::new(NeoHookeanMixed::incompressible(1.3)),
            Box::new(NeoHookeanMixed { shear_modulus: 1.3, bulk_modulus: 40.0 }),
            Box::new(NeoHookeanCompressible { mu: 0.8, lambda: 2.1 }),
            Box::new(SaintVenantKirchhoff { mu: 0.8, lambda: 2.1 }),
            Box::new(fibres()),
            Box::new(FibreReinforced { onset: 0.3, ..fibres() }),
            Box::new(on_compressible),
        ]
    }

    /// With an onset `delta` the fibres' `psi'` and `psi''` are continuous at `E = 0` and at
    /// `delta` (to 1e-9 of `k1`), `psi''` is the derivative of `psi'` across the onset (central
    /// differences), non-negative, and the published law's from `delta` on.
    #[test]
    fn fibres_engage_over_their_onset_with_a_continuous_tangent() {
        let delta = 0.02;
        let smooth = FibreReinforced { k1: 1e6, k2: 5.0, onset: delta, ..fibres() };
        let published = FibreReinforced { onset: 0.0, ..smooth.clone() };
        let k1 = smooth.k1;
        let at = |law: &FibreReinforced, e: f64| law.fibre_derivatives(1.0 + e);
        // Continuous at 0 (from zero) and at delta (into the published law).
        let (d1, d2) = at(&smooth, 1e-12);
        assert!(d1.abs() < 1e-9 * k1 && d2.abs() < 1e-9 * k1, "{d1} {d2}");
        let (below, above) = (at(&smooth, delta * (1.0 - 1e-12)), at(&published, delta * (1.0 + 1e-12)));
        assert!((below.0 - above.0).abs() < 1e-9 * k1 && (below.1 - above.1).abs() < 1e-9 * k1, "{below:?} {above:?}");
        // The published law jumps there: psi'' = k1 just past E = 0.
        assert!((at(&published, 1e-12).1 - k1).abs() < 1e-6 * k1);
        for i in 1..40 {
            let e = 1.5 * delta * i as f64 / 40.0;
            let h = 1e-7;
            let fd = (at(&smooth, e + h).0 - at(&smooth, e - h).0) / (2.0 * h);
            let (d1, d2) = at(&smooth, e);
            assert!((fd - d2).abs() < 1e-5 * k1, "E = {e}: psi'' {d2} against {fd}");
            assert!(d1 >= 0.0 && d2 >= 0.0, "E = {e}: {d1} {d2}");
            if e >= delta {
                assert_eq!((d1, d2), at(&published, e));
            }
        }
    }

    /// The kernel's Jacobian equals a central difference of its residual: every material, plane
    /// strain and axisymmetric (hoop stretch), total and updated Lagrangian, with inertia.
    #[test]
    fn jacobian_matches_finite_differences_2d() {
        let e = ReferenceElement::q2_quadrilateral();
        let mut cv = CellValues::new(quadrature::quadrilateral(5), &e, &e);
        // A curved, distorted cell away from the axis.
        let mut rnd = rng(11);
        let coords: Vec<[f64; 2]> = e
            .nodes()
            .iter()
            .map(|xi| [0.3 + 1.1 * xi[0] + 0.2 * xi[1] + 0.03 * rnd(), 0.5 + 0.9 * xi[1] + 0.1 * xi[0] * xi[0] + 0.03 * rnd()])
            .collect();
        cv.reinit(&coords).unwrap();
        let fprev: Vec<Mat3> = (0..cv.num_points())
            .map(|_| {
                let mut f: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| if i == j { 1.0 } else { 0.0 } + 0.1 * rnd()));
                f[0][2] = 0.0;
                f[1][2] = 0.0;
                f[2][0] = 0.0;
                f[2][1] = 0.0;
                f
            })
            .collect();
        for (s, m) in materials().iter().enumerate() {
            for form in [Formulation::Plane, Formulation::Axisymmetric] {
                check_kernel_fd(&cv, form, m.as_ref(), None, false, 5 + s as u64);
                check_kernel_fd(&cv, form, m.as_ref(), Some(&fprev), true, 7 + s as u64);
            }
        }
    }

    /// The same for the 27-node hexahedron.
    #[test]
    fn jacobian_matches_finite_differences_3d() {
        let e = ReferenceElement::q2_hexahedron();
        let mut cv = CellValues::new(quadrature::hexahedron(3), &e, &e);
        let mut rnd = rng(13);
        let coords: Vec<[f64; 3]> = e
            .nodes()
            .iter()
            .map(|xi| [xi[0] + 0.2 * xi[1] + 0.02 * rnd(), xi[1] + 0.1 * xi[2] * xi[2] + 0.02 * rnd(), 0.8 * xi[2] + 0.1 * xi[0] + 0.02 * rnd()])
            .collect();
        cv.reinit(&coords).unwrap();
        let fprev: Vec<Mat3> =
            (0..cv.num_points()).map(|_| std::array::from_fn(|i| std::array::from_fn(|j| if i == j { 1.0 } else { 0.0 } + 0.1 * rnd()))).collect();
        for (s, m) in materials().iter().enumerate() {
            check_kernel_fd(&cv, Formulation::ThreeD, m.as_ref(), None, s == 0, 17 + s as u64);
        }
        check_kernel_fd(&cv, Formulation::ThreeD, materials()[0].as_ref(), Some(&fprev), false, 31);
    }

    /// The follower-pressure Jacobian equals a central difference of its residual (2D plane,
    /// axisymmetric, 3D).
    #[test]
    fn follower_pressure_jacobian_matches_finite_differences() {
        fn check<const D: usize>(e: &ReferenceElement<D>, form: Formulation, pts_ref: &[[f64; D]], tangents: [[f64; D]; 2]) {
            let tab = e.tabulate(pts_ref);
            let nv = e.num_dofs();
            let mut rnd = rng(99);
            let dphi_t: Vec<Vec<[f64; 2]>> = (0..pts_ref.len())
                .map(|q| {
                    (0..nv)
                        .map(|i| {
                            let g = tab.grads[q * nv + i];
                            [(0..D).map(|d| g[d] * tangents[0][d]).sum(), (0..D).map(|d| g[d] * tangents[1][d]).sum()]
                        })
                        .collect()
                })
                .collect();
            let points: Vec<FacetPoint> = (0..pts_ref.len())
                .map(|q| FacetPoint { phi: &tab.values[q * nv..(q + 1) * nv], dphi_t: &dphi_t[q], weight: 0.3 + 0.1 * q as f64 })
                .collect();
            let x0: Vec<[f64; D]> = e.nodes().iter().map(|xi| std::array::from_fn(|d| 0.5 + xi[d] + 0.05 * rnd())).collect();
            let nu = nv * D;
            let eval = |x: &[[f64; D]], ke: &mut Vec<f64>, re: &mut Vec<f64>| {
                ke.iter_mut().for_each(|v| *v = 0.0);
                re.iter_mut().for_each(|v| *v = 0.0);
                follower_pressure_facet(form, x, &points, -1.0, 1.7, ke, nu, re);
            };
            let (mut ke, mut re) = (vec![0.0; nu * nu], vec![0.0; nu]);
            eval(&x0, &mut ke, &mut re);
            let h = 1e-6;
            for j in 0..nv {
                for b in 0..D {
                    let (mut xp, mut xm) = (x0.clone(), x0.clone());
                    xp[j][b] += h;
                    xm[j][b] -= h;
                    let (mut kk, mut rp, mut rm) = (vec![0.0; nu * nu], vec![0.0; nu], vec![0.0; nu]);
                    eval(&xp, &mut kk, &mut rp);
                    eval(&xm, &mut kk, &mut rm);
                    for i in 0..nu {
                        let fd = (rp[i] - rm[i]) / (2.0 * h);
                        assert!((fd - ke[i * nu + j * D + b]).abs() < 1e-7 * (1.0 + fd.abs()), "{form:?}");
                    }
                }
            }
        }
        let q2 = ReferenceElement::q2_quadrilateral();
        let pts: Vec<[f64; 2]> = [0.1, 0.5, 0.8].iter().map(|&t| [t, 0.0]).collect();
        check(&q2, Formulation::Plane, &pts, [[1.0, 0.0], [0.0, 0.0]]);
        check(&q2, Formulation::Axisymmetric, &pts, [[1.0, 0.0], [0.0, 0.0]]);
        let q2h = ReferenceElement::q2_hexahedron();
        let pts3: Vec<[f64; 3]> = [[0.1, 0.2, 0.0], [0.6, 0.7, 0.0]].to_vec();
        check(&q2h, Formulation::ThreeD, &pts3, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    }
}
