//! Reading a diagnosis's inputs from files, shared by the command line (`diagnose`) and the
//! Python package (`fogtemp.diagnose`): logs into 1 s (`bin_s`) means with constant memory
//! per sample, simulated and recorded logs paired by file name, and run metadata (position,
//! rate on the input axis) from a runs file or from the simulation's `manifest.json`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use fogtemp_cal::arrays::{visit_rows, RunArrays};
use fogtemp_cal::calibrate::TimeGaps;
use fogtemp_cal::ingest::{read_log_with_progress, IngestOptions, Row};
use fogtemp_cal::runs::RunsFile;
use fogtemp_cal::CalError;

use crate::{DiagnoseError, RunMeta, RunSeries};

/// A log's file name (its run name), or the whole path when it has none.
#[must_use]
pub fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// Running sums of one `bin_s` bin: (bin, n, sum t, n temp, sum temp, sum gyro).
type Bin = (i64, f64, f64, f64, f64, f64);

fn flush(series: &mut RunSeries, a: &Bin) {
    if a.1 > 0.0 {
        series.time_s.push(a.2 / a.1);
        series.temp_c.push(if a.3 > 0.0 { a.4 / a.3 } else { f64::NAN });
        series.gyro_dph.push(a.5 / a.1);
    }
}

/// A log read into bin means: the series, the bad rows skipped (only with `skip_bad_rows`)
/// and the gaps in its time stamps longer than two bins (at least one bin without data).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReadSeries {
    /// The bin means.
    pub series: RunSeries,
    /// Bad rows skipped.
    pub skipped: u64,
    /// Steps between rows longer than two bins.
    pub gaps: TimeGaps,
    /// The log's note on its rows with a temperature and no gyro reading (channels logged on
    /// separate rows: each reading went with the next sample), `None` without any.
    pub temperature_only_note: Option<String>,
}

impl ReadSeries {
    /// What the user is told about the log's gaps (`None` without any): the short means
    /// whose seconds they empty are left out (a mean counts when 90 % of its seconds hold data).
    pub fn gap_note(&self, path: &Path) -> Option<String> {
        let threshold = format!("{} s", self.gaps.longer_than_s);
        self.gaps.note_against(path, &threshold, "the short means they empty are left out of the diagnosis")
    }
}

/// Rows into `bin_s` means, with the gaps between rows longer than two bins: the one binning
/// of [`read_series`] and [`series_from_arrays`].
struct Binning {
    series: RunSeries,
    acc: Bin,
    gaps: TimeGaps,
    previous_s: Option<f64>,
    bin_s: f64,
}

impl Binning {
    fn new(name: String, meta: RunMeta, bin_s: f64) -> Self {
        Self {
            series: RunSeries { name, meta, ..RunSeries::default() },
            acc: (i64::MIN, 0.0, 0.0, 0.0, 0.0, 0.0),
            gaps: TimeGaps::new(2.0 * bin_s),
            previous_s: None,
            bin_s,
        }
    }

    fn add(&mut self, row: &Row<'_>) {
        self.gaps.observe(self.previous_s, row.time_s, row.line);
        self.previous_s = Some(row.time_s);
        let bin = (row.time_s / self.bin_s).floor() as i64;
        if bin != self.acc.0 {
            flush(&mut self.series, &self.acc);
            self.acc = (bin, 0.0, 0.0, 0.0, 0.0, 0.0);
        }
        self.acc.1 += 1.0;
        self.acc.2 += row.time_s;
        let temp = row.temp_c_for_axis(0);
        if temp.is_finite() {
            self.acc.3 += 1.0;
            self.acc.4 += temp;
        }
        self.acc.5 += row.gyros_dph.first().copied().unwrap_or(f64::NAN);
    }

    fn finish(mut self, skipped: u64) -> ReadSeries {
        flush(&mut self.series, &self.acc);
        ReadSeries { series: self.series, skipped, gaps: self.gaps, temperature_only_note: None }
    }
}

