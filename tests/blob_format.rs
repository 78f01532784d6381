//! The model blob, format versions 2 and 3, from the writer's side: round trip through
//! `fogtemp_cal::encode` and the core reader, the layout against the spec, the committed golden
//! bytes reproduced by today's writer, and rejection of corrupted written blobs without panics
//! (single-byte flips, truncations, structured mutations, targeted corruptions with their
//! specific errors).
//!
//! The reader's side alone (the core's CRC, the golden bytes read and evaluated, random bytes,
//! the fuzz regressions) is tested in the core's own `crates/fogtemp-core/tests/blob_format.rs`;
//! the byte helpers and the golden file names and queries are shared with it
//! (`crates/fogtemp-core/tests/common/blob.rs`, included here with `#[path]`).
//!
//! Golden files live in `tests/golden/`. They are written only when the environment variable
//! `FOGTEMP_BLESS=1` is set:
//!
//! ```text
//! FOGTEMP_BLESS=1 cargo test --test blob_format golden
//! cargo test -p fogtemp-core --test blob_format golden   # today's reader on the new files
//! ```
//!
//! Bless only when the format version changes (then add a new `model-vN` pair and keep the old
//! ones: every released version stays readable) or when the writer's output legitimately
//! changes for the same model; never to make a failing read of an old file pass.

mod common;
#[path = "../crates/fogtemp-core/tests/common/blob.rs"]
mod shared;

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Once;

use common::{bias_surface, paper_points, random_points, rng, FEATURES, NORMALISATION};
use fogtemp_cal::blob::{triangle_transform, LogReadingRecord, LogShapeRecord, LogTimeRecord};
use fogtemp_cal::ingest::Delimiter;
use fogtemp_cal::{build_mesh, encode, AxisModel, CalError, ColumnNames, MeshModel, MeshPoint, ModelFile};
use fogtemp_core::wire::*;
use fogtemp_core::{
    AxisProvenance, Error, FeatureSettings, InputRates, LogTimeUnit, Model, Normalisation, OutsidePolicy,
    PolyTerm, Vertex, WalkHint,
};
use rand::Rng;
use shared::{
    core_digest, exercise, fix_crc, fix_len_and_crc, golden_queries, put_f32, put_u16, put_u32, u16_at,
    u32_at, GOLDEN_HEADER, GOLDEN_V2_BLOB, GOLDEN_V2_CSV, GOLDEN_V3_BLOB, GOLDEN_V3_CSV, GOLDEN_V4_BLOB,
    GOLDEN_V4_COLUMNS, GOLDEN_V4_CSV, GOLDEN_V5_BLOB, GOLDEN_V5_CSV, GOLDEN_V5_TIME, GOLDEN_V6_BLOB,
    GOLDEN_V6_CSV, GOLDEN_V6_READING, GOLDEN_V7_BLOB, GOLDEN_V7_CSV, GOLDEN_V7_SHAPE, GOLDEN_V8_BLOB,
    GOLDEN_V8_CSV,
};

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("golden")
}

/// Offsets of one axis section's parts in a blob.
#[derive(Clone, Copy, Debug)]
struct Section {
    start: usize,
    terms: usize,
    vertices: usize,
    triangles: usize,
    hull: usize,
    poly_at: usize,
    vertex_at: usize,
    triangle_at: usize,
    hull_at: usize,
}

/// The layout of axis `axis` of a well-formed blob, computed from the spec (not the reader).
fn section(b: &[u8], axis: usize) -> Section {
    let mut start = FILE_HEADER_LEN;
    for _ in 0..axis {
        start += u32_at(b, start + AXIS_SECTION_LEN.start) as usize;
    }
    let count = |r: std::ops::Range<usize>| u32_at(b, start + r.start) as usize;
    let (terms, vertices, triangles, hull) = (
        count(AXIS_POLY_TERM_COUNT),
        count(AXIS_VERTEX_COUNT),
        count(AXIS_TRIANGLE_COUNT),
        count(AXIS_HULL_EDGE_COUNT),
    );
    let poly_at = start + AXIS_HEADER_LEN;
    let vertex_at = poly_at + terms * POLY_TERM_LEN;
    let triangle_at = vertex_at + vertices * VERTEX_LEN;
    let hull_at = triangle_at + triangles * TRIANGLE_LEN;
    Section { start, terms, vertices, triangles, hull, poly_at, vertex_at, triangle_at, hull_at }
}

fn provenance(seed: f32) -> AxisProvenance {
    AxisProvenance {
        fit_point_count: 1000 + seed as u32,
        residual_rms_dph: 0.0031 * seed,
        residual_max_abs_dph: 0.0172 * seed,
        temp_min_c: -41.25 + seed,
        temp_max_c: 79.5 - seed,
        rate_min_c_per_min: 0.0125 * seed,
        rate_max_c_per_min: 0.75 + 0.01 * seed,
    }
}

fn term(temp_power: u8, rate_power: u8, coefficient_dph: f32) -> PolyTerm {
    PolyTerm { temp_power, rate_power, coefficient_dph }
}

/// A three-axis model: poly-only, mesh-only, and hybrid poly+mesh with `OutsidePolicy::Zero`;
/// every axis has its own feature settings, normalisation and provenance.
fn three_axis_model() -> ModelFile {
    let n1 = Normalisation {
        temp_offset_c: 25.0,
        temp_scale_per_c: 1.0 / 50.0,
        rate_offset_c_per_min: 0.3,
        rate_scale_per_c_per_min: 1.5,
    };
    let axis0 = AxisModel {
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
        features: FeatureSettings { window_s: 60.0, block_count: 30, min_blocks: 5, max_gap_s: 2.5 },
        normalisation: NORMALISATION,
        outside_policy: OutsidePolicy::NearestHull,
        poly: vec![
            term(0, 0, 0.0123),
            term(1, 0, -0.25),
            term(0, 1, 0.0625),
            term(3, 2, 1.0e-4),
            term(6, 0, -3.5e-7),
            term(0, 6, 2.0e-6),
            term(2, 2, f32::MIN_POSITIVE),
        ],
        mesh: None,
        provenance: provenance(1.0),
    };
    let axis1 = AxisModel {
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
        features: FEATURES,
        normalisation: n1,
        outside_policy: OutsidePolicy::NearestHull,
        poly: Vec::new(),
        mesh: Some(build_mesh(&random_points(40, 11, bias_surface), &n1).expect("mesh")),
        provenance: provenance(2.0),
    };
    let axis2 = AxisModel {
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
        features: FeatureSettings { window_s: 250.0, block_count: 4096, min_blocks: 4096, max_gap_s: 1.0e3 },
        normalisation: NORMALISATION,
        outside_policy: OutsidePolicy::Zero,
        poly: vec![term(0, 0, -0.5), term(1, 1, 0.125)],
        mesh: Some(build_mesh(&paper_points(6, bias_surface), &NORMALISATION).expect("mesh")),
        provenance: provenance(3.0),
    };
    ModelFile {
        tool_version: "fogtemp rt 0.1".into(),
        input_digest: core_digest(),
        axes: vec![axis0, axis1, axis2],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    }
}

/// A hybrid axis of 17 mesh nodes and 3 poly terms, continued outside the hull by `policy`.
fn two_kb_axis(policy: OutsidePolicy) -> AxisModel {
    AxisModel {
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
        features: FEATURES,
        normalisation: NORMALISATION,
        outside_policy: policy,
        poly: vec![term(0, 0, 0.01), term(1, 0, 0.2), term(1, 1, -0.03)],
        mesh: Some(build_mesh(&random_points(17, 21, bias_surface), &NORMALISATION).expect("mesh")),
        provenance: provenance(4.0),
    }
}

