//! Structured mesh generators: rectangles, a graded channel, boxes, a circular pipe and a
//! quarter-disc membrane.
//!
//! Every generator returns a [`Mesh`] whose cells are positively oriented (`det J > 0`, so
//! [`Mesh::check`] passes), whose cells all carry the region [`DOMAIN_REGION`] (tag
//! [`DOMAIN_TAG`]), and whose every exterior facet is tagged exactly once with one of the
//! generator's boundary names. Boundary tags are numbered `1, 2, ...` in the order the names are
//! listed in each generator's documentation.
//!
//! A facet carries a single tag, so facets are never tagged twice: a corner (2D) or an edge (3D)
//! where two sides meet belongs to no facet of both. In particular the channel's walls are the
//! two separate boundaries `"bottom"` and `"top"` (there is no combined `"walls"` tag); apply a
//! wall condition to both names.
//!
//! Boundary facets are found by classifying every local facet of every cell by its vertices
//! (e.g. "all vertices have grid index `i = 0`"), never by floating-point comparisons, so the
//! classification is exact. A facet whose vertices all lie in one boundary plane (or, for the
//! pipe, on one boundary ring) is necessarily exterior, which is what makes this safe.
//!
//! Node numbering: grid nodes are numbered with `x` fastest, then `y`, then `z`.

use crate::element::ReferenceCell;
use crate::mesh::{geometry_element, geometry_nodes, BoundaryFacet, GeometryOrder, Mesh};

/// Name of the single region of every generated mesh.
pub const DOMAIN_REGION: &str = "domain";
/// Region tag of every generated cell.
pub const DOMAIN_TAG: u32 = 1;

/// Boundary names of the rectangle generators, tags 1..=4.
pub const RECTANGLE_BOUNDARIES: [&str; 4] = ["left", "right", "bottom", "top"];
/// Boundary names of [`channel_triangles`], tags 1..=4.
pub const CHANNEL_BOUNDARIES: [&str; 4] = ["inlet", "outlet", "bottom", "top"];
/// Boundary names of the box generators, tags 1..=6.
pub const BOX_BOUNDARIES: [&str; 6] = ["xmin", "xmax", "ymin", "ymax", "zmin", "zmax"];
/// Boundary names of [`pipe_tetrahedra`], tags 1..=5 (the last two for quarter pipes only).
pub const PIPE_BOUNDARIES: [&str; 5] = ["inlet", "outlet", "wall", "symmetry_x", "symmetry_y"];

/// How each grid square of a rectangle is cut into triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DiagonalPattern {
    /// One diagonal from the lower-left to the upper-right corner (`/`): 2 triangles per square.
    Right,
    /// One diagonal from the lower-right to the upper-left corner (`\`): 2 triangles per square.
    Left,
    /// `/` where `i + j` is even and `\` where it is odd (the "union jack" pattern).
    Alternating,
    /// Both diagonals, with a new vertex at the square's centre: 4 triangles per square.
    Crossed,
}

/// Triangle mesh of the rectangle `[x0, x1] x [y0, y1]` with `nx x ny` grid squares.
///
/// Boundaries (tags 1..=4): `"left"` (x = x0), `"right"` (x = x1), `"bottom"` (y = y0),
/// `"top"` (y = y1). Region `"domain"`.
///
/// # Panics
/// If an interval is empty or not finite, or `nx` or `ny` is 0.
pub fn rectangle_triangles(x0: f64, x1: f64, y0: f64, y1: f64, nx: usize, ny: usize, pattern: DiagonalPattern) -> Mesh<2> {
    check_interval("x", x0, x1);
    check_interval("y", y0, y1);
    check_count("nx", nx);
    check_count("ny", ny);
    grid_triangles(&uniform_axis(x0, x1, nx), &uniform_axis(y0, y1, ny), pattern, &RECTANGLE_BOUNDARIES)
}

/// Quadrilateral mesh of the rectangle `[x0, x1] x [y0, y1]` with `nx x ny` cells: 4-node (Q1)
/// cells for [`GeometryOrder::Linear`], 9-node (Q2, VTK order) cells for
/// [`GeometryOrder::Quadratic`]. Quadratic nodes lie on a `(2 nx + 1) x (2 ny + 1)` grid and are
/// shared between neighbouring cells.
///
/// Boundaries (tags 1..=4): `"left"`, `"right"`, `"bottom"`, `"top"`. Region `"domain"`.
///
/// # Panics
/// If an interval is empty or not finite, or `nx` or `ny` is 0.
pub fn rectangle_quads(x0: f64, x1: f64, y0: f64, y1: f64, nx: usize, ny: usize, order: GeometryOrder) -> Mesh<2> {
    check_interval("x", x0, x1);
    check_interval("y", y0, y1);
    check_count("nx", nx);
    check_count("ny", ny);
    tensor_mesh([uniform_axis(x0, x1, nx), uniform_axis(y0, y1, ny)], order, &RECTANGLE_BOUNDARIES)
}

/// Triangle mesh of the channel `[0, length] x [0, height]`, uniform in `y` (`ny` rows) and graded
/// in `x` (`nx` columns, see [`graded_spacing`]): fine in the middle of the channel (where an
/// obstacle or a valve sits) and coarse towards inlet and outlet. `grading = 1` gives a uniform
/// mesh. Squares are cut in the [`DiagonalPattern::Alternating`] pattern.
///
/// Boundaries (tags 1..=4): `"inlet"` (x = 0), `"outlet"` (x = length), `"bottom"` (y = 0),
/// `"top"` (y = height). The walls are the two tags `"bottom"` and `"top"`: a facet has one tag,
/// so there is no separate `"walls"` tag. Region `"domain"`.
///
/// # Panics
/// If `length` or `height` is not positive, `nx` or `ny` is 0, or `grading` is not positive.
pub fn channel_triangles(length: f64, height: f64, nx: usize, ny: usize, grading: f64) -> Mesh<2> {
    check_interval("x", 0.0, length);
    check_interval("y", 0.0, height);
    check_count("ny", ny);
    let xs = graded_spacing(length, nx, grading);
    grid_triangles(&xs, &uniform_axis(0.0, height, ny), DiagonalPattern::Alternating, &CHANNEL_BOUNDARIES)
}

