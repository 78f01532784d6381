//! Fuzz target: the CSV ingest (`fogtemp_cal::ingest::read_from`) on arbitrary bytes, under
//! option sets drawn from the first two bytes, must never panic, and every row it hands out
//! must keep ingest's rules: time finite and strictly increasing (from 0 at the first
//! accepted row), gyros finite, temperatures NaN or physical, lines increasing; a read that
//! succeeds counts exactly the rows it handed out; an error from the visitor stops the read
//! and is returned; every error formats.
#![no_main]

use std::path::Path;

use fogtemp_cal::ingest::{read_from, IngestOptions};
use fogtemp_cal::CalError;
use libfuzzer_sys::fuzz_target;

#[path = "ingest_options.rs"]
mod ingest_options;

fuzz_target!(|data: &[u8]| {
    let (Some(&a), Some(&b)) = (data.first(), data.get(1)) else { return };
    let options = ingest_options::options(a, b);
    let stop_after = (b & 0x80 != 0).then_some(3u64);
    read(&data[2..], &options, stop_after);
});

/// Reads `bytes` with `options`, checking every row; the visitor fails after `stop_after` rows.
fn read(bytes: &[u8], options: &IngestOptions, stop_after: Option<u64>) {
    let mut rows = 0u64;
    let mut previous: Option<(f64, u64)> = None;
    let outcome = read_from(
        bytes,
        Path::new("fuzz.csv"),
        options,
        |row| {
            assert!(row.time_s.is_finite(), "time {}", row.time_s);
            match previous {
                None => assert!(row.time_s == 0.0 || options.format.sample_rate_hz.is_some(), "first time {}", row.time_s),
                Some((t, line)) => {
                    assert!(row.time_s > t, "time {} after {t}", row.time_s);
                    // Every record ends a line (`\n`, `\r\n` or a lone `\r`).
                    assert!(row.line > line, "line {} after {line}", row.line);
                }
            }
            previous = Some((row.time_s, row.line));
            assert_eq!(row.gyros_dph.len(), options.format.gyro_columns.len());
            assert!(row.gyros_dph.iter().all(|g| g.is_finite()), "gyros {:?}", row.gyros_dph);
            assert!(row.temps_c.iter().all(|t| t.is_nan() || (t.is_finite() && *t > -273.2 && *t < 1000.1)), "temps {:?}", row.temps_c);
            rows += 1;
            if stop_after == Some(rows) {
                return Err(CalError::NonFinite { what: "fuzz stop", index: 0 });
            }
            Ok(())
        },
        |_, _| {},
    );
    match outcome {
        Ok(report) => {
            assert_eq!(report.rows, rows);
            assert!(stop_after.is_none_or(|n| rows < n), "the visitor's error was lost");
            assert!(report.first_skipped.len() as u64 <= report.skipped);
            assert!(options.skip_bad_rows || report.skipped == 0);
        }
        Err(e) => {
            let _ = e.to_string();
            if let CalError::NonFinite { what: "fuzz stop", .. } = e {
                assert_eq!(stop_after, Some(rows));
            }
        }
    }
}
