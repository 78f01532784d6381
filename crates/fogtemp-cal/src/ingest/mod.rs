//! Streaming CSV ingest of lab logs (one file per run; contract in docs/architecture.md, Contracts).
//!
//! Rows are parsed into reused buffers and handed to a visitor one at a time, in file
//! order, so memory stays constant whatever the log size. Every rejected row is reported
//! with its file, line and column; with `skip_bad_rows` the rows are skipped and counted
//! instead.
//!
//! The reader follows the `csv` crate's dialect (RFC 4180 with `"` quoting, flexible
//! record lengths): `\n`, `\r\n` and a lone `\r` all end a record, blank lines are
//! skipped, a UTF-8 byte-order mark at the start of the file is ignored and the last line
//! needs no newline. Line numbers are physical lines (1-based, counted by `\n`; the
//! header is line 1 unless blank lines precede it), including after blank lines and in
//! CRLF files.
//!
//! How it is fast (see `docs/ingest-performance.md`): records without quotes, whose
//! needed cells are plain decimals (`-12.345`, at most 15 digits), are split and
//! converted in one pass over the bytes, with exactly the value `fast-float2` would give
//! (the decimal's digits as an integer divided by a power of ten, both exact in `f64`,
//! so the one rounding is the correct one). Any other record (quotes, exponents, spaces,
//! `nan`, short rows, empty required cells, time not increasing) takes the general path,
//! which splits the record (with `csv-core` when it holds a quote) and parses its cells as
//! before, so errors and values are the same either way. On logs of 1 MiB or more, when
//! there is a second core, worker threads parse 1 MiB chunks of whole records and the
//! calling thread merges them in order and runs the visitor (see [`read_log`]); memory
//! is a few chunks whatever the log size.

mod batch;
mod columns;
pub use columns::AMBIGUOUS_TIME;
mod datetime;
mod decimal;
mod parallel;
mod parser;
#[cfg(test)]
mod shape_tests;
#[cfg(test)]
mod test_support;

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::digest::InputDigest;
use crate::error::CalError;
use batch::{Batch, Consumer};
use parallel::read_parallel;
use parser::Parser;

/// Unit of the time column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeUnit {
    /// Seconds.
    Seconds,
    /// Milliseconds.
    Milliseconds,
    /// Microseconds.
    Microseconds,
    /// Nanoseconds (an epoch stamp in ns reads to about 0.25 us: an f64's resolution there).
    Nanoseconds,
    /// Minutes, as chamber controllers and data loggers write elapsed time.
    Minutes,
    /// Hours.
    Hours,
    /// ISO 8601 date-times as loggers write them (`2026-11-24T10:00:00.125`, a space for
    /// the `T`, `/` for the `-`, optionally `Z` or an offset such as `+01:00`); a time
    /// without a zone is read as UTC (only differences between rows are used).
    DateTime,
    /// A clock time without a date (`15:45`, `09:05:07.25`), as hand logs and terminal
    /// programs write it: seconds since the first row's midnight. A row whose clock reads
    /// more than 12 h before the previous row's is on the next day (the clock passed
    /// midnight); rows more than 12 h apart cannot be placed without a date.
    TimeOfDay,
}

impl TimeUnit {
    /// The unit as a model's log-time record stores it.
    pub fn log_unit(self) -> fogtemp_core::LogTimeUnit {
        use fogtemp_core::LogTimeUnit as L;
        match self {
            TimeUnit::Seconds => L::Seconds,
            TimeUnit::Milliseconds => L::Milliseconds,
            TimeUnit::Microseconds => L::Microseconds,
            TimeUnit::Nanoseconds => L::Nanoseconds,
            TimeUnit::Minutes => L::Minutes,
            TimeUnit::Hours => L::Hours,
            TimeUnit::DateTime => L::DateTime,
            TimeUnit::TimeOfDay => L::TimeOfDay,
        }
    }

    /// The unit a model's log-time record stores.
    pub fn from_log_unit(unit: fogtemp_core::LogTimeUnit) -> Self {
        use fogtemp_core::LogTimeUnit as L;
        match unit {
            L::Seconds => TimeUnit::Seconds,
            L::Milliseconds => TimeUnit::Milliseconds,
            L::Microseconds => TimeUnit::Microseconds,
            L::Nanoseconds => TimeUnit::Nanoseconds,
            L::Minutes => TimeUnit::Minutes,
            L::Hours => TimeUnit::Hours,
            L::DateTime => TimeUnit::DateTime,
            L::TimeOfDay => TimeUnit::TimeOfDay,
        }
    }

    /// The unit as the command line's `--time-unit` names it.
    pub fn option_name(self) -> &'static str {
        match self {
            TimeUnit::Seconds => "s",
            TimeUnit::Milliseconds => "ms",
            TimeUnit::Microseconds => "us",
            TimeUnit::Nanoseconds => "ns",
            TimeUnit::Minutes => "min",
            TimeUnit::Hours => "h",
            TimeUnit::DateTime => "datetime",
            TimeUnit::TimeOfDay => "time-of-day",
        }
    }

    /// A time cell's value in seconds (date-times and times of day are read into seconds).
    /// Fractions of a second are divided out: `1700007200001234 / 1e6` is the f64 nearest
    /// the logged microseconds, where `* 1e-6` (1e-6 is not exact in binary) can be one step
    /// off (review20 F4); minutes and hours are multiplied (60 is exact, 1/60 is not).
    pub fn to_seconds(self, value: f64) -> f64 {
        match self {
            TimeUnit::Seconds | TimeUnit::DateTime | TimeUnit::TimeOfDay => value,
            TimeUnit::Milliseconds => value / 1.0e3,
            TimeUnit::Microseconds => value / 1.0e6,
            TimeUnit::Nanoseconds => value / 1.0e9,
            TimeUnit::Minutes => value * 60.0,
            TimeUnit::Hours => value * 3600.0,
        }
    }

    /// The time cells are text (date-times, times of day), not numbers.
    pub fn is_text(self) -> bool {
        matches!(self, TimeUnit::DateTime | TimeUnit::TimeOfDay)
    }
}

/// Unit of the gyro columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RateUnit {
    /// Degrees per hour.
    DegPerHour,
    /// Degrees per second.
    DegPerSecond,
    /// Radians per second.
    RadPerSecond,
}

impl RateUnit {
    /// Degrees per hour per unit.
    pub fn dph(self) -> f64 {
        match self {
            RateUnit::DegPerHour => 1.0,
            RateUnit::DegPerSecond => 3600.0,
            RateUnit::RadPerSecond => 3600.0 * 180.0 / std::f64::consts::PI,
        }
    }
}

