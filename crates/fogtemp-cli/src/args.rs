//! Command-line arguments (contract: docs/architecture.md, Contracts).

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{Args, Parser, Subcommand, ValueEnum};
use fogtemp_cal::identifiability::IdentifiabilitySettings;
use fogtemp_cal::ingest::{DecimalMark, Delimiter, IngestOptions, LogFormat, RateUnit, TimeUnit};

/// fogtemp-cal: calibrate fibre-optic gyro temperature drift from lab logs and check the result.
///
/// Logs are CSV files, one per power-on run, with a header row. By default the columns are
/// time_s (seconds), temp_c (deg C) and gyro_dph (deg/h); the ingest options map other
/// names and units, and read other shapes (a banner to skip, no header, no time column,
/// comment lines, semicolon, tab or whitespace delimiters). A folder argument means every
/// *.csv file in it, sorted by name with signed numbers read as numbers (`-40C` before
/// `-10C` before `5C`).
#[derive(Debug, Parser)]
#[command(name = "fogtemp-cal", version, about, long_about = None, propagate_version = true)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Fit a model (chosen by cross-validation, or polynomial, mesh, hybrid, cubic in T) to
    /// calibration logs and write the model file.
    Fit(FitArgs),
    /// Compensate one log with a model and write the compensated CSV.
    Compensate(CompensateArgs),
    /// Replay logs through the model exactly as firmware would; report raw vs compensated bias stability.
    Validate(ValidateArgs),
    /// Evaluate a model at (temp_c, rate_c_per_min) points from a CSV file.
    Evaluate(EvaluateArgs),
    /// Show what a model file holds: header, axes, polynomial, mesh nodes and triangles.
    Inspect(InspectArgs),
    /// Write a model as a source array for firmware (Rust or C).
    Export(ExportArgs),
    /// Overlapping Allan deviation of a log's gyro, with fitted noise terms N, B, K.
    Allan(AllanArgs),
    /// Simulate a lab experiment (the built-in paper scenario or a TOML file) into CSV logs.
    Simulate(SimulateArgs),
    /// The paper's experiment end to end: simulate, calibrate on position 1 with every model,
    /// validate on position 2, and print Table 1 beside the paper's.
    Demo(DemoArgs),
    /// Compare simulated and recorded runs: where they differ, which physics the simulation
    /// left out, a fitted model of it, and whether it helps on runs it did not see.
    Diagnose(DiagnoseArgs),
}

