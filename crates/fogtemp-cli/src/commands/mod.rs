//! The commands: parse arguments into library settings, run, report.

use std::io::Write;
use std::path::Path;

use anyhow::{bail, Context, Result};
use fogtemp_cal::calibrate::{self, CalibrationConfig, Method, Thinning};
use fogtemp_cal::ingest::{IngestOptions, IngestReport, LogFormat, RateUnit, TimeUnit};
use fogtemp_cal::metrics::{allan_deviation, fit_noise_terms, BiasStabilityOptions};
use fogtemp_cal::poly_fit::TermSelection;
use fogtemp_cal::thin::GreedyThinning;
use fogtemp_core::{Compensator, FeatureSettings, Flags, Model, OutsidePolicy, WalkHint};
use serde_json::{json, Value};

use crate::args::*;
use crate::output::{digest_files, expand_logs, hex, stage, write_atomic, RowProgress};

/// Runs one command.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Fit(a) => fit(a),
        Command::Compensate(a) => compensate(a),
        Command::Validate(a) => validate(a),
        Command::Evaluate(a) => evaluate(a),
        Command::Inspect(a) => inspect(a),
        Command::Export(a) => export(a),
        Command::Allan(a) => allan(a),
        Command::Simulate(a) => crate::simulate::simulate(a),
        Command::Demo(a) => crate::simulate::demo(a),
        Command::Diagnose(a) => {
            let ingest = ingest_options(&a.ingest)?;
            crate::diagnose::diagnose(a, ingest)
        }
    }
}

fn ingest_options(a: &IngestArgs) -> Result<IngestOptions> {
    if !a.delimiter.is_ascii() {
        bail!("--delimiter must be one ASCII character, got '{}'", a.delimiter);
    }
    Ok(IngestOptions {
        format: LogFormat {
            time_column: a.time_column.clone(),
            time_unit: match a.time_unit {
                TimeUnitArg::S => TimeUnit::Seconds,
                TimeUnitArg::Ms => TimeUnit::Milliseconds,
                TimeUnitArg::Us => TimeUnit::Microseconds,
            },
            temp_columns: a.temp_columns.clone(),
            temp_scale: a.temp_scale,
            temp_offset_c: a.temp_offset,
            gyro_columns: a.gyro_columns.clone(),
            gyro_unit: match a.gyro_unit {
                GyroUnitArg::Dph => RateUnit::DegPerHour,
                GyroUnitArg::Dps => RateUnit::DegPerSecond,
                GyroUnitArg::Rps => RateUnit::RadPerSecond,
            },
            gyro_scale: a.gyro_scale,
            delimiter: a.delimiter as u8,
        },
        skip_bad_rows: a.skip_bad_rows,
    })
}

fn read_model(path: &Path) -> Result<Vec<u8>> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read model {}", path.display()))?;
    Model::from_bytes(&bytes).map_err(|e| anyhow::anyhow!("{}: not a valid model: {e}", path.display()))?;
    Ok(bytes)
}

/// Tells the technician about skipped rows (nothing is dropped silently).
fn report_skipped(report: &IngestReport) {
    if report.skipped == 0 {
        return;
    }
    eprintln!(
        "warning: {}: skipped {} bad rows (--skip-bad-rows); first ones:",
        report.path.display(),
        report.skipped
    );
    for b in &report.first_skipped {
        eprintln!(
            "  line {} column {} '{}': {} (found '{}')",
            b.line,
            b.column,
            b.column_name,
            b.kind.describe(),
            b.found
        );
    }
}

fn skipped_json(report: &IngestReport) -> Value {
    json!({
        "path": report.path.display().to_string(),
        "rows": report.rows,
        "bytes": report.bytes,
        "skipped_rows": report.skipped,
        "first_skipped": report.first_skipped.iter().map(|b| json!({
            "line": b.line, "column": b.column, "column_name": b.column_name,
            "reason": b.kind.describe(), "found": b.found,
        })).collect::<Vec<_>>(),
    })
}

