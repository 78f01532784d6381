//! A fogtemp simulation's `manifest.json` as run metadata. DESIGN.md §3: a runs file is "used
//! by `diagnose`, `fit` and `validate`; a fogtemp simulation's `manifest.json` gives the same
//! when no file is given". Each run's position is the manifest's `group`, its true input rate
//! the manifest's `input_rate_dph`. `simulate` writes the manifest beside the logs.
//!
//! `fit` and `validate` use it only when it describes every log they were given, all from its
//! own folder: a log it does not list (a recording copied into the simulation's folder), or
//! logs from several folders, and it is not used, with a note saying why
//! ([`ManifestForLogs::NotUsed`]). Before 2026-11-29 only `diagnose` read it (review27b F1).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use crate::error::CalError;
use crate::runs::{run_name, RunMetadata, RunsFile, MAX_INPUT_RATE_DPH};

/// The manifest's file name, in the simulation's folder.
pub const MANIFEST_FILE: &str = "manifest.json";

/// One run of a manifest: what run metadata needs of it.
#[derive(Clone, Debug, PartialEq)]
pub struct ManifestRun {
    /// The run's name: its log's file name without `.csv`.
    pub name: String,
    /// Its position (the manifest's `group`), when given and not empty.
    pub group: Option<String>,
    /// The true rate about the input axis, deg/h, when given.
    pub input_rate_dph: Option<f64>,
}

/// The runs of `DIR/manifest.json`, in its order; `None` when the folder has no manifest.
/// Entries without a `name` are passed over. Numbers are read back exactly as written
/// (serde_json's `float_roundtrip`: its default parser was 1 ulp off on the Earth rate, so a
/// runs file written from the manifest by Python gave other bits).
///
/// # Errors
/// [`CalError::Io`] when the manifest cannot be read; [`CalError::ManifestJson`] when it is
/// not valid JSON.
pub fn read_manifest(dir: &Path) -> Result<Option<Vec<ManifestRun>>, CalError> {
    let path = dir.join(MANIFEST_FILE);
    if !path.is_file() {
        return Ok(None);
    }
    let text =
        std::fs::read_to_string(&path).map_err(|source| CalError::Io { path: path.clone(), source })?;
    let doc: serde_json::Value =
        serde_json::from_str(&text).map_err(|source| CalError::ManifestJson { path, source })?;
    let runs = doc["runs"].as_array().map(Vec::as_slice).unwrap_or_default();
    Ok(Some(
        runs.iter()
            .filter_map(|run| {
                Some(ManifestRun {
                    name: run["name"].as_str()?.to_string(),
                    group: run["group"].as_str().filter(|g| !g.is_empty()).map(str::to_string),
                    input_rate_dph: run["input_rate_dph"].as_f64(),
                })
            })
            .collect(),
    ))
}

/// What the manifest beside a command's logs says about them.
#[derive(Clone, Debug, PartialEq)]
pub enum ManifestForLogs {
    /// No folder of the logs holds a manifest.
    Absent,
    /// The manifest describes every log: its rows, as a runs file without roles, in the
    /// logs' order (each row's `line` is 0: the manifest has no lines to name).
    Runs(RunsFile),
    /// A manifest lies beside the logs but does not describe them all: why, for a note.
    NotUsed(String),
}

