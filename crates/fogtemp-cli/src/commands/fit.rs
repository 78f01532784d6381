//! `fit`: calibration logs -> model blob, with the fit of every axis.

use anyhow::{bail, Context, Result};
use fogtemp_cal::calibrate::{self, CalibrationConfig, Method, Thinning};
use fogtemp_cal::cv_correction::CvCorrection;
use fogtemp_cal::documents::{FitDocument, RunMetadataDocument};
use fogtemp_cal::identifiability::WarningKind;
use fogtemp_cal::poly_fit::TermSelection;
use fogtemp_cal::runs::Role;
use fogtemp_cal::selection::{CvScheme, CvScoring, Grouping, RuleScale, SelectionOptions};
use fogtemp_cal::thin::GreedyThinning;
use fogtemp_core::FeatureSettings;

use super::{capacity_fits, ingest_options, print_json, report_rows_not_read_as_samples, warn_of_time_unit};
use crate::args::{
    CvCorrectionArg, CvSchemeArg, CvScoringArg, FitArgs, MethodArg, PolyArg, RuleScaleArg, ThinningArg,
};
use crate::output::{
    check_output_file, check_report_folder, expand_logs, refuse_overwriting_inputs, write_atomic, RowProgress,
};

/// Calibration points from which a fit without a terminal says that it started (one
/// million: minutes of stepwise selection; a review's 65-day log had 5.65 million).
const LONG_FIT_POINTS: usize = 1_000_000;
/// Cross-validation folds from which `fit` says how long the choice of method can take.
const MANY_FOLDS: usize = 30;

