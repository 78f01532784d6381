//! The module's functions: `fit`, `read_log`, `validate`, `allan`, `simulate`.

use std::path::{Path, PathBuf};

use fogtemp_cal::allan_stream;
use fogtemp_cal::arrays::{extract_run_arrays, RunArrays};
use fogtemp_cal::axis_columns::{ShapeNamed, TimeNamed};
use fogtemp_cal::calibrate::{self, CalibrationConfig, Method, RunFeatures, Validation};
use fogtemp_cal::digest::Digests;
use fogtemp_cal::documents::{AllanDocument, ComparedModel, FitDocument, ValidationDocument};
use fogtemp_cal::ingest::{read_log_with_progress, IngestOptions, IngestReport};
use fogtemp_cal::metrics::BiasStabilityOptions;
use fogtemp_core::Model as CoreModel;
use numpy::{PyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyFileNotFoundError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{self, f64_vector, slice};
use crate::errors;
use crate::model::Model;
use crate::options::{self, Options, COLUMN_KEYS};
use crate::progress::{self, Progress};

/// The method names `fit` accepts.
pub const METHOD_NAMES: [&str; 5] = ["auto", "poly", "mesh", "hybrid", "cubic-t"];

/// The one place a method name becomes a [`Method`].
pub fn parse_method(name: &str) -> PyResult<Method> {
    Ok(match name {
        // The command line's default: cross-validated choice among the others.
        "auto" => Method::Auto,
        "poly" => Method::Poly,
        "mesh" => Method::Mesh,
        "hybrid" => Method::Hybrid,
        "cubic-t" | "cubic_t" => Method::CubicT,
        other => {
            return Err(errors::value(format!(
                "method must be one of {}, got '{other}'",
                METHOD_NAMES.join(", ")
            )))
        }
    })
}

/// Paths from a path, a list of paths, folders expanded to their `*.csv` files sorted by
/// name (the command line's rule).
pub fn expand_logs(items: &[PathBuf]) -> PyResult<Vec<PathBuf>> {
    expand_logs_ordered(items, false)
}

/// [`expand_logs`] with each folder's logs in reading order, as the command line's
/// `validate` lists them ([`fogtemp_cal::runs::sort_for_reading`]).
pub fn expand_logs_for_reading(items: &[PathBuf]) -> PyResult<Vec<PathBuf>> {
    expand_logs_ordered(items, true)
}

fn expand_logs_ordered(items: &[PathBuf], reading_order: bool) -> PyResult<Vec<PathBuf>> {
    let mut out = Vec::new();
    for arg in items {
        if arg.is_dir() {
            let listing = std::fs::read_dir(arg).map_err(|e| {
                pyo3::exceptions::PyOSError::new_err(format!("cannot list {}: {e}", arg.display()))
            })?;
            let mut found: Vec<PathBuf> = listing
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| fogtemp_cal::runs::is_log_file(p))
                .collect();
            found.sort();
            if reading_order {
                fogtemp_cal::runs::sort_for_reading(&mut found);
            }
            if found.is_empty() {
                return Err(errors::value(format!("{}: folder holds no *.csv files", arg.display())));
            }
            out.extend(found);
        } else if arg.is_file() {
            out.push(arg.clone());
        } else {
            return Err(PyFileNotFoundError::new_err(format!("{}: no such file or folder", arg.display())));
        }
    }
    Ok(out)
}

/// One argument or a list of them, as a list.
fn as_list<'py>(value: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyAny>>> {
    if value.is_instance_of::<PyList>() || value.is_instance_of::<pyo3::types::PyTuple>() {
        value.try_iter()?.collect()
    } else {
        Ok(vec![value.clone()])
    }
}

/// The items of a `logs` argument and, for a dict of runs, their names.
type LogsAndNames<'py> = (Vec<Bound<'py, PyAny>>, Option<Vec<String>>);

/// The logs or runs of a `logs` argument, and for a dict of runs keyed by run name (the form
/// `diagnose` takes) their names. All paths, or all runs given as arrays, not both.
fn runs_and_names<'py>(logs: &Bound<'py, PyAny>) -> PyResult<LogsAndNames<'py>> {
    let (items, names) =
        match logs.cast::<PyDict>() {
            // (review33b F8: `{}` was read as one run without columns.)
            Ok(dict) if dict.is_empty() => return Err(errors::value("no runs: the dict of runs is empty")),
            Ok(dict) if !dict.contains("time_s")? => {
                let mut names = Vec::with_capacity(dict.len());
                let mut items = Vec::with_capacity(dict.len());
                for (key, run) in dict.iter() {
                    names.push(key.extract::<String>().map_err(|_| {
                        PyTypeError::new_err("a dict of runs must be keyed by run name (str)")
                    })?);
                    items.push(run);
                }
                (items, Some(names))
            }
            _ => (as_list(logs)?, None),
        };
    let arrays = items.iter().map(convert::is_arrays).collect::<PyResult<Vec<bool>>>()?;
    if arrays.iter().any(|&a| a) && !arrays.iter().all(|&a| a) {
        return Err(PyTypeError::new_err(
            "give all logs as paths, or all runs as arrays (dicts or DataFrames), not both",
        ));
    }
    Ok((items, names))
}

/// Runs given as arrays: named by `names` (a dict's keys), else `runs[i]`.
fn array_runs_of<'py>(items: &[Bound<'py, PyAny>], names: Option<&[String]>) -> PyResult<Vec<ArrayRun<'py>>> {
    items
        .iter()
        .enumerate()
        .map(|(i, r)| match names.and_then(|n| n.get(i)) {
            Some(name) => ArrayRun::named(PathBuf::from(name), r),
            None => ArrayRun::new(i, r),
        })
        .collect()
}

/// Times given in a float type narrower than float64 whose steps it could not hold (float32
/// keeps 24 bits: 1 s steps vanish above 2^24 s, a Unix time's 0.1 s steps long before) are
/// refused naming the cause (`what`: how the caller names the array, e.g. `runs[0]['time_s']`);
/// the row rules would report a repeated time and suggest skipping.
pub(crate) fn refuse_times_lost_to_precision(
    given: &Bound<'_, PyAny>,
    time_s: &numpy::PyReadonlyArrayDyn<'_, f64>,
    what: &str,
) -> PyResult<()> {
    // Times in order (every good run) need no look at the dtype, which takes another
    // conversion of what was given: only a run the row rules would refuse pays for it.
    if !slice(time_s, "time_s")?.windows(2).any(|w| w[1] <= w[0]) {
        return Ok(());
    }
    let dtype = given.py().import("numpy")?.call_method1("asarray", (given,))?.getattr("dtype")?;
    let (kind, bytes): (String, usize) =
        (dtype.getattr("kind")?.extract()?, dtype.getattr("itemsize")?.extract()?);
    if kind == "f" && bytes < 8 {
        return Err(errors::value(format!(
            "{what} is float{}: too coarse for these times (steps vanish); give float64 times, \
             or subtract the start time before narrowing",
            8 * bytes
        )));
    }
    Ok(())
}

/// One run given as arrays, held as contiguous float64 numpy arrays.
pub(crate) struct ArrayRun<'py> {
    pub(crate) name: PathBuf,
    time_s: numpy::PyReadonlyArrayDyn<'py, f64>,
    temps_c: Vec<numpy::PyReadonlyArrayDyn<'py, f64>>,
    pub(crate) gyros_dph: Vec<numpy::PyReadonlyArrayDyn<'py, f64>>,
}

/// A column that is one array (1-D) or several (2-D, one per column of the second axis).
fn columns<'py>(value: &Bound<'py, PyAny>, what: &str) -> PyResult<Vec<numpy::PyReadonlyArrayDyn<'py, f64>>> {
    let array = convert::f64_array(value, what)?;
    match array.ndim() {
        1 => Ok(vec![array]),
        2 => {
            let t = array.as_any().getattr("T")?;
            (0..array.shape()[1]).map(|k| f64_vector(&t.get_item(k)?, what)).collect()
        }
        _ => Err(errors::value(format!(
            "{what} must be 1-D (or 2-D, one column per axis), got shape {:?}",
            array.shape()
        ))),
    }
}

