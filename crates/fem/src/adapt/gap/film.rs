//! The pressure of the film of blood in a closed gap by Reynolds' equation: at each of the gap's
//! cells, a mean of the pressures at the gap's mouths.
//!
//! A gap the cut takes is thinner than the cells (that is why it is cut), but the blood in it is
//! a film whose flow is lubrication flow: across a film of height `h` the flux per unit width is
//! `q = -h^3 / (12 mu) grad p`, and in a film whose height does not change (quasi-static: the
//! squeeze term `12 mu dh/dt` left out) it is conserved, Reynolds' equation
//!
//! ```text
//! div (h^3 grad p) = 0   in the film,      p = p_m   at its mouths m,
//! ```
//!
//! the mouths' pressures those of the fluid the film opens to. The gap's cells fill its height,
//! so the film is Darcy flow through them with the permeability `k = h^2` of a film `h` high
//! (`k h = h^3`; the factor `1 / (12 mu)` is common to all and cancels): two-point fluxes across
//! the facets off gamma_f between the gap's cells and from them to its mouths (the kept cells
//! across its facets off gamma_f, where the pressure is the mouth cell's at its centroid), each
//! facet's transmissibility `T = A / (d_a / k_a + d_b / k_b)` (`A` its measure, `d` the distance
//! from each cell's centroid to the facet's). `h` is the film's height at a cell's centroid: the
//! height of the gap layer's piece nearest it ([`film_height`]), whatever the cell's shape (its
//! least altitude, tried first, made slivers at the gap's ends into seals: an even film's
//! pressure fell by a third of its drop across one cell there); cells the layer does not reach
//! (pockets cut with the gap, mouths) are open fluid, `h` their size `(D! |K|)^(1/D)`. The discrete solution at each cell is then a
//! mean of the mouths' pressures with weights `w_m >= 0`, `sum_m w_m = 1` (an M-matrix's
//! maximum principle), linear in them: where the gap narrows to a seal the weights switch from
//! one side's mouths to the other's; where it is even they fall off with the distance along
//! it; and no single mouth cell decides the film's load unless the film opens to it alone.
//!
//! A film whose height changes carries, besides, the squeeze term: with the solid's faces on
//! the gap moving into it at `v_n`, `div (h^3 grad p) = 12 mu dh/dt` and the film's pressure rises
//! by `12 mu G (v_n dA)`, `G` the film's Green's function with the mouths held. Taken at each
//! cell as `12 mu s v_n`, `s = G 1` the film's pressure (per `12 mu`) when every face on the gap
//! moves into it at unit speed ([`CellFilm::squeeze`]; the same system with each cell's source
//! the measure of its facets on gamma_f, the mouths at zero), it is exact for a uniform squeeze
//! (the gap's faces moving as one into it or out of it) and an approximation otherwise: a face
//! rocking about the gap's middle squeezes one half and opens the other, which this puts on
//! each half alone, as if the whole gap moved so, a stiffer damper than the film is (`G 1`, the
//! row sums of `G`, is not local: unlike a lumped mass matrix it does not tend to `G` as the
//! cells shrink). For an even film of height `h` between mouths `2 L` apart, `s = (L^2 - x^2) /
//! (2 h^3)`. No film is thinner than a twentieth of its cell for it (where the solid lies on its
//! plane `h = 0`); in a gap of slivers this floor shrinks with them.

use super::{cell_size, FacetGraph, Gaps};
use crate::adapt::geom::{dist2, dot, sub};
use crate::adapt::surface::piece_measure;
use crate::adapt::Adapted;
use crate::mesh::Mesh;
use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use std::collections::HashMap;

/// Weights below this fraction of a cell's sum are dropped (and the rest scaled back to one):
/// each changes its pressure by less than a thousandth of the spread of its mouths', and each
/// kept weight couples the film's facet to another mouth's unknown.
const LEAST_WEIGHT: f64 = 1e-3;

/// A permeability below this fraction of the largest in its gap (or of the open fluid's, its
/// cells' size squared) is raised to it, so that the film's system stays definite where the
/// film's height is zero (the weights across such a cell are then within round-off of a
/// seal's).
const LEAST_PERMEABILITY: f64 = 1e-12;

/// The squeeze sees no film thinner than this fraction of its cell's size: thinner films, where
/// the solid touches its plane, would glue it there (Stefan's adhesion, `p ~ 1 / h^3`, which
/// real films escape by cavitating), and their resistance would swamp the system's other
/// entries.
const SQUEEZE_LEAST_HEIGHT: f64 = 0.05;

