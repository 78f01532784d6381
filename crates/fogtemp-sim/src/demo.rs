//! The paper's experiment end to end (`fogtemp-cal demo`): simulate the scenario, calibrate
//! on one position with each model, validate on the other by replaying the raw samples
//! through the firmware's `Compensator`, and compare with the paper's Table 1.

use std::path::{Path, PathBuf};
use std::time::Instant;

use fogtemp_core::Model;
use serde::Serialize;

use fogtemp_cal::calibrate::{
    self, CalibrationConfig, Method, RunFeatures, RunValidation, Thinning, Validation,
};
use fogtemp_cal::metrics::BiasStabilityOptions;
use fogtemp_cal::selection::Selection;
use fogtemp_cal::CalError;

use crate::error::SimError;
use crate::{RunSummary, Scenario};

/// The paper's Table 1 (validation bias stability, deg/h).
pub const PAPER_RAW_DPH: f64 = 0.0153;
/// The paper's polynomial model.
pub const PAPER_POLY_DPH: f64 = 0.0084;
/// The paper's 2-D interpolation model.
pub const PAPER_MESH_DPH: f64 = 0.0051;

/// One model the demo fits.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoModel {
    /// Key in the JSON (`poly` -> `poly_dph`) and file stem.
    pub key: String,
    /// What it is, for the report.
    pub description: String,
    /// How it is fitted.
    pub config: CalibrationConfig,
}

/// The models of the demo: the paper's two, our mesh, the hybrid, and the cross-validated
/// choice (`auto`).
pub fn default_models() -> Vec<DemoModel> {
    let base = CalibrationConfig::default();
    vec![
        DemoModel {
            key: "poly".into(),
            description: "polynomial in (T, dT/dt), stepwise selection (the paper's first model)".into(),
            config: CalibrationConfig { method: Method::Poly, ..base.clone() },
        },
        DemoModel {
            key: "mesh".into(),
            description: "Delaunay mesh, greedy thinning to 1.5x the target noise, least-squares node values"
                .into(),
            config: CalibrationConfig { method: Method::Mesh, ..base.clone() },
        },
        DemoModel {
            key: "mesh_paper".into(),
            description: "Delaunay mesh with the paper's thinning (one point per 100 s window; all while \
                          |dT/dt| >= 0.05 C/min, every 3rd after) and node values as sampled (the paper's \
                          second model)"
                .into(),
            config: CalibrationConfig {
                method: Method::Mesh,
                thinning: Thinning::Paper { fast_rate_c_per_min: 0.05, settled_every: 3 },
                least_squares_nodes: false,
                ..base.clone()
            },
        },
        DemoModel {
            key: "hybrid".into(),
            description: "polynomial plus a greedy mesh of its residuals (polynomial alone outside the hull)"
                .into(),
            config: CalibrationConfig { method: Method::Hybrid, ..base.clone() },
        },
        DemoModel {
            key: "auto".into(),
            description: "per axis, the one of cubic-t, poly, mesh, hybrid with the best leave-one-run-out \
                          cross-validated bias stability, the simplest within one standard error (`fit`'s default)"
                .into(),
            config: CalibrationConfig { method: Method::Auto, ..base },
        },
    ]
}

/// Settings of a demo run.
#[derive(Clone, Debug)]
pub struct DemoOptions {
    /// Position label used for calibration.
    pub calibrate_group: String,
    /// Position label used for validation.
    pub validate_group: String,
    /// The models.
    pub models: Vec<DemoModel>,
    /// Bias-stability definition.
    pub stability: BiasStabilityOptions,
    /// Write the report and figures (with the `report` feature; ignored without it).
    pub report: bool,
}

impl Default for DemoOptions {
    fn default() -> Self {
        Self {
            calibrate_group: "pos1".into(),
            validate_group: "pos2".into(),
            models: default_models(),
            stability: BiasStabilityOptions::default(),
            report: true,
        }
    }
}