/// How to read the logs.
#[derive(Debug, Clone, Args)]
pub struct IngestArgs {
    /// Name of the time column [default: time_s; validate and compensate: the one the model
    /// records].
    #[arg(long, help_heading = "Log columns")]
    pub time_column: Option<String>,
    /// A column with each row's date when the time column holds the time of day (a
    /// spreadsheet export's Date and Time): read together as one date-time, DATE T TIME.
    /// Needs --time-unit datetime.
    #[arg(long, value_name = "NAME", help_heading = "Log columns")]
    pub date_column: Option<String>,
    /// Unit of the time column (datetime: ISO 8601 date-times; time-of-day: hh:mm[:ss] without
    /// a date, or an elapsed h:mm:ss whose hours pass 24) [default: s; validate and
    /// compensate: the one the model records].
    #[arg(long, value_enum, help_heading = "Log columns")]
    pub time_unit: Option<TimeUnitArg>,
    /// The log has no time column: row k (0-based, counting rows rejected with
    /// --skip-bad-rows, not blank or comment lines) is at k / HZ seconds. A log that has a
    /// column named as --time-column as well is refused as ambiguous.
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, conflicts_with_all = ["time_column", "time_unit"], help_heading = "Log shape")]
    pub sample_rate_hz: Option<f64>,
    /// Lines at the start of every log to drop unread (e.g. a terminal program's banner),
    /// before the header or, with --columns, the data. Error line numbers still count them
    /// [default: 0; replaying a model: as its fit's logs].
    #[arg(long, value_name = "N", help_heading = "Log shape")]
    pub skip_lines: Option<u64>,
    /// The logs have no header row: these are their column names, in order (a,b,c). Then
    /// --time-column, --temp-column and --gyro-column choose among them; '' for logs with a
    /// header row [replaying a model: as its fit's logs].
    #[arg(long, value_name = "NAMES", value_delimiter = ',', help_heading = "Log shape")]
    pub columns: Vec<String>,
    /// Lines starting with this text (after spaces or tabs) are comments, skipped anywhere;
    /// '' for none [default: #; replaying a model: as its fit's logs].
    #[arg(long, value_name = "PREFIX", help_heading = "Log shape")]
    pub comment: Option<String>,
    /// Temperature column(s): one shared by all axes, or one per gyro column, the flag repeated
    /// [default: temp_c; replaying a model: the columns it was fitted with].
    #[arg(long = "temp-column", help_heading = "Log columns")]
    pub temp_columns: Vec<String>,
    /// temp_c = raw * temp-scale + temp-offset (for a sensor logged in raw counts) [default: 1;
    /// replaying a model: as it was fitted].
    #[arg(long, allow_negative_numbers = true, help_heading = "Log columns", value_parser = nonzero_finite)]
    pub temp_scale: Option<f64>,
    /// See --temp-scale, deg C [default: 0; replaying a model: as it was fitted].
    #[arg(long, allow_negative_numbers = true, help_heading = "Log columns", value_parser = finite)]
    pub temp_offset: Option<f64>,
    /// Gyro column(s), one model axis each, the flag repeated (--gyro-column gx --gyro-column gy)
    /// [default: gyro_dph; replaying a model: the columns it was fitted on, and named ones are
    /// checked against them]. Log shapes and options: docs/calibration-logs.md.
    #[arg(long = "gyro-column", help_heading = "Log columns")]
    pub gyro_columns: Vec<String>,
    /// Unit of the gyro columns [default: dph; replaying a model: as it was fitted].
    #[arg(long, value_enum, help_heading = "Log columns")]
    pub gyro_unit: Option<GyroUnitArg>,
    /// Extra factor applied to the gyro after unit conversion [default: 1; replaying a model:
    /// as it was fitted].
    #[arg(long, allow_negative_numbers = true, help_heading = "Log columns", value_parser = nonzero_finite)]
    pub gyro_scale: Option<f64>,
    /// Field delimiter: auto (from the header, or the first data row: the most frequent of
    /// comma, semicolon and tab, else whitespace if the fields are separated by spaces),
    /// comma, semicolon, tab, whitespace (runs of spaces and tabs, no quoting) or any one
    /// ASCII character [default: auto; replaying a model: as its fit's logs].
    #[arg(long, value_name = "DELIMITER", value_parser = parse_delimiter, help_heading = "Log shape")]
    pub delimiter: Option<Delimiter>,
    /// Decimal mark of the numbers: point (20.5) or comma (20,5, as written in many European
    /// locales; then the delimiter is not a comma, and a cell with a point is refused rather
    /// than read as a thousands separator or a decimal) [default: point; replaying a model: as
    /// it was fitted].
    #[arg(long, value_name = "MARK", value_parser = parse_decimal_mark, help_heading = "Log shape")]
    pub decimal_mark: Option<DecimalMark>,
    /// Skip malformed rows (non-numeric, NaN, short, duplicate or backward time) and report
    /// them, instead of stopping at the first.
    #[arg(long, help_heading = "Log columns")]
    pub skip_bad_rows: bool,
}

