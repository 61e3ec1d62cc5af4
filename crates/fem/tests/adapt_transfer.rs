//! Transfer of a P2+ velocity between two adapted meshes reproduces any quadratic vector field
//! to round-off (the P2+ interpolant of a quadratic is exact, and so is its evaluation anywhere).

use fdfsi_fem::adapt::{adapt, transfer_p2plus, Surface};
use fdfsi_fem::dofs::NodeMap;
use fdfsi_fem::element::ReferenceElement;
use fdfsi_fem::generate::{box_tetrahedra, rectangle_triangles, DiagonalPattern};
use fdfsi_fem::mesh::{Mesh, Topology};

fn field2(x: &[f64; 2]) -> [f64; 2] {
    [1.0 + 2.0 * x[0] - x[1] + 3.0 * x[0] * x[1] - 0.5 * x[1] * x[1], -0.3 + x[0] * x[0] + 0.7 * x[1] - 2.0 * x[0] * x[1]]
}

fn field3(x: &[f64; 3]) -> [f64; 3] {
    [
        1.0 + x[0] - 2.0 * x[2] + x[0] * x[1] - x[2] * x[2],
        0.5 * x[1] + 2.0 * x[0] * x[2] - x[1] * x[1],
        -1.0 + x[0] * x[0] + x[1] * x[2] + 0.25 * x[2],
    ]
}

/// Interpolates `f` on the P2+ nodes of `old`, transfers to the P2+ nodes of `new`, and returns
/// the largest error and the number of points.
fn max_transfer_error<const D: usize>(
    old: &Mesh<D>,
    new: &Mesh<D>,
    element: &ReferenceElement<D>,
    f: impl Fn(&[f64; D]) -> [f64; D],
) -> (f64, usize) {
    let old_map = NodeMap::continuous(old, &Topology::build(old), element);
    let values: Vec<f64> = old_map.coordinates(old, element).iter().flat_map(&f).collect();
    let new_map = NodeMap::continuous(new, &Topology::build(new), element);
    let targets = new_map.coordinates(new, element);
    let got = transfer_p2plus(old, &old_map, &values, &targets).unwrap();
    let mut err: f64 = 0.0;
    for (i, x) in targets.iter().enumerate() {
        let want = f(x);
        for d in 0..D {
            err = err.max((got[i * D + d] - want[d]).abs());
        }
    }
    (err, targets.len())
}

#[test]
fn adapt_quadratic_field_reproduced_2d() {
    let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 9, 7, DiagonalPattern::Alternating);
    let e = ReferenceElement::p2plus_triangle();
    for step in 0..20 {
        let t = step as f64 * 0.05;
        let s_old = Surface::from_polyline(vec![[0.2 + t * 0.3, -0.5], [0.3 + t * 0.2, 0.5], [0.25, 1.5]]).unwrap();
        let s_new = Surface::from_polyline(vec![[0.23 + t * 0.3, -0.5], [0.35 + t * 0.2, 0.5], [0.2, 1.5]]).unwrap();
        let old = adapt(&mesh, &s_old, 0.2).unwrap().mesh;
        let new = adapt(&mesh, &s_new, 0.2).unwrap().mesh;
        let (err, n) = max_transfer_error(&old, &new, &e, field2);
        assert!(err < 1e-12, "step {step}: error {err:.3e} over {n} nodes");
    }
}

#[test]
fn adapt_quadratic_field_reproduced_3d() {
    let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 4, 4, 4);
    let e = ReferenceElement::p2plus_tetrahedron();
    let plane = |z0: f64, tilt: f64| {
        let z = |x: f64, y: f64| z0 + tilt * (x - 0.5) + 0.5 * tilt * (y - 0.5);
        Surface::from_pieces(
            vec![[-1.0, -1.0, z(-1.0, -1.0)], [2.0, -1.0, z(2.0, -1.0)], [2.0, 2.0, z(2.0, 2.0)], [-1.0, 2.0, z(-1.0, 2.0)]],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap()
    };
    for step in 0..6 {
        let t = step as f64 * 0.07;
        let old = adapt(&mesh, &plane(0.41 + t, 0.2), 0.2).unwrap().mesh;
        let new = adapt(&mesh, &plane(0.43 + t, 0.25), 0.2).unwrap().mesh;
        let (err, n) = max_transfer_error(&old, &new, &e, field3);
        assert!(err < 1e-12, "step {step}: error {err:.3e} over {n} nodes");
    }
}

