//! Streaming CSV ingest of lab logs (one file per run; contract in DESIGN section 3).
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
//! before, so errors and values are the same either way. On logs over 1 MiB, when a
//! second core is available, one thread reads and parses into batches of rows while the
//! calling thread runs the visitor.

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::mpsc;

use memchr::{memchr, memchr2, memchr_iter};

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

/// Bytes between two progress calls.
const PROGRESS_EVERY_BYTES: u64 = 4 << 20;
/// Logs at least this large are parsed on a second thread (when there is a second core).
const THREADED_MIN_BYTES: u64 = 1 << 20;
/// Read buffer (grows only for a record longer than this).
const BUFFER_BYTES: usize = 1 << 20;
/// Rows per batch handed from the parser to the visitor.
const BATCH_ROWS: usize = 16 * 1024;
/// Parsed batches queued between the two threads.
const QUEUE_BATCHES: usize = 2;
/// The UTF-8 byte-order mark.
const BOM: &[u8] = b"\xef\xbb\xbf";

/// Reads the log at `path`, calling `visit` for every accepted row, in file order.
/// `progress` is called with the bytes read so far, about every 4 MiB and once at the end.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be read, [`CalError::MissingColumn`] if a named
/// column is absent, [`CalError::BadRow`] for the first bad row (unless `skip_bad_rows`),
/// or whatever error the visitor returns.
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
    let file = File::open(path).map_err(|source| CalError::Io { path: path.to_path_buf(), source })?;
    let size = file.metadata().map_or(0, |m| m.len());
    let threaded =
        size >= THREADED_MIN_BYTES && std::thread::available_parallelism().is_ok_and(|n| n.get() >= 2);
    let tuning = Tuning { threaded, ..Tuning::default() };
    read_from(path, file, options, tuning, visit, progress)
}

/// Internal knobs (the tests shrink them to exercise buffer and batch boundaries).
#[derive(Clone, Copy, Debug)]
struct Tuning {
    threaded: bool,
    buffer_bytes: usize,
    batch_rows: usize,
}

impl Default for Tuning {
    fn default() -> Self {
        Self { threaded: false, buffer_bytes: BUFFER_BYTES, batch_rows: BATCH_ROWS }
    }
}

fn read_from<R, F, P>(
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
    let mut parser = Parser::new(path, reader, options, tuning.buffer_bytes);
    let mut consumer = Consumer {
        report: IngestReport { path: path.to_path_buf(), ..Default::default() },
        temps: options.format.temp_columns.len(),
        stride: 1 + options.format.temp_columns.len() + options.format.gyro_columns.len(),
        last_progress: 0,
    };
    let batch_rows = tuning.batch_rows.max(1);
    if !tuning.threaded {
        let mut batch = Batch::default();
        loop {
            parser.fill(&mut batch, batch_rows);
            if consumer.consume(&mut batch, &mut visit, &mut progress)? {
                return Ok(consumer.report);
            }
        }
    }
    std::thread::scope(|scope| {
        let (full_tx, full_rx) = mpsc::sync_channel::<Batch>(QUEUE_BATCHES);
        let (empty_tx, empty_rx) = mpsc::channel::<Batch>();
        std::thread::Builder::new()
            .name("fogtemp-ingest".into())
            .spawn_scoped(scope, move || loop {
                let mut batch = empty_rx.try_recv().unwrap_or_default();
                parser.fill(&mut batch, batch_rows);
                let ended = batch.end.is_some();
                // A closed channel means the visitor stopped early: nothing more to do.
                if full_tx.send(batch).is_err() || ended {
                    break;
                }
            })
            .map_err(|source| CalError::Io { path: path.to_path_buf(), source })?;
        // Returning drops `full_rx`, which unblocks and ends the parser thread.
        for mut batch in full_rx.iter() {
            if consumer.consume(&mut batch, &mut visit, &mut progress)? {
                return Ok(consumer.report);
            }
            // The parser may already be gone (it sends nothing after the end).
            let _ = empty_tx.send(batch);
        }
        // Only if the parser thread panicked; the scope re-raises that panic.
        Err(CalError::Csv { path: path.to_path_buf(), line: 0, message: "ingest thread failed".into() })
    })
}

