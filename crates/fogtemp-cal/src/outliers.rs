//! Outliers in a series of means (a spike in a log: a corrupted sample, an overload code, a
//! shock): a Hampel filter. A value more than [`ROBUST_SDS`] robust standard deviations from
//! the median of the finite values within [`HALF_WINDOW`] places either side is an outlier.
//!
//! The window is symmetric about the value judged, so near the ends of a series it is
//! shorter (and a value with fewer than [`MIN_NEIGHBOURS`] finite values in it is not judged):
//! the median of a ramp is then its value at the centre. (A change after seeing a result: the
//! first version cut the window at the ends, and a smooth warm-up at a run's start, without
//! noise, read as 24 outliers in a unit test.)
//!
//! The principles (fixed before any result was seen): on a 1 s grid the window is a minute
//! either side, far shorter than any thermal effect (minutes to hours), so the median follows
//! the bias, steps and ramps alike, and only the noise is left in the deviations; 10 robust
//! SDs is a chance of 1.5e-23 per value for Gaussian noise, so no amount of clean data trips
//! it. `fit` (the gyro means of the feature points, [`crate::calibrate`]) and `diagnose` (the
//! residual's 1 s means) read outliers as missing and name them.

/// Values either side whose median an outlier is judged against.
pub const HALF_WINDOW: usize = 30;
/// Robust standard deviations beyond which a value is an outlier.
pub const ROBUST_SDS: f64 = 10.0;
/// Finite values a neighbourhood needs for its median to judge a value.
pub const MIN_NEIGHBOURS: usize = 5;

/// The outliers of `values` (NaN = none there): their indices and deviations from their
/// neighbourhood's median, and the series' robust standard deviation (1.4826 x the median
/// absolute deviation from the neighbourhood medians). Nothing is found in a series without
/// spread (a robust SD of 0: quantised or noise-free data, where any change would count).
pub fn screen(values: &[f64]) -> (Vec<(usize, f64)>, f64) {
    let n = values.len();
    let mut deviation = vec![f64::NAN; n];
    let mut window = Vec::with_capacity(2 * HALF_WINDOW + 1);
    for k in 0..n {
        if !values[k].is_finite() {
            continue;
        }
        window.clear();
        // Symmetric about k, also at the ends (fewer values there): the median of a ramp is
        // then its value at k; a one-sided window at a run's start put the median of a
        // warm-up's ramp off its centre, and a smooth noise-free start read as outliers.
        let half = HALF_WINDOW.min(k).min(n - 1 - k);
        let around = &values[k - half..=k + half];
        window.extend(around.iter().copied().filter(|v| v.is_finite()));
        if window.len() < MIN_NEIGHBOURS {
            continue;
        }
        deviation[k] = values[k] - median(&mut window);
    }
    let mut absolute: Vec<f64> = deviation.iter().filter(|d| d.is_finite()).map(|d| d.abs()).collect();
    if absolute.is_empty() {
        return (Vec::new(), f64::NAN);
    }
    let robust_sd = 1.4826 * median(&mut absolute);
    if robust_sd.is_nan() || robust_sd <= 0.0 {
        return (Vec::new(), robust_sd);
    }
    let limit = ROBUST_SDS * robust_sd;
    // An overload code (9.91e37) or an infinite mean is an outlier too, as far as it goes.
    let outlier = |v: f64, d: f64| d.abs() > limit || (v.is_infinite() && !d.is_finite());
    let found = deviation
        .iter()
        .zip(values)
        .enumerate()
        .filter(|(_, (d, v))| outlier(**v, **d))
        .map(|(k, (&d, _))| (k, d))
        .collect();
    (found, robust_sd)
}

/// Means of consecutive samples in blocks of a fixed count, streamed: the series [`screen`]
/// judges for a log too long to hold (`allan`'s). A block never spans a gap
/// ([`BlockMeans::end_segment`]); one cut short by a gap or the end is left out, as its mean of
/// fewer samples is noisier than the others.
#[derive(Clone, Debug, Default)]
pub struct BlockMeans {
    samples_per_block: usize,
    sum: f64,
    count: usize,
    first_s: f64,
    /// Each block's first sample time, s.
    pub time_s: Vec<f64>,
    /// Each block's mean.
    pub means: Vec<f64>,
}

impl BlockMeans {
    /// Blocks of `samples_per_block` samples (at least 1).
    pub fn new(samples_per_block: usize) -> Self {
        Self { samples_per_block: samples_per_block.max(1), ..Self::default() }
    }

    /// Blocks of about `block_s` of samples `period_s` apart (one sample when slower).
    pub fn of_duration(block_s: f64, period_s: f64) -> Self {
        let per_block = (block_s / period_s).round();
        Self::new(if per_block.is_finite() && per_block >= 1.0 { per_block as usize } else { 1 })
    }

    /// Adds a sample at `time_s`.
    pub fn push(&mut self, time_s: f64, value: f64) {
        if self.count == 0 {
            self.first_s = time_s;
        }
        self.sum += value;
        self.count += 1;
        if self.count == self.samples_per_block {
            self.time_s.push(self.first_s);
            self.means.push(self.sum / self.count as f64);
            self.end_segment();
        }
    }

