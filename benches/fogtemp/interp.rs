//! `interp/*`: per-sample mesh interpolation, the walk against spade and a full scan, on
//! the same nodes and the same queries.
//!
//! Peers, per mesh (each id is `<peer>/<mesh>`):
//! - `fogtemp_walk`: `Mesh::interpolate` (normalised f32 input) with a persistent `WalkHint`.
//! - `fogtemp_axis_evaluate`: `Axis::evaluate` (physical input: finite checks,
//!   normalisation, walk, plane) with a persistent `WalkHint`.
//! - `spade_locate_with_hint`: spade's `Triangulation::locate_with_hint` with the hint the
//!   last used vertex (the vertex of the previous query's face with the largest weight),
//!   then barycentric weights of that face (f64).
//! - `spade_barycentric`: `dt.barycentric().interpolate(..)`, spade's own barycentric
//!   interpolation with its built-in last-used-vertex hint (the reference).
//! - `fogtemp_grid_walk`: `Mesh::interpolate_with_grid`: the triangle of the query's cell of
//!   a start grid first, else a walk from it.
//! - `fogtemp_scan`: `Mesh::locate_by_scan` plus the triangle's plane, O(triangles) per
//!   query; measured on every `SCAN_STRIDE`-th query of the same stream.
//!
//! `interp/outside_hull`: random-order queries outside the hull only (the outside policy's
//! cost), per mesh:
//! - `fogtemp_nearest_hull_value`: `Mesh::nearest_hull_value` (fan binary search, descent,
//!   three edges).
//! - `fogtemp_nearest_hull_value_by_scan`: `Mesh::nearest_hull_value_by_scan`, every hull
//!   edge (the implementation before the search).
//! - `fogtemp_grid_walk`: `Mesh::interpolate_with_grid`, the whole outside query (walk from
//!   the start grid to the hull, then the hull value).

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkGroup, BenchmarkId, Criterion, SamplingMode, Throughput};
use fogtemp_core::{Location, Mesh, Model, WalkHint};
use spade::handles::FixedVertexHandle;
use spade::{DelaunayTriangulation, FloatTriangulation, PositionInTriangulation, Triangulation};

use crate::fixtures::{self, Node, Query};
use rand::Rng;

/// Queries in the coherent stream.
const COHERENT_QUERIES: usize = 1 << 17;
/// Queries in the random-order stream.
const RANDOM_QUERIES: usize = 1 << 14;
/// Queries in the outside-hull stream.
const OUTSIDE_QUERIES: usize = 1 << 14;
/// The scan peer runs on every `SCAN_STRIDE`-th query (it is O(triangles) per query).
const SCAN_STRIDE: usize = 64;

/// One mesh under test: its blob, and spade's triangulation of the same nodes.
struct Subject {
    name: String,
    blob: Vec<u8>,
    dt: DelaunayTriangulation<Node>,
}

impl Subject {
    fn new(name: &'static str, points: &[fogtemp_cal::MeshPoint]) -> Self {
        let blob = fixtures::model_blob(Vec::new(), Some(points));
        let mesh = fixtures::mesh_of(&blob);
        let dt = fixtures::spade_of(&mesh);
        assert_eq!(dt.num_vertices(), mesh.vertex_count() as usize, "spade keeps every node");
        Subject { name: format!("{name}{}", mesh.vertex_count()), blob, dt }
    }
}

fn subjects() -> Vec<Subject> {
    vec![
        Subject::new("paper", &fixtures::paper_points(fixtures::PAPER_POINTS_PER_RUN)),
        Subject::new("random", &fixtures::random_points(fixtures::LARGE_MESH_NODES, 7)),
    ]
}

