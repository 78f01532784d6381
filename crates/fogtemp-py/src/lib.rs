//! The `fogtemp` Python package: a thin PyO3 layer over `fogtemp-cal` (ingest, fit,
//! validation, the JSON documents), `fogtemp-core` (model, evaluation, the `Compensator`)
//! and `fogtemp-sim` (the simulator). Nothing is computed here that the libraries do not
//! compute for the command line: this crate converts arguments, arrays and errors.
//!
//! Errors carry the libraries' messages (the command line prints the same ones): a bad row
//! is a `ValueError` naming file, line and column; a missing file a `FileNotFoundError`.
//! Long work (ingest, fit, replay, evaluation of many points) runs with the GIL released.

mod compensate_notes;
mod convert;
mod diagnose;
mod errors;
mod functions;
mod model;
mod options;
mod progress;

use pyo3::prelude::*;

/// fogtemp: temperature-drift calibration of fibre-optic gyros (fit, evaluate, compensate,
/// validate, simulate, diagnose) from numpy arrays, pandas DataFrames and CSV logs.
#[pymodule]
#[pyo3(name = "fogtemp")]
fn fogtemp_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<model::Model>()?;
    m.add_function(wrap_pyfunction!(functions::fit, m)?)?;
    m.add_function(wrap_pyfunction!(functions::read_log, m)?)?;
    m.add_function(wrap_pyfunction!(functions::validate, m)?)?;
    m.add_function(wrap_pyfunction!(functions::allan, m)?)?;
    m.add_function(wrap_pyfunction!(functions::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose::diagnose, m)?)?;
    m.add("METHODS", functions::METHOD_NAMES.to_vec())?;
    m.add("FLAG_BITS", model::flag_bits(m.py())?)?;
    m.add("FogtempWarning", m.py().get_type::<progress::FogtempWarning>())?;
    m.add("FogtempNote", m.py().get_type::<progress::FogtempNote>())?;
    Ok(())
}
