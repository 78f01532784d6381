//! The model blob, format versions 1, 2 and 3, from the reader's side alone: the core's CRC against
//! `crc32fast`, the committed golden bytes read and evaluated bit-exactly, and arbitrary or
//! once-crashing input rejected or evaluated without panics.
//!
//! The writer's side (round trip through `fogtemp_cal::encode`, layout, the golden blob
//! reproduced by today's writer, corruptions of written blobs) is tested in the workspace
//! root's `tests/blob_format.rs`, which needs `fogtemp-cal`.
//!
//! The golden files live in the workspace root's `tests/golden/` (the root's writer test
//! compares them with today's writer and the fuzz seed corpus starts from them). They are
//! written only by the root test, with `FOGTEMP_BLESS=1 cargo test --test blob_format golden`
//! from the workspace root; see that file for when blessing is legitimate. The expected values
//! in the CSV were evaluated by the core reader when blessed, so this test checks that today's
//! reader still reads the version-1 bytes and gives the same f32 bits.
#![allow(clippy::expect_used, clippy::unwrap_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;

use common::blob::{
    core_digest, exercise, fix_len_and_crc, golden_queries, put_u16, put_u32, u32_at, GOLDEN_BLOB,
    GOLDEN_CSV, GOLDEN_HEADER, GOLDEN_V2_BLOB, GOLDEN_V2_CSV, GOLDEN_V3_BLOB, GOLDEN_V3_CSV, GOLDEN_V4_BLOB,
    GOLDEN_V4_COLUMNS, GOLDEN_V4_CSV, GOLDEN_V5_BLOB, GOLDEN_V5_CSV, GOLDEN_V5_TIME, GOLDEN_V6_BLOB,
    GOLDEN_V6_CSV, GOLDEN_V6_READING, GOLDEN_V7_BLOB, GOLDEN_V7_CSV, GOLDEN_V7_SHAPE, GOLDEN_V8_BLOB,
    GOLDEN_V8_CSV,
};
use common::rng;
use fogtemp_core::wire::*;
use fogtemp_core::{
    Error, InputRates, LogDelimiter, LogTimeUnit, Model, OutsidePolicy, PolyOutside, WalkHint,
};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};
use rand::Rng;

/// The workspace root's `tests/golden/`.
fn golden_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("..").join("tests").join("golden")
}

fn read_golden(name: &str) -> Vec<u8> {
    let path = golden_dir().join(name);
    std::fs::read(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e}; golden files are created once, from the workspace root, with \
             FOGTEMP_BLESS=1 cargo test --test blob_format golden",
            path.display()
        )
    })
}

fn proptest_config(cases: u32) -> Config {
    Config {
        cases,
        failure_persistence: None,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(0xB10B_F0A7),
        ..Config::default()
    }
}

// ---------------------------------------------------------------------------------------------
// CRC
// ---------------------------------------------------------------------------------------------

#[test]
fn core_crc32_equals_crc32fast_on_random_bytes() {
    assert_eq!(fogtemp_core::crc::crc32(b"123456789"), 0xCBF4_3926);
    let mut r = rng(42);
    for i in 0..3000 {
        let len = if i < 300 { i } else { r.gen_range(0..5000) };
        let bytes: Vec<u8> = (0..len).map(|_| r.gen()).collect();
        assert_eq!(fogtemp_core::crc::crc32(&bytes), crc32fast::hash(&bytes), "length {len}");
    }
}

// ---------------------------------------------------------------------------------------------
// Golden bytes of format versions 1 and 2
// ---------------------------------------------------------------------------------------------

#[test]
fn golden_v1_blob_parses_and_evaluates_every_expected_row_bit_exactly() {
    let model = check_golden(GOLDEN_BLOB, GOLDEN_CSV, 1);
    // Version 1 has no region: its polynomial is extrapolated, as when it was written.
    let a1 = model.axis(1).expect("axis 1");
    assert!(a1.region.is_none() && a1.poly_outside == PolyOutside::Extrapolate);
}

