//! `Mesh::nearest_hull_value` (a binary search over the hull fan, then a descent to the normal
//! cone holding the query; `src/hull.rs`) and the hull value of a walk that leaves the mesh
//! (`Mesh::interpolate`, descending from the hull edge the walk crossed) against the full scan
//! they replaced (`Mesh::nearest_hull_value_by_scan`) and against an f64 projection onto the
//! hull.
//!
//! Meshes: random point sets (fixed seeds), a hull of 200 points on a circle, thin and long
//! hulls, hulls with exactly collinear and nearly collinear points, and the meshes of the
//! committed golden model (written by `fogtemp-cal`). Queries: random around the hull, beside
//! every hull edge (1e-6 to 1 outward), on the extensions of every edge, in every vertex's
//! normal wedge and on its bounding normals, far out (1e3 to 1e6), and NaN/infinite.
//!
//! Oracle and tolerances (the workspace's `tests/mesh_oracle.rs` uses the same): the f64
//! projection onto every hull edge of the f32 vertices gives candidates `(d2, value)`. The
//! f32 squared distances carry an error of about `6 eps d R + 7 eps d^2` (`R`: coordinate
//! magnitude), so every edge within `16 eps (d R + d^2)` of the f64 minimum is a legitimate
//! nearest point (a tie f32 cannot resolve); a value is right when it is within
//! `4 eps (vmax + slope (d + R))` of such a candidate's value (rounding of the value and of
//! the projection parameter, times the edge's value slope).
//!
//! Asserted: the fast value is right for every finite query; it equals the scan bit for bit
//! except where two or more candidates tie, and there the scan's value is right too; where
//! the fast search certifies an edge, a tie candidate lies on that edge or its neighbours;
//! every query clearly outside (f64 distance above `CLEARLY_OUTSIDE`) and not far out is
//! certified (the scan is a fallback for rounding, not the common path); a walk that leaves the
//! mesh gives the search's value bit for bit; NaN and infinite queries give the scan's value.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)] // test code: a failed expectation is the test failing

mod common;

use std::collections::HashMap;
use std::path::PathBuf;

use common::blob::{fix_len_and_crc, put_u32};
use common::{axis_header, one_axis_file_header, rng};
use fogtemp_core::wire::*;
use fogtemp_core::{AxisProvenance, Mesh, Model, WalkHint};
use rand::Rng;
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

const EPS: f64 = f32::EPSILON as f64;

/// Queries at least this far (f64 distance, normalised units) outside the hull and at most
/// `NOT_FAR` from the origin must be answered by the fast search itself. Rounding decides the
/// side of an edge only within a few ulps of the hull (coordinates are about 1 here, one ulp
/// 1.2e-7), and far out the f32 projections lose the resolution to certify a vertex wedge.
const CLEARLY_OUTSIDE: f64 = 1e-5;
const NOT_FAR: f64 = 100.0;

#[derive(Clone, Copy, Debug)]
struct Node {
    position: Point2<f64>,
    value_dph: f64,
}

