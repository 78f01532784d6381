//! Shared fixtures of the core's own tests: nothing here uses `fogtemp-cal` (the core's tests
//! build without the writer; tests that need it live in the workspace root's `tests/`).
#![allow(dead_code, missing_docs)]

pub mod blob;

use fogtemp_core::FeatureSettings;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

/// Paper defaults: 100 s window of 100 one-second blocks.
pub const FEATURES: FeatureSettings =
    FeatureSettings { window_s: 100.0, block_count: 100, min_blocks: 10, max_gap_s: 5.0 };

/// A one-axis file header of format `version` (lengths and CRC patched later, e.g. by
/// [`blob::fix_len_and_crc`]).
pub fn one_axis_file_header(version: u16) -> Vec<u8> {
    use fogtemp_core::wire::*;
    let mut b = vec![0u8; FILE_HEADER_LEN];
    b[FILE_MAGIC].copy_from_slice(&MAGIC);
    blob::put_u16(&mut b, FILE_VERSION.start, version);
    blob::put_u16(&mut b, FILE_HEADER_LEN_FIELD.start, FILE_HEADER_LEN as u16);
    blob::put_u16(&mut b, FILE_AXIS_COUNT.start, 1);
    b
}

/// An axis header of `kind` whose section is `section_len` bytes, with [`FEATURES`] and the
/// identity normalisation (x = T, y = dT/dt); the counts are the caller's to set.
pub fn axis_header(section_len: usize, kind: u16) -> Vec<u8> {
    use fogtemp_core::wire::*;
    let mut h = vec![0u8; AXIS_HEADER_LEN];
    blob::put_u32(&mut h, AXIS_SECTION_LEN.start, section_len as u32);
    blob::put_u16(&mut h, AXIS_MODEL_KIND.start, kind);
    blob::put_f32(&mut h, AXIS_WINDOW_S.start, FEATURES.window_s);
    blob::put_u32(&mut h, AXIS_BLOCK_COUNT.start, FEATURES.block_count);
    blob::put_u32(&mut h, AXIS_MIN_BLOCKS.start, FEATURES.min_blocks);
    blob::put_f32(&mut h, AXIS_MAX_GAP_S.start, FEATURES.max_gap_s);
    blob::put_f32(&mut h, AXIS_TEMP_SCALE_PER_C.start, 1.0);
    blob::put_f32(&mut h, AXIS_RATE_SCALE_PER_C_PER_MIN.start, 1.0);
    h
}

pub fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}
