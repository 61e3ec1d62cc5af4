//! The fluid cells a closed gamma_f encloses, removed from the adapted mesh.
//!
//! A thick solid wetted on its whole boundary lies over fluid cells that the adapted mesh
//! separates from the rest by gamma_f (with the domain boundary, where the solid is fixed to a
//! wall). Kept, that fictitious fluid is incompressible: its area cannot change, so it would hold
//! a compressible solid's area fixed too. [`remove_enclosed`] removes those cells instead: the
//! region on the solid side of gamma_f (the side its normal points away from), found by a flood
//! fill from the cells on that side across every facet that is not on gamma_f. If the fill
//! reaches the fluid side of gamma_f, gamma_f does not enclose the solid (a slender solid
//! coupled on one face, or a gap where gamma_s meets a wall) and nothing is removed: that is an
//! error ([`AdaptError::NotEnclosed`]), since the covered fluid cannot be told apart.
//!
//! Unless gamma_s itself is closed (with the domain boundary) and the adapted mesh follows it
//! where the facet rules left the hole (a 3D edge bent or crossed so that a facet on it spans
//! two faces, a sliver along a feature line): then the cells are told apart by the side of
//! gamma_s they lie on instead ([`Surface::side`] at the vertices off gamma_s of the cells
//! touching it, or at their centroids where all their vertices are on it; a flood fill from
//! those for the other cells, far from gamma_s, where its nearest point does not tell the
//! side), and gamma_f is rebuilt as the facets between the two sides, each checked to lie on
//! gamma_s as a gamma_f facet must
//! ([`AdaptStats::cells_by_side`](super::AdaptStats::cells_by_side) counts the cells so told).
//! An open gamma_s (not closed by the domain boundary) has no sides: beyond its open end the
//! side of its nearest point flips across a line off it, where cells on the two sides meet at
//! facets that are not on gamma_s, and the error stands.

use super::gap::without_cells;
use super::geom::{dot, sub};
use super::surface::piece_normal;
use super::{dist2, AdaptError, Adapted, GammaFacet, Surface, GAMMA_F_REL_TOL};
use crate::mesh::{Mesh, Topology, NO_CELL};
use std::collections::{HashMap, HashSet};

/// The adapted mesh without the cells gamma_f encloses (see the module documentation): cells,
/// vertices and boundary facets renumbered in their old order, gamma_f seen from the fluid side
/// only (its solid side [`NO_CELL`]; facets with fluid on neither side, where the solid lies on
/// the domain boundary, dropped), [`super::AdaptStats::removed_cells`] set. The mesh no longer
/// fills the original domain, so [`super::verify_adapted`]'s measure check does not apply.
/// `surface` is the gamma_s `adapted` was adapted to.
pub fn remove_enclosed<const D: usize>(adapted: Adapted<D>, surface: &Surface<D>) -> Result<Adapted<D>, AdaptError> {
    let topology = Topology::build(&adapted.mesh);
    let (enclosed, rebuilt) = match enclosed_cells(&adapted, &topology) {
        Ok(enclosed) => (enclosed, None),
        Err(leak @ AdaptError::NotEnclosed(_)) => match cells_by_side(&adapted, &topology, surface) {
            Some(BySide { solid, gamma_f, told }) if !solid.is_empty() => (solid, Some((gamma_f, told))),
            _ => return Err(leak),
        },
        Err(e) => return Err(e),
    };
    if enclosed.is_empty() {
        return Ok(adapted);
    }
    let mut adapted = adapted;
    if let Some((rebuilt, told)) = rebuilt {
        adapted.stats.cells_by_side = told;
        adapted.stats.coupling_facets = rebuilt.len();
        adapted.gamma_f = rebuilt;
    }
    let nc = adapted.mesh.num_cells();
    let mut out = without_cells(adapted, &enclosed, None);
    out.stats.removed_cells = nc - out.mesh.num_cells();
    Ok(out)
}

/// The mean of `points` of `mesh`.
pub(super) fn centroid<const D: usize>(mesh: &Mesh<D>, points: &[usize]) -> [f64; D] {
    std::array::from_fn(|d| points.iter().map(|&p| mesh.points[p][d]).sum::<f64>() / points.len() as f64)
}

