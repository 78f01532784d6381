//! Model choice: profiling, leave-one-run-out (LORO) cross-validation, BIC on the
//! effective sample size, concealment, forward selection, and the held-out evaluation of
//! the chosen model.
//!
//! Definitions (stated in the report too):
//! - model: `residual = c + sum of chosen terms + e` fitted to the short means of all runs
//!   by least squares (per-run QR, stacked);
//! - LORO: each run is predicted by the model fitted to the other runs; a candidate's
//!   continuous profiled parameters (time constants, thresholds) are chosen by BIC and
//!   re-chosen in each fold from the training runs only; its complexity (basis size,
//!   polynomial degree) is the one with the lowest LORO error (slightly optimistic: a
//!   choice among at most 7 values), the size of a penalised spline basis the smallest
//!   within one standard error of it (see [`one_standard_error_choice`]);
//! - BIC = `n_eff ln(RSS / n) + k ln(n_eff)`, `n_eff = n / (1 + 2 sum_k w_k rho_k)`, rho_k
//!   the autocorrelations at lags 1..L (L = the Newey-West bandwidth) of the current
//!   model's residual short means within runs, Bartlett weights `w_k = 1 - k/(L+1)`, k =
//!   linear coefficients + profiled parameters;
//! - a fold (held-out run) is informative when the term's fitted contribution there, about
//!   its mean over all runs, has an RMS of at least a quarter of the noise of one short
//!   mean; a term is accepted when it is identifiable, lowers the total LORO error,
//!   improves at least `min_fold_fraction` of the informative folds (and at least two),
//!   lowers BIC, and is stable across folds (jackknife t of its contribution, see
//!   [`stability_t`], above the two-sided Student-t limit with runs - 1 degrees of freedom
//!   at 5 % / number of candidates; for a flexible term with more than two coefficients, a
//!   basis in T whose local coefficients a left-out run moves, every fold must instead
//!   reproduce, on its training runs, at least half of the full-data contribution). The accepted candidate with the lowest LORO error enters; selection
//!   stops when no candidate is accepted or `max_effects` are in.
//! - concealment index: R^2 of the candidate's fitted contribution on the terms already
//!   in the model.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::effects::{term_columns, Effect, EffectGrid, TermColumns};
use super::linalg::{
    autocorrelations, compress, effective_n, fit_stacked, jackknife_covariance, parabola_vertex, sse_of,
};
use super::prepare::Prepared;
use super::{CandidateReport, DiagnoseOptions, LeftOutEffect, Parameter, SelectionStep};
use crate::error::DiagnoseError;
use fogtemp_cal::metrics::{bias_stability, rms_over_runs, BiasStabilityOptions};

/// A held-out run is informative about a term when the term's contribution there (about its
/// mean over all runs) has an RMS of at least this fraction of the noise of one short mean.
/// (A matched-filter rule, `sqrt(sum v^2) / sigma >= 3`, counted near-zero-contribution runs
/// as informative; under flicker they improve at random and the fold rule then rejected real
/// effects and admitted spurious second terms: docs/diagnose.md.)
const MATERIAL_FRACTION: f64 = 0.25;

/// A term in the model: an effect at one grid point.
#[derive(Clone, Debug, PartialEq)]
pub struct ChosenTerm {
    /// The effect.
    pub effect: Effect,
    /// Index into the effect's grid (the profiled point before refinement).
    pub point: usize,
    /// The term's columns at its refined parameters.
    pub columns: TermColumns,
    /// Concealment index when it entered.
    pub concealment_index: f64,
    /// Most confusable other effect when it entered.
    pub most_confused_with: Option<(String, f64)>,
}