/// A valid one-axis hybrid blob of about 2 KB ([`two_kb_axis`], nearest-hull policy).
fn two_kb_blob() -> Vec<u8> {
    let axis = two_kb_axis(OutsidePolicy::NearestHull);
    encode(&ModelFile {
        tool_version: "fogtemp 2k".into(),
        input_digest: [3; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    })
    .expect("encodes")
}

fn bits(v: f32) -> u32 {
    v.to_bits()
}

// ---------------------------------------------------------------------------------------------
// 1. Round trip and layout
// ---------------------------------------------------------------------------------------------

#[test]
fn encode_then_from_bytes_returns_every_field_bit_exactly() {
    let file = three_axis_model();
    let blob = encode(&file).expect("encodes");
    let model = Model::from_bytes(&blob).expect("parses");
    // No axis continues its mesh with stored gradients: written as version 2.
    assert_eq!(model.format_version(), FORMAT_VERSION_WITHOUT_GRADIENTS);
    assert_eq!(model.tool_version(), file.tool_version.as_bytes());
    assert_eq!(model.input_digest(), file.input_digest);
    assert_eq!(model.axis_count(), 3);
    assert!(matches!(model.axis(3), Err(Error::NoSuchAxis { requested: 3, available: 3 })));

    for (i, written) in file.axes.iter().enumerate() {
        let axis = model.axis(i).expect("axis");
        assert_eq!(usize::from(axis.id), i);
        let (f, g) = (&axis.features, &written.features);
        assert_eq!(
            (bits(f.window_s), f.block_count, f.min_blocks, bits(f.max_gap_s)),
            (bits(g.window_s), g.block_count, g.min_blocks, bits(g.max_gap_s)),
            "axis {i}: features"
        );
        let (n, m) = (&axis.normalisation, &written.normalisation);
        assert_eq!(
            [n.temp_offset_c, n.temp_scale_per_c, n.rate_offset_c_per_min, n.rate_scale_per_c_per_min]
                .map(bits),
            [m.temp_offset_c, m.temp_scale_per_c, m.rate_offset_c_per_min, m.rate_scale_per_c_per_min]
                .map(bits),
            "axis {i}: normalisation"
        );
        let (p, q) = (&axis.provenance, &written.provenance);
        assert_eq!(p.fit_point_count, q.fit_point_count);
        assert_eq!(
            [
                p.residual_rms_dph,
                p.residual_max_abs_dph,
                p.temp_min_c,
                p.temp_max_c,
                p.rate_min_c_per_min,
                p.rate_max_c_per_min
            ]
            .map(bits),
            [
                q.residual_rms_dph,
                q.residual_max_abs_dph,
                q.temp_min_c,
                q.temp_max_c,
                q.rate_min_c_per_min,
                q.rate_max_c_per_min
            ]
            .map(bits),
            "axis {i}: provenance"
        );
        match &axis.poly {
            None => assert!(written.poly.is_empty(), "axis {i}: poly missing"),
            Some(poly) => {
                let read: Vec<(u8, u8, u32)> =
                    poly.terms().map(|t| (t.temp_power, t.rate_power, bits(t.coefficient_dph))).collect();
                let expected: Vec<(u8, u8, u32)> = written
                    .poly
                    .iter()
                    .map(|t| (t.temp_power, t.rate_power, bits(t.coefficient_dph)))
                    .collect();
                assert_eq!(read, expected, "axis {i}: poly terms");
                assert_eq!(poly.len(), written.poly.len());
            }
        }
        match (&axis.mesh, &written.mesh) {
            (None, None) => {}
            (Some(mesh), Some(w)) => {
                assert_eq!(mesh.outside_policy(), written.outside_policy, "axis {i}: policy");
                assert_eq!(mesh.vertex_count() as usize, w.vertices.len());
                assert_eq!(mesh.triangle_count() as usize, w.triangles.len());
                assert_eq!(mesh.hull_edge_count() as usize, w.hull.len());
                for (v, wv) in w.vertices.iter().enumerate() {
                    let rv = mesh.vertex(v as u32).expect("vertex");
                    assert_eq!(
                        [rv.x, rv.y, rv.value_dph].map(bits),
                        [wv.x, wv.y, wv.value_dph].map(bits),
                        "axis {i} vertex {v}"
                    );
                }
                assert!(mesh.vertex(w.vertices.len() as u32).is_none());
                for (t, (tri, nb)) in w.triangles.iter().zip(&w.neighbours).enumerate() {
                    let rec = mesh.triangle(t as u32).expect("triangle");
                    assert_eq!(rec.vertices, *tri, "axis {i} triangle {t}: vertices");
                    assert_eq!(rec.neighbours, *nb, "axis {i} triangle {t}: neighbours");
                    let tf = triangle_transform(w, *tri).expect("transform");
                    assert_eq!(rec.origin.map(bits), tf.origin.map(bits), "axis {i} triangle {t}: origin");
                    assert_eq!(
                        rec.bary.map(bits),
                        tf.bary.map(|v| bits(v as f32)),
                        "axis {i} triangle {t}: bary"
                    );
                    assert_eq!(
                        rec.plane.map(bits),
                        tf.plane.map(|v| bits(v as f32)),
                        "axis {i} triangle {t}: plane"
                    );
                }
                assert!(mesh.triangle(w.triangles.len() as u32).is_none());
                for (h, edge) in w.hull.iter().enumerate() {
                    assert_eq!(mesh.hull_edge(h as u32), Some(*edge), "axis {i} hull {h}");
                }
                assert!(mesh.hull_edge(w.hull.len() as u32).is_none());
            }
            _ => panic!("axis {i}: mesh presence differs"),
        }
    }
    assert!(exercise(&model, 1) > 0);
}

#[test]
fn blob_layout_follows_the_spec() {
    let file = three_axis_model();
    let blob = encode(&file).expect("encodes");
    assert_eq!(&blob[FILE_MAGIC], b"FOGM");
    assert_eq!(u16_at(&blob, FILE_VERSION.start), 2);
    assert_eq!(u16_at(&blob, FILE_HEADER_LEN_FIELD.start), 64);
    assert_eq!(u32_at(&blob, FILE_TOTAL_LEN.start) as usize, blob.len());
    assert_eq!(u16_at(&blob, FILE_AXIS_COUNT.start), 3);
    assert_eq!(u16_at(&blob, FILE_RESERVED.start), 0);
    assert_eq!(&blob[FILE_TOOL_VERSION][..14], b"fogtemp rt 0.1");
    assert!(blob[FILE_TOOL_VERSION][14..].iter().all(|&b| b == 0), "NUL padded");
    let body = blob.len() - 4;
    assert_eq!(u32_at(&blob, body), crc32fast::hash(&blob[..body]), "CRC-32 (IEEE) trailer over the body");
    let mut end = FILE_HEADER_LEN;
    for (i, axis) in file.axes.iter().enumerate() {
        let s = section(&blob, i);
        assert_eq!(s.start, end);
        assert_eq!(u16_at(&blob, s.start + AXIS_ID.start) as usize, i);
        let kind = u16_at(&blob, s.start + AXIS_MODEL_KIND.start);
        assert_eq!(kind & KIND_POLY != 0, !axis.poly.is_empty());
        assert_eq!(kind & KIND_MESH != 0, axis.mesh.is_some());
        assert_eq!(u32_at(&blob, s.start + AXIS_OUTSIDE_POLICY.start), axis.outside_policy.code());
        assert_eq!(u32_at(&blob, s.start + AXIS_REGION_VERTEX_COUNT.start) as usize, axis.region.len());
        assert_eq!(u32_at(&blob, s.start + AXIS_POLY_OUTSIDE.start), axis.poly_outside.code());
        let len = 96 + 8 * s.terms + 12 * s.vertices + 60 * s.triangles + 8 * s.hull + 8 * axis.region.len();
        assert_eq!(u32_at(&blob, s.start + AXIS_SECTION_LEN.start) as usize, len);
        for (k, t) in axis.poly.iter().enumerate() {
            let at = s.poly_at + 8 * k;
            assert_eq!(&blob[at..at + 4], &[t.temp_power, t.rate_power, 0, 0]);
            assert_eq!(blob[at + 4..at + 8], t.coefficient_dph.to_le_bytes());
        }
        if let Some(m) = &axis.mesh {
            let v0 = &m.vertices[0];
            assert_eq!(blob[s.vertex_at..s.vertex_at + 4], v0.x.to_le_bytes());
            let t0 = s.triangle_at;
            assert_eq!(u32_at(&blob, t0 + TRI_VERTICES.start), m.triangles[0][0]);
            assert_eq!(u32_at(&blob, t0 + TRI_NEIGHBOURS.start), m.neighbours[0][0]);
            assert_eq!(u32_at(&blob, s.hull_at), m.hull[0].0);
            assert_eq!(u32_at(&blob, s.hull_at + 4), m.hull[0].1);
        }
        end += len;
    }
    assert_eq!(end, body, "sections fill the blob up to the CRC");
}

// ---------------------------------------------------------------------------------------------
// 2. Golden bytes of format version 2 (the reader's side, and version 1's: the core's tests)
// ---------------------------------------------------------------------------------------------

/// A deterministic pseudo-random stream from an integer LCG (no float library functions, so
/// the golden model is the same on every platform and with every `rand` version).
struct Lcg(u32);

impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        f64::from(self.0 >> 8) / f64::from(1u32 << 24)
    }
}

/// Bias surface of the golden model: polynomial arithmetic only (exactly reproducible).
fn golden_surface(temp_c: f64, rate: f64) -> f64 {
    0.002 * temp_c + 1.5e-5 * temp_c * temp_c + 0.06 * rate - 4.0e-4 * temp_c * rate
}

/// The golden model: axis 0 hybrid (5 poly terms + a 30-node mesh on a jittered 6 x 5 grid,
/// nearest-hull policy), axis 1 polynomial only (own features and normalisation).
fn golden_model() -> ModelFile {
    let mut lcg = Lcg(0x00C0_FFEE);
    let mut points = Vec::new();
    for i in 0..6 {
        for j in 0..5 {
            let temp_c = -40.0 + 20.0 * (f64::from(i) + 0.15 + 0.7 * lcg.unit());
            let rate = 0.2 * (f64::from(j) + 0.15 + 0.7 * lcg.unit());
            points.push(MeshPoint { temp_c, rate_c_per_min: rate, value_dph: golden_surface(temp_c, rate) });
        }
    }
    let axis0 = AxisModel {
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
        features: FEATURES,
        normalisation: NORMALISATION,
        outside_policy: OutsidePolicy::NearestHull,
        poly: vec![
            term(0, 0, 0.05),
            term(1, 0, 0.12),
            term(0, 1, -0.03),
            term(2, 0, 0.01),
            term(1, 1, 0.004),
        ],
        mesh: Some(build_mesh(&points, &NORMALISATION).expect("golden mesh")),
        provenance: provenance(5.0),
    };
    let axis1 = AxisModel {
        // A calibrated region (normalised plane) with the polynomial held at its boundary.
        region: vec![[-0.8, -0.9], [0.8, -0.9], [0.9, 0.8], [-0.9, 0.9]],
        poly_outside: fogtemp_core::PolyOutside::HoldAtBoundary,
        features: FeatureSettings { window_s: 50.0, block_count: 25, min_blocks: 8, max_gap_s: 3.0 },
        normalisation: Normalisation {
            temp_offset_c: 15.0,
            temp_scale_per_c: 0.02,
            rate_offset_c_per_min: 0.25,
            rate_scale_per_c_per_min: 4.0,
        },
        outside_policy: OutsidePolicy::NearestHull,
        poly: vec![
            term(0, 0, -0.02),
            term(1, 0, 0.3),
            term(2, 0, -0.05),
            term(0, 1, 0.07),
            term(3, 1, 0.002),
        ],
        mesh: None,
        provenance: provenance(6.0),
    };
    ModelFile {
        tool_version: "fogtemp golden".into(),
        input_digest: core_digest(),
        axes: vec![axis0, axis1],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    }
}

/// The version-3 golden model: the version-2 one with axis 0's mesh continued by stored hull
/// gradients.
fn golden_model_v3() -> ModelFile {
    let mut model = golden_model();
    model.axes[0].outside_policy = OutsidePolicy::StoredGradients;
    model
}

/// The version-4 golden model: the version-3 one with each axis's log columns recorded.
fn golden_model_v4() -> ModelFile {
    let mut model = golden_model_v3();
    model.columns = GOLDEN_V4_COLUMNS
        .iter()
        .map(|&(gyro, temp, gyro_dph_per_unit, temp_c_per_unit, temp_offset_c)| ColumnNames {
            gyro: gyro.into(),
            temp: temp.into(),
            gyro_dph_per_unit,
            temp_c_per_unit,
            temp_offset_c,
        })
        .collect();
    model
}