/// Which columns hold what, and in which units.
#[derive(Clone, Debug, PartialEq)]
pub struct LogFormat {
    /// Time column name.
    pub time_column: String,
    /// Time unit.
    pub time_unit: TimeUnit,
    /// Temperature columns (one per model axis, or one shared by all axes).
    pub temp_columns: Vec<String>,
    /// `temp_c = raw * temp_scale + temp_offset` (for raw sensor counts).
    pub temp_scale: f64,
    /// See `temp_scale`, deg C.
    pub temp_offset_c: f64,
    /// Gyro columns, one per model axis.
    pub gyro_columns: Vec<String>,
    /// Gyro unit.
    pub gyro_unit: RateUnit,
    /// Extra factor on the gyro after the unit conversion (e.g. 0.5 for a driver that doubles).
    pub gyro_scale: f64,
    /// Field delimiter ([`Delimiter::Auto`] by default: from the first line that is not
    /// skipped, blank or a comment).
    pub delimiter: Delimiter,
    /// Lines at the start of the file dropped unread (a terminal program's banner), before
    /// the header or, for a headerless log, the data. Line numbers still count them.
    pub skip_lines: u64,
    /// Lines that start with this text (after any spaces or tabs) are comments and skipped
    /// wherever they are; `None` for no comments. `#` by default. It may not start with
    /// what a number or a record can start with (a digit, `+`, `-`, `.`, a space, a tab, a
    /// quote or the delimiter).
    pub comment: Option<String>,
    /// Names of the columns in order, for a log without a header row (its first line after
    /// `skip_lines` is data); empty when the log has a header row.
    pub column_names: Vec<String>,
    /// Sample rate for a log without a time column: data record `k` (0-based, counting
    /// rejected records but not blank or comment lines) is at `k / rate` seconds. A log
    /// that also has a column named `time_column` is refused as ambiguous.
    pub sample_rate_hz: Option<f64>,
    /// The sample rate is not named but the one a model records of its fit's logs
    /// (`axis_columns::choose_time`): a header column whose name looks like a time (`t`,
    /// `Time (ms)`, `timestamp`) is then refused as ambiguous too, as one named
    /// `time_column` always is, instead of being left unread while time comes from the row
    /// index.
    pub sample_rate_from_model: bool,
    /// A column holding the date of each row when the time column holds only the time of
    /// day (a spreadsheet export's `Date` and `Time`): the two cells are read as one
    /// date-time, `date` `T` `time`. Needs [`TimeUnit::DateTime`].
    pub date_column: Option<String>,
    /// The decimal mark of the numbers ([`DecimalMark::Point`] by default). Logs written
    /// in a locale with a decimal comma (`20,5`) need [`DecimalMark::Comma`] and another
    /// delimiter (usually `;`).
    pub decimal_mark: DecimalMark,
}

/// The character between a number's integer and fractional digits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DecimalMark {
    /// `20.5`.
    #[default]
    Point,
    /// `20,5`. A cell with a `.` is then refused rather than guessed at: in such locales a
    /// point is a thousands separator (`1.234,5`), so `1.234` would be 1234, not 1.234.
    Comma,
}

impl DecimalMark {
    /// A decimal mark by name (`point`, `comma`, or the character itself): the command
    /// line's `--decimal-mark`, Python's `decimal_mark=`.
    ///
    /// # Errors
    /// A message naming what is accepted.
    pub fn from_name(text: &str) -> Result<DecimalMark, String> {
        match text {
            "point" | "." => Ok(DecimalMark::Point),
            "comma" | "," => Ok(DecimalMark::Comma),
            _ => Err(format!("expected point or comma, got '{text}'")),
        }
    }
}

/// How the fields of a record are separated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delimiter {
    /// One byte (`,`, `;`, `\t`, ...); fields may be quoted with `"` (RFC 4180).
    Byte(u8),
    /// Runs of spaces and tabs (leading and trailing ones ignored); no quoting.
    Whitespace,
    /// Detected from the first line that is not skipped, blank or a comment (the header,
    /// or the first data row of a headerless log): the most frequent of `,` `;` and tab
    /// outside quotes (ties in that order); with none of them, whitespace if the line has a
    /// space or tab between fields; else `,` (a single column).
    Auto,
}

impl Delimiter {
    /// A delimiter by name (`auto`, `comma`, `semicolon`, `tab`, `whitespace`) or as one
    /// ASCII character (the command line's `--delimiter`, Python's `delimiter=`).
    ///
    /// # Errors
    /// A message naming what is accepted.
    pub fn from_name(text: &str) -> Result<Delimiter, String> {
        Ok(match text {
            "auto" => Delimiter::Auto,
            "comma" | "," => Delimiter::Byte(b','),
            "semicolon" | ";" => Delimiter::Byte(b';'),
            "tab" | "\t" | "\\t" => Delimiter::Byte(b'\t'),
            "whitespace" | "space" => Delimiter::Whitespace,
            _ => match text.as_bytes() {
                [b] if b.is_ascii() => Delimiter::Byte(*b),
                _ => {
                    return Err(format!(
                    "expected auto, comma, semicolon, tab, whitespace or one ASCII character, got '{text}'"
                ))
                }
            },
        })
    }

    /// The name [`Delimiter::from_name`] reads back: `auto`, `comma`, `semicolon`, `tab`,
    /// `whitespace`, or the character itself.
    pub fn name(self) -> String {
        match self {
            Delimiter::Auto => "auto".to_string(),
            Delimiter::Whitespace => "whitespace".to_string(),
            Delimiter::Byte(b',') => "comma".to_string(),
            Delimiter::Byte(b';') => "semicolon".to_string(),
            Delimiter::Byte(b'\t') => "tab".to_string(),
            Delimiter::Byte(b) => char::from(b).to_string(),
        }
    }

    /// The delimiter [`Delimiter::Auto`] picks for `line` (other variants return themselves).
    pub fn resolve(self, line: &[u8]) -> Delimiter {
        self.resolve_with(line, DecimalMark::Point)
    }

    /// [`Delimiter::resolve`] for numbers written with `decimal`: with a decimal comma a
    /// comma is never the delimiter (a headerless row `0,1;20,5` has more commas than
    /// semicolons).
    pub fn resolve_with(self, line: &[u8], decimal: DecimalMark) -> Delimiter {
        if self != Delimiter::Auto {
            return self;
        }
        let comma_delimits = decimal == DecimalMark::Point;
        let mut counts = [0usize; 3];
        let mut quoted = false;
        for &b in line {
            match b {
                b'"' => quoted = !quoted,
                b',' if !quoted && comma_delimits => counts[0] += 1,
                b';' if !quoted => counts[1] += 1,
                b'\t' if !quoted => counts[2] += 1,
                _ => {}
            }
        }
        let best = (0..3).fold(0, |best, k| if counts[k] > counts[best] { k } else { best });
        if counts[best] > 0 {
            return Delimiter::Byte([b',', b';', b'\t'][best]);
        }
        if line.trim_ascii().contains(&b' ') {
            return Delimiter::Whitespace;
        }
        Delimiter::Byte(b',')
    }
}

impl Default for LogFormat {
    fn default() -> Self {
        Self {
            time_column: "time_s".into(),
            time_unit: TimeUnit::Seconds,
            temp_columns: vec!["temp_c".into()],
            temp_scale: 1.0,
            temp_offset_c: 0.0,
            gyro_columns: vec!["gyro_dph".into()],
            gyro_unit: RateUnit::DegPerHour,
            gyro_scale: 1.0,
            delimiter: Delimiter::Auto,
            skip_lines: 0,
            comment: Some("#".into()),
            column_names: Vec::new(),
            sample_rate_hz: None,
            sample_rate_from_model: false,
            date_column: None,
            decimal_mark: DecimalMark::Point,
        }
    }
}

impl LogFormat {
    /// The columns each axis reads, its gyro column and its temperature column (the shared
    /// one, or the axis's own), and how their numbers are read, as a model records them.
    pub fn axis_columns(&self) -> Vec<crate::blob::ColumnNames> {
        let temp = |axis: usize| {
            let last = self.temp_columns.len().saturating_sub(1);
            self.temp_columns.get(axis.min(last)).cloned().unwrap_or_default()
        };
        self.gyro_columns
            .iter()
            .enumerate()
            .map(|(axis, gyro)| crate::blob::ColumnNames {
                gyro: gyro.clone(),
                temp: temp(axis),
                gyro_dph_per_unit: self.gyro_unit.dph() * self.gyro_scale,
                temp_c_per_unit: self.temp_scale,
                temp_offset_c: self.temp_offset_c,
            })
            .collect()
    }

