//! End-to-end tests of `fogtemp-cal simulate` and `fogtemp-cal demo` (docs/architecture.md, Contracts;
//! docs/simulator.md): the files a simulation writes and their format, agreement with the library,
//! byte-identical output per seed, error reporting for a bad scenario file, and a small demo
//! whose compensated bias stability beats the raw one.
//!
//! The binary is located as in `tests/cli.rs` (built once per test process by cargo, or
//! `FOGTEMP_CAL_BIN`). Scenarios are small (10 Hz, minutes per run) to keep the debug build
//! quick; everything is written to temporary folders.

mod common;

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};

use common::{cal, run_err, run_ok};
use fogtemp_sim::{simulate_in_memory, Scenario, PAPER_TOML};
use serde_json::{json, Value};
use tempfile::TempDir;

/// Runs `fogtemp-cal args...`, requires success, parses stdout as JSON.
fn run_json(args: &[&str]) -> Value {
    let stdout = run_ok(args);
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("stdout is not JSON ({e}):\n{stdout}"))
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 temporary path")
}

/// The paper's physics and noise, 10 Hz, three explicit 15-minute runs: a power-on at a
/// constant chamber, a chamber ramp, a step on a warm unit.
const SMALL: &str = r#"name = "small"
sample_rate_hz = 10.0
seed = 42

[site]
latitude_deg = 40.0

[thermal]
electronics_heat_capacity_j_per_k = 150.0
case_heat_capacity_j_per_k = 1000.0
coil_outer_heat_capacity_j_per_k = 100.0
coil_inner_heat_capacity_j_per_k = 100.0
electronics_case_w_per_k = 2.0
case_coil_w_per_k = 0.33
coil_radial_w_per_k = 0.83
case_ambient_w_per_k = 1.0
power_w = 10.0

[sensor]
mount = "case"
time_constant_s = 60.0
rate_hz = 1.0
noise_c = 0.01
quantum_c = 0.0625

[bias]
temperature_node = "coil"
reference_temp_c = 20.0
static_dph = [0.0, 0.005, 2.0e-5]
shupe_dph_per_c_per_min = 0.06
scale_factor_ppm_per_c = 5.0
turn_on_sigma_dph = 0.002

[noise]
arw_deg_per_sqrt_h = 0.0005
bias_instability_dph = 0.002

[chamber]
ripple_amplitude_c = 0.2
ripple_period_s = 600.0

[[runs]]
name = "hold"
duration_s = 900.0
input_axis = "up"
chamber = { kind = "constant", temp_c = -20.0 }

[[runs]]
name = "ramp"
duration_s = 900.0
input_axis = "north"
chamber = { kind = "ramp", start_c = 10.0, end_c = 30.0, rate_c_per_min = 2.0, start_s = 60.0 }

[[runs]]
name = "step"
duration_s = 900.0
input_axis = "down"
initial = "warm"
chamber = { kind = "step", start_c = 25.0, to_c = 0.0, at_s = 120.0 }
"#;

const NAMES: [&str; 3] = ["hold", "ramp", "step"];

/// `simulate` with a scenario file writes NAME.csv (`time_s,temp_c,gyro_dph`, one row per
/// sample at n / rate), truth/NAME.csv, scenario.toml (the file as given) and manifest.json,
/// and reports the samples in `--json`. The logged values are the library's samples printed
/// to 4 decimals (within 5e-5 + 1e-9: half the last printed digit).
#[test]
fn simulate_writes_logs_truth_scenario_and_manifest() {
    let dir = TempDir::new().expect("tmp");
    let file = dir.path().join("small.toml");
    fs::write(&file, SMALL).expect("write scenario");
    let out = dir.path().join("out");
    let started = std::time::Instant::now();
    let doc = run_json(&["simulate", "--scenario", s(&file), "--out", s(&out), "--json"]);
    eprintln!("simulate: {:.2} s", started.elapsed().as_secs_f64());

    assert_eq!(doc["scenario"], "small");
    assert_eq!(doc["seed"], 42);
    assert_eq!(doc["sample_rate_hz"], 10.0);
    assert_eq!(doc["samples"], 3 * 9001);
    let runs = doc["runs"].as_array().expect("runs[]");
    assert_eq!(runs.len(), 3);
    for (r, name) in runs.iter().zip(NAMES) {
        assert_eq!(r["name"], name);
        assert_eq!(r["samples"], 9001);
        assert_eq!(r["duration_s"], 900.0);
    }
    assert_eq!(runs[2]["initial"], "warm");
    assert_eq!(runs[1]["start_temp_c"], 10.0);

    // The library's samples for the same scenario.
    let scenario = Scenario::from_toml(SMALL, "small").expect("valid");
    let library: BTreeMap<String, Vec<fogtemp_sim::Sample>> =
        simulate_in_memory(&scenario).into_iter().map(|(t, x)| (t.spec.name.clone(), x)).collect();

    for name in NAMES {
        let text = fs::read_to_string(out.join(format!("{name}.csv"))).expect("log written");
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("time_s,temp_c,gyro_dph"));
        let rows: Vec<[f64; 3]> = lines
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|f| f.parse().expect("number")).collect();
                [v[0], v[1], v[2]]
            })
            .collect();
        assert_eq!(rows.len(), 9001, "{name}");
        let want = &library[name];
        for (n, (row, x)) in rows.iter().zip(want).enumerate() {
            assert!((row[0] - n as f64 / 10.0).abs() < 1e-9, "{name} row {n}: time {}", row[0]);
            assert!(
                (row[1] - x.temp_c).abs() <= 5e-5 + 1e-9,
                "{name} row {n}: temp {} vs {}",
                row[1],
                x.temp_c
            );
            assert!(
                (row[2] - x.gyro_dph).abs() <= 5e-5 + 1e-9,
                "{name} row {n}: gyro {} vs {}",
                row[2],
                x.gyro_dph
            );
        }

        let truth = fs::read_to_string(out.join("truth").join(format!("{name}.csv"))).expect("truth written");
        let mut lines = truth.lines();
        let header = lines.next().expect("header");
        assert!(header.starts_with("time_s,ambient_c,electronics_c,case_c,coil_c,sensor_true_c"), "{header}");
        let times: Vec<f64> =
            lines.map(|l| l.split(',').next().expect("time").parse().expect("number")).collect();
        assert!(
            times.len() >= 901 && times[0] == 0.0 && times[900] == 900.0,
            "{name}: truth on the 1 s grid"
        );
    }

    assert_eq!(fs::read_to_string(out.join("scenario.toml")).expect("scenario.toml"), SMALL);
    let manifest: Value =
        serde_json::from_slice(&fs::read(out.join("manifest.json")).expect("manifest")).expect("JSON");
    assert_eq!(manifest["scenario"], "small");
    assert_eq!(manifest["columns"], serde_json::json!(["time_s", "temp_c", "gyro_dph"]));
    assert_eq!(manifest["runs"].as_array().map(Vec::len), Some(3));
    assert_eq!(manifest["runs"][1]["name"], "ramp");
    let up_rate = manifest["runs"][0]["input_rate_dph"].as_f64().expect("rate");
    assert!((up_rate - 9.6682).abs() < 1e-3, "up at 40 N: {up_rate}");
    assert_eq!(manifest["runs"][2]["input_rate_dph"].as_f64(), Some(-up_rate));
    // The manifest's files are named from its own folder (the command ran elsewhere, with
    // --out a longer path), so it stays true when the folder is read from anywhere.
    for (run, name) in manifest["runs"].as_array().expect("runs").iter().zip(NAMES) {
        assert_eq!(run["file"], format!("{name}.csv"));
        assert_eq!(run["truth_file"], format!("truth/{name}.csv"));
        assert!(out.join(run["file"].as_str().expect("file")).is_file(), "{name}");
        assert!(out.join(run["truth_file"].as_str().expect("truth_file")).is_file(), "{name}");
    }
}

