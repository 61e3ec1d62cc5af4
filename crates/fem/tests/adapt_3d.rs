//! 3D adaptation of box tetrahedra to random planes, curved patches (spheres, cylinders),
//! folded surfaces and degenerate placements: every adapted mesh passes `verify_adapted`
//! (positive, conforming, volume kept, gamma_f on gamma_s), and a plane crossing the whole box
//! gives a gamma_f whose area is that of the plane's section of the box.
//!
//! Deterministic: a seeded SplitMix64 generator.

use fdfsi_fem::adapt::{adapt, verify_adapted, Adapted, Surface};
use fdfsi_fem::generate::box_tetrahedra;
use fdfsi_fem::mesh::Mesh;

struct Rng(u64);
impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    fn unit(&mut self) -> [f64; 3] {
        loop {
            let v = [self.uniform(-1.0, 1.0), self.uniform(-1.0, 1.0), self.uniform(-1.0, 1.0)];
            let l = dot(&v, &v).sqrt();
            if l > 0.1 && l < 1.0 {
                return v.map(|x| x / l);
            }
        }
    }
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn random_box(rng: &mut Rng) -> Mesh<3> {
    let n = [2 + rng.below(5), 2 + rng.below(5), 2 + rng.below(5)];
    box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n[0], n[1], n[2])
}

fn run(mesh: &Mesh<3>, s: &Surface<3>, eps_hat: f64, what: &str) -> Adapted<3> {
    let a = adapt(mesh, s, eps_hat).unwrap_or_else(|e| panic!("{what}: {e}"));
    if let Err(e) = verify_adapted(mesh, &a, s) {
        panic!("{what}: {e}\nstats {:?}", a.stats);
    }
    a
}

/// A grid of `n x n` quads (2 triangles each) of the map `(u, v) -> f(u, v)` over `[0, 1]^2`.
fn patch(n: usize, f: impl Fn(f64, f64) -> [f64; 3]) -> Surface<3> {
    let mut pts = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            pts.push(f(i as f64 / n as f64, j as f64 / n as f64));
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Surface::from_pieces(pts, tris).unwrap()
}

/// The plane through `p` with unit normal `n`, as a large square of 2 triangles.
fn plane(p: [f64; 3], n: [f64; 3]) -> Surface<3> {
    let a = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let t1 = cross(&n, &a);
    let l = dot(&t1, &t1).sqrt();
    let t1 = t1.map(|x| x / l);
    let t2 = cross(&n, &t1);
    patch(1, |u, v| std::array::from_fn(|d| p[d] + 4.0 * (u - 0.5) * t1[d] + 4.0 * (v - 0.5) * t2[d]))
}

/// Area of the section of the unit box by the plane `n . x = n . p`.
fn section_area(p: [f64; 3], n: [f64; 3]) -> f64 {
    let c = dot(&n, &p);
    let corner = |k: usize| [(k & 1) as f64, ((k >> 1) & 1) as f64, ((k >> 2) & 1) as f64];
    let mut pts: Vec<[f64; 3]> = Vec::new();
    for a in 0..8 {
        for d in 0..3 {
            let b = a | (1 << d);
            if b == a {
                continue;
            }
            let (pa, pb) = (corner(a), corner(b));
            let (fa, fb) = (dot(&n, &pa) - c, dot(&n, &pb) - c);
            if (fa < 0.0) != (fb < 0.0) {
                let t = fa / (fa - fb);
                pts.push(std::array::from_fn(|k| pa[k] + t * (pb[k] - pa[k])));
            }
        }
    }
    let m: [f64; 3] = std::array::from_fn(|k| pts.iter().map(|q| q[k]).sum::<f64>() / pts.len() as f64);
    let a = if n[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let t1 = cross(&n, &a);
    let t2 = cross(&n, &t1);
    let ang = |q: &[f64; 3]| {
        let r = [q[0] - m[0], q[1] - m[1], q[2] - m[2]];
        dot(&r, &t2).atan2(dot(&r, &t1))
    };
    pts.sort_by(|x, y| ang(x).total_cmp(&ang(y)));
    let mut area = 0.0;
    for i in 0..pts.len() {
        let (x, y) = (pts[i], pts[(i + 1) % pts.len()]);
        let cr = cross(&[x[0] - m[0], x[1] - m[1], x[2] - m[2]], &[y[0] - m[0], y[1] - m[1], y[2] - m[2]]);
        area += 0.5 * dot(&cr, &cr).sqrt();
    }
    area
}

#[test]
fn adapt_planes_crossing_the_box() {
    let mut rng = Rng(11);
    let mut tot = [0usize; 5];
    for case in 0..600 {
        let mesh = random_box(&mut rng);
        let p = [rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9)];
        let n = rng.unit();
        let s = plane(p, n);
        let a = run(&mesh, &s, [0.1, 0.2, 0.3, 0.5][case % 4], &format!("plane case {case}"));
        let want = section_area(p, n);
        let got = a.gamma_f_measure();
        assert!((got - want).abs() <= 1e-12 * want, "plane case {case}: gamma_f {got} vs section {want}, {:?}", a.stats);
        tot[0] += a.stats.moved_nodes;
        tot[1] += a.stats.new_nodes;
        tot[2] += a.stats.refused_moves;
        tot[3] += a.stats.degenerate_cases;
        tot[4] += a.stats.refused_boundary;
    }
    println!("planes: moved {} new {} refused {} (boundary {}) degenerate {}", tot[0], tot[1], tot[2], tot[4], tot[3]);
}

