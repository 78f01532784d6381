//! The cross-validation table of the fit report: every candidate method's cross-validated
//! bias stability with its standard error and per held-out run, the best, the one-standard-
//! error threshold and the method chosen. The input is a small row type of its own, so the
//! table does not depend on how the selection is computed; `fit` fills it from its
//! selection result and appends the Markdown to the report's summary.

/// One candidate method of one axis.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CrossValidationRow {
    /// Method name (`poly`, `mesh`, `hybrid`, `cubic-t`).
    pub method: String,
    /// Cross-validated bias stability (RMS over held-out runs), deg/h.
    pub cv_dph: f64,
    /// Its standard error, deg/h.
    pub se_dph: f64,
    /// Its excess on the best candidate and that excess's paired standard error, on the
    /// scale the one-standard-error rule uses (deg/h, or the log ratio with
    /// `fit --cv-rule-scale log`): within one standard error when the excess is at most it.
    pub excess: (f64, f64),
    /// The method the selection chose.
    pub chosen: bool,
    /// Whether the selection found it within one standard error of the best (the paired
    /// per-fold difference, `fogtemp_cal::selection`): the table shows the rule's own
    /// verdict instead of recomputing it.
    pub within_one_se: bool,
    /// Compensated bias stability per held-out run (or group), deg/h, in the order of the
    /// table's `held_out` names.
    pub held_out_dph: Vec<f64>,
    /// The training-size correction included in `cv_dph` (`fit --cv-correction
    /// training-size`), deg/h; `None` without it (the table then has no such column).
    pub correction_dph: Option<f64>,
}

/// `v` as [`crate::numbers::dph`] (`+` sign with `signed`), "-" when not finite.
fn number_or_dash(v: f64, signed: bool) -> String {
    match (v.is_finite(), signed) {
        (false, _) => "-".into(),
        (true, true) => crate::numbers::dph_signed(v),
        (true, false) => crate::numbers::dph(v),
    }
}

/// The Markdown table for `axis`: one row per candidate (the chosen one in bold), the
/// per-run columns named by `held_out`, and a line with the best and the threshold.
pub fn cross_validation_markdown(axis: usize, held_out: &[String], rows: &[CrossValidationRow]) -> String {
    let mut md = format!(
        "### Model choice by cross-validation, axis {axis}\n\n\
         Each candidate fitted without one run (or group) and replayed on it through the `Compensator`; \
         the cross-validated bias stability is the mean of the folds' held-out bias stability. The \
         simplest candidate within one standard error of the best is chosen: its excess on the best \
         (the mean of the paired per-fold differences) at most that excess's own standard error \
         (of the paired differences, smaller than the columns' standard errors when the folds \
         move together).\n\n\
         | method | CV bias stability, deg/h | standard error, deg/h | excess on the best | paired standard error of the excess | within 1 SE of the best | chosen |"
    );
    let corrected = rows.iter().any(|r| r.correction_dph.is_some());
    if corrected {
        md.push_str(" of which training-size correction, deg/h |");
    }
    for name in held_out {
        md.push_str(&format!(" held out {name}, deg/h |"));
    }
    md.push_str("\n|---|---|---|---|---|---|---|");
    md.push_str(&"---|".repeat(held_out.len() + usize::from(corrected)));
    md.push('\n');
    for r in rows {
        let method = if r.chosen { format!("**`{}`**", r.method) } else { format!("`{}`", r.method) };
        let within = if r.within_one_se { "yes" } else { "no" };
        md.push_str(&format!(
            "| {method} | {} | {} | {} | {} | {within} | {} |",
            number_or_dash(r.cv_dph, false),
            number_or_dash(r.se_dph, false),
            number_or_dash(r.excess.0, false),
            number_or_dash(r.excess.1, false),
            if r.chosen { "**chosen**" } else { "" }
        ));
        if corrected {
            md.push_str(&format!(" {} |", number_or_dash(r.correction_dph.unwrap_or(f64::NAN), true)));
        }
        for k in 0..held_out.len() {
            md.push_str(&format!(
                " {} |",
                number_or_dash(r.held_out_dph.get(k).copied().unwrap_or(f64::NAN), false)
            ));
        }
        md.push('\n');
    }
    md.push('\n');
    md
}

