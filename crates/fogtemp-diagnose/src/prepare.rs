//! Pairing, validation and the common time grid: 1 s means of both members of a pair,
//! smoothed temperature and its derivatives, and short means of the residual.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::{DiagnoseOptions, RunSeries};
use crate::error::{DiagnoseError, SeriesProblem, Side};

/// One short mean of a run (a "block").
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    /// Block number from the run's first second (gaps leave numbers out).
    pub index: usize,
    /// Block centre, seconds since power-on.
    pub since_on_s: f64,
    /// First second of the block on the run's 1 s grid.
    pub first_sec: usize,
    /// One past the last second.
    pub end_sec: usize,
    /// Smoothed recorded temperature, deg C.
    pub temp_c: f64,
    /// Recorded temperature rate, deg C/min.
    pub rate_c_per_min: f64,
    /// Recorded temperature acceleration, deg C/min^2.
    pub accel_c_per_min2: f64,
    /// Smoothed simulated temperature, deg C.
    pub temp_sim_c: f64,
    /// Simulated temperature rate, deg C/min.
    pub rate_sim_c_per_min: f64,
    /// Mean residual recorded - simulated gyro, deg/h.
    pub resid_dph: f64,
    /// Mean simulated gyro, deg/h.
    pub gyro_sim_dph: f64,
}

/// A run on the 1 s grid (second k covers `[t0 + k, t0 + k + 1)`, t0 = first recorded sample).
#[derive(Clone, Debug, PartialEq)]
pub struct SecondGrid {
    /// Second centre, seconds since power-on.
    pub since_on_s: Vec<f64>,
    /// Smoothed recorded temperature, deg C (NaN where unknown).
    pub temp_c: Vec<f64>,
    /// Recorded rate, deg C/min (NaN where unknown).
    pub rate_c_per_min: Vec<f64>,
    /// Smoothed simulated temperature, deg C.
    pub temp_sim_c: Vec<f64>,
    /// Simulated rate, deg C/min.
    pub rate_sim_c_per_min: Vec<f64>,
    /// Residual recorded - simulated gyro, deg/h (NaN where either is missing).
    pub resid_dph: Vec<f64>,
    /// Recorded gyro, deg/h.
    pub gyro_rec_dph: Vec<f64>,
    /// Block of each second (`usize::MAX` when the second is in no valid block).
    pub block_of: Vec<usize>,
}

/// A paired run ready for modelling.
#[derive(Clone, Debug, PartialEq)]
pub struct RunData {
    /// Run name.
    pub name: String,
    /// Position label.
    pub group: Option<String>,
    /// Input rate, deg/h.
    pub input_rate_dph: Option<f64>,
    /// The 1 s grid.
    pub sec: SecondGrid,
    /// Valid short means in time order.
    pub blocks: Vec<Block>,
    /// Seconds whose residual was an outlier, read as missing ([`fogtemp_cal::outliers::screen`]).
    pub outliers: Vec<OutlierSecond>,
}

/// Robust standard deviations beyond which a second's residual is an outlier
/// ([`fogtemp_cal::outliers`]: a Hampel filter over a minute either side).
pub const OUTLIER_ROBUST_SDS: f64 = fogtemp_cal::outliers::ROBUST_SDS;

/// One second of a run read as missing because its residual (recorded - simulated 1 s means)
/// lay beyond [`OUTLIER_ROBUST_SDS`] robust standard deviations of its neighbourhood's median.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OutlierSecond {
    /// Start of the second on the log's clock, s (the rows from there to 1 s later).
    pub log_time_s: f64,
    /// Its residual, deg/h.
    pub residual_dph: f64,
    /// Its deviation from the neighbourhood's median, deg/h.
    pub deviation_dph: f64,
    /// The run's robust standard deviation of 1 s residuals (1.4826 x the median absolute
    /// deviation from the neighbourhood medians), deg/h.
    pub robust_sd_dph: f64,
}

