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
//!   within one standard error of it (see `design::one_standard_error_choice`);
//! - BIC = `n_eff ln(RSS / n) + k ln(n_eff)`, `n_eff = n / (1 + 2 sum_k w_k rho_k)`, rho_k
//!   the autocorrelations at lags 1..L (L = the Newey-West bandwidth) of the current
//!   model's residual short means within runs, Bartlett weights `w_k = 1 - k/(L+1)`, k =
//!   linear coefficients + the profiled parameters the term depends on at its grid point
//!   (`Effect::inactive_parameters`);
//! - a fold (held-out run) is informative when the term's fitted contribution there, about
//!   its mean over all runs, has an RMS of at least a quarter of the noise of one short
//!   mean; a term is accepted when it is identifiable, lowers the total LORO error,
//!   improves at least `min_fold_fraction` of the informative folds (and at least two; a
//!   flexible term five, the fewest with which a sign test can reach 5 %) or
//!   the runs' Clark-West held-out gains are significantly positive (paired t over all runs
//!   or the exact Wilcoxon signed-rank test, each at 5 % / (2 x number of candidates), see
//!   `rules::clark_west_gains`, `rules::fold_gain_limit` and `rules::signed_rank_p`),
//!   lowers BIC, and is stable across folds (jackknife t of its contribution, see
//!   `rules::stability_t`, above the two-sided Student-t limit with runs - 1 degrees of freedom
//!   at 5 % / number of candidates; for a flexible term with more than two coefficients, a
//!   basis in T whose local coefficients a left-out run moves, every fold must instead
//!   reproduce, on its training runs, at least half of the full-data contribution), and a
//!   coefficient that is a physical share has its sign (`thermal_lag`'s gain is positive,
//!   `Effect::positive_coefficient`). Of the accepted candidates, the one with the fewest coefficients within one
//!   standard error of the lowest LORO error enters (`forward::parsimonious_set`); when two
//!   or more are left, the two of lowest LORO error are compared by encompassing in the
//!   noise model's metric (each one's GLS Wald p with the other in the model; the runner-up
//!   enters only when it adds significantly beyond the winner, at 5 %, and more than the
//!   winner adds beyond it, `forward::encompassing_p`,
//!   `DiagnoseOptions::encompassing_tie_break`); selection stops when no candidate is
//!   accepted or `max_effects` are in.
//! - backward elimination (`DiagnoseOptions::backward_elimination`, on by default): after
//!   forward selection every term is judged again with all the others in the model; a term
//!   whose removal does not raise the LORO error is dropped (a term only the noise-model route
//!   accepted, only when the route, run with the others as the model, no longer accepts it
//!   either), the one whose removal lowers the error most first (`forward::backward_eliminate`).
//! - concealment index: R^2 of the candidate's fitted contribution on the terms already
//!   in the model.
//! - noise-model route (`DiagnoseOptions::noise_model_acceptance`, on by default): at each
//!   step a noise model (white rate noise + bias-instability decades, two levels by REML
//!   with the current model in place, `crate::noise_model`) is fitted to the residual short
//!   means; if it passes its innovation check, a candidate that fails the run-level tests is
//!   still accepted when its GLS Wald test (smallest p over its grid) is significant at
//!   `forward::GLS_FAMILY_LEVEL` family-wise over every open candidate and grid point (the
//!   null distribution of the step's smallest p simulated under the fitted model) and its
//!   held-out claim holds: with `DiagnoseOptions::noise_model_heldout` (default) the
//!   leave-one-run-out GLS error in the model's metric falls with the candidate at its
//!   smallest-p point and the GLS sign is physical (`noise_model::heldout_gls`), else the
//!   run-level LORO error falls and the sign is physical. If the model does not fit, with
//!   `DiagnoseOptions::noise_model_candidate_levels` (on by default since the thirteenth
//!   session) each candidate's levels are refitted with it in the model and the candidate is
//!   tested at them if that model passes the check; otherwise the run-level rules decide alone
//!   (docs/diagnose.md, ninth and thirteenth sessions).
//! - alternatives: a runner-up that passed every rule is listed as an alternative explanation
//!   only when its fall in LORO error is at least half of the selected effect's
//!   (`forward::ALTERNATIVE_SHARE`).
//! - position-label permutation (`DiagnoseOptions::position_permutation`, on by default): a
//!   term that depends on the run's orientation (`Effect::orientation_dependent`) passes the
//!   run-level rules only if its profiled LORO error is also better than under random
//!   relabellings of the runs' positions, at the signed-rank test's level (5 % / (2 x
//!   candidates), `permutation`); with 8 runs in two positions it cannot reach that level
//!   and only the noise-model route can accept such a term (docs/diagnose.md, twelfth session).

mod design;
mod final_fit;
mod forward;
mod permutation;
mod rules;

pub use design::{
    bic, block_indices, build_design, fold_eval, heldout_residuals, pooled_rms, r_squared_runs, residuals,
    targets, Design, FoldEval,
};
pub use final_fit::{distinguishing_decimals, evaluate_final, heldout_bias_stability, FinalOutcome};
pub use forward::{chosen_parts, forward_select, ChosenTerm, DroppedTerm, Selection, GLS_FAMILY_LEVEL};
pub use rules::{
    fold_counts, folds_pass, material_runs, signed_rank_p, stability_limit, MIN_INFORMATIVE_FOLDS,
};
