//! Figures (SVG, plotters) and the reports a navigation engineer reads: `report.md` with
//! its SVG figures and a self-contained `report.html` beside it (module [`html`]). The
//! validation figures cover the span of the metric (module [`data`], docs/reports.md).

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crate::error::CalError;
use crate::metrics::AllanPoint;
use crate::numbers::dph;
use crate::output::write_file_atomic;

pub mod cross_validation;
pub mod data;
pub mod figures;
pub mod html;
pub mod temperature;

pub use cross_validation::{cross_validation_markdown, selection_markdown, CrossValidationRow};
pub use figures::{plot_drift, plot_grouped_bars, plot_run_bars, BarSeries, DriftRun, RAW_GREY};
pub use html::write_html_beside;

/// One run's traces for the figures (block means, typically 1 s).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunTrace {
    /// Short name (file name).
    pub name: String,
    /// Time since run start, seconds.
    pub time_s: Vec<f64>,
    /// Smoothed temperature, deg C (NaN where unknown).
    pub temp_c: Vec<f64>,
    /// Temperature rate, deg C/min (NaN where unknown).
    pub rate_c_per_min: Vec<f64>,
    /// Raw gyro, deg/h.
    pub raw_dph: Vec<f64>,
    /// Compensated gyro, deg/h (empty when not compensated).
    pub compensated_dph: Vec<f64>,
}

/// A mesh for the (T, rate) figure, in physical units.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshFigure {
    /// Nodes: (temp_c, rate_c_per_min, value_dph).
    pub nodes: Vec<(f64, f64, f64)>,
    /// Triangles as node indices.
    pub triangles: Vec<[u32; 3]>,
    /// Calibration points: (temp_c, rate_c_per_min).
    pub points: Vec<(f64, f64)>,
    /// The calibrated region's vertices (temp_c, rate_c_per_min), in order (empty: the model
    /// records none).
    pub region: Vec<(f64, f64)>,
    /// Per triangle: its centroid lies within the calibrated region (all `true` without one).
    pub inside_region: Vec<bool>,
}

/// Tick label with at most 4 significant digits and no float noise (0.01000000000001 -> 0.01).
/// Values under 1e-12 in magnitude are an axis's zero reached by adding steps (6.9e-17) and
/// print as 0.
pub fn tick(v: &f64) -> String {
    if v.abs() < 1e-12 {
        return "0".into();
    }
    let rounded: f64 = format!("{v:.3e}").parse().unwrap_or(*v);
    format!("{rounded}")
}

/// Draws an SVG of `size` pixels with `draw` in memory and writes it to `path` atomically
/// (a failed drawing leaves no half-drawn file).
///
/// # Errors
/// What `draw` returns, or [`CalError::Output`] if the file cannot be written.
pub fn write_svg(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(DrawingArea<SVGBackend<'_>, plotters::coord::Shift>) -> Result<(), CalError>,
) -> Result<(), CalError> {
    let mut svg = String::new();
    draw(SVGBackend::with_string(&mut svg, size).into_drawing_area())?;
    write_file_atomic(path, |w| w.write_all(svg.as_bytes()))
}

/// How a [`time_panel_with`] panel is laid out: an optional caption above it, the right
/// margin (room for the last tick label) and the width of the y-label area.
#[derive(Debug, Clone, Copy)]
pub struct PanelLayout<'c> {
    /// Drawn above the panel at 17 px.
    pub caption: Option<&'c str>,
    /// Pixels right of the plot.
    pub margin_right: u32,
    /// Pixels left of the plot for the tick labels and the axis label.
    pub y_label_area: u32,
}

impl Default for PanelLayout<'_> {
    fn default() -> Self {
        PanelLayout { caption: None, margin_right: 8, y_label_area: 70 }
    }
}

/// A panel against time since power-on (minutes, 0..`t_max_min`) with `y_range` and the
/// axis label `y_label`, mesh drawn, laid out by default.
///
/// # Errors
/// [`CalError::Io`] naming `path` if drawing fails.
pub fn time_panel<'a>(
    area: &DrawingArea<SVGBackend<'a>, plotters::coord::Shift>,
    path: &Path,
    t_max_min: f64,
    y_range: (f64, f64),
    y_label: &str,
) -> Result<TimeChart<'a>, CalError> {
    time_panel_with(area, path, t_max_min, y_range, y_label, PanelLayout::default())
}

/// A chart against time in minutes, as [`time_panel`] draws it.
pub type TimeChart<'a> = ChartContext<
    'a,
    SVGBackend<'a>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// [`time_panel`] laid out by `layout`.
///
/// # Errors
/// [`CalError::Io`] naming `path` if drawing fails.
pub fn time_panel_with<'a>(
    area: &DrawingArea<SVGBackend<'a>, plotters::coord::Shift>,
    path: &Path,
    t_max_min: f64,
    y_range: (f64, f64),
    y_label: &str,
    layout: PanelLayout<'_>,
) -> Result<TimeChart<'a>, CalError> {
    let mut builder = ChartBuilder::on(area);
    builder
        .margin(8)
        .margin_right(layout.margin_right)
        .x_label_area_size(35)
        .y_label_area_size(layout.y_label_area);
    if let Some(caption) = layout.caption {
        builder.caption(caption, ("sans-serif", 17));
    }
    let mut chart =
        builder.build_cartesian_2d(0.0..t_max_min, y_range.0..y_range.1).map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("time since power-on, min")
        .y_desc(y_label)
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(|e| plot_err(path, e))?;
    Ok(chart)
}

/// The series legend every figure uses (translucent white box, black border).
///
/// # Errors
/// [`CalError::Io`] naming `path` if drawing fails.
pub fn draw_legend<'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, CT>,
    path: &Path,
) -> Result<(), CalError> {
    draw_legend_at(chart, path, SeriesLabelPosition::MiddleRight)
}

/// [`draw_legend`] at `position` (where the figure's curves leave room).
///
/// # Errors
/// [`CalError::Io`] naming `path` if drawing fails.
pub fn draw_legend_at<'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, SVGBackend<'a>, CT>,
    path: &Path,
    position: SeriesLabelPosition,
) -> Result<(), CalError> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(path, e))
}

/// A drawing failure as an I/O error naming the figure's file.
pub fn plot_err(path: &Path, e: impl std::fmt::Display) -> CalError {
    CalError::Io { path: path.to_path_buf(), source: std::io::Error::other(e.to_string()) }
}

/// The range of the finite values, padded by 5 % ((0, 1) when there are none).
pub fn finite_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-9);
    (lo - pad, hi + pad)
}

/// Distinct colours for runs: the ten of matplotlib's `tab10` (a testbed case's nine
/// calibration runs no longer share one), then the ten darker shades of `tab20b` (a testbed
/// case's 17 runs no longer share one either).
pub fn run_colour(i: usize) -> RGBColor {
    const C: [RGBColor; 20] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
        RGBColor(57, 59, 121),
        RGBColor(99, 121, 57),
        RGBColor(140, 109, 49),
        RGBColor(132, 60, 57),
        RGBColor(123, 65, 115),
        RGBColor(82, 84, 163),
        RGBColor(140, 162, 82),
        RGBColor(189, 158, 57),
        RGBColor(173, 73, 74),
        RGBColor(165, 81, 148),
    ];
    C[i % C.len()]
}

/// Stacked panels against time: temperature, rate, raw gyro, and compensated gyro when present.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_runs(path: &Path, title: &str, gyro_label: &str, runs: &[RunTrace]) -> Result<(), CalError> {
    let with_comp = runs.iter().any(|r| !r.compensated_dph.is_empty());
    let panels = if with_comp { 4 } else { 3 };
    write_svg(path, (1200, 260 * panels as u32), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(|e| plot_err(path, e))?;
        let (root, legend) = root.split_horizontally(1030);
        draw_run_legend(&legend, path, runs.iter().map(|r| r.name.as_str()))?;
        let areas = root.split_evenly((panels, 1));
        let t_max = runs.iter().flat_map(|r| r.time_s.last().copied()).fold(1.0, f64::max) / 60.0;
        type Pick = fn(&RunTrace) -> &Vec<f64>;
        // The gyro panel's label is the caller's: it says what was taken from the gyro.
        let mut specs: Vec<(&str, Pick)> = vec![
            ("temperature, deg C", |r| &r.temp_c),
            ("rate, deg C/min", |r| &r.rate_c_per_min),
            (gyro_label, |r| &r.raw_dph),
        ];
        if with_comp {
            specs.push(("compensated gyro, deg/h", |r| &r.compensated_dph));
        }
        // Raw and compensated share one scale so the improvement is visible.
        let gyro_range =
            finite_range(runs.iter().flat_map(|r| r.raw_dph.iter().chain(&r.compensated_dph).copied()));
        for (area, (label, pick)) in areas.iter().zip(specs) {
            let y_range = if label.contains("gyro") {
                gyro_range
            } else {
                finite_range(runs.iter().flat_map(|r| pick(r).iter().copied()))
            };
            let mut chart = time_panel(area, path, t_max, y_range, label)?;
            for (i, run) in runs.iter().enumerate() {
                let series = run
                    .time_s
                    .iter()
                    .zip(pick(run))
                    .filter(|(_, v)| v.is_finite())
                    .map(|(t, v)| (t / 60.0, *v));
                chart.draw_series(LineSeries::new(series, run_colour(i))).map_err(|e| plot_err(path, e))?;
            }
        }
        root.present().map_err(|e| plot_err(path, e))
    })
}

