//! Run metadata (`--runs FILE`): what each log was.
//!
//! A CSV file with the header `run,position,input_rate_dph` and an optional `role` column
//! (`cal` or `val`), one row per run (contract: `docs/architecture.md`, "Contracts"):
//! - `run`: the log's file name without `.csv`;
//! - `position`: any label; runs in one position share the Earth-rate projection;
//! - `input_rate_dph`: the true rate about the input axis (the Earth-rate projection, or a
//!   turntable's rate), deg/h;
//! - `role`: whether the run calibrates (`cal`) or validates (`val`).
//!
//! Columns may come in any order, their names in any case; further columns are ignored. Every problem is an error
//! naming the file and the line: a missing column, a bad number or role, a run listed twice,
//! a row for a run no log has, a log no row describes.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::CalError;

/// Whether a run calibrates or validates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Calibration run.
    Cal,
    /// Validation run.
    Val,
}

/// One row of a runs file.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RunMetadata {
    /// The log's file name without `.csv`.
    pub run: String,
    /// Position label.
    pub position: String,
    /// True rate about the input axis, deg/h.
    pub input_rate_dph: f64,
    /// Calibration or validation, when the file says.
    pub role: Option<Role>,
    /// 1-based line of the row in the file.
    pub line: u64,
}

/// What is wrong with a runs file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RunsProblem {
    /// The header lacks a required column.
    #[error("no column named '{column}' (the header has: {available}){}", delimiter_hint(available))]
    MissingColumn {
        /// The required column.
        column: &'static str,
        /// The header's columns.
        available: String,
    },
    /// A cell is empty, not a number, or not a role.
    #[error("column '{column}': {what} (found '{found}')")]
    BadCell {
        /// Column name.
        column: &'static str,
        /// What it must be.
        what: &'static str,
        /// The cell.
        found: String,
    },
    /// Two rows name the same run.
    #[error("run '{run}' is listed twice (first on line {first_line})")]
    Duplicate {
        /// The run.
        run: String,
        /// Line of its first row.
        first_line: u64,
    },
    /// A row names a run that none of the logs is.
    #[error("run '{run}' has no log among the {logs} given: give its log, or leave the row out (fit needs no log for a row of role val, validate none for one of role cal: each takes the runs its `role` column marks cal or val, or all of them without one)")]
    UnknownRun {
        /// The run.
        run: String,
        /// Logs given.
        logs: usize,
    },
    /// A row has more cells than the header names.
    #[error("{cells} cells where the header names {columns} (a decimal comma in a number? write 9.67, not 9,67; or quote the cell)")]
    ExtraCells {
        /// Cells in the row.
        cells: usize,
        /// Columns in the header.
        columns: usize,
    },
    /// A row has fewer cells than the header names: a required one is missing.
    #[error("{cells} cells where the header names {columns}: the row lacks '{column}'")]
    FewerCells {
        /// Cells in the row.
        cells: usize,
        /// Columns in the header.
        columns: usize,
        /// The first required column the row lacks.
        column: &'static str,
    },
    /// Two logs have the same run name (file name without `.csv`), so one row would
    /// describe both.
    #[error("the logs {} and {} share the run name '{run}': one row cannot describe both; rename one", first.display(), second.display())]
    SharedName {
        /// The run name.
        run: String,
        /// The first log with it.
        first: PathBuf,
        /// The second.
        second: PathBuf,
    },
    /// A log has no row.
    #[error("no row for the log {}{}", log.display(), hint.as_deref().unwrap_or_default())]
    MissingRun {
        /// The log.
        log: PathBuf,
        /// What the file has that looks like it (a row naming the file with its extension).
        hint: Option<String>,
    },
    /// The file has no header.
    #[error("no header row")]
    Empty,
    /// The path is a folder, not a runs file.
    #[error(
        "is a folder: give the runs file (CSV: run,position,input_rate_dph[,role]), e.g. FOLDER/runs.csv"
    )]
    Folder,
    /// Roles are given, but this row has none: `fit` and `validate` cannot tell which of
    /// them it is for.
    #[error("run '{run}' has no role while other rows give one: write cal or val")]
    MissingRole {
        /// The run.
        run: String,
    },
    /// Roles are given, but no run has role `val`: nothing to validate.
    #[error("no run has role 'val': nothing to validate")]
    NoValidationRun,
    /// Every run has role `val`: nothing to calibrate on.
    #[error("every run has role 'val': none is left to calibrate on")]
    NoCalibrationRun,
    /// The CSV itself is malformed (unequal quoting, invalid UTF-8).
    #[error("{0}")]
    Csv(String),
}

/// The records of a CSV read from [`blank_comment_lines`]'s text, those starting with `#`
/// (comments and blank lines) passed over, so the lines keep their numbers in errors.
pub fn records_without_comments<R: Read>(
    reader: &mut csv::Reader<R>,
) -> impl Iterator<Item = csv::Result<csv::StringRecord>> + '_ {
    let is_comment = |r: &csv::StringRecord| r.get(0).is_some_and(|c| c.starts_with('#'));
    reader.records().filter(move |r| r.as_ref().map_or(true, |r| !is_comment(r)))
}

/// `text` with every `#` comment line and every line of blanks made a bare `#` (its line
/// end kept, so lines keep their numbers), and a UTF-8 byte-order mark left out: for the
/// small CSV files read whole (runs files, `evaluate`'s points), whose records starting with
/// `#` are then passed over ([`records_without_comments`]). A quote in a comment no longer
/// opens a field that swallows the rows after it (review28a 3).
pub fn blank_comment_lines(text: &[u8]) -> Vec<u8> {
    let text = text.strip_prefix(b"\xef\xbb\xbf").unwrap_or(text);
    let mut out = Vec::with_capacity(text.len());
    for line in text.split_inclusive(|&b| b == b'\n') {
        let body_end = line.iter().rposition(|&b| b != b'\n' && b != b'\r').map_or(0, |i| i + 1);
        let (body, end) = line.split_at(body_end);
        let first = body.iter().find(|b| !b.is_ascii_whitespace());
        if first.is_none_or(|&b| b == b'#') && !body.is_empty() {
            out.push(b'#');
            out.extend_from_slice(end);
        } else {
            out.extend_from_slice(line);
        }
    }
    out
}

