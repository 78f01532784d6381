//! The mesh walk and interpolation of `fogtemp-core` against oracles: `spade`'s barycentric
//! interpolation on the blob's own vertices, and f64 references for the out-of-hull policy.
//!
//! Every comparison states its tolerance and why. `ε` below is `f32::EPSILON` (2^-23).
//! Run with `--nocapture` to see the statistics each test prints.

mod common;

use std::collections::{HashMap, HashSet};
use std::sync::OnceLock;

use common::{bias_surface, load, mesh_blob, model_blob, paper_points, random_points, rng, NORMALISATION};
use fogtemp_cal::{build_mesh, CalError, MeshPoint};
use fogtemp_core::{Location, Mesh, OutsidePolicy, PolyTerm, TriangleRecord, WalkHint, INSIDE_EPS};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};
use rand::Rng;
use spade::{
    DelaunayTriangulation, FloatTriangulation, HasPosition, Point2, PositionInTriangulation, Triangulation,
};

/// f32 machine epsilon as f64.
const EPS: f64 = f32::EPSILON as f64;

/// Inside/outside may disagree with the oracle only this close to the hull (normalised units).
/// Our inside test accepts barycentric coordinates down to `-INSIDE_EPS` (1e-6), i.e. a point up
/// to 1e-6 times a hull triangle's height (< 3 normalised units) outside; 1e-5 covers that
/// with margin, while still being ~1e-4 of the smallest triangle in any fixture.
const HULL_SLACK: f64 = 1.0e-5;

/// A spade query is "clearly interior" to a face when all of spade's barycentric coordinates
/// exceed this (and the f32 rounding bound of our coordinates in that triangle, see
/// [`bary_rounding`]); then our walk must land in exactly that face.
const CLEAR_INTERIOR: f64 = 1.0e-4;

// ---------------------------------------------------------------------------------------------
// The oracle
// ---------------------------------------------------------------------------------------------

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

/// A hull segment in f64: endpoints and their values.
#[derive(Clone, Copy, Debug)]
struct Segment {
    a: [f64; 2],
    b: [f64; 2],
    va: f64,
    vb: f64,
}