#[test]
fn golden_v2_blob_parses_and_evaluates_every_expected_row_bit_exactly() {
    let model = check_golden(GOLDEN_V2_BLOB, GOLDEN_V2_CSV, 2);
    let a1 = model.axis(1).expect("axis 1");
    assert!(a1.region.is_some_and(|r| r.vertex_count() == 4));
    assert_eq!(a1.poly_outside, PolyOutside::HoldAtBoundary);
}

#[test]
fn golden_v3_blob_parses_and_evaluates_every_expected_row_bit_exactly() {
    let model = check_golden(GOLDEN_V3_BLOB, GOLDEN_V3_CSV, 3);
    let mesh = model.axis(0).expect("axis 0").mesh.expect("mesh");
    assert_eq!(mesh.outside_policy(), OutsidePolicy::StoredGradients);
    assert!((0..mesh.hull_edge_count()).all(|h| mesh.hull_gradient(h).is_some()));
}

#[test]
fn golden_v4_blob_evaluates_as_version_3_and_names_the_columns_of_each_axis() {
    let model = check_golden(GOLDEN_V4_BLOB, GOLDEN_V4_CSV, 4);
    assert_eq!(
        std::fs::read(golden_dir().join(GOLDEN_V4_CSV)).ok(),
        std::fs::read(golden_dir().join(GOLDEN_V3_CSV)).ok()
    );
    for (axis, &(gyro, temp, gyro_dph_per_unit, temp_c_per_unit, temp_offset_c)) in
        GOLDEN_V4_COLUMNS.iter().enumerate()
    {
        let c = model.axis_columns(axis).expect("recorded");
        assert_eq!((c.gyro, c.temp), (gyro, temp));
        assert_eq!(
            (c.gyro_dph_per_unit, c.temp_c_per_unit, c.temp_offset_c),
            (gyro_dph_per_unit, temp_c_per_unit, temp_offset_c)
        );
    }
    assert_eq!(model.axis_columns(2), None);
    // Older versions record none.
    for older in [GOLDEN_BLOB, GOLDEN_V2_BLOB, GOLDEN_V3_BLOB] {
        let blob = read_golden(older);
        assert_eq!(Model::from_bytes(&blob).expect("parses").axis_columns(0), None, "{older}");
    }
}

#[test]
fn golden_v5_blob_evaluates_as_version_4_and_reads_the_log_time() {
    let model = check_golden(GOLDEN_V5_BLOB, GOLDEN_V5_CSV, 5);
    assert_eq!(
        std::fs::read(golden_dir().join(GOLDEN_V5_CSV)).ok(),
        std::fs::read(golden_dir().join(GOLDEN_V4_CSV)).ok()
    );
    let (column, date_column, unit, sample_rate_hz) = GOLDEN_V5_TIME;
    let time = model.log_time().expect("recorded");
    assert_eq!(
        (time.column, time.date_column, time.unit.code(), time.sample_rate_hz),
        (column, date_column, unit, sample_rate_hz)
    );
    assert_eq!(time.unit, LogTimeUnit::Milliseconds);
    assert_eq!(model.axis_columns(1).expect("axis 1").gyro, GOLDEN_V4_COLUMNS[1].0);
    // Older versions record none.
    for older in [GOLDEN_BLOB, GOLDEN_V2_BLOB, GOLDEN_V3_BLOB, GOLDEN_V4_BLOB] {
        let blob = read_golden(older);
        assert_eq!(Model::from_bytes(&blob).expect("parses").log_time(), None, "{older}");
    }
    // Every code the record can hold, and no other.
    for code in 0..=255u8 {
        assert_eq!(LogTimeUnit::from_code(code).map(LogTimeUnit::code), (code <= 7).then_some(code));
    }
}

