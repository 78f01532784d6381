//! Polynomial bias model: least squares in the normalised inputs, with the paper's fixed
//! term set or stepwise selection (F-test to enter, t-test to remove).
//!
//! Solved by Householder QR (never the normal equations); the condition number comes
//! from the SVD of the final design matrix. Calibration points are autocorrelated (one
//! per block, targets smoothed over a window), so the tests use an effective sample size
//! `n_eff` that the caller states; with `n_eff = n` they are the textbook tests.

use fogtemp_core::{Normalisation, PolyTerm};
use nalgebra::{DMatrix, DVector};
use statrs::distribution::{ContinuousCDF, FisherSnedecor, StudentsT};

use crate::error::{CalError, FitProblem};
use crate::mesh::MeshPoint;

/// `(temp_power, rate_power)` of the paper's 11 terms (T, T^2, T^3, dT, dT^2, dT^3, T*dT,
/// T^2*dT, T*dT^2, T^3*dT, T*dT^3); the constant is always included in addition.
pub const PAPER_TERMS: [(u8, u8); 11] =
    [(1, 0), (2, 0), (3, 0), (0, 1), (0, 2), (0, 3), (1, 1), (2, 1), (1, 2), (3, 1), (1, 3)];

/// `(temp_power, rate_power)` of a cubic in temperature alone (T, T^2, T^3): the thermal
/// calibration PX4 and ArduPilot ship for their gyros, the baseline every report shows.
pub const CUBIC_T_TERMS: [(u8, u8); 3] = [(1, 0), (2, 0), (3, 0)];

/// Which terms to fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TermSelection {
    /// The paper's 11 terms plus the constant, all kept.
    Paper,
    /// A cubic in temperature alone plus the constant ([`CUBIC_T_TERMS`]), all kept.
    CubicInTemperature,
    /// Stepwise over every `T^i dT^j` with `1 <= i + j <= max_degree`.
    Stepwise {
        /// Highest total degree of a candidate term (3 or 4 are sensible).
        max_degree: u8,
        /// A term enters when its partial F-test p-value is below this.
        p_enter: f64,
        /// A term leaves when its t-test p-value is above this (must be >= `p_enter`).
        p_remove: f64,
    },
}

impl TermSelection {
    /// Stepwise up to degree 4 with p-to-enter 0.05 and p-to-remove 0.10.
    pub fn default_stepwise() -> Self {
        TermSelection::Stepwise { max_degree: 4, p_enter: 0.05, p_remove: 0.10 }
    }
}

/// One fitted term.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FittedTerm {
    /// Power of the normalised temperature.
    pub temp_power: u8,
    /// Power of the normalised rate.
    pub rate_power: u8,
    /// Coefficient, deg/h.
    pub coefficient_dph: f64,
    /// Standard error (inflated by `sqrt(n / n_eff)`), deg/h.
    pub std_error_dph: f64,
    /// Two-sided t-test p-value with `n_eff - p` degrees of freedom.
    pub p_value: f64,
}

/// A term's monomial in the normalised temperature `x` and rate `y`, as reports and
/// `inspect` write it: `x`, `x^2 y`; empty for the constant.
pub fn monomial(temp_power: u8, rate_power: u8) -> String {
    let power = |name: &str, k: u8| match k {
        0 => String::new(),
        1 => name.to_string(),
        _ => format!("{name}^{k}"),
    };
    [power("x", temp_power), power("y", rate_power)]
        .into_iter()
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

/// A fitted polynomial with its statistics.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PolyFit {
    /// Terms, constant first.
    pub terms: Vec<FittedTerm>,
    /// RMS of the least-squares residuals at the calibration points, deg/h: of the polynomial
    /// alone, in f64, before it is stored (`fit --json` `axes[].poly.residual_rms_dph`). The
    /// axis-level `axes[].residual_rms_dph` is the whole model's (a hybrid's mesh included) as
    /// the firmware evaluates it, in f32 through the core, so the two differ in the last digits
    /// for a polynomial and by the mesh's part for a hybrid.
    pub residual_rms_dph: f64,
    /// Largest absolute residual, deg/h (not serialised: the `fit --json` document has the
    /// model's own at the axis level).
    #[serde(skip)]
    pub residual_max_abs_dph: f64,
    /// 2-norm condition number of the design matrix (normalised inputs).
    pub condition_number: f64,
    /// Points used.
    pub n: usize,
    /// Effective sample size used in the tests.
    pub n_eff: f64,
    /// Stepwise log: `+T^1 dT^2 (p=...)`, `-...`.
    pub steps: Vec<String>,
}