#[test]
fn adapt_bad_inputs_are_errors() {
    let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 2, 2, DiagonalPattern::Right);
    let e = ReferenceElement::p2plus_triangle();
    let map = NodeMap::continuous(&mesh, &Topology::build(&mesh), &e);
    let values = vec![0.0; map.num_nodes * 2];
    assert!(transfer_p2plus(&mesh, &map, &values[1..], &[[0.5, 0.5]]).is_err());
    assert!(transfer_p2plus(&mesh, &map, &values, &[[1.5, 0.5]]).is_err());
    // Slightly outside by round-off: accepted.
    assert!(transfer_p2plus(&mesh, &map, &values, &[[1.0 + 1e-14, 0.5]]).is_ok());
}

/// `transfer_p2plus_or`: inside the old mesh the field, up to `extend` cell heights outside it
/// the nearest cell's polynomial, farther out the caller's value for that point (by index).
#[test]
fn transfer_extends_then_asks_for_points_outside() {
    use fdfsi_fem::adapt::transfer_p2plus_or;
    let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 2, 2, DiagonalPattern::Right);
    let e = ReferenceElement::p2plus_triangle();
    let map = NodeMap::continuous(&mesh, &Topology::build(&mesh), &e);
    // u = (1 + x, 2 y): linear, so the extension is exact.
    let mut values = vec![0.0; map.num_nodes * 2];
    let nodes = map.coordinates(&mesh, &e);
    for (n, p) in nodes.iter().enumerate() {
        values[2 * n] = 1.0 + p[0];
        values[2 * n + 1] = 2.0 * p[1];
    }
    let points = [[0.3, 0.6], [1.2, 0.5], [3.0, 0.5]];
    let mut asked = Vec::new();
    let got = transfer_p2plus_or(&mesh, &map, &values, &points, 0.5, |i, x| {
        asked.push((i, *x));
        Ok([-1.0, -2.0])
    })
    .unwrap();
    assert_eq!(asked, vec![(2, [3.0, 0.5])]);
    let want = [1.3, 1.2, 2.2, 1.0, -1.0, -2.0];
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() < 1e-12, "{got:?} against {want:?}");
    }
    // The caller's error is the transfer's.
    let refused = transfer_p2plus_or(&mesh, &map, &values, &points, 0.5, |_, _| Err(fdfsi_fem::adapt::AdaptError::Transfer("no".into())));
    assert!(refused.is_err());
}

/// `transfer_p1disc`: a pressure linear in each old cell (value at the centroid and gradient)
/// moves to another adapted mesh exactly where it is one linear function; a new cell whose
/// centroid lies outside the old mesh by more than `extend` takes zero; a wrong length is an
/// error.
#[test]
fn p1disc_pressure_moves_to_the_new_cells() {
    use fdfsi_fem::adapt::transfer_p1disc;
    let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 9, 7, DiagonalPattern::Alternating);
    let old = adapt(&mesh, &Surface::from_polyline(vec![[0.21, -0.5], [0.33, 0.5], [0.25, 1.5]]).unwrap(), 0.2).unwrap().mesh;
    let new = adapt(&mesh, &Surface::from_polyline(vec![[0.26, -0.5], [0.31, 0.5], [0.22, 1.5]]).unwrap(), 0.2).unwrap().mesh;
    let p = |x: &[f64; 2]| 3.0 - 2.0 * x[0] + 0.5 * x[1];
    let values: Vec<f64> = (0..old.num_cells()).flat_map(|c| [p(&old.vertex_centroid(c)), -2.0, 0.5]).collect();
    let got = transfer_p1disc(&old, &values, &new, 0.0).unwrap();
    for c in 0..new.num_cells() {
        let want = [p(&new.vertex_centroid(c)), -2.0, 0.5];
        for (g, w) in got[3 * c..3 * c + 3].iter().zip(want) {
            assert!((g - w).abs() < 1e-12, "cell {c}: {g} against {w}");
        }
    }
    // On a mesh reaching past the old one, the cells outside take zero.
    let wider = rectangle_triangles(0.0, 2.0, 0.0, 1.0, 2, 1, DiagonalPattern::Right);
    let got = transfer_p1disc(&old, &values, &wider, 0.0).unwrap();
    for c in 0..wider.num_cells() {
        let x = wider.vertex_centroid(c);
        let want = if x[0] < 1.0 { [p(&x), -2.0, 0.5] } else { [0.0; 3] };
        for (g, w) in got[3 * c..3 * c + 3].iter().zip(want) {
            assert!((g - w).abs() < 1e-12, "cell {c} at {x:?}: {g} against {w}");
        }
    }
    assert!(transfer_p1disc(&old, &values[1..], &new, 0.0).is_err());
}
