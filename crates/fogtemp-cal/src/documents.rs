//! The JSON documents of `fogtemp-cal fit`, `validate`, `inspect` and `allan` (`--json`),
//! as typed [`Serialize`] values built from the library's own results, so that a Rust or
//! Python caller gets the same document without the command.
//!
//! The key names are a contract (docs/architecture.md, Contracts): they never change. The command prints
//! each document as `serde_json::to_string_pretty(&serde_json::to_value(&doc)?)`: through a
//! `serde_json::Value` the keys come out sorted alphabetically, and NaN or infinite numbers
//! print as `null`. Numbers the model blob stores as `f32` are held here widened to `f64`
//! (exactly), as the command has always printed them.

use std::path::Path;

use fogtemp_core::{Model, OutsidePolicy};
use serde::Serialize;

use crate::allan_stream::{median_step, AllanAccumulator};
use crate::calibrate::{
    overall_white_noise_floor, AxisFitReport, FittedModel, RunFeatures, RunValidation, Validation,
    WhiteNoiseFloor,
};
use crate::ingest::{BadRow, IngestReport};
use crate::metrics::{fit_noise_terms, gap_free_ranges, AllanPoint, BiasStabilityOptions, NoiseTerms};

/// Lower-case hex of a byte string (the model's input digest).
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// What was read from one log, with the rows skipped (`fit --json`: `runs[]`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IngestDocument {
    /// The log, as displayed (lossy UTF-8).
    pub path: String,
    /// Rows accepted.
    pub rows: u64,
    /// Bytes read.
    pub bytes: u64,
    /// Rows skipped (only with `skip_bad_rows`).
    pub skipped_rows: u64,
    /// The first skipped rows (at most [`crate::ingest::MAX_REPORTED_BAD_ROWS`]).
    pub first_skipped: Vec<SkippedRowDocument>,
    /// Rows with a temperature and no gyro reading, not counted in `rows`: each reading went
    /// with the next sample ([`crate::ingest::IngestReport::temperature_only_rows`]).
    pub temperature_only_rows: u64,
    /// Gaps in the time stamps longer than the feature tracker's `max_gap_s` (`fit` only:
    /// [`crate::calibrate::TimeGaps`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_gaps: Option<TimeGapsDocument>,
}

/// Gaps in one log's time stamps (`fit --json`: `runs[].time_gaps`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TimeGapsDocument {
    /// The threshold: the tracker's `max_gap_s`.
    pub longer_than_s: f64,
    /// How many steps between consecutive rows were longer.
    pub count: u64,
    /// Their total, seconds.
    pub total_s: f64,
    /// The longest, seconds.
    pub largest_s: f64,
    /// The line of the row after the longest (0 when there is no gap).
    pub largest_before_line: u64,
}

impl TimeGapsDocument {
    /// The document of `gaps`.
    pub fn new(gaps: &crate::calibrate::TimeGaps) -> Self {
        Self {
            longer_than_s: gaps.longer_than_s,
            count: gaps.count,
            total_s: gaps.total_s,
            largest_s: gaps.largest_s,
            largest_before_line: gaps.largest_before_line,
        }
    }
}

impl IngestDocument {
    /// The document of one read.
    pub fn new(report: &IngestReport) -> Self {
        Self {
            path: report.path.display().to_string(),
            rows: report.rows,
            bytes: report.bytes,
            skipped_rows: report.skipped,
            first_skipped: report.first_skipped.iter().map(SkippedRowDocument::new).collect(),
            temperature_only_rows: report.temperature_only_rows,
            time_gaps: None,
        }
    }
}

/// One skipped row: where and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SkippedRowDocument {
    /// 1-based line.
    pub line: u64,
    /// 1-based column (field) number.
    pub column: usize,
    /// Column name from the header.
    pub column_name: String,
    /// Why, in words ([`crate::ingest::BadRowKind::describe`]).
    pub reason: &'static str,
    /// The offending text (cut to 40 characters).
    pub found: String,
}

impl SkippedRowDocument {
    /// The document of one rejected row.
    pub fn new(row: &BadRow) -> Self {
        Self {
            line: row.line,
            column: row.column,
            column_name: row.column_name.clone(),
            reason: row.kind.describe(),
            found: row.found.clone(),
        }
    }
}

/// `fit --json`: the model written, its inputs and every axis's fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitDocument {
    /// The model file, as displayed.
    pub model: String,
    /// Size of the blob, bytes.
    pub bytes: usize,
    /// SHA-256 of the calibration logs, hex.
    pub input_digest: String,
    /// Every calibration log read.
    pub runs: Vec<IngestDocument>,
    /// Every axis's fit.
    pub axes: Vec<FitAxisDocument>,
    /// What the calibration points cannot separate or do not cover
    /// ([`crate::identifiability`]; `kind`, `axis`, `message`, `values`).
    pub warnings: Vec<crate::identifiability::Warning>,
    /// The run metadata the fit used: `null` without a runs file or a simulation's manifest
    /// (review30a F9: only a note on stderr said that a manifest beside the logs was read).
    pub run_metadata: Option<RunMetadataDocument>,
}

/// The run metadata a fit used, per calibration run in the order of `runs[]`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunMetadataDocument {
    /// Where it came from: the runs file, or the simulations' `manifest.json` files (their
    /// paths, separated by ", ").
    pub source: String,
    /// Each run's position (the group `auto` leaves out when there are 3 or more).
    pub positions: Vec<String>,
    /// Each run's true input rate, deg/h.
    pub input_rates_dph: Vec<f64>,
    /// Whether the rates were subtracted from the gyro before the fit (a log of one gyro);
    /// false for logs of several gyros, whose models keep their input rates.
    pub input_rates_subtracted: bool,
}

