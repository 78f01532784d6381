//! `compensate`'s CSV, quickly: it writes tens of millions of rows, and formatting them was
//! most of its time (review18 F7). Rows are gathered in blocks and each block's text is made
//! on all cores, then written in order. Each number's text is byte for byte what its
//! definition gives (the tests check the quick ways against the definitions).

use std::io::Write;
use std::time::{Duration, Instant};

use rayon::prelude::*;

/// What the compensator gave one axis for one row.
#[derive(Clone, Copy)]
pub struct AxisOutput {
    pub raw_dph: f64,
    pub compensated_dph: f32,
    pub bias_dph: f32,
    pub flags: u8,
}

/// The header line: `time_s`, then per axis its four columns (suffixed `_i` when there are
/// several axes).
pub fn header(axes: usize) -> Vec<u8> {
    let mut text = b"time_s".to_vec();
    for i in 0..axes {
        let suffix = if axes == 1 { String::new() } else { format!("_{i}") };
        for col in ["raw_dph", "compensated_dph", "bias_dph", "flags"] {
            text.extend_from_slice(format!(",{col}{suffix}").as_bytes());
        }
    }
    text.push(b'\n');
    text
}

/// Rows waiting to be written: their times and, row after row, each axis's output.
struct PendingRows {
    axes: usize,
    times_s: Vec<f64>,
    outputs: Vec<AxisOutput>,
}

/// Rows gathered before their text is made: enough to share among cores, little memory.
const BLOCK_ROWS: usize = 1 << 16;

/// Rows whose text one task makes.
const TASK_ROWS: usize = 1 << 12;

impl PendingRows {
    fn new(axes: usize) -> Self {
        Self { axes, times_s: Vec::with_capacity(BLOCK_ROWS), outputs: Vec::with_capacity(BLOCK_ROWS * axes) }
    }

    /// Adds a row: its time and one output per axis, in order.
    fn push(&mut self, time_s: f64, outputs: impl IntoIterator<Item = AxisOutput>) {
        self.times_s.push(time_s);
        self.outputs.extend(outputs);
    }

    /// Whether a block is gathered.
    fn is_full(&self) -> bool {
        self.times_s.len() >= BLOCK_ROWS
    }

    /// The gathered rows' text, made on all cores.
    fn text(&self) -> Vec<Vec<u8>> {
        let axes = self.axes.max(1);
        self.times_s
            .par_chunks(TASK_ROWS)
            .zip(self.outputs.par_chunks(TASK_ROWS * axes))
            .map(|(times_s, outputs)| rows_text(times_s, outputs, axes))
            .collect()
    }
}

/// Rows in, CSV text out to `w` while the rows go on coming: `body` gets a [`RowSink`];
/// full blocks are turned into text on other threads, and written in order here. After
/// `body`, the rest is written too, also when `body` failed (on a stream, the rows before an
/// error are kept). With `latency` (a stream read as it is written, such as stdout), the
/// rows gathered are written and flushed at least that often while rows come.
pub fn write_rows<T>(
    w: &mut dyn Write,
    axes: usize,
    latency: Option<Duration>,
    body: impl FnOnce(&mut RowSink<'_>) -> T,
) -> (T, std::io::Result<()>) {
    std::thread::scope(|scope| {
        // One block queued behind the one in hand: the rows in memory stay few.
        let (to_text, blocks) = std::sync::mpsc::sync_channel::<PendingRows>(1);
        let (to_write, texts) = std::sync::mpsc::channel::<Vec<Vec<u8>>>();
        scope.spawn(move || {
            for block in blocks {
                if to_write.send(block.text()).is_err() {
                    break;
                }
            }
        });
        let mut sink = RowSink {
            pending: PendingRows::new(axes),
            to_text,
            texts,
            in_flight: 0,
            latency,
            last_written: Instant::now(),
            w,
        };
        let result = body(&mut sink);
        let written = sink.finish();
        (result, written)
    })
}

/// Where [`write_rows`]'s body puts rows.
pub struct RowSink<'w> {
    pending: PendingRows,
    to_text: std::sync::mpsc::SyncSender<PendingRows>,
    texts: std::sync::mpsc::Receiver<Vec<Vec<u8>>>,
    /// Blocks sent whose text is not written yet.
    in_flight: usize,
    latency: Option<Duration>,
    last_written: Instant,
    w: &'w mut dyn Write,
}

