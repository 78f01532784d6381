//! Temperature glitches: readings that jump away and come back faster than a FOG's
//! temperature can move. A sensor glitch or a corrupt cell (a 50 C step for one second, a
//! one-wire sensor's 85 C power-on value), not physics: a FOG's temperature changes by at
//! most about 0.7 C/min (docs/physics.md, peak dT/dt of case and coil).
//!
//! A **glitch** is a run of consecutive readings (one or several: a logger that repeats a
//! slow sensor's value on every row repeats a glitched value too), at most the tracker's
//! `max_gap_s` long, that all lie on the same side of both the reading before and the reading
//! after them by more than [`jump_limit_c`] of the time from the one to the other, with
//! both within `max_gap_s`. The limit is [`SPIKE_JUMP_C`] (1 C), or three times the largest
//! change physics allows over that time when that is more (readings minutes apart: a real
//! bump of a few C is not a glitch). At a run's **start** there is no reading before: the
//! leading readings (at most `max_gap_s` of them) are a glitch when the first reading more
//! than 1 C from them lies beyond the limit from every one of them, and the readings after it
//! stay within 1 C of it, no two more than `max_gap_s` apart, until more than `max_gap_s`
//! after it: longer than a glitch can last, so that level is the real one.
//!
//! Why calibration cares: the tracker turns one such reading into a window's worth of
//! (T, dT/dt) features at rates the run never had (-1.7 to +1.9 C/min from one 50 C cell in
//! a run that heats at up to 0.5 C/min), and those points widened the model's stored
//! calibrated region, so the firmware did not flag cooling as outside it. Calibration reads a
//! glitch's readings as missing (the tracker bridges them as it bridges a slow sensor's empty
//! cells) and `fit` warns with each glitch's lines; nothing else of the row changes.
//!
//! Not detected: glitches longer than `max_gap_s`, a run whose last readings are glitched
//! (no reading after them) or that ends before the level after a glitched start has stayed,
//! and jumps of 1 C or less (their effect on a window's rate is at
//! most the jump over the window).

use std::collections::VecDeque;

use serde::Serialize;

/// Smallest jump from the readings around a glitch that makes it one, deg C.
pub const SPIKE_JUMP_C: f64 = 1.0;
/// The fastest a FOG's temperature changes, deg C per minute: the peak case rate of
/// docs/physics.md (0.67 C/min, the coil's is 0.30).
pub const FASTEST_TEMP_RATE_C_PER_MIN: f64 = 0.67;
/// How many times the fastest physical change over the same time a jump must exceed: room
/// for chambers that ramp faster than the source's.
pub const PHYSICS_MARGIN: f64 = 3.0;
/// How many glitches per axis and run are listed individually (all are counted).
pub const MAX_LISTED_SPIKES: usize = 20;

/// The jump a glitch must exceed when the reading before it and the reading after it are
/// `span_s` apart, deg C: [`SPIKE_JUMP_C`], or [`PHYSICS_MARGIN`] times the largest change
/// physics allows in `span_s` when that is more (from a span of about 30 s).
pub fn jump_limit_c(span_s: f64) -> f64 {
    SPIKE_JUMP_C.max(PHYSICS_MARGIN * FASTEST_TEMP_RATE_C_PER_MIN * span_s / 60.0)
}

/// One glitch.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TemperatureSpike {
    /// 1-based line of its first reading in the log (the sample index for arrays).
    pub line: u64,
    /// 1-based line of its last reading (`line` for a single reading).
    pub last_line: u64,
    /// How many readings it holds.
    pub readings: u64,
    /// The time of its first reading since the run's first row, seconds.
    pub time_s: f64,
    /// Its first reading, deg C.
    pub temp_c: f64,
    /// The reading before it, deg C; NaN at a run's start.
    pub before_c: f64,
    /// The reading after it, deg C.
    pub after_c: f64,
}

