//! Units that a log's column names give (`time (ms)`, `gyrox rad/s`, `temp_k`), checked
//! against the units the columns are read in: a real log's header often says its units, and a
//! unit left at its default (seconds, deg/h, deg C) then reads the values wrongly without an
//! error (rad/s read as deg/h is 206,265 times too small; kelvin passes as a hot deg C). A
//! name is no proof of a unit, so these are warnings, said before the logs are read.

use crate::axis_columns::OptionNames;
use crate::ingest::{LogFormat, RateUnit, TimeUnit};

/// The warnings for `format`'s time, gyro and temperature columns whose names give another
/// unit than the one they are read in; `options` names the settings (the command line's or
/// Python's, as [`crate::axis_columns::CLI_OPTIONS`]).
pub fn unit_name_notes(format: &LogFormat, options: OptionNames<'_>) -> Vec<String> {
    let [_, _, gyro_units, temp_units, time_options, _, _] = options;
    let mut notes = Vec::new();
    if format.sample_rate_hz.is_none() {
        if let (Some(named), Some(read)) =
            (time_unit_in_name(&format.time_column), time_unit_read(format.time_unit))
        {
            if named != read {
                notes.push(format!(
                    "the time column '{}' says {named} in its name but is read in {read}: if its times are in \
                     {named}, give the unit ({time_options})",
                    format.time_column
                ));
            }
        }
    }
    // A gyro read with a scale is taken as converted when the scale keeps it within a factor
    // [`SCALE_TOLERANCE`] of the unit its name gives (psim-tvc's rad/s x 0.5); beyond that the
    // name and the reading disagree by orders of magnitude (a model fitted in deg/s replayed
    // on a deg/h column: review23b F2, 3600 times too large, said nowhere).
    let read_dph_per_unit = format.gyro_unit.dph() * format.gyro_scale;
    let read = if format.gyro_scale == 1.0 {
        rate_unit_text(format.gyro_unit).to_string()
    } else {
        format!("{} deg/h per unit", read_dph_per_unit as f32)
    };
    for column in &format.gyro_columns {
        let Some(named) = rate_unit_in_name(column) else { continue };
        // The size only: a negative scale turns an axis mounted the other way round, which is
        // no unit (review25a 4).
        let ratio = (read_dph_per_unit / named.dph()).abs();
        if (1.0 / SCALE_TOLERANCE..=SCALE_TOLERANCE).contains(&ratio) {
            continue;
        }
        notes.push(format!(
            "the gyro column '{column}' says {} in its name but is read in {read}: if it is in {}, give the \
             unit ({gyro_units})",
            rate_unit_text(named),
            rate_unit_text(named)
        ));
    }
    let as_read = format.temp_scale == 1.0 && format.temp_offset_c == 0.0;
    for column in format.temp_columns.iter().filter(|_| as_read) {
        if let Some((named, conversion)) = temperature_unit_in_name(column) {
            notes.push(format!(
                "the temperature column '{column}' says {named} in its name but is read in deg C as it is: if it \
                 is in {named}, convert it ({temp_units}: {conversion})"
            ));
        }
    }
    notes
}

/// How far a gyro scale may take the reading from the unit the column's name gives before
/// the two are said to disagree: the units themselves differ by 3600 (deg/h, deg/s) and 57.3
/// (deg/s, rad/s), a scale for counts or a half-range (psim-tvc's 0.5) by less.
const SCALE_TOLERANCE: f64 = 10.0;

/// Lower-case words of a name: runs of ASCII letters (`Time (ms)` -> `time`, `ms`).
pub(crate) fn words(name: &str) -> Vec<String> {
    name.to_ascii_lowercase()
        .split(|c: char| !c.is_ascii_alphabetic())
        .filter(|w| !w.is_empty())
        .map(str::to_string)
        .collect()
}

/// The one time unit a name gives among its words, or `None` (none, or several).
fn time_unit_in_name(name: &str) -> Option<&'static str> {
    let unit = |w: &str| match w {
        "s" | "sec" | "secs" | "second" | "seconds" => Some("s"),
        "ms" | "msec" | "msecs" | "millis" | "millisecond" | "milliseconds" => Some("ms"),
        "us" | "usec" | "usecs" | "micros" | "microsecond" | "microseconds" => Some("us"),
        "ns" | "nsec" | "nsecs" | "nanos" | "nanosecond" | "nanoseconds" => Some("ns"),
        "min" | "mins" | "minute" | "minutes" => Some("min"),
        "h" | "hr" | "hrs" | "hour" | "hours" => Some("h"),
        _ => None,
    };
    // The micro sign (micro or Greek mu) is no ASCII letter: `t (µs)` is read as `t (us)`.
    let name = name.replace(['\u{b5}', '\u{3bc}'], "u");
    let mut found: Vec<&'static str> = words(&name).iter().filter_map(|w| unit(w)).collect();
    found.dedup();
    match found.as_slice() {
        [one] => Some(one),
        _ => None,
    }
}

