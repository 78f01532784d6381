//! A fogtemp simulation's `manifest.json` as run metadata. DESIGN.md §3: a runs file is "used
//! by `diagnose`, `fit` and `validate`; a fogtemp simulation's `manifest.json` gives the same
//! when no file is given". Each run's position is the manifest's `group`, its true input rate
//! the manifest's `input_rate_dph`. `simulate` writes the manifest beside the logs.
//!
//! `fit` and `validate` use the manifests only when every log given lies in a folder whose
//! manifest lists it (folders compared as the file system resolves them, so `sim/a.csv` and
//! `./sim/b.csv` are one folder). Otherwise (a recording copied into a simulation's folder, a
//! folder without a manifest beside one with, a manifest that is malformed or lists a run
//! twice) none is used, and a note says why ([`ManifestForLogs::NotUsed`]). Before 2026-11-29
//! only `diagnose` read it (review27b F1; review30a checked this module).

use std::path::{Path, PathBuf};

use crate::error::CalError;
use crate::runs::{run_name, run_names, RunMetadata, MAX_INPUT_RATE_DPH};

/// The manifest's file name, in the simulation's folder.
pub const MANIFEST_FILE: &str = "manifest.json";

/// The file `simulate` writes into its folder before the first log and removes after the
/// manifest: a folder that still holds it holds an interrupted (or failed) simulation, a part
/// of its campaign at most (review27a 10).
pub const UNFINISHED_FILE: &str = "SIMULATION-UNFINISHED.txt";

/// The warning for logs read from a folder that holds [`UNFINISHED_FILE`], one per such
/// folder, in the logs' order.
#[must_use]
pub fn unfinished_simulation_warnings(logs: &[PathBuf]) -> Vec<String> {
    distinct_folders(logs)
        .iter()
        .filter(|(_, resolved)| resolved.join(UNFINISHED_FILE).is_file())
        .map(|(f, _)| f)
        .map(|f| {
            // "." alone read as a typo (review30b F8).
            let folder = if f == Path::new(".") { "the current folder (.)".into() } else { f.display().to_string() };
            format!(
                "{folder} holds {UNFINISHED_FILE}: the simulation written there did not finish (interrupted, or \
                 it failed), so its logs are a part of the campaign at most; simulate into it again"
            )
        })
        .collect()
}

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

/// `DIR/manifest.json` parsed; `None` when the folder has none.
fn read_manifest_doc(dir: &Path) -> Result<Option<serde_json::Value>, CalError> {
    let path = dir.join(MANIFEST_FILE);
    if !path.is_file() {
        return Ok(None);
    }
    let text =
        std::fs::read_to_string(&path).map_err(|source| CalError::Io { path: path.clone(), source })?;
    serde_json::from_str(&text).map(Some).map_err(|source| CalError::ManifestJson { path, source })
}

