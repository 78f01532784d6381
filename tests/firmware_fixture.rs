//! Fixture of the QEMU firmware harness (`examples/firmware-qemu`): a paper-size model, a
//! "recorded" warm-up trajectory and the host core's compensated output for it.
//!
//! The three files live in `examples/firmware-qemu/data/` and are committed:
//!
//! * `model.fogm`: one axis, hybrid: 4 polynomial terms plus a Delaunay mesh (`build_mesh`)
//!   of 8 paper-like warm-ups, 400 calibration points, written by `fogtemp_cal::encode`
//!   (about 50 KB);
//! * `trajectory.bin`: 240 s at 100 Hz, little-endian records `u64 time_us, f32 gyro_dph,
//!   f32 temp_c`, temperature on every 10th sample (NaN = no temperature with this sample),
//!   quantised to 0.0625 C. It holds the power-on warm-up (`WARMING_UP`, `PARTIAL_WINDOW`),
//!   a heater burst whose rate leaves the mesh hull (`OUTSIDE_HULL`), a duplicated record
//!   (`BAD_INPUT`) and an 8 s temperature dropout, longer than `max_gap_s` (`TEMP_STALE`,
//!   then a tracker restart);
//! * `expected_out.txt`: what the host `fogtemp_core::Compensator` outputs for it, in the
//!   firmware's line format (see [`expected_lines`]). `.ci/firmware-qemu.sh` checks that
//!   the firmware prints exactly these lines on the Cortex-M4F, so host == target bit for bit.
//!
//! Run with `FOGTEMP_BLESS=1` to (re)write the files. Without it the test regenerates them
//! in memory and fails if the committed files differ, that is, when the core or the writer
//! changed behaviour. Everything is generated with correctly rounded IEEE-754 operations
//! only (`+ - * /`, `sqrt`, `round`; own PRNG and `exp`, no libm, no `rand`), so the bytes
//! are the same on every host.

use std::path::PathBuf;

use fogtemp_cal::{build_mesh, encode, AxisModel, MeshPoint, ModelFile};
use fogtemp_core::{
    AxisProvenance, Compensator, FeatureSettings, Flags, Model, Normalisation, Output, OutsidePolicy,
    PolyTerm,
};

/// 20 s window of 20 one-second blocks: features are ready 5 s after power-on, so a short
/// trajectory reaches steady state.
const FEATURES: FeatureSettings =
    FeatureSettings { window_s: 20.0, block_count: 20, min_blocks: 5, max_gap_s: 5.0 };

/// Maps -40..80 C to -1..1 and 0..1 C/min to -1..1 (same as `tests/common`).
const NORMALISATION: Normalisation = Normalisation {
    temp_offset_c: 20.0,
    temp_scale_per_c: 1.0 / 60.0,
    rate_offset_c_per_min: 0.5,
    rate_scale_per_c_per_min: 2.0,
};

/// Feature-tracker capacity the firmware uses (`Compensator::<TRACKER_CAPACITY>`); it does
/// not change any result.
const TRACKER_CAPACITY: usize = 32;

/// Gyro sample period: 100 Hz.
const GYRO_PERIOD_US: u64 = 10_000;
/// Temperature arrives with every 10th gyro sample (10 Hz).
const TEMP_EVERY: u64 = 10;
/// Temperature sensor resolution, deg C (a typical 12-bit digital sensor).
const TEMP_LSB_C: f64 = 0.0625;
/// Trajectory length, gyro samples (240 s).
const GYRO_SAMPLES: u64 = 24_000;
/// Time of the first sample (the logger started 2 s after power-on).
const START_US: u64 = 2_000_000;
/// Earth-rate component the gyro sees at rest, deg/h: what compensation should leave.
const EARTH_DPH: f64 = 7.5;
/// Sample whose record the logger wrote twice (a temperature sample).
const DUPLICATED_SAMPLE: u64 = 6_000;
/// Temperature dropout (no temperature), seconds since the start: longer than `max_gap_s`.
const DROPOUT_S: (f64, f64) = (170.0, 178.0);
/// Heater burst: +0.5 C as a smoothstep from 90 s to 140 s (peak +0.9 C/min on top of the
/// warm-up), well above the fastest calibrated rate.
const HEATER: (f64, f64, f64) = (90.0, 140.0, 0.5);

/// Output lines: every `PRINT_STRIDE`-th record, plus every record where the flags or the
/// bias change, plus the first and the last.
const PRINT_STRIDE: usize = 20;

