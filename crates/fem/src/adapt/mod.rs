//! Local adaptation of the fluid mesh to the solid surface (the paper's section 2.2.1,
//! METHOD.md 3) and transfer of the fluid velocity between adapted meshes (METHOD.md 4).
//!
//! Every step starts from the ORIGINAL fluid mesh (prepared once as a [`Background`]) and the
//! CURRENT gamma_s (a [`Surface`] of flat pieces):
//!
//! 0. **Corners** ([`corners`], 2D) **and feature lines** ([`features`], 3D): where gamma_s turns
//!    sharply, the nearest fluid vertex that can is moved onto the corner first, so that the
//!    adapted mesh has a node there; in 3D the corners and ends of a thick solid's edges take a
//!    vertex each, and a chain of vertices moved onto each edge joins them (the cheapest path of
//!    fluid edges between them, [`features`]).
//! 1. **Cut edges** ([`intersect`]): the edges crossed by gamma_s, one point per edge (the one
//!    farthest from the edge's ends if there are several, and a second cut for step 2).
//! 2. **Move or add** ([`adapt_with`]): `eps = |x_i - x_n1| / |x_n2 - x_n1|`;
//!    `eps < eps_hat` moves `n1` onto `x_i`, `eps > 1 - eps_hat` moves `n2`, otherwise a new node
//!    is added at `x_i`. Rules for what the paper leaves open are listed below.
//! 3. **Subdivide** ([`subdivide`]): every cell with split edges is replaced by the children of
//!    successive bisection; faces are split consistently, so the mesh stays conforming. In 3D
//!    with feature lines, the children's edges that still cross gamma_s within their length of a
//!    line are cut and the cells subdivided again (`cut_crossings_near_features`), but for an
//!    edge that only skims the face of its end on gamma_s (`skims_its_face`) or crosses it
//!    next to a boundary vertex taken to lie on it (a boundary touch).
//! 4. **gamma_f**: facets of the adapted mesh whose vertices all lie on gamma_s and which lie in
//!    gamma_s, with the cells on both sides and each vertex's location on gamma_s.
//!
//! # Rules for the cases the paper does not treat (each counted in [`AdaptStats`])
//!
//! * **Order.** Cut edges are processed by increasing distance of the cut from the nearer end
//!   (`min(eps, 1 - eps) |edge|`, ties by edge number), so a node moves to its nearest cut.
//! * **A node moves at most once.** A second request to move a node that has already moved, or
//!   that lies on gamma_s already (touched), is dropped: after the first move the edge touches
//!   gamma_s at that node (`skipped_cuts`).
//! * **Cuts at moved ends** (`cuts_at_moved_ends`): all moves are decided before any node is
//!   added. Where a new node on an edge with a moved end makes a bad cell (inverted, flat or of
//!   poor quality, as below), the next pass drops that cut instead of undoing the move: the edge
//!   touches gamma_s at its moved end, if the chord from the cut to the moved end runs along
//!   gamma_s (not across a corner: there the move is undone). This happens where gamma_s runs
//!   nearly parallel to a plane of nodes: the nodes move a little onto gamma_s while the edges
//!   between them are cut far from their ends. Undoing the moves instead put new nodes next to
//!   the pinned nodes and refused their neighbours' moves in turn (model problem 4 with nodes at
//!   z = 2: 452 refused moves, cells of quality 3.6e-6, a singular system; now 133 moves, 24
//!   dropped cuts, 3 new nodes, worst quality 0.018, and the step converges). With
//!   [`AdaptOptions::min_cut_quality`] such a cut is dropped below that higher quality too, and
//!   no move is undone for that reason: where gamma_s lies within hundredths of an edge of a
//!   plane of fluid nodes (a valve leaflet pressed on its plane of coaptation) it cuts the
//!   plane's edges at grazing angles, and a new node there, nearly in line with a moved node and
//!   another new one, made needle cells (quality 0.015) with a facet on gamma_f, where Newton
//!   stalled.
//! * **Refused moves** (`refused_moves`) become a new node at `x_i` instead: a boundary vertex may
//!   only move within the planes (lines) of all its boundary facets (tolerance `1e-12` relative),
//!   so the domain never changes; and a move is undone when a cell touching the moved node (or one
//!   of its children) would get a non-positive measure, a quality below
//!   [`AdaptOptions::min_move_quality`], or is flat (all its vertices on gamma_s along one smooth
//!   part of it: see **Flat cells** below), unless a cut
//!   at a moved end is dropped instead (above). Undoing re-runs steps 2-3 with that node pinned,
//!   until no cell is refused.
//! * **Boundary touches** (`boundary_touches`, opt-in: [`AdaptOptions::touch_fixed_boundary`]):
//!   a boundary vertex that may not move onto a cut within `eps_hat / 4` of it (a cut off its
//!   boundary planes; it may be pinned) stays where it is and counts as on gamma_s: its cuts
//!   within `eps_hat` are dropped, as for a moved node, on all its edges. A gamma_f facet with a
//!   vertex farther from gamma_s than the gamma_f rule allows its centroid is rejected.
//!   Where gamma_s enters the domain's boundary (a valve leaflet embedded in the wall), the new
//!   nodes the refusal adds otherwise cluster around the vertex in cells of hundredths of its
//!   edges (`TOUCH_FRACTION`).
//! * **gamma_s through a vertex / along an edge / in a face**: the vertex (edge's, face's vertices)
//!   is on gamma_s as it is; the edges touching it there are not cut (`touched_vertices`,
//!   `edges_in_surface`). A cut within `T_SNAP = 1e-12` (relative) of an end point snaps to it
//!   (`snapped_cuts`).
//! * **Several points on one edge** (folded surface, two sheets, the two sides of a corner): the
//!   one farthest from the edge's ends is kept, ties to the one closest to `n1`
//!   (`multi_cut_edges`; see [`intersect`]). Of the others, the one nearest an end moves that end
//!   onto it, however far, after all other moves (`second_cut_moves`), unless the end is on
//!   gamma_s already, pinned, or a boundary vertex the move would take off its boundary lines or
//!   planes (`dropped_second_cuts`).
//! * **gamma_f rule**: a facet is on gamma_f when all its vertices are on gamma_s (touched, moved
//!   or new nodes) and its centroid is within `GAMMA_F_REL_TOL = 0.1` times the facet's diameter
//!   of gamma_s (this accepts chords of a curved gamma_s, rejects facets spanning a fold); in 3D
//!   also, where gamma_s has feature lines, its vertices on one smooth part of gamma_s
//!   ([`features::smooth_parts`]: a vertex on a block's edge is on both faces; this rejects a
//!   triangle across a block's edge, whose centroid lies near both faces, and one inside the
//!   block's wedge that is nearly parallel to one face, with a vertex on the other; vertices
//!   sharing two parts lie all on one feature line: a sliver along it, rejected too; a closed
//!   line's own triangles, such as a cap's rim, would be too), and where
//!   it has none (a smooth gamma_s, or pieces given without shared corners), its vertices within
//!   `GAMMA_F_REL_TOL` times its diameter of the plane of the gamma_s piece nearest its centroid,
//!   or (3D) its normal within `corners::CORNER_ANGLE_DEG` of the normals of the pieces nearest
//!   its vertices (the plane test alone refuses chords of faces curved more than that, such as a
//!   sheared block's sides near the floor or the 3D valve's leaflet, so it is not used where the
//!   parts tell the edges; the normals tell them where the parts do not); rejected ones are
//!   counted (`rejected_facets`). Where these rules leave a hole in gamma_f around a closed
//!   gamma_s that the mesh can close, [`remove_enclosed`] rebuilds it from the sides of gamma_s the cells lie on
//!   (`cells_by_side`).
//! * **Cells on both sides** (`two_sided_cells`): a cell whose vertices all lie on a curved
//!   gamma_s can have facets on gamma_f on both of its sides (it lies on the minus side of some
//!   and the plus side of others): gamma_f then folds around it, and its fluid is shut in by the
//!   coupling. Its pressure's mean is then a multiplier of a constraint that the weak coupling
//!   holds only nearly (no flux of the solid's velocity through the chords around it), and the
//!   Newton solves stall on it (the 3D valve's sector at t = 0.237: three such cells next to
//!   each other near the leaflet's free edge, 12 iterations a step with updates of 2e4 Pa at one cell's
//!   pressure). The facets of one side leave gamma_f, so the cell joins the fluid on that side:
//!   the side whose leaving leaves fewer ridges of gamma_f (edges in 3D, vertices in 2D) on one
//!   facet only (no hole opens where the two sides do not cover the same part of gamma_s), and
//!   of two such the one farther from gamma_s (the mean distance of the facets' centroids,
//!   weighted by their measure).
//! * **Flat cells**: a cell whose vertices all lie on gamma_s along one smooth part of it. With
//!   feature lines (3D): its vertices share a smooth part and its centroid lies within
//!   `GAMMA_F_REL_TOL` times its diameter of gamma_s. Without: its vertices lie within that
//!   distance of the plane of the piece nearest its centroid, or (3D) the pieces nearest its
//!   vertices turn by less than the corner angle from one another and two of its facets would
//!   be on gamma_f by the rule above; and none lies at a corner placed in step 0. A cell
//!   spanning a solid's corner or edge is not flat: it fills it.
//! * **Quadratic geometry**: a mesh with 6/10-node cells is adapted through its vertex mesh; its
//!   curved boundary geometry is not carried into the adapted (linear) mesh.
//! * **Region interfaces** inside the fluid mesh are not protected against moves (only the
//!   exterior boundary is).

pub mod background;
pub mod corners;
pub mod enclosed;
pub mod features;
pub mod gap;
mod geom;
pub mod intersect;
pub mod subdivide;
pub mod surface;
pub mod transfer;
pub mod verify;

pub use background::Background;
pub use enclosed::remove_enclosed;
pub use gap::{remove_closed_gaps, GapPlane, CLOSED_GAP};
pub use surface::{Surface, SurfacePoint};
pub use transfer::{p1disc_value, transfer_p1disc, transfer_p2plus, transfer_p2plus_or, CellLocator};
pub use verify::{verify_adapted, verify_adapted_within};

