//! A noise model for the residual's short means and a generalised-least-squares (GLS) test
//! of a candidate term (issue 10, eighth session; docs/diagnose.md, "A noise model in the
//! acceptance").
//!
//! Family (IEEE Std 952 terms, docs/physics.md): white rate noise (a level per 1 s second,
//! `alpha`) plus bias instability as a sum of stationary Gauss-Markov terms, one per decade
//! of correlation time [`FLICKER_DECADES_S`], each of the same variance (`beta` per decade:
//! the decade approximation of a flat Allan deviation). The decades are fixed by the
//! physics (from the 1 s grid to beyond the longest run), not by any simulator's scenario;
//! the two levels are estimated by REML from the runs with the current model in place. Runs
//! are independent. The model is checked against the data (time-ordered innovations
//! aggregated over windows, [`NoiseCheck`]); a caller falls back to its own rules when the
//! check fails.
//!
//! Per run, with `D` the white part and `S` the flicker part at unit levels,
//! `D^-1/2 S D^-1/2 = U diag(lambda) U^T`, so `Sigma = alpha D^1/2 U (I + r Lambda) U^T D^1/2`
//! (`r = beta / alpha`) is diagonal in the rotated coordinates `U^T D^-1/2 y`: every REML
//! evaluation is a weighted sum over those coordinates.

use std::collections::HashMap;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Correlation times of the bias-instability decades, seconds.
pub const FLICKER_DECADES_S: [f64; 6] = [1.0, 10.0, 100.0, 1e3, 1e4, 1e5];

/// Ratios `beta / alpha` searched by REML: 10^(i/8) for i in -80..=16, and 0.
const RATIO_STEPS: (i32, i32) = (-80, 16);

/// Windows (in short means) of the innovation check.
pub const CHECK_WINDOWS: [usize; 4] = [1, 4, 16, 64];

/// Family-wise level of the innovation check over its windows (one-sided: excess variance;
/// a model that overstates the noise only costs power).
pub const CHECK_LEVEL: f64 = 0.01;

/// Fewest windows a window size needs to be checked.
const MIN_CHECK_WINDOWS: usize = 10;

/// Seconds `[first, end)` of a short mean on the run's 1 s grid.
pub type Span = (usize, usize);

/// Sum over `s in a`, `t in b` of `phi^|s - t|` (a unit Gauss-Markov term on the 1 s grid).
fn ar1_pair_sum(phi: f64, a: Span, b: Span) -> f64 {
    let geo = |len: usize| if phi < 1.0 { (1.0 - phi.powi(len as i32)) / (1.0 - phi) } else { len as f64 };
    let (la, lb) = (a.1.saturating_sub(a.0), b.1.saturating_sub(b.0));
    if a.1 <= b.0 {
        geo(la) * geo(lb) * phi.powi((b.0 - a.1 + 1) as i32)
    } else if b.1 <= a.0 {
        ar1_pair_sum(phi, b, a)
    } else {
        let mut sum = 0.0;
        for s in a.0..a.1 {
            for t in b.0..b.1 {
                sum += phi.powi(s.abs_diff(t) as i32);
            }
        }
        sum
    }
}

/// Covariance of two short means (spans `a`, `b`) of the unit white part (variance 1 per
/// second) and of the unit flicker part (every decade of variance 1).
pub fn unit_block_cov(a: Span, b: Span) -> (f64, f64) {
    let (la, lb) = (a.1.saturating_sub(a.0) as f64, b.1.saturating_sub(b.0) as f64);
    let norm = (la * lb).max(1.0);
    let overlap = a.1.min(b.1).saturating_sub(a.0.max(b.0)) as f64;
    let flicker: f64 = FLICKER_DECADES_S.iter().map(|tau| ar1_pair_sum((-1.0 / tau).exp(), a, b)).sum();
    (overlap / norm, flicker / norm)
}

/// Covariance matrix of one run's short means at levels `(alpha, beta)`.
pub fn run_covariance(spans: &[Span], alpha: f64, beta: f64) -> DMatrix<f64> {
    let n = spans.len();
    DMatrix::from_fn(n, n, |i, j| {
        let (w, f) = unit_block_cov(spans[i], spans[j]);
        alpha * w + beta * f
    })
}

/// One run structure's joint diagonalisation (see the module documentation).
#[derive(Clone, Debug)]
struct Rotation {
    /// `U^T D^-1/2`.
    rotate: DMatrix<f64>,
    lambda: Vec<f64>,
    /// The unit white (diagonal) and flicker covariances.
    white: Vec<f64>,
    flicker: DMatrix<f64>,
}

impl Rotation {
    fn of(spans: &[Span]) -> Option<Self> {
        let n = spans.len();
        let white: Vec<f64> = spans.iter().map(|&sp| unit_block_cov(sp, sp).0).collect();
        let d_inv_sqrt: Vec<f64> = white.iter().map(|w| w.powf(-0.5)).collect();
        if d_inv_sqrt.iter().any(|d| !d.is_finite()) {
            return None;
        }
        let mut flicker = DMatrix::zeros(n, n);
        for i in 0..n {
            for j in i..n {
                let f = unit_block_cov(spans[i], spans[j]).1;
                flicker[(i, j)] = f;
                flicker[(j, i)] = f;
            }
        }
        let c = DMatrix::from_fn(n, n, |i, j| d_inv_sqrt[i] * flicker[(i, j)] * d_inv_sqrt[j]);
        let eig = c.symmetric_eigen();
        let mut rotate = eig.eigenvectors.transpose();
        for (j, d) in d_inv_sqrt.iter().enumerate() {
            rotate.column_mut(j).scale_mut(*d);
        }
        Some(Rotation {
            rotate,
            lambda: eig.eigenvalues.iter().map(|l| l.max(0.0)).collect(),
            white,
            flicker,
        })
    }
}

/// The fitted noise model of one set of runs.
#[derive(Clone, Debug)]
pub struct NoiseFit {
    /// White level: variance of one second's residual, (deg/h)^2.
    pub white_var: f64,
    /// Flicker level: variance of each Gauss-Markov decade, (deg/h)^2.
    pub flicker_var: f64,
    /// Whether the REML maximum lay at the edge of the searched ratios.
    pub at_edge: bool,
    /// The innovation check at the fitted levels.
    pub check: NoiseCheck,
    /// Mean variance of one short mean at the fitted levels, (deg/h)^2.
    pub block_var: f64,
    /// Per run: `diag(var^-1/2) U^T D^-1/2` (whitens the run's short means).
    whiten: Vec<DMatrix<f64>>,
}

