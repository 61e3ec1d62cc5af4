//! A thick solid coupled on its whole wetted boundary (issue 15): gamma_s of several tagged sides
//! with corners, the fluid cells it encloses removed, so that a compressible solid is free to
//! change its area.

use fdfsi::case::Case;
use fdfsi::run::{run_case, RunOptions, RunSummary};

/// A compressible block (neo-Hookean, G = K = 1) standing on the floor of a box of fluid with a
/// free top, pressed down by its weight (body force 0.3): gamma_s is its left, top and right
/// sides, which gamma_f closes with the floor. The fluid moves only while the block settles.
const BLOCK: &str = r#"
title = "compressible block under its weight, in fluid"
[mesh]
kind = "rectangle"
x = [0.0, 1.0]
y = [0.0, 1.0]
n = [10, 10]
[physics]
formulation = "plane"
model = "stokes"
[fluid]
density = 1.0
viscosity = 0.01
[solid]
mesh = { kind = "rectangle", x = [0.3, 0.7], y = [0.0, 0.4], n = [2, 2] }
surface = ["left", "top", "right"]
model = "neo-hookean"
shear_modulus = 1.0
bulk_modulus = 1.0
body_force = [0.0, -0.3]
covered_fluid = "removed"
[[solid.boundary]]
name = "bottom"
type = "displacement"
value = [0.0, 0.0]
[time]
dt = 1.0
end = 6.0
scheme = "euler"
[[boundary]]
name = "bottom"
type = "no-slip"
[[boundary]]
name = "left"
type = "no-slip"
[[boundary]]
name = "right"
type = "no-slip"
[[boundary]]
name = "top"
type = "free"
[[output.probe]]
name = "uy_top"
field = "displacement"
component = 1
point = [0.5, 0.4]
[[output.probe]]
name = "ux_corner"
field = "displacement"
component = 0
point = [0.7, 0.4]
"#;

fn run(text: &str, tag: &str) -> RunSummary {
    let case = Case::from_toml_str(text, tag).unwrap();
    let out = std::env::temp_dir().join(format!("fdfsi-test-thick-{tag}-{}", std::process::id()));
    run_case(&case, &RunOptions::new(out, std::env::temp_dir()), &mut |_: &str| {}).unwrap()
}

fn q(s: &RunSummary, name: &str) -> f64 {
    s.quantities[name]
}

/// The same block without fluid: quasi-static, the same weight and clamp.
fn solid_only() -> String {
    let solid = &BLOCK[BLOCK.find("[solid]").unwrap()..BLOCK.find("[time]").unwrap()];
    let solid = solid.replace("covered_fluid = \"removed\"\n", "").replace("surface = [\"left\", \"top\", \"right\"]\n", "");
    let probes = &BLOCK[BLOCK.find("[[output.probe]]").unwrap()..];
    format!(
        "title = \"the block alone\"\n[physics]\nformulation = \"plane\"\n{}{probes}",
        solid.replace("[solid]", "[solid]\nloading = { steps = 1 }")
    )
}

#[test]
fn a_compressible_solid_enclosed_by_gamma_f_changes_its_area_as_without_fluid() {
    let alone = run(&solid_only(), "alone");
    let removed = run(BLOCK, "removed");
    let kept = run(&BLOCK.replace("covered_fluid = \"removed\"", "covered_fluid = \"kept\""), "kept");
    let (uy, ux) = (q(&alone, "uy_top"), q(&alone, "ux_corner"));
    println!("block alone: uy_top {uy:.6e}, ux_corner {ux:.6e}");
    for (name, s) in [("removed", &removed), ("kept", &kept)] {
        println!("covered fluid {name}: uy_top {:.6e}, ux_corner {:.6e}", q(s, "uy_top"), q(s, "ux_corner"));
    }
    // The block shortens by 2.2 % of its height (Poisson: its corner moves out by 7e-5). With the
    // covered fluid removed, the fluid at rest leaves it as it is alone: measured 2.8e-5 of uy and
    // 6.2e-7 in ux (the weak no-slip's residual force; held at 1e-4 of uy).
    assert!(uy < -8e-3, "the block alone shortens: {uy}");
    assert!((q(&removed, "uy_top") - uy).abs() < 1e-4 * uy.abs());
    assert!((q(&removed, "ux_corner") - ux).abs() < 1e-4 * uy.abs());
    // Kept, the fictitious fluid inside holds the block's area: it shortens 40 % less and bulges
    // 26 times as far (measured -5.16e-3, 1.82e-3).
    assert!(q(&kept, "uy_top") > 0.7 * uy, "kept: {}", q(&kept, "uy_top"));
    assert!(q(&kept, "ux_corner") > 10.0 * ux, "kept: {}", q(&kept, "ux_corner"));
}

/// The block with inertia (rho_s = 1) released under its weight at t = 0, to t = 1 (it swings
/// down and back, damped by the fluid): `(uy_top, ux_corner)` with `scheme` and step `dt`.
fn swinging_block(scheme: &str, dt: f64) -> (f64, f64) {
    let text = BLOCK
        .replace("body_force = [0.0, -0.3]", "body_force = [0.0, -0.3]\ndensity = 1.0")
        .replace("dt = 1.0", &format!("dt = {dt}"))
        .replace("end = 6.0", "end = 1.0\noutput_every = 100000")
        .replace("scheme = \"euler\"", &format!("scheme = \"{scheme}\""));
    let s = run(&text, &format!("swing-{scheme}-{dt}"));
    (q(&s, "uy_top"), q(&s, "ux_corner"))
}

/// BDF2 in FSI: on the swinging block (the adapted mesh keeps its topology, so only the time
/// scheme's error changes with dt) BDF2 at dt = 0.025 is within 1e-4 of BDF2 at dt = 0.00625
/// (measured 5.3e-5 in uy, 4.2e-5 in ux), implicit Euler at dt = 0.025 ten times as far (6.4e-4,
/// 4.3e-4): held at 5 times. (Not a convergence rate: the differences from dt = 0.1 to 0.0125
/// do not shrink regularly for either scheme, BENCHMARKS.md "BDF2 in FSI".)
#[test]
fn bdf2_is_more_accurate_than_euler_for_a_solid_swinging_in_fluid() {
    let fine = swinging_block("bdf2", 0.00625);
    let bdf2 = swinging_block("bdf2", 0.025);
    let euler = swinging_block("euler", 0.025);
    let err = |x: (f64, f64)| ((x.0 - fine.0).abs(), (x.1 - fine.1).abs());
    let (eb, ee) = (err(bdf2), err(euler));
    println!("fine {fine:?}; BDF2 dt 0.025 off by {eb:?}, Euler by {ee:?}");
    assert!(fine.0 < -0.013 && fine.1 > 1e-3, "the block swings down and bulges: {fine:?}");
    assert!(eb.0 < 1e-4 && eb.1 < 1e-4, "BDF2: {eb:?}");
    assert!(ee.0 > 5.0 * eb.0 && ee.1 > 5.0 * eb.1, "Euler {ee:?} against BDF2 {eb:?}");
}