/// The `fit` command.
pub fn fit(a: FitArgs) -> Result<()> {
    capacity_fits(a.blocks as usize, a.capacity).context("--blocks")?;
    check_settings(&a)?;
    let named = expand_logs(&a.logs)?;
    let mut inputs: Vec<&std::path::Path> = named.iter().map(|p| p.as_path()).collect();
    inputs.extend(a.runs.as_deref());
    refuse_overwriting_inputs(&a.out, &inputs)?;
    check_output_file(&a.out)?;
    if let Some(dir) = &a.report {
        check_report_folder(dir)?;
    }
    let CalibrationLogs { logs, positions, input_rates_dph, source, unfinished } =
        calibration_logs(&named, a.runs.as_deref())?;
    let mut config = CalibrationConfig {
        ingest: ingest_options(&a.ingest)?,
        features: FeatureSettings {
            window_s: a.window_s,
            block_count: a.blocks,
            min_blocks: a.min_blocks,
            max_gap_s: a.max_gap_s,
        },
        target_window_s: a.target_window_s.unwrap_or(f64::from(a.window_s)),
        method: match a.method {
            MethodArg::Poly => Method::Poly,
            MethodArg::Mesh => Method::Mesh,
            MethodArg::Hybrid => Method::Hybrid,
            MethodArg::CubicT => Method::CubicT,
            MethodArg::Auto => Method::Auto,
        },
        thinning: match a.thinning {
            ThinningArg::Greedy => match a.tolerance_dph {
                Some(tolerance_dph) => Thinning::Greedy(GreedyThinning {
                    tolerance_dph,
                    max_nodes: a.max_nodes,
                    ..GreedyThinning::default()
                }),
                None => Thinning::GreedyAuto { noise_multiple: 1.5, max_nodes: a.max_nodes },
            },
            ThinningArg::Paper => {
                Thinning::Paper { fast_rate_c_per_min: a.fast_rate, settled_every: a.settled_every }
            }
        },
        poly: match a.poly {
            PolyArg::Paper => TermSelection::Paper,
            PolyArg::Stepwise => {
                TermSelection::Stepwise { max_degree: a.max_degree, p_enter: a.p_enter, p_remove: a.p_remove }
            }
        },
        full_windows_only: a.full_windows_only,
        least_squares_nodes: !a.interpolate_nodes,
        rate_axis_weight: 1.0,
        poly_outside: a.poly_outside.into(),
        mesh_outside: a.mesh_outside.into(),
        record_columns: true,
        refine_mesh: !a.no_mesh_refinement,
        mesh_relative_weight: a.mesh_relative_weight,
        mesh_cv_repeats: a.mesh_cv_repeats as usize,
        mesh_cv_salt: a.mesh_cv_salt,
        // Set once the run metadata's rates are taken off (below).
        input_rates: None,
    };
    let mut runs = Vec::with_capacity(logs.len());
    let mut input_digest = fogtemp_cal::digest::InputDigest::new();
    for (k, log) in logs.iter().enumerate() {
        // Which log of how many: a campaign's bar alone did not say how far the command was
        // (review24b S3).
        let bar = RowProgress::new(log, &format!("features {}/{}", k + 1, logs.len()));
        let run = calibrate::extract_run_digested(log, &config, &mut input_digest, |b, r| bar.update(b, r))
            .with_context(|| format!("reading calibration log {}", log.display()))?;
        bar.finish_and_clear();
        if run.ingest.rows == 0 {
            return Err(super::no_rows_error(&run.ingest));
        }
        report_rows_not_read_as_samples(&run.ingest);
        if let Some(note) = run.gaps.note(&run.path) {
            eprintln!("note: {note}");
        }
        for axis in 0..run.temperature_silences.len() {
            if let Some(note) = run.temperature_silence_note(axis) {
                eprintln!("note: {note}");
            }
        }
        warn_of_time_unit(&run.path, &run.gaps, &run.ingest);
        runs.push(run);
    }
    let (digest, each) = input_digest.finish();
    if let Some(warning) = fogtemp_cal::digest::same_logs_note(&logs, &each) {
        eprintln!("warning: {warning}");
    }
    let run_metadata = subtract_input_rates(
        &mut config,
        &mut runs,
        input_rates_dph.as_deref(),
        positions.as_deref(),
        source.as_deref(),
    );
    let mut warnings = fogtemp_cal::identifiability::fit_warnings(&runs, &config, &a.identifiability());
    if run_metadata.is_none() {
        warnings.push(fogtemp_cal::identifiability::Warning::no_run_metadata(
            "To fit the bias alone, give each run's position and input_rate_dph in a runs file (--runs FILE; \
             docs/diagnose.md, \"Run metadata\")",
        ));
    }
    warnings.iter().for_each(|w| eprintln!("warning: {}", w.message));

    let selection = SelectionOptions {
        positions,
        inside_range_only: a.cv_inside_range_only,
        scoring: match a.cv_scoring {
            CvScoringArg::WholeRun => CvScoring::WholeRun,
            CvScoringArg::InsideRegion => CvScoring::InsideRegion,
        },
        scheme: match a.cv_scheme {
            CvSchemeArg::LeaveOneOut => CvScheme::LeaveOneGroupOut,
            CvSchemeArg::BlockedKFold => CvScheme::BlockedKFold,
            CvSchemeArg::RunsAndBlocks => CvScheme::RunsAndBlocks,
        },
        blocks: a.cv_blocks,
        scale: match a.cv_rule_scale {
            RuleScaleArg::DegPerHour => RuleScale::DegPerHour,
            RuleScaleArg::Log => RuleScale::Log,
        },
        correction: match a.cv_correction {
            CvCorrectionArg::None => CvCorrection::None,
            CvCorrectionArg::TrainingSize => CvCorrection::TrainingSize,
        },
        ..SelectionOptions::default()
    };
    // A spinner while fitting (the folds' bar takes over when cross-validating): the final
    // fit of a long log can take minutes with nothing else moving. Without a terminal the
    // bar is hidden, so a long fit says once that it started.
    let points: usize = runs.iter().filter_map(|r| r.axes.first()).map(|(p, _)| p.len()).sum();
    let bar = indicatif::ProgressBar::new_spinner()
        .with_message(format!("fitting the model on {points} calibration points"));
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    // Leave-one-run-out over many runs refits every candidate once per run: 200 logs of 2 h
    // took about 145 s a fold, some 8 hours in all, with only "can take minutes" said
    // (review24b F2).
    let folds = match &selection.positions {
        Some(positions) => positions.iter().collect::<std::collections::BTreeSet<_>>().len(),
        None => runs.len(),
    };
    if config.method == Method::Auto && folds >= MANY_FOLDS {
        eprintln!(
            "note: choosing the method by cross-validation refits every candidate once per {} ({folds} folds, \
             {points} calibration points): on many long runs that takes hours; positions (a runs file, --runs, \
             or groups in a simulation's manifest.json) leave out a position per fold instead, and --method poly (or mesh, hybrid, cubic-t) skips the choice",
            if selection.positions.is_some() { "position" } else { "run" }
        );
    }
    if bar.is_hidden() && points >= LONG_FIT_POINTS {
        eprintln!(
            "note: fitting the model on {points} calibration points (a fit this large can take minutes)"
        );
    }
    let fitted = calibrate::fit_model_with(&runs, &config, digest, &selection, |fold, folds| {
        if bar.length().is_none() {
            // The length before the style: styled first, the bar drew "0/0 folds" until the
            // next draw (review24b F6). review18 F8: the default bar said only "0/3".
            bar.set_length(folds as u64);
            let style =
                indicatif::ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} folds, eta {eta}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
            bar.set_style(style.progress_chars("=> "));
            bar.set_message("cross-validation");
        }
        bar.set_length(folds as u64);
        bar.set_position(fold as u64);
        // Every fold done (the selection's last call): the chosen model's own fit follows.
        if fold >= folds {
            bar.set_message("folds done; fitting the chosen model");
        }
    })
    .context("fitting the model")?;
    bar.finish_and_clear();
    for (axis, r) in fitted.axes.iter().enumerate() {
        let Some(selection) = r.selection.as_ref() else { continue };
        // Too few runs to cross-validate was said already (`too_few_runs`); the summary below
        // says the method was the default.
        let said = selection.grouping == Grouping::Runs
            && selection.folds < fogtemp_cal::selection::MIN_FOLDS
            && warnings.iter().any(|w| w.axis == axis && w.kind == WarningKind::TooFewRuns);
        if let Some(warning) = selection.warning.as_ref().filter(|_| !said) {
            eprintln!("warning: axis {axis}: {warning}");
        }
    }
    let (blob, reports) = (&fitted.blob, &fitted.axes);
    for w in fogtemp_cal::identifiability::post_fit_warnings(&runs, &fitted) {
        eprintln!("warning: {}", w.message);
        warnings.push(w);
    }
    // Printed when the logs were chosen; last, for --json and the report too (review30b F7),
    // as Python's `fit_report` (review31a F3).
    warnings.extend(unfinished.into_iter().map(fogtemp_cal::identifiability::Warning::unfinished_simulation));
    write_atomic(&a.out, |w| Ok(w.write_all(blob)?))?;
    if let Some(dir) = &a.report {
        // The model is in place by now: a report that fails (a full disk) must say so, or the
        // status 1 reads as "nothing written" (review24b F3).
        fogtemp_cal::report::write_fit_report_for(dir, &a.out, &fitted, &runs, &warnings).with_context(
            || {
                format!(
                    "wrote the model {} ({} bytes), complete; its report in {} was not written (the folder is as it was)",
                    a.out.display(),
                    blob.len(),
                    dir.display()
                )
            },
        )?;
        eprintln!("report: {}", dir.join("fit-report.md").display());
    }
    if a.json {
        print_json(
            &FitDocument::new(&a.out, &fitted, &runs, &digest)
                .with_warnings(warnings)
                .with_run_metadata(run_metadata),
        )?;
    } else {
        println!(
            "wrote {} ({} bytes) from {}",
            a.out.display(),
            blob.len(),
            super::counted(logs.len() as u64, "log", "logs")
        );
        for (axis, r) in reports.iter().enumerate() {
            // No choice (too few runs, or too few folds with a score): the default method,
            // with the folds that could not be scored and why.
            if let Some(s) = r.selection.as_ref().filter(|s| s.best.is_none()) {
                println!(
                    "axis {axis}: method {}, the default, without a cross-validated choice (see the warning above)",
                    s.method.name()
                );
                for f in &s.skipped_folds {
                    println!("  fold '{}' skipped: {}", f.group, f.reason);
                }
            } else if let Some(s) = &r.selection {
                println!(
                    "axis {axis}: method {} chosen by cross-validation ({} folds leaving one {} out; compensated \
                     bias stability of the held-out runs, deg/h):",
                    s.method.name(),
                    s.folds,
                    match s.grouping {
                        Grouping::Runs => "run",
                        Grouping::Positions => "position",
                    }
                );
                print!("{}", s.table());
                // The rule, where it did not take the lowest score (review16 F2: "chosen by
                // cross-validation" beside a lower score read as a mistake).
                if let Some(best) = s.best.filter(|b| *b != s.method) {
                    println!(
                        "  {} is chosen, not {} (the lowest): the rule takes {}",
                        s.method.name(),
                        best.name(),
                        s.rule
                    );
                }
            }
            println!(
                "axis {axis}: {}, {} points, fit residual RMS {} deg/h (max {}), {} mesh nodes, {} triangles{}",
                r.method.name(),
                r.points,
                fogtemp_cal::numbers::dph(r.residual_rms_dph),
                fogtemp_cal::numbers::dph(r.residual_max_abs_dph),
                r.mesh_nodes,
                r.mesh_triangles,
                r.poly.as_ref().map_or(String::new(), |p| format!(
                    ", {} polynomial terms (condition number {:.1})",
                    p.terms.len(),
                    p.condition_number
                )),
            );
            if r.method == Method::Hybrid && r.mesh_nodes == 0 {
                println!(
                    "  hybrid: no mesh was added (the polynomial's residuals are within their noise, or \
                     cross-validation found that a mesh of them does not help): the model is the polynomial alone"
                );
            }
            if r.dropped_flat > 0 || r.merged_duplicates > 0 {
                println!(
                    "  mesh: {} duplicate points merged, {} points dropped for flat hull triangles",
                    r.merged_duplicates, r.dropped_flat
                );
            }
        }
    }
    Ok(())
}

