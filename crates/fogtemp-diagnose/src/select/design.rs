//! Design matrices and cross-validation: the scaled design `[1 | terms]`, the full and
//! leave-one-run-out (LORO) fits, BIC on the effective sample size, and the profiling of a
//! candidate over its grid (complexity by LORO error, continuous parameters by BIC).

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::rules::{fold_shares, stability_t, training_fold_shares};
use crate::effects::{EffectGrid, TermColumns};
use crate::error::DiagnoseError;
use crate::linalg::{compress, fit_stacked, sse_of};
use crate::prepare::Prepared;

/// A scaled design: per run `n_r x p`, first column the constant.
pub struct Design {
    /// Per-run matrices with unit-RMS columns.
    pub per_run: Vec<DMatrix<f64>>,
    /// Scale divided out of each column.
    pub scale: Vec<f64>,
    /// Penalty pseudo-observations on the scaled coefficients (rows x p), target 0.
    pub penalty: Option<DMatrix<f64>>,
}

impl Design {
    /// Number of columns.
    pub fn p(&self) -> usize {
        self.scale.len()
    }
}

/// Builds `[1 | parts...]` per run with columns scaled to unit RMS over all runs.
pub fn build_design(prep: &Prepared, parts: &[&TermColumns]) -> Design {
    let p = 1 + parts.iter().map(|t| t.k()).sum::<usize>();
    let mut per_run: Vec<DMatrix<f64>> = prep
        .runs
        .iter()
        .enumerate()
        .map(|(r, run)| {
            let n = run.blocks.len();
            let mut m = DMatrix::zeros(n, p);
            m.column_mut(0).fill(1.0);
            let mut at = 1;
            for t in parts {
                m.view_mut((0, at), (n, t.k())).copy_from(&t.per_run[r]);
                at += t.k();
            }
            m
        })
        .collect();
    let n_total: usize = per_run.iter().map(|m| m.nrows()).sum();
    let scale: Vec<f64> = (0..p)
        .map(|k| {
            let ss: f64 = per_run.iter().map(|m| m.column(k).norm_squared()).sum();
            let rms = (ss / n_total.max(1) as f64).sqrt();
            if rms > 0.0 && rms.is_finite() {
                rms
            } else {
                1.0
            }
        })
        .collect();
    for m in &mut per_run {
        for (k, s) in scale.iter().enumerate() {
            m.column_mut(k).unscale_mut(*s);
        }
    }
    let penalty = design_penalty(parts, &scale);
    Design { per_run, scale, penalty }
}

/// Penalty rows of all parts, placed on their columns and expressed in scaled coefficients.
pub(super) fn design_penalty(parts: &[&TermColumns], scale: &[f64]) -> Option<DMatrix<f64>> {
    let rows: usize = parts.iter().filter_map(|t| t.penalty.as_ref().map(|m| m.nrows())).sum();
    if rows == 0 {
        return None;
    }
    let mut pen = DMatrix::zeros(rows, scale.len());
    let (mut row, mut col) = (0, 1);
    for t in parts {
        if let Some(m) = &t.penalty {
            for i in 0..m.nrows() {
                for j in 0..t.k() {
                    pen[(row + i, col + j)] = m[(i, j)] / scale[col + j];
                }
            }
            row += m.nrows();
        }
        col += t.k();
    }
    Some(pen)
}

/// Residual short means per run.
pub fn targets(prep: &Prepared) -> Vec<Vec<f64>> {
    prep.runs.iter().map(|r| r.blocks.iter().map(|b| b.resid_dph).collect()).collect()
}

/// Block numbers per run (for lags).
pub fn block_indices(prep: &Prepared) -> Vec<Vec<usize>> {
    prep.runs.iter().map(|r| r.blocks.iter().map(|b| b.index).collect()).collect()
}

/// Full fit and every LORO fold of one design.
pub struct FoldEval {
    /// RSS of the full fit.
    pub full_rss: f64,
    /// Coefficients of the full fit (scaled design).
    pub full_beta: DVector<f64>,
    /// Training RSS of each fold.
    pub train_rss: Vec<f64>,
    /// Held-out squared error of each fold.
    pub fold_sse: Vec<f64>,
    /// Coefficients of each fold.
    pub fold_beta: Vec<DVector<f64>>,
}

