//! Incompressible flow on P2+/P1disc (Crouzeix-Raviart) elements: the cell kernel.
//!
//! Weak form (METHOD.md section 2), in residual form for Newton, for every velocity test
//! function `v` and pressure test function `q`:
//!
//! ```text
//! R_u(v) = rho/dt (u - u_old, v) + rho (u . grad u, v) + (2 eta D(u), D(v)) - (p, div v) - (f, v)
//!          - <t_N, v>_Gamma_N
//! R_p(q) = -(q, div u)
//! ```
//!
//! with `D(u) = (grad u + grad u^T) / 2`. The pressure row carries a minus sign so that the Stokes
//! Jacobian is the symmetric saddle-point matrix `[A B^T; B 0]`.
//!
//! **Axisymmetric** (coordinates `x = (z, r)`, velocity `(u_z, u_r)`, no swirl): every integral
//! carries the weight `r`, the strain rate gains the hoop component `D_tt = u_r / r`, and
//! `div u = d u_z/dz + d u_r/dr + u_r / r`. The symmetry axis `r = 0` needs `u_r = 0` (a
//! Dirichlet condition on the radial component); the weight `r` makes the other terms vanish there.
//!
//! The pressure space is P1 discontinuous in physical coordinates,
//! `p|_K = p_0 + g . (x - x_c)` ([`fdfsi_fem::values::p1disc_basis`]): its test functions contain
//! the constant on each cell, so `int_K div u_h = 0` for every cell (local mass conservation).

use fdfsi_fem::values::{p1disc_basis, CellValues};

/// The geometric formulation of the equations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Formulation {
    /// 2D plane flow (or plane strain).
    Plane,
    /// 2D axisymmetric about the x axis: `x[0] = z` axial, `x[1] = r` radial.
    Axisymmetric,
    /// 3D.
    #[serde(rename = "3d")]
    ThreeD,
}

impl Formulation {
    /// The integration weight at physical point `x`: `r = x[1]` (axisymmetric) or 1.
    #[inline]
    pub fn weight<const D: usize>(self, x: &[f64; D]) -> f64 {
        match self {
            Formulation::Axisymmetric => x[1],
            _ => 1.0,
        }
    }

    /// What an integral with [`Formulation::weight`] is multiplied by to be the whole body's:
    /// `2 pi` axisymmetric (the integrals are per radian), 1 otherwise (plane: per unit depth).
    #[inline]
    pub fn around(self) -> f64 {
        match self {
            Formulation::Axisymmetric => 2.0 * std::f64::consts::PI,
            _ => 1.0,
        }
    }
}

/// Form of the viscous term. Both give the same solution where the velocity is prescribed on the
/// whole boundary (`div u = 0`), and the same force on no-slip walls; they differ in the natural
/// boundary condition of outlets:
/// - `Stress`: `(2 eta D(u), D(v))`, natural condition `sigma n = t` (the paper's);
/// - `Laplace`: `(eta grad u, grad v)` (axisymmetric: plus `eta u_r v_r / r^2`), natural condition
///   `eta du/dn - p n = t`, the "do-nothing" outlet of the Schaefer-Turek benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ViscousForm {
    #[default]
    Stress,
    Laplace,
}

/// Form of the convective term (Navier-Stokes).
/// - `Convective`: `(rho u . grad u, v)` (the paper's);
/// - `SkewSymmetric`: `(rho u . grad u, v) + (rho / 2 (div u) u, v)` (Temam 1968). The added
///   term vanishes for the exact solution; it makes the discrete convective term's work on the
///   velocity itself a boundary term, `rho / 2 int (u . n) |u|^2`, where the P2+/P1disc velocity
///   is divergence-free only weakly, so that the kinetic energy cannot grow through it inside
///   the fluid. It keeps flows at high cell Reynolds numbers from blowing up at single nodes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ConvectiveForm {
    #[default]
    Convective,
    SkewSymmetric,
}

