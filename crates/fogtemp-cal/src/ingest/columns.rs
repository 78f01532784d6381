//! The column plan and the row checks: where the values are (from the header) and how they
//! are scaled, the general path's cell parsing, time order, and skipped rows.

use std::path::{Path, PathBuf};

use super::batch::Batch;
use super::parser::Fields;
use super::{
    BadRow, BadRowKind, DecimalMark, Delimiter, IngestOptions, LogFormat, TimeUnit, MAX_REPORTED_BAD_ROWS,
};
use crate::error::CalError;

/// How the error for a log with a time column read at a given sample rate begins (a caller
/// that gave the rate from a model says so).
pub const AMBIGUOUS_TIME: &str = "ambiguous time";

/// `Plan::roles` entry of a field no row value comes from.
pub(super) const SKIP: usize = usize::MAX;

/// Where the values come from (from the header) and how they are scaled.
#[derive(Clone)]
pub(super) struct Plan {
    pub(super) columns: Columns,
    /// Per field up to `min_fields`: the slot in `RowState::values` it is parsed into, or
    /// [`SKIP`].
    pub(super) roles: Vec<usize>,
    /// `None` when time comes from the record index ([`LogFormat::sample_rate_hz`]).
    pub(super) time_slot: Option<usize>,
    pub(super) temp_slots: Vec<usize>,
    pub(super) gyro_slots: Vec<usize>,
    /// How the time column is written: numbers in a unit, date-times or times of day.
    pub(super) time_unit: TimeUnit,
    /// Time of data record `k` is `k / rate` (no time column).
    pub(super) sample_rate_hz: Option<f64>,
    pub(super) gyro_factor: f64,
    pub(super) temp_scale: f64,
    pub(super) temp_offset_c: f64,
    /// The delimiter is one byte that cannot occur in a plain decimal, and the decimal mark
    /// is a point.
    pub(super) fast: bool,
    /// First byte of the comment prefix (the one-pass path leaves such records, and any
    /// starting with a space or tab, to the general path).
    pub(super) comment_first: Option<u8>,
    pub(super) decimal_mark: DecimalMark,
    /// [`super::IngestOptions::keep_impossible_temperatures`].
    pub(super) keep_impossible_temperatures: bool,
    /// Fields are split at runs of spaces ([`Delimiter::Whitespace`]).
    pub(super) spaced: bool,
}

/// Row-level state: header, previous time, skipped rows.
pub(super) struct RowState {
    pub(super) path: PathBuf,
    pub(super) format: LogFormat,
    skip_bad_rows: bool,
    keep_impossible_temperatures: bool,
    pub(super) plan: Option<Plan>,
    /// One-pass path: one value per distinct used field.
    pub(super) values: Vec<f64>,
    temps: Vec<f64>,
    gyros: Vec<f64>,
    /// The previous accepted row's time, a temperature-only row's too.
    pub(super) previous_time: Option<f64>,
    /// The previous row with gyro readings: its time.
    pub(super) previous_sample_time: Option<f64>,
    pub(super) origin: Option<f64>,
    pub(super) skipped: u64,
    pub(super) first_skipped: Vec<BadRow>,
    /// Data records seen (accepted or rejected): the index of the next one.
    pub(super) records: u64,
}

impl RowState {
    pub(super) fn new(path: &Path, options: &IngestOptions) -> Self {
        Self {
            path: path.to_path_buf(),
            format: options.format.clone(),
            skip_bad_rows: options.skip_bad_rows,
            keep_impossible_temperatures: options.keep_impossible_temperatures,
            plan: None,
            values: Vec::new(),
            temps: vec![f64::NAN; options.format.temp_columns.len()],
            gyros: vec![0.0; options.format.gyro_columns.len()],
            previous_time: None,
            previous_sample_time: None,
            origin: None,
            skipped: 0,
            first_skipped: Vec::new(),
            records: 0,
        }
    }

    /// Sets the plan from [`LogFormat::column_names`] (a headerless log); does nothing when
    /// the log has a header row.
    pub(super) fn plan_headerless(&mut self) -> Result<(), CalError> {
        if self.format.column_names.is_empty() || self.plan.is_some() {
            return Ok(());
        }
        let joined: Vec<u8> = self.format.column_names.concat().into_bytes();
        let mut bounds = Vec::new();
        let mut start = 0;
        for name in &self.format.column_names {
            bounds.push((start, start + name.len()));
            start += name.len();
        }
        self.set_plan(Fields { data: &joined, bounds: &bounds }, 0)
    }

    fn set_plan(&mut self, header: Fields<'_>, line: u64) -> Result<(), CalError> {
        let mut plan = make_plan(&self.path, header, &self.format, line)?;
        plan.keep_impossible_temperatures = self.keep_impossible_temperatures;
        self.values = vec![f64::NAN; plan.roles.iter().filter(|&&r| r != SKIP).count()];
        self.plan = Some(plan);
        Ok(())
    }

    /// The state a worker starts a chunk with: the same header, no previous time (the
    /// first row's time is checked when chunks are merged), no skipped rows, and an
    /// origin of zero, so that rows keep their absolute time (`t - 0.0 == t`).
    pub(super) fn for_chunk(&self) -> Self {
        Self {
            path: self.path.clone(),
            format: self.format.clone(),
            skip_bad_rows: self.skip_bad_rows,
            keep_impossible_temperatures: self.keep_impossible_temperatures,
            plan: self.plan.clone(),
            values: self.values.clone(),
            temps: self.temps.clone(),
            gyros: self.gyros.clone(),
            previous_time: None,
            previous_sample_time: None,
            origin: Some(0.0),
            skipped: 0,
            first_skipped: Vec::new(),
            records: 0,
        }
    }

