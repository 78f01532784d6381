//! `compensate`: one log replayed through the model, as CSV.

use std::io::Write;

use anyhow::{bail, Result};
use fogtemp_cal::calibrate::{self, TimeGaps};
use fogtemp_cal::spikes::{Sample, SpikeGuard};
use fogtemp_core::{Compensator, Model};

use super::{check_capacity, read_model, report_skipped};
use crate::args::CompensateArgs;
use crate::output::{check_output_file, refuse_overwriting_inputs, write_atomic, RowProgress};

/// Set while `compensate --out -` streams its CSV to stdout, for the interrupt handler's note.
pub static STREAMING_TO_STDOUT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

pub fn compensate(a: CompensateArgs) -> Result<()> {
    // One log in, one CSV out: a folder was read as a log ("Is a directory (os error 21)"
    // at line 1, review12 finding 11).
    if a.log.is_dir() {
        bail!(
            "{}: a folder; compensate takes one log and writes one CSV: run it per file, e.g. \
             for f in {}; do fogtemp-cal compensate --model {} \"$f\" --out \"${{f%.csv}}-comp.csv\"; done",
            a.log.display(),
            a.log.join("*.csv").display(),
            a.model.display()
        );
    }
    // `--out -`: the CSV on stdout (for a pipe), the summary on stderr (review12 F11: it wrote
    // a file named '-').
    let to_stdout = a.out.as_os_str() == "-";
    if !to_stdout {
        refuse_overwriting_inputs(&a.out, &[&a.log, &a.model])?;
        check_output_file(&a.out)?;
    }
    let blob = read_model(&a.model)?;
    check_capacity(&a.model, &blob, a.capacity)?;
    let model = Model::from_bytes(&blob).map_err(|e| anyhow::anyhow!("{e}"))?;
    let (mut ingest, columns) = super::ingest_options_for(&a.ingest, &model, &a.model)?;
    // A temperature no sensor reads (-999) goes to the compensator, which flags it BAD_INPUT
    // and keeps the row, as the firmware does: the output stays row for row with the log.
    ingest.keep_impossible_temperatures = true;
    super::warn_axis_count(&a.model, model.axis_count(), ingest.format.gyro_columns.len());
    let axes = model.axis_count().min(ingest.format.gyro_columns.len());
    let mut comps: Vec<Compensator<'_, { fogtemp_cal::features::CAL_CAPACITY }>> = (0..axes)
        .map(|i| Compensator::new(&model, i))
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow::anyhow!("{}: {e}", a.model.display()))?;
    // Gaps as the first axis's tracker sees them (the axes of one model share their settings).
    let max_gap_s = comps.first().map_or(f64::INFINITY, |c| c.tracker().max_gap_us() as f64 * 1e-6);
    let mut gaps = TimeGaps::new(max_gap_s);
    let mut previous_s = None;
    // Per axis: samples per flag bit (corrected = not WARMING_UP; OUTSIDE_HULL; the cause
    // when nothing was corrected).
    let mut flag_counts = vec![[0_u64; 8]; axes];
    // Per axis: temperature spikes, reported (the compensator takes every reading).
    let mut spike_guards: Vec<SpikeGuard> = (0..axes).map(|_| SpikeGuard::new(max_gap_s)).collect();
    let bar = RowProgress::new(&a.log, "compensate");
    let mut report = None;
    // A problem in the log is reported as the log's (with its hint), not as the output's.
    let mut input_error: Option<anyhow::Error> = None;
    let mut body = |w: &mut dyn Write| -> Result<()> {
        let mut out = csv::Writer::from_writer(w);
        let mut header = vec!["time_s".to_string()];
        for i in 0..axes {
            let suffix = if axes == 1 { String::new() } else { format!("_{i}") };
            for col in ["raw_dph", "compensated_dph", "bias_dph", "flags"] {
                header.push(format!("{col}{suffix}"));
            }
        }
        out.write_record(&header)?;
        let mut record: Vec<String> = Vec::with_capacity(header.len());
        let r = fogtemp_cal::ingest::read_log_with_progress(
            &a.log,
            &ingest,
            |row| {
                gaps.observe(previous_s, row.time_s, row.line);
                previous_s = Some(row.time_s);
                record.clear();
                // The log's own time stamp, so the output joins other channels by time.
                record.push(time_text(row.origin_s + row.time_s));
                let time_us = row.time_us();
                for (i, comp) in comps.iter_mut().enumerate() {
                    let temp = row.temp_c_for_axis(i);
                    // Only readings: rows without one change no verdict, and neither do
                    // temperatures no sensor reads (the compensator flags those BAD_INPUT).
                    if temp.is_finite() && fogtemp_core::is_physical_temperature(temp as f32) {
                        let sample = Sample {
                            time_s: row.time_s,
                            gyro_dph: row.gyros_dph[i],
                            temp_c: temp,
                            line: row.line,
                        };
                        spike_guards[i].push(sample, &mut |_| {});
                    }
                    let o =
                        comp.step(time_us, row.gyros_dph[i] as f32, (!temp.is_nan()).then_some(temp as f32));
                    record.push(raw_text(row.gyros_dph[i]));
                    record.push(format!("{}", o.rate_dph));
                    record.push(format!("{}", o.bias_dph));
                    record.push(format!("{}", o.flags.0));
                    for (bit, count) in flag_counts[i].iter_mut().enumerate() {
                        *count += u64::from((o.flags.0 >> bit) & 1);
                    }
                }
                out.write_record(&record).map_err(|e| fogtemp_cal::CalError::Io {
                    path: a.out.clone(),
                    source: std::io::Error::other(e),
                })
            },
            |b, r| bar.update(b, r),
        );
        let r = match r {
            Err(fogtemp_cal::CalError::Io { path, source }) if path == a.out => {
                return Err(fogtemp_cal::CalError::Io { path, source }.into())
            }
            Err(e) => {
                input_error = Some(columns.explain(e));
                bail!("the log could not be read");
            }
            Ok(r) => r,
        };
        if r.rows == 0 {
            input_error = Some(super::no_rows_error(&r));
            bail!("the log has no data rows");
        }
        out.flush()?;
        report = Some(r);
        Ok(())
    };
    let written = if to_stdout {
        STREAMING_TO_STDOUT.store(true, std::sync::atomic::Ordering::SeqCst);
        let mut stdout = std::io::BufWriter::new(std::io::stdout().lock());
        body(&mut stdout).and_then(|()| Ok(stdout.flush()?))
    } else {
        write_atomic(&a.out, body)
    };
    bar.finish_and_clear();
    // Streamed rows cannot be taken back (a file is written atomically instead).
    let pipe_closed = written.as_ref().is_err_and(broken_pipe);
    if to_stdout && written.is_err() && !pipe_closed {
        eprintln!("note: the CSV on stdout is cut short where the error below stopped it: discard it");
    }
    if let Some(e) = input_error {
        return Err(e);
    }
    // A reader that stops early (`| head`) closes the pipe: done, as other tools end there,
    // but the notes on the whole log were never reached: say so (review13 F12).
    if to_stdout && pipe_closed {
        eprintln!(
            "note: {}: the reader of stdout closed it before the log's end, so compensate stopped there; \
             the notes on the whole log (gaps, spikes, samples outside the calibrated region) need all of it: \
             write to a file with --out FILE for them",
            a.log.display()
        );
        return Ok(());
    }
    written?;
    if let Some(r) = &report {
        report_skipped(r);
        let consequence = "after each the compensator held its bias until its tracker had features again \
                           (flag WARMING_UP in the output, then PARTIAL_WINDOW until its window is full again)";
        if let Some(note) = gaps.note_then(&a.log, consequence) {
            eprintln!("note: {note}");
        }
        super::warn_if_mostly_gaps(&a.log, &gaps, r.rows);
        for (axis, (counts, guard)) in flag_counts.iter().zip(spike_guards).enumerate() {
            let name = format!("{} axis {axis}", a.log.display());
            let spikes = guard.finish(&mut |_| {});
            if let Some(note) = calibrate::temperature_spike_note(&name, &a.log, &spikes) {
                eprintln!("note: {note}");
            }
            let consequence = "the output's bias is 0";
            let notes =
                calibrate::compensation_notes(&name, counts, r.rows, max_gap_s, "the output", consequence);
            notes.iter().for_each(|note| eprintln!("note: {note}"));
        }
        let summary = format!("({} rows, {})", r.rows, super::counted(axes as u64, "axis", "axes"));
        if to_stdout {
            eprintln!("wrote the compensated log to stdout {summary}");
        } else {
            println!("wrote {} {summary}", a.out.display());
        }
    }
    Ok(())
}

