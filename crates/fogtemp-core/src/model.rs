//! `Model::from_bytes`: parse and fully validate a blob, then hand out per-axis views.

use crate::crc::crc32;
use crate::error::Error;
use crate::mesh::{
    barycentric, edge_vertices, plane_value, Mesh, MeshValue, OutsidePolicy, StartGrid, TriangleRecord,
    WalkHint,
};
use crate::names::{AxisColumns, InputRates, LogReading, LogShape, LogTime};
use crate::poly::{parse_term, Poly};
use crate::region::{PolyOutside, Region};
use crate::wire::*;

/// Largest magnitude accepted for a normalised vertex coordinate. Keeps every product
/// in the walk far from f32 overflow.
pub const MAX_NORMALISED_COORD: f32 = 1.0e6;

/// Feature-tracker settings stored per axis: how firmware computes T and dT/dt
/// exactly as calibration did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeatureSettings {
    /// Window length, seconds (the paper uses 100 s).
    pub window_s: f32,
    /// Sub-blocks per window; the rate is the least-squares slope over block means.
    pub block_count: u32,
    /// Blocks holding data needed before features are reported.
    pub min_blocks: u32,
    /// A silence of the temperature channel longer than this restarts the tracker, seconds.
    pub max_gap_s: f32,
}

impl FeatureSettings {
    /// Tracker capacity (blocks) these settings need: `block_count`. A
    /// [`crate::FeatureTracker<N>`], [`crate::Compensator<'_, N>`] or [`crate::AxisState`]
    /// built with less is refused with [`Error::CapacityTooSmall`] naming this number.
    #[inline]
    pub const fn blocks_needed(&self) -> usize {
        self.block_count as usize
    }
}

/// Affine map from physical inputs to the normalised plane the models live in:
/// `x = (temp_c - temp_offset_c) * temp_scale_per_c`,
/// `y = (rate_c_per_min - rate_offset_c_per_min) * rate_scale_per_c_per_min`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normalisation {
    /// Temperature subtracted before scaling, deg C.
    pub temp_offset_c: f32,
    /// Temperature scale, 1/deg C.
    pub temp_scale_per_c: f32,
    /// Rate subtracted before scaling, deg C/min.
    pub rate_offset_c_per_min: f32,
    /// Rate scale, 1/(deg C/min).
    pub rate_scale_per_c_per_min: f32,
}

impl Normalisation {
    /// Normalised `(x, y)`, each clamped to `±MAX_NORMALISED_COORD` (far outside any mesh)
    /// so that extreme inputs stay finite.
    #[inline]
    pub fn apply(&self, temp_c: f32, rate_c_per_min: f32) -> (f32, f32) {
        let x = (temp_c - self.temp_offset_c) * self.temp_scale_per_c;
        let y = (rate_c_per_min - self.rate_offset_c_per_min) * self.rate_scale_per_c_per_min;
        let c = MAX_NORMALISED_COORD;
        (x.clamp(-c, c), y.clamp(-c, c))
    }
}

/// Fit statistics and calibrated range stored with an axis (provenance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisProvenance {
    /// Calibration points used by the fit.
    pub fit_point_count: u32,
    /// RMS of the fit residuals, deg/h.
    pub residual_rms_dph: f32,
    /// Largest absolute fit residual, deg/h.
    pub residual_max_abs_dph: f32,
    /// Lowest calibrated temperature, deg C.
    pub temp_min_c: f32,
    /// Highest calibrated temperature, deg C.
    pub temp_max_c: f32,
    /// Lowest calibrated rate, deg C/min.
    pub rate_min_c_per_min: f32,
    /// Highest calibrated rate, deg C/min.
    pub rate_max_c_per_min: f32,
}

/// A model value at one query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evaluation {
    /// Modelled bias, deg/h (polynomial plus mesh, whichever the axis has).
    pub value_dph: f32,
    /// The query was outside the mesh hull (the outside policy produced the mesh part) or
    /// outside the calibrated region with the polynomial held at, or continued linearly
    /// from, its boundary (`PolyOutside::HoldAtBoundary`, `LinearFromBoundary`).
    pub outside_hull: bool,
}

/// One gyro axis of a model: feature settings, normalisation and the bias model.
#[derive(Clone, Copy, Debug)]
pub struct Axis<'a> {
    /// Axis number (its position in the blob).
    pub id: u16,
    /// How features are computed.
    pub features: FeatureSettings,
    /// Input normalisation.
    pub normalisation: Normalisation,
    /// Fit statistics.
    pub provenance: AxisProvenance,
    /// How the model kind was chosen: the `selection` field (`wire::AXIS_SELECTION`; 0 when
    /// the method was given).
    pub selection: u16,
    /// Polynomial part, if any.
    pub poly: Option<Poly<'a>>,
    /// Mesh part, if any.
    pub mesh: Option<Mesh<'a>>,
    /// The calibrated region (convex hull of the calibration points), if the blob has one
    /// (format version 2).
    pub region: Option<Region<'a>>,
    /// What the polynomial does outside `region`.
    pub poly_outside: PolyOutside,
}

impl<'a> Axis<'a> {
    /// Tracker capacity (blocks) this axis needs: its `block_count`
    /// ([`FeatureSettings::blocks_needed`]). `Compensator::<N>::new` and
    /// [`Axis::state`] refuse an `N` below it with [`Error::CapacityTooSmall`].
    #[inline]
    pub const fn blocks_needed(&self) -> usize {
        self.features.blocks_needed()
    }

