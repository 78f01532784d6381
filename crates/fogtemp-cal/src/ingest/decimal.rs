//! The decimal fast path: one pass over a plain record's needed cells, converting plain
//! decimals to exactly the value `fast-float2` would give.

use memchr::{memchr, memchr2, memchr_iter};

use super::columns::SKIP;

/// Scans the needed cells of a record at `pos` in one pass. Succeeds only for a record
/// without quotes whose needed cells are empty (NaN in `values`) or plain decimals, and
/// returns the index of its terminator; `None` sends the record to the general path
/// (also when it runs past the data in memory).
#[inline]
pub(super) fn fast_fields(
    buf: &[u8],
    mut pos: usize,
    delimiter: u8,
    roles: &[usize],
    named_fields: usize,
    values: &mut [f64],
) -> Option<usize> {
    let last = roles.len().checked_sub(1)?;
    for (field, &role) in roles.iter().enumerate() {
        if role == SKIP {
            loop {
                let b = *buf.get(pos)?;
                if b == delimiter {
                    break;
                }
                if matches!(b, b'\n' | b'\r' | b'"') {
                    return None;
                }
                pos += 1;
            }
        } else {
            let (value, end) = scan_decimal(buf, pos, delimiter)?;
            *values.get_mut(role)? = value;
            pos = end;
        }
        let b = *buf.get(pos)?;
        if field == last {
            if b != delimiter {
                return Some(pos);
            }
            // Fields the log has beyond the ones used: find the end, refuse quotes and more
            // fields than the header names (the general path judges them).
            let rest = buf.get(pos..)?;
            let len = memchr2(b'\n', b'\r', rest)?;
            let fields = roles.len() + memchr_iter(delimiter, &rest[..len]).count();
            return (memchr(b'"', &rest[..len]).is_none() && fields <= named_fields).then_some(pos + len);
        }
        if b != delimiter {
            return None;
        }
        pos += 1;
    }
    None
}

/// `10^i`, exact in `f64`.
const POW10: [f64; 16] =
    [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15];

/// A plain decimal cell (`-?digits[.digits]`, or empty → NaN) at `start`, ended by the
/// delimiter or a terminator; returns the value and the index of that end. The value is
/// the correctly rounded one, like `fast_float2::parse`: with at most 15 digits the
/// integer and `10^k` are exact in `f64` and the division rounds once; longer ones go to
/// `fast_float2`.
#[inline]
fn scan_decimal(buf: &[u8], start: usize, delimiter: u8) -> Option<(f64, usize)> {
    let negative = buf.get(start) == Some(&b'-');
    let mut pos = start + usize::from(negative);
    let mut mantissa = 0u64;
    let int_start = pos;
    pos += digit_run(buf, pos, &mut mantissa);
    let mut digits = pos - int_start;
    let mut decimals = 0;
    if buf.get(pos) == Some(&b'.') {
        pos += 1;
        decimals = digit_run(buf, pos, &mut mantissa);
        pos += decimals;
        digits += decimals;
    }
    let end = *buf.get(pos)?;
    if end != delimiter && end != b'\n' && end != b'\r' {
        return None;
    }
    if digits == 0 {
        // Only a truly empty cell; "-", "." and the like are for the general path.
        return (pos == start).then_some((f64::NAN, pos));
    }
    if digits <= 15 {
        // Below 10^15, so the signed conversion (one instruction) is exact.
        let value = mantissa as i64 as f64 / POW10[decimals];
        return Some((if negative { -value } else { value }, pos));
    }
    match fast_float2::parse::<f64, _>(&buf[start..pos]) {
        Ok(v) if v.is_finite() => Some((v, pos)),
        _ => None,
    }
}

/// Appends the ASCII digits at `pos` to `mantissa` (wrapping past 19 digits: the caller
/// then does not use it) and returns how many there were. A plain loop beats eight-byte
/// tricks here: the predictor learns the log's digit counts, so field ends do not wait
/// on arithmetic.
#[inline]
fn digit_run(buf: &[u8], pos: usize, mantissa: &mut u64) -> usize {
    let mut count = 0;
    for &b in buf.get(pos..).unwrap_or_default() {
        let digit = b.wrapping_sub(b'0');
        if digit >= 10 {
            break;
        }
        *mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(digit));
        count += 1;
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_spellings_match_the_general_parser() {
        let cells = [
            "0",
            "-0",
            "007",
            "1.",
            ".5",
            "-.5",
            "-1.",
            "+1",
            " 1",
            "1 ",
            "1e3",
            "1E-3",
            "0.1",
            "0.3",
            "123456789012345",
            "1234567890123456",
            "0.000000000000001",
            "0.1234567890123456789",
            "99999999999999999999999",
            "9007199254740993",
            "-12.3456789012345",
            "1.7976931348623157",
            "1..2",
            "1.2.3",
            "--1",
            "-",
            ".",
            "",
        ];
        for cell in cells {
            let line = format!("{cell},");
            let fast = scan_decimal(line.as_bytes(), 0, b',').map(|(v, end)| (v.to_bits(), end));
            let general = match cell.trim_ascii() {
                "" => Some(f64::NAN),
                t => fast_float2::parse::<f64, _>(t).ok(),
            };
            if let Some((bits, end)) = fast {
                assert_eq!(end, cell.len(), "{cell:?}");
                assert_eq!(Some(bits), general.map(f64::to_bits), "{cell:?}");
            }
        }
    }

    #[test]
    fn random_decimals_convert_exactly() {
        let mut state = 0x1234_5678_9abc_def0u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..200_000 {
            let r = next();
            let int_digits = (r % 9) as usize;
            let frac_digits = ((r >> 8) % 12) as usize;
            let mut cell = String::new();
            if r & (1 << 20) != 0 {
                cell.push('-');
            }
            let mut d = next();
            for _ in 0..int_digits {
                cell.push(char::from(b'0' + (d % 10) as u8));
                d /= 10;
            }
            if frac_digits > 0 || r & (1 << 21) != 0 {
                cell.push('.');
            }
            let mut d = next();
            for _ in 0..frac_digits {
                cell.push(char::from(b'0' + (d % 10) as u8));
                d /= 10;
            }
            let line = format!("{cell}\n");
            let fast = scan_decimal(line.as_bytes(), 0, b',').map(|(v, _)| v.to_bits());
            let general = fast_float2::parse::<f64, _>(cell.as_bytes()).ok().map(f64::to_bits);
            if fast.is_some() && !cell.is_empty() {
                assert_eq!(fast, general, "{cell:?}");
            }
        }
    }
}
