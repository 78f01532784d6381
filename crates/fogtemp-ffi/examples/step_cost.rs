//! Instruction counts of `fogtemp_step` (the C ABI over `Axis::step`), for callgrind:
//! `docs/c-api.md` has the commands and the results.
//!
//! ```sh
//! cargo build --release -p fogtemp-ffi --example step_cost
//! step_cost write-large-mesh /tmp/large10k.fogm           # the benches' 10,000-node mesh
//! valgrind --tool=callgrind --callgrind-out-file=cg.out step_cost measure MODEL.fogm
//! callgrind_annotate --inclusive=yes cg.out | grep cost_
//! ```
//!
//! `measure` prints how many times each `cost_*` wrapper was called; callgrind gives each
//! wrapper's inclusive instruction count (Ir); Ir / calls is the cost per call:
//!
//! - `cost_step_plain`: a 1 kHz sample with a temperature that closes no block;
//! - `cost_step_close`: a sample that closes a block in steady state (feature fit over the
//!   window, one model evaluation walking from the last triangle);
//! - `cost_step_gyro_only`: a sample without a temperature;
//! - `cost_step_worst`: a block close constructed to be expensive: the walk hint parked at
//!   the vertex farthest from the query, the query beyond the hull on the other side (walk
//!   across the mesh, then the nearest-hull scan over every hull edge);
//! - `cost_scan`: the fallback full scan (`Mesh::locate_by_scan`, every triangle) that runs
//!   only when a walk does not settle within T steps (never on a Delaunay mesh);
//! - `cost_hull`: the nearest-hull-point scan alone;
//! - `cost_walk_far`: `Mesh::locate` from the farthest triangle (the harness also counts the
//!   steps of that walk, to give the cost per walk step).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
#![allow(clippy::undocumented_unsafe_blocks, clippy::arithmetic_side_effects, missing_docs)]

use std::hint::black_box;

use fogtemp_cal::{build_mesh, encode, AxisModel, MeshPoint, ModelFile};
use fogtemp_core::{
    AxisProvenance, Compensator, FeatureSettings, Location, Mesh, Model, Normalisation, OutsidePolicy,
    WalkHint,
};
use fogtemp_ffi::*;
use rand::{Rng, SeedableRng};

/// The benches' settings (benches/fogtemp/fixtures.rs): 100 s window of 100 blocks.
const FEATURES: FeatureSettings =
    FeatureSettings { window_s: 100.0, block_count: 100, min_blocks: 10, max_gap_s: 5.0 };
const NORMALISATION: Normalisation = Normalisation {
    temp_offset_c: 20.0,
    temp_scale_per_c: 1.0 / 60.0,
    rate_offset_c_per_min: 0.5,
    rate_scale_per_c_per_min: 2.0,
};

fn bias_surface(temp_c: f64, rate_c_per_min: f64) -> f64 {
    0.002 * temp_c
        + 1.5e-5 * temp_c * temp_c
        + 0.06 * rate_c_per_min
        + 0.01 * (temp_c / 15.0).sin() * rate_c_per_min
}