/// Stabilisation of the convection (Navier-Stokes).
/// - `None`: the paper's Galerkin method (P2+/P1disc is inf-sup stable: the pressure needs none);
/// - `Supg`: streamline-upwind/Petrov-Galerkin (Brooks & Hughes 1982), the test function of the
///   momentum equation moved along the flow in each cell: adds
///   `sum_K int_K tau (u . grad v) . r(u, p)`, with `r = rho (du/dt + u . grad u) + grad p -
///   div(eta (grad u + grad u^T)) - f` the strong momentum residual (the Laplace form's viscous
///   term `eta Laplace u`; axisymmetric with its hoop terms), zero for the exact solution: the
///   method stays consistent. `tau = ((2 a)^2 + (2 |u| / h)^2 + 9 (4 nu / h^2)^2)^(-1/2)`
///   (Shakib, Hughes & Johan 1991), `a` the time scheme's `1/dt` factor (0 when steady),
///   `nu = eta / rho`, `h = (D! |K|)^(1/D) / 2` (the cell's size over the velocity's degree). It
///   removes the node-to-node wiggles of the Galerkin velocity where the cell Reynolds number
///   `|u| h / nu` is large. The Jacobian is exact (`tau`'s dependence on `u` included).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stabilization {
    #[default]
    None,
    Supg,
}

/// Material and time-discretisation parameters of the fluid kernel.
#[derive(Clone, Copy, Debug)]
pub struct FluidParams {
    /// Dynamic viscosity `eta`.
    pub viscosity: f64,
    /// Density `rho`.
    pub density: f64,
    /// `1/dt` of implicit Euler; 0 for a steady problem.
    pub inv_dt: f64,
    /// Include the convective term `rho u . grad u` (Navier-Stokes) or not (Stokes).
    pub convection: bool,
    /// Form of the convective term.
    pub convective_form: ConvectiveForm,
    /// Form of the viscous term.
    pub viscous_form: ViscousForm,
    /// Stabilisation of the convection; SUPG needs cell values made
    /// [`CellValues::with_hessians`].
    pub stabilization: Stabilization,
}

/// Local unknowns of one cell: velocity `u[i * D + a]` (node `i`, component `a`), the previous
/// time level `u_old` (same layout, ignored when steady), pressure `p[k]` (P1disc dofs).
pub struct CellState<'a> {
    pub u: &'a [f64],
    pub u_old: &'a [f64],
    pub p: &'a [f64],
}

