//! Python values in and out: arrays through numpy, documents through JSON.

use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde::Serialize;

use crate::errors;

/// `value` as a C-contiguous float64 numpy array (a copy only when it is not one already):
/// lists, scalars, pandas Series, arrays of any numeric dtype. `None` inside a list is a
/// missing value (NaN), as pandas reads an empty cell.
///
/// # Errors
/// `TypeError` naming `what` for `None` itself, text (`"20"`, an array of strings),
/// booleans and complex numbers, which numpy would turn into NaN, 20.0, 1.0 and their real
/// part without a word (complex: a `ComplexWarning` at most);
/// `ValueError` naming `what` when numpy cannot convert it.
pub fn f64_array<'py>(value: &Bound<'py, PyAny>, what: &str) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let py = value.py();
    if value.is_none() {
        return Err(errors::type_(format!("{what} must be numbers, got None")));
    }
    let numpy = py.import("numpy")?;
    let as_is = numpy
        .call_method1("asarray", (value,))
        .map_err(|e| errors::value(format!("{what} must be numbers convertible to float64 ({e})")))?;
    let kind: String = as_is.getattr("dtype")?.getattr("kind")?.extract()?;
    if let Some(found) = refused_kind(&kind) {
        return Err(errors::type_(format!("{what} must be numbers, got {found}")));
    }
    if kind == "O" {
        refuse_objects_that_are_not_numbers(&as_is, what)?;
    }
    if matches!(kind.as_str(), "f" | "i" | "u") {
        refuse_booleans_in_sequences(value, what, &mut 0)?;
    }
    let kwargs = PyDict::new(py);
    kwargs.set_item("dtype", numpy.getattr("float64")?)?;
    kwargs.set_item("order", "C")?;
    let array = numpy
        .call_method("asarray", (as_is,), Some(&kwargs))
        .map_err(|e| errors::value(format!("{what} must be numbers convertible to float64 ({e})")))?;
    Ok(array.cast_into::<PyArrayDyn<f64>>()?.readonly())
}

/// What a numpy dtype kind holds when it is not numbers: text and booleans convert to float64
/// silently (`"20"` to 20.0, `True` to 1.0), and date-times to ticks of their unit (taken as
/// seconds), so they are refused rather than read.
fn refused_kind(kind: &str) -> Option<&'static str> {
    match kind {
        "U" | "S" | "T" => Some("text (convert it with float() or pandas.to_numeric first)"),
        "b" => Some("booleans"),
        // numpy drops the imaginary part with no more than a ComplexWarning (review17 F4).
        "c" => Some("complex numbers (give the real part, z.real, if that is meant)"),
        "M" | "m" => Some(
            "date-times (datetime64/timedelta64); give seconds, e.g. (t - t.iloc[0]).dt.total_seconds() for a pandas column",
        ),
        _ => None,
    }
}

/// An object array (a pandas column of mixed or text values) holds numbers only: each
/// element is a real number, `None` or pandas' `NA` (missing). Text, booleans and
/// timestamps would be converted silently or with numpy's own words.
fn refuse_objects_that_are_not_numbers(array: &Bound<'_, PyAny>, what: &str) -> PyResult<()> {
    let py = array.py();
    let real = py.import("numbers")?.getattr("Real")?;
    for (index, element) in array.call_method0("ravel")?.try_iter()?.enumerate() {
        let element = element?;
        let type_name = element.get_type().name()?.to_string();
        let missing = element.is_none() || type_name == "NAType";
        let number = element.is_instance(&real)? && !type_name.starts_with("bool");
        if !(missing || number) {
            let found = match type_name.as_str() {
                "str" | "bytes" | "str_" | "bytes_" => {
                    "text (convert it with float() or pandas.to_numeric first)"
                }
                name if name.starts_with("bool") => "booleans",
                name if name.contains("Timestamp")
                    || name.contains("datetime")
                    || name.contains("Timedelta") =>
                {
                    "date-times; give seconds, e.g. (t - t.iloc[0]).dt.total_seconds() for a pandas column"
                }
                _ => "something that is not a number",
            };
            return Err(errors::type_(format!(
                "{what} must be numbers, got {found} (element {index}: {})",
                element.repr()?
            )));
        }
    }
    Ok(())
}

/// Booleans inside a list or tuple (nested ones too), which numpy turns into 1.0 and 0.0 as
/// it converts the list with the numbers beside them (review20 F10: `[20.0, True]` read as
/// `[20.0, 1.0]`), are refused as in an object array. Only Python's own containers are walked
/// (`element` counts their values in order, numpy's flat order), not the arrays inside them,
/// whose dtype tells.
fn refuse_booleans_in_sequences(value: &Bound<'_, PyAny>, what: &str, element: &mut usize) -> PyResult<()> {
    use pyo3::types::{PyBool, PyFloat, PyInt, PyList, PyTuple};
    if !(value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>()) {
        return Ok(());
    }
    for item in value.try_iter()? {
        let item = item?;
        if item.is_instance_of::<PyList>() || item.is_instance_of::<PyTuple>() {
            refuse_booleans_in_sequences(&item, what, element)?;
            continue;
        }
        // Plain numbers first: a long list is mostly floats, and a failed attribute lookup
        // costs an exception each.
        let plain = !item.is_instance_of::<PyBool>()
            && (item.is_instance_of::<PyFloat>() || item.is_instance_of::<PyInt>());
        if plain {
            *element += 1;
            continue;
        }
        // numpy's bool scalars, bool arrays and bool pandas columns carry their dtype.
        let dtype_kind = item.getattr("dtype").and_then(|d| d.getattr("kind")?.extract::<String>()).ok();
        if item.is_instance_of::<PyBool>() || dtype_kind.as_deref() == Some("b") {
            return Err(errors::type_(format!(
                "{what} must be numbers, got booleans (element {element}: {})",
                item.repr()?
            )));
        }
        *element += item.getattr("size").and_then(|n| n.extract::<usize>()).unwrap_or(1);
    }
    Ok(())
}

