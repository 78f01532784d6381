//! Batches of parsed rows, and the calling thread's consumer that visits them, reports
//! progress and builds the report.

use super::{BadRow, IngestReport, Row, PROGRESS_EVERY_BYTES};
use crate::error::CalError;

/// Rows parsed but not yet visited, and how the log ended if it did.
#[derive(Debug, Default)]
pub(super) struct Batch {
    /// Per row: time (s, relative), temperatures, gyros.
    pub(super) values: Vec<f64>,
    /// Per row: its line.
    pub(super) lines: Vec<u64>,
    /// File offset after the last record parsed.
    pub(super) bytes: u64,
    /// The parser's time origin (its first accepted time, s; 0 for a chunk's parser, whose
    /// times are absolute).
    pub(super) origin_s: f64,
    /// `Some` once the log has ended (summary) or failed.
    pub(super) end: Option<Result<Tail, CalError>>,
}

/// The parser's share of the report.
#[derive(Debug)]
pub(super) struct Tail {
    pub(super) bytes: u64,
    pub(super) skipped: u64,
    pub(super) first_skipped: Vec<BadRow>,
    pub(super) time_origin_s: f64,
}

/// The calling thread's side: visits rows, reports progress, builds the report.
pub(super) struct Consumer {
    pub(super) report: IngestReport,
    pub(super) temps: usize,
    pub(super) stride: usize,
    pub(super) last_progress: u64,
    /// Per temperature column: the reading of a temperature-only row not yet given to a
    /// sample (NaN: none).
    pub(super) pending_temps_c: Vec<f64>,
    /// The temperatures of the row being visited, when readings were held for it.
    pub(super) row_temps_c: Vec<f64>,
    /// A temperature row's reading waits for the next sample.
    pub(super) holds_temperatures: bool,
}

impl Consumer {
    /// Visits the batch's rows; `Ok(true)` once the log has ended.
    pub(super) fn consume<F, P>(
        &mut self,
        batch: &mut Batch,
        visit: &mut F,
        progress: &mut P,
    ) -> Result<bool, CalError>
    where
        F: FnMut(&Row<'_>) -> Result<(), CalError>,
        P: FnMut(u64, u64),
    {
        self.visit_rows(batch, 0, 0.0, batch.origin_s, visit)?;
        match batch.end.take() {
            None => {
                if batch.bytes - self.last_progress >= PROGRESS_EVERY_BYTES {
                    progress(batch.bytes, self.report.rows);
                    self.last_progress = batch.bytes;
                }
                Ok(false)
            }
            Some(Ok(tail)) => {
                self.report.bytes = tail.bytes;
                self.report.skipped = tail.skipped;
                self.report.first_skipped = tail.first_skipped;
                self.report.time_origin_s = tail.time_origin_s;
                progress(self.report.bytes, self.report.rows);
                Ok(true)
            }
            Some(Err(e)) => Err(e),
        }
    }
}

impl Consumer {
    /// Visits the batch's rows, adding `line_base` to their lines and taking `origin`
    /// from their times (both zero for a sequential parser's rows); `file_origin_s` is the
    /// file's first accepted time ([`Row::origin_s`]).
    pub(super) fn visit_rows<F>(
        &mut self,
        batch: &Batch,
        line_base: u64,
        origin: f64,
        file_origin_s: f64,
        visit: &mut F,
    ) -> Result<(), CalError>
    where
        F: FnMut(&Row<'_>) -> Result<(), CalError>,
    {
        let split = 1 + self.temps;
        for (values, &line) in batch.values.chunks_exact(self.stride).zip(&batch.lines) {
            let (temps_c, gyros_dph) = (&values[1..split], &values[split..]);
            if super::columns::is_temperature_only(gyros_dph) {
                self.hold_temperatures(temps_c);
                continue;
            }
            self.report.rows += 1;
            self.report.last_time_s = values[0] - origin;
            // Readings held from temperature rows go in (a copy only then: the hot path of
            // every other log is unchanged).
            let temps_c =
                if self.holds_temperatures { self.give_held_temperatures(temps_c) } else { temps_c };
            visit(&Row {
                line: line_base + line,
                time_s: values[0] - origin,
                origin_s: file_origin_s,
                temps_c,
                gyros_dph,
            })?;
        }
        if self.temps > 0 {
            // The first temperature column's first and last readings (an empty cell is NaN).
            let mut readings = batch.values.chunks_exact(self.stride).map(|v| v[1]).filter(|t| !t.is_nan());
            if let Some(first) = readings.next() {
                let last = readings.next_back().unwrap_or(first);
                let ends = self.report.temp_ends_c.get_or_insert((first, first));
                ends.1 = last;
            }
        }
        Ok(())
    }

    /// A temperature-only row (channels logged on separate rows): its readings wait for the
    /// next sample, a newer reading replacing one that waits.
    fn hold_temperatures(&mut self, temps_c: &[f64]) {
        self.report.temperature_only_rows += 1;
        self.holds_temperatures = true;
        self.pending_temps_c.resize(temps_c.len(), f64::NAN);
        for (held, &reading) in self.pending_temps_c.iter_mut().zip(temps_c) {
            if !reading.is_nan() {
                *held = reading;
            }
        }
    }

    /// A sample's temperatures: its own readings, else one held from a temperature-only row
    /// before it (the firmware's `step` likewise takes a reading with the next sample).
    fn give_held_temperatures<'a>(&'a mut self, temps_c: &[f64]) -> &'a [f64] {
        self.holds_temperatures = false;
        self.row_temps_c.clear();
        self.row_temps_c.extend_from_slice(temps_c);
        for (k, held) in self.pending_temps_c.iter_mut().enumerate() {
            if let Some(own) = self.row_temps_c.get_mut(k) {
                if own.is_nan() {
                    *own = *held;
                }
            }
            *held = f64::NAN;
        }
        &self.row_temps_c
    }
}