#[test]
fn covered_fluid_removed_needs_gamma_f_to_enclose_the_solid() {
    // Only the top side coupled: gamma_f is open, its solid side reaches the fluid side.
    let case = Case::from_toml_str(&BLOCK.replace("surface = [\"left\", \"top\", \"right\"]", "surface = \"top\""), "open").unwrap();
    let out = std::env::temp_dir().join(format!("fdfsi-test-thick-open-{}", std::process::id()));
    let e = run_case(&case, &RunOptions::new(out, std::env::temp_dir()), &mut |_: &str| {}).unwrap_err();
    let message = format!("{e:#}");
    assert!(message.contains("gamma_f does not enclose the solid"), "{message}");
}

/// Adapts `fluid` to `surface` with the covered cells removed and checks that gamma_f encloses
/// the bar: the removal succeeds from the facet rules alone (no cell told by its side), removes
/// cells, and gamma_f has gamma_s's length (chords of the curved bar: to 1e-4).
fn assert_encloses(bg: &fdfsi::fem::adapt::Background<2>, surface: &fdfsi::fem::adapt::Surface<2>, label: &str) {
    use fdfsi::fem::adapt::{adapt_with, remove_enclosed, AdaptOptions};
    let adapted = remove_enclosed(adapt_with(bg, surface, &AdaptOptions::new(0.2)).unwrap(), surface).unwrap_or_else(|e| panic!("{label}: {e}"));
    let gamma_f = adapted.gamma_f_measure();
    assert!((gamma_f - surface.measure()).abs() < 1e-4 * surface.measure(), "{label}: gamma_f {gamma_f} against gamma_s {}", surface.measure());
    assert!(adapted.stats.removed_cells > 0 && adapted.stats.cells_by_side == 0, "{label}: {:?}", adapted.stats);
}

/// The original fluid mesh `meshes/NAME.msh`, prepared for adaptation.
fn background(name: &str) -> fdfsi::fem::adapt::Background<2> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes").join(name);
    let fdfsi::fem::gmsh::AnyMesh::D2(fluid) = fdfsi::fem::gmsh::read_msh(&path).unwrap() else { panic!("{name}: a 2D mesh") };
    fdfsi::fem::adapt::Background::new(&fluid).unwrap()
}

/// The Turek-Hron bar swung far, its tip among the cells of `turek-hron-fsi-0.msh` as in the FSI3
/// and FSI2 runs where they stopped ("gamma_f does not enclose the solid"; gamma_s saved from
/// those runs in `tests/data`). FSI3 at t = 3.786 (swung down): near the tip's lower corner an
/// edge cut by the bottom face had its other end moved onto the tip face; the adaptation dropped
/// that cut as if the edge touched the bottom face at the moved end, and gamma_f lost the bottom
/// face between the cut and the corner; now the move is undone instead. FSI2 at t = 7.642 (swung
/// up): an edge from a vertex next to the bottom face crossed the tip face, and the point kept on
/// it was the bottom face's; now the point farther from the edge's ends is kept.
#[test]
fn the_adapted_mesh_encloses_the_bar_with_its_tip_among_the_cells() {
    let bg = background("turek-hron-fsi-0.msh");
    for data in ["turek-hron-fsi3-gamma-s-t3.786.csv", "turek-hron-fsi2-gamma-s-t7.642.csv"] {
        assert_encloses(&bg, &saved_gamma_s(data), data);
    }
}

/// gamma_s saved in `tests/data/NAME`: one flat piece per row, its `D` corners' coordinates
/// (`x0,y0,x1,y1` in 2D, `x0,y0,z0,x1,...,z2` in 3D); corners with equal coordinates are one point.
fn saved_gamma_s<const D: usize>(name: &str) -> fdfsi::fem::adapt::Surface<D> {
    let text = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)).unwrap();
    let (mut points, mut index, mut pieces) = (Vec::new(), std::collections::HashMap::new(), Vec::new());
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        assert_eq!(v.len(), D * D, "{name}: {line}");
        pieces.push(std::array::from_fn(|k| {
            let p: [f64; D] = std::array::from_fn(|d| v[D * k + d]);
            *index.entry(p.map(f64::to_bits)).or_insert_with(|| {
                points.push(p);
                points.len() - 1
            })
        }));
    }
    fdfsi::fem::adapt::Surface::from_pieces(points, pieces).unwrap()
}

/// Deflection of mode `n` (1, 2, 3) of a clamped-free Euler-Bernoulli beam of length `L` at
/// arc length `s`, scaled to 1 at the free end, and its slope:
/// `phi(s) = (cosh bs - cos bs - sigma (sinh bs - sin bs)) / 2` with `b L` = 1.8751, 4.6941,
/// 7.8548.
fn cantilever_mode(n: usize, s: f64, length: f64) -> (f64, f64) {
    let (bl, sigma) = [(1.875_104_068_7, 0.734_095_513_7), (4.694_091_133_0, 1.018_466_459_2), (7.854_757_438_2, 0.999_224_495_0)][n - 1];
    let b = bl / length;
    let x = b * s;
    let phi = (x.cosh() - x.cos() - sigma * (x.sinh() - x.sin())) / 2.0;
    let slope = b * (x.sinh() + x.sin() - sigma * (x.cosh() - x.cos())) / 2.0;
    let tip = (bl.cosh() - bl.cos() - sigma * (bl.sinh() - bl.sin())) / 2.0;
    (phi / tip, slope / tip)
}

