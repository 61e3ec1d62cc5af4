//! `solid.gif` of a 3D FSI run: the solid seen along the flow, with its mirror images.
//!
//! Each frame shows the boundary faces of the solid cells the run wrote at one output time
//! (`DIR/solution.pvd`, part `solid`), seen along a coordinate axis from its positive side (the
//! flow's: the fluid box's longest axis, so a valve is seen from the aorta), drawn far to near,
//! each face shaded by how squarely it faces the viewer. A model of a sector between symmetry
//! planes is shown whole: the faces are repeated in the images of the mirror group those planes
//! generate (six for a sixth of a valve between two planes 60 degrees apart).
//!
//! The symmetry planes are the fluid's `symmetry` boundaries of the case (`DIR/case.toml`); a
//! plane is where the fluid grid ends along its normal (the side the most grid points touch).

use super::picture::{draw_failed, PictureError};
use fdfsi_fem::element::HEX_FACETS;
use fdfsi_fem::vtk::{UnstructuredGrid, VtkCellType};
use plotters::prelude::*;
use std::collections::HashMap;
use std::path::Path;

/// A face of the solid's surface: its four corners in order around it.
pub type Quad = [[f64; 3]; 4];

/// The faces of the hexahedra of `grid` (27- or 8-node) that no other hexahedron shares: the
/// surface of the solid, by its corner nodes.
pub fn boundary_quads(grid: &UnstructuredGrid) -> Vec<Quad> {
    let mut faces: HashMap<[usize; 4], (usize, [usize; 4])> = HashMap::new();
    for c in 0..grid.num_cells() {
        if !matches!(grid.cell_types[c], VtkCellType::TriquadraticHexahedron | VtkCellType::Hexahedron) {
            continue;
        }
        let nodes = grid.cell(c);
        for f in HEX_FACETS {
            let face = f.map(|k| nodes[k]);
            let mut key = face;
            key.sort_unstable();
            faces.entry(key).or_insert((0, face)).0 += 1;
        }
    }
    let mut once: Vec<[usize; 4]> = faces.into_values().filter(|(n, _)| *n == 1).map(|(_, f)| f).collect();
    once.sort_unstable();
    once.into_iter().map(|f| f.map(|n| grid.points[n])).collect()
}

/// An isometry `x -> m x + v`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Isometry {
    pub m: [[f64; 3]; 3],
    pub v: [f64; 3],
}

impl Isometry {
    pub const IDENTITY: Isometry = Isometry { m: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], v: [0.0; 3] };

    /// The reflection in the plane `n . x = c` (`n` of any length): `x - 2 (n . x - c) n / |n|^2`.
    pub fn reflection(n: [f64; 3], c: f64) -> Self {
        let nn = dot(&n, &n);
        Isometry {
            m: std::array::from_fn(|i| std::array::from_fn(|j| if i == j { 1.0 } else { 0.0 } - 2.0 * n[i] * n[j] / nn)),
            v: n.map(|ni| 2.0 * c * ni / nn),
        }
    }

    pub fn apply(&self, x: &[f64; 3]) -> [f64; 3] {
        std::array::from_fn(|i| dot(&self.m[i], x) + self.v[i])
    }

    /// `self` after `other`.
    fn compose(&self, other: &Isometry) -> Isometry {
        Isometry { m: std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| self.m[i][k] * other.m[k][j]).sum())), v: self.apply(&other.v) }
    }

    fn near(&self, other: &Isometry, tol: f64) -> bool {
        (0..3).all(|i| (0..3).all(|j| (self.m[i][j] - other.m[i][j]).abs() <= 1e-9) && (self.v[i] - other.v[i]).abs() <= tol)
    }
}

/// The most images [`mirror_group`] makes: a larger group (parallel planes, or planes at an
/// angle that is no fraction of pi) gives none.
pub const MAX_IMAGES: usize = 24;

/// The group the reflections `mirrors` generate, the identity first: every product of them,
/// found by closing the set under each reflection (translations compared to `tol`). Where it
/// would have more than [`MAX_IMAGES`] elements, the identity alone.
pub fn mirror_group(mirrors: &[Isometry], tol: f64) -> Vec<Isometry> {
    let mut group = vec![Isometry::IDENTITY];
    let mut next = 0;
    while next < group.len() {
        let g = group[next];
        next += 1;
        for r in mirrors {
            let h = r.compose(&g);
            if !group.iter().any(|k| k.near(&h, tol)) {
                group.push(h);
            }
        }
        if group.len() > MAX_IMAGES {
            return vec![Isometry::IDENTITY];
        }
    }
    group
}

