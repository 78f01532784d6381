//! `compensator/step` and `features/push`: the per-sample firmware path over a long 1 kHz
//! replay of a warm-up (temperature with sensor noise and quantisation, noisy gyro).
//!
//! Each iteration replays [`REPLAY_SAMPLES`] samples (10 minutes at 1 kHz) into a clone of
//! a compensator (or tracker) already warmed over [`PREWARM_SAMPLES`] samples, so every
//! measured sample sees a full 100 s feature window; the clone is made outside the timing.
//! The model is hybrid (the paper's 12-term polynomial plus the paper-size mesh), so each
//! block close evaluates both parts. Peer `baseline_subtract` runs the same replay loop
//! doing only `gyro - bias`: the floor set by the loop and the replay data.

use std::hint::black_box;
use std::time::Duration;

use criterion::{BatchSize, BenchmarkGroup, BenchmarkId, Criterion, SamplingMode, Throughput};
use fogtemp_core::{Compensator, FeatureTracker, Model, DEFAULT_CAPACITY};

use crate::fixtures;

/// Samples replayed before the measurement: 120 s, more than the 100 s feature window.
const PREWARM_SAMPLES: usize = 120_000;
/// Samples per measured replay: 10 minutes at 1 kHz.
const REPLAY_SAMPLES: usize = 600_000;
/// Sample period at 1 kHz, microseconds.
const PERIOD_US: u64 = 1_000;

/// The replay: gyro per sample, and the temperature stream for each variant.
struct Replay {
    gyro_dph: Vec<f32>,
    temp_c: Vec<f32>,
}

impl Replay {
    fn new() -> Self {
        let n = PREWARM_SAMPLES + REPLAY_SAMPLES;
        Replay { gyro_dph: fixtures::gyro_replay(n, 3), temp_c: fixtures::temperature_replay(n, 5) }
    }

    /// Temperature for every `every`-th sample, `None` between.
    fn temperature_every(&self, every: usize) -> Vec<Option<f32>> {
        self.temp_c.iter().enumerate().map(|(i, &t)| (i % every == 0).then_some(t)).collect()
    }
}

fn time_us(i: usize) -> u64 {
    i as u64 * PERIOD_US + PERIOD_US
}

fn configure(group: &mut BenchmarkGroup<'_, criterion::measurement::WallTime>) {
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(20);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(4));
    group.throughput(Throughput::Elements(REPLAY_SAMPLES as u64));
}

/// `compensator/step`: temperature with every sample, and with every 100th sample.
pub fn step(c: &mut Criterion) {
    let replay = Replay::new();
    let points = fixtures::paper_points(fixtures::PAPER_POINTS_PER_RUN);
    let blob = fixtures::model_blob(fixtures::paper_poly(), Some(&points));
    let model = Model::from_bytes(&blob).expect("valid blob");

    let mut group = c.benchmark_group("compensator/step");
    configure(&mut group);
    for every in [1usize, 100] {
        let temps = replay.temperature_every(every);
        let mut warmed: Compensator<'_> = Compensator::new(&model, 0).expect("compensator");
        for (i, (&g, &t)) in replay.gyro_dph.iter().zip(&temps).take(PREWARM_SAMPLES).enumerate() {
            warmed.step(time_us(i), g, t);
        }
        let out = warmed.step(time_us(PREWARM_SAMPLES), replay.gyro_dph[PREWARM_SAMPLES], None);
        assert!(out.flags.is_empty(), "warmed compensator is in steady state: {:?}", out.flags);
        let (gyro, temps) = (&replay.gyro_dph[PREWARM_SAMPLES..], &temps[PREWARM_SAMPLES..]);
        let param = format!("temp_every_{every}");
        group.bench_function(BenchmarkId::new("fogtemp_compensator", &param), |b| {
            b.iter_batched_ref(
                || warmed.clone(),
                |comp| {
                    for (k, (&g, &t)) in black_box(gyro).iter().zip(black_box(temps)).enumerate() {
                        black_box(comp.step(time_us(PREWARM_SAMPLES + 1 + k), g, t));
                    }
                },
                BatchSize::PerIteration,
            )
        });
    }
    let bias_dph = black_box(0.0123f32);
    let gyro = &replay.gyro_dph[PREWARM_SAMPLES..];
    group.bench_function(BenchmarkId::new("baseline_subtract", "replay"), |b| {
        b.iter(|| {
            for &g in black_box(gyro) {
                black_box(g - bias_dph);
            }
        })
    });
    group.finish();
}

/// `features/push`: one `FeatureTracker::push` per 1 kHz temperature sample.
pub fn push(c: &mut Criterion) {
    let replay = Replay::new();
    let mut warmed: FeatureTracker<DEFAULT_CAPACITY> =
        FeatureTracker::new(&fixtures::FEATURES).expect("tracker");
    for (i, &t) in replay.temp_c[..PREWARM_SAMPLES].iter().enumerate() {
        warmed.push(time_us(i), t).expect("increasing time, finite temperature");
    }
    assert!(warmed.features().is_some_and(|f| f.window_full), "warmed tracker has a full window");
    let temps = &replay.temp_c[PREWARM_SAMPLES..];

    let mut group = c.benchmark_group("features/push");
    configure(&mut group);
    group.bench_function(BenchmarkId::new("fogtemp_tracker", "1kHz"), |b| {
        b.iter_batched_ref(
            || warmed.clone(),
            |tracker| {
                for (k, &t) in black_box(temps).iter().enumerate() {
                    let _ = black_box(tracker.push(time_us(PREWARM_SAMPLES + k), t));
                }
            },
            BatchSize::PerIteration,
        )
    });
    group.finish();
}
