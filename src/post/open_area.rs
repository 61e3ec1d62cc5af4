//! The geometric orifice area of a valve (3D FSI runs, `[output.open_area]`): the area of the
//! section of the fluid mesh by a plane across the flow, `x_a = at`, that the solid, seen along
//! the axis `a`, leaves open:
//!
//! ```text
//! A_open = | S \ P(gamma_s) |,    S = { y in the plane : (y, at) in the fluid mesh },
//! ```
//!
//! `P` the projection along `a` onto the plane. This is the area an echocardiographer traces on
//! a short-axis view (planimetry): the opening the leaflets leave, wherever along the axis they
//! are.
//!
//! Both sets are rasterised on one grid of `RESOLUTION x RESOLUTION` cells over the bounding box
//! of `S`: a grid point is in `S` when it lies in the section (a triangle or quadrilateral) of a
//! fluid cell, and covered when it lies in the projection of a piece of gamma_s. The area is
//! the count of points in `S` and not covered, times the grid cell's area: exact to the
//! rasterisation, whose error is about the length of the boundaries of both sets times the grid
//! spacing (`tests` below: the unit square less a triangle to 2 / RESOLUTION, and a plane
//! through a layer of faces; `tests/cases.rs`: the valve sector at rest to 0.1 % of an
//! independent computation, meshes/valve_3d_open_area.py). A plane through faces of the mesh
//! takes each face once, from the cell below it. No crate rasterises
//! polygons onto a bit grid without pulling in an image stack; the scan below is twenty lines.

use fdfsi_fem::mesh::Mesh;

/// Grid cells along each side of the section's bounding box.
pub const RESOLUTION: usize = 1500;

/// The open area of the section of `fluid` (its cells' vertices: straight cells) by the plane
/// `x[axis] = at` not covered by the projections of `triangles` along `axis` (3D; `NaN` in
/// other dimensions, which have no such area).
pub fn open_area<const D: usize>(fluid: &Mesh<D>, triangles: impl IntoIterator<Item = [[f64; D]; D]>, axis: usize, at: f64) -> f64 {
    if D != 3 || axis > 2 {
        return f64::NAN;
    }
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let sections: Vec<Vec<[f64; 2]>> = (0..fluid.num_cells())
        .filter_map(|c| {
            let x: Vec<[f64; 3]> = fluid.cell_vertices(c).iter().map(|&n| std::array::from_fn(|d| fluid.points[n][d])).collect();
            tetrahedron_section(&x, axis, at).map(|poly| poly.iter().map(|p| [p[u], p[v]]).collect())
        })
        .collect();
    let Some(grid) = Grid::around(&sections) else {
        return 0.0;
    };
    let mut inside = vec![false; RESOLUTION * RESOLUTION];
    for poly in &sections {
        grid.fill(poly, &mut inside);
    }
    let mut covered = vec![false; RESOLUTION * RESOLUTION];
    for t in triangles {
        grid.fill(&t.map(|p| [p[u], p[v]]), &mut covered);
    }
    let open = inside.iter().zip(&covered).filter(|(&i, &c)| i && !c).count();
    open as f64 * grid.cell_area()
}

/// The section of a straight tetrahedron by the plane `x[axis] = at`: the points where its
/// edges cross it, in order around the (convex) section; `None` if it does not cross (or only
/// touches) the plane.
fn tetrahedron_section(x: &[[f64; 3]], axis: usize, at: f64) -> Option<Vec<[f64; 3]>> {
    let mut points = Vec::with_capacity(4);
    for i in 0..x.len() {
        for j in i + 1..x.len() {
            let (a, b) = (x[i][axis] - at, x[j][axis] - at);
            if (a < 0.0) != (b < 0.0) {
                let t = a / (a - b);
                points.push(std::array::from_fn(|d| x[i][d] + t * (x[j][d] - x[i][d])));
            }
        }
    }
    if points.len() < 3 {
        return None;
    }
    // Order around the centroid (the section is convex).
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let n = points.len() as f64;
    let c = [points.iter().map(|p| p[u]).sum::<f64>() / n, points.iter().map(|p| p[v]).sum::<f64>() / n];
    points.sort_by(|p, q| f64::atan2(p[v] - c[1], p[u] - c[0]).total_cmp(&f64::atan2(q[v] - c[1], q[u] - c[0])));
    Some(points)
}