/// Innovation check: `(window, windows, ratio, p)` for each window size checked, and
/// whether every p is above its share of [`CHECK_LEVEL`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NoiseCheck {
    /// `(window in short means, windows, mean square of the window sums / window, one-sided p)`.
    pub windows: Vec<(usize, usize, f64, f64)>,
    /// The model fits (no window shows excess variance at the family-wise level).
    pub passed: bool,
}

/// Rotated design `[x | y]` per run with its eigenvalues.
struct Rotated {
    m: DMatrix<f64>,
    lambda: Vec<f64>,
}

/// Profile REML at ratio `r` (`alpha` profiled out): `(log-likelihood up to a constant, alpha)`.
fn profile_reml(rotated: &[Rotated], p: usize, r: f64) -> Option<(f64, f64)> {
    let mut a = DMatrix::<f64>::zeros(p, p);
    let mut b = DVector::<f64>::zeros(p);
    let (mut yy, mut log_det, mut n) = (0.0, 0.0, 0usize);
    for rot in rotated {
        let mut mw = rot.m.clone();
        for (i, l) in rot.lambda.iter().enumerate() {
            let v = 1.0 + r * l;
            log_det += v.ln();
            mw.row_mut(i).unscale_mut(v);
        }
        let x = rot.m.columns(0, p);
        let xw = mw.columns(0, p);
        a += x.transpose() * xw;
        b += xw.transpose() * rot.m.column(p);
        yy += rot.m.column(p).dot(&mw.column(p));
        n += rot.lambda.len();
    }
    let chol = a.clone().cholesky()?;
    let rss = yy - b.dot(&chol.solve(&b));
    let dof = n.checked_sub(p).filter(|d| *d > 0)? as f64;
    if rss <= 0.0 || !rss.is_finite() {
        return None;
    }
    let log_det_a: f64 = chol.l().diagonal().iter().map(|d| 2.0 * d.ln()).sum();
    Some((-0.5 * (dof * rss.ln() + log_det + log_det_a), rss / dof))
}

/// The runs' short-mean spans with each distinct run structure's rotation (built once per
/// diagnosis; the noise model is refitted at every step of the selection).
#[derive(Clone, Debug)]
pub struct NoiseBasis {
    spans: Vec<Vec<Span>>,
    cache: HashMap<Vec<Span>, Rotation>,
}

impl NoiseBasis {
    /// The runs' short-mean spans, one list per run, as [`NoiseBasis::new`] was given them.
    pub fn of(prep: &crate::prepare::Prepared) -> Option<Self> {
        let spans: Vec<Vec<Span>> =
            prep.runs.iter().map(|r| r.blocks.iter().map(|b| (b.first_sec, b.end_sec)).collect()).collect();
        Self::new(&spans)
    }

    /// `sum_{i,j} Sigma_ij` over the short means at `positions` of run `run` at levels
    /// `(alpha, beta)` (its unit covariances are cached: no AR(1) sums), or `None` for a
    /// run or position it does not have.
    pub fn subset_covariance_sum(
        &self,
        run: usize,
        positions: &[usize],
        alpha: f64,
        beta: f64,
    ) -> Option<f64> {
        let rot = self.cache.get(self.spans.get(run)?)?;
        let mut sum = 0.0;
        for (k, &i) in positions.iter().enumerate() {
            sum += alpha * rot.white.get(i)? + beta * rot.flicker.get((i, i))?;
            for &j in &positions[k + 1..] {
                sum += 2.0 * beta * rot.flicker.get((i, j))?;
            }
        }
        Some(sum)
    }

    /// `None` when a run has an empty short mean.
    pub fn new(spans: &[Vec<Span>]) -> Option<Self> {
        let distinct: Vec<&Vec<Span>> = {
            let mut seen: Vec<&Vec<Span>> = Vec::new();
            for s in spans {
                if !seen.contains(&s) {
                    seen.push(s);
                }
            }
            seen
        };
        let rotations: Vec<Rotation> = distinct.par_iter().map(|s| Rotation::of(s)).collect::<Option<_>>()?;
        let cache = distinct.into_iter().cloned().zip(rotations).collect();
        Some(NoiseBasis { spans: spans.to_vec(), cache })
    }
}

/// Fits the noise model by REML with the design `x` (per run, the same columns) in place:
/// the ratio `beta / alpha` on a log grid then refined by golden section between the grid
/// neighbours, `alpha` in closed form. `None` when the design is singular.
pub fn fit_noise(basis: &NoiseBasis, x: &[DMatrix<f64>], y: &[Vec<f64>]) -> Option<NoiseFit> {
    let p = x.first()?.ncols();
    let (spans, cache) = (&basis.spans, &basis.cache);
    let rotated: Vec<Rotated> = spans
        .iter()
        .zip(x)
        .zip(y)
        .map(|((s, xr), yr)| {
            let rot = &cache[s];
            let mut m = DMatrix::zeros(yr.len(), p + 1);
            m.columns_mut(0, p).copy_from(xr);
            m.column_mut(p).copy_from_slice(yr);
            Rotated { m: &rot.rotate * m, lambda: rot.lambda.clone() }
        })
        .collect();
    let ratio = |i: i32| if i < RATIO_STEPS.0 { 0.0 } else { 10f64.powf(i as f64 / 8.0) };
    let grid: Vec<(i32, f64)> = (RATIO_STEPS.0 - 1..=RATIO_STEPS.1)
        .into_par_iter()
        .filter_map(|i| profile_reml(&rotated, p, ratio(i)).map(|(l, _)| (i, l)))
        .collect();
    let (best_i, _) = grid.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1))?;
    let at_edge = best_i == RATIO_STEPS.1;
    let r = if best_i > RATIO_STEPS.0 && best_i < RATIO_STEPS.1 {
        golden_max(
            |lr| profile_reml(&rotated, p, lr.exp()).map_or(f64::NEG_INFINITY, |v| v.0),
            (ratio(best_i - 1).ln(), ratio(best_i + 1).ln()),
        )
        .exp()
    } else {
        ratio(best_i)
    };
    let (_, alpha) = profile_reml(&rotated, p, r)?;
    let beta = alpha * r;
    let whiten: Vec<DMatrix<f64>> = spans
        .iter()
        .map(|s| {
            let rot = &cache[s];
            let mut w = rot.rotate.clone();
            for (i, l) in rot.lambda.iter().enumerate() {
                w.row_mut(i).unscale_mut((alpha * (1.0 + r * l)).sqrt());
            }
            w
        })
        .collect();
    let covariances: Vec<DMatrix<f64>> = spans
        .iter()
        .map(|s| {
            let rot = &cache[s];
            let mut c = &rot.flicker * beta;
            for (i, w) in rot.white.iter().enumerate() {
                c[(i, i)] += alpha * w;
            }
            c
        })
        .collect();
    let check = innovation_check(&covariances, x, y, &whiten)?;
    let blocks: usize = covariances.iter().map(|c| c.nrows()).sum();
    let block_var = covariances.iter().map(|c| c.trace()).sum::<f64>() / blocks.max(1) as f64;
    Some(NoiseFit { white_var: alpha, flicker_var: beta, at_edge, check, block_var, whiten })
}

