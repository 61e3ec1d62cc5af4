//! Quadrature rules on the reference cells.
//!
//! Reference cells (the same as in [`crate::element`]):
//! - segment `[0, 1]`,
//! - triangle with vertices `(0,0), (1,0), (0,1)` (area 1/2),
//! - tetrahedron with vertices `(0,0,0), (1,0,0), (0,1,0), (0,0,1)` (volume 1/6),
//! - quadrilateral `[0,1]^2` and hexahedron `[0,1]^3`.
//!
//! A rule of degree `p` integrates every polynomial of total degree `<= p` (simplices) or of
//! degree `<= p` in each variable (tensor cells) exactly. Simplex rules of arbitrary degree are
//! built by the collapsed-coordinate (Duffy) map `x = u, y = (1-u) v [, z = (1-u)(1-v) w]` from
//! Gauss-Legendre rules, with enough points in each direction to absorb the Jacobian factors
//! `(1-u)` and `(1-u)^2 (1-v)`; the common rules have symmetric formulas with fewer points:
//! Dunavant's 7 points for degree 5 on the triangle, Keast's 24 points for degrees 5 and 6 on the
//! tetrahedron (instead of 48 and 80 collapsed points: the P2+ fluid cells integrate at degree 6,
//! and their assembly cost is proportional to the points). Exactness is tested on monomials in
//! this module's tests.

use crate::element::ReferenceCell;

/// Points and weights on a reference cell of dimension `D`.
#[derive(Clone, Debug)]
pub struct QuadratureRule<const D: usize> {
    /// The cell the points lie in.
    pub cell: ReferenceCell,
    /// Polynomial degree integrated exactly.
    pub degree: usize,
    /// Reference coordinates `xi` of the points.
    pub points: Vec<[f64; D]>,
    /// Weights; they sum to the reference cell's measure.
    pub weights: Vec<f64>,
}

impl<const D: usize> QuadratureRule<D> {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.weights.len()
    }
    /// True for a rule without points.
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }
}

/// Gauss-Legendre points and weights with `n` points on `[0, 1]`, exact to degree `2n - 1`.
///
/// Newton iteration on the Legendre polynomial `P_n` from Chebyshev starting guesses; converged to
/// machine precision for every `n` used here (`n <= 32`).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    assert!(n >= 1, "a Gauss-Legendre rule needs at least one point");
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    for i in 0..n.div_ceil(2) {
        // Root i of P_n on [-1, 1], from the largest downwards.
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (p, d) = legendre_and_derivative(n, z);
            dp = d;
            let dz = p / d;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        let (_, d) = legendre_and_derivative(n, z);
        dp = if d != 0.0 { d } else { dp };
        let weight = 2.0 / ((1.0 - z * z) * dp * dp);
        // Map [-1, 1] -> [0, 1].
        x[i] = 0.5 * (1.0 - z);
        x[n - 1 - i] = 0.5 * (1.0 + z);
        w[i] = 0.5 * weight;
        w[n - 1 - i] = 0.5 * weight;
    }
    (x, w)
}

/// `(P_n(z), P_n'(z))` by the three-term recurrence.
fn legendre_and_derivative(n: usize, z: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, z);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let k = k as f64;
        let p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
    }
    let nf = n as f64;
    let dp = nf * (z * p1 - p0) / (z * z - 1.0);
    (p1, dp)
}

/// Number of Gauss-Legendre points that integrate degree `p` exactly.
fn points_for_degree(p: usize) -> usize {
    (p + 2) / 2
}

/// Rule on the segment `[0, 1]` exact to degree `degree`.
pub fn segment(degree: usize) -> QuadratureRule<1> {
    let (x, w) = gauss_legendre(points_for_degree(degree));
    QuadratureRule { cell: ReferenceCell::Segment, degree, points: x.into_iter().map(|x| [x]).collect(), weights: w }
}

