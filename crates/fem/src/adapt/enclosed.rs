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

use super::{AdaptError, Adapted, GammaFacet};
use crate::mesh::{BoundaryFacet, NO_CELL};
use std::collections::{HashMap, HashSet};

/// The adapted mesh without the cells gamma_f encloses (see the module documentation): cells,
/// vertices and boundary facets renumbered in their old order, gamma_f seen from the fluid side
/// only (its solid side [`NO_CELL`]; facets with fluid on neither side, where the solid lies on
/// the domain boundary, dropped), [`super::AdaptStats::removed_cells`] set. The mesh no longer
/// fills the original domain, so [`super::verify_adapted`]'s measure check does not apply.
pub fn remove_enclosed<const D: usize>(adapted: Adapted<D>) -> Result<Adapted<D>, AdaptError> {
    let enclosed = enclosed_cells(&adapted)?;
    if enclosed.is_empty() {
        return Ok(adapted);
    }
    let Adapted { mesh, new_to_old_cell, on_surface, gamma_f, mut stats } = adapted;
    let nc = mesh.num_cells();
    let npc = mesh.nodes_per_cell();
    let mut new_cell = vec![usize::MAX; nc];
    let mut kept = 0;
    for (c, slot) in new_cell.iter_mut().enumerate() {
        if !enclosed.contains(&c) {
            *slot = kept;
            kept += 1;
        }
    }
    // Points of kept cells, numbered in their old order.
    let mut new_point = vec![usize::MAX; mesh.points.len()];
    for c in (0..nc).filter(|&c| new_cell[c] != usize::MAX) {
        for &p in mesh.cell(c) {
            new_point[p] = 0;
        }
    }
    let mut out = mesh.clone();
    out.points.clear();
    for (p, slot) in new_point.iter_mut().enumerate().filter(|(_, s)| **s == 0) {
        *slot = out.points.len();
        out.points.push(mesh.points[p]);
    }
    out.cell_nodes.clear();
    out.cell_tags.clear();
    for c in (0..nc).filter(|&c| new_cell[c] != usize::MAX) {
        out.cell_nodes.extend(mesh.cell(c).iter().map(|&p| new_point[p]));
        out.cell_tags.push(mesh.cell_tags[c]);
    }
    debug_assert_eq!(out.cell_nodes.len(), kept * npc);
    out.boundary = mesh.boundary.iter().filter(|b| new_cell[b.cell] != usize::MAX).map(|b| BoundaryFacet { cell: new_cell[b.cell], ..*b }).collect();
    let renumber_side = |(c, f): (usize, usize)| if c == usize::MAX || new_cell[c] == usize::MAX { NO_CELL } else { (new_cell[c], f) };
    // A gamma_f facet with no fluid left on either side (a side of the solid on the domain
    // boundary) is not wetted: it is dropped.
    let gamma_f = gamma_f
        .into_iter()
        .map(|g| GammaFacet { vertices: g.vertices.map(|v| new_point[v]), sides: g.sides.map(renumber_side), location: g.location })
        .filter(|g| g.sides.iter().any(|&s| s != NO_CELL))
        .collect();
    let on_surface = (0..mesh.points.len()).filter(|&p| new_point[p] != usize::MAX).map(|p| on_surface[p]).collect();
    let new_to_old_cell = (0..nc).filter(|&c| new_cell[c] != usize::MAX).map(|c| new_to_old_cell[c]).collect();
    stats.removed_cells = nc - kept;
    Ok(Adapted { mesh: out, new_to_old_cell, on_surface, gamma_f, stats })
}