/// Fits the design to all runs and in every leave-one-run-out fold.
///
/// # Errors
/// [`DiagnoseError::Fit`] if a fit has no rows or produces non-finite values.
pub fn fold_eval(design: &Design, ys: &[Vec<f64>]) -> Result<FoldEval, DiagnoseError> {
    let p = design.p();
    let rs: Vec<DMatrix<f64>> = design.per_run.iter().zip(ys).map(|(x, y)| compress(x, y)).collect();
    let pen = design.penalty.as_ref().map(|m| compress(m, &vec![0.0; m.nrows()]));
    let mut all: Vec<&DMatrix<f64>> = rs.iter().collect();
    all.extend(pen.as_ref());
    let failed = || DiagnoseError::Fit("least squares failed (no rows or non-finite values)");
    let (full_beta, full_rss) = fit_stacked(&all, p).ok_or_else(failed)?;
    let mut train_rss = Vec::with_capacity(rs.len());
    let mut fold_sse = Vec::with_capacity(rs.len());
    let mut fold_beta = Vec::with_capacity(rs.len());
    for j in 0..rs.len() {
        let mut others: Vec<&DMatrix<f64>> =
            rs.iter().enumerate().filter(|(i, _)| *i != j).map(|(_, r)| r).collect();
        others.extend(pen.as_ref());
        let (beta, rss) = fit_stacked(&others, p).ok_or_else(failed)?;
        fold_sse.push(sse_of(&rs[j], &beta));
        train_rss.push(rss);
        fold_beta.push(beta);
    }
    Ok(FoldEval { full_rss, full_beta, train_rss, fold_sse, fold_beta })
}

/// `n_eff ln(rss / n) + k ln(n_eff)`.
pub fn bic(rss: f64, k: usize, n: usize, n_eff: f64) -> f64 {
    n_eff * (rss.max(1e-300) / n as f64).ln() + k as f64 * n_eff.ln()
}

/// A candidate after profiling.
pub(super) struct Profiled {
    pub(super) point: usize,
    /// Linear coefficients of the term at `point` (its complexity).
    pub(super) coefficients: usize,
    pub(super) bic: f64,
    pub(super) full_beta: DVector<f64>,
    pub(super) fold_sse: Vec<f64>,
    pub(super) design_scale: Vec<f64>,
    /// Jackknife t of the contribution over LORO folds (see [`super::rules::stability_t`]).
    pub(super) stability_t: f64,
    /// Smallest share `c_j` of the full-data contribution that a fold reproduces.
    pub(super) min_fold_share: f64,
    /// Held-out residual of each run, predicted by its fold's fit (at the fold's point).
    pub(super) fold_resid: Vec<Vec<f64>>,
}

pub(super) fn profile_candidate(
    prep: &Prepared,
    base: &[&TermColumns],
    grid: &EffectGrid,
    ys: &[Vec<f64>],
    n_eff: f64,
) -> Result<Profiled, DiagnoseError> {
    let p_base = 1 + base.iter().map(|t| t.k()).sum::<usize>();
    let evals: Vec<(FoldEval, usize, Vec<f64>)> = grid
        .points
        .par_iter()
        .map(|cols| {
            let mut parts = base.to_vec();
            parts.push(cols);
            let design = build_design(prep, &parts);
            let k = p_base + cols.k() + grid.params.len() - grid.effect.inactive_parameters(&cols.theta);
            fold_eval(&design, ys).map(|e| (e, k, design.scale))
        })
        .collect::<Result<_, _>>()?;
    // Complexity (the discrete parameters) by LORO error; continuous parameters by BIC,
    // re-chosen in every fold from its training runs.
    let discrete = |j: usize| complexity_key(grid, j);
    let mut keys: Vec<Vec<u64>> = (0..evals.len()).map(discrete).collect();
    keys.sort();
    keys.dedup();
    let profiled: Vec<Profiled> = keys
        .iter()
        .map(|key| {
            let members: Vec<usize> = (0..evals.len()).filter(|&j| discrete(j) == *key).collect();
            profile_members(prep, base, grid, &evals, &members, ys, n_eff)
        })
        .collect();
    let choice = if grid.effect.nested_complexity() {
        one_standard_error_choice(profiled)
    } else {
        profiled.into_iter().min_by(|a, b| total_cv(a).total_cmp(&total_cv(b)))
    };
    choice.ok_or(DiagnoseError::Fit("empty profiling grid"))
}

/// The complexity of grid point `point`: its discrete parameters' values (basis size,
/// number of exponentials, degree, form), as bits so they can be compared and ordered.
pub(super) fn complexity_key(grid: &EffectGrid, point: usize) -> Vec<u64> {
    grid.params
        .iter()
        .zip(&grid.points[point].theta)
        .filter(|(p, _)| !p.continuous)
        .map(|(_, v)| v.to_bits())
        .collect()
}

pub(super) fn total_cv(p: &Profiled) -> f64 {
    p.fold_sse.iter().sum()
}

