//! Figures (SVG, plotters) and the Markdown report: what a navigation engineer reads.

use std::path::Path;

use plotters::prelude::*;

use crate::error::CalError;
use crate::metrics::AllanPoint;
use crate::output::write_file_atomic;

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
}

/// Tick label with at most 4 significant digits and no float noise (0.01000000000001 -> 0.01).
pub fn tick(v: &f64) -> String {
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

/// A panel against time since power-on (minutes, 0..`t_max_min`) with `y_range` and the
/// axis label `y_label`, mesh drawn.
///
/// # Errors
/// [`CalError::Io`] naming `path` if drawing fails.
pub fn time_panel<'a>(
    area: &DrawingArea<SVGBackend<'a>, plotters::coord::Shift>,
    path: &Path,
    t_max_min: f64,
    y_range: (f64, f64),
    y_label: &str,
) -> Result<
    ChartContext<
        'a,
        SVGBackend<'a>,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    CalError,
> {
    let mut chart = ChartBuilder::on(area)
        .margin(8)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_max_min, y_range.0..y_range.1)
        .map_err(|e| plot_err(path, e))?;
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
    chart
        .configure_series_labels()
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

/// Distinct colours for runs.
pub fn run_colour(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    C[i % C.len()]
}

/// Stacked panels against time: temperature, rate, raw gyro, and compensated gyro when present.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_runs(path: &Path, title: &str, runs: &[RunTrace]) -> Result<(), CalError> {
    let with_comp = runs.iter().any(|r| !r.compensated_dph.is_empty());
    let panels = if with_comp { 4 } else { 3 };
    write_svg(path, (1100, 260 * panels as u32), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let root = root.titled(title, ("sans-serif", 22)).map_err(|e| plot_err(path, e))?;
        let areas = root.split_evenly((panels, 1));
        let t_max = runs.iter().flat_map(|r| r.time_s.last().copied()).fold(1.0, f64::max) / 60.0;
        type Pick = fn(&RunTrace) -> &Vec<f64>;
        let mut specs: Vec<(&str, Pick)> = vec![
            ("temperature, deg C", |r| &r.temp_c),
            ("rate, deg C/min", |r| &r.rate_c_per_min),
            ("raw gyro, deg/h", |r| &r.raw_dph),
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
                chart
                    .draw_series(LineSeries::new(series, run_colour(i)))
                    .map_err(|e| plot_err(path, e))?
                    .label(run.name.clone())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], run_colour(i)));
            }
            if label.starts_with("temperature") && runs.len() <= 16 {
                draw_legend(&mut chart, path)?;
            }
        }
        root.present().map_err(|e| plot_err(path, e))
    })
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