/// gamma_s of the Turek-Hron bar (0.35 x 0.02, clamped to the cylinder at x = 0.24899) bent
/// into `sum a_n phi_n` (tip deflections `a`, [`cantilever_mode`]) and stretched by `stretch`
/// along its centreline, the sections kept normal to it: its bottom, tip and top faces in 80, 8
/// and 80 flat pieces, as the Q2 nodes of `turek-hron-bar-40.msh` divide them.
fn bent_bar(a: [f64; 3], stretch: f64) -> fdfsi::fem::adapt::Surface<2> {
    let (x0, length, thickness) = (0.248_989_794_855_663_6, 0.35, 0.02);
    let (along, across, substeps) = (80, 8, 50);
    let angle = |s: f64| (0..3).map(|n| a[n] * cantilever_mode(n + 1, s, length).1).sum::<f64>().atan();
    // The centreline and its angle at the section s = length i / along, by the midpoint rule.
    let mut centre = vec![([x0, 0.2], 0.0)];
    let ds = (1.0 + stretch) * length / (along * substeps) as f64;
    for i in 0..along {
        let mut c = centre[i].0;
        for k in 0..substeps {
            let theta = angle((i * substeps + k) as f64 * length / (along * substeps) as f64 + 0.5 * length / (along * substeps) as f64);
            c = [c[0] + ds * theta.cos(), c[1] + ds * theta.sin()];
        }
        centre.push((c, angle(length * (i + 1) as f64 / along as f64)));
    }
    let at = |i: usize, eta: f64| {
        let (c, theta) = centre[i];
        [c[0] - eta * theta.sin(), c[1] + eta * theta.cos()]
    };
    let half = thickness / 2.0;
    let mut points: Vec<[f64; 2]> = (0..=along).map(|i| at(i, -half)).collect();
    points.extend((1..=across).map(|j| at(along, -half + thickness * j as f64 / across as f64)));
    points.extend((0..along).rev().map(|i| at(i, half)));
    // The root's corners where the mesh has them, on the cylinder.
    let last = points.len() - 1;
    (points[0], points[last]) = ([x0, 0.19], [x0, 0.21]);
    let pieces = (0..points.len() - 1).map(|i| [i, i + 1]).collect();
    fdfsi::fem::adapt::Surface::from_pieces(points, pieces).unwrap()
}

/// The bar bent as in FSI2's swings over the level-1 mesh. The saved shape (cantilever modes
/// 1-3, its tip far down; `tests/data/turek-hron-bar-bent-level1.csv`) opened gamma_f at the
/// tip's lower corner (a 2.7 mm gap in the bottom face next to the corner; the same message as
/// FSI2 on level 1 at t = 17.08, whose checkpoint is lost, so whether that was this gap is not
/// known): a cell cut twice by the tip face, its third vertex moved onto the bottom face, was
/// bisected along the diagonal between the two faces; that child had all its vertices on gamma_s
/// (flat), the move was undone, and the bottom face between the corner and the next cut had no
/// facet. Now the diagonal that makes no flat child is taken. Found among 12 000 random shapes
/// (tip deflections up to 0.1, modes 2 and 3 up to 0.02 and 0.004, stretch up to 3e-3) on level 1;
/// with the fix none of them fails, nor 3 000 on each of levels 0 and 2. The swing below, tip
/// from -0.1 to 0.1 on levels 0 and 1, keeps the common shapes covered.
#[test]
fn the_adapted_mesh_encloses_the_bar_bent_as_in_fsi2() {
    let (l0, l1) = (background("turek-hron-fsi-0.msh"), background("turek-hron-fsi-1.msh"));
    assert_encloses(&l1, &saved_gamma_s("turek-hron-bar-bent-level1.csv"), "the tip's lower corner, level 1");
    for k in -10..=10 {
        let tip = 0.01 * k as f64;
        for (mesh, label) in [(&l0, "level 0"), (&l1, "level 1")] {
            assert_encloses(mesh, &bent_bar([tip, -0.1 * tip, 0.01 * tip], 0.0), &format!("tip {tip}, {label}"));
        }
    }
}

/// gamma_s of a rectangular block `length x thickness` centred at `centre` and turned by
/// `angle` (radians) from the x axis, closed: its long sides in 20 pieces, its short ones in 4.
fn block(centre: [f64; 2], length: f64, thickness: f64, angle: f64) -> fdfsi::fem::adapt::Surface<2> {
    let (c, s) = (angle.cos(), angle.sin());
    let at = |u: f64, v: f64| {
        [centre[0] + c * (u - length / 2.0) - s * (v - thickness / 2.0), centre[1] + s * (u - length / 2.0) + c * (v - thickness / 2.0)]
    };
    let (along, across) = (20, 4);
    let mut points: Vec<[f64; 2]> = (0..along).map(|i| at(length * i as f64 / along as f64, 0.0)).collect();
    points.extend((0..across).map(|j| at(length, thickness * j as f64 / across as f64)));
    points.extend((1..=along).rev().map(|i| at(length * i as f64 / along as f64, thickness)));
    points.extend((1..=across).rev().map(|j| at(0.0, thickness * j as f64 / across as f64)));
    let n = points.len();
    fdfsi::fem::adapt::Surface::from_pieces(points, (0..n).map(|i| [i, (i + 1) % n]).collect()).unwrap()
}

/// Blocks turned by any angle in the coarse part of `turek-hron-fsi-0.msh` (cells about 0.04
/// across), about a cell thick or more, are enclosed by gamma_f with nothing of gamma_s lost. The
/// first one's lower left corner lies in a cell whose opposite edge both sides cross, at 0.24 and
/// 0.75 of its length: the edge kept only the second point, and the left side between the corner
/// and that edge had no facet; now the end nearer the first point moves onto it (a second cut).
/// Random blocks (1 000 drawn for each range of thickness, length 0.06 to 0.24; BENCHMARKS.md)
/// failed once in 0.04-0.16 and once in 0.06-0.24 before, never since; of those 0.03-0.12 thick
/// one still fails, of those 0.02-0.08 thick seven (the failing blocks inspected were thinner than
/// 0.9 cells: the cells then span the block, and its two sides cut the same edges). The block
/// 0.75 cells thick below is one the flat rule mended: a cell spanning both long sides near a
/// corner was taken for flat.
#[test]
fn blocks_about_a_cell_thick_or_more_are_enclosed_at_any_angle() {
    let bg = background("turek-hron-fsi-0.msh");
    assert_encloses(
        &bg,
        &block([1.413_310_155_435_181, 0.178_744_534_049_332_8], 0.069_712_389_962_895_28, 0.148_173_893_130_628_62, 0.585_100_217_433_940_6),
        "the corner's edge cut twice",
    );
    assert_encloses(
        &bg,
        &block([1.003_204_631_580_276_7, 0.158_627_124_114_682_08], 0.130_630_894_702_419_2, 0.030_023_902_989_002_767, 0.921_181_926_205_838_2),
        "a block 0.75 cells thick",
    );
    for k in 0..40 {
        let angle = std::f64::consts::PI * k as f64 / 40.0;
        let centre = [0.9 + 0.033 * k as f64, 0.17 + 0.0013 * k as f64];
        for (length, thickness) in [(0.12, 0.045), (0.1, 0.08)] {
            assert_encloses(&bg, &block(centre, length, thickness, angle), &format!("block {length} x {thickness} at {centre:?} turned by {angle}"));
        }
    }
}

