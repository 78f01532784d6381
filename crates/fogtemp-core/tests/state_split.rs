//! Configuration apart from state (`Axis::step(&mut AxisState, ..)`), `reset`, the wrapping
//! 32-bit timer (`step_u32`), the tracker capacity contract (`Axis::blocks_needed`,
//! `CapacityTooSmall`) and the axis named in errors.
//!
//! Oracle: the existing `Compensator` (tolerance: none, every output compared bit for bit),
//! on the QEMU firmware's recorded trajectory (`examples/firmware-qemu/data`, the same one
//! `.ci/firmware-qemu.sh` replays) and on random sample streams with fixed seeds.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)] // test code: a failed expectation is the test failing

use fogtemp_core::{Axis, AxisState, Compensator, Error, Flags, Model, Output, WrappingClock};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

static FW_MODEL: &[u8] = include_bytes!("../../../examples/firmware-qemu/data/model.fogm");
static FW_TRAJECTORY: &[u8] = include_bytes!("../../../examples/firmware-qemu/data/trajectory.bin");
static GOLDEN: &[u8] = include_bytes!("../../../tests/golden/model-v1.fogm");

/// One trajectory record: `u64 time_us, f32 gyro_dph, f32 temp_c` (NaN = no temperature).
fn trajectory() -> Vec<(u64, f32, Option<f32>)> {
    FW_TRAJECTORY
        .chunks_exact(16)
        .map(|r| {
            let t = u64::from_le_bytes(r[0..8].try_into().unwrap());
            let g = f32::from_le_bytes(r[8..12].try_into().unwrap());
            let c = f32::from_le_bytes(r[12..16].try_into().unwrap());
            (t, g, (!c.is_nan()).then_some(c))
        })
        .collect()
}

fn bits(o: &Output) -> (u32, u32, u8) {
    (o.rate_dph.to_bits(), o.bias_dph.to_bits(), o.flags.0)
}

fn fw_axis() -> Axis<'static> {
    Model::from_bytes(FW_MODEL).expect("fixture model").axis(0).expect("axis 0")
}

#[test]
fn axis_step_with_caller_state_equals_compensator_bit_for_bit() {
    let model = Model::from_bytes(FW_MODEL).unwrap();
    let axis = model.axis(0).unwrap();
    let mut bundle: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let mut array_state: AxisState<[f32; 20]> = axis.state().unwrap();
    let mut blocks = [0.0f32; 20];
    let mut slice_state = axis.state_in(&mut blocks[..]).unwrap();
    let records = trajectory();
    assert_eq!(records.len(), 24_001);
    let mut flags_seen = Flags::empty();
    for &(t, g, c) in &records {
        let want = bundle.step(t, g, c);
        flags_seen |= want.flags;
        assert_eq!(bits(&axis.step(&mut array_state, t, g, c)), bits(&want), "t = {t}");
        assert_eq!(bits(&axis.step(&mut slice_state, t, g, c)), bits(&want), "t = {t}");
    }
    // The trajectory exercises every flag, so every branch of step was compared.
    assert_eq!(flags_seen.0, 0x1F, "flags seen {:#x}", flags_seen.0);
    assert_eq!(array_state.bias_dph().to_bits(), bundle.bias_dph().to_bits());
}

