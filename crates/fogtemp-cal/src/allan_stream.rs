//! The overlapping Allan deviation in memory that does not grow with the log: an
//! accumulator fed one sample at a time ([`AllanAccumulator`]), a streaming median of the
//! time steps ([`StepMedian`]) and the two passes over a log that `allan` makes with them
//! ([`scan_log`], [`allan_of_scanned_log`]).
//!
//! The accumulator gives [`crate::metrics::allan_deviation_in_segments`]'s curve: the same
//! ladder of cluster sizes, and for every cluster size up to its exact limit `L` the same
//! sums (equal up to float rounding). Above `L` it keeps the angle only every `d` samples
//! (see [`AllanAccumulator`]).

use std::collections::HashMap;
use std::path::Path;

use crate::documents::AllanDocument;
use crate::ingest::{read_log_with_progress, IngestOptions, IngestReport, Row};
use crate::metrics::{AllanPoint, ALLAN_MIN_SAMPLES};
use crate::outliers::{BlockMeans, OutlierSummary};
use crate::CalError;

/// The default exact limit `L`: every cluster size up to 2^16 samples is computed from
/// every overlapping cluster, so every segment up to 2^17 samples gets the exact curve.
pub const DEFAULT_EXACT_LIMIT: usize = 1 << 16;

/// The smallest exact limit taken (a smaller one is raised to it): from 16 on, the rounded
/// cluster sizes above the limit stay distinct and increasing along the ladder.
pub const MIN_EXACT_LIMIT: usize = 16;

/// Samples of a segment whose mean is the conditioning reference (see [`AllanAccumulator`]).
const REFERENCE_SAMPLES: usize = 1024;

/// The overlapping Allan deviation (IEEE Std 952) of a rate series fed one sample at a
/// time, per gap-free segment: [`AllanAccumulator::push`] each sample,
/// [`AllanAccumulator::end_segment`] at each gap, [`AllanAccumulator::finish`] for the curve.
///
/// The cluster sizes are [`crate::metrics::allan_deviation_in_segments`]'s ladder
/// (m = 1, 2, 3, 5, 8, 12, ..., `max(ceil(m sqrt 2), m + 1)`, while 2m is below the longest
/// segment), and each size pools the segments longer than 2m, as there.
///
/// * m <= L (the exact limit): exact. The angle `theta` is kept in a ring of its last 2L + 1
///   values, and every overlapping cluster (one starting at every sample) is summed: the
///   same squared second differences, added in the same order, as the in-memory function.
/// * m > L: decimated ("partially overlapping") estimator. The angle is also kept every
///   d samples (d = 2, 4, 8, ..., one ring of 2L + 1 per stride, made when a segment first
///   needs it), and the size m uses the stride d, the smallest power of two with m <= L d:
///   m is rounded down to a multiple of d (the point's tau is that of the rounded m), and
///   the clusters start every d samples instead of every sample. Each squared difference is
///   the same unbiased term, so the estimate has the same expectation; its variance is only
///   slightly above the fully overlapping one, because clusters started fewer than m samples
///   apart are strongly correlated and d <= 2m / L of them are skipped (W. J. Riley, NIST
///   Special Publication 1065, Handbook of Frequency Stability Analysis, 2008, sections 5.2.4
///   and 5.3: overlapping vs non-overlapping estimators and their confidence; IEEE Std 952,
///   Annex C). Its cluster count for the relative error is counted as for the exact part,
///   N/m - 1 with the rounded m.
///
/// Memory: (2L + 1) f64 for the exact ring plus as much per stride in use
/// (log2(longest segment / L) of them), and a few numbers per cluster size: with the default
/// L = 2^16 about 1 MiB per ring, 12 rings for a day at 1 kHz.
///
/// The mean is not removed: the second difference of the angle cancels a constant rate
/// exactly, so the result does not depend on it. Only for conditioning (an angle that stays
/// small keeps its rounding small) each segment's rate is taken relative to the mean of its
/// first 1024 samples (those are held back until then).
#[derive(Clone, Debug)]
pub struct AllanAccumulator {
    period_s: f64,
    exact_limit: usize,
    /// One per stride 2^k: the angle ring and the cluster sizes that use it.
    levels: Vec<Level>,
    /// Levels in use in the current segment (level 0 always).
    active_levels: usize,
    /// The next cluster size of the ladder (not yet in any level).
    next_m: usize,
    /// The current segment's first samples, before the reference is known.
    held_dph: Vec<f64>,
    reference_dph: Option<f64>,
    theta: f64,
    /// Samples of the current segment fed to the angle (= the newest angle's index).
    segment_samples: usize,
    longest_segment: usize,
    samples: usize,
}