const DATA_DIR: &str = "examples/firmware-qemu/data";

/// `exp` from `+ - * /` only, so the fixture does not depend on the platform's libm.
/// Relative error about 1e-15 for |x| < 10, plenty for synthetic data.
fn exp_det(x: f64) -> f64 {
    let (mut r, mut halvings) = (x, 0);
    while r.abs() > 0.125 {
        r /= 2.0;
        halvings += 1;
    }
    let (mut term, mut sum) = (1.0f64, 1.0f64);
    for n in 1..=14 {
        term *= r / f64::from(n);
        sum += term;
    }
    for _ in 0..halvings {
        sum *= sum;
    }
    sum
}

/// SplitMix64: a tiny fixed PRNG, so the fixture never changes with a `rand` release.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Zero-mean, unit-variance noise (Irwin-Hall sum of 4 uniforms; no `ln`/`cos`).
    fn noise(&mut self) -> f64 {
        let s: f64 = (0..4).map(|_| self.uniform()).sum();
        (s - 2.0) * 3.0f64.sqrt()
    }
}

/// The "true" drift of the simulated gyro, deg/h: smooth, not planar.
fn true_bias_dph(temp_c: f64, rate_c_per_min: f64) -> f64 {
    0.002 * temp_c + 1.5e-5 * temp_c * temp_c + 0.06 * rate_c_per_min + 8.0e-4 * temp_c * rate_c_per_min
        - 0.02 * rate_c_per_min * rate_c_per_min
}

/// Polynomial part of the model (normalised inputs): the temperature trend and the linear
/// rate term of [`true_bias_dph`]; the mesh carries the rest.
fn poly_terms() -> Vec<PolyTerm> {
    let term = |temp_power, rate_power, coefficient_dph| PolyTerm { temp_power, rate_power, coefficient_dph };
    vec![term(0, 0, 0.076), term(1, 0, 0.156), term(2, 0, 0.054), term(0, 1, 0.03)]
}

/// [`poly_terms`] in f64 (powers by repeated multiplication, no `powi`).
fn poly_f64(x: f64, y: f64) -> f64 {
    let power = |v: f64, n: u8| (0..n).fold(1.0, |p, _| p * v);
    poly_terms()
        .iter()
        .map(|t| f64::from(t.coefficient_dph) * power(x, t.temp_power) * power(y, t.rate_power))
        .sum()
}

/// Calibration points like the paper's: 8 power-on warm-ups (start -40..60 C), each a
/// first-order rise of 12 C with a 20 min time constant over 120 min, sampled densely
/// early. Values are the residual of [`true_bias_dph`] after the polynomial.
fn calibration_points() -> Vec<MeshPoint> {
    let starts = [-40.0, -25.0, -10.0, 5.0, 20.0, 35.0, 45.0, 60.0];
    let (self_heat_c, tau_min, duration_min, per_run) = (12.0, 20.0, 120.0, 50);
    let mut out = Vec::new();
    for (run, start) in starts.iter().enumerate() {
        for i in 0..per_run {
            let s = (f64::from(i) + 0.5) / f64::from(per_run);
            let t_min = duration_min * s * s;
            let decay = exp_det(-t_min / tau_min);
            let temp_c = start + self_heat_c * (1.0 - decay) + 0.01 * run as f64;
            let rate = self_heat_c / tau_min * decay;
            let x =
                (temp_c - f64::from(NORMALISATION.temp_offset_c)) * f64::from(NORMALISATION.temp_scale_per_c);
            let y = (rate - f64::from(NORMALISATION.rate_offset_c_per_min))
                * f64::from(NORMALISATION.rate_scale_per_c_per_min);
            let value_dph = true_bias_dph(temp_c, rate) - poly_f64(x, y);
            out.push(MeshPoint { temp_c, rate_c_per_min: rate, value_dph });
        }
    }
    out
}