/// A compressible block (neo-Hookean, G = K = 1) standing on the floor of a box of fluid (`n^3`
/// cubes of six tetrahedra), coupled on its four sides and its top, pressed down by its weight:
/// the 3D [`BLOCK`]. gamma_s has eight feature lines (four vertical edges ending on the floor,
/// four top edges) and four corners.
fn block_3d(n: usize) -> String {
    format!(
        r#"
title = "compressible block under its weight, in fluid, 3D"
[mesh]
kind = "box"
x = [0.0, 1.0]
y = [0.0, 1.0]
z = [0.0, 1.0]
n = [{n}, {n}, {n}]
[physics]
formulation = "3d"
model = "stokes"
[fluid]
density = 1.0
viscosity = 0.01
[solid]
mesh = {{ kind = "box", x = [0.31, 0.69], y = [0.33, 0.71], z = [0.0, 0.41], n = [2, 2, 2] }}
surface = ["xmin", "xmax", "ymin", "ymax", "zmax"]
model = "neo-hookean"
shear_modulus = 1.0
bulk_modulus = 1.0
body_force = [0.0, 0.0, -0.3]
covered_fluid = "removed"
[[solid.boundary]]
name = "zmin"
type = "displacement"
value = [0.0, 0.0, 0.0]
[time]
dt = 1.0
end = 6.0
scheme = "euler"
[[boundary]]
name = "zmin"
type = "no-slip"
[[boundary]]
name = "xmin"
type = "no-slip"
[[boundary]]
name = "xmax"
type = "no-slip"
[[boundary]]
name = "ymin"
type = "no-slip"
[[boundary]]
name = "ymax"
type = "no-slip"
[[boundary]]
name = "zmax"
type = "free"
[[output.probe]]
name = "uz_top"
field = "displacement"
component = 2
point = [0.5, 0.52, 0.41]
[[output.probe]]
name = "ux_corner"
field = "displacement"
component = 0
point = [0.69, 0.71, 0.41]
"#
    )
}

/// The 3D block at rest is enclosed by gamma_f, which has gamma_s's area (its faces are flat: to
/// 1e-9), on fluid meshes of 6 to 16 cubes a side: its edges and corners are chains of fluid
/// vertices (`adapt::features`), facets and cells across an edge are neither on gamma_f nor flat,
/// and the cells next to an edge whose children's edges still cross a face are cut again. Before
/// the chains, gamma_f covered 73 to 88 % of gamma_s (n = 6, 8, 12). On 11 cubes a side it
/// missed 0.8 % along the top edge at x = 0.31 (grid diagonals crossing both faces within 0.01 of
/// the edge, near their middles, keeping one point each) until the cells were cut again.
#[test]
fn a_3d_block_is_enclosed_with_its_edges_and_corners_on_meshes_of_several_sizes() {
    for n in [6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16] {
        let case = Case::from_toml_str(&block_3d(n), "block3d").unwrap();
        let out = std::env::temp_dir().join(format!("fdfsi-test-block3d-{n}-{}", std::process::id()));
        let a = fdfsi::run::adapt::adapt_case(&case, &std::env::temp_dir(), &out).unwrap_or_else(|e| panic!("n = {n}: {e:#}"));
        assert!(
            (a.gamma_f_measure - a.gamma_s_measure).abs() < 1e-9 * a.gamma_s_measure,
            "n = {n}: gamma_f {} against gamma_s {}",
            a.gamma_f_measure,
            a.gamma_s_measure
        );
        assert!(a.stats.removed_cells > 0 && a.stats.unplaced_corners == 0, "n = {n}: {:?}", a.stats);
        std::fs::remove_dir_all(&out).ok();
    }
}

/// gamma_s of a closed block of sides `size`, turned by `angle` (radians) about `axis` and centred
/// at `centre`: each face in 3 x 3 squares of two triangles.
fn turned_block_3d(size: [f64; 3], axis: [f64; 3], angle: f64, centre: [f64; 3]) -> fdfsi::fem::adapt::Surface<3> {
    let l = axis.iter().map(|v| v * v).sum::<f64>().sqrt();
    let [x, y, z] = axis.map(|v| v / l);
    let (c, s, t) = (angle.cos(), angle.sin(), 1.0 - angle.cos());
    let r = [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ];
    let m = 3;
    let mut points = Vec::new();
    let mut index = std::collections::HashMap::new();
    let mut id = |g: [usize; 3], points: &mut Vec<[f64; 3]>| {
        *index.entry(g).or_insert_with(|| {
            let local: [f64; 3] = std::array::from_fn(|d| size[d] * (g[d] as f64 / m as f64 - 0.5));
            points.push(std::array::from_fn(|i| centre[i] + (0..3).map(|j| r[i][j] * local[j]).sum::<f64>()));
            points.len() - 1
        })
    };
    let mut pieces = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, m] {
            for i in 0..m {
                for j in 0..m {
                    let g = |di: usize, dj: usize| {
                        let mut g = [side; 3];
                        (g[u], g[v]) = (i + di, j + dj);
                        g
                    };
                    let q = [g(0, 0), g(1, 0), g(1, 1), g(0, 1)].map(|g| id(g, &mut points));
                    // Outward: counter-clockwise seen from outside.
                    if side == 0 {
                        pieces.extend([[q[0], q[2], q[1]], [q[0], q[3], q[2]]]);
                    } else {
                        pieces.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
                    }
                }
            }
        }
    }
    fdfsi::fem::adapt::Surface::from_pieces(points, pieces).unwrap()
}

