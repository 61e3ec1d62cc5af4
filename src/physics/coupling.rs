//! The Lagrange-multiplier coupling of fluid and solid (paper eq. 7, METHOD.md section 2): the
//! point kernel.
//!
//! On each coupling element (a facet of gamma_f) the multiplier `lambda` is P1 discontinuous
//! (`D` components on each of the facet's `D` vertices). In residual form, for every multiplier
//! test function `mu`, fluid velocity test function `v` and solid test function `w`:
//!
//! ```text
//! R_lambda(mu) =  <mu, u_f - u_s>_gamma_f,        u_s = (x_{n+1} - x_n) / dt = Delta u / dt
//! R_f(v)      +=  <lambda, v>_gamma_f
//! R_s(w)      += -<lambda, w>_gamma_f
//! ```
//!
//! with the fluid residual of [`crate::physics::fluid`] (`(sigma_f, grad v) - ...`) and the solid
//! residual of [`crate::physics::solid`] (`(sigma_s, grad w) - ...`).
//!
//! **Sign convention.** Integrating the fluid's weak form by parts on both sides of gamma_f gives
//! `sum_sides sigma_f n_out + lambda = 0`, where `sigma_f n_out` is the traction the solid exerts
//! on the fluid; the solid's weak form has `lambda` as the traction applied to it. So `lambda`
//! is the **traction of the fluid on the solid** (action), `-lambda` that of the solid on the
//! fluid (reaction), and `int_gamma_f lambda ds` is the hydrodynamic force on the body, equal to
//! the consistent-residual force `-R_f(v_a)` of the fluid ([`crate::post::quantities::boundary_force`]).
//!
//! The constraint row carries `+<mu, u_f>`, so the fluid-multiplier blocks of the Jacobian are
//! transposes of each other (`B_f` and `B_f^T`); the solid-multiplier blocks are `-B_s^T` (solid
//! rows) and `-a B_s` (constraint rows; `a = 1/dt` for implicit Euler, `1.5/dt` for BDF2 at equal
//! steps).

/// One quadrature point of a coupling element: the weight (`ds`, times `r` when axisymmetric)
/// and the basis values there: multiplier `mu` (the facet's P1 functions), fluid velocity `phi_f`
/// (the P2+ basis of the fluid cell the trace is taken from), solid `phi_s` (the Q2 basis of the
/// solid cell the point lies in on gamma_s).
#[derive(Clone, Copy, Debug)]
pub struct CouplingPoint<'a> {
    pub weight: f64,
    pub mu: &'a [f64],
    pub phi_f: &'a [f64],
    pub phi_s: &'a [f64],
}

/// Local unknowns of one coupling point, component-fastest (`[i * D + a]`): the multiplier on
/// the facet's nodes, the fluid velocity of the fluid cell, the solid displacement increment of
/// the solid cell.
#[derive(Clone, Copy, Debug)]
pub struct CouplingState<'a> {
    pub lambda: &'a [f64],
    pub u_f: &'a [f64],
    pub du_s: &'a [f64],
}

