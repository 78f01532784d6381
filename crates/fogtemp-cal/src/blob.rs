//! Model blob writer (format version 4 with column names, 5 with the log time, 6 with the
//! log reading, 7 with a log shape other than the default, 8 with what the fit did with its
//! runs' input rates; without column names 2, or 3 with a mesh continued by stored gradients;
//! spec in `docs/model-format.md`, offsets in
//! [`fogtemp_core::wire`]). Every blob is read back through `Model::from_bytes`
//! before it is returned, so a writer bug is reported here instead of in firmware.

use fogtemp_core::wire::*;
use fogtemp_core::{
    AxisProvenance, FeatureSettings, InputRates, LogDelimiter, LogTimeUnit, Model, Normalisation,
    OutsidePolicy, PolyOutside, PolyTerm,
};

use crate::error::{CalError, EncodeProblem};
use crate::ingest::{Delimiter, LogFormat};
use crate::mesh::MeshModel;

/// One gyro axis to encode.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisModel {
    /// Feature tracker settings firmware must use.
    pub features: FeatureSettings,
    /// Input normalisation (shared by polynomial and mesh).
    pub normalisation: Normalisation,
    /// What the mesh returns outside its hull.
    pub outside_policy: OutsidePolicy,
    /// Polynomial terms (empty: no polynomial).
    pub poly: Vec<PolyTerm>,
    /// Mesh (None: no mesh).
    pub mesh: Option<MeshModel>,
    /// Fit statistics and calibrated range.
    pub provenance: AxisProvenance,
    /// The calibrated region: counter-clockwise vertices of a convex polygon in the
    /// normalised plane (see [`calibrated_region`]); empty for none.
    pub region: Vec<[f32; 2]>,
    /// What the polynomial does outside `region` (hold needs a region).
    pub poly_outside: PolyOutside,
}

/// A whole model file.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelFile {
    /// Writer version, at most 16 ASCII bytes (longer is cut).
    pub tool_version: String,
    /// SHA-256 (or other 32-byte digest) of the calibration inputs.
    pub input_digest: [u8; 32],
    /// Axes, in order.
    pub axes: Vec<AxisModel>,
    /// The log columns each axis was fitted on, one per axis (written as format version 4),
    /// or empty for none (version 2, or 3 with stored gradients, as before).
    pub columns: Vec<ColumnNames>,
    /// How the fit read its logs' time (written, with `columns`, as format version 5 when it
    /// records one; the default records none).
    pub log_time: LogTimeRecord,
    /// How the fit read its logs' numbers and which logs they were (written, with `columns`,
    /// as format version 6 when it records either; the default records neither).
    pub log_reading: LogReadingRecord,
    /// What the fit did with its runs' true input rates, when it had run metadata (written,
    /// with `columns`, as the run-metadata record of format version 8); `None` without.
    pub input_rates: Option<InputRates>,
}

/// How the fit read its logs' numbers, and a digest of each: the log-reading record of
/// format version 6.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LogReadingRecord {
    /// The logs wrote numbers with a decimal comma.
    pub decimal_comma: bool,
    /// Per calibration log, in the order the fit read them: the first 8 bytes of the SHA-256
    /// of its bytes (of its samples for a run given as arrays); more than 65535 do not encode.
    pub log_digests: Vec<[u8; LOG_DIGEST_LEN]>,
    /// The logs' shape (written as the log-shape record of format version 7 when it is not
    /// the default).
    pub shape: LogShapeRecord,
}

impl LogReadingRecord {
    /// Whether it records anything (a decimal comma, a log's digest, or a shape other than
    /// the default).
    pub fn is_recorded(&self) -> bool {
        self.decimal_comma || !self.log_digests.is_empty() || self.shape.is_recorded()
    }

    /// The record of logs read with `decimal_comma` whose full SHA-256 digests are `digests`.
    pub fn of_logs(decimal_comma: bool, digests: &[[u8; 32]]) -> Self {
        let log_digests = digests.iter().map(short_digest).collect();
        Self { decimal_comma, log_digests, shape: LogShapeRecord::default() }
    }

    /// What `model` records (the default before format version 6).
    pub fn of(model: &Model<'_>) -> Self {
        model.log_reading().map_or_else(Self::default, |r| Self {
            decimal_comma: r.decimal_comma,
            log_digests: (0..r.log_count()).filter_map(|i| r.log_digest(i)).collect(),
            shape: LogShapeRecord::of(model),
        })
    }
}

/// The shape of the fit's logs: the log-shape record of format version 7. The default is the
/// default [`LogFormat`]'s shape, which a blob does not record.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogShapeRecord {
    /// Lines dropped unread at the start of each log.
    pub skip_lines: u64,
    /// How the fields are separated.
    pub delimiter: Delimiter,
    /// The comment prefix; `None` for no comment lines.
    pub comment: Option<String>,
    /// The column names of logs without a header row; empty when they have one.
    pub column_names: Vec<String>,
}

impl Default for LogShapeRecord {
    fn default() -> Self {
        Self::of_format(&LogFormat::default())
    }
}

impl LogShapeRecord {
    /// The shape `format` reads.
    pub fn of_format(format: &LogFormat) -> Self {
        Self {
            skip_lines: format.skip_lines,
            delimiter: format.delimiter,
            comment: format.comment.clone(),
            column_names: format.column_names.clone(),
        }
    }

    /// Sets `format` to read this shape.
    pub fn apply_to(&self, format: &mut LogFormat) {
        format.skip_lines = self.skip_lines;
        format.delimiter = self.delimiter;
        format.comment.clone_from(&self.comment);
        format.column_names.clone_from(&self.column_names);
    }

    /// Whether it differs from the default shape (only then is it written).
    pub fn is_recorded(&self) -> bool {
        *self != Self::default()
    }

    /// Whether the record can hold it: at most `u32::MAX` lines skipped, a delimiter byte
    /// that is ASCII and not a quote, line end or NUL, and a comment prefix and at most 255
    /// column names of 1 to 255 bytes without control characters. A shape it cannot hold is
    /// not written (the logs' shape has to be named again when the model is replayed); with
    /// run metadata after it, the default shape is written in its place.
    pub fn is_storable(&self) -> bool {
        let delimiter = match self.delimiter {
            Delimiter::Byte(b) => b.is_ascii() && !matches!(b, 0 | b'"' | b'\n' | b'\r'),
            Delimiter::Auto | Delimiter::Whitespace => true,
        };
        let comment = self.comment.as_deref().is_none_or(|c| !c.is_empty() && storable_name(c));
        let names = self.column_names.len() <= usize::from(u8::MAX)
            && self.column_names.iter().all(|n| !n.is_empty() && storable_name(n));
        u32::try_from(self.skip_lines).is_ok() && delimiter && comment && names
    }