use crate::element::ReferenceCell;
use crate::mesh::{BoundaryFacet, Mesh, NO_CELL};
use geom::{cross, dist2, dot, min_angle2, pad3, simplex_measure, simplex_quality, sub};
use intersect::{find_cuts, CutSet, T_SNAP};
use std::collections::{HashMap, HashSet};
use thiserror::Error;

/// Facets whose centroid is farther than this times their diameter from gamma_s are not on
/// gamma_f.
pub const GAMMA_F_REL_TOL: f64 = 0.1;

/// 3D: a vertex lies on the smooth parts of gamma_s ([`features::smooth_parts`]) within this
/// times its coordinates' size (`1 + max |x_i|`) of it ([`PartsAt`]).
const PARTS_REL_TOL: f64 = 1e-9;

/// The smooth parts of gamma_s ([`features::smooth_parts`]) each vertex lies on (within
/// [`PARTS_REL_TOL`]), looked up once per vertex: one for a point inside a face, two on a
/// block's edge, three at its corner. Vertices that share no part span a feature line: a facet
/// of them is not on gamma_f, a cell of them is not flat.
struct PartsAt<'a, const D: usize> {
    surface: &'a Surface<D>,
    parts: &'a [usize],
    found: std::cell::RefCell<HashMap<usize, Vec<usize>>>,
}

impl<'a, const D: usize> PartsAt<'a, D> {
    fn new(surface: &'a Surface<D>, parts: &'a [usize]) -> Self {
        PartsAt { surface, parts, found: Default::default() }
    }

    /// Do `vertices` (at `pos`) lie on one smooth part?
    fn on_one_part(&self, vertices: &[usize], pos: impl Fn(usize) -> [f64; D]) -> bool {
        self.shared_parts(vertices, pos) > 0
    }

    /// On how many smooth parts do all `vertices` (at `pos`) lie? None: they span a feature
    /// line; one: they lie on one face; two or more: all lie on one feature line.
    fn shared_parts(&self, vertices: &[usize], pos: impl Fn(usize) -> [f64; D]) -> usize {
        let mut found = self.found.borrow_mut();
        let mut at = |v: usize| found.entry(v).or_insert_with(|| parts_of_point(self.surface, self.parts, &pos(v))).clone();
        let first = at(vertices[0]);
        let rest: Vec<Vec<usize>> = vertices[1..].iter().map(|&v| at(v)).collect();
        first.iter().filter(|p| rest.iter().all(|r| r.contains(p))).count()
    }
}

/// The smooth parts of gamma_s ([`features::smooth_parts`]) `x` lies on, within
/// [`PARTS_REL_TOL`].
fn parts_of_point<const D: usize>(surface: &Surface<D>, parts: &[usize], x: &[f64; D]) -> Vec<usize> {
    let tol = PARTS_REL_TOL * (1.0 + x.iter().fold(0.0f64, |m, c| m.max(c.abs())));
    features::parts_at(surface, parts, x, tol)
}

/// Name of the boundary [`tag_gamma_f`] gives the facets of gamma_f (seen from one side).
pub const GAMMA_F: &str = "gamma_f";
/// The facets of gamma_f seen from the cells on the minus side of gamma_s (opposite to the
/// surface normal).
pub const GAMMA_F_MINUS: &str = "gamma_f_minus";
/// ... and from the plus side (the side the surface normal points to).
pub const GAMMA_F_PLUS: &str = "gamma_f_plus";

/// Adds the facets of `gamma_f` to the boundary of `mesh` (the adapted mesh they belong to) under
/// the names [`GAMMA_F`] (one side, enough to name the facet's nodes), [`GAMMA_F_MINUS`] and
/// [`GAMMA_F_PLUS`] (each side separately, for one-sided quantities such as wall shear stress).
pub fn tag_gamma_f<const D: usize>(mesh: &mut Mesh<D>, gamma_f: &[GammaFacet<D>]) {
    let tag = mesh.boundary_names.iter().map(|(_, t)| *t).max().unwrap_or(0) + 1;
    let mut tagged = Vec::new();
    for g in gamma_f {
        if let Some(&(cell, facet)) = g.sides.iter().find(|s| s.0 != usize::MAX) {
            tagged.push(BoundaryFacet { cell, facet, tag });
        }
        for (k, &(cell, facet)) in g.sides.iter().enumerate() {
            if cell != usize::MAX {
                tagged.push(BoundaryFacet { cell, facet, tag: tag + 1 + k as u32 });
            }
        }
    }
    mesh.boundary.extend(tagged);
    mesh.add_boundary_name(GAMMA_F, tag);
    mesh.add_boundary_name(GAMMA_F_MINUS, tag + 1);
    mesh.add_boundary_name(GAMMA_F_PLUS, tag + 2);
}

/// Errors of the adaptation and of the transfer.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum AdaptError {
    #[error("eps_hat = {0} is outside (0, 0.5]: choose 0 < eps_hat <= 0.5 (the paper uses 0.2)")]
    EpsHat(f64),
    #[error("{0}")]
    NotSimplex(String),
    #[error("the original mesh is invalid: {0}")]
    BadMesh(String),
    #[error("invalid surface: {0}")]
    Surface(String),
    #[error("transfer: {0}")]
    Transfer(String),
    #[error("covered fluid: gamma_f does not enclose the solid: the fluid cells on its solid side connect to its fluid side (at the cell with centroid {0:?}); couple the solid on its whole wetted boundary, closed by the fluid domain's boundary, or keep the covered fluid")]
    NotEnclosed(Vec<f64>),
}

/// Knobs of the adaptation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptOptions {
    /// The paper's `eps_hat` in `(0, 0.5]`: cuts closer than `eps_hat |edge|` to an end point move
    /// that node.
    pub eps_hat: f64,
    /// A move is refused if a cell touching the moved node gets a quality (1 = equilateral)
    /// below this.
    pub min_move_quality: f64,
    /// What becomes of a cut within `eps_hat / 4` of a boundary vertex that may not move onto it
    /// (the cut is off the vertex's boundary planes): `false` (the default) adds a new node
    /// there, next to the vertex; `true` drops the cut and takes the vertex, where it is, to lie
    /// on gamma_s (`boundary_touches`; see the module documentation).
    pub touch_fixed_boundary: bool,
    /// A new node on an edge whose other end moved onto gamma_s is dropped, where the edge can
    /// touch gamma_s at its moved end instead (**Cuts at moved ends**), if a cell it is in with a
    /// moved node has a quality below this; such a cell alone undoes no move (that stays below
    /// `min_move_quality`). `0` (the default): only below `min_move_quality`.
    pub min_cut_quality: f64,
}

impl AdaptOptions {
    /// Options with the given `eps_hat`, `min_move_quality = 0.01` and `min_cut_quality = 0`.
    pub fn new(eps_hat: f64) -> Self {
        AdaptOptions { eps_hat, min_move_quality: 0.01, touch_fixed_boundary: false, min_cut_quality: 0.0 }
    }
}

/// Counters of one adaptation (see the module documentation for the rules they count).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct AdaptStats {
    /// Edges cut by gamma_s (after snapping).
    pub cut_edges: usize,
    /// Nodes moved onto gamma_s.
    pub moved_nodes: usize,
    /// Nodes added on cut edges.
    pub new_nodes: usize,
    /// Moves refused (boundary, inversion, quality, flat cell) and replaced by a new node.
    pub refused_moves: usize,
    /// Of which refused because the node is on the domain boundary and would leave it.
    pub refused_boundary: usize,
    /// Boundary vertices taken to lie on gamma_s where they are, their cuts dropped
    /// ([`AdaptOptions::touch_fixed_boundary`]; not counted in `refused_boundary`).
    pub boundary_touches: usize,
    /// Cells added (adapted minus original).
    pub new_cells: usize,
    /// Facets on gamma_f (the coupling elements).
    pub coupling_facets: usize,
    /// Sum of the degenerate-configuration counters below (all but `skipped_cuts`, which is the
    /// paper's own rule, and `passes`).
    pub degenerate_cases: usize,
    /// Fluid vertices moved onto corners of gamma_s (step 0; in 3D also onto its edges' ends and
    /// corners and, as chains, its edges).
    pub corner_nodes: usize,
    /// Corners of gamma_s no fluid vertex could move to (their neighbourhood is cut as elsewhere);
    /// in 3D also the edges whose chain could not be completed.
    pub unplaced_corners: usize,
    /// Cells enclosed by gamma_f and removed ([`remove_enclosed`]).
    pub removed_cells: usize,
    /// Cells cut off where the solid closes on a rigid plane or on another body
    /// ([`remove_closed_gaps`]).
    pub closed_gap_cells: usize,
    /// Pieces of the solid's surfaces (segments, triangles) whose gap layers cut them off: how
    /// much of the contact the cut covers, apart from the adapted mesh's cells.
    pub closed_gap_pieces: usize,
    /// Cells told inside or outside the solid by the side of gamma_s they lie on, where the
    /// facet rules left gamma_f open and [`remove_enclosed`] rebuilt it between the two sides
    /// (0 where gamma_f enclosed the solid; `rejected_facets` and `degenerate_cases` still
    /// count the facet rules' attempt).
    pub cells_by_side: usize,
    /// Smallest quality (1 = equilateral) of the cells that were split or touch a moved node
    /// (1 when there are none).
    pub min_quality: f64,
    /// Original vertices lying on gamma_s (through a vertex, along an edge, in a face, snapped),
    /// not counting the corner nodes of step 0.
    pub touched_vertices: usize,
    /// Cuts snapped to an end point.
    pub snapped_cuts: usize,
    /// Edges lying in the line / plane of a piece.
    pub edges_in_surface: usize,
    /// Edges cut at several different points.
    pub multi_cut_edges: usize,
    /// Of which the second point was taken by moving the edge's end nearer to it onto it.
    pub second_cut_moves: usize,
    /// Of which the second point was dropped (its end on gamma_s already, pinned, or a boundary
    /// vertex the move would take off its boundary lines or planes).
    pub dropped_second_cuts: usize,
    /// Second move requests dropped.
    pub skipped_cuts: usize,
    /// Cuts dropped because an end of their edge moved onto gamma_s and their new node made a
    /// bad cell with it.
    pub cuts_at_moved_ends: usize,
    /// Flat cells (all vertices on gamma_s along one smooth part of it, none placed in step 0)
    /// that were kept (no moved node to undo).
    pub flat_cells: usize,
    /// Facets with all vertices on gamma_s but not lying in it.
    pub rejected_facets: usize,
    /// Cells with gamma_f facets on both of their sides, whose facets on one side left gamma_f
    /// (see **Cells on both sides** in the module documentation).
    pub two_sided_cells: usize,
    /// 3D: edges of the subdivided cells still crossing gamma_s next to a feature line, cut in
    /// further passes (counted in `new_nodes` too).
    pub crossing_cuts: usize,
    /// 3D: points where a curved feature line bends between two vertices on it, added on the
    /// edge between them (counted in `new_nodes` too; see `features::kinks`).
    pub feature_kinks: usize,
    /// Kinks refused because a child cell holding one, split on another edge too, would be
    /// inverted or poor (their edges left unsplit; see `refused_kinks`). Counted in every pass
    /// that finds them: a kink can be counted more than once, and in `feature_kinks` too where a
    /// later pass takes it.
    pub refused_kinks: usize,
    /// Passes of steps 2-3 (1 + the number of rounds of undone moves or refused kinks), plus
    /// the 3D passes that cut again next to feature lines.
    pub passes: usize,
}

