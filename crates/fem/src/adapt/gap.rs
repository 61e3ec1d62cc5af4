//! The fluid cut off where a solid closes on a rigid plane, or two bodies close on each other
//! (valve closure).
//!
//! Where a solid presses on a rigid plane (a wall or a symmetry plane) the fluid layer between
//! them is thinner than any cell: the adapted mesh cannot follow it, and its cells would leave a
//! leak path across the contact (a cell straddling the solid's face where gamma_f ends above the
//! plane: a leaflet closed on a symmetry line leaked 0.6 % of the peak flux, steadily, before
//! the cut, and 3e-7 once settled after it, `tests/contact.rs`).
//! Such closed-gap cells leave the fluid system instead, from the step the solid's contact
//! boundary touches the plane ([`GapPlane::is_closed`]) until it leaves it:
//!
//! * the **gap layer** of a plane is the union, over the pieces of the solid's surfaces (gamma_s
//!   and its contact boundaries) whose corners all lie within `cut_off` of the plane, of the
//!   convex polytope between the piece and its projection onto the plane (a trapezoid in 2D, a
//!   prism in 3D; flat where the piece lies on the plane);
//! * a fluid cell that meets the gap layer (by the separating-axis test, touching counts) is
//!   removed ([`remove_closed_gaps`]), but where gamma_s itself is the face pressed on the plane
//!   (a 3D leaflet's coaptation face), only on the gap's side of gamma_s: the fluid behind it
//!   stays and presses the solid onto the plane;
//! * fluid the cut leaves walled in, away from gamma_f and from every boundary that sets the
//!   pressure's level, is removed too;
//! * the facets between kept and removed cells that are not on gamma_f become the boundary
//!   [`CLOSED_GAP`], where the fluid is held at rest like the plane (its Dirichlet condition is
//!   the caller's);
//! * the sides of gamma_f facets whose fluid was cut off (the other side's kept), and where
//!   gamma_s is pressed on a plane the sides of the facets lying on it, are listed with the kept
//!   cell at the gap's mouth nearest each ([`CutSide`], [`Adapted::cut_sides`]): a gap this thin
//!   still holds a film of blood at the pressure of the fluid it opens to, which the caller puts
//!   on them as a load (without it a leaflet pressed on its plane by the pressure behind it could
//!   not be lifted off by the pressure in front);
//! * each step adapts the original mesh again, so the cells come back in the first step after
//!   the contact boundary has left the plane.
//!
//! Between two bodies (a contact boundary against another body's) the layers are built the same
//! way with the nearest points on the other body's contact boundary in place of the plane's
//! projection ([`layer_towards`]); the caller decides when the contact is closed and which
//! pieces face which boundary.
//!
//! The kept cells keep their P1-discontinuous pressure and their zero divergence; with the fluid
//! at rest on the new walls the global flux balance holds exactly (counting, where gamma_f is
//! left with fluid on one side only, the flux the solid sweeps through it). What is lost is the
//! fluid in the cut cells, which the closed contact has pinched off.

use super::enclosed::centroid;
use super::{Adapted, GammaFacet, Surface};
use crate::mesh::{BoundaryFacet, Mesh, Topology, NO_CELL};
use film::Films;
use rstar::primitives::GeomWithData;
use rstar::RTree;
use std::collections::{HashMap, HashSet};

mod film;

/// Name of the boundary [`remove_closed_gaps`] gives the facets between kept and cut-off cells.
pub const CLOSED_GAP: &str = "closed_gap";

/// A side of a gamma_f facet whose fluid a closed gap cut off, the other side's kept, or, where
/// gamma_s lies on a plane it is pressed on, the side beyond the plane ([`remove_closed_gaps`]).
/// A real gap this thin still holds a film of blood, open to the fluid at the gap's mouth, which
/// loads the solid with its pressure; cut off, the side would carry no load at all, and a leaflet
/// pressed on its plane by the pressure behind it could not be lifted off by the ventricle's
/// (`runs/valve-3d-sector/NOTES.md`, session 46). The caller loads these sides with the pressure
/// of `mouth`, or with the film's mean of the mouths' pressures by Reynolds' equation, `film`.
#[derive(Clone, Debug, PartialEq)]
pub struct CutSide<const D: usize> {
    /// The facet: its index in [`Adapted::gamma_f`].
    pub facet: usize,
    /// The facet's unit normal pointing into the side cut off (out of the solid where gamma_s is
    /// its boundary).
    pub normal: [f64; D],
    /// The kept cell at the gap's mouth nearest the facet: the one across the [`CLOSED_GAP`]
    /// facet whose centroid is nearest the facet's; `None` where there is none.
    pub mouth: Option<usize>,
    /// The closed gap the side opens to, an index into [`Adapted::gap_mouths`]: the region of
    /// cut-off cells its own cell was in, or, for a facet lying on a plane (no cell on that side),
    /// a region `mouth` is a mouth of; `None` where there is none.
    pub gap: Option<usize>,
    /// The film's pressure at the facet by Reynolds' equation on the gap's cells (module
    /// `film`): the weights `w_m` of the gap's mouths (kept cells, ascending) in its mean
    /// `p = sum_m w_m p_m`, at the cell the side lost or, for a facet lying on a plane, at the
    /// gap's cell nearest the facet; `w_m >= 0`, summing to one. Empty where the gap has no mouth
    /// or its film's system could not be solved.
    pub film: Vec<(usize, f64)>,
    /// The film's squeeze at the same cell: its pressure per `12 mu` when the gap's faces on
    /// gamma_f all move into it at unit speed, the mouths' pressures zero (module `film`; a
    /// length's inverse); 0 where `film` is empty. A caller adds `12 mu squeeze v_n` to the
    /// film's pressure, `v_n` the solid's speed into the film at the facet.
    pub squeeze: f64,
}

/// The height, as a fraction of [`GapPlane::cut_off`], within which a contact boundary closes
/// its gap ([`GapPlane::is_closed`]): 37.5 um for the 3D valve's 0.75 mm. The contact's Newton
/// solve closes a touching gap to round-off, but a leaflet's band can hover just off its plane,
/// lifted for a step by its films' and the fluid's loads: the closed 3D valve 15 um off after a
/// step of a diastole trial, 34 um after a step of a run (session 52, `runs/valve-3d-sector/NOTES.md`).
/// With the test at round-off (`1e-6 cut_off` until then) the cells came back for the next step
/// and the valve leaked through them as through an open gap (16 ml/s, whole valve). A gap this
/// thin keeps its film (and the film's pressure) and leaks as `h^3`: between plates 10 mm wide
/// and 5 mm long, at 75 mmHg, 37.5 um of blood pass 0.15 ml/s for the whole valve.
pub const CLOSED_WITHIN: f64 = 0.05;

/// A rigid plane and the gap below which the fluid between it and the solid is cut off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GapPlane<const D: usize> {
    pub point: [f64; D],
    /// Unit normal, pointing to the side the solid stays on.
    pub normal: [f64; D],
    /// Pieces whose corners all lie within this distance of the plane make the gap layer; 0
    /// cuts nothing off.
    pub cut_off: f64,
}