/// Random streams (seeded): gaps, NaN/inf temperatures, repeated and backward times,
/// gyro-only samples; two axes of the golden model.
#[test]
fn axis_step_equals_compensator_on_random_streams() {
    let model = Model::from_bytes(GOLDEN).unwrap();
    for seed in 0..8u64 {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x5EED_0000 + seed);
        for index in 0..model.axis_count() {
            let axis = model.axis(index).unwrap();
            let mut bundle: Compensator<'_> = Compensator::new(&model, index).unwrap();
            let mut state: AxisState = axis.state().unwrap();
            let mut t = rng.gen_range(0..1_000_000u64);
            let mut temp = rng.gen_range(-40.0f32..80.0);
            for _ in 0..20_000 {
                t = match rng.gen_range(0..100) {
                    0 => t.saturating_sub(rng.gen_range(0..5_000)),
                    1 => t + rng.gen_range(1_000_000..20_000_000),
                    _ => t + rng.gen_range(500..3_000),
                };
                temp += rng.gen_range(-0.05f32..0.06);
                let c = match rng.gen_range(0..50) {
                    0 => Some(f32::NAN),
                    1 => Some(f32::INFINITY),
                    2..=20 => None,
                    _ => Some(temp),
                };
                let g = rng.gen_range(-50.0f32..50.0);
                let want = bundle.step(t, g, c);
                assert_eq!(bits(&axis.step(&mut state, t, g, c)), bits(&want), "seed {seed} axis {index}");
            }
        }
    }
}

/// The trajectory shifted so that the 32-bit microsecond timer wraps 100 s into it:
/// `step_u32` with the wrapped times equals `step` with the unwrapped 64-bit times, bit for
/// bit, and no sample after the wrap is `BAD_INPUT` (except the fixture's own duplicate).
#[test]
fn step_u32_across_the_wrap_equals_step_u64() {
    let model = Model::from_bytes(FW_MODEL).unwrap();
    let records = trajectory();
    let t0 = records[0].0;
    let offset = (1u64 << 32) - 100_000_000 - t0; // wrap at t0 + 100 s
    let mut reference: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let mut wrapped: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let mut naive: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let (mut crossed, mut bad_ref, mut restarted_naive, mut restarted_ref) = (false, 0, 0, 0);
    for &(t, g, c) in &records {
        let t64 = t + offset;
        let t32 = t64 as u32;
        crossed |= t64 >= 1 << 32;
        let want = reference.step(t, g, c);
        assert_eq!(bits(&wrapped.step_u32(t32, g, c)), bits(&want), "t64 = {t64}");
        bad_ref += usize::from(want.flags.contains(Flags::BAD_INPUT));
        let after_wrap = t64 >= 1 << 32;
        let warming =
            |o: fogtemp_core::Output| usize::from(after_wrap && o.flags.contains(Flags::WARMING_UP));
        restarted_naive += warming(naive.step(u64::from(t32), g, c));
        restarted_ref += warming(want);
    }
    assert!(crossed);
    assert_eq!(bad_ref, 1, "the fixture's one duplicated record");
    // A wrapped time fed as u64 is a step back of 71.6 min: the tracker restarts there and
    // loses its window (it used to reject every later temperature); step_u32 does not (its
    // warm-up samples after the wrap are the fixture's own).
    assert!(
        restarted_naive > restarted_ref + 10,
        "naive u64 use of a wrapping timer: {restarted_naive} samples warming up after the wrap, {restarted_ref} with step_u32"
    );
}

#[test]
fn wrapping_clock_extends_forward_and_keeps_backward_backward() {
    let mut clock = WrappingClock::new();
    assert_eq!(clock.extend(u32::MAX - 10), u64::from(u32::MAX) - 10);
    assert_eq!(clock.extend(5), (1u64 << 32) + 5);
    // Equal and backward times map at or before the last time (then rejected by the tracker).
    assert_eq!(clock.extend(5), (1u64 << 32) + 5);
    assert_eq!(clock.extend(u32::MAX - 1), (1u64 << 32) + 5 - 7);
    // The next time counts from the backward one: the chain of differences is exact.
    assert_eq!(clock.extend(1_005), (1u64 << 32) + 1_005);
    // A step back below 0 stops at 0; the samples after it count from there.
    let mut early = WrappingClock::new();
    assert_eq!(early.extend(200), 200);
    assert_eq!(early.extend(100u32.wrapping_sub(1_000)), 0);
    assert_eq!(early.extend(100u32.wrapping_sub(990)), 10);
    // Just under 2^31 us ahead is forward.
    let t = clock.extend(1_005u32.wrapping_add(i32::MAX as u32));
    assert_eq!(t, (1u64 << 32) + 1_005 + i32::MAX as u64);
}

