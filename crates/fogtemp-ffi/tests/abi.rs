//! The C ABI against the core it wraps: every output of a replay through `fogtemp_step` /
//! `fogtemp_step_u32` equals `fogtemp_core::Compensator`'s bit for bit (tolerance: none);
//! capacity, flash padding, reset, error details and messages; every caller mistake (NULL,
//! misaligned, uninitialised) is a status, never a crash.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    clippy::undocumented_unsafe_blocks,
    clippy::arithmetic_side_effects
)] // test code: a failed expectation is the test failing

use std::ffi::CStr;
use std::mem::{align_of, size_of, MaybeUninit};
use std::ptr;

use fogtemp_core::{Compensator, Model};
use fogtemp_ffi::*;

static FW_MODEL: &[u8] = include_bytes!("../../../examples/firmware-qemu/data/model.fogm");
static FW_TRAJECTORY: &[u8] = include_bytes!("../../../examples/firmware-qemu/data/trajectory.bin");
static GOLDEN: &[u8] = include_bytes!("../../../tests/golden/model-v1.fogm");

fn trajectory() -> Vec<(u64, f32, f32)> {
    FW_TRAJECTORY
        .chunks_exact(16)
        .map(|r| {
            (
                u64::from_le_bytes(r[0..8].try_into().unwrap()),
                f32::from_le_bytes(r[8..12].try_into().unwrap()),
                f32::from_le_bytes(r[12..16].try_into().unwrap()),
            )
        })
        .collect()
}

fn no_error() -> fogtemp_error {
    // SAFETY: fogtemp_error is plain integers.
    unsafe { MaybeUninit::zeroed().assume_init() }
}

/// Model + axis 0 + state through the ABI, with `blocks` as the tracker storage.
fn open(
    blob: &'static [u8],
    axis_index: usize,
    blocks: &mut [f32],
) -> (Box<fogtemp_axis>, Box<fogtemp_state>) {
    let mut model = Box::new(fogtemp_model { opaque: [0; 4] });
    let mut axis = Box::new(fogtemp_axis { opaque: [0; 24] });
    let mut state = Box::new(fogtemp_state { opaque: [0; 28] });
    let mut err = no_error();
    // SAFETY: live pointers; the blob is 'static, `blocks` outlives the returned state in
    // every caller.
    unsafe {
        assert_eq!(
            fogtemp_model_from_bytes(blob.as_ptr(), blob.len(), &mut *model, &mut err),
            fogtemp_status::Ok
        );
        assert_eq!(fogtemp_model_axis(&*model, axis_index, &mut *axis, &mut err), fogtemp_status::Ok);
        let s = fogtemp_state_init(&*axis, &mut *state, blocks.as_mut_ptr(), blocks.len(), &mut err);
        assert_eq!(s, fogtemp_status::Ok);
    }
    (axis, state)
}

fn message(err: &fogtemp_error) -> String {
    let mut buf = [0u8; 256];
    // SAFETY: live pointers.
    let n = unsafe { fogtemp_error_message(err, buf.as_mut_ptr().cast(), buf.len()) };
    CStr::from_bytes_until_nul(&buf).unwrap().to_str().unwrap().chars().take(n).collect()
}

#[test]
fn replay_through_the_abi_equals_the_compensator_bit_for_bit() {
    let model = Model::from_bytes(FW_MODEL).unwrap();
    let mut reference: Compensator<'_, 32> = Compensator::new(&model, 0).unwrap();
    let mut blocks = vec![0.0f32; 20];
    let (axis, mut state) = open(FW_MODEL, 0, &mut blocks);
    let mut blocks32 = vec![0.0f32; 20];
    let (_, mut state32) = open(FW_MODEL, 0, &mut blocks32);
    let records = trajectory();
    let offset = (1u64 << 32) - 90_000_000 - records[0].0; // the u32 timer wraps 90 s in
    for &(t, g, c) in &records {
        let want = reference.step(t, g, (!c.is_nan()).then_some(c));
        let mut out = fogtemp_output::default();
        let mut out32 = fogtemp_output::default();
        // SAFETY: live pointers, states made for `axis`.
        unsafe {
            assert_eq!(fogtemp_step(&*axis, &mut *state, t, g, c, !c.is_nan(), &mut out), fogtemp_status::Ok);
            let t32 = (t + offset) as u32;
            assert_eq!(
                fogtemp_step_u32(&*axis, &mut *state32, t32, g, c, !c.is_nan(), &mut out32),
                fogtemp_status::Ok
            );
        }
        for o in [out, out32] {
            assert_eq!(
                (o.rate_dph.to_bits(), o.bias_dph.to_bits(), o.flags),
                (want.rate_dph.to_bits(), want.bias_dph.to_bits(), want.flags.0),
                "t = {t}"
            );
        }
    }
}

