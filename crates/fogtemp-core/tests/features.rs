//! Feature tracker tests: smoothed temperature and its rate (deg C/min) against an
//! independent f64 reference written from the method's description (block means, the
//! least-squares line through the window's present block means at block-centre positions,
//! T at the end of the newest block), exact ramps, a quantised sensor, readiness, gaps and
//! rejected samples.
#![allow(clippy::expect_used, clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use std::collections::BTreeMap;

use fogtemp_core::{Error, FeatureSettings, FeatureTracker, Features, PushOutcome, DEFAULT_CAPACITY};
use proptest::prelude::*;
use rand::Rng;

use common::FEATURES;

type Tracker = FeatureTracker<DEFAULT_CAPACITY>;

const EPS32: f64 = f32::EPSILON as f64;

/// Tolerance of the f32 tracker against the f64 reference, in units of
/// `f32::EPSILON * scale * gain` (see [`RefFeatures`]): what every block mean being off by
/// one f32 epsilon of the temperature scale would do to the feature. Each mean carries
/// about one such rounding (the deviation sum, the division, adding back the block's
/// first sample: each half an ulp or less) and the f32 fit adds about one more; 2 units
/// allow for that. The largest errors seen over all random trajectories are 0.54 units
/// (temperature) and 0.14 units (rate), printed by the test.
const F32_ROUNDING_UNITS: f64 = 2.0;

// ---------------------------------------------------------------------------------------
// The f64 reference
// ---------------------------------------------------------------------------------------

/// Written from the description, not from `features.rs`: samples are grouped by block
/// index `(t - t_start) / block_us`, counted from the first sample after a (re)start;
/// the closed blocks are those before the newest sample's block; the window is the last
/// `block_count` closed blocks; the fit uses the blocks holding data, at their centres.
#[derive(Clone, Debug)]
struct Reference {
    block_us: u64,
    block_count: u64,
    min_blocks: usize,
    max_gap_us: u64,
    start_us: Option<u64>,
    last_us: Option<u64>,
    /// Block index since the (re)start -> (sum of samples, sample count).
    blocks: BTreeMap<u64, (f64, u32)>,
}

/// Reference features plus what the rounding tolerance needs.
#[derive(Clone, Copy, Debug)]
struct RefFeatures {
    time_us: u64,
    temp_c: f64,
    rate_c_per_min: f64,
    blocks_used: u32,
    window_full: bool,
    /// Both features are linear in the block means: `temp = sum c_i m_i`,
    /// `rate = sum w_i m_i`. These are `sum |c_i|` and `sum |w_i|`, the most an error of
    /// one unit in every mean can move each feature.
    temp_gain: f64,
    rate_gain: f64,
    /// Largest |block mean| in the window plus 1 C (the within-block deviations the
    /// tracker sums in f32 are below 1 C here, so temperatures near 0 C keep room for them).
    scale_c: f64,
}

impl RefFeatures {
    fn temp_tol(&self, units: f64) -> f64 {
        units * EPS32 * self.scale_c * self.temp_gain
    }

    fn rate_tol(&self, units: f64) -> f64 {
        units * EPS32 * self.scale_c * self.rate_gain
    }
}

impl Reference {
    fn new(s: &FeatureSettings) -> Self {
        Self {
            block_us: (f64::from(s.window_s) * 1.0e6 / f64::from(s.block_count)).round() as u64,
            block_count: u64::from(s.block_count),
            min_blocks: s.min_blocks as usize,
            max_gap_us: (f64::from(s.max_gap_s) * 1.0e6).round() as u64,
            start_us: None,
            last_us: None,
            blocks: BTreeMap::new(),
        }
    }

    /// Adds a valid sample; true when the silence before it restarted the reference.
    fn push(&mut self, time_us: u64, temp_c: f32) -> bool {
        let restarted = self.last_us.is_some_and(|last| time_us - last > self.max_gap_us);
        if restarted {
            self.start_us = None;
            self.blocks.clear();
        }
        let start = *self.start_us.get_or_insert(time_us);
        let block = self.blocks.entry((time_us - start) / self.block_us).or_insert((0.0, 0));
        block.0 += f64::from(temp_c);
        block.1 += 1;
        self.last_us = Some(time_us);
        restarted
    }

    /// Blocks closed since the (re)start: those before the newest sample's block.
    fn closed_blocks(&self) -> u64 {
        match (self.start_us, self.last_us) {
            (Some(start), Some(last)) => (last - start) / self.block_us,
            _ => 0,
        }
    }