    /// What `model` records (the default before format version 7, or when it records none).
    pub fn of(model: &Model<'_>) -> Self {
        model.log_shape().map_or_else(Self::default, |shape| Self {
            skip_lines: u64::from(shape.skip_lines),
            delimiter: match shape.delimiter {
                LogDelimiter::Detected => Delimiter::Auto,
                LogDelimiter::Byte(b) => Delimiter::Byte(b),
                LogDelimiter::Whitespace => Delimiter::Whitespace,
            },
            comment: shape.comment.map(str::to_string),
            column_names: (0..shape.column_count())
                .filter_map(|i| shape.column_name(i))
                .map(str::to_string)
                .collect(),
        })
    }
}

/// The part of a log's SHA-256 the log-reading record keeps.
pub fn short_digest(digest: &[u8; 32]) -> [u8; LOG_DIGEST_LEN] {
    let mut short = [0; LOG_DIGEST_LEN];
    short.copy_from_slice(&digest[..LOG_DIGEST_LEN]);
    short
}

/// How the fit read its logs' time: the log-time record of format version 5.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LogTimeRecord {
    /// The time column; empty for a log without one (time from `sample_rate_hz`) or when not
    /// recorded.
    pub column: String,
    /// The column with each row's date, read together with the time column; empty for none.
    pub date_column: String,
    /// The time column's unit.
    pub unit: LogTimeUnit,
    /// The sample rate of a log without a time column, Hz; 0 otherwise.
    pub sample_rate_hz: f64,
}

impl LogTimeRecord {
    /// Whether it records anything (a time column, or a sample rate).
    pub fn is_recorded(&self) -> bool {
        !self.column.is_empty() || self.sample_rate_hz > 0.0
    }

    /// What `model` records (the default before format version 5, or when it records none).
    pub fn of(model: &Model<'_>) -> Self {
        model.log_time().map_or_else(Self::default, |t| Self {
            column: t.column.to_string(),
            date_column: t.date_column.to_string(),
            unit: t.unit,
            sample_rate_hz: t.sample_rate_hz,
        })
    }
}

/// The log columns one axis was fitted on, and how their numbers were read.
#[derive(Clone, Debug, PartialEq)]
pub struct ColumnNames {
    /// The gyro column.
    pub gyro: String,
    /// The temperature column that fed the axis's features.
    pub temp: String,
    /// Deg/h per unit of the gyro column (the unit's factor times any extra scale).
    pub gyro_dph_per_unit: f64,
    /// Deg C per unit of the temperature column.
    pub temp_c_per_unit: f64,
    /// Added after the scale, deg C.
    pub temp_offset_c: f64,
}

impl Default for ColumnNames {
    /// No names; numbers read as deg/h and deg C.
    fn default() -> Self {
        Self {
            gyro: String::new(),
            temp: String::new(),
            gyro_dph_per_unit: 1.0,
            temp_c_per_unit: 1.0,
            temp_offset_c: 0.0,
        }
    }
}

impl ColumnNames {
    /// What an axis of `model` records (`None` before format version 4).
    pub fn of(model: &Model<'_>, axis: usize) -> Option<Self> {
        model.axis_columns(axis).map(|c| Self {
            gyro: c.gyro.to_string(),
            temp: c.temp.to_string(),
            gyro_dph_per_unit: c.gyro_dph_per_unit,
            temp_c_per_unit: c.temp_c_per_unit,
            temp_offset_c: c.temp_offset_c,
        })
    }
}

/// The version string this crate writes into blobs.
pub fn tool_version() -> String {
    format!("fogtemp {}", env!("CARGO_PKG_VERSION"))
}

/// Encodes `model` (format version 4 with column names, else 2 or 3) and validates it with
/// the core reader.
///
/// # Errors
/// [`CalError::Encode`] if a count exceeds the format's limits; [`CalError::SelfCheck`]
/// if the core rejects the result (for example a sliver triangle whose f32 transform
/// cannot reproduce its vertices).
pub fn encode(model: &ModelFile) -> Result<Vec<u8>, CalError> {
    encode_with_selection(model, &[])
}

