//! Output helpers: atomic file writes, progress bars, log discovery.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
pub use fogtemp_cal::output::Staged;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Writes a file atomically (`fogtemp_cal::output`): a temporary file in the same folder,
/// flushed and synced, then renamed over `path`. A failure leaves no partial file behind.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut dyn Write) -> Result<()>) -> Result<()> {
    stage(path, write)?.commit()?;
    Ok(())
}

/// The first half of [`write_atomic`]: for outputs that must all be written before any
/// of them is moved into place ([`Staged::commit`]).
pub fn stage(path: &Path, write: impl FnOnce(&mut dyn Write) -> Result<()>) -> Result<Staged> {
    if let Ok(destination) = fogtemp_cal::output::destination(path) {
        note_leftover_temporaries(destination.path());
    }
    // The closure's error chain travels inside the I/O error.
    Ok(fogtemp_cal::output::stage(path, |w| {
        write(w).map_err(|e| std::io::Error::other(chain_text(&e, path)))
    })?)
}

/// Names the temporary files of `path` that an earlier run left (review24b F9).
fn note_leftover_temporaries(path: &Path) {
    let found = fogtemp_cal::output::leftover_temporaries(path);
    let Some((first, _)) = found.first() else { return };
    let bytes: u64 = found.iter().map(|(_, b)| b).sum();
    let more = if found.len() > 1 {
        format!(" and {} more, {} in all", found.len() - 1, indicatif::HumanBytes(bytes))
    } else {
        format!(", {}", indicatif::HumanBytes(bytes))
    };
    eprintln!(
        "note: {} temporary file{} of {} ({}{more}) left by a run that did not finish (killed?), or being \
         written by one still running: remove {} once no fogtemp-cal writes {}",
        found.len(),
        if found.len() == 1 { "" } else { "s" },
        path.display(),
        first.display(),
        if found.len() == 1 { "it" } else { "them" },
        path.display()
    );
}

/// Names the temporary files that an earlier run left anywhere in the folder `dir` and its
/// subfolders, once: for `simulate` and `demo`, whose outputs (GB of logs at 1 kHz) are
/// written by the library, file by file (review25b F6: a killed `simulate` left 257 MB of
/// hidden files that the next run never mentioned). Nothing is removed.
pub fn note_leftover_temporaries_in(dir: &Path) {
    let mut found: Vec<(PathBuf, u64)> = Vec::new();
    let mut folders = vec![(dir.to_path_buf(), 0)];
    while let Some((folder, depth)) = folders.pop() {
        let Ok(entries) = std::fs::read_dir(&folder) else { continue };
        for entry in entries.filter_map(std::result::Result::ok) {
            let Ok(meta) = entry.metadata() else { continue };
            if meta.is_dir() && depth < 3 {
                folders.push((entry.path(), depth + 1));
            } else if meta.is_file() && is_temporary_name(&entry.file_name().to_string_lossy()) {
                found.push((entry.path(), meta.len()));
            }
        }
    }
    found.sort();
    let Some((first, _)) = found.first() else { return };
    let bytes: u64 = found.iter().map(|(_, b)| b).sum();
    eprintln!(
        "note: {} temporary file{} ({}) in {} left by a run that did not finish (killed?), or being written by \
         one still running: remove {} once no fogtemp-cal writes there (the first: {})",
        found.len(),
        if found.len() == 1 { "" } else { "s" },
        indicatif::HumanBytes(bytes),
        dir.display(),
        if found.len() == 1 { "it" } else { "them" },
        first.display()
    );
}

/// Whether a file name is one of `fogtemp_cal::output::stage`'s temporaries:
/// `.NAME.fogtemp-XXXXXX`.
fn is_temporary_name(name: &str) -> bool {
    name.starts_with('.')
        && name
            .rsplit_once(".fogtemp-")
            .is_some_and(|(_, random)| random.len() == 6 && random.bytes().all(|b| b.is_ascii_alphanumeric()))
}

/// `e` and its causes on one line, each cause left out when the text before already holds
/// it, and without a leading `path: ` (the output error names the path): "writing x.csv:
/// x.csv: No space left on device (os error 28): No space left on device (os error 28)"
/// said the path and the OS error twice (review24b F10).
fn chain_text(e: &anyhow::Error, path: &Path) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let part = cause.to_string();
        if text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    let prefix = format!("{}: ", path.display());
    text.strip_prefix(&prefix).map_or(text.clone(), str::to_string)
}