/// The run legend in its own area beside the panels, where it hides no curve: a line in
/// the run's colour and its name, for the first 24 runs.
///
/// # Errors
/// [`CalError::Io`] naming `path` if drawing fails.
pub fn draw_run_legend<'n>(
    area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    path: &Path,
    names: impl Iterator<Item = &'n str>,
) -> Result<(), CalError> {
    for (i, name) in names.enumerate().take(24) {
        let y = 24 + 17 * i as i32;
        area.draw(&PathElement::new(vec![(4, y), (24, y)], run_colour(i).stroke_width(3)))
            .map_err(|e| plot_err(path, e))?;
        area.draw(&Text::new(name.to_string(), (30, y - 7), ("sans-serif", 13)))
            .map_err(|e| plot_err(path, e))?;
    }
    Ok(())
}

/// The longest names a figure's legend, bar labels and panel titles show whole, characters.
pub const LABEL_CHARS: usize = 22;

/// Figure labels for runs: their names without the part every name shares at its start and
/// its end (cut at a `_`, `-`, `.` or space), when some name is longer than [`LABEL_CHARS`]
/// and what is left still tells the runs apart; with the shared parts (`prefix`, `suffix`)
/// for the caption. Lab names (`2026-03-07_FOG-SN001234_chamber-B_down_poweron_-35C_validation`)
/// were cut at the figure's edge to the same first 21 characters in every legend entry
/// (review26b F1). Names left longer than [`LABEL_CHARS`] keep their start and end around an
/// ellipsis.
pub fn run_labels(names: &[String]) -> (Vec<String>, Option<(String, String)>) {
    let long = |n: &String| n.chars().count() > LABEL_CHARS;
    if names.len() < 2 || !names.iter().any(long) {
        return (names.iter().map(|n| middle_ellipsis(n)).collect(), None);
    }
    let is_separator = |c: char| matches!(c, '_' | '-' | '.' | ' ');
    let chars: Vec<Vec<char>> = names.iter().map(|n| n.chars().collect()).collect();
    let shortest = chars.iter().map(Vec::len).min().unwrap_or(0);
    let same_at = |k: usize, from_end: bool| {
        let at = |c: &Vec<char>| if from_end { c[c.len() - 1 - k] } else { c[k] };
        chars.iter().all(|c| at(c) == at(&chars[0]))
    };
    let mut prefix = (0..shortest).take_while(|&k| same_at(k, false)).count();
    // Back to just after a separator, so that a label starts at a word ("-35C", not "5C").
    while prefix > 0 && !is_separator(chars[0][prefix - 1]) {
        prefix -= 1;
    }
    let mut suffix = (0..shortest - prefix).take_while(|&k| same_at(k, true)).count();
    while suffix > 0 && !is_separator(chars[0][chars[0].len() - suffix]) {
        suffix -= 1;
    }
    let labels: Vec<String> = chars.iter().map(|c| c[prefix..c.len() - suffix].iter().collect()).collect();
    let distinct = labels.iter().collect::<std::collections::BTreeSet<_>>().len() == labels.len();
    if (prefix == 0 && suffix == 0) || !distinct || labels.iter().any(|l| l.is_empty()) {
        return (names.iter().map(|n| middle_ellipsis(n)).collect(), None);
    }
    let shared = |range: &[char]| range.iter().collect::<String>();
    let first = &chars[0];
    let parts = (shared(&first[..prefix]), shared(&first[first.len() - suffix..]));
    (labels.iter().map(|l| middle_ellipsis(l)).collect(), Some(parts))
}

/// A name longer than [`LABEL_CHARS`] as its start and end around an ellipsis: the ends are
/// where names differ (a date in front, the condition at the back).
fn middle_ellipsis(name: &str) -> String {
    let chars: Vec<char> = name.chars().collect();
    if chars.len() <= LABEL_CHARS {
        return name.to_string();
    }
    let keep = (LABEL_CHARS - 1) / 2;
    let head: String = chars[..keep].iter().collect();
    let tail: String = chars[chars.len() - keep..].iter().collect();
    format!("{head}\u{2026}{tail}")
}

/// The caption line for [`run_labels`]' shared parts (empty without them).
pub fn run_labels_caption(parts: &Option<(String, String)>) -> String {
    match parts {
        Some((prefix, suffix)) => format!(
            "Runs are labelled by the part of their names that differs: `{prefix}`\u{2026}`{suffix}` left out.\n\n"
        ),
        None => String::new(),
    }
}

/// Blue (low, `t` = 0) to red (high, `t` = 1) through white (0.5); `t` is clamped to [0, 1].
pub fn diverging(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let lerp = |a: f64, b: f64, s: f64| (a + (b - a) * s) as u8;
    if t < 0.5 {
        let s = t / 0.5;
        RGBColor(lerp(33.0, 247.0, s), lerp(102.0, 247.0, s), lerp(172.0, 247.0, s))
    } else {
        let s = (t - 0.5) / 0.5;
        RGBColor(lerp(247.0, 178.0, s), lerp(247.0, 24.0, s), lerp(247.0, 43.0, s))
    }
}

/// A sequential colour map for values of one sign, `t` in [0, 1]: light yellow through
/// orange to brown (ColorBrewer YlOrBr, lightness falling monotonically), with no white, so
/// no colour reads as "no bias" (review21 second report F5: the diverging map put white at
/// 9.7 deg/h for node values of 9.42 to 9.99 that include the Earth rate).
pub fn sequential(t: f64) -> RGBColor {
    let t = t.clamp(0.0, 1.0);
    let lerp = |a: f64, b: f64, s: f64| (a + (b - a) * s) as u8;
    let stops = [(255.0, 237.0, 160.0), (254.0, 153.0, 41.0), (140.0, 45.0, 4.0)];
    let (from, to, s) =
        if t < 0.5 { (stops[0], stops[1], t / 0.5) } else { (stops[1], stops[2], (t - 0.5) / 0.5) };
    RGBColor(lerp(from.0, to.0, s), lerp(from.1, to.1, s), lerp(from.2, to.2, s))
}

/// The colour map of a mesh figure over node values `v0..v1`: [`diverging`] with white at
/// zero when they change sign, else [`sequential`]; and the key's note on it.
fn value_colours(v0: f64, v1: f64) -> (fn(f64) -> RGBColor, &'static str) {
    if v0 < 0.0 && v1 > 0.0 {
        (diverging, "colour: white is zero")
    } else {
        (sequential, "colour: values of one sign, light to dark")
    }
}

/// The (T, rate) plane: triangles filled by their mean node value, edges, nodes and the
/// calibration points, with a colour scale.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_mesh(path: &Path, title: &str, mesh: &MeshFigure) -> Result<(), CalError> {
    write_svg(path, (1040, 760), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let (main, legend) = root.split_horizontally(900);
        // The key goes under the title: the mesh fills the plane, a legend box would hide part.
        let (v0, v1) = finite_range(mesh.nodes.iter().map(|n| n.2));
        let (colours, colours_note) = value_colours(v0, v1);
        let dots = if mesh.points.is_empty() {
            format!("black dots: nodes; {colours_note}")
        } else {
            format!("black dots: nodes, grey: calibration points; {colours_note}")
        };
        let main = main.titled(title, ("sans-serif", 20)).map_err(|e| plot_err(path, e))?;
        let mut main = main.titled(&dots, ("sans-serif", 14)).map_err(|e| plot_err(path, e))?;
        if !mesh.region.is_empty() {
            // The region is the hull of the full-window points, so partial-window points and
            // nodes can lie outside it; a triangle is pale by its centre (review15 F5).
            let region = "thick line: the calibrated region (hull of the full-window points; OUTSIDE_HULL beyond it); \
                          triangles centred outside it pale";
            main = main.titled(region, ("sans-serif", 14)).map_err(|e| plot_err(path, e))?;
        }
        let (t0, t1) = finite_range(mesh.nodes.iter().map(|n| n.0).chain(mesh.points.iter().map(|p| p.0)));
        let (r0, r1) = finite_range(mesh.nodes.iter().map(|n| n.1).chain(mesh.points.iter().map(|p| p.1)));
        // Values on both sides of zero: limits symmetric about it, so white is no bias.
        let (v0, v1) = if v0 < 0.0 && v1 > 0.0 { (-v0.abs().max(v1), v0.abs().max(v1)) } else { (v0, v1) };
        let scale = |v: f64| (v - v0) / (v1 - v0);
        let mut chart = ChartBuilder::on(&main)
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, r0..r1)
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("temperature, deg C")
            .y_desc("rate, deg C/min")
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .disable_mesh()
            .draw()
            .map_err(|e| plot_err(path, e))?;
        let node = |i: u32| mesh.nodes.get(i as usize).copied().unwrap_or((0.0, 0.0, 0.0));
        chart
            .draw_series(mesh.triangles.iter().enumerate().map(|(k, t)| {
                let [a, b, c] = t.map(node);
                let colour = colours(scale((a.2 + b.2 + c.2) / 3.0));
                // Outside the calibrated region the firmware flags the value: drawn pale.
                let inside = mesh.inside_region.get(k).copied().unwrap_or(true);
                let fill = if inside { colour.filled() } else { colour.mix(0.3).filled() };
                Polygon::new(vec![(a.0, a.1), (b.0, b.1), (c.0, c.1)], fill)
            }))
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(mesh.triangles.iter().map(|t| {
                let [a, b, c] = t.map(node);
                PathElement::new(
                    vec![(a.0, a.1), (b.0, b.1), (c.0, c.1), (a.0, a.1)],
                    BLACK.mix(0.35).stroke_width(1),
                )
            }))
            .map_err(|e| plot_err(path, e))?;
        if !mesh.points.is_empty() {
            chart
                .draw_series(
                    mesh.points.iter().map(|p| Circle::new(*p, 1, RGBColor(90, 90, 90).mix(0.4).filled())),
                )
                .map_err(|e| plot_err(path, e))?;
        }
        chart
            .draw_series(mesh.nodes.iter().map(|n| Circle::new((n.0, n.1), 2, BLACK.filled())))
            .map_err(|e| plot_err(path, e))?;
        if let Some(&first) = mesh.region.first() {
            let outline: Vec<(f64, f64)> =
                mesh.region.iter().copied().chain(std::iter::once(first)).collect();
            chart
                .draw_series(std::iter::once(PathElement::new(outline, BLACK.stroke_width(3))))
                .map_err(|e| plot_err(path, e))?;
        }
        // Colour bar.
        let mut bar = ChartBuilder::on(&legend)
            .margin_top(60)
            .margin_bottom(60)
            .margin_right(25)
            .y_label_area_size(75)
            .caption("deg/h", ("sans-serif", 16))
            .build_cartesian_2d(0.0..1.0, v0..v1)
            .map_err(|e| plot_err(path, e))?;
        bar.configure_mesh()
            .disable_x_axis()
            .disable_mesh()
            .y_label_formatter(&tick)
            .y_label_style(("sans-serif", 13))
            .draw()
            .map_err(|e| plot_err(path, e))?;
        let steps = 100;
        bar.draw_series((0..steps).map(|k| {
            let a = v0 + (v1 - v0) * k as f64 / steps as f64;
            let b = v0 + (v1 - v0) * (k + 1) as f64 / steps as f64;
            Rectangle::new([(0.0, a), (1.0, b)], colours(scale((a + b) / 2.0)).filled())
        }))
        .map_err(|e| plot_err(path, e))?;
        root.present().map_err(|e| plot_err(path, e))
    })
}