/// The (T, rate) plane: triangles filled by their mean node value, edges, nodes and the
/// calibration points, with a colour scale.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_mesh(path: &Path, title: &str, mesh: &MeshFigure) -> Result<(), CalError> {
    write_svg(path, (1000, 760), |root| {
        root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
        let (main, legend) = root.split_horizontally(880);
        let (t0, t1) = finite_range(mesh.nodes.iter().map(|n| n.0).chain(mesh.points.iter().map(|p| p.0)));
        let (r0, r1) = finite_range(mesh.nodes.iter().map(|n| n.1).chain(mesh.points.iter().map(|p| p.1)));
        let (v0, v1) = finite_range(mesh.nodes.iter().map(|n| n.2));
        let scale = |v: f64| (v - v0) / (v1 - v0);
        let mut chart = ChartBuilder::on(&main)
            .caption(title, ("sans-serif", 20))
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
            .draw_series(mesh.triangles.iter().map(|t| {
                let [a, b, c] = t.map(node);
                Polygon::new(
                    vec![(a.0, a.1), (b.0, b.1), (c.0, c.1)],
                    diverging(scale((a.2 + b.2 + c.2) / 3.0)).filled(),
                )
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
                .map_err(|e| plot_err(path, e))?
                .label("calibration points")
                .legend(|(x, y)| Circle::new((x, y), 3, RGBColor(90, 90, 90).filled()));
        }
        chart
            .draw_series(mesh.nodes.iter().map(|n| Circle::new((n.0, n.1), 2, BLACK.filled())))
            .map_err(|e| plot_err(path, e))?
            .label("mesh nodes")
            .legend(|(x, y)| Circle::new((x, y), 3, BLACK.filled()));
        draw_legend(&mut chart, path)?;
        // Colour bar.
        let mut bar = ChartBuilder::on(&legend)
            .margin_top(60)
            .margin_bottom(60)
            .y_label_area_size(60)
            .caption("deg/h", ("sans-serif", 16))
            .build_cartesian_2d(0.0..1.0, v0..v1)
            .map_err(|e| plot_err(path, e))?;
        bar.configure_mesh()
            .disable_x_axis()
            .disable_mesh()
            .y_label_formatter(&tick)
            .draw()
            .map_err(|e| plot_err(path, e))?;
        let steps = 100;
        bar.draw_series((0..steps).map(|k| {
            let a = v0 + (v1 - v0) * k as f64 / steps as f64;
            let b = v0 + (v1 - v0) * (k + 1) as f64 / steps as f64;
            Rectangle::new([(0.0, a), (1.0, b)], diverging(scale((a + b) / 2.0)).filled())
        }))
        .map_err(|e| plot_err(path, e))?;
        root.present().map_err(|e| plot_err(path, e))
    })
}

/// Allan deviation curves, log-log.
///
/// # Errors
/// [`CalError::Io`] if the file cannot be written.
pub fn plot_allan(path: &Path, title: &str, curves: &[(String, Vec<AllanPoint>)]) -> Result<(), CalError> {
    let points =
        || curves.iter().flat_map(|(_, c)| c.iter()).filter(|p| p.adev_dph > 0.0 && p.adev_dph.is_finite());
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
            .build_cartesian_2d((t0 * 0.8..t1 * 1.25).log_scale(), (a0 * 0.8..a1 * 1.25).log_scale())
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
            let colour = run_colour(i);
            chart
                .draw_series(LineSeries::new(
                    curve.iter().map(|p| (p.tau_s, p.adev_dph)),
                    colour.stroke_width(2),
                ))
                .map_err(|e| plot_err(path, e))?
                .label(name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], colour.stroke_width(2)));
        }
        draw_legend(&mut chart, path)?;
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
    let triangles = (0..mesh.triangle_count()).filter_map(|k| mesh.triangle(k)).map(|t| t.vertices).collect();
    Some(MeshFigure { nodes, triangles, points })
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// Writes `report.md` and its figures into `dir` for a validation: per-run traces with
/// raw and compensated output, the model's mesh, and raw vs compensated Allan deviation.
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
    std::fs::create_dir_all(dir).map_err(|source| CalError::Io { path: dir.to_path_buf(), source })?;
    let mut md = String::new();
    md.push_str(&format!("# Validation of {}\n\n", file_name(model_path)));
    md.push_str(&format!(
        "Bias stability: {definition}. Runs replayed through the firmware's `Compensator`.\n\n"
    ));
    md.push_str("| run | axis | raw, deg/h | compensated, deg/h | ratio |\n|---|---|---|---|---|\n");
    for r in runs {
        md.push_str(&format!(
            "| {} | {} | {:.5} | {:.5} | {:.2} |\n",
            file_name(&r.path),
            r.axis,
            r.raw_bias_stability_dph,
            r.compensated_bias_stability_dph,
            r.raw_bias_stability_dph / r.compensated_bias_stability_dph
        ));
    }
    md.push_str(&format!(
        "| **overall (RMS over runs)** | | **{:.5}** | **{:.5}** | **{:.2}** |\n\n",
        overall.0,
        overall.1,
        overall.0 / overall.1
    ));
    for axis in 0..model.axis_count() {
        let axis_runs: Vec<&crate::calibrate::RunValidation> =
            runs.iter().filter(|r| r.axis == axis).collect();
        if axis_runs.is_empty() {
            continue;
        }
        let traces: Vec<RunTrace> = axis_runs
            .iter()
            .map(|r| RunTrace {
                name: file_name(&r.path),
                time_s: r.series.time_s.clone(),
                temp_c: r.series.temp_c.clone(),
                rate_c_per_min: r.series.rate_c_per_min.clone(),
                raw_dph: r.series.raw_dph.clone(),
                compensated_dph: r.series.compensated_dph.clone(),
            })
            .collect();
        let runs_svg = format!("runs-axis{axis}.svg");
        plot_runs(&dir.join(&runs_svg), &format!("Validation runs, axis {axis} (1 s means)"), &traces)?;
        md.push_str(&format!("## Axis {axis}\n\n![runs]({runs_svg})\n\n"));
        let raw_curves: Vec<Vec<AllanPoint>> =
            axis_runs.iter().map(|r| crate::metrics::allan_deviation(&r.series.raw_dph, 1.0)).collect();
        let comp_curves: Vec<Vec<AllanPoint>> = axis_runs
            .iter()
            .map(|r| crate::metrics::allan_deviation(&r.series.compensated_dph, 1.0))
            .collect();
        let allan_svg = format!("allan-axis{axis}.svg");
        plot_allan(
            &dir.join(&allan_svg),
            &format!("Allan deviation of 1 s means, RMS over runs, axis {axis}"),
            &[
                ("raw".into(), crate::metrics::rms_allan(&raw_curves)),
                ("compensated".into(), crate::metrics::rms_allan(&comp_curves)),
            ],
        )?;
        md.push_str(&format!("![Allan deviation]({allan_svg})\n\n"));
        if let Some(fig) = model.axis(axis).ok().and_then(|a| mesh_figure(&a, Vec::new())) {
            let mesh_svg = format!("mesh-axis{axis}.svg");
            plot_mesh(
                &dir.join(&mesh_svg),
                &format!("Model mesh, axis {axis}: value at nodes, deg/h"),
                &fig,
            )?;
            md.push_str(&format!("![mesh]({mesh_svg})\n\n"));
        }
    }
    let path = dir.join("report.md");
    write_file_atomic(&path, |w| w.write_all(md.as_bytes()))
}