/// A facet of gamma_f.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GammaFacet<const D: usize> {
    /// Mesh vertices, ordered so that their right-hand normal (2D: the tangent turned clockwise)
    /// points like the normal of the gamma_s piece nearest the facet's centroid (facets rebuilt
    /// by [`remove_enclosed`]: out of the solid, like the normals of a closed gamma_s).
    pub vertices: [usize; D],
    /// `(cell, local facet)` on the minus side (the normal points out of it) and on the plus
    /// side; [`NO_CELL`] where gamma_f lies on the domain boundary or the cells on that side were
    /// removed ([`remove_enclosed`]).
    pub sides: [(usize, usize); 2],
    /// Where each vertex lies on gamma_s.
    pub location: [SurfacePoint<D>; D],
}

/// The adapted mesh and its relation to the original and to gamma_s.
#[derive(Clone, Debug)]
pub struct Adapted<const D: usize> {
    /// Linear simplices; the first `nv` points are the original vertices (moved ones at their new
    /// position), new nodes follow; boundary tags and regions inherited from the parents. After
    /// [`remove_enclosed`], the points and cells of the kept cells only, in the same order.
    pub mesh: Mesh<D>,
    /// Parent (original) cell of each adapted cell. Cells of untouched parents keep their index
    /// (unless cells were removed);
    /// a split parent's first child takes its index, the other children are appended.
    pub new_to_old_cell: Vec<usize>,
    /// Whether each adapted-mesh vertex lies on gamma_s.
    pub on_surface: Vec<bool>,
    /// The coupling facets.
    pub gamma_f: Vec<GammaFacet<D>>,
    /// The sides of gamma_f facets whose fluid a closed gap cut off ([`remove_closed_gaps`]);
    /// empty before that.
    pub cut_sides: Vec<gap::CutSide<D>>,
    /// The mouths of each closed gap ([`gap::CutSide::gap`]): the kept cells across the facets
    /// off gamma_f of a connected region of cells the cut took, where the gap's film of blood
    /// opens to the fluid, ascending; empty before [`remove_closed_gaps`].
    pub gap_mouths: Vec<Vec<usize>>,
    pub stats: AdaptStats,
}

impl<const D: usize> Adapted<D> {
    /// Measure (length, area) of gamma_f.
    pub fn gamma_f_measure(&self) -> f64 {
        self.gamma_f.iter().map(|g| surface::piece_measure(&g.vertices.map(|v| self.mesh.points[v]))).sum()
    }
}

/// Adapts `original` to `surface` (see the module documentation). Prepares the original mesh
/// each call: for repeated steps build a [`Background`] once and call [`adapt_with`].
pub fn adapt<const D: usize>(original: &Mesh<D>, surface: &Surface<D>, eps_hat: f64) -> Result<Adapted<D>, AdaptError> {
    check_eps_hat(eps_hat)?;
    let bg = Background::new(original)?;
    adapt_with(&bg, surface, &AdaptOptions::new(eps_hat))
}

fn check_eps_hat(eps_hat: f64) -> Result<(), AdaptError> {
    if !(eps_hat > 0.0 && eps_hat <= 0.5) {
        return Err(AdaptError::EpsHat(eps_hat));
    }
    Ok(())
}

/// Adapts the prepared original mesh `bg` to `surface`.
pub fn adapt_with<const D: usize>(bg: &Background<D>, surface: &Surface<D>, opts: &AdaptOptions) -> Result<Adapted<D>, AdaptError> {
    check_eps_hat(opts.eps_hat)?;
    let (moves, unplaced_corners) = features::feature_moves(bg, surface, opts.min_move_quality);
    let cornered;
    let bg = if moves.is_empty() {
        bg
    } else {
        cornered = bg.with_moved_vertices(&moves);
        &cornered
    };
    let lines = features::features(surface).lines;
    let all_cuts = find_cuts(bg, surface);
    let mut kinks = features::kinks(bg, &lines, moves.iter().map(|m| m.0), opts.min_move_quality);
    let mut refused_kink_count = 0;
    let mut corner_vertices: Vec<usize> = moves.iter().map(|m| m.0).collect();
    corner_vertices.sort_unstable();
    // Without feature lines gamma_s is one part (pieces given without shared corners would
    // otherwise be a part each).
    let parts = if lines.is_empty() { vec![0; surface.num_pieces()] } else { features::smooth_parts(surface) };
    let has_parts = parts.iter().any(|&p| p != 0);
    let mut pinned: HashSet<usize> = HashSet::new();
    let mut dropped: HashSet<usize> = HashSet::new();
    let mut passes = 0;
    let (plan, split, cuts) = loop {
        passes += 1;
        let mut cuts = without_kink_edges(&all_cuts, &kinks);
        let mut plan = plan_moves(bg, &cuts, opts, &pinned, &dropped);
        cuts.touch(&plan.boundary_touched);
        for &(e, x) in &kinks {
            add_node(&mut plan, e, x);
        }
        let nv = bg.mesh.points.len();
        let on_surface = |g: usize| g >= nv || plan.moved.contains_key(&g) || cuts.touched.binary_search(&g).is_ok();
        let pos = |g: usize| plan.pos(bg, g);
        let parts_at = PartsAt::new(surface, &parts);
        let flat_test = FlatTest { on_surface: &on_surface, corners: &corner_vertices, parts: has_parts.then_some(&parts_at), pos: &pos, surface };
        let split = subdivide_cells(bg, &plan, &flat_test);
        let bad = refused_by_cells(bg, surface, &plan, &split, opts, &flat_test);
        let (np, nd) = (pinned.len(), dropped.len());
        pinned.extend(bad.pin);
        dropped.extend(bad.drop);
        if (pinned.len(), dropped.len()) == (np, nd) {
            // The moves settled: the kinks that still spoil a cell are refused.
            let refused = refused_kinks(bg, &plan, &split, &kinks, opts.min_move_quality);
            if refused.is_empty() {
                break (plan, split, cuts);
            }
            refused_kink_count += refused.len();
            kinks.retain(|k| !refused.contains(&k.0));
        }
    };
    let mut out = assemble(bg, &plan, &split);
    let mut on_surface = on_surface_flags(bg, &plan, &cuts);
    let mut candidates: Vec<usize> = out.child_index.iter().flatten().copied().collect();
    candidates.extend(cuts.touched.iter().chain(plan.moved.keys()).flat_map(|&v| bg.vertex_cells.row(v).iter().copied()));
    let extra = cut_crossings_near_features(&mut out, &mut on_surface, surface, &lines, &parts, opts)?;
    if extra.passes > 0 {
        let mesh = &out.mesh;
        candidates = (0..mesh.num_cells()).filter(|&c| mesh.cell(c).iter().any(|&v| on_surface[v])).collect();
    }
    let (gamma_f, rejected, two_sided) = build_gamma_f(&out.mesh, candidates, &on_surface, surface, &parts);
    let stats = &mut out.stats;
    stats.cut_edges = cuts.cuts.len();
    stats.moved_nodes = plan.moved.len();
    stats.new_nodes = plan.new_points.len() + extra.cuts + extra.kinks;
    stats.crossing_cuts = extra.cuts;
    stats.feature_kinks = kinks.len() + extra.kinks;
    stats.refused_kinks = refused_kink_count + extra.refused_kinks;
    stats.refused_moves = plan.refused;
    stats.refused_boundary = plan.refused_boundary;
    stats.boundary_touches = plan.boundary_touched.len();
    stats.new_cells = out.mesh.num_cells() - bg.num_cells();
    stats.coupling_facets = gamma_f.len();
    // Corner nodes touch by design; boundary touches are counted on their own.
    stats.touched_vertices = cuts.touched.len().saturating_sub(moves.len() + plan.boundary_touched.len());
    stats.snapped_cuts = cuts.snapped;
    stats.edges_in_surface = cuts.edges_in_surface;
    stats.multi_cut_edges = cuts.second_cuts.len();
    stats.skipped_cuts = plan.skipped;
    stats.cuts_at_moved_ends = plan.cuts_at_moved_ends;
    stats.second_cut_moves = plan.second_cut_moves;
    stats.dropped_second_cuts = plan.dropped_second_cuts;
    stats.flat_cells = split.flat_cells;
    stats.rejected_facets = rejected;
    stats.two_sided_cells = two_sided;
    stats.min_quality = split.min_quality.min(extra.min_quality);
    stats.passes = passes + extra.passes;
    stats.corner_nodes = moves.len();
    stats.unplaced_corners = unplaced_corners;
    stats.degenerate_cases = stats.touched_vertices
        + stats.snapped_cuts
        + stats.edges_in_surface
        + stats.multi_cut_edges
        + stats.flat_cells
        + stats.rejected_facets
        + stats.two_sided_cells;
    Ok(Adapted {
        mesh: out.mesh,
        new_to_old_cell: out.new_to_old_cell,
        on_surface,
        gamma_f,
        cut_sides: Vec::new(),
        gap_mouths: Vec::new(),
        stats: out.stats,
    })
}