#[test]
fn backward_u32_time_is_bad_input_not_a_jump() {
    let axis = fw_axis();
    let mut state: AxisState<[f32; 20]> = axis.state().unwrap();
    let base = u32::MAX - 500_000;
    let mut t = base;
    for k in 0..200u32 {
        t = t.wrapping_add(100_000);
        let out = axis.step_u32(&mut state, t, 1.0, Some(25.0 + k as f32 * 0.001));
        assert!(!out.flags.contains(Flags::BAD_INPUT), "k = {k}");
    }
    let out = axis.step_u32(&mut state, t.wrapping_sub(1), 1.0, Some(25.0));
    assert!(out.flags.contains(Flags::BAD_INPUT));
    assert!(!out.flags.contains(Flags::TEMP_STALE), "a backward time is not a gap");
    let out = axis.step_u32(&mut state, t.wrapping_add(100_000), 1.0, Some(25.2));
    assert!(!out.flags.contains(Flags::BAD_INPUT));
}

/// A 32-bit time base set back by 1,000 s (within the 2^31 us limit, longer than the gap
/// limit) restarts the tracker as `step` does when its 64-bit clock restarts: from the step
/// back on, every output equals that of `step` fed the restarted clock, bit for bit, with
/// no `BAD_INPUT`; early in a run (the extended time would fall below 0) and later alike.
#[test]
fn u32_time_base_set_back_restarts_like_step() {
    let axis = fw_axis();
    for base_s in [0u32, 3_000] {
        let mut wrapped: AxisState<[f32; 20]> = axis.state().unwrap();
        let mut restarted: AxisState<[f32; 20]> = axis.state().unwrap();
        let temp = |k: u32| 25.0 + k as f32 * 0.002;
        for k in 0..200u32 {
            let t_us = (base_s + k) * 1_000_000;
            axis.step_u32(&mut wrapped, t_us, 1.0, Some(temp(k)));
            axis.step(&mut restarted, u64::from(k) * 1_000_000, 1.0, Some(temp(k)));
        }
        let back_us = ((base_s + 200) * 1_000_000).wrapping_sub(1_000_000_000);
        for j in 0..300u32 {
            let a = axis.step_u32(&mut wrapped, back_us.wrapping_add(j * 1_000_000), 1.0, Some(temp(j)));
            let b = axis.step(&mut restarted, u64::from(j) * 1_000_000, 1.0, Some(temp(j)));
            assert!(!a.flags.contains(Flags::BAD_INPUT), "base {base_s} s, sample {j} after the step back");
            assert_eq!(
                (a.rate_dph.to_bits(), a.bias_dph.to_bits(), a.flags),
                (b.rate_dph.to_bits(), b.bias_dph.to_bits(), b.flags),
                "base {base_s} s, sample {j} after the step back"
            );
        }
    }
}

/// After `reset` a state (and a Compensator) behaves exactly as a fresh one, whatever it
/// went through before, including the wrapping clock.
#[test]
fn reset_is_power_on() {
    let model = Model::from_bytes(FW_MODEL).unwrap();
    let axis = model.axis(0).unwrap();
    let records = trajectory();
    let mut used: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let mut used_state: AxisState<[f32; 20]> = axis.state().unwrap();
    for &(t, g, c) in records.iter().take(15_000) {
        used.step(t, g, c);
        axis.step_u32(&mut used_state, (t + 9_000_000_000) as u32, g, c);
    }
    assert_ne!(used.bias_dph(), 0.0);
    used.reset();
    used_state.reset();
    assert_eq!(used.bias_dph(), 0.0);
    let mut fresh: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let mut fresh_state: AxisState<[f32; 20]> = axis.state().unwrap();
    for &(t, g, c) in &records {
        let want = fresh.step(t, g, c);
        assert_eq!(bits(&used.step(t, g, c)), bits(&want));
        // The time base may even start lower than before the reset.
        let t32 = (t + 7) as u32;
        let want = axis.step_u32(&mut fresh_state, t32, g, c);
        assert_eq!(bits(&axis.step_u32(&mut used_state, t32, g, c)), bits(&want));
    }
}

