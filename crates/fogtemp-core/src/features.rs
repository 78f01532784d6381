//! Feature tracker: smoothed temperature and its rate (deg C/min) from raw samples, with
//! fixed-size state. Calibration (`fogtemp-cal`) calls this same code, so firmware and
//! calibration compute features identically.
//!
//! Method: temperature samples are averaged into `block_count` sub-blocks of
//! `window_s / block_count` seconds. When a block closes, the features are the
//! least-squares line through the block means of the last window: the rate is its
//! slope, the temperature its value at the end of the newest block (the current time,
//! so the feature is causal and, for a linear trend, exact up to half a temperature sample
//! period: a block mean stands for its samples' mean time, half a period before the block
//! centre when sampling is uniform. Calibration and firmware share this code, so the lag
//! cancels when both sample the temperature at the same rate). Averaging before the
//! slope makes the rate robust to sensor quantisation, unlike a two-point difference.
//!
//! Gaps: when no temperature arrives for longer than `max_gap_s`, the tracker restarts,
//! so no window ever spans a gap. Blocks without samples (slow sensors, short dropouts)
//! are left out of the fit rather than filled.

use crate::error::Error;
use crate::model::FeatureSettings;

/// Smoothed features at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Features {
    /// Time the features refer to (end of the newest closed block), microseconds.
    pub time_us: u64,
    /// Smoothed temperature at `time_us`, deg C.
    pub temp_c: f32,
    /// Temperature rate, deg C per minute.
    pub rate_c_per_min: f32,
    /// Blocks with data in the window.
    pub blocks_used: u32,
    /// The whole window has elapsed since the tracker (re)started.
    pub window_full: bool,
}

/// What one temperature sample did to the tracker.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PushOutcome {
    /// One or more blocks closed and `features()` changed (may now be `None`).
    pub updated: bool,
    /// The silence before this sample exceeded `max_gap_s`; the tracker restarted.
    pub restarted: bool,
}

/// Where a tracker keeps its block means: a fixed array (`[f32; N]`, the usual case), a
/// borrowed slice, or storage a foreign caller owns (the C ABI). Only the first
/// `block_count` entries are used; the capacity is `blocks().len()`.
pub trait BlockStorage {
    /// The block means, read-only.
    fn blocks(&self) -> &[f32];
    /// The block means, writable.
    fn blocks_mut(&mut self) -> &mut [f32];
}

impl<const N: usize> BlockStorage for [f32; N] {
    #[inline(always)]
    fn blocks(&self) -> &[f32] {
        self
    }
    #[inline(always)]
    fn blocks_mut(&mut self) -> &mut [f32] {
        self
    }
}

impl BlockStorage for &mut [f32] {
    #[inline(always)]
    fn blocks(&self) -> &[f32] {
        self
    }
    #[inline(always)]
    fn blocks_mut(&mut self) -> &mut [f32] {
        self
    }
}

/// Fixed-capacity feature tracker holding up to `N` block means. No allocation.
pub type FeatureTracker<const N: usize> = BlockTracker<[f32; N]>;

/// The feature tracker over any [`BlockStorage`]; [`FeatureTracker<N>`] is the one with an
/// array of `N` blocks inside. No allocation.
#[derive(Clone, Debug)]
pub struct BlockTracker<S> {
    block_us: u64,
    block_count: usize,
    min_blocks: usize,
    max_gap_us: u64,
    /// Block means, oldest first from `head`; NaN = block without samples.
    ring_c: S,
    head: usize,
    /// Blocks closed since (re)start, saturating at `block_count`.
    closed: usize,
    /// Current block: end time, reference value, sum of deviations, sample count.
    block_end_us: u64,
    block_ref_c: f32,
    block_sum_dev_c: f32,
    block_samples: u32,
    last_time_us: Option<u64>,
    features: Option<Features>,
}

/// The block length and the longest tolerated gap in whole microseconds, or the name of
/// the field that cannot be timed (below 1 us or from 1e15 us, about 32 years). Shared by
/// the tracker and the blob validator, so a model `Model::from_bytes` accepts always gets a
/// tracker.
pub(crate) fn timing_us(settings: &FeatureSettings) -> Result<(u64, u64), &'static str> {
    if settings.block_count == 0 {
        return Err("block_count");
    }
    // f32, not f64: f64 would link ~3 KB of soft-float routines on Cortex-M4F for these
    // two start-up lines. The rounding is deterministic (IEEE) and identical in
    // calibration and firmware, which is what matters. `+ 0.5` rounds (no `round` in core).
    let block_us = settings.window_s * 1.0e6 / settings.block_count as f32 + 0.5;
    let max_gap_us = settings.max_gap_s * 1.0e6 + 0.5;
    if !(1.0..1.0e15).contains(&block_us) {
        return Err("window_s");
    }
    if !(1.0..1.0e15).contains(&max_gap_us) {
        return Err("max_gap_s");
    }
    Ok((block_us as u64, max_gap_us as u64))
}