/// Coupling kernel at one point: adds the residual to `re` and the Jacobian to `ke` (row-major,
/// `n x n` with `n = (nm + nf + ns) D`; local order: multiplier dofs, fluid velocity dofs, solid
/// displacement dofs, each `i * D + a`). `inv_dt` is `1/dt` of `u_s = Delta u / dt`.
/// Allocation-free; the Jacobian does not depend on the state (the coupling is bilinear).
pub fn coupling_point<const D: usize>(pt: &CouplingPoint<'_>, inv_dt: f64, state: &CouplingState<'_>, ke: &mut [f64], re: &mut [f64]) {
    let (nm, nf, ns) = (pt.mu.len(), pt.phi_f.len(), pt.phi_s.len());
    let (om, of, os) = (0, nm * D, (nm + nf) * D);
    let n = (nm + nf + ns) * D;
    debug_assert_eq!(ke.len(), n * n);
    debug_assert_eq!(re.len(), n);
    let w = pt.weight;
    let mut lam = [0.0; D];
    let mut uf = [0.0; D];
    let mut us = [0.0; D];
    for a in 0..D {
        lam[a] = (0..nm).map(|k| pt.mu[k] * state.lambda[k * D + a]).sum();
        uf[a] = (0..nf).map(|i| pt.phi_f[i] * state.u_f[i * D + a]).sum();
        us[a] = inv_dt * (0..ns).map(|i| pt.phi_s[i] * state.du_s[i * D + a]).sum::<f64>();
    }
    for a in 0..D {
        for k in 0..nm {
            let row = om + k * D + a;
            re[row] += w * pt.mu[k] * (uf[a] - us[a]);
            for j in 0..nf {
                let v = w * pt.mu[k] * pt.phi_f[j];
                ke[row * n + of + j * D + a] += v;
                ke[(of + j * D + a) * n + row] += v;
            }
            for j in 0..ns {
                let v = w * pt.mu[k] * pt.phi_s[j];
                ke[row * n + os + j * D + a] -= inv_dt * v;
                ke[(os + j * D + a) * n + row] -= v;
            }
        }
        for i in 0..nf {
            re[of + i * D + a] += w * pt.phi_f[i] * lam[a];
        }
        for i in 0..ns {
            re[os + i * D + a] -= w * pt.phi_s[i] * lam[a];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_matches_finite_differences_and_constants_are_reproduced() {
        const D: usize = 2;
        let mu = [0.3, 0.7];
        let phi_f = [0.1, -0.05, 0.2, 0.4, 0.3, 0.05, 0.0];
        let phi_s = [0.2, 0.1, 0.05, 0.05, 0.3, 0.1, 0.1, 0.05, 0.05];
        // Partitions of unity.
        assert!((phi_f.iter().sum::<f64>() - 1.0).abs() < 1e-14 && (phi_s.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        let pt = CouplingPoint { weight: 0.37, mu: &mu, phi_f: &phi_f, phi_s: &phi_s };
        let (nm, nf, ns) = (2, 7, 9);
        let n = (nm + nf + ns) * D;
        let inv_dt = 4.0;
        let mut s = 11u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let x0: Vec<f64> = (0..n).map(|_| rnd()).collect();
        let eval = |x: &[f64], ke: &mut Vec<f64>, re: &mut Vec<f64>| {
            ke.iter_mut().for_each(|v| *v = 0.0);
            re.iter_mut().for_each(|v| *v = 0.0);
            let st = CouplingState { lambda: &x[..nm * D], u_f: &x[nm * D..(nm + nf) * D], du_s: &x[(nm + nf) * D..] };
            coupling_point::<D>(&pt, inv_dt, &st, ke, re);
        };
        let (mut ke, mut re) = (vec![0.0; n * n], vec![0.0; n]);
        eval(&x0, &mut ke, &mut re);
        for j in 0..n {
            let (mut xp, mut xm) = (x0.clone(), x0.clone());
            xp[j] += 1e-6;
            xm[j] -= 1e-6;
            let (mut k2, mut rp, mut rm) = (vec![0.0; n * n], vec![0.0; n], vec![0.0; n]);
            eval(&xp, &mut k2, &mut rp);
            eval(&xm, &mut k2, &mut rm);
            for i in 0..n {
                let fd = (rp[i] - rm[i]) / 2e-6;
                assert!((fd - ke[i * n + j]).abs() < 1e-8, "K[{i}][{j}] = {} vs {fd}", ke[i * n + j]);
            }
        }
        // u_f = c, Delta u = dt c: zero constraint residual.
        let c = [0.8, -1.3];
        let mut x = vec![0.0; n];
        for i in 0..nf {
            x[(nm + i) * D..(nm + i + 1) * D].copy_from_slice(&c);
        }
        for i in 0..ns {
            for a in 0..D {
                x[(nm + nf + i) * D + a] = c[a] / inv_dt;
            }
        }
        eval(&x, &mut ke, &mut re);
        assert!(re[..nm * D].iter().all(|v| v.abs() < 1e-15), "{:?}", &re[..nm * D]);
    }
}
