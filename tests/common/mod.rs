//! Shared fixtures for the end-to-end tests: point sets and models built with the real writer.
#![allow(dead_code, missing_docs)]

use fogtemp_cal::{build_mesh, encode, AxisModel, MeshPoint, ModelFile};
use fogtemp_core::{AxisProvenance, FeatureSettings, Mesh, Model, Normalisation, OutsidePolicy, PolyTerm};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// Paper defaults: 100 s window of 100 one-second blocks.
pub const FEATURES: FeatureSettings =
    FeatureSettings { window_s: 100.0, block_count: 100, min_blocks: 10, max_gap_s: 5.0 };

/// Maps -40..80 C to -1..1 and 0..1 C/min to -1..1.
pub const NORMALISATION: Normalisation = Normalisation {
    temp_offset_c: 20.0,
    temp_scale_per_c: 1.0 / 60.0,
    rate_offset_c_per_min: 0.5,
    rate_scale_per_c_per_min: 2.0,
};

pub fn rng(seed: u64) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(seed)
}

/// Standard normal deviate (Box-Muller), so the tests need no distribution crate.
pub fn gaussian(r: &mut impl Rng) -> f64 {
    let u1: f64 = r.gen_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = r.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// A smooth, non-planar bias surface in deg/h.
pub fn bias_surface(temp_c: f64, rate_c_per_min: f64) -> f64 {
    0.002 * temp_c
        + 1.5e-5 * temp_c * temp_c
        + 0.06 * rate_c_per_min
        + 0.01 * (temp_c / 15.0).sin() * rate_c_per_min
}

/// Uniform random points over the calibrated box.
pub fn random_points(n: usize, seed: u64, value: impl Fn(f64, f64) -> f64) -> Vec<MeshPoint> {
    let mut r = rng(seed);
    (0..n)
        .map(|_| {
            let temp_c = r.gen_range(-40.0..80.0);
            let rate_c_per_min = r.gen_range(0.0..1.0);
            MeshPoint { temp_c, rate_c_per_min, value_dph: value(temp_c, rate_c_per_min) }
        })
        .collect()
}

/// Paper-like points: 8 power-on warm-ups (start -40..60 C), each a first-order rise of
/// `self_heat_c` with time constant `tau_min`, sampled densely early and sparsely later.
pub fn paper_points(per_run: usize, value: impl Fn(f64, f64) -> f64) -> Vec<MeshPoint> {
    let starts = [-40.0, -25.0, -10.0, 5.0, 20.0, 35.0, 45.0, 60.0];
    let (self_heat_c, tau_min, duration_min) = (12.0, 20.0, 120.0);
    let mut out = Vec::new();
    for (run, start) in starts.iter().enumerate() {
        for i in 0..per_run {
            // Quadratic spacing: dense during the fast warm-up.
            let s = (i as f64 + 0.5) / per_run as f64;
            let t_min = duration_min * s * s;
            let temp_c = start + self_heat_c * (1.0 - (-t_min / tau_min).exp()) + 0.01 * run as f64;
            let rate = self_heat_c / tau_min * (-t_min / tau_min).exp();
            out.push(MeshPoint { temp_c, rate_c_per_min: rate, value_dph: value(temp_c, rate) });
        }
    }
    out
}

pub fn provenance() -> AxisProvenance {
    AxisProvenance {
        fit_point_count: 0,
        residual_rms_dph: 0.0,
        residual_max_abs_dph: 0.0,
        temp_min_c: -40.0,
        temp_max_c: 80.0,
        rate_min_c_per_min: 0.0,
        rate_max_c_per_min: 1.0,
    }
}

/// A one-axis mesh model blob of `points`.
pub fn mesh_blob(points: &[MeshPoint], policy: OutsidePolicy) -> Vec<u8> {
    model_blob(Vec::new(), Some(points), policy)
}

/// A one-axis model with the given polynomial terms and optional mesh points.
pub fn model_blob(poly: Vec<PolyTerm>, points: Option<&[MeshPoint]>, policy: OutsidePolicy) -> Vec<u8> {
    let mesh = points.map(|p| build_mesh(p, &NORMALISATION).expect("mesh builds"));
    let axis = AxisModel {
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
        features: FEATURES,
        normalisation: NORMALISATION,
        outside_policy: policy,
        poly,
        mesh,
        provenance: provenance(),
    };
    encode(&ModelFile {
        tool_version: "fogtemp test".into(),
        input_digest: [7; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    })
    .expect("encodes")
}

/// Parses a leaked copy of a one-axis mesh `blob` (tests keep meshes for their whole run).
pub fn load(blob: Vec<u8>) -> (Model<'static>, Mesh<'static>) {
    let bytes: &'static [u8] = Box::leak(blob.into_boxed_slice());
    let model = Model::from_bytes(bytes).expect("writer output parses");
    let mesh = model.axis(0).expect("axis 0").mesh.expect("axis has a mesh");
    (model, mesh)
}

/// Path of the `fogtemp-cal` executable for the command-line tests: `FOGTEMP_CAL_BIN` if set,
/// else built once per test process by asking cargo (in the same profile as the tests) where
/// the binary is, since integration tests of the root package get no `CARGO_BIN_EXE_` for it.
pub fn fogtemp_cal_bin() -> &'static std::path::Path {
    static BIN: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    BIN.get_or_init(|| {
        if let Some(path) = std::env::var_os("FOGTEMP_CAL_BIN") {
            return std::path::PathBuf::from(path);
        }
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let mut build = std::process::Command::new(cargo);
        build
            .args(["build", "--package", "fogtemp-cli", "--bin", "fogtemp-cal"])
            .arg("--message-format=json-render-diagnostics")
            .arg("--manifest-path")
            .arg(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml"));
        if !cfg!(debug_assertions) {
            build.arg("--release");
        }
        let out = build.output().expect("cannot run cargo to build fogtemp-cal");
        assert!(
            out.status.success(),
            "cargo build -p fogtemp-cli failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter_map(|line| serde_json::from_str::<serde_json::Value>(line).ok())
            .filter(|m| m["reason"] == "compiler-artifact" && m["target"]["name"] == "fogtemp-cal")
            .find_map(|m| m["executable"].as_str().map(std::path::PathBuf::from))
            .expect("cargo reported no fogtemp-cal executable")
    })
}

/// A command line for `fogtemp-cal`.
pub fn cal() -> assert_cmd::Command {
    assert_cmd::Command::new(fogtemp_cal_bin())
}

/// Runs `fogtemp-cal args...`, requires success, returns stdout.
pub fn run_ok<I, S>(args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let out = cal().args(args).assert().success();
    String::from_utf8_lossy(&out.get_output().stdout).into_owned()
}

/// Runs `fogtemp-cal args...`, requires failure, returns stderr.
pub fn run_err<I, S>(args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let out = cal().args(args).assert().failure();
    String::from_utf8_lossy(&out.get_output().stderr).into_owned()
}

/// A fitted static shape on 81 points of the central 80 % of `lo..hi`: the B-spline basis of
/// `k` functions there, the first (the constant) left out, weighted by `coef` (the reported
/// `spline_1..` coefficients). Returns the grid and the shape on it.
pub fn static_shape_on_central_grid(lo: f64, hi: f64, k: usize, coef: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let grid: Vec<f64> = (0..=80).map(|i| lo + (hi - lo) * (0.1 + 0.8 * f64::from(i) / 80.0)).collect();
    let fitted =
        grid.iter().map(|&t| fogtemp_diagnose::effects::static_shape_value(t, lo, hi, k, coef)).collect();
    (grid, fitted)
}

/// Pearson correlation of two equally long series.
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

/// What every diagnosis promises about its named, dropped and alternative effects
/// (backward elimination, review16 F3): a dropped effect is not named and its removal did
/// not raise the LORO error; no named effect is another's alternative; and every effect the
/// run-level rules named lowers the held-out residual with the others kept (the test that
/// dropped the rest). A term only the noise-model route accepted is judged in the GLS metric
/// and may show a rise in the unweighted figure (its statement says it was accepted by that
/// test).
pub fn assert_selection_consistent(d: &fogtemp_diagnose::Diagnosis) {
    let named: Vec<&str> = d.left_out.iter().map(|e| e.effect.as_str()).collect();
    for e in &d.dropped {
        assert!(!named.contains(&e.effect.as_str()), "{} both named and dropped", e.effect);
        assert!(e.loro_rms_without_dph <= e.loro_rms_with_dph, "{e:?}");
        assert!(e.entered_at_step >= 1 && e.entered_at_step <= d.selection.len(), "{e:?}");
    }
    for e in &d.left_out {
        for alternative in &e.alternatives {
            assert!(
                !named.contains(&alternative.as_str()),
                "{alternative} named and {}'s alternative",
                e.effect
            );
        }
        let route_only = e.statement.contains("accepted by the noise-model GLS test");
        if d.left_out.len() > 1 && !route_only {
            assert!(e.heldout_improvement > 0.0, "{}: {}", e.effect, e.statement);
        }
    }
}