/// The note for the seconds of one run pair read as missing as outliers (at most five listed).
pub fn outliers_note(log: &str, seconds: &[OutlierSecond]) -> String {
    let listed: Vec<String> = seconds
        .iter()
        .take(5)
        .map(|o| {
            let (deviation, sds) = fogtemp_cal::outliers::deviation_text(o.deviation_dph, o.robust_sd_dph);
            format!("at {} s ({deviation} deg/h, {sds} robust SD)", o.log_time_s)
        })
        .collect();
    let more = seconds.len().saturating_sub(5);
    format!(
        "{log}: {} {} of the residual (recorded - simulated) beyond {} robust standard deviations of the minute around {} read as missing, on the log's clock {}{}: a spike? check those rows of the recorded and simulated logs",
        seconds.len(),
        if seconds.len() == 1 { "second" } else { "seconds" },
        OUTLIER_ROBUST_SDS,
        if seconds.len() == 1 { "it" } else { "them" },
        listed.join(", "),
        if more > 0 { format!(" and {more} more") } else { String::new() }
    )
}

/// The simulation's own prediction as a function of its temperature signals:
/// `g(T) + S dT/dt`, a cubic in T and a rate term fitted to the simulated short means with
/// one constant per position (the input rate of a position is a constant, not a function
/// of T; without it a +-Earth-rate step between positions bends the cubic). (One constant
/// per run instead named a lag in 2 of 20 seeds of the one-orientation design, where a
/// missing slope in T is all there is: a per-run constant lets within-run warm-up curves
/// alone decide the cubic.)
#[derive(Clone, Debug, PartialEq)]
pub struct StaticRelation {
    /// Centre of the normalised temperature, deg C.
    pub centre_c: f64,
    /// Half-range of the normalised temperature, deg C.
    pub half_range_c: f64,
    /// Coefficients of u, u^2, u^3 (u normalised temperature), deg/h.
    pub coefficients_dph: [f64; 3],
    /// Coefficient of the simulated temperature rate, deg/h per deg C/min.
    pub rate_dph_per_c_per_min: f64,
}

impl StaticRelation {
    /// `g(T)` without its constant, deg/h.
    pub fn eval(&self, temp_c: f64) -> f64 {
        let u = (temp_c - self.centre_c) / self.half_range_c;
        let [a, b, c] = self.coefficients_dph;
        u * (a + u * (b + u * c))
    }

    /// `dg/dT`, deg/h per deg C.
    pub fn slope(&self, temp_c: f64) -> f64 {
        let u = (temp_c - self.centre_c) / self.half_range_c;
        let [a, b, c] = self.coefficients_dph;
        (a + u * (2.0 * b + 3.0 * u * c)) / self.half_range_c
    }
}

/// All runs, ready for modelling.
#[derive(Clone, Debug, PartialEq)]
pub struct Prepared {
    /// Runs in the recorded order.
    pub runs: Vec<RunData>,
    /// The simulation's static relation, if the simulated temperature varies enough.
    pub static_relation: Option<StaticRelation>,
    /// Mean recorded temperature over all short means, deg C (reference of T-polynomials).
    pub temp_ref_c: f64,
    /// Smallest and largest recorded short-mean temperature, deg C.
    pub temp_range_c: (f64, f64),
    /// Seconds per short mean.
    pub block_s: usize,
    /// Newey-West bandwidth in short means.
    pub hac_lag_blocks: usize,
    /// Noise of one short mean: overlapping Allan deviation at tau = one short mean of the
    /// 1 s raw residual, RMS over runs, deg/h (short-term noise; slow structure hardly
    /// enters at this tau).
    pub noise_sigma_dph: f64,
    /// `Some(k)` when no gap-free stretch is long enough for the Allan deviation at one short
    /// mean and `noise_sigma_dph` is extrapolated from `tau = k` s (see [`short_mean_noise`]).
    pub noise_from_tau_s: Option<usize>,
}

impl Prepared {
    /// Total number of short means.
    pub fn n_blocks(&self) -> usize {
        self.runs.iter().map(|r| r.blocks.len()).sum()
    }
}

fn bad_series(side: Side, run: &RunSeries, problem: SeriesProblem) -> DiagnoseError {
    DiagnoseError::BadSeries { side, run: run.name.clone(), problem }
}