/// Rows parsed but not yet visited, and how the log ended if it did.
#[derive(Debug, Default)]
struct Batch {
    /// Per row: time (s, relative), temperatures, gyros.
    values: Vec<f64>,
    /// Per row: its line.
    lines: Vec<u64>,
    /// File offset after the last record parsed.
    bytes: u64,
    /// `Some` once the log has ended (summary) or failed.
    end: Option<Result<Tail, CalError>>,
}

/// The parser's share of the report.
#[derive(Debug)]
struct Tail {
    bytes: u64,
    skipped: u64,
    first_skipped: Vec<BadRow>,
    time_origin_s: f64,
}

/// The calling thread's side: visits rows, reports progress, builds the report.
struct Consumer {
    report: IngestReport,
    temps: usize,
    stride: usize,
    last_progress: u64,
}

impl Consumer {
    /// Visits the batch's rows; `Ok(true)` once the log has ended.
    fn consume<F, P>(&mut self, batch: &mut Batch, visit: &mut F, progress: &mut P) -> Result<bool, CalError>
    where
        F: FnMut(&Row<'_>) -> Result<(), CalError>,
        P: FnMut(u64, u64),
    {
        let split = 1 + self.temps;
        for (values, &line) in batch.values.chunks_exact(self.stride).zip(&batch.lines) {
            visit(&Row { line, time_s: values[0], temps_c: &values[1..split], gyros_dph: &values[split..] })?;
        }
        self.report.rows += batch.lines.len() as u64;
        match batch.end.take() {
            None => {
                if batch.bytes - self.last_progress >= PROGRESS_EVERY_BYTES {
                    progress(batch.bytes, self.report.rows);
                    self.last_progress = batch.bytes;
                }
                Ok(false)
            }
            Some(Ok(tail)) => {
                self.report.bytes = tail.bytes;
                self.report.skipped = tail.skipped;
                self.report.first_skipped = tail.first_skipped;
                self.report.time_origin_s = tail.time_origin_s;
                progress(self.report.bytes, self.report.rows);
                Ok(true)
            }
            Some(Err(e)) => Err(e),
        }
    }
}

/// The file, a window of it in memory, and where parsing is.
struct Source<R> {
    reader: R,
    buf: Vec<u8>,
    /// Next byte to parse.
    pos: usize,
    /// End of the valid data in `buf`.
    end: usize,
    eof: bool,
    /// File offset of `buf[0]`.
    base: u64,
    /// 1-based line of `buf[pos]`.
    line: u64,
}

impl<R: Read> Source<R> {
    /// Reads more, keeping `buf[pos..end]` (moved to the front; the buffer doubles only
    /// when one record fills it).
    fn refill(&mut self) -> std::io::Result<()> {
        if self.pos > 0 {
            self.buf.copy_within(self.pos..self.end, 0);
            self.base += self.pos as u64;
            self.end -= self.pos;
            self.pos = 0;
        }
        if self.end == self.buf.len() {
            let grown = (self.buf.len() * 2).max(64);
            self.buf.resize(grown, 0);
        }
        loop {
            match self.reader.read(&mut self.buf[self.end..]) {
                Ok(0) => {
                    self.eof = true;
                    return Ok(());
                }
                Ok(n) => {
                    self.end += n;
                    return Ok(());
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    fn offset(&self) -> u64 {
        self.base + self.pos as u64
    }

    /// Skips record terminators (blank lines), counting lines.
    fn skip_terminators(&mut self) {
        while let Some(&b) = self.buf[..self.end].get(self.pos) {
            match b {
                b'\n' => self.line += 1,
                b'\r' => {}
                _ => break,
            }
            self.pos += 1;
        }
    }
}

/// A record's fields: `data[start..end]` for each `(start, end)`.
#[derive(Clone, Copy)]
struct Fields<'a> {
    data: &'a [u8],
    bounds: &'a [(usize, usize)],
}

impl<'a> Fields<'a> {
    fn len(&self) -> usize {
        self.bounds.len()
    }

    fn get(&self, field: usize) -> Option<&'a [u8]> {
        self.bounds.get(field).and_then(|&(s, e)| self.data.get(s..e))
    }
}

/// A quoted record being read by `csv-core` (it may span buffer refills).
struct Quoted {
    line: u64,
    out_len: usize,
    ends_len: usize,
}

enum Flow {
    Continue,
    NeedMore,
}

/// Reads records and turns them into rows (runs on the parser thread when threaded).
struct Parser<R> {
    path: PathBuf,
    src: Source<R>,
    delimiter: u8,
    /// The one-pass path is usable (header read, and a delimiter no number contains).
    fast: bool,
    /// Every record goes through `csv-core` (a delimiter that is a quote or terminator).
    core_only: bool,
    bom_checked: bool,
    core: csv_core::Reader,
    quoted: Option<Quoted>,
    out: Vec<u8>,
    ends: Vec<usize>,
    bounds: Vec<(usize, usize)>,
    rows: RowState,
}

impl<R: Read> Parser<R> {
    fn new(path: &Path, reader: R, options: &IngestOptions, buffer_bytes: usize) -> Self {
        let delimiter = options.format.delimiter;
        let mut core = csv_core::ReaderBuilder::new().delimiter(delimiter).build();
        // Prime it so that it never strips a byte-order mark from a record mid-file
        // (the file's own mark is skipped before any record).
        let _ = core.read_record(b"\n", &mut [0u8; 1], &mut [0usize; 1]);
        Self {
            path: path.to_path_buf(),
            src: Source {
                reader,
                buf: vec![0; buffer_bytes.max(4)],
                pos: 0,
                end: 0,
                eof: false,
                base: 0,
                line: 1,
            },
            delimiter,
            fast: false,
            core_only: matches!(delimiter, b'"' | b'\r' | b'\n'),
            bom_checked: false,
            core,
            quoted: None,
            out: vec![0; 256],
            ends: vec![0; 16],
            bounds: Vec::new(),
            rows: RowState::new(path, options),
        }
    }

    /// Parses rows into `batch` (cleared first) until it holds `max_rows` rows or the log
    /// ends or fails (`batch.end` set).
    fn fill(&mut self, batch: &mut Batch, max_rows: usize) {
        batch.values.clear();
        batch.lines.clear();
        batch.end = None;
        match self.fill_rows(batch, max_rows) {
            Ok(false) => {}
            Ok(true) => {
                batch.end = Some(Ok(Tail {
                    bytes: self.src.base + self.src.end as u64,
                    skipped: self.rows.skipped,
                    first_skipped: std::mem::take(&mut self.rows.first_skipped),
                    time_origin_s: self.rows.origin.unwrap_or(0.0),
                }));
            }
            Err(e) => batch.end = Some(Err(e)),
        }
        batch.bytes = self.src.offset();
    }

    /// `Ok(true)` at the end of the log.
    fn fill_rows(&mut self, batch: &mut Batch, max_rows: usize) -> Result<bool, CalError> {
        if !self.bom_checked {
            while self.src.end < BOM.len() && !self.src.eof {
                self.refill()?;
            }
            if self.src.buf[..self.src.end].starts_with(BOM) {
                self.src.pos = BOM.len();
            }
            self.bom_checked = true;
        }
        while batch.lines.len() < max_rows {
            let flow = if self.quoted.is_some() {
                self.quoted_step(batch)?
            } else {
                if self.fast {
                    self.fast_rows(batch, max_rows);
                    if batch.lines.len() >= max_rows {
                        break;
                    }
                }
                self.src.skip_terminators();
                if self.src.pos == self.src.end {
                    if self.src.eof {
                        return Ok(true);
                    }
                    Flow::NeedMore
                } else {
                    self.general_record(batch)?
                }
            };
            if let Flow::NeedMore = flow {
                self.refill()?;
            }
        }
        Ok(false)
    }

    fn refill(&mut self) -> Result<(), CalError> {
        self.src.refill().map_err(|e| CalError::Csv {
            path: self.path.clone(),
            line: self.src.line,
            message: e.to_string(),
        })
    }

    /// The one-pass path, over as many records as it can take; stops (leaving `pos` at
    /// the record's start) at the first record it cannot, for `general_record`.
    fn fast_rows(&mut self, batch: &mut Batch, max_rows: usize) {
        let RowState { plan: Some(plan), values, previous_time, origin, .. } = &mut self.rows else {
            return;
        };
        let buf = &self.src.buf[..self.src.end];
        let (mut pos, mut line) = (self.src.pos, self.src.line);
        let mut count = batch.lines.len();
        loop {
            while let Some(&b) = buf.get(pos) {
                match b {
                    b'\n' => line += 1,
                    b'\r' => {}
                    _ => break,
                }
                pos += 1;
            }
            if count >= max_rows {
                break;
            }
            let Some(terminator) = fast_fields(buf, pos, self.delimiter, &plan.roles, values) else {
                break;
            };
            let raw_time = values[plan.time_slot];
            if raw_time.is_nan() || plan.gyro_slots.iter().any(|&k| values[k].is_nan()) {
                break; // an empty required cell: the general path reports it
            }
            let time = raw_time * plan.time_factor;
            if previous_time.is_some_and(|p| time <= p) {
                break; // duplicate or backward time: likewise
            }
            let time_origin = *origin.get_or_insert(time);
            *previous_time = Some(time);
            batch.lines.push(line);
            batch.values.push(time - time_origin);
            for &k in &plan.temp_slots {
                let raw = values[k];
                batch.values.push(if raw.is_nan() {
                    f64::NAN
                } else {
                    raw * plan.temp_scale + plan.temp_offset_c
                });
            }
            for &k in &plan.gyro_slots {
                batch.values.push(values[k] * plan.gyro_factor);
            }
            count += 1;
            pos = terminator;
        }
        self.src.pos = pos;
        self.src.line = line;
    }

    /// One record (at `pos`, not a terminator) by the general path.
    fn general_record(&mut self, batch: &mut Batch) -> Result<Flow, CalError> {
        let start = self.src.pos;
        let rest = &self.src.buf[start..self.src.end];
        let len = match memchr2(b'\n', b'\r', rest) {
            Some(len) if !self.core_only => len,
            None if self.src.eof && !self.core_only => rest.len(),
            _ if self.core_only => {
                self.quoted = Some(Quoted { line: self.src.line, out_len: 0, ends_len: 0 });
                return Ok(Flow::Continue);
            }
            _ => return Ok(Flow::NeedMore),
        };
        let record = &rest[..len];
        if memchr(b'"', record).is_some() {
            self.quoted = Some(Quoted { line: self.src.line, out_len: 0, ends_len: 0 });
            return Ok(Flow::Continue);
        }
        self.bounds.clear();
        let mut field_start = start;
        for i in memchr_iter(self.delimiter, record) {
            self.bounds.push((field_start, start + i));
            field_start = start + i + 1;
        }
        self.bounds.push((field_start, start + len));
        self.src.pos = start + len;
        let fields = Fields { data: &self.src.buf, bounds: &self.bounds };
        self.rows.record(fields, self.src.line, batch)?;
        self.fast = self.rows.plan.as_ref().is_some_and(|p| p.fast) && !self.core_only;
        Ok(Flow::Continue)
    }

    /// Feeds the quoted record in progress to `csv-core`.
    fn quoted_step(&mut self, batch: &mut Batch) -> Result<Flow, CalError> {
        use csv_core::ReadRecordResult as R;
        let Some(q) = self.quoted.as_mut() else { return Ok(Flow::Continue) };
        loop {
            let input = &self.src.buf[self.src.pos..self.src.end];
            let (result, read, written, ended) =
                self.core.read_record(input, &mut self.out[q.out_len..], &mut self.ends[q.ends_len..]);
            self.src.line += memchr_iter(b'\n', &input[..read]).count() as u64;
            self.src.pos += read;
            q.out_len += written;
            q.ends_len += ended;
            match result {
                R::InputEmpty if input.is_empty() => {
                    // Cannot happen (empty input is the end, answered by Record or End).
                    self.quoted = None;
                    return Ok(Flow::Continue);
                }
                R::InputEmpty if self.src.eof => {}
                R::InputEmpty => return Ok(Flow::NeedMore),
                R::OutputFull => {
                    let grown = self.out.len() * 2;
                    self.out.resize(grown, 0);
                }
                R::OutputEndsFull => {
                    let grown = self.ends.len() * 2;
                    self.ends.resize(grown, 0);
                }
                R::Record => {
                    let line = q.line;
                    self.bounds.clear();
                    let mut field_start = 0;
                    for &e in &self.ends[..q.ends_len] {
                        self.bounds.push((field_start, e));
                        field_start = e;
                    }
                    self.quoted = None;
                    let fields = Fields { data: &self.out, bounds: &self.bounds };
                    self.rows.record(fields, line, batch)?;
                    self.fast = self.rows.plan.as_ref().is_some_and(|p| p.fast) && !self.core_only;
                    return Ok(Flow::Continue);
                }
                R::End => {
                    self.quoted = None;
                    return Ok(Flow::Continue);
                }
            }
        }
    }
}

/// Scans the needed cells of a record at `pos` in one pass. Succeeds only for a record
/// without quotes whose needed cells are empty (NaN in `values`) or plain decimals, and
/// returns the index of its terminator; `None` sends the record to the general path
/// (also when it runs past the data in memory).
#[inline]
fn fast_fields(
    buf: &[u8],
    mut pos: usize,
    delimiter: u8,
    roles: &[usize],
    values: &mut [f64],
) -> Option<usize> {
    let last = roles.len().checked_sub(1)?;
    for (field, &role) in roles.iter().enumerate() {
        if role == SKIP {
            loop {
                let b = *buf.get(pos)?;
                if b == delimiter {
                    break;
                }
                if matches!(b, b'\n' | b'\r' | b'"') {
                    return None;
                }
                pos += 1;
            }
        } else {
            let (value, end) = scan_decimal(buf, pos, delimiter)?;
            *values.get_mut(role)? = value;
            pos = end;
        }
        let b = *buf.get(pos)?;
        if field == last {
            if b != delimiter {
                return Some(pos);
            }
            // Fields the log has beyond the ones used: find the end, refuse quotes.
            let rest = buf.get(pos..)?;
            let len = memchr2(b'\n', b'\r', rest)?;
            return memchr(b'"', &rest[..len]).is_none().then_some(pos + len);
        }
        if b != delimiter {
            return None;
        }
        pos += 1;
    }
    None
}

/// `10^i`, exact in `f64`.
const POW10: [f64; 16] =
    [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15];

/// A plain decimal cell (`-?digits[.digits]`, or empty → NaN) at `start`, ended by the
/// delimiter or a terminator; returns the value and the index of that end. The value is
/// the correctly rounded one, like `fast_float2::parse`: with at most 15 digits the
/// integer and `10^k` are exact in `f64` and the division rounds once; longer ones go to
/// `fast_float2`.
#[inline]
fn scan_decimal(buf: &[u8], start: usize, delimiter: u8) -> Option<(f64, usize)> {
    let negative = buf.get(start) == Some(&b'-');
    let mut pos = start + usize::from(negative);
    let mut mantissa = 0u64;
    let int_start = pos;
    while let Some(&b) = buf.get(pos) {
        let digit = b.wrapping_sub(b'0');
        if digit >= 10 {
            break;
        }
        mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(digit));
        pos += 1;
    }
    let mut digits = pos - int_start;
    let mut decimals = 0;
    if buf.get(pos) == Some(&b'.') {
        pos += 1;
        let frac_start = pos;
        while let Some(&b) = buf.get(pos) {
            let digit = b.wrapping_sub(b'0');
            if digit >= 10 {
                break;
            }
            mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(digit));
            pos += 1;
        }
        decimals = pos - frac_start;
        digits += decimals;
    }
    let end = *buf.get(pos)?;
    if end != delimiter && end != b'\n' && end != b'\r' {
        return None;
    }
    if digits == 0 {
        // Only a truly empty cell; "-", "." and the like are for the general path.
        return (pos == start).then_some((f64::NAN, pos));
    }
    if digits <= 15 {
        // Below 10^15, so the signed conversion (one instruction) is exact.
        let value = mantissa as i64 as f64 / POW10[decimals];
        return Some((if negative { -value } else { value }, pos));
    }
    match fast_float2::parse::<f64, _>(&buf[start..pos]) {
        Ok(v) if v.is_finite() => Some((v, pos)),
        _ => None,
    }
}

/// `Plan::roles` entry of a field no row value comes from.
const SKIP: usize = usize::MAX;

/// Where the values come from (from the header) and how they are scaled.
struct Plan {
    columns: Columns,
    /// Per field up to `min_fields`: the slot in `RowState::values` it is parsed into, or
    /// [`SKIP`].
    roles: Vec<usize>,
    time_slot: usize,
    temp_slots: Vec<usize>,
    gyro_slots: Vec<usize>,
    time_factor: f64,
    gyro_factor: f64,
    temp_scale: f64,
    temp_offset_c: f64,
    /// The delimiter cannot occur in a plain decimal.
    fast: bool,
}

/// Row-level state: header, previous time, skipped rows.
struct RowState {
    path: PathBuf,
    format: LogFormat,
    skip_bad_rows: bool,
    plan: Option<Plan>,
    /// One-pass path: one value per distinct used field.
    values: Vec<f64>,
    temps: Vec<f64>,
    gyros: Vec<f64>,
    previous_time: Option<f64>,
    origin: Option<f64>,
    skipped: u64,
    first_skipped: Vec<BadRow>,
}

impl RowState {
    fn new(path: &Path, options: &IngestOptions) -> Self {
        Self {
            path: path.to_path_buf(),
            format: options.format.clone(),
            skip_bad_rows: options.skip_bad_rows,
            plan: None,
            values: Vec::new(),
            temps: vec![f64::NAN; options.format.temp_columns.len()],
            gyros: vec![0.0; options.format.gyro_columns.len()],
            previous_time: None,
            origin: None,
            skipped: 0,
            first_skipped: Vec::new(),
        }
    }

