//! Shared fixtures: calibration point sets, model blobs built with the real writer, the
//! spade triangulation of a blob's own nodes, and the query streams every peer reads.
//!
//! Ideas copied from `tests/common/mod.rs` (the benches cannot import it); fixed seeds
//! throughout, so every run measures the same nodes and the same queries.

use fogtemp_cal::{build_mesh, encode, AxisModel, MeshPoint, ModelFile};
use fogtemp_core::{
    AxisProvenance, FeatureSettings, Location, Mesh, Model, Normalisation, OutsidePolicy, PolyTerm, WalkHint,
};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use spade::{DelaunayTriangulation, HasPosition, Point2, PositionInTriangulation, Triangulation};

/// Paper defaults: 100 s window of 100 one-second blocks.
pub const FEATURES: FeatureSettings =
    FeatureSettings { window_s: 100.0, block_count: 100, min_blocks: 10, max_gap_s: 5.0 };

/// Maps -40..80 C to -1..1 and 0..1 C/min to -1..1 (as in the tests).
pub const NORMALISATION: Normalisation = Normalisation {
    temp_offset_c: 20.0,
    temp_scale_per_c: 1.0 / 60.0,
    rate_offset_c_per_min: 0.5,
    rate_scale_per_c_per_min: 2.0,
};

/// Calibration points per warm-up run of the paper-size mesh: 8 runs of 72, 576 nodes
/// (the size of the spade reference measurement).
pub const PAPER_POINTS_PER_RUN: usize = 72;
/// Nodes of the large random mesh.
pub const LARGE_MESH_NODES: usize = 10_000;

/// Self-heating of the simulated warm-up, deg C, and its time constant, minutes.
const SELF_HEAT_C: f64 = 12.0;
const TAU_MIN: f64 = 20.0;

/// A seeded generator.
pub fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

/// A smooth, non-planar bias surface in deg/h.
pub fn bias_surface(temp_c: f64, rate_c_per_min: f64) -> f64 {
    0.002 * temp_c
        + 1.5e-5 * temp_c * temp_c
        + 0.06 * rate_c_per_min
        + 0.01 * (temp_c / 15.0).sin() * rate_c_per_min
}

/// Uniform random points over the calibrated box (-40..80 C, 0..1 C/min).
pub fn random_points(n: usize, seed: u64) -> Vec<MeshPoint> {
    let mut r = rng(seed);
    (0..n)
        .map(|_| {
            let temp_c = r.gen_range(-40.0..80.0);
            let rate_c_per_min = r.gen_range(0.0..1.0);
            MeshPoint { temp_c, rate_c_per_min, value_dph: bias_surface(temp_c, rate_c_per_min) }
        })
        .collect()
}

/// Temperature (deg C) and rate (deg C/min) of a first-order warm-up from `start_c`,
/// `t_min` minutes after power-on.
pub fn warm_up(start_c: f64, t_min: f64) -> (f64, f64) {
    let decay = (-t_min / TAU_MIN).exp();
    (start_c + SELF_HEAT_C * (1.0 - decay), SELF_HEAT_C / TAU_MIN * decay)
}

/// Paper-like points: 8 power-on warm-ups (start -40..60 C), sampled densely early and
/// sparsely later (quadratic spacing over 120 min).
pub fn paper_points(per_run: usize) -> Vec<MeshPoint> {
    let starts = [-40.0, -25.0, -10.0, 5.0, 20.0, 35.0, 45.0, 60.0];
    let mut out = Vec::new();
    for (run, start) in starts.iter().enumerate() {
        for i in 0..per_run {
            let s = (i as f64 + 0.5) / per_run as f64;
            let (temp_c, rate) = warm_up(*start, 120.0 * s * s);
            let temp_c = temp_c + 0.01 * run as f64;
            out.push(MeshPoint { temp_c, rate_c_per_min: rate, value_dph: bias_surface(temp_c, rate) });
        }
    }
    out
}

fn provenance() -> AxisProvenance {
    AxisProvenance {
        fit_point_count: 0,
        residual_rms_dph: 0.0,
        residual_max_abs_dph: 0.0,
        temp_min_c: -40.0,
        temp_max_c: 80.0,
        rate_min_c_per_min: 0.0,
        rate_max_c_per_min: 1.0,
    }
}