/// Step 2's decisions: moved nodes and new nodes.
#[derive(Clone, Debug, Default)]
struct Plan<const D: usize> {
    /// Moved vertex -> new position.
    moved: HashMap<usize, [f64; D]>,
    /// Cut edge with a new node -> index of the new node (into `new_points`).
    new_node: HashMap<usize, usize>,
    new_points: Vec<[f64; D]>,
    refused: usize,
    refused_boundary: usize,
    /// Boundary vertices taken to lie on gamma_s where they are
    /// ([`AdaptOptions::touch_fixed_boundary`]), sorted.
    boundary_touched: Vec<usize>,
    skipped: usize,
    cuts_at_moved_ends: usize,
    second_cut_moves: usize,
    dropped_second_cuts: usize,
}

impl<const D: usize> Plan<D> {
    /// Current position of adapted-mesh vertex `g` (original vertices first, then new nodes).
    fn pos(&self, bg: &Background<D>, g: usize) -> [f64; D] {
        let nv = bg.mesh.points.len();
        if g >= nv {
            self.new_points[g - nv]
        } else {
            self.moved.get(&g).copied().unwrap_or(bg.mesh.points[g])
        }
    }
}

/// With [`AdaptOptions::touch_fixed_boundary`], a boundary vertex that may not move onto a cut
/// of its edge is taken to lie on gamma_s if the cut is within this fraction of `eps_hat` (of
/// the edge's length) of it. Nearer cuts made the clusters of tiny cells around such a vertex
/// (the 3D valve sector's leaflet entering the wall: edges of 0.04 mm of 2 mm cells, Newton
/// stalling under SUPG); taking the vertex within the whole `eps_hat` left gamma_f with holes
/// there (28 facets rejected by the gamma_f rule rather than 6, 7 % of its area). A crossing of
/// `cut_crossings_near_features` within this fraction of `eps_hat` of an end on gamma_s is
/// dropped alike where the edge only skims that end's face, or where that end is such a vertex.
const TOUCH_FRACTION: f64 = 0.25;

/// Step 2 (see the module documentation for the order and the rules). `pinned` nodes do not
/// move; the cuts of `dropped` edges are dropped when an end of the edge moved.
fn plan_moves<const D: usize>(
    bg: &Background<D>,
    cuts: &CutSet<D>,
    opts: &AdaptOptions,
    pinned: &HashSet<usize>,
    dropped: &HashSet<usize>,
) -> Plan<D> {
    let eps_hat = opts.eps_hat;
    let mut order: Vec<usize> = (0..cuts.cuts.len()).collect();
    let near = |i: usize| {
        let c = &cuts.cuts[i];
        let [a, b] = bg.topology.edges[c.edge];
        c.t.min(1.0 - c.t) * dist2(&bg.mesh.points[a], &bg.mesh.points[b]).sqrt()
    };
    order.sort_by(|&i, &j| near(i).total_cmp(&near(j)).then(cuts.cuts[i].edge.cmp(&cuts.cuts[j].edge)));
    let mut plan = Plan::default();
    let touchable = if opts.touch_fixed_boundary { touchable_boundary_vertices(bg, cuts, eps_hat) } else { HashSet::new() };
    let mut touched_here: HashSet<usize> = HashSet::new();
    // Moves first, nearest cut first; the cuts that are not moves wait until all moves are known.
    let mut unmoved = Vec::new();
    for i in order {
        let cut = cuts.cuts[i];
        let [a, b] = bg.topology.edges[cut.edge];
        let v = if cut.t < eps_hat {
            a
        } else if cut.t > 1.0 - eps_hat {
            b
        } else {
            unmoved.push(i);
            continue;
        };
        if cuts.touched.binary_search(&v).is_ok() || plan.moved.contains_key(&v) || touched_here.contains(&v) {
            plan.skipped += 1;
        } else if !pinned.contains(&v) && boundary_move_ok(bg, v, &cut.x) {
            plan.moved.insert(v, cut.x);
        } else if touchable.contains(&v) {
            // The vertex stays, on gamma_s as the adapted mesh sees it; the cut is dropped.
            touched_here.insert(v);
        } else {
            plan.refused += 1;
            plan.refused_boundary += !pinned.contains(&v) as usize;
            unmoved.push(i);
        }
    }
    plan.boundary_touched = touched_here.into_iter().collect();
    plan.boundary_touched.sort_unstable();
    second_cut_moves(bg, cuts, pinned, &mut plan);
    unmoved.sort_unstable();
    for i in unmoved {
        let cut = cuts.cuts[i];
        if dropped.contains(&cut.edge) && bg.topology.edges[cut.edge].iter().any(|v| plan.moved.contains_key(v)) {
            plan.cuts_at_moved_ends += 1;
        } else {
            add_node(&mut plan, cut.edge, cut.x);
        }
    }
    plan
}

/// The second cuts of edges cut at several points ([`intersect`]), nearest its end first: each
/// moves the end nearer to it onto it, unless that end is on gamma_s already (touched or moved),
/// pinned, or on the domain boundary and would leave it; then it is dropped. The end's cells are
/// checked like any move's ([`refused_by_cells`]).
fn second_cut_moves<const D: usize>(bg: &Background<D>, cuts: &CutSet<D>, pinned: &HashSet<usize>, plan: &mut Plan<D>) {
    let end = |c: &intersect::Cut<D>| {
        let [a, b] = bg.topology.edges[c.edge];
        if c.t < 0.5 {
            a
        } else {
            b
        }
    };
    let mut order: Vec<&intersect::Cut<D>> = cuts.second_cuts.iter().collect();
    order.sort_by(|c, d| c.t.min(1.0 - c.t).total_cmp(&d.t.min(1.0 - d.t)).then(c.edge.cmp(&d.edge)));
    for cut in order {
        let v = end(cut);
        let on_surface = cuts.touched.binary_search(&v).is_ok() || plan.moved.contains_key(&v) || plan.boundary_touched.binary_search(&v).is_ok();
        if on_surface || pinned.contains(&v) || !boundary_move_ok(bg, v, &cut.x) {
            plan.dropped_second_cuts += 1;
        } else {
            plan.moved.insert(v, cut.x);
            plan.second_cut_moves += 1;
        }
    }
}

/// The boundary vertices [`AdaptOptions::touch_fixed_boundary`] may take to lie on gamma_s: those
/// with a cut within `TOUCH_FRACTION * eps_hat` of their edge that they may not move onto. Found
/// before the moves, so that the order of the cuts (by distance, not by fraction of the edge)
/// does not leave a nearer cut's new node beside a vertex touched later.
fn touchable_boundary_vertices<const D: usize>(bg: &Background<D>, cuts: &CutSet<D>, eps_hat: f64) -> HashSet<usize> {
    let limit = TOUCH_FRACTION * eps_hat;
    cuts.cuts
        .iter()
        .filter_map(|cut| {
            let [a, b] = bg.topology.edges[cut.edge];
            let v = if cut.t < limit {
                a
            } else if cut.t > 1.0 - limit {
                b
            } else {
                return None;
            };
            (!bg.vertex_boundary.row(v).is_empty() && !boundary_move_ok(bg, v, &cut.x)).then_some(v)
        })
        .collect()
}

fn add_node<const D: usize>(plan: &mut Plan<D>, edge: usize, x: [f64; D]) {
    plan.new_node.insert(edge, plan.new_points.len());
    plan.new_points.push(x);
}

/// May boundary vertex `v` move to `x`? Only if `x` stays in the line / plane of every boundary
/// facet of `v` (distance at most `1e-12` times the facet's size). Interior vertices always may.
pub(crate) fn boundary_move_ok<const D: usize>(bg: &Background<D>, v: usize, x: &[f64; D]) -> bool {
    bg.vertex_boundary.row(v).iter().all(|&i| {
        let b = bg.mesh.boundary[i];
        let fv = bg.mesh.cell_type.facet(b.facet);
        let pts: [[f64; D]; D] = std::array::from_fn(|k| bg.mesh.points[bg.cell(b.cell)[fv[k]]]);
        let size2 = (1..D).map(|k| dist2(&pts[k], &pts[0])).fold(0.0, f64::max);
        let n = surface::piece_normal(&pts);
        let h = geom::dot(&n, &sub(x, &pts[0]));
        h.is_finite() && h * h <= 1e-24 * size2
    })
}

/// `(parent, children as global vertex ids, children as labels)`.
type SplitCell = (usize, Vec<[usize; 4]>, Vec<[usize; 4]>);

/// Step 3's result: the children of every cell that is split or touches a moved node.
#[derive(Clone, Debug, Default)]
struct Split {
    /// `(parent, children as global vertex ids, children as labels)`; an unsplit cell touching a
    /// moved node has itself as only child.
    cells: Vec<SplitCell>,
    min_quality: f64,
    flat_cells: usize,
}

/// Step 3: subdivides the affected cells.
fn subdivide_cells<const D: usize>(bg: &Background<D>, plan: &Plan<D>, flat_test: &FlatTest<D>) -> Split {
    let mut affected: Vec<usize> = plan.new_node.keys().flat_map(|&e| bg.edge_cells.row(e).iter().copied()).collect();
    affected.extend(plan.moved.keys().flat_map(|&v| bg.vertex_cells.row(v).iter().copied()));
    affected.sort_unstable();
    affected.dedup();
    let nv = bg.mesh.points.len();
    let ct = bg.mesh.cell_type;
    let mut split = Split { min_quality: 1.0, ..Default::default() };
    for c in affected {
        let verts = bg.cell(c);
        let global = |l: usize| -> usize {
            if l <= D {
                verts[l]
            } else {
                nv + plan.new_node[&bg.cell_edge(c, l - D - 1)]
            }
        };
        let split_edges: Vec<usize> = (0..ct.edges().len()).filter(|&k| plan.new_node.contains_key(&bg.cell_edge(c, k))).collect();
        let flat = |l: &[usize; 4]| is_flat(&std::array::from_fn(|k| if k <= D { global(l[k]) } else { usize::MAX }), flat_test);
        let order = split_order(bg, plan, c, &split_edges, &global, &flat);
        let labels = subdivide::bisect(ct, &order);
        let ids: Vec<[usize; 4]> = labels.iter().map(|l| std::array::from_fn(|k| if k <= D { global(l[k]) } else { usize::MAX })).collect();
        for kid in &ids {
            let v: Vec<[f64; D]> = kid[..=D].iter().map(|&g| plan.pos(bg, g)).collect();
            split.min_quality = split.min_quality.min(simplex_quality(&v));
            split.flat_cells += is_flat(kid, flat_test) as usize;
        }
        split.cells.push((c, ids, labels));
    }
    split
}