impl<const D: usize> GapPlane<D> {
    /// The signed distance `(x - point) . normal`.
    pub fn distance(&self, x: &[f64; D]) -> f64 {
        (0..D).map(|d| (x[d] - self.point[d]) * self.normal[d]).sum()
    }

    /// Whether `surface` (the solid's contact boundary) closes the gap: a corner within
    /// [`CLOSED_WITHIN`] `cut_off` of the plane, or beyond.
    pub fn is_closed(&self, surface: &Surface<D>) -> bool {
        surface.points.iter().any(|x| self.distance(x) <= CLOSED_WITHIN * self.cut_off)
    }

    /// The gap layer below `surface`: one convex polytope (its corners) per piece whose corners
    /// all lie within `cut_off` of the plane: the piece's `D` corners and their projections.
    pub fn layer(&self, surface: &Surface<D>) -> Vec<Vec<[f64; D]>> {
        surface
            .pieces
            .iter()
            .filter_map(|piece| {
                let corners = piece.map(|p| surface.points[p]);
                let close = corners.iter().all(|x| self.distance(x) <= self.cut_off);
                close.then(|| {
                    let feet = corners.map(|x| {
                        let g = self.distance(&x);
                        std::array::from_fn(|d| x[d] - g * self.normal[d])
                    });
                    corners.into_iter().chain(feet).collect()
                })
            })
            .collect()
    }
}

/// The gap layer between two bodies in contact (a contact boundary against another solid's): one
/// convex polytope per piece of `pieces` (segments in 2D, triangles in 3D, of one body) whose
/// corners all lie within `cut_off` of `other` (a surface of the other body): the piece's corners
/// and their nearest points on `other`. As for a plane ([`GapPlane::layer`]), the cells the layer
/// meets leave the fluid while the bodies touch.
pub fn layer_towards<const D: usize>(pieces: impl IntoIterator<Item = [[f64; D]; D]>, other: &Surface<D>, cut_off: f64) -> Vec<Vec<[f64; D]>> {
    pieces
        .into_iter()
        .filter_map(|corners| {
            let feet: Vec<_> = corners.iter().map(|x| other.project(x)).collect::<Option<Vec<_>>>()?;
            feet.iter().all(|f| f.distance <= cut_off).then(|| corners.into_iter().chain(feet.iter().map(|f| f.x)).collect())
        })
        .collect()
}

/// The mean size `(D! |K|)^(1/D)` of the cells of `mesh` that contain one of `points` (0 for
/// none): the natural `cut_off` of a contact between two bodies, one cell of the fluid mesh
/// where they touch.
pub fn cell_size_at<const D: usize>(mesh: &Mesh<D>, points: &[[f64; D]]) -> f64 {
    let mut cells: Vec<usize> = points.iter().flat_map(|x| crate::locate::cells_containing(mesh, x)).map(|(c, _)| c).collect();
    cells.sort_unstable();
    cells.dedup();
    if cells.is_empty() {
        return 0.0;
    }
    let sizes: f64 = cells.iter().map(|&c| cell_size(mesh, c)).sum();
    sizes / cells.len() as f64
}

/// The size `(D! |K|)^(1/D)` of cell `c` of `mesh`.
fn cell_size<const D: usize>(mesh: &Mesh<D>, c: usize) -> f64 {
    let factorial = if D == 3 { 6.0 } else { 2.0 };
    (factorial * mesh.signed_vertex_measure(c).abs()).powf(1.0 / D as f64)
}

/// The natural `cut_off` of a plane that bounds the fluid (a wall, a symmetry line): the mean
/// extent along its normal of the cells of `mesh` with a vertex on it (within `1e-9` of the
/// mesh's size), one cell. 0 where no cell touches it or cells lie on both of its sides: a plane
/// inside the fluid (a stop) has fluid beyond it, and no gap closes there.
pub fn cell_height_at<const D: usize>(mesh: &Mesh<D>, plane: &GapPlane<D>) -> f64 {
    let (lo, hi) = crate::mesh::bounding_box(&mesh.points);
    let tol = 1e-9 * (0..D).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    let (mut sum, mut count) = (0.0, 0usize);
    for c in 0..mesh.num_cells() {
        let g: Vec<f64> = mesh.cell_vertices(c).iter().map(|&v| plane.distance(&mesh.points[v])).collect();
        let (min, max) = g.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        if min < -tol {
            if max > -tol {
                return 0.0;
            }
        } else if min <= tol {
            sum += max - min;
            count += 1;
        }
    }
    if count == 0 {
        0.0
    } else {
        sum / count as f64
    }
}

