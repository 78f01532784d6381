//! `simulate`: scenario -> CSV logs, in parallel, with a progress bar; `demo`: the paper's
//! experiment end to end.

use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{Context, Result};
use fogtemp_sim::documents::{DemoDocument, SimulateDocument};
use fogtemp_sim::{self as sim, Scenario};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::print_json;
use crate::args::SimulateArgs;

/// Reads `paper` or a TOML file, applies the command-line overrides, and returns the
/// scenario with the text to store beside the logs.
pub fn load_scenario(
    name: &str,
    rate_hz: Option<f64>,
    seed: Option<u64>,
    duration_s: Option<f64>,
) -> Result<(Scenario, String)> {
    let (mut scenario, mut text) = if name == "paper" {
        (Scenario::paper()?, sim::PAPER_TOML.to_string())
    } else {
        let text =
            std::fs::read_to_string(name).with_context(|| format!("cannot read scenario file {name}"))?;
        (Scenario::from_toml(&text, name)?, text)
    };
    let overridden = scenario
        .apply_overrides(rate_hz, seed, duration_s)
        .map_err(|e| anyhow::anyhow!("scenario after command-line overrides: {e}"))?;
    if overridden {
        // Store what was simulated, not the file before the overrides.
        let comment = Scenario::overrides_comment(name, rate_hz, seed, duration_s);
        text = format!("{comment}\n{}", scenario.to_toml()?);
    }
    Ok((scenario, text))
}

/// A samples progress bar on stderr (hidden when stderr is not a terminal).
pub fn samples_bar(total: u64, label: &str) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(
        "{prefix} [{bar:30}] {human_pos}/{human_len} samples {per_sec} eta {eta}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(label.to_string());
    bar
}

/// Total samples of a scenario.
pub fn total_samples(scenario: &Scenario) -> u64 {
    scenario.expanded_runs().iter().map(|r| (r.duration_s * scenario.sample_rate_hz).floor() as u64 + 1).sum()
}

/// CSV from which the size is said before simulating (1 GB).
const NOTED_CSV_BYTES: f64 = 1e9;

/// Says how much CSV a scenario writes when that is a lot, and refuses what no disk holds
/// (`fogtemp_sim::csv_bytes`), before the output folder is made.
fn check_size(scenario: &Scenario) -> Result<()> {
    let bytes = sim::csv_bytes(scenario)?;
    if bytes > NOTED_CSV_BYTES {
        eprintln!(
            "note: simulating {} runs: about {} of CSV",
            scenario.expanded_runs().len(),
            indicatif::HumanBytes(bytes as u64)
        );
    }
    Ok(())
}

/// Simulates into a folder; returns the run summaries and the seconds it took.
pub fn simulate_into(
    scenario: &Scenario,
    text: &str,
    out: &std::path::Path,
) -> Result<(Vec<sim::RunSummary>, f64)> {
    check_size(scenario)?;
    crate::output::note_leftover_temporaries_in(out);
    // `simulate_to_dir` checks the folder and the scenario, then makes the folder: a refused
    // scenario leaves nothing (review30b F4).
    let bar = samples_bar(total_samples(scenario), "simulate");
    let done = AtomicU64::new(0);
    let started = std::time::Instant::now();
    let runs = sim::simulate_to_dir(scenario, text, out, &|n| {
        let total = done.fetch_add(n, Ordering::Relaxed) + n;
        bar.set_position(total);
    })
    .with_context(|| format!("simulating into {}", out.display()))?;
    bar.finish_and_clear();
    Ok((runs, started.elapsed().as_secs_f64()))
}