#[test]
fn capacity_is_a_checked_contract_naming_needed_and_available() {
    let model = Model::from_bytes(FW_MODEL).unwrap();
    let axis = model.axis(0).unwrap();
    assert_eq!(axis.blocks_needed(), 20);
    assert_eq!(axis.features.blocks_needed(), 20);
    let small = Compensator::<'_, 19>::new(&model, 0).map(|_| ());
    assert_eq!(small, Err(Error::CapacityTooSmall { needed: 20, capacity: 19 }));
    assert!(Compensator::<'_, 20>::new(&model, 0).is_ok(), "exactly blocks_needed fits");
    let mut blocks = [0.0f32; 5];
    let e = axis.state_in(&mut blocks[..]).map(|_| ()).unwrap_err();
    assert_eq!(e, Error::CapacityTooSmall { needed: 20, capacity: 5 });
    assert_eq!(e.to_string(), "feature tracker holds 5 blocks but the model needs 20");
    assert!(matches!(axis.state::<8>(), Err(Error::CapacityTooSmall { needed: 20, capacity: 8 })));
    // The golden model: blocks_needed equals each axis's block_count.
    let golden = Model::from_bytes(GOLDEN).unwrap();
    for i in 0..golden.axis_count() {
        let a = golden.axis(i).unwrap();
        assert_eq!(a.blocks_needed(), a.features.block_count as usize);
    }
}

/// The tracker does not know its axis; the axis that creates it puts its own id in the error.
#[test]
fn tracker_errors_name_the_axis() {
    let model = Model::from_bytes(GOLDEN).unwrap();
    assert!(model.axis_count() >= 2);
    let mut axis = model.axis(1).unwrap();
    axis.features.block_count = 1; // no validated blob holds this; hand-built config can
    axis.features.min_blocks = 1;
    assert!(matches!(axis.state::<128>(), Err(Error::BadValue { field: "block_count", axis: 1, .. })));
    let mut axis = model.axis(1).unwrap();
    axis.features.max_gap_s = 1.0e12;
    assert!(matches!(axis.state::<128>(), Err(Error::BadValue { field: "max_gap_s", axis: 1, .. })));
}

/// A temperature no sensor reads (a logger's -999, a corrupted 1e30) is flagged
/// `BAD_INPUT` and left out of the features: every output equals, bit for bit, that of the
/// same stream with those samples' temperatures absent (the oracle), flags aside.
#[test]
fn impossible_temperatures_are_bad_input_and_change_nothing_else() {
    let model = Model::from_bytes(FW_MODEL).unwrap();
    let records = trajectory();
    let mut tested: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let mut oracle: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let spoiled = [-999.0_f32, 1.0e30, -273.2, 1000.5, f32::MAX];
    let mut flagged = 0;
    for (k, &(t, g, c)) in records.iter().enumerate() {
        let bad = (k % 97 == 50).then(|| spoiled[(k / 97) % spoiled.len()]);
        let out = tested.step(t, g, bad.or(c));
        let want = oracle.step(t, g, if bad.is_some() { None } else { c });
        assert_eq!(
            (out.rate_dph.to_bits(), out.bias_dph.to_bits()),
            (want.rate_dph.to_bits(), want.bias_dph.to_bits()),
            "k = {k}"
        );
        if bad.is_some() {
            assert!(out.flags.contains(Flags::BAD_INPUT), "k = {k}: {:?}", bad);
            flagged += 1;
        }
    }
    assert!(flagged > 10);
    assert!(fogtemp_core::is_physical_temperature(-273.15) && fogtemp_core::is_physical_temperature(1000.0));
    assert!(!fogtemp_core::is_physical_temperature(f32::NAN));
}
