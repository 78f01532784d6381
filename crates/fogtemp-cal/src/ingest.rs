//! Streaming CSV ingest of lab logs (one file per run; contract in DESIGN section 3).
//!
//! Rows are parsed into a reused buffer and handed to a visitor one at a time, so memory
//! stays constant whatever the log size. Every rejected row is reported with its file,
//! line and column; with `skip_bad_rows` the rows are skipped and counted instead.

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::CalError;

/// Unit of the time column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeUnit {
    /// Seconds.
    Seconds,
    /// Milliseconds.
    Milliseconds,
    /// Microseconds.
    Microseconds,
}

impl TimeUnit {
    /// Seconds per unit.
    pub fn seconds(self) -> f64 {
        match self {
            TimeUnit::Seconds => 1.0,
            TimeUnit::Milliseconds => 1.0e-3,
            TimeUnit::Microseconds => 1.0e-6,
        }
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
    /// Field delimiter.
    pub delimiter: u8,
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
            delimiter: b',',
        }
    }
}

/// One parsed row, borrowed from the reader's buffers (valid during the visitor call).
#[derive(Clone, Copy, Debug)]
pub struct Row<'a> {
    /// 1-based line number in the file.
    pub line: u64,
    /// Time since the first row of the file, seconds.
    pub time_s: f64,
    /// Temperatures, deg C, one per temperature column; NaN where the cell is empty
    /// (sensors slower than the gyro leave cells empty).
    pub temps_c: &'a [f64],
    /// Gyro rates, deg/h, one per gyro column.
    pub gyros_dph: &'a [f64],
}

/// Why a row was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum BadRowKind {
    /// A cell is not a number.
    NotANumber,
    /// A cell is NaN or infinite.
    NonFinite,
    /// Fewer fields than the header.
    ShortRow,
    /// Time equal to the previous row's.
    DuplicateTime,
    /// Time before the previous row's.
    BackwardTime,
    /// A required cell (time or gyro) is empty.
    EmptyCell,
}

impl BadRowKind {
    /// Short description for reports.
    pub fn describe(self) -> &'static str {
        match self {
            BadRowKind::NotANumber => "not a number",
            BadRowKind::NonFinite => "NaN or infinite",
            BadRowKind::ShortRow => "fewer fields than the header",
            BadRowKind::DuplicateTime => "time equal to the previous row",
            BadRowKind::BackwardTime => "time before the previous row",
            BadRowKind::EmptyCell => "empty required cell",
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
}

/// How many skipped rows are listed individually.
pub const MAX_REPORTED_BAD_ROWS: usize = 20;

/// Options for [`read_log`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IngestOptions {
    /// Columns and units.
    pub format: LogFormat,
    /// Skip bad rows (and report them) instead of stopping at the first.
    pub skip_bad_rows: bool,
}

struct Columns {
    time: usize,
    temps: Vec<usize>,
    gyros: Vec<usize>,
    names: Vec<String>,
    min_fields: usize,
}

/// Reads the log at `path`, calling `visit` for every accepted row, in file order.
/// `progress` is called with the bytes read so far, about every 4 MiB.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be read, [`CalError::MissingColumn`] if a named
/// column is absent, [`CalError::BadRow`] for the first bad row (unless `skip_bad_rows`),
/// or whatever error the visitor returns.
pub fn read_log<F, P>(
    path: &Path,
    options: &IngestOptions,
    mut visit: F,
    mut progress: P,
) -> Result<IngestReport, CalError>
where
    F: FnMut(&Row<'_>) -> Result<(), CalError>,
    P: FnMut(u64),
{
    let io = |source| CalError::Io { path: path.to_path_buf(), source };
    let file = File::open(path).map_err(io)?;
    let counting = CountingReader { inner: file, bytes: 0 };
    let mut reader = csv::ReaderBuilder::new()
        .delimiter(options.format.delimiter)
        .has_headers(true)
        .flexible(true)
        .buffer_capacity(1 << 20)
        .from_reader(counting);
    let header = reader.byte_headers().map_err(|e| csv_error(path, e))?.clone();
    let columns = locate_columns(path, &header, &options.format)?;

    let f = &options.format;
    let time_factor = f.time_unit.seconds();
    let gyro_factor = f.gyro_unit.dph() * f.gyro_scale;
    let mut report = IngestReport { path: path.to_path_buf(), ..Default::default() };
    let mut temps = vec![f64::NAN; columns.temps.len()];
    let mut gyros = vec![0.0; columns.gyros.len()];
    let mut record = csv::ByteRecord::new();
    let mut previous_time: Option<f64> = None;
    let mut last_progress = 0u64;
    loop {
        match reader.read_byte_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_error(path, e)),
        }
        let line = record.position().map_or(0, |p| p.line());
        let parsed = parse_row(&record, &columns, line, time_factor, gyro_factor, f, &mut temps, &mut gyros)
            .and_then(|time| check_time(time, previous_time, &columns, line, &record));
        match parsed {
            Ok(time) => {
                if previous_time.is_none() {
                    report.time_origin_s = time;
                }
                previous_time = Some(time);
                report.rows += 1;
                visit(&Row {
                    line,
                    time_s: time - report.time_origin_s,
                    temps_c: &temps,
                    gyros_dph: &gyros,
                })?;
            }
            Err(bad) if options.skip_bad_rows => {
                report.skipped += 1;
                if report.first_skipped.len() < MAX_REPORTED_BAD_ROWS {
                    report.first_skipped.push(bad);
                }
            }
            Err(bad) => return Err(CalError::BadRow { path: path.to_path_buf(), row: Box::new(bad) }),
        }
        let bytes = reader.get_ref().bytes;
        if bytes - last_progress >= 4 << 20 {
            progress(bytes);
            last_progress = bytes;
        }
    }
    report.bytes = reader.get_ref().bytes;
    progress(report.bytes);
    Ok(report)
}