/// A run's columns for `key`, one per axis: `key` itself (1-D, or 2-D with one column per
/// axis), or `key_0`, `key_1`, ... as `read_log` returns a log of several axes (review23a F3:
/// read_log's own output was refused, and renaming `gyro_dph_0` as the error advised fitted
/// one axis and dropped the other without a word). `None` when neither is there; `key` beside
/// `key_1` is refused as ambiguous.
fn numbered_columns<'py>(
    run: &Bound<'py, PyAny>,
    key: &str,
    label: &str,
) -> PyResult<Option<Vec<numpy::PyReadonlyArrayDyn<'py, f64>>>> {
    let mut numbered = Vec::new();
    while let Some(value) = convert::item(run, &format!("{key}_{}", numbered.len()))? {
        numbered.push(value);
    }
    // A number past a gap (`key_0`, `key_2`): an axis would be dropped without a word
    // (review33b F3, a dead channel's column deleted from an IMU DataFrame).
    if let Some(beyond) = numbered_beyond(run, key, numbered.len()).filter(|_| !numbered.is_empty()) {
        return Err(errors::value(format!(
            "{label}: '{beyond}' but no '{key}_{}': the axes' columns are numbered from 0 without gaps; \
             renumber them, or give every axis",
            numbered.len()
        )));
    }
    // `key_1` alone (no `key_0`: renamed to `key`) still says there is a second axis.
    let other = match numbered.is_empty() {
        false => Some(format!("{key}_0")),
        true => convert::item(run, &format!("{key}_1"))?
            .map(|_| format!("{key}_1"))
            .or_else(|| numbered_beyond(run, key, 1)),
    };
    match (convert::item(run, key)?, other) {
        (Some(_), Some(other)) => Err(errors::value(format!(
            "{label}: both '{key}' and '{other}': which columns are the axes cannot be told; give them as \
             {key}_0, {key}_1, ... (as read_log returns them) or as one 2-D '{key}' (np.column_stack)"
        ))),
        (Some(value), None) => columns(&value, &format!("{label}['{key}']")).map(Some),
        (None, _) if numbered.is_empty() => Ok(None),
        (None, _) => numbered
            .iter()
            .enumerate()
            .map(|(k, v)| f64_vector(v, &format!("{label}['{key}_{k}']")))
            .collect::<PyResult<Vec<_>>>()
            .map(Some),
    }
}

/// The first key of `run` named `key_N` with `N` at least `from` (`key_2` when `key_1` is
/// missing), if any; a run whose keys cannot be listed has none.
fn numbered_beyond(run: &Bound<'_, PyAny>, key: &str, from: usize) -> Option<String> {
    let keys = run.getattr("columns").or_else(|_| run.call_method0("keys")).ok()?;
    let prefix = format!("{key}_");
    keys.try_iter().ok()?.filter_map(|k| k.ok()?.extract::<String>().ok()).find(|name| {
        name.strip_prefix(&prefix)
            .filter(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|n| n.parse::<usize>().ok())
            .is_some_and(|n| n >= from)
    })
}

/// The runs file `path` for runs given as arrays, each named by its key in the dict they came
/// in (review33b F2), for a command that does not read the runs of role `unused`: the runs'
/// names as paths (a run's name is its path's) and the metadata, its position notes said.
fn array_runs_metadata(
    py: Python<'_>,
    runs: &[ArrayRun<'_>],
    path: &Path,
    unused: fogtemp_cal::runs::Role,
) -> PyResult<(Vec<PathBuf>, fogtemp_cal::runs::LogsMetadata)> {
    let named: Vec<PathBuf> = runs.iter().map(|r| r.name.clone()).collect();
    let file = fogtemp_cal::runs::RunsFile::read(path).map_err(errors::cal)?;
    let rows =
        file.for_logs_of_a_command(&named, Some(unused)).map_err(errors::cal)?.into_iter().cloned().collect();
    for note in file.position_notes() {
        progress::note(py, &note)?;
    }
    let metadata = fogtemp_cal::runs::LogsMetadata {
        source: path.display().to_string(),
        source_path: path.to_path_buf(),
        rows: Some(rows),
        ..Default::default()
    };
    Ok((named, metadata))
}

/// How messages and documents name a model `fit` returned without writing it (`out=`).
const UNSAVED_MODEL: &str = "the model of fogtemp.fit() (not saved)";

/// As the command line's `fit --runs`: each run's input rate taken from its gyro (one-gyro
/// logs; else left in, with a warning), and the positions `auto` leaves out one at a time;
/// the document of the metadata and the positions.
fn apply_run_metadata(
    py: Python<'_>,
    runs: &mut [fogtemp_cal::calibrate::RunFeatures],
    config: &mut CalibrationConfig,
    source: String,
    rows: Vec<fogtemp_cal::runs::RunMetadata>,
) -> PyResult<(fogtemp_cal::documents::RunMetadataDocument, Vec<String>)> {
    let rates: Vec<f64> = rows.iter().map(|r| r.input_rate_dph).collect();
    let axes = config.ingest.format.gyro_columns.len();
    let subtracted =
        calibrate::subtract_input_rates(runs, &rates, config) == fogtemp_core::InputRates::Subtracted;
    if !subtracted {
        // As the command line says it (review30a F7).
        progress::warn(
            py,
            &format!(
                "the run metadata gives one input rate per run, but the logs have {axes} gyro columns: the rates \
                 are not subtracted, so each axis's model includes its input rate"
            ),
        )?;
    }
    let positions: Vec<String> = rows.into_iter().map(|r| r.position).collect();
    let document = fogtemp_cal::documents::RunMetadataDocument {
        source,
        positions: positions.clone(),
        input_rates_dph: rates,
        input_rates_subtracted: subtracted,
    };
    Ok((document, positions))
}

/// Drops the samples `allan` cannot use (a time not finite or not after the previous kept
/// one, a rate not finite in any series), as `skip_bad_rows` drops a log's bad rows; their
/// indices in the input, in order.
fn keep_good_samples(times: &mut Vec<f64>, series: &mut [Vec<f64>]) -> Vec<usize> {
    let mut skipped = Vec::new();
    let mut kept = 0;
    let mut last: Option<f64> = None;
    for i in 0..times.len() {
        let t = times[i];
        let good = t.is_finite()
            && last.is_none_or(|p| t > p)
            && series.iter().all(|s| s.get(i).is_some_and(|g| g.is_finite()));
        if good {
            times[kept] = t;
            for s in series.iter_mut() {
                s[kept] = s[i];
            }
            kept += 1;
            last = Some(t);
        } else {
            skipped.push(i);
        }
    }
    times.truncate(kept);
    series.iter_mut().for_each(|s| s.truncate(kept));
    skipped
}

/// What a run given as a dict or DataFrame has instead of its `missing` column, and how to
/// rename one (review17 F5: a log file's error lists its header, a DataFrame's listed
/// nothing). The keys are shown as Python writes them (`repr`: `0` is not `'0'`), the rename
/// names a source only when one is plausible (review20 F9: it named the first key, which
/// could be the temperature for the time), and MultiIndex columns get a way to one level.
fn missing_column_help(run: &Bound<'_, PyAny>, missing: &str) -> String {
    let frame = run.hasattr("columns").unwrap_or(false);
    let keys: PyResult<Vec<Bound<'_, PyAny>>> =
        run.getattr("columns").or_else(|_| run.call_method0("keys")).and_then(|k| k.try_iter()?.collect());
    let keys = match keys {
        Ok(keys) if !keys.is_empty() => keys,
        _ => return "it has no keys or columns".to_string(),
    };
    let shown: Vec<String> =
        keys.iter().map(|k| k.repr().map_or_else(|_| "?".into(), |r| r.to_string())).collect();
    let has = format!("it has {}", shown.join(", "));
    if let Some(group) = keys.first().filter(|k| k.is_instance_of::<pyo3::types::PyTuple>()) {
        let first_level =
            group.get_item(0).and_then(|l| l.repr()).map_or_else(|_| "...".into(), |r| r.to_string());
        return format!(
            "{has}: the columns are a MultiIndex; select one group, e.g. df[{first_level}], or drop the outer \
             level with df.droplevel(0, axis=1)"
        );
    }
    let source = keys
        .iter()
        .zip(&shown)
        .find(|(k, _)| k.extract::<String>().is_ok_and(|name: String| plausible_source(&name, missing)))
        .map_or("...", |(_, shown)| shown.as_str());
    let rename = if frame {
        format!("df.rename(columns={{{source}: '{missing}'}})")
    } else {
        format!("run['{missing}'] = run.pop({source})")
    };
    let index = if frame { "; a DataFrame's index is not read: reset_index() makes it a column" } else { "" };
    format!(
        "{has}; rename, e.g. {rename}, converting units first (gyro in deg/h, temperature in deg C, time in s){index}"
    )
}

/// Whether a column `name` (not one of a run's own) plausibly holds the run's `missing`
/// column: a time, a temperature or a gyro rate by its name.
fn plausible_source(name: &str, missing: &str) -> bool {
    let lower = name.to_ascii_lowercase();
    if ["time_s", "temp_c", "gyro_dph"].contains(&lower.as_str()) {
        return false;
    }
    let words: &[&str] = match missing {
        "time_s" => &["time", "timestamp", "sec"],
        "temp_c" => &["temp", "tmp", "degc"],
        "gyro_dph" => &["gyro", "rate", "omega", "dph", "dps"],
        _ => &[],
    };
    words.iter().any(|w| lower.contains(w))
        || (missing == "time_s" && (lower == "t" || lower.starts_with("t_")))
}

impl<'py> ArrayRun<'py> {
    /// Run `index` of a list from a dict or DataFrame with `time_s`, `temp_c`, `gyro_dph`.
    fn new(index: usize, run: &Bound<'py, PyAny>) -> PyResult<Self> {
        Self::named(PathBuf::from(format!("runs[{index}]")), run)
    }

    /// A run named `name` (in errors and documents) from a dict or DataFrame with `time_s`,
    /// `temp_c`, `gyro_dph`.
    pub(crate) fn named(name: PathBuf, run: &Bound<'py, PyAny>) -> PyResult<Self> {
        // (diagnose's dict of runs comes here without `is_arrays`.)
        convert::refuse_runs_without_names(run)?;
        let label = name.display().to_string();
        let missing = |key: &str| {
            errors::value(format!(
                "{label}: no '{key}' (a run needs time_s, temp_c and gyro_dph; {})",
                missing_column_help(run, key)
            ))
        };
        let time = convert::item(run, "time_s")?.ok_or_else(|| missing("time_s"))?;
        let time_s = f64_vector(&time, &format!("{label}['time_s']"))?;
        refuse_times_lost_to_precision(&time, &time_s, &format!("{label}['time_s']"))?;
        let per_axis = |key: &str| -> PyResult<Vec<numpy::PyReadonlyArrayDyn<'py, f64>>> {
            numbered_columns(run, key, &label)?.ok_or_else(|| missing(key))
        };
        Ok(Self { time_s, temps_c: per_axis("temp_c")?, gyros_dph: per_axis("gyro_dph")?, name })
    }

    /// SHA-256 input: every array's little-endian bytes in order.
    fn digest_into(&self, hasher: &mut sha2::Sha256) -> PyResult<()> {
        use sha2::Digest;
        for a in std::iter::once(&self.time_s).chain(&self.temps_c).chain(&self.gyros_dph) {
            for v in slice(a, "run")? {
                hasher.update(v.to_le_bytes());
            }
        }
        Ok(())
    }
}