/// The model blob with the mesh's `policy` outside its hull, and a line describing its mesh.
fn model_blob(policy: OutsidePolicy) -> (Vec<u8>, String) {
    let points = calibration_points();
    let mesh = build_mesh(&points, &NORMALISATION).expect("mesh builds");
    let about = format!(
        "model: {} calibration points -> {} mesh nodes ({} merged, {} flat hull points dropped), {} triangles",
        points.len(),
        mesh.vertices.len(),
        mesh.merged_duplicates,
        mesh.dropped_flat.len(),
        mesh.triangles.len()
    );
    let range = |f: fn(&MeshPoint) -> f64| {
        let v: Vec<f64> = points.iter().map(f).collect();
        (
            v.iter().copied().fold(f64::INFINITY, f64::min) as f32,
            v.iter().copied().fold(f64::NEG_INFINITY, f64::max) as f32,
        )
    };
    let (temp_min_c, temp_max_c) = range(|p| p.temp_c);
    let (rate_min_c_per_min, rate_max_c_per_min) = range(|p| p.rate_c_per_min);
    let axis = AxisModel {
        region: Vec::new(),
        poly_outside: fogtemp_core::PolyOutside::Extrapolate,
        features: FEATURES,
        normalisation: NORMALISATION,
        outside_policy: policy,
        poly: poly_terms(),
        mesh: Some(mesh),
        provenance: AxisProvenance {
            fit_point_count: points.len() as u32,
            residual_rms_dph: 0.0,
            residual_max_abs_dph: 0.0,
            temp_min_c,
            temp_max_c,
            rate_min_c_per_min,
            rate_max_c_per_min,
        },
    };
    // A fixed tool string (not the crate version), so a version bump does not change the blob.
    let blob = encode(&ModelFile {
        tool_version: "fogtemp fw-fixt".into(),
        input_digest: [0x5a; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    })
    .expect("encodes");
    (blob, about)
}

/// One trajectory record.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Record {
    time_us: u64,
    gyro_dph: f32,
    temp_c: Option<f32>,
}

/// Smoothstep 0..1 over `u` in 0..1, and its derivative.
fn smoothstep(u: f64) -> (f64, f64) {
    if u <= 0.0 {
        (0.0, 0.0)
    } else if u >= 1.0 {
        (1.0, 0.0)
    } else {
        (u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u))
    }
}

/// True sensor temperature (deg C) and its rate (deg C/min) at `t_s` seconds: a warm-up
/// from 25 C (+10 C, time constant 25 min, so 0.4 C/min at power-on) plus the heater burst.
fn true_temperature(t_s: f64) -> (f64, f64) {
    let (rise_c, tau_s) = (10.0, 1500.0);
    let decay = exp_det(-t_s / tau_s);
    let (h0, h1, h_c) = HEATER;
    let (s, ds) = smoothstep((t_s - h0) / (h1 - h0));
    let temp_c = 25.0 + rise_c * (1.0 - decay) + h_c * s;
    let rate_c_per_s = rise_c / tau_s * decay + h_c * ds / (h1 - h0);
    (temp_c, rate_c_per_s * 60.0)
}

fn trajectory() -> Vec<Record> {
    let mut rng = SplitMix64(0x00F0_6000_0000_0001);
    let mut out = Vec::with_capacity(GYRO_SAMPLES as usize + 1);
    for i in 0..GYRO_SAMPLES {
        let t_s = (i * GYRO_PERIOD_US) as f64 * 1.0e-6;
        let (temp_c, rate) = true_temperature(t_s);
        let gyro_dph = (EARTH_DPH + true_bias_dph(temp_c, rate) + 0.05 * rng.noise()) as f32;
        let temp_noise_c = 0.02 * rng.noise();
        let in_dropout = (DROPOUT_S.0..DROPOUT_S.1).contains(&t_s);
        let temp_c = (i % TEMP_EVERY == 0 && !in_dropout)
            .then(|| (((temp_c + temp_noise_c) / TEMP_LSB_C).round() * TEMP_LSB_C) as f32);
        let record = Record { time_us: START_US + i * GYRO_PERIOD_US, gyro_dph, temp_c };
        out.push(record);
        if i == DUPLICATED_SAMPLE {
            out.push(record);
        }
    }
    out
}

/// `u64 time_us, f32 gyro_dph, f32 temp_c` little-endian; NaN temperature = none.
fn encode_trajectory(records: &[Record]) -> Vec<u8> {
    let mut out = Vec::with_capacity(records.len() * 16);
    for r in records {
        out.extend_from_slice(&r.time_us.to_le_bytes());
        out.extend_from_slice(&r.gyro_dph.to_le_bytes());
        out.extend_from_slice(&r.temp_c.unwrap_or(f32::NAN).to_le_bytes());
    }
    out
}

/// Runs the host compensator over `records`.
fn compensate(blob: &[u8], records: &[Record]) -> Vec<Output> {
    let model = Model::from_bytes(blob).expect("model parses");
    let mut comp: Compensator<'_, TRACKER_CAPACITY> = Compensator::new(&model, 0).expect("compensator");
    records.iter().map(|r| comp.step(r.time_us, r.gyro_dph, r.temp_c)).collect()
}

