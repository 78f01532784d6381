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

pub fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}