#[test]
fn adapt_curved_patches_spheres_and_cylinders() {
    let mut rng = Rng(12);
    for case in 0..400 {
        let mesh = random_box(&mut rng);
        let c = [rng.uniform(-0.3, 1.3), rng.uniform(-0.3, 1.3), rng.uniform(-0.3, 1.3)];
        let r = rng.uniform(0.2, 1.0);
        let (t0, t1) = (rng.uniform(0.0, 1.5), rng.uniform(1.6, 3.1));
        let (p0, p1) = (rng.uniform(0.0, 3.0), rng.uniform(3.2, 6.2));
        let n = 4 + rng.below(12);
        let s = if case % 2 == 0 {
            patch(n, |u, v| {
                let (th, ph) = (t0 + (t1 - t0) * u, p0 + (p1 - p0) * v);
                [c[0] + r * th.sin() * ph.cos(), c[1] + r * th.sin() * ph.sin(), c[2] + r * th.cos()]
            })
        } else {
            patch(n, |u, v| {
                let ph = p0 + (p1 - p0) * u;
                [c[0] + r * ph.cos(), c[1] + r * ph.sin(), -0.5 + 2.0 * v]
            })
        };
        run(&mesh, &s, [0.1, 0.2, 0.35][case % 3], &format!("curved case {case}"));
    }
}

#[test]
fn adapt_folded_height_fields() {
    let mut rng = Rng(13);
    for case in 0..200 {
        let mesh = random_box(&mut rng);
        let n = 3 + rng.below(8);
        let z: Vec<f64> = (0..(n + 1) * (n + 1)).map(|_| rng.uniform(0.0, 1.0)).collect();
        let s = patch(n, |u, v| {
            let (i, j) = ((u * n as f64).round() as usize, (v * n as f64).round() as usize);
            [-0.2 + 1.4 * u, -0.2 + 1.4 * v, z[j * (n + 1) + i]]
        });
        run(&mesh, &s, 0.2, &format!("folded case {case}"));
    }
}

