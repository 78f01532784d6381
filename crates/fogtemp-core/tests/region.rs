//! The calibrated region (format version 2): a polynomial held at the boundary of the
//! calibrated (T, dT/dt) region instead of extrapolated. Against an f64 reference: inside the
//! region the value is bit for bit the extrapolating one; outside it equals the polynomial at
//! the nearest boundary point (f64 projection onto the polygon) within f32 rounding, and the
//! evaluation and the compensator flag it. Malformed regions are refused.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)] // test code: a failed expectation is the test failing

mod common;

use common::blob::{fix_len_and_crc, put_u32};
use common::{axis_header, one_axis_file_header, rng};
use fogtemp_core::wire::*;
use fogtemp_core::{Compensator, Error, Flags, Model, PolyOutside, WalkHint};
use rand::Rng;

/// `(temp_power, rate_power, coefficient_dph)`: a cubic that runs away outside [-1, 1]^2.
const TERMS: [(u8, u8, f32); 6] =
    [(0, 0, 0.05), (1, 0, 0.3), (0, 1, -0.2), (2, 0, 0.1), (1, 1, 0.05), (3, 0, 0.02)];

/// A convex, counter-clockwise hexagon in the normalised plane.
const REGION: [[f32; 2]; 6] =
    [[-0.9, -0.8], [0.2, -0.95], [0.95, -0.3], [0.8, 0.7], [-0.1, 0.9], [-0.85, 0.4]];

/// A one-axis polynomial blob (identity normalisation: x = T, y = dT/dt) of format
/// `version` with `region` and the `poly_outside` code.
fn poly_blob(version: u16, region: &[[f32; 2]], poly_outside: u32) -> Vec<u8> {
    poly_blob_with(&TERMS, version, region, poly_outside)
}

/// As [`poly_blob`] with the polynomial `terms`.
fn poly_blob_with(terms: &[(u8, u8, f32)], version: u16, region: &[[f32; 2]], poly_outside: u32) -> Vec<u8> {
    let mut b = one_axis_file_header(version);
    let section = axis_section_len(terms.len() as u32, 0, 0, 0, region.len() as u32, 0).unwrap();
    let mut h = axis_header(section, KIND_POLY);
    put_u32(&mut h, AXIS_POLY_TERM_COUNT.start, terms.len() as u32);
    put_u32(&mut h, AXIS_REGION_VERTEX_COUNT.start, region.len() as u32);
    put_u32(&mut h, AXIS_POLY_OUTSIDE.start, poly_outside);
    b.extend_from_slice(&h);
    for &(tp, rp, c) in terms {
        b.extend_from_slice(&[tp, rp, 0, 0]);
        b.extend_from_slice(&c.to_le_bytes());
    }
    for v in region {
        b.extend_from_slice(&v[0].to_le_bytes());
        b.extend_from_slice(&v[1].to_le_bytes());
    }
    b.extend_from_slice(&[0; CRC_LEN]);
    fix_len_and_crc(&mut b);
    b
}

fn poly_f64(x: f64, y: f64) -> f64 {
    TERMS.iter().map(|&(tp, rp, c)| f64::from(c) * x.powi(i32::from(tp)) * y.powi(i32::from(rp))).sum()
}

/// f64 reference: inside (or on) the polygon, and the nearest boundary point.
fn reference(x: f64, y: f64) -> (bool, (f64, f64)) {
    let n = REGION.len();
    let v = |i: usize| (f64::from(REGION[i % n][0]), f64::from(REGION[i % n][1]));
    let inside = (0..n).all(|i| {
        let (a, b) = (v(i), v(i + 1));
        (b.0 - a.0) * (y - a.1) - (b.1 - a.1) * (x - a.0) >= 0.0
    });
    let mut best = (f64::INFINITY, (x, y));
    for i in 0..n {
        let (a, b) = (v(i), v(i + 1));
        let (ex, ey) = (b.0 - a.0, b.1 - a.1);
        let t = (((x - a.0) * ex + (y - a.1) * ey) / (ex * ex + ey * ey)).clamp(0.0, 1.0);
        let q = (a.0 + t * ex, a.1 + t * ey);
        let d2 = (x - q.0).powi(2) + (y - q.1).powi(2);
        if d2 < best.0 {
            best = (d2, q);
        }
    }
    (inside, best.1)
}