/// The folder a log is in (`.` for a bare file name).
fn folder_of(log: &Path) -> PathBuf {
    match log.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// The run metadata a simulation's manifest gives `logs` when no runs file is given: used only
/// when all logs are in one folder whose manifest lists each with a finite input rate. A run
/// without a group is a position of its own.
#[must_use]
pub fn manifest_for_logs(logs: &[PathBuf]) -> ManifestForLogs {
    let folders: BTreeSet<PathBuf> = logs.iter().map(|l| folder_of(l)).collect();
    let with_manifest: Vec<&PathBuf> = folders.iter().filter(|f| f.join(MANIFEST_FILE).is_file()).collect();
    let Some(first) = with_manifest.first() else { return ManifestForLogs::Absent };
    let path = first.join(MANIFEST_FILE);
    let not_used = |why: String| {
        ManifestForLogs::NotUsed(format!(
            "{} is not used as run metadata: {why}; give each run's position and input rate with --runs FILE",
            path.display()
        ))
    };
    if folders.len() > 1 {
        return not_used(format!(
            "the logs come from {} folders, and a manifest describes the runs of its own folder",
            folders.len()
        ));
    }
    let runs = match read_manifest(first) {
        Ok(Some(runs)) => runs,
        Ok(None) => return ManifestForLogs::Absent,
        Err(e) => return not_used(e.to_string()),
    };
    let mut rows = Vec::with_capacity(logs.len());
    for log in logs {
        let name = run_name(log);
        let Some(run) = runs.iter().find(|r| r.name == name) else {
            return not_used(format!("it does not list {}", log.display()));
        };
        // A run of no group (a scenario's own `[[runs]]`) is a position of its own: the
        // manifest does not say which runs share one.
        let position = run.group.clone().unwrap_or_else(|| name.clone());
        let rate = run.input_rate_dph.filter(|r| r.is_finite() && r.abs() <= MAX_INPUT_RATE_DPH);
        let Some(input_rate_dph) = rate else {
            return not_used(format!("it gives run '{name}' no finite input_rate_dph"));
        };
        rows.push(RunMetadata { run: name, position, input_rate_dph, role: None, line: 0 });
    }
    ManifestForLogs::Runs(RunsFile { path, runs: rows })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder_with(manifest: &str, logs: &[&str]) -> (tempfile::TempDir, Vec<PathBuf>) {
        let dir = tempfile::tempdir().expect("temporary folder");
        std::fs::write(dir.path().join(MANIFEST_FILE), manifest).expect("manifest written");
        let paths = logs.iter().map(|l| dir.path().join(l)).collect();
        (dir, paths)
    }

    const TWO_RUNS: &str = r#"{"runs": [
        {"name": "pos1_-40C", "group": "pos1", "input_rate_dph": 9.5},
        {"name": "pos2_-40C", "group": "pos2", "input_rate_dph": -9.5}
    ]}"#;

    #[test]
    fn a_manifest_gives_each_log_its_group_and_rate_in_the_logs_order() {
        let (_dir, logs) = folder_with(TWO_RUNS, &["pos2_-40C.csv", "pos1_-40C.csv"]);
        let ManifestForLogs::Runs(file) = manifest_for_logs(&logs) else { panic!("manifest not used") };
        let got: Vec<(&str, &str, f64)> =
            file.runs.iter().map(|r| (r.run.as_str(), r.position.as_str(), r.input_rate_dph)).collect();
        assert_eq!(got, vec![("pos2_-40C", "pos2", -9.5), ("pos1_-40C", "pos1", 9.5)]);
        assert!(file.runs.iter().all(|r| r.role.is_none()));
        // The rows fit the logs as a runs file's would.
        assert_eq!(file.for_logs(&logs).expect("rows for the logs").len(), 2);
    }

    #[test]
    fn a_subset_of_the_manifests_runs_is_described() {
        let (_dir, logs) = folder_with(TWO_RUNS, &["pos1_-40C.csv"]);
        let ManifestForLogs::Runs(file) = manifest_for_logs(&logs) else { panic!("manifest not used") };
        assert_eq!(file.runs.len(), 1);
    }

    #[test]
    fn a_log_the_manifest_does_not_list_stops_its_use_with_a_reason() {
        let (_dir, logs) = folder_with(TWO_RUNS, &["pos1_-40C.csv", "recorded.csv"]);
        match manifest_for_logs(&logs) {
            ManifestForLogs::NotUsed(why) => {
                assert!(why.contains("does not list") && why.contains("recorded.csv"), "{why}");
                assert!(why.contains("--runs FILE"), "{why}");
            }
            other => panic!("expected NotUsed, got {other:?}"),
        }
    }

    #[test]
    fn a_run_without_a_rate_stops_its_use_one_without_a_group_is_its_own_position() {
        let (_dir, logs) = folder_with(r#"{"runs": [{"name": "a", "group": "p"}]}"#, &["a.csv"]);
        assert!(
            matches!(manifest_for_logs(&logs), ManifestForLogs::NotUsed(w) if w.contains("input_rate_dph"))
        );
        let (_dir, logs) =
            folder_with(r#"{"runs": [{"name": "a", "group": "", "input_rate_dph": 1.0}]}"#, &["a.csv"]);
        let ManifestForLogs::Runs(file) = manifest_for_logs(&logs) else { panic!("manifest not used") };
        assert_eq!(file.runs[0].position, "a", "a run of no group is a position of its own");
        let (_dir, logs) =
            folder_with(r#"{"runs": [{"name": "a", "group": "p", "input_rate_dph": 1e30}]}"#, &["a.csv"]);
        assert!(matches!(manifest_for_logs(&logs), ManifestForLogs::NotUsed(_)));
    }

    #[test]
    fn invalid_json_is_named_and_not_used() {
        let (_dir, logs) = folder_with("{not json", &["a.csv"]);
        assert!(
            matches!(manifest_for_logs(&logs), ManifestForLogs::NotUsed(w) if w.contains("not valid JSON"))
        );
        let dir = logs[0].parent().expect("folder").to_path_buf();
        assert!(matches!(read_manifest(&dir), Err(CalError::ManifestJson { .. })));
    }

    #[test]
    fn logs_from_two_folders_or_none_with_a_manifest() {
        let (dir, mut logs) = folder_with(TWO_RUNS, &["pos1_-40C.csv"]);
        let other = tempfile::tempdir().expect("temporary folder");
        logs.push(other.path().join("pos2_-40C.csv"));
        assert!(matches!(manifest_for_logs(&logs), ManifestForLogs::NotUsed(w) if w.contains("2 folders")));
        assert_eq!(manifest_for_logs(&logs[1..]), ManifestForLogs::Absent);
        drop(dir);
    }
}
