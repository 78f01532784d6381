"""fogtemp: temperature-drift calibration of fibre-optic gyros (fit, evaluate, compensate,
validate, simulate) from numpy arrays, pandas DataFrames and CSV logs.

A thin layer over the Rust libraries fogtemp-cal (calibration), fogtemp-core (the firmware
runtime) and fogtemp-sim (the simulator): the same code the ``fogtemp-cal`` command runs, with
the same JSON documents (as dicts) and the same error messages.

Integer keywords (``blocks``, ``capacity``, ``axis``, ``seed``, ...) outside their range, negative
ones included, raise ValueError naming the keyword and the range; a non-integer (or a bool) raises
TypeError. Array arguments take numbers (lists, numpy arrays, pandas Series; ``None`` inside a
list is a missing value, NaN): ``None`` itself, text (``"20"``) and booleans raise TypeError
rather than being read as NaN, 20.0 and 1.0. Ctrl-C (KeyboardInterrupt) during ``fit``, ``validate``, ``diagnose`` and the readers is
raised at the next boundary between logs or stages, or in a fit's cross-validation at its next
held-out run: the libraries' work on one log, and the fits of one fold, are not cut short.
"""

import os
from typing import Any, Dict, List, Literal, Mapping, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

METHODS: List[str]
"""Accepted ``fit`` methods: "auto", "poly", "mesh", "hybrid", "cubic-t"."""

FLAG_BITS: Dict[str, int]
"""Compensator flag bits: WARMING_UP 1, PARTIAL_WINDOW 2, OUTSIDE_HULL 4, TEMP_STALE 8, BAD_INPUT 16."""

class FogtempWarning(UserWarning):
    """A note or warning of fogtemp's (the command line's ``note:`` and ``warning:`` lines): skipped
    rows, gaps, units read as the model was fitted, data that cannot support what was asked.
    ``warnings.filterwarnings("ignore", category=fogtemp.FogtempWarning)`` silences fogtemp's
    alone; ``"error"`` turns them into exceptions."""

class FogtempNote(FogtempWarning):
    """A note that needs no action (the command line's ``note:`` lines): logs read as the model
    was fitted, run metadata read from a file or manifest, gaps counted, channels on separate
    rows. ``warnings.filterwarnings("ignore", category=fogtemp.FogtempNote)`` silences the notes
    and keeps the warnings."""

# Names for the annotations below only (private: not in the module at run time).
_PathLike = Union[str, "os.PathLike[str]"]
_ArrayLike = npt.ArrayLike
_Run = Mapping[str, Any]
"""A run given as arrays: a dict or pandas DataFrame with ``time_s`` (s), ``temp_c`` (deg C, NaN =
no reading) and ``gyro_dph`` (deg/h; for several axes a dict holding a 2-D array with one column
per axis, or ``gyro_dph_0``, ``gyro_dph_1``, ... as ``read_log`` returns them; ``temp_c`` alike). Columns hold numbers (int, float32 or float64; None or pandas NA = missing); text,
booleans and date-times are refused (TypeError): give time in seconds, e.g.
``(t - t.iloc[0]).dt.total_seconds()``. A DataFrame's index is not read (``reset_index()``).
The gyro is the bias plus the true input rate: subtract each run's input rate (Earth rate in its
position, or a turntable's) from ``gyro_dph`` yourself, or give the runs in a dict with ``runs=``
(a runs file naming them by their keys), which does it; else the model takes a shared input
rate as bias (with the warning ``no_run_metadata``). Several runs: a list, or a dict keyed by run
name (the names then stand for the runs in documents, messages and a runs file)."""

