//! The calibration pipeline: logs -> features (core tracker) -> smoothed targets ->
//! thinning -> polynomial / mesh / hybrid fit -> model blob; and validation by replaying
//! raw samples through the firmware's own `Compensator`.

use std::io::Read;
use std::path::{Path, PathBuf};

use fogtemp_core::{
    AxisProvenance, Compensator, FeatureSettings, Flags, InputRates, Model, Normalisation, OutsidePolicy,
};

use crate::blob::{encode, AxisModel, ModelFile};
use crate::digest::InputDigest;
use crate::error::CalError;
use crate::features::{smoothed_gyro_dph, AxisFeatureStream, FeaturePoint, CAL_CAPACITY};
use crate::ingest::{read_from, read_log_digested, read_log_with_progress, IngestOptions, IngestReport, Row};
use crate::mesh::{build_mesh, MeshPoint};
use crate::metrics::{bias_stability, rms_over_runs, stability_of_means, window_stats, BiasStabilityOptions};
use crate::poly_fit::{fit_poly, PolyFit, TermSelection};
use crate::selection::{Selection, SelectionOptions};
use crate::spikes::{AxisSpikes, Sample, SpikeGuard};
use crate::thin::{thin_greedy, thin_paper, GreedyThinning};

/// Which model to fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Polynomial in (T, dT/dt).
    Poly,
    /// Delaunay mesh with linear interpolation (nearest hull value outside).
    Mesh,
    /// Polynomial plus a mesh of its residuals (polynomial alone outside the hull).
    Hybrid,
    /// A cubic in temperature alone (what PX4 and ArduPilot ship): the baseline.
    CubicT,
    /// Chosen per axis among the others by cross-validation over the runs
    /// ([`crate::selection`]), then fitted on all runs.
    Auto,
}

impl Method {
    /// The name `fit --method` takes (`poly`, `mesh`, `hybrid`, `cubic-t`, `auto`).
    pub fn name(self) -> &'static str {
        match self {
            Method::Poly => "poly",
            Method::Mesh => "mesh",
            Method::Hybrid => "hybrid",
            Method::CubicT => "cubic-t",
            Method::Auto => "auto",
        }
    }
}

/// How mesh nodes are chosen from the calibration points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Thinning {
    /// The paper: one point per smoothing window, then every point with
    /// |rate| >= `fast_rate_c_per_min` and every `settled_every`-th otherwise.
    Paper {
        /// Rate above which every point is kept, deg C/min.
        fast_rate_c_per_min: f64,
        /// Keep one in this many settled points.
        settled_every: usize,
    },
    /// Greedy insertion of the worst-interpolated point (default).
    Greedy(GreedyThinning),
    /// Greedy insertion until the RMS interpolation error is `noise_multiple` times the
    /// estimated noise of the smoothed targets (see [`target_noise_dph`]): RMS^2 = noise^2 +
    /// misfit^2, so 1.5 stops once the systematic misfit is about the noise (1.1 sigma) and
    /// nodes stop chasing noise.
    GreedyAuto {
        /// RMS tolerance in units of the target noise (1.5 by default).
        noise_multiple: f64,
        /// At most this many nodes.
        max_nodes: usize,
    },
}

/// Robust estimate of the noise of the smoothed gyro targets, deg/h.
///
/// Within each segment of each run, the 1 s block means are averaged over non-overlapping
/// windows of `target_window_s`; the second differences `m[j+2] - 2 m[j+1] + m[j]` of those
/// window means cancel a linear thermal drift and, for noise whose window means are
/// independent, have variance 6 sigma^2; the estimate is their median absolute value
/// / 0.6745 / sqrt 6 (robust to the few windows where the drift curves). Unlike first
/// differences of block means, this sees bias instability (flicker) at the window's time
/// scale as well as white noise. Falls back to the white-noise estimate (median first
/// difference of block means, scaled by sqrt(block_s / target_window_s)) when the runs hold
/// fewer than 10 second differences; NaN when there are too few blocks for that too.
pub fn target_noise_dph(runs: &[RunFeatures], axis: usize, block_s: f64, target_window_s: f64) -> f64 {
    let per_window = ((target_window_s / block_s).round() as usize).max(1);
    let mut second: Vec<f64> = Vec::new();
    let mut first: Vec<f64> = Vec::new();
    for (points, _) in runs.iter().filter_map(|r| r.axes.get(axis)) {
        for seg in points.chunk_by(|a, b| a.segment == b.segment) {
            let blocks: Vec<f64> = seg
                .iter()
                .filter(|p| p.gyro_samples > 0)
                .map(|p| p.gyro_mean_dph)
                .filter(|v| v.is_finite())
                .collect();
            first.extend(blocks.windows(2).map(|w| (w[1] - w[0]).abs()));
            let means: Vec<f64> =
                blocks.chunks_exact(per_window).map(|c| c.iter().sum::<f64>() / per_window as f64).collect();
            second.extend(means.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).abs()));
        }
    }
    if second.len() >= 10 {
        return median(&mut second) / 0.6745 / 6f64.sqrt();
    }
    if first.len() < 10 {
        return f64::NAN;
    }
    let block_sigma = median(&mut first) / 0.6745 / std::f64::consts::SQRT_2;
    block_sigma * (block_s / target_window_s).min(1.0).sqrt()
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    (sum / n.max(1) as f64).sqrt()
}

fn median(values: &mut [f64]) -> f64 {
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    *m
}

/// Everything `fit` needs besides the logs.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationConfig {
    /// Columns and units of the logs.
    pub ingest: IngestOptions,
    /// Feature tracker settings (written into the blob).
    pub features: FeatureSettings,
    /// Centred smoothing window of the gyro target, seconds (the paper: 100 s).
    pub target_window_s: f64,
    /// Model kind.
    pub method: Method,
    /// Mesh node selection.
    pub thinning: Thinning,
    /// Polynomial terms.
    pub poly: TermSelection,
    /// Leave out points whose feature window was not yet full.
    pub full_windows_only: bool,
    /// Fit the mesh node values by least squares to all calibration points (default)
    /// instead of taking each node's own smoothed target (the paper).
    pub least_squares_nodes: bool,
    /// Length of the rate axis relative to the temperature axis after normalisation
    /// (1: both span [-1, 1], the default; the Delaunay triangulation and the thinning
    /// distances see this aspect ratio).
    pub rate_axis_weight: f64,
    /// What the polynomial does outside the calibrated region (the convex hull of the
    /// calibration points, always stored in the blob). Default: continued linearly from the
    /// nearest boundary point (no worse than extrapolating on the testbed, and no runaway);
    /// holding at the boundary was worse (docs/calibration-testbed.md).
    pub poly_outside: fogtemp_core::PolyOutside,
    /// What a mesh model's mesh does outside its hull: continued linearly from the nearest hull
    /// point with gradients stored per hull vertex (the default, chosen after measuring it:
    /// the testbed's null cases within 3 % of the polynomial, the Python whole-box benchmark
    /// above 10x scipy; docs/calibration-testbed.md, "Mesh continuation with stored
    /// gradients"), the same with the gradient fitted per query, or held. The hybrid's mesh, a
    /// residual on the polynomial, is always zero outside (the polynomial's own continuation
    /// carries the trend there). A polynomial-only axis stores hold (no mesh to continue).
    pub mesh_outside: OutsidePolicy,
    /// Record the log columns each axis was fitted on in the blob (format version 4), and how
    /// the logs' time was read (version 5), so `validate` and `compensate` match a log's
    /// columns by name and read its time the same way. Off for runs given as several
    /// gyro or temperature arrays, whose column names are made up (`gyro_dph[0]`).
    pub record_columns: bool,
    /// Insert Steiner nodes where a plain mesh's triangles are too large to carry the
    /// polynomial part its node fit leaves free (`refine`; least-squares nodes only). On by
    /// default (docs/calibration-testbed.md, "Steiner nodes between the calibration paths").
    pub refine_mesh: bool,
    /// The mesh's smoothness weight relative to the data/penalty balance, given instead of
    /// cross-validated (a diagnostic: `fit --mesh-relative-weight`, hidden); `None` (the
    /// default): chosen by cross-validation within runs (`mesh_fit`).
    pub mesh_relative_weight: Option<f64>,
    /// Fold assignments the mesh weight's cross-validation averages over
    /// ([`crate::mesh_fit::CV_REPEATS`]; `fit --mesh-cv-repeats`, hidden, for measuring it).
    pub mesh_cv_repeats: usize,
    /// Salt of the first of those assignments (0: unsalted; `fit --mesh-cv-salt`, hidden).
    pub mesh_cv_salt: u64,
    /// What was done with the runs' true input rates before the fit, when run metadata gave
    /// them ([`subtract_input_rates`]); recorded in the blob (format version 8) so that
    /// `validate` can tell whether the model's output holds an input rate. `None`: no rates.
    pub input_rates: Option<InputRates>,
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        Self {
            ingest: IngestOptions::default(),
            features: default_features(),
            target_window_s: 100.0,
            method: Method::Auto,
            thinning: Thinning::GreedyAuto { noise_multiple: 1.5, max_nodes: 600 },
            poly: TermSelection::default_stepwise(),
            full_windows_only: false,
            least_squares_nodes: true,
            rate_axis_weight: 1.0,
            poly_outside: fogtemp_core::PolyOutside::LinearFromBoundary,
            mesh_outside: OutsidePolicy::StoredGradients,
            record_columns: true,
            refine_mesh: true,
            mesh_relative_weight: None,
            mesh_cv_repeats: crate::mesh_fit::CV_REPEATS,
            mesh_cv_salt: 0,
            input_rates: None,
        }
    }
}

/// The paper's 100 s window, as 100 one-second blocks, features after 10 s, restart
/// after 5 s without temperature.
pub fn default_features() -> FeatureSettings {
    FeatureSettings { window_s: 100.0, block_count: 100, min_blocks: 10, max_gap_s: 5.0 }
}

/// Features of one run, per axis.
#[derive(Clone, Debug, PartialEq)]
pub struct RunFeatures {
    /// The log.
    pub path: PathBuf,
    /// What ingest saw.
    pub ingest: IngestReport,
    /// Gaps in the log's time stamps longer than the tracker's `max_gap_s`.
    pub gaps: TimeGaps,
    /// Per axis: the feature points and their smoothed gyro targets (deg/h).
    pub axes: Vec<(Vec<FeaturePoint>, Vec<f64>)>,
    /// Per axis: the true input rate subtracted from its gyro means and targets
    /// ([`RunFeatures::subtract_input_rate`]), deg/h; empty or 0 where none was.
    pub input_rate_subtracted_dph: Vec<f64>,
    /// Per axis: temperature readings read as missing because they were single-reading
    /// spikes ([`crate::spikes`]); empty where none was looked for.
    pub temperature_spikes: Vec<AxisSpikes>,
    /// Per axis: stretches longer than the tracker's `max_gap_s` without a temperature
    /// reading while rows went on (a dropped-out temperature channel); the tracker restarted
    /// after each. Empty where none was looked for.
    pub temperature_silences: Vec<TimeGaps>,
    /// Per axis: feature points whose gyro mean was an outlier (a spike in the log), read as
    /// missing ([`screen_gyro_means`]); empty where none was looked for.
    pub gyro_outliers: Vec<Vec<GyroOutlier>>,
    /// Per axis: the smallest step between consecutive different temperature readings, and
    /// how many changes there were ([`TemperatureSteps`]); empty where none was looked for.
    pub temperature_steps: Vec<TemperatureSteps>,
    /// SHA-256 of the log's bytes (of its samples for a run given as arrays), when the caller
    /// took it (`fit` and Python's `fit` do, with the input digest): a model fitted on runs
    /// that all have one records each ([`crate::blob::LogReadingRecord`]), so `validate` can
    /// say which of its logs were calibration logs.
    pub digest: Option<[u8; 32]>,
}

/// A feature point's gyro mean read as missing because it lay beyond
/// [`crate::outliers::ROBUST_SDS`] robust standard deviations of the median of the points
/// around it (a spike in the log: a corrupted sample, an overload code).
#[derive(Clone, Debug, PartialEq)]
pub struct GyroOutlier {
    /// The point's time, seconds since the run's first row.
    pub time_s: f64,
    /// Its gyro mean, deg/h.
    pub gyro_mean_dph: f64,
    /// Its deviation from the median of the points around it, deg/h.
    pub deviation_dph: f64,
    /// The run's robust standard deviation of the points' gyro means, deg/h.
    pub robust_sd_dph: f64,
}

/// Reads as missing the gyro means of `points` that are outliers ([`crate::outliers`]: a
/// Hampel filter over 30 points either side, at 1 s blocks a minute), so that no target is
/// smoothed over them, and returns them. One +1000 deg/h sample in a 1 Hz log made `fit`'s
/// default model 9 times worse than none on clean runs (review12 finding 1).
pub fn screen_gyro_means(points: &mut [FeaturePoint]) -> Vec<GyroOutlier> {
    let means: Vec<f64> =
        points.iter().map(|p| if p.gyro_samples > 0 { p.gyro_mean_dph } else { f64::NAN }).collect();
    let (found, robust_sd_dph) = crate::outliers::screen(&means);
    found
        .into_iter()
        .map(|(k, deviation_dph)| {
            let p = &mut points[k];
            let outlier = GyroOutlier {
                time_s: p.time_s,
                gyro_mean_dph: p.gyro_mean_dph,
                deviation_dph,
                robust_sd_dph,
            };
            p.gyro_mean_dph = f64::NAN;
            p.gyro_samples = 0;
            outlier
        })
        .collect()
}

impl RunFeatures {
    /// The note for axis `axis`'s temperature silences (`None` without any).
    pub fn temperature_silence_note(&self, axis: usize) -> Option<String> {
        let gaps = self.temperature_silences.get(axis)?;
        let place = if gaps.in_samples { "sample" } else { "line" };
        match gaps.count {
            0 => None,
            1 => Some(format!(
                "{} axis {axis}: the temperature was silent for {} s before {place} {} while rows went on \
                 (longer than the tracker's max gap of {} s): no features or calibration points come from it, \
                 and the tracker restarted after it",
                self.path.display(),
                seconds(gaps.largest_s),
                gaps.largest_before_line,
                gaps.longer_than_s,
            )),
            n => Some(format!(
                "{} axis {axis}: the temperature was silent {n} times for longer than the tracker's max gap of {} s \
                 while rows went on, {} s in all, the longest {} s before {place} {}: no features or calibration \
                 points come from them, and the tracker restarted after each",
                self.path.display(),
                gaps.longer_than_s,
                seconds(gaps.total_s),
                seconds(gaps.largest_s),
                gaps.largest_before_line,
            )),
        }
    }
}

/// Subtracts each run's true input rate (`rates_dph`, one per run, in order) from its gyro
/// ([`RunFeatures::subtract_input_rate`]) when `config`'s logs have one gyro column: a runs
/// file gives one rate per run, about the input axis. Records what was done in
/// [`CalibrationConfig::input_rates`], for the blob (not subtracted with several columns),
/// and returns it.
pub fn subtract_input_rates(
    runs: &mut [RunFeatures],
    rates_dph: &[f64],
    config: &mut CalibrationConfig,
) -> InputRates {
    let done = if config.ingest.format.gyro_columns.len() == 1 {
        for (run, &rate) in runs.iter_mut().zip(rates_dph) {
            run.subtract_input_rate(0, rate);
        }
        InputRates::Subtracted
    } else {
        InputRates::NotSubtracted
    };
    config.input_rates = Some(done);
    done
}

/// The warning for a log most of whose steps between rows are gaps longer than the tracker's
/// max gap (a time column read in the wrong unit: ms read as s), or `None`. `unit_hint`
/// names the setting to check (the command line's `--time-unit`, Python's `time_unit=`), or
/// is empty for arrays, whose time is in seconds.
pub fn mostly_gaps_note(path: &Path, gaps: &TimeGaps, rows: u64, unit_hint: &str) -> Option<String> {
    gaps.mostly_gaps(rows).then(|| {
        format!(
            "{}: {} of its {} steps between rows are longer than the tracker's max gap of {} s: {}",
            path.display(),
            gaps.count,
            rows - 1,
            gaps.longer_than_s,
            another_unit(unit_hint)
        )
    })
}

/// Below this mean step between rows a log is faster than any gyro's logger writes, s (20
/// kHz): its time is in a larger unit read as seconds, such as a spreadsheet's serial days
/// (review32a F7: 10,800 rows at 2 Hz in 0.06 s, then "no calibration points" and advice to
/// check the temperature column).
pub const FASTEST_LOG_STEP_S: f64 = 5e-5;

/// The warning for a log of at least 100 rows whose mean step between rows is under
/// [`FASTEST_LOG_STEP_S`], or `None`; `unit_hint` as for [`mostly_gaps_note`].
pub fn too_brief_note(path: &Path, ingest: &crate::ingest::IngestReport, unit_hint: &str) -> Option<String> {
    let rows = ingest.rows;
    let step_s = ingest.last_time_s / rows.saturating_sub(1).max(1) as f64;
    (rows >= 100 && step_s < FASTEST_LOG_STEP_S).then(|| {
        format!(
            "{}: its {rows} rows span only {:.3e} s, {step_s:.1e} s a row, faster than any gyro's logger: {} \
             (dates as spreadsheets write them count days: convert them to seconds first)",
            path.display(),
            ingest.last_time_s,
            another_unit(unit_hint)
        )
    })
}

/// The warnings that a log's times are in another unit than read: most steps gaps
/// ([`mostly_gaps_note`]) or rows faster than any logger ([`too_brief_note`]); `gaps` as the
/// tracker saw them, `unit_hint` as for [`mostly_gaps_note`].
pub fn time_unit_notes(
    path: &Path,
    gaps: &TimeGaps,
    ingest: &crate::ingest::IngestReport,
    unit_hint: &str,
) -> impl Iterator<Item = String> {
    [mostly_gaps_note(path, gaps, ingest.rows, unit_hint), too_brief_note(path, ingest, unit_hint)]
        .into_iter()
        .flatten()
}

/// "are its times in another unit?" with the setting to check (`unit_hint`), or for arrays
/// (empty `unit_hint`) the unit they are read in.
fn another_unit(unit_hint: &str) -> String {
    if unit_hint.is_empty() {
        "is time_s in another unit? It is read in seconds (milliseconds / 1000)".to_string()
    } else {
        format!("are its times in another unit? ({unit_hint} s, ms, us, ns, min or h)")
    }
}

/// The warning for a model whose axis count differs from the log's gyro columns (only the
/// first of them are paired, axis k with the k-th column), or `None`. `column_hint` names the
/// setting (`--gyro-column`, `gyro_column=`).
pub fn axis_count_note(
    model: &str,
    model_axes: usize,
    gyro_columns: usize,
    column_hint: &str,
) -> Option<String> {
    (model_axes != gyro_columns).then(|| {
        format!(
            "{model} has {model_axes} {} but the log is read with {gyro_columns} gyro column{} ({column_hint}): \
             only the first {} are used, axis k with the k-th gyro column",
            if model_axes == 1 { "axis" } else { "axes" },
            if gyro_columns == 1 { "" } else { "s" },
            model_axes.min(gyro_columns)
        )
    })
}

/// The note for a log's axis whose compensator never corrected a sample (its tracker never
/// had features), `name` being "LOG axis K" and `consequence` what that left; `flags` the
/// samples' counts per flag bit ([`ReplaySeries::flag_counts`]), which name the likely
/// cause, and `max_gap_s` the model's gap limit.
pub fn never_corrected_note(
    name: &str,
    consequence: &str,
    flags: &[u64; 8],
    samples: u64,
    max_gap_s: f64,
) -> String {
    let count = |flag: Flags| flags.get(flag.0.trailing_zeros() as usize).copied().unwrap_or(0);
    let (stale, bad) = (count(Flags::TEMP_STALE), count(Flags::BAD_INPUT));
    // Rejected readings leave the temperature stale too: they are the cause to name first
    // (review20 F1: raw counts were put down to the gap limit).
    let cause = if 2 * bad > samples {
        format!(
            "{bad} of {samples} samples had their temperature or time rejected (BAD_INPUT): temperatures no \
             sensor reads (raw sensor counts read as deg C, above 1000; a logger's -999; NaN), or times out of \
             order; raw counts need the temperature's scale and offset"
        )
    } else if 4 * stale > samples {
        format!(
            "the temperature was silent for longer than the model's max gap of {max_gap_s} s at {stale} of \
             {samples} samples (TEMP_STALE): readings further apart than that, or an empty temperature \
             column; the gap limit is the model's, set by fit --max-gap-s"
        )
    } else {
        "no usable temperature, e.g. an empty temperature column, or time stamps in another unit than \
         the one given"
            .to_string()
    };
    format!("{name}: the compensator never corrected a sample: its feature tracker never had features ({cause}); {consequence}")
}

/// Where the samples a compensation flagged `BAD_INPUT` can come from, for
/// [`compensation_notes`] (review21 F8: `compensate`'s note named no line, and a cause its
/// reader refuses).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BadInputSources {
    /// The reader refused times not after the one before (a log file), so they are no cause.
    pub times_refused: bool,
    /// The log lines of the first flagged samples (empty when there are none: arrays).
    pub first_lines: Vec<u64>,
    /// Flagged samples whose gyro value was not finite (NaN or infinite: the core passes it
    /// through). A log's reader refuses them; arrays can hold them (review23a F6: the note
    /// blamed a temperature or a time).
    pub gyro_not_finite: u64,
    /// Flagged samples whose time fell in the same whole microsecond as the sample's before:
    /// the compensator's clock counts microseconds, so their temperature reading is refused
    /// as not after the one before, though the reader (in f64 seconds) took them (review25a 2:
    /// nanosecond stamps 200 ns apart were put down to temperatures no sensor reads).
    pub same_microsecond: u64,
}

/// The samples flagged `BAD_INPUT` whose temperature reading, one a sensor gives, falls in
/// the whole microsecond of the last reading the tracker took ([`BadInputSources::same_microsecond`]),
/// from a replay's inputs and flags (Python's `Model.compensate`; the command line counts
/// them as it streams, with [`SameMicrosecond`]).
pub fn same_microsecond_rejections(time_s: &[f64], temp_c: &[f64], flags: &[u8]) -> u64 {
    let bad = fogtemp_core::Flags::BAD_INPUT.0;
    let mut counter = SameMicrosecond::default();
    for ((&t, &temp), &f) in time_s.iter().zip(temp_c).zip(flags) {
        counter.observe(crate::features::micros(t), temp, f & bad != 0);
    }
    counter.count
}

/// Counts the temperature readings the tracker refused for coming in the microsecond of the
/// last one it took (its clock's resolution): time stamps finer than 1 us (review25a 2).
#[derive(Clone, Copy, Debug, Default)]
pub struct SameMicrosecond {
    last_reading_us: Option<u64>,
    /// Readings refused so.
    pub count: u64,
}

impl SameMicrosecond {
    /// One sample: its time, its temperature (NaN: none) and whether it was flagged `BAD_INPUT`.
    pub fn observe(&mut self, time_us: u64, temp_c: f64, flagged_bad: bool) {
        if !(temp_c.is_finite() && fogtemp_core::is_physical_temperature(temp_c as f32)) {
            return;
        }
        if flagged_bad && self.last_reading_us == Some(time_us) {
            self.count += 1;
        } else {
            self.last_reading_us = Some(time_us);
        }
    }
}

/// How many flagged samples' lines [`BadInputSources::first_lines`] keeps.
pub const BAD_INPUT_LINES_LISTED: usize = 5;