/// Rule on the reference triangle exact to total degree `degree`.
pub fn triangle(degree: usize) -> QuadratureRule<2> {
    if degree <= 1 {
        return QuadratureRule { cell: ReferenceCell::Triangle, degree, points: vec![[1.0 / 3.0, 1.0 / 3.0]], weights: vec![0.5] };
    }
    if degree <= 5 {
        return dunavant7();
    }
    // Collapsed rule: integrand in u has degree p + 1 (Jacobian 1 - u), in v degree p.
    let (xu, wu) = gauss_legendre(points_for_degree(degree + 1));
    let (xv, wv) = gauss_legendre(points_for_degree(degree));
    let mut points = Vec::new();
    let mut weights = Vec::new();
    for (&u, &a) in xu.iter().zip(&wu) {
        for (&v, &b) in xv.iter().zip(&wv) {
            points.push([u, (1.0 - u) * v]);
            weights.push(a * b * (1.0 - u));
        }
    }
    QuadratureRule { cell: ReferenceCell::Triangle, degree, points, weights }
}

/// Dunavant's symmetric 7-point rule of degree 5 on the reference triangle.
fn dunavant7() -> QuadratureRule<2> {
    let s15 = 15f64.sqrt();
    let a1 = (6.0 - s15) / 21.0;
    let a2 = (6.0 + s15) / 21.0;
    let w1 = (155.0 - s15) / 2400.0;
    let w2 = (155.0 + s15) / 2400.0;
    let points =
        vec![[1.0 / 3.0, 1.0 / 3.0], [a1, a1], [1.0 - 2.0 * a1, a1], [a1, 1.0 - 2.0 * a1], [a2, a2], [1.0 - 2.0 * a2, a2], [a2, 1.0 - 2.0 * a2]];
    let weights = vec![9.0 / 80.0, w1, w1, w1, w2, w2, w2];
    QuadratureRule { cell: ReferenceCell::Triangle, degree: 5, points, weights }
}

/// Keast's fully symmetric 24-point rule of degree 6 on the reference tetrahedron, all weights
/// positive (P. Keast, CMAME 55, 1986, rule 7; the 16-digit values of its published table, exact
/// on the monomials of degree 6 to 1.1e-16). Orbits in barycentric coordinates: three of 4 points
/// `(a, a, a, 1 - 3a)` and one of 12 points `(a, a, b, 1 - 2a - b)`; weights relative to the
/// volume.
fn keast24() -> QuadratureRule<3> {
    const ORBITS_31: [(f64, f64); 3] = [
        (0.039_922_750_258_167_9, 0.214_602_871_259_151_7),
        (0.010_077_211_055_320_7, 0.040_673_958_534_611_3),
        (0.055_357_181_543_654_4, 0.322_337_890_142_275_7),
    ];
    const ORBIT_211: (f64, f64, f64) = (27.0 / 560.0, 0.063_661_001_875_017_5, 0.269_672_331_458_315_9);
    let (mut points, mut weights) = (Vec::with_capacity(24), Vec::with_capacity(24));
    // A barycentric point (l0, l1, l2, l3) is the reference point (l1, l2, l3).
    let mut push = |l: [f64; 4], w: f64| {
        points.push([l[1], l[2], l[3]]);
        weights.push(w / 6.0);
    };
    for (w, a) in ORBITS_31 {
        let d = 1.0 - 3.0 * a;
        for k in 0..4 {
            push(std::array::from_fn(|i| if i == k { d } else { a }), w);
        }
    }
    let (w, a, b) = ORBIT_211;
    let c = 1.0 - 2.0 * a - b;
    // The 12 distinct arrangements of (a, a, b, c): b at position i, c at position j != i.
    for i in 0..4 {
        for j in (0..4).filter(|&j| j != i) {
            push(
                std::array::from_fn(|k| {
                    if k == i {
                        b
                    } else if k == j {
                        c
                    } else {
                        a
                    }
                }),
                w,
            );
        }
    }
    QuadratureRule { cell: ReferenceCell::Tetrahedron, degree: 6, points, weights }
}

