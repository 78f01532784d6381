//! Concealed-effect datasets generated with the project's simulator: the proving ground of
//! the diagnosis (`tests/diagnose_sim.rs`, `examples/diagnose_confusion.rs`,
//! `docs/diagnose.md`).
//!
//! Each dataset is a pair of scenarios: the engineer's simulation **without** one catalogue
//! effect and the "recording", the same scenario **with** it. Both are simulated with their
//! own noise seeds (never the same realisation: the residual would be noise-free). The
//! effect is concealed by the protocol or by another effect (see each dataset's
//! `concealment`), at a size comparable to the noise of the residual.
//!
//! Common to every design (the built-in `paper` scenario, `sim/paper.toml`): `b(T) = 0.005
//! (T - 20) + 2e-5 (T - 20)^2` deg/h on the coil, Shupe `S1 = 0.06` deg/h per C/min,
//! scale factor 5 ppm/C, coil lag 10 min behind a case-mounted sensor (1 min, 1 Hz, 0.0625 C
//! steps), self-heating 10 C, chamber ripple 0.2 C / 10 min, noise `N = 0.0005`
//! deg/sqrt(h), `B = 0.002` deg/h. Only the sample rate is lowered to 1 Hz (the diagnosis
//! works on 1 s means) and the runs are those of each design.
//!
//! Noise scale of the residual (recorded minus simulated, both noisy): the 100 s mean of
//! one gyro scatters by `sqrt((6 N)^2 + (1.17 B)^2) = 0.0038` deg/h (docs/physics.md section 5),
//! the difference of two by `0.0054` deg/h. Effect sizes below are stated against that
//! figure as the RMS of the injected contribution about its mean over all runs (what a
//! global offset cannot absorb), computed from the noise-free truth by [`effect_size`].

use std::collections::BTreeMap;

use super::effects::Effect;
use super::{RunMeta, RunSeries};
use fogtemp_sim::scenario::{ChamberProfile, Direction, InitialState, InputAxis, Node};
use fogtemp_sim::{simulate_in_memory, RunSpec, RunTruth, Sample, Scenario};

/// Sample rate of every dataset, Hz (the diagnosis grids everything onto 1 s means).
pub const RATE_HZ: f64 = 1.0;

/// Length of each run, s.
pub const RUN_S: f64 = 7200.0;

/// 100 s mean noise of the residual of two independent paper-noise gyros, deg/h
/// (`sqrt(2) * sqrt((6 N)^2 + (1.17 B)^2)`, N = 0.0005, B = 0.002).
pub const RESIDUAL_NOISE_100S_DPH: f64 = 0.0054;

/// A true value of a parameter the diagnosis reports, with how it is known.
#[derive(Clone, Debug, PartialEq)]
pub struct TrueParameter {
    /// Name as the diagnosis reports it (`tau_s`, `amplitude_dph`, ...).
    pub name: String,
    /// Value in the diagnosis's units.
    pub value: f64,
    /// Where it comes from (the scenario field, or how it was derived).
    pub source: String,
}

/// One dataset: simulation without the effect, recording with it.
#[derive(Clone, Debug)]
pub struct ConcealedDataset {
    /// Short label (`thermal_lag`, `null`, `scale_factor_one_orientation`, ...).
    pub label: String,
    /// The catalogue effect injected (`None` for the null dataset).
    pub injected: Option<Effect>,
    /// Whether the design is meant to identify the effect (false: concealed beyond
    /// recovery, the right answer is "not identifiable; run experiment X").
    pub identifiable: bool,
    /// What conceals the effect and what in the design reveals it.
    pub concealment: String,
    /// The effect's size and why.
    pub size: String,
    /// The engineer's simulation.
    pub simulated: Scenario,
    /// The "recording".
    pub recorded: Scenario,
    /// True values of the parameters the diagnosis reports for the injected effect.
    pub truth: Vec<TrueParameter>,
}

fn base() -> Scenario {
    let mut s = Scenario::paper().expect("the built-in paper scenario parses");
    s.sample_rate_hz = RATE_HZ;
    s.grid = None;
    s.runs = Vec::new();
    s
}

