//! Small geometric kernels of the adaptation: exact orientation signs, simplex measure and
//! quality, closest points on segments and triangles. All pure and allocation-free.

use robust::{Coord, Coord3D};

/// `b - a`.
#[inline]
pub(crate) fn sub<const D: usize>(a: &[f64; D], b: &[f64; D]) -> [f64; D] {
    std::array::from_fn(|d| a[d] - b[d])
}

/// Euclidean dot product.
#[inline]
pub(crate) fn dot<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    (0..D).map(|d| a[d] * b[d]).sum()
}

/// Squared distance.
#[inline]
pub(crate) fn dist2<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    let v = sub(a, b);
    dot(&v, &v)
}

/// `a + t (b - a)`.
#[inline]
pub(crate) fn lerp<const D: usize>(a: &[f64; D], b: &[f64; D], t: f64) -> [f64; D] {
    std::array::from_fn(|d| a[d] + t * (b[d] - a[d]))
}

/// Cross product of 3-vectors.
#[inline]
pub(crate) fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Pads a point to 3 components (for the exact predicates, which are written per dimension).
#[inline]
pub(crate) fn pad3<const D: usize>(a: &[f64; D]) -> [f64; 3] {
    std::array::from_fn(|d| if d < D { a[d] } else { 0.0 })
}

/// Exact sign-correct orientation of `D + 1` points, with the sign of the simplex's signed
/// measure: `orient2d(a, b, c) = det[b - a, c - a]` (> 0 counter-clockwise) and in 3D
/// `det[b - a, c - a, d - a]` (> 0 for a positively oriented tetrahedron). The magnitude is the
/// (adaptively refined) determinant, good for ratios such as the intersection parameter.
#[inline]
pub(crate) fn orient<const D: usize>(p: &[[f64; D]]) -> f64 {
    if D == 2 {
        let c = |q: &[f64; D]| Coord { x: q[0], y: q[1] };
        robust::orient2d(c(&p[0]), c(&p[1]), c(&p[2]))
    } else {
        let c = |q: &[f64; D]| Coord3D { x: q[0], y: q[1], z: q[2] };
        // robust's orient3d is det[a - d, b - d, c - d] = -det[b - a, c - a, d - a].
        -robust::orient3d(c(&p[0]), c(&p[1]), c(&p[2]), c(&p[3]))
    }
}

/// Exact 2D orientation of three points.
#[inline]
pub(crate) fn orient2(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    robust::orient2d(Coord { x: a[0], y: a[1] }, Coord { x: b[0], y: b[1] }, Coord { x: c[0], y: c[1] })
}

/// Signed measure (area, volume) of the simplex with vertices `v[..=D]` (floating point).
pub(crate) fn simplex_measure<const D: usize>(v: &[[f64; D]]) -> f64 {
    let e: [[f64; D]; D] = std::array::from_fn(|k| sub(&v[k + 1], &v[0]));
    if D == 2 {
        0.5 * (e[0][0] * e[1][1] - e[0][1] * e[1][0])
    } else {
        let (a, b, c) = (pad3(&e[0]), pad3(&e[1]), pad3(&e[2]));
        dot(&a, &cross(&b, &c)) / 6.0
    }
}

/// Mean-ratio type quality of a simplex, 1 for the equilateral one, <= 0 when inverted:
/// `4 sqrt(3) A / sum l^2` (triangle), `6 sqrt(2) V / l_rms^3` with `l_rms^2 = sum l^2 / 6`
/// (tetrahedron).
pub(crate) fn simplex_quality<const D: usize>(v: &[[f64; D]]) -> f64 {
    let mut s = 0.0;
    for i in 0..=D {
        for j in i + 1..=D {
            s += dist2(&v[i], &v[j]);
        }
    }
    if s <= 0.0 {
        return 0.0;
    }
    let m = simplex_measure(v);
    if D == 2 {
        4.0 * 3f64.sqrt() * m / s
    } else {
        6.0 * 2f64.sqrt() * m / (s / 6.0).powf(1.5)
    }
}

/// Smallest interior angle (radians) of a triangle in the plane.
pub(crate) fn min_angle2(v: &[[f64; 2]; 3]) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..3 {
        let a = sub(&v[(i + 1) % 3], &v[i]);
        let b = sub(&v[(i + 2) % 3], &v[i]);
        let ang = (a[0] * b[1] - a[1] * b[0]).abs().atan2(dot(&a, &b));
        best = best.min(ang);
    }
    best
}