/// The order in which the split edges of cell `c` are bisected: in 3D globally consistent
/// (longest edge first at the current node positions, ties by global edge number); in 2D the
/// order with the fewest flat children ([`is_flat`], children given by their labels), and among
/// those the one whose worst child has the largest minimum angle. A flat child would undo the
/// move of its moved node ([`refused_by_cells`]) where another diagonal makes none: near the
/// Turek-Hron bar's tip, a cell cut twice by the tip face with its third vertex moved onto the
/// bottom face got the diagonal between the two faces, a flat child across the corner; the
/// move was undone, the bottom face between the corner and the next cut had no facet, and
/// gamma_f was open (a bent bar on `turek-hron-fsi-1.msh`, `tests/fsi_thick_solid.rs`).
fn split_order<const D: usize>(
    bg: &Background<D>,
    plan: &Plan<D>,
    c: usize,
    split_edges: &[usize],
    global: &dyn Fn(usize) -> usize,
    flat: &dyn Fn(&[usize; 4]) -> bool,
) -> Vec<usize> {
    let ct = bg.mesh.cell_type;
    if D == 3 {
        let key = |k: usize| {
            let [i, j] = ct.edges()[k];
            let l2 = dist2(&plan.pos(bg, global(i)), &plan.pos(bg, global(j)));
            (l2, bg.cell_edge(c, k))
        };
        let mut order = split_edges.to_vec();
        order.sort_by(|&a, &b| {
            let (la, ea) = key(a);
            let (lb, eb) = key(b);
            lb.total_cmp(&la).then(ea.cmp(&eb))
        });
        return order;
    }
    let mut best = ((usize::MAX, f64::NEG_INFINITY), split_edges.to_vec());
    for order in subdivide::permutations(split_edges) {
        let children = subdivide::bisect(ct, &order);
        let flat_children = children.iter().filter(|l| flat(l)).count();
        let worst = children
            .iter()
            .map(|l| {
                let p: [[f64; 2]; 3] = std::array::from_fn(|k| {
                    let x = plan.pos(bg, global(l[k]));
                    [x[0], x[1]]
                });
                min_angle2(&p)
            })
            .fold(f64::INFINITY, f64::min);
        if flat_children < best.0 .0 || (flat_children == best.0 .0 && worst > best.0 .1) {
            best = ((flat_children, worst), order);
        }
    }
    best.1
}

/// What [`is_flat`] needs to know of the adaptation in progress.
struct FlatTest<'a, const D: usize> {
    on_surface: &'a dyn Fn(usize) -> bool,
    /// Vertices placed at corners, edges and vertices of gamma_s in step 0, sorted.
    corners: &'a [usize],
    /// The smooth parts at the vertices, where gamma_s has feature lines (3D).
    parts: Option<&'a PartsAt<'a, D>>,
    pos: &'a dyn Fn(usize) -> [f64; D],
    surface: &'a Surface<D>,
}

/// Is the cell with vertices `kid` flat: all its vertices on gamma_s, along one smooth part of
/// it? A cell that fills a solid's corner or wedge, its facets on the sides that meet there, is
/// not: where gamma_s has feature lines (3D), its vertices share no smooth part ([`PartsAt`]);
/// without (2D, or 3D without feature lines), it has a vertex placed at a corner in step 0.
/// Nor is a cell that spans such a wedge without one: a vertex farther than [`GAMMA_F_REL_TOL`] times the cell's diameter
/// from the plane of the gamma_s piece nearest the cell's centroid (in 3D, cells between a
/// block's two faces beside the chain of its edge; in 2D, a cell cut twice by a bar's tip face
/// with its third vertex on the bottom face). With feature lines the plane test is replaced by
/// the gamma_f rule's distance: the centroid within [`GAMMA_F_REL_TOL`] times the diameter of
/// gamma_s (the plane test let thin cells along a curved face pass as not flat, and their
/// facets on both sides went to gamma_f); without, in 3D, a cell that fails the plane test is
/// flat still where the pieces at its vertices lie on one sheet ([`on_one_sheet`]) and two of
/// its facets would be on gamma_f ([`smooth_gamma_f_facet`]). A cell with vertices on a block's
/// edge that lies along
/// one face is flat: a face moved near a plane of the grid gave such cells (a 3D block swinging
/// in fluid, t = 2.6 and 3.8).
fn is_flat<const D: usize>(kid: &[usize; 4], t: &FlatTest<D>) -> bool {
    let vertices = &kid[..kid.iter().position(|&g| g == usize::MAX).unwrap_or(4)];
    if !vertices.iter().all(|&g| (t.on_surface)(g)) {
        return false;
    }
    let fills_a_corner = match t.parts {
        Some(parts) => !parts.on_one_part(vertices, t.pos),
        None => vertices.iter().any(|g| t.corners.binary_search(g).is_ok()),
    };
    if fills_a_corner {
        return false;
    }
    let p: Vec<[f64; D]> = vertices.iter().map(|&g| (t.pos)(g)).collect();
    let centroid: [f64; D] = std::array::from_fn(|d| p.iter().map(|x| x[d]).sum::<f64>() / p.len() as f64);
    let Some(sp) = t.surface.project(&centroid) else { return true };
    let diameter = p.iter().flat_map(|a| p.iter().map(move |b| dist2(a, b))).fold(0.0, f64::max).sqrt();
    if t.parts.is_some() {
        // Along one curved face: near it as a gamma_f facet is (the plane test refuses the
        // cells of a face curved by more than the tolerance over their diameter).
        sp.distance <= GAMMA_F_REL_TOL * diameter
    } else {
        // 3D: a cell along one sheet of a curved gamma_s with facets on gamma_f on two of its
        // sides (not one across a wedge, each of its two facets along one face).
        let facet = |k: usize| -> [[f64; D]; D] {
            let local = ReferenceCell::Tetrahedron.facet(k);
            std::array::from_fn(|j| p[local[j]])
        };
        in_piece_plane(t.surface, sp.piece, &p, GAMMA_F_REL_TOL * diameter)
            || (D == 3 && p.len() == 4 && on_one_sheet(t.surface, &p) && (0..4).filter(|&k| smooth_gamma_f_facet(t.surface, &facet(k))).count() >= 2)
    }
}

/// Do the gamma_s pieces nearest `points` all turn by less than [`corners::CORNER_ANGLE_DEG`]
/// from one another (either way round)? Not so for points on two faces of a wedge.
fn on_one_sheet<const D: usize>(surface: &Surface<D>, points: &[[f64; D]]) -> bool {
    let normals: Vec<[f64; D]> = points.iter().filter_map(|x| surface.project(x)).map(|sp| surface.normal(sp.piece)).collect();
    let cos_corner = corners::CORNER_ANGLE_DEG.to_radians().cos();
    normals.iter().enumerate().all(|(i, a)| normals[i + 1..].iter().all(|b| geom::dot(a, b).abs() >= cos_corner))
}

/// Without feature lines (3D): does the triangle `vertices`, on gamma_s, lie along it rather
/// than across a wedge of pieces given without shared corners? Its normal within
/// [`corners::CORNER_ANGLE_DEG`] of the normals of the pieces nearest its vertices, either way
/// round (pieces need not be consistently oriented). This accepts a chord of a curved gamma_s
/// over pieces that turn, which the plane test refuses (a 3.5 mm facet over the 3D valve's
/// leaflet, its vertices 0.35-0.43 mm off the plane of the piece nearest its centroid, 6
/// degrees off, left a hole in gamma_f). A triangle across a wedge is half the wedge's turn off
/// each face: refused where the faces turn by more than twice the corner angle (a block's edge:
/// 45 degrees off both); across a shallower wedge only the centroid rule refuses it.
fn along_gamma_s<const D: usize>(surface: &Surface<D>, vertices: &[[f64; D]; D]) -> bool {
    let n = surface::piece_normal(vertices);
    let cos_corner = corners::CORNER_ANGLE_DEG.to_radians().cos();
    vertices.iter().all(|x| surface.project(x).is_some_and(|sp| geom::dot(&surface.normal(sp.piece), &n).abs() >= cos_corner))
}

/// Would the facet `vertices`, on gamma_s, be on gamma_f where gamma_s has no feature lines
/// (3D; see the module documentation): its centroid within [`GAMMA_F_REL_TOL`] times its
/// diameter of gamma_s, and it lies within that distance of the plane of the piece nearest its
/// centroid or [`along_gamma_s`]?
fn smooth_gamma_f_facet<const D: usize>(surface: &Surface<D>, vertices: &[[f64; D]; D]) -> bool {
    let centroid: [f64; D] = std::array::from_fn(|d| vertices.iter().map(|p| p[d]).sum::<f64>() / D as f64);
    let diameter = vertices.iter().flat_map(|a| vertices.iter().map(move |b| dist2(a, b))).fold(0.0, f64::max).sqrt();
    let Some(sp) = surface.project(&centroid) else { return false };
    let tol = GAMMA_F_REL_TOL * diameter;
    sp.distance <= tol && (in_piece_plane(surface, sp.piece, vertices, tol) || along_gamma_s(surface, vertices))
}