impl TemperatureSpike {
    /// `log:line [column ]T C between B and A C`, as the warnings and notes list it (lines
    /// `line-last_line` and the count for several readings; "at the run's start, then A C"
    /// without a reading before).
    pub fn describe(&self, log: &std::path::Path, column: Option<&str>) -> String {
        let column = column.map_or_else(String::new, |c| format!("{c} "));
        let lines = if self.readings > 1 {
            format!(
                "{}-{} {column}{:.2} C ({} readings)",
                self.line, self.last_line, self.temp_c, self.readings
            )
        } else {
            format!("{} {column}{:.2} C", self.line, self.temp_c)
        };
        if self.before_c.is_finite() {
            format!("{}:{lines} between {:.2} and {:.2} C", log.display(), self.before_c, self.after_c)
        } else {
            format!("{}:{lines} at the run's start, then {:.2} C", log.display(), self.after_c)
        }
    }
}

/// The glitches of one axis of one run.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct AxisSpikes {
    /// All glitches found.
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

/// A run of readings that jumped from the reading before it and may be a glitch.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    /// +1 when it jumped up, -1 down.
    direction: f64,
    /// The reading before it: (time, deg C).
    before: (f64, f64),
    /// Its first and last reading's time, seconds.
    first_s: f64,
    last_s: f64,
    /// Its reading nearest the level before and after (the one the limit is checked on).
    nearest_c: f64,
}

impl Candidate {
    fn extended_by(&self, reading: &Sample, max_gap_s: f64) -> bool {
        self.direction * (reading.temp_c - self.before.1) > SPIKE_JUMP_C
            && reading.time_s - self.first_s <= max_gap_s
    }

    fn returns_at(&self, after: &Sample, max_gap_s: f64) -> bool {
        let limit = jump_limit_c(after.time_s - self.before.0);
        after.time_s - self.last_s <= max_gap_s
            && self.direction * (self.nearest_c - self.before.1) > limit
            && self.direction * (self.nearest_c - after.temp_c) > limit
    }
}

/// The run's leading readings while they are being judged.
#[derive(Clone, Copy, Debug)]
struct Leading {
    /// The run's first reading.
    first: Sample,
    /// The last reading before the jump, and the lowest and highest of them, deg C.
    last_s: f64,
    low_c: f64,
    high_c: f64,
    /// The first reading more than 1 C from the first, and how many rows were held before it.
    jump: Option<(Sample, usize)>,
    /// The last reading within 1 C of the jump (the level after it), seconds; the level has
    /// stayed once such a reading comes more than `max_gap_s` after the jump, each within
    /// `max_gap_s` of the one before.
    last_level_s: f64,
}

/// What the leading readings are, once known.
#[derive(Clone, Copy, Debug, PartialEq)]
enum LeadingVerdict {
    /// More rows are needed.
    Open,
    /// Ordinary readings: everything held is judged again as readings with one before them.
    Ordinary,
    /// A glitch: the rows held before the jump have their readings read as missing.
    Glitch,
}

impl Leading {
    fn new(first: Sample) -> Self {
        Self {
            first,
            last_s: first.time_s,
            low_c: first.temp_c,
            high_c: first.temp_c,
            jump: None,
            last_level_s: first.time_s,
        }
    }

    /// Takes the next row (`held_before` rows are held before it).
    fn observe(&mut self, row: &Sample, held_before: usize, max_gap_s: f64) -> LeadingVerdict {
        let Some((jump, _)) = self.jump else { return self.observe_before_jump(row, held_before, max_gap_s) };
        if row.time_s - self.last_level_s > max_gap_s {
            return LeadingVerdict::Ordinary; // the level after the jump was not seen to stay
        }
        if !row.temp_c.is_finite() {
            return LeadingVerdict::Open;
        }
        if (row.temp_c - jump.temp_c).abs() > SPIKE_JUMP_C {
            return LeadingVerdict::Ordinary;
        }
        self.last_level_s = row.time_s;
        if row.time_s - jump.time_s > max_gap_s {
            return self.verdict_on_level();
        }
        LeadingVerdict::Open
    }

