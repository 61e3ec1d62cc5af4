//! Step 3: subdivision of a cell by the set of its edges that got a new node.
//!
//! Templates are built by **successive edge bisection**: the split edges are taken one at a time
//! in a given order, and every current sub-simplex that contains the whole edge `(i, j)` is
//! replaced by its two halves, the one with `i` replaced by the new node `m` and the one with
//! `j` replaced by `m`. Replacing a vertex by a point of an incident edge keeps the orientation,
//! and the halves' measures are `(1 - s)` and `s` times the parent's (`m = i + s (j - i)`), so
//! the sub-simplices are positive, tile the parent and their measures add up to the parent's.
//! The numbers of children are the paper's: a triangle gives 2, 3 or 4 triangles for 1, 2 or 3
//! split edges; a tetrahedron gives 2 for one split edge (fig. 3a), 3 for two edges sharing a
//! vertex (fig. 3b), 4 for three edges around a vertex (a flat cut separating one vertex,
//! fig. 3c/d) and 6 for four edges (a flat cut separating two vertices, a quadrilateral section,
//! fig. 3e); other patterns (two opposite edges, five or six edges), which a flat cut does not
//! produce, give more (tested for all 63 patterns: positive children that tile the parent). No
//! interior (Steiner) point is ever
//! needed.
//!
//! **Conformity.** Splitting an edge that is not in a face leaves that face's triangles
//! untouched, so the triangulation a face gets depends only on the order in which its own
//! split edges are taken. In 3D that order is global (see [`super::adapt_with`]: longest edge
//! first, ties by global edge number), so two tetrahedra sharing a face split it the same way.
//! In 2D a face is the cell itself, and the order is chosen per cell: of all orders of its split
//! edges (at most 3! = 6) the one whose worst triangle has the largest minimum angle (for two
//! split edges this is the choice of the quadrilateral's diagonal).
//!
//! **gamma_s and the templates.** After all splits, a sub-simplex contains an edge between two
//! original vertices only if that edge was not split; so when every edge crossing gamma_s has
//! been split (or had an end point moved onto gamma_s), no sub-simplex has original vertices on
//! both sides of a flat gamma_s, and the section of the parent by gamma_s is a union of
//! sub-facets: gamma_f.
//!
//! Labels: `0..=D` are the parent's vertices, `D + 1 + k` the new node on local edge `k`.

use crate::element::ReferenceCell;

/// Children of a simplex of dimension `dim` split along the local edges `order` (in that order),
/// as label lists (`dim + 1` entries used).
pub(crate) fn bisect(cell: ReferenceCell, order: &[usize]) -> Vec<[usize; 4]> {
    let dim = cell.dim();
    let mut out: Vec<[usize; 4]> = vec![[0, 1, 2, 3]];
    let edges = cell.edges();
    for &k in order {
        let [i, j] = edges[k];
        let m = dim + 1 + k;
        let mut next = Vec::with_capacity(out.len() * 2);
        for s in out {
            let pi = s[..=dim].iter().position(|&l| l == i);
            let pj = s[..=dim].iter().position(|&l| l == j);
            match (pi, pj) {
                (Some(pi), Some(pj)) => {
                    let mut a = s;
                    a[pi] = m;
                    let mut b = s;
                    b[pj] = m;
                    next.push(a);
                    next.push(b);
                }
                _ => next.push(s),
            }
        }
        out = next;
    }
    out
}

/// Does label `l` lie on local facet `f` of the parent (a facet vertex, or a new node on an edge
/// with both ends in the facet)?
pub(crate) fn label_on_facet(cell: ReferenceCell, l: usize, f: usize) -> bool {
    let fv = cell.facet(f);
    let nv = cell.num_vertices();
    if l < nv {
        fv.contains(&l)
    } else {
        let [a, b] = cell.edges()[l - nv];
        fv.contains(&a) && fv.contains(&b)
    }
}

/// All orders of the items of `v` (at most 6 here).
pub(crate) fn permutations(v: &[usize]) -> Vec<Vec<usize>> {
    if v.len() <= 1 {
        return vec![v.to_vec()];
    }
    let mut out = Vec::new();
    for i in 0..v.len() {
        let mut rest = v.to_vec();
        let x = rest.remove(i);
        for mut p in permutations(&rest) {
            p.insert(0, x);
            out.push(p);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adapt::geom::simplex_measure;

    fn label_coords(l: usize) -> [f64; 3] {
        let v = ReferenceCell::Tetrahedron.vertices();
        if l < 4 {
            v[l]
        } else {
            let [a, b] = ReferenceCell::Tetrahedron.edges()[l - 4];
            let s = 0.3 + 0.05 * l as f64;
            std::array::from_fn(|d| v[a][d] + s * (v[b][d] - v[a][d]))
        }
    }

    #[test]
    fn every_tetrahedron_pattern_tiles_the_parent() {
        for mask in 1u32..64 {
            let split: Vec<usize> = (0..6).filter(|k| mask & (1 << k) != 0).collect();
            for order in permutations(&split).into_iter().take(3) {
                let kids = bisect(ReferenceCell::Tetrahedron, &order);
                let mut total = 0.0;
                for k in &kids {
                    let v: Vec<[f64; 3]> = k.iter().map(|&l| label_coords(l)).collect();
                    let m = simplex_measure(&v);
                    assert!(m > 0.0, "mask {mask} order {order:?}");
                    total += m;
                }
                assert!((total - 1.0 / 6.0).abs() < 1e-15);
                if split.len() == 1 {
                    assert_eq!(kids.len(), 2);
                }
            }
        }
    }

    #[test]
    fn paper_counts() {
        // Plane cutting off vertex 0 (edges 0-1, 0-2, 0-3 = local edges 0, 2, 3): 4 tets.
        assert_eq!(bisect(ReferenceCell::Tetrahedron, &[0, 2, 3]).len(), 4);
        // Plane separating {0,1} from {2,3}: edges 1-2, 2-0, 0-3, 1-3 (1, 2, 3, 4): 6 tets.
        assert_eq!(bisect(ReferenceCell::Tetrahedron, &[1, 2, 3, 4]).len(), 6);
        assert_eq!(bisect(ReferenceCell::Triangle, &[0, 1]).len(), 3);
        assert_eq!(bisect(ReferenceCell::Triangle, &[0, 1, 2]).len(), 4);
    }
}
