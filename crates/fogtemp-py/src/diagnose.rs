//! `fogtemp.diagnose`: simulated vs recorded logs through `fogtemp_diagnose::diagnose`, as
//! the command line's `diagnose --json` does it.
//!
//! The reading of logs into 1 s means, the pairing by file name and the run metadata from
//! `runs` or the simulation's `manifest.json` are `fogtemp_diagnose::inputs`, which the
//! command line calls too; runs given as arrays are binned by `inputs::series_from_arrays`.

use std::path::{Path, PathBuf};

use fogtemp_cal::ingest::IngestOptions;
use fogtemp_diagnose::{inputs, DiagnoseDocument, DiagnoseError, DiagnoseOptions, RunMeta};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert;
use crate::errors;
use crate::functions::{array_error, expand_logs, ArrayColumns, ArrayRun};
use crate::options::{self, Options, COLUMN_KEYS};
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

/// One side of a diagnosis: log files (a folder, or a file), or runs given as arrays keyed by
/// run name. A run keyed `a` stands as `a.csv`: it pairs with the log `a.csv` of the other
/// side, a runs file's row `a` describes it, and the document names it so.
enum Side<'py> {
    Files {
        given: PathBuf,
        logs: Vec<PathBuf>,
    },
    /// The runs, and which side they are ("simulated", "recorded").
    Arrays(Vec<ArrayRun<'py>>, &'static str),
}

impl<'py> Side<'py> {
    fn new(value: &Bound<'py, PyAny>, what: &'static str) -> PyResult<Self> {
        if value.is_instance_of::<pyo3::types::PyList>() || value.is_instance_of::<pyo3::types::PyTuple>() {
            return Err(PyTypeError::new_err(format!(
                "diagnose(): {what} must be a folder or file of logs, or a dict of runs keyed by run name (not a list: runs are paired by name)"
            )));
        }
        let dict = value.cast::<PyDict>().ok();
        // One run: a DataFrame (or other table), or a dict holding its columns.
        let one_run = match dict {
            Some(d) => d.contains("time_s")?,
            None => convert::is_arrays(value)?,
        };
        if one_run {
            return Err(PyTypeError::new_err(format!(
                "diagnose(): {what} is one run; give a dict of runs keyed by run name (or a folder of logs)"
            )));
        }
        if let Some(dict) = dict {
            if dict.is_empty() {
                return Err(errors::value(format!("diagnose(): {what} holds no runs")));
            }
            let mut runs = Vec::with_capacity(dict.len());
            for (key, run) in dict.iter() {
                let key: String = key.extract().map_err(|_| {
                    PyTypeError::new_err(format!("diagnose(): {what}'s keys must be run names (str)"))
                })?;
                let name =
                    if key.to_ascii_lowercase().ends_with(".csv") { key } else { format!("{key}.csv") };
                runs.push(ArrayRun::named(PathBuf::from(name), &run)?);
            }
            return Ok(Side::Arrays(runs, what));
        }
        let given: PathBuf = value.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "diagnose(): {what} must be a folder or file of logs, or a dict of runs keyed by run name"
            ))
        })?;
        let logs = expand_logs(std::slice::from_ref(&given))?;
        Ok(Side::Files { given, logs })
    }

    /// The runs' paths (for arrays, their names as log files), for pairing and the runs file.
    fn paths(&self) -> Vec<PathBuf> {
        match self {
            Side::Files { logs, .. } => logs.clone(),
            Side::Arrays(runs, _) => runs.iter().map(|r| r.name.clone()).collect(),
        }
    }

    /// The run at `path` (one of [`Side::paths`]) as `bin_s` means.
    fn series(
        &self,
        py: Python<'_>,
        path: &Path,
        ingest: &IngestOptions,
        bin_s: f64,
        meta: RunMeta,
        show: bool,
    ) -> PyResult<inputs::ReadSeries> {
        let Side::Arrays(runs, what) = self else {
            return read_series(py, path, ingest, bin_s, meta, show);
        };
        let Some(run) = runs.iter().find(|r| r.name == path) else {
            return Err(errors::value(format!("no run named {}", path.display())));
        };
        let columns = ArrayColumns::new(run)?;
        let view = columns.view();
        let read = py.detach(|| inputs::series_from_arrays(&view, ingest.skip_bad_rows, bin_s, meta));
        py.check_signals()?;
        read.map_err(|e| match e {
            DiagnoseError::Cal(c) => array_error(c),
            DiagnoseError::NoDataRows { path } => {
                errors::value(format!("{what} run {}: no samples", path.display()))
            }
            other => diagnose_error(other),
        })
    }
}