/// Fluid cell kernel: element residual `re` and Jacobian `ke` (row-major, local order: all
/// velocity dofs `i * D + a`, then the `D + 1` pressure dofs). `cv` must be re-initialised for
/// the cell; `body_force(x)` is `f`.
pub fn fluid_cell<const D: usize>(
    cv: &CellValues<D>,
    formulation: Formulation,
    params: &FluidParams,
    state: &CellState<'_>,
    body_force: &dyn Fn(&[f64; D]) -> [f64; D],
    ke: &mut [f64],
    re: &mut [f64],
) {
    let nv = cv.num_dofs();
    let nu = nv * D;
    let np = D + 1;
    let n = nu + np;
    debug_assert_eq!(ke.len(), n * n);
    let axi = formulation == Formulation::Axisymmetric;
    let eta = params.viscosity;
    let rho = params.density;
    // Weight of the transposed-gradient term and of the hoop term: stress form 1 and 2,
    // Laplace form 0 and 1.
    let (sym, hoop_k) = match params.viscous_form {
        ViscousForm::Stress => (1.0, 2.0),
        ViscousForm::Laplace => (0.0, 1.0),
    };
    // rho / 2 of the skew-symmetric form's term (rho / 2) (div u) u; 0 in the convective form.
    let skew = if params.convection && params.convective_form == ConvectiveForm::SkewSymmetric { 0.5 * rho } else { 0.0 };
    let supg = (params.convection && params.stabilization == Stabilization::Supg).then(|| {
        let measure: f64 = cv.jxw.iter().sum();
        let factorial = if D == 3 { 6.0 } else { 2.0 };
        Supg { h: 0.5 * (factorial * measure).powf(1.0 / D as f64), sym, axi }
    });
    let mut psi = [0.0; 4];
    for q in 0..cv.num_points() {
        let x = cv.x[q];
        let r = if axi { x[1] } else { 1.0 };
        let w = cv.jxw[q] * r;
        let phi = cv.phi(q);
        let dphi = cv.grad_phi(q);
        p1disc_basis(&x, &cv.centroid, &mut psi);
        // Interpolated fields at the point.
        let mut u = [0.0; D];
        let mut u_old = [0.0; D];
        let mut gu = [[0.0; D]; D]; // gu[a][b] = d u_a / d x_b
        for i in 0..nv {
            for a in 0..D {
                let ua = state.u[i * D + a];
                u[a] += ua * phi[i];
                if params.inv_dt != 0.0 {
                    u_old[a] += state.u_old[i * D + a] * phi[i];
                }
                for b in 0..D {
                    gu[a][b] += ua * dphi[i][b];
                }
            }
        }
        let p: f64 = (0..np).map(|k| state.p[k] * psi[k]).sum();
        let mut div_u: f64 = (0..D).map(|a| gu[a][a]).sum();
        let hoop = if axi { u[1] / r } else { 0.0 };
        div_u += hoop;
        let f = body_force(&x);
        if let Some(supg) = &supg {
            let grad_p: [f64; D] = std::array::from_fn(|a| state.p[a + 1]);
            let point = SupgPoint { w, r, u, u_old, gu, grad_p, f, phi, dphi, hessian: cv.hessian_phi(q) };
            supg.add(params, &point, state.u, n, ke, re);
        }
        // Momentum "force" per component: inertia + convection - body force.
        let mut m = [0.0; D];
        for a in 0..D {
            m[a] = rho * params.inv_dt * (u[a] - u_old[a]) - f[a];
            if params.convection {
                m[a] += rho * (0..D).map(|b| u[b] * gu[a][b]).sum::<f64>() + skew * div_u * u[a];
            }
        }
        // Residual.
        for i in 0..nv {
            for a in 0..D {
                let mut s = 0.0;
                for b in 0..D {
                    s += eta * (gu[a][b] + sym * gu[b][a]) * dphi[i][b];
                }
                let mut div_v = dphi[i][a];
                if axi && a == 1 {
                    s += hoop_k * eta * hoop * phi[i] / r;
                    div_v += phi[i] / r;
                }
                re[i * D + a] += w * (s - p * div_v + m[a] * phi[i]);
            }
        }
        for k in 0..np {
            re[nu + k] -= w * psi[k] * div_u;
        }
        // Jacobian, per block (i, j) of velocity rows and columns:
        //   d_ij delta_ab + c_ij dU_a/dx_b + sym eta dphi_i/dx_b dphi_j/dx_a,
        //   d_ij = eta grad phi_i . grad phi_j + phi_i (rho/dt phi_j + rho u . grad phi_j),
        //   c_ij = rho phi_i phi_j (convection only),
        // plus the hoop term on (r, r) when axisymmetric; loop-invariant choices are made outside
        // the (i, j) loops (this is the hot loop of assembly).
        let mass = rho * params.inv_dt;
        let rho_c = if params.convection { rho } else { 0.0 };
        let mut conv = [0.0; 32];
        debug_assert!(nv <= conv.len(), "velocity elements of at most 32 nodes");
        for j in 0..nv {
            conv[j] = rho_c * (0..D).map(|b| u[b] * dphi[j][b]).sum::<f64>();
        }
        for i in 0..nv {
            let (wpi, wdpi) = (w * phi[i], dphi[i].map(|g| w * g));
            for j in 0..nv {
                let dpj = &dphi[j];
                let d = eta * (0..D).map(|b| wdpi[b] * dpj[b]).sum::<f64>() + wpi * (mass * phi[j] + conv[j]);
                let c = rho_c * wpi * phi[j];
                for a in 0..D {
                    let row = (i * D + a) * n + j * D;
                    for b in 0..D {
                        ke[row + b] += c * gu[a][b] + sym * eta * wdpi[b] * dpj[a];
                    }
                    ke[row + a] += d;
                }
            }
            if axi {
                let a = 1;
                for j in 0..nv {
                    ke[(i * D + a) * n + j * D + a] += hoop_k * eta * wpi * phi[j] / (r * r);
                }
            }
            if skew != 0.0 {
                // d/du_jb of (rho / 2) (div u) u_a phi_i: (rho / 2) phi_i (u_a ddiv_jb + div u
                // delta_ab phi_j), ddiv_jb = dphi_j/dx_b (+ phi_j / r for b = r when axisymmetric).
                for j in 0..nv {
                    for a in 0..D {
                        let row = (i * D + a) * n + j * D;
                        for b in 0..D {
                            let ddiv = dphi[j][b] + if axi && b == 1 { phi[j] / r } else { 0.0 };
                            ke[row + b] += skew * wpi * u[a] * ddiv;
                        }
                        ke[row + a] += skew * wpi * div_u * phi[j];
                    }
                }
            }
            for a in 0..D {
                let mut div_v = dphi[i][a];
                if axi && a == 1 {
                    div_v += phi[i] / r;
                }
                for k in 0..np {
                    let b = -w * psi[k] * div_v;
                    ke[(i * D + a) * n + nu + k] += b;
                    ke[(nu + k) * n + i * D + a] += b;
                }
            }
        }
    }
}

/// The SUPG term of one cell ([`Stabilization::Supg`]): its size `h`, the viscous form's
/// weight `sym` of the transposed gradient, and whether it is axisymmetric.
struct Supg {
    h: f64,
    sym: f64,
    axi: bool,
}

