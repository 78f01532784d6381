//! Metrics: bias stability (GJB 2426A style) and the overlapping Allan deviation with
//! fitted noise terms (IEEE Std 952). Every report prints the definition it used
//! ([`BiasStabilityOptions::describe`]).

/// How bias stability is computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BiasStabilityOptions {
    /// Averaging time, seconds (100 s default, 10 s option).
    pub tau_s: f64,
    /// Overlapping windows (starting every tenth of `tau_s`: every 10 s for 100 s windows)
    /// instead of non-overlapping.
    pub overlapping: bool,
    /// Remove a least-squares line from the window means before the standard deviation.
    pub detrend: bool,
    /// Seconds at the start of each run left out (warm-up exclusion).
    pub exclude_first_s: f64,
}

impl Default for BiasStabilityOptions {
    fn default() -> Self {
        Self { tau_s: 100.0, overlapping: false, detrend: false, exclude_first_s: 0.0 }
    }
}

impl BiasStabilityOptions {
    /// One-line definition for reports.
    pub fn describe(&self) -> String {
        format!(
            "bias stability = standard deviation (n-1) of {} {} s means{}{}, per run, raw and compensated alike \
             from the first sample the compensator corrects (after its tracker's start-up); overall = RMS over runs",
            if self.overlapping { "overlapping" } else { "non-overlapping" },
            self.tau_s,
            if self.detrend { ", after removing a least-squares line" } else { "" },
            if self.exclude_first_s > 0.0 { format!(", first {} s of each run excluded", self.exclude_first_s) } else { String::new() },
        )
    }
}

/// Window means of a run: non-overlapping `tau_s` windows aligned to the first sample;
/// a window counts only if it holds at least 90 % of the samples of the typical window
/// ([`fullness_threshold`]), so windows cut by gaps or the run's end are left out (and
/// counted).
pub fn window_means(times_s: &[f64], values: &[f64], options: &BiasStabilityOptions) -> (Vec<f64>, usize) {
    let stats = window_stats(times_s, values, options);
    (stats.means, stats.left_out)
}

/// The windows behind a bias stability ([`window_stats`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WindowStats {
    /// The means of the windows used.
    pub means: Vec<f64>,
    /// Windows left out: empty, or cut short by a gap or the run's end.
    pub left_out: usize,
    /// Samples in the windows used.
    pub samples_used: usize,
    /// The median spacing of consecutive used windows' starts, s (NaN with fewer than 2):
    /// the window length, unless windows between are left out (a log in bursts).
    pub used_spacing_s: f64,
}

/// [`window_means`] with the samples the used windows hold.
pub fn window_stats(times_s: &[f64], values: &[f64], options: &BiasStabilityOptions) -> WindowStats {
    let start = times_s.first().copied().unwrap_or(0.0) + options.exclude_first_s;
    // Sum and count per sub-window of tau/step; overlapping windows combine `step` of them.
    let step = if options.overlapping { 10 } else { 1 };
    let sub_s = options.tau_s / step as f64;
    let finite = |i: usize| values.get(i).is_some_and(|v| v.is_finite());
    let subs = sparse_bins(times_s, start, sub_s, finite, |w: &mut (f64, usize), i| {
        w.0 += values[i];
        w.1 += 1;
    });
    let (windows, window_count) = sparse_windows(&subs, step, |w, b| {
        w.0 += b.0;
        w.1 += b.1;
    });
    let threshold = fullness_threshold(windows.iter().map(|w| w.1 .1));
    let mut stats = WindowStats { used_spacing_s: f64::NAN, ..WindowStats::default() };
    let mut used_at = Vec::new();
    for &(j, (sum, count)) in &windows {
        if count >= threshold {
            stats.means.push(sum / count as f64);
            stats.samples_used += count;
            used_at.push(j);
        }
    }
    stats.left_out = window_count - used_at.len();
    // Window j starts j sub-windows (overlapping) or j windows after the first.
    let start_step_s = if options.overlapping { sub_s } else { options.tau_s };
    let mut spacings: Vec<usize> = used_at.windows(2).map(|w| w[1] - w[0]).collect();
    spacings.sort_unstable();
    if let Some(&median) = spacings.get(spacings.len() / 2) {
        stats.used_spacing_s = median as f64 * start_step_s;
    }
    stats
}