    fn features(&self) -> Option<RefFeatures> {
        let start = self.start_us?;
        let closed = self.closed_blocks();
        let first = closed.saturating_sub(self.block_count);
        let points: Vec<(f64, f64)> = self
            .blocks
            .range(first..closed)
            .map(|(&k, &(sum, n))| (k as f64 + 0.5, sum / f64::from(n)))
            .collect();
        if points.len() < self.min_blocks {
            return None;
        }
        let n = points.len() as f64;
        let mean_x = points.iter().map(|p| p.0).sum::<f64>() / n;
        let mean_y = points.iter().map(|p| p.1).sum::<f64>() / n;
        let sxx: f64 = points.iter().map(|p| (p.0 - mean_x).powi(2)).sum();
        let sxy: f64 = points.iter().map(|p| (p.0 - mean_x) * (p.1 - mean_y)).sum();
        let slope_c_per_block = sxy / sxx;
        let end_x = closed as f64; // end of the newest closed block, in blocks since start
        let block_min = self.block_us as f64 / 60.0e6;
        let weight = |x: f64| (x - mean_x) / sxx;
        Some(RefFeatures {
            time_us: start + closed * self.block_us,
            temp_c: mean_y + slope_c_per_block * (end_x - mean_x),
            rate_c_per_min: slope_c_per_block / block_min,
            blocks_used: points.len() as u32,
            window_full: closed >= self.block_count,
            temp_gain: points.iter().map(|p| (1.0 / n + weight(p.0) * (end_x - mean_x)).abs()).sum(),
            rate_gain: points.iter().map(|p| weight(p.0).abs()).sum::<f64>() / block_min,
            scale_c: points.iter().map(|p| p.1.abs()).fold(0.0, f64::max) + 1.0,
        })
    }
}

/// Largest error of the tracker against the reference, in [`F32_ROUNDING_UNITS`] units.
#[derive(Default, Debug)]
struct WorstRatio {
    temp: f64,
    rate: f64,
    updates: usize,
}

/// Asserts the tracker's features equal the reference's: counts and times exactly, the
/// floats within `units` f32 roundings. Returns the error ratios (error / one unit).
fn assert_matches(got: Option<Features>, want: Option<RefFeatures>, units: f64, context: &str) -> (f64, f64) {
    match (got, want) {
        (None, None) => (0.0, 0.0),
        (Some(g), Some(w)) => {
            assert_eq!(g.time_us, w.time_us, "{context}: time_us");
            assert_eq!(g.blocks_used, w.blocks_used, "{context}: blocks_used");
            assert_eq!(g.window_full, w.window_full, "{context}: window_full");
            let temp_err = (f64::from(g.temp_c) - w.temp_c).abs();
            let rate_err = (f64::from(g.rate_c_per_min) - w.rate_c_per_min).abs();
            assert!(
                temp_err <= w.temp_tol(units),
                "{context}: temp {} vs reference {} (err {temp_err:e}, tol {:e})",
                g.temp_c,
                w.temp_c,
                w.temp_tol(units)
            );
            assert!(
                rate_err <= w.rate_tol(units),
                "{context}: rate {} vs reference {} (err {rate_err:e}, tol {:e})",
                g.rate_c_per_min,
                w.rate_c_per_min,
                w.rate_tol(units)
            );
            (temp_err / w.temp_tol(1.0), rate_err / w.rate_tol(1.0))
        }
        (g, w) => panic!("{context}: tracker {g:?} but reference {w:?}"),
    }
}

/// Pushes `(time_us, temp_c)` into a tracker and the reference, checking the tracker
/// against the reference after every update and that features change only on updates.
fn run_against_reference(settings: &FeatureSettings, samples: &[(u64, f32)], context: &str) -> WorstRatio {
    let mut tracker = Tracker::new(settings).expect("settings fit the default capacity");
    let mut reference = Reference::new(settings);
    let mut worst = WorstRatio::default();
    for (i, &(time_us, temp_c)) in samples.iter().enumerate() {
        let before = tracker.features();
        let outcome = tracker.push(time_us, temp_c).expect("valid sample");
        let restarted = reference.push(time_us, temp_c);
        assert_eq!(outcome.restarted, restarted, "{context}: sample {i} restart");
        if outcome.updated {
            worst.updates += 1;
            let (t, r) = assert_matches(
                tracker.features(),
                reference.features(),
                F32_ROUNDING_UNITS,
                &format!("{context}, sample {i} at {time_us} us"),
            );
            worst.temp = worst.temp.max(t);
            worst.rate = worst.rate.max(r);
        } else {
            assert_eq!(tracker.features(), before, "{context}: features changed without an update");
        }
    }
    worst
}

// ---------------------------------------------------------------------------------------
// Signals
// ---------------------------------------------------------------------------------------

