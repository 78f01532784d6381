//! `fogtemp.Model`: a validated model blob, evaluated and replayed by `fogtemp-core`.

use std::path::{Path, PathBuf};

use fogtemp_cal::documents::ModelDocument;
use fogtemp_cal::features::{micros, CAL_CAPACITY};
use fogtemp_core::{Axis, Compensator, Flags, Model as CoreModel, StartGrid, WalkHint};
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyFileNotFoundError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFloat, PyTuple};

use crate::compensate_notes;
use crate::convert::{self, f64_array, f64_vector, slice};
use crate::errors;
use crate::options::{int_arg, MIN_CAPACITY};

/// Below this many points an evaluation walks from the last triangle only; above it a start
/// grid over the mesh makes random-order queries a step or two each.
const GRID_MIN_POINTS: usize = 4096;
/// Start-grid cells per mesh triangle (measured on the paper-like 573-node mesh, 1 M random
/// points inside the hull: 31 ms with 1/4 cell per triangle, 18 ms with 4, 17 ms with 16).
const GRID_CELLS_PER_TRIANGLE: usize = 4;
/// Below this many points an evaluation runs on one thread.
const PARALLEL_MIN_POINTS: usize = 1 << 16;

/// A fogtemp model: the validated blob that firmware reads (`fogtemp-core`), with the
/// calibration library's documents about it.
///
/// Make one with `fogtemp.fit(...)`, `Model.from_file(path)` or `Model.from_bytes(b)`.
#[pyclass(frozen, module = "fogtemp")]
pub struct Model {
    blob: Vec<u8>,
    /// Where the blob came from, as documents and errors name it.
    source: String,
    /// The `fit --json` document when this model was fitted in this process.
    fit_json: Option<String>,
    /// Per axis, the start grid of its mesh (side, cells), built with the model as scipy's
    /// interpolator builds its search structure at construction; `None` without a mesh.
    grids: Vec<Option<(u32, Vec<u32>)>>,
    /// `__hash__`: of the blob's bytes, computed once (the blob never changes).
    hash: u64,
}

impl Model {
    /// A model from `blob` after the core's validation.
    pub fn new(blob: Vec<u8>, source: String, fit_json: Option<String>) -> PyResult<Self> {
        let core = CoreModel::from_bytes(&blob).map_err(|e| errors::model(&source, e))?;
        let grids = (0..core.axis_count())
            .map(|i| core.axis(i).ok().and_then(|a| a.mesh).and_then(|mesh| start_grid(&mesh, usize::MAX)))
            .collect();
        let hash = {
            use std::hash::{Hash, Hasher};
            let mut hasher = std::collections::hash_map::DefaultHasher::new();
            blob.hash(&mut hasher);
            hasher.finish()
        };
        Ok(Self { blob, source, fit_json, grids, hash })
    }

    /// The blob.
    pub fn blob(&self) -> &[u8] {
        &self.blob
    }

    /// Where it came from.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The core's view of the blob (validated at construction; validated again, cheaply).
    fn core(&self) -> PyResult<CoreModel<'_>> {
        CoreModel::from_bytes(&self.blob).map_err(|e| errors::model(&self.source, e))
    }

    /// Axis `index`, or `IndexError`-like `ValueError` naming the axis count.
    fn axis(&self, index: usize) -> PyResult<Axis<'_>> {
        let model = self.core()?;
        if index >= model.axis_count() {
            return Err(errors::value(format!(
                "{}: axis {index} does not exist (the model has {} {})",
                self.source,
                model.axis_count(),
                if model.axis_count() == 1 { "axis" } else { "axes" }
            )));
        }
        model.axis(index).map_err(|e| errors::model(&self.source, e))
    }
}

#[pymethods]
impl Model {
    /// Reads and validates a model file (`.fogm`, as `fogtemp-cal fit` writes it).
    ///
    /// Raises FileNotFoundError if there is no such file, ValueError if the bytes are not a
    /// valid model (the message names the field the core's validation refused).
    #[staticmethod]
    fn from_file(path: PathBuf) -> PyResult<Self> {
        Self::new(read_model_file(&path)?, path.display().to_string(), None)
    }

