//! Byte layout of the model blob, format version 3 (spec: `docs/model-format.md`). Version 3
//! adds the hull gradients that `outside_policy = 3` needs (after the region, only with that
//! policy); a blob without that policy is written as version 2, byte for byte as before.
//! Version 1 blobs (no calibrated region: the same layout with [`AXIS_REGION_VERTEX_COUNT`]
//! and [`AXIS_POLY_OUTSIDE`] reserved as zero) are still read, with the polynomial
//! extrapolated.
//!
//! Every offset is a named constant so the reader here and the writer in `fogtemp-cal`
//! cannot drift apart. All integers and floats are little-endian; nothing is aligned,
//! every field is read with `from_le_bytes`, so a blob can sit at any address in flash.
//!
//! ```text
//! +--------------------+  offset 0
//! | file header (64 B) |  magic "FOGM", version, header_len, total_len, axis_count,
//! |                    |  reserved, tool_version[16], input_digest[32]
//! +--------------------+  64
//! | axis section 0     |  axis header (96 B) then payload:
//! |                    |    poly terms   P x  8 B
//! |                    |    vertices     V x 12 B
//! |                    |    triangles    T x 60 B
//! |                    |    hull edges   H x  8 B
//! |                    |    region       R x  8 B  (version 2; R = 0 in version 1)
//! |                    |    hull grads   H x  8 B  (version 3, outside_policy 3 only)
//! +--------------------+
//! | axis section 1 ... |
//! +--------------------+  total_len - 4
//! | CRC-32 (4 B)       |  over bytes [0, total_len - 4)
//! +--------------------+  total_len
//! ```

use core::ops::Range;

/// The four bytes every blob starts with.
pub const MAGIC: [u8; 4] = *b"FOGM";
/// The newest format version this build reads, and the one it writes for a blob that records
/// the log columns each axis was fitted on, the log's time and how its logs were read (the
/// log-columns section after the axis sections, ending with the log-time record and the
/// log-reading record), and its logs' shape when that is not the default (the log-shape
/// record, version 7); a blob whose logs had the default shape is written as version 6. A
/// blob whose fit had run metadata (each run's input rate) records what it did with the rates
/// in the run-metadata record after the log-shape record (version 8).
pub const FORMAT_VERSION: u16 = 8;
/// The version this build writes for a blob without column names whose mesh is continued by
/// stored gradients (`outside_policy = 3`, which needs it).
pub const FORMAT_VERSION_WITH_GRADIENTS: u16 = 3;
/// The version this build writes for every other blob without column names: version 2, whose
/// layout it has, so those blobs stay byte for byte what they were and readers of version 2
/// keep reading them.
pub const FORMAT_VERSION_WITHOUT_GRADIENTS: u16 = 2;
/// The oldest format version with the column-names section after the last axis section.
pub const FIRST_VERSION_WITH_COLUMN_NAMES: u16 = 4;
/// The oldest format version whose log-columns section ends with the log-time record (the
/// time column, date column, time unit and sample rate the fit read its logs with).
pub const FIRST_VERSION_WITH_LOG_TIME: u16 = 5;
/// The oldest format version whose log-columns section ends, after the log-time record, with
/// the log-reading record (the decimal mark and a digest of each calibration log).
pub const FIRST_VERSION_WITH_LOG_READING: u16 = 6;
/// The oldest format version whose log-columns section ends, after the log-reading record,
/// with the log-shape record (lines skipped, delimiter, comment prefix, headerless column
/// names).
pub const FIRST_VERSION_WITH_LOG_SHAPE: u16 = 7;
/// The oldest format version whose log-columns section ends, after the log-shape record (then
/// always present, the default shape included), with the run-metadata record: what the fit
/// did with its runs' input rates.
pub const FIRST_VERSION_WITH_RUN_METADATA: u16 = 8;
/// The run-metadata record: `input_rates` (u8: 1 taken off each run's gyro before the fit,
/// 2 given but not taken off).
pub const RUN_METADATA_LEN: usize = 1;
/// The log-shape record's fixed part before its names: `skip_lines` (u32), `delimiter` (u8),
/// `delimiter_byte` (u8) and `has_comment` (u8).
pub const LOG_SHAPE_FIXED_LEN: usize = 7;
/// The log-reading record's fixed part: `decimal_mark` (u8) and `log_count` (u16).
pub const LOG_READING_FIXED_LEN: usize = 3;
/// Bytes of one calibration log's digest in the log-reading record (the first 8 bytes of
/// the SHA-256 of the log's bytes: enough to recognise a log, not a security measure).
pub const LOG_DIGEST_LEN: usize = 8;
/// The longest column name the names section holds, in bytes (its length is one byte).
pub const MAX_COLUMN_NAME_LEN: usize = 255;
/// `names_len`: u32 at the start of the column-names section, the section's bytes with this
/// field.
pub const NAMES_LEN_LEN: usize = 4;
/// After each axis's two names: `gyro_dph_per_unit`, `temp_c_per_unit`, `temp_offset_c` (f64:
/// hosts read logs in f64, and these reproduce the fit's reading exactly).
pub const COLUMN_UNITS_LEN: usize = 24;
/// After the log-time record's two names: `time_unit` (u8) and `sample_rate_hz` (f64).
pub const LOG_TIME_FIXED_LEN: usize = 9;
/// The oldest format version whose `outside_policy` may be 3 (hull gradients present).
pub const FIRST_VERSION_WITH_GRADIENTS: u16 = 3;
/// The oldest format version this build reads: version 1 has no calibrated region (its
/// [`AXIS_REGION_VERTEX_COUNT`] and [`AXIS_POLY_OUTSIDE`] bytes are reserved, zero), so its
/// polynomial is extrapolated as before.
pub const OLDEST_READABLE_VERSION: u16 = 1;

