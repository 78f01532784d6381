//! Inputs the `ffi_entry_points` fuzz target (fuzz/fuzz_targets/ffi_entry_points.rs) crashed
//! on, replayed on stable: each file in `tests/fuzz-regressions/` is decoded as the target
//! decodes it (options byte, u16 blob length, blob; the blob also with `total_len` and the
//! CRC patched) and must keep the target's invariant: every axis of an accepted model gets a
//! state when the blocks array is as long as `fogtemp_axis_blocks_needed` says.
//!
//! - `ffi_entry_points-crash-2ac97491` (2026-11-23): the patched blob's axis had a
//!   `max_gap_s` the tracker cannot time in microseconds; `from_bytes` accepted it and
//!   `fogtemp_state_init` refused it with `BAD_VALUE`. Fixed in the validator.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
#![allow(clippy::undocumented_unsafe_blocks, clippy::arithmetic_side_effects)]

use fogtemp_ffi::*;

fn accepted_axes_get_states(blob: &[u8]) {
    let mut model = fogtemp_model { opaque: [0; 4] };
    let mut err = std::mem::MaybeUninit::<fogtemp_error>::zeroed();
    if unsafe { fogtemp_model_from_bytes(blob.as_ptr(), blob.len(), &mut model, err.as_mut_ptr()) }
        != fogtemp_status::Ok
    {
        return;
    }
    let mut count = 0usize;
    unsafe { fogtemp_model_axis_count(&model, &mut count) };
    for i in 0..count {
        let mut axis = fogtemp_axis { opaque: [0; 24] };
        assert_eq!(unsafe { fogtemp_model_axis(&model, i, &mut axis, err.as_mut_ptr()) }, fogtemp_status::Ok);
        let mut needed = 0usize;
        unsafe { fogtemp_axis_blocks_needed(&axis, &mut needed) };
        let mut blocks = vec![0.0f32; needed];
        let mut state = fogtemp_state { opaque: [0; 28] };
        let s =
            unsafe { fogtemp_state_init(&axis, &mut state, blocks.as_mut_ptr(), needed, err.as_mut_ptr()) };
        assert_eq!(s, fogtemp_status::Ok, "axis {i} of an accepted model refused a state");
    }
}

#[test]
fn fuzz_regressions_keep_the_invariant() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz-regressions");
    let mut files = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let data = std::fs::read(entry.unwrap().path()).unwrap();
        files += 1;
        let len = usize::from(u16::from_le_bytes([data[1], data[2]])).min(data.len() - 3);
        let blob = &data[3..3 + len];
        accepted_axes_get_states(blob);
        if blob.len() >= 68 {
            let mut fixed = blob.to_vec();
            let n = fixed.len();
            fixed[8..12].copy_from_slice(&(n as u32).to_le_bytes());
            let crc = fogtemp_core::crc::crc32(&fixed[..n - 4]);
            fixed[n - 4..].copy_from_slice(&crc.to_le_bytes());
            accepted_axes_get_states(&fixed);
        }
    }
    assert!(files >= 1);
}
