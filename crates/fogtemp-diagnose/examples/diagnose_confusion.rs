//! Confusion matrix of the diagnosis on concealed-effect datasets made with the simulator
//! (`fogtemp_diagnose::concealed`): every dataset over several noise seeds, the
//! effects named each time (injected effect x named effects, Markdown), and the recovery
//! of each injected effect's parameters (mean, spread over seeds, mean reported standard
//! error, and how often the truth lies within 3.5 reported SE).
//!
//! `cargo run --release -p fogtemp-diagnose --example diagnose_confusion -- [SEEDS] [FIRST_SEED] [SCALE] [LABEL...]`
//! (defaults: 20 seeds from 5000, sizes x1, every dataset; docs/diagnose.md gives the commands
//! it was made with). SCALE multiplies every injected size (`concealed::datasets_at`).
//! `-v` anywhere prints each diagnosis's candidate table; `--no-candidate-levels` and
//! `--no-gls-heldout` turn off the ninth session's two options (the first on since the
//! thirteenth session), `--no-encompassing` the
//! tenth session's tie-break, `--level-per-candidate` turns on and `--no-orientation-families` off the
//! eleventh session's two splits of the noise-model route's family-wise level, `--family-levels`
//! turns on its orientation family's own levels, `--no-position-permutation` turns off the twelfth
//! session's permutation test of the position labels, `--no-backward` the backward elimination
//! of 2026-11-28 (docs/diagnose.md).

use std::collections::BTreeMap;
use std::time::Instant;

use fogtemp_diagnose::concealed::{datasets_at, effect_size, generate, truth_map, RESIDUAL_NOISE_100S_DPH};
use fogtemp_diagnose::effects::Effect;
use fogtemp_diagnose::{diagnose, DiagnoseOptions, Diagnosis};

/// Recovery statistics of one parameter over seeds.
#[derive(Default)]
struct Recovery {
    truth: f64,
    values: Vec<f64>,
    ses: Vec<f64>,
    covered: usize,
}

/// One matrix row: label, identifiable, effects named (count per name), seeds naming
/// nothing, seeds where the injected effect is named or an alternative of a named one.
type Row = (String, bool, BTreeMap<String, usize>, usize, usize);

