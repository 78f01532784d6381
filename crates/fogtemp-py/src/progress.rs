//! Progress on `sys.stderr` (where a notebook shows it), as the command line shows its bars:
//! only for work that lasts more than a second, at most twice a second, cleared at the end.

use std::time::{Duration, Instant};

use pyo3::prelude::*;

/// One line of progress for one stage, rewritten in place.
pub struct Progress {
    label: String,
    enabled: bool,
    started: Instant,
    last_drawn: Option<Instant>,
}

impl Progress {
    /// A progress line for `label` (drawn only if `enabled`).
    pub fn new(label: impl Into<String>, enabled: bool) -> Self {
        Self { label: label.into(), enabled, started: Instant::now(), last_drawn: None }
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

    fn draw(&self, line: &str) {
        write_stderr(&format!("\r{line:<79}"));
    }

    /// Clears the line if anything was drawn.
    pub fn finish(&self) {
        if self.last_drawn.is_some() {
            write_stderr(&format!("\r{:<79}\r", ""));
        }
    }
}

/// Writes to Python's `sys.stderr` (errors writing progress are ignored: progress is never
/// worth failing the work for).
pub fn write_stderr(text: &str) {
    Python::attach(|py| {
        if let Ok(stderr) = py.import("sys").and_then(|sys| sys.getattr("stderr")) {
            let _ = stderr.call_method1("write", (text,));
            let _ = stderr.call_method0("flush");
        }
    });
}

/// A `warnings.warn` (e.g. skipped rows), printed like the command line's warning.
pub fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    py.import("warnings")?.call_method1("warn", (message,))?;
    Ok(())
}
