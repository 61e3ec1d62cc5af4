//! PNG pictures (the font compiled in, see [`super::plot`]; no system libraries):
//! [`write_speed_png`] draws `speed.png` of a 2D run, `|u|` on the mesh with axes, a colour bar
//! and the solid; [`write_slice_png`] draws `speed.png` of a 3D run, `|u|` on a plane through
//! the solid ([`Slice`]); [`write_surfaces_png`] draws the coupling surfaces gamma_s and gamma_f
//! of a 3D run (the paper's figs. 7 and 8).

use crate::discretize::flow::FlowDiscretization;
use fdfsi_fem::vtk::{UnstructuredGrid, VtkCellType};
use plotters::prelude::*;
use std::path::Path;

/// Why a picture was not drawn.
#[derive(Debug, thiserror::Error)]
pub enum PictureError {
    /// Nothing to draw, or a request that cannot be met (a 3D flow for a 2D picture, too small a
    /// size, a window off the mesh, ...).
    #[error("{0}")]
    Input(String),
    /// The drawing backend failed (a file it could not create, a font).
    #[error("drawing: {0}")]
    Draw(String),
    /// The velocity could not be evaluated on a slice's points.
    #[error("sampling the slice: {0}")]
    Transfer(#[from] fdfsi_fem::adapt::AdaptError),
    /// The finished picture could not be moved to its name.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// A drawing backend's failure as a [`PictureError`].
pub(super) fn draw_failed(e: impl std::fmt::Display) -> PictureError {
    PictureError::Draw(e.to_string())
}

/// Draws the axes of `chart` in model coordinates, without grid lines, named `across` and `up`.
fn draw_axes<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>>,
    across: &str,
    up: &str,
) -> Result<(), PictureError> {
    let font = super::plot::FAMILY;
    chart.configure_mesh().disable_mesh().x_desc(across).y_desc(up).label_style((font, 14)).axis_desc_style((font, 16)).draw().map_err(draw_failed)
}

/// The viridis colour map at `s` in [0, 1] (piecewise linear through 5 control colours).
pub fn viridis(s: f64) -> RGBColor {
    const C: [(f64, f64, f64); 5] = [(68.0, 1.0, 84.0), (59.0, 82.0, 139.0), (33.0, 145.0, 140.0), (94.0, 201.0, 98.0), (253.0, 231.0, 37.0)];
    let s = if s.is_finite() { s.clamp(0.0, 1.0) } else { 0.0 } * 4.0;
    let i = (s.floor() as usize).min(3);
    let f = s - i as f64;
    let mix = |a: f64, b: f64| (a + f * (b - a)).round() as u8;
    RGBColor(mix(C[i].0, C[i + 1].0), mix(C[i].1, C[i + 1].1), mix(C[i].2, C[i + 1].2))
}

/// What a speed picture ([`write_speed_png`]) shows besides the flow.
#[derive(Clone, Debug, Default)]
pub struct SpeedPicture {
    /// The caption above the picture.
    pub title: String,
    /// The rectangle `[[x0, y0], [x1, y1]]` shown (default: the whole mesh); it is widened
    /// across where the picture would be less than [`MIN_PLOT_HEIGHT`] pixels high.
    pub window: Option<[[f64; 2]; 2]>,
    /// Polygons filled in grey over the flow (the solid's cells).
    pub solid: Vec<Vec<[f64; 2]>>,
    /// Polylines drawn in white over the flow and the solid (gamma_f).
    pub outlines: Vec<Vec<[f64; 2]>>,
    /// The names of the axes across and up (default `x` and `y`).
    pub axis_labels: Option<[String; 2]>,
}

/// The speed of a 2D flow on its mesh: 6-node triangles (vertices, then the nodes on the edges
/// 01, 12, 20: VTK's order) and `|u|` at their nodes.
#[derive(Clone, Debug, Default)]
pub struct SpeedField {
    pub nodes: Vec<[f64; 2]>,
    pub triangles: Vec<[usize; 6]>,
    pub speed: Vec<f64>,
}

impl SpeedField {
    /// The speed of the flow solution `x` of `disc` (2D).
    pub fn of_flow<const D: usize>(disc: &FlowDiscretization<D>, x: &[f64]) -> Result<Self, PictureError> {
        if D != 2 {
            return Err(PictureError::Input(format!("speed pictures are drawn of 2D flows, not {D}D")));
        }
        let vf = &disc.velocity_field();
        let nodes = disc.velocity_nodes.iter().map(|p| [p[0], p[1]]).collect();
        let speed = (0..vf.nodes.num_nodes).map(|n| x[vf.dof(n, 0)].hypot(x[vf.dof(n, 1)])).collect();
        let triangles = (0..disc.mesh.num_cells()).map(|c| std::array::from_fn(|k| vf.nodes.cell(c)[k])).collect();
        Ok(SpeedField { nodes, triangles, speed })
    }

    /// The speed of a fluid grid as `fdfsi run` writes it (6-node triangles, point data
    /// `velocity`).
    pub fn of_grid(grid: &UnstructuredGrid) -> Result<Self, PictureError> {
        let v = velocity_of(grid)?;
        let mut triangles = Vec::with_capacity(grid.num_cells());
        for c in 0..grid.num_cells() {
            match (grid.cell_types[c], grid.cell(c)) {
                (VtkCellType::QuadraticTriangle, nodes) => triangles.push(std::array::from_fn(|k| nodes[k])),
                (other, _) => return Err(PictureError::Input(format!("cell {c} is a {other:?}, not a 6-node triangle (a 2D fluid grid)"))),
            }
        }
        Ok(SpeedField {
            nodes: grid.points.iter().map(|p| [p[0], p[1]]).collect(),
            triangles,
            speed: (0..grid.num_points()).map(|n| v[3 * n].hypot(v[3 * n + 1])).collect(),
        })
    }

