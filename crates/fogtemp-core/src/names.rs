//! The column-names section (format version 4): the log columns each axis was fitted on, so a
//! reader can match a log's columns to the model's axes by name instead of by position.
//!
//! Layout, after the last axis section and before the CRC trailer:
//! `names_len` (u32, the section's bytes with this field), then per axis in order the gyro
//! column and the temperature column, each a one-byte length and that many bytes of UTF-8
//! (no control characters; length 0 = not recorded).

use crate::error::Error;
use crate::wire::{u32_at, NAMES_LEN_LEN};

/// The column names of one axis, as recorded by the writer (`""` = not recorded).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisColumns<'a> {
    /// The gyro column the axis was fitted on.
    pub gyro: &'a str,
    /// The temperature column that fed its features.
    pub temp: &'a str,
}

/// Checks the names section that starts at `offset` and runs to the end of `body` (the blob
/// without its CRC) for `axis_count` axes.
pub(crate) fn validate(body: &[u8], offset: usize, axis_count: u16) -> Result<(), Error> {
    let mut at = section_start(body, offset)?;
    for axis in 0..axis_count {
        for field in ["gyro_column", "temp_column"] {
            let (_, next) = name_at(body, at, field, axis)?;
            at = next;
        }
    }
    if at != body.len() {
        return Err(Error::LengthMismatch {
            field: "names_len",
            expected: at.saturating_sub(offset),
            found: body.len().saturating_sub(offset),
        });
    }
    Ok(())
}

/// The names of axis `index` in a validated section at `offset` (`None` past the last axis).
pub(crate) fn axis_columns(body: &[u8], offset: usize, index: usize) -> Option<AxisColumns<'_>> {
    let mut at = section_start(body, offset).ok()?;
    let mut axis = 0usize;
    loop {
        let (gyro, next) = name_at(body, at, "gyro_column", 0).ok()?;
        let (temp, next) = name_at(body, next, "temp_column", 0).ok()?;
        if axis == index {
            return Some(AxisColumns { gyro, temp });
        }
        axis = axis.checked_add(1)?;
        at = next;
    }
}

/// Where the first name starts, once `names_len` is found to cover the rest of `body`.
fn section_start(body: &[u8], offset: usize) -> Result<usize, Error> {
    let start = offset.saturating_add(NAMES_LEN_LEN);
    let names_len = u32_at(body, offset).ok_or(Error::Truncated {
        field: "names_len",
        needed: start,
        found: body.len(),
    })? as usize;
    let rest = body.len().saturating_sub(offset);
    if names_len != rest {
        return Err(Error::LengthMismatch { field: "names_len", expected: rest, found: names_len });
    }
    Ok(start)
}

/// The name at `at` (length byte, then the bytes) and where the next one starts.
fn name_at<'a>(body: &'a [u8], at: usize, field: &'static str, axis: u16) -> Result<(&'a str, usize), Error> {
    let len = usize::from(*body.get(at).ok_or(Error::Truncated {
        field,
        needed: at.saturating_add(1),
        found: body.len(),
    })?);
    let start = at.saturating_add(1);
    let end = start.saturating_add(len);
    let bytes = body.get(start..end).ok_or(Error::Truncated { field, needed: end, found: body.len() })?;
    let text = core::str::from_utf8(bytes).map_err(|_| Error::BadValue { field, axis, index: 0 })?;
    if text.chars().any(char::is_control) {
        return Err(Error::BadValue { field, axis, index: 0 });
    }
    Ok((text, end))
}