/// Why a header lacks the columns, when its one cell holds another delimiter: the runs file
/// is read comma-separated (review27a 6: `run;position;input_rate_dph` said only which
/// columns it lacked).
fn delimiter_hint(available: &str) -> &'static str {
    if available.contains(';') {
        ": the runs file is read with commas between cells, and this header has semicolons; write it with commas"
    } else if available.contains('\t') {
        ": the runs file is read with commas between cells, and this header has tabs; write it with commas"
    } else {
        ""
    }
}

/// The largest true input rate a runs file may give, deg/h: 10,000 deg/s, beyond the range
/// of any gyro (tactical MEMS reach a few thousand deg/s). A larger one is a unit slip or a
/// typo, and subtracted from the gyro it would become the model's bias (review27a 5: 1e30
/// wrote a model with a residual of 1e22 deg/h and said nothing).
pub const MAX_INPUT_RATE_DPH: f64 = 3.6e7;

/// A parsed runs file.
#[derive(Clone, Debug, PartialEq)]
pub struct RunsFile {
    /// Where it came from.
    pub path: PathBuf,
    /// Its rows, in file order.
    pub runs: Vec<RunMetadata>,
}

fn problem(path: &Path, line: u64, problem: RunsProblem) -> CalError {
    CalError::Runs { path: path.to_path_buf(), line, problem }
}

impl RunsFile {
    /// Reads and checks the runs file at `path`.
    ///
    /// # Errors
    /// [`CalError::Io`] if it cannot be opened; [`CalError::Runs`] with the line and the
    /// problem otherwise.
    pub fn read(path: &Path) -> Result<Self, CalError> {
        if path.is_dir() {
            return Err(problem(path, 0, RunsProblem::Folder));
        }
        let file =
            std::fs::File::open(path).map_err(|source| CalError::Io { path: path.to_path_buf(), source })?;
        Self::from_reader(file, path)
    }