    /// The speed of the 3D flow solution `x` of `disc` on `slice`, sampled in the rectangle
    /// `[lo, hi]` of the plane (its coordinates, see [`Slice::project`]) at `(2 m + 1) x (2 n + 1)`
    /// points for `cells = [m, n]`: each `2 x 2` block of points makes two 6-node triangles. The
    /// P2+ velocity is evaluated in the cell containing each point; a point outside the fluid
    /// mesh (outside the model, or in the fluid a solid removed) gets the speed NaN and is not
    /// drawn.
    pub fn of_slice<const D: usize>(
        disc: &FlowDiscretization<D>,
        x: &[f64],
        slice: &Slice,
        window: [[f64; 2]; 2],
        cells: [usize; 2],
    ) -> Result<Self, PictureError> {
        if D != 3 {
            return Err(PictureError::Input(format!("slices are drawn of 3D flows, not {D}D")));
        }
        let samples = SliceSamples::new(slice, window, cells)?;
        let points: Vec<[f64; D]> = samples.points.iter().map(|p| std::array::from_fn(|d| p[d])).collect();
        let vf = disc.velocity_field();
        let velocity = fdfsi_fem::adapt::transfer::transfer_p2plus_or(&disc.mesh, &vf.nodes, &x[vf.range()], &points, 0.0, |_, _| Ok([f64::NAN; D]))?;
        let speed = velocity.chunks_exact(D).map(|v| v.iter().map(|c| c * c).sum::<f64>().sqrt()).collect();
        Ok(samples.with_speed(speed))
    }

    /// The speed of a 3D fluid grid as `fdfsi run` writes it (10-node tetrahedra in VTK's order,
    /// point data `velocity`) on `slice`, sampled as [`Self::of_slice`]: the P2 velocity of the
    /// tetrahedron containing each point (the grid has no bubble), NaN outside the grid.
    pub fn of_grid_slice(grid: &UnstructuredGrid, slice: &Slice, window: [[f64; 2]; 2], cells: [usize; 2]) -> Result<Self, PictureError> {
        use fdfsi_fem::element::{ElementFamily, ReferenceCell, ReferenceElement};
        let velocity = velocity_of(grid)?;
        if let Some(c) = (0..grid.num_cells()).find(|&c| grid.cell_types[c] != VtkCellType::QuadraticTetra) {
            return Err(PictureError::Input(format!("cell {c} is a {:?}, not a 10-node tetrahedron (a 3D fluid grid)", grid.cell_types[c])));
        }
        // The grid as a mesh of 10-node tetrahedra (VTK's node order is the P2 element's), for
        // the point location (by the cells' vertices) and the basis.
        let mesh = fdfsi_fem::mesh::Mesh::<3> {
            points: grid.points.clone(),
            cell_type: ReferenceCell::Tetrahedron,
            order: fdfsi_fem::mesh::GeometryOrder::Quadratic,
            cell_nodes: grid.connectivity.clone(),
            cell_tags: vec![0; grid.num_cells()],
            region_names: Vec::new(),
            boundary: Vec::new(),
            boundary_names: Vec::new(),
        };
        let p2 = ReferenceElement::<3>::new(ReferenceCell::Tetrahedron, ElementFamily::P2).expect("the P2 tetrahedron");
        let (mut phi, mut grads) = ([0.0; 10], [[0.0; 3]; 10]);
        let locator = fdfsi_fem::adapt::CellLocator::new(&mesh);
        let samples = SliceSamples::new(slice, window, cells)?;
        let speed = samples
            .points
            .iter()
            .map(|p| match locator.locate(&mesh, p) {
                Some((c, xi)) => {
                    p2.eval_into(&xi, &mut phi, &mut grads);
                    let u: [f64; 3] = std::array::from_fn(|a| mesh.cell(c).iter().zip(&phi).map(|(&n, f)| f * velocity[3 * n + a]).sum());
                    u.iter().map(|c| c * c).sum::<f64>().sqrt()
                }
                None => f64::NAN,
            })
            .collect();
        Ok(samples.with_speed(speed))
    }

    /// The bounding box of the nodes.
    pub fn bounds(&self) -> ([f64; 2], [f64; 2]) {
        fdfsi_fem::mesh::bounding_box(&self.nodes)
    }

