//! Date-times in the time column ([`super::TimeUnit::DateTime`]): ISO 8601 as loggers write
//! it, read into seconds since 1970-01-01 00:00 UTC. Only differences between rows are used
//! (a run's time starts at its first row), so a time without a zone is read as UTC.

/// `YYYY-MM-DD` (or `YYYY/MM/DD`, or `DD.MM.YYYY`: a dotted date is day first by convention,
/// as German and other European lab software writes it; one-digit day and month allowed
/// there), `T` or a space, `hh:mm[:ss[.fraction]]`, then optionally `Z`, `+hh:mm`, `+hhmm`
/// or `+hh` (or `-`): seconds since 1970-01-01 00:00 UTC. `None` for anything else, an
/// impossible date (2025-02-29) or a field out of range. (`MM/DD/YYYY` and `DD/MM/YYYY`
/// cannot be told apart and are not read.)
///
/// Resolution: the whole seconds are exact in an f64; with the fraction added, a time near
/// 2026 is rounded to 2.4e-7 s (one unit in the last place of 1.8e9), below the 1 us grid
/// the feature tracker uses.
pub fn parse_datetime(text: &[u8]) -> Option<f64> {
    let mut at = Cursor { text, pos: 0 };
    let (year, month, day) = if text.get(1..3).is_some_and(|t| t.contains(&b'.')) {
        at.dotted_date()?
    } else {
        let year = at.digits(4)? as i64;
        let date_sep = at.one_of(b"-/")?;
        let month = at.digits(2)?;
        at.exact(date_sep)?;
        (year, month, at.digits(2)?)
    };
    at.one_of(b"T ")?;
    let (clock_s, fraction) = at.clock(2, !HOURS_ELAPSED)?;
    let offset_s = at.zone()?;
    if at.pos != text.len() || !(1..=12).contains(&month) || day < 1 || day > days_in_month(year, month) {
        return None;
    }
    let whole = days_from_civil(year, month, day) * 86_400 + clock_s - offset_s;
    Some(whole as f64 + fraction)
}

/// Seconds in a day.
pub const DAY_S: f64 = 86_400.0;

/// A time of day without a date, `h:mm` or `hh:mm[:ss[.fraction]]` (as hand logs and
/// terminal programs write it): seconds since midnight; or an elapsed time whose hours
/// pass 23 (`25:13:02`, `100:00:00`, as chamber controllers write a test's elapsed time;
/// review32a F13): seconds since its zero, up to [`MAX_ELAPSED_HOUR_DIGITS`] digits of hours.
/// `None` for anything else or a minute or second out of range.
pub fn parse_time_of_day(text: &[u8]) -> Option<f64> {
    let mut at = Cursor { text, pos: 0 };
    let hour_digits =
        text.iter().position(|&b| b == b':').filter(|&n| (1..=MAX_ELAPSED_HOUR_DIGITS).contains(&n))?;
    let (clock_s, fraction) = at.clock(hour_digits, HOURS_ELAPSED)?;
    (at.pos == text.len()).then_some(clock_s as f64 + fraction)
}

/// Digits of hours an elapsed time may have (99,999 h: over 11 years).
pub const MAX_ELAPSED_HOUR_DIGITS: usize = 5;

/// A time of day's hours may pass 23 (an elapsed time); a date-time's may not.
const HOURS_ELAPSED: bool = true;

/// The time of a row whose clock reads `time_of_day_s` (seconds since midnight), after a
/// row at `previous_s` (seconds since the first row's midnight): the clock reading's
/// instant within 12 h either side of the previous row, the later one on a tie. So a
/// clock that passes midnight goes on to the next day, and a row more than 12 h before
/// or after the previous one cannot be placed (without a date nothing says which day).
pub fn continue_clock(time_of_day_s: f64, previous_s: Option<f64>) -> f64 {
    match previous_s {
        None => time_of_day_s,
        // Hours past 23: an elapsed time, as read (review33c F4: a 25 h pause read as 1 h).
        Some(_) if time_of_day_s >= DAY_S => time_of_day_s,
        Some(previous) => {
            let days = ((previous - 0.5 * DAY_S - time_of_day_s) / DAY_S).floor() + 1.0;
            time_of_day_s + days * DAY_S
        }
    }
}

/// Days from 1970-01-01 to the proleptic Gregorian date (H. Hinnant's `days_from_civil`).
fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let y = if month <= 2 { year - 1 } else { year };
    let era = y.div_euclid(400);
    let year_of_era = y - era * 400;
    let m = i64::from(month);
    let day_of_year = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(day) - 1;
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    era * 146_097 + day_of_era - 719_468
}