/// spade: `locate_with_hint` from the last used vertex, then barycentric weights (f64).
#[inline]
fn spade_with_hint(dt: &DelaunayTriangulation<Node>, q: &Query, hint: &mut FixedVertexHandle) -> f64 {
    match dt.locate_with_hint(q.p, *hint) {
        PositionInTriangulation::OnFace(face) => {
            let face = dt.face(face);
            let vs = face.vertices();
            let w = face.barycentric_interpolation(q.p);
            let k = if w[0] >= w[1] && w[0] >= w[2] {
                0
            } else if w[1] >= w[2] {
                1
            } else {
                2
            };
            *hint = vs[k].fix();
            w[0] * vs[0].data().value_dph + w[1] * vs[1].data().value_dph + w[2] * vs[2].data().value_dph
        }
        PositionInTriangulation::OnEdge(edge) => {
            let [a, b] = dt.directed_edge(edge).vertices();
            let (pa, pb) = (a.position(), b.position());
            let len2 = (pb.x - pa.x).powi(2) + (pb.y - pa.y).powi(2);
            let s = ((q.p.x - pa.x) * (pb.x - pa.x) + (q.p.y - pa.y) * (pb.y - pa.y)) / len2;
            *hint = a.fix();
            a.data().value_dph + s * (b.data().value_dph - a.data().value_dph)
        }
        PositionInTriangulation::OnVertex(v) => {
            *hint = v;
            dt.vertex(v).data().value_dph
        }
        PositionInTriangulation::OutsideOfConvexHull(edge) => {
            *hint = dt.directed_edge(edge).from().fix();
            0.0
        }
        PositionInTriangulation::NoTriangulation => 0.0,
    }
}

/// Scan every triangle, then the plane of the best one.
#[inline]
fn scan(mesh: &Mesh<'_>, q: &Query) -> f32 {
    match mesh.locate_by_scan(q.x, q.y) {
        Location::Inside { triangle, .. } => mesh.triangle(triangle).map_or(0.0, |r| {
            let (dx, dy) = (q.x - r.origin[0], q.y - r.origin[1]);
            r.plane[0] * dx + r.plane[1] * dy + r.plane[2]
        }),
        Location::Outside { .. } => 0.0,
    }
}

/// Side of the start grid: about four triangles per cell.
fn grid_side(mesh: &Mesh<'_>) -> u32 {
    ((mesh.triangle_count() as f32 / 4.0).sqrt() as u32).max(1)
}

/// The walk, spade and the scan agree on every query (to f32 rounding of the planes).
fn check_agreement(mesh: &Mesh<'_>, dt: &DelaunayTriangulation<Node>, queries: &[Query]) {
    let side = grid_side(mesh);
    let mut cells = vec![0u32; (side * side) as usize];
    let grid = mesh.start_grid(side, &mut cells).expect("grid fits");
    let mut hint = WalkHint::default();
    let mut grid_hint = WalkHint::default();
    let mut spade_hint = FixedVertexHandle::from_index(0);
    let mut worst = 0.0f64;
    for (i, q) in queries.iter().enumerate() {
        let ours = f64::from(mesh.interpolate(q.x, q.y, &mut hint).expect("finite").value_dph);
        let theirs = spade_with_hint(dt, q, &mut spade_hint);
        let grid_value =
            mesh.interpolate_with_grid(q.x, q.y, &mut grid_hint, &grid).expect("finite").value_dph;
        // Another start may end in the neighbour when the query lies on their shared edge.
        assert!((f64::from(grid_value) - ours).abs() < 1e-5, "grid walk disagrees at query {i}");
        worst = worst.max((ours - theirs).abs());
        if i % SCAN_STRIDE == 0 {
            assert!((f64::from(scan(mesh, q)) - ours).abs() < 1e-4, "scan disagrees at query {i}");
        }
    }
    assert!(worst < 1e-4, "walk and spade disagree by {worst} deg/h");
}

