//! Identifiability warnings: what the calibration points cannot tell apart or do not cover,
//! computed from the points themselves before any model is chosen.
//!
//! Each warning has a stable `kind` (snake_case, a JSON contract: docs/architecture.md,
//! Contracts), a message for the technician, and the numbers behind it. The thresholds and
//! why:
//!
//! - `temperature_rate_confounded`: dT/dt regressed on a cubic in T (the terms of the
//!   `cubic-t` model, on T normalised to [-1, 1]) explains R^2 of it; the variance inflation
//!   factor VIF = 1 / (1 - R^2) says how much the variance of a rate coefficient grows
//!   because T already explains the rate. Warn above [`MAX_VIF`] = 10 (R^2 > 0.9), the
//!   usual multicollinearity limit (Kutner, Nachtsheim, Neter, *Applied Linear Regression
//!   Models*, 4th ed., section 10.5; Marquardt 1970): the rate coefficient's standard error
//!   is then more than 3.2 times what an orthogonal design gives, and a rate effect can be
//!   taken up by the T terms (one warm-up run has dT/dt = (T_end - T) / tau exactly, so
//!   R^2 = 1: docs/physics.md, Identifiability). The docs' concealment index (R^2 > 0.99:
//!   "not identifiable") is the stricter limit; this one warns earlier.
//! - `too_few_runs`: fewer than [`MIN_RUNS`] = 3 runs with points. Run-to-run (turn-on)
//!   differences are the error a calibration must average out, and leave-one-run-out
//!   cross-validation needs at least 3 runs so that every fit still sees 2 runs and the
//!   spread over folds has a degree of freedom beyond one difference.
//! - `narrow_temperature_range`: when the temperature range the model will be used over is
//!   known, any part of it outside the calibrated range (that of the region's points,
//!   [`crate::calibrate::CalibrationPoints::region_points`], as the model stores it; there a
//!   polynomial, by default, continues linearly from its boundary and a mesh from its hull). Otherwise a
//!   calibrated span below [`MIN_TEMP_SPAN_C`] = 20 C: one power-on's self-heating alone spans 5-20 C
//!   (docs/physics.md, ranges), so a narrower calibration has not varied the ambient
//!   temperature and cannot tell the temperature's effect from the warm-up's.
//! - `heating_only` / `cooling_only`: the 99th percentile of dT/dt at or above
//!   [`MOVING_RATE_C_PER_MIN`] and the 1st percentile not at or below minus it (or the
//!   reverse). 0.05 C/min is the paper's limit between a changing and a settled
//!   temperature (its thinning keeps every point above it; `fit --fast-rate`). A rate
//!   effect (Shupe) is odd in dT/dt, and heating/cooling hysteresis needs both signs
//!   (docs/physics.md, table row 8). With no point of the missing sign beyond the limit,
//!   that sign lies outside the calibrated region; with a few (under 1 %), the text says
//!   "mostly" and counts them. Power-on runs never cool, so power-on-only calibrations get
//!   `heating_only`.
//! - `run_offsets` (after the fit, [`run_offsets`]): the runs' mean residuals differ by more
//!   than [`OFFSET_NOISE_MULTIPLE`] = 20 times the targets' noise and these per-run constants
//!   hold most (over half) of the residual's variance: the model cannot follow a constant
//!   that changes from run to run, such as logs from different positions (the Earth rate's
//!   projection differs by up to 2 x 15 deg/h) or a turn-on bias that is not repeatable. A
//!   run's mean residual otherwise scatters by the slow noise of one run, a few noise units
//!   (measured in docs/calibration-logs.md, "Runs that differ by a constant").
//! - `temperature_spikes`: glitched temperature readings, one or several that jump by more
//!   than [`crate::spikes::SPIKE_JUMP_C`] = 1 C from the readings around them and back, or a
//!   run's first readings (a sensor glitch; the rule and its reasoning are in
//!   [`crate::spikes`]).
//!   Calibration read them as missing; the warning names each by file and line.
//! - `implausible_temperatures`: every calibration temperature above 150 C, beyond any
//!   gyro's operating range: kelvin read as deg C, or raw counts.
//! - `implausible_rates`: half the calibration points change temperature faster than 3 x the
//!   peak case rate of docs/physics.md (2.01 C/min): a time column in minutes or hours read
//!   as seconds.
//! - `implausible_gyro`: every gyro mean of the calibration logs as read (before any input
//!   rate is taken off) within [`IMPLAUSIBLE_GYRO_DPH`] of zero, below any FOG's: a gyro
//!   logged in rad/s or deg/s read as deg/h.
//! - `gyro_outliers`: feature points whose gyro mean lay beyond 10 robust standard
//!   deviations of the median of the points around them ([`crate::outliers`]: a corrupted
//!   sample, an overload code). Calibration read them as missing; the warning names each by
//!   file and time.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::calibrate::{
    calibration_points_of, CalibrationConfig, CalibrationPoints, RunFeatures, TemperatureSteps,
};

/// Largest variance inflation factor of dT/dt over the cubic-in-T terms before
/// `temperature_rate_confounded` (see the module documentation).
pub const MAX_VIF: f64 = 10.0;
/// Spread of the runs' mean residuals, in units of the targets' noise, from which
/// `run_offsets` warns (with those means holding over half of the residual's variance).
pub const OFFSET_NOISE_MULTIPLE: f64 = 20.0;
/// Fewest runs before `too_few_runs`.
pub const MIN_RUNS: usize = 3;
/// Narrowest calibrated temperature span, deg C, when the operating range is unknown.
pub const MIN_TEMP_SPAN_C: f64 = 20.0;
/// |dT/dt| from which the temperature is changing, deg C/min (the paper's fast-rate limit).
pub const MOVING_RATE_C_PER_MIN: f64 = 0.05;

/// What the warnings are checked against.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IdentifiabilitySettings {
    /// The temperature range the model will be used over (min, max), deg C, when known.
    pub operating_temp_c: Option<(f64, f64)>,
}

/// Which warning.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WarningKind {
    /// T and dT/dt move together: a rate effect cannot be told from a temperature effect.
    TemperatureRateConfounded,
    /// Too few runs to average out run-to-run differences or to cross-validate.
    TooFewRuns,
    /// The calibrated temperatures do not cover the range the model is used over.
    NarrowTemperatureRange,
    /// No cooling in the calibration.
    HeatingOnly,
    /// No heating in the calibration.
    CoolingOnly,
    /// The runs differ by constants the model cannot follow (after the fit).
    RunOffsets,
    /// Runs that never fill the feature window (shorter than it): their features come
    /// from partial windows only.
    ShortRuns,
    /// Single temperature readings far from both neighbours (sensor glitches), read as
    /// missing ([`crate::spikes`]).
    TemperatureSpikes,
    /// Feature points whose gyro mean lay beyond 10 robust standard deviations of the points
    /// around it (a spike in the log), read as missing ([`crate::calibrate::screen_gyro_means`]).
    GyroOutliers,
    /// Every calibration temperature above [`IMPLAUSIBLE_TEMP_C`] (kelvin read as deg C?).
    ImplausibleTemperatures,
    /// Half the calibration points change temperature faster than a gyro's case can follow
    /// ([`IMPLAUSIBLE_RATE_C_PER_MIN`]): a time column in another unit (minutes read as seconds?).
    ImplausibleRates,
    /// Logs that continue one another in time ([`crate::continued`]): one run split over
    /// files, read as several runs. Reported on axis 0.
    ContinuedLogs,
    /// Every gyro mean of the calibration logs as read within [`IMPLAUSIBLE_GYRO_DPH`] of zero:
    /// a gyro in rad/s or deg/s read as deg/h (review32a F2).
    ImplausibleGyro,
    /// A run's temperature changes only in steps of [`COARSE_TEMPERATURE_STEP_C`] or more (a
    /// coarse sensor, or decimals cut off): dT/dt is a staircase's.
    CoarseTemperature,
    /// No calibration point over more than [`TEMPERATURE_GAP_C`] inside the calibrated
    /// temperature range (plateau runs far apart): the model is interpolated there.
    TemperatureGap,
    /// Logs from a folder where a simulation did not finish
    /// ([`crate::manifest::UNFINISHED_FILE`]): a part of its campaign at most. Reported on
    /// axis 0 (review30b F7: only stderr said so).
    UnfinishedSimulation,
    /// No run metadata (no runs file, no simulation manifest): the rate each run's gyro
    /// sensed (the Earth rate's share, a turntable's rate) stays in the calibration targets,
    /// so the model's bias holds their mean. Reported on axis 0 (review33b F1).
    NoRunMetadata,
    /// Runs that gave no calibration point at all (too short for the feature tracker, or
    /// without temperature readings): they calibrate nothing (review33b F8).
    RunsWithoutPoints,
}

