//! Checks of an adapted mesh, loud at the phase boundary (STYLE.md habit 3) and used by the tests.

use super::{Adapted, Surface};
use crate::mesh::Mesh;
use std::collections::HashMap;

/// Relative tolerance of the measure checks.
const MEASURE_TOL: f64 = 1e-12;

/// Checks `adapted` against its `original` and `surface`:
/// positive cells ([`Mesh::check`]); conformity (every facet shared by at most two cells, the
/// facets with one cell are exactly the tagged boundary facets, each tagged once: no hanging
/// nodes); total measure equal to the original's (`1e-12` relative); children of a parent
/// without moved vertices add up to the parent's measure; every gamma_f vertex within
/// `1e-12` times the mesh size of gamma_s, each gamma_f facet is a facet of its side cells, and
/// no cell lies on both sides of gamma_f.
/// (An adaptation whose enclosed cells were removed, [`super::remove_enclosed`], no longer fills
/// the original's measure: it is checked before the removal.)
pub fn verify_adapted<const D: usize>(original: &Mesh<D>, adapted: &Adapted<D>, surface: &Surface<D>) -> Result<(), String> {
    verify_adapted_within(original, adapted, surface, 1e-12 * bbox_diameter(&original.points))
}

/// As [`verify_adapted`], with the gamma_f vertices within `distance` of gamma_s (boundary
/// vertices taken to lie on it where they are, [`super::AdaptOptions::touch_fixed_boundary`],
/// are up to `eps_hat / 4` of an edge from it).
pub fn verify_adapted_within<const D: usize>(original: &Mesh<D>, adapted: &Adapted<D>, surface: &Surface<D>, distance: f64) -> Result<(), String> {
    let mesh = &adapted.mesh;
    mesh.check().map_err(|e| format!("adapted mesh: {e}"))?;
    check_conforming(mesh)?;
    let orig: f64 = (0..original.num_cells()).map(|c| original.signed_vertex_measure(c)).sum();
    let new: f64 = (0..mesh.num_cells()).map(|c| mesh.signed_vertex_measure(c)).sum();
    if (new - orig).abs() > MEASURE_TOL * orig.abs() {
        return Err(format!("total measure changed: {orig:.17e} -> {new:.17e}"));
    }
    check_children(original, adapted)?;
    for (i, g) in adapted.gamma_f.iter().enumerate() {
        for &v in &g.vertices {
            let d = surface.project(&mesh.points[v]).map(|sp| sp.distance).unwrap_or(f64::INFINITY);
            if d > distance {
                return Err(format!("gamma_f facet {i}: vertex {v} is {d:.3e} away from gamma_s"));
            }
        }
        for &(c, j) in g.sides.iter().filter(|s| s.0 != usize::MAX) {
            let mut a: Vec<usize> = mesh.cell_type.facet(j).iter().map(|&k| mesh.cell(c)[k]).collect();
            let mut b = g.vertices.to_vec();
            a.sort_unstable();
            b.sort_unstable();
            if a != b {
                return Err(format!("gamma_f facet {i}: side ({c}, {j}) is not that facet"));
            }
        }
    }
    check_one_side_per_cell(adapted)
}

/// No cell lies on both sides of gamma_f (see **Cells on both sides** in [`super`]).
fn check_one_side_per_cell<const D: usize>(adapted: &Adapted<D>) -> Result<(), String> {
    let mut side_of: HashMap<usize, (usize, usize)> = HashMap::new();
    for (i, g) in adapted.gamma_f.iter().enumerate() {
        for (side, &(c, _)) in g.sides.iter().enumerate().filter(|(_, s)| s.0 != usize::MAX) {
            let (first, facet) = *side_of.entry(c).or_insert((side, i));
            if first != side {
                return Err(format!("cell {c} lies on both sides of gamma_f (facets {facet} and {i})"));
            }
        }
    }
    Ok(())
}

/// Every facet in at most two cells; one-cell facets = the tagged boundary facets, tagged once.
fn check_conforming<const D: usize>(mesh: &Mesh<D>) -> Result<(), String> {
    let ct = mesh.cell_type;
    let mut count: HashMap<[usize; 3], (u32, (usize, usize))> = HashMap::new();
    for c in 0..mesh.num_cells() {
        for j in 0..ct.num_facets() {
            let mut key = [usize::MAX; 3];
            for (i, &k) in ct.facet(j).iter().enumerate() {
                key[i] = mesh.cell(c)[k];
            }
            key[..D].sort_unstable();
            let e = count.entry(key).or_insert((0, (c, j)));
            e.0 += 1;
            if e.0 > 2 {
                return Err(format!("facet {:?} is shared by more than two cells", &key[..D]));
            }
        }
    }
    let exterior: Vec<(usize, usize)> = count.values().filter(|v| v.0 == 1).map(|v| v.1).collect();
    let mut tagged: Vec<(usize, usize)> = mesh.boundary.iter().map(|b| (b.cell, b.facet)).collect();
    tagged.sort_unstable();
    let n_tagged = tagged.len();
    tagged.dedup();
    if tagged.len() != n_tagged {
        return Err("a boundary facet is tagged twice".into());
    }
    if exterior.len() != tagged.len() {
        return Err(format!("{} exterior facets but {} tagged boundary facets (hanging nodes or lost tags)", exterior.len(), tagged.len()));
    }
    for e in &exterior {
        if tagged.binary_search(e).is_err() {
            return Err(format!("exterior facet {e:?} is not tagged"));
        }
    }
    Ok(())
}

/// Children of parents without moved vertices add up to the parent's measure.
fn check_children<const D: usize>(original: &Mesh<D>, adapted: &Adapted<D>) -> Result<(), String> {
    let mesh = &adapted.mesh;
    let mut sum = vec![0.0; original.num_cells()];
    let mut moved = vec![false; original.num_cells()];
    let nv = original.points.len();
    let same_vertices = original.order == crate::mesh::GeometryOrder::Linear;
    for (c, &p) in adapted.new_to_old_cell.iter().enumerate() {
        sum[p] += mesh.signed_vertex_measure(c);
        if same_vertices {
            moved[p] |= mesh.cell(c).iter().any(|&v| v < nv && mesh.points[v] != original.points[v]);
        }
    }
    for p in 0..original.num_cells() {
        let m = original.signed_vertex_measure(p);
        if same_vertices && !moved[p] && (sum[p] - m).abs() > MEASURE_TOL * m {
            return Err(format!("children of cell {p} measure {:.17e}, the parent {m:.17e}", sum[p]));
        }
    }
    Ok(())
}

fn bbox_diameter<const D: usize>(points: &[[f64; D]]) -> f64 {
    let (lo, hi) = crate::mesh::bounding_box(points);
    (0..D).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt().max(1.0)
}