    /// Modelled bias at `(temp_c, rate_c_per_min)`: the polynomial plus the mesh.
    ///
    /// # Errors
    /// [`Error::NonFiniteSample`] if either input is NaN or infinite; `hint` unchanged.
    /// [`Error::NonFiniteValue`] if the value is not finite (a blob whose finite floats are
    /// too large together).
    #[inline]
    pub fn evaluate(
        &self,
        temp_c: f32,
        rate_c_per_min: f32,
        hint: &mut WalkHint,
    ) -> Result<Evaluation, Error> {
        self.evaluate_by(temp_c, rate_c_per_min, |mesh, x, y| mesh.interpolate(x, y, hint))
    }

    /// [`Axis::evaluate`] with the mesh located from a start grid of this axis's mesh
    /// ([`Mesh::start_grid`]; for many points in random order): the same value and flag.
    ///
    /// # Errors
    /// As [`Axis::evaluate`].
    #[inline]
    pub fn evaluate_with_grid(
        &self,
        temp_c: f32,
        rate_c_per_min: f32,
        hint: &mut WalkHint,
        grid: &StartGrid<'_>,
    ) -> Result<Evaluation, Error> {
        self.evaluate_by(temp_c, rate_c_per_min, |mesh, x, y| mesh.interpolate_with_grid(x, y, hint, grid))
    }

    /// The first step of [`Axis::evaluate_with_grid`] alone, without a branch on its outcome:
    /// the evaluation as the mesh's triangle at the query's grid cell gives it, and whether that
    /// triangle holds the query. When it does (`true`), the evaluation is
    /// [`Axis::evaluate_with_grid`]'s, bit for bit (that function tests the same triangle first
    /// with the same arithmetic and stops there); when not, the caller evaluates the point with
    /// [`Axis::evaluate_with_grid`]. An axis without a mesh always gives `true` (the
    /// polynomial alone), a NaN or infinite input `false`.
    ///
    /// For batches in random order: a caller that first runs this over a block of points,
    /// noting the `false` ones without branching, then evaluates those, does not mispredict the
    /// outcome of the cell test at every point where the cell's triangle does not hold it
    /// (outside the hull, near a triangle edge), as a loop over `evaluate_with_grid` does.
    #[inline]
    pub fn evaluate_in_grid_cell(
        &self,
        temp_c: f32,
        rate_c_per_min: f32,
        grid: &StartGrid<'_>,
    ) -> (Evaluation, bool) {
        let mut held = self.mesh.is_none();
        let evaluation = self.evaluate_by(temp_c, rate_c_per_min, |mesh, x, y| {
            let (value, inside) = mesh.interpolate_in_grid_cell(x, y, grid);
            held = inside;
            Ok(value)
        });
        match evaluation {
            Ok(evaluation) => (evaluation, held),
            Err(_) => (Evaluation { value_dph: f32::NAN, outside_hull: false }, false),
        }
    }

    /// The evaluation with the mesh interpolated by `interpolate`.
    #[inline(always)]
    fn evaluate_by(
        &self,
        temp_c: f32,
        rate_c_per_min: f32,
        interpolate: impl FnOnce(&Mesh<'a>, f32, f32) -> Result<MeshValue, Error>,
    ) -> Result<Evaluation, Error> {
        if !(temp_c.is_finite() && rate_c_per_min.is_finite()) {
            return Err(Error::NonFiniteSample);
        }
        let (x, y) = self.normalisation.apply(temp_c, rate_c_per_min);
        let (poly, poly_held) = match self.poly {
            Some(p) => self.poly_value(p, x, y),
            None => (0.0, false),
        };
        let evaluation = match &self.mesh {
            Some(mesh) => {
                let m = interpolate(mesh, x, y).map_err(|e| e.at_axis(self.id))?;
                // Outside the calibrated region a mesh's value is flagged even where its hull
                // reaches (nodes from a tracker's partial window, whose rate is noisier).
                let outside_region = || self.region.is_some_and(|r| !r.contains(x, y));
                let outside_hull = m.outside_hull || poly_held || outside_region();
                Evaluation { value_dph: poly + m.value_dph, outside_hull }
            }
            None => Evaluation { value_dph: poly, outside_hull: poly_held },
        };
        if evaluation.value_dph.is_finite() {
            Ok(evaluation)
        } else {
            Err(Error::NonFiniteValue { axis: self.id })
        }
    }

    /// The polynomial at `(x, y)`; outside the calibrated region, per the policy, at (or
    /// continued linearly from) the region's nearest boundary point (then `true`).
    #[inline]
    fn poly_value(&self, poly: Poly<'_>, x: f32, y: f32) -> (f32, bool) {
        match (self.poly_outside, self.region) {
            (PolyOutside::Extrapolate, _) | (_, None) => (poly.evaluate(x, y), false),
            (_, Some(region)) if region.contains(x, y) => (poly.evaluate(x, y), false),
            (PolyOutside::HoldAtBoundary, Some(region)) => {
                let (bx, by) = region.nearest_boundary_point(x, y);
                (poly.evaluate(bx, by), true)
            }
            (PolyOutside::LinearFromBoundary, Some(region)) => {
                let (bx, by) = region.nearest_boundary_point(x, y);
                let (value, d_dx, d_dy) = poly.evaluate_with_gradient(bx, by);
                (value + d_dx * (x - bx) + d_dy * (y - by), true)
            }
        }
    }
}

/// A validated model blob, borrowed (typically from flash via `include_bytes!`).
#[derive(Clone, Copy, Debug)]
pub struct Model<'a> {
    bytes: &'a [u8],
    axis_count: u16,
    version: u16,
}