/// The bins of `width_s` from `start_s` (bin k holds `start_s + k width_s <= t < start_s +
/// (k + 1) width_s`) that hold a sample `take` accepts, in bin order: each bin's number and
/// what `add` gathered of its samples (given each sample's index, in the order given).
///
/// A NaN time is passed over (the dense code before put it in bin 0).
///
/// Sparse: only bins that hold a sample exist, so a clock that jumps by years costs nothing
/// (review27a 13: one slot per 100 s window of a 1e12 s jump asked for 160 GB and aborted
/// the process).
pub fn sparse_bins<A: Default>(
    times_s: &[f64],
    start_s: f64,
    width_s: f64,
    take: impl Fn(usize) -> bool,
    mut add: impl FnMut(&mut A, usize),
) -> Vec<(usize, A)> {
    let mut bins: Vec<(usize, A)> = Vec::new();
    for (i, &t) in times_s.iter().enumerate() {
        if t.is_nan() || t < start_s || !take(i) {
            continue;
        }
        let k = ((t - start_s) / width_s) as usize;
        let at = match bins.last() {
            Some(&(last, _)) if last == k => bins.len() - 1,
            Some(&(last, _)) if last > k => match bins.binary_search_by_key(&k, |b| b.0) {
                Ok(at) => at,
                Err(at) => {
                    bins.insert(at, (k, A::default()));
                    at
                }
            },
            _ => {
                bins.push((k, A::default()));
                bins.len() - 1
            }
        };
        if let Some(bin) = bins.get_mut(at) {
            add(&mut bin.1, i);
        }
    }
    bins
}

/// The windows of `step` consecutive bins of [`sparse_bins`] (window j: bins j to
/// j + step - 1, each window's last bin within the bins' span) that hold any bin, in order,
/// each `combine`d from its bins in order; and how many windows the span holds, empty ones
/// too.
pub fn sparse_windows<A: Default + Clone>(
    bins: &[(usize, A)],
    step: usize,
    mut combine: impl FnMut(&mut A, &A),
) -> (Vec<(usize, A)>, usize) {
    let step = step.max(1);
    let window_count = bins.last().map_or(0, |&(last, _)| last.saturating_add(1).saturating_sub(step - 1));
    if step == 1 {
        return (bins.to_vec(), window_count);
    }
    let mut windows: std::collections::BTreeMap<usize, A> = std::collections::BTreeMap::new();
    for (k, bin) in bins {
        for j in k.saturating_sub(step - 1)..=*k {
            if j < window_count {
                combine(windows.entry(j).or_default(), bin);
            }
        }
    }
    (windows.into_iter().collect(), window_count)
}

/// The fewest samples an averaging window must hold to count, given every window's count:
/// 90 % of the typical window's, the median of the windows that hold any sample (at least
/// 1), so windows cut by a gap or the run's end are left out. The one rule of the metric's
/// windows, its figures' and the cross-validation's.
///
/// The median, not the fullest (the rule until 2026-11-28, review15 F2): a log whose
/// windows each hold a 60 s gap then counts them alike wherever the gaps fall (they were
/// all left out but the few full windows before the first gap, while bursts of the same
/// duty cycle aligned to the windows were all kept), and one window that holds two bursts
/// of a burst log no longer leaves out all the others. A log without gaps has the same
/// threshold either way (every window but the last is full).
pub fn fullness_threshold(counts: impl Iterator<Item = usize>) -> usize {
    let mut held: Vec<usize> = counts.filter(|&c| c > 0).collect();
    let typical = match held.len() {
        0 => 0,
        n => *held.select_nth_unstable(n / 2).1,
    };
    ((typical as f64 * 0.9).ceil() as usize).max(1)
}

/// Bias stability of one run, deg/h (NaN with fewer than 2 windows).
pub fn bias_stability(times_s: &[f64], values: &[f64], options: &BiasStabilityOptions) -> f64 {
    stability_of_means(window_means(times_s, values, options).0, options)
}

/// Bias stability from a run's window means ([`window_means`]): detrended if asked, then
/// their sample standard deviation (NaN with fewer than 2).
pub fn stability_of_means(mut means: Vec<f64>, options: &BiasStabilityOptions) -> f64 {
    if options.detrend {
        detrend(&mut means);
    }
    sample_std(&means)
}

/// RMS over runs of per-run figures (NaN runs are ignored).
pub fn rms_over_runs(per_run: &[f64]) -> f64 {
    let finite: Vec<f64> = per_run.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return f64::NAN;
    }
    (finite.iter().map(|v| v * v).sum::<f64>() / finite.len() as f64).sqrt()
}

