//! The log-columns section (format version 4): per axis, the log columns it was fitted on and
//! how their numbers were read, so a host can match a log's columns to the model's axes by
//! name and read them in the same units, instead of by position and by flags repeated.
//!
//! Layout, after the last axis section and before the CRC trailer: `names_len` (u32, the
//! section's bytes with this field), then per axis in order: the gyro column and the
//! temperature column, each a one-byte length and that many bytes of UTF-8 (no control
//! characters; length 0 = not recorded), then `gyro_dph_per_unit`, `temp_c_per_unit` and
//! `temp_offset_c` (f64 each, the one place a blob holds f64: hosts read logs in f64 and these
//! reproduce the fit's reading exactly; `gyro_dph = value * gyro_dph_per_unit`,
//! `temp_c = value * temp_c_per_unit + temp_offset_c`).
//!
//! From format version 5 the section ends, after the last axis, with the **log-time record**:
//! how the fit read each row's time. The time column and the date column (each a one-byte
//! length and UTF-8; length 0 = none), `time_unit` (u8: 0 seconds, 1 milliseconds,
//! 2 microseconds, 3 date-time, 4 time of day) and `sample_rate_hz` (f64: 0, or the rate of a
//! log without a time column, whose time column is then empty). An empty time column with rate
//! 0 means not recorded (a fit from arrays). A date column needs the date-time unit.
//!
//! From format version 6 the **log-reading record** follows: `decimal_mark` (u8: 0 point,
//! 1 comma), `log_count` (u16) and `log_count` digests of 8 bytes, the first bytes of the
//! SHA-256 of each calibration log (its bytes, or a run given as arrays: its samples), in
//! the order the fit read them, so a host can tell a validation log that was among them.
//!
//! From format version 7 the **log-shape record** follows, written only when the fit's logs
//! did not have the default shape: `skip_lines` (u32, lines dropped unread at the start),
//! `delimiter` (u8: 0 detected, 1 one byte, 2 runs of spaces and tabs), `delimiter_byte` (u8:
//! the byte for code 1, ASCII, not a quote, line end or NUL; 0 otherwise), `has_comment` (u8:
//! 0 no comment lines, 1 lines starting with the comment prefix are comments), the comment
//! prefix (a one-byte length and UTF-8: length 0 without comments, at least 1 with), then
//! `column_count` (u8: 0 = the logs have a header row) and that many column names of a
//! headerless log, in order (each a one-byte length, at least 1, and UTF-8).
//!
//! From format version 8 the log-shape record is always present (the default shape written
//! out when the logs had it: `skip_lines` 0, delimiter detected, comment lines starting with
//! `#`, `column_count` 0), and the **run-metadata record** follows it, written only when the fit had run metadata
//! (a runs file or a simulation's manifest giving each run's true input rate): `input_rates`
//! (u8: 1 = each calibration run's input rate was taken off its gyro before the fit, so the
//! model is the bias alone; 2 = the rates were given but not taken off, the logs having
//! several gyro columns, so each axis's model holds its calibration runs' input rate as bias).

use crate::error::Error;
use crate::wire::{
    f64_at, u16_at, u32_at, COLUMN_UNITS_LEN, LOG_DIGEST_LEN, LOG_READING_FIXED_LEN, LOG_SHAPE_FIXED_LEN,
    LOG_TIME_FIXED_LEN, NAMES_LEN_LEN, RUN_METADATA_LEN,
};

/// What one axis records of its log columns (names `""` = not recorded).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisColumns<'a> {
    /// The gyro column the axis was fitted on.
    pub gyro: &'a str,
    /// The temperature column that fed its features.
    pub temp: &'a str,
    /// Degrees per hour per unit of the gyro column (unit conversion and any extra scale):
    /// finite, not 0.
    pub gyro_dph_per_unit: f64,
    /// Degrees C per unit of the temperature column: finite, not 0.
    pub temp_c_per_unit: f64,
    /// Added after the scale, deg C: finite.
    pub temp_offset_c: f64,
}

