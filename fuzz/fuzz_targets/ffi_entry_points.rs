//! Fuzz target: the C ABI (`fogtemp-ffi`) on arbitrary input must never panic, never read or
//! write outside the memory it is given (AddressSanitizer), and keep its contracts:
//! a failed call leaves its out-struct untouched, `fogtemp_error_message` always
//! NUL-terminates inside the buffer, a step always writes finite-or-raw outputs.
//!
//! Input layout: byte 0 = options (padding kind, capacity slack, buffer length), bytes 1..3
//! = how many bytes the blob takes, the blob (tried as given and with `total_len` and the
//! CRC patched), then 12-byte sample records (`u32 time_us`, `f32 gyro`, `f32 temp`) that
//! drive `fogtemp_step` / `fogtemp_step_u32` / `fogtemp_state_reset` / `fogtemp_evaluate`.
#![no_main]

use core::ptr;

use fogtemp_core::wire::{CRC_LEN, FILE_HEADER_LEN, FILE_TOTAL_LEN};
use fogtemp_ffi::*;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&opts, rest)) = data.split_first() else { return };
    let (blob_len, rest) = match rest {
        [a, b, rest @ ..] => (usize::from(u16::from_le_bytes([*a, *b])), rest),
        _ => return,
    };
    let blob_len = blob_len.min(rest.len());
    let (blob, samples) = rest.split_at(blob_len);
    run(opts, blob, samples);
    if blob.len() >= FILE_HEADER_LEN + CRC_LEN {
        let mut fixed = blob.to_vec();
        let len = fixed.len();
        fixed[FILE_TOTAL_LEN].copy_from_slice(&(len as u32).to_le_bytes());
        let crc = fogtemp_core::crc::crc32(&fixed[..len - CRC_LEN]);
        fixed[len - CRC_LEN..].copy_from_slice(&crc.to_le_bytes());
        run(opts, &fixed, samples);
    }
    caller_mistakes();
});

fn run(opts: u8, blob: &[u8], samples: &[u8]) {
    // A flash partition: the blob, then padding chosen by the options (0xFF, 0x00, junk).
    let mut flash = blob.to_vec();
    let pad = usize::from(opts & 0x0F);
    let fill = match (opts >> 4) & 3 {
        0 => 0xFF,
        1 => 0x00,
        2 => 0x5A,
        _ => opts,
    };
    flash.extend(std::iter::repeat_n(fill, pad));
    let mut used = usize::MAX;
    let mut model = fogtemp_model { opaque: [0xA5; 4] };
    let mut err = std::mem::MaybeUninit::<fogtemp_error>::zeroed();
    // SAFETY: valid pointers to live locals.
    let s = unsafe { fogtemp_model_from_flash(flash.as_ptr(), flash.len(), &mut model, &mut used, err.as_mut_ptr()) };
    if s == fogtemp_status::Ok {
        assert_eq!(used, blob.len(), "from_flash must report the blob's length");
        assert!(pad == 0 || fill == 0xFF || fill == 0x00, "junk padding accepted");
    } else {
        assert_eq!(model.opaque, [0xA5; 4], "failed call wrote its out-struct");
        message_checks(err.as_ptr(), opts);
    }
    let mut model = fogtemp_model { opaque: [0; 4] };
    // SAFETY: as above.
    let s = unsafe { fogtemp_model_from_bytes(blob.as_ptr(), blob.len(), &mut model, err.as_mut_ptr()) };
    if s != fogtemp_status::Ok {
        message_checks(err.as_ptr(), opts);
        return;
    }
    let mut count = 0usize;
    // SAFETY: as above.
    assert_eq!(unsafe { fogtemp_model_axis_count(&model, &mut count) }, fogtemp_status::Ok);
    let mut axes = Vec::new();
    for i in 0..=count {
        let mut axis = fogtemp_axis { opaque: [0; 24] };
        // SAFETY: as above.
        let s = unsafe { fogtemp_model_axis(&model, i, &mut axis, err.as_mut_ptr()) };
        assert_eq!(s == fogtemp_status::Ok, i < count, "axis {i} of {count}: {s:?}");
        if s == fogtemp_status::Ok {
            axes.push(axis);
        } else {
            message_checks(err.as_ptr(), opts);
        }
    }
    for axis in &axes {
        let mut needed = 0usize;
        // SAFETY: as above.
        assert_eq!(unsafe { fogtemp_axis_blocks_needed(axis, &mut needed) }, fogtemp_status::Ok);
        // Capacity: sometimes one short (must be refused with needed/available), else enough.
        let capacity = if opts & 0x80 != 0 { needed.saturating_sub(1) } else { needed + usize::from(opts & 3) };
        let mut blocks = vec![0.0f32; capacity.max(1)];
        let mut state = fogtemp_state { opaque: [0; 28] };
        // SAFETY: `blocks` outlives `state` in this scope and is used by nothing else.
        let s = unsafe { fogtemp_state_init(axis, &mut state, blocks.as_mut_ptr(), capacity, err.as_mut_ptr()) };
        if capacity < needed {
            assert_eq!(s, fogtemp_status::CapacityTooSmall);
            // SAFETY: `err` was filled by the failed call.
            let e = unsafe { err.assume_init_ref() };
            assert_eq!((e.needed, e.found), (needed as u64, capacity as u64));
            message_checks(err.as_ptr(), opts);
            continue;
        }
        assert_eq!(s, fogtemp_status::Ok, "state for a valid axis");
        let mut t64 = 0u64;
        // The step function this state took since its init or reset: the other is
        // `MIXED_CLOCKS` (true: `fogtemp_step_u32`).
        let mut clock: Option<bool> = None;
        for (k, rec) in samples.chunks_exact(12).take(4096).enumerate() {
            let t = u32::from_le_bytes([rec[0], rec[1], rec[2], rec[3]]);
            let gyro = f32::from_le_bytes([rec[4], rec[5], rec[6], rec[7]]);
            let temp = f32::from_le_bytes([rec[8], rec[9], rec[10], rec[11]]);
            let mut out = fogtemp_output::default();
            // SAFETY: all pointers are live locals; `state` was filled above.
            let s = unsafe {
                match t % 5 {
                    0 => {
                        t64 = t64.wrapping_add(u64::from(t >> 8));
                        fogtemp_step(axis, &mut state, t64, gyro, temp, k % 3 == 0, &mut out)
                    }
                    1 => fogtemp_state_reset(&mut state),
                    2 => {
                        let (mut bias, mut outside) = (0.0f32, false);
                        let _ = fogtemp_evaluate(axis, &mut state, temp, gyro, &mut bias, &mut outside);
                        fogtemp_status::Ok
                    }
                    _ => fogtemp_step_u32(axis, &mut state, t, gyro, temp, k % 2 == 0, &mut out),
                }
            };
            let wanted = match (t % 5, clock) {
                (1, _) => {
                    clock = None;
                    fogtemp_status::Ok
                }
                (2, _) => fogtemp_status::Ok,
                (m, Some(u32_clock)) if u32_clock != (m != 0) => fogtemp_status::MixedClocks,
                (m, _) => {
                    clock = Some(m != 0);
                    fogtemp_status::Ok
                }
            };
            assert_eq!(s, wanted);
            assert!(out.flags & !0x1F == 0, "unknown flag bits {:#x}", out.flags);
            assert!(out.bias_dph.is_finite(), "bias not finite");
        }
        // A state used with another axis of the model: safe, whatever it computes.
        if let Some(other) = axes.last() {
            let mut out = fogtemp_output::default();
            // SAFETY: as above.
            let _ = unsafe { fogtemp_step(other, &mut state, u64::MAX, 1.0, 20.0, true, &mut out) };
        }
    }
}