impl<'a> Model<'a> {
    /// Parses `bytes` and validates every length, count, index, float, the CRC-32 and
    /// the mesh adjacency before returning. Never panics, for any input.
    ///
    /// # Errors
    /// The first problem found, saying which field and where.
    pub fn from_bytes(bytes: &'a [u8]) -> Result<Self, Error> {
        let found = bytes.len();
        let header = array::<FILE_HEADER_LEN>(bytes, 0).ok_or(Error::Truncated {
            field: "file header",
            needed: FILE_HEADER_LEN + CRC_LEN,
            found,
        })?;
        if header.first_chunk::<4>() != Some(&MAGIC) {
            return Err(Error::BadMagic);
        }
        let version = u16_at(&header, FILE_VERSION.start).unwrap_or(0);
        if !(OLDEST_READABLE_VERSION..=FORMAT_VERSION).contains(&version) {
            return Err(Error::UnsupportedVersion { expected: FORMAT_VERSION, found: version });
        }
        let header_len = usize::from(u16_at(&header, FILE_HEADER_LEN_FIELD.start).unwrap_or(0));
        if header_len != FILE_HEADER_LEN {
            return Err(Error::LengthMismatch {
                field: "header_len",
                expected: FILE_HEADER_LEN,
                found: header_len,
            });
        }
        let total_len = u32_at(&header, FILE_TOTAL_LEN.start).unwrap_or(0) as usize;
        if total_len != found {
            return Err(if total_len > found {
                Error::Truncated { field: "total_len", needed: total_len, found }
            } else {
                Error::LengthMismatch { field: "total_len", expected: found, found: total_len }
            });
        }
        let body_len = found
            .checked_sub(CRC_LEN)
            .filter(|&n| n >= FILE_HEADER_LEN)
            .ok_or(Error::Truncated { field: "crc", needed: FILE_HEADER_LEN + CRC_LEN, found })?;
        let stored_crc = u32_at(bytes, body_len).unwrap_or(0);
        let body = bytes.get(..body_len).unwrap_or(&[]);
        let computed = crc32(body);
        if computed != stored_crc {
            return Err(Error::CrcMismatch { expected: computed, found: stored_crc });
        }
        let axis_count = u16_at(&header, FILE_AXIS_COUNT.start).unwrap_or(0);
        if axis_count == 0 || axis_count > MAX_AXES {
            return Err(Error::BadHeaderValue { field: "axis_count", found: u64::from(axis_count) });
        }
        let reserved = u16_at(&header, FILE_RESERVED.start).unwrap_or(0);
        if reserved != 0 {
            return Err(Error::BadHeaderValue { field: "reserved", found: u64::from(reserved) });
        }
        let model = Model { bytes: body, axis_count, version };
        let mut offset = FILE_HEADER_LEN;
        for id in 0..axis_count {
            let (axis, len) = parse_axis(body, offset, id, version)?;
            validate_axis(&axis)?;
            offset = offset.saturating_add(len);
        }
        if version >= FIRST_VERSION_WITH_COLUMN_NAMES {
            let records = crate::names::Records {
                time: version >= FIRST_VERSION_WITH_LOG_TIME,
                reading: version >= FIRST_VERSION_WITH_LOG_READING,
                shape: version >= FIRST_VERSION_WITH_LOG_SHAPE,
                run_metadata: version >= FIRST_VERSION_WITH_RUN_METADATA,
            };
            crate::names::validate(body, offset, axis_count, records)?;
        } else if offset != body_len {
            return Err(Error::LengthMismatch {
                field: "sum of section_len",
                expected: body_len - FILE_HEADER_LEN,
                found: offset.saturating_sub(FILE_HEADER_LEN),
            });
        }
        Ok(model)
    }

    /// Reads a model from a flash partition: the blob followed by erased flash. The blob's
    /// own `total_len` says where it ends; the bytes after it must all be `0xFF` (erased
    /// NOR flash) or all be `0x00` (none is fine too). Returns the model and the bytes it
    /// occupies (`total_len`), so a caller can place something after it.
    ///
    /// [`Model::from_bytes`] still requires the exact length.
    ///
    /// # Errors
    /// [`Error::TrailingBytes`] if the padding is neither all `0xFF` nor all `0x00`;
    /// otherwise what [`Model::from_bytes`] returns for the first `total_len` bytes
    /// (a `total_len` beyond the partition is [`Error::Truncated`]).
    pub fn from_flash(bytes: &'a [u8]) -> Result<(Self, usize), Error> {
        let found = bytes.len();
        let header = array::<FILE_HEADER_LEN>(bytes, 0).ok_or(Error::Truncated {
            field: "file header",
            needed: FILE_HEADER_LEN + CRC_LEN,
            found,
        })?;
        if header.first_chunk::<4>() != Some(&MAGIC) {
            return Err(Error::BadMagic);
        }
        let total_len = u32_at(&header, FILE_TOTAL_LEN.start).unwrap_or(0) as usize;
        let (Some(blob), Some(padding)) = (bytes.get(..total_len), bytes.get(total_len..)) else {
            return Err(Error::Truncated { field: "total_len", needed: total_len, found });
        };
        let model = Self::from_bytes(blob)?;
        if let Some(&fill) = padding.first() {
            if !(fill == 0xFF || fill == 0x00) {
                return Err(Error::TrailingBytes { offset: total_len, fill: 0xFF });
            }
            if let Some(at) = padding.iter().position(|&b| b != fill) {
                return Err(Error::TrailingBytes { offset: total_len.saturating_add(at), fill });
            }
        }
        Ok((model, total_len))
    }