#[test]
fn golden_v6_blob_evaluates_as_version_4_and_reads_the_log_reading() {
    let model = check_golden(GOLDEN_V6_BLOB, GOLDEN_V6_CSV, 6);
    assert_eq!(
        std::fs::read(golden_dir().join(GOLDEN_V6_CSV)).ok(),
        std::fs::read(golden_dir().join(GOLDEN_V4_CSV)).ok()
    );
    assert_eq!(model.log_time().map(|t| t.column), Some(GOLDEN_V5_TIME.0));
    let reading = model.log_reading().expect("recorded");
    let (comma, digests) = GOLDEN_V6_READING;
    assert_eq!(reading.decimal_comma, comma);
    assert_eq!(reading.log_count(), 2);
    assert_eq!([reading.log_digest(0), reading.log_digest(1)], [Some(digests[0]), Some(digests[1])]);
    assert_eq!(reading.log_digest(2), None);
    assert_eq!(reading.log_digest(usize::MAX), None);
    for older in [GOLDEN_BLOB, GOLDEN_V2_BLOB, GOLDEN_V3_BLOB, GOLDEN_V4_BLOB, GOLDEN_V5_BLOB] {
        let blob = read_golden(older);
        assert_eq!(Model::from_bytes(&blob).expect("parses").log_reading(), None, "{older}");
    }
}

#[test]
fn golden_v7_blob_evaluates_as_version_4_and_reads_the_log_shape() {
    let model = check_golden(GOLDEN_V7_BLOB, GOLDEN_V7_CSV, 7);
    assert_eq!(
        std::fs::read(golden_dir().join(GOLDEN_V7_CSV)).ok(),
        std::fs::read(golden_dir().join(GOLDEN_V4_CSV)).ok()
    );
    assert_eq!(model.log_reading().map(|r| r.log_count()), Some(2));
    let shape = model.log_shape().expect("recorded");
    let (skip_lines, delimiter, comment, columns) = GOLDEN_V7_SHAPE;
    assert_eq!(
        (shape.skip_lines, shape.delimiter, shape.comment),
        (skip_lines, LogDelimiter::Byte(delimiter), Some(comment))
    );
    assert_eq!(shape.column_count(), columns.len());
    let read: Vec<Option<&str>> = (0..=columns.len()).map(|i| shape.column_name(i)).collect();
    let expected: Vec<Option<&str>> = columns.iter().map(|c| Some(*c)).chain([None]).collect();
    assert_eq!(read, expected);
    assert_eq!(shape.column_name(usize::MAX), None);
    for older in [GOLDEN_BLOB, GOLDEN_V2_BLOB, GOLDEN_V3_BLOB, GOLDEN_V4_BLOB, GOLDEN_V5_BLOB, GOLDEN_V6_BLOB]
    {
        let blob = read_golden(older);
        assert_eq!(Model::from_bytes(&blob).expect("parses").log_shape(), None, "{older}");
    }
}

#[test]
fn golden_v8_blob_evaluates_as_version_4_and_reads_the_run_metadata() {
    let model = check_golden(GOLDEN_V8_BLOB, GOLDEN_V8_CSV, 8);
    assert_eq!(
        std::fs::read(golden_dir().join(GOLDEN_V8_CSV)).ok(),
        std::fs::read(golden_dir().join(GOLDEN_V4_CSV)).ok()
    );
    assert_eq!(model.input_rates(), Some(InputRates::Subtracted));
    assert_eq!(model.log_reading().map(|r| r.log_count()), Some(2));
    // The default shape, written out: nothing skipped, the delimiter detected, comment lines
    // starting with '#', a header row.
    let shape = model.log_shape().expect("present in version 8");
    assert_eq!(
        (shape.skip_lines, shape.delimiter, shape.comment, shape.column_count()),
        (0, LogDelimiter::Detected, Some("#"), 0)
    );
    for older in [
        GOLDEN_BLOB,
        GOLDEN_V2_BLOB,
        GOLDEN_V3_BLOB,
        GOLDEN_V4_BLOB,
        GOLDEN_V5_BLOB,
        GOLDEN_V6_BLOB,
        GOLDEN_V7_BLOB,
    ] {
        let blob = read_golden(older);
        assert_eq!(Model::from_bytes(&blob).expect("parses").input_rates(), None, "{older}");
    }
    for code in 0..=255u8 {
        assert_eq!(InputRates::from_code(code).map(InputRates::code), matches!(code, 1 | 2).then_some(code));
    }
}