/// `adapted` without the fluid cells that meet the gap layers (see the module documentation):
/// every cell that meets one of `layers`, and every cell that meets one of `pressed` (the layers
/// below gamma_s `surface` where gamma_s is itself the contact boundary) on the gap's side of
/// gamma_s. A cell stays although it touches a pressed layer (as the cells beside gamma_f there
/// do) when its vertices all lie on gamma_s (the adaptation's [`Adapted::on_surface`]) or behind
/// it, and its centroid behind it ([`Surface::side`] at most a round-off: the side its outward
/// normals point away from, where the solid is, and the fluid beyond a thin solid coupled on one
/// face): the fluid behind presses the solid onto the plane. Cut off with the gap, it left the
/// solid's surface without a load over the whole contact: the 3D valve sector's leaflet sprang
/// 0.2-0.4 mm back off its plane at the next step, and the contact chattered until the run failed
/// (`runs/valve-3d-sector/NOTES.md`, sessions 34-35). Where the contact boundary is another face
/// (a 2D leaflet's tip), both sides of gamma_s next to it are cut off as before: which fluid cells
/// border the end of gamma_s from behind there changes from step to step with the adaptation, and
/// with a load on them the tip jittered (`tests/contact.rs`, the leaflet that seals). Then the
/// pockets the cut leaves (away from gamma_f and from every boundary whose tag is in
/// `open`) are cut off too. Cells renumbered in their old order, gamma_f seen from the kept cells
/// only (facets with no kept cell on either side dropped), the facets between kept and removed
/// cells off gamma_f tagged [`CLOSED_GAP`] (the name is added even when there are none, so a
/// condition on it always finds its boundary), [`super::AdaptStats::closed_gap_cells`] and
/// [`super::AdaptStats::closed_gap_pieces`] set. The sides of gamma_f the cut takes, and those of
/// the facets lying on one of `pressed_on` (the planes of `pressed`) beyond them, become
/// [`Adapted::cut_sides`].
pub fn remove_closed_gaps<const D: usize>(
    adapted: Adapted<D>,
    layers: &[Vec<[f64; D]>],
    pressed: &[Vec<[f64; D]>],
    pressed_on: &[GapPlane<D>],
    surface: &Surface<D>,
    open: &[u32],
) -> Adapted<D> {
    let mesh = &adapted.mesh;
    let (lo, hi) = crate::mesh::bounding_box(&mesh.points);
    let tol = 1e-9 * (0..D).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    let boxes = |polytopes: &[Vec<[f64; D]>]| polytopes.iter().map(|l| crate::mesh::bounding_box(l)).collect::<Vec<_>>();
    let (layer_boxes, pressed_boxes) = (boxes(layers), boxes(pressed));
    let behind = |x: &[f64; D]| surface.side(x).is_some_and(|s| s <= tol);
    let behind_gamma_s = |c: usize| {
        let vertices = mesh.cell_vertices(c);
        vertices.iter().all(|&v| adapted.on_surface[v] || behind(&mesh.points[v])) && behind(&mesh.vertex_centroid(c))
    };
    let mut cut = HashSet::new();
    let mut corners = Vec::new();
    for c in 0..mesh.num_cells() {
        corners.clear();
        corners.extend(mesh.cell_vertices(c).iter().map(|&v| mesh.points[v]));
        let (clo, chi) = crate::mesh::bounding_box(&corners);
        let meets = |polytopes: &[Vec<[f64; D]>], boxes: &[([f64; D], [f64; D])]| {
            polytopes.iter().zip(boxes).any(|(layer, (llo, lhi))| {
                (0..D).all(|d| clo[d] <= lhi[d] + tol && llo[d] <= chi[d] + tol) && convex_hulls_meet(&corners, layer, tol)
            })
        };
        if meets(layers, &layer_boxes) || (meets(pressed, &pressed_boxes) && !behind_gamma_s(c)) {
            cut.insert(c);
        }
    }
    // The floods over the cells (pockets, closed gaps) share one facet graph, built only when
    // something is cut off.
    let (gaps, films) = if cut.is_empty() {
        (Gaps::default(), Films::default())
    } else {
        let graph = FacetGraph::of(&adapted);
        cut.extend(pockets(&adapted, &graph, &cut, open));
        let gaps = Gaps::of_cut(&adapted, &graph, &cut);
        let films = Films::solve(&adapted, &graph, &gaps, &[layers, pressed].concat());
        (gaps, films)
    };
    let count = cut.len();
    let lost_sides = lost_sides(&adapted, &cut, &gaps, pressed_on);
    let mut out = without_cells(adapted, &cut, Some(CLOSED_GAP));
    out.cut_sides = cut_sides(&out, &lost_sides, &gaps, &films);
    out.gap_mouths = gaps.mouths;
    out.stats.closed_gap_cells = count;
    out.stats.closed_gap_pieces = layers.len() + pressed.len();
    out.stats.coupling_facets = out.gamma_f.len();
    out
}

/// The closed gaps of a cut: the connected regions of its cells (joined across facets off
/// gamma_f, numbered in the order of their lowest cell), and each region's mouths, the kept cells
/// across its facets off gamma_f, where the film of blood in the gap opens to the fluid.
#[derive(Default)]
struct Gaps {
    /// The region of each cut cell.
    of_cell: HashMap<usize, usize>,
    /// The cells of each region, in the order flooded.
    cells: Vec<Vec<usize>>,
    /// The mouths of each region, in the kept cells' numbering ([`without_cells`]'s), ascending.
    mouths: Vec<Vec<usize>>,
    /// Each cell's number among the kept ([`kept_numbering`]).
    kept_index: Vec<usize>,
}

impl Gaps {
    /// The closed gaps of the cells `cut` of `adapted` (`graph` its [`FacetGraph`]).
    fn of_cut<const D: usize>(adapted: &Adapted<D>, graph: &FacetGraph, cut: &HashSet<usize>) -> Self {
        let mesh = &adapted.mesh;
        let ct = mesh.cell_type;
        let FacetGraph { topology, on_gamma_f } = graph;
        let kept_index = kept_numbering(mesh.num_cells(), cut);
        let mut seeds: Vec<usize> = cut.iter().copied().collect();
        seeds.sort_unstable();
        let mut gaps = Gaps { of_cell: HashMap::new(), cells: Vec::new(), mouths: Vec::new(), kept_index };
        for seed in seeds {
            if gaps.of_cell.contains_key(&seed) {
                continue;
            }
            let region = gaps.mouths.len();
            gaps.of_cell.insert(seed, region);
            let (mut flood, mut cells, mut mouths) = (vec![seed], vec![seed], Vec::new());
            while let Some(c) = flood.pop() {
                let across = (0..ct.num_facets()).filter(|&f| !on_gamma_f.contains(&topology.facet(ct, c, f)));
                for n in across.filter_map(|f| topology.neighbour(ct, c, f)) {
                    if !cut.contains(&n) {
                        mouths.push(gaps.kept_index[n]);
                    } else if let std::collections::hash_map::Entry::Vacant(e) = gaps.of_cell.entry(n) {
                        e.insert(region);
                        flood.push(n);
                        cells.push(n);
                    }
                }
            }
            mouths.sort_unstable();
            mouths.dedup();
            gaps.cells.push(cells);
            gaps.mouths.push(mouths);
        }
        gaps
    }

    /// The first region that `mouth` (a kept cell) is a mouth of.
    fn opening_at(&self, mouth: usize) -> Option<usize> {
        self.mouths.iter().position(|m| m.binary_search(&mouth).is_ok())
    }
}

/// The facets of an adapted mesh ([`Topology`]) and which of them lie on gamma_f: what the floods
/// over its cells ([`regions`], [`Gaps::of_cut`]) may cross.
struct FacetGraph {
    topology: Topology,
    /// The facets on gamma_f ([`Topology`]'s numbering).
    on_gamma_f: HashSet<usize>,
}

impl FacetGraph {
    fn of<const D: usize>(adapted: &Adapted<D>) -> Self {
        let topology = Topology::build(&adapted.mesh);
        let on_gamma_f = gamma_f_facets(&adapted.mesh, &adapted.gamma_f, &topology);
        FacetGraph { topology, on_gamma_f }
    }
}

/// The facets of `mesh` ([`Topology`]'s numbering) on gamma_f `gamma_f`.
fn gamma_f_facets<const D: usize>(mesh: &Mesh<D>, gamma_f: &[GammaFacet<D>], topology: &Topology) -> HashSet<usize> {
    let ct = mesh.cell_type;
    gamma_f.iter().flat_map(|g| g.sides).filter(|&s| s != NO_CELL).map(|(c, f)| topology.facet(ct, c, f)).collect()
}

/// The new number of each of `num_cells` cells once those in `removed` are gone (the kept in
/// their old order), `usize::MAX` for a removed one.
fn kept_numbering(num_cells: usize, removed: &HashSet<usize>) -> Vec<usize> {
    let mut new_cell = vec![usize::MAX; num_cells];
    for (k, c) in (0..num_cells).filter(|c| !removed.contains(c)).enumerate() {
        new_cell[c] = k;
    }
    new_cell
}

