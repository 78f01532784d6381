//! The record parser: reads the log through a buffer, splits records (the one-pass path,
//! plain records by hand, quoted ones with `csv-core`) and fills batches of rows.

use std::io::Read;
use std::path::{Path, PathBuf};

use memchr::{memchr, memchr2, memchr_iter};

use super::batch::{Batch, Tail};
use super::columns::time_of_record;
use super::columns::RowState;
use super::decimal::fast_fields;
use super::{Delimiter, IngestOptions};
use crate::error::CalError;

/// The UTF-8 byte-order mark.
const BOM: &[u8] = b"\xef\xbb\xbf";

/// The file, a window of it in memory, and where parsing is.
pub(super) struct Source<R> {
    pub(super) reader: R,
    pub(super) buf: Vec<u8>,
    /// Next byte to parse.
    pub(super) pos: usize,
    /// End of the valid data in `buf`.
    pub(super) end: usize,
    pub(super) eof: bool,
    /// File offset of `buf[0]`.
    pub(super) base: u64,
    /// 1-based line of `buf[pos]`. A line ends at `\n`, `\r\n` or a lone `\r` (old Mac
    /// and some serial devices), as a record does.
    pub(super) line: u64,
    /// The last byte counted as a line break was a `\r`: a `\n` right after it is the same
    /// break (`\r\n`), even across a refill.
    pub(super) after_cr: bool,
}

/// Line breaks in `bytes` (`\n`, `\r\n` and a lone `\r` each one), with `after_cr` carried
/// in and out as in [`Source`].
pub(super) fn count_line_breaks(bytes: &[u8], after_cr: &mut bool) -> u64 {
    let mut breaks = 0;
    for &b in bytes {
        match b {
            b'\r' => {
                breaks += 1;
                *after_cr = true;
            }
            b'\n' => {
                breaks += u64::from(!*after_cr);
                *after_cr = false;
            }
            _ => *after_cr = false,
        }
    }
    breaks
}