#[test]
fn adapt_degenerate_placements() {
    let mut rng = Rng(14);
    let mut touched = 0;
    for case in 0..600 {
        let k = 2 + rng.below(4);
        let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, k, k, k);
        let h = 1.0 / k as f64;
        let (i, j, l) = (rng.below(k + 1) as f64 * h, rng.below(k + 1) as f64 * h, rng.below(k + 1) as f64 * h);
        let s = match case % 6 {
            // In grid planes: faces lie in the surface.
            0 => plane([0.5, 0.5, l], [0.0, 0.0, 1.0]),
            1 => plane([i, 0.5, 0.5], [1.0, 0.0, 0.0]),
            // The Kuhn diagonal planes x = y (through edges and faces of every cube).
            2 => plane([0.5, 0.5, 0.5], [0.5f64.sqrt(), -(0.5f64.sqrt()), 0.0]),
            // A fan through a grid vertex at random angles: the vertex is a surface corner.
            3 => {
                let (u, v) = (rng.unit(), rng.unit());
                let w = cross(&u, &v);
                let pts = vec![[i, j, l], [i + u[0], j + u[1], l + u[2]], [i + v[0], j + v[1], l + v[2]], [i + w[0], j + w[1], l + w[2]]];
                Surface::from_pieces(pts, vec![[0, 1, 2], [0, 2, 3]]).unwrap()
            }
            // A small patch ending inside the box, or touching a boundary face.
            4 => {
                let z0 = if rng.below(2) == 0 { 0.0 } else { rng.uniform(0.2, 0.8) };
                patch(3, |u, v| [0.2 + 0.5 * u, 0.3 + 0.4 * v, z0 + 0.3 * u * v])
            }
            // A grid plane offset by round-off: cuts within 1e-14 of vertices.
            _ => plane([0.5, 0.5, l + 1e-15], [1e-14, 0.0, 1.0]),
        };
        let a = run(&mesh, &s, [0.2, 0.5][case % 2], &format!("degenerate case {case}"));
        touched += a.stats.touched_vertices;
        if case % 6 == 0 && l > 0.0 && l < 1.0 {
            assert!((a.gamma_f_measure() - 1.0).abs() < 1e-12, "grid plane case {case}: {}", a.gamma_f_measure());
        }
        if case % 6 == 2 {
            assert!((a.gamma_f_measure() - 2f64.sqrt()).abs() < 1e-12, "diagonal plane case {case}: {}", a.gamma_f_measure());
        }
    }
    assert!(touched > 0);
}

/// A membrane bulging through a plane of mesh nodes (model problem 4 on a pipe with nodes at
/// z = 2): a cap `z = 1.975 + b (1 - x^2 - y^2)` in a quarter pipe of 12 rings and 8 layers.
/// Around the circle where the cap crosses z = 2, the nodes of that plane move a little onto the
/// cap while the edges between them are cut far from their ends. New nodes on those edges made
/// inverted and flat children; undoing the moves put new nodes next to the pinned nodes, whose
/// slivers refused the neighbours' moves in turn (b = 0.086 is model problem 4 at t = 1.8, where
/// this ended with cells of quality 3.6e-6 and a singular system). Dropping the cuts at moved ends
/// instead keeps every cell touching a moved node above the quality threshold.
#[test]
fn a_surface_near_a_plane_of_nodes_leaves_no_slivers() {
    let mesh = fdfsi_fem::generate::pipe_tetrahedra(1.0, 4.0, 12, 8, true);
    let mut dropped = 0;
    for b in [0.03, 0.05, 0.086, 0.1] {
        let cap = patch(24, |x, y| [x, y, 1.975 + b * (1.0 - x * x - y * y)]);
        let a = run(&mesh, &cap, 0.2, &format!("bulge {b}"));
        let st = &a.stats;
        assert!(st.min_quality > 0.01, "bulge {b}: worst cell {:.3e} ({st:?})", st.min_quality);
        // The section's 222 triangles, each one facet or two (a quadrilateral cut).
        assert!((222..=444).contains(&st.coupling_facets) && st.passes <= 3, "bulge {b}: {st:?}");
        dropped += st.cuts_at_moved_ends;
    }
    assert!(dropped > 0, "the bulges cut edges with moved ends");
}