    /// One record by the general path: the header if none yet, else a row (accepted into
    /// `batch`, skipped, or the error).
    pub(super) fn record(
        &mut self,
        fields: Fields<'_>,
        line: u64,
        batch: &mut Batch,
    ) -> Result<(), CalError> {
        let Some(plan) = &self.plan else {
            return self.set_plan(fields, line);
        };
        let index = self.records;
        self.records += 1;
        let parsed = parse_row(fields, plan, line, index, &mut self.temps, &mut self.gyros)
            .map_err(|bad| named_text_row(bad, fields, plan))
            .map(|time| continue_time(plan, time, self.previous_time));
        let sample = !is_temperature_only(&self.gyros);
        let previous = Previous { any: self.previous_time, sample: self.previous_sample_time };
        let parsed = parsed
            .and_then(|time| check_time(time, previous, sample, &plan.columns, line, fields))
            .map_err(|bad| named_nul_bytes(bad, fields, plan));
        match parsed {
            Ok(time) => {
                // The file's time zero is its first sample's (review33c F1: a temperature row
                // before it moved every sample's time); a temperature row before it is not visited.
                let origin =
                    if sample { *self.origin.get_or_insert(time) } else { self.origin.unwrap_or(time) };
                self.previous_time = Some(time);
                if sample {
                    self.previous_sample_time = Some(time);
                }
                batch.lines.push(line);
                batch.values.push(time - origin);
                batch.values.extend_from_slice(&self.temps);
                batch.values.extend_from_slice(&self.gyros);
                Ok(())
            }
            Err(bad) if self.skip_bad_rows => {
                self.skipped += 1;
                if self.first_skipped.len() < MAX_REPORTED_BAD_ROWS {
                    self.first_skipped.push(bad);
                }
                Ok(())
            }
            Err(bad) => Err(CalError::BadRow { path: self.path.clone(), row: Box::new(bad) }),
        }
    }
}

#[derive(Clone)]
pub(super) struct Columns {
    /// `None`: time from the record index.
    time: Option<usize>,
    /// The date of each row, read with the time column as one date-time.
    date: Option<usize>,
    pub(super) temps: Vec<usize>,
    pub(super) gyros: Vec<usize>,
    names: Vec<String>,
    min_fields: usize,
}

impl Columns {
    /// How many fields the header (or `--columns`) names: a record may hold more only when
    /// they are empty.
    pub(super) fn named_fields(&self) -> usize {
        self.names.len()
    }

    /// The fields read: time, date, temperatures and gyros.
    fn read(&self) -> impl Iterator<Item = usize> + '_ {
        self.time.iter().chain(&self.date).chain(&self.temps).chain(&self.gyros).copied()
    }
}

/// The plan from the header (`line`: its line, 0 for names given in [`LogFormat::column_names`]).
pub(super) fn make_plan(path: &Path, header: Fields<'_>, f: &LogFormat, line: u64) -> Result<Plan, CalError> {
    let columns = locate_columns(path, header, f, line)?;
    let mut roles = vec![SKIP; columns.min_fields];
    let mut slots = 0;
    let mut slot_of = |field: usize| {
        if roles[field] == SKIP {
            roles[field] = slots;
            slots += 1;
        }
        roles[field]
    };
    let time_slot = columns.time.map(&mut slot_of);
    let gyro_slots = columns.gyros.iter().map(|&c| slot_of(c)).collect();
    let temp_slots = columns.temps.iter().map(|&c| slot_of(c)).collect();
    Ok(Plan {
        columns,
        roles,
        time_slot,
        temp_slots,
        gyro_slots,
        time_unit: f.time_unit,
        sample_rate_hz: f.sample_rate_hz,
        gyro_factor: f.gyro_unit.dph() * f.gyro_scale,
        temp_scale: f.temp_scale,
        temp_offset_c: f.temp_offset_c,
        // The fast path reads decimal points only.
        fast: f.decimal_mark == DecimalMark::Point
            && !f.time_unit.is_text()
            && matches!(f.delimiter, Delimiter::Byte(b) if !matches!(b, b'0'..=b'9' | b'.' | b'-' | b'"' | b'\r' | b'\n')),
        comment_first: f.comment_prefix().first().copied(),
        decimal_mark: f.decimal_mark,
        keep_impossible_temperatures: false,
        spaced: f.delimiter == Delimiter::Whitespace,
    })
}

/// A header row that is not text (a NUL or other control byte: a binary file, or UTF-16) is
/// refused as such, instead of being listed byte by byte as column names. Invalid UTF-8 alone
/// is not refused: a Latin-1 "deg C" in a column the log does not need is harmless.
fn refuse_binary_header(path: &Path, header: &Fields<'_>, line: u64) -> Result<(), CalError> {
    let binary = |h: &[u8]| h.iter().position(|&b| b < 0x20 && b != b'\t');
    // gzip's magic bytes 1f 8b: say so (review12 finding 7: "not text" sent users in circles).
    if header.get(0).is_some_and(|f| f.starts_with(&[0x1f, 0x8b])) {
        return Err(CalError::LogFormat {
            path: path.to_path_buf(),
            line,
            problem: "the file is gzip-compressed: decompress it first (gunzip, or zcat into a .csv)".into(),
        });
    }
    // A UTF-16 byte-order mark: say so, rather than list "\u{ff}\u{fe}time_s" as a name
    // (review24b S7).
    if let Some(mark) =
        header.get(0).and_then(|f| f.get(..2)).filter(|m| *m == [0xff, 0xfe] || *m == [0xfe, 0xff])
    {
        return Err(CalError::LogFormat {
            path: path.to_path_buf(),
            line,
            problem: format!(
                "the file starts with a UTF-16 byte-order mark ({:02X} {:02X}): save it as UTF-8 or ASCII text",
                mark[0], mark[1]
            ),
        });
    }
    for i in 0..header.len() {
        let field = header.get(i).unwrap_or(b"");
        if let Some(at) = binary(field) {
            return Err(CalError::LogFormat {
                path: path.to_path_buf(),
                line,
                problem: format!(
                    "the header row is not text (byte 0x{:02x} in field {}): is this a CSV log? \
                     (a binary file, or text in UTF-16)",
                    field.get(at).copied().unwrap_or(0),
                    i + 1
                ),
            });
        }
    }
    Ok(())
}

/// `; also missing: 'b' (perhaps 'B'), ...`: every named column the header (`names`) lacks
/// besides the one reported, each with the names like it, or empty (review32a F15).
fn also_missing(f: &LogFormat, names: &[String], reported: &str) -> String {
    let read_elsewhere =
        |n: &String| f.gyro_columns.contains(n) || f.temp_columns.contains(n) || *n == f.time_column;
    let time = f.sample_rate_hz.is_none().then_some(&f.time_column);
    let mut missing: Vec<&String> = Vec::new();
    for wanted in time.into_iter().chain(&f.date_column).chain(&f.temp_columns).chain(&f.gyro_columns) {
        if wanted != reported && !names.contains(wanted) && !missing.contains(&wanted) {
            missing.push(wanted);
        }
    }
    let said: Vec<String> = missing
        .into_iter()
        .map(|w| {
            let like: Vec<String> =
                similar_names(w, names).into_iter().filter(|n| !read_elsewhere(n)).collect();
            match crate::error::similar_note(&like).strip_prefix("; ") {
                Some(note) => format!("'{w}' ({note})"),
                None => format!("'{w}'"),
            }
        })
        .collect();
    if said.is_empty() {
        String::new()
    } else {
        format!("; also missing: {}", said.join(", "))
    }
}