/// The size of a penalised basis by the one-standard-error rule of cross-validation
/// (Breiman et al. 1984; Hastie, Tibshirani & Friedman, *Elements of Statistical Learning*
/// 7.10): the smallest basis whose LORO error is within one standard error of the smallest,
/// the standard error from the spread of its per-run held-out errors. The penalty keeps a
/// bigger basis smooth, so the LORO error is flat over sizes and its minimum is decided by
/// noise; a bigger basis than needed is then judged (and rejected) as unstable. The same
/// for a warm-up's second exponential, a nested refinement that can mimic other effects'
/// power-on signatures. (Discrete choices between distinct terms, such as a polynomial
/// degree or a hysteresis form, keep the smallest error.)
pub(super) fn one_standard_error_choice(profiled: Vec<Profiled>) -> Option<Profiled> {
    let best = profiled.iter().min_by(|a, b| total_cv(a).total_cmp(&total_cv(b)))?;
    let limit = total_cv(best) + standard_error_of_total(&best.fold_sse);
    profiled
        .into_iter()
        .filter(|p| total_cv(p) <= limit)
        .min_by(|a, b| a.coefficients.cmp(&b.coefficients).then(total_cv(a).total_cmp(&total_cv(b))))
}

/// Standard error of a total over folds, g x (sd / sqrt(g)), the sd from the spread of the
/// per-fold values (the one-standard-error rules' unit).
pub(super) fn standard_error_of_total(per_fold: &[f64]) -> f64 {
    let g = per_fold.len() as f64;
    let mean = per_fold.iter().sum::<f64>() / g;
    let sd = (per_fold.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (g - 1.0).max(1.0)).sqrt();
    sd * g.sqrt()
}

/// BIC profile over `members` (grid points differing only in continuous parameters).
pub(super) fn profile_members(
    prep: &Prepared,
    base: &[&TermColumns],
    grid: &EffectGrid,
    evals: &[(FoldEval, usize, Vec<f64>)],
    members: &[usize],
    ys: &[Vec<f64>],
    n_eff: f64,
) -> Profiled {
    let n = prep.n_blocks();
    let pick = |score: &dyn Fn(usize) -> f64| -> usize {
        members.iter().copied().min_by(|&a, &b| score(a).total_cmp(&score(b))).unwrap_or(members[0])
    };
    let best = pick(&|g| bic(evals[g].0.full_rss, evals[g].1, n, n_eff));
    let fold_points: Vec<usize> = (0..prep.runs.len())
        .map(|j| {
            let n_train = n - prep.runs[j].blocks.len();
            let neff_train = n_eff * n_train as f64 / n as f64;
            pick(&|g| bic(evals[g].0.train_rss[j], evals[g].1, n_train, neff_train))
        })
        .collect();
    let fold_sse = fold_points.iter().enumerate().map(|(j, &g)| evals[g].0.fold_sse[j]).collect();
    let fold_resid = fold_points
        .iter()
        .enumerate()
        .map(|(j, &g)| {
            let mut parts = base.to_vec();
            parts.push(&grid.points[g]);
            run_residual(&parts, &evals[g].0.fold_beta[j], &evals[g].2, j, &ys[j])
        })
        .collect();
    let (eval, k, scale) = &evals[best];
    let full = contribution(prep, &grid.points[best], &eval.full_beta, scale);
    let folds: Vec<Vec<Vec<f64>>> = fold_points
        .iter()
        .enumerate()
        .map(|(j, &g)| contribution(prep, &grid.points[g], &evals[g].0.fold_beta[j], &evals[g].2))
        .collect();
    Profiled {
        point: best,
        coefficients: grid.points[best].k(),
        bic: bic(eval.full_rss, *k, n, n_eff),
        full_beta: eval.full_beta.clone(),
        fold_sse,
        design_scale: scale.clone(),
        stability_t: stability_t(&fold_shares(&full, &folds)),
        min_fold_share: training_fold_shares(&full, &folds).into_iter().fold(f64::INFINITY, f64::min),
        fold_resid,
    }
}

/// Residual `y - [1 | parts] beta` of run `r`, with `beta` on the design scaled by `scale`
/// (see [`build_design`]).
pub(super) fn run_residual(
    parts: &[&TermColumns],
    beta: &DVector<f64>,
    scale: &[f64],
    r: usize,
    y: &[f64],
) -> Vec<f64> {
    let constant = beta[0] / scale[0];
    y.iter()
        .enumerate()
        .map(|(i, yi)| {
            let mut at = 1;
            let mut fitted = constant;
            for t in parts {
                let m = &t.per_run[r];
                for c in 0..t.k() {
                    fitted += m[(i, c)] * beta[at + c] / scale[at + c];
                }
                at += t.k();
            }
            yi - fitted
        })
        .collect()
}