/// Checks one series: equal lengths, finite values, strictly increasing time, >= 1 Hz.
///
/// # Errors
/// [`DiagnoseError::BadSeries`] naming the run, the side and the sample.
pub fn check_series(run: &RunSeries, side: Side) -> Result<(), DiagnoseError> {
    let n = run.time_s.len();
    if n == 0 {
        return Err(bad_series(side, run, SeriesProblem::Empty));
    }
    if run.temp_c.len() != n || run.gyro_dph.len() != n {
        let lengths = [n, run.temp_c.len(), run.gyro_dph.len()];
        return Err(bad_series(side, run, SeriesProblem::UnequalLengths { lengths }));
    }
    let columns = [("time_s", &run.time_s), ("temp_c", &run.temp_c), ("gyro_dph", &run.gyro_dph)];
    for (what, values) in columns {
        if let Some(sample) = values.iter().position(|v| !v.is_finite()) {
            return Err(bad_series(side, run, SeriesProblem::NonFinite { what, sample }));
        }
    }
    if let Some(i) = run.time_s.windows(2).position(|w| w[1] <= w[0]) {
        let problem = SeriesProblem::TimeNotIncreasing {
            sample: i + 1,
            before_s: run.time_s[i],
            at_s: run.time_s[i + 1],
        };
        return Err(bad_series(side, run, problem));
    }
    if n > 1 {
        let mut dt: Vec<f64> = run.time_s.windows(2).map(|w| w[1] - w[0]).collect();
        dt.sort_by(f64::total_cmp);
        let median = dt[dt.len() / 2];
        if median > 1.05 {
            return Err(bad_series(side, run, SeriesProblem::TooSlow { median_interval_s: median }));
        }
    }
    if let Some(value) = run.meta.input_rate_dph.filter(|v| !v.is_finite()) {
        return Err(bad_series(side, run, SeriesProblem::NonFiniteMeta { what: "input_rate_dph", value }));
    }
    if let Some(value) = run.meta.power_on_at_s.filter(|v| !v.is_finite()) {
        return Err(bad_series(side, run, SeriesProblem::NonFiniteMeta { what: "power_on_at_s", value }));
    }
    Ok(())
}

/// Pairs runs by name.
///
/// # Errors
/// [`DiagnoseError::NoRuns`], [`DiagnoseError::DuplicateRun`] or [`DiagnoseError::Unpaired`].
pub fn pair<'a>(
    simulated: &'a [RunSeries],
    recorded: &'a [RunSeries],
) -> Result<Vec<(&'a RunSeries, &'a RunSeries)>, DiagnoseError> {
    if simulated.is_empty() || recorded.is_empty() {
        return Err(DiagnoseError::NoRuns { simulated: simulated.len(), recorded: recorded.len() });
    }
    for (side, runs) in [(Side::Simulated, simulated), (Side::Recorded, recorded)] {
        let mut names: Vec<&str> = runs.iter().map(|r| r.name.as_str()).collect();
        names.sort_unstable();
        if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
            return Err(DiagnoseError::DuplicateRun { side, name: w[0].to_string() });
        }
    }
    let unpaired = |a: &[RunSeries], b: &[RunSeries]| -> Vec<String> {
        a.iter().filter(|r| !b.iter().any(|s| s.name == r.name)).map(|r| r.name.clone()).collect()
    };
    let recorded_only = unpaired(recorded, simulated);
    let simulated_only = unpaired(simulated, recorded);
    if !recorded_only.is_empty() || !simulated_only.is_empty() {
        return Err(DiagnoseError::Unpaired { recorded_only, simulated_only });
    }
    Ok(recorded
        .iter()
        .filter_map(|rec| simulated.iter().find(|s| s.name == rec.name).map(|sim| (sim, rec)))
        .collect())
}