impl Segment {
    /// Squared distance from `p` to the segment, and the value at the nearest point.
    fn nearest(&self, p: [f64; 2]) -> (f64, f64) {
        let (dx, dy) = (self.b[0] - self.a[0], self.b[1] - self.a[1]);
        let len2 = dx * dx + dy * dy;
        let s = if len2 > 0.0 {
            (((p[0] - self.a[0]) * dx + (p[1] - self.a[1]) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (qx, qy) = (self.a[0] + s * dx, self.a[1] + s * dy);
        ((p[0] - qx).powi(2) + (p[1] - qy).powi(2), self.va + s * (self.vb - self.va))
    }

    fn length(&self) -> f64 {
        (self.b[0] - self.a[0]).hypot(self.b[1] - self.a[1])
    }
}

/// `spade` triangulation of the blob's vertices, inserted in blob order so that spade's vertex
/// index equals the blob's vertex index.
struct Oracle {
    dt: DelaunayTriangulation<Node>,
    hull: Vec<Segment>,
}

impl Oracle {
    fn new(mesh: &Mesh<'_>) -> Self {
        let mut dt = DelaunayTriangulation::<Node>::new();
        for i in 0..mesh.vertex_count() {
            let v = mesh.vertex(i).expect("vertex in range");
            let node = Node {
                position: Point2::new(f64::from(v.x), f64::from(v.y)),
                value_dph: f64::from(v.value_dph),
            };
            let handle = dt.insert(node).expect("finite vertex");
            assert_eq!(handle.index(), i as usize, "blob vertices must be distinct (oracle merged one)");
        }
        let hull = dt
            .convex_hull()
            .map(|e| {
                let (from, to) = (e.from(), e.to());
                Segment {
                    a: [from.position().x, from.position().y],
                    b: [to.position().x, to.position().y],
                    va: from.data().value_dph,
                    vb: to.data().value_dph,
                }
            })
            .collect();
        Oracle { dt, hull }
    }

    /// Barycentric interpolation (None outside the hull).
    fn interpolate(&self, x: f32, y: f32) -> Option<f64> {
        self.dt.barycentric().interpolate(|v| v.data().value_dph, Point2::new(f64::from(x), f64::from(y)))
    }

    /// The face containing `(x, y)` in its interior: sorted vertex indices and spade's
    /// barycentric coordinates.
    fn face(&self, x: f32, y: f32) -> Option<([u32; 3], [f64; 3])> {
        let p = Point2::new(f64::from(x), f64::from(y));
        match self.dt.locate(p) {
            PositionInTriangulation::OnFace(f) => {
                let face = self.dt.face(f);
                let mut vs = face.vertices().map(|v| v.fix().index() as u32);
                vs.sort_unstable();
                Some((vs, face.barycentric_interpolation(p)))
            }
            _ => None,
        }
    }

    /// Distance from `(x, y)` to the hull boundary, f64.
    fn hull_distance(&self, x: f64, y: f64) -> f64 {
        self.hull.iter().map(|s| s.nearest([x, y]).0).fold(f64::INFINITY, f64::min).sqrt()
    }

    /// Sorted vertex triples of every inner face.
    fn triangles(&self) -> HashSet<[u32; 3]> {
        self.dt
            .inner_faces()
            .map(|f| {
                let mut vs = f.vertices().map(|v| v.fix().index() as u32);
                vs.sort_unstable();
                vs
            })
            .collect()
    }
}

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// Barycentric coordinates of `(x, y)` in `rec`, computed exactly as the format defines them
/// (f32, relative to the origin). Used to check which triangles contain a point.
fn bary(rec: &TriangleRecord, x: f32, y: f32) -> [f32; 3] {
    let (dx, dy) = (x - rec.origin[0], y - rec.origin[1]);
    let l0 = rec.bary[0] * dx + rec.bary[1] * dy;
    let l1 = rec.bary[2] * dx + rec.bary[3] * dy;
    [l0, l1, 1.0 - l0 - l1]
}

/// Upper bound of the f32 rounding error of our barycentric coordinates in `rec` at `(x, y)`:
/// each coordinate is two products and a sum of terms of size `|b_i d|`, plus the rounding of
/// `d` itself, so 4ε times the sum of the term magnitudes bounds it.
fn bary_rounding(rec: &TriangleRecord, x: f32, y: f32) -> f64 {
    let (dx, dy) = (f64::from(x - rec.origin[0]).abs(), f64::from(y - rec.origin[1]).abs());
    let b = rec.bary.map(|v| f64::from(v).abs());
    4.0 * EPS * (b[0] * dx + b[1] * dy + b[2] * dx + b[3] * dy + 1.0)
}

/// f32 rounding bound of one plane evaluation `p0 dx + p1 dy + p2` (stored coefficients are
/// f64 values rounded to f32, `dx` is an f32 difference): each of the three terms carries at
/// most ~2ε relative error, so 4ε times the sum of term magnitudes bounds it with margin.
fn plane_rounding(rec: &TriangleRecord, x: f32, y: f32) -> f64 {
    let (dx, dy) = (f64::from(x - rec.origin[0]), f64::from(y - rec.origin[1]));
    let p = rec.plane.map(f64::from);
    4.0 * EPS * ((p[0] * dx).abs() + (p[1] * dy).abs() + p[2].abs())
}

fn min3(l: [f32; 3]) -> f32 {
    l[0].min(l[1]).min(l[2])
}

fn max_abs_value(mesh: &Mesh<'_>) -> f64 {
    (0..mesh.vertex_count())
        .map(|i| f64::from(mesh.vertex(i).expect("vertex").value_dph).abs())
        .fold(0.0, f64::max)
}

/// Largest gradient magnitude of any triangle's value plane: a Lipschitz constant of the
/// piecewise-linear interpolant (and, the projection onto a convex set being 1-Lipschitz, of
/// its nearest-hull extension).
fn max_gradient(mesh: &Mesh<'_>) -> f64 {
    (0..mesh.triangle_count())
        .map(|t| {
            let p = mesh.triangle(t).expect("triangle").plane;
            f64::from(p[0]).hypot(f64::from(p[1]))
        })
        .fold(0.0, f64::max)
}

fn sorted(mut v: [u32; 3]) -> [u32; 3] {
    v.sort_unstable();
    v
}

/// The point sets every oracle test runs on: random (sizes 3..2000, fixed seeds) and paper-like.
fn point_sets(value: fn(f64, f64) -> f64) -> Vec<(String, Vec<MeshPoint>)> {
    let mut sets: Vec<(String, Vec<MeshPoint>)> =
        [(3, 101), (4, 102), (7, 103), (25, 104), (120, 105), (600, 106), (2000, 107)]
            .into_iter()
            .map(|(n, seed)| (format!("random n={n} seed={seed}"), random_points(n, seed, value)))
            .collect();
    sets.push(("paper per_run=12".into(), paper_points(12, value)));
    sets.push(("paper per_run=70".into(), paper_points(70, value)));
    sets
}

/// Queries in the normalised plane: uniform over a box 30 % larger than the calibrated one,
/// every vertex exactly, and points on and beside every hull edge (offsets 0 to 1e-3 along the
/// outward and inward normal).
fn queries(oracle: &Oracle, mesh: &Mesh<'_>, seed: u64, uniform: usize) -> Vec<(f32, f32)> {
    let mut r = rng(seed);
    let mut out: Vec<(f32, f32)> =
        (0..uniform).map(|_| (r.gen_range(-1.3f32..1.3), r.gen_range(-1.3f32..1.3))).collect();
    for i in 0..mesh.vertex_count() {
        let v = mesh.vertex(i).expect("vertex");
        out.push((v.x, v.y));
    }
    for s in &oracle.hull {
        let len = s.length();
        let (nx, ny) = ((s.b[1] - s.a[1]) / len, -(s.b[0] - s.a[0]) / len); // outward (hull is ccw)
        for offset in [0.0, 1e-7, -1e-7, 1e-6, -1e-6, 1e-5, -1e-5, 1e-3, -1e-3] {
            let t: f64 = r.gen_range(0.0..1.0);
            let (x, y) = (s.a[0] + t * (s.b[0] - s.a[0]), s.a[1] + t * (s.b[1] - s.a[1]));
            out.push(((x + offset * nx) as f32, (y + offset * ny) as f32));
        }
    }
    out
}

#[derive(Default, Debug)]
struct Stats {
    queries: usize,
    inside: usize,
    near_hull_disagreements: usize,
    face_checks: usize,
    worst_value_error_over_tolerance: f64,
    worst_value_error_dph: f64,
}

// ---------------------------------------------------------------------------------------------
// 1. Values, inside/outside and located faces against spade
// ---------------------------------------------------------------------------------------------

/// Checks every query of one point set; returns statistics.
fn check_against_spade(name: &str, points: &[MeshPoint], seed: u64) -> Stats {
    let (model, mesh) = load(mesh_blob(points, OutsidePolicy::NearestHull));
    let axis = model.axis(0).expect("axis 0");
    let oracle = Oracle::new(&mesh);
    let span = max_abs_value(&mesh);
    let by_vertices: HashMap<[u32; 3], u32> = (0..mesh.triangle_count())
        .map(|t| (sorted(mesh.triangle(t).expect("triangle").vertices), t))
        .collect();
    assert_eq!(
        by_vertices.keys().copied().collect::<HashSet<_>>(),
        oracle.triangles(),
        "{name}: the blob's triangles are the Delaunay triangles of its vertices"
    );

    let mut stats = Stats::default();
    let mut hint = WalkHint::default(); // one persistent hint, as firmware uses it
    for (x, y) in queries(&oracle, &mesh, seed, 3000) {
        stats.queries += 1;
        let ours = mesh.interpolate(x, y, &mut hint).expect("finite query");
        assert!(hint.0 < mesh.triangle_count(), "{name}: hint left in range");
        let spade_value = oracle.interpolate(x, y);
        if ours.outside_hull != spade_value.is_none() {
            let d = oracle.hull_distance(f64::from(x), f64::from(y));
            assert!(
                d < HULL_SLACK,
                "{name}: ({x}, {y}) outside={} but spade says outside={}; {d:e} from the hull",
                ours.outside_hull,
                spade_value.is_none()
            );
            stats.near_hull_disagreements += 1;
            continue;
        }
        let Some(expected) = spade_value else { continue };
        stats.inside += 1;
        let rec = mesh.triangle(ours.triangle).expect("located triangle");
        // Tolerance: f32 rounding of the plane evaluation, plus (for a point on a shared edge
        // that our walk assigned to the neighbour of spade's face, up to INSIDE_EPS outside
        // it) the extrapolation by at most INSIDE_EPS of the value range.
        let tolerance = plane_rounding(&rec, x, y) + 4.0 * f64::from(INSIDE_EPS) * span;
        let error = (f64::from(ours.value_dph) - expected).abs();
        assert!(
            error <= tolerance,
            "{name}: value at ({x}, {y}) is {} but spade gives {expected} (error {error:e} > {tolerance:e})",
            ours.value_dph
        );
        stats.worst_value_error_over_tolerance =
            stats.worst_value_error_over_tolerance.max(error / tolerance);
        stats.worst_value_error_dph = stats.worst_value_error_dph.max(error);

        if let Some((face, l)) = oracle.face(x, y) {
            let face_rec = mesh.triangle(by_vertices[&face]).expect("face in blob");
            let margin = CLEAR_INTERIOR.max(bary_rounding(&face_rec, x, y));
            if l.iter().all(|&c| c > margin) {
                stats.face_checks += 1;
                assert_eq!(
                    sorted(rec.vertices),
                    face,
                    "{name}: ({x}, {y}) is clearly inside spade's face {face:?} (bary {l:?})"
                );
            }
        }
    }

    // Axis::evaluate is the mesh at the normalised physical inputs, bit for bit.
    let mut r = rng(seed ^ 0xA5A5);
    let (mut h1, mut h2) = (WalkHint::default(), WalkHint::default());
    for _ in 0..1000 {
        let (temp_c, rate) = (r.gen_range(-60.0f32..100.0), r.gen_range(-0.2f32..1.2));
        let e = axis.evaluate(temp_c, rate, &mut h1).expect("finite input");
        let (x, y) = axis.normalisation.apply(temp_c, rate);
        let m = mesh.interpolate(x, y, &mut h2).expect("finite input");
        assert_eq!(
            (e.value_dph.to_bits(), e.outside_hull),
            (m.value_dph.to_bits(), m.outside_hull),
            "{name}"
        );
    }
    stats
}

#[test]
fn mesh_value_and_inside_flag_match_spade_barycentric_interpolation() {
    for (i, (name, points)) in point_sets(bias_surface).iter().enumerate() {
        let stats = check_against_spade(name, points, 1000 + i as u64);
        println!("{name}: {stats:?}");
        assert!(stats.inside > 0, "{name}: some queries inside");
    }
}

#[test]
fn clearly_interior_query_lands_in_spades_face() {
    // Dense check on the biggest random set: many queries are clear interior points, and
    // the count of checked faces must be substantial (the check above is not vacuous).
    let points = random_points(2000, 107, bias_surface);
    let stats = check_against_spade("random n=2000", &points, 77);
    println!("clear-interior face checks: {} of {} queries", stats.face_checks, stats.queries);
    assert!(stats.face_checks > 1000);
}

// ---------------------------------------------------------------------------------------------
// 2. The hint does not change the result
// ---------------------------------------------------------------------------------------------

struct HintFixture {
    mesh: Mesh<'static>,
    big_mesh: Mesh<'static>,
    oracle_hull: Vec<Segment>,
}

fn hint_fixture() -> &'static HintFixture {
    static FIXTURE: OnceLock<HintFixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let (_, mesh) = load(mesh_blob(&random_points(300, 201, bias_surface), OutsidePolicy::NearestHull));
        let (_, big_mesh) =
            load(mesh_blob(&random_points(2000, 202, bias_surface), OutsidePolicy::NearestHull));
        let oracle_hull = Oracle::new(&mesh).hull;
        HintFixture { mesh, big_mesh, oracle_hull }
    })
}