/// The film's pressure at a cut cell: its centroid and its weights over the gap's mouths (the
/// kept cells' numbering), a mean `p = sum_m w_m p_m`; none where the gap has no mouth, or its
/// film's system could not be solved (a degenerate cell).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct CellFilm<const D: usize> {
    pub centroid: [f64; D],
    pub weights: Vec<(usize, f64)>,
    /// The film's pressure per `12 mu` at the cell when the gap's faces on gamma_f all move
    /// into it at unit speed, its mouths' pressures zero (the squeeze term, module
    /// documentation); a length's inverse, `>= 0`; 0 where there is no film.
    pub squeeze: f64,
}

/// The films of a cut's closed gaps ([`Gaps`]), cell by cell.
#[derive(Default)]
pub(super) struct Films<const D: usize> {
    /// The cells of each gap, in [`Gaps::cells`]' order.
    pub by_gap: Vec<Vec<CellFilm<D>>>,
    /// The gap of each cut cell and its place in that gap's list.
    at_cell: HashMap<usize, (usize, usize)>,
}

impl<const D: usize> Films<D> {
    /// Reynolds' films in the gaps `gaps` of `adapted` (before the cut; `graph` its facets), whose
    /// heights are those of the gap layers `layers` (each a piece's `D` corners, then their feet
    /// on the plane or the other body).
    pub fn solve(adapted: &Adapted<D>, graph: &FacetGraph, gaps: &Gaps, layers: &[Vec<[f64; D]>]) -> Self {
        let mut films = Films::default();
        for (g, cells) in gaps.cells.iter().enumerate() {
            films.at_cell.extend(cells.iter().enumerate().map(|(i, &c)| (c, (g, i))));
            films.by_gap.push(gap_film(adapted, graph, gaps, layers, g));
        }
        films
    }

    /// The film at the cut cell `cell`.
    pub fn at(&self, cell: usize) -> Option<&CellFilm<D>> {
        self.at_cell.get(&cell).map(|&(g, i)| &self.by_gap[g][i])
    }

    /// The film of gap `gap` at its cell nearest `x` (for a facet with no cell of the gap on its
    /// side: gamma_s lying on a plane it is pressed on).
    pub fn nearest(&self, gap: usize, x: &[f64; D]) -> Option<&CellFilm<D>> {
        let dist = |f: &&CellFilm<D>| (0..D).map(|d| (f.centroid[d] - x[d]).powi(2)).sum::<f64>();
        self.by_gap.get(gap)?.iter().min_by(|a, b| dist(a).total_cmp(&dist(b)))
    }
}

/// The film's height at `x` from the gap layer `layers` (each a piece's `D` corners `a_k`, then
/// their feet `f_k`): of the layer nearest `x`, `h = sum_k l_k |a_k - f_k|`, `l_k` the barycentric
/// coordinates of `x` projected on the feet's simplex (clamped to it), the layer nearest being
/// the one whose mid-surface point `sum_k l_k (a_k + f_k) / 2` lies nearest `x`, farther than
/// `reach` from every one: `None`.
fn film_height<const D: usize>(layers: &[Vec<[f64; D]>], x: &[f64; D], reach: f64) -> Option<f64> {
    let mut best: Option<(f64, f64)> = None;
    for layer in layers.iter().filter(|l| l.len() == 2 * D) {
        let (corners, feet) = layer.split_at(D);
        let l = clamped_barycentric(feet, x);
        let mid: [f64; D] = std::array::from_fn(|d| (0..D).map(|k| l[k] * 0.5 * (corners[k][d] + feet[k][d])).sum());
        let off = distance(&mid, x);
        if off <= reach && best.is_none_or(|(o, _)| off < o) {
            best = Some((off, (0..D).map(|k| l[k] * distance(&corners[k], &feet[k])).sum()));
        }
    }
    best.map(|(_, h)| h)
}