/// A bad sample of an array run in its own words (the library reports the sample index as
/// the line and the array as the column).
pub(crate) fn array_error(e: fogtemp_cal::CalError) -> PyErr {
    match &e {
        fogtemp_cal::CalError::BadRow { path, row } => errors::value(format!(
            "{}: sample {}: {}: {} (found {}); pass skip_bad_rows=True to skip such samples",
            path.display(),
            row.line,
            row.column_name,
            row.kind.describe(),
            row.found
        )),
        // Arrays have no lines: a shape problem is the run's, not a line 0's.
        fogtemp_cal::CalError::Csv { path, line: 0, message } => {
            errors::value(format!("{}: {message}", path.display()))
        }
        _ => errors::cal(e),
    }
}

/// Fits a model to calibration runs (the command line's `fit`).
///
/// `logs` is a path (a CSV log or a folder of them), a list of paths, or a list of runs given
/// as arrays: dicts or pandas DataFrames with `time_s` (s), `temp_c` (deg C, NaN = no reading)
/// and `gyro_dph` (deg/h; 2-D for several axes, or `gyro_dph_0`, `gyro_dph_1`, ... as
/// `read_log` returns them). `method` is "auto" (what the command
/// line's `fit` does by default), "poly", "mesh", "hybrid" or "cubic-t". Keywords: the command line's `fit` options (`window_s`, `blocks`,
/// `min_blocks`, `max_gap_s`, `target_window_s`, `full_windows_only`, `thinning`,
/// `tolerance_dph`, `max_nodes`, `interpolate_nodes`, `fast_rate`, `settled_every`, `poly`,
/// `max_degree`, `p_enter`, `p_remove`, `poly_outside`, `mesh_outside`, `capacity`, `operating_temp_c`) and, for files, its
/// log-column options (`time_column`, `time_unit`, `temp_column`, `temp_scale`, `temp_offset`,
/// `gyro_column`, `gyro_unit`, `gyro_scale`, `delimiter`, `skip_lines`, `columns`,
/// `sample_rate_hz`, `comment`, `decimal_mark`, `date_column`, `skip_bad_rows`; the log's
/// shape as `read_log` describes it: `columns` is a list of str or one str of comma-separated
/// names, "" for a header row) and `runs`
/// (a runs file, `run,position,input_rate_dph[,role]`, as `fit --runs`: `val` runs left out,
/// one position left out at a time by `auto`, each run's input rate subtracted from its gyro;
/// for log files, or runs given as arrays in a dict `{name: run}`, named by their keys);
/// identifiability warnings as Python warnings. `report` (a folder) writes `fit-report.md`,
/// `fit-report.html` and the figures, as `fit --report`. `out` also writes the model
/// file; `progress` shows reading and cross-validation progress on stderr. Runs with the GIL
/// released; Ctrl-C is raised between two logs, between reading and fitting, and in `auto`'s
/// cross-validation at its next held-out replay (a fold's fits are not cut short).
#[pyfunction]
#[pyo3(signature = (logs, method = "auto", *, out = None, progress = true, **options))]
pub fn fit(
    py: Python<'_>,
    logs: &Bound<'_, PyAny>,
    method: &str,
    out: Option<PathBuf>,
    progress: bool,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<Model> {
    let method = parse_method(method)?;
    // Before the fit, as the command line checks --out (review27a 11: a folder given by
    // mistake was found after the fit, and the model was lost).
    if let Some(path) = &out {
        fogtemp_cal::output::check_output_file(path).map_err(errors::cal)?;
    }
    let (items, names) = runs_and_names(logs)?;
    if items.is_empty() {
        return Err(errors::value("fit() needs at least one log or run"));
    }
    let mut o = Options::new("fit", options);
    let arrays = convert::is_arrays(&items[0])?;
    if arrays && o.any_given(&COLUMN_KEYS[..COLUMN_KEYS.len() - 1])? {
        return Err(PyTypeError::new_err(
            "fit(): column and unit options apply to log files; runs given as arrays are in time_s, temp_c, gyro_dph",
        ));
    }
    let ingest = options::ingest(&mut o)?;
    if !arrays {
        warn_unit_names(py, &ingest.format)?;
    }
    let mut config =
        options::calibration(&mut o, CalibrationConfig { ingest, method, ..CalibrationConfig::default() })?;
    let capacity = o.int("capacity", fogtemp_core::DEFAULT_CAPACITY, options::MIN_CAPACITY, u64::MAX)?;
    let runs_file = o.opt_path("runs")?;
    let report = o.report_folder()?;
    if arrays && runs_file.is_some() && names.is_none() {
        return Err(PyTypeError::new_err(
            "fit(): runs= names runs by their names: give runs as arrays in a dict {name: run}, the names \
             those of the runs file's run column",
        ));
    }
    let identifiability = fogtemp_cal::identifiability::IdentifiabilitySettings {
        operating_temp_c: o.opt_f64_pair("operating_temp_c")?,
    };
    o.finish()?;
    options::capacity_fits(config.features.block_count as usize, capacity)?;
    // What the document says of the run metadata (log files with a runs file or a manifest).
    let mut run_metadata = None;
    // Logs of an unfinished simulation: warned as read, in `fit_report`'s warnings too.
    let mut unfinished = Vec::new();
    let fitted = if arrays {
        let mut array_runs = array_runs_of(&items, names.as_deref())?;
        // A runs file names the runs given in a dict by their keys (review33b F2): val runs
        // left out, as for log files.
        let metadata = match runs_file.as_deref() {
            Some(path) => {
                let (named, all) = array_runs_metadata(py, &array_runs, path, fogtemp_cal::runs::Role::Val)?;
                let (kept, rows) = fogtemp_cal::runs::calibration_runs(&named, &all).map_err(errors::cal)?;
                array_runs.retain(|r| kept.contains(&r.name));
                rows.map(|rows| (all.source, rows))
            }
            None => None,
        };
        let (mut runs, digest) = array_features(py, &array_runs, &mut config)?;
        let mut selection = fogtemp_cal::selection::SelectionOptions::default();
        if let Some((source, rows)) = metadata {
            let (document, positions) = apply_run_metadata(py, &mut runs, &mut config, source, rows)?;
            run_metadata = Some(document);
            selection.positions = Some(positions);
        }
        let columns: Vec<ArrayColumns<'_>> =
            array_runs.iter().map(ArrayColumns::new).collect::<PyResult<_>>()?;
        // `auto` replays each held-out run from its arrays, as it rereads a file.
        let replay = |run: usize, models: &[&fogtemp_core::Model<'_>]| match columns.get(run) {
            Some(c) => fogtemp_cal::arrays::replay_models_arrays(&c.view(), models, &config, 1.0),
            None => Err(fogtemp_cal::CalError::Csv {
                path: PathBuf::from(format!("runs[{run}]")),
                line: 0,
                message: "no such run".into(),
            }),
        };
        let fitted = interruptible_fit(py, &runs, &config, digest, &selection, progress, &replay)?;
        (fitted, runs, digest)
    } else {
        let (mut runs, digest, metadata, warned) =
            file_runs(py, &items, &config, progress, runs_file.as_deref())?;
        unfinished = warned;
        let mut selection = fogtemp_cal::selection::SelectionOptions::default();
        if let Some((source, rows)) = metadata {
            let (document, positions) = apply_run_metadata(py, &mut runs, &mut config, source, rows)?;
            run_metadata = Some(document);
            selection.positions = Some(positions);
        }
        let fitted = {
            let replay = calibrate::replay_files(&runs, &config);
            interruptible_fit(py, &runs, &config, digest, &selection, progress, &replay)?
        };
        (fitted, runs, digest)
    };
    let (fitted, runs, digest) = fitted;
    // The command line's identifiability warnings: Python warnings, and in `fit_report`.
    let mut warnings = fogtemp_cal::identifiability::fit_warnings(&runs, &config, &identifiability);
    if run_metadata.is_none() {
        warnings.push(fogtemp_cal::identifiability::Warning::no_run_metadata(if arrays {
            "To fit the bias alone, give the runs in a dict {name: run} with a runs file (runs=), or \
             subtract each run's input rate from its gyro_dph before the fit"
        } else {
            "To fit the bias alone, give each run's position and input_rate_dph in a runs file (runs=)"
        }));
    }
    warnings.extend(fogtemp_cal::identifiability::post_fit_warnings(&runs, &fitted));
    for w in &warnings {
        progress::warn(py, &w.message)?;
    }
    warnings.extend(unfinished.into_iter().map(fogtemp_cal::identifiability::Warning::unfinished_simulation));
    // How messages name the model (review33b F5: "<fit>" was cryptic in notes).
    let source = out.as_ref().map_or_else(|| UNSAVED_MODEL.to_string(), |p| p.display().to_string());
    if let Some(dir) = &report {
        // The report's title names the model's file, or says it was not saved.
        let title = out
            .as_ref()
            .map_or_else(|| "fogtemp.fit() (not saved to a file)".to_string(), |_| source.clone());
        py.detach(|| {
            fogtemp_cal::report::write_fit_report_for(dir, Path::new(&title), &fitted, &runs, &warnings)
        })
        .map_err(errors::cal)?;
    }
    let doc = FitDocument::new(Path::new(&source), &fitted, &runs, &digest)
        .with_warnings(warnings)
        .with_run_metadata(run_metadata);
    let json = serde_json::to_value(&doc).and_then(|v| serde_json::to_string(&v)).ok();
    let model = Model::new(fitted.blob, source, json)?;
    if let Some(path) = &out {
        let blob = model.blob();
        py.detach(|| fogtemp_cal::output::write_file_atomic(path, |w| w.write_all(blob)))
            .map_err(errors::cal)?;
    }
    Ok(model)
}

/// The fit, with `auto`'s cross-validation stoppable by Ctrl-C: as each fold starts (on this
/// thread, where Python runs its signal handlers) an interrupt is looked for, and once one
/// has come the next held-out replay stops the fit (`CalError::Interrupted`); the
/// `KeyboardInterrupt` is then raised. Checked before the fit too (after reading).
fn interruptible_fit(
    py: Python<'_>,
    runs: &[RunFeatures],
    config: &CalibrationConfig,
    digest: [u8; 32],
    selection: &fogtemp_cal::selection::SelectionOptions,
    show: bool,
    replay: &fogtemp_cal::selection::ReplayRun<'_>,
) -> PyResult<fogtemp_cal::calibrate::FittedModel> {
    use std::sync::Mutex;
    py.check_signals()?;
    // An interrupt seen on this thread (where Python runs its signal handlers), as a fold
    // starts or before a held-out run is replayed; it stops the fit at the next replay.
    let interrupt: Mutex<Option<PyErr>> = Mutex::new(None);
    let on_this_thread = std::thread::current().id();
    let look = || {
        if std::thread::current().id() == on_this_thread {
            if let Err(e) = Python::attach(|py| py.check_signals()) {
                let mut pending = interrupt.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                pending.get_or_insert(e);
            }
        }
        interrupt.lock().map_or(true, |p| p.is_some())
    };
    let mut bar = Progress::new("cross-validation", show);
    // Also set when the progress line caught the interrupt while drawing (kept in the bar).
    let drawn_interrupt = std::sync::atomic::AtomicBool::new(false);
    let stoppable = |run: usize, models: &[&CoreModel<'_>]| {
        if look() || drawn_interrupt.load(std::sync::atomic::Ordering::Relaxed) {
            return Err(fogtemp_cal::CalError::Interrupted);
        }
        replay(run, models)
    };
    let fitted = py.detach(|| {
        let progress = |k: usize, n: usize| {
            bar.count(k as u64, n as u64, "folds");
            look();
            if bar.interrupted() {
                drawn_interrupt.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        };
        calibrate::fit_model_replaying(runs, config, digest, selection, progress, &stoppable)
    });
    bar.finish();
    if let Some(e) = interrupt.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner) {
        return Err(e);
    }
    bar.boundary(py)?;
    fitted.map_err(errors::cal)
}

/// What [`file_runs`] reads: each kept log's features, the input digest, with run metadata
/// its source and each kept log's row, and the run metadata's warnings (logs of an unfinished
/// simulation, warned already).
type FileRuns =
    (Vec<RunFeatures>, [u8; 32], Option<(String, Vec<fogtemp_cal::runs::RunMetadata>)>, Vec<String>);

/// Features of every log file (the command line's `fit` reading loop); with a runs file,
/// of the logs whose role is not `val`, each with its row.
fn file_runs(
    py: Python<'_>,
    items: &[Bound<'_, PyAny>],
    config: &CalibrationConfig,
    show: bool,
    runs_file: Option<&Path>,
) -> PyResult<FileRuns> {
    let paths: Vec<PathBuf> = items
        .iter()
        .map(|i| {
            i.extract::<PathBuf>().map_err(|_| {
                PyTypeError::new_err("fit(): logs must be paths, or runs given as dicts or DataFrames")
            })
        })
        .collect::<PyResult<_>>()?;
    let logs = expand_logs(&paths)?;
    // A runs file, else the fogtemp simulations' manifests beside the logs (DESIGN.md §3).
    let metadata = fogtemp_cal::runs::logs_metadata(&logs, runs_file, fogtemp_cal::runs::Role::Val, "runs=")
        .map_err(errors::cal)?;
    for note in &metadata.notes {
        progress::note(py, note)?;
    }
    for warning in &metadata.warnings {
        progress::warn(py, warning)?;
    }
    let (logs, rows) = fogtemp_cal::runs::calibration_runs(&logs, &metadata).map_err(errors::cal)?;
    let mut runs = Vec::with_capacity(logs.len());
    let mut input_digest = fogtemp_cal::digest::InputDigest::new();
    for log in &logs {
        let mut bar = Progress::new(format!("features {}", file_name(log)), show);
        let run = py.detach(|| {
            calibrate::extract_run_digested(log, config, &mut input_digest, |b, r| bar.rows(b, r))
        });
        bar.finish();
        // Ctrl-C is raised here, between two logs.
        bar.boundary(py)?;
        let run = run.map_err(errors::cal)?;
        if run.ingest.rows == 0 {
            let why = run.ingest.only_temperature_rows("gyro_column=");
            return Err(errors::value(
                why.unwrap_or_else(|| format!("{}: no data rows (only a header)", log.display())),
            ));
        }
        warn_skipped(py, &run.ingest, false)?;
        if let Some(note) = run.gaps.note(&run.path) {
            progress::note(py, &note)?;
        }
        for note in calibrate::time_unit_notes(&run.path, &run.gaps, &run.ingest, "time_unit=") {
            progress::warn(py, &note)?;
        }
        for note in (0..run.temperature_silences.len()).filter_map(|axis| run.temperature_silence_note(axis))
        {
            progress::note(py, &note)?;
        }
        runs.push(run);
    }
    let (digest, each) = input_digest.finish();
    if let Some(warning) = fogtemp_cal::digest::same_logs_note(&logs, &each) {
        progress::warn(py, &warning)?;
    }
    Ok((runs, digest, rows.map(|rows| (metadata.source, rows)), metadata.warnings))
}

/// Features of every run given as arrays, and the digest of their values.
/// Borrowed slices of one run's arrays (valid while the run's read-only arrays live).
pub(crate) struct ArrayColumns<'a> {
    name: &'a Path,
    time_s: &'a [f64],
    temps_c: Vec<&'a [f64]>,
    gyros_dph: Vec<&'a [f64]>,
}

impl<'a> ArrayColumns<'a> {
    pub(crate) fn new(run: &'a ArrayRun<'_>) -> PyResult<Self> {
        Ok(Self {
            name: &run.name,
            time_s: slice(&run.time_s, "time_s")?,
            temps_c: run.temps_c.iter().map(|a| slice(a, "temp_c")).collect::<PyResult<_>>()?,
            gyros_dph: run.gyros_dph.iter().map(|a| slice(a, "gyro_dph")).collect::<PyResult<_>>()?,
        })
    }

    pub(crate) fn view(&self) -> RunArrays<'_> {
        RunArrays { name: self.name, time_s: self.time_s, temps_c: &self.temps_c, gyros_dph: &self.gyros_dph }
    }
}