impl<R: Read> Source<R> {
    /// Reads more, keeping `buf[pos..end]` (moved to the front; the buffer doubles only
    /// when one record fills it).
    fn refill(&mut self) -> std::io::Result<()> {
        if self.pos > 0 {
            self.buf.copy_within(self.pos..self.end, 0);
            self.base += self.pos as u64;
            self.end -= self.pos;
            self.pos = 0;
        }
        if self.end == self.buf.len() {
            let grown = (self.buf.len() * 2).max(64);
            self.buf.resize(grown, 0);
        }
        loop {
            match self.reader.read(&mut self.buf[self.end..]) {
                Ok(0) => {
                    self.eof = true;
                    return Ok(());
                }
                Ok(n) => {
                    self.end += n;
                    return Ok(());
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    pub(super) fn offset(&self) -> u64 {
        self.base + self.pos as u64
    }

    /// Skips record terminators (blank lines), counting lines.
    fn skip_terminators(&mut self) {
        while let Some(&b) = self.buf[..self.end].get(self.pos) {
            if !matches!(b, b'\n' | b'\r') {
                self.after_cr = false;
                break;
            }
            self.line += count_line_breaks(&[b], &mut self.after_cr);
            self.pos += 1;
        }
    }
}

/// A record's fields: `data[start..end]` for each `(start, end)`.
#[derive(Clone, Copy)]
pub(super) struct Fields<'a> {
    pub(super) data: &'a [u8],
    pub(super) bounds: &'a [(usize, usize)],
}

impl<'a> Fields<'a> {
    pub(super) fn len(&self) -> usize {
        self.bounds.len()
    }

    pub(super) fn get(&self, field: usize) -> Option<&'a [u8]> {
        self.bounds.get(field).and_then(|&(s, e)| self.data.get(s..e))
    }
}

/// A quoted record being read by `csv-core` (it may span buffer refills).
struct Quoted {
    line: u64,
    out_len: usize,
    ends_len: usize,
}

enum Flow {
    Continue,
    NeedMore,
}

/// Reads records and turns them into rows (runs on the parser thread when threaded).
pub(super) struct Parser<R> {
    pub(super) path: PathBuf,
    pub(super) src: Source<R>,
    delimiter: u8,
    /// Fields are separated by runs of spaces and tabs (`delimiter` is then unused).
    whitespace: bool,
    /// The one-pass path is usable (header read, and a delimiter no number contains).
    fast: bool,
    /// Every record goes through `csv-core` (a delimiter that is a quote or terminator).
    core_only: bool,
    /// Byte-order mark, skipped lines, delimiter and a headerless log's columns are done.
    preamble_done: bool,
    core: csv_core::Reader,
    quoted: Option<Quoted>,
    out: Vec<u8>,
    ends: Vec<usize>,
    bounds: Vec<(usize, usize)>,
    pub(super) rows: RowState,
    /// Stop once the header is read (the parallel reader reads the header this way).
    pub(super) header_only: bool,
}

impl<R: Read> Parser<R> {
    pub(super) fn new(path: &Path, reader: R, options: &IngestOptions, buffer_bytes: usize) -> Self {
        let src = Source {
            reader,
            buf: vec![0; buffer_bytes.max(4)],
            pos: 0,
            end: 0,
            eof: false,
            base: 0,
            line: 1,
            after_cr: false,
        };
        Self::with_state(path, src, RowState::new(path, options), false)
    }

    /// A parser that carries on from `rows` (header read, times and skipped rows so
    /// far) over `src` (which starts at a record boundary, after any byte-order mark).
    pub(super) fn resume(path: &Path, src: Source<R>, rows: RowState) -> Self {
        Self::with_state(path, src, rows, true)
    }

    fn with_state(path: &Path, src: Source<R>, rows: RowState, preamble_done: bool) -> Self {
        // `Auto` stays until the preamble has seen the first line; comma meanwhile.
        let (delimiter, whitespace) = split_by(rows.format.delimiter);
        let mut parser = Self {
            path: path.to_path_buf(),
            src,
            delimiter,
            whitespace,
            fast: false,
            core_only: false,
            preamble_done,
            core: core_reader(delimiter),
            quoted: None,
            out: vec![0; 256],
            ends: vec![0; 16],
            bounds: Vec::new(),
            rows,
            header_only: false,
        };
        parser.core_only = !whitespace && matches!(delimiter, b'"' | b'\r' | b'\n');
        parser.refresh_fast();
        parser
    }

    /// Splits fields by `delimiter` from now on (also in the row state, so that chunks and
    /// the plan see the resolved one).
    fn set_delimiter(&mut self, delimiter: Delimiter) {
        (self.delimiter, self.whitespace) = split_by(delimiter);
        if delimiter != Delimiter::Auto {
            self.rows.format.delimiter = delimiter;
        }
        self.core = core_reader(self.delimiter);
        self.core_only = !self.whitespace && matches!(self.delimiter, b'"' | b'\r' | b'\n');
        self.refresh_fast();
    }

    fn refresh_fast(&mut self) {
        self.fast = self.rows.plan.as_ref().is_some_and(|p| p.fast) && !self.core_only;
    }

    /// Once, before any record: the byte-order mark, the lines to skip, the delimiter (when
    /// detected) and a headerless log's columns.
    fn preamble(&mut self) -> Result<(), CalError> {
        while self.src.end < BOM.len() && !self.src.eof {
            self.refill()?;
        }
        if self.src.buf[..self.src.end].starts_with(BOM) {
            self.src.pos = BOM.len();
        }
        let to_skip = self.rows.format.skip_lines;
        let mut left = to_skip;
        while left > 0 {
            if self.src.after_cr {
                // The `\n` of a `\r\n` ending the last line skipped is not a line of its own.
                if self.src.pos == self.src.end && !self.src.eof {
                    self.refill()?;
                    continue;
                }
                self.src.after_cr = false;
                if self.src.buf[..self.src.end].get(self.src.pos) == Some(&b'\n') {
                    self.src.pos += 1;
                    continue;
                }
            }
            match memchr2(b'\n', b'\r', &self.src.buf[self.src.pos..self.src.end]) {
                Some(i) => {
                    self.src.after_cr = self.src.buf[self.src.pos + i] == b'\r';
                    self.src.pos += i + 1;
                    self.src.line += 1;
                    left -= 1;
                }
                None if self.src.eof => {
                    // An unterminated last line still counts as one.
                    left -= u64::from(self.src.pos < self.src.end);
                    self.src.pos = self.src.end;
                    if left > 0 {
                        return Err(CalError::LogFormat {
                            path: self.path.clone(),
                            line: self.src.line,
                            problem: format!(
                                "the log ends within the {to_skip} line{} to skip",
                                if to_skip == 1 { "" } else { "s" }
                            ),
                        });
                    }
                }
                None => {
                    // A banner line longer than the buffer: drop what is read of it.
                    self.src.pos = self.src.end;
                    self.refill()?;
                }
            }
        }
        if self.rows.format.delimiter == Delimiter::Auto {
            let detected = self.detect_delimiter()?;
            self.set_delimiter(detected);
        }
        self.rows.plan_headerless()?;
        self.refresh_fast();
        self.preamble_done = true;
        Ok(())
    }

    /// [`Delimiter::Auto`] resolved on the first line that is not blank or a comment
    /// (looked at, not consumed).
    fn detect_delimiter(&mut self) -> Result<Delimiter, CalError> {
        let mut at = 0;
        loop {
            let rest = &self.src.buf[self.src.pos + at..self.src.end];
            let (line, next) = match memchr2(b'\n', b'\r', rest) {
                Some(i) => (&rest[..i], Some(at + i + 1)),
                None if self.src.eof => (rest, None),
                None => {
                    self.refill()?;
                    continue;
                }
            };
            if !(line.trim_ascii().is_empty() || is_comment(line, self.rows.format.comment_prefix())) {
                return Ok(Delimiter::Auto.resolve_with(line, self.rows.format.decimal_mark));
            }
            match next {
                Some(next) => at = next,
                None => return Ok(Delimiter::Byte(b',')),
            }
        }
    }

    /// Parses rows into `batch` (cleared first) until it holds `max_rows` rows or the log
    /// ends or fails (`batch.end` set).
    pub(super) fn fill(&mut self, batch: &mut Batch, max_rows: usize) {
        batch.values.clear();
        batch.lines.clear();
        batch.end = None;
        match self.fill_rows(batch, max_rows) {
            Ok(false) => {}
            Ok(true) => {
                batch.end = Some(Ok(Tail {
                    bytes: self.src.base + self.src.end as u64,
                    skipped: self.rows.skipped,
                    first_skipped: self.rows.first_skipped.clone(),
                    time_origin_s: self.rows.origin.unwrap_or(0.0),
                }));
            }
            Err(e) => batch.end = Some(Err(e)),
        }
        batch.bytes = self.src.offset();
        batch.origin_s = self.rows.origin.unwrap_or(0.0);
    }

    /// `Ok(true)` at the end of the log.
    fn fill_rows(&mut self, batch: &mut Batch, max_rows: usize) -> Result<bool, CalError> {
        if !self.preamble_done {
            self.preamble()?;
        }
        while batch.lines.len() < max_rows && !(self.header_only && self.rows.plan.is_some()) {
            let flow = if self.quoted.is_some() {
                self.quoted_step(batch)?
            } else {
                if self.fast {
                    self.fast_rows(batch, max_rows);
                    if batch.lines.len() >= max_rows {
                        break;
                    }
                }
                self.src.skip_terminators();
                if self.src.pos == self.src.end {
                    if self.src.eof {
                        if self.rows.plan.is_none() {
                            return Err(CalError::Csv {
                                path: self.rows.path.clone(),
                                line: 1,
                                message: "empty file: no header row (a logger that stopped before writing; remove it from the folder, or give the other logs by name)".into(),
                            });
                        }
                        return Ok(true);
                    }
                    Flow::NeedMore
                } else {
                    self.general_record(batch)?
                }
            };
            if let Flow::NeedMore = flow {
                self.refill()?;
            }
        }
        Ok(false)
    }

    fn refill(&mut self) -> Result<(), CalError> {
        self.src.refill().map_err(|e| CalError::Csv {
            path: self.path.clone(),
            line: self.src.line,
            message: e.to_string(),
        })
    }

    /// The one-pass path, over as many records as it can take; stops (leaving `pos` at
    /// the record's start) at the first record it cannot, for `general_record`.
    fn fast_rows(&mut self, batch: &mut Batch, max_rows: usize) {
        let RowState {
            plan: Some(plan), values, previous_time, previous_sample_time, origin, records, ..
        } = &mut self.rows
        else {
            return;
        };
        let buf = &self.src.buf[..self.src.end];
        let (mut pos, mut line, mut after_cr) = (self.src.pos, self.src.line, self.src.after_cr);
        let mut count = batch.lines.len();
        loop {
            while let Some(&b) = buf.get(pos) {
                if !matches!(b, b'\n' | b'\r') {
                    after_cr = false;
                    break;
                }
                line += count_line_breaks(&[b], &mut after_cr);
                pos += 1;
            }
            if count >= max_rows {
                break;
            }
            if let (Some(&b), Some(comment)) = (buf.get(pos), plan.comment_first) {
                if b == comment || b == b' ' || b == b'\t' {
                    break; // maybe a comment line: the general path decides
                }
            }
            let Some(terminator) =
                fast_fields(buf, pos, self.delimiter, &plan.roles, plan.columns.named_fields(), values)
            else {
                break;
            };
            let time = match plan.time_slot {
                Some(slot) => plan.time_unit.to_seconds(values[slot]),
                None => time_of_record(*records, plan.sample_rate_hz),
            };
            if time.is_nan() || plan.gyro_slots.iter().any(|&k| values[k].is_nan()) {
                break; // an empty required cell: the general path reports it
            }
            for &k in &plan.temp_slots {
                values[k] = values[k] * plan.temp_scale + plan.temp_offset_c; // NaN (empty) stays NaN
            }
            let refused =
                |v: f64| !v.is_nan() && !super::is_physical(v) && !plan.keep_impossible_temperatures;
            if plan.temp_slots.iter().any(|&k| refused(values[k])) {
                break; // an impossible temperature: likewise (the general path reads the record again)
            }
            for &k in &plan.gyro_slots {
                values[k] *= plan.gyro_factor; // to deg/h once, checked then pushed
            }
            if plan.gyro_slots.iter().any(|&k| !super::is_representable_rate(values[k])) {
                break; // a rate beyond the compensator's f32: likewise
            }
            if previous_time.is_some_and(|p| time <= p) {
                break; // duplicate or backward time: likewise
            }
            let time_origin = *origin.get_or_insert(time);
            *previous_time = Some(time);
            *previous_sample_time = Some(time);
            *records += 1;
            batch.lines.push(line);
            batch.values.push(time - time_origin);
            for &k in &plan.temp_slots {
                batch.values.push(values[k]);
            }
            for &k in &plan.gyro_slots {
                batch.values.push(values[k]);
            }
            count += 1;
            pos = terminator;
        }
        self.src.pos = pos;
        self.src.line = line;
        self.src.after_cr = after_cr;
    }

    /// One record (at `pos`, not a terminator) by the general path.
    fn general_record(&mut self, batch: &mut Batch) -> Result<Flow, CalError> {
        let start = self.src.pos;
        let rest = &self.src.buf[start..self.src.end];
        let len = match memchr2(b'\n', b'\r', rest) {
            Some(len) if !self.core_only => len,
            None if self.src.eof && !self.core_only => rest.len(),
            _ if self.core_only => {
                self.quoted = Some(Quoted { line: self.src.line, out_len: 0, ends_len: 0 });
                return Ok(Flow::Continue);
            }
            _ => return Ok(Flow::NeedMore),
        };
        let record = &rest[..len];
        if is_comment(record, self.rows.format.comment_prefix()) {
            self.src.pos = start + len;
            return Ok(Flow::Continue);
        }
        self.bounds.clear();
        if self.whitespace {
            split_whitespace(record, start, &mut self.bounds);
            if self.bounds.is_empty() {
                self.src.pos = start + len; // only spaces: a blank line
                return Ok(Flow::Continue);
            }
        } else {
            if record.trim_ascii().is_empty() {
                // Only spaces or tabs (an editor's trailing line): a blank line, as without them.
                self.src.pos = start + len;
                return Ok(Flow::Continue);
            }
            if memchr(b'"', record).is_some() {
                self.quoted = Some(Quoted { line: self.src.line, out_len: 0, ends_len: 0 });
                return Ok(Flow::Continue);
            }
            let mut field_start = start;
            for i in memchr_iter(self.delimiter, record) {
                self.bounds.push((field_start, start + i));
                field_start = start + i + 1;
            }
            self.bounds.push((field_start, start + len));
        }
        self.src.pos = start + len;
        let fields = Fields { data: &self.src.buf, bounds: &self.bounds };
        self.rows.record(fields, self.src.line, batch)?;
        self.refresh_fast();
        Ok(Flow::Continue)
    }

    /// Feeds the quoted record in progress to `csv-core`.
    fn quoted_step(&mut self, batch: &mut Batch) -> Result<Flow, CalError> {
        use csv_core::ReadRecordResult as R;
        let Some(q) = self.quoted.as_mut() else { return Ok(Flow::Continue) };
        loop {
            let input = &self.src.buf[self.src.pos..self.src.end];
            let (result, read, written, ended) =
                self.core.read_record(input, &mut self.out[q.out_len..], &mut self.ends[q.ends_len..]);
            self.src.line += count_line_breaks(&input[..read], &mut self.src.after_cr);
            self.src.pos += read;
            q.out_len += written;
            q.ends_len += ended;
            match result {
                R::InputEmpty if input.is_empty() => {
                    // Cannot happen (empty input is the end, answered by Record or End).
                    self.quoted = None;
                    return Ok(Flow::Continue);
                }
                R::InputEmpty if self.src.eof => {}
                R::InputEmpty => return Ok(Flow::NeedMore),
                R::OutputFull => {
                    let grown = self.out.len() * 2;
                    self.out.resize(grown, 0);
                }
                R::OutputEndsFull => {
                    let grown = self.ends.len() * 2;
                    self.ends.resize(grown, 0);
                }
                R::Record => {
                    let line = q.line;
                    self.bounds.clear();
                    let mut field_start = 0;
                    for &e in &self.ends[..q.ends_len] {
                        self.bounds.push((field_start, e));
                        field_start = e;
                    }
                    self.quoted = None;
                    let fields = Fields { data: &self.out, bounds: &self.bounds };
                    self.rows.record(fields, line, batch)?;
                    self.refresh_fast();
                    return Ok(Flow::Continue);
                }
                R::End => {
                    self.quoted = None;
                    return Ok(Flow::Continue);
                }
            }
        }
    }
}

/// The byte fields are split at, and whether runs of spaces and tabs split them instead.
fn split_by(delimiter: Delimiter) -> (u8, bool) {
    match delimiter {
        Delimiter::Byte(b) => (b, false),
        Delimiter::Whitespace => (b' ', true),
        Delimiter::Auto => (b',', false),
    }
}

/// `csv-core`'s reader for quoted records.
fn core_reader(delimiter: u8) -> csv_core::Reader {
    let mut core = csv_core::ReaderBuilder::new().delimiter(delimiter).build();
    // Prime it so that it never strips a byte-order mark from a record mid-file
    // (the file's own mark is skipped before any record).
    let _ = core.read_record(b"\n", &mut [0u8; 1], &mut [0usize; 1]);
    core
}

/// A record that starts (after spaces or tabs) with the comment prefix (none if empty).
fn is_comment(record: &[u8], prefix: &[u8]) -> bool {
    !prefix.is_empty() && record.trim_ascii_start().starts_with(prefix)
}

/// Bounds of the runs of non-blank bytes of `record` (at `offset` in the buffer).
fn split_whitespace(record: &[u8], offset: usize, bounds: &mut Vec<(usize, usize)>) {
    let mut field_start = None;
    for (i, &b) in record.iter().enumerate() {
        match (b == b' ' || b == b'\t', field_start) {
            (true, Some(s)) => {
                bounds.push((offset + s, offset + i));
                field_start = None;
            }
            (false, None) => field_start = Some(i),
            _ => {}
        }
    }
    if let Some(s) = field_start {
        bounds.push((offset + s, offset + record.len()));
    }
}

#[cfg(test)]
mod tests {
    use crate::error::CalError;
    use crate::ingest::test_support::*;
    use crate::ingest::{BadRowKind, IngestOptions, LogFormat};

    #[test]
    fn crlf_lines_are_exact() {
        let data = "time_s,temp_c,gyro_dph\r\n0,20,1\r\n1,20,1\r\n2,20,x\r\n";
        let b = bad(data);
        expect(&b, 4, 3, "gyro_dph", "x", BadRowKind::NotANumber);
        let seen = rows("time_s,temp_c,gyro_dph\r\n0,20,1\r\n1,20,2\r\n", &default_options());
        assert_eq!(values(&seen).iter().map(|v| (v.0, v.3[0])).collect::<Vec<_>>(), vec![(2, 1.0), (3, 2.0)]);
    }

    #[test]
    fn blank_lines_are_skipped_and_lines_still_exact() {
        let b = bad(&format!("{HEADER}0,20,1\n\n\n1,20,1\r\n\r\n2,20,x\n"));
        expect(&b, 7, 3, "gyro_dph", "x", BadRowKind::NotANumber);
        let b = bad("\n\ntime_s,temp_c,gyro_dph\n0,20,x\n");
        expect(&b, 4, 3, "gyro_dph", "x", BadRowKind::NotANumber);
        // Lines of spaces or tabs are blank too (a trailing one was a short row, review11 F14).
        let seen = rows(&format!("{HEADER}0,20,1\n \t \n1,20,2\n  \n"), &default_options());
        assert_eq!(seen.iter().map(|s| s.line).collect::<Vec<_>>(), vec![2, 4]);
        let b = bad(&format!("{HEADER}0,20,1\n\t\n1,20,x\n"));
        expect(&b, 4, 3, "gyro_dph", "x", BadRowKind::NotANumber);
    }

    #[test]
    fn lone_carriage_returns_end_records_and_lines() {
        // '\r' alone ends a record (as in the csv crate) and a line (as editors show it; lines
        // counted '\n' only before, so a log written with '\r' named every row line 1).
        let seen = rows("time_s,temp_c,gyro_dph\r0,20,1\r1,20,2\n2,20,3\n", &default_options());
        assert_eq!(seen.iter().map(|s| s.line).collect::<Vec<_>>(), vec![2, 3, 4]);
        for end in ["\n", "\r\n", "\r"] {
            let data = ["time_s,temp_c,gyro_dph", "0,20,1", "", "1,20,1", "2,20,x", ""].join(end);
            expect(&bad(&data), 5, 3, "gyro_dph", "x", BadRowKind::NotANumber);
            // Quoted records (the csv-core path) count the same lines.
            let quoted = ["time_s,temp_c,gyro_dph", "0,20,1", "", "\"1\",20,1", "\"2\",20,x", ""].join(end);
            expect(&bad(&quoted), 5, 3, "gyro_dph", "x", BadRowKind::NotANumber);
            // Banner lines to skip end the same way.
            let banner = ["banner", "more", "time_s,temp_c,gyro_dph", "0,20,1", "1,20,x", ""].join(end);
            let options = IngestOptions {
                format: LogFormat { skip_lines: 2, ..LogFormat::default() },
                ..IngestOptions::default()
            };
            match run(banner.as_bytes(), &options).1 {
                Err(CalError::BadRow { row, .. }) => {
                    expect(&row, 5, 3, "gyro_dph", "x", BadRowKind::NotANumber)
                }
                other => panic!("expected a bad row, got {}", summary(&other)),
            }
        }
    }

    #[test]
    fn byte_order_mark_in_the_header() {
        let data = format!("\u{feff}{HEADER}0,20,1\n1,20,x\n");
        expect(&bad(&data), 3, 3, "gyro_dph", "x", BadRowKind::NotANumber);
        assert_eq!(rows(&format!("\u{feff}{HEADER}0,20,1\n"), &default_options()).len(), 1);
        // A quoted header after the mark, too.
        let data = "\u{feff}\"time_s\",\"temp_c\",\"gyro_dph\"\n0,20,1\n";
        assert_eq!(rows(data, &default_options()).len(), 1);
    }

    #[test]
    fn final_line_without_newline() {
        let seen = rows(&format!("{HEADER}0,20,1\n1,20,2"), &default_options());
        assert_eq!(values(&seen).iter().map(|v| (v.0, v.3[0])).collect::<Vec<_>>(), vec![(2, 1.0), (3, 2.0)]);
        let b = bad(&format!("{HEADER}0,20,1\n1,20,2x"));
        expect(&b, 3, 3, "gyro_dph", "2x", BadRowKind::NotANumber);
        let b = bad(&format!("{HEADER}0,20,1\n1,20"));
        expect(&b, 3, 3, "gyro_dph", "", BadRowKind::ShortRow);
        assert_eq!(rows(&format!("{HEADER}0,20,1\r"), &default_options()).len(), 1);
    }

    #[test]
    fn quoted_fields() {
        let data = "time_s,note,temp_c,gyro_dph\n\
                    0,\"a, b\",20,1\n\
                    \"1\",\"two\nlines\",\"20.5\",\"2\"\n\
                    2,\"say \"\"hi\"\"\",21,3\n\
                    3,plain,22,x\n";
        let (seen, result) = run(data.as_bytes(), &default_options());
        let v = values(&seen);
        assert_eq!(
            v.iter().map(|v| (v.0, v.1, v.2[0], v.3[0])).collect::<Vec<_>>(),
            vec![(2, 0.0, 20.0, 1.0), (3, 1.0, 20.5, 2.0), (5, 2.0, 21.0, 3.0),]
        );
        match result {
            Err(CalError::BadRow { row, .. }) => expect(&row, 6, 4, "gyro_dph", "x", BadRowKind::NotANumber),
            other => panic!("{}", summary(&other)),
        }
        // A quoted bad cell reports its text without the quotes.
        let b = bad(&format!("{HEADER}0,20,\"1 2\"\n"));
        expect(&b, 2, 3, "gyro_dph", "1 2", BadRowKind::NotANumber);
        // A quote inside an unquoted field is a plain character (csv crate rules).
        let b = bad(&format!("{HEADER}0,20,1\"\n"));
        expect(&b, 2, 3, "gyro_dph", "1\"", BadRowKind::NotANumber);
    }
}