class Model:
    """A validated fogtemp model blob (what firmware embeds), with the library's documents.

    Models compare equal when their blobs are equal byte for byte (``to_bytes()``); where they
    came from and ``fit_report`` are not compared. A Model is immutable, so it is hashable
    (consistently with ``==``) and can key a dict or sit in a set."""

    @staticmethod
    def from_file(path: _PathLike) -> "Model":
        """Reads and validates a model file. FileNotFoundError, or ValueError naming the field."""
    @staticmethod
    def from_bytes(data: bytes) -> "Model":
        """Validates a blob's bytes; a truncated or corrupted blob raises ValueError."""
    def to_bytes(self) -> bytes:
        """The blob, exactly what firmware embeds."""
    def save(self, path: _PathLike) -> None:
        """Writes the blob atomically."""
    def inspect(self) -> Dict[str, Any]:
        """The ``fogtemp-cal inspect --json`` document (axes, nodes, triangles, polynomial, the log
        columns each axis was fitted on: ``gyro_column``, ``temp_column``, None when not recorded;
        ``log_time``: how the fit read the logs' time, None when not recorded; ``log_reading``:
        the decimal mark and each calibration log's digest, None before format 6;
        ``input_rates_subtracted``: True when the fit took each run's input rate off its gyro,
        False when run metadata gave rates that were left in, None when not recorded, ...)."""
    @property
    def axis_count(self) -> int:
        """Number of gyro axes."""
    @property
    def fit_report(self) -> Optional[Dict[str, Any]]:
        """The ``fit --json`` document when fitted by ``fogtemp.fit`` in this process, else None
        (not kept by pickle or save: ``json.dump`` it to keep it). The model choice of
        method="auto" is ``fit_report["axes"][i]["selection"]``: ``method`` (chosen), ``best``,
        ``rule``, ``grouping``, ``folds`` and ``candidates`` (per method its
        ``cv_bias_stability_dph``, ``standard_error_dph``, ``within_one_standard_error`` and per
        held-out run ``runs``), e.g. ``pandas.DataFrame(fit_report["axes"][0]["selection"]["candidates"])``."""
    @overload
    def evaluate(
        self,
        temp_c: float,
        rate_c_per_min: float,
        axis: int = 0,
        threads: Optional[int] = None,
    ) -> float: ...
    @overload
    def evaluate(
        self,
        temp_c: _ArrayLike,
        rate_c_per_min: _ArrayLike,
        axis: int = 0,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.float64]:
        """Bias in deg/h at (temp_c, rate_c_per_min), broadcast, any shape; NaN for NaN or infinite input (a warning for infinite).
        A float when both inputs are scalars (a 0-d array counts as one, so this overload's type is
        exact for arrays of at least one dimension), else an array of the broadcast shape.
        Through the core's f32 evaluation; GIL released; ``threads`` defaults to every core
        (0 or 1: the calling thread; more than the cores available are capped at their number).
        With ``return_outside=True``: ``(values, outside)``, outside a bool array (a bool for
        scalars), True where the point is outside the calibrated region (the model's
        continuation; C's ``fogtemp_evaluate`` outside flag); not flagged there for a polynomial
        fitted with ``poly_outside="extrapolate"``."""
    @overload
    def evaluate(
        self,
        temp_c: float,
        rate_c_per_min: float,
        axis: int = 0,
        threads: Optional[int] = None,
        *,
        return_outside: Literal[True],
    ) -> Tuple[float, bool]: ...
    @overload
    def evaluate(
        self,
        temp_c: _ArrayLike,
        rate_c_per_min: _ArrayLike,
        axis: int = 0,
        threads: Optional[int] = None,
        *,
        return_outside: Literal[True],
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]: ...
    @overload
    def compensate(
        self,
        time_s: _ArrayLike,
        gyro_dph: _ArrayLike,
        temp_c: _ArrayLike,
        axis: int = 0,
        return_bias: Literal[False] = False,
        capacity: int = 128,
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.uint8]]: ...
    @overload
    def compensate(
        self,
        time_s: _ArrayLike,
        gyro_dph: _ArrayLike,
        temp_c: _ArrayLike,
        axis: int = 0,
        return_bias: Literal[True] = ...,
        capacity: int = 128,
    ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.uint8], npt.NDArray[np.float64]]:
        """Replays the samples through the firmware's Compensator (``fogtemp-cal compensate``):
        ``(compensated_dph, flags)``, and ``bias_dph`` with ``return_bias=True``, row for row.
        FogtempWarnings say what ``fogtemp-cal compensate`` notes: time that goes back (named by
        the sample index; the command line refuses such a log, the compensator restarts there),
        gaps, temperature glitches (``sample:INDEX``, 0-based), and the shares of samples flagged
        BAD_INPUT, TEMP_STALE and OUTSIDE_HULL, the last with how far they reach beyond the
        calibrated ranges, in ``validate``'s words."""
    def __eq__(self, other: object) -> bool:
        """True when ``other`` is a Model with the same blob bytes."""
    def __hash__(self) -> int:
        """Of the blob bytes (equal models hash equal)."""
    def __reduce__(self) -> Tuple[Any, Tuple[bytes]]: ...

