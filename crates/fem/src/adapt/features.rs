//! Step 0 of the adaptation in 3D: the feature lines of gamma_s (a thick solid's edges) made
//! chains of fluid-mesh edges.
//!
//! Where two triangles of gamma_s meet at an angle of more than [`super::corners::CORNER_ANGLE_DEG`]
//! (a block's edges), cutting edges by each face on its own places no node on the edge between
//! them: the adapted facets next to it are chords that cut the solid's wedge off. So before the
//! cuts, (1) the **feature vertices** (where the feature segments do not continue as one line:
//! the block's corners, the ends of its edges on the domain boundary) take the nearest fluid
//! vertex that can move there, as the 2D corners do (`corners::corner_moves`); (2) each
//! **feature line** between two of them becomes a **chain**: the cheapest path of fluid edges
//! between its two end vertices whose vertices move onto the line, in order along it (a
//! shortest-path search, `chain`; each move keeps the cells positive and of quality at least
//! `min_move_quality` given the moves before it, and a boundary vertex on its boundary planes).
//! The chain's edges then lie along the feature line. Where a line has no chain (searched from
//! both ends), the vertices at its ends are left out and the placement is tried again
//! (`MAX_FEATURE_TRIES` at most): the vertex nearest a corner of a rotated block can leave its
//! neighbours no room to move onto the edges from it. Lines still without a chain, or with an
//! end no vertex could take, are counted ([`super::AdaptStats::unplaced_corners`]). A closed
//! line without feature vertices (a faceted rim) is counted and not walked (not treated yet).
//! Pieces need not be consistently oriented: where two run alike along their shared edge, one
//! normal is turned before the angle is taken.
//!
//! The lines split gamma_s into **smooth parts** ([`smooth_parts`]; a block's faces): a facet of
//! gamma_f must have its vertices on one part (step 4), and the cells next to the lines are cut
//! again where their edges still cross gamma_s (`super::cut_crossings_near_features`).

use super::background::Background;
use super::geom::{closest_on_piece, closest_on_segment, dist2, dot, lerp, piece_point, simplex_measure, simplex_quality, sub};
use super::surface::{piece_normal, Surface};
use std::collections::{HashMap, HashSet};

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
    let edge_pieces = edge_pieces(surface);
    let mut segments: Vec<[usize; 2]> = edge_pieces.iter().filter(|(_, p)| is_feature(surface, p)).map(|(e, _)| *e).collect();
    segments.sort_unstable();
    let cos_corner = super::corners::CORNER_ANGLE_DEG.to_radians().cos();
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

/// Each edge of the pieces of `surface` (as sorted point ids) with its pieces, and whether each
/// piece runs along the edge from its smaller point.
fn edge_pieces<const D: usize>(surface: &Surface<D>) -> HashMap<[usize; 2], Vec<(usize, bool)>> {
    let mut edge_pieces: HashMap<[usize; 2], Vec<(usize, bool)>> = HashMap::new();
    for (i, p) in surface.pieces.iter().enumerate() {
        for k in 0..D {
            let (a, b) = (p[k], p[(k + 1) % D]);
            edge_pieces.entry([a.min(b), a.max(b)]).or_default().push((i, a < b));
        }
    }
    edge_pieces
}

/// Is the edge shared by `pieces` (see [`edge_pieces`]) a feature segment: two pieces whose
/// normals turn by more than the corner angle? Two consistently oriented pieces run along their
/// shared edge in opposite directions; where they run alike (a surface given piece by piece, one
/// of them flipped), one normal is turned before the angle is taken.
fn is_feature<const D: usize>(surface: &Surface<D>, pieces: &[(usize, bool)]) -> bool {
    if pieces.len() != 2 {
        return false;
    }
    let unit = |i: usize| {
        let n = piece_normal(&surface.corners(i));
        let l = dot(&n, &n).sqrt();
        n.map(|v| v / l)
    };
    let alike = if pieces[0].1 == pieces[1].1 { -1.0 } else { 1.0 };
    alike * dot(&unit(pieces[0].0), &unit(pieces[1].0)) < super::corners::CORNER_ANGLE_DEG.to_radians().cos()
}