/// Rows between two looks at the clock when writing with a latency.
const ROWS_PER_CLOCK_LOOK: usize = 16;

impl RowSink<'_> {
    /// Adds a row; a full block goes to be turned into text, and the text that is ready is
    /// written. With a latency, rows waiting longer are written and flushed now.
    pub fn push(
        &mut self,
        time_s: f64,
        outputs: impl IntoIterator<Item = AxisOutput>,
    ) -> std::io::Result<()> {
        self.pending.push(time_s, outputs);
        if self.pending.is_full() {
            self.send_pending()?;
            while let Ok(text) = self.texts.try_recv() {
                self.in_flight -= 1;
                write_all(self.w, &text)?;
            }
        }
        if let Some(latency) = self.latency {
            let look = self.pending.times_s.len() % ROWS_PER_CLOCK_LOOK == 0;
            if look && self.last_written.elapsed() >= latency {
                self.send_pending()?;
                self.write_in_flight()?;
                self.w.flush()?;
                self.last_written = Instant::now();
            }
        }
        Ok(())
    }

    /// Sends the rows gathered (if any) to be turned into text.
    fn send_pending(&mut self) -> std::io::Result<()> {
        if self.pending.times_s.is_empty() {
            return Ok(());
        }
        let axes = self.pending.axes;
        let block = std::mem::replace(&mut self.pending, PendingRows::new(axes));
        self.send(block)?;
        self.in_flight += 1;
        Ok(())
    }

    /// Waits for the text of every block sent and writes it.
    fn write_in_flight(&mut self) -> std::io::Result<()> {
        while self.in_flight > 0 {
            let text = self.texts.recv().map_err(|_| text_thread_stopped())?;
            self.in_flight -= 1;
            write_all(self.w, &text)?;
        }
        Ok(())
    }

    /// Sends the last rows and writes every text still to come.
    fn finish(mut self) -> std::io::Result<()> {
        self.send_pending()?;
        self.write_in_flight()?;
        self.w.flush()
    }

    fn send(&self, block: PendingRows) -> std::io::Result<()> {
        self.to_text.send(block).map_err(|_| text_thread_stopped())
    }
}

fn text_thread_stopped() -> std::io::Error {
    std::io::Error::other("the CSV text thread stopped")
}

fn write_all(w: &mut dyn Write, texts: &[Vec<u8>]) -> std::io::Result<()> {
    texts.iter().try_for_each(|text| w.write_all(text))
}

/// The CSV lines of rows: a time, then each axis's four fields.
fn rows_text(times_s: &[f64], outputs: &[AxisOutput], axes: usize) -> Vec<u8> {
    let mut text = Vec::with_capacity(times_s.len() * (16 + 40 * axes));
    for (time_s, row) in times_s.iter().zip(outputs.chunks(axes)) {
        push_time_text(&mut text, *time_s);
        for o in row {
            text.push(b',');
            push_raw_text(&mut text, o.raw_dph);
            text.push(b',');
            push_shortest(&mut text, o.compensated_dph);
            text.push(b',');
            push_shortest(&mut text, o.bias_dph);
            // Writing to a Vec cannot fail.
            let _ = write!(text, ",{}", o.flags);
        }
        text.push(b'\n');
    }
    text
}

/// `value`'s shortest text that reads back as it, as `format!("{value}")` writes it.
fn push_shortest(text: &mut Vec<u8>, value: impl std::fmt::Display) {
    // Writing to a Vec cannot fail.
    let _ = write!(text, "{value}");
}

