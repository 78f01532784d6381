//! The diagnosis proved on concealed data made WITH THE PROJECT'S SIMULATOR: one dataset per
//! catalogue effect, where the effect is concealed by the protocol or by another effect, and
//! a null dataset (designs, sizes and what conceals what: `fogtemp_diagnose::concealed`
//! and docs/diagnose.md). "Simulated" is the scenario without the effect, "recorded" the same
//! scenario with it; each has its own noise seed (paper noise: N = 0.0005 deg/sqrt(h),
//! B = 0.002 deg/h), 1 Hz, 2 h runs.
//!
//! Every test but one uses the same fixed repetition seed ([`SEED`], chosen before any test
//! was run); `confusion_matrix_over_seeds` reruns the documented x2 confusion matrix on its
//! seeds (5000-5019) and checks it against docs/diagnose.md.
//! Sizes: the null and `thermal_lag` datasets as designed (the lag's size is the paper's
//! b(T) and coil lag); the other effects at twice the first design's sizes (`datasets_at(2.0)`,
//! RMS 0.7-2.7 x the residual's 100 s noise), because the first design's sizes (0.35-0.9 x)
//! were below the detection power of 8 runs with flicker noise (the confusion matrix of both
//! is in docs/diagnose.md). Parameter tolerance: 3.5 reported standard errors (the two-sided
//! 99 % Student-t quantile with 7 degrees of freedom, 8 runs; the thermal_lag and shupe_rate
//! designs have 10; the errors are delete-one-run jackknife), with each reported standard
//! error at most twice the mean one docs/diagnose.md reports for that parameter (see
//! [`MAX_SE_OVER_DOCUMENTED`]).

mod common;

use fogtemp_diagnose::concealed::{datasets_at, generate, truth_map, ConcealedDataset};
use fogtemp_diagnose::{diagnose, DiagnoseOptions, Diagnosis};

/// Repetition seed of every test (the simulated and recorded noise seeds derive from it).
const SEED: u64 = 7;

/// Tolerance in reported standard errors.
const K_SE: f64 = 3.5;

fn dataset(label: &str, scale: f64) -> ConcealedDataset {
    datasets_at(scale).into_iter().find(|d| d.label == label).expect("dataset exists")
}

/// Diagnoses `label` at `scale`; returns the diagnosis and the true parameters.
fn run(label: &str, scale: f64) -> (Diagnosis, std::collections::BTreeMap<String, f64>) {
    let ds = dataset(label, scale);
    let g = generate(&ds, SEED);
    assert!(g.simulated.iter().zip(&g.recorded).all(|(s, r)| s.name == r.name && s.gyro_dph != r.gyro_dph));
    let d =
        diagnose(&g.simulated, &g.recorded, &DiagnoseOptions::default(), |_, _| {}).expect("diagnosis runs");
    eprintln!("{label}: {}", d.summary);
    for e in &d.left_out {
        eprintln!("  left out {}: {:?}", e.effect, e.parameters);
    }
    common::assert_selection_consistent(&d);
    (d, truth_map(&ds, &g))
}

fn names(d: &Diagnosis) -> Vec<&str> {
    d.left_out.iter().map(|e| e.effect.as_str()).collect()
}

/// How far a reported standard error may exceed the documented one: at most this many times
/// the mean reported SE of the same parameter over seeds 5000-5019 (docs/diagnose.md, the x2
/// parameter-recovery table; the same datasets and options). A delete-one-run jackknife
/// variance has (runs - 1) degrees of freedom, 7 here (9 for the thermal_lag and shupe_rate
/// designs): if SE^2 scatters like E[SE^2] chi^2_7 / 7, one seed's SE exceeds twice its mean
/// with probability about 2e-4 (chi^2_7 > 28; chi^2_9 > 36: 4e-5). So the bound fails an SE
/// inflated to twice the method's documented error (which would let the 3.5 SE check accept
/// almost anything) and, by chance, practically never. Seen with [`SEED`]: SE / documented
/// mean SE from 0.58 (shupe_rate.coil_lag_s) to 1.78 (shupe_rate.coefficient), printed.
const MAX_SE_OVER_DOCUMENTED: f64 = 2.0;

