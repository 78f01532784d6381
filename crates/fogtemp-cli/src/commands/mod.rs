//! The commands: parse arguments into library settings, run, report.

//! One module per command; this one dispatches and holds what several share (ingest
//! options, reading a model, skipped-row warnings).

mod allan;
pub(crate) mod compensate;
mod diagnose;
mod evaluate;
mod export;
mod fit;
mod inspect;
mod simulate;
mod validate;

use std::path::Path;

use anyhow::{bail, Context, Result};
use fogtemp_cal::axis_columns::ShapeNamed;
use fogtemp_cal::ingest::{IngestOptions, IngestReport};
use fogtemp_core::Model;
use serde::Serialize;

use crate::args::{Command, IngestArgs};

/// Runs one command.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Fit(a) => fit::fit(a),
        Command::Compensate(a) => compensate::compensate(a),
        Command::Validate(a) => validate::validate(a),
        Command::Evaluate(a) => evaluate::evaluate(a),
        Command::Inspect(a) => inspect::inspect(a),
        Command::Export(a) => export::export(a),
        Command::Allan(a) => allan::allan(a),
        Command::Simulate(a) => simulate::simulate(a),
        Command::Demo(a) => simulate::demo(a),
        Command::Diagnose(a) => {
            let ingest = ingest_options(&a.ingest)?;
            diagnose::diagnose(a, ingest)
        }
    }
}

fn ingest_options(a: &IngestArgs) -> Result<IngestOptions> {
    let options = a.options()?;
    warn_unit_names(&options.format);
    Ok(options)
}

/// Warns for columns whose names give another unit than the one they are read in
/// (`fogtemp_cal::unit_names`).
fn warn_unit_names(format: &fogtemp_cal::ingest::LogFormat) {
    for note in fogtemp_cal::unit_names::unit_name_notes(format, fogtemp_cal::axis_columns::CLI_OPTIONS) {
        eprintln!("warning: {note}");
    }
}

/// The ingest settings for replaying `model` (read from `path`): the log columns and units it
/// records unless others are named, named columns checked against them (a swapped pair is an
/// error); the notes about named columns or units that differ are printed.
fn ingest_options_for(
    a: &IngestArgs,
    model: &Model<'_>,
    path: &Path,
) -> Result<(IngestOptions, ModelColumns)> {
    let mut ingest = a.options()?;
    let shape_named = fogtemp_cal::axis_columns::ShapeNamed {
        skip_lines: a.skip_lines.is_some(),
        delimiter: a.delimiter.is_some(),
        comment: a.comment.is_some(),
        columns: !a.columns.is_empty(),
    };
    let named = fogtemp_cal::axis_columns::Named {
        gyro_columns: &a.gyro_columns,
        temp_columns: &a.temp_columns,
        gyro_units: a.gyro_unit.is_some() || a.gyro_scale.is_some(),
        temp_units: a.temp_scale.is_some() || a.temp_offset.is_some(),
        time: fogtemp_cal::axis_columns::TimeNamed {
            column: a.time_column.is_some(),
            unit: a.time_unit.is_some(),
            sample_rate: a.sample_rate_hz.is_some(),
            date: a.date_column.is_some(),
        },
        decimal_mark: a.decimal_mark.is_some(),
        shape: shape_named,
    };
    let chosen = fogtemp_cal::axis_columns::choose_for_replay(
        model,
        &path.display().to_string(),
        &mut ingest.format,
        named,
        fogtemp_cal::axis_columns::CLI_OPTIONS,
    )?;
    for note in &chosen.notes {
        eprintln!("note: {note}");
    }
    warn_unit_names(&ingest.format);
    let from_model = chosen.gyro_from_model.then(|| {
        format!(
            "the log was read with the columns {} records (gyro {}; temperature {})",
            path.display(),
            chosen.gyro.join(", "),
            chosen.temp.join(", ")
        )
    });
    // The shape read, when the model gave part of it: said with a log that cannot be read so.
    let read_shape = fogtemp_cal::blob::LogShapeRecord::of_format(&ingest.format);
    let recorded_shape = fogtemp_cal::blob::LogShapeRecord::of(model);
    let shape = (recorded_shape.is_recorded() && shape_named != ShapeNamed::ALL).then(|| ShapeFromModel {
        context: format!(
            "the log was read in this shape, {} giving what was not named: {}; a log shaped otherwise needs \
             --skip-lines, --delimiter, --comment and --columns (--columns '' for a header row)",
            path.display(),
            fogtemp_cal::axis_columns::shape_in_full(&read_shape)
        ),
        // The header's line, or the first data line of a log without one.
        last_shape_line: read_shape.skip_lines + 1 + u64::from(read_shape.column_names.is_empty()),
    });
    let sample_rate = ingest.format.sample_rate_hz.filter(|_| a.sample_rate_hz.is_none()).map(|rate| {
        format!(
            "the sample rate, {rate} Hz, is the one {} records of its fit's logs, which had no time column: \
             for a log with one, name it with --time-column (and --time-unit if not seconds); \
             to read time from the row index at that rate all the same, name --sample-rate-hz",
            path.display()
        )
    });
    Ok((ingest, ModelColumns { columns: from_model, shape, sample_rate, notes: chosen.notes }))
}

