//! 2D adaptation to random straight, curved and degenerate surfaces: every adapted mesh passes
//! `verify_adapted` (positive, conforming, measure kept, gamma_f on gamma_s), and a straight
//! line crossing the whole domain gives a gamma_f as long as the line's chord.
//!
//! Deterministic: a seeded SplitMix64 generator, a few thousand cases, well under a second in
//! release.

use fdfsi_fem::adapt::{adapt, verify_adapted, Adapted, Surface};
use fdfsi_fem::generate::{rectangle_triangles, DiagonalPattern};
use fdfsi_fem::mesh::Mesh;

/// SplitMix64: small, seeded, reproducible.
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
}

const PATTERNS: [DiagonalPattern; 4] = [DiagonalPattern::Right, DiagonalPattern::Left, DiagonalPattern::Alternating, DiagonalPattern::Crossed];

fn random_mesh(rng: &mut Rng) -> (Mesh<2>, usize) {
    let n = 2 + rng.below(10);
    let m = 2 + rng.below(10);
    (rectangle_triangles(0.0, 1.0, 0.0, 1.0, n, m, PATTERNS[rng.below(4)]), n.max(m))
}

fn run(mesh: &Mesh<2>, s: &Surface<2>, eps_hat: f64, what: &str) -> Adapted<2> {
    let a = adapt(mesh, s, eps_hat).unwrap_or_else(|e| panic!("{what}: {e}"));
    if let Err(e) = verify_adapted(mesh, &a, s) {
        panic!("{what}: {e}\nstats {:?}\nsurface {:?}", a.stats, s.points);
    }
    a
}