def fit(
    logs: Union[_PathLike, _Run, Sequence[Union[_PathLike, _Run]]],
    method: str = "auto",
    *,
    out: Optional[_PathLike] = None,
    progress: bool = True,
    **options: Any,
) -> Model:
    """Fits a model to calibration logs (paths or folders) or runs given as arrays.

    method: "auto" (what ``fogtemp-cal fit`` does by default), "poly", "mesh", "hybrid", "cubic-t".

    Options: the ``fogtemp-cal fit`` flags as keywords (window_s, blocks, min_blocks, max_gap_s,
    target_window_s, full_windows_only, thinning, tolerance_dph, max_nodes, interpolate_nodes,
    fast_rate, settled_every, poly, max_degree, p_enter, p_remove, poly_outside ("linear_from_boundary",
    the default, "extrapolate" or "hold_at_boundary"), mesh_outside ("linear_stored_gradients",
    the default, "hold" or "linear_from_boundary"; a mesh model's mesh beyond its hull), capacity, operating_temp_c as a
    (min, max) pair) and, for files, the log-column options (time_column, time_unit ("s", "ms", "us", "ns", "min", "h", "datetime" or "time_of_day"), temp_column,
    temp_scale, temp_offset, gyro_column, gyro_unit, gyro_scale, delimiter, skip_lines, columns,
    sample_rate_hz, comment, decimal_mark ("point" or "comma"), date_column, skip_bad_rows; the
    log's shape as ``read_log`` describes it: ``columns`` is a list of str or one str of
    comma-separated names) and runs (a runs file, run,position,input_rate_dph[,role], describing exactly the logs given, or the runs given as arrays in a dict {name: run}, named by their keys; as fit --runs, val runs are left out and each run's input rate is subtracted from its gyro; without it, a fogtemp simulation's manifest.json beside the logs gives the same, with a warning saying so; ``Model.fit_report["run_metadata"]`` says which was used, None for neither). Identifiability warnings (too few runs, heating only,
    ...) are issued as Python warnings and listed in ``Model.fit_report["warnings"]`` (a property);
    without run metadata (no runs file or manifest) the warning ``no_run_metadata`` says that
    the rate each run's gyro sensed (the Earth rate's share) stays in the model's bias: give
    runs=, or for arrays subtract each run's input rate from ``gyro_dph`` first.
    ``report`` (a folder) writes fit-report.md, fit-report.html and the figures, as fit --report.
    ``progress`` shows reading and cross-validation progress on stderr.
    """

@overload
def read_log(
    path: _PathLike,
    *,
    model: Optional[Union[Model, _PathLike]] = None,
    as_dataframe: Literal[False] = False,
    progress: bool = True,
    **options: Any,
) -> Dict[str, Any]:
    """A CSV log as numpy arrays: time_s (s since the first row), temp_c (deg C, NaN without a
    reading), gyro_dph (deg/h); ``temp_c_0``, ``gyro_dph_0``, ... for several columns; and
    ``time_origin_s`` (a float): the first row's time in the log's own clock, seconds (an epoch
    stamp in s, ms, us, ns, min or h as seconds; seconds since 1970 UTC for time_unit="datetime", since
    midnight for "time_of_day"; 0 when timed by sample_rate_hz), so ``time_origin_s + time_s``
    is each row's own stamp, as ``fogtemp-cal compensate`` writes it. One entry per sample: a
    row with a temperature and no gyro reading (channels logged on separate rows) gives its
    reading to the next sample, with a warning that counts such rows.
    Keywords: the log-column options of ``fit``. The log's shape: ``skip_lines`` (int: lines
    dropped before the header or the data), ``delimiter`` ("auto", "comma", "semicolon", "tab",
    "whitespace" or one character), ``comment`` (a line prefix, "" for none) and ``columns``
    (a headerless log's column names in order: a list of str, or one str of comma-separated
    names as on the command line, "time_s,temp_c,gyro_dph"; "" or [] for a header row).
    ``model=``: read the log as the model's fit read its logs (columns, units, time and, for a
    model that records it, format 7, the shape: skip_lines, delimiter, comment, columns), as
    ``validate`` does, ready for ``Model.compensate``.
    ``keep_impossible_temperatures=True`` reads a log as ``fogtemp-cal compensate`` does: a
    temperature no sensor reads (below absolute zero, a logger's -999) is kept as read and a
    ``NaN`` or ``inf`` temperature cell is read as ``inf``, instead of refusing the row (or
    skipping it with ``skip_bad_rows``); ``Model.compensate`` flags those samples BAD_INPUT and
    keeps them, so its output is the command's row for row. (An empty cell stays NaN: no
    reading.)"""
@overload
def read_log(
    path: _PathLike,
    *,
    model: Optional[Union[Model, _PathLike]] = None,
    as_dataframe: Literal[True],
    progress: bool = True,
    **options: Any,
) -> Any:
    """``read_log`` as a pandas DataFrame of the arrays, with ``df.attrs["time_origin_s"]``."""
