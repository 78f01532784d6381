//! `ingest/*`: bytes per second of reading a 1 kHz lab log (`read_log`) and of turning it
//! into calibration features (`extract_run`: ingest plus the core's feature tracker and the
//! smoothed targets), on a generated log in the format of a real logger. The comparison
//! with `pandas.read_csv` on the same file (Python, so outside criterion) is
//! `scripts/ingest-vs-pandas.sh`; results in `docs/ingest-performance.md`.

use std::hint::black_box;
use std::io::Write;
use std::time::Duration;

use criterion::{Criterion, Throughput};
use fogtemp_cal::calibrate::{extract_run, CalibrationConfig};
use fogtemp_cal::ingest::{read_log, IngestOptions};

/// Rows in the generated log: 10 minutes at 1 kHz (about 15 MB).
const ROWS: usize = 600_000;

/// Writes a warm-up log: time with 3 decimals, temperature quantised to 0.0625 C with 4,
/// gyro with 6 (a deterministic pseudo-noise, no RNG state needed).
fn write_log(path: &std::path::Path) -> u64 {
    let file = std::fs::File::create(path).expect("create bench log");
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "time_s,temp_c,gyro_dph").expect("write");
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for i in 0..ROWS {
        let t = i as f64 * 1e-3;
        let temp = 20.0 + 12.0 * (1.0 - (-t / 1200.0).exp());
        let temp_q = (temp / 0.0625).round() * 0.0625;
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let noise = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        let gyro = 0.05 + 0.002 * temp + 0.95 * noise;
        writeln!(w, "{t:.3},{temp_q:.4},{gyro:.6}").expect("write");
    }
    w.flush().expect("flush");
    std::fs::metadata(path).map(|m| m.len()).unwrap_or(0)
}

/// `ingest/read_log` and `ingest/extract_run`, throughput in bytes.
pub fn throughput(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bench-1khz.csv");
    let bytes = write_log(&path);
    let mut group = c.benchmark_group("ingest");
    group.throughput(Throughput::Bytes(bytes));
    group.sample_size(10).measurement_time(Duration::from_secs(8));
    group.bench_function("read_log", |b| {
        b.iter(|| {
            let mut sum = 0.0f64;
            let report = read_log(
                &path,
                &IngestOptions::default(),
                |row| {
                    sum += row.gyros_dph[0];
                    Ok(())
                },
                |_| {},
            )
            .expect("bench log reads");
            black_box((sum, report.rows))
        })
    });
    group.bench_function("extract_run", |b| {
        b.iter(|| {
            let run = extract_run(&path, &CalibrationConfig::default(), |_, _| {}).expect("features");
            black_box(run.axes.len())
        })
    });
    group.finish();
}