/// The fields at one quadrature point, for [`Supg::add`]: weight `w` (times `r`), radius `r` (1
/// in plane), `u`, `u_old`, `gu[a][b] = du_a/dx_b`, the pressure gradient, the body force, the
/// basis values, gradients and second derivatives.
struct SupgPoint<'a, const D: usize> {
    w: f64,
    r: f64,
    u: [f64; D],
    u_old: [f64; D],
    gu: [[f64; D]; D],
    grad_p: [f64; D],
    f: [f64; D],
    phi: &'a [f64],
    dphi: &'a [[f64; D]],
    hessian: &'a [[[f64; D]; D]],
}

impl Supg {
    /// Adds `w tau (u . grad phi_i) r_a` to the residual rows of the velocity and its exact
    /// derivatives to `ke` (`n` local unknowns; the velocity `u_nodes[i * D + a]`).
    fn add<const D: usize>(&self, params: &FluidParams, pt: &SupgPoint<'_, D>, u_nodes: &[f64], n: usize, ke: &mut [f64], re: &mut [f64]) {
        let (eta, rho, a_t, h, r) = (params.viscosity, params.density, params.inv_dt, self.h, pt.r);
        let (u, gu, phi, dphi, hess) = (&pt.u, &pt.gu, pt.phi, pt.dphi, pt.hessian);
        let nv = phi.len();
        // Second derivatives of u: Laplace u and grad div u, with the axisymmetric hoop terms
        // (x = (z, r), no swirl): Laplace u_a += (du_a/dr) / r - [a = r] u_r / r^2,
        // d_a div u += (du_r/dx_a) / r - [a = r] u_r / r^2.
        let mut lap = [0.0; D];
        let mut grad_div = [0.0; D];
        for (i, hi) in hess.iter().enumerate() {
            for a in 0..D {
                let ua = u_nodes[i * D + a];
                for b in 0..D {
                    lap[a] += ua * hi[b][b];
                    grad_div[b] += ua * hi[a][b];
                }
            }
        }
        if self.axi {
            for a in 0..D {
                lap[a] += gu[a][1] / r;
                grad_div[a] += gu[1][a] / r;
            }
            lap[1] -= u[1] / (r * r);
            grad_div[1] -= u[1] / (r * r);
        }
        let residual: [f64; D] = std::array::from_fn(|a| {
            let convection: f64 = (0..D).map(|b| u[b] * gu[a][b]).sum();
            rho * a_t * (u[a] - pt.u_old[a]) + rho * convection + pt.grad_p[a] - pt.f[a] - eta * (lap[a] + self.sym * grad_div[a])
        });
        let nu = eta / rho;
        let speed2: f64 = u.iter().map(|v| v * v).sum();
        let tau = 1.0 / ((2.0 * a_t).powi(2) + 4.0 * speed2 / (h * h) + 144.0 * (nu / (h * h)).powi(2)).sqrt();
        // d tau / d u_b = -tau^3 (4 / h^2) u_b (times phi_j).
        let dtau: [f64; D] = std::array::from_fn(|b| -tau.powi(3) * 4.0 / (h * h) * u[b]);
        let mut streamline = [0.0; 32];
        assert!(nv <= streamline.len(), "velocity elements of at most 32 nodes");
        for (s_i, g) in streamline.iter_mut().zip(dphi) {
            *s_i = (0..D).map(|b| u[b] * g[b]).sum();
        }
        let w = pt.w;
        let nu_dofs = nv * D;
        // Per column node j, the parts of d r_a / d u_jb that do not depend on (a, b) beyond the
        // diagonal: rho a phi_j + rho u . grad phi_j - eta (trace H_j + hoop), hoisted out of the
        // (i, a, b) loops (this is the hot loop of a stabilised assembly).
        let mut diagonal = [0.0; 32];
        for j in 0..nv {
            let trace: f64 = (0..D).map(|c| hess[j][c][c]).sum::<f64>() + if self.axi { dphi[j][1] / r } else { 0.0 };
            diagonal[j] = rho * a_t * phi[j] + rho * streamline[j] - eta * trace;
        }
        for i in 0..nv {
            let s_i = streamline[i];
            let c = w * tau * s_i;
            for a in 0..D {
                re[i * D + a] += c * residual[a];
                // The pressure: d r_a / d p_k = d psi_k / dx_a, 1 for k = a + 1 (psi = {1, x - c}).
                ke[(i * D + a) * n + nu_dofs + a + 1] += c;
            }
            for j in 0..nv {
                let (pj, dpj, hj) = (phi[j], &dphi[j], &hess[j]);
                // d (w tau s_i) / d u_jb, times r_a below.
                let dweight: [f64; D] = std::array::from_fn(|b| w * pj * (dtau[b] * s_i + tau * dphi[i][b]));
                for a in 0..D {
                    let row = (i * D + a) * n + j * D;
                    for b in 0..D {
                        // d r_a / d u_jb.
                        let mut dvisc = self.sym * hj[a][b];
                        if self.axi && b == 1 {
                            dvisc += self.sym * (dpj[a] / r - if a == 1 { pj / (r * r) } else { 0.0 });
                        }
                        let mut dr = rho * pj * gu[a][b] - eta * dvisc;
                        if a == b {
                            dr += diagonal[j] + if self.axi && a == 1 { eta * pj / (r * r) } else { 0.0 };
                        }
                        ke[row + b] += dweight[b] * residual[a] + c * dr;
                    }
                }
            }
        }
    }
}

