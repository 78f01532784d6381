//! The training-size correction of cross-validation (the default since 2026-11-26, adopted by a
//! test written down before it was measured: docs/calibration-testbed.md; `fit --cv-correction
//! none` turns it off).
//!
//! A fold's model is fitted on fewer runs than the final model, and a flexible model loses
//! more from the missing run than a rigid one (its learning curve is steeper), so
//! leave-one-run-out cross-validation overstates the flexible candidates' error more than
//! the rigid ones'. Burman (1989, "A comparative study of ordinary cross-validation, v-fold
//! cross-validation and the repeated learning-testing methods", Biometrika 76(3), 503-514)
//! corrects v-fold cross-validation by the difference between the full model's and the fold
//! models' error over all the data:
//!
//! `CV* = CV + e(full) - mean_g e(g)`, `e(model)` = its mean loss over every calibration run.
//!
//! Here the loss of a run is its compensated bias stability, and the correction is applied
//! per fold, `s*_g = s_g + e(full) - e(g)`, so the one-standard-error rule pairs corrected
//! fold scores. `e` is computed from the runs' features already in memory (each feature
//! point's gyro mean minus the model at its (T, dT/dt): what the compensator subtracts over
//! that block), not by replaying the logs again; a fold model's held-out run is scored there
//! as the fold scores it (inside the training region by default). The correction uses the
//! same feature path for both of its terms, so what it adds is a difference of like with like.

use fogtemp_core::{Model, WalkHint};

use crate::calibrate::RunFeatures;
use crate::features::FeaturePoint;
use crate::metrics::BiasStabilityOptions;
use crate::selection::{score_series, TrainingRegion};

/// How cross-validated scores are corrected before the rule compares them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum CvCorrection {
    /// The fold scores as measured.
    None,
    /// Burman's (1989) correction for the fold models' smaller training set (this module; the
    /// default).
    #[default]
    TrainingSize,
}

impl CvCorrection {
    /// The name `fit --cv-correction` takes.
    pub fn name(self) -> &'static str {
        match self {
            CvCorrection::None => "none",
            CvCorrection::TrainingSize => "training-size",
        }
    }
}

/// Compensated bias stability of one run's features on `axis` of `model`: the feature
/// points' gyro means minus the model at their (T, dT/dt), scored by
/// [`score_series`] as a replayed run is (with `region`, only the windows whose every point
/// lies inside it). NaN when the axis cannot be read or too few windows remain.
pub fn feature_score(
    model: &Model<'_>,
    axis: usize,
    points: &[FeaturePoint],
    region: Option<&TrainingRegion>,
    options: &BiasStabilityOptions,
) -> f64 {
    let Ok(core_axis) = model.axis(axis) else { return f64::NAN };
    let mut hint = WalkHint::default();
    let times: Vec<f64> = points.iter().map(|p| p.time_s).collect();
    let compensated: Vec<f64> = points
        .iter()
        .map(|p| {
            let bias = core_axis.evaluate(p.temp_c as f32, p.rate_c_per_min as f32, &mut hint);
            bias.map_or(f64::NAN, |e| p.gyro_mean_dph - f64::from(e.value_dph))
        })
        .collect();
    let inside: Option<Vec<bool>> =
        region.map(|r| points.iter().map(|p| r.contains(p.temp_c, p.rate_c_per_min)).collect());
    score_series(&times, &compensated, inside.as_deref(), options).bias_stability_dph
}

/// `e(model)`: the mean of [`feature_score`] over every run of `runs`, the runs in
/// `held_out` scored inside `region` (when given) and the others over every window. NaN
/// when any run has no score (a fold whose held-out run has none is not scored at all).
pub fn mean_run_score(
    model: &Model<'_>,
    axis: usize,
    runs: &[RunFeatures],
    held_out: &[usize],
    region: Option<&TrainingRegion>,
    options: &BiasStabilityOptions,
) -> f64 {
    let scores: Vec<f64> = runs
        .iter()
        .enumerate()
        .map(|(i, run)| {
            let points = run.axes.get(axis).map_or(&[][..], |(p, _)| p.as_slice());
            let held = held_out.contains(&i);
            feature_score(model, axis, points, if held { region } else { None }, options)
        })
        .collect();
    scores.iter().sum::<f64>() / scores.len() as f64
}

