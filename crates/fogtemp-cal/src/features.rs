//! Calibration features, computed by the firmware's own [`FeatureTracker`] so that
//! calibration and compensation see identical T and dT/dt.
//!
//! For every feature update (one per closed block) the calibration records the features
//! and the mean gyro over the samples that follow until the next update: exactly the
//! samples the firmware compensates with those features.

use fogtemp_core::{FeatureSettings, FeatureTracker};

use crate::error::{CalError, EncodeProblem};

/// Tracker capacity used in calibration: the format's maximum block count.
pub const CAL_CAPACITY: usize = fogtemp_core::wire::MAX_BLOCKS as usize;

/// Seconds since the run start to whole microseconds (negative times clamp to 0).
pub fn micros(time_s: f64) -> u64 {
    (time_s * 1.0e6).round().max(0.0) as u64
}

/// One feature update of one axis, with the gyro it applies to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeaturePoint {
    /// Feature time, seconds since the start of the run.
    pub time_s: f64,
    /// Smoothed temperature, deg C.
    pub temp_c: f64,
    /// Temperature rate, deg C/min.
    pub rate_c_per_min: f64,
    /// The tracker's window was full.
    pub window_full: bool,
    /// Mean gyro over the samples this feature compensates, deg/h (NaN if none).
    pub gyro_mean_dph: f64,
    /// Gyro samples in that mean.
    pub gyro_samples: u32,
    /// Segment number: increments at every tracker restart (a gap in temperature).
    pub segment: u32,
}

#[cfg(test)]
impl FeaturePoint {
    /// A full-window point at `(temp_c, rate_c_per_min)`, nothing else set: the unit tests'.
    pub(crate) fn at(temp_c: f64, rate_c_per_min: f64) -> Self {
        Self {
            time_s: 0.0,
            temp_c,
            rate_c_per_min,
            window_full: true,
            gyro_mean_dph: 0.0,
            gyro_samples: 1,
            segment: 0,
        }
    }
}

/// Feature extraction for one axis of one run, fed row by row.
pub struct AxisFeatureStream {
    tracker: Box<FeatureTracker<CAL_CAPACITY>>,
    points: Vec<FeaturePoint>,
    gyro_sum_dph: f64,
    gyro_samples: u32,
    segment: u32,
    /// Rows whose temperature the tracker rejected (cannot happen after ingest checks,
    /// counted rather than dropped silently).
    pub rejected_temps: u64,
}

impl AxisFeatureStream {
    /// A stream with the given tracker settings.
    ///
    /// # Errors
    /// [`CalError::Encode`] if the settings are outside what the blob can carry.
    pub fn new(settings: &FeatureSettings) -> Result<Self, CalError> {
        let tracker =
            FeatureTracker::new(settings).map_err(|e| CalError::Encode(EncodeProblem::FeatureSettings(e)))?;
        Ok(Self {
            tracker: Box::new(tracker),
            points: Vec::new(),
            gyro_sum_dph: 0.0,
            gyro_samples: 0,
            segment: 0,
            rejected_temps: 0,
        })
    }

    /// Feeds one sample: time since run start (s), gyro (deg/h), temperature (deg C, NaN
    /// when this row has none).
    pub fn push(&mut self, time_s: f64, gyro_dph: f64, temp_c: f64) {
        if temp_c.is_finite() {
            let time_us = micros(time_s);
            match self.tracker.push(time_us, temp_c as f32) {
                Ok(outcome) if outcome.updated => {
                    self.close_point();
                    if outcome.restarted {
                        self.segment += 1;
                    }
                    if let Some(f) = self.tracker.features() {
                        self.points.push(FeaturePoint {
                            time_s: f.time_us as f64 * 1.0e-6,
                            temp_c: f64::from(f.temp_c),
                            rate_c_per_min: f64::from(f.rate_c_per_min),
                            window_full: f.window_full,
                            gyro_mean_dph: f64::NAN,
                            gyro_samples: 0,
                            segment: self.segment,
                        });
                    }
                }
                Ok(_) => {}
                Err(_) => self.rejected_temps += 1,
            }
        }
        if !self.points.is_empty() {
            self.gyro_sum_dph += gyro_dph;
            self.gyro_samples += 1;
        }
    }

    fn close_point(&mut self) {
        if let Some(last) = self.points.last_mut() {
            if self.gyro_samples > 0 && last.gyro_samples == 0 {
                last.gyro_mean_dph = self.gyro_sum_dph / f64::from(self.gyro_samples);
                last.gyro_samples = self.gyro_samples;
            }
        }
        self.gyro_sum_dph = 0.0;
        self.gyro_samples = 0;
    }

    /// Ends the run and returns its feature points.
    pub fn finish(mut self) -> Vec<FeaturePoint> {
        self.close_point();
        self.points
    }
}

/// Centred moving average of `gyro_mean_dph` over `window_s`, within each segment,
/// weighted by sample counts: the smoothed bias target the models are fitted to (the
/// paper smooths the gyro over 100 s). Points without gyro samples get NaN.
pub fn smoothed_gyro_dph(points: &[FeaturePoint], window_s: f64) -> Vec<f64> {
    let half = window_s / 2.0;
    let mut out = vec![f64::NAN; points.len()];
    let (mut lo, mut hi) = (0usize, 0usize);
    let (mut sum, mut count) = (0.0f64, 0u64);
    for (i, p) in points.iter().enumerate() {
        // Grow the window to the right.
        while hi < points.len() && points[hi].segment == p.segment && points[hi].time_s <= p.time_s + half {
            if points[hi].gyro_samples > 0 {
                sum += points[hi].gyro_mean_dph * f64::from(points[hi].gyro_samples);
                count += u64::from(points[hi].gyro_samples);
            }
            hi += 1;
        }
        // Shrink from the left (other segment or too old).
        while lo < i && (points[lo].segment != p.segment || points[lo].time_s < p.time_s - half) {
            if points[lo].gyro_samples > 0 {
                sum -= points[lo].gyro_mean_dph * f64::from(points[lo].gyro_samples);
                count -= u64::from(points[lo].gyro_samples);
            }
            lo += 1;
        }
        if count > 0 {
            out[i] = sum / count as f64;
        }
    }
    out
}