fn print_candidates(d: &Diagnosis) {
    for step in &d.selection {
        for c in &step.candidates {
            eprintln!(
                "    step {:?} {:<26} {:<16} cv {:+.3} folds {}/{} gain t {:.2} rank p {:.4} dBIC {:8.1} t {:6.1} share {:5.2} conceal {:.3} confused {:?} {:?} {}",
                step.model,
                c.effect,
                c.status,
                c.cv_improvement,
                c.folds_improved,
                c.folds_informative,
                c.fold_gain_t,
                c.fold_gain_rank_p,
                c.delta_bic,
                c.stability_t,
                c.min_fold_share,
                c.concealment_index,
                c.most_confused_with,
                c.profile,
                c.note
            );
        }
    }
    for e in &d.left_out {
        let p: Vec<String> = e
            .parameters
            .iter()
            .map(|(k, v)| format!("{k}={:.5}+-{:.5}", v.value, v.std_error.unwrap_or(f64::NAN)))
            .collect();
        eprintln!("    left out {}: {}", e.effect, p.join(" "));
        eprintln!("      {}", e.statement);
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let verbose = args.iter().any(|a| a == "-v");
    let options = DiagnoseOptions {
        noise_model_candidate_levels: !args.iter().any(|a| a == "--no-candidate-levels"),
        noise_model_heldout: !args.iter().any(|a| a == "--no-gls-heldout"),
        encompassing_tie_break: !args.iter().any(|a| a == "--no-encompassing"),
        noise_model_level_per_candidate: args.iter().any(|a| a == "--level-per-candidate"),
        noise_model_orientation_families: !args.iter().any(|a| a == "--no-orientation-families"),
        noise_model_family_levels: args.iter().any(|a| a == "--family-levels"),
        position_permutation: !args.iter().any(|a| a == "--no-position-permutation"),
        backward_elimination: !args.iter().any(|a| a == "--no-backward"),
        ..DiagnoseOptions::default()
    };
    let positional: Vec<&String> = args.iter().filter(|a| !a.starts_with('-')).collect();
    let seeds: u64 = positional.first().and_then(|v| v.parse().ok()).unwrap_or(20);
    let first: u64 = positional.get(1).and_then(|v| v.parse().ok()).unwrap_or(5000);
    let scale: f64 = positional.get(2).and_then(|v| v.parse().ok()).unwrap_or(1.0);
    let only: Vec<&str> = positional.iter().skip(3).map(|s| s.as_str()).collect();
    let all = datasets_at(scale);
    let columns: Vec<&str> = Effect::ALL.iter().map(|e| e.name()).collect();
    let mut rows: Vec<Row> = Vec::new();
    let mut recoveries: Vec<(String, BTreeMap<String, Recovery>)> = Vec::new();
    let mut sizes: Vec<(String, f64, f64)> = Vec::new();
    let start = Instant::now();
    for ds in all.iter().filter(|d| only.is_empty() || only.contains(&d.label.as_str())) {
        let mut counts: BTreeMap<String, usize> = BTreeMap::new();
        let mut none = 0;
        // Seeds where the injected effect is named or listed as an alternative of a named one.
        let mut offered = 0;
        let mut rec: BTreeMap<String, Recovery> = BTreeMap::new();
        for seed in first..first + seeds {
            let g = generate(ds, seed);
            if seed == first {
                let (rms, peak) = effect_size(&g.simulated_truth, &g.recorded_truth);
                sizes.push((ds.label.clone(), rms, peak));
            }
            let truth = truth_map(ds, &g);
            let t0 = Instant::now();
            let d = diagnose(&g.simulated, &g.recorded, &options, |_, _| {}).expect("diagnosis runs");
            let named: Vec<&str> = d.left_out.iter().map(|e| e.effect.as_str()).collect();
            eprintln!("{} seed {seed}: {:?} ({:.1} s)", ds.label, named, t0.elapsed().as_secs_f64());
            if verbose {
                print_candidates(&d);
            }
            if named.is_empty() {
                none += 1;
            }
            if let Some(effect) = ds.injected {
                if d.left_out
                    .iter()
                    .any(|e| e.effect == effect.name() || e.alternatives.iter().any(|a| a == effect.name()))
                {
                    offered += 1;
                }
            }
            for n in &named {
                *counts.entry((*n).to_string()).or_default() += 1;
            }
            if let Some(effect) = ds.injected {
                for (name, value) in &truth {
                    let r = rec.entry(name.clone()).or_default();
                    r.truth = *value;
                    if let Some(p) = d
                        .left_out
                        .iter()
                        .find(|e| e.effect == effect.name())
                        .and_then(|e| e.parameters.get(name))
                    {
                        let se = p.std_error.unwrap_or(f64::NAN);
                        r.values.push(p.value);
                        r.ses.push(se);
                        if (p.value - value).abs() <= 3.5 * se {
                            r.covered += 1;
                        }
                    }
                }
            }
        }
        rows.push((ds.label.clone(), ds.identifiable, counts, none, offered));
        recoveries.push((ds.label.clone(), rec));
    }
    println!(
        "Sizes x{scale}; seeds {first}..{} ({seeds} per dataset); {:.0} s in total.\n",
        first + seeds - 1,
        start.elapsed().as_secs_f64()
    );
    println!("| dataset (injected) | {} | none | injected named or an alternative |", columns.join(" | "));
    println!("|---|{}---|---|", "---|".repeat(columns.len()));
    for (label, identifiable, counts, none, offered) in &rows {
        let cells: Vec<String> =
            columns.iter().map(|c| counts.get(*c).copied().unwrap_or(0).to_string()).collect();
        let mark = if *identifiable { "" } else { " (concealed beyond recovery)" };
        let offered = if label == "null" { "-".to_string() } else { offered.to_string() };
        println!("| {label}{mark} | {} | {none} | {offered} |", cells.join(" | "));
    }
    println!("\nEffect sizes (noise-free truth, recorded minus simulated about its mean over all runs):\n");
    println!("| dataset | RMS deg/h | peak deg/h | RMS / {RESIDUAL_NOISE_100S_DPH} |");
    println!("|---|---|---|---|");
    for (label, rms, peak) in &sizes {
        println!("| {label} | {rms:.4} | {peak:.4} | {:.2} |", rms / RESIDUAL_NOISE_100S_DPH);
    }
    println!("\nParameter recovery (seeds where the injected effect was named):\n");
    println!(
        "| dataset | parameter | truth | named | mean | std over seeds | mean reported SE | within 3.5 SE |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (label, rec) in &recoveries {
        for (name, r) in rec {
            let n = r.values.len();
            if n == 0 {
                println!("| {label} | {name} | {:.5} | 0 | - | - | - | - |", r.truth);
                continue;
            }
            let mean = r.values.iter().sum::<f64>() / n.max(1) as f64;
            let sd =
                (r.values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n.max(2) - 1) as f64).sqrt();
            let se = r.ses.iter().sum::<f64>() / n.max(1) as f64;
            println!(
                "| {label} | {name} | {:.5} | {n} | {mean:.5} | {sd:.5} | {se:.5} | {}/{n} |",
                r.truth, r.covered
            );
        }
    }
}