/// File header length in bytes.
pub const FILE_HEADER_LEN: usize = 64;
/// `magic`: `b"FOGM"`.
pub const FILE_MAGIC: Range<usize> = 0..4;
/// `format_version`: u16.
pub const FILE_VERSION: Range<usize> = 4..6;
/// `header_len`: u16, must be [`FILE_HEADER_LEN`].
pub const FILE_HEADER_LEN_FIELD: Range<usize> = 6..8;
/// `total_len`: u32, whole blob including the CRC trailer.
pub const FILE_TOTAL_LEN: Range<usize> = 8..12;
/// `axis_count`: u16, 1..=[`MAX_AXES`].
pub const FILE_AXIS_COUNT: Range<usize> = 12..14;
/// `reserved`: u16, must be 0.
pub const FILE_RESERVED: Range<usize> = 14..16;
/// `tool_version`: 16 bytes of ASCII, NUL-padded.
pub const FILE_TOOL_VERSION: Range<usize> = 16..32;
/// `input_digest`: 32 bytes (SHA-256 of the calibration inputs, or zeros).
pub const FILE_INPUT_DIGEST: Range<usize> = 32..64;
/// Length of the CRC-32 trailer.
pub const CRC_LEN: usize = 4;

/// Axis section header length in bytes.
pub const AXIS_HEADER_LEN: usize = 96;
/// `section_len`: u32, header plus payload.
pub const AXIS_SECTION_LEN: Range<usize> = 0..4;
/// `axis_id`: u16, equal to the section's position.
pub const AXIS_ID: Range<usize> = 4..6;
/// `model_kind`: u16 bit set of [`KIND_POLY`] and [`KIND_MESH`], not zero.
pub const AXIS_MODEL_KIND: Range<usize> = 6..8;
/// `window_s`: f32, feature window length in seconds.
pub const AXIS_WINDOW_S: Range<usize> = 8..12;
/// `block_count`: u32, sub-blocks per window.
pub const AXIS_BLOCK_COUNT: Range<usize> = 12..16;
/// `min_blocks`: u32, blocks with data needed before features are reported.
pub const AXIS_MIN_BLOCKS: Range<usize> = 16..20;
/// `max_gap_s`: f32, a longer silence of the temperature channel restarts the tracker.
pub const AXIS_MAX_GAP_S: Range<usize> = 20..24;
/// `temp_offset_c`: f32; `x = (temp_c - temp_offset_c) * temp_scale_per_c`.
pub const AXIS_TEMP_OFFSET_C: Range<usize> = 24..28;
/// `temp_scale_per_c`: f32, > 0.
pub const AXIS_TEMP_SCALE_PER_C: Range<usize> = 28..32;
/// `rate_offset_c_per_min`: f32; `y = (rate - rate_offset) * rate_scale`.
pub const AXIS_RATE_OFFSET_C_PER_MIN: Range<usize> = 32..36;
/// `rate_scale_per_c_per_min`: f32, > 0.
pub const AXIS_RATE_SCALE_PER_C_PER_MIN: Range<usize> = 36..40;
/// `outside_policy`: u32, see [`crate::OutsidePolicy`].
pub const AXIS_OUTSIDE_POLICY: Range<usize> = 40..44;
/// `poly_term_count`: u32.
pub const AXIS_POLY_TERM_COUNT: Range<usize> = 44..48;
/// `vertex_count`: u32.
pub const AXIS_VERTEX_COUNT: Range<usize> = 48..52;
/// `triangle_count`: u32.
pub const AXIS_TRIANGLE_COUNT: Range<usize> = 52..56;
/// `hull_edge_count`: u32.
pub const AXIS_HULL_EDGE_COUNT: Range<usize> = 56..60;
/// `fit_point_count`: u32, calibration points the fit used (provenance).
pub const AXIS_FIT_POINT_COUNT: Range<usize> = 60..64;
/// `residual_rms_dph`: f32, fit residual RMS (provenance).
pub const AXIS_RESIDUAL_RMS_DPH: Range<usize> = 64..68;
/// `residual_max_abs_dph`: f32, largest absolute fit residual (provenance).
pub const AXIS_RESIDUAL_MAX_ABS_DPH: Range<usize> = 68..72;
/// `temp_min_c`: f32, calibrated temperature range (provenance).
pub const AXIS_TEMP_MIN_C: Range<usize> = 72..76;
/// `temp_max_c`: f32.
pub const AXIS_TEMP_MAX_C: Range<usize> = 76..80;
/// `rate_min_c_per_min`: f32, calibrated rate range (provenance).
pub const AXIS_RATE_MIN_C_PER_MIN: Range<usize> = 80..84;
/// `rate_max_c_per_min`: f32.
pub const AXIS_RATE_MAX_C_PER_MIN: Range<usize> = 84..88;
/// `region_vertex_count`: u32, vertices of the calibrated region (0, or 3..=
/// [`MAX_REGION_VERTICES`]); reserved (0) in version 1.
pub const AXIS_REGION_VERTEX_COUNT: Range<usize> = 88..92;
/// `poly_outside`: u16, what the polynomial does outside the calibrated region, see
/// [`crate::PolyOutside`]; reserved (0, extrapolate) in version 1.
pub const AXIS_POLY_OUTSIDE: Range<usize> = 92..94;
/// `selection`: u16 (reserved, 0, in version 1), how the model kind was chosen (provenance): low byte the method that
/// `fit --method auto` chose ([`SELECTION_NONE`] when the method was given, else
/// [`SELECTION_CUBIC_T`]..=[`SELECTION_HYBRID`]), high byte how
/// ([`SELECTION_BY_RUNS`], [`SELECTION_BY_GROUPS`], [`SELECTION_FALLBACK`]; 0 with
/// [`SELECTION_NONE`]).
pub const AXIS_SELECTION: Range<usize> = 94..96;