impl FitDocument {
    /// The document of `fitted`, written to `model`, from `runs` whose contents hash to
    /// `input_digest` (the arguments of [`crate::calibrate::fit_model`]).
    pub fn new(model: &Path, fitted: &FittedModel, runs: &[RunFeatures], input_digest: &[u8; 32]) -> Self {
        Self {
            model: model.display().to_string(),
            bytes: fitted.blob.len(),
            input_digest: hex(input_digest),
            runs: runs
                .iter()
                .map(|r| IngestDocument {
                    time_gaps: Some(TimeGapsDocument::new(&r.gaps)),
                    ..IngestDocument::new(&r.ingest)
                })
                .collect(),
            axes: fitted
                .axes
                .iter()
                .enumerate()
                .map(|(axis, r)| FitAxisDocument { axis, fit: r.clone() })
                .collect(),
            warnings: Vec::new(),
            run_metadata: None,
        }
    }

    /// The document with the run metadata the fit used.
    #[must_use]
    pub fn with_run_metadata(self, run_metadata: Option<RunMetadataDocument>) -> Self {
        Self { run_metadata, ..self }
    }

    /// The document with these identifiability warnings.
    pub fn with_warnings(self, warnings: Vec<crate::identifiability::Warning>) -> Self {
        Self { warnings, ..self }
    }
}

/// One axis's fit: its index and the [`AxisFitReport`] (`poly` is the
/// [`crate::poly_fit::PolyFit`] when the model has one, null without).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FitAxisDocument {
    /// Axis index.
    pub axis: usize,
    /// What the fit did, as keys of this object.
    #[serde(flatten)]
    pub fit: AxisFitReport,
}

/// `validate --json`: raw vs compensated bias stability per run and overall, and the
/// models compared on the same logs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ValidationDocument {
    /// The bias-stability definition ([`BiasStabilityOptions::describe`]).
    pub definition: String,
    /// Raw bias stability, RMS over runs, deg/h.
    pub raw_bias_stability_dph: f64,
    /// Compensated bias stability, RMS over runs, deg/h.
    pub compensated_bias_stability_dph: f64,
    /// raw / compensated.
    pub improvement_ratio: f64,
    /// The white-noise floor under the compensated figure (RMS over runs; `null` when a run
    /// has none): `from_tau_s`, the compensated output's Allan deviation there `adev_dph`, and
    /// `floor_dph`, that extrapolated to the window as white noise
    /// ([`crate::calibrate::WhiteNoiseFloor`]). Flicker and random walk come on top.
    pub white_noise_floor: Option<WhiteNoiseFloor>,
    /// Per axis: the RMS over that axis's runs (the overall figures above pool every axis).
    pub axes: Vec<AxisValidationDocument>,
    /// Every run and axis.
    pub runs: Vec<RunValidationDocument>,
    /// The primary model then every compared one (empty without a comparison).
    pub comparison: Vec<ComparedModel>,
    /// What the command said about the runs beside the figures (stderr's notes: gaps, logs
    /// that continue one another, samples outside the calibrated region, spikes, logs with
    /// the same bytes, in-sample runs), so a script can tell (review13 F7).
    pub notes: Vec<String>,
}

impl ValidationDocument {
    /// The document with the `notes` the command gave.
    #[must_use]
    pub fn with_notes(self, notes: Vec<String>) -> Self {
        Self { notes, ..self }
    }

    /// The document of `validation` under `options`, with the `comparison` rows
    /// ([`ComparedModel::new`]).
    pub fn new(
        options: &BiasStabilityOptions,
        validation: &Validation,
        comparison: Vec<ComparedModel>,
    ) -> Self {
        Self {
            definition: options.describe(),
            raw_bias_stability_dph: validation.raw_bias_stability_dph,
            compensated_bias_stability_dph: validation.compensated_bias_stability_dph,
            improvement_ratio: validation.raw_bias_stability_dph / validation.compensated_bias_stability_dph,
            white_noise_floor: overall_white_noise_floor(&validation.runs),
            axes: validation
                .per_axis()
                .into_iter()
                .map(|(axis, raw, comp)| AxisValidationDocument {
                    axis,
                    raw_bias_stability_dph: raw,
                    compensated_bias_stability_dph: comp,
                    improvement_ratio: raw / comp,
                    white_noise_floor: overall_white_noise_floor(
                        validation.runs.iter().filter(|r| r.axis == axis),
                    ),
                })
                .collect(),
            runs: validation.runs.iter().map(RunValidationDocument::new).collect(),
            comparison,
            notes: Vec::new(),
        }
    }
}

/// One axis of a validation: the RMS over its runs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AxisValidationDocument {
    /// Axis index.
    pub axis: usize,
    /// Raw bias stability, RMS over the axis's runs, deg/h.
    pub raw_bias_stability_dph: f64,
    /// Compensated bias stability, RMS over the axis's runs, deg/h.
    pub compensated_bias_stability_dph: f64,
    /// raw / compensated.
    pub improvement_ratio: f64,
    /// The white-noise floor, RMS over the axis's runs (as the document's).
    pub white_noise_floor: Option<WhiteNoiseFloor>,
}

/// One run and axis of a validation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunValidationDocument {
    /// The log, as displayed.
    pub path: String,
    /// Axis index.
    pub axis: usize,
    /// Raw bias stability, deg/h.
    pub raw_bias_stability_dph: f64,
    /// Compensated bias stability, deg/h.
    pub compensated_bias_stability_dph: f64,
    /// The run's white-noise floor (as the document's; `null` when its gap-free stretches
    /// are too short for an Allan deviation).
    pub white_noise_floor: Option<WhiteNoiseFloor>,
    /// The run's mean raw output over the metric's span less `input_rate_dph` (when given),
    /// deg/h: the run's own bias before compensation (`null` when the span is empty).
    pub raw_mean_dph: f64,
    /// The same for the compensated output: the bias the model leaves, which bias stability
    /// does not see (`null` when the span is empty).
    pub compensated_mean_dph: f64,
    /// The run's true input rate from `--runs`, or else from a fogtemp simulation's
    /// `manifest.json` beside the logs, deg/h, subtracted from both means; `null` without
    /// either or for a model of several axes.
    pub input_rate_dph: Option<f64>,
    /// Samples replayed.
    pub samples: u64,
    /// Samples that carried each compensator flag.
    pub flag_samples: FlagSamples,
    /// Rows skipped while reading the log.
    pub skipped_rows: u64,
    /// Gaps in the log's time stamps longer than the compensator's `max_gap_s`.
    pub time_gaps: TimeGapsDocument,
    /// The averaging windows of the metric: used, and left out because a gap or the run's
    /// end cut them short.
    pub metric_windows: MetricWindowsDocument,
}

