//! `fit --method auto` (the default) and `--runs FILE` for `fit` and `validate`, end to end
//! through the binary: the `selection` JSON keys (docs/architecture.md, Contracts), the runs
//! file's roles and positions, and its errors naming the file and the line.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn cal(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_fogtemp-cal")).args(args).output().expect("runs the binary")
}

fn ok_json(args: &[&str]) -> Value {
    let out = cal(args);
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("one JSON document")
}

fn err_text(args: &[&str]) -> String {
    let out = cal(args);
    assert!(!out.status.success(), "{args:?} should fail");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Six 30-minute power-on runs at 2 Hz: temperature settling from `start` by `step` with a
/// 6 min time constant; gyro = 0.01 deg/h per C plus 0.3 deg/h per C/min plus a
/// deterministic pseudo-random +-0.02 deg/h (an LCG, so the test needs no generator).
fn write_runs(dir: &Path) -> Vec<PathBuf> {
    let mut state: u64 = 12345;
    let mut noise = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.04
    };
    let profiles = [(-20.0, 15.0), (-5.0, -10.0), (10.0, 20.0), (25.0, -15.0), (40.0, 10.0), (55.0, -20.0)];
    profiles
        .iter()
        .enumerate()
        .map(|(k, &(start_c, step_c))| {
            let mut csv = String::from("time_s,temp_c,gyro_dph\n");
            for i in 0..3600 {
                let t = f64::from(i) / 2.0;
                let decay = (-t / 360.0_f64).exp();
                let temp_c: f64 = start_c + step_c * (1.0 - decay);
                let rate_c_per_min = step_c * decay / 6.0;
                let gyro = 0.01 * temp_c + 0.3 * rate_c_per_min + noise();
                csv.push_str(&format!("{t:.1},{temp_c:.4},{gyro:.6}\n"));
            }
            let path = dir.join(format!("run{k}.csv"));
            std::fs::write(&path, csv).expect("write log");
            path
        })
        .collect()
}

fn strings(paths: &[PathBuf]) -> Vec<String> {
    paths.iter().map(|p| p.display().to_string()).collect()
}

#[test]
fn auto_is_the_default_and_reports_its_cross_validation() {
    let dir = tempfile::tempdir().expect("tempdir");
    let logs = strings(&write_runs(dir.path()));
    let model = dir.path().join("m.fogm").display().to_string();
    let mut args = vec!["fit", "--json", "--out", &model];
    args.extend(logs.iter().map(String::as_str));
    let doc = ok_json(&args);
    let selection = &doc["axes"][0]["selection"];
    let method = selection["method"].as_str().expect("selection.method");
    assert_eq!(doc["axes"][0]["method"], method);
    assert_eq!(selection["grouping"], "runs");
    // Held-out runs are scored inside the training runs' calibrated region (the default):
    // a fold whose run has fewer than 10 windows there is skipped and named.
    assert_eq!(selection["scoring"], "inside-region");
    assert_eq!(selection["correction"], "training-size");
    let folds = selection["folds"].as_u64().expect("folds");
    let skipped = selection["skipped_folds"].as_array().expect("skipped_folds[]");
    assert_eq!(folds as usize + skipped.len(), 6, "{selection}");
    assert!(folds >= 3, "{selection}");
    let candidates = selection["candidates"].as_array().expect("candidates[]");
    let names: Vec<&str> = candidates.iter().filter_map(|c| c["method"].as_str()).collect();
    assert_eq!(names, ["cubic-t", "poly", "mesh", "hybrid"]);
    assert!(names.contains(&method));
    for c in candidates {
        let cv = c["cv_bias_stability_dph"].as_f64().expect("cv_bias_stability_dph");
        assert!(cv > 0.0 && c["standard_error_dph"].as_f64().is_some(), "{c}");
        let runs = c["runs"].as_array().expect("runs[]");
        assert_eq!(runs.len(), 6);
        // With one run per fold, the cross-validated value is the mean of the scored runs'
        // values plus the training-size correction (the default; the mean of the per-fold
        // corrections over the folds scored); a skipped fold's run has none (null) and fewer
        // than 10 windows scored.
        let scored: Vec<f64> = runs.iter().filter_map(|r| r["bias_stability_dph"].as_f64()).collect();
        assert_eq!(scored.len() as u64, folds);
        let correction = c["training_size_correction_dph"].as_f64().expect("training_size_correction_dph");
        let mean = scored.iter().sum::<f64>() / scored.len() as f64 + correction;
        assert!((mean - cv).abs() <= 1e-12 * cv.max(1.0), "{mean} vs {cv}");
        for r in runs {
            let windows = r["windows_scored"].as_u64().expect("windows_scored");
            assert!(
                r["windows_outside_region"].as_u64().is_some() && r["whole_run_bias_stability_dph"].is_f64()
            );
            assert_eq!(r["bias_stability_dph"].is_f64(), windows >= 10, "{r}");
        }
        assert!(runs.iter().all(|r| r["run"].as_str().is_some_and(|n| n.starts_with("run"))));
    }
    // The text output prints the table.
    let mut text_args = vec!["fit", "--out", &model];
    text_args.extend(logs.iter().map(String::as_str));
    let text = cal(&text_args);
    let stdout = String::from_utf8_lossy(&text.stdout);
    assert!(stdout.contains("chosen by cross-validation") && stdout.contains("<- chosen"), "{stdout}");
    // The blob records the choice: `inspect` reads it back, in JSON and in text.
    let inspected = ok_json(&["inspect", "--json", &model]);
    let recorded = format!("{method}, chosen by leave-one-run-out cross-validation");
    assert_eq!(inspected["axes"][0]["provenance"]["selection"], recorded.as_str());
    let inspect_text = cal(&["inspect", &model]);
    let inspect_text = String::from_utf8_lossy(&inspect_text.stdout);
    assert!(inspect_text.contains(&format!("method: {recorded}")));
    // The text lists the polynomial's terms: read back, the coefficients of `--json` to the
    // 6 decimals printed, term by term (review15: only their count was shown).
    if let Some(terms) = inspected["axes"][0]["poly"].as_array() {
        let line =
            inspect_text.lines().find(|l| l.starts_with("  polynomial, deg/h: ")).expect("the terms line");
        let body =
            line.trim_start_matches("  polynomial, deg/h: ").split(" (x = ").next().unwrap_or_default();
        let signed = body.replace(" - ", " + -");
        let printed: Vec<f64> = signed
            .split(" + ")
            .map(|t| t.split(' ').next().unwrap_or_default().parse::<f64>().expect("a coefficient"))
            .collect();
        assert_eq!(printed.len(), terms.len(), "{line}");
        for (p, t) in printed.iter().zip(terms) {
            assert!((p - t["coefficient_dph"].as_f64().unwrap()).abs() <= 5e-7, "{line} vs {t}");
        }
    }
}