/// Features of every run given as arrays (the same row rules and feature code as a file).
fn array_features(
    py: Python<'_>,
    runs: &[ArrayRun<'_>],
    config: &mut CalibrationConfig,
) -> PyResult<(Vec<RunFeatures>, [u8; 32])> {
    use sha2::Digest;
    let axes = runs[0].gyros_dph.len();
    // One gyro array and one temperature array are the columns `gyro_dph` and `temp_c` of a
    // log with the same samples, and the model records them as such; several arrays have no
    // column names of their own, so none are recorded (axes matched by position).
    let single = axes == 1 && runs[0].temps_c.len() == 1;
    config.ingest.format.gyro_columns =
        if single { vec!["gyro_dph".into()] } else { (0..axes).map(|k| format!("gyro_dph[{k}]")).collect() };
    config.record_columns = single;
    let mut hasher = sha2::Sha256::new();
    let mut features = Vec::with_capacity(runs.len());
    for run in runs {
        run.digest_into(&mut hasher)?;
        let mut own = sha2::Sha256::new();
        run.digest_into(&mut own)?;
        let columns = ArrayColumns::new(run)?;
        let view = columns.view();
        let f = py.detach(|| extract_run_arrays(&view, config));
        py.check_signals()?;
        let mut f = f.map_err(array_error)?;
        f.digest = Some(own.finalize().into());
        if f.ingest.rows == 0 {
            return Err(errors::value(format!("{}: no samples", run.name.display())));
        }
        warn_skipped(py, &f.ingest, true)?;
        if let Some(note) = f.gaps.note(&f.path) {
            progress::note(py, &note)?;
        }
        // Arrays are in seconds: another unit is said as such (review32a F7: arrays timed in
        // milliseconds got no "another unit?" warning, and then advice to name a column).
        for note in calibrate::time_unit_notes(&f.path, &f.gaps, &f.ingest, "") {
            progress::warn(py, &note)?;
        }
        for note in (0..f.temperature_silences.len()).filter_map(|axis| f.temperature_silence_note(axis)) {
            progress::note(py, &note)?;
        }
        features.push(f);
    }
    Ok((features, hasher.finalize().into()))
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// Warns about skipped rows, in the command line's words (nothing is dropped silently); for
/// runs given as arrays (`samples`), in the words of `fit`'s errors: sample indices, not lines.
fn warn_skipped(py: Python<'_>, report: &IngestReport, samples: bool) -> PyResult<()> {
    if let Some(note) = report.temperature_only_note() {
        progress::note(py, &note)?;
    }
    if report.skipped == 0 {
        return Ok(());
    }
    let unit = if samples { "sample" } else { "row" };
    // The share and, from 1 %, the advice to check the log, as the command line says them
    // (review25a 9).
    let mut text =
        format!("{}: {}; first ones:", report.path.display(), report.skipped_summary(unit, "skip_bad_rows"));
    for b in &report.first_skipped {
        let place = if samples {
            format!("sample {} '{}'", b.line, b.column_name)
        } else {
            format!("line {} column {} '{}'", b.line, b.column, b.column_name)
        };
        text.push_str(&format!("\n  {place}: {} (found '{}')", b.kind.describe(), b.found));
    }
    progress::warn(py, &text)
}

/// Reads a CSV log into numpy arrays (the library's ingest, as every command reads logs).
///
/// Returns `{"time_s", "temp_c", "gyro_dph", "time_origin_s"}`: time in seconds since the
/// first row, deg C (NaN where a row has no temperature reading), deg/h, one entry per
/// sample (a row with a temperature and no gyro reading is no sample: its reading goes with
/// the next sample, with a warning; channels logged on separate rows); with several
/// temperature or gyro columns the keys are `temp_c_0`, `temp_c_1`, ... and `gyro_dph_0`,
/// .... `time_origin_s` (a float) is the first row's time in the log's own clock, seconds:
/// its time cell in seconds for `time_unit` 's', 'ms', 'us', 'ns', 'min' and 'h' (an epoch stamp stays one),
/// seconds since 1970 UTC for 'datetime', since midnight for 'time_of_day', 0 when the rows
/// are timed by `sample_rate_hz`; `time_origin_s + time_s` is each row's own stamp, as `fogtemp-cal
/// compensate` writes it. `as_dataframe=True` returns a pandas DataFrame of the arrays
/// instead, with `df.attrs["time_origin_s"]`.
///
/// Keywords: the log-column options of `fit`. The log's shape: `skip_lines` (lines to drop
/// before the header or the data), `delimiter` ("auto", "comma", "semicolon", "tab",
/// "whitespace" or one character), `comment` (a line prefix; "" for none) and `columns`, the names of a
/// headerless log's columns in order: a list of str, or one str of comma-separated names as
/// on the command line ("time_s,temp_c,gyro_dph"); "" (or []) for a log with a header row.
/// `model=` (a `Model`, or a model file): read the log as the model's fit read its logs:
/// columns, units, time and, for a model that records it (format 7), the shape (skip_lines,
/// delimiter, comment, columns), as `validate` does (keywords given still win, with a warning
/// where they differ), so the arrays go straight into `Model.compensate`.
#[pyfunction]
#[pyo3(signature = (path, *, model = None, as_dataframe = false, progress = true, **options))]
pub fn read_log<'py>(
    py: Python<'py>,
    path: PathBuf,
    model: Option<&Bound<'py, PyAny>>,
    as_dataframe: bool,
    progress: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    if path.is_dir() {
        return Err(pyo3::exceptions::PyIsADirectoryError::new_err(format!(
            "{}: a folder; read_log() reads one log (fit() and validate() take folders)",
            path.display()
        )));
    }
    let mut o = Options::new("read_log", options);
    let named = (
        (o.any_given(&["gyro_column"])?, o.any_given(&["temp_column"])?),
        (o.any_given(&["gyro_unit", "gyro_scale"])?, o.any_given(&["temp_scale", "temp_offset"])?),
        time_named(&o)?,
        o.any_given(&["decimal_mark"])?,
        shape_named(&o)?,
    );
    let mut ingest = options::ingest(&mut o)?;
    // Only read_log takes it: fit and validate refuse such rows (review20 F2, the file part).
    ingest.keep_impossible_temperatures = o.bool("keep_impossible_temperatures", false)?;
    o.finish()?;
    if let Some(model) = model {
        let blob = model_arg(model)?;
        let core = CoreModel::from_bytes(&blob.0).map_err(|e| errors::model(&blob.1, e))?;
        choose_columns(py, &mut ingest, named, std::slice::from_ref(&blob), std::slice::from_ref(&core))?;
    }
    warn_unit_names(py, &ingest.format)?;
    let (temps, gyros) = (ingest.format.temp_columns.len(), ingest.format.gyro_columns.len());
    let mut time = Vec::new();
    let mut temp_cols: Vec<Vec<f64>> = vec![Vec::new(); temps];
    let mut gyro_cols: Vec<Vec<f64>> = vec![Vec::new(); gyros];
    let mut bar = Progress::new(format!("read {}", file_name(&path)), progress);
    let report = py.detach(|| {
        read_log_with_progress(
            &path,
            &ingest,
            |row| {
                time.push(row.time_s);
                for (c, v) in temp_cols.iter_mut().zip(row.temps_c) {
                    c.push(*v);
                }
                for (c, v) in gyro_cols.iter_mut().zip(row.gyros_dph) {
                    c.push(*v);
                }
                Ok(())
            },
            |b, r| bar.rows(b, r),
        )
    });
    bar.finish();
    bar.boundary(py)?;
    let report = report.map_err(errors::cal)?;
    warn_skipped(py, &report, false)?;
    let dict = PyDict::new(py);
    dict.set_item("time_s", PyArray1::from_vec(py, time))?;
    let named = |base: &str, k: usize, count: usize| {
        if count == 1 {
            base.to_string()
        } else {
            format!("{base}_{k}")
        }
    };
    for (k, c) in temp_cols.into_iter().enumerate() {
        dict.set_item(named("temp_c", k, temps), PyArray1::from_vec(py, c))?;
    }
    for (k, c) in gyro_cols.into_iter().enumerate() {
        dict.set_item(named("gyro_dph", k, gyros), PyArray1::from_vec(py, c))?;
    }
    // The log's own clock at its first row, so that `time_origin_s + time_s` joins other
    // channels by time as `compensate`'s output does (review20 F5).
    let time_origin_s = report.time_origin_s;
    if as_dataframe {
        let pandas = py.import("pandas").map_err(|e| {
            pyo3::exceptions::PyImportError::new_err(format!(
                "read_log(as_dataframe=True) needs pandas ({e})"
            ))
        })?;
        let frame = pandas.call_method1("DataFrame", (dict,))?;
        frame.getattr("attrs")?.set_item("time_origin_s", time_origin_s)?;
        return Ok(frame);
    }
    dict.set_item("time_origin_s", time_origin_s)?;
    Ok(dict.into_any())
}

/// A model argument: a `Model` or a path to a model file.
fn model_arg(value: &Bound<'_, PyAny>) -> PyResult<(Vec<u8>, String)> {
    if let Ok(m) = value.cast::<Model>() {
        let m = m.get();
        return Ok((m.blob().to_vec(), m.source().to_string()));
    }
    let path: PathBuf =
        value.extract().map_err(|_| PyTypeError::new_err("model must be a fogtemp.Model or a path"))?;
    Ok((crate::model::read_model_file(&path)?, path.display().to_string()))
}

/// Replays validation logs through the model exactly as firmware would (the command line's
/// `validate --json`): raw vs compensated bias stability per run and overall.
///
/// `model` is a `Model` or a path; `logs` paths or folders, or runs given as arrays (dicts or
/// DataFrames with `time_s`, `temp_c` and `gyro_dph`, as `fit` takes them: the same row rules
/// and the same replay as a log file holding those samples). Keywords: `tau_s`,
/// `overlapping`, `detrend`, `exclude_first_s`, `capacity`, `compare` (a list of further
/// models replayed on the same logs), `runs` (a runs file describing every log, as
/// `validate --runs`: when it gives roles, only the `val` runs are validated), `report` (a
/// folder: `report.md`, `report.html` and the figures, as `validate --report`), and the
/// log-column options (files only; `runs` also names runs given as arrays in a dict `{name:
/// run}` by their keys). Log files are read with the columns, units,
/// time and, for a model that records it (format 7), the shape (`skip_lines`, `delimiter`,
/// `comment`, `columns`: a list of str or one str of comma-separated names, "" for a header
/// row) the model records, for each keyword not given (with a warning); the document's
/// `notes` start with how the logs were read, as `validate --json`'s do. Ctrl-C is raised
/// between two logs.
#[pyfunction]
#[pyo3(signature = (model, logs, *, progress = true, **options))]
pub fn validate<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyAny>,
    logs: &Bound<'py, PyAny>,
    progress: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let (items, names) = runs_and_names(logs)?;
    if items.is_empty() {
        return Err(errors::value("validate() needs at least one log or run"));
    }
    let arrays = convert::is_arrays(&items[0])?;
    let mut o = Options::new("validate", options);
    if arrays && o.any_given(&COLUMN_KEYS[..COLUMN_KEYS.len() - 1])? {
        return Err(PyTypeError::new_err(
            "validate(): column and unit options apply to log files; runs given as arrays are in time_s, temp_c, gyro_dph",
        ));
    }
    let columns_named = (o.any_given(&["gyro_column"])?, o.any_given(&["temp_column"])?);
    let units_named =
        (o.any_given(&["gyro_unit", "gyro_scale"])?, o.any_given(&["temp_scale", "temp_offset"])?);
    let time_named = time_named(&o)?;
    let decimal_named = o.any_given(&["decimal_mark"])?;
    let shape_named = shape_named(&o)?;
    let mut ingest = options::ingest(&mut o)?;
    let stability = options::stability(&mut o)?;
    let capacity = o.int("capacity", fogtemp_core::DEFAULT_CAPACITY, options::MIN_CAPACITY, u64::MAX)?;
    let compare = match o.get("compare")? {
        Some(c) => as_list(&c)?,
        None => Vec::new(),
    };
    let runs_file = o.opt_path("runs")?;
    let report = o.report_folder()?;
    o.finish()?;
    if arrays && runs_file.is_some() && names.is_none() {
        return Err(PyTypeError::new_err(
            "validate(): runs= names runs by their names: give runs as arrays in a dict {name: run}, the \
             names those of the runs file's run column",
        ));
    }
    let mut blobs = vec![model_arg(model)?];
    for c in &compare {
        blobs.push(model_arg(c)?);
    }
    let models: Vec<CoreModel<'_>> = blobs
        .iter()
        .map(|(b, s)| CoreModel::from_bytes(b).map_err(|e| errors::model(s, e)))
        .collect::<PyResult<_>>()?;
    for ((_, source), m) in blobs.iter().zip(&models) {
        for index in 0..m.axis_count() {
            let axis = m.axis(index).map_err(|e| errors::model(source, e))?;
            options::capacity_fits(axis.blocks_needed(), capacity)
                .map_err(|e| errors::value(format!("{source} axis {index}: {}", e.value(py))))?;
        }
    }
    let refs: Vec<&CoreModel<'_>> = models.iter().collect();
    let (mut in_sample, mut file_notes): (Vec<String>, Vec<String>) = (Vec::new(), Vec::new());
    // How the logs were read, first in the document's notes as in `validate --json`'s.
    let mut how_read: Vec<String> = Vec::new();
    // Each log's true input rate from the run metadata (none for arrays or without any).
    let mut input_rates: Vec<(PathBuf, f64)> = Vec::new();
    // Logs of an unfinished simulation: warned as read, last in the document's notes.
    let mut unfinished: Vec<String> = Vec::new();
    let per_log = if arrays {
        let mut runs = array_runs_of(&items, names.as_deref())?;
        if let Some(path) = runs_file.as_deref() {
            // As for log files: the val runs when roles are given, each with its rate.
            let (named, metadata) = array_runs_metadata(py, &runs, path, fogtemp_cal::runs::Role::Cal)?;
            let kept;
            (kept, input_rates) =
                fogtemp_cal::runs::validation_runs(named, &metadata).map_err(errors::cal)?;
            runs.retain(|r| kept.contains(&r.name));
        }
        if let Some(note) = calibrate::axis_count_note(
            &blobs[0].1,
            models[0].axis_count(),
            runs[0].gyros_dph.len(),
            "gyro_dph",
        ) {
            progress::warn(py, &note)?;
        }
        validate_array_runs(py, &runs, &refs, ingest, &stability)?
    } else {
        let paths: Vec<PathBuf> = items.iter().map(|l| l.extract::<PathBuf>()).collect::<PyResult<_>>()?;
        let mut logs = expand_logs_for_reading(&paths)?;
        if logs.is_empty() {
            return Err(errors::value("validate() needs at least one log"));
        }
        // A runs file, else the fogtemp simulations' manifests beside the logs (DESIGN.md §3).
        let metadata = fogtemp_cal::runs::logs_metadata(
            &logs,
            runs_file.as_deref(),
            fogtemp_cal::runs::Role::Cal,
            "runs=",
        )
        .map_err(errors::cal)?;
        for note in &metadata.notes {
            progress::note(py, note)?;
        }
        for warning in &metadata.warnings {
            progress::warn(py, warning)?;
        }
        unfinished.clone_from(&metadata.warnings);
        (logs, input_rates) = fogtemp_cal::runs::validation_runs(logs, &metadata).map_err(errors::cal)?;
        how_read = choose_columns(
            py,
            &mut ingest,
            (columns_named, units_named, time_named, decimal_named, shape_named),
            &blobs,
            &models,
        )?;
        warn_unit_names(py, &ingest.format)?;
        let gyro_columns = ingest.format.gyro_columns.len();
        if let Some(note) =
            calibrate::axis_count_note(&blobs[0].1, models[0].axis_count(), gyro_columns, "gyro_column=")
        {
            progress::warn(py, &note)?;
        }
        let (per_log, digests) = validate_log_files(py, &logs, &refs, &ingest, &stability, progress)?;
        let (same, in_sample_logs) = digest_notes(&blobs[0].1, &models[0], &logs, &digests);
        for note in same.iter().chain(&in_sample_logs) {
            progress::warn(py, note)?;
        }
        file_notes.extend(same);
        in_sample.extend(in_sample_logs);
        per_log
    };
    let mut outcomes = Validation::combine_logs(refs.len(), per_log);
    let compared = outcomes.split_off(1.min(outcomes.len()));
    let validation = outcomes.pop().unwrap_or_default().with_input_rates(&input_rates);
    for r in validation.runs.iter().filter(|r| r.axis == 0) {
        if r.ingest.rows == 0 {
            let what = if arrays { "no samples" } else { "no data rows (only a header)" };
            let why = r.ingest.only_temperature_rows("gyro_column=");
            return Err(errors::value(why.unwrap_or_else(|| format!("{}: {what}", r.path.display()))));
        }
        warn_skipped(py, &r.ingest, arrays)?;
    }
    // The notes in the command line's order, for the document's `notes` (the temperature
    // rows' said above, with the skipped rows).
    let mut notes: Vec<String> = calibrate::gap_notes(&validation.runs)
        .into_iter()
        .chain(calibrate::continued_notes(&validation.runs))
        .collect();
    for note in &notes {
        progress::warn(py, note)?;
    }
    notes.splice(0..0, calibrate::temperature_row_notes(&validation.runs));
    // A log's time unit is a setting; arrays are in seconds (as fit() reads them).
    let unit_hint = if arrays { "" } else { "time_unit=" };
    for r in validation.runs.iter().filter(|r| r.axis == 0) {
        for note in calibrate::time_unit_notes(&r.path, &r.series.gaps, &r.ingest, unit_hint) {
            progress::warn(py, &note)?;
        }
    }
    // Arrays take no runs file (review31a F5): their rates come off the arrays themselves.
    let how_to_give = if arrays {
        "give the runs in a dict {name: run} with runs=, or take each run's input rate off its gyro array"
    } else {
        "give each run's input_rate_dph with runs="
    };
    let rates_note =
        fogtemp_cal::runs::input_rates_note(&blobs[0].1, &models[0], &validation.runs, how_to_give);
    for note in validation.runs.iter().flat_map(calibrate::RunValidation::notes).chain(rates_note.clone()) {
        progress::warn(py, &note)?;
        notes.push(note);
    }
    notes.extend(file_notes);
    notes.extend(in_sample.iter().cloned());
    let comparison: Vec<ComparedModel> = if compare.is_empty() {
        Vec::new()
    } else {
        std::iter::once(&validation)
            .chain(&compared)
            .zip(blobs.iter().zip(&models))
            .map(|(v, ((_, source), m))| ComparedModel::new(Path::new(source), m, v))
            .collect()
    };
    if let Some(dir) = &report {
        let source = Path::new(&blobs[0].1);
        py.detach(|| {
            write_validation_report(dir, source, &models[0], &validation, &stability, &comparison)?;
            fogtemp_cal::report::add_notes_to_validation_report(
                dir,
                "Runs the model was fitted on (their figures are in-sample):",
                &in_sample,
            )
            .map_err(errors::cal)?;
            let metadata: Vec<String> = rates_note.iter().chain(&unfinished).cloned().collect();
            fogtemp_cal::report::add_notes_to_validation_report(
                dir,
                fogtemp_cal::report::RUN_METADATA_HEADING,
                &metadata,
            )
            .map_err(errors::cal)
        })?;
    }
    let notes = how_read.into_iter().chain(notes).chain(unfinished).collect();
    convert::document(py, &ValidationDocument::new(&stability, &validation, comparison).with_notes(notes))
}