/// [`encode`], recording per axis how its model kind was chosen in the axis header's
/// `selection` field (`fogtemp_core::wire::AXIS_SELECTION`; axes beyond `selection` get 0,
/// "the method was given"). Codes come from [`crate::selection::Selection::blob_code`].
///
/// # Errors
/// As [`encode`]; [`CalError::SelfCheck`] for a code the core does not know.
pub fn encode_with_selection(model: &ModelFile, selection: &[u16]) -> Result<Vec<u8>, CalError> {
    if model.axes.is_empty() || model.axes.len() > usize::from(MAX_AXES) {
        return Err(CalError::Encode(EncodeProblem::AxisCount {
            axes: model.axes.len(),
            max: usize::from(MAX_AXES),
        }));
    }
    let mut out = vec![0u8; FILE_HEADER_LEN];
    out[FILE_MAGIC].copy_from_slice(&MAGIC);
    // The lowest version that holds the model: 3 only where the hull gradients need it, so
    // every other blob is byte for byte what it was, and readers of version 2 still take it.
    // Column names need version 4, which readers of 2 and 3 refuse.
    let needs_gradients = model.axes.iter().any(|a| a.outside_policy == OutsidePolicy::StoredGradients);
    if !model.columns.is_empty() && model.columns.len() != model.axes.len() {
        return Err(CalError::Encode(EncodeProblem::ColumnNameCount {
            names: model.columns.len(),
            axes: model.axes.len(),
        }));
    }
    // The log-time record needs version 5, the log-reading record 6 (with the log-time record
    // before it, recording nothing if need be); a model with columns and neither stays
    // version 4.
    // The log-shape record needs version 7, after the two records; written only when the
    // shape is not the default, so other blobs stay version 6 byte for byte.
    // The run-metadata record needs version 8, after a log-shape record (the default shape
    // written out if need be); written only with run metadata. A shape the record cannot hold
    // is written as the default one, which readers take as "not recorded", as when no record
    // is written (until 2026-11-30 it dropped the run-metadata record with it: review31a F4).
    let default_shape = LogShapeRecord::default();
    let shape = Some(&model.log_reading.shape).filter(|s| s.is_storable()).unwrap_or(&default_shape);
    let with_rates = !model.columns.is_empty() && model.input_rates.is_some();
    let with_shape = with_rates || (!model.columns.is_empty() && shape.is_recorded());
    let with_reading = with_shape || (!model.columns.is_empty() && model.log_reading.is_recorded());
    let with_time = with_reading || (!model.columns.is_empty() && model.log_time.is_recorded());
    let version = match (model.columns.is_empty(), with_time, with_reading, needs_gradients) {
        (false, _, true, _) if with_rates => FIRST_VERSION_WITH_RUN_METADATA,
        (false, _, true, _) if with_shape => FIRST_VERSION_WITH_LOG_SHAPE,
        (false, _, true, _) => FIRST_VERSION_WITH_LOG_READING,
        (false, true, false, _) => FIRST_VERSION_WITH_LOG_TIME,
        (false, false, _, _) => FIRST_VERSION_WITH_COLUMN_NAMES,
        (true, _, _, true) => FORMAT_VERSION_WITH_GRADIENTS,
        (true, _, _, false) => FORMAT_VERSION_WITHOUT_GRADIENTS,
    };
    put_u16(&mut out, FILE_VERSION.start, version);
    put_u16(&mut out, FILE_HEADER_LEN_FIELD.start, FILE_HEADER_LEN as u16);
    put_u16(&mut out, FILE_AXIS_COUNT.start, model.axes.len() as u16);
    let version = model.tool_version.as_bytes();
    let n = version.len().min(FILE_TOOL_VERSION.len());
    out[FILE_TOOL_VERSION.start..FILE_TOOL_VERSION.start + n].copy_from_slice(&version[..n]);
    out[FILE_INPUT_DIGEST].copy_from_slice(&model.input_digest);
    for (id, axis) in model.axes.iter().enumerate() {
        encode_axis(&mut out, id as u16, axis, selection.get(id).copied().unwrap_or(0))?;
    }
    let names_start = out.len();
    if !model.columns.is_empty() {
        encode_column_names(&mut out, &model.columns, with_time.then_some(&model.log_time));
        if with_reading {
            encode_log_reading(&mut out, &model.log_reading)?;
            if with_shape {
                encode_log_shape(&mut out, shape);
            }
            if let Some(rates) = model.input_rates.filter(|_| with_rates) {
                out.push(rates.code());
            }
            let len = out.len() - names_start;
            put_u32(&mut out, names_start, len as u32);
        }
    }
    let total = out.len() + CRC_LEN;
    let total_u32 = u32::try_from(total)
        .map_err(|_| CalError::Encode(EncodeProblem::TooLarge { what: "blob bytes", count: total }))?;
    put_u32(&mut out, FILE_TOTAL_LEN.start, total_u32);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Model::from_bytes(&out).map_err(CalError::SelfCheck)?;
    Ok(out)
}