/// Every peer on one mesh and one query stream, in one group.
fn bench_peers(
    group: &mut BenchmarkGroup<'_, criterion::measurement::WallTime>,
    s: &Subject,
    queries: &[Query],
) {
    let model = Model::from_bytes(&s.blob).expect("valid blob");
    let axis = model.axis(0).expect("axis 0");
    let mesh = axis.mesh.expect("mesh");
    let stats = fixtures::stream_stats(&mesh, queries);
    assert_eq!(stats.outside, 0, "every query lies inside the hull of {}", s.name);
    check_agreement(&mesh, &s.dt, queries);
    let side = grid_side(&mesh);
    let mut cells = vec![0u32; (side * side) as usize];
    let grid = mesh.start_grid(side, &mut cells).expect("grid fits");
    eprintln!(
        "{}: {} nodes, {} triangles, {} queries, {} triangle changes ({:.1} queries per triangle), \
         start grid {side}x{side}",
        s.name,
        mesh.vertex_count(),
        mesh.triangle_count(),
        queries.len(),
        stats.triangle_changes,
        queries.len() as f64 / stats.triangle_changes as f64,
    );

    group.throughput(Throughput::Elements(queries.len() as u64));
    let mut hint = WalkHint::default();
    group.bench_function(BenchmarkId::new("fogtemp_walk", &s.name), |b| {
        b.iter(|| {
            for q in black_box(queries) {
                black_box(mesh.interpolate(q.x, q.y, &mut hint).map_or(0.0, |v| v.value_dph));
            }
        })
    });
    let mut hint = WalkHint::default();
    group.bench_function(BenchmarkId::new("fogtemp_grid_walk", &s.name), |b| {
        b.iter(|| {
            for q in black_box(queries) {
                black_box(
                    mesh.interpolate_with_grid(q.x, q.y, &mut hint, &grid).map_or(0.0, |v| v.value_dph),
                );
            }
        })
    });
    let mut hint = WalkHint::default();
    group.bench_function(BenchmarkId::new("fogtemp_axis_evaluate", &s.name), |b| {
        b.iter(|| {
            for q in black_box(queries) {
                black_box(axis.evaluate(q.temp_c, q.rate_c_per_min, &mut hint).map_or(0.0, |e| e.value_dph));
            }
        })
    });
    let mut spade_hint = FixedVertexHandle::from_index(0);
    group.bench_function(BenchmarkId::new("spade_locate_with_hint", &s.name), |b| {
        b.iter(|| {
            for q in black_box(queries) {
                black_box(spade_with_hint(&s.dt, q, &mut spade_hint));
            }
        })
    });
    let barycentric = s.dt.barycentric();
    group.bench_function(BenchmarkId::new("spade_barycentric", &s.name), |b| {
        b.iter(|| {
            for q in black_box(queries) {
                black_box(barycentric.interpolate(|v| v.data().value_dph, q.p));
            }
        })
    });

    let strided: Vec<Query> = queries.iter().step_by(SCAN_STRIDE).copied().collect();
    group.throughput(Throughput::Elements(strided.len() as u64));
    group.bench_function(BenchmarkId::new("fogtemp_scan", &s.name), |b| {
        b.iter(|| {
            for q in black_box(&strided) {
                black_box(scan(&mesh, q));
            }
        })
    });
}

fn configure(group: &mut BenchmarkGroup<'_, criterion::measurement::WallTime>) {
    // Iterations take 0.3-30 ms: flat sampling, a few seconds each.
    group.sampling_mode(SamplingMode::Flat);
    group.sample_size(20);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(4));
}

/// `interp/coherent`: a smooth warm-up trajectory, many queries per triangle.
pub fn coherent(c: &mut Criterion) {
    let queries = fixtures::coherent_queries(COHERENT_QUERIES);
    let mut group = c.benchmark_group("interp/coherent");
    configure(&mut group);
    for s in &subjects() {
        bench_peers(&mut group, s, &queries);
    }
    group.finish();
}