/// The settings that depend on each other (each alone is checked as it is parsed).
fn check_settings(a: &FitArgs) -> Result<()> {
    if a.min_blocks > a.blocks {
        bail!(
            "--min-blocks {} exceeds --blocks {}: the tracker can never hold that many",
            a.min_blocks,
            a.blocks
        );
    }
    if a.p_remove < a.p_enter {
        bail!(
            "--p-remove {} is below --p-enter {}: a term could enter and leave at every step; use p-remove >= p-enter",
            a.p_remove,
            a.p_enter
        );
    }
    let block_s = a.window_s / a.blocks as f32;
    if block_s < 1.0e-3 {
        bail!(
            "--window-s {} over --blocks {} gives blocks of {block_s} s: at least 1 ms each",
            a.window_s,
            a.blocks
        );
    }
    Ok(())
}

/// With run metadata (a runs file or a simulation's manifest), each run's true input rate is
/// taken from its gyro before fitting, so that the model is the bias alone (a model that kept
/// it would remove the Earth rate from a navigation system's gyro, and runs in different
/// positions would disagree by it). The metadata gives one rate per run, about the input axis,
/// so only a one-gyro log is corrected; what was done goes into `config` for the blob to record.
/// Returns what `fit --json` says of the metadata.
fn subtract_input_rates(
    config: &mut CalibrationConfig,
    runs: &mut [fogtemp_cal::calibrate::RunFeatures],
    rates_dph: Option<&[f64]>,
    positions: Option<&[String]>,
    source: Option<&str>,
) -> Option<RunMetadataDocument> {
    let (Some(rates), Some(positions), Some(source)) = (rates_dph, positions, source) else { return None };
    let axes = config.ingest.format.gyro_columns.len();
    let subtracted =
        calibrate::subtract_input_rates(runs, rates, config) == fogtemp_core::InputRates::Subtracted;
    if subtracted {
        eprintln!("note: each run's input_rate_dph from {source} is subtracted from its gyro: the model is the bias alone");
    } else {
        eprintln!(
            "note: {source} gives one input rate per run, but the logs have {axes} gyro columns: the rates are \
             not subtracted, so each axis's model includes its input rate"
        );
    }
    Some(RunMetadataDocument {
        source: source.to_string(),
        positions: positions.to_vec(),
        input_rates_dph: rates.to_vec(),
        input_rates_subtracted: subtracted,
    })
}

