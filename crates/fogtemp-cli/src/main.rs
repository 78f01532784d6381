//! `fogtemp-cal`: the calibration command for lab technicians (thin glue over the fogtemp
//! libraries: `fogtemp-cal`, `fogtemp-sim`, `fogtemp-diagnose`).

// `println!` and `print!` for every module below: standard output that a reader closed (a
// pipe into `head`) ends the process quietly, as a Unix tool ends on SIGPIPE, instead of
// std's panic "failed printing to stdout".
macro_rules! println {
    () => {
        $crate::write_stdout(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::write_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}
macro_rules! print {
    ($($arg:tt)*) => {
        $crate::write_stdout(format_args!($($arg)*))
    };
}

// `eprintln!` likewise: standard error that is the same closed pipe (`2>&1 | head`) drops
// the message instead of std's panic "failed printing to stderr" (status 101, review24b F8).
macro_rules! eprintln {
    () => {
        $crate::write_stderr(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::write_stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}

mod args;
mod commands;
mod compensated_csv;
mod output;

/// Writes to standard output; a closed pipe exits with status 0 (the reader has what it
/// wanted), any other failure with an error on stderr and status 1.
fn write_stdout(text: std::fmt::Arguments<'_>) {
    use std::io::Write;
    if let Err(e) = std::io::stdout().lock().write_fmt(text) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: writing to standard output: {e}");
        std::process::exit(1);
    }
}

/// Writes to standard error; a failure is dropped (there is nowhere left to report it).
fn write_stderr(text: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let _ = std::io::stderr().lock().write_fmt(text);
}

use clap::Parser;
use fogtemp_cal::ingest::BadRowKind;
use fogtemp_cal::CalError;
use fogtemp_diagnose::DiagnoseError;
use fogtemp_sim::SimError;

fn main() -> std::process::ExitCode {
    // Ctrl-C (and SIGTERM): remove the temporary files of outputs being written, then end
    // as an interrupted process does (status 130). Without it a killed `compensate` left its
    // half-written output behind under a hidden name. If the handler cannot be installed,
    // the default action stays (outputs are still atomic: no half file under its name).
    let _ = ctrlc::set_handler(|| {
        fogtemp_cal::output::remove_pending_outputs();
        // A CSV streamed to stdout cannot be taken back: say it is cut short (review18 F9).
        if commands::compensate::STREAMING_TO_STDOUT.load(std::sync::atomic::Ordering::SeqCst) {
            eprintln!("note: interrupted: the CSV on stdout is cut short where the interrupt stopped it: discard it");
        } else {
            // Said, so that a silent status 130 does not leave the user guessing (review24b S4).
            eprintln!("note: interrupted: the files being written were removed; those already finished are in place");
        }
        std::process::exit(130);
    });
    let cli = args::Cli::parse();
    match commands::run(cli.command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{}", error_paragraph(&e));
            std::process::ExitCode::FAILURE
        }
    }
}

/// One paragraph: the error and its causes, each with the command-line hint that fits it.
fn error_paragraph(e: &anyhow::Error) -> String {
    let mut message = String::from("error: ");
    let mut previous = String::new();
    for (k, cause) in e.chain().enumerate() {
        let text = cause.to_string();
        // A context that already quotes its cause ("x.csv: File exists (os error 17)") is
        // not followed by that cause again.
        if k > 0 && previous.contains(&text) {
            continue;
        }
        if k > 0 {
            message.push_str("\n  caused by: ");
        }
        message.push_str(&text);
        message.push_str(&cut_off_note(cause));
        message.push_str(flag_hint(cause).unwrap_or_default());
        previous = text;
    }
    message
}

/// For a bad row on a log's last line when the log ends without a line end: the file was cut
/// off there (review24b S1: a power loss mid-line read as any short row). Reads the file's
/// last byte again, only on this error, and counts its line breaks only when that byte ends
/// no line.
fn cut_off_note(e: &(dyn std::error::Error + 'static)) -> String {
    let Some(CalError::BadRow { path, row }) = cal_error(e) else { return String::new() };
    if ends_without_line_end(path) != Some(true) {
        return String::new();
    }
    match line_breaks(path) {
        Some(breaks) if row.line == breaks + 1 => "; this is the file's last line and the file ends in it \
             without a line end: cut off (a power loss, or a copy still being written?)"
            .into(),
        _ => String::new(),
    }
}

/// Whether the file at `path` is not empty and its last byte ends no line (neither CR nor LF).
fn ends_without_line_end(path: &std::path::Path) -> Option<bool> {
    use std::io::{Read, Seek, SeekFrom};
    let mut file = std::fs::File::open(path).ok()?;
    if file.seek(SeekFrom::End(0)).ok()? == 0 {
        return Some(false);
    }
    file.seek(SeekFrom::End(-1)).ok()?;
    let mut last = [0u8; 1];
    file.read_exact(&mut last).ok()?;
    Some(last[0] != b'\n' && last[0] != b'\r')
}

/// The line breaks of the file at `path` as the reader counts them (a CR, an LF or a CRLF
/// ends a line); read in 1 MiB pieces.
fn line_breaks(path: &std::path::Path) -> Option<u64> {
    use std::io::Read;
    let mut file = std::fs::File::open(path).ok()?;
    let mut buffer = vec![0u8; 1 << 20];
    let (mut breaks, mut last) = (0u64, None);
    loop {
        let n = file.read(&mut buffer).ok()?;
        if n == 0 {
            break;
        }
        for &b in &buffer[..n] {
            // A CR counts when no LF follows it; an LF after a CR ends the same line.
            if (b == b'\n' && last != Some(b'\r')) || b == b'\r' {
                breaks += 1;
            }
            last = Some(b);
        }
    }
    Some(breaks)
}

/// The library's error inside `e`, if it is one (directly or wrapped by the simulator or
/// the diagnosis, whose wrapping variants are transparent).
fn cal_error<'e>(e: &'e (dyn std::error::Error + 'static)) -> Option<&'e CalError> {
    e.downcast_ref::<CalError>()
        .or_else(|| match e.downcast_ref::<SimError>() {
            Some(SimError::Cal(c)) => Some(c),
            _ => None,
        })
        .or_else(|| match e.downcast_ref::<DiagnoseError>() {
            Some(DiagnoseError::Cal(c)) => Some(c),
            _ => None,
        })
}

/// What to change on the command line, for the library errors a flag can fix (the
/// libraries name no flags: their callers have none).
fn flag_hint(e: &(dyn std::error::Error + 'static)) -> Option<&'static str> {
    match cal_error(e)? {
        CalError::BadRow { row, .. } if row.looks_like_datetime() => {
            Some("; the time column holds date-times: use --time-unit datetime")
        }
        CalError::BadRow { row, .. } if row.looks_like_time_of_day() => {
            Some("; the time column holds times of day (or elapsed h:mm:ss): use --time-unit time-of-day")
        }
        CalError::BadRow { row, .. } if row.looks_like_thousands_separators() && !row.looks_like_decimal_comma() => {
            Some("; thousands separators in the numbers (a spreadsheet's number format): save the log without them \
                  (--skip-bad-rows would drop every row from 1000 on)")
        }
        CalError::BadRow { row, .. } if row.looks_like_decimal_comma() => {
            Some("; the log seems to write numbers with a decimal comma: use --decimal-mark comma")
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::PointWithDecimalComma => {
            Some(
                "; the log writes decimal points? give --decimal-mark point (a model fitted on decimal-comma logs \
                 reads its logs so unless told)",
            )
        }
        // A word for a missing value (before the text-row arms: a row of them is a text row).
        CalError::BadRow { row, .. } if row.looks_like_missing_marker() => Some(
            "; a mark for a missing reading? in a temperature column empty those cells: an empty temperature \
             cell is read as no reading (--skip-bad-rows would drop the rows, gyro samples and all); a time or \
             gyro value missing: --skip-bad-rows skips its row",
        ),
        CalError::BadRow { row, .. } if row.looks_like_repeated_header() => Some(
            "; the header again (a logger restart, or two logs joined)? split the file there, each part a run \
             (--skip-bad-rows would skip it, and then, if the time started again, every row until it passes the \
             old one)",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::TextRow => Some(
            "; a banner above the data (a terminal program's log line)? skip it with --skip-lines N; a units row \
             under the header: skip both with --skip-lines N and name the columns with --columns a,b,c, which the \
             model records for validate and compensate (--skip-bad-rows also skips the row, but has to be given \
             again at every step)",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::ShortSpacedRow => Some(
            "; a row cut short (as a serial capture's): skip such rows with --skip-bad-rows (listed); a blank \
             cell: write the log with another delimiter (a comma keeps it in its place); if the header's names \
             hold spaces, name the columns in order with --skip-lines 1 --columns a,b,c",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::EmptyCell => Some(
            "; a time, date or gyro cell left empty: a lost sample? (--skip-bad-rows skips such rows, listed; a row with a temperature and \
             no gyro reading at all is read as a temperature row, its reading going with the next sample: \
             channels logged on separate rows)",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::DuplicateTime => Some(
            "; repeated time stamps: a clock coarser than the sample rate? give --sample-rate-hz HZ to time the rows \
             by their index (--skip-bad-rows would keep one row per stamp and drop the rest)",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::BackwardTime => Some(
            "; the time goes back: a logger restart (a new run starts here: split the file there), two logs \
             joined, a 32-bit counter that wrapped (if the time before was near 4294.97 s from microseconds or \
             4294967 s from milliseconds: give --sample-rate-hz HZ to time the rows by their index), or a \
             corrupted stamp in the row before that jumps ahead? --skip-bad-rows would drop every row until the \
             time passes the old one",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::NotADateTime => Some(
            "; date-times are read in ISO 8601 (2026-11-24T23:30:00, or with a space, optional .fff and Z or \
             +hh:mm, or a dotted day-first date, DD.MM.YYYY hh:mm:ss); convert other formats first (MM/DD/YYYY and DD/MM/YYYY cannot be told apart by the \
             tool), or give --sample-rate-hz HZ to time the rows by their index",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::NotATimeOfDay => Some(
            "; times of day are read as hh:mm[:ss[.fff]] on a 24-hour clock, elapsed times as h:mm:ss with hours \
             that may pass 24; convert others first (11:30:00 PM, 1.02:03:04), or give --sample-rate-hz HZ to time \
             the rows by their index",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::RateBeyondRange => Some(
            "; a logger's overload code: --skip-bad-rows skips such rows (listed); a unit or scale far off: \
             check --gyro-unit/--gyro-scale",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::ImpossibleTemperature => Some(
            "; raw counts or kelvin? give --temp-scale/--temp-offset; a logger's mark for a missing reading: \
             empty the cell, or --skip-bad-rows",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::SplitThousands => Some(
            "; write the numbers without thousands separators (1000.5; a spreadsheet's number format adds them): \
             --skip-bad-rows would drop every row from the first such number on",
        ),
        CalError::BadRow { row, .. } if row.kind == BadRowKind::NulBytes => Some(
            "; --skip-bad-rows skips such lines and lists them",
        ),
        CalError::BadRow { .. } => Some("; use --skip-bad-rows to skip such rows"),
        CalError::MissingColumn { column, role: role @ ("gyro" | "temperature"), .. } if column.contains(',') => {
            Some(if *role == "gyro" {
                "; one column per --gyro-column: repeat the flag, one for each model axis (--gyro-column gx \
                 --gyro-column gy)"
            } else {
                "; one column per --temp-column: repeat the flag, one for each model axis (--temp-column tx \
                 --temp-column ty)"
            })
        }
        CalError::MissingColumn { role: "time", .. } => Some(
            "; name the time column with --time-column (its unit with --time-unit), or give --sample-rate-hz \
             for a log without one; if line 1 is not the header (a terminal program's banner), skip it with \
             --skip-lines N; a file without a header: --columns",
        ),
        CalError::MissingColumn { .. } => Some(
            "; name the columns with --time-column, --temp-column and --gyro-column; if line 1 is not the \
             header (a terminal program's banner), skip it with --skip-lines N; a file without a header: \
             --columns",
        ),
        CalError::LogFormat { .. } => Some(
            "; see --skip-lines, --columns, --sample-rate-hz, --time-column, --comment, --delimiter and --decimal-mark \
             (docs/calibration-logs.md)",
        ),
        CalError::NoCalibrationPoints { .. } => {
            Some("; check --temp-column, or set --max-gap-s and --window-s to suit the temperature sampling")
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cause already quoted by the context above it is not printed again; other causes are.
    #[test]
    fn a_cause_quoted_by_its_context_is_not_repeated() {
        let io = std::io::Error::new(std::io::ErrorKind::AlreadyExists, "File exists (os error 17)");
        let quoted = anyhow::Error::new(io).context("rep: File exists (os error 17)");
        assert_eq!(error_paragraph(&quoted), "error: rep: File exists (os error 17)");
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory (os error 2)");
        let other = anyhow::Error::new(io).context("reading run.csv");
        assert_eq!(
            error_paragraph(&other),
            "error: reading run.csv\n  caused by: No such file or directory (os error 2)"
        );
    }
}