/// The log-columns section (`docs/model-format.md`, "Log columns"). A name the section
/// cannot hold (over 255 bytes, or with a control character) is written as not recorded.
/// With `log_time`, the section ends with the log-time record (version 5); a time or date
/// column it cannot hold is written as not recorded, and so is the record then.
fn encode_column_names(out: &mut Vec<u8>, columns: &[ColumnNames], log_time: Option<&LogTimeRecord>) {
    let start = out.len();
    out.extend_from_slice(&[0; NAMES_LEN_LEN]);
    for c in columns {
        for name in [&c.gyro, &c.temp] {
            push_name(out, name);
        }
        for v in [c.gyro_dph_per_unit, c.temp_c_per_unit, c.temp_offset_c] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    if let Some(time) = log_time {
        let storable = storable_name(&time.column) && storable_name(&time.date_column);
        let valid_rate = time.sample_rate_hz.is_finite()
            && time.sample_rate_hz >= 0.0
            && (time.sample_rate_hz == 0.0 || time.column.is_empty());
        let with_date = time.date_column.is_empty() || time.unit == LogTimeUnit::DateTime;
        let record =
            if storable && valid_rate && with_date { time.clone() } else { LogTimeRecord::default() };
        push_name(out, &record.column);
        push_name(out, &record.date_column);
        out.push(record.unit.code());
        out.extend_from_slice(&record.sample_rate_hz.to_le_bytes());
    }
    let len = out.len() - start;
    put_u32(out, start, len as u32);
}

/// The log-reading record (version 6) at the end of the log-columns section (whose length
/// the caller writes again).
fn encode_log_reading(out: &mut Vec<u8>, reading: &LogReadingRecord) -> Result<(), CalError> {
    let count = u16::try_from(reading.log_digests.len()).map_err(|_| {
        CalError::Encode(EncodeProblem::TooLarge {
            what: "calibration logs",
            count: reading.log_digests.len(),
        })
    })?;
    out.push(u8::from(reading.decimal_comma));
    out.extend_from_slice(&count.to_le_bytes());
    for digest in &reading.log_digests {
        out.extend_from_slice(digest);
    }
    Ok(())
}

/// The log-shape record (version 7) after the log-reading record, for a shape
/// [`LogShapeRecord::is_storable`] says it can hold.
fn encode_log_shape(out: &mut Vec<u8>, shape: &LogShapeRecord) {
    out.extend_from_slice(&u32::try_from(shape.skip_lines).unwrap_or(u32::MAX).to_le_bytes());
    let (code, byte) = match shape.delimiter {
        Delimiter::Auto => (0, 0),
        Delimiter::Byte(b) => (1, b),
        Delimiter::Whitespace => (2, 0),
    };
    out.extend_from_slice(&[code, byte, u8::from(shape.comment.is_some())]);
    push_name(out, shape.comment.as_deref().unwrap_or(""));
    out.push(shape.column_names.len() as u8);
    for name in &shape.column_names {
        push_name(out, name);
    }
}

/// Whether the section can hold `name` (at most 255 bytes, no control character).
fn storable_name(name: &str) -> bool {
    name.len() <= MAX_COLUMN_NAME_LEN && !name.chars().any(char::is_control)
}

/// A one-byte length and the name's bytes; a name the section cannot hold as not recorded.
fn push_name(out: &mut Vec<u8>, name: &str) {
    let bytes = if storable_name(name) { name.as_bytes() } else { &[] };
    out.push(bytes.len() as u8);
    out.extend_from_slice(bytes);
}

fn encode_axis(out: &mut Vec<u8>, id: u16, axis: &AxisModel, selection: u16) -> Result<(), CalError> {
    let empty = MeshModel {
        vertices: Vec::new(),
        triangles: Vec::new(),
        neighbours: Vec::new(),
        hull: Vec::new(),
        merged_duplicates: 0,
        dropped_flat: Vec::new(),
        moved_flat: Vec::new(),
    };
    let mesh = axis.mesh.as_ref().unwrap_or(&empty);
    // Stored gradients: the hull vertices numbered first, in hull order (their gradients are
    // then found by vertex index as well as by hull index; the core checks it).
    let renumbered;
    let mesh = if axis.outside_policy == OutsidePolicy::StoredGradients {
        renumbered = hull_vertices_first(mesh).map_err(CalError::Encode)?;
        &renumbered
    } else {
        mesh
    };
    let count = |what: &'static str, n: usize| {
        u32::try_from(n).map_err(|_| CalError::Encode(EncodeProblem::TooLarge { what, count: n }))
    };
    let (terms, vertices, triangles, hull, region) = (
        count("poly terms", axis.poly.len())?,
        count("vertices", mesh.vertices.len())?,
        count("triangles", mesh.triangles.len())?,
        count("hull edges", mesh.hull.len())?,
        count("region vertices", axis.region.len())?,
    );
    if mesh.neighbours.len() != mesh.triangles.len() {
        return Err(CalError::Encode(EncodeProblem::NeighbourMismatch));
    }
    let gradients = if axis.outside_policy == OutsidePolicy::StoredGradients {
        hull_gradients(mesh).map_err(CalError::Encode)?
    } else {
        Vec::new()
    };
    let section_len = axis_section_len(terms, vertices, triangles, hull, region, gradients.len() as u32)
        .and_then(|n| u32::try_from(n).ok())
        .ok_or(CalError::Encode(EncodeProblem::TooLarge {
            what: "axis section",
            count: mesh.vertices.len(),
        }))?;
    let kind =
        if axis.poly.is_empty() { 0 } else { KIND_POLY } | if axis.mesh.is_some() { KIND_MESH } else { 0 };

    let base = out.len();
    out.resize(base + AXIS_HEADER_LEN, 0);
    let h = &mut out[base..];
    put_u32(h, AXIS_SECTION_LEN.start, section_len);
    put_u16(h, AXIS_ID.start, id);
    put_u16(h, AXIS_MODEL_KIND.start, kind);
    let f = &axis.features;
    put_f32(h, AXIS_WINDOW_S.start, f.window_s);
    put_u32(h, AXIS_BLOCK_COUNT.start, f.block_count);
    put_u32(h, AXIS_MIN_BLOCKS.start, f.min_blocks);
    put_f32(h, AXIS_MAX_GAP_S.start, f.max_gap_s);
    let nz = &axis.normalisation;
    put_f32(h, AXIS_TEMP_OFFSET_C.start, nz.temp_offset_c);
    put_f32(h, AXIS_TEMP_SCALE_PER_C.start, nz.temp_scale_per_c);
    put_f32(h, AXIS_RATE_OFFSET_C_PER_MIN.start, nz.rate_offset_c_per_min);
    put_f32(h, AXIS_RATE_SCALE_PER_C_PER_MIN.start, nz.rate_scale_per_c_per_min);
    put_u32(h, AXIS_OUTSIDE_POLICY.start, axis.outside_policy.code());
    put_u32(h, AXIS_POLY_TERM_COUNT.start, terms);
    put_u32(h, AXIS_VERTEX_COUNT.start, vertices);
    put_u32(h, AXIS_TRIANGLE_COUNT.start, triangles);
    put_u32(h, AXIS_HULL_EDGE_COUNT.start, hull);
    let p = &axis.provenance;
    put_u32(h, AXIS_FIT_POINT_COUNT.start, p.fit_point_count);
    put_f32(h, AXIS_RESIDUAL_RMS_DPH.start, p.residual_rms_dph);
    put_f32(h, AXIS_RESIDUAL_MAX_ABS_DPH.start, p.residual_max_abs_dph);
    put_f32(h, AXIS_TEMP_MIN_C.start, p.temp_min_c);
    put_f32(h, AXIS_TEMP_MAX_C.start, p.temp_max_c);
    put_f32(h, AXIS_RATE_MIN_C_PER_MIN.start, p.rate_min_c_per_min);
    put_f32(h, AXIS_RATE_MAX_C_PER_MIN.start, p.rate_max_c_per_min);
    put_u32(h, AXIS_REGION_VERTEX_COUNT.start, region);
    // Codes are 0 and 1 (PolyOutside::code); the field is a u16.
    put_u16(h, AXIS_POLY_OUTSIDE.start, axis.poly_outside.code() as u16);
    put_u16(h, AXIS_SELECTION.start, selection);

    for t in &axis.poly {
        out.extend_from_slice(&[t.temp_power, t.rate_power, 0, 0]);
        out.extend_from_slice(&t.coefficient_dph.to_le_bytes());
    }
    for v in &mesh.vertices {
        for x in [v.x, v.y, v.value_dph] {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    for (t, (tri, nb)) in mesh.triangles.iter().zip(&mesh.neighbours).enumerate() {
        let tf = triangle_transform(mesh, *tri)
            .ok_or(CalError::Encode(EncodeProblem::BadTriangle { triangle: t }))?;
        for x in tf.origin {
            out.extend_from_slice(&x.to_le_bytes());
        }
        for x in tf.bary.iter().chain(&tf.plane) {
            out.extend_from_slice(&(*x as f32).to_le_bytes());
        }
        for i in nb.iter().chain(tri) {
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    for (t, e) in &mesh.hull {
        out.extend_from_slice(&t.to_le_bytes());
        out.extend_from_slice(&e.to_le_bytes());
    }
    for v in axis.region.iter().chain(&gradients) {
        out.extend_from_slice(&v[0].to_le_bytes());
        out.extend_from_slice(&v[1].to_le_bytes());
    }
    debug_assert_eq!(out.len() - base, section_len as usize);
    Ok(())
}

/// The calibrated region of normalised points: their convex hull, counter-clockwise,
/// without collinear vertices (Andrew's monotone chain, exact in f64 for f32 inputs),
/// starting from the lowest-leftmost point. A hull of more than [`MAX_REGION_VERTICES`]
/// vertices is reduced to a convex polygon that still holds every point
/// ([`enclosing_reduction`]). Empty for fewer than 3 non-collinear points (no region: the
/// polynomial is extrapolated).
pub fn calibrated_region(points: &[(f32, f32)]) -> Vec<[f32; 2]> {
    let mut p: Vec<(f32, f32)> =
        points.iter().copied().filter(|(x, y)| x.is_finite() && y.is_finite()).collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    p.dedup();
    if p.len() < 3 {
        return Vec::new();
    }
    let mut hull: Vec<(f32, f32)> = Vec::with_capacity(2 * p.len());
    for pass in [p.clone(), p.iter().rev().copied().collect::<Vec<_>>()] {
        let start = hull.len();
        for q in pass {
            while hull.len() >= start + 2 && turn(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    if hull.len() < 3 {
        return Vec::new();
    }
    if hull.len() > MAX_REGION_VERTICES as usize {
        let max = MAX_REGION_VERTICES as usize;
        // The enclosing polygon when it passes every check; else the shrinking reduction,
        // which always gives a valid region, so a fit never fails because of its region.
        return enclosing_reduction(&hull, max).unwrap_or_else(|| shrinking_reduction(hull, max));
    }
    hull.into_iter().map(|(x, y)| [x, y]).collect()
}

/// A convex polygon (counter-clockwise, more than `max_vertices` vertices) reduced to at most
/// `max_vertices` that still encloses it: repeatedly the edge whose removal adds the least
/// area is replaced by the meeting point of its two neighbouring edges, extended (the greedy
/// enclosing k-gon), in f64. The polygon only grows, by slivers along the boundary, so a
/// trajectory that runs along the boundary (a temperature cycle's loop in (T, dT/dt)) stays
/// inside it. The result is then offset outward by [`REGION_OUTWARD_OFFSET`] (so rounding to
/// f32 cannot cut the old boundary off), rounded, and cleared of vertices where rounding
/// left it turning right. `None` when the result fails a check ([`is_enclosing_region`]).
///
/// Before (until 2026-11-28) the vertex of least triangle area was dropped instead
/// ([`shrinking_reduction`], now the fallback), so the region only shrank: chords cut inside
/// the hull, and on a temperature-cycling calibration most samples of a run fitted on were
/// flagged `OUTSIDE_HULL` (98.5 % on a 1 kHz log of 2 C/min cycles; review18 F6). A first
/// version moved each meeting point outward inside the loop; on dense, smooth hulls that bent
/// the neighbouring turns backward and the fit failed (review19 F1).
fn enclosing_reduction(hull: &[(f32, f32)], max_vertices: usize) -> Option<Vec<[f32; 2]>> {
    let mut polygon: Vec<[f64; 2]> = hull.iter().map(|&p| widen(p)).collect();
    // Per edge i (vertex i to i + 1): the area its removal adds and the meeting point.
    let mut costs: Vec<Option<(f64, [f64; 2])>> =
        (0..polygon.len()).map(|i| edge_removal(&polygon, i)).collect();
    while polygon.len() > max_vertices.max(4) {
        let (edge, meeting) = costs
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.map(|(area, meeting)| (i, area, meeting)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _, meeting)| (i, meeting))?;
        let next = (edge + 1) % polygon.len();
        polygon[edge] = meeting;
        polygon.remove(next);
        costs.remove(next);
        // The removals of the edges within two of the new vertex change.
        let n = polygon.len();
        let at = if next == 0 { edge - 1 } else { edge };
        for offset in [n - 2, n - 1, 0, 1] {
            let i = (at + offset) % n;
            costs[i] = edge_removal(&polygon, i);
        }
    }
    let offset = offset_outward(&polygon, REGION_OUTWARD_OFFSET)?;
    let region = without_reflex_vertices(offset.iter().map(|&[x, y]| [x as f32, y as f32]).collect());
    is_enclosing_region(&region, hull, max_vertices).then_some(region)
}

/// How far (normalised units) the reduced region is offset outward before rounding to f32:
/// 16 f32 ulps at 1, more than rounding moves a vertex.
const REGION_OUTWARD_OFFSET: f64 = 2e-6;

/// The largest area of an enclosing region against its hull's that is taken: slivers along
/// a boundary add a few per cent; more means a meeting point flung far out.
const MAX_REGION_AREA_RATIO: f64 = 1.1;

/// A convex counter-clockwise polygon with every edge moved `distance` outward (parallel):
/// vertex i where the moved edges before and after it meet. `None` when two edges are
/// parallel or meet backward (no convex polygon).
fn offset_outward(polygon: &[[f64; 2]], distance: f64) -> Option<Vec<[f64; 2]>> {
    let n = polygon.len();
    let moved_edge = |i: usize| {
        let (a, d) = (polygon[i], sub(polygon[(i + 1) % n], polygon[i]));
        let length = d[0].hypot(d[1]);
        let outward = [d[1] / length * distance, -d[0] / length * distance];
        ([a[0] + outward[0], a[1] + outward[1]], d)
    };
    (0..n)
        .map(|i| {
            let ((p, d1), (q, d2)) = (moved_edge((i + n - 1) % n), moved_edge(i));
            let turn = cross(d1, d2);
            // p + t d1 on the line q + u d2.
            let t = cross(sub(q, p), d2) / turn;
            let vertex = [p[0] + t * d1[0], p[1] + t * d1[1]];
            (turn > 0.0 && vertex.iter().all(|c| c.is_finite())).then_some(vertex)
        })
        .collect()
}

/// Whether `region` is a valid calibrated region that encloses `hull`: 3 to `max_vertices`
/// distinct vertices, turning left or straight at each (in f64 of the f32 values: stricter
/// than the core's check), round once; every hull point inside by the core's test; an area
/// at most [`MAX_REGION_AREA_RATIO`] times the hull's.
fn is_enclosing_region(region: &[[f32; 2]], hull: &[(f32, f32)], max_vertices: usize) -> bool {
    let n = region.len();
    if !(3..=max_vertices).contains(&n) || region.iter().flatten().any(|c| !c.is_finite()) {
        return false;
    }
    if (0..n).any(|i| is_reflex_or_repeated(region, i)) {
        return false;
    }
    let upper = |e: [f64; 2]| e[1] > 0.0 || (e[1] == 0.0 && e[0] > 0.0);
    let windings = (0..n).filter(|&i| !upper(edge_f64(region, i)) && upper(edge_f64(region, i + 1))).count();
    let contains = |x: f32, y: f32| {
        (0..n).all(|i| {
            let ([ax, ay], [bx, by]) = (region[i], region[(i + 1) % n]);
            (bx - ax) * (y - ay) - (by - ay) * (x - ax) >= 0.0
        })
    };
    let region_area = polygon_area(&region.iter().map(|&[x, y]| widen((x, y))).collect::<Vec<_>>());
    let hull_area = polygon_area(&hull.iter().map(|&p| widen(p)).collect::<Vec<_>>());
    windings == 1
        && hull.iter().all(|&(x, y)| contains(x, y))
        && region_area <= MAX_REGION_AREA_RATIO * hull_area
}

/// Edge `i` of an f32 polygon (from vertex i to the next, indices taken round), in f64.
fn edge_f64(polygon: &[[f32; 2]], i: usize) -> [f64; 2] {
    let n = polygon.len();
    let (a, b) = (polygon[i % n], polygon[(i + 1) % n]);
    [f64::from(b[0]) - f64::from(a[0]), f64::from(b[1]) - f64::from(a[1])]
}

/// Whether an f32 polygon turns right at vertex `i`, or repeats the vertex before it
/// (exactly, in f64 of the f32 values).
fn is_reflex_or_repeated(polygon: &[[f32; 2]], i: usize) -> bool {
    let n = polygon.len();
    let (e1, e2) = (edge_f64(polygon, i + n - 1), edge_f64(polygon, i));
    e1 == [0.0, 0.0] || cross(e1, e2) < 0.0
}

/// The z component of the cross product of two plane vectors.
fn cross(u: [f64; 2], v: [f64; 2]) -> f64 {
    u[0] * v[1] - u[1] * v[0]
}

/// An f32 point in f64 (exact).
fn widen((x, y): (f32, f32)) -> [f64; 2] {
    [f64::from(x), f64::from(y)]
}

/// Twice the signed area of the triangle (o, a, b), exact in f64 for f32 points: positive
/// when it turns left at a.
fn turn(o: (f32, f32), a: (f32, f32), b: (f32, f32)) -> f64 {
    cross(sub(widen(a), widen(o)), sub(widen(b), widen(o)))
}

/// `p - q`.
fn sub(p: [f64; 2], q: [f64; 2]) -> [f64; 2] {
    [p[0] - q[0], p[1] - q[1]]
}

/// The signed (shoelace) area of a polygon: positive counter-clockwise.
fn polygon_area(polygon: &[[f64; 2]]) -> f64 {
    let n = polygon.len();
    0.5 * (0..n).map(|i| cross(polygon[i], polygon[(i + 1) % n])).sum::<f64>()
}

/// The reduction used until 2026-11-28, kept as the fallback: repeatedly the vertex whose
/// triangle with its neighbours has the smallest area is dropped, so the polygon stays convex
/// and only shrinks (its vertices are calibration points: always a valid region).
fn shrinking_reduction(mut hull: Vec<(f32, f32)>, max_vertices: usize) -> Vec<[f32; 2]> {
    while hull.len() > max_vertices {
        let n = hull.len();
        let area = |i: usize| turn(hull[(i + n - 1) % n], hull[i], hull[(i + 1) % n]).abs();
        let smallest = (0..n).min_by(|&a, &b| area(a).total_cmp(&area(b))).unwrap_or(0);
        hull.remove(smallest);
    }
    hull.into_iter().map(|(x, y)| [x, y]).collect()
}

/// `polygon` without the vertices where it turns right (or repeats), as rounding to f32 can
/// leave where it was nearly straight: dropping such a vertex only grows the polygon (its
/// neighbours' chord passes outside it), so it stays enclosing.
fn without_reflex_vertices(mut polygon: Vec<[f32; 2]>) -> Vec<[f32; 2]> {
    while polygon.len() > 3 {
        let Some(reflex) = (0..polygon.len()).find(|&i| is_reflex_or_repeated(&polygon, i)) else {
            break;
        };
        polygon.remove(reflex);
    }
    polygon
}

/// Removing edge `i` of a counter-clockwise convex polygon: the area added and the point
/// where the edges before and after it meet when extended; `None` when they do not meet
/// beyond it (their turns add up to half a turn or more, or to nothing).
fn edge_removal(polygon: &[[f64; 2]], i: usize) -> Option<(f64, [f64; 2])> {
    let n = polygon.len();
    let vertex = |k: usize| polygon[k % n];
    let (before, a, b, after) = (vertex(i + n - 1), vertex(i), vertex(i + 1), vertex(i + 2));
    let (d1, edge, d2) = (sub(a, before), sub(b, a), sub(after, b));
    let turn = cross(d1, d2);
    if turn <= 0.0 {
        return None;
    }
    // a + t d1 on the line of (b, after): t = cross(b - a, d2) / cross(d1, d2).
    let t = cross(edge, d2) / turn;
    if !t.is_finite() || t < 0.0 {
        return None;
    }
    let meeting = [a[0] + t * d1[0], a[1] + t * d1[1]];
    let area = 0.5 * cross(edge, sub(meeting, a)).abs();
    area.is_finite().then_some((area, meeting))
}

/// `mesh` with its vertices renumbered so that hull vertex h (the start of hull edge h) is
/// vertex h, the others after them in their order; triangles, neighbours and hull entries
/// unchanged but for the vertex indices, so every position, value and transform is the same.
///
/// # Errors
/// [`EncodeProblem::BadTriangle`] for a hull entry or vertex index out of range, or a hull
/// that visits a vertex twice.
pub fn hull_vertices_first(mesh: &MeshModel) -> Result<MeshModel, EncodeProblem> {
    const UNSET: u32 = u32::MAX;
    let n = mesh.vertices.len();
    let mut new_index = vec![UNSET; n];
    let mut order = Vec::with_capacity(n);
    for &(t, e) in &mesh.hull {
        let bad = EncodeProblem::BadTriangle { triangle: t as usize };
        let start = *mesh
            .triangles
            .get(t as usize)
            .and_then(|tri| tri.get((e as usize + 1) % 3))
            .ok_or(bad.clone())?;
        let slot = new_index.get_mut(start as usize).filter(|i| **i == UNSET).ok_or(bad)?;
        *slot = order.len() as u32;
        order.push(start);
    }
    for (v, index) in new_index.iter_mut().enumerate() {
        if *index == UNSET {
            *index = order.len() as u32;
            order.push(v as u32);
        }
    }
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let renumber =
            |v: u32| new_index.get(v as usize).copied().ok_or(EncodeProblem::BadTriangle { triangle: t });
        triangles.push([renumber(tri[0])?, renumber(tri[1])?, renumber(tri[2])?]);
    }
    Ok(MeshModel {
        vertices: order.iter().map(|&v| mesh.vertices[v as usize]).collect(),
        triangles,
        ..mesh.clone()
    })
}

/// The continuation gradients of `OutsidePolicy::StoredGradients`, one per hull edge, at its
/// start vertex `q` (deg/h per normalised unit): the gradient of the weighted least-squares
/// plane of the mesh nodes with biweight weights `(1 - r^2 / R^2)^2` within
/// `R = fogtemp_core::GRADIENT_RADIUS` of `q`, or of every node with equal weights where
/// those do not span a plane (`1 - rho^2 < 1e-2` of their weighted positions), the rule of the
/// query-time policy (`fogtemp-core`'s `src/beyond.rs`), here in f64 from the f32 nodes the
/// blob stores. Where not even every node spans a plane (a thin mesh: one warm-up run), zero:
/// the value is held there, as the query-time policy holds it when it finds no gradient.
/// Empty for a mesh without hull edges.
///
/// # Errors
/// [`EncodeProblem::NoHullGradient`] for a hull entry out of range.
pub fn hull_gradients(mesh: &MeshModel) -> Result<Vec<[f32; 2]>, EncodeProblem> {
    let nodes: Vec<[f64; 3]> =
        mesh.vertices.iter().map(|v| [f64::from(v.x), f64::from(v.y), f64::from(v.value_dph)]).collect();
    let radius2 = f64::from(fogtemp_core::GRADIENT_RADIUS).powi(2);
    let mut out = Vec::with_capacity(mesh.hull.len());
    for (h, &(t, e)) in mesh.hull.iter().enumerate() {
        let missing = EncodeProblem::NoHullGradient { hull_edge: h };
        // Edge e runs from vertex e + 1 to e + 2 of its triangle: its start vertex.
        let start = mesh.triangles.get(t as usize).and_then(|tri| tri.get((e as usize + 1) % 3));
        let q = start.and_then(|&i| nodes.get(i as usize)).ok_or(missing)?;
        let biweight = |p: &[f64; 3]| {
            let r2 = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)) / radius2;
            if r2 < 1.0 {
                (1.0 - r2).powi(2)
            } else {
                0.0
            }
        };
        let g =
            plane_gradient(&nodes, biweight).or_else(|| plane_gradient(&nodes, |_| 1.0)).unwrap_or([0.0; 2]);
        out.push([g[0] as f32, g[1] as f32]);
    }
    Ok(out)
}

/// Gradient of the plane `v = a x + b y + c` fitted to `nodes` (x, y, value) by least squares
/// with weights `weight(node)`, the moments centred on the weighted mean; `None` when the
/// weighted positions do not span a plane (`1 - rho^2 < 1e-2`, the core's test) or the
/// result is not finite in f32.
fn plane_gradient(nodes: &[[f64; 3]], weight: impl Fn(&[f64; 3]) -> f64) -> Option<[f64; 2]> {
    let weighted: Vec<(f64, &[f64; 3])> =
        nodes.iter().map(|p| (weight(p), p)).filter(|(w, _)| *w > 0.0).collect();
    let sw: f64 = weighted.iter().map(|(w, _)| w).sum();
    if sw.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let mean = |k: usize| weighted.iter().map(|(w, p)| w * p[k]).sum::<f64>() / sw;
    let m = [mean(0), mean(1), mean(2)];
    let (mut sxx, mut sxy, mut syy, mut sxv, mut syv) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (w, p) in &weighted {
        let (dx, dy, dv) = (p[0] - m[0], p[1] - m[1], p[2] - m[2]);
        sxx += w * dx * dx;
        sxy += w * dx * dy;
        syy += w * dy * dy;
        sxv += w * dx * dv;
        syv += w * dy * dv;
    }
    let det = sxx * syy - sxy * sxy;
    if !(det > 1e-2 * sxx * syy && det.is_finite()) {
        return None;
    }
    let g = [(syy * sxv - sxy * syv) / det, (sxx * syv - sxy * sxv) / det];
    g.iter().all(|v| (*v as f32).is_finite()).then_some(g)
}

/// A triangle's stored transforms, relative to `origin` (vertex 2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleTransform {
    /// Vertex 2's position.
    pub origin: [f32; 2],
    /// `l0 = b0 dx + b1 dy`, `l1 = b2 dx + b3 dy`.
    pub bary: [f64; 4],
    /// `value = p0 dx + p1 dy + p2`.
    pub plane: [f64; 3],
}

impl TriangleTransform {
    /// Barycentric coordinates `[l0, l1, 1 - l0 - l1]` of `(x, y)` (all in `[0, 1]` inside).
    pub fn barycentric(&self, x: f64, y: f64) -> [f64; 3] {
        let (dx, dy) = (x - f64::from(self.origin[0]), y - f64::from(self.origin[1]));
        let l0 = self.bary[0] * dx + self.bary[1] * dy;
        let l1 = self.bary[2] * dx + self.bary[3] * dy;
        [l0, l1, 1.0 - l0 - l1]
    }
}

/// Barycentric transform and value plane of triangle `tri`, in f64 from the f32 vertex
/// positions the blob stores, relative to vertex 2 (so small triangles far from the
/// origin keep their precision in f32). `None` for a bad index or a zero-area triangle.
pub fn triangle_transform(mesh: &MeshModel, tri: [u32; 3]) -> Option<TriangleTransform> {
    let vertex = |i: u32| mesh.vertices.get(i as usize);
    let (a, b, c) = (vertex(tri[0])?, vertex(tri[1])?, vertex(tri[2])?);
    let rel = |v: &fogtemp_core::Vertex| (f64::from(v.x) - f64::from(c.x), f64::from(v.y) - f64::from(c.y));
    let ((ax, ay), (bx, by)) = (rel(a), rel(b));
    // Solve [ax bx; ay by] [l0; l1] = [dx; dy].
    let det = ax * by - bx * ay;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let bary = [by / det, -bx / det, -ay / det, ax / det];
    let vc = f64::from(c.value_dph);
    let (da, db) = (f64::from(a.value_dph) - vc, f64::from(b.value_dph) - vc);
    let plane = [da * bary[0] + db * bary[2], da * bary[1] + db * bary[3], vc];
    Some(TriangleTransform { origin: [c.x, c.y], bary, plane })
}

fn put_u16(buf: &mut [u8], at: usize, v: u16) {
    buf[at..at + 2].copy_from_slice(&v.to_le_bytes());
}

fn put_u32(buf: &mut [u8], at: usize, v: u32) {
    buf[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_f32(buf: &mut [u8], at: usize, v: f32) {
    buf[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// The blob of a model of one axis, `axis`, with nothing else recorded.
#[cfg(test)]
pub(crate) fn test_blob(axis: AxisModel) -> Vec<u8> {
    encode(&ModelFile {
        tool_version: String::new(),
        input_digest: [0; 32],
        axes: vec![axis],
        columns: Vec::new(),
        log_time: Default::default(),
        log_reading: Default::default(),
        input_rates: None,
    })
    .expect("encodes")
}

/// A polynomial axis over the identity normalisation (T in C, dT/dt in C/min), with the
/// default feature settings and no region: the unit tests' small models.
#[cfg(test)]
pub(crate) fn test_poly_axis(poly: Vec<PolyTerm>) -> AxisModel {
    AxisModel {
        features: crate::calibrate::default_features(),
        normalisation: Normalisation {
            temp_offset_c: 0.0,
            temp_scale_per_c: 1.0,
            rate_offset_c_per_min: 0.0,
            rate_scale_per_c_per_min: 1.0,
        },
        outside_policy: OutsidePolicy::NearestHull,
        poly,
        mesh: None,
        provenance: AxisProvenance {
            fit_point_count: 2,
            residual_rms_dph: 0.0,
            residual_max_abs_dph: 0.0,
            temp_min_c: -50.0,
            temp_max_c: 50.0,
            rate_min_c_per_min: -1.0,
            rate_max_c_per_min: 1.0,
        },
        region: Vec::new(),
        poly_outside: PolyOutside::Extrapolate,
    }
}

#[cfg(test)]
mod region_tests {
    use super::{calibrated_region, test_blob, test_poly_axis, MAX_REGION_VERTICES};
    use fogtemp_core::{PolyOutside, PolyTerm};

    /// The region as the core reads it from a blob (which also checks it is convex and
    /// goes round once).
    fn core_contains(region: &[[f32; 2]], points: &[(f32, f32)]) -> Vec<bool> {
        let mut axis = test_poly_axis(vec![PolyTerm { temp_power: 0, rate_power: 0, coefficient_dph: 1.0 }]);
        axis.region = region.to_vec();
        axis.poly_outside = PolyOutside::HoldAtBoundary;
        let blob = test_blob(axis);
        let model = fogtemp_core::Model::from_bytes(&blob).expect("reads");
        let region = model.axis(0).expect("axis").region.expect("a region");
        points.iter().map(|&(x, y)| region.contains(x, y)).collect()
    }

    /// The shoelace area of a polygon.
    fn area(polygon: &[[f64; 2]]) -> f64 {
        let n = polygon.len();
        0.5 * (0..n)
            .map(|i| {
                let (a, b) = (polygon[i], polygon[(i + 1) % n]);
                a[0] * b[1] - a[1] * b[0]
            })
            .sum::<f64>()
    }

    /// The convex hull of points, counter-clockwise (monotone chain, f64).
    fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
        let mut sorted = points.to_vec();
        sorted.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        sorted.dedup();
        let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
            (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
        };
        let mut hull: Vec<[f64; 2]> = Vec::new();
        for pass in [sorted.clone(), sorted.iter().rev().copied().collect()] {
            let start = hull.len();
            for q in pass {
                while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
                    hull.pop();
                }
                hull.push(q);
            }
            hull.pop();
        }
        hull
    }

    /// A fixed-seed jitter in [-amplitude, amplitude].
    fn jitter(seed: &mut u64, amplitude: f64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        ((*seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * amplitude
    }

    /// A temperature cycle's loop in (T, dT/dt) (an ellipse, 3000 features on it), a
    /// stadium (ramps at constant rates joined by turns, jittered) and a quantised loop: the
    /// region has at most 64 vertices, holds every point by the core's own test, and is at
    /// most 2 % larger than the points' convex hull, and not smaller (the shrinking fallback
    /// would be).
    #[test]
    fn a_region_reduced_to_64_vertices_holds_every_point() {
        let mut seed = 0x5eed_u64;
        let ellipse: Vec<[f64; 2]> = (0..3000)
            .map(|k| {
                let phase = k as f64 / 3000.0 * std::f64::consts::TAU;
                [0.95 * phase.cos(), 0.9 * phase.sin()]
            })
            .collect();
        let mut stadium = Vec::new();
        for k in 0..1000 {
            let x = -0.6 + 1.2 * k as f64 / 1000.0;
            stadium.push([x, -0.8 + jitter(&mut seed, 1e-4)]);
        }
        for k in 0..500 {
            let phase = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / 500.0;
            stadium.push([0.6 + 0.3 * phase.cos(), 0.8 * phase.sin()]);
        }
        for k in 0..1000 {
            let x = 0.6 - 1.2 * k as f64 / 1000.0;
            stadium.push([x, 0.8 + jitter(&mut seed, 1e-4)]);
        }
        for k in 0..500 {
            let phase = std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / 500.0;
            stadium.push([-0.6 + 0.3 * phase.cos(), 0.8 * phase.sin()]);
        }
        // A dense, smooth loop with a second harmonic, its temperature quantised to 1/3000
        // of its span (a thermometer's 0.01 C over a 60 C cycle: a turn of about 1e-9 at
        // each hull vertex), which made the first version of the reduction fail (review19).
        let quantised: Vec<[f64; 2]> = (0..20_000)
            .map(|k| {
                let phase = k as f64 / 20_000.0 * std::f64::consts::TAU;
                [(phase.cos() * 1500.0).round() / 1500.0, phase.sin() + 0.3 * (2.0 * phase).sin()]
            })
            .collect();
        for boundary in [ellipse, stadium, quantised] {
            let mut points: Vec<(f32, f32)> = boundary.iter().map(|p| (p[0] as f32, p[1] as f32)).collect();
            // Points inside too, which change nothing.
            points.extend((0..500).map(|_| (jitter(&mut seed, 0.5) as f32, jitter(&mut seed, 0.5) as f32)));
            let region = calibrated_region(&points);
            assert!((3..=MAX_REGION_VERTICES as usize).contains(&region.len()), "{} vertices", region.len());
            let inside = core_contains(&region, &points);
            let outside: Vec<_> = points.iter().zip(&inside).filter(|(_, &i)| !i).map(|(p, _)| p).collect();
            assert!(outside.is_empty(), "{} points outside, e.g. {:?}", outside.len(), outside.first());
            let region_area =
                area(&region.iter().map(|v| [f64::from(v[0]), f64::from(v[1])]).collect::<Vec<_>>());
            let hull_area = area(&convex_hull(&boundary));
            assert!(
                region_area >= hull_area && region_area <= 1.02 * hull_area,
                "{region_area} vs {hull_area}"
            );
        }
    }

    /// A hull of at most 64 vertices is the region as it is: its vertices are calibration
    /// points, counter-clockwise from the lowest-leftmost.
    #[test]
    fn a_small_hull_is_the_region_unchanged() {
        let points = [(0.0, 0.0), (1.0, 0.0), (0.5, 0.2), (1.0, 1.0), (0.0, 1.0), (0.5, 1.0)];
        assert_eq!(calibrated_region(&points), vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    }
}