    fn observe_before_jump(&mut self, row: &Sample, held_before: usize, max_gap_s: f64) -> LeadingVerdict {
        if row.time_s - self.last_s > max_gap_s {
            return LeadingVerdict::Ordinary; // no reading can be judged against the ones before
        }
        if !row.temp_c.is_finite() {
            return LeadingVerdict::Open;
        }
        if (row.temp_c - self.first.temp_c).abs() > SPIKE_JUMP_C {
            self.jump = Some((*row, held_before));
            self.last_level_s = row.time_s;
            return LeadingVerdict::Open;
        }
        if row.time_s - self.first.time_s > max_gap_s {
            return LeadingVerdict::Ordinary; // a level longer than a glitch
        }
        self.last_s = row.time_s;
        self.low_c = self.low_c.min(row.temp_c);
        self.high_c = self.high_c.max(row.temp_c);
        LeadingVerdict::Open
    }

    /// The verdict once the level after the jump has stayed longer than a glitch can last:
    /// a glitch when every reading before the jump lies beyond the limit from it.
    fn verdict_on_level(&self) -> LeadingVerdict {
        let Some((jump, _)) = self.jump else { return LeadingVerdict::Ordinary };
        let limit = jump_limit_c(jump.time_s - self.first.time_s);
        let away_c = if self.first.temp_c > jump.temp_c {
            self.low_c - jump.temp_c
        } else {
            jump.temp_c - self.high_c
        };
        if away_c > limit {
            LeadingVerdict::Glitch
        } else {
            LeadingVerdict::Ordinary
        }
    }
}

/// Passes samples on in order, holding back what cannot be judged yet: a reading that jumps
/// (with the rows after it) until the readings after show whether it was a glitch, and a
/// run's leading readings until they are judged. A glitch's readings are passed on with
/// temperature NaN; everything else as read.
#[derive(Debug)]
pub struct SpikeGuard {
    max_gap_s: f64,
    /// `false` while the run's leading readings are being judged.
    leading_judged: bool,
    leading: Option<Leading>,
    /// The last reading passed on as read: (time, deg C).
    previous: Option<(f64, f64)>,
    candidate: Option<Candidate>,
    /// The rows held back, in order.
    held: VecDeque<Sample>,
    spikes: AxisSpikes,
}

impl SpikeGuard {
    /// A guard judging readings against neighbours at most `max_gap_s` away.
    pub fn new(max_gap_s: f64) -> Self {
        Self {
            max_gap_s,
            leading_judged: false,
            leading: None,
            previous: None,
            candidate: None,
            held: VecDeque::new(),
            spikes: AxisSpikes::default(),
        }
    }

    /// Takes the next row; `out` receives the rows that are decided, in order (a glitch's
    /// readings with temperature NaN).
    pub fn push(&mut self, sample: Sample, out: &mut impl FnMut(Sample)) {
        if self.leading_judged {
            self.push_judged(sample, out);
        } else {
            self.push_leading(sample, out);
        }
    }

    /// Passes on what is still held (the last readings cannot be judged as a glitch) and
    /// returns the glitches found.
    pub fn finish(mut self, out: &mut impl FnMut(Sample)) -> AxisSpikes {
        if !self.leading_judged {
            self.judge_leading(LeadingVerdict::Ordinary, out); // the level after a jump did not stay
        }
        self.release_as_read(out);
        self.spikes
    }

    fn push_leading(&mut self, sample: Sample, out: &mut impl FnMut(Sample)) {
        let Some(leading) = self.leading.as_mut() else {
            if sample.temp_c.is_finite() {
                self.leading = Some(Leading::new(sample));
                self.held.push_back(sample);
            } else {
                out(sample); // rows before the first reading
            }
            return;
        };
        let verdict = leading.observe(&sample, self.held.len(), self.max_gap_s);
        self.held.push_back(sample);
        if verdict != LeadingVerdict::Open {
            self.judge_leading(verdict, out);
        }
    }