/// `validate`'s notes from the logs' digests (`fogtemp_cal::digest`):
/// logs with the same bytes, and logs the model was fitted on.
fn digest_notes(
    name: &str,
    model: &CoreModel<'_>,
    logs: &[PathBuf],
    digests: &Digests,
) -> (Option<String>, Option<String>) {
    let same = fogtemp_cal::digest::same_logs_note(logs, &digests.1);
    (same, fogtemp_cal::digest::in_sample_note_from(name, model, logs, digests))
}

/// Which time keywords were given (the others are read as a model records them).
fn time_named(o: &Options<'_>) -> PyResult<TimeNamed> {
    Ok(TimeNamed {
        column: o.any_given(&["time_column"])?,
        unit: o.any_given(&["time_unit"])?,
        sample_rate: o.any_given(&["sample_rate_hz"])?,
        date: o.any_given(&["date_column"])?,
    })
}

/// Which log-shape keywords were given (the others are read as a model records them).
fn shape_named(o: &Options<'_>) -> PyResult<ShapeNamed> {
    Ok(ShapeNamed {
        skip_lines: o.any_given(&["skip_lines"])?,
        delimiter: o.any_given(&["delimiter"])?,
        comment: o.any_given(&["comment"])?,
        columns: o.any_given(&["columns"])?,
    })
}