#[test]
fn a_damaged_run_metadata_record_is_refused() {
    let golden = read_golden(GOLDEN_V8_BLOB);
    let record = golden.len() - CRC_LEN - 1;
    let reread = |mutate: &dyn Fn(&mut Vec<u8>)| reread_mutated(&golden, mutate);
    assert_eq!(reread(&|_| {}), Ok(()));
    assert_eq!(reread(&|b| b[record] = 2), Ok(()), "rates given, not taken off");
    for code in [0, 3, 0xff] {
        let found = reread(&|b| b[record] = code);
        assert_eq!(
            found,
            Err(Error::BadRunMetadata { field: "input_rates", found: u64::from(code) }),
            "code {code}"
        );
        // The message names the record and the byte (review31a F9: "log reading", no value).
        let message = found.expect_err("refused").to_string();
        assert_eq!(message, format!("run metadata: input_rates is {code}, outside its allowed range"));
    }
    // A version-7 blob relabelled 8 lacks the record.
    let mut v7 = read_golden(GOLDEN_V7_BLOB);
    put_u16(&mut v7, FILE_VERSION.start, 8);
    fix_len_and_crc(&mut v7);
    assert!(matches!(Model::from_bytes(&v7), Err(Error::Truncated { field: "run metadata", .. })));
    // And a version-8 blob relabelled 7 has a byte after its section's last record.
    let mut as_v7 = golden.clone();
    put_u16(&mut as_v7, FILE_VERSION.start, 7);
    fix_len_and_crc(&mut as_v7);
    assert!(matches!(Model::from_bytes(&as_v7), Err(Error::LengthMismatch { field: "names_len", .. })));
}

#[test]
fn a_damaged_log_shape_record_is_refused_by_field() {
    let golden = read_golden(GOLDEN_V7_BLOB);
    let body_end = golden.len() - CRC_LEN;
    // The record: skip_lines (4), delimiter code and byte, comment flag, "//" with its length,
    // the column count, then the names with their lengths.
    let names: usize = GOLDEN_V7_SHAPE.3.iter().map(|n| 1 + n.len()).sum();
    let record = body_end - (4 + 3 + 3 + 1 + names);
    let (code, byte, flag, comment_len, count) =
        (record + 4, record + 5, record + 6, record + 7, record + 10);
    let first_name = count + 1;
    let reread = |mutate: &dyn Fn(&mut Vec<u8>)| reread_mutated(&golden, mutate);
    let field = |field| Err(Error::BadLogReading { field });
    assert_eq!(reread(&|_| {}), Ok(()));
    assert_eq!(reread(&|b| b[record + 3] = 0xff), Ok(()), "any count of lines skipped");
    assert_eq!(reread(&|b| b[code] = 3), field("delimiter"));
    for (c, d) in [(1, 0), (1, b'"'), (1, b'\n'), (1, 0x80), (0, b';'), (2, b' ')] {
        assert_eq!(
            reread(&|b| {
                b[code] = c;
                b[byte] = d;
            }),
            field("delimiter_byte"),
            "code {c} byte {d}"
        );
    }
    assert_eq!(
        reread(&|b| {
            b[code] = 2;
            b[byte] = 0;
        }),
        Ok(())
    );
    assert_eq!(reread(&|b| b[flag] = 0), field("comment"), "a prefix without comments");
    assert_eq!(reread(&|b| b[flag] = 2), field("comment"));
    assert_eq!(reread(&|b| b[comment_len + 1] = 0x07), field("comment"), "a control character");
    assert_eq!(reread(&|b| b[first_name] = 0), field("column_names"), "an empty name");
    assert_eq!(reread(&|b| b[first_name + 1] = 0xff), field("column_names"), "not UTF-8");
    // A count beyond the names present: the record runs past the section.
    assert!(matches!(reread(&|b| b[count] = 6), Err(Error::Truncated { field: "column_names", .. })));
    // A count short of them: the section does not end where the record does.
    assert!(matches!(reread(&|b| b[count] = 4), Err(Error::LengthMismatch { field: "names_len", .. })));
    // A version-6 blob relabelled 7 lacks the record.
    let mut v6 = read_golden(GOLDEN_V6_BLOB);
    put_u16(&mut v6, FILE_VERSION.start, 7);
    fix_len_and_crc(&mut v6);
    assert!(matches!(Model::from_bytes(&v6), Err(Error::Truncated { field: "log shape", .. })));
}