/// Tick values for a log axis over `axis` (low, high) such that at least two fall inside
/// `data`, the span of the values drawn (one when that span is a single value): 1, 2 and 5
/// times the powers of ten; else every integer multiple 1..9 (a range under a decade); else
/// the multiples of a round linear step (1, 2 or 5 times a power of ten).
///
/// Counting the ticks inside the data, not on the padded axis, keeps a label beside the
/// curves: psim-tvc's Allan axis, padded to 8.95..19.8 deg/h around curves at 11.2..15.8,
/// was labelled 9 and 10 alone, both below every curve (review21 second report F2; review14
/// F11 before it).
pub fn log_ticks(axis: (f64, f64), data: (f64, f64)) -> Vec<f64> {
    let (lo, hi) = axis;
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return Vec::new();
    }
    let (data_lo, data_hi) = (data.0.max(lo), data.1.min(hi));
    let needed_inside = if data_hi > data_lo * (1.0 + 1e-9) { 2 } else { 1 };
    let inside = |ticks: &[f64]| ticks.iter().filter(|&&v| v >= data_lo && v <= data_hi).count();
    let coarse = log_multiples(lo, hi, &[1.0, 2.0, 5.0]);
    if coarse.len() >= 3 && inside(&coarse) >= needed_inside {
        return coarse;
    }
    let every = log_multiples(lo, hi, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    if every.len() >= 2 && inside(&every) >= needed_inside {
        return every;
    }
    // The largest round step with enough multiples inside the data; steps fall 5, 2, 1 per
    // decade from the axis's own size, so the loop ends within a few dozen steps.
    let mut exponent = hi.log10().ceil() as i32;
    for _ in 0..60 {
        for mantissa in [5.0, 2.0, 1.0] {
            let step = mantissa * 10f64.powi(exponent - 1);
            let ticks = linear_multiples(lo, hi, step);
            if ticks.len() >= 2 && inside(&ticks) >= needed_inside {
                return ticks;
            }
        }
        exponent -= 1;
    }
    every
}

/// `mantissas` times each power of ten, within `lo..=hi`.
fn log_multiples(lo: f64, hi: f64, mantissas: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    let mut exponent = lo.log10().floor() as i32;
    while 10f64.powi(exponent) <= hi {
        for m in mantissas {
            let v = round_12(m * 10f64.powi(exponent));
            if v >= lo && v <= hi {
                out.push(v);
            }
        }
        exponent += 1;
    }
    out
}

/// The multiples of `step` within `lo..=hi` (none when there would be more than 100).
fn linear_multiples(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let (first, last) = ((lo / step).ceil(), (hi / step).floor());
    if !(first.is_finite() && last.is_finite()) || last - first > 100.0 {
        return Vec::new();
    }
    let count = (last - first) as i64;
    (0..=count).map(|k| round_12((first + k as f64) * step)).filter(|v| *v >= lo && *v <= hi).collect()
}

/// Rounded to 12 significant digits, so 0.001 * 2 prints as 0.002.
fn round_12(v: f64) -> f64 {
    format!("{v:.11e}").parse().unwrap_or(f64::NAN)
}

/// Whether [`plot_allan`] has a point to draw: a positive, finite deviation (a log scale
/// cannot show 0, as from a residual that is exactly zero).
pub fn allan_plottable(curves: &[(String, Vec<AllanPoint>)]) -> bool {
    curves.iter().flat_map(|(_, c)| c.iter()).any(plottable)
}

fn plottable(p: &AllanPoint) -> bool {
    p.adev_dph > 0.0 && p.adev_dph.is_finite()
}

/// Allan deviation curves, log-log.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written, or there is no point to draw
/// ([`allan_plottable`]).
pub fn plot_allan(path: &Path, title: &str, curves: &[(String, Vec<AllanPoint>)]) -> Result<(), CalError> {
    let points = || curves.iter().flat_map(|(_, c)| c.iter()).filter(|p| plottable(p));
    let (t0, t1) = points().fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(p.tau_s), b.max(p.tau_s)));
    let (a0, a1) = points().fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(p.adev_dph), b.max(p.adev_dph)));
    if !t0.is_finite() {
        return Err(plot_err(path, "no Allan deviation points to plot"));
    }
    write_svg(path, (900, 650), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d(
                (t0 * 0.8..t1 * 1.25).log_scale().with_key_points(log_ticks((t0 * 0.8, t1 * 1.25), (t0, t1))),
                (a0 * 0.8..a1 * 1.25).log_scale().with_key_points(log_ticks((a0 * 0.8, a1 * 1.25), (a0, a1))),
            )
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .x_desc("averaging time tau, s")
            .y_desc("Allan deviation, deg/h")
            .x_labels(8)
            .y_labels(8)
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .draw()
            .map_err(|e| plot_err(path, e))?;
        for (i, (name, curve)) in curves.iter().enumerate() {
            // Raw grey and compensated blue, as in the bars figure beside it; the diagnosis's
            // residual before its model grey and after it blue likewise (review14 F8: before
            // was blue there, after orange).
            // The white-noise line is a reference: black, thinner than the measured curves.
            let reference = name.starts_with("white noise");
            let colour = match name.as_str() {
                "raw" | "residual before" => figures::RAW_GREY,
                "compensated" | "residual after the final model" => run_colour(0),
                _ if reference => BLACK,
                _ => run_colour(i),
            };
            let width = if reference { 1 } else { 2 };
            // Each point's relative error as a bar, cut at the axis (review21 second report F9:
            // the longest averaging times rest on one or two differences).
            let (axis_lo, axis_hi) = (a0 * 0.8, a1 * 1.25);
            chart
                .draw_series(curve.iter().filter(|p| plottable(p) && p.relative_error > 0.0).map(|p| {
                    let lo = (p.adev_dph * (1.0 - p.relative_error)).max(axis_lo);
                    let hi = (p.adev_dph * (1.0 + p.relative_error)).min(axis_hi);
                    PathElement::new(vec![(p.tau_s, lo), (p.tau_s, hi)], colour.mix(0.6).stroke_width(1))
                }))
                .map_err(|e| plot_err(path, e))?;
            chart
                .draw_series(LineSeries::new(
                    curve.iter().map(|p| (p.tau_s, p.adev_dph)),
                    colour.stroke_width(width),
                ))
                .map_err(|e| plot_err(path, e))?
                .label(name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2)));
        }
        // Allan curves fall from the upper left: the lower left is free.
        draw_legend_at(&mut chart, path, SeriesLabelPosition::LowerLeft)?;
        root.present().map_err(|e| plot_err(path, e))
    })
}