/// The unit of a log's time column, as the log-time record stores it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LogTimeUnit {
    /// Seconds (code 0).
    #[default]
    Seconds,
    /// Milliseconds (code 1).
    Milliseconds,
    /// Microseconds (code 2).
    Microseconds,
    /// ISO 8601 date-times (code 3).
    DateTime,
    /// Clock times without a date (code 4).
    TimeOfDay,
    /// Minutes (code 5), as chamber controllers and data loggers write elapsed time.
    Minutes,
    /// Hours (code 6).
    Hours,
    /// Nanoseconds (code 7), e.g. an epoch stamp in ns.
    Nanoseconds,
}

impl LogTimeUnit {
    /// The unit of a stored code; `None` for an unknown one.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0 => Self::Seconds,
            1 => Self::Milliseconds,
            2 => Self::Microseconds,
            3 => Self::DateTime,
            4 => Self::TimeOfDay,
            5 => Self::Minutes,
            6 => Self::Hours,
            7 => Self::Nanoseconds,
            _ => return None,
        })
    }

    /// The stored code.
    pub fn code(self) -> u8 {
        match self {
            Self::Seconds => 0,
            Self::Milliseconds => 1,
            Self::Microseconds => 2,
            Self::DateTime => 3,
            Self::TimeOfDay => 4,
            Self::Minutes => 5,
            Self::Hours => 6,
            Self::Nanoseconds => 7,
        }
    }
}

/// How the fit read its logs' time (format version 5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogTime<'a> {
    /// The time column; `""` for a log without one (time from `sample_rate_hz`).
    pub column: &'a str,
    /// The column with each row's date read together with the time column; `""` for none.
    pub date_column: &'a str,
    /// The time column's unit.
    pub unit: LogTimeUnit,
    /// The sample rate of a log without a time column, Hz; 0 otherwise.
    pub sample_rate_hz: f64,
}

/// How the fit read its logs' numbers, and which logs it read (format version 6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogReading<'a> {
    /// The logs wrote numbers with a decimal comma (`3,14`), not a point.
    pub decimal_comma: bool,
    /// The calibration logs' digests, [`crate::wire::LOG_DIGEST_LEN`] bytes each, in the
    /// order the fit read them.
    digests: &'a [u8],
}

impl<'a> LogReading<'a> {
    /// How many calibration logs have a digest.
    pub fn log_count(&self) -> usize {
        self.digests.len() / LOG_DIGEST_LEN
    }

    /// The digest of calibration log `index` (the first 8 bytes of its SHA-256), `None` past
    /// the last.
    pub fn log_digest(&self, index: usize) -> Option<[u8; LOG_DIGEST_LEN]> {
        let start = index.checked_mul(LOG_DIGEST_LEN)?;
        self.digests.get(start..start.checked_add(LOG_DIGEST_LEN)?)?.try_into().ok()
    }
}

/// What the fit did with its runs' true input rates (the run-metadata record, format version 8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputRates {
    /// Each calibration run's input rate was taken off its gyro before the fit (code 1): the
    /// model is the bias alone, and its output is the bias to remove.
    Subtracted,
    /// The rates were given but not taken off (code 2: logs with several gyro columns, one
    /// rate per run): each axis's model holds its calibration runs' input rate as bias.
    NotSubtracted,
}

impl InputRates {
    /// The rates of a stored code; `None` for an unknown one.
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            1 => Some(Self::Subtracted),
            2 => Some(Self::NotSubtracted),
            _ => None,
        }
    }

    /// The stored code.
    pub fn code(self) -> u8 {
        match self {
            Self::Subtracted => 1,
            Self::NotSubtracted => 2,
        }
    }
}

/// How the fields of a log's records are separated, as the log-shape record stores it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogDelimiter {
    /// Detected from the first line read (code 0).
    Detected,
    /// One byte (code 1): `,`, `;`, a tab, ...
    Byte(u8),
    /// Runs of spaces and tabs (code 2).
    Whitespace,
}

/// The shape of the fit's logs (format version 7): what comes before the data and how a
/// record is cut into fields.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogShape<'a> {
    /// Lines at the start of each log dropped unread (a terminal program's banner).
    pub skip_lines: u32,
    /// How the fields are separated.
    pub delimiter: LogDelimiter,
    /// Lines starting with this text are comments; `None` for none.
    pub comment: Option<&'a str>,
    /// The column names of a headerless log: `column_count` validated names.
    names: &'a [u8],
    column_count: u8,
}