/// The note on samples flagged `BAD_INPUT`, with the first lines when known.
fn bad_input_note(name: &str, bad: u64, samples: u64, output: &str, sources: &BadInputSources) -> String {
    let time = if sources.times_refused { "" } else { " or a time not after the one before" };
    let lines = match sources.first_lines.as_slice() {
        [] => String::new(),
        [one] => format!("; at line {one}"),
        many => {
            let listed: Vec<String> = many.iter().map(u64::to_string).collect();
            let first = if (many.len() as u64) < bad { "first " } else { "" };
            format!("; {first}at lines {}", listed.join(", "))
        }
    };
    let same_us = sources.same_microsecond.min(bad);
    if same_us > 0 {
        let rest = if same_us < bad {
            format!(
                "; the other {} a temperature no sensor reads or a gyro value that is not a number",
                bad - same_us
            )
        } else {
            String::new()
        };
        return format!(
            "{name}: {bad} of {samples} samples ({} %) had an input rejected (flag BAD_INPUT in {output}{lines}); {same_us} of them \
             came in the same microsecond as the last reading taken: the compensator counts time in whole \
             microseconds, so their temperature readings were refused as not after the one before (time stamps \
             finer than 1 us, e.g. several samples of a packet stamped ns apart: give each sample its own time, \
             or average the packet){rest}",
            share_percent(bad, samples)
        );
    }
    let gyro = sources.gyro_not_finite.min(bad);
    if gyro == bad {
        return format!(
            "{name}: {bad} of {samples} samples ({} %) had a gyro value that is not a number or infinite (flag \
             BAD_INPUT in {output}{lines}): passed through as given, as the firmware does; their temperatures \
             still feed the features",
            share_percent(bad, samples)
        );
    }
    let gyro_too = if gyro > 0 {
        format!("; {gyro} of them a gyro value that is not a number or infinite, passed through as given")
    } else {
        String::new()
    };
    format!(
        "{name}: {bad} of {samples} samples ({} %) had a temperature no sensor reads (below -273.15 C or above \
         1000 C, or not a number: a logger's mark for a missing reading?){time} (flag BAD_INPUT in {output}{lines}): \
         compensated as the firmware does, without them in the features{gyro_too}",
        share_percent(bad, samples)
    )
}

/// The notes on one axis's compensated output (`compensate`, Python's `Model.compensate`)
/// from how many of its `samples` carried each flag bit (`flag_counts[bit]`): that nothing
/// was corrected (with `never_consequence`, and then nothing else), and the shares of samples
/// flagged `BAD_INPUT`, `TEMP_STALE` and `OUTSIDE_HULL` (with how far those reach, `reach`,
/// from an [`OutsideWatch`]); `name` names the axis, `output` the place of the flags ("the
/// output", "flags"); `sources` where the `BAD_INPUT` samples can come from.
#[allow(clippy::too_many_arguments)] // two call sites, each with the replay's results
pub fn compensation_notes(
    name: &str,
    flag_counts: &[u64; 8],
    samples: u64,
    max_gap_s: f64,
    output: &str,
    never_consequence: &str,
    sources: &BadInputSources,
    reach: Option<&OutsideReach>,
) -> Vec<String> {
    use fogtemp_core::Flags;
    let count = |flag: Flags| flag_counts[flag.0.trailing_zeros() as usize & 7];
    if samples == 0 {
        return Vec::new();
    }
    if count(Flags::WARMING_UP) == samples {
        return vec![never_corrected_note(name, never_consequence, flag_counts, samples, max_gap_s)];
    }
    let mut notes = Vec::new();
    let bad = count(Flags::BAD_INPUT);
    if bad > 0 {
        notes.push(bad_input_note(name, bad, samples, output, sources));
    }
    let (stale, outside) = (count(Flags::TEMP_STALE), count(Flags::OUTSIDE_HULL));
    if stale > 0 {
        let flagged = format!("flag TEMP_STALE in {output}");
        notes.push(stale_temperature_note(name, stale, samples, max_gap_s, &flagged));
    }
    if outside > 0 {
        notes.push(outside_note(name, outside, samples, reach, &format!("flag OUTSIDE_HULL in {output}")));
    }
    notes
}

/// Whether model axis `axis` does not use dT/dt: a polynomial in T alone without a mesh
/// (`cubic-t`, or a stepwise fit that admitted no rate term).
pub fn ignores_rate(axis: &fogtemp_core::Axis<'_>) -> bool {
    axis.mesh.is_none() && axis.poly.is_some_and(|p| p.terms().all(|t| t.rate_power == 0))
}

/// The note for `outside` of `samples` samples outside the calibrated region (`flagged`
/// says where the flag can be seen).
pub fn outside_region_note(name: &str, outside: u64, samples: u64, flagged: &str) -> String {
    format!(
        "{name}: {outside} of {samples} samples ({} %) lie outside the model's calibrated (T, dT/dt) \
         region ({flagged}): the model is extrapolated there",
        share_percent(outside, samples)
    )
}

/// `part` of `whole` as a percentage to one decimal, or to the first significant digit
/// under 0.1 % ("0.04", not "0.0" for a share that is not zero).
pub fn share_percent(part: u64, whole: u64) -> String {
    let percent = 100.0 * part as f64 / whole.max(1) as f64;
    if percent > 0.0 && percent < 0.1 {
        let digits = (-percent.log10().floor()) as usize;
        format!("{percent:.digits$}")
    } else {
        format!("{percent:.1}")
    }
}

impl RunFeatures {
    /// Removes a known true rate about the gyro's input axis (the Earth rate's projection in
    /// the run's position, or a turntable's rate), deg/h, from axis `axis`'s gyro means and
    /// targets, so that a model fitted on them is the bias alone and runs in different
    /// positions agree (`fit --runs`).
    pub fn subtract_input_rate(&mut self, axis: usize, rate_dph: f64) {
        if let Some((features, targets)) = self.axes.get_mut(axis) {
            features.iter_mut().for_each(|f| f.gyro_mean_dph -= rate_dph);
            targets.iter_mut().for_each(|t| *t -= rate_dph);
            self.input_rate_subtracted_dph.resize(self.axes.len(), 0.0);
            if let Some(total) = self.input_rate_subtracted_dph.get_mut(axis) {
                *total += rate_dph;
            }
        }
    }
}

/// Steps between consecutive rows longer than the feature tracker's `max_gap_s`: after each
/// the tracker starts again (a logger that stalled, a capture that lost time, a clock that
/// jumped), so the time is not calibration data. Counted so that a technician is told.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TimeGaps {
    /// The threshold, seconds (the tracker's `max_gap_s`).
    pub longer_than_s: f64,
    /// How many.
    pub count: u64,
    /// Total time in them, seconds.
    pub total_s: f64,
    /// The longest, seconds, and the line of the row after it (0 when there is none).
    pub largest_s: f64,
    /// See `largest_s`; for a run given as arrays, the sample's 0-based index.
    pub largest_before_line: u64,
    /// The run was given as arrays: `largest_before_line` is a sample index, and the note
    /// says so.
    pub in_samples: bool,
}

impl TimeGaps {
    /// Whether most of the steps between `rows` rows are gaps (more than two rows): a time
    /// column read in the wrong unit, ms read as s.
    pub fn mostly_gaps(&self, rows: u64) -> bool {
        rows > 2 && self.count * 2 > rows
    }

    /// What a technician is told about the gaps of the log `path` (`None` without gaps): the
    /// command line's `note:` and Python's warning.
    pub fn note(&self, path: &Path) -> Option<String> {
        self.note_then(path, "features restart after each")
    }

    /// The note of [`Self::note`] ending in `consequence` (what the gaps did).
    pub fn note_then(&self, path: &Path, consequence: &str) -> Option<String> {
        self.note_against(path, &format!("the tracker's max gap of {} s", self.longer_than_s), consequence)
    }

    /// The note with the threshold described as `threshold` (e.g. "2 s").
    pub fn note_against(&self, path: &Path, threshold: &str, consequence: &str) -> Option<String> {
        let place = if self.in_samples { "sample" } else { "line" };
        (self.count > 0).then(|| {
            format!(
                "{}: {} gap{} in the time stamps longer than {threshold}, {} s in all, \
                 the longest {} s before {place} {}; {consequence}",
                path.display(),
                self.count,
                if self.count == 1 { "" } else { "s" },
                seconds(self.total_s),
                seconds(self.largest_s),
                self.largest_before_line
            )
        })
    }

    /// No gaps yet; steps longer than `longer_than_s` will count.
    pub fn new(longer_than_s: f64) -> Self {
        Self { longer_than_s, ..Self::default() }
    }

    /// Counts the step from `previous_s` to the row at `time_s` on `line`.
    pub fn observe(&mut self, previous_s: Option<f64>, time_s: f64, line: u64) {
        let Some(step) = previous_s.map(|p| time_s - p) else { return };
        if step > self.longer_than_s {
            self.count += 1;
            self.total_s += step;
            if step > self.largest_s {
                self.largest_s = step;
                self.largest_before_line = line;
            }
        }
    }
}

/// Reads one log and computes per-axis features and targets. `progress(bytes, rows)` as in
/// `read_log_with_progress`.
///
/// # Errors
/// Ingest errors (with file, line, column), or bad feature settings.
pub fn extract_run(
    path: &Path,
    config: &CalibrationConfig,
    progress: impl FnMut(u64, u64),
) -> Result<RunFeatures, CalError> {
    extract_with(path, config, |visit| read_log_with_progress(path, &config.ingest, visit, progress))
}

/// [`extract_run`] that adds the log's bytes to `digest` as they are read (the model's input
/// digest, in one read of the log) and keeps the log's own digest in [`RunFeatures::digest`].
/// `digest` is left as it was when the read fails.
///
/// # Errors
/// As [`extract_run`].
pub fn extract_run_digested(
    path: &Path,
    config: &CalibrationConfig,
    digest: &mut InputDigest,
    progress: impl FnMut(u64, u64),
) -> Result<RunFeatures, CalError> {
    let mut log_digest = None;
    let mut run = extract_with(path, config, |visit| {
        let (report, this_log) = read_log_digested(path, &config.ingest, digest, visit, progress)?;
        log_digest = Some(this_log);
        Ok(report)
    })?;
    run.digest = log_digest;
    Ok(run)
}

/// [`extract_run`] from any reader; `name` stands for the source in errors and in
/// [`RunFeatures::path`].
///
/// # Errors
/// As [`extract_run`].
pub fn extract_run_from<R: Read + Send>(
    reader: R,
    name: &Path,
    config: &CalibrationConfig,
) -> Result<RunFeatures, CalError> {
    extract_with(name, config, |visit| read_from(reader, name, &config.ingest, visit, |_, _| {}))
}

/// Features and targets of one run whose rows `read` hands to the visitor it is given.
pub(crate) fn extract_with(
    path: &Path,
    config: &CalibrationConfig,
    read: impl FnOnce(&mut dyn FnMut(&Row<'_>) -> Result<(), CalError>) -> Result<IngestReport, CalError>,
) -> Result<RunFeatures, CalError> {
    let axes = config.ingest.format.gyro_columns.len();
    let mut streams =
        (0..axes).map(|_| AxisFeatureStream::new(&config.features)).collect::<Result<Vec<_>, _>>()?;
    let max_gap_s = f64::from(config.features.max_gap_s);
    let mut guards: Vec<SpikeGuard> = (0..axes).map(|_| SpikeGuard::new(max_gap_s)).collect();
    let mut silences: Vec<TemperatureSilences> =
        (0..axes).map(|_| TemperatureSilences::new(max_gap_s)).collect();
    let mut gaps = TimeGaps::new(max_gap_s);
    let mut temperature_steps = vec![TemperatureSteps::default(); axes];
    let mut previous_s = None;
    let ingest = read(&mut |row: &Row<'_>| {
        gaps.observe(previous_s, row.time_s, row.line);
        previous_s = Some(row.time_s);
        for (axis, (((stream, guard), silence), steps)) in
            streams.iter_mut().zip(&mut guards).zip(&mut silences).zip(&mut temperature_steps).enumerate()
        {
            steps.observe(row.temp_c_for_axis(axis));
            let sample = Sample {
                time_s: row.time_s,
                gyro_dph: row.gyros_dph[axis],
                temp_c: row.temp_c_for_axis(axis),
                line: row.line,
            };
            guard.push(sample, &mut |s| {
                silence.observe(&s);
                stream.push(s.time_s, s.gyro_dph, s.temp_c);
            });
        }
        Ok(())
    })?;
    let mut temperature_spikes = Vec::with_capacity(axes);
    let mut temperature_silences = Vec::with_capacity(axes);
    let mut gyro_outliers = Vec::with_capacity(axes);
    let axes = streams
        .into_iter()
        .zip(guards)
        .zip(silences)
        .map(|((mut stream, guard), mut silence)| {
            temperature_spikes.push(guard.finish(&mut |s| {
                silence.observe(&s);
                stream.push(s.time_s, s.gyro_dph, s.temp_c);
            }));
            temperature_silences.push(silence.finish());
            let mut points = stream.finish();
            gyro_outliers.push(screen_gyro_means(&mut points));
            let targets = smoothed_gyro_dph(&points, config.target_window_s);
            (points, targets)
        })
        .collect();
    Ok(RunFeatures {
        path: path.to_path_buf(),
        ingest,
        gaps,
        axes,
        input_rate_subtracted_dph: Vec::new(),
        temperature_spikes,
        temperature_silences,
        gyro_outliers,
        temperature_steps,
        digest: None,
    })
}

/// The resolution a run's temperature readings show: the smallest step between
/// consecutive readings that differ, and how many such changes there were. A staircase of
/// whole degrees (a 1 C sensor, or decimals cut off by a decimal comma in a comma-separated
/// log: review24a F5) gives rates no 100 s window can resolve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemperatureSteps {
    /// The smallest |change| between consecutive finite readings that differ, deg C
    /// (infinite without a change).
    pub smallest_c: f64,
    /// Changes between consecutive finite readings.
    pub changes: u64,
    /// Finite readings: a staircase holds each value over several of them, a fine sensor
    /// read seldom changes at nearly every one (review25a 10).
    pub readings: u64,
    last_c: Option<f64>,
}

impl Default for TemperatureSteps {
    fn default() -> Self {
        Self { smallest_c: f64::INFINITY, changes: 0, readings: 0, last_c: None }
    }
}

impl TemperatureSteps {
    /// One reading (NaN: none).
    pub fn observe(&mut self, temp_c: f64) {
        if !temp_c.is_finite() {
            return;
        }
        self.readings += 1;
        if let Some(last) = self.last_c.filter(|&last| last != temp_c) {
            self.smallest_c = self.smallest_c.min((temp_c - last).abs());
            self.changes += 1;
        }
        self.last_c = Some(temp_c);
    }
}

/// A duration in a note: whole seconds, but a tenth under 10 s (a 3.5 s gap is not "4 s").
fn seconds(s: f64) -> String {
    if s < 10.0 {
        format!("{s:.1}")
    } else {
        format!("{s:.0}")
    }
}

/// Stretches longer than the tracker's `max_gap_s` without a temperature reading while rows
/// went on (a temperature channel that dropped out; gaps in the rows themselves are
/// [`TimeGaps`] of the log): the tracker restarts after each, and no calibration point comes
/// from them. A stretch that lasts to the end of the log counts up to its last row.
#[derive(Clone, Copy, Debug)]
struct TemperatureSilences {
    gaps: TimeGaps,
    /// The last reading's time, and the last row's time and line since it (if any).
    last_reading_s: Option<f64>,
    last_row: Option<(f64, u64)>,
}

impl TemperatureSilences {
    fn new(max_gap_s: f64) -> Self {
        Self { gaps: TimeGaps::new(max_gap_s), last_reading_s: None, last_row: None }
    }

    fn observe(&mut self, sample: &Sample) {
        if sample.temp_c.is_finite() {
            if self.last_row.is_some() {
                self.gaps.observe(self.last_reading_s, sample.time_s, sample.line);
            }
            self.last_reading_s = Some(sample.time_s);
            self.last_row = None;
        } else if self.last_reading_s.is_some() {
            self.last_row = Some((sample.time_s, sample.line));
        }
    }

    fn finish(mut self) -> TimeGaps {
        if let Some((time_s, line)) = self.last_row {
            self.gaps.observe(self.last_reading_s, time_s, line);
        }
        self.gaps
    }
}

/// The calibration points of one axis over all runs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CalibrationPoints {
    /// (T, dT/dt, smoothed gyro target) per point.
    pub points: Vec<MeshPoint>,
    /// The run index of each point.
    pub run_of: Vec<usize>,
    /// How many tracker blocks of time the points stand for: each point counts the whole
    /// blocks since the previous feature update of its run and segment (at least 1, at most a
    /// smoothing window's worth). Equal to the point count for a log whose temperature fills
    /// every block; larger for sparse logs (bursts minutes apart), where each point stands for
    /// all the time since the last one.
    pub block_equivalents: f64,
    /// Whether each point may set the calibrated region: its features come from a full
    /// tracker window, or, in a segment (a run, or its part after a tracker restart) that
    /// never fills one, such as a run shorter than the window, it comes half a window or more
    /// after the segment's first feature ([`calibration_points`]).
    pub in_region: Vec<bool>,
}

impl CalibrationPoints {
    /// The points that define the calibrated region: those [`Self::in_region`] marks (full
    /// tracker windows, and a never-full segment's points from half a window after its first
    /// feature on), or all of
    /// them when those do not span an area. A partial window's dT/dt is a line fitted to
    /// fewer blocks, its noise larger by (blocks in the window / blocks so far)^1.5: the
    /// demo's one 0.06 C quantum at 12 s, 13 blocks into a 100-block window, read -0.12 C/min
    /// in a run that only heats, and its convex hull claimed cooling as calibrated at every
    /// temperature. Those points are still fitted. A run shorter than the window has no full
    /// window at all: leaving every point of it out put a 65 s run at 13 C outside the region
    /// of a model fitted on it (review24a F1); from half a window on, its rates are at most
    /// 2^1.5 = 2.8 times as noisy as a full window's.
    pub fn region_points(&self) -> Vec<MeshPoint> {
        if self.region_leaves_out_points() {
            self.points.iter().zip(&self.in_region).filter(|(_, &f)| f).map(|(p, _)| *p).collect()
        } else {
            self.points.clone()
        }
    }

    /// Whether [`Self::region_points`] leaves points out: some are not [`Self::in_region`]
    /// and those that are span an area.
    pub fn region_leaves_out_points(&self) -> bool {
        if self.in_region.iter().all(|&f| f) {
            return false;
        }
        let plane: Vec<(f32, f32)> = self
            .points
            .iter()
            .zip(&self.in_region)
            .filter(|(_, &f)| f)
            .map(|(p, _)| (p.temp_c as f32, p.rate_c_per_min as f32))
            .collect();
        crate::blob::calibrated_region(&plane).len() >= 3
    }

    /// Effective number of independent targets for the stepwise tests: one per smoothing
    /// window of `target_window_s` covered (points are one per block, and consecutive targets
    /// share most of their window).
    pub fn n_eff(&self, block_s: f64, target_window_s: f64) -> f64 {
        self.block_equivalents * (block_s / target_window_s).min(1.0)
    }
}

/// [`calibration_points`] with `config`'s tracker and smoothing settings.
pub fn calibration_points_of(
    runs: &[RunFeatures],
    axis: usize,
    config: &CalibrationConfig,
) -> CalibrationPoints {
    let window_s = f64::from(config.features.window_s);
    let block_s = window_s / f64::from(config.features.block_count.max(1));
    calibration_points(runs, axis, config.full_windows_only, block_s, window_s, config.target_window_s)
}

/// Calibration points of one axis over all runs, with the run index of each and the time
/// they cover (in tracker blocks of `block_s`, at most `target_window_s` per point), and
/// whether each may set the calibrated region (`window_s` is the tracker's feature window).
/// Runs come in [`canonical_run_order`], each run's points in time order.
pub fn calibration_points(
    runs: &[RunFeatures],
    axis: usize,
    full_windows_only: bool,
    block_s: f64,
    window_s: f64,
    target_window_s: f64,
) -> CalibrationPoints {
    let max_blocks = (target_window_s / block_s).round().max(1.0);
    let mut out = CalibrationPoints::default();
    for r in canonical_run_order(runs, axis) {
        let Some((features, targets)) = runs[r].axes.get(axis) else { continue };
        let never_full = segments_never_full(features);
        let mut segment_start_s = f64::NAN;
        let mut previous: Option<&FeaturePoint> = None;
        for (f, &target) in features.iter().zip(targets) {
            if previous.is_none_or(|p| p.segment != f.segment) {
                // Counted from the segment's first feature (a few blocks after the tracker's
                // start): half a window from there is at least half a window of blocks.
                segment_start_s = f.time_s;
            }
            // Whole blocks since the previous update of this segment (rounded: block close
            // times are block multiples up to the microsecond clock).
            let blocks = match previous {
                Some(p) if p.segment == f.segment => {
                    ((f.time_s - p.time_s) / block_s).round().clamp(1.0, max_blocks)
                }
                _ => 1.0,
            };
            previous = Some(f);
            if target.is_finite() && (f.window_full || !full_windows_only) {
                out.points.push(MeshPoint {
                    temp_c: f.temp_c,
                    rate_c_per_min: f.rate_c_per_min,
                    value_dph: target,
                });
                out.run_of.push(r);
                let half_window = f.time_s - segment_start_s >= 0.5 * window_s;
                out.in_region.push(f.window_full || (never_full.contains(&f.segment) && half_window));
                out.block_equivalents += blocks;
            }
        }
    }
    out
}

/// The segments (tracker restarts) of one run's features none of whose points has a full
/// window.
fn segments_never_full(features: &[FeaturePoint]) -> std::collections::BTreeSet<u32> {
    let mut full = std::collections::BTreeSet::new();
    let mut seen = std::collections::BTreeSet::new();
    for f in features {
        seen.insert(f.segment);
        if f.window_full {
            full.insert(f.segment);
        }
    }
    seen.difference(&full).copied().collect()
}

/// The runs in an order fixed by their content (a hash of the axis's first feature point and
/// point count; equal contents by index), not by the order the logs were given in: the
/// mesh's greedy thinning keeps the first of nearby points and least-squares sums round in
/// the order of their terms, so the same logs in another order gave another model (seed 5's
/// null case: 950 vs 947 mesh nodes; docs/calibration-testbed.md).
fn canonical_run_order(runs: &[RunFeatures], axis: usize) -> Vec<usize> {
    let key = |r: &RunFeatures| {
        r.axes.get(axis).map_or(0, |(features, targets)| {
            let first = features.first();
            crate::mesh_fit::content_hash(&[
                first.map_or(0, |f| f.temp_c.to_bits()),
                first.map_or(0, |f| f.rate_c_per_min.to_bits()),
                targets.first().map_or(0, |t| t.to_bits()),
                features.len() as u64,
            ])
        })
    };
    let mut order: Vec<usize> = (0..runs.len()).collect();
    order.sort_by_cached_key(|&r| (key(&runs[r]), r));
    order
}

/// Normalisation mapping the points' bounding box to [-1, 1] on both axes.
///
/// # Errors
/// [`CalError::DegenerateMesh`] if there are no points.
pub fn choose_normalisation(points: &[MeshPoint]) -> Result<Normalisation, CalError> {
    if points.is_empty() {
        return Err(CalError::DegenerateMesh { reason: "no calibration points", points: 0 });
    }
    let span = |f: &dyn Fn(&MeshPoint) -> f64| {
        let (lo, hi) =
            points.iter().map(f).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        ((lo + hi) / 2.0, ((hi - lo) / 2.0).max(1e-6))
    };
    let (t_mid, t_half) = span(&|p| p.temp_c);
    let (r_mid, r_half) = span(&|p| p.rate_c_per_min);
    Ok(Normalisation {
        temp_offset_c: t_mid as f32,
        temp_scale_per_c: (1.0 / t_half) as f32,
        rate_offset_c_per_min: r_mid as f32,
        rate_scale_per_c_per_min: (1.0 / r_half) as f32,
    })
}