#[test]
fn runs_file_roles_and_positions_set_the_split_and_the_folds() {
    let dir = tempfile::tempdir().expect("tempdir");
    let logs = strings(&write_runs(dir.path()));
    let runs = dir.path().join("runs.csv");
    // Three positions over five calibration runs; run5 validates.
    std::fs::write(
        &runs,
        "run,position,input_rate_dph,role\nrun0,a,1,cal\nrun1,b,1,cal\nrun2,c,1,cal\nrun3,a,1,cal\nrun4,b,1,cal\nrun5,c,1,val\n",
    )
    .expect("write runs");
    let runs = runs.display().to_string();
    let model = dir.path().join("m.fogm").display().to_string();
    // Whole-run scoring (hidden option): in these runs, 15 C apart, holding a position out
    // leaves too little of its runs inside the others' region for the default scoring.
    let mut args = vec!["fit", "--json", "--out", &model, "--runs", &runs, "--cv-scoring", "whole-run"];
    args.extend(logs.iter().map(String::as_str));
    let doc = ok_json(&args);
    let read: Vec<&str> =
        doc["runs"].as_array().expect("runs[]").iter().filter_map(|r| r["path"].as_str()).collect();
    assert_eq!(read.len(), 5, "{read:?}");
    assert!(!read.iter().any(|p| p.ends_with("run5.csv")), "the val run is left out of the fit");
    let selection = &doc["axes"][0]["selection"];
    assert_eq!(selection["grouping"], "positions");
    assert_eq!(selection["folds"], 3);
    let held: Vec<(&str, &str)> = selection["candidates"][0]["runs"]
        .as_array()
        .expect("runs[]")
        .iter()
        .map(|r| (r["run"].as_str().unwrap_or(""), r["group"].as_str().unwrap_or("")))
        .collect();
    assert_eq!(held, [("run0", "a"), ("run3", "a"), ("run1", "b"), ("run4", "b"), ("run2", "c")]);

    let mut args = vec!["validate", "--json", "--model", &model, "--runs", &runs];
    args.extend(logs.iter().map(String::as_str));
    let doc = ok_json(&args);
    let validated: Vec<&str> =
        doc["runs"].as_array().expect("runs[]").iter().filter_map(|r| r["path"].as_str()).collect();
    assert_eq!(validated.len(), 1);
    assert!(validated[0].ends_with("run5.csv"));
}