/// Standard normal (Box-Muller), so the tests need no extra distribution crate.
fn gaussian(r: &mut impl Rng) -> f64 {
    let u1: f64 = r.gen_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = r.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Regular sample times: `count` samples every `period_us` from `start_us`.
fn regular_times(start_us: u64, period_us: u64, count: usize) -> impl Iterator<Item = u64> {
    (0..count as u64).map(move |i| start_us + i * period_us)
}

/// A 0.0625 C quantiser, as 12-bit digital temperature sensors have.
fn quantise(temp_c: f64) -> f64 {
    const STEP_C: f64 = 0.0625;
    (temp_c / STEP_C).round() * STEP_C
}

/// Warm-up exponential plus a sinusoid, deg C at `t_s` seconds.
#[derive(Clone, Copy, Debug)]
struct Smooth {
    start_c: f64,
    heat_c: f64,
    tau_s: f64,
    amplitude_c: f64,
    period_s: f64,
    phase: f64,
}

impl Smooth {
    fn random(r: &mut impl Rng) -> Self {
        Self {
            start_c: r.gen_range(-40.0..60.0),
            heat_c: r.gen_range(0.0..20.0),
            tau_s: r.gen_range(300.0..2400.0),
            amplitude_c: r.gen_range(0.0..2.0),
            period_s: r.gen_range(120.0..1800.0),
            phase: r.gen_range(0.0..std::f64::consts::TAU),
        }
    }

    fn temp_c(&self, t_s: f64) -> f64 {
        self.start_c
            + self.heat_c * (1.0 - (-t_s / self.tau_s).exp())
            + self.amplitude_c * (std::f64::consts::TAU * t_s / self.period_s + self.phase).sin()
    }
}

// ---------------------------------------------------------------------------------------
// Exact signals
// ---------------------------------------------------------------------------------------

/// A 0.5 C/min ramp sampled every `period_us`: once ready, the rate is the ramp's and T is
/// the ramp half a sample period before the newest block's end (a block mean of samples
/// taken at `start, start + dt, ...` is the ramp at the block centre minus `dt / 2`: each
/// sample stands for the interval after it). Tolerance: the f32 rounding of the inputs
/// and of the tracker's arithmetic, [`F32_ROUNDING_UNITS`] roundings of the temperature
/// scale through the fit's gains: about 1e-5 C for T; 1e-4 C/min for the rate of a
/// 10-block partial window, 1e-5 C/min once the window is full.
fn check_ramp(period_us: u64, duration_s: u64) {
    const RATE_C_PER_MIN: f64 = 0.5;
    let start_us = 3_000_017;
    let ramp = |time_us: f64| 20.0 + RATE_C_PER_MIN * (time_us - start_us as f64) / 60.0e6;
    let count = (duration_s * 1_000_000 / period_us) as usize;
    let samples: Vec<(u64, f32)> =
        regular_times(start_us, period_us, count).map(|t| (t, ramp(t as f64) as f32)).collect();
    let mut tracker = Tracker::new(&FEATURES).expect("fits");
    let mut reference = Reference::new(&FEATURES);
    let mut ready_updates = 0;
    for &(time_us, temp_c) in &samples {
        let outcome = tracker.push(time_us, temp_c).expect("valid");
        reference.push(time_us, temp_c);
        let (Some(f), Some(r)) = (tracker.features(), reference.features()) else {
            assert_eq!(tracker.features().is_some(), reference.features().is_some());
            continue;
        };
        if !outcome.updated {
            continue;
        }
        ready_updates += 1;
        let exact_temp_c = ramp(f.time_us as f64 - period_us as f64 / 2.0);
        // The oracle itself: exact up to the f32 rounding of its inputs (one unit).
        assert!((r.temp_c - exact_temp_c).abs() <= r.temp_tol(1.0), "reference temp at {time_us}");
        assert!((r.rate_c_per_min - RATE_C_PER_MIN).abs() <= r.rate_tol(1.0), "reference rate at {time_us}");
        let (temp_err, rate_err) = (
            (f64::from(f.temp_c) - exact_temp_c).abs(),
            (f64::from(f.rate_c_per_min) - RATE_C_PER_MIN).abs(),
        );
        assert!(
            temp_err <= r.temp_tol(F32_ROUNDING_UNITS),
            "temp {} vs ramp {exact_temp_c} at {time_us} us (err {temp_err:e}, tol {:e})",
            f.temp_c,
            r.temp_tol(F32_ROUNDING_UNITS)
        );
        assert!(
            rate_err <= r.rate_tol(F32_ROUNDING_UNITS),
            "rate {} vs 0.5 C/min at {time_us} us (err {rate_err:e}, tol {:e})",
            f.rate_c_per_min,
            r.rate_tol(F32_ROUNDING_UNITS)
        );
    }
    // Ready after min_blocks (10) one-second blocks: every later block close is checked.
    assert!(ready_updates as u64 >= duration_s - 11, "only {ready_updates} checked updates");
}

#[test]
fn linear_ramp_sampled_at_1khz_gives_exact_rate_and_temperature() {
    check_ramp(1_000, 250);
}

#[test]
fn linear_ramp_sampled_at_1hz_gives_exact_rate_and_temperature() {
    check_ramp(1_000_000, 400);
}

/// Every deviation from the block's first sample is exactly 0.0 in f32, so every block
/// mean and the fit are exact: tolerance zero.
#[test]
fn constant_temperature_gives_zero_rate_and_the_constant() {
    const TEMP_C: f32 = 23.17;
    let mut tracker = Tracker::new(&FEATURES).expect("fits");
    let mut ready = 0;
    for time_us in regular_times(0, 100_000, 3_000) {
        tracker.push(time_us, TEMP_C).expect("valid");
        if let Some(f) = tracker.features() {
            ready += 1;
            assert_eq!(f.rate_c_per_min, 0.0, "rate at {time_us} us");
            assert_eq!(f.temp_c, TEMP_C, "temp at {time_us} us");
        }
    }
    assert!(ready > 2_000);
}

// ---------------------------------------------------------------------------------------
// Random smooth trajectories against the reference
// ---------------------------------------------------------------------------------------

/// Warm-up exponential plus sinusoid plus Gaussian sensor noise, at 1 kHz, 10 Hz, 1 Hz and
/// at irregular intervals (10..700 ms): the tracker equals the f64 reference at every
/// update within [`F32_ROUNDING_UNITS`] f32 roundings (see [`RefFeatures`]).
#[test]
fn random_smooth_trajectories_match_f64_reference_at_every_update() {
    let mut worst = WorstRatio::default();
    for seed in 0..8u64 {
        let mut r = common::rng(0xFEA7_0000 + seed);
        let signal = Smooth::random(&mut r);
        let noise_c = r.gen_range(0.0..0.1);
        let start_us = r.gen_range(0..1_000_000_000u64);
        let times: Vec<u64> = match seed % 4 {
            0 => regular_times(start_us, 1_000, 250_000).collect(),
            1 => regular_times(start_us, 100_000, 9_000).collect(),
            2 => regular_times(start_us, 1_000_000, 1_500).collect(),
            _ => {
                let mut t = start_us;
                (0..3_000)
                    .map(|_| {
                        t += r.gen_range(10_000..700_000);
                        t
                    })
                    .collect()
            }
        };
        let samples: Vec<(u64, f32)> = times
            .iter()
            .map(|&t| {
                let t_s = (t - start_us) as f64 / 1.0e6;
                (t, (signal.temp_c(t_s) + noise_c * gaussian(&mut r)) as f32)
            })
            .collect();
        let ratio = run_against_reference(&FEATURES, &samples, &format!("seed {seed} ({signal:?})"));
        assert!(ratio.updates > 200, "seed {seed}: {} updates", ratio.updates);
        worst.temp = worst.temp.max(ratio.temp);
        worst.rate = worst.rate.max(ratio.rate);
        worst.updates += ratio.updates;
    }
    eprintln!("largest error / one f32 rounding unit: {worst:?} (limit {F32_ROUNDING_UNITS})");
}

// ---------------------------------------------------------------------------------------
// Quantisation
// ---------------------------------------------------------------------------------------

/// RMS and largest absolute error of a rate estimate, C/min.
#[derive(Debug, Default)]
struct RateError {
    sum_sq: f64,
    max_abs: f64,
    count: usize,
}

impl RateError {
    fn add(&mut self, err: f64) {
        self.sum_sq += err * err;
        self.max_abs = self.max_abs.max(err.abs());
        self.count += 1;
    }

    fn rms(&self) -> f64 {
        (self.sum_sq / self.count as f64).sqrt()
    }
}

/// Tracker rate vs a two-point difference over the same 100 s window, both from the same
/// 0.0625 C quantised 10 Hz readings of a 0.05 C/min ramp (the window spans 1.3 steps).
fn quantised_ramp_errors(noise_c: f64, seed: u64) -> (RateError, RateError) {
    const RATE_C_PER_MIN: f64 = 0.05;
    let mut r = common::rng(seed);
    let window_us = (FEATURES.window_s * 1.0e6) as u64;
    let readings: Vec<(u64, f32)> = regular_times(0, 100_000, 72_000) // 2 h
        .map(|t| {
            let true_c = 24.01 + RATE_C_PER_MIN * t as f64 / 60.0e6;
            (t, quantise(true_c + noise_c * gaussian(&mut r)) as f32)
        })
        .collect();
    let mut tracker = Tracker::new(&FEATURES).expect("fits");
    let (mut tracker_err, mut two_point_err) = (RateError::default(), RateError::default());
    for (i, &(time_us, temp_c)) in readings.iter().enumerate() {
        let outcome = tracker.push(time_us, temp_c).expect("valid");
        let Some(f) = tracker.features().filter(|f| outcome.updated && f.window_full) else { continue };
        tracker_err.add(f64::from(f.rate_c_per_min) - RATE_C_PER_MIN);
        // Two-point difference over the same window: newest reading vs the one 100 s before.
        let back = (window_us / 100_000) as usize;
        let (t_new, temp_new) = readings[i];
        let (t_old, temp_old) = readings[i - back];
        let minutes = (t_new - t_old) as f64 / 60.0e6;
        two_point_err.add((f64::from(temp_new) - f64::from(temp_old)) / minutes - RATE_C_PER_MIN);
    }
    (tracker_err, two_point_err)
}

/// Measured (fixed seed, 7100 updates over 2 h): noise-free staircase, tracker RMS error
/// 0.0043 C/min (max 0.0073) vs two-point 0.0177 C/min (max 0.025); with 0.02 C of sensor
/// noise before quantisation (which dithers the steps, as in real sensors), tracker
/// 0.0019 C/min (max 0.0065) vs two-point 0.0227 C/min (max 0.0625). Asserted with margin:
/// the tracker's RMS error is below a third (noise-free, measured 0.24) and an eighth
/// (noisy, measured 0.083) of the two-point difference's, and below 20% of the 0.05 C/min
/// being measured. A staircase without noise bounds any estimator, hence the weaker
/// noise-free ratio.
#[test]
fn quantised_sensor_rate_error_is_far_below_two_point_difference() {
    for (noise_c, max_ratio) in [(0.0, 1.0 / 3.0), (0.02, 1.0 / 8.0)] {
        let (tracker, two_point) = quantised_ramp_errors(noise_c, 0x0_0625);
        eprintln!(
            "noise {noise_c} C: tracker rate RMS {:.5} (max {:.5}) C/min, two-point RMS {:.5} \
             (max {:.5}) C/min, {} updates",
            tracker.rms(),
            tracker.max_abs,
            two_point.rms(),
            two_point.max_abs,
            tracker.count
        );
        assert!(tracker.count > 7_000);
        assert!(
            tracker.rms() < max_ratio * two_point.rms(),
            "noise {noise_c}: tracker {} vs two-point {}",
            tracker.rms(),
            two_point.rms()
        );
        assert!(tracker.rms() < 0.2 * 0.05, "noise {noise_c}: tracker RMS {}", tracker.rms());
    }
}

// ---------------------------------------------------------------------------------------
// Readiness
// ---------------------------------------------------------------------------------------

const SMALL: FeatureSettings =
    FeatureSettings { window_s: 10.0, block_count: 10, min_blocks: 4, max_gap_s: 5.0 };

/// Sampled at 10 Hz (every block holds data): features appear when exactly `min_blocks`
/// blocks have closed, `blocks_used` counts up to `block_count`, and `window_full`
/// becomes true when exactly `block_count` blocks have closed.
#[test]
fn features_appear_after_min_blocks_and_window_fills_after_block_count() {
    let mut tracker = Tracker::new(&SMALL).expect("fits");
    let start_us = 5_000_000;
    let mut first_ready = None;
    let mut first_full = None;
    for time_us in regular_times(start_us, 100_000, 300) {
        tracker.push(time_us, 30.0 + time_us as f32 * 1.0e-8).expect("valid");
        let closed = (time_us - start_us) / 1_000_000;
        match tracker.features() {
            None => assert!(closed < 4, "no features with {closed} closed blocks"),
            Some(f) => {
                assert!(closed >= 4, "features with only {closed} closed blocks");
                assert_eq!(u64::from(f.blocks_used), closed.min(10));
                assert_eq!(f.window_full, closed >= 10);
                first_ready.get_or_insert(time_us);
                if f.window_full {
                    first_full.get_or_insert(time_us);
                }
            }
        }
    }
    assert_eq!(first_ready, Some(start_us + 4_000_000));
    assert_eq!(first_full, Some(start_us + 10_000_000));
}

/// Sampled every 2.5 s with 1 s blocks: blocks without data do not count towards
/// `min_blocks`. Sample i (from 0) closes the blocks of samples 0..i, so features appear at
/// sample 4 (10 s, four blocks with data), not when four blocks have elapsed (4 s).
#[test]
fn features_wait_for_min_blocks_with_data_not_elapsed_blocks() {
    let mut tracker = Tracker::new(&SMALL).expect("fits");
    let mut reference = Reference::new(&SMALL);
    for (i, time_us) in regular_times(0, 2_500_000, 12).enumerate() {
        tracker.push(time_us, 30.0).expect("valid");
        reference.push(time_us, 30.0);
        let with_data = i; // every earlier sample sits in its own, now closed, block
        assert_eq!(tracker.features().is_some(), with_data >= 4, "sample {i}");
        assert_eq!(tracker.features().is_some(), reference.features().is_some(), "sample {i}");
        if let Some(f) = tracker.features() {
            // 10 s window of 1 s blocks, one sample every 2.5 s: 4 or 5 blocks hold data.
            assert!((4..=5).contains(&f.blocks_used), "sample {i}: {f:?}");
            assert_eq!(f.window_full, (time_us / 1_000_000) >= 10, "sample {i}");
        }
    }
}

// ---------------------------------------------------------------------------------------
// Gaps
// ---------------------------------------------------------------------------------------

/// A silence longer than `max_gap_s` restarts the tracker: the first sample after it
/// reports `restarted`, features are `None` again, and from then on the features are
/// exactly those of a fresh tracker fed only the samples after the gap, so no window
/// spans the gap.
#[test]
fn silence_longer_than_max_gap_restarts_the_tracker() {
    let mut r = common::rng(0x6A9);
    let before: Vec<(u64, f32)> =
        regular_times(0, 100_000, 2_000).map(|t| (t, 25.0 + 0.3 * gaussian(&mut r) as f32)).collect();
    let after: Vec<(u64, f32)> = regular_times(199_900_000 + 8_000_000, 100_000, 2_000)
        .map(|t| (t, 40.0 + 0.3 * gaussian(&mut r) as f32))
        .collect();
    let mut tracker = Tracker::new(&FEATURES).expect("fits");
    for &(t, c) in &before {
        tracker.push(t, c).expect("valid");
    }
    assert!(tracker.features().is_some_and(|f| f.window_full));
    let mut fresh = Tracker::new(&FEATURES).expect("fits");
    for (i, &(t, c)) in after.iter().enumerate() {
        let outcome = tracker.push(t, c).expect("valid");
        let fresh_outcome = fresh.push(t, c).expect("valid");
        if i == 0 {
            assert_eq!(outcome, PushOutcome { updated: true, restarted: true });
            assert_eq!(tracker.features(), None);
        } else {
            assert_eq!(outcome, fresh_outcome, "sample {i} after the gap");
        }
        assert_eq!(tracker.features(), fresh.features(), "sample {i} after the gap");
    }
    assert!(tracker.features().is_some_and(|f| f.window_full && (f.temp_c - 40.0).abs() < 0.1));
    // And the reference agrees over the whole run.
    let all: Vec<(u64, f32)> = before.iter().chain(&after).copied().collect();
    run_against_reference(&FEATURES, &all, "gap");
}

/// The boundary: a silence of exactly `max_gap_us` is tolerated, one microsecond more
/// restarts.
#[test]
fn silence_of_exactly_max_gap_does_not_restart_one_microsecond_more_does() {
    let mut tracker = Tracker::new(&FEATURES).expect("fits");
    let gap_us = tracker.max_gap_us();
    assert_eq!(gap_us, 5_000_000);
    let mut t = 0;
    for _ in 0..200 {
        tracker.push(t, 20.0).expect("valid");
        t += 100_000;
    }
    t -= 100_000;
    t += gap_us;
    assert!(!tracker.push(t, 20.0).expect("valid").restarted, "exactly max_gap_us");
    assert!(tracker.features().is_some());
    t += gap_us + 1;
    assert!(tracker.push(t, 20.0).expect("valid").restarted, "max_gap_us + 1");
    assert_eq!(tracker.features(), None);
}

/// A 3.7 s silence (shorter than the 5 s max_gap_s) leaves blocks 150, 151 and 152 (1 s
/// each) without data: they are left out of the fit, not filled in, for as long as they
/// are in the window (`blocks_used` 97, then 98 and 99 as they slide out), matching the
/// reference that skips empty blocks.
#[test]
fn short_silence_leaves_empty_blocks_out_of_the_fit() {
    let mut r = common::rng(0x5110);
    let signal = Smooth::random(&mut r);
    let samples: Vec<(u64, f32)> = regular_times(0, 100_000, 3_000)
        .filter(|&t| !(150_000_000..153_600_000).contains(&t))
        .map(|t| (t, (signal.temp_c(t as f64 / 1.0e6) + 0.05 * gaussian(&mut r)) as f32))
        .collect();
    run_against_reference(&FEATURES, &samples, "short silence");
    let mut tracker = Tracker::new(&FEATURES).expect("fits");
    let mut with_hole = Vec::new();
    for &(t, c) in &samples {
        let outcome = tracker.push(t, c).expect("valid");
        assert!(!outcome.restarted);
        if let Some(f) = tracker.features().filter(|f| outcome.updated && f.window_full) {
            let closed = f.time_us / 1_000_000;
            let empty_in_window = (150..153).filter(|b| (closed - 100..closed).contains(b)).count() as u32;
            assert_eq!(f.blocks_used, 100 - empty_in_window, "{f:?}");
            if empty_in_window > 0 {
                with_hole.push((f.time_us, f.blocks_used));
            }
        }
    }
    // The sample at 153.6 s closes blocks 149..=152 at once; block 152 leaves the window
    // when block 252 closes (at 253 s).
    assert_eq!(with_hole.first(), Some(&(153_000_000, 97)));
    assert_eq!(with_hole.last(), Some(&(252_000_000, 99)));
}

// ---------------------------------------------------------------------------------------
// Rejected samples
// ---------------------------------------------------------------------------------------

/// Feeds `good` into two trackers and, into the first only, `bad` samples before the good
/// sample at the given index; checks each bad sample's error and that the two trackers
/// stay identical (whole state, outcomes and features) from then on.
fn check_rejections(bad: &[(usize, u64, f32, Error)]) {
    let mut r = common::rng(0xBAD);
    let good: Vec<(u64, f32)> =
        regular_times(1_000_000, 100_000, 2_500).map(|t| (t, 30.0 + 0.2 * gaussian(&mut r) as f32)).collect();
    let mut tested = Tracker::new(&FEATURES).expect("fits");
    let mut clean = Tracker::new(&FEATURES).expect("fits");
    for (i, &(t, c)) in good.iter().enumerate() {
        for &(_, bad_t, bad_c, expected) in bad.iter().filter(|b| b.0 == i) {
            assert_eq!(tested.push(bad_t, bad_c), Err(expected), "bad sample before {i}");
            assert_eq!(format!("{tested:?}"), format!("{clean:?}"), "state after the bad sample before {i}");
        }
        assert_eq!(tested.push(t, c), clean.push(t, c), "sample {i}");
        assert_eq!(tested.features(), clean.features(), "sample {i}");
    }
    assert!(clean.features().is_some_and(|f| f.window_full));
}

/// NaN and +-inf are rejected with `NonFiniteSample` (including at a time that would
/// close a block, and as the very first sample) and change nothing.
#[test]
fn non_finite_temperature_is_rejected_and_changes_nothing() {
    check_rejections(&[
        (0, 0, f32::NAN, Error::NonFiniteSample),
        (5, 1_450_000, f32::NAN, Error::NonFiniteSample),
        (20, 3_000_000, f32::INFINITY, Error::NonFiniteSample), // would close a block
        (500, 50_950_000, f32::NEG_INFINITY, Error::NonFiniteSample),
        (1_000, 300_000_000, f32::NAN, Error::NonFiniteSample), // would restart
    ]);
}

/// A time equal to or before the previous sample's is rejected with
/// `TimeNotIncreasing { previous_us, found_us }` and changes nothing.
#[test]
fn non_increasing_time_is_rejected_and_changes_nothing() {
    let previous = |i: usize| 1_000_000 + (i as u64 - 1) * 100_000;
    let not_increasing = |i: usize, found_us: u64| {
        (i, found_us, 30.0, Error::TimeNotIncreasing { previous_us: previous(i), found_us })
    };
    check_rejections(&[
        not_increasing(1, previous(1)),
        not_increasing(10, previous(10)),
        not_increasing(11, previous(11) - 1),
        not_increasing(1_500, previous(1_500) - 5_000_000), // back by max_gap_s exactly: jitter
        not_increasing(1_500, previous(1_500)),
    ]);
}

/// A time more than `max_gap_s` before the previous one is a clock that restarted: the
/// tracker restarts there as after a gap (oracle: a fresh tracker fed the samples from the
/// restart on), so one wrong time far ahead cannot shut out every later sample.
#[test]
fn a_step_back_beyond_the_gap_limit_restarts_like_a_gap() {
    let good: Vec<(u64, f32)> =
        regular_times(1_000_000, 100_000, 3_000).map(|t| (t, 30.0 + t as f32 * 1e-7)).collect();
    let mut tracker = Tracker::new(&FEATURES).expect("fits");
    for &(t, c) in &good[..1_000] {
        tracker.push(t, c).expect("accepted");
    }
    // One time stamp 2^40 us ahead (a corrupted word), accepted as a gap: restart.
    let wrong = tracker.push(good[999].0 + (1 << 40), 30.0).expect("a forward jump is a gap");
    assert!(wrong.restarted);
    // The clock's true times are then 2^40 us back: restart again, and accepted.
    let back = tracker.push(good[1_000].0, good[1_000].1).expect("a long step back restarts");
    assert!(back.restarted && back.updated);
    let mut fresh = Tracker::new(&FEATURES).expect("fits");
    fresh.push(good[1_000].0, good[1_000].1).expect("accepted");
    for &(t, c) in &good[1_001..] {
        assert_eq!(tracker.push(t, c), fresh.push(t, c), "t = {t}");
        assert_eq!(tracker.features(), fresh.features(), "t = {t}");
    }
    assert!(tracker.features().is_some_and(|f| f.window_full), "features again after one window");
}

// ---------------------------------------------------------------------------------------
// Construction
// ---------------------------------------------------------------------------------------

#[test]
fn block_count_above_capacity_is_capacity_too_small() {
    let settings = FeatureSettings { block_count: 65, min_blocks: 10, ..FEATURES };
    assert_eq!(
        FeatureTracker::<64>::new(&settings).map(|_| ()),
        Err(Error::CapacityTooSmall { needed: 65, capacity: 64 })
    );
    let settings = FeatureSettings { block_count: 64, ..settings };
    assert!(FeatureTracker::<64>::new(&settings).is_ok(), "block_count == N fits");
}

// ---------------------------------------------------------------------------------------
// Properties
// ---------------------------------------------------------------------------------------

fn settings_strategy() -> impl Strategy<Value = FeatureSettings> {
    (0.5f32..500.0, 2u32..=64, 0.01f32..100.0).prop_flat_map(|(window_s, block_count, max_gap_s)| {
        (2..=block_count).prop_map(move |min_blocks| FeatureSettings {
            window_s,
            block_count,
            min_blocks,
            max_gap_s,
        })
    })
}

/// Time steps from a microsecond to 10^12 us (11.6 days); at most 2000 of them cannot
/// overflow a u64 from a start below 10^12.
fn step_strategy() -> impl Strategy<Value = u64> {
    prop_oneof![1u64..1_000, 1u64..10_000_000, 1u64..1_000_000_000_000]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Any increasing times and temperatures in a physical range (|T| < 1000 C): every
    /// push succeeds, nothing panics, and reported features are finite with a consistent
    /// block count.
    #[test]
    fn arbitrary_increasing_samples_never_panic_and_features_are_finite(
        settings in settings_strategy(),
        start_us in 0u64..1_000_000_000_000,
        samples in prop::collection::vec((step_strategy(), -1000.0f32..1000.0), 1..2_000),
    ) {
        let mut tracker = FeatureTracker::<64>::new(&settings).expect("valid settings");
        let mut t = start_us;
        for (dt, temp_c) in samples {
            t += dt;
            tracker.push(t, temp_c).expect("increasing time, finite temperature");
            if let Some(f) = tracker.features() {
                prop_assert!(f.temp_c.is_finite() && f.rate_c_per_min.is_finite(), "{f:?}");
                prop_assert!(f.blocks_used >= settings.min_blocks && f.blocks_used <= settings.block_count);
            }
        }
    }
}

/// Any finite f32 temperature, however absurd (up to +-3.4e38 C): features, when reported,
/// are still finite. Fails today: block means and fit sums overflow f32 and the tracker
/// reports `Some` with NaN temperature and rate (see the deterministic case below).
#[test]
fn huge_finite_temperatures_never_give_non_finite_features() {
    let settings = FeatureSettings { window_s: 10.0, block_count: 10, min_blocks: 2, max_gap_s: 5.0 };
    let mut tracker = Tracker::new(&settings).expect("fits");
    for (i, temp_c) in [3.0e38f32, -3.0e38, 3.0e38, -3.0e38, 20.0].into_iter().enumerate() {
        tracker.push(i as u64 * 1_000_000, temp_c).expect("finite temperature, increasing time");
        if let Some(f) = tracker.features() {
            assert!(f.temp_c.is_finite() && f.rate_c_per_min.is_finite(), "sample {i}: {f:?}");
        }
    }
}

proptest! {
    // No regression file: this property is expected to fail until the bug is fixed.
    #![proptest_config(ProptestConfig {
        cases: 256,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// As `arbitrary_increasing_samples_never_panic_and_features_are_finite`, over every
    /// finite f32.
    #[test]
    fn any_finite_f32_temperatures_give_finite_features(
        settings in settings_strategy(),
        samples in prop::collection::vec(
            (step_strategy(), any::<f32>().prop_filter("finite", |v| v.is_finite())),
            1..500,
        ),
    ) {
        let mut tracker = FeatureTracker::<64>::new(&settings).expect("valid settings");
        let mut t = 0;
        for (dt, temp_c) in samples {
            t += dt;
            tracker.push(t, temp_c).expect("increasing time, finite temperature");
            if let Some(f) = tracker.features() {
                prop_assert!(f.temp_c.is_finite() && f.rate_c_per_min.is_finite(), "{f:?}");
            }
        }
    }
}