/// The contiguous data of an array from [`f64_array`].
pub fn slice<'a>(array: &'a PyReadonlyArrayDyn<'_, f64>, what: &str) -> PyResult<&'a [f64]> {
    array.as_slice().map_err(|e| errors::value(format!("{what}: {e}")))
}

/// A 1-D float64 array (any shape is refused except one dimension).
pub fn f64_vector<'py>(value: &Bound<'py, PyAny>, what: &str) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    let array = f64_array(value, what)?;
    if array.ndim() != 1 {
        return Err(errors::value(format!("{what} must be one-dimensional, got shape {:?}", array.shape())));
    }
    Ok(array)
}

/// A library document as Python objects with the command line's `--json` keys: through
/// JSON exactly as the command prints it (NaN and infinities become `None`).
pub fn document<'py>(py: Python<'py>, doc: &impl Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_value(doc).and_then(|v| serde_json::to_string(&v)).map_err(|e| {
        pyo3::exceptions::PyRuntimeError::new_err(format!("cannot serialise the document: {e}"))
    })?;
    py.import("json")?.call_method1("loads", (text,))
}

/// `obj[key]` for a dict, a pandas DataFrame or any mapping; `None` when the key is absent.
pub fn item<'py>(obj: &Bound<'py, PyAny>, key: &str) -> PyResult<Option<Bound<'py, PyAny>>> {
    if !obj.hasattr("__getitem__")? || !obj.hasattr("__contains__")? {
        return Ok(None);
    }
    if !obj.contains(key)? {
        return Ok(None);
    }
    Ok(Some(obj.get_item(key)?))
}

/// True for a run given as arrays: a dict, a pandas DataFrame, or any mapping with a
/// `time_s` key (paths are strings or `os.PathLike`). A dict or DataFrame without `time_s`
/// counts too, so that its missing column is named rather than it being taken for a path.
///
/// # Errors
/// `TypeError` for a tuple, a list or a numpy array (structured or not), which have no
/// column names to read (review20 F9: numpy's own errors said nothing of what a run is).
pub fn is_arrays(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    if obj.is_instance_of::<pyo3::types::PyString>() || obj.hasattr("__fspath__")? {
        return Ok(false);
    }
    refuse_runs_without_names(obj)?;
    let table = obj.is_instance_of::<PyDict>() || obj.hasattr("columns")?;
    Ok(table || item(obj, "time_s")?.is_some())
}

/// A run given as a tuple or list of arrays, or as a numpy array, is refused naming what a
/// run must be (its `in` test would compare "time_s" with the arrays themselves).
pub fn refuse_runs_without_names(obj: &Bound<'_, PyAny>) -> PyResult<()> {
    let ndarray = obj.py().import("numpy")?.getattr("ndarray")?;
    let sequence =
        obj.is_instance_of::<pyo3::types::PyTuple>() || obj.is_instance_of::<pyo3::types::PyList>();
    // A list of paths inside the list of logs is left to the paths' own error.
    let of_arrays = sequence
        && obj.try_iter()?.any(|e| {
            e.is_ok_and(|e| {
                !e.is_instance_of::<pyo3::types::PyString>() && e.hasattr("__len__").unwrap_or(false)
            })
        });
    let (found, fix) = if of_arrays {
        let kind = if obj.is_instance_of::<pyo3::types::PyTuple>() { "a tuple" } else { "a list" };
        (kind.to_string(), "name its arrays: {'time_s': t, 'temp_c': c, 'gyro_dph': g}".to_string())
    } else if obj.is_instance(&ndarray)? {
        let fields = obj.getattr("dtype")?.getattr("names")?;
        if fields.is_none() {
            ("a numpy array".to_string(), "name its columns: {'time_s': a[:, 0], ...}".to_string())
        } else {
            let names: Vec<String> =
                fields.try_iter()?.map(|n| n?.repr().map(|r| r.to_string())).collect::<PyResult<_>>()?;
            (
                format!("a numpy structured array (fields {})", names.join(", ")),
                "pandas.DataFrame(array) makes one of it (fields named time_s, temp_c and gyro_dph)"
                    .to_string(),
            )
        }
    } else {
        return Ok(());
    };
    Err(errors::type_(format!(
        "a run given as arrays must be a dict or a pandas DataFrame keyed by column name, with time_s (s), \
         temp_c (deg C) and gyro_dph (deg/h); got {found}: {fix}"
    )))
}