/// With `touch_fixed_boundary`, a plane passing within hundredths of an edge of a vertex inside
/// a face of the box (the plane not parallel to the face, so the vertex may not move onto it)
/// leaves the vertex where it is, on gamma_s as the adapted mesh sees it, instead of adding new
/// nodes next to it: every adapted mesh passes the checks with gamma_f within `eps_hat / 4` of
/// an edge of gamma_s, and the worst cell of all the cases is a thousand times better.
#[test]
fn boundary_vertices_next_to_a_plane_are_touched_when_asked() {
    use fdfsi_fem::adapt::{adapt_with, verify_adapted_within, AdaptOptions, Background};
    let mut rng = Rng(17);
    let (mut touched, mut better, mut worse, mut worst) = (0, 0, 0, [1.0f64; 2]);
    let cases = 200;
    for case in 0..cases {
        let n = [2 + rng.below(4), 2 + rng.below(4), 2 + rng.below(4)];
        let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n[0], n[1], n[2]);
        // A vertex inside the face x = 0, and a plane through a point a small fraction of the
        // shortest edge from it.
        let v = [0.0, (1 + rng.below(n[1] - 1)) as f64 / n[1] as f64, (1 + rng.below(n[2] - 1)) as f64 / n[2] as f64];
        let normal = loop {
            let u = rng.unit();
            if u[0].abs() < 0.9 {
                break u;
            }
        };
        let h = 1.0 / *n.iter().max().unwrap() as f64;
        let d = rng.uniform(1e-4, 0.04) * h;
        let s = plane(std::array::from_fn(|k| v[k] + d * normal[k]), normal);
        let eps_hat = 0.2;
        let bg = Background::new(&mesh).unwrap();
        let what = format!("case {case}: n {n:?}, vertex {v:?}, normal {normal:?}, d {d:.3e}");
        let split = adapt_with(&bg, &s, &AdaptOptions::new(eps_hat)).unwrap_or_else(|e| panic!("{what}: {e}"));
        verify_adapted(&mesh, &split, &s).unwrap_or_else(|e| panic!("{what} (split): {e}"));
        let touch =
            adapt_with(&bg, &s, &AdaptOptions { touch_fixed_boundary: true, ..AdaptOptions::new(eps_hat) }).unwrap_or_else(|e| panic!("{what}: {e}"));
        // The longest edge of the box's tetrahedra: the diagonal of a cell.
        let longest = (0..3).map(|k| (1.0 / n[k] as f64).powi(2)).sum::<f64>().sqrt();
        verify_adapted_within(&mesh, &touch, &s, eps_hat / 4.0 * longest + 1e-12).unwrap_or_else(|e| panic!("{what} (touch): {e}"));
        assert_eq!(split.stats.boundary_touches, 0, "{what}");
        // No new node beside a touched vertex: its cuts within eps_hat of an edge were dropped.
        let shortest = 1.0 / *n.iter().max().unwrap() as f64;
        let nv = mesh.points.len();
        let on_face = |p: &[f64; 3]| p.iter().any(|&c| c.abs() < 1e-12 || (c - 1.0).abs() < 1e-12);
        let off = |p: &[f64; 3]| (0..3).map(|k| (p[k] - v[k] - d * normal[k]) * normal[k]).sum::<f64>().abs() > 1e-12;
        for t in (0..nv).filter(|&t| touch.on_surface[t] && on_face(&touch.mesh.points[t]) && off(&touch.mesh.points[t])) {
            let x = touch.mesh.points[t];
            for (k, y) in touch.mesh.points[nv..].iter().enumerate() {
                let r = (0..3).map(|c| (x[c] - y[c]).powi(2)).sum::<f64>().sqrt();
                assert!(r >= 0.99 * eps_hat * shortest, "{what}: new node {} at {r:.3e} from the touched vertex {t}", nv + k);
            }
        }
        touched += (touch.stats.boundary_touches > 0) as usize;
        better += (touch.stats.min_quality > 2.0 * split.stats.min_quality) as usize;
        worse += (touch.stats.min_quality < split.stats.min_quality) as usize;
        worst = [worst[0].min(split.stats.min_quality), worst[1].min(touch.stats.min_quality)];
    }
    println!("boundary touches in {touched} of {cases} cases; the worst cell more than twice as good in {better}, worse in {worse}; worst of all {worst:?}");
    // Measured: touches in 97 of 200 cases, the worst cell of all 1.0e-6 with new nodes and
    // 2.1e-3 with touches, worse in 4 cases (a little: the vertex's other cells).
    assert!(touched >= 2 * cases / 5, "touches in only {touched} of {cases} cases");
    assert!(better >= cases / 10, "the worst cell twice as good in only {better} of {cases} cases");
    assert!(worst[0] < 1e-5 && worst[1] > 1000.0 * worst[0], "the worst cells of all, with new nodes and with touches: {worst:?}");
    assert!(worse <= cases / 20, "touches made the worst cell worse in {worse} of {cases} cases");
}