/// Standard deviation with n-1 (NaN for fewer than 2 values).
pub fn sample_std(values: &[f64]) -> f64 {
    if values.len() < 2 {
        return f64::NAN;
    }
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (values.len() - 1) as f64).sqrt()
}

pub(crate) fn detrend(values: &mut [f64]) {
    let n = values.len() as f64;
    if n < 3.0 {
        return;
    }
    let mean_x = (n - 1.0) / 2.0;
    let mean_y = values.iter().sum::<f64>() / n;
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (i, v) in values.iter().enumerate() {
        let dx = i as f64 - mean_x;
        sxx += dx * dx;
        sxy += dx * (v - mean_y);
    }
    let slope = sxy / sxx;
    for (i, v) in values.iter_mut().enumerate() {
        *v -= mean_y + slope * (i as f64 - mean_x);
    }
}

/// One point of an Allan deviation curve.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct AllanPoint {
    /// Averaging time, seconds.
    pub tau_s: f64,
    /// Allan deviation, deg/h.
    pub adev_dph: f64,
    /// Approximate relative error of this point, `1 / sqrt(2 (N/m - 1))`.
    pub relative_error: f64,
}

/// The fewest samples [`allan_deviation`] gives a curve for (fewer: an empty curve).
pub const ALLAN_MIN_SAMPLES: usize = 4;

/// Overlapping Allan deviation (IEEE 952) of a rate series sampled every `dt_s`, at
/// cluster sizes about sqrt(2) apart (1, 2, 3, 5, 8, 12, ...), computed on the f64 angle `theta = cumsum(rate * dt)`
/// with the mean rate removed.
pub fn allan_deviation(rate_dph: &[f64], dt_s: f64) -> Vec<AllanPoint> {
    allan_deviation_in_segments(&[rate_dph], dt_s)
}

/// [`allan_deviation`] of a series with gaps, given as its gap-free `segments`: every
/// cluster lies within one segment, and each cluster size pools the squared differences of
/// every segment long enough for it (a gap is never bridged, so no averaging time exceeds
/// what one segment holds). One segment gives [`allan_deviation`]'s curve. Fewer than
/// [`ALLAN_MIN_SAMPLES`] samples in the longest segment: an empty curve.
pub fn allan_deviation_in_segments(segments: &[&[f64]], dt_s: f64) -> Vec<AllanPoint> {
    let longest = segments.iter().map(|s| s.len()).max().unwrap_or(0);
    if longest < ALLAN_MIN_SAMPLES {
        return Vec::new();
    }
    let thetas: Vec<Vec<f64>> = segments.iter().map(|s| angle(s, dt_s)).collect();
    let mut out = Vec::new();
    let mut m = 1usize;
    while 2 * m < longest {
        let tau = m as f64 * dt_s;
        let (mut sum, mut terms, mut clusters) = (0.0f64, 0usize, 0.0f64);
        for theta in thetas.iter().filter(|t| t.len() > 2 * m + 1) {
            let n = theta.len() - 2 * m;
            sum += (0..n).map(|k| (theta[k + 2 * m] - 2.0 * theta[k + m] + theta[k]).powi(2)).sum::<f64>();
            terms += n;
            clusters += (theta.len() - 1) as f64 / m as f64 - 1.0;
        }
        out.push(AllanPoint {
            tau_s: tau,
            adev_dph: (sum / (2.0 * tau * tau * terms as f64)).sqrt(),
            relative_error: 1.0 / (2.0 * clusters).sqrt(),
        });
        let next = ((m as f64) * 2f64.sqrt()).ceil() as usize;
        m = next.max(m + 1);
    }
    out
}

/// Index ranges of `time_s` (samples `period_s` apart) between gaps: a step of more than
/// 1.5 periods starts a new range.
pub fn gap_free_ranges(time_s: &[f64], period_s: f64) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
    let mut start = 0;
    (1..=time_s.len()).filter_map(move |i| {
        let cut = i == time_s.len() || time_s[i] - time_s[i - 1] > 1.5 * period_s;
        cut.then(|| {
            let range = start..i;
            start = i;
            range
        })
    })
}

/// The angle `theta = cumsum((rate - mean) * dt)` from 0, one longer than `rate_dph`.
fn angle(rate_dph: &[f64], dt_s: f64) -> Vec<f64> {
    let mean = rate_dph.iter().sum::<f64>() / rate_dph.len().max(1) as f64;
    let mut theta = Vec::with_capacity(rate_dph.len() + 1);
    theta.push(0.0f64);
    let mut acc = 0.0;
    for r in rate_dph {
        acc += (r - mean) * dt_s;
        theta.push(acc);
    }
    theta
}

