//! # fogtemp-cal
//!
//! The calibration library of fogtemp (std): builds the Delaunay mesh with `spade` on
//! normalised axes, writes the model blob that `fogtemp-core` reads, and (as it grows)
//! ingests lab logs, fits polynomial and mesh models and computes metrics.

pub mod blob;
pub mod calibrate;
pub mod demo;
pub mod diagnose;
pub mod error;
pub mod features;
pub mod ingest;
pub mod mesh;
pub mod mesh_fit;
pub mod metrics;
pub mod output;
pub mod poly_fit;
pub mod report;
pub mod sim;
pub mod thin;

pub use blob::{encode, AxisModel, ModelFile};
pub use error::CalError;
pub use mesh::{build_mesh, MeshModel, MeshPoint};