    /// Reads and checks a runs file from any reader; `name` stands for it in errors.
    ///
    /// # Errors
    /// [`CalError::Runs`] with the line and the problem.
    pub fn from_reader<R: Read>(mut reader: R, name: &Path) -> Result<Self, CalError> {
        let mut text = Vec::new();
        reader.read_to_end(&mut text).map_err(|source| CalError::Io { path: name.to_path_buf(), source })?;
        let text = blank_comment_lines(&text);
        let mut csv = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .flexible(true)
            .has_headers(false)
            .from_reader(text.as_slice());
        // `#` lines are comments, as in the logs: read as records and passed over (the csv
        // crate's own `comment` leaves them out of the line numbers), the header the first other.
        let mut records = records_without_comments(&mut csv);
        let (header, header_line) = match records.next() {
            None => return Err(problem(name, 1, RunsProblem::Empty)),
            Some(Err(e)) => {
                let line = e.position().map_or(1, csv::Position::line);
                return Err(problem(name, line, RunsProblem::Csv(e.to_string())));
            }
            Some(Ok(h)) => {
                let line = h.position().map_or(1, csv::Position::line);
                (h, line)
            }
        };
        if header.iter().all(str::is_empty) {
            return Err(problem(name, header_line, RunsProblem::Empty));
        }
        let column = |wanted: &'static str| {
            header.iter().position(|h| h.eq_ignore_ascii_case(wanted)).ok_or_else(|| {
                let available = header.iter().collect::<Vec<_>>().join(", ");
                problem(name, header_line, RunsProblem::MissingColumn { column: wanted, available })
            })
        };
        let (run_col, position_col, rate_col) =
            (column("run")?, column("position")?, column("input_rate_dph")?);
        let role_col = header.iter().position(|h| h.eq_ignore_ascii_case("role"));
        let mut runs: Vec<RunMetadata> = Vec::new();
        let mut first_line: BTreeMap<String, u64> = BTreeMap::new();
        for record in records {
            let record = record.map_err(|e| {
                let line = e.position().map_or(0, csv::Position::line);
                problem(name, line, RunsProblem::Csv(e.to_string()))
            })?;
            let line = record.position().map_or(0, csv::Position::line);
            if record.len() > header.len() {
                return Err(problem(
                    name,
                    line,
                    RunsProblem::ExtraCells { cells: record.len(), columns: header.len() },
                ));
            }
            let required = [("run", run_col), ("position", position_col), ("input_rate_dph", rate_col)];
            if let Some(&(column, _)) = required.iter().find(|(_, i)| *i >= record.len()) {
                return Err(problem(
                    name,
                    line,
                    RunsProblem::FewerCells { cells: record.len(), columns: header.len(), column },
                ));
            }
            let cell = |i: usize| record.get(i).unwrap_or("");
            let bad = |column: &'static str, what: &'static str, found: &str| {
                problem(name, line, RunsProblem::BadCell { column, what, found: found.to_string() })
            };
            let run = cell(run_col);
            if run.is_empty() {
                return Err(bad("run", "a run name is required", run));
            }
            let position = cell(position_col);
            if position.is_empty() {
                return Err(bad("position", "a position label is required", position));
            }
            let rate_text = cell(rate_col);
            let input_rate_dph: f64 = rate_text
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| bad("input_rate_dph", "not a finite number", rate_text))?;
            if input_rate_dph.abs() > MAX_INPUT_RATE_DPH {
                let what =
                    "beyond 10,000 deg/s (3.6e7 deg/h), more than any gyro measures: the rate is in deg/h \
                            (a rate in another unit, or a typo?)";
                return Err(bad("input_rate_dph", what, rate_text));
            }
            let role = match role_col.map(cell) {
                None | Some("") => None,
                Some("cal") => Some(Role::Cal),
                Some("val") => Some(Role::Val),
                Some(other) if other.parse::<f64>().is_ok() => {
                    let what = "must be 'cal' or 'val'; a number here (input_rate_dph written with a decimal comma? \
                                write 9.67, not 9,67)";
                    return Err(bad("role", what, other));
                }
                Some(other) => return Err(bad("role", "must be 'cal' or 'val'", other)),
            };
            if let Some(&first) = first_line.get(run) {
                return Err(problem(
                    name,
                    line,
                    RunsProblem::Duplicate { run: run.to_string(), first_line: first },
                ));
            }
            first_line.insert(run.to_string(), line);
            runs.push(RunMetadata {
                run: run.to_string(),
                position: position.to_string(),
                input_rate_dph,
                role,
                line,
            });
        }
        Ok(Self { path: name.to_path_buf(), runs })
    }

    /// A row that names `log`'s run as its file name with the extension, or in another case:
    /// what to change, for the error.
    fn near_miss(&self, log: &std::path::Path, name: &str) -> Option<String> {
        let file = log.file_name()?.to_string_lossy().into_owned();
        let row = self.runs.iter().find(|r| r.run == file || r.run.eq_ignore_ascii_case(name))?;
        Some(format!(
            " (line {} names it '{}': the run column holds the log's file name without '.csv', as '{name}', case included)",
            row.line, row.run
        ))
    }

    /// What looks wrong in the positions (review11 F11; each was accepted without a word): a
    /// position whose runs give different input rates (runs in one position share one
    /// Earth-rate projection: a sign slip, or two positions under one label), and, beside
    /// positions of several runs, a position of one run (a typo in its label makes a position
    /// of its own, `dwn` beside `down`).
    pub fn position_notes(&self) -> Vec<String> {
        let mut positions: BTreeMap<&str, Vec<&RunMetadata>> = BTreeMap::new();
        for r in &self.runs {
            positions.entry(r.position.as_str()).or_default().push(r);
        }
        let file = self.path.display();
        let mut notes = Vec::new();
        for (position, rows) in &positions {
            let mut rates: Vec<(f64, Vec<u64>)> = Vec::new();
            for r in rows {
                match rates.iter_mut().find(|(rate, _)| *rate == r.input_rate_dph) {
                    Some((_, lines)) => lines.push(r.line),
                    None => rates.push((r.input_rate_dph, vec![r.line])),
                }
            }
            if rates.len() > 1 {
                let listed: Vec<String> = rates
                    .iter()
                    .map(|(rate, lines)| format!("{rate} deg/h on {}", lines_text(lines)))
                    .collect();
                notes.push(format!(
                    "{file}: position '{position}' gives its runs different input rates ({}): runs in one position \
                     share one Earth-rate projection (a sign slip, or two positions under one label?)",
                    listed.join("; ")
                ));
            }
        }
        let largest = positions.values().map(Vec::len).max().unwrap_or(0);
        if positions.len() > 1 && largest > 1 {
            for (position, rows) in positions.iter().filter(|(_, rows)| rows.len() == 1) {
                let others: Vec<String> = positions
                    .iter()
                    .filter(|(p, _)| p != &position)
                    .map(|(p, r)| format!("'{p}' {}", r.len()))
                    .collect();
                notes.push(format!(
                    "{file}: position '{position}' holds one run (line {}) while the others hold several ({}): a typo \
                     in its label? a position of one run cannot tell its offset from that run's turn-on bias",
                    rows[0].line,
                    others.join(", ")
                ));
            }
        }
        notes
    }

    /// The rows that name no log, for the error of the log `missing` without a row (a typo in
    /// one of them, `up_poweron_-2OC` for `up_poweron_-20C`, is the usual cause: review11
    /// F11), the row most like `missing` first (fewest character edits; review13 F13: they
    /// were listed in file order).
    fn rows_without_log(&self, logs: &[PathBuf], missing: &str, unused: Option<Role>) -> Option<String> {
        // Rows of the role the command does not read need no log: not candidates.
        let mut orphans: Vec<&RunMetadata> = self
            .runs
            .iter()
            .filter(|r| unused.is_none() || r.role != unused)
            .filter(|r| !logs.iter().any(|l| run_name(l) == r.run))
            .collect();
        orphans.sort_by_key(|r| (edit_distance(&r.run, missing), r.line));
        let shown: Vec<String> =
            orphans.iter().take(3).map(|r| format!("line {} '{}'", r.line, r.run)).collect();
        let more = orphans.len().saturating_sub(3);
        let more = if more > 0 { format!(" and {more} more") } else { String::new() };
        (!orphans.is_empty())
            .then(|| format!(" (rows that name no log: {}{more}; a typo in the run name?)", shown.join(", ")))
    }

    /// The row of every log, in the logs' order, checking that the file and the logs name
    /// the same runs (a log's run is its file name without `.csv`).
    ///
    /// # Errors
    /// [`CalError::Runs`]: [`RunsProblem::SharedName`] for two logs of one run name and
    /// [`RunsProblem::MissingRun`] for a log without a row (line 0),
    /// [`RunsProblem::UnknownRun`] for a row without a log (its line).
    pub fn for_logs(&self, logs: &[PathBuf]) -> Result<Vec<&RunMetadata>, CalError> {
        self.for_logs_of_a_command(logs, None)
    }

    /// [`RunsFile::for_logs`] for a command that does not read the runs of role `unused`:
    /// their rows need no log (`fit` given only the `cal` logs of a lab's runs file that
    /// also lists its `val` runs, or `validate` only the `val` logs: review13 F13; before,
    /// each had to be given every log the file lists).
    ///
    /// # Errors
    /// As [`RunsFile::for_logs`], except that a row of role `unused` without a log is no
    /// error.
    pub fn for_logs_of_a_command(
        &self,
        logs: &[PathBuf],
        unused: Option<Role>,
    ) -> Result<Vec<&RunMetadata>, CalError> {
        // With roles, a row without one is neither command's (review15 F6: fit calibrated on it
        // while validate wanted its log and then did not validate it).
        if unused.is_some() && self.runs.iter().any(|r| r.role.is_some()) {
            if let Some(blank) = self.runs.iter().find(|r| r.role.is_none()) {
                let missing = RunsProblem::MissingRole { run: blank.run.clone() };
                return Err(problem(&self.path, blank.line, missing));
            }
        }
        let by_name: BTreeMap<&str, &RunMetadata> = self.runs.iter().map(|r| (r.run.as_str(), r)).collect();
        let mut first_log: BTreeMap<String, &PathBuf> = BTreeMap::new();
        let mut out = Vec::with_capacity(logs.len());
        for log in logs {
            let name = run_name(log);
            if let Some(first) = first_log.insert(name.clone(), log) {
                let shared = RunsProblem::SharedName { run: name, first: first.clone(), second: log.clone() };
                return Err(problem(&self.path, 0, shared));
            }
            let row = by_name.get(name.as_str()).ok_or_else(|| {
                let hint = self.near_miss(log, &name).or_else(|| self.rows_without_log(logs, &name, unused));
                problem(&self.path, 0, RunsProblem::MissingRun { log: log.clone(), hint })
            })?;
            out.push(*row);
        }
        let needs_a_log = |r: &&RunMetadata| unused.is_none() || r.role != unused;
        if let Some(extra) =
            self.runs.iter().filter(needs_a_log).find(|r| !logs.iter().any(|l| run_name(l) == r.run))
        {
            let unknown = RunsProblem::UnknownRun { run: extra.run.clone(), logs: logs.len() };
            return Err(problem(&self.path, extra.line, unknown));
        }
        Ok(out)
    }
}

