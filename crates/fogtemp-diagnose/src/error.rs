//! Errors of the diagnosis: which check fired, on which run and sample.

use std::path::PathBuf;

use fogtemp_cal::CalError;

/// Which member of a pair a series is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The simulation.
    Simulated,
    /// The recording.
    Recorded,
}

impl std::fmt::Display for Side {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Simulated => "simulated",
            Self::Recorded => "recorded",
        })
    }
}

/// Why a series cannot be diagnosed.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum SeriesProblem {
    /// No samples.
    Empty,
    /// `time_s`, `temp_c` and `gyro_dph` differ in length.
    UnequalLengths {
        /// Samples of time, temperature and gyro.
        lengths: [usize; 3],
    },
    /// A sample is NaN or infinite.
    NonFinite {
        /// Which series (`time_s`, `temp_c`, `gyro_dph`).
        what: &'static str,
        /// 0-based sample.
        sample: usize,
    },
    /// Time does not increase.
    TimeNotIncreasing {
        /// 0-based sample where it stops increasing.
        sample: usize,
        /// The time before it, s.
        before_s: f64,
        /// The time at it, s.
        at_s: f64,
    },
    /// Sampled slower than 1 Hz.
    TooSlow {
        /// Median sample interval, s.
        median_interval_s: f64,
    },
    /// Run metadata that is not finite.
    NonFiniteMeta {
        /// Which field (`input_rate_dph`, `power_on_at_s`).
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// Too few short means where both members and the smoothing windows are complete.
    TooShort {
        /// Short means found.
        means: usize,
        /// Their length, s.
        mean_window_s: usize,
    },
}

/// What can go wrong in a diagnosis. Every kind names the check that fired.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiagnoseError {
    /// A setting of [`crate::DiagnoseOptions`] is out of range.
    #[error("diagnose: {message}")]
    InvalidOption {
        /// The option (or options).
        option: &'static str,
        /// What the setting must be.
        message: String,
    },
    /// One side has no runs.
    #[error("diagnose: need simulated and recorded runs (got {simulated} simulated, {recorded} recorded)")]
    NoRuns {
        /// Simulated runs given.
        simulated: usize,
        /// Recorded runs given.
        recorded: usize,
    },
    /// Two runs on one side share a name.
    #[error("diagnose: two {side} runs are named '{name}'")]
    DuplicateRun {
        /// The side.
        side: Side,
        /// The name.
        name: String,
    },
    /// Runs without a partner of the same name.
    #[error(
        "diagnose: runs are paired by name; recorded without a simulated partner: [{}]; simulated without a recorded partner: [{}]",
        quoted(recorded_only),
        quoted(simulated_only)
    )]
    Unpaired {
        /// Recorded runs with no simulated partner.
        recorded_only: Vec<String>,
        /// Simulated runs with no recorded partner.
        simulated_only: Vec<String>,
    },
    /// A series is unusable.
    #[error("diagnose: {}", describe_series(*side, run, problem))]
    BadSeries {
        /// The side.
        side: Side,
        /// The run.
        run: String,
        /// What is wrong.
        problem: SeriesProblem,
    },
    /// A least-squares problem of the selection failed.
    #[error("fit failed: {0}")]
    Fit(&'static str),
    /// A log holds a header but no data rows.
    #[error("{}: no data rows (only a header)", path.display())]
    NoDataRows {
        /// The log.
        path: PathBuf,
    },
    /// Simulated and recorded logs whose file names have no partner.
    #[error("runs are paired by file name, and {} {} not:\n  {}", unmatched.len(), if unmatched.len() == 1 { "is" } else { "are" }, unmatched.join("\n  "))]
    UnpairedLogs {
        /// One line per log without a partner (`simulated a.csv has no recorded log of that name`).
        unmatched: Vec<String>,
    },
    /// The simulation's `manifest.json` is not valid JSON.
    #[error("{}: not valid JSON", path.display())]
    ManifestJson {
        /// The manifest.
        path: PathBuf,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// Reading, writing or a calibration-library step failed.
    #[error(transparent)]
    Cal(#[from] CalError),
    /// The simulation's `scenario.toml` could not be read or the updated one written.
    #[error(transparent)]
    Scenario(#[from] fogtemp_sim::SimError),
}

fn quoted(names: &[String]) -> String {
    names.iter().map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ")
}

fn describe_series(side: Side, run: &str, problem: &SeriesProblem) -> String {
    match problem {
        SeriesProblem::Empty => format!("{side} run '{run}' is empty"),
        SeriesProblem::UnequalLengths { lengths: [t, temp, gyro] } => format!(
            "{side} run '{run}': time_s, temp_c and gyro_dph have {t} / {temp} / {gyro} samples (must be equal)"
        ),
        SeriesProblem::NonFinite { what, sample } => format!("{side} run '{run}': {what} sample {sample} is not finite"),
        SeriesProblem::TimeNotIncreasing { sample, before_s, at_s } => {
            format!("{side} run '{run}': time_s does not increase at sample {sample} ({before_s} then {at_s})")
        }
        SeriesProblem::TooSlow { median_interval_s } => format!(
            "{side} run '{run}': median sample interval {median_interval_s} s; diagnose needs a sample rate >= 1 Hz"
        ),
        SeriesProblem::NonFiniteMeta { what, value } => format!("{side} run '{run}': {what} {value} is not finite"),
        SeriesProblem::TooShort { means, mean_window_s } => format!(
            "run '{run}': only {means} short means of {mean_window_s} s where both recorded and simulated data and the smoothing windows are complete (need >= 3): do the runs overlap in time? For a log with gaps or bursts, shorter means and lower coverage fit the data: --mean-window-s (a burst's length), --block-coverage, --rate-window-s (several bursts) and --window-coverage (Python: mean_window_s=, block_coverage=, rate_window_s=, window_coverage=)"
        ),
    }
}