/// The averaging windows behind one run's bias stability (`validate --json`:
/// `runs[].metric_windows`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MetricWindowsDocument {
    /// Windows whose means the metric used.
    pub used: usize,
    /// Windows cut short by a gap in the time stamps or by the run's end.
    pub left_out: usize,
}

impl RunValidationDocument {
    /// The document of one run's validation.
    pub fn new(r: &RunValidation) -> Self {
        Self {
            path: r.path.display().to_string(),
            axis: r.axis,
            raw_bias_stability_dph: r.raw_bias_stability_dph,
            compensated_bias_stability_dph: r.compensated_bias_stability_dph,
            white_noise_floor: r.white_noise_floor(),
            raw_mean_dph: r.residual_means_dph().0,
            compensated_mean_dph: r.residual_means_dph().1,
            input_rate_dph: r.input_rate_dph,
            samples: r.series.samples,
            flag_samples: FlagSamples::new(&r.series.flag_counts),
            skipped_rows: r.ingest.skipped,
            time_gaps: TimeGapsDocument::new(&r.series.gaps),
            metric_windows: MetricWindowsDocument { used: r.windows.used, left_out: r.windows.left_out },
        }
    }
}

/// Samples that carried each `fogtemp_core::Flags` bit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct FlagSamples {
    /// `WARMING_UP` (bit 0): no features yet.
    pub warming_up: u64,
    /// `PARTIAL_WINDOW` (bit 1): the window is not yet full.
    pub partial_window: u64,
    /// `OUTSIDE_HULL` (bit 2): outside the calibrated region (a mesh's hull, or the region a
    /// polynomial stores), the model continued by its outside policy.
    pub outside_hull: u64,
    /// `TEMP_STALE` (bit 3): no temperature for longer than `max_gap_s`.
    pub temp_stale: u64,
    /// `BAD_INPUT` (bit 4): the sample's input was rejected.
    pub bad_input: u64,
}

impl FlagSamples {
    /// From counts per flag bit ([`crate::calibrate::ReplaySeries::flag_counts`]).
    pub fn new(counts: &[u64; 8]) -> Self {
        Self {
            warming_up: counts[0],
            partial_window: counts[1],
            outside_hull: counts[2],
            temp_stale: counts[3],
            bad_input: counts[4],
        }
    }
}

/// One model's overall result on the validation logs (`validate --compare`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ComparedModel {
    /// The model file, as displayed.
    pub model: String,
    /// Mesh nodes over every axis.
    pub mesh_nodes: u32,
    /// Polynomial terms over every axis.
    pub polynomial_terms: usize,
    /// Raw bias stability, RMS over runs, deg/h.
    pub raw_bias_stability_dph: f64,
    /// Compensated bias stability, RMS over runs, deg/h.
    pub compensated_bias_stability_dph: f64,
}

impl ComparedModel {
    /// The row of the model read from `path`, validated as `validation`.
    pub fn new(path: &Path, model: &Model<'_>, validation: &Validation) -> Self {
        let (mesh_nodes, polynomial_terms) =
            (0..model.axis_count()).filter_map(|i| model.axis(i).ok()).fold((0, 0), |(n, t), a| {
                (n + a.mesh.map_or(0, |m| m.vertex_count()), t + a.poly.map_or(0, |p| p.len()))
            });
        Self {
            model: path.display().to_string(),
            mesh_nodes,
            polynomial_terms,
            raw_bias_stability_dph: validation.raw_bias_stability_dph,
            compensated_bias_stability_dph: validation.compensated_bias_stability_dph,
        }
    }
}

/// `inspect --json`: a model's header, sections, and the mesh in physical units.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModelDocument {
    /// The model file, as displayed.
    pub model: String,
    /// Size of the blob, bytes.
    pub bytes: usize,
    /// Blob format version.
    pub format_version: u16,
    /// The tool that wrote it (lossy UTF-8).
    pub tool_version: String,
    /// SHA-256 of the calibration logs, hex.
    pub input_digest: String,
    /// How the fit read its logs' time (format 5; `null` when not recorded): `time_column`
    /// (`null` for a log without one), `date_column`, `time_unit` (`s`, `ms`, `us`,
    /// `ns`, `min`, `h`, `datetime`, `time-of-day`: `--time-unit`'s names), `sample_rate_hz` (`null` with a time column).
    pub log_time: Option<LogTimeDocument>,
    /// How the fit read its logs' numbers and which logs it read (format 6; `null` before):
    /// `decimal_mark` (`point` or `comma`), `log_digests` (per calibration log, the first 8
    /// bytes of its SHA-256, hex, in the order the fit read them).
    pub log_reading: Option<LogReadingDocument>,
    /// The shape of the fit's logs (format 7, when not the default; `null` otherwise):
    /// `skip_lines`, `delimiter` (as `--delimiter` names it: `auto`, `comma`, `semicolon`,
    /// `tab`, `whitespace` or the character), `comment` (the prefix, `null` for no comment
    /// lines), `columns` (the names of a headerless log, in order; empty with a header row),
    /// `description` (in words).
    pub log_shape: Option<LogShapeDocument>,
    /// What the fit did with its runs' true input rates (format 8, written when the fit had
    /// run metadata): `true` taken off each run's gyro (the model is the bias alone), `false`
    /// given but left in (logs with several gyro columns); `null` when not recorded (fitted
    /// without run metadata, or before format 8).
    pub input_rates_subtracted: Option<bool>,
    /// Every axis.
    pub axes: Vec<ModelAxisDocument>,
}

/// A model's log-reading record in `inspect --json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LogReadingDocument {
    /// `point` or `comma`, as `--decimal-mark` names it.
    pub decimal_mark: &'static str,
    /// Per calibration log, in the order the fit read them: the first 8 bytes of its SHA-256,
    /// hex (`sha256sum LOG | cut -c1-16`).
    pub log_digests: Vec<String>,
}

