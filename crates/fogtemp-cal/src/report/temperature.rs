//! The fit report's model over temperature (review26b F10: a polynomial model, the default
//! choice, had no figure of what it does between and beyond the calibration temperatures):
//! the model at three of the calibration points' rates against temperature, over the
//! calibrated range and a sixth of it either side, with the calibration targets; below, each
//! point's residual (target less the model at its own temperature and rate).

use std::path::Path;

use plotters::prelude::*;

use super::{draw_legend_at, finite_range, plot_err, run_colour, tick, write_svg};
use crate::error::CalError;
use crate::features::FeaturePoint;

/// The figure's data: see the module.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TemperatureFigure {
    /// Calibration points: temperature (deg C), target and residual (deg/h), at most
    /// [`MAX_POINTS`] of them, evenly taken.
    pub points: Vec<(f64, f64, f64)>,
    /// The model's curves: label, then its points in increasing temperature.
    pub curves: Vec<(String, Vec<CurvePoint>)>,
    /// The calibrated temperature range (the model's provenance), deg C.
    pub calibrated_c: (f64, f64),
}

/// A point of a model curve: temperature (deg C), value (deg/h), and whether it lies outside
/// the calibrated region (the core's `outside_hull`, flag OUTSIDE_HULL).
pub type CurvePoint = (f64, f64, bool);

/// Points drawn at most (an SVG of every point of a long campaign would be megabytes).
pub const MAX_POINTS: usize = 4000;

/// Temperatures each curve is evaluated at.
const CURVE_STEPS: usize = 240;

/// The figure of model axis `axis`, fitted on `points` with their `targets`; `None` without
/// points or a calibrated range.
pub fn temperature_figure(
    axis: &fogtemp_core::Axis<'_>,
    points: &[&FeaturePoint],
    targets: &[f64],
) -> Option<TemperatureFigure> {
    let (t0, t1) = (f64::from(axis.provenance.temp_min_c), f64::from(axis.provenance.temp_max_c));
    if points.is_empty() || !(t0.is_finite() && t1.is_finite() && t1 > t0) {
        return None;
    }
    let mut hint = fogtemp_core::WalkHint::default();
    // The value and whether the point is outside the calibrated region (flag OUTSIDE_HULL).
    let mut evaluate = |temp_c: f64, rate: f64| {
        axis.evaluate(temp_c as f32, rate as f32, &mut hint)
            .map_or((f64::NAN, true), |e| (f64::from(e.value_dph), e.outside_hull))
    };
    let step = points.len().div_ceil(MAX_POINTS).max(1);
    let drawn = points
        .iter()
        .zip(targets)
        .step_by(step)
        .filter(|(p, target)| p.temp_c.is_finite() && target.is_finite())
        .map(|(p, &target)| (p.temp_c, target, target - evaluate(p.temp_c, p.rate_c_per_min).0))
        .collect();
    let margin = (t1 - t0) / 6.0;
    let temps: Vec<f64> = (0..=CURVE_STEPS)
        .map(|k| t0 - margin + (t1 - t0 + 2.0 * margin) * k as f64 / CURVE_STEPS as f64)
        .collect();
    let mut curve = |rate: f64| -> Vec<CurvePoint> {
        temps.iter().map(|&t| (t, evaluate(t, rate))).map(|(t, (v, outside))| (t, v, outside)).collect()
    };
    let curves = if crate::calibrate::ignores_rate(axis) {
        // At a rate inside the calibrated ones: the curve is flagged beyond the temperatures
        // alone.
        let rate = 0.5 * f64::from(axis.provenance.rate_min_c_per_min + axis.provenance.rate_max_c_per_min);
        vec![("the model (no dT/dt term)".to_string(), curve(rate))]
    } else {
        let mut rates: Vec<f64> = points.iter().map(|p| p.rate_c_per_min).filter(|r| r.is_finite()).collect();
        rates.sort_by(f64::total_cmp);
        let at = |q: f64| rates.get(((rates.len().saturating_sub(1)) as f64 * q).round() as usize).copied();
        [(0.1, "10th"), (0.5, "50th"), (0.9, "90th")]
            .into_iter()
            .filter_map(|(q, name)| at(q).map(|r| (name, r)))
            .map(|(name, r)| {
                (format!("the model at dT/dt = {r:.3} C/min (the points' {name} percentile)"), curve(r))
            })
            .collect()
    };
    Some(TemperatureFigure { points: drawn, curves, calibrated_c: (t0, t1) })
}