/// Do all `points` lie within `tol` of the line (2D) or plane (3D) of gamma_s piece `piece`?
fn in_piece_plane<const D: usize>(surface: &Surface<D>, piece: usize, points: &[[f64; D]], tol: f64) -> bool {
    let n = surface.normal(piece);
    let origin = surface.corners(piece)[0];
    let n_len = geom::dot(&n, &n).sqrt();
    points.iter().all(|x| geom::dot(&n, &sub(x, &origin)).abs() <= tol * n_len)
}

/// What the next pass of steps 2-3 changes (see [`refused_by_cells`]).
#[derive(Debug, Default)]
struct Refusals {
    /// Moved nodes whose move is undone.
    pin: Vec<usize>,
    /// Cut edges with a moved end whose cut is dropped.
    drop: Vec<usize>,
}

/// The remedies for the children that are inverted, of quality below `min_move_quality`, or flat
/// (all vertices on gamma_s) and touch a moved node: where such a child has a new node on an edge
/// with a moved end, and the chord from the new node to the moved end runs along gamma_s
/// ([`chord_along_surface`]), that edge's cut is dropped (the edge touches gamma_s at the moved
/// end); otherwise the moves of the child's nodes are undone. A child of quality below
/// `min_cut_quality` only (and not refused) gets the first remedy where it applies, and no
/// other. The chord test keeps a cut whose
/// moved end went to another side of a corner: near the Turek-Hron bar's tip, an edge cut by the
/// bottom face had its other end moved onto the tip face; dropping the cut left the bottom face
/// between that cut and the corner without a facet, and gamma_f open (FSI3 at t = 3.786).
fn refused_by_cells<const D: usize>(
    bg: &Background<D>,
    surface: &Surface<D>,
    plan: &Plan<D>,
    split: &Split,
    opts: &AdaptOptions,
    flat_test: &FlatTest<D>,
) -> Refusals {
    let nv = bg.mesh.points.len();
    let mut edge_of_new_node = vec![0; plan.new_points.len()];
    for (&e, &k) in &plan.new_node {
        edge_of_new_node[k] = e;
    }
    let mut r = Refusals::default();
    for (_, ids, _) in &split.cells {
        for kid in ids {
            let moved: Vec<usize> = kid[..=D].iter().copied().filter(|g| plan.moved.contains_key(g)).collect();
            if moved.is_empty() {
                continue;
            }
            let v: Vec<[f64; D]> = kid[..=D].iter().map(|&g| plan.pos(bg, g)).collect();
            let quality = simplex_quality(&v);
            // Negated comparisons: a NaN measure or quality is refused.
            let refused = !(simplex_measure(&v) > 0.0) || !(quality >= opts.min_move_quality) || is_flat(kid, flat_test);
            if !refused && quality >= opts.min_cut_quality {
                continue;
            }
            let len = r.drop.len();
            for &g in kid[..=D].iter().filter(|&&g| g >= nv) {
                let e = edge_of_new_node[g - nv];
                let cut = &plan.new_points[g - nv];
                if bg.topology.edges[e].iter().any(|v| plan.moved.get(v).is_some_and(|m| chord_along_surface(surface, cut, m))) {
                    r.drop.push(e);
                }
            }
            if refused && r.drop.len() == len {
                r.pin.extend(moved);
            }
        }
    }
    for list in [&mut r.pin, &mut r.drop] {
        list.sort_unstable();
        list.dedup();
    }
    r
}

/// Does the chord between two points of gamma_s run along it: its midpoint within
/// [`GAMMA_F_REL_TOL`] times its length of gamma_s (the gamma_f rule for a facet), or within
/// round-off (`T_SNAP` of the coordinates) where the points coincide? Not across a corner or a
/// fold.
fn chord_along_surface<const D: usize>(surface: &Surface<D>, a: &[f64; D], b: &[f64; D]) -> bool {
    let mid: [f64; D] = std::array::from_fn(|d| 0.5 * (a[d] + b[d]));
    let round_off = T_SNAP * (1.0 + a.iter().fold(0.0f64, |m, v| m.max(v.abs())));
    surface.project(&mid).is_some_and(|sp| sp.distance <= GAMMA_F_REL_TOL * dist2(a, b).sqrt() + round_off)
}

/// The adapted mesh without gamma_f.
struct Assembled<const D: usize> {
    mesh: Mesh<D>,
    new_to_old_cell: Vec<usize>,
    /// Adapted-mesh index of each child in `Split::cells` order.
    child_index: Vec<Vec<usize>>,
    stats: AdaptStats,
}

/// Builds the adapted mesh: moved points, new points, children in place of their parents,
/// boundary facets of split parents given to the children's facets that lie in them.
fn assemble<const D: usize>(bg: &Background<D>, plan: &Plan<D>, split: &Split) -> Assembled<D> {
    let mut mesh = bg.mesh.clone();
    for (&v, x) in &plan.moved {
        mesh.points[v] = *x;
    }
    mesh.points.extend_from_slice(&plan.new_points);
    let mut new_to_old_cell: Vec<usize> = (0..bg.num_cells()).collect();
    let mut child_index = Vec::with_capacity(split.cells.len());
    let mut split_parent = HashMap::new();
    for (si, (c, ids, _)) in split.cells.iter().enumerate() {
        split_parent.insert(*c, si);
        let mut idx = Vec::with_capacity(ids.len());
        for (k, kid) in ids.iter().enumerate() {
            let n = if k == 0 {
                *c
            } else {
                mesh.cell_tags.push(bg.mesh.cell_tags[*c]);
                mesh.cell_nodes.extend_from_slice(&[0; 4][..=D]);
                new_to_old_cell.push(*c);
                new_to_old_cell.len() - 1
            };
            mesh.cell_nodes[n * (D + 1)..(n + 1) * (D + 1)].copy_from_slice(&kid[..=D]);
            idx.push(n);
        }
        child_index.push(idx);
    }
    let ct = bg.mesh.cell_type;
    let mut boundary = Vec::with_capacity(bg.mesh.boundary.len());
    for b in &bg.mesh.boundary {
        let Some(&si) = split_parent.get(&b.cell) else {
            boundary.push(*b);
            continue;
        };
        let labels = &split.cells[si].2;
        for (k, l) in labels.iter().enumerate() {
            for j in 0..ct.num_facets() {
                if ct.facet(j).iter().all(|&lv| subdivide::label_on_facet(ct, l[lv], b.facet)) {
                    boundary.push(BoundaryFacet { cell: child_index[si][k], facet: j, tag: b.tag });
                }
            }
        }
    }
    mesh.boundary = boundary;
    Assembled { mesh, new_to_old_cell, child_index, stats: AdaptStats::default() }
}

/// On-gamma_s flag of every adapted-mesh vertex.
fn on_surface_flags<const D: usize>(bg: &Background<D>, plan: &Plan<D>, cuts: &CutSet<D>) -> Vec<bool> {
    let nv = bg.mesh.points.len();
    let mut f = vec![false; nv + plan.new_points.len()];
    for &v in plan.moved.keys().chain(cuts.touched.iter()) {
        f[v] = true;
    }
    f[nv..].iter_mut().for_each(|x| *x = true);
    f
}

/// 3D with feature lines: the edges of the adapted mesh that still cross gamma_s within their
/// length of a feature line, cut at new nodes (no moves), and the mesh subdivided again, pass
/// after pass (at most [`MAX_CROSSING_PASSES`]) until none is left; edges with both ends on
/// gamma_s are not cut (a chord along it), nor crossings within [`CROSSING_AT_END`] of an end on
/// gamma_s, nor those within `TOUCH_FRACTION * eps_hat` of an end on gamma_s of an edge that
/// only skims that end's face ([`skims_its_face`]: a new node there, beside the end, made a
/// needle facet on gamma_f, 0.038 mm among 1.3 mm edges at the 3D valve's first closure, whose
/// multiplier and the pressure gradient of the sliver cell beside it Newton could not control),
/// unless the edge crosses gamma_s again (its second cut), and those as near a boundary vertex
/// taken to lie on gamma_s off it (a boundary touch, on no smooth part: the valve's leaflet 0.03
/// mm above the plane of coaptation, whose crossings made five gamma_f vertices within 0.07
/// mm). Next to a block's edge a fluid cell can be cut by both faces without holding the edge's
/// chain: an edge of it passes through the solid's wedge, crossing both faces, and keeps one
/// point; the children of the bisection then have edges between that point and the cell's
/// other vertices that cross the other face, and gamma_f had a hole there (those near-end
/// crossings are cut: dropping every crossing within `TOUCH_FRACTION * eps_hat` of an end on
/// gamma_s left such holes). The cut children leave no edge crossing gamma_s near the feature
/// lines, so the faces there are unions of facets. Modifies `out` (its `child_index` is left as
/// it was) and `on_surface`.
fn cut_crossings_near_features<const D: usize>(
    out: &mut Assembled<D>,
    on_surface: &mut Vec<bool>,
    surface: &Surface<D>,
    lines: &[Vec<[f64; D]>],
    parts: &[usize],
    opts: &AdaptOptions,
) -> Result<Extra, AdaptError> {
    let min_quality = opts.min_move_quality;
    let near_end = TOUCH_FRACTION * opts.eps_hat;
    let parts_of = |x: &[f64; D]| parts_of_point(surface, parts, x);
    let mut extra = Extra { min_quality: 1.0, ..Default::default() };
    if D != 3 || lines.is_empty() {
        return Ok(extra);
    }
    while extra.passes < MAX_CROSSING_PASSES {
        let bg = Background::new(&out.mesh)?;
        let all_cuts = find_cuts(&bg, surface);
        let flags: &[bool] = on_surface;
        let mut kinks = features::kinks(&bg, lines, (0..flags.len()).filter(|&v| flags[v]), min_quality);
        let nv = bg.mesh.points.len();
        let on = |g: usize| g >= nv || flags[g];
        let (plan, split) = loop {
            let cuts = without_kink_edges(&all_cuts, &kinks);
            let mut plan = Plan::default();
            for c in &cuts.cuts {
                let [u, v] = bg.topology.edges[c.edge];
                let len2 = dist2(&bg.mesh.points[u], &bg.mesh.points[v]);
                // The kept cut of an edge crossing gamma_s twice is the one farther from its ends.
                let once = cuts.second_cuts.binary_search_by_key(&c.edge, |s| s.edge).is_err();
                let at_surface_end = [(u, c.t), (v, 1.0 - c.t)].iter().any(|&(w, t)| {
                    if !flags[w] || t > near_end {
                        return false;
                    }
                    let at_w = parts_of(&bg.mesh.points[w]);
                    // On no part: a boundary touch, off gamma_s by up to `TOUCH_FRACTION *
                    // eps_hat` of an edge; a crossing as near is that vertex touching it.
                    t <= CROSSING_AT_END || at_w.is_empty() || once && skims_its_face(&at_w, &parts_of(&c.x))
                });
                if !(at_surface_end || flags[u] && flags[v]) && lines.iter().any(|l| features::project_on_line(l, &c.x).2.powi(2) < len2) {
                    add_node(&mut plan, c.edge, c.x);
                }
            }
            for &(e, x) in &kinks {
                add_node(&mut plan, e, x);
            }
            let pos = |g: usize| plan.pos(&bg, g);
            let parts_at = PartsAt::new(surface, parts);
            let flat_test = FlatTest { on_surface: &on, corners: &[], parts: Some(&parts_at), pos: &pos, surface };
            let split = subdivide_cells(&bg, &plan, &flat_test);
            let refused = refused_kinks(&bg, &plan, &split, &kinks, min_quality);
            if refused.is_empty() {
                break (plan, split);
            }
            extra.refused_kinks += refused.len();
            kinks.retain(|k| !refused.contains(&k.0));
        };
        extra.kinks += kinks.len();
        if plan.new_points.is_empty() {
            break;
        }
        let next = assemble(&bg, &plan, &split);
        out.new_to_old_cell = next.new_to_old_cell.iter().map(|&c| out.new_to_old_cell[c]).collect();
        out.mesh = next.mesh;
        on_surface.resize(nv + plan.new_points.len(), true);
        extra.cuts += plan.new_points.len() - kinks.len();
        extra.min_quality = extra.min_quality.min(split.min_quality);
        extra.passes += 1;
    }
    Ok(extra)
}