/// The version-5 golden model: the version-4 one with its logs' time recorded.
fn golden_model_v5() -> ModelFile {
    let mut model = golden_model_v4();
    let (column, date_column, unit, sample_rate_hz) = GOLDEN_V5_TIME;
    model.log_time = LogTimeRecord {
        column: column.into(),
        date_column: date_column.into(),
        unit: LogTimeUnit::from_code(unit).expect("a unit"),
        sample_rate_hz,
    };
    model
}

/// The version-6 golden model: the version-5 one with its logs' reading recorded.
fn golden_model_v6() -> ModelFile {
    let mut model = golden_model_v5();
    let (decimal_comma, digests) = GOLDEN_V6_READING;
    model.log_reading =
        LogReadingRecord { decimal_comma, log_digests: digests.to_vec(), ..Default::default() };
    model
}

/// The version-7 golden model: the version-6 one with its logs' shape recorded.
fn golden_model_v7() -> ModelFile {
    let mut model = golden_model_v6();
    model.log_reading.shape = golden_shape_v7();
    model
}

/// The version-8 golden model: the version-6 one (logs of the default shape) whose fit took
/// each run's input rate off its gyro.
fn golden_model_v8() -> ModelFile {
    ModelFile { input_rates: Some(InputRates::Subtracted), ..golden_model_v6() }
}

/// [`GOLDEN_V7_SHAPE`] as the writer takes it.
fn golden_shape_v7() -> LogShapeRecord {
    let (skip_lines, delimiter, comment, columns) = GOLDEN_V7_SHAPE;
    LogShapeRecord {
        skip_lines: u64::from(skip_lines),
        delimiter: Delimiter::Byte(delimiter),
        comment: Some(comment.into()),
        column_names: columns.iter().map(|c| c.to_string()).collect(),
    }
}

/// One expected row: evaluated with a fresh default hint, so the row does not depend on the
/// order of the queries.
fn golden_row(model: &Model<'_>, (axis, temp_c, rate): (usize, f32, f32)) -> String {
    let e = model.axis(axis).expect("axis").evaluate(temp_c, rate, &mut WalkHint::default()).expect("finite");
    format!("{axis},{temp_c},{rate},{:08x},{}", e.value_dph.to_bits(), u8::from(e.outside_hull))
}

/// With `FOGTEMP_BLESS=1`, (re)writes the golden files from today's writer; otherwise nothing.
fn bless_if_requested() {
    static BLESS: Once = Once::new();
    BLESS.call_once(|| {
        if std::env::var("FOGTEMP_BLESS").as_deref() != Ok("1") {
            return;
        }
        std::fs::create_dir_all(golden_dir()).expect("create tests/golden");
        for (model, blob_name, csv_name) in [
            (golden_model(), GOLDEN_V2_BLOB, GOLDEN_V2_CSV),
            (golden_model_v3(), GOLDEN_V3_BLOB, GOLDEN_V3_CSV),
            (golden_model_v4(), GOLDEN_V4_BLOB, GOLDEN_V4_CSV),
            (golden_model_v5(), GOLDEN_V5_BLOB, GOLDEN_V5_CSV),
            (golden_model_v6(), GOLDEN_V6_BLOB, GOLDEN_V6_CSV),
            (golden_model_v7(), GOLDEN_V7_BLOB, GOLDEN_V7_CSV),
            (golden_model_v8(), GOLDEN_V8_BLOB, GOLDEN_V8_CSV),
        ] {
            let blob = encode(&model).expect("golden model encodes");
            let parsed = Model::from_bytes(&blob).expect("parses");
            let mut csv = String::from(GOLDEN_HEADER);
            csv.push('\n');
            for q in golden_queries() {
                csv.push_str(&golden_row(&parsed, q));
                csv.push('\n');
            }
            std::fs::write(golden_dir().join(blob_name), &blob).expect("write golden blob");
            std::fs::write(golden_dir().join(csv_name), csv).expect("write golden csv");
            eprintln!("FOGTEMP_BLESS=1: wrote {blob_name} ({} bytes) and {csv_name}", blob.len());
        }
    });
}

fn read_golden(name: &str) -> Vec<u8> {
    bless_if_requested();
    let path = golden_dir().join(name);
    std::fs::read(&path).unwrap_or_else(|e| {
        panic!("{}: {e}; golden files are created once with FOGTEMP_BLESS=1", path.display())
    })
}

#[test]
fn golden_v2_blob_is_reproduced_byte_for_byte_by_todays_writer() {
    // Version 1 (model-v1.fogm) is no longer written; the core's tests still read it.
    let golden = read_golden(GOLDEN_V2_BLOB);
    let today = encode(&golden_model()).expect("encodes");
    if today != golden {
        let first =
            today.iter().zip(&golden).position(|(a, b)| a != b).unwrap_or(today.len().min(golden.len()));
        panic!(
            "the writer's output for the golden model changed (lengths {} vs {}, first difference at \
             byte {first}). A format change needs a new version and a new golden file; a legitimate \
             writer change (e.g. a new triangle order) is blessed with FOGTEMP_BLESS=1 after checking \
             the expected values still hold.",
            today.len(),
            golden.len()
        );
    }
}

#[test]
fn golden_v3_blob_is_reproduced_byte_for_byte_by_todays_writer() {
    let golden = read_golden(GOLDEN_V3_BLOB);
    let today = encode(&golden_model_v3()).expect("encodes");
    assert_eq!(u16_at(&golden, FILE_VERSION.start), 3);
    assert!(today == golden, "the writer's output for the version-3 golden model changed");
    // Only axis 0's policy, hull gradients and vertex numbering differ from version 2; the
    // values inside the hull are version 2's bit for bit (the golden queries beyond it differ).
    let v2 = read_golden(GOLDEN_V2_BLOB);
    let (m2, m3) = (Model::from_bytes(&v2).expect("v2"), Model::from_bytes(&golden).expect("v3"));
    let mut differ = 0;
    for (axis, t, r) in golden_queries() {
        let e2 = m2.axis(axis).expect("axis").evaluate(t, r, &mut WalkHint::default()).expect("finite");
        let e3 = m3.axis(axis).expect("axis").evaluate(t, r, &mut WalkHint::default()).expect("finite");
        assert_eq!(e2.outside_hull, e3.outside_hull);
        if !e2.outside_hull {
            assert_eq!(bits(e2.value_dph), bits(e3.value_dph), "({axis}, {t}, {r})");
        }
        differ += usize::from(bits(e2.value_dph) != bits(e3.value_dph));
    }
    assert!(differ > 0, "the golden queries reach beyond the hull");
}

#[test]
fn golden_v4_blob_is_reproduced_byte_for_byte_by_todays_writer() {
    let golden = read_golden(GOLDEN_V4_BLOB);
    let today = encode(&golden_model_v4()).expect("encodes");
    assert_eq!(u16_at(&golden, FILE_VERSION.start), 4);
    assert!(today == golden, "the writer's output for the version-4 golden model changed");
    // Version 4 is version 3 with the names section before the CRC: the same axis sections,
    // and the section laid out as docs/model-format.md says, counted here by hand.
    let v3 = read_golden(GOLDEN_V3_BLOB);
    let axes_end = v3.len() - CRC_LEN;
    assert_eq!(golden[FILE_HEADER_LEN..axes_end], v3[FILE_HEADER_LEN..axes_end]);
    let mut expected = Vec::new();
    for (gyro, temp, gyro_dph_per_unit, temp_c_per_unit, temp_offset_c) in GOLDEN_V4_COLUMNS {
        for name in [gyro, temp] {
            expected.push(name.len() as u8);
            expected.extend_from_slice(name.as_bytes());
        }
        for v in [gyro_dph_per_unit, temp_c_per_unit, temp_offset_c] {
            expected.extend_from_slice(&v.to_le_bytes());
        }
    }
    // "gyro_x" 6 + "temp_c" 6 + "Drehrate Y (°/h)" 17 (the degree sign is two bytes) + "T_y" 3,
    // four length bytes, and three f64 per axis (names_len's four bytes come before).
    assert_eq!(expected.len(), 6 + 6 + 17 + 3 + 4 + 2 * 24);
    let names = &golden[axes_end..golden.len() - CRC_LEN];
    assert_eq!(u32_at(names, 0) as usize, 4 + expected.len());
    assert_eq!(names[4..], expected[..]);
}

#[test]
fn golden_v5_blob_is_reproduced_byte_for_byte_by_todays_writer() {
    let golden = read_golden(GOLDEN_V5_BLOB);
    let today = encode(&golden_model_v5()).expect("encodes");
    assert_eq!(u16_at(&golden, FILE_VERSION.start), 5);
    assert!(today == golden, "the writer's output for the version-5 golden model changed");
    // Version 5 is version 4 with the log-time record at the end of the names section,
    // counted here by hand: "Zeit [ms]" (9 bytes) with its length byte, an empty date column
    // (one length byte), the unit code 1 and the rate 0 as f64.
    let v4 = read_golden(GOLDEN_V4_BLOB);
    let v4_end = v4.len() - CRC_LEN;
    let axes_end = names_offset(&v4);
    assert_eq!(golden[FILE_HEADER_LEN..axes_end], v4[FILE_HEADER_LEN..axes_end]);
    let mut expected = v4[axes_end + 4..v4_end].to_vec();
    expected.extend_from_slice(&[9]);
    expected.extend_from_slice(b"Zeit [ms]");
    expected.extend_from_slice(&[0, 1]);
    expected.extend_from_slice(&0f64.to_le_bytes());
    assert_eq!(expected.len(), (v4_end - axes_end - 4) + 1 + 9 + 1 + 1 + 8);
    let names = &golden[axes_end..golden.len() - CRC_LEN];
    assert_eq!(u32_at(names, 0) as usize, 4 + expected.len());
    assert_eq!(names[4..], expected[..]);
    // A model with columns but no time stays version 4, byte for byte.
    assert!(encode(&golden_model_v4()).expect("encodes") == v4);
}

