//! Step 1 of the adaptation: the fluid edges cut by gamma_s and one intersection point per edge.
//!
//! Each surface piece queries the R-tree of the original mesh's edges with its bounding box, so
//! the work grows with the number of edges near gamma_s, never with all pairs. Each candidate
//! pair (edge `ab`, piece) is classified with exact orientation predicates (`robust`):
//!
//! * **cut**: `a` and `b` lie strictly on opposite sides of the piece's line / plane and the
//!   segment meets the closed piece, enlarged by `T_SNAP` times the lengths so that a side off
//!   the domain boundary by round-off still meets the boundary's edges; the point is
//!   `a + t (b - a)` with `t = o_a / (o_a - o_b)` (`o` the signed distances as orientation
//!   determinants). A cut at `t <= T_SNAP` (or
//!   `t >= 1 - T_SNAP`) is within round-off of the end point: it is **snapped**, the end vertex is
//!   treated as lying on gamma_s and the edge as touching it (counted).
//! * **touch**: exactly one end point lies on the piece's line / plane; it is on gamma_s when it
//!   lies in the closed piece. The edge is not cut (paper: an edge only touching gamma_s at an end
//!   point is not in S^f).
//! * **in surface**: both end points lie on the line / plane (the edge lies along gamma_s); the
//!   end points inside the piece are on gamma_s, the edge is not cut (counted).
//!
//! An edge cut by several pieces at different points (a folded surface, two sheets, or the two
//! sides of a corner) keeps the point farthest from its ends (ties: the one closest to its first
//! vertex `n1`, its smaller vertex number) and is counted. A point near an end is likely to be
//! taken by moving that end (step 2), which the end's other edges across the same sheet can
//! request too; a point inside the edge has no other way onto the mesh. Near the Turek-Hron bar's
//! tip swung up (FSI2 at t = 7.642), an edge from a vertex next to the bottom face crossed the
//! tip face; keeping the bottom face's point left the tip face without a facet between that edge
//! and the corner. The point nearest an end among the others is kept too, as the edge's
//! **second cut** (`CutSet::second_cuts`): step 2 moves that end onto it where it can, however
//! far, since an edge has room for one new node only. Across a block's corner, an edge cut at
//! 0.24 and 0.75 of its length by the two sides lost the first point, and the side between the
//! corner and that edge had no facet.

use super::background::Background;
use super::geom::{collinear_point_in_segment, coplanar_point_in_triangle, dist2, lerp, orient, pad3};
use super::surface::Surface;
use rstar::AABB;

/// Cuts closer than this (as a fraction of the edge) to an end point snap to it.
pub const T_SNAP: f64 = 1e-12;

/// One cut edge: intersection parameter from the edge's first (smaller-numbered) vertex, and
/// the point.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cut<const D: usize> {
    pub edge: usize,
    pub t: f64,
    pub x: [f64; D],
}

/// The result of step 1.
#[derive(Clone, Debug, Default)]
pub(crate) struct CutSet<const D: usize> {
    /// One cut per cut edge, sorted by edge.
    pub cuts: Vec<Cut<D>>,
    /// The second point of each edge cut at several points, sorted by edge (see the module
    /// documentation); one per edge cut at several points (`multi_cut_edges`).
    pub second_cuts: Vec<Cut<D>>,
    /// Original vertices lying on gamma_s (touched or snapped; after step 2 also the boundary
    /// touches, taken to lie on it), sorted, unique.
    pub touched: Vec<usize>,
    pub edges_in_surface: usize,
    pub snapped: usize,
}

impl<const D: usize> CutSet<D> {
    /// Adds `vertices` (sorted) to the vertices on gamma_s.
    pub(crate) fn touch(&mut self, vertices: &[usize]) {
        if vertices.is_empty() {
            return;
        }
        self.touched.extend_from_slice(vertices);
        self.touched.sort_unstable();
        self.touched.dedup();
    }
}

/// Outcome of one edge-piece test.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Hit {
    Miss,
    Cut(f64),
    /// Whether `a`, `b` lie on the piece (`in_plane` when both lie on its line / plane).
    Touch {
        a: bool,
        b: bool,
        in_plane: bool,
    },
}

