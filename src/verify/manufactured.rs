//! Manufactured solutions of the Stokes equations `-div sigma = f`, `div u = 0`,
//! `sigma = -p I + eta (grad u + grad u^T)`.
//!
//! Each solution gives the velocity, its gradient `g[a][b] = du_a/dx_b`, the pressure, and the
//! body force derived by hand; a unit test checks every body force against a finite-difference
//! divergence of the stress, so a slip in the algebra cannot hide.

use std::f64::consts::PI;

/// A smooth exact solution of the Stokes equations in `D` dimensions.
pub trait Manufactured<const D: usize>: Send + Sync {
    /// Viscosity the body force was derived for.
    fn viscosity(&self) -> f64;
    fn velocity(&self, x: &[f64; D]) -> [f64; D];
    fn gradient(&self, x: &[f64; D]) -> [[f64; D]; D];
    fn pressure(&self, x: &[f64; D]) -> f64;
    fn body_force(&self, x: &[f64; D]) -> [f64; D];
    /// Traction `sigma n` on a boundary with outward normal `n` (the meridian-plane stress in the
    /// axisymmetric case: the hoop stress has no traction on a meridian boundary).
    fn traction(&self, x: &[f64; D], n: &[f64; D]) -> [f64; D] {
        let g = self.gradient(x);
        let p = self.pressure(x);
        let eta = self.viscosity();
        std::array::from_fn(|a| (0..D).map(|b| (eta * (g[a][b] + g[b][a]) - if a == b { p } else { 0.0 }) * n[b]).sum())
    }
}

/// 2D plane: `u = (sin(pi x) cos(pi y), -cos(pi x) sin(pi y))`, `p = cos(pi x) cos(pi y)`.
/// `div u = 0`, `lap u = -2 pi^2 u`, so `f = 2 pi^2 eta u + grad p`.
pub struct PlaneStokes {
    pub eta: f64,
}

impl Manufactured<2> for PlaneStokes {
    fn viscosity(&self) -> f64 {
        self.eta
    }
    fn velocity(&self, x: &[f64; 2]) -> [f64; 2] {
        let (sx, cx, sy, cy) = ((PI * x[0]).sin(), (PI * x[0]).cos(), (PI * x[1]).sin(), (PI * x[1]).cos());
        [sx * cy, -cx * sy]
    }
    fn gradient(&self, x: &[f64; 2]) -> [[f64; 2]; 2] {
        let (sx, cx, sy, cy) = ((PI * x[0]).sin(), (PI * x[0]).cos(), (PI * x[1]).sin(), (PI * x[1]).cos());
        [[PI * cx * cy, -PI * sx * sy], [PI * sx * sy, -PI * cx * cy]]
    }
    fn pressure(&self, x: &[f64; 2]) -> f64 {
        (PI * x[0]).cos() * (PI * x[1]).cos()
    }
    fn body_force(&self, x: &[f64; 2]) -> [f64; 2] {
        let u = self.velocity(x);
        let (sx, cx, sy, cy) = ((PI * x[0]).sin(), (PI * x[0]).cos(), (PI * x[1]).sin(), (PI * x[1]).cos());
        let k = 2.0 * PI * PI * self.eta;
        [k * u[0] - PI * sx * cy, k * u[1] - PI * cx * sy]
    }
}

/// Axisymmetric, `x = (z, r)`: from the stream function `psi = r^2 (1 - r^2/2) sin(pi z)`,
/// `u_z = psi_r / r = 2 (1 - r^2) sin(pi z)`, `u_r = -psi_z / r = -pi (r - r^3/2) cos(pi z)`,
/// `p = r^2 cos(pi z)`. Smooth at the axis (`u_z` even, `u_r` odd in `r`), `div u = 0`, and
/// `f = -eta (vector Laplacian) u + grad p` with
/// `(lap u)_z = -(8 + 2 pi^2 (1 - r^2)) sin(pi z)`,
/// `(lap u)_r = (4 pi r + pi^3 (r - r^3/2)) cos(pi z)`.
pub struct AxisymmetricStokes {
    pub eta: f64,
}