impl IngestArgs {
    /// The library's ingest settings.
    ///
    /// # Errors
    /// Settings the library refuses before reading (see `LogFormat::check`).
    pub fn options(&self) -> Result<IngestOptions> {
        let defaults = LogFormat::default();
        let or_default =
            |named: &[String], default: Vec<String>| if named.is_empty() { default } else { named.to_vec() };
        let format = LogFormat {
            time_column: self.time_column.clone().unwrap_or(defaults.time_column.clone()),
            time_unit: match self.time_unit {
                None => defaults.time_unit,
                Some(TimeUnitArg::S) => TimeUnit::Seconds,
                Some(TimeUnitArg::Ms) => TimeUnit::Milliseconds,
                Some(TimeUnitArg::Us) => TimeUnit::Microseconds,
                Some(TimeUnitArg::Ns) => TimeUnit::Nanoseconds,
                Some(TimeUnitArg::Min) => TimeUnit::Minutes,
                Some(TimeUnitArg::H) => TimeUnit::Hours,
                Some(TimeUnitArg::Datetime) => TimeUnit::DateTime,
                Some(TimeUnitArg::TimeOfDay) => TimeUnit::TimeOfDay,
            },
            temp_columns: or_default(&self.temp_columns, defaults.temp_columns),
            temp_scale: self.temp_scale.unwrap_or(defaults.temp_scale),
            temp_offset_c: self.temp_offset.unwrap_or(defaults.temp_offset_c),
            gyro_columns: or_default(&self.gyro_columns, defaults.gyro_columns),
            gyro_unit: match self.gyro_unit {
                None => defaults.gyro_unit,
                Some(GyroUnitArg::Dph) => RateUnit::DegPerHour,
                Some(GyroUnitArg::Dps) => RateUnit::DegPerSecond,
                Some(GyroUnitArg::Rps) => RateUnit::RadPerSecond,
            },
            gyro_scale: self.gyro_scale.unwrap_or(defaults.gyro_scale),
            delimiter: self.delimiter.unwrap_or(defaults.delimiter),
            skip_lines: self.skip_lines.unwrap_or(defaults.skip_lines),
            comment: match &self.comment {
                None => defaults.comment.clone(),
                Some(prefix) => (!prefix.is_empty()).then(|| prefix.clone()),
            },
            // `--columns ''`: the logs have a header row (over a model's headerless columns).
            column_names: match self.columns.as_slice() {
                [only] if only.trim().is_empty() => Vec::new(),
                names => names.iter().map(|c| c.trim().to_string()).collect(),
            },
            sample_rate_hz: self.sample_rate_hz,
            sample_rate_from_model: false,
            date_column: self.date_column.clone(),
            decimal_mark: self.decimal_mark.unwrap_or_default(),
        };
        if let Err(e) = format.check(std::path::Path::new("--options")) {
            match e {
                fogtemp_cal::CalError::LogFormat { problem, .. } => bail!("{problem}"),
                other => bail!("{other}"),
            }
        }
        Ok(IngestOptions { format, skip_bad_rows: self.skip_bad_rows, keep_impossible_temperatures: false })
    }
}

/// `--delimiter`: a name or one ASCII character.
fn parse_delimiter(text: &str) -> Result<Delimiter, String> {
    Delimiter::from_name(text)
}

fn parse_decimal_mark(text: &str) -> Result<DecimalMark, String> {
    DecimalMark::from_name(text)
}

/// Time units.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum TimeUnitArg {
    /// Seconds.
    S,
    /// Milliseconds.
    Ms,
    /// Microseconds.
    Us,
    /// Nanoseconds.
    Ns,
    /// Minutes (elapsed time as chamber controllers and data loggers write it).
    Min,
    /// Hours.
    H,
    /// ISO 8601 date-times (2026-11-24T10:00:00.125, or with a space for the T; optional Z or
    /// +01:00); without a zone read as UTC.
    Datetime,
    /// A clock time without a date (15:45, 09:05:07.25), as hand logs and terminal programs
    /// write it; past midnight the next day (a row more than 12 h before the previous one's
    /// clock time is on the next day).
    TimeOfDay,
}

/// Gyro units.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum GyroUnitArg {
    /// Degrees per hour.
    Dph,
    /// Degrees per second.
    Dps,
    /// Radians per second.
    Rps,
}

/// Model kinds.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum MethodArg {
    /// Polynomial in temperature and rate (stepwise regression).
    Poly,
    /// Delaunay mesh with linear interpolation.
    Mesh,
    /// Polynomial plus a mesh of its residuals.
    Hybrid,
    /// A cubic in temperature alone (what PX4 and ArduPilot ship): the baseline.
    #[value(name = "cubic-t")]
    CubicT,
    /// Per axis, the one of cubic-t, poly, mesh, hybrid with the best cross-validated bias
    /// stability (leave one run out, or one position with 3 or more from --runs or a
    /// simulation's manifest.json; held-out runs replayed
    /// through the firmware's Compensator), the simplest within one standard error.
    Auto,
}

/// Mesh node selection.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum ThinningArg {
    /// Insert the worst-interpolated point until within --tolerance-dph or --max-nodes.
    Greedy,
    /// The paper: one point per smoothing window, all of them while |rate| >= --fast-rate,
    /// every --settled-every-th after.
    Paper,
}

/// Polynomial term sets.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum PolyArg {
    /// Stepwise selection (F-test to enter, t-test to remove) up to --max-degree.
    Stepwise,
    /// The paper's 11 terms plus a constant.
    Paper,
}

