//! The validation figures a navigation engineer reads: the drift as 100 s means, raw beside
//! compensated, and the per-run before/after bars. Their data come from [`super::data`].

use std::path::Path;

use plotters::prelude::*;

use super::data::{RelativeMeans, RunBar};
use super::{
    draw_legend_at, draw_run_legend, finite_range, plot_err, run_colour, tick, time_panel_with, write_svg,
    PanelLayout,
};
use crate::error::CalError;
use crate::numbers::dph;

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
        let top_layout = PanelLayout { margin_right: 20, ..PanelLayout::default() };
        let mut chart = time_panel_with(&top, path, t_max_min, temp_range, "temperature, deg C", top_layout)?;
        for (i, run) in runs.iter().enumerate() {
            // Broken where the tracker had no temperature (its restart after a gap in the
            // log) or no block for 10 blocks' time (the gap itself; a block left empty by
            // a sample on its edge is no break).
            let points: Vec<(f64, f64)> =
                run.time_s.iter().zip(&run.temp_c).map(|(t, v)| (t / 60.0, *v)).collect();
            let max_step_min = 10.0 * smallest_step(&points);
            for segment in unbroken_segments(&points, max_step_min) {
                chart
                    .draw_series(LineSeries::new(segment.iter().copied(), run_colour(i).stroke_width(2)))
                    .map_err(|e| plot_err(path, e))?;
            }
        }
        draw_run_legend(&legend, path, runs.iter().map(|r| r.name.as_str()))?;

        let panels = [
            (&left, format!("raw: bias stability {} deg/h", dph(stability_dph.0)), false),
            (&right, format!("compensated: bias stability {} deg/h", dph(stability_dph.1)), true),
        ];
        for (area, caption, compensated) in panels {
            let layout = PanelLayout { caption: Some(&caption), margin_right: 20, y_label_area: 80 };
            let y_label = format!("{tau_s} s mean - run mean, deg/h");
            let mut chart = time_panel_with(area, path, t_max_min, y, &y_label, layout)?;
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
                // A window a gap left out is a break in the line, not a straight join.
                for segment in unbroken_segments(&points, 1.5 * tau_s / 60.0) {
                    chart
                        .draw_series(LineSeries::new(segment.iter().copied(), colour.stroke_width(2)))
                        .map_err(|e| plot_err(path, e))?;
                }
                chart
                    .draw_series(points.iter().map(|p| Circle::new(*p, 2, colour.filled())))
                    .map_err(|e| plot_err(path, e))?;
            }
        }
        root.present().map_err(|e| plot_err(path, e))
    })
}

/// The smallest positive step between consecutive x of `points` (infinite with none).
fn smallest_step(points: &[(f64, f64)]) -> f64 {
    points.windows(2).map(|w| w[1].0 - w[0].0).filter(|d| *d > 0.0).fold(f64::INFINITY, f64::min)
}

/// The runs of `points` with finite y and no step in x longer than `max_step`: the pieces
/// of a line that a gap or a missing value breaks.
fn unbroken_segments(points: &[(f64, f64)], max_step: f64) -> Vec<&[(f64, f64)]> {
    let mut segments = Vec::new();
    let mut start = 0;
    for i in 0..=points.len() {
        let breaks_here = match (points.get(i), i.checked_sub(1).and_then(|j| points.get(j))) {
            (None, _) => true,
            (Some(p), _) if !p.1.is_finite() => true,
            (Some(p), Some(q)) => p.0 - q.0 > max_step,
            (Some(_), None) => false,
        };
        if breaks_here {
            if i > start {
                segments.push(&points[start..i]);
            }
            start = if points.get(i).is_some_and(|p| !p.1.is_finite()) { i + 1 } else { i };
        }
    }
    segments
}

/// Per-run before/after bars: raw (grey) beside compensated (blue) bias stability for each
/// run and the RMS over runs, from zero, values written above the bars.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_run_bars(path: &Path, title: &str, bars: &[RunBar]) -> Result<(), CalError> {
    let groups: Vec<String> = bars.iter().map(|b| b.name.clone()).collect();
    let series = [
        BarSeries { name: "raw".into(), colour: RAW_GREY, values: bars.iter().map(|b| b.raw_dph).collect() },
        BarSeries {
            name: "compensated".into(),
            colour: run_colour(0),
            values: bars.iter().map(|b| b.compensated_dph).collect(),
        },
    ];
    plot_grouped_bars(path, title, &groups, &series)
}

/// The colour of raw (uncompensated) bars.
pub const RAW_GREY: RGBColor = RGBColor(150, 150, 150);

/// One series of a grouped bar figure: a value per group, deg/h.
#[derive(Clone, Debug, PartialEq)]
pub struct BarSeries {
    /// Legend name.
    pub name: String,
    /// Bar colour.
    pub colour: RGBColor,
    /// One value per group (NaN: no bar).
    pub values: Vec<f64>,
}

/// How far below the x axis an upright group name starts, pixels: clear of the axis's tick
/// marks (5 px), which at 6 px ran into the name and read as a minus sign (review21 F10).
const NAME_BELOW_AXIS_PX: i32 = 12;

