//! The statistics behind `fit`'s `run_offsets` warning on a set of logs: the spread of the
//! runs' mean residuals in units of the targets' noise, and the share of the residual's
//! variance those means hold, for a polynomial (default settings) fitted on the logs.
//!
//! `cargo run --release -p fogtemp-cal --example run_offsets -- LOG...` prints one line:
//! `spread_in_noise_units share_of_variance` (the warning needs more than 20 and 0.5).

use std::path::PathBuf;

use fogtemp_cal::calibrate::{self, CalibrationConfig, Method};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let logs: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    let config = CalibrationConfig { method: Method::Poly, ..CalibrationConfig::default() };
    let runs =
        logs.iter().map(|l| calibrate::extract_run(l, &config, |_, _| {})).collect::<Result<Vec<_>, _>>()?;
    let fitted = calibrate::fit_model(&runs, &config, [0; 32])?;
    let model = fogtemp_core::Model::from_bytes(&fitted.blob).map_err(|e| format!("{e}"))?;
    let noise = fitted.axes.first().map_or(f64::NAN, |a| a.target_noise_dph);
    match fogtemp_cal::identifiability::run_offset_statistics(&runs, &model, 0, noise) {
        Some((spread, share)) => println!("{spread:.2} {share:.3}"),
        None => println!("none"),
    }
    Ok(())
}