/// Draws `fig` (see the module).
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_model_over_temperature(
    path: &Path,
    title: &str,
    fig: &TemperatureFigure,
) -> Result<(), CalError> {
    let (c0, c1) = fig.calibrated_c;
    let x = finite_range(
        fig.points.iter().map(|p| p.0).chain(fig.curves.iter().flat_map(|(_, c)| c.iter().map(|p| p.0))),
    );
    let y = finite_range(
        fig.points.iter().map(|p| p.1).chain(fig.curves.iter().flat_map(|(_, c)| c.iter().map(|p| p.1))),
    );
    let residual_max = fig.points.iter().map(|p| p.2.abs()).filter(|v| v.is_finite()).fold(0.0f64, f64::max);
    let r = if residual_max > 0.0 { residual_max * 1.1 } else { 1.0 };
    // Few points (a bursty log's dozens) drawn large enough to see, many small.
    let dot = match fig.points.len() {
        0..300 => 3,
        300..1500 => 2,
        _ => 1,
    };
    write_svg(path, (1200, 860), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(|e| plot_err(path, e))?;
        let root = root
            .titled(
                "grey: the calibration points' smoothed gyro targets; a curve is faint where its (T, dT/dt) lies \
                 outside the calibrated region (flag OUTSIDE_HULL)",
                ("sans-serif", 14),
            )
            .map_err(|e| plot_err(path, e))?;
        let root = root
            .titled(
                "shaded: beyond the calibrated temperatures (those of full tracker windows), where the model is \
                 continued",
                ("sans-serif", 14),
            )
            .map_err(|e| plot_err(path, e))?;
        let (top, bottom) = root.split_vertically(540);
        let mut chart = ChartBuilder::on(&top)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(x.0..x.1, y.0..y.1)
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("temperature, deg C")
            .y_desc("model value and targets, deg/h")
            .y_label_formatter(&tick)
            .draw()
            .map_err(|e| plot_err(path, e))?;
        shade_beyond(&mut chart, path, x, y, (c0, c1))?;
        chart
            .draw_series(
                fig.points.iter().map(|p| Circle::new((p.0, p.1), dot, RGBColor(150, 150, 150).filled())),
            )
            .map_err(|e| plot_err(path, e))?;
        for (i, (label, curve)) in fig.curves.iter().enumerate() {
            let colour = run_colour(i);
            // Solid inside the calibrated region, faint outside it (review31b F3).
            for (outside, segment) in segments(curve) {
                let style = if outside { colour.mix(0.35).stroke_width(1) } else { colour.stroke_width(2) };
                chart.draw_series(LineSeries::new(segment, style)).map_err(|e| plot_err(path, e))?;
            }
            chart
                .draw_series(LineSeries::new(std::iter::empty::<(f64, f64)>(), colour.stroke_width(2)))
                .map_err(|e| plot_err(path, e))?
                .label(label.as_str())
                .legend(move |(px, py)| {
                    PathElement::new(vec![(px, py), (px + 20, py)], colour.stroke_width(2))
                });
        }
        // The legend where the first curve leaves room: the upper left above a rising one
        // (review31b F8: it hid the start of a falling one).
        let rising = fig.curves.first().and_then(|(_, c)| {
            let finite: Vec<f64> = c.iter().map(|p| p.1).filter(|v| v.is_finite()).collect();
            Some(finite.first()? <= finite.last()?)
        });
        let corner = if rising == Some(false) {
            SeriesLabelPosition::UpperRight
        } else {
            SeriesLabelPosition::UpperLeft
        };
        draw_legend_at(&mut chart, path, corner)?;

        let mut chart = ChartBuilder::on(&bottom)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .caption(
                "residual: target less the model at the point's temperature and rate",
                ("sans-serif", 16),
            )
            .build_cartesian_2d(x.0..x.1, -r..r)
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("temperature, deg C")
            .y_desc("residual, deg/h")
            .y_label_formatter(&tick)
            .draw()
            .map_err(|e| plot_err(path, e))?;
        shade_beyond(&mut chart, path, x, (-r, r), (c0, c1))?;
        chart
            .draw_series(std::iter::once(PathElement::new(vec![(x.0, 0.0), (x.1, 0.0)], BLACK.mix(0.5))))
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(
                fig.points.iter().map(|p| Circle::new((p.0, p.2), dot, RGBColor(110, 110, 110).filled())),
            )
            .map_err(|e| plot_err(path, e))?;
        root.present().map_err(|e| plot_err(path, e))
    })
}

/// A curve cut where its flag changes, each piece with its flag, finite values only; the
/// pieces share their end points, so the line is unbroken.
fn segments(curve: &[CurvePoint]) -> Vec<(bool, Vec<(f64, f64)>)> {
    let mut pieces: Vec<(bool, Vec<(f64, f64)>)> = Vec::new();
    for &(t, v, outside) in curve.iter().filter(|p| p.1.is_finite()) {
        match pieces.last_mut() {
            Some((flag, piece)) if *flag == outside => piece.push((t, v)),
            Some((_, piece)) => {
                let joint = piece.last().copied();
                pieces.push((outside, joint.into_iter().chain([(t, v)]).collect()));
            }
            None => pieces.push((outside, vec![(t, v)])),
        }
    }
    pieces
}

