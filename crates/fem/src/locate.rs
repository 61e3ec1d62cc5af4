//! Point location in simplex meshes.
//!
//! [`locate_point`] finds a cell containing a physical point and the point's reference
//! coordinates, through the affine map of the cell's vertices (exact for straight cells; for
//! curved boundary cells the straight-sided approximation is used). A linear scan: fine for the
//! handful of probes of a run; the per-step transfer between adapted meshes uses a spatial index.

use crate::element::ReferenceCell;
use crate::mesh::Mesh;

/// Reference coordinates of `x` in the straight simplex with vertices `v` (barycentric
/// `l_1..l_D`), or `None` for a degenerate cell.
pub fn simplex_reference_coords<const D: usize>(v: &[[f64; D]], x: &[f64; D]) -> Option<[f64; D]> {
    let mut jac = [[0.0; D]; D];
    for a in 0..D {
        for b in 0..D {
            jac[a][b] = v[b + 1][a] - v[0][a];
        }
    }
    let (det, inv) = crate::values::det_inv(&jac);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let mut xi = [0.0; D];
    for a in 0..D {
        for b in 0..D {
            xi[a] += inv[a][b] * (x[b] - v[0][b]);
        }
    }
    Some(xi)
}

/// A cell containing `x` (within relative tolerance `1e-10`) and the reference coordinates of
/// `x` in it.
pub fn locate_point<const D: usize>(mesh: &Mesh<D>, x: &[f64; D]) -> Option<(usize, [f64; D])> {
    cells_containing(mesh, x).into_iter().next()
}

/// Every cell containing `x` (several when `x` lies on a facet, edge or vertex), with the
/// reference coordinates of `x` in each.
pub fn cells_containing<const D: usize>(mesh: &Mesh<D>, x: &[f64; D]) -> Vec<(usize, [f64; D])> {
    if !matches!(mesh.cell_type, ReferenceCell::Triangle | ReferenceCell::Tetrahedron) {
        return Vec::new();
    }
    let tol = 1e-10;
    let mut v = [[0.0; D]; 4];
    let mut out = Vec::new();
    for c in 0..mesh.num_cells() {
        for (k, &n) in mesh.cell_vertices(c).iter().enumerate() {
            v[k] = mesh.points[n];
        }
        if let Some(xi) = simplex_reference_coords(&v[..=D], x) {
            let l0 = 1.0 - xi.iter().sum::<f64>();
            if l0 >= -tol && xi.iter().all(|&l| l >= -tol) {
                out.push((c, xi));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{rectangle_triangles, DiagonalPattern};

    #[test]
    fn finds_the_cell_and_reference_coordinates() {
        let m = rectangle_triangles(0.0, 2.0, 0.0, 1.0, 4, 2, DiagonalPattern::Alternating);
        let x = [1.3, 0.7];
        let (c, xi) = locate_point(&m, &x).unwrap();
        // Map back.
        let v: Vec<[f64; 2]> = m.cell_vertices(c).iter().map(|&n| m.points[n]).collect();
        let back = [0, 1].map(|d| v[0][d] + xi[0] * (v[1][d] - v[0][d]) + xi[1] * (v[2][d] - v[0][d]));
        assert!((back[0] - x[0]).abs() < 1e-14 && (back[1] - x[1]).abs() < 1e-14);
        assert!(locate_point(&m, &[3.0, 0.5]).is_none());
    }
}