/// Whether `e` comes from writing to a closed pipe.
fn broken_pipe(e: &anyhow::Error) -> bool {
    let pipe = |io: &std::io::Error| io.kind() == std::io::ErrorKind::BrokenPipe;
    // The CSV writer's error travels inside the I/O error the writer wraps it in.
    let mut causes: Vec<&(dyn std::error::Error + 'static)> = e.chain().collect();
    while let Some(cause) = causes.pop() {
        let found = match (cause.downcast_ref::<std::io::Error>(), cause.downcast_ref::<csv::Error>()) {
            (Some(io), _) => {
                // `io::Error::source` skips the error it wraps: look inside it too.
                causes.extend(io.get_ref().map(|inner| inner as &(dyn std::error::Error + 'static)));
                pipe(io)
            }
            (_, Some(c)) => matches!(c.kind(), csv::ErrorKind::Io(io) if pipe(io)),
            _ => false,
        };
        if found {
            return true;
        }
        causes.extend(cause.source());
    }
    false
}

/// A time stamp to the nanosecond, without trailing zeros: the log's own time, without the
/// float noise of re-adding its origin (`0.019000000000000128` was written for 0.019).
fn time_text(time_s: f64) -> String {
    let text = format!("{time_s:.9}");
    let trimmed = text.trim_end_matches('0').trim_end_matches('.');
    if trimmed.is_empty() || trimmed == "-" {
        "0".to_string()
    } else {
        trimmed.to_string()
    }
}

/// A raw reading in deg/h to 12 significant digits, the shortest text that reads back as
/// that: the logged value without the float noise of its unit conversion (0.1 deg/s was
/// written `360.00000000000006`); 12 digits keep more than any gyro resolves.
fn raw_text(raw_dph: f64) -> String {
    if !raw_dph.is_finite() {
        return format!("{raw_dph}");
    }
    let rounded: f64 = format!("{raw_dph:.11e}").parse().unwrap_or(raw_dph);
    format!("{rounded}")
}

#[cfg(test)]
mod tests {
    use super::{raw_text, time_text};

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
    fn time_stamps_are_written_without_float_noise() {
        assert_eq!(time_text(0.019000000000000128), "0.019");
        assert_eq!(time_text(1_700_000_000.25), "1700000000.25");
        assert_eq!(time_text(12.0), "12");
        assert_eq!(time_text(0.0), "0");
        assert_eq!(time_text(-0.5), "-0.5");
        assert_eq!(time_text(3.000_000_001), "3.000000001");
    }
}
