//! What the validation figures draw, computed by small pure functions so it can be tested
//! against hand-computed numbers: every figure covers the span its metric covers.
//!
//! The span rule: bias stability is computed from the first block the compensator corrected
//! (before it, the tracker is starting up and the output is the raw input, flagged
//! `WARMING_UP`); the figures start there too, raw and compensated alike. Before this rule
//! the Allan deviation figure included the start-up and showed the compensated output 3-5x
//! noisier than raw, which it is not (docs/reports.md).

use crate::calibrate::{ReplaySeries, RunValidation};
use crate::metrics::{
    allan_deviation_in_segments, gap_free_ranges, rms_allan_pooled_error, rms_over_runs, AllanPoint,
    BiasStabilityOptions,
};

/// Block means of one run over the span the metric covers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span<'a> {
    /// Block centre times, seconds since the run start.
    pub time_s: &'a [f64],
    /// Raw gyro, deg/h.
    pub raw_dph: &'a [f64],
    /// Compensated gyro, deg/h.
    pub compensated_dph: &'a [f64],
    /// Smoothed temperature, deg C.
    pub temp_c: &'a [f64],
}

/// The blocks of `series` (of `block_s` seconds) from the first compensated one: the span
/// of the validation metric ([`ReplaySeries::first_compensated_block`]); empty when the
/// compensator never corrected.
pub fn compensated_span(series: &ReplaySeries, block_s: f64) -> Span<'_> {
    let from = series.first_compensated_block(block_s);
    fn tail(v: &[f64], from: usize) -> &[f64] {
        v.get(from..).unwrap_or_default()
    }
    Span {
        time_s: tail(&series.time_s, from),
        raw_dph: tail(&series.raw_dph, from),
        compensated_dph: tail(&series.compensated_dph, from),
        temp_c: tail(&series.temp_c, from),
    }
}

/// One run's window means, each relative to the mean of the run's window means.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RelativeMeans {
    /// Window centre times, seconds since the run start.
    pub time_s: Vec<f64>,
    /// Window mean minus the run's mean of window means, deg/h.
    pub deviation_dph: Vec<f64>,
}

/// Non-overlapping `options.tau_s` windows of one run, exactly the windows the bias
/// stability averages ([`crate::metrics::window_means`] without overlap: aligned to the
/// first sample plus `exclude_first_s`; a window counts only if it holds at least 90 % of
/// the samples of the typical window, so a window cut by the run's end is left out), each mean
/// given relative to the mean of the kept windows. Their sample standard deviation is the
/// run's (non-detrended, non-overlapping) bias stability.
pub fn relative_window_means(
    times_s: &[f64],
    values: &[f64],
    options: &BiasStabilityOptions,
) -> RelativeMeans {
    let Some(&first) = times_s.first() else { return RelativeMeans::default() };
    let start = first + options.exclude_first_s;
    let finite = |i: usize| values.get(i).is_some_and(|v| v.is_finite());
    let sums =
        crate::metrics::sparse_bins(times_s, start, options.tau_s, finite, |w: &mut (f64, usize), i| {
            w.0 += values[i];
            w.1 += 1;
        });
    let threshold = crate::metrics::fullness_threshold(sums.iter().map(|(_, w)| w.1));
    let (time_s, means): (Vec<f64>, Vec<f64>) = sums
        .iter()
        .filter(|(_, w)| w.1 >= threshold)
        .map(|&(k, w)| (start + (k as f64 + 0.5) * options.tau_s, w.0 / w.1 as f64))
        .unzip();
    let mean = means.iter().sum::<f64>() / means.len().max(1) as f64;
    RelativeMeans { time_s, deviation_dph: means.iter().map(|m| m - mean).collect() }
}

/// One run's bars: raw beside compensated bias stability, deg/h.
#[derive(Clone, Debug, PartialEq)]
pub struct RunBar {
    /// Run name.
    pub name: String,
    /// Raw bias stability, deg/h.
    pub raw_dph: f64,
    /// Compensated bias stability, deg/h.
    pub compensated_dph: f64,
}

/// The before/after bars of the validation runs of one axis, in log order, then the
/// overall bar (RMS over those runs, as the report's table).
pub fn run_bars(runs: &[&RunValidation], name: impl Fn(&RunValidation) -> String) -> Vec<RunBar> {
    let mut bars: Vec<RunBar> = runs
        .iter()
        .map(|r| RunBar {
            name: name(r),
            raw_dph: r.raw_bias_stability_dph,
            compensated_dph: r.compensated_bias_stability_dph,
        })
        .collect();
    let rms = |pick: fn(&RunBar) -> f64| rms_over_runs(&bars.iter().map(pick).collect::<Vec<_>>());
    let overall = RunBar {
        name: "RMS over runs".into(),
        raw_dph: rms(|b| b.raw_dph),
        compensated_dph: rms(|b| b.compensated_dph),
    };
    bars.push(overall);
    bars
}