impl WarningKind {
    /// The stable name (as in JSON).
    pub fn name(self) -> &'static str {
        match self {
            WarningKind::TemperatureRateConfounded => "temperature_rate_confounded",
            WarningKind::TooFewRuns => "too_few_runs",
            WarningKind::NarrowTemperatureRange => "narrow_temperature_range",
            WarningKind::HeatingOnly => "heating_only",
            WarningKind::CoolingOnly => "cooling_only",
            WarningKind::RunOffsets => "run_offsets",
            WarningKind::ShortRuns => "short_runs",
            WarningKind::TemperatureSpikes => "temperature_spikes",
            WarningKind::GyroOutliers => "gyro_outliers",
            WarningKind::ImplausibleTemperatures => "implausible_temperatures",
            WarningKind::ImplausibleRates => "implausible_rates",
            WarningKind::ContinuedLogs => "continued_logs",
            WarningKind::ImplausibleGyro => "implausible_gyro",
            WarningKind::CoarseTemperature => "coarse_temperature",
            WarningKind::TemperatureGap => "temperature_gap",
            WarningKind::UnfinishedSimulation => "unfinished_simulation",
            WarningKind::NoRunMetadata => "no_run_metadata",
            WarningKind::RunsWithoutPoints => "runs_without_points",
        }
    }
}

/// One warning: which axis, what, and the numbers behind it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Warning {
    /// Gyro axis.
    pub axis: usize,
    /// Which warning.
    pub kind: WarningKind,
    /// For the technician: what was found, why it matters, what experiment would help.
    pub message: String,
    /// The numbers behind it, by name (thresholds included).
    pub values: BTreeMap<&'static str, f64>,
    /// The logs it names, in its order (`continued_logs`; empty, and absent from the JSON,
    /// for the others), so a script need not parse the message (review13 F13).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub logs: Vec<String>,
}

