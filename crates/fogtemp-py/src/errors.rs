//! Library errors as Python exceptions, with the libraries' own messages (the ones the
//! command line prints after `error:`), plus the hint the command line gives, in keyword
//! form.

use fogtemp_cal::ingest::BadRowKind;
use fogtemp_cal::CalError;
use fogtemp_sim::SimError;
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyRuntimeError, PyValueError};
use pyo3::PyErr;

/// The exception for a calibration-library error: `FileNotFoundError` / `OSError` for
/// files, `RuntimeError` for a writer self-check failure (a bug), `ValueError` for
/// everything the input decides (bad rows, missing columns, no calibration points, a fit
/// that cannot be made, an invalid model).
pub fn cal(e: CalError) -> PyErr {
    let message = format!("{e}{}", hint(&e));
    match &e {
        CalError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(message)
        }
        CalError::Io { .. } | CalError::Output { .. } => PyOSError::new_err(message),
        CalError::SelfCheck(_) => PyRuntimeError::new_err(message),
        _ => PyValueError::new_err(message),
    }
}

/// What to change in the call, for the errors a keyword fixes (the command line names its
/// flags in the same place: `--skip-bad-rows`, `--temp-column`, ...).
fn hint(e: &CalError) -> &'static str {
    match e {
        CalError::BadRow { row, .. } if row.looks_like_datetime() => {
            "; the time column holds date-times: pass time_unit='datetime'"
        }
        CalError::BadRow { row, .. } if row.looks_like_time_of_day() => {
            "; the time column holds times of day (or elapsed h:mm:ss): pass time_unit='time_of_day'"
        }
        CalError::BadRow { row, .. } if row.looks_like_thousands_separators() && !row.looks_like_decimal_comma() => {
            "; thousands separators in the numbers (a spreadsheet's number format): save the log without them \
             (skip_bad_rows=True would drop every row from 1000 on)"
        }
        CalError::BadRow { row, .. } if row.looks_like_decimal_comma() => {
            "; the log seems to write numbers with a decimal comma: pass decimal_mark='comma'"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::PointWithDecimalComma => {
            "; the log writes decimal points? pass decimal_mark='point' (a model fitted on decimal-comma logs \
             reads its logs so unless told)"
        }
        // A word for a missing value (before the text-row arms: a row of them is a text row).
        CalError::BadRow { row, .. } if row.looks_like_missing_marker() => {
            "; a mark for a missing reading? in a temperature column empty those cells: an empty temperature cell \
             is read as no reading (skip_bad_rows=True would drop the rows, gyro samples and all); a time or gyro \
             value missing: skip_bad_rows=True skips its row"
        }
        CalError::BadRow { row, .. } if row.looks_like_repeated_header() => {
            "; the header again (a logger restart, or two logs joined)? split the file there, each part a run \
             (skip_bad_rows=True would skip it, and then, if the time started again, every row until it passes \
             the old one)"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::TextRow => {
            "; a banner above the data (a terminal program's log line)? skip it with skip_lines=N; a units row \
             under the header: skip both with skip_lines=N and name the columns with columns=[...], which the \
             model records for validate and compensate (skip_bad_rows=True also skips the row, but has to be \
             passed again at every step)"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::ShortSpacedRow => {
            "; a row cut short (as a serial capture's): pass skip_bad_rows=True to skip such rows (listed); a \
             blank cell: write the log with another delimiter (a comma keeps it in its place); if the header's \
             names hold spaces, name the columns in order with skip_lines=1, columns=[...]"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::EmptyCell => {
            "; a time, date or gyro cell left empty: a lost sample? (skip_bad_rows=True skips such rows, listed; a row with a temperature and \
             no gyro reading at all is read as a temperature row, its reading going with the next sample: \
             channels logged on separate rows)"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::DuplicateTime => {
            "; repeated time stamps: a clock coarser than the sample rate? pass sample_rate_hz= to time the rows by \
             their index (skip_bad_rows=True would keep one row per stamp and drop the rest)"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::BackwardTime => {
            "; the time goes back: a logger restart (a new run starts here: split the file there), two logs \
             joined, a 32-bit counter that wrapped (if the time before was near 4294.97 s from microseconds or \
             4294967 s from milliseconds: pass sample_rate_hz= to time the rows by their index), or a corrupted \
             stamp in the row before that jumps ahead? skip_bad_rows=True would drop every row until the time \
             passes the old one"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::NotADateTime => {
            "; date-times are read in ISO 8601 (2026-11-24T23:30:00, or with a space, optional .fff and Z or \
             +hh:mm, or a dotted day-first date, DD.MM.YYYY hh:mm:ss); convert other formats first (MM/DD/YYYY and DD/MM/YYYY cannot be told apart), or pass \
             sample_rate_hz= to time the rows by their index"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::NotATimeOfDay => {
            "; times of day are read as hh:mm[:ss[.fff]] on a 24-hour clock, elapsed times as h:mm:ss with hours \
             that may pass 24; convert others first (11:30:00 PM, 1.02:03:04), or pass sample_rate_hz= to time the \
             rows by their index"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::RateBeyondRange => {
            "; a logger's overload code: skip_bad_rows=True skips such rows (listed); a unit or scale far off: \
             check gyro_unit=/gyro_scale="
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::ImpossibleTemperature => {
            "; raw counts or kelvin? pass temp_scale=/temp_offset=; a logger's mark for a missing reading: empty \
             the cell, or skip_bad_rows=True"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::SplitThousands => {
            "; write the numbers without thousands separators (1000.5; a spreadsheet's number format adds them): \
             skip_bad_rows=True would drop every row from the first such number on"
        }
        CalError::BadRow { row, .. } if row.kind == BadRowKind::NulBytes => {
            "; skip_bad_rows=True skips such lines and lists them"
        }
        CalError::BadRow { .. } => "; pass skip_bad_rows=True to skip such rows",
        CalError::MissingColumn { column, role: "gyro" | "temperature", .. } if column.contains(',') => {
            "; one column per name: pass a list, one for each model axis (gyro_column=['gx', 'gy'], temp_column=['tx', 'ty'])"
        }
        CalError::NoCalibrationPoints { .. } => {
            "; check temp_column (for arrays, the temperature array: NaN is no reading), or set max_gap_s and window_s \
             to suit the temperature sampling"
        }
        _ => "",
    }
}

/// The exception for a simulator error (a calibration-library error inside keeps its type).
pub fn sim(e: SimError) -> PyErr {
    match e {
        SimError::Cal(c) => cal(c),
        other => PyValueError::new_err(other.to_string()),
    }
}

/// `ValueError` for a model blob the core refuses, as the command line says it.
pub fn model(source: &str, e: fogtemp_core::Error) -> PyErr {
    if let fogtemp_core::Error::LengthMismatch { field: "total_len", expected, found } = e {
        // The core's text points to Rust's `Model::from_flash`; here the fix is a slice.
        if found < expected {
            return PyValueError::new_err(format!(
                "{source}: not a valid model: total_len says the blob is {found} bytes but {expected} were \
                 given: bytes after the blob (a flash dump's padding?); pass data[:{found}]"
            ));
        }
    }
    PyValueError::new_err(format!("{source}: not a valid model: {e}"))
}

/// `ValueError` with `message`.
pub fn value(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// `TypeError` with `message`.
pub fn type_(message: impl Into<String>) -> PyErr {
    pyo3::exceptions::PyTypeError::new_err(message.into())
}