#[test]
fn capacity_too_small_names_needed_and_available() {
    let mut model = fogtemp_model { opaque: [0; 4] };
    let mut axis = fogtemp_axis { opaque: [0; 24] };
    let mut state = fogtemp_state { opaque: [0xEE; 28] };
    let mut err = no_error();
    let mut blocks = [0.0f32; 19];
    let mut needed = 0usize;
    // SAFETY: live pointers.
    unsafe {
        assert_eq!(
            fogtemp_model_from_bytes(FW_MODEL.as_ptr(), FW_MODEL.len(), &mut model, &mut err),
            fogtemp_status::Ok
        );
        assert_eq!(fogtemp_model_axis(&model, 0, &mut axis, &mut err), fogtemp_status::Ok);
        assert_eq!(fogtemp_axis_blocks_needed(&axis, &mut needed), fogtemp_status::Ok);
        assert_eq!(needed, 20);
        let s = fogtemp_state_init(&axis, &mut state, blocks.as_mut_ptr(), blocks.len(), &mut err);
        assert_eq!(s, fogtemp_status::CapacityTooSmall);
    }
    assert_eq!(err.status, fogtemp_status::CapacityTooSmall as u32);
    assert_eq!((err.needed, err.found), (20, 19));
    assert_eq!(message(&err), "feature tracker holds 19 blocks but the model needs 20");
    assert_eq!(state.opaque, [0xEE; 28], "a failed init leaves the state untouched");
    // A capacity no array can have (a negative count cast to size_t) is not "too small":
    // BAD_VALUE naming the largest count of floats a buffer can hold; the blocks are not touched.
    let most = isize::MAX as u64 / 4;
    for capacity in [usize::MAX, usize::MAX / 4, (isize::MAX as usize) / 4 + 1] {
        let mut err = no_error();
        // SAFETY: live pointers; the capacity is refused before `blocks` is used.
        let s = unsafe { fogtemp_state_init(&axis, &mut state, blocks.as_mut_ptr(), capacity, &mut err) };
        assert_eq!(s, fogtemp_status::BadValue);
        assert_eq!(
            (err.status, err.needed, err.found),
            (fogtemp_status::BadValue as u32, most, capacity as u64)
        );
        assert_eq!(
            message(&err),
            format!(
                "a length argument is larger than any buffer can be (PTRDIFF_MAX bytes): at most {most} of its elements, got {capacity}"
            )
        );
    }
    assert_eq!(state.opaque, [0xEE; 28]);
}

#[test]
fn a_zeroed_error_struct_has_no_message() {
    // Zeroing `err` before a call tells whether a failure filled it: a zeroed one (status
    // OK) has no message, as the header says.
    let err = no_error();
    let mut buf = [b'x'; 8];
    // SAFETY: live pointers.
    let n = unsafe { fogtemp_error_message(&err, buf.as_mut_ptr().cast(), buf.len()) };
    assert_eq!(n, 0);
}

#[test]
fn an_axis_past_the_end_is_named_in_good_grammar() {
    let mut model = fogtemp_model { opaque: [0; 4] };
    let mut axis = fogtemp_axis { opaque: [0; 24] };
    let mut err = no_error();
    // SAFETY: live pointers.
    unsafe {
        assert_eq!(
            fogtemp_model_from_bytes(FW_MODEL.as_ptr(), FW_MODEL.len(), &mut model, &mut err),
            fogtemp_status::Ok
        );
        assert_eq!(fogtemp_model_axis(&model, 1, &mut axis, &mut err), fogtemp_status::NoSuchAxis);
    }
    assert_eq!(message(&err), "axis 1 requested but the model has 1 axis, numbered 0");
}

#[test]
fn flash_padding_through_the_abi() {
    for fill in [0xFFu8, 0x00] {
        let mut flash = GOLDEN.to_vec();
        flash.resize(8192, fill);
        let mut model = fogtemp_model { opaque: [0; 4] };
        let (mut used, mut count) = (0usize, 0usize);
        let mut err = no_error();
        // SAFETY: live pointers; `flash` outlives `model` here.
        unsafe {
            let s = fogtemp_model_from_flash(flash.as_ptr(), flash.len(), &mut model, &mut used, &mut err);
            assert_eq!(s, fogtemp_status::Ok);
            assert_eq!(fogtemp_model_axis_count(&model, &mut count), fogtemp_status::Ok);
            // The exact-length reader refuses the same partition.
            let s = fogtemp_model_from_bytes(flash.as_ptr(), flash.len(), &mut model, &mut err);
            assert_eq!(s, fogtemp_status::LengthMismatch);
        }
        assert_eq!((used, count), (GOLDEN.len(), 2));
        flash[GOLDEN.len() + 100] = 0x12;
        // SAFETY: as above; `used` may be NULL.
        let s = unsafe {
            fogtemp_model_from_flash(flash.as_ptr(), flash.len(), &mut model, ptr::null_mut(), &mut err)
        };
        assert_eq!(s, fogtemp_status::TrailingBytes);
        assert_eq!(err.found, (GOLDEN.len() + 100) as u64);
        assert!(message(&err).starts_with(&format!("byte {} after the model blob", GOLDEN.len() + 100)));
    }
}