/// One model's result.
#[derive(Clone, Debug, Serialize)]
pub struct ModelResult {
    /// Key (`poly`, `mesh`, ...).
    pub key: String,
    /// What it is.
    pub description: String,
    /// The model file.
    pub model_file: PathBuf,
    /// Blob size, bytes.
    pub model_bytes: usize,
    /// Mesh nodes (0 for a polynomial).
    pub mesh_nodes: usize,
    /// Polynomial terms (0 for a pure mesh).
    pub poly_terms: usize,
    /// Residual RMS of the fit on the calibration points, deg/h.
    pub fit_residual_rms_dph: f64,
    /// Validation bias stability, RMS over runs, deg/h.
    pub compensated_dph: f64,
    /// raw / compensated.
    pub improvement_ratio: f64,
    /// Per validation run: (name, compensated bias stability deg/h).
    pub runs: Vec<(String, f64)>,
    /// For `auto`: the cross-validated choice of axis 0 (null for a given method).
    pub selection: Option<Selection>,
}

/// Everything the demo measured.
#[derive(Clone, Debug, Serialize)]
pub struct DemoResult {
    /// Scenario name.
    pub scenario: String,
    /// Gyro sample rate simulated, Hz.
    pub sample_rate_hz: f64,
    /// Seed.
    pub seed: u64,
    /// Bias-stability definition used.
    pub definition: String,
    /// Raw validation bias stability, RMS over runs, deg/h.
    pub raw_dph: f64,
    /// Per validation run: (name, raw bias stability deg/h).
    pub raw_runs: Vec<(String, f64)>,
    /// Every model.
    pub models: Vec<ModelResult>,
    /// Calibration logs.
    pub calibration_logs: Vec<PathBuf>,
    /// Validation logs.
    pub validation_logs: Vec<PathBuf>,
    /// Seconds spent: simulate, features, fit, validate.
    pub seconds: Timings,
}

/// Where the time went, seconds.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Timings {
    /// Simulation (CSV logs written).
    pub simulate: f64,
    /// Reading calibration logs and computing features.
    pub features: f64,
    /// Fitting all models.
    pub fit: f64,
    /// Replaying the validation logs through every model.
    pub validate: f64,
    /// Writing the report and figures.
    pub report: f64,
}

impl DemoResult {
    /// The result of model `key`.
    pub fn model(&self, key: &str) -> Option<&ModelResult> {
        self.models.iter().find(|m| m.key == key)
    }
}

/// Progress of the demo's stages: `(stage, done, total)` in the stage's own unit.
pub trait DemoProgress: Sync {
    /// A stage begins with `total` units.
    fn stage(&self, name: &str, total: u64);
    /// `n` more units of the current stage are done.
    fn advance(&self, n: u64);
}

/// No progress reporting.
pub struct NoProgress;