/// Node coordinates `0 = x_0 < x_1 < ... < x_n = length` of a symmetric graded spacing: the width
/// of cell `i` (`0 <= i < n`) is
///
/// `w_i = C g^{e_i}`,  `e_i = |2 i + 1 - n| / (n - 1)`  (`e_i = 0` when `n = 1`),
///
/// with `C` such that the widths sum to `length`. The exponent grows linearly from the middle of
/// the interval (`e = 0`, or `1/(n-1)` for the two middle cells when `n` is even) to the two end
/// cells (`e = 1`): widths grow geometrically from the middle to both ends, and the end cells are
/// `g` times as wide as a (virtual) centre cell. `g > 1` is fine in the middle, `g < 1` fine at
/// the ends, `g = 1` uniform (then `x_k = length k / n` exactly as computed in floating point).
///
/// # Panics
/// If `length` is not positive, `n` is 0, or `g` is not positive and finite.
pub fn graded_spacing(length: f64, n: usize, g: f64) -> Vec<f64> {
    check_interval("x", 0.0, length);
    check_count("nx", n);
    assert!(g.is_finite() && g > 0.0, "the grading ratio must be positive and finite, got {g}");
    if g == 1.0 || n == 1 {
        return uniform_axis(0.0, length, n);
    }
    let widths: Vec<f64> = (0..n)
        .map(|i| {
            let e = (2.0 * i as f64 + 1.0 - n as f64).abs() / (n as f64 - 1.0);
            g.powf(e)
        })
        .collect();
    let total: f64 = widths.iter().sum();
    let mut xs = Vec::with_capacity(n + 1);
    let mut acc = 0.0;
    xs.push(0.0);
    for (i, w) in widths.iter().enumerate() {
        acc += w;
        xs.push(if i + 1 == n { length } else { length * acc / total });
    }
    xs
}

/// Tetrahedral mesh of the box `[x0, x1] x [y0, y1] x [z0, z1]` with `nx x ny x nz` grid cubes,
/// each split into 6 tetrahedra by the Kuhn (Freudenthal) split: for each permutation `(a, b, c)`
/// of the axes, the tetrahedron `p, p + e_a, p + e_a + e_b, p + e_a + e_b + e_c` with `p` the
/// cube's lowest corner. All cubes are split the same way (all share the diagonal from the lowest
/// to the highest corner, and each face the diagonal through its lowest corner), so the mesh is
/// conforming. Odd permutations give negatively oriented vertex orders, which are fixed by
/// swapping vertices 1 and 2.
///
/// Boundaries (tags 1..=6): `"xmin"`, `"xmax"`, `"ymin"`, `"ymax"`, `"zmin"`, `"zmax"`.
/// Region `"domain"`.
///
/// # Panics
/// If an interval is empty or not finite, or a count is 0.
#[allow(clippy::too_many_arguments)]
pub fn box_tetrahedra(x0: f64, x1: f64, y0: f64, y1: f64, z0: f64, z1: f64, nx: usize, ny: usize, nz: usize) -> Mesh<3> {
    let axes = box_axes([(x0, x1), (y0, y1), (z0, z1)], [nx, ny, nz]);
    const PERMUTATIONS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let n = [nx, ny, nz];
    let m = [nx + 1, ny + 1, nz + 1];
    let points = grid_points(&axes, m);
    let mut cells = Vec::with_capacity(6 * 4 * nx * ny * nz);
    for c in 0..nx * ny * nz {
        let base = unravel(c, n);
        for perm in PERMUTATIONS {
            let mut corner = base;
            cells.push(ravel(corner, m));
            for &axis in &perm {
                corner[axis] += 1;
                cells.push(ravel(corner, m));
            }
        }
    }
    orient_simplices(&points, &mut cells, 4);
    finish(points, ReferenceCell::Tetrahedron, GeometryOrder::Linear, cells, &BOX_BOUNDARIES, |v| grid_side(m, v))
}

/// Hexahedral mesh of the box `[x0, x1] x [y0, y1] x [z0, z1]` with `nx x ny x nz` cells: 8-node
/// (Q1) cells for [`GeometryOrder::Linear`], 27-node (Q2, VTK order) cells for
/// [`GeometryOrder::Quadratic`], whose nodes lie on a `(2 nx + 1) x (2 ny + 1) x (2 nz + 1)` grid
/// and are shared between neighbours.
///
/// Boundaries (tags 1..=6): `"xmin"`, `"xmax"`, `"ymin"`, `"ymax"`, `"zmin"`, `"zmax"`.
/// Region `"domain"`.
///
/// # Panics
/// If an interval is empty or not finite, or a count is 0.
#[allow(clippy::too_many_arguments)]
pub fn box_hexahedra(x0: f64, x1: f64, y0: f64, y1: f64, z0: f64, z1: f64, nx: usize, ny: usize, nz: usize, order: GeometryOrder) -> Mesh<3> {
    let axes = box_axes([(x0, x1), (y0, y1), (z0, z1)], [nx, ny, nz]);
    tensor_mesh(axes, order, &BOX_BOUNDARIES)
}

/// Tetrahedral mesh of the circular pipe `x^2 + y^2 <= radius^2`, `0 <= z <= length` (or, with
/// `quarter`, of its quarter `x >= 0, y >= 0`), with straight-sided (linear) tetrahedra.
///
/// Cross-section: a centre vertex and `n_radial` concentric rings at radii `r_k = radius k /
/// n_radial`. Ring `k` has `6 k` equally spaced vertices on the full circle (a quarter circle gets
/// `max(1, round(3 k / 2))` segments, vertices at both ends), so the triangles are close to
/// equilateral. Ring 1 is joined to the centre by a fan, and rings `k - 1` and `k` by the
/// triangle strip that merges their vertices in angular order. The outer ring's vertices lie on
/// `r = radius` (up to the rounding of `cos`/`sin`; vertices on the axes are exact, so the quarter
/// pipe's symmetry planes are exactly `x = 0` and `y = 0`). The domain is the polygonal
/// approximation of the disc, whose area tends to `pi radius^2` as `n_radial` grows.
///
/// Axis: `n_axial` uniform layers. Each triangular prism (triangle `a < b < c` by vertex number,
/// primes for the upper layer) is split into the 3 tetrahedra `(a, b, c, c')`, `(a, b, b', c')`,
/// `(a, a', b', c')`: every side quad `(p, q, q', p')` with `p < q` is cut along the diagonal
/// `p q'`, which depends only on the vertex numbers, so neighbouring prisms agree and the mesh is
/// conforming. Vertex order is then fixed to positive orientation.
///
/// Boundaries: `"inlet"` (z = 0, tag 1), `"outlet"` (z = length, tag 2), `"wall"` (r = radius,
/// tag 3), and for quarter pipes `"symmetry_x"` (the plane x = 0, tag 4) and `"symmetry_y"` (the
/// plane y = 0, tag 5). Region `"domain"`.
///
/// # Panics
/// If `radius` or `length` is not positive, or a count is 0.
pub fn pipe_tetrahedra(radius: f64, length: f64, n_radial: usize, n_axial: usize, quarter: bool) -> Mesh<3> {
    check_interval("r", 0.0, radius);
    check_interval("z", 0.0, length);
    check_count("n_radial", n_radial);
    check_count("n_axial", n_axial);
    let section = disc_section(radius, n_radial, quarter);
    let n2 = section.points.len();
    let zs = uniform_axis(0.0, length, n_axial);
    let points: Vec<[f64; 3]> = zs.iter().flat_map(|&z| section.points.iter().map(move |p| [p[0], p[1], z])).collect();
    let mut cells = Vec::with_capacity(12 * section.triangles.len() * n_axial);
    for layer in 0..n_axial {
        let (lo, hi) = (layer * n2, (layer + 1) * n2);
        for tri in &section.triangles {
            let mut t = *tri;
            t.sort_unstable();
            let [a, b, c] = t;
            cells.extend([a + lo, b + lo, c + lo, c + hi]);
            cells.extend([a + lo, b + lo, b + hi, c + hi]);
            cells.extend([a + lo, a + hi, b + hi, c + hi]);
        }
    }
    orient_simplices(&points, &mut cells, 4);
    let names: &[&str] = if quarter { &PIPE_BOUNDARIES } else { &PIPE_BOUNDARIES[..3] };
    let flags = section.flags;
    finish(points, ReferenceCell::Tetrahedron, GeometryOrder::Linear, cells, names, |verts| {
        let layer = |v: usize| v / n2;
        let all = |bit: u8| verts.iter().all(|&v| flags[v % n2] & bit != 0);
        if verts.iter().all(|&v| layer(v) == 0) {
            Some(1)
        } else if verts.iter().all(|&v| layer(v) == n_axial) {
            Some(2)
        } else if all(ON_WALL) {
            Some(3)
        } else if quarter && all(ON_X0) {
            Some(4)
        } else if quarter && all(ON_Y0) {
            Some(5)
        } else {
            None
        }
    })
}