/// The angle every `stride` samples and the cluster sizes computed on it.
#[derive(Clone, Debug)]
struct Level {
    ring: AngleRing,
    clusters: Vec<ClusterSums>,
}

/// The last `values.len()` angles of a stride, newest at `newest`.
#[derive(Clone, Debug)]
struct AngleRing {
    stride: usize,
    values: Vec<f64>,
    newest: usize,
    /// Angles pushed in this segment (the newest one's index + 1).
    len: usize,
}

/// The sums of one cluster size.
#[derive(Clone, Debug)]
struct ClusterSums {
    /// The ladder's size (decides whether the point is in the curve).
    ladder_m: usize,
    /// The size used, samples (`ladder_m` rounded down to a multiple of the stride).
    m: usize,
    /// `m` in strides.
    steps: usize,
    sum: f64,
    terms: u64,
    clusters: f64,
    segment_sum: f64,
    segment_terms: u64,
}

impl AngleRing {
    fn new(stride: usize, capacity: usize) -> Self {
        Self { stride, values: vec![0.0; capacity], newest: 0, len: 0 }
    }

    fn clear(&mut self) {
        self.len = 0;
        self.newest = 0;
    }

    fn push(&mut self, theta: f64) {
        if self.len > 0 {
            self.newest = if self.newest + 1 == self.values.len() { 0 } else { self.newest + 1 };
        }
        if let Some(slot) = self.values.get_mut(self.newest) {
            *slot = theta;
        }
        self.len += 1;
    }

    /// The angle `steps` strides before the newest (`steps` below the capacity).
    fn back(&self, steps: usize) -> f64 {
        let at =
            if self.newest >= steps { self.newest - steps } else { self.newest + self.values.len() - steps };
        self.values.get(at).copied().unwrap_or(f64::NAN)
    }

    /// The angle with index `index` in this segment (NaN when no longer held).
    fn at(&self, index: usize) -> f64 {
        match self.len.checked_sub(index + 1) {
            Some(steps) if steps < self.values.len() => self.back(steps),
            _ => f64::NAN,
        }
    }
}

impl ClusterSums {
    /// Adds the squared second difference ending at the newest angle of `ring`.
    fn add_term(&mut self, ring: &AngleRing) {
        let d = ring.newest_value() - 2.0 * ring.back(self.steps) + ring.back(2 * self.steps);
        self.segment_sum += d.powi(2);
        self.segment_terms += 1;
    }

    /// Pools the segment's sums if the segment is longer than 2m (as the in-memory
    /// function does), then clears them.
    fn end_segment(&mut self, segment_samples: usize) {
        if segment_samples > 2 * self.m {
            self.sum += self.segment_sum;
            self.terms += self.segment_terms;
            self.clusters += segment_samples as f64 / self.m as f64 - 1.0;
        }
        self.segment_sum = 0.0;
        self.segment_terms = 0;
    }

    fn point(&self, period_s: f64) -> AllanPoint {
        let tau_s = self.m as f64 * period_s;
        AllanPoint {
            tau_s,
            adev_dph: (self.sum / (2.0 * tau_s * tau_s * self.terms as f64)).sqrt(),
            relative_error: 1.0 / (2.0 * self.clusters).sqrt(),
        }
    }
}

impl AngleRing {
    fn newest_value(&self) -> f64 {
        self.values.get(self.newest).copied().unwrap_or(f64::NAN)
    }
}

impl AllanAccumulator {
    /// An accumulator for samples `period_s` apart, exact up to [`DEFAULT_EXACT_LIMIT`].
    pub fn new(period_s: f64) -> Self {
        Self::with_exact_limit(period_s, DEFAULT_EXACT_LIMIT)
    }

    /// An accumulator exact for cluster sizes up to `exact_limit` samples (at least
    /// [`MIN_EXACT_LIMIT`]); larger ones are decimated.
    pub fn with_exact_limit(period_s: f64, exact_limit: usize) -> Self {
        let exact_limit = exact_limit.max(MIN_EXACT_LIMIT);
        Self {
            period_s,
            exact_limit,
            levels: vec![Level { ring: AngleRing::new(1, 2 * exact_limit + 1), clusters: Vec::new() }],
            active_levels: 1,
            next_m: 1,
            held_dph: Vec::with_capacity(REFERENCE_SAMPLES),
            reference_dph: None,
            theta: 0.0,
            segment_samples: 0,
            longest_segment: 0,
            samples: 0,
        }
    }