/// Maximum of a unimodal `f` on `[lo, hi]` by golden section (40 steps).
fn golden_max(f: impl Fn(f64) -> f64, (mut lo, mut hi): (f64, f64)) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..40 {
        if fc > fd {
            hi = d;
            d = c;
            fd = fc;
            c = hi - g * (hi - lo);
            fc = f(c);
        } else {
            lo = c;
            c = d;
            fc = fd;
            d = lo + g * (hi - lo);
            fd = f(d);
        }
    }
    (lo + hi) / 2.0
}

/// GLS coefficients of `x` under the fitted model (all runs).
fn gls_beta(x: &[DMatrix<f64>], y: &[Vec<f64>], whiten: &[DMatrix<f64>]) -> Option<DVector<f64>> {
    let p = x.first()?.ncols();
    let mut a = DMatrix::<f64>::zeros(p, p);
    let mut b = DVector::<f64>::zeros(p);
    for ((xr, yr), w) in x.iter().zip(y).zip(whiten) {
        let xw = w * xr;
        let yw = w * DVector::from_column_slice(yr);
        a += xw.transpose() * &xw;
        b += xw.transpose() * yw;
    }
    crate::linalg::least_squares(&a, &b)
}

/// Leave-one-run-out GLS under a fitted model: the full-data GLS coefficients of `x`
/// and the held-out error in the model's own metric, `sum_r e_r^T Sigma_r^-1 e_r` with
/// `e_r` run `r`'s residual from the coefficients fitted to the other runs. (The claim the
/// diagnosis makes for a term, that it predicts held-out runs better, measured where a run's
/// slow flicker offset counts as much as the model says it is likely, not as its square.)
#[derive(Clone, Debug, PartialEq)]
pub struct HeldOut {
    /// Full-data GLS coefficients.
    pub beta: DVector<f64>,
    /// Held-out whitened sum of squares of each run.
    pub per_run_sse: Vec<f64>,
}

impl HeldOut {
    /// Held-out whitened sum of squares over all runs.
    pub fn sse(&self) -> f64 {
        self.per_run_sse.iter().sum()
    }
}

/// See [`HeldOut`]. `penalty`: pseudo-observations of 0 on the coefficients (rows x p, in
/// the units of a short mean, as in the run-level fits); each row is weighted as one short
/// mean of the model's mean variance, so it is as heavy as in the run-level fits. `None`
/// when a fit fails or the shapes do not match.
pub fn heldout_gls(
    fit: &NoiseFit,
    x: &[DMatrix<f64>],
    y: &[Vec<f64>],
    penalty: Option<&DMatrix<f64>>,
) -> Option<HeldOut> {
    let p = x.first()?.ncols();
    if x.len() != y.len() || x.len() != fit.whiten.len() || penalty.is_some_and(|m| m.ncols() != p) {
        return None;
    }
    let pen_gram = penalty.map_or_else(|| DMatrix::zeros(p, p), |m| m.transpose() * m / fit.block_var);
    let mut parts = Vec::with_capacity(x.len());
    for ((xr, yr), w) in x.iter().zip(y).zip(&fit.whiten) {
        if xr.nrows() != yr.len() || w.ncols() != yr.len() || xr.ncols() != p {
            return None;
        }
        let xw = w * xr;
        let yw = w * DVector::from_column_slice(yr);
        let a = xw.transpose() * &xw;
        let b = xw.transpose() * &yw;
        parts.push((xw, yw, a, b));
    }
    let a_all = parts.iter().fold(pen_gram, |acc, q| acc + &q.2);
    let b_all = parts.iter().fold(DVector::<f64>::zeros(p), |acc, q| acc + &q.3);
    let beta = crate::linalg::least_squares(&a_all, &b_all)?;
    let mut per_run_sse = Vec::with_capacity(parts.len());
    for (xw, yw, a, b) in &parts {
        let beta_out = crate::linalg::least_squares(&(&a_all - a), &(&b_all - b))?;
        per_run_sse.push((yw - xw * beta_out).norm_squared());
    }
    Some(HeldOut { beta, per_run_sse })
}

/// Time-ordered innovations of the GLS residual (`L^-1 e`, `L` the Cholesky factor of the
/// run's covariance) summed over non-overlapping windows of consecutive short means: under
/// the model each window sum over `sqrt(window)` is standard normal and independent, so the
/// sum of their squares is chi-square with as many degrees of freedom as windows. Excess
/// variance at long windows is slow noise the family does not hold (e.g. rate random walk).
fn innovation_check(
    covariances: &[DMatrix<f64>],
    x: &[DMatrix<f64>],
    y: &[Vec<f64>],
    whiten: &[DMatrix<f64>],
) -> Option<NoiseCheck> {
    let coef = gls_beta(x, y, whiten)?;
    let innovations: Vec<Vec<f64>> = covariances
        .par_iter()
        .zip(x)
        .zip(y)
        .map(|((cov, xr), yr)| {
            let e = DVector::from_column_slice(yr) - xr * &coef;
            let chol = cov.clone().cholesky()?;
            let innov = chol.l().solve_lower_triangular(&e)?;
            Some(innov.iter().copied().collect())
        })
        .collect::<Option<_>>()?;
    let sizes: Vec<usize> = CHECK_WINDOWS
        .iter()
        .copied()
        .filter(|m| innovations.iter().map(|r| r.len() / m).sum::<usize>() >= MIN_CHECK_WINDOWS)
        .collect();
    let level = CHECK_LEVEL / sizes.len().max(1) as f64;
    let mut windows = Vec::new();
    for m in sizes {
        let sums: Vec<f64> = innovations
            .iter()
            .flat_map(|r| r.chunks_exact(m).map(|c| c.iter().sum::<f64>().powi(2) / m as f64))
            .collect();
        let count = sums.len();
        let total: f64 = sums.iter().sum();
        let p = ChiSquared::new(count as f64).map_or(f64::NAN, |c| c.sf(total));
        windows.push((m, count, total / count as f64, p));
    }
    let passed = !windows.is_empty() && windows.iter().all(|w| w.3 >= level);
    Some(NoiseCheck { windows, passed })
}

