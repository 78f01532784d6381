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
//! before, so errors and values are the same either way. On logs of 1 MiB or more, when
//! there is a second core, worker threads parse 1 MiB chunks of whole records and the
//! calling thread merges them in order and runs the visitor (see [`read_log`]); memory
//! is a few chunks whatever the log size.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Mutex};

use memchr::{memchr, memchr2, memchr_iter, memrchr2};

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
/// The UTF-8 byte-order mark.
const BOM: &[u8] = b"\xef\xbb\xbf";

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
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mode = if size >= PARALLEL_MIN_BYTES && cores >= 2 {
        Mode::Parallel { workers: cores.min(MAX_WORKERS) }
    } else {
        Mode::Single
    };
    let tuning = Tuning { mode, ..Tuning::default() };
    read_with_tuning(path, file, options, tuning, visit, progress)
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
    let mut parser = Parser::new(path, reader, options, tuning.buffer_bytes);
    let temps = options.format.temp_columns.len();
    let mut consumer = Consumer {
        report: IngestReport { path: path.to_path_buf(), ..Default::default() },
        temps,
        stride: 1 + temps + options.format.gyro_columns.len(),
        last_progress: 0,
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

/// The parallel reader, once `head` has read the header: workers take chunks of whole
/// records from a shared reader and parse them each on their own (relative lines,
/// absolute times, the first row's time not yet checked); the calling thread merges
/// them in order and visits the rows. A chunk whose first row is not after the previous
/// chunk's last is parsed again in order. At the first quote the rest of the log goes to
/// one sequential parser (a quoted field may hold a newline, so records can no longer be
/// cut at newlines).
fn read_parallel<R, F, P>(
    head: Parser<R>,
    consumer: Consumer,
    tuning: Tuning,
    workers: usize,
    visit: &mut F,
    progress: &mut P,
) -> Result<IngestReport, CalError>
where
    R: Read + Send,
    F: FnMut(&Row<'_>) -> Result<(), CalError>,
    P: FnMut(u64, u64),
{
    let Parser { path, src, rows, .. } = head;
    let chunker = Mutex::new(Chunker {
        carry: src.buf[src.pos..src.end].to_vec(),
        offset: src.offset(),
        eof: src.eof,
        reader: Some(src.reader),
        next_seq: 0,
        done: false,
        chunk_bytes: tuning.chunk_bytes.max(1),
    });
    let template = rows.for_chunk();
    let mut merger = Merger { path: &path, rows, line: src.line, consumer, tuning };
    // Chunks circulate: `free` to the workers, `parsed` back; never more than `pool`.
    let pool = workers + 2;
    let (free_tx, free_rx) = mpsc::sync_channel::<Chunk<R>>(pool);
    for _ in 0..pool {
        let _ = free_tx.send(Chunk::empty());
    }
    let free_rx = Mutex::new(free_rx);
    std::thread::scope(|scope| {
        // Owned here: returning drops it, which ends the workers.
        let free_tx = free_tx;
        let (parsed_tx, parsed_rx) = mpsc::channel::<Chunk<R>>();
        for _ in 0..workers {
            let parsed_tx = parsed_tx.clone();
            let (chunker, free_rx, template, path) = (&chunker, &free_rx, &template, &path);
            std::thread::Builder::new()
                .name("fogtemp-ingest".into())
                .spawn_scoped(scope, move || loop {
                    // A closed channel means the merge has ended (done, or the visitor stopped).
                    let Ok(mut chunk) = lock(free_rx).recv() else { break };
                    if !lock(chunker).next(&mut chunk) {
                        break;
                    }
                    chunk.parse(path, template);
                    if parsed_tx.send(chunk).is_err() {
                        break;
                    }
                })
                .map_err(|source| CalError::Io { path: path.clone(), source })?;
        }
        drop(parsed_tx);
        let mut pending = BTreeMap::new();
        let mut next = 0u64;
        loop {
            let mut chunk = match pending.remove(&next) {
                Some(chunk) => chunk,
                None => match parsed_rx.recv() {
                    Ok(chunk) if chunk.seq == next => chunk,
                    Ok(chunk) => {
                        pending.insert(chunk.seq, chunk);
                        continue;
                    }
                    // Only if a worker panicked; the scope re-raises that panic.
                    Err(_) => {
                        return Err(CalError::Csv {
                            path: path.clone(),
                            line: merger.line,
                            message: "ingest thread failed".into(),
                        })
                    }
                },
            };
            next += 1;
            if let Some(report) = merger.merge(&mut chunk, visit, progress)? {
                return Ok(report);
            }
            let _ = free_tx.send(chunk);
        }
    })
}

/// Locks, also after a panic elsewhere (the data stays usable: chunks are handed out whole).
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Hands out the log in chunks of whole records, in order.
struct Chunker<R> {
    reader: Option<R>,
    /// Bytes read after the last chunk's final newline.
    carry: Vec<u8>,
    /// File offset of `carry[0]`.
    offset: u64,
    eof: bool,
    next_seq: u64,
    /// Every chunk handed out (the last one is marked).
    done: bool,
    chunk_bytes: usize,
}

impl<R: Read> Chunker<R> {
    /// Fills `chunk` with the next records; `false` once all have been handed out.
    fn next(&mut self, chunk: &mut Chunk<R>) -> bool {
        if self.done {
            return false;
        }
        chunk.seq = self.next_seq;
        self.next_seq += 1;
        chunk.start = self.offset;
        chunk.last = false;
        chunk.rest = None;
        chunk.error = None;
        chunk.newlines = 0;
        chunk.batch.values.clear();
        chunk.batch.lines.clear();
        chunk.batch.end = None;
        chunk.data.clear();
        chunk.data.append(&mut self.carry);
        let mut target = self.chunk_bytes;
        let cut = loop {
            if !self.eof && chunk.data.len() < target {
                let want = (target - chunk.data.len()) as u64;
                let read = match self.reader.as_mut() {
                    Some(reader) => reader.by_ref().take(want).read_to_end(&mut chunk.data),
                    None => Ok(0),
                };
                match read {
                    Ok(n) => self.eof = (n as u64) < want,
                    Err(e) => {
                        chunk.error = Some(e);
                        chunk.last = true;
                        self.done = true;
                        return true;
                    }
                }
                continue;
            }
            if self.eof {
                break chunk.data.len();
            }
            // After any terminator is a record boundary (a "\r\n" cut in two is a record
            // and a blank line).
            match memrchr2(b'\n', b'\r', &chunk.data) {
                Some(i) => break i + 1,
                None => target = chunk.data.len() * 2, // one record longer than a chunk
            }
        };
        self.carry.extend_from_slice(&chunk.data[cut..]);
        chunk.data.truncate(cut);
        self.offset = chunk.start + cut as u64;
        if let Some(quote) = memchr(b'"', &chunk.data) {
            let record = memrchr2(b'\n', b'\r', &chunk.data[..quote]).map_or(0, |i| i + 1);
            let mut rest = chunk.data.split_off(record);
            rest.append(&mut self.carry);
            if let Some(reader) = self.reader.take() {
                chunk.rest = Some(Rest { bytes: rest, offset: chunk.start + record as u64, reader });
            }
            chunk.last = true;
            self.done = true;
        } else if self.eof && self.carry.is_empty() {
            chunk.last = true;
            self.done = true;
        }
        true
    }
}

/// The rest of a log from its first quoted record on, for the sequential parser.
struct Rest<R> {
    bytes: Vec<u8>,
    /// File offset of `bytes[0]`.
    offset: u64,
    reader: R,
}

/// Whole records of the log and, once parsed, their rows.
struct Chunk<R> {
    seq: u64,
    data: Vec<u8>,
    /// File offset of `data[0]`.
    start: u64,
    /// Nothing follows (but maybe `rest`).
    last: bool,
    rest: Option<Rest<R>>,
    error: Option<std::io::Error>,
    /// Rows: times absolute, lines counted from 0 at the chunk's start.
    batch: Batch,
    /// Newlines in `data`.
    newlines: u64,
}

impl<R> Chunk<R> {
    fn empty() -> Self {
        Self {
            seq: 0,
            data: Vec::new(),
            start: 0,
            last: false,
            rest: None,
            error: None,
            batch: Batch::default(),
            newlines: 0,
        }
    }

    /// Parses the chunk on its own (see [`RowState::for_chunk`]).
    fn parse(&mut self, path: &Path, template: &RowState) {
        if self.error.is_some() {
            return;
        }
        let data = std::mem::take(&mut self.data);
        let end = data.len();
        let src =
            Source { reader: std::io::empty(), buf: data, pos: 0, end, eof: true, base: self.start, line: 0 };
        let mut parser = Parser::resume(path, src, template.for_chunk());
        parser.fill(&mut self.batch, usize::MAX);
        self.newlines = parser.src.line;
        self.data = parser.src.buf;
    }
}

/// The calling thread's side of the parallel reader.
struct Merger<'a> {
    path: &'a Path,
    /// Header, last accepted time, origin, skipped rows: the log so far.
    rows: RowState,
    /// Line of the next chunk's first byte.
    line: u64,
    consumer: Consumer,
    tuning: Tuning,
}

impl Merger<'_> {
    /// Visits a parsed chunk's rows; the report once the log has ended.
    fn merge<R, F, P>(
        &mut self,
        chunk: &mut Chunk<R>,
        visit: &mut F,
        progress: &mut P,
    ) -> Result<Option<IngestReport>, CalError>
    where
        R: Read,
        F: FnMut(&Row<'_>) -> Result<(), CalError>,
        P: FnMut(u64, u64),
    {
        if let Some(e) = chunk.error.take() {
            return Err(CalError::Csv {
                path: self.path.to_path_buf(),
                line: self.line,
                message: e.to_string(),
            });
        }
        let stride = self.consumer.stride;
        let batch = &mut chunk.batch;
        let first_time = batch.values.first().copied();
        let in_order = match (self.rows.previous_time, first_time) {
            (Some(previous), Some(first)) => first > previous,
            _ => true,
        };
        if in_order {
            let base = self.line;
            if let Some(first) = first_time {
                let origin = *self.rows.origin.get_or_insert(first);
                self.consumer.visit_rows(batch, base, origin, visit)?;
                self.rows.previous_time = batch.values.len().checked_sub(stride).map(|i| batch.values[i]);
            }
            match batch.end.take() {
                Some(Ok(tail)) => {
                    self.rows.skipped += tail.skipped;
                    for mut bad in tail.first_skipped {
                        if self.rows.first_skipped.len() < MAX_REPORTED_BAD_ROWS {
                            bad.line += base;
                            self.rows.first_skipped.push(bad);
                        }
                    }
                }
                Some(Err(CalError::BadRow { path, mut row })) => {
                    row.line += base;
                    return Err(CalError::BadRow { path, row });
                }
                Some(Err(e)) => return Err(e),
                None => {}
            }
            self.line = base + chunk.newlines;
        } else {
            self.in_order(chunk, visit)?;
        }
        let bytes = chunk.start + chunk.data.len() as u64;
        if let Some(rest) = chunk.rest.take() {
            return self.sequential_rest(rest, visit, progress).map(Some);
        }
        if chunk.last {
            let report = &mut self.consumer.report;
            report.bytes = bytes;
            report.skipped = self.rows.skipped;
            report.first_skipped = std::mem::take(&mut self.rows.first_skipped);
            report.time_origin_s = self.rows.origin.unwrap_or(0.0);
            progress(report.bytes, report.rows);
            return Ok(Some(std::mem::take(report)));
        }
        if bytes - self.consumer.last_progress >= PROGRESS_EVERY_BYTES {
            progress(bytes, self.consumer.report.rows);
            self.consumer.last_progress = bytes;
        }
        Ok(None)
    }

    /// Parses a chunk again, carrying on from the log so far.
    fn in_order<R, F>(&mut self, chunk: &mut Chunk<R>, visit: &mut F) -> Result<(), CalError>
    where
        F: FnMut(&Row<'_>) -> Result<(), CalError>,
    {
        let fresh = self.rows.for_chunk();
        let rows = std::mem::replace(&mut self.rows, fresh);
        let data = std::mem::take(&mut chunk.data);
        let end = data.len();
        let src = Source {
            reader: std::io::empty(),
            buf: data,
            pos: 0,
            end,
            eof: true,
            base: chunk.start,
            line: self.line,
        };
        let mut parser = Parser::resume(self.path, src, rows);
        let mut batch = Batch::default();
        let result = loop {
            parser.fill(&mut batch, self.tuning.batch_rows.max(1));
            // Times are relative already, lines absolute.
            if let Err(e) = self.consumer.visit_rows(&batch, 0, 0.0, visit) {
                break Err(e);
            }
            match batch.end.take() {
                None => {}
                Some(Ok(_)) => break Ok(()),
                Some(Err(e)) => break Err(e),
            }
        };
        self.line = parser.src.line;
        self.rows = parser.rows;
        chunk.data = parser.src.buf;
        result
    }

    /// Reads the rest of the log with one sequential parser.
    fn sequential_rest<R, F, P>(
        &mut self,
        rest: Rest<R>,
        visit: &mut F,
        progress: &mut P,
    ) -> Result<IngestReport, CalError>
    where
        R: Read,
        F: FnMut(&Row<'_>) -> Result<(), CalError>,
        P: FnMut(u64, u64),
    {
        let fresh = self.rows.for_chunk();
        let rows = std::mem::replace(&mut self.rows, fresh);
        let mut buf = rest.bytes;
        let end = buf.len();
        buf.resize(end.max(self.tuning.buffer_bytes).max(4), 0);
        let src =
            Source { reader: rest.reader, buf, pos: 0, end, eof: false, base: rest.offset, line: self.line };
        let mut parser = Parser::resume(self.path, src, rows);
        let mut batch = Batch::default();
        loop {
            parser.fill(&mut batch, self.tuning.batch_rows.max(1));
            if self.consumer.consume(&mut batch, visit, progress)? {
                return Ok(std::mem::take(&mut self.consumer.report));
            }
        }
    }
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
        self.visit_rows(batch, 0, 0.0, visit)?;
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

impl Consumer {
    /// Visits the batch's rows, adding `line_base` to their lines and taking `origin`
    /// from their times (both zero for a sequential parser's rows).
    fn visit_rows<F>(
        &mut self,
        batch: &Batch,
        line_base: u64,
        origin: f64,
        visit: &mut F,
    ) -> Result<(), CalError>
    where
        F: FnMut(&Row<'_>) -> Result<(), CalError>,
    {
        let split = 1 + self.temps;
        for (values, &line) in batch.values.chunks_exact(self.stride).zip(&batch.lines) {
            visit(&Row {
                line: line_base + line,
                time_s: values[0] - origin,
                temps_c: &values[1..split],
                gyros_dph: &values[split..],
            })?;
        }
        self.report.rows += batch.lines.len() as u64;
        Ok(())
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
    /// Stop once the header is read (the parallel reader reads the header this way).
    header_only: bool,
}

impl<R: Read> Parser<R> {
    fn new(path: &Path, reader: R, options: &IngestOptions, buffer_bytes: usize) -> Self {
        let src = Source {
            reader,
            buf: vec![0; buffer_bytes.max(4)],
            pos: 0,
            end: 0,
            eof: false,
            base: 0,
            line: 1,
        };
        Self::with_state(path, src, RowState::new(path, options), false)
    }

    /// A parser that carries on from `rows` (header read, times and skipped rows so
    /// far) over `src` (which starts at a record boundary, after any byte-order mark).
    fn resume(path: &Path, src: Source<R>, rows: RowState) -> Self {
        Self::with_state(path, src, rows, true)
    }

    fn with_state(path: &Path, src: Source<R>, rows: RowState, bom_checked: bool) -> Self {
        let delimiter = rows.format.delimiter;
        let mut core = csv_core::ReaderBuilder::new().delimiter(delimiter).build();
        // Prime it so that it never strips a byte-order mark from a record mid-file
        // (the file's own mark is skipped before any record).
        let _ = core.read_record(b"\n", &mut [0u8; 1], &mut [0usize; 1]);
        let core_only = matches!(delimiter, b'"' | b'\r' | b'\n');
        Self {
            path: path.to_path_buf(),
            src,
            delimiter,
            fast: rows.plan.as_ref().is_some_and(|p| p.fast) && !core_only,
            core_only,
            bom_checked,
            core,
            quoted: None,
            out: vec![0; 256],
            ends: vec![0; 16],
            bounds: Vec::new(),
            rows,
            header_only: false,
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
                    first_skipped: self.rows.first_skipped.clone(),
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
        while batch.lines.len() < max_rows && !(self.header_only && self.rows.plan.is_some()) {
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
                        if self.rows.plan.is_none() {
                            return Err(CalError::Csv {
                                path: self.rows.path.clone(),
                                line: 1,
                                message: "empty file: no header row".into(),
                            });
                        }
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
    pos += digit_run(buf, pos, &mut mantissa);
    let mut digits = pos - int_start;
    let mut decimals = 0;
    if buf.get(pos) == Some(&b'.') {
        pos += 1;
        decimals = digit_run(buf, pos, &mut mantissa);
        pos += decimals;
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

/// Appends the ASCII digits at `pos` to `mantissa` (wrapping past 19 digits: the caller
/// then does not use it) and returns how many there were. A plain loop beats eight-byte
/// tricks here: the predictor learns the log's digit counts, so field ends do not wait
/// on arithmetic.
#[inline]
fn digit_run(buf: &[u8], pos: usize, mantissa: &mut u64) -> usize {
    let mut count = 0;
    for &b in buf.get(pos..).unwrap_or_default() {
        let digit = b.wrapping_sub(b'0');
        if digit >= 10 {
            break;
        }
        *mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(digit));
        count += 1;
    }
    count
}

/// `Plan::roles` entry of a field no row value comes from.
const SKIP: usize = usize::MAX;

/// Where the values come from (from the header) and how they are scaled.
#[derive(Clone)]
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

    /// The state a worker starts a chunk with: the same header, no previous time (the
    /// first row's time is checked when chunks are merged), no skipped rows, and an
    /// origin of zero, so that rows keep their absolute time (`t - 0.0 == t`).
    fn for_chunk(&self) -> Self {
        Self {
            path: self.path.clone(),
            format: self.format.clone(),
            skip_bad_rows: self.skip_bad_rows,
            plan: self.plan.clone(),
            values: self.values.clone(),
            temps: self.temps.clone(),
            gyros: self.gyros.clone(),
            previous_time: None,
            origin: Some(0.0),
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

#[derive(Clone)]
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Hands out at most `chunk` bytes per read, to put records across buffer refills.
    struct Chunky<'a> {
        data: &'a [u8],
        chunk: usize,
    }

    impl Read for Chunky<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = self.chunk.min(buf.len()).min(self.data.len());
            buf[..n].copy_from_slice(&self.data[..n]);
            self.data = &self.data[n..];
            Ok(n)
        }
    }

    /// One visited row, values as bits (so NaN compares equal to NaN).
    #[derive(Clone, Debug, PartialEq)]
    struct Seen {
        line: u64,
        time: u64,
        temps: Vec<u64>,
        gyros: Vec<u64>,
    }

    impl Seen {
        fn of(row: &Row<'_>) -> Self {
            Self {
                line: row.line,
                time: row.time_s.to_bits(),
                temps: row.temps_c.iter().map(|v| v.to_bits()).collect(),
                gyros: row.gyros_dph.iter().map(|v| v.to_bits()).collect(),
            }
        }
    }

    type Outcome = (Vec<Seen>, Result<IngestReport, CalError>);

    /// Every way of running the reader: one thread or in parallel, big or tiny buffers,
    /// batches and chunks, whole or dribbled reads.
    const MODES: [(Tuning, usize); 8] = [
        (tuning(Mode::Single, BUFFER_BYTES, BATCH_ROWS, CHUNK_BYTES), usize::MAX),
        (tuning(Mode::Parallel { workers: 2 }, BUFFER_BYTES, BATCH_ROWS, CHUNK_BYTES), usize::MAX),
        (tuning(Mode::Single, 4, 1, CHUNK_BYTES), 1),
        (tuning(Mode::Single, 16, 2, CHUNK_BYTES), 3),
        (tuning(Mode::Parallel { workers: 2 }, 8, 3, 16), 5),
        (tuning(Mode::Parallel { workers: 3 }, 64, 1, 1), 7),
        (tuning(Mode::Parallel { workers: 1 }, 16, 2, 64), 2),
        (tuning(Mode::Parallel { workers: 2 }, 4, 1, 40), usize::MAX),
    ];

    const fn tuning(mode: Mode, buffer_bytes: usize, batch_rows: usize, chunk_bytes: usize) -> Tuning {
        Tuning { mode, buffer_bytes, batch_rows, chunk_bytes }
    }

    fn run_mode(data: &[u8], options: &IngestOptions, tuning: Tuning, chunk: usize) -> Outcome {
        let mut seen = Vec::new();
        let reader = Chunky { data, chunk };
        let result = read_with_tuning(
            Path::new("log.csv"),
            reader,
            options,
            tuning,
            |row| {
                seen.push(Seen::of(row));
                Ok(())
            },
            |_, _| {},
        );
        (seen, result)
    }

    /// Runs every mode, checks they agree, returns the outcome.
    fn run(data: &[u8], options: &IngestOptions) -> Outcome {
        let first = run_mode(data, options, MODES[0].0, MODES[0].1);
        for (tuning, chunk) in &MODES[1..] {
            let other = run_mode(data, options, *tuning, *chunk);
            assert_eq!(first.0, other.0, "rows differ in mode {tuning:?} chunk {chunk}");
            assert_eq!(summary(&first.1), summary(&other.1), "result differs in mode {tuning:?}");
        }
        first
    }

    fn summary(result: &Result<IngestReport, CalError>) -> String {
        match result {
            Ok(r) => format!(
                "ok rows {} skipped {} bytes {} origin {:?} first {:?}",
                r.rows, r.skipped, r.bytes, r.time_origin_s, r.first_skipped
            ),
            Err(e) => format!("error {e}"),
        }
    }

    fn default_options() -> IngestOptions {
        IngestOptions::default()
    }

    fn skipping() -> IngestOptions {
        IngestOptions { skip_bad_rows: true, ..IngestOptions::default() }
    }

    /// The bad row of a failed run.
    fn bad(data: &str) -> BadRow {
        match run(data.as_bytes(), &default_options()).1 {
            Err(CalError::BadRow { row, .. }) => *row,
            other => panic!("expected a bad row, got {}", summary(&other)),
        }
    }

    fn rows(data: &str, options: &IngestOptions) -> Vec<Seen> {
        let (seen, result) = run(data.as_bytes(), options);
        assert!(result.is_ok(), "{}", summary(&result));
        seen
    }

    fn values(seen: &[Seen]) -> Vec<(u64, f64, Vec<f64>, Vec<f64>)> {
        seen.iter()
            .map(|s| {
                (
                    s.line,
                    f64::from_bits(s.time),
                    s.temps.iter().map(|&b| f64::from_bits(b)).collect(),
                    s.gyros.iter().map(|&b| f64::from_bits(b)).collect(),
                )
            })
            .collect()
    }

    const HEADER: &str = "time_s,temp_c,gyro_dph\n";

    fn expect(bad: &BadRow, line: u64, column: usize, name: &str, found: &str, kind: BadRowKind) {
        let want = BadRow { line, column, column_name: name.into(), found: found.into(), kind };
        assert_eq!(*bad, want);
    }

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
        let b = bad(&format!("{HEADER}0.0,20,1\n0.1,20,\n"));
        expect(&b, 3, 3, "gyro_dph", "", BadRowKind::EmptyCell);
        let b = bad(&format!("{HEADER}0.0,20,  \n"));
        expect(&b, 2, 3, "gyro_dph", "", BadRowKind::EmptyCell);
    }

    #[test]
    fn first_bad_cell_in_order_time_gyro_temperature() {
        let b = bad(&format!("{HEADER}x,y,z\n"));
        expect(&b, 2, 1, "time_s", "x", BadRowKind::NotANumber);
        let b = bad(&format!("{HEADER}0,y,z\n"));
        expect(&b, 2, 3, "gyro_dph", "z", BadRowKind::NotANumber);
    }

    #[test]
    fn rows_before_a_bad_row_are_visited() {
        let (seen, result) =
            run(format!("{HEADER}0,20,1\n1,20,1\n2,20,x\n3,20,1\n").as_bytes(), &default_options());
        assert!(matches!(result, Err(CalError::BadRow { .. })));
        assert_eq!(seen.iter().map(|s| s.line).collect::<Vec<_>>(), vec![2, 3]);
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
    fn crlf_lines_are_exact() {
        let data = "time_s,temp_c,gyro_dph\r\n0,20,1\r\n1,20,1\r\n2,20,x\r\n";
        let b = bad(data);
        expect(&b, 4, 3, "gyro_dph", "x", BadRowKind::NotANumber);
        let seen = rows("time_s,temp_c,gyro_dph\r\n0,20,1\r\n1,20,2\r\n", &default_options());
        assert_eq!(values(&seen).iter().map(|v| (v.0, v.3[0])).collect::<Vec<_>>(), vec![(2, 1.0), (3, 2.0)]);
    }

    #[test]
    fn blank_lines_are_skipped_and_lines_still_exact() {
        let b = bad(&format!("{HEADER}0,20,1\n\n\n1,20,1\r\n\r\n2,20,x\n"));
        expect(&b, 7, 3, "gyro_dph", "x", BadRowKind::NotANumber);
        let b = bad("\n\ntime_s,temp_c,gyro_dph\n0,20,x\n");
        expect(&b, 4, 3, "gyro_dph", "x", BadRowKind::NotANumber);
    }

    #[test]
    fn lone_carriage_returns_end_records() {
        // As in the csv crate: '\r' alone ends a record (lines count '\n' only).
        let seen = rows("time_s,temp_c,gyro_dph\r0,20,1\r1,20,2\n2,20,3\n", &default_options());
        assert_eq!(seen.iter().map(|s| s.line).collect::<Vec<_>>(), vec![1, 1, 2]);
    }

    #[test]
    fn byte_order_mark_in_the_header() {
        let data = format!("\u{feff}{HEADER}0,20,1\n1,20,x\n");
        expect(&bad(&data), 3, 3, "gyro_dph", "x", BadRowKind::NotANumber);
        assert_eq!(rows(&format!("\u{feff}{HEADER}0,20,1\n"), &default_options()).len(), 1);
        // A quoted header after the mark, too.
        let data = "\u{feff}\"time_s\",\"temp_c\",\"gyro_dph\"\n0,20,1\n";
        assert_eq!(rows(data, &default_options()).len(), 1);
    }

    #[test]
    fn final_line_without_newline() {
        let seen = rows(&format!("{HEADER}0,20,1\n1,20,2"), &default_options());
        assert_eq!(values(&seen).iter().map(|v| (v.0, v.3[0])).collect::<Vec<_>>(), vec![(2, 1.0), (3, 2.0)]);
        let b = bad(&format!("{HEADER}0,20,1\n1,20,2x"));
        expect(&b, 3, 3, "gyro_dph", "2x", BadRowKind::NotANumber);
        let b = bad(&format!("{HEADER}0,20,1\n1,20"));
        expect(&b, 3, 3, "gyro_dph", "", BadRowKind::ShortRow);
        assert_eq!(rows(&format!("{HEADER}0,20,1\r"), &default_options()).len(), 1);
    }

    #[test]
    fn quoted_fields() {
        let data = "time_s,note,temp_c,gyro_dph\n\
                    0,\"a, b\",20,1\n\
                    \"1\",\"two\nlines\",\"20.5\",\"2\"\n\
                    2,\"say \"\"hi\"\"\",21,3\n\
                    3,plain,22,x\n";
        let (seen, result) = run(data.as_bytes(), &default_options());
        let v = values(&seen);
        assert_eq!(
            v.iter().map(|v| (v.0, v.1, v.2[0], v.3[0])).collect::<Vec<_>>(),
            vec![(2, 0.0, 20.0, 1.0), (3, 1.0, 20.5, 2.0), (5, 2.0, 21.0, 3.0),]
        );
        match result {
            Err(CalError::BadRow { row, .. }) => expect(&row, 6, 4, "gyro_dph", "x", BadRowKind::NotANumber),
            other => panic!("{}", summary(&other)),
        }
        // A quoted bad cell reports its text without the quotes.
        let b = bad(&format!("{HEADER}0,20,\"1 2\"\n"));
        expect(&b, 2, 3, "gyro_dph", "1 2", BadRowKind::NotANumber);
        // A quote inside an unquoted field is a plain character (csv crate rules).
        let b = bad(&format!("{HEADER}0,20,1\"\n"));
        expect(&b, 2, 3, "gyro_dph", "1\"", BadRowKind::NotANumber);
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
                delimiter: b';',
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
        let data = "g1,id,time_s,temp_c,g0,comment\n2,a,0,20,1,\"x,y\"\n4,b,1,21,3,ok,more\n";
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
    fn missing_columns_and_empty_files() {
        let (_, result) = run(b"time_s,temp_c\n0,20\n", &default_options());
        assert!(
            matches!(&result, Err(CalError::MissingColumn { column, available, .. })
                if column == "gyro_dph" && available == "time_s, temp_c"),
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

    #[test]
    fn number_spellings_match_the_general_parser() {
        let cells = [
            "0",
            "-0",
            "007",
            "1.",
            ".5",
            "-.5",
            "-1.",
            "+1",
            " 1",
            "1 ",
            "1e3",
            "1E-3",
            "0.1",
            "0.3",
            "123456789012345",
            "1234567890123456",
            "0.000000000000001",
            "0.1234567890123456789",
            "99999999999999999999999",
            "9007199254740993",
            "-12.3456789012345",
            "1.7976931348623157",
            "1..2",
            "1.2.3",
            "--1",
            "-",
            ".",
            "",
        ];
        for cell in cells {
            let line = format!("{cell},");
            let fast = scan_decimal(line.as_bytes(), 0, b',').map(|(v, end)| (v.to_bits(), end));
            let general = match cell.trim_ascii() {
                "" => Some(f64::NAN),
                t => fast_float2::parse::<f64, _>(t).ok(),
            };
            if let Some((bits, end)) = fast {
                assert_eq!(end, cell.len(), "{cell:?}");
                assert_eq!(Some(bits), general.map(f64::to_bits), "{cell:?}");
            }
        }
    }

    #[test]
    fn random_decimals_convert_exactly() {
        let mut state = 0x1234_5678_9abc_def0u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..200_000 {
            let r = next();
            let int_digits = (r % 9) as usize;
            let frac_digits = ((r >> 8) % 12) as usize;
            let mut cell = String::new();
            if r & (1 << 20) != 0 {
                cell.push('-');
            }
            let mut d = next();
            for _ in 0..int_digits {
                cell.push(char::from(b'0' + (d % 10) as u8));
                d /= 10;
            }
            if frac_digits > 0 || r & (1 << 21) != 0 {
                cell.push('.');
            }
            let mut d = next();
            for _ in 0..frac_digits {
                cell.push(char::from(b'0' + (d % 10) as u8));
                d /= 10;
            }
            let line = format!("{cell}\n");
            let fast = scan_decimal(line.as_bytes(), 0, b',').map(|(v, _)| v.to_bits());
            let general = fast_float2::parse::<f64, _>(cell.as_bytes()).ok().map(f64::to_bits);
            if fast.is_some() && !cell.is_empty() {
                assert_eq!(fast, general, "{cell:?}");
            }
        }
    }

    #[test]
    fn visitor_errors_stop_the_read() {
        let mut data = String::from(HEADER);
        for i in 0..5000 {
            data.push_str(&format!("{i},20,1\n"));
        }
        for (tuning, chunk) in MODES {
            let mut calls = 0;
            let result = read_with_tuning(
                Path::new("log.csv"),
                Chunky { data: data.as_bytes(), chunk },
                &default_options(),
                tuning,
                |row| {
                    calls += 1;
                    if row.line == 100 {
                        return Err(CalError::NonFinite { what: "stop", index: 100 });
                    }
                    Ok(())
                },
                |_, _| {},
            );
            assert!(matches!(result, Err(CalError::NonFinite { what: "stop", index: 100 })));
            assert_eq!(calls, 99);
        }
    }

    #[test]
    fn a_panicking_visitor_does_not_hang_the_workers() {
        let mut data = String::from(HEADER);
        for i in 0..20_000 {
            data.push_str(&format!("{i},20,1\n"));
        }
        for (tuning, chunk) in MODES {
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                read_with_tuning(
                    Path::new("log.csv"),
                    Chunky { data: data.as_bytes(), chunk },
                    &default_options(),
                    tuning,
                    |row| {
                        assert!(row.line < 5000, "visitor gives up");
                        Ok(())
                    },
                    |_, _| {},
                )
            }));
            assert!(result.is_err(), "{tuning:?}");
        }
    }

    #[test]
    fn carriage_return_logs_are_cut_into_chunks() {
        let mut data = String::from("time_s,temp_c,gyro_dph\r");
        for i in 0..3000 {
            data.push_str(&format!("{i},20,{}\r", i % 7));
        }
        let seen = rows(&data, &default_options());
        assert_eq!(seen.len(), 3000);
        assert!(seen.iter().all(|s| s.line == 1));
        // Chunks of at most a few records (not the whole log): 3000 rows, 64-byte chunks.
        let tuning = Tuning { mode: Mode::Parallel { workers: 2 }, chunk_bytes: 64, ..Tuning::default() };
        let mut chunker = Chunker {
            reader: Some(data.as_bytes()),
            carry: Vec::new(),
            offset: 0,
            eof: false,
            next_seq: 0,
            done: false,
            chunk_bytes: tuning.chunk_bytes,
        };
        let mut chunk = Chunk::empty();
        let mut chunks = 0;
        while chunker.next(&mut chunk) {
            assert!(chunk.data.len() <= 64, "{}", chunk.data.len());
            chunks += 1;
        }
        assert!(chunks > data.len() / 128, "{chunks} chunks");
    }

    #[test]
    fn progress_reports_bytes_and_rows() {
        let mut data = String::from(HEADER);
        for i in 0..400_000 {
            data.push_str(&format!("{}.{:03},25.0625,0.123456\n", i / 1000, i % 1000));
        }
        for mode in [Mode::Single, Mode::Parallel { workers: 2 }] {
            let mut calls = Vec::new();
            let tuning = Tuning { mode, chunk_bytes: 64 << 10, ..Tuning::default() };
            let report = read_with_tuning(
                Path::new("log.csv"),
                data.as_bytes(),
                &default_options(),
                tuning,
                |_| Ok(()),
                |bytes, rows| calls.push((bytes, rows)),
            )
            .unwrap();
            assert!(calls.len() >= 3, "{calls:?}");
            assert!(calls.windows(2).all(|w| w[0].0 < w[1].0 && w[0].1 < w[1].1), "{calls:?}");
            assert_eq!(*calls.last().unwrap(), (data.len() as u64, 400_000));
            assert_eq!((report.bytes, report.rows), (data.len() as u64, 400_000));
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
            let mut reader = csv::ReaderBuilder::new()
                .delimiter(options.format.delimiter)
                .has_headers(true)
                .flexible(true)
                .from_reader(data);
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
            let plan = make_plan(path, Fields { data: &joined, bounds: &bounds }, &options.format)?;
            let mut report =
                IngestReport { path: path.into(), bytes: data.len() as u64, ..Default::default() };
            let mut temps = vec![f64::NAN; plan.columns.temps.len()];
            let mut gyros = vec![0.0; plan.columns.gyros.len()];
            let mut previous = None;
            let mut record = csv::ByteRecord::new();
            while reader.read_byte_record(&mut record).unwrap() {
                let line = record.position().map_or(0, |p| p.line());
                let mut bounds = Vec::new();
                let mut start = 0;
                for f in record.iter() {
                    bounds.push((start, start + f.len()));
                    start += f.len();
                }
                let joined: Vec<u8> = record.iter().flatten().copied().collect();
                let fields = Fields { data: &joined, bounds: &bounds };
                let parsed = parse_row(fields, &plan, line, &mut temps, &mut gyros)
                    .and_then(|time| check_time(time, previous, &plan.columns, line, fields));
                match parsed {
                    Ok(time) => {
                        if previous.is_none() {
                            report.time_origin_s = time;
                        }
                        previous = Some(time);
                        report.rows += 1;
                        seen.push(Seen::of(&Row {
                            line,
                            time_s: time - report.time_origin_s,
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
}