/// A header field's text: UTF-8, or else Latin-1 (ISO 8859-1, each byte its own character: a
/// Windows logger's `Temp (\u{b0}C)` writes the degree sign as the single byte 0xB0, which is no
/// UTF-8; read lossily it could not be named, review12 F15). The values are numbers in ASCII
/// either way.
fn header_text(field: &[u8]) -> std::borrow::Cow<'_, str> {
    match std::str::from_utf8(field) {
        Ok(text) => std::borrow::Cow::Borrowed(text),
        Err(_) => std::borrow::Cow::Owned(field.iter().map(|&b| char::from(b)).collect()),
    }
}

fn locate_columns(path: &Path, header: Fields<'_>, f: &LogFormat, line: u64) -> Result<Columns, CalError> {
    refuse_binary_header(path, &header, line)?;
    let names: Vec<String> = (0..header.len())
        .map(|i| {
            let h = header.get(i).unwrap_or(b"");
            header_text(h).trim().trim_start_matches('\u{feff}').to_string()
        })
        .collect();
    // A similar name that another role reads is no suggestion (a 3-axis model's gyro_z
    // missing: gyro_x and gyro_y are the other axes', review12 F16).
    let read_elsewhere =
        |n: &String| f.gyro_columns.contains(n) || f.temp_columns.contains(n) || *n == f.time_column;
    let find_as = |wanted: &str, role: &'static str| {
        let at: Vec<usize> = names.iter().enumerate().filter(|(_, n)| *n == wanted).map(|(i, _)| i).collect();
        match at.as_slice() {
            [] => Err(CalError::MissingColumn {
                path: path.into(),
                column: wanted.to_string(),
                role,
                available: names.join(", ").into(),
                similar: similar_names(wanted, &names).into_iter().filter(|n| !read_elsewhere(n)).collect(),
                also: "".into(),
            }),
            [one] => Ok(*one),
            // Two sensors logged under one name: reading the first without a word moved a
            // calibration by 30 C (review23b F3).
            several => Err(CalError::LogFormat {
                path: path.to_path_buf(),
                line,
                problem: format!(
                    "columns {} are each named '{wanted}' ({role}): which one is meant cannot be told; rename \
                     them, or name the columns in order with --skip-lines 1 --columns (Python skip_lines=, columns=)",
                    column_list(several)
                ),
            }),
        }
    };
    let has_time_column = names.contains(&f.time_column);
    if let (Some(rate), true) = (f.sample_rate_hz, has_time_column) {
        return Err(CalError::LogFormat {
            path: path.to_path_buf(),
            line,
            problem: format!(
                "{AMBIGUOUS_TIME}: the log has a time column '{}' and a sample rate of {rate} Hz is set (named, or recorded by the model); \
                 use one of them",
                f.time_column
            ),
        });
    }
    if let (Some(rate), true, true) = (f.sample_rate_hz, f.sample_rate_from_model, f.column_names.is_empty())
    {
        let unread = |n: &&String| !f.temp_columns.contains(n) && !f.gyro_columns.contains(n);
        if let Some(time_like) = names.iter().filter(unread).find(|n| looks_like_time(n)) {
            return Err(CalError::LogFormat {
                path: path.to_path_buf(),
                line,
                problem: format!(
                    "{AMBIGUOUS_TIME}: the log has a column '{time_like}' that looks like a time, and the sample rate of \
                     {rate} Hz recorded by the model would read time from the row index instead; name the time column, \
                     or name the sample rate to read the row index"
                ),
            });
        }
    }
    let located = (|| {
        let time = match f.sample_rate_hz {
            Some(_) => None,
            None => Some(find_as(&f.time_column, "time")?),
        };
        let date = f.date_column.as_deref().map(|c| find_as(c, "date")).transpose()?;
        let temps =
            f.temp_columns.iter().map(|c| find_as(c, "temperature")).collect::<Result<Vec<_>, _>>()?;
        let gyros = f.gyro_columns.iter().map(|c| find_as(c, "gyro")).collect::<Result<Vec<_>, _>>()?;
        Ok((time, date, temps, gyros))
    })();
    let (time, date, temps, gyros) = match located {
        Err(CalError::MissingColumn { .. }) if line > 0 && looks_like_data(&names, f) => {
            return Err(CalError::LogFormat {
                path: path.to_path_buf(),
                line,
                problem: format!(
                    "this line was read as the header but every cell is a number{} ({}): a log without a \
                     header row needs its column names given, and one without a time column its sample rate",
                    match f.time_unit {
                        TimeUnit::DateTime => " or a date-time",
                        TimeUnit::TimeOfDay => " or a time of day",
                        _ => "",
                    },
                    names.iter().filter(|n| !n.is_empty()).cloned().collect::<Vec<_>>().join(", ")
                ),
            })
        }
        Err(CalError::MissingColumn { path, column, role, available, similar, .. }) => {
            let also = also_missing(f, &names, &column).into();
            return Err(CalError::MissingColumn { path, column, role, available, similar, also });
        }
        other => other?,
    };
    if gyros.is_empty() {
        return Err(CalError::MissingColumn {
            path: path.into(),
            column: "(no gyro column named)".into(),
            role: "gyro",
            available: names.join(", ").into(),
            similar: Vec::new(),
            also: "".into(),
        });
    }
    let read_fields = temps.iter().chain(&gyros).copied().chain(time).chain(date).max().unwrap_or(0) + 1;
    // A headerless log read with `--columns` names every field (more fields with text are a
    // long row), so a row with fewer is a fragment (the tail of a record whose start a serial
    // link lost) even where the fields it lacks are not read: its cells are shifted
    // (review24a F4: a fragment's first cell read as 0 C). A header may name trailing
    // columns a logger leaves off, so there only the fields read are required.
    // Fields split at runs of spaces lose a blank cell, and the cells after it move left, so
    // there every named field is required too (review32a F1).
    let every_field = !f.column_names.is_empty() || f.delimiter == Delimiter::Whitespace;
    let min_fields = if every_field { read_fields.max(names.len()) } else { read_fields };
    Ok(Columns { time, date, temps, gyros, names, min_fields })
}

/// Header names that look like `wanted`: equal once case, units and punctuation are set
/// aside, or starting with its stem (`time_s` -> `time`: "Time [s]", "TIME"; `temp_c` ->
/// `temp`: "Temperature (C)"), compared on lower-case letters and digits only.
fn similar_names(wanted: &str, names: &[String]) -> Vec<String> {
    let plain =
        |s: &str| s.chars().filter(char::is_ascii_alphanumeric).collect::<String>().to_ascii_lowercase();
    let whole = plain(wanted);
    let stem = plain(wanted.split('_').next().unwrap_or(wanted));
    names
        .iter()
        .filter(|n| {
            let name = plain(n);
            !name.is_empty() && (name == whole || (stem.len() >= 3 && name.starts_with(&stem)))
        })
        .cloned()
        .collect()
}