/// A side of a gamma_f facet the cut takes ([`lost_sides`]): which of the facet's sides, its cell
/// and the closed gap that cell was in (none for a facet on a plane, which has no cell on that
/// side).
#[derive(Clone, Copy, Debug)]
struct LostSide {
    side: usize,
    cell: Option<usize>,
    gap: Option<usize>,
}

/// For each facet of gamma_f in `adapted` that keeps a cell (as [`without_cells`] keeps them, in
/// order), the side whose cell is in `cut` while the other side's is kept, or, for a facet lying
/// on one of the planes `pressed_on` (its corners within `1e-6 cut_off`: the fluid mesh's
/// vertices moved onto gamma_s where it lies on the plane), the side beyond the plane: gamma_s
/// pressed on it, with
/// no fluid between them in the mesh but a film in the blood.
fn lost_sides<const D: usize>(adapted: &Adapted<D>, cut: &HashSet<usize>, gaps: &Gaps, pressed_on: &[GapPlane<D>]) -> Vec<Option<LostSide>> {
    let kept = |s: (usize, usize)| s != NO_CELL && !cut.contains(&s.0);
    let on_plane = |g: &GammaFacet<D>| {
        pressed_on.iter().any(|plane| g.vertices.iter().all(|&v| plane.distance(&adapted.mesh.points[v]).abs() <= 1e-6 * plane.cut_off))
    };
    adapted
        .gamma_f
        .iter()
        .filter(|g| g.sides.iter().any(|&s| kept(s)))
        .map(|g| {
            let lost = |i: usize| match g.sides[i] {
                NO_CELL => on_plane(g),
                (c, _) => cut.contains(&c),
            };
            let side = (0..2).find(|&i| lost(i) && kept(g.sides[1 - i]))?;
            let cell = Some(g.sides[side].0).filter(|_| g.sides[side] != NO_CELL);
            Some(LostSide { side, cell, gap: cell.and_then(|c| gaps.of_cell.get(&c).copied()) })
        })
        .collect()
}

/// The [`CutSide`]s of `out` (the kept cells, its boundary [`CLOSED_GAP`] set), from the side
/// each of its gamma_f facets lost ([`lost_sides`]), the closed gaps of the cut and their films.
fn cut_sides<const D: usize>(out: &Adapted<D>, lost: &[Option<LostSide>], gaps: &Gaps, films: &Films<D>) -> Vec<CutSide<D>> {
    debug_assert_eq!(lost.len(), out.gamma_f.len());
    if lost.iter().all(Option::is_none) {
        return Vec::new();
    }
    let mesh = &out.mesh;
    let mouths: Vec<GeomWithData<[f64; D], usize>> = mesh
        .boundary_facets(CLOSED_GAP)
        .unwrap_or_default()
        .into_iter()
        .map(|b| {
            let nodes = mesh.cell(b.cell);
            let corners: Vec<usize> = mesh.facet_local_nodes(b.facet)[..D].iter().map(|&k| nodes[k]).collect();
            GeomWithData::new(centroid(mesh, &corners), b.cell)
        })
        .collect();
    let mouths = RTree::bulk_load(mouths);
    out.gamma_f
        .iter()
        .zip(lost)
        .enumerate()
        .filter_map(|(facet, (g, side))| {
            let n = super::surface::piece_normal(&g.vertices.map(|v| mesh.points[v]));
            let lost = (*side)?;
            let sign = if lost.side == 1 { 1.0 } else { -1.0 };
            let at = centroid(mesh, &g.vertices);
            let mouth = mouths.nearest_neighbor(at).map(|m| m.data);
            let gap = lost.gap.or_else(|| gaps.opening_at(mouth?));
            let film = match lost.cell {
                Some(c) => films.at(c),
                None => gap.and_then(|gap| films.nearest(gap, &at)),
            };
            let (film, squeeze) = film.map(|f| (f.weights.clone(), f.squeeze)).unwrap_or_default();
            Some(CutSide { facet, normal: n.map(|c| sign * c), mouth, gap, film, squeeze })
        })
        .collect()
}

/// A region of kept fluid cells joined across facets off gamma_f ([`pockets`]).
struct Region {
    cells: Vec<usize>,
    /// A cell of it has a facet on a boundary that sets the pressure's level.
    reaches_open: bool,
    /// A cell of it has a facet on gamma_f.
    wets_gamma_f: bool,
}

/// The cells of `adapted` outside `cut` in regions joined across facets off gamma_f (flooded one
/// at a time; `graph` its [`FacetGraph`]); `open`: the tags of the boundaries that set the
/// pressure's level.
fn regions<const D: usize>(adapted: &Adapted<D>, graph: &FacetGraph, cut: &HashSet<usize>, open: &[u32]) -> Vec<Region> {
    let mesh = &adapted.mesh;
    let ct = mesh.cell_type;
    let FacetGraph { topology, on_gamma_f } = graph;
    let beside_open: HashSet<usize> = mesh.boundary.iter().filter(|b| open.contains(&b.tag)).map(|b| b.cell).collect();
    let mut flooded = vec![false; mesh.num_cells()];
    let mut regions = Vec::new();
    for seed in 0..mesh.num_cells() {
        if flooded[seed] || cut.contains(&seed) {
            continue;
        }
        flooded[seed] = true;
        let mut region = Region { cells: vec![seed], reaches_open: false, wets_gamma_f: false };
        let mut k = 0;
        while let Some(&c) = region.cells.get(k) {
            k += 1;
            region.reaches_open |= beside_open.contains(&c);
            for f in 0..ct.num_facets() {
                if on_gamma_f.contains(&topology.facet(ct, c, f)) {
                    region.wets_gamma_f = true;
                } else if let Some(n) = topology.neighbour(ct, c, f).filter(|n| !flooded[*n] && !cut.contains(n)) {
                    flooded[n] = true;
                    region.cells.push(n);
                }
            }
        }
        regions.push(region);
    }
    regions
}

/// The cells of `adapted` outside `cut` in pockets: regions ([`regions`]) that neither reach a
/// boundary whose tag is in `open` (one that sets the pressure's level: a traction, pressure,
/// free or Windkessel condition, or none) nor border gamma_f. Walls alone bound such a pocket,
/// where the velocity is held: the level of its pressure is free and the system singular. (A
/// region that borders gamma_f has it set through the solid, by the volume it holds.) Where
/// every region is a pocket, none is taken: the problem then fixes the pressure itself.
fn pockets<const D: usize>(adapted: &Adapted<D>, graph: &FacetGraph, cut: &HashSet<usize>, open: &[u32]) -> Vec<usize> {
    let regions = regions(adapted, graph, cut, open);
    let is_pocket = |r: &Region| !r.reaches_open && !r.wets_gamma_f;
    if regions.iter().all(is_pocket) {
        return Vec::new();
    }
    regions.into_iter().filter(is_pocket).flat_map(|r| r.cells).collect()
}

