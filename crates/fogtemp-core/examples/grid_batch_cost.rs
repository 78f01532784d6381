//! Instruction counts of a batch of random-order evaluations as `Model.evaluate` in Python runs
//! them, for callgrind: one pass of `Axis::evaluate_with_grid` over every point
//! (`cost_one_pass`) against the two passes per block of 1024 points of the Python package
//! (`cost_two_passes`: `Axis::evaluate_in_grid_cell` everywhere, then `evaluate_with_grid` on
//! the points the grid cell's triangle did not hold). Both from a start grid of about 4 cells
//! per triangle, as the Python package builds it.
//!
//! ```sh
//! cargo build --release -p fogtemp-core --example grid_batch_cost
//! valgrind --tool=callgrind --branch-sim=yes --callgrind-out-file=cg.out \
//!     target/release/examples/grid_batch_cost MODEL.fogm [POINTS]
//! callgrind_annotate --inclusive=yes cg.out | grep cost_
//! ```
//!
//! The points: uniform over axis 0's calibrated box (`provenance`, as the Python benchmark
//! draws them), from a fixed-seed generator; 1,000,000 unless given. The program checks that
//! both ways give the same bits at every point and prints how many points the first pass held.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
#![allow(missing_docs)]

mod common;

use std::hint::black_box;

use fogtemp_core::{Axis, Model, StartGrid, WalkHint};

/// Points per block of the two-pass evaluation (as `crates/fogtemp-py/src/model.rs`).
const BLOCK_POINTS: usize = 1024;

#[inline(never)]
fn cost_one_pass(axis: &Axis<'_>, grid: &StartGrid<'_>, points: &[(f32, f32)], out: &mut [f32]) {
    let mut hint = WalkHint::default();
    for (o, &(t, r)) in out.iter_mut().zip(points) {
        *o = axis.evaluate_with_grid(black_box(t), r, &mut hint, grid).map_or(f32::NAN, |e| e.value_dph);
    }
}

#[inline(never)]
fn cost_two_passes(axis: &Axis<'_>, grid: &StartGrid<'_>, points: &[(f32, f32)], out: &mut [f32]) -> usize {
    let mut hint = WalkHint::default();
    let mut pending = [0u16; BLOCK_POINTS];
    let mut held_total = 0;
    for (out, points) in out.chunks_mut(BLOCK_POINTS).zip(points.chunks(BLOCK_POINTS)) {
        let mut count = 0;
        for (k, (o, &(t, r))) in out.iter_mut().zip(points).enumerate() {
            let (evaluation, held) = axis.evaluate_in_grid_cell(black_box(t), r, grid);
            *o = evaluation.value_dph;
            pending[count] = k as u16;
            count += usize::from(!held);
        }
        held_total += points.len() - count;
        for &k in &pending[..count] {
            let (t, r) = points[usize::from(k)];
            out[usize::from(k)] =
                axis.evaluate_with_grid(t, r, &mut hint, grid).map_or(f32::NAN, |e| e.value_dph);
        }
    }
    held_total
}

fn main() {
    let path = std::env::args().nth(1).expect("usage: grid_batch_cost MODEL.fogm [POINTS]");
    let count: usize = std::env::args().nth(2).map_or(1_000_000, |s| s.parse().expect("a count"));
    let blob = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let model = Model::from_bytes(&blob).expect("a valid model");
    let axis = model.axis(0).expect("axis 0");
    let mesh = axis.mesh.expect("a mesh on axis 0");
    let p = axis.provenance;
    let mut u = common::Uniform(0x9E37_79B9_7F4A_7C15);
    let points: Vec<(f32, f32)> = (0..count)
        .map(|_| {
            let t = p.temp_min_c + u.next() * (p.temp_max_c - p.temp_min_c);
            (t, p.rate_min_c_per_min + u.next() * (p.rate_max_c_per_min - p.rate_min_c_per_min))
        })
        .collect();
    let side = ((mesh.triangle_count() as f32 * 4.0).sqrt() as u32).max(1);
    let mut cells = vec![0u32; (side * side) as usize];
    let grid = mesh.start_grid(side, &mut cells).expect("grid");
    let (mut one, mut two) = (vec![0.0f32; count], vec![0.0f32; count]);
    cost_one_pass(&axis, &grid, &points, &mut one);
    let held = cost_two_passes(&axis, &grid, &points, &mut two);
    let differ = one.iter().zip(&two).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
    println!("calls cost_one_pass 1, cost_two_passes 1, {count} points each (start grid {side}x{side})");
    println!("{held} of {count} held by their grid cell's triangle; {differ} values not bit-equal");
}