/// Does an edge from a vertex on gamma_s (on the smooth parts `at_vertex`) that crosses it near
/// that vertex (at a point on the parts `at_crossing`) only skim the vertex's face? Yes where
/// the vertex lies inside one face (not on a feature line) and the crossing on that face too:
/// the edge leaves the face at a slant and crosses the faceted face back (its triangles turn
/// by some degrees), so the edge lies on the side of its far end but for a sliver. A crossing
/// of another face is the edge passing through the solid's wedge by a block's edge, and is cut.
/// (A solid thinner than that fraction of the edge, with a rounded rim and no feature line
/// between its faces, would be taken to be skimmed too; the valve's leaflet, 0.5 mm thick in
/// cells of 2 mm, has its faces apart at its edges.)
fn skims_its_face(at_vertex: &[usize], at_crossing: &[usize]) -> bool {
    matches!(at_vertex, [p] if at_crossing.contains(p))
}

/// `cuts` without the cuts (and second cuts) of the edges that take a kink of a feature line
/// instead.
fn without_kink_edges<const D: usize>(cuts: &CutSet<D>, kinks: &[(usize, [f64; D])]) -> CutSet<D> {
    let edges: HashSet<usize> = kinks.iter().map(|k| k.0).collect();
    let mut out = cuts.clone();
    out.cuts.retain(|c| !edges.contains(&c.edge));
    out.second_cuts.retain(|c| !edges.contains(&c.edge));
    out
}

/// The edges of `kinks` whose node leaves a child cell of `split` inverted, or of quality below
/// `min_quality` where the node on the edge's chord would not: [`features::kinks`] checks the
/// cells around the edge halved at the kink alone, but a cell cut on another edge too, or
/// holding two kink edges, is split further. Those kinks are refused (their edges left
/// unsplit).
fn refused_kinks<const D: usize>(bg: &Background<D>, plan: &Plan<D>, split: &Split, kinks: &[(usize, [f64; D])], min_quality: f64) -> HashSet<usize> {
    let nv = bg.mesh.points.len();
    // Adapted-mesh vertex of each kink -> (its edge, the nearest point of the edge's chord).
    let kink_at: HashMap<usize, (usize, [f64; D])> = kinks
        .iter()
        .filter_map(|&(e, x)| {
            let [a, b] = bg.topology.edges[e].map(|v| bg.mesh.points[v]);
            plan.new_node.get(&e).map(|&k| (nv + k, (e, geom::lerp(&a, &b, geom::closest_on_segment(&x, &a, &b)))))
        })
        .collect();
    let mut refused = HashSet::new();
    for kid in split.cells.iter().flat_map(|(_, ids, _)| ids) {
        let at: Vec<(usize, (usize, [f64; D]))> = kid[..=D].iter().filter_map(|g| kink_at.get(g).map(|k| (*g, *k))).collect();
        if at.is_empty() {
            continue;
        }
        let v: Vec<[f64; D]> = kid[..=D].iter().map(|&g| plan.pos(bg, g)).collect();
        let on_chords: Vec<[f64; D]> = kid[..=D].iter().map(|&g| at.iter().find(|k| k.0 == g).map_or(plan.pos(bg, g), |k| k.1 .1)).collect();
        let quality = simplex_quality(&v);
        let at_fault = simplex_measure(&v) <= 0.0 || quality < min_quality && simplex_quality(&on_chords) >= min_quality;
        if at_fault {
            refused.extend(at.iter().map(|k| k.1 .0));
        }
    }
    refused
}

/// A crossing this close (relative to its edge) to an end of the edge on gamma_s is that end
/// touching gamma_s, moved off it by round-off (`cut_crossings_near_features`): an edge
/// nearly parallel to a face from a vertex on a feature line.
const CROSSING_AT_END: f64 = 1e-6;

/// Passes of [`cut_crossings_near_features`] at most.
const MAX_CROSSING_PASSES: usize = 4;

/// What [`cut_crossings_near_features`] did.
#[derive(Clone, Copy, Debug, Default)]
struct Extra {
    passes: usize,
    cuts: usize,
    kinks: usize,
    refused_kinks: usize,
    min_quality: f64,
}

/// Step 4: gamma_f (see the module documentation for the rule) among the facets of the `cells`
/// of `mesh` (the children and the cells touching an on-surface vertex). Returns the facets and
/// the number rejected.
fn build_gamma_f<const D: usize>(
    mesh: &Mesh<D>,
    mut cells: Vec<usize>,
    on_surface: &[bool],
    surface: &Surface<D>,
    parts: &[usize],
) -> (Vec<GammaFacet<D>>, usize, usize) {
    let ct = mesh.cell_type;
    let has_features = parts.iter().any(|&p| p != 0);
    cells.sort_unstable();
    cells.dedup();
    let mut facets: HashMap<[usize; 3], Vec<(usize, usize)>> = HashMap::new();
    for &c in &cells {
        let v = mesh.cell(c);
        for j in 0..ct.num_facets() {
            let fv = ct.facet(j);
            if fv.iter().all(|&k| on_surface[v[k]]) {
                let mut key = [usize::MAX; 3];
                for (i, &k) in fv.iter().enumerate() {
                    key[i] = v[k];
                }
                key[..D].sort_unstable();
                facets.entry(key).or_default().push((c, j));
            }
        }
    }
    let mut keys: Vec<[usize; 3]> = facets.keys().copied().collect();
    keys.sort_unstable();
    let mut located: HashMap<usize, SurfacePoint<D>> = HashMap::new();
    let mut locate = |v: usize| *located.entry(v).or_insert_with(|| surface.project(&mesh.points[v]).expect("non-empty surface"));
    let parts_at = PartsAt::new(surface, parts);
    let mut out_facets = Vec::new();
    let mut rejected = 0;
    for key in keys {
        let sides = &facets[&key];
        let (c0, j0) = sides[0];
        let fv = ct.facet(j0);
        let mut verts: [usize; D] = std::array::from_fn(|k| mesh.cell(c0)[fv[k]]);
        let pts = verts.map(|v| mesh.points[v]);
        let centroid: [f64; D] = std::array::from_fn(|d| pts.iter().map(|p| p[d]).sum::<f64>() / D as f64);
        let diam2 = (0..D).flat_map(|i| (0..D).map(move |j| (i, j))).map(|(i, j)| dist2(&pts[i], &pts[j])).fold(0.0, f64::max);
        let Some(sp) = surface.project(&centroid) else { continue };
        let spans_a_feature = D == 3
            && if has_features {
                // On no part: across a feature line; on two: along one (a sliver between a
                // chain edge, a chord of the bent line, and a vertex on the line beside it; a
                // closed line's triangles, such as a cap's rim, would be refused too).
                parts_at.shared_parts(&verts, |v| mesh.points[v]) != 1
            } else {
                !(in_piece_plane(surface, sp.piece, &pts, GAMMA_F_REL_TOL * diam2.sqrt()) || along_gamma_s(surface, &pts))
            };
        // Vertices on gamma_s to round-off, except boundary touches (up to `eps_hat / 4` of an
        // edge off it): the coupling locates every quadrature point within this distance.
        let tol2 = GAMMA_F_REL_TOL * GAMMA_F_REL_TOL * diam2;
        let vertex_off = verts.iter().any(|&v| locate(v).distance.powi(2) > tol2);
        if sp.distance * sp.distance > tol2 || spans_a_feature || vertex_off {
            rejected += 1;
            continue;
        }
        // Outward normal of facet j0 of c0 against the piece normal.
        let n_out = surface::piece_normal(&pts);
        let n_piece = surface.normal(sp.piece);
        let other = sides.get(1).copied().unwrap_or(NO_CELL);
        let sides_arr = if geom::dot(&n_out, &n_piece) >= 0.0 {
            [(c0, j0), other]
        } else {
            verts.swap(0, 1);
            [other, (c0, j0)]
        };
        let location = verts.map(&mut locate);
        let misfit = Misfit { measure: facet_measure(&pts), distance: sp.distance };
        out_facets.push((GammaFacet { vertices: verts, sides: sides_arr, location }, misfit));
    }
    let (out_facets, two_sided) = one_side_per_cell(out_facets);
    (out_facets, rejected, two_sided)
}