#[test]
fn golden_v6_blob_is_reproduced_byte_for_byte_by_todays_writer() {
    let golden = read_golden(GOLDEN_V6_BLOB);
    let today = encode(&golden_model_v6()).expect("encodes");
    assert_eq!(u16_at(&golden, FILE_VERSION.start), 6);
    assert!(today == golden, "the writer's output for the version-6 golden model changed");
    // Version 6 is version 5 with the log-reading record after the log-time record, counted
    // here by hand: the mark 1 (comma), the count 2 as u16, then the two 8-byte digests.
    let v5 = read_golden(GOLDEN_V5_BLOB);
    let v5_end = v5.len() - CRC_LEN;
    let axes_end = names_offset(&v5);
    assert_eq!(golden[FILE_HEADER_LEN..axes_end], v5[FILE_HEADER_LEN..axes_end]);
    let mut expected = v5[axes_end + 4..v5_end].to_vec();
    expected.extend_from_slice(&[1, 2, 0]);
    expected.extend_from_slice(&[0xba, 0x78, 0x16, 0xbf, 0x8f, 0x01, 0xcf, 0xea]);
    expected.extend_from_slice(&[0xe3, 0xb0, 0xc4, 0x42, 0x98, 0xfc, 0x1c, 0x14]);
    let names = &golden[axes_end..golden.len() - CRC_LEN];
    assert_eq!(u32_at(names, 0) as usize, 4 + expected.len());
    assert_eq!(names[4..], expected[..]);
    // Without a log reading it stays version 5, byte for byte; a reading without a time is
    // written after an empty log-time record.
    assert!(encode(&golden_model_v5()).expect("encodes") == v5);
    let mut no_time = golden_model_v6();
    no_time.log_time = LogTimeRecord::default();
    let blob = encode(&no_time).expect("encodes");
    let model = Model::from_bytes(&blob).expect("parses");
    assert_eq!((model.format_version(), model.log_time()), (6, None));
    assert_eq!(model.log_reading().map(|r| (r.decimal_comma, r.log_count())), Some((true, 2)));
    // A digest of the SHA-256 the record keeps: its first 8 bytes.
    let sha_abc: [u8; 32] = std::array::from_fn(|i| {
        let hex = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
        u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).expect("hex")
    });
    assert_eq!(LogReadingRecord::of_logs(true, &[sha_abc]).log_digests, vec![GOLDEN_V6_READING.1[0]]);
}

#[test]
fn golden_v7_blob_is_reproduced_byte_for_byte_by_todays_writer() {
    let golden = read_golden(GOLDEN_V7_BLOB);
    let today = encode(&golden_model_v7()).expect("encodes");
    assert_eq!(u16_at(&golden, FILE_VERSION.start), 7);
    assert!(today == golden, "the writer's output for the version-7 golden model changed");
    // Version 7 is version 6 with the log-shape record after the log-reading record, counted
    // here by hand: 2 lines skipped (u32), the delimiter code 1 and ';', the comment flag 1
    // and "//", then 5 column names, each a length byte and its UTF-8.
    let v6 = read_golden(GOLDEN_V6_BLOB);
    let v6_end = v6.len() - CRC_LEN;
    let axes_end = names_offset(&v6);
    assert_eq!(golden[FILE_HEADER_LEN..axes_end], v6[FILE_HEADER_LEN..axes_end]);
    let mut expected = v6[axes_end + 4..v6_end].to_vec();
    expected.extend_from_slice(&[2, 0, 0, 0, 1, b';', 1, 2, b'/', b'/', 5]);
    for name in ["Zeit [ms]", "gyro_x", "temp_c", "Drehrate Y (°/h)", "T_y"] {
        expected.push(name.len() as u8);
        expected.extend_from_slice(name.as_bytes());
    }
    let names = &golden[axes_end..golden.len() - CRC_LEN];
    assert_eq!(u32_at(names, 0) as usize, 4 + expected.len());
    assert_eq!(names[4..], expected[..]);
    // Read back as written.
    let model = Model::from_bytes(&golden).expect("parses");
    assert_eq!(LogShapeRecord::of(&model), golden_shape_v7());
    // The default shape is not recorded: version 6, byte for byte.
    assert!(encode(&golden_model_v6()).expect("encodes") == v6);
    let mut default_shape = golden_model_v7();
    default_shape.log_reading.shape = LogShapeRecord::default();
    assert!(encode(&default_shape).expect("encodes") == v6);
}

#[test]
fn golden_v8_blob_is_reproduced_byte_for_byte_by_todays_writer() {
    let golden = read_golden(GOLDEN_V8_BLOB);
    let today = encode(&golden_model_v8()).expect("encodes");
    assert_eq!(u16_at(&golden, FILE_VERSION.start), 8);
    assert!(today == golden, "the writer's output for the version-8 golden model changed");
    // Version 8 is version 6 with the default log-shape record written out (0 lines skipped
    // as a u32, delimiter code 0 and byte 0, comment flag 1 and the prefix "#", 0 column
    // names), then the run-metadata record: 1, the rates taken off.
    let v6 = read_golden(GOLDEN_V6_BLOB);
    let v6_end = v6.len() - CRC_LEN;
    let axes_end = names_offset(&v6);
    assert_eq!(golden[FILE_HEADER_LEN..axes_end], v6[FILE_HEADER_LEN..axes_end]);
    let mut expected = v6[axes_end + 4..v6_end].to_vec();
    expected.extend_from_slice(&[0, 0, 0, 0, 0, 0, 1, 1, b'#', 0, 1]);
    let names = &golden[axes_end..golden.len() - CRC_LEN];
    assert_eq!(u32_at(names, 0) as usize, 4 + expected.len());
    assert_eq!(names[4..], expected[..]);
    let model = Model::from_bytes(&golden).expect("parses");
    assert_eq!(model.input_rates(), Some(InputRates::Subtracted));
    assert_eq!(LogShapeRecord::of(&model), LogShapeRecord::default());
    // With a shape other than the default, the record follows that shape's record.
    let shaped = encode(&ModelFile { input_rates: Some(InputRates::NotSubtracted), ..golden_model_v7() })
        .expect("encodes");
    let shaped_model = Model::from_bytes(&shaped).expect("parses");
    assert_eq!(u16_at(&shaped, FILE_VERSION.start), 8);
    assert_eq!(shaped_model.input_rates(), Some(InputRates::NotSubtracted));
    assert_eq!(LogShapeRecord::of(&shaped_model), golden_shape_v7());
    let v7 = read_golden(GOLDEN_V7_BLOB);
    let mut v7_records = v7[axes_end + 4..v7.len() - CRC_LEN].to_vec();
    v7_records.push(2);
    assert_eq!(shaped[axes_end + 4..shaped.len() - CRC_LEN], v7_records[..]);
    // A shape the log-shape record cannot hold is written as the default one (read as not
    // recorded, as version 6 has it), and the rates are kept after it: the golden's bytes
    // (review31a F4: until 2026-11-30 the rates were dropped with the shape).
    let mut unstorable = golden_model_v8();
    unstorable.log_reading.shape.column_names = vec!["a\tb".into()];
    let blob = encode(&unstorable).expect("encodes");
    assert!(blob == golden, "an unstorable shape with rates is the default shape with rates");
    assert_eq!(Model::from_bytes(&blob).expect("parses").input_rates(), Some(InputRates::Subtracted));
}

#[test]
fn a_log_shape_the_record_cannot_hold_is_not_recorded() {
    let version_of = |shape: LogShapeRecord| {
        let mut model = golden_model_v6();
        model.log_reading.shape = shape;
        let blob = encode(&model).expect("encodes");
        (u16_at(&blob, FILE_VERSION.start), LogShapeRecord::of(&Model::from_bytes(&blob).expect("parses")))
    };
    let shape = golden_shape_v7();
    for bad in [
        LogShapeRecord { skip_lines: u64::from(u32::MAX) + 1, ..shape.clone() },
        LogShapeRecord { delimiter: Delimiter::Byte(b'"'), ..shape.clone() },
        LogShapeRecord { delimiter: Delimiter::Byte(0xe9), ..shape.clone() },
        LogShapeRecord { comment: Some(String::new()), ..shape.clone() },
        LogShapeRecord { column_names: vec!["a".into(), String::new()], ..shape.clone() },
        LogShapeRecord { column_names: vec!["a\tb".into()], ..shape.clone() },
        LogShapeRecord { column_names: (0..256).map(|i| format!("c{i}")).collect(), ..shape.clone() },
    ] {
        assert_eq!(version_of(bad.clone()), (6, LogShapeRecord::default()), "{bad:?}");
    }
    // At the limits: stored and read back.
    for good in [
        LogShapeRecord { skip_lines: u64::from(u32::MAX), ..shape.clone() },
        LogShapeRecord { delimiter: Delimiter::Whitespace, comment: None, ..shape.clone() },
        LogShapeRecord { delimiter: Delimiter::Byte(b'\t'), column_names: Vec::new(), ..shape.clone() },
        LogShapeRecord { column_names: (0..255).map(|i| format!("c{i}")).collect(), ..shape.clone() },
    ] {
        assert_eq!(version_of(good.clone()), (7, good.clone()), "{good:?}");
    }
}

/// Where the names section starts: after the axis sections.
fn names_offset(blob: &[u8]) -> usize {
    let axes = usize::from(u16_at(blob, FILE_AXIS_COUNT.start));
    (0..axes).fold(FILE_HEADER_LEN, |at, _| at + u32_at(blob, at + AXIS_SECTION_LEN.start) as usize)
}

#[test]
fn a_log_time_the_record_cannot_hold_is_not_recorded() {
    let written = |time: LogTimeRecord| {
        let mut model = golden_model_v5();
        model.log_time = time;
        let blob = encode(&model).expect("encodes");
        let version = u16_at(&blob, FILE_VERSION.start);
        (
            version,
            Model::from_bytes(&blob)
                .expect("parses")
                .log_time()
                .map(|t| (t.column.to_string(), t.sample_rate_hz)),
        )
    };
    let ms = LogTimeUnit::Milliseconds;
    // A rate with a time column, a date column without date-times, a control character: written as not recorded (version 5, nothing read back).
    for bad in [
        LogTimeRecord { column: "t".into(), sample_rate_hz: 50.0, ..Default::default() },
        LogTimeRecord { column: "t".into(), date_column: "d".into(), unit: ms, sample_rate_hz: 0.0 },
        LogTimeRecord { column: "t\n".into(), ..Default::default() },
    ] {
        assert_eq!(written(bad.clone()), (5, None), "{bad:?}");
    }
    // Nothing recorded (a negative rate records nothing either): version 4.
    assert_eq!(written(LogTimeRecord { sample_rate_hz: -1.0, ..Default::default() }), (4, None));
    // Nothing recorded: version 4. A rate alone: the record of a log without a time column.
    assert_eq!(written(LogTimeRecord::default()), (4, None));
    assert_eq!(
        written(LogTimeRecord { sample_rate_hz: 50.0, ..Default::default() }),
        (5, Some((String::new(), 50.0)))
    );
}

