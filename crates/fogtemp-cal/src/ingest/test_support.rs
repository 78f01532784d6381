//! Shared test helpers: every way of running the reader, and what a run visited.

use std::io::Read;
use std::path::Path;

use super::{
    read_with_tuning, BadRow, BadRowKind, IngestOptions, IngestReport, Mode, Row, Tuning, BATCH_ROWS,
    BUFFER_BYTES, CHUNK_BYTES,
};
use crate::error::CalError;

/// Hands out at most `chunk` bytes per read, to put records across buffer refills.
pub(super) struct Chunky<'a> {
    pub(super) data: &'a [u8],
    pub(super) chunk: usize,
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
pub(super) struct Seen {
    pub(super) line: u64,
    pub(super) time: u64,
    pub(super) origin: u64,
    pub(super) temps: Vec<u64>,
    pub(super) gyros: Vec<u64>,
}

impl Seen {
    pub(super) fn of(row: &Row<'_>) -> Self {
        Self {
            line: row.line,
            time: row.time_s.to_bits(),
            origin: row.origin_s.to_bits(),
            temps: row.temps_c.iter().map(|v| v.to_bits()).collect(),
            gyros: row.gyros_dph.iter().map(|v| v.to_bits()).collect(),
        }
    }
}

pub(super) type Outcome = (Vec<Seen>, Result<IngestReport, CalError>);

/// Every way of running the reader: one thread or in parallel, big or tiny buffers,
/// batches and chunks, whole or dribbled reads.
pub(super) const MODES: [(Tuning, usize); 8] = [
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
pub(super) fn run(data: &[u8], options: &IngestOptions) -> Outcome {
    let first = run_mode(data, options, MODES[0].0, MODES[0].1);
    for (tuning, chunk) in &MODES[1..] {
        let other = run_mode(data, options, *tuning, *chunk);
        assert_eq!(first.0, other.0, "rows differ in mode {tuning:?} chunk {chunk}");
        assert_eq!(summary(&first.1), summary(&other.1), "result differs in mode {tuning:?}");
    }
    first
}

pub(super) fn summary(result: &Result<IngestReport, CalError>) -> String {
    match result {
        Ok(r) => format!(
            "ok rows {} skipped {} bytes {} origin {:?} last {:?} temps {:?} temperature-only {} first {:?}",
            r.rows,
            r.skipped,
            r.bytes,
            r.time_origin_s,
            r.last_time_s,
            r.temp_ends_c,
            r.temperature_only_rows,
            r.first_skipped
        ),
        Err(e) => format!("error {e}"),
    }
}

pub(super) fn default_options() -> IngestOptions {
    IngestOptions::default()
}

pub(super) fn skipping() -> IngestOptions {
    IngestOptions { skip_bad_rows: true, ..IngestOptions::default() }
}

/// The bad row of a failed run.
pub(super) fn bad(data: &str) -> BadRow {
    match run(data.as_bytes(), &default_options()).1 {
        Err(CalError::BadRow { row, .. }) => *row,
        other => panic!("expected a bad row, got {}", summary(&other)),
    }
}

pub(super) fn rows(data: &str, options: &IngestOptions) -> Vec<Seen> {
    let (seen, result) = run(data.as_bytes(), options);
    assert!(result.is_ok(), "{}", summary(&result));
    seen
}

pub(super) fn values(seen: &[Seen]) -> Vec<(u64, f64, Vec<f64>, Vec<f64>)> {
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

pub(super) const HEADER: &str = "time_s,temp_c,gyro_dph\n";

pub(super) fn expect(bad: &BadRow, line: u64, column: usize, name: &str, found: &str, kind: BadRowKind) {
    let want = BadRow { line, column, column_name: name.into(), found: found.into(), kind };
    assert_eq!(*bad, want);
}