/// The paper's polynomial in the normalised inputs: T, T^2, T^3, dT, dT^2, dT^3, T dT,
/// T^2 dT, T dT^2, T^3 dT, T dT^3, plus a constant (coefficients are arbitrary but of a
/// realistic size; only the cost matters here).
pub fn paper_poly() -> Vec<PolyTerm> {
    let terms: [(u8, u8, f32); 12] = [
        (0, 0, 0.031),
        (1, 0, 0.120),
        (2, 0, 0.054),
        (3, 0, -0.017),
        (0, 1, 0.030),
        (0, 2, -0.008),
        (0, 3, 0.002),
        (1, 1, 0.011),
        (2, 1, -0.004),
        (1, 2, 0.003),
        (3, 1, 0.001),
        (1, 3, -0.0007),
    ];
    terms
        .iter()
        .map(|&(temp_power, rate_power, coefficient_dph)| PolyTerm {
            temp_power,
            rate_power,
            coefficient_dph,
        })
        .collect()
}

/// A one-axis model blob: optional polynomial, optional mesh of `points`.
pub fn model_blob(poly: Vec<PolyTerm>, points: Option<&[MeshPoint]>) -> Vec<u8> {
    let mesh = points.map(|p| build_mesh(p, &NORMALISATION).expect("mesh builds"));
    let axis = AxisModel {
        features: FEATURES,
        normalisation: NORMALISATION,
        outside_policy: OutsidePolicy::NearestHull,
        poly,
        mesh,
        provenance: provenance(),
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
    };
    let file = ModelFile {
        tool_version: "fogtemp bench".into(),
        input_digest: [0; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    };
    encode(&file).expect("encodes")
}

/// The mesh of axis 0 of a model `blob`.
pub fn mesh_of(blob: &[u8]) -> Mesh<'_> {
    let model = Model::from_bytes(blob).expect("valid blob");
    model.axis(0).expect("axis 0").mesh.expect("mesh")
}

/// A spade vertex: normalised position (f64) and value (deg/h).
#[derive(Clone, Copy, Debug)]
pub struct Node {
    position: Point2<f64>,
    /// Bias at this node, deg/h.
    pub value_dph: f64,
}

impl HasPosition for Node {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.position
    }
}

/// Spade's Delaunay triangulation of exactly the blob's nodes (normalised f32 positions
/// widened to f64), so spade and the walk interpolate over the same triangles.
pub fn spade_of(mesh: &Mesh<'_>) -> DelaunayTriangulation<Node> {
    let nodes: Vec<Node> = (0..mesh.vertex_count())
        .map(|i| {
            let v = mesh.vertex(i).expect("vertex exists");
            Node { position: Point2::new(f64::from(v.x), f64::from(v.y)), value_dph: f64::from(v.value_dph) }
        })
        .collect();
    DelaunayTriangulation::bulk_load_stable(nodes).expect("spade triangulates the blob's nodes")
}

/// One query in every form a peer needs: physical inputs, the normalised f32 point the
/// firmware computes from them, and that point widened to f64 for spade.
#[derive(Clone, Copy, Debug)]
pub struct Query {
    /// Temperature, deg C.
    pub temp_c: f32,
    /// Temperature rate, deg C/min.
    pub rate_c_per_min: f32,
    /// Normalised temperature.
    pub x: f32,
    /// Normalised rate.
    pub y: f32,
    /// `(x, y)` as f64.
    pub p: Point2<f64>,
}

impl Query {
    /// The query for physical inputs.
    pub fn physical(temp_c: f32, rate_c_per_min: f32) -> Self {
        let (x, y) = NORMALISATION.apply(temp_c, rate_c_per_min);
        Query { temp_c, rate_c_per_min, x, y, p: Point2::new(f64::from(x), f64::from(y)) }
    }

    /// The query at a normalised point (physical inputs by the inverse map).
    pub fn normalised(x: f32, y: f32) -> Self {
        let n = &NORMALISATION;
        Self::physical(
            x / n.temp_scale_per_c + n.temp_offset_c,
            y / n.rate_scale_per_c_per_min + n.rate_offset_c_per_min,
        )
    }
}

/// Start temperature of the benchmark warm-up: between the 5 C and 20 C calibration runs.
pub const TRAJECTORY_START_C: f64 = 12.5;
/// Warm-up span the coherent trajectory covers, minutes after power-on (inside the
/// paper mesh's calibrated rate range at both ends).
pub const TRAJECTORY_SPAN_MIN: (f64, f64) = (0.1, 110.0);