/// The plane of normal `n` (unit) at which the points end on the side more of them touch
/// (within `tol`): `c` with every point on one side of `n . x = c` (a symmetry plane bounding a
/// fluid grid). `None` where both sides are touched by as many points (a slab between two such
/// planes): which one is meant is not known.
pub fn bounding_plane(points: &[[f64; 3]], n: [f64; 3], tol: f64) -> Option<f64> {
    let s: Vec<f64> = points.iter().map(|p| dot(&n, p)).collect();
    let (lo, hi) = s.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let count = |c: f64| s.iter().filter(|&&v| (v - c).abs() <= tol).count();
    match count(lo).cmp(&count(hi)) {
        std::cmp::Ordering::Greater => Some(lo),
        std::cmp::Ordering::Less => Some(hi),
        std::cmp::Ordering::Equal => None,
    }
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// One frame of `solid.gif`: the caption and the faces (images included).
#[derive(Clone, Debug, Default)]
pub struct SolidFrame {
    pub title: String,
    pub faces: Vec<Quad>,
}

/// The colour of a face turned `cos` (`|n . e|`, the cosine between its normal and the view) to
/// the viewer: light where it faces the viewer, darker as it turns away.
fn shade(cos: f64) -> RGBColor {
    let t = 0.35 + 0.65 * cos.clamp(0.0, 1.0);
    let c = |base: f64| (base * t).round() as u8;
    RGBColor(c(235.0), c(200.0), c(170.0))
}

/// Writes `frames` as an animated GIF `size` pixels square (plus the caption), `delay_ms` per
/// frame, looping: the faces seen along the axis `axis` from its positive side, far to near, at
/// one scale with labelled axes, all frames in the box of all their faces.
pub fn write_solid_gif(frames: &[SolidFrame], axis: usize, path: &Path, size: u32, delay_ms: u32) -> Result<(), PictureError> {
    if axis > 2 {
        return Err(PictureError::Input(format!("a view along axis {axis}: there are 3")));
    }
    if size < 200 {
        return Err(PictureError::Input(format!("a solid view {size} pixels square is too small: at least 200")));
    }
    let [a, b] = match axis {
        0 => [1, 2],
        1 => [2, 0],
        _ => [0, 1],
    };
    let points = || frames.iter().flat_map(|f| f.faces.iter().flatten());
    if points().next().is_none() || points().flatten().any(|v| !v.is_finite()) {
        return Err(PictureError::Input("no solid faces to draw, or a point that is not finite".into()));
    }
    let range = |d: usize| points().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[d]), hi.max(p[d])));
    let ((x0, x1), (y0, y1)) = (range(a), range(b));
    let span = 1.05 * (x1 - x0).max(y1 - y0).max(1e-12);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    super::plot::register_font();
    let font = super::plot::FAMILY;
    const CAPTION: u32 = 40;
    let tmp = path.with_extension("tmp.gif");
    {
        let root = BitMapBackend::gif(&tmp, (size, size + CAPTION), delay_ms).map_err(draw_failed)?.into_drawing_area();
        let names = ["x", "y", "z"];
        for frame in frames {
            root.fill(&WHITE).map_err(draw_failed)?;
            let titled = root.titled(&frame.title, (font, 18)).map_err(draw_failed)?;
            let mut chart = ChartBuilder::on(&titled)
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(56)
                .build_cartesian_2d(cx - 0.5 * span..cx + 0.5 * span, cy - 0.5 * span..cy + 0.5 * span)
                .map_err(draw_failed)?;
            chart.configure_mesh().disable_mesh().x_desc(names[a]).y_desc(names[b]).label_style((font, 14)).draw().map_err(draw_failed)?;
            let mut order: Vec<(f64, &Quad)> = frame.faces.iter().map(|q| (q.iter().map(|p| p[axis]).sum::<f64>(), q)).collect();
            order.sort_by(|p, q| p.0.total_cmp(&q.0));
            let plot = chart.plotting_area();
            for (_, q) in order {
                let e1: [f64; 3] = std::array::from_fn(|d| q[2][d] - q[0][d]);
                let e2: [f64; 3] = std::array::from_fn(|d| q[3][d] - q[1][d]);
                let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
                let len = dot(&n, &n).sqrt();
                let cos = if len > 0.0 { n[axis].abs() / len } else { 0.0 };
                let corners: Vec<(f64, f64)> = q.iter().map(|p| (p[a], p[b])).collect();
                plot.draw(&Polygon::new(corners.clone(), shade(cos).filled())).map_err(draw_failed)?;
                let mut outline = corners;
                outline.push(outline[0]);
                plot.draw(&PathElement::new(outline, RGBColor(90, 70, 60).stroke_width(1))).map_err(draw_failed)?;
            }
            root.present().map_err(draw_failed)?;
        }
    }
    Ok(std::fs::rename(&tmp, path)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_planes_sixty_degrees_apart_make_six_images() {
        let s = 60f64.to_radians();
        let mirrors = [Isometry::reflection([0.0, 1.0, 0.0], 0.0), Isometry::reflection([-s.sin(), s.cos(), 0.0], 0.0)];
        let group = mirror_group(&mirrors, 1e-9);
        assert_eq!(group.len(), 6);
        // A point at 10 degrees goes to 10 + 120 k and -10 + 120 k degrees, each once.
        let p = [10f64.to_radians().cos(), 10f64.to_radians().sin(), 0.5];
        let mut angles: Vec<f64> = group.iter().map(|g| g.apply(&p)).map(|q| q[1].atan2(q[0]).to_degrees().rem_euclid(360.0)).collect();
        angles.sort_by(f64::total_cmp);
        let want = [10.0, 110.0, 130.0, 230.0, 250.0, 350.0];
        assert!(angles.iter().zip(want).all(|(a, w)| (a - w).abs() < 1e-9), "{angles:?}");
        assert!(group.iter().all(|g| (g.apply(&p)[2] - 0.5).abs() < 1e-15));
        // A plane off the origin: one reflection, two images; parallel planes are cut off.
        assert_eq!(mirror_group(&[Isometry::reflection([1.0, 0.0, 0.0], 2.0)], 1e-9).len(), 2);
        assert_eq!(Isometry::reflection([2.0, 0.0, 0.0], 4.0).apply(&[1.0, 5.0, 6.0]), [3.0, 5.0, 6.0]);
        let parallel = [Isometry::reflection([1.0, 0.0, 0.0], 0.0), Isometry::reflection([1.0, 0.0, 0.0], 1.0)];
        assert_eq!(mirror_group(&parallel, 1e-9), [Isometry::IDENTITY]);
    }

    #[test]
    fn the_surface_of_two_hexahedra_is_their_ten_outer_faces_and_is_drawn() {
        // Two unit cubes side by side along x, 8-node hexahedra sharing the face x = 1.
        let p = |x: f64, y: f64, z: f64| [x, y, z];
        let mut points = Vec::new();
        for x in 0..3 {
            for (y, z) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
                points.push(p(x as f64, y as f64, z as f64));
            }
        }
        // Corner k of the cube at x0: VTK order (bottom 0-3 at z = 0, top 4-7 at z = 1).
        let cube = |x0: usize| {
            let at = |x: usize, k: usize| 4 * x + k;
            [at(x0, 0), at(x0 + 1, 0), at(x0 + 1, 1), at(x0, 1), at(x0, 3), at(x0 + 1, 3), at(x0 + 1, 2), at(x0, 2)]
        };
        let mut grid = UnstructuredGrid::new(points);
        grid.push_cell(VtkCellType::Hexahedron, &cube(0)).unwrap();
        grid.push_cell(VtkCellType::Hexahedron, &cube(1)).unwrap();
        let quads = boundary_quads(&grid);
        assert_eq!(quads.len(), 10);
        assert!(quads.iter().all(|q| !q.iter().all(|c| c[0] == 1.0)), "the shared face x = 1 is inside");
        let area: f64 = quads
            .iter()
            .map(|q| {
                let (e1, e2) = (std::array::from_fn::<f64, 3, _>(|d| q[1][d] - q[0][d]), std::array::from_fn::<f64, 3, _>(|d| q[3][d] - q[0][d]));
                (dot(&e1, &e1) * dot(&e2, &e2)).sqrt()
            })
            .sum();
        assert_eq!(area, 10.0);
        // A grid in 0 <= y <= 1, six points on each side: not known which; the side more points
        // touch: the top of a roof (one point) is not a plane.
        assert_eq!(bounding_plane(&grid.points, [0.0, 1.0, 0.0], 1e-12), None);
        let roof = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 1.0]];
        assert_eq!(bounding_plane(&roof, [0.0, 0.0, 1.0], 1e-12), Some(0.0));
        assert_eq!(bounding_plane(&roof, [0.0, 0.0, -1.0], 1e-12), Some(0.0));
        let dir = std::env::temp_dir().join(format!("fdfsi-view-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let gif = dir.join("solid.gif");
        let frames = [SolidFrame { title: "t = 0".into(), faces: quads.clone() }, SolidFrame { title: "t = 1".into(), faces: quads }];
        write_solid_gif(&frames, 2, &gif, 300, 100).unwrap();
        assert!(std::fs::read(&gif).unwrap().starts_with(b"GIF89a"));
        assert!(matches!(write_solid_gif(&frames, 3, &gif, 300, 100), Err(PictureError::Input(_))));
        assert!(matches!(write_solid_gif(&[], 2, &gif, 300, 100), Err(PictureError::Input(_))));
        std::fs::remove_dir_all(&dir).ok();
    }
}
