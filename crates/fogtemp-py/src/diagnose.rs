//! `fogtemp.diagnose`: simulated vs recorded logs through `fogtemp_diagnose::diagnose`, as
//! the command line's `diagnose --json` does it.
//!
//! The reading of logs into 1 s means, the pairing by file name and the run metadata from
//! `runs` or the simulation's `manifest.json` follow `fogtemp-cli/src/commands/diagnose.rs`
//! step for step (that glue lives in the command, not in a library; moving it into
//! `fogtemp-diagnose` would let both callers share one copy).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use fogtemp_cal::ingest::{read_log_with_progress, IngestOptions};
use fogtemp_diagnose::{DiagnoseDocument, DiagnoseOptions, RunMeta, RunSeries};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert;
use crate::errors;
use crate::functions::expand_logs;
use crate::options::{self, Options};
use crate::progress::{self, Progress};

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// A log as `bin_s` means of time, temperature (NaN in bins without a reading) and gyro (axis 0).
fn read_series(
    path: &Path,
    ingest: &IngestOptions,
    bin_s: f64,
    meta: RunMeta,
    show: bool,
) -> PyResult<(RunSeries, u64)> {
    let mut series = RunSeries { name: file_name(path), meta, ..RunSeries::default() };
    // (bin, n, sum t, n temp, sum temp, sum gyro)
    let mut acc: (i64, f64, f64, f64, f64, f64) = (i64::MIN, 0.0, 0.0, 0.0, 0.0, 0.0);
    let flush = |s: &mut RunSeries, a: &(i64, f64, f64, f64, f64, f64)| {
        if a.1 > 0.0 {
            s.time_s.push(a.2 / a.1);
            s.temp_c.push(if a.3 > 0.0 { a.4 / a.3 } else { f64::NAN });
            s.gyro_dph.push(a.5 / a.1);
        }
    };
    let mut bar = Progress::new(format!("read {}", file_name(path)), show);
    let report = read_log_with_progress(
        path,
        ingest,
        |row| {
            let bin = (row.time_s / bin_s).floor() as i64;
            if bin != acc.0 {
                flush(&mut series, &acc);
                acc = (bin, 0.0, 0.0, 0.0, 0.0, 0.0);
            }
            acc.1 += 1.0;
            acc.2 += row.time_s;
            let temp = row.temp_c_for_axis(0);
            if temp.is_finite() {
                acc.3 += 1.0;
                acc.4 += temp;
            }
            acc.5 += row.gyros_dph.first().copied().unwrap_or(f64::NAN);
            Ok(())
        },
        |b, r| bar.rows(b, r),
    );
    bar.finish();
    let report = report.map_err(errors::cal)?;
    flush(&mut series, &acc);
    if report.rows == 0 {
        return Err(errors::value(format!("{}: no data rows (only a header)", path.display())));
    }
    Ok((series, report.skipped))
}

/// Run metadata from `DIR/manifest.json` (written by `simulate`), keyed by file name.
fn manifest_meta(dir: &Path) -> PyResult<BTreeMap<String, RunMeta>> {
    let path = dir.join("manifest.json");
    if !path.is_file() {
        return Ok(BTreeMap::new());
    }
    let text = std::fs::read_to_string(&path)
        .map_err(|source| errors::cal(fogtemp_cal::CalError::Io { path: path.clone(), source }))?;
    let doc: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| errors::value(format!("{}: not valid JSON: {e}", path.display())))?;
    let mut out = BTreeMap::new();
    for run in doc["runs"].as_array().map(Vec::as_slice).unwrap_or_default() {
        let Some(name) = run["name"].as_str() else { continue };
        out.insert(
            format!("{name}.csv"),
            RunMeta {
                group: run["group"].as_str().filter(|g| !g.is_empty()).map(str::to_string),
                input_rate_dph: run["input_rate_dph"].as_f64(),
                power_on_at_s: None,
            },
        );
    }
    Ok(out)
}

/// Run metadata from a runs file, keyed by file name (every simulated log needs a row).
fn runs_file_meta(path: &Path, simulated: &[PathBuf]) -> PyResult<BTreeMap<String, RunMeta>> {
    let file = fogtemp_cal::runs::RunsFile::read(path).map_err(errors::cal)?;
    let rows = file.for_logs(simulated).map_err(errors::cal)?;
    Ok(simulated
        .iter()
        .zip(rows)
        .map(|(log, row)| {
            let meta = RunMeta {
                group: Some(row.position.clone()),
                input_rate_dph: Some(row.input_rate_dph),
                power_on_at_s: None,
            };
            (file_name(log), meta)
        })
        .collect())
}