impl HasPosition for Node {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// A smooth bias surface over the normalised plane (deg/h).
fn surface(x: f32, y: f32) -> f32 {
    let (x, y) = (f64::from(x), f64::from(y));
    (0.3 * (2.0 * x).sin() + 0.1 * y + 0.05 * x * y) as f32
}

/// A one-axis mesh blob (identity normalisation) of `points` `(x, y)`, values from
/// [`surface`]: spade's Delaunay triangulation written in the blob layout (the core's tests do
/// not use the writer in `fogtemp-cal`; the transforms are computed in f64 as it does).
fn mesh_blob(points: &[[f32; 2]]) -> Vec<u8> {
    let mut dt: DelaunayTriangulation<Node> = DelaunayTriangulation::new();
    for p in points {
        let position = Point2::new(f64::from(p[0]), f64::from(p[1]));
        dt.insert(Node { position, value_dph: f64::from(surface(p[0], p[1])) }).expect("finite point");
    }
    let vertices: Vec<[f32; 3]> = dt
        .vertices()
        .map(|v| [v.position().x as f32, v.position().y as f32, v.data().value_dph as f32])
        .collect();
    let mut face_to_triangle = vec![NO_NEIGHBOUR; dt.num_all_faces()];
    for (t, face) in dt.inner_faces().enumerate() {
        face_to_triangle[face.fix().index()] = t as u32;
    }
    let mut triangles = Vec::new();
    let mut hull_by_start = HashMap::new();
    for (t, face) in dt.inner_faces().enumerate() {
        let vs = face.vertices().map(|v| v.fix().index() as u32);
        // spade: edge k runs from vertex k to k + 1; ours: edge k is opposite vertex k.
        let edges = face.adjacent_edges();
        let mut nb = [NO_NEIGHBOUR; 3];
        for (k, slot) in nb.iter_mut().enumerate() {
            match edges[(k + 1) % 3].rev().face().as_inner() {
                Some(inner) => *slot = face_to_triangle[inner.fix().index()],
                None => {
                    hull_by_start.insert(vs[(k + 1) % 3], (t as u32, k as u32));
                }
            }
        }
        triangles.push((vs, nb));
    }
    let start = *hull_by_start.keys().min().expect("a hull");
    let mut hull = Vec::new();
    let mut at = start;
    loop {
        let (t, e) = hull_by_start[&at];
        hull.push((t, e));
        at = triangles[t as usize].0[(e as usize + 2) % 3];
        if at == start {
            break;
        }
    }
    assert_eq!(hull.len(), hull_by_start.len(), "one closed hull");

    let mut b = one_axis_file_header(FORMAT_VERSION_WITH_GRADIENTS);
    let (nv, nt, nh) = (vertices.len() as u32, triangles.len() as u32, hull.len() as u32);
    let section = axis_section_len(0, nv, nt, nh, 0, 0).unwrap();
    let mut h = axis_header(section, KIND_MESH);
    put_u32(&mut h, AXIS_VERTEX_COUNT.start, nv);
    put_u32(&mut h, AXIS_TRIANGLE_COUNT.start, nt);
    put_u32(&mut h, AXIS_HULL_EDGE_COUNT.start, nh);
    b.extend_from_slice(&h);
    for v in &vertices {
        for c in v {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for (vs, nb) in &triangles {
        let [a, bv, c] = vs.map(|i| vertices[i as usize].map(f64::from));
        let ((ax, ay), (bx, by)) = ((a[0] - c[0], a[1] - c[1]), (bv[0] - c[0], bv[1] - c[1]));
        let det = ax * by - bx * ay;
        let bary = [by / det, -bx / det, -ay / det, ax / det];
        let (da, db) = (a[2] - c[2], bv[2] - c[2]);
        let plane = [da * bary[0] + db * bary[2], da * bary[1] + db * bary[3], c[2]];
        for x in [c[0], c[1]].iter().chain(&bary).chain(&plane) {
            b.extend_from_slice(&(*x as f32).to_le_bytes());
        }
        for i in nb.iter().chain(vs) {
            b.extend_from_slice(&i.to_le_bytes());
        }
    }
    for (t, e) in &hull {
        b.extend_from_slice(&t.to_le_bytes());
        b.extend_from_slice(&e.to_le_bytes());
    }
    b.extend_from_slice(&[0; CRC_LEN]);
    fix_len_and_crc(&mut b);
    b
}

fn uniform(seed: u64, n: usize, half_width: [f32; 2]) -> Vec<[f32; 2]> {
    let mut r = rng(seed);
    (0..n)
        .map(|_| [r.gen_range(-half_width[0]..half_width[0]), r.gen_range(-half_width[1]..half_width[1])])
        .collect()
}

/// `n` points on the ellipse with semi-axes `axes` (all hull vertices), plus `inner` random
/// points well inside it.
fn ellipse(seed: u64, n: usize, axes: [f64; 2], inner: usize) -> Vec<[f32; 2]> {
    let mut r = rng(seed);
    let mut points: Vec<[f32; 2]> = (0..n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64;
            [(axes[0] * a.cos()) as f32, (axes[1] * a.sin()) as f32]
        })
        .collect();
    for _ in 0..inner {
        let (a, rho): (f64, f64) = (r.gen_range(0.0..std::f64::consts::TAU), r.gen_range(0.0..0.8));
        points.push([(axes[0] * rho * a.cos()) as f32, (axes[1] * rho * a.sin()) as f32]);
    }
    points
}

/// The square `[-1, 1]^2` with `per_side` exactly collinear points on each side (every one a
/// hull vertex with a straight angle) and `inner` random points inside.
fn collinear_square(seed: u64, per_side: usize, inner: usize) -> Vec<[f32; 2]> {
    let mut points = Vec::new();
    for i in 0..per_side {
        let s = -1.0 + 2.0 * i as f32 / per_side as f32;
        points.extend([[s, -1.0], [1.0, s], [-s, 1.0], [-1.0, -s]]);
    }
    points.extend(uniform(seed, inner, [0.9, 0.9]));
    points
}

/// A hexagon whose sides are arcs of circles of radius 1000 through `per_side` points each:
/// hull angles of 180 degrees minus about 1e-4 (nearly collinear).
fn nearly_collinear(seed: u64, per_side: usize, inner: usize) -> Vec<[f32; 2]> {
    let corners: Vec<[f64; 2]> = (0..6)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / 6.0;
            [a.cos(), a.sin()]
        })
        .collect();
    let radius = 1000.0;
    let mut points = Vec::new();
    for k in 0..6 {
        let (a, b) = (corners[k], corners[(k + 1) % 6]);
        let mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
        let half = ((b[0] - a[0]).hypot(b[1] - a[1])) / 2.0;
        let outward = [mid[0] / mid[0].hypot(mid[1]), mid[1] / mid[0].hypot(mid[1])];
        // Centre of the arc on the inner side, so the arc bulges outward.
        let depth = (radius * radius - half * half).sqrt();
        let centre = [mid[0] - depth * outward[0], mid[1] - depth * outward[1]];
        for i in 0..per_side {
            let t = -1.0 + 2.0 * i as f64 / per_side as f64;
            let along = [(b[0] - a[0]) / (2.0 * half), (b[1] - a[1]) / (2.0 * half)];
            let chord = [mid[0] + t * half * along[0], mid[1] + t * half * along[1]];
            let dir = [chord[0] - centre[0], chord[1] - centre[1]];
            let len = dir[0].hypot(dir[1]);
            points.push([
                (centre[0] + radius * dir[0] / len) as f32,
                (centre[1] + radius * dir[1] / len) as f32,
            ]);
        }
    }
    points.extend(uniform(seed, inner, [0.6, 0.6]));
    points
}