def validate(
    model: Union[Model, _PathLike],
    logs: Union[_PathLike, _Run, Sequence[Union[_PathLike, _Run]]],
    *,
    progress: bool = True,
    **options: Any,
) -> Dict[str, Any]:
    """The ``fogtemp-cal validate --json`` document: raw vs compensated bias stability.
    ``logs``: paths or folders, or runs given as arrays (dicts or DataFrames with time_s, temp_c,
    gyro_dph, as ``fit`` takes them; named ``runs[i]`` in the document): each is replayed
    through the firmware's Compensator with the row rules a log file holding the same samples
    gets. Options: tau_s, overlapping, detrend, exclude_first_s, capacity, compare, log-column options,
    runs (a runs file, run,position,input_rate_dph[,role], describing every log: as validate --runs,
    when it gives roles only the runs with role "val" are validated; for a model of one axis each
    run's input rate is subtracted from its means, ``runs[].input_rate_dph``; positions are not
    used; log files, or runs given as arrays in a dict named by their keys; without it, a fogtemp simulation's manifest.json beside the logs gives
    the same, with a warning saying so) and report (a folder: as validate --report, report.md, report.html and the SVG
    figures, with the table of the ``compare`` models).
    Gaps in a log's time stamps longer than the model's max gap raise a FogtempWarning (a UserWarning)
    (``runs[].time_gaps``; the metric's windows they cut: ``runs[].metric_windows``).
    ``white_noise_floor`` (overall, per axis and per run; None when unknown): the compensated
    output's Allan deviation at its shortest averaging time, extrapolated as white noise to the
    data a window mean averages (``from_tau_s``, ``adev_dph``, ``averaged_s``, ``floor_dph``):
    a lower bound on the noise floor (flicker and random walk come on top).
    ``runs[].raw_mean_dph`` and ``runs[].compensated_mean_dph``: each run's mean output over the
    metric's span less its input rate from ``runs`` (None when the span is empty): the bias the
    model leaves, which bias stability does not see.
    Log files are read with the gyro and temperature columns the model records (models fitted
    on files since blob format 4) unless gyro_column= / temp_column= name others, and in the
    units its fit read them in unless gyro_unit=, gyro_scale=, temp_scale= or temp_offset= are
    given, and with the time the model records (since blob format 5: time column and unit, or
    sample rate) for each of time_column=, time_unit=, sample_rate_hz=, date_column= not given; a
    gyro column the model fitted on another axis raises ValueError, a name, unit or time it does
    not record a FogtempWarning. A model that records its logs' shape (format 7) also gives the
    shape keywords not named (skip_lines, delimiter, comment, columns: a list of str or one str of
    comma-separated names; "" for a header row). How the logs were read (the gyro and
    temperature units and the time as the model records them, the shape) is also said first in
    the document's ``notes``, as ``validate --json`` says it."""

def allan(log: Union[_PathLike, _Run], *, progress: bool = True, **options: Any) -> Dict[str, Any]:
    """The ``fogtemp-cal allan --json`` document: overlapping Allan deviation, N, B, K, and the
    bound on B (``bias_instability_at_most_dph``: the curve's minimum over 0.664)."""

def simulate(
    scenario: str = "paper",
    *,
    out: _PathLike,
    rate: Optional[float] = None,
    seed: Optional[int] = None,
    duration_s: Optional[float] = None,
    progress: bool = True,
) -> Dict[str, Any]:
    """The ``fogtemp-cal simulate --json`` document, after writing the logs into ``out``."""

def diagnose(
    simulated: Union[_PathLike, Mapping[str, _Run]],
    recorded: Union[_PathLike, Mapping[str, _Run]],
    runs: Optional[_PathLike] = None,
    *,
    progress: bool = True,
    **options: Any,
) -> Dict[str, Any]:
    """The ``fogtemp-cal diagnose --json`` document: simulated vs recorded logs paired by file name.
    Either side may instead be a dict of runs given as arrays keyed by run name (each a dict or
    DataFrame with time_s, temp_c, gyro_dph, as ``fit`` takes them): a run keyed ``a`` pairs with a
    log ``a.csv``, a runs file's row ``a`` describes it, and the document names it ``a.csv``; the
    samples get the row rules a log holding them gets. Without ``runs`` and a simulation folder's
    manifest.json, the runs' positions and input rates are unknown.
    Options: mean_window_s, bin_s, rate_window_s, window_coverage, block_coverage, log-column options
    (for recorded log files; skip_bad_rows for recorded arrays too) and report (a folder: as diagnose --report, report.md, report.html and
    the SVG figures, and when ``simulated`` holds its scenario.toml, scenario-updated.toml with the
    effects found; the document's ``updated_scenario`` names it, ``scenario_changes`` lists them)."""