/// The shape a log was read in when the model gave part of it, for its errors.
struct ShapeFromModel {
    /// What is said.
    context: String,
    /// The last line whose failure is the shape's (the header, or the first data row without
    /// one): a bad row beyond it is a bad row in a log of that shape.
    last_shape_line: u64,
}

/// Whether the gyro columns and the log's shape were taken from the model, said as the
/// context of a missing column or a log that fails where its shape shows (the log may be
/// named or shaped differently).
struct ModelColumns {
    columns: Option<String>,
    shape: Option<ShapeFromModel>,
    /// Said when the model gave the sample rate and the log has a time column.
    sample_rate: Option<String>,
    /// The notes printed on how the log is read (columns, units, time, shape), for `--json`.
    notes: Vec<String>,
}

impl ModelColumns {
    /// `e`, with the shape's origin when the model gave part of it and the log fails where
    /// its shape shows (a missing column, the header, the first data row, a log ending among
    /// the lines to skip), else with the columns' origin when a column the model records is
    /// missing.
    fn explain(&self, e: fogtemp_cal::CalError) -> anyhow::Error {
        use fogtemp_cal::CalError::{BadRow, LogFormat, MissingColumn};
        let shape_shows = |shape: &ShapeFromModel| match &e {
            MissingColumn { .. } | LogFormat { .. } => true,
            BadRow { row, .. } => row.line <= shape.last_shape_line,
            _ => false,
        };
        if let (Some(origin), LogFormat { problem, .. }) = (&self.sample_rate, &e) {
            if problem.starts_with(fogtemp_cal::ingest::AMBIGUOUS_TIME) {
                return anyhow::Error::new(e).context(origin.clone());
            }
        }
        match (&self.shape, &self.columns, &e) {
            (Some(shape), _, _) if shape_shows(shape) => anyhow::Error::new(e).context(shape.context.clone()),
            (_, Some(origin), MissingColumn { .. }) => anyhow::Error::new(e).context(origin.clone()),
            _ => e.into(),
        }
    }
}

fn read_model(path: &Path) -> Result<Vec<u8>> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read model {}", path.display()))?;
    Model::from_bytes(&bytes).map_err(|e| anyhow::anyhow!("{}: not a valid model: {e}", path.display()))?;
    Ok(bytes)
}

/// Refuses a model whose feature tracker needs more blocks than the firmware's `capacity`
/// (it would fail at boot with `CapacityTooSmall`).
fn check_capacity(path: &Path, blob: &[u8], capacity: usize) -> Result<()> {
    let model =
        Model::from_bytes(blob).map_err(|e| anyhow::anyhow!("{}: not a valid model: {e}", path.display()))?;
    for index in 0..model.axis_count() {
        let axis = model.axis(index).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        capacity_fits(axis.blocks_needed(), capacity)
            .with_context(|| format!("{} axis {index}", path.display()))?;
    }
    Ok(())
}