impl<const N: usize> BlockTracker<[f32; N]> {
    /// A tracker for `settings`.
    ///
    /// # Errors
    /// [`Error::CapacityTooSmall`] if `settings.block_count > N`; [`Error::BadValue`] for
    /// settings a validated model cannot hold (non-positive window, gap, fewer than 2 blocks).
    pub fn new(settings: &FeatureSettings) -> Result<Self, Error> {
        Self::with_storage(settings, [f32::NAN; N])
    }
}

impl<S: BlockStorage> BlockTracker<S> {
    /// A tracker for `settings` keeping its block means in `storage` (at least
    /// `settings.block_count` entries; see [`FeatureSettings::blocks_needed`]).
    ///
    /// # Errors
    /// [`Error::CapacityTooSmall`] if `settings.block_count` exceeds the storage's length;
    /// [`Error::BadValue`] for settings a validated model cannot hold (non-positive window,
    /// gap, fewer than 2 blocks).
    pub fn with_storage(settings: &FeatureSettings, mut storage: S) -> Result<Self, Error> {
        let bad = |field| Error::BadValue { field, axis: 0, index: 0 };
        let block_count = settings.block_count as usize;
        let capacity = storage.blocks().len();
        if block_count > capacity {
            return Err(Error::CapacityTooSmall { needed: block_count, capacity });
        }
        if block_count < 2 || (settings.min_blocks as usize) < 2 || settings.min_blocks as usize > block_count
        {
            return Err(bad("block_count"));
        }
        let (block_us, max_gap_us) = timing_us(settings).map_err(bad)?;
        storage.blocks_mut().iter_mut().for_each(|b| *b = f32::NAN);
        Ok(Self {
            block_us,
            block_count,
            min_blocks: settings.min_blocks as usize,
            max_gap_us,
            ring_c: storage,
            head: 0,
            closed: 0,
            block_end_us: 0,
            block_ref_c: 0.0,
            block_sum_dev_c: 0.0,
            block_samples: 0,
            last_time_us: None,
            features: None,
        })
    }

    /// The latest features, or `None` while fewer than `min_blocks` blocks hold data (or
    /// while the window's values overflow f32: reported features are always finite).
    pub fn features(&self) -> Option<Features> {
        self.features
    }

    /// Blocks this tracker can hold (the storage's length).
    pub fn capacity(&self) -> usize {
        self.ring_c.blocks().len()
    }

    /// Blocks per window in use (the model's `block_count`).
    pub fn block_count(&self) -> usize {
        self.block_count
    }

    /// Time of the last accepted sample, microseconds.
    pub fn last_time_us(&self) -> Option<u64> {
        self.last_time_us
    }

    /// The longest temperature silence tolerated, microseconds.
    pub fn max_gap_us(&self) -> u64 {
        self.max_gap_us
    }

    /// Whether this tracker's block count and readiness (`min_blocks`) are those of
    /// `settings`: two integer comparisons, cheap enough for every sample. (Block length and
    /// gap limit are not compared: they would need the f32 timing computation per call.)
    #[inline]
    pub fn is_for(&self, settings: &FeatureSettings) -> bool {
        self.block_count == settings.block_count as usize && self.min_blocks == settings.min_blocks as usize
    }

    /// Forgets everything, as at power-on.
    pub fn reset(&mut self) {
        self.ring_c.blocks_mut().iter_mut().for_each(|b| *b = f32::NAN);
        self.head = 0;
        self.closed = 0;
        self.block_samples = 0;
        self.block_sum_dev_c = 0.0;
        self.last_time_us = None;
        self.features = None;
    }

    /// Adds one temperature sample.
    ///
    /// # Errors
    /// [`Error::NonFiniteSample`] for NaN/infinite temperature, [`Error::TimeNotIncreasing`]
    /// for a time not after the previous sample by at most `max_gap_s` (jitter). A rejected
    /// sample changes nothing. A time more than `max_gap_s` before the previous one restarts
    /// the tracker, as a gap does (a clock that restarted, or a wrong time far ahead before it).
    pub fn push(&mut self, time_us: u64, temp_c: f32) -> Result<PushOutcome, Error> {
        if !temp_c.is_finite() {
            return Err(Error::NonFiniteSample);
        }
        let mut outcome = PushOutcome::default();
        if let Some(previous_us) = self.last_time_us {
            if time_us <= previous_us && previous_us - time_us <= self.max_gap_us {
                return Err(Error::TimeNotIncreasing { previous_us, found_us: time_us });
            }
            // A step back longer than the gap limit is a clock that restarted (or a time
            // stamp far in the future before it): handled as a gap, so that one wrong time
            // cannot reject every later sample. A step back within it is jitter: rejected.
            if time_us.abs_diff(previous_us) > self.max_gap_us {
                self.reset();
                outcome.restarted = true;
                outcome.updated = true;
            }
        }
        if self.last_time_us.is_none() {
            self.block_end_us = time_us.saturating_add(self.block_us);
        } else if time_us >= self.block_end_us {
            self.close_blocks_until(time_us);
            self.features = self.compute();
            outcome.updated = true;
        }
        self.accumulate(temp_c);
        self.last_time_us = Some(time_us);
        Ok(outcome)
    }