impl LogReadingDocument {
    fn of(model: &Model<'_>) -> Option<Self> {
        model.log_reading()?;
        let record = crate::blob::LogReadingRecord::of(model);
        Some(Self {
            decimal_mark: if record.decimal_comma { "comma" } else { "point" },
            log_digests: record.log_digests.iter().map(|d| hex(d)).collect(),
        })
    }
}

/// A model's log-shape record in `inspect --json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LogShapeDocument {
    /// Lines dropped unread at the start of each log.
    pub skip_lines: u64,
    /// As `--delimiter` names it.
    pub delimiter: String,
    /// The comment prefix; `None` for no comment lines.
    pub comment: Option<String>,
    /// The column names of a headerless log, in order; empty with a header row.
    pub columns: Vec<String>,
    /// The shape in words, as `validate` and `compensate` say it.
    pub description: String,
}

impl LogShapeDocument {
    fn of(model: &Model<'_>) -> Option<Self> {
        model.log_shape()?;
        // Version 8 writes the default shape out: not a shape the fit was told.
        let record = Some(crate::blob::LogShapeRecord::of(model)).filter(|r| r.is_recorded())?;
        Some(Self {
            skip_lines: record.skip_lines,
            delimiter: record.delimiter.name(),
            description: crate::axis_columns::shape_in_words(&record),
            comment: record.comment,
            columns: record.column_names,
        })
    }
}

/// A model's log-time record in `inspect --json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LogTimeDocument {
    /// The time column; `None` for a log without one.
    pub time_column: Option<String>,
    /// The date column; `None` for none.
    pub date_column: Option<String>,
    /// The time column's unit, as `--time-unit` names it.
    pub time_unit: &'static str,
    /// The sample rate of a log without a time column, Hz.
    pub sample_rate_hz: Option<f64>,
    /// In words, as the notes of `validate` say it.
    pub description: String,
}

impl LogTimeDocument {
    fn of(model: &Model<'_>) -> Option<Self> {
        let record = crate::blob::LogTimeRecord::of(model);
        let named = |n: &str| (!n.is_empty()).then(|| n.to_string());
        record.is_recorded().then(|| Self {
            time_column: named(&record.column),
            date_column: named(&record.date_column),
            time_unit: crate::ingest::TimeUnit::from_log_unit(record.unit).option_name(),
            sample_rate_hz: (record.sample_rate_hz > 0.0).then_some(record.sample_rate_hz),
            description: crate::axis_columns::describe_time(&record),
        })
    }
}

impl ModelDocument {
    /// The document of the model blob `blob`, read from `path`.
    ///
    /// # Errors
    /// The blob or one of its axes is not valid.
    pub fn new(path: &Path, blob: &[u8]) -> Result<Self, fogtemp_core::Error> {
        let model = Model::from_bytes(blob)?;
        Ok(Self {
            model: path.display().to_string(),
            bytes: blob.len(),
            format_version: model.format_version(),
            tool_version: String::from_utf8_lossy(model.tool_version()).into_owned(),
            input_digest: hex(&model.input_digest()),
            log_time: LogTimeDocument::of(&model),
            log_reading: LogReadingDocument::of(&model),
            log_shape: LogShapeDocument::of(&model),
            input_rates_subtracted: model.input_rates().map(|r| r == fogtemp_core::InputRates::Subtracted),
            axes: (0..model.axis_count())
                .map(|i| {
                    let mut axis = ModelAxisDocument::new(i, &model.axis(i)?);
                    let names = model.axis_columns(i);
                    let recorded = |n: &str| (!n.is_empty()).then(|| n.to_string());
                    axis.gyro_column = names.and_then(|c| recorded(c.gyro));
                    axis.temp_column = names.and_then(|c| recorded(c.temp));
                    axis.gyro_dph_per_unit = names.map(|c| c.gyro_dph_per_unit);
                    axis.temp_c_per_unit = names.map(|c| c.temp_c_per_unit);
                    axis.temp_offset_c = names.map(|c| c.temp_offset_c);
                    Ok(axis)
                })
                .collect::<Result<_, fogtemp_core::Error>>()?,
        })
    }
}

/// One axis of a model.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModelAxisDocument {
    /// Axis index.
    pub axis: usize,
    /// Sections present: `poly`, `mesh` (in that order).
    pub kind: Vec<&'static str>,
    /// The feature tracker's settings.
    pub features: FeaturesDocument,
    /// The normalisation of (T, dT/dt) onto the model's axes.
    pub normalisation: NormalisationDocument,
    /// How a mesh continues beyond its hull: `nearest_hull`, `zero` (a hybrid's mesh),
    /// `linear_from_boundary` or `linear_stored_gradients` (the default of `fit
    /// --mesh-outside`, spelt there `linear-stored-gradients`); `None` (null) without a mesh.
    pub outside_policy: Option<&'static str>,
    /// What the polynomial does outside the calibrated region: `extrapolate`,
    /// `hold_at_boundary` or `linear_from_boundary` (blob format 2); null without a polynomial.
    pub poly_outside: Option<&'static str>,
    /// Vertices of the calibrated region stored in the blob (the convex hull of the
    /// calibration points in the normalised plane; for a model without a rate term, such as
    /// `cubic-t`, the rectangle of the temperature and rate ranges; 0 for none, as in format 1).
    pub region_vertex_count: u32,
    /// Those vertices, counter-clockwise, normalised and in deg C and deg C/min.
    pub region: Vec<RegionVertexDocument>,
    /// The log's gyro column the axis was fitted on (blob format 4; null when not recorded).
    pub gyro_column: Option<String>,
    /// The log's temperature column that fed its features (format 4; null when not recorded).
    pub temp_column: Option<String>,
    /// Deg/h per unit of the gyro column as the fit read it (format 4; null before).
    pub gyro_dph_per_unit: Option<f64>,
    /// Deg C per unit of the temperature column as the fit read it (format 4; null before).
    pub temp_c_per_unit: Option<f64>,
    /// Added to the temperature after its scale, deg C (format 4; null before).
    pub temp_offset_c: Option<f64>,
    /// What the fit saw.
    pub provenance: ProvenanceDocument,
    /// Polynomial terms, when the axis has a polynomial.
    pub poly: Option<Vec<PolyTermDocument>>,
    /// Mesh nodes (empty without a mesh).
    pub nodes: Vec<MeshNodeDocument>,
    /// Mesh triangles, three indices into `nodes` each.
    pub triangles: Vec<[u32; 3]>,
    /// The first node of every hull edge, in the blob's order.
    pub hull: Vec<u32>,
}