    /// Samples pushed so far.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// One sample, deg/h, the next of the current segment.
    pub fn push(&mut self, rate_dph: f64) {
        self.samples += 1;
        match self.reference_dph {
            Some(reference) => self.feed(rate_dph - reference),
            None => {
                self.held_dph.push(rate_dph);
                if self.held_dph.len() >= REFERENCE_SAMPLES {
                    self.start_segment();
                }
            }
        }
    }

    /// Ends the current segment (a gap follows): no cluster spans it.
    pub fn end_segment(&mut self) {
        if self.reference_dph.is_none() && !self.held_dph.is_empty() {
            self.start_segment();
        }
        if self.reference_dph.is_none() {
            return;
        }
        let n = self.segment_samples;
        for cluster in self.levels.iter_mut().flat_map(|l| l.clusters.iter_mut()) {
            cluster.end_segment(n);
        }
        self.longest_segment = self.longest_segment.max(n);
        self.reference_dph = None;
        self.theta = 0.0;
        self.segment_samples = 0;
        self.active_levels = 1;
        for level in &mut self.levels {
            level.ring.clear();
        }
    }

    /// The curve: one point per cluster size of the ladder below half the longest segment;
    /// empty when the longest segment has fewer than [`ALLAN_MIN_SAMPLES`] samples.
    pub fn finish(mut self) -> Vec<AllanPoint> {
        self.end_segment();
        if self.longest_segment < ALLAN_MIN_SAMPLES {
            return Vec::new();
        }
        let longest = self.longest_segment;
        self.levels
            .iter()
            .flat_map(|l| l.clusters.iter())
            .filter(|c| 2 * c.ladder_m < longest)
            .map(|c| c.point(self.period_s))
            .collect()
    }

    /// Fixes the segment's reference (the mean of the samples held) and feeds them.
    fn start_segment(&mut self) {
        let held = std::mem::take(&mut self.held_dph);
        let reference = held.iter().sum::<f64>() / held.len().max(1) as f64;
        self.reference_dph = Some(reference);
        self.push_angle(0.0);
        for &rate in &held {
            self.feed(rate - reference);
        }
        self.held_dph = held;
        self.held_dph.clear();
    }

    fn feed(&mut self, relative_rate_dph: f64) {
        self.theta += relative_rate_dph * self.period_s;
        self.segment_samples += 1;
        self.push_angle(self.theta);
    }

    /// Takes the angle with index `segment_samples`: into every ring whose stride divides
    /// the index, then the squared differences of every cluster size that ends there.
    fn push_angle(&mut self, theta: f64) {
        let j = self.segment_samples;
        for level in self.levels.iter_mut().take(self.active_levels) {
            if j & (level.ring.stride - 1) != 0 {
                break;
            }
            level.ring.push(theta);
        }
        self.activate_level(j);
        self.extend_ladder(j);
        for level in self.levels.iter_mut().take(self.active_levels) {
            if j & (level.ring.stride - 1) != 0 {
                break;
            }
            let newest = level.ring.len.saturating_sub(1);
            for cluster in level.clusters.iter_mut() {
                if 2 * cluster.steps > newest {
                    break;
                }
                cluster.add_term(&level.ring);
            }
        }
    }

    /// Starts the next stride's ring when the angle index reaches L times half that stride:
    /// the stride below still holds every angle since the segment's start (its 2L + 1
    /// values cover L times the new stride), and the first cluster size needing the new
    /// stride (over L/2 of its strides) has no difference before then.
    fn activate_level(&mut self, j: usize) {
        let k = self.active_levels;
        let Some(start) = 1usize.checked_shl((k - 1) as u32).and_then(|s| s.checked_mul(self.exact_limit))
        else {
            return;
        };
        if j != start {
            return;
        }
        let Some(stride) = 1usize.checked_shl(k as u32) else { return };
        if self.levels.len() == k {
            self.levels
                .push(Level { ring: AngleRing::new(stride, 2 * self.exact_limit + 1), clusters: Vec::new() });
        }
        let (below, this) = self.levels.split_at_mut(k);
        let (Some(parent), Some(level)) = (below.last(), this.first_mut()) else { return };
        level.ring.clear();
        for index in (0..parent.ring.len).step_by(2) {
            level.ring.push(parent.ring.at(index));
        }
        self.active_levels += 1;
    }

