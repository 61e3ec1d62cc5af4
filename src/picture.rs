//! PNG pictures of 2D fields (no fonts, no system libraries): `speed.png` of a 2D run shows
//! `|u|` on the mesh, each quadratic triangle drawn as its four linear sub-triangles coloured by
//! their mean nodal speed (viridis colour map, blue slow, yellow fast).

use crate::flow::FlowDiscretization;
use plotters::prelude::*;
use std::path::Path;

/// The viridis colour map at `s` in [0, 1] (piecewise linear through 5 control colours).
pub fn viridis(s: f64) -> RGBColor {
    const C: [(f64, f64, f64); 5] =
        [(68.0, 1.0, 84.0), (59.0, 82.0, 139.0), (33.0, 145.0, 140.0), (94.0, 201.0, 98.0), (253.0, 231.0, 37.0)];
    let s = if s.is_finite() { s.clamp(0.0, 1.0) } else { 0.0 } * 4.0;
    let i = (s.floor() as usize).min(3);
    let f = s - i as f64;
    let mix = |a: f64, b: f64| (a + f * (b - a)).round() as u8;
    RGBColor(mix(C[i].0, C[i + 1].0), mix(C[i].1, C[i + 1].1), mix(C[i].2, C[i + 1].2))
}

/// Writes the speed of a 2D flow solution as a PNG `width` pixels wide, showing the whole mesh.
pub fn write_speed_png(disc: &FlowDiscretization<2>, x: &[f64], path: &Path, width: u32) -> Result<(), String> {
    write_speed_png_window(disc, x, path, width, None, &[])
}

/// Writes the speed of a 2D flow solution as a PNG `width` pixels wide showing the rectangle
/// `window = [[x0, y0], [x1, y1]]` (default: the whole mesh), with the polylines `outlines`
/// (e.g. gamma_f) drawn in white over it. The colour scale spans the speeds in the picture.
pub fn write_speed_png_window(
    disc: &FlowDiscretization<2>,
    x: &[f64],
    path: &Path,
    width: u32,
    window: Option<[[f64; 2]; 2]>,
    outlines: &[Vec<[f64; 2]>],
) -> Result<(), String> {
    let vf = &disc.layout.fields[0];
    let nodes = &disc.velocity_nodes;
    let speed = |n: usize| (x[vf.dof(n, 0)].powi(2) + x[vf.dof(n, 1)].powi(2)).sqrt();
    let (mut lo, mut hi) = fdfsi_fem::mesh::bounding_box(&disc.mesh.points);
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