    /// A gap: the open block is left out.
    pub fn end_segment(&mut self) {
        self.sum = 0.0;
        self.count = 0;
    }
}

/// A series' outliers ([`screen`]) for a note: how many, and the first's time, deviation and
/// size.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct OutlierSummary {
    /// Means beyond [`ROBUST_SDS`] robust SDs of their neighbours' median.
    pub count: usize,
    /// The first one's time, s.
    pub first_at_s: f64,
    /// The first one's deviation from its neighbours' median, deg/h.
    pub deviation_dph: f64,
    /// The series' robust standard deviation, deg/h.
    pub robust_sd_dph: f64,
}

impl OutlierSummary {
    /// The outliers of `blocks`' means, `None` without any.
    pub fn of(blocks: &BlockMeans) -> Option<Self> {
        let (found, robust_sd_dph) = screen(&blocks.means);
        let &(first, deviation_dph) = found.first()?;
        Some(Self {
            count: found.len(),
            first_at_s: blocks.time_s.get(first).copied().unwrap_or(f64::NAN),
            deviation_dph,
            robust_sd_dph,
        })
    }
}

/// An outlier's deviation (deg/h, signed) and its size in robust SDs as text: five decimals
/// and whole SDs for ordinary sizes, and four significant digits in exponent form for an
/// overload code's 9.91e37 (its 38 digits said nothing).
pub fn deviation_text(deviation_dph: f64, robust_sd_dph: f64) -> (String, String) {
    let sds = deviation_dph.abs() / robust_sd_dph;
    let deviation = if deviation_dph.abs() < 1e6 {
        format!("{deviation_dph:+.5}")
    } else {
        format!("{deviation_dph:+.3e}")
    };
    let sds = if sds < 1e6 { format!("{sds:.0}") } else { format!("{sds:.3e}") };
    (deviation, sds)
}

/// The median of `values` (reordered; not empty).
fn median(values: &mut [f64]) -> f64 {
    values.sort_unstable_by(f64::total_cmp);
    let m = values.len() / 2;
    if values.len() % 2 == 1 {
        values[m]
    } else {
        0.5 * (values[m - 1] + values[m])
    }
}

#[cfg(test)]
mod tests {
    use super::{deviation_text, screen};

    #[test]
    fn deviations_are_written_plainly_and_overloads_in_exponent_form() {
        assert_eq!(deviation_text(999.944_553, 0.035_337), ("+999.94455".to_string(), "28297".to_string()));
        assert_eq!(deviation_text(-1.159_92, 0.030_52), ("-1.15992".to_string(), "38".to_string()));
        assert_eq!(deviation_text(9.91e37, 0.0353), ("+9.910e37".to_string(), "2.807e39".to_string()));
    }
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

    /// Against hand-made series: white noise of 7200 values with one spike of 20 SD finds
    /// the spike alone, at its index, its deviation within 0.5 SD of its value (the median of
    /// 61 noise values has SD 1.25 / sqrt(61) = 0.16 SD); a robust SD within 5 % of the
    /// noise's (standard error ~1.2 % at this length); a step of 50 SD, a ramp of 0.1 SD per
    /// value and a constant series find nothing; an overload code is found.
    #[test]
    fn a_spike_is_found_and_steps_ramps_noise_are_not() {
        let sigma = 0.03;
        let mut noise = white(7200, sigma, 41);
        let (found, robust_sd) = screen(&noise);
        assert!(found.is_empty(), "{found:?}");
        assert!((robust_sd / sigma - 1.0).abs() < 0.05, "{robust_sd}");
        noise[999] += 20.0 * sigma;
        let (found, _) = screen(&noise);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].0, 999);
        assert!((found[0].1 - noise[999]).abs() < 0.5 * sigma, "{found:?}");
        noise[2000] = 9.91e37;
        noise[3000] = f64::INFINITY;
        let found: Vec<usize> = screen(&noise).0.iter().map(|f| f.0).collect();
        assert_eq!(found, [999, 2000, 3000]);
        let step: Vec<f64> = white(7200, sigma, 42)
            .iter()
            .enumerate()
            .map(|(k, v)| v + if k >= 3600 { 50.0 * sigma } else { 0.0 })
            .collect();
        assert!(screen(&step).0.is_empty());
        let ramp: Vec<f64> =
            white(7200, sigma, 43).iter().enumerate().map(|(k, v)| v + 0.1 * sigma * k as f64).collect();
        assert!(screen(&ramp).0.is_empty());
        let (found, robust_sd) = screen(&[0.5; 100]);
        assert!(found.is_empty() && robust_sd == 0.0);
        // Gaps (NaN) are skipped, and a value with fewer than 5 finite neighbours is not judged.
        let mut sparse = vec![f64::NAN; 200];
        sparse[100] = 1.0;
        sparse[101] = 1.0;
        assert!(screen(&sparse).0.is_empty());
    }
}
