//! The JSON documents of `fogtemp-cal simulate` and `demo` (`--json`), as typed
//! [`Serialize`] values built from the simulator's own results.
//!
//! The key names are a contract (docs/architecture.md, Contracts): they never change. The command prints
//! each document through a `serde_json::Value` (keys sorted alphabetically, NaN or infinite
//! numbers as `null`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::demo::{
    DemoOptions, DemoResult, ModelResult, Timings, PAPER_MESH_DPH, PAPER_POLY_DPH, PAPER_RAW_DPH,
};
use crate::{RunSummary, Scenario};

/// `simulate --json`: what was simulated into a folder.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SimulateDocument {
    /// Scenario name.
    pub scenario: String,
    /// The folder, as displayed.
    pub out: String,
    /// Gyro sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Seed.
    pub seed: u64,
    /// Samples written over every run.
    pub samples: u64,
    /// Wall-clock time of the simulation, s.
    pub seconds: f64,
    /// Every run ([`crate::simulate_to_dir`]).
    pub runs: Vec<RunSummary>,
}

impl SimulateDocument {
    /// The document of `runs`, simulated from `scenario` into `out` in `seconds` (s).
    pub fn new(scenario: &Scenario, out: &Path, runs: &[RunSummary], seconds: f64) -> Self {
        Self {
            scenario: scenario.name.clone(),
            out: out.display().to_string(),
            sample_rate_hz: scenario.sample_rate_hz,
            seed: scenario.seed,
            samples: runs.iter().map(|r| r.samples).sum(),
            seconds,
            runs: runs.to_vec(),
        }
    }
}

/// `demo --json`: the paper's experiment end to end.
#[derive(Clone, Debug, Serialize)]
pub struct DemoDocument {
    /// Scenario name.
    pub scenario: String,
    /// Gyro sample rate simulated, Hz.
    pub sample_rate_hz: f64,
    /// Seed.
    pub seed: u64,
    /// Bias-stability definition used.
    pub definition: String,
    /// Raw validation bias stability, RMS over runs, deg/h.
    pub raw_dph: f64,
    /// The paper's Table 1.
    pub paper: PaperTable,
    /// Every model.
    pub models: Vec<ModelResult>,
    /// Wall-clock time per stage, s.
    pub seconds: Timings,
    /// The report written ([`demo_report_path`], as displayed), or `None` (null) without one.
    pub report: Option<String>,
    /// Each model's validation bias stability, RMS over runs, deg/h, under the key
    /// `<model key>_dph` (`poly_dph`, `mesh_dph`, ...), as keys of this object.
    #[serde(flatten)]
    pub compensated_dph: BTreeMap<String, f64>,
}

impl DemoDocument {
    /// The document of `result`, run into `out` with `options`.
    pub fn new(result: &DemoResult, out: &Path, options: &DemoOptions) -> Self {
        Self {
            scenario: result.scenario.clone(),
            sample_rate_hz: result.sample_rate_hz,
            seed: result.seed,
            definition: result.definition.clone(),
            raw_dph: result.raw_dph,
            paper: PaperTable::default(),
            models: result.models.clone(),
            seconds: result.seconds,
            report: (options.report && cfg!(feature = "report"))
                .then(|| demo_report_path(out).display().to_string()),
            compensated_dph: result
                .models
                .iter()
                .map(|m| (format!("{}_dph", m.key), m.compensated_dph))
                .collect(),
        }
    }
}

/// The report of a demo run into `out` (written when [`DemoOptions::report`] is set and the
/// crate has the `report` feature).
pub fn demo_report_path(out: &Path) -> PathBuf {
    out.join("report").join("report.md")
}

/// The paper's Table 1: validation bias stability, deg/h.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PaperTable {
    /// Raw, deg/h ([`PAPER_RAW_DPH`]).
    pub raw_dph: f64,
    /// Polynomial model, deg/h ([`PAPER_POLY_DPH`]).
    pub poly_dph: f64,
    /// 2-D interpolation model, deg/h ([`PAPER_MESH_DPH`]): the paper's thinned mesh, so
    /// named like the demo's `mesh_paper` model it is compared with, not like fogtemp's own
    /// `mesh` (review21 second report F6: `paper.mesh_dph` beside the top-level `mesh_dph`
    /// compared different models).
    pub mesh_paper_dph: f64,
}

impl Default for PaperTable {
    fn default() -> Self {
        Self { raw_dph: PAPER_RAW_DPH, poly_dph: PAPER_POLY_DPH, mesh_paper_dph: PAPER_MESH_DPH }
    }
}