impl ModelAxisDocument {
    /// The document of axis `index`.
    pub fn new(index: usize, axis: &fogtemp_core::Axis<'_>) -> Self {
        let n = &axis.normalisation;
        let mut kind = Vec::new();
        if axis.poly.is_some() {
            kind.push("poly");
        }
        if axis.mesh.is_some() {
            kind.push("mesh");
        }
        let (mut nodes, mut triangles, mut hull, mut outside_policy) =
            (Vec::new(), Vec::new(), Vec::new(), None);
        if let Some(mesh) = &axis.mesh {
            outside_policy = Some(match mesh.outside_policy() {
                OutsidePolicy::NearestHull => "nearest_hull",
                OutsidePolicy::Zero => "zero",
                OutsidePolicy::LinearFromBoundary => "linear_from_boundary",
                OutsidePolicy::StoredGradients => "linear_stored_gradients",
            });
            for v in (0..mesh.vertex_count()).filter_map(|k| mesh.vertex(k)) {
                let (temp_c, rate_c_per_min) = crate::mesh::to_physical(n, f64::from(v.x), f64::from(v.y));
                let poly = axis.poly.map_or(0.0, |p| p.evaluate(v.x, v.y));
                nodes.push(MeshNodeDocument {
                    temp_c,
                    rate_c_per_min,
                    value_dph: f64::from(poly + v.value_dph),
                    mesh_value_dph: f64::from(v.value_dph),
                    x: f64::from(v.x),
                    y: f64::from(v.y),
                });
            }
            triangles.extend((0..mesh.triangle_count()).filter_map(|k| mesh.triangle(k)).map(|t| t.vertices));
            hull.extend((0..mesh.hull_edge_count()).filter_map(|k| mesh.hull_edge(k)).filter_map(
                |(t, e)| {
                    let rec = mesh.triangle(t)?;
                    Some(rec.vertices[(e as usize + 1) % 3])
                },
            ));
        }
        let (f, p) = (&axis.features, &axis.provenance);
        Self {
            axis: index,
            kind,
            features: FeaturesDocument {
                window_s: f64::from(f.window_s),
                block_count: f.block_count,
                min_blocks: f.min_blocks,
                max_gap_s: f64::from(f.max_gap_s),
                blocks_needed: axis.blocks_needed(),
            },
            normalisation: NormalisationDocument {
                temp_offset_c: f64::from(n.temp_offset_c),
                temp_scale_per_c: f64::from(n.temp_scale_per_c),
                rate_offset_c_per_min: f64::from(n.rate_offset_c_per_min),
                rate_scale_per_c_per_min: f64::from(n.rate_scale_per_c_per_min),
            },
            outside_policy,
            poly_outside: axis.poly.as_ref().map(|_| match axis.poly_outside {
                fogtemp_core::PolyOutside::Extrapolate => "extrapolate",
                fogtemp_core::PolyOutside::HoldAtBoundary => "hold_at_boundary",
                fogtemp_core::PolyOutside::LinearFromBoundary => "linear_from_boundary",
            }),
            region_vertex_count: axis.region.as_ref().map_or(0, |r| r.vertex_count()),
            region: axis.region.as_ref().map_or_else(Vec::new, |r| {
                (0..r.vertex_count())
                    .filter_map(|i| r.vertex(i))
                    .map(|(x, y)| RegionVertexDocument {
                        x: f64::from(x),
                        y: f64::from(y),
                        temp_c: f64::from(x) / f64::from(n.temp_scale_per_c) + f64::from(n.temp_offset_c),
                        rate_c_per_min: f64::from(y) / f64::from(n.rate_scale_per_c_per_min)
                            + f64::from(n.rate_offset_c_per_min),
                    })
                    .collect()
            }),
            gyro_column: None,
            temp_column: None,
            gyro_dph_per_unit: None,
            temp_c_per_unit: None,
            temp_offset_c: None,
            provenance: ProvenanceDocument {
                fit_point_count: p.fit_point_count,
                residual_rms_dph: f64::from(p.residual_rms_dph),
                residual_max_abs_dph: f64::from(p.residual_max_abs_dph),
                temp_min_c: f64::from(p.temp_min_c),
                temp_max_c: f64::from(p.temp_max_c),
                rate_min_c_per_min: f64::from(p.rate_min_c_per_min),
                rate_max_c_per_min: f64::from(p.rate_max_c_per_min),
                selection: crate::selection::describe_blob_code(axis.selection),
            },
            poly: axis.poly.map(|poly| {
                poly.terms()
                    .map(|t| PolyTermDocument {
                        temp_power: t.temp_power,
                        rate_power: t.rate_power,
                        coefficient_dph: f64::from(t.coefficient_dph),
                    })
                    .collect()
            }),
            nodes,
            triangles,
            hull,
        }
    }
}

/// The feature tracker's settings of an axis (`fogtemp_core::FeatureSettings`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FeaturesDocument {
    /// Window of the features, s.
    pub window_s: f64,
    /// Blocks in the window.
    pub block_count: u32,
    /// Blocks needed before the first features.
    pub min_blocks: u32,
    /// A temperature gap longer than this restarts the tracker, s.
    pub max_gap_s: f64,
    /// The feature tracker capacity (block means) a firmware's `Compensator` needs for
    /// this axis (`fogtemp_core::Axis::blocks_needed`).
    pub blocks_needed: usize,
}

/// The normalisation of an axis (`fogtemp_core::Normalisation`): `x = (T - offset) scale`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NormalisationDocument {
    /// Temperature offset, deg C.
    pub temp_offset_c: f64,
    /// Temperature scale, 1/deg C.
    pub temp_scale_per_c: f64,
    /// Rate offset, deg C/min.
    pub rate_offset_c_per_min: f64,
    /// Rate scale, 1/(deg C/min).
    pub rate_scale_per_c_per_min: f64,
}

