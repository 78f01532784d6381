//! The forward-selection loop: every open candidate profiled and judged at each step, the
//! accepted one with the fewest coefficients within one standard error of the lowest LORO
//! error enters (two such rivals told apart by encompassing in the noise model's metric),
//! its continuous parameters refined.

use std::collections::BTreeMap;

use nalgebra::DMatrix;
use rayon::prelude::*;

use super::design::*;
use super::permutation::{position_permutation, PermutationTest};
use super::rules::*;
use crate::effects::{term_columns, Effect, EffectGrid, TermColumns};
use crate::error::DiagnoseError;
use crate::linalg::{autocorrelations, effective_n, parabola_vertex};
use crate::noise_model::heldout_gls;
use crate::prepare::Prepared;
use crate::{CandidateReport, DiagnoseOptions, SelectionStep, TieBreak};

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
    /// Accepted by the noise-model route alone: what the route measured. Selection goes on
    /// with the LORO-profiled `columns`; the final fit reports the term at the route's point
    /// (`final_fit::reported_terms`).
    pub route: Option<RouteEvidence>,
    /// The forward-selection step at which it entered (0-based index into
    /// [`Selection::steps`]; backward elimination may remove terms before it).
    pub step: usize,
}

/// What the noise-model route measured for a term it accepted and the run-level rules did not.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RouteEvidence {
    /// Grid point of the route's profile in its held-out GLS error, where it is reported.
    pub point: usize,
    /// Smallest GLS Wald p over the grid.
    pub min_p: f64,
    /// Family-wise p of that smallest p.
    pub family_p: f64,
    /// Held-out GLS error at `point` relative to the current model's, `1 - with / without`
    /// (`None`: not measured).
    pub heldout_gls_fall: Option<f64>,
}

/// Result of forward selection.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// Steps with every candidate's scores.
    pub steps: Vec<SelectionStep>,
    /// Chosen terms in order of entry, those backward elimination dropped left out.
    pub chosen: Vec<ChosenTerm>,
    /// Terms forward selection chose and backward elimination dropped, in the order dropped.
    pub dropped: Vec<DroppedTerm>,
}

/// A term forward selection chose that no longer lowers the LORO error once the terms that
/// entered after it are in ([`backward_eliminate`]).
#[derive(Clone, Debug, PartialEq)]
pub struct DroppedTerm {
    /// The effect.
    pub effect: Effect,
    /// The step at which it entered (0-based index into [`Selection::steps`]).
    pub step: usize,
    /// LORO RMS of the model with it (the terms left at the time it was dropped), deg/h.
    pub loro_rms_with_dph: f64,
    /// LORO RMS of the same model without it, deg/h (at most `loro_rms_with_dph`).
    pub loro_rms_without_dph: f64,
    /// The effects kept in the model it was judged in.
    pub judged_with: Vec<String>,
}

pub(super) fn profile_map(grid: &EffectGrid, point: usize) -> BTreeMap<String, f64> {
    grid.params.iter().zip(&grid.points[point].theta).map(|(p, v)| (p.name.to_string(), *v)).collect()
}

pub(super) struct StepContext<'a> {
    pub(super) prep: &'a Prepared,
    pub(super) grids: &'a [EffectGrid],
    pub(super) ys: &'a [Vec<f64>],
    pub(super) options: &'a DiagnoseOptions,
    pub(super) base_parts: Vec<&'a TermColumns>,
    pub(super) base: Design,
    pub(super) base_eval: FoldEval,
    /// Held-out residual of each run under the current model.
    pub(super) base_heldout: Vec<Vec<f64>>,
    pub(super) n_eff: f64,
    pub(super) in_model: Vec<Effect>,
    /// Candidates evaluated at this step (for the Bonferroni correction).
    pub(super) tests: usize,
    /// The noise-model route's verdicts at this step (None: off, or the model does not fit).
    pub(super) gls: Option<GlsStep>,
    /// The noise model's basis (None: the route is off), for the encompassing tie-break.
    pub(super) noise_basis: Option<&'a crate::noise_model::NoiseBasis>,
}

pub(super) fn not_evaluated(
    effect: Effect,
    status: &str,
    note: String,
    experiment: Option<String>,
) -> CandidateReport {
    CandidateReport {
        effect: effect.name().to_string(),
        status: status.to_string(),
        profile: BTreeMap::new(),
        cv_rms_dph: f64::NAN,
        cv_improvement: f64::NAN,
        folds_improved: 0,
        folds_informative: 0,
        fold_gain_t: f64::NAN,
        fold_gain_rank_p: f64::NAN,
        delta_bic: f64::NAN,
        stability_t: f64::NAN,
        min_fold_share: f64::NAN,
        concealment_index: f64::NAN,
        concealment_with_run_offsets: f64::NAN,
        most_confused_with: None,
        identifiable: false,
        experiment,
        note,
        position_permutation_p: None,
        runner_up_alternative: false,
    }
}

/// A profiled candidate with its fitted contribution per run.
pub(super) type ScoredProfile = (Profiled, Vec<Vec<f64>>);

/// The candidate a step adds.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Pick {
    pub(super) effect: Effect,
    /// Its LORO-profiled grid point.
    pub(super) point: usize,
    pub(super) concealment_index: f64,
    pub(super) most_confused_with: Option<(String, f64)>,
    /// Where only the noise-model route accepted it: what the route measured.
    pub(super) route: Option<RouteEvidence>,
}

/// Scores of one evaluated candidate.
pub(super) struct Scored {
    pub(super) report: CandidateReport,
    pub(super) point: usize,
    pub(super) accepted: bool,
    /// Accepted by the noise-model route alone: what the route measured.
    pub(super) route: Option<RouteEvidence>,
}

pub(super) fn score_candidate(
    ctx: &StepContext<'_>,
    grid: &EffectGrid,
) -> Result<Option<ScoredProfile>, DiagnoseError> {
    if grid.points.iter().all(|p| p.k() == 0) {
        return Ok(None);
    }
    let prof = profile_candidate(ctx.prep, &ctx.base_parts, grid, ctx.ys, ctx.n_eff)?;
    let v = contribution(ctx.prep, &grid.points[prof.point], &prof.full_beta, &prof.design_scale);
    Ok(Some((prof, v)))
}

pub(super) fn judge(
    ctx: &StepContext<'_>,
    grid: &EffectGrid,
    prof: &Profiled,
    v: &[Vec<f64>],
    confused: Option<(String, f64)>,
) -> Result<Scored, DiagnoseError> {
    let n = ctx.prep.n_blocks();
    let base_cv: f64 = ctx.base_eval.fold_sse.iter().sum();
    let cv_sse: f64 = prof.fold_sse.iter().sum();
    let material = material_runs(v, ctx.prep.noise_sigma_dph);
    let (improved, informative) = fold_counts(&ctx.base_eval.fold_sse, &prof.fold_sse, &material);
    let gains = clark_west_gains(&ctx.base_heldout, &prof.fold_resid);
    let gain_t = fold_gain_t(&gains);
    let rank_p = signed_rank_p(&gains);
    let base_bic = bic(ctx.base_eval.full_rss, ctx.base.p(), n, ctx.n_eff);
    let delta_bic = prof.bic - base_bic;
    let (conceal, conceal_runs) = concealment(ctx.prep, &ctx.base, v);
    let concealed = conceal > ctx.options.concealment_limit;
    let cv_rms = (cv_sse / n as f64).sqrt();
    let cv_improvement = 1.0 - cv_rms / (base_cv / n as f64).sqrt();
    let sign_ok = !grid.effect.positive_coefficient() || last_coefficient(prof) > 0.0;
    let mut failed: Vec<String> = acceptance_failures(&RuleInputs {
        cv_sse,
        base_cv_sse: base_cv,
        folds_improved: improved,
        folds_informative: informative,
        min_fold_fraction: ctx.options.min_fold_fraction,
        fold_gain_t: gain_t,
        fold_gain_limit: fold_gain_limit(ctx.prep.runs.len(), ctx.tests),
        fold_gain_rank_p: rank_p,
        fold_gain_alpha: fold_gain_alpha(ctx.tests),
        delta_bic,
        coefficients: grid.points[prof.point].k(),
        min_fold_share: prof.min_fold_share,
        stability_t: prof.stability_t,
        stability_limit: stability_limit(ctx.prep.runs.len(), ctx.tests),
        sign_ok,
    })
    .into_iter()
    .map(String::from)
    .collect::<Vec<String>>();
    let gls = ctx.gls.as_ref().and_then(|g| g.verdict(grid.effect));
    // The route replaces the run-level tests of significance (fold rule, BIC, stability),
    // not the claim the diagnosis makes: the term predicts held-out runs better.
    let gls_accepts = gls.is_some_and(|v| v.accepts(cv_sse < base_cv, sign_ok));
    // The run-level rules' fold gains of an orientation-dependent term share one contrast:
    // their claim is checked against relabellings of the runs' positions.
    let permutation = if ctx.options.position_permutation
        && grid.effect.orientation_dependent()
        && failed.is_empty()
        && !concealed
        && !gls_accepts
    {
        let level = fold_gain_alpha(ctx.tests);
        let test = position_permutation(ctx, grid, cv_sse, level);
        if test.p() > level {
            failed.push(permutation_failure(&test, level));
        }
        Some(test)
    } else {
        None
    };
    let accepted = !concealed && (failed.is_empty() || gls_accepts);
    let route = gls.filter(|_| accepted && !failed.is_empty()).map(|v| RouteEvidence {
        point: v.point,
        min_p: v.min_p,
        family_p: v.family_p,
        heldout_gls_fall: v.heldout_gls_fall,
    });
    let (status, note, experiment) = if concealed {
        (
            "not_identifiable",
            format!(
                "concealment index {conceal:.4} > {}: not identifiable from these runs",
                ctx.options.concealment_limit
            ),
            Some(crate::effects::separating_experiment(grid.effect, &crate::effects::run_content(ctx.prep))),
        )
    } else if accepted && failed.is_empty() {
        // With no informative run the fold rule passes without evidence: say so (review16 F4).
        let rules = if informative == 0 {
            "passes LORO, BIC and concealment rules (the fold rule had no run large enough to judge)"
        } else {
            "passes LORO, fold, BIC and concealment rules"
        };
        let note = match &permutation {
            Some(t) => format!(
                "{rules} and the permutation test of the position labels (p {:.4}, {} relabellings)",
                t.p(),
                t.evaluated
            ),
            None => rules.to_string(),
        };
        ("accepted", note, None)
    } else if accepted {
        ("accepted", format!("passes the noise-model GLS test ({})", gls_note(gls)), None)
    } else {
        let mut why = failed.join("; ");
        if let Some(v) = gls {
            why.push_str(&format!("; noise-model GLS test {} ({})", v.why_not(), gls_note(gls)));
        }
        ("rejected", why, None)
    };
    let report = CandidateReport {
        effect: grid.effect.name().to_string(),
        status: status.to_string(),
        profile: profile_map(grid, prof.point),
        cv_rms_dph: cv_rms,
        cv_improvement,
        folds_improved: improved,
        folds_informative: informative,
        fold_gain_t: gain_t,
        fold_gain_rank_p: rank_p,
        delta_bic,
        stability_t: prof.stability_t,
        min_fold_share: prof.min_fold_share,
        concealment_index: conceal,
        concealment_with_run_offsets: conceal_runs,
        most_confused_with: confused,
        identifiable: !concealed,
        experiment,
        note,
        position_permutation_p: permutation.map(|t| t.p()),
        runner_up_alternative: false,
    };
    Ok(Scored { report, point: prof.point, accepted, route })
}

