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
    /// The method the selection chose.
    pub chosen: bool,
    /// Compensated bias stability per held-out run (or group), deg/h, in the order of the
    /// table's `held_out` names.
    pub held_out_dph: Vec<f64>,
}

/// The one-standard-error threshold: the smallest finite `cv_dph` plus its standard error
/// (NaN when no row is finite). Methods at or under it are as good as the best within the
/// noise of the estimate.
pub fn one_se_threshold_dph(rows: &[CrossValidationRow]) -> f64 {
    rows.iter()
        .filter(|r| r.cv_dph.is_finite())
        .min_by(|a, b| a.cv_dph.total_cmp(&b.cv_dph))
        .map_or(f64::NAN, |best| best.cv_dph + if best.se_dph.is_finite() { best.se_dph } else { 0.0 })
}

fn number(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.5}")
    } else {
        "-".into()
    }
}

/// The Markdown table for `axis`: one row per candidate (the chosen one in bold), the
/// per-run columns named by `held_out`, and a line with the best and the threshold.
pub fn cross_validation_markdown(axis: usize, held_out: &[String], rows: &[CrossValidationRow]) -> String {
    let threshold = one_se_threshold_dph(rows);
    let mut md = format!(
        "### Model choice by cross-validation, axis {axis}\n\n\
         Each candidate fitted without one run (or group) and replayed on it through the `Compensator`; \
         the cross-validated bias stability is the RMS over the held-out runs. One-standard-error \
         threshold (best + its standard error): {} deg/h.\n\n\
         | method | CV bias stability, deg/h | standard error, deg/h | within 1 SE of the best | chosen |",
        number(threshold)
    );
    for name in held_out {
        md.push_str(&format!(" held out {name}, deg/h |"));
    }
    md.push_str("\n|---|---|---|---|---|");
    md.push_str(&"---|".repeat(held_out.len()));
    md.push('\n');
    for r in rows {
        let method = if r.chosen { format!("**`{}`**", r.method) } else { format!("`{}`", r.method) };
        let within = if r.cv_dph.is_finite() && r.cv_dph <= threshold { "yes" } else { "no" };
        md.push_str(&format!(
            "| {method} | {} | {} | {within} | {} |",
            number(r.cv_dph),
            number(r.se_dph),
            if r.chosen { "**chosen**" } else { "" }
        ));
        for k in 0..held_out.len() {
            md.push_str(&format!(" {} |", number(r.held_out_dph.get(k).copied().unwrap_or(f64::NAN))));
        }
        md.push('\n');
    }
    md.push('\n');
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: &str, cv: f64, se: f64, chosen: bool) -> CrossValidationRow {
        CrossValidationRow {
            method: method.into(),
            cv_dph: cv,
            se_dph: se,
            chosen,
            held_out_dph: vec![cv, 2.0 * cv],
        }
    }

    #[test]
    fn threshold_is_the_best_plus_its_standard_error() {
        let rows = [
            row("poly", 0.0050, 0.0004, true),
            row("mesh", 0.0047, 0.0005, false),
            row("x", f64::NAN, 1.0, false),
        ];
        assert!((one_se_threshold_dph(&rows) - 0.0052).abs() < 1e-15);
        assert!(one_se_threshold_dph(&[]).is_nan());
    }

    #[test]
    fn table_has_a_row_per_method_the_chosen_in_bold_and_per_run_columns() {
        let rows = [
            row("cubic-t", 0.0090, 0.0010, false),
            row("poly", 0.0050, 0.0004, true),
            row("mesh", 0.0047, 0.0005, false),
        ];
        let md = cross_validation_markdown(0, &["a".into(), "b".into()], &rows);
        assert!(md.contains("threshold (best + its standard error): 0.00520 deg/h"), "{md}");
        assert!(md.contains("| `cubic-t` | 0.00900 | 0.00100 | no |  | 0.00900 | 0.01800 |"), "{md}");
        assert!(
            md.contains("| **`poly`** | 0.00500 | 0.00040 | yes | **chosen** | 0.00500 | 0.01000 |"),
            "{md}"
        );
        assert!(md.contains("| `mesh` | 0.00470 | 0.00050 | yes |  | 0.00470 | 0.00940 |"), "{md}");
        assert!(md.contains("| held out a, deg/h | held out b, deg/h |"));
        assert!(md.contains("|---|---|---|---|---|---|---|\n"));
    }
}