/// What the fit of an axis saw (`fogtemp_core::AxisProvenance`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProvenanceDocument {
    /// Calibration points fitted.
    pub fit_point_count: u32,
    /// RMS of the residuals at the calibration points, deg/h.
    pub residual_rms_dph: f64,
    /// Largest absolute residual, deg/h.
    pub residual_max_abs_dph: f64,
    /// Lowest temperature calibrated, deg C.
    pub temp_min_c: f64,
    /// Highest temperature calibrated, deg C.
    pub temp_max_c: f64,
    /// Lowest temperature rate calibrated, deg C/min.
    pub rate_min_c_per_min: f64,
    /// Highest temperature rate calibrated, deg C/min.
    pub rate_max_c_per_min: f64,
    /// How `fit --method auto` chose the model kind (the blob's `selection` field, in
    /// words), or null when the method was given.
    pub selection: Option<String>,
}

/// One stored polynomial term (`fogtemp_core::PolyTerm`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PolyTermDocument {
    /// Power of the normalised temperature.
    pub temp_power: u8,
    /// Power of the normalised rate.
    pub rate_power: u8,
    /// Coefficient, deg/h.
    pub coefficient_dph: f64,
}

/// One vertex of the calibrated region (`inspect --json`: `axes[].region[]`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RegionVertexDocument {
    /// Normalised temperature.
    pub x: f64,
    /// Normalised rate.
    pub y: f64,
    /// Temperature, deg C.
    pub temp_c: f64,
    /// Temperature rate, deg C/min.
    pub rate_c_per_min: f64,
}

/// One mesh node in physical units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MeshNodeDocument {
    /// Temperature, deg C.
    pub temp_c: f64,
    /// Temperature rate, deg C/min.
    pub rate_c_per_min: f64,
    /// The axis's bias at the node (polynomial plus mesh), deg/h.
    pub value_dph: f64,
    /// The mesh's own value at the node, deg/h.
    pub mesh_value_dph: f64,
    /// Normalised temperature.
    pub x: f64,
    /// Normalised rate.
    pub y: f64,
}

/// What `allan --json` says the curve is.
pub const ALLAN_DEFINITION: &str = "overlapping Allan deviation (IEEE Std 952) of the gyro, from the f64 angle cumsum (the rate relative to the mean of a stretch's first 1024 samples; the second difference cancels a constant rate), within the stretches between gaps (time steps longer than 1.5 times the median sample period; no cluster spans a gap); N, B, K by non-negative least squares on sigma^2; bias_instability_at_most_dph = the curve's minimum / 0.664 (the flicker floor lies under the curve); cluster sizes up to 65536 samples from every overlapping cluster, larger ones from clusters started every d samples (d the smallest power of two with m <= 65536 d, m rounded down to a multiple of d, tau from the rounded m; partially overlapping estimator, NIST SP 1065 section 5.2.4); sample period = median of the positive time steps (with more than 65536 distinct steps, the centre of its bin of relative width 1e-6)";

/// `allan --json`: the Allan deviation of every gyro column of a log and its noise terms.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AllanDocument {
    /// The log, as displayed.
    pub log: String,
    /// [`ALLAN_DEFINITION`].
    pub definition: &'static str,
    /// Time steps longer than 1.5 times the median sample period.
    pub gaps: usize,
    /// Every gyro column.
    pub axes: Vec<AllanAxisDocument>,
}

impl AllanDocument {
    /// The document of a log's gyro `columns`, sampled at `times_s` (s) with one series per
    /// column in `series_dph` (deg/h). `None` when no two times increase (no sample period).
    /// The same accumulator and median as the streaming route
    /// ([`crate::allan_stream::allan_of_scanned_log`]), so a log and its rows as arrays give
    /// the same document.
    pub fn new(log: &Path, columns: &[String], times_s: &[f64], series_dph: &[Vec<f64>]) -> Option<Self> {
        let dt_s = median_step(times_s)?;
        let gaps = times_s.windows(2).filter(|w| (w[1] - w[0]) > 1.5 * dt_s).count();
        let samples = series_dph.first().map_or(0, Vec::len);
        let (curves, outliers) = series_dph
            .iter()
            .zip(columns)
            .map(|(s, _)| {
                let mut accumulator = AllanAccumulator::new(dt_s);
                let mut blocks = crate::outliers::BlockMeans::of_duration(SPIKE_BLOCK_S, dt_s);
                // From the first row, as a log's rows are read (review28a 8).
                let first_s = times_s.first().copied().unwrap_or(0.0);
                for range in gap_free_ranges(times_s, dt_s) {
                    let times = times_s.get(range.clone()).unwrap_or_default();
                    for (&rate_dph, &time_s) in s.get(range).unwrap_or_default().iter().zip(times) {
                        accumulator.push(rate_dph);
                        blocks.push(time_s - first_s, rate_dph);
                    }
                    accumulator.end_segment();
                    blocks.end_segment();
                }
                (accumulator.finish(), crate::outliers::OutlierSummary::of(&blocks))
            })
            .unzip();
        Some(Self::from_curves(log, columns, dt_s, gaps, samples, curves, outliers))
    }

    /// The document from the curves already computed (one per column, in order; the
    /// streaming route): the sample period `sample_period_s`, the `gaps` split at, the
    /// `samples` per column, and each column's spikes ([`SPIKE_BLOCK_S`] means screened by
    /// [`crate::outliers::screen`]).
    pub fn from_curves(
        log: &Path,
        columns: &[String],
        sample_period_s: f64,
        gaps: usize,
        samples: usize,
        curves: Vec<Vec<AllanPoint>>,
        outliers: Vec<Option<crate::outliers::OutlierSummary>>,
    ) -> Self {
        let axes = curves
            .into_iter()
            .zip(columns)
            .zip(outliers.into_iter().chain(std::iter::repeat(None)))
            .enumerate()
            .map(|(axis, ((curve, column), gyro_outliers))| AllanAxisDocument {
                gyro_outliers,
                ..AllanAxisDocument::new(axis, column, sample_period_s, samples, curve)
            })
            .collect();
        Self { log: log.display().to_string(), definition: ALLAN_DEFINITION, gaps, axes }
    }
}