/// Reads a log into `bin_s` means of time, temperature and gyro (axis 0). Bins without a
/// temperature reading keep NaN temperature. `progress(bytes, rows)` is called as the file is
/// read.
///
/// # Errors
/// [`DiagnoseError::Cal`] when the log cannot be read or parsed;
/// [`DiagnoseError::NoDataRows`] when it holds only a header.
pub fn read_series(
    path: &Path,
    ingest: &IngestOptions,
    bin_s: f64,
    meta: RunMeta,
    progress: impl FnMut(u64, u64),
) -> Result<ReadSeries, DiagnoseError> {
    let mut binning = Binning::new(file_name(path), meta, bin_s);
    let report = read_log_with_progress(
        path,
        ingest,
        |row| {
            binning.add(row);
            Ok(())
        },
        progress,
    )?;
    if report.rows == 0 {
        return Err(DiagnoseError::NoDataRows { path: path.to_path_buf() });
    }
    let mut read = binning.finish(report.skipped);
    read.temperature_only_note = report.temperature_only_note();
    Ok(read)
}

/// [`read_series`] for a run given as arrays (`fogtemp_cal::arrays`: the row rules a log
/// holding the same samples gets), named by `run.name`'s file name as a log is.
///
/// # Errors
/// [`DiagnoseError::Cal`] for arrays of the wrong shape or a bad sample (unless
/// `skip_bad_rows`); [`DiagnoseError::NoDataRows`] when no sample is accepted.
pub fn series_from_arrays(
    run: &RunArrays<'_>,
    skip_bad_rows: bool,
    bin_s: f64,
    meta: RunMeta,
) -> Result<ReadSeries, DiagnoseError> {
    let mut binning = Binning::new(file_name(run.name), meta, bin_s);
    let report = visit_rows(run, run.gyros_dph.len(), skip_bad_rows, |row| binning.add(row))?;
    if report.rows == 0 {
        return Err(DiagnoseError::NoDataRows { path: run.name.to_path_buf() });
    }
    let mut read = binning.finish(report.skipped);
    read.gaps.in_samples = true;
    Ok(read)
}

/// Run metadata from `DIR/manifest.json` (written by `simulate`), keyed by file name; empty
/// when there is no manifest.
///
/// # Errors
/// [`DiagnoseError::Cal`] ([`CalError::Io`]) when the manifest cannot be read;
/// [`DiagnoseError::ManifestJson`] when it is not valid JSON.
pub fn manifest_meta(dir: &Path) -> Result<BTreeMap<String, RunMeta>, DiagnoseError> {
    let runs = match fogtemp_cal::manifest::read_manifest(dir) {
        Ok(runs) => runs.unwrap_or_default(),
        Err(CalError::ManifestJson { path, source }) => {
            return Err(DiagnoseError::ManifestJson { path, source })
        }
        Err(e) => return Err(e.into()),
    };
    Ok(runs
        .into_iter()
        .map(|run| {
            let meta = RunMeta { group: run.group, input_rate_dph: run.input_rate_dph, power_on_at_s: None };
            (format!("{}.csv", run.name), meta)
        })
        .collect())
}

/// Run metadata from a runs file (`run,position,input_rate_dph`), keyed by file name. Every
/// simulated log must have a row and every row a log.
///
/// # Errors
/// [`DiagnoseError::Cal`] naming the file and line.
pub fn runs_file_meta(
    path: &Path,
    simulated: &[PathBuf],
) -> Result<BTreeMap<String, RunMeta>, DiagnoseError> {
    let file = RunsFile::read(path)?;
    let rows = file.for_logs(simulated)?;
    Ok(simulated
        .iter()
        .zip(rows)
        .map(|(log, row)| {
            let meta = RunMeta {
                group: Some(row.position.clone()),
                input_rate_dph: Some(row.input_rate_dph),
                power_on_at_s: None,
            };
            (file_name(log), meta)
        })
        .collect())
}

/// What looks wrong in a runs file's positions ([`RunsFile::position_notes`]: two input
/// rates under one position, a position of one run beside larger ones).
///
/// # Errors
/// [`DiagnoseError::Cal`] naming the file and line.
pub fn runs_file_notes(path: &Path) -> Result<Vec<String>, DiagnoseError> {
    Ok(RunsFile::read(path)?.position_notes())
}

