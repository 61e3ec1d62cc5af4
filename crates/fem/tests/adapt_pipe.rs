//! The paper's 3D sanity numbers (model problem 4): a quarter pipe of about 3600 tetrahedra
//! (radius 1, length 2, `n_radial = 6`, `n_axial = 21`: 3591 cells) adapted with `eps_hat = 0.2`
//! to a flat membrane, the quarter disc from the axis to the wall at mid-length. Prints the
//! counts (the paper reports a few hundred added elements and about 150-175 coupling triangles)
//! and asserts only structural properties. Run with `--nocapture` to see them.

use fdfsi_fem::adapt::{adapt, verify_adapted, Surface};
use fdfsi_fem::generate::pipe_tetrahedra;

/// The quarter disc `x, y >= 0, x^2 + y^2 <= radius^2` at height `z`, as a fan of `nr` rings of
/// `nt` triangles (slightly larger than the pipe's polygonal section, which it must cover).
fn quarter_disc(radius: f64, z: f64, nr: usize, nt: usize) -> Surface<3> {
    let mut pts = vec![[0.0, 0.0, z]];
    for i in 1..=nr {
        for j in 0..=nt {
            let (r, t) = (radius * i as f64 / nr as f64, std::f64::consts::FRAC_PI_2 * j as f64 / nt as f64);
            // Exact on the symmetry planes (cos(pi/2) is not 0 in floating point).
            let (c, s) = if j == nt { (0.0, 1.0) } else { (t.cos(), t.sin()) };
            pts.push([r * c, r * s, z]);
        }
    }
    let id = |i: usize, j: usize| if i == 0 { 0 } else { 1 + (i - 1) * (nt + 1) + j };
    let mut tris = Vec::new();
    for j in 0..nt {
        tris.push([0, id(1, j), id(1, j + 1)]);
    }
    for i in 1..nr {
        for j in 0..nt {
            tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Surface::from_pieces(pts, tris).unwrap()
}

#[test]
fn adapt_quarter_pipe_membrane_counts() {
    let mesh = pipe_tetrahedra(1.0, 2.0, 6, 21, true);
    assert!((3000..4200).contains(&mesh.num_cells()));
    let dz = 2.0 / 21.0;
    for (label, z) in [
        ("mid-length, eps = 0.5", 1.0),
        ("layer 10 + 0.1 dz, eps = 0.1", 10.1 * dz),
        ("layer 10 + 0.15 dz, eps = 0.15", 10.15 * dz),
        ("layer 10 + 0.3 dz, eps = 0.3", 10.3 * dz),
    ] {
        let s = quarter_disc(1.05, z, 12, 24);
        let a = adapt(&mesh, &s, 0.2).unwrap();
        verify_adapted(&mesh, &a, &s).unwrap();
        let area = a.gamma_f_measure();
        println!(
            "quarter pipe, {} tets, membrane at z = {z:.4} ({label}): added elements {}, coupling triangles {}, \
             moved {}, new nodes {}, refused {}, min quality {:.3}, gamma_f area {area:.6}",
            mesh.num_cells(),
            a.stats.new_cells,
            a.stats.coupling_facets,
            a.stats.moved_nodes,
            a.stats.new_nodes,
            a.stats.refused_moves,
            a.stats.min_quality
        );
        assert!(a.stats.coupling_facets >= 57);
        // gamma_f is the pipe's (polygonal) quarter section: area below pi/4, close to it.
        assert!(area < std::f64::consts::FRAC_PI_4 && area > 0.97 * std::f64::consts::FRAC_PI_4);
        // Every gamma_f facet has a fluid cell on both sides.
        assert!(a.gamma_f.iter().all(|g| g.sides.iter().all(|s| s.0 != usize::MAX)));
    }
}