#[derive(Clone, Debug)]
enum HintSource {
    Raw(u32),
    /// The hint the bigger mesh leaves after a query there (a hint from another mesh).
    FromBigMesh(f32, f32),
    /// The hint left by a previous query on the same mesh (stale).
    Stale(f32, f32),
}

fn hint_source() -> impl Strategy<Value = HintSource> {
    prop_oneof![
        any::<u32>().prop_map(HintSource::Raw),
        (0u32..700).prop_map(HintSource::Raw),
        Just(HintSource::Raw(u32::MAX)),
        Just(HintSource::Raw(u32::MAX - 1)),
        (-1.5f32..1.5, -1.5f32..1.5).prop_map(|(x, y)| HintSource::FromBigMesh(x, y)),
        (-1.5f32..1.5, -1.5f32..1.5).prop_map(|(x, y)| HintSource::Stale(x, y)),
    ]
}

fn proptest_config(cases: u32) -> Config {
    Config {
        cases,
        failure_persistence: None,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(0x0F06_7E39),
        ..Config::default()
    }
}

proptest! {
    #![proptest_config(proptest_config(2000))]

    #[test]
    fn walk_from_any_hint_gives_same_result_as_scan_and_fresh_hint(
        x in -1.5f32..1.5,
        y in -1.5f32..1.5,
        source in hint_source(),
    ) {
        let f = hint_fixture();
        let mesh = &f.mesh;
        let mut hint = match source {
            HintSource::Raw(h) => WalkHint(h),
            HintSource::FromBigMesh(bx, by) => {
                let mut h = WalkHint::default();
                f.big_mesh.locate(bx, by, &mut h).expect("finite");
                h
            }
            HintSource::Stale(sx, sy) => {
                let mut h = WalkHint::default();
                mesh.locate(sx, sy, &mut h).expect("finite");
                h
            }
        };
        let hinted = mesh.interpolate(x, y, &mut hint).expect("finite");
        prop_assert!(hint.0 < mesh.triangle_count(), "hint left in range");
        let fresh = mesh.interpolate(x, y, &mut WalkHint::default()).expect("finite");
        let scan = mesh.locate_by_scan(x, y);
        let scan_outside = matches!(scan, Location::Outside { .. });
        let near_hull = f.oracle_hull.iter().map(|s| s.nearest([f64::from(x), f64::from(y)]).0)
            .fold(f64::INFINITY, f64::min).sqrt() < HULL_SLACK;
        if !near_hull {
            prop_assert_eq!(hinted.outside_hull, fresh.outside_hull);
            prop_assert_eq!(hinted.outside_hull, scan_outside);
        }
        if hinted.outside_hull && fresh.outside_hull {
            // The nearest-hull value does not depend on the triangle: bit-identical.
            prop_assert_eq!(hinted.value_dph.to_bits(), fresh.value_dph.to_bits());
        } else if !hinted.outside_hull && !fresh.outside_hull {
            let a = mesh.triangle(hinted.triangle).expect("t");
            let b = mesh.triangle(fresh.triangle).expect("t");
            if hinted.triangle == fresh.triangle {
                prop_assert_eq!(hinted.value_dph.to_bits(), fresh.value_dph.to_bits());
            } else {
                // Two triangles only both accept a point on (within INSIDE_EPS of) their
                // common boundary; their planes agree there to f32 rounding plus the
                // INSIDE_EPS extrapolation of the value range.
                prop_assert!(min3(bary(&a, x, y)) >= -INSIDE_EPS && min3(bary(&b, x, y)) >= -INSIDE_EPS);
                let tolerance = plane_rounding(&a, x, y) + plane_rounding(&b, x, y)
                    + 8.0 * f64::from(INSIDE_EPS) * max_abs_value(mesh);
                let error = f64::from(hinted.value_dph - fresh.value_dph).abs();
                prop_assert!(error <= tolerance, "{} vs {}", hinted.value_dph, fresh.value_dph);
            }
            if let Location::Inside { triangle, .. } = scan {
                let s = mesh.triangle(triangle).expect("t");
                prop_assert!(min3(bary(&s, x, y)) >= -INSIDE_EPS);
                prop_assert!(min3(bary(&a, x, y)) >= -INSIDE_EPS);
            }
        }
    }
}