/// Means of `values` per 1 s bin of `time_s - t0` over `n_sec` bins (NaN where empty).
fn second_means(time_s: &[f64], values: &[f64], t0: f64, n_sec: usize) -> Vec<f64> {
    let mut sum = vec![0.0; n_sec];
    let mut count = vec![0u32; n_sec];
    for (&t, &v) in time_s.iter().zip(values) {
        let k = (t - t0).floor();
        if k >= 0.0 && (k as usize) < n_sec {
            sum[k as usize] += v;
            count[k as usize] += 1;
        }
    }
    sum.iter().zip(&count).map(|(s, &c)| if c > 0 { s / f64::from(c) } else { f64::NAN }).collect()
}

/// Centred least-squares line through the finite values within `half` samples either side:
/// `(level, slope per sample)` at every index, NaN where fewer than `min_count` values.
pub fn centred_line(values: &[f64], half: usize, min_count: usize) -> (Vec<f64>, Vec<f64>) {
    let n = values.len();
    let offset = values.iter().copied().find(|v| v.is_finite()).unwrap_or(0.0);
    // Prefix sums of count, x, x^2, y, x*y with y relative to the first value.
    let mut pre = vec![[0.0f64; 5]; n + 1];
    for (i, &v) in values.iter().enumerate() {
        let mut row = pre[i];
        if v.is_finite() {
            let (x, y) = (i as f64, v - offset);
            row[0] += 1.0;
            row[1] += x;
            row[2] += x * x;
            row[3] += y;
            row[4] += x * y;
        }
        pre[i + 1] = row;
    }
    let mut level = vec![f64::NAN; n];
    let mut slope = vec![f64::NAN; n];
    for i in 0..n {
        let (lo, hi) = (i.saturating_sub(half), (i + half + 1).min(n));
        let s: Vec<f64> = (0..5).map(|k| pre[hi][k] - pre[lo][k]).collect();
        let c = s[0];
        if c < min_count.max(2) as f64 {
            continue;
        }
        let sxx = s[2] - s[1] * s[1] / c;
        if sxx <= 0.0 {
            continue;
        }
        let b = (s[4] - s[1] * s[3] / c) / sxx;
        let (mx, my) = (s[1] / c, s[3] / c);
        slope[i] = b;
        level[i] = offset + my + b * (i as f64 - mx);
    }
    (level, slope)
}

/// Finite seconds a window of `len` seconds needs: the fraction `coverage`, and at least 3
/// (a line through fewer is not a rate).
fn coverage_count(len: usize, coverage: f64) -> usize {
    ((len as f64 * coverage).ceil() as usize).max(3)
}

/// Smoothed temperature and rate (deg C/min) from 1 s temperature means.
fn smooth_temperature(temp_1s: &[f64], options: &DiagnoseOptions) -> (Vec<f64>, Vec<f64>) {
    let half = (options.rate_window_s / 2.0).round().max(1.0) as usize;
    let (level, slope) = centred_line(temp_1s, half, coverage_count(2 * half + 1, options.window_coverage));
    (level, slope.iter().map(|s| s * 60.0).collect())
}

