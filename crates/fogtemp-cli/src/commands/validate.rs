//! `validate`: raw vs compensated bias stability per run and overall, and models compared
//! on the same logs.

use std::path::Path;

use anyhow::{bail, Context, Result};
use fogtemp_cal::calibrate::{self, Validation};
use fogtemp_cal::documents::{ComparedModel, ValidationDocument};
use fogtemp_cal::ingest::LogFormat;
use fogtemp_cal::metrics::BiasStabilityOptions;
use fogtemp_cal::numbers::dph;
use fogtemp_cal::runs::Role;
use fogtemp_core::Model;

use super::{check_capacity, print_json, read_model, report_rows_not_read_as_samples};
use crate::args::{StabilityArgs, ValidateArgs};
use crate::output::{expand_logs_for_reading, RowProgress};

fn stability_options(a: &StabilityArgs) -> Result<BiasStabilityOptions> {
    if !a.tau_s.is_finite() || a.tau_s <= 0.0 {
        bail!("--tau-s must be positive");
    }
    if !a.exclude_first_s.is_finite() || a.exclude_first_s < 0.0 {
        bail!("--exclude-first-s must be zero or positive");
    }
    Ok(BiasStabilityOptions {
        tau_s: a.tau_s,
        overlapping: a.overlapping,
        detrend: a.detrend,
        exclude_first_s: a.exclude_first_s,
    })
}

/// A compared model is replayed on the columns chosen for the primary one: refused when it
/// fitted one of them on another axis, noted when it records other names.
fn check_compared_columns(model: &Model<'_>, path: &Path, format: &LogFormat, primary: &Path) -> Result<()> {
    use fogtemp_cal::axis_columns::{choose_for_replay, Named, CLI_OPTIONS};
    let chosen = choose_for_replay(
        model,
        &path.display().to_string(),
        &mut format.clone(),
        Named::all_of(format),
        CLI_OPTIONS,
    )
    .with_context(|| {
        format!("--compare {} is replayed on the columns read for {}", path.display(), primary.display())
    })?;
    for note in &chosen.notes {
        eprintln!("note: {note}");
    }
    Ok(())
}

/// The logs to validate and, with run metadata (`--runs FILE`, else the fogtemp simulations'
/// `manifest.json` beside the logs), each kept log's true input rate (empty without); and the
/// warnings printed of them (logs of an unfinished simulation), for `--json`'s notes.
fn validation_logs(a: &ValidateArgs) -> Result<(fogtemp_cal::runs::ValidationRuns, Vec<String>)> {
    let logs = expand_logs_for_reading(&a.logs)?;
    let metadata = fogtemp_cal::runs::logs_metadata(&logs, a.runs.as_deref(), Role::Cal, "--runs FILE")?;
    for note in &metadata.notes {
        eprintln!("note: {note}");
    }
    for warning in &metadata.warnings {
        eprintln!("warning: {warning}");
    }
    Ok((fogtemp_cal::runs::validation_runs(logs, &metadata)?, metadata.warnings))
}