/// Whitened, stacked data for GLS tests at the fitted levels: the response and an
/// orthonormal basis of the current model's columns (all runs stacked).
pub struct GlsTester<'a> {
    fit: &'a NoiseFit,
    y: DVector<f64>,
    base: DMatrix<f64>,
    rows: Vec<usize>,
}

/// Relative size below which a whitened column adds no new direction.
const RANK_TOLERANCE: f64 = 1e-8;

impl<'a> GlsTester<'a> {
    /// Whitens `y` and the current model's design `x` (per run).
    pub fn new(fit: &'a NoiseFit, x: &[DMatrix<f64>], y: &[Vec<f64>]) -> Option<Self> {
        let rows: Vec<usize> = y.iter().map(Vec::len).collect();
        let yw = stack(
            &fit.whiten,
            &y.iter().map(|r| DMatrix::from_column_slice(r.len(), 1, r)).collect::<Vec<_>>(),
        )?;
        let xw = stack(&fit.whiten, x)?;
        let base = orthonormal(&xw, None);
        Some(GlsTester { fit, y: yw.column(0).into_owned(), base, rows })
    }

    /// Stacked whitened rows.
    pub fn n(&self) -> usize {
        self.y.len()
    }

    /// Orthonormal basis (whitened, orthogonal to the current model) of a candidate's
    /// columns `c` (per run); `None` if the shapes do not match.
    pub fn candidate_basis(&self, c: &[DMatrix<f64>]) -> Option<DMatrix<f64>> {
        if c.len() != self.rows.len() || c.iter().zip(&self.rows).any(|(m, n)| m.nrows() != *n) {
            return None;
        }
        let cw = stack(&self.fit.whiten, c)?;
        Some(orthonormal(&cw, Some(&self.base)))
    }

    /// GLS Wald statistic of a candidate (`||Q^T y_w||^2`, chi-square with `Q`'s columns
    /// degrees of freedom under the null) and its upper-tail p.
    pub fn wald(&self, q: &DMatrix<f64>) -> (f64, f64) {
        let w = (q.transpose() * &self.y).norm_squared();
        (w, chi2_sf(w, q.ncols()))
    }
}

/// Columns (per run) that span what `extra` adds to `base` (per run, the same columns in
/// every run; coefficients shared across runs): the stacked columns of `extra` made
/// orthonormal after `base`'s, dropping those without a new direction, split back by run.
/// `None` when the shapes do not match.
pub fn independent_extension(base: &[DMatrix<f64>], extra: &[DMatrix<f64>]) -> Option<Vec<DMatrix<f64>>> {
    if base.len() != extra.len() || base.iter().zip(extra).any(|(b, e)| b.nrows() != e.nrows()) {
        return None;
    }
    let identity: Vec<DMatrix<f64>> = base.iter().map(|b| DMatrix::identity(b.nrows(), b.nrows())).collect();
    let b = orthonormal(&stack(&identity, base)?, None);
    let q = orthonormal(&stack(&identity, extra)?, Some(&b));
    let mut at = 0;
    Some(
        base.iter()
            .map(|r| {
                let part = q.rows(at, r.nrows()).into_owned();
                at += r.nrows();
                part
            })
            .collect(),
    )
}

/// Upper tail of chi-square with `dof` degrees of freedom (1 with none).
pub fn chi2_sf(x: f64, dof: usize) -> f64 {
    if dof == 0 {
        return 1.0;
    }
    ChiSquared::new(dof as f64).map_or(1.0, |c| c.sf(x))
}

/// `diag(W_r) * m_r` stacked over runs.
fn stack(whiten: &[DMatrix<f64>], m: &[DMatrix<f64>]) -> Option<DMatrix<f64>> {
    let cols = m.first()?.ncols();
    let rows: usize = m.iter().map(|r| r.nrows()).sum();
    let mut out = DMatrix::zeros(rows, cols);
    let mut at = 0;
    for (w, r) in whiten.iter().zip(m) {
        if w.ncols() != r.nrows() || r.ncols() != cols {
            return None;
        }
        out.view_mut((at, 0), (r.nrows(), cols)).copy_from(&(w * r));
        at += r.nrows();
    }
    Some(out)
}

/// Orthonormal basis of the columns of `m` after removing `against` (itself orthonormal),
/// by modified Gram-Schmidt twice; columns that keep less than [`RANK_TOLERANCE`] of their
/// norm are dropped.
fn orthonormal(m: &DMatrix<f64>, against: Option<&DMatrix<f64>>) -> DMatrix<f64> {
    let mut kept: Vec<DVector<f64>> = Vec::new();
    for j in 0..m.ncols() {
        let mut v = m.column(j).into_owned();
        let norm0 = v.norm();
        if norm0 <= 0.0 || !norm0.is_finite() {
            continue;
        }
        for _ in 0..2 {
            if let Some(b) = against {
                let c = b.transpose() * &v;
                v -= b * c;
            }
            for q in &kept {
                let c = q.dot(&v);
                v.axpy(-c, q, 1.0);
            }
        }
        let norm = v.norm();
        if norm > RANK_TOLERANCE * norm0 {
            kept.push(v / norm);
        }
    }
    if kept.is_empty() {
        DMatrix::zeros(m.nrows(), 0)
    } else {
        DMatrix::from_columns(&kept)
    }
}

/// SplitMix64 (Steele, Lea & Flood 2014): fixed-seed standard normals for the simulated
/// null (Box-Muller), and the relabellings of `select::permutation` (Fisher-Yates).
pub(crate) struct SplitMix64(pub(crate) u64);

impl SplitMix64 {
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn pair(&mut self) -> (f64, f64) {
        let (u, v) = (self.uniform(), self.uniform());
        let r = (-2.0 * u.ln()).sqrt();
        let a = std::f64::consts::TAU * v;
        (r * a.cos(), r * a.sin())
    }

