//! The one error type of the core: small, `Copy`, and says what and where.

use core::fmt;

/// Everything that can go wrong in the core, with enough context to find the cause.
///
/// Field names are the names used in `docs/model-format.md`.
#[non_exhaustive]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Error {
    /// The blob ended before a field or section that must be there.
    Truncated {
        /// What was being read.
        field: &'static str,
        /// Bytes needed from the start of the blob.
        needed: usize,
        /// Bytes available.
        found: usize,
    },
    /// The blob does not start with `FOGM`.
    BadMagic,
    /// The format version is not one this build reads.
    UnsupportedVersion {
        /// Version this build reads.
        expected: u16,
        /// Version in the blob.
        found: u16,
    },
    /// A length or count field disagrees with the data.
    LengthMismatch {
        /// Which length field.
        field: &'static str,
        /// Value implied by the rest of the blob.
        expected: usize,
        /// Value found.
        found: usize,
    },
    /// An axis section's `section_len` differs from the length its header's counts imply.
    SectionLength {
        /// Axis section.
        axis: u16,
        /// Length the counts imply.
        expected: usize,
        /// `section_len` found.
        found: usize,
    },
    /// The CRC-32 trailer does not match the bytes.
    CrcMismatch {
        /// CRC computed over the blob.
        expected: u32,
        /// CRC stored in the trailer.
        found: u32,
    },
    /// A count, flag or enum field holds a value outside its allowed range.
    BadValue {
        /// Which field.
        field: &'static str,
        /// Axis section (file-header fields are [`Error::BadHeaderValue`]).
        axis: u16,
        /// Element index within the field's array (0 for scalars).
        index: u32,
    },
    /// A field of the log-time record (format version 5, at the end of the log-columns
    /// section) holds a value outside its allowed range.
    BadLogTime {
        /// Which field: `time_column`, `date_column`, `time_unit` or `sample_rate_hz`.
        field: &'static str,
    },
    /// A field of the log-reading record (format version 6, after the log-time record) or of
    /// the log-shape record after it (version 7) holds a value outside its allowed range.
    BadLogReading {
        /// Which field: `decimal_mark`; `delimiter`, `delimiter_byte`, `comment` or
        /// `column_names` of the log shape.
        field: &'static str,
    },
    /// A field of the run-metadata record (format version 8, after the log-shape record)
    /// holds a value outside its allowed range (until 2026-11-30 it was reported as a
    /// `BadLogReading`, without the value).
    BadRunMetadata {
        /// Which field: `input_rates`.
        field: &'static str,
        /// The value found.
        found: u64,
    },
    /// A field of the file header (before any axis section) holds a value outside its
    /// allowed range.
    BadHeaderValue {
        /// Which field.
        field: &'static str,
        /// The value found.
        found: u64,
    },
    /// A float field is NaN or infinite.
    NonFinite {
        /// Which field.
        field: &'static str,
        /// Axis section.
        axis: u16,
        /// Element index within the field's array (0 for scalars).
        index: u32,
    },
    /// An index points past the end of the array it refers to.
    IndexOutOfRange {
        /// Which field holds the index.
        field: &'static str,
        /// Axis section.
        axis: u16,
        /// Element holding the bad index.
        index: u32,
        /// The bad index value.
        value: u32,
        /// Length of the array it must index.
        limit: u32,
    },
    /// The mesh is not a consistent triangulation (neighbours not symmetric, hull not
    /// closed, triangle not counter-clockwise, stored transform not matching vertices), or
    /// the calibrated region is not a convex counter-clockwise polygon (`check` starts with
    /// `region`; any model kind has one).
    BadMesh {
        /// What check failed.
        check: &'static str,
        /// Axis section.
        axis: u16,
        /// Triangle or hull entry where it failed.
        index: u32,
    },
    /// The requested axis does not exist in this model.
    NoSuchAxis {
        /// Requested axis.
        requested: usize,
        /// Axes in the model.
        available: usize,
    },
    /// The feature tracker's compile-time capacity is smaller than the blob's block count.
    CapacityTooSmall {
        /// Blocks the model's feature settings need.
        needed: usize,
        /// Blocks the tracker can hold (its const generic `N`).
        capacity: usize,
    },
    /// A temperature sample, or a query's temperature or rate, was NaN or infinite.
    NonFiniteSample,
    /// The model evaluated to a value that is not finite at finite features: a blob whose
    /// stored floats are finite but too large (validation checks each float, not what they
    /// give together). The compensator holds its last bias and flags `WARMING_UP`.
    NonFiniteValue {
        /// Axis section.
        axis: u16,
    },
    /// A flash partition holds bytes after the blob that are not erased-flash padding
    /// (all `0xFF` or all `0x00`): [`crate::Model::from_flash`].
    TrailingBytes {
        /// Offset of the first byte that breaks the padding.
        offset: usize,
        /// The padding byte expected there (the first byte after the blob).
        fill: u8,
    },
    /// A sample's time is not after the previous sample's time.
    TimeNotIncreasing {
        /// Previous accepted time, microseconds.
        previous_us: u64,
        /// Rejected time, microseconds.
        found_us: u64,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated { field, needed, found } => {
                write!(f, "model blob truncated reading {field}: needs {needed} bytes, has {found}")
            }
            Error::BadMagic => f.write_str("not a fogtemp model blob (magic is not \"FOGM\")"),
            Error::UnsupportedVersion { expected, found } => write!(
                f,
                "model format version {found} is not supported (this build reads versions {} to {expected})",
                crate::wire::OLDEST_READABLE_VERSION
            ),
            Error::LengthMismatch { field: "total_len", expected, found } => write!(
                f,
                "total_len says the blob is {found} bytes but {expected} were given: bytes after the blob \
                 (a flash partition's padding is read with Model::from_flash)"
            ),
            Error::LengthMismatch { field, expected, found } => {
                write!(f, "{field} is {found} but the data implies {expected}")
            }
            Error::SectionLength { axis, expected, found } => write!(
                f,
                "axis {axis}: section_len is {found} but the counts in its header imply {expected}"
            ),
            Error::BadHeaderValue { field: "axis_count", found } => write!(
                f,
                "file header: axis_count is {found}, outside 1..={}",
                crate::wire::MAX_AXES
            ),
            Error::BadLogTime { field } => {
                write!(f, "log time: {field} holds a value outside its allowed range")
            }
            Error::BadLogReading { field } => {
                write!(f, "log reading: {field} holds a value outside its allowed range")
            }
            Error::BadRunMetadata { field, found } => {
                write!(f, "run metadata: {field} is {found}, outside its allowed range")
            }
            Error::BadHeaderValue { field, found } => {
                write!(f, "file header: {field} is {found}, outside its allowed range")
            }
            Error::CrcMismatch { expected, found } => {
                write!(f, "model blob corrupt: CRC-32 is {expected:#010x}, trailer says {found:#010x}")
            }
            Error::BadValue { field, axis, index } => {
                write!(f, "axis {axis}: {field}[{index}] holds a value outside its allowed range")
            }
            Error::NonFinite { field, axis, index } => {
                write!(f, "axis {axis}: {field}[{index}] is not a finite number")
            }
            Error::IndexOutOfRange { field, axis, index, value, limit } => {
                write!(f, "axis {axis}: {field}[{index}] = {value} is out of range (limit {limit})")
            }
            // The calibrated region shares the status (a poly-only model has one too).
            Error::BadMesh { check, axis, index } if check.starts_with("region") => {
                write!(f, "axis {axis}: calibrated-region check '{check}' failed at vertex {index}")
            }
            Error::BadMesh { check, axis, index } => {
                write!(f, "axis {axis}: mesh check '{check}' failed at element {index}")
            }
            Error::NoSuchAxis { requested, available } => match available {
                0 => write!(f, "axis {requested} requested but the model has no axes"),
                1 => write!(f, "axis {requested} requested but the model has 1 axis, numbered 0"),
                n => write!(f, "axis {requested} requested but the model has {n} axes, numbered 0 to {}", n - 1),
            },
            Error::CapacityTooSmall { needed, capacity } => {
                write!(f, "feature tracker holds {capacity} blocks but the model needs {needed}")
            }
            Error::NonFiniteSample => f.write_str("a temperature or rate is not a finite number"),
            Error::NonFiniteValue { axis } => write!(
                f,
                "axis {axis}: the model's value is not a finite number (stored coefficients or gradients too large for f32)"
            ),
            Error::TrailingBytes { offset, fill } => write!(
                f,
                "byte {offset} after the model blob breaks the erased-flash padding ({fill:#04x} expected; only all 0xff or all 0x00 is accepted)"
            ),
            Error::TimeNotIncreasing { previous_us, found_us } => {
                write!(f, "sample time {found_us} us is not after the previous sample at {previous_us} us")
            }
        }
    }
}

impl Error {
    /// The same error, naming `axis` where it names one (the mesh and the tracker do not
    /// know their axis; the axis that calls them does).
    pub(crate) fn at_axis(self, id: u16) -> Error {
        match self {
            Error::BadValue { field, index, .. } => Error::BadValue { field, axis: id, index },
            Error::NonFinite { field, index, .. } => Error::NonFinite { field, axis: id, index },
            Error::BadMesh { check, index, .. } => Error::BadMesh { check, axis: id, index },
            Error::IndexOutOfRange { field, index, value, limit, .. } => {
                Error::IndexOutOfRange { field, axis: id, index, value, limit }
            }
            other => other,
        }
    }
}

impl core::error::Error for Error {}
