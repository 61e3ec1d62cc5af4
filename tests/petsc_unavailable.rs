//! Without the `petsc` feature, `method = "petsc"` is refused by the case check with the way to
//! get it, and a solver asked for anyway fails the same way (no panic, no silent fallback).
#![cfg(not(feature = "petsc"))]

use fdfsi::case::{Case, LinearMethod, WITHOUT_PETSC};
use fdfsi::physics::fluid::Formulation;

#[test]
fn method_petsc_needs_the_feature() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let mut case = Case::read(&dir.join("schaefer-turek-2d1.toml")).unwrap();
    case.solver.linear.method = LinearMethod::Petsc;
    let e = case.validate("st.toml").unwrap_err().to_string();
    assert!(e.contains("method = \"petsc\"") && e.contains("--features petsc"), "{e}");
    let mut solver = case.solver.linear_solver(false, Formulation::Plane);
    let pattern = fdfsi_fem::sparse::Pattern { n: 1, col_ptr: vec![0, 1], row_idx: vec![0] };
    let a = fdfsi_fem::sparse::CscMatrix { pattern: &pattern, values: vec![1.0] };
    assert!(solver.factorize(&a).unwrap_err().to_string().contains(WITHOUT_PETSC));
}