/// `golden` mutated, its lengths and CRC fixed, read again.
fn reread_mutated(golden: &[u8], mutate: &dyn Fn(&mut Vec<u8>)) -> Result<(), Error> {
    let mut b = golden.to_vec();
    mutate(&mut b);
    fix_len_and_crc(&mut b);
    Model::from_bytes(&b).map(|_| ())
}

#[test]
fn a_damaged_log_reading_record_is_refused_by_field() {
    let golden = read_golden(GOLDEN_V6_BLOB);
    let body_end = golden.len() - CRC_LEN;
    // The record is the section's last 1 + 2 + 2 x 8 bytes: the mark, the count, two digests.
    let record = body_end - 19;
    let reread = |mutate: &dyn Fn(&mut Vec<u8>)| reread_mutated(&golden, mutate);
    assert_eq!(reread(&|_| {}), Ok(()));
    assert_eq!(reread(&|b| b[record] = 0), Ok(()));
    assert_eq!(reread(&|b| b[record] = 2), Err(Error::BadLogReading { field: "decimal_mark" }));
    // A count beyond the digests present: the record runs past the section.
    assert!(matches!(reread(&|b| b[record + 1] = 3), Err(Error::Truncated { field: "log_digests", .. })));
    // A count short of them: the section does not end where the record does.
    assert!(matches!(reread(&|b| b[record + 1] = 1), Err(Error::LengthMismatch { field: "names_len", .. })));
    // A version-5 blob relabelled 6 lacks the record.
    let mut v5 = read_golden(GOLDEN_V5_BLOB);
    put_u16(&mut v5, FILE_VERSION.start, 6);
    fix_len_and_crc(&mut v5);
    assert!(matches!(Model::from_bytes(&v5), Err(Error::Truncated { field: "log reading", .. })));
}

#[test]
fn a_damaged_log_time_record_is_refused_by_field() {
    let golden = read_golden(GOLDEN_V5_BLOB);
    let body_end = golden.len() - CRC_LEN;
    // The record is the section's last 1 + 9 + 1 + 1 + 8 bytes: "Zeit [ms]", no date column,
    // unit 1, rate 0.
    let record = body_end - 20;
    let (date_len, unit, rate) = (record + 10, record + 11, record + 12);
    let reread = |mutate: &dyn Fn(&mut Vec<u8>)| reread_mutated(&golden, mutate);
    assert_eq!(reread(&|_| {}), Ok(()));
    assert_eq!(reread(&|b| b[unit] = 8), Err(Error::BadLogTime { field: "time_unit" }));
    for bad_rate in [f64::NAN, -1.0, 50.0] {
        // NaN, negative, and a rate beside a time column.
        assert_eq!(
            reread(&|b| b[rate..rate + 8].copy_from_slice(&bad_rate.to_le_bytes())),
            Err(Error::BadLogTime { field: "sample_rate_hz" }),
            "{bad_rate}"
        );
    }
    assert_eq!(reread(&|b| b[record + 1] = 0xff), Err(Error::BadLogTime { field: "time_column" }));
    // A date column ("d") with a unit other than date-time; with date-time it is read.
    let with_date = |unit_code: u8| {
        move |b: &mut Vec<u8>| {
            b[date_len] = 1;
            b.insert(date_len + 1, b'd');
            b[unit + 1] = unit_code;
            let names_at = names_offset(b);
            let names_len = u32_at(b, names_at);
            put_u32(b, names_at, names_len + 1);
        }
    };
    assert_eq!(reread(&with_date(1)), Err(Error::BadLogTime { field: "date_column" }));
    assert_eq!(reread(&with_date(3)), Ok(()));
    // Cut inside the record: the section's length no longer matches, or the record is short.
    assert!(matches!(
        reread(&|b| {
            b.truncate(body_end - 4);
            let names_at = names_offset(b);
            let names_len = u32_at(b, names_at);
            put_u32(b, names_at, names_len - 4);
            b.extend_from_slice(&[0; CRC_LEN]);
        }),
        Err(Error::Truncated { field: "log time", .. })
    ));
}