/// Blocks 1.5 to 4.5 cells a side turned about axes and by angles spread over all directions, in
/// a box of 10^3 cubes of six tetrahedra, are enclosed by gamma_f with gamma_s's area (to 1e-9),
/// in adapted meshes that pass `verify_adapted`. Of 959 drawn at random (BENCHMARKS.md), 674
/// failed before the chains were shortest paths and the cells next to the edges were cut again;
/// now 15, each with an edge no chain could be found for (of 1 000 turned by at most 0.2 radians,
/// 481 before, none now). This test failed before.
#[test]
fn turned_3d_blocks_are_enclosed_with_their_edges_and_corners() {
    use fdfsi::fem::adapt::{adapt_with, remove_enclosed, verify_adapted, AdaptOptions, Background};
    let fluid = fdfsi::fem::generate::box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 10, 10, 10);
    let bg = Background::new(&fluid).unwrap();
    let golden = 2.399_963_229_728_653; // radians: the axes spread over the sphere
    for k in 0..40 {
        let kf = k as f64;
        let size = [0.15 + 0.3 * (0.37 * kf).fract(), 0.15 + 0.3 * (0.61 * kf).fract(), 0.15 + 0.3 * (0.83 * kf).fract()];
        let height = 1.0 - 2.0 * (kf + 0.5) / 40.0;
        let axis = [(1.0 - height * height).sqrt() * (golden * kf).cos(), (1.0 - height * height).sqrt() * (golden * kf).sin(), height];
        let angle = std::f64::consts::PI * (0.29 * kf + 0.1).fract();
        let centre = [0.45 + 0.1 * (0.53 * kf).fract(), 0.45 + 0.1 * (0.71 * kf).fract(), 0.45 + 0.1 * (0.97 * kf).fract()];
        let surface = turned_block_3d(size, axis, angle, centre);
        let label = format!("block {k}: {size:?} turned by {angle} about {axis:?} at {centre:?}");
        let adapted = adapt_with(&bg, &surface, &AdaptOptions::new(0.2)).unwrap();
        verify_adapted(&fluid, &adapted, &surface).unwrap_or_else(|e| panic!("{label}: {e}"));
        let ratio = adapted.gamma_f_measure() / surface.measure();
        assert!((ratio - 1.0).abs() < 1e-9, "{label}: gamma_f / gamma_s = {ratio} ({:?})", adapted.stats);
        let removed = remove_enclosed(adapted, &surface).unwrap_or_else(|e| panic!("{label}: {e}"));
        assert!(removed.stats.removed_cells > 0 && removed.stats.cells_by_side == 0, "{label}: {:?}", removed.stats);
    }
}

/// The shortest edge of gamma_f and its measure: cases/valve-3d-sector.toml's fluid mesh adapted
/// (with the case's options) to a saved gamma_s of its leaflet.
fn valve_gamma_f(gamma_s: &str) -> (f64, [f64; 3], f64) {
    use fdfsi::fem::adapt::{adapt_with, Background};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let case = Case::read(&root.join("cases/valve-3d-sector.toml")).unwrap();
    let options = fdfsi::setup::adapt_options(case.first_solid().unwrap());
    let fdfsi::fem::gmsh::AnyMesh::D3(fluid) = fdfsi::fem::gmsh::read_msh(&root.join("meshes/valve-3d-sector-fluid.msh")).unwrap() else {
        panic!("the valve's fluid mesh is 3D")
    };
    let surface = saved_gamma_s::<3>(gamma_s);
    let adapted = adapt_with(&Background::new(&fluid).unwrap(), &surface, &options).unwrap();
    let points = &adapted.mesh.points;
    let length = |a: usize, b: usize| (0..3).map(|d| (points[a][d] - points[b][d]).powi(2)).sum::<f64>().sqrt();
    let (shortest, at) = adapted
        .gamma_f
        .iter()
        .flat_map(|f| [(0, 1), (1, 2), (2, 0)].map(|(i, j)| (length(f.vertices[i], f.vertices[j]), points[f.vertices[i]])))
        .fold((f64::INFINITY, [0.0; 3]), |m, e| if e.0 < m.0 { e } else { m });
    let measure = adapted.gamma_f_measure();
    println!("{gamma_s}: shortest gamma_f edge {shortest:.4} mm at {at:?}; gamma_f {measure:.4} mm^2; {:?}", adapted.stats);
    (shortest, at, measure)
}

/// cases/valve-3d-sector.toml's fluid mesh adapted to its soft leaflet (G = 0.3 MPa) where it
/// first closes (step 282 of the run from rest; gamma_s saved by `fdfsi adapt --at`). The passes
/// that cut the edges still crossing gamma_s next to the feature lines put a node 0.038 mm from a
/// gamma_f vertex on the leaflet's face, near the middle of its free edge: an edge from that
/// vertex, leaving the faceted face at a slant, crossed it back there. Its needle facet (edges
/// 1.32, 1.33 and 0.038 mm) and the sliver cell beside it took multipliers and pressure gradients
/// Newton could not control, at every step length down to dt / 64. Such a crossing of the
/// vertex's own face is dropped now (a crossing of the other face of a block's edge is still cut:
/// [`turned_3d_blocks_are_enclosed_with_their_edges_and_corners`]). Measured: shortest gamma_f
/// edge 0.125 mm (at the root's wall; 0.038 before), held at 0.1 mm; gamma_f 179.491 mm^2 against
/// 179.630 before, held within 1e-3 (relative) of the latter: the 0.077 % less is one facet
/// (0.14 mm^2) with a vertex 0.16 mm from a boundary vertex taken to lie on gamma_s, at the
/// plane of coaptation (the rule of the next test).
#[test]
fn the_valve_leaflet_at_its_closure_leaves_no_needle_facet_on_gamma_f() {
    let (shortest, at, measure) = valve_gamma_f("valve-3d-sector-gamma-s-step282.csv");
    assert!(shortest > 0.1, "a needle facet on gamma_f: an edge of {shortest} mm at {at:?}");
    assert!((measure / 179.6299 - 1.0).abs() < 1e-3, "gamma_f {measure} mm^2");
}

/// The same two steps later (step 284), the leaflet on its plane of coaptation (y = 0), 0.03 mm
/// above a fluid vertex of the plane at (1.73, 0, 14.98). That vertex, which may not leave the
/// plane, is taken to lie on gamma_s (`boundary_cuts = "touch"`), and step 2 drops the cuts of
/// its edges within `eps_hat`; but the passes that cut the edges still crossing gamma_s next to
/// a feature line cut its children's edges 0.03-0.07 mm from it: five gamma_f vertices within
/// 0.07 mm, gamma_f edges of 0.017 mm, cells of quality 6e-4, and the multiplier there swinging
/// by 1e6-1e7 Pa from one Newton iteration to the next (the step failed in sub-steps of dt / 64).
/// Those crossings within `TOUCH_FRACTION * eps_hat` of such a vertex (the distance within which
/// it is taken to touch gamma_s) are dropped now. Measured: shortest gamma_f edge 0.117 mm (0.017
/// before), worst cell quality 8.5e-3 (5.8e-4), 1 crossing cut (7); held at 0.1 mm.
#[test]
fn the_valve_leaflet_on_its_plane_leaves_no_cluster_of_nodes_on_gamma_f() {
    let (shortest, at, _) = valve_gamma_f("valve-3d-sector-gamma-s-step284.csv");
    assert!(shortest > 0.1, "a cluster of gamma_f vertices: an edge of {shortest} mm at {at:?}");
}