    /// Number of gyro axes.
    pub fn axis_count(&self) -> usize {
        usize::from(self.axis_count)
    }

    /// The axis `index`.
    ///
    /// # Errors
    /// [`Error::NoSuchAxis`] if `index >= axis_count()`.
    pub fn axis(&self, index: usize) -> Result<Axis<'a>, Error> {
        if index >= self.axis_count() {
            return Err(Error::NoSuchAxis { requested: index, available: self.axis_count() });
        }
        let mut offset = FILE_HEADER_LEN;
        for id in 0..self.axis_count {
            let (axis, len) = parse_axis(self.bytes, offset, id, self.version)?;
            if usize::from(id) == index {
                return Ok(axis);
            }
            offset = offset.saturating_add(len);
        }
        Err(Error::NoSuchAxis { requested: index, available: self.axis_count() })
    }

    /// The writer's version string (ASCII, NUL padding removed).
    pub fn tool_version(&self) -> &'a [u8] {
        let field = self.bytes.get(FILE_TOOL_VERSION).unwrap_or(&[]);
        let end = field.iter().position(|&b| b == 0).unwrap_or(field.len());
        field.get(..end).unwrap_or(&[])
    }

    /// Digest of the calibration inputs (SHA-256, or zeros when unknown).
    pub fn input_digest(&self) -> [u8; 32] {
        array::<32>(self.bytes, FILE_INPUT_DIGEST.start).unwrap_or([0; 32])
    }

    /// The blob's format version ([`OLDEST_READABLE_VERSION`] to [`FORMAT_VERSION`]).
    pub fn format_version(&self) -> u16 {
        self.version
    }

    /// The log columns axis `index` was fitted on and how their numbers were read (format
    /// version 4; `None` for an older blob or an axis that does not exist; a name the writer
    /// did not record is `""`). Not used by evaluation: it lets a host match a log's columns
    /// to the axes by name and read them in the units of the fit.
    pub fn axis_columns(&self, index: usize) -> Option<AxisColumns<'a>> {
        if self.version < FIRST_VERSION_WITH_COLUMN_NAMES || index >= self.axis_count() {
            return None;
        }
        crate::names::axis_columns(self.bytes, self.names_offset()?, index)
    }

    /// How the fit read its logs' time: the time column (or the sample rate of a log without
    /// one), the date column and the unit (format version 5; `None` for an older blob or one
    /// that records none). Not used by evaluation: it lets a host read a log's time as the
    /// fit did.
    pub fn log_time(&self) -> Option<LogTime<'a>> {
        if self.version < FIRST_VERSION_WITH_LOG_TIME {
            return None;
        }
        crate::names::log_time(self.bytes, self.names_offset()?, self.axis_count)
    }

    /// How the fit read its logs' numbers (the decimal mark) and a digest of each calibration
    /// log (format version 6; `None` for an older blob). Not used by evaluation: it lets a host
    /// read a log as the fit did and tell a validation log that was among the fit's.
    pub fn log_reading(&self) -> Option<LogReading<'a>> {
        if self.version < FIRST_VERSION_WITH_LOG_READING {
            return None;
        }
        crate::names::log_reading(self.bytes, self.names_offset()?, self.axis_count)
    }

    /// The shape of the fit's logs: lines skipped before the header or data, the delimiter,
    /// the comment prefix and, for logs without a header row, their column names (format
    /// version 7, written when the shape was not the default; `None` otherwise; in version 8
    /// always present, the default shape included). Not used by
    /// evaluation: it lets a host read a log as the fit did.
    pub fn log_shape(&self) -> Option<LogShape<'a>> {
        if self.version < FIRST_VERSION_WITH_LOG_SHAPE {
            return None;
        }
        crate::names::log_shape(self.bytes, self.names_offset()?, self.axis_count)
    }

    /// What the fit did with its runs' true input rates (format version 8, written when the
    /// fit had run metadata: a runs file or a simulation's manifest; `None` otherwise, and for
    /// every blob written before version 8, whether or not its fit had rates). Not used by
    /// evaluation: it lets a host tell whether the model's output holds an input rate (the
    /// Earth rate a calibration position saw) besides the bias.
    pub fn input_rates(&self) -> Option<InputRates> {
        if self.version < FIRST_VERSION_WITH_RUN_METADATA {
            return None;
        }
        crate::names::input_rates(self.bytes, self.names_offset()?, self.axis_count)
    }

    /// Where the log-columns section starts: after the axis sections, whose lengths were
    /// validated.
    fn names_offset(&self) -> Option<usize> {
        let mut offset = FILE_HEADER_LEN;
        for _ in 0..self.axis_count {
            let len = u32_at(self.bytes, offset.saturating_add(AXIS_SECTION_LEN.start))? as usize;
            offset = offset.saturating_add(len);
        }
        Some(offset)
    }
}