    /// A model from the bytes of a blob (validated by the core: a truncated or corrupted blob
    /// raises ValueError, never crashes).
    #[staticmethod]
    fn from_bytes(data: &Bound<'_, PyAny>) -> PyResult<Self> {
        Self::new(blob_bytes(data)?, "<bytes>".to_string(), None)
    }

    /// The blob, exactly what firmware embeds (`include_bytes!`, or the C array of `export`).
    fn to_bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        PyBytes::new(py, &self.blob)
    }

    /// Writes the blob to `path` atomically (a temporary file in the same folder, synced,
    /// then renamed into place).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let blob = &self.blob;
        fogtemp_cal::output::check_output_file(&path).map_err(errors::cal)?;
        py.detach(|| fogtemp_cal::output::write_file_atomic(&path, |w| w.write_all(blob)))
            .map_err(errors::cal)
    }

    /// The `fogtemp-cal inspect --json` document: header, per axis the feature settings,
    /// normalisation, provenance, polynomial terms, mesh `nodes` (`temp_c`,
    /// `rate_c_per_min`, `value_dph`, normalised `x`, `y`), `triangles`, and the log columns
    /// the axis was fitted on (`gyro_column`, `temp_column`; `None` when not recorded).
    fn inspect<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let doc = ModelDocument::new(Path::new(&self.source), &self.blob)
            .map_err(|e| errors::model(&self.source, e))?;
        convert::document(py, &doc)
    }

    /// Number of gyro axes.
    #[getter]
    fn axis_count(&self) -> PyResult<usize> {
        Ok(self.core()?.axis_count())
    }

    /// The `fogtemp-cal fit --json` document of this model when it was fitted by
    /// `fogtemp.fit` in this process (per axis the points, polynomial, mesh size and
    /// residuals), else None.
    #[getter]
    fn fit_report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match &self.fit_json {
            Some(text) => Ok(Some(py.import("json")?.call_method1("loads", (text,))?)),
            None => Ok(None),
        }
    }

    /// The model's bias at `(temp_c, rate_c_per_min)`, deg/h, through the core's own
    /// evaluation (f32, normalisation, polynomial, mesh walk, outside-hull policy).
    ///
    /// The inputs are array-like (numpy arrays of any shape, lists, scalars, pandas Series)
    /// and broadcast against each other; the result has their broadcast shape, or is a
    /// Python float when both are scalars (or 0-d arrays), as numpy's ufuncs do. A NaN or
    /// infinite input gives NaN at that point. Runs with the GIL released, on `threads`
    /// threads for large inputs (default: every core; 0 or 1: the calling thread; more than
    /// the cores available to the process are capped at their number).
    ///
    /// With `return_outside=True`, returns `(values, outside)`: `outside` (bool, same shape)
    /// is True where the point lies outside the calibrated region, where the value is the
    /// model's continuation (the core's `outside_hull`, C's `fogtemp_evaluate`, the
    /// compensator's `OUTSIDE_HULL` flag); False at a NaN point, and outside the region of a
    /// polynomial fitted with `poly_outside="extrapolate"` (its value there is the polynomial's
    /// own, not flagged: mask by `inspect()`'s calibrated range instead).
    #[pyo3(signature = (temp_c, rate_c_per_min, axis = None, threads = None, return_outside = None))]
    #[pyo3(text_signature = "(self, temp_c, rate_c_per_min, axis=0, threads=None, return_outside=False)")]
    #[allow(clippy::too_many_arguments)] // Python's keywords, each with its default
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        temp_c: &Bound<'py, PyAny>,
        rate_c_per_min: &Bound<'py, PyAny>,
        axis: Option<&Bound<'py, PyAny>>,
        threads: Option<&Bound<'py, PyAny>>,
        return_outside: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let return_outside = bool_arg("Model.evaluate", "return_outside", return_outside)?;
        let axis = axis_arg("Model.evaluate", axis)?;
        let threads: Option<usize> =
            threads.map(|t| int_arg("Model.evaluate", "threads", t, 0, u64::MAX)).transpose()?;
        let core_axis = self.axis(axis)?;
        let (mut t, mut r) = (f64_array(temp_c, "temp_c")?, f64_array(rate_c_per_min, "rate_c_per_min")?);
        if t.shape() != r.shape() {
            let pair = py.import("numpy")?.call_method1("broadcast_arrays", (t.as_any(), r.as_any()))?;
            t = f64_array(&pair.get_item(0)?, "temp_c")?;
            r = f64_array(&pair.get_item(1)?, "rate_c_per_min")?;
        }
        let shape = t.shape().to_vec();
        let (ts, rs) = (slice(&t, "temp_c")?, slice(&r, "rate_c_per_min")?);
        // NaN or infinite gives NaN (not a point to place, so not outside either); an infinite
        // one is warned of, as it passed without a word (review27a 3).
        for (values, name) in [(ts, "temp_c"), (rs, "rate_c_per_min")] {
            let infinite = values.iter().filter(|v| v.is_infinite()).count();
            if let Some(k) = values.iter().position(|v| v.is_infinite()) {
                crate::progress::warn(
                    py,
                    &format!(
                        "Model.evaluate: {infinite} point{} with an infinite {name} (the first {name}[{k}] = {}) \
                         give NaN, as NaN does, and are not marked outside",
                        if infinite == 1 { "" } else { "s" },
                        values[k]
                    ),
                )?;
            }
        }
        // More threads than cores only add spawning and switching (review20 F12: threads=100000
        // spawned that many and ran 7x slower).
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = threads.unwrap_or(cores).clamp(1, cores);
        let cached = self.grids.get(axis).and_then(Option::as_ref);
        let values = py.detach(|| evaluate_points(&core_axis, cached, ts, rs, threads));
        let outside = return_outside.then(|| py.detach(|| outside_points(&core_axis, ts, rs, threads)));
        let (values, outside) = if shape.is_empty() {
            // Scalars in, a float out (a 0-d input holds one point).
            let value = PyFloat::new(py, values.first().copied().unwrap_or(f64::NAN)).into_any();
            let outside =
                outside.map(|o| PyBool::new(py, o.first().copied().unwrap_or(false)).to_owned().into_any());
            (value, outside)
        } else {
            let value = PyArray1::from_vec(py, values).reshape(shape.clone())?.into_any();
            let outside =
                outside.map(|o| PyArray1::from_vec(py, o).reshape(shape)).transpose()?.map(Bound::into_any);
            (value, outside)
        };
        match outside {
            Some(outside) => Ok(PyTuple::new(py, [values, outside])?.into_any()),
            None => Ok(values),
        }
    }

    /// Replays a recording through the core `Compensator` of `axis`, sample by sample,
    /// exactly as firmware would (the command line's `compensate`): returns
    /// `(compensated_dph, flags)` (and the subtracted `bias_dph` with `return_bias=True`).
    ///
    /// `time_s` (seconds, any origin: the compensator sees microseconds since the first
    /// sample), `gyro_dph` (deg/h) and `temp_c` (deg C; NaN where a sample has no
    /// temperature reading; an infinite or impossible one, -999 or 65236, is flagged
    /// BAD_INPUT as firmware flags it) are 1-D and of equal length; times in a float type too
    /// narrow for their steps (float32 at a Unix time) are refused. The outputs are float64 arrays
    /// holding the core's f32 results exactly, and uint8 flags (`fogtemp.FLAG_BITS`).
    /// `capacity` is the firmware's tracker capacity (the core's default, 128): a model whose
    /// window needs more blocks is refused, as the command line refuses it.
    ///
    /// FogtempWarnings say what the command line's `compensate` notes: time that goes back
    /// (named by the sample index; the command line refuses such a log, the compensator
    /// restarts there and the output stays row for row), gaps, temperature glitches (as
    /// `sample:INDEX`, 0-based), and the shares of samples flagged BAD_INPUT, TEMP_STALE and
    /// OUTSIDE_HULL.
    #[pyo3(signature = (time_s, gyro_dph, temp_c, axis = None, return_bias = None, capacity = None))]
    #[pyo3(text_signature = "(self, time_s, gyro_dph, temp_c, axis=0, return_bias=False, capacity=128)")]
    #[allow(clippy::too_many_arguments)] // Python's keywords, each with its default
    fn compensate<'py>(
        &self,
        py: Python<'py>,
        time_s: &Bound<'py, PyAny>,
        gyro_dph: &Bound<'py, PyAny>,
        temp_c: &Bound<'py, PyAny>,
        axis: Option<&Bound<'py, PyAny>>,
        return_bias: Option<&Bound<'py, PyAny>>,
        capacity: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let axis = axis_arg("Model.compensate", axis)?;
        let return_bias = bool_arg("Model.compensate", "return_bias", return_bias)?;
        let capacity = match capacity {
            Some(c) => int_arg("Model.compensate", "capacity", c, MIN_CAPACITY, u64::MAX)?,
            None => fogtemp_core::DEFAULT_CAPACITY,
        };
        // The firmware's tracker capacity: a model needing more blocks fails at its boot.
        crate::options::capacity_fits(self.axis(axis)?.blocks_needed(), capacity)?;
        let (t, g, c) =
            (f64_vector(time_s, "time_s")?, f64_vector(gyro_dph, "gyro_dph")?, f64_vector(temp_c, "temp_c")?);
        let (ts, gs, cs) = (slice(&t, "time_s")?, slice(&g, "gyro_dph")?, slice(&c, "temp_c")?);
        if gs.len() != ts.len() || cs.len() != ts.len() {
            return Err(errors::value(format!(
                "time_s, gyro_dph and temp_c must have the same length, got {}, {} and {}",
                ts.len(),
                gs.len(),
                cs.len()
            )));
        }
        if let Some(k) = ts.iter().position(|t| !t.is_finite()) {
            return Err(errors::value(format!("time_s[{k}] is not a finite number ({})", ts[k])));
        }
        // As the logs' reader refuses it (review27a 2: 1e300 came out as inf under a warning
        // that blamed the temperature or the time). NaN and inf pass through as the firmware's.
        if let Some(k) = gs.iter().position(|g| g.is_finite() && g.abs() > f64::from(f32::MAX)) {
            return Err(errors::value(format!(
                "gyro_dph[{k}] is {:.3e}, beyond the f32 the compensator takes (about 3.4e38 deg/h)",
                gs[k]
            )));
        }
        // As fit and validate refuse them (review23a F1: float32 times 11 h into a run lost 74 %
        // of their steps, flagged BAD_INPUT under a note that blamed the data).
        crate::functions::refuse_times_lost_to_precision(time_s, &t, "time_s")?;
        let model = self.core()?;
        let mut comp: Box<Compensator<'_, CAL_CAPACITY>> =
            Box::new(Compensator::new(&model, axis).map_err(|e| errors::model(&self.source, e))?);
        let max_gap_s = comp.tracker().max_gap_us() as f64 * 1e-6;
        let mut outside = fogtemp_cal::calibrate::OutsideWatch::new(&model, axis);
        let replay = py.detach(|| {
            // The glitches are looked for beside the replay (they only read the inputs), so
            // that the note costs no time where a second core is free.
            std::thread::scope(|scope| {
                let glitches = scope.spawn(|| compensate_notes::temperature_glitches(ts, gs, cs, max_gap_s));
                let (out, bias, flags) = replay_samples(&mut comp, ts, gs, cs, &mut outside);
                let glitches = glitches.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic));
                (out, bias, flags, glitches)
            })
        });
        let (out, bias, flags, glitches) = replay;
        let sources = fogtemp_cal::calibrate::BadInputSources {
            gyro_not_finite: gs.iter().filter(|g| !g.is_finite()).count() as u64,
            same_microsecond: fogtemp_cal::calibrate::same_microsecond_rejections(ts, cs, &flags),
            ..Default::default()
        };
        let replay = Replay {
            flags: &flags,
            max_gap_s,
            glitches: &glitches,
            sources: &sources,
            outside: outside.reach(),
        };
        warn_about_compensation(py, axis, ts, &replay)?;
        let mut items: Vec<Bound<'py, PyAny>> =
            vec![PyArray1::from_vec(py, out).into_any(), PyArray1::from_vec(py, flags).into_any()];
        if return_bias {
            items.push(PyArray1::from_vec(py, bias).into_any());
        }
        PyTuple::new(py, items)
    }

    fn __repr__(&self) -> PyResult<String> {
        let model = self.core()?;
        let axes: Vec<String> = (0..model.axis_count())
            .filter_map(|i| model.axis(i).ok())
            .map(|a| {
                let mut kind = Vec::new();
                if let Some(p) = a.poly {
                    let t_alone = if p.terms().all(|t| t.rate_power == 0) { ", T alone" } else { "" };
                    kind.push(format!("poly({} terms{t_alone})", p.len()));
                }
                if let Some(m) = a.mesh {
                    kind.push(format!("mesh({} nodes)", m.vertex_count()));
                }
                kind.join("+")
            })
            .collect();
        Ok(format!("<fogtemp.Model {} bytes, axes: [{}]>", self.blob.len(), axes.join(", ")))
    }

    /// Equal when the blobs are equal byte for byte (where each came from and its fit
    /// report are not compared); a `Model` is never equal to anything else.
    fn __eq__(&self, other: &Self) -> bool {
        self.blob == other.blob
    }

    /// Of the blob's bytes, consistent with `==`: a `Model` never changes (its blob is what
    /// firmware embeds), so it can key a dict or sit in a set as `bytes` can.
    fn __hash__(&self) -> u64 {
        self.hash
    }

    /// Pickles as its bytes.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let from_bytes = py.get_type::<Model>().getattr("from_bytes")?;
        let bytes = PyBytes::new(py, &slf.get().blob);
        PyTuple::new(py, [from_bytes, PyTuple::new(py, [bytes])?.into_any()])
    }
}