/// [`block_3d`] swinging sideways in its fluid: softer (G = 0.2), with inertia (density 1), its
/// weight and a lateral force (body force [0.25, 0.12, -0.1]), BDF2 with dt = 0.1 to `end`,
/// no step cuts (a step that fails fails the run). Its sides shear and bend: gamma_s has curved
/// faces and edges that move through the fluid cells, adapted every step with the covered cells
/// removed.
fn swinging_block_3d(n: usize, end: f64) -> String {
    let text = block_3d(n)
        .replace("shear_modulus = 1.0", "shear_modulus = 0.2\ndensity = 1.0")
        .replace("body_force = [0.0, 0.0, -0.3]", "body_force = [0.25, 0.12, -0.1]")
        .replace("dt = 1.0\nend = 6.0\nscheme = \"euler\"", &format!("dt = 0.1\nend = {end}\nscheme = \"bdf2\"\nmax_cuts = 0\noutput_every = 1000"));
    assert!(["shear_modulus = 0.2", "[0.25, 0.12, -0.1]", "dt = 0.1"].iter().all(|t| text.contains(t)), "{text}");
    text
}

/// The first steps of [`swinging_block_3d`] on 6^3 cubes: every step adapts, encloses the block
/// (else the run fails) and converges; the top corner moves sideways.
#[test]
fn a_3d_block_starts_swinging_in_fluid() {
    let s = run(&swinging_block_3d(6, 0.6), "swing3d");
    assert_eq!(s.steps, 6);
    assert!(q(&s, "ux_corner") > 1e-3, "ux_corner {}", q(&s, "ux_corner"));
}

/// [`swinging_block_3d`] on 8^3 cubes to t = 5 (50 steps; about 9 s each), no step cuts: the
/// block sways to and fro (its top corner 0.14 sideways), its faces sheared and curved; every
/// step's gamma_f encloses it. It stopped at step 3 before the feature lines' kinks, at step 18
/// before the smooth parts told a chord of a curved face from one across an edge, at step 26
/// before a cell along one face with vertices on the block's edge was flat, at step 38 before a
/// thin cell along a curved face was, and at step 49 before a sliver along an edge line was
/// refused as a facet (the saved surfaces of [`a_swung_3d_block_with_curved_faces_is_enclosed`];
/// those runs halved failed steps); without step cuts it stopped at step 6 until the cells were
/// told by their side of gamma_s where the facet rules leave a hole
/// ([`a_hole_the_facet_rules_leave_is_closed_by_the_sides_of_gamma_s`]).
#[test]
#[ignore = "about 8 minutes: run with --ignored"]
fn a_3d_block_swinging_in_fluid_is_enclosed_at_every_step() {
    let s = run(&swinging_block_3d(8, 5.0), "swing3d-long");
    assert!(s.steps >= 50);
    assert!(q(&s, "ux_corner").abs() > 1e-2, "ux_corner {}", q(&s, "ux_corner"));
}

/// The block of [`block_3d`] on 8^3 cubes swung sideways in fluid (the ignored
/// [`a_3d_block_swinging_in_fluid_is_enclosed_at_every_step`]), its gamma_s saved in `tests/data`
/// at the two times where that run stopped ("gamma_f does not enclose the solid"):
/// - t = 1.8, at the floor beside the face leaning out. The sheared faces are curved (their
///   normals turn by 13 degrees within a cell height above the floor), and a triangle of fluid
///   vertices on one face, a chord from the floor to the face's edge, was refused as spanning an
///   edge: a vertex lay 12 % of its diameter off the plane of the piece at its centroid (the
///   limit is 10 %). Where gamma_s has feature lines, that is now told by the smooth parts alone.
/// - t = 2.6, where a face had come near a plane of the grid: cells with all four vertices on
///   that face, two of them on the block's edge, were not taken as flat (a cell with a vertex on
///   an edge was taken to fill the wedge), and gamma_f had facets on both their sides. A cell is
///   now flat when its vertices share a smooth part.
/// - t = 3.8, at the floor again: a thin cell with its four vertices along the curved face (from
///   the floor to a cell height) was not flat by the plane test, and gamma_f had facets on both
///   its sides. With feature lines a cell is now flat when its centroid is as near gamma_s as a
///   gamma_f facet's must be.
/// - t = 4.9, at the foot of a vertical edge: a vertex moved onto the bent edge line beside a
///   chain edge (a chord of the line) made a sliver triangle with it, all three vertices on the
///   line; it passed as a facet, and the edge of gamma_f had three facets. A facet whose
///   vertices share two smooth parts (all on one line) is no longer on gamma_f.
///
/// gamma_f (chords of the curved faces) has 99.79, 99.99, 99.75 and 99.66 % of gamma_s's area
/// (held at 0.5 %).
#[test]
fn a_swung_3d_block_with_curved_faces_is_enclosed() {
    use fdfsi::fem::adapt::{adapt_with, remove_enclosed, verify_adapted, AdaptOptions, Background};
    let fluid = fdfsi::fem::generate::box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 8, 8, 8);
    let bg = Background::new(&fluid).unwrap();
    for data in
        ["block-3d-swung-gamma-s-t1.8.csv", "block-3d-swung-gamma-s-t2.6.csv", "block-3d-swung-gamma-s-t3.8.csv", "block-3d-swung-gamma-s-t4.9.csv"]
    {
        let surface = saved_gamma_s::<3>(data);
        let adapted = adapt_with(&bg, &surface, &AdaptOptions::new(0.2)).unwrap();
        verify_adapted(&fluid, &adapted, &surface).unwrap_or_else(|e| panic!("{data}: {e}"));
        let ratio = adapted.gamma_f_measure() / surface.measure();
        assert!((ratio - 1.0).abs() < 5e-3, "{data}: gamma_f / gamma_s = {ratio}");
        let removed = remove_enclosed(adapted, &surface).unwrap_or_else(|e| panic!("{data}: {e}"));
        assert!(
            removed.stats.removed_cells > 0 && removed.stats.feature_kinks > 0 && removed.stats.cells_by_side == 0,
            "{data}: {:?}",
            removed.stats
        );
    }
}