#[test]
fn inside_the_region_the_value_is_bit_exact_and_outside_it_is_the_nearest_boundary_value() {
    let held = poly_blob(2, &REGION, PolyOutside::HoldAtBoundary.code());
    let free = poly_blob(2, &REGION, PolyOutside::Extrapolate.code());
    let (held, free) = (Model::from_bytes(&held).unwrap(), Model::from_bytes(&free).unwrap());
    assert_eq!(held.format_version(), 2);
    let (held, free) = (held.axis(0).unwrap(), free.axis(0).unwrap());
    // f32 projection and evaluation: a few ulps of the terms (|x|, |y| <= 1 on the boundary).
    assert_inside_as_extrapolated_outside_as_reference(&held, &free, 11, 1e-5, |_, _, (qx, qy)| {
        poly_f64(qx, qy)
    });
}

/// At 20 000 seeded points of [-2.5, 2.5]^2 (more than 1000 inside the region, more than
/// 10 000 outside): inside (by [`reference`]) `axis` gives the extrapolating axis `free`'s
/// value bit for bit, unflagged; outside it is flagged and within `tol` of `want(x, y, q)`,
/// q the nearest boundary point.
fn assert_inside_as_extrapolated_outside_as_reference(
    axis: &fogtemp_core::Axis<'_>,
    free: &fogtemp_core::Axis<'_>,
    seed: u64,
    tol: f64,
    want: impl Fn(f64, f64, (f64, f64)) -> f64,
) {
    let mut r = rng(seed);
    let (mut inside, mut outside) = (0, 0);
    for _ in 0..20_000 {
        let (x, y): (f32, f32) = (r.gen_range(-2.5..2.5), r.gen_range(-2.5..2.5));
        let h = axis.evaluate(x, y, &mut WalkHint::default()).unwrap();
        let f = free.evaluate(x, y, &mut WalkHint::default()).unwrap();
        let (ref_inside, q) = reference(f64::from(x), f64::from(y));
        if ref_inside {
            inside += 1;
            assert_eq!((h.value_dph.to_bits(), h.outside_hull), (f.value_dph.to_bits(), false), "({x}, {y})");
        } else {
            outside += 1;
            let want = want(f64::from(x), f64::from(y), q);
            assert!((f64::from(h.value_dph) - want).abs() <= tol, "({x}, {y}): {} vs {want}", h.value_dph);
            assert!(h.outside_hull, "({x}, {y}) outside but not flagged");
        }
    }
    assert!(inside > 1000 && outside > 10_000, "{inside} inside, {outside} outside");
}

/// Gradient of the f64 reference polynomial.
fn poly_gradient_f64(x: f64, y: f64) -> (f64, f64) {
    TERMS.iter().fold((0.0, 0.0), |(gx, gy), &(tp, rp, c)| {
        let (i, j, c) = (i32::from(tp), i32::from(rp), f64::from(c));
        let dx = if i > 0 { f64::from(i) * x.powi(i - 1) * y.powi(j) } else { 0.0 };
        let dy = if j > 0 { f64::from(j) * x.powi(i) * y.powi(j - 1) } else { 0.0 };
        (gx + c * dx, gy + c * dy)
    })
}

