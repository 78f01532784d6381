//! Physics simulator of the lab experiment (`fogtemp-cal simulate`).
//!
//! A [`Scenario`] (TOML) describes the protocol, the thermal network, the bias physics, the
//! noise and the temperature sensor. Each run is computed in two passes: the deterministic
//! truth on a 1 s grid with the exact discrete step of the linear thermal network
//! ([`thermal`]), then samples at the gyro rate (truth interpolated linearly, plus noise,
//! plus the logged sensor). Runs are independent and deterministic per seed and run name,
//! so they are generated in parallel with rayon and stream to CSV in the log format of
//! docs/architecture.md (Contracts: log format) (`time_s,temp_c,gyro_dph`).

pub mod demo;
pub mod documents;
pub mod error;
pub mod noise;
pub mod run;
pub mod scenario;
pub mod thermal;

use std::io::Write;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;

pub use error::SimError;
pub use run::{run_truth, RunGenerator, RunTruth, Sample, TruthPoint};
pub use scenario::{RunSpec, Scenario, PAPER_TOML};

use fogtemp_cal::manifest::{MANIFEST_FILE, UNFINISHED_FILE};
use fogtemp_cal::output::write_file_atomic;
use fogtemp_cal::CalError;

/// Samples between progress reports.
const PROGRESS_EVERY: u64 = 1 << 16;
/// Bytes buffered before a write.
const WRITE_CHUNK: usize = 1 << 20;

/// What was written for one run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunSummary {
    /// Run name (file stem).
    pub name: String,
    /// The log file.
    pub file: PathBuf,
    /// The truth file (1 s grid).
    pub truth_file: PathBuf,
    /// Position label.
    pub group: String,
    /// Chamber temperature at the start, deg C.
    pub start_temp_c: f64,
    /// Input axis, unit vector north-east-down.
    pub input_axis_ned: [f64; 3],
    /// Earth rate on the input axis, deg/h.
    pub input_rate_dph: f64,
    /// Turn-on bias drawn for this run, deg/h.
    pub turn_on_dph: f64,
    /// Samples written.
    pub samples: u64,
    /// Length, s.
    pub duration_s: f64,
    /// `soaked` (power-on) or `warm` (hot restart).
    pub initial: scenario::InitialState,
}

/// Decimals of the time column: the fewest (up to 6) that print every sample time exactly.
pub fn time_decimals(rate_hz: f64) -> usize {
    (0..=6).find(|&d| (10f64.powi(d as i32) / rate_hz).fract().abs() < 1e-9).unwrap_or(6)
}

/// Appends `value` with exactly `decimals` digits after the point (no exponent).
pub fn push_fixed(buf: &mut Vec<u8>, value: f64, decimals: usize) {
    let scale = 10f64.powi(decimals as i32);
    let scaled = (value * scale).round();
    if !scaled.is_finite() || scaled.abs() >= 9.0e18 {
        let _ = write!(buf, "{value:.decimals$}");
        return;
    }
    let mut n = scaled as i64;
    if n < 0 {
        buf.push(b'-');
        n = -n;
    }
    let n = n as u64;
    let p = 10u64.pow(decimals as u32);
    push_digits(buf, n / p, 1);
    if decimals > 0 {
        buf.push(b'.');
        push_digits(buf, n % p, decimals);
    }
}

/// Appends `n` in decimal with at least `width` digits (zero padded).
fn push_digits(buf: &mut Vec<u8>, mut n: u64, width: usize) {
    let mut digits = [0u8; 20];
    let mut len = 0;
    while n > 0 || len < width {
        digits[len] = b'0' + (n % 10) as u8;
        n /= 10;
        len += 1;
    }
    buf.extend(digits[..len].iter().rev());
}

/// Streams one run's log (`time_s,temp_c,gyro_dph`) to `out`; `progress(samples)` is called
/// with increments. Returns the number of samples.
///
/// # Errors
/// I/O errors of `out`.
pub fn write_run_csv(
    scenario: &Scenario,
    truth: &RunTruth,
    out: &mut impl Write,
    progress: &(dyn Fn(u64) + Sync),
) -> std::io::Result<u64> {
    let decimals = time_decimals(scenario.sample_rate_hz);
    let mut buf = Vec::with_capacity(WRITE_CHUNK + 256);
    buf.extend_from_slice(b"time_s,temp_c,gyro_dph\n");
    let mut written = 0u64;
    for sample in RunGenerator::new(scenario, truth) {
        push_fixed(&mut buf, sample.time_s, decimals);
        buf.push(b',');
        push_fixed(&mut buf, sample.temp_c, 4);
        buf.push(b',');
        push_fixed(&mut buf, sample.gyro_dph, 4);
        buf.push(b'\n');
        written += 1;
        if buf.len() >= WRITE_CHUNK {
            out.write_all(&buf)?;
            buf.clear();
        }
        if written % PROGRESS_EVERY == 0 {
            progress(PROGRESS_EVERY);
        }
    }
    out.write_all(&buf)?;
    progress(written % PROGRESS_EVERY);
    Ok(written)
}

