//! `diagnose`: simulated vs recorded logs -> located mismatch, named physics, fitted term,
//! held-out before/after. Reads the logs into 1 s means (constant memory per sample), pairs
//! them by file name, takes run metadata (position, Earth rate on the input axis) from
//! `--runs FILE` or else from the simulation's `manifest.json` when it has one.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use fogtemp_cal::ingest::{read_log_with_progress, IngestOptions};
use fogtemp_diagnose::{
    diagnose as run_diagnosis, write_diagnosis_report, DiagnoseDocument, DiagnoseOptions, Diagnosis, RunMeta,
    RunSeries,
};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::print_json;
use crate::args::DiagnoseArgs;
use crate::output::{expand_logs, RowProgress};

/// Reads a log into `bin_s` means of time, temperature and gyro (axis 0). Bins without a
/// temperature reading keep NaN temperature.
fn read_series(path: &Path, ingest: &IngestOptions, bin_s: f64, meta: RunMeta) -> Result<RunSeries> {
    let bar = RowProgress::new(path, "read");
    let mut series = RunSeries { name: file_name(path), meta, ..RunSeries::default() };
    // (bin, n, sum t, n temp, sum temp, sum gyro)
    let mut acc: (i64, f64, f64, f64, f64, f64) = (i64::MIN, 0.0, 0.0, 0.0, 0.0, 0.0);
    let flush = |s: &mut RunSeries, a: &(i64, f64, f64, f64, f64, f64)| {
        if a.1 > 0.0 {
            s.time_s.push(a.2 / a.1);
            s.temp_c.push(if a.3 > 0.0 { a.4 / a.3 } else { f64::NAN });
            s.gyro_dph.push(a.5 / a.1);
        }
    };
    let report = read_log_with_progress(
        path,
        ingest,
        |row| {
            let bin = (row.time_s / bin_s).floor() as i64;
            if bin != acc.0 {
                flush(&mut series, &acc);
                acc = (bin, 0.0, 0.0, 0.0, 0.0, 0.0);
            }
            acc.1 += 1.0;
            acc.2 += row.time_s;
            let temp = row.temp_c_for_axis(0);
            if temp.is_finite() {
                acc.3 += 1.0;
                acc.4 += temp;
            }
            acc.5 += row.gyros_dph.first().copied().unwrap_or(f64::NAN);
            Ok(())
        },
        |b, r| bar.update(b, r),
    )
    .with_context(|| format!("reading {}", path.display()))?;
    flush(&mut series, &acc);
    bar.finish_and_clear();
    if report.rows == 0 {
        bail!("{}: no data rows (only a header)", path.display());
    }
    if report.skipped > 0 {
        eprintln!("{}: skipped {} bad rows", path.display(), report.skipped);
    }
    Ok(series)
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// Run metadata from `DIR/manifest.json` (written by `simulate`), keyed by file name.
fn manifest_meta(dir: &Path) -> Result<BTreeMap<String, RunMeta>> {
    let path = dir.join("manifest.json");
    if !path.is_file() {
        return Ok(BTreeMap::new());
    }
    let text = std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let doc: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", path.display()))?;
    let mut out = BTreeMap::new();
    for run in doc["runs"].as_array().map(Vec::as_slice).unwrap_or_default() {
        let Some(name) = run["name"].as_str() else { continue };
        out.insert(
            format!("{name}.csv"),
            RunMeta {
                group: run["group"].as_str().filter(|g| !g.is_empty()).map(str::to_string),
                input_rate_dph: run["input_rate_dph"].as_f64(),
                power_on_at_s: None,
            },
        );
    }
    Ok(out)
}

/// Run metadata from a runs file (`--runs`), keyed by file name. Every simulated log must
/// have a row and every row a log (errors name the file and line).
fn runs_file_meta(path: &Path, simulated: &[PathBuf]) -> Result<BTreeMap<String, RunMeta>> {
    let file = fogtemp_cal::runs::RunsFile::read(path)?;
    let rows = file.for_logs(simulated)?;
    Ok(simulated
        .iter()
        .zip(rows)
        .map(|(log, row)| {
            let meta = RunMeta {
                group: Some(row.position.clone()),
                input_rate_dph: Some(row.input_rate_dph),
                power_on_at_s: None,
            };
            (file_name(log), meta)
        })
        .collect())
}

/// Pairs simulated and recorded logs by file name; every log must have a partner.
fn pair(simulated: &[PathBuf], recorded: &[PathBuf]) -> Result<Vec<(PathBuf, PathBuf)>> {
    let by_name: BTreeMap<String, &PathBuf> = recorded.iter().map(|p| (file_name(p), p)).collect();
    let mut pairs = Vec::new();
    let mut unmatched = Vec::new();
    for s in simulated {
        match by_name.get(&file_name(s)) {
            Some(r) => pairs.push((s.clone(), (*r).clone())),
            None => unmatched.push(format!("simulated {} has no recorded log of that name", file_name(s))),
        }
    }
    let sim_names: std::collections::BTreeSet<String> = simulated.iter().map(|p| file_name(p)).collect();
    for r in recorded {
        if !sim_names.contains(&file_name(r)) {
            unmatched.push(format!("recorded {} has no simulated log of that name", file_name(r)));
        }
    }
    if !unmatched.is_empty() {
        bail!("runs are paired by file name, and {} are not:\n  {}", unmatched.len(), unmatched.join("\n  "));
    }
    Ok(pairs)
}

/// The `diagnose` command.
pub fn diagnose(a: DiagnoseArgs, recorded_ingest: IngestOptions) -> Result<()> {
    let simulated = expand_logs(std::slice::from_ref(&a.simulated))?;
    let recorded = expand_logs(std::slice::from_ref(&a.recorded))?;
    let pairs = pair(&simulated, &recorded)?;
    let meta = match &a.runs {
        Some(path) => runs_file_meta(path, &simulated)?,
        None => manifest_meta(&a.simulated)?,
    };
    let sim_ingest = IngestOptions::default();
    let mut sims = Vec::new();
    let mut recs = Vec::new();
    for (s, r) in &pairs {
        let m = meta.get(&file_name(s)).cloned().unwrap_or_default();
        sims.push(read_series(s, &sim_ingest, a.bin_s, m.clone())?);
        recs.push(read_series(r, &recorded_ingest, a.bin_s, m)?);
    }
    let options = DiagnoseOptions {
        mean_window_s: a.mean_window_s,
        rate_window_s: a.rate_window_s,
        window_coverage: a.window_coverage,
        block_coverage: a.block_coverage,
        ..DiagnoseOptions::default()
    };
    let bar = ProgressBar::with_draw_target(Some(1000), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template("diagnose [{bar:30}] {percent}% {msg}") {
        bar.set_style(style.progress_chars("=> "));
    }
    let started = std::time::Instant::now();
    let d = run_diagnosis(&sims, &recs, &options, |stage, fraction| {
        bar.set_message(stage.to_string());
        bar.set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
    })
    .context("diagnosing")?;
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let mut scenario_changes = Vec::new();
    let mut updated_path = None;
    if let Some(dir) = &a.report {
        write_diagnosis_report(dir, &d)
            .with_context(|| format!("writing the report into {}", dir.display()))?;
        eprintln!("report: {}", dir.join("report.md").display());
        if let Some((path, changes)) = write_updated_scenario(&a.simulated, dir, &d)? {
            eprintln!("scenario with the effects found: {}", path.display());
            scenario_changes = changes;
            updated_path = Some(path);
        }
    }
    if a.json {
        print_json(&DiagnoseDocument {
            diagnosis: &d,
            seconds,
            updated_scenario: updated_path.map(|p| p.display().to_string()),
            scenario_changes,
        })?;
    } else {
        println!("{}", d.summary);
        eprintln!("diagnosed {} run pairs in {seconds:.1} s", pairs.len());
    }
    Ok(())
}

/// When the simulation folder holds the `scenario.toml` it was made from, writes
/// `DIR/scenario-updated.toml`: that scenario with every effect found (the changes listed
/// at its top). Returns the path and the changes, or `None` without a scenario.
fn write_updated_scenario(
    simulated: &Path,
    dir: &Path,
    d: &Diagnosis,
) -> Result<Option<(PathBuf, Vec<String>)>> {
    let source = simulated.join("scenario.toml");
    if !source.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&source).with_context(|| format!("reading {}", source.display()))?;
    let scenario = fogtemp_sim::Scenario::from_toml(&text, &source.display().to_string())?;
    let (updated, changes) = fogtemp_diagnose::updated_scenario(&scenario, d);
    let mut out =
        format!("# {} updated by `fogtemp-cal diagnose` with the effects it found:\n", source.display());
    if changes.is_empty() {
        out.push_str("# (none: nothing is left out)\n");
    }
    for c in &changes {
        out.push_str(&format!("# - {c}\n"));
    }
    out.push_str(&updated.to_toml()?);
    let path = dir.join("scenario-updated.toml");
    crate::output::write_atomic(&path, |w| Ok(w.write_all(out.as_bytes())?))?;
    Ok(Some((path, changes)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn runs_file(text: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("runs.csv");
        std::fs::write(&path, text).expect("write runs.csv");
        (dir, path)
    }

    fn logs(names: &[&str]) -> Vec<PathBuf> {
        names.iter().map(|n| PathBuf::from(format!("sim/{n}.csv"))).collect()
    }

    #[test]
    fn runs_file_gives_every_log_its_position_and_rate() {
        let (_dir, path) = runs_file("run,position,input_rate_dph\nb,down,-9.5\na,up,9.5\n");
        let meta = runs_file_meta(&path, &logs(&["a", "b"])).expect("valid");
        assert_eq!(meta["a.csv"].group.as_deref(), Some("up"));
        assert_eq!(meta["a.csv"].input_rate_dph, Some(9.5));
        assert_eq!(meta["b.csv"].group.as_deref(), Some("down"));
        assert_eq!(meta["b.csv"].input_rate_dph, Some(-9.5));
    }

    #[test]
    fn runs_file_errors_name_the_file_and_line() {
        let message = |text: &str, names: &[&str]| {
            let (_dir, path) = runs_file(text);
            let err = runs_file_meta(&path, &logs(names)).expect_err("must fail");
            (format!("{err:#}"), path.display().to_string())
        };
        let (m, file) = message("run,position,input_rate_dph\na,up,1\na,down,-1\n", &["a"]);
        assert!(m.starts_with(&format!("{file}:3: ")) && m.contains("listed twice"), "{m}");
        let (m, file) = message("run,position,input_rate_dph\na,up,1\nc,down,-1\n", &["a"]);
        assert!(m.starts_with(&format!("{file}:3: ")) && m.contains("'c'"), "{m}");
        let (m, file) = message("run,position,input_rate_dph\na,up,1\n", &["a", "b"]);
        assert!(m.starts_with(&format!("{file}:")) && m.contains("b.csv"), "{m}");
        let (m, file) = message("run,position\na,up\n", &["a"]);
        assert!(m.starts_with(&format!("{file}:1: ")) && m.contains("input_rate_dph"), "{m}");
    }
}
