//! Diagnosis library tests on in-memory synthetic pairs: a simulated run (the model's
//! physics, noise-free) and a recorded run (the same physics plus at most ONE catalogue
//! effect, plus white and flicker noise, a quantised sample-and-hold temperature channel).
//!
//! Thermal truth: chamber temperature `T_a(t)`; after power-on the case (where the sensor
//! sits) approaches `T_a + 10 C` with tau 25 min; the coil follows the case through a
//! first-order lag of 10 min. The simulation assumes the coil is at the sensor temperature:
//! `gyro_sim = b(T_case) + S1 dT_case/dt` with `b(T) = 0.005 (T - 20) + 5e-5 (T - 20)^2`
//! deg/h and `S1 = 0.06` deg/h per C/min (docs/physics.md section 5). Only the `thermal_lag`
//! scenario lets the coil's lag show in the recorded gyro. Noise (docs/physics.md section 3):
//! white N = 0.0005 deg/sqrt(h), flicker B = 0.002 deg/h as one Gauss-Markov process per
//! decade (tau 1 s .. 1e5 s, stationary start), plus a recorded global offset of
//! 0.002 deg/h. Effect sizes are comparable to the noise of a 100 s mean (0.003 deg/h).

mod common;

use std::time::Instant;

use fogtemp_diagnose::{
    diagnose, write_diagnosis_report, DiagnoseError, DiagnoseOptions, Diagnosis, RunMeta, RunSeries,
    SeriesProblem, Side,
};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

const RUN_S: f64 = 7200.0;
const TAU_CASE_S: f64 = 1500.0;
const TAU_COIL_S: f64 = 600.0;
const SELF_HEATING_C: f64 = 10.0;
const S1_DPH_PER_C_PER_MIN: f64 = 0.06;
const ARW_DEG_PER_SQRT_H: f64 = 0.0005;
const BIAS_INSTABILITY_DPH: f64 = 0.002;
const RECORDED_OFFSET_DPH: f64 = 0.002;
const EARTH_UP_DPH: f64 = 9.67;

fn static_bias_dph(t: f64) -> f64 {
    0.005 * (t - 20.0) + 5e-5 * (t - 20.0).powi(2)
}

/// Chamber temperature profile.
#[derive(Clone, Copy, Debug)]
enum Chamber {
    /// Constant at the start temperature.
    Constant,
    /// Ramp of `rate_c_per_min` from `start_s` for `duration_s`.
    Ramp { rate_c_per_min: f64, start_s: f64, duration_s: f64 },
    /// Sinusoid of amplitude `amp_c` and period `period_s`.
    Sine { amp_c: f64, period_s: f64 },
    /// Triangle wave of amplitude `amp_c` and period `period_s` (starts rising).
    Triangle { amp_c: f64, period_s: f64 },
}

impl Chamber {
    fn at(self, start_c: f64, t: f64) -> f64 {
        match self {
            Chamber::Constant => start_c,
            Chamber::Ramp { rate_c_per_min, start_s, duration_s } => {
                start_c + rate_c_per_min / 60.0 * (t - start_s).clamp(0.0, duration_s)
            }
            Chamber::Sine { amp_c, period_s } => {
                start_c + amp_c * (std::f64::consts::TAU * t / period_s).sin()
            }
            Chamber::Triangle { amp_c, period_s } => {
                let phase = (t / period_s).fract();
                let tri = if phase < 0.25 {
                    4.0 * phase
                } else if phase < 0.75 {
                    2.0 - 4.0 * phase
                } else {
                    4.0 * phase - 4.0
                };
                start_c + amp_c * tri
            }
        }
    }
}

#[derive(Clone, Debug)]
struct RunPlan {
    name: String,
    start_c: f64,
    chamber: Chamber,
    group: Option<String>,
    input_rate_dph: Option<f64>,
}

fn plan(name: &str, start_c: f64, chamber: Chamber) -> RunPlan {
    RunPlan { name: name.into(), start_c, chamber, group: None, input_rate_dph: None }
}

/// The one catalogue effect injected into the recorded runs.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Injected {
    None,
    /// The coil sees the case temperature through a first-order lag of 600 s.
    ThermalLag,
    /// The recorded dT/dt coefficient is larger than the simulated one by this, deg/h per C/min.
    ShupeRate(f64),
    /// `A exp(-t / tau)`: (A deg/h, tau s).
    Warmup(f64, f64),
    /// Offset of group "B" relative to group "A", deg/h.
    Orientation(f64),
    /// +h on heating, -h on cooling; the branch switches when |dT/dt| > 0.02 C/min.
    Hysteresis(f64),
    /// `A sin(2 pi T / period)`: (A deg/h, period C).
    StaticRipple(f64, f64),
    /// Input rate x s1 x (T - 20 C), s1 in ppm/C.
    ScaleFactor(f64),
    /// Not in the catalogue: a bump `A exp(-((t - t0) / w)^2 / 2)` in the time since power-on
    /// (say, a board that heats up and settles): (A deg/h, t0 s, w s).
    TimeBump(f64, f64, f64),
}

/// Thermal state on a 1 s grid: (case, coil, case rate C/min).
fn thermal(run: &RunPlan) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = RUN_S as usize + 1;
    let (a_case, a_coil) = ((-1.0 / TAU_CASE_S).exp(), (-1.0 / TAU_COIL_S).exp());
    let mut case = Vec::with_capacity(n);
    let mut coil = Vec::with_capacity(n);
    let mut rate = Vec::with_capacity(n);
    let (mut tc, mut tk) = (run.start_c, run.start_c);
    for k in 0..n {
        let target = run.chamber.at(run.start_c, k as f64) + SELF_HEATING_C;
        case.push(tc);
        coil.push(tk);
        rate.push((target - tc) / TAU_CASE_S * 60.0);
        let next_c = target + (tc - target) * a_case;
        tk = next_c + (tk - next_c) * a_coil;
        tc = next_c;
    }
    (case, coil, rate)
}

