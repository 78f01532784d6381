//! End-to-end tests of the `fogtemp-cal` command line (docs/architecture.md, Contracts): the
//! log format, the command contract (fit, validate, compensate, evaluate, inspect, export,
//! allan), error reporting on bad input, atomic outputs and the noise metrics.
//!
//! The logs are generated here with fixed seeds: power-on warm-ups at 20 Hz, temperature
//! quantised to 0.0625 C, gyro = [`true_bias_dph`]`(T, dT/dt)` + white noise. The 16
//! shared 30-minute runs are cached under the target's tmp folder, keyed by a hash of this
//! file; everything a test writes goes to its own temporary folder.
//!
//! Locating the binary: `fogtemp-cal` belongs to another workspace package (`fogtemp-cli`),
//! so `CARGO_BIN_EXE_fogtemp-cal` is not defined for this package's tests and
//! `assert_cmd`'s `cargo_bin` only finds the file if something else happened to build it
//! into the same target folder. [`bin`] therefore runs `cargo build -p fogtemp-cli --bin
//! fogtemp-cal --message-format=json` once per test process and takes the executable's path
//! from cargo's own report (so `CARGO_TARGET_DIR` and the release profile are honoured).
//! Set `FOGTEMP_CAL_BIN` to test a prebuilt binary instead.

mod common;

use std::collections::BTreeSet;
use std::ffi::{OsStr, OsString};
use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::{cal, gaussian, rng, run_err, run_ok};
use predicates::prelude::*;
use rand::Rng;
use serde_json::Value;
use tempfile::TempDir;

// ---------------------------------------------------------------------------------------
// The binary (run by `common::{cal, run_ok, run_err}`) and its output
// ---------------------------------------------------------------------------------------

/// A share in percent as messages print it: one decimal, or from below 0.1 % its first
/// significant digit (`0.03` for 1 of 3600).
fn share_text(percent: f64) -> String {
    if percent > 0.0 && percent < 0.1 {
        let digits = (-percent.log10().floor()) as usize;
        format!("{percent:.digits$}")
    } else {
        format!("{percent:.1}")
    }
}

fn json(text: &str) -> Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("not one JSON document ({e}):\n{text}"))
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn arr(v: &Value) -> &Vec<Value> {
    v.as_array().unwrap_or_else(|| panic!("not an array: {v}"))
}

/// Names in a folder (including hidden temporary files).
fn entries(dir: &Path) -> BTreeSet<String> {
    fs::read_dir(dir)
        .expect("list folder")
        .map(|e| e.expect("folder entry").file_name().to_string_lossy().into_owned())
        .collect()
}

/// Arguments of mixed types (`&str`, `&Path`, `&PathBuf`, `String`) as a `Vec<OsString>`.
macro_rules! args {
    ($($a:expr),* $(,)?) => {
        Vec::<OsString>::from([$(OsString::from(AsRef::<OsStr>::as_ref(&$a))),*])
    };
}

// ---------------------------------------------------------------------------------------
// Generated logs
// ---------------------------------------------------------------------------------------

/// Sample rate of the warm-up logs, Hz.
const RATE_HZ: f64 = 20.0;
/// Duration of a warm-up run, minutes.
const RUN_MIN: f64 = 30.0;
/// Self-heating after power-on, deg C, reached with time constant [`TAU_MIN`].
const SELF_HEAT_C: f64 = 12.0;
/// Warm-up time constant, minutes.
const TAU_MIN: f64 = 8.0;
/// Largest true rate, at power-on, deg C/min.
const MAX_RATE: f64 = SELF_HEAT_C / TAU_MIN;
/// Temperature quantum of the logged sensor, deg C.
const QUANTUM_C: f64 = 0.0625;
/// White gyro noise per sample, deg/h (0.05 / sqrt(2000) = 0.0011 deg/h in a 100 s mean).
const NOISE_DPH: f64 = 0.05;
/// Chamber temperatures of the calibration runs (the paper's eight).
const CAL_STARTS: [f64; 8] = [-40.0, -25.0, -10.0, 5.0, 20.0, 35.0, 45.0, 60.0];
/// Chamber temperatures of the validation runs (between the calibration ones).
const VAL_STARTS: [f64; 8] = [-33.0, -18.0, -3.0, 12.0, 27.0, 40.0, 50.0, 55.0];

/// The bias the logs carry, deg/h: static b(T) plus a Shupe-like term in dT/dt (C/min).
/// Over a run it moves by about 1 deg/h, against 0.0011 deg/h of noise in a 100 s mean.
fn true_bias_dph(temp_c: f64, rate_c_per_min: f64) -> f64 {
    1.0 + 0.02 * temp_c
        + 1.5e-4 * temp_c * temp_c
        + 0.6 * rate_c_per_min
        + 0.1 * (temp_c / 20.0).sin() * rate_c_per_min
}

fn quantise(temp_c: f64) -> f64 {
    (temp_c / QUANTUM_C).round() * QUANTUM_C
}

/// Temperature of a warm-up from `start_c` at `t_min` minutes after power-on.
fn warmup_temp(start_c: f64, t_min: f64) -> f64 {
    start_c + SELF_HEAT_C * (1.0 - (-t_min / TAU_MIN).exp())
}

/// Writes a power-on warm-up log: `time_s,temp_c,gyro_dph` at [`RATE_HZ`] for `minutes`.
fn write_warmup(path: &Path, start_c: f64, minutes: f64, seed: u64) {
    let mut r = rng(seed);
    let mut w = BufWriter::new(fs::File::create(path).expect("create log"));
    writeln!(w, "time_s,temp_c,gyro_dph").expect("write log");
    let rows = (minutes * 60.0 * RATE_HZ).round() as u64;
    for k in 0..rows {
        let t_s = k as f64 / RATE_HZ;
        let t_min = t_s / 60.0;
        let temp = warmup_temp(start_c, t_min);
        let rate = MAX_RATE * (-t_min / TAU_MIN).exp();
        let gyro = true_bias_dph(temp, rate) + NOISE_DPH * gaussian(&mut r);
        writeln!(w, "{t_s:.2},{:.4},{gyro:.5}", quantise(temp)).expect("write log");
    }
    w.flush().expect("flush log");
}

/// `validate --json`'s white-noise floors against the closed form of the logs' white noise:
/// `NOISE_DPH` per sample at `RATE_HZ` gives 100 s means scattered by
/// `NOISE_DPH / sqrt(100 RATE_HZ)`. Each run's estimate, from its Allan deviation at 1 s over
/// about 1700 s, carries about 1 / sqrt(2 x 1700) = 1.7 % relative error (6 %: over three of
/// it); the RMS over 8 runs about 0.6 % (2 %).
fn check_white_noise_floor(doc: &Value, runs: &[Value]) {
    let closed_form = NOISE_DPH / (100.0 * RATE_HZ).sqrt();
    for r in runs {
        let floor = &r["white_noise_floor"];
        let (from, adev, value) = (f(&floor["from_tau_s"]), f(&floor["adev_dph"]), f(&floor["floor_dph"]));
        let averaged = f(&floor["averaged_s"]);
        assert_eq!(from, 1.0, "{floor}");
        // Full windows, but for blocks that are partly before the compensator's first sample.
        assert!((99.0..=100.0).contains(&averaged), "{floor}");
        assert!((value - adev * (from / averaged).sqrt()).abs() <= 1e-12 * value, "{floor}");
        assert!((value / closed_form - 1.0).abs() < 0.06, "{floor} against {closed_form}");
    }
    let overall = f(&doc["white_noise_floor"]["floor_dph"]);
    let rms = (runs.iter().map(|r| f(&r["white_noise_floor"]["floor_dph"]).powi(2)).sum::<f64>()
        / runs.len() as f64)
        .sqrt();
    assert!((overall - rms).abs() <= 1e-12 * overall, "{overall} vs RMS {rms}");
    assert!((overall / closed_form - 1.0).abs() < 0.02, "{overall} against {closed_form}");
}

/// The shared warm-up logs: `cal/run0..7.csv` and `val/run0..7.csv`.
struct Logs {
    cal: PathBuf,
    val: PathBuf,
}

/// FNV-1a, to key the log cache by this file's source.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The warm-up logs, generated once and cached under the target's tmp folder, keyed by a
/// hash of this source file (so an edit to the generator regenerates them).
fn logs() -> &'static Logs {
    static LOGS: OnceLock<Logs> = OnceLock::new();
    LOGS.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR"));
        let name = format!("fogtemp-cli-logs-{:016x}", fnv1a(include_bytes!("cli.rs")));
        let dir = root.join(&name);
        let complete = |d: &Path| d.join("complete").is_file();
        if !complete(&dir) {
            fs::create_dir_all(root).expect("create target tmp folder");
            // Older generations of the cache (best effort).
            for e in fs::read_dir(root).into_iter().flatten().flatten() {
                let n = e.file_name().to_string_lossy().into_owned();
                if n.starts_with("fogtemp-cli-logs-") && n != name {
                    let _ = fs::remove_dir_all(e.path());
                }
            }
            let staging = tempfile::Builder::new().prefix(".logs-").tempdir_in(root).expect("staging");
            for (set, starts, seed0) in [("cal", CAL_STARTS, 1000), ("val", VAL_STARTS, 2000)] {
                let sub = staging.path().join(set);
                fs::create_dir(&sub).expect("create log folder");
                for (i, start) in starts.iter().enumerate() {
                    write_warmup(&sub.join(format!("run{i}.csv")), *start, RUN_MIN, seed0 + i as u64);
                }
            }
            fs::write(staging.path().join("complete"), b"").expect("mark complete");
            // Another test process may have won the race; then use its copy.
            if fs::rename(staging.path(), &dir).is_err() {
                assert!(complete(&dir), "cannot move the generated logs to {}", dir.display());
            }
        }
        Logs { cal: dir.join("cal"), val: dir.join("val") }
    })
}

/// Lowest and highest temperature in the calibration logs, deg C (each run rises
/// monotonically, so the extremes are the first row of the coldest run and the last row
/// of the hottest).
fn cal_temp_range() -> (f64, f64) {
    let last_min = (RUN_MIN * 60.0 * RATE_HZ - 1.0) / RATE_HZ / 60.0;
    (quantise(CAL_STARTS[0]), quantise(warmup_temp(CAL_STARTS[7], last_min)))
}

/// Fit options that keep a debug-build fit of the 8 runs to a few seconds: 5 s feature
/// blocks (20 per 100 s window, features after 2 blocks = 10 s), at most 200 mesh nodes,
/// polynomial terms up to degree 3.
const FAST_FIT: &str = "--blocks 20 --min-blocks 2 --max-nodes 200 --tolerance-dph 0.005 --max-degree 3";

/// Fits `method` on `logs` into `model`, returns the `fit --json` document.
fn fit(method: &str, model: &Path, logs: &[&Path]) -> Value {
    let mut args = args!["fit", "--method", method, "--json", "--out", model];
    args.extend(FAST_FIT.split(' ').map(OsString::from));
    args.extend(logs.iter().map(OsString::from));
    json(&run_ok(args))
}

// ---------------------------------------------------------------------------------------
// 1. Round trip: fit -> validate -> compensate -> inspect -> export
// ---------------------------------------------------------------------------------------

#[test]
fn round_trip_poly() {
    round_trip("poly");
}

#[test]
fn round_trip_mesh() {
    round_trip("mesh");
}

#[test]
fn round_trip_hybrid() {
    round_trip("hybrid");
}

fn round_trip(method: &str) {
    let logs = logs();
    let dir = TempDir::new().expect("tempdir");
    let model = dir.path().join(format!("{method}.fogm"));

    // fit
    let doc = fit(method, &model, &[&logs.cal]);
    let blob = fs::read(&model).expect("model written");
    assert_eq!(entries(dir.path()), BTreeSet::from([format!("{method}.fogm")]), "stray files after fit");
    assert_eq!(doc["bytes"].as_u64(), Some(blob.len() as u64));
    let runs = arr(&doc["runs"]);
    assert_eq!(runs.len(), 8);
    for run in runs {
        assert_eq!(run["skipped_rows"], 0);
        assert_eq!(run["rows"].as_u64(), Some((RUN_MIN * 60.0 * RATE_HZ) as u64));
    }
    let axis = &arr(&doc["axes"])[0];
    assert!(axis["points"].as_u64().unwrap_or(0) > 1000, "{axis}");
    // A hybrid keeps its residual mesh only when (blocked) cross-validation says it
    // helps (on these logs it does not: "no mesh" is within one standard error of the best).
    let has_mesh = match method {
        "poly" => false,
        "hybrid" => axis["mesh_smoothing"]["relative_weight"].is_number(),
        _ => true,
    };
    if method != "poly" {
        let curve = arr(&axis["mesh_smoothing"]["curve"]);
        assert_eq!(curve.len(), if method == "hybrid" { 14 } else { 13 }, "{axis}");
    }
    let has_poly = method != "mesh";
    assert_eq!(axis["mesh_nodes"].as_u64().unwrap_or(0) >= 3, has_mesh, "{axis}");
    assert_eq!(axis["poly"].is_object(), has_poly, "{axis}");

    // validate: raw vs compensated bias stability (100 s, non-overlapping, RMS over runs)
    let validate = |extra: &[&str]| {
        let mut args = args!["validate", "--json", "--model", &model];
        args.extend(extra.iter().map(OsString::from));
        args.push(logs.val.clone().into());
        json(&run_ok(args))
    };
    let v = validate(&[]);
    let (raw, comp) = (f(&v["raw_bias_stability_dph"]), f(&v["compensated_bias_stability_dph"]));
    let vruns = arr(&v["runs"]);
    assert_eq!(vruns.len(), 8);
    for r in vruns {
        assert_eq!(r["axis"], 0);
        assert!(f(&r["raw_bias_stability_dph"]) > 0.0 && f(&r["compensated_bias_stability_dph"]) > 0.0);
        assert_eq!(r["samples"].as_u64(), Some((RUN_MIN * 60.0 * RATE_HZ) as u64));
    }
    // The overall figure is the RMS over runs (docs/architecture.md, Contracts: metrics).
    for (key, overall) in [("raw_bias_stability_dph", raw), ("compensated_bias_stability_dph", comp)] {
        let rms = (vruns.iter().map(|r| f(&r[key]).powi(2)).sum::<f64>() / vruns.len() as f64).sqrt();
        assert!((rms - overall).abs() <= 1e-12 * overall, "{key}: {overall} vs RMS {rms}");
    }
    check_white_noise_floor(&v, vruns);
    // The first 100 s window holds the 10 s before the first feature (nothing subtracted
    // while the raw bias is 1-3 deg/h) and the partial-window start, so it dominates the
    // compensated figure; leaving it out shows the model itself.
    let v100 = validate(&["--exclude-first-s", "100"]);
    let (raw100, comp100) = (f(&v100["raw_bias_stability_dph"]), f(&v100["compensated_bias_stability_dph"]));
    eprintln!(
        "{method}: bias stability raw {raw:.5} -> compensated {comp:.5} deg/h (x{:.1}); \
         first 100 s excluded: {raw100:.5} -> {comp100:.5} (x{:.1})",
        raw / comp,
        raw100 / comp100
    );
    assert!(comp < 0.5 * raw, "{method}: compensated {comp} not below half of raw {raw}");
    assert!(comp100 < 0.25 * raw100, "{method}: compensated {comp100} not below a quarter of raw {raw100}");

    // compensate one validation log
    let log = logs.val.join("run3.csv");
    let out = dir.path().join("compensated.csv");
    run_ok(args!["compensate", "--model", &model, &log, "--out", &out]);
    check_compensated(&log, &out);
    allan_of_compensated_starts_after_the_warm_up(&out);

    // inspect
    let inspect = json(&run_ok(args!["inspect", &model, "--json"]));
    assert_eq!(inspect["bytes"].as_u64(), Some(blob.len() as u64));
    let iaxis = &arr(&inspect["axes"])[0];
    let kind: Vec<&str> = arr(&iaxis["kind"]).iter().filter_map(Value::as_str).collect();
    assert_eq!(kind.contains(&"mesh"), has_mesh, "{kind:?}");
    assert_eq!(kind.contains(&"poly"), has_poly, "{kind:?}");
    let nodes = arr(&iaxis["nodes"]);
    let triangles = arr(&iaxis["triangles"]);
    assert_eq!(nodes.len() as u64, axis["mesh_nodes"].as_u64().unwrap_or(u64::MAX));
    assert_eq!(triangles.len() as u64, axis["mesh_triangles"].as_u64().unwrap_or(u64::MAX));
    if has_mesh {
        check_mesh_json(nodes, triangles, method == "mesh");
    } else {
        assert!(nodes.is_empty() && triangles.is_empty());
        assert!(!arr(&iaxis["poly"]).is_empty());
    }

    // inspect's text names the kind, a polynomial with a rate term as plain `poly`.
    let text = run_ok(args!["inspect", &model]);
    let with_rate = has_poly && arr(&iaxis["poly"]).iter().any(|t| t["rate_power"].as_u64() != Some(0));
    let expected_kind = match (has_poly, has_mesh) {
        (true, true) => "poly+mesh",
        (false, true) => "mesh",
        _ => "poly",
    };
    assert!(with_rate || !has_poly, "the warm-up logs' Shupe-like term gives the fit a rate term");
    assert!(text.contains(&format!("axis 0: {expected_kind} |")), "{text}");

    // export
    check_export(&model, &blob, dir.path());
}

