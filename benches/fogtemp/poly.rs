//! `poly/evaluate`: the paper's polynomial (11 terms plus a constant) per sample.
//!
//! Peers: `fogtemp_poly` (`Poly::evaluate`, terms read from the blob), `fogtemp_axis_evaluate`
//! (`Axis::evaluate` of a polynomial-only axis: finite checks, normalisation, polynomial)
//! and `inline_f32`, the same twelve terms written out by hand with the coefficients as
//! constants (what a code generator would emit; the floor for this arithmetic).

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput};
use fogtemp_core::{Model, WalkHint};

use crate::fixtures::{self, Query};

/// Queries per iteration (a decimated warm-up; the polynomial cost does not depend on it).
const QUERIES: usize = 4096;

/// The twelve terms of [`fixtures::paper_poly`], by hand.
#[inline]
fn inline_f32(c: &[f32; 12], x: f32, y: f32) -> f32 {
    let (x2, y2) = (x * x, y * y);
    let (x3, y3) = (x2 * x, y2 * y);
    c[0] + c[1] * x
        + c[2] * x2
        + c[3] * x3
        + c[4] * y
        + c[5] * y2
        + c[6] * y3
        + c[7] * x * y
        + c[8] * x2 * y
        + c[9] * x * y2
        + c[10] * x3 * y
        + c[11] * x * y3
}

/// `poly/evaluate`.
pub fn evaluate(c: &mut Criterion) {
    let terms = fixtures::paper_poly();
    let blob = fixtures::model_blob(terms.clone(), None);
    let model = Model::from_bytes(&blob).expect("valid blob");
    let axis = model.axis(0).expect("axis 0");
    let poly = axis.poly.expect("poly");
    let queries: Vec<Query> = fixtures::coherent_queries(QUERIES);
    let coefficients: [f32; 12] = core::array::from_fn(|i| terms[i].coefficient_dph);

    // The hand-written form computes the same value.
    for q in &queries {
        let (a, b) = (poly.evaluate(q.x, q.y), inline_f32(&coefficients, q.x, q.y));
        assert!((a - b).abs() <= 1e-5 * (1.0 + a.abs()), "inline form disagrees: {a} vs {b}");
    }

    let mut group = c.benchmark_group("poly/evaluate");
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(3));
    group.throughput(Throughput::Elements(queries.len() as u64));
    let id = format!("paper{}", poly.len());
    group.bench_function(BenchmarkId::new("fogtemp_poly", &id), |b| {
        b.iter(|| {
            for q in black_box(&queries) {
                black_box(poly.evaluate(q.x, q.y));
            }
        })
    });
    let mut hint = WalkHint::default();
    group.bench_function(BenchmarkId::new("fogtemp_axis_evaluate", &id), |b| {
        b.iter(|| {
            for q in black_box(&queries) {
                black_box(axis.evaluate(q.temp_c, q.rate_c_per_min, &mut hint).map_or(0.0, |e| e.value_dph));
            }
        })
    });
    let coefficients = black_box(coefficients);
    group.bench_function(BenchmarkId::new("inline_f32", &id), |b| {
        b.iter(|| {
            for q in black_box(&queries) {
                black_box(inline_f32(&coefficients, q.x, q.y));
            }
        })
    });
    group.finish();
}