/// The barycentric coordinates of `x` projected on the simplex of the `D` points `p` (a segment
/// in 2D, a triangle in 3D), clamped to `[0, 1]` and scaled back to sum to one; the centre's
/// for a degenerate simplex.
fn clamped_barycentric<const D: usize>(p: &[[f64; D]], x: &[f64; D]) -> [f64; D] {
    let r = sub(x, &p[0]);
    let edges: Vec<[f64; D]> = (1..D).map(|k| sub(&p[k], &p[0])).collect();
    // The normal equations `G t = E^T r` of the least squares `x - p0 ~ sum_k t_k e_k`.
    let mut t = [0.0; D];
    let centre = [1.0 / D as f64; D];
    if D == 2 {
        let g = dot(&edges[0], &edges[0]);
        if g <= 0.0 {
            return centre;
        }
        t[1] = dot(&edges[0], &r) / g;
    } else {
        let (g00, g01, g11) = (dot(&edges[0], &edges[0]), dot(&edges[0], &edges[1]), dot(&edges[1], &edges[1]));
        let det = g00 * g11 - g01 * g01;
        if det <= 1e-14 * g00 * g11 {
            return centre;
        }
        let (b0, b1) = (dot(&edges[0], &r), dot(&edges[1], &r));
        t[1] = (g11 * b0 - g01 * b1) / det;
        t[2] = (g00 * b1 - g01 * b0) / det;
    }
    t[0] = 1.0 - (1..D).map(|k| t[k]).sum::<f64>();
    let clamped = t.map(|v| v.clamp(0.0, 1.0));
    let sum: f64 = clamped.iter().sum();
    clamped.map(|v| v / sum)
}

/// The corners of facet `f` of cell `c`.
fn facet_corners<const D: usize>(mesh: &Mesh<D>, c: usize, f: usize) -> [[f64; D]; D] {
    let nodes = mesh.cell(c);
    let local = mesh.facet_local_nodes(f);
    std::array::from_fn(|k| mesh.points[nodes[local[k]]])
}

fn distance<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    dist2(a, b).sqrt()
}

/// The film of gap `g`: the weights of its mouths and its squeeze at each of its cells (see the
/// module documentation). A gap without mouths has no film (empty weights).
fn gap_film<const D: usize>(adapted: &Adapted<D>, graph: &FacetGraph, gaps: &Gaps, layers: &[Vec<[f64; D]>], g: usize) -> Vec<CellFilm<D>> {
    let mesh = &adapted.mesh;
    let (cells, mouths) = (&gaps.cells[g], &gaps.mouths[g]);
    let centroids: Vec<[f64; D]> = cells.iter().map(|&c| mesh.vertex_centroid(c)).collect();
    let no_film = || centroids.iter().map(|&centroid| CellFilm { centroid, weights: Vec::new(), squeeze: 0.0 }).collect();
    if mouths.is_empty() {
        return no_film();
    }
    // A layer reaches a cell within its size (the height of open fluid there) of its centroid.
    let sizes: Vec<f64> = cells.iter().map(|&c| cell_size(mesh, c)).collect();
    let heights: HashMap<usize, (f64, f64)> =
        cells.iter().zip(centroids.iter().zip(&sizes)).map(|(&c, (x, &size))| (c, (film_height(layers, x, size).unwrap_or(size), size))).collect();
    // The mouths' weights; the squeeze's, no film thinner than its cell's `SQUEEZE_LEAST_HEIGHT`.
    let open = sizes.iter().map(|s| s.powi(2)).fold(0.0, f64::max);
    let permeability = |k: &dyn Fn(f64, f64) -> f64| heights.iter().map(|(&c, &(h, size))| (c, k(h, size))).collect::<HashMap<usize, f64>>();
    let system = |k: HashMap<usize, f64>| FilmSystem::new(mesh, graph, cells, mouths, gaps, floored(mesh, k, open));
    let weights = system(permeability(&|h, _| h * h)).solve_mouths();
    let squeeze = system(permeability(&|h, size| h.max(SQUEEZE_LEAST_HEIGHT * size).powi(2))).solve_squeeze();
    // Definite unless a cell is degenerate (no permeability anywhere): then the caller's
    // fallback, the nearest mouth; a squeeze that cannot be solved is left out (zero).
    let Some(w) = weights else {
        return no_film();
    };
    let m = mouths.len();
    centroids
        .into_iter()
        .enumerate()
        .map(|(i, centroid)| {
            let row: Vec<f64> = (0..m).map(|j| w[(i, j)].max(0.0)).collect();
            let sum: f64 = row.iter().sum();
            let kept: Vec<(usize, f64)> = row.iter().enumerate().filter(|(_, &v)| v >= LEAST_WEIGHT * sum).map(|(j, &v)| (mouths[j], v)).collect();
            let total: f64 = kept.iter().map(|(_, v)| v).sum();
            let weights = kept.into_iter().map(|(mouth, v)| (mouth, v / total)).collect();
            CellFilm { centroid, weights, squeeze: squeeze.as_ref().map_or(0.0, |s| s[(i, 0)].max(0.0)) }
        })
        .collect()
}