/// Review21 F7: a cubic in T alone was listed by `inspect` as `poly`, the (T, dT/dt) fit's name.
#[test]
fn inspect_says_a_cubic_t_model_is_a_polynomial_in_t_alone() {
    let logs = logs();
    let dir = tempfile::tempdir().expect("tempdir");
    let model = dir.path().join("cubic.fogm");
    fit("cubic-t", &model, &[&logs.cal]);
    let text = run_ok(args!["inspect", &model]);
    assert!(text.contains("axis 0: poly in T alone |"), "{text}");
    let inspect = json(&run_ok(args!["inspect", &model, "--json"]));
    let terms = arr(&arr(&inspect["axes"])[0]["poly"]).clone();
    assert!(!terms.is_empty() && terms.iter().all(|t| t["rate_power"].as_u64() == Some(0)), "{terms:?}");
}

/// `compensate` output: the header, one row per input row, time and raw as logged, and
/// compensated = raw - bias exactly in f32 (as the firmware computes it) as printed.
fn check_compensated(log: &Path, out: &Path) {
    let input = fs::read_to_string(log).expect("read log");
    let output = fs::read_to_string(out).expect("read compensated");
    let mut lines = output.lines();
    assert_eq!(lines.next(), Some("time_s,raw_dph,compensated_dph,bias_dph,flags"));
    let rows: Vec<&str> = lines.collect();
    let inputs: Vec<&str> = input.lines().skip(1).collect();
    assert_eq!(rows.len(), inputs.len(), "one output row per input row");
    let (mut warming, mut clean) = (0, 0);
    for (k, (row, inp)) in rows.iter().zip(&inputs).enumerate() {
        let c: Vec<&str> = row.split(',').collect();
        let i: Vec<&str> = inp.split(',').collect();
        assert_eq!(c.len(), 5, "row {k}: {row}");
        let t: f64 = c[0].parse().expect("time");
        let t_in: f64 = i[0].parse().expect("time");
        assert!((t - t_in).abs() < 1e-9, "row {k}: time {t} vs logged {t_in}");
        let raw: f64 = c[1].parse().expect("raw");
        assert_eq!(raw, i[2].parse::<f64>().expect("gyro"), "row {k}: raw is the logged gyro");
        let comp: f32 = c[2].parse().expect("compensated");
        let bias: f32 = c[3].parse().expect("bias");
        let flags: u8 = c[4].parse().expect("flags");
        assert_eq!(comp, raw as f32 - bias, "row {k}: {row}");
        assert_eq!(flags & !0x1f, 0, "row {k}: unknown flag bits {flags}");
        warming += usize::from(flags & 0x01 != 0);
        clean += usize::from(flags == 0);
        if k == 0 {
            assert_eq!(bias, 0.0, "nothing is subtracted before the first feature");
            assert_ne!(flags & 0x01, 0, "the first sample is flagged warming up");
        }
    }
    // Features after 2 blocks of 5 s: 10 s = 200 samples at 20 Hz are warming up.
    assert!((150..=250).contains(&warming), "{warming} samples warming up");
    assert!(clean > rows.len() / 2, "only {clean} of {} samples unflagged", rows.len());
}

/// `inspect --json` mesh: finite nodes inside the calibration data's range, triangles of
/// three distinct in-range node indices with positive (counter-clockwise) area.
fn check_mesh_json(nodes: &[Value], triangles: &[Value], pure_mesh: bool) {
    let (t_lo, t_hi) = cal_temp_range();
    // A feature temperature is the least-squares line through the window's block means,
    // taken at the window's end: it may pass the logged extremes by a fraction of the
    // 0.0625 C quantum (measured: 0.02 C), never by a whole one. The rate stays within the
    // true range plus the quantisation noise of a 10 s slope.
    let (temp_tol, rate_lo, rate_hi) = (QUANTUM_C, -0.1, MAX_RATE + 0.1);
    let mut seen = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for n in nodes {
        let (t, r, v) = (f(&n["temp_c"]), f(&n["rate_c_per_min"]), f(&n["value_dph"]));
        assert!(v.is_finite());
        assert!(t >= t_lo - temp_tol && t <= t_hi + temp_tol, "node temp {t} outside {t_lo}..{t_hi}");
        assert!(r >= rate_lo && r <= rate_hi, "node rate {r} outside {rate_lo}..{rate_hi}");
        if pure_mesh {
            assert_eq!(n["value_dph"], n["mesh_value_dph"]);
        }
        seen = (seen.0.min(t), seen.1.max(t), seen.2.min(r), seen.3.max(r));
    }
    // The hull spans most of the calibrated plane.
    assert!(seen.0 < t_lo + 1.0 && seen.1 > t_hi - 1.0, "node temps {seen:?}");
    assert!(seen.3 > 0.8 * MAX_RATE, "node rates {seen:?}");
    for tri in triangles {
        let idx: Vec<usize> = arr(tri).iter().map(|i| i.as_u64().expect("index") as usize).collect();
        assert_eq!(idx.len(), 3, "{tri}");
        assert!(idx.iter().all(|&i| i < nodes.len()), "{tri}: index out of range");
        assert!(idx[0] != idx[1] && idx[1] != idx[2] && idx[0] != idx[2], "{tri}");
        let p: Vec<(f64, f64)> = idx.iter().map(|&i| (f(&nodes[i]["x"]), f(&nodes[i]["y"]))).collect();
        let area2 = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0);
        assert!(area2 > 0.0, "{tri}: not counter-clockwise (area {area2})");
    }
}

/// Hex bytes `0x..` in `text` between `open` and the next `close`.
fn array_bytes(text: &str, open: &str, close: &str) -> Vec<u8> {
    let start = text.find(open).unwrap_or_else(|| panic!("no '{open}' in:\n{text}")) + open.len();
    let len = text[start..].find(close).unwrap_or_else(|| panic!("no '{close}' after '{open}'"));
    text[start..start + len]
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| {
            let hex = t.strip_prefix("0x").unwrap_or_else(|| panic!("not a hex byte: '{t}'"));
            u8::from_str_radix(hex, 16).unwrap_or_else(|_| panic!("not a hex byte: '{t}'"))
        })
        .collect()
}

/// `export --format rust|c`: the array holds exactly the model's bytes; the C header
/// declares the length.
fn check_export(model: &Path, blob: &[u8], dir: &Path) {
    let n = blob.len();
    let rs = dir.join("model.rs");
    run_ok(args!["export", "--model", model, "--format", "rust", "--out", &rs]);
    let text = fs::read_to_string(&rs).expect("read rust export");
    let decl = format!("pub static FOGTEMP_MODEL: [u8; {n}] = [");
    assert!(text.contains(&decl), "no '{decl}' in the Rust export");
    assert_eq!(array_bytes(&text, &decl, "];"), blob, "Rust export bytes");

    let c = dir.join("model.c");
    run_ok(args!["export", "--model", model, "--format", "c", "--name", "gyro_model", "--out", &c]);
    let header = fs::read_to_string(dir.join("model.h")).expect("C export writes model.h beside model.c");
    assert!(header.contains(&format!("#define GYRO_MODEL_LEN {n}u")), "{header}");
    assert!(header.contains(&format!("extern const uint8_t gyro_model[{n}];")), "{header}");
    // The units the model was fitted in, as inspect reports them (review23a F2).
    let inspect = json(&run_ok(args!["inspect", model, "--json"]));
    let axis = &arr(&inspect["axes"])[0];
    for (key, constant) in [
        ("gyro_dph_per_unit", "GYRO_DPH_PER_UNIT"),
        ("temp_c_per_unit", "TEMP_C_PER_UNIT"),
        ("temp_offset_c", "TEMP_OFFSET_C"),
    ] {
        let value = axis[key].as_f64().unwrap_or(f64::NAN);
        assert!(header.contains(&format!("#define GYRO_MODEL_{constant} {value:?}f ")), "{key}: {header}");
        assert!(
            text.contains(&format!("pub const FOGTEMP_MODEL_{constant}: f64 = {value:?};")),
            "{key}: {text}"
        );
    }
    let source = fs::read_to_string(&c).expect("read C export");
    assert!(source.contains("#include \"model.h\""), "{source}");
    let decl = format!("const uint8_t gyro_model[{n}] = {{");
    assert_eq!(array_bytes(&source, &decl, "};"), blob, "C export bytes");
    // The guard is the export's own, never fogtemp.h's (review22 F6: --name fogtemp gave
    // FOGTEMP_H and the second include vanished).
    assert!(header.contains("#ifndef GYRO_MODEL_FOGTEMP_EXPORT_H"), "{header}");
    run_ok(args!["export", "--model", model, "--format", "c", "--name", "fogtemp", "--out", &c]);
    let header = fs::read_to_string(dir.join("model.h")).expect("model.h");
    assert!(!header.contains("FOGTEMP_H\n"), "{header}");
    let err =
        run_err(args!["export", "--model", model, "--format", "c", "--name", "fogtemp_model", "--out", &c]);
    assert!(err.contains("fogtemp.h declares its types and functions as fogtemp_*"), "{err}");
    // Nor the header's constants, nor a macro the export derives (review23a F7).
    for (name, clash) in
        [("FOGTEMP_STATUS_OK", "FOGTEMP_STATUS_OK"), ("FOGTEMP_FLAG_BAD_INPUT", "FOGTEMP_FLAG_BAD_INPUT")]
    {
        let err = run_err(args!["export", "--model", model, "--format", "c", "--name", name, "--out", &c]);
        assert!(err.contains(&format!("fogtemp.h already declares {clash}")), "{err}");
    }

    // `--out -` is stdout for Rust, the same text as the file; C needs a path.
    let streamed = run_ok(args!["export", "--model", model, "--format", "rust", "--out", "-"]);
    assert_eq!(streamed, text);
    assert!(!Path::new("-").exists(), "no file named -");
    let err = run_err(args!["export", "--model", model, "--format", "c", "--out", "-"]);
    assert!(err.contains("--format c writes a source and a header beside it, so it needs a path"), "{err}");
}

// ---------------------------------------------------------------------------------------
// 2. evaluate vs an independent f64 barycentric reference
// ---------------------------------------------------------------------------------------

/// Barycentric coordinates of `p` in triangle `(a, b, c)`, f64.
fn barycentric(p: (f64, f64), a: (f64, f64), b: (f64, f64), c: (f64, f64)) -> [f64; 3] {
    let det = (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1);
    let l1 = ((p.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (p.1 - a.1)) / det;
    let l2 = ((b.0 - a.0) * (p.1 - a.1) - (p.0 - a.0) * (b.1 - a.1)) / det;
    [1.0 - l1 - l2, l1, l2]
}

/// `evaluate` vs the f64 barycentric reference inside the hull, deg/h. The model evaluates
/// in f32: node values reach about 5 deg/h, where one ulp is 4.8e-7; rounding the query to
/// f32, normalising it and the stored f32 plane coefficients add a few ulps. 1e-5 is about
/// 20 ulps (measured worst: 3e-7).
const VALUE_TOL: f64 = 1e-5;

/// The same outside the hull (nearest hull value). The squared distance is flat
/// (quadratic) in the position along the hull around the nearest point, so its f32
/// rounding (relative 6e-8) lets the model pick a hull point up to sqrt(6e-8) = 2.4e-4
/// times the distance away from the exact one: with queries up to ~0.3 normalised units
/// outside and values changing by up to ~0.5 deg/h per unit along the hull, about 4e-5.
/// Measured worst: 9e-6 (a query equidistant, to 1e-9, from a hull vertex and the long
/// edge before it); tolerance 1e-4.
const OUTSIDE_TOL: f64 = 1e-4;

#[test]
fn evaluate_matches_f64_barycentric_reference() {
    let logs = logs();
    let dir = TempDir::new().expect("tempdir");
    let model = dir.path().join("mesh.fogm");
    let runs: Vec<PathBuf> = [0, 2, 4, 6].iter().map(|i| logs.cal.join(format!("run{i}.csv"))).collect();
    // The held hull value (named here; the default continues linearly) is this test's reference outside the hull;
    // the linear continuation is checked against its own f64 reference in tests/mesh_beyond_hull.rs.
    let mut args = args!["fit", "--method", "mesh", "--mesh-outside", "hold", "--json", "--out", &model];
    args.extend(FAST_FIT.split(' ').map(OsString::from));
    args.extend(runs.iter().map(OsString::from));
    run_ok(args);
    let inspect = json(&run_ok(args!["inspect", "--json", &model]));
    let axis = &arr(&inspect["axes"])[0];
    assert_eq!(axis["outside_policy"], "nearest_hull");
    let nodes: Vec<(f64, f64, f64, f64, f64)> = arr(&axis["nodes"])
        .iter()
        .map(|n| (f(&n["temp_c"]), f(&n["rate_c_per_min"]), f(&n["value_dph"]), f(&n["x"]), f(&n["y"])))
        .collect();
    let triangles: Vec<[usize; 3]> = arr(&axis["triangles"])
        .iter()
        .map(|t| {
            let v = arr(t);
            [0, 1, 2].map(|k| v[k].as_u64().expect("index") as usize)
        })
        .collect();
    let hull: Vec<usize> = arr(&axis["hull"]).iter().map(|i| i.as_u64().expect("index") as usize).collect();
    // The calibrated region (normalised, counter-clockwise): outside it the core flags a mesh's
    // value too. The smallest signed distance to its edges, f64; negative outside.
    let region: Vec<(f64, f64)> = arr(&axis["region"]).iter().map(|v| (f(&v["x"]), f(&v["y"]))).collect();
    assert!(region.len() >= 3, "the model stores a region");
    let region_margin = |x: f64, y: f64| {
        (0..region.len())
            .map(|k| {
                let (a, b) = (region[k], region[(k + 1) % region.len()]);
                let (ex, ey) = (b.0 - a.0, b.1 - a.1);
                (ex * (y - a.1) - ey * (x - a.0)) / ex.hypot(ey)
            })
            .fold(f64::INFINITY, f64::min)
    };
    let nz = &axis["normalisation"];
    let (t_off, t_scale) = (f(&nz["temp_offset_c"]), f(&nz["temp_scale_per_c"]));
    let (r_off, r_scale) = (f(&nz["rate_offset_c_per_min"]), f(&nz["rate_scale_per_c_per_min"]));

    // Queries: the nodes' bounding box widened by 15 % on every side.
    let span = |k: fn(&(f64, f64, f64, f64, f64)) -> f64| {
        let (lo, hi) =
            nodes.iter().map(k).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        (lo - 0.15 * (hi - lo), hi + 0.15 * (hi - lo))
    };
    let (t_range, r_range) = (span(|n| n.0), span(|n| n.1));
    let mut r = rng(42);
    let queries: Vec<(f64, f64)> =
        (0..3000).map(|_| (r.gen_range(t_range.0..t_range.1), r.gen_range(r_range.0..r_range.1))).collect();
    let points = dir.path().join("points.csv");
    let mut text = String::from("temp_c,rate_c_per_min\n");
    for (t, rate) in &queries {
        text.push_str(&format!("{t},{rate}\n"));
    }
    fs::write(&points, text).expect("write points");
    let out = run_ok(args!["evaluate", "--model", &model, "--points", &points]);
    let mut lines = out.lines();
    assert_eq!(lines.next(), Some("temp_c,rate_c_per_min,value_dph,flags"));
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), queries.len());

    // Reference, f64. Point-in-triangle is affine invariant, so the physical coordinates
    // (which the model normalises before triangulating) give the same containment.
    let (mut inside, mut outside, mut near_edge) = (0, 0, 0);
    let (mut worst_inside, mut worst_outside) = (0.0f64, 0.0f64);
    for (row, &(t, rate)) in rows.iter().zip(&queries) {
        let c: Vec<&str> = row.split(',').collect();
        assert_eq!(c.len(), 4, "{row}");
        assert_eq!((c[0].parse::<f64>().ok(), c[1].parse::<f64>().ok()), (Some(t), Some(rate)), "{row}");
        let value: f64 = c[2].parse().expect("value_dph");
        let flags: u8 = c[3].parse().expect("flags");
        let (best, reference) = triangles
            .iter()
            .map(|tri| {
                let [a, b, cc] = tri.map(|i| (nodes[i].0, nodes[i].1));
                let l = barycentric((t, rate), a, b, cc);
                let v = l[0] * nodes[tri[0]].2 + l[1] * nodes[tri[1]].2 + l[2] * nodes[tri[2]].2;
                (l[0].min(l[1]).min(l[2]), v)
            })
            .fold((f64::NEG_INFINITY, f64::NAN), |m, e| if e.0 > m.0 { e } else { m });
        if best >= 0.0 {
            let err = (value - reference).abs();
            worst_inside = worst_inside.max(err);
            assert!(err <= VALUE_TOL, "({t}, {rate}): evaluate {value} vs f64 barycentric {reference}");
        } else {
            // Nearest point of the hull polygon in the normalised plane (the policy's own
            // metric), value linear along the edge.
            let (x, y) = ((t - t_off) * t_scale, (rate - r_off) * r_scale);
            let mut nearest = (f64::INFINITY, f64::NAN);
            for (k, &a) in hull.iter().enumerate() {
                let b = hull[(k + 1) % hull.len()];
                let (ax, ay, bx, by) = (nodes[a].3, nodes[a].4, nodes[b].3, nodes[b].4);
                let (dx, dy) = (bx - ax, by - ay);
                let s = (((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
                let d2 = (x - ax - s * dx).powi(2) + (y - ay - s * dy).powi(2);
                if d2 < nearest.0 {
                    nearest = (d2, nodes[a].2 + s * (nodes[b].2 - nodes[a].2));
                }
            }
            let err = (value - nearest.1).abs();
            worst_outside = worst_outside.max(err);
            assert!(
                err <= OUTSIDE_TOL,
                "({t}, {rate}): evaluate {value} vs f64 nearest hull value {}",
                nearest.1
            );
        }
        // Flags only where f32 rounding cannot decide containment differently: inside the mesh
        // the flag says whether the query is outside the region.
        let margin = region_margin((t - t_off) * t_scale, (rate - r_off) * r_scale);
        if best >= 1e-4 && margin.abs() >= 1e-4 {
            inside += 1;
            let expected = if margin < 0.0 { 4 } else { 0 };
            assert_eq!(
                flags, expected,
                "({t}, {rate}) is inside (min barycentric {best}, region margin {margin})"
            );
        } else if best <= -1e-4 {
            outside += 1;
            assert_eq!(flags, 4, "({t}, {rate}) is outside every triangle: flags must mark outside_hull (4)");
        } else {
            near_edge += 1;
        }
    }
    eprintln!(
        "evaluate vs f64: {inside} inside (worst |diff| {worst_inside:.2e} deg/h), {outside} outside \
         (nearest hull, worst {worst_outside:.2e}), {near_edge} within 1e-4 of the hull"
    );
    assert!(inside > 300 && outside > 300, "{inside} inside, {outside} outside");
}

// ---------------------------------------------------------------------------------------
// 3. Bad input
// ---------------------------------------------------------------------------------------

/// Requires `args` to fail with every `needles` in stderr, leaving `dir` as it was.
fn expect_failure(args: &[OsString], dir: &Path, out: Option<&Path>, needles: &[&str]) -> String {
    let before = entries(dir);
    let stderr = run_err(args);
    for needle in needles {
        assert!(stderr.contains(needle), "{args:?}: stderr lacks '{needle}':\n{stderr}");
    }
    if let Some(out) = out {
        assert!(!out.exists(), "{args:?}: wrote {}", out.display());
    }
    assert_eq!(entries(dir), before, "{args:?}: files left behind:\n{stderr}");
    stderr
}

/// A short (3 min) warm-up log, 3600 data rows: line `k + 2` is data row `k`.
fn short_log(dir: &Path, name: &str) -> (PathBuf, Vec<String>) {
    let path = dir.join(name);
    write_warmup(&path, 20.0, 3.0, 7);
    let lines = fs::read_to_string(&path).expect("read").lines().map(String::from).collect();
    (path, lines)
}

/// [`short_log`] `ok.csv` in `dir` and a model `model_name` fitted on it by `method`:
/// the log, its lines and the model.
fn short_log_and_model(dir: &Path, method: &str, model_name: &str) -> (PathBuf, Vec<String>, PathBuf) {
    let (ok, lines) = short_log(dir, "ok.csv");
    let model = dir.join(model_name);
    run_ok(args!["fit", "--method", method, "--out", &model, &ok]);
    (ok, lines, model)
}

/// A log's lines with a second gyro column, `gyro2`, a copy of the last column.
fn with_second_gyro<'a>(lines: impl Iterator<Item = &'a str>) -> Vec<String> {
    lines
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("{l},gyro2")
            } else {
                format!("{l},{}", l.rsplit(',').next().unwrap_or("0"))
            }
        })
        .collect()
}