#[test]
fn reset_through_the_abi_is_power_on() {
    let mut blocks = vec![0.0f32; 20];
    let (axis, mut state) = open(FW_MODEL, 0, &mut blocks);
    let mut fresh_blocks = vec![0.0f32; 20];
    let (_, mut fresh) = open(FW_MODEL, 0, &mut fresh_blocks);
    let records = trajectory();
    let mut out = fogtemp_output::default();
    for &(t, g, c) in records.iter().take(9_000) {
        // SAFETY: live pointers.
        unsafe { fogtemp_step(&*axis, &mut *state, t, g, c, !c.is_nan(), &mut out) };
    }
    assert_ne!(out.bias_dph, 0.0);
    // SAFETY: live pointer.
    assert_eq!(unsafe { fogtemp_state_reset(&mut *state) }, fogtemp_status::Ok);
    for &(t, g, c) in &records {
        let (mut a, mut b) = (fogtemp_output::default(), fogtemp_output::default());
        // SAFETY: live pointers.
        unsafe {
            fogtemp_step(&*axis, &mut *state, t, g, c, !c.is_nan(), &mut a);
            fogtemp_step(&*axis, &mut *fresh, t, g, c, !c.is_nan(), &mut b);
        }
        assert_eq!(
            (a.rate_dph.to_bits(), a.bias_dph.to_bits(), a.flags),
            (b.rate_dph.to_bits(), b.bias_dph.to_bits(), b.flags)
        );
    }
}

#[test]
fn errors_carry_the_axis_and_the_element() {
    let mut model = fogtemp_model { opaque: [0; 4] };
    let mut axis = fogtemp_axis { opaque: [0; 24] };
    let mut err = no_error();
    // Corrupt axis 1's vertex count of the golden model (and fix the CRC): the error names axis 1.
    let mut blob = GOLDEN.to_vec();
    let axis1 = 64 + u32::from_le_bytes(blob[64..68].try_into().unwrap()) as usize;
    blob[axis1 + 40..axis1 + 44].copy_from_slice(&7u32.to_le_bytes()); // outside_policy = 7
    let n = blob.len();
    let crc = fogtemp_core::crc::crc32(&blob[..n - 4]);
    blob[n - 4..].copy_from_slice(&crc.to_le_bytes());
    // SAFETY: live pointers; `blob` outlives the (failed) model.
    unsafe {
        assert_eq!(
            fogtemp_model_from_bytes(blob.as_ptr(), n, &mut model, &mut err),
            fogtemp_status::BadValue
        );
    }
    assert_eq!(err.axis, 1);
    assert_eq!(message(&err), "axis 1: outside_policy[0] holds a value outside its allowed range");
    // NoSuchAxis: needed = axes available, found = requested.
    // SAFETY: live pointers.
    unsafe {
        assert_eq!(
            fogtemp_model_from_bytes(GOLDEN.as_ptr(), GOLDEN.len(), &mut model, &mut err),
            fogtemp_status::Ok
        );
        assert_eq!(fogtemp_model_axis(&model, 5, &mut axis, &mut err), fogtemp_status::NoSuchAxis);
    }
    assert_eq!((err.needed, err.found, err.axis), (2, 5, FOGTEMP_NO_AXIS));
    // A file-header field names no axis and carries the value found.
    let mut blob = GOLDEN.to_vec();
    let at = fogtemp_core::wire::FILE_AXIS_COUNT.start;
    blob[at..at + 2].copy_from_slice(&17u16.to_le_bytes());
    let crc = fogtemp_core::crc::crc32(&blob[..n - 4]);
    blob[n - 4..].copy_from_slice(&crc.to_le_bytes());
    // SAFETY: live pointers; `blob` outlives the (failed) model.
    let status = unsafe { fogtemp_model_from_bytes(blob.as_ptr(), n, &mut model, &mut err) };
    assert_eq!((status, err.axis, err.found), (fogtemp_status::BadValue, FOGTEMP_NO_AXIS, 17));
    assert_eq!(message(&err), "file header: axis_count is 17, outside 1..=16");
    // So does the run-metadata record of format 8 (its byte before the CRC): review31a F9.
    let mut blob = include_bytes!("../../../tests/golden/model-v8.fogm").to_vec();
    let m = blob.len();
    blob[m - 5] = 3;
    let crc = fogtemp_core::crc::crc32(&blob[..m - 4]);
    blob[m - 4..].copy_from_slice(&crc.to_le_bytes());
    // SAFETY: live pointers; `blob` outlives the (failed) model.
    let status = unsafe { fogtemp_model_from_bytes(blob.as_ptr(), m, &mut model, &mut err) };
    assert_eq!((status, err.axis, err.found), (fogtemp_status::BadValue, FOGTEMP_NO_AXIS, 3));
    assert_eq!(message(&err), "run metadata: input_rates is 3, outside its allowed range");
    // A section_len that disagrees with its counts names its axis (needed: the implied length).
    let mut blob = GOLDEN.to_vec();
    let axis1 = 64 + u32::from_le_bytes(blob[64..68].try_into().unwrap()) as usize;
    let stored = u32::from_le_bytes(blob[axis1..axis1 + 4].try_into().unwrap());
    blob[axis1..axis1 + 4].copy_from_slice(&(stored + 8).to_le_bytes());
    let crc = fogtemp_core::crc::crc32(&blob[..n - 4]);
    blob[n - 4..].copy_from_slice(&crc.to_le_bytes());
    // SAFETY: live pointers; `blob` outlives the (failed) model.
    let status = unsafe { fogtemp_model_from_bytes(blob.as_ptr(), n, &mut model, &mut err) };
    assert_eq!(
        (status, err.axis, err.needed, err.found),
        (fogtemp_status::LengthMismatch, 1, u64::from(stored), u64::from(stored) + 8)
    );
}