    /// Shuffles `items` uniformly (Fisher-Yates; the modulo bias of `next_u64 % n` is below
    /// 2^-50 for the few dozen runs of a diagnosis).
    pub(crate) fn shuffle<T>(&mut self, items: &mut [T]) {
        for i in (1..items.len()).rev() {
            let j = (self.next_u64() % (i as u64 + 1)) as usize;
            items.swap(i, j);
        }
    }
}

/// Family-wise p of observed smallest Wald p's, by simulation under the fitted model: the
/// whitened null data orthogonal to the current model are standard normal, so each
/// simulated statistic of a basis `Q` (all candidates' grid points of one step) is
/// `||Q^T z||^2` with `z ~ N(0, I)` (`sims` draws, seed `seed`). For each observed p, the
/// Monte Carlo p `(1 + #{draws whose smallest p over all bases <= observed}) / (sims + 1)`.
/// (Compared as statistics: each basis's chi-square limit at the observed p.)
pub fn family_p(n: usize, bases: &[&DMatrix<f64>], observed: &[f64], sims: usize, seed: u64) -> Vec<f64> {
    const CHUNK: usize = 100;
    let bases: Vec<&DMatrix<f64>> = bases.iter().copied().filter(|q| q.ncols() > 0).collect();
    // limits[b][o]: the statistic of basis b whose p equals observed[o].
    let limits: Vec<Vec<f64>> = bases
        .iter()
        .map(|q| {
            let chi = ChiSquared::new(q.ncols() as f64).ok();
            observed
                .iter()
                .map(|p| match &chi {
                    Some(c) if *p < 1.0 => c.inverse_cdf(1.0 - p.max(1e-15)),
                    Some(_) => 0.0,
                    None => f64::INFINITY,
                })
                .collect()
        })
        .collect();
    // All bases side by side: one product per chunk of draws.
    let widths: Vec<usize> = bases.iter().map(|q| q.ncols()).collect();
    let total: usize = widths.iter().sum();
    let mut all = DMatrix::zeros(n, total);
    let mut at = 0;
    for q in &bases {
        all.columns_mut(at, q.ncols()).copy_from(q);
        at += q.ncols();
    }
    // The statistics depend on z only through all^T z ~ N(0, all^T all): draw that vector
    // directly as G u, G = V Lambda^1/2 from the eigen-decomposition of the Gram matrix
    // (size: the bases' columns, not the data).
    let eig = (all.transpose() * &all).symmetric_eigen();
    let mut gen = eig.eigenvectors;
    for (j, l) in eig.eigenvalues.iter().enumerate() {
        gen.column_mut(j).scale_mut(l.max(0.0).sqrt());
    }
    let chunks = sims.div_ceil(CHUNK);
    let counts: Vec<Vec<usize>> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            let cols = CHUNK.min(sims - c * CHUNK);
            let mut g = SplitMix64(seed ^ (c as u64 + 1).wrapping_mul(0xA24B_AED4_963E_E407));
            let mut z = DMatrix::zeros(total, cols);
            let mut spare = None;
            for v in z.iter_mut() {
                *v = match spare.take() {
                    Some(x) => x,
                    None => {
                        let (a, b) = g.pair();
                        spare = Some(b);
                        a
                    }
                };
            }
            let t = &gen * z;
            let mut hit = vec![vec![false; observed.len()]; cols];
            for (s, h) in hit.iter_mut().enumerate() {
                let col = t.column(s);
                let mut at = 0;
                for (w, lim) in widths.iter().zip(&limits) {
                    let stat: f64 = col.rows(at, *w).norm_squared();
                    at += w;
                    for (o, l) in lim.iter().enumerate() {
                        h[o] |= stat >= *l;
                    }
                }
            }
            (0..observed.len()).map(|o| hit.iter().filter(|h| h[o]).count()).collect()
        })
        .collect();
    (0..observed.len())
        .map(|o| (1 + counts.iter().map(|c| c[o]).sum::<usize>()) as f64 / (sims + 1) as f64)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spans(n: usize, len: usize) -> Vec<Span> {
        (0..n).map(|i| (i * len, (i + 1) * len)).collect()
    }

    /// The oracle of [`NoiseBasis::subset_covariance_sum`], from the AR(1) sums: the variance
    /// of the mean of the short means `selected` (per run, their spans; runs independent) at
    /// levels `(alpha, beta)`, `(1/n^2) sum_runs sum_{i,j} Sigma_ij`.
    fn variance_of_mean(selected: &[Vec<Span>], alpha: f64, beta: f64) -> f64 {
        let n: usize = selected.iter().map(Vec::len).sum();
        let mut sum = 0.0;
        for spans in selected {
            for (i, &a) in spans.iter().enumerate() {
                let (w, f) = unit_block_cov(a, a);
                sum += alpha * w + beta * f;
                for &b in &spans[i + 1..] {
                    let (w, f) = unit_block_cov(a, b);
                    sum += 2.0 * (alpha * w + beta * f);
                }
            }
        }
        sum / (n.max(1) as f64).powi(2)
    }

    /// White only: n means of L seconds have variance alpha / (L n) (closed form); with
    /// flicker, the sum of the run covariance matrix's entries over n^2 (the matrix the
    /// acceptance uses), over two independent runs and a subset with a hole.
    #[test]
    fn variance_of_a_mean_matches_closed_form_and_the_covariance_matrix() {
        let white = variance_of_mean(&[spans(12, 20), spans(8, 20)], 3.0, 0.0);
        assert!((white - 3.0 / (20.0 * 20.0)).abs() < 1e-15, "{white}");
        let run_a: Vec<Span> =
            spans(30, 20).into_iter().enumerate().filter(|(i, _)| i % 7 != 3).map(|(_, s)| s).collect();
        let run_b = spans(10, 20);
        let (alpha, beta) = (2.0, 0.3);
        let total = |s: &[Span]| run_covariance(s, alpha, beta).sum();
        let n = (run_a.len() + run_b.len()) as f64;
        let want = (total(&run_a) + total(&run_b)) / (n * n);
        let got = variance_of_mean(&[run_a.clone(), run_b.clone()], alpha, beta);
        assert!((got - want).abs() <= 1e-12 * want, "{got} vs {want}");
        // From the basis's cached matrices: the same sums, run by run, for a subset.
        let full_a = spans(30, 20);
        let basis = NoiseBasis::new(&[full_a, run_b.clone()]).expect("basis");
        let at_a: Vec<usize> = (0..30).filter(|i| i % 7 != 3).collect();
        let at_b: Vec<usize> = (0..10).collect();
        let cached = basis.subset_covariance_sum(0, &at_a, alpha, beta).expect("run 0")
            + basis.subset_covariance_sum(1, &at_b, alpha, beta).expect("run 1");
        assert!((cached / (n * n) - want).abs() <= 1e-12 * want, "{} vs {want}", cached / (n * n));
        assert_eq!(basis.subset_covariance_sum(2, &at_b, alpha, beta), None);
    }

    #[test]
    fn block_covariance_matches_the_double_sum() {
        let phi = (-1.0f64 / 10.0).exp();
        for (a, b) in [((0, 20), (0, 20)), ((0, 20), (20, 40)), ((40, 60), (0, 20)), ((5, 25), (10, 30))] {
            let mut direct = 0.0;
            for s in a.0..a.1 {
                for t in b.0..b.1 {
                    direct += phi.powi((s as i64 - t as i64).unsigned_abs() as i32);
                }
            }
            let closed = ar1_pair_sum(phi, a, b);
            assert!(
                (closed - direct).abs() <= 1e-12 * direct.abs().max(1.0),
                "{a:?} {b:?}: {closed} vs {direct}"
            );
        }
        // White: a 20 s mean of unit seconds has variance 1/20; disjoint means are uncorrelated.
        assert_eq!(unit_block_cov((0, 20), (0, 20)).0, 0.05);
        assert_eq!(unit_block_cov((0, 20), (20, 40)).0, 0.0);
    }

    #[test]
    fn orthonormal_basis_drops_dependent_columns() {
        let m = DMatrix::from_row_slice(4, 3, &[1.0, 2.0, 1.0, 1.0, 2.0, 0.0, 1.0, 2.0, 0.0, 1.0, 2.0, 1.0]);
        let q = orthonormal(&m, None);
        assert_eq!(q.ncols(), 2);
        assert!((q.transpose() * &q - DMatrix::identity(2, 2)).abs().max() < 1e-12);
    }
    /// `runs` runs of `blocks` 20 s short means drawn from the model at `(alpha, beta)` plus
    /// `rrw` (deg/h per sqrt(s)) of rate random walk, fixed seed.
    fn simulate(runs: usize, blocks: usize, alpha: f64, beta: f64, rrw: f64, seed: u64) -> Vec<Vec<f64>> {
        let sp = spans(blocks, 20);
        let chol = run_covariance(&sp, alpha, beta).cholesky().map(|c| c.l());
        let mut g = SplitMix64(seed);
        (0..runs)
            .map(|_| {
                let z = DVector::from_fn(blocks, |_, _| g.pair().0);
                let mut y: Vec<f64> = chol.as_ref().map_or(Vec::new(), |l| (l * z).iter().copied().collect());
                // Random walk: block means of a per-second walk, approximated by a walk of block steps.
                let mut walk = 0.0;
                for v in &mut y {
                    walk += rrw * 20f64.sqrt() * g.pair().0;
                    *v += walk;
                }
                y
            })
            .collect()
    }

    fn intercepts(runs: usize, blocks: usize) -> Vec<DMatrix<f64>> {
        (0..runs).map(|_| DMatrix::from_element(blocks, 1, 1.0)).collect()
    }

    /// `runs` runs of `blocks` contiguous 20 s short means: the noise basis and the
    /// intercept-only design.
    fn intercept_model(runs: usize, blocks: usize) -> (NoiseBasis, Vec<DMatrix<f64>>) {
        let sp = vec![spans(blocks, 20); runs];
        (NoiseBasis::new(&sp).expect("basis"), intercepts(runs, blocks))
    }

    #[test]
    fn reml_recovers_known_levels_and_the_check_passes() {
        // 16 runs x 360 short means (2 h each), the paper scenario's order of levels: white
        // 9e-4 (deg/h)^2 per second, flicker 2e-6 per decade. Tolerances: 10 % for the white
        // level (5760 means: its REML SD is about 2 %), 35 % for the flicker level (its
        // slow decades are seen in 16 runs only).
        let (alpha, beta) = (9e-4, 2e-6);
        let (runs, blocks) = (16, 360);
        let y = simulate(runs, blocks, alpha, beta, 0.0, 11);
        let sp = vec![spans(blocks, 20); runs];
        let fit =
            fit_noise(&NoiseBasis::new(&sp).expect("basis"), &intercepts(runs, blocks), &y).expect("fit");
        assert!((fit.white_var / alpha - 1.0).abs() < 0.10, "white {:.3e}", fit.white_var);
        assert!((fit.flicker_var / beta - 1.0).abs() < 0.35, "flicker {:.3e}", fit.flicker_var);
        assert!(!fit.at_edge);
        assert!(fit.check.passed, "{:?}", fit.check);
    }

    #[test]
    fn the_check_fails_on_a_rate_random_walk_the_family_does_not_hold() {
        // The same runs plus a rate random walk whose drift over a run (sqrt(7200) x 1e-4 =
        // 0.0085 deg/h) is several times the flicker's: excess variance at long windows.
        let (runs, blocks) = (16, 360);
        let y = simulate(runs, blocks, 9e-4, 2e-6, 1e-4, 12);
        let sp = vec![spans(blocks, 20); runs];
        let fit =
            fit_noise(&NoiseBasis::new(&sp).expect("basis"), &intercepts(runs, blocks), &y).expect("fit");
        assert!(!fit.check.passed, "{:?}", fit.check);
    }

    #[test]
    fn gls_wald_statistic_matches_a_dense_reference() {
        // 3 runs of 15 short means, base [1, t], candidate two columns; levels fitted.
        let (runs, blocks) = (3, 15);
        let y = simulate(runs, blocks, 9e-4, 2e-5, 0.0, 13);
        let sp = vec![spans(blocks, 20); runs];
        let x: Vec<DMatrix<f64>> = (0..runs)
            .map(|r| DMatrix::from_fn(blocks, 2, |i, j| if j == 0 { 1.0 } else { (i + r) as f64 }))
            .collect();
        let c: Vec<DMatrix<f64>> = (0..runs)
            .map(|r| DMatrix::from_fn(blocks, 2, |i, j| ((i * (j + 2) + r) as f64 * 0.7).sin()))
            .collect();
        let fit = fit_noise(&NoiseBasis::new(&sp).expect("basis"), &x, &y).expect("fit");
        let tester = GlsTester::new(&fit, &x, &y).expect("tester");
        let q = tester.candidate_basis(&c).expect("basis");
        let (w, p) = tester.wald(&q);
        // Dense: block-diagonal Sigma, GLS RSS with and without the candidate.
        let n = runs * blocks;
        let sigma_run = run_covariance(&sp[0], fit.white_var, fit.flicker_var);
        let mut sigma = DMatrix::zeros(n, n);
        for r in 0..runs {
            sigma.view_mut((r * blocks, r * blocks), (blocks, blocks)).copy_from(&sigma_run);
        }
        let inv = sigma.try_inverse().expect("inverse");
        let yv = DVector::from_iterator(n, y.iter().flatten().copied());
        let stacked = |m: &[DMatrix<f64>]| {
            let k = m[0].ncols();
            DMatrix::from_fn(n, k, |i, j| m[i / blocks][(i % blocks, j)])
        };
        let rss = |xm: &DMatrix<f64>| {
            let a = xm.transpose() * &inv * xm;
            let b = xm.transpose() * &inv * &yv;
            let beta = a.try_inverse().expect("normal equations") * b;
            let e = &yv - xm * beta;
            (e.transpose() * &inv * e)[(0, 0)]
        };
        let xb = stacked(&x);
        let mut xf = DMatrix::zeros(n, 4);
        xf.columns_mut(0, 2).copy_from(&xb);
        xf.columns_mut(2, 2).copy_from(&stacked(&c));
        let dense = rss(&xb) - rss(&xf);
        assert!((w - dense).abs() <= 1e-8 * dense.abs().max(1.0), "{w} vs {dense}");
        assert_eq!(q.ncols(), 2);
        // scipy.stats.chi2.sf(x, 2) = exp(-x / 2).
        assert!((p - (-w / 2.0).exp()).abs() < 1e-12);
    }

    #[test]
    fn family_p_of_one_column_is_its_own_p_and_of_two_is_sidak() {
        // One unit column: the family-wise p of an observed p is that p (2000 draws; the
        // Monte Carlo p's SD at 0.05 is 0.0049, tolerance 0.02).
        let n = 50;
        let mut q = DMatrix::zeros(n, 1);
        q[(3, 0)] = 1.0;
        let one = family_p(n, &[&q], &[0.05, 1.0], 2000, 7);
        assert!((one[0] - 0.05).abs() < 0.02, "{one:?}");
        assert_eq!(one[1], 1.0);
        // Two orthogonal columns tested separately: 1 - 0.95^2 = 0.0975 (tolerance 0.027).
        let mut q2 = DMatrix::zeros(n, 1);
        q2[(7, 0)] = 1.0;
        let two = family_p(n, &[&q, &q2], &[0.05], 2000, 8);
        assert!((two[0] - 0.0975).abs() < 0.027, "{two:?}");
        // Two columns in one basis (2 dof) against the closed form exp(-x / 2).
        let mut q3 = DMatrix::zeros(n, 2);
        q3[(3, 0)] = 1.0;
        q3[(7, 1)] = 1.0;
        let joint = family_p(n, &[&q3], &[0.05], 2000, 9);
        assert!((joint[0] - 0.05).abs() < 0.02, "{joint:?}");
    }

    #[test]
    fn heldout_gls_matches_a_dense_reference() {
        // 4 runs of 12 short means, design [1, t, sin] with a penalty row on the last two
        // coefficients; levels fitted. Reference: dense Sigma per run, normal equations
        // with the penalty row weighted by 1 / (mean short-mean variance), each run left
        // out in turn, held-out error e^T Sigma_r^-1 e (1e-8 relative).
        let (runs, blocks) = (4, 12);
        let y = simulate(runs, blocks, 9e-4, 2e-5, 0.0, 21);
        let sp = vec![spans(blocks, 20); runs];
        let x: Vec<DMatrix<f64>> = (0..runs)
            .map(|r| {
                DMatrix::from_fn(blocks, 3, |i, j| match j {
                    0 => 1.0,
                    1 => (i + 3 * r) as f64 / 10.0,
                    _ => ((i * 7 + r) as f64 * 0.4).sin(),
                })
            })
            .collect();
        let pen = DMatrix::from_row_slice(1, 3, &[0.0, 1.0, -1.0]);
        let fit = fit_noise(&NoiseBasis::new(&sp).expect("basis"), &x, &y).expect("fit");
        let got = heldout_gls(&fit, &x, &y, Some(&pen)).expect("held out");
        let inv = run_covariance(&sp[0], fit.white_var, fit.flicker_var).try_inverse().expect("inverse");
        let mean_var = run_covariance(&sp[0], fit.white_var, fit.flicker_var).trace() / blocks as f64;
        let normal = |skip: Option<usize>| {
            let mut a = pen.transpose() * &pen / mean_var;
            let mut b = DVector::zeros(3);
            for r in (0..runs).filter(|r| Some(*r) != skip) {
                let yr = DVector::from_column_slice(&y[r]);
                a += x[r].transpose() * &inv * &x[r];
                b += x[r].transpose() * &inv * yr;
            }
            a.try_inverse().expect("normal equations") * b
        };
        let mut sse = 0.0;
        for r in 0..runs {
            let e = DVector::from_column_slice(&y[r]) - &x[r] * normal(Some(r));
            sse += (e.transpose() * &inv * &e)[(0, 0)];
        }
        assert!((got.sse() - sse).abs() <= 1e-8 * sse, "{} vs {sse}", got.sse());
        let full = normal(None);
        assert!((&got.beta - &full).norm() <= 1e-8 * full.norm(), "{} vs {full}", got.beta);
    }

    #[test]
    fn independent_extension_spans_what_the_extra_columns_add() {
        // 3 runs x 5 short means, base = an intercept; extra = [a, 2a + 1 (no new direction
        // beyond a and the base), b]: two columns come back, orthonormal when stacked,
        // orthogonal to the base, and a and b lie in the span of base and them (1e-12).
        let (runs, blocks) = (3, 5);
        let base = intercepts(runs, blocks);
        let a = |r: usize, i: usize| ((i + 2 * r) as f64).sin();
        let b = |r: usize, i: usize| if r == 1 { (i * i) as f64 } else { 0.0 };
        let extra: Vec<DMatrix<f64>> = (0..runs)
            .map(|r| {
                DMatrix::from_fn(blocks, 3, |i, j| match j {
                    0 => a(r, i),
                    1 => 2.0 * a(r, i) + 1.0,
                    _ => b(r, i),
                })
            })
            .collect();
        let q = independent_extension(&base, &extra).expect("shapes");
        assert!(q.iter().all(|m| m.ncols() == 2 && m.nrows() == blocks));
        let identity: Vec<DMatrix<f64>> = (0..runs).map(|_| DMatrix::identity(blocks, blocks)).collect();
        let qs = stack(&identity, &q).expect("stack");
        let gram = qs.transpose() * &qs;
        assert!((gram - DMatrix::identity(2, 2)).amax() < 1e-12);
        let ones = stack(&identity, &base).expect("stack");
        assert!((ones.transpose() * &qs).amax() < 1e-12);
        let mut span = DMatrix::zeros(runs * blocks, 3);
        span.column_mut(0).copy_from(&ones.column(0));
        span.columns_mut(1, 2).copy_from(&qs);
        let u = span.qr().q();
        let xs = stack(&identity, &extra).expect("stack");
        let left = &xs - &u * (u.transpose() * &xs);
        assert!(left.amax() < 1e-12 * xs.amax(), "{}", left.amax());
        // Mismatched shapes: None.
        assert!(independent_extension(&base, &extra[..2]).is_none());
    }

    #[test]
    fn an_orientation_candidates_wald_p_is_nominal_at_the_current_levels_not_at_its_spans() {
        // The orientation family's shape: 8 runs in two positions (4 each), null data from
        // the model (1000 fixed seeds); the family's grid = a per-position constant, a ramp of
        // opposite sign by position with a per-run offset (the scale factor's degree 1) and
        // that ramp with its square (degree 2). The degree-1 column's Wald p:
        // - at the current model's levels (REML with the intercept only: the route's default)
        //   its share at 0.05 and 0.01 is within 3.5 binomial SD (0.024, 0.011) of nominal;
        // - at levels fitted with the family's whole span in the model
        //   (`DiagnoseOptions::noise_model_family_levels`) it is heavier-tailed than
        //   chi-square(1): the variance is then estimated from what the column does not
        //   touch, few per-run degrees of freedom of the flicker, an F-like statistic. Its
        //   share at 0.01 is more than 3.5 SD above nominal; that is why the option is off.
        let (runs, blocks, draws) = (8, 90, 1000);
        let (basis, base) = intercept_model(runs, blocks);
        let sign = |r: usize| if r < 4 { 1.0 } else { -1.0 };
        let ramp = |r: usize, i: usize| sign(r) * ((i as f64 / blocks as f64) + r as f64 % 4.0 - 1.5);
        let family: Vec<DMatrix<f64>> = (0..runs)
            .map(|r| {
                DMatrix::from_fn(blocks, 4, |i, j| match j {
                    0 => f64::from(u8::from(r >= 4)),
                    1 | 2 => ramp(r, i),
                    _ => sign(r) * ramp(r, i).powi(2),
                })
            })
            .collect();
        let span = independent_extension(&base, &family).expect("span");
        assert!(span.iter().all(|m| m.ncols() == 3), "three directions beyond the intercept");
        let with: Vec<DMatrix<f64>> = base
            .iter()
            .zip(&span)
            .map(|(b, e)| DMatrix::from_fn(blocks, 4, |i, j| if j == 0 { b[(i, 0)] } else { e[(i, j - 1)] }))
            .collect();
        let degree_one: Vec<DMatrix<f64>> = family.iter().map(|m| m.columns(1, 1).into_owned()).collect();
        let shares = |levels_design: &[DMatrix<f64>]| -> (f64, f64) {
            let ps: Vec<f64> = (0..draws)
                .into_par_iter()
                .map(|d| {
                    let y = simulate(runs, blocks, 9e-4, 2e-6, 0.0, 3000 + d as u64);
                    let fit = fit_noise(&basis, levels_design, &y).expect("fit");
                    let tester = GlsTester::new(&fit, &base, &y).expect("tester");
                    tester.wald(&tester.candidate_basis(&degree_one).expect("basis")).1
                })
                .collect();
            let share = |level: f64| ps.iter().filter(|p| **p <= level).count() as f64 / draws as f64;
            (share(0.05), share(0.01))
        };
        let (current_05, current_01) = shares(&base);
        let (span_05, span_01) = shares(&with);
        eprintln!("current levels: {current_05} {current_01}; family-span levels: {span_05} {span_01}");
        assert!((current_05 - 0.05).abs() <= 0.024, "current levels: {current_05} at 0.05");
        assert!((current_01 - 0.01).abs() <= 0.011, "current levels: {current_01} at 0.01");
        assert!(span_01 > 0.01 + 0.011, "family-span levels: {span_01} at 0.01");
    }

    #[test]
    fn wald_p_with_the_candidate_in_the_levels_holds_its_nominal_level() {
        // Null data from the model (8 runs x 90 short means, 300 fixed seeds); a one-column
        // candidate (a slow ramp in half of the runs); levels refitted by REML with the
        // candidate in the model, Wald p at those levels. Share of p <= 0.05 and <= 0.20:
        // binomial SDs 0.0126 and 0.023; tolerances 3.5 SD (0.044 and 0.081).
        let (runs, blocks, draws) = (8, 90, 300);
        let (basis, base) = intercept_model(runs, blocks);
        let cand: Vec<DMatrix<f64>> = (0..runs)
            .map(|r| {
                DMatrix::from_fn(blocks, 1, |i, _| if r % 2 == 0 { i as f64 / blocks as f64 } else { 0.0 })
            })
            .collect();
        let with: Vec<DMatrix<f64>> = base
            .iter()
            .zip(&cand)
            .map(|(b, c)| DMatrix::from_fn(blocks, 2, |i, j| if j == 0 { b[(i, 0)] } else { c[(i, 0)] }))
            .collect();
        let ps: Vec<f64> = (0..draws)
            .into_par_iter()
            .map(|d| {
                let y = simulate(runs, blocks, 9e-4, 2e-6, 0.0, 1000 + d as u64);
                let fit = fit_noise(&basis, &with, &y).expect("fit");
                let tester = GlsTester::new(&fit, &base, &y).expect("tester");
                tester.wald(&tester.candidate_basis(&cand).expect("basis")).1
            })
            .collect();
        for (level, tol) in [(0.05, 0.044), (0.20, 0.081)] {
            let share = ps.iter().filter(|p| **p <= level).count() as f64 / draws as f64;
            assert!((share - level).abs() <= tol, "share {share} at {level}");
        }
    }
}