/// The parameter of `effect` is within `K_SE` reported standard errors of its truth, and
/// that SE is at most [`MAX_SE_OVER_DOCUMENTED`] times `documented_se`, the parameter's mean
/// reported SE over seeds in docs/diagnose.md (x2 table), so an inflated SE cannot pass.
fn assert_recovered(d: &Diagnosis, effect: &str, name: &str, truth: f64, documented_se: f64) {
    let e = d.left_out.iter().find(|e| e.effect == effect).expect("effect named");
    let p = e.parameters.get(name).unwrap_or_else(|| panic!("{effect}.{name} in {:?}", e.parameters));
    let se = p.std_error.expect("standard error");
    eprintln!(
        "  {effect}.{name} = {:.5} +- {se:.5} (truth {truth:.5}; {:.2} SE off; SE / documented {:.2})",
        p.value,
        (p.value - truth).abs() / se,
        se / documented_se
    );
    assert!(se.is_finite() && se > 0.0, "{effect}.{name}: SE {se}");
    assert!(
        se <= MAX_SE_OVER_DOCUMENTED * documented_se,
        "{effect}.{name}: SE {se} above {MAX_SE_OVER_DOCUMENTED} x the documented mean SE {documented_se}"
    );
    assert!(
        (p.value - truth).abs() <= K_SE * se,
        "{effect}.{name} = {} +- {se}, truth {truth} (tolerance {K_SE} SE)",
        p.value
    );
}

fn assert_named_first(d: &Diagnosis, effect: &str) {
    assert_eq!(names(d).first().copied(), Some(effect), "named {:?}", names(d));
    let e = &d.left_out[0];
    assert!(e.heldout_improvement > 0.0, "{effect}: held-out improvement {}", e.heldout_improvement);
}

fn candidate<'a>(d: &'a Diagnosis, effect: &str) -> &'a fogtemp_diagnose::CandidateReport {
    d.selection[0].candidates.iter().find(|c| c.effect == effect).expect("candidate")
}

#[test]
fn null_dataset_names_nothing() {
    let (d, _) = run("null", 1.0);
    assert!(d.left_out.is_empty(), "null dataset named {:?}", names(&d));
    // Spans significant against within-run (HAC) errors may remain under flicker; the
    // statement then locates them and says they do not repeat across runs (never "noise").
    assert!(
        d.summary.contains("consistent with noise") || d.summary.contains("does not repeat across runs"),
        "{}",
        d.summary
    );
}

/// Two-orientation designs with every injected size 0: the seeds (of 7000-7099) where the
/// run-level rules alone named an orientation term (docs/diagnose.md, twelfth session; 12 of
/// the 16 alarms of both designs). With the permutation test of the position labels, an
/// orientation-dependent term is not named on any of them; without it, on each.
#[test]
fn two_orientation_nulls_name_no_orientation_term() {
    let alarms = [
        ("orientation_offset", 7043),
        ("orientation_offset", 7058),
        ("scale_factor_temperature", 7002),
        ("scale_factor_temperature", 7015),
    ];
    let off = DiagnoseOptions { position_permutation: false, ..DiagnoseOptions::default() };
    for (label, seed) in alarms {
        let g = generate(&dataset(label, 0.0), seed);
        let orientation = |options: &DiagnoseOptions| -> Vec<String> {
            let d = diagnose(&g.simulated, &g.recorded, options, |_, _| {}).expect("diagnosis runs");
            d.left_out
                .iter()
                .map(|e| e.effect.clone())
                .filter(|e| e == "orientation_offset" || e == "scale_factor_temperature")
                .collect()
        };
        assert!(orientation(&DiagnoseOptions::default()).is_empty(), "{label} seed {seed}");
        assert!(!orientation(&off).is_empty(), "{label} seed {seed}: the old rules no longer alarm here");
    }
}

#[test]
fn thermal_lag_hidden_behind_shupe_is_named_and_recovered() {
    let (d, truth) = run("thermal_lag", 1.0);
    assert_named_first(&d, "thermal_lag");
    // A Shupe term explains nearly the same residual (b(T - tau dT/dt) ~ b - b' tau dT/dt):
    // the report must say that these runs hardly separate the two, and how to separate them.
    // Shupe comes first (alternatives are in catalogue order); since the signed-rank
    // fold rule (docs/diagnose.md, sixth session) gradient_rate, a rate term of the same
    // lagged temperature, also passes at that step and is listed after it.
    let lag = &d.left_out[0];
    assert_eq!(lag.alternatives.first().map(String::as_str), Some("shupe_rate"), "{}", lag.statement);
    assert!(lag.alternatives.iter().all(|a| a == "shupe_rate" || a == "gradient_rate"), "{}", lag.statement);
    assert!(lag.statement.contains("alternative explanation: shupe_rate"), "{}", lag.statement);
    assert_recovered(&d, "thermal_lag", "gain", truth["gain"], 0.16823);
    assert_recovered(&d, "thermal_lag", "tau_s", truth["tau_s"], 125.00141);
}

#[test]
fn shupe_rate_mimicking_a_warmup_is_named_and_recovered() {
    let (d, truth) = run("shupe_rate", 2.0);
    assert_named_first(&d, "shupe_rate");
    assert_recovered(
        &d,
        "shupe_rate",
        "coefficient_dph_per_c_per_min",
        truth["coefficient_dph_per_c_per_min"],
        0.00315,
    );
    assert_recovered(&d, "shupe_rate", "coil_lag_s", truth["coil_lag_s"], 96.04723);
}