/// The `validate` command.
pub fn validate(a: ValidateArgs) -> Result<()> {
    if let Some(dir) = &a.report {
        crate::output::check_report_folder(dir)?;
    }
    let blob = read_model(&a.model)?;
    check_capacity(&a.model, &blob, a.capacity)?;
    let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let ((logs, input_rates), unfinished) = validation_logs(&a)?;
    let (ingest, columns) = super::ingest_options_for(&a.ingest, &model, &a.model)?;
    super::warn_axis_count(&a.model, model.axis_count(), ingest.format.gyro_columns.len());
    let options = stability_options(&a.stability)?;
    // The compared models are replayed in the same pass over each log as the primary one.
    let compare_blobs: Vec<Vec<u8>> = a.compare.iter().map(|p| read_model(p)).collect::<Result<_>>()?;
    let mut models = vec![model];
    for (path, blob) in a.compare.iter().zip(&compare_blobs) {
        check_capacity(path, blob, a.capacity)?;
        let compared = Model::from_bytes(blob).map_err(|e| anyhow::anyhow!("{e}"))?;
        check_compared_columns(&compared, path, &ingest.format, &a.model)?;
        models.push(compared);
    }
    let refs: Vec<&Model<'_>> = models.iter().collect();
    // A log's bar is made when its reading starts and cleared when the next log's starts:
    // made all at once, each bar's rate and ETA counted from the command's start (review24b
    // F1: "541 KiB/s, eta 5m" for a log read in 1.3 s).
    let mut bar: Option<(usize, RowProgress)> = None;
    let mut input_digest = fogtemp_cal::digest::InputDigest::new();
    let mut outcomes =
        calibrate::validate_models_digested(&logs, &refs, &ingest, &options, &mut input_digest, |i, b, r| {
            if bar.as_ref().is_none_or(|(shown, _)| *shown != i) {
                if let Some((_, done)) = bar.take() {
                    done.finish_and_clear();
                }
                let label = format!("validate {}/{}", i + 1, logs.len());
                bar = logs.get(i).map(|log| (i, RowProgress::new(log, &label)));
            }
            if let Some((_, current)) = &bar {
                current.update(b, r);
            }
        })
        .map_err(|e| columns.explain(e))?;
    if let Some((_, done)) = bar {
        done.finish_and_clear();
    }
    let compared = outcomes.split_off(1.min(outcomes.len()));
    let validation = outcomes.pop().unwrap_or_default().with_input_rates(&input_rates);
    let (runs, raw, comp) =
        (&validation.runs, validation.raw_bias_stability_dph, validation.compensated_bias_stability_dph);
    let model = &models[0];
    for r in runs.iter().filter(|r| r.axis == 0) {
        if r.ingest.rows == 0 {
            return Err(super::no_rows_error(&r.ingest));
        }
        report_rows_not_read_as_samples(&r.ingest);
    }
    // Every note goes to stderr and into --json's `notes` (the temperature rows' said above;
    // review33c F7).
    let mut notes: Vec<String> = calibrate::temperature_row_notes(runs)
        .into_iter()
        .chain(calibrate::gap_notes(runs))
        .chain(calibrate::continued_notes(runs))
        .collect();
    for r in runs.iter().filter(|r| r.axis == 0) {
        super::warn_of_time_unit(&r.path, &r.series.gaps, &r.ingest);
    }
    notes.extend(runs.iter().flat_map(calibrate::RunValidation::notes));
    let rates_note = fogtemp_cal::runs::input_rates_note(
        &a.model.display().to_string(),
        model,
        runs,
        "give each run's input_rate_dph with --runs FILE",
    );
    notes.extend(rates_note.clone());
    let digests = input_digest.finish();
    notes.extend(fogtemp_cal::digest::same_logs_note(&logs, &digests.1));
    let in_sample =
        fogtemp_cal::digest::in_sample_note_from(&a.model.display().to_string(), model, &logs, &digests);
    notes.extend(in_sample.clone());
    for note in &notes {
        eprintln!("note: {note}");
    }
    let comparison = compare_models(&a, &models, &validation, &compared);
    if let Some(dir) = &a.report {
        fogtemp_cal::report::write_validation_report_with(
            dir,
            &a.model,
            model,
            runs,
            (raw, comp),
            &options,
            &options.describe(),
        )
        .with_context(|| format!("writing the report into {} (the folder is as it was)", dir.display()))?;
        if !comparison.is_empty() {
            fogtemp_cal::report::add_comparison_to_validation_report(dir, &comparison)?;
        }
        let in_sample: Vec<String> = in_sample.into_iter().collect();
        fogtemp_cal::report::add_notes_to_validation_report(dir, IN_SAMPLE_HEADING, &in_sample)?;
        let metadata: Vec<String> = rates_note.into_iter().chain(unfinished.iter().cloned()).collect();
        fogtemp_cal::report::add_notes_to_validation_report(
            dir,
            fogtemp_cal::report::RUN_METADATA_HEADING,
            &metadata,
        )?;
        eprintln!("report: {}", dir.join("report.md").display());
    }
    if a.json {
        // How the logs were read (printed first) goes into the document's notes too.
        // And the warnings of an unfinished simulation (review30b F7).
        let all_notes = columns.notes.iter().cloned().chain(notes).chain(unfinished).collect();
        print_json(&ValidationDocument::new(&options, &validation, comparison).with_notes(all_notes))?;
        return nothing_validated(runs);
    }
    println!("{}", options.describe());
    let names = run_labels(runs);
    // As wide as the longest name, so that long names do not push the columns out of line.
    let width = names.iter().map(|n| n.chars().count() + 1).max().unwrap_or(0).max(40);
    println!(
        "{:<width$} {:>4} {:>14} {:>14} {:>8} {:>14} {:>14} {:>14}",
        "run", "axis", "raw deg/h", "comp deg/h", "raw/comp", "floor deg/h", "raw mean", "comp mean"
    );
    // An undefined figure (a run shorter than two windows) says so, not NaN (review24a F6).
    let dph = |v: f64| if v.is_nan() { "undefined".to_string() } else { dph(v) };
    let ratio = |raw: f64, comp: f64| {
        let r = raw / comp;
        if r.is_nan() {
            "-".to_string()
        } else {
            format!("{r:.2}")
        }
    };
    // To the digits the figure holds, as the other columns (a MEMS run's -7163 deg/h beside a
    // FOG's 0.00090).
    let mean = dph;
    for (r, name) in runs.iter().zip(&names) {
        let (raw_mean, comp_mean) = r.residual_means_dph();
        println!(
            "{:<width$} {:>4} {:>14} {:>14} {:>8} {:>14} {:>14} {:>14}",
            name,
            r.axis,
            dph(r.raw_bias_stability_dph),
            dph(r.compensated_bias_stability_dph),
            ratio(r.raw_bias_stability_dph, r.compensated_bias_stability_dph),
            fogtemp_cal::report::white_noise_floor_cell(r.white_noise_floor()),
            mean(raw_mean),
            mean(comp_mean)
        );
    }
    let per_axis = validation.per_axis();
    if per_axis.len() > 1 {
        for (axis, axis_raw, axis_comp) in &per_axis {
            println!(
                "{:<width$} {:>4} {:>14} {:>14} {:>8} {:>14}",
                "overall of the axis (RMS over runs)",
                axis,
                dph(*axis_raw),
                dph(*axis_comp),
                ratio(*axis_raw, *axis_comp),
                fogtemp_cal::report::white_noise_floor_cell(calibrate::overall_white_noise_floor(
                    runs.iter().filter(|r| r.axis == *axis)
                ))
            );
        }
    }
    let overall =
        if per_axis.len() > 1 { "overall (RMS over runs and axes)" } else { "overall (RMS over runs)" };
    let overall_floor = calibrate::overall_white_noise_floor(runs);
    println!(
        "{:<width$} {:>4} {:>14} {:>14} {:>8} {:>14}",
        overall,
        "",
        dph(raw),
        dph(comp),
        ratio(raw, comp),
        fogtemp_cal::report::white_noise_floor_cell(overall_floor)
    );
    println!(
        "floor = white noise alone: {}",
        fogtemp_cal::report::white_noise_floor_explanation(overall_floor, comp, options.tau_s)
    );
    println!("raw mean, comp mean = {}", fogtemp_cal::report::means_meaning(runs, model.input_rates()));
    if !comparison.is_empty() {
        println!("\nmodels compared on the same logs (overall, RMS over runs):");
        println!(
            "{:<40} {:>11} {:>8} {:>14} {:>14} {:>8}",
            "model", "mesh nodes", "terms", "raw deg/h", "comp deg/h", "raw/comp"
        );
        for c in &comparison {
            println!(
                "{:<40} {:>11} {:>8} {:>14} {:>14} {:>8.2}",
                c.model,
                c.mesh_nodes,
                c.polynomial_terms,
                dph(c.raw_bias_stability_dph),
                dph(c.compensated_bias_stability_dph),
                c.raw_bias_stability_dph / c.compensated_bias_stability_dph
            );
        }
    }
    nothing_validated(runs)
}