/// The fewest single-character insertions, deletions and substitutions that turn `a` into
/// `b` (Levenshtein), over characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut previous: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut current = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let substitution = previous[j] + usize::from(ca != *cb);
            current[j + 1] = substitution.min(previous[j + 1] + 1).min(current[j] + 1);
        }
        previous = current;
    }
    previous[b.len()]
}

/// `line 3`, `lines 3, 4`.
fn lines_text(lines: &[u64]) -> String {
    let listed: Vec<String> = lines.iter().map(u64::to_string).collect();
    match lines.len() {
        1 => format!("line {}", listed[0]),
        _ => format!("lines {}", listed.join(", ")),
    }
}

/// The run metadata of a command's logs, one row per log, and what to tell the user about it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LogsMetadata {
    /// Where the rows came from, for notes: the runs file, or the simulations' manifests.
    pub source: String,
    /// The runs file, or the first manifest: errors name it.
    pub source_path: PathBuf,
    /// One row per log, in the logs' order; `None` without a runs file or usable manifests.
    pub rows: Option<Vec<RunMetadata>>,
    /// Notes for the user: the runs file's [`RunsFile::position_notes`], that the manifests
    /// were read, or why a manifest beside the logs was not.
    pub notes: Vec<String>,
    /// Warnings for the user: logs from a simulation that did not finish
    /// ([`crate::manifest::unfinished_simulation_warnings`]).
    pub warnings: Vec<String>,
}

/// The run metadata of `logs` for a command that does not read the runs of role `unused`
/// (`fit`: `val`; `validate`: `cal`): the runs file `runs` when given, else the fogtemp
/// simulations' `manifest.json` beside the logs when they describe every one
/// ([`crate::manifest::manifest_for_logs`]; DESIGN.md §3), else none. `runs_option` is how
/// the caller names a runs file in notes (`--runs FILE`, or Python's `runs=`).
///
/// # Errors
/// The runs file cannot be read, is malformed or does not describe the logs
/// ([`RunsFile::for_logs_of_a_command`]).
pub fn logs_metadata(
    logs: &[PathBuf],
    runs: Option<&Path>,
    unused: Role,
    runs_option: &str,
) -> Result<LogsMetadata, CalError> {
    use crate::manifest::{manifest_for_logs, unfinished_simulation_warnings, ManifestForLogs};
    let warnings = unfinished_simulation_warnings(logs);
    if let Some(path) = runs {
        let file = RunsFile::read(path)?;
        let rows = file.for_logs_of_a_command(logs, Some(unused))?.into_iter().cloned().collect();
        return Ok(LogsMetadata {
            source: path.display().to_string(),
            source_path: path.to_path_buf(),
            rows: Some(rows),
            notes: file.position_notes(),
            warnings,
        });
    }
    Ok(match manifest_for_logs(logs, runs_option) {
        ManifestForLogs::Absent => LogsMetadata { warnings, ..LogsMetadata::default() },
        ManifestForLogs::NotUsed(why) => {
            LogsMetadata { notes: vec![why], warnings, ..LogsMetadata::default() }
        }
        ManifestForLogs::Runs(found) => {
            // Every manifest's path, for a program reading `run_metadata.source` (review30b F6).
            let source: Vec<String> = found.manifests.iter().map(|m| m.display().to_string()).collect();
            let source = source.join(", ");
            let mut positions: Vec<&str> = found.rows.iter().map(|r| r.position.as_str()).collect();
            positions.sort_unstable();
            positions.dedup();
            let positions = match &found.ungrouped {
                Some(run) => format!("run '{run}' has no group, so each run is a position of its own"),
                None => format!(
                    "{} position{}: {}",
                    positions.len(),
                    if positions.len() == 1 { "" } else { "s" },
                    positions.join(", ")
                ),
            };
            let note = format!(
                "each run's position and input rate from {source} ({positions}); a runs file ({runs_option}) \
                 overrides it"
            );
            LogsMetadata {
                source,
                source_path: found.manifests.first().cloned().unwrap_or_default(),
                rows: Some(found.rows),
                notes: vec![note],
                warnings,
            }
        }
    })
}

