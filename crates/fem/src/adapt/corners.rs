//! Step 0 of the adaptation (2D): the corners of gamma_s made vertices of the fluid mesh.
//!
//! Where gamma_s turns sharply (a thick solid's corner: the Turek-Hron bar's tip turns by 90
//! degrees twice), cutting edges places no node at the corner: the adapted facets next to it are
//! chords that cut it off, up to a cell's size away from gamma_s, and the coupling points on
//! them cannot be found on the solid. So before the cuts, each **corner** (a point of gamma_s
//! shared by exactly two pieces whose directions turn by more than [`CORNER_ANGLE_DEG`]) takes
//! the nearest fluid vertex that can move there: one whose cells all keep a positive area and a
//! quality of at least `min_move_quality` with it at the corner, that is not yet at another
//! corner, and that stays on its boundary lines if it is a boundary vertex. The cuts are then
//! found on the mesh with those vertices moved; the moved vertices lie on gamma_s (they touch
//! it). A corner no vertex can take is counted ([`super::AdaptStats::unplaced_corners`]).
//! The ends of an open gamma_s are not corners. In 3D [`corners`] finds none: the edges and
//! vertices of gamma_s are treated in [`super::features`], which uses `corner_moves` for the
//! vertices.

use super::background::Background;
use super::geom::{dist2, dot, simplex_measure, simplex_quality, sub};
use super::surface::Surface;
use rstar::AABB;
use std::collections::HashMap;

/// gamma_s has a corner where two pieces turn by more than this angle (degrees).
pub const CORNER_ANGLE_DEG: f64 = 30.0;

/// The corners of `surface` (see the module documentation), in piece-corner order; none in 3D.
pub fn corners<const D: usize>(surface: &Surface<D>) -> Vec<[f64; D]> {
    if D != 2 {
        return Vec::new();
    }
    // For every surface point: the unit directions of its pieces, pointing away from it.
    let mut away: HashMap<usize, Vec<[f64; D]>> = HashMap::new();
    for piece in &surface.pieces {
        let (a, b) = (piece[0], piece[1]);
        let t = sub(&surface.points[b], &surface.points[a]);
        let l = dot(&t, &t).sqrt();
        let u: [f64; D] = std::array::from_fn(|d| t[d] / l);
        away.entry(a).or_default().push(u);
        away.entry(b).or_default().push(u.map(|v| -v));
    }
    let straight = -CORNER_ANGLE_DEG.to_radians().cos();
    let mut out: Vec<(usize, [f64; D])> =
        away.into_iter().filter(|(_, dirs)| dirs.len() == 2 && dot(&dirs[0], &dirs[1]) > straight).map(|(p, _)| (p, surface.points[p])).collect();
    out.sort_unstable_by_key(|(p, _)| *p);
    out.into_iter().map(|(_, x)| x).collect()
}

/// The vertex moves that put fluid vertices at `corners` (see the module documentation; the
/// vertices `banned` are not taken) and the number of corners left without one.
pub(crate) fn corner_moves<const D: usize>(
    bg: &Background<D>,
    corners: &[[f64; D]],
    min_quality: f64,
    banned: &std::collections::HashSet<usize>,
) -> (Vec<(usize, [f64; D])>, usize) {
    let mut moves: Vec<(usize, [f64; D])> = Vec::new();
    let mut unplaced = 0;
    let h = (bg.measure / bg.num_cells().max(1) as f64).powf(1.0 / D as f64);
    for x in corners {
        let mut candidates: Vec<usize> = Vec::new();
        let mut r = h;
        while candidates.is_empty() && r < 1e3 * h {
            let env = AABB::from_corners(x.map(|v| v - r), x.map(|v| v + r));
            candidates = bg.edge_tree.locate_in_envelope_intersecting(env).flat_map(|e| bg.topology.edges[e.edge]).collect();
            r *= 2.0;
        }
        candidates.sort_by(|&a, &b| dist2(&bg.mesh.points[a], x).total_cmp(&dist2(&bg.mesh.points[b], x)).then(a.cmp(&b)));
        candidates.dedup();
        let free = |v: usize| !banned.contains(&v) && !moves.iter().any(|(m, _)| *m == v);
        match candidates.into_iter().find(|&v| free(v) && super::boundary_move_ok(bg, v, x) && star_ok(bg, &moves, v, x, min_quality)) {
            Some(v) => moves.push((v, *x)),
            None => unplaced += 1,
        }
    }
    (moves, unplaced)
}

/// Do all cells around vertex `v` keep a positive measure and quality `min_quality` with `v` at
/// `x` and the vertices of `moves` already moved?
pub(crate) fn star_ok<const D: usize>(bg: &Background<D>, moves: &[(usize, [f64; D])], v: usize, x: &[f64; D], min_quality: f64) -> bool {
    let at = |g: usize| match moves.iter().find(|m| m.0 == g) {
        Some(m) => m.1,
        None => bg.mesh.points[g],
    };
    bg.vertex_cells.row(v).iter().all(|&c| {
        let p: Vec<[f64; D]> = bg.cell(c).iter().map(|&g| if g == v { *x } else { at(g) }).collect();
        simplex_measure(&p) > 0.0 && simplex_quality(&p) >= min_quality
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_two_corners_of_a_bar_tip_but_not_its_ends_or_gentle_turns() {
        let pts = vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.1], [2.0, 1.0], [0.0, 1.0]];
        let s = Surface::from_polyline(pts).unwrap();
        // Turns: 5.7 degrees at [1, 0], 84.3 at [2, 0.1], 90 at [2, 1].
        assert_eq!(corners(&s), vec![[2.0, 0.1], [2.0, 1.0]]);
    }
}
