//! Convergence of P2+/P1disc Stokes on manufactured solutions (the same code `fdfsi verify`
//! runs): velocity L2 rate >= 2.8, H1 >= 1.8, pressure L2 >= 1.8, and the discrete divergence
//! zero on every cell (to 8e-14). Independent references: the manufactured solutions and the
//! element's orders.

use fdfsi::verify::{self, Effort, StokesRun};

fn check(run: &StokesRun) {
    for s in &run.studies {
        let min = match s.quantity.as_str() {
            "velocity_l2" => 2.8,
            _ => 1.8,
        };
        println!("{} {}: errors {:?} rate {:.3}", s.name, s.quantity, s.errors, s.observed_rate);
        assert!(s.observed_rate >= min, "{} {}: rate {:.3} < {min}", s.name, s.quantity, s.observed_rate);
    }
    // README: the largest |int_K div u_h| is 8.6e-15 (plane), 1.7e-14 (axisymmetric), 3.1e-14
    // (3D) on the `fdfsi verify --full` meshes; round-off, held here at 8e-14.
    println!("{}: max |int_K div u_h| = {:.3e}", run.studies[0].name, run.max_cell_divergence);
    assert!(run.max_cell_divergence < 8e-14, "cell divergence {:.3e}", run.max_cell_divergence);
}

#[test]
fn stokes_plane_converges_at_optimal_rates() {
    check(&verify::stokes_plane(Effort::Quick).unwrap());
}

#[test]
fn stokes_axisymmetric_converges_at_optimal_rates() {
    check(&verify::stokes_axisymmetric(Effort::Quick).unwrap());
}

#[test]
fn stokes_3d_converges_at_optimal_rates() {
    check(&verify::stokes_3d(Effort::Quick).unwrap());
}

#[test]
fn kovasznay_navier_stokes_converges_at_optimal_rates() {
    let studies = verify::kovasznay(Effort::Quick).unwrap();
    for s in &studies {
        let min = if s.quantity == "velocity_l2" { 2.8 } else { 1.8 };
        println!("{} {}: errors {:?} rate {:.3}", s.name, s.quantity, s.errors, s.observed_rate);
        assert!(s.observed_rate >= min, "{} {}: rate {:.3}", s.name, s.quantity, s.observed_rate);
    }
}