/// What `fit` did for one axis.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct AxisFitReport {
    /// Calibration points offered.
    pub points: usize,
    /// Polynomial fit, when the method has one.
    pub poly: Option<PolyFit>,
    /// Mesh nodes (after thinning, merging and flat-triangle removal).
    pub mesh_nodes: usize,
    /// Mesh triangles.
    pub mesh_triangles: usize,
    /// Points merged as duplicates.
    pub merged_duplicates: usize,
    /// Points dropped for flat hull triangles.
    pub dropped_flat: usize,
    /// RMS of model minus target at all calibration points, deg/h.
    pub residual_rms_dph: f64,
    /// Largest |model - target|, deg/h.
    pub residual_max_abs_dph: f64,
    /// Estimated noise of the smoothed targets used for thinning, deg/h (NaN if unknown).
    pub target_noise_dph: f64,
    /// The method fitted.
    pub method: Method,
    /// How `auto` chose the method (cross-validation table); null when it was given.
    pub selection: Option<Selection>,
    /// How the mesh's smoothness weight was chosen (least-squares nodes only).
    pub mesh_smoothing: Option<crate::mesh_fit::MeshSmoothing>,
    /// Steiner nodes a plain mesh got where its triangles could not carry the polynomial part
    /// its node fit leaves free (`refine`); null when not refined.
    pub mesh_refinement: Option<crate::refine::Refinement>,
}

/// One fitted axis: what goes into the blob and what the fit did.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedAxis {
    /// The axis section of the blob.
    pub model: AxisModel,
    /// What the fit did.
    pub report: AxisFitReport,
}

/// The terms `(temperature power, rate power)` a plain mesh's smoothness penalty leaves free:
/// the polynomial's stepwise selection on the same points, restricted to the physical form
/// b(T) + c(T) dT/dt (static bias, Shupe and lag terms: rate power at most one,
/// docs/physics.md). A polynomial that cannot be fitted leaves the planes only (none).
fn mesh_free_terms(poly: Option<&PolyFit>) -> Vec<(u8, u8)> {
    poly.map(|f| f.terms.iter().filter(|t| t.rate_power <= 1).map(|t| (t.temp_power, t.rate_power)).collect())
        .unwrap_or_default()
}

/// Most Steiner nodes refinement may add: as many as thinning may place (so the mesh at most
/// doubles; the node fit's dense solve grows with the cube of the count).
fn max_refinement_nodes(thinning: Thinning) -> usize {
    match thinning {
        Thinning::Greedy(g) => g.max_nodes,
        Thinning::GreedyAuto { max_nodes, .. } => max_nodes,
        Thinning::Paper { .. } => GreedyThinning::default().max_nodes,
    }
}

/// The surface a plain mesh's refinement aims to carry: the least-squares fit to `points` of
/// the terms its node fit leaves free ([`mesh_free_terms`], with the constant and the planes),
/// as `(temperature power, rate power, coefficient)` on the normalised axes. Refitted, not the
/// stepwise polynomial's own coefficients: those were fitted jointly with its other terms (rate
/// powers above one), without which they are not the fit of these. `None` if the fit fails.
fn free_surface_terms(
    points: &[MeshPoint],
    normalisation: &Normalisation,
    free: &[(u8, u8)],
) -> Option<Vec<(u8, u8, f64)>> {
    let planes = [(0, 0), (1, 0), (0, 1)];
    let terms: Vec<(u8, u8)> =
        planes.iter().chain(free.iter().filter(|t| !planes.contains(t))).copied().collect();
    let xy: Vec<(f64, f64)> = points
        .iter()
        .map(|p| crate::poly_fit::normalised_f64(normalisation, p.temp_c, p.rate_c_per_min))
        .collect();
    let design = nalgebra::DMatrix::from_fn(points.len(), terms.len(), |r, c| {
        let (x, y) = xy[r];
        x.powi(i32::from(terms[c].0)) * y.powi(i32::from(terms[c].1))
    });
    let target = nalgebra::DVector::from_iterator(points.len(), points.iter().map(|p| p.value_dph));
    let coefficients = design.svd(true, true).solve(&target, 1e-12).ok()?;
    coefficients
        .iter()
        .all(|c| c.is_finite())
        .then(|| terms.iter().zip(coefficients.iter()).map(|(&(i, j), &c)| (i, j, c)).collect())
}

/// The polynomial `terms` (`free_surface_terms`) as a function of the normalised `(x, y)`.
fn surface_of(terms: &[(u8, u8, f64)]) -> impl Fn(f64, f64) -> f64 + '_ {
    move |x, y| terms.iter().map(|&(i, j, c)| c * x.powi(i32::from(i)) * y.powi(i32::from(j))).sum()
}

/// Fits one axis to its calibration points with `config.method`.
///
/// # Errors
/// Fit or mesh errors ([`CalError::Fit`], [`CalError::DegenerateMesh`]);
/// [`CalError::AutoNeedsRuns`] for [`Method::Auto`], which chooses by replaying whole runs
/// ([`fit_model`]).
pub fn fit_axis(
    calibration: &CalibrationPoints,
    config: &CalibrationConfig,
    target_noise_dph: f64,
) -> Result<FittedAxis, CalError> {
    let (points, runs) = (calibration.points.as_slice(), calibration.run_of.as_slice());
    let mut normalisation = choose_normalisation(points)?;
    if config.rate_axis_weight.is_finite() && config.rate_axis_weight > 0.0 {
        normalisation.rate_scale_per_c_per_min *= config.rate_axis_weight as f32;
    }
    // One independent target per smoothing window (points are one per block).
    let block_s = f64::from(config.features.window_s) / f64::from(config.features.block_count);
    let n_eff = calibration.n_eff(block_s, config.target_window_s);
    if config.method == Method::Auto {
        return Err(CalError::AutoNeedsRuns);
    }
    let poly = match config.method {
        Method::Poly | Method::Hybrid => Some(fit_poly(points, &normalisation, config.poly, n_eff)?),
        Method::CubicT => {
            enough_temperatures_for_a_cubic(points)?;
            Some(fit_poly(points, &normalisation, TermSelection::CubicInTemperature, n_eff)?)
        }
        Method::Mesh | Method::Auto => None,
    };
    let residual_points: Vec<MeshPoint> = points
        .iter()
        .map(|p| MeshPoint {
            value_dph: p.value_dph
                - poly.as_ref().map_or(0.0, |f| f.evaluate(&normalisation, p.temp_c, p.rate_c_per_min)),
            ..*p
        })
        .collect();
    let auto_tolerance_dph = |noise_multiple: f64| {
        if target_noise_dph.is_finite() && target_noise_dph > 0.0 {
            noise_multiple * target_noise_dph
        } else {
            GreedyThinning::default().tolerance_dph
        }
    };
    // A hybrid needs no mesh when the polynomial already leaves no more than the tolerance
    // (a mesh of its residuals would only carry their noise into the compensation).
    let poly_is_enough = match (config.method, config.thinning) {
        (Method::Hybrid, Thinning::GreedyAuto { noise_multiple, .. }) => {
            rms(residual_points.iter().map(|p| p.value_dph)) <= auto_tolerance_dph(noise_multiple)
        }
        (Method::Hybrid, Thinning::Greedy(g)) if g.stop_on_rms => {
            rms(residual_points.iter().map(|p| p.value_dph)) <= g.tolerance_dph
        }
        _ => false,
    };
    let mut mesh_smoothing = None;
    let mut mesh_refinement = None;
    let mesh = match config.method {
        Method::Poly | Method::CubicT | Method::Auto => None,
        // Otherwise (least-squares nodes) cross-validation decides whether it keeps its mesh.
        Method::Hybrid if poly_is_enough => None,
        Method::Mesh | Method::Hybrid => {
            let keep = match config.thinning {
                Thinning::Paper { fast_rate_c_per_min, settled_every } => {
                    let stride = (config.target_window_s / block_s).round().max(1.0) as usize;
                    thin_paper(&residual_points, runs, stride, fast_rate_c_per_min, settled_every)
                }
                Thinning::Greedy(g) => thin_greedy(&residual_points, &normalisation, &g)?.keep,
                Thinning::GreedyAuto { noise_multiple, max_nodes } => {
                    let g = GreedyThinning {
                        tolerance_dph: auto_tolerance_dph(noise_multiple),
                        max_nodes,
                        stop_on_rms: true,
                        ..GreedyThinning::default()
                    };
                    thin_greedy(&residual_points, &normalisation, &g)?.keep
                }
            };
            let mut nodes: Vec<MeshPoint> = keep.iter().map(|&i| residual_points[i]).collect();
            let hybrid = config.method == Method::Hybrid;
            // A plain mesh's node fit leaves the polynomial's terms free: that polynomial, once.
            let free_poly = if hybrid || !config.least_squares_nodes {
                None
            } else {
                fit_poly(points, &normalisation, config.poly, n_eff).ok()
            };
            // Refined: Steiner nodes tied to the thinned nodes' mesh (`refine`), whose values
            // the node fit below fits as without refinement.
            let (mut mesh, refined) = match &free_poly {
                Some(poly) if config.refine_mesh => {
                    let tolerance_dph = crate::refine::SURFACE_TOLERANCE_NOISE * auto_tolerance_dph(1.0);
                    let terms = free_surface_terms(points, &normalisation, &mesh_free_terms(Some(poly)))
                        .ok_or(CalError::DegenerateMesh {
                            reason: "mesh refinement surface fit failed",
                            points: nodes.len(),
                        })?;
                    let surface = surface_of(&terms);
                    let crate::refine::Refined { mesh: fine, coarse, report } =
                        crate::refine::refine_for_surface(
                            &mut nodes,
                            &normalisation,
                            &surface,
                            tolerance_dph,
                            max_refinement_nodes(config.thinning),
                        )?;
                    mesh_refinement = Some(report);
                    if report.added_nodes > 0 {
                        // The tie keeps the coarse geometry; the node fit below fits a copy's values.
                        let tie = crate::refine::tie(&fine, coarse, &surface);
                        (tie.coarse.clone(), Some((fine, tie)))
                    } else {
                        (coarse, None)
                    }
                }
                _ => (build_mesh(&nodes, &normalisation)?, None),
            };
            if config.least_squares_nodes {
                let targets: Vec<(f32, f32, f64)> = residual_points
                    .iter()
                    .map(|p| {
                        let (x, y) = crate::mesh::normalised(p, &normalisation);
                        (x, y, p.value_dph)
                    })
                    .collect();
                // Guard: one smoothing window of points (targets that share raw samples).
                let cv = crate::mesh_fit::MeshCv {
                    guard_points: (config.target_window_s / block_s).round().max(0.0) as usize,
                    given_relative_weight: config.mesh_relative_weight,
                    repeats: config.mesh_cv_repeats,
                    first_salt: config.mesh_cv_salt,
                    ..crate::mesh_fit::MeshCv::default()
                };
                // A hybrid's residual has the polynomial's terms fitted already.
                let free_terms = mesh_free_terms(free_poly.as_ref());
                let (_, smoothing) = crate::mesh_fit::fit_node_values_cv_with_free_terms(
                    &mut mesh,
                    &targets,
                    runs,
                    hybrid,
                    cv,
                    &free_terms,
                )?;
                // The refined mesh: its values refitted once, at the weight the coarse mesh's
                // cross-validation chose, through the refined mesh's own interpolation.
                if let (Some((mut fine, tie)), Some(relative)) = (refined, smoothing.relative_weight) {
                    crate::mesh_fit::fit_node_values_tied_at(
                        &mut fine,
                        &tie,
                        &targets,
                        runs,
                        relative,
                        &free_terms,
                    )?;
                    mesh = fine;
                }
                let keep = !smoothing.no_mesh();
                mesh_smoothing = Some(smoothing);
                keep.then_some(mesh)
            } else {
                Some(mesh)
            }
        }
    };
    // Stored gradients need a mesh (and format version 3): an axis without one stores 0, so a
    // polynomial's blob stays version 2, byte for byte as before.
    let outside_policy = match (config.method, config.mesh_outside) {
        (Method::Hybrid, _) => OutsidePolicy::Zero,
        (_, OutsidePolicy::StoredGradients) if mesh.is_none() => OutsidePolicy::NearestHull,
        (_, policy) => policy,
    };
    // The calibrated region, from the points of full tracker windows
    // ([`CalibrationPoints::region_points`]), and its range; outside it the policy holds or
    // continues the polynomial from its boundary (no runaway; flagged OUTSIDE_HULL). Points
    // without an area (collinear: one warm-up run) have no region, and a polynomial without
    // one can only extrapolate. A mesh's nodes come from every point (thinning them from the
    // region's points alone was measured worse on the testbed: docs/calibration-testbed.md);
    // the core flags a mesh's features outside the region too.
    let region_points = calibration.region_points();
    let range = |f: &dyn Fn(&MeshPoint) -> f64| {
        region_points.iter().map(f).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)))
    };
    let (temp_min, temp_max) = range(&|p| p.temp_c);
    let (rate_min, rate_max) = range(&|p| p.rate_c_per_min);
    // A polynomial in T alone (cubic-t, or a stepwise fit that admitted no rate term) is
    // calibrated over the rectangle of the temperature and rate ranges: continued from the
    // hull's nearest point, a query cooling faster than any run took the value of a boundary
    // point at another temperature, so a model without the rate changed with it (review21 F1,
    // 0.004 deg/h at -0.5 C/min), and combinations inside both ranges were flagged (F2).
    // From the rectangle's nearest point the rate moves alone and the value is the cubic's.
    let t_alone = mesh.is_none()
        && poly.as_ref().is_some_and(|p| p.blob_terms().iter().all(|term| term.rate_power == 0));
    let region_plane: Vec<(f32, f32)> = if t_alone && region_points.len() >= 3 {
        [(temp_min, rate_min), (temp_max, rate_min), (temp_max, rate_max), (temp_min, rate_max)]
            .iter()
            .map(|&(temp_c, rate_c_per_min)| {
                crate::mesh::normalised(&MeshPoint { temp_c, rate_c_per_min, value_dph: 0.0 }, &normalisation)
            })
            .collect()
    } else {
        region_points.iter().map(|p| crate::mesh::normalised(p, &normalisation)).collect()
    };
    let region = crate::blob::calibrated_region(&region_plane);
    let poly_outside =
        if region.len() >= 3 { config.poly_outside } else { fogtemp_core::PolyOutside::Extrapolate };
    let mut axis = AxisModel {
        features: config.features,
        normalisation,
        outside_policy,
        poly: poly.as_ref().map(|p| p.blob_terms()).unwrap_or_default(),
        mesh: mesh.clone(),
        provenance: AxisProvenance {
            fit_point_count: points.len() as u32,
            residual_rms_dph: 0.0,
            residual_max_abs_dph: 0.0,
            temp_min_c: temp_min as f32,
            temp_max_c: temp_max as f32,
            rate_min_c_per_min: rate_min as f32,
            rate_max_c_per_min: rate_max as f32,
        },
        region,
        poly_outside,
    };
    // Residuals of the model as the firmware evaluates it (f32, through the core).
    let probe = encode(&ModelFile {
        tool_version: String::new(),
        input_digest: [0; 32],
        axes: vec![axis.clone()],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    })?;
    let model = Model::from_bytes(&probe).map_err(CalError::SelfCheck)?;
    let core_axis = model.axis(0).map_err(CalError::SelfCheck)?;
    let mut hint = fogtemp_core::WalkHint::default();
    let residuals: Vec<f64> = points
        .iter()
        .map(|p| {
            let v = core_axis
                .evaluate(p.temp_c as f32, p.rate_c_per_min as f32, &mut hint)
                .map_or(f64::NAN, |e| f64::from(e.value_dph));
            v - p.value_dph
        })
        .collect();
    let residual_rms_dph =
        (residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len().max(1) as f64).sqrt();
    let residual_max_abs_dph = residuals.iter().fold(0.0f64, |m, r| m.max(r.abs()));
    axis.provenance.residual_rms_dph = residual_rms_dph as f32;
    axis.provenance.residual_max_abs_dph = residual_max_abs_dph as f32;
    let report = AxisFitReport {
        points: points.len(),
        mesh_nodes: mesh.as_ref().map_or(0, |m| m.vertices.len()),
        mesh_triangles: mesh.as_ref().map_or(0, |m| m.triangles.len()),
        merged_duplicates: mesh.as_ref().map_or(0, |m| m.merged_duplicates),
        dropped_flat: mesh.as_ref().map_or(0, |m| m.dropped_flat.len()),
        poly,
        residual_rms_dph,
        residual_max_abs_dph,
        target_noise_dph,
        method: config.method,
        selection: None,
        mesh_smoothing,
        mesh_refinement,
    };
    Ok(FittedAxis { model: axis, report })
}

/// A fitted model: the blob and, per axis, what the fit did.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedModel {
    /// The encoded model (validated by the core before it is returned).
    pub blob: Vec<u8>,
    /// Per axis, what the fit did.
    pub axes: Vec<AxisFitReport>,
}

/// Fits every axis over all runs and encodes the blob. With [`Method::Auto`], each axis's
/// method is chosen by leave-one-run-out cross-validation ([`crate::selection::select`],
/// default [`SelectionOptions`]): the runs' logs must be readable again at their paths.
///
/// # Errors
/// As [`fit_axis`] and [`encode`]; with [`Method::Auto`], as [`crate::selection::select`].
pub fn fit_model(
    runs: &[RunFeatures],
    config: &CalibrationConfig,
    input_digest: [u8; 32],
) -> Result<FittedModel, CalError> {
    fit_model_with(runs, config, input_digest, &SelectionOptions::default(), |_, _| {})
}

/// [`fit_model`] with the cross-validation of [`Method::Auto`] set up by `selection`
/// (groups, candidates); `progress(fold, folds)` as each fold starts.
///
/// # Errors
/// As [`fit_model`].
pub fn fit_model_with(
    runs: &[RunFeatures],
    config: &CalibrationConfig,
    input_digest: [u8; 32],
    selection: &SelectionOptions,
    progress: impl FnMut(usize, usize),
) -> Result<FittedModel, CalError> {
    fit_model_replaying(runs, config, input_digest, selection, progress, &replay_files(runs, config))
}

/// The held-out replay of runs read from files ([`fit_model_with`]'s): run `run` of `runs`
/// read again from its path and replayed through `models`.
pub fn replay_files<'a>(
    runs: &'a [RunFeatures],
    config: &'a CalibrationConfig,
) -> impl Fn(usize, &[&Model<'_>]) -> Result<Replay, CalError> + Sync + 'a {
    move |run, models| match runs.get(run) {
        Some(r) => replay_models(&r.path, models, &config.ingest, 1.0, |_, _| {}),
        None => Err(CalError::Csv { path: PathBuf::new(), line: 0, message: format!("no run {run}") }),
    }
}

/// [`fit_model_with`] for runs whose logs are not files (arrays in memory): `replay(run,
/// models)` replays run `run` (its index in `runs`) through `models`, as [`replay_models`]
/// does for a file; [`Method::Auto`]'s cross-validation replays the held-out runs with it.
///
/// # Errors
/// As [`fit_model`], and what `replay` returns.
pub fn fit_model_replaying(
    runs: &[RunFeatures],
    config: &CalibrationConfig,
    input_digest: [u8; 32],
    selection: &SelectionOptions,
    progress: impl FnMut(usize, usize),
    replay: &crate::selection::ReplayRun<'_>,
) -> Result<FittedModel, CalError> {
    let axis_count = config.ingest.format.gyro_columns.len();
    let mut choices: Vec<Option<Selection>> = vec![None; axis_count];
    if config.method == Method::Auto {
        let selected = crate::selection::select(runs, config, selection, progress, replay)?;
        choices = selected.into_iter().map(Some).collect();
    }
    let mut axes = Vec::new();
    let mut reports = Vec::new();
    for (axis, choice) in choices.into_iter().enumerate() {
        let method = choice.as_ref().map_or(config.method, |s| s.method);
        let config = &CalibrationConfig { method, ..config.clone() };
        let block_s = f64::from(config.features.window_s) / f64::from(config.features.block_count);
        let calibration = calibration_points_of(runs, axis, config);
        if calibration.points.is_empty() {
            return Err(CalError::NoCalibrationPoints {
                axis,
                min_blocks: config.features.min_blocks,
                max_gap_s: config.features.max_gap_s,
            });
        }
        let noise = target_noise_dph(runs, axis, block_s, config.target_window_s);
        let mut fitted = fit_axis(&calibration, config, noise)?;
        fitted.report.selection = choice;
        axes.push(fitted.model);
        reports.push(fitted.report);
    }
    let codes: Vec<u16> =
        reports.iter().map(|r| r.selection.as_ref().map_or(0, Selection::blob_code)).collect();
    let columns = if config.record_columns { config.ingest.format.axis_columns() } else { Vec::new() };
    let log_time = if config.record_columns { config.ingest.format.log_time() } else { Default::default() };
    let log_reading =
        if config.record_columns { log_reading(runs, &config.ingest.format) } else { Default::default() };
    let model = ModelFile {
        tool_version: crate::blob::tool_version(),
        input_digest,
        axes,
        columns,
        log_time,
        log_reading,
        input_rates: config.input_rates,
    };
    let blob = crate::blob::encode_with_selection(&model, &codes)?;
    Ok(FittedModel { blob, axes: reports })
}

/// The log-reading record of a fit on `runs` read with `format`: the decimal mark, each
/// run's digest when every run has one, and the logs' shape.
fn log_reading(runs: &[RunFeatures], format: &crate::ingest::LogFormat) -> crate::blob::LogReadingRecord {
    let digests: Option<Vec<[u8; 32]>> = runs.iter().map(|r| r.digest).collect();
    let decimal_comma = format.decimal_mark == crate::ingest::DecimalMark::Comma;
    crate::blob::LogReadingRecord {
        shape: crate::blob::LogShapeRecord::of_format(format),
        ..crate::blob::LogReadingRecord::of_logs(decimal_comma, &digests.unwrap_or_default())
    }
}

/// Raw and compensated series of one run and axis, as block means (1 s by default).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReplaySeries {
    /// Block centre times, seconds since the run start.
    pub time_s: Vec<f64>,
    /// Mean raw gyro per block, deg/h.
    pub raw_dph: Vec<f64>,
    /// Mean compensated gyro per block, deg/h.
    pub compensated_dph: Vec<f64>,
    /// Mean subtracted bias per block, deg/h.
    pub bias_dph: Vec<f64>,
    /// The tracker's smoothed temperature at the end of each block, deg C (NaN before features).
    pub temp_c: Vec<f64>,
    /// The tracker's rate at the end of each block, deg C/min (NaN before features).
    pub rate_c_per_min: Vec<f64>,
    /// Samples with each flag bit set (index = bit number).
    pub flag_counts: [u64; 8],
    /// Samples replayed.
    pub samples: u64,
    /// Samples in the fullest block (what a block holds where the log has no gap).
    pub fullest_block_samples: u64,
    /// Time of the first sample the compensator corrected (its tracker's start-up is over),
    /// seconds; NaN if it never did.
    pub compensating_from_s: f64,
    /// Steps between rows longer than the compensator's `max_gap_s`: after each its tracker
    /// started again and the bias was held until it had features.
    pub gaps: TimeGaps,
    /// Single-reading temperature spikes ([`crate::spikes`]), found but compensated as read
    /// (as the firmware would).
    pub temperature_spikes: AxisSpikes,
    /// How far the blocks with samples flagged `OUTSIDE_HULL` lie beyond the calibrated
    /// ranges (`None` when the model records none).
    pub outside_reach: Option<OutsideReach>,
}

/// How far a replay went beyond a model axis's calibrated temperature and rate ranges, at the
/// tracker's features of each sample flagged outside the calibrated region.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OutsideReach {
    /// The calibrated temperature range, deg C.
    pub temp_range_c: (f64, f64),
    /// The calibrated rate range, deg C/min.
    pub rate_range_c_per_min: (f64, f64),
    /// The furthest temperature beyond the range, deg C (0: within it).
    pub temp_beyond_c: f64,
    /// The furthest rate beyond the range, deg C/min (0: within it).
    pub rate_beyond_c_per_min: f64,
    /// Samples flagged outside whose features lie beyond either range.
    pub samples_beyond: u64,
    /// Samples flagged outside whose features lie within both ranges (a combination
    /// of temperature and rate no calibration run held), outside the calibrated region.
    pub samples_within: u64,
    /// Samples flagged outside whose features lie inside the calibrated region: a
    /// mesh's hull (its thinned nodes) need not cover the region, and between the two the
    /// mesh is continued from its edge.
    pub samples_in_region: u64,
    /// The model's value does not depend on dT/dt (a polynomial in T alone, no mesh): a
    /// sample beyond the calibrated rates at a calibrated temperature is flagged, but its
    /// value is the polynomial's own, not extrapolated (review26b F4). Its rate reach is then
    /// that of those samples alone.
    pub rate_unused: bool,
    /// Of a model that does not use the rate: samples flagged outside at a temperature within
    /// the calibrated range, flagged for their rate alone.
    pub samples_rate_only: u64,
}