    /// Ends the leading judgement: a glitch's rows are passed on without their readings, and
    /// the rest of what is held is judged again as rows after a reading.
    fn judge_leading(&mut self, verdict: LeadingVerdict, out: &mut impl FnMut(Sample)) {
        self.leading_judged = true;
        let mut rows: Vec<Sample> = self.held.drain(..).collect();
        let mut rest = 0;
        if let (LeadingVerdict::Glitch, Some(Leading { jump: Some((jump, before)), .. })) =
            (verdict, self.leading)
        {
            let glitch = &mut rows[..before];
            self.record(glitch, f64::NAN, jump.temp_c);
            glitch.iter_mut().for_each(|row| row.temp_c = f64::NAN);
            glitch.iter().for_each(|&row| out(row));
            rest = before;
        }
        rows[rest..].iter().for_each(|&row| self.push_judged(row, out));
    }

    fn push_judged(&mut self, sample: Sample, out: &mut impl FnMut(Sample)) {
        let Some(candidate) = self.candidate else {
            self.push_ordinary(sample, out);
            return;
        };
        if !sample.temp_c.is_finite() {
            if sample.time_s - candidate.last_s > self.max_gap_s {
                self.release_as_read(out); // no reading after it can be judged against it
                out(sample);
            } else {
                self.held.push_back(sample);
            }
            return;
        }
        if candidate.extended_by(&sample, self.max_gap_s) {
            let direction = candidate.direction;
            if let Some(c) = self.candidate.as_mut() {
                c.last_s = sample.time_s;
                if direction * sample.temp_c < direction * c.nearest_c {
                    c.nearest_c = sample.temp_c;
                }
            }
            self.held.push_back(sample);
            return;
        }
        if candidate.returns_at(&sample, self.max_gap_s) {
            self.release_as_glitch(candidate.before.1, sample.temp_c, out);
        } else {
            self.release_as_read(out);
        }
        self.push_ordinary(sample, out); // judged afresh against the reading before it
    }

    /// A row while nothing is held back: a reading that jumps from the one before becomes a
    /// candidate; anything else is passed on.
    fn push_ordinary(&mut self, sample: Sample, out: &mut impl FnMut(Sample)) {
        if !sample.temp_c.is_finite() {
            out(sample);
            return;
        }
        match self.previous {
            Some((before_s, before_c))
                if sample.time_s - before_s <= self.max_gap_s
                    && (sample.temp_c - before_c).abs() > SPIKE_JUMP_C =>
            {
                self.candidate = Some(Candidate {
                    direction: (sample.temp_c - before_c).signum(),
                    before: (before_s, before_c),
                    first_s: sample.time_s,
                    last_s: sample.time_s,
                    nearest_c: sample.temp_c,
                });
                self.held.push_back(sample);
            }
            _ => {
                self.previous = Some((sample.time_s, sample.temp_c));
                out(sample);
            }
        }
    }

    /// Passes on the held rows as read; the last held reading becomes the one before.
    fn release_as_read(&mut self, out: &mut impl FnMut(Sample)) {
        self.candidate = None;
        if let Some(last) = self.held.iter().rev().find(|s| s.temp_c.is_finite()) {
            self.previous = Some((last.time_s, last.temp_c));
        }
        self.held.drain(..).for_each(&mut *out);
    }

    /// Passes on the held rows with their readings read as missing.
    fn release_as_glitch(&mut self, before_c: f64, after_c: f64, out: &mut impl FnMut(Sample)) {
        self.candidate = None;
        let mut rows: Vec<Sample> = self.held.drain(..).collect();
        self.record(&rows, before_c, after_c);
        rows.iter_mut().for_each(|row| row.temp_c = f64::NAN);
        rows.into_iter().for_each(&mut *out);
    }