/// A grid of `RESOLUTION^2` points, at the centres of the cells of a box.
struct Grid {
    lo: [f64; 2],
    h: [f64; 2],
}

impl Grid {
    /// The grid over the bounding box of `polygons`; `None` if it is empty or flat.
    fn around(polygons: &[Vec<[f64; 2]>]) -> Option<Grid> {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for p in polygons.iter().flatten() {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let h = [0, 1].map(|d| (hi[d] - lo[d]) / RESOLUTION as f64);
        (h[0] > 0.0 && h[1] > 0.0).then_some(Grid { lo, h })
    }

    fn cell_area(&self) -> f64 {
        self.h[0] * self.h[1]
    }

    /// Marks the grid points inside the convex polygon `poly` (either orientation; a point on
    /// an edge, to round-off, counts as inside).
    fn fill(&self, poly: &[[f64; 2]], marks: &mut [bool]) {
        let n = poly.len();
        let area2: f64 = (0..n).map(|k| cross(poly[k], poly[(k + 1) % n], [0.0, 0.0])).sum();
        if area2 == 0.0 {
            return;
        }
        let sign = area2.signum();
        // Points on an edge shared by two polygons belong to one of them despite round-off.
        let tol = -1e-12 * area2.abs();
        let index = |x: f64, d: usize| ((x - self.lo[d]) / self.h[d] - 0.5).clamp(-1.0, RESOLUTION as f64);
        let lo = [0, 1].map(|d| index(poly.iter().map(|p| p[d]).fold(f64::INFINITY, f64::min), d).ceil().max(0.0) as usize);
        let hi = [0, 1].map(|d| index(poly.iter().map(|p| p[d]).fold(f64::NEG_INFINITY, f64::max), d).floor());
        if hi[0] < 0.0 || hi[1] < 0.0 {
            return;
        }
        let hi = hi.map(|x| (x as usize).min(RESOLUTION - 1));
        for j in lo[1]..=hi[1] {
            let y = self.lo[1] + (j as f64 + 0.5) * self.h[1];
            for i in lo[0]..=hi[0] {
                let x = self.lo[0] + (i as f64 + 0.5) * self.h[0];
                if (0..n).all(|k| sign * cross(poly[k], poly[(k + 1) % n], [x, y]) >= tol) {
                    marks[j * RESOLUTION + i] = true;
                }
            }
        }
    }
}

/// `(b - a) x (p - a)`: positive when `p` lies to the left of `a -> b`.
fn cross(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use fdfsi_fem::generate::box_tetrahedra;

    /// The unit cube's section by z = 0.3 is the unit square; a triangle of area 1/8 (its
    /// projection, wherever it lies along z) and one outside leave 7/8 of it open.
    #[test]
    fn square_section_less_a_triangle() {
        let cube = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 3, 3, 3);
        let full = open_area(&cube, [], 2, 0.3);
        assert!((full - 1.0).abs() < 1e-12, "{full}");
        let tri = [[0.0, 0.0, 0.9], [0.5, 0.0, -2.0], [0.0, 0.5, 0.2]];
        let outside = [[2.0, 2.0, 0.0], [3.0, 2.0, 0.0], [2.0, 3.0, 0.0]];
        let a = open_area(&cube, [tri, outside], 2, 0.3);
        assert!((a - 0.875).abs() < 2.0 / RESOLUTION as f64, "{a}");
        // Along x: the section is the square in (y, z); the triangle projects onto a segment.
        let a = open_area(&cube, [[[0.0, 0.0, 0.0], [1.0, 0.5, 0.5], [0.5, 0.5, 0.5]]], 0, 0.5);
        assert!((a - 1.0).abs() < 2.0 / RESOLUTION as f64, "{a}");
    }

    /// A plane through a layer of faces (z = 0.5 of a 2 x 2 x 2 box mesh) sees the square once.
    #[test]
    fn plane_through_a_layer_of_faces() {
        let cube = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 2, 2, 2);
        let a = open_area(&cube, [], 2, 0.5);
        assert!((a - 1.0).abs() < 1e-12, "{a}");
    }

    /// A plane that misses the mesh leaves no area.
    #[test]
    fn plane_outside_the_mesh() {
        let cube = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 2, 2, 2);
        assert_eq!(open_area(&cube, [], 2, 1.5), 0.0);
    }
}