/// Mesh figure data from a model axis: nodes in physical units (model value at the node:
/// polynomial plus mesh) and triangles.
pub fn mesh_figure(axis: &fogtemp_core::Axis<'_>, points: Vec<(f64, f64)>) -> Option<MeshFigure> {
    let mesh = axis.mesh?;
    let n = &axis.normalisation;
    let nodes = (0..mesh.vertex_count())
        .filter_map(|k| mesh.vertex(k))
        .map(|v| {
            let (t, r) = crate::mesh::to_physical(n, f64::from(v.x), f64::from(v.y));
            let poly = axis.poly.map_or(0.0, |p| f64::from(p.evaluate(v.x, v.y)));
            (t, r, poly + f64::from(v.value_dph))
        })
        .collect();
    let triangles: Vec<[u32; 3]> =
        (0..mesh.triangle_count()).filter_map(|k| mesh.triangle(k)).map(|t| t.vertices).collect();
    let region = axis.region.map_or_else(Vec::new, |r| {
        (0..r.vertex_count())
            .filter_map(|k| r.vertex(k))
            .map(|(x, y)| crate::mesh::to_physical(n, f64::from(x), f64::from(y)))
            .collect()
    });
    // A triangle's centroid in the normalised plane the region is tested in.
    let inside_region = triangles
        .iter()
        .map(|t| {
            let corners: Vec<(f32, f32)> =
                t.iter().filter_map(|&k| mesh.vertex(k)).map(|v| (v.x, v.y)).collect();
            let (x, y) = corners.iter().fold((0.0, 0.0), |(x, y), c| (x + c.0 / 3.0, y + c.1 / 3.0));
            axis.region.is_none_or(|r| r.contains(x, y))
        })
        .collect();
    Some(MeshFigure { nodes, triangles, points, region, inside_region })
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// Writes `report.md`, `report.html` and their figures into `dir` for a validation: per axis
/// the drift of the runs as 100 s means (raw beside compensated), the per-run before/after
/// bars, raw vs compensated Allan deviation and the model's mesh. Every figure covers the
/// span of the metric: from each run's first compensated sample (module [`data`]).
///
/// # Errors
/// [`CalError::Io`] when a file cannot be written.
pub fn write_validation_report(
    dir: &Path,
    model_path: &Path,
    model: &fogtemp_core::Model<'_>,
    runs: &[crate::calibrate::RunValidation],
    overall: (f64, f64),
    definition: &str,
) -> Result<(), CalError> {
    write_validation_report_with(
        dir,
        model_path,
        model,
        runs,
        overall,
        &crate::metrics::BiasStabilityOptions::default(),
        definition,
    )
}

/// Adds the table of models compared on the same logs (`validate --compare`; `rows` the
/// primary model first) to the validation report in `dir`, before its first section, and
/// writes `report.html` again. The command line's `validate --report` and Python's
/// `validate(report=, compare=)`.
///
/// # Errors
/// [`CalError::Io`] when the report cannot be read or written.
pub fn add_comparison_to_validation_report(
    dir: &Path,
    rows: &[crate::documents::ComparedModel],
) -> Result<(), CalError> {
    let mut table = String::from(
        "## Models compared on the same logs\n\n| model | mesh nodes | polynomial terms | raw, deg/h | compensated, deg/h | raw / compensated (above 1: better) |\n|---|---|---|---|---|---|\n",
    );
    for c in rows {
        table.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:.2} |\n",
            c.model,
            c.mesh_nodes,
            c.polynomial_terms,
            dph(c.raw_bias_stability_dph),
            dph(c.compensated_bias_stability_dph),
            c.raw_bias_stability_dph / c.compensated_bias_stability_dph
        ));
    }
    insert_before_first_section(dir, &format!("{table}\n"))
}

/// Inserts `text` into the report in `dir` before its first section, and writes its HTML again.
fn insert_before_first_section(dir: &Path, text: &str) -> Result<(), CalError> {
    let path = dir.join("report.md");
    let report = crate::output::read_current(&path)
        .map_err(|source| CalError::Io { path: path.clone(), source })?
        .replacen("\n## ", &format!("\n{text}## "), 1);
    write_file_atomic(&path, |w| w.write_all(report.as_bytes()))?;
    write_html_beside(&path)
}

/// The validation report's heading for what `validate` says of the run metadata: the input
/// rates' note ([`crate::runs::input_rates_note`]) and logs of a simulation that did not
/// finish (review31a F6: only the terminal and `--json` had them).
pub const RUN_METADATA_HEADING: &str =
    "Run metadata (what the mean columns hold; logs of a simulation that did not finish):";

/// Adds `notes` under `heading` to the validation report in `dir`, before its first section
/// (what the command line said about the runs as a whole: the in-sample note).
///
/// # Errors
/// [`CalError::Io`] when the report cannot be read or written.
pub fn add_notes_to_validation_report(dir: &Path, heading: &str, notes: &[String]) -> Result<(), CalError> {
    if notes.is_empty() {
        return Ok(());
    }
    insert_before_first_section(dir, &bullet_section(heading, notes))
}

/// [`write_validation_report`] with the bias-stability settings the runs were measured with
/// (the drift figure uses their window length and exclusion). All or nothing: the files are
/// moved into place only when all are written ([`crate::output::all_or_nothing`]).
///
/// # Errors
/// [`CalError::Io`] when a file cannot be written (then no file of the folder is replaced).
pub fn write_validation_report_with(
    dir: &Path,
    model_path: &Path,
    model: &fogtemp_core::Model<'_>,
    runs: &[crate::calibrate::RunValidation],
    overall: (f64, f64),
    options: &crate::metrics::BiasStabilityOptions,
    definition: &str,
) -> Result<(), CalError> {
    // All or nothing: every file staged, all moved into place at the end (review24b F4).
    crate::output::all_or_nothing(|| {
        std::fs::create_dir_all(dir).map_err(|source| CalError::Io { path: dir.to_path_buf(), source })?;
        let mut md = String::new();
        md.push_str(&format!("# Validation of {}\n\n", file_name(model_path)));
        md.push_str(&format!(
            "Definition: {definition}. Runs replayed through the firmware's `Compensator`. \
             Every figure covers the same span as the metric: each run from the first sample the \
             compensator corrected (the start-up before it, where the output is the raw input, is \
             left out of figures and metric alike).\n\n"
        ));
        md.push_str(
            "| run | axis | raw, deg/h | compensated, deg/h | raw / compensated (above 1: better) | white-noise floor, deg/h | windows (scatter of each figure) | outside the calibrated region | mean raw, deg/h | mean compensated, deg/h |\n|---|---|---|---|---|---|---|---|---|---|\n",
        );
        let outside_bit = fogtemp_core::Flags::OUTSIDE_HULL.0.trailing_zeros() as usize;
        for r in runs {
            let outside = r.series.flag_counts.get(outside_bit).copied().unwrap_or(0);
            let scatter = r
                .windows
                .relative_standard_error()
                .map_or(String::new(), |se| format!(" (+-{:.0} %)", 100.0 * se));
            let (raw_mean, comp_mean) = r.residual_means_dph();
            md.push_str(&format!(
                "| {} | {} | {} | {} | {:.2} | {} | {}{scatter} | {} % | {} | {} |\n",
                file_name(&r.path),
                r.axis,
                dph(r.raw_bias_stability_dph),
                dph(r.compensated_bias_stability_dph),
                r.raw_bias_stability_dph / r.compensated_bias_stability_dph,
                white_noise_floor_cell(r.white_noise_floor()),
                r.windows.used,
                crate::calibrate::share_percent(outside, r.series.samples),
                mean_cell(raw_mean),
                mean_cell(comp_mean)
            ));
        }
        let per_axis = crate::calibrate::per_axis_overall(runs);
        if per_axis.len() > 1 {
            for (axis, raw, comp) in &per_axis {
                md.push_str(&format!(
                    "| overall of axis {axis} (RMS over its runs) | {axis} | {} | {} | {:.2} | {} | | | | |\n",
                    dph(*raw),
                    dph(*comp),
                    raw / comp,
                    white_noise_floor_cell(crate::calibrate::overall_white_noise_floor(
                        runs.iter().filter(|r| r.axis == *axis)
                    ))
                ));
            }
        }
        let label =
            if per_axis.len() > 1 { "overall (RMS over runs and axes)" } else { "overall (RMS over runs)" };
        let overall_floor = crate::calibrate::overall_white_noise_floor(runs);
        md.push_str(&format!(
            "| **{label}** | | **{}** | **{}** | **{:.2}** | {} | | | | |\n\n",
            dph(overall.0),
            dph(overall.1),
            overall.0 / overall.1,
            white_noise_floor_cell(overall_floor)
        ));
        // What a compensated figure is to be judged against (review14 F4).
        md.push_str(&format!(
            "White-noise floor: {}\n\n",
            white_noise_floor_explanation(overall_floor, overall.1, options.tau_s)
        ));
        md.push_str(&format!("Means: {}.\n\n", crate::report::means_meaning(runs, model.input_rates())));
        // How far one run's figure moves with its noise alone (review14 F4: per-run ratios of
        // 0.87-0.96 read as compensation making things worse, within a run's ~8 % scatter).
        md.push_str(
            "Scatter: the relative standard error of one run's bias stability from its averaging windows, \
             1 / sqrt(2 (n - 1)) for n independent window means; raw and compensated figures, and so their ratio, \
             move by about that with the noise alone, so a run's ratio within about twice it of 1 says neither \
             better nor worse.\n\n",
        );
        md.push_str(&bullet_section(
            "Samples the calibration did not cover or the model did not compensate (\"outside\": the share of a \
             run's samples flagged OUTSIDE_HULL, outside the calibrated (T, dT/dt) region: a model is extrapolated \
             there, but a polynomial in T alone only beyond the calibrated temperatures, its value elsewhere its \
             own):",
            &runs.iter().flat_map(crate::calibrate::RunValidation::coverage_notes).collect::<Vec<_>>(),
        ));
        md.push_str(&bullet_section(
            "Runs whose figures need a word (compensation made clearly worse; averaging windows the data fill in \
             part; gyro spikes left in the figures):",
            &runs.iter().flat_map(crate::calibrate::RunValidation::figure_notes).collect::<Vec<_>>(),
        ));
        md.push_str(&bullet_section(
            "Gaps in the time stamps (the drift figure shows them as breaks):",
            &crate::calibrate::gap_notes(runs),
        ));
        md.push_str(&bullet_section(
            "Logs that continue one another (each scored as a run of its own):",
            &crate::calibrate::continued_notes(runs),
        ));
        for axis in 0..model.axis_count() {
            let axis_runs: Vec<&crate::calibrate::RunValidation> =
                runs.iter().filter(|r| r.axis == axis).collect();
            if axis_runs.is_empty() {
                continue;
            }
            md.push_str(&format!("## Axis {axis}\n\n"));
            md.push_str(&validation_axis_figures(dir, axis, &axis_runs, options)?);
            if let Some(fig) = model.axis(axis).ok().and_then(|a| mesh_figure(&a, Vec::new())) {
                let mesh_svg = format!("mesh-axis{axis}.svg");
                plot_mesh(
                    &dir.join(&mesh_svg),
                    &format!("Model mesh, axis {axis}: value at nodes, deg/h"),
                    &fig,
                )?;
                md.push_str(&format!(
                    "![The model's mesh over (T, dT/dt), value at the nodes]({mesh_svg})\n\n"
                ));
            }
        }
        remove_stale_figures(dir, &VALIDATION_FIGURES, &md)?;
        let path = dir.join("report.md");
        write_file_atomic(&path, |w| w.write_all(md.as_bytes()))?;
        write_html_beside(&path)
    })
}