/// The swung block of [`a_swung_3d_block_with_curved_faces_is_enclosed`] at t = 0.6, where the
/// run without step cuts stopped: on the top edge a node of the top face (0.00023 off the edge
/// line) and one of the side face lie 2.5e-4 apart, and the sliver cell between them has no
/// facet that passes the gamma_f rule (its facets across the edge share no smooth part), so
/// the facet rules leave a hole. The mesh follows gamma_s there all the same: the removal tells
/// the cells by their side of gamma_s and rebuilds gamma_f between them. gamma_f then has
/// gamma_s's area (chords: measured 99.98 %, held at 0.5 %), and the fluid left and the
/// solid fill the box (the solid's volume from gamma_s, its floor at z = 0 adding nothing to
/// `(1/3) int x . n`: measured to 7.0e-5, held at 5e-4).
#[test]
fn a_hole_the_facet_rules_leave_is_closed_by_the_sides_of_gamma_s() {
    use fdfsi::fem::adapt::{adapt_with, remove_enclosed, verify_adapted, AdaptOptions, Background};
    let fluid = fdfsi::fem::generate::box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 8, 8, 8);
    let surface = saved_gamma_s::<3>("block-3d-swung-gamma-s-t0.6.csv");
    let adapted = adapt_with(&Background::new(&fluid).unwrap(), &surface, &AdaptOptions::new(0.2)).unwrap();
    verify_adapted(&fluid, &adapted, &surface).unwrap();
    let removed = remove_enclosed(adapted, &surface).unwrap();
    assert!(removed.stats.cells_by_side > 0, "{:?}", removed.stats);
    removed.mesh.check().unwrap();
    let ratio = removed.gamma_f_measure() / surface.measure();
    let solid_volume: f64 = (0..surface.num_pieces())
        .map(|i| {
            let c = surface.corners(i);
            let (u, v) = ([0, 1, 2].map(|d| c[1][d] - c[0][d]), [0, 1, 2].map(|d| c[2][d] - c[0][d]));
            let area_normal = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
            (0..3).map(|d| (c[0][d] + c[1][d] + c[2][d]) / 3.0 * area_normal[d] / 2.0).sum::<f64>() / 3.0
        })
        .sum();
    let fluid_volume: f64 = (0..removed.mesh.num_cells()).map(|c| removed.mesh.signed_vertex_measure(c)).sum();
    println!("gamma_f / gamma_s = {ratio}, fluid + solid = {} (solid {solid_volume})", fluid_volume + solid_volume);
    assert!((ratio - 1.0).abs() < 5e-3, "gamma_f / gamma_s = {ratio}");
    assert!((fluid_volume + solid_volume - 1.0).abs() < 5e-4, "fluid {fluid_volume} + solid {solid_volume}");
}

/// [`a_compressible_solid_enclosed_by_gamma_f_changes_its_area_as_without_fluid`] in 3D: the
/// block in fluid with the covered cells removed settles as alone (measured 3.0e-5 of uz, 2.6e-6
/// in ux: held at 1e-4 and 5e-4 of uz); kept, the fictitious fluid holds its volume: it shortens
/// 23 % less and bulges 390 times as far (measured -7.60e-3 against -9.81e-3, 9.6e-4 against
/// -2.5e-6).
#[test]
fn a_compressible_3d_block_enclosed_by_gamma_f_changes_its_volume_as_without_fluid() {
    let text = block_3d(6);
    let solid = &text[text.find("[solid]").unwrap()..text.find("[time]").unwrap()];
    let solid = solid.replace("covered_fluid = \"removed\"\n", "").replace("surface = [\"xmin\", \"xmax\", \"ymin\", \"ymax\", \"zmax\"]\n", "");
    let probes = &text[text.find("[[output.probe]]").unwrap()..];
    let alone = format!(
        "title = \"the 3D block alone\"\n[physics]\nformulation = \"3d\"\n{}{probes}",
        solid.replace("[solid]", "[solid]\nloading = { steps = 1 }")
    );
    let alone = run(&alone, "alone3d");
    let removed = run(&text, "removed3d");
    let kept = run(&text.replace("covered_fluid = \"removed\"", "covered_fluid = \"kept\""), "kept3d");
    let (uz, ux) = (q(&alone, "uz_top"), q(&alone, "ux_corner"));
    for (name, s) in [("removed", &removed), ("kept", &kept)] {
        println!("covered fluid {name}: uz_top {:.6e}, ux_corner {:.6e} (alone {uz:.6e}, {ux:.6e})", q(s, "uz_top"), q(s, "ux_corner"));
    }
    assert!(uz < -9e-3, "the block alone shortens: {uz}");
    assert!((q(&removed, "uz_top") - uz).abs() < 1e-4 * uz.abs());
    assert!((q(&removed, "ux_corner") - ux).abs() < 5e-4 * uz.abs());
    assert!(q(&kept, "uz_top") > 0.85 * uz, "kept: {}", q(&kept, "uz_top"));
    assert!(q(&kept, "ux_corner") > 0.05 * uz.abs(), "kept: {}", q(&kept, "ux_corner"));
}

