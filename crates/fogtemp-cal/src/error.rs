//! Errors of the calibration library.

use std::path::{Path, PathBuf};

/// Everything that can go wrong while calibrating, with the place it went wrong.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalError {
    /// The point set cannot be triangulated (fewer than 3 distinct points, or all collinear).
    #[error(
        "cannot build a mesh: {reason} ({points} distinct point{}): a mesh needs calibration runs whose \
         temperatures and rates vary (a temperature that never changes, a stuck sensor or the wrong column, gives \
         one point); calibrate at several temperatures, or fit --method poly",
        if *points == 1 { "" } else { "s" }
    )]
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
    Fit(FitProblem),
    /// A cubic in T alone on fewer distinct temperatures than its terms (review27a 4: a
    /// constant temperature said "design matrix is rank deficient").
    #[error(
        "a cubic in T needs at least {needed} distinct temperatures; the calibration points hold {distinct} \
         ({temperatures}): calibrate at more temperatures, or fit --method poly"
    )]
    TooFewTemperatures {
        /// Distinct temperatures among the calibration points.
        distinct: usize,
        /// Terms of the cubic.
        needed: usize,
        /// The temperatures, or their range, as text.
        temperatures: String,
    },
    /// No axis point ever had features: the tracker never had `min_blocks` blocks of
    /// temperature data without a gap longer than `max_gap_s` (the temperature column, the
    /// window or the gap limit do not suit the log's temperature sampling).
    #[error(
        "fit failed: axis {axis}: no calibration points: the feature tracker never had {min_blocks} blocks of \
         temperature data without a gap longer than {max_gap_s} s"
    )]
    NoCalibrationPoints {
        /// Gyro axis.
        axis: usize,
        /// Blocks the tracker needs before its first features.
        min_blocks: u32,
        /// The longest silence the tracker bridges, seconds.
        max_gap_s: f32,
    },
    /// `Method::Auto` given where there are no runs to cross-validate.
    #[error(
        "method auto chooses by replaying held-out runs: fit it with fit_model over the runs, not fit_axis"
    )]
    AutoNeedsRuns,
    /// A model does not fit the blob format's limits.
    #[error("model cannot be encoded: {0}")]
    Encode(EncodeProblem),
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
    #[error("{}: no column named '{column}' (the header has: {available}){}{also}", path.display(), similar_note(similar))]
    MissingColumn {
        /// File (boxed, as `also`: the error stays small enough to return by value).
        path: Box<Path>,
        /// The missing column.
        column: String,
        /// What it was to hold: `time`, `date`, `temperature` or `gyro`.
        role: &'static str,
        /// Columns the header does have.
        available: Box<str>,
        /// Header names that look like the missing one (case, units or punctuation aside).
        similar: Vec<String>,
        /// The other named columns the header lacks, with theirs (`; also missing: 'b'
        /// (perhaps 'B')`), or empty: every one is said at once (review32a F15: a log with
        /// upper-case names took three runs of the command).
        also: Box<str>,
    },
    /// A row was rejected.
    #[error("{}:{}:{}: column '{}': {} (found '{}')", path.display(), row.line, row.column, row.column_name, row.kind.describe(), row.found)]
    BadRow {
        /// File.
        path: PathBuf,
        /// Where and why.
        row: Box<crate::ingest::BadRow>,
    },
    /// The log's shape settings are contradictory, or the log does not fit them (a time
    /// column and a sample rate both, a header that looks like data, a bad comment prefix).
    #[error("{}{}: {problem}", path.display(), at_line(*line))]
    LogFormat {
        /// File.
        path: PathBuf,
        /// 1-based line, 0 when the problem is not on one line.
        line: u64,
        /// What is wrong.
        problem: String,
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
    /// A run-metadata file (`--runs`) is malformed or does not match the logs.
    #[error("{}{}: {problem}", path.display(), line_suffix(*line))]
    Runs {
        /// The runs file.
        path: PathBuf,
        /// 1-based line (0 when the problem is not on one line).
        line: u64,
        /// What is wrong.
        problem: crate::runs::RunsProblem,
    },
    /// A simulation's `manifest.json` is not valid JSON (see [`crate::manifest`]).
    #[error("{}: not valid JSON: {source}", path.display())]
    ManifestJson {
        /// The manifest.
        path: PathBuf,
        /// The parser's error.
        source: serde_json::Error,
    },
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
    /// The caller stopped the work (a replay callback returned it, e.g. Python's Ctrl-C during
    /// a fit's cross-validation).
    #[error("interrupted")]
    Interrupted,
}