/// The runs of `DIR/manifest.json`, in its order; `None` when the folder has no manifest.
/// Read leniently, as `diagnose` always has: entries without a `name` are passed over, a group
/// or rate of another type is taken as absent. Numbers are read back exactly as written
/// (serde_json's `float_roundtrip`: its default parser was 1 ulp off on the Earth rate, so a
/// runs file written from the manifest by Python gave other bits).
///
/// # Errors
/// [`CalError::Io`] when the manifest cannot be read; [`CalError::ManifestJson`] when it is
/// not valid JSON.
pub fn read_manifest(dir: &Path) -> Result<Option<Vec<ManifestRun>>, CalError> {
    let Some(doc) = read_manifest_doc(dir)? else { return Ok(None) };
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

/// The runs of a manifest read strictly, for `fit` and `validate`: every entry named once,
/// with a finite input rate within [`MAX_INPUT_RATE_DPH`] and a group that is text (or
/// absent, null or empty: none). `Err` says what is wrong, for the note.
fn strict_runs(doc: &serde_json::Value) -> Result<Vec<ManifestRun>, String> {
    let Some(entries) = doc["runs"].as_array() else { return Err("it has no list of runs".to_string()) };
    let mut runs: Vec<ManifestRun> = Vec::with_capacity(entries.len());
    for (k, entry) in entries.iter().enumerate() {
        let Some(name) = entry["name"].as_str() else { return Err(format!("its run {} has no name", k + 1)) };
        if runs.iter().any(|r| r.name == name) {
            return Err(format!("it lists run '{name}' twice"));
        }
        let group = match &entry["group"] {
            serde_json::Value::Null => None,
            serde_json::Value::String(g) => Some(g.clone()).filter(|g| !g.is_empty()),
            other => return Err(format!("it gives run '{name}' a group that is not text ({other})")),
        };
        let input_rate_dph = match entry["input_rate_dph"].as_f64() {
            Some(rate) if rate.abs() <= MAX_INPUT_RATE_DPH => rate,
            Some(rate) => {
                return Err(format!(
                    "it gives run '{name}' an input_rate_dph of {rate:e} deg/h, beyond any gyro's range \
                     ({MAX_INPUT_RATE_DPH:e} deg/h)"
                ))
            }
            None => return Err(format!("it gives run '{name}' no input_rate_dph (a number)")),
        };
        runs.push(ManifestRun { name: name.to_string(), group, input_rate_dph: Some(input_rate_dph) });
    }
    Ok(runs)
}

/// The run metadata the manifests give a command's logs.
#[derive(Clone, Debug, PartialEq)]
pub struct ManifestRows {
    /// The manifests read, one per folder, in the logs' order.
    pub manifests: Vec<PathBuf>,
    /// One row per log, in the logs' order (each row's `line` is 0: a manifest has no lines
    /// to name; `role` none).
    pub rows: Vec<RunMetadata>,
    /// A run without a group when there is one, its name: then no run has a position but
    /// its own (the manifest does not say which runs share one), so `auto` leaves one run out
    /// at a time.
    pub ungrouped: Option<String>,
}

/// What the manifests beside a command's logs say about them.
#[derive(Clone, Debug, PartialEq)]
pub enum ManifestForLogs {
    /// No folder of the logs holds a manifest.
    Absent,
    /// The manifests describe every log.
    Runs(ManifestRows),
    /// A manifest lies beside the logs but the manifests do not describe them all: why, for a
    /// note.
    NotUsed(String),
}

/// The folder a log is in (`.` for a bare file name).
fn folder_of(log: &Path) -> PathBuf {
    match log.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// The logs' folders, each once as the file system resolves it (`sim`, `./sim` and an
/// absolute path to it are one folder), in the logs' order: (the folder as first written,
/// its resolved form).
fn distinct_folders(logs: &[PathBuf]) -> Vec<(PathBuf, PathBuf)> {
    let mut folders: Vec<(PathBuf, PathBuf)> = Vec::new();
    for folder in logs.iter().map(|l| folder_of(l)) {
        let resolved = folder.canonicalize().unwrap_or_else(|_| folder.clone());
        if !folders.iter().any(|(_, r)| *r == resolved) {
            folders.push((folder, resolved));
        }
    }
    folders
}

/// The run metadata the simulations' manifests give `logs` when no runs file is given: used
/// only when every log's folder has a manifest that lists it ([`strict_runs`]). A run without
/// a group leaves every run a position of its own ([`ManifestRows::ungrouped`]).
/// `runs_option` is how the caller names a runs file in the note (`--runs FILE`, `runs=`).
#[must_use]
pub fn manifest_for_logs(logs: &[PathBuf], runs_option: &str) -> ManifestForLogs {
    let folders = distinct_folders(logs);
    let with_manifest: Vec<&PathBuf> =
        folders.iter().filter(|(_, r)| r.join(MANIFEST_FILE).is_file()).map(|(f, _)| f).collect();
    let Some(first) = with_manifest.first() else { return ManifestForLogs::Absent };
    let not_used = |path: &Path, why: String| {
        ManifestForLogs::NotUsed(format!(
            "{} is not used as run metadata: {why}; give each run's position and input rate in a runs file \
             ({runs_option})",
            path.display()
        ))
    };
    if let Some((bare, _)) = folders.iter().find(|(_, r)| !r.join(MANIFEST_FILE).is_file()) {
        return not_used(
            &first.join(MANIFEST_FILE),
            format!("the logs in {} have no manifest beside them", bare.display()),
        );
    }
    let mut per_folder: Vec<(PathBuf, Vec<ManifestRun>)> = Vec::with_capacity(folders.len());
    for (folder, resolved) in &folders {
        let path = folder.join(MANIFEST_FILE);
        let runs = match read_manifest_doc(resolved) {
            Ok(Some(doc)) => strict_runs(&doc),
            Ok(None) => Err("it went away while being read".to_string()),
            Err(CalError::ManifestJson { source, .. }) => Err(format!("it is not valid JSON ({source})")),
            Err(e) => Err(e.to_string()),
        };
        match runs {
            Ok(runs) => per_folder.push((resolved.clone(), runs)),
            Err(why) => return not_used(&path, why),
        }
    }
    let mut rows = Vec::with_capacity(logs.len());
    let mut ungrouped = None;
    for log in logs {
        let resolved = folder_of(log).canonicalize().unwrap_or_else(|_| folder_of(log));
        let Some((_, runs)) = per_folder.iter().find(|(r, _)| *r == resolved) else {
            return not_used(&folder_of(log).join(MANIFEST_FILE), "it cannot be read".to_string());
        };
        let name = run_name(log);
        let Some(run) = runs.iter().find(|r| r.name == name) else {
            return not_used(
                &folder_of(log).join(MANIFEST_FILE),
                format!("it does not list {}", log.display()),
            );
        };
        if run.group.is_none() && ungrouped.is_none() {
            ungrouped = Some(name.clone());
        }
        let position = run.group.clone().unwrap_or_default();
        rows.push(RunMetadata {
            run: name,
            position,
            input_rate_dph: run.input_rate_dph.unwrap_or(0.0),
            role: None,
            line: 0,
        });
    }
    if ungrouped.is_some() {
        // Each run its own position, named as the logs are (by path where file names repeat).
        let paths: Vec<&Path> = logs.iter().map(PathBuf::as_path).collect();
        for (row, name) in rows.iter_mut().zip(run_names(&paths)) {
            row.position = name;
        }
    }
    let manifests = folders.iter().map(|(f, _)| f.join(MANIFEST_FILE)).collect();
    ManifestForLogs::Runs(ManifestRows { manifests, rows, ungrouped })
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

    fn rows_of(logs: &[PathBuf]) -> ManifestRows {
        match manifest_for_logs(logs, "--runs FILE") {
            ManifestForLogs::Runs(found) => found,
            other => panic!("manifest not used: {other:?}"),
        }
    }

    fn why_not(logs: &[PathBuf]) -> String {
        match manifest_for_logs(logs, "--runs FILE") {
            ManifestForLogs::NotUsed(why) => why,
            other => panic!("expected NotUsed, got {other:?}"),
        }
    }

    #[test]
    fn a_manifest_gives_each_log_its_group_and_rate_in_the_logs_order() {
        let (_dir, logs) = folder_with(TWO_RUNS, &["pos2_-40C.csv", "pos1_-40C.csv"]);
        let found = rows_of(&logs);
        let got: Vec<(&str, &str, f64)> =
            found.rows.iter().map(|r| (r.run.as_str(), r.position.as_str(), r.input_rate_dph)).collect();
        assert_eq!(got, vec![("pos2_-40C", "pos2", -9.5), ("pos1_-40C", "pos1", 9.5)]);
        assert!(found.rows.iter().all(|r| r.role.is_none()));
        assert_eq!(found.ungrouped, None);
        assert_eq!(found.manifests.len(), 1);
        // A subset of its runs is described too.
        assert_eq!(rows_of(&logs[..1]).rows.len(), 1);
    }

    /// review30a F1: `sim/a.csv` beside `sim/./b.csv` (or an absolute path to it) is one
    /// folder, not two.
    #[test]
    fn one_folder_written_two_ways_is_one_folder() {
        let (dir, logs) = folder_with(TWO_RUNS, &["pos1_-40C.csv"]);
        let other_spelling = dir.path().join(".").join("pos2_-40C.csv");
        let found = rows_of(&[logs[0].clone(), other_spelling]);
        assert_eq!(found.manifests.len(), 1);
        assert_eq!(found.rows[1].input_rate_dph, -9.5);
    }

    /// review30a F4: two simulations of one scenario share run names; each log takes its own
    /// folder's row.
    #[test]
    fn logs_of_two_simulations_take_their_own_folders_rows() {
        let (_a, mut logs) = folder_with(TWO_RUNS, &["pos1_-40C.csv"]);
        let (_b, other) = folder_with(&TWO_RUNS.replace("9.5", "7.25"), &["pos1_-40C.csv"]);
        logs.extend(other);
        let found = rows_of(&logs);
        assert_eq!(found.manifests.len(), 2);
        let rates: Vec<f64> = found.rows.iter().map(|r| r.input_rate_dph).collect();
        assert_eq!(rates, vec![9.5, 7.25]);
    }

    /// review30a F2: a run of no group leaves every run a position of its own (named as the
    /// logs are), so `auto` does not take one ungrouped run for a third position.
    #[test]
    fn a_run_without_a_group_leaves_every_run_its_own_position() {
        let manifest = r#"{"runs": [
            {"name": "a", "group": "pos1", "input_rate_dph": 1.0},
            {"name": "b", "group": "pos1", "input_rate_dph": 1.0},
            {"name": "c", "group": "", "input_rate_dph": 2.0}
        ]}"#;
        let (_dir, logs) = folder_with(manifest, &["a.csv", "b.csv", "c.csv"]);
        let found = rows_of(&logs);
        assert_eq!(found.ungrouped.as_deref(), Some("c"));
        let positions: Vec<&str> = found.rows.iter().map(|r| r.position.as_str()).collect();
        assert_eq!(positions, vec!["a", "b", "c"]);
        // Without c, the group holds.
        assert_eq!(rows_of(&logs[..2]).rows[1].position, "pos1");
    }

    #[test]
    fn what_stops_a_manifests_use_is_said() {
        let cases: [(&str, &[&str], &str); 8] = [
            (TWO_RUNS, &["pos1_-40C.csv", "recorded.csv"], "does not list"),
            (r#"{"runs": [{"name": "a", "group": "p"}]}"#, &["a.csv"], "no input_rate_dph"),
            (
                r#"{"runs": [{"name": "a", "group": "p", "input_rate_dph": 1e30}]}"#,
                &["a.csv"],
                "beyond any gyro",
            ),
            (r#"{"runs": [{"name": "a", "group": 1, "input_rate_dph": 1.0}]}"#, &["a.csv"], "not text"),
            (
                r#"{"runs": [{"name": "a", "group": "p", "input_rate_dph": 1.0}, {"name": "a", "group": "p", "input_rate_dph": -1.0}]}"#,
                &["a.csv"],
                "lists run 'a' twice",
            ),
            (r#"{"scenario": "x"}"#, &["a.csv"], "no list of runs"),
            (r#"{"runs": [{"group": "p", "input_rate_dph": 1.0}]}"#, &["a.csv"], "run 1 has no name"),
            ("{not json", &["a.csv"], "is not valid JSON ("),
        ];
        for (manifest, logs, expected) in cases {
            let (_dir, logs) = folder_with(manifest, logs);
            let why = why_not(&logs);
            assert!(why.contains(expected) && why.contains("runs file"), "{manifest}: {why}");
            // The manifest's path once, not twice (review30a F8).
            assert_eq!(why.matches(MANIFEST_FILE).count(), 1, "{why}");
        }
    }

    #[test]
    fn invalid_json_is_an_error_of_the_lenient_reader() {
        let (_dir, logs) = folder_with("{not json", &["a.csv"]);
        let dir = logs[0].parent().expect("folder").to_path_buf();
        assert!(matches!(read_manifest(&dir), Err(CalError::ManifestJson { .. })));
    }

    #[test]
    fn a_folder_without_a_manifest_beside_one_with_stops_its_use() {
        let (_dir, mut logs) = folder_with(TWO_RUNS, &["pos1_-40C.csv"]);
        let other = tempfile::tempdir().expect("temporary folder");
        logs.push(other.path().join("pos2_-40C.csv"));
        assert!(why_not(&logs).contains("have no manifest beside them"));
        assert_eq!(manifest_for_logs(&logs[1..], "--runs FILE"), ManifestForLogs::Absent);
    }

    #[test]
    fn a_folder_with_the_unfinished_marker_is_warned_of_once() {
        let (dir, logs) = folder_with(TWO_RUNS, &["pos1_-40C.csv", "pos2_-40C.csv"]);
        assert!(unfinished_simulation_warnings(&logs).is_empty());
        std::fs::write(dir.path().join(UNFINISHED_FILE), "x").expect("marker");
        let warnings = unfinished_simulation_warnings(&logs);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains(UNFINISHED_FILE) && warnings[0].contains("did not finish"),
            "{warnings:?}"
        );
    }
}