/// The figures a validation report draws, `{prefix}{axis}.svg`.
const VALIDATION_FIGURES: [&str; 4] = ["mesh-axis", "drift-axis", "bars-axis", "allan-axis"];
/// The figures a fit report draws, `{prefix}{axis}.svg`.
const FIT_FIGURES: [&str; 3] = ["fit-runs-axis", "fit-temperature-axis", "fit-mesh-axis"];

/// Removes from `dir` the figures of an earlier report of the same kind (`{prefix}{axis}.svg`
/// for one of `prefixes`) that `markdown`, the report being written, does not show, so a
/// re-used folder holds no figure of another model. Other files are left alone.
///
/// # Errors
/// [`CalError::Io`] when the folder cannot be listed or a stale figure removed.
fn remove_stale_figures(dir: &Path, prefixes: &[&str], markdown: &str) -> Result<(), CalError> {
    let io = |path: PathBuf| move |source| CalError::Io { path, source };
    for entry in std::fs::read_dir(dir).map_err(io(dir.to_path_buf()))? {
        let name = entry.map_err(io(dir.to_path_buf()))?.file_name().to_string_lossy().into_owned();
        let ours = name.strip_suffix(".svg").is_some_and(|stem| {
            prefixes.iter().any(|p| {
                stem.strip_prefix(p).is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
            })
        });
        if ours && !markdown.contains(&format!("]({name})")) {
            let path = dir.join(&name);
            crate::output::remove_file_deferred(&path).map_err(io(path.clone()))?;
        }
    }
    Ok(())
}

/// The drift, bars and Allan figures of one axis's validation runs, and their Markdown.
fn validation_axis_figures(
    dir: &Path,
    axis: usize,
    runs: &[&crate::calibrate::RunValidation],
    options: &crate::metrics::BiasStabilityOptions,
) -> Result<String, CalError> {
    let mut md = String::new();
    let stems: Vec<String> = runs
        .iter()
        .map(|r| r.path.file_stem().map_or_else(|| file_name(&r.path), |s| s.to_string_lossy().into_owned()))
        .collect();
    let (labels, shared) = run_labels(&stems);
    md.push_str(&run_labels_caption(&shared));
    let label_of = |r: &crate::calibrate::RunValidation| {
        runs.iter().position(|x| std::ptr::eq(*x, r)).and_then(|i| labels.get(i).cloned()).unwrap_or_default()
    };
    let drift: Vec<DriftRun> = runs
        .iter()
        .zip(&labels)
        .map(|(r, label)| {
            let span = data::compensated_span(&r.series, 1.0);
            DriftRun {
                name: label.clone(),
                time_s: span.time_s.to_vec(),
                temp_c: span.temp_c.to_vec(),
                raw: data::relative_window_means(span.time_s, span.raw_dph, options),
                compensated: data::relative_window_means(span.time_s, span.compensated_dph, options),
            }
        })
        .collect();
    let bars = data::run_bars(runs, label_of);
    let overall = bars.last().map_or((f64::NAN, f64::NAN), |b| (b.raw_dph, b.compensated_dph));
    let starts: Vec<f64> = runs
        .iter()
        .filter_map(|r| data::compensated_span(&r.series, 1.0).time_s.first().map(|t| t - 0.5))
        .collect();
    let (first, last) = starts.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &t| (a.min(t), b.max(t)));
    if first.is_finite() {
        let when = if last > first { format!("{first} s to {last} s") } else { format!("{first} s") };
        md.push_str(&format!(
            "Span of the metric and of every figure below: each run from its first compensated block, \
             {when} after power-on.\n\n"
        ));
    }
    let drift_svg = format!("drift-axis{axis}.svg");
    plot_drift(
        &dir.join(&drift_svg),
        &format!(
            "Validation runs, axis {axis}: {} s means, each run relative to its own mean",
            options.tau_s
        ),
        &drift,
        options.tau_s,
        overall,
    )?;
    md.push_str(&format!(
        "![Drift: {tau} s means of each run relative to its own mean, raw beside compensated on one scale; \
         their standard deviation per run is the run's bias stability]({drift_svg})\n\n",
        tau = options.tau_s
    ));
    let bars_svg = format!("bars-axis{axis}.svg");
    plot_run_bars(&dir.join(&bars_svg), &format!("Bias stability per validation run, axis {axis}"), &bars)?;
    md.push_str(&format!("![Bias stability per run, raw beside compensated]({bars_svg})\n\n"));
    let series: Vec<&crate::calibrate::ReplaySeries> = runs.iter().map(|r| &r.series).collect();
    let data::SpanAllan { raw, compensated: comp, longest_run_tau_s } = data::span_allan(&series, 1.0);
    let mut curves = vec![("raw".to_string(), raw.clone()), ("compensated".to_string(), comp.clone())];
    if let Some(f) = crate::calibrate::overall_white_noise_floor(runs.iter().copied()) {
        curves.push((
            format!("white noise through compensated at {} s (slope -1/2)", f.from_tau_s),
            white_noise_line(&f, &comp),
        ));
    }
    if !raw.is_empty() && !comp.is_empty() && allan_plottable(&curves) {
        let allan_svg = format!("allan-axis{axis}.svg");
        plot_allan(
            &dir.join(&allan_svg),
            &format!(
                "Allan deviation of 1 s means from the first compensated sample, RMS over runs, axis {axis}"
            ),
            &curves,
        )?;
        md.push_str(&format!(
            "![Allan deviation, raw and compensated, each run from its first compensated sample]({allan_svg})\n\n"
        ));
        md.push_str(&allan_reach_sentence(&comp, longest_run_tau_s));
        md.push_str(&allan_table(&raw, &comp));
    }
    Ok(md)
}

/// The white-noise line of `floor` at the averaging times of `curve`:
/// `adev * sqrt(from_tau_s / tau)`.
fn white_noise_line(floor: &crate::calibrate::WhiteNoiseFloor, curve: &[AllanPoint]) -> Vec<AllanPoint> {
    curve
        .iter()
        .map(|p| AllanPoint {
            tau_s: p.tau_s,
            adev_dph: floor.adev_dph * (floor.from_tau_s / p.tau_s).sqrt(),
            relative_error: 0.0,
        })
        .collect()
}

/// What the Allan figure's span and bars are: the bars are each point's relative error
/// (`1 / sqrt(2 (clusters - 1))` per run, pooled over the runs), and when a run reaches
/// longer averaging times than the RMS curve shows (runs of unequal length), how far.
fn allan_reach_sentence(comp: &[AllanPoint], longest_run_tau_s: f64) -> String {
    let mut text = String::from(
        "The bars are each point's relative error (from the number of independent clusters, pooled over the \
         runs): points with few clusters, at the longest averaging times, rest on one or two differences.",
    );
    if let Some(last) = comp.last() {
        if longest_run_tau_s > 1.5 * last.tau_s {
            text.push_str(&format!(
                " The curves stop at {} s, the longest averaging time every run reaches; the longest run reaches {} s \
                 (the RMS over runs is taken where all runs have a point).",
                last.tau_s, longest_run_tau_s
            ));
        }
    }
    text.push_str("\n\n");
    text
}

/// Raw and compensated Allan deviation at 1, 10, 100 and 1000 s (where present), their
/// ratio and the compensated point's relative error.
fn allan_table(raw: &[AllanPoint], comp: &[AllanPoint]) -> String {
    let mut md = String::from(
        "| tau, s | raw ADEV, deg/h | compensated ADEV, deg/h | compensated / raw | relative error |\n|---|---|---|---|---|\n",
    );
    let mut shown = Vec::new();
    for target in [1.0f64, 10.0, 100.0, 1000.0] {
        // The curve's cluster sizes are octave-spaced: the one nearest the target in log.
        let nearest = raw
            .iter()
            .zip(comp)
            .filter(|(r, c)| r.tau_s == c.tau_s)
            .min_by(|a, b| (a.0.tau_s / target).ln().abs().total_cmp(&(b.0.tau_s / target).ln().abs()));
        if let Some((r, c)) = nearest {
            if (r.tau_s / target).ln().abs() < 0.5 && !shown.contains(&r.tau_s) {
                shown.push(r.tau_s);
                md.push_str(&format!(
                    "| {} | {} | {} | {:.3} | +-{} % |\n",
                    r.tau_s,
                    dph(r.adev_dph),
                    dph(c.adev_dph),
                    c.adev_dph / r.adev_dph,
                    percent_to_two_figures(100.0 * c.relative_error)
                ));
            }
        }
    }
    md.push('\n');
    md
}