#[test]
fn linear_from_boundary_is_the_tangent_plane_at_the_nearest_boundary_point() {
    let linear = poly_blob(2, &REGION, PolyOutside::LinearFromBoundary.code());
    let free = poly_blob(2, &REGION, PolyOutside::Extrapolate.code());
    let (linear, free) = (Model::from_bytes(&linear).unwrap(), Model::from_bytes(&free).unwrap());
    let (linear, free) = (linear.axis(0).unwrap(), free.axis(0).unwrap());
    assert_eq!(linear.poly_outside, PolyOutside::LinearFromBoundary);
    // f32 projection, value and gradient: a few ulps of terms of order 1, times the
    // distance (at most 3.5) for the gradient part.
    assert_inside_as_extrapolated_outside_as_reference(&linear, &free, 12, 5e-5, |x, y, (qx, qy)| {
        let (gx, gy) = poly_gradient_f64(qx, qy);
        poly_f64(qx, qy) + gx * (x - qx) + gy * (y - qy)
    });
    // Far out (x = 50, nearest the vertex (0.95, -0.3)) the continuation is still the tangent
    // plane there, growing linearly, while the extrapolated cubic runs away.
    let far =
        |axis: &fogtemp_core::Axis<'_>| axis.evaluate(50.0, 0.0, &mut WalkHint::default()).unwrap().value_dph;
    let (gx, gy) = poly_gradient_f64(0.95, -0.3);
    let want = poly_f64(0.95, -0.3) + gx * (50.0 - 0.95) + gy * 0.3;
    assert!((f64::from(far(&linear)) - want).abs() <= 1e-5 * want.abs(), "{} vs {want}", far(&linear));
    assert!(f64::from(far(&free)) > 2000.0, "the cubic runs away: {}", far(&free));
}