    /// The largest speed at a node in the rectangle `[lo, hi]`, at least 1e-12 (the top of a
    /// colour bar; a flow at rest gets `0..1e-12`).
    pub fn max_speed_in(&self, lo: [f64; 2], hi: [f64; 2]) -> f64 {
        let inside = |p: &[f64; 2]| (0..2).all(|d| p[d] >= lo[d] && p[d] <= hi[d]);
        (0..self.nodes.len()).filter(|&n| inside(&self.nodes[n])).map(|n| self.speed[n]).filter(|s| s.is_finite()).fold(1e-12, f64::max)
    }
}

/// The point array `velocity` of a fluid grid as `fdfsi run` writes it (3 components a point).
fn velocity_of(grid: &UnstructuredGrid) -> Result<&[f64], PictureError> {
    let velocity = grid.point_array("velocity").ok_or_else(|| PictureError::Input("the grid has no point data 'velocity'".into()))?;
    if velocity.components != 3 || velocity.values.len() != 3 * grid.num_points() {
        return Err(PictureError::Input(format!("'velocity' has {} components for {} points", velocity.components, grid.num_points())));
    }
    Ok(&velocity.values)
}

/// The points where a slice is sampled ([`SpeedField::of_slice`]): `(2 m + 1) x (2 n + 1)` points
/// of the rectangle `[lo, hi]` of the plane for `cells = [m, n]`, each `2 x 2` block of them
/// two 6-node triangles.
struct SliceSamples {
    nodes: Vec<[f64; 2]>,
    points: Vec<[f64; 3]>,
    triangles: Vec<[usize; 6]>,
}

impl SliceSamples {
    fn new(slice: &Slice, [lo, hi]: [[f64; 2]; 2], [m, n]: [usize; 2]) -> Result<Self, PictureError> {
        if m == 0 || n == 0 {
            return Err(PictureError::Input(format!("a slice needs at least one cell across and up, got {m} x {n}")));
        }
        let (nu, nv) = (2 * m + 1, 2 * n + 1);
        let node = |i: usize, j: usize| j * nu + i;
        let nodes: Vec<[f64; 2]> = (0..nv)
            .flat_map(|j| {
                (0..nu).map(move |i| [lo[0] + (hi[0] - lo[0]) * i as f64 / (nu - 1) as f64, lo[1] + (hi[1] - lo[1]) * j as f64 / (nv - 1) as f64])
            })
            .collect();
        let points = nodes.iter().map(|&q| slice.point(q)).collect();
        let mut triangles = Vec::with_capacity(2 * m * n);
        for j in (0..nv - 1).step_by(2) {
            for i in (0..nu - 1).step_by(2) {
                let q = |a: usize, b: usize| node(i + a, j + b);
                triangles.push([q(0, 0), q(2, 0), q(2, 2), q(1, 0), q(2, 1), q(1, 1)]);
                triangles.push([q(0, 0), q(2, 2), q(0, 2), q(1, 1), q(1, 2), q(0, 1)]);
            }
        }
        Ok(SliceSamples { nodes, points, triangles })
    }

    fn with_speed(self, speed: Vec<f64>) -> SpeedField {
        SpeedField { nodes: self.nodes, triangles: self.triangles, speed }
    }
}

/// The names of the coordinate axes.
const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];

/// A point of 2 or 3 coordinates as 3 (the missing one 0).
pub fn lift<const D: usize>(p: &[f64; D]) -> [f64; 3] {
    std::array::from_fn(|d| if d < D { p[d] } else { 0.0 })
}

/// A plane through a 3D model, normal to the coordinate axis `normal` at `normal`'s coordinate
/// `at`, drawn with the axis `axes[0]` across and `axes[1]` up (a projection: seen from the
/// side of the normal that makes `axes` right-handed or from the other, as the axes fall).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slice {
    pub normal: usize,
    pub at: f64,
    pub axes: [usize; 2],
}

impl Slice {
    /// The plane normal to the axis `normal` at `at` through a model whose box is `[lo, hi]`, the
    /// longer of its other two sides across.
    pub fn new(normal: usize, at: f64, lo: [f64; 3], hi: [f64; 3]) -> Self {
        assert!(normal < 3, "a plane normal to axis {normal}: there are 3");
        let [a, b] = match normal {
            0 => [1, 2],
            1 => [0, 2],
            _ => [0, 1],
        };
        let axes = if hi[b] - lo[b] > hi[a] - lo[a] { [b, a] } else { [a, b] };
        Slice { normal, at, axes }
    }

    /// The plane of a 3D run's `speed.png` through a model whose fluid mesh has the box `fluid`:
    /// normal to `normal` (default [`Self::thinnest_axis`] of `fluid`) at `at` (default the middle
    /// of the box `centre` along the normal: the solid's, or the fluid mesh's own).
    pub fn through(normal: Option<usize>, at: Option<f64>, fluid: ([f64; 3], [f64; 3]), centre: ([f64; 3], [f64; 3])) -> Self {
        let normal = normal.unwrap_or_else(|| Self::thinnest_axis(fluid.0, fluid.1));
        let at = at.unwrap_or(0.5 * (centre.0[normal] + centre.1[normal]));
        Self::new(normal, at, fluid.0, fluid.1)
    }

    /// `the plane y = 0.5000`.
    pub fn describe(&self) -> String {
        format!("the plane {} = {:.4}", AXIS_NAMES[self.normal], self.at)
    }

    /// The axis along which the box `[lo, hi]` is thinnest (of equal ones the last).
    pub fn thinnest_axis(lo: [f64; 3], hi: [f64; 3]) -> usize {
        (0..3).fold(0, |best, d| if hi[d] - lo[d] <= hi[best] - lo[best] { d } else { best })
    }

    /// The names of the axes across and up.
    pub fn axis_labels(&self) -> [String; 2] {
        self.axes.map(|d| AXIS_NAMES[d].to_string())
    }

    /// The point of the plane at the plane coordinates `q`.
    pub fn point(&self, q: [f64; 2]) -> [f64; 3] {
        let mut p = [0.0; 3];
        p[self.normal] = self.at;
        p[self.axes[0]] = q[0];
        p[self.axes[1]] = q[1];
        p
    }

    /// The plane coordinates of the point `p` (projected onto the plane).
    pub fn project(&self, p: &[f64]) -> [f64; 2] {
        [p[self.axes[0]], p[self.axes[1]]]
    }

    /// The rectangle of the plane covered by the projection of the box `[lo, hi]`.
    pub fn project_box(&self, lo: [f64; 3], hi: [f64; 3]) -> [[f64; 2]; 2] {
        [self.project(&lo), self.project(&hi)]
    }

