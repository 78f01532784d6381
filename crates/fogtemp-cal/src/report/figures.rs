//! The validation figures a navigation engineer reads: the drift as 100 s means, raw beside
//! compensated, and the per-run before/after bars. Their data come from [`super::data`].

use std::path::Path;

use plotters::prelude::*;

use super::data::{RelativeMeans, RunBar};
use super::{draw_legend_at, draw_run_legend, finite_range, plot_err, run_colour, tick, write_svg};
use crate::error::CalError;

/// One validation run for the drift figure, over the metric's span.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DriftRun {
    /// Run name.
    pub name: String,
    /// Block centre times of the temperature, seconds since power-on.
    pub time_s: Vec<f64>,
    /// Smoothed temperature, deg C.
    pub temp_c: Vec<f64>,
    /// Raw window means relative to the run's mean.
    pub raw: RelativeMeans,
    /// Compensated window means relative to the run's mean.
    pub compensated: RelativeMeans,
}

/// A symmetric range around zero holding every finite value, padded by 10 %.
fn symmetric_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let max = values.filter(|v| v.is_finite()).fold(0.0f64, |m, v| m.max(v.abs()));
    let half = if max > 0.0 { max * 1.1 } else { 1.0 };
    (-half, half)
}

/// The drift figure: temperature over the metric's span on top; below, raw (left) beside
/// compensated (right) `tau_s` window means, each run relative to its own mean, on one
/// symmetric scale so the drift the model removes is visible. `stability_dph` (raw,
/// compensated) goes into the panel titles.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_drift(
    path: &Path,
    title: &str,
    runs: &[DriftRun],
    tau_s: f64,
    stability_dph: (f64, f64),
) -> Result<(), CalError> {
    let t_max_min =
        runs.iter().flat_map(|r| r.time_s.iter().chain(&r.raw.time_s).copied()).fold(1.0f64, f64::max) / 60.0;
    let y = symmetric_range(
        runs.iter().flat_map(|r| r.raw.deviation_dph.iter().chain(&r.compensated.deviation_dph).copied()),
    );
    write_svg(path, (1200, 860), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(|e| plot_err(path, e))?;
        let (top, bottom) = root.split_vertically(300);
        let (top, legend) = top.split_horizontally(1040);
        let (left, right) = bottom.split_horizontally(600);

        let temp_range = finite_range(runs.iter().flat_map(|r| r.temp_c.iter().copied()));
        let mut chart = ChartBuilder::on(&top)
            .margin(8)
            .margin_right(20)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..t_max_min, temp_range.0..temp_range.1)
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("time since power-on, min")
            .y_desc("temperature, deg C")
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|e| plot_err(path, e))?;
        for (i, run) in runs.iter().enumerate() {
            let series = run
                .time_s
                .iter()
                .zip(&run.temp_c)
                .filter(|(_, v)| v.is_finite())
                .map(|(t, v)| (t / 60.0, *v));
            chart
                .draw_series(LineSeries::new(series, run_colour(i).stroke_width(2)))
                .map_err(|e| plot_err(path, e))?;
        }
        draw_run_legend(&legend, path, runs.iter().map(|r| r.name.as_str()))?;

        let panels = [
            (&left, format!("raw: bias stability {:.4} deg/h", stability_dph.0), false),
            (&right, format!("compensated: bias stability {:.4} deg/h", stability_dph.1), true),
        ];
        for (area, caption, compensated) in panels {
            let mut chart = ChartBuilder::on(area)
                .caption(caption, ("sans-serif", 17))
                .margin(8)
                .margin_right(20)
                .x_label_area_size(35)
                .y_label_area_size(80)
                .build_cartesian_2d(0.0..t_max_min, y.0..y.1)
                .map_err(|e| plot_err(path, e))?;
            chart
                .configure_mesh()
                .x_desc("time since power-on, min")
                .y_desc(format!("{tau_s} s mean - run mean, deg/h"))
                .x_label_formatter(&tick)
                .y_label_formatter(&tick)
                .light_line_style(WHITE.mix(0.0))
                .draw()
                .map_err(|e| plot_err(path, e))?;
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(0.0, 0.0), (t_max_min, 0.0)],
                    BLACK.mix(0.5),
                )))
                .map_err(|e| plot_err(path, e))?;
            for (i, run) in runs.iter().enumerate() {
                let m = if compensated { &run.compensated } else { &run.raw };
                let points: Vec<(f64, f64)> =
                    m.time_s.iter().zip(&m.deviation_dph).map(|(t, v)| (t / 60.0, *v)).collect();
                let colour = run_colour(i);
                chart
                    .draw_series(LineSeries::new(points.iter().copied(), colour.stroke_width(2)))
                    .map_err(|e| plot_err(path, e))?;
                chart
                    .draw_series(points.iter().map(|p| Circle::new(*p, 2, colour.filled())))
                    .map_err(|e| plot_err(path, e))?;
            }
        }
        root.present().map_err(|e| plot_err(path, e))
    })
}

/// Per-run before/after bars: raw (grey) beside compensated (blue) bias stability for each
/// run and the RMS over runs, from zero, values written above the bars.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_run_bars(path: &Path, title: &str, bars: &[RunBar]) -> Result<(), CalError> {
    let top = bars
        .iter()
        .flat_map(|b| [b.raw_dph, b.compensated_dph])
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let top = if top > 0.0 { top * 1.15 } else { 1.0 };
    let n = bars.len();
    let names: Vec<String> = bars.iter().map(|b| b.name.clone()).collect();
    let raw_colour = RGBColor(150, 150, 150);
    let comp_colour = RGBColor(31, 119, 180);
    write_svg(path, (1200, 520), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(-0.5..(n as f64 - 0.5), 0.0..top)
            .map_err(|e| plot_err(path, e))?;
        let label = |v: &f64| {
            let k = v.round();
            if (v - k).abs() < 1e-6 && k >= 0.0 {
                names.get(k as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n + 1)
            .x_label_formatter(&label)
            .y_desc("bias stability, deg/h")
            .y_label_formatter(&tick)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|e| plot_err(path, e))?;
        let width = 0.36;
        for (offset, colour, name, pick) in [
            (-0.19, raw_colour, "raw", (|b: &RunBar| b.raw_dph) as fn(&RunBar) -> f64),
            (0.19, comp_colour, "compensated", |b: &RunBar| b.compensated_dph),
        ] {
            let rects = bars.iter().enumerate().filter(|(_, b)| pick(b).is_finite()).map(move |(i, b)| {
                let x = i as f64 + offset;
                Rectangle::new([(x - width / 2.0, 0.0), (x + width / 2.0, pick(b))], colour.filled())
            });
            chart
                .draw_series(rects)
                .map_err(|e| plot_err(path, e))?
                .label(name)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], colour.filled()));
            let values = bars.iter().enumerate().filter(|(_, b)| pick(b).is_finite()).map(move |(i, b)| {
                Text::new(
                    format!("{:.4}", pick(b)),
                    (i as f64 + offset, pick(b)),
                    ("sans-serif", 12).into_font().color(&BLACK).pos(plotters::style::text_anchor::Pos::new(
                        plotters::style::text_anchor::HPos::Center,
                        plotters::style::text_anchor::VPos::Bottom,
                    )),
                )
            });
            chart.draw_series(values).map_err(|e| plot_err(path, e))?;
        }
        // Upper left: the 15 % headroom above the tallest bar keeps the legend clear of most bars;
        // every value is also written on its bar.
        draw_legend_at(&mut chart, path, SeriesLabelPosition::UpperLeft)?;
        root.present().map_err(|e| plot_err(path, e))
    })
}
