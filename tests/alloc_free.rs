//! `Compensator::step` never allocates: this test binary installs a counting global
//! allocator (`stats_alloc`, which wraps `std::alloc::System` and counts every call in
//! atomics; its `unsafe impl GlobalAlloc` lives in that crate, so this file needs no
//! `unsafe` under the workspace's `forbid(unsafe_code)`), builds the model and the
//! compensator (allocation allowed), then counts the allocations of 100,000 `step` calls.
//!
//! The counter is global (all threads), so this binary holds exactly one test: nothing
//! else runs while it measures, and it prints nothing while measuring.

mod common;

use std::alloc::System;

use common::{bias_surface, model_blob, paper_points};
use fogtemp_core::{Compensator, Flags, Model, OutsidePolicy, PolyTerm};
use stats_alloc::{Region, StatsAlloc, INSTRUMENTED_SYSTEM};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// 100,000 samples 2 ms apart (200 s), temperature every 100th sample (5 Hz): a warm-up
/// inside the hull (features from 10 s), a jump to 95 C from 30 s to 50 s (outside the
/// hull, which ends at 72 C), back on the warm-up, then no temperature from 56 s to 64 s
/// (longer than the 5 s max_gap_s: TEMP_STALE, then a restart), and the warm-up to the end
/// (window full again at 164 s, flags clear).
fn inputs() -> Vec<(u64, f32, Option<f32>)> {
    (0..100_000u64)
        .map(|i| {
            let t_s = i as f64 * 0.002;
            let warm_up_c = 20.0 + 10.0 * (1.0 - (-t_s / 1200.0).exp());
            let temp_c = if (30.0..50.0).contains(&t_s) { 95.0 } else { warm_up_c };
            let gyro_dph = bias_surface(temp_c, 0.3) + 0.01 * (i % 7) as f64;
            let reading = (i % 100 == 0 && !(56.0..64.0).contains(&t_s)).then_some(temp_c as f32);
            (1_000 + i * 2_000, gyro_dph as f32, reading)
        })
        .collect()
}

/// Which paths the measured run went through (counted without allocating).
#[derive(Debug, Default)]
struct Seen {
    feature_updates: usize,
    warming_up: usize,
    partial_window: usize,
    outside_hull: usize,
    temp_stale: usize,
    clear: usize,
}

#[test]
fn step_never_allocates_through_updates_hull_excursion_and_gap() {
    // The held mesh and the mesh continued with stored gradients (the fit's default).
    for policy in [OutsidePolicy::NearestHull, OutsidePolicy::StoredGradients] {
        steps_without_allocating(policy);
    }
}

fn steps_without_allocating(policy: OutsidePolicy) {
    // The counter counts: a Vec allocation made inside a region shows up in it.
    let region = Region::new(GLOBAL);
    let probe: Vec<u64> = std::hint::black_box(Vec::with_capacity(16));
    let counted = region.change().allocations;
    drop(probe);
    assert!(counted >= 1, "the counting allocator did not see a Vec allocation");

    // Set-up: allocation allowed. A hybrid model (polynomial plus mesh) exercises both parts.
    let poly = vec![
        PolyTerm { temp_power: 1, rate_power: 0, coefficient_dph: 0.002 },
        PolyTerm { temp_power: 1, rate_power: 1, coefficient_dph: -0.001 },
        PolyTerm { temp_power: 0, rate_power: 0, coefficient_dph: 0.01 },
    ];
    let points = paper_points(40, bias_surface);
    let blob = model_blob(poly, Some(&points), policy);
    let model = Model::from_bytes(&blob).expect("valid blob");
    let mut comp: Compensator = Compensator::new(&model, 0).expect("axis 0");
    let inputs = inputs();
    let mut seen = Seen::default();
    let mut last_feature_us = 0u64;
    let mut checksum = 0.0f64;

    let mut region = Region::new(GLOBAL);
    region.reset();
    for &(time_us, gyro_dph, temp_c) in &inputs {
        let out = comp.step(time_us, gyro_dph, temp_c);
        checksum += f64::from(out.rate_dph);
        if let Some(f) = comp.tracker().features() {
            if f.time_us != last_feature_us {
                last_feature_us = f.time_us;
                seen.feature_updates += 1;
            }
        }
        for (flag, count) in [
            (Flags::WARMING_UP, &mut seen.warming_up),
            (Flags::PARTIAL_WINDOW, &mut seen.partial_window),
            (Flags::OUTSIDE_HULL, &mut seen.outside_hull),
            (Flags::TEMP_STALE, &mut seen.temp_stale),
        ] {
            if out.flags.contains(flag) {
                *count += 1;
            }
        }
        if out.flags.is_empty() {
            seen.clear += 1;
        }
    }
    let stats = region.change();
    std::hint::black_box(checksum);

    assert_eq!(
        (stats.allocations, stats.reallocations, stats.bytes_allocated),
        (0, 0, 0),
        "allocations during 100,000 steps with {policy:?}: {stats:?}"
    );
    // The run went where it was meant to (500 steps a second): block closes with features
    // at 10..=55 s (the 56 s block never closes: the gap) and 74..=199 s; warm-ups 0-10 s
    // and 64-74 s; the excursion from about 30 s to the restart at 64 s; stale from 60.8 s
    // (5 s after the last reading) to 64 s; clear flags 164-200 s.
    assert_eq!(seen.feature_updates, 46 + 126, "{seen:?}");
    assert_eq!(seen.warming_up, 10_000, "{seen:?}");
    assert!(seen.partial_window > 60_000, "{seen:?}");
    assert!(seen.outside_hull > 15_000, "{seen:?}");
    assert!((1_400..1_600).contains(&seen.temp_stale), "{seen:?}");
    assert_eq!(seen.clear, 18_000, "{seen:?}");
}