impl OutsideReach {
    /// Widens the reach by the features `(temp_c, rate_c_per_min)` of `samples` samples
    /// outside the region.
    fn observe(&mut self, temp_c: f64, rate_c_per_min: f64, samples: u64, in_region: bool) {
        if in_region {
            self.samples_in_region += samples;
            return;
        }
        let beyond =
            |v: f64, (lo, hi): (f64, f64)| if v.is_finite() { (lo - v).max(v - hi).max(0.0) } else { 0.0 };
        let (temp, rate) =
            (beyond(temp_c, self.temp_range_c), beyond(rate_c_per_min, self.rate_range_c_per_min));
        if self.rate_unused {
            // Only the temperature moves the value: the rate is not part of how far it is
            // extrapolated.
            if temp > 0.0 {
                self.temp_beyond_c = self.temp_beyond_c.max(temp);
                self.samples_beyond += samples;
            } else {
                self.rate_beyond_c_per_min = self.rate_beyond_c_per_min.max(rate);
                self.samples_rate_only += samples;
            }
            return;
        }
        self.temp_beyond_c = self.temp_beyond_c.max(temp);
        self.rate_beyond_c_per_min = self.rate_beyond_c_per_min.max(rate);
        if temp > 0.0 || rate > 0.0 {
            self.samples_beyond += samples;
        } else {
            self.samples_within += samples;
        }
    }

    /// How far outside, for the outside-region note (review14 F5: "85 % extrapolated" read as
    /// dire for a run 0.5 C past the calibrated maximum): the samples beyond the calibrated
    /// ranges with how far (only the ranges exceeded are named), those within both (review15
    /// F4), and those inside the region beyond a mesh's outermost nodes, each part with its
    /// count (`all of them` when it is the only part).
    pub fn text(&self) -> String {
        let parts = self.parts();
        match parts.as_slice() {
            [(_, only)] => format!("all of them {only}"),
            _ => parts.iter().map(|(n, part)| format!("{n} of them {part}")).collect::<Vec<_>>().join("; "),
        }
    }

    /// The parts of [`OutsideReach::text`] that hold samples, each with its count.
    fn parts(&self) -> Vec<(u64, String)> {
        let (t0, t1) = self.temp_range_c;
        let (r0, r1) = self.rate_range_c_per_min;
        let mut reach = Vec::new();
        if self.temp_beyond_c > 0.0 {
            reach.push(format!(
                "{} C beyond the calibrated {t0:.2} .. {t1:.2} C",
                distance_text(self.temp_beyond_c, 2)
            ));
        }
        let rate_reach = format!(
            "{} C/min beyond the calibrated {r0:.4} .. {r1:.4} C/min",
            distance_text(self.rate_beyond_c_per_min, 4)
        );
        if self.rate_beyond_c_per_min > 0.0 && !self.rate_unused {
            reach.push(rate_reach.clone());
        }
        // A model without the rate is extrapolated beyond its temperatures only: said where
        // its other samples are not (review31b F1); the note's head says it when they are all
        // beyond.
        let continued = if self.rate_unused && self.samples_rate_only > 0 {
            ", where the model is extrapolated"
        } else {
            ""
        };
        let beyond = format!("at most {} (the tracker's features){continued}", reach.join(" and "));
        let rate_only = format!(
            "at a calibrated temperature, at most {rate_reach}: a rate this model (a polynomial in T alone) does \
             not use, so its value there is the polynomial's own, as inside the region"
        );
        let within = format!(
            "within the calibrated ranges ({t0:.2} .. {t1:.2} C, {r0:.4} .. {r1:.4} C/min) at combinations of \
             temperature and rate no calibration run held"
        );
        let in_region =
            "inside the calibrated region but outside the hull of the mesh's nodes, where the mesh is \
                         continued from its edge"
                .to_string();
        [
            (self.samples_beyond, beyond),
            (self.samples_within, within),
            (self.samples_in_region, in_region),
            (self.samples_rate_only, rate_only),
        ]
        .into_iter()
        .filter(|(samples, _)| *samples > 0)
        .collect()
    }
}

/// Follows a replay's samples flagged `OUTSIDE_HULL` on one model axis, at the tracker's
/// features as the compensator flagged each, into an [`OutsideReach`] (`validate`, and since
/// 2026-11-30 `compensate` and Python's `Model.compensate`, whose note said "extrapolated" of
/// samples a polynomial in T alone is flagged for by their rate alone).
pub struct OutsideWatch<'m> {
    /// `None` when the model records no calibrated ranges to measure against.
    reach: Option<OutsideReach>,
    /// The features at the last sample flagged and whether they lie in the region: features
    /// change once per tracker block, so a run of flagged samples tests the region once.
    last: Option<(f32, f32, bool)>,
    /// The calibrated region of an axis with a mesh and the plane it is drawn in (a
    /// polynomial alone is flagged only outside the region).
    region: Option<(fogtemp_core::Region<'m>, Normalisation)>,
}

impl<'m> OutsideWatch<'m> {
    /// A watch on axis `axis` of `model`, against its recorded ranges and region.
    pub fn new(model: &'m Model<'_>, axis: usize) -> Self {
        let axis = model.axis(axis).ok();
        let reach = axis.as_ref().map(|a| OutsideReach {
            temp_range_c: (f64::from(a.provenance.temp_min_c), f64::from(a.provenance.temp_max_c)),
            rate_range_c_per_min: (
                f64::from(a.provenance.rate_min_c_per_min),
                f64::from(a.provenance.rate_max_c_per_min),
            ),
            rate_unused: ignores_rate(a),
            ..OutsideReach::default()
        });
        let region = axis.filter(|a| a.mesh.is_some()).and_then(|a| Some((a.region?, a.normalisation)));
        Self { reach, last: None, region }
    }

    /// Counts one sample flagged outside, at the tracker's `features` when it was flagged
    /// (nothing without features: the compensator flags none then).
    pub fn observe(&mut self, features: Option<fogtemp_core::Features>) {
        let Some(f) = features else { return };
        let in_region = match self.last {
            Some((temp_c, rate_c_per_min, inside))
                if temp_c == f.temp_c && rate_c_per_min == f.rate_c_per_min =>
            {
                inside
            }
            _ => {
                let inside = self.region.is_some_and(|(region, normalisation)| {
                    let (x, y) = normalisation.apply(f.temp_c, f.rate_c_per_min);
                    region.contains(x, y)
                });
                self.last = Some((f.temp_c, f.rate_c_per_min, inside));
                inside
            }
        };
        if let Some(reach) = self.reach.as_mut() {
            reach.observe(f64::from(f.temp_c), f64::from(f.rate_c_per_min), 1, in_region);
        }
    }

    /// Counts the compensator's last output when it is flagged `OUTSIDE_HULL`, at its
    /// tracker's features: what every replay does after each step.
    pub fn observe_output<const N: usize>(
        &mut self,
        output: &fogtemp_core::Output,
        comp: &Compensator<'_, N>,
    ) {
        if output.flags.contains(Flags::OUTSIDE_HULL) {
            self.observe(comp.tracker().features());
        }
    }

    /// The reach of the samples counted so far.
    pub fn reach(&self) -> Option<&OutsideReach> {
        self.reach.as_ref()
    }
}

/// The note on `outside` of `samples` samples flagged outside the calibrated region, with how
/// far they reach when it is known (`flagged` says where the flag is seen: "flag
/// OUTSIDE_HULL", "flag OUTSIDE_HULL in the output"). Samples a polynomial in T alone flags
/// for their rate alone are not called extrapolated (review26b F4), nor, without "outside the
/// region", are samples inside the region beyond a mesh's nodes.
pub fn outside_note(
    name: &str,
    outside: u64,
    samples: u64,
    reach: Option<&OutsideReach>,
    flagged: &str,
) -> String {
    let share = share_percent(outside, samples);
    let mut note = match reach {
        // All flagged for a rate the model does not use: not "extrapolated".
        Some(reach) if reach.rate_unused && reach.samples_rate_only == outside => {
            format!("{name}: {outside} of {samples} samples ({share} %) are {flagged_for} for their rate alone", flagged_for = flagged_as(flagged))
        }
        // Some of them: the parts say which are extrapolated (review31b F1).
        Some(reach) if reach.rate_unused && reach.samples_rate_only > 0 => format!(
            "{name}: {outside} of {samples} samples ({share} %) lie outside the model's calibrated (T, dT/dt) region \
             ({flagged})"
        ),
        // Some inside the region: "outside the region" is not said of them all.
        Some(reach) if reach.samples_in_region > 0 => {
            format!("{name}: {outside} of {samples} samples ({share} %) are where the model is extrapolated ({flagged})")
        }
        _ => outside_region_note(name, outside, samples, flagged),
    };
    if let Some(reach) = reach.filter(|r| !r.parts().is_empty()) {
        note.push_str(&format!(": {}", reach.text()));
    }
    note
}

/// "flag OUTSIDE_HULL in the output" as "flagged OUTSIDE_HULL in the output".
fn flagged_as(flagged: &str) -> String {
    flagged.strip_prefix("flag ").map_or_else(|| flagged.to_string(), |rest| format!("flagged {rest}"))
}

/// A positive distance to `decimals` decimals, or to its first significant digit when it is
/// smaller than that shows (review25b F8: "at most 0.00 C beyond").
fn distance_text(value: f64, decimals: usize) -> String {
    let shown = 10f64.powi(-(decimals as i32));
    if value >= 0.5 * shown || value.is_nan() || value <= 0.0 {
        return format!("{value:.decimals$}");
    }
    let needed = (-value.log10()).ceil().clamp(decimals as f64, 12.0) as usize;
    format!("{value:.needed$}")
}

impl ReplaySeries {
    /// Index of the first block that starts at or after [`Self::compensating_from_s`]
    /// (the length of the series if there is none).
    pub fn first_compensated_block(&self, block_s: f64) -> usize {
        let from = self.compensating_from_s;
        if !from.is_finite() {
            return self.time_s.len();
        }
        self.time_s.iter().position(|t| t - 0.5 * block_s >= from - 1e-9).unwrap_or(self.time_s.len())
    }
}

/// One compensator being replayed, with the block means it keeps.
struct Replayer<'m> {
    comp: Compensator<'m, CAL_CAPACITY>,
    axis: usize,
    block_s: f64,
    series: ReplaySeries,
    /// Samples, raw sum, compensated sum, bias sum and block number of the open block.
    acc: (u64, f64, f64, f64, i64),
    /// Samples in the fullest block closed so far.
    fullest_block: u64,
    /// The time of the previous row, seconds.
    previous_s: Option<f64>,
    /// Where the block grid starts, seconds (from the log's first two rows:
    /// [`block_grid_origin_s`]); `None` until the second row.
    grid_origin_s: Option<f64>,
    /// Finds temperature spikes (only reports them: the compensator takes every reading).
    spikes: SpikeGuard,
    /// The samples flagged `OUTSIDE_HULL`, and how far they reach (into the series at the end).
    outside: OutsideWatch<'m>,
}

impl<'m> Replayer<'m> {
    fn new(path: &Path, model: &'m Model<'_>, axis: usize, block_s: f64) -> Result<Self, CalError> {
        let comp = Compensator::new(model, axis)
            .map_err(|source| CalError::Model { path: path.to_path_buf(), source })?;
        let max_gap_s = comp.tracker().max_gap_us() as f64 * 1e-6;
        let series = ReplaySeries {
            compensating_from_s: f64::NAN,
            gaps: TimeGaps::new(max_gap_s),
            ..ReplaySeries::default()
        };
        let acc = (0, 0.0, 0.0, 0.0, 0);
        let spikes = SpikeGuard::new(max_gap_s);
        Ok(Self {
            comp,
            axis,
            block_s,
            series,
            acc,
            fullest_block: 0,
            previous_s: None,
            grid_origin_s: None,
            spikes,
            outside: OutsideWatch::new(model, axis),
        })
    }

    fn step(&mut self, row: &crate::ingest::Row<'_>) {
        self.series.gaps.observe(self.previous_s, row.time_s, row.line);
        if let (Some(first_s), None) = (self.previous_s, self.grid_origin_s) {
            // The open block holds the first row alone: it moves to the grid the first step sets.
            let origin_s = block_grid_origin_s(first_s, row.time_s - first_s, self.block_s);
            self.grid_origin_s = Some(origin_s);
            self.acc.4 = ((first_s - origin_s) / self.block_s).floor() as i64;
        }
        self.previous_s = Some(row.time_s);
        let temp = row.temp_c_for_axis(self.axis);
        let raw = row.gyros_dph[self.axis];
        // Only readings: rows without one change no verdict, and the guard would hold them
        // for nothing.
        if temp.is_finite() {
            let sample = Sample { time_s: row.time_s, gyro_dph: raw, temp_c: temp, line: row.line };
            self.spikes.push(sample, &mut |_| {});
        }
        let out = self.comp.step(row.time_us(), raw as f32, temp.is_finite().then_some(temp as f32));
        if self.series.compensating_from_s.is_nan() && out.flags.0 & fogtemp_core::Flags::WARMING_UP.0 == 0 {
            self.series.compensating_from_s = row.time_s;
        }
        let block = ((row.time_s - self.grid_origin_s.unwrap_or(0.0)) / self.block_s).floor() as i64;
        if block != self.acc.4 {
            self.flush();
            self.acc.4 = block;
        }
        self.acc.0 += 1;
        self.acc.1 += raw;
        self.acc.2 += f64::from(out.rate_dph);
        self.acc.3 += f64::from(out.bias_dph);
        self.series.samples += 1;
        // At the tracker's features as the compensator flagged it. (Until 2026-11-29 a block's
        // flagged samples were counted at the features of the block's end, which, with tracker
        // and replay blocks not aligned, put some "within the calibrated ranges" that were
        // flagged beyond them: psim-tvc's T-alone model, 49 of 250.)
        self.outside.observe_output(&out, &self.comp);
        for (bit, count) in self.series.flag_counts.iter_mut().enumerate() {
            if out.flags.0 & (1 << bit) != 0 {
                *count += 1;
            }
        }
    }

    /// Closes the open block (the tracker's features as they stand at its end).
    fn flush(&mut self) {
        let (n, raw, comp, bias, block) = self.acc;
        if n > 0 {
            let n = n as f64;
            let f = self.comp.tracker().features();
            let series = &mut self.series;
            series.time_s.push((block as f64 + 0.5) * self.block_s);
            series.raw_dph.push(raw / n);
            series.compensated_dph.push(comp / n);
            series.bias_dph.push(bias / n);
            series.temp_c.push(f.map_or(f64::NAN, |f| f64::from(f.temp_c)));
            series.rate_c_per_min.push(f.map_or(f64::NAN, |f| f64::from(f.rate_c_per_min)));
        }
        self.fullest_block = self.fullest_block.max(self.acc.0);
        self.acc = (0, 0.0, 0.0, 0.0, block);
    }

    /// The series at the end of the log. A last block cut short by the end (under 90 % of
    /// the fullest block, e.g. the one sample logged at exactly the run's duration) is left
    /// out: its mean of few samples is much noisier than the others and spiked the figures.
    fn finish(mut self) -> ReplaySeries {
        // A block cut short is left out of the series; the outside note has counted its
        // samples as they came (review21 F3: a run's last sample alone outside gave the note
        // an empty reach).
        if self.acc.0 * 10 >= self.fullest_block * 9 {
            self.flush();
        }
        self.series.fullest_block_samples = self.fullest_block;
        self.series.temperature_spikes = self.spikes.finish(&mut |_| {});
        self.series.outside_reach = self.outside.reach().copied();
        self.series
    }
}

/// Refuses a cubic in T on fewer distinct temperatures than its 4 terms, naming them.
fn enough_temperatures_for_a_cubic(points: &[MeshPoint]) -> Result<(), CalError> {
    const TERMS: usize = 4;
    let mut temperatures: Vec<f64> = points.iter().map(|p| p.temp_c).filter(|t| t.is_finite()).collect();
    temperatures.sort_by(f64::total_cmp);
    temperatures.dedup();
    if temperatures.len() >= TERMS {
        return Ok(());
    }
    let listed: Vec<String> = temperatures.iter().map(|t| format!("{t:.2} C")).collect();
    Err(CalError::TooFewTemperatures {
        distinct: temperatures.len(),
        needed: TERMS,
        temperatures: if listed.is_empty() { "none".into() } else { listed.join(", ") },
    })
}

/// Where a replay's block grid starts, seconds, from the log's first time stamp and its first
/// step. For a log of at most two samples a block (a step over a third of a block, at most
/// 1.5 blocks): half a sample spacing (the step, at most a block) before the first stamp's
/// phase on that spacing, so each stamp sits mid-way between two block edges and stamps that
/// jitter by less than half a spacing stay in their blocks: a 1 Hz log stamped 1.000020,
/// 1.999990, ... on a whole-second grid gave blocks of 2, 0 and 1 samples, and every empty one
/// cut the white-noise floor's stretches short (review25a). A log on multiples of its spacing
/// is grouped as by whole seconds either way. Denser logs, and a first step that is a gap or
/// none, keep whole seconds (origin 0): jitter moves a sample of many, and the figures of logs
/// in bursts, whose edge blocks hold a few samples, stay as they were. The block's time stays
/// `(block + 0.5) * block_s`.
fn block_grid_origin_s(first_s: f64, first_step_s: f64, block_s: f64) -> f64 {
    let known = first_step_s.is_finite() && first_step_s > 0.0 && first_step_s <= 1.5 * block_s;
    let spacing_s = first_step_s.min(block_s);
    if !known || spacing_s <= block_s / 3.0 {
        return 0.0;
    }
    let phase_s = first_s.rem_euclid(spacing_s);
    if phase_s.is_finite() {
        phase_s - spacing_s / 2.0
    } else {
        0.0
    }
}

/// One log replayed through every model: the series per model, per axis, and what ingest saw.
#[derive(Clone, Debug, PartialEq)]
pub struct Replay {
    /// Per model (in the order given), per axis: the block means.
    pub models: Vec<Vec<ReplaySeries>>,
    /// What ingest saw.
    pub ingest: IngestReport,
}