/// Whether the convex hulls of the point sets `a` and `b` (simplices, prisms; possibly flat)
/// meet, within `tol`: no axis separates them by more than `tol`. The axes tried are those of
/// the separating-axis theorem for convex polytopes (2D: the normals of all edges; 3D: the cross
/// products of all pairs of edges, which include the faces' normals), over every pair of points
/// of each set as its edges, which is a superset and so still exact.
pub fn convex_hulls_meet<const D: usize>(a: &[[f64; D]], b: &[[f64; D]], tol: f64) -> bool {
    let mut edges: Vec<[f64; D]> = Vec::new();
    for set in [a, b] {
        for i in 0..set.len() {
            for j in i + 1..set.len() {
                let e: [f64; D] = std::array::from_fn(|d| set[j][d] - set[i][d]);
                if e.iter().any(|v| v.abs() > tol) {
                    edges.push(e);
                }
            }
        }
    }
    let separates = |axis: &[f64; D]| {
        let norm = axis.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm <= 0.0 {
            return false;
        }
        let project = |set: &[[f64; D]]| {
            set.iter()
                .map(|x| (0..D).map(|d| x[d] * axis[d]).sum::<f64>() / norm)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
        };
        let ((alo, ahi), (blo, bhi)) = (project(a), project(b));
        blo > ahi + tol || alo > bhi + tol
    };
    match D {
        2 => !edges.iter().any(|e| {
            let mut n = [0.0; D];
            n[0] = -e[1];
            n[1] = e[0];
            separates(&n) || separates(e)
        }),
        3 => {
            let cross = |u: &[f64; D], v: &[f64; D]| -> [f64; D] {
                std::array::from_fn(|d| u[(d + 1) % 3] * v[(d + 2) % 3] - u[(d + 2) % 3] * v[(d + 1) % 3])
            };
            !(edges.iter().any(&separates) || edges.iter().enumerate().any(|(i, u)| edges[i + 1..].iter().any(|v| separates(&cross(u, v)))))
        }
        _ => true,
    }
}

