//! Fuzz target: `Model::from_bytes` must never panic, and a model it accepts must evaluate
//! without panicking at any query, with any walk hint.
//!
//! Each input is tried twice: as given, and with `total_len` and the CRC-32 trailer patched
//! to match (otherwise almost every mutation stops at the CRC check and the validation behind
//! it is never reached).
#![no_main]

use fogtemp_core::wire::{CRC_LEN, FILE_HEADER_LEN, FILE_TOTAL_LEN};
use fogtemp_core::{Location, Model, WalkHint};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    check(data, data);
    if data.len() >= FILE_HEADER_LEN + CRC_LEN {
        let mut fixed = data.to_vec();
        let len = fixed.len();
        fixed[FILE_TOTAL_LEN].copy_from_slice(&(len as u32).to_le_bytes());
        let crc = fogtemp_core::crc::crc32(&fixed[..len - CRC_LEN]);
        fixed[len - CRC_LEN..].copy_from_slice(&crc.to_le_bytes());
        check(&fixed, data);
    }
});

/// Parses `bytes` and, if accepted, evaluates every axis at queries drawn from `seed_bytes`.
fn check(bytes: &[u8], seed_bytes: &[u8]) {
    let Ok(model) = Model::from_bytes(bytes) else { return };
    let _ = (model.tool_version(), model.input_digest(), model.format_version());
    assert!(model.axis(model.axis_count()).is_err());
    // The log records (versions 4 to 8): every accessor, one past the last entry too.
    for index in 0..=model.axis_count() {
        let _ = model.axis_columns(index);
    }
    let _ = model.log_time();
    if let Some(reading) = model.log_reading() {
        for index in 0..=reading.log_count() {
            let _ = reading.log_digest(index);
        }
    }
    if let Some(shape) = model.log_shape() {
        let names = (0..shape.column_count()).filter_map(|i| shape.column_name(i)).count();
        assert_eq!(names, shape.column_count(), "an accepted shape hands out each of its names");
        assert!(shape.column_name(shape.column_count()).is_none());
    }
    if model.input_rates().is_some() {
        assert!(model.log_shape().is_some(), "the run-metadata record follows a log-shape record");
    }
    // Queries: a few fixed ones, and f32s taken from the input (any bit pattern: NaN, inf,
    // subnormal, huge).
    let mut queries = vec![(20.0f32, 0.5f32), (-40.0, 0.0), (80.0, 1.0), (1.0e30, -1.0e30), (f32::NAN, 0.0)];
    for chunk in seed_bytes.chunks_exact(8).rev().take(6) {
        let t = f32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
        let r = f32::from_le_bytes([chunk[4], chunk[5], chunk[6], chunk[7]]);
        queries.push((t, r));
    }
    let hint_seed = seed_bytes.iter().fold(0u32, |h, &b| h.rotate_left(5) ^ u32::from(b));
    for index in 0..model.axis_count() {
        let axis = model.axis(index).expect("an accepted model hands out each of its axes");
        let mut hint = WalkHint(hint_seed);
        for &(t, r) in &queries {
            let _ = axis.evaluate(t, r, &mut hint);
            if let Some(mesh) = &axis.mesh {
                assert!(hint.0 < mesh.triangle_count(), "hint left out of range");
                let (x, y) = axis.normalisation.apply(t, r);
                for h in [0, hint_seed, u32::MAX, mesh.triangle_count()] {
                    let mut hint = WalkHint(h);
                    if let Ok(Location::Inside { triangle, .. } | Location::Outside { triangle }) =
                        mesh.locate(x, y, &mut hint)
                    {
                        assert!(triangle < mesh.triangle_count());
                    }
                    let _ = mesh.interpolate(x, y, &mut hint);
                }
                let _ = (mesh.locate_by_scan(x, y), mesh.nearest_hull_value(x, y));
            }
            if let Some(poly) = &axis.poly {
                let (x, y) = axis.normalisation.apply(t, r);
                let _ = poly.evaluate(x, y);
            }
        }
    }
}