/// Why the permutation test of the position labels failed a candidate.
fn permutation_failure(test: &PermutationTest, level: f64) -> String {
    let reach = if test.complete() {
        String::new()
    } else {
        format!(", stopped after {} of {}: it can no longer reach the level", test.evaluated, test.planned)
    };
    format!(
        "permutation of the position labels: p {:.4} > {level:.2e} ({} of the relabellings at least as good{reach}; the folds share one contrast between positions)",
        test.p(),
        test.as_good
    )
}

/// The full-data coefficient of the candidate's last column (unscaled).
pub(super) fn last_coefficient(prof: &Profiled) -> f64 {
    let p = prof.full_beta.len();
    match (p.checked_sub(1), prof.design_scale.last()) {
        (Some(last), Some(scale)) if *scale != 0.0 => prof.full_beta[last] / scale,
        _ => f64::NAN,
    }
}

/// Most confusable other candidate: the largest R^2 of `v` on the model's terms plus
/// another candidate's columns at its own profiled point.
pub(super) fn most_confused(
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

pub(super) fn run_step(ctx: &StepContext<'_>) -> Result<StepOutcome, DiagnoseError> {
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
    let mut accepted: Vec<(Vec<f64>, usize, Pick)> = Vec::new();
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
                let sc = judge(ctx, g, prof, v, confused.clone())?;
                if sc.accepted {
                    let pick = Pick {
                        effect: g.effect,
                        point: sc.point,
                        concealment_index: sc.report.concealment_index,
                        most_confused_with: confused,
                        route: sc.route,
                    };
                    accepted.push((prof.fold_sse.clone(), g.points[sc.point].k(), pick));
                }
                reports.push(sc.report);
            }
        }
    }
    let held_out_sse: Vec<(Effect, f64)> = accepted.iter().map(|a| (a.2.effect, a.0.iter().sum())).collect();
    let mut set = parsimonious_set(accepted).into_iter().map(|a| a.2);
    let (first, second) = (set.next(), set.next());
    // Two rivals of one size within one SE: the LORO error cannot tell them apart, so the
    // one that encompasses the other in the noise model's metric enters.
    let tie_break = match (&first, &second, ctx.noise_basis) {
        (Some(a), Some(b), Some(basis)) if ctx.options.encompassing_tie_break => {
            let a_given_b = wald_p_given(ctx, basis, a, b);
            let b_given_a = wald_p_given(ctx, basis, b, a);
            a_given_b.zip(b_given_a).map(|(ab, ba)| TieBreak {
                loro_winner: a.effect.name().into(),
                runner_up: b.effect.name().into(),
                winner_given_runner_up_p: ab,
                runner_up_given_winner_p: ba,
                runner_up_entered: encompassing_prefers_second(ab, ba),
            })
        }
        _ => None,
    };
    let entered = tie_break.as_ref().is_some_and(|t| t.runner_up_entered);
    let best = if entered { second } else { first };
    if let Some(effect) = best.as_ref().map(|p| p.effect) {
        for r in &mut reports {
            if r.effect == effect.name() {
                r.status = "selected".into();
                if let Some(t) = &tie_break {
                    r.note.push_str(&format!(
                        "; encompassing tie-break (GLS Wald p of the LORO winner with the runner-up in the model {:.2e}, of the runner-up with the winner in {:.2e})",
                        t.winner_given_runner_up_p, t.runner_up_given_winner_p
                    ));
                }
            } else if r.status == "accepted" {
                r.status = "rejected".into();
                r.runner_up_alternative = explains_half(ctx, &held_out_sse, &r.effect, effect);
                let replaced = entered && tie_break.as_ref().is_some_and(|t| t.loro_winner == r.effect);
                r.note = match (replaced, r.runner_up_alternative) {
                    (true, _) => ENCOMPASSED_NOTE,
                    (false, true) => RUNNER_UP_NOTE,
                    (false, false) => RUNNER_UP_PARTIAL_NOTE,
                }
                .into();
            }
        }
    }
    Ok(StepOutcome { reports, pick: best, tie_break })
}

/// What one step of forward selection found.
pub(super) struct StepOutcome {
    /// Every candidate's report.
    pub(super) reports: Vec<CandidateReport>,
    /// The effect that enters, if any.
    pub(super) pick: Option<Pick>,
    /// The encompassing tie-break, when it ran.
    pub(super) tie_break: Option<TieBreak>,
}

/// GLS Wald p of `add` (at its profiled point) with `given` (at its) in the current model;
/// see [`encompassing_p`].
fn wald_p_given(
    ctx: &StepContext<'_>,
    basis: &crate::noise_model::NoiseBasis,
    add: &Pick,
    given: &Pick,
) -> Option<f64> {
    let cols_of =
        |p: &Pick| ctx.grids.iter().find(|g| g.effect == p.effect).and_then(|g| g.points.get(p.point));
    encompassing_p(basis, &ctx.base.per_run, ctx.ys, &cols_of(add)?.per_run, &cols_of(given)?.per_run)
}

/// GLS Wald p of the columns `add` (per run) with the model `base` plus `given` in place,
/// the noise levels refitted by REML on that model; `None` when the noise model does not
/// fit it (innovation check) or `add` has no direction beyond it.
pub(super) fn encompassing_p(
    basis: &crate::noise_model::NoiseBasis,
    base: &[DMatrix<f64>],
    ys: &[Vec<f64>],
    add: &[DMatrix<f64>],
    given: &[DMatrix<f64>],
) -> Option<f64> {
    use crate::noise_model::{fit_noise, GlsTester};
    if given.len() != base.len() || base.iter().zip(given).any(|(b, g)| b.nrows() != g.nrows()) {
        return None;
    }
    let with: Vec<DMatrix<f64>> = base
        .iter()
        .zip(given)
        .map(|(b, g)| {
            let mut m = DMatrix::zeros(b.nrows(), b.ncols() + g.ncols());
            m.view_mut((0, 0), b.shape()).copy_from(b);
            m.view_mut((0, b.ncols()), g.shape()).copy_from(g);
            m
        })
        .collect();
    let fit = fit_noise(basis, &with, ys)?;
    if !fit.check.passed {
        return None;
    }
    let tester = GlsTester::new(&fit, &with, ys)?;
    let q = tester.candidate_basis(add)?;
    (q.ncols() > 0).then(|| tester.wald(&q).1)
}

/// Level at which the runner-up must add to the LORO winner before it can replace it: the
/// conventional 5 %, not tuned.
pub(super) const ENCOMPASSING_LEVEL: f64 = 0.05;

/// Encompassing between the LORO winner `a` and the runner-up `b`: `a_given_b` is the GLS
/// Wald p of `a` with `b` in the model, `b_given_a` the reverse. The runner-up enters when
/// it adds significantly beyond the winner (`b_given_a` below [`ENCOMPASSING_LEVEL`]) and
/// the winner adds less beyond it than that (a larger p). Otherwise the winner stays: when
/// neither adds significantly beyond the other the data cannot tell them apart, and the
/// smaller of two p's that are both not significant is no evidence (Gelman and Stern 2006,
/// "The difference between 'significant' and 'not significant' is not itself statistically
/// significant"); ties keep the winner too.
pub(super) fn encompassing_prefers_second(a_given_b: f64, b_given_a: f64) -> bool {
    b_given_a < ENCOMPASSING_LEVEL && a_given_b > b_given_a
}

/// Among accepted candidates `(held-out SSE per run, coefficients, pick)`, the one with the
/// fewest coefficients whose LORO error is within one standard error of the lowest (the
/// one-SE rule across effects: two effects that predict held-out runs equally well are
/// told apart by parsimony, not by noise); ties in size go to the lower error.
#[cfg(test)]
pub(super) fn parsimonious_pick(accepted: Vec<(Vec<f64>, usize, Pick)>) -> Option<Pick> {
    parsimonious_set(accepted).into_iter().next().map(|a| a.2)
}

/// Smallest share of the selected effect's fall in LORO error that a runner-up must reach
/// to be listed as an alternative explanation: at least half of what the selected effect
/// explains in held-out runs (the same "half" a flexible term's folds must reproduce,
/// [`MIN_FOLD_SHARE`]).
pub(super) const ALTERNATIVE_SHARE: f64 = 0.5;

/// A runner-up's fall in LORO error over the current model (`base_sse`) as a share of the
/// selected effect's: `(base - mine) / (base - chosen)`; 0 when the selected effect lowers
/// nothing.
pub(super) fn explained_share(base_sse: f64, mine_sse: f64, chosen_sse: f64) -> f64 {
    let chosen_gain = base_sse - chosen_sse;
    if chosen_gain > 0.0 {
        (base_sse - mine_sse) / chosen_gain
    } else {
        0.0
    }
}

/// Whether an accepted candidate `runner_up` that was not selected is an alternative
/// explanation: it explains at least [`ALTERNATIVE_SHARE`] of what `selected` does
/// (`held_out_sse`: each accepted candidate's total LORO error).
fn explains_half(
    ctx: &StepContext<'_>,
    held_out_sse: &[(Effect, f64)],
    runner_up: &str,
    selected: Effect,
) -> bool {
    let sse_of = |name: &str| held_out_sse.iter().find(|(e, _)| e.name() == name).map(|x| x.1);
    let base_sse: f64 = ctx.base_eval.fold_sse.iter().sum();
    let share = match (sse_of(runner_up), sse_of(selected.name())) {
        (Some(mine), Some(chosen)) => explained_share(base_sse, mine, chosen),
        _ => 0.0,
    };
    share >= ALTERNATIVE_SHARE
}

/// The candidates `parsimonious_pick` chooses among: those with the fewest coefficients
/// within one standard error of the lowest LORO error, lowest error first.
pub(super) fn parsimonious_set(accepted: Vec<(Vec<f64>, usize, Pick)>) -> Vec<(Vec<f64>, usize, Pick)> {
    let total = |f: &[f64]| f.iter().sum::<f64>();
    let Some(best) = accepted.iter().min_by(|a, b| total(&a.0).total_cmp(&total(&b.0))) else {
        return Vec::new();
    };
    let g = best.0.len() as f64;
    let mean = total(&best.0) / g;
    let sd = (best.0.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (g - 1.0).max(1.0)).sqrt();
    let limit = total(&best.0) + sd * g.sqrt();
    let mut within: Vec<(Vec<f64>, usize, Pick)> =
        accepted.into_iter().filter(|a| total(&a.0) <= limit).collect();
    let Some(fewest) = within.iter().map(|a| a.1).min() else { return Vec::new() };
    within.retain(|a| a.1 == fewest);
    within.sort_by(|a, b| total(&a.0).total_cmp(&total(&b.0)));
    within
}

