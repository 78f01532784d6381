//! `Model::from_flash`: a blob followed by erased flash (all 0xFF or all 0x00) is accepted
//! and reports the bytes it uses; any other trailing byte is refused with its offset;
//! `from_bytes` keeps requiring the exact length. And the blob-validation regression the
//! FFI fuzz target found (a `max_gap_s` the tracker cannot time).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)] // test code: a failed expectation is the test failing

use fogtemp_core::wire::{CRC_LEN, FILE_HEADER_LEN};
use fogtemp_core::{Error, Model};

static GOLDEN: &[u8] = include_bytes!("../../../tests/golden/model-v1.fogm");
static FW_MODEL: &[u8] = include_bytes!("../../../examples/firmware-qemu/data/model.fogm");

fn partition(blob: &[u8], fill: u8, len: usize) -> Vec<u8> {
    let mut p = blob.to_vec();
    p.resize(blob.len() + len, fill);
    p
}

#[test]
fn erased_flash_padding_is_accepted_and_the_used_length_reported() {
    for blob in [GOLDEN, FW_MODEL] {
        for fill in [0xFF, 0x00] {
            for pad in [0usize, 1, 3, 4, 4096, 65_536 - blob.len() % 65_536] {
                let p = partition(blob, fill, pad);
                let (model, used) = Model::from_flash(&p).expect("blob + erased flash");
                assert_eq!(used, blob.len());
                let exact = Model::from_bytes(blob).unwrap();
                assert_eq!(model.axis_count(), exact.axis_count());
                assert_eq!(model.input_digest(), exact.input_digest());
                if pad > 0 {
                    // from_bytes still wants the exact length.
                    assert!(matches!(
                        Model::from_bytes(&p),
                        Err(Error::LengthMismatch { field: "total_len", .. })
                    ));
                }
            }
        }
    }
}

#[test]
fn other_trailing_bytes_are_rejected_with_their_offset() {
    let n = GOLDEN.len();
    // A junk first byte.
    let p = partition(GOLDEN, 0x5A, 16);
    assert_eq!(Model::from_flash(&p).map(|_| ()), Err(Error::TrailingBytes { offset: n, fill: 0xFF }));
    // One programmed byte in erased flash, anywhere.
    for fill in [0xFF, 0x00] {
        for at in [0usize, 1, 7, 1000, 4095] {
            let mut p = partition(GOLDEN, fill, 4096);
            p[n + at] = 0x42;
            let r = Model::from_flash(&p).map(|_| ());
            let want_fill = if at == 0 { 0xFF } else { fill };
            assert_eq!(
                r,
                Err(Error::TrailingBytes { offset: n + at, fill: want_fill }),
                "fill {fill:#x} at {at}"
            );
        }
    }
    // 0xFF then 0x00: not one erased pattern.
    let mut p = partition(GOLDEN, 0xFF, 8);
    p.extend([0u8; 8]);
    assert_eq!(Model::from_flash(&p).map(|_| ()), Err(Error::TrailingBytes { offset: n + 8, fill: 0xFF }));
    let e = Error::TrailingBytes { offset: n + 8, fill: 0xFF };
    assert!(e.to_string().contains(&format!("byte {}", n + 8)), "{e}");
}

#[test]
fn a_partition_shorter_than_the_blob_or_not_a_blob_is_refused() {
    let p = &GOLDEN[..GOLDEN.len() - 1];
    assert!(matches!(Model::from_flash(p), Err(Error::Truncated { field: "total_len", .. })));
    assert!(matches!(Model::from_flash(&[0xFF; 4096]), Err(Error::BadMagic)), "erased partition");
    assert!(matches!(Model::from_flash(&[]), Err(Error::Truncated { .. })));
    // A corrupt blob inside the partition is reported as such (the CRC), not as padding.
    let mut p = partition(GOLDEN, 0xFF, 64);
    p[FILE_HEADER_LEN + 20] ^= 1;
    assert!(matches!(Model::from_flash(&p), Err(Error::CrcMismatch { .. })));
}

/// Fuzz regression (ffi_entry_points, 2026-11-23): a blob whose `max_gap_s` is finite and
/// positive but too long for the tracker's microsecond arithmetic (>= 1e15 us) was accepted
/// by `from_bytes` and then refused by every `Compensator::new`. The validator now runs the
/// tracker's own timing check.
#[test]
fn a_gap_the_tracker_cannot_time_is_refused_by_the_validator() {
    const MAX_GAP_S: usize = 20;
    let blob = golden_with_axis0_f32(MAX_GAP_S, 1.0e10);
    assert_eq!(
        Model::from_bytes(&blob).map(|_| ()),
        Err(Error::BadValue { field: "max_gap_s", axis: 0, index: 0 })
    );
}

/// A window too short for its (valid) block count, a block under 1 us (a review's blob
/// with `window_s` = 1.8e-38): the validator names `window_s`, the field changed, not
/// `block_count` (docs/model-format.md, Validation 3).
#[test]
fn a_window_too_short_for_its_blocks_names_the_window() {
    const WINDOW_S: usize = 8;
    let blob = golden_with_axis0_f32(WINDOW_S, 1.8e-38);
    assert_eq!(
        Model::from_bytes(&blob).map(|_| ()),
        Err(Error::BadValue { field: "window_s", axis: 0, index: 0 })
    );
}

/// The golden blob with the f32 at `offset` of axis 0's header set to `value`, its CRC
/// fixed (a blob whose only fault is that value).
fn golden_with_axis0_f32(offset: usize, value: f32) -> Vec<u8> {
    let at = FILE_HEADER_LEN + offset;
    let mut blob = GOLDEN.to_vec();
    blob[at..at + 4].copy_from_slice(&value.to_le_bytes());
    let n = blob.len();
    let crc = fogtemp_core::crc::crc32(&blob[..n - CRC_LEN]);
    blob[n - CRC_LEN..].copy_from_slice(&crc.to_le_bytes());
    blob
}
