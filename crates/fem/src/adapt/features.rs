//! Step 0 of the adaptation in 3D: the feature lines of gamma_s (a thick solid's edges) made
//! chains of fluid-mesh edges.
//!
//! Where two triangles of gamma_s meet at an angle of more than [`super::corners::CORNER_ANGLE_DEG`]
//! (a block's edges), cutting edges by each face on its own places no node on the edge between
//! them: the adapted facets next to it are chords that cut the solid's wedge off. So before the
//! cuts, (1) the **feature vertices** (where the feature segments do not continue as one line:
//! the block's corners, the ends of its edges on the domain boundary) take the nearest fluid
//! vertex that can move there, as the 2D corners do (`corners::corner_moves`); (2) each
//! **feature line** between two of them is walked from its first end: among the fluid neighbours
//! of the last chain vertex that lie farther along the line, the one nearest the line moves onto
//! it (where its cells stay positive and of quality at least `min_move_quality`, and a boundary
//! vertex stays on its boundary planes), until the vertex at the other end is a neighbour. The
//! chain's edges then lie along the feature line (a line with only its last end placed is walked
//! from that end). A line with neither end placed, or whose walk finds no vertex to move before
//! it reaches the other end, is counted ([`super::AdaptStats::unplaced_corners`]). A closed line
//! without feature vertices (a faceted rim) is counted and not walked (not treated yet). Pieces
//! need not be consistently oriented: where two run alike along their shared edge, one normal is
//! turned before the angle is taken.

use super::background::Background;
use super::geom::{closest_on_segment, dist2, dot, lerp, sub};
use super::surface::{piece_normal, Surface};
use std::collections::HashMap;

/// The feature lines of a 3D gamma_s: polylines of surface points between feature vertices (or
/// closed loops), and the feature vertices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Features<const D: usize> {
    pub vertices: Vec<[f64; D]>,
    pub lines: Vec<Vec<[f64; D]>>,
}

/// The feature segments of `surface` (edges shared by two triangles whose normals turn by more
/// than the corner angle), joined into lines at the points where exactly two meet in a straight
/// enough line; the other points on them are the feature vertices.
pub fn features<const D: usize>(surface: &Surface<D>) -> Features<D> {
    if D != 3 {
        return Features { vertices: Vec::new(), lines: Vec::new() };
    }
    // Each edge's pieces, with whether the piece runs along the edge from its smaller point.
    let mut edge_pieces: HashMap<[usize; 2], Vec<(usize, bool)>> = HashMap::new();
    for (i, p) in surface.pieces.iter().enumerate() {
        for k in 0..D {
            let (a, b) = (p[k], p[(k + 1) % D]);
            edge_pieces.entry([a.min(b), a.max(b)]).or_default().push((i, a < b));
        }
    }
    let cos_corner = super::corners::CORNER_ANGLE_DEG.to_radians().cos();
    let unit = |i: usize| {
        let n = piece_normal(&surface.corners(i));
        let l = dot(&n, &n).sqrt();
        n.map(|v| v / l)
    };
    // Two consistently oriented pieces run along their shared edge in opposite directions; where
    // they run alike (a surface given piece by piece, one of them flipped), one normal is turned.
    let turn = |p: &[(usize, bool)]| {
        let alike = if p[0].1 == p[1].1 { -1.0 } else { 1.0 };
        alike * dot(&unit(p[0].0), &unit(p[1].0))
    };
    let mut segments: Vec<[usize; 2]> = edge_pieces.iter().filter(|(_, p)| p.len() == 2 && turn(p) < cos_corner).map(|(e, _)| *e).collect();
    segments.sort_unstable();
    let mut at: HashMap<usize, Vec<usize>> = HashMap::new();
    for (s, e) in segments.iter().enumerate() {
        at.entry(e[0]).or_default().push(s);
        at.entry(e[1]).or_default().push(s);
    }
    let direction = |s: usize, from: usize| {
        let e = segments[s];
        let to = if e[0] == from { e[1] } else { e[0] };
        let d = sub(&surface.points[to], &surface.points[from]);
        let l = dot(&d, &d).sqrt();
        d.map(|v| v / l)
    };
    // A point continues a line where exactly two segments meet and turn by less than the corner
    // angle.
    let continues = |p: usize| {
        let s = &at[&p];
        s.len() == 2 && dot(&direction(s[0], p), &direction(s[1], p)) < -cos_corner
    };
    let mut vertex_ids: Vec<usize> = at.keys().copied().filter(|&p| !continues(p)).collect();
    vertex_ids.sort_unstable();
    let mut used = vec![false; segments.len()];
    let mut lines = Vec::new();
    let walk = |start: usize, first: usize, used: &mut Vec<bool>| {
        let mut line = vec![start];
        let (mut p, mut s) = (start, first);
        loop {
            used[s] = true;
            let e = segments[s];
            p = if e[0] == p { e[1] } else { e[0] };
            line.push(p);
            if !continues(p) {
                break;
            }
            match at[&p].iter().copied().find(|&t| !used[t]) {
                Some(t) => s = t,
                None => break,
            }
        }
        line.iter().map(|&q| surface.points[q]).collect::<Vec<_>>()
    };
    for &v in &vertex_ids {
        for &s in &at[&v] {
            if !used[s] {
                lines.push(walk(v, s, &mut used));
            }
        }
    }
    // Closed loops without a feature vertex.
    for s in 0..segments.len() {
        if !used[s] {
            lines.push(walk(segments[s][0], s, &mut used));
        }
    }
    Features { vertices: vertex_ids.iter().map(|&p| surface.points[p]).collect(), lines }
}