/// Where the names section of a version-4 blob starts.
fn names_offset(blob: &[u8]) -> usize {
    let axes =
        usize::from(u16::from_le_bytes([blob[FILE_AXIS_COUNT.start], blob[FILE_AXIS_COUNT.start + 1]]));
    (0..axes).fold(FILE_HEADER_LEN, |at, _| at + u32_at(blob, at + AXIS_SECTION_LEN.start) as usize)
}

#[test]
fn a_damaged_names_section_is_refused_by_field_and_axis() {
    let golden = read_golden(GOLDEN_V4_BLOB);
    let at = names_offset(&golden);
    let first_name = at + NAMES_LEN_LEN + 1; // "gyro_x" of axis 0
    let units0 = at + NAMES_LEN_LEN + (1 + 6) * 2; // axis 0's three numbers
    let second_axis_gyro = units0 + COLUMN_UNITS_LEN + 1; // axis 1's gyro name
    let reread = |mutate: &dyn Fn(&mut Vec<u8>)| reread_mutated(&golden, mutate);
    let names_len = u32_at(&golden, at) as usize;
    assert_eq!(
        reread(&|b| put_u32(b, at, names_len as u32 + 1)),
        Err(Error::LengthMismatch { field: "names_len", expected: names_len, found: names_len + 1 })
    );
    // Invalid UTF-8 (a lone continuation byte) and a control character, each named by axis.
    assert_eq!(
        reread(&|b| b[second_axis_gyro] = 0x80),
        Err(Error::BadValue { field: "gyro_column", axis: 1, index: 0 })
    );
    assert_eq!(
        reread(&|b| b[first_name] = b'\n'),
        Err(Error::BadValue { field: "gyro_column", axis: 0, index: 0 })
    );
    // The numbers: a zero scale, a non-finite offset.
    assert_eq!(
        reread(&|b| b[units0..units0 + 8].copy_from_slice(&0f64.to_le_bytes())),
        Err(Error::BadValue { field: "gyro_dph_per_unit", axis: 0, index: 0 })
    );
    assert_eq!(
        reread(&|b| b[units0 + 8..units0 + 16].copy_from_slice(&0f64.to_le_bytes())),
        Err(Error::BadValue { field: "temp_c_per_unit", axis: 0, index: 0 })
    );
    assert_eq!(
        reread(&|b| b[units0 + 16..units0 + 24].copy_from_slice(&f64::NAN.to_le_bytes())),
        Err(Error::NonFinite { field: "temp_offset_c", axis: 0, index: 0 })
    );
    // A name length that runs past the section, and a section cut after names_len.
    assert!(matches!(
        reread(&|b| b[at + NAMES_LEN_LEN] = 200),
        Err(Error::Truncated { field: "gyro_column", .. } | Error::LengthMismatch { field: "names_len", .. })
    ));
    assert_eq!(
        reread(&|b| {
            b.truncate(at + NAMES_LEN_LEN);
            put_u32(b, at, NAMES_LEN_LEN as u32);
            b.extend_from_slice(&[0; CRC_LEN]);
        }),
        Err(Error::Truncated {
            field: "gyro_column",
            needed: at + NAMES_LEN_LEN + 1,
            found: at + NAMES_LEN_LEN
        })
    );
    // No section at all in a version-4 blob; and a version-3 blob with one.
    assert!(matches!(
        reread(&|b| {
            b.truncate(at);
            b.extend_from_slice(&[0; CRC_LEN]);
        }),
        Err(Error::Truncated { field: "names_len", .. })
    ));
    assert!(matches!(
        reread(&|b| put_u16(b, FILE_VERSION.start, 3)),
        Err(Error::LengthMismatch { field: "sum of section_len", .. })
    ));
}