/// Refuses to write `out` when it is one of `inputs` (the same file, however named): the
/// write would replace the input. An `out` that does not exist yet is no input.
pub fn refuse_overwriting_inputs(out: &Path, inputs: &[&Path]) -> Result<()> {
    let Ok(target) = std::fs::canonicalize(out) else { return Ok(()) };
    for input in inputs {
        if std::fs::canonicalize(input).is_ok_and(|i| i == target) {
            let alias = if *input == out { String::new() } else { format!(" (as {})", input.display()) };
            bail!(
                "{}: this is also an input{alias}; writing it would replace the input: choose another output path",
                out.display()
            );
        }
    }
    Ok(())
}

/// Checks before any long work that the file `out` can be written where it is named
/// (`fogtemp_cal::output::check_output_file`): not a folder, its folder exists and a file can
/// be made in it; a device or a pipe as it is.
pub fn check_output_file(out: &Path) -> Result<()> {
    Ok(fogtemp_cal::output::check_output_file(out)?)
}

/// Checks before any long work that `dir` can hold a report: an existing folder, or a path
/// that does not exist yet (it is created then); not a file.
pub fn check_report_folder(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        bail!(
            "{}: exists and is not a folder; --report names the folder to write the report into",
            dir.display()
        );
    }
    Ok(())
}

/// Every log named: files as given, folders expanded to their `*.csv` files sorted by name.
/// The same file named twice (directly, through a folder, or by another path) is an error:
/// its run would count twice.
pub fn expand_logs(args: &[PathBuf]) -> Result<Vec<PathBuf>> {
    expand_logs_ordered(args, false)
}

/// [`expand_logs`] with each folder's logs in reading order
/// ([`fogtemp_cal::runs::sort_for_reading`]: `-35C`, `-05C`, `+10C`), for `validate`'s list
/// of runs (review21 F10); logs named one by one keep the order given.
///
/// # Errors
/// As [`expand_logs`].
pub fn expand_logs_for_reading(args: &[PathBuf]) -> Result<Vec<PathBuf>> {
    expand_logs_ordered(args, true)
}

fn expand_logs_ordered(args: &[PathBuf], reading_order: bool) -> Result<Vec<PathBuf>> {
    let mut seen: Vec<(PathBuf, String)> = Vec::new();
    let mut logs = Vec::new();
    for arg in args {
        let mut found = expand_log_paths(arg)?;
        if reading_order && arg.is_dir() {
            fogtemp_cal::runs::sort_for_reading(&mut found);
        }
        for log in found {
            let canonical =
                std::fs::canonicalize(&log).with_context(|| format!("cannot open {}", log.display()))?;
            let origin =
                if log == *arg { format!("as {}", arg.display()) } else { format!("in {}", arg.display()) };
            if let Some((_, first)) = seen.iter().find(|(c, _)| *c == canonical) {
                // The same path given twice is said once (review13 F13: "x.csv is named twice
                // (as x.csv and as x.csv)").
                let how = if *first == origin {
                    "given twice".to_string()
                } else {
                    format!("{first} and {origin}")
                };
                bail!(
                    "{} is named twice ({how}): its run would count twice; name each log once",
                    log.display()
                );
            }
            seen.push((canonical, origin));
            logs.push(log);
        }
    }
    Ok(logs)
}

/// The note for a folder argument's entries that are not read as logs (`None` when there
/// are none): other files, sub-folders (not searched), and `*.csv` names that are not
/// files (a broken link).
fn left_out_note(folder: &Path, read: usize, left: &[PathBuf]) -> Option<String> {
    const LISTED: usize = 8;
    if left.is_empty() {
        return None;
    }
    let name = |p: &PathBuf| {
        let n = p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned());
        if p.is_dir() {
            format!("{n}/ (a folder: not searched)")
        } else if !p.exists() {
            format!("{n} (a broken link)")
        } else if fogtemp_cal::runs::is_apple_double(p) {
            format!("{n} (a macOS copy's resource file)")
        } else {
            n
        }
    };
    let mut listed: Vec<String> = left.iter().take(LISTED).map(name).collect();
    if left.len() > LISTED {
        listed.push(format!("and {} more", left.len() - LISTED));
    }
    Some(format!(
        "{}: read {read} *.csv file{}; left out: {}",
        folder.display(),
        if read == 1 { "" } else { "s" },
        listed.join(", ")
    ))
}