fn prepare_run(
    sim: &RunSeries,
    rec: &RunSeries,
    options: &DiagnoseOptions,
) -> Result<RunData, DiagnoseError> {
    let t0 = rec.time_s[0];
    let t_end = rec.time_s[rec.time_s.len() - 1];
    let n_sec = (t_end - t0).floor() as usize + 1;
    let power_on = rec.meta.power_on_at_s.or(sim.meta.power_on_at_s).unwrap_or(t0);
    let rec_temp = second_means(&rec.time_s, &rec.temp_c, t0, n_sec);
    let rec_gyro = second_means(&rec.time_s, &rec.gyro_dph, t0, n_sec);
    let sim_temp = second_means(&sim.time_s, &sim.temp_c, t0, n_sec);
    let sim_gyro = second_means(&sim.time_s, &sim.gyro_dph, t0, n_sec);
    let (temp_c, rate_c_per_min) = smooth_temperature(&rec_temp, options);
    let (temp_sim_c, rate_sim_c_per_min) = smooth_temperature(&sim_temp, options);
    let accel_half = (options.accel_window_s / 2.0).round().max(1.0) as usize;
    let (_, accel) = centred_line(
        &rate_c_per_min,
        accel_half,
        coverage_count(2 * accel_half + 1, options.window_coverage),
    );
    let accel_c_per_min2: Vec<f64> = accel.iter().map(|a| a * 60.0).collect();
    let mut resid_dph: Vec<f64> = rec_gyro.iter().zip(&sim_gyro).map(|(r, s)| r - s).collect();
    let mut rec_gyro = rec_gyro;
    // A spike in a log (one corrupted sample of 1000 deg/h among 122,400) would otherwise set
    // the noise level and the fits: read as missing and reported (review11 finding 1).
    let (found, robust_sd_dph) = fogtemp_cal::outliers::screen(&resid_dph);
    let outliers = found
        .into_iter()
        .map(|(k, deviation_dph)| {
            let second = OutlierSecond {
                log_time_s: t0 + k as f64,
                residual_dph: resid_dph[k],
                deviation_dph,
                robust_sd_dph,
            };
            resid_dph[k] = f64::NAN;
            rec_gyro[k] = f64::NAN;
            second
        })
        .collect();
    let since_on_s: Vec<f64> = (0..n_sec).map(|k| t0 + k as f64 + 0.5 - power_on).collect();
    let block_s = options.mean_window_s.round().max(1.0) as usize;
    let needed = (((block_s as f64) * options.block_coverage).ceil() as usize).max(1);
    let mut blocks = Vec::new();
    let mut block_of = vec![usize::MAX; n_sec];
    for index in 0..n_sec.div_ceil(block_s) {
        let (first, end) = (index * block_s, ((index + 1) * block_s).min(n_sec));
        let ok: Vec<usize> = (first..end)
            .filter(|&k| {
                [resid_dph[k], temp_c[k], rate_c_per_min[k], accel_c_per_min2[k], temp_sim_c[k], sim_gyro[k]]
                    .iter()
                    .all(|v| v.is_finite())
            })
            .collect();
        if ok.len() < needed {
            continue;
        }
        let mean = |v: &[f64]| ok.iter().map(|&k| v[k]).sum::<f64>() / ok.len() as f64;
        for &k in &ok {
            block_of[k] = blocks.len();
        }
        let rate_sim = mean(&rate_sim_c_per_min);
        blocks.push(Block {
            index,
            since_on_s: mean(&since_on_s),
            first_sec: first,
            end_sec: end,
            temp_c: mean(&temp_c),
            rate_c_per_min: mean(&rate_c_per_min),
            accel_c_per_min2: mean(&accel_c_per_min2),
            temp_sim_c: mean(&temp_sim_c),
            rate_sim_c_per_min: if rate_sim.is_finite() { rate_sim } else { 0.0 },
            resid_dph: mean(&resid_dph),
            gyro_sim_dph: mean(&sim_gyro),
        });
    }
    if blocks.len() < 3 {
        let problem = SeriesProblem::TooShort { means: blocks.len(), mean_window_s: block_s };
        return Err(bad_series(Side::Recorded, rec, problem));
    }
    let sec = SecondGrid {
        since_on_s,
        temp_c,
        rate_c_per_min,
        temp_sim_c,
        rate_sim_c_per_min,
        resid_dph,
        gyro_rec_dph: rec_gyro,
        block_of,
    };
    let meta =
        if rec.meta.group.is_some() || rec.meta.input_rate_dph.is_some() { &rec.meta } else { &sim.meta };
    Ok(RunData {
        name: rec.name.clone(),
        group: meta.group.clone(),
        input_rate_dph: meta.input_rate_dph,
        sec,
        blocks,
        outliers,
    })
}

