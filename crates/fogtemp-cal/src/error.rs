//! Errors of the calibration library.

use std::path::PathBuf;

/// Everything that can go wrong while calibrating, with the place it went wrong.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalError {
    /// The point set cannot be triangulated (fewer than 3 distinct points, or all collinear).
    #[error("cannot build a mesh: {reason} ({points} distinct points)")]
    DegenerateMesh {
        /// Why.
        reason: &'static str,
        /// Distinct points offered.
        points: usize,
    },
    /// A number that must be finite is not.
    #[error("{what} is not a finite number (item {index})")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// Which item.
        index: usize,
    },
    /// A model does not fit the blob format's limits.
    #[error("model cannot be encoded: {0}")]
    Encode(String),
    /// The encoded blob failed the core's own validation (a writer bug, reported rather than shipped).
    #[error("encoded model failed validation: {0}")]
    SelfCheck(fogtemp_core::Error),
    /// A model blob could not be read.
    #[error("{path}: {source}")]
    Model {
        /// File.
        path: PathBuf,
        /// What the core said.
        source: fogtemp_core::Error,
    },
    /// I/O on a named file.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}