#[test]
fn failed_locate_leaves_hint_unchanged() {
    let f = hint_fixture();
    for bad in [(f32::NAN, 0.0), (0.0, f32::NAN), (f32::INFINITY, 0.0), (0.0, f32::NEG_INFINITY)] {
        let mut hint = WalkHint(17);
        assert!(f.mesh.locate(bad.0, bad.1, &mut hint).is_err());
        assert!(f.mesh.interpolate(bad.0, bad.1, &mut hint).is_err());
        assert_eq!(hint, WalkHint(17));
    }
}

#[test]
fn failed_interpolate_from_the_right_triangle_leaves_hint_unchanged() {
    // The hint already holds the triangle of a nearby finite point, so the hot path (the hint
    // triangle's own test) sees the non-finite query first; it must still be an error.
    let f = hint_fixture();
    let side = 8;
    let mut cells = vec![0u32; side * side];
    let grid = f.mesh.start_grid(side as u32, &mut cells).expect("grid fits");
    let (x0, y0) = (0.1f32, -0.2f32);
    let mut hint = WalkHint::default();
    f.mesh.interpolate(x0, y0, &mut hint).expect("finite");
    let settled = hint;
    for bad in [
        (f32::NAN, y0),
        (x0, f32::NAN),
        (f32::INFINITY, y0),
        (f32::NEG_INFINITY, y0),
        (x0, f32::INFINITY),
        (x0, f32::NEG_INFINITY),
        (f32::INFINITY, f32::INFINITY),
        (f32::NAN, f32::NAN),
    ] {
        let mut h = settled;
        assert_eq!(f.mesh.interpolate(bad.0, bad.1, &mut h), Err(fogtemp_core::Error::NonFiniteSample));
        assert_eq!(h, settled);
        assert_eq!(
            f.mesh.interpolate_with_grid(bad.0, bad.1, &mut h, &grid),
            Err(fogtemp_core::Error::NonFiniteSample)
        );
        assert_eq!(h, settled);
    }
}