/// One argument's logs: a file as given, a folder's `*.csv` files sorted by name. What a
/// folder holds besides is named in a note (nothing is left out silently).
fn expand_log_paths(arg: &Path) -> Result<Vec<PathBuf>> {
    if arg.is_dir() {
        let entries: Vec<PathBuf> = std::fs::read_dir(arg)
            .with_context(|| format!("cannot list {}", arg.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        let (mut found, mut left): (Vec<PathBuf>, Vec<PathBuf>) =
            entries.into_iter().partition(|p| fogtemp_cal::runs::is_log_file(p));
        found.sort();
        left.sort();
        if found.is_empty() {
            let files: Vec<&PathBuf> = left.iter().filter(|p| p.is_file()).collect();
            let hint = match files.first().and_then(|p| p.extension()) {
                Some(ext) => format!(
                    " ({} other file{}, e.g. {}: give them as paths, e.g. {}.{})",
                    files.len(),
                    if files.len() == 1 { "" } else { "s" },
                    files[0].display(),
                    arg.join("*").display(),
                    ext.to_string_lossy()
                ),
                None => String::new(),
            };
            bail!("{}: folder holds no *.csv files{hint}", arg.display());
        }
        if let Some(note) = left_out_note(arg, found.len(), &left) {
            eprintln!("note: {note}");
        }
        Ok(found)
    } else if arg.is_file() {
        Ok(vec![arg.to_path_buf()])
    } else {
        bail!("{}: no such file or folder", arg.display());
    }
}

/// A bar for reading the file at `path` (bytes, rate, eta), labelled `label` and the file
/// name, drawn on `target` (a hidden bar draws nothing while it is styled).
fn file_progress(path: &Path, label: &str, target: ProgressDrawTarget) -> ProgressBar {
    let len = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let bar = ProgressBar::with_draw_target(Some(len), target);
    if let Ok(style) = ProgressStyle::with_template(
        "{prefix} [{bar:30}] {bytes}/{total_bytes} {binary_bytes_per_sec} eta {eta} {msg}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    let name =
        path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    bar.set_prefix(format!("{label} {name}"));
    bar
}

/// A [`file_progress`] bar that also shows rows read and rows/s, fed by the
/// `progress(bytes, rows)` callback of `fogtemp_cal::ingest::read_log_with_progress`.
/// It stays hidden for reads that finish within a second, and draws on stderr only when
/// that is a terminal.
pub struct RowProgress {
    bar: ProgressBar,
    shown: std::cell::Cell<bool>,
}

impl RowProgress {
    /// A hidden bar for the log at `path`, labelled like [`file_progress`].
    pub fn new(path: &Path, label: &str) -> Self {
        // Hidden from the start: a bar made on stderr and hidden after its styling left its
        // first frame ("0 B") on the terminal for good, warnings printed after it on its line.
        let bar = file_progress(path, label, ProgressDrawTarget::hidden());
        Self { bar, shown: std::cell::Cell::new(false) }
    }

    /// Records the bytes and rows read so far; shows the bar once a second has passed.
    pub fn update(&self, bytes: u64, rows: u64) {
        self.bar.set_position(bytes);
        let seconds = self.bar.elapsed().as_secs_f64();
        if seconds > 0.0 {
            let per_second = rows as f64 / seconds;
            self.bar.set_message(format!(
                "{} rows, {} rows/s",
                indicatif::HumanCount(rows),
                indicatif::HumanCount(per_second as u64)
            ));
        }
        if !self.shown.get() && seconds >= 1.0 {
            self.shown.set(true);
            self.bar.set_draw_target(ProgressDrawTarget::stderr());
        }
    }

    /// Removes the bar.
    pub fn finish_and_clear(&self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chain of a write error as compensate makes it (a `CalError::Io` naming the output
    /// around the OS error): the path and the OS error once each.
    #[test]
    fn a_write_error_says_the_os_error_once_without_the_path() {
        let os =
            std::io::Error::new(std::io::ErrorKind::StorageFull, "No space left on device (os error 28)");
        let io = fogtemp_cal::CalError::Io { path: "small/comp.csv".into(), source: os };
        let e = anyhow::Error::new(io);
        assert_eq!(chain_text(&e, Path::new("small/comp.csv")), "No space left on device (os error 28)");
        let other = anyhow::anyhow!("the CSV text thread stopped").context("streaming rows");
        assert_eq!(chain_text(&other, Path::new("x.csv")), "streaming rows: the CSV text thread stopped");
    }
}
