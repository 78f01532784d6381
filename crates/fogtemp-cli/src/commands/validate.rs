//! `validate`: raw vs compensated bias stability per run and overall, and models compared
//! on the same logs.

use anyhow::{bail, Context, Result};
use fogtemp_cal::calibrate;
use fogtemp_cal::metrics::BiasStabilityOptions;
use fogtemp_core::Model;
use serde_json::{json, Value};

use super::{ingest_options, read_model, report_skipped};
use crate::args::{StabilityArgs, ValidateArgs};
use crate::output::{expand_logs, write_atomic, RowProgress};

fn stability_options(a: &StabilityArgs) -> Result<BiasStabilityOptions> {
    if !a.tau_s.is_finite() || a.tau_s <= 0.0 {
        bail!("--tau-s must be positive");
    }
    Ok(BiasStabilityOptions {
        tau_s: a.tau_s,
        overlapping: a.overlapping,
        detrend: a.detrend,
        exclude_first_s: a.exclude_first_s,
    })
}

fn flag_names(counts: &[u64; 8]) -> Value {
    let names = ["warming_up", "partial_window", "outside_hull", "temp_stale", "bad_input"];
    Value::Object(names.iter().enumerate().map(|(bit, n)| (n.to_string(), json!(counts[bit]))).collect())
}

