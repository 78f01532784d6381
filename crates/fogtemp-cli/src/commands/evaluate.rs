//! `evaluate`: the model's value at given (T, dT/dt) points, as CSV.

use std::io::Write;

use anyhow::{bail, Context, Result};
use fogtemp_cal::ingest::{DecimalMark, Delimiter};
use fogtemp_core::{Flags, Model, WalkHint};

use super::read_model;
use crate::args::EvaluateArgs;
use crate::output::{check_output_file, refuse_overwriting_inputs, write_atomic};

pub fn evaluate(a: EvaluateArgs) -> Result<()> {
    if let Some(out) = &a.out {
        check_output_file(out)?;
        refuse_overwriting_inputs(out, &[&a.model, &a.points])?;
    }
    let blob = read_model(&a.model)?;
    let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let axis = model.axis(a.axis).map_err(|e| anyhow::anyhow!("{}: {e}", a.model.display()))?;
    let mark = points_decimal_mark(&model, &a);
    // `#` lines are comments and rows of another length are said at their line, as in the
    // logs (review27a 12: the csv crate's "record 2 (line: 3, byte: 29)"). Comments and blank
    // lines are made bare `#` records and passed over (`runs::blank_comment_lines`): the csv
    // crate's own `comment` leaves them out of line numbers.
    let text = std::fs::read(&a.points).with_context(|| format!("cannot open {}", a.points.display()))?;
    let text = fogtemp_cal::runs::blank_comment_lines(&text);
    let delimiter = points_delimiter(&a.points, &text, mark)?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .delimiter(delimiter)
        .flexible(true)
        .has_headers(false)
        .from_reader(text.as_slice());
    let mut records = fogtemp_cal::runs::records_without_comments(&mut reader);
    let header = match records.next() {
        Some(header) => header.with_context(|| format!("{}: cannot read the header", a.points.display()))?,
        None => csv::StringRecord::new(),
    };
    let col = |name: &str| {
        header.iter().position(|h| h == name).with_context(|| {
            format!(
                "{}: no column named '{name}' (the header has: {})",
                a.points.display(),
                header.iter().collect::<Vec<_>>().join(", ")
            )
        })
    };
    if header.iter().all(str::is_empty) {
        bail!(
            "{}: empty file: a header temp_c,rate_c_per_min and one point a row are needed",
            a.points.display()
        );
    }
    let (ti, ri) = (col("temp_c")?, col("rate_c_per_min")?);
    let mut rows = Vec::new();
    for (k, rec) in records.enumerate() {
        let rec = rec.with_context(|| format!("{}: malformed CSV", a.points.display()))?;
        let line = rec.position().map_or(k as u64 + 2, |p| p.line());
        if rec.len() > header.len() {
            bail!(
                "{}:{line}: {} fields where the header names {} (a decimal comma with comma delimiters? quote the cell, or use --decimal-mark comma with semicolons)",
                a.points.display(),
                rec.len(),
                header.len()
            );
        }
        let cell = |i: usize, name: &str| -> Result<f64> {
            let Some(text) = rec.get(i) else {
                bail!(
                    "{}:{line}:{}: column '{name}': fewer fields than the header ({} of {})",
                    a.points.display(),
                    i + 1,
                    rec.len(),
                    header.len()
                );
            };
            let v: f64 = number(text, mark).ok_or_else(|| {
                anyhow::anyhow!(
                    "{}:{line}:{}: column '{name}': not a number (found '{text}'){}",
                    a.points.display(),
                    i + 1,
                    decimal_hint(text, mark, a.decimal_mark.is_some())
                )
            })?;
            if !v.is_finite() {
                bail!(
                    "{}:{line}:{}: column '{name}': NaN or infinite (found '{text}')",
                    a.points.display(),
                    i + 1
                );
            }
            Ok(v)
        };
        let temp_c = cell(ti, "temp_c")?;
        let physical =
            f64::from(fogtemp_core::MIN_PHYSICAL_TEMP_C)..=f64::from(fogtemp_core::MAX_PHYSICAL_TEMP_C);
        if !physical.contains(&temp_c) {
            bail!(
                "{}:{line}:{}: column 'temp_c': not a temperature a sensor reads (below -273.15 C or above 1000 C; found {temp_c})",
                a.points.display(),
                ti + 1
            );
        }
        rows.push((temp_c, cell(ri, "rate_c_per_min")?));
    }
    let mut hint = WalkHint::default();
    let mut lines = Vec::with_capacity(rows.len());
    for (t, r) in rows {
        let e = axis.evaluate(t as f32, r as f32, &mut hint).map_err(|e| anyhow::anyhow!("{e}"))?;
        let flags = if e.outside_hull { Flags::OUTSIDE_HULL.0 } else { 0 };
        // Debug formatting: the shortest text that reads back, with an exponent for 1e30.
        lines.push(format!("{t:?},{r:?},{:?},{flags}", e.value_dph));
    }
    let write = |w: &mut dyn Write| -> Result<()> {
        writeln!(w, "temp_c,rate_c_per_min,value_dph,flags")?;
        for l in &lines {
            writeln!(w, "{l}")?;
        }
        Ok(())
    };
    match &a.out {
        Some(path) => write_atomic(path, write),
        None => write(&mut std::io::stdout().lock()),
    }
}