/// Result of forward selection.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// Steps with every candidate's scores.
    pub steps: Vec<SelectionStep>,
    /// Chosen terms in order of entry.
    pub chosen: Vec<ChosenTerm>,
}

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
fn design_penalty(parts: &[&TermColumns], scale: &[f64]) -> Option<DMatrix<f64>> {
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
struct Profiled {
    point: usize,
    /// Linear coefficients of the term at `point` (its complexity).
    coefficients: usize,
    bic: f64,
    full_beta: DVector<f64>,
    fold_sse: Vec<f64>,
    design_scale: Vec<f64>,
    /// Jackknife t of the contribution over LORO folds (see [`stability_t`]).
    stability_t: f64,
    /// Smallest share `c_j` of the full-data contribution that a fold reproduces.
    min_fold_share: f64,
}

/// Terms with more linear coefficients than this are "flexible" (a basis in T): their
/// stability is judged by the smallest fold share instead of the jackknife t.
const FLEXIBLE_TERM_COEFFICIENTS: usize = 2;

/// Smallest fold share a flexible term needs (see [`fold_shares`]).
const MIN_FOLD_SHARE: f64 = 0.5;

/// `<a, b>` over the runs `keep` allows.
fn dot_runs(a: &[Vec<f64>], b: &[Vec<f64>], keep: impl Fn(usize) -> bool) -> f64 {
    a.iter()
        .zip(b)
        .enumerate()
        .filter(|(r, _)| keep(*r))
        .map(|(_, (x, y))| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>())
        .sum()
}

/// `c_j = <v_j, v> / <v, v>` for every fold (see [`stability_t`]).
fn fold_shares(full: &[Vec<f64>], folds: &[Vec<Vec<f64>>]) -> Vec<f64> {
    let vv = dot_runs(full, full, |_| true);
    if vv.is_nan() || vv <= 0.0 {
        return vec![0.0; folds.len()];
    }
    folds.iter().map(|f| dot_runs(f, full, |_| true) / vv).collect()
}

/// Fold shares of a flexible term (a basis in T) over each fold's training runs only:
/// `<v_j, v> / <v, v>` without the held-out run `j`. Where only the held-out run covers
/// some temperatures, the fold's coefficients there are unsupported (the penalty keeps them
/// at the simulation's shape) and the held-out error already judges that region; the share
/// asks whether the shape the other runs support is reproduced without run `j`.
fn training_fold_shares(full: &[Vec<f64>], folds: &[Vec<Vec<f64>>]) -> Vec<f64> {
    folds
        .iter()
        .enumerate()
        .map(|(j, f)| {
            let vv = dot_runs(full, full, |r| r != j);
            if vv.is_nan() || vv <= 0.0 {
                0.0
            } else {
                dot_runs(f, full, |r| r != j) / vv
            }
        })
        .collect()
}

/// Fold-to-fold stability of a term: each LORO fold's fitted contribution `v_j` (at the
/// fold's own profiled point, evaluated on all runs) is projected on the full-data
/// contribution `v`, `c_j = <v_j, v> / <v, v>`; the delete-one-run jackknife standard error
/// of `c` is `sqrt((G - 1)/G sum (c_j - mean c)^2)` and the result is `1 / SE`. It accounts for
/// any correlation within runs (flicker, per-run offsets), which `n_eff` cannot.
fn stability_t(c: &[f64]) -> f64 {
    if c.len() < 2 {
        return 0.0;
    }
    let g = c.len() as f64;
    let mean = c.iter().sum::<f64>() / g;
    let se = ((g - 1.0) / g * c.iter().map(|x| (x - mean).powi(2)).sum::<f64>()).sqrt();
    if se > 0.0 {
        1.0 / se
    } else {
        f64::INFINITY
    }
}

/// The stability a term needs: the two-sided Student-t limit with `runs - 1` degrees of
/// freedom at 5 % family-wise (Bonferroni over the `tests` candidates of a step).
pub fn stability_limit(runs: usize, tests: usize) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    let dof = (runs.max(2) - 1) as f64;
    let alpha = 0.05 / tests.max(1) as f64;
    StudentsT::new(0.0, 1.0, dof).map_or(5.0, |t| t.inverse_cdf(1.0 - alpha / 2.0))
}

fn profile_candidate(
    prep: &Prepared,
    base: &[&TermColumns],
    grid: &EffectGrid,
    ys: &[Vec<f64>],
    n_eff: f64,
) -> Result<Profiled, DiagnoseError> {
    let n = prep.n_blocks();
    let p_base = 1 + base.iter().map(|t| t.k()).sum::<usize>();
    let evals: Vec<(FoldEval, usize, Vec<f64>)> = grid
        .points
        .par_iter()
        .map(|cols| {
            let mut parts = base.to_vec();
            parts.push(cols);
            let design = build_design(prep, &parts);
            let k = p_base + cols.k() + grid.params.len();
            fold_eval(&design, ys).map(|e| (e, k, design.scale))
        })
        .collect::<Result<_, _>>()?;
    // Complexity (the discrete parameters) by LORO error; continuous parameters by BIC,
    // re-chosen in every fold from its training runs.
    let discrete = |j: usize| -> Vec<u64> {
        grid.params
            .iter()
            .zip(&grid.points[j].theta)
            .filter(|(p, _)| !p.continuous)
            .map(|(_, v)| v.to_bits())
            .collect()
    };
    let mut keys: Vec<Vec<u64>> = (0..evals.len()).map(discrete).collect();
    keys.sort();
    keys.dedup();
    let profiled: Vec<Profiled> = keys
        .iter()
        .map(|key| {
            let members: Vec<usize> = (0..evals.len()).filter(|&j| discrete(j) == *key).collect();
            profile_members(prep, grid, &evals, &members, n, n_eff)
        })
        .collect();
    let penalised = grid.points.iter().any(|p| p.penalty.is_some());
    let choice = if penalised {
        one_standard_error_choice(profiled)
    } else {
        profiled.into_iter().min_by(|a, b| total_cv(a).total_cmp(&total_cv(b)))
    };
    choice.ok_or(DiagnoseError::Fit("empty profiling grid"))
}

fn total_cv(p: &Profiled) -> f64 {
    p.fold_sse.iter().sum()
}

/// The size of a penalised basis by the one-standard-error rule of cross-validation
/// (Breiman et al. 1984; Hastie, Tibshirani & Friedman, *Elements of Statistical Learning*
/// 7.10): the smallest basis whose LORO error is within one standard error of the smallest,
/// the standard error from the spread of its per-run held-out errors. The penalty keeps a
/// bigger basis smooth, so the LORO error is flat over sizes and its minimum is decided by
/// noise; a bigger basis than needed is then judged (and rejected) as unstable. (Discrete
/// choices between distinct terms, such as a polynomial degree, keep the smallest error.)
fn one_standard_error_choice(profiled: Vec<Profiled>) -> Option<Profiled> {
    let best = profiled.iter().min_by(|a, b| total_cv(a).total_cmp(&total_cv(b)))?;
    let g = best.fold_sse.len() as f64;
    let mean = total_cv(best) / g;
    let sd = (best.fold_sse.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (g - 1.0).max(1.0)).sqrt();
    // Standard error of the total over g folds: g x (sd / sqrt(g)).
    let limit = total_cv(best) + sd * g.sqrt();
    profiled
        .into_iter()
        .filter(|p| total_cv(p) <= limit)
        .min_by(|a, b| a.coefficients.cmp(&b.coefficients).then(total_cv(a).total_cmp(&total_cv(b))))
}