impl Warning {
    fn new(axis: usize, kind: WarningKind, message: String, values: &[(&'static str, f64)]) -> Self {
        Self { axis, kind, message, values: values.iter().copied().collect(), logs: Vec::new() }
    }

    /// `unfinished_simulation`, from the run metadata's warning `message`
    /// ([`crate::runs::LogsMetadata::warnings`]), for `fit --json` and Python's `fit_report`.
    pub fn unfinished_simulation(message: String) -> Self {
        Self::new(0, WarningKind::UnfinishedSimulation, message, &[])
    }

    /// `no_run_metadata`, for a fit without run metadata; `remedy` says how to give it (the
    /// command line's `--runs FILE`, Python's `runs=`, or for arrays taking the rates off).
    pub fn no_run_metadata(remedy: &str) -> Self {
        let message = format!(
            "no run metadata: whatever constant rate the gyro sensed in each calibration run stays in the model's \
             bias (the Earth rate's share about the input axis, up to {EARTH_RATE_DPH} deg/h, or a turntable's \
             rate), averaged over the runs; the model then takes that mean off every sample, so a run at another \
             position or rate is compensated wrongly by the difference, which bias stability does not show. \
             {remedy}; logs whose gyro has the rate taken off already need nothing"
        );
        Self::new(0, WarningKind::NoRunMetadata, message, &[("earth_rate_dph", EARTH_RATE_DPH)])
    }
}

/// The Earth's rotation rate, deg/h (360 deg per sidereal day, 86,164.1 s).
pub const EARTH_RATE_DPH: f64 = 15.041;

/// The warnings of every axis, from the calibration points `fit` uses (the same selection as
/// [`crate::calibrate::fit_model`]).
pub fn fit_warnings(
    runs: &[RunFeatures],
    config: &CalibrationConfig,
    settings: &IdentifiabilitySettings,
) -> Vec<Warning> {
    (0..config.ingest.format.gyro_columns.len())
        .flat_map(|axis| {
            let points = calibration_points_of(runs, axis, config);
            let mut found = warnings(&points, axis, settings);
            found.extend(short_runs(runs, axis, f64::from(config.features.window_s)));
            found.extend(runs_without_points(runs, axis, config));
            let temp_columns = &config.ingest.format.temp_columns;
            let column = temp_columns.get(axis.min(temp_columns.len().saturating_sub(1)));
            found.extend(temperature_spikes(runs, axis, column.map_or("temperature", String::as_str)));
            found.extend(gyro_outliers(runs, axis));
            found.extend(implausible_gyro(runs, axis));
            found.extend(coarse_temperature(runs, axis, f64::from(config.features.window_s)));
            found
        })
        .chain(continued_logs(runs, f64::from(config.features.max_gap_s)))
        .collect()
}

/// `continued_logs`: one warning per chain of logs that continue one another, and one for
/// those that cannot be paired (review12
/// finding 2: a run in three files calibrated and validated as three runs, without a word).
fn continued_logs(runs: &[RunFeatures], max_gap_s: f64) -> Vec<Warning> {
    crate::continued::continued_logs(runs.iter().map(|r| &r.ingest), max_gap_s)
        .into_iter()
        .map(|found| {
            let (named, largest_step_s) = match &found {
                crate::continued::Continued::Chain { parts, largest_step_s, .. } => {
                    (parts.clone(), *largest_step_s)
                }
                crate::continued::Continued::Unpaired { later, earlier, largest_step_s } => {
                    (earlier.iter().chain(later).cloned().collect(), *largest_step_s)
                }
            };
            let values =
                [("logs", named.len() as f64), ("largest_step_s", largest_step_s), ("max_gap_s", max_gap_s)];
            let mut warning = Warning::new(0, WarningKind::ContinuedLogs, found.message(), &values);
            warning.logs = named.iter().map(|p| p.display().to_string()).collect();
            warning
        })
        .collect()
}

/// `short_runs` for axis `axis`: the runs with feature points none of which has a full
/// window (a log shorter than the `window_s` feature window). Their T and dT/dt come from
/// partial windows only, and a target smoothed over the whole short log fits any model,
/// so a fit of such runs alone shows a residual near 0 that says nothing.
fn short_runs(runs: &[RunFeatures], axis: usize, window_s: f64) -> Option<Warning> {
    let short: Vec<(String, f64)> = runs
        .iter()
        .filter_map(|run| {
            let (points, _) = run.axes.get(axis)?;
            let last = points.last()?;
            (!points.iter().any(|p| p.window_full)).then(|| (crate::runs::run_name(&run.path), last.time_s))
        })
        .collect();
    let (first, span_s) = short.first()?;
    let others = match short.len() {
        1 => String::new(),
        n => format!(" and {} more", n - 1),
    };
    Some(Warning::new(
        axis,
        WarningKind::ShortRuns,
        format!(
            "axis {axis}: {} of {} never fill the {window_s:.0} s feature window ({first}, features up to {span_s:.0} s{others}): \
             their T and dT/dt come from partial windows (from half a window after their first feature \
             on, their points count in the calibrated region) and a short log's smoothed target fits any model; \
             record runs of several windows, or choose a feature window (--window-s, Python window_s=) below the runs' length",
            short.len(),
            if runs.len() == 1 { "1 run".to_string() } else { format!("{} runs", runs.len()) }
        ),
        &[("short_runs", short.len() as f64), ("window_s", window_s)],
    ))
}

/// `runs_without_points` for axis `axis`: the runs (with rows) whose feature tracker never
/// gave a point, named with their rows and span; they calibrate nothing, so a run too short
/// for the tracker, or without temperature readings, is said rather than left out silently.
fn runs_without_points(runs: &[RunFeatures], axis: usize, config: &CalibrationConfig) -> Option<Warning> {
    let empty: Vec<String> = runs
        .iter()
        .filter(|run| run.axes.get(axis).is_some_and(|(points, _)| points.is_empty()))
        .map(|run| {
            format!(
                "{} ({} row{}, {:.0} s)",
                crate::runs::run_name(&run.path),
                run.ingest.rows,
                if run.ingest.rows == 1 { "" } else { "s" },
                run.ingest.last_time_s
            )
        })
        .collect();
    if empty.is_empty() {
        return None;
    }
    let features = &config.features;
    let ready_s = f64::from(features.min_blocks) * f64::from(features.window_s)
        / f64::from(features.block_count.max(1));
    Some(Warning::new(
        axis,
        WarningKind::RunsWithoutPoints,
        format!(
            "axis {axis}: {} of {} gave no calibration point and calibrate nothing: {}; the feature tracker needs \
             {ready_s:.0} s of temperature readings without a gap longer than {:.0} s before its first point",
            empty.len(),
            if runs.len() == 1 { "1 run".to_string() } else { format!("{} runs", runs.len()) },
            empty.join(", "),
            features.max_gap_s
        ),
        &[("runs_without_points", empty.len() as f64), ("ready_s", ready_s)],
    ))
}

/// How many spikes `temperature_spikes` names by line.
const NAMED_SPIKES: usize = 5;

/// `temperature_spikes` for axis `axis`: the temperature glitches calibration read as
/// missing, the first [`NAMED_SPIKES`] by file and line (`column` names the temperature
/// column).
fn temperature_spikes(runs: &[RunFeatures], axis: usize, column: &str) -> Option<Warning> {
    let per_run: Vec<(&RunFeatures, &crate::spikes::AxisSpikes)> = runs
        .iter()
        .filter_map(|run| Some((run, run.temperature_spikes.get(axis)?)))
        .filter(|(_, spikes)| spikes.count > 0)
        .collect();
    let total: u64 = per_run.iter().map(|(_, s)| s.count).sum();
    if total == 0 {
        return None;
    }
    let named: Vec<String> = per_run
        .iter()
        .flat_map(|(run, spikes)| spikes.first.iter().map(move |s| (run, s)))
        .take(NAMED_SPIKES)
        .map(|(run, s)| s.describe(&run.path, Some(column)))
        .collect();
    let more = total.saturating_sub(named.len() as u64);
    let more = if more > 0 { format!("; and {more} more") } else { String::new() };
    let glitches =
        if total == 1 { "1 temperature glitch".to_string() } else { format!("{total} temperature glitches") };
    let runs_text = if per_run.len() == 1 { "1 run".to_string() } else { format!("{} runs", per_run.len()) };
    Some(Warning::new(
        axis,
        WarningKind::TemperatureSpikes,
        format!(
            "axis {axis}: {glitches} in {runs_text} ({}{more}): readings that jump by more than {:.0} C \
             (more where readings are far apart) from the readings around them and back: \
             read as missing, so they neither set features nor widen the calibrated region; \
             a gyro's temperature does not move like that, so check the sensor or the logger",
            named.join(", "),
            crate::spikes::SPIKE_JUMP_C,
        ),
        &[("temperature_spikes", total as f64), ("spike_jump_c", crate::spikes::SPIKE_JUMP_C)],
    ))
}

/// The smallest temperature step, deg C, below which a run's readings count as resolved: a
/// run whose temperature changes (at least [`COARSE_MIN_CHANGES`] times) only in steps this
/// large or larger gets the `coarse_temperature` warning. Half a degree: an LM75's
/// resolution; common sensors read 0.0625 C (DS18B20, TMP117 0.0078 C) or finer.
pub const COARSE_TEMPERATURE_STEP_C: f64 = 0.5;

/// Changes a run's temperature must make before its steps say anything of its resolution.
pub const COARSE_MIN_CHANGES: u64 = 3;

/// Readings per change, on average, from which large steps are a staircase: a sensor of
/// coarse resolution holds each value over several readings; a fine one read seldom on a
/// ramp (once a minute at 0.8 C/min) changes at every reading by as much, which says nothing
/// of its resolution (review25a 10). Two: a staircase repeats each value at least once.
pub const COARSE_READINGS_PER_STEP: u64 = 2;

/// `coarse_temperature` for axis `axis`: the runs whose temperature changes only in steps of
/// [`COARSE_TEMPERATURE_STEP_C`] or more. A tracker window of `window_s` sees such a
/// staircase change at most once per step, so rates below step / window are not resolved
/// (review24a F5: a decimal comma inside a comma-separated log read 32,04466 C as 32 C).
fn coarse_temperature(runs: &[RunFeatures], axis: usize, window_s: f64) -> Option<Warning> {
    let coarse: Vec<(String, TemperatureSteps)> = runs
        .iter()
        .filter_map(|run| Some((crate::runs::run_name(&run.path), *run.temperature_steps.get(axis)?)))
        .filter(|(_, steps)| {
            steps.changes >= COARSE_MIN_CHANGES
                && steps.smallest_c >= COARSE_TEMPERATURE_STEP_C
                && steps.readings >= COARSE_READINGS_PER_STEP * steps.changes
        })
        .collect();
    let (first, steps) = coarse.first()?;
    let smallest_c = coarse.iter().map(|(_, s)| s.smallest_c).fold(f64::INFINITY, f64::min);
    let resolved_c_per_min = smallest_c / window_s * 60.0;
    let others = match coarse.len() {
        1 => String::new(),
        n => format!(" and {} more", n - 1),
    };
    Some(Warning::new(
        axis,
        WarningKind::CoarseTemperature,
        format!(
            "axis {axis}: the temperature changes only in steps of {smallest_c:.2} C or more in {} of {} ({first}: {} \
             changes, none smaller{others}): dT/dt over the {window_s:.0} s feature window is a staircase's, rates \
             below {resolved_c_per_min:.2} C/min are not resolved; a sensor of that resolution, a slow sensor's \
             reading repeated on every row until the next, or decimals cut off \
             (a decimal comma inside a comma-separated log reads 32,04 as 32 and a column of 04: convert such a log \
             to semicolons first)",
            coarse.len(),
            if runs.len() == 1 { "1 run".to_string() } else { format!("{} runs", runs.len()) },
            steps.changes,
        ),
        &[
            ("coarse_runs", coarse.len() as f64),
            ("smallest_step_c", smallest_c),
            ("step_limit_c", COARSE_TEMPERATURE_STEP_C),
            ("resolved_rate_c_per_min", resolved_c_per_min),
        ],
    ))
}

/// `gyro_outliers` for axis `axis`: the feature points whose gyro mean calibration read as
/// missing as an outlier, the first [`NAMED_SPIKES`] by file and time.
fn gyro_outliers(runs: &[RunFeatures], axis: usize) -> Option<Warning> {
    let per_run: Vec<(&RunFeatures, &Vec<crate::calibrate::GyroOutlier>)> = runs
        .iter()
        .filter_map(|run| Some((run, run.gyro_outliers.get(axis)?)))
        .filter(|(_, found)| !found.is_empty())
        .collect();
    let total: usize = per_run.iter().map(|(_, found)| found.len()).sum();
    if total == 0 {
        return None;
    }
    let named: Vec<String> = per_run
        .iter()
        .flat_map(|(run, found)| found.iter().map(move |o| (run, o)))
        .take(NAMED_SPIKES)
        .map(|(run, o)| {
            let (deviation, sds) = crate::outliers::deviation_text(o.deviation_dph, o.robust_sd_dph);
            format!(
                "{} at {} s after its first row ({deviation} deg/h from the points around it, {sds} robust SD)",
                run.path.display(),
                o.time_s,
            )
        })
        .collect();
    let more = total - named.len();
    let more = if more > 0 { format!("; and {more} more") } else { String::new() };
    let means = if total == 1 { "1 gyro mean".to_string() } else { format!("{total} gyro means") };
    let runs_text = if per_run.len() == 1 { "1 run".to_string() } else { format!("{} runs", per_run.len()) };
    Some(Warning::new(
        axis,
        WarningKind::GyroOutliers,
        format!(
            "axis {axis}: {means} of the feature points in {runs_text} lay beyond {:.0} robust standard deviations of \
             the median of the points around them ({}{more}): read as missing, so no target is smoothed over them; \
             a gyro's bias does not jump like that, so check those rows of the logs (a corrupted sample, an overload \
             code, a shock)",
            crate::outliers::ROBUST_SDS,
            named.join(", "),
        ),
        &[("gyro_outliers", total as f64), ("robust_sds", crate::outliers::ROBUST_SDS)],
    ))
}

/// `run_offsets` for axis `axis` of a fitted model (`None` when the runs agree, or with
/// fewer than two runs or no noise estimate): the residual `target - model` at every
/// feature point with a finite target, its mean per run, and how much of the residual's
/// variance those means hold (see the module documentation).
pub fn run_offsets(
    runs: &[RunFeatures],
    model: &fogtemp_core::Model<'_>,
    axis: usize,
    target_noise_dph: f64,
) -> Option<Warning> {
    if !(target_noise_dph.is_finite() && target_noise_dph > 0.0) {
        return None;
    }
    let (per_run, share) = per_run_residual_means(runs, model, axis)?;
    let lowest = per_run.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
    let highest = per_run.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    let spread = highest.1 - lowest.1;
    if spread <= OFFSET_NOISE_MULTIPLE * target_noise_dph || share <= 0.5 {
        return None;
    }
    let mut warning = run_offsets_warning(axis, (lowest, highest), target_noise_dph, share);
    if let Some(follows) = offsets_follow_temperature(&per_run) {
        warning.message.push_str(&follows);
    }
    Some(warning)
}

/// How closely the runs' mean residuals must follow their mean temperatures (|Pearson r|)
/// for the `run_offsets` warning to name a temperature effect as a cause.
const OFFSETS_FOLLOW_TEMPERATURE_R: f64 = 0.9;

/// The clause `run_offsets` adds when the runs' mean residuals follow their mean
/// temperatures (|r| >= [`OFFSETS_FOLLOW_TEMPERATURE_R`] over runs whose mean temperatures
/// differ): a temperature effect the fit did not take up (review24a F2: two plateau runs 35 C
/// apart, a constant model, and a warning that named only positions and turn-on biases). With
/// two runs r is +-1 whenever their temperatures differ, so the clause says it cannot tell.
fn offsets_follow_temperature(per_run: &[RunMean]) -> Option<String> {
    let n = per_run.len() as f64;
    let mean = |f: &dyn Fn(&RunMean) -> f64| per_run.iter().map(f).sum::<f64>() / n;
    let (residual, temp) = (mean(&|r| r.1), mean(&|r| r.3));
    let covariance = per_run.iter().map(|r| (r.1 - residual) * (r.3 - temp)).sum::<f64>();
    let var_residual = per_run.iter().map(|r| (r.1 - residual).powi(2)).sum::<f64>();
    let var_temp = per_run.iter().map(|r| (r.3 - temp).powi(2)).sum::<f64>();
    let r = covariance / (var_residual * var_temp).sqrt();
    let coldest = per_run.iter().min_by(|a, b| a.3.total_cmp(&b.3))?;
    let hottest = per_run.iter().max_by(|a, b| a.3.total_cmp(&b.3))?;
    if r.is_nan() || r.abs() < OFFSETS_FOLLOW_TEMPERATURE_R {
        return None;
    }
    let evidence = if per_run.len() == 2 {
        "two runs cannot tell a temperature effect from a run offset".to_string()
    } else {
        format!("r = {r:+.2} over {} runs", per_run.len())
    };
    Some(format!(
        "; the offsets follow the runs' mean temperatures ({} at {:.1} C, {} at {:.1} C; {evidence}): if it is \
         the temperature, the fit did not take it up (too few independent points for its term tests?); record \
         runs at more temperatures",
        coldest.0, coldest.3, hottest.0, hottest.3
    ))
}

/// The warnings that need the fitted model (`run_offsets`), for every axis of `fitted`.
pub fn post_fit_warnings(runs: &[RunFeatures], fitted: &crate::calibrate::FittedModel) -> Vec<Warning> {
    let Ok(model) = fogtemp_core::Model::from_bytes(&fitted.blob) else { return Vec::new() };
    fitted
        .axes
        .iter()
        .enumerate()
        .filter_map(|(axis, report)| run_offsets(runs, &model, axis, report.target_noise_dph))
        .collect()
}

/// The spread of the runs' mean residuals in units of `target_noise_dph` and the share of
/// the residual's variance they hold, for axis `axis` (what [`run_offsets`] compares with
/// its limits); `None` as there.
pub fn run_offset_statistics(
    runs: &[RunFeatures],
    model: &fogtemp_core::Model<'_>,
    axis: usize,
    target_noise_dph: f64,
) -> Option<(f64, f64)> {
    let (per_run, share) = per_run_residual_means(runs, model, axis)?;
    let lowest = per_run.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
    let highest = per_run.iter().map(|r| r.1).fold(f64::NEG_INFINITY, f64::max);
    (target_noise_dph.is_finite() && target_noise_dph > 0.0)
        .then(|| ((highest - lowest) / target_noise_dph, share))
}

fn run_offsets_warning(
    axis: usize,
    (lowest, highest): (&RunMean, &RunMean),
    target_noise_dph: f64,
    share: f64,
) -> Warning {
    let spread = highest.1 - lowest.1;
    Warning::new(
        axis,
        WarningKind::RunOffsets,
        format!(
            "axis {axis}: the runs differ by constants the model cannot follow: their mean residuals range from \
             {:+.4} deg/h ({}) to {:+.4} deg/h ({}), {:.0} times the targets' noise of {target_noise_dph:.4} deg/h, \
             and hold {:.0} % of the residual's variance; logs from different positions or input rates (a runs \
             file gives each run's input_rate_dph, which `fit --runs` subtracts), or a turn-on bias that changes \
             from run to run",
            lowest.1,
            lowest.0,
            highest.1,
            highest.0,
            spread / target_noise_dph,
            100.0 * share
        ),
        &[
            ("spread_dph", spread),
            ("target_noise_dph", target_noise_dph),
            ("share_of_variance", share),
            ("noise_multiple", OFFSET_NOISE_MULTIPLE),
        ],
    )
}

/// One run's mean residual: (run name, mean `target - model` in deg/h, points, mean
/// temperature of those points in deg C).
type RunMean = (String, f64, usize, f64);

/// Per run, its [`RunMean`] on axis `axis`, and the share of the residual's variance the
/// run means hold; `None` with fewer than two runs.
fn per_run_residual_means(
    runs: &[RunFeatures],
    model: &fogtemp_core::Model<'_>,
    axis: usize,
) -> Option<(Vec<RunMean>, f64)> {
    let fitted = model.axis(axis).ok()?;
    let mut hint = fogtemp_core::WalkHint::default();
    let mut per_run: Vec<RunMean> = Vec::new();
    let mut all: Vec<f64> = Vec::new();
    for run in runs {
        let Some((features, targets)) = run.axes.get(axis) else { continue };
        let (residuals, temps_c): (Vec<f64>, Vec<f64>) = features
            .iter()
            .zip(targets)
            .filter(|(_, t)| t.is_finite())
            .filter_map(|(f, t)| {
                let e = fitted.evaluate(f.temp_c as f32, f.rate_c_per_min as f32, &mut hint).ok()?;
                Some((t - f64::from(e.value_dph), f.temp_c))
            })
            .unzip();
        if !residuals.is_empty() {
            let count = residuals.len() as f64;
            let mean = residuals.iter().sum::<f64>() / count;
            let temp_c = temps_c.iter().sum::<f64>() / count;
            per_run.push((crate::runs::run_name(&run.path), mean, residuals.len(), temp_c));
            all.extend(residuals);
        }
    }
    if per_run.len() < 2 {
        return None;
    }
    let n = all.len() as f64;
    let grand = all.iter().sum::<f64>() / n;
    let total_var = all.iter().map(|r| (r - grand).powi(2)).sum::<f64>() / n;
    let between_var = per_run.iter().map(|(_, m, k, _)| *k as f64 * (m - grand).powi(2)).sum::<f64>() / n;
    let share = if total_var > 0.0 { between_var / total_var } else { 0.0 };
    Some((per_run, share))
}

/// The warnings for one axis's calibration points (none for an empty set: `fit` reports
/// that itself).
pub fn warnings(points: &CalibrationPoints, axis: usize, settings: &IdentifiabilitySettings) -> Vec<Warning> {
    if points.points.is_empty() {
        return Vec::new();
    }
    [
        confounding(points, axis),
        too_few_runs(points, axis),
        temperature_range(points, axis, settings),
        temperature_gap(points, axis),
        rate_signs(points, axis),
        implausible_temperatures(points, axis),
        implausible_rates(points, axis),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// Above this every calibration point's temperature lies beyond any gyro's operating range
/// (FOGs are specified to about +85 C; military parts to +125 C), deg C: kelvin read as
/// deg C (a room at 298 K), or raw counts.
pub const IMPLAUSIBLE_TEMP_C: f64 = 150.0;

/// `implausible_temperatures`: every calibration point above [`IMPLAUSIBLE_TEMP_C`] (review12
/// finding 5: kelvin logs without `--temp-offset` calibrated as 238..334 C, silently, and
/// firmware feeding deg C would be compensated wrongly everywhere).
fn implausible_temperatures(points: &CalibrationPoints, axis: usize) -> Option<Warning> {
    let (lo, hi) = points
        .points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p.temp_c), hi.max(p.temp_c)));
    (lo > IMPLAUSIBLE_TEMP_C).then(|| {
        Warning::new(
            axis,
            WarningKind::ImplausibleTemperatures,
            format!(
                "axis {axis}: every calibration temperature lies between {lo:.2} and {hi:.2} C, above any gyro's \
                 operating range (> {IMPLAUSIBLE_TEMP_C:.0} C): kelvin read as deg C? give --temp-offset -273.15 \
                 (Python temp_offset=); raw counts? --temp-scale; the model expects the temperatures the firmware \
                 will feed it"
            ),
            &[("temp_min_c", lo), ("temp_max_c", hi), ("implausible_temp_c", IMPLAUSIBLE_TEMP_C)],
        )
    })
}

/// Above this median |dT/dt| half the calibration points change temperature faster than a
/// gyro's case follows, deg C/min: the peak rate of docs/physics.md (0.67 C/min, the case;
/// the coil's is 0.30) times the margin the spike screen allows ([`crate::spikes`]). A time
/// column in minutes read as seconds makes every rate 60 times too large (review23b F1: 1.9
/// to 16 C/min from runs that heat at up to 0.5 C/min, fitted without a word).
pub const IMPLAUSIBLE_RATE_C_PER_MIN: f64 =
    crate::spikes::PHYSICS_MARGIN * crate::spikes::FASTEST_TEMP_RATE_C_PER_MIN;

/// `implausible_rates`: the median |dT/dt| of the calibration points above
/// [`IMPLAUSIBLE_RATE_C_PER_MIN`].
fn implausible_rates(points: &CalibrationPoints, axis: usize) -> Option<Warning> {
    let mut speeds: Vec<f64> = points.points.iter().map(|p| p.rate_c_per_min.abs()).collect();
    speeds.sort_by(f64::total_cmp);
    let median = *speeds.get(speeds.len() / 2)?;
    (median > IMPLAUSIBLE_RATE_C_PER_MIN).then(|| {
        Warning::new(
            axis,
            WarningKind::ImplausibleRates,
            format!(
                "axis {axis}: half the calibration points change temperature faster than {median:.2} C/min, beyond \
                 what a gyro's case follows (> {IMPLAUSIBLE_RATE_C_PER_MIN:.2} C/min): is the time column in \
                 another unit? minutes or hours read as seconds: give --time-unit min or h (Python time_unit=)"
            ),
            &[("median_abs_rate_c_per_min", median), ("implausible_rate_c_per_min", IMPLAUSIBLE_RATE_C_PER_MIN)],
        )
    })
}

/// Below this every smoothed gyro mean of the calibration logs lies closer to zero than any FOG's,
/// deg/h: a FOG ten times quieter than docs/physics.md's (angle random walk N = 5e-5 against
/// 5e-4 deg/sqrt(h)) scatters by 6 N = 3e-4 deg/h over a 100 s mean, so thousands of points
/// reach past 1e-3, and a gyro also reads its bias and the Earth rate's projection. A gyro in rad/s
/// read as deg/h is 206,265 times too small: a FOG reading under 20 deg/h is under 1e-4
/// rad/s (review32a F2: a model 206,265 times too small, exit 0, no word). Applied to the
/// features' gyro means as read (after `--gyro-unit`, before input rates are taken off).
pub const IMPLAUSIBLE_GYRO_DPH: f64 = 1e-4;

/// `implausible_gyro`: the largest |gyro mean| of the runs' features as read, before any input
/// rate was taken off (review32b F2: after it, an ideal gyro reading the Earth rate alone was
/// near zero, and a rad/s gyro beside a manifest's rates was not), below
/// [`IMPLAUSIBLE_GYRO_DPH`].
fn implausible_gyro(runs: &[RunFeatures], axis: usize) -> Option<Warning> {
    let as_read = runs.iter().flat_map(|run| {
        let taken_off = run.input_rate_subtracted_dph.get(axis).copied().unwrap_or(0.0);
        run.axes
            .get(axis)
            .into_iter()
            .flat_map(move |(features, _)| features.iter().map(move |f| (f.gyro_mean_dph + taken_off).abs()))
    });
    let largest = as_read.filter(|v| v.is_finite()).reduce(f64::max)?;
    (largest < IMPLAUSIBLE_GYRO_DPH).then(|| {
        Warning::new(
            axis,
            WarningKind::ImplausibleGyro,
            format!(
                "axis {axis}: every gyro mean of the calibration logs, as read, lies within {} deg/h of zero, below \
                 any FOG's (its noise alone scatters them by more than {IMPLAUSIBLE_GYRO_DPH:.0e}, and it reads its \
                 bias and the Earth rate): a gyro logged in rad/s or deg/s read as deg/h? give --gyro-unit rps or \
                 dps (Python gyro_unit=); the model is in the unit the gyro is read in",
                crate::numbers::dph(largest)
            ),
            &[("largest_abs_gyro_dph", largest), ("implausible_gyro_dph", IMPLAUSIBLE_GYRO_DPH)],
        )
    })
}

/// The widest stretch of temperature without a calibration point, inside the calibrated
/// range, beyond which `temperature_gap` warns, deg C: half the span of one power-on's
/// self-heating (up to 20 C, the narrow-range limit), so runs at chamber temperatures 10 C
/// apart never trip it, plateaus 35 C apart do (review24a F3).
pub const TEMPERATURE_GAP_C: f64 = 10.0;

/// `temperature_gap`: the widest gap between the sorted temperatures of the region's points.
fn temperature_gap(points: &CalibrationPoints, axis: usize) -> Option<Warning> {
    let mut temps: Vec<f64> =
        points.region_points().iter().map(|p| p.temp_c).filter(|t| t.is_finite()).collect();
    temps.sort_by(f64::total_cmp);
    let (lo, hi) =
        temps.windows(2).map(|w| (w[0], w[1])).max_by(|a, b| (a.1 - a.0).total_cmp(&(b.1 - b.0)))?;
    let gap_c = hi - lo;
    if gap_c <= TEMPERATURE_GAP_C {
        return None;
    }
    Some(Warning::new(
        axis,
        WarningKind::TemperatureGap,
        format!(
            "axis {axis}: no calibration point between {lo:.1} and {hi:.1} C ({gap_c:.1} C without data inside the \
             calibrated range): the model is interpolated there from the points on either side (a polynomial's \
             shape between two clusters is set by its terms, not by data), and the firmware does not flag those \
             temperatures; calibrate at temperatures in between"
        ),
        &[("gap_low_c", lo), ("gap_high_c", hi), ("gap_c", gap_c), ("max_gap_c", TEMPERATURE_GAP_C)],
    ))
}

/// `temperature_rate_confounded`, from the R^2 of dT/dt on {1, T, T^2, T^3}.
fn confounding(points: &CalibrationPoints, axis: usize) -> Option<Warning> {
    let temps: Vec<f64> = points.points.iter().map(|p| p.temp_c).collect();
    let rates: Vec<f64> = points.points.iter().map(|p| p.rate_c_per_min).collect();
    let r_squared = r_squared_on_cubic(&temps, &rates)?;
    let vif = 1.0 / (1.0 - r_squared).max(f64::MIN_POSITIVE);
    if vif <= MAX_VIF {
        return None;
    }
    let corr = correlation(&temps, &rates);
    Some(Warning::new(
        axis,
        WarningKind::TemperatureRateConfounded,
        format!(
            "axis {axis}: temperature and its rate are confounded: a cubic in T explains {:.1} % of the \
             variance of dT/dt (variance inflation factor {vif:.1} > {MAX_VIF}, corr(T, dT/dt) = {corr:.3}), so \
             a rate effect cannot be told from a temperature effect; add runs that reach the same \
             temperatures at other rates (power-on at several chamber temperatures, ramps at two rates, \
             cooling runs)",
            100.0 * r_squared
        ),
        &[
            ("r_squared_rate_on_cubic_t", r_squared),
            ("variance_inflation_factor", vif),
            ("max_variance_inflation_factor", MAX_VIF),
            ("corr_temp_rate", corr),
        ],
    ))
}

/// `too_few_runs`.
fn too_few_runs(points: &CalibrationPoints, axis: usize) -> Option<Warning> {
    let mut runs = points.run_of.clone();
    runs.sort_unstable();
    runs.dedup();
    if runs.len() >= MIN_RUNS {
        return None;
    }
    Some(Warning::new(
        axis,
        WarningKind::TooFewRuns,
        format!(
            "axis {axis}: only {} {} calibration points (at least {MIN_RUNS}): run-to-run \
             differences are not averaged out and cannot be cross-validated; record more power-on runs",
            runs.len(),
            if runs.len() == 1 { "run has" } else { "runs have" }
        ),
        &[("runs", runs.len() as f64), ("min_runs", MIN_RUNS as f64)],
    ))
}

/// `narrow_temperature_range`.
fn temperature_range(
    points: &CalibrationPoints,
    axis: usize,
    settings: &IdentifiabilitySettings,
) -> Option<Warning> {
    // The calibrated range, as the model stores it: that of the region's points.
    let (lo, hi) = min_max(points.region_points().iter().map(|p| p.temp_c));
    let span = hi - lo;
    match settings.operating_temp_c {
        Some((op_lo, op_hi)) => {
            let (below, above) = ((lo - op_lo).max(0.0), (op_hi - hi).max(0.0));
            if below + above <= 0.0 {
                return None;
            }
            Some(Warning::new(
                axis,
                WarningKind::NarrowTemperatureRange,
                format!(
                    "axis {axis}: the calibration covers {lo:.1} to {hi:.1} C but the model is used over \
                     {op_lo:.1} to {op_hi:.1} C: {below:.1} C below and {above:.1} C above are not calibrated \
                     (by default a polynomial continues linearly from its boundary and a mesh from its hull's nearest point); extend the chamber's range"
                ),
                &[
                    ("temp_min_c", lo),
                    ("temp_max_c", hi),
                    ("operating_temp_min_c", op_lo),
                    ("operating_temp_max_c", op_hi),
                    ("uncovered_c", below + above),
                ],
            ))
        }
        None if span < MIN_TEMP_SPAN_C => Some(Warning::new(
            axis,
            WarningKind::NarrowTemperatureRange,
            format!(
                "axis {axis}: the calibration spans only {span:.1} C ({lo:.1} to {hi:.1} C), less than \
                 {MIN_TEMP_SPAN_C} C (one power-on's self-heating alone spans up to 20 C): the temperature's \
                 effect is not separated from the warm-up's, and outside this range the model is \
                 extrapolated (by default a polynomial continues linearly from its boundary and a mesh from its \
                 hull's nearest point); calibrate at several chamber temperatures"
            ),
            &[
                ("temp_min_c", lo),
                ("temp_max_c", hi),
                ("temp_span_c", span),
                ("min_temp_span_c", MIN_TEMP_SPAN_C),
            ],
        )),
        None => None,
    }
}

/// `heating_only` / `cooling_only`, from the 1st and 99th percentiles of dT/dt.
///
/// The text says what the points show: with no point of the missing sign beyond
/// [`MOVING_RATE_C_PER_MIN`], that sign is outside the calibrated region; with a few (under
/// 1 %), the calibration "mostly" heats or cools and those few are counted. The region can hold
/// them, so "outside the calibrated region" would contradict `inspect` (review21 second
/// report F3: testbed seed 1's `static_shape` case cools to -0.11 C/min at its end).
fn rate_signs(points: &CalibrationPoints, axis: usize) -> Option<Warning> {
    let mut rates: Vec<f64> =
        points.points.iter().map(|p| p.rate_c_per_min).filter(|r| r.is_finite()).collect();
    if rates.is_empty() {
        return None;
    }
    rates.sort_unstable_by(f64::total_cmp);
    let (p01, p99) = (percentile(&rates, 0.01), percentile(&rates, 0.99));
    let heating = p99 >= MOVING_RATE_C_PER_MIN;
    let cooling = p01 <= -MOVING_RATE_C_PER_MIN;
    let (rate_min, rate_max) = (rates[0], rates[rates.len() - 1]);
    let (kind, what, missing, missing_verb, opposite, extreme) = match (heating, cooling) {
        (true, false) => {
            let opposite = rates.iter().filter(|&&r| r <= -MOVING_RATE_C_PER_MIN).count();
            (WarningKind::HeatingOnly, "heats", "cooling", "cool", opposite, rate_min)
        }
        (false, true) => {
            let opposite = rates.iter().filter(|&&r| r >= MOVING_RATE_C_PER_MIN).count();
            (WarningKind::CoolingOnly, "cools", "heating", "heat", opposite, rate_max)
        }
        _ => return None,
    };
    let outside_policy =
        "(by default a polynomial continues linearly from its boundary and a mesh from its hull's nearest point)";
    let span = format!("dT/dt of the fit's points from {rate_min:.3} to {rate_max:.3} C/min");
    let message = if opposite == 0 {
        format!(
            "axis {axis}: the calibration only {what}: no point {missing_verb}s faster than {MOVING_RATE_C_PER_MIN} \
             C/min ({span}, partial tracker windows included): {missing} rates are outside the calibrated region {outside_policy} and \
             heating/cooling hysteresis cannot be seen; add {missing} runs to the calibration"
        )
    } else {
        format!(
            "axis {axis}: the calibration mostly {what}: {opposite} of its {} points ({} %) {missing_verb} faster \
             than {MOVING_RATE_C_PER_MIN} C/min, to {extreme:.3} C/min at most ({span}, {p01:.3} to {p99:.3} at the \
             1st and 99th percentiles, partial tracker windows included): a rate effect's {missing} side and \
             heating/cooling hysteresis rest on those few points at most, and beyond the calibrated region \
             (`inspect` shows how far it reaches; it is drawn from full tracker windows only) the model is \
             extrapolated {outside_policy}; add {missing} runs to the calibration",
            rates.len(),
            crate::calibrate::share_percent(opposite as u64, rates.len() as u64)
        )
    };
    Some(Warning::new(
        axis,
        kind,
        message,
        &[
            ("rate_p01_c_per_min", p01),
            ("rate_p99_c_per_min", p99),
            ("rate_min_c_per_min", rate_min),
            ("rate_max_c_per_min", rate_max),
            ("opposite_sign_points", opposite as f64),
            ("moving_rate_c_per_min", MOVING_RATE_C_PER_MIN),
        ],
    ))
}

/// R^2 of `y` regressed on {1, u, u^2, u^3} with `u` the `x` mapped to [-1, 1]; `None` when
/// `y` does not vary or there are too few finite points (5) to say.
fn r_squared_on_cubic(x: &[f64], y: &[f64]) -> Option<f64> {
    let pairs: Vec<(f64, f64)> =
        x.iter().zip(y).filter(|(a, b)| a.is_finite() && b.is_finite()).map(|(&a, &b)| (a, b)).collect();
    if pairs.len() < 5 {
        return None;
    }
    let n = pairs.len() as f64;
    let mean_y = pairs.iter().map(|p| p.1).sum::<f64>() / n;
    let ss_total: f64 = pairs.iter().map(|p| (p.1 - mean_y).powi(2)).sum();
    if ss_total <= f64::EPSILON * mean_y.abs().max(1.0) * n {
        return None;
    }
    let (lo, hi) = min_max(pairs.iter().map(|p| p.0));
    let (mid, half) = ((lo + hi) / 2.0, ((hi - lo) / 2.0).max(f64::MIN_POSITIVE));
    let design = DMatrix::from_fn(pairs.len(), 4, |i, j| ((pairs[i].0 - mid) / half).powi(j as i32));
    let target = DVector::from_iterator(pairs.len(), pairs.iter().map(|p| p.1));
    // SVD least squares: a constant T makes the design rank one, which it handles.
    let svd = design.clone().svd(true, true);
    let coefficients = svd.solve(&target, 1e-12).ok()?;
    let residual = target - design * coefficients;
    Some((1.0 - residual.norm_squared() / ss_total).clamp(0.0, 1.0))
}

/// Pearson correlation (NaN when either does not vary).
fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len()) as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    sxy / (sxx * syy).sqrt()
}