/// Rule on the reference tetrahedron exact to total degree `degree`: Keast's 24 points for
/// degrees 5 and 6, collapsed Gauss otherwise.
pub fn tetrahedron(degree: usize) -> QuadratureRule<3> {
    if degree <= 1 {
        return QuadratureRule { cell: ReferenceCell::Tetrahedron, degree, points: vec![[0.25, 0.25, 0.25]], weights: vec![1.0 / 6.0] };
    }
    if degree == 5 || degree == 6 {
        return QuadratureRule { degree, ..keast24() };
    }
    let (xu, wu) = gauss_legendre(points_for_degree(degree + 2));
    let (xv, wv) = gauss_legendre(points_for_degree(degree + 1));
    let (xw, ww) = gauss_legendre(points_for_degree(degree));
    let mut points = Vec::new();
    let mut weights = Vec::new();
    for (&u, &a) in xu.iter().zip(&wu) {
        for (&v, &b) in xv.iter().zip(&wv) {
            for (&w, &c) in xw.iter().zip(&ww) {
                points.push([u, (1.0 - u) * v, (1.0 - u) * (1.0 - v) * w]);
                weights.push(a * b * c * (1.0 - u) * (1.0 - u) * (1.0 - v));
            }
        }
    }
    QuadratureRule { cell: ReferenceCell::Tetrahedron, degree, points, weights }
}

/// Tensor Gauss rule on `[0,1]^2` exact to degree `degree` in each variable.
pub fn quadrilateral(degree: usize) -> QuadratureRule<2> {
    let (x, w) = gauss_legendre(points_for_degree(degree));
    let mut points = Vec::new();
    let mut weights = Vec::new();
    for (&a, &wa) in x.iter().zip(&w) {
        for (&b, &wb) in x.iter().zip(&w) {
            points.push([a, b]);
            weights.push(wa * wb);
        }
    }
    QuadratureRule { cell: ReferenceCell::Quadrilateral, degree, points, weights }
}

/// Tensor Gauss rule on `[0,1]^3` exact to degree `degree` in each variable.
pub fn hexahedron(degree: usize) -> QuadratureRule<3> {
    let (x, w) = gauss_legendre(points_for_degree(degree));
    let mut points = Vec::new();
    let mut weights = Vec::new();
    for (&a, &wa) in x.iter().zip(&w) {
        for (&b, &wb) in x.iter().zip(&w) {
            for (&c, &wc) in x.iter().zip(&w) {
                points.push([a, b, c]);
                weights.push(wa * wb * wc);
            }
        }
    }
    QuadratureRule { cell: ReferenceCell::Hexahedron, degree, points, weights }
}

/// The rule of degree `degree` on `cell`, whose dimension must be `D` (panics otherwise: a
/// programming error, not an input error).
pub fn for_cell<const D: usize>(cell: ReferenceCell, degree: usize) -> QuadratureRule<D> {
    assert_eq!(cell.dim(), D, "{cell:?} is not a {D}D cell");
    match cell {
        ReferenceCell::Segment => segment(degree).in_dim(),
        ReferenceCell::Triangle => triangle(degree).in_dim(),
        ReferenceCell::Quadrilateral => quadrilateral(degree).in_dim(),
        ReferenceCell::Tetrahedron => tetrahedron(degree).in_dim(),
        ReferenceCell::Hexahedron => hexahedron(degree).in_dim(),
    }
}

impl<const E: usize> QuadratureRule<E> {
    /// The rule with its points as `D`-vectors (`D = E`: the same rule, for code generic over `D`).
    fn in_dim<const D: usize>(self) -> QuadratureRule<D> {
        let points = self.points.iter().map(|p| std::array::from_fn(|d| p[d])).collect();
        QuadratureRule { cell: self.cell, degree: self.degree, points, weights: self.weights }
    }
}

