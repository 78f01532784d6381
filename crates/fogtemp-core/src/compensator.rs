//! The per-sample compensator: model axis + feature tracker + walk hint.

use crate::error::Error;
use crate::features::FeatureTracker;
use crate::mesh::WalkHint;
use crate::model::{Axis, Model};

/// Status bits of one compensated sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Flags(pub u8);

impl Flags {
    /// No features yet (fewer than `min_blocks` blocks since power-on or a gap): the
    /// bias is the last valid one, or zero if there never was one.
    pub const WARMING_UP: Flags = Flags(0x01);
    /// Features exist but the window is not yet full (noisier than in steady state).
    pub const PARTIAL_WINDOW: Flags = Flags(0x02);
    /// The features lie outside the calibrated mesh; the outside policy gave the value.
    pub const OUTSIDE_HULL: Flags = Flags(0x04);
    /// No temperature for longer than the model's `max_gap_s`; the bias is held.
    pub const TEMP_STALE: Flags = Flags(0x08);
    /// This sample's temperature or time was rejected (NaN, not increasing) or the gyro
    /// value is not finite.
    pub const BAD_INPUT: Flags = Flags(0x10);

    /// No bits set.
    pub const fn empty() -> Flags {
        Flags(0)
    }

    /// True if every bit of `other` is set.
    pub const fn contains(self, other: Flags) -> bool {
        self.0 & other.0 == other.0
    }

    /// True if no bit is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
}

impl core::ops::BitOr for Flags {
    type Output = Flags;
    fn bitor(self, rhs: Flags) -> Flags {
        Flags(self.0 | rhs.0)
    }
}

impl core::ops::BitOrAssign for Flags {
    fn bitor_assign(&mut self, rhs: Flags) {
        self.0 |= rhs.0;
    }
}

/// One compensated sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Output {
    /// Compensated rate, deg/h: raw minus `bias_dph`.
    pub rate_dph: f32,
    /// Bias subtracted, deg/h.
    pub bias_dph: f32,
    /// Status of this sample.
    pub flags: Flags,
}

/// Default tracker capacity: enough for the default 100 one-second blocks.
pub const DEFAULT_CAPACITY: usize = 128;

/// Compensates one gyro axis one sample at a time. No allocation; `N` is the feature
/// tracker's block capacity.
///
/// The bias is re-evaluated only when the tracker closes a block (by default once a
/// second), so the per-sample cost is a subtraction plus the tracker's accumulation.
#[derive(Clone, Debug)]
pub struct Compensator<'a, const N: usize = DEFAULT_CAPACITY> {
    axis: Axis<'a>,
    tracker: FeatureTracker<N>,
    hint: WalkHint,
    bias_dph: f32,
    /// Flags that persist between feature updates.
    state_flags: Flags,
}

impl<'a, const N: usize> Compensator<'a, N> {
    /// A compensator for axis `axis_index` of `model`.
    ///
    /// # Errors
    /// [`Error::NoSuchAxis`], or [`Error::CapacityTooSmall`] if the model's `block_count`
    /// exceeds `N`.
    pub fn new(model: &Model<'a>, axis_index: usize) -> Result<Self, Error> {
        let axis = model.axis(axis_index)?;
        Ok(Self {
            tracker: FeatureTracker::new(&axis.features)?,
            axis,
            hint: WalkHint::default(),
            bias_dph: 0.0,
            state_flags: Flags::WARMING_UP,
        })
    }

    /// The model axis in use.
    pub fn axis(&self) -> &Axis<'a> {
        &self.axis
    }

    /// The feature tracker (read-only).
    pub fn tracker(&self) -> &FeatureTracker<N> {
        &self.tracker
    }

    /// The bias currently subtracted, deg/h.
    pub fn bias_dph(&self) -> f32 {
        self.bias_dph
    }

    /// Compensates one sample: `gyro_dph` at `time_us`, with a temperature reading when
    /// one arrived with this sample (`None` for a gyro-only sample).
    pub fn step(&mut self, time_us: u64, gyro_dph: f32, temp_c: Option<f32>) -> Output {
        let mut flags = Flags::empty();
        if let Some(temp_c) = temp_c {
            match self.tracker.push(time_us, temp_c) {
                Ok(outcome) if outcome.updated => self.refresh_bias(),
                Ok(_) => {}
                Err(_) => flags |= Flags::BAD_INPUT,
            }
        }
        let stale =
            self.tracker.last_time_us().is_none_or(|t| time_us.saturating_sub(t) > self.tracker.max_gap_us());
        if stale {
            flags |= Flags::TEMP_STALE;
        }
        if !gyro_dph.is_finite() {
            flags |= Flags::BAD_INPUT;
        }
        Output {
            rate_dph: gyro_dph - self.bias_dph,
            bias_dph: self.bias_dph,
            flags: flags | self.state_flags,
        }
    }

    /// Re-evaluates the model at the tracker's new features.
    #[cold]
    fn refresh_bias(&mut self) {
        let Some(f) = self.tracker.features() else {
            self.state_flags = Flags::WARMING_UP;
            return;
        };
        let mut flags = if f.window_full { Flags::empty() } else { Flags::PARTIAL_WINDOW };
        match self.axis.evaluate(f.temp_c, f.rate_c_per_min, &mut self.hint) {
            Ok(e) => {
                self.bias_dph = e.value_dph;
                if e.outside_hull {
                    flags |= Flags::OUTSIDE_HULL;
                }
            }
            // Reported features are finite; should evaluation still fail, hold the bias.
            Err(_) => flags |= Flags::WARMING_UP,
        }
        self.state_flags = flags;
    }
}