/// Writes `fit-report.md` and its figures into `dir` for a fit: calibration runs
/// (features and raw gyro), and per axis the mesh with the calibration points.
///
/// # Errors
/// [`CalError::Io`] when a file cannot be written.
pub fn write_fit_report(
    dir: &Path,
    model_path: &Path,
    model: &fogtemp_core::Model<'_>,
    runs: &[crate::calibrate::RunFeatures],
    summary_markdown: &str,
) -> Result<(), CalError> {
    std::fs::create_dir_all(dir).map_err(|source| CalError::Io { path: dir.to_path_buf(), source })?;
    let mut md = format!("# Fit of {}\n\n{summary_markdown}\n\n", file_name(model_path));
    for axis in 0..model.axis_count() {
        let traces: Vec<RunTrace> = runs
            .iter()
            .filter_map(|r| {
                let (points, targets) = r.axes.get(axis)?;
                Some(RunTrace {
                    name: file_name(&r.path),
                    time_s: points.iter().map(|p| p.time_s).collect(),
                    temp_c: points.iter().map(|p| p.temp_c).collect(),
                    rate_c_per_min: points.iter().map(|p| p.rate_c_per_min).collect(),
                    raw_dph: targets.clone(),
                    compensated_dph: Vec::new(),
                })
            })
            .collect();
        let runs_svg = format!("fit-runs-axis{axis}.svg");
        plot_runs(
            &dir.join(&runs_svg),
            &format!("Calibration runs, axis {axis} (gyro: smoothed target)"),
            &traces,
        )?;
        md.push_str(&format!("## Axis {axis}\n\n![calibration runs]({runs_svg})\n\n"));
        let points: Vec<(f64, f64)> = runs
            .iter()
            .filter_map(|r| r.axes.get(axis))
            .flat_map(|(p, _)| p.iter().step_by(5).map(|f| (f.temp_c, f.rate_c_per_min)))
            .collect();
        if let Some(fig) = model.axis(axis).ok().and_then(|a| mesh_figure(&a, points)) {
            let mesh_svg = format!("fit-mesh-axis{axis}.svg");
            plot_mesh(&dir.join(&mesh_svg), &format!("Mesh over the calibration points, axis {axis}"), &fig)?;
            md.push_str(&format!("![mesh]({mesh_svg})\n\n"));
        }
    }
    let path = dir.join("fit-report.md");
    write_file_atomic(&path, |w| w.write_all(md.as_bytes()))
}