/// The logs `fit` calibrates on, each with its row: every log but those of role `val`; all
/// logs, without rows, when there is no metadata.
///
/// # Errors
/// Every run has role `val` ([`RunsProblem::NoCalibrationRun`]).
pub fn calibration_runs(logs: &[PathBuf], metadata: &LogsMetadata) -> Result<CalibrationRuns, CalError> {
    let Some(rows) = &metadata.rows else { return Ok((logs.to_vec(), None)) };
    let (kept, rows): (Vec<PathBuf>, Vec<RunMetadata>) = logs
        .iter()
        .zip(rows)
        .filter(|(_, row)| row.role != Some(Role::Val))
        .map(|(log, row)| (log.clone(), row.clone()))
        .unzip();
    if kept.is_empty() {
        return Err(problem(&metadata.source_path, 0, RunsProblem::NoCalibrationRun));
    }
    Ok((kept, Some(rows)))
}

/// The logs to calibrate on, and their rows when there is metadata.
pub type CalibrationRuns = (Vec<PathBuf>, Option<Vec<RunMetadata>>);

/// The logs `validate` validates (and Python's `validate`): when the metadata gives roles,
/// the logs of role `val`; else every log; each with its true input rate, deg/h, when there
/// is metadata.
///
/// # Errors
/// Roles are given and none is `val` ([`RunsProblem::NoValidationRun`]).
pub fn validation_runs(logs: Vec<PathBuf>, metadata: &LogsMetadata) -> Result<ValidationRuns, CalError> {
    let Some(rows) = &metadata.rows else { return Ok((logs, Vec::new())) };
    let with_roles = rows.iter().any(|r| r.role.is_some());
    let kept: Vec<(PathBuf, f64)> = logs
        .iter()
        .zip(rows)
        .filter(|(_, r)| !with_roles || r.role == Some(Role::Val))
        .map(|(l, r)| (l.clone(), r.input_rate_dph))
        .collect();
    if kept.is_empty() && with_roles {
        return Err(problem(&metadata.source_path, 0, RunsProblem::NoValidationRun));
    }
    Ok((kept.iter().map(|(l, _)| l.clone()).collect(), kept))
}

/// The logs to validate, and each kept log with its input rate, deg/h (empty without
/// metadata).
pub type ValidationRuns = (Vec<PathBuf>, Vec<(PathBuf, f64)>);

/// What `validate` says when the model's record of its fit's input rates (format version 8)
/// and the validated runs' run metadata do not match, so that the mean columns do not read as
/// a bias the model leaves (review30a F3): a model fitted without the rates holds the mean of
/// its calibration runs' rates as bias, and a model of the bias alone validated without them
/// shows each run's rate in both means. `None` when they agree. `how_to_give` says how the
/// caller gives each run's rate (`give each run's input_rate_dph with --runs FILE`).
pub fn input_rates_note(
    model_name: &str,
    model: &fogtemp_core::Model<'_>,
    runs: &[crate::calibrate::RunValidation],
    how_to_give: &str,
) -> Option<String> {
    use fogtemp_core::InputRates;
    let rates_taken_off = runs.iter().any(|r| r.input_rate_dph.is_some());
    // What a model holds when its fit kept the rates: their mean over its calibration runs,
    // 0 when they cancel (two opposite positions), so the means are off only by that mean
    // (review31a F1: the note said "off by that rate" of a two-position model that was right).
    let held = "the mean of its calibration runs' input rates as bias (the Earth rate's share in their \
                positions; about 0 when they cancel, as two opposite positions do), so each comp mean here, less \
                the run's input rate, is off by that mean";
    match (model.input_rates(), rates_taken_off) {
        (Some(InputRates::Subtracted), true) => None,
        (Some(InputRates::Subtracted), false) => (model.axis_count() == 1).then(|| {
            format!(
                "{model_name} was fitted with each calibration run's input rate taken off its gyro (it is the bias \
                 alone), and these runs have no run metadata: each run's raw mean and comp mean include the rate \
                 its gyro sensed (the Earth rate's share); {how_to_give} for the means of the bias alone"
            )
        }),
        (Some(InputRates::NotSubtracted), true) => Some(format!(
            "{model_name} was fitted with its runs' input rates left in its gyro (its logs had several gyro \
             columns): it holds {held}"
        )),
        (None, true) => Some(format!(
            "{model_name} does not record whether its fit took its runs' input rates off their gyro (fitted \
             without run metadata, or written before model format 8 recorded it); fitted without them, it holds \
             {held}"
        )),
        (_, false) => None,
    }
}

/// A folder's entry that is a log: a file named `*.csv` (any case), not a macOS AppleDouble
/// companion `._*.csv` (resource data a copy to a FAT or exFAT stick leaves beside each file:
/// binary, it stopped a whole folder, review23b F8). Everything else is named as left out.
pub fn is_log_file(path: &Path) -> bool {
    path.extension().is_some_and(|x| x.eq_ignore_ascii_case("csv"))
        && !is_apple_double(path)
        && path.is_file()
}

/// A macOS AppleDouble companion (`._name`), which [`is_log_file`] leaves out.
pub fn is_apple_double(path: &Path) -> bool {
    path.file_name().is_some_and(|n| n.to_string_lossy().starts_with("._"))
}

/// The run names of `logs` ([`run_name`]), except that logs sharing a file name (the same
/// `run.csv` in folders `day1/` and `day2/`) are named by their paths without `.csv`: each
/// log is its own run (they used to count as one run, and cross-validation was skipped
/// for "too few runs"). A runs file still refuses such logs (its rows name runs by file
/// name).
pub fn run_names(logs: &[&Path]) -> Vec<String> {
    let names: Vec<String> = logs.iter().map(|l| run_name(l)).collect();
    names
        .iter()
        .zip(logs)
        .map(|(name, log)| {
            if names.iter().filter(|n| *n == name).count() > 1 {
                let path = log.display().to_string();
                path.strip_suffix(".csv").map(str::to_string).unwrap_or(path)
            } else {
                name.clone()
            }
        })
        .collect()
}

/// A log's run name: its file name without a trailing `.csv`.
pub fn run_name(log: &Path) -> String {
    let name =
        log.file_name().map_or_else(|| log.display().to_string(), |n| n.to_string_lossy().into_owned());
    name.strip_suffix(".csv").map(str::to_string).unwrap_or(name)
}