/// Boundary names of [`quarter_disc_hexahedra`], tags 1..=5.
pub const DISC_BOUNDARIES: [&str; 5] = ["zmin", "zmax", "wall", "symmetry_x", "symmetry_y"];

/// Number of segments of the outer ring of a quarter [`pipe_tetrahedra`] section with
/// `n_radial` rings: a quarter-disc solid made with [`quarter_disc_hexahedra`] fills that pipe's
/// section exactly when `2 n_core` equals it.
pub fn quarter_pipe_wall_segments(n_radial: usize) -> usize {
    ring_segments(n_radial, true)
}

/// 27-node hexahedral mesh of a quarter disc (`x, y >= 0`) of thickness `z0 <= z <= z1`: a
/// membrane across a quarter pipe.
///
/// Cross-section (an "O-grid"): a core block, the bilinear image of the unit square with corners
/// `(0, 0)`, `(radius/2, 0)`, `(0.42 radius, 0.42 radius)`, `(0, radius/2)` in `n_core x n_core`
/// quads, and two outer blocks between the core's outer edges and the rim, each `n_core` quads
/// along the rim by `n_ring` radially (points blended linearly from the core edge to the rim). The
/// rim is the polygon through `2 n_core` equal segments of the circle `r = radius`, with the
/// vertices of [`pipe_tetrahedra`]'s outer ring of that many segments (the same floating-point
/// values) and straight edges: with `2 n_core = quarter_pipe_wall_segments(n_radial)` the disc
/// fills that pipe's polygonal section exactly, so a clamped rim seals the pipe. `n_layers`
/// cells through the thickness. Cells: `n_layers (n_core^2 + 2 n_core n_ring)`.
///
/// Boundaries (tags 1..=5): `"zmin"`, `"zmax"`, `"wall"` (the rim), `"symmetry_x"` (x = 0),
/// `"symmetry_y"` (y = 0). Region `"domain"`. Nodes on the symmetry planes have that
/// coordinate exactly 0.
///
/// # Panics
/// If `radius` is not positive, the interval is empty, or a count is 0.
pub fn quarter_disc_hexahedra(radius: f64, z0: f64, z1: f64, n_core: usize, n_ring: usize, n_layers: usize) -> Mesh<3> {
    check_interval("r", 0.0, radius);
    check_interval("z", z0, z1);
    check_count("n_core", n_core);
    check_count("n_ring", n_ring);
    check_count("n_layers", n_layers);
    let section = QuarterDiscSection::new(radius, n_core, n_ring);
    let zs = with_midpoints(&uniform_axis(z0, z1, n_layers));
    let nz = zs.len();
    let points: Vec<[f64; 3]> = section.points.iter().flat_map(|p| zs.iter().map(move |&z| [p[0], p[1], z])).collect();
    let geo = geometry_element::<3>(ReferenceCell::Hexahedron, GeometryOrder::Quadratic);
    let offsets: Vec<[usize; 3]> = geo.nodes().iter().map(|xi| std::array::from_fn(|d| (2.0 * xi[d]).round() as usize)).collect();
    let mut cells = Vec::new();
    for (block, n0, n1) in section.blocks() {
        for layer in 0..n_layers {
            for c1 in 0..n1 {
                for c0 in 0..n0 {
                    for o in &offsets {
                        let planar = section.node(block, 2 * c0 + o[0], 2 * c1 + o[1]);
                        cells.push(planar * nz + 2 * layer + o[2]);
                    }
                }
            }
        }
    }
    let flags = section.flags;
    finish(points, ReferenceCell::Hexahedron, GeometryOrder::Quadratic, cells, &DISC_BOUNDARIES, |verts| {
        let all = |bit: u8| verts.iter().all(|&v| flags[v / nz] & bit != 0);
        if verts.iter().all(|&v| v % nz == 0) {
            Some(1)
        } else if verts.iter().all(|&v| v % nz == nz - 1) {
            Some(2)
        } else if all(ON_WALL) {
            Some(3)
        } else if all(ON_X0) {
            Some(4)
        } else if all(ON_Y0) {
            Some(5)
        } else {
            None
        }
    })
}

/// Blocks of the quarter-disc O-grid (see [`quarter_disc_hexahedra`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum DiscBlock {
    /// Index `(i, j)` along x-ish and y-ish.
    Core,
    /// Between the core edge `i = 2 n_core` and the rim from 0 to 45 degrees: `(t, k)`, `t`
    /// outwards, `k` along the rim.
    Lower,
    /// Between the core edge `j = 2 n_core` (walked from 45 to 90 degrees) and the rim: `(t, k)`.
    Upper,
}

/// Nodes of the quarter-disc section on the fine (quadratic) grid of each block, shared nodes
/// numbered once.
struct QuarterDiscSection {
    n_core: usize,
    n_ring: usize,
    points: Vec<[f64; 2]>,
    flags: Vec<u8>,
    ids: std::collections::HashMap<(DiscBlock, usize, usize), usize>,
}

