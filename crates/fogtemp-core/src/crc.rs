//! CRC-32 (IEEE 802.3, the zlib/PNG one): reflected polynomial 0xEDB88320,
//! initial value and final XOR 0xFFFFFFFF. Check value: `crc32(b"123456789") == 0xCBF43926`.

/// Lookup table built at compile time (1 KiB of flash).
const TABLE: [u32; 256] = build_table();

// Evaluated at compile time: an out-of-range index would fail the build, not panic.
#[allow(clippy::indexing_slicing)]
const fn build_table() -> [u32; 256] {
    let mut table = [0u32; 256];
    let mut n = 0;
    while n < 256 {
        let mut c = n as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
            k += 1;
        }
        table[n] = c;
        n += 1;
    }
    table
}

/// CRC-32 (IEEE) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in bytes {
        let slot = ((crc ^ u32::from(b)) & 0xFF) as usize;
        // `slot` < 256 by the mask, so the fallback is never taken.
        crc = TABLE.get(slot).copied().unwrap_or(0) ^ (crc >> 8);
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::crc32;

    #[test]
    fn crc32_matches_standard_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }
}