/// Replays a log through the core `Compensator` of every axis of every model, exactly as
/// firmware would, reading the log once, and keeps `block_s` block means of raw,
/// compensated and bias (constant memory per sample). Returns the series per model, per
/// axis (the axes the model and the log's gyro columns share).
///
/// # Errors
/// Ingest errors; [`CalError::Model`] if an axis cannot be compensated.
pub fn replay_models(
    path: &Path,
    models: &[&Model<'_>],
    ingest: &IngestOptions,
    block_s: f64,
    progress: impl FnMut(u64, u64),
) -> Result<Replay, CalError> {
    replay_with(path, models, ingest, block_s, |visit| read_log_with_progress(path, ingest, visit, progress))
}

/// [`replay_models`] from any reader; `name` stands for the source in errors and reports.
///
/// # Errors
/// As [`replay_models`].
pub fn replay_models_from<R: Read + Send>(
    reader: R,
    name: &Path,
    models: &[&Model<'_>],
    ingest: &IngestOptions,
    block_s: f64,
) -> Result<Replay, CalError> {
    replay_with(name, models, ingest, block_s, |visit| read_from(reader, name, ingest, visit, |_, _| {}))
}

/// The replay of one log whose rows `read` hands to the visitor it is given.
pub(crate) fn replay_with(
    path: &Path,
    models: &[&Model<'_>],
    ingest: &IngestOptions,
    block_s: f64,
    read: impl FnOnce(&mut dyn FnMut(&Row<'_>) -> Result<(), CalError>) -> Result<IngestReport, CalError>,
) -> Result<Replay, CalError> {
    let axes = |m: &Model<'_>| m.axis_count().min(ingest.format.gyro_columns.len());
    let mut replayers: Vec<Replayer<'_>> = Vec::new();
    for model in models {
        for axis in 0..axes(model) {
            replayers.push(Replayer::new(path, model, axis, block_s)?);
        }
    }
    let report = read(&mut |row: &Row<'_>| {
        replayers.iter_mut().for_each(|r| r.step(row));
        Ok(())
    })?;
    let mut finished = replayers.into_iter().map(Replayer::finish);
    let series = models.iter().map(|m| finished.by_ref().take(axes(m)).collect()).collect();
    Ok(Replay { models: series, ingest: report })
}

/// Raw vs compensated bias stability of one run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunValidation {
    /// The log.
    pub path: PathBuf,
    /// Axis.
    pub axis: usize,
    /// Raw bias stability, deg/h.
    pub raw_bias_stability_dph: f64,
    /// Compensated bias stability, deg/h.
    pub compensated_bias_stability_dph: f64,
    /// The replayed series.
    pub series: ReplaySeries,
    /// What ingest saw (rows, skipped rows and where).
    pub ingest: IngestReport,
    /// The averaging windows of the metric: how many it used and how many it left out
    /// because a gap or the run's end cut them short ([`crate::metrics::window_means`]).
    pub windows: MetricWindows,
    /// The run's mean raw output over the metric's span, deg/h ([`span_means`]); NaN when
    /// the span is empty. Bias stability is blind to a constant; this is where a model that
    /// leaves a run's bias behind shows (review24a S1: two plateaus of a MEMS calibration).
    pub raw_mean_dph: f64,
    /// The run's mean compensated output over the same span, deg/h: its residual bias, plus
    /// the true input rate unless [`Self::input_rate_dph`] names it.
    pub compensated_mean_dph: f64,
    /// The true rate about the input axis that a runs file gives for this run, deg/h
    /// ([`Validation::with_input_rates`]); `None` when none was given.
    pub input_rate_dph: Option<f64>,
}

impl RunValidation {
    /// The run's mean raw and compensated output over the metric's span less its true input
    /// rate where a runs file gave one, deg/h: what each leaves of the run's bias.
    pub fn residual_means_dph(&self) -> (f64, f64) {
        let rate = self.input_rate_dph.unwrap_or(0.0);
        (self.raw_mean_dph - rate, self.compensated_mean_dph - rate)
    }

    /// What a technician is told about the gaps in this run's time stamps (`None` without
    /// gaps): the command line's `note:` and Python's warning.
    pub fn gap_note(&self) -> Option<String> {
        let w = self.windows;
        let consequence = format!(
            "after each the compensator held its bias until its tracker had features again; \
             {} of the metric's {} averaging windows were cut short (by a gap or the run's end) and left out",
            w.left_out,
            w.used + w.left_out
        );
        self.series.gaps.note_then(&self.path, &consequence)
    }

    /// The note for a run that compensation made clearly worse: its compensated bias
    /// stability above the raw one by more than twice the metric's relative standard error
    /// (`1 / sqrt(2 (n - 1))` for a standard deviation of `n` window means), with the likely
    /// causes; `None` otherwise, or when either figure is undefined.
    pub fn worse_than_raw_note(&self, name: &str) -> Option<String> {
        let (raw, comp) = (self.raw_bias_stability_dph, self.compensated_bias_stability_dph);
        let windows = self.windows.used;
        if !(raw.is_finite() && comp.is_finite()) || windows < 2 {
            return None;
        }
        let relative_se = self.windows.relative_standard_error()?;
        (comp > raw * (1.0 + 2.0 * relative_se)).then(|| {
            format!(
                "{name}: compensation made the bias stability worse: {} deg/h against {} raw \
                 (ratio {:.2}), beyond the metric's own scatter (about {:.0} % from {windows} averaging windows). \
                 Check that the log's gyro and temperature columns and units are the ones the model was fitted \
                 on (fogtemp-cal inspect shows the columns), and that the run's temperatures and rates lie within \
                 the calibration's",
                crate::numbers::dph(comp),
                crate::numbers::dph(raw),
                raw / comp,
                100.0 * relative_se
            )
        })
    }

    /// The compensated output's white-noise floor for this run's bias stability
    /// ([`WhiteNoiseFloor`]): its Allan deviation at the blocks' own spacing (1 s, or the
    /// log's sample spacing when slower), over the metric's span and its gap-free stretches,
    /// extrapolated to the metric's window as white noise. The shortest averaging time, because
    /// from a few seconds on the compensator's own feature jitter shows (on `tests/cli.rs`'s
    /// logs the Allan deviation at 8 s is 9 % above their white noise, at 1 s on it). `None`
    /// when the stretches are too short for an Allan deviation, or the spacing is over a tenth
    /// of the window.
    pub fn white_noise_floor(&self) -> Option<WhiteNoiseFloor> {
        let compensated_from = self.series.first_compensated_block(1.0);
        // The metric's span leaves out the first `excluded_s` after that, as its windows do
        // (review27b F2: the floor took the warm-up that --exclude-first-s left out).
        let excluded_s = self.windows.excluded_s.max(0.0);
        let span_start_s = self.series.time_s.get(compensated_from).map_or(f64::INFINITY, |t| t + excluded_s);
        let from = compensated_from
            + self
                .series
                .time_s
                .get(compensated_from..)
                .unwrap_or_default()
                .partition_point(|&t| t < span_start_s);
        let times = self.series.time_s.get(from..).unwrap_or_default();
        let values = self.series.compensated_dph.get(from..).unwrap_or_default();
        let spacing_s = crate::allan_stream::median_step(times)?.max(1.0);
        let window_s = self.windows.tau_s;
        if spacing_s > window_s / 10.0 {
            return None;
        }
        let segments: Vec<&[f64]> =
            crate::metrics::gap_free_ranges(times, spacing_s).filter_map(|r| values.get(r)).collect();
        let first = crate::metrics::allan_deviation_in_segments(&segments, spacing_s).into_iter().next()?;
        // A window mean averages only the data in it: a log in bursts fills a fraction.
        let averaged_s = self.window_data_s().unwrap_or(window_s).clamp(first.tau_s, window_s);
        (first.adev_dph.is_finite() && first.adev_dph > 0.0).then(|| WhiteNoiseFloor {
            from_tau_s: first.tau_s,
            adev_dph: first.adev_dph,
            averaged_s,
            floor_dph: first.adev_dph * (first.tau_s / averaged_s).sqrt(),
        })
    }

    /// Every note on this run: [`RunValidation::coverage_notes`], then
    /// [`RunValidation::figure_notes`].
    pub fn notes(&self) -> Vec<String> {
        let mut notes = self.coverage_notes();
        notes.extend(self.figure_notes());
        notes
    }

    /// What a technician is told about the run's figures themselves: a run compensation made
    /// clearly worse ([`RunValidation::worse_than_raw_note`]), averaging windows the data fill
    /// in part, gyro spikes left in the figures. Empty when nothing of that. Apart from
    /// [`RunValidation::coverage_notes`], so a report does not list a verdict under the
    /// heading for extrapolated samples (review21 second report F4).
    pub fn figure_notes(&self) -> Vec<String> {
        let name = format!("{} axis {}", self.path.display(), self.axis);
        let mut notes = Vec::new();
        notes.extend(self.worse_than_raw_note(&name));
        notes.extend(self.sparse_windows_note(&name));
        notes.extend(self.gyro_outlier_note(&name));
        notes
    }

    /// What a technician is told about samples the model did not compensate as calibrated:
    /// none compensated at all, with the likely causes; a share outside the calibrated
    /// region, extrapolated; temperature spikes or silences. Empty when nothing of that.
    pub fn coverage_notes(&self) -> Vec<String> {
        let name = format!("{} axis {}", self.path.display(), self.axis);
        let s = &self.series;
        let mut notes = Vec::new();
        if s.samples > 0 && !s.compensating_from_s.is_finite() {
            let consequence = "the compensated bias stability is undefined";
            notes.push(never_corrected_note(
                &name,
                consequence,
                &s.flag_counts,
                s.samples,
                s.gaps.longer_than_s,
            ));
        } else if self.compensated_bias_stability_dph.is_nan() && s.samples > 0 {
            // How long the compensated span is, and the averaging time that gives figures: two
            // windows at least (review24a F6: 65 s and 131 s runs printed NaN, no way out said).
            // The metric's own span: after the start the metric leaves out (review25a 5: the
            // advice ignored --exclude-first-s and still gave no figures).
            let excluded_s = self.windows.excluded_s.max(0.0);
            let span_s = s.time_s.last().map_or(0.0, |&t| t - s.compensating_from_s - excluded_s);
            let after = if excluded_s > 0.0 {
                format!(" after the first {excluded_s} s left out")
            } else {
                String::new()
            };
            let shorter = if span_s <= 0.0 && excluded_s > 0.0 {
                format!(
                    "; the first {excluded_s} s left out cover the whole compensated span: a shorter \
                     --exclude-first-s (Python exclude_first_s=) gives figures"
                )
            } else if span_s >= 2.0 {
                format!(
                    "; the compensated span is {span_s:.0} s{after}: a shorter averaging time gives figures (--tau-s at most \
                     {:.0}, Python tau_s=)",
                    (span_s / 2.0).floor()
                )
            } else {
                String::new()
            };
            notes.push(format!(
                "{name}: the compensated bias stability is undefined: too few complete averaging windows \
                 after the compensator's start-up ({} used){shorter}",
                self.windows.used
            ));
        }
        let outside = s.flag_counts[Flags::OUTSIDE_HULL.0.trailing_zeros() as usize];
        if outside > 0 {
            let note = outside_note(&name, outside, s.samples, s.outside_reach.as_ref(), "flag OUTSIDE_HULL");
            notes.push(note);
        }
        notes.extend(temperature_spike_note(&name, &self.path, &s.temperature_spikes));
        let stale = s.flag_counts[Flags::TEMP_STALE.0.trailing_zeros() as usize];
        if stale > 0 && s.compensating_from_s.is_finite() {
            notes.push(stale_temperature_note(
                &name,
                stale,
                s.samples,
                s.gaps.longer_than_s,
                "flag TEMP_STALE",
            ));
        }
        notes
    }
}

impl RunValidation {
    /// The data time a used averaging window holds on average, s (`None` without windows):
    /// its blocks times the share of a full block the run's blocks hold on average (blocks at
    /// a burst's edges hold part of one: psim-tvc's 5 s bursts touch 6 one-second blocks;
    /// review15 F3).
    fn window_data_s(&self) -> Option<f64> {
        let w = self.windows;
        let s = &self.series;
        if w.used == 0 || w.tau_s <= 0.0 || s.fullest_block_samples == 0 {
            return None;
        }
        let from = s.first_compensated_block(1.0);
        let step_s = crate::allan_stream::median_step(s.time_s.get(from..)?)?;
        let fill = s.samples as f64 / (s.time_s.len() as f64 * s.fullest_block_samples as f64);
        Some(w.samples_used as f64 / w.used as f64 * step_s * fill.min(1.0))
    }

    /// The note for averaging windows that data fill for less than half their length (a log
    /// recorded in bursts, review14 F2: psim-tvc's 5 s bursts every 100 s or so gave a "100 s"
    /// bias stability that is the scatter of 5 s means, with 46 of 65 windows empty, without a
    /// word): the data time per used window from [`RunValidation::window_data_s`].
    fn sparse_windows_note(&self, name: &str) -> Option<String> {
        let w = self.windows;
        let data_s = self.window_data_s()?;
        let tau = w.tau_s;
        let apart_s = if w.used_spacing_s.is_finite() { w.used_spacing_s } else { tau };
        (data_s < 0.5 * tau).then(|| {
            format!(
                "{name}: data fill about {data_s:.1} s of each {tau} s averaging window ({} used, {} left out as empty \
                 or cut short): the log is recorded in bursts or with gaps, so its bias stability is the scatter of \
                 about {data_s:.0} s means about {apart_s:.0} s apart, not comparable with a {tau} s specification",
                w.used, w.left_out
            )
        })
    }

    /// The note for gyro block means beyond 10 robust SDs of their neighbours' median (the
    /// screen `fit` reads as missing, [`crate::outliers::screen`]): `validate` measures the
    /// data as logged, so such a spike (an overload code's 9.91e37 deg/h made a run's bias
    /// stability 1.2e35 with ratio 1.00, review13 F1) stays in its figures, and is named.
    fn gyro_outlier_note(&self, name: &str) -> Option<String> {
        let s = &self.series;
        let (found, robust_sd) = crate::outliers::screen(&not_at_gap_edges(&s.time_s, &s.raw_dph));
        let (&(first, deviation), count) = (found.first()?, found.len());
        let (deviation, sds) = crate::outliers::deviation_text(deviation, robust_sd);
        let at = s.time_s.get(first).copied().unwrap_or(f64::NAN);
        Some(format!(
            "{name}: the raw gyro has {} beyond {} robust SDs of the median around {} (the first at {at:.0} s, \
             {deviation} deg/h from it, {sds} SDs): spikes or a logger's overload code, kept in this run's figures \
             as logged (fit reads them as missing); check the log there",
            if count == 1 { "1 block mean".to_string() } else { format!("{count} block means") },
            crate::outliers::ROBUST_SDS,
            if count == 1 { "it" } else { "them" },
        ))
    }
}

/// `values` (one per block, at `time_s`) with the blocks next to a gap read as missing: a
/// block at a gap's edge may hold a single sample, whose noise is a full block's times the
/// square root of its samples (review24b F7: one 1 kHz sample before a 180 s gap's end read
/// as a 30-SD spike of the raw gyro that the log does not have). A gap is a step between
/// block times beyond 1.5 times their median step.
fn not_at_gap_edges(time_s: &[f64], values: &[f64]) -> Vec<f64> {
    let mut steps: Vec<f64> = time_s.windows(2).map(|w| w[1] - w[0]).filter(|d| d.is_finite()).collect();
    if steps.is_empty() {
        return values.to_vec();
    }
    steps.sort_by(f64::total_cmp);
    let limit = 1.5 * steps[steps.len() / 2];
    let gap_after = |k: usize| time_s.get(k + 1).is_some_and(|next| next - time_s[k] > limit);
    values
        .iter()
        .enumerate()
        .map(|(k, &v)| if gap_after(k) || (k > 0 && gap_after(k - 1)) { f64::NAN } else { v })
        .collect()
}

/// The note for temperature spikes in a log being compensated (`None` without any): the
/// compensator took them as read, as the firmware would, so its features and output are
/// disturbed for up to a feature window after each. The first few by line of `log`.
pub fn temperature_spike_note(name: &str, log: &Path, spikes: &AxisSpikes) -> Option<String> {
    const NAMED: usize = 3;
    if spikes.count == 0 {
        return None;
    }
    let named: Vec<String> = spikes.first.iter().take(NAMED).map(|s| s.describe(log, None)).collect();
    let more = spikes.count.saturating_sub(named.len() as u64);
    let more = if more > 0 { format!(" and {more} more") } else { String::new() };
    let glitches = if spikes.count == 1 {
        "1 temperature glitch".to_string()
    } else {
        format!("{} temperature glitches", spikes.count)
    };
    Some(format!(
        "{name}: {glitches} ({}{more}): readings that jump by more than {:.0} C (more where readings are far apart) \
         from the readings around them and back: \
         compensated as read, as the firmware would, so the output after each is disturbed for up to a feature window; \
         a gyro's temperature does not move like that, so check the sensor or the logger",
        named.join(", "),
        crate::spikes::SPIKE_JUMP_C,
    ))
}

/// The note for `stale` of `samples` samples compensated without a temperature for longer
/// than the model's gap limit `max_gap_s` (a temperature channel that dropped out while the
/// gyro went on; `flagged` says where the flag can be seen).
pub fn stale_temperature_note(name: &str, stale: u64, samples: u64, max_gap_s: f64, flagged: &str) -> String {
    format!(
        "{name}: {stale} of {samples} samples ({} %) came more than the model's max gap of {max_gap_s} s \
         after the last temperature reading ({flagged}): the compensator held its bias there, and \
         its features restart when readings return",
        share_percent(stale, samples)
    )
}

/// The temperature rows' notes of `runs` (channels logged on separate rows), one per log
/// (from its axis 0), for `validate`'s `notes`.
pub fn temperature_row_notes(runs: &[RunValidation]) -> Vec<String> {
    runs.iter().filter(|r| r.axis == 0).filter_map(|r| r.ingest.temperature_only_note()).collect()
}

/// The gap notes of `runs`, one per log and distinct gaps (the axes of one log usually
/// share them).
pub fn gap_notes(runs: &[RunValidation]) -> Vec<String> {
    let mut seen: Vec<(&Path, TimeGaps)> = Vec::new();
    let mut notes = Vec::new();
    for r in runs {
        let key = (r.path.as_path(), r.series.gaps);
        if seen.contains(&key) {
            continue;
        }
        seen.push(key);
        notes.extend(r.gap_note());
    }
    notes
}

/// One note per chain of validated logs that continue one another ([`crate::continued`]),
/// judged by the model's max gap: each was replayed and scored as a run of its own.
pub fn continued_notes(runs: &[RunValidation]) -> Vec<String> {
    let max_gap_s = runs.first().map_or(0.0, |r| r.series.gaps.longer_than_s);
    crate::continued::continued_logs(runs.iter().map(|r| &r.ingest), max_gap_s)
        .iter()
        .map(crate::continued::Continued::message)
        .collect()
}

/// The noise floor a run's bias stability cannot go below, from white noise alone: the
/// compensated output's Allan deviation at a short averaging time, where temperature drift does
/// not show yet, extrapolated as white noise (`sigma ~ 1 / sqrt(tau)`) to the data time a
/// window mean averages (the window, or the part of it a log in bursts fills).
/// White, flicker and rate random-walk noise each fall no faster than that with the averaging
/// time, so the real floor is at least this: flicker and random walk, which no model removes,
/// come on top (review14 F4: the report gave nothing to judge a compensated figure against).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct WhiteNoiseFloor {
    /// The averaging time extrapolated from, s.
    pub from_tau_s: f64,
    /// The compensated output's Allan deviation there, deg/h.
    pub adev_dph: f64,
    /// The data time a window mean averages, s: the window, or less where the data fill only
    /// part of each window used (a log in bursts).
    pub averaged_s: f64,
    /// The floor at the metric's window: `adev_dph * sqrt(from_tau_s / averaged_s)`, deg/h.
    pub floor_dph: f64,
}

/// The RMS over `runs` of their white-noise floors ([`RunValidation::white_noise_floor`]), as
/// the overall bias stability is the RMS of theirs, and the longest averaging time extrapolated
/// from; `None` unless every run with a compensated figure has a floor.
pub fn overall_white_noise_floor<'a>(
    runs: impl IntoIterator<Item = &'a RunValidation>,
) -> Option<WhiteNoiseFloor> {
    let floors: Vec<WhiteNoiseFloor> = runs
        .into_iter()
        .filter(|r| r.compensated_bias_stability_dph.is_finite())
        .map(RunValidation::white_noise_floor)
        .collect::<Option<_>>()?;
    if floors.is_empty() {
        return None;
    }
    let rms = |f: fn(&WhiteNoiseFloor) -> f64| rms_over_runs(&floors.iter().map(f).collect::<Vec<_>>());
    Some(WhiteNoiseFloor {
        from_tau_s: floors.iter().map(|f| f.from_tau_s).fold(0.0, f64::max),
        adev_dph: rms(|f| f.adev_dph),
        averaged_s: floors.iter().map(|f| f.averaged_s).fold(f64::INFINITY, f64::min),
        floor_dph: rms(|f| f.floor_dph),
    })
}

/// The averaging windows behind one run's bias stability.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MetricWindows {
    /// Windows whose means the metric used.
    pub used: usize,
    /// Windows left out: empty, or cut short by a gap in the time stamps or by the run's end
    /// (a window counts when it holds at least 90 % of the typical window's samples,
    /// `metrics::fullness_threshold`).
    pub left_out: usize,
    /// Block means (the series' samples) in the windows used.
    pub samples_used: usize,
    /// The windows' length, s (0: unknown).
    pub tau_s: f64,
    /// The median spacing of consecutive used windows, s (NaN: unknown).
    pub used_spacing_s: f64,
    /// The start of each run the metric left out (`--exclude-first-s`), s.
    pub excluded_s: f64,
}

impl MetricWindows {
    /// The relative standard error of a bias stability from these windows: `1 / sqrt(2 (n - 1))`
    /// for the standard deviation of `n` independent, normal window means; `None` under 2.
    pub fn relative_standard_error(&self) -> Option<f64> {
        (self.used >= 2).then(|| 1.0 / (2.0 * (self.used as f64 - 1.0)).sqrt())
    }
}

/// [`Validation::per_axis`] of `runs`.
pub fn per_axis_overall(runs: &[RunValidation]) -> Vec<(usize, f64, f64)> {
    let axes = runs.iter().map(|r| r.axis + 1).max().unwrap_or(0);
    (0..axes)
        .map(|axis| {
            let of = |value: fn(&RunValidation) -> f64| {
                let values: Vec<f64> = runs.iter().filter(|r| r.axis == axis).map(value).collect();
                rms_over_runs(&values)
            };
            (axis, of(|r| r.raw_bias_stability_dph), of(|r| r.compensated_bias_stability_dph))
        })
        .collect()
}

/// The mean raw and compensated block values over the metric's span: the blocks from
/// `from` (the first the compensator corrected) whose centres lie at least `exclude_first_s`
/// after that block's, as [`bias_stability`] takes them. Every block counts once (a block cut
/// by a gap counts as much as a full one); NaN when no block is in the span.
pub fn span_means(series: &ReplaySeries, from: usize, exclude_first_s: f64) -> (f64, f64) {
    let times = series.time_s.get(from..).unwrap_or_default();
    let start_s = times.first().copied().unwrap_or(0.0) + exclude_first_s;
    let (mut raw_sum, mut comp_sum, mut blocks) = (0.0, 0.0, 0usize);
    let raw = series.raw_dph.get(from..).unwrap_or_default();
    let comp = series.compensated_dph.get(from..).unwrap_or_default();
    for ((t, r), c) in times.iter().zip(raw).zip(comp) {
        if *t >= start_s && r.is_finite() && c.is_finite() {
            raw_sum += r;
            comp_sum += c;
            blocks += 1;
        }
    }
    if blocks == 0 {
        return (f64::NAN, f64::NAN);
    }
    (raw_sum / blocks as f64, comp_sum / blocks as f64)
}

/// One model's validation: per run and axis, and overall (RMS over runs and axes).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Validation {
    /// Per run and axis, in log order.
    pub runs: Vec<RunValidation>,
    /// Raw bias stability, RMS over `runs`, deg/h.
    pub raw_bias_stability_dph: f64,
    /// Compensated bias stability, RMS over `runs`, deg/h.
    pub compensated_bias_stability_dph: f64,
}

impl Validation {
    /// The validation of `runs` (in log order): overall, the RMS over them.
    pub fn from_runs(runs: Vec<RunValidation>) -> Self {
        let raw = rms_over_runs(&runs.iter().map(|r| r.raw_bias_stability_dph).collect::<Vec<_>>());
        let comp = rms_over_runs(&runs.iter().map(|r| r.compensated_bias_stability_dph).collect::<Vec<_>>());
        Self { runs, raw_bias_stability_dph: raw, compensated_bias_stability_dph: comp }
    }

    /// Per axis, in axis order: the RMS over that axis's runs, raw and compensated, deg/h
    /// (`(axis, raw, comp)`; a model of several axes pools them in the overall figure, which
    /// mixes gyros).
    pub fn per_axis(&self) -> Vec<(usize, f64, f64)> {
        per_axis_overall(&self.runs)
    }

    /// Each model's validation over several logs from its validations of one log at a time
    /// (`per_log[log][model]`, as [`validate_models`] returns them for one log).
    pub fn combine_logs(models: usize, per_log: Vec<Vec<Validation>>) -> Vec<Validation> {
        let mut runs: Vec<Vec<RunValidation>> = vec![Vec::new(); models];
        for log in per_log {
            for (all, v) in runs.iter_mut().zip(log) {
                all.extend(v.runs);
            }
        }
        runs.into_iter().map(Self::from_runs).collect()
    }

    /// The same validation with each run's true input rate from a runs file
    /// (`rates[log]`, deg/h), so that its residual bias can be read: set on axis 0 of models
    /// of one axis only, as `fit` subtracts the rates ([`subtract_input_rates`]).
    pub fn with_input_rates(mut self, rates: &[(PathBuf, f64)]) -> Self {
        if self.runs.iter().any(|r| r.axis != 0) {
            return self;
        }
        for run in &mut self.runs {
            run.input_rate_dph = rates.iter().find(|(log, _)| *log == run.path).map(|(_, rate)| *rate);
        }
        self
    }
}

/// Replays every run and axis and computes bias stability raw vs compensated.
///
/// # Errors
/// As [`replay_models`].
pub fn validate_runs(
    paths: &[PathBuf],
    model: &Model<'_>,
    ingest: &IngestOptions,
    options: &BiasStabilityOptions,
    progress: impl FnMut(usize, u64, u64),
) -> Result<Validation, CalError> {
    let mut all = validate_models(paths, &[model], ingest, options, progress)?;
    Ok(all.pop().unwrap_or_default())
}