impl DemoProgress for NoProgress {
    fn stage(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
}

/// Whether two configurations read the logs into the same features and targets.
fn same_features(a: &CalibrationConfig, b: &CalibrationConfig) -> bool {
    a.ingest == b.ingest && a.features == b.features && a.target_window_s == b.target_window_s
}

fn run_name(p: &Path) -> String {
    p.file_stem().map_or_else(|| p.display().to_string(), |s| s.to_string_lossy().into_owned())
}

/// Runs the demo into `out` (`logs/`, `models/`, `report/`).
///
/// # Errors
/// Simulation, ingest, fit or report errors, each naming its file; [`SimError::NoRunsInPosition`]
/// when a position has no runs.
pub fn run_demo(
    scenario: &Scenario,
    scenario_text: &str,
    out: &Path,
    options: &DemoOptions,
    progress: &dyn DemoProgress,
) -> Result<DemoResult, SimError> {
    let mut seconds = Timings::default();
    let logs_dir = out.join("logs");
    let models_dir = out.join("models");
    for dir in [&logs_dir, &models_dir] {
        std::fs::create_dir_all(dir).map_err(|source| CalError::Io { path: dir.clone(), source })?;
    }

    let started = Instant::now();
    let total_samples: u64 = scenario
        .expanded_runs()
        .iter()
        .map(|r| (r.duration_s * scenario.sample_rate_hz).floor() as u64 + 1)
        .sum();
    progress.stage("simulate", total_samples);
    let runs = crate::simulate_to_dir(scenario, scenario_text, &logs_dir, &|n| progress.advance(n))?;
    seconds.simulate = started.elapsed().as_secs_f64();

    let logs_of = |group: &str| -> Result<Vec<PathBuf>, SimError> {
        let logs: Vec<PathBuf> =
            runs.iter().filter(|r: &&RunSummary| r.group == group).map(|r| r.file.clone()).collect();
        if logs.is_empty() {
            return Err(SimError::NoRunsInPosition { group: group.to_string() });
        }
        Ok(logs)
    };
    let calibration_logs = logs_of(&options.calibrate_group)?;
    let validation_logs = logs_of(&options.validate_group)?;

    // Features depend on the ingest and tracker settings only: compute them once per setting.
    let started = Instant::now();
    progress.stage("features", calibration_logs.len() as u64);
    // Each log's digest is taken in the same read, as `fit` does, so the models record their
    // calibration logs and `validate` names them when given them again (review21 second
    // report F1: the demo's models had a digest of zeros).
    let mut feature_sets: Vec<(CalibrationConfig, Vec<RunFeatures>, [u8; 32])> = Vec::new();
    for model in &options.models {
        if feature_sets.iter().any(|(c, _, _)| same_features(c, &model.config)) {
            continue;
        }
        let mut set = Vec::new();
        let mut digest = fogtemp_cal::digest::InputDigest::new();
        for log in &calibration_logs {
            set.push(calibrate::extract_run_digested(log, &model.config, &mut digest, |_, _| {})?);
            progress.advance(1);
        }
        feature_sets.push((model.config.clone(), set, digest.finish().0));
    }
    seconds.features = started.elapsed().as_secs_f64();

    let started = Instant::now();
    progress.stage("fit", options.models.len() as u64);
    let mut blobs = Vec::new();
    let mut selections = Vec::new();
    for model in &options.models {
        let (features, input_digest) = feature_sets
            .iter()
            .find(|(c, _, _)| same_features(c, &model.config))
            .map_or((&[][..], [0; 32]), |(_, f, d)| (f.as_slice(), *d));
        let fitted = calibrate::fit_model(features, &model.config, input_digest)?;
        let path = models_dir.join(format!("{}.fogm", model.key));
        fogtemp_cal::output::write_file_atomic(&path, |w| std::io::Write::write_all(w, &fitted.blob))?;
        selections.push(fitted.axes.first().and_then(|r| r.selection.clone()));
        blobs.push(FittedFile { path, fitted });
        progress.advance(1);
    }
    seconds.fit = started.elapsed().as_secs_f64();

    let started = Instant::now();
    progress.stage("validate", validation_logs.len() as u64);
    let parsed: Vec<Model<'_>> = blobs
        .iter()
        .map(|b| Model::from_bytes(&b.fitted.blob).map_err(CalError::SelfCheck))
        .collect::<Result<_, _>>()?;
    let outcomes = validate_all(&validation_logs, &parsed, options, progress)?;
    let mut results = Vec::new();
    let mut validations: Vec<(Vec<RunValidation>, f64)> = Vec::new();
    let mut raw_dph = f64::NAN;
    let mut raw_runs = Vec::new();
    for (((model, file), validation), selection) in
        options.models.iter().zip(&blobs).zip(outcomes).zip(selections)
    {
        let Validation { runs, raw_bias_stability_dph: raw, compensated_bias_stability_dph: comp } =
            validation;
        raw_dph = raw;
        raw_runs = runs.iter().map(|r| (run_name(&r.path), r.raw_bias_stability_dph)).collect();
        results.push(ModelResult {
            key: model.key.clone(),
            description: model.description.clone(),
            model_file: file.path.clone(),
            model_bytes: file.fitted.blob.len(),
            mesh_nodes: file.first_axis().map_or(0, |r| r.mesh_nodes),
            poly_terms: file.first_axis().and_then(|r| r.poly.as_ref()).map_or(0, |p| p.terms.len()),
            fit_residual_rms_dph: file.first_axis().map_or(f64::NAN, |r| r.residual_rms_dph),
            compensated_dph: comp,
            improvement_ratio: raw / comp,
            runs: runs.iter().map(|r| (run_name(&r.path), r.compensated_bias_stability_dph)).collect(),
            selection,
        });
        validations.push((runs, raw));
    }
    seconds.validate = started.elapsed().as_secs_f64();

    let mut result = DemoResult {
        scenario: scenario.name.clone(),
        sample_rate_hz: scenario.sample_rate_hz,
        seed: scenario.seed,
        definition: options.stability.describe(),
        raw_dph,
        raw_runs,
        models: results,
        calibration_logs,
        validation_logs,
        seconds,
    };
    if options.report {
        let started = Instant::now();
        progress.stage("report", 1);
        // All or nothing: no new figure beside an old report.md (review24b F4).
        fogtemp_cal::output::all_or_nothing(|| {
            write_demo_report(
                &out.join("report"),
                &result,
                &blobs,
                &validations,
                &feature_sets,
                &options.stability,
            )
        })?;
        progress.advance(1);
        result.seconds.report = started.elapsed().as_secs_f64();
    }
    Ok(result)
}

/// A fitted model and the file it was written to.
struct FittedFile {
    path: PathBuf,
    fitted: calibrate::FittedModel,
}

impl FittedFile {
    /// The fit's report of axis 0 (the demo's logs have one gyro axis).
    fn first_axis(&self) -> Option<&calibrate::AxisFitReport> {
        self.fitted.axes.first()
    }
}

/// Validates every model on the validation logs: in one pass over each log when the models
/// read the logs alike (the usual case), else model by model. Advances `progress` per log.
fn validate_all(
    logs: &[PathBuf],
    models: &[Model<'_>],
    options: &DemoOptions,
    progress: &dyn DemoProgress,
) -> Result<Vec<Validation>, CalError> {
    let mut current = usize::MAX;
    let mut advance = |i: usize, _: u64, _: u64| {
        if i != current {
            current = i;
            progress.advance(1);
        }
    };
    let ingest = |k: usize| options.models.get(k).map(|m| &m.config.ingest);
    if (1..models.len()).all(|k| ingest(k) == ingest(0)) {
        let refs: Vec<&Model<'_>> = models.iter().collect();
        let ingest = ingest(0).cloned().unwrap_or_default();
        return calibrate::validate_models(logs, &refs, &ingest, &options.stability, advance);
    }
    models
        .iter()
        .zip(&options.models)
        .map(|(model, m)| {
            calibrate::validate_runs(logs, model, &m.config.ingest, &options.stability, &mut advance)
        })
        .collect()
}

#[cfg(feature = "report")]
fn write_demo_report(
    dir: &Path,
    result: &DemoResult,
    blobs: &[FittedFile],
    validations: &[(Vec<RunValidation>, f64)],
    feature_sets: &[(CalibrationConfig, Vec<RunFeatures>, [u8; 32])],
    stability: &BiasStabilityOptions,
) -> Result<(), CalError> {
    std::fs::create_dir_all(dir).map_err(|source| CalError::Io { path: dir.to_path_buf(), source })?;
    for (model, (FittedFile { path, fitted }, (runs, raw))) in
        result.models.iter().zip(blobs.iter().zip(validations))
    {
        let parsed = Model::from_bytes(&fitted.blob).map_err(CalError::SelfCheck)?;
        fogtemp_cal::report::write_validation_report_with(
            &dir.join(&model.key),
            path,
            &parsed,
            runs,
            (*raw, model.compensated_dph),
            stability,
            &result.definition,
        )?;
        if model.mesh_nodes > 0 {
            if let Some((config, features, _)) = feature_sets.first() {
                // The summary and warnings `fit --report` gives for the same logs, under the
                // model's description.
                let warnings = fogtemp_cal::identifiability::fit_warnings(
                    features,
                    config,
                    &fogtemp_cal::identifiability::IdentifiabilitySettings::default(),
                );
                let summary = format!(
                    "{} (`{}`).\n\n{}",
                    model.description,
                    model.key,
                    fogtemp_cal::report::fit_summary_markdown(&parsed, fitted, &warnings)
                );
                fogtemp_cal::report::write_fit_report(
                    &dir.join(&model.key),
                    path,
                    &parsed,
                    features,
                    summary.trim_end(),
                )?;
            }
        }
    }
    let path = dir.join("report.md");
    let mut text = demo_markdown(result);
    let bars = demo_bars(dir, result)?;
    match text.find("\n## Figures") {
        Some(at) => text.insert_str(at + 1, &bars),
        None => text.push_str(&bars),
    }
    fogtemp_cal::output::write_file_atomic(&path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
    fogtemp_cal::report::write_html_beside(&path)
}

/// The per-run bars of every model beside raw (`bars.svg` in `dir`) and their Markdown.
#[cfg(feature = "report")]
fn demo_bars(dir: &Path, result: &DemoResult) -> Result<String, CalError> {
    use fogtemp_cal::report::{plot_grouped_bars, run_colour, BarSeries, RAW_GREY};
    let mut groups: Vec<String> = result.raw_runs.iter().map(|r| r.0.clone()).collect();
    groups.push("RMS over runs".into());
    let with_rms = |runs: &[(String, f64)], rms: f64| -> Vec<f64> {
        runs.iter().map(|r| r.1).chain(std::iter::once(rms)).collect()
    };
    let mut series = vec![BarSeries {
        name: "raw".into(),
        colour: RAW_GREY,
        values: with_rms(&result.raw_runs, result.raw_dph),
    }];
    for (i, m) in result.models.iter().enumerate() {
        series.push(BarSeries {
            name: m.key.clone(),
            colour: run_colour(i),
            values: with_rms(&m.runs, m.compensated_dph),
        });
    }
    plot_grouped_bars(
        &dir.join("bars.svg"),
        "Validation bias stability per run: raw and every model",
        &groups,
        &series,
    )?;
    Ok("## Per validation run, every model\n\n![Bias stability per validation run, raw beside every model \
        (the last group is the RMS over runs, Table 1)](bars.svg)\n\n"
        .to_string())
}

/// Without the `report` feature there are no figures to draw: the demo writes no report.
#[cfg(not(feature = "report"))]
fn write_demo_report(
    _dir: &Path,
    _result: &DemoResult,
    _blobs: &[FittedFile],
    _validations: &[(Vec<RunValidation>, f64)],
    _feature_sets: &[(CalibrationConfig, Vec<RunFeatures>, [u8; 32])],
    _stability: &BiasStabilityOptions,
) -> Result<(), CalError> {
    Ok(())
}

/// The cross-validation table as the fit report has it (Markdown, with the paired standard
/// error the rule uses); the plain-text table without the report feature.
#[cfg(feature = "report")]
fn selection_table(s: &fogtemp_cal::selection::Selection) -> String {
    fogtemp_cal::report::selection_markdown(0, s).lines().skip(2).collect::<Vec<_>>().join("\n") + "\n"
}

#[cfg(not(feature = "report"))]
fn selection_table(s: &fogtemp_cal::selection::Selection) -> String {
    format!("```text\n{}```\n", s.table())
}

/// The Markdown report: Table 1 beside the paper's, per-run figures, settings.
pub fn demo_markdown(r: &DemoResult) -> String {
    let mut md = format!(
        "# fogtemp demo: the paper's experiment on the simulated `{}` scenario\n\n\
         Simulated at {} Hz (seed {}); calibrated on {} logs (position 1), validated on {} logs \
         (position 2) by replaying every raw sample through the firmware's `Compensator`.\n\n\
         Bias stability: {}.\n\n",
        r.scenario,
        r.sample_rate_hz,
        r.seed,
        r.calibration_logs.len(),
        r.validation_logs.len(),
        r.definition
    );
    if r.sample_rate_hz < 1000.0 {
        md.push_str(&format!(
            "The paper sampled at 1000 Hz; this run used {} Hz to finish quickly. White noise averages \
             to the same 100 s means at any rate (the ARW per sample is scaled by sqrt(rate)), so the \
             figures below estimate the 1000 Hz ones; `fogtemp-cal demo --rate 1000` runs the full \
             experiment.\n\n",
            r.sample_rate_hz
        ));
    }
    md.push_str("## Table 1: validation bias stability, deg/h\n\n");
    md.push_str("| model | paper | fogtemp | ratio raw/model (paper) | ratio raw/model (fogtemp) |\n");
    md.push_str("|---|---|---|---|---|\n");
    md.push_str(&format!("| raw (uncompensated) | {PAPER_RAW_DPH:.4} | {:.5} | 1 | 1 |\n", r.raw_dph));
    for m in &r.models {
        let paper = match m.key.as_str() {
            "poly" => Some(PAPER_POLY_DPH),
            "mesh_paper" => Some(PAPER_MESH_DPH),
            _ => None,
        };
        md.push_str(&format!(
            "| `{}` | {} | {:.5} | {} | {:.2} |\n",
            m.key,
            paper.map_or_else(|| "-".into(), |p| format!("{p:.4}")),
            m.compensated_dph,
            paper.map_or_else(|| "-".into(), |p| format!("{:.2}", PAPER_RAW_DPH / p)),
            m.improvement_ratio
        ));
    }
    for m in &r.models {
        if let Some(s) = &m.selection {
            md.push_str(&format!(
                "\n`{}` chose `{}` by cross-validation on the calibration runs ({} folds; compensated bias \
                 stability of the held-out runs, deg/h):\n\n{}",
                m.key,
                s.method.name(),
                s.folds,
                selection_table(s)
            ));
        }
    }
    md.push_str("\n## The models\n\n| model | what | mesh nodes | polynomial terms | fit residual RMS, deg/h | bytes |\n|---|---|---|---|---|---|\n");
    for m in &r.models {
        md.push_str(&format!(
            "| `{}` | {} | {} | {} | {:.5} | {} |\n",
            m.key,
            m.description.replace('|', "\\|"),
            m.mesh_nodes,
            m.poly_terms,
            m.fit_residual_rms_dph,
            m.model_bytes
        ));
    }
    if r.models.iter().any(|m| m.key == "hybrid" && m.mesh_nodes == 0) {
        md.push_str(
            "\n`hybrid` kept no mesh nodes: cross-validation found nothing in the polynomial's residuals \
             for a mesh to add, so here it is the polynomial alone, and its figures are `poly`'s.\n",
        );
    }
    md.push_str("\n## Per validation run, deg/h\n\n| run | raw |");
    for m in &r.models {
        md.push_str(&format!(" `{}` |", m.key));
    }
    md.push_str("\n|---|---|");
    for _ in &r.models {
        md.push_str("---|");
    }
    md.push('\n');
    for (i, (name, raw)) in r.raw_runs.iter().enumerate() {
        md.push_str(&format!("| {name} | {raw:.5} |"));
        for m in &r.models {
            md.push_str(&format!(" {:.5} |", m.runs.get(i).map_or(f64::NAN, |x| x.1)));
        }
        md.push('\n');
    }
    md.push_str("\n## Figures\n\n");
    for m in &r.models {
        md.push_str(&format!(
            "- `{0}`: [validation report]({0}/report.md){1}\n",
            m.key,
            if m.mesh_nodes > 0 {
                format!(", [fit report with the mesh]({}/fit-report.md)", m.key)
            } else {
                String::new()
            }
        ));
    }
    md.push_str(&format!(
        "\n## Time\n\nsimulate {:.1} s, features {:.1} s, fit {:.1} s, validate {:.1} s.\n",
        r.seconds.simulate, r.seconds.features, r.seconds.fit, r.seconds.validate
    ));
    md
}
