//! # fogtemp-cal
//!
//! The calibration library of fogtemp (std): reads lab logs ([`ingest`]), computes the
//! firmware's own (T, dT/dt) features ([`features`]), thins them ([`thin`]), fits a
//! stepwise polynomial ([`poly_fit`]) and a Delaunay mesh on normalised axes ([`mesh`],
//! [`mesh_fit`]), writes the model blob that `fogtemp-core` reads ([`blob`]), and replays
//! logs through the core `Compensator` to measure raw vs compensated bias stability
//! ([`calibrate`], [`metrics`]). SVG and Markdown reports are behind the `report` feature.
//!
//! Fit a model and validate it, from Rust:
//!
//! ```
//! # fn main() -> Result<(), fogtemp_cal::CalError> {
//! use fogtemp_cal::calibrate::{self, CalibrationConfig, Method};
//! use fogtemp_cal::metrics::BiasStabilityOptions;
//! use std::path::Path;
//!
//! // Two 20-minute runs at 10 Hz whose bias is 0.5 deg/h per deg C above 20 C.
//! let log = |start_c: f64| {
//!     let mut csv = String::from("time_s,temp_c,gyro_dph\n");
//!     for k in 0..12_000 {
//!         let t = k as f64 / 10.0;
//!         let temp_c = start_c + 10.0 * (1.0 - (-t / 600.0).exp());
//!         csv.push_str(&format!("{t},{temp_c},{}\n", 0.5 * (temp_c - 20.0)));
//!     }
//!     csv
//! };
//! let config = CalibrationConfig { method: Method::Poly, ..CalibrationConfig::default() };
//! let (cold, warm) = (log(-10.0), log(30.0));
//! let runs = [
//!     calibrate::extract_run_from(cold.as_bytes(), Path::new("cold.csv"), &config)?,
//!     calibrate::extract_run_from(warm.as_bytes(), Path::new("warm.csv"), &config)?,
//! ];
//! let fitted = calibrate::fit_model(&runs, &config, [0; 32])?;
//! // The bias spans about 24 deg/h; the fit follows it within 0.5 % of that (what remains is the
//! // causal tracker's lag against the centred 100 s targets while the temperature curves).
//! assert!(fitted.axes[0].residual_rms_dph < 0.1, "{}", fitted.axes[0].residual_rms_dph);
//!
//! // Validate by replaying the runs through the firmware's own Compensator.
//! let model = fogtemp_core::Model::from_bytes(&fitted.blob).expect("the writer validates its blob");
//! let validation = calibrate::validate_readers(
//!     [("cold.csv", cold.as_bytes()), ("warm.csv", warm.as_bytes())],
//!     &model,
//!     &config.ingest,
//!     &BiasStabilityOptions::default(),
//! )?;
//! assert!(validation.compensated_bias_stability_dph < validation.raw_bias_stability_dph);
//! # Ok(())
//! # }
//! ```

pub mod allan_stream;
pub mod arrays;
pub mod axis_columns;
pub mod blob;
pub mod calibrate;
pub mod continued;
pub mod cv_correction;
pub mod digest;
pub mod documents;
pub mod envelope;
pub mod error;
pub mod features;
pub mod identifiability;
pub mod ingest;
pub mod manifest;
pub mod mesh;
pub mod mesh_fit;
pub mod metrics;
pub mod numbers;
pub mod outliers;
pub mod output;
pub mod poly_fit;
pub mod refine;
#[cfg(feature = "report")]
pub mod report;
pub mod runs;
pub mod selection;
pub mod spikes;
pub mod thin;
pub mod unit_names;

pub use blob::{encode, AxisModel, ColumnNames, LogReadingRecord, ModelFile};
pub use error::CalError;
pub use mesh::{build_mesh, MeshModel, MeshPoint};