/// What the user is told when nothing says what each run was (no runs file, no
/// `manifest.json` beside the simulated logs): `None` when `meta` describes some run.
#[must_use]
pub fn unknown_setup_note(meta: &BTreeMap<String, RunMeta>) -> Option<String> {
    meta.is_empty().then(|| {
        "no runs file and no manifest.json beside the simulated logs: each run's position and input rate \
         are unknown, so orientation_offset and scale_factor_temperature cannot be tested and runs from \
         several positions are treated as one; give a runs file (run,position,input_rate_dph)"
            .to_string()
    })
}

/// What is wrong with the two sides as given, before any log is listed (`None` when
/// nothing is): the same path for both (the residual would be exactly zero), or a folder that
/// holds `simulated/` and `recorded/` folders of its own (a testbed case folder: its
/// `runs.csv` was read as a log, review11 finding 9). `names` are the options or keywords
/// naming the sides, for the message.
pub fn sides_problem(simulated: &Path, recorded: &Path, names: (&str, &str)) -> Option<String> {
    let same = match (simulated.canonicalize(), recorded.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => simulated == recorded,
    };
    if same {
        return Some(format!(
            "{} and {} are the same path, {}: the simulation and the recordings must be different logs",
            names.0,
            names.1,
            simulated.display()
        ));
    }
    [simulated, recorded]
        .into_iter()
        .find(|p| p.join("simulated").is_dir() && p.join("recorded").is_dir())
        .map(|p| {
            format!(
                "{} holds the folders simulated/ and recorded/ (a case folder): give {} {} {} {}",
                p.display(),
                names.0,
                p.join("simulated").display(),
                names.1,
                p.join("recorded").display()
            )
        })
}