/// The injected effect per second, deg/h.
fn effect_series(effect: Injected, run: &RunPlan, case: &[f64], coil: &[f64], rate: &[f64]) -> Vec<f64> {
    let mut branch = 1.0;
    (0..case.len())
        .map(|k| match effect {
            Injected::None => 0.0,
            Injected::ThermalLag => static_bias_dph(coil[k]) - static_bias_dph(case[k]),
            Injected::ShupeRate(c) => c * rate[k],
            Injected::Warmup(a, tau) => a * (-(k as f64) / tau).exp(),
            Injected::Orientation(o) => {
                if run.group.as_deref() == Some("B") {
                    o
                } else {
                    0.0
                }
            }
            Injected::Hysteresis(h) => {
                if rate[k] > 0.02 {
                    branch = 1.0;
                } else if rate[k] < -0.02 {
                    branch = -1.0;
                }
                h * branch
            }
            Injected::StaticRipple(a, period) => a * (std::f64::consts::TAU * case[k] / period).sin(),
            Injected::ScaleFactor(s1) => run.input_rate_dph.unwrap_or(0.0) * s1 * 1e-6 * (case[k] - 20.0),
            Injected::TimeBump(a, t0, w) => a * (-0.5 * ((k as f64 - t0) / w).powi(2)).exp(),
        })
        .collect()
}

/// Standard normal deviate (Box-Muller; the root package has no rand_distr).
fn normal(rng: &mut Xoshiro256PlusPlus) -> f64 {
    let u1: f64 = 1.0 - rng.gen::<f64>();
    let u2: f64 = rng.gen::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Flicker noise as a sum of first-order Gauss-Markov processes, one per decade.
struct Flicker {
    state: Vec<f64>,
    phi: Vec<f64>,
    drive: Vec<f64>,
}

impl Flicker {
    fn new(dt_s: f64, rng: &mut Xoshiro256PlusPlus) -> Self {
        let q = BIAS_INSTABILITY_DPH.powi(2) * std::f64::consts::LN_10 / std::f64::consts::PI;
        let taus = [1.0, 10.0, 100.0, 1e3, 1e4, 1e5];
        let phi: Vec<f64> = taus.iter().map(|t: &f64| (-dt_s / t).exp()).collect();
        let drive = phi.iter().map(|p| (q * (1.0 - p * p)).sqrt()).collect();
        let state = taus.iter().map(|_| q.sqrt() * normal(rng)).collect::<Vec<f64>>();
        Self { state, phi, drive }
    }

    fn next(&mut self, rng: &mut Xoshiro256PlusPlus) -> f64 {
        let mut sum = 0.0;
        for ((x, p), d) in self.state.iter_mut().zip(&self.phi).zip(&self.drive) {
            let w = normal(rng);
            *x = p * *x + d * w;
            sum += *x;
        }
        sum
    }
}

/// One simulated and one recorded run.
fn make_pair(run: &RunPlan, effect: Injected, rate_hz: f64, seed: u64) -> (RunSeries, RunSeries) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let (case, coil, rate) = thermal(run);
    let extra = effect_series(effect, run, &case, &coil, &rate);
    let dt = 1.0 / rate_hz;
    let n = (RUN_S * rate_hz) as usize;
    let ns = noise_scale();
    let white_sigma = ns * 60.0 * ARW_DEG_PER_SQRT_H * rate_hz.sqrt();
    let mut flicker = Flicker::new(dt, &mut rng);
    let meta = RunMeta { group: run.group.clone(), input_rate_dph: run.input_rate_dph, power_on_at_s: None };
    let mut sim = RunSeries { name: run.name.clone(), meta: meta.clone(), ..RunSeries::default() };
    let mut rec = RunSeries { name: run.name.clone(), meta, ..RunSeries::default() };
    let mut held_temp = f64::NAN;
    for i in 0..n {
        let t = i as f64 * dt;
        let k = (t.floor() as usize).min(case.len() - 1);
        let frac = t - k as f64;
        let k1 = (k + 1).min(case.len() - 1);
        let t_case = case[k] + (case[k1] - case[k]) * frac;
        let sim_gyro =
            static_bias_dph(t_case) + S1_DPH_PER_C_PER_MIN * rate[k] + run.input_rate_dph.unwrap_or(0.0);
        // The temperature sensor reads at 1 Hz, quantised to 1/16 C; the log holds the last reading.
        if i % (rate_hz.round().max(1.0) as usize) == 0 {
            let noisy = t_case + 0.01 * normal(&mut rng);
            held_temp = (noisy / 0.0625).round() * 0.0625;
        }
        let white = normal(&mut rng);
        let rec_gyro =
            sim_gyro + extra[k] + RECORDED_OFFSET_DPH + white_sigma * white + ns * flicker.next(&mut rng);
        sim.time_s.push(t);
        sim.temp_c.push(t_case);
        sim.gyro_dph.push(sim_gyro);
        rec.time_s.push(t);
        rec.temp_c.push(held_temp);
        rec.gyro_dph.push(rec_gyro);
    }
    (sim, rec)
}

fn make_set(
    plans: &[RunPlan],
    effect: Injected,
    rate_hz: f64,
    seed: u64,
) -> (Vec<RunSeries>, Vec<RunSeries>) {
    plans.iter().enumerate().map(|(i, p)| make_pair(p, effect, rate_hz, seed * 1000 + i as u64)).unzip()
}

