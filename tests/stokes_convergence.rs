//! Convergence of P2+/P1disc Stokes on manufactured solutions (the same code `fdfsi verify`
//! runs): velocity L2 rate >= 2.8, H1 >= 1.8, pressure L2 >= 1.8, and the discrete divergence
//! zero on every cell (to 10 times the round-off README prints). Independent references: the manufactured solutions and the
//! element's orders.

use fdfsi::physics::fluid::Stabilization;
use fdfsi::verify::{self, Effort, StokesRun};

/// Checks the rates and that the largest |int_K div u_h| is within 10 times `divergence` (the value
/// README.md prints for the first three meshes).
fn check(run: &StokesRun, divergence: f64) {
    for s in &run.studies {
        let min = match s.quantity.as_str() {
            "velocity_l2" => 2.8,
            _ => 1.8,
        };
        println!("{} {}: errors {:?} rate {:.3}", s.name, s.quantity, s.errors, s.observed_rate);
        assert!(s.observed_rate >= min, "{} {}: rate {:.3} < {min}", s.name, s.quantity, s.observed_rate);
    }
    // Round-off: README prints 8.6e-15 (plane), 5.3e-15 (axisymmetric), 7.2e-15 (3D).
    println!("{}: max |int_K div u_h| = {:.3e}", run.studies[0].name, run.max_cell_divergence);
    assert!(run.max_cell_divergence < 10.0 * divergence, "cell divergence {:.3e}", run.max_cell_divergence);
}

#[test]
fn stokes_plane_converges_at_optimal_rates() {
    check(&verify::stokes_plane(Effort::Quick).unwrap(), 8.6e-15);
}

#[test]
fn stokes_axisymmetric_converges_at_optimal_rates() {
    check(&verify::stokes_axisymmetric(Effort::Quick).unwrap(), 5.3e-15);
}

#[test]
fn stokes_3d_converges_at_optimal_rates() {
    check(&verify::stokes_3d(Effort::Quick).unwrap(), 7.2e-15);
}

#[test]
fn kovasznay_navier_stokes_converges_at_optimal_rates() {
    let galerkin = verify::kovasznay(Effort::Quick, Stabilization::None).unwrap();
    // SUPG is consistent: the same rates, and on the finest mesh errors within 5 % of Galerkin's
    // (measured: 0.98-1.02).
    let supg = verify::kovasznay(Effort::Quick, Stabilization::Supg).unwrap();
    for (s, g) in supg.iter().zip(&galerkin) {
        let ratio = s.errors.last().unwrap() / g.errors.last().unwrap();
        println!("{} {}: errors {:?} rate {:.3}, finest against Galerkin's {ratio:.3}", s.name, s.quantity, s.errors, s.observed_rate);
        assert!((ratio - 1.0).abs() < 0.05, "{} {}: {ratio}", s.name, s.quantity);
    }
    for s in galerkin.iter().chain(&supg) {
        let min = if s.quantity == "velocity_l2" { 2.8 } else { 1.8 };
        println!("{} {}: errors {:?} rate {:.3}", s.name, s.quantity, s.errors, s.observed_rate);
        assert!(s.observed_rate >= min, "{} {}: rate {:.3}", s.name, s.quantity, s.observed_rate);
    }
}