/// Byte-identical logs and truth for the same seed (twice from the file, and with the same
/// seed given on the command line); another `--seed` changes every log; `--rate` and
/// `--duration-s` change the sample count, and scenario.toml records the overrides and
/// parses back to what was simulated.
#[test]
fn simulate_is_deterministic_per_seed() {
    let dir = TempDir::new().expect("tmp");
    let file = dir.path().join("small.toml");
    fs::write(&file, SMALL).expect("write scenario");
    let sim = |out: &str, extra: &[&str]| -> PathBuf {
        let out = dir.path().join(out);
        let mut args = vec!["simulate", "--scenario", s(&file), "--out", s(&out), "--duration-s", "300"];
        args.extend_from_slice(extra);
        cal().args(&args).assert().success();
        out
    };
    let a = sim("a", &[]);
    let b = sim("b", &[]);
    let c = sim("c", &["--seed", "42"]);
    let d = sim("d", &["--seed", "43"]);
    for name in NAMES {
        let log = |dir: &Path| fs::read(dir.join(format!("{name}.csv"))).expect("log");
        let truth = |dir: &Path| fs::read(dir.join("truth").join(format!("{name}.csv"))).expect("truth");
        assert_eq!(log(&a), log(&b), "{name}: same seed, same bytes");
        assert_eq!(truth(&a), truth(&b), "{name}: same truth");
        assert_eq!(log(&a), log(&c), "{name}: --seed 42 is the file's seed");
        assert_ne!(log(&a), log(&d), "{name}: another seed");
        assert!(!log(&a).is_empty(), "{name}: a log was written");
    }
    let lines = |dir: &Path| fs::read_to_string(dir.join("hold.csv")).expect("log").lines().count();
    assert_eq!(lines(&a), 3002, "300 s at 10 Hz plus the header");

    let e = sim("e", &["--rate", "4", "--seed", "9"]);
    assert_eq!(lines(&e), 1202, "300 s at 4 Hz plus the header");
    let stored = fs::read_to_string(e.join("scenario.toml")).expect("scenario.toml");
    assert!(
        stored.starts_with("# ")
            && stored.contains("with overrides: rate 4 Hz, seed 9, every run 300 s long\n"),
        "{stored}"
    );
    assert!(!stored.contains("Some(") && !stored.contains("None"), "Rust's debug text: {stored}");
    let back = Scenario::from_toml(&stored, "stored").expect("the stored scenario parses");
    assert_eq!((back.sample_rate_hz, back.seed, back.runs[0].duration_s), (4.0, 9, 300.0));
}