/// R^2 of `v` (per run) on the columns of `z` (per run, holding a constant), computed from
/// per-run QR factors.
pub fn r_squared_runs(v: &[Vec<f64>], z: &[DMatrix<f64>]) -> f64 {
    let n: usize = v.iter().map(Vec::len).sum();
    let mean = v.iter().flatten().sum::<f64>() / n.max(1) as f64;
    let total: f64 = v.iter().flatten().map(|a| (a - mean).powi(2)).sum();
    let p = z.first().map_or(0, |m| m.ncols());
    let rs: Vec<DMatrix<f64>> = z.iter().zip(v).map(|(x, y)| compress(x, y)).collect();
    let refs: Vec<&DMatrix<f64>> = rs.iter().collect();
    let Some((_, rss)) = fit_stacked(&refs, p) else { return f64::NAN };
    if total <= 1e-30 * (1.0 + mean * mean) * n as f64 {
        return if rss <= 1e-24 * n as f64 { 1.0 } else { 0.0 };
    }
    (1.0 - rss / total).clamp(0.0, 1.0)
}

/// The candidate's fitted contribution per run (unscaled, from a design whose last
/// `cols.k()` columns are the candidate).
pub(super) fn contribution(
    prep: &Prepared,
    cols: &TermColumns,
    beta: &DVector<f64>,
    scale: &[f64],
) -> Vec<Vec<f64>> {
    let p = beta.len();
    let k = cols.k();
    let coef: Vec<f64> = (0..k).map(|c| beta[p - k + c] / scale[p - k + c]).collect();
    (0..prep.runs.len())
        .map(|r| {
            let m = &cols.per_run[r];
            (0..m.nrows()).map(|i| (0..k).map(|c| m[(i, c)] * coef[c]).sum()).collect()
        })
        .collect()
}

/// Per-run design `[base | extra]` unscaled.
pub(super) fn concat(base: &Design, extra: &[&DMatrix<f64>], r: usize) -> DMatrix<f64> {
    let b = &base.per_run[r];
    let parts: Vec<&DMatrix<f64>> = std::iter::once(b).chain(extra.iter().copied()).collect();
    hcat(b.nrows(), &parts)
}

/// Per run, `[base | extra_r]` unscaled: the current model with one term's columns added.
pub(super) fn concat_runs(base: &Design, extra: &[DMatrix<f64>]) -> Vec<DMatrix<f64>> {
    extra.iter().enumerate().map(|(r, e)| concat(base, &[e], r)).collect()
}

/// `parts` side by side, each `rows` tall.
pub(super) fn hcat(rows: usize, parts: &[&DMatrix<f64>]) -> DMatrix<f64> {
    let k: usize = parts.iter().map(|m| m.ncols()).sum();
    let mut m = DMatrix::zeros(rows, k);
    let mut at = 0;
    for e in parts {
        m.view_mut((0, at), e.shape()).copy_from(*e);
        at += e.ncols();
    }
    m
}

pub(super) fn run_dummies(prep: &Prepared, r: usize) -> DMatrix<f64> {
    let n = prep.runs[r].blocks.len();
    DMatrix::from_fn(n, prep.runs.len(), |_, j| f64::from(u8::from(j == r)))
}

/// RSS of the full fit of `[1 | parts]`.
pub(super) fn full_rss(prep: &Prepared, parts: &[&TermColumns], ys: &[Vec<f64>]) -> f64 {
    let design = build_design(prep, parts);
    let mut rs: Vec<DMatrix<f64>> = design.per_run.iter().zip(ys).map(|(x, y)| compress(x, y)).collect();
    rs.extend(design.penalty.as_ref().map(|m| compress(m, &vec![0.0; m.nrows()])));
    let refs: Vec<&DMatrix<f64>> = rs.iter().collect();
    fit_stacked(&refs, design.p()).map_or(f64::INFINITY, |f| f.1)
}

/// In-sample residual of a design's full fit, per run.
pub fn residuals(design: &Design, beta: &DVector<f64>, ys: &[Vec<f64>]) -> Vec<Vec<f64>> {
    design
        .per_run
        .iter()
        .zip(ys)
        .map(|(x, y)| {
            let fitted = x * beta;
            y.iter().zip(fitted.iter()).map(|(a, b)| a - b).collect()
        })
        .collect()
}

/// Held-out (LORO) results of a design: residual per run per short mean.
pub fn heldout_residuals(design: &Design, eval: &FoldEval, ys: &[Vec<f64>]) -> Vec<Vec<f64>> {
    design
        .per_run
        .iter()
        .zip(ys)
        .zip(&eval.fold_beta)
        .map(|((x, y), beta)| {
            let fitted = x * beta;
            y.iter().zip(fitted.iter()).map(|(a, b)| a - b).collect()
        })
        .collect()
}

/// Pooled RMS of per-run series.
pub fn pooled_rms(values: &[Vec<f64>]) -> f64 {
    let n: usize = values.iter().map(Vec::len).sum();
    (values.iter().flatten().map(|v| v * v).sum::<f64>() / n.max(1) as f64).sqrt()
}