    /// How this format reads each row's time, as a model records it.
    pub fn log_time(&self) -> crate::blob::LogTimeRecord {
        match self.sample_rate_hz {
            Some(rate) => crate::blob::LogTimeRecord { sample_rate_hz: rate, ..Default::default() },
            None => crate::blob::LogTimeRecord {
                column: self.time_column.clone(),
                date_column: self.date_column.clone().unwrap_or_default(),
                unit: self.time_unit.log_unit(),
                sample_rate_hz: 0.0,
            },
        }
    }

    /// Reads each row's time as `record` says (a model's log-time record).
    pub fn set_log_time(&mut self, record: &crate::blob::LogTimeRecord) {
        if record.sample_rate_hz > 0.0 {
            self.sample_rate_hz = Some(record.sample_rate_hz);
        } else {
            self.sample_rate_hz = None;
            self.time_column.clone_from(&record.column);
            self.time_unit = TimeUnit::from_log_unit(record.unit);
            self.date_column = (!record.date_column.is_empty()).then(|| record.date_column.clone());
        }
    }

    /// Checks the settings that do not depend on the log's contents; `path` names the log
    /// in the error.
    ///
    /// # Errors
    /// [`CalError::LogFormat`] for a sample rate that is not a positive finite number, a
    /// comment prefix that could start a record, or an empty column name.
    pub fn check(&self, path: &Path) -> Result<(), CalError> {
        let problem =
            |problem: String| Err(CalError::LogFormat { path: path.to_path_buf(), line: 0, problem });
        if let Some(rate) = self.sample_rate_hz {
            if !(rate.is_finite() && rate > 0.0) {
                return problem(format!("the sample rate must be a positive number of Hz, got {rate}"));
            }
        }
        if let Some(first) = self.comment_prefix().first() {
            let clashes =
                matches!(first, b'0'..=b'9' | b'+' | b'-' | b'.' | b' ' | b'\t' | b'"' | b'\r' | b'\n')
                    || self.delimiter == Delimiter::Byte(*first);
            if clashes {
                return problem(format!(
                    "the comment prefix {:?} starts with a character a record can start with",
                    self.comment.as_deref().unwrap_or_default()
                ));
            }
        }
        if self.column_names.iter().any(|n| n.trim().is_empty()) {
            return problem("a column name is empty".into());
        }
        if self.date_column.is_some()
            && (self.time_unit != TimeUnit::DateTime || self.sample_rate_hz.is_some())
        {
            return problem(
                "a date column needs the time column read as date-times (time unit datetime)".into(),
            );
        }
        if self.decimal_mark == DecimalMark::Comma && self.delimiter == Delimiter::Byte(b',') {
            return problem("a log with a decimal comma needs another delimiter (e.g. semicolon)".into());
        }
        if let Some(clash) = self.column_clash() {
            return problem(clash);
        }
        Ok(())
    }

    /// A column asked to be two things at once (`None` when there is none): a name given
    /// twice to a headerless log, a gyro column read for two axes (one gyro would make a
    /// two-axis model), or one column read as two of time, temperature and gyro. A
    /// temperature column shared by several axes is fine.
    fn column_clash(&self) -> Option<String> {
        let twice = |names: &[String]| {
            names.iter().enumerate().find(|(k, n)| names[..*k].contains(n)).map(|(_, n)| n.clone())
        };
        if let Some(name) = twice(&self.column_names) {
            return Some(format!("the column names given to a log without a header name '{name}' twice"));
        }
        if let Some(name) = twice(&self.gyro_columns) {
            return Some(format!("the gyro column '{name}' is given for two axes"));
        }
        let time = self.sample_rate_hz.is_none().then_some(&self.time_column);
        let roles = self
            .gyro_columns
            .iter()
            .map(|c| (c, "gyro"))
            .chain(self.temp_columns.iter().map(|c| (c, "temperature")))
            .chain(time.map(|c| (c, "time")))
            .chain(self.date_column.iter().map(|c| (c, "date")));
        let roles: Vec<(&String, &str)> = roles.collect();
        roles.iter().enumerate().find_map(|(k, (name, role))| {
            let other = roles[..k].iter().find(|(n, r)| n == name && r != role)?;
            Some(format!("the column '{name}' is read as both the {} and the {role}", other.1))
        })
    }

    /// The comment prefix as bytes (empty: no comments).
    pub(crate) fn comment_prefix(&self) -> &[u8] {
        self.comment.as_deref().unwrap_or_default().as_bytes()
    }
}

/// One parsed row, borrowed from the reader's buffers (valid during the visitor call).
#[derive(Clone, Copy, Debug)]
pub struct Row<'a> {
    /// 1-based line number in the file.
    pub line: u64,
    /// Time since the file's first accepted row, seconds.
    pub time_s: f64,
    /// Time of the file's first accepted row in the file's own clock, seconds (0 when the
    /// time comes from `sample_rate_hz`): `origin_s + time_s` is the row's own time stamp.
    pub origin_s: f64,
    /// Temperatures, deg C, one per temperature column; NaN where the cell is empty
    /// (sensors slower than the gyro leave cells empty).
    pub temps_c: &'a [f64],
    /// Gyro rates, deg/h, one per gyro column.
    pub gyros_dph: &'a [f64],
}

impl Row<'_> {
    /// The temperature for model axis `axis`, deg C: its own column when there is one per
    /// gyro column, else the shared one. NaN when this row has no reading.
    pub fn temp_c_for_axis(&self, axis: usize) -> f64 {
        self.temps_c.get(axis.min(self.temps_c.len().saturating_sub(1))).copied().unwrap_or(f64::NAN)
    }

    /// [`Row::time_s`] in whole microseconds, as the feature tracker and compensator take it.
    pub fn time_us(&self) -> u64 {
        crate::features::micros(self.time_s)
    }
}

/// Why a row was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BadRowKind {
    /// A cell is not a number.
    NotANumber,
    /// Not a number, and no cell the log is read from holds one: text where every number
    /// belongs, as a units row under the header (`s,degC,deg/h`) or a header repeated where
    /// two logs were joined.
    TextRow,
    /// A cell is NaN or infinite.
    NonFinite,
    /// Fewer fields than the header.
    ShortRow,
    /// Fewer fields than the header (or the names of `--columns`) in a log whose fields are
    /// separated by runs of spaces: a blank cell there vanishes and every cell after it
    /// moves one column left, so which cell is missing cannot be told (review32a F1: a
    /// fixed-width log's blank temperature read the gyro as the temperature, exit 0).
    ShortSpacedRow,
    /// More fields than the header (or the names of `--columns`) with text in the extra
    /// ones: two records run together (a lost line break). Empty extra fields (a trailing
    /// delimiter) are not.
    LongRow,
    /// More fields than the header because numbers were written with thousands separators
    /// equal to the delimiter (`1,000.5` in a comma log, `1 000.5` in a spaced one): a field
    /// of 1-3 digits followed by one of exactly 3 digits (and a fraction), as many such pairs
    /// as extra fields (review32a F9: explained as a lost line break, and `--skip-bad-rows`
    /// dropped every row from 1000 s on).
    SplitThousands,
    /// Time equal to the previous row's.
    DuplicateTime,
    /// Time before the previous row's.
    BackwardTime,
    /// A required cell (time or gyro) is empty.
    EmptyCell,
    /// A cell holds a point in a log read with [`DecimalMark::Comma`].
    PointWithDecimalComma,
    /// The time cell of a log read with [`TimeUnit::DateTime`] is not an ISO 8601 date-time.
    NotADateTime,
    /// The time cell of a log read with [`TimeUnit::TimeOfDay`] is not a time of day.
    NotATimeOfDay,
    /// A temperature (after `temp_scale` and `temp_offset`) below absolute zero or above
    /// 1000 C ([`fogtemp_core::is_physical_temperature`]): no reading of a sensor, often a
    /// logger's sentinel for a missing one (-999, 9999). The firmware's compensator flags
    /// such a sample `BAD_INPUT` by the same rule.
    ImpossibleTemperature,
    /// A gyro rate (after the unit and `gyro_scale`) beyond the f32 the compensator takes
    /// (magnitude above 3.4e38, infinite there): no rate a gyro reads, and its square
    /// overflows every statistic.
    RateBeyondRange,
    /// The record holds NUL bytes: a file padded with zeros after a power cut, or a block of
    /// an SD card that was never written (read as a short row or junk behind a number
    /// otherwise).
    NulBytes,
}