fn point_sets() -> Vec<(&'static str, Vec<[f32; 2]>)> {
    vec![
        ("random n=3", uniform(11, 3, [1.0, 1.0])),
        ("random n=12", uniform(12, 12, [1.0, 1.0])),
        ("random n=300", uniform(13, 300, [1.0, 1.0])),
        ("random n=3000", uniform(14, 3000, [1.0, 1.0])),
        ("circle 200 + 300 inside", ellipse(15, 200, [1.0, 1.0], 300)),
        ("thin box 2 x 0.002", uniform(16, 400, [1.0, 1e-3])),
        ("thin ellipse 1 x 0.02", ellipse(17, 120, [1.0, 0.02], 100)),
        ("long box 0.01 x 20", uniform(18, 300, [5e-3, 10.0])),
        ("collinear square", collinear_square(19, 40, 300)),
        ("nearly collinear hexagon", nearly_collinear(20, 25, 200)),
    ]
}

/// A hull edge in f64, from the blob's f32 vertices.
struct Segment {
    a: [f64; 2],
    b: [f64; 2],
    va: f64,
    vb: f64,
}

impl Segment {
    /// Squared distance to the f64 projection of `p` and the value there.
    fn nearest(&self, p: [f64; 2]) -> (f64, f64) {
        let (dx, dy) = (self.b[0] - self.a[0], self.b[1] - self.a[1]);
        let s = (((p[0] - self.a[0]) * dx + (p[1] - self.a[1]) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
        let (qx, qy) = (self.a[0] + s * dx, self.a[1] + s * dy);
        ((p[0] - qx).powi(2) + (p[1] - qy).powi(2), self.va + s * (self.vb - self.va))
    }

    fn outward_normal(&self) -> [f64; 2] {
        let (dx, dy) = (self.b[0] - self.a[0], self.b[1] - self.a[1]);
        let len = dx.hypot(dy);
        [dy / len, -dx / len]
    }
}

fn hull_segments(mesh: &Mesh<'_>) -> Vec<Segment> {
    (0..mesh.hull_edge_count())
        .map(|h| {
            let (a, b) = mesh.hull_edge_vertices(h).expect("hull edge");
            Segment {
                a: [f64::from(a.x), f64::from(a.y)],
                b: [f64::from(b.x), f64::from(b.y)],
                va: f64::from(a.value_dph),
                vb: f64::from(b.value_dph),
            }
        })
        .collect()
}

/// Queries around the hull (see the module documentation).
fn queries(hull: &[Segment], seed: u64) -> Vec<[f64; 2]> {
    let mut r = rng(seed);
    let (lo, hi) = hull.iter().fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), s| {
        ([lo[0].min(s.a[0]), lo[1].min(s.a[1])], [hi[0].max(s.a[0]), hi[1].max(s.a[1])])
    });
    let span = [hi[0] - lo[0], hi[1] - lo[1]];
    let mut out = Vec::new();
    for _ in 0..4000 {
        out.push([
            r.gen_range(lo[0] - span[0]..hi[0] + span[0]),
            r.gen_range(lo[1] - span[1]..hi[1] + span[1]),
        ]);
    }
    let n = hull.len();
    for (i, s) in hull.iter().enumerate() {
        let nrm = s.outward_normal();
        let e = [s.b[0] - s.a[0], s.b[1] - s.a[1]];
        let at = |t: f64, offset: f64, along: [f64; 2]| {
            [s.a[0] + t * e[0] + offset * along[0], s.a[1] + t * e[1] + offset * along[1]]
        };
        for offset in [1e-6, 1e-4, 1e-2, 1.0] {
            out.push(at(r.gen_range(0.0..1.0), offset, nrm));
        }
        // On the edge's line beyond either end, and just outside those points.
        for t in [-3.0, -0.5, -1e-3, 1.0 + 1e-3, 1.5, 4.0] {
            out.push(at(t, 0.0, nrm));
            out.push(at(t, 1e-3, nrm));
        }
        // The start vertex's normal wedge: the two bounding normals and between them.
        let before = hull[(i + n - 1) % n].outward_normal();
        let mid = [before[0] + nrm[0], before[1] + nrm[1]];
        let mid_len = mid[0].hypot(mid[1]).max(1e-300);
        for dist in [1e-5, 1e-2, 0.5] {
            for dir in [before, nrm, [mid[0] / mid_len, mid[1] / mid_len]] {
                out.push([s.a[0] + dist * dir[0], s.a[1] + dist * dir[1]]);
            }
        }
    }
    for k in 0..300 {
        let angle: f64 = r.gen_range(0.0..std::f64::consts::TAU);
        let radius = [1e3, 1e5, 1e6][k % 3];
        out.push([radius * angle.cos(), radius * angle.sin()]);
    }
    out
}