/// A time stamp without float noise: its shortest text when that has at most 9 decimals,
/// else the time rounded to the nanosecond, without trailing zeros. The log's own time, not
/// the noise of re-adding its origin (`0.019000000000000128` was written for 0.019).
///
/// Below 2^22 s (48 days) a time's ulp is under 1 ns, so a shortest text with at most 9
/// decimals is the time rounded to the nanosecond: the two are one rule there. Above, the
/// ulp of a Unix epoch stamp is 238 ns, and the shortest text (`1700007200.001`) is what the
/// log said, where nanosecond rounding wrote the binary value's digits (`1700007200.000999928`,
/// until 2026-11-28, review19 F7); both read back as the same f64.
fn push_time_text(text: &mut Vec<u8>, time_s: f64) {
    let start = text.len();
    push_shortest(text, time_s);
    if decimals(&text[start..]) <= 9 {
        return;
    }
    text.truncate(start);
    // Writing to a Vec cannot fail.
    let _ = write!(text, "{time_s:.9}");
    // The fraction's trailing zeros, then its point when nothing is left of it.
    while text.len() > start && text.last() == Some(&b'0') {
        text.pop();
    }
    if text.last() == Some(&b'.') {
        text.pop();
    }
    if text.len() == start || text[start..] == *b"-" {
        text.truncate(start);
        text.push(b'0');
    }
}

/// Times below this have an ulp under 1 ns (2^22 s: ulp 2^-30 s).
#[cfg(test)]
const NANOSECOND_ULP_LIMIT_S: f64 = 4_194_304.0;

/// The digits after the decimal point in a number's plain decimal text.
fn decimals(number: &[u8]) -> usize {
    number.iter().position(|&b| b == b'.').map_or(0, |point| number.len() - point - 1)
}

/// A raw reading in deg/h to 12 significant digits, the shortest text that reads back as
/// that: the logged value without the float noise of its unit conversion (0.1 deg/s was
/// written `360.00000000000006`); 12 digits keep more than any gyro resolves.
fn push_raw_text(text: &mut Vec<u8>, raw_dph: f64) {
    let start = text.len();
    push_shortest(text, raw_dph);
    // The shortest text of a value with at most 12 significant digits is already that value
    // rounded to 12 digits (the value lies within half a unit in its 17th digit of it), so
    // only longer texts are rounded, which is the rare and slow case.
    if !raw_dph.is_finite() || significant_digits(&text[start..]) <= RAW_SIGNIFICANT_DIGITS {
        return;
    }
    text.truncate(start);
    let rounded: f64 = format!("{raw_dph:.*e}", RAW_SIGNIFICANT_DIGITS - 1).parse().unwrap_or(raw_dph);
    // Writing to a Vec cannot fail.
    let _ = write!(text, "{rounded}");
}

/// Significant digits kept in a raw reading's text.
const RAW_SIGNIFICANT_DIGITS: usize = 12;

/// The significant digits in a number's plain decimal text (no exponent): its digits less
/// the leading and trailing zeros.
fn significant_digits(number: &[u8]) -> usize {
    let digits = number.iter().filter(|b| b.is_ascii_digit()).skip_while(|&&d| d == b'0');
    // The count up to the last digit that is not zero.
    digits.enumerate().filter(|&(_, &d)| d != b'0').last().map_or(0, |(k, _)| k + 1)
}

#[cfg(test)]
mod tests {
    use super::{push_raw_text, push_time_text, significant_digits};

    fn raw_text(raw_dph: f64) -> String {
        let mut text = Vec::new();
        push_raw_text(&mut text, raw_dph);
        String::from_utf8(text).unwrap()
    }

    fn time_text(time_s: f64) -> String {
        let mut text = b"x,".to_vec();
        push_time_text(&mut text, time_s);
        String::from_utf8(text[2..].to_vec()).unwrap()
    }

    /// The definition: the value rounded to 12 significant digits, then its shortest text.
    fn raw_text_by_definition(raw_dph: f64) -> String {
        if !raw_dph.is_finite() {
            return format!("{raw_dph}");
        }
        let rounded: f64 = format!("{raw_dph:.11e}").parse().unwrap();
        format!("{rounded}")
    }