/// What the polynomial does outside the calibrated (T, dT/dt) region.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum PolyOutsideArg {
    /// Evaluate the polynomial at the query wherever it is.
    Extrapolate,
    /// Evaluate it at the nearest point of the region's boundary (flagged OUTSIDE_HULL).
    #[value(alias = "hold")]
    HoldAtBoundary,
    /// Continue it linearly from the nearest boundary point (its tangent plane there;
    /// flagged OUTSIDE_HULL).
    #[value(alias = "linear")]
    LinearFromBoundary,
}

impl From<PolyOutsideArg> for fogtemp_core::PolyOutside {
    fn from(a: PolyOutsideArg) -> Self {
        match a {
            PolyOutsideArg::Extrapolate => fogtemp_core::PolyOutside::Extrapolate,
            PolyOutsideArg::HoldAtBoundary => fogtemp_core::PolyOutside::HoldAtBoundary,
            PolyOutsideArg::LinearFromBoundary => fogtemp_core::PolyOutside::LinearFromBoundary,
        }
    }
}

/// What a mesh model's mesh does outside its hull.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum MeshOutsideArg {
    /// The value at the nearest hull point (flagged OUTSIDE_HULL).
    #[value(alias = "nearest-hull")]
    Hold,
    /// Continued linearly from the nearest hull point, with the slope of the weighted
    /// least-squares plane of the nodes near it (flagged OUTSIDE_HULL).
    #[value(alias = "linear")]
    LinearFromBoundary,
    /// As `linear-from-boundary`, with the slope computed once by `fit` at each hull vertex
    /// and stored in the model (linear along each hull edge): an outside query costs the
    /// nearest hull point, no pass over the nodes (flagged OUTSIDE_HULL; model format 3).
    LinearStoredGradients,
}

impl From<MeshOutsideArg> for fogtemp_core::OutsidePolicy {
    fn from(a: MeshOutsideArg) -> Self {
        match a {
            MeshOutsideArg::Hold => fogtemp_core::OutsidePolicy::NearestHull,
            MeshOutsideArg::LinearFromBoundary => fogtemp_core::OutsidePolicy::LinearFromBoundary,
            MeshOutsideArg::LinearStoredGradients => fogtemp_core::OutsidePolicy::StoredGradients,
        }
    }
}

/// How `auto` scores a held-out run (hidden; docs/calibration-testbed.md).
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum CvScoringArg {
    /// Every 100 s window of the held-out run.
    WholeRun,
    /// Only the windows inside the training runs' calibrated region.
    InsideRegion,
}

/// How `auto` forms its folds (hidden; docs/calibration-testbed.md).
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum CvSchemeArg {
    /// Leave one run (or position) out.
    LeaveOneOut,
    /// Every run cut into --cv-blocks contiguous blocks, one block of each run per fold.
    BlockedKFold,
    /// Both: each held-out run scored by leaving it out and by its blocks, combined.
    RunsAndBlocks,
}

/// How `auto` corrects its fold scores (docs/calibration-testbed.md).
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum CvCorrectionArg {
    /// The fold scores as measured.
    None,
    /// Burman's (1989) correction for the folds' smaller training set.
    TrainingSize,
}

/// The scale of `auto`'s rule (hidden; docs/calibration-testbed.md).
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum RuleScaleArg {
    /// Fold scores in deg/h.
    DegPerHour,
    /// Their logarithms.
    Log,
}