impl QuarterDiscSection {
    fn new(radius: f64, n_core: usize, n_ring: usize) -> Self {
        let mut s = QuarterDiscSection { n_core, n_ring, points: Vec::new(), flags: Vec::new(), ids: Default::default() };
        let (m, l) = (2 * n_core, 2 * n_ring);
        let (a, c) = (0.5 * radius, 0.42 * radius);
        let corner = [[0.0, 0.0], [a, 0.0], [c, c], [0.0, a]];
        let bilinear = |u: f64, v: f64| -> [f64; 2] {
            std::array::from_fn(|d| {
                (1.0 - u) * (1.0 - v) * corner[0][d] + u * (1.0 - v) * corner[1][d] + u * v * corner[2][d] + (1.0 - u) * v * corner[3][d]
            })
        };
        let segs = 2 * n_core;
        // Rim point `k` of the fine grid (0..=2 segs): vertices of the pipe's outer ring, and the
        // midpoints of its straight edges.
        let rim = |k: usize| -> [f64; 2] {
            let v = |j: usize| {
                let u = unit_vector(j, segs, true);
                [radius * u[0], radius * u[1]]
            };
            if k.is_multiple_of(2) {
                v(k / 2)
            } else {
                let (p, q) = (v(k / 2), v(k / 2 + 1));
                [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])]
            }
        };
        let frac = |k: usize, n: usize| if k == n { 1.0 } else { k as f64 / n as f64 };
        for j in 0..=m {
            for i in 0..=m {
                let mut f = 0;
                if i == 0 {
                    f |= ON_X0;
                }
                if j == 0 {
                    f |= ON_Y0;
                }
                s.add((DiscBlock::Core, i, j), bilinear(frac(i, m), frac(j, m)), f);
            }
        }
        for (block, first_rim) in [(DiscBlock::Lower, 0), (DiscBlock::Upper, m)] {
            for k in 0..=m {
                let inner = match block {
                    DiscBlock::Lower => bilinear(1.0, frac(k, m)),
                    _ => bilinear(1.0 - frac(k, m), 1.0),
                };
                let outer = rim(first_rim + k);
                for t in 0..=l {
                    let tau = frac(t, l);
                    let mut x: [f64; 2] = std::array::from_fn(|d| (1.0 - tau) * inner[d] + tau * outer[d]);
                    let mut f = if t == l { ON_WALL } else { 0 };
                    // Exact zeros on the symmetry planes.
                    if block == DiscBlock::Lower && k == 0 {
                        x[1] = 0.0;
                        f |= ON_Y0;
                    }
                    if block == DiscBlock::Upper && k == m {
                        x[0] = 0.0;
                        f |= ON_X0;
                    }
                    s.add((block, t, k), x, f);
                }
            }
        }
        s
    }

    /// The shared key of a node: outer-block nodes on the core edge are core nodes, and the
    /// upper block's first column is the lower block's last.
    fn canonical(&self, key: (DiscBlock, usize, usize)) -> (DiscBlock, usize, usize) {
        let m = 2 * self.n_core;
        match key {
            (DiscBlock::Lower, 0, k) => (DiscBlock::Core, m, k),
            (DiscBlock::Upper, 0, k) => (DiscBlock::Core, m - k, m),
            (DiscBlock::Upper, t, 0) => (DiscBlock::Lower, t, m),
            other => other,
        }
    }

    fn add(&mut self, key: (DiscBlock, usize, usize), x: [f64; 2], flags: u8) {
        let key = self.canonical(key);
        if !self.ids.contains_key(&key) {
            self.ids.insert(key, self.points.len());
            self.points.push(x);
            self.flags.push(flags);
        }
    }

    fn node(&self, block: DiscBlock, a: usize, b: usize) -> usize {
        self.ids[&self.canonical((block, a, b))]
    }

    /// Each block with its cell counts along its two indices.
    fn blocks(&self) -> [(DiscBlock, usize, usize); 3] {
        [(DiscBlock::Core, self.n_core, self.n_core), (DiscBlock::Lower, self.n_ring, self.n_core), (DiscBlock::Upper, self.n_ring, self.n_core)]
    }
}

/// Cross-section vertex flags of the pipe.
const ON_WALL: u8 = 1;
const ON_X0: u8 = 2;
const ON_Y0: u8 = 4;

/// Triangulated disc (or quarter disc) with per-vertex boundary flags.
struct DiscSection {
    points: Vec<[f64; 2]>,
    flags: Vec<u8>,
    triangles: Vec<[usize; 3]>,
}

/// Number of segments of ring `k` (see [`pipe_tetrahedra`]).
fn ring_segments(k: usize, quarter: bool) -> usize {
    if quarter {
        ((1.5 * k as f64).round() as usize).max(1)
    } else {
        6 * k
    }
}

/// Unit vector at angle `span * j / n` with `span` a full turn (or a quarter turn for
/// `quarter`); exact on the coordinate axes.
fn unit_vector(j: usize, n: usize, quarter: bool) -> [f64; 2] {
    let quarters = if quarter { 1 } else { 4 };
    // The angle is (j / n) * quarters quarter turns; exact multiples of a quarter turn are exact.
    if (j * quarters).is_multiple_of(n) {
        return match (j * quarters / n) % 4 {
            0 => [1.0, 0.0],
            1 => [0.0, 1.0],
            2 => [-1.0, 0.0],
            _ => [0.0, -1.0],
        };
    }
    let angle = std::f64::consts::FRAC_PI_2 * quarters as f64 * j as f64 / n as f64;
    [angle.cos(), angle.sin()]
}

/// The pipe's cross-section (see [`pipe_tetrahedra`]).
fn disc_section(radius: f64, n_radial: usize, quarter: bool) -> DiscSection {
    let mut points = vec![[0.0, 0.0]];
    let mut flags = vec![if quarter { ON_X0 | ON_Y0 } else { 0 }];
    // First vertex and segment count of each ring; ring 0 is the centre.
    let mut rings: Vec<(usize, usize)> = vec![(0, 0)];
    for k in 1..=n_radial {
        let segs = ring_segments(k, quarter);
        let r = if k == n_radial { radius } else { radius * k as f64 / n_radial as f64 };
        rings.push((points.len(), segs));
        let count = if quarter { segs + 1 } else { segs };
        for j in 0..count {
            let u = unit_vector(j, segs, quarter);
            points.push([r * u[0], r * u[1]]);
            let mut f = if k == n_radial { ON_WALL } else { 0 };
            if quarter && j == 0 {
                f |= ON_Y0;
            }
            if quarter && j == segs {
                f |= ON_X0;
            }
            flags.push(f);
        }
    }
    // Vertex `j` of a ring, wrapping around on full rings.
    let vertex = |(start, segs): (usize, usize), j: usize| if quarter { start + j } else { start + j % segs };
    let mut triangles = Vec::new();
    let first = rings[1];
    for j in 0..first.1 {
        triangles.push([0, vertex(first, j), vertex(first, j + 1)]);
    }
    for k in 2..=n_radial {
        let (inner, outer) = (rings[k - 1], rings[k]);
        let (ni, no) = (inner.1, outer.1);
        let (mut i, mut j) = (0, 0);
        while i < ni || j < no {
            // Advance on the ring whose next vertex comes first in angle: compare (j+1)/no with
            // (i+1)/ni exactly in integers.
            let advance_outer = i == ni || (j < no && (j + 1) * ni <= (i + 1) * no);
            if advance_outer {
                triangles.push([vertex(inner, i), vertex(outer, j), vertex(outer, j + 1)]);
                j += 1;
            } else {
                triangles.push([vertex(inner, i), vertex(outer, j), vertex(inner, i + 1)]);
                i += 1;
            }
        }
    }
    let mut flat: Vec<usize> = triangles.iter().flatten().copied().collect();
    orient_simplices(&points, &mut flat, 3);
    let triangles = flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    DiscSection { points, flags, triangles }
}