/// A percentage to two significant figures, at most one decimal (0.31 -> "0.3", 9.6 -> "9.6",
/// 67.4 -> "67").
fn percent_to_two_figures(percent: f64) -> String {
    let decimals = crate::numbers::decimals_for(percent, 1, 2);
    format!("{percent:.decimals$}")
}

/// A white-noise floor as a table cell, deg/h ([`dph`]), or "unknown" (the validation
/// report's column and `validate`'s).
pub fn white_noise_floor_cell(floor: Option<crate::calibrate::WhiteNoiseFloor>) -> String {
    floor.map_or_else(|| "unknown".to_string(), |f| dph(f.floor_dph))
}

/// What the white-noise floor beside a validation's figures means, and what it bounds: the
/// drift the compensation left is at most about `sqrt(comp^2 - floor^2)`, the part of the
/// compensated figure above noise that is at least the floor (the terminal's line under its
/// table, and the report's).
pub fn white_noise_floor_explanation(
    floor: Option<crate::calibrate::WhiteNoiseFloor>,
    compensated_dph: f64,
    window_s: f64,
) -> String {
    let Some(f) = floor else {
        // Taken over the runs with a compensated figure: with none, there is nothing to bound
        // (review24a F7: the stretches were blamed while each run's floor was printed).
        if !compensated_dph.is_finite() {
            return "unknown: no run has a compensated bias stability to set it beside (see the notes)"
                .into();
        }
        return format!(
            "unknown: a run's gap-free stretches are too short for an Allan deviation at up to a tenth of \
             the {window_s} s window"
        );
    };
    let to = if f.averaged_s < 0.9 * window_s {
        format!("the about {:.1} s of data each {window_s} s window holds", f.averaged_s)
    } else {
        format!("the {window_s} s window")
    };
    let meaning = format!(
        "the compensated output's Allan deviation at {} s, where temperature drift does \
         not show yet, extrapolated to {to} as 1/sqrt(tau). Flicker and rate random walk, which \
         no model removes, come on top, so the real floor is higher",
        f.from_tau_s
    );
    let above = compensated_dph * compensated_dph - f.floor_dph * f.floor_dph;
    if !compensated_dph.is_finite() {
        return format!("{meaning}.");
    }
    if above <= 0.0 {
        return format!(
            "{meaning}. The compensated figure ({} deg/h) is at the floor: the noise hides any drift left.",
            dph(compensated_dph)
        );
    }
    format!(
        "{meaning}. The compensated figure is {:.2} x the floor: the drift left is at most about {} deg/h \
         (sqrt(compensated^2 - floor^2)), less by what flicker and random walk add.",
        compensated_dph / f.floor_dph,
        dph(above.sqrt())
    )
}

/// A Markdown paragraph `heading` followed by one bullet per item, and a blank line; empty
/// without items (a report says nothing of what did not happen).
pub fn bullet_section(heading: &str, items: &[String]) -> String {
    if items.is_empty() {
        return String::new();
    }
    let mut md = format!("{heading}\n\n");
    for item in items {
        md.push_str(&format!("- {item}\n"));
    }
    md.push('\n');
    md
}

/// `fit --report DIR` (and Python's `fit(report=)`): [`write_fit_report`] with the summary
/// the command line gives: per axis its method, points, residual, mesh nodes, polynomial terms
/// and cross-validation table, then the warnings. The model is `fitted`'s blob, named
/// `model_path` in the report.
///
/// # Errors
/// [`CalError::Io`] when a file cannot be written; the blob's own error if it does not read.
pub fn write_fit_report_for(
    dir: &Path,
    model_path: &Path,
    fitted: &crate::calibrate::FittedModel,
    runs: &[crate::calibrate::RunFeatures],
    warnings: &[crate::identifiability::Warning],
) -> Result<(), CalError> {
    let model = fogtemp_core::Model::from_bytes(&fitted.blob).map_err(CalError::SelfCheck)?;
    let summary = fit_summary_markdown(&model, fitted, warnings);
    write_fit_report(dir, model_path, &model, runs, &summary)
}

/// The summary [`write_fit_report_for`] puts at the top of a fit report: per axis its method,
/// points, residual, mesh nodes, polynomial terms, calibrated range, merged or dropped mesh
/// points, polynomial terms and cross-validation table, then the warnings. The demo's fit
/// reports use it too (review21 second report F1: theirs lacked the range and the points).
pub fn fit_summary_markdown(
    model: &fogtemp_core::Model<'_>,
    fitted: &crate::calibrate::FittedModel,
    warnings: &[crate::identifiability::Warning],
) -> String {
    let summary: Vec<String> = fitted
        .axes
        .iter()
        .enumerate()
        .map(|(axis, r)| {
            let table =
                r.selection.as_ref().map_or(String::new(), |s| format!("\n\n{}", selection_markdown(axis, s)));
            let model_axis = model.axis(axis).ok();
            let range = model_axis.as_ref().map_or(String::new(), calibrated_range_item);
            let merged = if r.dropped_flat > 0 || r.merged_duplicates > 0 {
                format!(
                    "\n  - mesh: {} duplicate points merged, {} points dropped for flat hull triangles",
                    r.merged_duplicates, r.dropped_flat
                )
            } else {
                String::new()
            };
            let terms = match (&r.poly, &model_axis) {
                (Some(p), Some(a)) => format!("\n\n{}", poly_terms_markdown(axis, p, &a.normalisation)),
                _ => String::new(),
            };
            format!(
                "- axis {axis}: {}, {} calibration points, residual RMS {} deg/h (max {}), {} mesh nodes, {} polynomial terms{range}{merged}{terms}{table}",
                r.method.name(),
                r.points,
                dph(r.residual_rms_dph),
                dph(r.residual_max_abs_dph),
                r.mesh_nodes,
                r.poly.as_ref().map_or(0, |p| p.terms.len())
            )
        })
        .collect();
    let mut summary = summary.join("\n").trim_end().to_string();
    let messages: Vec<String> = warnings.iter().map(|w| w.message.clone()).collect();
    let warned = bullet_section("Warnings (what the data cannot support):", &messages);
    if !warned.is_empty() {
        summary.push_str("\n\n");
        summary.push_str(warned.trim_end());
    }
    summary
}

/// The calibrated range of a model axis as a sub-item of its summary line: what the
/// validation's "outside the calibrated region" notes refer to (review14 F9: the fit report
/// did not say where the model is valid).
fn calibrated_range_item(axis: &fogtemp_core::Axis<'_>) -> String {
    let p = &axis.provenance;
    let region = axis.region.map_or(String::new(), |r| {
        format!("; the firmware flags OUTSIDE_HULL beyond the region's {} vertices", r.vertex_count())
    });
    format!(
        "\n  - calibrated range: {:.2} .. {:.2} C, {:.4} .. {:.4} C/min{region}",
        p.temp_min_c, p.temp_max_c, p.rate_min_c_per_min, p.rate_max_c_per_min
    )
}

/// The polynomial's terms as a table (coefficient, standard error, p), in the normalised
/// inputs the firmware evaluates, with their definition (review14 F9: the report gave only the
/// number of terms).
fn poly_terms_markdown(
    axis: usize,
    poly: &crate::poly_fit::PolyFit,
    n: &fogtemp_core::Normalisation,
) -> String {
    let mut md = format!(
        "Polynomial terms, axis {axis}, in x = (T {} C) x {:.6} /C and y = (dT/dt {} C/min) x {:.6} min/C \
         (the stepwise selection's; p from its t-test with the effective sample size {:.1}):\n\n\
         | term | coefficient, deg/h | standard error, deg/h | p |\n|---|---|---|---|\n",
        crate::numbers::minus_text(f64::from(n.temp_offset_c), 4),
        n.temp_scale_per_c,
        crate::numbers::minus_text(f64::from(n.rate_offset_c_per_min), 6),
        n.rate_scale_per_c_per_min,
        poly.n_eff
    );
    for t in &poly.terms {
        let name = match crate::poly_fit::monomial(t.temp_power, t.rate_power) {
            constant if constant.is_empty() => "1".to_string(),
            name => name,
        };
        // A p below the smallest f64 is 0: shown as a bound, not as "0e0".
        let p = if t.p_value > 0.0 { format!("{:.2e}", t.p_value) } else { "< 1e-300".to_string() };
        md.push_str(&format!("| {name} | {:.6} | {:.6} | {p} |\n", t.coefficient_dph, t.std_error_dph));
    }
    md
}