/// `fogtemp_error_message` into buffers of several lengths: never past the end, always
/// NUL-terminated, the returned length is the full message's.
fn message_checks(err: *const fogtemp_error, opts: u8) {
    let mut full = [0x7Fu8; 512];
    // SAFETY: `err` points to a live `fogtemp_error`; the buffer is a live local.
    let n = unsafe { fogtemp_error_message(err, full.as_mut_ptr().cast(), full.len()) };
    assert!(n < full.len() && full[n] == 0, "message not NUL-terminated at its length");
    for len in [0usize, 1, 2, usize::from(opts % 64)] {
        let mut buf = [0x7Fu8; 80];
        // SAFETY: `len <= buf.len()`.
        let m = unsafe { fogtemp_error_message(err, buf.as_mut_ptr().cast(), len) };
        assert_eq!(m, n);
        if len > 0 {
            let end = n.min(len - 1);
            assert_eq!(buf[end], 0);
            assert_eq!(&buf[..end], &full[..end]);
        }
        assert!(buf[len..].iter().all(|&b| b == 0x7F), "wrote past the buffer");
    }
}

/// Null, misaligned and uninitialised arguments are refused with a status.
fn caller_mistakes() {
    let mut out = fogtemp_output::default();
    let zeroed_axis = fogtemp_axis { opaque: [0; 24] };
    let mut zeroed_state = fogtemp_state { opaque: [0; 28] };
    // SAFETY: null and zeroed structs are what is being tested; all non-null are live locals.
    unsafe {
        assert_eq!(fogtemp_step(ptr::null(), ptr::null_mut(), 0, 0.0, 0.0, true, &mut out), fogtemp_status::NullPointer);
        assert_eq!(
            fogtemp_step(&zeroed_axis, &mut zeroed_state, 0, 0.0, 0.0, true, &mut out),
            fogtemp_status::NotInitialised
        );
        let mut raw = [0u64; 30];
        let misaligned = raw.as_mut_ptr().cast::<u8>().add(4).cast::<fogtemp_state>();
        assert_eq!(fogtemp_state_reset(misaligned), fogtemp_status::Misaligned);
        assert!(!fogtemp_status_message(u32::MAX).is_null());
    }
}