/// Triangle mesh over the tensor grid `xs x ys` (boundary tags 1..=4 for x-min, x-max, y-min,
/// y-max, named by `names`).
fn grid_triangles(xs: &[f64], ys: &[f64], pattern: DiagonalPattern, names: &[&str]) -> Mesh<2> {
    let (nx, ny) = (xs.len() - 1, ys.len() - 1);
    let m = [nx + 1, ny + 1];
    let mut points = grid_points(&[xs.to_vec(), ys.to_vec()], m);
    let num_grid = points.len();
    let id = |i: usize, j: usize| ravel([i, j], m);
    let mut cells = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            let right = match pattern {
                DiagonalPattern::Right => true,
                DiagonalPattern::Left => false,
                DiagonalPattern::Alternating => (i + j) % 2 == 0,
                DiagonalPattern::Crossed => {
                    let e = points.len();
                    points.push([0.5 * (xs[i] + xs[i + 1]), 0.5 * (ys[j] + ys[j + 1])]);
                    cells.extend([a, b, e, b, c, e, c, d, e, d, a, e]);
                    continue;
                }
            };
            if right {
                cells.extend([a, b, c, a, c, d]);
            } else {
                cells.extend([a, b, d, b, c, d]);
            }
        }
    }
    orient_simplices(&points, &mut cells, 3);
    // Centre vertices (ids >= num_grid) lie on no boundary; grid_side returns None for them.
    debug_assert_eq!(num_grid, m[0] * m[1]);
    finish(points, ReferenceCell::Triangle, GeometryOrder::Linear, cells, names, |v| grid_side(m, v))
}

/// Q1/Q2 quadrilateral (D = 2) or hexahedral (D = 3) mesh over the tensor grid of `axes` (cell
/// boundaries along each axis). Quadratic nodes are placed at the midpoints of the cell
/// intervals, on a grid twice as fine; each cell's nodes are found from the reference
/// coordinates (in {0, 1/2, 1}) of its geometry element's nodes, so they are in VTK order.
fn tensor_mesh<const D: usize>(axes: [Vec<f64>; D], order: GeometryOrder, names: &[&str]) -> Mesh<D> {
    let s = match order {
        GeometryOrder::Linear => 1,
        GeometryOrder::Quadratic => 2,
    };
    let fine: [Vec<f64>; D] = std::array::from_fn(|d| if s == 2 { with_midpoints(&axes[d]) } else { axes[d].clone() });
    let m: [usize; D] = std::array::from_fn(|d| fine[d].len());
    let n: [usize; D] = std::array::from_fn(|d| axes[d].len() - 1);
    let points = grid_points(&fine, m);
    let cell_type = if D == 2 { ReferenceCell::Quadrilateral } else { ReferenceCell::Hexahedron };
    let offsets: Vec<[usize; D]> =
        geometry_element::<D>(cell_type, order).nodes().iter().map(|xi| std::array::from_fn(|d| (xi[d] * s as f64).round() as usize)).collect();
    let num_cells: usize = n.iter().product();
    let mut cells = Vec::with_capacity(num_cells * offsets.len());
    for c in 0..num_cells {
        let ci = unravel(c, n);
        for off in &offsets {
            cells.push(ravel(std::array::from_fn(|d| s * ci[d] + off[d]), m));
        }
    }
    finish(points, cell_type, order, cells, names, |v| grid_side(m, v))
}

/// Builds the mesh with region [`DOMAIN_REGION`] and boundary names `names` (tags `1..`), tagging
/// local facet `f` of cell `c` with `classify(vertices of the facet)` where that is `Some`.
fn finish<const D: usize>(
    points: Vec<[f64; D]>,
    cell_type: ReferenceCell,
    order: GeometryOrder,
    cell_nodes: Vec<usize>,
    names: &[&str],
    classify: impl Fn(&[usize]) -> Option<u32>,
) -> Mesh<D> {
    let num_cells = cell_nodes.len() / geometry_nodes(cell_type, order);
    let mut mesh = Mesh {
        points,
        cell_type,
        order,
        cell_nodes,
        cell_tags: vec![DOMAIN_TAG; num_cells],
        region_names: vec![(DOMAIN_REGION.to_string(), DOMAIN_TAG)],
        boundary: Vec::new(),
        boundary_names: names.iter().enumerate().map(|(i, n)| (n.to_string(), i as u32 + 1)).collect(),
    };
    let mut boundary = Vec::new();
    let mut verts = Vec::with_capacity(4);
    for c in 0..num_cells {
        let cv = mesh.cell_vertices(c);
        for f in 0..cell_type.num_facets() {
            verts.clear();
            verts.extend(cell_type.facet(f).iter().map(|&i| cv[i]));
            if let Some(tag) = classify(&verts) {
                boundary.push(BoundaryFacet { cell: c, facet: f, tag });
            }
        }
    }
    mesh.boundary = boundary;
    mesh
}

/// Side of a structured grid with `m[d]` nodes along axis `d` that a facet lies on: `2 d + 1` if
/// all its vertices have grid index 0 along `d`, `2 d + 2` if all have index `m[d] - 1`; `None`
/// for interior facets and for facets with a vertex that is not a grid node (`id >= prod m`).
fn grid_side<const D: usize>(m: [usize; D], verts: &[usize]) -> Option<u32> {
    let total: usize = m.iter().product();
    if verts.iter().any(|&v| v >= total) {
        return None;
    }
    for d in 0..D {
        if verts.iter().all(|&v| unravel(v, m)[d] == 0) {
            return Some(2 * d as u32 + 1);
        }
        if verts.iter().all(|&v| unravel(v, m)[d] == m[d] - 1) {
            return Some(2 * d as u32 + 2);
        }
    }
    None
}

/// Points of the tensor grid of `axes` (x fastest).
fn grid_points<const D: usize>(axes: &[Vec<f64>], m: [usize; D]) -> Vec<[f64; D]> {
    let total: usize = m.iter().product();
    (0..total)
        .map(|v| {
            let i = unravel(v, m);
            std::array::from_fn(|d| axes[d][i[d]])
        })
        .collect()
}

/// Grid index of node `v` in a grid with `m[d]` nodes along axis `d` (x fastest).
fn unravel<const D: usize>(v: usize, m: [usize; D]) -> [usize; D] {
    let mut r = v;
    std::array::from_fn(|d| {
        let i = r % m[d];
        r /= m[d];
        i
    })
}

/// Node number of grid index `i` (inverse of [`unravel`]).
fn ravel<const D: usize>(i: [usize; D], m: [usize; D]) -> usize {
    (0..D).rev().fold(0, |acc, d| acc * m[d] + i[d])
}

/// `n + 1` uniformly spaced coordinates from `a` to `b`, the last exactly `b`.
fn uniform_axis(a: f64, b: f64, n: usize) -> Vec<f64> {
    (0..=n).map(|k| if k == n { b } else { a + (b - a) * (k as f64 / n as f64) }).collect()
}