/// Writes the truth grid of a run as CSV.
///
/// # Errors
/// I/O errors of `out`.
pub fn write_truth_csv(truth: &RunTruth, out: &mut impl Write) -> std::io::Result<()> {
    let mut buf = Vec::with_capacity(truth.points.len() * 120);
    buf.extend_from_slice(
        b"time_s,ambient_c,electronics_c,case_c,coil_c,sensor_true_c,bias_temp_c,coil_rate_c_per_min,\
gradient_c,gradient_rate_c_per_min,power_w,bias_dph,output_dph\n",
    );
    for p in &truth.points {
        let fields = [
            p.time_s,
            p.ambient_c,
            p.electronics_c,
            p.case_c,
            p.coil_c,
            p.sensor_c,
            p.bias_temp_c,
            p.coil_rate_c_per_min,
            p.gradient_c,
            p.gradient_rate_c_per_min,
            p.power_w,
            p.bias_dph,
            p.output_dph,
        ];
        for (i, v) in fields.iter().enumerate() {
            if i > 0 {
                buf.push(b',');
            }
            push_fixed(&mut buf, *v, 6);
        }
        buf.push(b'\n');
    }
    out.write_all(&buf)
}

/// Bytes of CSV a simulated sample takes, about: the paper scenario at 1 kHz writes 2.7 GB
/// for 115.2 M samples.
pub const CSV_BYTES_PER_SAMPLE: f64 = 24.0;

/// CSV beyond what any disk holds (1 PB): refused before the first row (review27a 7:
/// `--rate 1e12` started writing about 3 EB without a word).
pub const MAX_CSV_BYTES: f64 = 1e15;

/// The CSV `scenario`'s logs take, bytes, about ([`CSV_BYTES_PER_SAMPLE`]).
///
/// # Errors
/// [`SimError::TooLarge`] beyond [`MAX_CSV_BYTES`].
pub fn csv_bytes(scenario: &Scenario) -> Result<f64, SimError> {
    let runs = scenario.expanded_runs();
    let samples: f64 = runs.iter().map(|r| (r.duration_s * scenario.sample_rate_hz).floor() + 1.0).sum();
    let bytes = samples * CSV_BYTES_PER_SAMPLE;
    if bytes > MAX_CSV_BYTES {
        return Err(SimError::TooLarge {
            runs: runs.len(),
            samples,
            rate_hz: scenario.sample_rate_hz,
            bytes,
        });
    }
    Ok(bytes)
}