/// Sorts logs in the order a person reads runs: by file name, signed numbers compared as
/// numbers (`..._-35C`, `-20C`, `-05C`, `+10C`, ...), then by path. `validate` lists a
/// folder's runs so (review21 F10: the testbed's runs read +10, +25, +40, +55, -05, -20, -35
/// in text order); logs named one by one keep the order given. Only for what is shown:
/// `fit`'s model does not depend on the logs' order, and `diagnose` keeps its own.
pub fn sort_for_reading(logs: &mut [PathBuf]) {
    logs.sort_by(|a, b| {
        let key = |p: &Path| {
            reading_key(&p.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned()))
        };
        compare_keys(&key(a), &key(b)).then_with(|| a.cmp(b))
    });
}

/// A part of a name for [`sort_for_reading`].
#[derive(Debug, PartialEq)]
enum NamePart {
    Number(f64),
    Text(String),
}

/// `name` as text and numbers; a `+` or `-` right before a digit and not after a letter or
/// digit is the number's sign (`pos2_-10C`: "pos", 2, "_", -10, "C").
fn reading_key(name: &str) -> Vec<NamePart> {
    let chars: Vec<char> = name.chars().collect();
    let mut parts = Vec::new();
    let mut text = String::new();
    let mut i = 0;
    while i < chars.len() {
        let after_word = i > 0 && chars[i - 1].is_alphanumeric();
        let signed = (chars[i] == '+' || chars[i] == '-')
            && !after_word
            && chars.get(i + 1).is_some_and(char::is_ascii_digit);
        if chars[i].is_ascii_digit() || signed {
            let start = i;
            i += 1;
            while i < chars.len()
                && (chars[i].is_ascii_digit()
                    || (chars[i] == '.' && chars.get(i + 1).is_some_and(char::is_ascii_digit)))
            {
                i += 1;
            }
            let number: String = chars[start..i].iter().collect();
            if !text.is_empty() {
                parts.push(NamePart::Text(std::mem::take(&mut text)));
            }
            parts.push(NamePart::Number(number.parse().unwrap_or(f64::NAN)));
        } else {
            text.push(chars[i]);
            i += 1;
        }
    }
    if !text.is_empty() {
        parts.push(NamePart::Text(text));
    }
    parts
}