fn csv_error(path: &Path, e: csv::Error) -> CalError {
    let line = e.position().map_or(0, |p| p.line());
    CalError::Csv { path: path.to_path_buf(), line, message: e.to_string() }
}

fn locate_columns(path: &Path, header: &csv::ByteRecord, f: &LogFormat) -> Result<Columns, CalError> {
    let names: Vec<String> = header
        .iter()
        .map(|h| String::from_utf8_lossy(h).trim().trim_start_matches('\u{feff}').to_string())
        .collect();
    let find = |wanted: &str| {
        names.iter().position(|n| n == wanted).ok_or_else(|| CalError::MissingColumn {
            path: path.to_path_buf(),
            column: wanted.to_string(),
            available: names.join(", "),
        })
    };
    let time = find(&f.time_column)?;
    let temps = f.temp_columns.iter().map(|c| find(c)).collect::<Result<Vec<_>, _>>()?;
    let gyros = f.gyro_columns.iter().map(|c| find(c)).collect::<Result<Vec<_>, _>>()?;
    if gyros.is_empty() {
        return Err(CalError::MissingColumn {
            path: path.to_path_buf(),
            column: "(no gyro column named)".into(),
            available: names.join(", "),
        });
    }
    let min_fields = temps.iter().chain(&gyros).copied().chain([time]).max().unwrap_or(0) + 1;
    Ok(Columns { time, temps, gyros, names, min_fields })
}

fn bad_row(columns: &Columns, line: u64, field: usize, found: &[u8], kind: BadRowKind) -> BadRow {
    let text = String::from_utf8_lossy(found);
    BadRow {
        line,
        column: field + 1,
        column_name: columns.names.get(field).cloned().unwrap_or_default(),
        found: text.chars().take(40).collect(),
        kind,
    }
}

/// Parses one numeric cell; `Ok(None)` for an empty cell.
fn parse_cell(
    columns: &Columns,
    record: &csv::ByteRecord,
    field: usize,
    line: u64,
) -> Result<Option<f64>, BadRow> {
    let raw = record.get(field).unwrap_or(b"");
    let trimmed = raw.trim_ascii();
    if trimmed.is_empty() {
        return Ok(None);
    }
    match fast_float2::parse::<f64, _>(trimmed) {
        Ok(v) if v.is_finite() => Ok(Some(v)),
        Ok(_) => Err(bad_row(columns, line, field, raw, BadRowKind::NonFinite)),
        Err(_) => Err(bad_row(columns, line, field, raw, BadRowKind::NotANumber)),
    }
}

#[allow(clippy::too_many_arguments)]
fn parse_row(
    record: &csv::ByteRecord,
    columns: &Columns,
    line: u64,
    time_factor: f64,
    gyro_factor: f64,
    f: &LogFormat,
    temps: &mut [f64],
    gyros: &mut [f64],
) -> Result<f64, BadRow> {
    if record.len() < columns.min_fields {
        let field = record.len();
        return Err(bad_row(
            columns,
            line,
            field.min(columns.names.len().saturating_sub(1)),
            b"",
            BadRowKind::ShortRow,
        ));
    }
    let required = |field: usize| -> Result<f64, BadRow> {
        parse_cell(columns, record, field, line)?
            .ok_or_else(|| bad_row(columns, line, field, b"", BadRowKind::EmptyCell))
    };
    let time = required(columns.time)? * time_factor;
    for (slot, &field) in gyros.iter_mut().zip(&columns.gyros) {
        *slot = required(field)? * gyro_factor;
    }
    for (slot, &field) in temps.iter_mut().zip(&columns.temps) {
        *slot = parse_cell(columns, record, field, line)?
            .map_or(f64::NAN, |raw| raw * f.temp_scale + f.temp_offset_c);
    }
    Ok(time)
}

fn check_time(
    time: f64,
    previous: Option<f64>,
    columns: &Columns,
    line: u64,
    record: &csv::ByteRecord,
) -> Result<f64, BadRow> {
    match previous {
        Some(p) if time == p => Err(bad_row(
            columns,
            line,
            columns.time,
            record.get(columns.time).unwrap_or(b""),
            BadRowKind::DuplicateTime,
        )),
        Some(p) if time < p => Err(bad_row(
            columns,
            line,
            columns.time,
            record.get(columns.time).unwrap_or(b""),
            BadRowKind::BackwardTime,
        )),
        _ => Ok(time),
    }
}

struct CountingReader<R> {
    inner: R,
    bytes: u64,
}

impl<R: Read> Read for CountingReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }
}