/// `selection` low byte: the method was given, not chosen.
pub const SELECTION_NONE: u8 = 0;
/// `selection` low byte: a cubic in temperature alone was chosen.
pub const SELECTION_CUBIC_T: u8 = 1;
/// `selection` low byte: the polynomial in (T, dT/dt) was chosen.
pub const SELECTION_POLY: u8 = 2;
/// `selection` low byte: the mesh was chosen.
pub const SELECTION_MESH: u8 = 3;
/// `selection` low byte: the hybrid (polynomial plus mesh) was chosen.
pub const SELECTION_HYBRID: u8 = 4;
/// `selection` high byte: by leave-one-run-out cross-validation.
pub const SELECTION_BY_RUNS: u8 = 0;
/// `selection` high byte: by leave-one-group-out (position) cross-validation.
pub const SELECTION_BY_GROUPS: u8 = 1;
/// `selection` high byte: too few runs to cross-validate; the stated default.
pub const SELECTION_FALLBACK: u8 = 2;

/// `model_kind` bit: the axis has a polynomial.
pub const KIND_POLY: u16 = 1;
/// `model_kind` bit: the axis has a mesh.
pub const KIND_MESH: u16 = 2;

/// Bytes per polynomial term: `temp_power` u8, `rate_power` u8, reserved u16, `coefficient_dph` f32.
pub const POLY_TERM_LEN: usize = 8;
/// Bytes per vertex: `x` f32, `y` f32 (normalised), `value_dph` f32.
pub const VERTEX_LEN: usize = 12;
/// Bytes per triangle record.
pub const TRIANGLE_LEN: usize = 60;
/// Triangle: origin `[ox, oy]` f32, the position of vertex 2. Transforms are relative to
/// it (`dx = x - ox`, `dy = y - oy`) so small triangles keep full f32 precision.
pub const TRI_ORIGIN: Range<usize> = 0..8;
/// Triangle: barycentric transform `[b0, b1, b2, b3]` f32: `l0 = b0 dx + b1 dy`,
/// `l1 = b2 dx + b3 dy`, `l2 = 1 - l0 - l1`.
pub const TRI_BARY: Range<usize> = 8..24;
/// Triangle: value plane `[p0, p1, p2]` f32: `value = p0 dx + p1 dy + p2` (`p2` is vertex 2's value).
pub const TRI_PLANE: Range<usize> = 24..36;
/// Triangle: neighbours u32 x3, neighbour k lies across the edge opposite vertex k.
pub const TRI_NEIGHBOURS: Range<usize> = 36..48;
/// Triangle: vertex indices u32 x3, counter-clockwise.
pub const TRI_VERTICES: Range<usize> = 48..60;
/// Bytes per hull edge: `triangle` u32, `edge` u32 (the edge opposite vertex `edge`).
pub const HULL_EDGE_LEN: usize = 8;
/// Bytes per calibrated-region vertex: `x` f32, `y` f32 (normalised), counter-clockwise
/// vertices of a convex polygon.
pub const REGION_VERTEX_LEN: usize = 8;
/// Bytes per hull gradient (version 3, `outside_policy = 3` only): `d_dx` f32, `d_dy` f32, the
/// mesh's continuation gradient (deg/h per normalised unit) at the start vertex of the hull
/// edge of the same index.
pub const HULL_GRADIENT_LEN: usize = 8;
/// Most calibrated-region vertices per axis (bounds the cost of holding at the boundary).
pub const MAX_REGION_VERTICES: u32 = 64;