impl Manufactured<2> for AxisymmetricStokes {
    fn viscosity(&self) -> f64 {
        self.eta
    }
    fn velocity(&self, x: &[f64; 2]) -> [f64; 2] {
        let (z, r) = (x[0], x[1]);
        [2.0 * (1.0 - r * r) * (PI * z).sin(), -PI * (r - r * r * r / 2.0) * (PI * z).cos()]
    }
    fn gradient(&self, x: &[f64; 2]) -> [[f64; 2]; 2] {
        let (z, r) = (x[0], x[1]);
        let (s, c) = ((PI * z).sin(), (PI * z).cos());
        [[2.0 * PI * (1.0 - r * r) * c, -4.0 * r * s], [PI * PI * (r - r * r * r / 2.0) * s, -PI * (1.0 - 1.5 * r * r) * c]]
    }
    fn pressure(&self, x: &[f64; 2]) -> f64 {
        x[1] * x[1] * (PI * x[0]).cos()
    }
    fn body_force(&self, x: &[f64; 2]) -> [f64; 2] {
        let (z, r) = (x[0], x[1]);
        let (s, c) = ((PI * z).sin(), (PI * z).cos());
        let eta = self.eta;
        [
            eta * (8.0 + 2.0 * PI * PI * (1.0 - r * r)) * s - PI * r * r * s,
            -eta * (4.0 * PI * r + PI.powi(3) * (r - r * r * r / 2.0)) * c + 2.0 * r * c,
        ]
    }
}

/// 3D: `u = (sin(pi y) sin(pi z), sin(pi x) sin(pi z), sin(pi x) sin(pi y))` (each component
/// independent of its own coordinate, so `div u = 0`), `p = cos(pi x) cos(pi y) cos(pi z)`,
/// `lap u = -2 pi^2 u`, `f = 2 pi^2 eta u + grad p`.
pub struct Stokes3d {
    pub eta: f64,
}