/// `interp/random_order`: uniform random queries inside the hull, the walk's worst case.
pub fn random_order(c: &mut Criterion) {
    let mut group = c.benchmark_group("interp/random_order");
    configure(&mut group);
    for s in &subjects() {
        let mesh = fixtures::mesh_of(&s.blob);
        let queries = fixtures::random_inside_queries(&mesh, &s.dt, RANDOM_QUERIES, 11);
        bench_peers(&mut group, s, &queries);
    }
    group.finish();
}

/// `n` queries uniform over `mesh`'s bounding box grown by `margin` of its span on every side,
/// kept only when outside the hull (by the scan), in random order.
fn random_outside_queries(mesh: &Mesh<'_>, n: usize, margin: f32, seed: u64) -> Vec<Query> {
    let (lo, hi) = fixtures::node_box(mesh);
    let grow = [margin * (hi[0] - lo[0]), margin * (hi[1] - lo[1])];
    let mut r = fixtures::rng(seed);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let q = Query::normalised(
            r.gen_range(lo[0] - grow[0]..hi[0] + grow[0]),
            r.gen_range(lo[1] - grow[1]..hi[1] + grow[1]),
        );
        if matches!(mesh.locate_by_scan(q.x, q.y), Location::Outside { .. }) {
            out.push(q);
        }
    }
    out
}

/// `interp/outside_hull`: the value at the nearest hull point, by the search and by the scan,
/// and the whole outside query, on random points of the box 30 % larger than the mesh's that
/// fall outside its hull.
pub fn outside_hull(c: &mut Criterion) {
    let mut group = c.benchmark_group("interp/outside_hull");
    configure(&mut group);
    for s in &subjects() {
        let mesh = fixtures::mesh_of(&s.blob);
        let queries = random_outside_queries(&mesh, OUTSIDE_QUERIES, 0.3, 13);
        // The search agrees with the scan: bit for bit, or (a tie f32 cannot resolve) to the
        // value tolerance of `check_agreement`.
        let mut certified = 0usize;
        let mut differ = 0usize;
        for (i, q) in queries.iter().enumerate() {
            let (fast, scan) = (mesh.nearest_hull_value(q.x, q.y), mesh.nearest_hull_value_by_scan(q.x, q.y));
            assert!((fast - scan).abs() < 1e-4, "{}: search and scan disagree at query {i}", s.name);
            differ += usize::from(fast.to_bits() != scan.to_bits());
            certified += usize::from(mesh.nearest_hull_edge(q.x, q.y).is_some());
        }
        eprintln!(
            "{}: {} hull edges, {} outside queries, {certified} answered by the search, \
             {differ} not bit-equal to the scan",
            s.name,
            mesh.hull_edge_count(),
            queries.len(),
        );
        group.throughput(Throughput::Elements(queries.len() as u64));
        group.bench_function(BenchmarkId::new("fogtemp_nearest_hull_value", &s.name), |b| {
            b.iter(|| {
                for q in black_box(&queries) {
                    black_box(mesh.nearest_hull_value(q.x, q.y));
                }
            })
        });
        group.bench_function(BenchmarkId::new("fogtemp_nearest_hull_value_by_scan", &s.name), |b| {
            b.iter(|| {
                for q in black_box(&queries) {
                    black_box(mesh.nearest_hull_value_by_scan(q.x, q.y));
                }
            })
        });
        let side = grid_side(&mesh);
        let mut cells = vec![0u32; (side * side) as usize];
        let grid = mesh.start_grid(side, &mut cells).expect("grid fits");
        let mut hint = WalkHint::default();
        group.bench_function(BenchmarkId::new("fogtemp_grid_walk", &s.name), |b| {
            b.iter(|| {
                for q in black_box(&queries) {
                    black_box(
                        mesh.interpolate_with_grid(q.x, q.y, &mut hint, &grid).map_or(0.0, |v| v.value_dph),
                    );
                }
            })
        });
    }
    group.finish();
}
