//! PNG pictures (no fonts, no system libraries): `speed.png` of a 2D run shows `|u|` on the mesh,
//! each quadratic triangle drawn as its four linear sub-triangles coloured by their mean nodal
//! speed (viridis colour map, blue slow, yellow fast); [`write_surfaces_png`] draws the coupling
//! surfaces gamma_s and gamma_f of a 3D run (the paper's figs. 7 and 8).

use crate::discretize::flow::FlowDiscretization;
use plotters::prelude::*;
use std::path::Path;

/// The viridis colour map at `s` in [0, 1] (piecewise linear through 5 control colours).
pub fn viridis(s: f64) -> RGBColor {
    const C: [(f64, f64, f64); 5] = [(68.0, 1.0, 84.0), (59.0, 82.0, 139.0), (33.0, 145.0, 140.0), (94.0, 201.0, 98.0), (253.0, 231.0, 37.0)];
    let s = if s.is_finite() { s.clamp(0.0, 1.0) } else { 0.0 } * 4.0;
    let i = (s.floor() as usize).min(3);
    let f = s - i as f64;
    let mix = |a: f64, b: f64| (a + f * (b - a)).round() as u8;
    RGBColor(mix(C[i].0, C[i + 1].0), mix(C[i].1, C[i + 1].1), mix(C[i].2, C[i + 1].2))
}

/// Writes the speed of a 2D flow solution as a PNG `width` pixels wide, showing the whole mesh.
pub fn write_speed_png<const D: usize>(disc: &FlowDiscretization<D>, x: &[f64], path: &Path, width: u32) -> Result<(), String> {
    write_speed_png_window(disc, x, path, width, None, &[])
}

/// Writes the speed of a 2D flow solution as a PNG `width` pixels wide showing the rectangle
/// `window = [[x0, y0], [x1, y1]]` (default: the whole mesh), with the polylines `outlines`
/// (e.g. gamma_f) drawn in white over it. The colour scale spans the speeds in the picture.
/// 2D only: a 3D discretisation is an error.
pub fn write_speed_png_window<const D: usize>(
    disc: &FlowDiscretization<D>,
    x: &[f64],
    path: &Path,
    width: u32,
    window: Option<[[f64; 2]; 2]>,
    outlines: &[Vec<[f64; 2]>],
) -> Result<(), String> {
    if D != 2 {
        return Err(format!("speed pictures are drawn of 2D flows, not {D}D"));
    }
    let vf = &disc.velocity_field();
    let nodes: Vec<[f64; 2]> = disc.velocity_nodes.iter().map(|p| [p[0], p[1]]).collect();
    let speed = |n: usize| (x[vf.dof(n, 0)].powi(2) + x[vf.dof(n, 1)].powi(2)).sqrt();
    let (lo, hi) = fdfsi_fem::mesh::bounding_box(&disc.mesh.points);
    let (mut lo, mut hi) = ([lo[0], lo[1]], [hi[0], hi[1]]);
    if let Some([a, b]) = window {
        (lo, hi) = ([a[0].max(lo[0]), a[1].max(lo[1])], [b[0].min(hi[0]), b[1].min(hi[1])]);
        if !(hi[0] > lo[0] && hi[1] > lo[1]) {
            return Err(format!("the picture window {window:?} does not overlap the mesh"));
        }
    }
    let inside = |p: &[f64; 2]| (0..2).all(|d| p[d] >= lo[d] && p[d] <= hi[d]);
    let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
    let height = ((width as f64) * h / w).round().clamp(40.0, 4.0 * width as f64) as u32;
    let smax = (0..vf.nodes.num_nodes).filter(|&n| inside(&nodes[n])).map(speed).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    // Drawn under a temporary name and renamed, so a crash never leaves a half-written picture.
    let tmp = path.with_extension("tmp.png");
    let root = BitMapBackend::new(&tmp, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let px = |p: [f64; 2]| -> (i32, i32) {
        (((p[0] - lo[0]) / w * (width - 1) as f64).round() as i32, ((hi[1] - p[1]) / h * (height - 1) as f64).round() as i32)
    };
    // Sub-triangles of a 6-node triangle (vertices 0-2, mid-edge nodes 3: 01, 4: 12, 5: 20).
    const SUB: [[usize; 3]; 4] = [[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]];
    for c in 0..disc.mesh.num_cells() {
        let cn = vf.nodes.cell(c);
        for t in SUB {
            let s = t.iter().map(|&k| speed(cn[k])).sum::<f64>() / 3.0 / smax;
            let pts: Vec<(i32, i32)> = t.iter().map(|&k| px(nodes[cn[k]])).collect();
            root.draw(&Polygon::new(pts, viridis(s).filled())).map_err(|e| e.to_string())?;
        }
    }
    for line in outlines {
        let pts: Vec<(i32, i32)> = line.iter().map(|&p| px(p)).collect();
        root.draw(&PathElement::new(pts, WHITE.stroke_width(3))).map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())?;
    drop(root);
    std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display()))
}