/// A known `selection` code: no choice (0), or a chosen method with how it was chosen.
fn valid_selection(code: u16) -> bool {
    let [method, how] = code.to_le_bytes();
    match method {
        SELECTION_NONE => how == 0,
        SELECTION_CUBIC_T..=SELECTION_HYBRID => how <= SELECTION_FALLBACK,
        _ => false,
    }
}

/// Strictly positive (false for NaN).
fn positive(v: f32) -> bool {
    v > 0.0
}

fn truncated(field: &'static str, needed: usize, found: usize) -> Error {
    Error::Truncated { field, needed, found }
}

/// Parses the axis section at `offset` of a blob of format `version` (header checks and
/// slicing only); returns the axis and the section length.
fn parse_axis(body: &[u8], offset: usize, id: u16, version: u16) -> Result<(Axis<'_>, usize), Error> {
    let found = body.len();
    let header_end = offset.saturating_add(AXIS_HEADER_LEN);
    let h = body.get(offset..header_end).ok_or(truncated("axis header", header_end, found))?;
    let u32f = |r: core::ops::Range<usize>| u32_at(h, r.start).unwrap_or(0);
    let f32f = |r: core::ops::Range<usize>| f32_at(h, r.start).unwrap_or(f32::NAN);
    let bad = |field: &'static str| Error::BadValue { field, axis: id, index: 0 };

    if u16_at(h, AXIS_ID.start) != Some(id) {
        return Err(bad("axis_id"));
    }
    let kind = u16_at(h, AXIS_MODEL_KIND.start).unwrap_or(0);
    if kind == 0 || kind & !(KIND_POLY | KIND_MESH) != 0 {
        return Err(bad("model_kind"));
    }
    let region_count = u32f(AXIS_REGION_VERTEX_COUNT);
    let poly_outside_code = u32::from(u16_at(h, AXIS_POLY_OUTSIDE.start).unwrap_or(u16::MAX));
    let selection = u16_at(h, AXIS_SELECTION.start).unwrap_or(u16::MAX);
    if version < 2 && (region_count != 0 || poly_outside_code != 0 || selection != 0) {
        return Err(bad("reserved"));
    }
    if !valid_selection(selection) {
        return Err(bad("selection"));
    }
    let poly_outside = PolyOutside::from_code(poly_outside_code).ok_or(bad("poly_outside"))?;
    if region_count != 0 && !(3..=MAX_REGION_VERTICES).contains(&region_count) {
        return Err(bad("region_vertex_count"));
    }
    if poly_outside != PolyOutside::Extrapolate && region_count == 0 {
        return Err(bad("poly_outside"));
    }
    let (terms, vertices, triangles, hull) = (
        u32f(AXIS_POLY_TERM_COUNT),
        u32f(AXIS_VERTEX_COUNT),
        u32f(AXIS_TRIANGLE_COUNT),
        u32f(AXIS_HULL_EDGE_COUNT),
    );
    let has_poly = kind & KIND_POLY != 0;
    let has_mesh = kind & KIND_MESH != 0;
    if has_poly != (terms > 0) || terms > MAX_POLY_TERMS {
        return Err(bad("poly_term_count"));
    }
    if has_mesh {
        if !(3..=MAX_TRIANGLES).contains(&vertices) {
            return Err(bad("vertex_count"));
        }
        if !(1..=MAX_TRIANGLES).contains(&triangles) {
            return Err(bad("triangle_count"));
        }
        if !(3..=triangles.saturating_add(2)).contains(&hull) {
            return Err(bad("hull_edge_count"));
        }
    } else if vertices != 0 || triangles != 0 || hull != 0 {
        return Err(bad("vertex_count"));
    }
    // Hull gradients: one per hull edge with policy 3, which needs the version that has them
    // (a code unknown to this reader or to the blob's version is refused by name here).
    let policy = OutsidePolicy::from_code(u32f(AXIS_OUTSIDE_POLICY))
        .filter(|p| *p != OutsidePolicy::StoredGradients || version >= FIRST_VERSION_WITH_GRADIENTS)
        .ok_or(bad("outside_policy"))?;
    let gradients = if policy == OutsidePolicy::StoredGradients { hull } else { 0 };
    let section_len = u32f(AXIS_SECTION_LEN) as usize;
    let expected =
        axis_section_len(terms, vertices, triangles, hull, region_count, gradients).unwrap_or(usize::MAX);
    if section_len != expected {
        return Err(Error::SectionLength { axis: id, expected, found: section_len });
    }
    let end = offset.checked_add(section_len).ok_or(truncated("axis section", usize::MAX, found))?;
    let section = body.get(offset..end).ok_or(truncated("axis section", end, found))?;

    let features = FeatureSettings {
        window_s: f32f(AXIS_WINDOW_S),
        block_count: u32f(AXIS_BLOCK_COUNT),
        min_blocks: u32f(AXIS_MIN_BLOCKS),
        max_gap_s: f32f(AXIS_MAX_GAP_S),
    };
    let normalisation = Normalisation {
        temp_offset_c: f32f(AXIS_TEMP_OFFSET_C),
        temp_scale_per_c: f32f(AXIS_TEMP_SCALE_PER_C),
        rate_offset_c_per_min: f32f(AXIS_RATE_OFFSET_C_PER_MIN),
        rate_scale_per_c_per_min: f32f(AXIS_RATE_SCALE_PER_C_PER_MIN),
    };
    let provenance = AxisProvenance {
        fit_point_count: u32f(AXIS_FIT_POINT_COUNT),
        residual_rms_dph: f32f(AXIS_RESIDUAL_RMS_DPH),
        residual_max_abs_dph: f32f(AXIS_RESIDUAL_MAX_ABS_DPH),
        temp_min_c: f32f(AXIS_TEMP_MIN_C),
        temp_max_c: f32f(AXIS_TEMP_MAX_C),
        rate_min_c_per_min: f32f(AXIS_RATE_MIN_C_PER_MIN),
        rate_max_c_per_min: f32f(AXIS_RATE_MAX_C_PER_MIN),
    };

    // Payload slices, in order. Lengths were checked against section_len above.
    let mut cursor = AXIS_HEADER_LEN;
    let mut take = |n: usize| {
        let start = cursor;
        cursor = cursor.saturating_add(n);
        section.get(start..cursor).unwrap_or(&[])
    };
    let poly_bytes = take(terms as usize * POLY_TERM_LEN);
    let vertex_bytes = take(vertices as usize * VERTEX_LEN);
    let triangle_bytes = take(triangles as usize * TRIANGLE_LEN);
    let hull_bytes = take(hull as usize * HULL_EDGE_LEN);
    let region_bytes = take(region_count as usize * REGION_VERTEX_LEN);
    let gradient_bytes = take(gradients as usize * HULL_GRADIENT_LEN);
    let axis = Axis {
        id,
        features,
        normalisation,
        provenance,
        selection,
        poly: has_poly.then(|| Poly::new(poly_bytes)),
        mesh: has_mesh.then_some(Mesh {
            vertices: vertex_bytes,
            triangles: triangle_bytes,
            hull: hull_bytes,
            gradients: gradient_bytes,
            policy,
            axis: id,
        }),
        region: (region_count > 0).then(|| Region::new(region_bytes)),
        poly_outside,
    };
    Ok((axis, section_len))
}