pub(super) fn model_names(chosen: &[ChosenTerm]) -> Vec<String> {
    chosen.iter().map(|c| c.effect.name().to_string()).collect()
}

/// Columns of the chosen terms.
pub fn chosen_parts(chosen: &[ChosenTerm]) -> Vec<&TermColumns> {
    chosen.iter().map(|c| &c.columns).collect()
}

/// Refines each continuous profiled parameter of the chosen grid point between its grid
/// neighbours: a parabola in ln(parameter) through the full-data RSS at the point and its
/// two neighbours; the vertex is kept if it lowers the RSS.
pub(super) fn refine(
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

/// Forward selection over the catalogue (see the module documentation for the rule);
/// `noise_basis` ([`crate::noise_model::NoiseBasis::of`] the same runs, built once per
/// diagnosis) for the noise-model route when `options.noise_model_acceptance`.
///
/// # Errors
/// [`DiagnoseError::Fit`] if a least-squares problem fails.
pub fn forward_select(
    prep: &Prepared,
    grids: &[EffectGrid],
    noise_basis: Option<&crate::noise_model::NoiseBasis>,
    options: &DiagnoseOptions,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Selection, DiagnoseError> {
    let ys = targets(prep);
    let indices = block_indices(prep);
    let mut chosen: Vec<ChosenTerm> = Vec::new();
    let mut steps = Vec::new();
    let noise_basis = noise_basis.filter(|_| options.noise_model_acceptance);
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
        let base_heldout = heldout_residuals(&base, &base_eval, &ys);
        let in_model: Vec<Effect> = chosen.iter().map(|c| c.effect).collect();
        let gls = match noise_basis {
            Some(basis) if step < options.max_effects => {
                GlsStep::of(basis, &base, &ys, grids, &in_model, step, options)
            }
            _ => None,
        };
        let ctx = StepContext {
            prep,
            grids,
            ys: &ys,
            options,
            base_parts,
            base,
            base_eval,
            base_heldout,
            n_eff,
            in_model,
            gls,
            noise_basis,
            tests: grids
                .iter()
                .filter(|g| g.unmet_requirement.is_none() && !chosen.iter().any(|c| c.effect == g.effect))
                .count(),
        };
        let cv_rms = (ctx.base_eval.fold_sse.iter().sum::<f64>() / prep.n_blocks() as f64).sqrt();
        let StepOutcome { reports: candidates, pick, tie_break } = if step < options.max_effects {
            run_step(&ctx)?
        } else {
            StepOutcome { reports: Vec::new(), pick: None, tie_break: None }
        };
        steps.push(SelectionStep {
            model: model_names(&chosen),
            cv_rms_dph: cv_rms,
            n_eff,
            rho,
            candidates,
            added: pick.as_ref().map(|p| p.effect.name().to_string()),
            tie_break,
        });
        match pick {
            Some(Pick { effect, point, concealment_index, most_confused_with, route }) => {
                let grid = grids
                    .iter()
                    .find(|g| g.effect == effect)
                    .ok_or(DiagnoseError::Fit("effect grid missing"))?;
                let columns = refine(prep, &chosen_parts(&chosen), grid, point, &ys);
                chosen.push(ChosenTerm {
                    effect,
                    point,
                    columns,
                    concealment_index,
                    most_confused_with,
                    route,
                    step,
                })
            }
            None => break,
        }
    }
    let dropped = if options.backward_elimination {
        let ctx = BackwardContext { prep, grids, ys: &ys, noise_basis, options };
        backward_eliminate(&ctx, &mut chosen)?
    } else {
        Vec::new()
    };
    Ok(Selection { steps, chosen, dropped })
}

/// LORO sum of squared held-out errors (short means) of the model with these terms.
fn loro_sse(prep: &Prepared, parts: &[&TermColumns], ys: &[Vec<f64>]) -> Result<f64, DiagnoseError> {
    let design = build_design(prep, parts);
    Ok(fold_eval(&design, ys)?.fold_sse.iter().sum())
}

/// Backward elimination after forward selection: a term that entered early may be made
/// useless by terms that entered after it (review16 F3: testbed seed 301's hysteresis case
/// named `warmup_transient` at step 1, 0.3 standard errors from zero and +0.1 % held-out once
/// `hysteresis` was in). Every term had to pass a held-out test to enter; with all the others
/// in the model it is judged by the same test again:
/// - a term the run-level rules accepted must still lower the LORO error (the final model's
///   LORO error below that of the model without it);
/// - a term only the noise-model route accepted (its held-out claim is made in the GLS
///   metric) is dropped when it fails the first test and the route, run again with the
///   others as the model ([`GlsStep::of`]), no longer accepts it; when the noise model cannot
///   judge (it cannot be fitted or fails its check) the term is kept.
///
/// Of the terms that fail, the one whose removal lowers the LORO error most is dropped first,
/// and the rest are judged again. The terms are judged at the columns the final model reports
/// ([`super::final_fit::reported_terms`]), so every run-level term left shows a held-out fall
/// in its statement.
///
/// # Errors
/// [`DiagnoseError::Fit`] if a least-squares problem fails.
pub(super) fn backward_eliminate(
    ctx: &BackwardContext<'_>,
    chosen: &mut Vec<ChosenTerm>,
) -> Result<Vec<DroppedTerm>, DiagnoseError> {
    let n_blocks = ctx.prep.n_blocks().max(1) as f64;
    let mut dropped = Vec::new();
    while chosen.len() >= 2 {
        let reported = super::final_fit::reported_terms(ctx.grids, chosen);
        let with_all = loro_sse(ctx.prep, &chosen_parts(&reported), ctx.ys)?;
        let mut without_sse = Vec::with_capacity(reported.len());
        for i in 0..reported.len() {
            without_sse.push(loro_sse(ctx.prep, &chosen_parts(&all_but(&reported, i)), ctx.ys)?);
        }
        let route_only: Vec<bool> = reported.iter().map(|t| t.route.is_some()).collect();
        let still_accepted = |i: usize| ctx.route_still_accepts(&reported, i, dropped.len());
        let Some(i) = weakest_failing(with_all, &without_sse, &route_only, still_accepted) else { break };
        let without = without_sse[i];
        let term = chosen.remove(i);
        dropped.push(DroppedTerm {
            effect: term.effect,
            step: term.step,
            loro_rms_with_dph: (with_all / n_blocks).sqrt(),
            loro_rms_without_dph: (without / n_blocks).sqrt(),
            judged_with: model_names(chosen),
        });
    }
    Ok(dropped)
}

/// What backward elimination reads: the data, the grids and the noise-model route's inputs.
pub(super) struct BackwardContext<'a> {
    pub(super) prep: &'a Prepared,
    pub(super) grids: &'a [EffectGrid],
    pub(super) ys: &'a [Vec<f64>],
    pub(super) noise_basis: Option<&'a crate::noise_model::NoiseBasis>,
    pub(super) options: &'a DiagnoseOptions,
}

impl BackwardContext<'_> {
    /// Whether the noise-model route, run with every term of `reported` but the `i`-th as
    /// the model, still accepts the `i`-th term's effect; true when the route cannot judge.
    /// `round` picks the simulated null's stream (one per backward round, after the forward
    /// steps').
    fn route_still_accepts(&self, reported: &[ChosenTerm], i: usize, round: usize) -> bool {
        let Some(basis) = self.noise_basis else { return true };
        let others = all_but(reported, i);
        let base = build_design(self.prep, &chosen_parts(&others));
        let in_model: Vec<Effect> = others.iter().map(|t| t.effect).collect();
        let step = self.options.max_effects + 1 + round;
        match GlsStep::of(basis, &base, self.ys, self.grids, &in_model, step, self.options) {
            Some(gls) => {
                gls.verdict(reported[i].effect).is_none_or(|v| route_significant(v.family_p, v.heldout))
            }
            None => true,
        }
    }
}

/// Every term but the `i`-th.
fn all_but(terms: &[ChosenTerm], i: usize) -> Vec<ChosenTerm> {
    terms.iter().enumerate().filter(|(j, _)| *j != i).map(|(_, t)| t.clone()).collect()
}

/// The term backward elimination drops next, if any: of the terms whose removal does not
/// raise the LORO error (`without_sse[i] <= with_all`, sums of squared held-out errors) and,
/// for a term only the noise-model route accepted (`route_only[i]`), that the route no longer
/// accepts (`still_accepted(i)`, asked only of such terms), the one whose removal lowers the
/// error most.
fn weakest_failing(
    with_all: f64,
    without_sse: &[f64],
    route_only: &[bool],
    mut still_accepted: impl FnMut(usize) -> bool,
) -> Option<usize> {
    let mut weakest: Option<usize> = None;
    for (i, (&without, &route)) in without_sse.iter().zip(route_only).enumerate() {
        let lower = weakest.is_none_or(|w| without < without_sse[w]);
        if without <= with_all && lower && (!route || !still_accepted(i)) {
            weakest = Some(i);
        }
    }
    weakest
}

/// Family-wise level of the noise-model route at one step (over every open candidate and
/// every point of its grid, by simulation). The false-alarm budget is 2 of 100 null
/// datasets and the run-level rules already spend about that on the null designs
/// (docs/diagnose.md), so the route gets a tenth of the budget. (1 % was tried first: 3 of
/// 100 on the null design and 5 of 100 on a beyond-recovery design; docs/diagnose.md,
/// eighth session.)
pub const GLS_FAMILY_LEVEL: f64 = 0.002;

/// Simulated null draws of the step's smallest GLS p (the Monte Carlo p resolves 1/4001).
pub const GLS_SIMULATIONS: usize = 4000;

/// Seed of the simulated null (one stream per step).
const GLS_SEED: u64 = 0x5EED_0010;

/// One candidate's noise-model GLS test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct GlsVerdict {
    /// Smallest Wald p over the candidate's grid points.
    pub(super) min_p: f64,
    /// Where the route is significant and its held-out claim holds: the grid point of the
    /// route's profile in its held-out GLS error ([`route_report_point`]); a term the route
    /// alone accepts is reported there, not at its LORO-profiled point. Otherwise the
    /// smallest-p point.
    pub(super) point: usize,
    /// The held-out GLS error at `point` relative to the current model's, `1 - with /
    /// without`, where `point` is the route's profile (`None`: not computed).
    pub(super) heldout_gls_fall: Option<f64>,
    /// Family-wise p: the simulated null probability that any open candidate's smallest p
    /// is at least as small.
    pub(super) family_p: f64,
    /// Fitted levels: white (deg/h)^2 per second, flicker (deg/h)^2 per decade.
    pub(super) levels: (f64, f64),
    /// With [`DiagnoseOptions::noise_model_heldout`]: whether the held-out GLS error (the
    /// noise model's metric) falls with the candidate at its smallest-p point, and whether
    /// its GLS coefficient has the physical sign. `None`: the run-level LORO error decides.
    pub(super) heldout: Option<(bool, bool)>,
    /// Whether the levels were fitted with the candidate in the model.
    pub(super) own_levels: bool,
    /// How the family-wise level was shared at this step.
    pub(super) split: LevelSplit,
}