/// [`validate_runs`] for several models on the same logs, reading each log once: one
/// [`Validation`] per model.
///
/// # Errors
/// As [`replay_models`].
pub fn validate_models(
    paths: &[PathBuf],
    models: &[&Model<'_>],
    ingest: &IngestOptions,
    options: &BiasStabilityOptions,
    mut progress: impl FnMut(usize, u64, u64),
) -> Result<Vec<Validation>, CalError> {
    let replays = paths.iter().enumerate().map(|(i, path)| {
        Ok((path.clone(), replay_models(path, models, ingest, 1.0, |b, r| progress(i, b, r))?))
    });
    validations(models.len(), replays, options)
}

/// [`validate_models`] that adds the logs' bytes to `digest` as they are read (what
/// `validate` compares with the model's input digest), so that each log is read once.
///
/// # Errors
/// As [`replay_models`].
pub fn validate_models_digested(
    paths: &[PathBuf],
    models: &[&Model<'_>],
    ingest: &IngestOptions,
    options: &BiasStabilityOptions,
    digest: &mut InputDigest,
    mut progress: impl FnMut(usize, u64, u64),
) -> Result<Vec<Validation>, CalError> {
    let replays = paths.iter().enumerate().map(|(i, path)| {
        let replay = replay_with(path, models, ingest, 1.0, |visit| {
            let (report, _) = read_log_digested(path, ingest, digest, visit, |b, r| progress(i, b, r))?;
            Ok(report)
        })?;
        Ok((path.clone(), replay))
    });
    validations(models.len(), replays, options)
}

/// [`validate_runs`] over logs given as `(name, reader)` pairs, for logs that are not files
/// (bytes in memory, a decompressor); `name` stands for each log in errors and results.
///
/// # Errors
/// As [`replay_models`].
pub fn validate_readers<N, R>(
    logs: impl IntoIterator<Item = (N, R)>,
    model: &Model<'_>,
    ingest: &IngestOptions,
    options: &BiasStabilityOptions,
) -> Result<Validation, CalError>
where
    N: AsRef<Path>,
    R: Read + Send,
{
    let replays = logs.into_iter().map(|(name, reader)| {
        let name = name.as_ref();
        Ok((name.to_path_buf(), replay_models_from(reader, name, &[model], ingest, 1.0)?))
    });
    Ok(validations(1, replays, options)?.pop().unwrap_or_default())
}

/// Bias stability raw vs compensated per model from the replays of every log: what
/// [`validate_models`] computes from the logs it replays, for replays made elsewhere (runs
/// given as arrays: [`crate::arrays::replay_models_arrays`]). One [`Validation`] per model.
///
/// # Errors
/// The first replay that is an error.
pub fn validations(
    model_count: usize,
    replays: impl Iterator<Item = Result<(PathBuf, Replay), CalError>>,
    options: &BiasStabilityOptions,
) -> Result<Vec<Validation>, CalError> {
    let mut runs: Vec<Vec<RunValidation>> = (0..model_count).map(|_| Vec::new()).collect();
    for replay in replays {
        let (path, Replay { models: per_model, ingest: report }) = replay?;
        for (model_runs, per_axis) in runs.iter_mut().zip(per_model) {
            for (axis, series) in per_axis.into_iter().enumerate() {
                // Raw and compensated over the same span: from the first block the compensator
                // corrected (before that its output is the raw input, flagged WARMING_UP).
                let from = series.first_compensated_block(1.0);
                let times = series.time_s.get(from..).unwrap_or_default();
                let raw = bias_stability(times, series.raw_dph.get(from..).unwrap_or_default(), options);
                let stats =
                    window_stats(times, series.compensated_dph.get(from..).unwrap_or_default(), options);
                let windows = MetricWindows {
                    used: stats.means.len(),
                    left_out: stats.left_out,
                    samples_used: stats.samples_used,
                    tau_s: options.tau_s,
                    used_spacing_s: stats.used_spacing_s,
                    excluded_s: options.exclude_first_s,
                };
                let means = stats.means;
                let (raw_mean_dph, compensated_mean_dph) = span_means(&series, from, options.exclude_first_s);
                model_runs.push(RunValidation {
                    windows,
                    raw_mean_dph,
                    compensated_mean_dph,
                    input_rate_dph: None,
                    path: path.clone(),
                    axis,
                    raw_bias_stability_dph: raw,
                    compensated_bias_stability_dph: stability_of_means(means, options),
                    series,
                    ingest: report.clone(),
                });
            }
        }
    }
    Ok(runs.into_iter().map(Validation::from_runs).collect())
}

#[cfg(test)]
mod tests {
    #[test]
    fn shares_under_a_tenth_of_a_percent_keep_a_significant_digit() {
        assert_eq!(share_percent(3, 7200), "0.04");
        assert_eq!(share_percent(1, 1_000_000), "0.0001");
        assert_eq!(share_percent(0, 7200), "0.0");
        assert_eq!(share_percent(250, 6250), "4.0");
        assert_eq!(share_percent(7200, 7200), "100.0");
    }

    #[test]
    fn a_run_never_corrected_is_put_down_to_its_rejected_readings_first() {
        use fogtemp_core::Flags;
        let bit = |flag: Flags| flag.0.trailing_zeros() as usize;
        let mut flags = [0u64; 8];
        // Raw counts (65236) in every row: rejected (BAD_INPUT), so the temperature is stale
        // (TEMP_STALE) and the tracker warms up throughout (review20 F1).
        for flag in [Flags::WARMING_UP, Flags::TEMP_STALE, Flags::BAD_INPUT] {
            flags[bit(flag)] = 7200;
        }
        let note = never_corrected_note("run.csv", "the output's bias is 0", &flags, 7200, 5.0);
        assert!(
            note.contains("7200 of 7200 samples had their temperature or time rejected (BAD_INPUT)")
                && note.contains("raw counts need the temperature's scale and offset")
                && !note.contains("silent"),
            "{note}"
        );
        // Readings too far apart, none rejected: the gap limit.
        flags[bit(Flags::BAD_INPUT)] = 0;
        let note = never_corrected_note("run.csv", "the output's bias is 0", &flags, 7200, 5.0);
        assert!(note.contains("silent for longer than the model's max gap of 5 s at 7200 of 7200"), "{note}");
    }

    #[test]
    fn rejections_in_the_microsecond_before_count_only_readings_a_sensor_gives() {
        let bad = fogtemp_core::Flags::BAD_INPUT.0;
        // Times in s: 1.0000002 shares 1.0's microsecond, and 2.0000004 that of 2.0 (the last
        // reading taken: 2.0000002 has none).
        let time_s = [1.0, 1.000_000_2, 2.0, 2.000_000_2, 2.000_000_4, 2.000_000_4, 3.0];
        let temp_c = [20.0, 20.0, 20.0, f64::NAN, 20.0, -999.0, 20.0];
        let flags = [0, bad, 0, 0, bad, bad, bad];
        // Samples 1 and 4 count; 5 is a -999 reading (refused for itself); 6 is a new microsecond.
        assert_eq!(same_microsecond_rejections(&time_s, &temp_c, &flags), 2);
        assert_eq!(same_microsecond_rejections(&time_s[..1], &temp_c[..1], &flags[..1]), 0);
    }

    #[test]
    fn the_bad_input_note_names_the_first_lines_and_only_causes_that_can_occur() {
        let from_file = BadInputSources {
            times_refused: true,
            first_lines: vec![101, 230, 231, 400, 512],
            gyro_not_finite: 0,
            same_microsecond: 0,
        };
        let note = bad_input_note("run.csv axis 0", 9, 7200, "the output", &from_file);
        assert!(
            note.contains("(flag BAD_INPUT in the output; first at lines 101, 230, 231, 400, 512)"),
            "{note}"
        );
        assert!(!note.contains("a time not after"), "{note}");
        // Time stamps finer than the compensator's microsecond (review25a 2): named, not put
        // down to the temperature.
        let bursts = BadInputSources { same_microsecond: 9, ..from_file.clone() };
        let note = bad_input_note("run.csv axis 0", 9, 7200, "the output", &bursts);
        assert!(note.contains("9 of them came in the same microsecond as the last reading taken"), "{note}");
        assert!(!note.contains("no sensor reads"), "{note}");
        let mixed = BadInputSources { same_microsecond: 6, ..from_file.clone() };
        let note = bad_input_note("run.csv axis 0", 9, 7200, "the output", &mixed);
        assert!(
            note.contains("6 of them came in the same microsecond")
                && note.contains("the other 3 a temperature"),
            "{note}"
        );
        let all_listed = BadInputSources { first_lines: vec![7, 9], ..from_file };
        let note = bad_input_note("run.csv axis 0", 2, 7200, "the output", &all_listed);
        assert!(note.contains("; at lines 7, 9)"), "{note}");
        let arrays = bad_input_note("runs[0] axis 0", 1, 10, "flags", &BadInputSources::default());
        assert!(arrays.contains("or a time not after the one before (flag BAD_INPUT in flags)"), "{arrays}");
        // Non-finite gyro values are said as such (review23a F6), alone or beside the rest.
        let nan_gyro = BadInputSources { gyro_not_finite: 1, ..BadInputSources::default() };
        let note = bad_input_note("runs[0] axis 0", 1, 10, "flags", &nan_gyro);
        assert!(
            note.contains("1 of 10 samples (10.0 %) had a gyro value that is not a number or infinite"),
            "{note}"
        );
        assert!(!note.contains("temperature no sensor reads"), "{note}");
        let note = bad_input_note("runs[0] axis 0", 3, 10, "flags", &nan_gyro);
        assert!(
            note.contains("temperature no sensor reads") && note.contains("; 1 of them a gyro value"),
            "{note}"
        );
    }

    /// A validated run of axis 0 of `path` with `series` and a defined compensated figure:
    /// what its coverage notes need.
    fn run_of_series(path: &str, series: ReplaySeries) -> RunValidation {
        RunValidation {
            path: PathBuf::from(path),
            axis: 0,
            raw_bias_stability_dph: f64::NAN,
            compensated_bias_stability_dph: 0.001,
            series,
            ingest: IngestReport::default(),
            raw_mean_dph: f64::NAN,
            compensated_mean_dph: f64::NAN,
            input_rate_dph: None,
            windows: MetricWindows::default(),
        }
    }

    /// The reach of a model without dT/dt over -35 .. 62.55 C and -0.08 .. 0.54 C/min.
    fn t_alone_reach() -> OutsideReach {
        OutsideReach {
            temp_range_c: (-35.0, 62.55),
            rate_range_c_per_min: (-0.08, 0.54),
            rate_unused: true,
            ..OutsideReach::default()
        }
    }

    #[test]
    fn a_model_in_t_alone_is_not_called_extrapolated_at_a_rate_beyond_its_calibration() {
        // review26b F4: a cubic in T flagged OUTSIDE_HULL for a rate it does not use.
        let mut reach = t_alone_reach();
        reach.observe(20.0, 0.6, 3, false);
        let rate_only = "at a calibrated temperature, at most 0.0600 C/min beyond the calibrated -0.0800 .. 0.5400 \
                         C/min: a rate this model (a polynomial in T alone) does not use, so its value there is the \
                         polynomial's own, as inside the region";
        assert_eq!(reach.text(), format!("all of them {rate_only}"));
        // Beyond the temperatures, the temperature alone is how far it is extrapolated.
        reach.observe(63.05, 0.9, 2, false);
        assert_eq!((reach.samples_beyond, reach.samples_rate_only), (2, 3));
        assert!((reach.rate_beyond_c_per_min - 0.06).abs() < 1e-9);
        assert_eq!(
            reach.text(),
            format!(
                "2 of them at most 0.50 C beyond the calibrated -35.00 .. 62.55 C (the tracker's features), where the \
                 model is extrapolated; 3 of them {rate_only}"
            )
        );
    }

    #[test]
    fn a_model_in_t_alone_says_which_flagged_samples_are_extrapolated() {
        // review31b F1: 2 samples beyond the temperatures and 3 beyond the rates only; the
        // note's head said "the model is extrapolated there" of all 5.
        let mut reach = t_alone_reach();
        reach.observe(20.0, 0.6, 3, false);
        reach.observe(63.05, 0.9, 2, false);
        let mut series = ReplaySeries {
            samples: 10,
            compensating_from_s: 0.0,
            outside_reach: Some(reach),
            ..ReplaySeries::default()
        };
        series.flag_counts[Flags::OUTSIDE_HULL.0.trailing_zeros() as usize] = 5;
        let run = run_of_series("m.csv", series);
        let notes = run.coverage_notes();
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(
            notes[0].starts_with(
                "m.csv axis 0: 5 of 10 samples (50.0 %) lie outside the model's calibrated (T, dT/dt) region (flag \
                 OUTSIDE_HULL): 2 of them at most 0.50 C beyond the calibrated -35.00 .. 62.55 C (the tracker's \
                 features), where the model is extrapolated; 3 of them at a calibrated temperature"
            ),
            "{notes:?}"
        );
        assert_eq!(notes[0].matches("extrapolated").count(), 1, "{notes:?}");
    }

    #[test]
    fn the_outside_reach_is_the_furthest_feature_beyond_the_calibrated_ranges() {
        let mut reach = OutsideReach {
            temp_range_c: (-35.0, 62.55),
            rate_range_c_per_min: (-0.08, 0.54),
            ..OutsideReach::default()
        };
        reach.observe(20.0, 0.1, 7, false);
        assert_eq!(
            reach.text(),
            "all of them within the calibrated ranges (-35.00 .. 62.55 C, -0.0800 .. 0.5400 C/min) at combinations \
             of temperature and rate no calibration run held"
        );
        reach.observe(63.06, 0.1, 10, false);
        reach.observe(62.9, 0.3, 5, false);
        reach.observe(f64::NAN, f64::NAN, 1, false);
        assert!((reach.temp_beyond_c - 0.51).abs() < 1e-9 && reach.rate_beyond_c_per_min == 0.0);
        assert_eq!((reach.samples_beyond, reach.samples_within), (15, 8));
        assert_eq!(
            reach.text(),
            "15 of them at most 0.51 C beyond the calibrated -35.00 .. 62.55 C (the tracker's features); 8 of them \
             within the calibrated ranges (-35.00 .. 62.55 C, -0.0800 .. 0.5400 C/min) at combinations of temperature and rate \
             no calibration run held"
        );
        let mut rate_only = OutsideReach { samples_within: 0, ..reach };
        rate_only.temp_beyond_c = 0.0;
        rate_only.rate_beyond_c_per_min = 0.02;
        assert_eq!(
            rate_only.text(),
            "all of them at most 0.0200 C/min beyond the calibrated -0.0800 .. 0.5400 C/min (the tracker's features)"
        );
        // A mesh's samples inside the region (beyond its node hull) are counted apart, and
        // their features do not widen the reach.
        let beside = "inside the calibrated region but outside the hull of the mesh's nodes, where the mesh is continued \
                      from its edge";
        rate_only.observe(70.0, 0.1, 4, true);
        assert_eq!(rate_only.temp_beyond_c, 0.0);
        assert_eq!(
            rate_only.text(),
            format!(
                "15 of them at most 0.0200 C/min beyond the calibrated -0.0800 .. 0.5400 C/min (the tracker's \
                 features); 4 of them {beside}"
            )
        );
        let mut mesh_only = OutsideReach { samples_beyond: 0, samples_within: 0, ..reach };
        mesh_only.observe(20.0, 0.1, 3, true);
        assert_eq!(mesh_only.text(), format!("all of them {beside}"));
        mesh_only.observe(20.0, 0.4, 2, false);
        assert!(
            mesh_only.text().starts_with("2 of them within the calibrated ranges"),
            "{}",
            mesh_only.text()
        );
        assert!(
            mesh_only.text().ends_with(&format!("no calibration run held; 3 of them {beside}")),
            "{}",
            mesh_only.text()
        );
    }

    #[test]
    fn windows_that_data_fill_for_less_than_half_their_length_are_noted() {
        // 1 s block means of 50 samples each at full length: bursts of 5 s every 300 s, each
        // touching 6 blocks (its first and last hold 25 samples: psim-tvc's shape), against
        // the same run logged throughout, and a 0.1 Hz log (one block of 1 sample every 10 s
        // fills its windows: 10 samples x 10 s).
        let run_of = |time_s: Vec<f64>, samples: u64, fullest: u64| {
            let values = vec![0.0; time_s.len()];
            let options = BiasStabilityOptions::default();
            let stats = window_stats(&time_s, &values, &options);
            RunValidation {
                path: PathBuf::from("run.csv"),
                axis: 0,
                raw_bias_stability_dph: 0.0,
                compensated_bias_stability_dph: 0.0,
                series: ReplaySeries {
                    time_s,
                    compensating_from_s: 0.0,
                    samples,
                    fullest_block_samples: fullest,
                    ..ReplaySeries::default()
                },
                ingest: IngestReport::default(),
                raw_mean_dph: f64::NAN,
                compensated_mean_dph: f64::NAN,
                input_rate_dph: None,
                windows: MetricWindows {
                    used: stats.means.len(),
                    left_out: stats.left_out,
                    samples_used: stats.samples_used,
                    tau_s: options.tau_s,
                    used_spacing_s: stats.used_spacing_s,
                    excluded_s: 0.0,
                },
            }
        };
        let bursts: Vec<f64> =
            (0..30).flat_map(|b| (0..6).map(move |k| 300.0 * b as f64 + 0.5 + k as f64)).collect();
        let note = run_of(bursts, 30 * 250, 50).sparse_windows_note("run.csv axis 0").expect("5 s in 300");
        assert!(
            note.starts_with(
                "run.csv axis 0: data fill about 5.0 s of each 100 s averaging window (30 used, 58 left out"
            ),
            "{note}"
        );
        assert!(note.contains("the scatter of about 5 s means about 300 s apart"), "{note}");
        let whole: Vec<f64> = (0..3000).map(|k| k as f64 + 0.5).collect();
        assert!(run_of(whole, 3000 * 50, 50).sparse_windows_note("r").is_none());
        let slow: Vec<f64> = (0..300).map(|k| 10.0 * k as f64 + 0.5).collect();
        assert!(run_of(slow, 300, 1).sparse_windows_note("r").is_none());
    }

    #[test]
    fn the_white_noise_floor_is_the_closed_form_and_ignores_slow_drift() {
        use rand::SeedableRng;
        use rand_distr::Distribution;
        // 2 h of 1 s block means of white noise, sigma 0.03 deg/h at 1 s: the standard
        // deviation of 100 s means is 0.03 / sqrt(100) = 0.003 deg/h (closed form). The
        // estimate from the Allan deviation at 1 s carries about 1 / sqrt(2 (7199 - 1)) =
        // 0.8 % relative error: 3 % is over three of it.
        let sigma_1s = 0.03;
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(41);
        let normal = rand_distr::Normal::new(0.0, sigma_1s).expect("a valid sigma");
        let noise: Vec<f64> = (0..7200).map(|_| normal.sample(&mut rng)).collect();
        let run_of = |drift_dph: f64| {
            let time_s: Vec<f64> = (0..7200).map(|k| k as f64 + 0.5).collect();
            let compensated_dph: Vec<f64> = time_s
                .iter()
                .zip(&noise)
                .map(|(t, n)| n + drift_dph * (2.0 * std::f64::consts::PI * t / 1800.0).sin())
                .collect();
            let options = BiasStabilityOptions::default();
            let stats = window_stats(&time_s, &compensated_dph, &options);
            RunValidation {
                path: PathBuf::from("run.csv"),
                axis: 0,
                raw_bias_stability_dph: f64::NAN,
                compensated_bias_stability_dph: stability_of_means(stats.means.clone(), &options),
                series: ReplaySeries {
                    time_s,
                    compensated_dph,
                    compensating_from_s: 0.0,
                    ..ReplaySeries::default()
                },
                ingest: IngestReport::default(),
                raw_mean_dph: f64::NAN,
                compensated_mean_dph: f64::NAN,
                input_rate_dph: None,
                windows: MetricWindows {
                    used: stats.means.len(),
                    samples_used: stats.samples_used,
                    tau_s: options.tau_s,
                    ..MetricWindows::default()
                },
            }
        };
        let (flat, drifting) = (run_of(0.0), run_of(0.02));
        for run in [&flat, &drifting] {
            let floor = run.white_noise_floor().expect("a 2 h run has a 1 s Allan deviation");
            assert_eq!(floor.from_tau_s, 1.0);
            assert!((floor.floor_dph / (sigma_1s / 10.0) - 1.0).abs() < 0.03, "{floor:?}");
        }
        // The noise alone sits at its floor; a drift of 0.02 deg/h the compensation left
        // stands well above it, while its floor moves by under 1 %.
        let floor = |r: &RunValidation| r.white_noise_floor().map_or(f64::NAN, |f| f.floor_dph);
        assert!((flat.compensated_bias_stability_dph / floor(&flat) - 1.0).abs() < 0.25);
        assert!(drifting.compensated_bias_stability_dph > 3.0 * floor(&drifting));
        assert!((floor(&drifting) / floor(&flat) - 1.0).abs() < 0.01);
        let overall = overall_white_noise_floor([&flat, &drifting]).expect("both have floors");
        let rms = ((floor(&flat).powi(2) + floor(&drifting).powi(2)) / 2.0).sqrt();
        assert!((overall.floor_dph - rms).abs() < 1e-12);
        // `flat`'s windows over other block times: the noise's first samples at them.
        let at_times = |time_s: Vec<f64>| RunValidation {
            series: ReplaySeries {
                compensated_dph: noise[..time_s.len()].to_vec(),
                time_s,
                compensating_from_s: 0.0,
                ..ReplaySeries::default()
            },
            ..flat.clone()
        };
        // A run of 3 s stretches (under the 4 samples an Allan deviation needs): none; nor a
        // run sampled every 20 s (its spacing over a tenth of the 100 s window).
        let short = at_times((0..15).map(|k| 60.0 * (k / 3) as f64 + (k % 3) as f64 + 0.5).collect());
        assert!(short.white_noise_floor().is_none());
        assert!(overall_white_noise_floor([&flat, &short]).is_none());
        let sparse = at_times((0..360).map(|k| 20.0 * k as f64 + 0.5).collect());
        assert!(sparse.white_noise_floor().is_none());
        // Every 10 s: the floor from 10 s blocks, sigma_1s / sqrt(100 / 10) (one sample per
        // block here), within 3 x 1 / sqrt(2 x 358) = 11 %.
        let slow = at_times((0..720).map(|k| 10.0 * k as f64 + 0.5).collect());
        // Bursts of 5 s every 300 s (psim-tvc's shape): a window mean averages 5 s of data,
        // so the floor is the 1 s deviation over sqrt(5), within 3 x 1 / sqrt(2 x 96) = 22 %
        // (120 differences inside 30 bursts).
        let time_s: Vec<f64> =
            (0..30).flat_map(|b| (0..5).map(move |k| 300.0 * b as f64 + 10.5 + k as f64)).collect();
        let options = BiasStabilityOptions::default();
        let stats = window_stats(&time_s, &noise[..150], &options);
        let bursts = RunValidation {
            series: ReplaySeries {
                time_s,
                compensated_dph: noise[..150].to_vec(),
                compensating_from_s: 0.0,
                samples: 150 * 50,
                fullest_block_samples: 50,
                ..ReplaySeries::default()
            },
            windows: MetricWindows {
                used: stats.means.len(),
                samples_used: stats.samples_used,
                tau_s: 100.0,
                ..MetricWindows::default()
            },
            ..flat.clone()
        };
        let floor = bursts.white_noise_floor().expect("5 s bursts have a 1 s Allan deviation");
        assert_eq!((floor.from_tau_s, floor.averaged_s), (1.0, 5.0));
        assert!((floor.floor_dph / (sigma_1s / 5f64.sqrt()) - 1.0).abs() < 0.22, "{floor:?}");
        let floor = slow.white_noise_floor().expect("a 10 s spacing is a tenth of the window");
        assert_eq!(floor.from_tau_s, 10.0);
        assert!((floor.floor_dph / (sigma_1s / 10f64.sqrt()) - 1.0).abs() < 0.11, "{floor:?}");
    }

    #[test]
    fn distances_below_the_decimals_show_their_first_digit() {
        assert_eq!(distance_text(1.234, 2), "1.23");
        assert_eq!(distance_text(0.005, 2), "0.01");
        assert_eq!(distance_text(0.0043, 2), "0.004");
        assert_eq!(distance_text(0.00047, 2), "0.0005");
        assert_eq!(distance_text(0.00002, 4), "0.00002");
    }

    #[test]
    fn the_shorter_averaging_time_advised_counts_the_start_left_out() {
        // Blocks at 0.5 .. 239.5 s, corrected from 10 s on: 229.5 s of compensated span to
        // the last block's centre; with the first 100 s left out, 129.5 s.
        let run = |excluded_s: f64| RunValidation {
            path: PathBuf::from("short.csv"),
            compensated_bias_stability_dph: f64::NAN,
            series: ReplaySeries {
                time_s: (0..240).map(|k| k as f64 + 0.5).collect(),
                compensating_from_s: 10.0,
                samples: 240,
                ..ReplaySeries::default()
            },
            windows: MetricWindows { excluded_s, ..MetricWindows::default() },
            ..RunValidation::default()
        };
        let said = |r: RunValidation| r.notes().join("\n");
        let plain = said(run(0.0));
        assert!(
            plain.contains(
                "the compensated span is 230 s: a shorter averaging time gives figures (--tau-s at most 114"
            ),
            "{plain}"
        );
        let all = said(run(300.0));
        assert!(all.contains("the first 300 s left out cover the whole compensated span"), "{all}");
        let excluded = said(run(100.0));
        assert!(
            excluded.contains("the compensated span is 130 s after the first 100 s left out: a shorter averaging time gives figures (--tau-s at most 64"),
            "{excluded}"
        );
    }

    #[test]
    fn span_means_take_the_blocks_of_the_metrics_span_on_hand_computed_numbers() {
        let series = ReplaySeries {
            time_s: vec![0.5, 1.5, 2.5, 3.5, 4.5, 5.5],
            raw_dph: vec![9.0, 1.0, 2.0, f64::NAN, 4.0, 6.0],
            compensated_dph: vec![9.0, 0.5, -0.5, 7.0, 1.5, 0.5],
            ..ReplaySeries::default()
        };
        // From block 1: (1 + 2 + 4 + 6) / 4 and (0.5 - 0.5 + 1.5 + 0.5) / 4 (block 3 has no
        // raw value and counts for neither).
        assert_eq!(span_means(&series, 1, 0.0), (3.25, 0.5));
        // 2 s excluded after block 1's centre (1.5 s): blocks from 3.5 s on.
        assert_eq!(span_means(&series, 1, 2.0), (5.0, 1.0));
        let (raw, comp) = span_means(&series, 6, 0.0);
        assert!(raw.is_nan() && comp.is_nan(), "an empty span");
        let run = |path: &str, axis: usize| RunValidation {
            path: PathBuf::from(path),
            axis,
            raw_mean_dph: 12.0,
            compensated_mean_dph: 10.5,
            ..RunValidation::default()
        };
        let rates = [(PathBuf::from("a.csv"), 10.0)];
        let one_axis = Validation::from_runs(vec![run("a.csv", 0), run("b.csv", 0)]).with_input_rates(&rates);
        assert_eq!(one_axis.runs[0].input_rate_dph, Some(10.0));
        assert_eq!(one_axis.runs[0].residual_means_dph(), (2.0, 0.5));
        assert_eq!(one_axis.runs[1].input_rate_dph, None);
        assert_eq!(one_axis.runs[1].residual_means_dph(), (12.0, 10.5));
        // Several axes: a runs file's rate is about one input axis, so none is set.
        let two_axes = Validation::from_runs(vec![run("a.csv", 0), run("a.csv", 1)]).with_input_rates(&rates);
        assert!(two_axes.runs.iter().all(|r| r.input_rate_dph.is_none()));
    }

    #[test]
    fn a_run_made_worse_beyond_the_metrics_scatter_is_noted() {
        // 51 windows: relative standard error 1 / sqrt(100) = 10 %, so the bound is 1.2 x raw.
        let run = |raw: f64, comp: f64, used: usize| RunValidation {
            path: PathBuf::from("run.csv"),
            axis: 1,
            raw_bias_stability_dph: raw,
            compensated_bias_stability_dph: comp,
            series: ReplaySeries::default(),
            ingest: IngestReport::default(),
            raw_mean_dph: f64::NAN,
            compensated_mean_dph: f64::NAN,
            input_rate_dph: None,
            windows: MetricWindows { used, left_out: 0, ..MetricWindows::default() },
        };
        let note = run(0.005, 0.0232, 51).worse_than_raw_note("run.csv axis 1").expect("4.6 x worse");
        assert!(
            note.starts_with("run.csv axis 1: compensation made the bias stability worse: 0.02320 deg/h"),
            "{note}"
        );
        assert!(
            note.contains("(ratio 0.22)") && note.contains("about 10 % from 51 averaging windows"),
            "{note}"
        );
        assert!(run(0.005, 0.0061, 51).worse_than_raw_note("r").is_some(), "1.22 x: beyond 1.2");
        assert!(run(0.005, 0.0059, 51).worse_than_raw_note("r").is_none(), "1.18 x: within the scatter");
        assert!(
            run(0.005, 0.0232, 1).worse_than_raw_note("r").is_none(),
            "one window: no scatter to compare"
        );
        assert!(run(f64::NAN, 0.0232, 51).worse_than_raw_note("r").is_none());
        let worse = run(0.005, 0.0232, 51);
        assert!(worse.figure_notes().iter().any(|n| n.contains("made the bias stability worse")));
        assert!(worse.notes().iter().any(|n| n.contains("made the bias stability worse")));
        assert!(!worse.coverage_notes().iter().any(|n| n.contains("made the bias stability worse")));
    }

    use super::*;

    /// A log in 5 s bursts at 50 Hz every 300 s for 2 h (the shape of a thermal-vacuum
    /// recording), temperature falling 20 -> -20 C, bias `slope_dph_per_c * T` plus a
    /// deterministic +-1 deg/h wobble per burst.
    fn burst_log(slope_dph_per_c: f64) -> String {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for burst in 0..24 {
            let start_s = 300.0 * f64::from(burst);
            for k in 0..250 {
                let t = start_s + f64::from(k) * 0.02;
                let temp_c = 20.0 - 40.0 * t / 7200.0;
                let wobble = if burst % 2 == 0 { 1.0 } else { -1.0 };
                csv.push_str(&format!("{t:.3},{temp_c:.4},{}\n", slope_dph_per_c * temp_c + wobble));
            }
        }
        csv
    }

    fn sparse_config() -> CalibrationConfig {
        let features = FeatureSettings { window_s: 1200.0, block_count: 40, min_blocks: 3, max_gap_s: 400.0 };
        CalibrationConfig {
            features,
            target_window_s: 1200.0,
            method: Method::Poly,
            poly: TermSelection::default_stepwise(),
            ..CalibrationConfig::default()
        }
    }

    #[test]
    fn sparse_bursts_count_the_time_each_point_stands_for() {
        let config = sparse_config();
        let run =
            extract_run_from(burst_log(100.0).as_bytes(), Path::new("bursts.csv"), &config).expect("reads");
        let block_s = 1200.0 / 40.0;
        let c = calibration_points(std::slice::from_ref(&run), 0, false, block_s, 1200.0, 1200.0);
        // One feature update per burst (the 5 s burst lies inside one 30 s block), 300 s =
        // 10 blocks apart: every point after the first of its segment counts 10 blocks.
        let n = c.points.len() as f64;
        assert!(n >= 20.0, "{n} points");
        assert_eq!(c.block_equivalents, 1.0 + 10.0 * (n - 1.0));
        assert_eq!(c.n_eff(block_s, 1200.0), c.block_equivalents * block_s / 1200.0);
    }

    #[test]
    fn gaps_longer_than_the_trackers_are_counted_with_the_longest() {
        // The burst log: 24 bursts 300 s apart, each 250 rows 0.02 s apart, so 23 steps of
        // 300 - 249 * 0.02 = 295.02 s between bursts (the first row after each is on line
        // 2 + 250 k). With the default max gap (5 s) all 23 are gaps; with 400 s none.
        let log = burst_log(100.0);
        let run =
            extract_run_from(log.as_bytes(), Path::new("b.csv"), &CalibrationConfig::default()).unwrap();
        let g = run.gaps;
        assert_eq!((g.longer_than_s, g.count), (5.0, 23));
        assert!((g.total_s - 23.0 * 295.02).abs() < 1e-6 && (g.largest_s - 295.02).abs() < 1e-9, "{g:?}");
        // The steps are equal to the printed digits, so the longest is any burst's first row.
        let line = g.largest_before_line;
        assert!(line > 2 && (line - 2) % 250 == 0, "{line}");
        let sparse = extract_run_from(log.as_bytes(), Path::new("b.csv"), &sparse_config()).unwrap();
        assert_eq!((sparse.gaps.count, sparse.gaps.largest_before_line), (0, 0));
    }

    #[test]
    fn sparse_bursts_get_their_temperature_term() {
        // 100 deg/h per C over 40 C is a 4000 deg/h drift against a 1 deg/h wobble: the
        // stepwise selection must admit T (with n_eff = points, one per 30 s block, it
        // had 24 * 30 / 1200 = 0.6 -> 1 independent target and admitted nothing).
        let config = sparse_config();
        let run =
            extract_run_from(burst_log(100.0).as_bytes(), Path::new("bursts.csv"), &config).expect("reads");
        let fitted = fit_model(&[run], &config, [0; 32]).expect("fits");
        let axis = &fitted.axes[0];
        let poly = axis.poly.as_ref().expect("a polynomial");
        assert!(poly.terms.iter().any(|t| t.temp_power == 1 && t.rate_power == 0), "{:?}", poly.steps);
        // What remains (43 deg/h here) is the burst sampling of the causal tracker against the
        // centred targets on a 0.33 C/min ramp, about 1 % of the drift: allow 2 %.
        assert!(axis.residual_rms_dph < 0.02 * 4000.0, "{}", axis.residual_rms_dph);
    }

    #[test]
    fn contiguous_logs_count_one_block_per_point() {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..3000 {
            let t = f64::from(k) * 0.1;
            csv.push_str(&format!("{t:.1},{:.4},0.0\n", 20.0 + t / 60.0));
        }
        let config = CalibrationConfig::default();
        let run = extract_run_from(csv.as_bytes(), Path::new("c.csv"), &config).expect("reads");
        let c = calibration_points(std::slice::from_ref(&run), 0, false, 1.0, 100.0, 100.0);
        assert!(!c.points.is_empty());
        assert_eq!(c.block_equivalents, c.points.len() as f64);
    }

    /// A 3000 s ramp from `start_c` at `rate_c_per_min`, bias 0.01 T + 0.002 sin(T).
    fn ramp_log(start_c: f64, rate_c_per_min: f64) -> String {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..3000 {
            let t = f64::from(k);
            let temp_c = start_c + rate_c_per_min * t / 60.0;
            csv.push_str(&format!("{t:.1},{temp_c:.4},{:.6}\n", 0.01 * temp_c + 0.002 * temp_c.sin()));
        }
        csv
    }

    /// Review25a: a 1 Hz log whose stamps jitter by 20 us about whole seconds fell into 1 s
    /// blocks of 2, 0 and 1 samples, so the white-noise floor's gap-free stretches were too
    /// short. Oracle: the same log with exact stamps, whose blocks each hold one sample.
    #[test]
    fn a_1_hz_log_whose_stamps_jitter_gives_one_sample_a_block() {
        let config = CalibrationConfig { method: Method::Poly, ..CalibrationConfig::default() };
        let fitted = fit_ramps(&config, &[(-10.0, 0.5), (0.0, -0.3), (5.0, 0.2)]);
        let model = Model::from_bytes(&fitted.blob).expect("parses");
        let exact = ramp_log(0.0, 0.2);
        // A fixed pattern of early and late stamps: 2, 0 and 1 samples a block on a whole-second grid.
        let jittered: String = exact
            .lines()
            .enumerate()
            .map(|(i, line)| match line.split_once(',') {
                Some((t, rest)) if i > 0 => {
                    let jitter_s = if (i * 7 + i / 3) % 4 < 2 { 20e-6 } else { -20e-6 };
                    let t: f64 = t.parse().expect("a time");
                    format!("{:.6},{rest}\n", t + if i == 1 { 0.0 } else { jitter_s })
                }
                _ => format!("{line}\n"),
            })
            .collect();
        let replay = |log: &str| {
            replay_models_from(log.as_bytes(), Path::new("j.csv"), &[&model], &config.ingest, 1.0)
                .expect("replays")
                .models[0][0]
                .clone()
        };
        let (a, b) = (replay(&exact), replay(&jittered));
        assert_eq!(a.time_s.len(), 3000, "one block a sample with exact stamps");
        assert_eq!(b.time_s, a.time_s, "the jittered log's blocks are the exact log's");
        assert_eq!(b.raw_dph, a.raw_dph, "each block holds the same one sample");
        assert_eq!(b.fullest_block_samples, 1);
    }

    /// Review27b F2: the white-noise floor took the start that `--exclude-first-s` leaves out
    /// of the metric. Closed form: blocks alternating +-a have a 1 s Allan deviation of
    /// `a sqrt(2)`; the first 500 s alternate +-10, the rest +-1.
    #[test]
    fn the_white_noise_floor_leaves_out_the_start_the_metric_leaves_out() {
        let time_s: Vec<f64> = (0..1000).map(|k| f64::from(k) + 0.5).collect();
        let compensated_dph: Vec<f64> = (0..1000)
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 } * if k < 500 { 10.0 } else { 1.0 })
            .collect();
        let run = |excluded_s: f64| RunValidation {
            series: ReplaySeries {
                time_s: time_s.clone(),
                compensated_dph: compensated_dph.clone(),
                compensating_from_s: 0.0,
                ..ReplaySeries::default()
            },
            windows: MetricWindows { tau_s: 100.0, excluded_s, ..MetricWindows::default() },
            ..RunValidation::default()
        };
        let floor = |excluded_s: f64| run(excluded_s).white_noise_floor().expect("a floor").adev_dph;
        assert!((floor(500.0) - 2f64.sqrt()).abs() < 1e-9, "{}", floor(500.0));
        // Without: the mean square of both halves (and one step between them).
        let both = (0.5 * (2.0 * 100.0 + 2.0 * 1.0_f64)).sqrt();
        assert!((floor(0.0) - both).abs() < 0.01 * both, "{} against {both}", floor(0.0));
    }

    /// The block grid's origin: half a sample spacing before the stamps' phase, so a log on
    /// multiples of its spacing is grouped by whole seconds as before. Closed forms.
    #[test]
    fn the_block_grid_puts_each_stamp_half_a_spacing_from_the_edges() {
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(close(block_grid_origin_s(12.0, 1.0, 1.0), -0.5), "1 Hz on whole seconds");
        assert!(close(block_grid_origin_s(7.5, 1.0, 1.0), 0.0), "1 Hz on half seconds");
        assert!(close(block_grid_origin_s(7.3, 0.5, 1.0), 0.05), "2 Hz off the grid");
        assert!(close(block_grid_origin_s(3.0, 1.4, 1.0), -0.5), "a late second sample: a block");
        assert!(close(block_grid_origin_s(3.0, 40.0, 1.0), 0.0), "a gap first: whole seconds");
        assert!(close(block_grid_origin_s(3.0, 0.0, 1.0), 0.0), "no step: whole seconds");
        assert!(close(block_grid_origin_s(0.0, 0.49998, 1.0), -0.24999), "2 Hz, a first step a little short");
        assert!(close(block_grid_origin_s(0.03, 0.1, 1.0), 0.0), "10 Hz: whole seconds");
        assert!(close(block_grid_origin_s(15.352, 0.019, 1.0), 0.0), "50 Hz: whole seconds");
        // 2 Hz from 0 s: the samples 0.0 and 0.5 s in block 0, 1.0 s in block 1, as floor(t).
        let origin_s = block_grid_origin_s(0.0, 0.5, 1.0);
        for k in 0..40 {
            let t = f64::from(k) * 0.5;
            assert_eq!(((t - origin_s) / 1.0).floor(), t.floor(), "{t} s");
        }
    }

    /// The same logs in another order give the same calibration points in the same order
    /// (each with its own run's index) and a byte-identical mesh model.
    #[test]
    fn the_order_of_the_logs_does_not_change_the_points_or_the_model() {
        let config = CalibrationConfig { method: Method::Mesh, ..CalibrationConfig::default() };
        let read = |name: &str, start_c: f64, rate: f64| {
            extract_run_from(ramp_log(start_c, rate).as_bytes(), Path::new(name), &config).expect("reads")
        };
        let given = vec![read("a.csv", -10.0, 0.5), read("b.csv", 0.0, -0.3), read("c.csv", 5.0, 0.2)];
        let rotated: Vec<RunFeatures> = [2, 0, 1].iter().map(|&r| given[r].clone()).collect();
        let (p, q) = (
            calibration_points(&given, 0, false, 1.0, 100.0, 100.0),
            calibration_points(&rotated, 0, false, 1.0, 100.0, 100.0),
        );
        assert!(p.points == q.points, "the points come in another order ({} points)", p.points.len());
        // Run r of `rotated` is run [2, 0, 1][r] of `given`.
        let back: Vec<usize> = q.run_of.iter().map(|&r| [2, 0, 1][r]).collect();
        assert!(p.run_of == back, "the points' runs differ");
        let (a, b) = (
            fit_model(&given, &config, [0; 32]).expect("fits"),
            fit_model(&rotated, &config, [0; 32]).expect("fits"),
        );
        assert_eq!(a.axes[0].mesh_nodes, b.axes[0].mesh_nodes);
        assert!(a.axes[0].mesh_nodes > 3, "{}", a.axes[0].mesh_nodes);
        assert!(a.blob == b.blob, "the blobs differ");
    }

    /// The model `config` fits on `ramp_log`s starting at each `(start_c, rate_c_per_min)`.
    fn fit_ramps(config: &CalibrationConfig, ramps: &[(f64, f64)]) -> FittedModel {
        let runs: Vec<RunFeatures> = ramps
            .iter()
            .enumerate()
            .map(|(i, &(start_c, rate))| {
                extract_run_from(ramp_log(start_c, rate).as_bytes(), Path::new(&format!("r{i}.csv")), config)
                    .expect("reads")
            })
            .collect();
        fit_model(&runs, config, [0; 32]).expect("fits")
    }

    /// Review21 F3: the outside note counted a run's flagged samples, its reach only those in
    /// the blocks the series keeps; a last sample alone in its block (left out of the series)
    /// and outside gave the note an empty reach. Now the reach's parts count every flagged one.
    #[test]
    fn the_outside_reach_counts_the_samples_of_a_last_block_the_series_leaves_out() {
        let config = CalibrationConfig { method: Method::Poly, ..CalibrationConfig::default() };
        let fitted = fit_ramps(&config, &[(-10.0, 0.5), (0.0, -0.3), (5.0, 0.2)]);
        let model = Model::from_bytes(&fitted.blob).expect("parses");
        // A ramp that leaves the calibrated temperatures (up to 15 C) for 45 C, and one more
        // row at 3000 s: alone in its 10 s block, which the series leaves out.
        let mut log = ramp_log(20.0, 0.5);
        log.push_str("3000.0,45.0000,0.450000\n");
        let replay = replay_models_from(log.as_bytes(), Path::new("v.csv"), &[&model], &config.ingest, 10.0)
            .expect("replays");
        let series = &replay.models[0][0];
        assert_eq!(series.time_s.len(), 300, "the last, one-sample block is left out of the series");
        let flagged = series.flag_counts[Flags::OUTSIDE_HULL.0.trailing_zeros() as usize];
        let reach = series.outside_reach.expect("a polynomial with a region records its reach");
        let counted = reach.samples_beyond + reach.samples_within + reach.samples_in_region;
        assert!(flagged > 2000, "{flagged}");
        assert_eq!(counted, flagged, "every flagged sample is in one part of the reach");
    }

    /// Review21 F1/F2: a cubic in T alone, continued from the (T, dT/dt) hull's nearest point,
    /// changed with a rate it does not use, and flagged combinations inside both ranges. Oracle:
    /// its own value inside the calibrated region at the same temperature, and the ranges.
    #[test]
    fn a_polynomial_in_t_alone_does_not_change_with_the_rate_outside_the_region() {
        let config = CalibrationConfig { method: Method::CubicT, ..CalibrationConfig::default() };
        let fitted = fit_ramps(&config, &[(-10.0, 0.5), (0.0, 0.3), (5.0, 0.2)]);
        let model = Model::from_bytes(&fitted.blob).expect("parses");
        let axis = model.axis(0).expect("axis 0");
        let p = axis.provenance;
        let mid_rate = 0.5 * (p.rate_min_c_per_min + p.rate_max_c_per_min);
        let mut hint = fogtemp_core::WalkHint::default();
        let mut at = |temp: f32, rate: f32| axis.evaluate(temp, rate, &mut hint).expect("finite");
        for temp in
            [p.temp_min_c + 1.0, 0.5 * (p.temp_min_c + p.temp_max_c), p.temp_max_c - 1.0, p.temp_max_c + 5.0]
        {
            let inside = at(temp, mid_rate);
            for rate in [p.rate_min_c_per_min, p.rate_max_c_per_min, -2.0, 3.0] {
                let other = at(temp, rate);
                assert!(
                    (other.value_dph - inside.value_dph).abs() <= 1e-6 * inside.value_dph.abs().max(1e-3),
                    "T {temp} C: {} deg/h at {rate} C/min, {} at {mid_rate}",
                    other.value_dph,
                    inside.value_dph
                );
            }
        }
        // Inside both ranges is inside the region; beyond either range is outside it.
        assert!(!at(p.temp_min_c + 0.5, p.rate_max_c_per_min - 0.01).outside_hull);
        assert!(!at(p.temp_max_c - 0.5, p.rate_min_c_per_min + 0.01).outside_hull);
        assert!(at(p.temp_max_c - 0.5, p.rate_max_c_per_min + 0.5).outside_hull);
        assert!(at(p.temp_max_c + 0.5, mid_rate).outside_hull);
    }

    /// A polynomial in T alone is calibrated over the box of its ranges, so a sample flagged
    /// outside has features beyond a range: the outside note may count none "within the
    /// calibrated ranges". A run cooling into the range crosses it inside a 10 s replay block;
    /// counted at the block's end, the flagged samples of that block were "within" (psim-tvc:
    /// 49 of 250). Counted at each sample's own features, none is.
    #[test]
    fn a_model_in_t_alone_counts_no_flagged_sample_within_its_ranges() {
        let config = CalibrationConfig { method: Method::CubicT, ..CalibrationConfig::default() };
        let fitted = fit_ramps(&config, &[(-10.0, 0.5), (0.0, -0.3), (5.0, 0.2)]);
        let model = Model::from_bytes(&fitted.blob).expect("parses");
        let p = model.axis(0).expect("axis 0").provenance;
        // From 10 C above the calibrated maximum, cooling into the range within the rates.
        let log = ramp_log(f64::from(p.temp_max_c) + 10.0, -0.25);
        let replay = replay_models_from(log.as_bytes(), Path::new("v.csv"), &[&model], &config.ingest, 10.0)
            .expect("replays");
        let series = &replay.models[0][0];
        let flagged = series.flag_counts[Flags::OUTSIDE_HULL.0.trailing_zeros() as usize];
        let reach = series.outside_reach.expect("reach");
        assert!(flagged > 0, "the run starts outside");
        assert_eq!(reach.samples_within, 0, "{reach:?}");
        assert_eq!(reach.samples_beyond, flagged, "{reach:?}");
        assert!(reach.rate_unused && reach.rate_beyond_c_per_min == 0.0, "{reach:?}");
        // Within the calibrated temperatures (-15 .. 15 C), heating faster than any
        // calibration run (0.52 against 0.5 C/min at most): flagged for the rate alone, and
        // the note does not call the value extrapolated (review26b F4).
        let fast = ramp_log(-12.0, 0.52);
        let replay =
            replay_models_from(fast.as_bytes(), Path::new("fast.csv"), &[&model], &config.ingest, 10.0)
                .expect("replays");
        let series = replay.models[0][0].clone();
        let flagged = series.flag_counts[Flags::OUTSIDE_HULL.0.trailing_zeros() as usize];
        let reach = series.outside_reach.expect("reach");
        assert!(flagged > 0 && reach.samples_rate_only == flagged && reach.samples_beyond == 0, "{reach:?}");
        assert!((reach.rate_beyond_c_per_min - 0.02).abs() < 1e-3, "{reach:?}");
        let run = run_of_series("fast.csv", series);
        let notes = run.coverage_notes();
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].starts_with(&format!("fast.csv axis 0: {flagged} of ")), "{notes:?}");
        assert!(
            notes[0].contains(
                "flagged OUTSIDE_HULL for their rate alone: all of them at a calibrated temperature"
            ) && !notes[0].contains("extrapolated"),
            "{notes:?}"
        );
    }

    /// `compensate`'s note (the CLI's and Python's) counts its flagged samples with the same
    /// watch as `validate`'s: a polynomial in T alone that flags samples for their rate alone
    /// is not called extrapolated there either (it was until 2026-11-30). Oracle: validate's
    /// reach of the same log, and the closed count of the compensator's flags.
    #[test]
    fn compensation_notes_count_the_reach_as_validate_does() {
        let config = CalibrationConfig { method: Method::CubicT, ..CalibrationConfig::default() };
        let fitted = fit_ramps(&config, &[(-10.0, 0.5), (0.0, -0.3), (5.0, 0.2)]);
        let model = Model::from_bytes(&fitted.blob).expect("parses");
        let note_of = |log: &str| {
            let validated =
                replay_models_from(log.as_bytes(), Path::new("v.csv"), &[&model], &config.ingest, 10.0)
                    .expect("replays")
                    .models[0][0]
                    .outside_reach
                    .expect("reach");
            let mut comp = Compensator::<CAL_CAPACITY>::new(&model, 0).expect("compensator");
            let mut watch = OutsideWatch::new(&model, 0);
            let (mut counts, mut samples) = ([0_u64; 8], 0);
            for line in log.lines().skip(1) {
                let v: Vec<f64> = line.split(',').map(|f| f.parse().expect("number")).collect();
                let o = comp.step(crate::features::micros(v[0]), v[2] as f32, Some(v[1] as f32));
                if o.flags.contains(Flags::OUTSIDE_HULL) {
                    watch.observe(comp.tracker().features());
                }
                for (bit, count) in counts.iter_mut().enumerate() {
                    *count += u64::from((o.flags.0 >> bit) & 1);
                }
                samples += 1;
            }
            assert_eq!(watch.reach(), Some(&validated), "compensate's reach is validate's");
            let outside = counts[Flags::OUTSIDE_HULL.0.trailing_zeros() as usize];
            let notes = compensation_notes(
                "c.csv axis 0",
                &counts,
                samples,
                60.0,
                "the output",
                "the output's bias is 0",
                &BadInputSources::default(),
                watch.reach(),
            );
            (outside, notes)
        };
        // Heating faster than any calibration run at calibrated temperatures: flagged for
        // the rate alone.
        let (outside, notes) = note_of(&ramp_log(-12.0, 0.52));
        assert!(outside > 0, "{notes:?}");
        assert_eq!(
            notes,
            [format!(
                "c.csv axis 0: {outside} of 3000 samples ({} %) are flagged OUTSIDE_HULL in the output for their \
                 rate alone: all of them at a calibrated temperature, at most 0.0200 C/min beyond the calibrated \
                 -0.3000 .. 0.5000 C/min: a rate this model (a polynomial in T alone) does not use, so its value \
                 there is the polynomial's own, as inside the region",
                share_percent(outside, 3000)
            )]
        );
        // From 10 C above the calibrated maximum: extrapolated, and said so with how far.
        let p = model.axis(0).expect("axis 0").provenance;
        let (outside, notes) = note_of(&ramp_log(f64::from(p.temp_max_c) + 10.0, -0.25));
        assert!(outside > 0 && notes.len() == 1, "{notes:?}");
        let head =
            "lie outside the model's calibrated (T, dT/dt) region (flag OUTSIDE_HULL in the output): the \
                    model is extrapolated there: all of them at most ";
        assert!(
            notes[0].contains(head) && notes[0].contains(" C beyond the calibrated -14.99 .. 14.99 C"),
            "{notes:?}"
        );
        assert_eq!(notes[0].matches("extrapolated").count(), 1, "said once: {notes:?}");
    }

    /// A log whose rows come faster than any logger writes (a spreadsheet's serial days read
    /// as seconds) is said to be in another unit; a 10 kHz log is not (review32a F7).
    #[test]
    fn rows_faster_than_any_logger_are_said_to_be_in_another_unit() {
        let report = |rows: u64, span_s: f64| crate::ingest::IngestReport {
            rows,
            last_time_s: span_s,
            ..crate::ingest::IngestReport::default()
        };
        // 10,800 rows at 2 Hz, in days: 5399.5 / 86400 s.
        let days = report(10_800, 5399.5 / 86_400.0);
        let note = too_brief_note(Path::new("x.csv"), &days, "--time-unit").expect("noted");
        assert_eq!(
            note,
            "x.csv: its 10800 rows span only 6.249e-2 s, 5.8e-6 s a row, faster than any gyro's logger: are its \
             times in another unit? (--time-unit s, ms, us, ns, min or h) (dates as spreadsheets write them count \
             days: convert them to seconds first)"
        );
        assert!(too_brief_note(Path::new("a"), &days, "").expect("noted").contains("It is read in seconds"));
        assert!(
            too_brief_note(Path::new("x.csv"), &report(10_000, 0.9999), "--time-unit").is_none(),
            "10 kHz"
        );
        assert!(
            too_brief_note(Path::new("x.csv"), &report(50, 1e-6), "--time-unit").is_none(),
            "too few rows"
        );
    }

    /// `ramp_log` with the temperature cell of data row `row` (0-based) replaced by `cell`.
    fn with_temperature_cell(log: &str, row: usize, cell: &str) -> String {
        log.lines()
            .enumerate()
            .map(|(i, line)| {
                if i == row + 1 {
                    let f: Vec<&str> = line.split(',').collect();
                    format!("{},{cell},{}\n", f[0], f[2])
                } else {
                    format!("{line}\n")
                }
            })
            .collect()
    }

    /// A 50 C glitch in one cell of each log is read as that cell left empty (oracle: the
    /// same logs with the cell empty): the same feature points, the same calibrated region
    /// and byte for byte the same model; the warning names each glitch's file and line.
    #[test]
    fn a_temperature_spike_calibrates_as_a_missing_reading_and_is_named() {
        let config = CalibrationConfig { method: Method::Poly, ..CalibrationConfig::default() };
        let logs = [("a.csv", -10.0, 0.5), ("b.csv", 0.0, 0.3), ("c.csv", 5.0, 0.2)];
        let read = |cell: Option<&str>| -> Vec<RunFeatures> {
            logs.iter()
                .map(|&(name, start_c, rate)| {
                    let clean = ramp_log(start_c, rate);
                    let text = cell.map_or(clean.clone(), |c| with_temperature_cell(&clean, 1500, c));
                    extract_run_from(text.as_bytes(), Path::new(name), &config).expect("reads")
                })
                .collect()
        };
        let (glitched, emptied, clean) = (read(Some("75.0")), read(Some("")), read(None));
        for (g, e) in glitched.iter().zip(&emptied) {
            assert!(g.axes == e.axes, "{}: features differ from the emptied cell's", g.path.display());
            assert_eq!(g.temperature_spikes[0].count, 1);
            assert_eq!(g.temperature_spikes[0].first[0].line, 1502, "header + 1-based row 1501");
            assert_eq!(e.temperature_spikes[0].count, 0);
        }
        let fit = |runs: &[RunFeatures]| fit_model(runs, &config, [0; 32]).expect("fits");
        let (g, e, c) = (fit(&glitched), fit(&emptied), fit(&clean));
        assert!(g.blob == e.blob, "the models differ");
        let rates = |runs: &[RunFeatures]| {
            let p = calibration_points(runs, 0, false, 1.0, 100.0, 100.0).points;
            p.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
                (lo.min(q.rate_c_per_min), hi.max(q.rate_c_per_min))
            })
        };
        // The clean logs' rates differ from the glitched ones' by one block's features at
        // most: within 0.001 C/min on ramps at 0.2-0.5 C/min (the glitch alone spans
        // tens of C/min).
        let (rg, rc) = (rates(&glitched), rates(&clean));
        assert!((rg.0 - rc.0).abs() < 1e-3 && (rg.1 - rc.1).abs() < 1e-3, "{rg:?} against {rc:?}");
        assert!(c.axes[0].points > 0);
        let warnings = crate::identifiability::fit_warnings(&glitched, &config, &Default::default());
        let spikes: Vec<_> = warnings
            .iter()
            .filter(|w| w.kind == crate::identifiability::WarningKind::TemperatureSpikes)
            .collect();
        assert_eq!(spikes.len(), 1, "{warnings:?}");
        assert_eq!(spikes[0].values["temperature_spikes"], 3.0);
        for name in ["a.csv:1502", "b.csv:1502", "c.csv:1502"] {
            assert!(spikes[0].message.contains(name), "{}", spikes[0].message);
        }
    }

    /// A heating ramp's log with white gyro noise of 0.03 deg/h per sample (seeded), and a
    /// gyro cell of `spike_dph` at row 1500 when given.
    fn noisy_ramp_log(start_c: f64, rate_c_per_min: f64, seed: u64, spike_dph: Option<f64>) -> String {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..3000 {
            let t = f64::from(k);
            let temp_c = start_c + rate_c_per_min * t / 60.0;
            // Uniform noise of SD 0.03 (sqrt(12) x 0.03 wide): the robust SD needs no normal law.
            let noise = 0.03 * 12f64.sqrt() * (rng.gen::<f64>() - 0.5);
            let gyro = match spike_dph {
                Some(spike) if k == 1500 => spike,
                _ => 0.01 * temp_c + 0.002 * temp_c.sin() + noise,
            };
            csv.push_str(&format!("{t:.1},{temp_c:.4},{gyro:.6}\n"));
        }
        csv
    }

    /// A spike in the gyro (+1000 deg/h, and an overload code 9.91e37) at one row of every log
    /// is read as missing: the model is within 0.001 deg/h of the clean logs' over the
    /// calibrated range (one sample of ~100 in the targets of ~100 points of 9000 changes,
    /// at most 3 SD / 99 = 0.001 each; unscreened, the +1000 spike moves those targets by
    /// 10 deg/h), and the warning names each file (review12 finding 1).
    #[test]
    fn a_gyro_spike_calibrates_as_a_missing_mean_and_is_named() {
        let config = CalibrationConfig { method: Method::Poly, ..CalibrationConfig::default() };
        let logs = [("a.csv", -10.0, 0.5, 1), ("b.csv", 0.0, 0.3, 2), ("c.csv", 5.0, 0.2, 3)];
        let read = |spike: Option<f64>| -> Vec<RunFeatures> {
            logs.iter()
                .map(|&(name, start_c, rate, seed)| {
                    let text = noisy_ramp_log(start_c, rate, seed, spike);
                    extract_run_from(text.as_bytes(), Path::new(name), &config).expect("reads")
                })
                .collect()
        };
        let clean = read(None);
        assert!(clean.iter().all(|r| r.gyro_outliers[0].is_empty()), "clean logs have no outlier");
        let fit = |runs: &[RunFeatures]| fit_model(runs, &config, [0; 32]).expect("fits");
        let reference = fit(&clean);
        let reference = fogtemp_core::Model::from_bytes(&reference.blob).expect("valid");
        let value = |model: &fogtemp_core::Model<'_>, temp_c: f32, rate: f32| {
            let axis = model.axis(0).expect("axis 0");
            let mut hint = fogtemp_core::WalkHint::default();
            f64::from(axis.evaluate(temp_c, rate, &mut hint).expect("evaluates").value_dph)
        };
        for spike in [1000.0, 9.91e37] {
            let spiked = read(Some(spike));
            for run in &spiked {
                assert_eq!(run.gyro_outliers[0].len(), 1, "{}: {:?}", run.path.display(), run.gyro_outliers);
            }
            let fitted = fit(&spiked);
            let model = fogtemp_core::Model::from_bytes(&fitted.blob).expect("valid");
            for temp_c in [-5.0f32, 0.0, 5.0, 10.0, 15.0] {
                for rate in [0.2f32, 0.3, 0.5] {
                    let (got, want) = (value(&model, temp_c, rate), value(&reference, temp_c, rate));
                    assert!((got - want).abs() < 1e-3, "{spike}: at {temp_c} C, {rate}: {got} vs {want}");
                }
            }
            let warnings = crate::identifiability::fit_warnings(&spiked, &config, &Default::default());
            let named: Vec<_> = warnings
                .iter()
                .filter(|w| w.kind == crate::identifiability::WarningKind::GyroOutliers)
                .collect();
            assert_eq!(named.len(), 1, "{warnings:?}");
            assert_eq!(named[0].values["gyro_outliers"], 3.0);
            for name in ["a.csv at ", "b.csv at ", "c.csv at "] {
                assert!(named[0].message.contains(name), "{}", named[0].message);
            }
        }
    }

    /// A minute at `start_c`, then a heating ramp at `rate_c_per_min`, the temperature
    /// quantised to 0.0625 C (a 12-bit sensor) and one reading a quantum low at 12 s: 13
    /// blocks into the default 100-block window the tracker reads that as cooling at about
    /// -0.12 C/min (the demo's pos1_35C).
    fn quantised_ramp_with_dip(start_c: f64, rate_c_per_min: f64) -> String {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..3000 {
            let t = f64::from(k);
            let exact = start_c + rate_c_per_min * (t - 60.0).max(0.0) / 60.0;
            let mut temp_c = (exact / 0.0625).round() * 0.0625;
            if k == 12 {
                temp_c -= 0.0625;
            }
            csv.push_str(&format!("{t:.1},{temp_c:.4},{:.6}\n", 0.01 * exact));
        }
        csv
    }

    /// The calibrated region comes from full-window features: the model's stored rate range is
    /// the full-window points' range (oracle: those points' own extremes), the partial
    /// window's cooling reading lies outside it, and the polynomial is held and flagged there.
    ///
    /// A mesh keeps the partial window's nodes (its hull reaches the cooling reading), and the
    /// core flags its value there as outside the region.
    #[test]
    fn the_calibrated_region_is_set_by_full_windows_not_a_start_up_reading() {
        for method in [Method::Poly, Method::Mesh] {
            region_from_full_windows(method);
        }
    }

    fn region_from_full_windows(method: Method) {
        let config = CalibrationConfig { method, ..CalibrationConfig::default() };
        let runs: Vec<RunFeatures> = [(-10.0, 0.4), (10.0, 0.3), (30.0, 0.2)]
            .iter()
            .enumerate()
            .map(|(i, &(start_c, rate))| {
                let log = quantised_ramp_with_dip(start_c, rate);
                extract_run_from(log.as_bytes(), Path::new(&format!("r{i}.csv")), &config).expect("reads")
            })
            .collect();
        let calibration = calibration_points(&runs, 0, false, 1.0, 100.0, 100.0);
        let extremes = |full: bool| {
            calibration
                .points
                .iter()
                .zip(&calibration.in_region)
                .filter(|(_, &f)| f || !full)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (p, _)| {
                    (lo.min(p.rate_c_per_min), hi.max(p.rate_c_per_min))
                })
        };
        let (all, full) = (extremes(false), extremes(true));
        assert!(all.0 < -0.05, "the dip reads as cooling in a partial window: {all:?}");
        assert!(full.0 > 0.0, "full windows only heat: {full:?}");
        let fitted = fit_model(&runs, &config, [0; 32]).expect("fits");
        let model = Model::from_bytes(&fitted.blob).expect("parses");
        let axis = model.axis(0).expect("axis 0");
        let p = axis.provenance;
        assert_eq!((p.rate_min_c_per_min, p.rate_max_c_per_min), (full.0 as f32, full.1 as f32));
        let mut hint = fogtemp_core::WalkHint::default();
        let at = |temp: f32, rate: f32, hint: &mut fogtemp_core::WalkHint| {
            axis.evaluate(temp, rate, hint).expect("finite")
        };
        // The cooling the partial window read, at a temperature every run passed through.
        assert!(at(12.0, all.0 as f32, &mut hint).outside_hull, "{method:?}");
        assert!(!at(12.0, ((full.0 + full.1) / 2.0) as f32, &mut hint).outside_hull, "{method:?}");
        if let Some(mesh) = axis.mesh {
            let (x, y) = axis.normalisation.apply(12.0, all.0 as f32);
            let inside_hull = mesh.interpolate(x, y, &mut hint).map(|m| !m.outside_hull);
            assert_eq!(inside_hull, Ok(true), "the mesh's own hull reaches the partial window");
        }
    }

    /// Blocks next to a gap (a step beyond 1.5 x the median step) are read as missing, the
    /// others kept: times 0..=4, a gap, 100..=103 leave out the blocks at 4 and 100.
    #[test]
    fn blocks_at_a_gaps_edges_are_not_judged() {
        let time_s = [0.0, 1.0, 2.0, 3.0, 4.0, 100.0, 101.0, 102.0, 103.0];
        let values: Vec<f64> = (0..9).map(f64::from).collect();
        let kept = not_at_gap_edges(&time_s, &values);
        let missing: Vec<usize> = (0..9).filter(|&k| kept[k].is_nan()).collect();
        assert_eq!(missing, vec![4, 5]);
        assert_eq!(kept[3], 3.0);
        assert_eq!(not_at_gap_edges(&time_s[..5], &values[..5]), values[..5].to_vec(), "no gap, no change");
    }

    /// A run shorter than the feature window (review24a F1: a 65 s run at 13 C beside runs at
    /// 47 C) sets the calibrated region with its points from half a window on; its earlier
    /// points, and every partial window of a run that fills one, do not.
    #[test]
    fn a_run_shorter_than_the_window_sets_the_region_from_half_a_window_on() {
        let config = CalibrationConfig { method: Method::Poly, ..CalibrationConfig::default() };
        let long: Vec<RunFeatures> = [(40.0, 0.3), (45.0, -0.3)]
            .iter()
            .enumerate()
            .map(|(i, &(start_c, rate))| {
                extract_run_from(
                    ramp_log(start_c, rate).as_bytes(),
                    Path::new(&format!("long{i}.csv")),
                    &config,
                )
                .expect("reads")
            })
            .collect();
        let short_log: String = ramp_log(13.0, 0.05).lines().take(66).map(|l| format!("{l}\n")).collect();
        let short = extract_run_from(short_log.as_bytes(), Path::new("short.csv"), &config).expect("reads");
        assert!(short.axes[0].0.iter().all(|f| !f.window_full), "65 s never fills a 100 s window");
        let runs: Vec<RunFeatures> = long.iter().cloned().chain([short]).collect();
        let c = calibration_points_of(&runs, 0, &config);
        let short_run = 2;
        for ((p, &in_region), &r) in c.points.iter().zip(&c.in_region).zip(&c.run_of) {
            let feature = runs[r].axes[0]
                .0
                .iter()
                .find(|f| f.temp_c == p.temp_c && f.rate_c_per_min == p.rate_c_per_min);
            let feature = feature.expect("a point is a feature");
            let first_s = runs[r].axes[0].0[0].time_s;
            let expected = feature.window_full || (r == short_run && feature.time_s - first_s >= 50.0);
            assert_eq!(in_region, expected, "run {r} at {} s", feature.time_s);
        }
        let lowest = c.region_points().iter().map(|p| p.temp_c).fold(f64::INFINITY, f64::min);
        assert!((13.0..14.0).contains(&lowest), "the short run's temperature is in the region: {lowest}");
        let fitted = fit_model(&runs, &config, [0; 32]).expect("fits");
        let model = Model::from_bytes(&fitted.blob).expect("parses");
        let p = model.axis(0).expect("axis 0").provenance;
        assert!(p.temp_min_c < 14.0 && p.temp_max_c > 50.0, "{} .. {}", p.temp_min_c, p.temp_max_c);
    }

    /// Full-window points without an area (on one line) do not make a region: then every
    /// point does; with an area, only they do.
    #[test]
    fn region_points_fall_back_to_every_point_when_full_windows_span_no_area() {
        let point = |temp_c: f64, rate_c_per_min: f64| MeshPoint { temp_c, rate_c_per_min, value_dph: 0.0 };
        let line = vec![point(0.0, 0.125), point(10.0, 0.25), point(20.0, 0.375), point(5.0, -0.5)];
        let calibration = CalibrationPoints {
            points: line.clone(),
            run_of: vec![0; 4],
            block_equivalents: 4.0,
            in_region: vec![true, true, true, false],
        };
        assert_eq!(calibration.region_points(), line);
        let mut square = calibration.clone();
        square.points[1] = point(10.0, 0.0);
        assert_eq!(square.region_points(), square.points[..3].to_vec());
    }

    /// A temperature channel silent for rows 1000-1599 and from row 2800 to the end, the gyro
    /// going on: two silences, 601 s (reading at 999 s to reading at 1600 s, line 1602) and
    /// 200 s (to the last row at 2999 s), and the note says so; a 3 s silence is not one.
    #[test]
    fn temperature_silences_longer_than_the_gap_are_counted_with_the_longest() {
        let config = CalibrationConfig { method: Method::Poly, ..CalibrationConfig::default() };
        let mut log = ramp_log(0.0, 0.3);
        for row in (1000..1600).chain(2800..3000).chain(500..503) {
            log = with_temperature_cell(&log, row, "");
        }
        let run = extract_run_from(log.as_bytes(), Path::new("quiet.csv"), &config).expect("reads");
        let gaps = run.temperature_silences[0];
        assert_eq!((gaps.count, gaps.largest_s, gaps.largest_before_line), (2, 601.0, 1602));
        assert_eq!(gaps.total_s, 801.0);
        assert_eq!(run.gaps.count, 0, "the rows themselves have no gap");
        let note = run.temperature_silence_note(0).expect("a note");
        assert!(note.contains("silent 2 times") && note.contains("601 s before line 1602"), "{note}");
        let silent_points = run.axes[0].0.iter().filter(|p| p.time_s > 1000.0 && p.time_s < 1600.0).count();
        assert_eq!(silent_points, 0);
    }
}