/// Raw and compensated Allan deviation of `block_s` block means, RMS over runs, each run
/// from its first compensated block (the span of the metric) and within its gap-free
/// stretches ([`gap_free_ranges`]): a log of bursts gets no averaging time longer than a
/// burst (bridging its gaps made a 5 s burst every 300 s read as 1 s means at 12-50 s).
pub struct SpanAllan {
    /// The raw gyro's curve, RMS over runs.
    pub raw: Vec<AllanPoint>,
    /// The compensated output's curve, RMS over runs.
    pub compensated: Vec<AllanPoint>,
    /// The longest averaging time of any one run's compensated curve, s (0 without one):
    /// beyond the RMS curve's last point when the runs differ in length, since the RMS keeps
    /// the averaging times every run reaches (review21 second report F9: the report stopped
    /// at the shortest run's without a word).
    pub longest_run_tau_s: f64,
}

/// The [`SpanAllan`] of `series`.
pub fn span_allan(series: &[&ReplaySeries], block_s: f64) -> SpanAllan {
    let raw_runs = run_allan_curves(series, block_s, |s| s.raw_dph);
    let compensated_runs = run_allan_curves(series, block_s, |s| s.compensated_dph);
    let longest_run_tau_s =
        compensated_runs.iter().filter_map(|c| c.last().map(|p| p.tau_s)).fold(0.0, f64::max);
    SpanAllan {
        raw: rms_allan_pooled_error(&raw_runs),
        compensated: rms_allan_pooled_error(&compensated_runs),
        longest_run_tau_s,
    }
}