/// The `axis` argument of `method` (0 when not given): `ValueError` for a negative one.
/// A True/False keyword (None: False), with a TypeError naming the method and keyword for
/// anything else (`"yes"`, `1`).
fn bool_arg(method: &str, name: &str, value: Option<&Bound<'_, PyAny>>) -> PyResult<bool> {
    let Some(value) = value.filter(|v| !v.is_none()) else { return Ok(false) };
    value.cast::<PyBool>().map(|b| b.is_true()).map_err(|_| {
        let kind = value.get_type().name().map_or_else(|_| "?".to_string(), |n| n.to_string());
        pyo3::exceptions::PyTypeError::new_err(format!(
            "{method}(): {name} must be True or False, got a {kind}"
        ))
    })
}

fn axis_arg(method: &str, axis: Option<&Bound<'_, PyAny>>) -> PyResult<usize> {
    axis.map_or(Ok(0), |a| int_arg(method, "axis", a, 0, u64::MAX))
}

/// A start grid of about [`GRID_CELLS_PER_TRIANGLE`] cells per triangle, but at most
/// `max_cells` (side, cells); `None` if the mesh cannot give one.
fn start_grid(mesh: &fogtemp_core::Mesh<'_>, max_cells: usize) -> Option<(u32, Vec<u32>)> {
    let cells_wanted = (GRID_CELLS_PER_TRIANGLE * mesh.triangle_count() as usize).min(max_cells).max(1);
    let side = u32::try_from((cells_wanted as f64).sqrt() as u64).ok()?.max(1);
    let mut cells = vec![0u32; (side as usize).checked_mul(side as usize)?];
    mesh.start_grid(side, &mut cells).ok()?;
    Some((side, cells))
}