#[test]
fn column_names_are_one_per_axis_and_a_name_the_section_cannot_hold_is_not_recorded() {
    let mut model = golden_model_v4();
    model.columns.pop();
    match encode(&model) {
        Err(CalError::Encode(fogtemp_cal::error::EncodeProblem::ColumnNameCount { names: 1, axes: 2 })) => {}
        other => panic!("one pair for two axes: {other:?}"),
    }
    let mut model = golden_model_v4();
    model.columns[0].gyro = "g".repeat(256);
    model.columns[1].temp = "tab\there".into();
    let blob = encode(&model).expect("encodes");
    let parsed = Model::from_bytes(&blob).expect("parses");
    let (a0, a1) = (parsed.axis_columns(0).expect("axis 0"), parsed.axis_columns(1).expect("axis 1"));
    assert_eq!((a0.gyro, a0.temp), ("", "temp_c"));
    assert_eq!((a1.gyro, a1.temp), ("Drehrate Y (°/h)", ""));
    // 255 bytes is the longest name kept.
    model.columns[0].gyro = "g".repeat(255);
    let blob = encode(&model).expect("encodes");
    assert_eq!(Model::from_bytes(&blob).expect("parses").axis_columns(0).expect("axis 0").gyro.len(), 255);
}

// ---------------------------------------------------------------------------------------------
// 3. Corruption
// ---------------------------------------------------------------------------------------------

const MASKS: [u8; 9] = [0x01, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40, 0x80, 0xFF];

#[test]
fn every_single_byte_flip_is_rejected_by_the_crc_or_length_checks() {
    // CRC-32 detects every error burst of up to 32 bits, so no single-byte change can pass.
    let blob = two_kb_blob();
    assert!((1800..2300).contains(&blob.len()), "{} bytes", blob.len());
    for at in 0..blob.len() {
        for mask in MASKS {
            let mut b = blob.clone();
            b[at] ^= mask;
            let result = Model::from_bytes(&b);
            assert!(result.is_err(), "flip {mask:#04x} at {at} accepted");
        }
    }
}

#[test]
fn every_single_byte_flip_with_crc_recomputed_is_rejected_or_evaluates_without_panic() {
    let blob = two_kb_blob();
    let mut outcomes: BTreeMap<String, usize> = BTreeMap::new();
    let mut evaluations = 0;
    for at in 0..blob.len() - CRC_LEN {
        for mask in MASKS {
            let mut b = blob.clone();
            b[at] ^= mask;
            let (outcome, n) = read_mutant(&mut b, at as u64)
                .unwrap_or_else(|_| panic!("panic on flip {mask:#04x} at byte {at}"));
            *outcomes.entry(outcome).or_default() += 1;
            evaluations += n;
        }
    }
    println!("single-byte flips with CRC fixed: {outcomes:?}; {evaluations} evaluations of accepted mutants");
    assert!(outcomes.get("accepted").copied().unwrap_or(0) > 0, "some flips (values, provenance) are valid");
}

#[test]
fn every_truncation_is_rejected() {
    let blob = two_kb_blob();
    for len in 0..blob.len() {
        assert!(Model::from_bytes(&blob[..len]).is_err(), "truncated to {len} accepted");
        // Even with total_len and CRC patched to match, a cut section cannot be accepted.
        let mut b = blob[..len].to_vec();
        fix_len_and_crc(&mut b);
        assert!(Model::from_bytes(&b).is_err(), "truncated to {len} with length and CRC fixed accepted");
    }
}

/// Reads the mutant `b` after fixing its CRC: `("accepted", evaluations)` after exercising
/// every read-side API with `seed`, or `(variant, 0)` for the error; `Err` if anything panicked.
fn read_mutant(b: &mut [u8], seed: u64) -> std::thread::Result<(String, usize)> {
    fix_crc(b);
    let b: &[u8] = b;
    catch_unwind(AssertUnwindSafe(|| match Model::from_bytes(b) {
        Ok(model) => (String::from("accepted"), exercise(&model, seed)),
        Err(e) => (variant(&e), 0),
    }))
}

/// The name of an error variant (for statistics).
fn variant(e: &Error) -> String {
    let s = format!("{e:?}");
    s.split([' ', '{', '(']).next().unwrap_or("").to_string()
}

/// One structured mutation of a valid blob.
#[derive(Clone, Debug)]
enum Mutation {
    /// Overwrite one byte.
    Byte { at: usize, value: u8 },
    /// Overwrite an aligned u32 (counts, indices, neighbours, hull entries).
    Word { at: usize, value: u32 },
    /// Overwrite an aligned f32 with a special value.
    Float { at: usize, value: f32 },
    /// Change one of axis 0's counts by `delta`, inserting or removing records (filled with
    /// `fill`) so that `section_len` and `total_len` stay consistent.
    Resize { which: usize, delta: i32, fill: u8 },
    /// Swap two 4-byte words.
    Swap { a: usize, b: usize },
}

fn interesting_u32(r: &mut impl Rng, blob: &[u8]) -> u32 {
    let s = section(blob, 0);
    let counts = [s.terms, s.vertices, s.triangles, s.hull].map(|c| c as u32);
    match r.gen_range(0..8) {
        0 => 0,
        1 => u32::MAX,
        2 => u32::MAX - 1,
        3 => counts[r.gen_range(0..4)],
        4 => counts[r.gen_range(0..4)].wrapping_sub(1),
        5 => r.gen_range(0..4),
        6 => 1 << r.gen_range(0..32),
        _ => r.gen(),
    }
}

fn interesting_f32(r: &mut impl Rng) -> f32 {
    const SPECIAL: [f32; 14] = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        0.0,
        -0.0,
        f32::MAX,
        f32::MIN,
        f32::MIN_POSITIVE,
        1.0e-45,
        1.0e6,
        1.000_000_1e6,
        -1.0e6,
        1.0,
        -1.0,
    ];
    if r.gen_bool(0.6) {
        SPECIAL[r.gen_range(0..SPECIAL.len())]
    } else {
        f32::from_bits(r.gen())
    }
}

fn random_mutation(r: &mut impl Rng, blob: &[u8]) -> Mutation {
    let body = blob.len() - CRC_LEN;
    let words = body / 4;
    match r.gen_range(0..10) {
        0 | 1 => Mutation::Byte { at: r.gen_range(0..body), value: r.gen() },
        2..=4 => Mutation::Word { at: 4 * r.gen_range(0..words), value: interesting_u32(r, blob) },
        5 | 6 => Mutation::Float { at: 4 * r.gen_range(0..words), value: interesting_f32(r) },
        7 | 8 => Mutation::Resize { which: r.gen_range(0..4), delta: r.gen_range(-2..=2), fill: r.gen() },
        _ => Mutation::Swap { a: 4 * r.gen_range(0..words), b: 4 * r.gen_range(0..words) },
    }
}

fn apply(b: &mut Vec<u8>, m: &Mutation) {
    let body = b.len() - CRC_LEN;
    let fits = |at: usize, n: usize| at + n <= body;
    match *m {
        Mutation::Byte { at, .. } if !fits(at, 1) => {}
        Mutation::Word { at, .. } | Mutation::Float { at, .. } if !fits(at, 4) => {}
        Mutation::Swap { a, b: c } if !fits(a, 4) || !fits(c, 4) => {}
        Mutation::Byte { at, value } => b[at] = value,
        Mutation::Word { at, value } => put_u32(b, at, value),
        Mutation::Float { at, value } => put_f32(b, at, value),
        Mutation::Swap { a, b: c } => {
            let (x, y) = (u32_at(b, a), u32_at(b, c));
            put_u32(b, a, y);
            put_u32(b, c, x);
        }
        Mutation::Resize { which, delta, fill } => {
            // Only meaningful while axis 0's header is intact enough to describe the layout.
            let s = section(b, 0);
            let (count_field, count, record_len, array_end) = match which {
                0 => (AXIS_POLY_TERM_COUNT, s.terms, POLY_TERM_LEN, s.vertex_at),
                1 => (AXIS_VERTEX_COUNT, s.vertices, VERTEX_LEN, s.triangle_at),
                2 => (AXIS_TRIANGLE_COUNT, s.triangles, TRIANGLE_LEN, s.hull_at),
                _ => (AXIS_HULL_EDGE_COUNT, s.hull, HULL_EDGE_LEN, s.hull_at + s.hull * HULL_EDGE_LEN),
            };
            if array_end > body || count > 1 << 20 {
                return;
            }
            let new_count = count as i64 + i64::from(delta);
            if new_count < 0 {
                return;
            }
            let bytes = (delta.unsigned_abs() as usize) * record_len;
            if delta > 0 {
                b.splice(array_end..array_end, std::iter::repeat_n(fill, bytes));
            } else if delta < 0 {
                if bytes > count * record_len {
                    return;
                }
                b.drain(array_end - bytes..array_end);
            }
            put_u32(b, s.start + count_field.start, new_count as u32);
            let section_len =
                u32_at(b, s.start + AXIS_SECTION_LEN.start) as i64 + i64::from(delta) * record_len as i64;
            put_u32(b, s.start + AXIS_SECTION_LEN.start, section_len as u32);
            fix_len_and_crc(b);
        }
    }
}

#[test]
fn random_mutations_with_crc_recomputed_never_panic_and_accepted_ones_evaluate() {
    let blobs = [two_kb_blob(), encode(&three_axis_model()).expect("encodes")];
    let mut r = rng(0xFEED);
    let mut outcomes: BTreeMap<String, usize> = BTreeMap::new();
    let mut evaluations = 0usize;
    let panics_dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("blob-mutation-panics");
    for case in 0..20_000u64 {
        let base = &blobs[(case % 2) as usize];
        let mut b = base.clone();
        let mut mutations = Vec::new();
        for _ in 0..r.gen_range(1..=4) {
            // Each mutation is drawn against the current (possibly resized) bytes.
            let m = random_mutation(&mut r, &b);
            apply(&mut b, &m);
            mutations.push(m);
        }
        let Ok((outcome, n)) = read_mutant(&mut b, case) else {
            std::fs::create_dir_all(&panics_dir).expect("dir");
            let path = panics_dir.join(format!("case-{case}.fogm"));
            std::fs::write(&path, &b).expect("write");
            panic!("case {case}: panic after {mutations:?}; bytes in {}", path.display());
        };
        *outcomes.entry(outcome).or_default() += 1;
        evaluations += n;
    }
    println!("20000 mutants with CRC fixed: {outcomes:?}; {evaluations} evaluations of accepted mutants");
    assert!(outcomes.len() >= 6, "mutations reach many different checks: {outcomes:?}");
}

