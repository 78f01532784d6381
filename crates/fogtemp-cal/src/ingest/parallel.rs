//! The parallel reader: worker threads parse chunks of whole records, the calling thread
//! merges them in order and runs the visitor.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;
use std::sync::{mpsc, Mutex};

use memchr::{memchr, memrchr2};

use super::batch::{Batch, Consumer};
use super::columns::{continue_time, is_temperature_only, RowState};
use super::parser::{Parser, Source};
use super::{IngestReport, Row, Tuning, MAX_REPORTED_BAD_ROWS, PROGRESS_EVERY_BYTES};
use crate::error::CalError;

/// The parallel reader, once `head` has read the header: workers take chunks of whole
/// records from a shared reader and parse them each on their own (relative lines,
/// absolute times, the first row's time not yet checked); the calling thread merges
/// them in order and visits the rows. A chunk whose first row is not after the previous
/// chunk's last is parsed again in order. At the first quote the rest of the log goes to
/// one sequential parser (a quoted field may hold a newline, so records can no longer be
/// cut at newlines).
pub(super) fn read_parallel<R, F, P>(
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
        carry_after_cr: src.after_cr,
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
    /// The byte before `carry[0]` was a `\r` counted as a line break (a `\r\n` cut in two).
    carry_after_cr: bool,
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
        chunk.after_cr = self.carry_after_cr;
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
        self.carry_after_cr = cut.checked_sub(1).and_then(|i| chunk.data.get(i)) == Some(&b'\r');
        chunk.data.truncate(cut);
        self.offset = chunk.start + cut as u64;
        if let Some(quote) = memchr(b'"', &chunk.data) {
            let record = memrchr2(b'\n', b'\r', &chunk.data[..quote]).map_or(0, |i| i + 1);
            let after_cr = match record.checked_sub(1) {
                Some(i) => chunk.data.get(i) == Some(&b'\r'),
                None => chunk.after_cr,
            };
            let mut rest = chunk.data.split_off(record);
            rest.append(&mut self.carry);
            if let Some(reader) = self.reader.take() {
                chunk.rest =
                    Some(Rest { bytes: rest, offset: chunk.start + record as u64, after_cr, reader });
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
    /// The byte before `bytes[0]` was a `\r` (see [`Source::after_cr`]).
    after_cr: bool,
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
    /// Line breaks in `data`.
    newlines: u64,
    /// The byte before `data[0]` was a `\r` (see [`Source::after_cr`]).
    after_cr: bool,
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
            after_cr: false,
        }
    }

    /// Parses the chunk on its own (see [`RowState::for_chunk`]).
    fn parse(&mut self, path: &Path, template: &RowState) {
        if self.error.is_some() {
            return;
        }
        let data = std::mem::take(&mut self.data);
        let end = data.len();
        let src = Source {
            reader: std::io::empty(),
            buf: data,
            pos: 0,
            end,
            eof: true,
            base: self.start,
            line: 0,
            after_cr: self.after_cr,
        };
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

/// A log with times of day: a worker counted days from its chunk's first row, so its
/// rows go on by whole days to follow the previous chunk's last row (as [`continue_time`]
/// places the first row; the rest keep their distance from it).
fn continue_chunk_clock(rows: &RowState, batch: &mut Batch, stride: usize) {
    let (Some(plan), Some(&first)) = (&rows.plan, batch.values.first()) else { return };
    let days_s = continue_time(plan, first, rows.previous_time) - first;
    if days_s != 0.0 {
        for time in batch.values.iter_mut().step_by(stride.max(1)) {
            *time += days_s;
        }
    }
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
        continue_chunk_clock(&self.rows, batch, stride);
        let first_time = batch.values.first().copied();
        let in_order = match (self.rows.previous_time, first_time) {
            (Some(previous), Some(first)) => first > previous,
            _ => true,
        };
        if in_order {
            let base = self.line;
            if let Some(first) = first_time {
                let temps = self.consumer.temps;
                let is_sample = |v: &&[f64]| !is_temperature_only(&v[1 + temps..]);
                let mut samples = batch.values.chunks_exact(stride.max(1)).filter(is_sample);
                // The file's time zero is its first sample's (a temperature row is not one).
                let origin = match samples.next() {
                    Some(v) => *self.rows.origin.get_or_insert(v[0]),
                    None => self.rows.origin.unwrap_or(first),
                };
                self.consumer.visit_rows(batch, base, origin, origin, visit)?;
                self.rows.previous_time = batch.values.len().checked_sub(stride).map(|i| batch.values[i]);
                if let Some(last) = batch.values.chunks_exact(stride.max(1)).rev().find(is_sample) {
                    self.rows.previous_sample_time = Some(last[0]);
                }
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
            after_cr: chunk.after_cr,
        };
        let mut parser = Parser::resume(self.path, src, rows);
        let mut batch = Batch::default();
        let result = loop {
            parser.fill(&mut batch, self.tuning.batch_rows.max(1));
            // Times are relative already, lines absolute.
            if let Err(e) = self.consumer.visit_rows(&batch, 0, 0.0, batch.origin_s, visit) {
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
        let src = Source {
            reader: rest.reader,
            buf,
            pos: 0,
            end,
            eof: false,
            base: rest.offset,
            line: self.line,
            after_cr: rest.after_cr,
        };
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ingest::test_support::*;
    use crate::ingest::{read_with_tuning, Mode};

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
        // Each record on its own line (a lone '\r' ends a line), in every mode.
        assert!(seen.iter().enumerate().all(|(i, s)| s.line == i as u64 + 2));
        // Chunks of at most a few records (not the whole log): 3000 rows, 64-byte chunks.
        let tuning = Tuning { mode: Mode::Parallel { workers: 2 }, chunk_bytes: 64, ..Tuning::default() };
        let mut chunker = Chunker {
            reader: Some(data.as_bytes()),
            carry: Vec::new(),
            carry_after_cr: false,
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
}