/// A coherent trajectory: the warm-up from [`TRAJECTORY_START_C`] over
/// [`TRAJECTORY_SPAN_MIN`], in `n` equal time steps (for `n = 2^17`, one step is 50 ms of
/// warm-up: a 1 kHz stream of a warm-up 50 times faster than the real one, so the walk
/// crosses triangles 50 times more often than in the field).
pub fn coherent_queries(n: usize) -> Vec<Query> {
    let (t0, t1) = TRAJECTORY_SPAN_MIN;
    (0..n)
        .map(|i| {
            let t_min = t0 + (t1 - t0) * i as f64 / (n - 1) as f64;
            let (temp_c, rate) = warm_up(TRAJECTORY_START_C, t_min);
            Query::physical(temp_c as f32, rate as f32)
        })
        .collect()
}

/// The bounding box of `mesh`'s nodes (normalised): lowest and highest `[x, y]`.
pub fn node_box(mesh: &Mesh<'_>) -> ([f32; 2], [f32; 2]) {
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for i in 0..mesh.vertex_count() {
        let v = mesh.vertex(i).expect("vertex exists");
        lo = [lo[0].min(v.x), lo[1].min(v.y)];
        hi = [hi[0].max(v.x), hi[1].max(v.y)];
    }
    (lo, hi)
}

/// `n` queries uniform over the bounding box of `mesh`'s nodes, kept only when inside the
/// hull for both the walk and spade (outside the hull the peers do different things), in
/// random order: every query starts the walk from an unrelated triangle.
pub fn random_inside_queries(
    mesh: &Mesh<'_>,
    dt: &DelaunayTriangulation<Node>,
    n: usize,
    seed: u64,
) -> Vec<Query> {
    let (lo, hi) = node_box(mesh);
    let mut r = rng(seed);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let q = Query::normalised(r.gen_range(lo[0]..hi[0]), r.gen_range(lo[1]..hi[1]));
        // Round-trip through physical units moves the point by an ulp or so: use what
        // the firmware would see.
        let ours_inside = matches!(mesh.locate_by_scan(q.x, q.y), Location::Inside { .. });
        let spade_inside = !matches!(dt.locate(q.p), PositionInTriangulation::OutsideOfConvexHull(_));
        if ours_inside && spade_inside {
            out.push(q);
        }
    }
    out
}

/// Walk statistics of a query stream: how many queries fall outside the hull and how
/// often the containing triangle changes from one query to the next.
pub struct StreamStats {
    /// Queries outside the hull.
    pub outside: usize,
    /// Queries whose triangle differs from the previous query's.
    pub triangle_changes: usize,
}

/// Runs `queries` through the walk once (outside the measurement).
pub fn stream_stats(mesh: &Mesh<'_>, queries: &[Query]) -> StreamStats {
    let mut hint = WalkHint::default();
    let (mut outside, mut triangle_changes, mut previous) = (0, 0, u32::MAX);
    for q in queries {
        let t = match mesh.locate(q.x, q.y, &mut hint).expect("finite query") {
            Location::Inside { triangle, .. } => triangle,
            Location::Outside { triangle } => {
                outside += 1;
                triangle
            }
        };
        if t != previous {
            triangle_changes += 1;
            previous = t;
        }
    }
    StreamStats { outside, triangle_changes }
}

/// A temperature replay at 1 kHz: a warm-up from [`TRAJECTORY_START_C`] at power-on, with
/// a seeded ±0.01 deg C sensor noise quantised to 1/256 deg C. Sample `i` is at `i` ms.
pub fn temperature_replay(samples: usize, seed: u64) -> Vec<f32> {
    let mut r = rng(seed);
    (0..samples)
        .map(|i| {
            let (temp_c, _) = warm_up(TRAJECTORY_START_C, i as f64 / 60_000.0);
            let noisy = temp_c + r.gen_range(-0.01..0.01);
            ((noisy * 256.0).round() / 256.0) as f32
        })
        .collect()
}

/// Gyro samples in deg/h: a small constant rate plus seeded white noise.
pub fn gyro_replay(samples: usize, seed: u64) -> Vec<f32> {
    let mut r = rng(seed);
    (0..samples).map(|_| 15.0 + r.gen_range(-0.5f32..0.5)).collect()
}