fn axis(d: Direction) -> InputAxis {
    InputAxis::Named(d)
}

/// A power-on run (soaked at the chamber temperature, powered at t = 0).
fn power_on(group: &str, temp_c: f64, input_axis: InputAxis) -> RunSpec {
    RunSpec {
        name: format!("{group}_on_{}C", fmt_temp(temp_c)),
        group: group.into(),
        duration_s: RUN_S,
        chamber: ChamberProfile::Constant { temp_c },
        input_axis,
        initial: InitialState::Soaked,
    }
}

/// A hot restart (warm at its powered steady state) with a chamber profile through `points`.
fn warm(name: &str, group: &str, points: Vec<[f64; 2]>, input_axis: InputAxis) -> RunSpec {
    let chamber = if points.len() == 1 {
        ChamberProfile::Constant { temp_c: points[0][1] }
    } else {
        ChamberProfile::Points { points }
    };
    RunSpec {
        name: name.into(),
        group: group.into(),
        duration_s: RUN_S,
        chamber,
        input_axis,
        initial: InitialState::Warm,
    }
}

fn fmt_temp(t: f64) -> String {
    if t < 0.0 {
        format!("m{}", -t)
    } else {
        format!("{t}")
    }
}

/// Six power-on runs over the paper's range, a hot restart with a chamber ramp up and down
/// at 0.25 C/min (dT/dt of both signs, not tied to the time since power-on) and a hot
/// restart at a constant chamber (power-on without thermal transient).
fn mixed_runs() -> Vec<RunSpec> {
    let mut runs: Vec<RunSpec> = [-40.0, -20.0, 0.0, 20.0, 40.0, 60.0]
        .iter()
        .map(|&t| power_on("pos1", t, axis(Direction::Up)))
        .collect();
    runs.push(warm(
        "pos1_warm_ramp_10C",
        "pos1",
        vec![[0.0, 10.0], [600.0, 10.0], [3600.0, 22.5], [6600.0, 10.0]],
        axis(Direction::Up),
    ));
    runs.push(warm("pos1_warm_30C", "pos1", vec![[0.0, 30.0]], axis(Direction::Up)));
    runs
}

/// The mixed runs plus two hot restarts with chamber ramps across most of the range at
/// 0.7 C/min, one heating (-30 -> 40 C) and one cooling (40 -> -30 C). A lag of b(T) gives
/// -b'(T) tau dT/dt there, which grows with T along the ramp (b' doubles from -30 to 40 C);
/// a Shupe term gives S1 dT/dt, constant along it. The mixed runs' 12.5 C ramp is too
/// narrow for that (b' changes by 10 % over it): the separating experiment of
/// [`Effect::ThermalLag`] / [`Effect::ShupeRate`] (docs/physics.md section 4 row 1).
fn wide_ramp_runs() -> Vec<RunSpec> {
    let mut runs = mixed_runs();
    for (name, from, to) in
        [("pos1_warm_ramp_up_m30C", -30.0, 40.0), ("pos1_warm_ramp_down_40C", 40.0, -30.0)]
    {
        runs.push(warm(name, "pos1", vec![[0.0, from], [600.0, from], [6600.0, to]], axis(Direction::Up)));
    }
    runs
}

/// The same six power-on runs only (the paper's protocol: dT/dt >= 0, tied to the time
/// since power-on).
fn power_on_runs() -> Vec<RunSpec> {
    [-40.0, -20.0, 0.0, 20.0, 40.0, 60.0].iter().map(|&t| power_on("pos1", t, axis(Direction::Up))).collect()
}

fn pair(label: &str, runs: Vec<RunSpec>, inject: impl Fn(&mut Scenario)) -> (Scenario, Scenario) {
    let mut sim = base();
    sim.name = format!("{label}-simulated");
    sim.runs = runs;
    let mut rec = sim.clone();
    rec.name = format!("{label}-recorded");
    inject(&mut rec);
    (sim, rec)
}

fn tp(name: &str, value: f64, source: &str) -> TrueParameter {
    TrueParameter { name: name.into(), value, source: source.into() }
}

