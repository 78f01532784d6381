//! The option sets of the log-reader fuzz targets (`ingest_csv`, `ingest_parallel`), drawn
//! from two input bytes.

use fogtemp_cal::ingest::{DecimalMark, Delimiter, IngestOptions, LogFormat, TimeUnit};

/// The option set of the two option bytes `a` and `b`.
pub fn options(a: u8, b: u8) -> IngestOptions {
    let mut f = LogFormat::default();
    f.delimiter = match a & 0x07 {
        1 => Delimiter::Byte(b','),
        2 => Delimiter::Byte(b';'),
        3 => Delimiter::Byte(b'\t'),
        4 => Delimiter::Whitespace,
        5 => Delimiter::Byte(b'|'),
        _ => Delimiter::Auto,
    };
    if a & 0x08 != 0 {
        f.decimal_mark = DecimalMark::Comma;
        if f.delimiter == Delimiter::Byte(b',') {
            f.delimiter = Delimiter::Byte(b';');
        }
    }
    f.time_unit = match (a >> 5) & 0x03 {
        1 => TimeUnit::Milliseconds,
        2 => TimeUnit::DateTime,
        3 => TimeUnit::TimeOfDay,
        _ => TimeUnit::Seconds,
    };
    if a & 0x80 != 0 {
        f.column_names = vec!["time_s".into(), "temp_c".into(), "gyro_dph".into()];
    }
    f.skip_lines = u64::from(b & 0x03);
    if b & 0x04 != 0 {
        f.sample_rate_hz = Some(50.0);
        f.time_unit = TimeUnit::Seconds;
        if a & 0x80 != 0 {
            f.column_names = vec!["temp_c".into(), "gyro_dph".into()];
        }
    }
    if b & 0x08 != 0 {
        f.comment = None;
    }
    if b & 0x10 != 0 {
        f.gyro_columns = vec!["gyro_dph".into(), "g2".into()];
    }
    if b & 0x20 != 0 && f.time_unit == TimeUnit::DateTime {
        f.date_column = Some("date".into());
    }
    if b & 0x40 != 0 {
        f.temp_scale = 0.0625;
        f.temp_offset_c = -10.0;
    }
    // Impossible temperatures refused (the rows' checks expect physical ones).
    IngestOptions { format: f, skip_bad_rows: a & 0x10 != 0, keep_impossible_temperatures: false }
}
