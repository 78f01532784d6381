//! What `Model.compensate` says about its input as warnings, where `fogtemp-cal compensate`
//! (which reads a log) notes or refuses the same: time that goes back, and temperature
//! glitches. Samples are named by their 0-based index, as Python indexes the arrays.

use std::path::Path;

use fogtemp_cal::calibrate;
use fogtemp_cal::spikes::{AxisSpikes, Sample, SpikeGuard, MAX_LISTED_SPIKES};

/// The note for time stamps that go back (review20 F3: two runs joined with `pd.concat`
/// were compensated without a word, while `validate()` and the command line refuse them).
/// `None` when the time never goes back. The output stays as the firmware's compensator
/// gives it: a step back longer than its max gap restarts its tracker; a shorter one has
/// its temperature readings rejected (flag BAD_INPUT) until the time passes the old one.
pub fn backward_time_note(name: &str, time_s: &[f64], max_gap_s: f64) -> Option<String> {
    let mut back = (1..time_s.len()).filter(|&k| time_s[k] < time_s[k - 1]);
    let first = back.next()?;
    let more = back.count();
    let (before_s, at_s) = (time_s[first - 1], time_s[first]);
    let did = if before_s - at_s > max_gap_s {
        format!(
            "the compensator restarted there (flag WARMING_UP until its tracker has features again), as \
             the firmware's does after a step back longer than the model's max gap of {max_gap_s} s"
        )
    } else {
        format!(
            "the compensator rejected the temperature readings (flag BAD_INPUT) until the time passed \
             the old one, as the firmware's does after a step back within the model's max gap of {max_gap_s} s"
        )
    };
    let after = first + 1;
    // One stamp out of line: the time after it is past the time before it again.
    let single = more == 0 && time_s.get(after).is_some_and(|&t| t > before_s);
    Some(if single {
        format!(
            "{name}: the time goes back at sample {first}: time_s[{first}] = {at_s} is before time_s[{}] = \
             {before_s}, and time_s[{after}] is after it again: one corrupted stamp? ({did}; a gap noted \
             before sample {after} is its step forward.) fogtemp.validate() refuses such arrays: correct \
             or drop that sample",
            first - 1
        )
    } else {
        let more = match more {
            0 => String::new(),
            1 => ", and at 1 more sample".to_string(),
            n => format!(", and at {n} more samples"),
        };
        format!(
            "{name}: the time goes back at sample {first} (time_s[{first}] = {at_s} is before time_s[{}] = \
             {before_s}){more}: a logger restart, or two runs joined (pd.concat)? {}. fogtemp.validate() \
             and fogtemp-cal compensate refuse such a log: compensate each run on its own (split the arrays \
             at sample {first})",
            first - 1,
            capitalised(&did)
        )
    })
}

/// `text` with its first letter a capital, to start a sentence.
fn capitalised(text: &str) -> String {
    let mut chars = text.chars();
    chars.next().map_or_else(String::new, |first| first.to_uppercase().chain(chars).collect())
}

/// The temperature glitches `fogtemp-cal compensate` notes (review20 F7), found by the
/// library's [`SpikeGuard`] over the readings a sensor can give (the compensator flags the
/// others BAD_INPUT), with the sample index as the line. A step back in time starts a new
/// guard, as it starts a new run for the compensator (it restarts or rejects there).
pub fn temperature_glitches(time_s: &[f64], gyro_dph: &[f64], temp_c: &[f64], max_gap_s: f64) -> AxisSpikes {
    let mut found = AxisSpikes::default();
    let mut guard = SpikeGuard::new(max_gap_s);
    let origin_s = time_s.first().copied().unwrap_or(0.0);
    for (k, ((&t, &g), &c)) in time_s.iter().zip(gyro_dph).zip(temp_c).enumerate() {
        if k > 0 && t < time_s[k - 1] {
            let ended = std::mem::replace(&mut guard, SpikeGuard::new(max_gap_s));
            add_spikes(&mut found, ended.finish(&mut |_| {}));
        }
        if c.is_finite() && fogtemp_core::is_physical_temperature(c as f32) {
            let sample = Sample { time_s: t - origin_s, gyro_dph: g, temp_c: c, line: k as u64 };
            guard.push(sample, &mut |_| {});
        }
    }
    add_spikes(&mut found, guard.finish(&mut |_| {}));
    found
}

/// `more` counted into `found`, its glitches listed up to the library's limit.
fn add_spikes(found: &mut AxisSpikes, more: AxisSpikes) {
    found.count += more.count;
    let room = MAX_LISTED_SPIKES.saturating_sub(found.first.len());
    found.first.extend(more.first.into_iter().take(room));
}

/// The command line's glitch note for axis `name`, its samples named `sample:INDEX`.
pub fn temperature_glitch_note(name: &str, spikes: &AxisSpikes) -> Option<String> {
    calibrate::temperature_spike_note(name, Path::new("sample"), spikes)
}