impl PolyFit {
    /// The terms as the blob stores them (f32 coefficients).
    pub fn blob_terms(&self) -> Vec<PolyTerm> {
        self.terms
            .iter()
            .map(|t| PolyTerm {
                temp_power: t.temp_power,
                rate_power: t.rate_power,
                coefficient_dph: t.coefficient_dph as f32,
            })
            .collect()
    }

    /// Value at physical inputs (f64, for residuals and reports).
    pub fn evaluate(&self, normalisation: &Normalisation, temp_c: f64, rate_c_per_min: f64) -> f64 {
        let (x, y) = normalised_f64(normalisation, temp_c, rate_c_per_min);
        self.terms
            .iter()
            .map(|t| t.coefficient_dph * x.powi(i32::from(t.temp_power)) * y.powi(i32::from(t.rate_power)))
            .sum()
    }
}

/// Normalised inputs in f64 (the firmware does the same in f32).
pub fn normalised_f64(n: &Normalisation, temp_c: f64, rate_c_per_min: f64) -> (f64, f64) {
    (
        (temp_c - f64::from(n.temp_offset_c)) * f64::from(n.temp_scale_per_c),
        (rate_c_per_min - f64::from(n.rate_offset_c_per_min)) * f64::from(n.rate_scale_per_c_per_min),
    )
}

/// Fits the polynomial to `points`.
///
/// # Errors
/// [`CalError::NonFinite`] for a NaN point; [`CalError::Fit`] when there are fewer points
/// than terms or the design is rank deficient.
pub fn fit_poly(
    points: &[MeshPoint],
    normalisation: &Normalisation,
    selection: TermSelection,
    n_eff: f64,
) -> Result<PolyFit, CalError> {
    for (index, p) in points.iter().enumerate() {
        if !(p.temp_c.is_finite() && p.rate_c_per_min.is_finite() && p.value_dph.is_finite()) {
            return Err(CalError::NonFinite { what: "calibration point", index });
        }
    }
    let n = points.len();
    let n_eff = n_eff.clamp(1.0, n as f64);
    let xy: Vec<(f64, f64)> =
        points.iter().map(|p| normalised_f64(normalisation, p.temp_c, p.rate_c_per_min)).collect();
    let y = DVector::from_iterator(n, points.iter().map(|p| p.value_dph));
    let candidates: Vec<(u8, u8)> = match selection {
        TermSelection::Paper => PAPER_TERMS.to_vec(),
        TermSelection::CubicInTemperature => CUBIC_T_TERMS.to_vec(),
        TermSelection::Stepwise { max_degree, .. } => {
            (1..=max_degree).flat_map(|d| (0..=d).rev().map(move |i| (i, d - i))).collect()
        }
    };
    let column = |(i, j): (u8, u8)| {
        DVector::from_iterator(n, xy.iter().map(|&(x, r)| x.powi(i32::from(i)) * r.powi(i32::from(j))))
    };
    let mut chosen: Vec<(u8, u8)> = vec![(0, 0)];
    let mut steps = Vec::new();
    match selection {
        TermSelection::Paper => chosen.extend(PAPER_TERMS),
        TermSelection::CubicInTemperature => chosen.extend(CUBIC_T_TERMS),
        TermSelection::Stepwise { p_enter, p_remove, .. } => stepwise(
            &candidates,
            &column,
            &y,
            n_eff,
            p_enter,
            p_remove.max(p_enter),
            &mut chosen,
            &mut steps,
        )?,
    }
    finish(&chosen, &column, &y, n_eff, steps)
}