fn min_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)))
}

/// Nearest-rank percentile of sorted values (`q` in [0, 1]).
fn percentile(sorted: &[f64], q: f64) -> f64 {
    let rank = (q * sorted.len() as f64).ceil().max(1.0) as usize;
    sorted[rank.min(sorted.len()) - 1]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshPoint;

    /// Two clusters 30 C apart leave a gap of 30 C (hand: 15 to 45 C), warned; clusters 8 C
    /// apart do not.
    #[test]
    fn a_gap_between_plateaus_is_warned_of() {
        let plateaus = |low_c: f64, high_c: f64| {
            let mut triples = Vec::new();
            for k in 0..50 {
                let wiggle = f64::from(k % 5) * 0.25;
                triples.push((0, low_c - wiggle, 0.01 * f64::from(k % 3)));
                triples.push((1, high_c + wiggle, -0.01 * f64::from(k % 3)));
            }
            points(&triples)
        };
        let w = temperature_gap(&plateaus(15.0, 45.0), 0).expect("a 30 C gap");
        assert_eq!((w.values["gap_low_c"], w.values["gap_high_c"], w.values["gap_c"]), (15.0, 45.0, 30.0));
        assert!(w.message.contains("no calibration point between 15.0 and 45.0 C"), "{}", w.message);
        assert_eq!(temperature_gap(&plateaus(20.0, 28.0), 0), None);
    }

    /// A ramp of 0.3 C/min for 3000 s at 1 Hz, its temperature rounded to `step_c`.
    fn ramp_in_steps(step_c: f64) -> RunFeatures {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..3000 {
            let temp_c = ((20.0 + 0.3 * f64::from(k) / 60.0) / step_c).round() * step_c;
            csv.push_str(&format!("{k},{temp_c:.4},{:.6}\n", 0.01 * temp_c));
        }
        let config = CalibrationConfig::default();
        crate::calibrate::extract_run_from(csv.as_bytes(), std::path::Path::new("ramp.csv"), &config)
            .expect("reads")
    }

    /// Whole degrees (15 changes over 15 C) are coarse; 0.0625 C steps are not. The staircase
    /// resolves rates down to 1 C / 100 s = 0.60 C/min. A run with fewer than three changes
    /// says nothing. Steps by hand: 20, 20, 21, 22.5, 22.5, 20 change 3 times, 1.0 the least.
    #[test]
    fn a_temperature_in_whole_degrees_is_warned_of() {
        let whole = ramp_in_steps(1.0);
        let w = coarse_temperature(std::slice::from_ref(&whole), 0, 100.0).expect("whole degrees");
        assert_eq!(w.kind.name(), "coarse_temperature");
        assert_eq!((w.values["smallest_step_c"], w.values["resolved_rate_c_per_min"]), (1.0, 0.6));
        assert!(
            w.message.contains("steps of 1.00 C or more in 1 of 1 run (ramp: 15 changes"),
            "{}",
            w.message
        );
        assert_eq!(coarse_temperature(&[ramp_in_steps(0.0625)], 0, 100.0), None);
        let mut steps = TemperatureSteps::default();
        for t in [20.0, 20.0, f64::NAN, 21.0, 22.5, 22.5, 20.0] {
            steps.observe(t);
        }
        assert_eq!((steps.smallest_c, steps.changes, steps.readings), (1.0, 3, 6));
        let mut two = whole.clone();
        two.temperature_steps[0].changes = 2;
        assert_eq!(coarse_temperature(&[two], 0, 100.0), None, "two changes say nothing");
    }

    /// A fine sensor read once a minute on a 0.8 C/min ramp changes by 0.8 C at every reading:
    /// large steps, but no staircase (review25a 10). Readings 3 decimals, 1 Hz gyro rows, the
    /// temperature cell empty in the other 59 of each 60.
    #[test]
    fn a_fine_temperature_read_seldom_is_no_staircase() {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..3600 {
            let temp = if k % 60 == 0 {
                format!("{:.3}", 20.0 + 0.8 * f64::from(k) / 60.0 + 0.0123)
            } else {
                String::new()
            };
            csv.push_str(&format!("{k},{temp},{:.6}\n", 0.001 * f64::from(k)));
        }
        let config = CalibrationConfig::default();
        let run =
            crate::calibrate::extract_run_from(csv.as_bytes(), std::path::Path::new("sparse.csv"), &config)
                .expect("reads");
        let steps = run.temperature_steps[0];
        assert_eq!((steps.readings, steps.changes), (60, 59));
        assert!((steps.smallest_c - 0.8).abs() < 1e-9, "{steps:?}");
        assert_eq!(coarse_temperature(&[run], 0, 600.0), None);
    }

    /// The run_offsets clause on temperature: Pearson r of the run means against their mean
    /// temperatures, by hand: residuals (-1, 0, 1) at (10, 20, 30) C give r = 1; at (10, 30,
    /// 20) C, r = 0.5 (covariance 10, variances 2 and 200); equal temperatures give no r.
    #[test]
    fn run_offsets_name_a_temperature_effect_when_the_offsets_follow_temperature() {
        let runs = |temps: &[f64]| -> Vec<RunMean> {
            temps.iter().enumerate().map(|(i, &t)| (format!("r{i}"), i as f64 - 1.0, 10, t)).collect()
        };
        let follows = offsets_follow_temperature(&runs(&[10.0, 20.0, 30.0])).expect("r = 1");
        assert!(
            follows.contains("r = +1.00 over 3 runs") && follows.contains("r0 at 10.0 C, r2 at 30.0 C"),
            "{follows}"
        );
        assert_eq!(offsets_follow_temperature(&runs(&[10.0, 30.0, 20.0])), None, "r = 0.5");
        assert_eq!(offsets_follow_temperature(&runs(&[20.0, 20.0, 20.0])), None, "no spread in temperature");
        let two = offsets_follow_temperature(&runs(&[13.0, 47.0])[..2]).expect("two runs");
        assert!(two.contains("two runs cannot tell"), "{two}");
    }

    /// Points from (run, temp, rate) triples (the targets do not matter here).
    fn points(triples: &[(usize, f64, f64)]) -> CalibrationPoints {
        CalibrationPoints {
            points: triples
                .iter()
                .map(|&(_, temp_c, rate_c_per_min)| MeshPoint { temp_c, rate_c_per_min, value_dph: 0.0 })
                .collect(),
            run_of: triples.iter().map(|t| t.0).collect(),
            block_equivalents: triples.len() as f64,
            in_region: vec![true; triples.len()],
        }
    }

    /// A warm-up from `start_c` by 15 C with time constant `tau_min`: rate = (T_end - T) / tau.
    fn warm_up(run: usize, start_c: f64, tau_min: f64) -> Vec<(usize, f64, f64)> {
        (0..120)
            .map(|k| {
                let t_min = k as f64;
                let temp = start_c + 15.0 * (1.0 - (-t_min / tau_min).exp());
                (run, temp, (start_c + 15.0 - temp) / tau_min)
            })
            .collect()
    }

    /// Chamber ramps up and down between -20 and 40 C at two rates: T and dT/dt independent.
    fn ramps() -> Vec<(usize, f64, f64)> {
        let mut out = Vec::new();
        for (run, rate) in [(0, 0.5), (1, -0.5), (2, 1.0), (3, -1.0)] {
            for k in 0..=60 {
                let temp = if rate > 0.0 { -20.0 + k as f64 } else { 40.0 - k as f64 };
                out.push((run, temp, rate));
            }
        }
        out
    }

    fn kinds(w: &[Warning]) -> Vec<WarningKind> {
        w.iter().map(|w| w.kind).collect()
    }

    #[test]
    fn one_warm_up_is_confounded_and_ramps_are_not() {
        // One exponential warm-up: rate is linear in T, R^2 = 1 (docs/physics.md).
        let w = confounding(&points(&warm_up(0, 20.0, 20.0)), 0).expect("confounded");
        assert!(w.values["r_squared_rate_on_cubic_t"] > 1.0 - 1e-9, "{:?}", w.values);
        assert!((w.values["corr_temp_rate"] + 1.0).abs() < 1e-9, "{:?}", w.values);
        assert_eq!(w.kind.name(), "temperature_rate_confounded");
        // Ramps at +-0.5 and +-1 C/min over the same temperatures: the rate is independent
        // of T by construction; the regression explains none of it (closed form: the
        // mean rate is 0 at every T).
        assert!(confounding(&points(&ramps()), 0).is_none());
        assert!(r_squared_on_cubic(
            &ramps().iter().map(|t| t.1).collect::<Vec<_>>(),
            &ramps().iter().map(|t| t.2).collect::<Vec<_>>()
        )
        .is_some_and(|r2| r2 < 1e-12));
    }

    #[test]
    fn confounding_threshold_is_the_vif_of_ten() {
        // rate = T/10 + c * (+-1 alternating): R^2 = var(T/10) / (var(T/10) + c^2) exactly
        // for T symmetric about 0 and the alternation orthogonal to {1, T, T^2, T^3}
        // (checked by the regression itself below). Choose c on both sides of R^2 = 0.9.
        let temps: Vec<f64> = (0..200).map(|k| -10.0 + 20.0 * (k / 2) as f64 / 99.0).collect();
        let var_signal = {
            let m = temps.iter().sum::<f64>() / 200.0;
            temps.iter().map(|t| (t / 10.0 - m / 10.0).powi(2)).sum::<f64>() / 200.0
        };
        for (r2_wanted, fires) in [(0.95, true), (0.85, false)] {
            let c = (var_signal * (1.0 - r2_wanted) / r2_wanted).sqrt();
            let triples: Vec<(usize, f64, f64)> = temps
                .iter()
                .enumerate()
                .map(|(k, &t)| (k % 4, t, t / 10.0 + if k % 2 == 0 { c } else { -c }))
                .collect();
            let p = points(&triples);
            let r2 = r_squared_on_cubic(
                &triples.iter().map(|t| t.1).collect::<Vec<_>>(),
                &triples.iter().map(|t| t.2).collect::<Vec<_>>(),
            )
            .unwrap();
            assert!((r2 - r2_wanted).abs() < 1e-9, "R^2 {r2} wanted {r2_wanted}");
            assert_eq!(confounding(&p, 0).is_some(), fires, "R^2 {r2}");
        }
        // A constant rate has nothing to confound.
        assert!(confounding(
            &points(&[(0, 1.0, 0.2), (0, 2.0, 0.2), (0, 3.0, 0.2), (1, 4.0, 0.2), (2, 5.0, 0.2)]),
            0
        )
        .is_none());
    }

    /// Kelvin read as deg C (238-334, review12's logs) warns with the range and the fix; a
    /// chamber run to 140 C, or one point below the limit, does not.
    #[test]
    fn temperatures_above_any_operating_range_are_said_to_be_kelvin_or_counts() {
        let kelvin = points(&[(0, 238.15, 0.1), (1, 300.0, 0.2), (2, 334.22, -0.1)]);
        let w = implausible_temperatures(&kelvin, 0).expect("warned");
        assert_eq!(w.kind.name(), "implausible_temperatures");
        assert!(
            w.message.contains("between 238.15 and 334.22 C") && w.message.contains("--temp-offset -273.15"),
            "{}",
            w.message
        );
        assert_eq!(w.values["temp_min_c"], 238.15);
        assert!(implausible_temperatures(&points(&[(0, 20.0, 0.1), (1, 140.0, 0.2)]), 0).is_none());
        assert!(implausible_temperatures(&points(&[(0, 149.0, 0.1), (1, 300.0, 0.2)]), 0).is_none());
    }

    /// A 0.5 C/min ramp for 3000 s at 1 Hz whose gyro reads `gyro_dph(temp_c)`.
    fn ramp_reading(gyro_dph: impl Fn(f64) -> f64) -> RunFeatures {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..3000 {
            let temp_c = 20.0 + 0.5 * f64::from(k) / 60.0;
            csv.push_str(&format!("{k},{temp_c:.4},{:e}\n", gyro_dph(temp_c)));
        }
        let config = CalibrationConfig::default();
        crate::calibrate::extract_run_from(csv.as_bytes(), std::path::Path::new("ramp.csv"), &config)
            .expect("reads")
    }

    /// A gyro in rad/s read as deg/h (206,265 times too small) warns with the largest mean and
    /// the fix, whether or not an input rate was taken off (it is added back); a gyro reading
    /// the Earth rate alone, taken off, does not (review32a F2, review32b F2).
    #[test]
    fn a_gyro_closer_to_zero_than_any_fog_is_said_to_be_in_another_unit() {
        let rad_per_s = |temp_c: f64| (9.67 + 0.02 * temp_c) / 206_264.8;
        let mut run = ramp_reading(rad_per_s);
        let w = implausible_gyro(std::slice::from_ref(&run), 0).expect("warned");
        assert_eq!(w.kind.name(), "implausible_gyro");
        let largest = w.values["largest_abs_gyro_dph"];
        // Oracle: the ramp's hottest reading, 45 C (features are means over the window).
        assert!(largest < rad_per_s(45.0) && largest > rad_per_s(40.0), "{largest}");
        assert!(
            w.message.starts_with("axis 0: every gyro mean of the calibration logs, as read, lies within ")
                && w.message.contains("--gyro-unit rps or dps"),
            "{}",
            w.message
        );
        run.subtract_input_rate(0, 9.67);
        assert!(implausible_gyro(std::slice::from_ref(&run), 0).is_some(), "rates taken off are added back");
        let mut earth = ramp_reading(|_| 9.67);
        earth.subtract_input_rate(0, 9.67);
        assert!(implausible_gyro(std::slice::from_ref(&earth), 0).is_none(), "as read it is 9.67 deg/h");
        assert!(implausible_gyro(&[ramp_reading(|t| 0.5 + 0.01 * t)], 0).is_none());
        assert!(implausible_gyro(&[], 0).is_none());
    }

    /// Minutes read as seconds (every rate 60 times too large) warns with the median and the
    /// fix; a calibration whose fastest points exceed the limit, but not half of them, does not.
    #[test]
    fn rates_a_gyro_cannot_follow_are_said_to_be_a_time_unit() {
        let minutes: Vec<(usize, f64, f64)> = [0.1, -0.05, 0.3, 0.5, 0.2]
            .iter()
            .enumerate()
            .map(|(k, r)| (k, 20.0 + k as f64, 60.0 * r))
            .collect();
        let w = implausible_rates(&points(&minutes), 0).expect("warned");
        assert_eq!(w.kind.name(), "implausible_rates");
        // Sorted speeds 3, 6, 12, 18, 30 C/min: the median is 12.
        assert_eq!(w.values["median_abs_rate_c_per_min"], 12.0);
        assert!(
            w.message.contains("faster than 12.00 C/min") && w.message.contains("--time-unit min"),
            "{}",
            w.message
        );
        let seconds: Vec<(usize, f64, f64)> = minutes.iter().map(|&(k, t, r)| (k, t, r / 60.0)).collect();
        assert!(implausible_rates(&points(&seconds), 0).is_none());
        let fast_tail = points(&[(0, 20.0, 0.1), (1, 21.0, 0.2), (2, 22.0, 5.0), (3, 23.0, 9.0)]);
        assert!(implausible_rates(&fast_tail, 0).is_some(), "median of 4 is the upper middle: 5 C/min");
        let fast_few = points(&[(0, 20.0, 0.1), (1, 21.0, 0.2), (2, 22.0, 0.3), (3, 23.0, 9.0)]);
        assert!(implausible_rates(&fast_few, 0).is_none());
    }

    #[test]
    fn too_few_runs_fires_below_three() {
        let two: Vec<_> = warm_up(0, 0.0, 20.0).into_iter().chain(warm_up(1, 20.0, 20.0)).collect();
        let w = too_few_runs(&points(&two), 0).expect("two runs");
        assert_eq!((w.values["runs"], w.values["min_runs"]), (2.0, 3.0));
        let three: Vec<_> = two.into_iter().chain(warm_up(2, 40.0, 20.0)).collect();
        assert!(too_few_runs(&points(&three), 0).is_none());
    }

    #[test]
    fn narrow_range_absolute_floor_and_operating_range() {
        let settings = IdentifiabilitySettings::default();
        // One warm-up spans 15 C * (1 - e^-119/20) = 14.96 C < 20 C.
        let w = temperature_range(&points(&warm_up(0, 20.0, 20.0)), 0, &settings).expect("narrow");
        assert!((w.values["temp_span_c"] - 15.0 * (1.0 - (-119.0f64 / 20.0).exp())).abs() < 1e-9);
        // Ramps span 60 C.
        assert!(temperature_range(&points(&ramps()), 0, &settings).is_none());
        // Known use from -30 to 40 C: 10 C below the calibrated -20 C uncovered.
        let used = IdentifiabilitySettings { operating_temp_c: Some((-30.0, 40.0)) };
        let w = temperature_range(&points(&ramps()), 0, &used).expect("uncovered");
        assert_eq!(w.values["uncovered_c"], 10.0);
        let inside = IdentifiabilitySettings { operating_temp_c: Some((-10.0, 35.0)) };
        assert!(temperature_range(&points(&ramps()), 0, &inside).is_none());
        // A narrow calibration that does cover its stated use passes.
        let narrow_use = IdentifiabilitySettings { operating_temp_c: Some((21.0, 30.0)) };
        assert!(temperature_range(&points(&warm_up(0, 20.0, 20.0)), 0, &narrow_use).is_none());
    }

    #[test]
    fn heating_only_cooling_only_and_both() {
        let heating: Vec<_> = (0..3).flat_map(|r| warm_up(r, 20.0 * r as f64, 20.0)).collect();
        let w = rate_signs(&points(&heating), 0).expect("heating only");
        assert_eq!((w.kind, w.kind.name()), (WarningKind::HeatingOnly, "heating_only"));
        let cooling: Vec<_> = heating.iter().map(|&(r, t, rate)| (r, t, -rate)).collect();
        assert_eq!(rate_signs(&points(&cooling), 0).map(|w| w.kind), Some(WarningKind::CoolingOnly));
        assert!(rate_signs(&points(&ramps()), 0).is_none());
        // Settled (|rate| below 0.05 C/min everywhere): neither side is moving, no warning.
        let settled: Vec<_> =
            (0..50).map(|k| (k % 3, k as f64, 0.04 * ((k % 5) as f64 - 2.0) / 2.0)).collect();
        assert!(rate_signs(&points(&settled), 0).is_none());
        // One cooling point among 201 is beyond the 1st percentile (rank 3 of 201): still
        // heating only, but the text counts that point and does not call cooling outside.
        let mut mostly: Vec<_> = (0..200).map(|k| (0, k as f64, 0.5)).collect();
        mostly.push((0, 50.0, -0.5));
        let w = rate_signs(&points(&mostly), 0).expect("mostly heating");
        assert_eq!(w.kind, WarningKind::HeatingOnly);
        assert!(
            w.message
                .contains("mostly heats: 1 of its 201 points (0.5 %) cool faster than 0.05 C/min, to -0.500"),
            "{}",
            w.message
        );
        assert!(!w.message.contains("cooling rates are outside"), "{}", w.message);
        // With none, cooling is outside.
        let w = rate_signs(&points(&heating), 0).expect("heating only");
        assert!(w.message.contains("only heats: no point cools faster than 0.05 C/min"), "{}", w.message);
        assert!(w.message.contains("cooling rates are outside the calibrated region"), "{}", w.message);
    }

    #[test]
    fn all_warnings_together_and_none() {
        let w = warnings(&points(&warm_up(0, 20.0, 20.0)), 1, &IdentifiabilitySettings::default());
        assert_eq!(
            kinds(&w),
            vec![
                WarningKind::TemperatureRateConfounded,
                WarningKind::TooFewRuns,
                WarningKind::NarrowTemperatureRange,
                WarningKind::HeatingOnly
            ]
        );
        assert!(w.iter().all(|w| w.axis == 1 && w.message.starts_with("axis 1: ")));
        assert!(warnings(&points(&ramps()), 0, &IdentifiabilitySettings::default()).is_empty());
        assert!(warnings(&CalibrationPoints::default(), 0, &IdentifiabilitySettings::default()).is_empty());
        assert!(w[0].values["variance_inflation_factor"] > MAX_VIF);
    }
}