/// Pairs simulated and recorded logs by file name; every log must have a partner.
fn pair(simulated: &[PathBuf], recorded: &[PathBuf]) -> PyResult<Vec<(PathBuf, PathBuf)>> {
    let by_name: BTreeMap<String, &PathBuf> = recorded.iter().map(|p| (file_name(p), p)).collect();
    let mut pairs = Vec::new();
    let mut unmatched = Vec::new();
    for s in simulated {
        match by_name.get(&file_name(s)) {
            Some(r) => pairs.push((s.clone(), (*r).clone())),
            None => unmatched.push(format!("simulated {} has no recorded log of that name", file_name(s))),
        }
    }
    let sim_names: BTreeSet<String> = simulated.iter().map(|p| file_name(p)).collect();
    for r in recorded {
        if !sim_names.contains(&file_name(r)) {
            unmatched.push(format!("recorded {} has no simulated log of that name", file_name(r)));
        }
    }
    if !unmatched.is_empty() {
        return Err(errors::value(format!(
            "runs are paired by file name, and {} are not:\n  {}",
            unmatched.len(),
            unmatched.join("\n  ")
        )));
    }
    Ok(pairs)
}

/// Compares simulated and recorded runs (the command line's `diagnose --json`): where they
/// differ, which physics the simulation left out, a fitted model of it, and whether it helps
/// on runs it did not see.
///
/// `simulated` and `recorded` are folders (or files) of logs paired by file name; `runs` a
/// runs file (`run,position,input_rate_dph`), else the simulation's `manifest.json` gives each
/// run's position and Earth rate. Keywords: `mean_window_s`, `bin_s`, `rate_window_s`,
/// `window_coverage`, `block_coverage` (the command's options, same defaults) and the
/// log-column options, which apply to the recorded logs.
#[pyfunction]
#[pyo3(signature = (simulated, recorded, runs = None, *, progress = true, **options))]
pub fn diagnose<'py>(
    py: Python<'py>,
    simulated: PathBuf,
    recorded: PathBuf,
    runs: Option<PathBuf>,
    progress: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut o = Options::new("diagnose", options);
    let recorded_ingest = options::ingest(&mut o)?;
    let defaults = DiagnoseOptions::default();
    let bin_s = o.f64("bin_s", 1.0)?;
    let settings = DiagnoseOptions {
        mean_window_s: o.f64("mean_window_s", 20.0)?,
        rate_window_s: o.f64("rate_window_s", 100.0)?,
        window_coverage: o.f64("window_coverage", 0.5)?,
        block_coverage: o.f64("block_coverage", 0.9)?,
        ..defaults
    };
    o.finish()?;
    if !(bin_s.is_finite() && bin_s > 0.0) {
        return Err(errors::value("bin_s must be positive"));
    }
    let simulated_logs = expand_logs(std::slice::from_ref(&simulated))?;
    let recorded_logs = expand_logs(std::slice::from_ref(&recorded))?;
    let pairs = pair(&simulated_logs, &recorded_logs)?;
    let meta = match &runs {
        Some(path) => runs_file_meta(path, &simulated_logs)?,
        None => manifest_meta(&simulated)?,
    };
    let sim_ingest = IngestOptions::default();
    let (mut sims, mut recs) = (Vec::new(), Vec::new());
    for (s, r) in &pairs {
        let m = meta.get(&file_name(s)).cloned().unwrap_or_default();
        let (series, _) = py.detach(|| read_series(s, &sim_ingest, bin_s, m.clone(), progress))?;
        sims.push(series);
        let (series, skipped) = py.detach(|| read_series(r, &recorded_ingest, bin_s, m, progress))?;
        if skipped > 0 {
            progress::warn(py, &format!("{}: skipped {skipped} bad rows", r.display()))?;
        }
        recs.push(series);
    }
    let started = std::time::Instant::now();
    let mut bar = Progress::new("diagnose", progress);
    let diagnosis = py.detach(|| {
        fogtemp_diagnose::diagnose(&sims, &recs, &settings, |_stage, fraction| {
            bar.count((fraction.clamp(0.0, 1.0) * 100.0) as u64, 100, "%");
        })
    });
    bar.finish();
    let diagnosis = diagnosis.map_err(|e| match e {
        fogtemp_diagnose::DiagnoseError::Cal(c) => errors::cal(c),
        other => errors::value(other.to_string()),
    })?;
    let doc = DiagnoseDocument {
        diagnosis: &diagnosis,
        seconds: started.elapsed().as_secs_f64(),
        updated_scenario: None,
        scenario_changes: Vec::new(),
    };
    convert::document(py, &doc)
}