// ---------------------------------------------------------------------------------------------
// 4. Targeted corruptions (CRC recomputed): each gives its specific error
// ---------------------------------------------------------------------------------------------

fn mutated(f: impl FnOnce(&mut Vec<u8>, Section)) -> Result<(), Error> {
    let mut b = two_kb_blob();
    let s = section(&b, 0);
    f(&mut b, s);
    fix_crc(&mut b);
    Model::from_bytes(&b).map(|_| ())
}

/// Finds a triangle slot `(t, k)` satisfying `want` in axis 0 of `b`.
fn find_slot(b: &[u8], s: Section, want: impl Fn(u32) -> bool) -> (usize, usize) {
    for t in 0..s.triangles {
        for k in 0..3 {
            if want(u32_at(b, s.triangle_at + 60 * t + TRI_NEIGHBOURS.start + 4 * k)) {
                return (t, k);
            }
        }
    }
    panic!("no such slot");
}

#[test]
fn a_wrong_section_len_names_its_axis() {
    let mut b = encode(&three_axis_model()).expect("encodes");
    let s = section(&b, 2);
    let stored = u32_at(&b, s.start + AXIS_SECTION_LEN.start) as usize;
    put_u32(&mut b, s.start + AXIS_SECTION_LEN.start, stored as u32 + 8);
    fix_crc(&mut b);
    let e = Model::from_bytes(&b).expect_err("refused");
    assert_eq!(e, Error::SectionLength { axis: 2, expected: stored, found: stored + 8 });
    assert_eq!(
        e.to_string(),
        format!("axis 2: section_len is {} but the counts in its header imply {stored}", stored + 8)
    );
}

#[test]
fn targeted_header_corruptions_give_their_specific_errors() {
    let r = mutated(|b, _| b[0] = b'X');
    assert!(matches!(r, Err(Error::BadMagic)), "{r:?}");
    let r = mutated(|b, _| put_u16(b, FILE_VERSION.start, 9));
    assert!(matches!(r, Err(Error::UnsupportedVersion { expected: 8, found: 9 })), "{r:?}");
    let r = mutated(|b, _| put_u16(b, FILE_VERSION.start, 0));
    assert!(matches!(r, Err(Error::UnsupportedVersion { expected: 8, found: 0 })), "{r:?}");
    // Versions 4 to 8 have a names section after the axes: a blob without one ends early.
    for version in 4..=8 {
        let r = mutated(|b, _| put_u16(b, FILE_VERSION.start, version));
        assert!(matches!(r, Err(Error::Truncated { field: "names_len", .. })), "{version}: {r:?}");
    }
    // Version 3 differs from 2 only with outside_policy 3: this blob reads the same as either.
    assert!(mutated(|b, _| put_u16(b, FILE_VERSION.start, 3)).is_ok());
    for count in [0u16, 17, u16::MAX] {
        let r = mutated(|b, _| put_u16(b, FILE_AXIS_COUNT.start, count));
        let expected = Error::BadHeaderValue { field: "axis_count", found: u64::from(count) };
        assert_eq!(r.err(), Some(expected), "axis_count {count}");
    }
    let message = mutated(|b, _| put_u16(b, FILE_AXIS_COUNT.start, 0)).err().map(|e| e.to_string());
    assert_eq!(message.as_deref(), Some("file header: axis_count is 0, outside 1..=16"));
    let r = mutated(|b, _| put_u16(b, FILE_AXIS_COUNT.start, 2));
    assert!(matches!(r, Err(Error::Truncated { .. })), "a second axis that is not there: {r:?}");
    let r = mutated(|b, _| put_u16(b, FILE_HEADER_LEN_FIELD.start, 65));
    assert!(matches!(r, Err(Error::LengthMismatch { field: "header_len", .. })), "{r:?}");
    let r = mutated(|b, _| put_u16(b, FILE_RESERVED.start, 1));
    assert_eq!(r.err(), Some(Error::BadHeaderValue { field: "reserved", found: 1 }));
    // total_len is checked against the slice before the CRC.
    let r = mutated(|b, _| {
        let n = b.len() as u32;
        put_u32(b, FILE_TOTAL_LEN.start, n + 1);
    });
    assert!(matches!(r, Err(Error::Truncated { field: "total_len", .. })), "{r:?}");
    // A slice longer than the blob (a flash partition's padding) names what to use instead.
    let mut padded = two_kb_blob();
    let blob_len = padded.len();
    padded.extend_from_slice(&[0xFF; 16]);
    let message = Model::from_bytes(&padded).err().map(|e| e.to_string()).unwrap_or_default();
    assert_eq!(
        message,
        format!(
            "total_len says the blob is {blob_len} bytes but {} were given: bytes after the blob \
             (a flash partition's padding is read with Model::from_flash)",
            blob_len + 16
        )
    );
    assert!(Model::from_flash(&padded).is_ok());
    // CRC not recomputed.
    let mut b = two_kb_blob();
    b[100] ^= 1;
    assert!(matches!(Model::from_bytes(&b), Err(Error::CrcMismatch { .. })));
    assert!(matches!(Model::from_bytes(&b[..10]), Err(Error::Truncated { .. })));
}

#[test]
fn targeted_axis_corruptions_give_their_specific_errors() {
    let r = mutated(|b, s| put_u16(b, s.start + AXIS_ID.start, 1));
    assert!(matches!(r, Err(Error::BadValue { field: "axis_id", .. })), "{r:?}");
    let r = mutated(|b, s| put_u16(b, s.start + AXIS_MODEL_KIND.start, 4));
    assert!(matches!(r, Err(Error::BadValue { field: "model_kind", .. })), "{r:?}");
    // Codes 0 to 2 are policies (2, linear from the boundary, since the mesh's continuation).
    let r = mutated(|b, s| put_u32(b, s.start + AXIS_OUTSIDE_POLICY.start, 2));
    assert!(r.is_ok(), "{r:?}");
    // Code 3 (stored gradients) needs format version 3: in this version-2 blob it is refused by
    // name; 4 is no policy in any version.
    let r = mutated(|b, s| put_u32(b, s.start + AXIS_OUTSIDE_POLICY.start, 3));
    assert!(matches!(r, Err(Error::BadValue { field: "outside_policy", .. })), "{r:?}");
    let r = mutated(|b, s| {
        put_u16(b, FILE_VERSION.start, 3);
        put_u32(b, s.start + AXIS_OUTSIDE_POLICY.start, 4);
    });
    assert!(matches!(r, Err(Error::BadValue { field: "outside_policy", .. })), "{r:?}");
    let r = mutated(|b, s| b[s.start + AXIS_REGION_VERTEX_COUNT.start + 3] = 1);
    assert!(matches!(r, Err(Error::BadValue { field: "region_vertex_count", .. })), "{r:?}");
    let r = mutated(|b, s| put_u32(b, s.start + AXIS_POLY_OUTSIDE.start, 2));
    assert!(matches!(r, Err(Error::BadValue { field: "poly_outside", .. })), "{r:?}");
    let r = mutated(|b, s| put_u32(b, s.start + AXIS_SECTION_LEN.start, 96));
    assert!(matches!(r, Err(Error::SectionLength { axis: 0, .. })), "{r:?}");
    let r = mutated(|b, s| put_f32(b, s.start + AXIS_WINDOW_S.start, f32::NAN));
    assert!(matches!(r, Err(Error::NonFinite { field: "window_s", .. })), "{r:?}");
    let r = mutated(|b, s| put_f32(b, s.start + AXIS_TEMP_SCALE_PER_C.start, -1.0));
    assert!(matches!(r, Err(Error::BadValue { field: "temp_scale_per_c", .. })), "{r:?}");
    let r = mutated(|b, s| put_u32(b, s.start + AXIS_BLOCK_COUNT.start, 5000));
    assert!(matches!(r, Err(Error::BadValue { field: "block_count", .. })), "{r:?}");
    let r = mutated(|b, s| put_f32(b, s.start + AXIS_RESIDUAL_RMS_DPH.start, f32::INFINITY));
    assert!(matches!(r, Err(Error::NonFinite { field: "residual_rms_dph", .. })), "{r:?}");
    let r = mutated(|b, s| b[s.poly_at] = 7);
    assert!(matches!(r, Err(Error::BadValue { field: "poly_terms", .. })), "{r:?}");
    let r = mutated(|b, s| put_f32(b, s.poly_at + 4, f32::NAN));
    assert!(matches!(r, Err(Error::NonFinite { field: "poly_terms.coefficient_dph", .. })), "{r:?}");
}