/// Writes `fit-report.md` and its figures into `dir` for a fit: calibration runs
/// (features and raw gyro), and per axis the mesh with the calibration points; all or
/// nothing, as [`write_validation_report_with`].
///
/// # Errors
/// [`CalError::Io`] when a file cannot be written (then no file of the folder is replaced).
pub fn write_fit_report(
    dir: &Path,
    model_path: &Path,
    model: &fogtemp_core::Model<'_>,
    runs: &[crate::calibrate::RunFeatures],
    summary_markdown: &str,
) -> Result<(), CalError> {
    // All or nothing, as the validation report.
    crate::output::all_or_nothing(|| {
        std::fs::create_dir_all(dir).map_err(|source| CalError::Io { path: dir.to_path_buf(), source })?;
        let mut md = format!("# Fit of {}\n\n{summary_markdown}\n\n", file_name(model_path));
        let gap_notes: Vec<String> = runs.iter().filter_map(|r| r.gaps.note(&r.path)).collect();
        md.push_str(&bullet_section("Gaps in the time stamps:", &gap_notes));
        let silences: Vec<String> = runs
            .iter()
            .flat_map(|r| {
                (0..r.temperature_silences.len()).filter_map(|axis| r.temperature_silence_note(axis))
            })
            .collect();
        md.push_str(&bullet_section("Temperature silent while the gyro went on:", &silences));
        let (labels, shared) = run_labels(&runs.iter().map(|r| file_name(&r.path)).collect::<Vec<_>>());
        md.push_str(&run_labels_caption(&shared));
        for axis in 0..model.axis_count() {
            let traces: Vec<RunTrace> = runs
                .iter()
                .zip(&labels)
                .filter_map(|(r, label)| {
                    let (points, targets) = r.axes.get(axis)?;
                    Some(RunTrace {
                        name: label.clone(),
                        time_s: points.iter().map(|p| p.time_s).collect(),
                        temp_c: points.iter().map(|p| p.temp_c).collect(),
                        rate_c_per_min: points.iter().map(|p| p.rate_c_per_min).collect(),
                        raw_dph: targets.clone(),
                        compensated_dph: Vec::new(),
                    })
                })
                .collect();
            let runs_svg = format!("fit-runs-axis{axis}.svg");
            let input_rates: Vec<f64> = runs
                .iter()
                .filter_map(|r| r.input_rate_subtracted_dph.get(axis).copied())
                .filter(|rate| *rate != 0.0)
                .collect();
            let gyro_label = if input_rates.is_empty() {
                "gyro, uncompensated, deg/h"
            } else {
                "gyro less the runs file's input rate, deg/h"
            };
            plot_runs(
                &dir.join(&runs_svg),
                &format!("Calibration runs, axis {axis} (gyro: the smoothed target the model is fitted to)"),
                gyro_label,
                &traces,
            )?;
            md.push_str(&format!(
                "## Axis {axis}\n\n![Calibration runs: temperature, rate and the smoothed gyro target against time]({runs_svg})\n\n"
            ));
            if let (Some(lo), Some(hi)) =
                (input_rates.iter().copied().reduce(f64::min), input_rates.iter().copied().reduce(f64::max))
            {
                let range = if (hi - lo).abs() < 5e-4 {
                    format!("{lo:.3} deg/h")
                } else {
                    format!("{lo:.3} to {hi:.3} deg/h")
                };
                md.push_str(&format!(
                    "Each run's `input_rate_dph` from the run metadata (a runs file, or the simulation's `manifest.json`) ({range}: the Earth rate's \
                     projection or a turntable's rate) was subtracted from its gyro before the fit, so the model \
                     is the bias alone; the gyro panel shows the gyro less that rate.\n\n"
                ));
            }
            let (axis_points, axis_targets): (Vec<&crate::features::FeaturePoint>, Vec<f64>) = runs
                .iter()
                .filter_map(|r| r.axes.get(axis))
                .flat_map(|(p, t)| p.iter().zip(t.iter().copied()))
                .unzip();
            let over_temperature = model
                .axis(axis)
                .ok()
                .and_then(|a| temperature::temperature_figure(&a, &axis_points, &axis_targets));
            if let Some(fig) = over_temperature {
                let temp_svg = format!("fit-temperature-axis{axis}.svg");
                // The gyro column too, where the model records it (review31b F10).
                let column = model.axis_columns(axis).map(|c| c.gyro).filter(|g| !g.is_empty());
                let title = match column {
                    Some(gyro) => format!("The model over temperature, axis {axis} ({gyro})"),
                    None => format!("The model over temperature, axis {axis}"),
                };
                temperature::plot_model_over_temperature(&dir.join(&temp_svg), &title, &fig)?;
                md.push_str(&format!(
                    "![The model against temperature at the calibration points' rates, with their targets, and \
                     each point's residual]({temp_svg})\n\n"
                ));
            }
            let points: Vec<(f64, f64)> = runs
                .iter()
                .filter_map(|r| r.axes.get(axis))
                .flat_map(|(p, _)| p.iter().step_by(5).map(|f| (f.temp_c, f.rate_c_per_min)))
                .collect();
            if let Some(fig) = model.axis(axis).ok().and_then(|a| mesh_figure(&a, points)) {
                let mesh_svg = format!("fit-mesh-axis{axis}.svg");
                plot_mesh(
                    &dir.join(&mesh_svg),
                    &format!("Mesh over the calibration points, axis {axis}"),
                    &fig,
                )?;
                md.push_str(&format!(
                    "![The mesh over (T, dT/dt): model value at the nodes, calibration points in grey]({mesh_svg})\n\n"
                ));
            }
        }
        remove_stale_figures(dir, &FIT_FIGURES, &md)?;
        let path = dir.join("fit-report.md");
        write_file_atomic(&path, |w| w.write_all(md.as_bytes()))?;
        write_html_beside(&path)
    })
}

/// A run's mean output in a table cell, deg/h ("undefined" for an empty span).
fn mean_cell(value_dph: f64) -> String {
    if value_dph.is_nan() {
        "undefined".into()
    } else {
        dph(value_dph)
    }
}