/// A bad scenario file fails with a non-zero exit and a message naming the file and the
/// line (syntax and unknown fields) or the field (invalid values); nothing is written. A
/// missing file is named too, and an override that makes the scenario invalid is refused.
/// `simulate` into a folder that holds a log of one of its run names but is no simulation's
/// (no `manifest.json`, e.g. a lab's recordings) is refused and the log kept; into a previous
/// simulation's folder it simulates again.
#[test]
fn simulate_never_replaces_logs_it_did_not_write() {
    let dir = TempDir::new().expect("tmp");
    let file = dir.path().join("small.toml");
    fs::write(&file, SMALL).expect("write scenario");
    let first = dir.path().join("first");
    cal()
        .args(["simulate", "--scenario", s(&file), "--out", s(&first), "--duration-s", "60"])
        .assert()
        .success();
    let name = fs::read_dir(&first)
        .expect("list")
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .find(|n| n.ends_with(".csv"))
        .expect("a simulated log");
    // Again into the simulation's own folder: fine; a temporary file a killed run left there
    // is named (review25b F6), and kept (it may be another run's).
    let leftover = first.join(format!(".{name}.fogtemp-Xy12Zz"));
    fs::write(&leftover, vec![b'1'; 2048]).expect("plant a leftover");
    let again = cal()
        .args(["simulate", "--scenario", s(&file), "--out", s(&first), "--duration-s", "60"])
        .assert()
        .success();
    let said = String::from_utf8_lossy(&again.get_output().stderr).into_owned();
    assert!(
        said.contains(&format!("note: 1 temporary file (2.00 KiB) in {}", first.display()))
            && said.contains(&leftover.display().to_string()),
        "{said}"
    );
    assert!(leftover.exists());
    // A lab folder with a log of that name: refused, the log untouched.
    let lab = dir.path().join("lab");
    fs::create_dir(&lab).expect("mkdir");
    fs::write(lab.join(&name), "recorded data\n").expect("write");
    let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&lab), "--duration-s", "60"]);
    assert!(err.contains("is not a simulation's folder") && err.contains(&name), "{err}");
    assert_eq!(fs::read_to_string(lab.join(&name)).expect("read"), "recorded data\n");
    assert!(!lab.join("manifest.json").exists());
    // What an interrupted simulation leaves (review27a 10): a log and the marker, no manifest.
    // `fit` warns of it; `simulate` takes the folder as its own and, done, removes the marker.
    let partial = dir.path().join("partial");
    fs::create_dir(&partial).expect("mkdir");
    fs::copy(first.join(&name), partial.join(&name)).expect("copy");
    // A marker that lists no runs leaves the log foreign: refused (review30b F2).
    fs::write(partial.join("SIMULATION-UNFINISHED.txt"), "left by an interrupted simulate\n")
        .expect("marker");
    let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&partial), "--duration-s", "60"]);
    assert!(err.contains("is not a simulation's folder"), "{err}");
    let marker = format!("left by an interrupted simulate\n\nRuns being written:\n  {name}\n");
    fs::write(partial.join("SIMULATION-UNFINISHED.txt"), marker).expect("marker");
    let model = dir.path().join("partial.fogm");
    let fitted =
        cal().args(["fit", "--method", "poly", "--out", s(&model), s(&partial), "--json"]).assert().success();
    let said = String::from_utf8_lossy(&fitted.get_output().stderr).into_owned();
    assert!(
        said.contains("warning:") && said.contains("SIMULATION-UNFINISHED.txt: the simulation"),
        "{said}"
    );
    // And in the documents (review30b F7): a warning of its own kind, validate's last note.
    let doc: Value = serde_json::from_slice(&fitted.get_output().stdout).expect("fit --json");
    let unfinished: Vec<&Value> = doc["warnings"]
        .as_array()
        .expect("warnings")
        .iter()
        .filter(|w| w["kind"] == "unfinished_simulation")
        .collect();
    assert_eq!(unfinished.len(), 1, "{doc}");
    assert!(unfinished[0]["message"].as_str().is_some_and(|m| said.contains(m)), "{doc}");
    let validated = run_json(&["validate", "--model", s(&model), s(&partial), "--json"]);
    let last = validated["notes"].as_array().and_then(|n| n.last()).and_then(Value::as_str).unwrap_or("");
    assert!(last.contains("SIMULATION-UNFINISHED.txt: the simulation"), "{validated}");
    run_ok(["simulate", "--scenario", s(&file), "--out", s(&partial), "--duration-s", "60"]);
    assert!(!partial.join("SIMULATION-UNFINISHED.txt").exists());
    assert!(partial.join("manifest.json").is_file());
    assert_eq!(fs::read(partial.join(&name)).expect("read"), fs::read(first.join(&name)).expect("read"));
}

#[test]
fn simulate_rejects_a_bad_scenario_file() {
    let dir = TempDir::new().expect("tmp");
    let out = dir.path().join("out");
    let cases = [
        ("unknown.toml", SMALL.replace("power_w = 10.0", "power_w = 10.0\nfan_w = 2.0"), "fan_w"),
        ("syntax.toml", SMALL.replace("seed = 42", "seed = = 42"), "seed"),
        ("kind.toml", SMALL.replace("\"step\", start_c", "\"stair\", start_c"), "stair"),
    ];
    for (name, text, needle) in cases {
        let file = dir.path().join(name);
        fs::write(&file, &text).expect("write");
        let line = text.lines().position(|l| l.contains(needle)).expect("needle") + 1;
        let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&out)]);
        assert!(err.contains(s(&file)), "{name}: the file is named: {err}");
        assert!(err.contains(&format!("line {line}")), "{name}: line {line}: {err}");
        assert!(err.contains(needle), "{name}: {err}");
        assert!(!out.exists(), "{name}: nothing written");
    }

    let file = dir.path().join("negative.toml");
    fs::write(
        &file,
        SMALL.replace("case_heat_capacity_j_per_k = 1000.0", "case_heat_capacity_j_per_k = -5.0"),
    )
    .expect("write");
    let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&out)]);
    assert!(err.contains(s(&file)) && err.contains("thermal.case_heat_capacity_j_per_k"), "{err}");

    let file = dir.path().join("duplicate.toml");
    fs::write(&file, SMALL.replace("name = \"ramp\"", "name = \"hold\"")).expect("write");
    let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&out)]);
    assert!(err.contains("two runs are named 'hold'"), "{err}");

    let missing = dir.path().join("missing.toml");
    let err = run_err(["simulate", "--scenario", s(&missing), "--out", s(&out)]);
    assert!(err.contains(s(&missing)), "{err}");

    let file = dir.path().join("small.toml");
    fs::write(&file, SMALL).expect("write");
    let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&out), "--rate", "0"]);
    assert!(err.contains("sample_rate_hz"), "{err}");
    assert!(!out.exists(), "nothing written");
    // More CSV than a disk holds is refused before the first row (review27a 7): the small
    // scenario's runs at 1e12 Hz, about 24 bytes a sample.
    let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&out), "--rate", "1e12"]);
    assert!(err.contains("more than a disk holds") && err.contains("lower the rate (--rate)"), "{err}");
    assert!(!out.exists(), "nothing written");
}

/// The paper scenario with 4 start temperatures (-40, -10, 20, 50 C) x 2 positions x 30 min
/// at 10 Hz (`--rate` overrides the 1000 Hz).
fn small_demo_scenario() -> String {
    let text = PAPER_TOML
        .replace(
            "start_temps_c = [-40.0, -25.0, -10.0, 5.0, 20.0, 35.0, 45.0, 60.0]",
            "start_temps_c = [-40.0, -10.0, 20.0, 50.0]",
        )
        .replace("duration_s = 7200.0", "duration_s = 1800.0")
        .replace("name = \"paper\"", "name = \"small-demo\"");
    let s = Scenario::from_toml(&text, "small demo").expect("valid");
    let runs = s.expanded_runs();
    assert_eq!(runs.len(), 8, "the replacements took effect");
    assert!(runs.iter().all(|r| r.duration_s == 1800.0));
    text
}