#[derive(Default, Debug)]
struct Counts {
    queries: usize,
    clearly_outside: usize,
    certified: usize,
    bit_equal: usize,
    tie_mismatches: usize,
    walked_outside: usize,
}

/// Every assertion of the module documentation for one mesh.
fn check_mesh(name: &str, mesh: &Mesh<'_>, seed: u64) -> Counts {
    let hull = hull_segments(mesh);
    let n = hull.len();
    let vmax = (0..mesh.vertex_count())
        .map(|i| f64::from(mesh.vertex(i).expect("vertex").value_dph.abs()))
        .fold(0.0, f64::max);
    let slope = hull
        .iter()
        .map(|s| (s.vb - s.va).abs() / (s.b[0] - s.a[0]).hypot(s.b[1] - s.a[1]))
        .fold(0.0, f64::max);
    let hull_coord = hull.iter().map(|s| s.a[0].abs().max(s.a[1].abs())).fold(1.0, f64::max);
    let mut counts = Counts::default();
    let mut hint = WalkHint::default();
    for p in queries(&hull, seed) {
        let (x, y) = (p[0] as f32, p[1] as f32);
        let q = [f64::from(x), f64::from(y)];
        let (fast, scan) = (mesh.nearest_hull_value(x, y), mesh.nearest_hull_value_by_scan(x, y));
        let candidates: Vec<(f64, f64)> = hull.iter().map(|s| s.nearest(q)).collect();
        let d2min = candidates.iter().map(|c| c.0).fold(f64::INFINITY, f64::min);
        let d = d2min.sqrt();
        let coord = hull_coord.max(q[0].abs()).max(q[1].abs());
        let d2_slack = 16.0 * EPS * (d * coord + d * d);
        let value_tolerance = 4.0 * EPS * (vmax + slope * (d + coord));
        let ties: Vec<usize> = (0..n).filter(|&h| candidates[h].0 <= d2min + d2_slack).collect();
        let right =
            |value: f32| ties.iter().any(|&h| (f64::from(value) - candidates[h].1).abs() <= value_tolerance);
        let at = format!("{name}: query ({x:e}, {y:e}), distance {d:e}");
        assert!(right(fast), "{at}: fast {fast} is not the value of a nearest hull point");
        if fast.to_bits() == scan.to_bits() {
            counts.bit_equal += 1;
        } else {
            assert!(ties.len() >= 2, "{at}: fast {fast} != scan {scan} without a tie");
            assert!(right(scan), "{at}: scan {scan} is not the value of a nearest hull point");
            counts.tie_mismatches += 1;
        }
        let certified = mesh.nearest_hull_edge(x, y);
        if let Some(h) = certified {
            let near = [(h as usize + n - 1) % n, h as usize, (h as usize + 1) % n];
            assert!(
                near.iter().any(|k| ties.contains(k)),
                "{at}: certified edge {h}, nearest edges {ties:?}"
            );
            counts.certified += 1;
        }
        let inside = hull
            .iter()
            .all(|s| (s.b[0] - s.a[0]) * (q[1] - s.a[1]) - (s.b[1] - s.a[1]) * (q[0] - s.a[0]) >= 0.0);
        if !inside && d > CLEARLY_OUTSIDE && coord <= NOT_FAR {
            assert!(certified.is_some(), "{at}: clearly outside but not certified");
            counts.clearly_outside += 1;
        }
        // A walk that leaves the mesh starts from the edge it crossed: the same value.
        let walked = mesh.interpolate(x, y, &mut hint).expect("finite query");
        if walked.outside_hull {
            assert_eq!(walked.value_dph.to_bits(), fast.to_bits(), "{at}: walk {walked:?}, search {fast}");
            counts.walked_outside += 1;
        }
        counts.queries += 1;
    }
    for (x, y) in [
        (f32::NAN, 0.0),
        (0.0, f32::NAN),
        (f32::INFINITY, 0.5),
        (0.5, f32::NEG_INFINITY),
        (f32::INFINITY, f32::INFINITY),
        (f32::NEG_INFINITY, f32::NAN),
    ] {
        let (fast, scan) = (mesh.nearest_hull_value(x, y), mesh.nearest_hull_value_by_scan(x, y));
        assert_eq!(fast.to_bits(), scan.to_bits(), "{name}: ({x}, {y})");
        assert_eq!(mesh.nearest_hull_edge(x, y), None, "{name}: ({x}, {y}) is not certified");
    }
    println!("{name}: {n} hull edges, {counts:?}");
    counts
}

