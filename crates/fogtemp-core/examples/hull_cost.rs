//! Instruction counts of the value at the nearest hull point, for callgrind: the search
//! (`Mesh::nearest_hull_value`) against the scan of every hull edge
//! (`Mesh::nearest_hull_value_by_scan`) on the same queries outside the hull, and the whole
//! outside query as `Model.evaluate` in Python runs it (`Mesh::interpolate_with_grid` from a
//! start grid of about 4 cells per triangle: the walk to the hull, then the hull value from
//! the edge the walk crossed, `hull_value_after_walk`).
//!
//! ```sh
//! cargo build --release -p fogtemp-core --example hull_cost
//! valgrind --tool=callgrind --callgrind-out-file=cg.out target/release/examples/hull_cost MODEL.fogm
//! callgrind_annotate --inclusive=yes cg.out | grep cost_
//! ```
//!
//! The queries: uniform over the bounding box of axis 0's mesh grown by 30 % of its span on
//! every side (a fixed-seed generator), kept when outside the hull. Each `cost_*` wrapper is
//! called once per query; callgrind's inclusive Ir divided by the printed call count is the
//! cost per query.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
#![allow(missing_docs)]

mod common;

use std::hint::black_box;

use fogtemp_core::{Location, Mesh, Model, StartGrid, WalkHint};

#[inline(never)]
fn cost_search(mesh: &Mesh<'_>, x: f32, y: f32) -> f32 {
    mesh.nearest_hull_value(black_box(x), black_box(y))
}

#[inline(never)]
fn cost_scan(mesh: &Mesh<'_>, x: f32, y: f32) -> f32 {
    black_box(1_u8); // distinct body: LLVM would merge identical wrappers
    mesh.nearest_hull_value_by_scan(black_box(x), black_box(y))
}

#[inline(never)]
fn cost_grid_walk(mesh: &Mesh<'_>, grid: &StartGrid<'_>, hint: &mut WalkHint, x: f32, y: f32) -> f32 {
    mesh.interpolate_with_grid(black_box(x), black_box(y), hint, grid).map_or(f32::NAN, |v| v.value_dph)
}

fn main() {
    let path = std::env::args().nth(1).expect("usage: hull_cost MODEL.fogm [QUERIES]");
    let count: usize = std::env::args().nth(2).map_or(10_000, |s| s.parse().expect("a count"));
    let blob = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let model = Model::from_bytes(&blob).expect("a valid model");
    let mesh = model.axis(0).expect("axis 0").mesh.expect("a mesh on axis 0");
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for v in (0..mesh.vertex_count()).filter_map(|i| mesh.vertex(i)) {
        lo = [lo[0].min(v.x), lo[1].min(v.y)];
        hi = [hi[0].max(v.x), hi[1].max(v.y)];
    }
    let grow = [0.3 * (hi[0] - lo[0]), 0.3 * (hi[1] - lo[1])];
    let mut u = common::Uniform(0x9E37_79B9_7F4A_7C15);
    let mut queries = Vec::with_capacity(count);
    while queries.len() < count {
        let x = lo[0] - grow[0] + u.next() * (hi[0] - lo[0] + 2.0 * grow[0]);
        let y = lo[1] - grow[1] + u.next() * (hi[1] - lo[1] + 2.0 * grow[1]);
        if matches!(mesh.locate_by_scan(x, y), Location::Outside { .. }) {
            queries.push((x, y));
        }
    }
    let side = ((mesh.triangle_count() as f32 * 4.0).sqrt() as u32).max(1);
    let mut cells = vec![0u32; (side * side) as usize];
    let grid = mesh.start_grid(side, &mut cells).expect("grid");
    let mut hint = WalkHint::default();
    let (mut certified, mut differ, mut walk_differ) = (0usize, 0usize, 0usize);
    for &(x, y) in &queries {
        let (fast, scan) = (cost_search(&mesh, x, y), cost_scan(&mesh, x, y));
        let walked = cost_grid_walk(&mesh, &grid, &mut hint, x, y);
        differ += usize::from(fast.to_bits() != scan.to_bits());
        walk_differ += usize::from(walked.to_bits() != fast.to_bits());
        certified += usize::from(mesh.nearest_hull_edge(x, y).is_some());
    }
    println!("calls cost_search {count}");
    println!("calls cost_scan {count}");
    println!("calls cost_grid_walk {count} (start grid {side}x{side}; {walk_differ} values not bit-equal to the search)");
    println!(
        "hull edges {}, vertices {}, triangles {}; {certified} of {count} answered by the search, \
         {differ} not bit-equal to the scan",
        mesh.hull_edge_count(),
        mesh.vertex_count(),
        mesh.triangle_count()
    );
}