/// `xs` with the midpoint of each interval inserted.
fn with_midpoints(xs: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(2 * xs.len() - 1);
    for w in xs.windows(2) {
        out.push(w[0]);
        out.push(0.5 * (w[0] + w[1]));
    }
    out.extend(xs.last());
    out
}

/// Uniform axes of a box, checking the arguments.
fn box_axes(intervals: [(f64, f64); 3], n: [usize; 3]) -> [Vec<f64>; 3] {
    for (d, ((a, b), k)) in intervals.iter().zip(n).enumerate() {
        let name = ["x", "y", "z"][d];
        check_interval(name, *a, *b);
        check_count(&format!("n{name}"), k);
    }
    std::array::from_fn(|d| uniform_axis(intervals[d].0, intervals[d].1, n[d]))
}

/// Makes every linear simplex (`k = D + 1` vertices per cell) positively oriented by swapping
/// vertices 1 and 2 where the signed measure is negative.
fn orient_simplices<const D: usize>(points: &[[f64; D]], cells: &mut [usize], k: usize) {
    for cell in cells.chunks_exact_mut(k) {
        let p = |i: usize| points[cell[i]];
        let e = |i: usize| -> [f64; D] { std::array::from_fn(|d| p(i)[d] - p(0)[d]) };
        let det = match D {
            2 => {
                let (a, b) = (e(1), e(2));
                a[0] * b[1] - a[1] * b[0]
            }
            _ => {
                let (a, b, c) = (e(1), e(2), e(3));
                a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
            }
        };
        if det < 0.0 {
            cell.swap(1, 2);
        }
    }
}

fn check_interval(name: &str, a: f64, b: f64) {
    assert!(a.is_finite() && b.is_finite() && a < b, "invalid {name} interval [{a}, {b}]: need finite a < b");
}

