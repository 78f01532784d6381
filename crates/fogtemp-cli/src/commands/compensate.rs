//! `compensate`: one log replayed through the model, as CSV.

use std::io::Write;

use anyhow::{bail, Result};
use fogtemp_cal::calibrate::{self, TimeGaps};
use fogtemp_cal::spikes::{Sample, SpikeGuard};
use fogtemp_core::{Compensator, Model};

use super::{check_capacity, read_model, report_rows_not_read_as_samples};
use crate::args::CompensateArgs;
use crate::compensated_csv::{self, AxisOutput, RowSink};
use crate::output::{check_output_file, refuse_overwriting_inputs, write_atomic, RowProgress};

/// How long rows may wait before `--out -` writes them: a live log piped in is compensated
/// as it comes.
const STREAM_LATENCY: std::time::Duration = std::time::Duration::from_millis(100);

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
    // A log that cannot be opened is said before anything is written (review20 F11: `--out -`
    // wrote the CSV header to the pipe first).
    if let Err(source) = std::fs::File::open(&a.log) {
        return Err(fogtemp_cal::CalError::Io { path: a.log.clone(), source }.into());
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
    // Per axis: the lines of the first samples flagged BAD_INPUT, for the note.
    let mut bad_lines: Vec<Vec<u64>> = vec![Vec::new(); axes];
    // Per axis: readings refused for coming in the whole microsecond of the last one taken:
    // the compensator's clock (`--time-unit ns` reads steps under 1 us; review25a 2).
    let mut same_microsecond = vec![calibrate::SameMicrosecond::default(); axes];
    // Per axis: temperature spikes, reported (the compensator takes every reading).
    let mut spike_guards: Vec<SpikeGuard> = (0..axes).map(|_| SpikeGuard::new(max_gap_s)).collect();
    // Per axis: the samples flagged OUTSIDE_HULL and how far they reach, for the note.
    let mut outside: Vec<calibrate::OutsideWatch<'_>> =
        (0..axes).map(|axis| calibrate::OutsideWatch::new(&model, axis)).collect();
    let bar = RowProgress::new(&a.log, "compensate");
    let mut report = None;
    // A problem in the log is reported as the log's (with its hint), not as the output's.
    let mut input_error: Option<anyhow::Error> = None;
    let mut body = |w: &mut dyn Write| -> Result<()> {
        // Rows are gathered in blocks whose text is made on all cores: every field is a
        // number (or a flag count), which CSV never quotes, so no CSV writer is needed.
        let output_error = |source: std::io::Error| fogtemp_cal::CalError::Io { path: a.out.clone(), source };
        w.write_all(&compensated_csv::header(axes)).map_err(output_error)?;
        if to_stdout {
            // A stream shows its header at once.
            w.flush().map_err(output_error)?;
        }
        let read = |sink: &mut RowSink<'_>| {
            fogtemp_cal::ingest::read_log_with_progress(
                &a.log,
                &ingest,
                |row| {
                    gaps.observe(previous_s, row.time_s, row.line);
                    previous_s = Some(row.time_s);
                    let time_us = row.time_us();
                    let outputs = comps.iter_mut().enumerate().map(|(i, comp)| {
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
                        let o = comp.step(
                            time_us,
                            row.gyros_dph[i] as f32,
                            (!temp.is_nan()).then_some(temp as f32),
                        );
                        for (bit, count) in flag_counts[i].iter_mut().enumerate() {
                            *count += u64::from((o.flags.0 >> bit) & 1);
                        }
                        outside[i].observe_output(&o, comp);
                        let bad = o.flags.contains(fogtemp_core::Flags::BAD_INPUT);
                        if bad && bad_lines[i].len() < calibrate::BAD_INPUT_LINES_LISTED {
                            bad_lines[i].push(row.line);
                        }
                        same_microsecond[i].observe(time_us, temp, bad);
                        AxisOutput {
                            raw_dph: row.gyros_dph[i],
                            compensated_dph: o.rate_dph,
                            bias_dph: o.bias_dph,
                            flags: o.flags.0,
                        }
                    });
                    // The log's own time stamp, so the output joins other channels by time.
                    sink.push(row.origin_s + row.time_s, outputs).map_err(output_error)
                },
                |b, r| bar.update(b, r),
            )
        };
        let (r, written) = compensated_csv::write_rows(w, axes, to_stdout.then_some(STREAM_LATENCY), read);
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
        written.map_err(output_error)?;
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
        report_rows_not_read_as_samples(r);
        let consequence = "after each the compensator held its bias until its tracker had features again \
                           (flag WARMING_UP in the output, then PARTIAL_WINDOW until its window is full again)";
        if let Some(note) = gaps.note_then(&a.log, consequence) {
            eprintln!("note: {note}");
        }
        super::warn_of_time_unit(&a.log, &gaps, r);
        for (axis, ((counts, guard), first_lines)) in
            flag_counts.iter().zip(spike_guards).zip(bad_lines).enumerate()
        {
            let name = format!("{} axis {axis}", a.log.display());
            let spikes = guard.finish(&mut |_| {});
            if let Some(note) = calibrate::temperature_spike_note(&name, &a.log, &spikes) {
                eprintln!("note: {note}");
            }
            let consequence = "the output's bias is 0";
            // The reader refuses a time not after the one before: not a cause here.
            let bad = calibrate::BadInputSources {
                times_refused: true,
                first_lines,
                gyro_not_finite: 0,
                same_microsecond: same_microsecond[axis].count,
            };
            let notes = calibrate::compensation_notes(
                &name,
                counts,
                r.rows,
                max_gap_s,
                "the output",
                consequence,
                &bad,
                outside[axis].reach(),
            );
            notes.iter().for_each(|note| eprintln!("note: {note}"));
        }
        if let Some(note) = clock_note(ingest.format.time_unit) {
            eprintln!("note: {note}");
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

/// What the output's `time_s` counts when the log's time column is a clock, not seconds: the
/// output keeps the log's own clock so it joins other channels by time, which for date-times
/// is Unix time (review32a F14: epoch seconds under `time_s` without a word).
fn clock_note(unit: fogtemp_cal::ingest::TimeUnit) -> Option<&'static str> {
    match unit {
        fogtemp_cal::ingest::TimeUnit::DateTime => Some(
            "the output's time_s is the log's date-time as seconds since 1970-01-01 00:00:00 UTC (Unix time), \
             so that it joins the log's other channels by time",
        ),
        fogtemp_cal::ingest::TimeUnit::TimeOfDay => Some(
            "the output's time_s is the log's time of day as seconds since the midnight before its first row \
             (past the next midnight it goes on counting; an elapsed h:mm:ss as seconds since its zero), so that \
             it joins the log's other channels by time",
        ),
        _ => None,
    }
}

/// Whether `e` comes from writing to a closed pipe.
fn broken_pipe(e: &anyhow::Error) -> bool {
    // The write error may travel inside another I/O error (`write_atomic` wraps the body's).
    let mut causes: Vec<&(dyn std::error::Error + 'static)> = e.chain().collect();
    while let Some(cause) = causes.pop() {
        if let Some(io) = cause.downcast_ref::<std::io::Error>() {
            if io.kind() == std::io::ErrorKind::BrokenPipe {
                return true;
            }
            // `io::Error::source` skips the error it wraps: look inside it too.
            causes.extend(io.get_ref().map(|inner| inner as &(dyn std::error::Error + 'static)));
        }
        causes.extend(cause.source());
    }
    false
}