/// The paper's 8 chamber temperatures; one run has a chamber ramp and one a chamber
/// sinusoid so that dT/dt is not tied to the time since power-on everywhere.
fn paper_runs() -> Vec<RunPlan> {
    let temps = [-40.0, -25.0, -10.0, 5.0, 20.0, 35.0, 45.0, 60.0];
    temps
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            let chamber = match i {
                2 => Chamber::Ramp { rate_c_per_min: 0.25, start_s: 3600.0, duration_s: 2400.0 },
                5 => Chamber::Sine { amp_c: 3.0, period_s: 1800.0 },
                _ => Chamber::Constant,
            };
            plan(&format!("run{i:02}_{t}C.csv"), t, chamber)
        })
        .collect()
}

/// Eight power-on runs 6 C apart: with 10 C of self-heating their temperature ranges
/// overlap, which a shape in T needs (docs/physics.md section 4, row 9).
fn overlapping_runs() -> Vec<RunPlan> {
    (0..8)
        .map(|i| {
            let t = -10.0 + 6.0 * f64::from(i);
            plan(&format!("overlap{i:02}_{t}C.csv"), t, Chamber::Constant)
        })
        .collect()
}

/// Two positions (A: input axis up, B: down) at the same four temperatures.
fn two_position_runs(rate_a_dph: f64, rate_b_dph: f64) -> Vec<RunPlan> {
    let temps = [-40.0, -10.0, 20.0, 50.0];
    let mut out = Vec::new();
    for (g, rate) in [("A", rate_a_dph), ("B", rate_b_dph)] {
        for (i, &t) in temps.iter().enumerate() {
            let chamber = if i == 1 {
                Chamber::Ramp { rate_c_per_min: 0.25, start_s: 3600.0, duration_s: 2400.0 }
            } else {
                Chamber::Constant
            };
            let mut p = plan(&format!("pos{g}_{t}C.csv"), t, chamber);
            p.group = Some(g.into());
            p.input_rate_dph = Some(rate);
            out.push(p);
        }
    }
    out
}

/// Six power-on runs and two chamber-cycling runs at two ramp rates.
fn cycling_runs() -> Vec<RunPlan> {
    let mut out: Vec<RunPlan> = [-40.0, -20.0, 0.0, 20.0, 40.0, 60.0]
        .iter()
        .map(|&t| plan(&format!("power_on_{t}C.csv"), t, Chamber::Constant))
        .collect();
    out.push(plan("cycle_fast_10C.csv", 10.0, Chamber::Triangle { amp_c: 8.0, period_s: 2400.0 }));
    out.push(plan("cycle_slow_30C.csv", 30.0, Chamber::Triangle { amp_c: 8.0, period_s: 4800.0 }));
    out
}

fn run_diagnosis(plans: &[RunPlan], effect: Injected, rate_hz: f64, seed: u64) -> Diagnosis {
    let (sim, rec) = make_set(plans, effect, rate_hz, seed);
    let d = diagnose(&sim, &rec, &DiagnoseOptions::default(), |_, _| {}).expect("diagnosis runs");
    eprintln!("{effect:?}: {}", d.summary);
    for step in &d.selection {
        for c in &step.candidates {
            eprintln!(
                "  step {:?} {:<26} {:<16} cv {:.5} ({:+.3}) folds {}/{} dBIC {:9.1} t {:6.1} conceal {:.3} / {:.3} {:?} {:?} {}",
                step.model, c.effect, c.status, c.cv_rms_dph, c.cv_improvement, c.folds_improved, c.folds_informative,
                c.delta_bic, c.stability_t, c.concealment_index, c.concealment_with_run_offsets, c.most_confused_with, c.profile, c.note
            );
        }
    }
    for e in &d.left_out {
        eprintln!("  left out {}: {:?}", e.effect, e.parameters);
    }
    common::assert_selection_consistent(&d);
    d
}

fn names(d: &Diagnosis) -> Vec<&str> {
    d.left_out.iter().map(|e| e.effect.as_str()).collect()
}

fn param(d: &Diagnosis, effect: &str, name: &str) -> (f64, f64) {
    let e = d.left_out.iter().find(|e| e.effect == effect).expect("effect present");
    let p = e.parameters.get(name).unwrap_or_else(|| panic!("parameter {name} in {:?}", e.parameters));
    (p.value, p.std_error.unwrap_or(f64::NAN))
}

/// Two-sided 99 % Student-t quantile with `runs - 1` degrees of freedom (the jackknife
/// standard errors have that many), for 5..=8 runs.
fn t99(runs: usize) -> f64 {
    match runs {
        5 => 4.604,
        6 => 4.032,
        7 => 3.707,
        _ => 3.499,
    }
}

/// `|value - truth| <= t99 SE` (reported jackknife SE), and the SE itself is informative
/// (below `max_relative_se` of the truth), so a useless estimate with a huge error bar
/// cannot pass.
fn assert_recovered(d: &Diagnosis, effect: &str, name: &str, truth: f64, max_relative_se: f64) {
    let (v, se) = param(d, effect, name);
    eprintln!(
        "  {effect}.{name} = {v:.5} +- {se:.5} (truth {truth}; SE / truth {:.3}, limit {max_relative_se})",
        se / truth.abs()
    );
    assert!(se.is_finite() && se > 0.0, "{effect}.{name}: standard error {se}");
    assert!(se <= max_relative_se * truth.abs(), "{effect}.{name}: SE {se} too large for truth {truth}");
    let k = t99(d.runs.len());
    assert!((v - truth).abs() <= k * se, "{effect}.{name}: {v} +- {se}, truth {truth} (tolerance {k} SE)");
}