/// How far a gamma_f facet lies from gamma_s: its measure, and the distance of its centroid.
#[derive(Clone, Copy, Debug)]
struct Misfit {
    measure: f64,
    distance: f64,
}

/// The measure (length, area) of a facet.
fn facet_measure<const D: usize>(p: &[[f64; D]; D]) -> f64 {
    let t = pad3(&sub(&p[1], &p[0]));
    if D == 2 {
        dot(&t, &t).sqrt()
    } else {
        let n = cross(&t, &pad3(&sub(&p[2], &p[0])));
        0.5 * dot(&n, &n).sqrt()
    }
}

/// The **cells on both sides** rule (see the module documentation): where a cell has gamma_f
/// facets on both of its sides (on the minus side of some, the plus side of others), the facets
/// of one side leave gamma_f, cell by cell in increasing order, skipping cells that a facet
/// dropped before made one-sided. The side dropped is the one that leaves fewer ridges (edges in
/// 3D, vertices in 2D) of gamma_f on one facet only, so that gamma_f gets no hole where the
/// sides do not cover the same part of gamma_s; where both leave as many, the side farther from
/// gamma_s (mean distance of its facets' centroids, weighted by their measure; ties: the plus
/// side). Returns the facets kept and the number of such cells.
fn one_side_per_cell<const D: usize>(facets: Vec<(GammaFacet<D>, Misfit)>) -> (Vec<GammaFacet<D>>, usize) {
    // For each cell, its facets on gamma_f with the side it lies on (0: minus, 1: plus).
    let mut of_cell: HashMap<usize, Vec<(usize, usize)>> = HashMap::new();
    for (f, (g, _)) in facets.iter().enumerate() {
        for (side, &(c, _)) in g.sides.iter().enumerate().filter(|(_, &s)| s != NO_CELL) {
            of_cell.entry(c).or_default().push((f, side));
        }
    }
    // How many facets of gamma_f (those kept so far) share each ridge.
    let ridges = |g: &GammaFacet<D>| -> Vec<Vec<usize>> {
        (0..D)
            .map(|skip| {
                let mut r: Vec<usize> = (0..D).filter(|&k| k != skip).map(|k| g.vertices[k]).collect();
                r.sort_unstable();
                r
            })
            .collect()
    };
    let mut sharing: HashMap<Vec<usize>, usize> = HashMap::new();
    for (g, _) in &facets {
        for r in ridges(g) {
            *sharing.entry(r).or_default() += 1;
        }
    }
    let mut cells: Vec<usize> = of_cell.keys().copied().collect();
    cells.sort_unstable();
    let mut dropped = vec![false; facets.len()];
    let mut two_sided = 0;
    for c in cells {
        let kept: Vec<(usize, usize)> = of_cell[&c].iter().copied().filter(|&(f, _)| !dropped[f]).collect();
        let side = |s: usize| kept.iter().filter(move |&&(_, k)| k == s).map(|&(f, _)| f);
        if side(0).next().is_none() || side(1).next().is_none() {
            continue;
        }
        two_sided += 1;
        // The ridges of side `s` that would be left on one facet without it.
        let opened = |s: usize| {
            let mut less: HashMap<Vec<usize>, usize> = HashMap::new();
            side(s).flat_map(|f| ridges(&facets[f].0)).for_each(|r| *less.entry(r).or_default() += 1);
            less.iter().filter(|(r, &n)| sharing[*r] - n == 1).count()
        };
        let mean_distance = |s: usize| {
            let (weighted, measure) = side(s).map(|f| facets[f].1).fold((0.0, 0.0), |(w, m), x| (w + x.measure * x.distance, m + x.measure));
            weighted / measure
        };
        let drop_side = match opened(0).cmp(&opened(1)) {
            std::cmp::Ordering::Less => 0,
            std::cmp::Ordering::Greater => 1,
            std::cmp::Ordering::Equal if mean_distance(0) > mean_distance(1) => 0,
            std::cmp::Ordering::Equal => 1,
        };
        for f in side(drop_side).collect::<Vec<_>>() {
            dropped[f] = true;
            for r in ridges(&facets[f].0) {
                *sharing.get_mut(&r).expect("counted above") -= 1;
            }
        }
    }
    let kept = facets.into_iter().zip(dropped).filter(|(_, d)| !d).map(|((g, _), _)| g).collect();
    (kept, two_sided)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::{rectangle_triangles, DiagonalPattern};

    #[test]
    fn rejects_bad_eps_hat_and_cell_type() {
        let m = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 2, 2, DiagonalPattern::Right);
        let s = Surface::from_polyline(vec![[0.5, -1.0], [0.5, 2.0]]).unwrap();
        assert!(matches!(adapt(&m, &s, 0.0), Err(AdaptError::EpsHat(_))));
        assert!(matches!(adapt(&m, &s, 0.6), Err(AdaptError::EpsHat(_))));
        let q = crate::generate::rectangle_quads(0.0, 1.0, 0.0, 1.0, 2, 2, crate::mesh::GeometryOrder::Linear);
        assert!(matches!(adapt(&q, &s, 0.2), Err(AdaptError::NotSimplex(_))));
    }

    /// A cell with gamma_f facets on both of its sides (a sliver along a curved gamma_s, its
    /// two sides over the same four edges) keeps those of the side nearer gamma_s; the cells
    /// beside it, and a cell on one side only, keep theirs.
    #[test]
    fn a_cell_on_both_sides_of_gamma_f_keeps_the_side_nearer_gamma_s() {
        let at = SurfacePoint { piece: 0, bary: [1.0, 0.0, 0.0], x: [0.0; 3], distance: 0.0 };
        let facet = |vertices: [usize; 3], sides: [(usize, usize); 2], measure: f64, distance: f64| {
            (GammaFacet { vertices, sides, location: [at; 3] }, Misfit { measure, distance })
        };
        // The sliver 0123: on its minus side the facets over the diagonal 1-3, at a mean distance
        // (weighted by measure) of 0.013 from gamma_s; on its plus side those over 0-2, 0.033,
        // though one lies on it: the plus side leaves. Cell 5 lies on one side only.
        let facets = vec![
            facet([0, 1, 3], [(0, 0), (1, 0)], 1.0, 0.01),
            facet([1, 2, 3], [(0, 1), (2, 0)], 0.5, 0.02),
            facet([0, 1, 2], [(3, 0), (0, 2)], 1.0, 0.05),
            facet([0, 2, 3], [(4, 0), (0, 3)], 0.5, 0.0),
            facet([6, 7, 8], [(5, 0), (6, 0)], 1.0, 0.3),
            facet([7, 8, 9], [(5, 1), NO_CELL], 1.0, 0.3),
        ];
        let (kept, two_sided) = one_side_per_cell(facets);
        assert_eq!(two_sided, 1);
        let kept: Vec<[usize; 3]> = kept.iter().map(|g| g.vertices).collect();
        assert_eq!(kept, [[0, 1, 3], [1, 2, 3], [6, 7, 8], [7, 8, 9]]);
    }

    /// Where the two sides of a cell do not cover the same part of gamma_s, the side whose
    /// leaving opens no hole in gamma_f leaves, though it lies nearer gamma_s (2D: the triangle
    /// abc along gamma_f x-a-b-c-y whose edge bc was not taken; dropping ac would leave b and c
    /// each on one facet only).
    #[test]
    fn a_cell_on_both_sides_of_gamma_f_leaves_no_hole() {
        let at = SurfacePoint { piece: 0, bary: [1.0, 0.0, 0.0], x: [0.0; 2], distance: 0.0 };
        let facet = |vertices: [usize; 2], sides: [(usize, usize); 2], distance: f64| {
            (GammaFacet { vertices, sides, location: [at; 2] }, Misfit { measure: 1.0, distance })
        };
        let (a, b, c, x, y) = (0, 1, 2, 3, 4);
        let facets = vec![
            facet([x, a], [(1, 0), (2, 0)], 0.0),
            facet([a, b], [(0, 0), (3, 0)], 0.0),
            facet([a, c], [(4, 0), (0, 1)], 0.1),
            facet([c, y], [(5, 0), (6, 0)], 0.0),
        ];
        let (kept, two_sided) = one_side_per_cell(facets);
        assert_eq!(two_sided, 1);
        let kept: Vec<[usize; 2]> = kept.iter().map(|g| g.vertices).collect();
        assert_eq!(kept, [[x, a], [a, c], [c, y]]);
    }

    /// A cell in the wedge of two faces given without shared corners (no feature lines), two of
    /// its vertices on the edge and one on each face: each face holds one of its facets, but it
    /// fills the wedge and is not flat.
    #[test]
    fn a_cell_across_a_wedge_of_loose_pieces_is_not_flat() {
        let pieces = vec![[0.0, -1.0, 0.0], [2.0, -1.0, 0.0], [0.0, 2.0, 0.0], [0.0, -1.0, 0.0], [0.0, 2.0, 0.0], [0.0, -1.0, 2.0]];
        let s = Surface::from_pieces(pieces, vec![[0, 1, 2], [3, 4, 5]]).unwrap();
        let x: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.5]];
        let (on, pos) = (|_: usize| true, |g: usize| x[g]);
        let t = FlatTest { on_surface: &on, corners: &[], parts: None, pos: &pos, surface: &s };
        assert!(!is_flat(&[0, 1, 2, 3], &t));
        // Each of the two facets alone would be on gamma_f.
        assert!(smooth_gamma_f_facet(&s, &[x[0], x[1], x[2]]) && smooth_gamma_f_facet(&s, &[x[0], x[1], x[3]]));
    }

    #[test]
    fn vertical_line_through_unit_square() {
        let m = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 4, 4, DiagonalPattern::Right);
        let s = Surface::from_polyline(vec![[0.4, -1.0], [0.4, 2.0]]).unwrap();
        let a = adapt(&m, &s, 0.2).unwrap();
        a.mesh.check().unwrap();
        assert!((a.gamma_f_measure() - 1.0).abs() < 1e-12, "{}", a.gamma_f_measure());
        verify_adapted(&m, &a, &s).unwrap();
    }
}