/// The cells on the solid side of gamma_f, by flood fill (see the module documentation).
fn enclosed_cells<const D: usize>(adapted: &Adapted<D>, topology: &Topology) -> Result<HashSet<usize>, AdaptError> {
    let mesh = &adapted.mesh;
    let ct = mesh.cell_type;
    let mut barrier: HashSet<usize> = HashSet::new();
    let mut fluid_side: HashSet<usize> = HashSet::new();
    let mut stack: Vec<usize> = Vec::new();
    for g in &adapted.gamma_f {
        if let Some(&(c, j)) = g.sides.iter().find(|&&s| s != NO_CELL) {
            barrier.insert(topology.facet(ct, c, j));
        }
        if g.sides[0] != NO_CELL {
            stack.push(g.sides[0].0);
        }
        if g.sides[1] != NO_CELL {
            fluid_side.insert(g.sides[1].0);
        }
    }
    let mut enclosed: HashSet<usize> = HashSet::new();
    while let Some(c) = stack.pop() {
        if !enclosed.insert(c) {
            continue;
        }
        if fluid_side.contains(&c) {
            return Err(AdaptError::NotEnclosed(mesh.vertex_centroid(c).to_vec()));
        }
        for j in 0..ct.num_facets() {
            if !barrier.contains(&topology.facet(ct, c, j)) {
                stack.extend(topology.neighbour(ct, c, j).filter(|n| !enclosed.contains(n)));
            }
        }
    }
    Ok(enclosed)
}

/// Does cell `c`, with a vertex on gamma_s, lie on the solid side ([`Surface::side`]
/// negative)? Its vertices off gamma_s tell (`vertex_side` caches their sides): a cell of a mesh
/// that follows gamma_s lies on one side, and the vertex is farther from gamma_s than its
/// centroid may be (a thin cell along a face curved away from the solid, three vertices on it,
/// has its centroid outside a chord that bulges out beyond the face). A cell with vertices on
/// both sides crosses gamma_s: `None`. Where all its vertices lie on gamma_s (within round-off
/// of the cell's size), its centroid tells: a cell filling a solid's edge lies inside, a flat
/// cell along a face either way.
fn on_solid_side<const D: usize>(
    mesh: &Mesh<D>,
    c: usize,
    on_surface: &[bool],
    surface: &Surface<D>,
    vertex_side: &mut HashMap<usize, f64>,
) -> Option<bool> {
    let vertices = mesh.cell_vertices(c);
    let round_off = 1e-9 * diameter(mesh, vertices);
    let mut sides = vertices
        .iter()
        .filter(|&&v| !on_surface[v])
        .map(|&v| *vertex_side.entry(v).or_insert_with(|| surface.side(&mesh.points[v]).unwrap_or(0.0)))
        .filter(|s| s.abs() > round_off);
    match sides.next() {
        Some(first) => sides.all(|s| (s < 0.0) == (first < 0.0)).then_some(first < 0.0),
        None => Some(surface.side(&centroid(mesh, vertices)).is_some_and(|s| s < 0.0)),
    }
}

/// Largest distance between two of `points`.
fn diameter<const D: usize>(mesh: &Mesh<D>, points: &[usize]) -> f64 {
    points.iter().flat_map(|&a| points.iter().map(move |&b| dist2(&mesh.points[a], &mesh.points[b]))).fold(0.0, f64::max).sqrt()
}

/// Does the facet with `vertices` lie on gamma_s as a gamma_f facet must: its vertices on it,
/// its centroid within [`GAMMA_F_REL_TOL`] times its diameter of it?
fn lies_on_gamma_s<const D: usize>(mesh: &Mesh<D>, vertices: &[usize], on_surface: &[bool], surface: &Surface<D>) -> bool {
    vertices.iter().all(|&v| on_surface[v])
        && surface.project(&centroid(mesh, vertices)).is_some_and(|sp| sp.distance <= GAMMA_F_REL_TOL * diameter(mesh, vertices))
}