/// Step 1 (see the module documentation).
pub(crate) fn find_cuts<const D: usize>(bg: &Background<D>, surface: &Surface<D>) -> CutSet<D> {
    let mut raw: Vec<(usize, f64, usize)> = Vec::new();
    let mut touched = Vec::new();
    let mut in_plane_edges = Vec::new();
    let mut snapped = 0;
    for pb in surface.tree().iter() {
        let env = AABB::from_points(pb.corners.iter());
        for eb in bg.edge_tree.locate_in_envelope_intersecting(env) {
            let [ia, ib] = bg.topology.edges[eb.edge];
            let (a, b) = (bg.mesh.points[ia], bg.mesh.points[ib]);
            match classify(&a, &b, &pb.corners) {
                Hit::Miss => {}
                Hit::Cut(t) if t <= T_SNAP => {
                    snapped += 1;
                    touched.push(ia);
                }
                Hit::Cut(t) if t >= 1.0 - T_SNAP => {
                    snapped += 1;
                    touched.push(ib);
                }
                Hit::Cut(t) => raw.push((eb.edge, t, pb.index)),
                Hit::Touch { a, b, in_plane } => {
                    if a {
                        touched.push(ia);
                    }
                    if b {
                        touched.push(ib);
                    }
                    if in_plane && (a || b) {
                        in_plane_edges.push(eb.edge);
                    }
                }
            }
        }
    }
    raw.sort_unstable_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)).then(x.2.cmp(&y.2)));
    let mut cuts: Vec<Cut<D>> = Vec::new();
    let mut second_cuts: Vec<Cut<D>> = Vec::new();
    let mut i = 0;
    while i < raw.len() {
        let edge = raw[i].0;
        let mut j = i;
        while j < raw.len() && raw[j].0 == edge {
            j += 1;
        }
        let ts: Vec<f64> = raw[i..j].iter().map(|r| r.1).collect();
        let [ia, ib] = bg.topology.edges[edge];
        let cut = |t: f64| Cut { edge, t, x: lerp(&bg.mesh.points[ia], &bg.mesh.points[ib], t) };
        let (kept, second) = kept_and_second(&ts);
        cuts.push(cut(kept));
        second_cuts.extend(second.map(cut));
        i = j;
    }
    touched.sort_unstable();
    touched.dedup();
    in_plane_edges.sort_unstable();
    in_plane_edges.dedup();
    CutSet { cuts, second_cuts, touched, edges_in_surface: in_plane_edges.len(), snapped }
}

/// Of the points `ts` (sorted) where pieces cut one edge: the one kept as the edge's cut, farthest
/// from the edge's ends (ties: the first), and, where others lie more than `1e-12` from it, the
/// second: the one of those nearest an end (ties: the first).
fn kept_and_second(ts: &[f64]) -> (f64, Option<f64>) {
    let from_ends = |t: f64| t.min(1.0 - t);
    // Sorted by t: a later point wins only if it is strictly farther from the ends.
    let kept = ts.iter().copied().fold(ts[0], |k, t| if from_ends(t) > from_ends(k) + 1e-12 { t } else { k });
    let second = ts.iter().copied().filter(|t| (t - kept).abs() > 1e-12).fold(None, |s: Option<f64>, t| match s {
        Some(s) if from_ends(s) <= from_ends(t) + 1e-12 => Some(s),
        _ => Some(t),
    });
    (kept, second)
}

/// Round-off allowance of the side orientations in [`classify`]: an orientation of segment `ab`
/// (length `ab`) with a piece's side (length `side`) is taken as zero below `T_SNAP` times
/// `ab side max(ab, side)` (3D; `ab max(ab, side)` in 2D), i.e. when the segment passes within
/// about `T_SNAP` of the lengths of the side's line. Without it a piece whose side lies on the
/// domain boundary up to round-off (the clamped rim of model problem 4: midpoints of the wall's
/// chords, off its plane by 1e-18) missed the wall edges through that side, and gamma_f had
/// holes along the rim.
fn side_tolerance<const D: usize>(ab: f64, side: f64) -> f64 {
    let l = ab.max(side);
    T_SNAP * l * if D == 3 { ab * side } else { ab }
}