impl Manufactured<3> for Stokes3d {
    fn viscosity(&self) -> f64 {
        self.eta
    }
    fn velocity(&self, x: &[f64; 3]) -> [f64; 3] {
        let s: [f64; 3] = std::array::from_fn(|d| (PI * x[d]).sin());
        [s[1] * s[2], s[0] * s[2], s[0] * s[1]]
    }
    fn gradient(&self, x: &[f64; 3]) -> [[f64; 3]; 3] {
        let s: [f64; 3] = std::array::from_fn(|d| (PI * x[d]).sin());
        let c: [f64; 3] = std::array::from_fn(|d| (PI * x[d]).cos());
        [[0.0, PI * c[1] * s[2], PI * s[1] * c[2]], [PI * c[0] * s[2], 0.0, PI * s[0] * c[2]], [PI * c[0] * s[1], PI * s[0] * c[1], 0.0]]
    }
    fn pressure(&self, x: &[f64; 3]) -> f64 {
        (0..3).map(|d| (PI * x[d]).cos()).product()
    }
    fn body_force(&self, x: &[f64; 3]) -> [f64; 3] {
        let u = self.velocity(x);
        let s: [f64; 3] = std::array::from_fn(|d| (PI * x[d]).sin());
        let c: [f64; 3] = std::array::from_fn(|d| (PI * x[d]).cos());
        let k = 2.0 * PI * PI * self.eta;
        [k * u[0] - PI * s[0] * c[1] * c[2], k * u[1] - PI * c[0] * s[1] * c[2], k * u[2] - PI * c[0] * c[1] * s[2]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Full stress tensor (`D x D`) from the manufactured fields.
    fn stress<const D: usize>(m: &dyn Manufactured<D>, x: &[f64; D]) -> [[f64; D]; D] {
        let g = m.gradient(x);
        let p = m.pressure(x);
        std::array::from_fn(|a| std::array::from_fn(|b| m.viscosity() * (g[a][b] + g[b][a]) - if a == b { p } else { 0.0 }))
    }

    fn fd_check_gradient<const D: usize>(m: &dyn Manufactured<D>, x: &[f64; D]) {
        let h = 1e-6;
        let g = m.gradient(x);
        for b in 0..D {
            let (mut xp, mut xm) = (*x, *x);
            xp[b] += h;
            xm[b] -= h;
            let (up, um) = (m.velocity(&xp), m.velocity(&xm));
            for a in 0..D {
                let fd = (up[a] - um[a]) / (2.0 * h);
                assert!((fd - g[a][b]).abs() < 1e-7, "grad[{a}][{b}]: {} vs {fd}", g[a][b]);
            }
        }
    }

    const POINTS: [[f64; 3]; 4] = [[0.3, 0.7, 0.2], [0.81, 0.13, 0.55], [0.5, 0.5, 0.5], [0.05, 0.9, 0.33]];

    #[test]
    fn cartesian_body_forces_equal_minus_div_sigma() {
        let h = 1e-5;
        let plane = PlaneStokes { eta: 0.7 };
        for p in POINTS {
            let x = [p[0], p[1]];
            fd_check_gradient(&plane, &x);
            let f = plane.body_force(&x);
            for a in 0..2 {
                let mut div = 0.0;
                for b in 0..2 {
                    let (mut xp, mut xm) = (x, x);
                    xp[b] += h;
                    xm[b] -= h;
                    div += (stress(&plane, &xp)[a][b] - stress(&plane, &xm)[a][b]) / (2.0 * h);
                }
                assert!((f[a] + div).abs() < 1e-6, "plane f[{a}]");
            }
            let g = plane.gradient(&x);
            assert!((g[0][0] + g[1][1]).abs() < 1e-14);
        }
        let s3 = Stokes3d { eta: 1.3 };
        for x in POINTS {
            fd_check_gradient(&s3, &x);
            let f = s3.body_force(&x);
            for a in 0..3 {
                let mut div = 0.0;
                for b in 0..3 {
                    let (mut xp, mut xm) = (x, x);
                    xp[b] += h;
                    xm[b] -= h;
                    div += (stress(&s3, &xp)[a][b] - stress(&s3, &xm)[a][b]) / (2.0 * h);
                }
                assert!((f[a] + div).abs() < 1e-6, "3d f[{a}]");
            }
        }
    }

    #[test]
    fn axisymmetric_body_force_equals_minus_div_sigma_in_cylindrical_coordinates() {
        // f_z = -(d sigma_zz/dz + (1/r) d(r sigma_rz)/dr)
        // f_r = -(d sigma_rz/dz + (1/r) d(r sigma_rr)/dr - sigma_tt / r), sigma_tt = -p + 2 eta u_r / r
        let m = AxisymmetricStokes { eta: 0.9 };
        let h = 1e-5;
        for p in POINTS {
            let x = [p[0], 0.1 + 0.8 * p[1]];
            fd_check_gradient(&m, &x);
            let (z, r) = (x[0], x[1]);
            let s = |z: f64, r: f64| stress(&m, &[z, r]);
            let d_dz = |a: usize, b: usize| (s(z + h, r)[a][b] - s(z - h, r)[a][b]) / (2.0 * h);
            let d_r_r = |a: usize, b: usize| ((r + h) * s(z, r + h)[a][b] - (r - h) * s(z, r - h)[a][b]) / (2.0 * h) / r;
            let u = m.velocity(&x);
            let s_tt = -m.pressure(&x) + 2.0 * m.eta * u[1] / r;
            let fz = -(d_dz(0, 0) + d_r_r(0, 1));
            let fr = -(d_dz(1, 0) + d_r_r(1, 1) - s_tt / r);
            let f = m.body_force(&x);
            assert!((f[0] - fz).abs() < 1e-6, "f_z {} vs {fz}", f[0]);
            assert!((f[1] - fr).abs() < 1e-6, "f_r {} vs {fr}", f[1]);
            let g = m.gradient(&x);
            assert!((g[0][0] + g[1][1] + u[1] / r).abs() < 1e-13, "div u");
        }
    }
}