fn fit(a: FitArgs) -> Result<()> {
    let logs = expand_logs(&a.logs)?;
    let config = CalibrationConfig {
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
    };
    let mut runs = Vec::with_capacity(logs.len());
    for log in &logs {
        let bar = RowProgress::new(log, "features");
        let run = calibrate::extract_run(log, &config, |b, r| bar.update(b, r))
            .with_context(|| format!("reading calibration log {}", log.display()))?;
        bar.finish_and_clear();
        if run.ingest.rows == 0 {
            bail!("{}: no data rows (only a header)", log.display());
        }
        report_skipped(&run.ingest);
        runs.push(run);
    }
    let digest = digest_files(&logs)?;
    let fitted = calibrate::fit_model(&runs, &config, digest).context("fitting the model")?;
    let (blob, reports) = (fitted.blob, fitted.axes);
    write_atomic(&a.out, |w| Ok(w.write_all(&blob)?))?;
    if let Some(dir) = &a.report {
        let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
        let summary: Vec<String> = reports
            .iter()
            .enumerate()
            .map(|(axis, r)| {
                format!(
                    "- axis {axis}: {} calibration points, residual RMS {:.5} deg/h, {} mesh nodes, {} polynomial terms",
                    r.points,
                    r.residual_rms_dph,
                    r.mesh_nodes,
                    r.poly.as_ref().map_or(0, |p| p.terms.len())
                )
            })
            .collect();
        fogtemp_cal::report::write_fit_report(dir, &a.out, &model, &runs, &summary.join("\n"))?;
        eprintln!("report: {}", dir.join("fit-report.md").display());
    }
    let axes: Vec<Value> = reports
        .iter()
        .enumerate()
        .map(|(axis, r)| {
            json!({
                "axis": axis,
                "points": r.points,
                "mesh_nodes": r.mesh_nodes,
                "mesh_triangles": r.mesh_triangles,
                "merged_duplicates": r.merged_duplicates,
                "dropped_flat": r.dropped_flat,
                "residual_rms_dph": r.residual_rms_dph,
                "residual_max_abs_dph": r.residual_max_abs_dph,
                "target_noise_dph": r.target_noise_dph,
                "poly": r.poly.as_ref().map(|p| json!({
                    "terms": p.terms.iter().map(|t| json!({
                        "temp_power": t.temp_power, "rate_power": t.rate_power,
                        "coefficient_dph": t.coefficient_dph, "std_error_dph": t.std_error_dph, "p_value": t.p_value,
                    })).collect::<Vec<_>>(),
                    "condition_number": p.condition_number,
                    "residual_rms_dph": p.residual_rms_dph,
                    "n": p.n, "n_eff": p.n_eff, "steps": p.steps,
                })),
            })
        })
        .collect();
    let doc = json!({
        "model": a.out.display().to_string(),
        "bytes": blob.len(),
        "input_digest": hex(&digest),
        "runs": runs.iter().map(|r| skipped_json(&r.ingest)).collect::<Vec<_>>(),
        "axes": axes,
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc)?);
    } else {
        println!("wrote {} ({} bytes) from {} logs", a.out.display(), blob.len(), logs.len());
        for (axis, r) in reports.iter().enumerate() {
            println!(
                "axis {axis}: {} points, fit residual RMS {:.5} deg/h (max {:.5}), {} mesh nodes, {} triangles{}",
                r.points,
                r.residual_rms_dph,
                r.residual_max_abs_dph,
                r.mesh_nodes,
                r.mesh_triangles,
                r.poly.as_ref().map_or(String::new(), |p| format!(
                    ", {} polynomial terms (condition number {:.1})",
                    p.terms.len(),
                    p.condition_number
                )),
            );
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

fn compensate(a: CompensateArgs) -> Result<()> {
    let blob = read_model(&a.model)?;
    let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let ingest = ingest_options(&a.ingest)?;
    let axes = model.axis_count().min(ingest.format.gyro_columns.len());
    let mut comps: Vec<Compensator<'_, { fogtemp_cal::features::CAL_CAPACITY }>> = (0..axes)
        .map(|i| Compensator::new(&model, i))
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.model.display()))?;
    let bar = RowProgress::new(&a.log, "compensate");
    let mut report = None;
    write_atomic(&a.out, |w| {
        let mut out = csv::Writer::from_writer(w);
        let mut header = vec!["time_s".to_string()];
        for i in 0..axes {
            let suffix = if axes == 1 { String::new() } else { format!("_{i}") };
            for col in ["raw_dph", "compensated_dph", "bias_dph", "flags"] {
                header.push(format!("{col}{suffix}"));
            }
        }
        out.write_record(&header)?;
        let mut record: Vec<String> = Vec::with_capacity(header.len());
        let r = fogtemp_cal::ingest::read_log_with_progress(
            &a.log,
            &ingest,
            |row| {
                record.clear();
                record.push(format!("{}", row.time_s));
                let time_us = row.time_us();
                for (i, comp) in comps.iter_mut().enumerate() {
                    let temp = row.temp_c_for_axis(i);
                    let o =
                        comp.step(time_us, row.gyros_dph[i] as f32, temp.is_finite().then_some(temp as f32));
                    record.push(format!("{}", row.gyros_dph[i]));
                    record.push(format!("{}", o.rate_dph));
                    record.push(format!("{}", o.bias_dph));
                    record.push(format!("{}", o.flags.0));
                }
                out.write_record(&record).map_err(|e| fogtemp_cal::CalError::Io {
                    path: a.out.clone(),
                    source: std::io::Error::other(e),
                })
            },
            |b, r| bar.update(b, r),
        )?;
        if r.rows == 0 {
            bail!("{}: no data rows (only a header)", a.log.display());
        }
        out.flush()?;
        report = Some(r);
        Ok(())
    })?;
    bar.finish_and_clear();
    if let Some(r) = &report {
        report_skipped(r);
        println!("wrote {} ({} rows, {} axes)", a.out.display(), r.rows, axes);
    }
    Ok(())
}

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