/// The smooth parts of a 3D gamma_s: pieces joined across the edges they share that are not
/// feature segments (a block's faces). Returns the part of each piece, numbered from 0. In 2D
/// all pieces are one part.
pub fn smooth_parts<const D: usize>(surface: &Surface<D>) -> Vec<usize> {
    let n = surface.num_pieces();
    if D != 3 {
        return vec![0; n];
    }
    let joined = edge_pieces(surface).into_values().filter(|p| p.len() == 2 && !is_feature(surface, p)).map(|p| (p[0].0, p[1].0));
    crate::mesh::connected_components(n, joined)
}

/// The smooth parts (numbers from [`smooth_parts`]) of the pieces within `tol` of `x`, sorted:
/// one for a point inside a face, two on a block's edge, three at its corner.
pub(crate) fn parts_at<const D: usize>(surface: &Surface<D>, parts: &[usize], x: &[f64; D], tol: f64) -> Vec<usize> {
    let lo: [f64; D] = std::array::from_fn(|d| x[d] - tol);
    let hi: [f64; D] = std::array::from_fn(|d| x[d] + tol);
    let mut found: Vec<usize> = surface
        .tree()
        .locate_in_envelope_intersecting(rstar::AABB::from_corners(lo, hi))
        .filter(|pb| dist2(x, &piece_point(&pb.corners, &closest_on_piece(x, &pb.corners))) <= tol * tol)
        .map(|pb| parts[pb.index])
        .collect();
    found.sort_unstable();
    found.dedup();
    found
}

/// The kinks of the feature `lines` between mesh vertices on them: for each edge of `bg` whose
/// two ends (among `on_line`, checked) lie on one line (within round-off), the point of the line
/// between them where it bends away from the edge by more than round-off (the middle one of
/// several), with the edge. A curved solid's edge is a polyline through its geometry nodes; a
/// chain's edge between two of its vertices is a chord of it, and the faces meeting at the line
/// cross that chord next to the bend: cut there on both faces, at points apart by the chord's
/// sag (1.7e-5 for a block's top edge bent by its Q2 deformation), they left a sliver between
/// them and a hole in gamma_f. The bend placed as the edge's node (off the edge by its sag,
/// at most [`MAX_KINK_SAG`] of its length, where the cells around the edge stay positive and of
/// quality `min_quality`: [`halves_ok`]) makes the chain follow the line; further passes take
/// the other bends. A cell split on other edges too can still be spoilt by the kink: the
/// adaptation checks the children and refuses such kinks (`AdaptStats::refused_kinks`).
pub(crate) fn kinks<const D: usize>(
    bg: &Background<D>,
    lines: &[Vec<[f64; D]>],
    on_line: impl Iterator<Item = usize>,
    min_quality: f64,
) -> Vec<(usize, [f64; D])> {
    if lines.is_empty() {
        return Vec::new();
    }
    // Each candidate vertex's lines and arc lengths.
    let mut at: HashMap<usize, Vec<(usize, f64)>> = HashMap::new();
    for v in on_line {
        let x = bg.mesh.points[v];
        let scale = 1.0 + x.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        for (i, line) in lines.iter().enumerate() {
            let (s, _, d) = project_on_line(line, &x);
            if d <= ON_LINE_TOL * scale {
                at.entry(v).or_default().push((i, s));
            }
        }
    }
    let mut out = Vec::new();
    for (e, [a, b]) in bg.topology.edges.iter().enumerate() {
        let (Some(la), Some(lb)) = (at.get(a), at.get(b)) else { continue };
        let (pa, pb) = (bg.mesh.points[*a], bg.mesh.points[*b]);
        let len = dist2(&pa, &pb).sqrt();
        for &(i, sa) in la {
            let Some(&(_, sb)) = lb.iter().find(|l| l.0 == i) else { continue };
            let (s0, s1) = (sa.min(sb), sa.max(sb));
            let line = &lines[i];
            let mut s = 0.0;
            let mut bends = Vec::new();
            for w in line.windows(2) {
                s += dist2(&w[0], &w[1]).sqrt();
                if s > s0 + KINK_GAP * len && s < s1 - KINK_GAP * len {
                    let sag = dist2(&w[1], &lerp(&pa, &pb, closest_on_segment(&w[1], &pa, &pb))).sqrt();
                    if sag > ON_LINE_TOL * (1.0 + len) && sag <= MAX_KINK_SAG * len {
                        bends.push(w[1]);
                    }
                }
            }
            if !bends.is_empty() {
                let x = bends[bends.len() / 2];
                if halves_ok(bg, e, &x, min_quality) {
                    out.push((e, x));
                }
                break;
            }
        }
    }
    out
}