fn assert_helps(d: &Diagnosis, effect: &str) {
    let e = d.left_out.iter().find(|e| e.effect == effect).expect("effect present");
    assert!(e.heldout_improvement > 0.0, "{effect}: held-out improvement {}", e.heldout_improvement);
    assert!(e.residual_after_dph < e.residual_before_dph);
}

#[test]
fn null_case_leaves_nothing_out_and_says_consistent_with_noise() {
    let d = run_diagnosis(&paper_runs(), Injected::None, 2.0, 77);
    assert!(d.left_out.is_empty(), "null case named {:?}", names(&d));
    assert_contract_json(&d);
    assert!(!d.unexplained.structured, "{}", d.unexplained.statement);
    // Spans significant against within-run (HAC) errors may remain under flicker; the
    // statement then locates them and says they do not repeat across runs (never "noise").
    assert!(
        d.summary.contains("consistent with noise") || d.summary.contains("does not repeat across runs"),
        "{}",
        d.summary
    );
    // The global offset is the recorded offset (3 SE), and its SE is at most twice the
    // closed-form one (see `offset_se_closed_form_dph`), so an inflated SE cannot pass.
    // Seen: 0.00166 +- 0.00037 deg/h against a closed-form SE of 0.00087 (the SE equals the
    // spread of this seed's eight run means / sqrt(8), a low draw; over seeds 100-119 that
    // spread gives 0.00034-0.00109, mean 0.00073).
    let o = &d.global_offset;
    let se = o.std_error.unwrap_or(f64::NAN);
    let expected_se = offset_se_closed_form_dph(paper_runs().len(), 2.0);
    eprintln!(
        "global offset {:.5} +- {se:.5} deg/h (truth {RECORDED_OFFSET_DPH}; closed-form SE {expected_se:.5})",
        o.value
    );
    assert!(se > 0.0 && se <= 2.0 * expected_se, "{o:?}: SE against closed-form {expected_se}");
    assert!((o.value - RECORDED_OFFSET_DPH).abs() <= 3.0 * se, "{o:?}");
}

/// Noise scale of the recorded runs (`NOISE`, default 1), as `make_pair` reads it.
fn noise_scale() -> f64 {
    std::env::var("NOISE").ok().and_then(|v| v.parse().ok()).unwrap_or(1.0)
}

/// Standard error of the global offset when nothing is named, in closed form from the noise
/// model of [`make_pair`]: the offset-only model's constant is the mean of the runs' residual
/// means (equal-length runs), and its delete-one-run jackknife SE estimates sigma_run /
/// sqrt(runs), where sigma_run^2 is the variance of one run's mean of `n` samples: white
/// noise sigma_w^2 / n plus, per flicker decade (a stationary AR(1) of variance q and
/// coefficient phi), q / n [(1 + phi) / (1 - phi) - 2 phi (1 - phi^n) / (n (1 - phi)^2)].
/// With 8 runs the jackknife variance has 7 degrees of freedom: an SE above twice this
/// happens by chance with probability about 2e-4 (chi^2_7 > 28).
fn offset_se_closed_form_dph(runs: usize, rate_hz: f64) -> f64 {
    let n = RUN_S * rate_hz;
    let ns = noise_scale();
    let white_sigma = ns * 60.0 * ARW_DEG_PER_SQRT_H * rate_hz.sqrt();
    let q = (ns * BIAS_INSTABILITY_DPH).powi(2) * std::f64::consts::LN_10 / std::f64::consts::PI;
    let flicker: f64 = [1.0, 10.0, 100.0, 1e3, 1e4, 1e5]
        .iter()
        .map(|tau: &f64| {
            let phi = (-1.0 / rate_hz / tau).exp();
            q / n * ((1.0 + phi) / (1.0 - phi) - 2.0 * phi * (1.0 - phi.powf(n)) / (n * (1.0 - phi).powi(2)))
        })
        .sum();
    ((white_sigma.powi(2) / n + flicker) / runs as f64).sqrt()
}

#[test]
fn structure_outside_the_catalogue_is_located_and_reported_unexplained() {
    // A bump 50 min after power-on in every run: no catalogue term has that shape. A
    // catalogue term may take a share of it (with this seed gradient_rate, 2 % held-out
    // improvement, its coil lag at the edge of the grid); what remains must be located and
    // reported as structure no catalogue effect explains.
    let d = run_diagnosis(&paper_runs(), Injected::TimeBump(0.02, 3000.0, 400.0), 2.0, 78);
    assert!(d.unexplained.structured, "{}", d.unexplained.statement);
    let table = d.unexplained.tables.iter().find(|t| t.table == "time since power-on").expect("time table");
    assert!(table.structured, "{table:?}");
    assert!(d.summary.contains("structure remains that no catalogue effect explains"), "{}", d.summary);
    // Located: the settled span (after 30 min) of most runs is significant.
    let settled = d.location.spans.iter().filter(|s| s.span == "settled" && s.significant).count();
    assert!(settled * 2 >= d.runs.len(), "{settled} significant settled spans of {}", d.runs.len());
}