#[test]
fn warmup_transient_decaying_like_dt_dt_is_named_and_recovered() {
    let (d, truth) = run("warmup_transient", 2.0);
    assert_named_first(&d, "warmup_transient");
    assert_recovered(&d, "warmup_transient", "amplitude_dph", truth["amplitude_dph"], 0.00172);
    assert_recovered(&d, "warmup_transient", "tau_s", truth["tau_s"], 333.88101);
}

#[test]
fn orientation_offset_of_a_tilted_position_is_named_and_recovered() {
    let (d, truth) = run("orientation_offset", 2.0);
    assert_named_first(&d, "orientation_offset");
    assert_recovered(
        &d,
        "orientation_offset",
        "offset_pos2_minus_pos1_dph",
        truth["offset_pos2_minus_pos1_dph"],
        0.00217,
    );
}

#[test]
fn hysteresis_seen_only_in_two_cycling_runs_is_named_and_recovered() {
    let (d, truth) = run("hysteresis", 2.0);
    assert_named_first(&d, "hysteresis");
    assert_recovered(&d, "hysteresis", "half_gap_dph", truth["half_gap_dph"], 0.00167);
}

#[test]
fn static_ripple_across_overlapping_runs_is_named_and_its_shape_recovered() {
    let (d, truth) = run("static_shape", 2.0);
    assert_named_first(&d, "static_shape");
    let e = &d.left_out[0];
    let get = |n: &str| e.parameters.get(n).map(|p| p.value).unwrap_or_else(|| panic!("{n}"));
    let (lo, hi, k) = (get("t_min_c"), get("t_max_c"), get("basis_functions") as usize);
    let coef: Vec<f64> = (1..k).map(|j| get(&format!("spline_{j}_dph"))).collect();
    // The fitted shape (a function of the coil temperature) follows the injected ripple over
    // the central 80 % of the range: correlation > 0.7, and peak-to-peak within 50 %.
    let (grid, fitted) = common::static_shape_on_central_grid(lo, hi, k, &coef);
    let amplitude = truth["peak_to_peak_dph"] / 2.0;
    let injected: Vec<f64> =
        grid.iter().map(|t| amplitude * (std::f64::consts::TAU * t / 20.0).sin()).collect();
    let r = common::correlation(&fitted, &injected);
    eprintln!(
        "  shape correlation {r:.3}, peak-to-peak {:.5} (truth {:.5})",
        get("peak_to_peak_dph"),
        2.0 * amplitude
    );
    assert!(r > 0.7, "correlation of fitted and injected shape {r}");
    assert!((get("peak_to_peak_dph") / (2.0 * amplitude) - 1.0).abs() < 0.5);
}

#[test]
fn scale_factor_temperature_with_two_orientations_is_named_and_recovered() {
    let (d, truth) = run("scale_factor_temperature", 2.0);
    assert_named_first(&d, "scale_factor_temperature");
    assert_recovered(&d, "scale_factor_temperature", "s1_ppm_per_c", truth["s1_ppm_per_c"], 3.33894);
}

/// The coefficient is S3 times the coil's radial time constant (deg/h per deg C/min^2 of the
/// coil), not S3 itself, so only the coil lag is compared with the truth.
#[test]
fn gradient_rate_is_named_and_its_coefficient_and_coil_lag_recovered() {
    let (d, truth) = run("gradient_rate", 2.0);
    assert_named_first(&d, "gradient_rate");
    assert_recovered(&d, "gradient_rate", "coil_lag_s", truth["coil_lag_s"], 148.80980);
    assert_recovered(
        &d,
        "gradient_rate",
        "coefficient_dph_per_c_per_min2",
        truth["coefficient_dph_per_c_per_min2"],
        0.11418,
    );
}

#[test]
fn scale_factor_in_one_orientation_is_reported_not_identifiable() {
    let (d, _) = run("scale_factor_one_orientation", 2.0);
    let c = candidate(&d, "scale_factor_temperature");
    assert_eq!(c.status, "not_identifiable");
    assert!(c.note.contains(">= 2 orientations"), "{}", c.note);
    assert!(!names(&d).contains(&"scale_factor_temperature"));
}

#[test]
fn hysteresis_from_power_on_runs_only_is_reported_not_identifiable() {
    let (d, _) = run("hysteresis_power_on_only", 2.0);
    let c = candidate(&d, "hysteresis");
    assert_eq!(c.status, "not_identifiable");
    assert!(c.experiment.as_deref().unwrap_or("").contains("two ramp rates"));
    assert!(!names(&d).contains(&"hysteresis"));
}