#[test]
fn targeted_mesh_corruptions_give_their_specific_errors() {
    // A NaN vertex.
    let r = mutated(|b, s| put_f32(b, s.vertex_at + 12 * 3, f32::NAN));
    assert!(matches!(r, Err(Error::NonFinite { field: "vertices.x", index: 3, .. })), "{r:?}");
    let r = mutated(|b, s| put_f32(b, s.vertex_at + 12 * 2 + 8, f32::INFINITY));
    assert!(matches!(r, Err(Error::NonFinite { field: "vertices.value_dph", index: 2, .. })), "{r:?}");
    let r = mutated(|b, s| put_f32(b, s.vertex_at + 4, 2.0e6));
    assert!(matches!(r, Err(Error::BadValue { field: "vertices.y", .. })), "{r:?}");
    // A neighbour index out of range, and pointing at itself.
    let r = mutated(|b, s| {
        let (t, k) = find_slot(b, s, |n| n != NO_NEIGHBOUR);
        put_u32(b, s.triangle_at + 60 * t + TRI_NEIGHBOURS.start + 4 * k, s.triangles as u32);
    });
    assert!(matches!(r, Err(Error::IndexOutOfRange { field: "triangles.neighbours", .. })), "{r:?}");
    let r = mutated(|b, s| {
        let (t, k) = find_slot(b, s, |n| n != NO_NEIGHBOUR);
        put_u32(b, s.triangle_at + 60 * t + TRI_NEIGHBOURS.start + 4 * k, t as u32);
    });
    assert!(matches!(r, Err(Error::IndexOutOfRange { field: "triangles.neighbours", .. })), "{r:?}");
    // Asymmetric neighbours: one slot points at a valid triangle that does not point back.
    let r = mutated(|b, s| {
        let (t, k) = find_slot(b, s, |n| n != NO_NEIGHBOUR);
        let at = s.triangle_at + 60 * t + TRI_NEIGHBOURS.start;
        let current: Vec<u32> = (0..3).map(|j| u32_at(b, at + 4 * j)).collect();
        let other = (0..s.triangles as u32)
            .find(|&o| o != t as u32 && !current.contains(&o))
            .expect("another triangle");
        put_u32(b, at + 4 * k, other);
    });
    assert!(matches!(r, Err(Error::BadMesh { check: "neighbours symmetric", .. })), "{r:?}");
    // A hull slot turned into an interior slot: hull count no longer matches.
    let r = mutated(|b, s| {
        let (t, k) = find_slot(b, s, |n| n == NO_NEIGHBOUR);
        put_u32(b, s.triangle_at + 60 * t + TRI_NEIGHBOURS.start + 4 * k, 0);
    });
    assert!(matches!(r, Err(Error::IndexOutOfRange { .. } | Error::BadMesh { .. })), "{r:?}");
    // Vertex index out of range, repeated vertex, clockwise triangle.
    let r = mutated(|b, s| put_u32(b, s.triangle_at + TRI_VERTICES.start, s.vertices as u32));
    assert!(matches!(r, Err(Error::IndexOutOfRange { field: "triangles.vertices", .. })), "{r:?}");
    let r = mutated(|b, s| {
        let v1 = u32_at(b, s.triangle_at + TRI_VERTICES.start + 4);
        put_u32(b, s.triangle_at + TRI_VERTICES.start, v1);
    });
    assert!(matches!(r, Err(Error::BadMesh { check: "distinct vertices", .. })), "{r:?}");
    let r = mutated(|b, s| {
        let at = s.triangle_at + TRI_VERTICES.start;
        let (v0, v1) = (u32_at(b, at), u32_at(b, at + 4));
        put_u32(b, at, v1);
        put_u32(b, at + 4, v0);
    });
    assert!(matches!(r, Err(Error::BadMesh { check: "counter-clockwise", .. })), "{r:?}");
    // Transforms: origin, barycentric transform and plane of another triangle.
    let r = mutated(|b, s| put_f32(b, s.triangle_at + TRI_ORIGIN.start, 0.123));
    assert!(matches!(r, Err(Error::BadMesh { check: "origin is vertex 2", .. })), "{r:?}");
    let r = mutated(|b, s| put_f32(b, s.triangle_at + TRI_BARY.start, f32::NAN));
    assert!(matches!(r, Err(Error::NonFinite { field: "triangles.bary", .. })), "{r:?}");
    let r = mutated(|b, s| {
        let (from, to) = (s.triangle_at + 60 + TRI_BARY.start, s.triangle_at + TRI_BARY.start);
        let other: Vec<u8> = b[from..from + 16].to_vec();
        b[to..to + 16].copy_from_slice(&other);
    });
    assert!(matches!(r, Err(Error::BadMesh { check: "barycentric transform", .. })), "{r:?}");
    let r = mutated(|b, s| {
        let at = s.triangle_at + TRI_PLANE.start;
        let p0 = f32::from_le_bytes(b[at..at + 4].try_into().expect("4"));
        put_f32(b, at, p0 + 10.0);
    });
    assert!(matches!(r, Err(Error::BadMesh { check: "value plane", .. })), "{r:?}");
}

#[test]
fn targeted_hull_corruptions_give_their_specific_errors() {
    // A hull entry naming a slot that is not on the hull.
    let r = mutated(|b, s| {
        let (t, e) = (u32_at(b, s.hull_at) as usize, u32_at(b, s.hull_at + 4) as usize);
        let at = s.triangle_at + 60 * t + TRI_NEIGHBOURS.start;
        let inner = (0..3).find(|&k| k != e && u32_at(b, at + 4 * k) != NO_NEIGHBOUR);
        match inner {
            Some(k) => put_u32(b, s.hull_at + 4, k as u32),
            None => put_u32(b, s.hull_at + 4, 3), // edge index 3 is never a hull slot
        }
    });
    assert!(matches!(r, Err(Error::BadMesh { check: "hull entry is a hull edge", index: 0, .. })), "{r:?}");
    let r = mutated(|b, s| put_u32(b, s.hull_at + 4, 3));
    assert!(matches!(r, Err(Error::BadMesh { check: "hull entry is a hull edge", .. })), "{r:?}");
    let r = mutated(|b, s| put_u32(b, s.hull_at, s.triangles as u32));
    assert!(matches!(r, Err(Error::IndexOutOfRange { field: "hull.triangle", .. })), "{r:?}");
    // Two hull entries swapped: still hull slots, no longer chained.
    let r = mutated(|b, s| {
        let (a, c) = (s.hull_at, s.hull_at + 8);
        let (x, y) = (b[a..a + 8].to_vec(), b[c..c + 8].to_vec());
        b[a..a + 8].copy_from_slice(&y);
        b[c..c + 8].copy_from_slice(&x);
    });
    assert!(matches!(r, Err(Error::BadMesh { check: "hull chained", .. })), "{r:?}");
    // Wrong hull count (section length adjusted so the count check itself is reached).
    let mut b = two_kb_blob();
    apply(&mut b, &Mutation::Resize { which: 3, delta: 1, fill: 0 });
    let r = Model::from_bytes(&b);
    assert!(matches!(r, Err(Error::LengthMismatch { field: "hull_edge_count", .. })), "{r:?}");
}

// ---------------------------------------------------------------------------------------------
// 5. Validation gaps found by these tests (fail until crates/fogtemp-core is fixed)
// ---------------------------------------------------------------------------------------------

fn vertex(x: f32, y: f32, value_dph: f32) -> Vertex {
    Vertex { x, y, value_dph }
}