    /// Where the plane cuts a convex cell (or a triangle) with the corners `vertices` and the
    /// `edges` between them: the points, in plane coordinates, where it crosses an edge or meets
    /// a corner, ordered around their centre. Empty when the plane misses the cell; two points
    /// for a triangle it crosses, a polygon for a cell.
    pub fn cut(&self, vertices: &[[f64; 3]], edges: &[[usize; 2]]) -> Vec<[f64; 2]> {
        let side = |p: &[f64; 3]| p[self.normal] - self.at;
        let mut points: Vec<[f64; 2]> = vertices.iter().filter(|p| side(p) == 0.0).map(|p| self.project(p)).collect();
        for &[a, b] in edges {
            let (pa, pb) = (&vertices[a], &vertices[b]);
            let (sa, sb) = (side(pa), side(pb));
            if sa * sb < 0.0 {
                let t = sa / (sa - sb);
                points.push(self.project(&std::array::from_fn::<f64, 3, _>(|d| pa[d] + t * (pb[d] - pa[d]))));
            }
        }
        let n = points.len().max(1) as f64;
        let c = [points.iter().map(|p| p[0]).sum::<f64>() / n, points.iter().map(|p| p[1]).sum::<f64>() / n];
        let angle = |p: &[f64; 2]| (p[1] - c[1]).atan2(p[0] - c[0]);
        points.sort_by(|p, q| angle(p).total_cmp(&angle(q)));
        points.dedup_by(|p, q| (p[0] - q[0]).abs() + (p[1] - q[1]).abs() <= 1e-12 * (1.0 + c[0].abs() + c[1].abs()));
        points
    }
}

/// The nodes around a 9-node quadrilateral's boundary in order (VTK's order: corners 0-3, then
/// the nodes on edges 01, 12, 23, 30), the outline a solid cell is drawn with.
pub const QUAD9_OUTLINE: [usize; 8] = [0, 4, 1, 5, 2, 6, 3, 7];

/// The window of a picture of a solid whose box is `[lo, hi]`: the box widened by twice its size
/// on each side.
pub fn window_around(lo: [f64; 2], hi: [f64; 2]) -> [[f64; 2]; 2] {
    let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    [[lo[0] - 2.0 * size, lo[1] - 2.0 * size], [hi[0] + 2.0 * size, hi[1] + 2.0 * size]]
}

/// The least height of the plot area of a speed picture (pixels).
pub const MIN_PLOT_HEIGHT: u32 = 160;
/// Width of the colour bar's area at the right of a speed picture (pixels).
const COLOUR_BAR_AREA: u32 = 170;
/// Colour of the solid in a speed picture.
pub const SOLID_COLOUR: RGBColor = RGBColor(190, 190, 190);
/// Margin, x-label area, y-label area and caption height of a speed picture (pixels).
const MARGIN: u32 = 12;
const X_LABELS: u32 = 48;
const Y_LABELS: u32 = 72;
const CAPTION: u32 = 40;

/// Where a speed picture's plot goes: the rectangle shown (`lo`, `hi`), the plot area's height
/// and the picture's.
#[derive(Clone, Copy, Debug)]
struct Layout {
    lo: [f64; 2],
    hi: [f64; 2],
    plot_w: u32,
    plot_h: u32,
    height: u32,
}

impl Layout {
    /// The layout of a picture `width` pixels wide of `window` (clipped to the mesh's `bounds`;
    /// default the whole mesh), at the model's aspect ratio, widened across to
    /// [`MIN_PLOT_HEIGHT`].
    fn new((lo, hi): ([f64; 2], [f64; 2]), window: Option<[[f64; 2]; 2]>, width: u32) -> Result<Self, PictureError> {
        let (mut lo, mut hi) = (lo, hi);
        if let Some([a, b]) = window {
            (lo, hi) = ([a[0].max(lo[0]), a[1].max(lo[1])], [b[0].min(hi[0]), b[1].min(hi[1])]);
            if !(hi[0] > lo[0] && hi[1] > lo[1]) {
                return Err(PictureError::Input(format!("the picture window {window:?} does not overlap the mesh")));
            }
        }
        let least = COLOUR_BAR_AREA + Y_LABELS + 2 * MARGIN + 100;
        if width < least {
            return Err(PictureError::Input(format!("a speed picture {width} pixels wide is too narrow: at least {least}")));
        }
        if !(lo.iter().chain(&hi).all(|v| v.is_finite()) && hi[0] > lo[0] && hi[1] > lo[1]) {
            return Err(PictureError::Input(format!("nothing to draw: the mesh spans {lo:?} to {hi:?}")));
        }
        let plot_w = width - (COLOUR_BAR_AREA + Y_LABELS + 2 * MARGIN);
        let mut plot_h = (plot_w as f64 * (hi[1] - lo[1]) / (hi[0] - lo[0])).round();
        if plot_h < MIN_PLOT_HEIGHT as f64 {
            let half = 0.5 * (hi[0] - lo[0]) * MIN_PLOT_HEIGHT as f64 / plot_w as f64;
            let mid = 0.5 * (lo[1] + hi[1]);
            (lo[1], hi[1], plot_h) = (mid - half, mid + half, MIN_PLOT_HEIGHT as f64);
        }
        let plot_h = plot_h.min(4.0 * plot_w as f64) as u32;
        Ok(Layout { lo, hi, plot_w, plot_h, height: plot_h + X_LABELS + CAPTION + 2 * MARGIN })
    }

    /// The cells a slice is sampled with ([`SpeedField::of_slice`]): one per 4 pixels.
    fn slice_cells(&self) -> [usize; 2] {
        [(self.plot_w / 4).max(1) as usize, (self.plot_h / 4).max(1) as usize]
    }
}