#[cfg(test)]
mod tests {
    use crate::ingest::test_support::*;
    use crate::ingest::*;

    #[test]
    fn rows_before_a_bad_row_are_visited() {
        let (seen, result) =
            run(format!("{HEADER}0,20,1\n1,20,1\n2,20,x\n3,20,1\n").as_bytes(), &default_options());
        assert!(matches!(result, Err(CalError::BadRow { .. })));
        assert_eq!(seen.iter().map(|s| s.line).collect::<Vec<_>>(), vec![2, 3]);
    }

    #[test]
    fn visitor_errors_stop_the_read() {
        let mut data = String::from(HEADER);
        for i in 0..5000 {
            data.push_str(&format!("{i},20,1\n"));
        }
        for (tuning, chunk) in MODES {
            let mut calls = 0;
            let result = read_with_tuning(
                Path::new("log.csv"),
                Chunky { data: data.as_bytes(), chunk },
                &default_options(),
                tuning,
                |row| {
                    calls += 1;
                    if row.line == 100 {
                        return Err(CalError::NonFinite { what: "stop", index: 100 });
                    }
                    Ok(())
                },
                |_, _| {},
            );
            assert!(matches!(result, Err(CalError::NonFinite { what: "stop", index: 100 })));
            assert_eq!(calls, 99);
        }
    }

    #[test]
    fn progress_reports_bytes_and_rows() {
        let mut data = String::from(HEADER);
        for i in 0..400_000 {
            data.push_str(&format!("{}.{:03},25.0625,0.123456\n", i / 1000, i % 1000));
        }
        for mode in [Mode::Single, Mode::Parallel { workers: 2 }] {
            let mut calls = Vec::new();
            let tuning = Tuning { mode, chunk_bytes: 64 << 10, ..Tuning::default() };
            let report = read_with_tuning(
                Path::new("log.csv"),
                data.as_bytes(),
                &default_options(),
                tuning,
                |_| Ok(()),
                |bytes, rows| calls.push((bytes, rows)),
            )
            .unwrap();
            assert!(calls.len() >= 3, "{calls:?}");
            assert!(calls.windows(2).all(|w| w[0].0 < w[1].0 && w[0].1 < w[1].1), "{calls:?}");
            assert_eq!(*calls.last().unwrap(), (data.len() as u64, 400_000));
            assert_eq!((report.bytes, report.rows), (data.len() as u64, 400_000));
        }
    }
}