/// Closest point of the segment `[a, b]` to `x`: returns the parameter `s` in `[0, 1]`
/// (point `a + s (b - a)`).
pub(crate) fn closest_on_segment<const D: usize>(x: &[f64; D], a: &[f64; D], b: &[f64; D]) -> f64 {
    let ab = sub(b, a);
    let l2 = dot(&ab, &ab);
    if l2 <= 0.0 {
        return 0.0;
    }
    (dot(&sub(x, a), &ab) / l2).clamp(0.0, 1.0)
}

/// Closest point of the triangle `abc` to `x` (Ericson, Real-Time Collision Detection 5.1.5):
/// barycentric weights `[wa, wb, wc]`.
pub(crate) fn closest_on_triangle(x: &[f64; 3], a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> [f64; 3] {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(x, a);
    let d1 = dot(&ab, &ap);
    let d2 = dot(&ac, &ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = sub(x, b);
    let d3 = dot(&ab, &bp);
    let d4 = dot(&ac, &bp);
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = sub(x, c);
    let d5 = dot(&ab, &cp);
    let d6 = dot(&ac, &cp);
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    [1.0 - v - w, v, w]
}

/// Closest point of the flat piece with corners `p[..D]` (a segment in 2D, a triangle in 3D) to
/// `x`, as barycentric weights of the corners (third weight 0 in 2D).
pub(crate) fn closest_on_piece<const D: usize>(x: &[f64; D], p: &[[f64; D]; D]) -> [f64; 3] {
    if D == 2 {
        let s = closest_on_segment(x, &p[0], &p[1]);
        [1.0 - s, s, 0.0]
    } else {
        closest_on_triangle(&pad3(x), &pad3(&p[0]), &pad3(&p[1]), &pad3(&p[2]))
    }
}

/// Point of the piece with barycentric weights `w`.
pub(crate) fn piece_point<const D: usize>(p: &[[f64; D]; D], w: &[f64; 3]) -> [f64; D] {
    std::array::from_fn(|d| (0..D).map(|k| w[k] * p[k][d]).sum())
}

/// Is the point `x`, known to lie in the plane of triangle `abc`, inside the closed triangle?
/// Exact: the test projects on the coordinate plane best aligned with the triangle (projection
/// drops a coordinate, so no rounding) and uses exact 2D orientations.
pub(crate) fn coplanar_point_in_triangle(x: &[f64; 3], a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> bool {
    let n = cross(&sub(b, a), &sub(c, a));
    let k = (0..3).max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs())).unwrap_or(2);
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    let pr = |p: &[f64; 3]| [p[i], p[j]];
    let s1 = orient2(pr(a), pr(b), pr(x));
    let s2 = orient2(pr(b), pr(c), pr(x));
    let s3 = orient2(pr(c), pr(a), pr(x));
    (s1 >= 0.0 && s2 >= 0.0 && s3 >= 0.0) || (s1 <= 0.0 && s2 <= 0.0 && s3 <= 0.0)
}

/// Is `x`, known to be collinear with `a` and `b`, inside the closed segment `[a, b]`? Exact.
pub(crate) fn collinear_point_in_segment<const D: usize>(x: &[f64; D], a: &[f64; D], b: &[f64; D]) -> bool {
    (0..D).all(|d| x[d] >= a[d].min(b[d]) && x[d] <= a[d].max(b[d]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_sign_matches_measure() {
        let t2 = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        assert!(orient(&t2) > 0.0 && simplex_measure(&t2) > 0.0);
        let t3 = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(orient(&t3) > 0.0 && (simplex_measure(&t3) - 1.0 / 6.0).abs() < 1e-16);
        let reg = [[0.0, 0.0], [1.0, 0.0], [0.5, 0.75f64.sqrt()]];
        assert!((simplex_quality(&reg) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn closest_point_on_triangle_regions() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(closest_on_triangle(&[-1.0, -1.0, 3.0], &a, &b, &c), [1.0, 0.0, 0.0]);
        let w = closest_on_triangle(&[0.25, 0.25, 2.0], &a, &b, &c);
        assert!((w[1] - 0.25).abs() < 1e-15 && (w[2] - 0.25).abs() < 1e-15);
        let w = closest_on_triangle(&[1.0, 1.0, 0.0], &a, &b, &c);
        assert!((w[1] - 0.5).abs() < 1e-15 && (w[2] - 0.5).abs() < 1e-15);
    }
}