/// A frame of a 3D run's animation: the speed of the fluid `grid` (see
/// [`SpeedField::of_grid_slice`]) on `slice` where a picture `width` pixels wide shows it, the
/// `window` of the plane (default: all of it) within `bounds`, the rectangle of the plane the
/// fluid's box projects to, sampled as [`write_slice_png`] samples.
pub fn grid_slice_field(
    grid: &UnstructuredGrid,
    slice: &Slice,
    bounds: [[f64; 2]; 2],
    window: Option<[[f64; 2]; 2]>,
    width: u32,
) -> Result<SpeedField, PictureError> {
    let layout = Layout::new((bounds[0], bounds[1]), window, width)?;
    SpeedField::of_grid_slice(grid, slice, [layout.lo, layout.hi], layout.slice_cells())
}

/// Writes the speed `|u|` of a 2D flow solution `x` as a PNG `width` pixels wide: the flow in
/// the window of `picture`, in model coordinates with labelled axes at the same scale, each
/// quadratic triangle drawn as its four linear sub-triangles coloured by their mean nodal speed
/// (viridis, from 0 to the largest speed in the window), the solid and gamma_f over it, and a
/// colour bar with its range at the right. 2D only: a 3D discretisation is an error.
pub fn write_speed_png<const D: usize>(
    disc: &FlowDiscretization<D>,
    x: &[f64],
    path: &Path,
    width: u32,
    picture: &SpeedPicture,
) -> Result<(), PictureError> {
    let field = SpeedField::of_flow(disc, x)?;
    let layout = Layout::new(field.bounds(), picture.window, width)?;
    write_field_png(&field, &layout, path, width, picture)
}

/// Writes the speed `|u|` of a 3D flow solution `x` on the plane `slice` as [`write_speed_png`]
/// draws a 2D flow: in the window of `picture` (default: the fluid mesh's box projected onto
/// the plane), the speed sampled at about one point per 2 pixels ([`SpeedField::of_slice`]);
/// `picture` holds what the run cuts from the solid and gamma_f ([`Slice::cut`]).
pub fn write_slice_png<const D: usize>(
    disc: &FlowDiscretization<D>,
    x: &[f64],
    slice: &Slice,
    path: &Path,
    width: u32,
    picture: &SpeedPicture,
) -> Result<(), PictureError> {
    if D != 3 {
        return Err(PictureError::Input(format!("slices are drawn of 3D flows, not {D}D")));
    }
    let (lo, hi) = fdfsi_fem::mesh::bounding_box(&disc.mesh.points);
    let [a, b] = slice.project_box(lift(&lo), lift(&hi));
    let layout = Layout::new((a, b), picture.window, width)?;
    let field = SpeedField::of_slice(disc, x, slice, [layout.lo, layout.hi], layout.slice_cells())?;
    if !field.speed.iter().any(|s| s.is_finite()) {
        return Err(PictureError::Input(format!("{} misses the fluid mesh (or the flow is not finite there)", slice.describe())));
    }
    write_field_png(&field, &layout, path, width, picture)
}

/// Writes `field` drawn with `layout` (see [`write_speed_png`]).
fn write_field_png(field: &SpeedField, layout: &Layout, path: &Path, width: u32, picture: &SpeedPicture) -> Result<(), PictureError> {
    let smax = field.max_speed_in(layout.lo, layout.hi);
    // Drawn under a temporary name and renamed, so a crash never leaves a half-written picture.
    let tmp = path.with_extension("tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (width, layout.height)).into_drawing_area();
        draw_speed(&root, field, picture, layout, smax)?;
        root.present().map_err(draw_failed)?;
    }
    Ok(std::fs::rename(&tmp, path)?)
}

/// One frame of an animation ([`write_speed_gif`]).
#[derive(Clone, Debug, Default)]
pub struct Frame {
    pub field: SpeedField,
    pub picture: SpeedPicture,
}

/// Writes `frames` as an animated GIF `width` pixels wide, `delay_ms` per frame, looping: each
/// frame drawn as [`write_speed_png`] draws it, all in the window of the first frame (default
/// the first frame's mesh) and on one colour scale, from 0 to the largest speed in that window
/// over all frames.
pub fn write_speed_gif(frames: &[Frame], path: &Path, width: u32, delay_ms: u32) -> Result<(), PictureError> {
    let first = frames.first().ok_or_else(|| PictureError::Input("no frames to animate".into()))?;
    let layout = Layout::new(first.field.bounds(), first.picture.window, width)?;
    let smax = frames.iter().map(|f| f.field.max_speed_in(layout.lo, layout.hi)).fold(f64::MIN_POSITIVE, f64::max);
    let tmp = path.with_extension("tmp.gif");
    {
        let root = BitMapBackend::gif(&tmp, (width, layout.height), delay_ms).map_err(draw_failed)?.into_drawing_area();
        for frame in frames {
            draw_speed(&root, &frame.field, &frame.picture, &layout, smax)?;
            root.present().map_err(draw_failed)?;
        }
    }
    Ok(std::fs::rename(&tmp, path)?)
}