    /// One record by the general path: the header if none yet, else a row (accepted into
    /// `batch`, skipped, or the error).
    fn record(&mut self, fields: Fields<'_>, line: u64, batch: &mut Batch) -> Result<(), CalError> {
        let Some(plan) = &self.plan else {
            let plan = make_plan(&self.path, fields, &self.format)?;
            self.values = vec![f64::NAN; plan.roles.iter().filter(|&&r| r != SKIP).count()];
            self.plan = Some(plan);
            return Ok(());
        };
        let parsed = parse_row(fields, plan, line, &mut self.temps, &mut self.gyros)
            .and_then(|time| check_time(time, self.previous_time, &plan.columns, line, fields));
        match parsed {
            Ok(time) => {
                let origin = *self.origin.get_or_insert(time);
                self.previous_time = Some(time);
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

struct Columns {
    time: usize,
    temps: Vec<usize>,
    gyros: Vec<usize>,
    names: Vec<String>,
    min_fields: usize,
}

fn make_plan(path: &Path, header: Fields<'_>, f: &LogFormat) -> Result<Plan, CalError> {
    let columns = locate_columns(path, header, f)?;
    let mut roles = vec![SKIP; columns.min_fields];
    let mut slots = 0;
    let mut slot_of = |field: usize| {
        if roles[field] == SKIP {
            roles[field] = slots;
            slots += 1;
        }
        roles[field]
    };
    let time_slot = slot_of(columns.time);
    let gyro_slots = columns.gyros.iter().map(|&c| slot_of(c)).collect();
    let temp_slots = columns.temps.iter().map(|&c| slot_of(c)).collect();
    Ok(Plan {
        columns,
        roles,
        time_slot,
        temp_slots,
        gyro_slots,
        time_factor: f.time_unit.seconds(),
        gyro_factor: f.gyro_unit.dph() * f.gyro_scale,
        temp_scale: f.temp_scale,
        temp_offset_c: f.temp_offset_c,
        fast: !matches!(f.delimiter, b'0'..=b'9' | b'.' | b'-' | b'"' | b'\r' | b'\n'),
    })
}

fn locate_columns(path: &Path, header: Fields<'_>, f: &LogFormat) -> Result<Columns, CalError> {
    let names: Vec<String> = (0..header.len())
        .map(|i| {
            let h = header.get(i).unwrap_or(b"");
            String::from_utf8_lossy(h).trim().trim_start_matches('\u{feff}').to_string()
        })
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
fn parse_cell(columns: &Columns, fields: Fields<'_>, field: usize, line: u64) -> Result<Option<f64>, BadRow> {
    let raw = fields.get(field).unwrap_or(b"");
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

/// The general path: time (returned, s), gyros and temperatures (into the slices), with
/// the first bad cell in the order time, gyros, temperatures.
fn parse_row(
    fields: Fields<'_>,
    plan: &Plan,
    line: u64,
    temps: &mut [f64],
    gyros: &mut [f64],
) -> Result<f64, BadRow> {
    let columns = &plan.columns;
    if fields.len() < columns.min_fields {
        let field = fields.len();
        return Err(bad_row(
            columns,
            line,
            field.min(columns.names.len().saturating_sub(1)),
            b"",
            BadRowKind::ShortRow,
        ));
    }
    let required = |field: usize| -> Result<f64, BadRow> {
        parse_cell(columns, fields, field, line)?
            .ok_or_else(|| bad_row(columns, line, field, b"", BadRowKind::EmptyCell))
    };
    let time = required(columns.time)? * plan.time_factor;
    for (slot, &field) in gyros.iter_mut().zip(&columns.gyros) {
        *slot = required(field)? * plan.gyro_factor;
    }
    for (slot, &field) in temps.iter_mut().zip(&columns.temps) {
        *slot = parse_cell(columns, fields, field, line)?
            .map_or(f64::NAN, |raw| raw * plan.temp_scale + plan.temp_offset_c);
    }
    Ok(time)
}

fn check_time(
    time: f64,
    previous: Option<f64>,
    columns: &Columns,
    line: u64,
    fields: Fields<'_>,
) -> Result<f64, BadRow> {
    let found = || fields.get(columns.time).unwrap_or(b"");
    match previous {
        Some(p) if time == p => Err(bad_row(columns, line, columns.time, found(), BadRowKind::DuplicateTime)),
        Some(p) if time < p => Err(bad_row(columns, line, columns.time, found(), BadRowKind::BackwardTime)),
        _ => Ok(time),
    }
}