/// How the noise-model route's family-wise level is shared among the open candidates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum LevelSplit {
    /// One family: the smallest p over every candidate's grid.
    None,
    /// [`DiagnoseOptions::noise_model_level_per_candidate`]: evenly over this many open
    /// candidates (the family-wise p is that many times the candidate's own p over its grid).
    Candidates(usize),
    /// [`DiagnoseOptions::noise_model_orientation_families`]: half the level to the
    /// orientation-dependent candidates, half to the rest, each family's smallest p over
    /// its own grids (the family-wise p is twice the family's own).
    OrientationFamilies,
}

impl GlsVerdict {
    /// The route accepts: family-wise significant, and the held-out claim holds (in the
    /// model's metric when measured there, else the run-level LORO error `cv_falls` and
    /// the run-level sign `sign_ok`).
    pub(super) fn accepts(&self, cv_falls: bool, sign_ok: bool) -> bool {
        let claim = match self.heldout {
            Some((falls, sign)) => falls && sign,
            None => cv_falls && sign_ok,
        };
        self.family_p <= GLS_FAMILY_LEVEL && claim
    }

    /// Why the route did not accept, in words: the condition that failed (review16 F7: "not
    /// significant" beside a family-wise p of 0.0000, where the held-out error had not fallen).
    pub(super) fn why_not(&self) -> &'static str {
        if self.family_p.is_nan() {
            "not decided (no family-wise p)"
        } else if self.family_p > GLS_FAMILY_LEVEL {
            "not significant"
        } else {
            match self.heldout {
                Some((false, _)) => "significant, but its held-out GLS error does not fall",
                Some((true, false)) => "significant, but its GLS coefficient has the unphysical sign",
                _ => "significant, but the held-out run-level error does not fall or the sign is unphysical",
            }
        }
    }
}

/// The noise-model route at one step: every candidate's verdict.
pub(super) struct GlsStep {
    verdicts: Vec<(Effect, GlsVerdict)>,
}

/// A candidate's whitened grid bases, their Wald p's and the smallest.
struct GridTest {
    bases: Vec<DMatrix<f64>>,
    min_p: f64,
    /// Grid point of the smallest p.
    best: usize,
}

fn grid_test(tester: &crate::noise_model::GlsTester<'_>, grid: &EffectGrid) -> GridTest {
    let (points, bases): (Vec<usize>, Vec<DMatrix<f64>>) = grid
        .points
        .par_iter()
        .enumerate()
        .filter_map(|(i, pt)| tester.candidate_basis(&pt.per_run).map(|q| (i, q)))
        .unzip();
    let (best, min_p) = points
        .iter()
        .zip(&bases)
        .map(|(i, q)| (*i, tester.wald(q).1))
        .fold((0, 1.0), |acc, (i, p)| if p < acc.1 { (i, p) } else { acc });
    GridTest { bases, min_p, best }
}

/// Family-wise p's of candidates `(whitened grid bases, smallest p, family)` at `level`,
/// and how many families are present. One family (all `false`, or all `true`): the
/// smallest p over every basis, by `sims` simulated draws where the bounds do not decide
/// ([`family_p_at`]). Two families (some of each with a basis): each gets half the level
/// and judges its candidates by the smallest p over its own bases, by twice the draws so
/// that its share is resolved as the whole level is; the family-wise p is twice the
/// family's own (Bonferroni over the two families). A family's stream is `seed` for the
/// first (`false`) family, so that with one family the result is the unsplit route's.
pub(super) fn shared_family_ps(
    n: usize,
    members: &[(&[DMatrix<f64>], f64, bool)],
    level: f64,
    sims: usize,
    seed: u64,
) -> (Vec<f64>, usize) {
    use crate::noise_model::family_p;
    let present = [false, true]
        .iter()
        .filter(|f| members.iter().any(|(b, _, fam)| fam == *f && !b.is_empty()))
        .count()
        .max(1);
    let share = level / present as f64;
    let mut out = vec![f64::NAN; members.len()];
    for (f, fam) in [false, true].into_iter().enumerate() {
        let idx: Vec<usize> = (0..members.len()).filter(|&i| members[i].2 == fam).collect();
        let total: usize = idx.iter().map(|&i| members[i].0.len()).sum();
        let min_ps: Vec<f64> = idx.iter().map(|&i| members[i].1).collect();
        let undecided = min_ps.iter().any(|p| *p <= share && (p * total as f64).min(1.0) > share);
        let simulated = if undecided {
            let refs: Vec<&DMatrix<f64>> = idx.iter().flat_map(|&i| members[i].0).collect();
            let stream = if f == 0 { seed } else { seed ^ 0x0D1E_5EED };
            family_p(n, &refs, &min_ps, sims * present, stream)
        } else {
            min_ps.clone()
        };
        for ((&i, p), sim) in idx.iter().zip(&min_ps).zip(&simulated) {
            out[i] = (present as f64 * family_p_at(*p, total, share, || *sim)).min(1.0);
        }
    }
    (out, present)
}

/// The family-wise p of one candidate's smallest p (`min_p`) among `total` bases of the
/// step: its own p when above the level, its Bonferroni bound when that is at the level,
/// else `simulate()` (the simulated null of the step's smallest p).
fn family_p_of(min_p: f64, total: usize, simulate: impl FnOnce() -> f64) -> f64 {
    family_p_at(min_p, total, GLS_FAMILY_LEVEL, simulate)
}

/// [`family_p_of`] at the level `level` (a family's share of the route's level).
fn family_p_at(min_p: f64, total: usize, level: f64, simulate: impl FnOnce() -> f64) -> f64 {
    let bonferroni = (min_p * total as f64).min(1.0);
    if min_p > level {
        min_p
    } else if bonferroni <= level {
        bonferroni
    } else {
        simulate()
    }
}

/// Noise levels by REML with the current model plus the whole span of `family`'s grids
/// (every grid point's columns, reduced to independent directions) in place; `None` when
/// that design is singular or the model fails its innovation check.
fn family_span_fit(
    basis: &crate::noise_model::NoiseBasis,
    base: &Design,
    ys: &[Vec<f64>],
    family: &[&EffectGrid],
) -> Option<crate::noise_model::NoiseFit> {
    let runs = base.per_run.len();
    let extra: Vec<DMatrix<f64>> = (0..runs)
        .map(|r| {
            let cols: Vec<&DMatrix<f64>> =
                family.iter().flat_map(|g| g.points.iter().filter_map(move |pt| pt.per_run.get(r))).collect();
            hcat(base.per_run[r].nrows(), &cols)
        })
        .collect();
    let span = crate::noise_model::independent_extension(&base.per_run, &extra)?;
    let with = concat_runs(base, &span);
    let fit = crate::noise_model::fit_noise(basis, &with, ys)?;
    fit.check.passed.then_some(fit)
}

/// Simulated null draws of one candidate's own smallest p over its grid when the level is
/// split over the candidates: its share of the level (0.002 / 7 = 2.9e-4 for 7 open
/// candidates) is then resolved by about 11 draws.
pub const GLS_OWN_SIMULATIONS: usize = 40_000;

/// The family-wise p of one candidate's smallest p (`min_p`, over its `points` grid bases)
/// when the level is split evenly over `candidates` open candidates (Bonferroni over
/// effects): `candidates` times its own p, which lies between `min_p` (one point) and
/// `points x min_p` (Bonferroni over its grid). The bounds decide when they can; else
/// `simulate()` gives the own p (the simulated null of its smallest p over its grid).
fn split_family_p(min_p: f64, points: usize, candidates: usize, simulate: impl FnOnce() -> f64) -> f64 {
    let m = candidates.max(1) as f64;
    (m * family_p_at(min_p, points, GLS_FAMILY_LEVEL / m, simulate)).min(1.0)
}

/// Held-out GLS fit (leave one run out, under the levels of `fit`) of the current model
/// with `cols` added. The spline penalties of the current model and of the candidate are
/// kept, as in the run-level LORO fits.
fn heldout_with(
    fit: &crate::noise_model::NoiseFit,
    base: &Design,
    ys: &[Vec<f64>],
    cols: &TermColumns,
) -> Option<crate::noise_model::HeldOut> {
    let with = concat_runs(base, &cols.per_run);
    let (p, k) = (base.p(), cols.k());
    let base_rows = base.penalty.as_ref().map_or(0, |m| m.nrows());
    let cand_rows = cols.penalty.as_ref().map_or(0, |m| m.nrows());
    if base.penalty.as_ref().is_some_and(|m| m.ncols() != p)
        || cols.penalty.as_ref().is_some_and(|m| m.ncols() != k)
    {
        return None;
    }
    let pen_with = (base_rows + cand_rows > 0).then(|| {
        let mut m = DMatrix::zeros(base_rows + cand_rows, p + k);
        if let Some(b) = &base.penalty {
            m.view_mut((0, 0), (base_rows, p)).copy_from(b);
        }
        if let Some(c) = &cols.penalty {
            m.view_mut((base_rows, p), (cand_rows, k)).copy_from(c);
        }
        m
    });
    heldout_gls(fit, &with, ys, pen_with.as_ref())
}

/// Held-out GLS claim of a candidate's grid point under `fit`: (error falls below the
/// current model's `without_sse`, sign holds).
fn heldout_claim(
    fit: &crate::noise_model::NoiseFit,
    base: &Design,
    ys: &[Vec<f64>],
    grid: &EffectGrid,
    point: usize,
    without_sse: f64,
) -> Option<(bool, bool)> {
    let with = heldout_with(fit, base, ys, &grid.points[point])?;
    let last = with.beta.len().checked_sub(1).map_or(f64::NAN, |i| with.beta[i]);
    let sign = !grid.effect.positive_coefficient() || last > 0.0;
    Some((with.sse() < without_sse, sign))
}

/// The grid point at which a term the route accepts is reported, [`route_profile`] under
/// `fit`, with its held-out GLS error's fall below the current model's `without_sse`
/// (`1 - with / without`). Only computed when the route is significant and its claim holds
/// (`route_accepts`); otherwise, or when no point can be fitted, the smallest-p point.
fn route_report_point(
    fit: &crate::noise_model::NoiseFit,
    base: &Design,
    ys: &[Vec<f64>],
    grid: &EffectGrid,
    smallest_p_point: usize,
    route_accepts: bool,
    without_sse: Option<f64>,
) -> (usize, Option<f64>) {
    if !route_accepts {
        return (smallest_p_point, None);
    }
    let fitted: Vec<(usize, crate::noise_model::HeldOut)> = grid
        .points
        .par_iter()
        .enumerate()
        .filter_map(|(i, cols)| heldout_with(fit, base, ys, cols).map(|h| (i, h)))
        .collect();
    route_profile(grid, &fitted)
        .map_or((smallest_p_point, None), |(i, sse)| (i, without_sse.map(|w| 1.0 - sse / w)))
}

