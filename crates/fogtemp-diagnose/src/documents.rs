//! JSON documents built on a [`Diagnosis`], shared by the CLI (`diagnose --json`) and other
//! front ends so that every one of them prints the same keys.

use serde::Serialize;

use crate::Diagnosis;

/// `diagnose --json`: the diagnosis with what the command adds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DiagnoseDocument<'a> {
    /// The diagnosis, as keys of this object.
    #[serde(flatten)]
    pub diagnosis: &'a Diagnosis,
    /// Wall-clock time of the diagnosis, s.
    pub seconds: f64,
    /// `scenario-updated.toml` written beside the report, as displayed, or `None` (null).
    pub updated_scenario: Option<String>,
    /// The changes made to the scenario (empty without one).
    pub scenario_changes: Vec<String>,
}