/// Evaluates every point (NaN where an input is not finite), on up to `threads` threads,
/// through `Axis::evaluate_with_grid` (the firmware's evaluation, the mesh located from a
/// start grid). The model's own grid serves calls of at least four points per cell; a smaller
/// call builds a smaller grid (never more cells than a quarter of the points, so that
/// building it stays a small part of the call).
fn evaluate_points(
    axis: &Axis<'_>,
    cached: Option<&(u32, Vec<u32>)>,
    ts: &[f64],
    rs: &[f64],
    threads: usize,
) -> Vec<f64> {
    // Zeroed, not NaN-filled: every element is written below, and a fresh zeroed allocation
    // costs no pass over the 8 bytes per point that a fill would write first.
    let mut out = vec![0.0; ts.len()];
    let large = ts.len() >= GRID_MIN_POINTS;
    let kept = cached.filter(|(_, cells)| large && cells.len() <= ts.len() / 4);
    let own = match (&axis.mesh, kept) {
        (Some(mesh), None) if large => start_grid(mesh, ts.len() / 4),
        _ => None,
    };
    let grid = axis
        .mesh
        .as_ref()
        .zip(own.as_ref().or(kept))
        .and_then(|(mesh, (side, cells))| mesh.grid_from_cells(*side, cells).ok());
    let threads = if ts.len() >= PARALLEL_MIN_POINTS { threads } else { 1 };
    let chunk = ts.len().div_ceil(threads).max(1);
    std::thread::scope(|scope| {
        for ((out, ts), rs) in out.chunks_mut(chunk).zip(ts.chunks(chunk)).zip(rs.chunks(chunk)) {
            let grid = grid.as_ref();
            scope.spawn(move || evaluate_chunk(axis, grid, ts, rs, out));
        }
    });
    out
}