/// `fit` arguments.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Blocks the firmware's feature tracker holds: its `Compensator` capacity (fogtemp-core's
    /// default, 128). A model whose window needs more blocks is refused.
    #[arg(long, default_value_t = fogtemp_core::DEFAULT_CAPACITY, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(2..))]
    pub capacity: usize,
    /// Calibration logs (files or folders of *.csv).
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Model file to write (written atomically).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Model kind.
    #[arg(long, value_enum, default_value_t = MethodArg::Auto)]
    pub method: MethodArg,
    /// Run metadata (CSV: run,position,input_rate_dph[,role]) describing every log: runs
    /// with role `val` are left out of the fit; with 3 or more positions, `auto` leaves one
    /// position out at a time instead of one run; each run's input rate is subtracted.
    /// Without it, a fogtemp simulation's `manifest.json` beside the logs gives the same.
    #[arg(long)]
    pub runs: Option<PathBuf>,
    /// Experimental: `auto` scores only the folds whose held-out runs lie within the
    /// temperature and rate ranges of the other runs (docs/calibration-testbed.md).
    #[arg(long, hide = true)]
    pub cv_inside_range_only: bool,
    /// What the polynomial (and the hybrid's polynomial) does outside the calibrated
    /// (T, dT/dt) region, stored in the model: continued linearly from the region's nearest
    /// boundary point (the default: no runaway of higher powers, exact for a linear rate
    /// term), extrapolated, or held at the boundary as the mesh holds its hull value
    /// (docs/calibration-testbed.md, "Continued linearly").
    #[arg(long, value_enum, default_value_t = PolyOutsideArg::LinearFromBoundary)]
    pub poly_outside: PolyOutsideArg,
    /// What a mesh model's mesh does outside its hull, stored in the model: continued linearly
    /// from the nearest hull point as the polynomial is, with the slope stored per hull vertex
    /// (the default: an outside query costs about what holding costs; model format 3), the
    /// same with the slope fitted per query (one pass over the mesh's nodes per outside query),
    /// or held at the nearest hull point (docs/calibration-testbed.md, "Mesh continuation with
    /// stored gradients"). The hybrid's mesh is zero outside its hull either way.
    #[arg(long, value_enum, default_value_t = MeshOutsideArg::LinearStoredGradients)]
    pub mesh_outside: MeshOutsideArg,
    /// How `auto` scores a held-out run: every window, or only the windows inside the
    /// training runs' calibrated region (docs/calibration-testbed.md).
    #[arg(long, value_enum, default_value_t = CvScoringArg::InsideRegion, hide = true)]
    pub cv_scoring: CvScoringArg,
    /// How `auto` forms its folds: leave one run (position) out, blocked K-fold within
    /// runs, or both combined per run (docs/calibration-testbed.md).
    #[arg(long, value_enum, default_value_t = CvSchemeArg::LeaveOneOut, hide = true)]
    pub cv_scheme: CvSchemeArg,
    /// The scale of `auto`'s one-standard-error rule: deg/h differences, or log ratios
    /// (docs/calibration-testbed.md).
    #[arg(long, value_enum, default_value_t = RuleScaleArg::DegPerHour, hide = true)]
    pub cv_rule_scale: RuleScaleArg,
    /// How `auto` corrects the fold scores before its rule: for the fold models' smaller
    /// training set (the default; Burman 1989: each fold score plus the difference between the
    /// full model's and the fold model's mean run score over every run; leave-one-out folds
    /// only), or not at all (docs/calibration-testbed.md).
    #[arg(long, value_enum, default_value_t = CvCorrectionArg::TrainingSize, hide = true)]
    pub cv_correction: CvCorrectionArg,
    /// Blocks per run (K) for `--cv-scheme blocked-k-fold` and `runs-and-blocks`.
    #[arg(long, default_value_t = fogtemp_cal::selection::DEFAULT_BLOCKS, hide = true)]
    pub cv_blocks: usize,
    /// Feature window (smoothing of T and dT/dt), seconds.
    #[arg(long, allow_negative_numbers = true, default_value_t = 100.0, help_heading = "Features", value_parser = positive_finite_f32)]
    pub window_s: f32,
    /// Sub-blocks per window (the rate is a least-squares slope over block means).
    #[arg(long, default_value_t = 100, help_heading = "Features", value_parser = clap::value_parser!(u32).range(2..=i64::from(fogtemp_core::wire::MAX_BLOCKS)))]
    pub blocks: u32,
    /// Blocks with data before features are reported.
    #[arg(long, default_value_t = 10, help_heading = "Features", value_parser = clap::value_parser!(u32).range(2..))]
    pub min_blocks: u32,
    /// A longer silence of the temperature channel restarts the features, seconds.
    #[arg(long, allow_negative_numbers = true, default_value_t = 5.0, help_heading = "Features", value_parser = positive_finite_f32)]
    pub max_gap_s: f32,
    /// Centred smoothing window of the gyro target, seconds (default: --window-s).
    #[arg(long, allow_negative_numbers = true, help_heading = "Features", value_parser = positive_finite)]
    pub target_window_s: Option<f64>,
    /// Use only points whose feature window is full.
    #[arg(long, help_heading = "Features")]
    pub full_windows_only: bool,
    /// Mesh node selection.
    #[arg(long, value_enum, default_value_t = ThinningArg::Greedy, help_heading = "Mesh")]
    pub thinning: ThinningArg,
    /// Greedy thinning: stop when every point is interpolated within this, deg/h
    /// (default: stop when the RMS interpolation error is 1.5 times the estimated noise of
    /// the smoothed gyro, so the mesh follows the data down to its noise and no further).
    #[arg(long, allow_negative_numbers = true, help_heading = "Mesh", value_parser = positive_finite)]
    pub tolerance_dph: Option<f64>,
    /// Greedy thinning: at most this many nodes, or every point on the convex hull if those are more (refinement may add as many again; --no-mesh-refinement).
    #[arg(long, default_value_t = 600, help_heading = "Mesh", value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(3..))]
    pub max_nodes: usize,
    /// Use each node's own smoothed target as its value (the paper) instead of fitting the
    /// node values by least squares to all calibration points (default).
    #[arg(long, help_heading = "Mesh")]
    pub interpolate_nodes: bool,
    /// Do not insert Steiner nodes where a plain mesh's triangles are too large to follow the
    /// polynomial part its node fit leaves free (by default nodes are added until the linear
    /// interpolation of that surface is within a tenth of the target noise, at most --max-nodes
    /// more, and the mesh is refitted through them at the cross-validated weight).
    #[arg(long, help_heading = "Mesh")]
    pub no_mesh_refinement: bool,
    /// Use this smoothness weight for the mesh's node fit (relative to the data/penalty
    /// balance; the cross-validated grid is 1e-4 to 1e8) instead of the cross-validated one.
    /// A diagnostic: the cross-validation still runs and is reported in the JSON.
    #[arg(long, allow_negative_numbers = true, value_parser = positive_finite, hide = true, help_heading = "Mesh")]
    pub mesh_relative_weight: Option<f64>,
    /// Fold assignments the mesh weight's cross-validation averages over (repeated K-fold;
    /// default 1). A diagnostic, for measuring what the repetition changes.
    #[arg(long, default_value_t = fogtemp_cal::mesh_fit::CV_REPEATS as u32, value_parser = clap::value_parser!(u32).range(1..=16), hide = true, help_heading = "Mesh")]
    pub mesh_cv_repeats: u32,
    /// Salt of the first of those fold assignments (0: the unsalted one). A diagnostic.
    #[arg(long, default_value_t = 0, hide = true, help_heading = "Mesh")]
    pub mesh_cv_salt: u64,
    /// Paper thinning: keep every point while |rate| >= this, deg C/min.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.05, help_heading = "Mesh", value_parser = positive_finite)]
    pub fast_rate: f64,
    /// Paper thinning: then keep one in this many.
    #[arg(long, default_value_t = 3, help_heading = "Mesh")]
    pub settled_every: usize,
    /// Polynomial terms.
    #[arg(long, value_enum, default_value_t = PolyArg::Stepwise, help_heading = "Polynomial")]
    pub poly: PolyArg,
    /// Stepwise: highest total degree of a term.
    #[arg(long, default_value_t = 4, help_heading = "Polynomial")]
    pub max_degree: u8,
    /// Stepwise: p-value to enter.
    #[arg(long, default_value_t = 0.05, help_heading = "Polynomial", value_parser = probability)]
    pub p_enter: f64,
    /// Stepwise: p-value to remove.
    #[arg(long, default_value_t = 0.10, help_heading = "Polynomial", value_parser = probability)]
    pub p_remove: f64,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Write fit-report.md with figures (calibration runs, mesh over the points) into this folder.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Temperature range the model will be used over, MIN,MAX in deg C (e.g. -40,85): a
    /// warning names any part of it the calibration does not cover (without it, a warning
    /// comes when the calibration spans less than 20 C).
    #[arg(long, value_name = "MIN,MAX", value_parser = parse_range, allow_hyphen_values = true)]
    pub operating_temp_c: Option<(f64, f64)>,
    /// Log columns and units.
    #[command(flatten)]
    pub ingest: IngestArgs,
}

