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
    /// A least-squares fit failed (too few points, rank deficient).
    #[error("fit failed: {0}")]
    Fit(String),
    /// A model does not fit the blob format's limits.
    #[error("model cannot be encoded: {0}")]
    Encode(String),
    /// The encoded blob failed the core's own validation (a writer bug, reported rather than shipped).
    #[error("encoded model failed validation: {0}")]
    SelfCheck(fogtemp_core::Error),
    /// A model blob could not be read.
    #[error("{}: {source}", path.display())]
    Model {
        /// File.
        path: PathBuf,
        /// What the core said.
        source: fogtemp_core::Error,
    },
    /// A named column is not in the file's header.
    #[error("{}: no column named '{column}' (the header has: {available})", path.display())]
    MissingColumn {
        /// File.
        path: PathBuf,
        /// The missing column.
        column: String,
        /// Columns the header does have.
        available: String,
    },
    /// A row was rejected.
    #[error("{}:{}:{}: column '{}': {} (found '{}'); use --skip-bad-rows to skip such rows", path.display(), row.line, row.column, row.column_name, row.kind.describe(), row.found)]
    BadRow {
        /// File.
        path: PathBuf,
        /// Where and why.
        row: Box<crate::ingest::BadRow>,
    },
    /// The CSV reader failed (invalid UTF-8 in the header, I/O error mid-file).
    #[error("{}:{line}: {message}", path.display())]
    Csv {
        /// File.
        path: PathBuf,
        /// 1-based line, 0 if unknown.
        line: u64,
        /// The reader's message.
        message: String,
    },
    /// A simulation scenario is invalid (TOML syntax with line and column, or a named field).
    #[error("scenario: {0}")]
    Scenario(String),
    /// The inputs of a diagnosis (simulated vs recorded runs) are unusable: unpaired or
    /// duplicate names, empty or non-finite series, time not increasing, too few runs.
    #[error("diagnose: {0}")]
    Diagnose(String),
    /// Writing an output file failed (see [`crate::output`]).
    #[error("{action} {}: {source}", path.display())]
    Output {
        /// What failed ("writing", "syncing", "cannot move the output into place at", ...).
        action: &'static str,
        /// File or folder.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// I/O on a named file.
    #[error("{}: {source}", path.display())]
    Io {
        /// File.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
}