/// Whether each point is outside the calibrated region (the core's `outside_hull`; false
/// where the evaluation fails, a NaN point), on up to `threads` threads.
fn outside_points(axis: &Axis<'_>, ts: &[f64], rs: &[f64], threads: usize) -> Vec<bool> {
    let mut out = vec![false; ts.len()];
    let threads = if ts.len() >= PARALLEL_MIN_POINTS { threads } else { 1 };
    let chunk = ts.len().div_ceil(threads).max(1);
    std::thread::scope(|scope| {
        for ((out, ts), rs) in out.chunks_mut(chunk).zip(ts.chunks(chunk)).zip(rs.chunks(chunk)) {
            scope.spawn(move || {
                let mut hint = WalkHint::default();
                for ((o, &t), &r) in out.iter_mut().zip(ts).zip(rs) {
                    *o = axis.evaluate(t as f32, r as f32, &mut hint).is_ok_and(|e| e.outside_hull);
                }
            });
        }
    });
    out
}

/// Points per block of [`evaluate_chunk`]'s two passes: the block's pending list (2 bytes a
/// point) stays in the first-level cache.
const BLOCK_POINTS: usize = 1024;
// The pending list holds a block's indices as u16.
const _: () = assert!(BLOCK_POINTS <= 1 << 16);