/// Simulates every run of `scenario` into `dir` (one `NAME.csv` per run, `truth/NAME.csv`,
/// `scenario.toml` with `scenario_text` and `manifest.json`), runs in parallel.
/// `progress(samples)` receives increments from any thread. While it writes, the folder holds
/// [`UNFINISHED_FILE`] and no manifest: the marker is removed after the manifest is written,
/// so a folder left by an interrupted simulation says so.
///
/// # Errors
/// [`SimError::Cal`] with [`CalError::Io`] or [`CalError::Output`] naming the file that could
/// not be written; [`SimError::TooLarge`] for more CSV than a disk holds;
/// [`SimError::NotASimulationFolder`] for a folder holding a log of a run that is not a
/// simulation's.
pub fn simulate_to_dir(
    scenario: &Scenario,
    scenario_text: &str,
    dir: &Path,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Vec<RunSummary>, SimError> {
    csv_bytes(scenario)?;
    refuse_a_file(dir)?;
    refuse_overwriting_other_logs(scenario, dir)?;
    refuse_unreadable_scenario(scenario)?;
    let truth_dir = dir.join("truth");
    std::fs::create_dir_all(&truth_dir).map_err(|source| CalError::Io { path: truth_dir.clone(), source })?;
    let marker = mark_unfinished(scenario, dir)?;
    let runs = scenario.expanded_runs();
    let summaries = runs
        .par_iter()
        .map(|spec| {
            let truth = run_truth(scenario, spec);
            let file = dir.join(format!("{}.csv", spec.name));
            let truth_file = truth_dir.join(format!("{}.csv", spec.name));
            write_file_atomic(&truth_file, |mut w| write_truth_csv(&truth, &mut w))?;
            let mut samples = 0;
            write_file_atomic(&file, |mut w| {
                samples = write_run_csv(scenario, &truth, &mut w, progress)?;
                Ok(())
            })?;
            Ok(RunSummary {
                name: spec.name.clone(),
                file,
                truth_file,
                group: spec.group.clone(),
                start_temp_c: spec.chamber.start_c(),
                input_axis_ned: spec.input_axis.ned().unwrap_or([f64::NAN; 3]),
                input_rate_dph: truth.input_rate_dph,
                turn_on_dph: truth.turn_on_dph,
                samples,
                duration_s: spec.duration_s,
                initial: spec.initial,
            })
        })
        .collect::<Result<Vec<_>, SimError>>()?;
    write_file_atomic(&dir.join("scenario.toml"), |w| w.write_all(scenario_text.as_bytes()))?;
    let manifest = Manifest {
        scenario: scenario.name.clone(),
        sample_rate_hz: scenario.sample_rate_hz,
        seed: scenario.seed,
        columns: ["time_s", "temp_c", "gyro_dph"],
        runs: summaries.iter().map(relative_to_folder).collect(),
    };
    let json = serde_json::to_vec_pretty(&manifest)
        .map_err(|e| SimError::Serialise { what: "manifest", message: e.to_string() })?;
    write_file_atomic(&dir.join(MANIFEST_FILE), |w| w.write_all(&json))?;
    std::fs::remove_file(&marker).map_err(|source| CalError::Io { path: marker, source })?;
    Ok(summaries)
}

/// Refuses an output path that is a file (review27a 14.8: "File exists (os error 17)").
///
/// # Errors
/// [`SimError::OutputIsAFile`].
pub fn refuse_a_file(dir: &Path) -> Result<(), SimError> {
    let what = match std::fs::symlink_metadata(dir) {
        Ok(_) if dir.is_dir() => return Ok(()),
        Ok(meta) if meta.file_type().is_symlink() && !dir.exists() => {
            let target = std::fs::read_link(dir).unwrap_or_default();
            format!("a link to {}, which does not exist", target.display())
        }
        Ok(_) => "a file".to_string(),
        Err(_) => return Ok(()),
    };
    Err(SimError::OutputIsAFile { path: dir.to_path_buf(), what })
}

/// Refuses a scenario whose logs its own reader would refuse, naming the first run and time
/// (review27a 7: `power_w = 1e30` wrote logs of 1e22 C that `fit` stopped on at their third
/// line, and `simulate` said nothing): the logged temperature must stay one a sensor reads
/// (-273.15 to 1000 C, `fogtemp_core::is_physical_temperature`) with the sensor's offset and
/// six standard deviations of its noise either way, and the gyro within f32. Computes every
/// run's 1 s truth (cheap beside the samples); callers check it before making the folder.
///
/// # Errors
/// [`SimError::Unreadable`].
pub fn refuse_unreadable_scenario(scenario: &Scenario) -> Result<(), SimError> {
    scenario
        .expanded_runs()
        .par_iter()
        .try_for_each(|spec| refuse_unreadable(scenario, &run_truth(scenario, spec)))
}

fn refuse_unreadable(scenario: &Scenario, truth: &RunTruth) -> Result<(), SimError> {
    let offset_c = scenario.sensor.offset_c;
    let spread_c = 6.0 * scenario.sensor.noise_c;
    let readable = |t: f64| fogtemp_core::is_physical_temperature(t as f32);
    for p in &truth.points {
        let logged_c = p.sensor_c + offset_c;
        let unreadable = |what: String, limit| {
            Err(SimError::Unreadable { run: truth.spec.name.clone(), time_s: p.time_s, what, limit })
        };
        if !(readable(logged_c - spread_c) && readable(logged_c + spread_c)) {
            return unreadable(
                format!("a temperature of {logged_c:.4e} C (its sensor's offset included, noise +-{spread_c:.3e} C)"),
                "what a sensor reads (-273.15 to 1000 C)",
            );
        }
        if !(p.output_dph as f32).is_finite() {
            return unreadable(format!("a gyro of {:.4e} deg/h", p.output_dph), "what an f32 holds (3.4e38)");
        }
    }
    Ok(())
}

/// The marker's line before the runs it lists.
const MARKER_RUNS_LINE: &str = "Runs being written:";

/// The runs' logs a marker lists ([`mark_unfinished`]).
fn marker_runs(marker: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(marker).unwrap_or_default();
    text.lines()
        .skip_while(|l| l.trim() != MARKER_RUNS_LINE)
        .skip(1)
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect()
}

/// Refuses a folder that holds a log of one of the runs but is not a simulation's (no
/// `manifest.json`, no [`UNFINISHED_FILE`]): it may be a lab's recording, which the simulated
/// log would replace. A simulation's folder, finished or not, is simulated into again.
/// (Python's `simulate` had no such check before 2026-11-29: only the command line did.)
fn refuse_overwriting_other_logs(scenario: &Scenario, dir: &Path) -> Result<(), SimError> {
    if !dir.is_dir() || dir.join(MANIFEST_FILE).is_file() {
        return Ok(());
    }
    // An interrupted simulation's marker makes the logs it lists its own (review30b F2: any
    // marker made every log in the folder replaceable, a lab's too).
    let ours = marker_runs(&dir.join(UNFINISHED_FILE));
    let foreign = |name: &String| {
        let file = format!("{name}.csv");
        dir.join(&file).exists() && !ours.contains(&file)
    };
    match scenario.expanded_runs().iter().find(|r| foreign(&r.name)) {
        Some(run) => Err(SimError::NotASimulationFolder { dir: dir.to_path_buf(), run: run.name.clone() }),
        None => Ok(()),
    }
}

/// Marks `dir` as holding a simulation being written ([`UNFINISHED_FILE`]) and removes the
/// manifest of an earlier one, so that an interrupted simulation leaves a folder that says so
/// (review27a 10: two runs of sixteen looked like a finished campaign, and `simulate` then
/// refused the folder as not its own). Returns the marker's path, removed when the manifest
/// is written.
fn mark_unfinished(scenario: &Scenario, dir: &Path) -> Result<PathBuf, SimError> {
    let marker = dir.join(UNFINISHED_FILE);
    let runs: String = scenario.expanded_runs().iter().map(|r| format!("  {}.csv\n", r.name)).collect();
    let text = format!(
        "A fogtemp simulation (fogtemp-cal simulate or demo, or Python's fogtemp.simulate) began writing here\n\
         (scenario '{}', {} runs) and has not finished. If this file remains, it was interrupted or failed:\n\
         the logs here are a part of the campaign at most, and fit, validate and diagnose warn of them.\n\
         Simulate into this folder again to replace them.\n\n{MARKER_RUNS_LINE}\n{runs}",
        scenario.name,
        scenario.expanded_runs().len()
    );
    write_file_atomic(&marker, |w| w.write_all(text.as_bytes()))?;
    let manifest = dir.join(MANIFEST_FILE);
    match std::fs::remove_file(&manifest) {
        Err(source) if source.kind() != std::io::ErrorKind::NotFound => {
            Err(CalError::Io { path: manifest, source }.into())
        }
        _ => Ok(marker),
    }
}

/// A run's summary for `manifest.json`: its files named relative to the simulation's folder
/// (`NAME.csv`, `truth/NAME.csv`), so that the manifest stays true wherever the folder is read
/// from or moved to (the summary itself keeps the paths as written, for its caller).
fn relative_to_folder(run: &RunSummary) -> RunSummary {
    RunSummary {
        file: PathBuf::from(format!("{}.csv", run.name)),
        truth_file: Path::new("truth").join(format!("{}.csv", run.name)),
        ..run.clone()
    }
}

/// `manifest.json` of a simulation folder: what each log is.
#[derive(Clone, Debug, Serialize)]
pub struct Manifest {
    /// Scenario name.
    pub scenario: String,
    /// Gyro rate, Hz.
    pub sample_rate_hz: f64,
    /// Seed.
    pub seed: u64,
    /// Columns of every log.
    pub columns: [&'static str; 3],
    /// The runs.
    pub runs: Vec<RunSummary>,
}

/// Every run's samples in memory (for tests and small rates; a 2 h run at 1 kHz is 170 MB).
pub fn simulate_in_memory(scenario: &Scenario) -> Vec<(RunTruth, Vec<Sample>)> {
    scenario
        .expanded_runs()
        .par_iter()
        .map(|spec| {
            let truth = run_truth(scenario, spec);
            let samples: Vec<Sample> = RunGenerator::new(scenario, &truth).collect();
            (truth, samples)
        })
        .collect()
}