impl<'a> LogShape<'a> {
    /// How many column names the record holds (0: the logs have a header row).
    pub fn column_count(&self) -> usize {
        usize::from(self.column_count)
    }

    /// Column `index` of a headerless log, `None` past the last.
    pub fn column_name(&self, index: usize) -> Option<&'a str> {
        if index >= self.column_count() {
            return None;
        }
        let mut at = 0;
        for _ in 0..index {
            at = name_at(self.names, at, "column_names", 0).ok()?.1;
        }
        name_at(self.names, at, "column_names", 0).ok().map(|(name, _)| name)
    }
}

/// Which records end the section after the axes' records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Records {
    /// The log-time record (version 5).
    pub(crate) time: bool,
    /// The log-reading record after it (version 6).
    pub(crate) reading: bool,
    /// The log-shape record after that (version 7).
    pub(crate) shape: bool,
    /// The run-metadata record after the log-shape record (version 8).
    pub(crate) run_metadata: bool,
}

/// Checks the section that starts at `offset` and runs to the end of `body` (the blob without
/// its CRC) for `axis_count` axes, with the records `records` at its end.
pub(crate) fn validate(body: &[u8], offset: usize, axis_count: u16, records: Records) -> Result<(), Error> {
    let mut at = section_start(body, offset)?;
    for axis in 0..axis_count {
        let (_, next) = record_at(body, at, axis)?;
        at = next;
    }
    if records.time {
        at = log_time_at(body, at)?.1;
    }
    if records.reading {
        at = log_reading_at(body, at)?.1;
    }
    if records.shape {
        at = log_shape_at(body, at)?.1;
    }
    if records.run_metadata {
        at = input_rates_at(body, at)?.1;
    }
    if at != body.len() {
        return Err(Error::LengthMismatch {
            field: "names_len",
            expected: at.saturating_sub(offset),
            found: body.len().saturating_sub(offset),
        });
    }
    Ok(())
}

/// The record of axis `index` in a validated section at `offset` (`None` past the last axis).
pub(crate) fn axis_columns(body: &[u8], offset: usize, index: usize) -> Option<AxisColumns<'_>> {
    let mut at = section_start(body, offset).ok()?;
    for _ in 0..index {
        at = record_at(body, at, 0).ok()?.1;
    }
    record_at(body, at, 0).ok().map(|(record, _)| record)
}

/// The log-time record of a validated section at `offset` with `axis_count` axes (`None`
/// when it records nothing: no time column and no rate).
pub(crate) fn log_time(body: &[u8], offset: usize, axis_count: u16) -> Option<LogTime<'_>> {
    let (time, _) = log_time_at(body, after_axes(body, offset, axis_count)?).ok()?;
    (!time.column.is_empty() || time.sample_rate_hz > 0.0).then_some(time)
}

/// The log-reading record of a validated version-6 section at `offset` with `axis_count` axes.
pub(crate) fn log_reading(body: &[u8], offset: usize, axis_count: u16) -> Option<LogReading<'_>> {
    let at = log_time_at(body, after_axes(body, offset, axis_count)?).ok()?.1;
    log_reading_at(body, at).ok().map(|(reading, _)| reading)
}

/// The log-shape record of a validated version-7 section at `offset` with `axis_count` axes.
pub(crate) fn log_shape(body: &[u8], offset: usize, axis_count: u16) -> Option<LogShape<'_>> {
    let at = log_time_at(body, after_axes(body, offset, axis_count)?).ok()?.1;
    let at = log_reading_at(body, at).ok()?.1;
    log_shape_at(body, at).ok().map(|(shape, _)| shape)
}

/// The run-metadata record of a validated version-8 section at `offset` with `axis_count`
/// axes.
pub(crate) fn input_rates(body: &[u8], offset: usize, axis_count: u16) -> Option<InputRates> {
    let at = log_time_at(body, after_axes(body, offset, axis_count)?).ok()?.1;
    let at = log_reading_at(body, at).ok()?.1;
    let at = log_shape_at(body, at).ok()?.1;
    input_rates_at(body, at).ok().map(|(rates, _)| rates)
}