#[test]
fn a_recording_equal_to_its_simulation_gets_a_report_without_an_allan_figure() {
    // The residual is exactly zero: nothing a log scale can draw. Writing the report failed
    // on the Allan figure before ("no Allan deviation points to plot"), leaving half a report.
    let (sim, _) = make_set(&paper_runs(), Injected::None, 2.0, 5);
    let d = diagnose(&sim, &sim, &DiagnoseOptions::default(), |_, _| {}).expect("diagnosis runs");
    assert!(d.left_out.is_empty(), "{}", d.summary);
    let dir = tempfile::tempdir().expect("temp dir");
    write_diagnosis_report(dir.path(), &d).expect("report written");
    let md = std::fs::read_to_string(dir.path().join("report.md")).expect("report.md");
    assert!(!dir.path().join("allan.svg").exists() && !md.contains("allan.svg"), "{md}");
    for file in ["residuals.svg", "map.svg", "report.html"] {
        assert!(dir.path().join(file).is_file(), "{file}");
    }
}

#[test]
fn thermal_lag_is_named_and_its_time_constant_recovered() {
    let d = run_diagnosis(&paper_runs(), Injected::ThermalLag, 2.0, 11);
    assert_eq!(names(&d), ["thermal_lag"]);
    assert_recovered(&d, "thermal_lag", "tau_s", TAU_COIL_S, 0.25);
    assert_recovered(&d, "thermal_lag", "gain", 1.0, 0.25);
    assert_helps(&d, "thermal_lag");
    assert_contract_json(&d);
    let dir = tempfile::tempdir().expect("temp dir");
    write_diagnosis_report(dir.path(), &d).expect("report written");
    let md = std::fs::read_to_string(dir.path().join("report.md")).expect("report.md");
    assert!(md.contains("### thermal_lag") && md.contains("bias stability = standard deviation"), "{md}");
    let html = std::fs::read_to_string(dir.path().join("report.html")).expect("report.html");
    assert!(html.contains("<h3>thermal_lag</h3>") && html.contains("bias stability = standard deviation"));
    for svg in ["residuals.svg", "map.svg", "allan.svg"] {
        let text = std::fs::read_to_string(dir.path().join(svg)).expect(svg);
        assert!(text.starts_with("<svg"), "{svg}");
        assert!(md.contains(&format!("]({svg})")), "{svg} linked");
    }
    // The page is self-contained: every figure inlined, no file linked.
    assert_eq!(html.matches("<svg").count(), 3, "three figures inlined");
    assert!(!html.contains(".svg\""), "no figure left as a link");
    // The static-shape figure only when static_shape is named.
    assert!(!dir.path().join("static_shape.svg").exists() && !md.contains("static_shape.svg"));
}

/// The CLI prints the diagnosis as JSON; the contract keys are there with the right types.
fn assert_contract_json(d: &Diagnosis) {
    let v = serde_json::to_value(d).expect("serialisable");
    let left_out = v["left_out"].as_array().expect("left_out array");
    assert_eq!(left_out.len(), d.left_out.len());
    for e in left_out {
        assert!(e["effect"].is_string());
        assert!(e["parameters"].is_object());
        for key in ["residual_before_dph", "residual_after_dph", "heldout_improvement"] {
            assert!(e[key].is_number(), "{key} in {e}");
        }
    }
    assert!(v["summary"].is_string());
}

#[test]
fn shupe_rate_is_named_and_its_coefficient_recovered() {
    let d = run_diagnosis(&paper_runs(), Injected::ShupeRate(0.03), 2.0, 12);
    assert_eq!(names(&d), ["shupe_rate"]);
    assert_recovered(&d, "shupe_rate", "coefficient_dph_per_c_per_min", 0.03, 0.25);
    assert_helps(&d, "shupe_rate");
}

/// A spike in one recorded sample (a corrupted row: +1000 deg/h) is read as missing with its
/// second and reported (review11 finding 1: one such sample turned a named effect into
/// "consistent with noise"). Oracle: the same data with that second's rows deleted, a gap the
/// diagnosis already reads as missing, gives the same diagnosis, number for number.
#[test]
fn a_spike_in_a_log_is_read_as_missing_and_named_with_its_run_and_time() {
    let (sim, clean) = make_set(&paper_runs(), Injected::ShupeRate(0.03), 2.0, 12);
    let (run, at) = (3, 2001);
    let second_s = clean[run].time_s[0] + (clean[run].time_s[at] - clean[run].time_s[0]).floor();
    let mut spiked = clean.clone();
    spiked[run].gyro_dph[at] += 1000.0;
    let mut gap = clean.clone();
    let keep: Vec<bool> = gap[run].time_s.iter().map(|&t| !(second_s..second_s + 1.0).contains(&t)).collect();
    let series = &mut gap[run];
    for column in [&mut series.time_s, &mut series.temp_c, &mut series.gyro_dph] {
        let mut k = keep.iter();
        column.retain(|_| *k.next().unwrap_or(&true));
    }
    assert_eq!(gap[run].time_s.len(), clean[run].time_s.len() - 2, "2 Hz: the second held two rows");
    let options = DiagnoseOptions::default();
    let with_spike = diagnose(&sim, &spiked, &options, |_, _| {}).expect("diagnosis runs");
    let with_gap = diagnose(&sim, &gap, &options, |_, _| {}).expect("diagnosis runs");
    assert_eq!(names(&with_spike), ["shupe_rate"], "{}", with_spike.summary);
    // The gap also takes that second's temperature rows, so the smoothed temperature differs
    // in the last digits: the same statements, parameters within 1e-6 relative.
    let statements = |d: &Diagnosis| d.left_out.iter().map(|e| e.statement.clone()).collect::<Vec<_>>();
    assert_eq!(statements(&with_spike), statements(&with_gap));
    for (a, b) in with_spike.left_out.iter().zip(&with_gap.left_out) {
        for (name, p) in &a.parameters {
            let q = b.parameters[name].value;
            assert!((p.value - q).abs() <= 1e-6 * q.abs().max(1e-9), "{name}: {} vs {q}", p.value);
        }
    }
    let (sigma_spike, sigma_gap) =
        (with_spike.noise.short_mean_sigma_dph, with_gap.noise.short_mean_sigma_dph);
    assert!((sigma_spike / sigma_gap - 1.0).abs() < 1e-6, "{sigma_spike} vs {sigma_gap}");
    assert!(with_gap.outliers.is_empty(), "{:?}", with_gap.outliers);
    assert_eq!(with_spike.outliers.len(), 1, "{:?}", with_spike.outliers);
    let o = &with_spike.outliers[0];
    assert_eq!((o.run.as_str(), o.seconds.len()), (clean[run].name.as_str(), 1));
    assert_eq!(o.seconds[0].log_time_s, second_s);
    // The second's mean holds half the spike (two rows at 2 Hz), less the minute's median.
    assert!((o.seconds[0].deviation_dph - 500.0).abs() < 1.0, "{:?}", o.seconds[0]);
    assert!(
        with_spike.summary.contains("1 second of the residual read as missing as outliers"),
        "{}",
        with_spike.summary
    );
    // The clean runs have no outlier at all.
    let clean_d = diagnose(&sim, &clean, &options, |_, _| {}).expect("diagnosis runs");
    assert!(clean_d.outliers.is_empty(), "{:?}", clean_d.outliers);
}

