//! Errors of the simulator and the demo.

use fogtemp_cal::CalError;

/// What can go wrong while simulating or running the demo.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A scenario is invalid: TOML syntax (with line and column) or a field's value.
    #[error("scenario: {origin}: {message}")]
    Scenario {
        /// Where the scenario came from (a file name, or "paper").
        origin: String,
        /// 1-based line of a syntax error, if the parser gave one.
        line: Option<usize>,
        /// 1-based column of a syntax error, if the parser gave one.
        column: Option<usize>,
        /// What is wrong (the parser's message, or the field and its problem).
        message: String,
    },
    /// A document (scenario, manifest) could not be serialised.
    #[error("scenario: {what} could not be serialised: {message}")]
    Serialise {
        /// Which document.
        what: &'static str,
        /// The serialiser's message.
        message: String,
    },
    /// The demo's calibration or validation position has no runs in the scenario.
    #[error("scenario: no runs in position '{group}'")]
    NoRunsInPosition {
        /// The position (run group).
        group: String,
    },
    /// The scenario would write more CSV than a disk holds ([`crate::MAX_CSV_BYTES`]).
    #[error(
        "{runs} runs of {samples:.3e} samples in all at {rate_hz} Hz would write about {bytes:.1e} bytes of CSV, \
         more than a disk holds: lower the rate (--rate) or the duration (--duration-s)"
    )]
    TooLarge {
        /// Runs.
        runs: usize,
        /// Samples over all runs.
        samples: f64,
        /// The sample rate, Hz.
        rate_hz: f64,
        /// CSV bytes, about.
        bytes: f64,
    },
    /// The output folder holds a log of one of the runs but is not a simulation's folder (no
    /// `manifest.json`, no unfinished-simulation marker): it may be a lab's recording, which
    /// the simulated log would replace.
    #[error(
        "{} holds {run}.csv but is not a simulation's folder (no manifest.json, and no SIMULATION-UNFINISHED.txt \
         naming that run): simulating would replace it; choose another output folder (or, if it is a simulation's \
         whose run was interrupted by a version before 2026-11-29, delete its logs)",
        dir.display()
    )]
    NotASimulationFolder {
        /// The output folder.
        dir: std::path::PathBuf,
        /// The run whose log is there.
        run: String,
    },
    /// A run's logged temperature or gyro leaves what a log can hold: a scenario far outside
    /// the physics (a heater of 1e30 W, a sensor offset of 5000 C).
    #[error(
        "run '{run}' at {time_s} s would log {what}, beyond {limit}, so fit and validate would refuse its log; check \
         the scenario's thermal, sensor and bias parameters (docs/physics.md gives their ranges)"
    )]
    Unreadable {
        /// The run.
        run: String,
        /// The first such time on its 1 s grid, s.
        time_s: f64,
        /// What it would log there ("a temperature of 3.673e22 C").
        what: String,
        /// The range it leaves.
        limit: &'static str,
    },
    /// The output path is a file, or a link to nothing, not a folder.
    #[error("{} is {what}: a simulation is written into a folder (NAME.csv per run, truth/, manifest.json); give a folder", path.display())]
    OutputIsAFile {
        /// The path given.
        path: std::path::PathBuf,
        /// "a file", or "a link to X, which does not exist".
        what: String,
    },
    /// Writing, reading, fitting or validating failed (the calibration library's error).
    #[error(transparent)]
    Cal(#[from] CalError),
}