    fn accumulate(&mut self, temp_c: f32) {
        if self.block_samples == 0 {
            self.block_ref_c = temp_c;
            self.block_sum_dev_c = 0.0;
        }
        self.block_sum_dev_c += temp_c - self.block_ref_c;
        self.block_samples = self.block_samples.saturating_add(1);
    }

    /// Closes the current block and any empty ones up to the block holding `time_us`.
    fn close_blocks_until(&mut self, time_us: u64) {
        // `checked_*`, here and below: the validator guarantees a block of >= 1 us and >= 2
        // blocks, but the compiler cannot see it, and a division by zero would link a panic
        // path (a link-time no-panic check on Cortex-M4 found three; docs/architecture.md).
        let behind = time_us.saturating_sub(self.block_end_us).checked_div(self.block_us).unwrap_or(0);
        let to_close = behind.saturating_add(1);
        let mean = if self.block_samples > 0 {
            self.block_ref_c + self.block_sum_dev_c / self.block_samples as f32
        } else {
            f32::NAN
        };
        self.push_block(mean);
        // Empty blocks after it, at most one window's worth matters.
        let empties = (to_close - 1).min(self.block_count as u64) as usize;
        for _ in 0..empties {
            self.push_block(f32::NAN);
        }
        self.block_end_us = self.block_end_us.saturating_add(to_close.saturating_mul(self.block_us));
        self.block_samples = 0;
        self.block_sum_dev_c = 0.0;
    }

    fn push_block(&mut self, mean_c: f32) {
        if let Some(slot) = self.ring_c.blocks_mut().get_mut(self.head) {
            *slot = mean_c;
        }
        self.head = (self.head + 1).checked_rem(self.block_count).unwrap_or(0);
        self.closed = (self.closed + 1).min(self.block_count);
    }

    /// Block means of the window, oldest first, as `(position, mean)`; position 0 is the
    /// oldest block of a full window, so positions are block centres in block units.
    fn window(&self) -> impl Iterator<Item = (f32, f32)> + '_ {
        let n = self.block_count;
        let first = n - self.closed;
        (first..n).filter_map(move |pos| {
            let idx = (self.head + pos).checked_rem(n).unwrap_or(0);
            let mean = self.ring_c.blocks().get(idx).copied().unwrap_or(f32::NAN);
            (!mean.is_nan()).then_some((pos as f32, mean))
        })
    }

    /// Least-squares line through the window's block means (centred sums in f32).
    fn compute(&self) -> Option<Features> {
        let (mut count, mut sum_x, mut sum_y) = (0u32, 0.0f32, 0.0f32);
        let y_ref = self.window().next()?.1;
        for (x, y) in self.window() {
            count += 1;
            sum_x += x;
            sum_y += y - y_ref;
        }
        if (count as usize) < self.min_blocks {
            return None;
        }
        let (mean_x, mean_dy) = (sum_x / count as f32, sum_y / count as f32);
        let (mut sxx, mut sxy) = (0.0f32, 0.0f32);
        for (x, y) in self.window() {
            let dx = x - mean_x;
            sxx += dx * dx;
            sxy += dx * (y - y_ref - mean_dy);
        }
        if sxx.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
            return None;
        }
        let slope_c_per_block = sxy / sxx;
        let end_x = self.block_count as f32 - 0.5;
        let block_min = self.block_us as f32 / 60.0e6;
        let temp_c = y_ref + mean_dy + slope_c_per_block * (end_x - mean_x);
        let rate_c_per_min = slope_c_per_block / block_min;
        // Finite inputs near f32::MAX overflow the sums or the fit: report no features
        // rather than NaN or infinity.
        if !(temp_c.is_finite() && rate_c_per_min.is_finite()) {
            return None;
        }
        Some(Features {
            time_us: self.block_end_us.saturating_sub(self.block_us),
            temp_c,
            rate_c_per_min,
            blocks_used: count,
            window_full: self.closed >= self.block_count,
        })
    }
}