/// Arc length along `line` of the point of `line` nearest `x`, that point, and its distance.
fn project_on_line<const D: usize>(line: &[[f64; D]], x: &[f64; D]) -> (f64, [f64; D], f64) {
    let mut best = (0.0, line[0], f64::INFINITY);
    let mut s0 = 0.0;
    for w in line.windows(2) {
        let t = closest_on_segment(x, &w[0], &w[1]);
        let p = lerp(&w[0], &w[1], t);
        let d = dist2(x, &p).sqrt();
        let len = dist2(&w[0], &w[1]).sqrt();
        if d < best.2 {
            best = (s0 + t * len, p, d);
        }
        s0 += len;
    }
    best
}

/// Moves of fluid vertices onto the feature vertices and lines of `surface` (see the module
/// documentation), and the number of feature vertices and lines left without them.
/// In 2D, the corners' moves ([`super::corners`]).
pub(crate) fn feature_moves<const D: usize>(bg: &Background<D>, surface: &Surface<D>, min_quality: f64) -> (Vec<(usize, [f64; D])>, usize) {
    if D != 3 {
        return super::corners::corner_moves(bg, &super::corners::corners(surface), min_quality);
    }
    let f = features(surface);
    let (mut moves, mut unplaced) = super::corners::corner_moves(bg, &f.vertices, min_quality);
    if f.lines.is_empty() {
        return (moves, unplaced);
    }
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); bg.mesh.points.len()];
    for e in &bg.topology.edges {
        neighbours[e[0]].push(e[1]);
        neighbours[e[1]].push(e[0]);
    }
    let vertex_at = |moves: &[(usize, [f64; D])], x: &[f64; D]| moves.iter().find(|m| m.1 == *x).map(|m| m.0);
    for line in &f.lines {
        // Walked from an end with a vertex: the first, else the last.
        let reversed: Vec<[f64; D]>;
        let line = if vertex_at(&moves, &line[0]).is_none() && vertex_at(&moves, &line[line.len() - 1]).is_some() {
            reversed = line.iter().rev().copied().collect();
            &reversed
        } else {
            line
        };
        let (first, last) = (line[0], line[line.len() - 1]);
        let Some(mut v) = vertex_at(&moves, &first) else {
            unplaced += 1;
            continue;
        };
        let end = vertex_at(&moves, &last);
        let length: f64 = line.windows(2).map(|w| dist2(&w[0], &w[1]).sqrt()).sum();
        let mut s_v = 0.0;
        loop {
            if end.is_some_and(|e| neighbours[v].contains(&e)) {
                break;
            }
            let mut candidates: Vec<(f64, usize, f64, [f64; D])> = neighbours[v]
                .iter()
                .copied()
                .filter(|&w| !moves.iter().any(|m| m.0 == w))
                .map(|w| {
                    // Not moved yet (filtered above): at its original position.
                    let (s, p, d) = project_on_line(line, &bg.mesh.points[w]);
                    (d, w, s, p)
                })
                .filter(|&(_, _, s, _)| s > s_v && s < length)
                .collect();
            candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            let next = candidates
                .into_iter()
                .find(|&(_, w, _, p)| super::boundary_move_ok(bg, w, &p) && super::corners::star_ok(bg, &moves, w, &p, min_quality));
            match next {
                Some((_, w, s, p)) => {
                    moves.push((w, p));
                    (v, s_v) = (w, s);
                }
                None => {
                    unplaced += 1;
                    break;
                }
            }
        }
    }
    (moves, unplaced)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube's sides and top, two triangles a face: its four vertical edges (each from a
    /// top corner to its end on the floor) and four top edges; the faces' diagonals are flat.
    #[test]
    fn an_open_box_has_eight_feature_lines_between_eight_feature_vertices() {
        let p = |i: usize| [(i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64];
        let points: Vec<[f64; 3]> = (0..8).map(p).collect();
        let quads = [[0, 1, 5, 4], [1, 3, 7, 5], [3, 2, 6, 7], [2, 0, 4, 6], [4, 5, 7, 6]];
        let pieces: Vec<[usize; 3]> = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        // The same with one triangle of the top flipped: its diagonal is still flat.
        let mut flipped = pieces.clone();
        flipped[8].swap(1, 2);
        for pieces in [pieces, flipped] {
            let f = features(&Surface::from_pieces(points.clone(), pieces).unwrap());
            assert_eq!(f.vertices.len(), 8);
            assert_eq!(f.lines.len(), 8);
            assert!(f.lines.iter().all(|l| l.len() == 2 && dist2(&l[0], &l[1]) == 1.0), "{:?}", f.lines);
            let vertical = f.lines.iter().filter(|l| l[0][2] != l[1][2]).count();
            assert_eq!(vertical, 4);
        }
    }
}