/// Where the records after the axes' column records start in a validated section at
/// `offset` with `axis_count` axes.
fn after_axes(body: &[u8], offset: usize, axis_count: u16) -> Option<usize> {
    let mut at = section_start(body, offset).ok()?;
    for _ in 0..axis_count {
        at = record_at(body, at, 0).ok()?.1;
    }
    Some(at)
}

/// The run-metadata record at `at` and where it ends.
fn input_rates_at(body: &[u8], at: usize) -> Result<(InputRates, usize), Error> {
    let end = at.saturating_add(RUN_METADATA_LEN);
    let code =
        *body.get(at).ok_or(Error::Truncated { field: "run metadata", needed: end, found: body.len() })?;
    let rates = InputRates::from_code(code)
        .ok_or(Error::BadRunMetadata { field: "input_rates", found: u64::from(code) })?;
    Ok((rates, end))
}

/// The log-shape record at `at` and where it ends.
fn log_shape_at(body: &[u8], at: usize) -> Result<(LogShape<'_>, usize), Error> {
    let bad = |field| Error::BadLogReading { field };
    let fixed_end = at.saturating_add(LOG_SHAPE_FIXED_LEN);
    let fixed = body.get(at..fixed_end).ok_or(Error::Truncated {
        field: "log shape",
        needed: fixed_end,
        found: body.len(),
    })?;
    let &[s0, s1, s2, s3, code, byte, has_comment] = fixed else {
        return Err(Error::Truncated { field: "log shape", needed: fixed_end, found: body.len() });
    };
    let skip_lines = u32::from_le_bytes([s0, s1, s2, s3]);
    let delimiter = match (code, byte) {
        (0, 0) => LogDelimiter::Detected,
        (2, 0) => LogDelimiter::Whitespace,
        (1, b) if b.is_ascii() && !matches!(b, 0 | b'"' | b'\n' | b'\r') => LogDelimiter::Byte(b),
        (0..=2, _) => return Err(bad("delimiter_byte")),
        _ => return Err(bad("delimiter")),
    };
    let (comment, at) = name_at(body, fixed_end, "comment", 0).map_err(|e| reading_bad(e, "comment"))?;
    let comment = match (has_comment, comment.is_empty()) {
        (0, true) => None,
        (1, false) => Some(comment),
        _ => return Err(bad("comment")),
    };
    let count = *body.get(at).ok_or(Error::Truncated {
        field: "column_count",
        needed: at.saturating_add(1),
        found: body.len(),
    })?;
    let names_start = at.saturating_add(1);
    let mut end = names_start;
    for _ in 0..count {
        let (name, next) =
            name_at(body, end, "column_names", 0).map_err(|e| reading_bad(e, "column_names"))?;
        if name.is_empty() {
            return Err(bad("column_names"));
        }
        end = next;
    }
    let names = body.get(names_start..end).unwrap_or_default();
    Ok((LogShape { skip_lines, delimiter, comment, names, column_count: count }, end))
}

/// A name's invalid text as [`Error::BadLogReading`]; truncation stays as it is.
fn reading_bad(e: Error, field: &'static str) -> Error {
    match e {
        Error::BadValue { .. } => Error::BadLogReading { field },
        other => other,
    }
}

/// The log-reading record at `at` and where it ends.
fn log_reading_at(body: &[u8], at: usize) -> Result<(LogReading<'_>, usize), Error> {
    let fixed_end = at.saturating_add(LOG_READING_FIXED_LEN);
    if body.len() < fixed_end {
        return Err(Error::Truncated { field: "log reading", needed: fixed_end, found: body.len() });
    }
    let decimal_comma = match body.get(at) {
        Some(0) => false,
        Some(1) => true,
        _ => return Err(Error::BadLogReading { field: "decimal_mark" }),
    };
    let count = usize::from(u16_at(body, at.saturating_add(1)).unwrap_or(0));
    let end = fixed_end.saturating_add(count.saturating_mul(LOG_DIGEST_LEN));
    let digests = body.get(fixed_end..end).ok_or(Error::Truncated {
        field: "log_digests",
        needed: end,
        found: body.len(),
    })?;
    Ok((LogReading { decimal_comma, digests }, end))
}