fn days_in_month(year: i64, month: u32) -> u32 {
    let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    match month {
        2 if leap => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

struct Cursor<'a> {
    text: &'a [u8],
    pos: usize,
}

impl Cursor<'_> {
    fn peek(&self) -> Option<u8> {
        self.text.get(self.pos).copied()
    }

    /// Exactly `n` ASCII digits.
    fn digits(&mut self, n: usize) -> Option<u32> {
        let field = self.text.get(self.pos..self.pos + n)?;
        if !field.iter().all(u8::is_ascii_digit) {
            return None;
        }
        self.pos += n;
        Some(field.iter().fold(0, |v, d| v * 10 + u32::from(d - b'0')))
    }

    /// One or two ASCII digits.
    fn one_or_two_digits(&mut self) -> Option<u32> {
        let n = if self.text.get(self.pos + 1).is_some_and(u8::is_ascii_digit) { 2 } else { 1 };
        self.digits(n)
    }

    /// `D.M.YYYY` (one or two digits of day and month): year, month, day.
    fn dotted_date(&mut self) -> Option<(i64, u32, u32)> {
        let day = self.one_or_two_digits()?;
        self.exact(b'.')?;
        let month = self.one_or_two_digits()?;
        self.exact(b'.')?;
        Some((i64::from(self.digits(4)?), month, day))
    }

    fn exact(&mut self, byte: u8) -> Option<()> {
        (self.peek()? == byte).then(|| self.pos += 1)
    }

    fn one_of(&mut self, bytes: &[u8]) -> Option<u8> {
        let b = self.peek().filter(|b| bytes.contains(b))?;
        self.pos += 1;
        Some(b)
    }

    /// `hh:mm[:ss[.fraction]]` with `hour_digits` digits of hour: whole seconds since
    /// midnight (or since an elapsed time's zero, with `elapsed`, where the hours may pass
    /// 23) and the fraction; `None` for a field out of range.
    fn clock(&mut self, hour_digits: usize, elapsed: bool) -> Option<(i64, f64)> {
        let hour = self.digits(hour_digits)?;
        self.exact(b':')?;
        let minute = self.digits(2)?;
        let (second, fraction) = if self.peek() == Some(b':') {
            self.pos += 1;
            let second = self.digits(2)?;
            (second, self.fraction()?)
        } else {
            (0, 0.0)
        };
        if (hour > 23 && !elapsed) || minute > 59 || second > 59 {
            return None;
        }
        Some((i64::from(hour) * 3600 + i64::from(minute * 60 + second), fraction))
    }

    /// `.ddd...` (or `,ddd...`, ISO's other decimal sign) as seconds; 0 when absent.
    fn fraction(&mut self) -> Option<f64> {
        if !matches!(self.peek(), Some(b'.' | b',')) {
            return Some(0.0);
        }
        self.pos += 1;
        let start = self.pos;
        while self.peek().is_some_and(|b| b.is_ascii_digit()) {
            self.pos += 1;
        }
        let digits = self.text.get(start..self.pos)?;
        if digits.is_empty() {
            return None;
        }
        // The first 15 digits as an integer over a power of ten: both exact in an f64, so the
        // quotient is correctly rounded (no allocation per row); later digits are below 1e-15 s.
        let kept = &digits[..digits.len().min(15)];
        let numerator = kept.iter().fold(0u64, |v, d| v * 10 + u64::from(d - b'0'));
        Some(numerator as f64 / 10f64.powi(kept.len() as i32))
    }

    /// The zone's offset east of UTC, seconds (0 without a zone).
    fn zone(&mut self) -> Option<i64> {
        let sign = match self.peek() {
            None => return Some(0),
            Some(b'Z') => {
                self.pos += 1;
                return Some(0);
            }
            Some(b'+') => 1,
            Some(b'-') => -1,
            Some(_) => return None,
        };
        self.pos += 1;
        let hours = self.digits(2)?;
        let minutes = match self.peek() {
            None => 0,
            Some(b':') => {
                self.pos += 1;
                self.digits(2)?
            }
            Some(_) => self.digits(2)?,
        };
        if hours > 23 || minutes > 59 {
            return None;
        }
        Some(sign * i64::from(hours * 3600 + minutes * 60))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Oracle: Python's `datetime.fromisoformat(s.replace('Z', '+00:00'))`, naive times as
    /// UTC, `.timestamp()` (python3 3.11, printed with `repr`).
    #[test]
    fn iso_date_times_match_pythons_timestamps() {
        for (text, expected) in [
            ("2026-11-24T10:00:00Z", 1_795_514_400.0),
            ("2026-11-24 10:00:00.125", 1_795_514_400.125),
            ("2000-02-29T23:59:59.5+01:00", 951_865_199.5),
            ("1999-12-31T23:00-05:30", 946_701_000.0),
            ("2024-03-01T00:00:00", 1_709_251_200.0),
            ("1970-01-01T00:00:00Z", 0.0),
            ("2100-12-31T12:34:56.000001+0000", 4_133_939_696.000_001),
        ] {
            let got = parse_datetime(text.as_bytes()).unwrap_or_else(|| panic!("{text}"));
            // 5e-7 s: two units in the last place of an f64 near 4e9 s.
            assert!((got - expected).abs() < 5e-7, "{text}: {got} against {expected}");
        }
        // Slashes and a decimal comma in the seconds, and an hour-only zone.
        assert_eq!(parse_datetime(b"2026/11/24 10:00:01,5+01"), Some(1_795_514_401.5 - 3600.0));
        // A dotted date is day first (review32a F13): the same instants.
        assert_eq!(parse_datetime(b"24.11.2026 10:00:00"), parse_datetime(b"2026-11-24T10:00:00"));
        assert_eq!(parse_datetime(b"4.3.2026T12:00:00.5"), parse_datetime(b"2026-03-04T12:00:00.5"));
        assert_eq!(parse_datetime(b"29.02.2024 00:00"), Some(1_709_164_800.0));
    }

    #[test]
    fn malformed_or_impossible_date_times_are_refused() {
        for text in [
            "",
            "2026-11-24",
            "2026-11-24T10",
            "2025-02-29T00:00:00",
            "2026-13-01T00:00:00",
            "2026-04-31T00:00:00",
            "2026-11-24T24:00:00",
            "29.02.2025 00:00:00",
            "24.13.2026 00:00:00",
            "24.11.26 00:00:00",
            "124.11.2026 00:00:00",
            "24.11.2026",
            "11/24/2026 10:00:00",
            "2026-11-24T10:60:00",
            "2026-11-24T10:00:60",
            "2026-11-24T10:00:00.",
            "2026-11-24T10:00:00 ",
            "2026-11-24T10:00:00+2400",
            "2026-11-24x10:00:00",
            "2026-11/24T10:00:00",
            "26-11-24T10:00:00",
            "1795514400",
        ] {
            assert_eq!(parse_datetime(text.as_bytes()), None, "{text:?}");
        }
    }

    #[test]
    fn times_of_day_are_seconds_since_midnight() {
        for (text, expected) in [
            ("15:45", 56_700.0),
            ("9:05", 32_700.0),
            ("09:05:07", 32_707.0),
            ("00:00:00.25", 0.25),
            ("23:59:59,5", 86_399.5),
            // Elapsed times past a day (review32a F13): 24 h 0 min is 86,400 s, and so on.
            ("24:00:00", 86_400.0),
            ("25:13:02.5", 25.0 * 3600.0 + 13.0 * 60.0 + 2.5),
            ("123:00", 123.0 * 3600.0),
            ("99999:59:59", 99_999.0 * 3600.0 + 3599.0),
        ] {
            assert_eq!(parse_time_of_day(text.as_bytes()), Some(expected), "{text}");
        }
        for text in [
            "",
            "15",
            "15:4",
            ":15",
            "100000:00",
            "12:60",
            "12:00:60",
            "1:2:3",
            "15:45 ",
            "15:45Z",
            "2026-11-24T15:45",
            "2026-11-24 24:00",
        ] {
            assert_eq!(parse_time_of_day(text.as_bytes()), None, "{text:?}");
        }
    }

    #[test]
    fn a_clock_continues_across_midnight_and_only_there() {
        // An elapsed time (hours past 23) is as read, whatever the previous row's.
        assert_eq!(continue_clock(55.0 * 3600.0, Some(30.0 * 3600.0 + 1.0)), 55.0 * 3600.0);
        assert_eq!(continue_clock(43.5 * 3600.0, Some(30.0 * 3600.0)), 43.5 * 3600.0);
        // Closed forms: the instant within 12 h of the previous row.
        assert_eq!(continue_clock(3600.0, None), 3600.0);
        assert_eq!(continue_clock(10.0, Some(DAY_S - 5.0)), DAY_S + 10.0);
        // 15 s before a row just after midnight: the same night, a step back.
        assert_eq!(continue_clock(DAY_S - 5.0, Some(DAY_S + 10.0)), DAY_S - 5.0);
        assert_eq!(continue_clock(20.0, Some(2.0 * DAY_S + 10.0)), 2.0 * DAY_S + 20.0);
        // A step back within the same day stays a step back (the reader refuses it).
        assert_eq!(continue_clock(3590.0, Some(3600.0)), 3590.0);
        // Exactly 12 h on: forward.
        assert_eq!(continue_clock(0.5 * DAY_S, Some(0.0)), 0.5 * DAY_S);
        assert_eq!(continue_clock(0.0, Some(0.5 * DAY_S)), DAY_S);
    }

    #[test]
    fn days_from_civil_counts_leap_years_and_centuries() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2000, 3, 1) - days_from_civil(2000, 2, 28), 2);
        assert_eq!(days_from_civil(1900, 3, 1) - days_from_civil(1900, 2, 28), 1);
        assert_eq!(days_from_civil(1969, 12, 31), -1);
        assert_eq!(days_from_civil(2001, 1, 1) - days_from_civil(2000, 1, 1), 366);
    }
}