/// The route's profile of a grid from each point's held-out GLS fit (`fitted`), as
/// `design::profile_candidate` profiles by the LORO error, in the route's metric: per
/// discrete complexity (basis size, number of exponentials, degree, form) the continuous
/// parameters of the lowest held-out GLS error; across complexities the lowest, or for an
/// effect of nested complexity (`design::one_standard_error_choice`) the fewest coefficients
/// within one standard error of the lowest, the error of the per-run differences (paired:
/// the runs' whitened errors differ with their lengths far more than between two fits).
/// Returns the point and its error.
fn route_profile(grid: &EffectGrid, fitted: &[(usize, crate::noise_model::HeldOut)]) -> Option<(usize, f64)> {
    let mut per_complexity: BTreeMap<Vec<u64>, &(usize, crate::noise_model::HeldOut)> = BTreeMap::new();
    for f in fitted {
        let slot = per_complexity.entry(complexity_key(grid, f.0)).or_insert(f);
        if f.1.sse() < slot.1.sse() {
            *slot = f;
        }
    }
    let lowest = per_complexity.values().min_by(|a, b| a.1.sse().total_cmp(&b.1.sse()))?;
    // Within one standard error of the lowest, paired over the runs: the standard error of
    // the total of the per-run differences.
    let within = |f: &(usize, crate::noise_model::HeldOut)| {
        if !grid.effect.nested_complexity() {
            return f.1.sse() <= lowest.1.sse();
        }
        let d: Vec<f64> = f.1.per_run_sse.iter().zip(&lowest.1.per_run_sse).map(|(a, b)| a - b).collect();
        d.iter().sum::<f64>() <= standard_error_of_total(&d)
    };
    let k = |f: &(usize, crate::noise_model::HeldOut)| grid.points[f.0].k();
    per_complexity
        .values()
        .filter(|f| within(f))
        .min_by(|a, b| k(a).cmp(&k(b)).then(a.1.sse().total_cmp(&b.1.sse())))
        .map(|f| (f.0, f.1.sse()))
}

/// Whether the route's verdict is significant and its held-out claim (when measured) holds.
fn route_significant(family_p: f64, heldout: Option<(bool, bool)>) -> bool {
    family_p <= GLS_FAMILY_LEVEL && heldout.is_none_or(|(falls, sign)| falls && sign)
}

impl GlsStep {
    /// The route at one step. Without `own_levels`: the noise model is fitted with the
    /// current model in place; `None` when it cannot be fitted or fails its innovation
    /// check (the run-level rules then decide alone). With `own_levels`: each candidate's
    /// levels are refitted with it (at its smallest-p point under the current model's
    /// levels) in the model, its innovation check is made on that model, and its grid is
    /// tested at those levels; a candidate whose model fails the check gets no verdict.
    pub(super) fn of(
        basis: &crate::noise_model::NoiseBasis,
        base: &Design,
        ys: &[Vec<f64>],
        grids: &[EffectGrid],
        in_model: &[Effect],
        step: usize,
        options: &DiagnoseOptions,
    ) -> Option<Self> {
        use crate::noise_model::{fit_noise, GlsTester};
        let fit = fit_noise(basis, &base.per_run, ys)?;
        // Under the null (no open candidate) the current model is the true one: its levels
        // make the simulated family-wise p exact for the whole procedure. Levels refitted
        // with the smallest-p candidate absorb part of the slow noise under the null (the
        // point is chosen to fit it), so they are used only where the current model fails
        // its check, i.e. where the null model is already rejected by the data.
        let own_levels = options.noise_model_candidate_levels && !fit.check.passed;
        if !own_levels && !fit.check.passed {
            return None;
        }
        let tester = GlsTester::new(&fit, &base.per_run, ys)?;
        let open: Vec<&EffectGrid> =
            grids.iter().filter(|g| g.unmet_requirement.is_none() && !in_model.contains(&g.effect)).collect();
        let tests: Vec<GridTest> = open.par_iter().map(|g| grid_test(&tester, g)).collect();
        let route = RouteStep {
            basis,
            base,
            ys,
            options,
            fit: &fit,
            tester: &tester,
            open,
            tests,
            seed: GLS_SEED + step as u64,
        };
        let verdicts = if own_levels {
            route.own_level_verdicts()
        } else if options.noise_model_level_per_candidate {
            route.per_candidate_verdicts()
        } else {
            route.family_split_verdicts()
        };
        Some(GlsStep { verdicts })
    }

    pub(super) fn verdict(&self, effect: Effect) -> Option<GlsVerdict> {
        self.verdicts.iter().find(|(e, _)| *e == effect).map(|(_, v)| *v)
    }
}

/// One candidate as judged by one of the route's three ways, before its verdict is made.
struct Judged {
    /// Smallest Wald p over the grid, at point `best`.
    min_p: f64,
    best: usize,
    family_p: f64,
    /// The held-out claim at `best` (falls, physical sign); `None`: not computed.
    heldout: Option<(bool, bool)>,
    /// The current model's held-out GLS error under the levels `fit` (see `verdict_of`).
    without_sse: Option<f64>,
}

/// What the route's three ways of judging the open candidates share at one step.
struct RouteStep<'a> {
    basis: &'a crate::noise_model::NoiseBasis,
    base: &'a Design,
    ys: &'a [Vec<f64>],
    options: &'a DiagnoseOptions,
    /// The noise model fitted with the current model in place.
    fit: &'a crate::noise_model::NoiseFit,
    tester: &'a crate::noise_model::GlsTester<'a>,
    open: Vec<&'a EffectGrid>,
    /// Each open candidate's grid tested at the current model's levels.
    tests: Vec<GridTest>,
    /// Seed of the step's simulated null.
    seed: u64,
}

impl RouteStep<'_> {
    /// The current model's held-out GLS error under levels `f` (with the option on).
    fn heldout_of(&self, f: &crate::noise_model::NoiseFit) -> Option<crate::noise_model::HeldOut> {
        self.options
            .noise_model_heldout
            .then(|| heldout_gls(f, &self.base.per_run, self.ys, self.base.penalty.as_ref()))
            .flatten()
    }

    /// The verdict the three ways share once a candidate is judged under the levels `fit`:
    /// accepted when significant with its claim holding, then reported at the route's
    /// profile ([`route_report_point`]).
    fn verdict_of(
        &self,
        fit: &crate::noise_model::NoiseFit,
        grid: &EffectGrid,
        judged: Judged,
        own_levels: bool,
        split: LevelSplit,
    ) -> GlsVerdict {
        let accepts = route_significant(judged.family_p, judged.heldout);
        let (point, heldout_gls_fall) =
            route_report_point(fit, self.base, self.ys, grid, judged.best, accepts, judged.without_sse);
        GlsVerdict {
            min_p: judged.min_p,
            point,
            heldout_gls_fall,
            family_p: judged.family_p,
            levels: (fit.white_var, fit.flicker_var),
            heldout: judged.heldout,
            own_levels,
            split,
        }
    }

    /// [`DiagnoseOptions::noise_model_candidate_levels`]: each candidate at levels refitted
    /// with it in the model (see [`GlsStep::of`]).
    fn own_level_verdicts(&self) -> Vec<(Effect, GlsVerdict)> {
        use crate::noise_model::{family_p, fit_noise, GlsTester};
        let (base, ys) = (self.base, self.ys);
        let total: usize = self.tests.iter().map(|t| t.bases.len()).sum();
        self.open
            .par_iter()
            .zip(&self.tests)
            .filter_map(|(g, t)| {
                let cols = &g.points[t.best];
                let with = concat_runs(base, &cols.per_run);
                let own = fit_noise(self.basis, &with, ys)?;
                if !own.check.passed {
                    return None;
                }
                let own_tester = GlsTester::new(&own, &base.per_run, ys)?;
                let mine = grid_test(&own_tester, g);
                let without_sse = if self.options.noise_model_heldout {
                    Some(heldout_gls(&own, &base.per_run, ys, base.penalty.as_ref())?.sse())
                } else {
                    None
                };
                let heldout = without_sse.and_then(|w| heldout_claim(&own, base, ys, g, mine.best, w));
                // The simulation (the whole step at this candidate's levels) is only
                // needed when the held-out claim holds; else NaN: not simulated.
                let claim = heldout.is_none_or(|(falls, sign)| falls && sign);
                let family_p = family_p_of(mine.min_p, total, || {
                    if !claim {
                        return f64::NAN;
                    }
                    let all: Vec<GridTest> = self.open.iter().map(|h| grid_test(&own_tester, h)).collect();
                    let refs: Vec<&DMatrix<f64>> = all.iter().flat_map(|t| &t.bases).collect();
                    family_p(own_tester.n(), &refs, &[mine.min_p], GLS_SIMULATIONS, self.seed)[0]
                });
                let judged = Judged { min_p: mine.min_p, best: mine.best, family_p, heldout, without_sse };
                Some((g.effect, self.verdict_of(&own, g, judged, true, LevelSplit::None)))
            })
            .collect()
    }

    /// [`DiagnoseOptions::noise_model_level_per_candidate`]: the level split evenly over the
    /// open candidates, each judged by its own grid.
    fn per_candidate_verdicts(&self) -> Vec<(Effect, GlsVerdict)> {
        use crate::noise_model::family_p;
        let without = self.heldout_of(self.fit);
        let candidates = self.tests.iter().filter(|t| !t.bases.is_empty()).count();
        self.open
            .par_iter()
            .zip(&self.tests)
            .enumerate()
            .map(|(i, (g, t))| {
                let heldout = without
                    .as_ref()
                    .and_then(|w| heldout_claim(self.fit, self.base, self.ys, g, t.best, w.sse()));
                // The simulation of the candidate's own grid is needed only when its claim
                // holds; else NaN: not simulated.
                let claim = heldout.is_none_or(|(falls, sign)| falls && sign);
                let family_p = split_family_p(t.min_p, t.bases.len(), candidates, || {
                    if !claim {
                        return f64::NAN;
                    }
                    let refs: Vec<&DMatrix<f64>> = t.bases.iter().collect();
                    let stream = self.seed ^ (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                    family_p(self.tester.n(), &refs, &[t.min_p], GLS_OWN_SIMULATIONS, stream)[0]
                });
                let without_sse = without.as_ref().map(|w| w.sse());
                let judged = Judged { min_p: t.min_p, best: t.best, family_p, heldout, without_sse };
                (g.effect, self.verdict_of(self.fit, g, judged, false, LevelSplit::Candidates(candidates)))
            })
            .collect()
    }

    /// The default: every open candidate against the smallest p over its family's grids
    /// (one family, or with [`DiagnoseOptions::noise_model_orientation_families`] the
    /// orientation-dependent candidates and the rest, each with half the level).
    fn family_split_verdicts(&self) -> Vec<(Effect, GlsVerdict)> {
        let options = self.options;
        let in_family = |e: Effect| options.noise_model_orientation_families && e.orientation_dependent();
        let family_fit = self.orientation_family_fit(&in_family);
        let family_tester = family_fit
            .as_ref()
            .and_then(|f| crate::noise_model::GlsTester::new(f, &self.base.per_run, self.ys));
        let family_tests: Vec<Option<GridTest>> = self
            .open
            .par_iter()
            .map(|g| match &family_tester {
                Some(ft) if in_family(g.effect) => Some(grid_test(ft, g)),
                _ => None,
            })
            .collect();
        let chosen: Vec<&GridTest> =
            self.tests.iter().zip(&family_tests).map(|(t, ft)| ft.as_ref().unwrap_or(t)).collect();
        let members: Vec<(&[DMatrix<f64>], f64, bool)> = self
            .open
            .iter()
            .zip(&chosen)
            .map(|(g, t)| (t.bases.as_slice(), t.min_p, in_family(g.effect)))
            .collect();
        let (simulated, present) =
            shared_family_ps(self.tester.n(), &members, GLS_FAMILY_LEVEL, GLS_SIMULATIONS, self.seed);
        let split = if present > 1 { LevelSplit::OrientationFamilies } else { LevelSplit::None };
        let without = self.heldout_of(self.fit);
        let family_without = family_fit.as_ref().and_then(|f| self.heldout_of(f));
        self.open
            .iter()
            .zip(&chosen)
            .zip(&family_tests)
            .zip(&simulated)
            .map(|(((g, t), ft), family_p)| {
                let (f, w) = match (ft, &family_fit) {
                    (Some(_), Some(ff)) => (ff, family_without.as_ref()),
                    _ => (self.fit, without.as_ref()),
                };
                let heldout = w.and_then(|w| heldout_claim(f, self.base, self.ys, g, t.best, w.sse()));
                let without_sse = w.map(|w| w.sse());
                let judged =
                    Judged { min_p: t.min_p, best: t.best, family_p: *family_p, heldout, without_sse };
                (g.effect, self.verdict_of(f, g, judged, ft.is_some(), split))
            })
            .collect()
    }

    /// With [`DiagnoseOptions::noise_model_family_levels`]: the orientation family's own
    /// levels, REML with its candidates' whole grid span in the model (a choice that does not
    /// depend on the data), when both families are open and that model passes its check.
    fn orientation_family_fit(
        &self,
        in_family: &dyn Fn(Effect) -> bool,
    ) -> Option<crate::noise_model::NoiseFit> {
        let both_open = [false, true].iter().all(|f| {
            self.open.iter().zip(&self.tests).any(|(g, t)| in_family(g.effect) == *f && !t.bases.is_empty())
        });
        if !(self.options.noise_model_family_levels && both_open) {
            return None;
        }
        let family: Vec<&EffectGrid> = self.open.iter().copied().filter(|g| in_family(g.effect)).collect();
        family_span_fit(self.basis, self.base, self.ys, &family)
    }
}