/// Whether a temperature read from a log is one a sensor can report: the compensator's rule
/// on the f32 it would be given.
pub(crate) fn is_physical(temp_c: f64) -> bool {
    fogtemp_core::is_physical_temperature(temp_c as f32)
}

/// Whether a gyro rate read from a log (deg/h, finite) stays finite as the f32 the
/// compensator is given.
pub(crate) fn is_representable_rate(rate_dph: f64) -> bool {
    (rate_dph as f32).is_finite()
}

impl BadRowKind {
    /// Short description for reports.
    pub fn describe(self) -> &'static str {
        match self {
            BadRowKind::NotANumber => "not a number",
            BadRowKind::TextRow => {
                "not a number: the row holds text in every column read (a units row under the header, or a \
                 header repeated where two logs were joined?)"
            }
            BadRowKind::NonFinite => "NaN or infinite",
            BadRowKind::ShortRow => "fewer fields than the header (or the names given for a headerless log)",
            BadRowKind::ShortSpacedRow => {
                "fewer fields than the header (or the names given for a headerless log) in a log whose columns are \
                 separated by spaces: a row cut short, or a blank cell, which vanishes there (the cells after it \
                 move left: which one is missing cannot be told)"
            }
            BadRowKind::LongRow => {
                "more fields than the header (or the names given for a headerless log): two records run together (a lost line \
                 break)? name every field of a log without a header"
            }
            BadRowKind::SplitThousands => {
                "more fields than the header: a number written with a thousands separator that is the log's \
                 delimiter (1,000.5), split in two"
            }
            BadRowKind::DuplicateTime => "time equal to the previous row",
            BadRowKind::BackwardTime => "time before the previous row",
            BadRowKind::EmptyCell => "empty required cell",
            BadRowKind::PointWithDecimalComma => "a point in a log read with a decimal comma",
            BadRowKind::NotADateTime => "not a date-time (YYYY-MM-DDThh:mm:ss[.fff][Z|+hh:mm])",
            BadRowKind::NotATimeOfDay => "not a time of day (hh:mm[:ss[.fff]])",
            BadRowKind::ImpossibleTemperature => {
                "not a temperature a sensor reads (below -273.15 C or above 1000 C; a logger's mark for a missing \
                 reading? leave the cell empty)"
            }
            BadRowKind::NulBytes => {
                "NUL bytes in the line (a file padded with zeros after a power cut, or a block of an SD card never \
                 written?)"
            }
            BadRowKind::RateBeyondRange => {
                "a rate beyond the f32 range the compensator takes (magnitude above 3.4e38 deg/h; an instrument's \
                 overload code, or a unit or --gyro-scale that is far off?)"
            }
        }
    }
}

/// A rejected row: where and why.
#[derive(Clone, Debug, PartialEq)]
pub struct BadRow {
    /// 1-based line.
    pub line: u64,
    /// 1-based column (field) number.
    pub column: usize,
    /// Column name from the header.
    pub column_name: String,
    /// The offending text (cut to 40 characters).
    pub found: String,
    /// Why.
    pub kind: BadRowKind,
}

impl BadRow {
    /// The cell is not a number but is an ISO 8601 date-time: a hint for the caller to
    /// suggest [`TimeUnit::DateTime`].
    pub fn looks_like_datetime(&self) -> bool {
        self.kind == BadRowKind::NotANumber
            && datetime::parse_datetime(self.found.trim().as_bytes()).is_some()
    }

    /// The cell is not a number but is a time of day (`15:45`): a hint for the caller to
    /// suggest [`TimeUnit::TimeOfDay`].
    pub fn looks_like_time_of_day(&self) -> bool {
        self.kind == BadRowKind::NotANumber
            && datetime::parse_time_of_day(self.found.trim().as_bytes()).is_some()
    }

    /// The cell is not a number but would be one with a decimal comma (`20,5`, `-1,5e-3`):
    /// a hint for the caller to suggest [`DecimalMark::Comma`].
    pub fn looks_like_decimal_comma(&self) -> bool {
        let text = self.found.trim();
        let digits = |t: &str| !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit());
        let (mantissa, exponent) = match text.split_once(['e', 'E']) {
            Some((m, e)) => (m, Some(e.strip_prefix(['+', '-']).unwrap_or(e))),
            None => (text, None),
        };
        let unsigned = mantissa.strip_prefix(['+', '-']).unwrap_or(mantissa);
        self.kind == BadRowKind::NotANumber
            && unsigned.split_once(',').is_some_and(|(int, frac)| digits(int) && digits(frac))
            && exponent.is_none_or(digits)
    }

    /// The cell is not a number but would be one without thousands separators (`1,000.000`,
    /// `-12,345`: a spreadsheet's number format): skipping such rows drops every value from
    /// 1000 on (review23b F8: a fit on the first 1000 s of every run, exit status 0).
    pub fn looks_like_thousands_separators(&self) -> bool {
        // Commas grouping a number with a decimal point, or (read with a decimal comma, where
        // a point is refused) points grouping one with a decimal comma (review32a F8). One
        // point alone there is a decimal point (`0.500`: a log that writes points, review32b
        // F1), so a point grouping needs the decimal comma too, or a second point.
        let text = self.found.trim();
        let (group, decimal) = match self.kind {
            BadRowKind::NotANumber => (',', '.'),
            BadRowKind::PointWithDecimalComma if text.contains(',') || text.matches('.').count() > 1 => {
                ('.', ',')
            }
            _ => return false,
        };
        let unsigned = text.strip_prefix(['+', '-']).unwrap_or(text);
        let integer = unsigned.split_once(decimal).map_or(unsigned, |(int, _)| int);
        let mut groups = integer.split(group);
        let first = groups.next().unwrap_or("");
        let grouped = (1..=3).contains(&first.len())
            && first.bytes().all(|b| b.is_ascii_digit())
            && integer.contains(group)
            && groups.all(|g| g.len() == 3 && g.bytes().all(|b| b.is_ascii_digit()));
        grouped
            && unsigned.split_once(decimal).is_none_or(|(_, frac)| frac.bytes().all(|b| b.is_ascii_digit()))
    }

    /// The cell of a log holds a word loggers and spreadsheets write for a missing value
    /// (`NaN`, `N/A`, `NA`, `-`, `null`, ...): a hint for the caller to say that an empty
    /// temperature cell is read as no reading (review32a F6). (Arrays' errors do not come
    /// here: their NaN is a value, said in their own words.)
    pub fn looks_like_missing_marker(&self) -> bool {
        const MARKERS: [&str; 9] = ["n/a", "na", "-", "--", "null", "none", "nil", "#n/a", "?"];
        let text = self.found.trim().trim_matches('"').to_ascii_lowercase();
        match self.kind {
            BadRowKind::NotANumber | BadRowKind::TextRow => MARKERS.contains(&text.as_str()),
            BadRowKind::NonFinite => text == "nan",
            _ => false,
        }
    }

    /// A row of text whose cell repeats the header's name of its column: the header again,
    /// where a logger restarted or two logs were joined (a units row holds units instead).
    pub fn looks_like_repeated_header(&self) -> bool {
        self.kind == BadRowKind::TextRow && self.found.trim() == self.column_name
    }
}