/// `adapted` without the cells `removed`: cells, vertices and boundary facets renumbered in
/// their old order, gamma_f seen from the kept cells only (a side whose cell is removed becomes
/// [`NO_CELL`]; facets with no kept cell left dropped). With `walls`, the facets between a kept
/// and a removed cell that are not on gamma_f are added to the boundary under that name. No
/// [`Adapted::cut_sides`]: they are found after it ([`remove_closed_gaps`]).
pub(super) fn without_cells<const D: usize>(adapted: Adapted<D>, removed: &HashSet<usize>, walls: Option<&str>) -> Adapted<D> {
    let Adapted { mesh, new_to_old_cell, on_surface, gamma_f, stats, .. } = adapted;
    let nc = mesh.num_cells();
    let npc = mesh.nodes_per_cell();
    let new_cell = kept_numbering(nc, removed);
    let kept = nc - removed.len();
    // Facets between kept and removed cells, off gamma_f (before renumbering).
    let mut wall_facets = Vec::new();
    if walls.is_some() && !removed.is_empty() {
        let topology = Topology::build(&mesh);
        let ct = mesh.cell_type;
        let on_gamma_f = gamma_f_facets(&mesh, &gamma_f, &topology);
        for c in (0..nc).filter(|&c| new_cell[c] != usize::MAX) {
            for f in 0..ct.num_facets() {
                let beside_removed = topology.neighbour(ct, c, f).is_some_and(|n| new_cell[n] == usize::MAX);
                if beside_removed && !on_gamma_f.contains(&topology.facet(ct, c, f)) {
                    wall_facets.push((new_cell[c], f));
                }
            }
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
    if let Some(name) = walls {
        let tag = out.boundary_names.iter().map(|(_, t)| *t).chain(out.boundary.iter().map(|b| b.tag)).max().unwrap_or(0) + 1;
        out.boundary.extend(wall_facets.into_iter().map(|(cell, facet)| BoundaryFacet { cell, facet, tag }));
        out.add_boundary_name(name, tag);
    }
    let renumber_side = |(c, f): (usize, usize)| if c == usize::MAX || new_cell[c] == usize::MAX { NO_CELL } else { (new_cell[c], f) };
    let gamma_f = gamma_f
        .into_iter()
        .map(|g| GammaFacet { vertices: g.vertices.map(|v| new_point[v]), sides: g.sides.map(renumber_side), location: g.location })
        .filter(|g| g.sides.iter().any(|&s| s != NO_CELL))
        .collect::<Vec<_>>();
    let on_surface = (0..mesh.points.len()).filter(|&p| new_point[p] != usize::MAX).map(|p| on_surface[p]).collect();
    let new_to_old_cell = (0..nc).filter(|&c| new_cell[c] != usize::MAX).map(|c| new_to_old_cell[c]).collect();
    Adapted { mesh: out, new_to_old_cell, on_surface, gamma_f, cut_sides: Vec::new(), gap_mouths: Vec::new(), stats }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Between two bodies: a piece within `cut_off` of the other surface gives the polytope of its
    /// corners and their nearest points; one farther off gives none. The size of the cells at a
    /// point: `(2 |K|)^(1/2)` of the triangles holding it.
    #[test]
    fn layers_between_two_surfaces_and_the_cell_size_at_them() {
        let other = Surface::from_pieces(vec![[0.0, 0.0], [1.0, 0.0]], vec![[0, 1]]).unwrap();
        let near = [[0.2, 0.05], [0.4, 0.05]];
        let layers = layer_towards([near], &other, 0.1);
        assert_eq!(layers.len(), 1);
        let expected = [[0.2, 0.05], [0.4, 0.05], [0.2, 0.0], [0.4, 0.0]];
        assert!(layers[0].iter().zip(&expected).all(|(a, b)| (a[0] - b[0]).abs() < 1e-15 && (a[1] - b[1]).abs() < 1e-15), "{layers:?}");
        assert!(layer_towards([[[0.2, 0.05], [0.4, 0.2]]], &other, 0.1).is_empty(), "a corner beyond the cut-off");
        let square = crate::generate::rectangle_triangles(0.0, 2.0, 0.0, 2.0, 1, 1, crate::generate::DiagonalPattern::Right);
        assert!((cell_size_at(&square, &[[0.5, 1.5]]) - 2.0).abs() < 1e-12);
        assert_eq!(cell_size_at(&square, &[[3.0, 3.0]]), 0.0, "no cell: nothing cut off");
    }

    #[test]
    fn separating_axes_tell_meeting_hulls() {
        let tri = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        // A flat layer on the triangle's edge y = 0 meets it; one below by 0.1 does not.
        assert!(convex_hulls_meet(&tri, &[[0.2, 0.0], [0.4, 0.0]], 1e-12));
        assert!(!convex_hulls_meet(&tri, &[[0.2, -0.1], [0.4, -0.1]], 1e-12));
        // Beyond the hypotenuse (only its normal separates).
        assert!(!convex_hulls_meet(&tri, &[[0.6, 0.6], [0.9, 0.6], [0.6, 0.9]], 1e-12));
        assert!(convex_hulls_meet(&tri, &[[0.5, 0.5], [0.9, 0.6], [0.6, 0.9]], 1e-12));
        // Collinear segments apart along their line (only the line's direction separates).
        assert!(!convex_hulls_meet(&[[0.0, 0.0], [1.0, 0.0]], &[[1.5, 0.0], [2.0, 0.0]], 1e-12));
        let tet = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(convex_hulls_meet(&tet, &[[0.1, 0.1, 0.0], [0.3, 0.1, 0.0], [0.1, 0.3, 0.0]], 1e-12));
        assert!(!convex_hulls_meet(&tet, &[[0.6, 0.6, 0.6], [0.9, 0.6, 0.6], [0.6, 0.9, 0.6]], 1e-12));
        // Two skew edges, separated only by the cross product of their directions.
        let edge = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        assert!(!convex_hulls_meet(&edge, &[[0.5, -1.0, 0.1], [0.5, 1.0, 0.1]], 1e-12));
        assert!(convex_hulls_meet(&edge, &[[0.5, -1.0, 0.0], [0.5, 1.0, 0.0]], 1e-12));
    }

    #[test]
    fn the_natural_cut_off_is_one_cell_at_a_boundary_plane_and_none_inside() {
        use crate::generate::{rectangle_triangles, DiagonalPattern};
        let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 4, 8, DiagonalPattern::Right);
        let wall = GapPlane { point: [0.0, 0.0], normal: [0.0, 1.0], cut_off: 0.0 };
        assert!((cell_height_at(&mesh, &wall) - 0.125).abs() < 1e-14);
        let inside = GapPlane { point: [0.0, 0.5], normal: [0.0, 1.0], cut_off: 0.0 };
        assert_eq!(cell_height_at(&mesh, &inside), 0.0);
    }

    /// A flat piece of gamma_s at height 0.05 over [0.3, 0.7] of the unit square, its normal down
    /// to the plane y = 0 (closed), its layer down to the plane, cut off as a layer of another
    /// face (`both_sides`) or as one of gamma_s pressed on the plane.
    fn cut_below_a_flat_piece(both_sides: bool) -> (Adapted<2>, Vec<Vec<[f64; 2]>>, f64) {
        use crate::generate::{rectangle_triangles, DiagonalPattern};
        let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 8, 8, DiagonalPattern::Right);
        let surface = Surface::from_pieces(vec![[0.3, 0.05], [0.7, 0.05]], vec![[0, 1]]).unwrap();
        let adapted = super::super::adapt(&mesh, &surface, 0.2).unwrap();
        let plane = GapPlane { point: [0.0, 0.0], normal: [0.0, 1.0], cut_off: 0.1 };
        assert!(plane.is_closed(&Surface::from_pieces(vec![[0.3, 0.0], [0.7, 0.0]], vec![[0, 1]]).unwrap()));
        assert!(!plane.is_closed(&surface));
        let layer = plane.layer(&surface);
        let (before, gamma_f_before) = (adapted.mesh.num_cells(), adapted.gamma_f_measure());
        assert!(gamma_f_before > 0.3);
        let (cut_both, pressed) = if both_sides { (&layer[..], &[][..]) } else { (&[][..], &layer[..]) };
        let cut = remove_closed_gaps(adapted, cut_both, pressed, &[], &surface, &[]);
        let removed = before - cut.mesh.num_cells();
        assert_eq!(cut.stats.closed_gap_cells, removed);
        assert_eq!(cut.stats.closed_gap_pieces, 1, "the one piece of gamma_s makes the layer");
        assert!(removed > 0);
        assert!(!cut.mesh.boundary_facets(CLOSED_GAP).unwrap().is_empty(), "walls bound the hole");
        // The kept mesh and the hole tile the square.
        let kept: f64 = (0..cut.mesh.num_cells()).map(|c| cut.mesh.signed_vertex_measure(c)).sum();
        assert!(kept < 1.0 - 0.4 * 0.05 && kept > 0.5);
        let meeting = (0..cut.mesh.num_cells())
            .map(|c| cut.mesh.cell_vertices(c).iter().map(|&v| cut.mesh.points[v]).collect::<Vec<_>>())
            .filter(|corners| convex_hulls_meet(corners, &layer[0], 1e-12))
            .collect();
        (cut, meeting, gamma_f_before)
    }

    /// Cut off as another face's layer, no kept cell meets it, and gamma_f on it is gone.
    #[test]
    fn cells_meeting_the_layer_leave_with_walls_where_they_were() {
        let (cut, meeting, _) = cut_below_a_flat_piece(true);
        assert!(meeting.is_empty(), "{meeting:?}");
        assert!(cut.gamma_f.is_empty(), "both sides of the piece cut off");
        assert!(cut.cut_sides.is_empty(), "no facet left to carry a film");
    }

    /// Where gamma_s itself is pressed on the plane, the cells above it (behind gamma_s) stay,
    /// and gamma_f with them, seen from above: the fluid there keeps pressing the solid down.
    #[test]
    fn the_fluid_behind_gamma_s_pressed_on_the_plane_stays() {
        let (cut, meeting, gamma_f_before) = cut_below_a_flat_piece(false);
        assert!(!meeting.is_empty());
        for corners in &meeting {
            assert!(corners.iter().all(|x| x[1] >= 0.05 - 1e-12), "a kept cell below gamma_s meets the layer: {corners:?}");
        }
        assert!((cut.gamma_f_measure() - gamma_f_before).abs() < 1e-12, "gamma_f {} of {gamma_f_before}", cut.gamma_f_measure());
        assert!(cut.gamma_f.iter().all(|g| g.sides.iter().filter(|&&s| s != NO_CELL).count() == 1));
    }

    /// The sides cut off below gamma_s pressed on the plane: one per facet of gamma_f (each lost
    /// the side below it), its normal down into the gap, its mouth a kept cell within a cell of
    /// the end of the piece on the facet's side of its middle (x = 0.5): where the gap opens to
    /// the fluid that would fill it.
    #[test]
    fn each_facet_over_the_gap_has_its_cut_side_and_the_mouth_nearest_it() {
        let (cut, _, _) = cut_below_a_flat_piece(false);
        let mut facets: Vec<usize> = cut.cut_sides.iter().map(|s| s.facet).collect();
        facets.dedup();
        assert_eq!(facets, (0..cut.gamma_f.len()).collect::<Vec<_>>());
        let mesh = &cut.mesh;
        for side in &cut.cut_sides {
            assert!((side.normal[0]).abs() < 1e-12 && (side.normal[1] + 1.0).abs() < 1e-12, "{:?}", side.normal);
            let g = &cut.gamma_f[side.facet];
            assert_eq!(g.sides[1], NO_CELL, "the plus side, below gamma_s, is cut off");
            let x = 0.5 * (mesh.points[g.vertices[0]][0] + mesh.points[g.vertices[1]][0]);
            let mouth = side.mouth.expect("the gap has a mouth");
            let m = mesh.vertex_centroid(mouth);
            let end = if x < 0.5 { [0.3, 0.05] } else { [0.7, 0.05] };
            assert!((m[0] - end[0]).hypot(m[1] - end[1]) < 0.125, "facet at x = {x}: mouth at {m:?}, not by the end of the piece");
        }
    }

    /// The gap below the flat piece is one region of cut cells, open at both ends of the piece:
    /// every cut side opens to it, and its mouths (the kept cells across its facets off gamma_f)
    /// lie by the piece's two ends, within 0.15 (the cells are 0.125 wide) of each end along x and
    /// below y = 0.2, none over the middle of the piece (across gamma_f), and hold each side's
    /// nearest mouth.
    #[test]
    fn the_sides_over_the_gap_open_to_its_mouths_at_both_ends() {
        let (cut, _, _) = cut_below_a_flat_piece(false);
        assert_eq!(cut.gap_mouths.len(), 1, "one gap");
        let mouths = &cut.gap_mouths[0];
        assert!(mouths.windows(2).all(|w| w[0] < w[1]), "ascending, each once");
        let by_end = |m: usize, end: f64| {
            let c = cut.mesh.vertex_centroid(m);
            (c[0] - end).abs() < 0.15 && c[1] < 0.2
        };
        assert!(mouths.iter().any(|&m| by_end(m, 0.3)) && mouths.iter().any(|&m| by_end(m, 0.7)), "open at both ends");
        for &m in mouths {
            assert!(by_end(m, 0.3) || by_end(m, 0.7), "mouth at {:?}", cut.mesh.vertex_centroid(m));
        }
        assert!(!cut.cut_sides.is_empty());
        for side in &cut.cut_sides {
            assert_eq!(side.gap, Some(0));
            assert!(mouths.binary_search(&side.mouth.expect("a mouth")).is_ok(), "the nearest mouth is one of the gap's");
        }
    }

    /// A contact boundary closes its gap when it comes within `CLOSED_WITHIN cut_off` of the
    /// plane, not only at round-off: a band hovering just off its plane keeps it closed.
    #[test]
    fn a_boundary_hovering_just_off_its_plane_keeps_the_gap_closed() {
        let plane = GapPlane { point: [0.0, 0.0], normal: [0.0, 1.0], cut_off: 0.75 };
        let at = |h: f64| Surface::from_pieces(vec![[0.3, h], [0.7, 0.5]], vec![[0, 1]]).unwrap();
        assert!(plane.is_closed(&at(0.0)) && plane.is_closed(&at(-1e-3)), "touching or beyond");
        assert!(plane.is_closed(&at(0.0148)), "15 um off, as after a step of a diastole trial");
        assert!(plane.is_closed(&at(0.99 * CLOSED_WITHIN * 0.75)));
        assert!(!plane.is_closed(&at(1.01 * CLOSED_WITHIN * 0.75)));
        assert!(!plane.is_closed(&at(0.11)), "off its plane");
    }

    /// gamma_s pressed flat on the plane y = 0 (the bottom of the unit square) over [0.3, 0.7]:
    /// gamma_f lies on the boundary, seen from above only, and each of its facets has the side
    /// beyond the plane as its cut side, the normal down; not so when the plane is not given as
    /// one gamma_s is pressed on.
    #[test]
    fn facets_on_the_plane_gamma_s_is_pressed_on_have_the_side_beyond_it_cut() {
        use crate::generate::{rectangle_triangles, DiagonalPattern};
        let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 8, 8, DiagonalPattern::Right);
        let surface = Surface::from_pieces(vec![[0.3, 0.0], [0.7, 0.0]], vec![[0, 1]]).unwrap();
        let adapted = super::super::adapt(&mesh, &surface, 0.2).unwrap();
        assert!(!adapted.gamma_f.is_empty() && adapted.gamma_f.iter().all(|g| g.sides[1] == NO_CELL), "on the boundary, seen from above");
        let plane = GapPlane { point: [0.0, 0.0], normal: [0.0, 1.0], cut_off: 0.1 };
        assert!(plane.is_closed(&surface));
        let layer = plane.layer(&surface);
        let cut = remove_closed_gaps(adapted.clone(), &[], &layer, &[plane], &surface, &[]);
        assert_eq!(cut.gamma_f.len(), adapted.gamma_f.len());
        assert_eq!(cut.cut_sides.len(), cut.gamma_f.len());
        assert!(cut.cut_sides.iter().all(|s| s.normal[0].abs() < 1e-12 && (s.normal[1] + 1.0).abs() < 1e-12));
        let unpressed = remove_closed_gaps(adapted, &[], &layer, &[], &surface, &[]);
        assert!(unpressed.cut_sides.is_empty());
    }

    /// A layer across the unit square at x = 0.5 cuts it in two; gamma_s is a short piece in the
    /// right half. The left half, away from gamma_f, is a pocket unless its boundary `left` sets
    /// the pressure there (`open`).
    #[test]
    fn a_pocket_without_an_open_boundary_or_gamma_f_leaves_with_the_gap() {
        use crate::generate::{rectangle_triangles, DiagonalPattern};
        let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 8, 8, DiagonalPattern::Right);
        let tag = |name: &str| mesh.boundary_tag(name).unwrap();
        let (left, right) = (tag("left"), tag("right"));
        let surface = Surface::from_pieces(vec![[0.9, 0.3], [0.7, 0.3]], vec![[0, 1]]).unwrap();
        let adapted = super::super::adapt(&mesh, &surface, 0.2).unwrap();
        let layer = vec![vec![[0.49, -0.1], [0.51, -0.1], [0.51, 1.1], [0.49, 1.1]]];
        let area = |a: &Adapted<2>, side: f64| -> f64 {
            let of_side = |c: usize| a.mesh.cell_vertices(c).iter().all(|&v| (a.mesh.points[v][0] - 0.5) * side >= -1e-12);
            (0..a.mesh.num_cells()).filter(|&c| of_side(c)).map(|c| a.mesh.signed_vertex_measure(c)).sum()
        };
        let (gamma_f, right_area) = (adapted.gamma_f_measure(), area(&adapted, 1.0));
        let sealed = remove_closed_gaps(adapted.clone(), &layer, &[], &[], &surface, &[right]);
        assert_eq!(area(&sealed, -1.0), 0.0, "the left half has no open boundary and no gamma_f");
        let strip = 0.125 + 1e-12; // a column of cells each side
        assert!(area(&sealed, 1.0) >= right_area - strip, "the right half stays but for the strip's cells");
        assert!((sealed.gamma_f_measure() - gamma_f).abs() < 1e-12);
        let open = remove_closed_gaps(adapted, &layer, &[], &[], &surface, &[left, right]);
        assert!(area(&open, -1.0) > 0.5 - 0.125 - 1e-12, "only the strip's cells leave");
        assert!(open.stats.closed_gap_cells < sealed.stats.closed_gap_cells);
    }

    /// gamma_s along `polyline` over the unit square (`n` by `n` cells), pressed on the plane y =
    /// 0 (cut-off 0.1), its normals down: the cut's sides with the x of their facet's centroid.
    fn pressed_polyline(polyline: Vec<[f64; 2]>, n: usize) -> (Adapted<2>, Vec<(f64, CutSide<2>)>) {
        use crate::generate::{rectangle_triangles, DiagonalPattern};
        let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, n, n, DiagonalPattern::Right);
        let surface = Surface::from_polyline(polyline).unwrap();
        let adapted = super::super::adapt(&mesh, &surface, 0.2).unwrap();
        let plane = GapPlane { point: [0.0, 0.0], normal: [0.0, 1.0], cut_off: 0.1 };
        let cut = remove_closed_gaps(adapted, &[], &plane.layer(&surface), &[], &surface, &[]);
        let sides = cut.cut_sides.iter().map(|s| (centroid(&cut.mesh, &cut.gamma_f[s.facet].vertices)[0], s.clone())).collect();
        (cut, sides)
    }

    /// The film's mean `sum_m w_m f(x_m)` of a function `f` of the mouths' centroids.
    fn film_mean(cut: &Adapted<2>, side: &CutSide<2>, f: impl Fn([f64; 2]) -> f64) -> f64 {
        side.film.iter().map(|&(m, w)| w * f(cut.mesh.vertex_centroid(m))).sum()
    }

    /// Under a flat piece at y = 0.02 over x = 0.3-0.7 the gap is even, Reynolds' equation is
    /// Laplace's along it, and the film's pressure falls linearly from one end's mouths to the
    /// other's: the weights are a mean (non-negative, summing to one, over the gap's mouths), and
    /// they give `p = x` at the mouths back at each facet, within 0.02 (cells 1/32 wide). At its
    /// nearest mouth alone, or at the mean of all the mouths, a facet would be up to 0.2 off.
    #[test]
    fn an_even_film_falls_linearly_from_one_mouth_to_the_other() {
        let (cut, sides) = pressed_polyline(vec![[0.3, 0.02], [0.7, 0.02]], 32);
        assert_eq!(cut.gap_mouths.len(), 1, "one gap");
        assert!(sides.len() > 10, "{} sides", sides.len());
        let mut worst: f64 = 0.0;
        for (x, side) in &sides {
            assert!(!side.film.is_empty(), "a film at x = {x}");
            assert!(side.film.iter().all(|&(m, w)| w > 0.0 && cut.gap_mouths[0].binary_search(&m).is_ok()));
            assert!((side.film.iter().map(|(_, w)| w).sum::<f64>() - 1.0).abs() < 1e-12);
            let p = film_mean(&cut, side, |c| c[0]);
            worst = worst.max((p - x).abs());
        }
        println!("the even film: p = x off by at most {worst:.4}");
        assert!(worst < 0.02, "{worst}");
    }

    /// The squeeze of the even film (above): its faces moving into it at unit speed, the film's
    /// pressure per `12 mu` is Reynolds' `s = (L^2 - (x - 0.5)^2) / (2 h^3)`, `h = 0.02`, `L` the
    /// mean distance from x = 0.5 to the mouths' centroids (where their pressure is held). At the
    /// middle within 2 %, everywhere within a tenth of the middle's (the cells next to the mouths,
    /// a cell from the held pressure, are the farthest off). A squeeze without the facets'
    /// measures as its sources, or with the permeability `h` for `h^2`, is off by factors.
    #[test]
    fn an_even_films_squeeze_is_reynolds_parabola() {
        let (cut, sides) = pressed_polyline(vec![[0.3, 0.02], [0.7, 0.02]], 32);
        let mouths: Vec<f64> = cut.gap_mouths[0].iter().map(|&m| (cut.mesh.vertex_centroid(m)[0] - 0.5).abs()).collect();
        let l = mouths.iter().sum::<f64>() / mouths.len() as f64;
        let h: f64 = 0.02;
        let exact = |x: f64| (l * l - (x - 0.5).powi(2)) / (2.0 * h.powi(3));
        let peak = exact(0.5);
        let (mut worst, mut middle, mut in_middle): (f64, f64, usize) = (0.0, 0.0, 0);
        for (x, side) in &sides {
            worst = worst.max((side.squeeze - exact(*x)).abs() / peak);
            if (x - 0.5).abs() < 0.02 {
                middle = middle.max((side.squeeze - exact(*x)).abs() / peak);
                in_middle += 1;
            }
        }
        assert!(in_middle > 0, "sides in the middle");
        println!("the even film's squeeze: L = {l:.4}, off by {middle:.4} of the peak {peak:.4e} in the middle, {worst:.4} at most");
        assert!(middle < 0.02 && worst < 0.1, "{middle} {worst}");
    }

    /// Where the gap narrows to a seal its film's pressure is the pressure of its own side's
    /// mouths: under a piece dipping from y = 0.08 at x = 0.3 and 0.7 to 0.004 at x = 0.5 the
    /// resistance `int dx / h^3` of the film lies almost all at the dip, and a facet at x < 0.45
    /// (x > 0.55) takes more than 0.95 of its weight from the left (right) end's mouths; an even
    /// film would give those at 0.35-0.45 (0.55-0.65) at most 0.875, and there are some.
    #[test]
    fn a_film_narrowing_to_a_seal_carries_its_own_sides_pressure() {
        let (cut, sides) = pressed_polyline(vec![[0.3, 0.08], [0.5, 0.004], [0.7, 0.08]], 32);
        assert_eq!(cut.gap_mouths.len(), 1, "one gap");
        let (mut checked, mut inner) = (0, 0);
        for (x, side) in &sides {
            inner += usize::from((0.35..0.45).contains(x) || (0.55..0.65).contains(x));
            let left = film_mean(&cut, side, |c| if c[0] < 0.5 { 1.0 } else { 0.0 });
            if *x < 0.45 {
                assert!(left > 0.95, "x = {x}: {left} of its weight from the left");
                checked += 1;
            } else if *x > 0.55 {
                assert!(left < 0.05, "x = {x}: {left} of its weight from the left");
                checked += 1;
            }
        }
        assert!(checked > 10 && inner > 4, "{checked} sides away from the dip, {inner} between 0.35 and 0.45 or 0.55 and 0.65");
    }

    #[test]
    fn the_layer_takes_the_pieces_within_the_cut_off() {
        let surface = Surface::from_pieces(vec![[0.0, 0.05], [1.0, 0.0], [2.0, 0.5]], vec![[0, 1], [1, 2]]).unwrap();
        let plane = GapPlane { point: [0.0, 0.0], normal: [0.0, 1.0], cut_off: 0.1 };
        let layer = plane.layer(&surface);
        assert_eq!(layer, vec![vec![[0.0, 0.05], [1.0, 0.0], [0.0, 0.0], [1.0, 0.0]]]);
    }
}