/// `demo` on the small scenario: one JSON document with finite raw_dph, poly_dph, mesh_dph,
/// mesh_paper_dph, hybrid_dph and auto_dph, report/report.md and one models/KEY.fogm per model; the
/// compensated figures are below half the raw one for poly, mesh and hybrid, and below raw
/// for the paper's mesh (measured: raw 0.0116, poly 0.0041, mesh 0.0043, mesh_paper 0.0045,
/// hybrid 0.0041 deg/h). The physics makes this so: the raw figure is the power-on warm-up
/// drift (static slope x self-heating and the Shupe term), which every model removes down to
/// the noise floor (6 N = 0.003 deg/h of white noise at 100 s, plus flicker).
#[test]
fn demo_compensates_below_raw() {
    let dir = TempDir::new().expect("tmp");
    let file = dir.path().join("demo.toml");
    fs::write(&file, small_demo_scenario()).expect("write scenario");
    let out = dir.path().join("demo");
    let started = std::time::Instant::now();
    let doc = run_json(&["demo", "--scenario", s(&file), "--rate", "10", "--out", s(&out), "--json"]);
    eprintln!("demo: {:.2} s; stages {}", started.elapsed().as_secs_f64(), doc["seconds"]);

    assert_eq!(doc["scenario"], "small-demo");
    assert_eq!(doc["sample_rate_hz"], 10.0);
    let value = |key: &str| doc[key].as_f64().unwrap_or_else(|| panic!("{key} missing: {doc}"));
    let raw = value("raw_dph");
    let keys = ["poly_dph", "mesh_dph", "mesh_paper_dph", "hybrid_dph", "auto_dph"];
    eprintln!(
        "raw {raw:.5}, {}",
        keys.iter().map(|k| format!("{k} {:.5}", value(k))).collect::<Vec<_>>().join(", ")
    );
    assert!(raw.is_finite() && raw > 0.0, "raw {raw}");
    for key in keys {
        let v = value(key);
        assert!(v.is_finite() && v > 0.0, "{key} {v}");
        assert!(v < raw, "{key} {v} is not below raw {raw}");
    }
    for key in ["poly_dph", "mesh_dph", "hybrid_dph", "auto_dph"] {
        assert!(value(key) < 0.5 * raw, "{key} {} is not below half of raw {raw}", value(key));
    }

    let models = doc["models"].as_array().expect("models[]");
    let model_keys: Vec<&str> = models.iter().filter_map(|m| m["key"].as_str()).collect();
    assert_eq!(model_keys, ["poly", "mesh", "mesh_paper", "hybrid", "auto"]);
    // auto records its cross-validation: 4 calibration runs, 4 folds, scored or skipped (a
    // held-out run outside the other runs' calibrated region has no window to score), and
    // with fewer than 3 scored folds it says so (folds 0) and fits the default.
    let selection = &models[4]["selection"];
    let scored = selection["folds"].as_u64().expect("folds");
    let skipped = selection["skipped_folds"].as_array().expect("skipped_folds[]").len() as u64;
    if selection["warning"].is_string() {
        assert!(scored == 0 && (2..=4).contains(&skipped), "{selection}");
    } else {
        assert!(scored >= 3 && scored + skipped == 4, "{selection}");
    }
    assert!(["cubic-t", "poly", "mesh", "hybrid"].contains(&selection["method"].as_str().unwrap_or("")));
    for m in models {
        let key = m["key"].as_str().expect("key");
        assert_eq!(m["compensated_dph"].as_f64(), Some(value(&format!("{key}_dph"))));
        let runs = m["runs"].as_array().expect("runs");
        assert_eq!(runs.len(), 4, "{key}: the four pos2 runs validate");
        assert!(runs.iter().all(|r| r[0].as_str().is_some_and(|n| n.starts_with("pos2_"))));
        let path = out.join("models").join(format!("{key}.fogm"));
        let bytes = fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(m["model_bytes"].as_u64(), Some(bytes.len() as u64), "{key}");
    }
    let report = fs::read_to_string(out.join("report").join("report.md")).expect("report.md");
    for key in ["poly", "mesh", "hybrid"] {
        assert!(report.contains(key), "report mentions {key}");
    }
    let logs = fs::read_dir(out.join("logs")).expect("logs").filter_map(Result::ok);
    let csv = logs.filter(|e| e.path().extension().is_some_and(|x| x == "csv")).count();
    assert_eq!(csv, 8, "one log per run");

    // Every model file is a valid blob for the library's own reader.
    let inspect = run_json(&["inspect", s(&out.join("models").join("hybrid.fogm")), "--json"]);
    assert!(inspect.is_object());

    // The paper's figures are named like the models they compare with (review21 second
    // report F6).
    assert_eq!(doc["paper"]["mesh_paper_dph"].as_f64(), Some(0.0051), "{}", doc["paper"]);
    assert!(doc["paper"].get("mesh_dph").is_none(), "{}", doc["paper"]);
    demo_models_know_their_calibration_logs(&out);
}

/// The demo's models record their calibration logs as `fit`'s do (review21 second report F1):
/// a non-zero input digest, and `validate` given the position-1 logs says they are in-sample,
/// given the position-2 logs does not.
fn demo_models_know_their_calibration_logs(out: &Path) {
    let model = out.join("models").join("poly.fogm");
    let inspect = run_json(&["inspect", s(&model), "--json"]);
    let digest = inspect["input_digest"].as_str().expect("input_digest");
    assert!(digest.len() == 64 && digest.chars().any(|c| c != '0'), "{digest}");
    let logs_of = |position: &str| -> Vec<String> {
        let mut logs: Vec<String> = fs::read_dir(out.join("logs"))
            .expect("logs")
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with(position)))
            .map(|p| p.display().to_string())
            .collect();
        logs.sort();
        logs
    };
    let validate_stderr = |position: &str| {
        let mut args = vec!["validate".to_string(), "--model".into(), s(&model).into()];
        args.extend(logs_of(position));
        let output = cal().args(&args).assert().success();
        String::from_utf8_lossy(&output.get_output().stderr).into_owned()
    };
    let calibration = validate_stderr("pos1_");
    assert!(calibration.contains("figures are in-sample"), "{calibration}");
    let validation = validate_stderr("pos2_");
    assert!(!validation.contains("in-sample"), "{validation}");
    // The demo's fit report gives the calibrated range as `fit --report` does.
    let fit_report =
        fs::read_to_string(out.join("report").join("mesh").join("fit-report.md")).expect("fit report");
    assert!(fit_report.contains("  - calibrated range: "), "{fit_report}");
    // With the model over temperature (review26b F10), a file the report names.
    assert!(fit_report.contains("(fit-temperature-axis0.svg)"), "{fit_report}");
    let svg =
        fs::read_to_string(out.join("report").join("mesh").join("fit-temperature-axis0.svg")).expect("svg");
    assert!(svg.contains("50th percentile)"), "a mesh model's curves at three rates");
}