/// Compares simulated and recorded runs (the command line's `diagnose --json`): where they
/// differ, which physics the simulation left out, a fitted model of it, and whether it helps
/// on runs it did not see.
///
/// `simulated` and `recorded` are folders (or files) of logs paired by file name, or dicts of
/// runs given as arrays keyed by run name (each a dict or DataFrame with `time_s`, `temp_c`,
/// `gyro_dph`, as `fit` takes them; a run keyed `a` pairs with a log `a.csv`), in any
/// combination; `runs` a runs file (`run,position,input_rate_dph`), else the simulation's
/// `manifest.json` gives each run's position and Earth rate. Keywords: `mean_window_s`,
/// `bin_s`, `rate_window_s`, `window_coverage`, `block_coverage` (the command's options, same
/// defaults), `report` (a folder: `report.md`, `report.html`, the figures and, when the
/// simulation folder holds its `scenario.toml`, `scenario-updated.toml`, as `diagnose
/// --report`; the document then names it in `updated_scenario`, its changes in
/// `scenario_changes`) and the log-column options, which apply to recorded log files
/// (`skip_bad_rows` to recorded arrays too). Ctrl-C is raised between two logs and between stages.
#[pyfunction]
#[pyo3(signature = (simulated, recorded, runs = None, *, progress = true, **options))]
pub fn diagnose<'py>(
    py: Python<'py>,
    simulated: &Bound<'py, PyAny>,
    recorded: &Bound<'py, PyAny>,
    runs: Option<PathBuf>,
    progress: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut o = Options::new("diagnose", options);
    if recorded.is_instance_of::<PyDict>() && o.any_given(&COLUMN_KEYS[..COLUMN_KEYS.len() - 1])? {
        return Err(PyTypeError::new_err(
            "diagnose(): column and unit options apply to recorded log files; runs given as arrays are in time_s, temp_c, gyro_dph",
        ));
    }
    let recorded_ingest = options::ingest(&mut o)?;
    if !recorded.is_instance_of::<PyDict>() {
        crate::functions::warn_unit_names(py, &recorded_ingest.format)?;
    }
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
    // After the options: a bad report folder is refused before any log is looked for.
    let simulated = Side::new(simulated, "simulated")?;
    let recorded = Side::new(recorded, "recorded")?;
    if let (Side::Files { given: s, .. }, Side::Files { given: r, .. }) = (&simulated, &recorded) {
        if let Some(problem) = inputs::sides_problem(s, r, ("simulated=", "recorded=")) {
            return Err(errors::value(format!("diagnose(): {problem}")));
        }
    }
    let (simulated_logs, recorded_logs) = (simulated.paths(), recorded.paths());
    // Runs given as arrays have names, not folders.
    let files: Vec<PathBuf> = [(&simulated, &simulated_logs), (&recorded, &recorded_logs)]
        .into_iter()
        .filter(|(side, _)| matches!(side, Side::Files { .. }))
        .flat_map(|(_, logs)| logs.iter().cloned())
        .collect();
    for warning in fogtemp_cal::manifest::unfinished_simulation_warnings(&files) {
        progress::warn(py, &warning)?;
    }
    let pairs = inputs::pair(&simulated_logs, &recorded_logs).map_err(diagnose_error)?;
    let meta = match (&runs, &simulated) {
        (Some(path), _) => inputs::runs_file_meta(path, &simulated_logs),
        (None, Side::Files { given, .. }) => inputs::manifest_meta(given),
        (None, Side::Arrays(..)) => Ok(Default::default()),
    }
    .map_err(diagnose_error)?;
    for note in
        runs.as_deref().map(inputs::runs_file_notes).transpose().map_err(diagnose_error)?.unwrap_or_default()
    {
        progress::warn(py, &note)?;
    }
    if let Some(note) = inputs::unknown_setup_note(&meta) {
        progress::warn(py, &format!("{note} (runs=)"))?;
    }
    let sim_ingest = IngestOptions::default();
    let (mut sims, mut recs) = (Vec::new(), Vec::new());
    for (s, r) in &pairs {
        let m = meta.get(&inputs::file_name(s)).cloned().unwrap_or_default();
        let sim = simulated.series(py, s, &sim_ingest, bin_s, m.clone(), progress)?;
        if let Some(note) = sim.gap_note(s) {
            progress::warn(py, &note)?;
        }
        if let Some(note) = &sim.temperature_only_note {
            progress::note(py, note)?;
        }
        sims.push(sim.series);
        let rec = recorded.series(py, r, &recorded_ingest, bin_s, m, progress)?;
        if rec.skipped > 0 {
            let unit = if matches!(recorded, Side::Arrays(..)) { "samples" } else { "rows" };
            progress::warn(py, &format!("{}: skipped {} bad {unit}", r.display(), rec.skipped))?;
        }
        if let Some(note) = rec.gap_note(r) {
            progress::warn(py, &note)?;
        }
        if let Some(note) = &rec.temperature_only_note {
            progress::note(py, note)?;
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
    for run in &diagnosis.outliers {
        progress::warn(py, &fogtemp_diagnose::prepare::outliers_note(&run.run, &run.seconds))?;
    }
    let seconds = started.elapsed().as_secs_f64();
    let (mut updated_scenario, mut scenario_changes) = (None, Vec::new());
    if let Some(dir) = &report {
        py.detach(|| fogtemp_diagnose::write_diagnosis_report(dir, &diagnosis)).map_err(diagnose_error)?;
        // Only a simulation folder holds the scenario.toml that the update starts from.
        if let Side::Files { given, .. } = &simulated {
            if let Some((path, changes)) = py
                .detach(|| fogtemp_diagnose::write_updated_scenario(given, dir, &diagnosis))
                .map_err(diagnose_error)?
            {
                updated_scenario = Some(path.display().to_string());
                scenario_changes = changes;
            }
        }
    }
    let doc = DiagnoseDocument { diagnosis: &diagnosis, seconds, updated_scenario, scenario_changes };
    convert::document(py, &doc)
}