impl FitArgs {
    /// What the identifiability warnings are checked against.
    pub fn identifiability(&self) -> IdentifiabilitySettings {
        IdentifiabilitySettings { operating_temp_c: self.operating_temp_c }
    }
}

/// A positive finite number.
fn positive_finite(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("expected a positive finite number, got '{text}'")),
    }
}

/// [`positive_finite`] as `f32` (the feature settings the blob stores).
fn positive_finite_f32(text: &str) -> Result<f32, String> {
    positive_finite(text).and_then(|v| {
        let single = v as f32;
        if single.is_finite() && single > 0.0 {
            Ok(single)
        } else {
            Err(format!("expected a positive number within f32's range, got '{text}'"))
        }
    })
}

/// A finite number (an offset: NaN or infinity would make every value NaN).
fn finite(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("expected a finite number, got '{text}'")),
    }
}

/// A finite, non-zero number (a scale factor).
fn nonzero_finite(text: &str) -> Result<f64, String> {
    match finite(text)? {
        0.0 => Err(format!("expected a non-zero scale, got '{text}'")),
        v => Ok(v),
    }
}

/// A probability strictly between 0 and 1 (a significance level).
fn probability(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v < 1.0 => Ok(v),
        _ => Err(format!("expected a probability between 0 and 1 (exclusive), got '{text}'")),
    }
}

