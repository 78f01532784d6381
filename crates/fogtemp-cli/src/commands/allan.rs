//! `allan`: overlapping Allan deviation and fitted noise terms of a log.

use anyhow::{Context, Result};
use fogtemp_cal::documents::AllanDocument;

use super::{ingest_options, json_text, print_json, report_skipped};
use crate::args::AllanArgs;
use crate::output::RowProgress;

/// The `allan` command.
pub fn allan(a: AllanArgs) -> Result<()> {
    let mut ingest = ingest_options(&a.ingest)?;
    // The Allan deviation reads only time and gyro: a gyro-only log (a rate-table or static
    // noise capture) needs no temperature column, and a temperature cell is not checked.
    ingest.format.temp_columns.clear();
    let bar = RowProgress::new(&a.log, "allan");
    let series = fogtemp_cal::ingest::read_gyro_series(&a.log, &ingest, |b, r| bar.update(b, r))?;
    bar.finish_and_clear();
    report_skipped(&series.report);
    let doc = AllanDocument::new(&a.log, &ingest.format.gyro_columns, &series.time_s, &series.gyros_dph)
        .with_context(|| format!("{}: the log needs at least two rows", a.log.display()))?;
    if a.json {
        return print_json(&doc);
    }
    if doc.gaps > 0 {
        let steps = if doc.gaps == 1 { "step" } else { "steps" };
        eprintln!(
            "note: {}: {} {steps} longer than 1.5x the median sample period: the Allan deviation is computed within the {} stretches between them (no averaging cluster spans a gap), so averaging times stop below the longest stretch",
            a.log.display(),
            doc.gaps,
            doc.gaps + 1
        );
    }
    // A number JSON prints as null (NaN, infinite) shows as `or`.
    let finite_or = |x: f64, or: f64| if x.is_finite() { x } else { or };
    for d in &doc.axes {
        if let Some(note) = d.too_short_note() {
            eprintln!("warning: {note}");
        }
        println!(
            "axis {} ({}): N = {:.6} deg/sqrt(h), B = {:.6} deg/h, K = {:.6} deg/h/sqrt(h)",
            d.axis,
            json_text(&d.column),
            finite_or(d.noise.arw_deg_per_sqrt_h, f64::NAN),
            finite_or(d.noise.bias_instability_dph, f64::NAN),
            finite_or(d.noise.rrw_dph_per_sqrt_h, f64::NAN)
        );
        for p in &d.curve {
            println!(
                "  tau {:>10.3} s  adev {:.6} deg/h",
                finite_or(p.tau_s, 0.0),
                finite_or(p.adev_dph, 0.0)
            );
        }
    }
    Ok(())
}