/// Simulated and recorded given the other way round (the noise-free simulation as the
/// recording): the summary says the recorded gyro is far quieter than the residual and asks
/// to check the order (review11 finding 8: the same verdict with flipped signs, and no
/// hint); in the right order it says nothing of the kind.
#[test]
fn swapped_sides_are_said_when_the_recording_is_the_quiet_one() {
    let (sim, rec) = make_set(&paper_runs(), Injected::None, 2.0, 77);
    let options = DiagnoseOptions::default();
    let swapped = diagnose(&rec, &sim, &options, |_, _| {}).expect("diagnosis runs");
    assert!(
        swapped.summary.contains("The recorded gyro is far quieter than the residual"),
        "{}",
        swapped.summary
    );
    assert!(swapped.summary.contains("check the order: --simulated first"), "{}", swapped.summary);
    let right = diagnose(&sim, &rec, &options, |_, _| {}).expect("diagnosis runs");
    assert!(!right.summary.contains("far quieter"), "{}", right.summary);
}

#[test]
fn warmup_transient_is_named_and_recovered() {
    let d = run_diagnosis(&paper_runs(), Injected::Warmup(0.012, 480.0), 2.0, 13);
    assert_eq!(names(&d), ["warmup_transient"]);
    assert_recovered(&d, "warmup_transient", "amplitude_dph", 0.012, 0.25);
    assert_recovered(&d, "warmup_transient", "tau_s", 480.0, 0.25);
    assert_helps(&d, "warmup_transient");
}

#[test]
fn orientation_offset_is_named_with_two_positions() {
    let d =
        run_diagnosis(&two_position_runs(EARTH_UP_DPH, -EARTH_UP_DPH), Injected::Orientation(0.010), 2.0, 14);
    assert_eq!(names(&d), ["orientation_offset"]);
    assert_recovered(&d, "orientation_offset", "offset_B_minus_A_dph", 0.010, 0.35);
    assert_helps(&d, "orientation_offset");
}

#[test]
fn hysteresis_is_named_from_chamber_cycling_runs() {
    let d = run_diagnosis(&cycling_runs(), Injected::Hysteresis(0.005), 2.0, 15);
    assert_eq!(names(&d), ["hysteresis"]);
    assert_recovered(&d, "hysteresis", "half_gap_dph", 0.005, 0.35);
    assert_helps(&d, "hysteresis");
}

#[test]
fn static_shape_is_named_for_a_ripple_in_temperature() {
    let d = run_diagnosis(&overlapping_runs(), Injected::StaticRipple(0.005, 35.0), 2.0, 16);
    assert_eq!(names(&d), ["static_shape"]);
    // The fitted shape (B-splines from the reported coefficients) follows the injected ripple
    // over the central 80 % of the temperature range: correlation > 0.7 after removing means.
    let (lo, hi) = (param(&d, "static_shape", "t_min_c").0, param(&d, "static_shape", "t_max_c").0);
    let k = param(&d, "static_shape", "basis_functions").0 as usize;
    let coef: Vec<f64> = (1..k).map(|j| param(&d, "static_shape", &format!("spline_{j}_dph")).0).collect();
    let (grid, fitted) = common::static_shape_on_central_grid(lo, hi, k, &coef);
    let truth: Vec<f64> = grid.iter().map(|t| 0.005 * (std::f64::consts::TAU * t / 35.0).sin()).collect();
    let r = common::correlation(&fitted, &truth);
    assert!(r > 0.7, "correlation of fitted and injected shape {r}");
    assert_helps(&d, "static_shape");
}

#[test]
fn static_shape_is_not_identifiable_when_run_temperatures_do_not_overlap() {
    // The paper's chamber temperatures are 10-15 C apart and self-heating is 10 C.
    let d = run_diagnosis(&paper_runs(), Injected::StaticRipple(0.005, 35.0), 2.0, 20);
    let c = d.selection[0].candidates.iter().find(|c| c.effect == "static_shape").expect("candidate");
    assert_eq!(c.status, "not_identifiable");
    assert!(c.note.contains("overlap"), "{}", c.note);
    assert!(!names(&d).contains(&"static_shape"));
}