/// May edge `e` of `bg` take a node at `x` off it: is it inside the domain (not both ends on the
/// boundary, where the cells around it do not close), and are the halves of every cell around
/// it, with `x` in place of either end, positive and of quality `min_quality` at least?
fn halves_ok<const D: usize>(bg: &Background<D>, e: usize, x: &[f64; D], min_quality: f64) -> bool {
    let ends = bg.topology.edges[e];
    if ends.iter().all(|&v| !bg.vertex_boundary.row(v).is_empty()) {
        return false;
    }
    bg.edge_cells.row(e).iter().all(|&c| {
        ends.iter().all(|&end| {
            let p: Vec<[f64; D]> = bg.cell(c).iter().map(|&g| if g == end { *x } else { bg.mesh.points[g] }).collect();
            simplex_measure(&p) > 0.0 && simplex_quality(&p) >= min_quality
        })
    })
}

/// A vertex this close (relative to its coordinates) to a feature line is on it ([`kinks`]).
const ON_LINE_TOL: f64 = 1e-9;
/// Bends closer than this (relative to the edge) to an end of the edge are that end ([`kinks`]).
const KINK_GAP: f64 = 1e-6;
/// Bends farther than this (relative to the edge) from it are not put on it ([`kinks`]): the
/// node would leave the edge too far for the cells around it.
const MAX_KINK_SAG: f64 = 0.05;