/// The table of a fit's cross-validated choice ([`crate::selection::Selection`]): one column
/// per held-out run in the order the first scored candidate lists them. The fallback (too
/// few runs to cross-validate) is its warning as a sentence.
pub fn selection_markdown(axis: usize, selection: &crate::selection::Selection) -> String {
    if let Some(warning) = &selection.warning {
        return format!("### Model choice, axis {axis}\n\n{warning}.\n\n");
    }
    let held_out: Vec<String> = selection
        .candidates
        .iter()
        .find(|c| c.error.is_none())
        .map(|c| c.runs.iter().map(|r| r.run.clone()).collect())
        .unwrap_or_default();
    let rows: Vec<CrossValidationRow> = selection
        .candidates
        .iter()
        .map(|c| CrossValidationRow {
            method: c.method.name().to_string(),
            cv_dph: c.cv_bias_stability_dph,
            se_dph: c.standard_error_dph,
            excess: match selection.scale {
                crate::selection::RuleScale::DegPerHour => {
                    (c.difference_from_best_dph, c.difference_standard_error_dph)
                }
                crate::selection::RuleScale::Log => (c.log_ratio_to_best, c.log_ratio_standard_error),
            },
            chosen: c.method == selection.method,
            within_one_se: c.within_one_standard_error,
            held_out_dph: held_out
                .iter()
                .map(|name| c.runs.iter().find(|r| &r.run == name).map_or(f64::NAN, |r| r.bias_stability_dph))
                .collect(),
            correction_dph: (selection.correction == crate::cv_correction::CvCorrection::TrainingSize)
                .then_some(c.training_size_correction_dph),
        })
        .collect();
    let mut md = cross_validation_markdown(axis, &held_out, &rows);
    // How the held-out runs were scored and the skipped folds (their runs show "-").
    let note: Vec<String> = selection.scoring_note().lines().map(|l| format!("- {}", l.trim())).collect();
    if !note.is_empty() {
        md.push_str(&format!("{}\n\n", note.join("\n")));
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: &str, cv: f64, se: f64, chosen: bool, within_one_se: bool) -> CrossValidationRow {
        CrossValidationRow {
            method: method.into(),
            cv_dph: cv,
            se_dph: se,
            excess: (cv - 0.0047, 0.0002),
            chosen,
            within_one_se,
            held_out_dph: vec![cv, 2.0 * cv],
            correction_dph: None,
        }
    }

    #[test]
    fn table_has_a_row_per_method_the_chosen_in_bold_and_per_run_columns() {
        let rows = [
            row("cubic-t", 0.0090, 0.0010, false, false),
            row("poly", 0.0050, 0.0004, true, true),
            row("mesh", 0.0047, 0.0005, false, true),
            row("hybrid", f64::NAN, f64::NAN, false, false),
        ];
        let md = cross_validation_markdown(0, &["a".into(), "b".into()], &rows);
        assert!(
            md.contains("| `cubic-t` | 0.00900 | 0.00100 | 0.00430 | 0.00020 | no |  | 0.00900 | 0.01800 |"),
            "{md}"
        );
        assert!(
            md.contains("| **`poly`** | 0.00500 | 0.00040 | 0.00030 | 0.00020 | yes | **chosen** | 0.00500 | 0.01000 |"),
            "{md}"
        );
        assert!(
            md.contains("| `mesh` | 0.00470 | 0.00050 | 0.00000 | 0.00020 | yes |  | 0.00470 | 0.00940 |"),
            "{md}"
        );
        assert!(md.contains("| `hybrid` | - | - | - | 0.00020 | no |  | - | - |"), "{md}");
        assert!(md.contains("| held out a, deg/h | held out b, deg/h |"));
        assert!(md.contains("|---|---|---|---|---|---|---|---|---|\n"));
    }

    /// A selection of one scored candidate (`poly`, CV 0.004 deg/h) over held-out runs a-d
    /// (d not scored), scored inside the fold regions, with `correction`.
    fn one_candidate_selection(
        correction: crate::cv_correction::CvCorrection,
        correction_dph: f64,
    ) -> crate::selection::Selection {
        use crate::selection::{
            CandidateScore, CvScheme, CvScoring, Grouping, HeldOutRun, Selection, SkippedFold,
        };
        let run = |name: &str, v: f64| HeldOutRun {
            run: name.into(),
            group: name.into(),
            bias_stability_dph: v,
            whole_run_bias_stability_dph: v,
            windows_scored: if v.is_finite() { 70 } else { 0 },
            windows_outside_region: if v.is_finite() { 2 } else { 72 },
            left_out_bias_stability_dph: v,
            blocked_bias_stability_dph: f64::NAN,
        };
        Selection {
            method: crate::calibrate::Method::Poly,
            best: Some(crate::calibrate::Method::Poly),
            grouping: Grouping::Runs,
            folds: 3,
            scoring: CvScoring::InsideRegion,
            scheme: CvScheme::LeaveOneGroupOut,
            blocks: None,
            skipped_folds: vec![SkippedFold { group: "d".into(), reason: "no windows inside".into() }],
            scale: crate::selection::RuleScale::DegPerHour,
            correction,
            rule: crate::selection::RULE,
            warning: None,
            candidates: vec![CandidateScore {
                method: crate::calibrate::Method::Poly,
                cv_bias_stability_dph: 0.004,
                standard_error_dph: 0.001,
                difference_from_best_dph: 0.0,
                difference_standard_error_dph: 0.0,
                log_ratio_to_best: 0.0,
                log_ratio_standard_error: 0.0,
                within_one_standard_error: true,
                training_size_correction_dph: correction_dph,
                runs: vec![run("a", 0.003), run("b", 0.004), run("c", 0.005), run("d", f64::NAN)],
                error: None,
            }],
        }
    }

    #[test]
    fn the_selection_table_says_how_runs_were_scored_and_which_folds_were_skipped() {
        let selection = one_candidate_selection(crate::cv_correction::CvCorrection::None, f64::NAN);
        let md = selection_markdown(0, &selection);
        assert!(
            md.contains("| 0.00000 | 0.00000 | yes | **chosen** | 0.00300 | 0.00400 | 0.00500 | - |"),
            "{md}"
        );
        assert!(!md.contains("training-size correction"), "{md}");
        assert!(
            md.contains("- scored on the averaging windows inside each fold's training region (3 folds)\n"),
            "{md}"
        );
        assert!(md.contains("- fold 'd' skipped: no windows inside\n"), "{md}");
        assert!(md.contains("- the choice rests on the "), "what a skipped fold means: {md}");
        assert!(md.contains("cross-validation did not test the methods where its runs lie outside"), "{md}");
    }

    #[test]
    fn a_corrected_selection_shows_the_correction_the_cv_column_includes() {
        let selection = one_candidate_selection(crate::cv_correction::CvCorrection::TrainingSize, -0.00012);
        let md = selection_markdown(0, &selection);
        assert!(
            md.contains("| chosen | of which training-size correction, deg/h | held out a, deg/h |"),
            "{md}"
        );
        assert!(md.contains("| **chosen** | -0.00012 | 0.00300 | 0.00400 | 0.00500 | - |"), "{md}");
        assert!(md.contains("|---|---|---|---|---|---|---|---|---|---|---|---|\n"), "{md}");
        assert!(md.contains("- fold scores corrected for the fold models' smaller training set"), "{md}");
    }
}