#[test]
fn scale_factor_temperature_is_named_with_two_input_rates() {
    let d =
        run_diagnosis(&two_position_runs(EARTH_UP_DPH, -EARTH_UP_DPH), Injected::ScaleFactor(20.0), 2.0, 17);
    assert_eq!(names(&d), ["scale_factor_temperature"]);
    assert_recovered(&d, "scale_factor_temperature", "s1_ppm_per_c", 20.0, 0.35);
    assert_helps(&d, "scale_factor_temperature");
}

#[test]
fn scale_factor_with_one_input_rate_is_reported_not_identifiable() {
    let d =
        run_diagnosis(&two_position_runs(EARTH_UP_DPH, EARTH_UP_DPH), Injected::ScaleFactor(20.0), 2.0, 18);
    assert!(!names(&d).contains(&"scale_factor_temperature"));
    let c =
        d.selection[0].candidates.iter().find(|c| c.effect == "scale_factor_temperature").expect("candidate");
    assert_eq!(c.status, "not_identifiable");
    assert!(c.note.contains(">= 2 orientations"), "{}", c.note);
    // The structure is still found, as the static shape it is indistinguishable from.
    assert_eq!(names(&d), ["static_shape"]);
}

#[test]
fn hysteresis_is_not_identifiable_from_power_on_runs_alone() {
    let plans: Vec<RunPlan> = cycling_runs().into_iter().take(6).collect();
    let d = run_diagnosis(&plans, Injected::Hysteresis(0.005), 2.0, 19);
    let c = d.selection[0].candidates.iter().find(|c| c.effect == "hysteresis").expect("candidate");
    assert_eq!(c.status, "not_identifiable");
    assert!(c.experiment.as_deref().unwrap_or("").contains("two ramp rates"));
}