    /// Adds every ladder size whose first difference ends at angle index `j` (2m = j with
    /// the rounded m), so that no difference of it is missed.
    fn extend_ladder(&mut self, j: usize) {
        loop {
            let ladder_m = self.next_m;
            let (level, stride) = self.level_for(ladder_m);
            let steps = ladder_m / stride;
            let m = steps * stride;
            if 2 * m > j || level >= self.active_levels {
                return;
            }
            if let Some(l) = self.levels.get_mut(level) {
                l.clusters.push(ClusterSums {
                    ladder_m,
                    m,
                    steps,
                    sum: 0.0,
                    terms: 0,
                    clusters: 0.0,
                    segment_sum: 0.0,
                    segment_terms: 0,
                });
            }
            let next = ((ladder_m as f64) * 2f64.sqrt()).ceil() as usize;
            self.next_m = next.max(ladder_m + 1);
        }
    }

    /// The level and stride of cluster size `m`: the smallest power of two d with m <= L d.
    fn level_for(&self, m: usize) -> (usize, usize) {
        let mut level = 0;
        let mut stride = 1usize;
        while m > self.exact_limit.saturating_mul(stride) && stride < (1 << 62) {
            stride *= 2;
            level += 1;
        }
        (level, stride)
    }
}

/// The most distinct step values [`StepMedian`] counts exactly (and the most bins after).
pub const MAX_DISTINCT_STEPS: usize = 1 << 16;

/// The relative width of [`StepMedian`]'s bins once the steps are too many to count exactly.
pub const STEP_BIN_RELATIVE_WIDTH: f64 = 1e-6;

/// The median of the positive time steps of a log, fed one step at a time in memory that
/// does not grow with the log.
///
/// Exact while the steps take at most [`MAX_DISTINCT_STEPS`] distinct values (logged times
/// take few: a count per distinct f64 step): the same value as sorting every step and taking
/// the one at index len/2. With more distinct steps (times with jitter), the steps are
/// counted in bins of relative width [`STEP_BIN_RELATIVE_WIDTH`] on a log scale (the width
/// doubled whenever the bins too exceed [`MAX_DISTINCT_STEPS`]), and the median is the
/// centre of the bin holding it: within half a bin width (5e-7 relative) of the exact
/// median. What changes then: the sample period (and every tau) by at most that, and a step
/// within a bin width of 1.5 periods may count as a gap or not where the exact median would
/// say otherwise.
#[derive(Clone, Debug, Default)]
pub struct StepMedian {
    exact: HashMap<u64, u64>,
    bins: Option<LogBins>,
    /// The last step seen and how often in a row (added to the counts when the step changes).
    run: Option<(f64, u64)>,
}

/// Counts per bin of ln(step) / width.
#[derive(Clone, Debug)]
struct LogBins {
    width_ln: f64,
    counts: HashMap<i64, u64>,
}

impl LogBins {
    fn add(&mut self, step_s: f64, count: u64) {
        let bin = (step_s.ln() / self.width_ln).floor() as i64;
        *self.counts.entry(bin).or_insert(0) += count;
        if self.counts.len() > MAX_DISTINCT_STEPS {
            self.width_ln *= 2.0;
            let old = std::mem::take(&mut self.counts);
            for (bin, count) in old {
                *self.counts.entry(bin.div_euclid(2)).or_insert(0) += count;
            }
        }
    }
}

impl StepMedian {
    /// No steps yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// One step, s (steps that are not positive are left out, as in the in-memory median).
    pub fn push(&mut self, step_s: f64) {
        if step_s.is_nan() || step_s <= 0.0 {
            return;
        }
        match &mut self.run {
            Some((last, count)) if last.to_bits() == step_s.to_bits() => *count += 1,
            _ => {
                self.flush();
                self.run = Some((step_s, 1));
            }
        }
    }

    /// Whether the median is exact (the steps took few distinct values).
    pub fn is_exact(&self) -> bool {
        self.bins.is_none()
    }

    /// The median step, s (the middle one, index len/2 of the sorted steps); `None` without
    /// a positive step.
    pub fn median(&self) -> Option<f64> {
        let mut counted = self.clone();
        counted.flush();
        match &counted.bins {
            None => {
                let mut steps: Vec<(f64, u64)> =
                    counted.exact.iter().map(|(bits, count)| (f64::from_bits(*bits), *count)).collect();
                steps.sort_by(|a, b| a.0.total_cmp(&b.0));
                middle(&steps)
            }
            Some(bins) => {
                let mut steps: Vec<(i64, u64)> = bins.counts.iter().map(|(b, c)| (*b, *c)).collect();
                steps.sort_by_key(|s| s.0);
                let bin = middle(&steps)?;
                Some(((bin as f64 + 0.5) * bins.width_ln).exp())
            }
        }
    }

