//! Single-reading temperature spikes: a reading that jumps by more than [`SPIKE_JUMP_C`]
//! from both neighbouring readings, in the same direction, while they lie within the
//! tracker's `max_gap_s` of it. A sensor glitch or a corrupt cell (a 50 C step for one
//! second), not physics: a FOG's temperature changes by at most about 0.7 C/min
//! (docs/physics.md, peak dT/dt of case and coil), so 1 C between readings at most
//! `max_gap_s` (5 s by default) apart is over 15 times that rate, and a real change does not
//! return at the next reading.
//!
//! Why calibration cares: the tracker turns one such reading into a window's worth of
//! (T, dT/dt) features at rates the run never had (-1.7 to +1.9 C/min from one 50 C cell in
//! a run that heats at up to 0.5 C/min), and those points widened the model's stored
//! calibrated region, so the firmware did not flag cooling as outside it. Calibration reads a
//! spike as a missing reading (the tracker bridges it as it bridges a slow sensor's empty
//! cells) and `fit` warns with each spike's line; nothing else of the row changes.
//!
//! Not detected: a spike on a run's first reading (no reading before it), spikes of several
//! readings, and jumps of 1 C or less (their effect on a window's rate is at most the jump
//! over the window).

use std::collections::VecDeque;

use serde::Serialize;

/// Smallest jump from both neighbouring readings that makes a reading a spike, deg C.
pub const SPIKE_JUMP_C: f64 = 1.0;
/// How many spikes per axis and run are listed individually (all are counted).
pub const MAX_LISTED_SPIKES: usize = 20;

/// One spike.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TemperatureSpike {
    /// 1-based line of the reading in the log (the sample index for arrays).
    pub line: u64,
    /// Its time since the run's first row, seconds.
    pub time_s: f64,
    /// The reading, deg C.
    pub temp_c: f64,
    /// The readings before and after it, deg C.
    pub before_c: f64,
    /// See `before_c`.
    pub after_c: f64,
}

impl TemperatureSpike {
    /// `log:line [column ]T C between B and A C`, as the warnings and notes list it.
    pub fn describe(&self, log: &std::path::Path, column: Option<&str>) -> String {
        let column = column.map_or_else(String::new, |c| format!("{c} "));
        format!(
            "{}:{} {column}{:.2} C between {:.2} and {:.2} C",
            log.display(),
            self.line,
            self.temp_c,
            self.before_c,
            self.after_c
        )
    }
}

/// The spikes of one axis of one run.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct AxisSpikes {
    /// All spikes found.
    pub count: u64,
    /// The first [`MAX_LISTED_SPIKES`] of them.
    pub first: Vec<TemperatureSpike>,
}

/// One row as the feature stream takes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Seconds since the run's first row.
    pub time_s: f64,
    /// Gyro, deg/h.
    pub gyro_dph: f64,
    /// Temperature, deg C; NaN when the row has no reading.
    pub temp_c: f64,
    /// 1-based line in the log.
    pub line: u64,
}

/// Passes samples on in order, one reading late: a reading is held (with the rows without a
/// reading after it) until the next reading shows whether it was a spike, or until
/// `max_gap_s` has passed without one (then it cannot be judged and is passed as read).
#[derive(Debug)]
pub struct SpikeGuard {
    max_gap_s: f64,
    /// The last reading passed on as read: (time, deg C).
    previous: Option<(f64, f64)>,
    /// The held reading first, then the rows without a reading that followed it.
    held: VecDeque<Sample>,
    spikes: AxisSpikes,
}

impl SpikeGuard {
    /// A guard judging readings against neighbours at most `max_gap_s` away.
    pub fn new(max_gap_s: f64) -> Self {
        Self { max_gap_s, previous: None, held: VecDeque::new(), spikes: AxisSpikes::default() }
    }

    /// Takes the next row; `out` receives the rows that are decided, in order (a spike with
    /// its temperature NaN).
    pub fn push(&mut self, sample: Sample, out: &mut impl FnMut(Sample)) {
        let Some(&reading) = self.held.front() else {
            if sample.temp_c.is_finite() {
                self.held.push_back(sample);
            } else {
                out(sample);
            }
            return;
        };
        if sample.temp_c.is_finite() {
            let spike_next = self.is_spike(&reading, &sample).then_some(sample.temp_c);
            self.release(spike_next, out);
            self.held.push_back(sample);
        } else if sample.time_s - reading.time_s > self.max_gap_s {
            self.release(None, out);
            out(sample);
        } else {
            self.held.push_back(sample);
        }
    }

