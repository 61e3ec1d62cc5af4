//! Flexible GMRES (Saad 1993) with right preconditioning.
//!
//! Solves `A x = b` for `x` in `x_0 + span{z_1, ..., z_m}` with `z_j = P_j^{-1} v_j`, where the
//! `v_j` are the orthonormal Arnoldi vectors (modified Gram-Schmidt) and `P_j^{-1}` may change
//! from one iteration to the next (an inner solve with a reused or inexact factorisation). The
//! `z_j` are kept, so the update is `x = x_0 + Z_m y` with `y` minimising `|beta e_1 - H_m y|`
//! (Givens rotations); the residual it reports is the true `|b - A x|`, not only the Arnoldi
//! estimate. Restarts after `restart` iterations.
//!
//! Why our own: the Krylov crates on crates.io are tied to their own matrix types or are dense
//! only; FGMRES on closures over our CSC matrix and block preconditioner is short.

/// Options of the Krylov solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KrylovOptions {
    /// Converged when `|b - A x| <= rel_tol |b|`.
    pub rel_tol: f64,
    /// Most iterations (preconditioner applications) in all.
    pub max_iterations: usize,
    /// Iterations between restarts.
    pub restart: usize,
}

impl Default for KrylovOptions {
    fn default() -> Self {
        KrylovOptions { rel_tol: 1e-8, max_iterations: 60, restart: 30 }
    }
}

/// What a Krylov solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KrylovReport {
    pub iterations: usize,
    /// `|b - A x| / |b|` at the end.
    pub residual: f64,
    pub converged: bool,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn axpy(alpha: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(yi, xi)| *yi += alpha * xi);
}

/// `r = b - A x`; returns `|r|`.
fn residual(apply: &mut impl FnMut(&[f64], &mut [f64]), b: &[f64], x: &[f64], r: &mut [f64]) -> f64 {
    apply(x, r);
    r.iter_mut().zip(b).for_each(|(ri, bi)| *ri = bi - *ri);
    dot(r, r).sqrt()
}

/// FGMRES on `A x = b` from the initial guess in `x`: `apply(v, out)` sets `out = A v`,
/// `precondition(v, out)` sets `out ~ A^{-1} v`.
pub fn fgmres(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    mut precondition: impl FnMut(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    options: &KrylovOptions,
) -> KrylovReport {
    let n = b.len();
    let m = options.restart.max(1);
    let bnorm = dot(b, b).sqrt();
    let mut report = KrylovReport::default();
    if bnorm == 0.0 {
        x.iter_mut().for_each(|v| *v = 0.0);
        report.converged = true;
        return report;
    }
    let target = options.rel_tol * bnorm;
    let mut r = vec![0.0; n];
    let mut v: Vec<Vec<f64>> = Vec::with_capacity(m + 1);
    let mut z: Vec<Vec<f64>> = Vec::with_capacity(m);
    let mut h = vec![vec![0.0; m]; m + 1];
    let (mut cs, mut sn, mut g) = (vec![0.0; m], vec![0.0; m], vec![0.0; m + 1]);
    let mut rnorm = residual(&mut apply, b, x, &mut r);
    while rnorm > target && report.iterations < options.max_iterations && rnorm.is_finite() {
        v.clear();
        z.clear();
        v.push(r.iter().map(|ri| ri / rnorm).collect());
        g.iter_mut().for_each(|gi| *gi = 0.0);
        g[0] = rnorm;
        let mut k = 0;
        while k < m && report.iterations < options.max_iterations {
            let mut zk = vec![0.0; n];
            precondition(&v[k], &mut zk);
            let mut w = vec![0.0; n];
            apply(&zk, &mut w);
            z.push(zk);
            for (i, vi) in v.iter().enumerate() {
                h[i][k] = dot(&w, vi);
                axpy(-h[i][k], vi, &mut w);
            }
            h[k + 1][k] = dot(&w, &w).sqrt();
            for i in 0..k {
                let t = cs[i] * h[i][k] + sn[i] * h[i + 1][k];
                h[i + 1][k] = -sn[i] * h[i][k] + cs[i] * h[i + 1][k];
                h[i][k] = t;
            }
            let d = h[k][k].hypot(h[k + 1][k]);
            (cs[k], sn[k]) = if d == 0.0 { (1.0, 0.0) } else { (h[k][k] / d, h[k + 1][k] / d) };
            h[k][k] = d;
            g[k + 1] = -sn[k] * g[k];
            g[k] *= cs[k];
            let breakdown = h[k + 1][k] == 0.0;
            if !breakdown {
                let s = 1.0 / h[k + 1][k];
                v.push(w.iter().map(|wi| wi * s).collect());
            }
            h[k + 1][k] = 0.0;
            k += 1;
            report.iterations += 1;
            tracing::trace!("fgmres {}: |r| / |b| = {:.3e} (Arnoldi estimate)", report.iterations, g[k].abs() / bnorm);
            if g[k].abs() <= target || breakdown || !g[k].is_finite() {
                break;
            }
        }
        // y = H^{-1} g (upper triangular), x += Z y.
        let mut y = vec![0.0; k];
        for i in (0..k).rev() {
            let s: f64 = (i + 1..k).map(|j| h[i][j] * y[j]).sum();
            y[i] = if h[i][i] == 0.0 { 0.0 } else { (g[i] - s) / h[i][i] };
        }
        for (zi, yi) in z.iter().zip(&y) {
            axpy(*yi, zi, x);
        }
        let previous = rnorm;
        rnorm = residual(&mut apply, b, x, &mut r);
        if k == 0 || rnorm >= previous {
            break; // no progress (breakdown of the preconditioner): report what we have
        }
    }
    report.residual = rnorm / bnorm;
    report.converged = rnorm <= target;
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A nonsymmetric tridiagonal system: FGMRES without preconditioning reaches the tolerance
    /// through restarts; with the exact inverse it needs one iteration.
    #[test]
    fn solves_nonsymmetric_tridiagonal() {
        let n = 50;
        let apply = |v: &[f64], out: &mut [f64]| {
            for i in 0..n {
                out[i] = 4.0 * v[i] - if i > 0 { 1.5 * v[i - 1] } else { 0.0 } - if i + 1 < n { 0.5 * v[i + 1] } else { 0.0 };
            }
        };
        let exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut b = vec![0.0; n];
        apply(&exact, &mut b);
        let mut x = vec![0.0; n];
        let options = KrylovOptions { rel_tol: 1e-12, max_iterations: 200, restart: 10 };
        let report = fgmres(apply, |v, out| out.copy_from_slice(v), &b, &mut x, &options);
        assert!(report.converged && report.residual <= 1e-12, "{report:?}");
        assert!(report.iterations > 10, "restarted: {report:?}");
        let err = x.iter().zip(&exact).map(|(a, e)| (a - e).abs()).fold(0.0, f64::max);
        assert!(err < 1e-10, "error {err}");
        // The exact inverse (by many unpreconditioned restarts) as preconditioner: one iteration.
        let inverse = |v: &[f64], out: &mut [f64]| {
            out.iter_mut().for_each(|o| *o = 0.0);
            fgmres(apply, |a, o| o.copy_from_slice(a), v, out, &KrylovOptions { rel_tol: 1e-14, max_iterations: 500, restart: 50 });
        };
        let mut x = vec![0.0; n];
        let report = fgmres(apply, inverse, &b, &mut x, &options);
        assert!(report.converged && report.iterations == 1, "{report:?}");
    }
}