/// The per-fold corrections `e_full - e_g`. A fold whose `e_g` could not be computed (its
/// held-out run has fewer feature windows inside the region than its replay had) gets the
/// mean of the others; all NaN when `e_full` or every `e_g` is NaN (no correction).
pub fn fold_corrections(full: f64, folds: &[f64]) -> Vec<f64> {
    let c: Vec<f64> = folds.iter().map(|e| full - e).collect();
    let finite: Vec<f64> = c.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return vec![f64::NAN; folds.len()];
    }
    let mean = finite.iter().sum::<f64>() / finite.len() as f64;
    c.into_iter().map(|v| if v.is_finite() { v } else { mean }).collect()
}

/// The corrected fold scores `s_g + e_full - e_g` ([`fold_corrections`]); unchanged when no
/// correction can be computed or the lengths differ, so the rule still pairs like with like.
pub fn corrected(fold_scores: &[f64], full: f64, folds: &[f64]) -> Vec<f64> {
    let c = fold_corrections(full, folds);
    if folds.len() != fold_scores.len() || c.iter().any(|v| !v.is_finite()) {
        return fold_scores.to_vec();
    }
    fold_scores.iter().zip(c).map(|(s, c)| s + c).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use fogtemp_core::PolyTerm;

    /// A blob with one polynomial axis `c0 + c1 * T` (identity normalisation).
    fn linear_in_t(c0: f32, c1: f32) -> Vec<u8> {
        let term = |temp_power, coefficient_dph| PolyTerm { temp_power, rate_power: 0, coefficient_dph };
        crate::blob::test_blob(crate::blob::test_poly_axis(vec![term(0, c0), term(1, c1)]))
    }

    fn points(n: usize, f: impl Fn(f64) -> (f64, f64)) -> Vec<FeaturePoint> {
        (0..n)
            .map(|i| {
                let time_s = i as f64;
                let (temp_c, gyro_mean_dph) = f(time_s);
                FeaturePoint {
                    time_s,
                    temp_c,
                    rate_c_per_min: 0.0,
                    window_full: true,
                    gyro_mean_dph,
                    gyro_samples: 1,
                    segment: 0,
                }
            })
            .collect()
    }

    #[test]
    fn a_model_that_removes_the_bias_leaves_the_window_pattern() {
        // gyro = 0.5 + 0.01 T + pattern, pattern +-a alternating per 100 s window; the model
        // 0.5 + 0.01 T leaves the pattern, whose window means are +-a: sample std over 10
        // windows = a sqrt(10/9) (closed form).
        let a = 0.003;
        let pattern = |t: f64| if ((t / 100.0) as usize) % 2 == 0 { a } else { -a };
        let pts = points(1000, |t| {
            let temp = -10.0 + 0.02 * t;
            (temp, 0.5 + 0.01 * temp + pattern(t))
        });
        let blob = linear_in_t(0.5, 0.01);
        let model = Model::from_bytes(&blob).expect("valid");
        let s = feature_score(&model, 0, &pts, None, &BiasStabilityOptions::default());
        let expected = a * (10.0f64 / 9.0).sqrt();
        assert!((s - expected).abs() < 1e-6 * expected.max(1e-9) + 1e-7, "{s} vs {expected}");
        // A model with a wrong slope adds the slope's window means: worse.
        let wrong_blob = linear_in_t(0.5, 0.0);
        let wrong = Model::from_bytes(&wrong_blob).expect("valid");
        let worse = feature_score(&wrong, 0, &pts, None, &BiasStabilityOptions::default());
        assert!(worse > 2.0 * s, "{worse} vs {s}");
    }

    #[test]
    fn the_correction_shifts_every_fold_by_the_full_minus_the_fold_error() {
        // Hand-computed: s = [1.0, 2.0], e_full 0.5, e_g = [0.7, 0.6] -> [0.8, 1.9].
        let c = corrected(&[1.0, 2.0], 0.5, &[0.7, 0.6]);
        assert!((c[0] - 0.8).abs() < 1e-12 && (c[1] - 1.9).abs() < 1e-12, "{c:?}");
        // Without a full-data error nothing changes.
        assert_eq!(corrected(&[1.0, 2.0], f64::NAN, &[0.7, 0.6]), vec![1.0, 2.0]);
        // A fold without e_g takes the others' mean correction: (-0.2 - 0.1) / 2 = -0.15.
        let c = corrected(&[1.0, 2.0, 3.0], 0.5, &[0.7, f64::NAN, 0.6]);
        assert!((c[1] - 1.85).abs() < 1e-12, "{c:?}");
    }
}