#[test]
fn caller_mistakes_are_statuses() {
    let mut blocks = vec![0.0f32; 20];
    let (axis, mut state) = open(FW_MODEL, 0, &mut blocks);
    let mut out = fogtemp_output::default();
    let zero_axis = fogtemp_axis { opaque: [0; 24] };
    let mut zero_state = fogtemp_state { opaque: [0; 28] };
    let mut err = no_error();
    let mut raw = [0u64; 40];
    let misaligned_state = raw.as_mut_ptr().cast::<u8>().wrapping_add(4).cast::<fogtemp_state>();
    let misaligned_out = raw.as_mut_ptr().cast::<u8>().wrapping_add(1).cast::<fogtemp_output>();
    let mut model = fogtemp_model { opaque: [0; 4] };
    // SAFETY: the invalid pointers are what is tested; the ABI must refuse them unread.
    unsafe {
        use fogtemp_status::*;
        assert_eq!(fogtemp_step(ptr::null(), &mut *state, 0, 0.0, 0.0, false, &mut out), NullPointer);
        assert_eq!(fogtemp_step(&*axis, ptr::null_mut(), 0, 0.0, 0.0, false, &mut out), NullPointer);
        assert_eq!(fogtemp_step(&*axis, &mut *state, 0, 0.0, 0.0, false, ptr::null_mut()), NullPointer);
        assert_eq!(fogtemp_step(&*axis, &mut *state, 0, 0.0, 0.0, false, misaligned_out), Misaligned);
        assert_eq!(fogtemp_step(&*axis, misaligned_state, 0, 0.0, 0.0, false, &mut out), Misaligned);
        assert_eq!(fogtemp_step(&zero_axis, &mut *state, 0, 0.0, 0.0, false, &mut out), NotInitialised);
        assert_eq!(fogtemp_step(&*axis, &mut zero_state, 0, 0.0, 0.0, false, &mut out), NotInitialised);
        assert_eq!(fogtemp_step_u32(&*axis, &mut zero_state, 0, 0.0, 0.0, false, &mut out), NotInitialised);
        assert_eq!(fogtemp_state_reset(ptr::null_mut()), NullPointer);
        assert_eq!(fogtemp_state_reset(&mut zero_state), NotInitialised);
        // The axis struct is not a state: its tag differs.
        assert_eq!(fogtemp_state_reset((&*axis as *const fogtemp_axis).cast_mut().cast()), NotInitialised);
        assert_eq!(fogtemp_model_from_bytes(ptr::null(), 10, &mut model, &mut err), NullPointer);
        assert_eq!(err.status, NullPointer as u32);
        assert_eq!(message(&err), "a required pointer is NULL");
        // A length no buffer can have (a negative length cast to size_t) names itself; the
        // pointer is not read.
        assert_eq!(fogtemp_model_from_bytes(GOLDEN.as_ptr(), usize::MAX, &mut model, &mut err), BadValue);
        assert_eq!((err.status, err.needed, err.found), (BadValue as u32, isize::MAX as u64, u64::MAX));
        assert_eq!(
            message(&err),
            format!(
                "a length argument is larger than any buffer can be (PTRDIFF_MAX bytes): at most {} of its elements, got {}",
                isize::MAX,
                u64::MAX
            )
        );
        let mut used = 0usize;
        assert_eq!(
            fogtemp_model_from_flash(GOLDEN.as_ptr(), usize::MAX, &mut model, &mut used, &mut err),
            BadValue
        );
        assert_eq!(err.found, u64::MAX);
        assert_eq!(
            fogtemp_model_from_bytes(GOLDEN.as_ptr(), GOLDEN.len(), ptr::null_mut(), ptr::null_mut()),
            NullPointer
        );
        assert_eq!(
            fogtemp_model_axis(&model, 0, &mut *Box::new(fogtemp_axis { opaque: [0; 24] }), &mut err),
            NotInitialised
        );
        let mut n = 0usize;
        assert_eq!(fogtemp_axis_blocks_needed(&zero_axis, &mut n), NotInitialised);
        assert_eq!(fogtemp_axis_blocks_needed(&*axis, ptr::null_mut()), NullPointer);
        assert_eq!(fogtemp_state_init(&*axis, &mut zero_state, ptr::null_mut(), 20, &mut err), NullPointer);
        let odd_blocks = raw.as_mut_ptr().cast::<u8>().wrapping_add(2).cast::<f32>();
        assert_eq!(fogtemp_state_init(&*axis, &mut zero_state, odd_blocks, 20, &mut err), Misaligned);
        let mut bias = 0.0f32;
        assert_eq!(fogtemp_evaluate(&*axis, &mut *state, 25.0, 0.1, &mut bias, ptr::null_mut()), Ok);
        assert_eq!(
            fogtemp_evaluate(&*axis, &mut *state, f32::NAN, 0.1, &mut bias, ptr::null_mut()),
            NonFiniteSample
        );
        assert_eq!(
            fogtemp_evaluate(&*axis, &mut *state, 25.0, 0.1, ptr::null_mut(), ptr::null_mut()),
            NullPointer
        );
        assert_eq!(fogtemp_error_message(ptr::null(), ptr::null_mut(), 0), 0);
    }
}