/// Neighbour value meaning "this edge is on the convex hull".
pub const NO_NEIGHBOUR: u32 = u32::MAX;
/// Most axis sections in one blob.
pub const MAX_AXES: u16 = 16;
/// Highest power of either input in a polynomial term.
pub const MAX_POWER: u8 = 6;
/// Most polynomial terms per axis.
pub const MAX_POLY_TERMS: u32 = 64;
/// Most sub-blocks per feature window.
pub const MAX_BLOCKS: u32 = 4096;
/// Most triangles per axis (keeps every index and byte offset far from overflow).
pub const MAX_TRIANGLES: u32 = 1 << 22;

/// Byte length of an axis section with the given counts, or `None` on overflow.
/// `hull_gradients` is `hull_edges` with `outside_policy = 3`, else 0.
pub fn axis_section_len(
    poly_terms: u32,
    vertices: u32,
    triangles: u32,
    hull_edges: u32,
    region_vertices: u32,
    hull_gradients: u32,
) -> Option<usize> {
    let parts = [
        (poly_terms as usize).checked_mul(POLY_TERM_LEN)?,
        (vertices as usize).checked_mul(VERTEX_LEN)?,
        (triangles as usize).checked_mul(TRIANGLE_LEN)?,
        (hull_edges as usize).checked_mul(HULL_EDGE_LEN)?,
        (region_vertices as usize).checked_mul(REGION_VERTEX_LEN)?,
        (hull_gradients as usize).checked_mul(HULL_GRADIENT_LEN)?,
    ];
    parts.iter().try_fold(AXIS_HEADER_LEN, |acc, &p| acc.checked_add(p))
}

/// Reads `N` bytes at `range` of `bytes`, if present.
#[inline]
pub(crate) fn array<const N: usize>(bytes: &[u8], start: usize) -> Option<[u8; N]> {
    let end = start.checked_add(N)?;
    bytes.get(start..end)?.first_chunk::<N>().copied()
}

/// Little-endian u16 at `start`.
#[inline]
pub(crate) fn u16_at(bytes: &[u8], start: usize) -> Option<u16> {
    array::<2>(bytes, start).map(u16::from_le_bytes)
}

/// Little-endian u32 at `start`.
#[inline]
pub(crate) fn u32_at(bytes: &[u8], start: usize) -> Option<u32> {
    array::<4>(bytes, start).map(u32::from_le_bytes)
}

/// Little-endian f32 at `start`.
#[inline]
pub(crate) fn f32_at(bytes: &[u8], start: usize) -> Option<f32> {
    array::<4>(bytes, start).map(f32::from_le_bytes)
}

/// Little-endian f64 at `start` (the log-columns section's numbers only).
#[inline]
pub(crate) fn f64_at(bytes: &[u8], start: usize) -> Option<f64> {
    array::<8>(bytes, start).map(f64::from_le_bytes)
}