#[test]
fn fewer_than_three_runs_warn_and_fit_the_default() {
    let dir = tempfile::tempdir().expect("tempdir");
    let logs = strings(&write_runs(dir.path()));
    let model = dir.path().join("m.fogm").display().to_string();
    let out = cal(&["fit", "--json", "--out", &model, &logs[0], &logs[1]]);
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    // Said once, by the identifiability warning; the selection's own warning stays in the JSON.
    assert!(stderr.contains("warning: axis 0: only 2 runs have calibration points"), "{stderr}");
    assert!(!stderr.contains("too few calibration runs"), "{stderr}");
    let doc: Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(doc["axes"][0]["selection"]["method"], "poly");
    assert!(doc["axes"][0]["selection"]["warning"].as_str().is_some());
}

#[test]
fn runs_file_problems_name_the_file_and_the_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    let logs = strings(&write_runs(dir.path()));
    let model = dir.path().join("m.fogm").display().to_string();
    let fit_ok = ok_json(&["fit", "--method", "poly", "--json", "--out", &model, &logs[0]]);
    assert!(fit_ok["axes"][0]["selection"].is_null(), "a given method has no selection");
    let cases = [
        (
            "dup.csv",
            "run,position,input_rate_dph\nrun0,a,1\nrun1,a,1\nrun0,b,1\n",
            "dup.csv:4: run 'run0' is listed twice",
        ),
        (
            "unknown.csv",
            "run,position,input_rate_dph\nrun0,a,1\nrun1,a,1\nrun9,a,1\n",
            "unknown.csv:4: run 'run9' has no log",
        ),
        ("missing.csv", "run,position,input_rate_dph\nrun0,a,1\n", "no row for the log"),
        (
            "role.csv",
            "run,position,input_rate_dph,role\nrun0,a,1,cal\nrun1,a,1,test\n",
            "role.csv:3: column 'role'",
        ),
    ];
    for (name, text, needle) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write");
        let path = path.display().to_string();
        let fit = err_text(&["fit", "--out", &model, "--runs", &path, &logs[0], &logs[1]]);
        assert!(fit.contains(needle), "fit {name}: {fit}");
        let val = err_text(&["validate", "--model", &model, "--runs", &path, &logs[0], &logs[1]]);
        assert!(val.contains(needle), "validate {name}: {val}");
    }
    let path = dir.path().join("allval.csv");
    std::fs::write(&path, "run,position,input_rate_dph,role\nrun0,a,1,val\n").expect("write");
    let path = path.display().to_string();
    let fit = err_text(&["fit", "--out", &model, "--runs", &path, &logs[0]]);
    assert!(fit.contains("allval.csv: every run has role 'val'"), "{fit}");
}