/// Reads a golden blob of format `version` and checks every expected row bit for bit.
fn check_golden(blob_name: &str, csv_name: &str, version: u16) -> Model<'static> {
    let blob: &'static [u8] = Vec::leak(read_golden(blob_name));
    let csv = String::from_utf8(read_golden(csv_name)).expect("utf-8");
    let model = Model::from_bytes(blob).expect("today's reader accepts the golden blob");
    assert_eq!(model.format_version(), version);
    assert_eq!(model.axis_count(), 2);
    assert_eq!(model.tool_version(), b"fogtemp golden");
    assert_eq!(model.input_digest(), core_digest());
    let (a0, a1) = (model.axis(0).expect("axis 0"), model.axis(1).expect("axis 1"));
    assert!(a0.poly.is_some() && a0.mesh.is_some() && a1.poly.is_some() && a1.mesh.is_none());
    assert!(a0.mesh.expect("mesh").vertex_count() >= 25);

    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(GOLDEN_HEADER));
    let mut rows = 0;
    let mut outside = 0;
    for (n, line) in lines.enumerate() {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields.len(), 5, "row {n}: {line}");
        let axis: usize = fields[0].parse().expect("axis");
        let temp_c: f32 = fields[1].parse().expect("temp_c");
        let rate: f32 = fields[2].parse().expect("rate_c_per_min");
        let expected_bits = u32::from_str_radix(fields[3], 16).expect("value_dph_bits");
        let expected_outside = fields[4] == "1";
        let e =
            model.axis(axis).expect("axis").evaluate(temp_c, rate, &mut WalkHint::default()).expect("finite");
        assert_eq!(
            (e.value_dph.to_bits(), e.outside_hull),
            (expected_bits, expected_outside),
            "row {n} ({line}): today's reader gives {} ({:08x})",
            e.value_dph,
            e.value_dph.to_bits()
        );
        rows += 1;
        outside += usize::from(expected_outside);
    }
    assert_eq!(rows, golden_queries().len());
    assert!(outside > 0 && outside < rows, "the golden queries cover inside and outside the hull");
    model
}

// ---------------------------------------------------------------------------------------------
// Arbitrary input
// ---------------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(proptest_config(3000))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
        if let Ok(model) = Model::from_bytes(&bytes) {
            exercise(&model, 9);
        }
    }

    #[test]
    fn random_bytes_behind_a_valid_header_never_panic(
        axis_count in 0u16..20,
        payload in proptest::collection::vec(any::<u8>(), 0..3000),
    ) {
        // A well-formed file header with a matching length and CRC: the reader has to go
        // through the axis sections, which are random.
        let mut b = vec![0u8; FILE_HEADER_LEN];
        b[FILE_MAGIC].copy_from_slice(&MAGIC);
        put_u16(&mut b, FILE_VERSION.start, FORMAT_VERSION);
        put_u16(&mut b, FILE_HEADER_LEN_FIELD.start, FILE_HEADER_LEN as u16);
        put_u16(&mut b, FILE_AXIS_COUNT.start, axis_count);
        b.extend_from_slice(&payload);
        b.extend_from_slice(&[0; CRC_LEN]);
        fix_len_and_crc(&mut b);
        if let Ok(model) = Model::from_bytes(&b) {
            exercise(&model, 10);
        }
    }
}

#[test]
fn fuzz_regressions_never_panic() {
    // Inputs the fuzz target once crashed on (see tests/golden/fuzz-regressions/README.md),
    // through the same two paths as the target: as given, and with length and CRC patched.
    let dir = golden_dir().join("fuzz-regressions");
    let mut replayed = 0;
    for entry in std::fs::read_dir(&dir).expect("tests/golden/fuzz-regressions exists") {
        let path = entry.expect("dir entry").path();
        if path.extension().is_some_and(|e| e == "md") {
            continue;
        }
        let bytes = std::fs::read(&path).expect("read regression input");
        let mut fixed = bytes.clone();
        fix_len_and_crc(&mut fixed);
        for input in [&bytes, &fixed] {
            let outcome = catch_unwind(AssertUnwindSafe(|| {
                if let Ok(model) = Model::from_bytes(input) {
                    exercise(&model, 0);
                }
            }));
            assert!(outcome.is_ok(), "{}: panics", path.display());
        }
        replayed += 1;
    }
    println!("replayed {replayed} fuzz regression inputs");
}