fn gls_note(v: Option<GlsVerdict>) -> String {
    v.map_or_else(String::new, |v| {
        format!(
            "family-wise p {}{}, {GLS_FAMILY_LEVEL} needed; smallest Wald p over the grid {:.2e}; noise{}: white {:.2e} (deg/h)^2 per s, bias-instability decade {:.2e} (deg/h)^2{}",
            if v.family_p.is_nan() { "not simulated".to_string() } else { format!("{:.4}", v.family_p) },
            match v.split {
                LevelSplit::None => String::new(),
                LevelSplit::Candidates(m) => format!(
                    " ({m} x the candidate's own p over its grid: the level split over {m} open candidates)"
                ),
                LevelSplit::OrientationFamilies => " (2 x its family's p: the level split between the orientation-dependent candidates and the rest)".to_string(),
            },
            v.min_p,
            match (v.own_levels, v.split) {
                (false, _) => "",
                (true, LevelSplit::OrientationFamilies) => " (levels with the family's grid span)",
                (true, _) => " (levels with the candidate)",
            },
            v.levels.0,
            v.levels.1,
            match v.heldout {
                Some((falls, sign)) => format!(
                    "; held-out GLS error {}{}",
                    if falls { "falls" } else { "does not fall" },
                    if sign { "" } else { "; GLS coefficient has the unphysical sign" }
                ),
                None => String::new(),
            }
        )
    })
}

/// Passes every rule at a step without being selected, and lowers the LORO error by at
/// least [`ALTERNATIVE_SHARE`] of what the selected effect lowers it by: an alternative
/// explanation these runs hardly separate.
pub(super) const RUNNER_UP_NOTE: &str = "passes the rules but another effect lowers the LORO error more";

/// The LORO winner that the encompassing tie-break replaced: the runner-up adds significantly
/// beyond it in the noise model, and more than it adds beyond the runner-up.
pub(super) const ENCOMPASSED_NOTE: &str = "passes the rules and has the lowest LORO error, but the selected effect \
     encompasses it in the noise model (it adds significantly beyond this one, and more than this one adds beyond it)";

/// Passes every rule at a step without being selected, but lowers the LORO error by less
/// than [`ALTERNATIVE_SHARE`] of what the selected effect lowers it by: it explains part of
/// what another effect explains better, so it is not listed as an alternative.
pub(super) const RUNNER_UP_PARTIAL_NOTE: &str =
    "passes the rules but explains less than half of what the selected effect explains in held-out runs";

#[cfg(test)]
mod tests {
    use super::*;

    fn cand(effect: Effect, fold_sse: &[f64], k: usize) -> (Vec<f64>, usize, Pick) {
        (
            fold_sse.to_vec(),
            k,
            Pick { effect, point: 0, concealment_index: 0.0, most_confused_with: None, route: None },
        )
    }

    #[test]
    fn the_route_accepts_only_a_family_wise_significant_candidate_whose_claim_holds() {
        let v = |family_p: f64, heldout: Option<(bool, bool)>| GlsVerdict {
            min_p: family_p,
            point: 0,
            heldout_gls_fall: None,
            family_p,
            levels: (1e-3, 1e-6),
            heldout,
            own_levels: false,
            split: LevelSplit::None,
        };
        // Held-out claim in the model's metric: the run-level LORO error and sign do not count.
        assert!(v(0.002, Some((true, true))).accepts(false, false));
        assert!(!v(0.0021, Some((true, true))).accepts(true, true));
        assert!(!v(0.001, Some((false, true))).accepts(true, true));
        assert!(!v(0.001, Some((true, false))).accepts(true, true));
        // Without it: the run-level LORO error and sign decide the claim.
        assert!(v(0.001, None).accepts(true, true));
        assert!(!v(0.001, None).accepts(false, true));
        assert!(!v(0.001, None).accepts(true, false));
    }

    #[test]
    fn family_p_of_uses_the_bounds_before_simulating() {
        // Own p above the level: reported as is. Bonferroni bound 1e-5 x 100 = 1e-3 at the
        // level: the bound. Between: the simulation.
        assert_eq!(family_p_of(0.01, 100, || f64::NAN), 0.01);
        assert!((family_p_of(1e-5, 100, || f64::NAN) - 1e-3).abs() < 1e-15);
        assert_eq!(family_p_of(1e-4, 100, || 0.0042), 0.0042);
    }

    #[test]
    fn split_family_p_is_the_candidates_times_the_own_p_within_its_bounds() {
        // 7 candidates, level 0.002: own p 1e-3 -> 7e-3 (lower bound, above); one point at
        // 2e-4 -> 1.4e-3 (the bounds meet); 1e-4 over 3 points -> between 7e-4 and 2.1e-3:
        // 7 x the simulated own p.
        assert!((split_family_p(1e-3, 3, 7, || f64::NAN) - 7e-3).abs() < 1e-15);
        assert!((split_family_p(2e-4, 1, 7, || f64::NAN) - 1.4e-3).abs() < 1e-15);
        assert!((split_family_p(1e-4, 3, 7, || 1.5e-4) - 1.05e-3).abs() < 1e-15);
        assert_eq!(split_family_p(0.5, 3, 7, || f64::NAN), 1.0);
    }

    /// Orthonormal columns `cols` of an n x k basis: unit vectors e_j (cos a) + e_{j+1} (sin a)
    /// spread over the rows, so that neighbouring grid points share a direction.
    fn grid_bases(n: usize, first_row: usize, points: usize, angle: f64) -> Vec<DMatrix<f64>> {
        (0..points)
            .map(|k| {
                let mut q = DMatrix::zeros(n, 1);
                q[(first_row, 0)] = (angle * k as f64).cos();
                q[(first_row + 1, 0)] = (angle * k as f64).sin();
                q
            })
            .collect()
    }

    fn smallest_p(bases: &[DMatrix<f64>], z: &nalgebra::DVector<f64>) -> f64 {
        use crate::noise_model::chi2_sf;
        bases.iter().map(|q| chi2_sf((q.transpose() * z).norm_squared(), q.ncols())).fold(1.0, f64::min)
    }

    #[test]
    fn shared_family_ps_with_one_family_are_the_unsplit_ones_and_with_two_twice_the_own() {
        // One 1-column candidate per family, orthogonal: the bounds decide, 2 x its p.
        let n = 20;
        let a = grid_bases(n, 0, 1, 0.0);
        let b = grid_bases(n, 4, 1, 0.0);
        let (two, present) =
            shared_family_ps(n, &[(a.as_slice(), 1e-4, false), (b.as_slice(), 0.3, true)], 0.002, 4000, 1);
        assert_eq!(present, 2);
        assert!((two[0] - 2e-4).abs() < 1e-15 && (two[1] - 0.6).abs() < 1e-15, "{two:?}");
        // Both in one family: the unsplit route (family_p_of over their 2 bases).
        let (one, present) =
            shared_family_ps(n, &[(a.as_slice(), 1e-4, false), (b.as_slice(), 0.3, false)], 0.002, 4000, 1);
        assert_eq!(present, 1);
        assert_eq!(one, vec![family_p_of(1e-4, 2, || f64::NAN), 0.3]);
        // A family whose candidates have no basis is absent: the other keeps the whole level.
        let none: Vec<DMatrix<f64>> = Vec::new();
        let (_, present) =
            shared_family_ps(n, &[(a.as_slice(), 1e-4, false), (none.as_slice(), 1.0, true)], 0.002, 4000, 1);
        assert_eq!(present, 1);
    }