/// Shupe coefficient missing from the simulation in the `shupe_rate` design, deg/h per C/min.
pub const SHUPE_DELTA: f64 = 0.03;
/// Warm-up amplitude and time constant of the `warmup_transient` design.
pub const WARMUP: (f64, f64) = (0.008, 1200.0);
/// Tilt of the second position's input axis in the recording, rad.
pub const TILT_RAD: f64 = 5e-4;
/// Hysteresis half-gap of the `hysteresis` design, deg/h.
pub const HYSTERESIS_DPH: f64 = 0.005;
/// Static ripple amplitude and period of the `static_shape` design (deg/h, deg C).
pub const RIPPLE: (f64, f64) = (0.005, 20.0);
/// Scale-factor temperature coefficient missing from the simulation, ppm/C.
pub const SCALE_FACTOR_DELTA: f64 = 15.0;
/// Gradient-rate coefficient S3 missing from the simulation, deg/h per (deg C/min).
pub const GRADIENT_RATE_S3: f64 = 0.15;

/// Every dataset at the stated sizes (`scale` 1): see [`datasets_at`].
pub fn datasets() -> Vec<ConcealedDataset> {
    datasets_at(1.0)
}

/// Every dataset: the null case, one identifiable design per catalogue effect, then the
/// designs concealed beyond recovery, with every injected size multiplied by `scale`
/// (except `thermal_lag`, whose size is the paper's b(T) and coil lag).
pub fn datasets_at(scale: f64) -> Vec<ConcealedDataset> {
    let mut out = Vec::new();
    let k = scale;
    let earth = 7.292_115e-5_f64.to_degrees() * 3600.0;
    let lat = 40f64.to_radians();

    let (simulated, recorded) = pair("null", mixed_runs(), |_| {});
    out.push(ConcealedDataset {
        label: "null".into(),
        injected: None,
        identifiable: true,
        concealment: "nothing is left out: recorded and simulated differ only in their noise (flicker makes slow wander that in-sample tests mistake for structure)".into(),
        size: "none".into(),
        simulated,
        recorded,
        truth: Vec::new(),
    });

    let (simulated, recorded) =
        pair("thermal_lag", wide_ramp_runs(), |s| s.bias.temperature_node = Node::Coil);
    let mut simulated = simulated;
    simulated.bias.temperature_node = Node::Sensor;
    out.push(ConcealedDataset {
        label: "thermal_lag".into(),
        injected: Some(Effect::ThermalLag),
        identifiable: true,
        concealment: "the simulation drives b(T) with the sensor temperature, the recording with the coil's (10 min behind the case): in power-on runs b(T_coil) - b(T_s) ~ -b'(T) tau dT/dt looks like a Shupe term; the chamber ramps (both signs of dT/dt, not tied to power-on) and, on the two wide ramps, an offset that grows with b'(T) along the ramp (a Shupe term's does not) reveal it".into(),
        size: "fixed by the paper's physics (b' = 0.005 deg/h/C, lag ~10 min): b' tau dT/dt is 0.01-0.03 deg/h at the start of a power-on run, 0.011 deg/h on the 0.25 C/min ramp and 0.02-0.04 deg/h on the 0.7 C/min wide ramps".into(),
        simulated,
        recorded,
        truth: vec![tp("gain", 1.0, "the recording's b(T) is the simulation's on the coil temperature")],
    });

    let (mut simulated, recorded) = pair("shupe_rate", wide_ramp_runs(), |_| {});
    simulated.bias.shupe_dph_per_c_per_min -= k * SHUPE_DELTA;
    out.push(ConcealedDataset {
        label: "shupe_rate".into(),
        injected: Some(Effect::ShupeRate),
        identifiable: true,
        concealment: "the simulation's S1 is 0.03 instead of 0.06 deg/h per C/min: in power-on runs dS1 dT/dt decays with the time since power-on like a warm-up transient; the ramps (dT/dt of both signs) and the hot restart (no dT/dt at power-on) separate them, and the wide ramps separate it from a lag of b(T)".into(),
        size: "dS1 = 0.03 deg/h per C/min: 0.009 deg/h at the 0.3 C/min peak coil rate of a power-on, 0.0075 deg/h on the ramp".into(),
        simulated,
        recorded,
        truth: vec![tp(
            "coefficient_dph_per_c_per_min",
            k * SHUPE_DELTA,
            "bias.shupe_dph_per_c_per_min recorded minus simulated (on the coil's rate)",
        )],
    });

    let (simulated, recorded) = pair("gradient_rate", mixed_runs(), |s| {
        s.bias.gradient_rate_dph_per_c_per_min = k * GRADIENT_RATE_S3;
    });
    out.push(ConcealedDataset {
        label: "gradient_rate".into(),
        injected: Some(Effect::GradientRate),
        identifiable: true,
        concealment: "S3 d(dT_r)/dt with dT_r ~ tau_r dT/dt: in power-on runs it is a decay after power-on (Shupe- and warm-up-like); at the ramp's corners d2T/dt2 changes sign independently of dT/dt".into(),
        size: "S3 = 0.15 deg/h per C/min (tau_r = 2 min): about 0.005 deg/h right after power-on and at the ramp's corners".into(),
        simulated,
        recorded,
        truth: Vec::new(),
    });

    let (simulated, recorded) = pair("warmup_transient", mixed_runs(), |s| {
        s.bias.warmup_amplitude_dph = k * WARMUP.0;
        s.bias.warmup_time_constant_s = WARMUP.1;
    });
    out.push(ConcealedDataset {
        label: "warmup_transient".into(),
        injected: Some(Effect::WarmupTransient),
        identifiable: true,
        concealment: "A exp(-t/tau_w) with tau_w = 20 min, close to the case's thermal time constant (22.5 min): in power-on runs it decays like dT/dt (Shupe-like); the two hot restarts show it without any dT/dt".into(),
        size: "A = 0.008 deg/h".into(),
        simulated,
        recorded,
        truth: vec![
            tp("amplitude_dph", k * WARMUP.0, "bias.warmup_amplitude_dph"),
            tp("tau_s", WARMUP.1, "bias.warmup_time_constant_s"),
        ],
    });

    let two_positions = |temps: &[f64]| -> Vec<RunSpec> {
        let mut runs: Vec<RunSpec> =
            temps.iter().map(|&t| power_on("pos1", t, axis(Direction::Up))).collect();
        runs.extend(temps.iter().map(|&t| power_on("pos2", t, axis(Direction::Down))));
        runs
    };
    let tilt = k * TILT_RAD;
    let tilted = InputAxis::Ned([tilt.sin(), 0.0, tilt.cos()]);
    let tilt_offset = earth * (lat.cos() * tilt.sin() - lat.sin() * tilt.cos()) + earth * lat.sin();
    let (simulated, recorded) = pair("orientation_offset", two_positions(&[-30.0, 0.0, 30.0, 60.0]), |s| {
        for r in &mut s.runs {
            if r.group == "pos2" {
                r.input_axis = tilted.clone();
            }
        }
    });
    out.push(ConcealedDataset {
        label: "orientation_offset".into(),
        injected: Some(Effect::OrientationOffset),
        identifiable: true,
        concealment: "the second position's input axis is tilted 0.5 mrad towards north in the recording, but the test plan (and the simulation) says 'down': a constant per position that a per-position calibration absorbs in each group's mean; four power-ons per position at the same temperatures separate it from turn-on scatter and from b(T)".into(),
        size: format!("Omega_E cos(lat) x 0.5 mrad = {tilt_offset:.4} deg/h: 1 mrad is the whole budget (docs/physics.md section 1)"),
        simulated,
        recorded,
        truth: vec![tp("offset_pos2_minus_pos1_dph", tilt_offset, "Earth rate on the tilted axis minus on 'down'")],
    });

    let mut cycling = power_on_runs();
    cycling.push(warm(
        "pos1_cycle_fast_0C",
        "pos1",
        vec![[0.0, 0.0], [600.0, 0.0], [1800.0, 8.0], [4200.0, -8.0], [6600.0, 8.0]],
        axis(Direction::Up),
    ));
    cycling.push(warm(
        "pos1_cycle_slow_30C",
        "pos1",
        vec![[0.0, 30.0], [600.0, 30.0], [3600.0, 38.0], [7200.0, 28.4]],
        axis(Direction::Up),
    ));
    let (simulated, recorded) = pair("hysteresis", cycling, |s| s.bias.hysteresis_dph = k * HYSTERESIS_DPH);
    out.push(ConcealedDataset {
        label: "hysteresis".into(),
        injected: Some(Effect::Hysteresis),
        identifiable: true,
        concealment: "h tanh(dT_coil/dt / 0.01 C/min): power-on runs only heat, so there it is a constant (the global offset) that fades late in the run (warm-up-like); only the two chamber-cycling runs (0.4 and 0.16 C/min) show the branches".into(),
        size: "h = 0.005 deg/h".into(),
        simulated,
        recorded,
        truth: vec![tp("half_gap_dph", k * HYSTERESIS_DPH, "bias.hysteresis_dph")],
    });

    let mut overlap: Vec<RunSpec> =
        (0..8).map(|i| power_on("pos1", -10.0 + 6.0 * f64::from(i), axis(Direction::Up))).collect();
    overlap.push(warm(
        "pos1_warm_ramp_5C",
        "pos1",
        vec![[0.0, 5.0], [600.0, 5.0], [6600.0, 30.0]],
        axis(Direction::Up),
    ));
    let (simulated, recorded) = pair("static_shape", overlap, |s| {
        s.bias.static_ripple_dph = k * RIPPLE.0;
        s.bias.static_ripple_period_c = RIPPLE.1;
    });
    out.push(ConcealedDataset {
        label: "static_shape".into(),
        injected: Some(Effect::StaticShape),
        identifiable: true,
        concealment: "a 20 C-period ripple in b(T) (polarisation non-reciprocity): within one power-on run it is a drift that per-run offsets and the warm-up absorb; eight power-ons 6 C apart (ranges overlap with 10 C of self-heating) and a slow chamber ramp over 5-30 C show the same shape in T across runs".into(),
        size: "0.005 deg/h amplitude".into(),
        simulated,
        recorded,
        truth: vec![tp("peak_to_peak_dph", 2.0 * k * RIPPLE.0, "2 x bias.static_ripple_dph (the runs cover more than one 20 C period)")],
    });

    let (mut simulated, recorded) =
        pair("scale_factor_temperature", two_positions(&[-35.0, -5.0, 25.0, 55.0]), |_| {});
    simulated.bias.scale_factor_ppm_per_c -= k * SCALE_FACTOR_DELTA;
    out.push(ConcealedDataset {
        label: "scale_factor_temperature".into(),
        injected: Some(Effect::ScaleFactorTemperature),
        identifiable: true,
        concealment: "the simulation's scale-factor TC is 15 ppm/C too small: in one orientation Omega_in s1 (T - 20) is exactly a static slope in b(T); input axis up and down (+-9.67 deg/h) over the same temperatures flip its sign".into(),
        size: "9.67 deg/h x 15 ppm/C x +-40 C = +-0.006 deg/h".into(),
        simulated,
        recorded,
        truth: vec![tp("s1_ppm_per_c", k * SCALE_FACTOR_DELTA, "bias.scale_factor_ppm_per_c recorded minus simulated")],
    });

    // Concealed beyond recovery.
    let (mut simulated, recorded) = pair("scale_factor_one_orientation", power_on_runs(), |_| {});
    simulated.bias.scale_factor_ppm_per_c -= k * SCALE_FACTOR_DELTA;
    out.push(ConcealedDataset {
        label: "scale_factor_one_orientation".into(),
        injected: Some(Effect::ScaleFactorTemperature),
        identifiable: false,
        concealment: "as scale_factor_temperature, but every run has the input axis up: Omega_in s1 (T - 20) is exactly a slope in b(T); the right answer is 'not identifiable; run two orientations'".into(),
        size: "9.67 deg/h x 15 ppm/C: 0.00015 deg/h per C, 0.015 deg/h over the 100 C range".into(),
        simulated,
        recorded,
        truth: Vec::new(),
    });

    let (simulated, recorded) =
        pair("hysteresis_power_on_only", power_on_runs(), |s| s.bias.hysteresis_dph = k * HYSTERESIS_DPH);
    out.push(ConcealedDataset {
        label: "hysteresis_power_on_only".into(),
        injected: Some(Effect::Hysteresis),
        identifiable: false,
        concealment: "as hysteresis, without the cycling runs: power-on data never cool, so the branches cannot be compared; the right answer is 'not identifiable; run chamber cycling at two ramp rates'".into(),
        size: "h = 0.005 deg/h".into(),
        simulated,
        recorded,
        truth: Vec::new(),
    });
    if scale != 1.0 {
        for d in out.iter_mut().filter(|d| d.injected.is_some_and(|e| e != Effect::ThermalLag)) {
            d.size = format!("{scale} x the stated design: {}", d.size);
        }
    }
    out
}