/// How many rows were rejected, and where the first of them are.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IngestReport {
    /// File read.
    pub path: PathBuf,
    /// Bytes read.
    pub bytes: u64,
    /// Rows accepted.
    pub rows: u64,
    /// Rows skipped (only with `skip_bad_rows`).
    pub skipped: u64,
    /// The first [`MAX_REPORTED_BAD_ROWS`] skipped rows.
    pub first_skipped: Vec<BadRow>,
    /// Time of the first accepted row in the file's own units converted to seconds
    /// (`Row::time_s` is relative to it).
    pub time_origin_s: f64,
    /// Time of the last accepted row, s since [`IngestReport::time_origin_s`] (0 without rows).
    pub last_time_s: f64,
    /// The first and the last reading of the first temperature column, deg C (`None` without
    /// any): whether another log continues this one ([`crate::continued`]).
    pub temp_ends_c: Option<(f64, f64)>,
    /// Rows with a temperature and no gyro reading (channels logged on separate rows): not
    /// rows of [`IngestReport::rows`]; each reading went with the next sample.
    pub temperature_only_rows: u64,
}

/// How many skipped rows are listed individually.
pub const MAX_REPORTED_BAD_ROWS: usize = 20;

/// The share of skipped rows, percent, from which the warning says to check the log.
pub const MANY_SKIPPED_PERCENT: f64 = 1.0;

impl IngestReport {
    /// Why a log gave no sample although it has rows: every row held only a temperature
    /// (review33c F6: "only a header" was said); `None` otherwise. `option` names the gyro
    /// column's setting (`--gyro-column`, `gyro_column=`).
    pub fn only_temperature_rows(&self, option: &str) -> Option<String> {
        (self.rows == 0 && self.skipped == 0 && self.temperature_only_rows > 0).then(|| {
            format!(
                "{}: no gyro reading: all {} rows held a temperature and no gyro reading (is {option} the \
                 gyro's column?)",
                self.path.display(),
                self.temperature_only_rows
            )
        })
    }

    /// What the command line and Python say of temperature-only rows, naming the log, or
    /// `None` without any.
    pub fn temperature_only_note(&self) -> Option<String> {
        let n = self.temperature_only_rows;
        (n > 0).then(|| {
            format!(
                "{}: {n} row{} held a temperature and no gyro reading (channels logged on separate rows): each \
                 reading went with the next row that has one, as the firmware takes a reading with the next sample",
                self.path.display(),
                if n == 1 { "" } else { "s" }
            )
        })
    }

    /// What the command line and Python say of the skipped rows, before the list of the
    /// first ones: `skipped N bad rows of M rows (x %) (OPTION)`, and from
    /// [`MANY_SKIPPED_PERCENT`] on, to check the log (review24b S2: 36,001 of 72,001 rows
    /// skipped read like a few). `unit` names a row (`row`, or `sample` for arrays).
    pub fn skipped_summary(&self, unit: &str, option: &str) -> String {
        let read = self.rows + self.skipped;
        let share = 100.0 * self.skipped as f64 / read.max(1) as f64;
        let plural = |n: u64| if n == 1 { "" } else { "s" };
        // Said of whatever reads the rows (fit, validate, compensate, a read of arrays).
        let loud = if share >= MANY_SKIPPED_PERCENT {
            format!(" (check the input: this many bad {unit}s is no stray glitch, and only the rest is used)")
        } else {
            String::new()
        };
        format!(
            "skipped {} bad {unit}{} of {read} {unit}{} ({} %) ({option}){loud}",
            self.skipped,
            plural(self.skipped),
            plural(read),
            crate::calibrate::share_percent(self.skipped, read)
        )
    }
}

/// Options for [`read_log`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IngestOptions {
    /// Columns and units.
    pub format: LogFormat,
    /// Skip bad rows (and report them) instead of stopping at the first.
    pub skip_bad_rows: bool,
    /// Pass a temperature no sensor reads (a logger's -999) through as read instead of
    /// refusing its row, and a `NaN` or `inf` cell as an infinite one: for `compensate`,
    /// whose `Compensator` flags such a sample `BAD_INPUT` and keeps it, as the firmware
    /// does, so its output stays row for row.
    pub keep_impossible_temperatures: bool,
}

/// Bytes between two progress calls.
const PROGRESS_EVERY_BYTES: u64 = 4 << 20;
/// Logs at least this large are parsed in parallel (when there is a second core).
const PARALLEL_MIN_BYTES: u64 = 1 << 20;
/// Read buffer (grows only for a record longer than this).
const BUFFER_BYTES: usize = 1 << 20;
/// Rows per batch handed from the parser to the visitor.
const BATCH_ROWS: usize = 16 * 1024;
/// Bytes per chunk of the parallel reader (cut at the last newline).
const CHUNK_BYTES: usize = 1 << 20;
/// Parsing threads of the parallel reader, at most.
const MAX_WORKERS: usize = 4;

/// Reads the log at `path`, calling `visit` for every accepted row, in file order, on
/// the calling thread (a log of 1 MiB or more is parsed by worker threads meanwhile, when
/// there is more than one core). `progress` is called with the bytes read so far, about
/// every 4 MiB and once at the end.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be opened, [`CalError::Csv`] if reading it fails
/// or it has no header row, [`CalError::MissingColumn`] if a named column is absent,
/// [`CalError::BadRow`] for the first bad row (unless `skip_bad_rows`), or whatever error
/// the visitor returns (the read stops there).
pub fn read_log<F, P>(
    path: &Path,
    options: &IngestOptions,
    visit: F,
    mut progress: P,
) -> Result<IngestReport, CalError>
where
    F: FnMut(&Row<'_>) -> Result<(), CalError>,
    P: FnMut(u64),
{
    read_log_with_progress(path, options, visit, |bytes, _rows| progress(bytes))
}

/// A log's times and gyro columns in memory (what `allan` analyses).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GyroSeries {
    /// Sample times, s since the first accepted row.
    pub time_s: Vec<f64>,
    /// Gyro rates per axis, deg/h, one entry per row.
    pub gyros_dph: Vec<Vec<f64>>,
    /// What the read found (rows, skipped rows).
    pub report: IngestReport,
}

/// Reads `path` into a [`GyroSeries`], with `progress` as [`read_log_with_progress`].
///
/// # Errors
/// As [`read_log`].
pub fn read_gyro_series(
    path: &Path,
    options: &IngestOptions,
    progress: impl FnMut(u64, u64),
) -> Result<GyroSeries, CalError> {
    let mut time_s = Vec::new();
    let mut gyros_dph: Vec<Vec<f64>> = vec![Vec::new(); options.format.gyro_columns.len()];
    let report = read_log_with_progress(
        path,
        options,
        |row| {
            time_s.push(row.time_s);
            for (series, gyro) in gyros_dph.iter_mut().zip(row.gyros_dph) {
                series.push(*gyro);
            }
            Ok(())
        },
        progress,
    )?;
    Ok(GyroSeries { time_s, gyros_dph, report })
}