    #[test]
    fn shared_family_ps_hold_the_family_wise_level_under_the_null() {
        // Null data z ~ N(0, I_30) (fixed seeds), three candidates: a 1-column one and a
        // 2-point grid (60 degrees apart) in the orientation family, a 6-point grid (20
        // degrees apart) in the other. Level 0.05 (so that 1000 datasets resolve it), 1000
        // draws per simulation. Bonferroni over the two families holds the level: share of
        // datasets with any family-wise p <= 0.05 at most 0.05 + 3.5 binomial SD (0.0069),
        // and each family's share near its half, 0.025 (3.5 SD: 0.017).
        let n = 30;
        let one = grid_bases(n, 0, 1, 0.0);
        let two = grid_bases(n, 2, 2, std::f64::consts::FRAC_PI_3);
        let six = grid_bases(n, 6, 6, std::f64::consts::PI / 9.0);
        let datasets = 1000;
        let (mut any, mut orientation, mut rest) = (0, 0, 0);
        for d in 0..datasets {
            let z = nalgebra::DVector::from_vec(normals(5000 + d as u64, n));
            let members = [
                (one.as_slice(), smallest_p(&one, &z), true),
                (two.as_slice(), smallest_p(&two, &z), true),
                (six.as_slice(), smallest_p(&six, &z), false),
            ];
            let (ps, present) = shared_family_ps(n, &members, 0.05, 1000, 77 + d as u64);
            assert_eq!(present, 2);
            let hit_o = ps[0] <= 0.05 || ps[1] <= 0.05;
            let hit_r = ps[2] <= 0.05;
            any += usize::from(hit_o || hit_r);
            orientation += usize::from(hit_o);
            rest += usize::from(hit_r);
        }
        let share = |k: usize| k as f64 / datasets as f64;
        eprintln!(
            "null shares: any {}, orientation {}, rest {}",
            share(any),
            share(orientation),
            share(rest)
        );
        assert!(share(any) <= 0.05 + 3.5 * 0.0069, "any {}", share(any));
        assert!((share(orientation) - 0.025).abs() <= 0.017, "orientation {}", share(orientation));
        assert!((share(rest) - 0.025).abs() <= 0.017, "rest {}", share(rest));
    }

    #[test]
    fn parsimonious_pick_takes_the_smallest_term_within_one_standard_error() {
        // Best: total 4, per-run errors 0.5, 1.5, 1, 1: mean 1, sd sqrt(0.5 / 3) = 0.40825,
        // limit 4 + 0.40825 x sqrt(4) = 4.8165.
        let best = [0.5, 1.5, 1.0, 1.0];
        let picked = parsimonious_pick(vec![
            cand(Effect::WarmupTransient, &best, 2),
            cand(Effect::GradientRate, &[1.2, 1.2, 1.0, 1.1], 1), // 4.5, within
            cand(Effect::Hysteresis, &[1.0, 1.2, 1.0, 1.1], 1),   // 4.3, within, lower
            cand(Effect::ShupeRate, &[1.3, 1.2, 1.2, 1.2], 1),    // 4.9, outside
        ]);
        assert_eq!(picked.map(|p| p.effect), Some(Effect::Hysteresis));
        // Equal per-run errors: sd 0, the limit is the best itself.
        let picked = parsimonious_pick(vec![
            cand(Effect::WarmupTransient, &[1.0; 4], 2),
            cand(Effect::Hysteresis, &[1.0, 1.0, 1.0, 1.01], 1),
        ]);
        assert_eq!(picked.map(|p| p.effect), Some(Effect::WarmupTransient));
        assert!(parsimonious_pick(Vec::new()).is_none());
    }

    #[test]
    fn explained_share_is_the_runner_ups_fall_over_the_selected_ones() {
        // Base 10, selected 6 (falls 4), runner-up 8 (falls 2): half.
        assert!((explained_share(10.0, 8.0, 6.0) - 0.5).abs() < 1e-15);
        assert!((explained_share(10.0, 5.0, 6.0) - 1.25).abs() < 1e-15); // lower error than the selected
        assert!(explained_share(10.0, 11.0, 6.0) < 0.0); // rises
        assert_eq!(explained_share(10.0, 8.0, 10.0), 0.0); // the selected lowers nothing
    }

    #[test]
    fn parsimonious_set_keeps_the_fewest_coefficients_within_the_limit_lowest_error_first() {
        // The first case above: limit 4.8165; warm-up has two coefficients, shupe 4.9 is
        // outside; hysteresis 4.3 and gradient 4.5 remain, in that order.
        let best = [0.5, 1.5, 1.0, 1.0];
        let set: Vec<Effect> = parsimonious_set(vec![
            cand(Effect::WarmupTransient, &best, 2),
            cand(Effect::GradientRate, &[1.2, 1.2, 1.0, 1.1], 1),
            cand(Effect::Hysteresis, &[1.0, 1.2, 1.0, 1.1], 1),
            cand(Effect::ShupeRate, &[1.3, 1.2, 1.2, 1.2], 1),
        ])
        .into_iter()
        .map(|a| a.2.effect)
        .collect();
        assert_eq!(set, vec![Effect::Hysteresis, Effect::GradientRate]);
        assert!(parsimonious_set(Vec::new()).is_empty());
    }

    #[test]
    fn encompassing_prefers_the_candidate_the_other_adds_less_to() {
        // Winner adds p 0.01 beyond the runner-up, the runner-up p 0.3 beyond the winner: keep.
        assert!(!encompassing_prefers_second(0.01, 0.3));
        // Reversed: the runner-up explains what the winner does and more.
        assert!(encompassing_prefers_second(0.3, 0.01));
        // Equal: the LORO winner stays.
        assert!(!encompassing_prefers_second(0.2, 0.2));
        // Neither adds significantly beyond the other (testbed seed 16's lag against a rate
        // term, 0.267 and 0.173): the smaller p is no evidence, the winner stays.
        assert!(!encompassing_prefers_second(0.267, 0.173));
        // Both add significantly: the one the other adds less to (our design's seed 5002,
        // shupe_rate the winner at 0.037, the lag the runner-up at 0.0075).
        assert!(encompassing_prefers_second(0.037, 0.0075));
        // Just at the level: not below it, the winner stays.
        assert!(!encompassing_prefers_second(0.5, ENCOMPASSING_LEVEL));
    }