/// Noise terms fitted to an Allan deviation curve (IEEE 952).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct NoiseTerms {
    /// Angle random walk N, deg/sqrt(h).
    pub arw_deg_per_sqrt_h: f64,
    /// Bias instability B, deg/h (the flicker floor is 0.664 B).
    pub bias_instability_dph: f64,
    /// Rate random walk K, deg/h/sqrt(h).
    pub rrw_dph_per_sqrt_h: f64,
}

/// Fits `sigma^2(tau) = (60 N)^2 / tau + (2 ln2 / pi) B^2 + (K^2 / 3600) tau / 3` (tau in s,
/// sigma in deg/h) by non-negative least squares, each point weighted by its relative error.
/// An empty curve (a series too short for any averaging time) gives NaN terms: unknown, not
/// zero noise.
pub fn fit_noise_terms(curve: &[AllanPoint]) -> NoiseTerms {
    if curve.is_empty() {
        return NoiseTerms {
            arw_deg_per_sqrt_h: f64::NAN,
            bias_instability_dph: f64::NAN,
            rrw_dph_per_sqrt_h: f64::NAN,
        };
    }
    let floor = 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI;
    let rows: Vec<([f64; 3], f64, f64)> = curve
        .iter()
        .filter(|p| p.adev_dph.is_finite() && p.adev_dph > 0.0)
        .map(|p| {
            let var = p.adev_dph * p.adev_dph;
            // Relative error of sigma^2 is twice that of sigma.
            let w = 1.0 / (var * 2.0 * p.relative_error.max(1e-3));
            ([3600.0 / p.tau_s, floor, p.tau_s / (3.0 * 3600.0)], var, w)
        })
        .collect();
    let x = nnls3(&rows);
    NoiseTerms {
        arw_deg_per_sqrt_h: x[0].sqrt(),
        bias_instability_dph: x[1].sqrt(),
        rrw_dph_per_sqrt_h: x[2].sqrt(),
    }
}

/// Non-negative least squares for 3 unknowns by trying every active set (8 subsets).
fn nnls3(rows: &[([f64; 3], f64, f64)]) -> [f64; 3] {
    let mut best = ([0.0; 3], f64::INFINITY);
    for mask in 1u8..8 {
        let idx: Vec<usize> = (0..3).filter(|k| mask & (1 << k) != 0).collect();
        let p = idx.len();
        let mut a = nalgebra::DMatrix::zeros(rows.len(), p);
        let mut b = nalgebra::DVector::zeros(rows.len());
        for (r, (h, y, w)) in rows.iter().enumerate() {
            for (c, &k) in idx.iter().enumerate() {
                a[(r, c)] = h[k] * w;
            }
            b[r] = y * w;
        }
        if rows.len() < p {
            continue;
        }
        let Ok(sol) = a.clone().svd(true, true).solve(&b, 1e-14) else { continue };
        if sol.iter().any(|v| *v < 0.0) {
            continue;
        }
        let resid = (&a * &sol - &b).norm_squared();
        if resid < best.1 {
            let mut x = [0.0; 3];
            for (c, &k) in idx.iter().enumerate() {
                x[k] = sol[c];
            }
            best = (x, resid);
        }
    }
    best.0
}
/// RMS over runs of Allan deviation curves, on the cluster sizes all runs share; each
/// point's relative error is the first run's (callers that pool scale it themselves, as the
/// diagnosis does by the square root of the runs). [`rms_allan_pooled_error`] gives the RMS's
/// own.
pub fn rms_allan(curves: &[Vec<AllanPoint>]) -> Vec<AllanPoint> {
    let shortest = curves.iter().map(Vec::len).min().unwrap_or(0);
    (0..shortest)
        .map(|k| {
            let var = curves.iter().map(|c| c[k].adev_dph.powi(2)).sum::<f64>() / curves.len() as f64;
            AllanPoint {
                tau_s: curves[0][k].tau_s,
                adev_dph: var.sqrt(),
                relative_error: curves[0][k].relative_error,
            }
        })
        .collect()
}