fn write_lines(path: &Path, lines: &[String]) {
    fs::write(path, lines.join("\n") + "\n").expect("write log");
}

/// A log cut off mid-line (a power loss) is named as cut off on its last line; the same short
/// row with a line end after it, or before other rows, is not (review24b S1).
#[test]
fn a_log_cut_off_mid_line_is_named_as_such() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (_, lines) = short_log(dir.path(), "whole.csv");
    let cut_row: String = lines[3000].split(',').take(2).collect::<Vec<_>>().join(",");
    let mut kept: Vec<String> = lines[..3000].to_vec();
    kept.push(cut_row);
    let cut = dir.path().join("cut.csv");
    fs::write(&cut, kept.join("\n")).expect("write");
    let model = dir.path().join("m.fogm");
    let said = expect_failure(
        &args!["fit", "--out", &model, &cut],
        dir.path(),
        Some(&model),
        &[&format!("{}:3001:3:", cut.display())],
    );
    assert!(
        said.contains("this is the file's last line and the file ends in it without a line end: cut off"),
        "{said}"
    );
    let ended = dir.path().join("ended.csv");
    write_lines(&ended, &kept);
    let said = expect_failure(
        &args!["fit", "--out", &model, &ended],
        dir.path(),
        Some(&model),
        &["ended.csv:3001:3:"],
    );
    assert!(!said.contains("cut off"), "{said}");
}

#[test]
fn bad_log_rows_are_located_and_nothing_is_written() {
    let dir = TempDir::new().expect("tempdir");
    let (_, lines, model) = short_log_and_model(dir.path(), "poly", "ok.fogm");
    let out_model = dir.path().join("out.fogm");
    let out_csv = dir.path().join("out.csv");
    // (name, line 101 rewritten, column, reason)
    let line = 101;
    let previous_time = lines[line - 2].split(',').next().expect("time").to_string();
    let original: Vec<String> = lines[line - 1].split(',').map(String::from).collect();
    let cases: [(&str, String, usize, &str); 8] = [
        ("nonnumeric", format!("{},{},abc", original[0], original[1]), 3, "not a number (found 'abc')"),
        (
            "nonnumeric_temp",
            format!("{},2x.5,{}", original[0], original[2]),
            2,
            "not a number (found '2x.5')",
        ),
        ("nan", format!("{},{},NaN", original[0], original[1]), 3, "NaN or infinite"),
        ("inf", format!("{},{},inf", original[0], original[1]), 3, "NaN or infinite"),
        ("short", format!("{},{}", original[0], original[1]), 3, "fewer fields than the header"),
        (
            "duplicate",
            format!("{previous_time},{},{}", original[1], original[2]),
            1,
            "time equal to the previous row",
        ),
        ("backward", format!("1.00,{},{}", original[1], original[2]), 1, "time before the previous row"),
        ("sentinel", format!("{},-999,{}", original[0], original[2]), 2, "below -273.15 C or above 1000 C"),
    ];
    for (name, bad, column, reason) in cases {
        let mut l = lines.clone();
        l[line - 1] = bad;
        let log = dir.path().join(format!("{name}.csv"));
        write_lines(&log, &l);
        let place = format!("{}:{line}:{column}:", log.display());
        let fit_args = args!["fit", "--out", &out_model, &log];
        expect_failure(&fit_args, dir.path(), Some(&out_model), &[&place, reason, "--skip-bad-rows"]);
        // compensate replays a sentinel temperature flagged BAD_INPUT, as the firmware does
        // (`compensate_keeps_a_sentinel_temperature_row_flagged_as_the_firmware_does`).
        if name != "sentinel" {
            let comp_args = args!["compensate", "--model", &model, &log, "--out", &out_csv];
            expect_failure(&comp_args, dir.path(), Some(&out_csv), &[&place, reason]);
        }
        let val_args = args!["validate", "--model", &model, &log];
        expect_failure(&val_args, dir.path(), None, &[&place, reason]);
    }
}

/// Logs as other lab tools write them get the hint that fits, not "use --skip-bad-rows"
/// alone, which dropped their data (review32a F1, F3, F4, F5, F6, F8): a blank cell in
/// space-aligned columns, words and NaN for a missing temperature, a header repeated after a
/// logger restart, a wrapped microsecond counter, thousands points with a decimal comma,
/// unquoted thousands commas (F9), a lost sample.
#[test]
fn logs_of_other_lab_tools_get_the_hint_that_fits() {
    let dir = TempDir::new().expect("tempdir");
    let out = dir.path().join("m.fogm");
    let rows = |line: &dyn Fn(u32) -> String| (0..400).map(line).collect::<Vec<_>>().join("\n");
    let plain = |k: u32| format!("{k},{:.2},1.5", 20.0 + 0.05 * f64::from(k));
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "spaced.txt",
            format!(
                "  time_s  temp_c  gyro_dph  rh_pct\n{}",
                rows(&|k| if k == 5 {
                    format!("{k:>8}  {:>6}  {:>8}  {:>6}", "", "1.5", "45.0")
                } else {
                    format!("{k:>8}  {:>6.2}  {:>8}  {:>6}", 20.0 + 0.05 * f64::from(k), "1.5", "45.0")
                })
            ),
            vec![
                ":7:4: column 'rh_pct'",
                "a blank cell, which vanishes there",
                "another delimiter",
                "--skip-lines 1 --columns",
            ],
        ),
        (
            "na.csv",
            format!(
                "time_s,temp_c,gyro_dph\n{}",
                rows(&|k| if k == 9 { format!("{k},N/A,1.5") } else { plain(k) })
            ),
            vec![":11:2: column 'temp_c'", "(found 'N/A')", "empty those cells"],
        ),
        (
            "nan.csv",
            format!(
                "time_s,temp_c,gyro_dph\n{}",
                rows(&|k| if k == 9 { format!("{k},NaN,1.5") } else { plain(k) })
            ),
            vec![":11:2: column 'temp_c'", "empty those cells"],
        ),
        (
            "thousands.csv",
            format!(
                "time_s,temp_c,gyro_dph\n{}",
                rows(&|k| if k >= 300 {
                    format!("{},{:03}.000,20.5,1.5", k / 100, k % 100)
                } else {
                    plain(k)
                })
            ),
            vec![":302:1: column 'time_s'", "(found '3,000.000')", "without thousands separators"],
        ),
        (
            "restart.csv",
            format!(
                "time_s,temp_c,gyro_dph\n{}",
                rows(&|k| if k == 200 { "time_s,temp_c,gyro_dph".into() } else { plain(k % 200) })
            ),
            vec![":202:1:", "the header again", "split the file there"],
        ),
        (
            "wrap.csv",
            format!(
                "time_us,temp_c,gyro_dph\n{}",
                rows(&|k| format!(
                    "{},{:.2},1.5",
                    (4_294_000_000_u64 + u64::from(k) * 2_000_000) % (1 << 32),
                    20.0
                ))
            ),
            vec!["time before the previous row", "a 32-bit counter that wrapped", "--sample-rate-hz"],
        ),
        (
            "lost.csv",
            format!(
                "time_s,temp_c,gyro_dph\n{}",
                rows(&|k| if k % 2 == 1 { format!("{k},,") } else { plain(k) })
            ),
            vec![
                ":3:3: column 'gyro_dph'",
                "empty required cell",
                "a lost sample?",
                "channels logged on separate rows",
            ],
        ),
    ];
    for (name, text, needles) in cases {
        let log = dir.path().join(name);
        fs::write(&log, text).expect("write");
        let mut args = args!["fit", "--out", &out, &log];
        if name == "wrap.csv" {
            args.extend(args!["--time-column", "time_us", "--time-unit", "us"]);
        }
        expect_failure(&args, dir.path(), Some(&out), &needles);
        fs::remove_file(&log).expect("remove");
    }
    // Thousands points in a log read with a decimal comma: not "give --decimal-mark point".
    let log = dir.path().join("comma.csv");
    let text = format!(
        "time_s;temp_c;gyro_dph\n{}",
        rows(&|k| if k == 300 { "1.000,5;20,5;1,5".into() } else { format!("{k},5;20,5;1,5") })
    );
    fs::write(&log, text).expect("write");
    let args = args!["fit", "--out", &out, &log, "--decimal-mark", "comma"];
    let stderr = expect_failure(&args, dir.path(), Some(&out), &[":302:1:", "thousands separators"]);
    assert!(!stderr.contains("give --decimal-mark point"), "{stderr}");
    // A units row under the header: the hint's shape is recorded in the model, so validate
    // then reads the log with no option given (F12); below a banner the units row is still
    // one, not the header again (review32b F4).
    let log = dir.path().join("units.csv");
    fs::write(&log, format!("time_s,temp_c,gyro_dph\ns,degC,deg/h\n{}", rows(&plain))).expect("write");
    expect_failure(&args!["fit", "--out", &out, &log], dir.path(), Some(&out), &[":2:1:", "--columns a,b,c"]);
    let banner = format!("logger v2\nstarted 12:00\ntime_s,temp_c,gyro_dph\ns,degC,deg/h\n{}", rows(&plain));
    fs::write(&log, banner).expect("write");
    let args = args!["fit", "--out", &out, &log, "--skip-lines", "2"];
    let stderr =
        expect_failure(&args, dir.path(), Some(&out), &[":4:1:", "a units row under the header: skip both"]);
    assert!(!stderr.contains("split the file"), "{stderr}");
    let columns = ["--skip-lines", "4", "--columns", "time_s,temp_c,gyro_dph"];
    let mut shaped = args!["fit", "--method", "poly", "--out", &out, &log];
    shaped.extend(columns.iter().map(OsString::from));
    let output = cal().args(&shaped).output().expect("run");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let output = cal().args(args!["validate", "--model", &out, &log]).output().expect("run");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    fs::remove_file(&out).expect("remove");
    // A spreadsheet's serial days read as seconds: 400 rows in 0.005 s (F7).
    let log = dir.path().join("days.csv");
    let days = rows(&|k| {
        format!("{:.10},{:.2},1.5", 46_085.5 + f64::from(k) / 86_400.0, 20.0 + 0.05 * f64::from(k))
    });
    fs::write(&log, format!("time_days,temp_c,gyro_dph\n{days}")).expect("write");
    let args = args!["fit", "--out", &out, &log, "--time-column", "time_days"];
    expect_failure(
        &args,
        dir.path(),
        Some(&out),
        &["faster than any gyro's logger", "convert them to seconds"],
    );
    // Two gyro columns in one flag: the flag is repeated instead (F15).
    let log = dir.path().join("two.csv");
    fs::write(&log, format!("time_s,temp_c,gx,gy\n{}", rows(&|k| format!("{k},20,1,2")))).expect("write");
    let args = args!["fit", "--out", &out, &log, "--gyro-column", "gx,gy"];
    expect_failure(
        &args,
        dir.path(),
        Some(&out),
        &["no column named 'gx,gy'", "repeat the flag", "--gyro-column gy"],
    );
}

#[test]
fn bad_log_files_are_named_and_nothing_is_written() {
    let dir = TempDir::new().expect("tempdir");
    let (ok, lines, model) = short_log_and_model(dir.path(), "poly", "ok.fogm");
    let out_model = dir.path().join("out.fogm");
    let out_csv = dir.path().join("out.csv");

    let missing = dir.path().join("missing_column.csv");
    let mut l = lines.clone();
    l[0] = "time_s,temp_c,gyro".into();
    write_lines(&missing, &l);
    let nothing = dir.path().join("no_such_log.csv");
    let no_csv = dir.path().join("no_csv");
    fs::create_dir(&no_csv).expect("mkdir");
    fs::write(no_csv.join("notes.txt"), "not a log").expect("write");

    let missing_msg =
        format!("{}: no column named 'gyro_dph' (the header has: time_s, temp_c, gyro)", missing.display());
    let nothing_msg = nothing.display().to_string();
    let no_csv_msg = format!(
        "{}: folder holds no *.csv files (1 other file, e.g. {}: give them as paths, e.g. {}/*.txt)",
        no_csv.display(),
        no_csv.join("notes.txt").display(),
        no_csv.display()
    );
    for (log, msg) in [(&missing, &missing_msg), (&nothing, &nothing_msg), (&no_csv, &no_csv_msg)] {
        let fit_args = args!["fit", "--out", &out_model, log];
        expect_failure(&fit_args, dir.path(), Some(&out_model), &[msg.as_str()]);
        let val_args = args!["validate", "--model", &model, log];
        expect_failure(&val_args, dir.path(), None, &[msg.as_str()]);
        if log != &no_csv {
            let comp_args = args!["compensate", "--model", &model, log, "--out", &out_csv];
            expect_failure(&comp_args, dir.path(), Some(&out_csv), &[&log.display().to_string()]);
            expect_failure(&args!["allan", log], dir.path(), None, &[&log.display().to_string()]);
        }
    }
    // A bad log among good ones is still named.
    let fit_args = args!["fit", "--out", &out_model, &ok, &missing];
    expect_failure(&fit_args, dir.path(), Some(&out_model), &[&missing_msg]);
}

#[test]
fn empty_or_header_only_log_is_rejected_naming_the_file() {
    let dir = TempDir::new().expect("tempdir");
    let (ok, lines, model) = short_log_and_model(dir.path(), "poly", "ok.fogm");
    let header = dir.path().join("header_only.csv");
    write_lines(&header, &lines[..1]);
    let empty = dir.path().join("empty.csv");
    fs::write(&empty, "").expect("write");
    let out_model = dir.path().join("out.fogm");
    let out_csv = dir.path().join("out.csv");
    for (log, why) in [(&header, "no data rows"), (&empty, "no header row")] {
        let name = log.display().to_string();
        let needles = [name.as_str(), why];
        for method in ["poly", "mesh", "hybrid"] {
            let args = args!["fit", "--method", method, "--out", &out_model, log];
            expect_failure(&args, dir.path(), Some(&out_model), &needles);
        }
        // Also next to a good log: a run without data must not pass silently.
        let args = args!["fit", "--out", &out_model, &ok, log];
        expect_failure(&args, dir.path(), Some(&out_model), &needles);
        let args = args!["compensate", "--model", &model, log, "--out", &out_csv];
        expect_failure(&args, dir.path(), Some(&out_csv), &needles);
        let args = args!["validate", "--model", &model, log];
        expect_failure(&args, dir.path(), None, &needles);
        expect_failure(&args!["allan", log], dir.path(), None, &[name.as_str()]);
    }
}