/// The cells on the solid side of gamma_f, by flood fill (see the module documentation).
fn enclosed_cells<const D: usize>(adapted: &Adapted<D>) -> Result<HashSet<usize>, AdaptError> {
    let mesh = &adapted.mesh;
    let ct = mesh.cell_type;
    let key = |c: usize, j: usize| -> [usize; 3] {
        let mut k = [usize::MAX; 3];
        for (i, &l) in ct.facet(j).iter().enumerate() {
            k[i] = mesh.cell(c)[l];
        }
        k[..D].sort_unstable();
        k
    };
    let mut facet_cells: HashMap<[usize; 3], Vec<usize>> = HashMap::new();
    for c in 0..mesh.num_cells() {
        for j in 0..ct.num_facets() {
            facet_cells.entry(key(c, j)).or_default().push(c);
        }
    }
    let mut barrier: HashSet<[usize; 3]> = HashSet::new();
    let mut fluid_side: HashSet<usize> = HashSet::new();
    let mut stack: Vec<usize> = Vec::new();
    for g in &adapted.gamma_f {
        let mut k = [usize::MAX; 3];
        k[..D].copy_from_slice(&g.vertices);
        k[..D].sort_unstable();
        barrier.insert(k);
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
            let v = mesh.cell_vertices(c);
            let centroid = (0..D).map(|d| v.iter().map(|&p| mesh.points[p][d]).sum::<f64>() / v.len() as f64).collect();
            return Err(AdaptError::NotEnclosed(centroid));
        }
        for j in 0..ct.num_facets() {
            let k = key(c, j);
            if !barrier.contains(&k) {
                stack.extend(facet_cells[&k].iter().copied().filter(|n| !enclosed.contains(n)));
            }
        }
    }
    Ok(enclosed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adapt::{adapt, Surface};
    use crate::generate::{rectangle_triangles, DiagonalPattern};

    fn area(mesh: &crate::mesh::Mesh<2>) -> f64 {
        (0..mesh.num_cells()).map(|c| mesh.signed_vertex_measure(c)).sum()
    }

    #[test]
    fn removes_exactly_the_square_a_closed_surface_encloses() {
        // A square not aligned with the 7 x 7 mesh, counter-clockwise (outward normals).
        let m = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 7, 7, DiagonalPattern::Alternating);
        let square = vec![[0.33, 0.31], [0.71, 0.31], [0.71, 0.69], [0.33, 0.69]];
        let a = adapt(&m, &Surface::from_pieces(square, vec![[0, 1], [1, 2], [2, 3], [3, 0]]).unwrap(), 0.2).unwrap();
        assert_eq!(a.stats.corner_nodes, 4);
        assert!((a.gamma_f_measure() - 4.0 * 0.38).abs() < 1e-14, "{}", a.gamma_f_measure());
        let cells = a.mesh.num_cells();
        let r = remove_enclosed(a).unwrap();
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

    #[test]
    fn a_side_on_the_domain_boundary_is_not_wetted() {
        // A block standing on the floor, gamma_s all four sides (its bottom on the floor).
        let m = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 7, 7, DiagonalPattern::Alternating);
        let block = vec![[0.33, 0.0], [0.71, 0.0], [0.71, 0.69], [0.33, 0.69]];
        let a = adapt(&m, &Surface::from_pieces(block, vec![[0, 1], [1, 2], [2, 3], [3, 0]]).unwrap(), 0.2).unwrap();
        let r = remove_enclosed(a).unwrap();
        r.mesh.check().unwrap();
        assert!((r.gamma_f_measure() - (0.38 + 2.0 * 0.69)).abs() < 1e-14, "{}", r.gamma_f_measure());
        assert!((area(&r.mesh) - (1.0 - 0.38 * 0.69)).abs() < 1e-14);
    }

    #[test]
    fn an_open_surface_is_not_enclosed() {
        let m = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 7, 7, DiagonalPattern::Alternating);
        let open = vec![[0.33, 0.31], [0.71, 0.31], [0.71, 0.69]];
        let a = adapt(&m, &Surface::from_polyline(open).unwrap(), 0.2).unwrap();
        assert!(matches!(remove_enclosed(a), Err(AdaptError::NotEnclosed(_))));
    }
}