    /// Passes on what is still held (the last reading cannot be judged) and returns the
    /// spikes found.
    pub fn finish(mut self, out: &mut impl FnMut(Sample)) -> AxisSpikes {
        self.release(None, out);
        self.spikes
    }

    fn is_spike(&self, reading: &Sample, next: &Sample) -> bool {
        let Some((before_s, before_c)) = self.previous else { return false };
        let near =
            reading.time_s - before_s <= self.max_gap_s && next.time_s - reading.time_s <= self.max_gap_s;
        let rise = reading.temp_c - before_c;
        let fall = reading.temp_c - next.temp_c;
        near && rise * fall > 0.0 && rise.abs().min(fall.abs()) > SPIKE_JUMP_C
    }

    /// Passes on the held rows, the reading first: as read, or as a spike (no reading) when
    /// `spike_next_c` holds the reading after it.
    fn release(&mut self, spike_next_c: Option<f64>, out: &mut impl FnMut(Sample)) {
        let Some(mut reading) = self.held.pop_front() else { return };
        if let Some(after_c) = spike_next_c {
            self.record(&reading, after_c);
            reading.temp_c = f64::NAN;
        } else {
            self.previous = Some((reading.time_s, reading.temp_c));
        }
        out(reading);
        self.held.drain(..).for_each(&mut *out);
    }

