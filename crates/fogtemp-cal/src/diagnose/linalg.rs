//! Least squares for the diagnosis: per-run QR compression (so that every leave-one-run-out
//! fold is a small QR of stacked triangular factors, never the normal equations),
//! rank-tolerant SVD solves, Newey-West (HAC) covariances and the effective sample size.

use nalgebra::{DMatrix, DVector};

/// Relative singular-value tolerance: directions weaker than this (on unit-RMS columns)
/// are treated as absent (minimum-norm solution).
const SVD_TOLERANCE: f64 = 1e-9;

/// Minimum-norm least-squares solution of `x beta = y` by SVD with a relative tolerance
/// (columns are scaled to unit RMS first). `None` if a value is not finite.
pub fn least_squares(x: &DMatrix<f64>, y: &DVector<f64>) -> Option<DVector<f64>> {
    let (n, p) = x.shape();
    if n == 0 || p == 0 {
        return None;
    }
    let scale: Vec<f64> = (0..p)
        .map(|k| {
            let rms = (x.column(k).norm_squared() / n as f64).sqrt();
            if rms > 0.0 && rms.is_finite() {
                rms
            } else {
                1.0
            }
        })
        .collect();
    let mut xs = x.clone();
    for (k, s) in scale.iter().enumerate() {
        xs.column_mut(k).unscale_mut(*s);
    }
    let svd = xs.svd(true, true);
    let tol = SVD_TOLERANCE * svd.singular_values.max();
    let beta = svd.solve(y, tol).ok()?;
    let beta = DVector::from_iterator(p, beta.iter().zip(&scale).map(|(b, s)| b / s));
    beta.iter().all(|b| b.is_finite()).then_some(beta)
}

/// Upper-triangular factor R of `[x | y]` (at most `p + 1` rows): `R^T R = [x|y]^T [x|y]`.
pub fn compress(x: &DMatrix<f64>, y: &[f64]) -> DMatrix<f64> {
    let (n, p) = x.shape();
    let mut m = DMatrix::zeros(n, p + 1);
    m.view_mut((0, 0), (n, p)).copy_from(x);
    for (i, v) in y.iter().enumerate() {
        m[(i, p)] = *v;
    }
    if n == 0 {
        return DMatrix::zeros(0, p + 1);
    }
    m.qr().r()
}

/// Least squares over the stacked factors `rs` (each from [`compress`] with `p` columns):
/// `(beta, rss)`, minimum norm when columns are collinear; `None` without rows.
pub fn fit_stacked(rs: &[&DMatrix<f64>], p: usize) -> Option<(DVector<f64>, f64)> {
    let rows: usize = rs.iter().map(|r| r.nrows()).sum();
    if rows == 0 {
        return None;
    }
    let mut s = DMatrix::zeros(rows, p + 1);
    let mut at = 0;
    for r in rs {
        s.view_mut((at, 0), (r.nrows(), p + 1)).copy_from(*r);
        at += r.nrows();
    }
    let r = if rows > p + 1 { s.qr().r() } else { s };
    let a = r.columns(0, p).into_owned();
    let b = r.column(p).into_owned();
    let svd = a.svd(true, true);
    let tol = SVD_TOLERANCE * svd.singular_values.max().max(f64::MIN_POSITIVE);
    let beta = svd.solve(&b, tol).ok()?;
    let rss = sse_of(&r, &beta);
    beta.iter().all(|v| v.is_finite()).then_some((beta, rss))
}

/// Sum of squared residuals `||[x|y] [-beta; 1]||^2` from a compressed factor.
pub fn sse_of(r: &DMatrix<f64>, beta: &DVector<f64>) -> f64 {
    let p = beta.len();
    (0..r.nrows())
        .map(|i| {
            let fitted: f64 = (0..p).map(|k| r[(i, k)] * beta[k]).sum();
            (r[(i, p)] - fitted).powi(2)
        })
        .sum()
}

/// Pooled lag-1 autocorrelation of residuals within runs, over consecutive short means
/// only (block numbers differing by one), clamped to `[0, 0.99]`.
pub fn lag1_rho(residuals: &[Vec<f64>], indices: &[Vec<usize>]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (e, idx) in residuals.iter().zip(indices) {
        let mean = e.iter().sum::<f64>() / e.len().max(1) as f64;
        den += e.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
        for k in 1..e.len() {
            if idx[k] == idx[k - 1] + 1 {
                num += (e[k] - mean) * (e[k - 1] - mean);
            }
        }
    }
    if den > 0.0 {
        (num / den).clamp(0.0, 0.99)
    } else {
        0.0
    }
}

/// Effective sample size of `n` AR(1)-correlated values: `n (1 - rho) / (1 + rho)`.
pub fn effective_n(n: usize, rho: f64) -> f64 {
    (n as f64 * (1.0 - rho) / (1.0 + rho)).max(2.0)
}

/// Delete-one-group jackknife covariance of coefficient vectors estimated with each group
/// (run) left out: `(G - 1)/G sum_j (b_j - mean b)(b_j - mean b)^T`.
pub fn jackknife_covariance(fold_betas: &[DVector<f64>]) -> DMatrix<f64> {
    let g = fold_betas.len();
    let p = fold_betas.first().map_or(0, |b| b.len());
    let mut cov = DMatrix::zeros(p, p);
    if g < 2 {
        return cov.add_scalar(f64::NAN);
    }
    let mean = fold_betas.iter().fold(DVector::zeros(p), |a, b| a + b) / g as f64;
    for b in fold_betas {
        let d = b - &mean;
        cov += &d * d.transpose();
    }
    cov * ((g - 1) as f64 / g as f64)
}

/// Newey-West standard error of the mean of `values` (per run, with block numbers).
pub fn hac_se_of_mean(values: &[Vec<f64>], indices: &[Vec<usize>], lag: usize) -> f64 {
    let n: usize = values.iter().map(Vec::len).sum();
    if n < 2 {
        return f64::NAN;
    }
    let mean = values.iter().flatten().sum::<f64>() / n as f64;
    let mut s = 0.0;
    for (v, idx) in values.iter().zip(indices) {
        for i in 0..v.len() {
            s += (v[i] - mean).powi(2);
            for j in i + 1..v.len() {
                let l = idx[j] - idx[i];
                if l > lag {
                    break;
                }
                s += 2.0 * (1.0 - l as f64 / (lag as f64 + 1.0)) * (v[i] - mean) * (v[j] - mean);
            }
        }
    }
    (s.max(0.0) * n as f64 / (n - 1) as f64).sqrt() / n as f64
}