/// FNV-1a 64 over every output (rate bits, bias bits, both little-endian, then flags):
/// the firmware computes the same, so all samples are compared, not only printed ones.
fn digest(outputs: &[Output]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for o in outputs {
        for b in o
            .rate_dph
            .to_bits()
            .to_le_bytes()
            .into_iter()
            .chain(o.bias_dph.to_bits().to_le_bytes())
            .chain([o.flags.0])
        {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// The firmware's comparable lines: `out <index> <rate bits> <bias bits> <flags>` (8, 8, 2
/// lowercase hex digits) for the selected records, then `digest <records> <16 hex digits>`.
fn expected_lines(outputs: &[Output]) -> String {
    let mut s = String::new();
    let last = outputs.len().saturating_sub(1);
    for (i, o) in outputs.iter().enumerate() {
        let changed = i
            .checked_sub(1)
            .and_then(|p| outputs.get(p))
            .is_none_or(|prev| prev.flags != o.flags || prev.bias_dph.to_bits() != o.bias_dph.to_bits());
        if changed || i % PRINT_STRIDE == 0 || i == last {
            s.push_str(&format!(
                "out {i} {:08x} {:08x} {:02x}\n",
                o.rate_dph.to_bits(),
                o.bias_dph.to_bits(),
                o.flags.0
            ));
        }
    }
    s.push_str(&format!("digest {} {:016x}\n", outputs.len(), digest(outputs)));
    s
}

/// Checks that the fixture exercises what it claims to; returns a summary.
fn check_fixture(
    blob: &[u8],
    trajectory_bytes: &[u8],
    records: &[Record],
    outputs: &[Output],
    lines: &str,
) -> String {
    let model = Model::from_bytes(blob).expect("model parses");
    let mesh = model.axis(0).expect("axis 0").mesh.expect("mesh");
    assert!((300..=600).contains(&mesh.vertex_count()), "paper-size mesh: {} nodes", mesh.vertex_count());
    assert!(trajectory_bytes.len() < 400_000, "trajectory.bin is {} bytes", trajectory_bytes.len());
    let printed = lines.lines().count();
    assert!(printed <= 3000, "{printed} output lines is too many for semihosting");

    let any = |flag: Flags| outputs.iter().any(|o| o.flags.contains(flag));
    for (name, flag) in Flags::NAMED {
        assert!(any(flag), "the trajectory never raises {name}");
    }
    // The dropout restarts the tracker: WARMING_UP again after steady state.
    let first_clean = outputs.iter().position(|o| o.flags.is_empty()).expect("a steady stretch");
    assert!(
        outputs[first_clean..].iter().any(|o| o.flags.contains(Flags::WARMING_UP)),
        "no restart after the dropout"
    );
    assert!(records.iter().all(|r| r.temp_c.is_none_or(|t| t.is_finite())));

    // Compensation works: in steady state (no flags) the output is the Earth rate, on
    // average, with the drift gone.
    let clean: Vec<(f64, f64)> = records
        .iter()
        .zip(outputs)
        .filter(|(_, o)| o.flags.is_empty())
        .map(|(r, o)| (f64::from(r.gyro_dph), f64::from(o.rate_dph)))
        .collect();
    let mean = |f: fn(&(f64, f64)) -> f64| clean.iter().map(f).sum::<f64>() / clean.len() as f64;
    let (raw, compensated) = (mean(|p| p.0), mean(|p| p.1));
    assert!((compensated - EARTH_DPH).abs() < 0.01, "compensated mean {compensated} deg/h (raw {raw})");
    assert!((raw - EARTH_DPH).abs() > 0.05, "the drift is too small to show compensation: raw {raw}");
    format!(
        "trajectory: {} records ({} bytes); expected_out.txt: {printed} lines; flag-free samples: \
         raw mean {raw:.4} deg/h, compensated mean {compensated:.4} deg/h (Earth rate {EARTH_DPH})",
        records.len(),
        trajectory_bytes.len()
    )
}

/// What today's code produces: (file name, bytes). The second model is the same with the
/// mesh continued linearly beyond its hull (`OutsidePolicy::LinearFromBoundary`), the third
/// with that continuation's gradients stored in the blob (`OutsidePolicy::StoredGradients`,
/// format version 3), the same trajectory through each: `.ci/run` runs the firmware on all
/// three.
fn generate() -> (Vec<(&'static str, Vec<u8>)>, String) {
    let (blob, about_model) = model_blob(OutsidePolicy::NearestHull);
    let records = trajectory();
    let trajectory_bytes = encode_trajectory(&records);
    let outputs = compensate(&blob, &records);
    let lines = expected_lines(&outputs);
    let about_run = check_fixture(&blob, &trajectory_bytes, &records, &outputs, &lines);
    let (linear_blob, _) = model_blob(OutsidePolicy::LinearFromBoundary);
    let linear_outputs = compensate(&linear_blob, &records);
    let about_linear = check_linear(&outputs, &linear_outputs);
    let linear_lines = expected_lines(&linear_outputs);
    let (stored_blob, _) = model_blob(OutsidePolicy::StoredGradients);
    assert_eq!(Model::from_bytes(&stored_blob).expect("parses").format_version(), 3);
    let stored_outputs = compensate(&stored_blob, &records);
    let about_stored = check_linear(&outputs, &stored_outputs).replace("model-linear", "model-gradients");
    let stored_lines = expected_lines(&stored_outputs);
    let files = vec![
        ("model.fogm", blob),
        ("trajectory.bin", trajectory_bytes),
        ("expected_out.txt", lines.into_bytes()),
        ("model-linear.fogm", linear_blob),
        ("expected_out-linear.txt", linear_lines.into_bytes()),
        ("model-gradients.fogm", stored_blob),
        ("expected_out-gradients.txt", stored_lines.into_bytes()),
    ];
    (files, format!("{about_model}\n{about_run}\n{about_linear}\n{about_stored}"))
}

/// A linear policy changes only what is flagged `OUTSIDE_HULL`, and changes some of it (the
/// heater burst leaves the hull), so the second and third firmware runs exercise the
/// continuation.
fn check_linear(held: &[Output], linear: &[Output]) -> String {
    assert_eq!(held.len(), linear.len());
    let mut changed = 0usize;
    for (h, l) in held.iter().zip(linear) {
        assert_eq!(h.flags, l.flags, "the policy does not change the flags");
        if h.flags.contains(Flags::OUTSIDE_HULL) {
            changed += usize::from(h.rate_dph.to_bits() != l.rate_dph.to_bits());
        } else {
            assert_eq!(h.rate_dph.to_bits(), l.rate_dph.to_bits(), "inside the hull the policies agree");
        }
    }
    let outside = held.iter().filter(|o| o.flags.contains(Flags::OUTSIDE_HULL)).count();
    assert!(changed > 0, "no OUTSIDE_HULL sample changes with the linear policy ({outside} flagged)");
    format!("model-linear.fogm: {changed} of {outside} OUTSIDE_HULL outputs differ from the held ones")
}

#[test]
fn firmware_fixture_matches_host_core() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(DATA_DIR);
    let (files, about) = generate();
    eprintln!("{about}");
    if std::env::var_os("FOGTEMP_BLESS").is_some_and(|v| v == "1") {
        for (name, bytes) in &files {
            let path = dir.join(name);
            std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("write {}: {e}", path.display()));
            eprintln!("blessed {} ({} bytes)", path.display(), bytes.len());
        }
        return;
    }
    let mut stale = Vec::new();
    for (name, bytes) in &files {
        let path = dir.join(name);
        match std::fs::read(&path) {
            Ok(committed) if committed == *bytes => {}
            Ok(committed) => {
                let at = committed
                    .iter()
                    .zip(bytes)
                    .position(|(a, b)| a != b)
                    .unwrap_or(committed.len().min(bytes.len()));
                stale.push(format!(
                    "{DATA_DIR}/{name}: differs at byte {at} (committed {} bytes, generated {} bytes)",
                    committed.len(),
                    bytes.len()
                ));
            }
            Err(e) => stale.push(format!("{DATA_DIR}/{name}: cannot read ({e})")),
        }
    }
    assert!(
        stale.is_empty(),
        "the committed firmware fixture is not what today's fogtemp-core/fogtemp-cal produce:\n  {}\n\
         If the change in behaviour is intended, re-bless with\n  \
         FOGTEMP_BLESS=1 cargo test --test firmware_fixture\n\
         then re-run `bash .ci/firmware-qemu.sh` (the firmware must still match bit for bit) \
         and commit the files in {DATA_DIR}/.",
        stale.join("\n  ")
    );
}
