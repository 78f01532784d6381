//! Fuzz target: the parallel CSV reader (worker threads parse chunks of whole records, merged
//! in order; what `fit` uses on a log of 1 MiB or more) must hand out exactly what the
//! one-thread reader does, on arbitrary bytes: the same rows (line, time, temperatures, gyros,
//! bit for bit), the same report, or the same error. Its chunks, buffer and batches are shrunk
//! to a few bytes (from the third input byte), so that small inputs cross every chunk
//! boundary. Options from the first two bytes as in `ingest_csv` (shared: `ingest_options.rs`).
#![no_main]

use std::path::Path;

use fogtemp_cal::ingest::{read_from, read_from_in_chunks, IngestReport};
use libfuzzer_sys::fuzz_target;

#[path = "ingest_options.rs"]
mod ingest_options;

fuzz_target!(|data: &[u8]| {
    let (Some(&a), Some(&b), Some(&c)) = (data.first(), data.get(1), data.get(2)) else { return };
    let options = ingest_options::options(a, b);
    let bytes = &data[3..];
    let chunk_bytes = usize::from(c & 0x3f) + 1;
    let workers = usize::from(c >> 6) + 1;
    let one_thread = rows_of(|visit| read_from(bytes, Path::new("fuzz.csv"), &options, visit, |_, _| {}));
    let parallel =
        rows_of(|visit| read_from_in_chunks(bytes, Path::new("fuzz.csv"), &options, workers, chunk_bytes, visit));
    assert_eq!(one_thread, parallel, "chunks of {chunk_bytes} bytes, {workers} workers");
});

/// A row as bits (NaN temperatures compare equal to themselves).
type Bits = (u64, u64, Vec<u64>, Vec<u64>);

/// Every row the read hands out, and its report or its error as text.
fn rows_of(
    read: impl FnOnce(&mut dyn FnMut(&fogtemp_cal::ingest::Row<'_>) -> Result<(), fogtemp_cal::CalError>) -> Result<IngestReport, fogtemp_cal::CalError>,
) -> (Vec<Bits>, Result<String, String>) {
    let mut rows = Vec::new();
    let outcome = read(&mut |row| {
        rows.push((
            row.line,
            row.time_s.to_bits(),
            row.temps_c.iter().map(|t| t.to_bits()).collect(),
            row.gyros_dph.iter().map(|g| g.to_bits()).collect(),
        ));
        Ok(())
    });
    (rows, outcome.map(|report| format!("{report:?}")).map_err(|e| e.to_string()))
}