/// The permeability `k(c)` of cell `c`: a gap's cell's from `gap` (the others, its mouths, are
/// open fluid: their size squared), raised to `LEAST_PERMEABILITY` of the largest of the gap's
/// and the open fluid's `open` (the cells' largest size squared), so that the film's system
/// stays definite where the film's height is zero (a gap whose cells all lie by the solid lying
/// on its plane is sealed evenly).
fn floored<const D: usize>(mesh: &Mesh<D>, gap: HashMap<usize, f64>, open: f64) -> impl Fn(usize) -> f64 + '_ {
    let floor = LEAST_PERMEABILITY * gap.values().copied().fold(open, f64::max);
    move |c| gap.get(&c).copied().unwrap_or_else(|| cell_size(mesh, c).powi(2)).max(floor)
}

/// The two-point flux system of a gap's film (module documentation) with the permeability
/// `k(cell)`: its matrix, and the right-hand sides of its mouths (a column each, the mouth's
/// pressure one and the others' zero) and of the squeeze (the measure of each cell's facets on
/// gamma_f, every mouth's pressure zero).
struct FilmSystem {
    matrix: Vec<Triplet<usize, usize, f64>>,
    mouths: Mat<f64>,
    squeeze: Mat<f64>,
}

impl FilmSystem {
    fn new<const D: usize>(mesh: &Mesh<D>, graph: &FacetGraph, cells: &[usize], mouths: &[usize], gaps: &Gaps, k: impl Fn(usize) -> f64) -> Self {
        let ct = mesh.cell_type;
        let local: HashMap<usize, usize> = cells.iter().enumerate().map(|(i, &c)| (c, i)).collect();
        let n = cells.len();
        let mut out = FilmSystem { matrix: Vec::new(), mouths: Mat::zeros(n, mouths.len()), squeeze: Mat::zeros(n, 1) };
        let FacetGraph { topology, on_gamma_f } = graph;
        for (i, &c) in cells.iter().enumerate() {
            let centroid = mesh.vertex_centroid(c);
            for f in 0..ct.num_facets() {
                let corners = facet_corners(mesh, c, f);
                if on_gamma_f.contains(&topology.facet(ct, c, f)) {
                    out.squeeze[(i, 0)] += piece_measure(&corners);
                    continue;
                }
                let Some(nb) = topology.neighbour(ct, c, f) else { continue };
                let at: [f64; D] = std::array::from_fn(|d| corners.iter().map(|x| x[d]).sum::<f64>() / D as f64);
                let resistance = |cell: usize, x: &[f64; D]| distance(x, &at) / k(cell);
                let t = piece_measure(&corners) / (resistance(c, &centroid) + resistance(nb, &mesh.vertex_centroid(nb)));
                out.matrix.push(Triplet::new(i, i, t));
                match local.get(&nb) {
                    Some(&j) => out.matrix.push(Triplet::new(i, j, -t)),
                    None => {
                        let mouth = mouths.binary_search(&gaps.kept_index[nb]).expect("a kept neighbour of a gap's cell is one of its mouths");
                        out.mouths[(i, mouth)] += t;
                    }
                }
            }
        }
        out
    }

    /// The solution for the mouths' right-hand sides; `None` where the matrix is not definite
    /// or the solution not finite.
    fn solve_mouths(&self) -> Option<Mat<f64>> {
        self.solve(&self.mouths)
    }

    /// The solution for the squeeze's right-hand side (as [`Self::solve_mouths`]).
    fn solve_squeeze(&self) -> Option<Mat<f64>> {
        self.solve(&self.squeeze)
    }

    fn solve(&self, rhs: &Mat<f64>) -> Option<Mat<f64>> {
        let n = self.squeeze.nrows();
        let llt = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &self.matrix).ok()?.sp_cholesky(Side::Lower).ok()?;
        let x = llt.solve(rhs);
        (0..n).all(|i| (0..x.ncols()).all(|j| x[(i, j)].is_finite())).then_some(x)
    }
}