/// Warns for columns whose names give another unit than the one they are read in
/// (`fogtemp_cal::unit_names`), as the command line does.
pub(crate) fn warn_unit_names(py: Python<'_>, format: &fogtemp_cal::ingest::LogFormat) -> PyResult<()> {
    for note in fogtemp_cal::unit_names::unit_name_notes(format, fogtemp_cal::axis_columns::PYTHON_OPTIONS) {
        progress::warn(py, &note)?;
    }
    Ok(())
}

/// Which of the column, unit, time, decimal-mark and shape keywords were given.
type NamedKeywords = ((bool, bool), (bool, bool), TimeNamed, bool, ShapeNamed);

/// The log columns, units, time and shape for replaying `models` (the first is validated,
/// the rest compared): the ones each model records unless `gyro_column=`, `temp_column=`, the
/// unit keywords, the time keywords, `decimal_mark=` or the shape keywords were given
/// (`named`), named columns checked against them (as the command line's `validate`); notes
/// become warnings. Returns the first model's notes, how the logs are read, which
/// `validate --json` puts first in its document's `notes` (review20 F6).
fn choose_columns(
    py: Python<'_>,
    ingest: &mut IngestOptions,
    ((gyro_named, temp_named), (gyro_units, temp_units), time, decimal_mark, shape): NamedKeywords,
    blobs: &[(Vec<u8>, String)],
    models: &[CoreModel<'_>],
) -> PyResult<Vec<String>> {
    use fogtemp_cal::axis_columns::{choose_for_replay, Named, PYTHON_OPTIONS};
    let none = Vec::new();
    let (gyro, temp) = (ingest.format.gyro_columns.clone(), ingest.format.temp_columns.clone());
    let named = Named {
        gyro_columns: if gyro_named { &gyro } else { &none },
        temp_columns: if temp_named { &temp } else { &none },
        gyro_units,
        temp_units,
        time,
        decimal_mark,
        shape,
    };
    let mut format = ingest.format.clone();
    let mut how_read = Vec::new();
    for (index, ((_, source), model)) in blobs.iter().zip(models).enumerate() {
        // The compared models are checked against the columns and units chosen for the first.
        let chosen = match index {
            0 => choose_for_replay(model, source, &mut ingest.format, named, PYTHON_OPTIONS),
            _ => {
                choose_for_replay(model, source, &mut format.clone(), Named::all_of(&format), PYTHON_OPTIONS)
            }
        }
        .map_err(|e| errors::value(e.to_string()))?;
        for note in &chosen.notes {
            progress::note(py, note)?;
        }
        if index == 0 {
            format = ingest.format.clone();
            how_read = chosen.notes;
        }
    }
    Ok(how_read)
}

/// Every log file replayed through every model, one log at a time (the library's validation
/// of each, in log order), so that Ctrl-C is raised between two logs; with the logs' digests
/// taken as they are read.
fn validate_log_files(
    py: Python<'_>,
    logs: &[PathBuf],
    models: &[&CoreModel<'_>],
    ingest: &IngestOptions,
    stability: &BiasStabilityOptions,
    progress: bool,
) -> PyResult<(Vec<Vec<Validation>>, Digests)> {
    let mut per_log = Vec::with_capacity(logs.len());
    let mut digest = fogtemp_cal::digest::InputDigest::new();
    for log in logs {
        let mut bar = Progress::new(format!("validate {}", file_name(log)), progress);
        let outcome = py.detach(|| {
            let one = std::slice::from_ref(log);
            calibrate::validate_models_digested(one, models, ingest, stability, &mut digest, |_, b, r| {
                bar.rows(b, r);
            })
        });
        bar.finish();
        bar.boundary(py)?;
        per_log.push(outcome.map_err(errors::cal)?);
    }
    Ok((per_log, digest.finish()))
}

/// Every run given as arrays replayed through every model with the row rules and the
/// `Compensator` a log file gets (`fogtemp_cal::arrays::replay_models_arrays`), one run at a
/// time (Ctrl-C between two). Every run needs as many gyro columns as the first.
fn validate_array_runs(
    py: Python<'_>,
    runs: &[ArrayRun<'_>],
    models: &[&CoreModel<'_>],
    ingest: IngestOptions,
    stability: &BiasStabilityOptions,
) -> PyResult<Vec<Vec<Validation>>> {
    let axes = runs[0].gyros_dph.len();
    if let Some(run) = runs.iter().find(|r| r.gyros_dph.len() != axes) {
        return Err(errors::value(format!(
            "{}['gyro_dph'] has {} columns but runs[0]['gyro_dph'] has {axes}: every run needs the same axes",
            run.name.display(),
            run.gyros_dph.len()
        )));
    }
    let mut config = CalibrationConfig { ingest, ..CalibrationConfig::default() };
    config.ingest.format.gyro_columns = (0..axes).map(|k| format!("gyro_dph[{k}]")).collect();
    let mut per_run = Vec::with_capacity(runs.len());
    for run in runs {
        let columns = ArrayColumns::new(run)?;
        let view = columns.view();
        let outcome = py.detach(|| {
            let replay = fogtemp_cal::arrays::replay_models_arrays(&view, models, &config, 1.0)?;
            calibrate::validations(
                models.len(),
                std::iter::once(Ok((view.name.to_path_buf(), replay))),
                stability,
            )
        });
        py.check_signals()?;
        per_run.push(outcome.map_err(array_error)?);
    }
    Ok(per_run)
}

/// `validate --report DIR`: the library's validation report, and with compared models their
/// table before the first section, as the command line writes it.
fn write_validation_report(
    dir: &Path,
    model_path: &Path,
    model: &CoreModel<'_>,
    validation: &Validation,
    stability: &BiasStabilityOptions,
    comparison: &[ComparedModel],
) -> PyResult<()> {
    let overall = (validation.raw_bias_stability_dph, validation.compensated_bias_stability_dph);
    fogtemp_cal::report::write_validation_report_with(
        dir,
        model_path,
        model,
        &validation.runs,
        overall,
        stability,
        &stability.describe(),
    )
    .map_err(errors::cal)?;
    if comparison.is_empty() {
        return Ok(());
    }
    fogtemp_cal::report::add_comparison_to_validation_report(dir, comparison).map_err(errors::cal)
}

/// Overlapping Allan deviation of a log's gyro with the fitted noise terms N, B, K (the
/// command line's `allan --json`).
///
/// `log` is a path (log-column options as keywords) or a dict/DataFrame with `time_s` and
/// `gyro_dph` (deg/h).
#[pyfunction]
#[pyo3(signature = (log, *, progress = true, **options))]
pub fn allan<'py>(
    py: Python<'py>,
    log: &Bound<'py, PyAny>,
    progress: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let mut o = Options::new("allan", options);
    if convert::is_arrays(log)? {
        // As fit() and validate() take it for arrays (review33b F6).
        let skip_bad_rows = o.bool("skip_bad_rows", false)?;
        o.finish()?;
        let missing =
            |key: &str| errors::value(format!("allan(): no '{key}': {}", missing_column_help(log, key)));
        let time = f64_vector(&convert::item(log, "time_s")?.ok_or_else(|| missing("time_s"))?, "time_s")?;
        // One 2-D `gyro_dph`, or `gyro_dph_0`, `gyro_dph_1`, ... as read_log returns them
        // (review33c F8: the hint said to rename one, dropping the others).
        let gyros = numbered_columns(log, "gyro_dph", "allan()")?.ok_or_else(|| missing("gyro_dph"))?;
        let mut times = slice(&time, "time_s")?.to_vec();
        let mut series: Vec<Vec<f64>> =
            gyros.iter().map(|g| slice(g, "gyro_dph").map(<[f64]>::to_vec)).collect::<PyResult<_>>()?;
        if let Some(s) = series.iter().find(|s| s.len() != times.len()) {
            return Err(errors::value(format!(
                "gyro_dph has {} samples but time_s has {}",
                s.len(),
                times.len()
            )));
        }
        let names: Vec<String> = (0..series.len())
            .map(|k| if series.len() == 1 { "gyro_dph".into() } else { format!("gyro_dph[{k}]") })
            .collect();
        if skip_bad_rows {
            let skipped = keep_good_samples(&mut times, &mut series);
            if let Some((&first, count)) = skipped.first().zip(Some(skipped.len())) {
                progress::warn(
                    py,
                    &format!(
                        "allan(): skipped {count} bad sample{} of {} (a time not finite or not after the previous \
                         kept one, or a rate not finite), the first at index {first}",
                        if count == 1 { "" } else { "s" },
                        count + times.len()
                    ),
                )?;
            }
        }
        let times = times.as_slice();
        // The rules fit() applies to arrays: finite samples, time increasing.
        if let Some(i) = times.iter().position(|t| !t.is_finite()) {
            return Err(errors::value(format!("allan(): time_s[{i}] is {}: not a finite time", times[i])));
        }
        if let Some(i) = times.windows(2).position(|w| w[1] <= w[0]) {
            let (a, b) = (times[i], times[i + 1]);
            return Err(errors::value(format!(
                "allan(): time_s[{}] = {b} is not after time_s[{i}] = {a}: time must increase",
                i + 1
            )));
        }
        for (name, s) in names.iter().zip(&series) {
            if let Some(i) = s.iter().position(|g| !g.is_finite()) {
                return Err(errors::value(format!(
                    "allan(): {name}, sample {i}: {} is not a finite rate",
                    s[i]
                )));
            }
        }
        let doc =
            py.detach(|| AllanDocument::new(Path::new("<arrays>"), &names, times, &series)).ok_or_else(
                || errors::value("allan(): the log needs at least two samples with increasing time"),
            )?;
        for note in doc.axes.iter().flat_map(|d| d.too_short_note().into_iter().chain(d.outlier_note())) {
            progress::warn(py, &note)?;
        }
        return convert::document(py, &doc);
    }
    let ingest: IngestOptions = options::ingest(&mut o)?;
    o.finish()?;
    warn_unit_names(py, &ingest.format)?;
    let path: PathBuf = log.extract()?;
    // Two passes in memory that does not grow with the log: the median sample period, then
    // the curves (the same document as the arrays of the log would give).
    let mut bar = Progress::new(format!("allan 1/2 {}", file_name(&path)), progress);
    let scan = py.detach(|| allan_stream::scan_log(&path, &ingest, |_| true, |b, r| bar.rows(b, r)));
    bar.finish();
    bar.boundary(py)?;
    let scan = scan.map_err(errors::cal)?;
    warn_skipped(py, &scan.report, false)?;
    let mut bar = Progress::new(format!("allan 2/2 {}", file_name(&path)), progress);
    let doc = py.detach(|| {
        allan_stream::allan_of_scanned_log(
            &path,
            &ingest,
            &ingest.format.gyro_columns,
            &scan,
            allan_stream::DEFAULT_EXACT_LIMIT,
            |b, r| bar.rows(b, r),
        )
    });
    bar.finish();
    bar.boundary(py)?;
    let doc = doc
        .map_err(errors::cal)?
        .ok_or_else(|| errors::value(format!("{}: the log needs at least two rows", path.display())))?;
    for note in doc.axes.iter().flat_map(|d| d.too_short_note().into_iter().chain(d.outlier_note())) {
        progress::warn(py, &note)?;
    }
    convert::document(py, &doc)
}

/// Simulates a lab experiment into CSV logs (the command line's `simulate --json`):
/// `scenario` is "paper" (the built-in scenario of the paper's experiment) or a scenario TOML
/// file; `rate` (Hz), `seed` and `duration_s` override it. Writes `out/NAME.csv` per run,
/// `truth/`, `scenario.toml` and `manifest.json`; returns the document.
#[pyfunction]
#[pyo3(signature = (scenario = "paper", *, out, rate = None, seed = None, duration_s = None, progress = true))]
pub fn simulate<'py>(
    py: Python<'py>,
    scenario: &str,
    out: PathBuf,
    rate: Option<f64>,
    seed: Option<&Bound<'py, PyAny>>,
    duration_s: Option<f64>,
    progress: bool,
) -> PyResult<Bound<'py, PyAny>> {
    use fogtemp_sim::Scenario;
    let seed: Option<u64> = seed.map(|s| options::int_arg("simulate", "seed", s, 0, u64::MAX)).transpose()?;
    let (mut sc, mut text) = if scenario == "paper" {
        (Scenario::paper().map_err(errors::sim)?, fogtemp_sim::PAPER_TOML.to_string())
    } else {
        let text = std::fs::read_to_string(scenario).map_err(|e| {
            errors::cal(fogtemp_cal::CalError::Io { path: PathBuf::from(scenario), source: e })
        })?;
        (Scenario::from_toml(&text, scenario).map_err(errors::sim)?, text)
    };
    // The command line's overrides (`simulate --rate --seed --duration-s`).
    let overridden = sc
        .apply_overrides(rate, seed, duration_s)
        .map_err(|e| errors::value(format!("scenario after the overrides: {e}")))?;
    if overridden {
        let comment = Scenario::overrides_comment(scenario, rate, seed, duration_s);
        text = format!("{comment}\n{}", sc.to_toml().map_err(errors::sim)?);
    }
    // `simulate_to_dir` checks the folder and the scenario, then makes the folder.
    let total: u64 =
        sc.expanded_runs().iter().map(|r| (r.duration_s * sc.sample_rate_hz).floor() as u64 + 1).sum();
    let bar = std::sync::Mutex::new((Progress::new("simulate", progress), 0u64));
    let started = std::time::Instant::now();
    let runs = py.detach(|| {
        fogtemp_sim::simulate_to_dir(&sc, &text, &out, &|n| {
            if let Ok(mut b) = bar.lock() {
                b.1 += n;
                let done = b.1;
                b.0.count(done, total, "samples");
            }
        })
    });
    if let Ok(mut b) = bar.lock() {
        b.0.finish();
        b.0.boundary(py)?;
    }
    let runs = runs.map_err(errors::sim)?;
    let doc =
        fogtemp_sim::documents::SimulateDocument::new(&sc, &out, &runs, started.elapsed().as_secs_f64());
    convert::document(py, &doc)
}