#[test]
fn corrupt_and_truncated_models_are_rejected() {
    let dir = TempDir::new().expect("tempdir");
    let (ok, _, good) = short_log_and_model(dir.path(), "hybrid", "good.fogm");
    let blob = fs::read(&good).expect("read model");
    let points = dir.path().join("points.csv");
    fs::write(&points, "temp_c,rate_c_per_min\n21.0,0.5\n").expect("write points");
    let n = blob.len();
    let mut variants: Vec<(String, Vec<u8>)> = Vec::new();
    for at in [0, 6, 40, n / 2, n - 5, n - 1] {
        let mut b = blob.clone();
        b[at] ^= 0x10;
        variants.push((format!("flipped_{at}.fogm"), b));
    }
    for len in [0, 10, n / 2, n - 1] {
        variants.push((format!("truncated_{len}.fogm"), blob[..len].to_vec()));
    }
    let out = dir.path().join("out.csv");
    let out_rs = dir.path().join("out.rs");
    for (name, bytes) in variants {
        let model = dir.path().join(&name);
        fs::write(&model, bytes).expect("write model");
        let msg = format!("{}: not a valid model", model.display());
        let m = &model;
        let cases = [
            args!["validate", "--model", m, &ok],
            args!["compensate", "--model", m, &ok, "--out", &out],
            args!["inspect", m, "--json"],
            args!["evaluate", "--model", m, "--points", &points, "--out", &out],
            args!["export", "--model", m, "--format", "rust", "--out", &out_rs],
        ];
        for args in cases {
            let stderr = expect_failure(&args, dir.path(), Some(&out), &[&msg]);
            assert!(!out_rs.exists(), "{stderr}");
        }
    }
}

#[test]
fn evaluate_points_with_bad_cells_are_located() {
    let dir = TempDir::new().expect("tempdir");
    let (_, _, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let out = dir.path().join("values.csv");
    // (points file, what follows the file name in the error)
    let cases = [
        (
            "temp_c,rate_c_per_min\n21,0.5\n22,abc\n",
            ":3:2: column 'rate_c_per_min': not a number (found 'abc')",
        ),
        ("temp_c,rate_c_per_min\n21,0.5\nhot,0.1\n", ":3:1: column 'temp_c': not a number (found 'hot')"),
        ("temp_c,rate_c_per_min\n21,0.5\n22,0.4\nNaN,0.1\n", ":4:1: column 'temp_c': NaN or infinite"),
        ("temp,rate_c_per_min\n21,0.5\n", ": no column named 'temp_c'"),
        ("temp_c rate_c_per_min\n21 0.5\n", ":1: the columns are separated by spaces"),
        // Review27a 12: rows of another length at their line and column; below absolute zero.
        (
            "temp_c,rate_c_per_min\n21,0.5\n22\n",
            ":3:2: column 'rate_c_per_min': fewer fields than the header (1 of 2)",
        ),
        ("temp_c,rate_c_per_min\n21,0.5,7\n", ":2: 3 fields where the header names 2"),
        ("temp_c,rate_c_per_min\n-300,0.1\n", ":2:1: column 'temp_c': not a temperature a sensor reads"),
        ("", ": empty file"),
        ("# grid\ntemp_c,rate_c_per_min\n# cold\n21,abc\n", ":4:2: column 'rate_c_per_min': not a number"),
    ];
    for (i, (text, needle)) in cases.iter().enumerate() {
        let points = dir.path().join(format!("points{i}.csv"));
        fs::write(&points, text).expect("write points");
        let msg = format!("{}{needle}", points.display());
        let args = args!["evaluate", "--model", &model, "--points", &points, "--out", &out];
        expect_failure(&args, dir.path(), Some(&out), &[&msg]);
    }
    // `#` comment lines and blank lines are skipped, as in the logs (review27a 12).
    let commented = dir.path().join("commented.csv");
    // A quote in a comment must not open a field (review28a 3); a line of blanks is blank.
    fs::write(
        &commented,
        "# grid for the \"report\"\ntemp_c,rate_c_per_min\n21,0.5\n   \n# cold end\n-60,0\n",
    )
    .expect("write");
    let plain = dir.path().join("plain.csv");
    fs::write(&plain, "temp_c,rate_c_per_min\n21,0.5\n-60,0\n").expect("write");
    assert_eq!(
        run_ok(args!["evaluate", "--model", &model, "--points", &commented]),
        run_ok(args!["evaluate", "--model", &model, "--points", &plain])
    );
    // Semicolons or tabs (a spreadsheet's export) read as commas do (review6 F17).
    let comma = dir.path().join("comma.csv");
    fs::write(&comma, "temp_c,rate_c_per_min\n21,0.5\n-60,0\n").expect("write points");
    let by_comma = run_ok(args!["evaluate", "--model", &model, "--points", &comma]);
    for (name, text) in [
        ("semi.csv", "temp_c;rate_c_per_min\n21;0.5\n-60;0\n"),
        ("tab.csv", "temp_c\trate_c_per_min\n21\t0.5\n-60\t0\n"),
    ] {
        let points = dir.path().join(name);
        fs::write(&points, text).expect("write points");
        assert_eq!(run_ok(args!["evaluate", "--model", &model, "--points", &points]), by_comma, "{name}");
    }
    // A European grid (decimal commas, semicolons) reads with --decimal-mark comma, and
    // without it the error says so (review12 F12); an axis the model lacks names the ones it has.
    let european = dir.path().join("european.csv");
    fs::write(
        &european,
        "temp_c;rate_c_per_min
21;0,5
-60;0
",
    )
    .expect("write points");
    assert_eq!(
        run_ok(args!["evaluate", "--model", &model, "--points", &european, "--decimal-mark", "comma"]),
        by_comma
    );
    let msg = format!(
        "{}:2:2: column 'rate_c_per_min': not a number (found '0,5'); the points seem to write numbers with a \
         decimal comma: use --decimal-mark comma",
        european.display()
    );
    expect_failure(
        &args!["evaluate", "--model", &model, "--points", &european, "--out", &out],
        dir.path(),
        Some(&out),
        &[&msg],
    );
    expect_failure(
        &args!["evaluate", "--model", &model, "--points", &comma, "--axis", "1", "--out", &out],
        dir.path(),
        Some(&out),
        &["axis 1 requested but the model has 1 axis, numbered 0"],
    );
}

#[test]
fn degenerate_point_sets() {
    let logs = logs();
    let dir = TempDir::new().expect("tempdir");
    // A chamber at constant temperature: every feature is the same (T, 0) point.
    let flat = dir.path().join("flat.csv");
    let mut r = rng(3);
    let mut text = String::from("time_s,temp_c,gyro_dph\n");
    for k in 0..(RATE_HZ as usize * 600) {
        text.push_str(&format!(
            "{:.2},25.0000,{:.5}\n",
            k as f64 / RATE_HZ,
            1.0 + NOISE_DPH * gaussian(&mut r)
        ));
    }
    fs::write(&flat, text).expect("write flat log");
    let out = dir.path().join("flat.fogm");
    let args = args!["fit", "--method", "mesh", "--out", &out, &flat];
    expect_failure(&args, dir.path(), Some(&out), &["cannot build a mesh", "points do not span an area"]);
    // The hybrid needs no mesh there: the polynomial (a constant) already leaves only noise.
    let doc = json(&run_ok(args!["fit", "--method", "hybrid", "--json", "--out", &out, &flat]));
    assert_eq!(arr(&doc["axes"])[0]["mesh_nodes"].as_u64(), Some(0), "{doc}");
    fs::remove_file(&out).expect("remove the hybrid model");
    // The polynomial falls back to a constant.
    let doc = fit("poly", &out, &[&flat]);
    let terms = arr(&arr(&doc["axes"])[0]["poly"]["terms"]);
    assert_eq!(terms.len(), 1, "{terms:?}");
    assert!((f(&terms[0]["coefficient_dph"]) - 1.0).abs() < 0.01, "{terms:?}");

    // One warm-up run: nearly a line in the (T, dT/dt) plane, but the lagged features and
    // the quantised temperature give it some width, so the mesh is thin, not degenerate.
    let one = dir.path().join("one.fogm");
    let doc = fit("mesh", &one, &[&logs.cal.join("run3.csv")]);
    let axis = &arr(&doc["axes"])[0];
    assert!(axis["mesh_triangles"].as_u64().unwrap_or(0) >= 1, "{axis}");
    // A run at another chamber temperature lies outside that hull: it is flagged and
    // compensated with the nearest hull value (the fallback), not rejected.
    let v = json(&run_ok(args!["validate", "--json", "--model", &one, &logs.val.join("run0.csv")]));
    let run = &arr(&v["runs"])[0];
    let outside = run["flag_samples"]["outside_hull"].as_u64().unwrap_or(0);
    let samples = run["samples"].as_u64().unwrap_or(0);
    eprintln!(
        "single-run mesh: {} triangles; a -33 C run is outside the hull for {outside} of {samples} samples",
        axis["mesh_triangles"]
    );
    assert!(outside > samples / 2, "{outside} of {samples} samples flagged outside the hull");
}

#[test]
fn skip_bad_rows_reports_count_and_where() {
    let dir = TempDir::new().expect("tempdir");
    // Line L of the file is lines[L - 1] (line 1 is the header).
    let (_, mut lines) = short_log(dir.path(), "ok.csv");
    let previous = lines[1500 - 2].split(',').next().expect("time").to_string();
    let cells = |l: &str| l.split(',').map(String::from).collect::<Vec<_>>();
    let c = cells(&lines[49]);
    lines[49] = format!("{},{},abc", c[0], c[1]);
    let c = cells(&lines[499]);
    lines[499] = format!("{},NaN,{}", c[0], c[2]);
    let c = cells(&lines[1499]);
    lines[1499] = format!("{previous},{},{}", c[1], c[2]);
    let log = dir.path().join("three_bad.csv");
    write_lines(&log, &lines);
    let model = dir.path().join("m.fogm");

    // Without the option: stops at the first.
    let args = args!["fit", "--out", &model, &log];
    expect_failure(&args, dir.path(), Some(&model), &[&format!("{}:50:3:", log.display())]);

    let out = cal()
        .args(args!["fit", "--method", "poly", "--skip-bad-rows", "--json"])
        .args(args!["--out", &model, &log])
        .assert()
        .success()
        .stderr(predicate::str::contains(format!(
            "{}: skipped 3 bad rows of {} rows ({} %) (--skip-bad-rows); first ones:",
            log.display(),
            lines.len() - 1,
            share_text(300.0 / (lines.len() - 1) as f64)
        )))
        .stderr(predicate::str::contains("line 50 column 3 'gyro_dph': not a number (found 'abc')"))
        .stderr(predicate::str::contains("line 500 column 2 'temp_c': NaN or infinite (found 'NaN')"))
        .stderr(predicate::str::contains("line 1500 column 1 'time_s': time equal to the previous row"));
    let doc = json(&String::from_utf8_lossy(&out.get_output().stdout));
    let run = &arr(&doc["runs"])[0];
    assert_eq!(run["skipped_rows"], 3, "{run}");
    assert_eq!(run["rows"].as_u64(), Some(lines.len() as u64 - 1 - 3), "{run}");
    let where_: Vec<(u64, u64, &str)> = arr(&run["first_skipped"])
        .iter()
        .map(|s| {
            (
                s["line"].as_u64().unwrap_or(0),
                s["column"].as_u64().unwrap_or(0),
                s["column_name"].as_str().unwrap_or(""),
            )
        })
        .collect();
    assert_eq!(where_, vec![(50, 3, "gyro_dph"), (500, 2, "temp_c"), (1500, 1, "time_s")]);

    // compensate skips the other two, says so, and writes one row per accepted row; the NaN
    // temperature it keeps, flagged BAD_INPUT as the firmware flags it (review18 F3).
    let comp = dir.path().join("comp.csv");
    cal()
        .args(args!["compensate", "--skip-bad-rows", "--model", &model, &log])
        .args(args!["--out", &comp])
        .assert()
        .success()
        .stderr(
            predicate::str::contains("skipped 2 bad rows")
                .and(predicate::str::contains("line 1500 column 1"))
                .and(
                    predicate::str::contains("1 of")
                        .and(predicate::str::contains("flag BAD_INPUT in the output")),
                ),
        );
    assert_eq!(fs::read_to_string(&comp).expect("read").lines().count(), lines.len() - 2);
}

#[test]
fn validate_reports_skipped_rows() {
    let dir = TempDir::new().expect("tempdir");
    let (_, mut lines, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let c: Vec<String> = lines[49].split(',').map(String::from).collect();
    lines[49] = format!("{},{},abc", c[0], c[1]);
    let log = dir.path().join("one_bad.csv");
    write_lines(&log, &lines);
    let out = cal()
        .args(args!["validate", "--skip-bad-rows", "--json", "--model", &model, &log])
        .assert()
        .success()
        .stderr(
            predicate::str::contains("skipped 1 bad row of 3600 rows (0.03 %) (")
                .and(predicate::str::contains("line 50 column 3")),
        );
    let doc = json(&String::from_utf8_lossy(&out.get_output().stdout));
    assert_eq!(arr(&doc["runs"])[0]["skipped_rows"], 1);
}

// ---------------------------------------------------------------------------------------
// 4. Help and usage
// ---------------------------------------------------------------------------------------

#[test]
fn help_of_every_command_names_its_key_options() {
    let top = run_ok(args!["--help"]);
    for command in ["fit", "compensate", "validate", "evaluate", "inspect", "export", "allan"] {
        assert!(top.contains(command), "top-level help lacks '{command}':\n{top}");
    }
    let cases = [
        ("fit", "--method poly mesh hybrid --out --json --skip-bad-rows --window-s --thinning <LOGS>..."),
        ("compensate", "--model --out <LOG> --skip-bad-rows --gyro-unit"),
        ("validate", "--model --json --tau-s --overlapping --detrend --exclude-first-s <LOGS>..."),
        ("evaluate", "--model --points --axis --out temp_c rate_c_per_min"),
        ("inspect", "<MODEL> --json"),
        ("export", "--model --format rust --out --name"),
        ("allan", "<LOG> --json --gyro-column"),
    ];
    for (command, options) in cases {
        let help = run_ok(args![command, "--help"]);
        for option in options.split(' ') {
            assert!(help.contains(option), "'{command} --help' lacks '{option}':\n{help}");
        }
    }
}

#[test]
fn unknown_command_or_option_fails() {
    cal()
        .arg("calibrate")
        .assert()
        .failure()
        .stderr(predicate::str::contains("unrecognized subcommand 'calibrate'"));
    cal().assert().failure().stderr(predicate::str::contains("Usage"));
    cal()
        .args(args!["fit", "--bogus", "x.csv", "--out", "x.fogm"])
        .assert()
        .failure()
        .stderr(predicate::str::contains("--bogus"));
    cal().args(args!["export", "--model", "m", "--format", "pascal", "--out", "x"]).assert().failure();
}

/// Runs logged in two positions carry the Earth rate's two projections: without a runs file
/// `fit` warns (`run_offsets`) that the runs differ by constants; with one, it subtracts
/// each run's `input_rate_dph` and fits the same model as on the logs without the rates
/// (the oracle: the original logs, to the rounding of the written gyro).
#[test]
fn input_rates_from_a_runs_file_are_subtracted_and_their_absence_is_warned() {
    let logs = logs();
    let dir = TempDir::new().expect("tempdir");
    let shifted = dir.path().join("shifted");
    fs::create_dir(&shifted).expect("mkdir");
    let mut runs_csv = String::from("run,position,input_rate_dph\n");
    let originals: Vec<PathBuf> = (0..8).map(|i| logs.cal.join(format!("run{i}.csv"))).collect();
    for (i, log) in originals.iter().enumerate() {
        let (position, rate) = if i % 2 == 0 { ("up", 9.66) } else { ("down", -9.66) };
        runs_csv.push_str(&format!("run{i},{position},{rate}\n"));
        let text = fs::read_to_string(log).expect("read log");
        let mut lines = text.lines();
        let mut out = vec![lines.next().expect("header").to_string()];
        for line in lines {
            let cells: Vec<&str> = line.split(',').collect();
            let gyro: f64 = cells[2].parse().expect("gyro");
            out.push(format!("{},{},{:.5}", cells[0], cells[1], gyro + rate));
        }
        write_lines(&shifted.join(format!("run{i}.csv")), &out);
    }
    let runs = dir.path().join("runs.csv");
    fs::write(&runs, runs_csv).expect("write runs");
    let fit_json = |logs: &Path, extra: &[&Path]| -> Value {
        let mut args = args!["fit", "--method", "poly", "--json", "--out", dir.path().join("m.fogm")];
        args.extend(FAST_FIT.split(' ').map(OsString::from));
        for e in extra {
            args.extend(args!["--runs", e]);
        }
        args.push(logs.into());
        json(&run_ok(args))
    };
    let kinds = |doc: &Value| -> Vec<String> {
        arr(&doc["warnings"]).iter().map(|w| w["kind"].as_str().unwrap_or_default().to_string()).collect()
    };
    let rms = |doc: &Value| f(&doc["axes"][0]["residual_rms_dph"]);
    let original = fit_json(&logs.cal, &[]);
    let without = fit_json(&shifted, &[]);
    let with = fit_json(&shifted, &[&runs]);
    assert!(kinds(&without).contains(&"run_offsets".to_string()), "{:?}", kinds(&without));
    assert!(rms(&without) > 5.0, "the rates stay in the residual: {}", rms(&without));
    assert!(!kinds(&with).contains(&"run_offsets".to_string()), "{:?}", kinds(&with));
    assert!(!kinds(&original).contains(&"run_offsets".to_string()), "{:?}", kinds(&original));
    assert!((rms(&with) - rms(&original)).abs() < 1e-6, "{} vs {}", rms(&with), rms(&original));
    check_validated_means(dir.path(), &shifted, &runs);
}

/// `validate`'s per-run means (review24a S1: a model that leaves a run's bias behind) on the
/// shifted logs of [`input_rates_from_a_runs_file_are_subtracted_and_their_absence_is_warned`]
/// with the model fitted with their rates. The oracle: `compensate`'s output of the same log,
/// averaged over the samples it corrected (flags without WARMING_UP), less the run's rate;
/// to the rounding of the written CSV (6 decimals). Without `--runs` the means keep the rate.
fn check_validated_means(dir: &Path, shifted: &Path, runs: &Path) {
    let model = dir.join("m.fogm");
    let validate = |extra: &[&Path]| -> Value {
        let mut args = args!["validate", "--json", "--model", &model];
        for e in extra {
            args.extend(args!["--runs", e]);
        }
        args.push(shifted.into());
        json(&run_ok(args))
    };
    let (with, without) = (validate(&[runs]), validate(&[]));
    let out = dir.join("compensated.csv");
    for (i, (r, bare)) in arr(&with["runs"]).iter().zip(arr(&without["runs"])).enumerate() {
        let rate = if i % 2 == 0 { 9.66 } else { -9.66 };
        assert_eq!(f(&r["input_rate_dph"]), rate, "{r}");
        assert!(bare["input_rate_dph"].is_null(), "{bare}");
        run_ok(args!["compensate", "--model", &model, "--out", &out, shifted.join(format!("run{i}.csv"))]);
        let text = fs::read_to_string(&out).expect("read compensated");
        let corrected: Vec<(f64, f64)> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|c| c.parse().expect("number")).collect::<Vec<f64>>())
            .filter(|c| (c[4] as u32) & 1 == 0)
            .map(|c| (c[1], c[2]))
            .collect();
        let n = corrected.len() as f64;
        let raw_mean = corrected.iter().map(|c| c.0).sum::<f64>() / n - rate;
        let comp_mean = corrected.iter().map(|c| c.1).sum::<f64>() / n - rate;
        assert!((f(&r["raw_mean_dph"]) - raw_mean).abs() < 2e-6, "{r} against {raw_mean}");
        assert!((f(&r["compensated_mean_dph"]) - comp_mean).abs() < 2e-6, "{r} against {comp_mean}");
        assert!((f(&bare["compensated_mean_dph"]) - (comp_mean + rate)).abs() < 2e-6, "{bare}");
        // The model was fitted with the rates subtracted: what it leaves is near zero,
        // against a raw mean that is the warm-up bias (tens of deg/h here).
        assert!(comp_mean.abs() < 0.05 * raw_mean.abs(), "{comp_mean} against raw {raw_mean}");
    }
}