/// Seeds of the simulated and recorded noise for repetition `seed` (always different).
pub fn seeds(seed: u64) -> (u64, u64) {
    (1_000_003 * seed + 17, 1_000_003 * seed + 29)
}

/// A simulated run as the diagnosis's input; `meta_from` is the simulation's truth of the
/// same run (the test plan: group and the input rate the engineer believes in).
pub fn to_series(truth: &RunTruth, samples: &[Sample], meta_from: &RunTruth) -> RunSeries {
    RunSeries {
        name: truth.spec.name.clone(),
        time_s: samples.iter().map(|s| s.time_s).collect(),
        temp_c: samples.iter().map(|s| s.temp_c).collect(),
        gyro_dph: samples.iter().map(|s| s.gyro_dph).collect(),
        meta: RunMeta {
            group: Some(meta_from.spec.group.clone()),
            input_rate_dph: Some(meta_from.input_rate_dph),
            power_on_at_s: None,
        },
    }
}

/// Generated pair of a dataset at repetition `seed`: (simulated, recorded) runs and the
/// truths of both (simulated first).
pub struct Generated {
    /// Simulated runs.
    pub simulated: Vec<RunSeries>,
    /// Recorded runs.
    pub recorded: Vec<RunSeries>,
    /// Truth of the simulated runs.
    pub simulated_truth: Vec<RunTruth>,
    /// Truth of the recorded runs.
    pub recorded_truth: Vec<RunTruth>,
}