/// [`read_log`] with a progress callback that also gets the rows accepted so far:
/// `progress(bytes, rows)`, about every 4 MiB and once at the end (with
/// [`IngestReport::bytes`] and [`IngestReport::rows`]), enough for a bar showing bytes/s
/// and rows/s.
///
/// # Errors
/// As [`read_log`].
pub fn read_log_with_progress<F, P>(
    path: &Path,
    options: &IngestOptions,
    visit: F,
    progress: P,
) -> Result<IngestReport, CalError>
where
    F: FnMut(&Row<'_>) -> Result<(), CalError>,
    P: FnMut(u64, u64),
{
    let (file, tuning) = open_log(path)?;
    read_with_tuning(path, file, options, tuning, visit, progress)
}

/// [`read_log_with_progress`] that adds the log's bytes to `digest` as they are read (the
/// model's input digest, `docs/model-format.md`), so that the log is read once, and returns
/// the log's own digest beside the report. `digest` is left as it was when the read fails.
///
/// # Errors
/// As [`read_log`].
pub fn read_log_digested<F, P>(
    path: &Path,
    options: &IngestOptions,
    digest: &mut InputDigest,
    visit: F,
    progress: P,
) -> Result<(IngestReport, [u8; 32]), CalError>
where
    F: FnMut(&Row<'_>) -> Result<(), CalError>,
    P: FnMut(u64, u64),
{
    let (file, tuning) = open_log(path)?;
    let mut reader = digest.reading(file);
    let report = read_with_tuning(path, &mut reader, options, tuning, visit, progress)?;
    let log_digest = reader.finish().map_err(|source| CalError::Io { path: path.to_path_buf(), source })?;
    Ok((report, log_digest))
}

/// The log at `path`, opened, and how to read it: a log of 1 MiB or more by worker threads
/// when there is more than one core.
fn open_log(path: &Path) -> Result<(File, Tuning), CalError> {
    let file = File::open(path).map_err(|source| CalError::Io { path: path.to_path_buf(), source })?;
    let size = file.metadata().map_or(0, |m| m.len());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mode = if size >= PARALLEL_MIN_BYTES && cores >= 2 {
        Mode::Parallel { workers: cores.min(MAX_WORKERS) }
    } else {
        Mode::Single
    };
    Ok((file, Tuning { mode, ..Tuning::default() }))
}

/// [`read_log_with_progress`] from any reader (a socket, a decompressor, bytes in memory),
/// like `csv::Reader::from_reader` beside `from_path`. `name` stands for the source in
/// errors and in [`IngestReport::path`] (for example the file name the bytes came from).
/// The rows are parsed on the calling thread.
///
/// # Errors
/// As [`read_log`], with `name` as the file; [`CalError::Csv`] for a failing reader.
pub fn read_from<R, F, P>(
    reader: R,
    name: &Path,
    options: &IngestOptions,
    visit: F,
    progress: P,
) -> Result<IngestReport, CalError>
where
    R: Read + Send,
    F: FnMut(&Row<'_>) -> Result<(), CalError>,
    P: FnMut(u64, u64),
{
    read_with_tuning(name, reader, options, Tuning::default(), visit, progress)
}

/// [`read_from`] on bytes in memory through the parallel reader, as a log of 1 MiB or more is read, with its
/// chunks, read buffer and row batches shrunk to `chunk_bytes` (at least 1), so that small
/// inputs cross every boundary: for the fuzz target that checks it against the one-thread
/// reader (`fuzz/fuzz_targets/ingest_parallel.rs`). Not part of the API.
///
/// # Errors
/// As [`read_from`].
#[doc(hidden)]
pub fn read_from_in_chunks(
    bytes: &[u8],
    name: &Path,
    options: &IngestOptions,
    workers: usize,
    chunk_bytes: usize,
    visit: &mut dyn FnMut(&Row<'_>) -> Result<(), CalError>,
) -> Result<IngestReport, CalError> {
    let small = chunk_bytes.max(1);
    let tuning = Tuning {
        mode: Mode::Parallel { workers: workers.clamp(1, MAX_WORKERS) },
        buffer_bytes: small,
        batch_rows: small,
        chunk_bytes: small,
    };
    read_with_tuning(name, bytes, options, tuning, visit, |_, _| {})
}

/// How [`read_with_tuning`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// Everything on the calling thread.
    Single,
    /// The header on the calling thread, then chunks of whole records parsed by `workers`
    /// threads and merged, in order, on the calling thread (which runs the visitor).
    Parallel {
        /// Parsing threads.
        workers: usize,
    },
}

/// Internal knobs (the tests shrink them to exercise buffer, batch and chunk boundaries).
#[derive(Clone, Copy, Debug)]
struct Tuning {
    mode: Mode,
    buffer_bytes: usize,
    batch_rows: usize,
    chunk_bytes: usize,
}

impl Default for Tuning {
    fn default() -> Self {
        Self {
            mode: Mode::Single,
            buffer_bytes: BUFFER_BYTES,
            batch_rows: BATCH_ROWS,
            chunk_bytes: CHUNK_BYTES,
        }
    }
}

fn read_with_tuning<R, F, P>(
    path: &Path,
    reader: R,
    options: &IngestOptions,
    tuning: Tuning,
    mut visit: F,
    mut progress: P,
) -> Result<IngestReport, CalError>
where
    R: Read + Send,
    F: FnMut(&Row<'_>) -> Result<(), CalError>,
    P: FnMut(u64, u64),
{
    options.format.check(path)?;
    // Times from the record index need every record counted in order: one thread.
    let tuning = if options.format.sample_rate_hz.is_some() {
        Tuning { mode: Mode::Single, ..tuning }
    } else {
        tuning
    };
    let mut parser = Parser::new(path, reader, options, tuning.buffer_bytes);
    let temps = options.format.temp_columns.len();
    let mut consumer = Consumer {
        report: IngestReport { path: path.to_path_buf(), ..Default::default() },
        temps,
        stride: 1 + temps + options.format.gyro_columns.len(),
        last_progress: 0,
        pending_temps_c: Vec::new(),
        row_temps_c: Vec::new(),
        holds_temperatures: false,
    };
    let batch_rows = tuning.batch_rows.max(1);
    let mut batch = Batch::default();
    if let Mode::Parallel { workers } = tuning.mode {
        parser.header_only = true;
        parser.fill(&mut batch, batch_rows);
        parser.header_only = false;
        if batch.end.is_none() {
            return read_parallel(parser, consumer, tuning, workers.max(1), &mut visit, &mut progress);
        }
        // No header (an empty log, a missing column): `consume` reports it below.
    }
    loop {
        if consumer.consume(&mut batch, &mut visit, &mut progress)? {
            return Ok(consumer.report);
        }
        parser.fill(&mut batch, batch_rows);
    }
}

#[cfg(test)]
mod tests {
    use super::columns::{check_time, make_plan, parse_row, Previous};
    use super::parser::Fields;
    use super::test_support::*;
    use super::*;

    #[test]
    fn plain_log_values_and_lines() {
        let data = format!("{HEADER}10.000,25.0625,0.5\n10.001,25.1250,-0.25\n10.002,,1e-3\n");
        let v = values(&rows(&data, &default_options()));
        assert_eq!(v.len(), 3);
        assert_eq!((v[0].0, v[0].1, v[0].2[0], v[0].3[0]), (2, 0.0, 25.0625, 0.5));
        assert_eq!((v[1].0, v[1].2[0], v[1].3[0]), (3, 25.125, -0.25));
        assert_eq!(v[1].1, 10.001 - 10.0);
        assert_eq!(v[2].0, 4);
        assert!(v[2].2[0].is_nan(), "empty temperature cell is no reading");
        assert_eq!(v[2].3[0], 1e-3);
        let (_, report) = run(data.as_bytes(), &default_options());
        let report = report.unwrap();
        assert_eq!((report.rows, report.skipped, report.bytes), (3, 0, data.len() as u64));
        assert_eq!(report.time_origin_s, 10.0);
    }

    /// Every row carries the file's first accepted time (in every reading mode: `run`
    /// checks they agree), so `origin_s + time_s` is the row's own stamp; with a bad first
    /// row skipped, the first kept row's.
    #[test]
    fn rows_carry_the_files_time_origin() {
        let data = format!("{HEADER}12345.500,25.0,0.5\n12346.500,25.0,0.5\n12347.750,25.0,0.5\n");
        let seen = rows(&data, &default_options());
        let stamps: Vec<f64> =
            seen.iter().map(|s| f64::from_bits(s.origin) + f64::from_bits(s.time)).collect();
        assert_eq!(stamps, vec![12345.5, 12346.5, 12347.75]);
        let bad_first = format!("{HEADER}x,25.0,0.5\n12346.500,25.0,0.5\n12347.750,25.0,0.5\n");
        let seen = rows(&bad_first, &skipping());
        assert!(seen.iter().all(|s| f64::from_bits(s.origin) == 12346.5));
    }

    /// Epoch stamps in microseconds and milliseconds: `origin_s + time_s` is the f64 nearest
    /// the logged value in seconds (the logged integer divided by 1e6 or 1e3, correctly
    /// rounded; review20 F4: multiplying by 1e-6 was one step off in 95 of 300 rows).
    #[test]
    fn epoch_stamps_in_ms_and_us_read_as_the_nearest_seconds() {
        for (unit, per_second, first, step) in [
            (TimeUnit::Microseconds, 1e6, 1_700_007_200_001_234_i64, 1_000_013),
            (TimeUnit::Milliseconds, 1e3, 1_700_007_200_001, 1_003),
        ] {
            let logged: Vec<i64> = (0..300).map(|k| first + k * step).collect();
            let mut data = String::from("t,temp_c,gyro_dph\n");
            for t in &logged {
                data.push_str(&format!("{t},25.0,0.5\n"));
            }
            let format = LogFormat { time_column: "t".into(), time_unit: unit, ..LogFormat::default() };
            let seen = rows(&data, &IngestOptions { format, ..default_options() });
            let stamps: Vec<f64> =
                seen.iter().map(|s| f64::from_bits(s.origin) + f64::from_bits(s.time)).collect();
            let nearest: Vec<f64> = logged.iter().map(|&t| t as f64 / per_second).collect();
            assert_eq!(stamps, nearest, "{unit:?}");
        }
    }

    /// Elapsed time in minutes or hours (chamber controllers, review23b F1) reads as seconds:
    /// 1.25 min is 75 s exactly, 0.5 h is 1800 s; nanoseconds as ms and us are read.
    #[test]
    fn minutes_hours_and_nanoseconds_read_as_seconds() {
        for (unit, cells, seconds) in [
            (TimeUnit::Minutes, ["0", "0.25", "1.25"], [0.0, 15.0, 75.0]),
            (TimeUnit::Hours, ["0", "0.5", "2"], [0.0, 1800.0, 7200.0]),
            (TimeUnit::Nanoseconds, ["0", "500000000", "1250000000"], [0.0, 0.5, 1.25]),
        ] {
            let mut data = String::from("t,temp_c,gyro_dph\n");
            for t in cells {
                data.push_str(&format!("{t},25.0,0.5\n"));
            }
            let format = LogFormat { time_column: "t".into(), time_unit: unit, ..LogFormat::default() };
            let seen = rows(&data, &IngestOptions { format, ..default_options() });
            let stamps: Vec<f64> =
                seen.iter().map(|s| f64::from_bits(s.origin) + f64::from_bits(s.time)).collect();
            assert_eq!(stamps, seconds, "{unit:?}");
        }
    }

    #[test]
    fn read_log_reads_a_file() {
        let path = std::env::temp_dir().join(format!("fogtemp-ingest-test-{}.csv", std::process::id()));
        let mut data = String::from(HEADER);
        for i in 0..100_000 {
            data.push_str(&format!("{}.{:03},25.0625,0.123456\n", i / 1000, i % 1000));
        }
        std::fs::write(&path, &data).unwrap();
        let mut last = 0;
        let mut rows = 0;
        let report = read_log(
            &path,
            &default_options(),
            |_| {
                rows += 1;
                Ok(())
            },
            |bytes| last = bytes,
        );
        std::fs::remove_file(&path).unwrap();
        let report = report.unwrap();
        assert_eq!(
            (report.rows, rows, last, report.bytes),
            (100_000, 100_000, data.len() as u64, data.len() as u64)
        );
        let missing = read_log(Path::new("/nonexistent/log.csv"), &default_options(), |_| Ok(()), |_| {});
        assert!(matches!(missing, Err(CalError::Io { .. })));
    }

    /// The reader this module replaced (the `csv` crate), kept as the reference: same
    /// rows, same values, same errors. Its line numbers are off after blank lines and in
    /// CRLF files, so lines are compared only for files without those.
    fn reference(data: &[u8], options: &IngestOptions) -> Outcome {
        let mut seen = Vec::new();
        let result = (|| {
            let path = Path::new("log.csv");
            let mut reader =
                csv::ReaderBuilder::new().delimiter(b',').has_headers(true).flexible(true).from_reader(data);
            let header = reader.byte_headers().map_err(|e| CalError::Csv {
                path: path.into(),
                line: 0,
                message: e.to_string(),
            })?;
            let bounds: Vec<(usize, usize)> = {
                let mut start = 0;
                (0..header.len())
                    .map(|i| {
                        let end = start + header[i].len();
                        let b = (start, end);
                        start = end;
                        b
                    })
                    .collect()
            };
            let joined: Vec<u8> = header.iter().flatten().copied().collect();
            let format = LogFormat { delimiter: Delimiter::Byte(b','), ..options.format.clone() };
            let plan = make_plan(path, Fields { data: &joined, bounds: &bounds }, &format, 1)?;
            let mut report =
                IngestReport { path: path.into(), bytes: data.len() as u64, ..Default::default() };
            let mut temps = vec![f64::NAN; plan.columns.temps.len()];
            let mut gyros = vec![0.0; plan.columns.gyros.len()];
            let mut previous = Previous { any: None, sample: None };
            let mut held = vec![f64::NAN; temps.len()];
            let mut records = 0;
            let mut record = csv::ByteRecord::new();
            while reader.read_byte_record(&mut record).unwrap() {
                let line = record.position().map_or(0, |p| p.line());
                // A line of spaces or tabs (unquoted) is blank, as an empty one is.
                let at = record.position().map_or(0, |p| p.byte() as usize);
                // (The position may be that of blank lines the crate skipped before the record.)
                let raw = data.get(at..).unwrap_or_default();
                let raw = &raw[raw.iter().position(|&b| b != b'\n' && b != b'\r').unwrap_or(raw.len())..];
                let raw_line =
                    &raw[..raw.iter().position(|&b| b == b'\n' || b == b'\r').unwrap_or(raw.len())];
                if raw_line.trim_ascii().is_empty() {
                    continue;
                }
                let mut bounds = Vec::new();
                let mut start = 0;
                for f in record.iter() {
                    bounds.push((start, start + f.len()));
                    start += f.len();
                }
                let joined: Vec<u8> = record.iter().flatten().copied().collect();
                let fields = Fields { data: &joined, bounds: &bounds };
                let parsed = parse_row(fields, &plan, line, records, &mut temps, &mut gyros);
                let sample = !gyros[0].is_nan();
                let parsed =
                    parsed.and_then(|time| check_time(time, previous, sample, &plan.columns, line, fields));
                records += 1;
                match parsed {
                    Ok(time) => {
                        if previous.sample.is_none() && sample {
                            report.time_origin_s = time;
                        }
                        previous.any = Some(time);
                        if let Some(&t) = temps.first().filter(|t| !t.is_nan()) {
                            report.temp_ends_c.get_or_insert((t, t)).1 = t;
                        }
                        if !sample {
                            // A temperature-only row: its readings go with the next sample.
                            report.temperature_only_rows += 1;
                            for (h, &t) in held.iter_mut().zip(&temps) {
                                if !t.is_nan() {
                                    *h = t;
                                }
                            }
                            continue;
                        }
                        previous.sample = Some(time);
                        for (t, h) in temps.iter_mut().zip(held.iter_mut()) {
                            if t.is_nan() {
                                *t = *h;
                            }
                            *h = f64::NAN;
                        }
                        report.rows += 1;
                        report.last_time_s = time - report.time_origin_s;
                        seen.push(Seen::of(&Row {
                            line,
                            time_s: time - report.time_origin_s,
                            origin_s: report.time_origin_s,
                            temps_c: &temps,
                            gyros_dph: &gyros,
                        }));
                    }
                    Err(bad) if options.skip_bad_rows => {
                        report.skipped += 1;
                        if report.first_skipped.len() < MAX_REPORTED_BAD_ROWS {
                            report.first_skipped.push(bad);
                        }
                    }
                    Err(bad) => return Err(CalError::BadRow { path: path.into(), row: Box::new(bad) }),
                }
            }
            Ok(report)
        })();
        (seen, result)
    }

    /// Cells that exercise every path: plain decimals, other spellings, bad values,
    /// quotes (with delimiters and newlines inside), spaces, empties.
    const CELLS: [&str; 28] = [
        "",
        " ",
        "0",
        "1.5",
        "-2.25",
        "25.0625",
        "0.000001",
        "1e2",
        "1E-2",
        " 3 ",
        "x",
        "nan",
        "inf",
        "-",
        ".",
        "7.",
        ".7",
        "+8",
        "\"4\"",
        "\"5,5\"",
        "\"6\n\"",
        "\"a\"\"b\"",
        "9\"",
        "12345678901234567",
        "0.12345678901234567",
        "1e999",
        "--1",
        "1.2.3",
    ];

    fn random_log(seed: u64) -> (Vec<u8>, IngestOptions, bool) {
        let mut state = seed | 1;
        let mut next = move |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        };
        let mut names = ["time_s", "temp_c", "gyro_dph", "note"];
        for i in (1..names.len()).rev() {
            names.swap(i, next(i as u64 + 1) as usize);
        }
        let terminators = ["\n", "\n", "\n", "\r\n", "\r"];
        let terminator = terminators[next(5) as usize];
        let mut data = Vec::new();
        if next(4) == 0 {
            data.extend_from_slice("\u{feff}".as_bytes());
        }
        let quote_header = next(4) == 0;
        let header: Vec<String> =
            names.iter().map(|n| if quote_header { format!("\"{n}\"") } else { (*n).to_string() }).collect();
        data.extend_from_slice(header.join(",").as_bytes());
        let mut time = 0.0f64;
        let rows = next(40);
        for _ in 0..rows {
            data.extend_from_slice(terminator.as_bytes());
            if next(10) == 0 {
                data.extend_from_slice(terminator.as_bytes());
            }
            let fields = if next(12) == 0 { next(4) as usize } else { 4 };
            let mut cells = Vec::new();
            for name in names.iter().take(fields) {
                let mostly_good = next(6) != 0;
                let cell = match *name {
                    "time_s" if mostly_good => {
                        time += [0.001, 0.25, 1.0, 0.0, -0.5][next(5) as usize];
                        let spelled = format!("{time:.3}");
                        if next(8) == 0 {
                            format!("\"{spelled}\"")
                        } else {
                            spelled
                        }
                    }
                    "temp_c" | "gyro_dph" if mostly_good => format!("{}.{:04}", next(80), next(10_000)),
                    _ => CELLS[next(CELLS.len() as u64) as usize].to_string(),
                };
                cells.push(cell);
            }
            data.extend_from_slice(cells.join(",").as_bytes());
        }
        if next(2) == 0 {
            data.extend_from_slice(terminator.as_bytes());
        }
        let options = IngestOptions { skip_bad_rows: next(2) == 0, ..IngestOptions::default() };
        let blank_lines = data.windows(2).any(|w| w == b"\n\n" || w == b"\r\r" || w == b"\r\n");
        let compare_lines = !blank_lines && !data.contains(&b'\r');
        (data, options, compare_lines)
    }

    #[test]
    fn agrees_with_the_csv_crate_reader_on_random_logs() {
        for seed in 1..1500u64 {
            let (data, options, compare_lines) = random_log(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15));
            let text = String::from_utf8_lossy(&data).into_owned();
            let (mut ours, mut our_result) = run(&data, &options);
            let (mut theirs, mut their_result) = reference(&data, &options);
            if !compare_lines {
                for s in ours.iter_mut().chain(theirs.iter_mut()) {
                    s.line = 0;
                }
                for r in [&mut our_result, &mut their_result] {
                    match r {
                        Ok(report) => report.first_skipped.iter_mut().for_each(|b| b.line = 0),
                        Err(CalError::BadRow { row, .. }) => row.line = 0,
                        Err(_) => {}
                    }
                }
            }
            assert_eq!(ours, theirs, "rows differ for {text:?}");
            assert_eq!(summary(&our_result), summary(&their_result), "result differs for {text:?}");
        }
    }

    /// The digest taken while reading (one read of each log) is SHA-256 of the bytes, the
    /// same as a separate read of the files gives (`digest::digests_of_files`, itself checked
    /// against FIPS 180-2), for a small log and one of more than 1 MiB (read by worker threads
    /// when there are two cores); a read that fails, or that its visitor stops, leaves the
    /// digest as it was.
    #[test]
    fn the_digest_taken_while_reading_is_the_files_sha256() {
        let dir = tempfile::tempdir().expect("tempdir");
        let small = dir.path().join("small.csv");
        let large = dir.path().join("large.csv");
        let bad = dir.path().join("bad.csv");
        std::fs::write(&small, format!("{HEADER}0.0,25.0,0.5\n1.0,25.5,-0.25")).expect("write");
        let mut text = String::from(HEADER);
        for i in 0..(1 << 16) {
            text.push_str(&format!(
                "{}.{:03},{:.4},{:.6}\n",
                i / 1000,
                i % 1000,
                20.0 + f64::from(i) * 1e-4,
                0.5
            ));
        }
        assert!(text.len() as u64 > PARALLEL_MIN_BYTES);
        std::fs::write(&large, &text).expect("write");
        std::fs::write(&bad, format!("{HEADER}0.0,25.0,0.5\n1.0,x,0.5\n")).expect("write");
        let options = default_options();
        let mut digest = InputDigest::new();
        let mut own = Vec::new();
        for log in [&small, &large] {
            let (report, one) =
                read_log_digested(log, &options, &mut digest, |_| Ok(()), |_, _| {}).expect("reads");
            assert!(report.rows > 0);
            own.push(one);
        }
        let failed = read_log_digested(&bad, &options, &mut digest, |_| Ok(()), |_, _| {});
        assert!(matches!(failed, Err(CalError::BadRow { .. })), "{:?}", failed.map(|r| r.0.rows));
        let stopped = read_log_digested(
            &large,
            &options,
            &mut digest,
            |row| {
                if row.line > 100 {
                    Err(CalError::Io {
                        path: PathBuf::from("visitor"),
                        source: std::io::Error::other("stop"),
                    })
                } else {
                    Ok(())
                }
            },
            |_, _| {},
        );
        assert!(stopped.is_err());
        let (all, each) = digest.finish();
        let (want_all, want_each) = crate::digest::digests_of_files(&[small, large]).expect("digests");
        assert_eq!((all, &each), (want_all, &want_each));
        assert_eq!(own, want_each);
    }
}