/// Every value check of one axis: floats, ranges, indices, adjacency, hull, transforms.
fn validate_axis(axis: &Axis<'_>) -> Result<(), Error> {
    let id = axis.id;
    let bad = |field: &'static str, index: u32| Error::BadValue { field, axis: id, index };
    let finite = |field: &'static str, v: f32, index: u32| {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(Error::NonFinite { field, axis: id, index })
        }
    };

    let f = &axis.features;
    if !positive(finite("window_s", f.window_s, 0)?) || f.window_s > 1.0e6 {
        return Err(bad("window_s", 0));
    }
    if f.block_count < 2 || f.block_count > MAX_BLOCKS {
        return Err(bad("block_count", 0));
    }
    if f.min_blocks < 2 || f.min_blocks > f.block_count {
        return Err(bad("min_blocks", 0));
    }
    // A block shorter than a microsecond cannot be timed by the tracker: the window is too
    // short for its (valid) block count.
    if f.window_s / (f.block_count as f32) < 1.0e-6 {
        return Err(bad("window_s", 0));
    }
    if !positive(finite("max_gap_s", f.max_gap_s, 0)?) {
        return Err(bad("max_gap_s", 0));
    }
    // The tracker's own timing check: every accepted axis gets a tracker.
    crate::features::timing_us(f).map_err(|field| bad(field, 0))?;
    let n = &axis.normalisation;
    finite("temp_offset_c", n.temp_offset_c, 0)?;
    finite("rate_offset_c_per_min", n.rate_offset_c_per_min, 0)?;
    if !positive(finite("temp_scale_per_c", n.temp_scale_per_c, 0)?) {
        return Err(bad("temp_scale_per_c", 0));
    }
    if !positive(finite("rate_scale_per_c_per_min", n.rate_scale_per_c_per_min, 0)?) {
        return Err(bad("rate_scale_per_c_per_min", 0));
    }
    let p = &axis.provenance;
    for (field, v) in [
        ("residual_rms_dph", p.residual_rms_dph),
        ("residual_max_abs_dph", p.residual_max_abs_dph),
        ("temp_min_c", p.temp_min_c),
        ("temp_max_c", p.temp_max_c),
        ("rate_min_c_per_min", p.rate_min_c_per_min),
        ("rate_max_c_per_min", p.rate_max_c_per_min),
    ] {
        finite(field, v, 0)?;
    }
    if let Some(poly) = &axis.poly {
        validate_poly(poly, id)?;
    }
    if let Some(mesh) = &axis.mesh {
        validate_mesh(mesh, id)?;
    }
    if let Some(region) = &axis.region {
        validate_region(region, id)?;
    }
    Ok(())
}