/// An error (exit status 1) when the compensator corrected no sample of any run: the model
/// could not be applied to these logs at all (the figures above are all undefined), and a
/// script checking the status must not read success. (Runs too short for two averaging
/// windows also give undefined figures, but the model was applied: a note, not an error.)
fn nothing_validated(runs: &[calibrate::RunValidation]) -> Result<()> {
    if !runs.is_empty() && runs.iter().all(|r| !r.series.compensating_from_s.is_finite()) {
        bail!("no run could be validated: the compensator corrected no sample of any run (the notes above say why)");
    }
    Ok(())
}

/// The primary model first, then every `--compare` model, replayed on the same logs (none
/// without `--compare`).
fn compare_models(
    a: &ValidateArgs,
    models: &[Model<'_>],
    primary: &Validation,
    compared: &[Validation],
) -> Vec<ComparedModel> {
    if a.compare.is_empty() {
        return Vec::new();
    }
    let mut out = vec![ComparedModel::new(&a.model, &models[0], primary)];
    for ((path, model), v) in a.compare.iter().zip(models.iter().skip(1)).zip(compared) {
        out.push(ComparedModel::new(path, model, v));
    }
    out
}

/// Each run's label in the table: its file name, or its path as given where two logs share
/// a file name (`day1/run.csv`, `day2/run.csv` both read `run.csv` before).
fn run_labels(runs: &[calibrate::RunValidation]) -> Vec<String> {
    let file_name = |p: &Path| p.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let names: Vec<String> = runs.iter().map(|r| file_name(&r.path)).collect();
    runs.iter()
        .zip(&names)
        .map(|(r, name)| {
            let shared = runs.iter().zip(&names).any(|(other, n)| n == name && other.path != r.path);
            if shared {
                r.path.display().to_string()
            } else {
                name.clone()
            }
        })
        .collect()
}

/// The validation report's heading of the in-sample note.
const IN_SAMPLE_HEADING: &str = "Runs the model was fitted on (their figures are in-sample):";