/// A header name that reads as a time: a word such as `time`, `timestamp`, `epoch` or
/// `elapsed` in it (`Time (ms)`, `gps_time`), or `t` or `ts` alone or with a unit of time
/// (`t`, `t_s`), or such a unit alone (`ms`, `seconds`; not `s`). Words are runs of ASCII letters, compared in lower case.
fn looks_like_time(name: &str) -> bool {
    const TIME_WORDS: [&str; 10] = [
        "time",
        "times",
        "timestamp",
        "timestamps",
        "datetime",
        "epoch",
        "elapsed",
        "tstamp",
        "millis",
        "micros",
    ];
    const UNITS: [&str; 8] = ["s", "sec", "secs", "second", "seconds", "ms", "us", "ns"];
    let owned = crate::unit_names::words(name);
    let words: Vec<&str> = owned.iter().map(String::as_str).collect();
    let time_word = words.iter().any(|w| TIME_WORDS.contains(w));
    let alone = match words.as_slice() {
        [one] => matches!(*one, "t" | "ts") || (*one != "s" && UNITS.contains(one)),
        [stem, unit] => matches!(*stem, "t" | "ts") && UNITS.contains(unit),
        _ => false,
    };
    time_word || alone
}

/// Every cell a number (or, in a log read with date-times or times of day, one of those): a data row, not a
/// header.
fn looks_like_data(names: &[String], f: &LogFormat) -> bool {
    let datum = |n: &String| {
        parse_number(n.as_bytes(), f.decimal_mark).is_some()
            || (f.time_unit == TimeUnit::DateTime && super::datetime::parse_datetime(n.as_bytes()).is_some())
            || (f.time_unit == TimeUnit::TimeOfDay
                && super::datetime::parse_time_of_day(n.as_bytes()).is_some())
    };
    // Empty names are the fields a trailing delimiter leaves (review32a F11: a LabVIEW row
    // ending in a tab, read as the header, was listed as names instead).
    let filled: Vec<&String> = names.iter().filter(|n| !n.is_empty()).collect();
    !filled.is_empty() && filled.into_iter().all(datum)
}

/// Longest cell a decimal comma is replaced in (longer ones are not numbers this reader
/// writes or reads: 17 significant digits, a sign, an exponent).
const MAX_NUMBER_LEN: usize = 64;

/// A cell's number (`trimmed`: no surrounding spaces) with the log's decimal mark: with
/// [`DecimalMark::Comma`] the comma is read as a point and a cell holding a point is not
/// a number (it would be a thousands separator there).
fn parse_number(trimmed: &[u8], decimal: DecimalMark) -> Option<f64> {
    match decimal {
        DecimalMark::Point => fast_float2::parse::<f64, _>(trimmed).ok(),
        DecimalMark::Comma => {
            if trimmed.contains(&b'.') || trimmed.len() > MAX_NUMBER_LEN {
                return None;
            }
            let mut text = [0u8; MAX_NUMBER_LEN];
            let text = text.get_mut(..trimmed.len())?;
            for (to, &from) in text.iter_mut().zip(trimmed) {
                *to = if from == b',' { b'.' } else { from };
            }
            fast_float2::parse::<f64, _>(&*text).ok()
        }
    }
}

/// A bad cell's text is cut to this many characters.
const MAX_FOUND_CHARS: usize = 40;

fn bad_row(columns: &Columns, line: u64, field: usize, found: &[u8], kind: BadRowKind) -> BadRow {
    let text = String::from_utf8_lossy(found);
    BadRow {
        line,
        column: field + 1,
        column_name: columns
            .names
            .get(field)
            .cloned()
            .unwrap_or_else(|| format!("(unnamed: the header names {})", columns.names.len())),
        found: text.chars().take(MAX_FOUND_CHARS).collect(),
        kind,
    }
}

/// A cell that is not a number, in a row where no column read holds a number and some hold
/// words, is named [`BadRowKind::TextRow`] (a units row, a repeated header); else `bad` as is.
fn named_text_row(bad: BadRow, fields: Fields<'_>, plan: &Plan) -> BadRow {
    if bad.kind != BadRowKind::NotANumber {
        return bad;
    }
    let c = &plan.columns;
    let cells: Vec<&[u8]> = c
        .time
        .iter()
        .chain(&c.gyros)
        .chain(&c.temps)
        .map(|&k| fields.get(k).unwrap_or(b"").trim_ascii())
        .collect();
    let no_number = cells.iter().all(|t| t.is_empty() || parse_number(t, plan.decimal_mark).is_none());
    let words = cells.iter().filter(|t| t.iter().any(u8::is_ascii_alphabetic)).count();
    if no_number && words >= 2.min(cells.len()) {
        BadRow { kind: BadRowKind::TextRow, ..bad }
    } else {
        bad
    }
}

/// A bad row whose record holds NUL bytes is named [`BadRowKind::NulBytes`] at the first
/// cell that holds one, the NULs shown as `\0` (a file padded with zeros after a power cut
/// reads as a short row or a number with junk behind it otherwise); else `bad` as is.
fn named_nul_bytes(bad: BadRow, fields: Fields<'_>, plan: &Plan) -> BadRow {
    let Some((field, cell)) =
        (0..fields.len()).filter_map(|k| Some((k, fields.get(k)?))).find(|(_, cell)| cell.contains(&0))
    else {
        return bad;
    };
    let mut shown = String::new();
    for c in String::from_utf8_lossy(cell).chars() {
        let piece = if c == '\0' { "\\0".to_string() } else { c.to_string() };
        if shown.chars().count() + piece.chars().count() > MAX_FOUND_CHARS {
            break;
        }
        shown.push_str(&piece);
    }
    BadRow {
        kind: BadRowKind::NulBytes,
        found: shown,
        ..bad_row(&plan.columns, bad.line, field, b"", bad.kind)
    }
}

