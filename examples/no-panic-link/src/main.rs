//! Link-time proof that the calls a firmware makes into `fogtemp-core` hold no panic path:
//! `panic-never`'s handler calls a symbol that no library defines, so the link fails if the
//! optimiser leaves any panic reachable (a division the compiler cannot prove non-zero, an
//! index it cannot prove in range, an `unwrap`). A review found three such divisions
//! (guarded by the blob validator, but invisible to the compiler) on 2026-11-27; they are
//! `checked_*` since. Nothing is constant-folded
//! away: `exercise` is exported, so every path `from_bytes`, `from_flash`,
//! `Compensator::step`, `step_u32`, `Axis::evaluate` and `evaluate_with_grid` can take is
//! kept.
#![no_std]
#![no_main]

use core::hint::black_box;

use fogtemp_core::{Compensator, Model, WalkHint};
use panic_never as _;

/// Every core entry point a firmware uses. Exported, so it is compiled for any arguments:
/// the blob and the samples are opaque to the optimiser.
#[no_mangle]
pub extern "C" fn exercise(blob: &[u8; 4096], times_us: &[u64; 16], gyros_dph: &[f32; 16], temps_c: &[f32; 16]) -> f32 {
    let bytes: &[u8] = blob;
    let Ok(model) = Model::from_bytes(bytes) else { return -1.0 };
    let mut acc = 0.0;
    if let Ok((flash, _)) = Model::from_flash(bytes) {
        acc += flash.axis_count() as f32;
    }
    let Ok(mut compensator) = Compensator::<128>::new(&model, 0) else { return -2.0 };
    let Ok(mut wrapped) = Compensator::<128>::new(&model, 0) else { return -3.0 };
    for ((&time_us, &gyro_dph), &temp_c) in times_us.iter().zip(gyros_dph).zip(temps_c) {
        acc += compensator.step(time_us, gyro_dph, (!temp_c.is_nan()).then_some(temp_c)).rate_dph;
        acc += wrapped.step_u32(time_us as u32, gyro_dph, Some(temp_c)).rate_dph;
    }
    if let Ok(axis) = model.axis(times_us[0] as usize) {
        let mut hint = WalkHint::default();
        if let Ok(e) = axis.evaluate(acc, acc * 0.5, &mut hint) {
            acc += e.value_dph;
        }
        if let Some(mesh) = axis.mesh.as_ref() {
            let mut cells = [0u32; 256];
            if let Ok(grid) = mesh.start_grid(times_us[1] as u32, &mut cells) {
                if let Ok(e) = axis.evaluate_with_grid(acc, acc, &mut hint, &grid) {
                    acc += e.value_dph;
                }
            }
        }
    }
    acc
}

/// Inputs for the reset vector's call.
static BLOB: [u8; 4096] = [0; 4096];
static TIMES_US: [u64; 16] = [0; 16];
static VALUES: [f32; 16] = [0.0; 16];

/// The reset vector: runs the calls once and keeps the result.
#[no_mangle]
pub extern "C" fn Reset() -> ! {
    black_box(exercise(black_box(&BLOB), &TIMES_US, &VALUES, &VALUES));
    loop {}
}
