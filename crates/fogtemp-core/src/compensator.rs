//! The per-sample compensator, configuration apart from state (the habit of `idsp`):
//! the [`Axis`] is immutable configuration borrowed from the model; [`AxisState`] (feature
//! tracker, walk hint, held bias, flags, wrapping-clock extension) is a plain value the
//! caller owns, so it can live in a `static` or a C struct:
//! `axis.step(&mut state, time_us, gyro_dph, temp_c)`. [`Compensator`] bundles the two.

use crate::error::Error;
use crate::features::{BlockStorage, BlockTracker, FeatureTracker};
use crate::mesh::WalkHint;
use crate::model::{Axis, Model};

/// Status bits of one compensated sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Flags(pub u8);

/// The lowest temperature a sensor can read, deg C: absolute zero.
pub const MIN_PHYSICAL_TEMP_C: f32 = -273.15;
/// The highest temperature taken as a reading, deg C: a gyro does not survive it (its
/// aluminium housing melts at 660 C), so a larger value is a fault or a sentinel, not a
/// temperature.
pub const MAX_PHYSICAL_TEMP_C: f32 = 1000.0;

/// Whether `temp_c` can be a sensor's reading: finite and within
/// [`MIN_PHYSICAL_TEMP_C`, `MAX_PHYSICAL_TEMP_C`]. The compensator flags any other sample
/// `BAD_INPUT` and leaves it out of the features; calibration's ingest refuses it as a bad row.
#[inline]
pub fn is_physical_temperature(temp_c: f32) -> bool {
    (MIN_PHYSICAL_TEMP_C..=MAX_PHYSICAL_TEMP_C).contains(&temp_c)
}

impl Flags {
    /// No features yet (fewer than `min_blocks` blocks since power-on or a gap): the
    /// bias is the last valid one, or zero if there never was one.
    pub const WARMING_UP: Flags = Flags(0x01);
    /// Features exist but the window is not yet full (noisier than in steady state).
    pub const PARTIAL_WINDOW: Flags = Flags(0x02);
    /// The features lie outside the calibrated region (blob format 2) or the mesh's hull: a
    /// polynomial is held at (or continued from) the region's boundary, a mesh outside its
    /// hull gives its outside policy's value, and inside its hull but outside the region its
    /// interpolation between nodes that only partial tracker windows reached.
    pub const OUTSIDE_HULL: Flags = Flags(0x04);
    /// No temperature for longer than the model's `max_gap_s`; the bias is held.
    pub const TEMP_STALE: Flags = Flags(0x08);
    /// This sample's temperature or time was rejected (NaN, not a physical temperature,
    /// a time not increasing by a step back within `max_gap_s`) or the gyro value is not
    /// finite.
    pub const BAD_INPUT: Flags = Flags(0x10);

    /// Every flag with its name, in bit order (for bindings and reports).
    pub const NAMED: [(&'static str, Flags); 5] = [
        ("WARMING_UP", Flags::WARMING_UP),
        ("PARTIAL_WINDOW", Flags::PARTIAL_WINDOW),
        ("OUTSIDE_HULL", Flags::OUTSIDE_HULL),
        ("TEMP_STALE", Flags::TEMP_STALE),
        ("BAD_INPUT", Flags::BAD_INPUT),
    ];

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

/// Extends a wrapping 32-bit microsecond timer (71.6 min period) to 64 bits.
///
/// Each call adds the wrapping difference from the previous sample, as a signed 32-bit
/// number, to the previous sample's 64-bit time, so a wrap between two samples is seamless
/// and a time that goes backwards stays backwards (the sample is then rejected like any
/// non-increasing time, or restarts the tracker when the step back is longer than the gap
/// limit, as with [`Axis::step`]). Samples must therefore be less than 2^31 us (35.8 min)
/// apart.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WrappingClock {
    /// Last raw 32-bit time and its 64-bit extension; `None` before the first sample.
    last: Option<(u32, u64)>,
}

impl WrappingClock {
    /// A clock that has seen no sample.
    pub const fn new() -> Self {
        Self { last: None }
    }