/// Parses one numeric cell; `Ok(None)` for an empty cell.
fn parse_cell(plan: &Plan, fields: Fields<'_>, field: usize, line: u64) -> Result<Option<f64>, BadRow> {
    let raw = fields.get(field).unwrap_or(b"");
    let trimmed = raw.trim_ascii();
    if trimmed.is_empty() {
        return Ok(None);
    }
    match parse_number(trimmed, plan.decimal_mark) {
        Some(v) if v.is_finite() => Ok(Some(v)),
        Some(_) => Err(bad_row(&plan.columns, line, field, raw, BadRowKind::NonFinite)),
        None if plan.decimal_mark == DecimalMark::Comma && trimmed.contains(&b'.') => {
            Err(bad_row(&plan.columns, line, field, raw, BadRowKind::PointWithDecimalComma))
        }
        None => Err(bad_row(&plan.columns, line, field, raw, BadRowKind::NotANumber)),
    }
}

/// The general path: time (returned, s; from the record `index` when the log has no time
/// column), gyros and temperatures (into the slices), with the first bad cell in the order
/// time, gyros, temperatures.
pub(super) fn parse_row(
    fields: Fields<'_>,
    plan: &Plan,
    line: u64,
    index: u64,
    temps: &mut [f64],
    gyros: &mut [f64],
) -> Result<f64, BadRow> {
    let columns = &plan.columns;
    if fields.len() < columns.min_fields {
        // The first missing field that is read (review24a F8: the error named a column the
        // user does not read), else the first missing one.
        let field = columns.read().filter(|&k| k >= fields.len()).min().unwrap_or(fields.len());
        return Err(bad_row(
            columns,
            line,
            field.min(columns.names.len().saturating_sub(1)),
            b"",
            if plan.spaced { BadRowKind::ShortSpacedRow } else { BadRowKind::ShortRow },
        ));
    }
    if let Some(extra) = (columns.named_fields()..fields.len())
        .find(|&k| !fields.get(k).unwrap_or(b"").trim_ascii().is_empty())
    {
        // The extra fields with text (a trailing delimiter's empty field is none).
        let last_filled =
            (0..fields.len()).rev().find(|&k| !fields.get(k).unwrap_or(b"").trim_ascii().is_empty());
        let extra_filled = last_filled.map_or(0, |k| k + 1).saturating_sub(columns.named_fields());
        if let Some(field) = split_thousands(fields, extra_filled) {
            let separator = if plan.spaced { b' ' } else { b',' };
            let joined =
                [fields.get(field).unwrap_or(b""), fields.get(field + 1).unwrap_or(b"")].join(&separator);
            return Err(bad_row(columns, line, field, &joined, BadRowKind::SplitThousands));
        }
        return Err(bad_row(columns, line, extra, fields.get(extra).unwrap_or(b""), BadRowKind::LongRow));
    }
    let required = |field: usize| -> Result<f64, BadRow> {
        parse_cell(plan, fields, field, line)?
            .ok_or_else(|| bad_row(columns, line, field, b"", BadRowKind::EmptyCell))
    };
    let time = match columns.time {
        Some(field) if plan.time_unit == TimeUnit::DateTime => datetime_cell(plan, fields, field, line)?,
        Some(field) if plan.time_unit == TimeUnit::TimeOfDay => time_of_day_cell(plan, fields, field, line)?,
        Some(field) => plan.time_unit.to_seconds(required(field)?),
        None => time_of_record(index, plan.sample_rate_hz),
    };
    // Every gyro cell empty: a temperature-only row when it holds a temperature (channels
    // logged on separate rows; the reading goes with the next sample, `batch::Consumer`).
    let gyros_empty =
        columns.gyros.iter().all(|&field| fields.get(field).unwrap_or(b"").trim_ascii().is_empty());
    for (slot, &field) in gyros.iter_mut().zip(&columns.gyros) {
        if gyros_empty {
            *slot = f64::NAN;
            continue;
        }
        *slot = required(field)? * plan.gyro_factor;
        if !super::is_representable_rate(*slot) {
            let raw = fields.get(field).unwrap_or(b"");
            return Err(bad_row(columns, line, field, raw, BadRowKind::RateBeyondRange));
        }
    }
    for (slot, &field) in temps.iter_mut().zip(&columns.temps) {
        let reading = match parse_cell(plan, fields, field, line) {
            // 'NaN' or 'inf' written for a reading: kept as one no sensor reads, like -999, where
            // impossible temperatures are kept (an empty cell stays NaN: no reading).
            Err(bad) if bad.kind == BadRowKind::NonFinite && plan.keep_impossible_temperatures => {
                Some(f64::INFINITY)
            }
            other => other?,
        };
        *slot = reading.map_or(f64::NAN, |raw| raw * plan.temp_scale + plan.temp_offset_c);
        if !slot.is_nan() && !super::is_physical(*slot) && !plan.keep_impossible_temperatures {
            let raw = fields.get(field).unwrap_or(b"");
            return Err(bad_row(columns, line, field, raw, BadRowKind::ImpossibleTemperature));
        }
    }
    if gyros_empty && temps.iter().all(|t| t.is_nan()) {
        // Neither a gyro nor a temperature: the empty gyro cell is the error.
        return Err(bad_row(
            columns,
            line,
            columns.gyros.first().copied().unwrap_or(0),
            b"",
            BadRowKind::EmptyCell,
        ));
    }
    Ok(time)
}

/// A row parsed with no gyro reading (every gyro NaN): a temperature-only row.
pub(super) fn is_temperature_only(gyros: &[f64]) -> bool {
    gyros.first().is_some_and(|g| g.is_nan())
}

/// The times a row's time is checked against.
#[derive(Clone, Copy)]
pub(super) struct Previous {
    /// The previous accepted row's, a temperature-only row's too.
    pub(super) any: Option<f64>,
    /// The previous row with gyro readings'.
    pub(super) sample: Option<f64>,
}

/// The first field of a number split at its thousands separators, when the row's `extra`
/// fields can all be such splits: a field of 1-3 digits (with a sign) followed by fields of
/// exactly 3 digits, the last of them with an optional fraction (`1`, `000.5`; `1`, `000`,
/// `000`). A head followed by several groups may have split into fewer of them (`1`, `000`,
/// `250`: a 3-digit integer cell after `1,000`), so `extra` must lie between the heads'
/// count and the groups'.
fn split_thousands(fields: Fields<'_>, extra: usize) -> Option<usize> {
    let cell = |k: usize| fields.get(k).unwrap_or(b"").trim_ascii();
    let is_digits = |t: &[u8]| !t.is_empty() && t.iter().all(u8::is_ascii_digit);
    let head = |t: &[u8]| {
        let t = t.strip_prefix(b"-").or_else(|| t.strip_prefix(b"+")).unwrap_or(t);
        is_digits(t) && t.len() <= 3
    };
    let group = |t: &[u8]| {
        let (whole, fraction) = match t.iter().position(|&b| b == b'.') {
            Some(at) => (&t[..at], Some(&t[at + 1..])),
            None => (t, None),
        };
        whole.len() == 3 && is_digits(whole) && fraction.is_none_or(|f| f.iter().all(u8::is_ascii_digit))
    };
    let (mut first, mut heads, mut groups, mut k) = (None, 0, 0, 0);
    while k < fields.len() {
        let mut next = k + 1;
        if head(cell(k)) {
            // The groups after it, up to one with a fraction.
            while next < fields.len() && group(cell(next)) {
                next += 1;
                if cell(next - 1).contains(&b'.') {
                    break;
                }
            }
            if next > k + 1 {
                first = first.or(Some(k));
                heads += 1;
                groups += next - k - 1;
            }
        }
        k = next;
    }
    first.filter(|_| extra > 0 && (heads..=groups).contains(&extra))
}