/// Draws a speed picture (see [`write_speed_png`]) onto `root`, colours scaled to `smax`.
fn draw_speed<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    field: &SpeedField,
    picture: &SpeedPicture,
    layout: &Layout,
    smax: f64,
) -> Result<(), PictureError> {
    super::plot::register_font();
    let font = super::plot::FAMILY;
    let (lo, hi) = (layout.lo, layout.hi);
    root.fill(&WHITE).map_err(draw_failed)?;
    let (width, _) = root.dim_in_pixel();
    let (main, bar) = root.split_horizontally(width - COLOUR_BAR_AREA);
    let mut chart = ChartBuilder::on(&main)
        .caption(&picture.title, (font, 20))
        .margin(MARGIN)
        .x_label_area_size(X_LABELS)
        .y_label_area_size(Y_LABELS)
        .build_cartesian_2d(lo[0]..hi[0], lo[1]..hi[1])
        .map_err(draw_failed)?;
    let [across, up] = picture.axis_labels.clone().unwrap_or_else(|| ["x".into(), "y".into()]);
    draw_axes(&mut chart, &across, &up)?;
    // A cell is drawn when its box overlaps the view (plotters clips it to the plot area).
    let overlaps = |p: &[[f64; 2]]| (0..2).all(|d| p.iter().any(|q| q[d] >= lo[d]) && p.iter().any(|q| q[d] <= hi[d]));
    // Sub-triangles of a 6-node triangle (vertices 0-2, mid-edge nodes 3: 01, 4: 12, 5: 20).
    const SUB: [[usize; 3]; 4] = [[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]];
    let xy = |p: [f64; 2]| (p[0], p[1]);
    let plot = chart.plotting_area();
    for cn in &field.triangles {
        if !overlaps(&[field.nodes[cn[0]], field.nodes[cn[1]], field.nodes[cn[2]]]) {
            continue;
        }
        for t in SUB {
            let s = t.iter().map(|&k| field.speed[cn[k]]).sum::<f64>() / 3.0 / smax;
            if !s.is_finite() {
                continue; // a slice's point outside the fluid, or a value not finite: left blank
            }
            let mut pts: Vec<(f64, f64)> = t.iter().map(|&k| xy(field.nodes[cn[k]])).collect();
            plot.draw(&Polygon::new(pts.clone(), viridis(s).filled())).map_err(draw_failed)?;
            // The outline too: the fill alone leaves pixel gaps along some edges.
            pts.push(pts[0]);
            plot.draw(&PathElement::new(pts, viridis(s).stroke_width(1))).map_err(draw_failed)?;
        }
    }
    for polygon in &picture.solid {
        plot.draw(&Polygon::new(polygon.iter().map(|&p| xy(p)).collect::<Vec<_>>(), SOLID_COLOUR.filled())).map_err(draw_failed)?;
    }
    for line in &picture.outlines {
        plot.draw(&PathElement::new(line.iter().map(|&p| xy(p)).collect::<Vec<_>>(), WHITE.stroke_width(3))).map_err(draw_failed)?;
    }
    draw_colour_bar(&bar, smax, layout.plot_h, MARGIN + CAPTION, "speed |u|")
}

/// The viridis colour bar from 0 to `max`, `plot_h` pixels high and `top` pixels from the top
/// of `area`, with its ticks and `label`.
fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    max: f64,
    plot_h: u32,
    top: u32,
    label: &str,
) -> Result<(), PictureError> {
    let font = super::plot::FAMILY;
    let (_, h) = area.dim_in_pixel();
    let bottom = h.saturating_sub(top + plot_h);
    let area = area.margin(top, bottom, 16, 0);
    let mut chart = ChartBuilder::on(&area).y_label_area_size(90).build_cartesian_2d(0.0..1.0, 0.0..max).map_err(draw_failed)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc(label)
        .y_labels(6)
        .y_label_formatter(&|v| colour_bar_tick(*v, max))
        .label_style((font, 14))
        .axis_desc_style((font, 16))
        .draw()
        .map_err(draw_failed)?;
    const SLICES: usize = 100;
    chart
        .draw_series((0..SLICES).map(|i| {
            let (a, b) = (i as f64 / SLICES as f64, (i + 1) as f64 / SLICES as f64);
            Rectangle::new([(0.0, a * max), (0.35, b * max)], viridis(0.5 * (a + b)).filled())
        }))
        .map_err(draw_failed)?;
    Ok(())
}

/// The label of the tick `v` of a colour bar from 0 to `max`: two significant digits of `max`
/// in fixed notation, or scientific notation below 1e-3 and from 1e5 on.
fn colour_bar_tick(v: f64, max: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !(1e-3..1e5).contains(&max) {
        return format!("{v:.1e}");
    }
    let decimals = (1.0 - max.log10().floor()).clamp(0.0, 4.0) as usize;
    format!("{v:.decimals$}")
}

/// Colour of gamma_s (the solid's surface pieces) in [`write_surfaces_png`].
pub const GAMMA_S_COLOUR: RGBColor = RGBColor(31, 119, 180);
/// Colour of gamma_f (the adapted fluid mesh's facets) in [`write_surfaces_png`].
pub const GAMMA_F_COLOUR: RGBColor = RGBColor(214, 39, 40);