/// The Allan deviation of one gyro column.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AllanAxisDocument {
    /// Axis index.
    pub axis: usize,
    /// Gyro column name.
    pub column: String,
    /// Median sample period, s.
    pub sample_period_s: f64,
    /// Samples.
    pub samples: usize,
    /// N (deg/sqrt(h)), B (deg/h), K (deg/h/sqrt(h)), as keys of this object.
    #[serde(flatten)]
    pub noise: NoiseTerms,
    /// The curve's lowest point among averaging times with at most 25 % relative error:
    /// deviation (deg/h) and averaging time (s); NaN without one.
    pub adev_min_dph: f64,
    /// See `adev_min_dph`.
    pub adev_min_tau_s: f64,
    /// The most B can be, deg/h: the flicker floor 0.664 B lies under the curve everywhere,
    /// as the other noise terms and any drift only add to it, so B <= `adev_min_dph` / 0.664.
    pub bias_instability_at_most_dph: f64,
    /// The curve, at cluster sizes about sqrt(2) apart (1, 2, 3, 5, 8, 12, ... samples).
    pub curve: Vec<AllanPoint>,
    /// The gyro's 1 s means (or samples, when slower) beyond 10 robust SDs of their
    /// neighbours' median: spikes, which the curve and N, B, K keep as logged (`count`,
    /// `first_at_s` from the log's first row, `deviation_dph`, `robust_sd_dph`); null without any (review27a 9: one
    /// spiked sample set N 190 times too large, and nothing said so).
    pub gyro_outliers: Option<crate::outliers::OutlierSummary>,
}

/// The means the spike screen of `allan` judges, s: as `validate`'s 1 s blocks.
pub const SPIKE_BLOCK_S: f64 = 1.0;

/// The flicker floor of the Allan deviation in units of B (IEEE 952: sqrt(2 ln 2 / pi)).
const FLICKER_FLOOR: f64 = 0.664;
/// The largest relative error of an averaging time whose deviation can be the curve's
/// minimum: about 8 independent clusters or more, so that the minimum is not a dip of the
/// estimate's own noise at the longest averaging times (a compensated 2 h testbed run fell to
/// 0.25 x the flicker floor of its generator's B at 3378 s, relative error 0.67).
const MINIMUM_RELATIVE_ERROR: f64 = 0.25;

impl AllanAxisDocument {
    /// The document of one column's `curve`: its noise terms and minimum.
    fn new(axis: usize, column: &str, sample_period_s: f64, samples: usize, curve: Vec<AllanPoint>) -> Self {
        let minimum = curve
            .iter()
            .filter(|p| p.adev_dph.is_finite() && p.relative_error <= MINIMUM_RELATIVE_ERROR)
            .min_by(|a, b| a.adev_dph.total_cmp(&b.adev_dph));
        Self {
            axis,
            column: column.to_string(),
            sample_period_s,
            samples,
            noise: fit_noise_terms(&curve),
            adev_min_dph: minimum.map_or(f64::NAN, |p| p.adev_dph),
            adev_min_tau_s: minimum.map_or(f64::NAN, |p| p.tau_s),
            bias_instability_at_most_dph: minimum.map_or(f64::NAN, |p| p.adev_dph / FLICKER_FLOOR),
            curve,
            gyro_outliers: None,
        }
    }

    /// The note for spikes in the gyro ([`Self::gyro_outliers`]), `None` without any.
    pub fn outlier_note(&self) -> Option<String> {
        let o = self.gyro_outliers?;
        let (deviation, sds) = crate::outliers::deviation_text(o.deviation_dph, o.robust_sd_dph);
        Some(format!(
            "axis {} (column '{}'): {} of the gyro beyond {} robust SDs of the median around {} (the first at \
             {:.0} s, {deviation} deg/h from it, {sds} SDs): spikes or a logger's overload code, kept in the curve \
             and in N, B and K as logged, which they can raise many times over; check the log there, and quote \
             noise terms from a log without them (fit reads them as missing, validate names them)",
            self.axis,
            self.column,
            if o.count == 1 { "1 mean".to_string() } else { format!("{} means", o.count) },
            crate::outliers::ROBUST_SDS,
            if o.count == 1 { "it" } else { "them" },
            o.first_at_s,
        ))
    }

    /// The note for noise terms the fit put at zero (`None` when all three are positive or
    /// unknown): a term at its bound is not resolved by the curve, usually because another
    /// term or a drift covers it; for B the curve's minimum still bounds it.
    pub fn unresolved_terms_note(&self) -> Option<String> {
        let n = &self.noise;
        let at_zero: Vec<&str> =
            [("N", n.arw_deg_per_sqrt_h), ("B", n.bias_instability_dph), ("K", n.rrw_dph_per_sqrt_h)]
                .iter()
                .filter(|(_, v)| *v == 0.0)
                .map(|(name, _)| *name)
                .collect();
        if at_zero.is_empty() {
            return None;
        }
        let terms = at_zero.join(" and ");
        let bound = if self.adev_min_dph.is_finite() {
            format!(
                "B is at most {:.6} deg/h (the curve's minimum {:.6} deg/h at {:.0} s over 0.664)",
                self.bias_instability_at_most_dph, self.adev_min_dph, self.adev_min_tau_s
            )
        } else {
            // No averaging time has a relative error of 25 % or less (a few samples): no bound
            // (it printed "at most NaN", review15 F7).
            "no averaging time is known to 25 % or better, so the curve bounds B nowhere".to_string()
        };
        let last = self.curve.last().map_or(f64::NAN, |p| p.adev_dph);
        let why = if last > 1.5 * self.adev_min_dph {
            // On compensate's output the rise is the drift the model left: advising to run
            // compensate there was advice to do what was done (review21 second report F8).
            let advice = if self.column.starts_with("compensated_dph") {
                "this is compensate's output, so the rise is drift the model left (or slow noise the terms do not \
                 model), and the other terms, K above all, are upper bounds of the sensor's; for the sensor's own \
                 noise terms use a static run at constant temperature"
            } else {
                "for the sensor's noise terms use a static run at constant temperature, or the output of `compensate`"
            };
            format!(
                "the curve rises {:.1}x from its minimum at {:.0} s to its longest averaging time, as drift (temperature) does, and the fit gives that rise to the other terms; {bound}; {advice}",
                last / self.adev_min_dph,
                self.adev_min_tau_s
            )
        } else {
            format!("the other terms cover it on this curve; {bound}")
        };
        Some(format!(
            "axis {} (column '{}'): {terms} fitted at zero, not resolved: {why}",
            self.axis, self.column
        ))
    }