/// Encodes a hand-made mesh. Returns `Err` if the writer's self-check (the core reader) already
/// rejects it.
fn encode_mesh(mesh: MeshModel) -> Result<Vec<u8>, Error> {
    let axis = AxisModel {
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
        features: FEATURES,
        normalisation: NORMALISATION,
        outside_policy: OutsidePolicy::NearestHull,
        poly: Vec::new(),
        mesh: Some(mesh),
        provenance: provenance(1.0),
    };
    match encode(&ModelFile {
        tool_version: "crafted".into(),
        input_digest: [0; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    }) {
        Ok(b) => Ok(b),
        Err(CalError::SelfCheck(e)) => Err(e),
        Err(e) => panic!("crafted mesh does not encode: {e}"),
    }
}

/// One triangle whose vertices are all more than 1 away from vertex 2 in both coordinates,
/// so a transform coefficient of `f32::MAX` overflows at vertices 0 and 1.
fn big_triangle() -> MeshModel {
    MeshModel {
        // Relative to vertex 2 at the origin: a = (-4, 5), b = (4, -8); counter-clockwise.
        vertices: vec![vertex(-4.0, 5.0, 0.1), vertex(4.0, -8.0, 0.2), vertex(0.0, 0.0, 0.3)],
        triangles: vec![[0, 1, 2]],
        neighbours: vec![[NO_NEIGHBOUR; 3]],
        hull: vec![(0, 2), (0, 0), (0, 1)],
        merged_duplicates: 0,
        dropped_flat: Vec::new(),
        moved_flat: Vec::new(),
    }
}

#[test]
fn transform_that_evaluates_to_nan_at_its_vertices_is_rejected() {
    // Stored coefficients of f32::MAX are finite, but at vertices 0 and 1 they give
    // inf - inf = NaN. The validator compares `|l - expected| > tol`, which is false for NaN,
    // so the transform passes as "reproducing the vertices".
    let clean = encode_mesh(big_triangle()).expect("the honest triangle is valid");
    let s = section(&clean, 0);
    for (what, range) in
        [("barycentric transform", TRI_BARY), ("value plane", TRI_PLANE.start..TRI_PLANE.start + 8)]
    {
        let mut b = clean.clone();
        for at in range.step_by(4) {
            put_f32(&mut b, s.triangle_at + at, f32::MAX);
        }
        fix_crc(&mut b);
        let result = Model::from_bytes(&b);
        let detail = result.as_ref().ok().map(|m| {
            let mesh = m.axis(0).expect("axis").mesh.expect("mesh");
            // The centroid of the only triangle.
            let (x, y) = (0.0f32, -1.0f32);
            (mesh.locate(x, y, &mut WalkHint::default()), mesh.interpolate(x, y, &mut WalkHint::default()))
        });
        assert!(
            matches!(result, Err(Error::BadMesh { check, .. }) if check == what),
            "a {what} of f32::MAX was accepted; at the centroid of the triangle: {detail:?}"
        );
    }
}

/// Two separate pieces: a triangle split at an interior point (3 triangles, hull of 3 slots)
/// and a lone triangle (3 hull slots). Its hull list names the first piece's loop twice:
/// 6 entries = 6 hull slots <= triangle count + 2, each a hull slot, chained, turning left.
fn two_pieces_with_hull_listed_twice() -> MeshModel {
    MeshModel {
        vertices: vec![
            vertex(0.0, 0.0, 0.0),  // 0 A
            vertex(4.0, 0.0, 0.4),  // 1 B
            vertex(0.0, 4.0, 0.8),  // 2 C
            vertex(1.0, 1.0, 0.2),  // 3 D (interior)
            vertex(10.0, 0.0, 5.0), // 4 E
            vertex(12.0, 0.0, 5.0), // 5 F
            vertex(10.0, 2.0, 5.0), // 6 G
        ],
        triangles: vec![[0, 1, 3], [1, 2, 3], [2, 0, 3], [4, 5, 6]],
        neighbours: vec![[1, 2, NO_NEIGHBOUR], [2, 0, NO_NEIGHBOUR], [0, 1, NO_NEIGHBOUR], [NO_NEIGHBOUR; 3]],
        hull: vec![(0, 2), (1, 2), (2, 2), (0, 2), (1, 2), (2, 2)],
        merged_duplicates: 0,
        dropped_flat: Vec::new(),
        moved_flat: Vec::new(),
    }
}

#[test]
fn hull_that_does_not_go_round_exactly_once_is_rejected() {
    let Ok(b) = encode_mesh(two_pieces_with_hull_listed_twice()) else {
        return; // the writer's self-check (the core reader) rejected it: fixed
    };
    let result = Model::from_bytes(&b);
    let detail = result.as_ref().ok().map(|m| {
        let mesh = m.axis(0).expect("axis").mesh.expect("mesh");
        // A point inside the lone triangle: the answer depends on the hint.
        let (x, y) = (10.5f32, 0.5f32);
        (
            mesh.interpolate(x, y, &mut WalkHint(0)),
            mesh.interpolate(x, y, &mut WalkHint(3)),
            mesh.locate_by_scan(x, y),
        )
    });
    assert!(
        matches!(result, Err(Error::BadMesh { .. })),
        "a disconnected mesh whose hull list goes round one piece twice was accepted; inside the \
         other piece, (hint 0, hint 3, scan) give {detail:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// 5. Stored hull gradients (format version 3, outside_policy 3)
// ---------------------------------------------------------------------------------------------

/// The mesh of [`two_kb_blob`] with the policy `StoredGradients`, and the blob.
fn gradient_blob() -> (MeshModel, Vec<u8>) {
    let axis = two_kb_axis(OutsidePolicy::StoredGradients);
    let mesh = axis.mesh.clone().expect("the axis has a mesh");
    let blob = encode(&ModelFile {
        tool_version: "fogtemp grad".into(),
        input_digest: [3; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    })
    .expect("encodes");
    (mesh, blob)
}

/// Byte offset of axis 0's hull gradients (after its hull; these blobs have no region).
fn gradients_at(s: &Section) -> usize {
    s.hull_at + s.hull * HULL_EDGE_LEN
}

#[test]
fn stored_gradients_are_written_as_version_3_after_the_hull_and_read_back_bit_exactly() {
    let (mesh, blob) = gradient_blob();
    assert_eq!(u16_at(&blob, FILE_VERSION.start), 3);
    let s = section(&blob, 0);
    // The writer numbers the hull vertices first (hull vertex h is vertex h), then fits.
    let renumbered = fogtemp_cal::blob::hull_vertices_first(&mesh).expect("renumbers");
    let expected = fogtemp_cal::blob::hull_gradients(&renumbered).expect("gradients");
    assert_eq!(expected.len(), s.hull);
    // The section: the version-2 layout plus one 8-byte gradient per hull edge, then the CRC.
    assert_eq!(
        u32_at(&blob, s.start + AXIS_SECTION_LEN.start) as usize,
        gradients_at(&s) + 8 * s.hull - s.start
    );
    assert_eq!(gradients_at(&s) + 8 * s.hull + CRC_LEN, blob.len());
    let model = Model::from_bytes(&blob).expect("parses");
    assert_eq!(model.format_version(), 3);
    let read = model.axis(0).expect("axis").mesh.expect("mesh");
    assert_eq!(read.outside_policy(), OutsidePolicy::StoredGradients);
    for (h, g) in expected.iter().enumerate() {
        let at = gradients_at(&s) + 8 * h;
        let stored = [
            f32::from_le_bytes(blob[at..at + 4].try_into().expect("4")),
            f32::from_le_bytes(blob[at + 4..at + 8].try_into().expect("4")),
        ];
        assert_eq!(stored.map(bits), g.map(bits), "hull gradient {h} in the bytes");
        assert_eq!(read.hull_gradient(h as u32).map(|g| g.map(bits)), Some(g.map(bits)), "hull gradient {h}");
    }
    assert!(read.hull_gradient(s.hull as u32).is_none());
    for h in 0..s.hull as u32 {
        let (a, _) = read.hull_edge_vertices(h).expect("hull edge");
        let v = read.vertex(h).expect("vertex");
        assert_eq!(
            [a.x, a.y, a.value_dph].map(bits),
            [v.x, v.y, v.value_dph].map(bits),
            "hull vertex {h} is vertex {h}"
        );
    }
    // Renumbering moves no node: the same nodes, and the same value wherever the policies
    // agree (inside the hull), bit for bit.
    let held_model_bytes = two_kb_blob();
    let held_model = Model::from_bytes(&held_model_bytes).expect("parses");
    let held_mesh = held_model.axis(0).expect("axis").mesh.expect("mesh");
    let sorted = |m: &fogtemp_core::Mesh<'_>| {
        let mut v: Vec<[u32; 3]> = (0..m.vertex_count())
            .map(|i| m.vertex(i).expect("vertex"))
            .map(|v| [v.x, v.y, v.value_dph].map(bits))
            .collect();
        v.sort_unstable();
        v
    };
    assert_eq!(sorted(&read), sorted(&held_mesh));
    let mut r = rng(5);
    let mut inside = 0;
    for _ in 0..2000 {
        let (x, y) = (r.gen_range(-1.0f32..1.0), r.gen_range(-1.0f32..1.0));
        let a = read.interpolate(x, y, &mut WalkHint::default()).expect("finite");
        let b = held_mesh.interpolate(x, y, &mut WalkHint::default()).expect("finite");
        if !a.outside_hull {
            inside += 1;
            assert_eq!((bits(a.value_dph), a.triangle), (bits(b.value_dph), b.triangle), "({x}, {y})");
        }
    }
    assert!(inside > 100, "{inside} queries inside");
    // The same mesh held: version 2, no gradients, every other byte of the section the same.
    let held = two_kb_blob();
    assert_eq!(u16_at(&held, FILE_VERSION.start), 2);
    assert_eq!(held.len() + 8 * s.hull, blob.len());
    assert!(Model::from_bytes(&held)
        .expect("parses")
        .axis(0)
        .expect("axis")
        .mesh
        .expect("mesh")
        .hull_gradient(0)
        .is_none());
}

fn gradient_mutated(f: impl FnOnce(&mut Vec<u8>, Section)) -> Result<(), Error> {
    let (_, mut b) = gradient_blob();
    let s = section(&b, 0);
    f(&mut b, s);
    fix_crc(&mut b);
    Model::from_bytes(&b).map(|_| ())
}

#[test]
fn corrupt_or_missing_stored_gradients_give_their_specific_errors() {
    assert!(gradient_mutated(|_, _| {}).is_ok());
    for (k, v) in [(0, f32::NAN), (4, f32::INFINITY), (4, f32::NEG_INFINITY)] {
        let r = gradient_mutated(|b, s| put_f32(b, gradients_at(&s) + 8 * 2 + k, v));
        assert!(
            matches!(r, Err(Error::NonFinite { field: "hull_gradients", index: 2, .. })),
            "{v} at {k}: {r:?}"
        );
    }
    // Version 2 has no gradients: the policy is refused by name.
    let r = gradient_mutated(|b, _| put_u16(b, FILE_VERSION.start, 2));
    assert!(matches!(r, Err(Error::BadValue { field: "outside_policy", .. })), "{r:?}");
    // Another policy does not expect the gradients that are there.
    for code in [0, 1, 2] {
        let r = gradient_mutated(|b, s| put_u32(b, s.start + AXIS_OUTSIDE_POLICY.start, code));
        assert!(matches!(r, Err(Error::SectionLength { axis: 0, .. })), "code {code}: {r:?}");
    }
    let r = gradient_mutated(|b, s| put_u32(b, s.start + AXIS_OUTSIDE_POLICY.start, 4));
    assert!(matches!(r, Err(Error::BadValue { field: "outside_policy", .. })), "{r:?}");
    // The hull listed from its second vertex: still a valid hull, but hull vertex 0 is not
    // vertex 0, so a gradient could not be found by vertex index.
    let r = gradient_mutated(|b, s| b[s.hull_at..s.hull_at + 8 * s.hull].rotate_left(8));
    assert!(
        matches!(r, Err(Error::BadMesh { check: "hull vertices numbered first", index: 0, .. })),
        "{r:?}"
    );
    // The same hull order in a held blob is fine (no gradients to find).
    assert!(mutated(|b, s| b[s.hull_at..s.hull_at + 8 * s.hull].rotate_left(8)).is_ok());
    // One gradient short, with total_len and section_len patched to match: the count the hull
    // implies is not there.
    let r = gradient_mutated(|b, s| {
        let end = b.len() - CRC_LEN;
        b.drain(end - 8..end);
        let section_len = u32_at(b, s.start + AXIS_SECTION_LEN.start) - 8;
        put_u32(b, s.start + AXIS_SECTION_LEN.start, section_len);
        let total = b.len() as u32;
        put_u32(b, FILE_TOTAL_LEN.start, total);
    });
    assert!(matches!(r, Err(Error::SectionLength { axis: 0, .. })), "{r:?}");
}

#[test]
fn every_truncation_and_byte_flip_of_a_gradient_blob_is_rejected_or_evaluates_without_panic() {
    let (_, blob) = gradient_blob();
    for len in 0..blob.len() {
        assert!(Model::from_bytes(&blob[..len]).is_err(), "truncated to {len} accepted");
        let mut b = blob[..len].to_vec();
        fix_len_and_crc(&mut b);
        assert!(Model::from_bytes(&b).is_err(), "truncated to {len} with length and CRC fixed accepted");
    }
    let mut outcomes: BTreeMap<String, usize> = BTreeMap::new();
    let mut evaluations = 0;
    // The flips of the hull and gradient bytes and of the header (the rest is the layout of
    // the version-2 tests above).
    let s = section(&blob, 0);
    let positions = (0..FILE_HEADER_LEN + AXIS_HEADER_LEN).chain(s.hull_at..blob.len() - CRC_LEN);
    for at in positions {
        for mask in MASKS {
            let mut b = blob.clone();
            b[at] ^= mask;
            assert!(Model::from_bytes(&b).is_err(), "flip {mask:#04x} at {at} passed the CRC");
            let (outcome, n) = read_mutant(&mut b, at as u64)
                .unwrap_or_else(|_| panic!("panic on flip {mask:#04x} at byte {at}"));
            *outcomes.entry(outcome).or_default() += 1;
            evaluations += n;
        }
    }
    println!(
        "gradient blob flips with CRC fixed: {outcomes:?}; {evaluations} evaluations of accepted mutants"
    );
    assert!(outcomes.get("accepted").copied().unwrap_or(0) > 0, "finite gradient flips are valid");
}