/// Arc length along `line` of the point of `line` nearest `x`, that point, and its distance.
pub(crate) fn project_on_line<const D: usize>(line: &[[f64; D]], x: &[f64; D]) -> (f64, [f64; D], f64) {
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

/// The chain along `line` from the vertex `start` placed at its first point to `end`, placed at
/// its last: a path of mesh edges from `start` to `end` through unmoved vertices, the cheapest
/// Dijkstra's search finds (each vertex is reached once, its move checked against the path that
/// reached it first, so a cheaper path through it can be missed), each vertex moving onto the
/// line, farther along it than the one before, to a
/// point nearer to it than its edge from the one before is long, and costing its squared
/// distance to that point over that edge's squared length plus [`CHAIN_VERTEX_COST`] (few
/// vertices, short moves). A vertex's point is its projection onto the line or, where the
/// boundary or its cells refuse that (quality `min_quality`, given the moves of the path before
/// it), the projection shifted along the line by [`CHAIN_SHIFTS`] times the edge's length. Every
/// move is checked with all moves before it, so the chain leaves every cell valid. Returns
/// whether a chain was placed (its moves appended to `moves`).
fn chain<const D: usize>(
    bg: &Background<D>,
    neighbours: &[Vec<usize>],
    line: &[[f64; D]],
    start: usize,
    end: usize,
    moves: &mut Vec<(usize, [f64; D])>,
    min_quality: f64,
) -> bool {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    if neighbours[start].contains(&end) {
        return true;
    }
    let length: f64 = line.windows(2).map(|w| dist2(&w[0], &w[1]).sqrt()).sum();
    // Per reached vertex: cost, previous vertex, arc length and point on the line.
    let mut reached: HashMap<usize, (f64, usize, f64, [f64; D])> = HashMap::new();
    reached.insert(start, (0.0, usize::MAX, 0.0, line[0]));
    let mut heap = BinaryHeap::from([(Reverse(Ord64(0.0)), start)]);
    let mut best: Option<(f64, usize)> = None;
    while let Some((Reverse(Ord64(c)), u)) = heap.pop() {
        let (cu, _, s_u, _) = reached[&u];
        if c > cu || best.is_some_and(|b| c >= b.0) {
            continue;
        }
        if neighbours[u].contains(&end) && u != start {
            best = Some((c, u));
            continue;
        }
        let mut trial = moves.clone();
        let mut w = u;
        while w != start {
            let (_, prev, _, p) = reached[&w];
            trial.push((w, p));
            w = prev;
        }
        for &w in &neighbours[u] {
            if trial.iter().any(|m| m.0 == w) {
                continue;
            }
            let x = bg.mesh.points[w];
            let (s, _, _) = project_on_line(line, &x);
            let l = dist2(&bg.mesh.points[u], &x).sqrt();
            let placed = CHAIN_SHIFTS.iter().find_map(|k| {
                let s = s + k * l;
                if s <= s_u || s >= length {
                    return None;
                }
                let p = point_at(line, s);
                let ok = dist2(&p, &x) < l * l && super::boundary_move_ok(bg, w, &p) && super::corners::star_ok(bg, &trial, w, &p, min_quality);
                ok.then_some((s, p))
            });
            let Some((s, p)) = placed else { continue };
            let cw = c + dist2(&p, &x) / (l * l) + CHAIN_VERTEX_COST;
            if reached.get(&w).is_none_or(|r| cw < r.0) {
                reached.insert(w, (cw, u, s, p));
                heap.push((Reverse(Ord64(cw)), w));
            }
        }
    }
    let Some((_, mut w)) = best else { return false };
    let mut path = Vec::new();
    while w != start {
        let (_, prev, _, p) = reached[&w];
        path.push((w, p));
        w = prev;
    }
    moves.extend(path.into_iter().rev());
    true
}

/// The point at arc length `s` along `line` (clamped to its ends).
fn point_at<const D: usize>(line: &[[f64; D]], s: f64) -> [f64; D] {
    let mut s0 = 0.0;
    for w in line.windows(2) {
        let len = dist2(&w[0], &w[1]).sqrt();
        if s <= s0 + len {
            return lerp(&w[0], &w[1], ((s - s0) / len).clamp(0.0, 1.0));
        }
        s0 += len;
    }
    line[line.len() - 1]
}

/// Cost of a chain vertex on top of its move ([`chain`]).
const CHAIN_VERTEX_COST: f64 = 0.1;
/// Shifts along the line (times the edge's length) tried for a chain vertex's point, in order
/// ([`chain`]).
const CHAIN_SHIFTS: [f64; 9] = [0.0, 0.15, -0.15, 0.3, -0.3, 0.45, -0.45, 0.6, -0.6];

/// An `f64` ordered by `total_cmp`, for the heap of [`chain`].
#[derive(Clone, Copy, Debug, PartialEq)]
struct Ord64(f64);
impl Eq for Ord64 {}
impl PartialOrd for Ord64 {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Ord64 {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// A line with one end placed (at `v`; no vertex could take the other) is walked from it as far
/// as it goes: the unmoved neighbour farther along the line and nearest it moves onto it, while
/// one can (gamma_f follows the solid's edge that far).
fn partial_chain<const D: usize>(
    bg: &Background<D>,
    neighbours: &[Vec<usize>],
    line: &[[f64; D]],
    mut v: usize,
    moves: &mut Vec<(usize, [f64; D])>,
    min_quality: f64,
) {
    let length: f64 = line.windows(2).map(|w| dist2(&w[0], &w[1]).sqrt()).sum();
    let mut s_v = 0.0;
    loop {
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
        let next =
            candidates.into_iter().find(|&(_, w, _, p)| super::boundary_move_ok(bg, w, &p) && super::corners::star_ok(bg, moves, w, &p, min_quality));
        match next {
            Some((_, w, s, p)) => {
                moves.push((w, p));
                (v, s_v) = (w, s);
            }
            None => return,
        }
    }
}

/// Moves of fluid vertices onto the feature vertices and lines of `surface` (see the module
/// documentation), and the number of feature vertices and lines left without them.
/// In 2D, the corners' moves ([`super::corners`]).
pub(crate) fn feature_moves<const D: usize>(bg: &Background<D>, surface: &Surface<D>, min_quality: f64) -> (Vec<(usize, [f64; D])>, usize) {
    let mut banned = HashSet::new();
    if D != 3 {
        return super::corners::corner_moves(bg, &super::corners::corners(surface), min_quality, &banned);
    }
    let f = features(surface);
    if f.lines.is_empty() && f.vertices.is_empty() {
        return (Vec::new(), 0);
    }
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); bg.mesh.points.len()];
    for e in &bg.topology.edges {
        neighbours[e[0]].push(e[1]);
        neighbours[e[1]].push(e[0]);
    }
    let mut best: Option<(Moves<D>, usize)> = None;
    for _ in 0..MAX_FEATURE_TRIES {
        let (moves, unplaced, stuck) = place_features(bg, &f, &neighbours, min_quality, &banned);
        if best.as_ref().is_none_or(|b| unplaced < b.1) {
            best = Some((moves, unplaced));
        }
        if unplaced == 0 || stuck.iter().all(|v| banned.contains(v)) {
            break;
        }
        banned.extend(stuck);
    }
    best.unwrap_or_default()
}

/// Vertex moves: the vertex and its new position.
type Moves<const D: usize> = Vec<(usize, [f64; D])>;

/// Placements of the feature vertices and lines tried at most ([`feature_moves`]).
const MAX_FEATURE_TRIES: usize = 6;

/// One placement of the feature vertices (not on the `banned` vertices) and lines of `f`: the
/// moves, the number of vertices and lines left without them, and the vertices at the ends of
/// the lines whose chain could not be found (to be banned in the next try: the vertex nearest
/// a block's corner can leave its neighbours no room to move onto the edges from it).
fn place_features<const D: usize>(
    bg: &Background<D>,
    f: &Features<D>,
    neighbours: &[Vec<usize>],
    min_quality: f64,
    banned: &HashSet<usize>,
) -> (Moves<D>, usize, Vec<usize>) {
    let (mut moves, mut unplaced) = super::corners::corner_moves(bg, &f.vertices, min_quality, banned);
    let mut stuck = Vec::new();
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
        let Some(v) = vertex_at(&moves, &first) else {
            unplaced += 1;
            continue;
        };
        let placed = match vertex_at(&moves, &last) {
            Some(end) => {
                let back: Vec<[f64; D]> = line.iter().rev().copied().collect();
                let placed =
                    chain(bg, neighbours, line, v, end, &mut moves, min_quality) || chain(bg, neighbours, &back, end, v, &mut moves, min_quality);
                if !placed {
                    stuck.extend([v, end]);
                }
                placed
            }
            None => {
                partial_chain(bg, neighbours, line, v, &mut moves, min_quality);
                false
            }
        };
        unplaced += !placed as usize;
    }
    (moves, unplaced, stuck)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube's sides and top, two triangles a face: its four vertical edges (each from a
    /// top corner to its end on the floor) and four top edges; the faces' diagonals are flat.
    #[test]
    fn an_open_box_has_eight_feature_lines_between_eight_feature_vertices_and_five_smooth_parts() {
        let p = |i: usize| [(i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64];
        let points: Vec<[f64; 3]> = (0..8).map(p).collect();
        let quads = [[0, 1, 5, 4], [1, 3, 7, 5], [3, 2, 6, 7], [2, 0, 4, 6], [4, 5, 7, 6]];
        let pieces: Vec<[usize; 3]> = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        // The same with one triangle of the top flipped: its diagonal is still flat.
        let mut flipped = pieces.clone();
        flipped[8].swap(1, 2);
        for pieces in [pieces, flipped] {
            let surface = Surface::from_pieces(points.clone(), pieces).unwrap();
            let f = features(&surface);
            assert_eq!(f.vertices.len(), 8);
            assert_eq!(f.lines.len(), 8);
            assert!(f.lines.iter().all(|l| l.len() == 2 && dist2(&l[0], &l[1]) == 1.0), "{:?}", f.lines);
            let vertical = f.lines.iter().filter(|l| l[0][2] != l[1][2]).count();
            assert_eq!(vertical, 4);
            // Five faces, two triangles each.
            assert_eq!(smooth_parts(&surface), vec![0, 0, 1, 1, 2, 2, 3, 3, 4, 4]);
            // A point inside a face, on an edge, at a corner.
            let at = |x: [f64; 3]| parts_at(&surface, &smooth_parts(&surface), &x, 1e-12);
            assert_eq!(at([0.5, 0.0, 0.3]), vec![0]);
            assert_eq!(at([1.0, 0.0, 0.3]), vec![0, 1]);
            assert_eq!(at([1.0, 1.0, 1.0]), vec![1, 2, 4]);
        }
    }
}