fn time_unit_read(unit: TimeUnit) -> Option<&'static str> {
    match unit {
        TimeUnit::Seconds => Some("s"),
        TimeUnit::Milliseconds => Some("ms"),
        TimeUnit::Microseconds => Some("us"),
        TimeUnit::Nanoseconds => Some("ns"),
        TimeUnit::Minutes => Some("min"),
        TimeUnit::Hours => Some("h"),
        TimeUnit::DateTime | TimeUnit::TimeOfDay => None,
    }
}

fn rate_unit_text(unit: RateUnit) -> &'static str {
    match unit {
        RateUnit::DegPerHour => "deg/h",
        RateUnit::DegPerSecond => "deg/s",
        RateUnit::RadPerSecond => "rad/s",
    }
}

/// The one angular-rate unit a name gives (`rad/s`, `rps`, `deg/s`, `dps`, `deg/h`, `dph`,
/// `°/s`), or `None`: none, several, or one with a prefix this reader has no unit for
/// (`mdps`, `mrad/s`).
fn rate_unit_in_name(name: &str) -> Option<RateUnit> {
    let lower = name.to_ascii_lowercase();
    let word = |w: &str| match w {
        "rps" | "rads" | "radps" => Some(RateUnit::RadPerSecond),
        "dps" | "degs" | "degps" => Some(RateUnit::DegPerSecond),
        "dph" | "degh" | "degph" => Some(RateUnit::DegPerHour),
        _ => None,
    };
    let mut found: Vec<RateUnit> = words(name).iter().filter_map(|w| word(w)).collect();
    for (text, unit) in [
        ("rad/s", RateUnit::RadPerSecond),
        ("deg/s", RateUnit::DegPerSecond),
        ("\u{b0}/s", RateUnit::DegPerSecond),
        ("deg/h", RateUnit::DegPerHour),
        ("\u{b0}/h", RateUnit::DegPerHour),
    ] {
        for (at, _) in lower.match_indices(text) {
            let prefixed = lower[..at].ends_with(['m', 'u', '\u{b5}', 'k']);
            if prefixed {
                return None;
            }
            found.push(unit);
        }
    }
    found.dedup();
    match found.as_slice() {
        [one] => Some(*one),
        _ => None,
    }
}

