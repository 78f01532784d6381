//! Sensitivity of the demo's Table 1 to the smoothing window, the thinning rule, the axis
//! scaling, the noise level and the bias structure: runs the demo (simulate, calibrate on
//! position 1, validate on position 2) once per variant and seed, and prints a Markdown
//! table of validation bias stability (deg/h, mean over seeds).
//!
//! `cargo run --release -p fogtemp-sim --example demo_sensitivity -- [RATE_HZ] [SEEDS]`
//! (defaults 100 Hz and 2 seeds; docs/demo-sensitivity.md was made with them).

use fogtemp_cal::calibrate::Thinning;
use fogtemp_core::FeatureSettings;
use fogtemp_sim::demo::{default_models, run_demo, DemoOptions, NoProgress};
use fogtemp_sim::Scenario;

/// One row of the table: what changes, and how.
struct Variant {
    name: &'static str,
    scenario: fn(&mut Scenario),
    options: fn(&mut DemoOptions),
}

fn same_scenario(_: &mut Scenario) {}
fn same_options(_: &mut DemoOptions) {}

fn window(options: &mut DemoOptions, window_s: f32) {
    for m in &mut options.models {
        m.config.features =
            FeatureSettings { window_s, block_count: window_s.round() as u32, ..m.config.features };
        m.config.target_window_s = f64::from(window_s);
    }
}

fn greedy_multiple(options: &mut DemoOptions, multiple: f64) {
    for m in &mut options.models {
        if let Thinning::GreedyAuto { max_nodes, .. } = m.config.thinning {
            m.config.thinning = Thinning::GreedyAuto { noise_multiple: multiple, max_nodes };
        }
    }
}

fn paper_thinning(options: &mut DemoOptions, settled_every: usize) {
    for m in &mut options.models {
        if let Thinning::Paper { fast_rate_c_per_min, .. } = m.config.thinning {
            m.config.thinning = Thinning::Paper { fast_rate_c_per_min, settled_every };
        }
    }
}

fn rate_weight(options: &mut DemoOptions, weight: f64) {
    for m in &mut options.models {
        m.config.rate_axis_weight = weight;
    }
}

fn variants() -> Vec<Variant> {
    vec![
        Variant {
            name: "baseline (paper scenario, defaults)",
            scenario: same_scenario,
            options: same_options,
        },
        Variant { name: "smoothing window 50 s", scenario: same_scenario, options: |o| window(o, 50.0) },
        Variant { name: "smoothing window 200 s", scenario: same_scenario, options: |o| window(o, 200.0) },
        Variant {
            name: "greedy thinning to 1.0x noise",
            scenario: same_scenario,
            options: |o| greedy_multiple(o, 1.0),
        },
        Variant {
            name: "greedy thinning to 3.0x noise",
            scenario: same_scenario,
            options: |o| greedy_multiple(o, 3.0),
        },
        Variant {
            name: "paper thinning: every 2nd settled point",
            scenario: same_scenario,
            options: |o| paper_thinning(o, 2),
        },
        Variant {
            name: "paper thinning: every 10th settled point",
            scenario: same_scenario,
            options: |o| paper_thinning(o, 10),
        },
        Variant {
            name: "rate axis 0.1x temperature axis",
            scenario: same_scenario,
            options: |o| rate_weight(o, 0.1),
        },
        Variant {
            name: "rate axis 10x temperature axis",
            scenario: same_scenario,
            options: |o| rate_weight(o, 10.0),
        },
        Variant {
            name: "unscaled axes (deg C vs deg C/min)",
            scenario: same_scenario,
            // Physical units: T spans ~110 C, the rate ~0.7 C/min, so the normalised rate
            // axis is shrunk by their ratio.
            options: |o| rate_weight(o, 0.7 / 110.0),
        },
        Variant {
            name: "noise: N = 0.0003 deg/sqrt(h), B = 0.001 deg/h",
            scenario: |s| {
                s.noise.arw_deg_per_sqrt_h = 0.0003;
                s.noise.bias_instability_dph = 0.001;
            },
            options: same_options,
        },
        Variant {
            name: "noise: N = 0.0008 deg/sqrt(h), B = 0.004 deg/h",
            scenario: |s| {
                s.noise.arw_deg_per_sqrt_h = 0.0008;
                s.noise.bias_instability_dph = 0.004;
            },
            options: same_options,
        },
        Variant {
            name: "no noise (N = B = 0)",
            scenario: |s| {
                s.noise.arw_deg_per_sqrt_h = 0.0;
                s.noise.bias_instability_dph = 0.0;
            },
            options: same_options,
        },
        Variant {
            name: "bias structure: PNR ripple 0.01 deg/h, period 20 C",
            scenario: |s| s.bias.static_ripple_dph = 0.01,
            options: same_options,
        },
        Variant {
            name: "bias structure: warm-up transient 0.02 deg/h, 10 min",
            scenario: |s| s.bias.warmup_amplitude_dph = 0.02,
            options: same_options,
        },
        Variant {
            name: "Shupe coefficient of the opposite sign",
            scenario: |s| s.bias.shupe_dph_per_c_per_min = -s.bias.shupe_dph_per_c_per_min,
            options: same_options,
        },
    ]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let rate_hz: f64 = args.get(1).map_or(Ok(100.0), |a| a.parse())?;
    let seeds: u64 = args.get(2).map_or(Ok(2), |a| a.parse())?;
    let keys: Vec<String> = default_models().into_iter().map(|m| m.key).collect();
    let dir = std::env::temp_dir().join(format!("fogtemp-sensitivity-{}", std::process::id()));
    println!(
        "Validation bias stability, deg/h (RMS over the 8 position-2 runs; mean over {seeds} seeds at {rate_hz} Hz)\n"
    );
    print!("| variant | raw |");
    for k in &keys {
        print!(" `{k}` |");
    }
    print!("\n|---|---|");
    for _ in &keys {
        print!("---|");
    }
    println!();
    let started = std::time::Instant::now();
    for v in variants() {
        let mut sums = vec![0.0; keys.len() + 1];
        for seed in 0..seeds {
            let mut scenario = Scenario::paper()?;
            scenario.sample_rate_hz = rate_hz;
            scenario.seed = 2020 + seed;
            (v.scenario)(&mut scenario);
            let mut options = DemoOptions { report: false, ..DemoOptions::default() };
            (v.options)(&mut options);
            let text = scenario.to_toml()?;
            let result = run_demo(&scenario, &text, &dir, &options, &NoProgress)?;
            sums[0] += result.raw_dph;
            for (i, k) in keys.iter().enumerate() {
                sums[i + 1] += result.model(k).map_or(f64::NAN, |m| m.compensated_dph);
            }
        }
        print!("| {} |", v.name);
        for s in &sums {
            print!(" {:.4} |", s / seeds as f64);
        }
        println!();
    }
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!("took {:.0} s", started.elapsed().as_secs_f64());
    Ok(())
}