/// A date-time time cell, seconds since 1970 UTC; with a date column, its cell `T` the
/// time cell (a bad one is reported at the time column, with both cells' text).
fn datetime_cell(plan: &Plan, fields: Fields<'_>, field: usize, line: u64) -> Result<f64, BadRow> {
    let cell = |f: usize| fields.get(f).unwrap_or(b"").trim_ascii();
    let required = |f: usize| match cell(f) {
        [] => Err(bad_row(&plan.columns, line, f, b"", BadRowKind::EmptyCell)),
        text => Ok(text),
    };
    let time = required(field)?;
    // `date T time` joined on the stack (no allocation per row); a longer pair is no stamp.
    let mut joined = [0u8; 2 * MAX_NUMBER_LEN];
    let stamp: &[u8] = match plan.columns.date {
        Some(date) => {
            let date = required(date)?;
            let len = date.len() + 1 + time.len();
            match joined.get_mut(..len) {
                Some(out) => {
                    out[..date.len()].copy_from_slice(date);
                    out[date.len()] = b'T';
                    out[date.len() + 1..].copy_from_slice(time);
                    out
                }
                None => return Err(bad_row(&plan.columns, line, field, time, BadRowKind::NotADateTime)),
            }
        }
        None => time,
    };
    super::datetime::parse_datetime(stamp)
        .ok_or_else(|| bad_row(&plan.columns, line, field, stamp, BadRowKind::NotADateTime))
}

/// A time-of-day cell, seconds since midnight (the day is added by [`continue_time`]).
fn time_of_day_cell(plan: &Plan, fields: Fields<'_>, field: usize, line: u64) -> Result<f64, BadRow> {
    match fields.get(field).unwrap_or(b"").trim_ascii() {
        [] => Err(bad_row(&plan.columns, line, field, b"", BadRowKind::EmptyCell)),
        text => super::datetime::parse_time_of_day(text)
            .ok_or_else(|| bad_row(&plan.columns, line, field, text, BadRowKind::NotATimeOfDay)),
    }
}

/// A row's time after the previous row's: a time of day read from a time column goes on
/// to the next day when the clock passed midnight ([`super::datetime::continue_clock`]);
/// every other time is as read.
pub(super) fn continue_time(plan: &Plan, time: f64, previous: Option<f64>) -> f64 {
    if plan.time_unit == TimeUnit::TimeOfDay && plan.columns.time.is_some() {
        super::datetime::continue_clock(time, previous)
    } else {
        time
    }
}

/// Time of data record `index` from the sample rate, seconds.
#[inline]
pub(super) fn time_of_record(index: u64, sample_rate_hz: Option<f64>) -> f64 {
    index as f64 / sample_rate_hz.unwrap_or(1.0)
}

/// `time`, or the bad row for a time equal to (`DuplicateTime`) or before (`BackwardTime`)
/// the previous row's; a log without a time column is not checked.
///
/// Times increase strictly, except that a temperature-only row may share its time with
/// the row before it and the next sample may share it with the temperature-only row (a
/// logger that writes each channel's row with one time stamp): two samples never share one.
pub(super) fn check_time(
    time: f64,
    previous: Previous,
    sample: bool,
    columns: &Columns,
    line: u64,
    fields: Fields<'_>,
) -> Result<f64, BadRow> {
    let Some(field) = columns.time else { return Ok(time) };
    let found = || fields.get(field).unwrap_or(b"");
    let shared = |p: Option<f64>| p.is_some_and(|p| time == p);
    match previous.any {
        Some(p) if time < p => Err(bad_row(columns, line, field, found(), BadRowKind::BackwardTime)),
        _ if sample && shared(previous.sample) => {
            Err(bad_row(columns, line, field, found(), BadRowKind::DuplicateTime))
        }
        _ => Ok(time),
    }
}

/// 1-based column numbers as prose: "2 and 4", "2, 4 and 6".
fn column_list(indices: &[usize]) -> String {
    let numbers: Vec<String> = indices.iter().map(|i| (i + 1).to_string()).collect();
    match numbers.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        _ => numbers.join(""),
    }
}

#[cfg(test)]
mod tests {
    use super::{looks_like_time, similar_names};
    use crate::ingest::test_support::*;
    use crate::ingest::*;

    #[test]
    fn time_like_names() {
        for time in [
            "t",
            "T [s]",
            "ts",
            "time",
            "Time (ms)",
            "TIMESTAMP",
            "gps_time",
            "t_ms",
            "elapsed",
            "epoch_s",
            "seconds",
            "us",
        ] {
            assert!(looks_like_time(time), "{time}");
        }
        for other in
            ["s", "temp", "tempo", "temp_c", "gyro_dph", "t_case", "tc", "status", "mag1x [T]", "", "2"]
        {
            assert!(!looks_like_time(other), "{other}");
        }
    }

    #[test]
    fn not_a_number_names_line_column_and_text() {
        let b = bad(&format!("{HEADER}0.0,20,1\n0.1,20,1\n0.2,20,abc\n"));
        expect(&b, 4, 3, "gyro_dph", "abc", BadRowKind::NotANumber);
        let b = bad(&format!("{HEADER}0.0,2x0,1\n"));
        expect(&b, 2, 2, "temp_c", "2x0", BadRowKind::NotANumber);
        let b = bad(&format!("{HEADER}0.0,20,1\n-,20,1\n"));
        expect(&b, 3, 1, "time_s", "-", BadRowKind::NotANumber);
    }