#[test]
fn error_message_truncates_and_always_terminates() {
    let mut err = no_error();
    let mut model = fogtemp_model { opaque: [0; 4] };
    let junk = [0u8; 100];
    // SAFETY: live pointers.
    let s = unsafe { fogtemp_model_from_bytes(junk.as_ptr(), junk.len(), &mut model, &mut err) };
    assert_eq!(s, fogtemp_status::BadMagic);
    let full = message(&err);
    assert_eq!(full, "not a fogtemp model blob (magic is not \"FOGM\")");
    for len in 0..full.len() + 3 {
        let mut buf = vec![0x7Fu8; len + 4];
        // SAFETY: `buf` has `len + 4` bytes; only `len` are offered.
        let n = unsafe { fogtemp_error_message(&err, buf.as_mut_ptr().cast(), len) };
        assert_eq!(n, full.len());
        if len > 0 {
            let k = full.len().min(len - 1);
            assert_eq!(&buf[..k], &full.as_bytes()[..k]);
            assert_eq!(buf[k], 0);
        }
        assert!(buf[len..].iter().all(|&b| b == 0x7F), "wrote past len {len}");
    }
    // No message (a zeroed or NULL err): the empty string, not what the buffer held
    // (review23a F4), and nothing past it.
    let zeroed = no_error();
    for err in [&zeroed as *const fogtemp_error, ptr::null()] {
        let mut buf = [b'X'; 16];
        // SAFETY: `buf` is writable for 8 of its bytes; `err` is NULL or a live zeroed struct.
        let n = unsafe { fogtemp_error_message(err, buf.as_mut_ptr().cast(), 8) };
        assert_eq!((n, buf[0]), (0, 0));
        assert!(buf[1..].iter().all(|&b| b == b'X'));
    }
    // Every status has a static message; unknown codes too.
    for code in 0..=20u32 {
        // SAFETY: the ABI returns a static NUL-terminated string, never NULL.
        let m = unsafe { CStr::from_ptr(fogtemp_status_message(code)) };
        assert!(!m.to_bytes().is_empty());
    }
    // SAFETY: as above.
    assert_eq!(unsafe { CStr::from_ptr(fogtemp_status_message(999)) }.to_str().unwrap(), "unknown status");
}

#[test]
fn layout_matches_the_header() {
    let mut layout = [0usize; 8];
    // SAFETY: live pointer.
    assert_eq!(unsafe { fogtemp_layout(&mut layout) }, fogtemp_status::Ok);
    assert_eq!(
        layout,
        [
            size_of::<fogtemp_model>(),
            align_of::<fogtemp_model>(),
            size_of::<fogtemp_axis>(),
            align_of::<fogtemp_axis>(),
            size_of::<fogtemp_state>(),
            align_of::<fogtemp_state>(),
            size_of::<fogtemp_error>(),
            align_of::<fogtemp_error>(),
        ]
    );
    assert_eq!(layout, [32, 8, 192, 8, 224, 8, 80, 8]);
}

