//! The fogtemp criterion harness: per-sample latency of the firmware runtime, with peers
//! measured in the same run on the same nodes and the same queries.
//!
//! One module per topic: `interp` (the walk against spade and a full scan), `poly`,
//! `runtime` (`Compensator::step`, `FeatureTracker::push`), `ingest` (log reading and
//! calibration features, bytes per second); `fixtures` builds the models
//! with the real writer. Every group reports ns per sample through
//! `Throughput::Elements` over a batch of queries. Results and the machine they were
//! measured on: `docs/performance.md`.
//!
//! Run: `cargo bench --bench fogtemp` (about 3.5 minutes after the build), or one group with a filter,
//! e.g. `cargo bench --bench fogtemp -- interp/coherent`.

use criterion::{criterion_group, criterion_main, Criterion};

#[path = "fogtemp/fixtures.rs"]
mod fixtures;
#[path = "fogtemp/ingest.rs"]
mod ingest;
#[path = "fogtemp/interp.rs"]
mod interp;
#[path = "fogtemp/poly.rs"]
mod poly;
#[path = "fogtemp/runtime.rs"]
mod runtime;

fn config() -> Criterion {
    Criterion::default().without_plots()
}

criterion_group! {
    name = benches;
    config = config();
    targets = interp::coherent, interp::random_order, interp::outside_hull, poly::evaluate, runtime::step, runtime::push,
        ingest::throughput
}
criterion_main!(benches);