/// What the validation's mean columns are (`validate`'s table and report): each run's mean
/// output over the metric's span, the bias a constant leaves that bias stability does not
/// see; less the true input rate where a runs file gave it.
pub fn means_meaning(
    runs: &[crate::calibrate::RunValidation],
    recorded: Option<fogtemp_core::InputRates>,
) -> String {
    let given = runs.iter().filter(|r| r.input_rate_dph.is_some()).count();
    // The model says what its fit did with the rates (format 8): no conditional then
    // (review31a F11).
    let bias_alone = recorded == Some(fogtemp_core::InputRates::Subtracted);
    let left_in = recorded == Some(fogtemp_core::InputRates::NotSubtracted);
    let rate = if left_in {
        format!(
            "{}the model records that its fit left its runs' input rates in (several gyro columns), so it holds \
             the mean of its calibration runs' rates as bias and each compensated mean is off by that mean",
            if given > 0 { "less the run's input rate from the run metadata for the rows that give it; " } else { "" }
        )
    } else if given == 0 && bias_alone {
        "it includes the rate the gyro sensed (the Earth rate's share), which a runs file's input_rate_dph \
         takes off for a model of one axis; the model records that its fit took its runs' rates off (it is the \
         bias alone), so the compensated mean is the bias it leaves plus the run's rate"
            .to_string()
    } else if given == runs.len() && bias_alone {
        "less the run's input rate from the run metadata (a runs file, or the simulation's manifest.json); the \
         model records that its fit took its runs' rates off (it is the bias alone)"
            .to_string()
    } else if given == 0 {
        "it includes the rate the gyro sensed (the Earth rate's share), which a runs file's \
         input_rate_dph takes off for a model of one axis (a rate is about one input axis); and a \
         model fitted without the runs' rates holds the mean of its calibration runs' rates as bias, so \
         a run's compensated mean is its own rate less that mean (twice the Earth rate's share for a \
         model of one position validated in the opposite one)"
            .to_string()
    } else if given == runs.len() {
        "less the run's input rate from the run metadata (a runs file, or the simulation's manifest.json); \
         a model fitted without the runs' rates holds the mean of its calibration runs' rates as bias, so its \
         compensated mean here is off by that mean"
            .to_string()
    } else {
        format!("less the run's input rate from the run metadata for {given} of {} rows", runs.len())
    };
    format!(
        "each run's mean output over the metric's span, deg/h: the bias raw (the gyro's own, after start-up) \
         and the bias the model leaves (compensated), which bias stability does not see; {rate}"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// review31b F6, F7, F11: the legend of the mean columns says what the model records of
    /// its runs' input rates, for runs with and without rates.
    #[test]
    fn the_means_legend_says_what_the_model_records() {
        use fogtemp_core::InputRates;
        let run = |rate: Option<f64>| crate::calibrate::RunValidation {
            path: "r.csv".into(),
            axis: 0,
            raw_bias_stability_dph: 0.01,
            compensated_bias_stability_dph: 0.005,
            series: Default::default(),
            ingest: Default::default(),
            raw_mean_dph: 0.0,
            compensated_mean_dph: 0.0,
            input_rate_dph: rate,
            windows: Default::default(),
        };
        let (with, without) = ([run(Some(9.67)), run(Some(-9.67))], [run(None), run(None)]);
        let alone = Some(InputRates::Subtracted);
        let legend = means_meaning(&with, alone);
        assert!(
            legend.contains("records that its fit took its runs' rates off")
                && !legend.contains("fitted without")
        );
        assert!(means_meaning(&with, None).contains("holds the mean of its calibration runs' rates as bias"));
        assert!(means_meaning(&without, alone).contains("plus the run's rate"));
        assert!(means_meaning(&without, None).contains("its own rate less that mean"));
        let left = means_meaning(&without, Some(InputRates::NotSubtracted));
        assert!(
            left.contains("left its runs' input rates in") && !left.contains("less the run's input rate"),
            "{left}"
        );
        let left = means_meaning(&with, Some(InputRates::NotSubtracted));
        assert!(left.contains("less the run's input rate from the run metadata for the rows"), "{left}");
    }

    /// Lab names lose what every one shares, cut at separators; short names (the testbed's)
    /// and names that would not stay apart are kept (ends around an ellipsis when long).
    #[test]
    fn run_labels_keep_the_part_that_differs() {
        let lab: Vec<String> = ["-35C", "+10C", "-05C"]
            .iter()
            .map(|t| format!("2026-03-07_FOG-SN001234_chamber-B_down_poweron_{t}_validation"))
            .collect();
        let (labels, shared) = run_labels(&lab);
        assert_eq!(labels, ["-35C", "+10C", "-05C"]);
        assert_eq!(
            shared,
            Some(("2026-03-07_FOG-SN001234_chamber-B_down_poweron_".to_string(), "_validation".to_string()))
        );
        assert!(run_labels_caption(&shared).contains("`2026-03-07_FOG-SN001234_chamber-B_down_poweron_`"));
        let testbed: Vec<String> =
            ["down_poweron_-35C.csv", "down_triangle_+30C.csv"].map(String::from).to_vec();
        assert_eq!(run_labels(&testbed), (testbed.clone(), None));
        // Shared digits are cut back to the separator: "run_12" and "run_13" keep "12", "13".
        let numbered: Vec<String> =
            ["chamber_B_serial_0042_run_12", "chamber_B_serial_0042_run_13"].map(String::from).to_vec();
        assert_eq!(run_labels(&numbered).0, ["12", "13"]);
        // One long name alone: its ends around an ellipsis (10 + 1 + 10 characters).
        let one = vec!["abcdefghij_0123456789_klmnopqrst".to_string()];
        assert_eq!(run_labels(&one).0, ["abcdefghij\u{2026}klmnopqrst"]);
    }

    #[test]
    fn ticks_print_an_accumulated_zero_as_zero() {
        assert_eq!(tick(&6.938893903907228e-17), "0");
        assert_eq!(tick(&0.010000000000000002), "0.01");
        assert_eq!(tick(&-0.05), "-0.05");
    }

    #[test]
    fn log_ticks_by_hand() {
        let over = |lo: f64, hi: f64| log_ticks((lo, hi), (lo, hi));
        // 0.0014..0.037: 0.002, 0.005, 0.01, 0.02.
        assert_eq!(over(0.0014, 0.037), [0.002, 0.005, 0.01, 0.02]);
        // 0.8..4000: 1, 2, 5, 10, ..., 2000.
        assert_eq!(over(0.8, 4000.0), [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0]);
        // Under a decade: every multiple.
        assert_eq!(over(0.0025, 0.0045), [0.003, 0.004]);
        // At most one multiple in the range: a round linear step.
        assert_eq!(over(12.6, 19.7), [14.0, 16.0, 18.0]);
        assert_eq!(over(2.1, 2.9), [2.2, 2.4, 2.6, 2.8]);
        assert!(over(0.0, 1.0).is_empty());
    }

    /// psim-tvc's Allan figure (review21 second report F2): curves at 11.2..15.8 deg/h on an
    /// axis padded by 0.8 and 1.25. Every multiple gives 9 and 10, both below the curves;
    /// the ticks must include two inside the curves' span.
    #[test]
    fn log_ticks_label_the_span_of_the_curves_not_only_the_padding() {
        let (data_lo, data_hi) = (11.2, 15.8);
        let ticks = log_ticks((data_lo * 0.8, data_hi * 1.25), (data_lo, data_hi));
        assert_eq!(ticks, [10.0, 12.0, 14.0, 16.0, 18.0]);
        let inside = ticks.iter().filter(|&&v| (data_lo..=data_hi).contains(&v)).count();
        assert!(inside >= 2, "{ticks:?}");
        // A single value: one tick at it or beside it is enough.
        let single = log_ticks((0.004 * 0.8, 0.004 * 1.25), (0.004, 0.004));
        assert!(single.contains(&0.004), "{single:?}");
        // Every tick of each case lies on its axis.
        for (axis, data) in
            [((8.96, 19.75), (11.2, 15.8)), ((0.0032, 0.005), (0.004, 0.004)), ((0.8, 2.5), (1.0, 2.0))]
        {
            let ticks = log_ticks(axis, data);
            assert!(ticks.iter().all(|v| (axis.0..=axis.1).contains(v)), "{axis:?}: {ticks:?}");
            assert!(ticks.len() >= 2, "{axis:?}: {ticks:?}");
        }
    }

    /// A 2 h log at 10 Hz: temperature rising 20 -> 40 C with a time constant of 30 min,
    /// bias 0.002 deg/h per C plus white noise (fixed seed), Earth rate 10 deg/h.
    fn log(seed: u64, earth_dph: f64) -> String {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut csv = String::from("time_s,temp_c,gyro_dph\n");
        for k in 0..72_001 {
            let t = f64::from(k) * 0.1;
            let temp_c = 20.0 + 20.0 * (1.0 - (-t / 1800.0).exp());
            let noise: f64 = (0..12).map(|_| rng.gen::<f64>()).sum::<f64>() - 6.0;
            csv.push_str(&format!("{t:.1},{temp_c:.4},{:.6}\n", earth_dph + 0.002 * temp_c + 0.05 * noise));
        }
        csv
    }

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("fogtemp-report-test-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }

    /// Every figure the Markdown names exists, and the HTML inlines each of them and loads
    /// nothing: no `src=`, no `http` anywhere (the SVG namespace is dropped).
    fn assert_self_contained(dir: &Path, md_name: &str) {
        let md = std::fs::read_to_string(dir.join(md_name)).expect("markdown");
        let html = std::fs::read_to_string(dir.join(md_name).with_extension("html")).expect("html");
        let figures: Vec<&str> = md
            .lines()
            .filter_map(|l| l.trim().strip_prefix("!["))
            .filter_map(|l| l.split("](").nth(1))
            .collect();
        assert!(!figures.is_empty(), "{md}");
        for f in &figures {
            let file = f.trim_end_matches(')');
            assert!(dir.join(file).is_file(), "{file} missing");
        }
        assert_eq!(html.matches("<svg ").count(), figures.len(), "every figure inlined once");
        assert_eq!(html.matches("<figure>").count(), figures.len());
        assert!(!html.contains("http") && !html.contains("src="), "external reference in {md_name}");
        assert_eq!(html.matches("<table>").count(), md.matches("\n|---").count(), "every table");
    }

    #[test]
    fn validation_and_fit_reports_are_self_contained_and_hold_every_figure() {
        let config = crate::calibrate::CalibrationConfig {
            method: crate::calibrate::Method::Poly,
            ..crate::calibrate::CalibrationConfig::default()
        };
        let runs: Vec<crate::calibrate::RunFeatures> = (1..=2)
            .map(|seed| {
                let text = log(seed, 10.0);
                crate::calibrate::extract_run_from(
                    text.as_bytes(),
                    Path::new(&format!("cal{seed}.csv")),
                    &config,
                )
                .expect("features")
            })
            .collect();
        let fitted = crate::calibrate::fit_model(&runs, &config, [0; 32]).expect("fit");
        let model = fogtemp_core::Model::from_bytes(&fitted.blob).expect("model");
        let options = crate::metrics::BiasStabilityOptions::default();
        let logs: Vec<(String, String)> =
            (3..=4).map(|seed| (format!("val{seed}.csv"), log(seed, -5.0))).collect();
        let validation = crate::calibrate::validate_readers(
            logs.iter().map(|(name, text)| (name.clone(), text.as_bytes())),
            &model,
            &config.ingest,
            &options,
        )
        .expect("validation");
        let dir = scratch("validate");
        // A re-used folder: the figures of an earlier report that this one does not draw go
        // (a second axis, a mesh this polynomial model does not have); other files stay.
        let stale = ["drift-axis1.svg", "mesh-axis0.svg"];
        let kept = ["mine.svg", "drift-axis1-old.svg", "fit-runs-axis0.svg", "drift-axisX.svg"];
        std::fs::create_dir_all(&dir).expect("scratch folder");
        for name in stale.iter().chain(&kept) {
            std::fs::write(dir.join(name), "<svg/>").expect("plant a file");
        }
        write_validation_report_with(
            &dir,
            Path::new("m.fogm"),
            &model,
            &validation.runs,
            (validation.raw_bias_stability_dph, validation.compensated_bias_stability_dph),
            &options,
            &options.describe(),
        )
        .expect("validation report");
        assert_self_contained(&dir, "report.md");
        let md = std::fs::read_to_string(dir.join("report.md")).expect("md");
        for figure in ["drift-axis0.svg", "bars-axis0.svg", "allan-axis0.svg"] {
            assert!(md.contains(figure), "{figure} not in the report");
        }
        assert!(stale.iter().all(|n| !dir.join(n).exists()), "stale figures removed");
        assert!(kept.iter().all(|n| dir.join(n).is_file()), "other files kept");

        let fit_dir = scratch("fit");
        let table = cross_validation_markdown(
            0,
            &["cal1".into(), "cal2".into()],
            &[CrossValidationRow {
                method: "poly".into(),
                cv_dph: 0.01,
                se_dph: 0.001,
                excess: (0.0, 0.0),
                chosen: true,
                within_one_se: true,
                held_out_dph: vec![0.01, 0.01],
                correction_dph: None,
            }],
        );
        write_fit_report(
            &fit_dir,
            Path::new("m.fogm"),
            &model,
            &runs,
            &format!("- axis 0: fitted\n\n{table}"),
        )
        .expect("fit report");
        assert_self_contained(&fit_dir, "fit-report.md");
        let html = std::fs::read_to_string(fit_dir.join("fit-report.html")).expect("html");
        assert!(html.contains("<strong><code>poly</code></strong>"), "the cross-validation table");
        let _ = std::fs::remove_dir_all(&dir);
        let _ = std::fs::remove_dir_all(&fit_dir);
    }
}
