//! Keyword options: the command line's flags as keywords (`--temp-column` is
//! `temp_column=`), mapped onto the same library settings with the same defaults.

use std::collections::BTreeSet;

use fogtemp_cal::calibrate::{CalibrationConfig, Thinning};
use fogtemp_cal::ingest::{DecimalMark, Delimiter, IngestOptions, LogFormat, RateUnit, TimeUnit};
use fogtemp_cal::metrics::BiasStabilityOptions;
use fogtemp_cal::poly_fit::TermSelection;
use fogtemp_cal::thin::GreedyThinning;
use fogtemp_core::FeatureSettings;
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

use crate::errors;

/// The keyword arguments of one call; every key must be taken once, or [`Options::finish`]
/// raises `TypeError` naming it (a misspelt option is never ignored).
pub struct Options<'py> {
    dict: Option<Bound<'py, PyDict>>,
    taken: BTreeSet<String>,
    function: &'static str,
}

impl<'py> Options<'py> {
    /// The options of `function` (for messages).
    pub fn new(function: &'static str, dict: Option<&Bound<'py, PyDict>>) -> Self {
        Self { dict: dict.cloned(), taken: BTreeSet::new(), function }
    }

    /// The value of `key` unless absent or `None`.
    pub fn get(&mut self, key: &str) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.taken.insert(key.to_string());
        let Some(dict) = &self.dict else { return Ok(None) };
        Ok(dict.get_item(key)?.filter(|v| !v.is_none()))
    }

    /// A `TypeError` for a value of the wrong type.
    fn wrong(&self, key: &str, expected: &str, e: PyErr) -> PyErr {
        PyTypeError::new_err(format!("{}(): {key} must be {expected} ({e})", self.function))
    }

    /// A float option.
    pub fn f64(&mut self, key: &str, default: f64) -> PyResult<f64> {
        match self.get(key)? {
            Some(v) => v.extract::<f64>().map_err(|e| self.wrong(key, "a number", e)),
            None => Ok(default),
        }
    }

    /// An optional float option.
    pub fn opt_f64(&mut self, key: &str) -> PyResult<Option<f64>> {
        match self.get(key)? {
            Some(v) => v.extract::<f64>().map(Some).map_err(|e| self.wrong(key, "a number", e)),
            None => Ok(None),
        }
    }

    /// An optional `(min, max)` pair with min < max, both finite.
    pub fn opt_f64_pair(&mut self, key: &str) -> PyResult<Option<(f64, f64)>> {
        match self.get(key)? {
            None => Ok(None),
            Some(v) => {
                let (lo, hi) =
                    v.extract::<(f64, f64)>().map_err(|e| self.wrong(key, "a (min, max) pair", e))?;
                if lo.is_finite() && hi.is_finite() && lo < hi {
                    Ok(Some((lo, hi)))
                } else {
                    Err(errors::value(format!("{key} must be (min, max) with min < max, got ({lo}, {hi})")))
                }
            }
        }
    }

    /// An integer option in `min..=max` (the command line's range for the flag); see
    /// [`int_arg`].
    pub fn int<T: TryFrom<u64>>(&mut self, key: &str, default: T, min: u64, max: u64) -> PyResult<T> {
        match self.get(key)? {
            Some(v) => int_arg(self.function, key, &v, min, max),
            None => Ok(default),
        }
    }

    /// A boolean option.
    pub fn bool(&mut self, key: &str, default: bool) -> PyResult<bool> {
        match self.get(key)? {
            Some(v) => v.extract::<bool>().map_err(|e| self.wrong(key, "True or False", e)),
            None => Ok(default),
        }
    }

    /// A string option.
    pub fn string(&mut self, key: &str, default: &str) -> PyResult<String> {
        match self.get(key)? {
            Some(v) => v.extract::<String>().map_err(|e| self.wrong(key, "a string", e)),
            None => Ok(default.to_string()),
        }
    }

    /// An optional string option.
    pub fn opt_string(&mut self, key: &str) -> PyResult<Option<String>> {
        match self.get(key)? {
            Some(v) => v.extract::<String>().map(Some).map_err(|e| self.wrong(key, "a string", e)),
            None => Ok(None),
        }
    }

    /// An optional path option (a string or an `os.PathLike`).
    pub fn opt_path(&mut self, key: &str) -> PyResult<Option<std::path::PathBuf>> {
        match self.get(key)? {
            Some(v) => v.extract::<std::path::PathBuf>().map(Some).map_err(|e| self.wrong(key, "a path", e)),
            None => Ok(None),
        }
    }

    /// `report=`: the folder a report is written into, checked before any work as the command
    /// line checks `--report`: an empty path (which would write into the current folder,
    /// over what is there) and an existing file are refused.
    pub fn report_folder(&mut self) -> PyResult<Option<std::path::PathBuf>> {
        let Some(dir) = self.opt_path("report")? else { return Ok(None) };
        if dir.as_os_str().is_empty() {
            return Err(errors::value(format!(
                "{}(): report= is an empty path: give the folder to write the report into, or None for no report",
                self.function
            )));
        }
        if dir.exists() && !dir.is_dir() {
            return Err(errors::value(format!(
                "{}: exists and is not a folder; report= names the folder to write the report into",
                dir.display()
            )));
        }
        Ok(Some(dir))
    }

    /// A string or a list of strings.
    pub fn strings(&mut self, key: &str, default: &str) -> PyResult<Vec<String>> {
        match self.get(key)? {
            Some(v) if v.is_instance_of::<PyString>() => Ok(vec![v.extract::<String>()?]),
            Some(v) => {
                v.extract::<Vec<String>>().map_err(|e| self.wrong(key, "a string or a list of strings", e))
            }
            None => Ok(vec![default.to_string()]),
        }
    }

    /// True if any of `keys` was given (and not `None`).
    pub fn any_given(&self, keys: &[&str]) -> PyResult<bool> {
        let Some(dict) = &self.dict else { return Ok(false) };
        for key in keys {
            if dict.get_item(key)?.is_some_and(|v| !v.is_none()) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Raises `TypeError` for any keyword no option took.
    pub fn finish(self) -> PyResult<()> {
        let Some(dict) = &self.dict else { return Ok(()) };
        for key in dict.keys() {
            let key: String = key.extract()?;
            if !self.taken.contains(&key) {
                return Err(PyTypeError::new_err(format!(
                    "{}() got an unexpected keyword argument '{key}'",
                    self.function
                )));
            }
        }
        Ok(())
    }
}

/// The smallest tracker capacity a firmware `Compensator` can have, blocks (the command
/// line's `--capacity` range).
pub const MIN_CAPACITY: u64 = 2;

/// An integer keyword or argument `key` of `function` in `min..=max` (`u64::MAX`: no upper
/// bound but `T`'s), as a `T`: any Python integer (numpy's included) outside the range,
/// negative or too large for `T`, raises `ValueError` naming the keyword and the range, as
/// the other keyword checks do; a value that is not an integer raises `TypeError`.
pub fn int_arg<T: TryFrom<u64>>(
    function: &str,
    key: &str,
    value: &Bound<'_, PyAny>,
    min: u64,
    max: u64,
) -> PyResult<T> {
    if value.is_instance_of::<pyo3::types::PyBool>() {
        // `True` is an int to Python, but never what a count, an axis or a seed means.
        return Err(PyTypeError::new_err(format!("{function}(): {key} must be an integer, got a bool")));
    }
    let index = value
        .py()
        .import("operator")?
        .call_method1("index", (value,))
        .map_err(|e| PyTypeError::new_err(format!("{function}(): {key} must be an integer ({e})")))?;
    index
        .extract::<u64>()
        .ok()
        .filter(|n| (min..=max).contains(n))
        .and_then(|n| T::try_from(n).ok())
        .ok_or_else(|| errors::value(format!("{key} must be {}, got {index}", range_words(min, max))))
}

/// An integer range in the words of the keyword messages: "2 to 4096", "at least 3".
fn range_words(min: u64, max: u64) -> String {
    if max == u64::MAX && min == 0 {
        "a non-negative integer below 2**64".to_string()
    } else if max == u64::MAX {
        format!("at least {min} and below 2**64")
    } else {
        format!("{min} to {max}")
    }
}

/// The log-column keywords (the command line's "Log columns" flags).
pub const COLUMN_KEYS: [&str; 16] = [
    "time_column",
    "time_unit",
    "temp_column",
    "temp_scale",
    "temp_offset",
    "gyro_column",
    "gyro_unit",
    "gyro_scale",
    "delimiter",
    "skip_lines",
    "columns",
    "sample_rate_hz",
    "comment",
    "decimal_mark",
    "date_column",
    "skip_bad_rows",
];

/// Ingest options from the log-column keywords, with the command line's defaults.
pub fn ingest(o: &mut Options<'_>) -> PyResult<IngestOptions> {
    let time_unit = match o.string("time_unit", "s")?.as_str() {
        "s" => TimeUnit::Seconds,
        "ms" => TimeUnit::Milliseconds,
        "us" => TimeUnit::Microseconds,
        "ns" => TimeUnit::Nanoseconds,
        "min" => TimeUnit::Minutes,
        "h" => TimeUnit::Hours,
        "datetime" => TimeUnit::DateTime,
        "time_of_day" => TimeUnit::TimeOfDay,
        other => {
            return Err(errors::value(format!(
            "time_unit must be 's', 'ms', 'us', 'ns', 'min', 'h', 'datetime' or 'time_of_day', got '{other}'"
        )))
        }
    };
    let gyro_unit = match o.string("gyro_unit", "dph")?.as_str() {
        "dph" => RateUnit::DegPerHour,
        "dps" => RateUnit::DegPerSecond,
        "rps" => RateUnit::RadPerSecond,
        other => {
            return Err(errors::value(format!("gyro_unit must be 'dph', 'dps' or 'rps', got '{other}'")))
        }
    };
    let delimiter = Delimiter::from_name(&o.string("delimiter", "auto")?)
        .map_err(|e| errors::value(format!("delimiter: {e}")))?;
    let decimal_mark = DecimalMark::from_name(&o.string("decimal_mark", "point")?)
        .map_err(|e| errors::value(format!("decimal_mark: {e}")))?;
    let comment = o.string("comment", "#")?;
    let columns = column_names(o)?;
    Ok(IngestOptions {
        format: LogFormat {
            time_column: o.string("time_column", "time_s")?,
            time_unit,
            temp_columns: o.strings("temp_column", "temp_c")?,
            temp_scale: o.f64("temp_scale", 1.0)?,
            temp_offset_c: o.f64("temp_offset", 0.0)?,
            gyro_columns: o.strings("gyro_column", "gyro_dph")?,
            gyro_unit,
            gyro_scale: o.f64("gyro_scale", 1.0)?,
            delimiter,
            skip_lines: o.int("skip_lines", 0, 0, u64::MAX)?,
            comment: (!comment.is_empty()).then_some(comment),
            column_names: columns,
            sample_rate_hz: o.opt_f64("sample_rate_hz")?,
            sample_rate_from_model: false,
            date_column: o.opt_string("date_column")?,
            decimal_mark,
        },
        skip_bad_rows: o.bool("skip_bad_rows", false)?,
        keep_impossible_temperatures: false,
    })
    .and_then(|options: IngestOptions| {
        let f = &options.format;
        require(
            "temp_scale",
            f.temp_scale.is_finite() && f.temp_scale != 0.0,
            "a finite, non-zero number",
            f.temp_scale,
        )?;
        require("temp_offset", f.temp_offset_c.is_finite(), "a finite number", f.temp_offset_c)?;
        require(
            "gyro_scale",
            f.gyro_scale.is_finite() && f.gyro_scale != 0.0,
            "a finite, non-zero number",
            f.gyro_scale,
        )?;
        Ok(options)
    })
}

/// `columns=`: the names of a headerless log's columns, in order, trimmed: a list of names,
/// or one string of names separated by commas as the command line's `--columns a,b,c` takes
/// them (review20 F8: "a,b,c" was read as one name). `""` or `[]`: the logs have a header
/// row (over a model's headerless columns); not given: none.
fn column_names(o: &mut Options<'_>) -> PyResult<Vec<String>> {
    if !o.any_given(&["columns"])? {
        return Ok(Vec::new());
    }
    let text = o.get("columns")?.is_some_and(|v| v.is_instance_of::<PyString>());
    let given = o.strings("columns", "")?;
    let names: Vec<String> = if text {
        given.iter().flat_map(|g| g.split(',')).map(|name| name.trim().to_string()).collect()
    } else {
        // A list item with commas would be one column of that name, which a comma-separated
        // log cannot have: the list was meant as names.
        if let Some(joined) = given.iter().find(|name| name.contains(',')) {
            let split: Vec<String> = joined.split(',').map(|n| format!("'{}'", n.trim())).collect();
            return Err(errors::value(format!(
                "columns: the list item '{joined}' holds commas: give each name as its own item \
                 ([{}]), or all of them as one string '{joined}'",
                split.join(", ")
            )));
        }
        given.iter().map(|name| name.trim().to_string()).collect()
    };
    Ok(if matches!(names.as_slice(), [only] if only.is_empty()) { Vec::new() } else { names })
}

/// A `ValueError` naming the keyword, what it must be and what it was, unless `ok`.
fn require(name: &str, ok: bool, what: &str, found: impl std::fmt::Display) -> PyResult<()> {
    if ok {
        Ok(())
    } else {
        Err(errors::value(format!("{name} must be {what}, got {found}")))
    }
}

/// Refuses settings no fit can use, naming the keyword (the command line refuses the same
/// values as it parses its flags), before any log is read.
/// (The integer keywords are checked as they are read, by [`Options::int`].)
fn check_calibration(c: &CalibrationConfig, tolerance_dph: Option<f64>) -> PyResult<()> {
    let f = &c.features;
    let positive = |v: f64| v.is_finite() && v > 0.0;
    require("window_s", positive(f64::from(f.window_s)), "positive and finite", f.window_s)?;
    // The default min_blocks (10) with a smaller blocks: named as the command line names it.
    if !(2..=f.block_count).contains(&f.min_blocks) {
        return Err(errors::value(format!(
            "min_blocks {} (the default, 10, unless given) exceeds blocks {}: give min_blocks=2..{} too",
            f.min_blocks, f.block_count, f.block_count
        )));
    }
    require("max_gap_s", positive(f64::from(f.max_gap_s)), "positive and finite", f.max_gap_s)?;
    require("target_window_s", positive(c.target_window_s), "positive and finite", c.target_window_s)?;
    if let Some(t) = tolerance_dph {
        require("tolerance_dph", positive(t), "positive and finite", t)?;
    }
    if let TermSelection::Stepwise { p_enter, p_remove, .. } = c.poly {
        let probability = |p: f64| p > 0.0 && p < 1.0;
        require("p_enter", probability(p_enter), "between 0 and 1 (exclusive)", p_enter)?;
        require("p_remove", probability(p_remove) && p_remove >= p_enter, "between p_enter and 1", p_remove)?;
    }
    Ok(())
}

/// The fit settings (everything but the method and the ingest options) from the command
/// line's `fit` keywords, with its defaults.
pub fn calibration(o: &mut Options<'_>, base: CalibrationConfig) -> PyResult<CalibrationConfig> {
    let defaults = fogtemp_cal::calibrate::default_features();
    let window_s = o.f64("window_s", f64::from(defaults.window_s))? as f32;
    // The command line's ranges: blocks 2 to the format's maximum, min_blocks 2 to blocks.
    let block_count = o.int("blocks", defaults.block_count, 2, u64::from(fogtemp_core::wire::MAX_BLOCKS))?;
    let min_blocks = o.int("min_blocks", defaults.min_blocks, 2, u64::from(block_count))?;
    let max_gap_s = o.f64("max_gap_s", f64::from(defaults.max_gap_s))? as f32;
    let features = FeatureSettings { window_s, block_count, min_blocks, max_gap_s };
    let target_window_s = o.opt_f64("target_window_s")?.unwrap_or(f64::from(features.window_s));
    let max_nodes = o.int("max_nodes", 600, 3, u64::MAX)?;
    let tolerance_dph = o.opt_f64("tolerance_dph")?;
    let (fast_rate_c_per_min, settled_every) =
        (o.f64("fast_rate", 0.05)?, o.int("settled_every", 3, 0, u64::MAX)?);
    let thinning = match o.string("thinning", "greedy")?.as_str() {
        "greedy" => match tolerance_dph {
            Some(tolerance_dph) => {
                Thinning::Greedy(GreedyThinning { tolerance_dph, max_nodes, ..GreedyThinning::default() })
            }
            None => Thinning::GreedyAuto { noise_multiple: 1.5, max_nodes },
        },
        "paper" => Thinning::Paper { fast_rate_c_per_min, settled_every },
        other => return Err(errors::value(format!("thinning must be 'greedy' or 'paper', got '{other}'"))),
    };
    let max_degree = o.int("max_degree", 4, 0, u64::from(u8::MAX))?;
    let (p_enter, p_remove) = (o.f64("p_enter", 0.05)?, o.f64("p_remove", 0.10)?);
    let poly = match o.string("poly", "stepwise")?.as_str() {
        "stepwise" => TermSelection::Stepwise { max_degree, p_enter, p_remove },
        "paper" => TermSelection::Paper,
        other => return Err(errors::value(format!("poly must be 'stepwise' or 'paper', got '{other}'"))),
    };
    let poly_outside = match o.string("poly_outside", "linear_from_boundary")?.as_str() {
        "extrapolate" => fogtemp_core::PolyOutside::Extrapolate,
        "hold_at_boundary" | "hold" => fogtemp_core::PolyOutside::HoldAtBoundary,
        "linear_from_boundary" | "linear" => fogtemp_core::PolyOutside::LinearFromBoundary,
        other => {
            return Err(errors::value(format!(
            "poly_outside must be 'extrapolate', 'hold_at_boundary' or 'linear_from_boundary', got '{other}'"
        )))
        }
    };
    let mesh_outside = match o.string("mesh_outside", mesh_outside_name(base.mesh_outside))?.as_str() {
        "hold" | "nearest_hull" => fogtemp_core::OutsidePolicy::NearestHull,
        "linear_from_boundary" | "linear" => fogtemp_core::OutsidePolicy::LinearFromBoundary,
        "linear_stored_gradients" => fogtemp_core::OutsidePolicy::StoredGradients,
        other => {
            return Err(errors::value(format!(
            "mesh_outside must be 'hold', 'linear_from_boundary' or 'linear_stored_gradients', got '{other}'"
        )))
        }
    };
    let config = CalibrationConfig {
        features,
        target_window_s,
        poly_outside,
        mesh_outside,
        thinning,
        poly,
        full_windows_only: o.bool("full_windows_only", false)?,
        least_squares_nodes: !o.bool("interpolate_nodes", false)?,
        refine_mesh: o.bool("refine_mesh", base.refine_mesh)?,
        ..base
    };
    check_calibration(&config, tolerance_dph)?;
    Ok(config)
}

/// Bias-stability keywords (the command line's `validate` flags), with its defaults.
pub fn stability(o: &mut Options<'_>) -> PyResult<BiasStabilityOptions> {
    let d = BiasStabilityOptions::default();
    let tau_s = o.f64("tau_s", d.tau_s)?;
    if !tau_s.is_finite() || tau_s <= 0.0 {
        return Err(errors::value("tau_s must be positive"));
    }
    let exclude_first_s = o.f64("exclude_first_s", d.exclude_first_s)?;
    if !exclude_first_s.is_finite() || exclude_first_s < 0.0 {
        return Err(errors::value("exclude_first_s must be zero or positive"));
    }
    Ok(BiasStabilityOptions {
        tau_s,
        overlapping: o.bool("overlapping", d.overlapping)?,
        detrend: o.bool("detrend", d.detrend)?,
        exclude_first_s,
    })
}

/// Refuses settings whose feature tracker needs more blocks than the firmware's `capacity`
/// (the command line's check and message, in keyword form).
///
/// # Errors
/// `ValueError` naming `capacity`.
pub fn capacity_fits(needed: usize, capacity: usize) -> PyResult<()> {
    require("capacity", capacity as u64 >= MIN_CAPACITY, "at least 2 (blocks)", capacity)?;
    if needed > capacity {
        return Err(errors::value(format!(
            "the model's feature tracker needs {needed} blocks but the firmware's capacity is {capacity} \
             (capacity=): fit with blocks={capacity} or fewer, or build the firmware's Compensator with \
             capacity {needed} and pass capacity={needed}"
        )));
    }
    Ok(())
}

/// The Python name of a mesh outside policy (the default of `mesh_outside`).
fn mesh_outside_name(policy: fogtemp_core::OutsidePolicy) -> &'static str {
    match policy {
        fogtemp_core::OutsidePolicy::LinearFromBoundary => "linear_from_boundary",
        fogtemp_core::OutsidePolicy::StoredGradients => "linear_stored_gradients",
        fogtemp_core::OutsidePolicy::NearestHull | fogtemp_core::OutsidePolicy::Zero => "hold",
    }
}