/// Region vertices finite and in range; the polygon counter-clockwise, convex (collinear
/// vertices allowed, as f32 rounding may tilt them slightly), without repeated vertices, and
/// going round once.
fn validate_region(region: &Region<'_>, id: u16) -> Result<(), Error> {
    let n = region.vertex_count();
    let err = |check: &'static str, index: u32| Error::BadMesh { check, axis: id, index };
    for i in 0..n {
        let (x, y) = region.vertex(i).ok_or(err("region vertex", i))?;
        for (field, c) in [("region.x", x), ("region.y", y)] {
            if !c.is_finite() {
                return Err(Error::NonFinite { field, axis: id, index: i });
            }
            if c.abs() > MAX_NORMALISED_COORD {
                return Err(Error::BadValue { field, axis: id, index: i });
            }
        }
    }
    let upper = |dx: f32, dy: f32| dy > 0.0 || (dy == 0.0 && dx > 0.0);
    let mut windings = 0u32;
    for i in 0..n {
        let vertex = |k: u32| {
            let k = k.checked_rem(n).unwrap_or(0);
            region.vertex(k).ok_or(err("region vertex", k))
        };
        let (a, b, c) = (vertex(i)?, vertex(i + 1)?, vertex(i + 2)?);
        let (e1x, e1y, e2x, e2y) = (b.0 - a.0, b.1 - a.1, c.0 - b.0, c.1 - b.1);
        if e1x == 0.0 && e1y == 0.0 {
            return Err(err("region vertices distinct", i));
        }
        let turn = e1x * e2y - e1y * e2x;
        let scale = (e1x.abs() + e1y.abs()) * (e2x.abs() + e2y.abs());
        if turn < -1.0e-5 * scale {
            return Err(err("region convex", i));
        }
        if !upper(e1x, e1y) && upper(e2x, e2y) {
            windings += 1;
        }
    }
    if windings != 1 {
        return Err(err("region goes round once", 0));
    }
    Ok(())
}

fn validate_poly(poly: &Poly<'_>, id: u16) -> Result<(), Error> {
    for (i, chunk) in poly.raw_terms().enumerate() {
        let index = i as u32;
        let term = parse_term(chunk);
        if term.temp_power > MAX_POWER || term.rate_power > MAX_POWER || u16_at(chunk, 2) != Some(0) {
            return Err(Error::BadValue { field: "poly_terms", axis: id, index });
        }
        if !term.coefficient_dph.is_finite() {
            return Err(Error::NonFinite { field: "poly_terms.coefficient_dph", axis: id, index });
        }
    }
    Ok(())
}

fn validate_mesh(mesh: &Mesh<'_>, id: u16) -> Result<(), Error> {
    let vcount = mesh.vertex_count();
    let tcount = mesh.triangle_count();
    let mesh_err = |check: &'static str, index: u32| Error::BadMesh { check, axis: id, index };
    for i in 0..vcount {
        let v = mesh.vertex(i).ok_or(mesh_err("vertex", i))?;
        for (field, c) in [("vertices.x", v.x), ("vertices.y", v.y)] {
            if !c.is_finite() {
                return Err(Error::NonFinite { field, axis: id, index: i });
            }
            if c.abs() > MAX_NORMALISED_COORD {
                return Err(Error::BadValue { field, axis: id, index: i });
            }
        }
        if !v.value_dph.is_finite() {
            return Err(Error::NonFinite { field: "vertices.value_dph", axis: id, index: i });
        }
    }
    let mut hull_slots = 0u32;
    for t in 0..tcount {
        let rec = mesh.triangle(t).ok_or(mesh_err("triangle", t))?;
        validate_triangle_indices(&rec, t, vcount, tcount, id)?;
        hull_slots += rec.neighbours.iter().filter(|&&n| n == NO_NEIGHBOUR).count() as u32;
        validate_triangle_geometry(mesh, &rec, t, id)?;
        for (k, &n) in rec.neighbours.iter().enumerate() {
            if n != NO_NEIGHBOUR && !neighbour_points_back(mesh, &rec, t, k as u32, n) {
                return Err(mesh_err("neighbours symmetric", t));
            }
        }
    }
    if hull_slots != mesh.hull_edge_count() {
        return Err(Error::LengthMismatch {
            field: "hull_edge_count",
            expected: hull_slots as usize,
            found: mesh.hull_edge_count() as usize,
        });
    }
    validate_hull(mesh, id)?;
    validate_gradients(mesh, id)
}

/// With stored gradients, hull vertex h is vertex h (the start of hull edge h), and one finite
/// pair per hull edge (the count is implied by `hull_edge_count` and checked with
/// `section_len`).
fn validate_gradients(mesh: &Mesh<'_>, id: u16) -> Result<(), Error> {
    if mesh.policy != OutsidePolicy::StoredGradients {
        return Ok(());
    }
    for h in 0..mesh.hull_edge_count() {
        if mesh.hull_start_index(h) != Some(h) {
            return Err(Error::BadMesh { check: "hull vertices numbered first", axis: id, index: h });
        }
        let g = mesh.hull_gradient(h).ok_or(Error::BadMesh { check: "hull gradient", axis: id, index: h })?;
        if !g.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFinite { field: "hull_gradients", axis: id, index: h });
        }
    }
    Ok(())
}

fn validate_triangle_indices(
    rec: &TriangleRecord,
    t: u32,
    vcount: u32,
    tcount: u32,
    id: u16,
) -> Result<(), Error> {
    for (k, &v) in rec.vertices.iter().enumerate() {
        if v >= vcount {
            return Err(Error::IndexOutOfRange {
                field: "triangles.vertices",
                axis: id,
                index: t,
                value: v,
                limit: vcount,
            });
        }
        if rec.vertices.iter().skip(k + 1).any(|&w| w == v) {
            return Err(Error::BadMesh { check: "distinct vertices", axis: id, index: t });
        }
    }
    for &n in &rec.neighbours {
        if n != NO_NEIGHBOUR && (n >= tcount || n == t) {
            return Err(Error::IndexOutOfRange {
                field: "triangles.neighbours",
                axis: id,
                index: t,
                value: n,
                limit: tcount,
            });
        }
    }
    for (field, vals) in [
        ("triangles.origin", &rec.origin[..]),
        ("triangles.bary", &rec.bary[..]),
        ("triangles.plane", &rec.plane[..]),
    ] {
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite { field, axis: id, index: t });
        }
    }
    Ok(())
}