/// Traction (Neumann) facet kernel: subtracts `int_facet t . v (r)` from the residual rows of the
/// velocity. `phi` at each point comes from `fv`; `traction(x, n)` gives `t`.
#[allow(clippy::type_complexity, reason = "the traction as a function of position and normal")]
pub fn traction_facet<const D: usize>(
    fv: &fdfsi_fem::values::FacetValues<D>,
    formulation: Formulation,
    traction: &dyn Fn(&[f64; D], &[f64; D]) -> [f64; D],
    re: &mut [f64],
) {
    for q in 0..fv.num_points() {
        let x = fv.x[q];
        let w = fv.jxw[q] * formulation.weight(&x);
        let t = traction(&x, &fv.normal[q]);
        for (i, phi) in fv.phi(q).iter().enumerate() {
            for a in 0..D {
                re[i * D + a] -= w * t[a] * phi;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fdfsi_fem::element::ReferenceElement;
    use fdfsi_fem::quadrature;

    /// Asserts that the Jacobian `eval` gives at `x0` is the central finite difference of the
    /// residual it gives, column by column, to `1e-6 (1 + |fd|)`.
    /// The fluid kernel on `cv` as a function of the cell's unknowns (velocity, then pressure):
    /// `(x, K, R)` with `K` and `R` zeroed first.
    fn kernel<'a, const D: usize>(
        cv: &'a CellValues<D>,
        form: Formulation,
        params: &'a FluidParams,
        u_old: &'a [f64],
        f: &'a dyn Fn(&[f64; D]) -> [f64; D],
    ) -> impl Fn(&[f64], &mut Vec<f64>, &mut Vec<f64>) + 'a {
        move |xs, ke, re| {
            ke.iter_mut().for_each(|v| *v = 0.0);
            re.iter_mut().for_each(|v| *v = 0.0);
            let st = CellState { u: &xs[..u_old.len()], u_old, p: &xs[u_old.len()..] };
            fluid_cell(cv, form, params, &st, f, ke, re);
        }
    }

    /// Numbers in [-0.5, 0.5) from a linear congruential generator seeded with `seed`.
    fn centred_uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    fn assert_jacobian_is_the_residuals_derivative(x0: &[f64], eval: impl Fn(&[f64], &mut Vec<f64>, &mut Vec<f64>), what: &str) {
        let n = x0.len();
        let (mut ke, mut re) = (vec![0.0; n * n], vec![0.0; n]);
        eval(x0, &mut ke, &mut re);
        let h = 1e-6;
        for j in 0..n {
            let (mut xp, mut xm) = (x0.to_vec(), x0.to_vec());
            xp[j] += h;
            xm[j] -= h;
            let (mut kp, mut rp, mut rm) = (vec![0.0; n * n], vec![0.0; n], vec![0.0; n]);
            eval(&xp, &mut kp, &mut rp);
            eval(&xm, &mut kp, &mut rm);
            for i in 0..n {
                let fd = (rp[i] - rm[i]) / (2.0 * h);
                assert!((fd - ke[i * n + j]).abs() < 1e-6 * (1.0 + fd.abs()), "{what}: K[{i}][{j}] = {} vs FD {fd}", ke[i * n + j]);
            }
        }
    }

    /// The kernel's Jacobian equals a central finite difference of its residual, for every
    /// formulation, with convection and inertia switched on.
    #[test]
    fn jacobian_matches_finite_differences_of_residual() {
        let fun = ReferenceElement::p2plus_triangle();
        let geo = ReferenceElement::p1_triangle();
        let mut cv = CellValues::new(quadrature::triangle(5), &fun, &geo);
        cv.reinit(&[[0.2, 0.3], [1.1, 0.4], [0.5, 1.2]]).unwrap();
        let nu = 14;
        let n = nu + 3;
        let forms = [ViscousForm::Stress, ViscousForm::Laplace]
            .into_iter()
            .flat_map(|v| [(v, ConvectiveForm::Convective), (v, ConvectiveForm::SkewSymmetric)]);
        for (form_v, form_c) in forms {
            let params = FluidParams {
                viscosity: 0.7,
                density: 1.3,
                inv_dt: 5.0,
                convection: true,
                convective_form: form_c,
                viscous_form: form_v,
                stabilization: Stabilization::None,
            };
            let mut rnd = centred_uniform(7);
            let x0: Vec<f64> = (0..n).map(|_| rnd()).collect();
            let u_old: Vec<f64> = (0..nu).map(|_| rnd()).collect();
            let f = |x: &[f64; 2]| [x[0].sin(), x[1] * x[0]];
            for form in [Formulation::Plane, Formulation::Axisymmetric] {
                let eval = kernel(&cv, form, &params, &u_old, &f);
                assert_jacobian_is_the_residuals_derivative(&x0, eval, &format!("{form:?}"));
            }
        }
    }

    /// With SUPG the kernel's Jacobian (`tau`'s dependence on `u`, the streamline test function,
    /// the strong residual's second derivatives) equals a central finite difference of its
    /// residual: plane and axisymmetric, both viscous forms, steady and unsteady, on a straight
    /// and a curved (P2 geometry) cell.
    #[test]
    fn supg_jacobian_matches_finite_differences_of_residual() {
        let fun = ReferenceElement::p2plus_triangle();
        let straight = ReferenceElement::p1_triangle();
        let curved = ReferenceElement::p2_triangle();
        let cells: [(&ReferenceElement<2>, Vec<[f64; 2]>); 2] = [
            (&straight, vec![[0.2, 0.3], [1.1, 0.4], [0.5, 1.2]]),
            (&curved, vec![[0.2, 0.3], [1.1, 0.4], [0.5, 1.2], [0.65, 0.3], [0.9, 0.9], [0.3, 0.75]]),
        ];
        let (nu, n) = (14, 17);
        let mut rnd = centred_uniform(11);
        let x0: Vec<f64> = (0..n).map(|_| 3.0 * rnd()).collect();
        let u_old: Vec<f64> = (0..nu).map(|_| rnd()).collect();
        let f = |x: &[f64; 2]| [x[0].sin(), x[1] * x[0]];
        for (geo, coords) in &cells {
            let mut cv = CellValues::new(quadrature::triangle(5), &fun, geo).with_hessians(&fun, geo);
            cv.reinit(coords).unwrap();
            for (form_v, inv_dt, form) in [
                (ViscousForm::Stress, 5.0, Formulation::Plane),
                (ViscousForm::Laplace, 0.0, Formulation::Plane),
                (ViscousForm::Stress, 0.0, Formulation::Axisymmetric),
                (ViscousForm::Laplace, 5.0, Formulation::Axisymmetric),
            ] {
                let params = FluidParams {
                    viscosity: 0.07,
                    density: 1.3,
                    inv_dt,
                    convection: true,
                    convective_form: ConvectiveForm::Convective,
                    viscous_form: form_v,
                    stabilization: Stabilization::Supg,
                };
                let eval = kernel(&cv, form, &params, &u_old, &f);
                let (mut ke, mut re) = (vec![0.0; n * n], vec![0.0; n]);
                eval(&x0, &mut ke, &mut re);
                // The SUPG term is there: the residual differs from Galerkin's.
                let galerkin = FluidParams { stabilization: Stabilization::None, ..params };
                let (mut kg, mut rg) = (vec![0.0; n * n], vec![0.0; n]);
                let st = CellState { u: &x0[..nu], u_old: &u_old, p: &x0[nu..] };
                fluid_cell(&cv, form, &galerkin, &st, &f, &mut kg, &mut rg);
                assert!(re.iter().zip(&rg).any(|(a, b)| (a - b).abs() > 1e-3 * b.abs().max(1.0)), "{form:?}: no SUPG term");
                assert_jacobian_is_the_residuals_derivative(
                    &x0,
                    eval,
                    &format!("{form:?} {form_v:?} inv_dt {inv_dt} ({} geometry nodes)", coords.len()),
                );
            }
        }
    }

    /// The same in 3D (P2+ tetrahedra, whose face and volume bubbles have second derivatives of
    /// their own), with the skew-symmetric Galerkin convection that the 3D valve sector uses
    /// beside SUPG, and a cell a hundred times thinner than it is wide (the slivers the
    /// adaptation leaves where gamma_s passes near a node).
    #[test]
    fn supg_jacobian_matches_finite_differences_of_residual_in_3d() {
        let fun = ReferenceElement::p2plus_tetrahedron();
        let geo = ReferenceElement::p1_tetrahedron();
        let cells: [[[f64; 3]; 4]; 2] = [
            [[0.2, 0.3, 0.1], [1.1, 0.4, 0.2], [0.5, 1.2, 0.0], [0.4, 0.5, 0.9]],
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.4, 0.3, 0.01]],
        ];
        let (nu, n) = (45, 49);
        let mut rnd = centred_uniform(13);
        let x0: Vec<f64> = (0..n).map(|_| 3.0 * rnd()).collect();
        let u_old: Vec<f64> = (0..nu).map(|_| rnd()).collect();
        let f = |x: &[f64; 3]| [x[0].sin(), x[1] * x[0], x[2]];
        for coords in &cells {
            let mut cv = CellValues::new(quadrature::tetrahedron(5), &fun, &geo).with_hessians(&fun, &geo);
            cv.reinit(coords).unwrap();
            for (form_v, form_c) in [(ViscousForm::Stress, ConvectiveForm::SkewSymmetric), (ViscousForm::Laplace, ConvectiveForm::Convective)] {
                let params = FluidParams {
                    viscosity: 0.07,
                    density: 1.3,
                    inv_dt: 5.0,
                    convection: true,
                    convective_form: form_c,
                    viscous_form: form_v,
                    stabilization: Stabilization::Supg,
                };
                let eval = kernel(&cv, Formulation::Plane, &params, &u_old, &f);
                assert_jacobian_is_the_residuals_derivative(&x0, eval, &format!("3D {form_v:?} {form_c:?} cell {coords:?}"));
            }
        }
    }

    /// SUPG is consistent: where the velocity and the pressure are the exact solution (here a
    /// quadratic velocity with its pressure, interpolated exactly by P2+/P1disc, and the body
    /// force that makes them solve the Navier-Stokes equations), the SUPG term of the residual
    /// is zero; axisymmetric too (a straight cell: on a curved one P2+ does not hold quadratics).
    #[test]
    fn supg_vanishes_on_an_exact_solution() {
        let fun = ReferenceElement::p2plus_triangle();
        let geo = ReferenceElement::p1_triangle();
        let coords = [[0.2, 0.3], [1.1, 0.4], [0.5, 1.2]];
        let mut cv = CellValues::new(quadrature::triangle(6), &fun, &geo).with_hessians(&fun, &geo);
        cv.reinit(&coords).unwrap();
        // The velocity nodes' positions: the map of the reference nodes.
        let tab = geo.tabulate(fun.nodes());
        let nodes: Vec<[f64; 2]> = (0..7).map(|i| std::array::from_fn(|d| (0..3).map(|k| tab.values[i * 3 + k] * coords[k][d]).sum())).collect();
        let (eta, rho, inv_dt) = (0.3, 1.3, 4.0);
        // u = (x^2 + y, x y - 1) (not divergence-free: the residual holds any u), u_old = u - (1, 2) / inv_dt,
        // p = 2 + x - 3 y: f = rho (du/dt + u . grad u) + grad p - div(eta (grad u + grad u^T)) - eta / r-terms.
        let u_at = |x: &[f64; 2]| [x[0] * x[0] + x[1], x[0] * x[1] - 1.0];
        let (p0, px, py) = (2.0, 1.0, -3.0);
        for (form, form_v) in [
            (Formulation::Plane, ViscousForm::Stress),
            (Formulation::Plane, ViscousForm::Laplace),
            (Formulation::Axisymmetric, ViscousForm::Stress),
            (Formulation::Axisymmetric, ViscousForm::Laplace),
        ] {
            let axi = form == Formulation::Axisymmetric;
            let sym = if form_v == ViscousForm::Stress { 1.0 } else { 0.0 };
            let force = |x: &[f64; 2]| -> [f64; 2] {
                let [u, v] = u_at(x);
                let g = [[2.0 * x[0], 1.0], [x[1], x[0]]];
                // Laplace u = (2, 0); grad div u = grad(2 x + x) = (3, 0).
                let mut lap = [2.0, 0.0];
                let mut grad_div = [3.0, 0.0];
                if axi {
                    let r = x[1];
                    lap = [lap[0] + g[0][1] / r, lap[1] + g[1][1] / r - v / (r * r)];
                    grad_div = [grad_div[0] + g[1][0] / r, grad_div[1] + g[1][1] / r - v / (r * r)];
                }
                let dudt = [1.0, 2.0];
                std::array::from_fn(|a| rho * (dudt[a] + u * g[a][0] + v * g[a][1]) + [px, py][a] - eta * (lap[a] + sym * grad_div[a]))
            };
            let u: Vec<f64> = nodes.iter().flat_map(&u_at).collect();
            let u_old: Vec<f64> = u.iter().enumerate().map(|(k, v)| v - [1.0, 2.0][k % 2] / inv_dt).collect();
            let c = cv.centroid;
            let p = [p0 + px * c[0] + py * c[1], px, py];
            let params = |stabilization| FluidParams {
                viscosity: eta,
                density: rho,
                inv_dt,
                convection: true,
                convective_form: ConvectiveForm::Convective,
                viscous_form: form_v,
                stabilization,
            };
            let residual = |stabilization| {
                let (mut ke, mut re) = (vec![0.0; 17 * 17], vec![0.0; 17]);
                fluid_cell(&cv, form, &params(stabilization), &CellState { u: &u, u_old: &u_old, p: &p }, &force, &mut ke, &mut re);
                re
            };
            let (with, without) = (residual(Stabilization::Supg), residual(Stabilization::None));
            let scale = without.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let worst = with.iter().zip(&without).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(worst < 1e-12 * scale, "{form:?} {form_v:?}: SUPG term {worst:e} of {scale:e}");
        }
    }

    /// The skew-symmetric convective term's work on the velocity itself is the boundary term
    /// `rho / 2 int_dK (u . n) |u|^2` on a cell, for any velocity (one not divergence-free
    /// here); the convective form's differs from it by `rho / 2 int_K (div u) |u|^2`.
    #[test]
    fn skew_symmetric_convection_works_on_the_velocity_only_through_the_boundary() {
        let fun = ReferenceElement::p2plus_triangle();
        let geo = ReferenceElement::p1_triangle();
        let coords = [[0.2, 0.3], [1.1, 0.4], [0.5, 1.2]];
        let mut cv = CellValues::new(quadrature::triangle(8), &fun, &geo);
        cv.reinit(&coords).unwrap();
        let (points, weights) = quadrature::for_facets(fdfsi_fem::element::ReferenceCell::Triangle, 8);
        let mut fv = fdfsi_fem::values::FacetValues::new(fdfsi_fem::element::ReferenceCell::Triangle, &points, &weights, &fun, &geo);
        let (nu, n) = (14, 17);
        let u: Vec<f64> = (0..nu).map(|k| ((k * 7 + 3) % 11) as f64 / 5.0 - 1.0).collect();
        let rho = 1.3;
        let work = |form: ConvectiveForm| {
            let params = FluidParams {
                viscosity: 0.0,
                density: rho,
                inv_dt: 0.0,
                convection: true,
                convective_form: form,
                viscous_form: ViscousForm::Stress,
                stabilization: Stabilization::None,
            };
            let (mut ke, mut re) = (vec![0.0; n * n], vec![0.0; n]);
            let st = CellState { u: &u, u_old: &u, p: &[0.0; 3] };
            fluid_cell(&cv, Formulation::Plane, &params, &st, &|_| [0.0; 2], &mut ke, &mut re);
            (0..nu).map(|k| re[k] * u[k]).sum::<f64>()
        };
        let mut boundary = 0.0;
        for facet in 0..3 {
            fv.reinit(&coords, facet).unwrap();
            for q in 0..fv.num_points() {
                let phi = fv.phi(q);
                let uq: [f64; 2] = std::array::from_fn(|a| (0..7).map(|i| u[i * 2 + a] * phi[i]).sum());
                let un = uq[0] * fv.normal[q][0] + uq[1] * fv.normal[q][1];
                boundary += 0.5 * rho * fv.jxw[q] * un * (uq[0] * uq[0] + uq[1] * uq[1]);
            }
        }
        let (skew, plain) = (work(ConvectiveForm::SkewSymmetric), work(ConvectiveForm::Convective));
        assert!((skew - boundary).abs() < 1e-12 * boundary.abs().max(1.0), "skew-symmetric {skew} vs boundary {boundary}");
        assert!((plain - boundary).abs() > 1e-3 * boundary.abs().max(1.0), "convective {plain} vs boundary {boundary}");
    }
}
