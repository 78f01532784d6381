//! Ingest throughput measurement (see `docs/ingest-performance.md`).
//!
//! ```text
//! ingest_throughput gen OUT.csv [--runs N] [--rows-per-run R]   # streaming 1 kHz log generator
//! ingest_throughput read LOG.csv [--repeat N]                     # read_log alone
//! ingest_throughput features LOG.csv [--repeat N]                 # extract_run (ingest + features)
//! ```
//!
//! `read` and `features` print one line per repetition and a final `best` line with MB/s
//! (10^6 bytes per second) and rows/s; peak memory is measured from outside
//! (`/usr/bin/time -f %M`).

use std::hint::black_box;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use fogtemp_cal::calibrate::{extract_run, CalibrationConfig};
use fogtemp_cal::ingest::{read_log, IngestOptions};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str, default: u64| -> u64 {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .map_or(default, |v| v.parse().unwrap_or_else(|_| panic!("{name} needs a number, got {v}")))
    };
    // A path that looks like an option (`gen --help`) is the usage, not a file to write.
    let (Some(cmd), Some(path)) = (args.first(), args.get(1).filter(|p| !p.starts_with('-'))) else {
        eprintln!(
            "usage: ingest_throughput gen|read|features PATH [--runs N] [--rows-per-run R] [--repeat N]"
        );
        std::process::exit(2);
    };
    let path = PathBuf::from(path);
    match cmd.as_str() {
        "gen" => generate(&path, flag("--runs", 1), flag("--rows-per-run", 7_200_000))
            .unwrap_or_else(|e| panic!("writing {}: {e}", path.display())),
        "read" | "features" => measure(cmd, &path, flag("--repeat", 3)),
        other => {
            eprintln!("unknown command {other}");
            std::process::exit(2);
        }
    }
}

fn measure(cmd: &str, path: &Path, repeat: u64) {
    let mut best = f64::INFINITY;
    let (mut bytes, mut rows) = (0u64, 0u64);
    for i in 0..repeat.max(1) {
        let start = Instant::now();
        let mut progress_calls = 0u64;
        let mut progress = |_: u64| progress_calls += 1;
        let (report, extra) = if cmd == "read" {
            let mut sum = 0.0f64;
            let report = read_log(
                path,
                &IngestOptions::default(),
                |row| {
                    sum += row.time_s + row.gyros_dph[0] + row.temps_c[0];
                    Ok(())
                },
                &mut progress,
            )
            .unwrap_or_else(|e| panic!("{e}"));
            (report, format!("checksum {:.6e}", black_box(sum)))
        } else {
            let run = extract_run(path, &CalibrationConfig::default(), |bytes, _rows| progress(bytes))
                .unwrap_or_else(|e| panic!("{e}"));
            let points = run.axes.first().map_or(0, |a| a.0.len());
            // A hash of every feature and target, to check optimisations change nothing.
            let mut hash = 0u64;
            for (features, targets) in &run.axes {
                for (f, t) in features.iter().zip(targets) {
                    for v in [f.time_s, f.temp_c, f.rate_c_per_min, f.gyro_mean_dph, *t] {
                        hash = (hash ^ v.to_bits()).wrapping_mul(0x0100_0000_01b3);
                    }
                }
            }
            (run.ingest, format!("feature points {points}, hash {hash:016x}"))
        };
        let secs = start.elapsed().as_secs_f64();
        best = best.min(secs);
        bytes = report.bytes;
        rows = report.rows;
        println!(
            "{cmd} #{i}: {secs:.3} s, {:.1} MB/s, {:.2} M rows/s, {rows} rows, {} skipped, {progress_calls} progress calls, {extra}",
            bytes as f64 / secs / 1e6,
            rows as f64 / secs / 1e6,
            report.skipped,
        );
    }
    println!(
        "best {cmd}: {best:.3} s, {:.1} MB/s, {:.2} M rows/s ({bytes} bytes, {rows} rows)",
        bytes as f64 / best / 1e6,
        rows as f64 / best / 1e6
    );
}

/// Small deterministic PRNG (xorshift64*), enough for sensor noise.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Approximately normal (sum of four uniforms), unit variance.
    fn gauss(&mut self) -> f64 {
        let s: f64 = (0..4).map(|_| self.uniform()).sum();
        (s - 2.0) * 3.0f64.sqrt()
    }
}

/// Writes a 1 kHz log, `runs` 2-hour temperature cycles concatenated in time, streaming:
/// `time_s` with 3 decimals, `temp_c` quantised to 0.0625 with 4 decimals, `gyro_dph`
/// with 6 decimals (a bias that depends on temperature and its rate, plus white noise).
fn generate(path: &Path, runs: u64, rows_per_run: u64) -> std::io::Result<()> {
    let mut out = BufWriter::with_capacity(1 << 20, std::fs::File::create(path)?);
    writeln!(out, "time_s,temp_c,gyro_dph")?;
    let mut noise = Noise(0x9e37_79b9_7f4a_7c15);
    let period_s = rows_per_run as f64 / 1000.0;
    for run in 0..runs {
        let ambient = 20.0 + 5.0 * (run as f64 * 0.7).sin();
        for i in 0..rows_per_run {
            let ms = run * rows_per_run + i;
            let t = i as f64 / 1000.0;
            let phase = std::f64::consts::TAU * t / period_s;
            // A -20..+60 deg C cycle around the ambient, plus sensor noise.
            let temp = ambient + 20.0 - 40.0 * phase.cos() + 0.02 * noise.gauss();
            let temp_q = (temp / 0.0625).round() * 0.0625 + 0.0; // no "-0.0000"
            let rate = 40.0 * phase.sin() * std::f64::consts::TAU / (period_s / 60.0);
            let gyro = 0.8
                + 0.004 * (temp - 25.0)
                + 0.0001 * (temp - 25.0).powi(2)
                + 0.3 * rate
                + 0.05 * noise.gauss();
            writeln!(out, "{}.{:03},{temp_q:.4},{gyro:.6}", ms / 1000, ms % 1000)?;
        }
    }
    out.flush()
}