/// Simulates both members of `dataset` with the seeds of repetition `seed`.
pub fn generate(dataset: &ConcealedDataset, seed: u64) -> Generated {
    let (s_seed, r_seed) = seeds(seed);
    let mut sim = dataset.simulated.clone();
    sim.seed = s_seed;
    let mut rec = dataset.recorded.clone();
    rec.seed = r_seed;
    let (sim_out, rec_out) = rayon::join(|| simulate_in_memory(&sim), || simulate_in_memory(&rec));
    let simulated = sim_out.iter().map(|(t, s)| to_series(t, s, t)).collect();
    let recorded = rec_out.iter().zip(&sim_out).map(|((t, s), (st, _))| to_series(t, s, st)).collect();
    Generated {
        simulated,
        recorded,
        simulated_truth: sim_out.into_iter().map(|(t, _)| t).collect(),
        recorded_truth: rec_out.into_iter().map(|(t, _)| t).collect(),
    }
}

/// Size of the injected effect from the noise-free truths: `(rms, peak)` of recorded minus
/// simulated deterministic output over all runs' 1 s grids, about its overall mean, deg/h.
pub fn effect_size(simulated: &[RunTruth], recorded: &[RunTruth]) -> (f64, f64) {
    let diffs: Vec<f64> = simulated
        .iter()
        .zip(recorded)
        .flat_map(|(s, r)| s.points.iter().zip(&r.points).map(|(a, b)| b.output_dph - a.output_dph))
        .collect();
    let n = diffs.len().max(1) as f64;
    let mean = diffs.iter().sum::<f64>() / n;
    let rms = (diffs.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n).sqrt();
    let peak = diffs.iter().map(|d| (d - mean).abs()).fold(0.0, f64::max);
    (rms, peak)
}