/// Output into a pipe whose reader has gone (`fogtemp-cal allan log | head -1`) ends the
/// command quietly with status 0, not with std's "failed printing to stdout" panic; and
/// `allan` reads a log without a temperature column (it needs none).
#[test]
fn a_closed_output_pipe_ends_quietly_and_allan_needs_no_temperature() {
    let dir = TempDir::new().expect("tempdir");
    let (ok, lines) = short_log(dir.path(), "ok.csv");
    let gyro_only: Vec<String> = lines
        .iter()
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            format!("{},{}", c[0], c[2])
        })
        .collect();
    let no_temp = dir.path().join("gyro_only.csv");
    write_lines(&no_temp, &gyro_only);
    let with_temp = run_ok(args!["allan", &ok, "--json"]);
    let without = run_ok(args!["allan", &no_temp, "--json"]);
    let curve = |doc: &str| json(doc)["axes"][0]["curve"].clone();
    assert_eq!(curve(&with_temp), curve(&without), "the same gyro gives the same Allan deviation");
    for _ in 0..3 {
        let (status, stderr) = run_with_stdout_closed(args!["allan", &ok]);
        assert!(status.success() && !stderr.contains("panicked"), "{status:?}: {stderr}");
    }
}

/// Runs the command with its stdout closed at once (a reader that has gone, as `| head`
/// leaves it): its exit status and stderr.
fn run_with_stdout_closed(args: Vec<OsString>) -> (std::process::ExitStatus, String) {
    let mut child = std::process::Command::new(common::fogtemp_cal_bin())
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    drop(child.stdout.take());
    let output = child.wait_with_output().expect("wait");
    (output.status, String::from_utf8_lossy(&output.stderr).into_owned())
}

/// A model whose axes and the log's gyro columns differ in number is used on the first of
/// them, and validate and compensate say so.
#[test]
fn a_model_and_a_log_of_different_axis_counts_are_warned() {
    let dir = TempDir::new().expect("tempdir");
    let (ok, lines) = short_log(dir.path(), "ok.csv");
    let two = with_second_gyro(lines.iter().map(String::as_str));
    let two_log = dir.path().join("two.csv");
    write_lines(&two_log, &two);
    let model = dir.path().join("two.fogm");
    let mut fit_args =
        args!["fit", "--method", "poly", "--gyro-column", "gyro_dph", "--gyro-column", "gyro2"];
    fit_args.extend(args!["--out", &model, &two_log]);
    run_ok(fit_args);
    // Nothing named: the model's two columns are read, and the one-gyro log lacks the second.
    let c = dir.path().join("c.csv");
    for args in
        [args!["validate", "--model", &model, &ok], args!["compensate", "--model", &model, &ok, "--out", &c]]
    {
        expect_failure(
            &args,
            dir.path(),
            Some(&c),
            &[
                "the log was read with the columns",
                "records (gyro gyro_dph, gyro2; temperature temp_c)",
                "no column named 'gyro2'",
            ],
        );
    }
    // Named: the first axis alone, with the warning.
    for args in [
        args!["validate", "--model", &model, "--gyro-column", "gyro_dph", &ok],
        args!["compensate", "--model", &model, "--gyro-column", "gyro_dph", &ok, "--out", &c],
    ] {
        let output = cal().args(&args).output().expect("run");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            output.status.success() && stderr.contains("has 2 axes but the log is read with 1 gyro column ("),
            "{args:?}:\n{stderr}"
        );
    }
    let quiet = cal()
        .args(args![
            "validate",
            "--model",
            &model,
            "--gyro-column",
            "gyro_dph",
            "--gyro-column",
            "gyro2",
            &two_log
        ])
        .output()
        .expect("run");
    assert!(!String::from_utf8_lossy(&quiet.stderr).contains("axes but the log"));
}

/// Review6 F2: a model records the log column each axis was fitted on; `validate` and
/// `compensate` read those when none are named, refuse a gyro column the model fitted on
/// another axis (a swapped pair used to make axis 1 4.6 times worse without a word), and note
/// a name the model does not know.
#[test]
fn log_columns_are_matched_to_axes_by_the_names_the_model_records() {
    let dir = TempDir::new().expect("tempdir");
    let (_, lines) = short_log(dir.path(), "ok.csv");
    // A second axis with another drift: the negated gyro plus 0.01 deg/h per C.
    let with_second = |gyro_name: &str| -> Vec<String> {
        let mut out = vec![format!("time_s,temp_c,{gyro_name},gyro2")];
        for l in &lines[1..] {
            let cells: Vec<f64> = l.split(',').map(|c| c.parse().expect("number")).collect();
            out.push(format!("{l},{:.5}", -cells[2] + 0.01 * (cells[1] - 20.0)));
        }
        out
    };
    let (two, renamed) = (dir.path().join("two.csv"), dir.path().join("renamed.csv"));
    write_lines(&two, &with_second("gyro_dph"));
    write_lines(&renamed, &with_second("gx"));
    let model = dir.path().join("two.fogm");
    run_ok(args![
        "fit",
        "--method",
        "poly",
        "--gyro-column",
        "gyro_dph",
        "--gyro-column",
        "gyro2",
        "--out",
        &model,
        &two
    ]);
    let inspected = json(&run_ok(args!["inspect", "--json", &model]));
    let names: Vec<(&str, &str)> = arr(&inspected["axes"])
        .iter()
        .map(|a| (a["gyro_column"].as_str().expect("gyro"), a["temp_column"].as_str().expect("temp")))
        .collect();
    assert_eq!(names, [("gyro_dph", "temp_c"), ("gyro2", "temp_c")]);
    assert_eq!(inspected["format_version"], 6);

    // Nothing named reads what naming the columns in the model's order reads.
    let compensated = |args: Vec<OsString>| -> Vec<f64> {
        arr(&json(&run_ok(args))["runs"]).iter().map(|r| f(&r["compensated_bias_stability_dph"])).collect()
    };
    // (10 s windows: the log is 3 minutes long.)
    let by_default = compensated(args!["validate", "--json", "--tau-s", "10", "--model", &model, &two]);
    let in_order = compensated(args![
        "validate",
        "--json",
        "--tau-s",
        "10",
        "--model",
        &model,
        "--gyro-column",
        "gyro_dph",
        "--gyro-column",
        "gyro2",
        &two
    ]);
    assert!(by_default.len() == 2 && by_default.iter().all(|v| v.is_finite()), "{by_default:?}");
    assert_eq!(by_default, in_order);
    // Per axis, the RMS over that axis's runs (one run each here: its own figure), beside the
    // overall that pools both gyros (review9 finding 5).
    let doc = json(&run_ok(args!["validate", "--json", "--tau-s", "10", "--model", &model, &two]));
    let axes = arr(&doc["axes"]);
    assert_eq!(axes.len(), 2);
    for (axis, run) in axes.iter().zip(arr(&doc["runs"])) {
        assert_eq!(axis["axis"], run["axis"]);
        assert_eq!(f(&axis["compensated_bias_stability_dph"]), f(&run["compensated_bias_stability_dph"]));
        assert_eq!(f(&axis["raw_bias_stability_dph"]), f(&run["raw_bias_stability_dph"]));
    }
    let pooled = ((by_default[0].powi(2) + by_default[1].powi(2)) / 2.0).sqrt();
    assert!((f(&doc["compensated_bias_stability_dph"]) - pooled).abs() <= 1e-12 * pooled);

    // A swapped pair, or axis 1's column alone: refused, nothing written.
    let c = dir.path().join("c.csv");
    let swapped = ["--gyro-column", "gyro2", "--gyro-column", "gyro_dph"];
    let refusal = [
        "--gyro-column gives 'gyro2' for axis 0, but the model's axis 0 was fitted on 'gyro_dph' and its axis 1 on 'gyro2'",
        "Name them in the model's order (--gyro-column gyro_dph --gyro-column gyro2)",
    ];
    let mut validate_swapped = args!["validate", "--model", &model];
    validate_swapped.extend(swapped.iter().map(OsString::from));
    validate_swapped.push(two.clone().into());
    expect_failure(&validate_swapped, dir.path(), None, &refusal);
    let mut compensate_swapped = args!["compensate", "--model", &model, "--out", &c];
    compensate_swapped.extend(swapped.iter().map(OsString::from));
    compensate_swapped.push(two.clone().into());
    expect_failure(&compensate_swapped, dir.path(), Some(&c), &refusal);
    expect_failure(
        &args!["validate", "--model", &model, "--gyro-column", "gyro2", &two],
        dir.path(),
        None,
        &[refusal[0]],
    );

    // Another logger's name for axis 0's gyro: read as given, with a note.
    let output = cal()
        .args(args!["validate", "--model", &model, "--gyro-column", "gx", "--gyro-column", "gyro2", &renamed])
        .output()
        .expect("run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains(
            "axis 0 was fitted on the gyro column 'gyro_dph'; the log's column 'gx' (--gyro-column)"
        ),
        "{stderr}"
    );
}

/// A model records how its fit read the numbers (unit, scales, offset): `validate` reads the
/// logs the same way when no unit option is named (the README's psim-tvc command needed every
/// flag repeated), and says so; named units that differ are used, with a note.
#[test]
fn units_the_model_records_are_read_when_none_are_named() {
    let dir = TempDir::new().expect("tempdir");
    let (_, lines) = short_log(dir.path(), "ok.csv");
    // The same samples logged as a gyro in deg/s at half scale and a temperature in 1/16 C
    // counts from -40 C.
    let mut raw = vec!["time_s,counts,gyro_dps".to_string()];
    for l in &lines[1..] {
        let c: Vec<f64> = l.split(',').map(|v| v.parse().expect("number")).collect();
        raw.push(format!("{},{},{:e}", c[0], (c[1] + 40.0) * 16.0, c[2] / 3600.0 / 0.5));
    }
    let log = dir.path().join("raw.csv");
    write_lines(&log, &raw);
    let units =
        ["--gyro-unit", "dps", "--gyro-scale", "0.5", "--temp-scale", "0.0625", "--temp-offset", "-40"];
    let model = dir.path().join("m.fogm");
    let mut fit_args =
        args!["fit", "--method", "poly", "--gyro-column", "gyro_dps", "--temp-column", "counts"];
    fit_args.extend(units.iter().map(OsString::from));
    fit_args.extend(args!["--out", &model, &log]);
    run_ok(fit_args);
    let validate = |extra: &[&str]| validated_quietly(&model, &log, extra);
    let (named, quiet) = validate(&units);
    let (recorded, said) = validate(&[]);
    let comp = |d: &Value| f(&d["compensated_bias_stability_dph"]);
    assert!(comp(&named).is_finite());
    assert_eq!(comp(&recorded).to_bits(), comp(&named).to_bits(), "read the same way, bit for bit");
    assert!(!quiet.contains("as the model was fitted"), "{quiet}");
    assert!(said.contains("the gyro is read as the model was fitted: 1800 deg/h per unit"), "{said}");
    assert!(
        said.contains("the temperature is read as the model was fitted: 0.0625 C per unit - 40 C"),
        "{said}"
    );
    // Another unit named: used as given, with a note naming both.
    let (_, other) = validate(&["--gyro-unit", "dps"]);
    assert!(
        other.contains("was fitted on the gyro read as 1800 deg/h per unit; this log is read as 3600"),
        "{other}"
    );
}

/// A logger's -999 for a missing temperature: `compensate` keeps the row and the compensator
/// flags it BAD_INPUT, as the firmware does (review10 F5: the log was refused, or with
/// --skip-bad-rows the row dropped, so the output no longer lined up with the firmware's).
/// Oracle: the same log with that cell empty (no reading), whose output must be the same bit
/// for bit except that row's BAD_INPUT flag.
#[test]
fn compensate_keeps_a_sentinel_temperature_row_flagged_as_the_firmware_does() {
    let dir = TempDir::new().expect("tempdir");
    let (_, lines, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let with_cell = |cell: &str| {
        let mut l = lines.clone();
        let mut fields: Vec<&str> = l[100].split(',').collect();
        fields[1] = cell; // temp_c
        l[100] = fields.join(",");
        l
    };
    let (sentinel, empty) = (dir.path().join("sentinel.csv"), dir.path().join("empty.csv"));
    write_lines(&sentinel, &with_cell("-999"));
    write_lines(&empty, &with_cell(""));
    let (out_sentinel, out_empty) = (dir.path().join("c1.csv"), dir.path().join("c2.csv"));
    let done = cal()
        .args(args!["compensate", "--model", &model, &sentinel, "--out", &out_sentinel])
        .assert()
        .success();
    let said = String::from_utf8_lossy(&done.get_output().stderr).to_string();
    run_ok(args!["compensate", "--model", &model, &empty, "--out", &out_empty]);
    let (a, b) =
        (fs::read_to_string(&out_sentinel).expect("read"), fs::read_to_string(&out_empty).expect("read"));
    let (a, b): (Vec<&str>, Vec<&str>) = (a.lines().collect(), b.lines().collect());
    assert_eq!(a.len(), lines.len(), "one output row per log row");
    assert_eq!(a.len(), b.len());
    for (k, (x, y)) in a.iter().zip(&b).enumerate() {
        if k == 100 {
            let (xs, ys): (Vec<&str>, Vec<&str>) = (x.split(',').collect(), y.split(',').collect());
            assert_eq!(xs[..4], ys[..4], "the values of the flagged row");
            let (fx, fy): (u8, u8) = (xs[4].parse().expect("flags"), ys[4].parse().expect("flags"));
            assert_eq!(fx, fy | 0x10, "BAD_INPUT added");
        } else {
            assert_eq!(x, y, "row {k}");
        }
    }
    assert!(said.contains("1 of") && said.contains("flag BAD_INPUT in the output"), "{said}");
    // The note names the line, and no cause the reader refuses (review21 F8: a time not
    // after the one before stops compensate with an error).
    assert!(said.contains("(flag BAD_INPUT in the output; at line 101)"), "{said}");
    assert!(!said.contains("a time not after"), "{said}");
    assert!(!said.contains("glitch"), "a sentinel is not a glitch: {said}");
    // 'NaN' and 'inf' written for the reading: the same as -999 (review18 F3: compensate
    // stopped there, though the firmware flags them alike).
    for cell in ["NaN", "inf", "-Infinity"] {
        let (log, out) = (dir.path().join("nonfinite.csv"), dir.path().join("c3.csv"));
        write_lines(&log, &with_cell(cell));
        run_ok(args!["compensate", "--model", &model, &log, "--out", &out]);
        let nonfinite = fs::read_to_string(&out).expect("read");
        assert!(nonfinite.lines().eq(a.iter().copied()), "{cell}: as -999");
    }
}

/// `validate --json --tau-s 10` of `log` with `model` and the `extra` options: the document
/// and what was said on stderr (10 s windows: the short logs of these tests are 3 minutes).
fn validated_quietly(model: &Path, log: &Path, extra: &[&str]) -> (Value, String) {
    let mut args = args!["validate", "--json", "--tau-s", "10", "--model", model, log];
    args.extend(extra.iter().map(OsString::from));
    let output = cal().args(&args).output().expect("run");
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    (json(&String::from_utf8_lossy(&output.stdout)), String::from_utf8_lossy(&output.stderr).into_owned())
}

/// A header that says its units (`time (ms)`, `gyro rad/s`) read in the defaults' units (s,
/// deg/h) is warned of before the fit, naming the option; read in those units, nothing is
/// said; a model's replay, which folds the gyro unit into a scale, says nothing either.
#[test]
fn units_that_column_names_say_are_warned_of_when_not_read() {
    let dir = TempDir::new().expect("tempdir");
    let (_, lines) = short_log(dir.path(), "ok.csv");
    let mut named = vec!["time (ms),temp_c,gyro rad/s".to_string()];
    for l in &lines[1..] {
        let f: Vec<f64> = l.split(',').map(|v| v.parse().expect("number")).collect();
        named.push(format!("{},{},{}", f[0] * 1000.0, f[1], f[2] / (3600.0 * 180.0 / std::f64::consts::PI)));
    }
    let log = dir.path().join("named.csv");
    write_lines(&log, &named);
    let model = dir.path().join("m.fogm");
    let columns = ["--time-column", "time (ms)", "--gyro-column", "gyro rad/s"];
    let mut fit = args!["fit", "--method", "poly", "--out", &model, &log];
    fit.extend(columns.iter().map(OsString::from));
    let said = String::from_utf8_lossy(&cal().args(&fit).output().expect("run").stderr).into_owned();
    assert!(
        said.contains("warning: the time column 'time (ms)' says ms in its name but is read in s")
            && said.contains(
                "warning: the gyro column 'gyro rad/s' says rad/s in its name but is read in deg/h"
            )
            && said.contains("--gyro-unit/--gyro-scale"),
        "{said}"
    );
    fit.extend(args!["--time-unit", "ms", "--gyro-unit", "rps"]);
    let output = cal().args(&fit).output().expect("run");
    let quiet = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success() && !quiet.contains("in its name"), "{quiet}");
    let output = cal().args(args!["validate", "--model", &model, &log]).output().expect("run");
    let replay = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success() && !replay.contains("in its name"), "{replay}");
    // Under a name that says no unit, the rad/s gyro is told by its size: every calibration
    // mean closer to zero than any FOG's (review32a F2: a model 206,265 times too small, no
    // word). Read in rad/s, nothing is said.
    let plain = dir.path().join("plain.csv");
    let mut rows = vec!["time_s,temp_c,gyro".to_string()];
    rows.extend(named[1..].iter().map(|l| {
        let f: Vec<f64> = l.split(',').map(|v| v.parse().expect("number")).collect();
        format!("{},{},{}", f[0] / 1000.0, f[1], f[2])
    }));
    write_lines(&plain, &rows);
    let kinds = |unit: &[&str]| {
        let mut fit =
            args!["fit", "--method", "poly", "--json", "--out", &model, &plain, "--gyro-column", "gyro"];
        fit.extend(unit.iter().map(OsString::from));
        let report = json(&run_ok(fit));
        report["warnings"]
            .as_array()
            .expect("warnings")
            .iter()
            .map(|w| w["kind"].to_string())
            .collect::<Vec<_>>()
    };
    assert!(kinds(&[]).contains(&"\"implausible_gyro\"".to_string()), "{:?}", kinds(&[]));
    assert!(!kinds(&["--gyro-unit", "rps"]).contains(&"\"implausible_gyro\"".to_string()));
}