/// A surface lying within hundredths of an edge of a plane of nodes, tilted and curved a little
/// (a valve leaflet pressed on its plane of coaptation): it cuts the plane's edges at grazing
/// angles, and new nodes there, nearly in line with a moved node, make needle cells. With
/// `min_cut_quality` those cuts are dropped (no move refused for them): every adapted mesh
/// passes the checks, and the worst cell is never worse and sometimes better. Measured: 11 more
/// cuts dropped in 120 cases, the worst cell better in 5 and worse in none; the worst of all
/// 0.041 without, 0.051 with.
#[test]
fn cuts_beside_moved_nodes_are_dropped_below_min_cut_quality() {
    use fdfsi_fem::adapt::{adapt_with, AdaptOptions, Background};
    let mut rng = Rng(29);
    let (mut better, mut worse, mut dropped, mut worst) = (0, 0, 0, [1.0f64; 2]);
    let cases = 120;
    for case in 0..cases {
        let n = 3 + rng.below(3);
        let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n, n, n);
        let h = 1.0 / n as f64;
        let z0 = (1 + rng.below(n - 1)) as f64 * h;
        let (a, b, c) = (rng.uniform(-0.03, 0.03) * h, rng.uniform(-0.03, 0.03) * h, rng.uniform(0.0, 0.05) * h);
        let s = patch(16, |x, y| [1.2 * x - 0.1, 1.2 * y - 0.1, z0 + a * x + b * y + c * ((x - 0.5).powi(2) + (y - 0.5).powi(2))]);
        let what = format!("case {case}: n {n}, z0 {z0}, tilt {a:.2e} {b:.2e}, bulge {c:.2e}");
        let bg = Background::new(&mesh).unwrap();
        let plain = AdaptOptions::new(0.2);
        let base = adapt_with(&bg, &s, &plain).unwrap_or_else(|e| panic!("{what}: {e}"));
        let cut = adapt_with(&bg, &s, &AdaptOptions { min_cut_quality: 0.05, ..plain }).unwrap_or_else(|e| panic!("{what}: {e}"));
        verify_adapted(&mesh, &base, &s).unwrap_or_else(|e| panic!("{what} (plain): {e}"));
        verify_adapted(&mesh, &cut, &s).unwrap_or_else(|e| panic!("{what} (min_cut_quality): {e}"));
        let (q0, q1) = (base.stats.min_quality, cut.stats.min_quality);
        better += (q1 > 1.5 * q0) as usize;
        worse += (q1 < q0) as usize;
        dropped += cut.stats.cuts_at_moved_ends as i64 - base.stats.cuts_at_moved_ends as i64;
        worst = [worst[0].min(q0), worst[1].min(q1)];
    }
    println!("min_cut_quality 0.05: {dropped} more cuts dropped; the worst cell better in {better} of {cases} cases, worse in {worse}; worst of all {worst:?}");
    assert!(dropped > 0 && better > 0, "no cut dropped or no cell bettered: {dropped}, {better}");
    assert_eq!(worse, 0, "the worst cell worse in {worse} cases");
    assert!(worst[1] > worst[0], "the worst cell of all: {worst:?}");
}

/// The distance from `p` to the triangle `t` (Ericson, Real-Time Collision Detection, 5.1.5).
fn distance_to_triangle(p: &[f64; 3], t: &[[f64; 3]; 3]) -> f64 {
    let sub = |a: &[f64; 3], b: &[f64; 3]| -> [f64; 3] { std::array::from_fn(|k| a[k] - b[k]) };
    let [a, b, c] = t;
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let at = |s: f64, t: f64| -> [f64; 3] { std::array::from_fn(|k| a[k] + s * ab[k] + t * ac[k]) };
    let closest = {
        let (d1, d2) = (dot(&ab, &ap), dot(&ac, &ap));
        let bp = sub(p, b);
        let (d3, d4) = (dot(&ab, &bp), dot(&ac, &bp));
        let cp = sub(p, c);
        let (d5, d6) = (dot(&ab, &cp), dot(&ac, &cp));
        let (va, vb, vc) = (d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2);
        if d1 <= 0.0 && d2 <= 0.0 {
            *a
        } else if d3 >= 0.0 && d4 <= d3 {
            *b
        } else if d6 >= 0.0 && d5 <= d6 {
            *c
        } else if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            at(d1 / (d1 - d3), 0.0)
        } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            at(0.0, d2 / (d2 - d6))
        } else if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            std::array::from_fn(|k| b[k] + w * (c[k] - b[k]))
        } else {
            let denom = 1.0 / (va + vb + vc);
            at(vb * denom, vc * denom)
        }
    };
    let d = sub(p, &closest);
    dot(&d, &d).sqrt()
}