/// BIC profile over `members` (grid points differing only in continuous parameters).
fn profile_members(
    prep: &Prepared,
    grid: &EffectGrid,
    evals: &[(FoldEval, usize, Vec<f64>)],
    members: &[usize],
    n: usize,
    n_eff: f64,
) -> Profiled {
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
    }
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
fn contribution(prep: &Prepared, cols: &TermColumns, beta: &DVector<f64>, scale: &[f64]) -> Vec<Vec<f64>> {
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

/// Per-run design `[base | extra]` unscaled (for R^2 only).
fn concat(base: &Design, extra: &[&DMatrix<f64>], r: usize) -> DMatrix<f64> {
    let b = &base.per_run[r];
    let k: usize = extra.iter().map(|m| m.ncols()).sum();
    let mut m = DMatrix::zeros(b.nrows(), b.ncols() + k);
    m.view_mut((0, 0), b.shape()).copy_from(b);
    let mut at = b.ncols();
    for e in extra {
        m.view_mut((0, at), e.shape()).copy_from(*e);
        at += e.ncols();
    }
    m
}

fn run_dummies(prep: &Prepared, r: usize) -> DMatrix<f64> {
    let n = prep.runs[r].blocks.len();
    DMatrix::from_fn(n, prep.runs.len(), |_, j| f64::from(u8::from(j == r)))
}

/// Concealment of `v`: on the model's terms, and on them plus per-run offsets.
fn concealment(prep: &Prepared, base: &Design, v: &[Vec<f64>]) -> (f64, f64) {
    let plain = r_squared_runs(v, &base.per_run);
    let with_runs: Vec<DMatrix<f64>> =
        (0..prep.runs.len()).map(|r| concat(base, &[&run_dummies(prep, r)], r)).collect();
    (plain, r_squared_runs(v, &with_runs))
}

/// Runs where a contribution `v` (per run) is material: RMS of `v` about its mean over all
/// runs at least a quarter of the noise of one short mean.
pub fn material_runs(v: &[Vec<f64>], noise_sigma_dph: f64) -> Vec<bool> {
    let n: usize = v.iter().map(Vec::len).sum();
    let mean = v.iter().flatten().sum::<f64>() / n.max(1) as f64;
    v.iter()
        .map(|r| {
            let ms = r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / r.len().max(1) as f64;
            ms.sqrt() >= MATERIAL_FRACTION * noise_sigma_dph
        })
        .collect()
}

/// Fold comparison over the informative folds: (improved, informative).
pub fn fold_counts(before: &[f64], after: &[f64], informative: &[bool]) -> (usize, usize) {
    let mut improved = 0;
    let mut count = 0;
    for ((b, a), _) in before.iter().zip(after).zip(informative).filter(|(_, i)| **i) {
        count += 1;
        if a < b {
            improved += 1;
        }
    }
    (improved, count)
}

/// Whether fold counts pass the acceptance rule.
pub fn folds_pass(improved: usize, informative: usize, min_fraction: f64) -> bool {
    informative >= 2 && improved as f64 >= min_fraction * informative as f64
}

fn profile_map(grid: &EffectGrid, point: usize) -> BTreeMap<String, f64> {
    grid.params.iter().zip(&grid.points[point].theta).map(|(p, v)| (p.name.to_string(), *v)).collect()
}

struct StepContext<'a> {
    prep: &'a Prepared,
    grids: &'a [EffectGrid],
    ys: &'a [Vec<f64>],
    options: &'a DiagnoseOptions,
    base_parts: Vec<&'a TermColumns>,
    base: Design,
    base_eval: FoldEval,
    n_eff: f64,
    in_model: Vec<Effect>,
    /// Candidates evaluated at this step (for the Bonferroni correction).
    tests: usize,
}

fn not_evaluated(effect: Effect, status: &str, note: String, experiment: Option<String>) -> CandidateReport {
    CandidateReport {
        effect: effect.name().to_string(),
        status: status.to_string(),
        profile: BTreeMap::new(),
        cv_rms_dph: f64::NAN,
        cv_improvement: f64::NAN,
        folds_improved: 0,
        folds_informative: 0,
        delta_bic: f64::NAN,
        stability_t: f64::NAN,
        min_fold_share: f64::NAN,
        concealment_index: f64::NAN,
        concealment_with_run_offsets: f64::NAN,
        most_confused_with: None,
        identifiable: false,
        experiment,
        note,
    }
}

/// A profiled candidate with its fitted contribution per run.
type ScoredProfile = (Profiled, Vec<Vec<f64>>);

/// The candidate a step adds: effect, grid point, concealment index, most confused effect.
type Pick = (Effect, usize, f64, Option<(String, f64)>);

/// Scores of one evaluated candidate.
struct Scored {
    report: CandidateReport,
    point: usize,
    cv_sse: f64,
    accepted: bool,
}