    /// The 64-bit time of `time_us` (the first sample maps to itself): the previous
    /// sample's plus the signed difference, at least 0. The clock follows every sample,
    /// backward ones too, so the samples after a step back count from it. (Until
    /// 2026-11-27 it followed forward steps only: after a step back early in a run, every
    /// later time was pinned at 0 and rejected until the timer caught up with the old
    /// time, up to half an hour, where `step` restarts at once.)
    pub fn extend(&mut self, time_us: u32) -> u64 {
        let Some((last32, last64)) = self.last else {
            self.last = Some((time_us, u64::from(time_us)));
            return u64::from(time_us);
        };
        let delta = time_us.wrapping_sub(last32) as i32;
        let t = if delta >= 0 {
            last64.saturating_add(u64::from(delta.unsigned_abs()))
        } else {
            last64.saturating_sub(u64::from(delta.unsigned_abs()))
        };
        self.last = Some((time_us, t));
        t
    }
}

/// The mutable half of a compensator, owned by the caller: the feature tracker (block
/// means in `S`), the walk hint, the bias held between feature updates, the persistent
/// flags and the wrapping-clock extension. Use it with the [`Axis`] that created it
/// ([`Axis::state`], [`Axis::state_in`]); any value is memory-safe with any axis (a foreign
/// hint is clamped), but the features follow the settings it was created with.
///
/// `S` is `[f32; N]` for a state with its blocks inside (`AxisState<[f32; 100]>`), or any
/// other [`BlockStorage`].
#[derive(Clone, Debug)]
pub struct AxisState<S = [f32; DEFAULT_CAPACITY]> {
    tracker: BlockTracker<S>,
    hint: WalkHint,
    bias_dph: f32,
    /// Flags that persist between feature updates.
    state_flags: Flags,
    clock: WrappingClock,
}

impl<S: BlockStorage> AxisState<S> {
    /// Forgets everything, as at power-on: tracker, walk hint, held bias (0), flags
    /// (`WARMING_UP`) and the wrapping clock. The settings stay.
    pub fn reset(&mut self) {
        self.tracker.reset();
        self.hint = WalkHint::default();
        self.bias_dph = 0.0;
        self.state_flags = Flags::WARMING_UP;
        self.clock = WrappingClock::new();
    }

    /// The feature tracker (read-only).
    pub fn tracker(&self) -> &BlockTracker<S> {
        &self.tracker
    }

    /// Whether this state's tracker has `axis`'s block count and readiness (a state made for
    /// an axis with other settings would compute other features); see [`BlockTracker::is_for`].
    #[inline]
    pub fn is_for(&self, axis: &Axis<'_>) -> bool {
        self.tracker.is_for(&axis.features)
    }

    /// The bias currently subtracted, deg/h.
    pub fn bias_dph(&self) -> f32 {
        self.bias_dph
    }

    /// The walk hint (the triangle of the last mesh evaluation).
    pub fn hint(&self) -> WalkHint {
        self.hint
    }

    /// Sets the walk hint (any value is safe: an out-of-range hint is clamped at the next
    /// walk). For callers that evaluate the axis themselves with this state's hint.
    pub fn set_hint(&mut self, hint: WalkHint) {
        self.hint = hint;
    }
}

impl<'a> Axis<'a> {
    /// A fresh state for this axis with `N` blocks inside: `axis.state::<100>()`.
    ///
    /// # Errors
    /// [`Error::CapacityTooSmall`] if `N` is below [`Axis::blocks_needed`].
    pub fn state<const N: usize>(&self) -> Result<AxisState<[f32; N]>, Error> {
        self.state_in([f32::NAN; N])
    }

    /// A fresh state for this axis keeping its block means in `storage` (at least
    /// [`Axis::blocks_needed`] entries).
    ///
    /// # Errors
    /// [`Error::CapacityTooSmall`] naming the blocks needed and the storage's length;
    /// [`Error::BadValue`] (naming this axis) for settings a validated model cannot hold.
    pub fn state_in<S: BlockStorage>(&self, storage: S) -> Result<AxisState<S>, Error> {
        Ok(AxisState {
            tracker: BlockTracker::with_storage(&self.features, storage).map_err(|e| e.at_axis(self.id))?,
            hint: WalkHint::default(),
            bias_dph: 0.0,
            state_flags: Flags::WARMING_UP,
            clock: WrappingClock::new(),
        })
    }

    /// Compensates one sample: `gyro_dph` at `time_us` (a 64-bit microsecond count that
    /// never wraps), with a temperature reading when one arrived with this sample (`None`
    /// for a gyro-only sample).
    ///
    /// Cost: a subtraction and the tracker's accumulation, plus at a block close the
    /// feature fit (O(`block_count`)) and one model evaluation (a walk from the last
    /// triangle; see `docs/c-api.md` for the measured worst case).
    #[inline]
    pub fn step<S: BlockStorage>(
        &self,
        state: &mut AxisState<S>,
        time_us: u64,
        gyro_dph: f32,
        temp_c: Option<f32>,
    ) -> Output {
        let mut flags = Flags::empty();
        if let Some(temp_c) = temp_c {
            if !is_physical_temperature(temp_c) {
                // No sensor reads this (a logger's -999 for "missing", a corrupted word):
                // one such sample would spoil a whole window's features.
                flags |= Flags::BAD_INPUT;
            } else {
                match state.tracker.push(time_us, temp_c) {
                    Ok(outcome) if outcome.updated => self.refresh_bias(state),
                    Ok(_) => {}
                    Err(_) => flags |= Flags::BAD_INPUT,
                }
            }
        }
        let stale = state
            .tracker
            .last_time_us()
            .is_none_or(|t| time_us.saturating_sub(t) > state.tracker.max_gap_us());
        if stale {
            flags |= Flags::TEMP_STALE;
        }
        if !gyro_dph.is_finite() {
            flags |= Flags::BAD_INPUT;
        }
        Output {
            rate_dph: gyro_dph - state.bias_dph,
            bias_dph: state.bias_dph,
            flags: flags | state.state_flags,
        }
    }