fn validate(a: ValidateArgs) -> Result<()> {
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

fn evaluate(a: EvaluateArgs) -> Result<()> {
    let blob = read_model(&a.model)?;
    let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let axis = model.axis(a.axis).map_err(|e| anyhow::anyhow!("{}: {e}", a.model.display()))?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(&a.points)
        .with_context(|| format!("cannot open {}", a.points.display()))?;
    let header =
        reader.headers().with_context(|| format!("{}: cannot read the header", a.points.display()))?.clone();
    let col = |name: &str| {
        header.iter().position(|h| h == name).with_context(|| {
            format!(
                "{}: no column named '{name}' (the header has: {})",
                a.points.display(),
                header.iter().collect::<Vec<_>>().join(", ")
            )
        })
    };
    let (ti, ri) = (col("temp_c")?, col("rate_c_per_min")?);
    let mut rows = Vec::new();
    for (k, rec) in reader.records().enumerate() {
        let rec = rec.with_context(|| format!("{}: malformed CSV", a.points.display()))?;
        let line = rec.position().map_or(k as u64 + 2, |p| p.line());
        let cell = |i: usize, name: &str| -> Result<f64> {
            let text = rec.get(i).unwrap_or("");
            let v: f64 = text.parse().map_err(|_| {
                anyhow::anyhow!(
                    "{}:{line}:{}: column '{name}': not a number (found '{text}')",
                    a.points.display(),
                    i + 1
                )
            })?;
            if !v.is_finite() {
                bail!(
                    "{}:{line}:{}: column '{name}': NaN or infinite (found '{text}')",
                    a.points.display(),
                    i + 1
                );
            }
            Ok(v)
        };
        rows.push((cell(ti, "temp_c")?, cell(ri, "rate_c_per_min")?));
    }
    let mut hint = WalkHint::default();
    let mut lines = Vec::with_capacity(rows.len());
    for (t, r) in rows {
        let e = axis.evaluate(t as f32, r as f32, &mut hint).map_err(|e| anyhow::anyhow!("{e}"))?;
        let flags = if e.outside_hull { Flags::OUTSIDE_HULL.0 } else { 0 };
        lines.push(format!("{t},{r},{},{flags}", e.value_dph));
    }
    let write = |w: &mut dyn Write| -> Result<()> {
        writeln!(w, "temp_c,rate_c_per_min,value_dph,flags")?;
        for l in &lines {
            writeln!(w, "{l}")?;
        }
        Ok(())
    };
    match &a.out {
        Some(path) => write_atomic(path, write),
        None => write(&mut std::io::stdout().lock()),
    }
}

fn inspect_json(path: &Path, blob: &[u8], model: &Model<'_>) -> Result<Value> {
    let mut axes = Vec::new();
    for i in 0..model.axis_count() {
        let axis = model.axis(i).map_err(|e| anyhow::anyhow!("{e}"))?;
        let n = &axis.normalisation;
        let mut kind = Vec::new();
        if axis.poly.is_some() {
            kind.push("poly");
        }
        if axis.mesh.is_some() {
            kind.push("mesh");
        }
        let (mut nodes, mut triangles, mut hull) = (Vec::new(), Vec::new(), Vec::new());
        let mut policy = Value::Null;
        if let Some(mesh) = &axis.mesh {
            policy = json!(match mesh.outside_policy() {
                OutsidePolicy::NearestHull => "nearest_hull",
                OutsidePolicy::Zero => "zero",
            });
            for v in (0..mesh.vertex_count()).filter_map(|k| mesh.vertex(k)) {
                let (t, r) = fogtemp_cal::mesh::to_physical(n, f64::from(v.x), f64::from(v.y));
                let poly = axis.poly.map_or(0.0, |p| p.evaluate(v.x, v.y));
                nodes.push(json!({
                    "temp_c": t, "rate_c_per_min": r,
                    "value_dph": poly + v.value_dph, "mesh_value_dph": v.value_dph,
                    "x": v.x, "y": v.y,
                }));
            }
            for tri in (0..mesh.triangle_count()).filter_map(|k| mesh.triangle(k)) {
                triangles.push(json!(tri.vertices));
            }
            for (a, _) in
                (0..mesh.hull_edge_count()).filter_map(|k| mesh.hull_edge(k)).filter_map(|(t, e)| {
                    let rec = mesh.triangle(t)?;
                    let e = e as usize;
                    Some((rec.vertices[(e + 1) % 3], rec.vertices[(e + 2) % 3]))
                })
            {
                hull.push(a);
            }
        }
        let p = &axis.provenance;
        axes.push(json!({
            "axis": i,
            "kind": kind,
            "features": {
                "window_s": axis.features.window_s, "block_count": axis.features.block_count,
                "min_blocks": axis.features.min_blocks, "max_gap_s": axis.features.max_gap_s,
            },
            "normalisation": {
                "temp_offset_c": n.temp_offset_c, "temp_scale_per_c": n.temp_scale_per_c,
                "rate_offset_c_per_min": n.rate_offset_c_per_min, "rate_scale_per_c_per_min": n.rate_scale_per_c_per_min,
            },
            "outside_policy": policy,
            "provenance": {
                "fit_point_count": p.fit_point_count, "residual_rms_dph": p.residual_rms_dph,
                "residual_max_abs_dph": p.residual_max_abs_dph,
                "temp_min_c": p.temp_min_c, "temp_max_c": p.temp_max_c,
                "rate_min_c_per_min": p.rate_min_c_per_min, "rate_max_c_per_min": p.rate_max_c_per_min,
            },
            "poly": axis.poly.map(|poly| poly.terms().map(|t| json!({
                "temp_power": t.temp_power, "rate_power": t.rate_power, "coefficient_dph": t.coefficient_dph,
            })).collect::<Vec<_>>()),
            "nodes": nodes,
            "triangles": triangles,
            "hull": hull,
        }));
    }
    Ok(json!({
        "model": path.display().to_string(),
        "bytes": blob.len(),
        "format_version": model.format_version(),
        "tool_version": String::from_utf8_lossy(model.tool_version()),
        "input_digest": hex(&model.input_digest()),
        "axes": axes,
    }))
}

fn inspect(a: InspectArgs) -> Result<()> {
    let blob = read_model(&a.model)?;
    let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let doc = inspect_json(&a.model, &blob, &model)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    println!(
        "{}: fogtemp model, format {}, {} bytes, written by '{}', input digest {}",
        a.model.display(),
        doc["format_version"],
        blob.len(),
        String::from_utf8_lossy(model.tool_version()),
        hex(&model.input_digest())
    );
    for axis in doc["axes"].as_array().into_iter().flatten() {
        println!(
            "axis {}: {} | window {} s in {} blocks, restart after {} s | {} polynomial terms, {} nodes, {} triangles, outside: {} | fit residual RMS {} deg/h over {} points",
            axis["axis"],
            axis["kind"].as_array().map(|k| k.iter().filter_map(|v| v.as_str()).collect::<Vec<_>>().join("+")).unwrap_or_default(),
            axis["features"]["window_s"],
            axis["features"]["block_count"],
            axis["features"]["max_gap_s"],
            axis["poly"].as_array().map_or(0, |p| p.len()),
            axis["nodes"].as_array().map_or(0, |n| n.len()),
            axis["triangles"].as_array().map_or(0, |t| t.len()),
            axis["outside_policy"],
            axis["provenance"]["residual_rms_dph"],
            axis["provenance"]["fit_point_count"],
        );
        println!(
            "  calibrated range: {} .. {} C, {} .. {} C/min",
            axis["provenance"]["temp_min_c"],
            axis["provenance"]["temp_max_c"],
            axis["provenance"]["rate_min_c_per_min"],
            axis["provenance"]["rate_max_c_per_min"]
        );
    }
    Ok(())
}

fn export(a: ExportArgs) -> Result<()> {
    let blob = read_model(&a.model)?;
    let name = &a.name;
    if name.is_empty()
        || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        || name.starts_with(|c: char| c.is_ascii_digit())
    {
        bail!("--name '{name}' is not a valid identifier");
    }
    let bytes_lines = |per_line: usize| -> String {
        blob.chunks(per_line)
            .map(|c| format!("    {}", c.iter().map(|b| format!("0x{b:02x},")).collect::<Vec<_>>().join(" ")))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let source = a.model.display().to_string();
    match a.format {
        ExportFormat::Rust => write_atomic(&a.out, |w| {
            writeln!(w, "// fogtemp model exported from {source} ({} bytes). Generated by fogtemp-cal export; do not edit.", blob.len())?;
            writeln!(w, "// Use: fogtemp_core::Model::from_bytes(&{name})")?;
            writeln!(w, "pub static {name}: [u8; {}] = [\n{}\n];", blob.len(), bytes_lines(16))?;
            Ok(())
        }),
        ExportFormat::C => {
            let header_path = a.out.with_extension("h");
            let header_name = header_path
                .file_name()
                .map_or_else(|| "model.h".into(), |n| n.to_string_lossy().into_owned());
            let guard = format!("{}_H", name.to_ascii_uppercase());
            // Both files are written before either is moved into place, the source first:
            // an unusable --out leaves no header behind.
            let header = stage(&header_path, |w| {
                writeln!(w, "/* fogtemp model exported from {source}. Generated by fogtemp-cal export; do not edit. */")?;
                writeln!(w, "#ifndef {guard}\n#define {guard}\n#include <stdint.h>\n")?;
                writeln!(w, "#define {}_LEN {}u", name.to_ascii_uppercase(), blob.len())?;
                writeln!(w, "extern const uint8_t {name}[{}];\n\n#endif", blob.len())?;
                Ok(())
            })?;
            let source_file = stage(&a.out, |w| {
                writeln!(w, "/* fogtemp model exported from {source} ({} bytes). Generated by fogtemp-cal export; do not edit. */", blob.len())?;
                writeln!(w, "#include \"{header_name}\"\n")?;
                writeln!(w, "const uint8_t {name}[{}] = {{\n{}\n}};", blob.len(), bytes_lines(16))?;
                Ok(())
            })?;
            source_file.commit()?;
            header.commit().map_err(anyhow::Error::from)
        }
    }?;
    println!("wrote {}", a.out.display());
    Ok(())
}

fn allan(a: AllanArgs) -> Result<()> {
    let ingest = ingest_options(&a.ingest)?;
    let axes = ingest.format.gyro_columns.len();
    let mut series: Vec<Vec<f64>> = vec![Vec::new(); axes];
    let mut times = Vec::new();
    let bar = RowProgress::new(&a.log, "allan");
    let report = fogtemp_cal::ingest::read_log_with_progress(
        &a.log,
        &ingest,
        |row| {
            times.push(row.time_s);
            for (s, g) in series.iter_mut().zip(row.gyros_dph) {
                s.push(*g);
            }
            Ok(())
        },
        |b, r| bar.update(b, r),
    )?;
    bar.finish_and_clear();
    report_skipped(&report);
    let dt_s = median_step(&times)
        .with_context(|| format!("{}: the log needs at least two rows", a.log.display()))?;
    let irregular = times.windows(2).filter(|w| (w[1] - w[0]) > 1.5 * dt_s).count();
    let mut docs = Vec::new();
    for (axis, s) in series.iter().enumerate() {
        let curve = allan_deviation(s, dt_s);
        let terms = fit_noise_terms(&curve);
        docs.push(json!({
            "axis": axis,
            "column": ingest.format.gyro_columns[axis],
            "sample_period_s": dt_s,
            "samples": s.len(),
            "arw_deg_per_sqrt_h": terms.arw_deg_per_sqrt_h,
            "bias_instability_dph": terms.bias_instability_dph,
            "rrw_dph_per_sqrt_h": terms.rrw_dph_per_sqrt_h,
            "curve": curve.iter().map(|p| json!({"tau_s": p.tau_s, "adev_dph": p.adev_dph, "relative_error": p.relative_error})).collect::<Vec<_>>(),
        }));
    }
    let doc = json!({
        "log": a.log.display().to_string(),
        "definition": "overlapping Allan deviation (IEEE Std 952) of the gyro, from the f64 angle cumsum with the mean removed; N, B, K by non-negative least squares on sigma^2",
        "gaps": irregular,
        "axes": docs,
    });
    if a.json {
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    if irregular > 0 {
        eprintln!("warning: {irregular} steps longer than 1.5x the median sample period; the Allan deviation assumes uniform sampling");
    }
    for d in doc["axes"].as_array().into_iter().flatten() {
        println!(
            "axis {} ({}): N = {:.6} deg/sqrt(h), B = {:.6} deg/h, K = {:.6} deg/h/sqrt(h)",
            d["axis"],
            d["column"],
            d["arw_deg_per_sqrt_h"].as_f64().unwrap_or(f64::NAN),
            d["bias_instability_dph"].as_f64().unwrap_or(f64::NAN),
            d["rrw_dph_per_sqrt_h"].as_f64().unwrap_or(f64::NAN)
        );
        for p in d["curve"].as_array().into_iter().flatten() {
            println!(
                "  tau {:>10.3} s  adev {:.6} deg/h",
                p["tau_s"].as_f64().unwrap_or(0.0),
                p["adev_dph"].as_f64().unwrap_or(0.0)
            );
        }
    }
    Ok(())
}

fn median_step(times: &[f64]) -> Option<f64> {
    let mut steps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0.0).collect();
    if steps.is_empty() {
        return None;
    }
    let mid = steps.len() / 2;
    let (_, m, _) = steps.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    Some(*m)
}
