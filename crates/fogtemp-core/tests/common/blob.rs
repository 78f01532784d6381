//! Blob helpers shared by the core's reader tests (`crates/fogtemp-core/tests/blob_format.rs`)
//! and the workspace root's writer tests (`tests/blob_format.rs`, which includes this file with
//! `#[path]`): byte access, CRC and length patching, an exerciser of every read-side API, and
//! the names and queries of the committed golden files. Uses only `fogtemp-core` (and
//! `crc32fast`, `rand`, `rand_xoshiro`), never the writer.
#![allow(dead_code)]

use fogtemp_core::wire::{CRC_LEN, FILE_HEADER_LEN, FILE_TOTAL_LEN};
use fogtemp_core::{Location, Model, WalkHint};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

// ---------------------------------------------------------------------------------------------
// Bytes
// ---------------------------------------------------------------------------------------------

pub fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

pub fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

pub fn put_u16(b: &mut [u8], at: usize, v: u16) {
    b[at..at + 2].copy_from_slice(&v.to_le_bytes());
}

pub fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

pub fn put_f32(b: &mut [u8], at: usize, v: f32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// Rewrites the CRC trailer to match the bytes, so that a mutant gets past the integrity
/// check and exercises the validation behind it.
pub fn fix_crc(b: &mut [u8]) {
    if b.len() < FILE_HEADER_LEN + CRC_LEN {
        return;
    }
    let body = b.len() - CRC_LEN;
    let crc = crc32fast::hash(&b[..body]);
    b[body..].copy_from_slice(&crc.to_le_bytes());
}

/// As [`fix_crc`], after rewriting `total_len` to the buffer length.
pub fn fix_len_and_crc(b: &mut [u8]) {
    if b.len() >= FILE_HEADER_LEN + CRC_LEN {
        let len = b.len() as u32;
        put_u32(b, FILE_TOTAL_LEN.start, len);
    }
    fix_crc(b);
}

// ---------------------------------------------------------------------------------------------
// Every read-side API
// ---------------------------------------------------------------------------------------------

/// Exercises every read-side API of an accepted model at many queries and hints. Returns the
/// number of evaluations. Must never panic, whatever the model.
pub fn exercise(model: &Model<'_>, seed: u64) -> usize {
    let mut r = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut n = 0;
    let _ = (model.tool_version(), model.input_digest(), model.format_version());
    assert!(model.axis(model.axis_count()).is_err());
    // The log records (versions 4 to 7): every accessor, one past the last entry too.
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
    for i in 0..model.axis_count() {
        let axis = model.axis(i).expect("an accepted model hands out each of its axes");
        let mut queries: Vec<(f32, f32)> =
            (0..24).map(|_| (r.gen_range(-100.0f32..150.0), r.gen_range(-1.0f32..2.0))).collect();
        queries.extend([
            (f32::MAX, f32::MAX),
            (f32::MIN, 0.0),
            (0.0, f32::MIN),
            (1.0e30, -1.0e30),
            (f32::NAN, 0.0),
            (0.0, f32::INFINITY),
            (-0.0, f32::MIN_POSITIVE),
        ]);
        let mut hint = WalkHint(r.gen());
        for &(t, rate) in &queries {
            let _ = axis.evaluate(t, rate, &mut hint);
            n += 1;
        }
        if let Some(poly) = &axis.poly {
            let _ = (poly.len(), poly.is_empty(), poly.terms().count(), poly.evaluate(1.0e6, -1.0e6));
        }
        if let Some(mesh) = &axis.mesh {
            for &(t, rate) in &queries {
                let (x, y) = axis.normalisation.apply(t, rate);
                for h in [0, 1, mesh.triangle_count() / 2, mesh.triangle_count(), u32::MAX, r.gen()] {
                    let mut hint = WalkHint(h);
                    if let Ok(loc) = mesh.locate(x, y, &mut hint) {
                        assert!(hint.0 < mesh.triangle_count(), "hint left in range");
                        let (Location::Inside { triangle, .. } | Location::Outside { triangle }) = loc;
                        assert!(triangle < mesh.triangle_count());
                    }
                    let _ = mesh.interpolate(x, y, &mut hint);
                    n += 1;
                }
                let _ = (mesh.locate_by_scan(x, y), mesh.nearest_hull_value(x, y));
            }
            for h in 0..=mesh.hull_edge_count() {
                let _ = (mesh.hull_edge(h), mesh.hull_edge_vertices(h));
            }
            let _ = (
                mesh.vertex(u32::MAX),
                mesh.triangle(u32::MAX),
                mesh.hull_edge(u32::MAX),
                mesh.outside_policy(),
            );
        }
    }
    n
}

// ---------------------------------------------------------------------------------------------
// The golden files of format versions 1, 2 and 3 (`tests/golden/` of the workspace root)
// ---------------------------------------------------------------------------------------------

pub const GOLDEN_BLOB: &str = "model-v1.fogm";
pub const GOLDEN_CSV: &str = "model-v1.expected.csv";
/// The golden files of format version 2 (axis 1 carries a calibrated region, polynomial held at
/// its boundary), written by today's writer.
pub const GOLDEN_V2_BLOB: &str = "model-v2.fogm";
pub const GOLDEN_V2_CSV: &str = "model-v2.expected.csv";
/// The golden files of format version 3: the version-2 golden model with axis 0's mesh
/// continued by stored hull gradients (`outside_policy = 3`).
pub const GOLDEN_V3_BLOB: &str = "model-v3.fogm";
pub const GOLDEN_V3_CSV: &str = "model-v3.expected.csv";
/// The golden files of format version 4: the version-3 golden model with the log columns of
/// each axis recorded (the column-names section).
pub const GOLDEN_V4_BLOB: &str = "model-v4.fogm";
pub const GOLDEN_V4_CSV: &str = "model-v4.expected.csv";
/// What the version-4 golden model records per axis: gyro and temperature column, deg/h per
/// gyro unit, deg C per temperature unit, temperature offset (axis 1: a gyro in deg/s read
/// at half scale, a temperature in raw counts of 1/256 C from -231 C).
pub const GOLDEN_V4_COLUMNS: [(&str, &str, f64, f64, f64); 2] =
    [("gyro_x", "temp_c", 1.0, 1.0, 0.0), ("Drehrate Y (°/h)", "T_y", 1800.0, 0.00390625, -231.0)];
/// The golden files of format version 5: the version-4 golden model with its logs' time
/// recorded (the log-time record at the end of the column-names section).
pub const GOLDEN_V5_BLOB: &str = "model-v5.fogm";
pub const GOLDEN_V5_CSV: &str = "model-v5.expected.csv";
/// What the version-5 golden model records of its logs' time: time column, date column, unit
/// code (1: milliseconds), sample rate (0: the log has a time column).
pub const GOLDEN_V5_TIME: (&str, &str, u8, f64) = ("Zeit [ms]", "", 1, 0.0);
/// The golden files of format version 6: the version-5 golden model with the log-reading
/// record (the decimal mark and each calibration log's digest) after the log-time record.
pub const GOLDEN_V6_BLOB: &str = "model-v6.fogm";
pub const GOLDEN_V6_CSV: &str = "model-v6.expected.csv";
/// What the version-6 golden model records of its logs' reading: a decimal comma, and the
/// first 8 bytes of the SHA-256 of two logs, "abc" (FIPS 180-2's example,
/// ba7816bf8f01cfea...) and an empty file (e3b0c44298fc1c14...).
pub const GOLDEN_V6_READING: (bool, [[u8; 8]; 2]) = (
    true,
    [[0xba, 0x78, 0x16, 0xbf, 0x8f, 0x01, 0xcf, 0xea], [0xe3, 0xb0, 0xc4, 0x42, 0x98, 0xfc, 0x1c, 0x14]],
);
/// The golden files of format version 7: the version-6 golden model with the log-shape record
/// after the log-reading record.
pub const GOLDEN_V7_BLOB: &str = "model-v7.fogm";
pub const GOLDEN_V7_CSV: &str = "model-v7.expected.csv";
/// What the version-7 golden model records of its logs' shape: 2 lines skipped, fields
/// separated by `;`, comment lines starting with `//`, and no header row, the columns named in
/// order.
pub const GOLDEN_V7_SHAPE: (u32, u8, &str, [&str; 5]) =
    (2, b';', "//", ["Zeit [ms]", "gyro_x", "temp_c", "Drehrate Y (°/h)", "T_y"]);
/// The golden files of format version 8: the version-6 golden model (logs of the default
/// shape) whose fit took each run's input rate off its gyro: the default log-shape record
/// written out, then the run-metadata record (code 1).
pub const GOLDEN_V8_BLOB: &str = "model-v8.fogm";
pub const GOLDEN_V8_CSV: &str = "model-v8.expected.csv";
pub const GOLDEN_HEADER: &str = "axis,temp_c,rate_c_per_min,value_dph_bits,outside";

/// The input digest the golden model (and the root's three-axis model) carries.
pub fn core_digest() -> [u8; 32] {
    let mut d = [0u8; 32];
    for (i, b) in d.iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(37).wrapping_add(5);
    }
    d
}

/// The golden query points: axis 0 on a 6 x 5 grid reaching outside the hull, axis 1 on 5 x 4.
pub fn golden_queries() -> Vec<(usize, f32, f32)> {
    let mut q = Vec::new();
    for temp_c in [-70.0f32, -35.5, -2.25, 21.0, 47.75, 95.0] {
        for rate in [-0.25f32, 0.125, 0.4, 0.7, 1.3] {
            q.push((0, temp_c, rate));
        }
    }
    for temp_c in [-40.0f32, -10.0, 15.0, 40.0, 85.0] {
        for rate in [0.0f32, 0.2, 0.45, 0.9] {
            q.push((1, temp_c, rate));
        }
    }
    q
}