/// `; perhaps 'a' or 'b'` for header names close to a missing column's, nothing without any.
pub(crate) fn similar_note(similar: &[String]) -> String {
    match similar {
        [] => String::new(),
        names => {
            let quoted: Vec<String> = names.iter().map(|n| format!("'{n}'")).collect();
            // A Latin-1 header ('°C') reads with replacement characters nobody can type.
            let not_utf8 = if names.iter().any(|n| n.contains('\u{FFFD}')) {
                " (the header is not UTF-8, so a character reads as '\u{FFFD}': skip the header line \
                 and name the columns yourself)"
            } else {
                ""
            };
            format!("; perhaps {}{not_utf8}", quoted.join(" or "))
        }
    }
}

/// `:line` for a known line, nothing for 0.
fn at_line(line: u64) -> String {
    if line == 0 {
        String::new()
    } else {
        format!(":{line}")
    }
}

/// Why a least-squares fit failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FitProblem {
    /// Fewer points than terms.
    #[error("{points} points cannot fit {terms} terms")]
    TooFewPoints {
        /// Points offered.
        points: usize,
        /// Terms to fit.
        terms: usize,
    },
    /// Two or more terms cannot be told apart on these points.
    #[error("design matrix is rank deficient (terms not separable on these points)")]
    RankDeficient,
    /// The triangular factor could not be inverted.
    #[error("singular R")]
    Singular,
    /// A test distribution could not be set up (degrees of freedom out of range).
    #[error("{0}")]
    Distribution(String),
}

/// Why a model cannot be encoded in the blob format.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EncodeProblem {
    /// Axis count outside what the format allows.
    #[error("{axes} axes (allowed 1..={max})")]
    AxisCount {
        /// Axes offered.
        axes: usize,
        /// The format's limit.
        max: usize,
    },
    /// A count or a size does not fit the format's fields.
    #[error("{what}: {count}")]
    TooLarge {
        /// Which count ("blob bytes", "vertices", ...).
        what: &'static str,
        /// The count.
        count: usize,
    },
    /// The mesh's neighbour list does not match its triangle list.
    #[error("neighbour list length differs from triangle list")]
    NeighbourMismatch,
    /// A triangle refers to a vertex that does not exist, or has zero area.
    #[error("triangle {triangle} has a vertex index out of range or zero area")]
    BadTriangle {
        /// Triangle index.
        triangle: usize,
    },
    /// A hull entry names a triangle or vertex that does not exist, so its gradient cannot be
    /// computed.
    #[error("no gradient at the start of hull edge {hull_edge}: its triangle or vertex does not exist")]
    NoHullGradient {
        /// Hull edge index.
        hull_edge: usize,
    },
    /// Column names were given, but not one per axis.
    #[error("{names} column-name pairs for {axes} axes (one per axis, or none)")]
    ColumnNameCount {
        /// Pairs given.
        names: usize,
        /// Axes in the model.
        axes: usize,
    },
    /// The feature tracker settings are outside what the core accepts.
    #[error("feature settings: {0}")]
    FeatureSettings(fogtemp_core::Error),
}

/// `:line` after a file name, or nothing for line 0 (a problem not on one line).
fn line_suffix(line: u64) -> String {
    if line == 0 {
        String::new()
    } else {
        format!(":{line}")
    }
}

#[cfg(test)]
mod similar_name_tests {
    use super::similar_note;

    /// A suggested name with a replacement character (a Latin-1 header) says why and what to do.
    #[test]
    fn a_header_that_is_not_utf8_is_named_as_such() {
        assert_eq!(similar_note(&[]), "");
        assert_eq!(similar_note(&["Temp_C".into()]), "; perhaps 'Temp_C'");
        let note = similar_note(&["temp_\u{FFFD}C".into()]);
        assert!(note.starts_with("; perhaps 'temp_\u{FFFD}C' (the header is not UTF-8"), "{note}");
        assert!(note.contains("name the columns yourself"), "{note}");
    }
}