/// A cell's number with the points' decimal mark (with a comma, a cell holding a point is
/// not a number: there it would be a thousands separator).
fn number(text: &str, mark: DecimalMark) -> Option<f64> {
    match mark {
        DecimalMark::Point => text.parse().ok(),
        DecimalMark::Comma if text.contains('.') => None,
        DecimalMark::Comma => text.replace(',', ".").parse().ok(),
    }
}

/// The points' decimal mark: as `--decimal-mark` names it, else as the model records of its
/// calibration logs (format 6: a lab whose logs write 20,5 writes its grids so too; review13
/// F11), with a note when that is a comma; else a point.
fn points_decimal_mark(model: &Model<'_>, a: &EvaluateArgs) -> DecimalMark {
    if let Some(named) = a.decimal_mark {
        return named;
    }
    let recorded = model.log_reading().is_some_and(|r| r.decimal_comma);
    if !recorded {
        return DecimalMark::Point;
    }
    eprintln!(
        "note: {}: read with a decimal comma, as {} records of its calibration logs (--decimal-mark point to read points)",
        a.points.display(),
        a.model.display()
    );
    DecimalMark::Comma
}

/// What to give when a cell is a number with the other decimal mark (`named`: the mark was
/// given with `--decimal-mark`, not taken from the model).
fn decimal_hint(text: &str, mark: DecimalMark, named: bool) -> &'static str {
    match mark {
        DecimalMark::Point if number(text, DecimalMark::Comma).is_some() => {
            "; the points seem to write numbers with a decimal comma: use --decimal-mark comma"
        }
        DecimalMark::Comma if number(text, DecimalMark::Point).is_some() && named => {
            "; a point in points read with a decimal comma: leave out --decimal-mark comma"
        }
        DecimalMark::Comma if number(text, DecimalMark::Point).is_some() => {
            "; a point in points read with the decimal comma of the model's calibration logs: use --decimal-mark point"
        }
        _ => "",
    }
}

/// The points file's delimiter, from its header as a log's is found (`--delimiter auto`):
/// the most frequent of comma, semicolon and tab (a spreadsheet in a European locale writes
/// `temp_c;rate_c_per_min`).
fn points_delimiter(path: &std::path::Path, text: &[u8], mark: DecimalMark) -> Result<u8> {
    // The header: the first line that is not a comment (comments and blank lines are `#`
    // already: `runs::blank_comment_lines`).
    let (line, header) = text
        .split(|&b| b == b'\n')
        .enumerate()
        .find(|(_, l)| !l.starts_with(b"#"))
        .map_or((1, &[][..]), |(k, l)| (k + 1, l));
    match Delimiter::Auto.resolve_with(header, mark) {
        Delimiter::Byte(b) => Ok(b),
        _ => bail!(
            "{}:{line}: the columns are separated by spaces: separate them with commas, semicolons or tabs",
            path.display()
        ),
    }
}