fn check_count(name: &str, n: usize) {
    assert!(n >= 1, "{name} must be at least 1");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::{HEX_EDGES, HEX_FACETS, QUAD_EDGES};
    use crate::mesh::Topology;
    use std::collections::{HashMap, HashSet};

    fn total_measure<const D: usize>(m: &Mesh<D>) -> f64 {
        (0..m.num_cells()).map(|c| m.signed_vertex_measure(c)).sum()
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * b.abs().max(1.0)
    }

    /// Every exterior facet (by the topology) is tagged exactly once, and only those are tagged.
    fn assert_boundary_complete<const D: usize>(m: &Mesh<D>) {
        let topo = Topology::build(m);
        let exterior: HashSet<(usize, usize)> = topo.exterior_facets().into_iter().collect();
        let tagged: Vec<(usize, usize)> = m.boundary.iter().map(|b| (b.cell, b.facet)).collect();
        let tagged_set: HashSet<(usize, usize)> = tagged.iter().copied().collect();
        assert_eq!(tagged.len(), tagged_set.len(), "a facet is tagged twice");
        assert_eq!(exterior.len(), tagged.len(), "exterior facets vs tagged facets");
        assert_eq!(exterior, tagged_set);
        for b in &m.boundary {
            assert!(m.boundary_names.iter().any(|(_, t)| *t == b.tag), "tag {} has no name", b.tag);
        }
    }

    /// Every facet (by sorted vertices) is shared by one or two cells, and the facets of one cell
    /// are exactly the tagged ones: the mesh is conforming (no hanging facets).
    fn assert_conforming<const D: usize>(m: &Mesh<D>) {
        let mut count: HashMap<Vec<usize>, usize> = HashMap::new();
        for c in 0..m.num_cells() {
            let v = m.cell_vertices(c);
            for f in 0..m.cell_type.num_facets() {
                let mut key: Vec<usize> = m.cell_type.facet(f).iter().map(|&i| v[i]).collect();
                key.sort_unstable();
                *count.entry(key).or_default() += 1;
            }
        }
        assert!(count.values().all(|&k| k == 1 || k == 2), "a facet is shared by more than two cells");
        let single = count.values().filter(|&&k| k == 1).count();
        assert_eq!(single, m.boundary.len(), "facets of a single cell must all be boundary facets");
        let topo = Topology::build(m);
        assert_eq!(topo.num_facets(), count.len());
        for fc in &topo.facet_cells {
            assert_ne!(fc[0], crate::mesh::NO_CELL);
        }
    }

    /// Every facet tagged `name` has all its vertices on the set `on`.
    fn assert_named_boundary<const D: usize>(m: &Mesh<D>, name: &str, expected: usize, on: impl Fn([f64; D]) -> bool) {
        let facets = m.boundary_facets(name).unwrap();
        assert_eq!(facets.len(), expected, "number of facets on '{name}'");
        for b in facets {
            let v = m.cell_vertices(b.cell);
            for &i in m.cell_type.facet(b.facet) {
                let p = m.points[v[i]];
                assert!(on(p), "vertex {p:?} of a '{name}' facet is off that boundary");
            }
        }
    }

    #[test]
    fn rectangle_triangles_all_patterns() {
        for pattern in [DiagonalPattern::Right, DiagonalPattern::Left, DiagonalPattern::Alternating, DiagonalPattern::Crossed] {
            let m = rectangle_triangles(-1.0, 2.0, 0.5, 1.5, 6, 4, pattern);
            m.check().unwrap();
            let per_square = if pattern == DiagonalPattern::Crossed { 4 } else { 2 };
            assert_eq!(m.num_cells(), 24 * per_square);
            assert!(close(total_measure(&m), 3.0, 1e-14));
            assert_boundary_complete(&m);
            assert_conforming(&m);
            assert_named_boundary(&m, "left", 4, |p| p[0] == -1.0);
            assert_named_boundary(&m, "right", 4, |p| p[0] == 2.0);
            assert_named_boundary(&m, "bottom", 6, |p| p[1] == 0.5);
            assert_named_boundary(&m, "top", 6, |p| p[1] == 1.5);
            assert_eq!(m.region_tag("domain").unwrap(), DOMAIN_TAG);
        }
    }

    #[test]
    fn rectangle_quads_q1_and_q2() {
        for order in [GeometryOrder::Linear, GeometryOrder::Quadratic] {
            let m = rectangle_quads(0.0, 2.0, 0.0, 1.0, 4, 3, order);
            m.check().unwrap();
            assert_eq!(m.num_cells(), 12);
            assert!(close(total_measure(&m), 2.0, 1e-14));
            assert_boundary_complete(&m);
            assert_conforming(&m);
            assert_named_boundary(&m, "left", 3, |p| p[0] == 0.0);
            assert_named_boundary(&m, "right", 3, |p| p[0] == 2.0);
            assert_named_boundary(&m, "bottom", 4, |p| p[1] == 0.0);
            assert_named_boundary(&m, "top", 4, |p| p[1] == 1.0);
            // Every point is used, and shared nodes are not duplicated.
            let used: HashSet<usize> = m.cell_nodes.iter().copied().collect();
            assert_eq!(used.len(), m.points.len());
            if order == GeometryOrder::Quadratic {
                assert_eq!(m.points.len(), 9 * 7);
                assert_eq!(m.nodes_per_cell(), 9);
                for c in 0..m.num_cells() {
                    let n = m.cell(c);
                    for (k, e) in QUAD_EDGES.iter().enumerate() {
                        let (a, b, mid) = (m.points[n[e[0]]], m.points[n[e[1]]], m.points[n[4 + k]]);
                        assert_eq!(mid, [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])]);
                    }
                    let centre: [f64; 2] = std::array::from_fn(|d| (0..4).map(|i| m.points[n[i]][d]).sum::<f64>() / 4.0);
                    let p8 = m.points[n[8]];
                    assert!((p8[0] - centre[0]).abs() < 1e-15 && (p8[1] - centre[1]).abs() < 1e-15);
                }
            }
        }
    }

    #[test]
    fn graded_spacing_is_symmetric_and_graded() {
        let u = graded_spacing(2.0, 8, 1.0);
        assert_eq!(u, uniform_axis(0.0, 2.0, 8));
        for n in [1, 2, 7, 20] {
            let xs = graded_spacing(2.5, n, 4.0);
            assert_eq!(xs.len(), n + 1);
            assert_eq!(xs[0], 0.0);
            assert_eq!(xs[n], 2.5);
            let w: Vec<f64> = xs.windows(2).map(|p| p[1] - p[0]).collect();
            assert!(w.iter().all(|&wi| wi > 0.0));
            for i in 0..n {
                assert!((w[i] - w[n - 1 - i]).abs() < 1e-12, "symmetric");
            }
            if n >= 3 {
                let mid = w[(n - 1) / 2];
                // Odd n: the centre cell exists and the end cells are exactly g times wider.
                if n % 2 == 1 {
                    assert!((w[0] / mid - 4.0).abs() < 1e-12);
                }
                for i in 0..(n - 1) / 2 {
                    assert!(w[i] > w[i + 1], "widths shrink towards the middle");
                }
            }
        }
    }

    #[test]
    fn channel_is_fine_in_the_middle() {
        let m = channel_triangles(2.2, 0.41, 20, 6, 3.0);
        m.check().unwrap();
        assert!(close(total_measure(&m), 2.2 * 0.41, 1e-13));
        assert_boundary_complete(&m);
        assert_conforming(&m);
        assert_named_boundary(&m, "inlet", 6, |p| p[0] == 0.0);
        assert_named_boundary(&m, "outlet", 6, |p| p[0] == 2.2);
        assert_named_boundary(&m, "bottom", 20, |p| p[1] == 0.0);
        assert_named_boundary(&m, "top", 20, |p| p[1] == 0.41);
        assert!(m.boundary_tag("walls").is_err());
        let xs = graded_spacing(2.2, 20, 3.0);
        assert!(xs[1] - xs[0] > 2.5 * (xs[10] - xs[9]));
    }

    #[test]
    fn box_tetrahedra_is_conforming() {
        let m = box_tetrahedra(0.0, 1.0, -1.0, 1.0, 0.0, 3.0, 3, 4, 2);
        m.check().unwrap();
        assert_eq!(m.num_cells(), 6 * 24);
        assert!(close(total_measure(&m), 6.0, 1e-13));
        assert_boundary_complete(&m);
        assert_conforming(&m);
        // Each interior face is shared by exactly two cells (Topology::facet_cells).
        let topo = Topology::build(&m);
        let interior = topo.facet_cells.iter().filter(|fc| fc[1] != crate::mesh::NO_CELL).count();
        let faces_total = (4 * m.num_cells() + m.boundary.len()) / 2;
        assert_eq!(interior + m.boundary.len(), faces_total);
        assert_named_boundary(&m, "xmin", 2 * 4 * 2, |p| p[0] == 0.0);
        assert_named_boundary(&m, "xmax", 2 * 4 * 2, |p| p[0] == 1.0);
        assert_named_boundary(&m, "ymin", 2 * 3 * 2, |p| p[1] == -1.0);
        assert_named_boundary(&m, "ymax", 2 * 3 * 2, |p| p[1] == 1.0);
        assert_named_boundary(&m, "zmin", 2 * 3 * 4, |p| p[2] == 0.0);
        assert_named_boundary(&m, "zmax", 2 * 3 * 4, |p| p[2] == 3.0);
    }

    #[test]
    fn box_hexahedra_q1_and_q2() {
        for order in [GeometryOrder::Linear, GeometryOrder::Quadratic] {
            let m = box_hexahedra(0.0, 2.0, 0.0, 1.0, 0.0, 0.5, 2, 3, 2, order);
            m.check().unwrap();
            assert!(close(total_measure(&m), 1.0, 1e-14));
            assert_boundary_complete(&m);
            assert_conforming(&m);
            assert_named_boundary(&m, "xmin", 6, |p| p[0] == 0.0);
            assert_named_boundary(&m, "xmax", 6, |p| p[0] == 2.0);
            assert_named_boundary(&m, "ymin", 4, |p| p[1] == 0.0);
            assert_named_boundary(&m, "ymax", 4, |p| p[1] == 1.0);
            assert_named_boundary(&m, "zmin", 6, |p| p[2] == 0.0);
            assert_named_boundary(&m, "zmax", 6, |p| p[2] == 0.5);
            let used: HashSet<usize> = m.cell_nodes.iter().copied().collect();
            assert_eq!(used.len(), m.points.len());
            if order == GeometryOrder::Quadratic {
                assert_eq!(m.points.len(), 5 * 7 * 5);
                for c in 0..m.num_cells() {
                    let n = m.cell(c);
                    let p = |k: usize| m.points[n[k]];
                    for (k, e) in HEX_EDGES.iter().enumerate() {
                        let mid: [f64; 3] = std::array::from_fn(|d| 0.5 * (p(e[0])[d] + p(e[1])[d]));
                        assert_eq!(p(8 + k), mid, "edge node {k}");
                    }
                    for (f, face) in HEX_FACETS.iter().enumerate() {
                        let centre: [f64; 3] = std::array::from_fn(|d| face.iter().map(|&i| p(i)[d]).sum::<f64>() / 4.0);
                        let q = p(20 + f);
                        assert!((0..3).all(|d| (q[d] - centre[d]).abs() < 1e-15), "face node {f}");
                    }
                }
            }
        }
    }

    fn polygon_area(radius: f64, n_radial: usize, quarter: bool) -> f64 {
        let n = ring_segments(n_radial, quarter) as f64;
        let span = if quarter { std::f64::consts::FRAC_PI_2 } else { 2.0 * std::f64::consts::PI };
        0.5 * n * radius * radius * (span / n).sin()
    }

    #[test]
    fn pipe_is_conforming_and_measures_the_polygonal_cylinder() {
        let (r, l) = (0.3, 2.0);
        for quarter in [false, true] {
            for n_radial in [1, 2, 5] {
                let m = pipe_tetrahedra(r, l, n_radial, 3, quarter);
                m.check().unwrap();
                let vol = total_measure(&m);
                let exact = polygon_area(r, n_radial, quarter) * l;
                assert!(close(vol, exact, 1e-12), "{vol} vs {exact}");
                assert_boundary_complete(&m);
                assert_conforming(&m);
                let ring = ring_segments(n_radial, quarter);
                let section_tris: usize =
                    (1..=n_radial).map(|k| ring_segments(k, quarter) + if k > 1 { ring_segments(k - 1, quarter) } else { 0 }).sum();
                assert_named_boundary(&m, "inlet", section_tris, |p| p[2] == 0.0);
                assert_named_boundary(&m, "outlet", section_tris, |p| p[2] == l);
                assert_named_boundary(&m, "wall", 2 * 3 * ring, |p| ((p[0].hypot(p[1])) - r).abs() <= 4e-16 * r);
                if quarter {
                    assert_named_boundary(&m, "symmetry_x", 2 * 3 * n_radial, |p| p[0] == 0.0);
                    assert_named_boundary(&m, "symmetry_y", 2 * 3 * n_radial, |p| p[1] == 0.0);
                    assert!(m.points.iter().all(|p| p[0] >= 0.0 && p[1] >= 0.0));
                } else {
                    assert!(m.boundary_tag("symmetry_x").is_err());
                }
            }
        }
    }

    #[test]
    fn pipe_volume_converges_to_the_cylinder() {
        let (r, l) = (1.0, 1.0);
        let exact = std::f64::consts::PI * r * r * l;
        for quarter in [false, true] {
            let mut last = f64::INFINITY;
            for n in [2, 4, 8, 16] {
                let m = pipe_tetrahedra(r, l, n, 1, quarter);
                let scale = if quarter { 4.0 } else { 1.0 };
                let err = (scale * total_measure(&m) - exact).abs() / exact;
                assert!(err < last, "error must decrease under refinement");
                last = err;
            }
            assert!(last < 2e-3, "{last}");
        }
    }

    #[test]
    fn pipe_cells_are_well_shaped() {
        // The smallest tetrahedron is not a sliver: volume over (longest edge)^3 bounded below.
        let m = pipe_tetrahedra(1.0, 1.0, 6, 6, false);
        let mut worst = f64::INFINITY;
        for c in 0..m.num_cells() {
            let v = m.cell_vertices(c);
            let mut h: f64 = 0.0;
            for a in 0..4 {
                for b in a + 1..4 {
                    let (p, q) = (m.points[v[a]], m.points[v[b]]);
                    h = h.max(((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt());
                }
            }
            worst = worst.min(m.signed_vertex_measure(c) / h.powi(3));
        }
        assert!(worst > 0.01, "worst shape ratio {worst}");
    }
    #[test]
    fn quarter_disc_is_conforming_fills_the_quarter_pipe_section_and_shares_its_wall_vertices() {
        let (r, z0, z1) = (1.0, 1.975, 2.025);
        for (n_radial, n_core, n_ring, n_layers) in [(4, 3, 2, 1), (8, 6, 3, 2)] {
            assert_eq!(quarter_pipe_wall_segments(n_radial), 2 * n_core);
            let m = quarter_disc_hexahedra(r, z0, z1, n_core, n_ring, n_layers);
            m.check().unwrap();
            assert_eq!(m.num_cells(), n_layers * (n_core * n_core + 2 * n_core * n_ring));
            // Volume by Gauss quadrature of det J over each 27-node cell.
            let rule = crate::quadrature::hexahedron(6);
            let geo = m.geometry_element();
            let tab = geo.tabulate(&rule.points);
            let n = geo.num_dofs();
            let mut vol = 0.0;
            for c in 0..m.num_cells() {
                for (q, w) in rule.weights.iter().enumerate() {
                    let mut j = [[0.0; 3]; 3];
                    for (k, &node) in m.cell(c).iter().enumerate() {
                        let g = tab.grads[q * n + k];
                        for a in 0..3 {
                            for b in 0..3 {
                                j[a][b] += m.points[node][a] * g[b];
                            }
                        }
                    }
                    let det = j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1]) - j[0][1] * (j[1][0] * j[2][2] - j[1][2] * j[2][0])
                        + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0]);
                    assert!(det > 0.0, "cell {c} is inverted at a quadrature point");
                    vol += w * det;
                }
            }
            let exact = polygon_area(r, n_radial, true) * (z1 - z0);
            assert!(close(vol, exact, 1e-12), "{vol} vs {exact}");
            assert_boundary_complete(&m);
            assert_conforming(&m);
            // Shared facets carry the same quadratic nodes from both sides.
            let mut faces: HashMap<Vec<usize>, Vec<usize>> = HashMap::new();
            for c in 0..m.num_cells() {
                for f in 0..6 {
                    let local = m.facet_local_nodes(f);
                    let mut v: Vec<usize> = m.cell_type.facet(f).iter().map(|&i| m.cell_vertices(c)[i]).collect();
                    v.sort_unstable();
                    let mut all: Vec<usize> = local.iter().map(|&l| m.cell(c)[l]).collect();
                    all.sort_unstable();
                    if let Some(other) = faces.insert(v, all.clone()) {
                        assert_eq!(other, all, "a shared face has different nodes in its two cells");
                    }
                }
            }
            let ring = 2 * n_core;
            assert_named_boundary(&m, "zmin", n_core * n_core + 2 * n_core * n_ring, |p| p[2] == z0);
            assert_named_boundary(&m, "zmax", n_core * n_core + 2 * n_core * n_ring, |p| p[2] == z1);
            assert_named_boundary(&m, "wall", ring * n_layers, |p| (p[0].hypot(p[1]) - r).abs() <= 4e-16);
            assert_named_boundary(&m, "symmetry_x", (n_core + n_ring) * n_layers, |p| p[0] == 0.0);
            assert_named_boundary(&m, "symmetry_y", (n_core + n_ring) * n_layers, |p| p[1] == 0.0);
            // The rim's vertices are the quarter pipe's outer-ring vertices, bit for bit.
            let pipe = pipe_tetrahedra(r, 4.0, n_radial, 1, true);
            let wall: HashSet<[u64; 2]> =
                pipe.points.iter().filter(|p| p[2] == 0.0 && p[0].hypot(p[1]) > 0.999).map(|p| [p[0].to_bits(), p[1].to_bits()]).collect();
            let mr = &m;
            let rim: HashSet<[u64; 2]> = m
                .boundary_facets("wall")
                .unwrap()
                .iter()
                .flat_map(|b| mr.cell_type.facet(b.facet).iter().map(move |&i| mr.cell_vertices(b.cell)[i]).collect::<Vec<_>>())
                .filter(|&v| m.points[v][2] == z0)
                .map(|v| [m.points[v][0].to_bits(), m.points[v][1].to_bits()])
                .collect();
            assert_eq!(rim, wall);
        }
    }
}