/// A model records how its fit read the logs' time (format 5): a log whose time is in
/// milliseconds under another name validates without the time options, bit for bit as with
/// them (oracle: the same validation with every option named), and with the time column
/// alone named in the recorded unit; a wrong unit named is used as given with a note naming
/// the model's.
#[test]
fn the_time_the_model_records_is_read_when_none_is_named() {
    let dir = TempDir::new().expect("tempdir");
    let (_, lines) = short_log(dir.path(), "ok.csv");
    let mut ms = vec!["t_ms,temp_c,gyro_dph".to_string()];
    for l in &lines[1..] {
        let (time, rest) = l.split_once(',').expect("row");
        ms.push(format!("{},{rest}", time.parse::<f64>().expect("time") * 1000.0));
    }
    let log = dir.path().join("ms.csv");
    write_lines(&log, &ms);
    let model = dir.path().join("m.fogm");
    let time = ["--time-column", "t_ms", "--time-unit", "ms"];
    let mut fit_args = args!["fit", "--method", "poly", "--out", &model, &log];
    fit_args.extend(time.iter().map(OsString::from));
    run_ok(fit_args);
    let inspect = json(&run_ok(args!["inspect", "--json", &model]));
    assert_eq!(inspect["format_version"], 6);
    assert_eq!(inspect["log_time"]["time_column"], "t_ms");
    assert_eq!(inspect["log_time"]["time_unit"], "ms");
    let validate = |extra: &[&str]| validated_quietly(&model, &log, extra);
    let (named, quiet) = validate(&time);
    let (recorded, said) = validate(&[]);
    let comp = |d: &Value| f(&d["compensated_bias_stability_dph"]);
    assert!(comp(&named).is_finite());
    assert_eq!(comp(&recorded).to_bits(), comp(&named).to_bits(), "read the same way, bit for bit");
    assert!(!quiet.contains("time"), "{quiet}");
    assert!(said.contains("the logs' time is read as") && said.contains("column 't_ms' in ms"), "{said}");
    // The column named without its unit: still the recorded milliseconds (each time option
    // not named is the model's), bit for bit, with a note saying so.
    let (column_only, noted) = validate(&["--time-column", "t_ms"]);
    assert_eq!(comp(&column_only).to_bits(), comp(&named).to_bits(), "{noted}");
    assert!(noted.contains("the logs' time is read with the time unit ms, as"), "{noted}");
    // Another unit named: read as given (seconds, the column still the model's), with a note
    // naming the model's (here every step is then longer than the gap, so nothing is
    // compensated and validate fails).
    let output = cal()
        .args(args!["validate", "--tau-s", "10", "--model", &model, &log, "--time-unit", "s"])
        .output()
        .expect("run");
    let other = String::from_utf8_lossy(&output.stderr);
    assert!(
        other.contains("was fitted on logs whose time is column 't_ms' in ms")
            && other.contains("give column 't_ms' in s"),
        "{other}"
    );
}

/// A model records its logs' shape when it is not the default (format 7): a serial capture (a
/// banner line, no header, no time column, fields separated by spaces, `%` comments) fitted with
/// the shape options validates and compensates without them, bit for bit as with them (oracle:
/// the same commands with every option named), says where the shape came from, and a log
/// shaped otherwise is refused naming the recorded shape and how to name another.
#[test]
fn the_shape_the_model_records_is_read_when_none_is_named() {
    let dir = TempDir::new().expect("tempdir");
    let (csv, lines) = short_log(dir.path(), "ok.csv");
    let mut capture = vec!["COM3 115200 8N1 - capture started".to_string()];
    for (k, l) in lines[1..].iter().enumerate() {
        let fields: Vec<&str> = l.split(',').collect();
        capture.push(format!(" {}   {}", fields[2], fields[1]));
        if k == 100 {
            capture.push("% the chamber door was opened".to_string());
        }
    }
    let log = dir.path().join("capture.txt");
    write_lines(&log, &capture);
    let step_s = lines[2].split(',').next().and_then(|t| t.parse::<f64>().ok()).expect("time");
    let rate = format!("{}", 1.0 / step_s);
    let shape =
        ["--skip-lines", "1", "--columns", "gyro_dph,temp_c", "--delimiter", "whitespace", "--comment", "%"];
    let model = dir.path().join("m.fogm");
    let mut fit_args = args!["fit", "--method", "poly", "--out", &model, &log, "--sample-rate-hz", &rate];
    fit_args.extend(shape.iter().map(OsString::from));
    run_ok(fit_args);
    let inspect = json(&run_ok(args!["inspect", "--json", &model]));
    assert_eq!(inspect["format_version"], 7);
    let recorded = &inspect["log_shape"];
    assert_eq!(
        (recorded["skip_lines"].as_u64(), recorded["delimiter"].as_str()),
        (Some(1), Some("whitespace"))
    );
    assert_eq!(
        (recorded["comment"].as_str(), recorded["columns"].clone()),
        (Some("%"), serde_json::json!(["gyro_dph", "temp_c"]))
    );
    let inspect_text = run_ok(args!["inspect", &model]);
    assert!(
        inspect_text.contains("log shape: 1 line skipped at the start; fields separated by spaces or tabs"),
        "{inspect_text}"
    );
    // Validated without the shape options: bit for bit as with them.
    let (named, quiet) = validated_quietly(&model, &log, &shape);
    let (from_model, said) = validated_quietly(&model, &log, &[]);
    let comp = |d: &Value| f(&d["compensated_bias_stability_dph"]);
    assert!(comp(&named).is_finite());
    assert_eq!(comp(&from_model).to_bits(), comp(&named).to_bits(), "read the same way, bit for bit");
    assert!(!quiet.contains("records of its fit's logs"), "{quiet}");
    assert!(
        said.contains("the logs are read as") && said.contains("no header row, columns gyro_dph,temp_c"),
        "{said}"
    );
    // Compensated without them: the same file as with them.
    let (out_named, out_model) = (dir.path().join("named.csv"), dir.path().join("model.csv"));
    let mut comp_args = args!["compensate", "--model", &model, &log, "--out", &out_named];
    comp_args.extend(shape.iter().map(OsString::from));
    run_ok(comp_args);
    run_ok(args!["compensate", "--model", &model, &log, "--out", &out_model]);
    assert_eq!(fs::read(&out_model).expect("read"), fs::read(&out_named).expect("read"));
    // The CSV log with a header row: refused in the recorded shape, naming it and the way out.
    let err = run_err(args!["validate", "--model", &model, &csv]);
    assert!(
        err.contains("the log was read in this shape, ")
            && err.contains("1 line skipped at the start; fields separated by spaces or tabs")
            && err.contains("--columns '' for a header row"),
        "{err}"
    );
    // Its shape named but not its time column: the model's sample rate is said to be the
    // model's, with the option that names the column (not the shape's options).
    let err = run_err(args![
        "validate",
        "--model",
        &model,
        &csv,
        "--columns",
        "",
        "--skip-lines",
        "0",
        "--delimiter",
        "auto"
    ]);
    assert!(
        err.contains(&format!("the sample rate, {rate} Hz, is the one"))
            && err.contains("name it with --time-column")
            && !err.contains("the log was read in this shape"),
        "{err}"
    );
    // Named as it is (a header row, nothing skipped, its time column): validated, with a note
    // naming the model's shape.
    let (csv_doc, noted) = validated_quietly(
        &model,
        &csv,
        &[
            "--columns",
            "",
            "--skip-lines",
            "0",
            "--delimiter",
            "auto",
            "--comment",
            "#",
            "--time-column",
            "time_s",
        ],
    );
    assert!(comp(&csv_doc).is_finite());
    let json_notes = csv_doc["notes"].to_string();
    assert!(
        json_notes.contains("was fitted on logs shaped otherwise"),
        "the shape note in --json: {json_notes}"
    );
    assert!(noted.contains("was fitted on logs shaped otherwise"), "{noted}");
    // A time column of another name (review19 F4): refused as ambiguous, naming the column
    // and both ways out, where it used to be left unread and the rows timed at the model's
    // rate. With the rate named, the rows are timed by their index as asked.
    let renamed = dir.path().join("t.csv");
    let text = fs::read_to_string(&csv).expect("read");
    fs::write(&renamed, text.replacen("time_s", "Time (s)", 1)).expect("write");
    let header_shape = ["--columns", "", "--skip-lines", "0", "--delimiter", "auto", "--comment", "#"];
    let mut ambiguous = args!["validate", "--model", &model, &renamed];
    ambiguous.extend(header_shape.iter().map(OsString::from));
    let err = run_err(ambiguous);
    assert!(
        err.contains("ambiguous time: the log has a column 'Time (s)' that looks like a time")
            && err.contains("name it with --time-column")
            && err.contains("name --sample-rate-hz"),
        "{err}"
    );
    // The same rows as the capture, timed the same way: bit for bit its figure.
    let (by_index, _) =
        validated_quietly(&model, &renamed, &[&header_shape[..], &["--sample-rate-hz", &rate]].concat());
    assert_eq!(comp(&by_index).to_bits(), comp(&from_model).to_bits());
}

/// Settings no fit can use are refused before any log is read, naming the option (they
/// used to surface after the fitting as a blob field out of range, or not at all).
#[test]
fn unusable_fit_settings_are_refused_naming_the_option() {
    let dir = TempDir::new().expect("tempdir");
    let (ok, _) = short_log(dir.path(), "ok.csv");
    let out = dir.path().join("m.fogm");
    let cases: [(&[&str], &str); 11] = [
        (&["--p-enter", "2"], "--p-enter"),
        (&["--p-enter", "nan"], "--p-enter"),
        (&["--p-remove", "0.01"], "--p-remove"),
        (&["--target-window-s", "0"], "--target-window-s"),
        (&["--max-nodes", "0"], "--max-nodes"),
        (&["--window-s", "0"], "--window-s"),
        (&["--blocks", "1"], "--blocks"),
        (&["--min-blocks", "1000"], "--min-blocks"),
        (&["--max-gap-s", "0"], "--max-gap-s"),
        (&["--gyro-scale", "nan"], "--gyro-scale"),
        (&["--temp-scale", "0"], "--temp-scale"),
    ];
    for (options, named) in cases {
        let mut args = args!["fit", "--method", "poly", "--out", &out, &ok];
        args.extend(options.iter().map(OsString::from));
        expect_failure(&args, dir.path(), Some(&out), &[named]);
    }
}

// ---------------------------------------------------------------------------------------
// 5. Atomic outputs
// ---------------------------------------------------------------------------------------