/// Shades the parts of the x range `x` beyond the calibrated temperatures `(c0, c1)`.
fn shade_beyond<'a>(
    chart: &mut ChartContext<
        'a,
        SVGBackend<'a>,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    path: &Path,
    x: (f64, f64),
    y: (f64, f64),
    (c0, c1): (f64, f64),
) -> Result<(), CalError> {
    let shade = RGBColor(225, 225, 225).mix(0.6).filled();
    let bands = [(x.0, c0), (c1, x.1)].into_iter().filter(|(a, b)| b > a);
    chart
        .draw_series(bands.map(|(a, b)| Rectangle::new([(a, y.0), (b, y.1)], shade)))
        .map_err(|e| plot_err(path, e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blob::{test_blob, test_poly_axis};
    use fogtemp_core::{Model, PolyTerm};

    fn term(temp_power: u8, rate_power: u8, coefficient_dph: f32) -> PolyTerm {
        PolyTerm { temp_power, rate_power, coefficient_dph }
    }

    fn point(temp_c: f64, rate_c_per_min: f64) -> FeaturePoint {
        FeaturePoint::at(temp_c, rate_c_per_min)
    }

    /// Oracle: the closed form of the polynomial (identity normalisation, extrapolated).
    #[test]
    fn the_curves_and_residuals_are_the_models_values() {
        // b = 0.5 + 0.01 T + 0.2 dT/dt (deg/h), over -50 .. 50 C.
        let blob = test_blob(test_poly_axis(vec![term(0, 0, 0.5), term(1, 0, 0.01), term(0, 1, 0.2)]));
        let model = Model::from_bytes(&blob).expect("parses");
        let axis = model.axis(0).expect("axis");
        let points: Vec<FeaturePoint> =
            (0..101).map(|k| point(f64::from(k) - 50.0, f64::from(k % 5) * 0.1)).collect();
        let refs: Vec<&FeaturePoint> = points.iter().collect();
        let closed = |t: f64, r: f64| 0.5 + 0.01 * t + 0.2 * r;
        let targets: Vec<f64> = points.iter().map(|p| closed(p.temp_c, p.rate_c_per_min) + 0.003).collect();
        let fig = temperature_figure(&axis, &refs, &targets).expect("a figure");
        assert_eq!(fig.calibrated_c, (-50.0, 50.0));
        assert_eq!(fig.points.len(), 101);
        // Every residual is the 0.003 added (f32 evaluation: within 1e-6 deg/h).
        assert!(fig.points.iter().all(|p| (p.2 - 0.003).abs() < 1e-6), "{:?}", &fig.points[..3]);
        // Three curves at the 10th, 50th and 90th percentile rates (0, 0.2, 0.4 C/min), each
        // from a sixth of the span below the range to a sixth above.
        let rates: Vec<&str> = fig.curves.iter().map(|(l, _)| l.as_str()).collect();
        assert_eq!(rates.len(), 3, "{rates:?}");
        for ((label, curve), rate) in fig.curves.iter().zip([0.0, 0.2, 0.4]) {
            assert!(label.contains(&format!("{rate:.3} C/min")), "{label}");
            assert!(
                (curve[0].0 + 50.0 + 100.0 / 6.0).abs() < 1e-9
                    && (curve[CURVE_STEPS].0 - 50.0 - 100.0 / 6.0).abs() < 1e-9
            );
            assert!(curve.iter().all(|&(t, v, _)| (v - closed(t, rate)).abs() < 1e-5), "{label}");
        }
        // A model without dT/dt: one curve.
        let blob = test_blob(test_poly_axis(vec![term(0, 0, 0.5), term(1, 0, 0.01)]));
        let model = Model::from_bytes(&blob).expect("parses");
        let fig = temperature_figure(&model.axis(0).expect("axis"), &refs, &targets).expect("a figure");
        assert_eq!(fig.curves.len(), 1);
        assert!(fig.curves[0].0.contains("no dT/dt term"));
        // No points: no figure.
        assert!(temperature_figure(&model.axis(0).expect("axis"), &[], &[]).is_none());
    }

    #[test]
    fn a_curve_is_cut_where_it_leaves_the_region_and_stays_unbroken() {
        let curve = [
            (0.0, 1.0, true),
            (1.0, 2.0, false),
            (2.0, f64::NAN, false),
            (3.0, 3.0, false),
            (4.0, 4.0, true),
        ];
        assert_eq!(
            segments(&curve),
            vec![
                (true, vec![(0.0, 1.0)]),
                (false, vec![(0.0, 1.0), (1.0, 2.0), (3.0, 3.0)]),
                (true, vec![(3.0, 3.0), (4.0, 4.0)]),
            ]
        );
        assert!(segments(&[]).is_empty());
    }

    #[test]
    fn a_long_campaign_draws_at_most_max_points() {
        let blob = test_blob(test_poly_axis(vec![term(0, 0, 0.5)]));
        let model = Model::from_bytes(&blob).expect("parses");
        let points: Vec<FeaturePoint> =
            (0..3 * MAX_POINTS + 7).map(|k| point((k % 90) as f64 - 45.0, 0.0)).collect();
        let refs: Vec<&FeaturePoint> = points.iter().collect();
        let targets = vec![0.5; points.len()];
        let fig = temperature_figure(&model.axis(0).expect("axis"), &refs, &targets).expect("a figure");
        assert!(fig.points.len() <= MAX_POINTS && fig.points.len() >= MAX_POINTS / 2, "{}", fig.points.len());
    }
}
