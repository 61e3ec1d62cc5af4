//! Temporal convergence on a manufactured Navier-Stokes solution with no spatial error:
//! implicit Euler rate >= 0.9, BDF2 rate >= 1.8.

use fdfsi::time::TimeScheme;
use fdfsi::verify::time_convergence;

#[test]
fn implicit_euler_is_first_order() {
    let s = time_convergence(TimeScheme::Euler).unwrap();
    println!("{:?} rate {}", s.errors, s.observed_rate);
    assert!(s.observed_rate >= 0.9, "{s:?}");
}

#[test]
fn bdf2_is_second_order() {
    let s = time_convergence(TimeScheme::Bdf2).unwrap();
    println!("{:?} rate {}", s.errors, s.observed_rate);
    assert!(s.observed_rate >= 1.8, "{s:?}");
}