/// Part by part: numbers by value, before text; text as text.
fn compare_keys(a: &[NamePart], b: &[NamePart]) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    for (x, y) in a.iter().zip(b) {
        let order = match (x, y) {
            (NamePart::Number(p), NamePart::Number(q)) => p.total_cmp(q),
            (NamePart::Number(_), NamePart::Text(_)) => Ordering::Less,
            (NamePart::Text(_), NamePart::Number(_)) => Ordering::Greater,
            (NamePart::Text(p), NamePart::Text(q)) => p.cmp(q),
        };
        if order != Ordering::Equal {
            return order;
        }
    }
    a.len().cmp(&b.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Logs sharing a file name in different folders are distinct runs, named by path;
    /// the others keep their file names.
    #[test]
    fn logs_sharing_a_file_name_get_their_paths_as_run_names() {
        let logs = [Path::new("day1/run.csv"), Path::new("day2/run.csv"), Path::new("day2/ramp.csv")];
        assert_eq!(run_names(&logs), vec!["day1/run", "day2/run", "ramp"]);
    }

    fn parse(text: &str) -> Result<RunsFile, CalError> {
        RunsFile::from_reader(text.as_bytes(), Path::new("runs.csv"))
    }

    fn runs_problem(result: Result<RunsFile, CalError>) -> (u64, RunsProblem) {
        match result {
            Err(CalError::Runs { line, problem, .. }) => (line, problem),
            other => panic!("expected a runs-file error, got {other:?}"),
        }
    }

    #[test]
    fn reads_rows_in_any_column_order_with_and_without_roles() {
        let f =
            parse("position,run,input_rate_dph,role,note\nup,a,8.95,cal,x\ndown,b,-8.95,val,\nup,c,8.95,,\n")
                .expect("valid");
        assert_eq!(f.runs.len(), 3);
        assert_eq!(f.runs[0].run, "a");
        assert_eq!(f.runs[0].position, "up");
        assert_eq!(f.runs[0].input_rate_dph, 8.95);
        assert_eq!(f.runs[0].role, Some(Role::Cal));
        assert_eq!(f.runs[1].role, Some(Role::Val));
        assert_eq!(f.runs[2].role, None);
        assert_eq!([f.runs[0].line, f.runs[1].line, f.runs[2].line], [2, 3, 4]);
        let plain = parse("run,position,input_rate_dph\nup_poweron_-35C,up,8.958929\n").expect("valid");
        assert_eq!(plain.runs[0].role, None);
    }

    #[test]
    fn a_folder_is_named_as_a_folder_not_as_a_line_of_a_file() {
        let dir = std::env::temp_dir();
        let e = RunsFile::read(&dir).expect_err("a folder");
        assert!(matches!(&e, CalError::Runs { line: 0, problem: RunsProblem::Folder, .. }), "{e:?}");
        let text = e.to_string();
        assert!(text.contains("is a folder: give the runs file") && !text.contains(":1:"), "{text}");
    }

    #[test]
    fn each_problem_names_its_line() {
        let (line, p) = runs_problem(parse("run,input_rate_dph\na,1\n"));
        assert_eq!(line, 1);
        assert!(matches!(p, RunsProblem::MissingColumn { column: "position", .. }), "{p}");
        let (line, p) = runs_problem(parse("run,position,input_rate_dph\na,up,1\nb,up,fast\n"));
        assert_eq!(line, 3);
        assert!(matches!(p, RunsProblem::BadCell { column: "input_rate_dph", .. }), "{p}");
        let (line, p) = runs_problem(parse("run,position,input_rate_dph\na,up,NaN\n"));
        assert_eq!(line, 2);
        assert!(matches!(p, RunsProblem::BadCell { column: "input_rate_dph", .. }), "{p}");
        // Review27a 5 and 6: a rate beyond any gyro's range, a short row, semicolons, comments.
        let (line, p) = runs_problem(parse("run,position,input_rate_dph\na,up,9.6\nb,up,1e30\n"));
        assert_eq!(line, 3);
        assert!(p.to_string().contains("beyond 10,000 deg/s"), "{p}");
        assert!(parse("run,position,input_rate_dph\na,up,-3.6e7\n").is_ok(), "10,000 deg/s itself is read");
        let (line, p) = runs_problem(parse("run,position,input_rate_dph\na,up\n"));
        assert_eq!(line, 2);
        assert_eq!(p, RunsProblem::FewerCells { cells: 2, columns: 3, column: "input_rate_dph" });
        let (_, p) = runs_problem(parse("run;position;input_rate_dph\na;up;1\n"));
        assert!(p.to_string().contains("this header has semicolons"), "{p}");
        let commented =
            parse("# lab runs, 2026-11\nrun,position,input_rate_dph\n# up first\na,up,1\n").expect("reads");
        assert_eq!(commented.runs.len(), 1);
        assert_eq!(commented.runs[0].line, 4);
        // Review28a 3: a quote in a comment opened a field that swallowed the rows after it;
        // a line of blanks and a byte-order mark before a comment are passed over too.
        let quoted = parse("\u{feff}# the \"cold\" runs\nrun,position,input_rate_dph\n   \na,up,1\nb,up,2\n")
            .expect("reads");
        assert_eq!(
            quoted.runs.iter().map(|r| (r.run.as_str(), r.line)).collect::<Vec<_>>(),
            [("a", 4), ("b", 5)]
        );
        let (line, p) = runs_problem(parse("run,position,input_rate_dph,role\na,up,1,calibrate\n"));
        assert_eq!(line, 2);
        assert!(matches!(p, RunsProblem::BadCell { column: "role", .. }), "{p}");
        let (line, p) = runs_problem(parse("run,position,input_rate_dph\na,up,1\nb,up,1\na,down,-1\n"));
        assert_eq!(line, 4);
        assert_eq!(p, RunsProblem::Duplicate { run: "a".into(), first_line: 2 });
        let (line, p) = runs_problem(parse("run,position,input_rate_dph\n,up,1\n"));
        assert_eq!(line, 2);
        assert!(matches!(p, RunsProblem::BadCell { column: "run", .. }), "{p}");
        let (_, p) = runs_problem(parse(""));
        assert_eq!(p, RunsProblem::Empty);
        // A decimal comma splits a number into two cells: named, not read as the role.
        let (line, p) = runs_problem(parse("run,position,input_rate_dph,role\na,up,1.5,cal\nb,up,9,67\n"));
        assert_eq!(line, 3);
        assert!(
            matches!(&p, RunsProblem::BadCell { column: "role", what, found } if what.contains("decimal comma") && found == "67"),
            "{p}"
        );
        let (line, p) = runs_problem(parse("run,position,input_rate_dph\na,up,9,67\n"));
        assert_eq!((line, p), (2, RunsProblem::ExtraCells { cells: 4, columns: 3 }));
    }

    #[test]
    fn header_names_are_read_in_any_case() {
        let f = parse("Run,POSITION,Input_Rate_dph,Role\na,up,1,val\n").expect("valid");
        assert_eq!(f.runs[0].role, Some(Role::Val), "a 'Role' column is the role, not an ignored column");
        assert_eq!(f.runs[0].input_rate_dph, 1.0);
    }

    #[test]
    fn two_logs_of_one_run_name_are_refused_and_named() {
        let f = parse("run,position,input_rate_dph\na,up,1\n").expect("valid");
        let logs = [PathBuf::from("x/a.csv"), PathBuf::from("y/a.csv")];
        let err = f.for_logs(&logs).unwrap_err();
        assert!(
            matches!(&err, CalError::Runs { line: 0, problem: RunsProblem::SharedName { run, .. }, .. } if run == "a"),
            "{err}"
        );
        let text = err.to_string();
        assert!(
            text.starts_with("runs.csv: the logs x/a.csv and y/a.csv"),
            "no line 0 in the message: {text}"
        );
    }

    #[test]
    fn positions_with_two_rates_or_one_run_beside_larger_ones_are_noted() {
        let clean =
            parse("run,position,input_rate_dph\na,up,7.2\nb,up,7.2\nc,down,-7.2\nd,down,-7.2\n").unwrap();
        assert!(clean.position_notes().is_empty());
        // One run per position (a turntable's rates) is the design, not a typo.
        let single = parse("run,position,input_rate_dph\na,p1,10\nb,p2,20\n").unwrap();
        assert!(single.position_notes().is_empty());
        let text = "run,position,input_rate_dph\na,up,7.2\nb,up,7.2\nc,down,-7.2\nd,down,7.2\ne,dwn,-7.2\n";
        let notes = parse(text).unwrap().position_notes();
        assert_eq!(notes.len(), 2, "{notes:?}");
        assert!(
            notes[0].starts_with(
                "runs.csv: position 'down' gives its runs different input rates (-7.2 deg/h on line 4; 7.2 deg/h on line 5)"
            ),
            "{notes:?}"
        );
        assert!(
            notes[1].starts_with(
                "runs.csv: position 'dwn' holds one run (line 6) while the others hold several ('down' 2, 'up' 2)"
            ),
            "{notes:?}"
        );
    }

    #[test]
    fn logs_and_rows_must_name_the_same_runs() {
        let f = parse("run,position,input_rate_dph\na,up,1\nb,down,-1\n").expect("valid");
        let logs = [PathBuf::from("dir/b.csv"), PathBuf::from("dir/a.csv")];
        let rows = f.for_logs(&logs).expect("every log has a row");
        assert_eq!(rows.iter().map(|r| r.run.as_str()).collect::<Vec<_>>(), ["b", "a"]);
        // A log without a row beside a row without a log: the row is named (a typo in it?).
        let err = f.for_logs(&[PathBuf::from("a.csv"), PathBuf::from("c.csv")]).unwrap_err();
        assert!(
            matches!(&err, CalError::Runs { problem: RunsProblem::MissingRun { log, .. }, .. } if log.ends_with("c.csv"))
        );
        assert!(
            err.to_string().ends_with(
                "no row for the log c.csv (rows that name no log: line 3 'b'; a typo in the run name?)"
            ),
            "{err}"
        );
        let all = f
            .for_logs(&[PathBuf::from("a.csv"), PathBuf::from("b.csv"), PathBuf::from("c.csv")])
            .unwrap_err();
        assert!(
            matches!(&all, CalError::Runs { problem: RunsProblem::MissingRun { hint: None, .. }, .. }),
            "every row has its log: {all}"
        );
        // A row naming the file with its extension is pointed at (review9 finding 6).
        let ext = parse("run,position,input_rate_dph\na.csv,up,1\n").expect("valid");
        let err = ext.for_logs(&[PathBuf::from("dir/a.csv")]).unwrap_err();
        assert!(
            err.to_string().ends_with(
                "no row for the log dir/a.csv (line 2 names it 'a.csv': the run column holds the log's file name without '.csv', as 'a', case included)"
            ),
            "{err}"
        );
        let err = f.for_logs(&[PathBuf::from("a.csv")]).unwrap_err();
        assert!(
            matches!(&err, CalError::Runs { line: 3, problem: RunsProblem::UnknownRun { run, logs: 1 }, .. } if run == "b"),
            "{err}"
        );
        assert!(err.to_string().starts_with("runs.csv:3: "), "{err}");
    }

    #[test]
    fn a_command_needs_no_log_for_the_rows_of_the_role_it_does_not_read() {
        let f = parse("run,position,input_rate_dph,role\nu1,up,1,cal\nu2,up,1,cal\nd1,down,-1,val\n")
            .expect("valid");
        let cal = [PathBuf::from("u1.csv"), PathBuf::from("u2.csv")];
        let rows = f.for_logs_of_a_command(&cal, Some(Role::Val)).expect("the val row needs no log for fit");
        assert_eq!(rows.iter().map(|r| r.line).collect::<Vec<_>>(), [2, 3]);
        // A cal row still needs its log for fit.
        let err = f.for_logs_of_a_command(&cal[..1], Some(Role::Val)).unwrap_err();
        assert!(
            matches!(&err, CalError::Runs { line: 3, problem: RunsProblem::UnknownRun { run, .. }, .. } if run == "u2"),
            "{err}"
        );
        let val = [PathBuf::from("d1.csv")];
        assert_eq!(f.for_logs_of_a_command(&val, Some(Role::Cal)).expect("cal rows need no log").len(), 1);
        // The plain check (diagnose) still wants every row's log.
        let err = f.for_logs(&cal).unwrap_err();
        assert!(matches!(&err, CalError::Runs { line: 4, .. }), "{err}");
        // With roles, a row without one is refused by fit and validate (not by diagnose).
        let blank =
            parse("run,position,input_rate_dph,role\nu1,up,1,cal\nx,up,1,\nd1,down,-1,val\n").expect("valid");
        let logs = [PathBuf::from("u1.csv"), PathBuf::from("x.csv"), PathBuf::from("d1.csv")];
        for unused in [Role::Val, Role::Cal] {
            let err = blank.for_logs_of_a_command(&logs, Some(unused)).unwrap_err();
            assert!(
                matches!(&err, CalError::Runs { line: 3, problem: RunsProblem::MissingRole { run }, .. } if run == "x"),
                "{err}"
            );
        }
        assert_eq!(blank.for_logs(&logs).expect("diagnose reads no role").len(), 3);
    }

    #[test]
    fn rows_without_a_log_are_listed_most_alike_first() {
        let f = parse(
            "run,position,input_rate_dph\ndown_poweron_-35C,d,1\ndown_poweron_-20C,d,1\nup_poweron_-2OC,u,1\nup_step,u,1\n",
        )
        .expect("valid");
        let err = f.for_logs(&[PathBuf::from("up_poweron_-20C.csv")]).unwrap_err();
        assert!(
            err.to_string().ends_with(
                "(rows that name no log: line 4 'up_poweron_-2OC', line 3 'down_poweron_-20C', line 2 'down_poweron_-35C' and 1 more; a typo in the run name?)"
            ),
            "{err}"
        );
    }

    #[test]
    fn edit_distance_counts_single_character_edits() {
        assert_eq!(edit_distance("", ""), 0);
        assert_eq!(edit_distance("abc", ""), 3);
        assert_eq!(edit_distance("", "ab"), 2);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("-20C", "-2OC"), 1);
        assert_eq!(edit_distance("°C", "C"), 1, "characters, not bytes");
    }

    #[test]
    fn logs_sort_for_reading_by_signed_numbers() {
        let mut logs: Vec<PathBuf> = [
            "r/up_poweron_+10C.csv",
            "r/down_poweron_-05C.csv",
            "r/down_poweron_+55C.csv",
            "r/down_poweron_+10C.csv",
            "r/down_poweron_-35C.csv",
            "r/down_triangle_+30C.csv",
            "r/pos2_5C.csv",
            "r/pos2_-10C.csv",
            "r/pos10_0C.csv",
            "r/run-2.csv",
            "r/run-10.csv",
        ]
        .iter()
        .map(PathBuf::from)
        .collect();
        sort_for_reading(&mut logs);
        let names: Vec<String> = logs.iter().map(|l| run_name(l)).collect();
        assert_eq!(
            names,
            [
                "down_poweron_-35C",
                "down_poweron_-05C",
                "down_poweron_+10C",
                "down_poweron_+55C",
                "down_triangle_+30C",
                "pos2_-10C",
                "pos2_5C",
                "pos10_0C",
                "run-2",
                "run-10",
                "up_poweron_+10C"
            ]
        );
    }
}