/// `demo` needs runs in positions pos1 and pos2: a scenario without pos2 is refused with a
/// message naming the position.
#[test]
fn demo_without_a_validation_position_fails() {
    let dir = TempDir::new().expect("tmp");
    let text = SMALL.replace("duration_s = 900.0", "duration_s = 60.0");
    let file = dir.path().join("nopos.toml");
    fs::write(&file, text).expect("write");
    let out = dir.path().join("demo");
    let err = run_err(["demo", "--scenario", s(&file), "--out", s(&out), "--no-report", "--json"]);
    assert!(err.contains("no runs in position 'pos1'"), "{err}");
}

// ---------------------------------------------------------------------------------------
// diagnose: simulated vs recorded folders through the command line
// ---------------------------------------------------------------------------------------

/// The paper scenario at 1 Hz (the diagnosis accepts >= 1 Hz), with `bias.temperature_node`
/// set as given: `"sensor"` is a simulation that leaves the coil's lag out.
fn paper_at_1hz(temperature_node: &str) -> String {
    let text = PAPER_TOML
        .replace("sample_rate_hz = 1000.0", "sample_rate_hz = 1.0")
        .replace("temperature_node = \"coil\"", &format!("temperature_node = \"{temperature_node}\""));
    assert!(text.contains("sample_rate_hz = 1.0") && text.contains(temperature_node), "paper.toml changed");
    text
}

/// Simulates `toml` with `seed` into `dir/name` through the CLI and returns the folder.
fn simulate_dir(dir: &Path, name: &str, toml: &str, seed: u64) -> PathBuf {
    let scenario = dir.join(format!("{name}.toml"));
    fs::write(&scenario, toml).expect("write scenario");
    let out = dir.join(name);
    cal()
        .args(["simulate", "--scenario", s(&scenario), "--out", s(&out), "--seed", &seed.to_string()])
        .assert()
        .success();
    out
}

/// A recording whose coil lags the sensor, against a simulation without the lag (different
/// noise seeds): the command names `thermal_lag`, recovers a lag near the network's
/// effective sensor-to-coil lag, reports the contract keys and writes the report; the same
/// scenario against itself (another seed) names nothing.
#[test]
fn diagnose_names_a_left_out_lag_and_nothing_in_the_null_case() {
    let dir = TempDir::new().expect("tempdir");
    let simulated = simulate_dir(dir.path(), "sim", &paper_at_1hz("sensor"), 11);
    let recorded = simulate_dir(dir.path(), "rec", &paper_at_1hz("coil"), 12);
    let report = dir.path().join("report");
    let doc = run_json(&[
        "diagnose",
        "--simulated",
        s(&simulated),
        "--recorded",
        s(&recorded),
        "--json",
        "--report",
        s(&report),
    ]);
    let left_out = doc["left_out"].as_array().expect("left_out[]");
    let names: Vec<&str> = left_out.iter().filter_map(|e| e["effect"].as_str()).collect();
    assert_eq!(names.first(), Some(&"thermal_lag"), "named {names:?}\n{}", doc["summary"]);
    let lag = &left_out[0];
    for key in ["residual_before_dph", "residual_after_dph", "heldout_improvement"] {
        assert!(lag[key].as_f64().is_some_and(f64::is_finite), "{key} missing: {lag}");
    }
    assert!(lag["heldout_improvement"].as_f64().unwrap_or(0.0) > 0.0, "{lag}");
    // The case-to-coil network lag is (C_o + C_i) / G_co = 606 s and the sensor adds its own
    // 60 s the other way; accept the estimate within 4 reported standard errors of 546 s.
    let tau = &lag["parameters"]["tau_s"];
    let (value, se) =
        (tau["value"].as_f64().unwrap_or(f64::NAN), tau["std_error"].as_f64().unwrap_or(f64::NAN));
    assert!((value - 546.0).abs() <= 4.0 * se.max(30.0), "tau {value} +- {se} s");
    assert!(report.join("report.md").is_file(), "no report.md");
    // The text gives the fitted parameters beside the verdict, as --json has them.
    let text = run_ok(["diagnose", "--simulated", s(&simulated), "--recorded", s(&recorded)]);
    let fitted = text.split("Fitted (value +- standard error):\n").nth(1).expect("a Fitted block");
    assert!(fitted.contains("(statistical errors only, the spread over the runs"), "{text}");
    let lag_line = fitted.lines().next().unwrap_or_default();
    assert!(lag_line.starts_with("thermal_lag: "), "{text}");
    for (name, p) in lag["parameters"].as_object().expect("parameters") {
        assert!(lag_line.contains(&format!("{name} ")), "{name} missing: {lag_line}");
        if let Some(units) = p["units"].as_str() {
            assert!(lag_line.contains(units), "{units} missing: {lag_line}");
        }
    }
    let tau_text = lag_line.split("tau_s ").nth(1).and_then(|t| t.split(' ').next()).unwrap_or_default();
    let tau_read: f64 = tau_text.parse().unwrap_or(f64::NAN);
    assert!(
        (tau_read - value).abs() <= 0.01 * se.max(1.0) + 0.5,
        "tau {tau_text} in text, {value} in --json"
    );

    // The scenario updated with what was found, simulated again (another noise seed):
    // nothing is left out any more and the residual shrinks.
    let updated = fs::read_to_string(report.join("scenario-updated.toml")).expect("scenario-updated.toml");
    assert!(updated.contains("temperature_node = \"coil\""), "{updated}");
    let resimulated = simulate_dir(dir.path(), "sim-updated", &updated, 14);
    let again = run_json(&["diagnose", "--simulated", s(&resimulated), "--recorded", s(&recorded), "--json"]);
    assert_eq!(again["left_out"].as_array().map(Vec::len), Some(0), "{}", again["summary"]);
    let rms = |d: &Value| d["location"]["raw_residual_rms_dph"].as_f64().unwrap_or(f64::NAN);
    assert!(rms(&again) < rms(&doc), "residual RMS {} -> {}", rms(&doc), rms(&again));

    let null = simulate_dir(dir.path(), "rec-null", &paper_at_1hz("sensor"), 13);
    let doc = run_json(&["diagnose", "--simulated", s(&simulated), "--recorded", s(&null), "--json"]);
    assert_eq!(doc["left_out"].as_array().map(Vec::len), Some(0), "{}", doc["summary"]);
    // The text output: the verdict's lines first, then the full summary.
    let text = run_ok(["diagnose", "--simulated", s(&simulated), "--recorded", s(&null)]);
    let summary = doc["summary"].as_str().expect("summary");
    assert!(text.starts_with("Verdict: no catalogue effect is shown to be left out"), "{text}");
    assert!(text.contains(&format!("\n\nIn full: {summary}")), "{text}");
}