fn parse_range(text: &str) -> Result<(f64, f64), String> {
    let parsed =
        text.split_once(',').and_then(|(a, b)| Some((a.trim().parse().ok()?, b.trim().parse().ok()?)));
    match parsed {
        Some((lo, hi)) if f64::is_finite(lo) && f64::is_finite(hi) && lo < hi => Ok((lo, hi)),
        _ => Err(format!("expected MIN,MAX in deg C with MIN < MAX, got '{text}'")),
    }
}

/// `compensate` arguments.
#[derive(Debug, Args)]
pub struct CompensateArgs {
    /// Blocks the firmware's feature tracker holds: its `Compensator` capacity (fogtemp-core's
    /// default, 128). A model whose window needs more blocks is refused.
    #[arg(long, default_value_t = fogtemp_core::DEFAULT_CAPACITY, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(2..))]
    pub capacity: usize,
    /// Model file.
    #[arg(long, short)]
    pub model: PathBuf,
    /// Log to compensate.
    pub log: PathBuf,
    /// Output CSV (written atomically; `-` for stdout, streamed: an error part-way leaves the rows before it): time_s (the log's own time stamps, s; from the row index with --sample-rate-hz), then per axis raw, compensated, bias, flags.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Log columns and units.
    #[command(flatten)]
    pub ingest: IngestArgs,
}

/// Bias stability options.
#[derive(Debug, Clone, Args)]
pub struct StabilityArgs {
    /// Averaging time, seconds.
    #[arg(long, default_value_t = 100.0, help_heading = "Bias stability")]
    pub tau_s: f64,
    /// Overlapping windows.
    #[arg(long, help_heading = "Bias stability")]
    pub overlapping: bool,
    /// Remove a least-squares line before the standard deviation.
    #[arg(long, help_heading = "Bias stability")]
    pub detrend: bool,
    /// Seconds at the start of each run left out.
    #[arg(long, default_value_t = 0.0, help_heading = "Bias stability")]
    pub exclude_first_s: f64,
}

/// `validate` arguments.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// Blocks the firmware's feature tracker holds: its `Compensator` capacity (fogtemp-core's
    /// default, 128). A model whose window needs more blocks is refused.
    #[arg(long, default_value_t = fogtemp_core::DEFAULT_CAPACITY, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(2..))]
    pub capacity: usize,
    /// Model file.
    #[arg(long, short)]
    pub model: PathBuf,
    /// Validation logs (files or folders).
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Write report.md with figures (runs raw vs compensated, Allan deviation, mesh) into this folder.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Also replay these models on the same logs and add a comparison table (e.g. the same
    /// calibration fitted with --thinning paper and --thinning greedy). Repeatable.
    #[arg(long = "compare", value_name = "MODEL")]
    pub compare: Vec<PathBuf>,
    /// Run metadata (CSV: run,position,input_rate_dph[,role]) describing every log: when it
    /// gives roles, only the runs with role `val` are validated; each run's means are given
    /// less its input rate. Without it, a fogtemp simulation's `manifest.json` beside the
    /// logs gives the same.
    #[arg(long)]
    pub runs: Option<PathBuf>,
    /// Bias stability definition.
    #[command(flatten)]
    pub stability: StabilityArgs,
    /// Log columns and units.
    #[command(flatten)]
    pub ingest: IngestArgs,
}

/// `evaluate` arguments.
#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// Model file.
    #[arg(long, short)]
    pub model: PathBuf,
    /// CSV with columns temp_c, rate_c_per_min (separated by commas, semicolons or tabs: found
    /// from the header).
    #[arg(long)]
    pub points: PathBuf,
    /// Model axis.
    #[arg(long, default_value_t = 0)]
    pub axis: usize,
    /// Decimal mark of the points' numbers: point (20.5) or comma (20,5; then the columns
    /// are separated by semicolons or tabs) [default: the mark of the model's calibration
    /// logs (format 6), else point]. The output always writes points.
    #[arg(long, value_name = "MARK", value_parser = parse_decimal_mark)]
    pub decimal_mark: Option<DecimalMark>,
    /// Output CSV (temp_c,rate_c_per_min,value_dph,flags); stdout if absent. flags is 0 for
    /// a point inside the calibrated region and 4 (the compensator's OUTSIDE_HULL) outside
    /// it, where the model holds or continues its boundary value.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
}