/// The fluid's force on a solid computed two ways agrees at every step, with either scheme: from
/// the multiplier (`coupling_force_*`) and by the consistent residual method on gamma_f from the
/// fluid side (`kind = "force"`), whose inertia term must be the one the step solved, `a (u -
/// u*)`, BDF2's `a = 1.5 / dt` included (`1 / dt` was used: 1.4 % off in BDF2 steps here, and
/// the Turek-Hron FSI2/FSI3 cylinder forces were off by as much). The block of [`BLOCK`], lifted
/// off the floor and coupled on its whole boundary (no wall touches gamma_f, whose nodes would
/// carry the wall's reaction), falls under its weight; measured 8.9e-13 (Euler) and 1.9e-12
/// (BDF2) of a force of 0.05, held at 1e-9.
#[test]
fn the_fluid_side_force_on_gamma_f_is_the_multipliers_at_every_step() {
    for scheme in ["euler", "bdf2"] {
        let text = BLOCK
            .replace("body_force = [0.0, -0.3]", "body_force = [0.0, -0.3]\ndensity = 1.0")
            .replace("dt = 1.0", "dt = 0.025")
            .replace("end = 6.0", "end = 0.5\noutput_every = 100000")
            .replace("scheme = \"euler\"", &format!("scheme = \"{scheme}\""))
            .replace("y = [0.0, 0.4], n = [2, 2] }", "y = [0.3, 0.7], n = [2, 2] }")
            .replace("surface = [\"left\", \"top\", \"right\"]", "surface = [\"left\", \"top\", \"right\", \"bottom\"]")
            .replace("[[solid.boundary]]\nname = \"bottom\"\ntype = \"displacement\"\nvalue = [0.0, 0.0]\n", "")
            + "[[output.boundary_integral]]\nname = \"fx\"\nboundary = \"gamma_f\"\nkind = \"force\"\ncomponent = 0\n"
            + "[[output.boundary_integral]]\nname = \"fy\"\nboundary = \"gamma_f\"\nkind = \"force\"\ncomponent = 1\n";
        let tag = format!("falling-{scheme}");
        run(&text, &tag);
        let out = std::env::temp_dir().join(format!("fdfsi-test-thick-{tag}-{}", std::process::id()));
        let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
        let mut lines = history.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
        let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
        let scale = rows.iter().map(|r| r[col("coupling_force_y")].abs()).fold(0.0, f64::max);
        let worst = rows
            .iter()
            .flat_map(|r| [(r[col("fx")] - r[col("coupling_force_x")]).abs(), (r[col("fy")] - r[col("coupling_force_y")]).abs()])
            .fold(0.0, f64::max);
        println!("{scheme}: {} steps, the largest difference {worst:.3e}, the largest force {scale:.3e}", rows.len());
        assert!(rows.len() == 20 && scale > 0.01, "{scheme}: {} steps, force {scale}", rows.len());
        assert!(worst < 1e-9 * scale.max(1.0), "{scheme}: fluid-side force against the multiplier's: {worst:.3e} (force {scale:.3e})");
    }
}

/// The fluid velocity of `t_n` on the next step's mesh where the solid uncovered fluid (issue 15,
/// FSI2 on the second mesh level: the bar's tip uncovers more than a cell in a step). The block
/// of [`BLOCK`] slid 0.25 to the right in one step (2.5 cells of the fluid mesh): the new
/// velocity nodes in the block's old place lie in the hole of the old adapted mesh (its covered
/// cells were removed). Up to a cell height beyond an old cell's facets (the cell scaled by 4
/// about its centroid: up to 0.2 into the hole here) they take the old fluid velocity's
/// extension (0 here, as everywhere outside the hole), farther in the solid's velocity at the
/// nearest point of the hole's boundary (the block's left, top and right sides), a rigid
/// rotation's here (affine: the Q2 interpolation is exact).
#[test]
fn fluid_the_solid_uncovered_in_a_step_takes_the_solids_velocity() {
    use fdfsi::discretize::fsi::{CouplingPattern, FluidRestart, FsiDiscretization, FsiRestart, FsiState, StepStart};
    let case = Case::from_toml_str(BLOCK, "block").unwrap();
    let dir = std::env::temp_dir();
    let fdfsi::fem::gmsh::AnyMesh::D2(fluid_mesh) = fdfsi::setup::build_mesh(&case, &dir).unwrap() else { panic!("a 2D mesh") };
    let model = fdfsi::setup::fsi_model(&case, &fluid_mesh, &dir).unwrap();
    let n = model.solid.num_dofs();
    let at_rest = vec![0.0; n];
    let old = FsiDiscretization::build(&model, &at_rest, &CouplingPattern::default()).unwrap();
    let slide = 0.25;
    // The solid's velocity at a point of its old place: a rigid rotation about (0.5, 0.2).
    let v_solid = |x: &[f64; 2]| [0.6 - 0.5 * (x[1] - 0.2), -0.1 + 0.5 * (x[0] - 0.5)];
    let vf = model.solid.displacement_field();
    let (mut solid_x, mut solid_v) = (vec![0.0; n], vec![0.0; n]);
    for (node, x0) in model.solid.nodes_x0.iter().enumerate() {
        solid_x[vf.dof(node, 0)] = slide;
        for (k, v) in v_solid(x0).iter().enumerate() {
            solid_v[vf.dof(node, k)] = *v;
        }
    }
    // The nearest points of the old block's sides x = 0.3, y = 0.4, x = 0.7 (gamma_s; two where
    // the sides are as near).
    let nearest_side_points = |x: [f64; 2]| -> Vec<[f64; 2]> {
        let on_sides = [[0.3, x[1].min(0.4)], [x[0].clamp(0.3, 0.7), 0.4], [0.7, x[1].min(0.4)]];
        let d = |p: &[f64; 2]| (p[0] - x[0]).hypot(p[1] - x[1]);
        let least = on_sides.iter().map(d).fold(f64::INFINITY, f64::min);
        on_sides.into_iter().filter(|p| d(p) < least + 1e-12).collect()
    };
    let restart = FsiRestart {
        solid_x,
        solid_f: FsiState::at_rest(&model).solid_f,
        solid_v,
        fluid: Some(FluidRestart {
            solid_base: at_rest,
            velocity: vec![0.0; old.flow.velocity_field().num_dofs()],
            lumped: vec![],
            pressure: vec![],
        }),
        coupling_pattern: CouplingPattern::default(),
        previous: None,
        dt: 0.1,
    };
    let state = FsiState::from_restart(&model, 1.0, &restart).unwrap();
    let start = StepStart::new(&model, &state, 0.1).unwrap();
    let u = &start.u_old[start.disc.flow.velocity_field().range()];
    // Distance of a point of the old block ([0.3, 0.7] x [0, 0.4]) from the old fluid.
    let depth_in_old_block = |x: &[f64; 2]| (x[0] - 0.3).min(0.7 - x[0]).min(0.4 - x[1]);
    let mut solids = 0;
    for (i, x) in start.disc.flow.velocity_nodes.iter().enumerate() {
        let ui = [u[2 * i], u[2 * i + 1]];
        let is = |v: [f64; 2]| (0..2).all(|k| (ui[k] - v[k]).abs() < 1e-12);
        let depth = depth_in_old_block(x);
        if nearest_side_points(*x).iter().any(|p| is(v_solid(p))) {
            solids += 1;
            assert!(depth > 0.0, "node {i} at {x:?}, outside the old block, has the solid's velocity");
        } else {
            assert!(is([0.0, 0.0]) && depth < 0.2, "node {i} at {x:?}, {depth:.3} into the old block: u = {ui:?}");
        }
    }
    assert!(solids > 4, "{solids} nodes with the solid's velocity");
}