/// [`rms_allan`] with each point's relative error that of the RMS: a run's Allan variance
/// has about twice its deviation's relative error, the mean of the runs' variances the root
/// sum of squares of those (independent estimates) over their sum, and the RMS half that
/// (the validation report's figure and table; review21 second report F9).
pub fn rms_allan_pooled_error(curves: &[Vec<AllanPoint>]) -> Vec<AllanPoint> {
    let mut pooled = rms_allan(curves);
    for (k, point) in pooled.iter_mut().enumerate() {
        let (sum, spread_sq) = curves.iter().map(|c| (c[k].adev_dph.powi(2), c[k].relative_error)).fold(
            (0.0, 0.0),
            |(sum, spread), (variance, relative)| {
                (sum + variance, spread + (2.0 * relative * variance).powi(2))
            },
        );
        if sum > 0.0 {
            point.relative_error = spread_sq.sqrt() / sum / 2.0;
        }
    }
    pooled
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Review27a 13: a clock that jumps by 1e12 s mid-log (a multiple of the window, so the
    /// windows after it align as without it) asked for one slot per window of the jump.
    /// Oracle: the same log without the jump gives the same means; the windows of the jump,
    /// all empty, are counted as left out (1e10 of them), and overlapping windows alike.
    #[test]
    fn a_clock_jump_of_years_costs_nothing_and_changes_no_window_mean() {
        let values: Vec<f64> =
            (0..3000).map(|k| f64::from(k % 37) * 0.01 + (f64::from(k) * 0.01).sin()).collect();
        let plain: Vec<f64> = (0..3000).map(f64::from).collect();
        let jumped: Vec<f64> = plain.iter().map(|&t| if t >= 1500.0 { t + 1e12 } else { t }).collect();
        for overlapping in [false, true] {
            let options = BiasStabilityOptions { overlapping, ..BiasStabilityOptions::default() };
            let (a, b) = (window_stats(&plain, &values, &options), window_stats(&jumped, &values, &options));
            assert_eq!(a.left_out, 0, "3000 s fill every window");
            if overlapping {
                // 291 windows stepped by 10 s. Of the 9 on each side of the jump that hold part
                // of it, the one with 90 of 100 samples counts (the 90 % rule), the other 8 are
                // left out; the jump itself holds 1e11 empty starts.
                assert_eq!(a.means.len(), 291);
                assert_eq!(b.means.len(), 141 + 1 + 1 + 141);
                assert_eq!(b.means[..141], a.means[..141]);
                assert_eq!(b.means[143..], a.means[150..]);
                assert_eq!(b.samples_used, 282 * 100 + 2 * 90);
                assert_eq!(b.left_out, 100_000_000_000 + 291 - 284);
            } else {
                assert_eq!(b.means, a.means);
                assert_eq!(b.samples_used, a.samples_used);
                assert_eq!(b.left_out, 10_000_000_000);
            }
        }
    }

    /// The RMS over runs and its relative error by hand: one run keeps its own; four equal
    /// runs halve it (1 / sqrt(4)); runs of unequal length share the shorter's points.
    #[test]
    fn rms_allan_pooled_error_by_hand() {
        let rms_allan = rms_allan_pooled_error;
        let point =
            |tau_s: f64, adev_dph: f64, relative_error: f64| AllanPoint { tau_s, adev_dph, relative_error };
        let one = vec![vec![point(1.0, 0.02, 0.1), point(2.0, 0.01, 0.4)]];
        assert_eq!(rms_allan(&one), one[0]);
        let four = vec![one[0].clone(); 4];
        let rms = rms_allan(&four);
        assert!((rms[1].relative_error - 0.2).abs() < 1e-12, "{rms:?}");
        assert!((rms[1].adev_dph - 0.01).abs() < 1e-15);
        // Variances 1e-4 and 4e-4 with 10 % each: RMS sqrt(2.5e-4), relative error
        // sqrt((2 * 0.1 * 1e-4)^2 + (2 * 0.1 * 4e-4)^2) / 5e-4 / 2.
        let two = vec![vec![point(1.0, 0.01, 0.1)], vec![point(1.0, 0.02, 0.1), point(2.0, 0.02, 0.2)]];
        let rms = rms_allan(&two);
        assert_eq!(rms.len(), 1);
        assert!((rms[0].adev_dph - 2.5e-4f64.sqrt()).abs() < 1e-15);
        let expected = ((2e-5f64).powi(2) + (8e-5f64).powi(2)).sqrt() / 5e-4 / 2.0;
        assert!((rms[0].relative_error - expected).abs() < 1e-12, "{} vs {expected}", rms[0].relative_error);
    }
}