pub fn validate(a: ValidateArgs) -> Result<()> {
    let blob = read_model(&a.model)?;
    let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let logs = expand_logs(&a.logs)?;
    let ingest = ingest_options(&a.ingest)?;
    let options = stability_options(&a.stability)?;
    // The compared models are replayed in the same pass over each log as the primary one.
    let compare_blobs: Vec<Vec<u8>> = a.compare.iter().map(|p| read_model(p)).collect::<Result<_>>()?;
    let mut models = vec![model];
    for blob in &compare_blobs {
        models.push(Model::from_bytes(blob).map_err(|e| anyhow::anyhow!("{e}"))?);
    }
    let refs: Vec<&Model<'_>> = models.iter().collect();
    let bars: Vec<_> = logs.iter().map(|l| RowProgress::new(l, "validate")).collect();
    let mut outcomes = calibrate::validate_models(&logs, &refs, &ingest, &options, |i, b, r| {
        if let Some(bar) = bars.get(i) {
            bar.update(b, r);
        }
    })?;
    for bar in &bars {
        bar.finish_and_clear();
    }
    let compared = outcomes.split_off(1.min(outcomes.len()));
    let calibrate::Validation { runs, raw_bias_stability_dph: raw, compensated_bias_stability_dph: comp } =
        outcomes.pop().unwrap_or_default();
    let model = &models[0];
    for r in runs.iter().filter(|r| r.axis == 0) {
        if r.ingest.rows == 0 {
            bail!("{}: no data rows (only a header)", r.path.display());
        }
        report_skipped(&r.ingest);
    }
    let comparison = compare_models(&a, &models, &compared, raw, comp);
    if let Some(dir) = &a.report {
        fogtemp_cal::report::write_validation_report(
            dir,
            &a.model,
            model,
            &runs,
            (raw, comp),
            &options.describe(),
        )?;
        if !comparison.is_empty() {
            let table = comparison_markdown(&comparison);
            let path = dir.join("report.md");
            let mut text =
                std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
            text = text.replacen("\n## ", &format!("\n{table}\n## "), 1);
            write_atomic(&path, |w| Ok(w.write_all(text.as_bytes())?))?;
        }
        eprintln!("report: {}", dir.join("report.md").display());
    }
    let doc = json!({
        "definition": options.describe(),
        "raw_bias_stability_dph": raw,
        "compensated_bias_stability_dph": comp,
        "improvement_ratio": raw / comp,
        "runs": runs.iter().map(|r| json!({
            "path": r.path.display().to_string(),
            "axis": r.axis,
            "raw_bias_stability_dph": r.raw_bias_stability_dph,
            "compensated_bias_stability_dph": r.compensated_bias_stability_dph,
            "samples": r.series.samples,
            "flag_samples": flag_names(&r.series.flag_counts),
            "skipped_rows": r.ingest.skipped,
        })).collect::<Vec<_>>(),
        "comparison": comparison.iter().map(|c| json!({
            "model": c.model.display().to_string(),
            "mesh_nodes": c.mesh_nodes,
            "polynomial_terms": c.poly_terms,
            "raw_bias_stability_dph": c.raw_dph,
            "compensated_bias_stability_dph": c.compensated_dph,
        })).collect::<Vec<_>>(),
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    println!("{}", options.describe());
    println!("{:<40} {:>4} {:>14} {:>14} {:>8}", "run", "axis", "raw deg/h", "comp deg/h", "ratio");
    for r in &runs {
        let name = r.path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        println!(
            "{:<40} {:>4} {:>14.5} {:>14.5} {:>8.2}",
            name,
            r.axis,
            r.raw_bias_stability_dph,
            r.compensated_bias_stability_dph,
            r.raw_bias_stability_dph / r.compensated_bias_stability_dph
        );
    }
    println!("{:<40} {:>4} {:>14.5} {:>14.5} {:>8.2}", "overall (RMS over runs)", "", raw, comp, raw / comp);
    if !comparison.is_empty() {
        println!("\nmodels compared on the same logs:");
        for c in &comparison {
            println!(
                "{:<40} {:>6} nodes {:>3} terms {:>14.5} {:>8.2}",
                c.model.display(),
                c.mesh_nodes,
                c.poly_terms,
                c.compensated_dph,
                c.raw_dph / c.compensated_dph
            );
        }
    }
    Ok(())
}

/// One model's overall result on the validation logs.
struct Compared {
    model: std::path::PathBuf,
    mesh_nodes: u32,
    poly_terms: usize,
    raw_dph: f64,
    compensated_dph: f64,
}

fn model_size(model: &Model<'_>) -> (u32, usize) {
    (0..model.axis_count()).filter_map(|i| model.axis(i).ok()).fold((0, 0), |(n, t), a| {
        (n + a.mesh.map_or(0, |m| m.vertex_count()), t + a.poly.map_or(0, |p| p.len()))
    })
}

/// The primary model first, then every `--compare` model, replayed on the same logs.
fn compare_models(
    a: &ValidateArgs,
    models: &[Model<'_>],
    compared: &[calibrate::Validation],
    raw: f64,
    comp: f64,
) -> Vec<Compared> {
    if a.compare.is_empty() {
        return Vec::new();
    }
    let entry = |path: &std::path::Path, model: &Model<'_>, raw_dph: f64, compensated_dph: f64| {
        let (mesh_nodes, poly_terms) = model_size(model);
        Compared { model: path.to_path_buf(), mesh_nodes, poly_terms, raw_dph, compensated_dph }
    };
    let mut out = vec![entry(&a.model, &models[0], raw, comp)];
    for ((path, model), v) in a.compare.iter().zip(models.iter().skip(1)).zip(compared) {
        out.push(entry(path, model, v.raw_bias_stability_dph, v.compensated_bias_stability_dph));
    }
    out
}

fn comparison_markdown(rows: &[Compared]) -> String {
    let mut md = String::from(
        "## Models compared on the same logs\n\n| model | mesh nodes | polynomial terms | raw, deg/h | compensated, deg/h | ratio |\n|---|---|---|---|---|---|\n",
    );
    for c in rows {
        md.push_str(&format!(
            "| {} | {} | {} | {:.5} | {:.5} | {:.2} |\n",
            c.model.display(),
            c.mesh_nodes,
            c.poly_terms,
            c.raw_dph,
            c.compensated_dph,
            c.raw_dph / c.compensated_dph
        ));
    }
    md
}