    fn flush(&mut self) {
        let Some((step_s, count)) = self.run.take() else { return };
        match &mut self.bins {
            Some(bins) => bins.add(step_s, count),
            None => {
                *self.exact.entry(step_s.to_bits()).or_insert(0) += count;
                if self.exact.len() > MAX_DISTINCT_STEPS {
                    self.switch_to_bins();
                }
            }
        }
    }

    fn switch_to_bins(&mut self) {
        let mut bins = LogBins { width_ln: STEP_BIN_RELATIVE_WIDTH.ln_1p(), counts: HashMap::new() };
        for (bits, count) in std::mem::take(&mut self.exact) {
            bins.add(f64::from_bits(bits), count);
        }
        self.bins = Some(bins);
    }
}

/// The value at index total/2 of sorted `(value, count)` pairs.
fn middle<T: Copy>(sorted: &[(T, u64)]) -> Option<T> {
    let total: u64 = sorted.iter().map(|s| s.1).sum();
    let rank = total / 2;
    let mut below = 0u64;
    for &(value, count) in sorted {
        below += count;
        if below > rank {
            return Some(value);
        }
    }
    None
}

/// The median of the positive steps between consecutive `times_s` ([`StepMedian`]).
pub fn median_step(times_s: &[f64]) -> Option<f64> {
    let mut median = StepMedian::new();
    for w in times_s.windows(2) {
        median.push(w[1] - w[0]);
    }
    median.median()
}

/// What the first pass over a log found ([`scan_log`]).
#[derive(Clone, Debug)]
pub struct LogScan {
    /// The read's report (rows, skipped rows).
    pub report: IngestReport,
    /// The first row analysed (0-based among the rows read; `report.rows` when none is).
    pub start_row: u64,
    /// The time of the first row read, s.
    pub first_time_s: f64,
    /// The time of the first row analysed, s (NaN when none is).
    pub start_time_s: f64,
    /// The median of the positive time steps from the first row analysed on, s; `None`
    /// without one (fewer than two rows with increasing time).
    pub period_s: Option<f64>,
    /// Whether `period_s` is the exact median ([`StepMedian`]).
    pub period_exact: bool,
}