/// One thread's points, with its own walk hint. With a start grid, block by block in two
/// passes: first every point's grid-cell triangle (`Axis::evaluate_in_grid_cell`), its value
/// kept where that triangle holds the point and the others noted without a branch, then those
/// others by `Axis::evaluate_with_grid`. The same values as `evaluate_with_grid` on every
/// point (the first pass's values are its own first step), without mispredicting, at every
/// point outside the hull or near a triangle edge, which of the two paths it takes: on random
/// points those are a quarter of them, interleaved at random with the rest.
fn evaluate_chunk(axis: &Axis<'_>, grid: Option<&StartGrid<'_>>, ts: &[f64], rs: &[f64], out: &mut [f64]) {
    let mut hint = WalkHint::default();
    let Some(grid) = grid else {
        for ((o, &t), &r) in out.iter_mut().zip(ts).zip(rs) {
            *o = axis.evaluate(t as f32, r as f32, &mut hint).map_or(f64::NAN, |e| f64::from(e.value_dph));
        }
        return;
    };
    let mut pending = [0u16; BLOCK_POINTS];
    let blocks = out.chunks_mut(BLOCK_POINTS).zip(ts.chunks(BLOCK_POINTS)).zip(rs.chunks(BLOCK_POINTS));
    for ((out, ts), rs) in blocks {
        let mut count = 0;
        for (k, ((o, &t), &r)) in out.iter_mut().zip(ts).zip(rs).enumerate() {
            let (evaluation, held) = axis.evaluate_in_grid_cell(t as f32, r as f32, grid);
            *o = f64::from(evaluation.value_dph);
            // Written always, kept (counted) only when the cell's triangle did not hold it.
            if let Some(slot) = pending.get_mut(count) {
                *slot = k as u16;
            }
            count += usize::from(!held);
        }
        for &k in pending.iter().take(count) {
            let k = usize::from(k);
            if let (Some(o), Some(&t), Some(&r)) = (out.get_mut(k), ts.get(k), rs.get(k)) {
                let evaluation = axis.evaluate_with_grid(t as f32, r as f32, &mut hint, grid);
                *o = evaluation.map_or(f64::NAN, |e| f64::from(e.value_dph));
            }
        }
    }
}