    /// [`Axis::step`] with the time from a wrapping 32-bit microsecond timer (it wraps
    /// every 71.6 min): extended to 64 bits by the state's [`WrappingClock`], so the wrap is
    /// seamless. Consecutive calls must be less than 2^31 us (35.8 min) apart; a time that
    /// goes backwards is rejected as with `step`, and a step back longer than the gap limit
    /// restarts the tracker as with `step`. Use either `step` or `step_u32` on one state.
    #[inline]
    pub fn step_u32<S: BlockStorage>(
        &self,
        state: &mut AxisState<S>,
        time_us: u32,
        gyro_dph: f32,
        temp_c: Option<f32>,
    ) -> Output {
        let time_us = state.clock.extend(time_us);
        self.step(state, time_us, gyro_dph, temp_c)
    }

    /// Re-evaluates the model at the tracker's new features.
    #[cold]
    fn refresh_bias<S: BlockStorage>(&self, state: &mut AxisState<S>) {
        let Some(f) = state.tracker.features() else {
            state.state_flags = Flags::WARMING_UP;
            return;
        };
        let mut flags = if f.window_full { Flags::empty() } else { Flags::PARTIAL_WINDOW };
        match self.evaluate(f.temp_c, f.rate_c_per_min, &mut state.hint) {
            Ok(e) => {
                state.bias_dph = e.value_dph;
                if e.outside_hull {
                    flags |= Flags::OUTSIDE_HULL;
                }
            }
            // Reported features are finite; should evaluation still fail, hold the bias.
            Err(_) => flags |= Flags::WARMING_UP,
        }
        state.state_flags = flags;
    }
}

/// Compensates one gyro axis one sample at a time: an [`Axis`] and its [`AxisState`] in one
/// value. No allocation; `N` is the feature tracker's block capacity.
///
/// The bias is re-evaluated only when the tracker closes a block (by default once a
/// second), so the per-sample cost is a subtraction plus the tracker's accumulation.
#[derive(Clone, Debug)]
pub struct Compensator<'a, const N: usize = DEFAULT_CAPACITY> {
    axis: Axis<'a>,
    state: AxisState<[f32; N]>,
}

impl<'a, const N: usize> Compensator<'a, N> {
    /// A compensator for axis `axis_index` of `model`.
    ///
    /// # Errors
    /// [`Error::NoSuchAxis`], or [`Error::CapacityTooSmall`] if the model's `block_count`
    /// ([`Axis::blocks_needed`]) exceeds `N`.
    pub fn new(model: &Model<'a>, axis_index: usize) -> Result<Self, Error> {
        let axis = model.axis(axis_index)?;
        Ok(Self { state: axis.state::<N>()?, axis })
    }

    /// The model axis in use.
    pub fn axis(&self) -> &Axis<'a> {
        &self.axis
    }

    /// The state (read-only).
    pub fn state(&self) -> &AxisState<[f32; N]> {
        &self.state
    }

    /// The feature tracker (read-only).
    pub fn tracker(&self) -> &FeatureTracker<N> {
        &self.state.tracker
    }

    /// The bias currently subtracted, deg/h.
    pub fn bias_dph(&self) -> f32 {
        self.state.bias_dph
    }

    /// Forgets everything, as at power-on ([`AxisState::reset`]).
    pub fn reset(&mut self) {
        self.state.reset();
    }

    /// Compensates one sample: `gyro_dph` at `time_us`, with a temperature reading when
    /// one arrived with this sample (`None` for a gyro-only sample). [`Axis::step`].
    #[inline]
    pub fn step(&mut self, time_us: u64, gyro_dph: f32, temp_c: Option<f32>) -> Output {
        self.axis.step(&mut self.state, time_us, gyro_dph, temp_c)
    }

    /// [`Compensator::step`] with a wrapping 32-bit microsecond timer ([`Axis::step_u32`]).
    #[inline]
    pub fn step_u32(&mut self, time_us: u32, gyro_dph: f32, temp_c: Option<f32>) -> Output {
        self.axis.step_u32(&mut self.state, time_us, gyro_dph, temp_c)
    }
}