struct LsFit {
    coefficients: DVector<f64>,
    std_errors: Vec<f64>,
    p_values: Vec<f64>,
    residuals: DVector<f64>,
    rss: f64,
    q: DMatrix<f64>,
}

fn design(chosen: &[(u8, u8)], column: &dyn Fn((u8, u8)) -> DVector<f64>, n: usize) -> DMatrix<f64> {
    let mut h = DMatrix::zeros(n, chosen.len());
    for (k, &term) in chosen.iter().enumerate() {
        h.set_column(k, &column(term));
    }
    h
}

fn least_squares(h: DMatrix<f64>, y: &DVector<f64>, n_eff: f64) -> Result<LsFit, CalError> {
    let (n, p) = h.shape();
    if n <= p {
        return Err(CalError::Fit(FitProblem::TooFewPoints { points: n, terms: p }));
    }
    let qr = h.clone().qr();
    let (q, r) = (qr.q(), qr.r());
    if (0..p).any(|k| r[(k, k)].abs() <= 1e-12 * r[(0, 0)].abs().max(1e-300)) {
        return Err(CalError::Fit(FitProblem::RankDeficient));
    }
    let qty = q.transpose() * y;
    let coefficients = r.solve_upper_triangular(&qty).ok_or(CalError::Fit(FitProblem::Singular))?;
    let residuals = y - &h * &coefficients;
    let rss = residuals.norm_squared();
    let r_inv =
        r.solve_upper_triangular(&DMatrix::identity(p, p)).ok_or(CalError::Fit(FitProblem::Singular))?;
    // Variance with n - p dof, inflated by n / n_eff for autocorrelated residuals.
    let sigma2 = rss / (n - p) as f64 * (n as f64 / n_eff);
    let dof = (n_eff - p as f64).max(1.0);
    let t =
        StudentsT::new(0.0, 1.0, dof).map_err(|e| CalError::Fit(FitProblem::Distribution(e.to_string())))?;
    let std_errors: Vec<f64> = (0..p).map(|k| (sigma2 * r_inv.row(k).norm_squared()).sqrt()).collect();
    let p_values = (0..p)
        .map(|k| {
            let ts = coefficients[k] / std_errors[k];
            if ts.is_finite() {
                2.0 * t.sf(ts.abs())
            } else {
                0.0
            }
        })
        .collect();
    Ok(LsFit { coefficients, std_errors, p_values, residuals, rss, q })
}

#[allow(clippy::too_many_arguments)]
fn stepwise(
    candidates: &[(u8, u8)],
    column: &dyn Fn((u8, u8)) -> DVector<f64>,
    y: &DVector<f64>,
    n_eff: f64,
    p_enter: f64,
    p_remove: f64,
    chosen: &mut Vec<(u8, u8)>,
    steps: &mut Vec<String>,
) -> Result<(), CalError> {
    let n = y.len();
    // Each term can enter and leave a bounded number of times.
    for _ in 0..4 * candidates.len() + 4 {
        let fit = least_squares(design(chosen, column, n), y, n_eff)?;
        // Forward: best partial F among candidates not in the model. A further term must
        // leave residual degrees of freedom, in the data and in the effective sample size.
        let p = chosen.len();
        if p + 1 >= n || n_eff - ((p + 1) as f64) < 1.0 {
            return Ok(());
        }
        let mut best: Option<((u8, u8), f64)> = None;
        for &c in candidates.iter().filter(|c| !chosen.contains(c)) {
            let x = column(c);
            let v = &x - &fit.q * (fit.q.transpose() * &x);
            let vv = v.norm_squared();
            if vv <= 1e-12 * x.norm_squared() {
                continue; // collinear with the model
            }
            let gain = v.dot(&fit.residuals).powi(2) / vv;
            let rss_new = (fit.rss - gain).max(f64::MIN_POSITIVE);
            let dof2 = n_eff - (p + 1) as f64;
            let f_stat = gain / (rss_new / (n - p - 1) as f64) * (n_eff / n as f64);
            let dist = FisherSnedecor::new(1.0, dof2)
                .map_err(|e| CalError::Fit(FitProblem::Distribution(e.to_string())))?;
            let p_value = dist.sf(f_stat);
            if best.is_none_or(|(_, bp)| p_value < bp) {
                best = Some((c, p_value));
            }
        }
        if let Some((term, p_value)) = best.filter(|&(_, pv)| pv < p_enter) {
            chosen.push(term);
            steps.push(format!("+T^{} dT^{} (F-test p={p_value:.3e})", term.0, term.1));
            // Backward: drop the least significant term (never the constant).
            let fit = least_squares(design(chosen, column, n), y, n_eff)?;
            if let Some((k, pv)) =
                fit.p_values.iter().copied().enumerate().skip(1).max_by(|a, b| a.1.total_cmp(&b.1))
            {
                if pv > p_remove {
                    let gone = chosen.remove(k);
                    steps.push(format!("-T^{} dT^{} (t-test p={pv:.3e})", gone.0, gone.1));
                }
            }
            continue;
        }
        return Ok(());
    }
    steps.push("stopped: iteration limit".into());
    Ok(())
}