#[test]
fn interpolate_is_bit_identical_to_locate_then_plane() {
    // `interpolate` answers most queries from the hint triangle alone (its hot path) and
    // sends the rest through the walk; `locate` always walks. Inside the hull the value must
    // be the located triangle's stored plane, bit for bit, and the hint must end in the same
    // triangle. Queries: a slow drift (many per triangle), jumps, points on and beyond the
    // hull, huge finite coordinates, and hints past the last triangle.
    let f = hint_fixture();
    let mesh = &f.mesh;
    let mut r = rng(303);
    let (mut hint_i, mut hint_l) = (WalkHint::default(), WalkHint::default());
    let mut queries = Vec::new();
    let (mut x, mut y) = (-0.5f32, -0.5f32);
    for i in 0..20_000 {
        if i % 997 == 0 {
            (x, y) = (r.gen_range(-1.2f32..1.2), r.gen_range(-1.2f32..1.2));
        } else {
            (x, y) = (x + r.gen_range(-1e-3f32..1e-3), y + r.gen_range(-1e-3f32..1e-3));
        }
        queries.push((x, y));
    }
    queries.extend([(f32::MAX, 0.0), (0.0, -f32::MAX), (3e38, 3e38), (-1e30, 1e-30), (1.0, 1.0)]);
    for (i, &(x, y)) in queries.iter().enumerate() {
        if i % 1000 == 500 {
            (hint_i, hint_l) = (WalkHint(u32::MAX), WalkHint(u32::MAX));
        }
        let got = mesh.interpolate(x, y, &mut hint_i).expect("finite");
        let loc = mesh.locate(x, y, &mut hint_l).expect("finite");
        assert_eq!(hint_i, hint_l, "query {i} ({x}, {y})");
        match loc {
            Location::Inside { triangle, .. } => {
                let rec = mesh.triangle(triangle).expect("triangle");
                let (dx, dy) = (x - rec.origin[0], y - rec.origin[1]);
                let want = rec.plane[0] * dx + rec.plane[1] * dy + rec.plane[2];
                assert_eq!(got.value_dph.to_bits(), want.to_bits(), "query {i} ({x}, {y})");
                assert_eq!((got.triangle, got.outside_hull), (triangle, false), "query {i}");
            }
            Location::Outside { triangle } => {
                assert_eq!((got.triangle, got.outside_hull), (triangle, true), "query {i}");
                let want = mesh.nearest_hull_value(x, y);
                assert_eq!(got.value_dph.to_bits(), want.to_bits(), "query {i} ({x}, {y})");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 3. Planar and constant surfaces
// ---------------------------------------------------------------------------------------------

/// A plane in physical units, `a T + b R + c` (deg/h), evaluated at the physical preimage of
/// the f32 normalised position. The writer stores a point at its f32 normalised position, so
/// this makes the vertex values exact plane values at the stored positions (up to the f32
/// rounding of the value) and leaves only the interpolation's own rounding to test.
fn plane_at_normalised(x: f64, y: f64) -> f64 {
    let (a, b, c) = (0.004, 0.08, -0.05);
    let n = NORMALISATION;
    let temp_c = x / f64::from(n.temp_scale_per_c) + f64::from(n.temp_offset_c);
    let rate = y / f64::from(n.rate_scale_per_c_per_min) + f64::from(n.rate_offset_c_per_min);
    a * temp_c + b * rate + c
}

fn plane_physical(temp_c: f64, rate: f64) -> f64 {
    let (x, y) = NORMALISATION.apply(temp_c as f32, rate as f32);
    plane_at_normalised(f64::from(x), f64::from(y))
}

#[test]
fn planar_surface_is_reproduced_within_f32_rounding() {
    let mut worst = 0.0f64;
    let mut checked = 0usize;
    for (i, (name, points)) in point_sets(plane_physical).iter().enumerate() {
        let (_, mesh) = load(mesh_blob(points, OutsidePolicy::NearestHull));
        let oracle = Oracle::new(&mesh);
        let mut hint = WalkHint::default();
        for (x, y) in queries(&oracle, &mesh, 3000 + i as u64, 3000) {
            let ours = mesh.interpolate(x, y, &mut hint).expect("finite");
            if ours.outside_hull {
                continue;
            }
            let rec = mesh.triangle(ours.triangle).expect("triangle");
            let vmax = rec.vertices.map(|v| f64::from(mesh.vertex(v).expect("v").value_dph).abs());
            // Bound: the plane evaluation's rounding (see plane_rounding) plus the f32 rounding
            // of the three vertex values (ε/2 each, weighted by barycentric coordinates that
            // sum to 1 and are >= -1e-6), taken as ε times the largest vertex value.
            let tolerance = plane_rounding(&rec, x, y) + EPS * vmax[0].max(vmax[1]).max(vmax[2]);
            let expected = plane_at_normalised(f64::from(x), f64::from(y));
            let error = (f64::from(ours.value_dph) - expected).abs();
            assert!(
                error <= tolerance,
                "{name}: ({x}, {y}) gives {} not {expected} ({error:e} > {tolerance:e})",
                ours.value_dph
            );
            worst = worst.max(error / tolerance);
            checked += 1;
        }
    }
    println!("planar: {checked} inside queries, worst error / bound = {worst:.3}");
}

#[test]
fn constant_surface_is_reproduced_exactly_inside_and_outside() {
    for constant in [0.1234_f32, -7.5, 1.0e-3] {
        let value = f64::from(constant);
        for (i, (name, points)) in point_sets(|_, _| 0.0).iter().enumerate() {
            let points: Vec<MeshPoint> =
                points.iter().map(|p| MeshPoint { value_dph: value, ..*p }).collect();
            let (_, mesh) = load(mesh_blob(&points, OutsidePolicy::NearestHull));
            let oracle = Oracle::new(&mesh);
            let mut hint = WalkHint::default();
            let mut far = queries(&oracle, &mesh, 4000 + i as u64, 500);
            far.extend([(1.0e5, 3.0), (-1.0e6, 1.0e6), (0.0, -50.0)]);
            for (x, y) in far {
                let ours = mesh.interpolate(x, y, &mut hint).expect("finite");
                // Exact: every plane is (0, 0, c) and every hull edge has equal end values,
                // so no rounding can occur (0 * d + 0 * d + c == c, c + s * 0 == c).
                assert_eq!(
                    ours.value_dph.to_bits(),
                    constant.to_bits(),
                    "{name}: ({x}, {y}) -> {}",
                    ours.value_dph
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 4. Outside the hull
// ---------------------------------------------------------------------------------------------

/// First crossing of the ray `c + t u` (t > 0) with the hull, f64.
fn ray_exit(hull: &[Segment], c: [f64; 2], u: [f64; 2]) -> f64 {
    let mut best = f64::INFINITY;
    for s in hull {
        let e = [s.b[0] - s.a[0], s.b[1] - s.a[1]];
        let den = u[0] * e[1] - u[1] * e[0];
        if den.abs() < 1e-300 {
            continue;
        }
        let w = [s.a[0] - c[0], s.a[1] - c[1]];
        let t = (w[0] * e[1] - w[1] * e[0]) / den;
        let r = (w[0] * u[1] - w[1] * u[0]) / den;
        if t > 0.0 && (-1e-12..=1.0 + 1e-12).contains(&r) {
            best = best.min(t);
        }
    }
    best
}

#[test]
fn nearest_hull_value_is_continuous_across_the_hull() {
    let mut checked = 0usize;
    let mut worst = 0.0f64;
    for (i, (name, points)) in point_sets(bias_surface).iter().enumerate() {
        let (_, mesh) = load(mesh_blob(points, OutsidePolicy::NearestHull));
        let oracle = Oracle::new(&mesh);
        let lipschitz = max_gradient(&mesh);
        let vmax = max_abs_value(&mesh);
        let n = f64::from(mesh.vertex_count());
        let centre = (0..mesh.vertex_count()).fold([0.0, 0.0], |acc, i| {
            let v = mesh.vertex(i).expect("v");
            [acc[0] + f64::from(v.x) / n, acc[1] + f64::from(v.y) / n]
        });
        let mut r = rng(5000 + i as u64);
        let mut hint = WalkHint::default();
        for _ in 0..400 {
            let angle: f64 = r.gen_range(0.0..std::f64::consts::TAU);
            let u = [angle.cos(), angle.sin()];
            let t_exit = ray_exit(&oracle.hull, centre, u);
            assert!(t_exit.is_finite(), "{name}: the ray from the centroid leaves the hull");
            for step in [1e-3, 1e-4, 1e-5] {
                let at = |t: f64| ((centre[0] + t * u[0]) as f32, (centre[1] + t * u[1]) as f32);
                let (qi, qo) = (at(t_exit - step), at(t_exit + step));
                let vi = mesh.interpolate(qi.0, qi.1, &mut hint).expect("finite");
                let vo = mesh.interpolate(qo.0, qo.1, &mut hint).expect("finite");
                // Lipschitz bound over the true distance between the two f32 points (rounding
                // of the positions included), plus f32 rounding of both evaluations (4ε each
                // of the largest value, see plane_rounding; the hull value is one product and
                // two sums).
                let dist = (f64::from(qi.0) - f64::from(qo.0)).hypot(f64::from(qi.1) - f64::from(qo.1));
                let tolerance = lipschitz * dist + 16.0 * EPS * vmax;
                let jump = f64::from(vi.value_dph - vo.value_dph).abs();
                assert!(
                    jump <= tolerance,
                    "{name}: jump {jump:e} > {tolerance:e} across the hull at step {step}"
                );
                worst = worst.max(jump / tolerance);
                let (di, d_o) = (
                    oracle.hull_distance(f64::from(qi.0), f64::from(qi.1)),
                    oracle.hull_distance(f64::from(qo.0), f64::from(qo.1)),
                );
                if di > HULL_SLACK {
                    assert!(!vi.outside_hull, "{name}: inner point flagged outside");
                }
                if d_o > HULL_SLACK {
                    assert!(vo.outside_hull, "{name}: outer point flagged inside");
                }
                checked += 1;
            }
        }
    }
    println!("continuity: {checked} ray crossings, worst jump / bound = {worst:.3}");
}

#[test]
fn nearest_hull_value_far_away_matches_f64_projection() {
    let (mut checked, mut not_f64_nearest) = (0usize, 0usize);
    for (i, (name, points)) in point_sets(bias_surface).iter().enumerate() {
        let (_, mesh) = load(mesh_blob(points, OutsidePolicy::NearestHull));
        let oracle = Oracle::new(&mesh);
        let vmax = max_abs_value(&mesh);
        let edge_gradient = oracle.hull.iter().map(|s| (s.vb - s.va).abs() / s.length()).fold(0.0, f64::max);
        let mut r = rng(6000 + i as u64);
        let mut hint = WalkHint::default();
        for k in 0..1500 {
            let angle: f64 = r.gen_range(0.0..std::f64::consts::TAU);
            let radius: f64 = match k % 10 {
                0 => 1.0e3,
                1 => 1.0e5,
                _ => r.gen_range(1.5..6.0),
            };
            let (x, y) = ((radius * angle.cos()) as f32, (radius * angle.sin()) as f32);
            let ours = mesh.interpolate(x, y, &mut hint).expect("finite");
            assert!(ours.outside_hull, "{name}: ({x}, {y}) is far outside");
            assert_eq!(ours.value_dph.to_bits(), mesh.nearest_hull_value(x, y).to_bits());
            let p = [f64::from(x), f64::from(y)];
            let candidates: Vec<(f64, f64)> = oracle.hull.iter().map(|s| s.nearest(p)).collect();
            let d2min = candidates.iter().map(|c| c.0).fold(f64::INFINITY, f64::min);
            let d = d2min.sqrt();
            let coord = 1.5f64.max(f64::from(x.abs())).max(f64::from(y.abs()));
            // Our f32 squared distances carry an error of about 6ε·d·R + 7ε·d² (R: coordinate
            // magnitude), so any hull segment within that (doubled) of the f64 minimum may
            // legitimately win. The value on the winning segment is then exact to 4ε of the
            // value magnitude plus the f32 error of the projection parameter (≈ 2ε·d / edge
            // length, times the edge's value slope).
            let d2_slack = 16.0 * EPS * (d * coord + d * d);
            let value_tolerance = 4.0 * EPS * (vmax + edge_gradient * (d + coord));
            let value = f64::from(ours.value_dph);
            let ok = candidates
                .iter()
                .any(|&(d2, v)| d2 <= d2min + d2_slack && (value - v).abs() <= value_tolerance);
            assert!(ok, "{name}: ({x}, {y}) gives {value}, not the value of any nearest hull point");
            let (_, v_nearest) =
                candidates.iter().copied().fold((f64::INFINITY, 0.0), |m, c| if c.0 < m.0 { c } else { m });
            if (value - v_nearest).abs() > value_tolerance {
                not_f64_nearest += 1;
            }
            checked += 1;
        }
    }
    println!(
        "far queries: {checked}, of which {not_f64_nearest} took a near-tie hull point \
         other than the f64 nearest"
    );
}

#[test]
fn zero_policy_gives_zero_outside_and_the_same_mesh_inside() {
    let poly = vec![
        PolyTerm { temp_power: 0, rate_power: 0, coefficient_dph: 0.25 },
        PolyTerm { temp_power: 1, rate_power: 1, coefficient_dph: -0.125 },
    ];
    for (i, (name, points)) in point_sets(bias_surface).iter().enumerate() {
        let (zero_model, zero) = load(mesh_blob(points, OutsidePolicy::Zero));
        let (_, nearest) = load(mesh_blob(points, OutsidePolicy::NearestHull));
        let (hybrid_model, _) = load(model_blob(poly.clone(), Some(points), OutsidePolicy::Zero));
        let oracle = Oracle::new(&zero);
        let (zero_axis, hybrid_axis) =
            (zero_model.axis(0).expect("axis"), hybrid_model.axis(0).expect("axis"));
        let mut r = rng(7000 + i as u64);
        let (mut h1, mut h2, mut h3) = (WalkHint::default(), WalkHint::default(), WalkHint::default());
        let mut outside = 0usize;
        for _ in 0..2000 {
            let (temp_c, rate) = (r.gen_range(-80.0f32..120.0), r.gen_range(-0.5f32..1.5));
            let z = zero_axis.evaluate(temp_c, rate, &mut h1).expect("finite");
            let (x, y) = zero_axis.normalisation.apply(temp_c, rate);
            let nh = nearest.interpolate(x, y, &mut h2).expect("finite");
            let hy = hybrid_axis.evaluate(temp_c, rate, &mut h3).expect("finite");
            let poly_only = hybrid_axis.poly.expect("poly").evaluate(x, y);
            assert_eq!(z.outside_hull, nh.outside_hull, "{name}: same mesh, same walk");
            assert_eq!(hy.outside_hull, z.outside_hull, "{name}");
            if z.outside_hull {
                outside += 1;
                // Flag only with a real margin: inside/outside is only decided to HULL_SLACK.
                let d = oracle.hull_distance(f64::from(x), f64::from(y));
                assert!(d < HULL_SLACK || oracle.interpolate(x, y).is_none(), "{name}: ({x}, {y}) is inside");
                assert_eq!(z.value_dph.to_bits(), 0.0f32.to_bits(), "{name}: Zero policy outside is +0");
                assert_eq!(
                    hy.value_dph.to_bits(),
                    (poly_only + 0.0).to_bits(),
                    "{name}: hybrid outside is the polynomial"
                );
            } else {
                assert_eq!(
                    z.value_dph.to_bits(),
                    nh.value_dph.to_bits(),
                    "{name}: the policy only acts outside"
                );
                assert_eq!(hy.value_dph.to_bits(), (poly_only + z.value_dph).to_bits(), "{name}");
            }
        }
        assert!(outside > 100, "{name}: the query box reaches well outside the hull");
    }
}

// ---------------------------------------------------------------------------------------------
// 5. Coherent trajectories
// ---------------------------------------------------------------------------------------------

#[test]
fn walk_along_warm_up_trajectory_agrees_with_scan_and_moves_between_adjacent_triangles() {
    let (_, mesh) = load(mesh_blob(&paper_points(70, bias_surface), OutsidePolicy::NearestHull));
    let oracle = Oracle::new(&mesh);
    let (mut steps, mut changes, mut vertex_only_adjacent, mut near_hull) = (0usize, 0usize, 0usize, 0usize);
    // Warm-ups starting between the calibration runs, sampled every 10 ms for the first 20 s
    // (1 kHz firmware moves even less per sample) and every second for two hours.
    let (self_heat_c, tau_min) = (12.0f64, 20.0f64);
    for start_c in [-32.5f64, -2.5, 27.5, 52.5] {
        let times_s = (0..2000).map(|k| f64::from(k) * 0.01).chain((20..7200).map(f64::from));
        let mut hint = WalkHint::default();
        let mut previous: Option<Location> = None;
        for time_s in times_s {
            let t_min = time_s / 60.0;
            let temp_c = start_c + self_heat_c * (1.0 - (-t_min / tau_min).exp());
            let rate = self_heat_c / tau_min * (-t_min / tau_min).exp();
            let (x, y) = NORMALISATION.apply(temp_c as f32, rate as f32);
            let walk = mesh.locate(x, y, &mut hint).expect("finite");
            let scan = mesh.locate_by_scan(x, y);
            steps += 1;
            match (walk, scan) {
                (Location::Inside { triangle: w, .. }, Location::Inside { triangle: s, .. }) => {
                    if w != s {
                        // Only a point on a shared boundary is accepted by two triangles.
                        let (a, b) = (mesh.triangle(w).expect("t"), mesh.triangle(s).expect("t"));
                        assert!(min3(bary(&a, x, y)) >= -INSIDE_EPS && min3(bary(&b, x, y)) >= -INSIDE_EPS);
                    }
                }
                (Location::Outside { .. }, Location::Outside { .. }) => {}
                _ => {
                    let d = oracle.hull_distance(f64::from(x), f64::from(y));
                    assert!(d < HULL_SLACK, "walk {walk:?} and scan {scan:?} disagree {d:e} from the hull");
                    near_hull += 1;
                }
            }
            let now = match walk {
                Location::Inside { triangle, .. } | Location::Outside { triangle } => triangle,
            };
            if let Some(Location::Inside { triangle: before, .. } | Location::Outside { triangle: before }) =
                previous
            {
                if before != now {
                    changes += 1;
                    let (a, b) = (mesh.triangle(before).expect("t"), mesh.triangle(now).expect("t"));
                    if !a.neighbours.contains(&now) {
                        // A step of at most ~2e-4 normalised can only pass a vertex corner.
                        assert!(
                            a.vertices.iter().any(|v| b.vertices.contains(v)),
                            "a small step jumped from triangle {before} to the unrelated {now}"
                        );
                        vertex_only_adjacent += 1;
                    }
                }
            }
            previous = Some(walk);
        }
    }
    println!(
        "trajectory: {steps} steps, {changes} triangle changes ({vertex_only_adjacent} across a vertex), \
         {near_hull} near-hull disagreements"
    );
    assert!(changes > 20, "the trajectories cross the mesh");
    assert!(changes * 20 < steps, "a coherent trajectory stays in its triangle most of the time");
}

// ---------------------------------------------------------------------------------------------
// 6. Degenerate input, and what the writer merges and drops
// ---------------------------------------------------------------------------------------------

fn point(temp_c: f64, rate_c_per_min: f64) -> MeshPoint {
    MeshPoint { temp_c, rate_c_per_min, value_dph: 0.1 }
}

#[test]
fn degenerate_point_sets_are_rejected_as_degenerate_mesh() {
    let cases: Vec<(&str, Vec<MeshPoint>)> = vec![
        ("empty", vec![]),
        ("one point", vec![point(20.0, 0.5)]),
        ("two points", vec![point(20.0, 0.5), point(30.0, 0.1)]),
        ("all duplicates", vec![point(20.0, 0.5); 6]),
        ("three points, two equal", vec![point(20.0, 0.5), point(20.0, 0.5), point(30.0, 0.1)]),
        ("collinear, constant rate", (0..10).map(|i| point(-40.0 + 12.0 * f64::from(i), 0.25)).collect()),
        ("collinear, constant temperature", (0..10).map(|i| point(5.0, 0.1 * f64::from(i))).collect()),
        (
            "collinear, diagonal",
            (0..10).map(|i| point(-40.0 + 12.0 * f64::from(i), 0.1 * f64::from(i))).collect(),
        ),
    ];
    for (name, points) in cases {
        match build_mesh(&points, &NORMALISATION) {
            Err(CalError::DegenerateMesh { .. }) => {}
            other => panic!("{name}: expected DegenerateMesh, got {other:?}"),
        }
    }
}

#[test]
fn non_finite_points_are_rejected() {
    let good = random_points(20, 301, bias_surface);
    for (field, bad) in
        [(0, f64::NAN), (1, f64::NAN), (2, f64::NAN), (0, f64::INFINITY), (2, f64::NEG_INFINITY)]
    {
        let mut points = good.clone();
        match field {
            0 => points[7].temp_c = bad,
            1 => points[7].rate_c_per_min = bad,
            _ => points[7].value_dph = bad,
        }
        let result = build_mesh(&points, &NORMALISATION);
        assert!(
            matches!(result, Err(CalError::NonFinite { index: 7, .. })),
            "field {field} = {bad}: {result:?}"
        );
    }
}

#[test]
fn paper_mesh_keeps_every_point_and_moves_hull_points_by_less_than_a_millidegree_scale() {
    // A first-order warm-up is a straight line in (T, rate), so the outermost runs lie
    // exactly along the hull and make flat triangles; the writer pushes such points
    // outward by PUSH_RATIO of the long edge instead of dropping them.
    let points = paper_points(70, bias_surface);
    let mesh = build_mesh(&points, &NORMALISATION).expect("paper points triangulate");
    let (max_dt, max_dr) =
        mesh.moved_flat.iter().fold((0.0f64, 0.0f64), |(a, b), (dt, dr)| (a.max(dt.abs()), b.max(dr.abs())));
    println!(
        "paper_points(70): {} input points, {} merged duplicates, {} dropped, {} moved (max |dT| {:.2e} C, \
         max |dR| {:.2e} C/min), {} vertices, {} triangles, {} hull edges",
        points.len(),
        mesh.merged_duplicates,
        mesh.dropped_flat.len(),
        mesh.moved_flat.len(),
        max_dt,
        max_dr,
        mesh.vertices.len(),
        mesh.triangles.len(),
        mesh.hull.len()
    );
    assert!(mesh.dropped_flat.is_empty(), "no calibration point is dropped");
    assert_eq!(mesh.vertices.len() + mesh.merged_duplicates, points.len());
    // The push is PUSH_RATIO (4e-4) of an edge of at most the normalised box diagonal
    // (2 sqrt 2), i.e. < 1.2e-3 normalised: 0.07 C and 6e-4 C/min with NORMALISATION,
    // far below a 0.0625 C sensor step. A second push of the same point is allowed.
    assert!(max_dt < 2.0 * 1.2e-3 * 60.0, "temperature shift {max_dt} C");
    assert!(max_dr < 2.0 * 1.2e-3 / 2.0, "rate shift {max_dr} C/min");
    // Every point keeps its value at (nearly) its place: the model at the original point.
    let (model, _) = load(mesh_blob(&points, OutsidePolicy::NearestHull));
    let axis = model.axis(0).expect("axis");
    let mut hint = WalkHint::default();
    let worst = points
        .iter()
        .map(|p| {
            let e = axis.evaluate(p.temp_c as f32, p.rate_c_per_min as f32, &mut hint).expect("finite");
            (f64::from(e.value_dph) - p.value_dph).abs()
        })
        .fold(0.0, f64::max);
    println!("  largest |model - value| at a calibration point: {worst:.3e} dph");
    // Bound: the surface's gradient times the shift, plus f32 rounding of values ~0.3 dph.
    // bias_surface: |d/dT| <= 0.002 + 2 * 1.5e-5 * 72 + 0.01 / 15 < 0.005 dph/C,
    // |d/dR| <= 0.06 + 0.01 = 0.07 dph per C/min.
    let bound = 0.005 * max_dt + 0.07 * max_dr + 1e-6;
    assert!(worst < bound, "model misses a calibration point by {worst} dph (bound {bound})");
}

#[test]
fn grid_walk_gives_the_same_value_and_flag_as_the_hint_walk() {
    // Same planes, different start triangle: the values may differ only when a query lies
    // on an edge shared by two triangles (both planes agree there to f32 rounding), so the
    // tolerance is a few ulps of the values (|v| < 1 dph).
    for (name, points) in
        [("random", random_points(2000, 21, bias_surface)), ("paper", paper_points(70, bias_surface))]
    {
        let (_, mesh) = load(mesh_blob(&points, OutsidePolicy::NearestHull));
        for side in [1u32, 7, 32] {
            let mut cells = vec![0u32; (side * side) as usize];
            let grid = mesh.start_grid(side, &mut cells).expect("grid fits its buffer");
            let (mut hint, mut grid_hint) = (WalkHint::default(), WalkHint::default());
            let mut r = rng(77);
            for i in 0..5000 {
                let (x, y) = (r.gen_range(-1.3f32..1.3), r.gen_range(-1.3f32..1.3));
                let plain = mesh.interpolate(x, y, &mut hint).expect("finite");
                let gridded = mesh.interpolate_with_grid(x, y, &mut grid_hint, &grid).expect("finite");
                assert_eq!(
                    plain.outside_hull, gridded.outside_hull,
                    "{name} side {side} query {i} ({x}, {y})"
                );
                assert!(
                    (plain.value_dph - gridded.value_dph).abs() <= 1e-6,
                    "{name} side {side} query {i}: {} vs {}",
                    plain.value_dph,
                    gridded.value_dph
                );
            }
        }
    }
}

#[test]
fn start_grid_rejects_a_buffer_too_short() {
    let (_, mesh) = load(mesh_blob(&random_points(50, 3, bias_surface), OutsidePolicy::NearestHull));
    let mut cells = vec![0u32; 15];
    assert!(mesh.start_grid(4, &mut cells).is_err());
    assert!(mesh.start_grid(0, &mut cells).is_err());
    assert!(mesh.start_grid(3, &mut cells).is_ok());
}