/// The x2 confusion matrix of docs/diagnose.md (seeds 5000-5019, made with
/// `cargo run --release -p fogtemp-cal --example diagnose_confusion -- 20 5000 2`), per
/// dataset with an identifiable injected effect: (label, seeds where the injected effect was
/// named, seeds where it was named or listed in `alternatives` of a named effect).
/// (Seventh session's x2 matrix, "False alarms: fold counts of flexible terms and the sign
/// of a lag's gain" in docs/diagnose.md.)
const DOCUMENTED_X2: [(&str, usize, usize); 8] = [
    ("thermal_lag", 14, 20),
    ("shupe_rate", 20, 20),
    ("gradient_rate", 19, 19),
    ("warmup_transient", 20, 20),
    ("orientation_offset", 16, 16),
    ("hysteresis", 14, 14),
    ("static_shape", 18, 18),
    ("scale_factor_temperature", 17, 17),
];

/// First seed and number of seeds of the documented matrices.
const MATRIX_SEEDS: (u64, u64) = (5000, 20);

/// The documented x2 confusion matrix still holds, on the same seeds: every identifiable
/// injected effect is named in at least as many of the 20 seeds as docs/diagnose.md reports
/// (and named or offered as an alternative at least as often), and the null dataset and the
/// two designs concealed beyond recovery name nothing in any seed (the documented 20/20
/// "none"). Same seeds, same datasets, same options as the example that made the table, so
/// the documented counts are what the method achieves here; a lower count is a regression
/// of the diagnosis (or the table in docs/diagnose.md is out of date and must be re-measured
/// with the command above). 220 diagnoses.
#[test]
fn confusion_matrix_over_seeds() {
    let (first, count) = MATRIX_SEEDS;
    let datasets = datasets_at(2.0);
    // The diagnosis and the simulator already use every core (rayon): one dataset at a time.
    let rows: Vec<ConfusionRow> = datasets.iter().map(|ds| confusion_row(ds, first..first + count)).collect();
    let mut failures = Vec::new();
    for (ds, row) in datasets.iter().zip(&rows) {
        let ConfusionRow { named, offered, nothing, counts } = row;
        eprintln!(
            "CONFUSION x2 {:<30} named {named:>2}, named or alternative {offered:>2}, nothing {nothing:>2} \
             of {count}; {counts:?}",
            ds.label
        );
        match DOCUMENTED_X2.iter().find(|(label, ..)| *label == ds.label) {
            Some(&(label, doc_named, doc_offered)) => {
                assert!(ds.identifiable && ds.injected.is_some(), "{label}");
                if *named < doc_named || *offered < doc_offered {
                    failures.push(format!(
                        "{label}: named {named}, named or alternative {offered} of {count} \
                         (documented {doc_named}, {doc_offered})"
                    ));
                }
            }
            None => {
                // The null dataset and the designs concealed beyond recovery.
                assert!(ds.injected.is_none() || !ds.identifiable, "{} has no documented row", ds.label);
                if *nothing < count as usize {
                    failures.push(format!(
                        "{}: named {counts:?}; documented: nothing named in any of the {count} seeds",
                        ds.label
                    ));
                }
            }
        }
    }
    assert_eq!(
        rows.len(),
        DOCUMENTED_X2.len() + 3,
        "the null dataset, 8 identifiable designs, 2 beyond recovery"
    );
    assert!(failures.is_empty(), "below docs/diagnose.md's x2 matrix:\n{}", failures.join("\n"));
}

/// One row of the confusion matrix: seeds where the injected effect was named, where it was
/// named or an alternative of a named effect, where nothing was named, and how often each
/// effect was named.
struct ConfusionRow {
    named: usize,
    offered: usize,
    nothing: usize,
    counts: std::collections::BTreeMap<String, usize>,
}

fn confusion_row(ds: &ConcealedDataset, seeds: std::ops::Range<u64>) -> ConfusionRow {
    let mut row = ConfusionRow { named: 0, offered: 0, nothing: 0, counts: Default::default() };
    for seed in seeds {
        let g = generate(ds, seed);
        let d = diagnose(&g.simulated, &g.recorded, &DiagnoseOptions::default(), |_, _| {})
            .expect("diagnosis runs");
        for e in &d.left_out {
            *row.counts.entry(e.effect.clone()).or_default() += 1;
        }
        row.nothing += usize::from(d.left_out.is_empty());
        if let Some(effect) = ds.injected.map(|e| e.name()) {
            row.named += usize::from(d.left_out.iter().any(|e| e.effect == effect));
            row.offered += usize::from(
                d.left_out.iter().any(|e| e.effect == effect || e.alternatives.iter().any(|a| a == effect)),
            );
        }
    }
    row
}