#[test]
fn the_held_value_is_continuous_across_the_boundary() {
    let blob = poly_blob(2, &REGION, PolyOutside::HoldAtBoundary.code());
    let model = Model::from_bytes(&blob).unwrap();
    let axis = model.axis(0).unwrap();
    // Walk out along the outward normal of every edge's midpoint: the value stays put.
    for i in 0..REGION.len() {
        let (a, b) = (REGION[i], REGION[(i + 1) % REGION.len()]);
        let (mx, my) = ((a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0);
        let (nx, ny) = (b[1] - a[1], -(b[0] - a[0]));
        let at = |s: f32| axis.evaluate(mx + s * nx, my + s * ny, &mut WalkHint::default()).unwrap();
        let on = at(0.0).value_dph;
        for s in [1e-4f32, 0.1, 1.0, 10.0] {
            let e = at(s);
            assert!(e.outside_hull);
            assert!((e.value_dph - on).abs() <= 1e-5, "edge {i}, step {s}: {} vs {on}", e.value_dph);
        }
    }
}

#[test]
fn the_compensator_flags_outside_hull_and_subtracts_the_held_value() {
    // A constant temperature gives dT/dt = 0; a region at rates 0.5..1 leaves it outside.
    let region = [[-1.0, 0.5], [1.0, 0.5], [1.0, 1.0], [-1.0, 1.0]];
    let blob = poly_blob(2, &region, PolyOutside::HoldAtBoundary.code());
    let model = Model::from_bytes(&blob).unwrap();
    let mut comp: Compensator = Compensator::new(&model, 0).unwrap();
    let mut last = None;
    for k in 0..200u64 {
        last = Some(comp.step(k * 1_000_000, 1.0, Some(0.25)));
    }
    let out = last.unwrap();
    assert_ne!(out.flags.0 & Flags::OUTSIDE_HULL.0, 0, "flags {:#x}", out.flags.0);
    // Nearest point of the region to (0.25, 0) is (0.25, 0.5).
    let want = poly_f64(0.25, 0.5);
    assert!((f64::from(out.bias_dph) - want).abs() <= 1e-5, "{} vs {want}", out.bias_dph);
}

#[test]
fn malformed_regions_and_policies_are_refused() {
    let bad = |b: Vec<u8>| Model::from_bytes(&b).map(|_| ()).unwrap_err();
    let hold = PolyOutside::HoldAtBoundary.code();
    // Clockwise.
    let mut cw = REGION;
    cw.reverse();
    assert!(matches!(bad(poly_blob(2, &cw, hold)), Error::BadMesh { check: "region convex", .. }));
    // Not convex (a dent).
    let mut dent = REGION;
    dent[2] = [0.0, 0.0];
    assert!(matches!(bad(poly_blob(2, &dent, hold)), Error::BadMesh { check: "region convex", .. }));
    // Said as the region's, not the mesh's: the model has no mesh.
    let said = bad(poly_blob(2, &dent, hold)).to_string();
    assert!(said.starts_with("axis 0: calibrated-region check 'region convex' failed at vertex "), "{said}");
    // Two vertices; hold without a region; an unknown policy.
    assert!(matches!(
        bad(poly_blob(2, &REGION[..2], hold)),
        Error::BadValue { field: "region_vertex_count", .. }
    ));
    assert!(matches!(bad(poly_blob(2, &[], hold)), Error::BadValue { field: "poly_outside", .. }));
    let linear = PolyOutside::LinearFromBoundary.code();
    assert!(matches!(bad(poly_blob(2, &[], linear)), Error::BadValue { field: "poly_outside", .. }));
    assert!(matches!(bad(poly_blob(2, &REGION, 7)), Error::BadValue { field: "poly_outside", .. }));
    // A NaN vertex.
    let mut nan = REGION;
    nan[1][0] = f32::NAN;
    assert!(matches!(bad(poly_blob(2, &nan, hold)), Error::NonFinite { field: "region.x", .. }));
    // Version 1 has no region: the bytes are reserved.
    assert!(matches!(bad(poly_blob(1, &REGION, hold)), Error::BadValue { field: "reserved", .. }));
    // Version 9 is not known (3 adds the mesh's stored hull gradients, none here; 4 the
    // column names, 5 the log time, 6 the log reading, 7 the log shape and 8 the run
    // metadata, so a version-4 to -8 blob without them ends early).
    assert!(matches!(bad(poly_blob(9, &REGION, hold)), Error::UnsupportedVersion { expected: 8, found: 9 }));
    for version in 4..=8 {
        assert!(matches!(
            bad(poly_blob(version, &REGION, hold)),
            Error::Truncated { field: "names_len", .. }
        ));
    }
    assert!(Model::from_bytes(&poly_blob(3, &REGION, hold)).is_ok());
    // Version 1 without a region reads, and extrapolates.
    let v1 = poly_blob(1, &[], 0);
    let m = Model::from_bytes(&v1).unwrap();
    assert_eq!(m.format_version(), 1);
    let e = m.axis(0).unwrap().evaluate(3.0, 3.0, &mut WalkHint::default()).unwrap();
    assert!(!e.outside_hull && (f64::from(e.value_dph) - poly_f64(3.0, 3.0)).abs() < 1e-5);
}

/// A blob whose floats are each finite but give a value beyond f32 (a cubic term of 3e38
/// deg/h at |x| = 10) passes validation; its evaluation there is `NonFiniteValue`, not
/// `Ok(inf)`, and the compensator holds its last bias (0 before any) and flags `WARMING_UP`
/// rather than subtracting infinity. Where the value is finite (x = 0.5: 3.75e37) it is
/// returned as before.
#[test]
fn a_value_beyond_f32_is_an_error_and_the_compensator_holds_its_bias() {
    let terms = [(0, 0, 1.0), (3, 0, 3.0e38)];
    let blob = poly_blob_with(&terms, 2, &REGION, PolyOutside::Extrapolate.code());
    let model = Model::from_bytes(&blob).unwrap();
    let axis = model.axis(0).unwrap();
    let mut hint = WalkHint::default();
    assert_eq!(axis.evaluate(10.0, 0.0, &mut hint), Err(Error::NonFiniteValue { axis: 0 }));
    let near = axis.evaluate(0.5, 0.0, &mut hint).unwrap().value_dph;
    assert_eq!(near, 1.0 + 3.0e38 * 0.125);
    let mut comp: Compensator<'_, 256> = Compensator::new(&model, 0).unwrap();
    let mut last = None;
    for k in 0..600_u64 {
        last = Some(comp.step(k * 1_000_000, 5.0, Some(10.0)));
    }
    let out = last.unwrap();
    assert_eq!((out.bias_dph, out.rate_dph), (0.0, 5.0));
    assert!(out.flags.0 & Flags::WARMING_UP.0 != 0, "flags {:#x}", out.flags.0);
}