    /// Counts the glitch whose readings are in `rows`, and lists it while fewer than
    /// [`MAX_LISTED_SPIKES`] are.
    fn record(&mut self, rows: &[Sample], before_c: f64, after_c: f64) {
        let mut readings = rows.iter().filter(|s| s.temp_c.is_finite());
        let Some(first) = readings.next() else { return };
        let (count, last) = readings.fold((1, first), |(n, _), s| (n + 1, s));
        self.spikes.count += 1;
        if self.spikes.first.len() < MAX_LISTED_SPIKES {
            self.spikes.first.push(TemperatureSpike {
                line: first.line,
                last_line: last.line,
                readings: count,
                time_s: first.time_s,
                temp_c: first.temp_c,
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

    /// Rows every `step_s` seconds with temperatures `temps`.
    fn samples_every(step_s: f64, temps: &[f64]) -> Vec<Sample> {
        let mut rows = samples(temps);
        rows.iter_mut().for_each(|s| s.time_s *= step_s);
        rows
    }

    #[test]
    fn a_glitch_at_the_start_is_read_as_missing_when_the_level_after_it_stays() {
        // A one-wire sensor's 85 C power-on value for two readings, then 20 C that stays.
        let mut temps = vec![85.0, 85.0];
        temps.extend((0..12).map(|k| 20.0 + 0.01 * k as f64));
        let input = samples(&temps);
        let (out, spikes) = guarded(&input, 5.0);
        assert!(same(&out, &without_readings(&input, &[0, 1])));
        assert_eq!(spikes.count, 1);
        let s = spikes.first[0];
        assert_eq!((s.line, s.last_line, s.readings, s.temp_c, s.after_c), (2, 3, 2, 85.0, 20.0));
        assert!(s.before_c.is_nan());
        assert!(s.describe(std::path::Path::new("r.csv"), None).contains("at the run's start, then 20.00 C"));
    }

    #[test]
    fn a_start_whose_next_level_does_not_stay_is_read_as_read() {
        // 20 C, then 85 C for one reading: the 85 is the glitch (judged with 20 before it),
        // not the start.
        let temps = [20.0, 20.0, 85.0, 20.0, 20.0, 20.0, 20.0, 20.0, 20.0, 20.0];
        let input = samples(&temps);
        let (out, spikes) = guarded(&input, 5.0);
        assert!(same(&out, &without_readings(&input, &[2])));
        assert_eq!((spikes.count, spikes.first[0].before_c, spikes.first[0].after_c), (1, 20.0, 20.0));
        // A start longer than the gap is a level, not a glitch, whatever follows.
        let temps: Vec<f64> = (0..14).map(|k| if k < 7 { 85.0 } else { 20.0 }).collect();
        let (out, spikes) = guarded(&samples(&temps), 5.0);
        assert!(same(&out, &samples(&temps)));
        assert_eq!(spikes.count, 0);
        // The level after the jump not seen to stay longer than a glitch can last (the gap)
        // before the run ends: nothing shows which level is real.
        let temps = [85.0, 20.0, 20.0, 20.0, 20.0, 20.0];
        let (out, spikes) = guarded(&samples(&temps), 5.0);
        assert!(same(&out, &samples(&temps)));
        assert_eq!(spikes.count, 0);
        // One more reading, 5.5 s after the jump: it stayed.
        let mut rows = samples(&temps);
        rows.push(Sample { time_s: 6.5, gyro_dph: 0.0, temp_c: 20.0, line: 99 });
        assert_eq!(guarded(&rows, 5.0).1.count, 1);
    }

    #[test]
    fn the_last_readings_are_passed_as_read() {
        let temps = [20.0, 20.0, 20.0, 20.0, 90.0, 90.0];
        let (out, spikes) = guarded(&samples(&temps), 5.0);
        assert!(same(&out, &samples(&temps)));
        assert_eq!(spikes.count, 0);
    }

    #[test]
    fn a_glitched_value_repeated_on_every_row_is_one_glitch() {
        // 10 rows per second repeat a 1 Hz sensor's value; one glitched conversion repeats
        // for 10 rows (1 s).
        let temps: Vec<f64> =
            (0..100).map(|k| if (40..50).contains(&k) { 70.0 } else { 20.0 + 0.001 * k as f64 }).collect();
        let input = samples_every(0.1, &temps);
        let glitch: Vec<usize> = (40..50).collect();
        let (out, spikes) = guarded(&input, 5.0);
        assert!(same(&out, &without_readings(&input, &glitch)));
        assert_eq!(spikes.count, 1);
        let s = spikes.first[0];
        assert_eq!((s.line, s.last_line, s.readings), (42, 51, 10));
        assert_eq!((s.before_c, s.after_c), (temps[39], temps[50]));
        assert!(s
            .describe(std::path::Path::new("r.csv"), Some("temp_c"))
            .starts_with("r.csv:42-51 temp_c 70.00 C (10 readings) between"));
    }

    #[test]
    fn a_glitch_longer_than_the_gap_or_not_beyond_the_limit_on_every_reading_is_not_one() {
        // Readings at 70 C from 10 s to 16 s (6 s) with a gap of 5 s: a level, not a glitch.
        let temps: Vec<f64> = (0..30).map(|k| if (10..17).contains(&k) { 70.0 } else { 20.0 }).collect();
        let (out, spikes) = guarded(&samples(&temps), 5.0);
        assert!(same(&out, &samples(&temps)));
        assert_eq!(spikes.count, 0);
        // From 10 s to 15 s (5 s, the gap): one glitch of 6 readings.
        let temps: Vec<f64> = (0..30).map(|k| if (10..16).contains(&k) { 70.0 } else { 20.0 }).collect();
        let (_, spikes) = guarded(&samples(&temps), 5.0);
        assert_eq!((spikes.count, spikes.first[0].readings), (1, 6));
        // A run of readings whose last is only 0.5 C above the reading after: not a glitch.
        let temps = [20.0, 20.0, 25.0, 22.0, 21.5, 21.0, 21.0, 21.0];
        let (out, spikes) = guarded(&samples(&temps), 5.0);
        assert!(same(&out, &samples(&temps)));
        assert_eq!(spikes.count, 0);
    }

    #[test]
    fn the_limit_grows_with_the_time_between_readings() {
        // Hand-computed: readings 120 s apart, so the span from the reading before to the one
        // after is 240 s and the limit 3 x 0.67 C/min x 4 min = 8.04 C.
        assert!((jump_limit_c(240.0) - 8.04).abs() < 1e-12);
        assert_eq!(jump_limit_c(2.0), SPIKE_JUMP_C);
        let gap_s = 300.0;
        // A 5 C bump over 4 minutes: physics allows it.
        let temps = [20.0, 20.0, 25.0, 20.0, 20.0];
        let (out, spikes) = guarded(&samples_every(120.0, &temps), gap_s);
        assert!(same(&out, &samples_every(120.0, &temps)));
        assert_eq!(spikes.count, 0);
        // 8.1 C is beyond it; 8.0 C is not.
        assert_eq!(guarded(&samples_every(120.0, &[20.0, 20.0, 28.1, 20.0, 20.0]), gap_s).1.count, 1);
        assert_eq!(guarded(&samples_every(120.0, &[20.0, 20.0, 28.0, 20.0, 20.0]), gap_s).1.count, 0);
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
                0 | 3 => 85.0,                          // a glitch at the start
                18 | 45 | 48 => 80.0,                   // one reading, and two
                k if (24..36).contains(&k) => f64::NAN, // a 12 s silence: not judged across it
                _ => 20.0,
            })
            .collect();
        let rows = samples(&temps);
        let readings: Vec<Sample> = rows.iter().copied().filter(|s| s.temp_c.is_finite()).collect();
        let (_, every) = guarded(&rows, 5.0);
        let (_, alone) = guarded(&readings, 5.0);
        assert_eq!(format!("{every:?}"), format!("{alone:?}")); // NaN before the start
        assert_eq!(every.count, 3);
        let lines: Vec<(u64, u64)> = every.first.iter().map(|s| (s.line, s.last_line)).collect();
        assert_eq!(lines, [(2, 5), (20, 20), (47, 50)]);
    }
}