/// Facet `j` of cell `c`'s vertices, ordered so that their right-hand normal points away from
/// `x` (a point on one side of the facet).
fn facing_away_from<const D: usize>(mesh: &Mesh<D>, (c, j): (usize, usize), x: &[f64; D]) -> [usize; D] {
    let mut vertices: [usize; D] = std::array::from_fn(|k| mesh.cell(c)[mesh.cell_type.facet(j)[k]]);
    let pts = vertices.map(|v| mesh.points[v]);
    if dot(&piece_normal(&pts), &sub(&centroid(mesh, &vertices), x)) < 0.0 {
        vertices.swap(0, 1);
    }
    vertices
}

/// The cells on the solid side told by the side of gamma_s they lie on, and gamma_f rebuilt
/// between them ([`cells_by_side`]).
struct BySide<const D: usize> {
    solid: HashSet<usize>,
    gamma_f: Vec<GammaFacet<D>>,
    /// Cells told by [`Surface::side`] (those with a vertex on gamma_s).
    told: usize,
}

/// Where gamma_f is open (see the module documentation): a cell with a vertex on gamma_s lies
/// on the side of gamma_s its other vertices, or where it has none its centroid, lie on
/// ([`on_solid_side`]); a cell with no vertex on gamma_s lies wholly on one side and takes the
/// side of the cells it connects to (a flood fill through the cells with no vertex on gamma_s,
/// far from which [`Surface::side`] is not asked: beyond the open end of a bar's gamma_s, where
/// the domain boundary closes it, the side of the nearest point does not tell). gamma_f is the
/// facets between the two sides, its normal out of the solid, and those on the domain boundary
/// with fluid on one side that lie on gamma_s (the solid outside the domain). `None` where the
/// fill reaches a cell from both sides, a cell has vertices on both sides, or a facet between
/// the sides does not lie on gamma_s ([`lies_on_gamma_s`]): there the adapted mesh does not
/// follow gamma_s, or gamma_s is open.
fn cells_by_side<const D: usize>(adapted: &Adapted<D>, topology: &Topology, surface: &Surface<D>) -> Option<BySide<D>> {
    let mesh = &adapted.mesh;
    let ct = mesh.cell_type;
    let nc = mesh.num_cells();
    let touches = |c: usize| mesh.cell_vertices(c).iter().any(|&v| adapted.on_surface[v]);
    let mut solid_side: Vec<Option<bool>> = vec![None; nc];
    let mut told = 0;
    let mut vertex_side: HashMap<usize, f64> = HashMap::new();
    for c in (0..nc).filter(|&c| touches(c)) {
        solid_side[c] = Some(on_solid_side(mesh, c, &adapted.on_surface, surface, &mut vertex_side)?);
        told += 1;
    }
    let mut stack: Vec<usize> = (0..nc).filter(|&c| solid_side[c].is_some()).collect();
    while let Some(c) = stack.pop() {
        let side = solid_side[c];
        for j in 0..ct.num_facets() {
            if let Some(n) = topology.neighbour(ct, c, j) {
                match solid_side[n] {
                    None => {
                        solid_side[n] = side;
                        stack.push(n);
                    }
                    Some(s) if Some(s) != side && !touches(n) => return None,
                    _ => {}
                }
            }
        }
    }
    let is_solid = |c: usize| solid_side[c] == Some(true);
    let mut gamma_f = Vec::new();
    for &[a, b] in &topology.facet_cells {
        let vertices: [usize; D] = std::array::from_fn(|k| mesh.cell(a.0)[ct.facet(a.1)[k]]);
        let (sides, vertices) = if b == NO_CELL {
            // On the domain boundary: wetted where the solid lies outside the domain.
            if is_solid(a.0) || !lies_on_gamma_s(mesh, &vertices, &adapted.on_surface, surface) {
                continue;
            }
            let mut into_the_fluid = facing_away_from(mesh, a, &mesh.vertex_centroid(a.0));
            into_the_fluid.swap(0, 1);
            ([NO_CELL, a], into_the_fluid)
        } else if is_solid(a.0) != is_solid(b.0) {
            let (inner, outer) = if is_solid(a.0) { (a, b) } else { (b, a) };
            if !lies_on_gamma_s(mesh, &vertices, &adapted.on_surface, surface) {
                return None;
            }
            ([inner, outer], facing_away_from(mesh, inner, &mesh.vertex_centroid(inner.0)))
        } else {
            continue;
        };
        let location = vertices.map(|v| surface.project(&mesh.points[v]).expect("gamma_s has pieces"));
        gamma_f.push(GammaFacet { vertices, sides, location });
    }
    let solid = (0..nc).filter(|&c| is_solid(c)).collect();
    Some(BySide { solid, gamma_f, told })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adapt::{adapt, Surface};
    use crate::generate::{rectangle_triangles, DiagonalPattern};

    /// The 7 x 7 unit square and, counter-clockwise (outward normals), the rectangle
    /// `[0.33, 0.71] x [y0, y1]`, not aligned with the mesh (on the floor for `y0 = 0`).
    fn square([y0, y1]: [f64; 2]) -> (crate::mesh::Mesh<2>, Surface<2>) {
        let m = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 7, 7, DiagonalPattern::Alternating);
        let corners = vec![[0.33, y0], [0.71, y0], [0.71, y1], [0.33, y1]];
        (m, Surface::from_pieces(corners, vec![[0, 1], [1, 2], [2, 3], [3, 0]]).unwrap())
    }

    fn area(mesh: &crate::mesh::Mesh<2>) -> f64 {
        (0..mesh.num_cells()).map(|c| mesh.signed_vertex_measure(c)).sum()
    }

    #[test]
    fn removes_exactly_the_square_a_closed_surface_encloses() {
        let (m, s) = square([0.31, 0.69]);
        let a = adapt(&m, &s, 0.2).unwrap();
        assert_eq!(a.stats.corner_nodes, 4);
        assert!((a.gamma_f_measure() - 4.0 * 0.38).abs() < 1e-14, "{}", a.gamma_f_measure());
        let cells = a.mesh.num_cells();
        let r = remove_enclosed(a, &s).unwrap();
        r.mesh.check().unwrap();
        assert_eq!(r.stats.removed_cells, cells - r.mesh.num_cells());
        assert!((area(&r.mesh) - (1.0 - 0.38 * 0.38)).abs() < 1e-14, "{}", area(&r.mesh));
        assert!((r.gamma_f_measure() - 4.0 * 0.38).abs() < 1e-14);
        // gamma_f is seen from the fluid (plus) side only; every vertex is used.
        assert!(r.gamma_f.iter().all(|g| g.sides[0] == NO_CELL && g.sides[1] != NO_CELL));
        let mut used = vec![false; r.mesh.points.len()];
        r.mesh.cell_nodes.iter().for_each(|&p| used[p] = true);
        assert!(used.iter().all(|&u| u));
        assert!(r.gamma_f.iter().all(|g| g.vertices.iter().all(|&v| r.on_surface[v])), "gamma_f's vertices are on gamma_s");
        assert_eq!(r.on_surface.iter().filter(|&&f| f).count(), r.gamma_f.len(), "a closed chain: as many vertices as facets");
    }

    /// The square of [`removes_exactly_the_square_a_closed_surface_encloses`] with one facet
    /// taken out of gamma_f, as where the facet rules miss one: the cells are told by their side
    /// of gamma_s, and gamma_f is whole again, oriented out of the square.
    #[test]
    fn a_hole_in_gamma_f_is_closed_by_the_sides_of_gamma_s() {
        let (m, s) = square([0.31, 0.69]);
        let mut a = adapt(&m, &s, 0.2).unwrap();
        let facets = a.gamma_f.len();
        a.gamma_f.remove(3);
        let r = remove_enclosed(a, &s).unwrap();
        r.mesh.check().unwrap();
        assert!(r.stats.cells_by_side > 0);
        assert_eq!((r.gamma_f.len(), r.stats.coupling_facets), (facets, facets));
        assert!((area(&r.mesh) - (1.0 - 0.38 * 0.38)).abs() < 1e-14, "{}", area(&r.mesh));
        assert!((r.gamma_f_measure() - 4.0 * 0.38).abs() < 1e-14);
        for g in &r.gamma_f {
            assert!(g.sides[0] == NO_CELL && g.sides[1] != NO_CELL);
            let [a, b] = g.vertices.map(|v| r.mesh.points[v]);
            let normal = crate::adapt::surface::piece_normal(&[a, b]);
            let out = [0.5 * (a[0] + b[0]) - 0.52, 0.5 * (a[1] + b[1]) - 0.5];
            assert!(normal[0] * out[0] + normal[1] * out[1] > 0.0, "{g:?}");
            assert!(g.location.iter().all(|l| l.distance < 1e-14), "{g:?}");
        }
    }

    /// Where the adapted mesh does not follow gamma_s, a facet between the two sides is not on
    /// it, and the hole stays an error: here a vertex of the facet taken out of gamma_f is
    /// taken off gamma_s, either as not on it or moved 0.6 cells outward (the facets beside it
    /// then lie 0.3-0.4 of their length off gamma_s).
    #[test]
    fn a_facet_between_the_sides_off_gamma_s_leaves_the_hole() {
        let (m, s) = square([0.31, 0.69]);
        for moved in [false, true] {
            let mut a = adapt(&m, &s, 0.2).unwrap();
            let hole = a.gamma_f.remove(3);
            let v = hole.vertices[0];
            if moved {
                let sp = s.project(&a.mesh.points[v]).unwrap();
                let n = s.normal(sp.piece);
                a.mesh.points[v] = std::array::from_fn(|d| a.mesh.points[v][d] + 0.6 / 7.0 * n[d]);
            } else {
                a.on_surface[v] = false;
            }
            assert!(matches!(remove_enclosed(a, &s), Err(AdaptError::NotEnclosed(_))), "moved {moved}");
        }
    }

    /// [`a_side_on_the_domain_boundary_is_not_wetted`] with a facet taken out of gamma_f: the
    /// sides close it, and the side on the floor stays dry.
    #[test]
    fn a_hole_beside_the_domain_boundary_is_closed_by_the_sides() {
        let (m, s) = square([0.0, 0.69]);
        let mut a = adapt(&m, &s, 0.2).unwrap();
        let hole = a.gamma_f.iter().position(|g| g.sides.iter().all(|&c| c != NO_CELL)).unwrap();
        a.gamma_f.remove(hole);
        let r = remove_enclosed(a, &s).unwrap();
        r.mesh.check().unwrap();
        assert!(r.stats.cells_by_side > 0);
        assert!((r.gamma_f_measure() - (0.38 + 2.0 * 0.69)).abs() < 1e-14, "{}", r.gamma_f_measure());
        assert!((area(&r.mesh) - (1.0 - 0.38 * 0.69)).abs() < 1e-14);
    }

    #[test]
    fn a_side_on_the_domain_boundary_is_not_wetted() {
        // A block standing on the floor, gamma_s all four sides (its bottom on the floor).
        let (m, s) = square([0.0, 0.69]);
        let a = adapt(&m, &s, 0.2).unwrap();
        let r = remove_enclosed(a, &s).unwrap();
        r.mesh.check().unwrap();
        assert!((r.gamma_f_measure() - (0.38 + 2.0 * 0.69)).abs() < 1e-14, "{}", r.gamma_f_measure());
        assert!((area(&r.mesh) - (1.0 - 0.38 * 0.69)).abs() < 1e-14);
    }

    #[test]
    fn an_open_surface_is_not_enclosed() {
        let m = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 7, 7, DiagonalPattern::Alternating);
        let open = vec![[0.33, 0.31], [0.71, 0.31], [0.71, 0.69]];
        let s = Surface::from_polyline(open).unwrap();
        let a = adapt(&m, &s, 0.2).unwrap();
        assert!(matches!(remove_enclosed(a, &s), Err(AdaptError::NotEnclosed(_))));
    }
}