/// Each run's Allan deviation of the series `pick` chooses, over the metric's span and within
/// its gap-free stretches; runs without a point left out.
fn run_allan_curves(
    series: &[&ReplaySeries],
    block_s: f64,
    pick: for<'a> fn(&Span<'a>) -> &'a [f64],
) -> Vec<Vec<AllanPoint>> {
    series
        .iter()
        .map(|s| {
            let span = compensated_span(s, block_s);
            let values = pick(&span);
            let segments: Vec<&[f64]> =
                gap_free_ranges(span.time_s, block_s).filter_map(|r| values.get(r)).collect();
            allan_deviation_in_segments(&segments, block_s)
        })
        .filter(|c| !c.is_empty())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::{bias_stability, window_means};

    fn series(n: usize, from_s: f64, value: impl Fn(f64) -> f64) -> ReplaySeries {
        let time_s: Vec<f64> = (0..n).map(|k| k as f64 + 0.5).collect();
        ReplaySeries {
            raw_dph: time_s.iter().map(|&t| value(t)).collect(),
            compensated_dph: time_s.iter().map(|&t| value(t) * 0.5).collect(),
            temp_c: vec![20.0; n],
            time_s,
            compensating_from_s: from_s,
            ..ReplaySeries::default()
        }
    }

    #[test]
    fn span_starts_at_the_first_compensated_block() {
        // Compensating from 100.2 s: blocks [100, 101) is partly start-up, the first block
        // at or after 100.2 s starts at 101 s (index 101, centre 101.5 s).
        let s = series(300, 100.2, |t| t);
        let span = compensated_span(&s, 1.0);
        assert_eq!(span.time_s.len(), 199);
        assert_eq!(span.time_s[0], 101.5);
        assert_eq!(span.raw_dph[0], 101.5);
        assert_eq!(span.compensated_dph[0], 50.75);
        let never = ReplaySeries { compensating_from_s: f64::NAN, ..series(10, 0.0, |t| t) };
        assert!(compensated_span(&never, 1.0).time_s.is_empty());
    }

    #[test]
    fn relative_means_by_hand() {
        // 1 s blocks at 0.5..349.5 with value = window index (0, 1, 2, 3 for windows of
        // 100 s; the last window holds 50 blocks and is left out): means 0, 1, 2, mean 1.
        let times: Vec<f64> = (0..350).map(|k| k as f64 + 0.5).collect();
        let values: Vec<f64> = times.iter().map(|t| (t / 100.0).floor()).collect();
        let m = relative_window_means(&times, &values, &BiasStabilityOptions::default());
        assert_eq!(m.time_s, [50.5, 150.5, 250.5]);
        assert_eq!(m.deviation_dph, [-1.0, 0.0, 1.0]);
    }

    #[test]
    fn a_short_last_window_does_not_spike() {
        // A drift-free run whose last window holds 10 blocks of a large outlier (a cut-short
        // block mean is noisy): the window is left out like in the metric.
        let times: Vec<f64> = (0..310).map(|k| k as f64 + 0.5).collect();
        let values: Vec<f64> = times.iter().map(|&t| if t > 300.0 { 50.0 } else { 3.0 }).collect();
        let m = relative_window_means(&times, &values, &BiasStabilityOptions::default());
        assert_eq!(m.deviation_dph, [0.0, 0.0, 0.0]);
    }

    #[test]
    fn relative_means_are_the_metrics_windows_and_their_std_is_the_bias_stability() {
        // A drifting, noisy-looking deterministic series with a gap and an exclusion.
        let times: Vec<f64> =
            (0..2000).map(|k| k as f64 + 0.5).filter(|t| !(700.0..760.0).contains(t)).collect();
        let values: Vec<f64> =
            times.iter().map(|t| 0.01 * (t / 300.0).sin() + 0.003 * (t * 1.7).cos()).collect();
        let options = BiasStabilityOptions { exclude_first_s: 120.0, ..BiasStabilityOptions::default() };
        let m = relative_window_means(&times, &values, &options);
        let (means, dropped) = window_means(&times, &values, &options);
        // Windows from 120.5 s: the 60 s gap cuts [620.5, 720.5) and [720.5, 820.5), the run's
        // end cuts [1920.5, 2020.5) to 79 blocks.
        assert_eq!(dropped, 3);
        assert_eq!(m.deviation_dph.len(), means.len());
        let mean = means.iter().sum::<f64>() / means.len() as f64;
        for (d, w) in m.deviation_dph.iter().zip(&means) {
            assert!((d - (w - mean)).abs() < 1e-15);
        }
        let std = crate::metrics::sample_std(&m.deviation_dph);
        assert!((std - bias_stability(&times, &values, &options)).abs() < 1e-15);
    }

    /// Replays a 10 Hz log of `blocks` whole seconds through a constant model, ending with
    /// `extra` samples of the next second (each 100 deg/h off, as a noisy short block).
    fn replayed(blocks: u32, extra: u32) -> ReplaySeries {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..(blocks * 10 + extra) {
            let gyro = if k >= blocks * 10 { 100.0 } else { 1.0 };
            csv.push_str(&format!("{:.1},20.0,{gyro}\n", f64::from(k) * 0.1));
        }
        let config = crate::calibrate::CalibrationConfig {
            method: crate::calibrate::Method::Poly,
            ..crate::calibrate::CalibrationConfig::default()
        };
        let run = crate::calibrate::extract_run_from(
            replayed_log(300).as_bytes(),
            std::path::Path::new("cal.csv"),
            &config,
        )
        .expect("features");
        let fitted = crate::calibrate::fit_model(&[run], &config, [0; 32]).expect("fit");
        let model = fogtemp_core::Model::from_bytes(&fitted.blob).expect("model");
        let replay = crate::calibrate::replay_models_from(
            csv.as_bytes(),
            std::path::Path::new("val.csv"),
            &[&model],
            &config.ingest,
            1.0,
        )
        .expect("replay");
        replay.models[0][0].clone()
    }

    fn replayed_log(seconds: u32) -> String {
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..seconds * 10 {
            let t = f64::from(k) * 0.1;
            csv.push_str(&format!("{t:.1},{:.3},{}\n", 20.0 + t / 60.0, 1.0 + 0.01 * t / 60.0));
        }
        csv
    }

    #[test]
    fn a_last_block_cut_short_by_the_log_end_is_left_out() {
        // 200 whole seconds, then 1 sample at t = 200.0 s (a run logged up to its duration
        // inclusive): the 1-sample block is not a 1 s mean and is dropped.
        let short = replayed(200, 1);
        assert_eq!(short.time_s.len(), 200);
        assert_eq!(short.time_s.last(), Some(&199.5));
        assert!(short.raw_dph.iter().all(|&v| v == 1.0));
        // 9 of 10 samples (90 % of the fullest block) still count as a block.
        let nine = replayed(200, 9);
        assert_eq!(nine.time_s.last(), Some(&200.5));
        assert_eq!(nine.raw_dph.last(), Some(&100.0));
    }

    fn validation(raw: f64, comp: f64) -> RunValidation {
        RunValidation {
            path: format!("run{raw}.csv").into(),
            axis: 0,
            raw_bias_stability_dph: raw,
            compensated_bias_stability_dph: comp,
            series: ReplaySeries::default(),
            ingest: crate::ingest::IngestReport::default(),
            raw_mean_dph: f64::NAN,
            compensated_mean_dph: f64::NAN,
            input_rate_dph: None,
            windows: crate::calibrate::MetricWindows::default(),
        }
    }

    #[test]
    fn bars_are_the_runs_then_their_rms() {
        let runs = [validation(3.0, 1.0), validation(4.0, 7.0)];
        let refs: Vec<&RunValidation> = runs.iter().collect();
        let bars = run_bars(&refs, |r| r.path.display().to_string());
        assert_eq!(bars.len(), 3);
        assert_eq!((bars[0].name.as_str(), bars[0].raw_dph, bars[0].compensated_dph), ("run3.csv", 3.0, 1.0));
        assert_eq!((bars[1].raw_dph, bars[1].compensated_dph), (4.0, 7.0));
        // RMS of (3, 4) = sqrt(12.5), of (1, 7) = 5.
        assert!((bars[2].raw_dph - 12.5f64.sqrt()).abs() < 1e-15);
        assert!((bars[2].compensated_dph - 5.0).abs() < 1e-15);
    }

    #[test]
    fn allan_leaves_out_the_start_up() {
        // Raw: alternating +-1 (white-like, adev at 1 s = sqrt(mean of squared differences
        // / 2) = sqrt(2) about the closed form below); compensated: the raw values halved after a start-up
        // ramp. Over the full series the ramp dominates the compensated curve at long tau;
        // from the first compensated block it is exactly half the raw curve.
        let mut s = series(1024 + 200, 200.0, |t| if (t as i64) % 2 == 0 { 1.0 } else { -1.0 });
        for (k, c) in s.compensated_dph.iter_mut().enumerate().take(200) {
            *c = k as f64 * 0.05;
        }
        let SpanAllan { raw, compensated: comp, .. } = span_allan(&[&s], 1.0);
        assert!(!raw.is_empty());
        for (r, c) in raw.iter().zip(&comp) {
            assert_eq!(r.tau_s, c.tau_s);
            assert!((c.adev_dph - 0.5 * r.adev_dph).abs() <= 1e-12 * r.adev_dph, "{r:?} {c:?}");
        }
        // At tau = 1 s the alternating series has adev sqrt(<(y_{k+1}-y_k)^2>/2) = sqrt(2).
        assert!((raw[0].adev_dph - 2f64.sqrt()).abs() < 1e-9, "{:?}", raw[0]);
        let full = crate::metrics::allan_deviation(&s.compensated_dph, 1.0);
        assert!(full.last().unwrap().adev_dph > 10.0 * comp.last().unwrap().adev_dph);
    }

    /// A log of 5 s bursts every 300 s, each burst at its own level (a slow drift sampled in
    /// bursts): within a burst the series is the alternating +-1 of the test above, so the
    /// curve stops below one burst (tau 1 and 2 s), equals one burst's own curve (closed
    /// form: the bursts are identical apart from their level, which the second difference
    /// removes), and shows nothing of the levels (bridging the gaps made them noise at
    /// 3-50 s).
    #[test]
    fn allan_does_not_bridge_gaps() {
        let burst = |b: usize| {
            (0..5).map(move |k| {
                (b as f64 * 300.0 + k as f64 + 0.5, b as f64 * 7.0 + if k % 2 == 0 { 1.0 } else { -1.0 })
            })
        };
        let samples: Vec<(f64, f64)> = (0..25).flat_map(burst).collect();
        let s = ReplaySeries {
            time_s: samples.iter().map(|p| p.0).collect(),
            raw_dph: samples.iter().map(|p| p.1).collect(),
            compensated_dph: samples.iter().map(|p| p.1).collect(),
            temp_c: vec![20.0; samples.len()],
            compensating_from_s: 0.0,
            ..ReplaySeries::default()
        };
        let ranges: Vec<_> = gap_free_ranges(&s.time_s, 1.0).collect();
        assert_eq!(ranges.len(), 25);
        assert!(ranges.iter().all(|r| r.len() == 5));
        let raw = span_allan(&[&s], 1.0).raw;
        let one_burst = crate::metrics::allan_deviation(&s.raw_dph[..5], 1.0);
        assert_eq!(raw.iter().map(|p| p.tau_s).collect::<Vec<_>>(), vec![1.0, 2.0]);
        for (a, b) in raw.iter().zip(&one_burst) {
            assert!((a.adev_dph - b.adev_dph).abs() <= 1e-12 * b.adev_dph, "{a:?} {b:?}");
            // 25 bursts: the relative error is that of 25 x the clusters of one.
            let one = 1.0 / (2.0 * (5.0 / a.tau_s - 1.0)).sqrt();
            assert!((a.relative_error - one / 5.0).abs() < 1e-12, "{a:?}");
        }
    }
}
