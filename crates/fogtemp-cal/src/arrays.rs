//! Calibration runs given as arrays in memory (numpy through the Python package, a
//! simulator, a lab format read by other code) instead of CSV logs.
//!
//! A run's samples go through the same row rules as ingest (time finite and strictly
//! increasing, gyro finite, temperature finite or NaN for "no reading"; bad samples stop
//! the read or, with `skip_bad_rows`, are skipped and listed) and then through exactly the
//! feature code the CSV route uses (the core's tracker via [`crate::features::AxisFeatureStream`], then
//! [`crate::features::smoothed_gyro_dph`]), so [`crate::calibrate::fit_model`] on these runs gives the same
//! model as on the same samples written as CSV (only the caller's input digest differs).
//! The arrays are in the log contract's units: seconds, deg C, deg/h; the column and unit
//! options of [`crate::ingest::LogFormat`] do not apply (only the number of gyro columns,
//! which is the number of model axes, and `skip_bad_rows`).

use std::path::Path;

use crate::calibrate::{CalibrationConfig, RunFeatures};
use crate::error::CalError;
use crate::ingest::{BadRow, BadRowKind, IngestReport, Row, MAX_REPORTED_BAD_ROWS};

/// One run as arrays of equal length.
#[derive(Clone, Copy, Debug)]
pub struct RunArrays<'a> {
    /// Stands for the run in errors and in [`RunFeatures::path`] (e.g. `runs[2]`).
    pub name: &'a Path,
    /// Sample times, seconds, strictly increasing (any origin: features use the time since
    /// the first accepted sample, as ingest does).
    pub time_s: &'a [f64],
    /// Temperatures, deg C: one array shared by every axis, or one per gyro array; NaN
    /// where a sample has no reading.
    pub temps_c: &'a [&'a [f64]],
    /// Gyro rates, deg/h, one array per model axis.
    pub gyros_dph: &'a [&'a [f64]],
}

impl RunArrays<'_> {
    /// The name of column `k` in errors: `time_s`, then `temp_c[i]`, then `gyro_dph[i]`
    /// (without the index when there is one array of that kind).
    fn column_name(&self, k: usize) -> String {
        let indexed = |base: &str, i: usize, count: usize| {
            if count == 1 {
                base.to_string()
            } else {
                format!("{base}[{i}]")
            }
        };
        let temps = self.temps_c.len();
        match k {
            0 => "time_s".to_string(),
            k if k <= temps => indexed("temp_c", k - 1, temps),
            k => indexed("gyro_dph", k - 1 - temps, self.gyros_dph.len()),
        }
    }

    /// A rejected sample: `line` is the sample's 0-based index, `column` 1-based in the
    /// order time, temperatures, gyros.
    fn bad(&self, index: usize, column: usize, value: f64, kind: BadRowKind) -> BadRow {
        BadRow {
            line: index as u64,
            column: column + 1,
            column_name: self.column_name(column),
            found: format!("{value}"),
            kind,
        }
    }

    /// Checks the shapes against `axes` gyro columns.
    fn check_shape(&self, axes: usize) -> Result<(), CalError> {
        let problem = |message: String| CalError::Csv { path: self.name.to_path_buf(), line: 0, message };
        if self.gyros_dph.len() != axes {
            return Err(problem(format!("{} gyro arrays for {axes} model axes", self.gyros_dph.len())));
        }
        if self.temps_c.is_empty() || (self.temps_c.len() != 1 && self.temps_c.len() != axes) {
            return Err(problem(format!(
                "{} temperature arrays: give one shared by all axes or one per gyro array ({axes})",
                self.temps_c.len()
            )));
        }
        let n = self.time_s.len();
        for (k, column) in self.temps_c.iter().chain(self.gyros_dph).enumerate() {
            if column.len() != n {
                return Err(problem(format!(
                    "{} has {} samples but time_s has {n}",
                    self.column_name(k + 1),
                    column.len()
                )));
            }
        }
        Ok(())
    }
}