/// Pairs simulated and recorded logs by file name, in the order of `simulated`; every log
/// must have a partner.
///
/// # Errors
/// [`DiagnoseError::UnpairedLogs`] listing every log without one.
pub fn pair(simulated: &[PathBuf], recorded: &[PathBuf]) -> Result<Vec<(PathBuf, PathBuf)>, DiagnoseError> {
    let by_name: BTreeMap<String, &PathBuf> = recorded.iter().map(|p| (file_name(p), p)).collect();
    let mut pairs = Vec::new();
    let mut unmatched = Vec::new();
    for s in simulated {
        match by_name.get(&file_name(s)) {
            Some(r) => pairs.push((s.clone(), (*r).clone())),
            None => unmatched.push(format!("simulated {} has no recorded log of that name", file_name(s))),
        }
    }
    let sim_names: BTreeSet<String> = simulated.iter().map(|p| file_name(p)).collect();
    for r in recorded {
        if !sim_names.contains(&file_name(r)) {
            unmatched.push(format!("recorded {} has no simulated log of that name", file_name(r)));
        }
    }
    if !unmatched.is_empty() {
        return Err(DiagnoseError::UnpairedLogs { unmatched });
    }
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, text: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join(name);
        std::fs::write(&path, text).expect("write file");
        (dir, path)
    }

    fn logs(names: &[&str]) -> Vec<PathBuf> {
        names.iter().map(|n| PathBuf::from(format!("sim/{n}.csv"))).collect()
    }

    #[test]
    fn runs_file_gives_every_log_its_position_and_rate() {
        let (_dir, path) = write("runs.csv", "run,position,input_rate_dph\nb,down,-9.5\na,up,9.5\n");
        let meta = runs_file_meta(&path, &logs(&["a", "b"])).expect("valid");
        assert_eq!(meta["a.csv"].group.as_deref(), Some("up"));
        assert_eq!(meta["a.csv"].input_rate_dph, Some(9.5));
        assert_eq!(meta["b.csv"].group.as_deref(), Some("down"));
        assert_eq!(meta["b.csv"].input_rate_dph, Some(-9.5));
    }

    #[test]
    fn runs_file_errors_name_the_file_and_line() {
        let message = |text: &str, names: &[&str]| {
            let (_dir, path) = write("runs.csv", text);
            let err = runs_file_meta(&path, &logs(names)).expect_err("must fail");
            (err.to_string(), path.display().to_string())
        };
        let (m, file) = message("run,position,input_rate_dph\na,up,1\na,down,-1\n", &["a"]);
        assert!(m.starts_with(&format!("{file}:3: ")) && m.contains("listed twice"), "{m}");
        let (m, file) = message("run,position,input_rate_dph\na,up,1\nc,down,-1\n", &["a"]);
        assert!(m.starts_with(&format!("{file}:3: ")) && m.contains("'c'"), "{m}");
        let (m, file) = message("run,position,input_rate_dph\na,up,1\n", &["a", "b"]);
        assert!(m.starts_with(&format!("{file}:")) && m.contains("b.csv"), "{m}");
        let (m, file) = message("run,position\na,up\n", &["a"]);
        assert!(m.starts_with(&format!("{file}:1: ")) && m.contains("input_rate_dph"), "{m}");
    }

    #[test]
    fn pairing_lists_every_log_without_a_partner() {
        let sim = logs(&["a", "b"]);
        let rec = vec![PathBuf::from("rec/b.csv"), PathBuf::from("rec/c.csv")];
        let err = pair(&sim, &rec).expect_err("a and c unpaired");
        assert_eq!(
            err.to_string(),
            "runs are paired by file name, and 2 are not:\n  simulated a.csv has no recorded log of that \
             name\n  recorded c.csv has no simulated log of that name"
        );
        let pairs = pair(&logs(&["b"]), &rec[..1]).expect("paired");
        assert_eq!(pairs, vec![(PathBuf::from("sim/b.csv"), PathBuf::from("rec/b.csv"))]);
    }

    #[test]
    fn manifest_gives_group_and_rate_and_bad_json_names_the_file() {
        let (dir, _) = write(
            "manifest.json",
            r#"{"runs": [{"name": "r1", "group": "up", "input_rate_dph": 9.5}, {"name": "r2", "group": ""}]}"#,
        );
        let meta = manifest_meta(dir.path()).expect("valid");
        assert_eq!(meta["r1.csv"].group.as_deref(), Some("up"));
        assert_eq!(meta["r1.csv"].input_rate_dph, Some(9.5));
        assert_eq!(meta["r2.csv"], RunMeta::default());
        let (bad, path) = write("manifest.json", "{runs");
        let err = manifest_meta(bad.path()).expect_err("not JSON");
        assert_eq!(err.to_string(), format!("{}: not valid JSON", path.display()));
        let empty = tempfile::tempdir().expect("temp dir");
        assert!(manifest_meta(empty.path()).expect("no manifest").is_empty());
    }

    /// Channels on separate rows: the series of the log with each reading merged into the next
    /// sample's row (the oracle), and a note counting the temperature rows.
    #[test]
    fn temperature_rows_give_the_merged_series_and_a_note() {
        let split = "time_s,temp_c,gyro_dph\n-60.0,19,\n0.0,,1\n0.25,22,\n0.5,,3\n1.0,,5\n1.5,,7\n";
        let merged = "time_s,temp_c,gyro_dph\n0.0,19,1\n0.5,22,3\n1.0,,5\n1.5,,7\n";
        let (_a, split_path) = write("r.csv", split);
        let (_b, merged_path) = write("r.csv", merged);
        let read = |path: &Path| {
            read_series(path, &IngestOptions::default(), 1.0, RunMeta::default(), |_, _| {}).expect("valid")
        };
        let (from_split, from_merged) = (read(&split_path), read(&merged_path));
        // (Debug text: a bin without a temperature is NaN in both, which == does not equal.)
        assert_eq!(format!("{:?}", from_split.series), format!("{:?}", from_merged.series));
        assert!(from_merged.temperature_only_note.is_none());
        let note = from_split.temperature_only_note.expect("a note");
        assert!(note.contains("r.csv: 2 rows held a temperature and no gyro reading"), "{note}");
    }

    #[test]
    fn series_are_bin_means_and_a_header_alone_is_an_error() {
        let text = "time_s,temp_c,gyro_dph\n0.0,20,1\n0.5,22,3\n1.0,,5\n1.5,,7\n";
        let (_dir, path) = write("r.csv", text);
        let read =
            read_series(&path, &IngestOptions::default(), 1.0, RunMeta::default(), |_, _| {}).expect("valid");
        let series = &read.series;
        assert_eq!((read.skipped, read.gaps.count), (0, 0));
        assert!(read.gap_note(&path).is_none());
        assert_eq!(series.name, "r.csv");
        assert_eq!(series.time_s, vec![0.25, 1.25]);
        assert_eq!(series.temp_c[0], 21.0);
        assert!(series.temp_c[1].is_nan());
        assert_eq!(series.gyro_dph, vec![2.0, 6.0]);
        // Steps of 0.5 s, then 3.5 s (bins 1-3 empty; before line 4), then 1 s, then 2.5 s
        // (bin 6 empty; before line 6): two gaps longer than 2 bins, 6 s in all.
        let gappy = "time_s,temp_c,gyro_dph\n0.0,20,1\n0.5,20,1\n4.0,20,1\n5.0,20,1\n7.5,20,1\n";
        let (_dir, path) = write("g.csv", gappy);
        let read =
            read_series(&path, &IngestOptions::default(), 1.0, RunMeta::default(), |_, _| {}).expect("valid");
        let g = read.gaps;
        assert_eq!((g.count, g.total_s, g.largest_s, g.largest_before_line), (2, 6.0, 3.5, 4));
        assert_eq!(read.series.time_s, vec![0.25, 4.0, 5.0, 7.5]);
        assert_eq!(
            read.gap_note(&path).expect("a note"),
            format!(
                "{}: 2 gaps in the time stamps longer than 2 s, 6.0 s in all, the longest 3.5 s before line 4; \
                 the short means they empty are left out of the diagnosis",
                path.display()
            )
        );
        let (_dir, path) = write("h.csv", "time_s,temp_c,gyro_dph\n");
        let err = read_series(&path, &IngestOptions::default(), 1.0, RunMeta::default(), |_, _| {})
            .expect_err("header only");
        assert_eq!(err.to_string(), format!("{}: no data rows (only a header)", path.display()));
    }

    #[test]
    fn arrays_give_the_series_a_log_of_the_same_samples_gives() {
        // 10 Hz for 40 s from t = 100 s, a temperature reading on every 7th sample, a 5 s gap;
        // the log writes each value with Rust's shortest round-trip text.
        let time: Vec<f64> =
            (0..400).map(|k| 100.0 + f64::from(k) * 0.1 + if k >= 250 { 5.0 } else { 0.0 }).collect();
        let temp: Vec<f64> =
            (0..400).map(|k| if k % 7 == 0 { 20.0 + 0.013 * f64::from(k) } else { f64::NAN }).collect();
        let gyro: Vec<f64> = (0..400).map(|k| (f64::from(k) * 0.37).sin() * 0.01 + 0.5).collect();
        let mut text = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..400 {
            let t = if temp[k].is_nan() { String::new() } else { format!("{:?}", temp[k]) };
            text.push_str(&format!("{:?},{t},{:?}\n", time[k], gyro[k]));
        }
        let (_dir, path) = write("run.csv", &text);
        let meta = RunMeta { group: Some("up".into()), input_rate_dph: Some(9.5), power_on_at_s: None };
        let from_log =
            read_series(&path, &IngestOptions::default(), 1.0, meta.clone(), |_, _| {}).expect("valid");
        let name = PathBuf::from("run.csv");
        let run = RunArrays { name: &name, time_s: &time, temps_c: &[&temp], gyros_dph: &[&gyro] };
        let from_arrays = series_from_arrays(&run, false, 1.0, meta).expect("valid");
        assert_eq!(from_arrays.series, from_log.series);
        assert_eq!(
            (from_arrays.gaps.count, from_arrays.gaps.total_s),
            (from_log.gaps.count, from_log.gaps.total_s)
        );
        assert_eq!(from_arrays.gaps.count, 1);
        // The gap is named where each keeps it: a file's line, an array's sample index.
        assert!(from_log.gap_note(&path).expect("a gap").contains("before line 252;"));
        assert!(from_arrays.gap_note(&name).expect("a gap").contains("before sample 250;"));
        // A bad sample is an error naming the run and the sample, or skipped and counted.
        let mut bad = gyro.clone();
        bad[12] = f64::NAN;
        let run = RunArrays { gyros_dph: &[&bad], ..run };
        let err = series_from_arrays(&run, false, 1.0, RunMeta::default()).expect_err("NaN gyro");
        assert!(err.to_string().contains("run.csv") && err.to_string().contains("NaN or infinite"), "{err}");
        assert_eq!(series_from_arrays(&run, true, 1.0, RunMeta::default()).expect("skipped").skipped, 1);
    }
}