/// One runs file serves `fit` given only its `cal` logs and `validate` given only its `val`
/// logs (review13 F13): the same model and the same validation as when both get every log;
/// with roles, a row without one is refused (review15 F6).
#[test]
fn one_runs_file_serves_fit_and_validate_each_given_its_own_logs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let logs = strings(&write_runs(dir.path()));
    let runs = dir.path().join("runs.csv");
    let roles = ["cal", "cal", "cal", "cal", "val", "val"];
    let rows: Vec<String> = roles.iter().enumerate().map(|(k, role)| format!("run{k},a,0,{role}")).collect();
    std::fs::write(&runs, format!("run,position,input_rate_dph,role\n{}\n", rows.join("\n"))).expect("write");
    let runs = runs.display().to_string();
    let fit = |model: &str, logs: &[String]| {
        let mut args = vec!["fit", "--method", "poly", "--out", model, "--runs", runs.as_str()];
        args.extend(logs.iter().map(String::as_str));
        let out = cal(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    let (whole, own) = (dir.path().join("whole.fogm"), dir.path().join("own.fogm"));
    let (whole, own) = (whole.display().to_string(), own.display().to_string());
    fit(&whole, &logs);
    fit(&own, &logs[..4]);
    let (a, b) = (ok_json(&["inspect", "--json", &whole]), ok_json(&["inspect", "--json", &own]));
    assert_eq!(a["axes"], b["axes"], "the same fit from the cal logs alone");
    let validate = |logs: &[String]| {
        let mut args = vec!["validate", "--json", "--model", own.as_str(), "--runs", runs.as_str()];
        args.extend(logs.iter().map(String::as_str));
        ok_json(&args)
    };
    let (all, val) = (validate(&logs), validate(&logs[4..]));
    assert_eq!(all["runs"], val["runs"], "the same two val runs validated");
    assert_eq!(val["runs"].as_array().map(Vec::len), Some(2));
    // With roles, a row without one is refused by name and line (neither command's).
    let plain = dir.path().join("plain.csv");
    std::fs::write(
        &plain,
        "run,position,input_rate_dph,role\nrun0,a,0,cal\nrun1,a,0,cal\nrun2,a,0,cal\nrun5,a,0,\n",
    )
    .expect("write");
    let plain = plain.display().to_string();
    let err = err_text(&["fit", "--out", &own, "--runs", &plain, &logs[0], &logs[1], &logs[2], &logs[5]]);
    assert!(err.contains("plain.csv:5: run 'run5' has no role while other rows give one"), "{err}");
    let err = err_text(&["validate", "--model", &own, "--runs", &plain, &logs[5]]);
    assert!(err.contains("plain.csv:5: run 'run5' has no role while other rows give one"), "{err}");
}

/// `fit --poly-outside`: the policy is stored in the model (`inspect --json`); inside the
/// calibrated region both policies give the same value bit for bit; far outside it the
/// extrapolated polynomial equals an f64 evaluation of its own coefficients at the query,
/// while the held one stays within the values the data can give (|0.01 T| <= 0.55 and
/// |0.3 dT/dt| <= 0.3 x 20/6 over the runs' ranges, plus the noise and fit error, 0.1) and is
/// flagged OUTSIDE_HULL.
#[test]
fn poly_outside_hold_stays_within_the_calibrated_values() {
    let dir = tempfile::tempdir().expect("tempdir");
    let logs = strings(&write_runs(dir.path()));
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "temp_c,rate_c_per_min\n20,0\n20,50\n").expect("write points");
    let points = points.display().to_string();
    let (mut evaluated, mut reference) = (Vec::new(), f64::NAN);
    for policy in ["extrapolate", "hold-at-boundary"] {
        let model = dir.path().join(format!("{policy}.fogm")).display().to_string();
        let mut args = vec!["fit", "--method", "poly", "--poly-outside", policy, "--out", &model];
        args.extend(logs.iter().map(String::as_str));
        let fit = cal(&args);
        assert!(fit.status.success(), "{}", String::from_utf8_lossy(&fit.stderr));
        let inspect = ok_json(&["inspect", "--json", &model]);
        assert_eq!(inspect["axes"][0]["poly_outside"], policy.replace('-', "_").as_str(), "{inspect}");
        if policy == "extrapolate" {
            reference = poly_reference(&inspect["axes"][0], 20.0, 50.0);
        }
        evaluated.push(evaluate_rows(&model, &points));
    }
    let (extrapolated, held) = (&evaluated[0], &evaluated[1]);
    assert_eq!(extrapolated[0], held[0], "inside the region both policies agree");
    let value = |row: &[String]| row[2].parse::<f64>().expect("value_dph");
    let tolerance_dph = 1e-5 * reference.abs().max(1.0);
    assert!((value(&extrapolated[1]) - reference).abs() <= tolerance_dph, "{extrapolated:?} vs {reference}");
    assert!(value(&held[1]).abs() <= 0.55 + 0.3 * 20.0 / 6.0 + 0.1, "{held:?}");
    let outside_hull =
        |row: &[String]| row[3].parse::<u8>().expect("flags") & fogtemp_core::Flags::OUTSIDE_HULL.0 != 0;
    assert!(outside_hull(&held[1]) && !outside_hull(&extrapolated[1]), "{held:?} {extrapolated:?}");
}

/// The polynomial of an `inspect --json` axis at (temp_c, rate_c_per_min), in f64.
fn poly_reference(axis: &Value, temp_c: f64, rate_c_per_min: f64) -> f64 {
    let n = &axis["normalisation"];
    let f = |key: &str| n[key].as_f64().expect("normalisation field");
    let x = (temp_c - f("temp_offset_c")) * f("temp_scale_per_c");
    let y = (rate_c_per_min - f("rate_offset_c_per_min")) * f("rate_scale_per_c_per_min");
    let terms = axis["poly"].as_array().expect("poly terms");
    terms
        .iter()
        .map(|t| {
            let power = |key: &str| t[key].as_i64().expect("power") as i32;
            t["coefficient_dph"].as_f64().expect("coefficient")
                * x.powi(power("temp_power"))
                * y.powi(power("rate_power"))
        })
        .sum()
}