#[test]
fn fast_hull_value_equals_the_scan_and_the_f64_projection_on_synthetic_meshes() {
    let mut total = Counts::default();
    for (i, (name, points)) in point_sets().into_iter().enumerate() {
        let blob = mesh_blob(&points);
        let model = Model::from_bytes(&blob).unwrap_or_else(|e| panic!("{name}: {e:?}"));
        let mesh = model.axis(0).expect("axis").mesh.expect("mesh");
        let c = check_mesh(name, &mesh, 100 + i as u64);
        total.queries += c.queries;
        total.clearly_outside += c.clearly_outside;
        total.certified += c.certified;
        total.bit_equal += c.bit_equal;
        total.tie_mismatches += c.tie_mismatches;
        total.walked_outside += c.walked_outside;
    }
    println!("all synthetic meshes: {total:?}");
    assert!(total.clearly_outside > 10_000, "the queries reach outside the hulls");
}

/// The golden model's bytes (tests/golden/model-v2.fogm).
fn golden_blob() -> Vec<u8> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/golden/model-v2.fogm");
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The axis's calibrated (T, rate) box widened by its own width on every side: (T range, rate
/// range), so that queries reach well outside the hull.
fn widened_box(p: &AxisProvenance) -> ((f32, f32), (f32, f32)) {
    let widen = |lo: f32, hi: f32| (lo - (hi - lo), hi + (hi - lo));
    (widen(p.temp_min_c, p.temp_max_c), widen(p.rate_min_c_per_min, p.rate_max_c_per_min))
}