/// A temperature unit other than deg C that a name gives as a word of its own (`temp_k`,
/// `T [K]`, `Temp (F)`, `kelvin`), with the conversion to deg C.
///
/// Words here run over letters and digits, so a sensor's label (`temp_F1`, `TK2`) is no unit;
/// a `K` after `type` is a thermocouple's type, and a name that also gives deg C (`TC1 type K
/// [°C]`) says its unit (review25a 8).
fn temperature_unit_in_name(name: &str) -> Option<(&'static str, &'static str)> {
    let words: Vec<String> = name
        .to_ascii_lowercase()
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(str::to_string)
        .collect();
    let has = |list: &[&str]| words.iter().any(|w| list.contains(&w.as_str()));
    let celsius = has(&["c", "degc", "celsius"]) || name.contains("\u{b0}C");
    let thermocouple_k = |i: usize| i > 0 && words.get(i - 1).is_some_and(|w| w == "type");
    let kelvin = words.iter().enumerate().any(|(i, w)| w == "kelvin" || (w == "k" && !thermocouple_k(i)));
    let fahrenheit = has(&["f", "degf", "fahrenheit"]) || name.contains("\u{b0}F");
    if celsius {
        return None;
    }
    match (kelvin, fahrenheit) {
        (true, false) => Some(("kelvin", "offset -273.15")),
        (false, true) => Some(("deg F", "scale 0.5555556, offset -17.777778")),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axis_columns::CLI_OPTIONS;

    fn format(time: &str, gyro: &str, temp: &str) -> LogFormat {
        LogFormat {
            time_column: time.into(),
            gyro_columns: vec![gyro.into()],
            temp_columns: vec![temp.into()],
            ..LogFormat::default()
        }
    }

    #[test]
    fn units_in_names() {
        for (name, unit) in [
            ("time_s", Some("s")),
            ("Time (ms)", Some("ms")),
            ("t_us", Some("us")),
            ("t [µs]", Some("us")),
            ("time_ns", Some("ns")),
            ("Time (min)", Some("min")),
            ("elapsed minutes", Some("min")),
            ("Time [h]", Some("h")),
        ] {
            assert_eq!(time_unit_in_name(name), unit, "{name}");
        }
        for name in ["timestamp", "t", "s_ms", "h_min"] {
            assert_eq!(time_unit_in_name(name), None, "{name}");
        }
        for (name, unit) in [
            ("gyrox rad/s", RateUnit::RadPerSecond),
            ("gyro_rps", RateUnit::RadPerSecond),
            ("Gyro X (deg/s)", RateUnit::DegPerSecond),
            ("gyro_dps", RateUnit::DegPerSecond),
            ("w [°/s]", RateUnit::DegPerSecond),
            ("gyro_dph", RateUnit::DegPerHour),
            ("rate deg/h", RateUnit::DegPerHour),
        ] {
            assert_eq!(rate_unit_in_name(name), Some(unit), "{name}");
        }
        for name in ["gyro", "gyro_mdps", "gyro mrad/s", "rad/s or deg/s", "radius"] {
            assert_eq!(rate_unit_in_name(name), None, "{name}");
        }
        for name in ["temp_k", "T [K]", "Temp (F)", "temp_kelvin", "t °F"] {
            assert!(temperature_unit_in_name(name).is_some(), "{name}");
        }
        for name in
            ["temp_c", "temp", "T [°C]", "kf", "temp_k_f", "TC1 type K [°C]", "TC1 type K", "temp_F1", "TK2"]
        {
            assert_eq!(temperature_unit_in_name(name), None, "{name}");
        }
    }

    #[test]
    fn a_unit_named_but_not_read_is_said_once_per_column() {
        // The defaults' own names agree with their units.
        assert!(unit_name_notes(&LogFormat::default(), CLI_OPTIONS).is_empty());
        // psim-tvc's header read with the defaults' units.
        let psim = format("time (ms)", "gyrox rad/s", "temp");
        assert_eq!(
            unit_name_notes(&psim, CLI_OPTIONS),
            vec![
                "the time column 'time (ms)' says ms in its name but is read in s: if its times are in ms, give \
                 the unit (--time-column/--time-unit/--sample-rate-hz/--date-column)"
                    .to_string(),
                "the gyro column 'gyrox rad/s' says rad/s in its name but is read in deg/h: if it is in rad/s, give \
                 the unit (--gyro-unit/--gyro-scale)"
                    .to_string(),
            ]
        );
        // Read in the units the names give: nothing to say.
        let read_so = LogFormat {
            time_unit: TimeUnit::Milliseconds,
            gyro_unit: RateUnit::RadPerSecond,
            ..psim.clone()
        };
        assert!(unit_name_notes(&read_so, CLI_OPTIONS).is_empty());
        // A scale given: the gyro is taken as converted within a factor 10 of its name's unit
        // (psim-tvc's rad/s x 0.5 is 103,132 deg/h per unit).
        let scaled = LogFormat { gyro_scale: 103_132.41, time_unit: TimeUnit::Milliseconds, ..psim.clone() };
        assert!(unit_name_notes(&scaled, CLI_OPTIONS).is_empty());
        // A negative scale turns an axis round: no unit (review25a 4).
        let inverted = LogFormat { gyro_scale: -1.0, ..format("time_s", "gyro_dph", "temp_c") };
        assert!(unit_name_notes(&inverted, CLI_OPTIONS).is_empty());
        // A model fitted in deg/s replays a deg/h column at 3600 deg/h per unit (review23b F2).
        let replayed = LogFormat { gyro_scale: 3600.0, ..format("time_s", "gyro_dph", "temp_c") };
        assert_eq!(
            unit_name_notes(&replayed, CLI_OPTIONS),
            vec!["the gyro column 'gyro_dph' says deg/h in its name but is read in 3600 deg/h per unit: if it is in \
                  deg/h, give the unit (--gyro-unit/--gyro-scale)"
                .to_string()]
        );
        // A time from the sample rate has no column to check; a converted temperature is
        // taken as converted.
        let kelvin = LogFormat { sample_rate_hz: Some(50.0), ..format("time (ms)", "gyro_dph", "temp_k") };
        let notes = unit_name_notes(&kelvin, CLI_OPTIONS);
        assert_eq!(notes.len(), 1);
        assert!(
            notes[0].contains("'temp_k' says kelvin") && notes[0].contains("offset -273.15"),
            "{notes:?}"
        );
        let converted = LogFormat { temp_offset_c: -273.15, ..kelvin };
        assert!(unit_name_notes(&converted, CLI_OPTIONS).is_empty());
    }
}
