//! # fogtemp-core
//!
//! The firmware runtime of fogtemp: compensates the temperature drift of a fibre-optic
//! gyro one sample at a time, from a calibration model stored as a binary blob.
//!
//! - `#![no_std]`, no allocation, no `unsafe`, no panics: every fallible step returns
//!   [`Error`], a small `Copy` enum that says what and where.
//! - [`Model::from_bytes`] validates a blob borrowed from flash (layout in
//!   `docs/model-format.md`, constants in [`wire`]).
//! - [`Mesh`] locates the triangle by a bounded visibility walk from a caller-owned
//!   [`WalkHint`] and interpolates linearly (barycentric); [`Poly`] evaluates polynomial terms.
//! - [`FeatureTracker`] turns raw temperature samples into smoothed T and dT/dt (deg C/min);
//!   calibration uses the same code.
//! - [`Axis::step`] compensates one sample with a caller-owned [`AxisState`]
//!   (configuration apart from state); [`Compensator`] bundles the axis and its state:
//!   `step(time_us, gyro_dph, temp_c)` per sample, `step_u32` for a wrapping 32-bit timer.
//! - [`Model::from_flash`] reads a blob followed by erased flash; [`Axis::blocks_needed`]
//!   is the tracker capacity an axis needs.
//!
//! All arithmetic is f32 (Cortex-M4F has a single-precision FPU only).
//!
//! ```
//! # fn demo(blob: &[u8]) -> Result<(), fogtemp_core::Error> {
//! use fogtemp_core::{Compensator, Model};
//! let model = Model::from_bytes(blob)?; // e.g. include_bytes!("model.fogm")
//! let mut x_axis: Compensator = Compensator::new(&model, 0)?;
//! let out = x_axis.step(1_000, 12.5, Some(24.8)); // time us, gyro deg/h, temp deg C
//! let _compensated_dph = out.rate_dph;
//! # Ok(()) }
//! ```
#![no_std]
#![forbid(unsafe_code)]

mod beyond;
mod compensator;
pub mod crc;
mod error;
mod features;
mod hull;
mod mesh;
mod model;
mod names;
mod poly;
mod region;
pub mod wire;

pub use beyond::GRADIENT_RADIUS;
pub use compensator::{
    is_physical_temperature, AxisState, Compensator, Flags, Output, WrappingClock, DEFAULT_CAPACITY,
    MAX_PHYSICAL_TEMP_C, MIN_PHYSICAL_TEMP_C,
};
pub use error::Error;
pub use features::{BlockStorage, BlockTracker, FeatureTracker, Features, PushOutcome};
pub use mesh::{
    Location, Mesh, MeshValue, OutsidePolicy, StartGrid, TriangleRecord, Vertex, WalkHint, INSIDE_EPS,
};
pub use model::{
    Axis, AxisProvenance, Evaluation, FeatureSettings, Model, Normalisation, MAX_NORMALISED_COORD,
};
pub use names::{AxisColumns, InputRates, LogDelimiter, LogReading, LogShape, LogTime, LogTimeUnit};
pub use poly::{Poly, PolyTerm};
pub use region::{PolyOutside, Region};
