//! Real lab log shapes through the command: serial captures (a banner, no header, no time
//! column, 50 Hz, one row cut short) calibrated and validated end to end, the shape flags on
//! every command that reads logs, and the errors.
//!
//! The captures are generated here from a known formula (the oracle): a warm-up
//! T(t) = T0 + 15 (1 - exp(-t / 600 s)) and a gyro that reads exactly its bias
//! b = 0.5 (T - 20) deg/h (printed to 6 decimals, T to 4).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

const RATE_HZ: f64 = 50.0;
/// 30 minutes at 50 Hz.
const RECORDS: usize = 90_000;

fn bias_dph(temp_c: f64) -> f64 {
    0.5 * (temp_c - 20.0)
}

fn temp_c(start_c: f64, t_s: f64) -> f64 {
    start_c + 15.0 * (1.0 - (-t_s / 600.0).exp())
}

/// Writes a capture: banner on line 1, then `gyro_dph temp_c` per line (whitespace), record
/// `cut` without its temperature (record k is on line k + 2).
fn write_capture(dir: &Path, name: &str, start_c: f64, cut: usize) -> PathBuf {
    let mut text = String::from("Tera Term VT: COM3 115200 baud, 8N1, log started 2026-11-24 10:00:00\n");
    for k in 0..RECORDS {
        let temp = temp_c(start_c, k as f64 / RATE_HZ);
        if k == cut {
            text.push_str(&format!("{:.6}\n", bias_dph(temp)));
        } else {
            text.push_str(&format!("{:.6}   {temp:.4}\n", bias_dph(temp)));
        }
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

const SHAPE: [&str; 6] = ["--skip-lines", "1", "--columns", "gyro_dph,temp_c", "--sample-rate-hz", "50"];

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_fogtemp-cal")).args(args).output().unwrap()
}

fn ok_json(args: &[&str]) -> (Value, String) {
    let out = run(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{args:?} failed: {stderr}");
    (serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{e}: {stderr}")), stderr)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn serial_captures_fit_and_validate_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let cal: Vec<PathBuf> = [(0.0, 7_000), (20.0, 45_000), (40.0, RECORDS - 1)]
        .iter()
        .enumerate()
        .map(|(i, &(start, cut))| write_capture(dir.path(), &format!("cal{i}.txt"), start, cut))
        .collect();
    let val: Vec<PathBuf> = [(10.0, 30_000), (30.0, 60_000)]
        .iter()
        .enumerate()
        .map(|(i, &(start, cut))| write_capture(dir.path(), &format!("val{i}.txt"), start, cut))
        .collect();
    let model = dir.path().join("capture.fogm");

    // Without --skip-bad-rows the cut row stops the fit at its real line and column.
    let mut args = vec!["fit", "--method", "poly", "--out", s(&model)];
    args.extend(SHAPE);
    args.extend(cal.iter().map(|p| s(p)));
    let out = run(&args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains(&format!(
            "{}:7002:2: column 'temp_c': fewer fields than the header (or the names given for a headerless log) in a log whose \
             columns are separated by spaces: a row cut short, or a blank cell, which vanishes there",
            cal[0].display()
        )) && stderr.contains("--skip-bad-rows"),
        "{stderr}"
    );
    assert!(!model.exists());

    // With it: each run lists its one skipped row; the warnings come from the points.
    args.extend(["--skip-bad-rows", "--json"]);
    let (fit, stderr) = ok_json(&args);
    for (i, line) in [7_002, 45_002, RECORDS as u64 + 1].iter().enumerate() {
        let run = &fit["runs"][i];
        assert_eq!((run["rows"].as_u64(), run["skipped_rows"].as_u64()), (Some(RECORDS as u64 - 1), Some(1)));
        assert_eq!(run["first_skipped"][0]["line"].as_u64(), Some(*line), "{run}");
        assert_eq!(run["first_skipped"][0]["column_name"], "temp_c");
    }
    assert!(stderr.contains("skipped 1 bad row "), "{stderr}");
    // Warm-ups only heat (dT/dt >= 0 by construction, up to 1.5 C/min): heating_only, and
    // nothing about runs (3) or range (0 to 54 C).
    let kinds: Vec<&str> =
        fit["warnings"].as_array().unwrap().iter().map(|w| w["kind"].as_str().unwrap()).collect();
    assert!(kinds.contains(&"heating_only"), "{kinds:?}");
    assert!(!kinds.contains(&"too_few_runs") && !kinds.contains(&"narrow_temperature_range"), "{kinds:?}");
    assert!(stderr.contains("warning: axis 0: the calibration only heats"), "{stderr}");

    // Time from the sample rate: the calibrated rates are in C/min only if the 50 Hz rows
    // are 20 ms apart (the warm-up's rate is 15/10 = 1.5 C/min at the start, 0.075 at 30 min;
    // a 1 Hz reading would give 50 times less).
    let (inspect, _) = ok_json(&["inspect", "--json", s(&model)]);
    let provenance = &inspect["axes"][0]["provenance"];
    let rate_max = provenance["rate_max_c_per_min"].as_f64().unwrap();
    assert!((1.0..=1.5).contains(&rate_max), "{provenance}");
    let (temp_min, temp_max) =
        (provenance["temp_min_c"].as_f64().unwrap(), provenance["temp_max_c"].as_f64().unwrap());
    // The range is that of the full-window features (the calibrated region's points): from
    // one 100 s window into the coldest warm-up, T(100 s) = 15 (1 - e^(-1/6)) = 2.30 C; within
    // 0.2 C (the tracker's line through the window's block means, read at its end).
    let first_full_c = temp_c(0.0, 100.0);
    assert!((temp_min - first_full_c).abs() < 0.2 && temp_max > 54.0, "{provenance}");

    // A stated operating range the calibration does not cover: the uncovered degrees.
    let mut args =
        vec!["fit", "--method", "poly", "--skip-bad-rows", "--json", "--operating-temp-c", "-10,60"];
    let other = dir.path().join("other.fogm");
    args.extend(["--out", s(&other)]);
    args.extend(SHAPE);
    args.extend(cal.iter().map(|p| s(p)));
    let (ranged, _) = ok_json(&args);
    let narrow: Vec<&Value> = ranged["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|w| w["kind"] == "narrow_temperature_range")
        .collect();
    assert_eq!(narrow.len(), 1, "{ranged}");
    let uncovered = narrow[0]["values"]["uncovered_c"].as_f64().unwrap();
    // The provenance holds the same range in f32.
    assert!((uncovered - ((temp_min + 10.0) + (60.0 - temp_max))).abs() < 1e-4, "{uncovered}");

    // The model against the oracle along the calibrated warm-ups (from 5 min, once the
    // feature window has filled): within 0.05 deg/h, 0.2 % of the 27 deg/h the bias spans
    // (what remains is the causal tracker's lag against the centred targets).
    let grid = dir.path().join("grid.csv");
    let mut points = String::from("temp_c,rate_c_per_min\n");
    let mut truth = Vec::new();
    for start in [0.0, 20.0, 40.0] {
        for minute in 5..30 {
            let temp = temp_c(start, 60.0 * f64::from(minute));
            let rate = (start + 15.0 - temp) / 10.0;
            points.push_str(&format!("{temp},{rate}\n"));
            truth.push(bias_dph(temp));
        }
    }
    std::fs::write(&grid, points).unwrap();
    let out = run(&["evaluate", "--model", s(&model), "--points", s(&grid)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let values: Vec<f64> =
        text.lines().skip(1).map(|l| l.split(',').nth(2).unwrap().parse().unwrap()).collect();
    assert_eq!(values.len(), truth.len());
    let worst = values.iter().zip(&truth).map(|(v, t)| (v - t).abs()).fold(0.0, f64::max);
    assert!(worst < 0.05, "worst model error {worst} deg/h");

    // Validation on two other captures (warm-ups from 10 and 30 C, one row cut short each).
    let mut args = vec!["validate", "--json", "--skip-bad-rows", "--model", s(&model)];
    args.extend(SHAPE);
    args.extend(val.iter().map(|p| s(p)));
    let (validation, _) = ok_json(&args);
    // Oracle for raw: the sample standard deviation of 100 s means of b(T(t)) over the
    // run (from its start; the metric may leave out the compensator's first window, which
    // moves it by a few per cent; 1.7 % here), RMS over the two runs. Tolerance 15 %.
    let raw_oracle = {
        let per_run: Vec<f64> = [10.0, 30.0]
            .iter()
            .map(|&start| {
                let means: Vec<f64> = (0..18)
                    .map(|w| {
                        (0..5000)
                            .map(|k| bias_dph(temp_c(start, (w * 5000 + k) as f64 / RATE_HZ)))
                            .sum::<f64>()
                            / 5000.0
                    })
                    .collect();
                let mean = means.iter().sum::<f64>() / means.len() as f64;
                (means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (means.len() - 1) as f64).sqrt()
            })
            .collect();
        (per_run.iter().map(|v| v * v).sum::<f64>() / 2.0).sqrt()
    };
    let raw = validation["raw_bias_stability_dph"].as_f64().unwrap();
    let compensated = validation["compensated_bias_stability_dph"].as_f64().unwrap();
    assert!((raw / raw_oracle - 1.0).abs() < 0.15, "raw {raw} vs oracle {raw_oracle}");
    // Compensated: the model removes the drift to within its 0.05 deg/h error above.
    assert!(compensated < 0.05, "compensated {compensated} (raw {raw})");
    for run in validation["runs"].as_array().unwrap() {
        assert_eq!(run["skipped_rows"].as_u64(), Some(1), "{run}");
    }
}

#[test]
fn shape_flags_reach_compensate_and_allan() {
    let dir = tempfile::tempdir().unwrap();
    // A semicolon log with comments and a banner of two lines, time in ms.
    let log = dir.path().join("semi.csv");
    let mut text = String::from("logger v2 \"boot\"\nchannels: 3\n# header next\ntime (ms);temp;gyro\n");
    for k in 0..20_000 {
        if k % 1000 == 0 {
            text.push_str("# marker\n");
        }
        text.push_str(&format!("{};{:.3};{:.4}\n", 10 * k, 20.0 + k as f64 * 1e-4, (k % 7) as f64 * 0.01));
    }
    std::fs::write(&log, &text).unwrap();
    let flags =
        ["--skip-lines", "2", "--time-column", "time (ms)", "--time-unit", "ms", "--temp-column", "temp"];
    let mut args = vec!["allan", "--json", "--gyro-column", "gyro", s(&log)];
    args.extend(flags);
    let (allan, _) = ok_json(&args);
    assert!(allan.is_object(), "{allan}");

    // A model from the library defaults is enough to see compensate read the shape.
    let capture = write_capture(dir.path(), "cap.txt", 0.0, 100);
    let model = dir.path().join("m.fogm");
    let mut fit = vec!["fit", "--method", "cubic-t", "--skip-bad-rows", "--out", s(&model)];
    fit.extend(SHAPE);
    fit.push(s(&capture));
    let out = run(&fit);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let compensated = dir.path().join("comp.csv");
    let mut args = vec!["compensate", "--skip-bad-rows", "--model", s(&model), "--out", s(&compensated)];
    args.extend(SHAPE);
    args.push(s(&capture));
    let out = run(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let written = std::fs::read_to_string(&compensated).unwrap();
    let times: Vec<f64> =
        written.lines().skip(1).map(|l| l.split(',').next().unwrap().parse().unwrap()).collect();
    // 89,999 rows; record 100 (cut short) missing, so its neighbours are 40 ms apart.
    assert_eq!(times.len(), RECORDS - 1);
    assert_eq!((times[0], times[99], times[100]), (0.0, 99.0 / 50.0, 101.0 / 50.0));
}

#[test]
fn ambiguous_or_malformed_shapes_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("log.csv");
    std::fs::write(&log, "time_s,temp_c,gyro_dph\n0,20,1\n1,20,1\n").unwrap();
    let model = dir.path().join("m.fogm");
    // A time column named on the command line and a rate: refused by the parser.
    let out = run(&["fit", "--out", s(&model), "--time-column", "t", "--sample-rate-hz", "50", s(&log)]);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot be used with"));
    // The log has the (default) time column and a rate is given: refused with the line.
    let out = run(&["fit", "--out", s(&model), "--sample-rate-hz", "50", s(&log)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains(&format!("{}:1: ambiguous time", log.display())),
        "{stderr}"
    );
    // A headerless log read as if it had a header.
    std::fs::write(&log, "0,20,1\n1,20,1\n").unwrap();
    let out = run(&["fit", "--out", s(&model), s(&log)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains(":1: this line was read as the header but every cell is a number"), "{stderr}");
    assert!(stderr.contains("; see --skip-lines, --columns, --sample-rate-hz"), "{stderr}");
    // Bad values for the shape flags.
    for (bad, says) in [
        (vec!["--sample-rate-hz", "0"], "positive number of Hz"),
        (vec!["--comment", "1"], "comment prefix"),
        (vec!["--delimiter", "pipe-ish"], "expected auto, comma"),
        (vec!["--columns", "a,,b"], "column name is empty"),
    ] {
        let mut args = vec!["fit", "--out", s(&model)];
        args.extend(bad.iter().copied());
        args.push(s(&log));
        let out = run(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(says), "{bad:?}: {stderr}");
        assert!(!model.exists());
    }
}

/// A log of a European locale's spreadsheet export: semicolons and decimal commas, 1 Hz.
fn write_locale_log(path: &Path, start_c: f64, decimal_comma: bool) {
    let mut text = String::from("time_s;temp_c;gyro_dph\n");
    for k in 0..3600 {
        let temp = temp_c(start_c, f64::from(k));
        let row = format!("{k}.0;{temp:.4};{:.6}\n", bias_dph(temp));
        text.push_str(&if decimal_comma { row.replace('.', ",") } else { row });
    }
    std::fs::write(path, text).unwrap();
}

/// Two folders of three warm-ups from 0, 20 and 40 C: `write(path, start_c, true)` for the
/// shape under test, `write(path, start_c, false)` for its plain twin (the oracle).
fn twin_folders(dir: &Path, write: fn(&Path, f64, bool)) -> (PathBuf, PathBuf) {
    let (shaped, plain) = (dir.join("shaped"), dir.join("plain"));
    for (folder, shaped) in [(&shaped, true), (&plain, false)] {
        std::fs::create_dir(folder).unwrap();
        for (i, start) in [0.0, 20.0, 40.0].into_iter().enumerate() {
            write(&folder.join(format!("run{i}.csv")), start, shaped);
        }
    }
    (shaped, plain)
}

/// What `inspect --json` says a model stores, without the digest of its input bytes (which
/// differ between twins) and its path.
fn stored_model(model: &Path) -> Value {
    let (mut doc, _) = ok_json(&["inspect", "--json", s(model)]);
    assert!(doc["input_digest"].take().is_string(), "{doc}");
    doc["model"].take();
    // How the time was read differs between twins by design (recorded since format 5), and
    // how the numbers were read and the logs' digests (format 6).
    assert!(doc["log_time"].take().is_object(), "{doc}");
    assert!(doc["log_reading"].take().is_object(), "{doc}");
    doc
}

/// The decimal mark a model records (`inspect --json`).
fn recorded_decimal_mark(model: &Path) -> Value {
    let (doc, _) = ok_json(&["inspect", "--json", s(model)]);
    doc["log_reading"]["decimal_mark"].clone()
}

#[test]
fn decimal_comma_logs_fit_the_same_model_as_their_point_twins() {
    let dir = tempfile::tempdir().unwrap();
    let (commas, points) = twin_folders(dir.path(), write_locale_log);
    // Without the flag: the first cell is refused, and the error says what to pass.
    let model = dir.path().join("m.fogm");
    let out = run(&["fit", "--method", "poly", "--out", s(&model), s(&commas)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && !model.exists(), "{stderr}");
    assert!(stderr.contains("run0.csv:2:1: column 'time_s': not a number (found '0,0')"), "{stderr}");
    assert!(stderr.contains("use --decimal-mark comma"), "{stderr}");
    // With it: the model of the same numbers written with points (the oracle), every stored
    // value equal; only the digest of the input bytes differs.
    let twin = dir.path().join("twin.fogm");
    let out = run(&["fit", "--method", "poly", "--decimal-mark", "comma", "--out", s(&model), s(&commas)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = run(&["fit", "--method", "poly", "--out", s(&twin), s(&points)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let fitted = stored_model(&model);
    assert_eq!(fitted["axes"][0]["kind"][0], "poly", "{fitted}");
    assert_eq!(fitted, stored_model(&twin));
    assert_eq!(
        (recorded_decimal_mark(&model), recorded_decimal_mark(&twin)),
        ("comma".into(), "point".into())
    );
    // validate reads the logs as the model records (format 6): the comma logs without the
    // flag give the figures of the point twins with theirs, with a note; naming a point is
    // said to differ (and refused at the first cell).
    let validated = |m: &Path, logs: &Path, flag: &[&str]| {
        let mut args = vec!["validate", "--json", "--model", s(m)];
        args.extend(flag);
        args.push(s(logs));
        run(&args)
    };
    let out = validated(&model, &commas, &[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && stderr.contains("read with a decimal comma, as"), "{stderr}");
    let figures = |out: &Output| {
        let doc: Value = serde_json::from_slice(&out.stdout).unwrap();
        (doc["raw_bias_stability_dph"].clone(), doc["compensated_bias_stability_dph"].clone())
    };
    assert_eq!(figures(&out), figures(&validated(&twin, &points, &[])));
    let out = validated(&model, &commas, &["--decimal-mark", "point"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("was fitted on logs with a decimal comma; these are read with a decimal point"),
        "{stderr}"
    );
    // evaluate reads a grid with the model's decimal comma too (review13 F11): the values of
    // the point grid under the point twin, with a note; a point grid is told the flag.
    let (comma_grid, point_grid) = (dir.path().join("grid_comma.csv"), dir.path().join("grid.csv"));
    std::fs::write(&comma_grid, "temp_c;rate_c_per_min\n25,5;0,1\n40;-0,25\n").unwrap();
    std::fs::write(&point_grid, "temp_c,rate_c_per_min\n25.5,0.1\n40,-0.25\n").unwrap();
    let out = run(&["evaluate", "--model", s(&model), "--points", s(&comma_grid)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stderr.contains("grid_comma.csv: read with a decimal comma, as"),
        "{stderr}"
    );
    let twin_values = run(&["evaluate", "--model", s(&twin), "--points", s(&point_grid)]);
    assert_eq!(out.stdout, twin_values.stdout, "the same points, the same stored model: the same output");
    let out = run(&["evaluate", "--model", s(&model), "--points", s(&point_grid)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("grid.csv:2:1: column 'temp_c'"), "{stderr}");
    assert!(stderr.contains("use --decimal-mark point"), "{stderr}");
    let out = run(&["evaluate", "--decimal-mark", "point", "--model", s(&model), "--points", s(&point_grid)]);
    assert_eq!(out.stdout, twin_values.stdout, "{}", String::from_utf8_lossy(&out.stderr));
    // The flag on a log with points names the cell and the way back.
    let out = run(&["allan", "--decimal-mark", "comma", s(&points.join("run0.csv"))]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("run0.csv:2:1: column 'time_s': a point in a log read with a decimal comma"),
        "{stderr}"
    );
    assert!(stderr.contains("the log writes decimal points? give --decimal-mark point"), "{stderr}");
}

/// A logger's run with ISO 8601 date-times (1 Hz from `start` local time at +01:00), or the
/// same run with seconds from its first row.
/// A 1 Hz warm-up of an hour from `start_c`, its time column `time_header` written by
/// `time_of(k)` for the k-th second.
fn write_timed_log(path: &Path, start_c: f64, time_header: &str, time_of: impl Fn(u32) -> String) {
    let mut text = format!("{time_header},temp_c,gyro_dph\n");
    for k in 0..3600u32 {
        let temp = temp_c(start_c, f64::from(k));
        text.push_str(&format!("{},{temp:.4},{:.6}\n", time_of(k), bias_dph(temp)));
    }
    std::fs::write(path, text).unwrap();
}

fn write_datetime_log(path: &Path, start_c: f64, datetime: bool) {
    write_timed_log(path, start_c, "time_s", |k| {
        if datetime {
            // 2026-11-24 23:30:00 +01:00 onwards: the run crosses midnight.
            let s = 23 * 3600 + 30 * 60 + k;
            let (day, s) = (24 + s / 86_400, s % 86_400);
            format!("2026-11-{day:02} {:02}:{:02}:{:02}.000+01:00", s / 3600, s / 60 % 60, s % 60)
        } else {
            format!("{k}.000")
        }
    });
}

#[test]
fn date_time_logs_fit_the_same_model_as_their_seconds_twins() {
    let dir = tempfile::tempdir().unwrap();
    let (dated, seconds) = twin_folders(dir.path(), write_datetime_log);
    let (model, twin) = (dir.path().join("m.fogm"), dir.path().join("twin.fogm"));
    let out = run(&["fit", "--method", "poly", "--out", s(&model), s(&dated)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("not a number (found '2026-11-24 23:30:00.000+01:00')"),
        "{stderr}"
    );
    assert!(stderr.contains("use --time-unit datetime"), "{stderr}");
    let out = run(&["fit", "--method", "poly", "--time-unit", "datetime", "--out", s(&model), s(&dated)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = run(&["fit", "--method", "poly", "--out", s(&twin), s(&seconds)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The oracle: every stored value equal to the model of the same run timed in seconds.
    assert_eq!(stored_model(&model), stored_model(&twin));
    // compensate keeps the log's clock, Unix time for date-times, and says so (review32a
    // F14). Oracle: 2026-11-24 23:30:00 +01:00 is 1795559400 s (`date -u -d "2026-11-24
    // 22:30:00" +%s`).
    let comp = dir.path().join("comp.csv");
    let log = dated.join("run0.csv");
    let out = run(&["compensate", "--model", s(&model), "--out", s(&comp), s(&log)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stderr.contains("seconds since 1970-01-01 00:00:00 UTC (Unix time)"),
        "{stderr}"
    );
    let text = std::fs::read_to_string(&comp).unwrap();
    let first = text.lines().nth(1).and_then(|l| l.split(',').next()).unwrap();
    assert_eq!(first.parse::<f64>().unwrap(), 1_795_559_400.0, "{first}");
    // A log timed in seconds says nothing of its clock.
    let out = run(&["compensate", "--model", s(&twin), "--out", s(&comp), s(&seconds.join("run0.csv"))]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("Unix time"));
}

fn write_clock_log(path: &Path, start_c: f64, clock: bool) {
    write_timed_log(path, start_c, "Time", |k| {
        if clock {
            // 23:30:00 onwards, no date: the run crosses midnight.
            let s = (23 * 3600 + 30 * 60 + k) % 86_400;
            format!("{:02}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
        } else {
            format!("{k}")
        }
    });
}

#[test]
fn time_of_day_logs_fit_the_same_model_as_their_seconds_twins() {
    let dir = tempfile::tempdir().unwrap();
    let (clocked, seconds) = twin_folders(dir.path(), write_clock_log);
    let (model, twin) = (dir.path().join("m.fogm"), dir.path().join("twin.fogm"));
    let fit = |extra: &[&str], out: &Path, logs: &Path| {
        let mut args = vec!["fit", "--method", "poly", "--time-column", "Time"];
        args.extend_from_slice(extra);
        args.extend(["--out", s(out), s(logs)]);
        run(&args)
    };
    let out = fit(&[], &model, &clocked);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && stderr.contains("run0.csv:2:1: column 'Time': not a number (found '23:30:00')")
    );
    assert!(stderr.contains("use --time-unit time-of-day"), "{stderr}");
    let out = fit(&["--time-unit", "time-of-day"], &model, &clocked);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = fit(&[], &twin, &seconds);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The oracle: every stored value equal to the model of the same run timed in seconds.
    assert_eq!(stored_model(&model), stored_model(&twin));
}

#[test]
fn gaps_in_the_time_stamps_are_reported_by_fit_validate_and_compensate() {
    // Three 1 Hz warm-ups; the first loses 60 s of rows after its 1000th (rows 1000..1059
    // missing, so the step before line 1002 is 61 s).
    let dir = tempfile::tempdir().unwrap();
    let mut logs = Vec::new();
    for (i, start) in [0.0, 20.0, 40.0].into_iter().enumerate() {
        let mut text = String::from("time_s,temp_c,gyro_dph\n");
        for k in (0..3600u32).filter(|k| i != 0 || !(1000..1060).contains(k)) {
            let temp = temp_c(start, f64::from(k));
            text.push_str(&format!("{k},{temp:.4},{:.6}\n", bias_dph(temp)));
        }
        let path = dir.path().join(format!("run{i}.csv"));
        std::fs::write(&path, text).unwrap();
        logs.push(path);
    }
    let model = dir.path().join("m.fogm");
    let fit_report = dir.path().join("fit-report");
    let mut args = vec!["fit", "--method", "poly", "--json", "--out", s(&model), "--report", s(&fit_report)];
    args.extend(logs.iter().map(|p| s(p)));
    let (doc, stderr) = ok_json(&args);
    // The report carries what the command line said: the warnings (warm-ups only heat) and the gap.
    let md = std::fs::read_to_string(fit_report.join("fit-report.md")).unwrap();
    assert!(
        md.contains("Warnings (what the data cannot support):\n\n- axis 0: the calibration only heats"),
        "{md}"
    );
    assert!(
        md.contains("Gaps in the time stamps:\n\n- ") && md.contains("run0.csv: 1 gap in the time stamps"),
        "{md}"
    );
    // ... and what was fitted (review14 F9): each term of `fit --json` with its coefficient,
    // and the calibrated range `inspect --json` gives.
    let terms = doc["axes"][0]["poly"]["terms"].as_array().unwrap();
    assert!(
        !terms.is_empty() && md.contains("| term | coefficient, deg/h | standard error, deg/h | p |"),
        "{md}"
    );
    for t in terms {
        let name = match (t["temp_power"].as_u64().unwrap(), t["rate_power"].as_u64().unwrap()) {
            (0, 0) => "1".to_string(),
            (a, b) => [("x", a), ("y", b)]
                .iter()
                .filter(|(_, k)| *k > 0)
                .map(|(v, k)| if *k == 1 { v.to_string() } else { format!("{v}^{k}") })
                .collect::<Vec<_>>()
                .join(" "),
        };
        let row = format!(
            "| {name} | {:.6} | {:.6} |",
            t["coefficient_dph"].as_f64().unwrap(),
            t["std_error_dph"].as_f64().unwrap()
        );
        assert!(md.contains(&row), "{row} in {md}");
    }
    let (inspect, _) = ok_json(&["inspect", "--json", s(&model)]);
    let p = &inspect["axes"][0]["provenance"];
    let range = format!(
        "  - calibrated range: {:.2} .. {:.2} C, {:.4} .. {:.4} C/min",
        p["temp_min_c"].as_f64().unwrap(),
        p["temp_max_c"].as_f64().unwrap(),
        p["rate_min_c_per_min"].as_f64().unwrap(),
        p["rate_max_c_per_min"].as_f64().unwrap()
    );
    assert!(md.contains(&range), "{range} in {md}");
    let gaps: Vec<&Value> = doc["runs"].as_array().unwrap().iter().map(|r| &r["time_gaps"]).collect();
    assert_eq!(gaps[0]["count"], 1, "{doc}");
    assert_eq!(
        (gaps[0]["largest_s"].as_f64(), gaps[0]["largest_before_line"].as_u64()),
        (Some(61.0), Some(1002))
    );
    assert_eq!((gaps[1]["count"].as_u64(), gaps[2]["count"].as_u64()), (Some(0), Some(0)));
    assert!(
        stderr.contains("run0.csv: 1 gap in the time stamps longer than the tracker's max gap of 5 s"),
        "{stderr}"
    );
    assert!(!stderr.contains("run1.csv: "), "{stderr}");

    // validate replays the same logs: the gap is counted against the model's max gap, the
    // compensator restarts after it, and the metric's windows it cuts are counted.
    let validation_report = dir.path().join("validation-report");
    let mut args = vec!["validate", "--json", "--model", s(&model), "--report", s(&validation_report)];
    args.extend(logs.iter().map(|p| s(p)));
    let (doc, stderr) = ok_json(&args);
    let md = std::fs::read_to_string(validation_report.join("report.md")).unwrap();
    assert!(md.contains("run0.csv: 1 gap in the time stamps") && !md.contains("run1.csv: "), "{md}");
    let runs = doc["runs"].as_array().unwrap();
    assert_eq!(runs[0]["time_gaps"], gaps[0].clone(), "{doc}");
    assert_eq!(runs[1]["time_gaps"]["count"], 0, "{doc}");
    // The closed form: 1 s blocks, features after 10 blocks, so WARMING_UP for 10 samples
    // after the start and again after the gap. The metric's 100 s windows start at the
    // first compensated block (centre 10.5 s): 3590 blocks make 35 full windows and a last
    // one of 90 blocks (90 % of the fullest: used). The gap takes blocks 1000..1059: the
    // window from 910.5 s keeps 90 blocks (used), the one from 1010.5 s keeps 50 (left out).
    assert_eq!(
        (runs[0]["flag_samples"]["warming_up"].as_u64(), runs[1]["flag_samples"]["warming_up"].as_u64()),
        (Some(20), Some(10))
    );
    let windows =
        |r: &Value| (r["metric_windows"]["used"].as_u64(), r["metric_windows"]["left_out"].as_u64());
    assert_eq!((windows(&runs[0]), windows(&runs[1])), ((Some(35), Some(1)), (Some(36), Some(0))), "{doc}");
    assert!(
        stderr.contains(
            "run0.csv: 1 gap in the time stamps longer than the tracker's max gap of 5 s, 61 s in all"
        ) && stderr.contains("1 of the metric's 36 averaging windows were cut short"),
        "{stderr}"
    );
    assert!(!stderr.contains("run1.csv: "), "{stderr}");

    // compensate says it too; its output shows the restart in the flags.
    let out_csv = dir.path().join("comp.csv");
    let out = run(&["compensate", "--model", s(&model), "--out", s(&out_csv), s(&logs[0])]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("run0.csv: 1 gap in the time stamps") && stderr.contains("flag WARMING_UP"),
        "{stderr}"
    );
    let written = std::fs::read_to_string(&out_csv).unwrap();
    let warming: Vec<&str> = written
        .lines()
        .skip(1)
        .filter(|l| l.rsplit(',').next().is_some_and(|f| f.parse::<u8>().unwrap() & 1 == 1))
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(warming.len(), 20);
    assert_eq!((warming[0], warming[10]), ("0", "1060"));
}

#[test]
fn a_run_split_over_files_is_named_by_fit_and_validate() {
    // Three 1 h warm-ups in date-times; the third in two files, the second starting one
    // sample after the first ends (a logger that starts a new file every 30 minutes).
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, day: u32, start_c: f64, seconds: std::ops::Range<u32>| {
        let mut text = String::from("time,temp_c,gyro_dph\n");
        for k in seconds {
            let temp = temp_c(start_c, f64::from(k));
            text.push_str(&format!(
                "2026-11-{day:02}T{:02}:{:02}:{:02},{temp:.4},{:.6}\n",
                10 + k / 3600,
                (k / 60) % 60,
                k % 60,
                bias_dph(temp)
            ));
        }
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let logs = [
        write("a.csv", 20, 0.0, 0..3600),
        write("b.csv", 21, 20.0, 0..3600),
        write("c_part1.csv", 22, 40.0, 0..1800),
        write("c_part2.csv", 22, 40.0, 1800..3600),
    ];
    let model = dir.path().join("m.fogm");
    let mut args =
        vec!["fit", "--method", "poly", "--json", "--time-column", "time", "--time-unit", "datetime"];
    args.extend(["--out", s(&model)]);
    args.extend(logs.iter().map(|p| s(p)));
    let (doc, stderr) = ok_json(&args);
    let warned: Vec<&Value> =
        doc["warnings"].as_array().unwrap().iter().filter(|w| w["kind"] == "continued_logs").collect();
    assert_eq!(warned.len(), 1, "{doc}");
    assert_eq!(
        (warned[0]["values"]["logs"].as_f64(), warned[0]["values"]["largest_step_s"].as_f64()),
        (Some(2.0), Some(1.0))
    );
    // The logs themselves, in order, for a script (review13 F13).
    assert_eq!(warned[0]["logs"], serde_json::json!([s(&logs[2]), s(&logs[3])]), "{doc}");
    assert!(doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .all(|w| w["kind"] == "continued_logs" || w.get("logs").is_none()));
    let expected = format!(
        "{} and {} follow one another in time (each starts at most 1 s after",
        s(&logs[2]),
        s(&logs[3])
    );
    assert!(stderr.contains(&format!("warning: {expected}")), "{stderr}");
    assert!(stderr.contains(&format!("tail -n +2 {}; }} > joined.csv", s(&logs[3]))), "{stderr}");

    // validate names them from the model's max gap; runs in their own files alone are quiet.
    let mut args = vec!["validate", "--model", s(&model)];
    args.extend(logs.iter().map(|p| s(p)));
    let out = run(&args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && stderr.contains(&format!("note: {expected}")), "{stderr}");
    let out = run(&["validate", "--model", s(&model), s(&logs[0]), s(&logs[1]), s(&logs[2])]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && !stderr.contains("continue"), "{stderr}");
}

/// A 1 Hz warm-up of an hour from `start_c` whose temperature is read every 2 s: with
/// `separate`, on its own row half a second before the gyro row it goes with (a CAN or
/// multi-instrument logger); else in that gyro row's temperature cell (the oracle).
fn write_separate_channel_log(path: &Path, start_c: f64, separate: bool) {
    let mut text = String::from("time_s,temp_c,gyro_dph\n");
    for k in 0..3600u32 {
        let temp = temp_c(start_c, f64::from(k));
        let gyro = bias_dph(temp);
        match (k % 2 == 1, separate) {
            (true, true) => text.push_str(&format!("{}.5,{temp:.4},\n{k}.0,,{gyro:.6}\n", k - 1)),
            (true, false) => text.push_str(&format!("{k}.0,{temp:.4},{gyro:.6}\n")),
            (false, _) => text.push_str(&format!("{k}.0,,{gyro:.6}\n")),
        }
    }
    std::fs::write(path, text).unwrap();
}

/// Channels logged on separate rows (review32a F5): `fit` stores the model of the logs with
/// each reading merged into the next sample's row, `validate` and `compensate` give that
/// twin's figures and output, and each says how many rows held only a temperature.
#[test]
fn separate_channel_logs_fit_the_same_model_as_their_merged_twins() {
    let dir = tempfile::tempdir().unwrap();
    let (separate, merged) = twin_folders(dir.path(), write_separate_channel_log);
    let (model, twin) = (dir.path().join("m.fogm"), dir.path().join("twin.fogm"));
    let fitted =
        |m: &Path, logs: &Path| ok_json(&["fit", "--json", "--method", "poly", "--out", s(m), s(logs)]);
    let (doc, stderr) = fitted(&model, &separate);
    assert!(
        stderr.contains(
            "run0.csv: 1800 rows held a temperature and no gyro reading (channels logged on separate rows)"
        ),
        "{stderr}"
    );
    assert_eq!(
        (doc["runs"][0]["temperature_only_rows"].as_u64(), doc["runs"][0]["rows"].as_u64()),
        (Some(1800), Some(3600))
    );
    let (twin_doc, twin_stderr) = fitted(&twin, &merged);
    assert!(!twin_stderr.contains("no gyro reading"), "{twin_stderr}");
    assert_eq!(twin_doc["runs"][0]["temperature_only_rows"].as_u64(), Some(0));
    assert_eq!(stored_model(&model), stored_model(&twin));
    let figures = |m: &Path, logs: &Path| {
        let (doc, stderr) = ok_json(&["validate", "--json", "--model", s(m), s(logs)]);
        ((doc["raw_bias_stability_dph"].clone(), doc["compensated_bias_stability_dph"].clone()), stderr)
    };
    let (validated, stderr) = figures(&model, &separate);
    assert!(stderr.contains("1800 rows held a temperature"), "{stderr}");
    // validate --json carries the note too (review33c F7).
    let (doc, _) = ok_json(&["validate", "--json", "--model", s(&model), s(&separate)]);
    let notes =
        doc["notes"].as_array().map(|n| n.iter().filter_map(Value::as_str).collect::<Vec<_>>().join("\n"));
    assert!(notes.as_deref().unwrap_or("").contains("run0.csv: 1800 rows held a temperature"), "{notes:?}");
    // A log of temperature rows only is said so, not "only a header" (review33c F6).
    let only = dir.path().join("only.csv");
    std::fs::write(&only, "time_s,temp_c,gyro_dph\n0,20,\n1,20.5,\n").unwrap();
    let out = run(&["fit", "--method", "poly", "--out", s(&dir.path().join("o.fogm")), s(&only)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("only.csv: no gyro reading: all 2 rows held a temperature"),
        "{stderr}"
    );
    assert_eq!(validated, figures(&twin, &merged).0);
    let compensated = |m: &Path, log: &Path, out: &Path| {
        let o = run(&["compensate", "--model", s(m), "--out", s(out), s(log)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out).unwrap()
    };
    let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
    assert_eq!(
        compensated(&model, &separate.join("run1.csv"), &a),
        compensated(&twin, &merged.join("run1.csv"), &b)
    );
}