#[test]
fn bad_inputs_are_clear_errors() {
    let (sim, rec) = make_set(&paper_runs()[..2], Injected::None, 1.0, 5);
    let opts = DiagnoseOptions::default();
    let mut renamed = rec.clone();
    renamed[1].name = "other.csv".into();
    let e = diagnose(&sim, &renamed, &opts, |_, _| {}).unwrap_err();
    assert!(
        matches!(&e, DiagnoseError::Unpaired { recorded_only, simulated_only }
            if recorded_only == &["other.csv"] && simulated_only.len() == 1),
        "{e}"
    );
    assert!(e.to_string().contains("'other.csv'"), "{e}");
    let mut nan = rec.clone();
    nan[0].gyro_dph[10] = f64::NAN;
    let e = diagnose(&sim, &nan, &opts, |_, _| {}).unwrap_err();
    assert!(
        matches!(
            &e,
            DiagnoseError::BadSeries {
                side: Side::Recorded,
                problem: SeriesProblem::NonFinite { what: "gyro_dph", sample: 10 },
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("gyro_dph sample 10"), "{e}");
    let mut empty = rec.clone();
    empty[0].time_s.clear();
    empty[0].temp_c.clear();
    empty[0].gyro_dph.clear();
    let e = diagnose(&sim, &empty, &opts, |_, _| {}).unwrap_err();
    assert!(matches!(&e, DiagnoseError::BadSeries { problem: SeriesProblem::Empty, .. }), "{e}");
    // One run is located but nothing can be named (no held-out run): not an error.
    let one = diagnose(&sim[..1], &rec[..1], &opts, |_, _| {}).expect("one run is located");
    assert!(one.left_out.is_empty() && one.summary.starts_with("ONE PAIRED RUN"), "{}", one.summary);
    let e = diagnose(&[], &[], &opts, |_, _| {}).unwrap_err();
    assert!(matches!(e, DiagnoseError::NoRuns { simulated: 0, recorded: 0 }), "{e}");
    let mut backwards = rec.clone();
    backwards[0].time_s[5] = backwards[0].time_s[4];
    let e = diagnose(&sim, &backwards, &opts, |_, _| {}).unwrap_err();
    assert!(
        matches!(
            &e,
            DiagnoseError::BadSeries { problem: SeriesProblem::TimeNotIncreasing { sample: 5, .. }, .. }
        ),
        "{e}"
    );
    let bad_opts = DiagnoseOptions { mean_window_s: f64::NAN, ..DiagnoseOptions::default() };
    let e = diagnose(&sim, &rec, &bad_opts, |_, _| {}).unwrap_err();
    assert!(matches!(e, DiagnoseError::InvalidOption { option: "mean_window_s", .. }), "{e}");
    let mut twice = rec.clone();
    twice[1].name = twice[0].name.clone();
    let e = diagnose(&sim, &twice, &opts, |_, _| {}).unwrap_err();
    assert!(matches!(&e, DiagnoseError::DuplicateRun { side: Side::Recorded, .. }), "{e}");
}

/// Speed: 18 runs x 2 h at 10 Hz (run with `cargo test --release --test diagnose_lib -- --ignored --nocapture`).
#[test]
#[ignore]
fn speed_18_runs_2h_10hz() {
    let mut plans = paper_runs();
    plans.extend(paper_runs().into_iter().map(|mut p| {
        p.name = format!("b_{}", p.name);
        p
    }));
    plans.extend(cycling_runs().into_iter().take(2));
    let (sim, rec) = make_set(&plans, Injected::ShupeRate(0.03), 10.0, 99);
    let start = Instant::now();
    let d = diagnose(&sim, &rec, &DiagnoseOptions::default(), |_, _| {}).expect("diagnosis runs");
    let secs = start.elapsed().as_secs_f64();
    eprintln!("18 runs x 2 h x 10 Hz: diagnosis took {secs:.2} s; left out {:?}", names(&d));
    assert!(secs <= 30.0, "took {secs} s");
}

/// The permutation test's relabelled columns (`effects::orientation_columns` with permuted
/// labels) are exactly the catalogue's columns of runs that carry those labels (oracle:
/// `term_columns` on a copy of the prepared runs with their position and input rate moved).
#[test]
fn relabelled_orientation_columns_are_the_columns_of_relabelled_runs() {
    use fogtemp_diagnose::effects::{orientation_columns, run_labels, term_columns, Effect};
    let (sim, rec) = make_set(&two_position_runs(EARTH_UP_DPH, -EARTH_UP_DPH), Injected::None, 1.0, 21);
    let prep = fogtemp_diagnose::prepare::prepare(&sim, &rec, &DiagnoseOptions::default()).expect("prepared");
    // Run r takes the labels of run order[r]: a rotation by three moves runs across positions.
    let n = prep.runs.len();
    let order: Vec<usize> = (0..n).map(|r| (r + 3) % n).collect();
    let labels = run_labels(&prep);
    let permuted: Vec<_> = order.iter().map(|&r| labels[r]).collect();
    let mut relabelled = prep.clone();
    for (run, &from) in relabelled.runs.iter_mut().zip(&order) {
        run.group = prep.runs[from].group.clone();
        run.input_rate_dph = prep.runs[from].input_rate_dph;
    }
    for (effect, theta) in [(Effect::OrientationOffset, vec![]), (Effect::ScaleFactorTemperature, vec![2.0])]
    {
        let got = orientation_columns(&prep, effect, &theta, &permuted);
        let want = term_columns(&relabelled, effect, &theta);
        assert_eq!(got.coefficients, want.coefficients, "{effect:?}");
        assert_eq!(got.per_run, want.per_run, "{effect:?}");
        // And with the runs' own labels they are the catalogue's columns of the runs as recorded.
        assert_eq!(
            orientation_columns(&prep, effect, &theta, &labels).per_run,
            term_columns(&prep, effect, &theta).per_run
        );
        // The relabelling changed something (the test is not vacuous).
        assert_ne!(got.per_run, term_columns(&prep, effect, &theta).per_run, "{effect:?}");
    }
}

/// A 12 C ripple in b(T) that the current model cannot absorb makes that model fail the noise
/// model's innovation check, which closed the noise-model route to every candidate until the
/// candidates' own levels were used there (`noise_model_candidate_levels`, docs/diagnose.md,
/// thirteenth session). Named and followed in each of three seeds; with the fallback off, not
/// named in at least one (so the test exercises it). (At 0.008 deg/h neither names it.)
#[test]
fn a_ripple_that_fails_the_noise_check_is_named_at_the_candidates_levels() {
    let (amp, period) = (0.012, 12.0);
    let off = DiagnoseOptions { noise_model_candidate_levels: false, ..DiagnoseOptions::default() };
    let mut named_without = 0;
    for seed in 31..34 {
        let (sim, rec) = make_set(&overlapping_runs(), Injected::StaticRipple(amp, period), 1.0, seed);
        let d = diagnose(&sim, &rec, &DiagnoseOptions::default(), |_, _| {}).expect("diagnosis runs");
        assert_eq!(names(&d), ["static_shape"], "seed {seed}: {}", d.summary);
        let (lo, hi) = (param(&d, "static_shape", "t_min_c").0, param(&d, "static_shape", "t_max_c").0);
        let k = param(&d, "static_shape", "basis_functions").0 as usize;
        let coef: Vec<f64> =
            (1..k).map(|j| param(&d, "static_shape", &format!("spline_{j}_dph")).0).collect();
        let (grid, fitted) = common::static_shape_on_central_grid(lo, hi, k, &coef);
        let truth: Vec<f64> = grid.iter().map(|t| amp * (std::f64::consts::TAU * t / period).sin()).collect();
        let r = common::correlation(&fitted, &truth);
        eprintln!("seed {seed}: {k} functions, correlation {r}");
        assert!(r > 0.7, "seed {seed}: correlation of fitted and injected shape {r}");
        // The statement says which test accepted the term, as the selection step does.
        let selected = d
            .selection
            .iter()
            .flat_map(|s| &s.candidates)
            .find(|c| c.status == "selected" && c.effect == "static_shape")
            .expect("selection step of static_shape");
        let statement = &d.left_out[0].statement;
        assert_eq!(
            statement.contains("accepted by the noise-model GLS test"),
            selected.note.starts_with("passes the noise-model GLS test"),
            "seed {seed}: {statement} / {}",
            selected.note
        );
        eprintln!("seed {seed}: {statement} (profiled {:?})", selected.profile);
        if seed == 31 {
            // The report draws the named shape.
            let dir = tempfile::tempdir().expect("temp dir");
            write_diagnosis_report(dir.path(), &d).expect("report written");
            let md = std::fs::read_to_string(dir.path().join("report.md")).expect("report.md");
            assert!(md.contains("![static shape](static_shape.svg)"), "{md}");
            let svg = std::fs::read_to_string(dir.path().join("static_shape.svg")).expect("static_shape.svg");
            assert!(svg.starts_with("<svg") && svg.contains("fitted shape over the coil temperature"));
            let html = std::fs::read_to_string(dir.path().join("report.html")).expect("report.html");
            assert!(
                html.contains("fitted shape over the coil temperature"),
                "the shape inlined in report.html"
            );
        }
        let d_off = diagnose(&sim, &rec, &off, |_, _| {}).expect("diagnosis runs");
        named_without += usize::from(names(&d_off).contains(&"static_shape"));
    }
    assert!(named_without < 3, "the fallback decided nothing here");
}
