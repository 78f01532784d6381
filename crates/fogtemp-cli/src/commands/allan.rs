//! `allan`: overlapping Allan deviation and fitted noise terms of a log.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use anyhow::{Context, Result};
use fogtemp_cal::allan_stream::{allan_of_scanned_log, scan_log, DEFAULT_EXACT_LIMIT};
use fogtemp_cal::ingest::LogFormat;
use fogtemp_core::Flags;

use super::{ingest_options, json_text, print_json, report_rows_not_read_as_samples};
use crate::args::AllanArgs;
use crate::output::RowProgress;

/// The `allan` command.
pub fn allan(a: AllanArgs) -> Result<()> {
    let mut ingest = ingest_options(&a.ingest)?;
    // The Allan deviation reads only time and gyro: a gyro-only log (a rate-table or static
    // noise capture) needs no temperature column, and a temperature cell is not checked.
    ingest.format.temp_columns.clear();
    if a.ingest.gyro_columns.is_empty() {
        if let Some(columns) = compensated_columns(&a.log, &ingest.format) {
            eprintln!(
                "note: {}: compensate's output: reading {} (name --gyro-column raw_dph for the raw gyro)",
                a.log.display(),
                columns.join(", ")
            );
            ingest.format.gyro_columns = columns;
        }
    }
    let gyro_columns = ingest.format.gyro_columns.clone();
    let flag_columns = compensate_flag_columns(&a.log, &ingest.format);
    ingest.format.gyro_columns.extend(flag_columns.iter().cloned());
    // Two passes, in memory that does not grow with the log: the first finds the first
    // compensated row and the median sample period, the second the curves.
    let factor = ingest.format.gyro_unit.dph() * ingest.format.gyro_scale;
    let axes = gyro_columns.len();
    let bar = RowProgress::new(&a.log, "allan 1/2");
    let scan = scan_log(
        &a.log,
        &ingest,
        |row| !warming_up(row.gyros_dph.get(axes..).unwrap_or_default(), factor),
        |b, r| bar.update(b, r),
    )?;
    bar.finish_and_clear();
    report_rows_not_read_as_samples(&scan.report);
    if scan.start_row > 0 {
        eprintln!(
            "note: {}: the first {} rows ({:.1} s) are the compensator's start-up (flag WARMING_UP in {}: its output is the raw gyro, then it steps by the bias): the Allan deviation starts at the first compensated row, as validate's does",
            a.log.display(),
            scan.start_row,
            scan.start_time_s - scan.first_time_s,
            flag_columns.join(", ")
        );
    }
    let bar = RowProgress::new(&a.log, "allan 2/2");
    let doc = allan_of_scanned_log(&a.log, &ingest, &gyro_columns, &scan, DEFAULT_EXACT_LIMIT, |b, r| {
        bar.update(b, r);
    });
    bar.finish_and_clear();
    let doc = doc?.with_context(|| {
        format!(
            "{}: the log needs at least two rows with increasing times for a sample period (and {} samples for an Allan deviation)",
            a.log.display(),
            fogtemp_cal::metrics::ALLAN_MIN_SAMPLES
        )
    })?;
    if a.json {
        return print_json(&doc);
    }
    if doc.gaps > 0 {
        let steps = if doc.gaps == 1 { "step" } else { "steps" };
        eprintln!(
            "note: {}: {} {steps} longer than 1.5x the median sample period: the Allan deviation is computed within the {} stretches between them (no averaging cluster spans a gap), so averaging times stop below the longest stretch{}",
            a.log.display(),
            doc.gaps,
            doc.gaps + 1,
            many_gaps_hint(&doc)
        );
    }
    // A number JSON prints as null (NaN, infinite) shows as `or`.
    let finite_or = |x: f64, or: f64| if x.is_finite() { x } else { or };
    // Six decimals, or scientific notation where they would print a nonzero term as 0.000000
    // (a gyro in deg/s read as deg/h: review23b F4).
    let value = |x: f64| match x {
        x if !x.is_finite() => "unknown".to_string(),
        x if x != 0.0 && x.abs() < 5e-7 => format!("{x:.3e}"),
        x => format!("{x:.6}"),
    };
    for d in &doc.axes {
        if let Some(note) = d.too_short_note() {
            eprintln!("warning: {note}");
        }
        if let Some(note) = d.unresolved_terms_note() {
            eprintln!("note: {note}");
        }
        if let Some(note) = d.b_above_bound_note() {
            eprintln!("note: {note}");
        }
        if let Some(note) = d.outlier_note() {
            eprintln!("warning: {note}");
        }
        // Unknown, not NaN, where the curve is too short (review15 F7).
        println!(
            "axis {} ({}): N = {} deg/sqrt(h), B = {} deg/h (at most {}), K = {} deg/h/sqrt(h)",
            d.axis,
            json_text(&d.column),
            value(d.noise.arw_deg_per_sqrt_h),
            value(d.noise.bias_instability_dph),
            value(d.bias_instability_at_most_dph),
            value(d.noise.rrw_dph_per_sqrt_h)
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

/// What to do when gaps cut a log into many short stretches (over 1 step in 1000): time
/// stamps that jitter about even spacing, or single dropped samples, each split the log, so
/// the curve stopped at seconds in a 2 h log and B and K were fitted to that (review15 F1).
fn many_gaps_hint(doc: &fogtemp_cal::documents::AllanDocument) -> String {
    let samples = doc.axes.first().map_or(0, |d| d.samples);
    if doc.gaps * 1000 <= samples {
        return String::new();
    }
    let last_tau_s = doc.axes.iter().flat_map(|d| d.curve.last()).map(|p| p.tau_s).fold(0.0, f64::max);
    let rate_hz = doc.axes.first().map_or(f64::NAN, |d| 1.0 / d.sample_period_s);
    format!(
        ". That is over 1 step in 1000, and the curve ends at {last_tau_s:.1} s: if the rows are evenly spaced \
         and only their time stamps jitter, time them by row instead (--skip-lines 1 --columns with the header's \
         names and the time column renamed, --sample-rate-hz {rate_hz:.6}); if samples were dropped, N is measured \
         but B and K only over these short stretches"
    )
}

/// The `flags` columns of `compensate`'s output that belong to the gyro columns read
/// (`raw_dph`, `compensated_dph` or `bias_dph` with an axis suffix: `flags` with the same
/// suffix), when `log` is such an output with its header; empty otherwise.
fn compensate_flag_columns(log: &Path, format: &LogFormat) -> Vec<String> {
    if format.skip_lines > 0 || !format.column_names.is_empty() {
        return Vec::new();
    }
    let Some(header) = first_line(log) else { return Vec::new() };
    let names: Vec<&str> = header.trim_start_matches('\u{feff}').trim_end().split(',').collect();
    if names.first() != Some(&"time_s") {
        return Vec::new();
    }
    let mut flags: Vec<String> = format
        .gyro_columns
        .iter()
        .filter_map(|column| {
            let suffix =
                ["raw_dph", "compensated_dph", "bias_dph"].iter().find_map(|p| column.strip_prefix(p))?;
            let flags = format!("flags{suffix}");
            names.contains(&flags.as_str()).then_some(flags)
        })
        .collect();
    flags.dedup();
    flags
}

/// The `compensated_dph` columns of `compensate`'s output (a header starting `time_s` with
/// no `gyro_dph`), for an `allan` given no gyro column (review12 finding 9: the README's
/// `allan` of compensate's output failed on the default `gyro_dph`); `None` otherwise.
fn compensated_columns(log: &Path, format: &LogFormat) -> Option<Vec<String>> {
    if format.skip_lines > 0 || !format.column_names.is_empty() {
        return None;
    }
    let header = first_line(log)?;
    let names: Vec<&str> = header.trim_start_matches('\u{feff}').trim_end().split(',').collect();
    if names.first() != Some(&"time_s") || names.contains(&"gyro_dph") {
        return None;
    }
    let columns: Vec<String> =
        names.iter().filter(|n| n.starts_with("compensated_dph")).map(|n| (*n).to_string()).collect();
    (!columns.is_empty()).then_some(columns)
}

/// The log's first line, if it can be read as text (at most 64 KiB).
fn first_line(log: &Path) -> Option<String> {
    let file = std::fs::File::open(log).ok()?;
    let mut line = String::new();
    BufReader::new(file.take(1 << 16)).read_line(&mut line).ok()?;
    Some(line)
}

/// Whether a row's `flags` (compensate's flag columns, read with the unit factor `factor`)
/// have `WARMING_UP` set in any column (false without flag columns).
fn warming_up(flags: &[f64], factor: f64) -> bool {
    flags.iter().any(|f| {
        let bits = (f / factor).round();
        bits.is_finite() && (bits as u64) & u64::from(Flags::WARMING_UP.0) != 0
    })
}