/// An error saying "capacity" and what to change when `needed` blocks exceed `capacity`.
fn capacity_fits(needed: usize, capacity: usize) -> Result<()> {
    if needed > capacity {
        bail!(
            "the model's feature tracker needs {needed} blocks but the firmware's capacity is {capacity} \
             (--capacity): fit with --blocks {capacity} or fewer, or build the firmware's Compensator with \
             capacity {needed} and pass --capacity {needed}"
        );
    }
    Ok(())
}

/// Warns when a log's times look read in the wrong unit: most steps between rows gaps
/// (milliseconds read as seconds make every 20 ms step a 20 s gap), or rows faster than any
/// logger writes (days read as seconds).
fn warn_of_time_unit(
    path: &Path,
    gaps: &fogtemp_cal::calibrate::TimeGaps,
    ingest: &fogtemp_cal::ingest::IngestReport,
) {
    for note in fogtemp_cal::calibrate::time_unit_notes(path, gaps, ingest, "--time-unit") {
        eprintln!("warning: {note}");
    }
}

/// Warns when the model's axes and the log's gyro columns differ in number: only the
/// first `min` of them are paired (axis k with gyro column k).
fn warn_axis_count(model_path: &Path, model_axes: usize, gyro_columns: usize) {
    let model = model_path.display().to_string();
    if let Some(note) =
        fogtemp_cal::calibrate::axis_count_note(&model, model_axes, gyro_columns, "--gyro-column")
    {
        eprintln!("warning: {note}");
    }
}

/// Tells the technician about skipped rows (nothing is dropped silently).
/// The error for a log with no data row left: only a header, or every row skipped as bad
/// (`--skip-bad-rows`; then the skipped rows are listed first, and the likely cause named).
fn no_rows_error(report: &IngestReport) -> anyhow::Error {
    if let Some(why) = report.only_temperature_rows("--gyro-column") {
        return anyhow::anyhow!(why);
    }
    if report.skipped == 0 {
        return anyhow::anyhow!(
            "{}: no data rows (only a header, or with --columns only skipped and comment lines)",
            report.path.display()
        );
    }
    report_rows_not_read_as_samples(report);
    anyhow::anyhow!(
        "{}: no data rows left: all {} were skipped as bad (listed above); when every row fails alike, \
         the log's shape is not the one given: check --delimiter, --skip-lines (a banner line), \
         --columns and the column options",
        report.path.display(),
        report.skipped
    )
}

/// "1 bad row", "3 bad rows".
fn bad_rows(count: u64) -> String {
    format!("{count} bad row{}", if count == 1 { "" } else { "s" })
}

/// Says what of a log was not read as a sample: temperature-only rows (a note) and skipped
/// bad rows (a warning, with the first ones).
fn report_rows_not_read_as_samples(report: &IngestReport) {
    if let Some(note) = report.temperature_only_note() {
        eprintln!("note: {note}");
    }
    if report.skipped == 0 {
        return;
    }
    eprintln!(
        "warning: {}: {}; first ones:",
        report.path.display(),
        report.skipped_summary("row", "--skip-bad-rows")
    );
    for b in &report.first_skipped {
        eprintln!(
            "  line {} column {} '{}': {} (found '{}')",
            b.line,
            b.column,
            b.column_name,
            b.kind.describe(),
            b.found
        );
    }
}

/// Prints a library document as the one JSON document on stdout: through a
/// `serde_json::Value`, so the keys come out sorted and NaN or infinite numbers as `null`.
/// `n` and the noun in its number: "1 axis", "2 axes".
fn counted(n: impl Into<u64>, one: &str, many: &str) -> String {
    let n = n.into();
    format!("{n} {}", if n == 1 { one } else { many })
}

fn print_json(doc: &impl Serialize) -> Result<()> {
    println!("{}", serde_json::to_string_pretty(&serde_json::to_value(doc)?)?);
    Ok(())
}

/// A value as the JSON text of it (numbers as JSON prints them: `100.0`, `null` for NaN),
/// for the text outputs that have always shown them so.
fn json_text(value: &impl Serialize) -> String {
    serde_json::to_string(value).unwrap_or_default()
}