    /// The note for a fitted B above the curve's own bound (`None` otherwise): the fit spreads
    /// the curve over three terms and can put more into B than the curve's minimum allows, so
    /// the bound is the figure to report (review23b F6: "B = 0.003188 deg/h (at most 0.002856)"
    /// on one testbed log, unexplained).
    pub fn b_above_bound_note(&self) -> Option<String> {
        let (fitted, bound) = (self.noise.bias_instability_dph, self.bias_instability_at_most_dph);
        (fitted > bound).then(|| {
            format!(
                "axis {} (column '{}'): the fitted B ({fitted:.6} deg/h) is above the curve's bound ({bound:.6} deg/h, \
                 its minimum {:.6} deg/h at {:.0} s over 0.664): the three-term fit does not resolve B on this curve; \
                 report B as at most {bound:.6} deg/h",
                self.axis, self.column, self.adev_min_dph, self.adev_min_tau_s
            )
        })
    }

    /// The warning for a column too short for any averaging time (its curve empty and its
    /// noise terms unknown, NaN), or `None`.
    pub fn too_short_note(&self) -> Option<String> {
        self.curve.is_empty().then(|| {
            format!(
                "axis {} (column '{}'): {} samples are too few for an Allan deviation (at least {}): no noise terms",
                self.axis,
                self.column,
                self.samples,
                crate::metrics::ALLAN_MIN_SAMPLES
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Review27a 9: `allan` said nothing of a spike that set N 190 times too large. Oracle:
    /// the sample spiked, in a 10 Hz series of +-0.1 deg/h (a fixed pattern), is named at
    /// its 1 s block; the same series without it names nothing.
    #[test]
    fn allan_names_a_spike_in_the_gyro() {
        let times_s: Vec<f64> = (0..6000).map(|k| f64::from(k) * 0.1).collect();
        let clean: Vec<f64> = (0..6000).map(|k| 9.6 + 0.1 * f64::from((k * 7919) % 13) / 6.0 - 0.1).collect();
        let mut spiked = clean.clone();
        spiked[2345] = 1000.0;
        let columns = vec!["gyro_dph".to_string()];
        let doc = |series: &Vec<f64>| {
            AllanDocument::new(Path::new("x.csv"), &columns, &times_s, std::slice::from_ref(series))
                .expect("a document")
        };
        assert_eq!(doc(&clean).axes[0].gyro_outliers, None);
        let found = doc(&spiked).axes[0].gyro_outliers.expect("the spike is found");
        assert_eq!(found.count, 1);
        assert!((found.first_at_s - 234.0).abs() < 1e-9, "{}", found.first_at_s);
        assert!((found.deviation_dph - (1000.0 - 9.6) / 10.0).abs() < 0.05, "{}", found.deviation_dph);
        assert!(doc(&spiked).axes[0].outlier_note().expect("a note").contains("the first at 234 s"));
    }

    /// A curve with white noise falling to 0.001 deg/h at 100 s and then rising 4x, as drift
    /// does, with B fitted at zero: the note's advice depends on whether the column is
    /// compensate's output (review21 second report F8).
    fn rising(column: &str) -> AllanAxisDocument {
        let curve: Vec<AllanPoint> =
            [(1.0, 0.01, 0.01), (10.0, 0.0032, 0.03), (100.0, 0.001, 0.1), (1000.0, 0.004, 0.4)]
                .iter()
                .map(|&(tau_s, adev_dph, relative_error)| AllanPoint { tau_s, adev_dph, relative_error })
                .collect();
        let mut doc = AllanAxisDocument::new(0, column, 1.0, 7200, curve);
        doc.noise =
            NoiseTerms { arw_deg_per_sqrt_h: 1.7e-4, bias_instability_dph: 0.0, rrw_dph_per_sqrt_h: 0.01 };
        doc
    }

    #[test]
    fn the_rise_on_compensate_output_is_called_drift_left_not_a_reason_to_compensate() {
        let note = rising("compensated_dph").unresolved_terms_note().expect("B at zero");
        assert!(note.contains("the curve rises 4.0x from its minimum at 100 s"), "{note}");
        assert!(note.contains("this is compensate's output, so the rise is drift the model left"), "{note}");
        assert!(!note.contains("or the output of `compensate`"), "{note}");
        let raw = rising("gyro_dph").unresolved_terms_note().expect("B at zero");
        assert!(raw.contains("or the output of `compensate`"), "{raw}");
        assert!(!raw.contains("this is compensate's output"), "{raw}");
    }

    /// A fitted B above the curve's minimum / 0.664 is said, with the bound to report; one
    /// below it is not.
    #[test]
    fn a_fitted_b_above_the_curves_bound_is_said() {
        let mut doc = rising("gyro_dph");
        // The minimum 0.001 deg/h at 100 s bounds B at 0.001 / 0.664 = 0.001506 deg/h.
        assert!((doc.bias_instability_at_most_dph - 0.001 / 0.664).abs() < 1e-12);
        assert!(doc.b_above_bound_note().is_none(), "B fitted at zero");
        doc.noise.bias_instability_dph = 0.0016;
        let note = doc.b_above_bound_note().expect("above the bound");
        assert!(
            note.contains("the fitted B (0.001600 deg/h) is above the curve's bound (0.001506 deg/h"),
            "{note}"
        );
        assert!(note.contains("report B as at most 0.001506 deg/h"), "{note}");
    }
}