/// Length of the chord of the unit square cut by the line through `p` with direction `d`
/// (Liang-Barsky clipping).
fn chord(p: [f64; 2], d: [f64; 2]) -> f64 {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..2 {
        if d[k] == 0.0 {
            if p[k] < 0.0 || p[k] > 1.0 {
                return 0.0;
            }
            continue;
        }
        let (a, b) = ((0.0 - p[k]) / d[k], (1.0 - p[k]) / d[k]);
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    ((t1 - t0).max(0.0)) * (d[0] * d[0] + d[1] * d[1]).sqrt()
}

#[test]
fn adapt_straight_lines_crossing_the_domain() {
    let mut rng = Rng(1);
    let mut stats = [0usize; 4];
    for case in 0..1500 {
        let (mesh, _) = random_mesh(&mut rng);
        let p = [rng.uniform(0.05, 0.95), rng.uniform(0.05, 0.95)];
        let ang = rng.uniform(0.0, std::f64::consts::PI);
        let d = [ang.cos(), ang.sin()];
        let s = Surface::from_polyline(vec![[p[0] - 3.0 * d[0], p[1] - 3.0 * d[1]], [p[0] + 3.0 * d[0], p[1] + 3.0 * d[1]]]).unwrap();
        let eps_hat = [0.1, 0.2, 0.3, 0.5][case % 4];
        let a = run(&mesh, &s, eps_hat, &format!("line case {case}"));
        let want = chord(p, d);
        let got = a.gamma_f_measure();
        assert!((got - want).abs() <= 1e-12 * want, "line case {case}: gamma_f {got} vs chord {want}, {:?}", a.stats);
        stats[0] += a.stats.moved_nodes;
        stats[1] += a.stats.new_nodes;
        stats[2] += a.stats.refused_moves;
        stats[3] += a.stats.degenerate_cases;
        if case < 3 {
            println!("{:?}", a.stats);
        }
    }
    println!("lines: moved {} new {} refused {} degenerate {}", stats[0], stats[1], stats[2], stats[3]);
}

#[test]
fn adapt_arcs_and_polylines_ending_anywhere() {
    let mut rng = Rng(2);
    for case in 0..1500 {
        let (mesh, _) = random_mesh(&mut rng);
        let c = [rng.uniform(-0.5, 1.5), rng.uniform(-0.5, 1.5)];
        let r = rng.uniform(0.1, 1.2);
        let a0 = rng.uniform(0.0, 6.3);
        let span = rng.uniform(0.3, 6.2);
        let n = 3 + rng.below(40);
        let pts: Vec<[f64; 2]> = (0..=n)
            .map(|i| {
                let a = a0 + span * i as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect();
        let s = Surface::from_polyline(pts).unwrap();
        run(&mesh, &s, [0.1, 0.2, 0.35, 0.5][case % 4], &format!("arc case {case}"));
    }
}

#[test]
fn adapt_zigzags_fold_over_edges() {
    let mut rng = Rng(3);
    for case in 0..500 {
        let (mesh, _) = random_mesh(&mut rng);
        let n = 2 + rng.below(30);
        let pts: Vec<[f64; 2]> = (0..=n).map(|_| [rng.uniform(-0.2, 1.2), rng.uniform(-0.2, 1.2)]).collect();
        let s = Surface::from_polyline(pts).unwrap();
        run(&mesh, &s, 0.2, &format!("zigzag case {case}"));
    }
}

#[test]
fn adapt_degenerate_lines_through_vertices_along_edges_and_boundaries() {
    let mut rng = Rng(4);
    let mut touched = 0;
    for case in 0..1000 {
        let n = 2 + rng.below(8);
        let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, n, n, PATTERNS[rng.below(4)]);
        let h = 1.0 / n as f64;
        let (i, j) = (rng.below(n + 1) as f64 * h, rng.below(n + 1) as f64 * h);
        let pts = match case % 6 {
            // Along a grid line (edges in the surface), crossing the domain.
            0 => vec![[i, -1.0], [i, 2.0]],
            1 => vec![[-1.0, j], [2.0, j]],
            // Along the main diagonal (edges of the Right pattern).
            2 => vec![[-1.0, -1.0], [2.0, 2.0]],
            // Through a grid vertex at a random angle: the vertex is a polyline corner.
            3 => {
                let a = rng.uniform(0.0, 6.3);
                let b = a + rng.uniform(0.5, 5.8);
                vec![[i + 2.0 * a.cos(), j + 2.0 * a.sin()], [i, j], [i + 2.0 * b.cos(), j + 2.0 * b.sin()]]
            }
            // Ending exactly on the boundary, or inside the domain.
            4 => vec![[0.0, rng.uniform(0.0, 1.0)], [rng.uniform(0.1, 0.9), rng.uniform(0.1, 0.9)]],
            // Tiny offsets from a grid line: cuts within round-off of vertices.
            _ => vec![[i + 1e-14, -1.0], [i - 1e-14, 2.0]],
        };
        let s = Surface::from_polyline(pts).unwrap();
        let a = run(&mesh, &s, [0.2, 0.5][case % 2], &format!("degenerate case {case}"));
        touched += a.stats.touched_vertices;
        if case % 6 <= 1 && i > 0.0 && i < 1.0 {
            assert!((a.gamma_f_measure() - 1.0).abs() < 1e-12, "grid line case {case}: {}", a.gamma_f_measure());
        }
    }
    assert!(touched > 0);
}

#[test]
fn adapt_gamma_f_sides_and_surface_locations() {
    let mesh = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 8, 8, DiagonalPattern::Alternating);
    let s = Surface::from_polyline(vec![[0.33, -0.5], [0.41, 1.5]]).unwrap();
    let a = run(&mesh, &s, 0.2, "sides");
    assert!(a.stats.coupling_facets > 0);
    let n = s.normal(0);
    for g in &a.gamma_f {
        // Both sides present; the minus side's centroid lies behind the normal.
        let [(c0, _), (c1, _)] = g.sides;
        assert!(c0 != usize::MAX && c1 != usize::MAX);
        let centroid = |c: usize| -> [f64; 2] {
            let v = a.mesh.cell(c);
            std::array::from_fn(|d| v.iter().map(|&k| a.mesh.points[k][d]).sum::<f64>() / 3.0)
        };
        let x = a.mesh.points[g.vertices[0]];
        let side = |c: usize| (centroid(c)[0] - x[0]) * n[0] + (centroid(c)[1] - x[1]) * n[1];
        assert!(side(c0) < 0.0 && side(c1) > 0.0);
        for (k, loc) in g.location.iter().enumerate() {
            let p = a.mesh.points[g.vertices[k]];
            assert!(loc.distance < 1e-14 && (loc.x[0] - p[0]).abs() < 1e-14 && (loc.x[1] - p[1]).abs() < 1e-14);
        }
    }
}

#[test]
fn adapt_to_a_solid_boundary_maps_back_to_the_solid() {
    use fdfsi_fem::generate::rectangle_quads;
    use fdfsi_fem::mesh::GeometryOrder;
    // A solid slab [0.3, 0.7] x [0.2, 0.8] of 9-node quads; gamma_s = its top side.
    let solid = rectangle_quads(0.3, 0.7, 0.2, 0.8, 3, 4, GeometryOrder::Quadratic);
    let s = Surface::from_mesh_boundary(&solid, "top").unwrap();
    assert_eq!(s.num_pieces(), 6);
    let fluid = rectangle_triangles(0.0, 1.0, 0.0, 1.0, 7, 9, DiagonalPattern::Alternating);
    let a = run(&fluid, &s, 0.2, "solid top");
    // gamma_s ends inside fluid cells: the part between its end point and the last cut fluid
    // edge is not resolved (no node is put at an end of gamma_s), at most one cell per end.
    let m = a.gamma_f_measure();
    assert!(m <= 0.4 + 1e-12 && m > 0.4 - 2.0 / 7.0 * 2f64.sqrt(), "{m}");
    for g in &a.gamma_f {
        for (k, loc) in g.location.iter().enumerate() {
            let (cell, xi) = s.solid_point(loc);
            let v: Vec<[f64; 2]> = solid.cell_vertices(cell).iter().map(|&n| solid.points[n]).collect();
            let x = [v[0][0] + xi[0] * (v[1][0] - v[0][0]), v[0][1] + xi[1] * (v[3][1] - v[0][1])];
            let p = a.mesh.points[g.vertices[k]];
            assert!((x[0] - p[0]).abs() < 1e-13 && (x[1] - p[1]).abs() < 1e-13, "{x:?} vs {p:?}");
        }
    }
}