/// Hands every accepted sample of `run` to `visit` as a [`Row`] (time relative to the
/// first accepted sample, `line` = the sample's 0-based index), applying ingest's row rules.
///
/// # Errors
/// [`CalError::Csv`] (line 0) for arrays of the wrong number or length;
/// [`CalError::BadRow`] for the first bad sample (unless `skip_bad_rows`), with the sample
/// index as its line and the array as its column.
pub fn visit_rows(
    run: &RunArrays<'_>,
    axes: usize,
    skip_bad_rows: bool,
    mut visit: impl FnMut(&Row<'_>),
) -> Result<IngestReport, CalError> {
    run.check_shape(axes)?;
    let columns = 1 + run.temps_c.len() + run.gyros_dph.len();
    let mut report = IngestReport {
        path: run.name.to_path_buf(),
        bytes: (run.time_s.len() * columns * std::mem::size_of::<f64>()) as u64,
        ..IngestReport::default()
    };
    let mut temps = vec![f64::NAN; run.temps_c.len()];
    let mut gyros = vec![f64::NAN; run.gyros_dph.len()];
    let mut previous: Option<f64> = None;
    for (index, &time) in run.time_s.iter().enumerate() {
        match check_sample(run, index, time, previous, &mut temps, &mut gyros) {
            Ok(()) => {
                if report.rows == 0 {
                    report.time_origin_s = time;
                }
                previous = Some(time);
                report.rows += 1;
                report.last_time_s = time - report.time_origin_s;
                if let Some(&t) = temps.first().filter(|t| !t.is_nan()) {
                    report.temp_ends_c.get_or_insert((t, t)).1 = t;
                }
                visit(&Row {
                    line: index as u64,
                    time_s: time - report.time_origin_s,
                    origin_s: report.time_origin_s,
                    temps_c: &temps,
                    gyros_dph: &gyros,
                });
            }
            Err(row) if skip_bad_rows => {
                report.skipped += 1;
                if report.first_skipped.len() < MAX_REPORTED_BAD_ROWS {
                    report.first_skipped.push(row);
                }
            }
            Err(row) => return Err(CalError::BadRow { path: run.name.to_path_buf(), row: Box::new(row) }),
        }
    }
    Ok(report)
}

/// Ingest's row rules for sample `index`, in ingest's order (time, gyros, temperatures);
/// fills `temps` and `gyros` when the sample is accepted.
fn check_sample(
    run: &RunArrays<'_>,
    index: usize,
    time: f64,
    previous: Option<f64>,
    temps: &mut [f64],
    gyros: &mut [f64],
) -> Result<(), BadRow> {
    if !time.is_finite() {
        return Err(run.bad(index, 0, time, BadRowKind::NonFinite));
    }
    match previous {
        Some(p) if time == p => return Err(run.bad(index, 0, time, BadRowKind::DuplicateTime)),
        Some(p) if time < p => return Err(run.bad(index, 0, time, BadRowKind::BackwardTime)),
        _ => {}
    }
    let first_gyro = 1 + run.temps_c.len();
    for (k, (slot, column)) in gyros.iter_mut().zip(run.gyros_dph).enumerate() {
        let value = column.get(index).copied().unwrap_or(f64::NAN);
        if !value.is_finite() {
            return Err(run.bad(index, first_gyro + k, value, BadRowKind::NonFinite));
        }
        if !crate::ingest::is_representable_rate(value) {
            return Err(run.bad(index, first_gyro + k, value, BadRowKind::RateBeyondRange));
        }
        *slot = value;
    }
    for (k, (slot, column)) in temps.iter_mut().zip(run.temps_c).enumerate() {
        let value = column.get(index).copied().unwrap_or(f64::NAN);
        if value.is_infinite() {
            return Err(run.bad(index, 1 + k, value, BadRowKind::NonFinite));
        }
        if !value.is_nan() && !crate::ingest::is_physical(value) {
            return Err(run.bad(index, 1 + k, value, BadRowKind::ImpossibleTemperature));
        }
        *slot = value;
    }
    Ok(())
}

/// The replay of one run given as arrays through `models` (as
/// [`crate::calibrate::replay_models`] replays a log file): the same row rules as
/// [`extract_run_arrays`], then every model's `Compensator`.
///
/// # Errors
/// As [`visit_rows`].
pub fn replay_models_arrays(
    run: &RunArrays<'_>,
    models: &[&fogtemp_core::Model<'_>],
    config: &CalibrationConfig,
    block_s: f64,
) -> Result<crate::calibrate::Replay, CalError> {
    let mut replay = crate::calibrate::replay_with(run.name, models, &config.ingest, block_s, |visit| {
        visit_rows_until_error(run, config, visit)
    })?;
    for series in replay.models.iter_mut().flatten() {
        series.gaps.in_samples = true;
    }
    Ok(replay)
}

/// Features and smoothed targets of one run given as arrays: what
/// [`crate::calibrate::extract_run`] computes from a log holding the same samples.
///
/// # Errors
/// As [`visit_rows`] (with `config.ingest.skip_bad_rows`), or bad feature settings.
pub fn extract_run_arrays(run: &RunArrays<'_>, config: &CalibrationConfig) -> Result<RunFeatures, CalError> {
    let mut features =
        crate::calibrate::extract_with(run.name, config, |visit| visit_rows_until_error(run, config, visit))?;
    features.gaps.in_samples = true;
    features.temperature_silences.iter_mut().for_each(|g| g.in_samples = true);
    Ok(features)
}

/// [`visit_rows`] for a visitor that can fail: the first error it returns is the result
/// (the remaining samples are still checked, as ingest reads a file to its end).
fn visit_rows_until_error(
    run: &RunArrays<'_>,
    config: &CalibrationConfig,
    visit: &mut dyn FnMut(&Row<'_>) -> Result<(), CalError>,
) -> Result<IngestReport, CalError> {
    let axes = config.ingest.format.gyro_columns.len();
    let mut failed = None;
    let report = visit_rows(run, axes, config.ingest.skip_bad_rows, |row| {
        if failed.is_none() {
            failed = visit(row).err();
        }
    })?;
    failed.map_or(Ok(report), Err)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::{extract_run_from, fit_model, Method};

    /// A 20-minute run at 10 Hz warming from `start_c`, bias 0.5 deg/h per deg C, a
    /// temperature reading on every third sample only.
    fn samples(start_c: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let (mut t, mut temp, mut gyro) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..12_000u32 {
            let time = 1000.0 + f64::from(k) / 10.0;
            let temp_c = start_c + 10.0 * (1.0 - (-(time - 1000.0) / 600.0).exp());
            t.push(time);
            temp.push(if k % 3 == 0 { temp_c } else { f64::NAN });
            gyro.push(0.5 * (temp_c - 20.0) + 0.01 * f64::from(k % 7));
        }
        (t, temp, gyro)
    }

    /// The same samples as a CSV log (Rust's shortest round-trip formatting, so the parser
    /// reads back the identical f64; an empty cell where the temperature is NaN).
    fn csv(t: &[f64], temp: &[f64], gyro: &[f64]) -> String {
        let mut out = String::from("time_s,temp_c,gyro_dph\n");
        for ((t, temp), gyro) in t.iter().zip(temp).zip(gyro) {
            let temp = if temp.is_nan() { String::new() } else { format!("{temp}") };
            out.push_str(&format!("{t},{temp},{gyro}\n"));
        }
        out
    }

    #[test]
    fn arrays_fit_the_same_blob_as_the_csv_route() {
        let config = CalibrationConfig { method: Method::Hybrid, ..CalibrationConfig::default() };
        let mut from_arrays = Vec::new();
        let mut from_csv = Vec::new();
        for (i, start_c) in [-10.0, 30.0].into_iter().enumerate() {
            let (t, temp, gyro) = samples(start_c);
            let name = format!("run{i}.csv");
            let run =
                RunArrays { name: Path::new(&name), time_s: &t, temps_c: &[&temp], gyros_dph: &[&gyro] };
            from_arrays.push(extract_run_arrays(&run, &config).expect("arrays read"));
            let text = csv(&t, &temp, &gyro);
            from_csv.push(extract_run_from(text.as_bytes(), Path::new(&name), &config).expect("csv read"));
        }
        for (a, c) in from_arrays.iter().zip(&from_csv) {
            assert_eq!(a.axes, c.axes);
            assert_eq!((a.ingest.rows, a.ingest.time_origin_s), (c.ingest.rows, c.ingest.time_origin_s));
        }
        let a = fit_model(&from_arrays, &config, [7; 32]).expect("fits");
        let c = fit_model(&from_csv, &config, [7; 32]).expect("fits");
        assert_eq!(a.blob, c.blob);
    }

    #[test]
    fn bad_samples_name_the_array_and_index_or_are_skipped() {
        let (t, temp, mut gyro) = samples(0.0);
        gyro[17] = f64::NAN;
        let mut t2 = t.clone();
        t2[40] = t2[39];
        let config = CalibrationConfig::default();
        let run =
            RunArrays { name: Path::new("runs[0]"), time_s: &t, temps_c: &[&temp], gyros_dph: &[&gyro] };
        match extract_run_arrays(&run, &config) {
            Err(CalError::BadRow { row, .. }) => {
                assert_eq!((row.line, row.column, row.column_name.as_str()), (17, 3, "gyro_dph"));
                assert_eq!(row.kind, BadRowKind::NonFinite);
            }
            other => panic!("expected a bad row, got {other:?}"),
        }
        let run2 = RunArrays { time_s: &t2, ..run };
        let skipping = CalibrationConfig {
            ingest: crate::ingest::IngestOptions { skip_bad_rows: true, ..Default::default() },
            ..config
        };
        let features = extract_run_arrays(&run2, &skipping).expect("skips");
        assert_eq!(features.ingest.skipped, 2);
        assert_eq!(features.ingest.rows, 12_000 - 2);
        let kinds: Vec<_> = features.ingest.first_skipped.iter().map(|b| (b.line, b.kind)).collect();
        assert_eq!(kinds, vec![(17, BadRowKind::NonFinite), (40, BadRowKind::DuplicateTime)]);
        // A temperature below absolute zero (a logger's -999) is a bad sample too.
        let mut cold = temp.clone();
        cold[5] = -999.0;
        let run3 = RunArrays { temps_c: &[&cold], ..run };
        match extract_run_arrays(&run3, &config) {
            Err(CalError::BadRow { row, .. }) => {
                assert_eq!((row.line, row.column, row.kind), (5, 2, BadRowKind::ImpossibleTemperature));
            }
            other => panic!("expected a bad row, got {other:?}"),
        }
        // A rate the compensator's f32 cannot hold (1e300 deg/h) too.
        let mut huge = gyro.clone();
        huge[9] = 1e300;
        let run4 = RunArrays { gyros_dph: &[&huge], ..run };
        match extract_run_arrays(&run4, &config) {
            Err(CalError::BadRow { row, .. }) => {
                assert_eq!((row.line, row.column, row.kind), (9, 3, BadRowKind::RateBeyondRange));
            }
            other => panic!("expected a bad row, got {other:?}"),
        }
    }

    #[test]
    fn wrong_lengths_and_counts_are_errors() {
        let (t, temp, gyro) = samples(0.0);
        let config = CalibrationConfig::default();
        let short = &gyro[..100];
        let run = RunArrays { name: Path::new("r"), time_s: &t, temps_c: &[&temp], gyros_dph: &[short] };
        let e = extract_run_arrays(&run, &config).expect_err("length");
        assert!(e.to_string().contains("gyro_dph has 100 samples but time_s has 12000"), "{e}");
        let run = RunArrays { gyros_dph: &[&gyro, &gyro], ..run };
        let e = extract_run_arrays(&run, &config).expect_err("count");
        assert!(e.to_string().contains("2 gyro arrays for 1 model axes"), "{e}");
        let run = RunArrays { gyros_dph: &[&gyro], temps_c: &[], ..run };
        assert!(extract_run_arrays(&run, &config).is_err());
    }
}