/// What a replay of one axis left for its notes.
struct Replay<'a> {
    /// Each sample's flags.
    flags: &'a [u8],
    /// The tracker's max gap, seconds.
    max_gap_s: f64,
    /// Temperature glitches found beside the replay.
    glitches: &'a fogtemp_cal::spikes::AxisSpikes,
    /// Where its `BAD_INPUT` samples can come from.
    sources: &'a fogtemp_cal::calibrate::BadInputSources,
    /// How far its samples flagged `OUTSIDE_HULL` reach.
    outside: Option<&'a fogtemp_cal::calibrate::OutsideReach>,
}

/// Every sample through `comp`, as firmware steps it (times as microseconds since the first
/// sample; a NaN temperature is no reading, an infinite one a reading the compensator flags
/// BAD_INPUT, as the command line and the C API pass it; review20 F2): the rate, bias and
/// flags of each; the samples flagged `OUTSIDE_HULL` are counted in `outside`.
fn replay_samples(
    comp: &mut Compensator<'_, CAL_CAPACITY>,
    ts: &[f64],
    gs: &[f64],
    cs: &[f64],
    outside: &mut fogtemp_cal::calibrate::OutsideWatch<'_>,
) -> (Vec<f64>, Vec<f64>, Vec<u8>) {
    let n = ts.len();
    let (mut out, mut bias, mut flags) = (vec![0.0; n], vec![0.0; n], vec![0u8; n]);
    let origin = ts.first().copied().unwrap_or(0.0);
    for k in 0..n {
        let temp = cs[k];
        let o = comp.step(micros(ts[k] - origin), gs[k] as f32, (!temp.is_nan()).then_some(temp as f32));
        out[k] = f64::from(o.rate_dph);
        bias[k] = f64::from(o.bias_dph);
        flags[k] = o.flags.0;
        outside.observe_output(&o, comp);
    }
    (out, bias, flags)
}

/// `{name: bit}` of the compensator's flags.
pub fn flag_bits(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    for (name, flag) in Flags::NAMED {
        d.set_item(name, flag.0)?;
    }
    Ok(d)
}