/// The calibration logs: every log, or with run metadata those not of role `val`, each with
/// its row.
struct CalibrationLogs {
    logs: Vec<std::path::PathBuf>,
    /// Per log, its position (with run metadata).
    positions: Option<Vec<String>>,
    /// Per log, the true rate about the input axis, deg/h (with run metadata).
    input_rates_dph: Option<Vec<f64>>,
    /// Where the run metadata came from: the runs file, or the simulations' manifests.
    source: Option<String>,
    /// The warnings for logs of a simulation that did not finish (printed already).
    unfinished: Vec<String>,
}

/// The logs to calibrate on and, with run metadata (`--runs FILE`, else a fogtemp
/// simulation's `manifest.json` beside the logs), each one's position: every log must have a
/// row (and every row a log); runs with role `val` are left out.
fn calibration_logs(logs: &[std::path::PathBuf], runs: Option<&std::path::Path>) -> Result<CalibrationLogs> {
    let metadata = fogtemp_cal::runs::logs_metadata(logs, runs, Role::Val, "--runs FILE")?;
    for note in &metadata.notes {
        eprintln!("note: {note}");
    }
    for warning in &metadata.warnings {
        eprintln!("warning: {warning}");
    }
    let (kept, rows) = fogtemp_cal::runs::calibration_runs(logs, &metadata)?;
    Ok(CalibrationLogs {
        logs: kept,
        positions: rows.as_ref().map(|rows| rows.iter().map(|r| r.position.clone()).collect()),
        input_rates_dph: rows.as_ref().map(|rows| rows.iter().map(|r| r.input_rate_dph).collect()),
        source: rows.is_some().then_some(metadata.source),
        unfinished: metadata.warnings,
    })
}