/// Runs are paired by file name: a recorded folder missing one run is refused, naming it.
#[test]
fn diagnose_refuses_unpaired_runs() {
    let dir = TempDir::new().expect("tempdir");
    let simulated = simulate_dir(dir.path(), "sim", &paper_at_1hz("coil"), 1);
    let recorded = dir.path().join("rec");
    fs::create_dir_all(&recorded).expect("mkdir");
    for name in ["pos1_-40C.csv", "pos1_-25C.csv"] {
        fs::copy(simulated.join(name), recorded.join(name)).expect("copy");
    }
    let err = run_err(["diagnose", "--simulated", s(&simulated), "--recorded", s(&recorded)]);
    assert!(err.contains("paired by file name") && err.contains("pos2_60C.csv"), "{err}");
    // The same folder for both sides, or a case folder holding both (review11 finding 9: its
    // runs.csv was read as a log), is refused before any log is read, saying what to give.
    let err = run_err(["diagnose", "--simulated", s(&simulated), "--recorded", s(&simulated)]);
    assert!(err.contains("--simulated and --recorded are the same path"), "{err}");
    let case = dir.path().join("case");
    fs::create_dir_all(case.join("simulated")).expect("mkdir");
    fs::create_dir_all(case.join("recorded")).expect("mkdir");
    let err = run_err(["diagnose", "--simulated", s(&case), "--recorded", s(&recorded)]);
    let want = format!(
        "give --simulated {} --recorded {}",
        case.join("simulated").display(),
        case.join("recorded").display()
    );
    assert!(err.contains("holds the folders simulated/ and recorded/") && err.contains(&want), "{err}");
}

/// One paired run: the mismatch is located, but nothing can be named (naming needs a run
/// held out of the fit); the command says so instead of failing or claiming "nothing left
/// out".
#[test]
fn diagnose_of_one_run_locates_but_names_nothing_and_says_why() {
    let dir = TempDir::new().expect("tempdir");
    let simulated = simulate_dir(dir.path(), "sim", &paper_at_1hz("sensor"), 21);
    let recorded = simulate_dir(dir.path(), "rec", &paper_at_1hz("coil"), 22);
    let (sim_log, rec_log) = (simulated.join("pos1_-40C.csv"), recorded.join("pos1_-40C.csv"));
    let doc = run_json(&["diagnose", "--simulated", s(&sim_log), "--recorded", s(&rec_log), "--json"]);
    assert_eq!(doc["left_out"].as_array().map(Vec::len), Some(0), "{doc}");
    let summary = doc["summary"].as_str().unwrap_or_default();
    assert!(
        summary.starts_with("ONE PAIRED RUN")
            && !summary.contains("No catalogue effect is shown to be left out"),
        "{summary}"
    );
    assert!(doc["location"]["spans"].as_array().is_some_and(|s| !s.is_empty()), "no spans located");
    // The verdict says nothing was tested (it used to head the output "no catalogue effect is
    // left out"), and the report's residual figure has the run's points (the in-sample offset
    // removed) and no NaN figures (review11 finding 7).
    let report = dir.path().join("report");
    let text =
        run_ok(["diagnose", "--simulated", s(&sim_log), "--recorded", s(&rec_log), "--report", s(&report)]);
    assert!(text.starts_with("Verdict: not tested: one paired run gives no held-out run"), "{text}");
    let before = &doc["traces"][0]["before_dph"];
    assert!(before.as_array().is_some_and(|b| !b.is_empty() && b.iter().all(Value::is_f64)), "{before}");
    let md = fs::read_to_string(report.join("report.md")).expect("report.md");
    assert!(!md.contains("NaN -> NaN") && md.contains("Whole model on held-out runs: not measured"), "{md}");
    // No NaN in prose and no count after a model that was not fitted (review22 F4).
    assert!(!md.contains("NaN deg/h"), "{md}");
    assert!(md.contains("After the model: not tested (one paired run: no model was fitted)."), "{md}");
    let svg = fs::read_to_string(report.join("residuals.svg")).expect("residuals.svg");
    assert!(svg.contains("<circle"), "no residual points drawn");
    assert!(svg.contains("no held-out prediction to draw"), "the title promises no line");
}

/// review27a 7: a scenario whose heater is 1e30 W drove the logged temperature to 1e22 C; the
/// logs were written, and `fit` stopped on them at their third line. Now `simulate` refuses it
/// naming the run, before any log is written.
#[test]
fn simulate_refuses_a_scenario_whose_logs_no_reader_takes() {
    let dir = TempDir::new().expect("tmp");
    let file = dir.path().join("hot.toml");
    fs::write(&file, SMALL.replace("power_w = 10.0", "power_w = 1e30")).expect("write scenario");
    let out = dir.path().join("out");
    let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&out), "--duration-s", "60"]);
    assert!(err.contains("run 'hold'") && err.contains("beyond what a sensor reads"), "{err}");
    assert!(!out.exists(), "nothing is written, not even the folder");
    // The sensor's offset counts too (review30b F1: 5000 C of offset passed the check).
    fs::write(&file, SMALL.replace("noise_c = 0.01", "noise_c = 0.01\noffset_c = 5000.0"))
        .expect("write scenario");
    let err = run_err(["simulate", "--scenario", s(&file), "--out", s(&out), "--duration-s", "60"]);
    assert!(
        err.contains("its sensor's offset included") && err.contains("beyond what a sensor reads"),
        "{err}"
    );
    assert!(!out.exists());
    // A file given for the folder is named as such (review27a 14.8: "File exists").
    let a_file = dir.path().join("a_file");
    fs::write(&a_file, "kept\n").expect("write");
    let err = run_err(["simulate", "--out", s(&a_file), "--rate", "1", "--duration-s", "60"]);
    assert!(err.contains("is a file: a simulation is written into a folder"), "{err}");
    assert_eq!(fs::read_to_string(&a_file).expect("read"), "kept\n");
}