/// `benches/fogtemp/fixtures.rs::random_points(10_000, 7)` through the real writer.
fn large_mesh_blob() -> Vec<u8> {
    let mut r = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
    let points: Vec<MeshPoint> = (0..10_000)
        .map(|_| {
            let temp_c = r.gen_range(-40.0..80.0);
            let rate_c_per_min = r.gen_range(0.0..1.0);
            MeshPoint { temp_c, rate_c_per_min, value_dph: bias_surface(temp_c, rate_c_per_min) }
        })
        .collect();
    let axis = AxisModel {
        features: FEATURES,
        normalisation: NORMALISATION,
        outside_policy: OutsidePolicy::NearestHull,
        poly: Vec::new(),
        mesh: Some(build_mesh(&points, &NORMALISATION).expect("mesh builds")),
        provenance: AxisProvenance {
            fit_point_count: 0,
            residual_rms_dph: 0.0,
            residual_max_abs_dph: 0.0,
            temp_min_c: -40.0,
            temp_max_c: 80.0,
            rate_min_c_per_min: 0.0,
            rate_max_c_per_min: 1.0,
        },
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
    };
    let file = ModelFile {
        tool_version: "step_cost".into(),
        input_digest: [0; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    };
    encode(&file).expect("encodes")
}

#[inline(never)]
fn cost_step_plain(a: &fogtemp_axis, s: &mut fogtemp_state, t: u64, g: f32, c: f32, o: &mut fogtemp_output) {
    black_box(1_u8); // distinct body: LLVM would merge identical wrappers
    unsafe { fogtemp_step(a, s, t, g, c, true, o) };
}
#[inline(never)]
fn cost_step_close(a: &fogtemp_axis, s: &mut fogtemp_state, t: u64, g: f32, c: f32, o: &mut fogtemp_output) {
    black_box(2_u8); // distinct body: LLVM would merge identical wrappers
    unsafe { fogtemp_step(a, s, t, g, c, true, o) };
}
#[inline(never)]
fn cost_step_gyro_only(a: &fogtemp_axis, s: &mut fogtemp_state, t: u64, g: f32, o: &mut fogtemp_output) {
    unsafe { fogtemp_step(a, s, t, g, 0.0, false, o) };
}
#[inline(never)]
fn cost_step_worst(a: &fogtemp_axis, s: &mut fogtemp_state, t: u64, g: f32, c: f32, o: &mut fogtemp_output) {
    black_box(3_u8); // distinct body: LLVM would merge identical wrappers
    unsafe { fogtemp_step(a, s, t, g, c, true, o) };
}
#[inline(never)]
fn cost_scan(mesh: &Mesh<'_>, x: f32, y: f32) -> Location {
    mesh.locate_by_scan(black_box(x), black_box(y))
}
#[inline(never)]
fn cost_hull(mesh: &Mesh<'_>, x: f32, y: f32) -> f32 {
    mesh.nearest_hull_value(black_box(x), black_box(y))
}
#[inline(never)]
fn cost_walk_far(mesh: &Mesh<'_>, x: f32, y: f32, hint: &mut WalkHint) -> Location {
    mesh.locate(black_box(x), black_box(y), hint).unwrap()
}
#[inline(never)]
fn warm(a: &fogtemp_axis, s: &mut fogtemp_state, t: u64, g: f32, c: f32, o: &mut fogtemp_output) {
    black_box(4_u8); // distinct body: LLVM would merge identical wrappers
    unsafe { fogtemp_step(a, s, t, g, c, true, o) };
}

/// Steps of the visibility walk from `start` (the core's rule: cross the edge of the most
/// negative barycentric coordinate; stop inside, on a hull edge, or on a step straight back).
fn walk_steps(mesh: &Mesh<'_>, start: u32, x: f32, y: f32) -> u32 {
    let (mut t, mut previous, mut steps) = (start, u32::MAX, 1);
    loop {
        let r = mesh.triangle(t).unwrap();
        let (dx, dy) = (x - r.origin[0], y - r.origin[1]);
        let l0 = r.bary[0] * dx + r.bary[1] * dy;
        let l1 = r.bary[2] * dx + r.bary[3] * dy;
        let l = [l0, l1, 1.0 - l0 - l1];
        let mut k = 0;
        for j in 1..3 {
            if l[j] < l[k] {
                k = j;
            }
        }
        let next = r.neighbours[k];
        if l[k] >= -fogtemp_core::INSIDE_EPS || next == u32::MAX || next == previous {
            return steps;
        }
        (previous, t, steps) = (t, next, steps + 1);
    }
}

fn measure(blob: &'static [u8]) {
    let model_rs = Model::from_bytes(blob).expect("valid model");
    let axis_rs = model_rs.axis(0).unwrap();
    let mut model = fogtemp_model { opaque: [0; 4] };
    let mut axis = fogtemp_axis { opaque: [0; 24] };
    let mut state = fogtemp_state { opaque: [0; 28] };
    let mut blocks = vec![0.0f32; axis_rs.blocks_needed()];
    let mut err = std::mem::MaybeUninit::<fogtemp_error>::zeroed();
    unsafe {
        assert_eq!(
            fogtemp_model_from_bytes(blob.as_ptr(), blob.len(), &mut model, err.as_mut_ptr()),
            fogtemp_status::Ok
        );
        assert_eq!(fogtemp_model_axis(&model, 0, &mut axis, err.as_mut_ptr()), fogtemp_status::Ok);
        let s = fogtemp_state_init(&axis, &mut state, blocks.as_mut_ptr(), blocks.len(), err.as_mut_ptr());
        assert_eq!(s, fogtemp_status::Ok);
    }
    // A shadow Compensator (not measured) says which sample closes a block.
    let mut shadow: Compensator<'_, 4096> = Compensator::new(&model_rs, 0).unwrap();
    let p = axis_rs.provenance;
    let (t_lo, t_hi) = (p.temp_min_c, p.temp_max_c);
    // A 1 kHz stream, temperature every sample: 120 s unmeasured, then 600 s measured,
    // along a straight ramp through a calibration node (the node of median temperature;
    // with no mesh, the middle of the calibrated box), so the features stay near the data.
    let (node_c, node_rate) = axis_rs
        .mesh
        .and_then(|m| {
            let mut v: Vec<_> = (0..m.vertex_count()).filter_map(|i| m.vertex(i)).collect();
            v.sort_by(|a, b| a.x.total_cmp(&b.x));
            let mid = v.get(v.len() / 2)?;
            let n = &axis_rs.normalisation;
            Some((
                mid.x / n.temp_scale_per_c + n.temp_offset_c,
                mid.y / n.rate_scale_per_c_per_min + n.rate_offset_c_per_min,
            ))
        })
        .unwrap_or(((t_lo + t_hi) / 2.0, (p.rate_min_c_per_min + p.rate_max_c_per_min) / 2.0));
    let rate_c_per_s = node_rate / 60.0;
    let start_c = node_c - rate_c_per_s * 420.0; // at the node 420 s in (the measured middle)
    println!("ramp through ({node_c:.2} C, {node_rate:.4} C/min)");
    let (mut plain, mut close, mut gyro_only) = (0u64, 0u64, 0u64);
    let mut outside = 0u64;
    let mut o = fogtemp_output::default();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
    let mut t_us = 1_000u64;
    for k in 0..720_000u64 {
        t_us += 1_000;
        let temp = start_c + rate_c_per_s * (k as f32 / 1000.0) + rng.gen_range(-0.03f32..0.03);
        let gyro = 10.0 + rng.gen_range(-0.5f32..0.5);
        let before = shadow.tracker().features().map(|f| f.time_us);
        shadow.step(t_us, gyro, Some(temp));
        let closed = shadow.tracker().features().map(|f| f.time_us) != before;
        if k < 120_000 {
            warm(&axis, &mut state, t_us, gyro, temp, &mut o);
        } else if closed {
            cost_step_close(&axis, &mut state, t_us, gyro, temp, &mut o);
            close += 1;
            outside += u64::from(o.flags & FOGTEMP_FLAG_OUTSIDE_HULL != 0);
        } else {
            cost_step_plain(&axis, &mut state, t_us, gyro, temp, &mut o);
            plain += 1;
        }
    }
    for _ in 0..10_000 {
        t_us += 1_000;
        cost_step_gyro_only(&axis, &mut state, t_us, 10.0, &mut o);
        gyro_only += 1;
    }
    println!("calls cost_step_plain {plain}");
    println!("calls cost_step_close {close} (outside hull: {outside})");
    println!("calls cost_step_gyro_only {gyro_only}");

    // Worst case at a block close: features beyond the hull on the hot, fast side; the hint
    // parked at the cold end. A fresh state warmed on a steep ramp (unmeasured).
    let mut worst_state = fogtemp_state { opaque: [0; 28] };
    let mut worst_blocks = vec![0.0f32; axis_rs.blocks_needed()];
    unsafe {
        fogtemp_state_init(
            &axis,
            &mut worst_state,
            worst_blocks.as_mut_ptr(),
            worst_blocks.len(),
            err.as_mut_ptr(),
        );
    }
    let mut shadow: Compensator<'_, 4096> = Compensator::new(&model_rs, 0).unwrap();
    let fast_c_per_s = (p.rate_max_c_per_min.abs() * 3.0 + 1.0) / 60.0;
    let window_ms = (axis_rs.features.window_s * 1000.0) as u64 + 2_000;
    let mut t_us = 1_000u64;
    let mut closes_to_go = None;
    let mut worst_calls = 0u64;
    for k in 0..window_ms * 3 {
        t_us += 1_000;
        let temp = t_hi - 10.0 + fast_c_per_s * (k as f32 / 1000.0);
        let before = shadow.tracker().features().map(|f| f.time_us);
        // Just before the block close we measure: park the hint at the cold end.
        shadow.step(t_us, 10.0, Some(temp));
        let closed = shadow.tracker().features().map(|f| f.time_us) != before;
        if closed && k > window_ms {
            let (mut bias, mut out_hull) = (0.0f32, false);
            unsafe {
                fogtemp_evaluate(
                    &axis,
                    &mut worst_state,
                    t_lo,
                    p.rate_min_c_per_min,
                    &mut bias,
                    &mut out_hull,
                )
            };
            cost_step_worst(&axis, &mut worst_state, t_us, 10.0, temp, &mut o);
            worst_calls += 1;
            closes_to_go = Some(o.flags);
            if worst_calls == 10 {
                break;
            }
        } else {
            warm(&axis, &mut worst_state, t_us, 10.0, temp, &mut o);
        }
    }
    println!("calls cost_step_worst {worst_calls} (flags {:#04x})", closes_to_go.unwrap_or(0));

    if let Some(mesh) = axis_rs.mesh {
        // Farthest pair: the query at the hot, fast corner, the walk from the triangle holding
        // the cold, slow corner.
        let (qx, qy) = axis_rs.normalisation.apply(t_hi, p.rate_max_c_per_min);
        let (cx, cy) = axis_rs.normalisation.apply(t_lo, p.rate_min_c_per_min);
        let mut far = WalkHint::default();
        mesh.locate(cx, cy, &mut far).unwrap();
        let steps = walk_steps(&mesh, far.0, qx, qy);
        for _ in 0..10 {
            let mut hint = far;
            black_box(cost_walk_far(&mesh, qx, qy, &mut hint));
            black_box(cost_scan(&mesh, qx, qy));
            black_box(cost_hull(&mesh, qx + 10.0, qy + 10.0));
        }
        println!("calls cost_walk_far 10 (walk steps {steps})");
        println!("calls cost_scan 10 (triangles {})", mesh.triangle_count());
        println!("calls cost_hull 10 (hull edges {})", mesh.hull_edge_count());
    }
    println!(
        "model blocks {} vertices {} triangles {}",
        axis_rs.blocks_needed(),
        axis_rs.mesh.map_or(0, |m| m.vertex_count()),
        axis_rs.mesh.map_or(0, |m| m.triangle_count())
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    match args.get(1).map(String::as_str) {
        Some("write-large-mesh") => {
            let out = args.get(2).expect("output path");
            std::fs::write(out, large_mesh_blob()).expect("write");
        }
        Some("measure") => {
            let path = args.get(2).expect("model path");
            let blob: &'static [u8] = Vec::leak(std::fs::read(path).expect("read model"));
            measure(blob);
        }
        _ => eprintln!("usage: step_cost write-large-mesh OUT | step_cost measure MODEL.fogm"),
    }
}