#[test]
fn fast_hull_value_equals_the_scan_and_the_f64_projection_on_the_golden_model() {
    let blob = golden_blob();
    let model = Model::from_bytes(&blob).expect("golden model");
    let mut meshes = 0;
    for a in 0..model.axis_count() {
        if let Some(mesh) = model.axis(a).expect("axis").mesh {
            check_mesh(&format!("golden axis {a}"), &mesh, 200 + a as u64);
            meshes += 1;
        }
    }
    assert!(meshes > 0, "the golden model has a mesh");
}

/// `Axis::evaluate_with_grid` (a start grid, also one rebuilt from kept cells by
/// `Mesh::grid_from_cells`) gives `Axis::evaluate`'s value and flag bit for bit, inside and
/// outside the hull of every axis of the golden model (polynomial, mesh and hybrid axes).
#[test]
fn evaluate_with_grid_equals_evaluate_on_the_golden_model() {
    let blob = golden_blob();
    let model = Model::from_bytes(&blob).expect("golden model");
    let mut compared = 0;
    for a in 0..model.axis_count() {
        let axis = model.axis(a).expect("axis");
        let Some(mesh) = axis.mesh else { continue };
        let mut cells = vec![0u32; 16 * 16];
        mesh.start_grid(16, &mut cells).expect("grid");
        let grid = mesh.grid_from_cells(16, &cells).expect("grid from kept cells");
        let mut r = rng(300 + a as u64);
        let (mut plain_hint, mut grid_hint, mut outside) = (WalkHint::default(), WalkHint::default(), 0);
        let ((t0, t1), (r0, r1)) = widened_box(&axis.provenance);
        for _ in 0..20_000 {
            let (temp_c, rate_c_per_min): (f32, f32) = (r.gen_range(t0..t1), r.gen_range(r0..r1));
            let plain = axis.evaluate(temp_c, rate_c_per_min, &mut plain_hint).expect("evaluate");
            let gridded =
                axis.evaluate_with_grid(temp_c, rate_c_per_min, &mut grid_hint, &grid).expect("grid");
            assert_eq!(
                (plain.value_dph.to_bits(), plain.outside_hull),
                (gridded.value_dph.to_bits(), gridded.outside_hull),
                "axis {a} at ({temp_c}, {rate_c_per_min})"
            );
            outside += usize::from(plain.outside_hull);
            compared += 1;
        }
        assert!(outside > 1000, "axis {a}: {outside} of 20000 outside");
    }
    assert!(compared > 0, "the golden model has a mesh axis");
    assert!(matches!(
        model.axis(0).expect("axis").mesh.map(|m| m.grid_from_cells(16, &[0; 10])),
        Some(Err(fogtemp_core::Error::BadValue { .. })) | None
    ));
}