/// A state stepped with an axis of other feature settings than the one it was initialised
/// for is refused (`STATE_AXIS_MISMATCH`), its output and state untouched; with its own
/// axis it steps.
#[test]
fn a_state_belongs_to_its_axis() {
    let mut fw_blocks = vec![0.0f32; 20];
    let (fw_axis, mut fw_state) = open(FW_MODEL, 0, &mut fw_blocks);
    let mut golden_blocks = vec![0.0f32; 256];
    let (golden_axis, _) = open(GOLDEN, 0, &mut golden_blocks);
    let mut out = fogtemp_output { rate_dph: 7.0, bias_dph: 7.0, flags: 7 };
    // SAFETY: live pointers.
    let status = unsafe { fogtemp_step(&*golden_axis, &mut *fw_state, 1_000, 1.0, 25.0, true, &mut out) };
    assert_eq!(status, fogtemp_status::StateAxisMismatch);
    assert_eq!((out.rate_dph, out.bias_dph, out.flags), (7.0, 7.0, 7), "output untouched");
    // SAFETY: live pointers.
    let status = unsafe { fogtemp_step_u32(&*golden_axis, &mut *fw_state, 1_000, 1.0, 25.0, true, &mut out) };
    assert_eq!(status, fogtemp_status::StateAxisMismatch);
    // SAFETY: live pointers.
    let status = unsafe { fogtemp_step(&*fw_axis, &mut *fw_state, 1_000, 1.0, 25.0, true, &mut out) };
    assert_eq!(status, fogtemp_status::Ok);
    let (mut bias, mut outside) = (7.0f32, true);
    // SAFETY: live pointers.
    let status =
        unsafe { fogtemp_evaluate(&*golden_axis, &mut *fw_state, 25.0, 0.1, &mut bias, &mut outside) };
    assert_eq!(status, fogtemp_status::StateAxisMismatch);
    assert_eq!((bias, outside), (7.0, true), "outputs untouched");
    // SAFETY: a static C string.
    let text = unsafe { CStr::from_ptr(fogtemp_status_message(fogtemp_status::StateAxisMismatch as u32)) };
    assert!(text.to_str().unwrap().contains("another axis"));
}

/// Two axes of one model with equal feature settings: a state belongs to the axis number
/// it was initialised for (`STATE_AXIS_MISMATCH` with the other), in `fogtemp_step` and
/// `fogtemp_evaluate`.
#[test]
fn a_state_belongs_to_its_axis_number_when_the_settings_agree() {
    let blob = twin_axes_blob();
    let blob: &'static [u8] = Box::leak(blob.into_boxed_slice());
    let (mut blocks0, mut blocks1) = (vec![0.0f32; 8], vec![0.0f32; 8]);
    let (axis0, mut state0) = open(blob, 0, &mut blocks0);
    let (axis1, _state1) = open(blob, 1, &mut blocks1);
    let mut out = fogtemp_output { rate_dph: 7.0, bias_dph: 7.0, flags: 7 };
    // SAFETY: live pointers.
    let status = unsafe { fogtemp_step(&*axis1, &mut *state0, 1_000, 1.0, 25.0, true, &mut out) };
    assert_eq!(status, fogtemp_status::StateAxisMismatch);
    assert_eq!((out.rate_dph, out.bias_dph, out.flags), (7.0, 7.0, 7), "output untouched");
    let mut bias = 7.0f32;
    // SAFETY: live pointers; `outside_hull` may be NULL.
    let status = unsafe { fogtemp_evaluate(&*axis1, &mut *state0, 25.0, 0.1, &mut bias, ptr::null_mut()) };
    assert_eq!(status, fogtemp_status::StateAxisMismatch);
    // SAFETY: live pointers.
    let status = unsafe { fogtemp_step(&*axis0, &mut *state0, 1_000, 1.0, 25.0, true, &mut out) };
    assert_eq!(status, fogtemp_status::Ok);
}