/// The `simulate` command.
pub fn simulate(a: SimulateArgs) -> Result<()> {
    let (scenario, text) = load_scenario(&a.scenario, a.rate, a.seed, a.duration_s)?;
    let (runs, seconds) = simulate_into(&scenario, &text, &a.out)?;
    let doc = SimulateDocument::new(&scenario, &a.out, &runs, seconds);
    if a.json {
        print_json(&doc)?;
    } else {
        println!(
            "simulated {} runs, {} samples at {} Hz in {:.1} s into {}",
            doc.runs.len(),
            doc.samples,
            doc.sample_rate_hz,
            doc.seconds,
            a.out.display()
        );
        for r in &doc.runs {
            println!(
                "  {:<16} start {:>6.1} C  input rate {:>8.4} deg/h  {} samples",
                r.name, r.start_temp_c, r.input_rate_dph, r.samples
            );
        }
    }
    Ok(())
}

/// Demo progress: one bar per stage on stderr.
struct StageBars {
    bar: std::sync::Mutex<Option<ProgressBar>>,
}

impl fogtemp_sim::demo::DemoProgress for StageBars {
    fn stage(&self, name: &str, total: u64) {
        if let Ok(mut slot) = self.bar.lock() {
            if let Some(old) = slot.take() {
                old.finish_and_clear();
            }
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
            if let Ok(style) =
                ProgressStyle::with_template("{prefix:>9} [{bar:30}] {human_pos}/{human_len} eta {eta}")
            {
                bar.set_style(style.progress_chars("=> "));
            }
            bar.set_prefix(name.to_string());
            *slot = Some(bar);
        }
    }

    fn advance(&self, n: u64) {
        if let Ok(slot) = self.bar.lock() {
            if let Some(bar) = slot.as_ref() {
                bar.inc(n);
            }
        }
    }
}

/// The `demo` command.
pub fn demo(a: crate::args::DemoArgs) -> Result<()> {
    use fogtemp_sim::demo::{run_demo, DemoOptions, PAPER_MESH_DPH, PAPER_POLY_DPH, PAPER_RAW_DPH};
    let (scenario, text) = load_scenario(&a.scenario, a.rate, a.seed, None)?;
    let options = DemoOptions { report: !a.no_report, ..DemoOptions::default() };
    let bars = StageBars { bar: std::sync::Mutex::new(None) };
    crate::output::note_leftover_temporaries_in(&a.out);
    let result = run_demo(&scenario, &text, &a.out, &options, &bars).context("running the demo")?;
    if let Ok(mut slot) = bars.bar.lock() {
        if let Some(bar) = slot.take() {
            bar.finish_and_clear();
        }
    }
    let doc = DemoDocument::new(&result, &a.out, &options);
    if a.json {
        return print_json(&doc);
    }
    println!(
        "{} scenario at {} Hz, seed {}: calibrated on {} runs, validated on {} runs",
        result.scenario,
        result.sample_rate_hz,
        result.seed,
        result.calibration_logs.len(),
        result.validation_logs.len()
    );
    println!("{}\n", result.definition);
    println!("Table 1: validation bias stability, deg/h");
    println!("{:<12} {:>10} {:>10} {:>12} {:>12}", "model", "paper", "fogtemp", "paper ratio", "our ratio");
    // Ours to 5 decimals: 4 printed the demo's poly and mesh both 0.0040 beside ratios 3.25 and
    // 3.20 (review14 F14); the paper gives 4.
    println!("{:<12} {:>10.4} {:>10.5} {:>12} {:>12}", "raw", PAPER_RAW_DPH, result.raw_dph, "1", "1");
    for m in &result.models {
        let paper = match m.key.as_str() {
            "poly" => Some(PAPER_POLY_DPH),
            "mesh_paper" => Some(PAPER_MESH_DPH),
            _ => None,
        };
        println!(
            "{:<12} {:>10} {:>10.5} {:>12} {:>12.2}",
            m.key,
            paper.map_or_else(|| "-".into(), |p| format!("{p:.4}")),
            m.compensated_dph,
            paper.map_or_else(|| "-".into(), |p| format!("{:.2}", PAPER_RAW_DPH / p)),
            m.improvement_ratio
        );
    }
    if let Some(report) = &doc.report {
        println!("\nreport: {report}");
    }
    Ok(())
}