#[test]
fn the_rule_scale_and_the_runs_and_blocks_scheme_are_options() {
    let dir = tempfile::tempdir().expect("tempdir");
    let logs = strings(&write_runs(dir.path()));
    let model = dir.path().join("m.fogm").display().to_string();
    let mut args =
        vec!["fit", "--json", "--out", &model, "--cv-scheme", "runs-and-blocks", "--cv-rule-scale", "log"];
    args.extend(logs.iter().map(String::as_str));
    let doc = ok_json(&args);
    let selection = &doc["axes"][0]["selection"];
    assert_eq!(
        (selection["scheme"].as_str(), selection["scale"].as_str()),
        (Some("runs-and-blocks"), Some("log"))
    );
    assert!(selection["rule"].as_str().is_some_and(|r| r.contains("log ratio")), "{selection}");
    for c in selection["candidates"].as_array().expect("candidates[]") {
        for r in c["runs"].as_array().expect("runs[]") {
            // Every run has its blocked score; its score is the geometric mean of the two
            // (or the blocked one alone when it has no left-out score).
            let blocked = r["blocked_bias_stability_dph"].as_f64().expect("blocked score");
            let score = r["bias_stability_dph"].as_f64().expect("score");
            let expected =
                r["left_out_bias_stability_dph"].as_f64().map_or(blocked, |l| (l * blocked).sqrt());
            assert!((score - expected).abs() <= 1e-12 * expected, "{r}");
        }
    }
    // The default is leave-one-run-out on the deg/h scale.
    let mut args = vec!["fit", "--json", "--out", &model];
    args.extend(logs.iter().map(String::as_str));
    let selection = &ok_json(&args)["axes"][0]["selection"];
    assert_eq!(
        (selection["scheme"].as_str(), selection["scale"].as_str()),
        (Some("leave-one-group-out"), Some("deg-per-hour"))
    );
}

/// `fit --mesh-outside` stores the mesh's policy, `inspect` names it, and it acts only outside
/// the hull: inside, hold and linear give the same value bit for bit; far outside (50 C/min,
/// beyond every run) both are flagged OUTSIDE_HULL and the linear one differs from the held
/// hull value. The values themselves are checked against closed forms and an f64 reference in
/// tests/mesh_beyond_hull.rs.
/// `fogtemp-cal evaluate --model MODEL --points POINTS`: its CSV rows after the header.
fn evaluate_rows(model: &str, points: &str) -> Vec<Vec<String>> {
    let out = cal(&["evaluate", "--model", model, "--points", points]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect()
}

#[test]
fn mesh_outside_is_stored_named_and_acts_only_outside_the_hull() {
    let dir = tempfile::tempdir().expect("tempdir");
    let logs = strings(&write_runs(dir.path()));
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "temp_c,rate_c_per_min\n20,0\n20,50\n").expect("write points");
    let points = points.display().to_string();
    let mut evaluated = Vec::new();
    // The default (no flag) is the continuation with stored gradients.
    for (policy, stored) in [
        ("hold", "nearest_hull"),
        ("linear-from-boundary", "linear_from_boundary"),
        ("", "linear_stored_gradients"),
        ("linear-stored-gradients", "linear_stored_gradients"),
    ] {
        let model = dir.path().join(format!("{policy}.fogm")).display().to_string();
        let mut args = vec!["fit", "--method", "mesh", "--out", &model];
        if !policy.is_empty() {
            args.extend(["--mesh-outside", policy]);
        }
        args.extend(logs.iter().map(String::as_str));
        let fit = cal(&args);
        assert!(fit.status.success(), "{}", String::from_utf8_lossy(&fit.stderr));
        let inspect = ok_json(&["inspect", "--json", &model]);
        assert_eq!(inspect["axes"][0]["outside_policy"], stored, "{inspect}");
        evaluated.push(evaluate_rows(&model, &points));
    }
    let (held, linear) = (&evaluated[0], &evaluated[1]);
    let outside_hull =
        |row: &[String]| row[3].parse::<u8>().expect("flags") & fogtemp_core::Flags::OUTSIDE_HULL.0 != 0;
    assert_eq!(held[0], linear[0], "inside the hull both policies agree");
    assert!(!outside_hull(&held[0]), "{held:?}");
    assert!(outside_hull(&held[1]) && outside_hull(&linear[1]), "{held:?} {linear:?}");
    assert_ne!(held[1][2], linear[1][2], "beyond the hull the continuation moves the value");
    let (default, stored) = (&evaluated[2], &evaluated[3]);
    assert_eq!(default, stored, "the default is linear-stored-gradients");
    assert_eq!(held[0], stored[0], "inside the hull the stored-gradient policy agrees");
    assert!(outside_hull(&stored[1]), "{stored:?}");
    assert_ne!(held[1][2], stored[1][2], "beyond the hull the stored continuation moves the value");
}