/// The bytes of a model file: FileNotFoundError if there is none, OSError if it cannot be read.
pub(crate) fn read_model_file(path: &std::path::Path) -> PyResult<Vec<u8>> {
    std::fs::read(path).map_err(|e| {
        let message = format!("cannot read model {}: {e}", path.display());
        if e.kind() == std::io::ErrorKind::NotFound {
            PyFileNotFoundError::new_err(message)
        } else {
            pyo3::exceptions::PyOSError::new_err(message)
        }
    })
}

/// The bytes of a blob given to `from_bytes`: bytes, bytearray, memoryview or a sequence of
/// byte values; text is refused naming what to pass instead (PyO3's own message named a Rust
/// type).
fn blob_bytes(data: &Bound<'_, PyAny>) -> PyResult<Vec<u8>> {
    if data.is_instance_of::<pyo3::types::PyString>() {
        return Err(errors::type_(
            "Model.from_bytes(): data must be bytes (a model blob), got str; to read a model file use \
             Model.from_file(path)",
        ));
    }
    if let Ok(view) = data.cast::<pyo3::types::PyMemoryView>() {
        return view.call_method0("tobytes")?.extract();
    }
    data.extract::<Vec<u8>>().map_err(|_| {
        let type_name = data.get_type().name().map_or_else(|_| "?".to_string(), |n| n.to_string());
        errors::type_(format!(
            "Model.from_bytes(): data must be bytes, bytearray or memoryview (a model blob), got {type_name}"
        ))
    })
}

/// What `fogtemp-cal compensate` notes of its output, as warnings (review17 F1: a notebook
/// user who does not decode the flags got the raw gyro back, or a bias continued far outside
/// the calibration, without a word): time that goes back (which the command line refuses),
/// times mostly further apart than the tracker's max gap (another unit?), temperature
/// glitches, nothing corrected, and the shares of samples flagged `BAD_INPUT` (`sources`: how
/// many with a gyro value that is not finite, or in the microsecond of the sample before),
/// `TEMP_STALE` and `OUTSIDE_HULL` (with how far those reach).
fn warn_about_compensation(py: Python<'_>, axis: usize, time_s: &[f64], replay: &Replay<'_>) -> PyResult<()> {
    let Replay { flags, max_gap_s, glitches, sources, outside } = *replay;
    let name = format!("Model.compensate axis {axis}");
    if let Some(note) = compensate_notes::backward_time_note(&name, time_s, max_gap_s) {
        crate::progress::warn(py, &note)?;
    }
    let mut gaps = fogtemp_cal::calibrate::TimeGaps::new(max_gap_s);
    gaps.in_samples = true;
    for (k, pair) in time_s.windows(2).enumerate() {
        gaps.observe(Some(pair[0]), pair[1], k as u64 + 1);
    }
    let samples = flags.len() as u64;
    let path = Path::new(&name);
    if gaps.mostly_gaps(samples) {
        let note = format!(
            "{name}: {} of its {} steps between samples are longer than the tracker's max gap of {max_gap_s} s: \
             is time_s in another unit? It is read in seconds (milliseconds / 1000)",
            gaps.count,
            samples - 1
        );
        crate::progress::warn(py, &note)?;
    } else if let Some(note) =
        gaps.note_then(path, "after each the compensator held its bias until its tracker had features again")
    {
        crate::progress::warn(py, &note)?;
    }
    if let Some(note) = compensate_notes::temperature_glitch_note(&name, glitches) {
        crate::progress::warn(py, &note)?;
    }
    let mut counts = [0u64; 8];
    for f in flags {
        for (bit, count) in counts.iter_mut().enumerate() {
            *count += u64::from((f >> bit) & 1);
        }
    }
    let consequence = "the returned rate is the gyro input and its bias 0";
    for note in fogtemp_cal::calibrate::compensation_notes(
        &name,
        &counts,
        samples,
        max_gap_s,
        "flags",
        consequence,
        sources,
        outside,
    ) {
        crate::progress::warn(py, &note)?;
    }
    Ok(())
}
