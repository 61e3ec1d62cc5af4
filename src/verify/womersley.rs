//! Womersley flow: fully developed pulsatile flow in a pipe of radius `R` driven by the axial
//! pressure gradient `-dp/dz = Re{A e^{i w t}}` (EXACT-SOLUTIONS.md section 2.3):
//!
//! ```text
//! u_z(r, t) = Re{ A / (i rho w) [1 - J0(L r / R) / J0(L)] e^{i w t} },
//! L = i^{3/2} alpha,  alpha = R sqrt(w / nu).
//! ```
//!
//! `J0` of a complex argument by its power series `sum_k (-z^2/4)^k / (k!)^2`, accurate to
//! round-off for `|z| <= 15` (the largest term is below `e^15`, so at most ~7 digits are lost
//! there; alpha <= 10 keeps it below 1e-12 relative).

use num_complex::Complex64;

/// `J0(z)` for complex `z` by its power series.
pub fn bessel_j0(z: Complex64) -> Complex64 {
    let q = -z * z / 4.0;
    let mut term = Complex64::new(1.0, 0.0);
    let mut sum = term;
    for k in 1..200 {
        term = term * q / ((k * k) as f64);
        sum += term;
        if term.norm() < 1e-17 * sum.norm() {
            break;
        }
    }
    sum
}

/// The Womersley solution for the gradient amplitude `a`, density `rho`, kinematic viscosity
/// `nu`, angular frequency `omega`, radius `radius`.
#[derive(Clone, Copy, Debug)]
pub struct Womersley {
    pub a: f64,
    pub rho: f64,
    pub nu: f64,
    pub omega: f64,
    pub radius: f64,
}

impl Womersley {
    /// Womersley number `alpha = R sqrt(omega / nu)`.
    pub fn alpha(&self) -> f64 {
        self.radius * (self.omega / self.nu).sqrt()
    }
    /// Complex amplitude of `u_z` at radius `r`.
    pub fn amplitude(&self, r: f64) -> Complex64 {
        let i = Complex64::i();
        let lambda = Complex64::from_polar(1.0, 0.75 * std::f64::consts::PI) * self.alpha();
        self.a / (i * self.rho * self.omega) * (1.0 - bessel_j0(lambda * r / self.radius) / bessel_j0(lambda))
    }
    /// Axial velocity at radius `r` and time `t`.
    pub fn velocity(&self, r: f64, t: f64) -> f64 {
        (self.amplitude(r) * Complex64::from_polar(1.0, self.omega * t)).re
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_tabulated_amplitude_ratios() {
        // |u_z(0)| / u0 with u0 = A R^2 / (4 rho nu): 0.98493 (alpha 1), 0.18567 (5), 0.03975 (10).
        for (alpha, ratio) in [(1.0, 0.98493), (5.0, 0.18567), (10.0, 0.03975)] {
            let w = Womersley { a: 1.0, rho: 1.0, nu: 1.0, omega: alpha * alpha, radius: 1.0 };
            let got = w.amplitude(0.0).norm() / 0.25;
            assert!((got - ratio).abs() < 1e-5, "alpha {alpha}: {got} vs {ratio}");
        }
    }

    #[test]
    fn j0_series_matches_known_values() {
        // J0(1) = 0.7651976865579666, J0(2.404825557695773) = 0 (first root).
        assert!((bessel_j0(Complex64::new(1.0, 0.0)).re - 0.7651976865579666).abs() < 1e-15);
        assert!(bessel_j0(Complex64::new(2.404825557695773, 0.0)).norm() < 1e-14);
        // No-slip at the wall.
        let w = Womersley { a: 1.0, rho: 1.0, nu: 1.0, omega: 25.0, radius: 1.0 };
        assert!(w.amplitude(1.0).norm() < 1e-14);
    }
}