/// Counter-clockwise, and the stored transform and plane reproduce the vertices.
fn validate_triangle_geometry(mesh: &Mesh<'_>, rec: &TriangleRecord, t: u32, id: u16) -> Result<(), Error> {
    let mesh_err = |check: &'static str| Error::BadMesh { check, axis: id, index: t };
    let [a, b, c] = rec.vertices.map(|v| mesh.vertex(v));
    let (Some(a), Some(b), Some(c)) = (a, b, c) else { return Err(mesh_err("vertex")) };
    let area2 = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if !positive(area2) {
        return Err(mesh_err("counter-clockwise"));
    }
    if rec.origin != [c.x, c.y] {
        return Err(mesh_err("origin is vertex 2"));
    }
    // Loose enough for f32 rounding of any triangle the writer accepts (height at least
    // 1e-4 of the longest edge); tight enough that a transform of another triangle fails.
    const BARY_TOL: f32 = 1.0e-2;
    let value_scale = a.value_dph.abs().max(b.value_dph.abs()).max(c.value_dph.abs());
    // `within` is false for NaN: finite coefficients can still overflow to inf - inf at a vertex.
    let within = |error: f32, tol: f32| error <= tol;
    for (k, v) in [a, b, c].iter().enumerate() {
        let l = barycentric(rec, v.x, v.y);
        let unit = |j: usize| if j == k { 1.0 } else { 0.0 };
        if !l.iter().enumerate().all(|(j, &lj)| within((lj - unit(j)).abs(), BARY_TOL)) {
            return Err(mesh_err("barycentric transform"));
        }
        if !within((plane_value(rec, v.x, v.y) - v.value_dph).abs(), BARY_TOL * (1.0 + value_scale)) {
            return Err(mesh_err("value plane"));
        }
    }
    Ok(())
}

/// Triangle `n` has `t` as a neighbour across the same edge, traversed the other way.
fn neighbour_points_back(mesh: &Mesh<'_>, rec: &TriangleRecord, t: u32, k: u32, n: u32) -> bool {
    let Some(other) = mesh.triangle(n) else { return false };
    let Some((from, to)) = edge_vertices(rec, k) else { return false };
    other
        .neighbours
        .iter()
        .enumerate()
        .any(|(j, &back)| back == t && edge_vertices(&other, j as u32) == Some((to, from)))
}

/// Hull entries are hull slots, chained end to start in a closed loop, turning left.
fn validate_hull(mesh: &Mesh<'_>, id: u16) -> Result<(), Error> {
    let hcount = mesh.hull_edge_count();
    let mesh_err = |check: &'static str, index: u32| Error::BadMesh { check, axis: id, index };
    let edge = |h: u32| -> Result<(u32, u32), Error> {
        let (t, e) = mesh.hull_edge(h).ok_or(mesh_err("hull entry", h))?;
        let rec = mesh.triangle(t).ok_or(Error::IndexOutOfRange {
            field: "hull.triangle",
            axis: id,
            index: h,
            value: t,
            limit: mesh.triangle_count(),
        })?;
        if rec.neighbours.get(e as usize) != Some(&NO_NEIGHBOUR) {
            return Err(mesh_err("hull entry is a hull edge", h));
        }
        edge_vertices(&rec, e).ok_or(mesh_err("hull edge index", h))
    };
    // Edge directions of a left-turning loop that goes round once cross the +x direction
    // (from the lower half-plane to the upper) exactly once; a loop listed twice, or wound
    // twice, crosses it more often.
    let upper = |dx: f32, dy: f32| dy > 0.0 || (dy == 0.0 && dx > 0.0);
    let mut windings = 0u32;
    for h in 0..hcount {
        let (a, b) = edge(h)?;
        let (b2, c) = edge((h + 1).checked_rem(hcount).unwrap_or(0))?;
        if b != b2 {
            return Err(mesh_err("hull chained", h));
        }
        let (Some(va), Some(vb), Some(vc)) = (mesh.vertex(a), mesh.vertex(b), mesh.vertex(c)) else {
            return Err(mesh_err("hull vertex", h));
        };
        let turn = (vb.x - va.x) * (vc.y - vb.y) - (vb.y - va.y) * (vc.x - vb.x);
        // Collinear hull points are allowed; f32 rounding may tilt them slightly.
        let scale = ((vb.x - va.x).abs() + (vb.y - va.y).abs()) * ((vc.x - vb.x).abs() + (vc.y - vb.y).abs());
        if turn < -1.0e-5 * scale {
            return Err(mesh_err("hull convex", h));
        }
        if !upper(vb.x - va.x, vb.y - va.y) && upper(vc.x - vb.x, vc.y - vb.y) {
            windings += 1;
        }
    }
    if windings != 1 {
        return Err(mesh_err("hull goes round once", 0));
    }
    Ok(())
}