/// Grouped bars of bias stability from zero: one group per name in `groups`, one bar per
/// series in each, values written above the bars (rotated when the bars are narrow).
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_grouped_bars(
    path: &Path,
    title: &str,
    groups: &[String],
    series: &[BarSeries],
) -> Result<(), CalError> {
    let top =
        series.iter().flat_map(|s| s.values.iter().copied()).filter(|v| v.is_finite()).fold(0.0, f64::max);
    let top = if top > 0.0 { top * 1.18 } else { 1.0 };
    let n = groups.len();
    let k = series.len().max(1);
    let slot = 0.8 / k as f64;
    // Names wider than their group (about 7 px a character at 12 px) are written upright,
    // in a label area as tall as the longest.
    let longest = groups.iter().map(|g| g.chars().count()).max().unwrap_or(0);
    let upright = longest as f64 * 7.0 > 1100.0 / n.max(1) as f64;
    let label_area =
        if upright { (longest as u32 * 7 + 10 + NAME_BELOW_AXIS_PX as u32).min(260) } else { 40 };
    write_svg(path, (1200, 500 + label_area), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(label_area)
            .y_label_area_size(80)
            .build_cartesian_2d(-0.5..(n as f64 - 0.5), 0.0..top)
            .map_err(|e| plot_err(path, e))?;
        // Unit steps of the x axis are the groups (n + 1 labels asked: plotters then steps by 1).
        // Upright names are drawn below (plotters centres a rotated axis label on its tick).
        let label = |v: &f64| {
            let g = v.round();
            if (v - g).abs() < 1e-6 && g >= 0.0 && !upright {
                groups.get(g as usize).cloned().unwrap_or_default()
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
        // Bar width in pixels decides whether the values fit upright.
        let bar_px = 1100.0 / n.max(1) as f64 * slot;
        for (j, s) in series.iter().enumerate() {
            let offset = -0.4 + slot * (j as f64 + 0.5);
            let colour = s.colour;
            let bars = s.values.iter().enumerate().filter(|(_, v)| v.is_finite()).map(move |(i, &v)| {
                let x = i as f64 + offset;
                Rectangle::new([(x - 0.45 * slot, 0.0), (x + 0.45 * slot, v)], colour.filled())
            });
            chart
                .draw_series(bars)
                .map_err(|e| plot_err(path, e))?
                .label(s.name.clone())
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 16, y + 5)], colour.filled()));
            let values = s.values.iter().enumerate().filter(|(_, v)| v.is_finite()).map(move |(i, &v)| {
                let font = ("sans-serif", 12).into_font().color(&BLACK);
                use plotters::style::text_anchor::{HPos, Pos, VPos};
                // Rotated text anchors in its own frame: left = its start (the bar's top),
                // centre = across the bar.
                let (font, pos) = if bar_px >= 40.0 {
                    (font, Pos::new(HPos::Center, VPos::Bottom))
                } else {
                    (font.transform(FontTransform::Rotate270), Pos::new(HPos::Left, VPos::Center))
                };
                Text::new(dph(v), (i as f64 + offset, v), font.pos(pos))
            });
            chart.draw_series(values).map_err(|e| plot_err(path, e))?;
        }
        if upright {
            use plotters::style::text_anchor::{HPos, Pos, VPos};
            // Rotated, anchored at its start: each name runs down from under its group.
            let style = ("sans-serif", 12)
                .into_font()
                .transform(FontTransform::Rotate90)
                .color(&BLACK)
                .pos(Pos::new(HPos::Left, VPos::Center));
            for (i, name) in groups.iter().enumerate() {
                let (x, y) = chart.backend_coord(&(i as f64, 0.0));
                root.draw(&Text::new(name.clone(), (x, y + NAME_BELOW_AXIS_PX), style.clone()))
                    .map_err(|e| plot_err(path, e))?;
            }
        }
        // Upper left: the headroom above the tallest bar keeps the legend clear of most bars;
        // every value is also written on its bar.
        draw_legend_at(&mut chart, path, SeriesLabelPosition::UpperLeft)?;
        root.present().map_err(|e| plot_err(path, e))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_break_at_missing_values_and_long_steps() {
        let nan = f64::NAN;
        // Steps of 1, a missing value at x = 3, then a step of 5 between 6 and 11.
        let p = [
            (0.0, 1.0),
            (1.0, 2.0),
            (2.0, 3.0),
            (3.0, nan),
            (4.0, 1.0),
            (5.0, 1.0),
            (6.0, 1.0),
            (11.0, 2.0),
            (12.0, 2.0),
        ];
        assert_eq!(smallest_step(&p), 1.0);
        let segments = unbroken_segments(&p, 1.5);
        let xs: Vec<Vec<f64>> = segments.iter().map(|s| s.iter().map(|q| q.0).collect()).collect();
        assert_eq!(xs, vec![vec![0.0, 1.0, 2.0], vec![4.0, 5.0, 6.0], vec![11.0, 12.0]]);
        // Nothing to break: one segment; nothing finite: none.
        assert_eq!(unbroken_segments(&p[..3], 1.5).len(), 1);
        assert!(unbroken_segments(&[(0.0, nan), (1.0, nan)], 1.5).is_empty());
        assert!(unbroken_segments(&[], 1.5).is_empty());
    }
}