fn score_candidate(ctx: &StepContext<'_>, grid: &EffectGrid) -> Result<Option<ScoredProfile>, DiagnoseError> {
    if grid.points.iter().all(|p| p.k() == 0) {
        return Ok(None);
    }
    let prof = profile_candidate(ctx.prep, &ctx.base_parts, grid, ctx.ys, ctx.n_eff)?;
    let v = contribution(ctx.prep, &grid.points[prof.point], &prof.full_beta, &prof.design_scale);
    Ok(Some((prof, v)))
}

fn judge(
    ctx: &StepContext<'_>,
    grid: &EffectGrid,
    prof: &Profiled,
    v: &[Vec<f64>],
    confused: Option<(String, f64)>,
) -> Scored {
    let n = ctx.prep.n_blocks();
    let base_cv: f64 = ctx.base_eval.fold_sse.iter().sum();
    let cv_sse: f64 = prof.fold_sse.iter().sum();
    let material = material_runs(v, ctx.prep.noise_sigma_dph);
    let (improved, informative) = fold_counts(&ctx.base_eval.fold_sse, &prof.fold_sse, &material);
    let base_bic = bic(ctx.base_eval.full_rss, ctx.base.p(), n, ctx.n_eff);
    let delta_bic = prof.bic - base_bic;
    let (conceal, conceal_runs) = concealment(ctx.prep, &ctx.base, v);
    let concealed = conceal > ctx.options.concealment_limit;
    let cv_rms = (cv_sse / n as f64).sqrt();
    let cv_improvement = 1.0 - cv_rms / (base_cv / n as f64).sqrt();
    let checks = [
        (cv_sse < base_cv, "LORO error does not fall"),
        (
            folds_pass(improved, informative, ctx.options.min_fold_fraction),
            "too few informative folds improve",
        ),
        (delta_bic < 0.0, "BIC (n_eff) does not fall"),
        if grid.points[prof.point].k() > FLEXIBLE_TERM_COEFFICIENTS {
            (prof.min_fold_share >= MIN_FOLD_SHARE, "a fold reproduces less than half of the fitted shape")
        } else {
            (
                prof.stability_t >= stability_limit(ctx.prep.runs.len(), ctx.tests),
                "not stable across folds (jackknife t)",
            )
        },
    ];
    let failed: Vec<&str> = checks.iter().filter(|(ok, _)| !ok).map(|(_, why)| *why).collect();
    let accepted = !concealed && failed.is_empty();
    let (status, note, experiment) = if concealed {
        (
            "not_identifiable",
            format!(
                "concealment index {conceal:.4} > {}: not identifiable from these runs",
                ctx.options.concealment_limit
            ),
            Some(grid.effect.experiment().to_string()),
        )
    } else if accepted {
        ("accepted", "passes LORO, fold, BIC and concealment rules".to_string(), None)
    } else {
        ("rejected", failed.join("; "), None)
    };
    let report = CandidateReport {
        effect: grid.effect.name().to_string(),
        status: status.to_string(),
        profile: profile_map(grid, prof.point),
        cv_rms_dph: cv_rms,
        cv_improvement,
        folds_improved: improved,
        folds_informative: informative,
        delta_bic,
        stability_t: prof.stability_t,
        min_fold_share: prof.min_fold_share,
        concealment_index: conceal,
        concealment_with_run_offsets: conceal_runs,
        most_confused_with: confused,
        identifiable: !concealed,
        experiment,
        note,
    };
    Scored { report, point: prof.point, cv_sse, accepted }
}