/// Writes the edges of two triangulated surfaces of a 3D run, gamma_s (blue) and gamma_f (red),
/// as a PNG of two panels `size` pixels square under the caption `title`, each with labelled axes
/// in model coordinates: left, seen along the z axis (the x-y plane at one scale, the two
/// non-conforming triangulations over each other); right, seen from the side, with
/// `r = sqrt(x^2 + y^2)` across and z up, z stretched to fill the panel (the shape of the bulge).
pub fn write_surfaces_png(path: &Path, title: &str, gamma_s: &[[[f64; 3]; 3]], gamma_f: &[[[f64; 3]; 3]], size: u32) -> Result<(), PictureError> {
    let all = || gamma_s.iter().chain(gamma_f).flatten();
    if all().next().is_none() || all().flatten().any(|v| !v.is_finite()) {
        return Err(PictureError::Input("no surface to draw, or a point that is not finite".into()));
    }
    if size < 200 {
        return Err(PictureError::Input(format!("a surface picture {size} pixels square is too small: at least 200")));
    }
    let fold = |f: &dyn Fn(&[f64; 3]) -> f64| all().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(f(p)), hi.max(f(p))));
    let r = |p: &[f64; 3]| p[0].hypot(p[1]);
    let (x, y, rr, z) = (fold(&|p| p[0]), fold(&|p| p[1]), fold(&r), fold(&|p| p[2]));
    let pad = |(lo, hi): (f64, f64)| {
        let m = 0.05 * (hi - lo).max(1e-9 * (1.0 + hi.abs()));
        (lo - m, hi + m)
    };
    // The left panel at one scale: its plot area is about square.
    let span = (x.1 - x.0).max(y.1 - y.0);
    let (x, y) = (pad((x.0, x.0 + span)), pad((y.0, y.0 + span)));
    let (rr, z) = (pad((rr.0.min(0.0), rr.1)), pad(z));
    super::plot::register_font();
    let font = super::plot::FAMILY;
    let tmp = path.with_extension("tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (2 * size, size + CAPTION)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_failed)?;
        let root = root.titled(title, (font, 20)).map_err(draw_failed)?;
        let (left, right) = root.split_horizontally(size);
        let panels =
            [(&left, "seen along z", x, y, ["x", "y"], 0usize), (&right, "seen from the side (z stretched)", rr, z, ["r = |(x, y)|", "z"], 1)];
        for (area, caption, across, up, [xd, yd], view) in panels {
            let mut chart = ChartBuilder::on(area)
                .caption(caption, (font, 16))
                .margin(MARGIN)
                .x_label_area_size(X_LABELS)
                .y_label_area_size(Y_LABELS)
                .build_cartesian_2d(across.0..across.1, up.0..up.1)
                .map_err(draw_failed)?;
            draw_axes(&mut chart, xd, yd)?;
            let at = |p: &[f64; 3]| if view == 0 { (p[0], p[1]) } else { (r(p), p[2]) };
            for (tris, colour, name) in [(gamma_s, GAMMA_S_COLOUR, "gamma_s (solid surface)"), (gamma_f, GAMMA_F_COLOUR, "gamma_f (fluid facets)")] {
                chart
                    .draw_series(tris.iter().map(|t| PathElement::new([0, 1, 2, 0].map(|k| at(&t[k])).to_vec(), colour.stroke_width(1))))
                    .map_err(draw_failed)?
                    .label(name)
                    .legend(move |(px, py)| PathElement::new(vec![(px, py), (px + 20, py)], colour.stroke_width(2)));
            }
            if view == 1 {
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperRight)
                    .label_font((font, 14))
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .draw()
                    .map_err(draw_failed)?;
            }
        }
        root.present().map_err(draw_failed)?;
    }
    Ok(std::fs::rename(&tmp, path)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::fluid::Formulation;
    use fdfsi_fem::element::ReferenceCell;
    use fdfsi_fem::generate::box_tetrahedra;

    #[test]
    fn a_slice_cuts_cells_and_triangles_where_the_plane_crosses_them() {
        let plane = Slice::new(2, 0.5, [0.0; 3], [1.0, 1.0, 4.0]);
        assert_eq!(plane.axes, [0, 1]);
        // The unit cube: the square of its four side edges' midpoints, in order around it.
        let cube: Vec<[f64; 3]> = ReferenceCell::Hexahedron.vertices().to_vec();
        let square = plane.cut(&cube, ReferenceCell::Hexahedron.edges());
        assert_eq!(square.len(), 4);
        for (p, q) in square.iter().zip(square.iter().cycle().skip(1)) {
            assert!(((p[0] - q[0]).abs() + (p[1] - q[1]).abs() - 1.0).abs() < 1e-15, "{square:?}: a side from {p:?} to {q:?}");
        }
        // The unit tetrahedron: the triangle (0, 0), (0.5, 0), (0, 0.5).
        let tet: Vec<[f64; 3]> = ReferenceCell::Tetrahedron.vertices().to_vec();
        let mut tri = plane.cut(&tet, ReferenceCell::Tetrahedron.edges());
        tri.sort_by(|p, q| (p[0] + 2.0 * p[1]).total_cmp(&(q[0] + 2.0 * q[1])));
        assert_eq!(tri, [[0.0, 0.0], [0.5, 0.0], [0.0, 0.5]]);
        // A triangle: the segment where the plane crosses it; a corner on the plane counts once.
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
        assert_eq!(plane.cut(&t, ReferenceCell::Triangle.edges()).len(), 2);
        let touching = [[0.0, 0.0, 0.5], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]];
        assert_eq!(plane.cut(&touching, ReferenceCell::Triangle.edges()), [[0.0, 0.0]]);
        // Missed.
        let away = Slice::new(2, 2.0, [0.0; 3], [1.0, 1.0, 4.0]);
        assert!(away.cut(&cube, ReferenceCell::Hexahedron.edges()).is_empty());
    }

    #[test]
    fn colour_bar_ticks_show_two_significant_digits_of_the_range() {
        assert_eq!([colour_bar_tick(0.2, 0.41), colour_bar_tick(1.5, 2.1), colour_bar_tick(100.0, 450.0)], ["0.20", "1.5", "100"]);
        assert_eq!([colour_bar_tick(0.01, 0.04), colour_bar_tick(2e-4, 4e-4), colour_bar_tick(0.0, 4e-4)], ["0.010", "2.0e-4", "0"]);
    }

    #[test]
    fn a_slice_is_normal_to_the_thinnest_axis_with_the_longer_side_across() {
        let (lo, hi) = ([0.0; 3], [1.0, 1.0, 4.0]);
        let normal = Slice::thinnest_axis(lo, hi);
        assert_eq!(normal, 1, "x and y are equal: the last");
        let plane = Slice::new(normal, 0.25, lo, hi);
        assert_eq!((plane.axes, plane.axis_labels()), ([2, 0], ["z".to_string(), "x".to_string()]));
        assert_eq!(plane.point([3.0, 0.5]), [0.5, 0.25, 3.0]);
        assert_eq!(plane.project(&[0.5, 0.25, 3.0]), [3.0, 0.5]);
        assert_eq!(Slice::thinnest_axis(lo, [1.0, 2.0, 0.5]), 2);
    }

    /// P2+ reproduces quadratics: the sampled speed of an interpolated quadratic flow is exact
    /// inside the mesh and NaN outside it.
    #[test]
    fn the_speed_on_a_slice_is_the_flows_at_each_sample_and_nan_outside() {
        let disc = FlowDiscretization::build(box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 2.0, 2, 2, 4), Formulation::ThreeD).unwrap();
        let u = |p: &[f64; 3]| [p[1] * p[2], 0.5 - p[0] * p[0], 1.0 + p[0] * p[1] - p[2] * p[2]];
        let vf = disc.velocity_field();
        let mut x = vec![0.0; disc.num_dofs()];
        for (n, p) in disc.velocity_nodes.iter().enumerate() {
            for (k, v) in u(p).into_iter().enumerate() {
                x[vf.dof(n, k)] = v;
            }
        }
        let plane = Slice::new(1, 0.3, [0.0; 3], [1.0, 1.0, 2.0]);
        assert_eq!(plane.axes, [2, 0]);
        let field = SpeedField::of_slice(&disc, &x, &plane, [[-0.5, -0.25], [2.5, 1.25]], [12, 6]).unwrap();
        assert_eq!((field.nodes.len(), field.triangles.len()), (25 * 13, 2 * 12 * 6));
        let (mut inside, mut outside) = (0, 0);
        for (q, s) in field.nodes.iter().zip(&field.speed) {
            let p = plane.point(*q);
            if (0.0..=2.0).contains(&p[2]) && (0.0..=1.0).contains(&p[0]) {
                let exact = u(&p).iter().map(|c| c * c).sum::<f64>().sqrt();
                assert!((s - exact).abs() < 1e-12, "at {p:?}: {s} against {exact}");
                inside += 1;
            } else {
                assert!(s.is_nan(), "at {p:?}, outside the mesh: {s}");
                outside += 1;
            }
        }
        assert!(inside > 100 && outside > 100, "{inside} samples inside, {outside} outside");
        // The same from the grid a run writes (10-node tetrahedra, P2 without the bubble: exact
        // for this quadratic flow too), as the frames of a 3D animation are drawn.
        let grid = crate::io::fields::fluid_grid(&disc, &x).unwrap();
        let from_grid = SpeedField::of_grid_slice(&grid, &plane, [[-0.5, -0.25], [2.5, 1.25]], [12, 6]).unwrap();
        assert_eq!((&from_grid.nodes, &from_grid.triangles), (&field.nodes, &field.triangles));
        for ((q, s), t) in field.nodes.iter().zip(&field.speed).zip(&from_grid.speed) {
            assert!((s.is_nan() && t.is_nan()) || (s - t).abs() < 1e-12, "at {q:?}: {t} from the grid against {s}");
        }
        // Each triangle: vertices at three corners of its 2 x 2 block, mid-edge nodes between them.
        for t in &field.triangles {
            for (m, [a, b]) in [(3, [0, 1]), (4, [1, 2]), (5, [2, 0])] {
                let (pa, pb, pm) = (field.nodes[t[a]], field.nodes[t[b]], field.nodes[t[m]]);
                assert!((0..2).all(|d| (0.5 * (pa[d] + pb[d]) - pm[d]).abs() < 1e-12), "triangle {t:?}");
            }
        }
        // The picture; a plane that misses the mesh has nothing to draw.
        let dir = std::env::temp_dir().join(format!("fdfsi-slice-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let png = dir.join("speed.png");
        write_slice_png(&disc, &x, &plane, &png, 800, &SpeedPicture::default()).unwrap();
        assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
        let away = Slice::new(1, 3.0, [0.0; 3], [1.0, 1.0, 2.0]);
        let err = write_slice_png(&disc, &x, &away, &dir.join("away.png"), 800, &SpeedPicture::default()).unwrap_err();
        assert!(err.to_string().contains("the plane y = 3.0000 misses the fluid mesh"), "{err}");
        // The coupling surfaces: drawn, and refused too small.
        let t = [[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.1]]];
        write_surfaces_png(&dir.join("gamma.png"), "t = 0", &t, &t, 300).unwrap();
        assert!(dir.join("gamma.png").exists());
        assert!(matches!(write_surfaces_png(&dir.join("small.png"), "", &t, &t, 100), Err(PictureError::Input(_))));
        std::fs::remove_dir_all(&dir).ok();
        // A 2D flow has no slice.
        let square = fdfsi_fem::generate::rectangle_triangles(0.0, 1.0, 0.0, 1.0, 1, 1, fdfsi_fem::generate::DiagonalPattern::Right);
        let flat = FlowDiscretization::build(square, Formulation::Plane).unwrap();
        assert!(SpeedField::of_slice(&flat, &vec![0.0; flat.num_dofs()], &plane, [[0.0; 2], [1.0; 2]], [1, 1]).is_err());
    }
}