    fn record(&mut self, reading: &Sample, after_c: f64) {
        self.spikes.count += 1;
        if self.spikes.first.len() < MAX_LISTED_SPIKES {
            let before_c = self.previous.map_or(f64::NAN, |(_, t)| t);
            self.spikes.first.push(TemperatureSpike {
                line: reading.line,
                time_s: reading.time_s,
                temp_c: reading.temp_c,
                before_c,
                after_c,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples at 1 s with temperatures `temps` (NaN for rows without a reading), gyro = line.
    fn samples(temps: &[f64]) -> Vec<Sample> {
        temps
            .iter()
            .enumerate()
            .map(|(k, &t)| Sample { time_s: k as f64, gyro_dph: k as f64, temp_c: t, line: k as u64 + 2 })
            .collect()
    }

    fn guarded(input: &[Sample], max_gap_s: f64) -> (Vec<Sample>, AxisSpikes) {
        let mut out = Vec::new();
        let mut guard = SpikeGuard::new(max_gap_s);
        input.iter().for_each(|&s| guard.push(s, &mut |s| out.push(s)));
        let spikes = guard.finish(&mut |s| out.push(s));
        (out, spikes)
    }

    /// `expected` with the temperatures at `indices` replaced by NaN.
    fn without_readings(expected: &[Sample], indices: &[usize]) -> Vec<Sample> {
        let mut e = expected.to_vec();
        indices.iter().for_each(|&i| e[i].temp_c = f64::NAN);
        e
    }

    fn same(a: &[Sample], b: &[Sample]) -> bool {
        a.len() == b.len()
            && a.iter().zip(b).all(|(x, y)| {
                x.time_s == y.time_s
                    && x.gyro_dph == y.gyro_dph
                    && x.line == y.line
                    && x.temp_c.to_bits() == y.temp_c.to_bits()
            })
    }

    #[test]
    fn a_reading_that_jumps_and_returns_is_a_spike_and_nothing_else_changes() {
        let ramp: Vec<f64> = (0..10).map(|k| 20.0 + 0.01 * k as f64).collect();
        let mut temps = ramp.clone();
        temps[4] += 50.0;
        let input = samples(&temps);
        let (out, spikes) = guarded(&input, 5.0);
        assert!(same(&out, &without_readings(&input, &[4])));
        assert_eq!(spikes.count, 1);
        let s = spikes.first[0];
        assert_eq!((s.line, s.time_s), (6, 4.0));
        assert_eq!((s.temp_c, s.before_c, s.after_c), (temps[4], ramp[3], ramp[5]));
    }

    #[test]
    fn downward_spikes_count_and_steps_that_stay_do_not() {
        let mut temps = vec![20.0; 12];
        temps[3] = -30.0; // down and back: a spike
        temps[7..].iter_mut().for_each(|t| *t = 30.0); // a step that stays: not one
        let input = samples(&temps);
        let (out, spikes) = guarded(&input, 5.0);
        assert!(same(&out, &without_readings(&input, &[3])));
        assert_eq!(spikes.count, 1);
    }

    #[test]
    fn a_jump_of_exactly_the_limit_or_one_not_back_is_not_a_spike() {
        // Reading 1 is exactly 1 C from both neighbours; reading 4 is 1.5 C above reading 3
        // but only 0.5 C above reading 5.
        let temps = [20.0, 20.0 + SPIKE_JUMP_C, 20.0, 20.0, 21.5, 21.0, 21.0];
        let (out, spikes) = guarded(&samples(&temps), 5.0);
        assert!(same(&out, &samples(&temps)));
        assert_eq!(spikes.count, 0);
        // Just beyond the limit, the same reading is one.
        let temps = [20.0, 20.0 + SPIKE_JUMP_C + 0.01, 20.0, 20.0];
        assert_eq!(guarded(&samples(&temps), 5.0).1.count, 1);
    }

    #[test]
    fn rows_without_a_reading_keep_their_place_and_the_neighbours_are_readings() {
        // A sensor read every third row; the spike's neighbours are two rows away.
        let temps: Vec<f64> = (0..15)
            .map(|k| {
                if k % 3 == 0 {
                    if k == 6 {
                        80.0
                    } else {
                        20.0
                    }
                } else {
                    f64::NAN
                }
            })
            .collect();
        let input = samples(&temps);
        let (out, spikes) = guarded(&input, 5.0);
        assert!(same(&out, &without_readings(&input, &[6])));
        assert_eq!((spikes.count, spikes.first[0].before_c, spikes.first[0].after_c), (1, 20.0, 20.0));
    }

    #[test]
    fn readings_further_apart_than_the_gap_are_not_judged() {
        let mut temps = vec![20.0, f64::NAN, f64::NAN, 70.0, f64::NAN, f64::NAN, 20.0];
        let (out, spikes) = guarded(&samples(&temps), 2.0);
        assert!(same(&out, &samples(&temps)));
        assert_eq!(spikes.count, 0);
        // The same readings within the gap: a spike.
        temps.retain(|t| t.is_finite());
        let (_, spikes) = guarded(&samples(&temps), 2.0);
        assert_eq!(spikes.count, 1);
    }

    #[test]
    fn the_first_and_last_readings_are_passed_as_read() {
        let temps = [90.0, 20.0, 20.0, 20.0, 90.0];
        let (out, spikes) = guarded(&samples(&temps), 5.0);
        assert!(same(&out, &samples(&temps)));
        assert_eq!(spikes.count, 0);
    }

    #[test]
    fn every_spike_is_counted_and_the_first_are_listed() {
        let temps: Vec<f64> = (0..200).map(|k| if k % 4 == 2 { 70.0 } else { 20.0 }).collect();
        let (out, spikes) = guarded(&samples(&temps), 5.0);
        assert_eq!(spikes.count, 50);
        assert_eq!(spikes.first.len(), MAX_LISTED_SPIKES);
        assert_eq!(out.iter().filter(|s| s.temp_c.is_nan()).count(), 50);
    }

    /// Detection only (`validate`, `compensate` give the guard readings alone): the same
    /// spikes as with every row, also where readings are further apart than the gap.
    #[test]
    fn readings_alone_find_the_same_spikes_as_every_row() {
        let temps: Vec<f64> = (0..60)
            .map(|k| match k {
                k if k % 3 != 0 => f64::NAN,
                12 | 45 => 80.0,
                k if (24..36).contains(&k) => f64::NAN, // a 12 s silence: not judged across it
                _ => 20.0,
            })
            .collect();
        let rows = samples(&temps);
        let readings: Vec<Sample> = rows.iter().copied().filter(|s| s.temp_c.is_finite()).collect();
        let (_, every) = guarded(&rows, 5.0);
        let (_, alone) = guarded(&readings, 5.0);
        assert_eq!(every, alone);
        assert_eq!(every.count, 2);
    }
}