/// The first pass of `allan` over `path`: the first row for which `starts` is true (the
/// rows before it are left out, as a compensator's start-up) and the median time step from
/// there on. `progress(bytes, rows)` as [`read_log_with_progress`].
///
/// # Errors
/// As [`read_log_with_progress`].
pub fn scan_log(
    path: &Path,
    options: &IngestOptions,
    mut starts: impl FnMut(&Row<'_>) -> bool,
    progress: impl FnMut(u64, u64),
) -> Result<LogScan, CalError> {
    let mut rows = 0u64;
    let mut start_row: Option<u64> = None;
    let (mut first_time_s, mut start_time_s, mut previous_s) = (f64::NAN, f64::NAN, f64::NAN);
    let mut median = StepMedian::new();
    let report = read_log_with_progress(
        path,
        options,
        |row| {
            if rows == 0 {
                first_time_s = row.time_s;
            }
            if start_row.is_some() {
                median.push(row.time_s - previous_s);
                previous_s = row.time_s;
            } else if starts(row) {
                start_row = Some(rows);
                start_time_s = row.time_s;
                previous_s = row.time_s;
            }
            rows += 1;
            Ok(())
        },
        progress,
    )?;
    Ok(LogScan {
        start_row: start_row.unwrap_or(report.rows),
        report,
        first_time_s,
        start_time_s,
        period_s: median.median(),
        period_exact: median.is_exact(),
    })
}

/// The second pass of `allan` over `path`: the Allan deviation of the gyro `columns` (the
/// first `columns.len()` gyro columns the options read) from `scan.start_row` on, split at
/// the gaps (steps over 1.5 times `scan.period_s`), as [`AllanDocument`]. `None` without a
/// sample period. `progress(bytes, rows)` as [`read_log_with_progress`].
///
/// # Errors
/// As [`read_log_with_progress`]; [`CalError::LogFormat`] when the log's rows changed since
/// the first pass.
pub fn allan_of_scanned_log(
    path: &Path,
    options: &IngestOptions,
    columns: &[String],
    scan: &LogScan,
    exact_limit: usize,
    progress: impl FnMut(u64, u64),
) -> Result<Option<AllanDocument>, CalError> {
    let Some(period_s) = scan.period_s else { return Ok(None) };
    let mut axes: Vec<AllanAccumulator> =
        columns.iter().map(|_| AllanAccumulator::with_exact_limit(period_s, exact_limit)).collect();
    let mut blocks: Vec<BlockMeans> =
        columns.iter().map(|_| BlockMeans::of_duration(crate::documents::SPIKE_BLOCK_S, period_s)).collect();
    let (mut row_index, mut gaps, mut previous_s) = (0u64, 0usize, None::<f64>);
    let report = read_log_with_progress(
        path,
        options,
        |row| {
            row_index += 1;
            if row_index <= scan.start_row {
                return Ok(());
            }
            if previous_s.is_some_and(|p| row.time_s - p > 1.5 * period_s) {
                gaps += 1;
                axes.iter_mut().for_each(AllanAccumulator::end_segment);
                blocks.iter_mut().for_each(BlockMeans::end_segment);
            }
            previous_s = Some(row.time_s);
            for ((axis, block), rate_dph) in axes.iter_mut().zip(&mut blocks).zip(row.gyros_dph) {
                axis.push(*rate_dph);
                block.push(row.time_s, *rate_dph);
            }
            Ok(())
        },
        progress,
    )?;
    if report.rows != scan.report.rows || report.bytes != scan.report.bytes {
        return Err(CalError::LogFormat {
            path: path.to_path_buf(),
            line: 0,
            problem: format!(
                "the log changed while it was read twice ({} rows, then {})",
                scan.report.rows, report.rows
            ),
        });
    }
    let samples = axes.first().map_or(0, AllanAccumulator::samples);
    let curves = axes.into_iter().map(AllanAccumulator::finish).collect();
    let outliers = blocks.iter().map(OutlierSummary::of).collect();
    Ok(Some(AllanDocument::from_curves(path, columns, period_s, gaps, samples, curves, outliers)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::allan_deviation_in_segments;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, StandardNormal};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// White noise of standard deviation `sigma` around `bias`, deg/h.
    fn white(seed: u64, n: usize, bias: f64, sigma: f64) -> Vec<f64> {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                bias + sigma * z
            })
            .collect()
    }

    fn streamed(segments: &[&[f64]], dt_s: f64, exact_limit: usize) -> Vec<AllanPoint> {
        let mut accumulator = AllanAccumulator::with_exact_limit(dt_s, exact_limit);
        for segment in segments {
            for &r in *segment {
                accumulator.push(r);
            }
            accumulator.end_segment();
        }
        accumulator.finish()
    }

    /// The exact overlapping Allan deviation at one cluster size `m` (the oracle for the
    /// decimated sizes): every cluster of one segment, the mean removed.
    fn brute_force_adev(rate_dph: &[f64], dt_s: f64, m: usize) -> f64 {
        let mean = rate_dph.iter().sum::<f64>() / rate_dph.len() as f64;
        let mut theta = vec![0.0];
        for r in rate_dph {
            theta.push(theta[theta.len() - 1] + (r - mean) * dt_s);
        }
        let n = theta.len() - 2 * m;
        let sum: f64 = (0..n).map(|k| (theta[k + 2 * m] - 2.0 * theta[k + m] + theta[k]).powi(2)).sum();
        let tau = m as f64 * dt_s;
        (sum / (2.0 * tau * tau * n as f64)).sqrt()
    }

    /// Up to the exact limit the accumulator gives the in-memory curve: the same cluster
    /// sizes and relative errors, deviations within 1e-9 relative (only the angle's rounding
    /// differs: it is taken relative to another reference), for random series with a bias,
    /// cut into segments of random length (some too short for any size), and several limits.
    #[test]
    fn exact_part_matches_the_in_memory_curve() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        for (case, exact_limit) in [16usize, 37, 64, 1024, DEFAULT_EXACT_LIMIT].into_iter().enumerate() {
            let series = white(100 + case as u64, 30_000, 250.0 * rng.gen::<f64>() - 100.0, 3.0);
            // A random walk on top, so the sizes do not all see the same slope.
            let mut walk = 0.0;
            let series: Vec<f64> = series
                .iter()
                .map(|r| {
                    walk += 0.01 * rng.gen::<f64>() - 0.005;
                    r + walk
                })
                .collect();
            let mut cuts = vec![0];
            while cuts.last().is_some_and(|&c| c < series.len()) {
                let len = [1, 3, 5, 200, 2000, 9000][rng.gen_range(0..6)];
                cuts.push((cuts[cuts.len() - 1] + len).min(series.len()));
            }
            let segments: Vec<&[f64]> = cuts.windows(2).map(|w| &series[w[0]..w[1]]).collect();
            let dt_s = 0.01;
            let expected = allan_deviation_in_segments(&segments, dt_s);
            let got = streamed(&segments, dt_s, exact_limit);
            assert_eq!(got.len(), expected.len(), "L = {exact_limit}");
            let mut exact_points = 0;
            for (g, e) in got.iter().zip(&expected) {
                let m = (e.tau_s / dt_s).round() as usize;
                if m > exact_limit {
                    continue;
                }
                exact_points += 1;
                assert_eq!(g.tau_s, e.tau_s);
                assert!((g.relative_error / e.relative_error - 1.0).abs() <= 1e-12, "{g:?} vs {e:?}");
                assert!(
                    (g.adev_dph / e.adev_dph - 1.0).abs() <= 1e-9,
                    "L = {exact_limit}, m = {m}: {g:?} vs {e:?}"
                );
            }
            assert!(exact_points >= 6, "{exact_points}");
        }
    }

    /// One segment and series shorter than the ladder's start: the same as in memory
    /// (empty below 4 samples).
    #[test]
    fn short_series_match_the_in_memory_curve() {
        for n in 0..40 {
            let series = white(n as u64, n, 1.0, 1.0);
            let expected = allan_deviation_in_segments(&[&series], 0.1);
            let got = streamed(&[&series], 0.1, MIN_EXACT_LIMIT);
            assert_eq!(got.len(), expected.len(), "n = {n}");
            for (g, e) in got.iter().zip(&expected).filter(|(_, e)| e.tau_s <= 0.1 * MIN_EXACT_LIMIT as f64) {
                assert!((g.adev_dph / e.adev_dph - 1.0).abs() <= 1e-9, "n = {n}: {g:?} vs {e:?}");
            }
        }
        let mut empty = AllanAccumulator::new(0.1);
        empty.end_segment();
        empty.end_segment();
        assert!(empty.finish().is_empty());
    }

    /// Above the exact limit (L = 16 here, so sizes from 17 samples on are decimated, with
    /// strides up to m / 8: far coarser than the default's m / 32768) the partially
    /// overlapping estimate follows the fully overlapping one at the same (rounded) size on
    /// the same white noise: both are unbiased, and the clusters it skips start fewer than
    /// m / 8 samples from one it keeps, so they add little independent information. Bound:
    /// half the point's relative error where that is at most 0.25 (8 independent clusters or
    /// more; measured at most 0.22 over 3 seeds), one relative error at the longest sizes,
    /// where the starts left span less than a stride or two (measured 0.70). And the closed
    /// form sigma sqrt(dt / tau) within 3 relative errors (3 sigma of the estimate).
    #[test]
    fn decimated_part_follows_the_exact_estimate_and_white_noise() {
        let (dt_s, sigma) = (0.01, 2.0);
        let mut worst = 0.0f64;
        for seed in [1, 2, 3] {
            let series = white(seed, 40_000, 5.0, sigma);
            let exact = allan_deviation_in_segments(&[&series], dt_s);
            let curve = streamed(&[&series], dt_s, 16);
            assert_eq!(curve.len(), exact.len());
            let mut decimated = 0;
            for (p, e) in curve.iter().zip(&exact) {
                let m = (p.tau_s / dt_s).round() as usize;
                let ladder_m = (e.tau_s / dt_s).round() as usize;
                if ladder_m <= 16 {
                    continue;
                }
                decimated += 1;
                // m rounded down to a multiple of the stride, by less than one stride.
                let (_, stride) = AllanAccumulator::with_exact_limit(dt_s, 16).level_for(ladder_m);
                assert!(m % stride == 0 && m <= ladder_m && ladder_m - m < stride, "{m} {ladder_m} {stride}");
                let full = brute_force_adev(&series, dt_s, m);
                let deviation = (p.adev_dph / full - 1.0).abs() / p.relative_error;
                worst = worst.max(deviation);
                let bound = if p.relative_error <= 0.25 { 0.5 } else { 1.0 };
                assert!(deviation <= bound, "m = {m}: {} vs {full} ({:?})", p.adev_dph, p);
                let closed_form = sigma * (dt_s / p.tau_s).sqrt();
                assert!(
                    (p.adev_dph / closed_form - 1.0).abs() <= 3.0 * p.relative_error,
                    "m = {m}: {} vs {closed_form} ({:?})",
                    p.adev_dph,
                    p
                );
            }
            assert!(decimated >= 15, "{decimated}");
        }
        eprintln!("decimated vs exact: worst {worst:.3} relative errors");
    }

    /// The decimated sizes are distinct and increasing, and the memory is one ring per
    /// stride in use.
    #[test]
    fn decimated_sizes_increase_and_rings_stay_few() {
        let series = white(9, 200_000, 0.0, 1.0);
        let mut accumulator = AllanAccumulator::with_exact_limit(1.0, 16);
        for &r in &series {
            accumulator.push(r);
        }
        // 200 000 / 16 needs strides up to 2^13 (rings made at 16 * 2^(k-1) <= 200 000).
        assert!(accumulator.levels.len() <= 15, "{}", accumulator.levels.len());
        assert!(accumulator.levels.iter().all(|l| l.ring.values.len() == 33));
        let curve = accumulator.finish();
        assert!(curve.windows(2).all(|w| w[1].tau_s > w[0].tau_s), "{curve:?}");
        assert!(curve.iter().all(|p| p.adev_dph.is_finite() && p.relative_error.is_finite()));
    }

    /// With few distinct steps the median is exact; with jittered times (every step
    /// distinct, more than 2^16 of them) it is the centre of a bin of relative width 1e-6,
    /// within half of that of the exact median.
    #[test]
    fn step_median_is_exact_then_binned() {
        let times: Vec<f64> = (0..100_000).map(|k| f64::from(k) * 0.001).collect();
        let exact = sorted_median(&times);
        let mut median = StepMedian::new();
        times.windows(2).for_each(|w| median.push(w[1] - w[0]));
        assert!(median.is_exact());
        assert_eq!(median.median(), Some(exact));
        assert_eq!(median_step(&times), Some(exact));

        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        for n in [70_000, 300_000] {
            let times: Vec<f64> =
                (0..n).map(|k| f64::from(k) * 0.01 + 2e-4 * (rng.gen::<f64>() - 0.5)).collect();
            let exact = sorted_median(&times);
            let mut median = StepMedian::new();
            times.windows(2).for_each(|w| median.push(w[1] - w[0]));
            assert!(!median.is_exact());
            let binned = median.median().expect("a median");
            assert!((binned / exact - 1.0).abs() <= 0.5e-6 + 1e-12, "{binned} vs {exact}");
        }
        assert_eq!(median_step(&[1.0]), None);
        assert_eq!(median_step(&[1.0, 1.0, 0.5]), None);
    }

    /// A log read in two streaming passes gives the document its rows give as arrays
    /// (`AllanDocument::new`), bit for bit: here with two gaps, a left-out start (the rows
    /// before the first with a positive second column, as a compensator's start-up) and a
    /// stretch of 150 000 samples, so that sizes above the exact limit are in the curve.
    #[test]
    fn a_log_read_twice_gives_the_arrays_document() {
        let dir = std::env::temp_dir().join(format!("fogtemp-allan-stream-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let path = dir.join("static.csv");
        let mut csv = String::from("time_s,gyro_dph,gyro2_dph\n");
        let noise = white(21, 170_000, 0.3, 2.0);
        let mut t_ms = 0u64;
        for (k, r) in noise.iter().enumerate() {
            t_ms += if k == 9_000 || k == 12_000 { 700 } else { 10 };
            let flag = if k < 500 { -1.0 } else { 1.0 };
            csv.push_str(&format!("{}.{:03},{r:.6},{flag}\n", t_ms / 1000, t_ms % 1000));
        }
        std::fs::write(&path, csv).expect("write log");
        let mut options = IngestOptions::default();
        options.format.temp_columns.clear();
        options.format.gyro_columns = vec!["gyro_dph".into(), "gyro2_dph".into()];
        let columns = vec!["gyro_dph".to_string()];
        let scan = scan_log(&path, &options, |row| row.gyros_dph.get(1).is_some_and(|f| *f > 0.0), |_, _| {})
            .expect("pass 1");
        assert_eq!(scan.start_row, 500);
        let streamed = allan_of_scanned_log(&path, &options, &columns, &scan, DEFAULT_EXACT_LIMIT, |_, _| {})
            .expect("pass 2")
            .expect("a period");
        let series = crate::ingest::read_gyro_series(&path, &options, |_, _| {}).expect("read");
        let _ = std::fs::remove_dir_all(&dir);
        let arrays = AllanDocument::new(
            &path,
            &columns,
            &series.time_s[500..],
            &[series.gyros_dph[0][500..].to_vec()],
        )
        .expect("a period");
        assert_eq!(streamed, arrays);
        assert_eq!(streamed.gaps, 2);
        assert_eq!(streamed.axes[0].samples, 169_500);
        assert!(streamed.axes[0].curve.iter().any(|p| p.tau_s > DEFAULT_EXACT_LIMIT as f64 * 0.01));
    }

    /// The in-memory median: the positive step at index len/2 of the sorted steps.
    fn sorted_median(times: &[f64]) -> f64 {
        let mut steps: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0.0).collect();
        steps.sort_by(f64::total_cmp);
        steps[steps.len() / 2]
    }
}