/// Exact classification of edge `ab` against a flat piece (see the module documentation).
fn classify<const D: usize>(a: &[f64; D], b: &[f64; D], c: &[[f64; D]; D]) -> Hit {
    let with = |x: &[f64; D]| -> [[f64; D]; 4] {
        let mut p = [[0.0; D]; 4];
        p[..D].copy_from_slice(c);
        p[D] = *x;
        p
    };
    let oa = orient(&with(a)[..=D]);
    let ob = orient(&with(b)[..=D]);
    let inside = |x: &[f64; D]| -> bool {
        if D == 2 {
            collinear_point_in_segment(x, &c[0], &c[1])
        } else {
            coplanar_point_in_triangle(&pad3(x), &pad3(&c[0]), &pad3(&c[1]), &pad3(&c[2]))
        }
    };
    if oa == 0.0 || ob == 0.0 {
        let ta = oa == 0.0 && inside(a);
        let tb = ob == 0.0 && inside(b);
        return Hit::Touch { a: ta, b: tb, in_plane: oa == 0.0 && ob == 0.0 };
    }
    if (oa > 0.0) == (ob > 0.0) {
        return Hit::Miss;
    }
    // The segment meets the closed piece iff, in 2D, the piece's end points are not strictly on
    // one side of line ab; in 3D, the orientations of line ab with the three sides of the
    // triangle do not take both strict signs. "Strictly": beyond `T_SNAP` times the lengths
    // (see `side_tolerance`), so a segment through a piece's side stays cut when that side is
    // off by round-off.
    let ab = dist2(a, b).sqrt();
    if D == 2 {
        let tol = side_tolerance::<D>(ab, dist2(&c[0], &c[1]).sqrt());
        let (s1, s2) = (orient(&[*a, *b, c[0]]), orient(&[*a, *b, c[1]]));
        if (s1 > tol && s2 > tol) || (s1 < -tol && s2 < -tol) {
            return Hit::Miss;
        }
    } else {
        let s: [(f64, f64); 3] = std::array::from_fn(|k| {
            let (p, q) = (c[k], c[(k + 1) % D]);
            (orient(&[*a, *b, p, q]), side_tolerance::<D>(ab, dist2(&p, &q).sqrt()))
        });
        if s.iter().any(|&(v, tol)| v > tol) && s.iter().any(|&(v, tol)| v < -tol) {
            return Hit::Miss;
        }
    }
    Hit::Cut(oa / (oa - ob))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classification_2d() {
        let piece = [[0.0, -1.0], [0.0, 1.0]];
        assert!(matches!(classify(&[-1.0, 0.0], &[3.0, 0.0], &piece), Hit::Cut(t) if (t - 0.25).abs() < 1e-15));
        assert_eq!(classify(&[-1.0, 2.0], &[3.0, 2.0], &piece), Hit::Miss);
        assert_eq!(classify(&[0.0, 0.5], &[3.0, 0.0], &piece), Hit::Touch { a: true, b: false, in_plane: false });
        assert_eq!(classify(&[0.0, 0.5], &[0.0, 3.0], &piece), Hit::Touch { a: true, b: false, in_plane: true });
        // The piece ends on the edge: still a cut.
        assert!(matches!(classify(&[-1.0, 1.0], &[1.0, 1.0], &piece), Hit::Cut(_)));
    }

    #[test]
    fn an_edge_cut_twice_keeps_the_inner_point_and_the_other_as_its_second_cut() {
        assert_eq!(kept_and_second(&[0.24, 0.75]), (0.75, Some(0.24)));
        assert_eq!(kept_and_second(&[0.1, 0.3, 0.95]), (0.3, Some(0.95)));
        assert_eq!(kept_and_second(&[0.5]), (0.5, None));
        // Points within 1e-12 are one point (a piece's end shared by two pieces).
        assert_eq!(kept_and_second(&[0.1, 0.1 + 1e-13]), (0.1, None));
    }

    #[test]
    fn classification_3d() {
        let piece = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(matches!(classify(&[0.2, 0.2, -1.0], &[0.2, 0.2, 3.0], &piece), Hit::Cut(t) if (t - 0.25).abs() < 1e-15));
        assert_eq!(classify(&[0.8, 0.8, -1.0], &[0.8, 0.8, 1.0], &piece), Hit::Miss);
        assert_eq!(classify(&[0.2, 0.2, 0.0], &[0.2, 0.2, 1.0], &piece), Hit::Touch { a: true, b: false, in_plane: false });
        assert_eq!(classify(&[0.2, 0.2, 0.0], &[2.0, 0.2, 0.0], &piece), Hit::Touch { a: true, b: false, in_plane: true });
        // Through a piece edge (closed piece).
        assert!(matches!(classify(&[0.5, 0.0, -1.0], &[0.5, 0.0, 1.0], &piece), Hit::Cut(_)));
    }
}