    #[test]
    fn rows_of_text_are_named_as_units_rows_or_repeated_headers() {
        // A units row under the header, and a header repeated where two logs were joined.
        let b = bad(&format!("{HEADER}s,degC,deg/h\n0.0,20,1\n"));
        expect(&b, 2, 1, "time_s", "s", BadRowKind::TextRow);
        assert!(b.kind.describe().contains("a units row under the header"));
        let b = bad(&format!("{HEADER}0.0,20,1\n1.0,20,1\n{HEADER}2.0,20,1\n"));
        expect(&b, 4, 1, "time_s", "time_s", BadRowKind::TextRow);
        // A units row with an empty temperature unit is text too; one word among numbers,
        // or garbage without letters, is not.
        expect(&bad(&format!("{HEADER}s,,deg/h\n")), 2, 1, "time_s", "s", BadRowKind::TextRow);
        expect(&bad(&format!("{HEADER}0.0,20,abc\n")), 2, 3, "gyro_dph", "abc", BadRowKind::NotANumber);
        expect(&bad(&format!("{HEADER}x,20,1\n")), 2, 1, "time_s", "x", BadRowKind::NotANumber);
        expect(&bad(&format!("{HEADER}-,-,-\n")), 2, 1, "time_s", "-", BadRowKind::NotANumber);
        // Skipped like any bad row, and listed with its reason.
        let (seen, result) =
            run(format!("{HEADER}s,degC,deg/h\n0.0,20,1\n1.0,20,2\n").as_bytes(), &skipping());
        assert_eq!(seen.len(), 2);
        let report = result.expect("read");
        assert_eq!((report.skipped, report.first_skipped[0].kind), (1, BadRowKind::TextRow));
    }

    #[test]
    fn non_finite_cells_are_rejected() {
        for text in ["nan", "NaN", "inf", "-inf", "infinity", "1e400"] {
            let b = bad(&format!("{HEADER}0.0,20,1\n0.1,20,{text}\n"));
            expect(&b, 3, 3, "gyro_dph", text, BadRowKind::NonFinite);
        }
        let b = bad(&format!("{HEADER}0.0,nan,1\n"));
        expect(&b, 2, 2, "temp_c", "nan", BadRowKind::NonFinite);
    }

    #[test]
    fn short_row_names_the_first_missing_column() {
        let b = bad(&format!("{HEADER}0.0,20,1\n0.1,20\n"));
        expect(&b, 3, 3, "gyro_dph", "", BadRowKind::ShortRow);
        let b = bad(&format!("{HEADER}0.0\n"));
        expect(&b, 2, 2, "temp_c", "", BadRowKind::ShortRow);
    }

    #[test]
    fn duplicate_and_backward_time() {
        let b = bad(&format!("{HEADER}0.0,20,1\n0.1,20,1\n0.1,20,1\n"));
        expect(&b, 4, 1, "time_s", "0.1", BadRowKind::DuplicateTime);
        let b = bad(&format!("{HEADER}0.0,20,1\n0.2,20,1\n0.100,20,1\n"));
        expect(&b, 4, 1, "time_s", "0.100", BadRowKind::BackwardTime);
        // Same value in another spelling is still a duplicate.
        let b = bad(&format!("{HEADER}1.5,20,1\n1.50,20,1\n"));
        expect(&b, 3, 1, "time_s", "1.50", BadRowKind::DuplicateTime);
    }

    #[test]
    fn empty_required_cells() {
        let b = bad(&format!("{HEADER}0.0,20,1\n,20,1\n"));
        expect(&b, 3, 1, "time_s", "", BadRowKind::EmptyCell);
        // A row with a temperature and no gyro is a temperature-only row (shape_tests); with
        // neither, the empty gyro cell is the error.
        let b = bad(&format!("{HEADER}0.0,20,1\n0.1,,\n"));
        expect(&b, 3, 3, "gyro_dph", "", BadRowKind::EmptyCell);
        let b = bad(&format!("{HEADER}0.0,  ,  \n"));
        expect(&b, 2, 3, "gyro_dph", "", BadRowKind::EmptyCell);
    }

    #[test]
    fn first_bad_cell_in_order_time_gyro_temperature() {
        // (A row of words only is named a text row; the cell reported is still the first.)
        let b = bad(&format!("{HEADER}x,y,z\n"));
        expect(&b, 2, 1, "time_s", "x", BadRowKind::TextRow);
        let b = bad(&format!("{HEADER}0,y,z\n"));
        expect(&b, 2, 3, "gyro_dph", "z", BadRowKind::NotANumber);
    }

    #[test]
    fn error_message_names_file_line_column() {
        let (_, result) = run(format!("{HEADER}0,20,1\n1,20,x\n").as_bytes(), &default_options());
        let message = result.unwrap_err().to_string();
        assert!(message.starts_with("log.csv:3:3: column 'gyro_dph': not a number (found 'x')"), "{message}");
    }

    #[test]
    fn skip_bad_rows_counts_and_lists_the_first_twenty() {
        let mut data = String::from(HEADER);
        let mut t = 0;
        for i in 0..30 {
            data.push_str(&format!("{t},20,1\n"));
            t += 1;
            data.push_str(&format!("{t},20,bad{i}\n"));
        }
        let (seen, result) = run(data.as_bytes(), &skipping());
        let report = result.unwrap();
        assert_eq!((seen.len(), report.rows, report.skipped), (30, 30, 30));
        assert_eq!(report.first_skipped.len(), MAX_REPORTED_BAD_ROWS);
        assert_eq!(report.first_skipped[0].line, 3);
        assert_eq!(report.first_skipped[19].line, 41);
        assert_eq!(report.first_skipped[19].found, "bad19");
        // A skipped row does not advance the previous time.
        let data = format!("{HEADER}0,20,1\n5,20,x\n1,20,1\n1,20,1\n");
        let (seen, result) = run(data.as_bytes(), &skipping());
        let report = result.unwrap();
        assert_eq!(seen.iter().map(|s| s.line).collect::<Vec<_>>(), vec![2, 4]);
        assert_eq!(report.first_skipped[1].kind, BadRowKind::DuplicateTime);
        assert_eq!(report.first_skipped[1].line, 5);
    }

    #[test]
    fn empty_temperature_cells_are_no_reading() {
        let options = IngestOptions {
            format: LogFormat { temp_columns: vec!["t1".into(), "t2".into()], ..LogFormat::default() },
            ..IngestOptions::default()
        };
        let seen = rows("time_s,t1,t2,gyro_dph\n0,,20,1\n1,21,,1\n2,,,1\n3, ,22,1\n", &options);
        let v = values(&seen);
        let nan = |x: f64| x.is_nan();
        assert!(nan(v[0].2[0]) && v[0].2[1] == 20.0);
        assert!(v[1].2[0] == 21.0 && nan(v[1].2[1]));
        assert!(nan(v[2].2[0]) && nan(v[2].2[1]));
        assert!(nan(v[3].2[0]) && v[3].2[1] == 22.0);
    }

