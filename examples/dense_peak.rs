//! The dense-kernel rate of this machine, the ceiling of the supernodal LU's numeric
//! factorisation: faer's matrix product (`C -= A B`) and partial-pivoting LU of `n x n` matrices,
//! on one thread (`Par::Seq`), in GFLOP/s (`2 n^3` and `2/3 n^3` flops), best of 3.
//!
//! `cargo run --release --example dense_peak -- [N ...]` (default 256 512 1024 2048)
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use std::time::Instant;

fn best_of_3(mut f: impl FnMut()) -> f64 {
    (0..3)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    faer::set_global_parallelism(Par::Seq); // the LU too: one thread
    let sizes: Vec<usize> = std::env::args().skip(1).map(|v| v.parse().expect("N")).collect();
    let sizes = if sizes.is_empty() { vec![256, 512, 1024, 2048] } else { sizes };
    for n in sizes {
        let a = Mat::<f64>::from_fn(n, n, |i, j| if i == j { n as f64 } else { ((i * 7 + j * 13) % 17) as f64 / 17.0 });
        let b = a.clone();
        let mut c = Mat::<f64>::zeros(n, n);
        let gemm = best_of_3(|| matmul(c.as_mut(), Accum::Add, a.as_ref(), b.as_ref(), -1.0, Par::Seq));
        let lu = best_of_3(|| {
            std::hint::black_box(a.partial_piv_lu());
        });
        let nf = n as f64;
        println!("n = {n}: gemm {:.1} GFLOP/s, lu {:.1} GFLOP/s", 2.0 * nf.powi(3) / gemm / 1e9, 2.0 / 3.0 * nf.powi(3) / lu / 1e9);
    }
}