/// `inspect` arguments.
#[derive(Debug, Args)]
pub struct InspectArgs {
    /// Model file.
    #[arg(required_unless_present = "model_flag", conflicts_with = "model_flag", value_name = "MODEL")]
    pub model: Option<PathBuf>,
    /// Model file, as the other commands take it (`--model m.fogm` or `-m m.fogm`).
    #[arg(long = "model", short = 'm', id = "model_flag", value_name = "MODEL")]
    pub model_flag: Option<PathBuf>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Export formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExportFormat {
    /// A Rust `static` byte array.
    Rust,
    /// A C array with a header.
    C,
}

/// `export` arguments.
#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Model file.
    #[arg(long, short)]
    pub model: PathBuf,
    /// Source language.
    #[arg(long, value_enum)]
    pub format: ExportFormat,
    /// Output file (for C, the header is written beside it with extension .h).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Identifier of the array.
    #[arg(long, default_value = "FOGTEMP_MODEL")]
    pub name: String,
}

/// `allan` arguments.
#[derive(Debug, Args)]
pub struct AllanArgs {
    /// Log (best: a static, stationary recording).
    pub log: PathBuf,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Log columns and units.
    #[command(flatten)]
    pub ingest: IngestArgs,
}

/// `simulate` arguments.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// `paper` (the built-in scenario of the paper's experiment) or a scenario TOML file.
    #[arg(long, default_value = "paper")]
    pub scenario: String,
    /// Output folder: one NAME.csv per run, truth/NAME.csv, scenario.toml, manifest.json.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Gyro sample rate, Hz (overrides the scenario's).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Random seed (overrides the scenario's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Length of every run, s (overrides the scenario's; for quick looks).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `demo` arguments.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Output folder: logs/, models/, report/ (report/report.md is the summary).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Gyro sample rate, Hz (default: the scenario's; the paper's is 1000 Hz, about 2.7 GB of
    /// logs and under a minute here; a lower rate is quicker and the report says so).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Random seed (overrides the scenario's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// `paper` (built in) or a scenario TOML file with positions `pos1` and `pos2`.
    #[arg(long, default_value = "paper")]
    pub scenario: String,
    /// Skip the report and figures.
    #[arg(long)]
    pub no_report: bool,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `diagnose` arguments.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Folder (or file) of simulated logs in the default columns (as `simulate` writes them;
    /// its `manifest.json`, when present, gives each run's position and Earth rate).
    #[arg(long)]
    pub simulated: PathBuf,
    /// Folder (or file) of recorded logs; runs are paired with the simulated ones by file
    /// name. The log-column options below apply to these.
    #[arg(long)]
    pub recorded: PathBuf,
    /// Run metadata: a CSV file with the header `run,position,input_rate_dph` (optional
    /// `role`), one row per log (`run` = file name without `.csv`); without it, the simulated
    /// folder's `manifest.json` is read when present.
    #[arg(long)]
    pub runs: Option<PathBuf>,
    /// Print one JSON document on stdout.
    #[arg(long)]
    pub json: bool,
    /// Write report.md and SVG figures into this folder.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Length of the short means the residual is modelled on, seconds (10-100).
    #[arg(long, default_value_t = 20.0)]
    pub mean_window_s: f64,
    /// The logs are first reduced to means over this many seconds (constant memory).
    #[arg(long, default_value_t = 1.0)]
    pub bin_s: f64,
    /// Window of the least-squares temperature rate, seconds.
    #[arg(long, default_value_t = 100.0)]
    pub rate_window_s: f64,
    /// Fraction of a rate window that must hold data (lower for sparse logs, e.g. bursts).
    #[arg(long, default_value_t = 0.5)]
    pub window_coverage: f64,
    /// Fraction of a short mean that must hold data.
    #[arg(long, default_value_t = 0.9)]
    pub block_coverage: f64,
    /// Columns and units of the recorded logs.
    #[command(flatten)]
    pub ingest: IngestArgs,
}