/// `fogtemp_evaluate` where the model's value overflows f32 (a cubic term of 3e38 deg/h at
/// x = 10, through the real writer): `NON_FINITE_VALUE`, the bias unwritten; where it is
/// finite (x = 0.5), `OK` with the value.
#[test]
fn a_value_beyond_f32_is_a_status_not_infinity() {
    use fogtemp_core::PolyTerm;
    let mut axis = poly_axis();
    axis.poly = vec![
        PolyTerm { temp_power: 0, rate_power: 0, coefficient_dph: 1.0 },
        PolyTerm { temp_power: 3, rate_power: 0, coefficient_dph: 3.0e38 },
    ];
    let file = fogtemp_cal::ModelFile {
        tool_version: "abi test".into(),
        input_digest: [0; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    };
    let blob: &'static [u8] = Box::leak(fogtemp_cal::encode(&file).unwrap().into_boxed_slice());
    let mut blocks = vec![0.0f32; 8];
    let (axis, mut state) = open(blob, 0, &mut blocks);
    let mut bias = 7.0f32;
    // SAFETY: live pointers; `outside_hull` may be NULL. x = (420 - 20) / 40 = 10.
    let status = unsafe { fogtemp_evaluate(&*axis, &mut *state, 420.0, 0.0, &mut bias, ptr::null_mut()) };
    assert_eq!((status, bias), (fogtemp_status::NonFiniteValue, 7.0));
    // SAFETY: as above; x = 0.5.
    let status = unsafe { fogtemp_evaluate(&*axis, &mut *state, 40.0, 0.0, &mut bias, ptr::null_mut()) };
    assert_eq!((status, bias), (fogtemp_status::Ok, 1.0 + 3.0e38 * 0.125));
}

/// A model of two polynomial axes with equal feature settings, through the real writer:
/// bias 0.1 + 0.01 x deg/h on both.
fn twin_axes_blob() -> Vec<u8> {
    use fogtemp_cal::{encode, ModelFile};
    let axis = poly_axis();
    let file = ModelFile {
        tool_version: "abi test".into(),
        input_digest: [0; 32],
        axes: vec![axis.clone(), axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    };
    encode(&file).unwrap()
}

/// One polynomial axis, bias 0.1 + 0.01 x deg/h, x = (T - 20) / 40.
fn poly_axis() -> fogtemp_cal::AxisModel {
    use fogtemp_core::{
        AxisProvenance, FeatureSettings, Normalisation, OutsidePolicy, PolyOutside, PolyTerm,
    };
    fogtemp_cal::AxisModel {
        features: FeatureSettings { window_s: 8.0, block_count: 8, min_blocks: 2, max_gap_s: 5.0 },
        normalisation: Normalisation {
            temp_offset_c: 20.0,
            temp_scale_per_c: 1.0 / 40.0,
            rate_offset_c_per_min: 0.0,
            rate_scale_per_c_per_min: 1.0,
        },
        outside_policy: OutsidePolicy::NearestHull,
        poly: vec![
            PolyTerm { temp_power: 0, rate_power: 0, coefficient_dph: 0.1 },
            PolyTerm { temp_power: 1, rate_power: 0, coefficient_dph: 0.01 },
        ],
        mesh: None,
        provenance: AxisProvenance {
            fit_point_count: 0,
            residual_rms_dph: 0.0,
            residual_max_abs_dph: 0.0,
            temp_min_c: 0.0,
            temp_max_c: 40.0,
            rate_min_c_per_min: -1.0,
            rate_max_c_per_min: 1.0,
        },
        region: Vec::new(),
        poly_outside: PolyOutside::Extrapolate,
    }
}

/// `fogtemp_step` and `fogtemp_step_u32` on one state: the second kind is
/// `MIXED_CLOCKS`, the output and state untouched, until a reset; after it the other kind
/// steps as on a fresh state.
#[test]
fn one_state_takes_one_clock_until_a_reset() {
    let mut blocks = vec![0.0f32; 20];
    let (axis, mut state) = open(FW_MODEL, 0, &mut blocks);
    let mut twin_blocks = vec![0.0f32; 20];
    let (_, mut twin) = open(FW_MODEL, 0, &mut twin_blocks);
    let mut fresh_blocks = vec![0.0f32; 20];
    let (_, mut fresh) = open(FW_MODEL, 0, &mut fresh_blocks);
    let records = trajectory();
    /// One sample through `state` and `twin`, with equal outputs.
    fn step_both(
        axis: &fogtemp_axis,
        state: &mut fogtemp_state,
        twin: &mut fogtemp_state,
        (t, g, c): (u64, f32, f32),
    ) {
        let (mut out, mut twin_out) = (fogtemp_output::default(), fogtemp_output::default());
        // SAFETY: live pointers.
        unsafe {
            assert_eq!(fogtemp_step(axis, state, t, g, c, !c.is_nan(), &mut out), fogtemp_status::Ok);
            assert_eq!(fogtemp_step(axis, twin, t, g, c, !c.is_nan(), &mut twin_out), fogtemp_status::Ok);
        }
        assert_eq!(
            (out.rate_dph.to_bits(), out.bias_dph.to_bits(), out.flags),
            (twin_out.rate_dph.to_bits(), twin_out.bias_dph.to_bits(), twin_out.flags)
        );
    }
    for &record in records.iter().take(3_000) {
        step_both(&axis, &mut state, &mut twin, record);
    }
    let (t, g, c) = records[3_000];
    let mut mixed = fogtemp_output { rate_dph: 7.0, bias_dph: 7.0, flags: 7 };
    // SAFETY: live pointers.
    let status = unsafe { fogtemp_step_u32(&*axis, &mut *state, t as u32, g, c, true, &mut mixed) };
    assert_eq!(status, fogtemp_status::MixedClocks);
    assert_eq!((mixed.rate_dph, mixed.bias_dph, mixed.flags), (7.0, 7.0, 7), "output untouched");
    // The state is untouched: it goes on as its twin, which was never given the 32-bit call.
    for &record in &records[3_000..6_000] {
        step_both(&axis, &mut state, &mut twin, record);
    }
    let mut next = fogtemp_output::default();
    let mut next_fresh = fogtemp_output::default();
    // SAFETY: live pointer.
    assert_eq!(unsafe { fogtemp_state_reset(&mut *state) }, fogtemp_status::Ok);
    for &(t, g, c) in records.iter().take(3_000) {
        // SAFETY: live pointers.
        unsafe {
            assert_eq!(
                fogtemp_step_u32(&*axis, &mut *state, t as u32, g, c, !c.is_nan(), &mut next),
                fogtemp_status::Ok
            );
            assert_eq!(
                fogtemp_step_u32(&*axis, &mut *fresh, t as u32, g, c, !c.is_nan(), &mut next_fresh),
                fogtemp_status::Ok
            );
        }
        assert_eq!(
            (next.rate_dph.to_bits(), next.bias_dph.to_bits(), next.flags),
            (next_fresh.rate_dph.to_bits(), next_fresh.bias_dph.to_bits(), next_fresh.flags)
        );
    }
    // SAFETY: a static C string.
    let text = unsafe { CStr::from_ptr(fogtemp_status_message(fogtemp_status::MixedClocks as u32)) };
    assert!(text.to_str().unwrap().contains("fogtemp_step_u32"));
}

/// `fogtemp_model_axis_units` gives back the conversions the writer stored (review33a F2):
/// deg/s with an extra scale 0.5 on axis 0, a temperature in counts of 1/16 C with an offset
/// on axis 1 (the oracle: the writer's own numbers, exactly); a model before format 4 says
/// none is recorded, with the identity; an axis past the end and caller mistakes are statuses.
#[test]
fn axis_units_are_the_ones_the_writer_stored() {
    use fogtemp_cal::{blob::ColumnNames, encode, ModelFile};
    let axes = vec![poly_axis(), poly_axis()];
    let columns = vec![
        ColumnNames { gyro: "gx_dps".into(), gyro_dph_per_unit: 3600.0 * 0.5, ..ColumnNames::default() },
        ColumnNames {
            temp: "t_counts".into(),
            temp_c_per_unit: 0.0625,
            temp_offset_c: -40.0,
            ..ColumnNames::default()
        },
    ];
    let file = ModelFile {
        tool_version: "abi test".into(),
        input_digest: [0; 32],
        axes,
        columns,
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    };
    let blob: &'static [u8] = Box::leak(encode(&file).unwrap().into_boxed_slice());
    let units_of = |blob: &'static [u8], index: usize| {
        let mut model = fogtemp_model { opaque: [0; 4] };
        let mut units = fogtemp_axis_units::default();
        // SAFETY: live pointers; the blob is 'static.
        unsafe {
            assert_eq!(
                fogtemp_model_from_bytes(blob.as_ptr(), blob.len(), &mut model, ptr::null_mut()),
                fogtemp_status::Ok
            );
            let status = fogtemp_model_axis_units(&model, index, &mut units);
            (status, units)
        }
    };
    let ok = |gyro, temp, offset, recorded| {
        (
            fogtemp_status::Ok,
            fogtemp_axis_units {
                gyro_dph_per_unit: gyro,
                temp_c_per_unit: temp,
                temp_offset_c: offset,
                recorded,
            },
        )
    };
    assert_eq!(units_of(blob, 0), ok(1800.0, 1.0, 0.0, 1));
    assert_eq!(units_of(blob, 1), ok(1.0, 0.0625, -40.0, 1));
    assert_eq!(units_of(blob, 2), (fogtemp_status::NoSuchAxis, fogtemp_axis_units::default()));
    assert_eq!(units_of(GOLDEN, 0), ok(1.0, 1.0, 0.0, 0));
    let mut units = fogtemp_axis_units::default();
    let unfilled = fogtemp_model { opaque: [0; 4] };
    // SAFETY: live pointers, or NULL as the mistake under test.
    unsafe {
        assert_eq!(fogtemp_model_axis_units(&unfilled, 0, &mut units), fogtemp_status::NotInitialised);
        assert_eq!(fogtemp_model_axis_units(ptr::null(), 0, &mut units), fogtemp_status::NullPointer);
    }
    let mut model = fogtemp_model { opaque: [0; 4] };
    // SAFETY: live pointers, or NULL as the mistake under test.
    unsafe {
        assert_eq!(
            fogtemp_model_from_bytes(blob.as_ptr(), blob.len(), &mut model, ptr::null_mut()),
            fogtemp_status::Ok
        );
        assert_eq!(fogtemp_model_axis_units(&model, 0, ptr::null_mut()), fogtemp_status::NullPointer);
    }
}