/// Colour of gamma_s (the solid's surface pieces) in [`write_surfaces_png`].
pub const GAMMA_S_COLOUR: RGBColor = RGBColor(31, 119, 180);
/// Colour of gamma_f (the adapted fluid mesh's facets) in [`write_surfaces_png`].
pub const GAMMA_F_COLOUR: RGBColor = RGBColor(214, 39, 40);

/// Writes the edges of two triangulated surfaces of a 3D run, gamma_s (blue) and gamma_f (red),
/// as a PNG of two panels `size` pixels square: left, seen along the z axis (the x-y plane, the
/// two non-conforming triangulations over each other); right, seen from the side in `(r, z)`
/// with `r = sqrt(x^2 + y^2)` across and z up, z stretched to fill the panel (the shape of the
/// bulge; the z range is printed nowhere, it is that of the surfaces with 10 % margins).
pub fn write_surfaces_png(path: &Path, gamma_s: &[[[f64; 3]; 3]], gamma_f: &[[[f64; 3]; 3]], size: u32) -> Result<(), String> {
    let all = || gamma_s.iter().chain(gamma_f).flatten();
    if all().next().is_none() || all().flatten().any(|v| !v.is_finite()) {
        return Err("no surface to draw, or a point that is not finite".into());
    }
    let fold = |f: &dyn Fn(&[f64; 3]) -> f64| all().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(f(p)), hi.max(f(p))));
    let r = |p: &[f64; 3]| p[0].hypot(p[1]);
    let (x, y, rr, z) = (fold(&|p| p[0]), fold(&|p| p[1]), fold(&r), fold(&|p| p[2]));
    let pad = |(lo, hi): (f64, f64)| {
        let m = 0.1 * (hi - lo).max(1e-9 * (1.0 + hi.abs()));
        (lo - m, hi + m)
    };
    let span = (x.1 - x.0).max(y.1 - y.0);
    let (x, y) = (pad((x.0, x.0 + span)), pad((y.0, y.0 + span)));
    let (rr, z) = (pad((rr.0.min(0.0), rr.1)), pad(z));
    let tmp = path.with_extension("tmp.png");
    let root = BitMapBackend::new(&tmp, (2 * size, size)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let to_px = |u: f64, (u0, u1): (f64, f64), flip: bool| {
        let t = (u - u0) / (u1 - u0);
        ((if flip { 1.0 - t } else { t }) * (size - 1) as f64).round() as i32
    };
    let top = |p: &[f64; 3]| (to_px(p[0], x, false), to_px(p[1], y, true));
    let side = |p: &[f64; 3]| (size as i32 + to_px(r(p), rr, false), to_px(p[2], z, true));
    for (tris, colour) in [(gamma_s, GAMMA_S_COLOUR), (gamma_f, GAMMA_F_COLOUR)] {
        for t in tris {
            for view in [&top as &dyn Fn(&[f64; 3]) -> (i32, i32), &side] {
                let pts: Vec<(i32, i32)> = [0, 1, 2, 0].iter().map(|&k| view(&t[k])).collect();
                root.draw(&PathElement::new(pts, colour.stroke_width(1))).map_err(|e| e.to_string())?;
            }
        }
    }
    let split = [(size as i32, 0), (size as i32, size as i32)];
    root.draw(&PathElement::new(split, BLACK.stroke_width(1))).map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    drop(root);
    std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display()))
}