fn finish(
    chosen: &[(u8, u8)],
    column: &dyn Fn((u8, u8)) -> DVector<f64>,
    y: &DVector<f64>,
    n_eff: f64,
    steps: Vec<String>,
) -> Result<PolyFit, CalError> {
    let n = y.len();
    let h = design(chosen, column, n);
    let sv = h.clone().svd(false, false).singular_values;
    let condition_number = sv.max() / sv.min();
    let fit = least_squares(h, y, n_eff)?;
    let terms = chosen
        .iter()
        .enumerate()
        .map(|(k, &(i, j))| FittedTerm {
            temp_power: i,
            rate_power: j,
            coefficient_dph: fit.coefficients[k],
            std_error_dph: fit.std_errors[k],
            p_value: fit.p_values[k],
        })
        .collect();
    Ok(PolyFit {
        terms,
        residual_rms_dph: (fit.rss / n as f64).sqrt(),
        residual_max_abs_dph: fit.residuals.amax(),
        condition_number,
        n,
        n_eff,
        steps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const UNIT: Normalisation = Normalisation {
        temp_offset_c: 20.0,
        temp_scale_per_c: 0.02,
        rate_offset_c_per_min: 0.0,
        rate_scale_per_c_per_min: 1.0,
    };

    #[test]
    fn cubic_in_temperature_recovers_a_cubic_and_ignores_the_rate() {
        // b = 0.3 + 0.2 x - 0.1 x^2 + 0.05 x^3 in the normalised temperature x; the rate
        // varies independently and must get no term.
        let points: Vec<MeshPoint> = (0..200)
            .map(|k| {
                let temp_c = -30.0 + 0.5 * f64::from(k);
                let rate_c_per_min = (f64::from(k) * 0.7).sin();
                let (x, _) = normalised_f64(&UNIT, temp_c, rate_c_per_min);
                MeshPoint {
                    temp_c,
                    rate_c_per_min,
                    value_dph: 0.3 + 0.2 * x - 0.1 * x * x + 0.05 * x * x * x,
                }
            })
            .collect();
        let fit = fit_poly(&points, &UNIT, TermSelection::CubicInTemperature, 200.0).expect("fits");
        let got: Vec<(u8, u8, f64)> =
            fit.terms.iter().map(|t| (t.temp_power, t.rate_power, t.coefficient_dph)).collect();
        let want = [(0, 0, 0.3), (1, 0, 0.2), (2, 0, -0.1), (3, 0, 0.05)];
        assert_eq!(got.len(), want.len());
        for ((ti, tj, c), (wi, wj, w)) in got.iter().zip(want) {
            assert_eq!((*ti, *tj), (wi, wj));
            assert!((c - w).abs() < 1e-12, "T^{ti}: {c} vs {w}");
        }
        assert!(fit.residual_rms_dph < 1e-12);
    }
}