/// The log-time record at `at` and where it ends.
fn log_time_at(body: &[u8], at: usize) -> Result<(LogTime<'_>, usize), Error> {
    let bad = |field| Error::BadLogTime { field };
    let (column, at) = name_at(body, at, "time_column", 0).map_err(|e| named_bad(e, "time_column"))?;
    let (date_column, at) = name_at(body, at, "date_column", 0).map_err(|e| named_bad(e, "date_column"))?;
    let end = at.saturating_add(LOG_TIME_FIXED_LEN);
    if body.len() < end {
        return Err(Error::Truncated { field: "log time", needed: end, found: body.len() });
    }
    let unit = body.get(at).copied().and_then(LogTimeUnit::from_code).ok_or(bad("time_unit"))?;
    let sample_rate_hz = f64_at(body, at.saturating_add(1)).unwrap_or(f64::NAN);
    if !(sample_rate_hz.is_finite() && sample_rate_hz >= 0.0) || (sample_rate_hz > 0.0 && !column.is_empty())
    {
        return Err(bad("sample_rate_hz"));
    }
    if !date_column.is_empty() && unit != LogTimeUnit::DateTime {
        return Err(bad("date_column"));
    }
    Ok((LogTime { column, date_column, unit, sample_rate_hz }, end))
}

/// A name's invalid text as [`Error::BadLogTime`]; truncation stays as it is.
fn named_bad(e: Error, field: &'static str) -> Error {
    match e {
        Error::BadValue { .. } => Error::BadLogTime { field },
        other => other,
    }
}

/// Where the first record starts, once `names_len` is found to cover the rest of `body`.
fn section_start(body: &[u8], offset: usize) -> Result<usize, Error> {
    let start = offset.saturating_add(NAMES_LEN_LEN);
    let names_len = u32_at(body, offset).ok_or(Error::Truncated {
        field: "names_len",
        needed: start,
        found: body.len(),
    })? as usize;
    let rest = body.len().saturating_sub(offset);
    if names_len != rest {
        return Err(Error::LengthMismatch { field: "names_len", expected: rest, found: names_len });
    }
    Ok(start)
}

/// Axis `axis`'s record at `at` and where the next one starts.
fn record_at(body: &[u8], at: usize, axis: u16) -> Result<(AxisColumns<'_>, usize), Error> {
    let (gyro, at) = name_at(body, at, "gyro_column", axis)?;
    let (temp, at) = name_at(body, at, "temp_column", axis)?;
    let end = at.saturating_add(COLUMN_UNITS_LEN);
    if body.len() < end {
        return Err(Error::Truncated { field: "column units", needed: end, found: body.len() });
    }
    let number = |k: usize, field: &'static str, nonzero: bool| {
        let v = f64_at(body, at.saturating_add(8 * k)).unwrap_or(f64::NAN);
        if !v.is_finite() {
            return Err(Error::NonFinite { field, axis, index: 0 });
        }
        if nonzero && v == 0.0 {
            return Err(Error::BadValue { field, axis, index: 0 });
        }
        Ok(v)
    };
    let record = AxisColumns {
        gyro,
        temp,
        gyro_dph_per_unit: number(0, "gyro_dph_per_unit", true)?,
        temp_c_per_unit: number(1, "temp_c_per_unit", true)?,
        temp_offset_c: number(2, "temp_offset_c", false)?,
    };
    Ok((record, end))
}

/// The name at `at` (length byte, then the bytes) and where the next field starts.
fn name_at<'a>(body: &'a [u8], at: usize, field: &'static str, axis: u16) -> Result<(&'a str, usize), Error> {
    let len = usize::from(*body.get(at).ok_or(Error::Truncated {
        field,
        needed: at.saturating_add(1),
        found: body.len(),
    })?);
    let start = at.saturating_add(1);
    let end = start.saturating_add(len);
    let bytes = body.get(start..end).ok_or(Error::Truncated { field, needed: end, found: body.len() })?;
    let text = core::str::from_utf8(bytes).map_err(|_| Error::BadValue { field, axis, index: 0 })?;
    if text.chars().any(char::is_control) {
        return Err(Error::BadValue { field, axis, index: 0 });
    }
    Ok((text, end))
}
