//! Progress on `sys.stderr` (where a notebook shows it), as the command line shows its bars:
//! only for work that lasts more than a second, at most twice a second, cleared at the end.
//!
//! Ctrl-C: the libraries' loops cannot be stopped from their progress callbacks, so an
//! interrupt is raised at the next boundary between pieces of work (a log read, a stage):
//! [`Progress::boundary`] there. A bar that draws takes the GIL and runs Python code (in a
//! notebook `sys.stderr.write` is Python), where Python runs the `SIGINT` handler; the
//! `KeyboardInterrupt` it raises there is kept for the boundary, never dropped.

use std::time::{Duration, Instant};

use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;

/// One line of progress for one stage, rewritten in place.
pub struct Progress {
    label: String,
    enabled: bool,
    started: Instant,
    last_drawn: Option<Instant>,
    /// An interrupt that arrived while drawing, raised at the next [`Progress::boundary`].
    interrupt: Option<PyErr>,
}

impl Progress {
    /// A progress line for `label` (drawn only if `enabled`).
    pub fn new(label: impl Into<String>, enabled: bool) -> Self {
        Self { label: label.into(), enabled, started: Instant::now(), last_drawn: None, interrupt: None }
    }

    /// Bytes and rows read so far (the ingest callback). Takes the GIL only when it draws.
    pub fn rows(&mut self, bytes: u64, rows: u64) {
        if self.due() {
            let seconds = self.started.elapsed().as_secs_f64();
            let line = format!(
                "{}: {:.1} MB, {} rows, {:.0} rows/s",
                self.label,
                bytes as f64 / 1e6,
                rows,
                rows as f64 / seconds.max(1e-9)
            );
            self.draw(&line);
        }
    }

    /// A count out of a total (samples simulated).
    pub fn count(&mut self, done: u64, total: u64, unit: &str) {
        if self.due() {
            let line = format!("{}: {done}/{total} {unit}", self.label);
            self.draw(&line);
        }
    }

    fn due(&mut self) -> bool {
        let now = Instant::now();
        let due = self.enabled
            && now.duration_since(self.started) >= Duration::from_secs(1)
            && self.last_drawn.is_none_or(|t| now.duration_since(t) >= Duration::from_millis(500));
        if due {
            self.last_drawn = Some(now);
        }
        due
    }

    fn draw(&mut self, line: &str) {
        let text = format!("\r{line:<79}");
        Python::attach(|py| {
            let pending = write_stderr(py, &text).and_then(|()| py.check_signals()).err();
            self.interrupt = self.interrupt.take().or(pending);
        });
    }

    /// Whether an interrupt arrived while this line was drawn (kept for [`Progress::boundary`]).
    pub fn interrupted(&self) -> bool {
        self.interrupt.is_some()
    }

    /// Clears the line if anything was drawn.
    pub fn finish(&mut self) {
        if self.last_drawn.is_some() {
            let text = format!("\r{:<79}\r", "");
            Python::attach(|py| {
                let pending = write_stderr(py, &text).err();
                self.interrupt = self.interrupt.take().or(pending);
            });
        }
    }

    /// A boundary between pieces of work (after a log, before a stage): raises the interrupt
    /// that arrived while this bar drew, else any signal pending now (`KeyboardInterrupt`
    /// after Ctrl-C).
    ///
    /// # Errors
    /// The exception of the signal handler.
    pub fn boundary(&mut self, py: Python<'_>) -> PyResult<()> {
        match self.interrupt.take() {
            Some(e) => Err(e),
            None => py.check_signals(),
        }
    }
}

/// Writes to Python's `sys.stderr`. Errors writing progress are ignored (progress is never
/// worth failing the work for), except an interrupt raised while Python ran the write,
/// which is returned to be raised at the next boundary.
fn write_stderr(py: Python<'_>, text: &str) -> PyResult<()> {
    let interrupt = |e: PyErr| if e.is_instance_of::<PyKeyboardInterrupt>(py) { Err(e) } else { Ok(()) };
    if let Ok(stderr) = py.import("sys").and_then(|sys| sys.getattr("stderr")) {
        stderr.call_method1("write", (text,)).map(drop).or_else(interrupt)?;
        stderr.call_method0("flush").map(drop).or_else(interrupt)?;
    }
    Ok(())
}

pyo3::create_exception!(
    fogtemp,
    FogtempWarning,
    pyo3::exceptions::PyUserWarning,
    "A note or warning of fogtemp's (the command line's `note:` and `warning:` lines): skipped rows, \
     gaps, units read as the model was fitted, data that cannot support what was asked. A subclass of \
     UserWarning, so `warnings.filterwarnings(\"ignore\", category=fogtemp.FogtempWarning)` silences \
     fogtemp's alone, and `\"error\"` turns them into exceptions."
);

pyo3::create_exception!(
    fogtemp,
    FogtempNote,
    FogtempWarning,
    "A note of fogtemp's that needs no action (the command line's `note:` lines): logs read as the \
     model was fitted, run metadata read from a file, gaps counted, a temperature held. A subclass of \
     FogtempWarning, so `warnings.filterwarnings(\"ignore\", category=fogtemp.FogtempNote)` silences \
     the notes and keeps the warnings."
);

/// A `warnings.warn` of category [`FogtempWarning`] (e.g. skipped rows), printed like the
/// command line's warning.
pub fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    let category = py.get_type::<FogtempWarning>();
    py.import("warnings")?.call_method1("warn", (message, category))?;
    Ok(())
}

/// A `warnings.warn` of category [`FogtempNote`]: what the command line says as a `note:`
/// (review33b F5: information and warnings could not be told apart by category).
pub fn note(py: Python<'_>, message: &str) -> PyResult<()> {
    let category = py.get_type::<FogtempNote>();
    py.import("warnings")?.call_method1("warn", (message, category))?;
    Ok(())
}