    #[test]
    fn units_and_scales() {
        let options = IngestOptions {
            format: LogFormat {
                time_column: "t_ms".into(),
                time_unit: TimeUnit::Milliseconds,
                temp_columns: vec!["raw".into()],
                temp_scale: 0.0625,
                temp_offset_c: -10.0,
                gyro_columns: vec!["gx".into(), "gy".into()],
                gyro_unit: RateUnit::RadPerSecond,
                gyro_scale: 0.5,
                delimiter: Delimiter::Byte(b';'),
                ..LogFormat::default()
            },
            ..IngestOptions::default()
        };
        let seen = rows("gx;t_ms;raw;gy\n1;1000;400;-2\n0.5;1001.5;416;0\n", &options);
        let v = values(&seen);
        let rad = RateUnit::RadPerSecond.dph() * 0.5;
        assert_eq!(v[0].1, 0.0);
        assert_eq!(v[1].1, 1001.5 * 1e-3 - 1000.0 * 1e-3);
        assert_eq!(v[0].2, vec![400.0 * 0.0625 - 10.0]);
        assert_eq!(v[1].2, vec![416.0 * 0.0625 - 10.0]);
        assert_eq!(v[0].3, vec![rad, -2.0 * rad]);
        assert_eq!(v[1].3, vec![0.5 * rad, 0.0]);
        let options = IngestOptions {
            format: LogFormat {
                gyro_unit: RateUnit::DegPerSecond,
                time_unit: TimeUnit::Microseconds,
                ..LogFormat::default()
            },
            ..IngestOptions::default()
        };
        let v = values(&rows(&format!("{HEADER}1000000,20,1\n1500000,20,-0.5\n"), &options));
        assert_eq!((v[1].1, v[0].3[0], v[1].3[0]), (0.5, 3600.0, -1800.0));
    }

    #[test]
    fn extra_columns_and_shared_temperature_column() {
        let options = IngestOptions {
            format: LogFormat {
                temp_columns: vec!["temp_c".into(), "temp_c".into()],
                gyro_columns: vec!["g0".into(), "g1".into()],
                ..LogFormat::default()
            },
            ..IngestOptions::default()
        };
        // (A field beyond the header's is a long row: `records_run_together_are_a_long_row...`.)
        let data = "g1,id,time_s,temp_c,g0,comment\n2,a,0,20,1,\"x,y\"\n4,b,1,21,3,ok\n";
        let v = values(&rows(data, &options));
        assert_eq!(v[0].2, vec![20.0, 20.0]);
        assert_eq!(v[0].3, vec![1.0, 2.0]);
        assert_eq!(v[1].3, vec![3.0, 4.0]);
        // A short row reports the first column it lacks, even one the model does not use.
        let b = match run(b"time_s,x,temp_c,gyro_dph\n0,1\n", &default_options()).1 {
            Err(CalError::BadRow { row, .. }) => *row,
            other => panic!("{}", summary(&other)),
        };
        expect(&b, 2, 3, "temp_c", "", BadRowKind::ShortRow);
    }

    #[test]
    fn a_missing_column_names_the_header_names_that_look_like_it() {
        let names: Vec<String> = ["Time [s]", "Temperature (C)", "GyroX (deg/h)", "GYRO_DPH", "id", "tem"]
            .map(String::from)
            .to_vec();
        assert_eq!(similar_names("time_s", &names), ["Time [s]"]);
        assert_eq!(similar_names("temp_c", &names), ["Temperature (C)"]);
        assert_eq!(similar_names("gyro_dph", &names), ["GyroX (deg/h)", "GYRO_DPH"]);
        assert!(similar_names("id_x", &names).is_empty(), "a stem under 3 characters matches nothing");
        assert!(similar_names("pressure", &names).is_empty());
        let (_, result) = run(b"Time_s,Temp_C,Gyro_dph\n0,20,1\n", &default_options());
        let e = result.unwrap_err();
        assert!(
            e.to_string().ends_with(
                "no column named 'time_s' (the header has: Time_s, Temp_C, Gyro_dph); perhaps 'Time_s'; also \
                 missing: 'temp_c' (perhaps 'Temp_C'), 'gyro_dph' (perhaps 'Gyro_dph')"
            ),
            "{e}"
        );
        // A column another axis reads is no suggestion: a 3-axis read of a log without gyro_z.
        let three = IngestOptions {
            format: LogFormat {
                gyro_columns: vec!["gyro_x".into(), "gyro_y".into(), "gyro_z".into()],
                ..LogFormat::default()
            },
            ..IngestOptions::default()
        };
        let (_, result) = run(b"time_s,temp_c,gyro_x,gyro_y\n0,20,1,2\n", &three);
        match result {
            Err(CalError::MissingColumn { column, similar, .. }) => {
                assert_eq!((column.as_str(), similar), ("gyro_z", Vec::<String>::new()));
            }
            other => panic!("{}", summary(&other)),
        }
    }

    #[test]
    fn missing_columns_and_empty_files() {
        let (_, result) = run(b"time_s,temp_c\n0,20\n", &default_options());
        assert!(
            matches!(&result, Err(CalError::MissingColumn { column, available, .. })
                if column == "gyro_dph" && &**available == "time_s, temp_c"),
            "{}",
            summary(&result)
        );
        for empty in ["", "\n\n", "\u{feff}"] {
            let (seen, result) = run(empty.as_bytes(), &default_options());
            assert!(seen.is_empty() && result.is_err(), "{empty:?}: {}", summary(&result));
        }
        // A header alone is a log without rows.
        let report = run(HEADER.trim_end().as_bytes(), &default_options()).1.unwrap();
        assert_eq!(report.rows, 0);
    }

    /// Two columns under a name the reader needs are refused, naming both (review23b F3: the
    /// first was read without a word); a duplicated name no one reads is no matter.
    #[test]
    fn a_needed_name_on_two_columns_is_refused() {
        let (seen, result) = run(b"time_s,temp_c,gyro_dph,temp_c\n0,50,1,20\n", &default_options());
        let message = summary(&result);
        assert!(seen.is_empty(), "{message}");
        assert!(
            message.contains("columns 2 and 4 are each named 'temp_c' (temperature)")
                && message.contains("--columns"),
            "{message}"
        );
        let report = run(b"time_s,temp_c,gyro_dph,spare,spare\n0,50,1,2,3\n", &default_options()).1;
        assert_eq!(report.map(|r| r.rows).ok(), Some(1));
        assert_eq!(super::column_list(&[1, 3, 5]), "2, 4 and 6");
    }
}