/// A rule of degree `degree` on the facet cell of `cell` (segment, triangle or quadrilateral),
/// with the points padded to 2 components: the form [`crate::values::FacetValues`] and
/// [`crate::element::ReferenceCell::facet_point`] take.
pub fn for_facets(cell: ReferenceCell, degree: usize) -> (Vec<[f64; 2]>, Vec<f64>) {
    match cell.facet_cell() {
        ReferenceCell::Triangle => {
            let q = triangle(degree);
            (q.points, q.weights)
        }
        ReferenceCell::Quadrilateral => {
            let q = quadrilateral(degree);
            (q.points, q.weights)
        }
        _ => {
            let q = segment(degree);
            (q.points.iter().map(|p| [p[0], 0.0]).collect(), q.weights)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// n! as f64.
    fn fact(n: usize) -> f64 {
        (1..=n).map(|k| k as f64).product()
    }

    /// Exact integral of x^a y^b over the reference triangle: a! b! / (a + b + 2)!.
    fn tri_monomial(a: usize, b: usize) -> f64 {
        fact(a) * fact(b) / fact(a + b + 2)
    }

    /// Exact integral of x^a y^b z^c over the reference tetrahedron: a! b! c! / (a+b+c+3)!.
    fn tet_monomial(a: usize, b: usize, c: usize) -> f64 {
        fact(a) * fact(b) * fact(c) / fact(a + b + c + 3)
    }

    #[test]
    fn gauss_legendre_exact_on_monomials() {
        for n in 1..12 {
            let (x, w) = gauss_legendre(n);
            for p in 0..2 * n {
                let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(p as i32)).sum();
                assert!((q - 1.0 / (p as f64 + 1.0)).abs() < 1e-14, "n={n} p={p} q={q}");
            }
            // ... and not exact one degree higher: the rule is no stronger than claimed.
            if n > 6 {
                continue; // the degree-2n error drops below round-off-level tolerances
            }
            let p = 2 * n;
            let q: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(p as i32)).sum();
            assert!((q - 1.0 / (p as f64 + 1.0)).abs() > 1e-12, "n={n}");
        }
    }

    #[test]
    fn triangle_rules_exact_to_their_degree() {
        for degree in 0..=12 {
            let qr = triangle(degree);
            for a in 0..=degree {
                for b in 0..=degree - a {
                    let q: f64 = qr.points.iter().zip(&qr.weights).map(|(p, w)| w * p[0].powi(a as i32) * p[1].powi(b as i32)).sum();
                    let exact = tri_monomial(a, b);
                    assert!((q - exact).abs() < 1e-14, "deg {degree}: x^{a} y^{b}: {q} vs {exact}");
                }
            }
        }
    }

    #[test]
    fn tetrahedron_rules_exact_to_their_degree() {
        assert_eq!(tetrahedron(6).points.len(), 24, "Keast's rule for the P2+ cells");
        for degree in 0..=10 {
            let qr = tetrahedron(degree);
            for a in 0..=degree {
                for b in 0..=degree - a {
                    for c in 0..=degree - a - b {
                        let q: f64 =
                            qr.points.iter().zip(&qr.weights).map(|(p, w)| w * p[0].powi(a as i32) * p[1].powi(b as i32) * p[2].powi(c as i32)).sum();
                        let exact = tet_monomial(a, b, c);
                        assert!((q - exact).abs() < 1e-14, "deg {degree}: {a},{b},{c}");
                    }
                }
            }
        }
    }

    #[test]
    fn tensor_rules_exact_per_variable() {
        for degree in 0..=9 {
            let q2 = quadrilateral(degree);
            let q3 = hexahedron(degree);
            for a in 0..=degree {
                for b in 0..=degree {
                    let q: f64 = q2.points.iter().zip(&q2.weights).map(|(p, w)| w * p[0].powi(a as i32) * p[1].powi(b as i32)).sum();
                    let exact = 1.0 / ((a + 1) * (b + 1)) as f64;
                    assert!((q - exact).abs() < 1e-14);
                    let c = (a + b) % (degree + 1);
                    let q: f64 =
                        q3.points.iter().zip(&q3.weights).map(|(p, w)| w * p[0].powi(a as i32) * p[1].powi(b as i32) * p[2].powi(c as i32)).sum();
                    let exact = exact / (c + 1) as f64;
                    assert!((q - exact).abs() < 1e-14);
                }
            }
        }
    }

    #[test]
    fn weights_positive_and_points_inside() {
        for degree in 0..=10 {
            for (p, w) in triangle(degree).points.iter().zip(&triangle(degree).weights) {
                assert!(*w > 0.0 && p[0] >= 0.0 && p[1] >= 0.0 && p[0] + p[1] <= 1.0);
            }
            let t = tetrahedron(degree);
            for (p, w) in t.points.iter().zip(&t.weights) {
                assert!(*w > 0.0 && p.iter().all(|c| *c >= 0.0) && p.iter().sum::<f64>() <= 1.0);
            }
        }
    }
}