    /// Standard normals from a fixed-seed 64-bit LCG (Box-Muller).
    fn normals(seed: u64, n: usize) -> Vec<f64> {
        let mut s = seed;
        let mut u = || {
            s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        (0..n).map(|_| (-2.0 * u().ln()).sqrt() * (std::f64::consts::TAU * u()).cos()).collect()
    }

    /// The noise basis of `runs` runs of `blocks` consecutive 20 s short means.
    fn short_mean_basis(runs: usize, blocks: usize) -> crate::noise_model::NoiseBasis {
        let spans: Vec<Vec<(usize, usize)>> =
            vec![(0..blocks).map(|i| (20 * i, 20 * i + 20)).collect(); runs];
        crate::noise_model::NoiseBasis::new(&spans).expect("basis")
    }

    #[test]
    fn a_term_the_route_accepts_is_reported_where_its_heldout_gls_error_is_lowest() {
        // 6 runs of 180 short means of 20 s, white noise of SD 0.01 per short mean, an
        // intercept per run. The data hold a slow trend 0.004 x sin(i / 9) and a ripple
        // 0.004 x sin(i / 2). Grid: the trend alone (point 0), trend and ripple (point 1), the
        // trend and a ripple of the wrong frequency (point 2). Leaving the ripple out adds its
        // variance, 0.004^2 / 2 = 8e-6 per short mean (8.6e-3 over 1080 means), to the
        // held-out error, 86 x the noise variance 1e-4 that one needless coefficient costs
        // (the wrong ripple of point 2 costs about that); so point 1 is the lowest by far.
        // Not significant: the smallest-p point is kept.
        let (runs, blocks) = (6, 180);
        let basis = short_mean_basis(runs, blocks);
        let trend = |r: usize, i: usize| ((i + 17 * r) as f64 / 9.0).sin();
        let ripple = |r: usize, i: usize| ((i + 5 * r) as f64 / 2.0).sin();
        let wrong = |r: usize, i: usize| ((i + 5 * r) as f64 / 3.0).sin();
        let term = |fs: &[&dyn Fn(usize, usize) -> f64]| TermColumns {
            theta: vec![],
            coefficients: vec![("c".into(), "deg/h".into()); fs.len()],
            per_run: (0..runs).map(|r| DMatrix::from_fn(blocks, fs.len(), |i, j| fs[j](r, i))).collect(),
            penalty: None,
        };
        let grid = EffectGrid {
            effect: Effect::StaticShape,
            params: vec![],
            points: vec![term(&[&trend]), term(&[&trend, &ripple]), term(&[&trend, &wrong])],
            unmet_requirement: None,
        };
        let base = Design {
            per_run: (0..runs).map(|_| DMatrix::from_element(blocks, 1, 1.0)).collect(),
            scale: vec![1.0],
            penalty: None,
        };
        let ys: Vec<Vec<f64>> = (0..runs)
            .map(|r| {
                let e = normals(200 + r as u64, blocks);
                (0..blocks).map(|i| 0.004 * (trend(r, i) + ripple(r, i)) + 0.01 * e[i]).collect()
            })
            .collect();
        let fit = crate::noise_model::fit_noise(&basis, &base.per_run, &ys).expect("noise fit");
        let without = heldout_gls(&fit, &base.per_run, &ys, None).expect("fit").sse();
        let (point, fall) = route_report_point(&fit, &base, &ys, &grid, 0, true, Some(without));
        assert_eq!(point, 1);
        assert_eq!(route_report_point(&fit, &base, &ys, &grid, 2, false, Some(without)), (2, None));
        // The held-out errors behind it (whitened: about 1 per short mean, so one needless
        // coefficient costs about 1): point 1 lowest, more than 10 below the others.
        let sse: Vec<f64> =
            grid.points.iter().map(|c| heldout_with(&fit, &base, &ys, c).expect("fit").sse()).collect();
        assert!(sse[1] + 10.0 < sse[0].min(sse[2]), "{sse:?}");
        // The reported fall is that point's error against the intercept-only model's.
        assert_eq!(fall, Some(1.0 - sse[1] / without));
        assert!(fall.is_some_and(|f| f > 0.0));
    }

    #[test]
    fn the_routes_profile_takes_the_fewest_coefficients_within_one_paired_standard_error() {
        use crate::effects::ProfiledParam;
        use crate::noise_model::HeldOut;
        let cols = |k: usize, theta: Vec<f64>| TermColumns {
            theta,
            coefficients: vec![("c".into(), "deg/h".into()); k],
            per_run: Vec::new(),
            penalty: None,
        };
        let grid = |effect: Effect| EffectGrid {
            effect,
            params: vec![
                ProfiledParam { name: "tau_s", units: "s", continuous: true },
                ProfiledParam { name: "exponentials", units: "1", continuous: false },
            ],
            points: vec![cols(1, vec![600.0, 1.0]), cols(1, vec![1200.0, 1.0]), cols(2, vec![900.0, 2.0])],
            unmet_requirement: None,
        };
        let fit = |point: usize, per_run_sse: Vec<f64>| {
            (point, HeldOut { beta: nalgebra::DVector::zeros(1), per_run_sse })
        };
        // One exponential: 1200 s beats 600 s (28 < 30). Two: 27.2, the lowest; against it
        // the 1200 s point differs by [0.5, 0, 0.3] per run, total 0.8, sd 0.2517, so the
        // standard error of the total 0.2517 x sqrt(3) = 0.436 < 0.8: the lowest stays.
        let sharp =
            [fit(0, vec![10.0, 10.0, 10.0]), fit(1, vec![9.0, 9.5, 9.5]), fit(2, vec![8.5, 9.5, 9.2])];
        let warmup = grid(Effect::WarmupTransient);
        assert_eq!(route_profile(&warmup, &sharp).map(|c| c.0), Some(2));
        // Two exponentials at 27.6 with differences [1.0, -0.5, -0.1] per run: total 0.4, sd
        // 0.7767, standard error 1.345 >= 0.4: within one, so the single exponential.
        let noisy =
            [fit(0, vec![10.0, 10.0, 10.0]), fit(1, vec![9.0, 9.5, 9.5]), fit(2, vec![8.0, 10.0, 9.6])];
        assert_eq!(route_profile(&warmup, &noisy).map(|c| c.0), Some(1));
        // Not of nested complexity: the lowest error, whatever its size.
        assert_eq!(route_profile(&grid(Effect::Hysteresis), &noisy).map(|c| c.0), Some(2));
        assert_eq!(route_profile(&warmup, &[]), None);
    }

    #[test]
    fn the_route_reports_only_a_significant_verdict_whose_claim_holds() {
        assert!(route_significant(GLS_FAMILY_LEVEL, Some((true, true))));
        assert!(route_significant(GLS_FAMILY_LEVEL / 2.0, None));
        assert!(!route_significant(GLS_FAMILY_LEVEL * 1.01, Some((true, true))));
        assert!(!route_significant(0.0, Some((false, true))));
        assert!(!route_significant(0.0, Some((true, false))));
    }

    #[test]
    fn a_rejection_by_the_route_names_the_condition_that_failed() {
        let verdict = |family_p: f64, heldout: Option<(bool, bool)>| GlsVerdict {
            min_p: 1e-9,
            point: 0,
            heldout_gls_fall: None,
            family_p,
            levels: (1e-6, 1e-7),
            heldout,
            own_levels: false,
            split: LevelSplit::None,
        };
        assert_eq!(verdict(f64::NAN, None).why_not(), "not decided (no family-wise p)");
        assert_eq!(verdict(GLS_FAMILY_LEVEL * 1.01, Some((true, true))).why_not(), "not significant");
        assert_eq!(
            verdict(0.0, Some((false, true))).why_not(),
            "significant, but its held-out GLS error does not fall"
        );
        assert_eq!(
            verdict(GLS_FAMILY_LEVEL, Some((true, false))).why_not(),
            "significant, but its GLS coefficient has the unphysical sign"
        );
    }

    #[test]
    fn backward_elimination_drops_the_term_whose_removal_lowers_the_error_most() {
        // The model with all four terms has a LORO SSE of 10; without each: 9.5 (run-level,
        // fails), 12 (needed), 9.0 (route-only), 9.8 (run-level, fails).
        let without = [9.5, 12.0, 9.0, 9.8];
        let route_only = [false, false, true, false];
        let mut asked = Vec::new();
        // The route still accepts the third: the first goes, the lowest of the failing rest.
        let kept = weakest_failing(10.0, &without, &route_only, |i| {
            asked.push(i);
            true
        });
        assert_eq!(kept, Some(0));
        // Only a route-only term is put to the route.
        assert_eq!(asked, [2]);
        // The route no longer accepts it: its removal lowers the error most, it goes first.
        assert_eq!(weakest_failing(10.0, &without, &route_only, |_| false), Some(2));
        // A removal that leaves the error equal counts as not lowering it: the term goes.
        assert_eq!(weakest_failing(10.0, &[10.0, 11.0], &[false, false], |_| true), Some(0));
        // Every removal raises the error: nothing goes, and the route is not asked.
        assert_eq!(weakest_failing(10.0, &[10.5, 11.0], &[true, false], |_| panic!("asked")), None);
    }

    /// Backward elimination on prepared runs (6 runs of 2 h at 1 Hz, recorded gyro white
    /// noise, 20 s short means): `useful` is the data's short means plus a third of their noise
    /// again; `useless` is `useful` plus a column of the same size the data do not hold, and
    /// entered first. With `useful` in the model, `useless` only adds a coefficient fitted to
    /// noise: removing it lowers the LORO error, so it is dropped; `useful` alone then stays
    /// (removing it leaves the constant, far worse). Route-only terms are not asked without a
    /// noise basis (the route cannot judge: kept), so the same pair marked route-only keeps both.
    #[test]
    fn backward_elimination_drops_a_term_a_later_one_made_useless() {
        let runs: Vec<crate::RunSeries> = (0..6)
            .map(|r| {
                let n = 7200;
                let noise = normals(40 + r as u64, n);
                crate::RunSeries {
                    name: format!("run{r}"),
                    time_s: (0..n).map(|i| i as f64).collect(),
                    temp_c: (0..n).map(|i| 10.0 * r as f64 + i as f64 / 600.0).collect(),
                    gyro_dph: noise.iter().map(|e| 0.05 * e).collect(),
                    meta: crate::RunMeta::default(),
                }
            })
            .collect();
        let simulated: Vec<crate::RunSeries> = runs
            .iter()
            .map(|r| crate::RunSeries { gyro_dph: vec![0.0; r.time_s.len()], ..r.clone() })
            .collect();
        let options = DiagnoseOptions::default();
        let prep = crate::prepare::prepare(&simulated, &runs, &options).expect("prepared");
        let ys = targets(&prep);
        let sigma = prep.noise_sigma_dph;
        let column = |values: &dyn Fn(usize, usize) -> f64| -> Vec<DMatrix<f64>> {
            ys.iter().enumerate().map(|(r, y)| DMatrix::from_fn(y.len(), 1, |i, _| values(r, i))).collect()
        };
        let extra: Vec<Vec<f64>> = (0..ys.len()).map(|r| normals(90 + r as u64, ys[r].len())).collect();
        let useful = column(&|r, i| ys[r][i] + sigma / 3.0 * extra[r][i]);
        let useless = column(&|r, i| useful[r][(i, 0)] + sigma * ((i + 7 * r) as f64 / 5.0).sin());
        let term = |effect: Effect, per_run: Vec<DMatrix<f64>>, step: usize, route: bool| ChosenTerm {
            effect,
            point: 0,
            columns: TermColumns {
                theta: Vec::new(),
                coefficients: vec![("c".into(), "deg/h".into())],
                per_run,
                penalty: None,
            },
            concealment_index: 0.0,
            most_confused_with: None,
            route: route.then_some(RouteEvidence {
                point: 0,
                min_p: 1e-9,
                family_p: 1e-4,
                heldout_gls_fall: None,
            }),
            step,
        };
        let ctx = BackwardContext { prep: &prep, grids: &[], ys: &ys, noise_basis: None, options: &options };
        let mut chosen = vec![
            term(Effect::WarmupTransient, useless.clone(), 0, false),
            term(Effect::Hysteresis, useful.clone(), 1, false),
        ];
        let dropped = backward_eliminate(&ctx, &mut chosen).expect("fits");
        assert_eq!(chosen.iter().map(|t| t.effect).collect::<Vec<_>>(), [Effect::Hysteresis]);
        assert_eq!(dropped.len(), 1, "{dropped:?}");
        let d = &dropped[0];
        assert_eq!(
            (d.effect, d.step, d.judged_with.clone()),
            (Effect::WarmupTransient, 0, vec!["hysteresis".to_string()])
        );
        assert!(d.loro_rms_without_dph <= d.loro_rms_with_dph, "{d:?}");
        // The figures are the LORO RMS of the two models, computed here directly.
        let n = prep.n_blocks() as f64;
        let rms = |parts: &[&TermColumns]| (loro_sse(&prep, parts, &ys).unwrap() / n).sqrt();
        let (useless_cols, useful_cols) =
            (&term(Effect::WarmupTransient, useless.clone(), 0, false).columns, &chosen[0].columns);
        assert_eq!(d.loro_rms_with_dph, rms(&[useless_cols, useful_cols]));
        assert_eq!(d.loro_rms_without_dph, rms(&[useful_cols]));
        // Marked route-only, the useless term is kept: without a noise basis the route cannot judge.
        let mut chosen =
            vec![term(Effect::WarmupTransient, useless, 0, true), term(Effect::Hysteresis, useful, 1, false)];
        assert!(backward_eliminate(&ctx, &mut chosen).expect("fits").is_empty());
        assert_eq!(chosen.len(), 2);
    }

    #[test]
    fn encompassing_p_finds_the_term_in_the_data() {
        // 6 runs of 180 short means of 20 s, white noise of SD 0.01 per short mean (level
        // 2e-3 per second), an intercept per run. The data hold 0.004 x a (a = sin of the
        // short-mean index / 9, offset by run); the rival b = a + c with c = cos(i / 4),
        // R^2(a, b) about 0.5. a's Wald p with b in the model: its statistic is about
        // (0.004 x |a perp b| / 0.01)^2 with a perp b about (a - c) / 2, |a perp b|^2 about
        // 45 per run, 270 in all: a statistic near 43, p about 1e-10 (1.6e-12 here). (The size is small
        // enough that the model with b alone still passes the innovation check.)
        // b's with a in: c alone, absent from the data: p not small (here > 0.01).
        let (runs, blocks) = (6, 180);
        let basis = short_mean_basis(runs, blocks);
        let col = |f: &dyn Fn(usize, usize) -> f64| -> Vec<DMatrix<f64>> {
            (0..runs).map(|r| DMatrix::from_fn(blocks, 1, |i, _| f(r, i))).collect()
        };
        let a = col(&|r, i| ((i + 17 * r) as f64 / 9.0).sin());
        let b = col(&|r, i| ((i + 17 * r) as f64 / 9.0).sin() + (i as f64 / 4.0).cos());
        let base = col(&|_, _| 1.0);
        let ys: Vec<Vec<f64>> = (0..runs)
            .map(|r| {
                let e = normals(100 + r as u64, blocks);
                (0..blocks).map(|i| 0.004 * a[r][(i, 0)] + 0.01 * e[i]).collect()
            })
            .collect();
        let a_given_b = encompassing_p(&basis, &base, &ys, &a, &b).expect("a given b");
        let b_given_a = encompassing_p(&basis, &base, &ys, &b, &a).expect("b given a");
        assert!(a_given_b < 1e-6, "a given b {a_given_b:.3e}");
        assert!(b_given_a > 0.01, "b given a {b_given_a:.3e}");
        // With b (the runner-up here) as LORO winner, a enters.
        assert!(encompassing_prefers_second(b_given_a, a_given_b));
        // A column inside the model plus the other adds no direction: no p.
        let two_a = col(&|r, i| 2.0 * ((i + 17 * r) as f64 / 9.0).sin());
        assert!(encompassing_p(&basis, &base, &ys, &two_a, &a).is_none());
    }
}
