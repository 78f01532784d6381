//! `fogtemp.diagnose`: simulated vs recorded logs through `fogtemp_diagnose::diagnose`, as
//! the command line's `diagnose --json` does it.
//!
//! The reading of logs into 1 s means, the pairing by file name and the run metadata from
//! `runs` or the simulation's `manifest.json` are `fogtemp_diagnose::inputs`, which the
//! command line calls too.

use std::path::{Path, PathBuf};

use fogtemp_cal::ingest::IngestOptions;
use fogtemp_diagnose::{inputs, DiagnoseDocument, DiagnoseError, DiagnoseOptions, RunMeta};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert;
use crate::errors;
use crate::functions::expand_logs;
use crate::options::{self, Options};
use crate::progress::{self, Progress};

/// A diagnosis error as a Python exception: the calibration library's errors as
/// [`errors::cal`] maps them, every other as `ValueError` with its causes.
fn diagnose_error(e: DiagnoseError) -> PyErr {
    match e {
        DiagnoseError::Cal(c) => errors::cal(c),
        other => {
            let mut message = other.to_string();
            let mut cause = std::error::Error::source(&other);
            while let Some(c) = cause {
                message.push_str(&format!(": {c}"));
                cause = c.source();
            }
            errors::value(message)
        }
    }
}

/// A log as `bin_s` means (`fogtemp_diagnose::inputs`), with a progress bar; also the bad
/// rows skipped and the gaps. Ctrl-C is raised after the log.
fn read_series(
    py: Python<'_>,
    path: &Path,
    ingest: &IngestOptions,
    bin_s: f64,
    meta: RunMeta,
    show: bool,
) -> PyResult<inputs::ReadSeries> {
    let mut bar = Progress::new(format!("read {}", inputs::file_name(path)), show);
    let read = py.detach(|| inputs::read_series(path, ingest, bin_s, meta, |b, r| bar.rows(b, r)));
    bar.finish();
    bar.boundary(py)?;
    read.map_err(diagnose_error)
}

/// Compares simulated and recorded runs (the command line's `diagnose --json`): where they
/// differ, which physics the simulation left out, a fitted model of it, and whether it helps
/// on runs it did not see.
///
/// `simulated` and `recorded` are folders (or files) of logs paired by file name; `runs` a
/// runs file (`run,position,input_rate_dph`), else the simulation's `manifest.json` gives each
/// run's position and Earth rate. Keywords: `mean_window_s`, `bin_s`, `rate_window_s`,
/// `window_coverage`, `block_coverage` (the command's options, same defaults), `report` (a
/// folder: `report.md`, `report.html`, the figures and, when the simulation folder holds its
/// `scenario.toml`, `scenario-updated.toml`, as `diagnose --report`; the document then names
/// it in `updated_scenario`, its changes in `scenario_changes`) and the log-column options,
/// which apply to the recorded logs. Ctrl-C is raised between two logs and between stages.
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
    let report = o.report_folder()?;
    o.finish()?;
    if !(bin_s.is_finite() && bin_s > 0.0) {
        return Err(errors::value("bin_s must be positive"));
    }
    let simulated_logs = expand_logs(std::slice::from_ref(&simulated))?;
    let recorded_logs = expand_logs(std::slice::from_ref(&recorded))?;
    let pairs = inputs::pair(&simulated_logs, &recorded_logs).map_err(diagnose_error)?;
    let meta = match &runs {
        Some(path) => inputs::runs_file_meta(path, &simulated_logs),
        None => inputs::manifest_meta(&simulated),
    }
    .map_err(diagnose_error)?;
    let sim_ingest = IngestOptions::default();
    let (mut sims, mut recs) = (Vec::new(), Vec::new());
    for (s, r) in &pairs {
        let m = meta.get(&inputs::file_name(s)).cloned().unwrap_or_default();
        let sim = read_series(py, s, &sim_ingest, bin_s, m.clone(), progress)?;
        if let Some(note) = sim.gap_note(s) {
            progress::warn(py, &note)?;
        }
        sims.push(sim.series);
        let rec = read_series(py, r, &recorded_ingest, bin_s, m, progress)?;
        if rec.skipped > 0 {
            progress::warn(py, &format!("{}: skipped {} bad rows", r.display(), rec.skipped))?;
        }
        if let Some(note) = rec.gap_note(r) {
            progress::warn(py, &note)?;
        }
        recs.push(rec.series);
    }
    // Between the stages: after reading, before the diagnosis.
    py.check_signals()?;
    let started = std::time::Instant::now();
    let mut bar = Progress::new("diagnose", progress);
    let diagnosis = py.detach(|| {
        fogtemp_diagnose::diagnose(&sims, &recs, &settings, |_stage, fraction| {
            bar.count((fraction.clamp(0.0, 1.0) * 100.0) as u64, 100, "%");
        })
    });
    bar.finish();
    bar.boundary(py)?;
    let diagnosis = diagnosis.map_err(diagnose_error)?;
    let seconds = started.elapsed().as_secs_f64();
    let (mut updated_scenario, mut scenario_changes) = (None, Vec::new());
    if let Some(dir) = &report {
        py.detach(|| fogtemp_diagnose::write_diagnosis_report(dir, &diagnosis)).map_err(diagnose_error)?;
        if let Some((path, changes)) = py
            .detach(|| fogtemp_diagnose::write_updated_scenario(&simulated, dir, &diagnosis))
            .map_err(diagnose_error)?
        {
            updated_scenario = Some(path.display().to_string());
            scenario_changes = changes;
        }
    }
    let doc = DiagnoseDocument { diagnosis: &diagnosis, seconds, updated_scenario, scenario_changes };
    convert::document(py, &doc)
}
