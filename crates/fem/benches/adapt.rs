//! Adaptation cost (crates/fem/src/adapt):
//!
//! * `adapt_mesh_size/{prepare,step}/N`: box tetrahedra of N cells (about 1e3 .. 1e6) cut by a
//!   fixed, slightly tilted plane. `prepare` builds the [`Background`] (vertex mesh, topology,
//!   edge R-tree, incidence tables: once per run, mesh-size dependent); `step` is one adaptation
//!   with the prepared background (what runs every time step).
//! * `adapt_cut_size/step/K`: a fixed mesh (about 1e5 cells) cut by a disc of growing radius;
//!   K is the number of cut edges. The step's cut-dependent work grows with K; the remaining
//!   mesh-size part is the copy of the cell table into the adapted mesh.
//!
//! Run: `CARGO_TARGET_DIR=/tmp/target-adapt cargo bench -p fdfsi-fem --bench adapt`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use fdfsi_fem::adapt::{adapt_with, AdaptOptions, Background, Surface};
use fdfsi_fem::generate::box_tetrahedra;
use std::time::{Duration, Instant};

fn tilted_plane() -> Surface<3> {
    let z = |x: f64, y: f64| 0.5013 + 0.05 * (x - 0.5) + 0.03 * (y - 0.5);
    Surface::from_pieces(
        vec![[-1.0, -1.0, z(-1.0, -1.0)], [2.0, -1.0, z(2.0, -1.0)], [2.0, 2.0, z(2.0, 2.0)], [-1.0, 2.0, z(-1.0, 2.0)]],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
}

/// A disc of radius `r` centred in the box at a non-grid height, 64 sectors.
fn disc(r: f64) -> Surface<3> {
    let n = 64;
    let c = [0.5, 0.5, 0.5013];
    let mut pts = vec![c];
    for j in 0..n {
        let t = 2.0 * std::f64::consts::PI * j as f64 / n as f64;
        pts.push([c[0] + r * t.cos(), c[1] + r * t.sin(), c[2] + 0.01 * r * t.cos()]);
    }
    let tris = (0..n).map(|j| [0, 1 + j, 1 + (j + 1) % n]).collect();
    Surface::from_pieces(pts, tris).unwrap()
}

fn mesh_size(c: &mut Criterion) {
    let mut g = c.benchmark_group("adapt_mesh_size");
    g.sample_size(10).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_millis(500));
    let s = tilted_plane();
    let opts = AdaptOptions::new(0.2);
    for n in [6usize, 13, 28, 55] {
        let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, n, n, n);
        let cells = mesh.num_cells();
        let t0 = Instant::now();
        let bg = Background::new(&mesh).unwrap();
        let prep = t0.elapsed();
        let a = adapt_with(&bg, &s, &opts).unwrap();
        println!(
            "{cells} cells: prepare {:.3} s (one shot); cut edges {}, new cells {}, coupling facets {}",
            prep.as_secs_f64(),
            a.stats.cut_edges,
            a.stats.new_cells,
            a.stats.coupling_facets
        );
        if n <= 28 {
            g.bench_with_input(BenchmarkId::new("prepare", cells), &mesh, |b, m| b.iter(|| Background::new(m).unwrap()));
        }
        g.bench_with_input(BenchmarkId::new("step", cells), &bg, |b, bg| b.iter(|| adapt_with(bg, &s, &opts).unwrap()));
    }
    g.finish();
}

fn cut_size(c: &mut Criterion) {
    let mut g = c.benchmark_group("adapt_cut_size");
    g.sample_size(10).measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_millis(500));
    let mesh = box_tetrahedra(0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 26, 26, 26);
    let bg = Background::new(&mesh).unwrap();
    let opts = AdaptOptions::new(0.2);
    for r in [0.02, 0.05, 0.1, 0.2, 0.4] {
        let s = disc(r);
        let a = adapt_with(&bg, &s, &opts).unwrap();
        let k = a.stats.cut_edges;
        println!("{} cells, disc r = {r}: cut edges {k}, new cells {}", mesh.num_cells(), a.stats.new_cells);
        g.bench_with_input(BenchmarkId::new("step", k), &s, |b, s| b.iter(|| adapt_with(&bg, s, &opts).unwrap()));
    }
    g.finish();
}

criterion_group!(benches, mesh_size, cut_size);
criterion_main!(benches);