/// Runs `fogtemp-cal args...`, requires success, returns (stdout, stderr).
fn run_ok_with_stderr(args: &[&str]) -> (String, String) {
    let out = cal().args(args).assert().success();
    let out = out.get_output();
    (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// DESIGN.md §3: without `--runs`, a fogtemp simulation's `manifest.json` gives `fit` and
/// `validate` each run's position and input rate (review27b F1: only `diagnose` read it).
/// Oracles: the same figures as an explicit runs file written from the manifest, and each
/// run's raw mean that of the same log without any metadata (a copy of the folder without
/// the manifest) less the manifest's input rate. A log the manifest does not list stops its
/// use, with a note saying why.
#[test]
fn fit_and_validate_read_a_simulations_manifest_as_run_metadata() {
    let dir = TempDir::new().expect("tmp");
    let file = dir.path().join("small.toml");
    fs::write(&file, SMALL).expect("write scenario");
    let sim = dir.path().join("sim");
    run_ok(["simulate", "--scenario", s(&file), "--out", s(&sim), "--duration-s", "300"]);
    let manifest: Value =
        serde_json::from_slice(&fs::read(sim.join("manifest.json")).expect("manifest")).expect("JSON");
    let rates: BTreeMap<String, f64> = manifest["runs"]
        .as_array()
        .expect("runs")
        .iter()
        .map(|r| (r["name"].as_str().expect("name").to_string(), r["input_rate_dph"].as_f64().expect("rate")))
        .collect();
    // The scenario's own runs have no group: each is a position of its own.
    let runs_csv = dir.path().join("runs.csv");
    let rows: String = rates.iter().map(|(name, rate)| format!("{name},{name},{rate:?}\n")).collect();
    fs::write(&runs_csv, format!("run,position,input_rate_dph\n{rows}")).expect("runs file");
    let bare = dir.path().join("bare");
    fs::create_dir(&bare).expect("folder");
    for name in NAMES {
        fs::copy(sim.join(format!("{name}.csv")), bare.join(format!("{name}.csv"))).expect("copy");
    }

    let fit = |extra: &[&str], out: &str| -> (Value, String) {
        let out = dir.path().join(out);
        let mut args = vec!["fit", "--method", "poly", "--out", s(&out), "--json"];
        args.extend_from_slice(extra);
        let (stdout, stderr) = run_ok_with_stderr(&args);
        (serde_json::from_str(&stdout).expect("fit --json"), stderr)
    };
    let (from_manifest, said) = fit(&[s(&sim)], "m.fogm");
    assert!(said.contains("manifest.json") && said.contains("subtracted"), "{said}");
    let (from_file, _) = fit(&[s(&sim), "--runs", s(&runs_csv)], "f.fogm");
    let (without, _) = fit(&[s(&bare)], "b.fogm");
    for key in ["residual_rms_dph", "points", "method"] {
        assert_eq!(from_manifest["axes"][0][key], from_file["axes"][0][key], "{key}");
    }
    // `fit --json` says which metadata it used (review30a F9).
    let used = &from_manifest["run_metadata"];
    assert!(used["source"].as_str().is_some_and(|s| s.ends_with("manifest.json")), "{used}");
    assert_eq!(used["positions"], serde_json::json!(["hold", "ramp", "step"]), "{used}");
    assert_eq!(used["input_rates_subtracted"], true, "{used}");
    let given: Vec<f64> = NAMES.iter().map(|n| rates[*n]).collect();
    assert_eq!(used["input_rates_dph"], serde_json::json!(given), "{used}");
    assert!(without["run_metadata"].is_null());
    // The runs differ by their input rates, which only the metadata takes out.
    let rms = |d: &Value| d["axes"][0]["residual_rms_dph"].as_f64().expect("residual");
    assert!(rms(&from_manifest) < rms(&without), "{} vs {}", rms(&from_manifest), rms(&without));

    let model = dir.path().join("m.fogm");
    let validate = |logs: &Path, extra: &[&str]| -> Value {
        let mut args = vec!["validate", "--model", s(&model), s(logs), "--json"];
        args.extend_from_slice(extra);
        run_json(&args)
    };
    let (v_manifest, v_file, v_bare) =
        (validate(&sim, &[]), validate(&sim, &["--runs", s(&runs_csv)]), validate(&bare, &[]));
    for ((m, f), b) in v_manifest["runs"]
        .as_array()
        .expect("runs")
        .iter()
        .zip(v_file["runs"].as_array().expect("runs"))
        .zip(v_bare["runs"].as_array().expect("runs"))
    {
        let name = m["path"].as_str().and_then(|p| Path::new(p).file_stem()).expect("path").to_string_lossy();
        let rate = rates[name.as_ref()];
        assert_eq!(m["input_rate_dph"].as_f64(), Some(rate), "{name}");
        assert_eq!(m["raw_mean_dph"], f["raw_mean_dph"], "{name}");
        assert!(b["input_rate_dph"].is_null(), "{name}");
        let (with, plain) =
            (m["raw_mean_dph"].as_f64().expect("mean"), b["raw_mean_dph"].as_f64().expect("mean"));
        assert!(
            (with - (plain - rate)).abs() <= 1e-9 * plain.abs().max(1.0),
            "{name}: {with} vs {plain} - {rate}"
        );
    }

    // A runs file wins over the manifest (review30a F10): one that says otherwise (rates 0, one
    // position) gives what it gives on the copy without a manifest, not the manifest's figures.
    let zero_csv = dir.path().join("zero.csv");
    let rows: String = NAMES.iter().map(|name| format!("{name},lab,0\n")).collect();
    fs::write(&zero_csv, format!("run,position,input_rate_dph\n{rows}")).expect("runs file");
    let (overridden, _) = fit(&[s(&sim), "--runs", s(&zero_csv)], "z.fogm");
    let (bare_zero, _) = fit(&[s(&bare), "--runs", s(&zero_csv)], "bz.fogm");
    assert_eq!(overridden["axes"][0]["residual_rms_dph"], bare_zero["axes"][0]["residual_rms_dph"]);
    assert_ne!(overridden["axes"][0]["residual_rms_dph"], from_manifest["axes"][0]["residual_rms_dph"]);
    let v_zero = validate(&sim, &["--runs", s(&zero_csv)]);
    assert!(v_zero["runs"].as_array().expect("runs").iter().all(|r| r["input_rate_dph"] == 0.0));

    // The model records that the rates were taken off (format 8), the same from the manifest
    // as from a runs file with its values; a model fitted without metadata records nothing,
    // and `validate` says when the record and the runs' metadata disagree (review30a F3).
    let read = |name: &str| fs::read(dir.path().join(name)).expect("model");
    assert!(read("m.fogm") == read("f.fogm"), "the manifest's model and the runs file's differ");
    let inspect = |name: &str| run_json(&["inspect", s(&dir.path().join(name)), "--json"]);
    let (with_rates, plain) = (inspect("m.fogm"), inspect("b.fogm"));
    assert_eq!(
        (&with_rates["format_version"], &with_rates["input_rates_subtracted"]),
        (&json!(8), &json!(true))
    );
    assert!(with_rates["log_shape"].is_null(), "the default shape written out is not a shape told");
    assert_eq!((&plain["format_version"], &plain["input_rates_subtracted"]), (&json!(6), &Value::Null));
    let notes = |v: &Value| -> String {
        v["notes"].as_array().expect("notes").iter().filter_map(Value::as_str).collect::<Vec<_>>().join("\n")
    };
    let (without_record, taken_off) =
        ("does not record whether its fit took", "input rate taken off its gyro");
    let agree = [notes(&v_manifest), notes(&v_file)];
    assert!(agree.iter().all(|n| !n.contains(without_record) && !n.contains(taken_off)), "{agree:?}");
    let no_rates_here = notes(&v_bare);
    assert!(no_rates_here.contains(taken_off) && no_rates_here.contains("--runs FILE"), "{no_rates_here}");
    let plain_on_sim = run_json(&["validate", "--model", s(&dir.path().join("b.fogm")), s(&sim), "--json"]);
    assert!(notes(&plain_on_sim).contains(without_record), "{}", notes(&plain_on_sim));
    // The report carries it too, under its own heading (review31a F6).
    let report = dir.path().join("plain-report");
    run_ok(["validate", "--model", s(&dir.path().join("b.fogm")), s(&sim), "--report", s(&report)]);
    let md = fs::read_to_string(report.join("report.md")).expect("report.md");
    let section = md.split("Run metadata (what the mean columns hold").nth(1).unwrap_or_default();
    assert!(section.split("\n\n").nth(1).is_some_and(|b| b.contains(without_record)), "{md}");
    let plain_on_bare = run_json(&["validate", "--model", s(&dir.path().join("b.fogm")), s(&bare), "--json"]);
    let quiet = notes(&plain_on_bare);
    assert!(!quiet.contains(without_record) && !quiet.contains(taken_off), "{quiet}");

    // A log the manifest does not list: no metadata, and a note says why.
    fs::copy(sim.join("hold.csv"), sim.join("recorded.csv")).expect("copy");
    let (listed, said) = fit(&[s(&sim)], "r.fogm");
    assert!(said.contains("is not used as run metadata") && said.contains("recorded.csv"), "{said}");
    assert!(!said.contains("subtracted"), "{said}");
    assert_eq!(listed["runs"].as_array().map(Vec::len), Some(4));
}

/// The manifest's groups are positions for `fit --method auto` (review30a F10): three groups
/// of two runs leave one group out at a time, each held-out run labelled with its group; a run
/// without a group makes every run a position of its own (review30a F2), so each run is its
/// own fold. (The runs are too short for a scored fold: only the folds are checked.)
#[test]
fn auto_leaves_out_the_manifests_groups() {
    let dir = TempDir::new().expect("tmp");
    let mut toml = SMALL.split("[[runs]]").next().expect("head").to_string();
    for (k, (group, axis)) in
        [("g1", "up"), ("g1", "up"), ("g2", "down"), ("g2", "down"), ("g3", "north"), ("g3", "north")]
            .into_iter()
            .enumerate()
    {
        let start_c = -10.0 + 10.0 * k as f64;
        toml.push_str(&format!(
            "[[runs]]\nname = \"r{k}\"\ngroup = \"{group}\"\nduration_s = 600.0\ninput_axis = \"{axis}\"\n\
             chamber = {{ kind = \"ramp\", start_c = {start_c:?}, end_c = {:?}, rate_c_per_min = 2.0, start_s = 60.0 }}\n\n",
            start_c + 15.0
        ));
    }
    let file = dir.path().join("groups.toml");
    fs::write(&file, &toml).expect("write scenario");
    let sim = dir.path().join("sim");
    run_ok(["simulate", "--scenario", s(&file), "--out", s(&sim)]);
    let out = dir.path().join("m.fogm");
    let (stdout, said) = run_ok_with_stderr(&["fit", s(&sim), "--out", s(&out), "--json"]);
    assert!(said.contains("(3 positions: g1, g2, g3)"), "{said}");
    let doc: Value = serde_json::from_str(&stdout).expect("fit --json");
    let groups = |doc: &Value| -> Vec<String> {
        let runs = doc["axes"][0]["selection"]["candidates"][0]["runs"].as_array().expect("runs[]").clone();
        runs.iter().map(|r| r["group"].as_str().expect("group").to_string()).collect()
    };
    assert_eq!(doc["axes"][0]["selection"]["grouping"], "positions");
    assert_eq!(groups(&doc), vec!["g1", "g1", "g2", "g2", "g3", "g3"]);

    // One run's group removed: every run its own position, one fold per run.
    let manifest = sim.join("manifest.json");
    let text = fs::read_to_string(&manifest).expect("manifest");
    let mut doc: Value = serde_json::from_str(&text).expect("JSON");
    doc["runs"][5]["group"] = Value::String(String::new());
    fs::write(&manifest, serde_json::to_string(&doc).expect("JSON")).expect("manifest");
    let (stdout, said) = run_ok_with_stderr(&["fit", s(&sim), "--out", s(&out), "--json"]);
    assert!(said.contains("run 'r5' has no group, so each run is a position of its own"), "{said}");
    let doc: Value = serde_json::from_str(&stdout).expect("fit --json");
    assert_eq!(groups(&doc), vec!["r0", "r1", "r2", "r3", "r4", "r5"]);
}