/// Most confusable other candidate: the largest R^2 of `v` on the model's terms plus
/// another candidate's columns at its own profiled point.
fn most_confused(
    ctx: &StepContext<'_>,
    me: Effect,
    v: &[Vec<f64>],
    others: &[(Effect, &TermColumns)],
) -> Option<(String, f64)> {
    others
        .iter()
        .filter(|(e, c)| *e != me && c.k() > 0)
        .map(|(e, cols)| {
            let z: Vec<DMatrix<f64>> =
                (0..ctx.prep.runs.len()).map(|r| concat(&ctx.base, &[&cols.per_run[r]], r)).collect();
            (e.name().to_string(), r_squared_runs(v, &z))
        })
        .filter(|(_, r2)| r2.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

fn run_step(ctx: &StepContext<'_>) -> Result<(Vec<CandidateReport>, Option<Pick>), DiagnoseError> {
    let open: Vec<&EffectGrid> = ctx.grids.iter().filter(|g| !ctx.in_model.contains(&g.effect)).collect();
    let scored: Vec<Option<ScoredProfile>> = open
        .par_iter()
        .map(|g| if g.unmet_requirement.is_some() { Ok(None) } else { score_candidate(ctx, g) })
        .collect::<Result<_, _>>()?;
    let profiled_cols: Vec<(Effect, &TermColumns)> = open
        .iter()
        .zip(&scored)
        .filter_map(|(g, s)| s.as_ref().map(|(p, _)| (g.effect, &g.points[p.point])))
        .collect();
    let mut reports = Vec::new();
    let mut best: Option<(f64, Pick)> = None;
    for (g, s) in open.iter().zip(&scored) {
        match (s, &g.unmet_requirement) {
            (_, Some(why)) => reports.push(not_evaluated(
                g.effect,
                "not_identifiable",
                format!("not identifiable from these runs: {why}"),
                Some(g.effect.experiment().to_string()),
            )),
            (None, None) => reports.push(not_evaluated(
                g.effect,
                "not_evaluable",
                "the term is identically zero on these runs".into(),
                None,
            )),
            (Some((prof, v)), None) => {
                let confused = most_confused(ctx, g.effect, v, &profiled_cols);
                let sc = judge(ctx, g, prof, v, confused.clone());
                if sc.accepted && best.as_ref().is_none_or(|b| sc.cv_sse < b.0) {
                    best = Some((sc.cv_sse, (g.effect, sc.point, sc.report.concealment_index, confused)));
                }
                reports.push(sc.report);
            }
        }
    }
    if let Some((_, (effect, _, _, _))) = &best {
        for r in &mut reports {
            if r.effect == effect.name() {
                r.status = "selected".into();
            } else if r.status == "accepted" {
                r.status = "rejected".into();
                r.note = RUNNER_UP_NOTE.into();
            }
        }
    }
    Ok((reports, best.map(|b| b.1)))
}

fn model_names(chosen: &[ChosenTerm]) -> Vec<String> {
    chosen.iter().map(|c| c.effect.name().to_string()).collect()
}

/// Columns of the chosen terms.
pub fn chosen_parts(chosen: &[ChosenTerm]) -> Vec<&TermColumns> {
    chosen.iter().map(|c| &c.columns).collect()
}

/// RSS of the full fit of `[1 | parts]`.
fn full_rss(prep: &Prepared, parts: &[&TermColumns], ys: &[Vec<f64>]) -> f64 {
    let design = build_design(prep, parts);
    let mut rs: Vec<DMatrix<f64>> = design.per_run.iter().zip(ys).map(|(x, y)| compress(x, y)).collect();
    rs.extend(design.penalty.as_ref().map(|m| compress(m, &vec![0.0; m.nrows()])));
    let refs: Vec<&DMatrix<f64>> = rs.iter().collect();
    fit_stacked(&refs, design.p()).map_or(f64::INFINITY, |f| f.1)
}

/// Refines each continuous profiled parameter of the chosen grid point between its grid
/// neighbours: a parabola in ln(parameter) through the full-data RSS at the point and its
/// two neighbours; the vertex is kept if it lowers the RSS.
fn refine(
    prep: &Prepared,
    base: &[&TermColumns],
    grid: &EffectGrid,
    point: usize,
    ys: &[Vec<f64>],
) -> TermColumns {
    let best = &grid.points[point];
    let rss_of = |cols: &TermColumns| {
        let mut parts = base.to_vec();
        parts.push(cols);
        full_rss(prep, &parts, ys)
    };
    let mut theta = best.theta.clone();
    for (m, _) in grid.params.iter().enumerate().filter(|(_, p)| p.continuous) {
        let mut line: Vec<usize> = (0..grid.points.len())
            .filter(|&j| (0..theta.len()).all(|q| q == m || grid.points[j].theta[q] == best.theta[q]))
            .collect();
        line.sort_by(|a, b| grid.points[*a].theta[m].total_cmp(&grid.points[*b].theta[m]));
        let Some(pos) = line.iter().position(|&j| j == point) else { continue };
        if pos == 0 || pos + 1 >= line.len() {
            continue;
        }
        let pts: Vec<(f64, f64)> = [line[pos - 1], point, line[pos + 1]]
            .iter()
            .map(|&j| (grid.points[j].theta[m].ln(), rss_of(&grid.points[j])))
            .collect();
        if let Some(x) = parabola_vertex([pts[0], pts[1], pts[2]]) {
            theta[m] = x.clamp(pts[0].0, pts[2].0).exp();
        }
    }
    if theta == best.theta {
        return best.clone();
    }
    let refined = term_columns(prep, grid.effect, &theta);
    if rss_of(&refined) < rss_of(best) {
        refined
    } else {
        best.clone()
    }
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

/// Forward selection over the catalogue (see the module documentation for the rule).
///
/// # Errors
/// [`DiagnoseError::Fit`] if a least-squares problem fails.
pub fn forward_select(
    prep: &Prepared,
    grids: &[EffectGrid],
    options: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Selection, DiagnoseError> {
    let ys = targets(prep);
    let indices = block_indices(prep);
    let mut chosen: Vec<ChosenTerm> = Vec::new();
    let mut steps = Vec::new();
    for step in 0..=options.max_effects {
        progress(
            &format!("forward selection, step {}", step + 1),
            0.3 + 0.5 * step as f64 / (options.max_effects + 1) as f64,
        );
        let base_parts = chosen_parts(&chosen);
        let base = build_design(prep, &base_parts);
        let base_eval = fold_eval(&base, &ys)?;
        let base_resid = residuals(&base, &base_eval.full_beta, &ys);
        let acf = autocorrelations(&base_resid, &indices, prep.hac_lag_blocks);
        let rho = acf.first().copied().unwrap_or(0.0);
        let n_eff = effective_n(prep.n_blocks(), &acf);
        let ctx = StepContext {
            prep,
            grids,
            ys: &ys,
            options,
            base_parts,
            base,
            base_eval,
            n_eff,
            in_model: chosen.iter().map(|c| c.effect).collect(),
            tests: grids
                .iter()
                .filter(|g| g.unmet_requirement.is_none() && !chosen.iter().any(|c| c.effect == g.effect))
                .count(),
        };
        let cv_rms = (ctx.base_eval.fold_sse.iter().sum::<f64>() / prep.n_blocks() as f64).sqrt();
        let (candidates, pick) =
            if step < options.max_effects { run_step(&ctx)? } else { (Vec::new(), None) };
        steps.push(SelectionStep {
            model: model_names(&chosen),
            cv_rms_dph: cv_rms,
            n_eff,
            rho,
            candidates,
            added: pick.as_ref().map(|p| p.0.name().to_string()),
        });
        match pick {
            Some((effect, point, concealment_index, most_confused_with)) => {
                let grid = grids
                    .iter()
                    .find(|g| g.effect == effect)
                    .ok_or(DiagnoseError::Fit("effect grid missing"))?;
                let columns = refine(prep, &chosen_parts(&chosen), grid, point, &ys);
                chosen.push(ChosenTerm { effect, point, columns, concealment_index, most_confused_with })
            }
            None => break,
        }
    }
    Ok(Selection { steps, chosen })
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

/// Bias stability (RMS over runs) of 1 s residuals corrected by per-block predictions
/// (`heldout` = block residuals, so prediction = block residual target - heldout).
pub fn heldout_bias_stability(prep: &Prepared, heldout: &[Vec<f64>], options: &DiagnoseOptions) -> f64 {
    let bs = BiasStabilityOptions { tau_s: options.bias_stability_tau_s, ..BiasStabilityOptions::default() };
    let per_run: Vec<f64> = prep
        .runs
        .iter()
        .zip(heldout)
        .map(|(run, h)| {
            let mut t = Vec::new();
            let mut v = Vec::new();
            for (k, &b) in run.sec.block_of.iter().enumerate() {
                if b != usize::MAX && run.sec.resid_dph[k].is_finite() {
                    let prediction = run.blocks[b].resid_dph - h[b];
                    t.push(run.sec.since_on_s[k]);
                    v.push(run.sec.resid_dph[k] - prediction);
                }
            }
            bias_stability(&t, &v, &bs)
        })
        .collect();
    rms_over_runs(&per_run)
}

/// What the final model achieves on held-out runs.
pub struct FinalOutcome {
    /// The chosen effects with parameters and held-out figures.
    pub left_out: Vec<LeftOutEffect>,
    /// The model's global offset.
    pub global_offset: Parameter,
    /// Held-out residual RMS, offset only, deg/h.
    pub residual_before_dph: f64,
    /// Held-out residual RMS, final model, deg/h.
    pub residual_after_dph: f64,
    /// Held-out bias stability, offset only, deg/h.
    pub bias_stability_before_dph: f64,
    /// Held-out bias stability, final model, deg/h.
    pub bias_stability_after_dph: f64,
    /// In-sample residual of the final model per run.
    pub fitted_resid: Vec<Vec<f64>>,
    /// Held-out residual of the final model per run.
    pub heldout_resid: Vec<Vec<f64>>,
    /// Held-out residual of the offset-only model per run.
    pub baseline_heldout: Vec<Vec<f64>>,
}

/// Contribution of the `i`-th part of a design (`[1 | parts]`) per run, unscaled.
fn term_contribution(
    design: &Design,
    beta: &DVector<f64>,
    parts: &[&TermColumns],
    i: usize,
) -> Vec<Vec<f64>> {
    let start = 1 + parts[..i].iter().map(|t| t.k()).sum::<usize>();
    let k = parts[i].k();
    design
        .per_run
        .iter()
        .map(|m| (0..m.nrows()).map(|r| (start..start + k).map(|c| m[(r, c)] * beta[c]).sum()).collect())
        .collect()
}

/// Linearised derivative column of a term with respect to profiled parameter `m`.
fn derivative_columns(
    prep: &Prepared,
    effect: Effect,
    cols: &TermColumns,
    coef: &[f64],
    m: usize,
) -> (Vec<DMatrix<f64>>, f64) {
    let theta = &cols.theta;
    let h = (theta[m].abs() * 0.05).max(1e-6);
    let mut up = theta.clone();
    up[m] += h;
    let mut down = theta.clone();
    down[m] = (down[m] - h).max(theta[m] * 0.5);
    let width = up[m] - down[m];
    let (cu, cd) = (term_columns(prep, effect, &up), term_columns(prep, effect, &down));
    let per_run = (0..prep.runs.len())
        .map(|r| {
            let value = |t: &TermColumns| &t.per_run[r] * DVector::from_column_slice(coef);
            DMatrix::from_column_slice(
                cols.per_run[r].nrows(),
                1,
                ((value(&cu) - value(&cd)) / width).as_slice(),
            )
        })
        .collect();
    (per_run, width)
}

fn parameters_of(
    prep: &Prepared,
    grid: &EffectGrid,
    cols: &TermColumns,
    coef: &[f64],
    se: &[f64],
    theta_se: &[Option<f64>],
) -> BTreeMap<String, Parameter> {
    let mut out = BTreeMap::new();
    for (((name, units), v), s) in cols.coefficients.iter().zip(coef).zip(se) {
        out.insert(name.clone(), Parameter { value: *v, std_error: Some(*s), units: units.clone() });
    }
    for ((p, v), s) in grid.params.iter().zip(&cols.theta).zip(theta_se) {
        out.insert(p.name.to_string(), Parameter { value: *v, std_error: *s, units: p.units.to_string() });
    }
    if grid.effect == Effect::StaticShape {
        let (lo, hi) = prep.temp_range_c;
        let k = cols.theta[0] as usize;
        let shape: Vec<f64> = (0..=100)
            .map(|i| {
                let b = super::effects::bspline_basis(lo + (hi - lo) * f64::from(i) / 100.0, lo, hi, k);
                b.iter().skip(1).zip(coef).map(|(x, c)| x * c).sum()
            })
            .collect();
        let (mn, mx) =
            shape.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
        out.insert(
            "peak_to_peak_dph".into(),
            Parameter { value: mx - mn, std_error: None, units: "deg/h".into() },
        );
        out.insert(
            "t_min_c".into(),
            Parameter { value: lo, std_error: None, units: "deg C (basis range start)".into() },
        );
        out.insert(
            "t_max_c".into(),
            Parameter { value: hi, std_error: None, units: "deg C (basis range end)".into() },
        );
    }
    if grid.effect == Effect::ScaleFactorTemperature || grid.effect == Effect::Hysteresis {
        out.insert(
            "t_ref_c".into(),
            Parameter { value: prep.temp_ref_c, std_error: None, units: "deg C".into() },
        );
    }
    out
}

struct Fitted {
    coef: Vec<Vec<f64>>,
    se: Vec<Vec<f64>>,
    theta_se: Vec<Vec<Option<f64>>>,
    offset: Parameter,
}

/// Final-model coefficients with delete-one-run jackknife standard errors; profiled
/// parameters get a linearised (Gauss-Newton) standard error: the derivative of the term
/// with respect to the parameter is added as a column, and the jackknife covers the
/// one-step estimates of all coefficients. Runs are the independent units, so the errors
/// hold for any correlation within a run (flicker, turn-on offsets).
fn fit_parameters(
    prep: &Prepared,
    grids: &[EffectGrid],
    chosen: &[ChosenTerm],
    design: &Design,
    beta: &DVector<f64>,
    ys: &[Vec<f64>],
) -> Fitted {
    let parts = chosen_parts(chosen);
    let unscaled: Vec<f64> = beta.iter().zip(&design.scale).map(|(b, s)| b / s).collect();
    let mut coef = Vec::new();
    let mut at = 1;
    for t in &parts {
        coef.push(unscaled[at..at + t.k()].to_vec());
        at += t.k();
    }
    // Augmented design: scaled linear columns, then derivative columns (scaled too).
    let mut extra: Vec<Vec<DMatrix<f64>>> = Vec::new();
    let mut owner: Vec<(usize, usize)> = Vec::new();
    for (ti, (c, t)) in chosen.iter().zip(&parts).enumerate() {
        let grid = grids.iter().find(|g| g.effect == c.effect);
        for (m, p) in grid.map(|g| g.params.as_slice()).unwrap_or(&[]).iter().enumerate() {
            // A parameter at the edge of its grid is a bound, not an estimate: its derivative
            // column would be near-collinear with the term and inflate every other SE.
            let at_edge = grid.is_some_and(|g| {
                let values = g.points.iter().map(|pt| pt.theta[m]);
                let (lo, hi) =
                    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
                t.theta[m] <= lo || t.theta[m] >= hi
            });
            if p.continuous && !at_edge {
                extra.push(derivative_columns(prep, c.effect, t, &coef[ti], m).0);
                owner.push((ti, m));
            }
        }
    }
    let extra_scale: Vec<f64> = extra
        .iter()
        .map(|cols| {
            let n: usize = cols.iter().map(|m| m.nrows()).sum();
            let ss: f64 = cols.iter().map(|m| m.norm_squared()).sum();
            let rms = (ss / n.max(1) as f64).sqrt();
            if rms > 0.0 && rms.is_finite() {
                rms
            } else {
                1.0
            }
        })
        .collect();
    let aug: Vec<DMatrix<f64>> = (0..prep.runs.len())
        .map(|r| {
            let scaled: Vec<DMatrix<f64>> = extra.iter().zip(&extra_scale).map(|(e, s)| &e[r] / *s).collect();
            let refs: Vec<&DMatrix<f64>> = scaled.iter().collect();
            concat(design, &refs, r)
        })
        .collect();
    let all_scale: Vec<f64> = design.scale.iter().chain(&extra_scale).copied().collect();
    let penalty = design.penalty.as_ref().map(|m| {
        let mut padded = DMatrix::zeros(m.nrows(), all_scale.len());
        padded.view_mut((0, 0), m.shape()).copy_from(m);
        padded
    });
    let aug_design = Design { per_run: aug, scale: all_scale.clone(), penalty };
    let cov = fold_eval(&aug_design, ys).ok().map(|e| jackknife_covariance(&e.fold_beta));
    let se_of = |k: usize| cov.as_ref().map_or(f64::NAN, |c| c[(k, k)].max(0.0).sqrt() / all_scale[k]);
    let mut se = Vec::new();
    let mut at = 1;
    for t in &parts {
        se.push((at..at + t.k()).map(se_of).collect());
        at += t.k();
    }
    let mut theta_se: Vec<Vec<Option<f64>>> = parts.iter().map(|t| vec![None; t.theta.len()]).collect();
    for (j, (ti, m)) in owner.iter().enumerate() {
        theta_se[*ti][*m] = Some(se_of(design.p() + j));
    }
    let offset = Parameter { value: unscaled[0], std_error: Some(se_of(0)), units: "deg/h".into() };
    Fitted { coef, se, theta_se, offset }
}

/// Passes every rule at a step without being selected.
const RUNNER_UP_NOTE: &str = "passes the rules but another effect lowers the LORO error more";

/// Alternative explanations of the effect chosen at step `k`: candidates that passed every
/// rule at that step (only the lower LORO error decided) and no longer pass once the chosen
/// effect is in the model (it explains what they explained), with their LORO RMS. When
/// selection stopped at `max_effects` there is no next step and every runner-up counts.
fn alternatives(steps: &[SelectionStep], k: usize) -> Vec<(String, f64)> {
    let Some(step) = steps.get(k) else { return Vec::new() };
    let next = steps.get(k + 1).filter(|s| !s.candidates.is_empty());
    step.candidates
        .iter()
        .filter(|c| c.status == "rejected" && c.note == RUNNER_UP_NOTE)
        .filter(|c| {
            next.is_none_or(|n| {
                n.candidates
                    .iter()
                    .any(|d| d.effect == c.effect && !matches!(d.status.as_str(), "selected" | "accepted"))
            })
        })
        .map(|c| (c.effect.clone(), c.cv_rms_dph))
        .collect()
}

/// Held-out evaluation of the chosen model, each effect's contribution, and parameters.
///
/// # Errors
/// [`DiagnoseError::Fit`] if a least-squares problem fails.
pub fn evaluate_final(
    prep: &Prepared,
    grids: &[EffectGrid],
    selection: &Selection,
    options: &DiagnoseOptions,
) -> Result<FinalOutcome, DiagnoseError> {
    let ys = targets(prep);
    let chosen = &selection.chosen;
    let design = build_design(prep, &chosen_parts(chosen));
    let eval = fold_eval(&design, &ys)?;
    let heldout = heldout_residuals(&design, &eval, &ys);
    let fitted_resid = residuals(&design, &eval.full_beta, &ys);
    let base = build_design(prep, &[]);
    let base_eval = fold_eval(&base, &ys)?;
    let baseline_heldout = heldout_residuals(&base, &base_eval, &ys);
    let fitted = fit_parameters(prep, grids, chosen, &design, &eval.full_beta, &ys);
    let bs_after = heldout_bias_stability(prep, &heldout, options);
    let rms_after = pooled_rms(&heldout);
    let mut left_out = Vec::new();
    for (i, c) in chosen.iter().enumerate() {
        let without: Vec<ChosenTerm> =
            chosen.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, t)| t.clone()).collect();
        let d0 = build_design(prep, &chosen_parts(&without));
        let e0 = fold_eval(&d0, &ys)?;
        let h0 = heldout_residuals(&d0, &e0, &ys);
        let v = term_contribution(&design, &eval.full_beta, &chosen_parts(chosen), i);
        let material = material_runs(&v, prep.noise_sigma_dph);
        let (improved, informative) = fold_counts(&e0.fold_sse, &eval.fold_sse, &material);
        let before = pooled_rms(&h0);
        let grid =
            grids.iter().find(|g| g.effect == c.effect).ok_or(DiagnoseError::Fit("effect grid missing"))?;
        let cols = &c.columns;
        let parameters = parameters_of(prep, grid, cols, &fitted.coef[i], &fitted.se[i], &fitted.theta_se[i]);
        let improvement = 1.0 - rms_after / before;
        let mut statement = format!(
            "{}: held-out residual RMS {:.5} -> {:.5} deg/h ({:+.1} %), improved in {} of {} informative runs",
            c.effect.name(),
            before,
            rms_after,
            -100.0 * improvement,
            improved,
            informative
        );
        if let Some((other, r2)) =
            c.most_confused_with.as_ref().filter(|(_, r2)| *r2 > options.concealment_limit)
        {
            statement.push_str(&format!(
                "; cannot be told apart from {other} on these runs (R^2 {r2:.4}): run {}",
                c.effect.experiment()
            ));
        }
        let alternatives = alternatives(&selection.steps, i);
        if !alternatives.is_empty() {
            let chosen_cv = selection.steps[i]
                .candidates
                .iter()
                .find(|r| r.effect == c.effect.name())
                .map_or(f64::NAN, |r| r.cv_rms_dph);
            let list: Vec<String> =
                alternatives.iter().map(|(e, cv)| format!("{e} (LORO RMS {cv:.5} deg/h)")).collect();
            statement.push_str(&format!(
                "; alternative explanation: {} passed every rule too and no longer does once {} is in (only the lower LORO RMS, {chosen_cv:.5} deg/h, chose {}); to separate them run {}",
                list.join(", "),
                c.effect.name(),
                c.effect.name(),
                c.effect.experiment()
            ));
        }
        left_out.push(LeftOutEffect {
            alternatives: alternatives.into_iter().map(|(e, _)| e).collect(),
            effect: c.effect.name().to_string(),
            parameters,
            residual_before_dph: before,
            residual_after_dph: rms_after,
            heldout_improvement: improvement,
            bias_stability_before_dph: heldout_bias_stability(prep, &h0, options),
            bias_stability_after_dph: bs_after,
            folds_improved: improved,
            folds_informative: informative,
            concealment_index: c.concealment_index,
            statement,
        });
    }
    Ok(FinalOutcome {
        left_out,
        global_offset: fitted.offset,
        residual_before_dph: pooled_rms(&baseline_heldout),
        residual_after_dph: rms_after,
        bias_stability_before_dph: heldout_bias_stability(prep, &baseline_heldout, options),
        bias_stability_after_dph: bs_after,
        fitted_resid,
        heldout_resid: heldout,
        baseline_heldout,
    })
}