/// Fits the simulation's static relation `g(T)` (see [`StaticRelation`]).
fn fit_static_relation(runs: &[RunData]) -> Option<StaticRelation> {
    let rows: Vec<(usize, &Block)> =
        runs.iter().enumerate().flat_map(|(r, run)| run.blocks.iter().map(move |b| (r, b))).collect();
    let (lo, hi) = rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (_, r)| {
        (a.min(r.temp_sim_c), b.max(r.temp_sim_c))
    });
    if hi - lo < 1.0 || hi.is_nan() || lo.is_nan() || rows.len() < 10 {
        return None;
    }
    let (centre_c, half_range_c) = ((hi + lo) / 2.0, (hi - lo) / 2.0);
    // One constant per position: runs without a label share one.
    let mut positions: Vec<Option<&str>> = runs.iter().map(|r| r.group.as_deref()).collect();
    positions.sort_unstable();
    positions.dedup();
    let position_of: Vec<usize> =
        runs.iter().map(|r| positions.iter().position(|p| *p == r.group.as_deref()).unwrap_or(0)).collect();
    let n_runs = positions.len();
    let mut x = DMatrix::zeros(rows.len(), n_runs + 4);
    let mut y = DVector::zeros(rows.len());
    for (i, (run, r)) in rows.iter().enumerate() {
        let u = (r.temp_sim_c - centre_c) / half_range_c;
        x[(i, position_of[*run])] = 1.0;
        x[(i, n_runs)] = u;
        x[(i, n_runs + 1)] = u * u;
        x[(i, n_runs + 2)] = u * u * u;
        x[(i, n_runs + 3)] = r.rate_sim_c_per_min;
        y[i] = r.gyro_sim_dph;
    }
    let beta = super::linalg::least_squares(&x, &y)?;
    let coefficients_dph = [beta[n_runs], beta[n_runs + 1], beta[n_runs + 2]];
    let rate_dph_per_c_per_min = beta[n_runs + 3];
    (coefficients_dph.iter().all(|c| c.is_finite()) && rate_dph_per_c_per_min.is_finite())
        .then_some(StaticRelation { centre_c, half_range_c, coefficients_dph, rate_dph_per_c_per_min })
}

/// Pairs, validates and grids the runs.
///
/// # Errors
/// [`DiagnoseError`] for unusable inputs (see [`super::diagnose`]).
pub fn prepare(
    simulated: &[RunSeries],
    recorded: &[RunSeries],
    options: &DiagnoseOptions,
) -> Result<Prepared, DiagnoseError> {
    for r in simulated {
        check_series(r, Side::Simulated)?;
    }
    for r in recorded {
        check_series(r, Side::Recorded)?;
    }
    let pairs = pair(simulated, recorded)?;
    if pairs.is_empty() {
        return Err(DiagnoseError::NoRuns { simulated: simulated.len(), recorded: recorded.len() });
    }
    let runs: Vec<RunData> =
        pairs.iter().map(|(s, r)| prepare_run(s, r, options)).collect::<Result<_, _>>()?;
    let temps = || runs.iter().flat_map(|r| r.blocks.iter().map(|b| b.temp_c));
    let n = temps().count() as f64;
    let temp_ref_c = temps().sum::<f64>() / n;
    let temp_range_c = temps().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| (a.min(t), b.max(t)));
    let block_s = options.mean_window_s.round().max(1.0) as usize;
    let hac_lag_blocks = (options.hac_lag_s / block_s as f64).ceil().max(1.0) as usize;
    let static_relation = fit_static_relation(&runs);
    let resid: Vec<&[f64]> = runs.iter().map(|r| r.sec.resid_dph.as_slice()).collect();
    let (noise_sigma_dph, noise_from_tau_s) = short_mean_noise(&resid, block_s);
    Ok(Prepared {
        runs,
        static_relation,
        temp_ref_c,
        temp_range_c,
        block_s,
        hac_lag_blocks,
        noise_sigma_dph,
        noise_from_tau_s,
    })
}

/// Longest stretch of finite values.
pub fn longest_finite(v: &[f64]) -> &[f64] {
    let (mut best, mut start) = ((0, 0), 0);
    for i in 0..=v.len() {
        if i == v.len() || !v[i].is_finite() {
            if i - start > best.1 - best.0 {
                best = (start, i);
            }
            start = i + 1;
        }
    }
    &v[best.0..best.1]
}

/// Fewest Allan-variance terms (second differences) pooled over gap-free stretches for an
/// extrapolated short-mean noise.
const MIN_POOLED_TERMS: usize = 10;