    /// A fixed-seed xorshift generator of 64-bit values.
    fn xorshift(mut state: u64) -> impl FnMut() -> u64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        }
    }

    #[test]
    fn raw_readings_are_written_without_conversion_noise() {
        assert_eq!(raw_text(0.1 * 3600.0), "360");
        assert_eq!(raw_text(0.000_123_456_789_012_345_6), "0.000123456789012");
        assert_eq!(raw_text(-216.0326), "-216.0326");
        assert_eq!(raw_text(0.0), "0");
        assert_eq!(raw_text(f64::NAN), "NaN");
        // 12 significant digits: a reading with more is rounded there.
        assert_eq!(raw_text(1.234_567_890_123_4), "1.23456789012");
    }

    #[test]
    fn the_quick_raw_text_is_the_definitions_for_any_value() {
        // Values of every magnitude and digit count, from a fixed-seed generator: logged
        // readings (few digits), converted ones (float noise), and arbitrary bit patterns.
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
        for k in 0..200_000 {
            let bits = next();
            let value = match k % 3 {
                0 => f64::from_bits(bits),
                1 => (bits % 2_000_000) as f64 / 1e6 - 1.0,
                _ => (bits % 100_000) as f64 * 1e-4 * 3600.0 / 7.0,
            };
            assert_eq!(raw_text(value), raw_text_by_definition(value), "{value:e} ({bits:#x})");
        }
    }

    /// The definition: the time rounded to the nanosecond, less trailing zeros.
    fn time_text_by_definition(time_s: f64) -> String {
        let text = format!("{time_s:.9}");
        let trimmed = text.trim_end_matches('0').trim_end_matches('.');
        if trimmed.is_empty() || trimmed == "-" {
            "0".to_string()
        } else {
            trimmed.to_string()
        }
    }

    /// Below 2^22 s: the nanosecond rounding's text exactly. Above: a text that reads back
    /// as the time itself, or else the nanosecond rounding's, and never longer than it.
    fn check_time_text(time_s: f64) {
        let (written, rounded) = (time_text(time_s), time_text_by_definition(time_s));
        if time_s.abs() < super::NANOSECOND_ULP_LIMIT_S {
            assert_eq!(written, rounded, "{time_s:e}");
        } else {
            let reads_back = written.parse::<f64>().is_ok_and(|t| t == time_s);
            assert!(reads_back || written == rounded, "{time_s:e}: {written} ({rounded})");
            assert!(written.len() <= rounded.len(), "{time_s:e}: {written} ({rounded})");
        }
    }

    #[test]
    fn time_texts_are_the_nanosecond_rounding_or_read_back_as_the_time() {
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        for k in 0..200_000 {
            let bits = next();
            let time_s = match k % 4 {
                // Sample times of logs at 1 Hz to 10 kHz, from an origin added in f64.
                0 => 12.5 + (bits % 100_000_000) as f64 * 1e-4,
                1 => (bits % 1_000_000_000) as f64 / 1000.0,
                // Unix epoch stamps and times near the quick path's limit.
                2 => 1_700_000_000.0 + (bits % 1_000_000) as f64 * 1e-3,
                _ => super::NANOSECOND_ULP_LIMIT_S + ((bits % 2_000_001) as f64 - 1e6) * 1e-6,
            };
            for time_s in [time_s, -time_s] {
                check_time_text(time_s);
            }
        }
        for bits in (0..200_000).map(|_| next()) {
            let time_s = f64::from_bits(bits);
            if time_s.is_finite() {
                check_time_text(time_s);
            }
        }
    }

    #[test]
    fn significant_digits_ignore_leading_and_trailing_zeros() {
        assert_eq!(significant_digits(b"0"), 0);
        assert_eq!(significant_digits(b"-0.000120"), 2);
        assert_eq!(significant_digits(b"100000000000000000000"), 1);
        assert_eq!(significant_digits(b"1200.5"), 5);
        assert_eq!(significant_digits(b"360.00000000000006"), 17);
    }

    #[test]
    fn time_stamps_are_written_without_float_noise() {
        assert_eq!(time_text(0.019000000000000128), "0.019");
        assert_eq!(time_text(1_700_000_000.25), "1700000000.25");
        assert_eq!(time_text(12.0), "12");
        assert_eq!(time_text(100.0), "100");
        assert_eq!(time_text(0.0), "0");
        assert_eq!(time_text(-0.5), "-0.5");
        assert_eq!(time_text(3.000_000_001), "3.000000001");
        // A Unix epoch stamp as logged, not its binary value's digits.
        assert_eq!(time_text(1_700_007_200.001), "1700007200.001");
    }

    /// Rows of every block size and two axes, written through the threads, are the rows
    /// written one by one by the definitions, in order; a body that failed writes only the
    /// blocks it had finished.
    #[test]
    fn rows_written_through_the_threads_are_the_rows_in_order() {
        let axes = 2;
        let rows = 3 * super::BLOCK_ROWS + 12_345;
        let output = |k: usize, axis: usize| super::AxisOutput {
            raw_dph: (k as f64 * 0.1 + axis as f64) * 3600.0 / 7.0,
            compensated_dph: (k as f32).sin() * 0.01,
            bias_dph: k as f32 * 1e-7 - axis as f32,
            flags: ((k + axis) % 32) as u8,
        };
        let time_s = |k: usize| 1_000.0 + k as f64 * 0.001;
        let mut expected = super::header(axes);
        for k in 0..rows {
            expected.extend_from_slice(time_text_by_definition(time_s(k)).as_bytes());
            for axis in 0..axes {
                let o = output(k, axis);
                let fields = format!(
                    ",{},{},{},{}",
                    raw_text_by_definition(o.raw_dph),
                    o.compensated_dph,
                    o.bias_dph,
                    o.flags
                );
                expected.extend_from_slice(fields.as_bytes());
            }
            expected.push(b'\n');
        }
        let mut written = super::header(axes);
        let (count, result) = super::write_rows(&mut written, axes, None, |sink| {
            (0..rows).map(|k| sink.push(time_s(k), (0..axes).map(|axis| output(k, axis)))).count()
        });
        result.unwrap();
        assert_eq!(count, rows);
        assert!(
            written == expected,
            "the text differs from the definitions' (lengths {} and {})",
            written.len(),
            expected.len()
        );

        // A body that stops part-way (a bad row): every row it gave is written, in order.
        let stopped_at = super::BLOCK_ROWS + 10;
        let mut cut = Vec::new();
        let ((), result) = super::write_rows(&mut cut, axes, None, |sink| {
            for k in 0..stopped_at {
                sink.push(time_s(k), (0..axes).map(|axis| output(k, axis))).unwrap();
            }
        });
        result.unwrap();
        let header_len = super::header(axes).len();
        assert_eq!(cut, expected[header_len..header_len + cut.len()]);
        assert_eq!(cut.iter().filter(|&&b| b == b'\n').count(), stopped_at);
    }

    /// A writer that counts the bytes it was given and the flushes, readable while it is lent.
    struct Counting(std::rc::Rc<std::cell::Cell<(usize, usize)>>);

    impl std::io::Write for Counting {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            let (written, flushes) = self.0.get();
            self.0.set((written + bytes.len(), flushes));
            Ok(bytes.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            let (written, flushes) = self.0.get();
            self.0.set((written, flushes + 1));
            Ok(())
        }
    }

    /// With a latency, rows are written and flushed while the body goes on (a live stream);
    /// without, they wait for a whole block.
    #[test]
    fn a_stream_gets_its_rows_while_they_come() {
        let output = super::AxisOutput { raw_dph: 1.5, compensated_dph: 1.25, bias_dph: 0.25, flags: 0 };
        for (latency, expect_early) in [(Some(std::time::Duration::ZERO), true), (None, false)] {
            let seen = std::rc::Rc::new(std::cell::Cell::new((0, 0)));
            let mut w = Counting(seen.clone());
            let (during, result) = super::write_rows(&mut w, 1, latency, |sink| {
                for k in 0..100 {
                    sink.push(k as f64, [output]).unwrap();
                }
                seen.get()
            });
            result.unwrap();
            let (written, flushes) = during;
            assert_eq!(
                written > 0 && flushes > 0,
                expect_early,
                "{latency:?}: {written} bytes, {flushes} flushes"
            );
            let total: usize = (0..100).map(|k| format!("{k},1.5,1.25,0.25,0\n").len()).sum();
            assert_eq!(seen.get().0, total, "every row written in the end");
        }
    }
}