#[test]
fn outputs_are_atomic() {
    let dir = TempDir::new().expect("tempdir");
    let (ok, lines, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let points = dir.path().join("points.csv");
    fs::write(&points, "temp_c,rate_c_per_min\n21,0.5\n").expect("write points");

    let commands = |out: &Path| -> Vec<Vec<OsString>> {
        vec![
            args!["fit", "--method", "poly", "--out", out, &ok],
            args!["compensate", "--model", &model, &ok, "--out", out],
            args!["evaluate", "--model", &model, "--points", &points, "--out", out],
            args!["export", "--model", &model, "--format", "rust", "--out", out],
            args!["export", "--model", &model, "--format", "c", "--out", out],
        ]
    };
    let before = entries(dir.path());

    // --out into a folder that does not exist.
    let missing = dir.path().join("no_such_folder").join("out.file");
    for args in commands(&missing) {
        let stderr = run_err(&args);
        assert!(stderr.contains("no_such_folder"), "{args:?}: {stderr}");
        assert_eq!(entries(dir.path()), before, "{args:?}");
    }

    // --out under a file, as if it were a folder: said so (it used to say "does not exist").
    let under_file = dir.path().join("existing_file");
    fs::write(&under_file, "x").expect("write");
    let inside = under_file.join("out.file");
    for args in commands(&inside).into_iter().take(2) {
        let stderr = run_err(&args);
        assert!(stderr.contains("existing_file is a file, not a folder"), "{args:?}: {stderr}");
    }
    fs::remove_file(&under_file).expect("remove");

    // --out names an existing folder: every command refuses it before its work (the rename
    // failure behind that check is `fogtemp_cal::output`'s test).
    let taken = dir.path().join("taken");
    fs::create_dir(&taken).expect("mkdir");
    for args in commands(&taken).into_iter().take(4) {
        let stderr = run_err(&args);
        assert!(stderr.contains("is a folder"), "{args:?}: {stderr}");
        assert!(taken.is_dir() && entries(&taken).is_empty());
        let now: BTreeSet<String> = entries(dir.path()).into_iter().filter(|n| n != "taken").collect();
        assert_eq!(now, before, "{args:?}: files left behind");
    }

    // A failure half-way through leaves an existing output untouched.
    let out = dir.path().join("existing.csv");
    fs::write(&out, "previous contents\n").expect("write");
    let mut bad = lines.clone();
    let last = bad.len() - 1;
    bad[last] = "1e9,20,abc".into();
    let bad_log = dir.path().join("bad_at_end.csv");
    write_lines(&bad_log, &bad);
    let snapshot = entries(dir.path());
    run_err(args!["compensate", "--model", &model, &bad_log, "--out", &out]);
    assert_eq!(fs::read_to_string(&out).expect("read"), "previous contents\n");
    assert_eq!(entries(dir.path()), snapshot);

    // A read-only folder (not testable as root, who may write anyway).
    let ro = dir.path().join("read_only");
    fs::create_dir(&ro).expect("mkdir");
    let writable = fs::metadata(&ro).expect("stat").permissions();
    let mut read_only = writable.clone();
    read_only.set_readonly(true);
    fs::set_permissions(&ro, read_only).expect("chmod");
    let probe = ro.join("probe");
    if fs::write(&probe, b"").is_ok() {
        let _ = fs::remove_file(&probe);
        eprintln!("outputs_are_atomic: running as a user who can write to read-only folders; read-only case skipped");
    } else {
        for args in commands(&ro.join("out.file")) {
            let stderr = run_err(&args);
            assert!(stderr.contains("cannot create a temporary file"), "{args:?}: {stderr}");
            assert!(entries(&ro).is_empty(), "{args:?}: files left behind");
        }
    }
    fs::set_permissions(&ro, writable).expect("chmod");
}

/// An output that is one of the inputs is refused before anything is written, and a log
/// named twice is refused (its run would count twice).
#[test]
fn outputs_never_replace_inputs_and_logs_count_once() {
    let dir = TempDir::new().expect("tempdir");
    let (ok, lines, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let points = dir.path().join("points.csv");
    fs::write(&points, "temp_c,rate_c_per_min\n21,0.5\n").expect("write points");
    let model_bytes = fs::read(&model).expect("read model");
    let same_log = dir.path().join(".").join("ok.csv");
    let cases: Vec<(Vec<OsString>, &Path)> = vec![
        (args!["fit", "--method", "poly", "--out", &same_log, &ok], &ok),
        (args!["compensate", "--model", &model, &ok, "--out", &same_log], &ok),
        (args!["compensate", "--model", &model, &ok, "--out", &model], &model),
        (args!["export", "--model", &model, "--format", "c", "--out", &model], &model),
        (args!["evaluate", "--model", &model, "--points", &points, "--out", &points], &points),
    ];
    for (args, input) in &cases {
        let before = fs::read(input).expect("read input");
        let stderr =
            expect_failure(args, dir.path(), None, &["this is also an input", "choose another output path"]);
        assert_eq!(&fs::read(input).expect("read input"), &before, "{args:?} changed its input:\n{stderr}");
    }
    assert_eq!(fs::read(&model).expect("read model"), model_bytes);
    assert_eq!(fs::read_to_string(&ok).expect("read log").lines().count(), lines.len());

    // The same log twice, directly and through its folder or another path to it.
    let sub = dir.path().join("runs");
    fs::create_dir(&sub).expect("mkdir");
    let (a, _) = short_log(&sub, "a.csv");
    let out = dir.path().join("twice.fogm");
    for args in [
        args!["fit", "--method", "poly", "--out", &out, &sub, &a],
        args!["fit", "--method", "poly", "--out", &out, &a, sub.join("..").join("runs").join("a.csv")],
    ] {
        expect_failure(&args, dir.path(), Some(&out), &["is named twice", "its run would count twice"]);
    }
    // The same path twice is said once, not "(as a.csv and as a.csv)".
    let stderr = expect_failure(
        &args!["fit", "--method", "poly", "--out", &out, &a, &a],
        dir.path(),
        Some(&out),
        &["is named twice (given twice)"],
    );
    assert!(!stderr.contains(" and as "), "{stderr}");
    run_ok(args!["fit", "--method", "poly", "--out", &out, &sub]);
}

/// Samples outside the calibrated region, and a log the compensator never corrects, are
/// told on stderr by validate and compensate with their counts (nothing only in --json).
#[test]
fn uncalibrated_samples_are_noted_with_their_count() {
    let dir = TempDir::new().expect("tempdir");
    let (_, lines, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    // 40 C above the calibration: every corrected sample is outside the region.
    let hot = dir.path().join("hot.csv");
    write_warmup(&hot, 60.0, 3.0, 8);
    let out = dir.path().join("hot_out.csv");
    let rows = lines.len() - 1;
    let (mut counts, mut notes) = (Vec::new(), Vec::new());
    for args in [
        args!["validate", "--model", &model, &hot],
        args!["compensate", "--model", &model, &hot, "--out", &out],
    ] {
        let output = cal().args(&args).output().expect("run");
        assert!(output.status.success(), "{args:?}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        let note = stderr
            .lines()
            .find(|l| l.contains("outside the model's calibrated"))
            .unwrap_or_else(|| panic!("{args:?}: no outside note:\n{stderr}"))
            .to_string();
        let count: u64 = note
            .split(" axis 0: ")
            .nth(1)
            .and_then(|s| s.split(' ').next())
            .and_then(|n| n.parse().ok())
            .expect("count");
        assert!(count > rows as u64 / 2 && count < rows as u64, "{note}");
        counts.push(count);
        notes.push(note);
    }
    // Both say how far the samples reach, in the same words (compensate's said only
    // "extrapolated" until 2026-11-30); only where the flag is seen differs.
    assert!(
        notes[0].contains("all of them at most ") && notes[0].contains(" C beyond the calibrated "),
        "{notes:?}"
    );
    assert_eq!(
        notes[0].replace("(flag OUTSIDE_HULL)", "(flag OUTSIDE_HULL in the output)"),
        notes[1],
        "validate's and compensate's notes"
    );
    // The oracle: the compensated output's own flags (bit 2, OUTSIDE_HULL), row by row.
    let text = fs::read_to_string(&out).expect("read");
    let flagged = text
        .lines()
        .skip(1)
        .filter(|l| l.rsplit(',').next().and_then(|f| f.parse::<u8>().ok()).is_some_and(|f| f & 4 != 0))
        .count() as u64;
    assert_eq!(counts, [flagged, flagged], "validate's and compensate's counts against the output's flags");
    // A log whose temperature cells are all empty: nothing is corrected, and it is said
    // with the cause (the temperature silent beyond the model's max gap); validate then
    // fails (exit 1: no run validated), compensate succeeds (its output is the raw gyro).
    let blank: Vec<String> = lines
        .iter()
        .enumerate()
        .map(|(k, l)| {
            if k == 0 {
                l.clone()
            } else {
                let c: Vec<&str> = l.split(',').collect();
                format!("{},,{}", c[0], c[2])
            }
        })
        .collect();
    let no_temp = dir.path().join("no_temp.csv");
    write_lines(&no_temp, &blank);
    for (args, succeeds) in [
        (args!["validate", "--model", &model, &no_temp], false),
        (args!["compensate", "--model", &model, &no_temp, "--out", dir.path().join("nt_out.csv")], true),
    ] {
        let output = cal().args(&args).output().expect("run");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            output.status.success() == succeeds
                && stderr.contains("never corrected a sample")
                && stderr.contains("silent for longer than the model's max gap"),
            "{args:?}:\n{stderr}"
        );
        if !succeeds {
            assert!(stderr.contains("no run could be validated"), "{stderr}");
        }
    }
}

#[test]
fn export_c_failure_leaves_no_header_behind() {
    let dir = TempDir::new().expect("tempdir");
    let (_, _, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let out = dir.path().join("model.c");
    fs::create_dir(&out).expect("mkdir");
    let args = args!["export", "--model", &model, "--format", "c", "--out", &out];
    expect_failure(&args, dir.path(), None, &["model.c: is a folder"]);
    assert!(!dir.path().join("model.h").exists());
    // The header's path in the way: refused before either file is written (a source without
    // its header was left behind when only the rename of the header failed).
    fs::remove_dir(&out).expect("rmdir");
    fs::create_dir(dir.path().join("model.h")).expect("mkdir");
    expect_failure(&args, dir.path(), None, &["model.h: is a folder"]);
    assert!(!out.exists());
}

/// Ctrl-C while `compensate` writes its output: the process ends with status 130 and
/// leaves neither the output nor its hidden temporary file (a review found 181-386 MB left
/// under `.fogtemp-*`).
#[cfg(unix)]
#[test]
fn an_interrupted_compensate_leaves_no_file() {
    use std::time::{Duration, Instant};
    let dir = TempDir::new().expect("tempdir");
    let (_, _, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let long = dir.path().join("long.csv");
    {
        let mut w = BufWriter::new(fs::File::create(&long).expect("create"));
        writeln!(w, "time_s,temp_c,gyro_dph").expect("write");
        for k in 0..2_000_000u64 {
            writeln!(w, "{:.2},{:.4},{:.5}", k as f64 * 0.01, 20.0 + k as f64 * 1e-6, (k % 7) as f64 * 0.1)
                .expect("write");
        }
    }
    let out_dir = dir.path().join("out");
    fs::create_dir(&out_dir).expect("mkdir");
    let mut child = std::process::Command::new(common::fogtemp_cal_bin())
        .args(args!["compensate", "--model", &model, "--out", out_dir.join("comp.csv"), &long])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("spawn");
    let started = Instant::now();
    let staged = loop {
        if fs::read_dir(&out_dir).expect("list").next().is_some() {
            break true;
        }
        if started.elapsed() > Duration::from_secs(20) || child.try_wait().expect("wait").is_some() {
            break false;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    assert!(staged, "the temporary output never appeared");
    let kill =
        std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill");
    assert!(kill.success());
    let status = child.wait().expect("wait");
    assert_eq!(status.code(), Some(130), "{status:?}");
    let left: Vec<_> = fs::read_dir(&out_dir).expect("list").map(|e| e.expect("entry").file_name()).collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

/// A folder given as logs: its `*.csv` files are read, and what else it holds (another
/// file, a sub-folder, which is not searched, a `*.csv` that is not a file) is named in a
/// note: nothing is left out silently.
#[test]
fn a_folders_other_entries_are_named() {
    let dir = TempDir::new().expect("tempdir");
    let logs = dir.path().join("logs");
    fs::create_dir_all(logs.join("sub")).expect("mkdir");
    let (_, lines) = short_log(&logs, "a.csv");
    write_lines(&logs.join("b.txt"), &lines);
    fs::create_dir(logs.join("c.csv")).expect("mkdir");
    // A macOS copy's AppleDouble companion: binary, named and left out (review23b F8).
    fs::write(logs.join("._a.csv"), b"\x00\x05\x16\x07\x00\x02\x00\x00Mac OS X").expect("write");
    let output = cal()
        .args(args!["fit", "--method", "poly", "--out", &dir.path().join("m.fogm"), &logs])
        .output()
        .expect("run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains(
            "read 1 *.csv file; left out: ._a.csv (a macOS copy's resource file), b.txt, c.csv/ (a folder: not \
             searched), sub/ (a folder: not searched)"
        ),
        "{stderr}"
    );
}

/// A log shorter than the feature window (1 min against the default 100 s) gets the
/// `short_runs` warning naming it (its fit residual of about 0 says nothing); a log of
/// several windows does not.
#[test]
fn a_log_shorter_than_the_window_is_named() {
    let dir = TempDir::new().expect("tempdir");
    let short = dir.path().join("one_minute.csv");
    write_warmup(&short, 20.0, 1.0, 5);
    let doc = json(&run_ok(args![
        "fit",
        "--method",
        "poly",
        "--json",
        "--out",
        &dir.path().join("s.fogm"),
        &short
    ]));
    let kinds: Vec<&str> = arr(&doc["warnings"]).iter().filter_map(|w| w["kind"].as_str()).collect();
    assert!(kinds.contains(&"short_runs"), "{kinds:?}");
    let message =
        arr(&doc["warnings"]).iter().find(|w| w["kind"] == "short_runs").unwrap()["message"].to_string();
    assert!(message.contains("one_minute") && message.contains("100 s feature window"), "{message}");
    let (long, _) = short_log(dir.path(), "three_minutes.csv");
    let doc =
        json(&run_ok(args!["fit", "--method", "poly", "--json", "--out", &dir.path().join("l.fogm"), &long]));
    assert!(arr(&doc["warnings"]).iter().all(|w| w["kind"] != "short_runs"), "{}", doc["warnings"]);
}

/// `--out model.h` for C would be both the source and its header (the header used to
/// replace the array: "wrote model.h" with no byte of the model in it); a keyword as
/// `--name` would not compile. Both are refused before anything is written.
#[test]
fn export_refuses_a_header_as_the_source_and_keyword_names() {
    let dir = TempDir::new().expect("tempdir");
    let (_, _, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let header = dir.path().join("model.h");
    let args = args!["export", "--model", &model, "--format", "c", "--out", &header];
    expect_failure(&args, dir.path(), None, &["names the C source", "model.c"]);
    assert!(!header.exists());
    let rust = dir.path().join("m.rs");
    let args = args!["export", "--model", &model, "--format", "rust", "--name", "fn", "--out", &rust];
    expect_failure(&args, dir.path(), None, &["'fn' is a keyword"]);
    let args = args![
        "export",
        "--model",
        &model,
        "--format",
        "c",
        "--name",
        "int",
        "--out",
        &dir.path().join("x.c")
    ];
    expect_failure(&args, dir.path(), None, &["'int' is a keyword"]);
    assert!(!rust.exists());
}

#[cfg(unix)]
#[test]
fn outputs_get_the_usual_file_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = TempDir::new().expect("tempdir");
    let (_, _, model) = short_log_and_model(dir.path(), "poly", "m.fogm");
    let plain = dir.path().join("plain");
    fs::write(&plain, b"").expect("write");
    let mode = |p: &Path| fs::metadata(p).expect("stat").permissions().mode() & 0o777;
    assert_eq!(
        mode(&model),
        mode(&plain),
        "model file mode {:o} vs a plainly created file {:o}",
        mode(&model),
        mode(&plain)
    );
}

// ---------------------------------------------------------------------------------------
// 6. Allan deviation
// ---------------------------------------------------------------------------------------

/// White noise of known angle random walk N: per-sample standard deviation
/// `60 N / sqrt(dt)` deg/h gives sigma(tau) = 60 N / sqrt(tau) (tau in s).
///
/// Tolerance 10 %: the overlapping estimate at tau = m dt from n samples has a relative
/// error of about 1 / sqrt(2 (n / m - 1)); with n = 60 000 (20 min at 50 Hz) that is 0.3 %
/// at tau = dt and 2 % at tau = 1 s (m = 50). The short-tau points dominate the weighted
/// fit of N, so 10 % is at least 5 sigma, while a unit slip (60 between per-sqrt(h) and
/// per-sqrt(s), 3600 between deg/h and deg/s) or a wrong sample period (sqrt(50)) fails it
/// by far. Measured: N = 0.010012 deg/sqrt(h).
#[test]
fn allan_recovers_white_noise_arw() {
    const N: f64 = 0.01;
    const HZ: f64 = 50.0;
    let dir = TempDir::new().expect("tempdir");
    let log = dir.path().join("static.csv");
    let sigma = 60.0 * N * HZ.sqrt();
    let mut r = rng(11);
    let mut w = BufWriter::new(fs::File::create(&log).expect("create"));
    writeln!(w, "time_s,temp_c,gyro_dph").expect("write");
    for k in 0..60_000u32 {
        writeln!(w, "{:.2},25.0000,{:.5}", f64::from(k) / HZ, 0.5 + sigma * gaussian(&mut r)).expect("write");
    }
    w.flush().expect("flush");
    drop(w);
    let doc = json(&run_ok(args!["allan", &log, "--json"]));
    assert_eq!(doc["gaps"], 0);
    let axis = &arr(&doc["axes"])[0];
    assert!((f(&axis["sample_period_s"]) - 1.0 / HZ).abs() < 1e-9);
    assert_eq!(axis["samples"], 60_000);
    let n_hat = f(&axis["arw_deg_per_sqrt_h"]);
    eprintln!(
        "allan: N = {n_hat:.6} deg/sqrt(h) (true {N}), B = {}, K = {}",
        axis["bias_instability_dph"], axis["rrw_dph_per_sqrt_h"]
    );
    assert!((n_hat / N - 1.0).abs() < 0.10, "N = {n_hat}, expected {N} within 10 %");
    // The curve itself: sigma(1 s) = 60 N.
    let at_1s = arr(&axis["curve"])
        .iter()
        .min_by(|a, b| (f(&a["tau_s"]) - 1.0).abs().total_cmp(&(f(&b["tau_s"]) - 1.0).abs()))
        .expect("curve");
    let expected = 60.0 * N / f(&at_1s["tau_s"]).sqrt();
    assert!((f(&at_1s["adev_dph"]) / expected - 1.0).abs() < 0.10, "{at_1s} vs {expected}");
    // The bound on B: the curve's minimum over averaging times with at most 25 % relative
    // error, over 0.664. White noise falls as 1 / sqrt(tau), so the minimum is at the longest
    // such time, and within 3 of its relative errors of 60 N / sqrt(tau).
    let longest = arr(&axis["curve"])
        .iter()
        .filter(|p| f(&p["relative_error"]) <= 0.25)
        .max_by(|a, b| f(&a["tau_s"]).total_cmp(&f(&b["tau_s"])))
        .expect("a point");
    assert_eq!(f(&axis["adev_min_tau_s"]), f(&longest["tau_s"]));
    let minimum = f(&axis["adev_min_dph"]);
    let closed_form = 60.0 * N / f(&longest["tau_s"]).sqrt();
    assert!(
        (minimum / closed_form - 1.0).abs() < 3.0 * f(&longest["relative_error"]),
        "{minimum} vs {closed_form}"
    );
    assert_eq!(f(&axis["bias_instability_at_most_dph"]), minimum / 0.664);
}

/// `allan` of `compensate`'s output leaves out the compensator's start-up rows (flag
/// WARMING_UP: raw output, then a step by the bias), with a note: oracle, `allan` of a copy
/// holding only the rows from the first without the flag, whose curve must be the same bit
/// for bit.
fn allan_of_compensated_starts_after_the_warm_up(compensated: &Path) {
    let text = fs::read_to_string(compensated).expect("read compensated");
    let mut lines = text.lines();
    let header = lines.next().expect("header");
    let flags_at = header.split(',').position(|c| c == "flags").expect("flags column");
    let rows: Vec<&str> = lines.collect();
    let warming = |row: &&str| {
        row.split(',').nth(flags_at).and_then(|f| f.parse::<u32>().ok()).is_some_and(|f| f & 1 != 0)
    };
    let first = rows.iter().position(|r| !warming(r)).expect("a compensated row");
    assert!(first > 0, "the output starts with start-up rows");
    let trimmed = compensated.with_file_name("compensated-from-first.csv");
    fs::write(&trimmed, format!("{header}\n{}\n", rows[first..].join("\n"))).expect("write trimmed");
    let args_for = |log: &Path| args!["allan", log, "--json", "--gyro-column", "compensated_dph"];
    let whole = cal().args(args_for(compensated)).assert().success();
    let stderr = String::from_utf8_lossy(&whole.get_output().stderr).to_string();
    let whole = json(&String::from_utf8_lossy(&whole.get_output().stdout));
    let after = json(&run_ok(args_for(&trimmed)));
    assert_eq!(whole["axes"][0]["curve"], after["axes"][0]["curve"]);
    assert_eq!(whole["axes"][0]["samples"].as_u64(), Some((rows.len() - first) as u64));
    assert!(stderr.contains(&format!("the first {first} rows")) && stderr.contains("WARMING_UP"), "{stderr}");
    // Without --gyro-column, compensate's output is read by its compensated column, the same
    // curve (the README's `allan run-comp.csv`; it failed on the default gyro_dph: review12 F9).
    let default = cal().args(args!["allan", compensated, "--json"]).assert().success();
    let said = String::from_utf8_lossy(&default.get_output().stderr).to_string();
    let default = json(&String::from_utf8_lossy(&default.get_output().stdout));
    assert_eq!(default["axes"][0]["curve"], whole["axes"][0]["curve"]);
    assert!(said.contains("compensate's output: reading compensated_dph"), "{said}");
}

/// A log too short for any averaging time has no Allan deviation: its noise terms are
/// unknown (JSON null, text NaN) with a warning, not zero noise.
#[test]
fn allan_of_a_log_too_short_says_so() {
    let dir = TempDir::new().expect("tempdir");
    let log = dir.path().join("short.csv");
    fs::write(&log, "time_s,temp_c,gyro_dph\n0,20,1\n1,20,2\n2,20,3\n").expect("write");
    let doc = json(&run_ok(args!["allan", &log, "--json"]));
    let axis = &arr(&doc["axes"])[0];
    assert!(arr(&axis["curve"]).is_empty());
    for term in ["arw_deg_per_sqrt_h", "bias_instability_dph", "rrw_dph_per_sqrt_h"] {
        assert!(axis[term].is_null(), "{term}: {}", axis[term]);
    }
    let assert = cal().args(args!["allan", &log]).assert().success();
    let out = assert.get_output();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains(
            "axis 0 (column 'gyro_dph'): 3 samples are too few for an Allan deviation (at least 4)"
        ),
        "{stderr}"
    );
    // Unknown, not NaN (review15 F7).
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("N = unknown deg/sqrt(h), B = unknown deg/h (at most unknown)"), "{stdout}");
    assert!(!stdout.contains("NaN") && !stderr.contains("NaN"), "{stdout}{stderr}");
}

/// A log cut into many stretches (a dropped sample in 100) is told how to time its rows by
/// index, with the rate; a few gaps are not (review15 F1).
#[test]
fn allan_of_a_log_with_many_gaps_says_how_to_time_its_rows() {
    let dir = TempDir::new().expect("tempdir");
    let write = |name: &str, dropped: &dyn Fn(u32) -> bool| {
        let mut text = String::from("time_s,gyro_dph\n");
        for k in (0..20_000u32).filter(|k| !dropped(*k)) {
            // A deterministic, noise-like sequence: the hint does not depend on the values.
            let gyro = f64::from((k * 7919) % 1000) / 1000.0;
            text.push_str(&format!("{:.2},{gyro:.3}\n", f64::from(k) * 0.01));
        }
        let log = dir.path().join(name);
        fs::write(&log, text).expect("write");
        log
    };
    let many = write("many.csv", &|k| k % 100 == 50);
    let few = write("few.csv", &|k| k == 5000 || k == 15000);
    let stderr = |log: &Path| {
        let assert = cal().args(args!["allan", log]).assert().success();
        String::from_utf8_lossy(&assert.get_output().stderr).into_owned()
    };
    let told = stderr(&many);
    assert!(told.contains("200 steps longer than 1.5x the median sample period"), "{told}");
    assert!(
        told.contains("That is over 1 step in 1000") && told.contains("--sample-rate-hz 100.000000"),
        "{told}"
    );
    let quiet = stderr(&few);
    assert!(quiet.contains("2 steps longer") && !quiet.contains("over 1 step in 1000"), "{quiet}");
}

// ---------------------------------------------------------------------------------------
// Capacity: the firmware's tracker capacity is a checked contract
// ---------------------------------------------------------------------------------------

#[test]
fn capacity_is_checked_at_fit_validate_compensate_and_exported() {
    let logs = logs();
    let dir = TempDir::new().expect("tempdir");
    let model = dir.path().join("m.fogm");
    // 200 blocks do not fit the firmware default of 128: refused before anything is read.
    let err = run_err(args!["fit", "--method", "poly", "--blocks", "200", "--out", &model, &logs.cal]);
    assert!(
        err.contains("capacity") && err.contains("needs 200 blocks") && err.contains("--blocks 128"),
        "{err}"
    );
    assert!(!model.exists());
    // ... and accepted when the firmware is said to hold them.
    let model200 = dir.path().join("m200.fogm");
    run_ok(args![
        "fit",
        "--method",
        "poly",
        "--blocks",
        "200",
        "--min-blocks",
        "2",
        "--capacity",
        "256",
        "--out",
        &model200,
        &logs.cal
    ]);
    let doc = json(&run_ok(args!["inspect", &model200, "--json"]));
    assert_eq!(doc["axes"][0]["features"]["blocks_needed"], 200);
    assert!(run_ok(args!["inspect", &model200]).contains("capacity needed: 200 blocks"));
    // validate and compensate refuse it at the default capacity, naming the model.
    let err = run_err(args!["validate", "--model", &model200, &logs.val]);
    assert!(err.contains("m200.fogm axis 0") && err.contains("capacity is 128"), "{err}");
    let out = dir.path().join("c.csv");
    let err = run_err(args!["compensate", "--model", &model200, logs.val.join("run0.csv"), "--out", &out]);
    assert!(err.contains("capacity"), "{err}");
    assert!(!out.exists());
    // The exports carry the capacity the model needs.
    let rs = dir.path().join("model.rs");
    run_ok(args!["export", "--model", &model200, "--format", "rust", "--out", &rs, "--name", "GYRO_MODEL"]);
    assert!(fs::read_to_string(&rs).expect("rs").contains("pub const GYRO_MODEL_CAPACITY: usize = 200;"));
    let c = dir.path().join("model.c");
    run_ok(args!["export", "--model", &model200, "--format", "c", "--out", &c, "--name", "gyro_model"]);
    assert!(fs::read_to_string(dir.path().join("model.h"))
        .expect("h")
        .contains("#define GYRO_MODEL_CAPACITY 200u"));
}

/// `validate` on the logs a model was fitted on says the figures are in-sample (the
/// model's input digest is that of those logs, in order); on other logs it does not.
#[test]
fn validate_on_the_fitted_logs_says_in_sample() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = dir.path().join("m.fogm");
    let cal_logs: Vec<PathBuf> =
        (0..CAL_STARTS.len()).map(|i| logs().cal.join(format!("run{i}.csv"))).collect();
    let refs: Vec<&Path> = cal_logs.iter().map(PathBuf::as_path).collect();
    fit("poly", &model, &refs);
    let stderr = |logs: &[PathBuf]| {
        let mut args = args!["validate", "--model", &model];
        args.extend(logs.iter().map(OsString::from));
        let out = cal().args(args).assert().success();
        String::from_utf8_lossy(&out.get_output().stderr).into_owned()
    };
    let same = stderr(&cal_logs);
    assert!(same.contains("these 8 logs are the ones") && same.contains("in-sample"), "{same}");
    let other: Vec<PathBuf> = (0..VAL_STARTS.len()).map(|i| logs().val.join(format!("run{i}.csv"))).collect();
    let quiet = stderr(&other);
    assert!(!quiet.contains("in-sample"), "{quiet}");
    // Two calibration logs among the validation logs (format 6 records each log's digest):
    // named, with how many of the logs given they are, on stderr and in the report.
    let mixed: Vec<PathBuf> = other.iter().chain(&cal_logs[..2]).cloned().collect();
    let report = dir.path().join("report");
    let mut args = args!["validate", "--model", &model, "--report", &report];
    args.extend(mixed.iter().map(OsString::from));
    let out = cal().args(args).assert().success();
    let said = String::from_utf8_lossy(&out.get_output().stderr).into_owned();
    let expected = format!(
        "{}, {} (2 of the {} logs given) are among the 8 logs {} was fitted on (their digests match)",
        cal_logs[0].display(),
        cal_logs[1].display(),
        mixed.len(),
        model.display()
    );
    assert!(said.contains(&expected), "{said}");
    let md = std::fs::read_to_string(report.join("report.md")).expect("report");
    assert!(
        md.contains("Runs the model was fitted on (their figures are in-sample):\n\n- ")
            && md.contains(&expected),
        "{md}"
    );
}

/// A gzip-compressed log is named as such (review12 finding 7: "the header row is not text"
/// and a folder hint with a doubled slash sent users in circles).
#[test]
fn a_gzip_log_is_named_gzip_compressed() {
    let dir = TempDir::new().expect("tempdir");
    let log = dir.path().join("run.csv");
    // gzip's header: magic 1f 8b, method 08, then flags and a time stamp.
    fs::write(&log, [0x1f, 0x8b, 0x08, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x03, b'x', b'\n'])
        .expect("write");
    let output = cal().args(args!["fit", "--out", dir.path().join("m.fogm"), &log]).output().expect("run");
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(err.contains("run.csv:1: the file is gzip-compressed: decompress it first"), "{err}");
}

/// `compensate` given a folder says it takes one log and how to run it per file (it said
/// "Is a directory (os error 21)" at line 1: review12 finding 11).
#[test]
fn compensate_of_a_folder_says_to_run_it_per_file() {
    let dir = TempDir::new().expect("tempdir");
    let (log, _) = short_log(dir.path(), "ok.csv");
    let model = dir.path().join("m.fogm");
    run_ok(args!["fit", "--method", "poly", "--out", &model, &log]);
    let output = cal()
        .args(args!["compensate", "--model", &model, dir.path(), "--out", dir.path().join("c.csv")])
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(err.contains("a folder; compensate takes one log and writes one CSV: run it per file"), "{err}");
    assert!(!dir.path().join("c.csv").exists());
}

/// review13: a spike within the f32 range stays in validate's figures (data as logged) and is
/// named on stderr and in --json's notes; a copy of a log under another name is named by fit
/// and validate; compensate --out - writes to stdout what a file output holds.
#[test]
fn spikes_copies_and_streamed_output_are_said() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = dir.path().join("m.fogm");
    let cal_logs: Vec<PathBuf> =
        (0..CAL_STARTS.len()).map(|i| logs().cal.join(format!("run{i}.csv"))).collect();
    // A copy of the first calibration log under another name: fitted twice, said.
    let copy = dir.path().join("copy.csv");
    fs::copy(&cal_logs[0], &copy).expect("copy");
    let mut args = args!["fit", "--method", "poly", "--out", &model];
    args.extend(cal_logs.iter().chain([&copy]).map(OsString::from));
    let out = cal().args(args).assert().success();
    let said = String::from_utf8_lossy(&out.get_output().stderr).into_owned();
    let same = format!(
        "logs with the same bytes, each counted as a run of its own: {} = {}",
        cal_logs[0].display(),
        copy.display()
    );
    assert!(said.contains(&format!("warning: {same}")), "{said}");
    // One row of a validation log holds an overload code.
    let val = logs().val.join("run0.csv");
    let text = fs::read_to_string(&val).expect("read");
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[1000].split(',').map(String::from).collect();
    let gyro = cells.len() - 1;
    cells[gyro] = "9.91E+37".into();
    lines[1000] = cells.join(",");
    let spiked = dir.path().join("spiked.csv");
    fs::write(&spiked, lines.join("\n") + "\n").expect("write");
    let doc = json(&run_ok(args!["validate", "--json", "--model", &model, &spiked, &val]));
    let notes: Vec<&str> = doc["notes"].as_array().expect("notes").iter().filter_map(Value::as_str).collect();
    let spike_note = notes.iter().find(|n| n.contains("beyond 10 robust SDs")).expect("the spike is named");
    assert!(
        spike_note
            .starts_with(&format!("{} axis 0: the raw gyro has 1 block mean beyond 10", spiked.display())),
        "{spike_note}"
    );
    // One block mean (of the log's samples) holds the code: its share shows in exponent form.
    assert!(
        spike_note.contains("e36 deg/h from it") || spike_note.contains("e37 deg/h from it"),
        "{spike_note}"
    );
    assert!(
        !notes.iter().any(|n| n.starts_with(&format!("{} axis 0: the raw gyro", val.display()))),
        "{notes:?}"
    );
    // The figures keep it: the spiked run's raw bias stability is beyond any gyro's.
    assert!(f(&doc["runs"][0]["raw_bias_stability_dph"]) > 1e30, "{doc}");
    // compensate to stdout: the same bytes as to a file.
    let file = dir.path().join("comp.csv");
    run_ok(args!["compensate", "--model", &model, "--out", &file, &val]);
    let streamed = run_ok(args!["compensate", "--model", &model, "--out", "-", &val]);
    assert_eq!(streamed, fs::read_to_string(&file).expect("read"));
    assert!(!dir.path().join("-").exists() && !Path::new("-").exists());
    // A log that does not exist: the error alone, nothing on stdout (review20 F11: the CSV
    // header was written first).
    let missing = dir.path().join("nosuch.csv");
    let output =
        cal().args(args!["compensate", "--model", &model, "--out", "-", &missing]).output().expect("run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success() && output.stdout.is_empty(), "{:?}", output.stdout);
    assert!(stderr.contains("nosuch.csv") && !stderr.contains("cut short"), "{stderr}");
    // A reader that closes stdout at once (`| head`): status 0, and a note that the notes on
    // the whole log were not reached (review13 F12: they were lost without a word).
    let (status, stderr) = run_with_stdout_closed(args!["compensate", "--model", &model, "--out", "-", &val]);
    assert!(status.success(), "{status:?}: {stderr}");
    assert!(stderr.contains("the reader of stdout closed it before the log's end"), "{stderr}");
    assert!(stderr.contains("--out FILE"), "{stderr}");
}

/// Logs with two gyro columns and a runs file: one rate per run is about one input axis, so
/// `fit` leaves the rates in and the model records so (format 8, code 2; review31a F7).
/// Validated on one of its gyro columns with the rates, a note says that the model holds its
/// calibration runs' rates; on both columns no rate is applied and nothing is said.
#[test]
fn rates_left_in_for_two_gyro_columns_are_recorded_and_noted() {
    let dir = TempDir::new().expect("tempdir");
    let mut logs = Vec::new();
    let mut rows = String::from("run,position,input_rate_dph\n");
    for (k, start_c) in [-10.0, 10.0, 30.0].into_iter().enumerate() {
        let one = dir.path().join(format!("one{k}.csv"));
        write_warmup(&one, start_c, 20.0, 40 + k as u64);
        let text = fs::read_to_string(&one).expect("read");
        let two = with_second_gyro(text.lines());
        let log = dir.path().join(format!("two{k}.csv"));
        write_lines(&log, &two);
        logs.push(log);
        rows.push_str(&format!("two{k},p{k},{}\n", 9.67 * if k == 1 { -1.0 } else { 1.0 }));
    }
    let runs = dir.path().join("runs.csv");
    fs::write(&runs, rows).expect("runs file");
    let model = dir.path().join("two.fogm");
    let mut fit = args!["fit", "--method", "poly", "--gyro-column", "gyro_dph", "--gyro-column", "gyro2"];
    fit.extend(args!["--runs", &runs, "--out", &model, "--json"]);
    fit.extend(logs.iter().map(OsString::from));
    let fitted = json(&run_ok(fit));
    assert_eq!(fitted["run_metadata"]["input_rates_subtracted"], false, "{}", fitted["run_metadata"]);
    let inspect = json(&run_ok(args!["inspect", &model, "--json"]));
    assert_eq!(
        (&inspect["format_version"], &inspect["input_rates_subtracted"]),
        (&Value::from(8), &Value::from(false))
    );
    let notes =
        |doc: &Value| arr(&doc["notes"]).iter().filter_map(Value::as_str).collect::<Vec<_>>().join("\n");
    let mut both = args!["validate", "--model", &model, "--runs", &runs, "--json"];
    both.extend(logs.iter().map(OsString::from));
    let both = json(&run_ok(both));
    assert!(
        arr(&both["runs"]).iter().all(|r| r["input_rate_dph"].is_null()),
        "rates about one axis are not applied"
    );
    assert!(!notes(&both).contains("input rates left in"), "{}", notes(&both));
    let mut first =
        args!["validate", "--model", &model, "--gyro-column", "gyro_dph", "--runs", &runs, "--json"];
    first.extend(logs.iter().map(OsString::from));
    let first = json(&run_ok(first));
    assert!(arr(&first["runs"]).iter().all(|r| r["input_rate_dph"].is_number()));
    assert!(
        notes(&first).contains("was fitted with its runs' input rates left in its gyro"),
        "{}",
        notes(&first)
    );
}

/// A fit without run metadata says that the rates the runs sensed stay in the model's bias
/// (review33b F1: a model of an up position held the Earth rate's 11.2 deg/h as bias, without
/// a word); with a runs file nothing of it is said.
#[test]
fn a_fit_without_run_metadata_says_the_sensed_rates_stay_in_the_bias() {
    let dir = TempDir::new().expect("tempdir");
    let mut logs = Vec::new();
    let mut rows = String::from("run,position,input_rate_dph\n");
    for (k, start_c) in [-10.0, 10.0, 30.0].into_iter().enumerate() {
        let log = dir.path().join(format!("run{k}.csv"));
        write_warmup(&log, start_c, 20.0, 60 + k as u64);
        logs.push(log);
        rows.push_str(&format!("run{k},up,9.67\n"));
    }
    let runs = dir.path().join("runs.csv");
    fs::write(&runs, rows).expect("runs file");
    let model = dir.path().join("m.fogm");
    let kinds = |doc: &Value| {
        arr(&doc["warnings"])
            .iter()
            .filter_map(|w| w["kind"].as_str().map(str::to_string))
            .collect::<Vec<_>>()
    };
    let mut bare = args!["fit", "--method", "poly", "--out", &model, "--json"];
    bare.extend(logs.iter().map(OsString::from));
    let output = cal().args(&bare).output().expect("run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("warning: no run metadata: whatever constant rate the gyro sensed"), "{stderr}");
    assert!(stderr.contains("--runs FILE"), "{stderr}");
    let doc: Value = serde_json::from_slice(&output.stdout).expect("json");
    assert!(kinds(&doc).contains(&"no_run_metadata".to_string()), "{:?}", kinds(&doc));
    let mut with_runs = args!["fit", "--method", "poly", "--runs", &runs, "--out", &model, "--json"];
    with_runs.extend(logs.iter().map(OsString::from));
    let output = cal().args(&with_runs).output().expect("run");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success() && !stderr.contains("no run metadata"), "{stderr}");
    let doc: Value = serde_json::from_slice(&output.stdout).expect("json");
    assert!(!kinds(&doc).contains(&"no_run_metadata".to_string()), "{:?}", kinds(&doc));
}