/// The effective first-order lag from the logged sensor's true temperature to the coil's,
/// fitted over the recorded runs' truth (least squares on a log grid, then a parabola), s.
pub fn coil_lag_s(recorded: &[RunTruth]) -> f64 {
    let sse = |tau: f64| -> f64 {
        recorded
            .iter()
            .map(|r| {
                let sensor: Vec<f64> = r.points.iter().map(|p| p.sensor_c).collect();
                let lagged = super::effects::low_pass(&sensor, tau);
                r.points.iter().zip(&lagged).map(|(p, l)| (p.coil_c - l).powi(2)).sum::<f64>()
            })
            .sum()
    };
    let grid: Vec<f64> = (0..=60).map(|i| 60.0 * 1.05f64.powi(i)).collect();
    let values: Vec<f64> = grid.iter().map(|&t| sse(t)).collect();
    let best = (0..grid.len()).min_by(|&a, &b| values[a].total_cmp(&values[b])).unwrap_or(0);
    if best == 0 || best + 1 == grid.len() {
        return grid[best];
    }
    let point = |j: usize| (grid[j].ln(), values[j]);
    super::linalg::parabola_vertex([point(best - 1), point(best), point(best + 1)])
        .map_or(grid[best], f64::exp)
}

/// The coefficient of the `gradient_rate` term that best maps the true injected
/// contribution (recorded minus simulated noise-free output) onto the term built, as the
/// diagnosis builds it, from the true sensor temperature with the coil lag `tau_s`:
/// `d2 LPF_tau(T_s)/dt2` in deg C/min^2 (least squares with an intercept over all runs).
/// The simulator's radial gradient is not exactly a first-order lag of the coil's rate, so
/// this is the term's best value, not S3 times a time constant.
pub fn gradient_coefficient(simulated: &[RunTruth], recorded: &[RunTruth], tau_s: f64) -> f64 {
    let (mut xs, mut vs) = (Vec::new(), Vec::new());
    for (sim, rec) in simulated.iter().zip(recorded) {
        let sensor: Vec<f64> = rec.points.iter().map(|p| p.sensor_c).collect();
        let lagged = super::effects::low_pass(&sensor, tau_s);
        let n = sensor.len();
        for i in 1..n.saturating_sub(1) {
            let dt_min = (rec.points[i + 1].time_s - rec.points[i - 1].time_s) / 60.0;
            let rate_c_per_min = (sensor[i + 1] - sensor[i - 1]) / dt_min;
            xs.push(super::effects::lagged_accel_c_per_min2(sensor[i], lagged[i], rate_c_per_min, tau_s));
            vs.push(rec.points[i].output_dph - sim.points[i].output_dph);
        }
    }
    let n = xs.len().max(1) as f64;
    let (mx, mv) = (xs.iter().sum::<f64>() / n, vs.iter().sum::<f64>() / n);
    let sxv: f64 = xs.iter().zip(&vs).map(|(x, v)| (x - mx) * (v - mv)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    if sxx > 0.0 {
        sxv / sxx
    } else {
        f64::NAN
    }
}

/// The datasets' true parameters as a map (label -> parameter -> value), with the coil lag
/// of the `thermal_lag` design derived from its truth.
pub fn truth_map(dataset: &ConcealedDataset, generated: &Generated) -> BTreeMap<String, f64> {
    let mut m: BTreeMap<String, f64> = dataset.truth.iter().map(|t| (t.name.clone(), t.value)).collect();
    if dataset.identifiable && dataset.injected == Some(Effect::ThermalLag) {
        m.insert("tau_s".into(), coil_lag_s(&generated.recorded_truth));
    }
    if dataset.identifiable && matches!(dataset.injected, Some(Effect::ShupeRate | Effect::GradientRate)) {
        m.insert("coil_lag_s".into(), coil_lag_s(&generated.recorded_truth));
    }
    if dataset.identifiable && dataset.injected == Some(Effect::GradientRate) {
        let tau_s = coil_lag_s(&generated.recorded_truth);
        let c = gradient_coefficient(&generated.simulated_truth, &generated.recorded_truth, tau_s);
        m.insert("coefficient_dph_per_c_per_min2".into(), c);
    }
    m
}
