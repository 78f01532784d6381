//! `allan`: overlapping Allan deviation and fitted noise terms of a log.

use anyhow::{Context, Result};
use fogtemp_cal::metrics::{allan_deviation, fit_noise_terms};
use serde_json::json;

use super::{ingest_options, report_skipped};
use crate::args::AllanArgs;
use crate::output::RowProgress;

pub fn allan(a: AllanArgs) -> Result<()> {
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