/// Noise of one `m`-second mean from 1 s series (one per run, NaN = no data): the
/// overlapping Allan deviation at `tau = m` s on each run's longest gap-free stretch, RMS
/// over runs, and `None`. When no run has a stretch of more than `2 m` seconds (sparse bursts),
/// the Allan variance pooled over every gap-free stretch at the longest cluster `k < m` with
/// at least 10 terms, scaled by `k / m` (white noise between `k` and `m` seconds, stated
/// wherever it is reported), and `Some(k)`; NaN and `None` when even that is impossible.
pub fn short_mean_noise(series: &[&[f64]], m: usize) -> (f64, Option<usize>) {
    let adevs: Vec<f64> =
        series.iter().map(|s| adev_at(longest_finite(s), m)).filter(|v| v.is_finite()).collect();
    if !adevs.is_empty() {
        return ((adevs.iter().map(|v| v * v).sum::<f64>() / adevs.len() as f64).sqrt(), None);
    }
    let stretches: Vec<&[f64]> = series.iter().flat_map(|s| s.split(|v| !v.is_finite())).collect();
    for k in (1..m).rev() {
        let (mut sum, mut terms) = (0.0, 0usize);
        for st in stretches.iter().filter(|st| st.len() > 2 * k) {
            let (s2, t) = second_difference_sum(st, k);
            sum += s2;
            terms += t;
        }
        if terms >= MIN_POOLED_TERMS {
            let avar = sum / (2.0 * (k * k) as f64 * terms as f64);
            return ((avar * k as f64 / m as f64).sqrt(), Some(k));
        }
    }
    (f64::NAN, None)
}

/// Sum of squared overlapping second differences of `m`-second cluster means (times `m^2`)
/// of a gap-free 1 s series, and their number.
fn second_difference_sum(v: &[f64], m: usize) -> (f64, usize) {
    let n = v.len();
    if m == 0 || 2 * m >= n {
        return (0.0, 0);
    }
    let mu = v.iter().sum::<f64>() / n as f64;
    let mut theta = Vec::with_capacity(n + 1);
    theta.push(0.0);
    let mut acc = 0.0;
    for x in v {
        acc += x - mu;
        theta.push(acc);
    }
    let terms = theta.len() - 2 * m;
    let s: f64 = (0..terms).map(|k| (theta[k + 2 * m] - 2.0 * theta[k + m] + theta[k]).powi(2)).sum();
    (s, terms)
}

/// Overlapping Allan deviation of a 1 s series at cluster size `m` seconds (NaN when the
/// series is shorter than `2 m + 1`).
pub fn adev_at(v: &[f64], m: usize) -> f64 {
    let (s, terms) = second_difference_sum(v, m);
    if terms == 0 {
        return f64::NAN;
    }
    (s / (2.0 * (m * m) as f64 * terms as f64)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    use rand_xoshiro::Xoshiro256PlusPlus;

    fn white(n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                sigma * z
            })
            .collect()
    }

    /// White 1 s noise of sigma has Allan deviation sigma / sqrt(m) at tau = m s (closed
    /// form): directly from a long run, and extrapolated from tau = 2 s inside 5 s bursts
    /// separated by gaps. Tolerance 5 % (about 3 standard errors of the estimates here).
    #[test]
    fn short_mean_noise_matches_white_noise_with_and_without_gaps() {
        let sigma = 0.01;
        let long = white(40_000, sigma, 11);
        let (s, from) = short_mean_noise(&[long.as_slice()], 20);
        assert_eq!(from, None);
        assert!((s / (sigma / 20f64.sqrt()) - 1.0).abs() < 0.05, "{s}");

        let mut bursts = white(6 * 3000, sigma, 12);
        for i in (5..bursts.len()).step_by(6) {
            bursts[i] = f64::NAN;
        }
        let (s, from) = short_mean_noise(&[bursts.as_slice()], 5);
        assert_eq!(from, Some(2));
        assert!((s / (sigma / 5f64.sqrt()) - 1.0).abs() < 0.05, "{s}");

        let (s, from) = short_mean_noise(&[&[1.0, f64::NAN, 2.0][..]], 5);
        assert!(s.is_nan());
        assert_eq!(from, None);
    }
}