/// `Axis::evaluate_in_grid_cell`, the first step of `evaluate_with_grid` alone: where it says
/// the cell's triangle holds the point, its evaluation is `Axis::evaluate`'s bit for bit; a NaN
/// or infinite input is never held; and the two-pass batch the Python package runs (the held
/// points' values kept, the others by `evaluate_with_grid`) equals `evaluate` at every point,
/// inside and outside the hull of every mesh axis of the golden model.
#[test]
fn evaluate_in_grid_cell_is_the_first_step_of_evaluate_with_grid() {
    let blob = golden_blob();
    let model = Model::from_bytes(&blob).expect("golden model");
    let mut axes = 0;
    for a in 0..model.axis_count() {
        let axis = model.axis(a).expect("axis");
        let Some(mesh) = axis.mesh else { continue };
        let mut cells = vec![0u32; 16 * 16];
        let grid = mesh.start_grid(16, &mut cells).expect("grid");
        let mut r = rng(400 + a as u64);
        let ((t0, t1), (r0, r1)) = widened_box(&axis.provenance);
        let mut points: Vec<(f32, f32)> =
            (0..20_000).map(|_| (r.gen_range(t0..t1), r.gen_range(r0..r1))).collect();
        points.extend([(f32::NAN, 0.0), (20.0, f32::INFINITY), (f32::NEG_INFINITY, f32::NAN)]);
        // The two passes: the cell test everywhere, then the points it did not hold.
        let mut batch: Vec<(f32, bool)> = points
            .iter()
            .map(|&(temp_c, rate_c_per_min)| {
                let (evaluation, held) = axis.evaluate_in_grid_cell(temp_c, rate_c_per_min, &grid);
                (evaluation.value_dph, held)
            })
            .collect();
        let mut grid_hint = WalkHint::default();
        for (&(temp_c, rate_c_per_min), value) in points.iter().zip(batch.iter_mut()) {
            if !value.1 {
                value.0 = axis
                    .evaluate_with_grid(temp_c, rate_c_per_min, &mut grid_hint, &grid)
                    .map_or(f32::NAN, |e| e.value_dph);
            }
        }
        let (mut plain_hint, mut held, mut outside) = (WalkHint::default(), 0, 0);
        for (&(temp_c, rate_c_per_min), &(value, in_cell)) in points.iter().zip(&batch) {
            let plain = axis.evaluate(temp_c, rate_c_per_min, &mut plain_hint);
            match plain {
                Ok(plain) => {
                    assert_eq!(
                        plain.value_dph.to_bits(),
                        value.to_bits(),
                        "axis {a} at ({temp_c}, {rate_c_per_min})"
                    );
                    if in_cell {
                        let (first, _) = axis.evaluate_in_grid_cell(temp_c, rate_c_per_min, &grid);
                        assert_eq!(
                            first.outside_hull, plain.outside_hull,
                            "axis {a} at ({temp_c}, {rate_c_per_min})"
                        );
                    }
                    outside += usize::from(plain.outside_hull);
                }
                Err(_) => {
                    assert!(value.is_nan() && !in_cell, "axis {a}: non-finite ({temp_c}, {rate_c_per_min})")
                }
            }
            held += usize::from(in_cell);
        }
        // Both passes did work (the widened box is mostly outside the golden meshes' hulls).
        assert!(held > 100 && points.len() - held > 100, "axis {a}: {held} of {} held", points.len());
        assert!(outside > 1000, "axis {a}: {outside} of {} outside", points.len());
        axes += 1;
    }
    assert!(axes > 0, "the golden model has a mesh axis");
}