/// gamma_f covers a curved gamma_s that crosses the box: every point of a cylinder or sphere
/// patch (radius at least twice the longest edge of the box's cells, so that a chord of a cell's
/// facet lies within the gamma_f rule's distance of it) inside the box, away from the box's faces
/// and the patch's rim, lies within an eighth of the longest edge of a gamma_f facet. Facets whose
/// vertices are all on gamma_s, their centroid near it, but not within the tolerance of the plane
/// of the piece nearest the centroid (a chord over pieces that turn) were once refused, and left
/// holes a facet wide (the 3D valve's leaflet, session 33).
#[test]
fn gamma_f_covers_curved_patches() {
    let mut rng = Rng(18);
    let (mut worst, mut samples) = (0.0f64, 0usize);
    for case in 0..200 {
        let k = 4 + rng.below(4);
        let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, k, k, k);
        let longest = 3f64.sqrt() / k as f64;
        let r = rng.uniform(2.0, 4.0) * longest;
        let c = [rng.uniform(0.2, 0.8), rng.uniform(0.2, 0.8), rng.uniform(0.2, 0.8)];
        // Pieces turning by at most 22.5 degrees: no feature lines.
        let n = 16 + rng.below(16);
        let sphere = case % 2 == 0;
        // The whole sphere or cylinder (about z, longer than the box), as a patch.
        let map = |u: f64, v: f64| -> [f64; 3] {
            if sphere {
                let (th, ph) = (0.05 + 3.04 * u, 2.0 * std::f64::consts::PI * v);
                [c[0] + r * th.sin() * ph.cos(), c[1] + r * th.sin() * ph.sin(), c[2] + r * th.cos()]
            } else {
                let ph = 2.0 * std::f64::consts::PI * u;
                [c[0] + r * ph.cos(), c[1] + r * ph.sin(), -1.0 + 3.0 * v]
            }
        };
        let s = patch(n, map);
        let eps_hat = [0.1, 0.2, 0.35][case % 3];
        let a = run(&mesh, &s, eps_hat, &format!("covered case {case}"));
        let facets: Vec<[[f64; 3]; 3]> = a.gamma_f.iter().map(|g| g.vertices.map(|v| a.mesh.points[v])).collect();
        let margin = longest / 2.0;
        let m = 120;
        for j in 0..=m {
            for i in 0..=m {
                let (u, v) = (i as f64 / m as f64, j as f64 / m as f64);
                // Away from the rim of the patch (the sphere's poles, and its seam, are inside).
                if sphere && (u * 3.04 < 0.2 || u * 3.04 > 2.84) {
                    continue;
                }
                // The point on the patch's triangles, not on the analytic surface.
                let (fi, fj) = (u * n as f64, v * n as f64);
                let (i0, j0) = ((fi.floor() as usize).min(n - 1), (fj.floor() as usize).min(n - 1));
                let (s_, t_) = (fi - i0 as f64, fj - j0 as f64);
                let q = |a: usize, b: usize| map(a as f64 / n as f64, b as f64 / n as f64);
                let (p00, p10, p11, p01) = (q(i0, j0), q(i0 + 1, j0), q(i0 + 1, j0 + 1), q(i0, j0 + 1));
                let x: [f64; 3] = if s_ >= t_ {
                    std::array::from_fn(|d| p00[d] + s_ * (p10[d] - p00[d]) + t_ * (p11[d] - p10[d]))
                } else {
                    std::array::from_fn(|d| p00[d] + s_ * (p11[d] - p01[d]) + t_ * (p01[d] - p00[d]))
                };
                if x.iter().any(|&xk| xk < margin || xk > 1.0 - margin) {
                    continue;
                }
                let d = facets.iter().map(|t| distance_to_triangle(&x, t)).fold(f64::INFINITY, f64::min);
                samples += 1;
                worst = worst.max(d / longest);
                assert!(
                    d <= longest / 8.0,
                    "covered case {case} ({}, k {k}, r {r:.3}, n {n}, eps_hat {eps_hat}): the point {x:?} of gamma_s is {d:.3e} from gamma_f \
                     ({} facets, {} rejected)",
                    if sphere { "sphere" } else { "cylinder" },
                    a.gamma_f.len(),
                    a.stats.rejected_facets
                );
            }
        }
    }
    println!("{samples} points of gamma_s, the farthest from gamma_f {worst:.3e} of the longest edge");
}
