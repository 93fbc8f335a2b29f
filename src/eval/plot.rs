//! Evaluation plots drawn with `plotters` (PNG or SVG, chosen by the file extension), text in
//! the embedded DejaVu Sans ([`crate::draw::font`]).
//!
//! - trajectory views: ground truth (blue, cropped to the evaluated time span) and the aligned
//!   estimate (orange), equal metric scale on both axes; top view is world `x` right, `z` up
//!   the page, side view is `z` right, `-y` up (cameras have `y` down);
//! - error over time: the error series against seconds from the first evaluated pose, with
//!   its mean and median as horizontal lines;
//! - histogram: the error distribution in 20 equal bins from 0 to the largest error.
//!
//! [`write_plot`] puts a top view beside the ATE over time; [`write_eval_plots`] writes every
//! figure of an `eval` run into one folder.

use std::path::{Path, PathBuf};

use image::{Rgb, RgbImage};
use plotters::coord::Shift;
use plotters::prelude::*;
use thiserror::Error;

use super::{AteResult, RpeResult, Stats};
use crate::draw::font::{register_plot_font, PLOT_FAMILY};
use crate::trajectory::Trajectory;

/// Width and height of one panel, pixels.
pub const PANEL_SIZE: u32 = 560;
/// Ground-truth colour.
pub const GT_COLOUR: Rgb<u8> = Rgb([31, 119, 180]);
/// Estimate colour.
pub const EST_COLOUR: Rgb<u8> = Rgb([255, 127, 14]);
/// Error-curve colour.
pub const ERROR_COLOUR: Rgb<u8> = Rgb([214, 39, 40]);
const MEAN_COLOUR: RGBColor = RGBColor(44, 160, 44);
const MEDIAN_COLOUR: RGBColor = RGBColor(148, 103, 189);
const HISTOGRAM_BINS: usize = 20;

/// Errors of the plot writers.
#[derive(Debug, Error)]
pub enum PlotError {
    /// Nothing to draw: both trajectories or the error series are empty.
    #[error("nothing to plot: {0}")]
    Empty(&'static str),
    /// A coordinate is NaN or infinite.
    #[error("a plotted value is not finite")]
    NotFinite,
    /// `plotters` failed to draw or to write an SVG file.
    #[error("drawing failed: {0}")]
    Draw(String),
    /// The PNG could not be written.
    #[error(transparent)]
    Image(#[from] image::ImageError),
    /// The output folder could not be created.
    #[error("{path}: {source}")]
    Io {
        /// The folder.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for PlotError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        PlotError::Draw(e.to_string())
    }
}

/// Which plane of the world a trajectory view shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum View {
    /// `x` right, `z` up the page (from above, for cameras with `y` down).
    Top,
    /// `z` right, `-y` up the page (from the side).
    Side,
}

impl View {
    fn project(self, p: &nalgebra::Isometry3<f64>) -> (f64, f64) {
        let v = p.translation.vector;
        match self {
            View::Top => (v.x, v.z),
            View::Side => (v.z, -v.y),
        }
    }

    fn axis_names(self) -> (&'static str, &'static str) {
        match self {
            View::Top => ("x (m)", "z (m)"),
            View::Side => ("z (m)", "height -y (m)"),
        }
    }
}

/// One error series over time for [`error_panel`] and [`histogram_panel`].
struct Series<'a> {
    /// `(timestamp s, error)`.
    points: Vec<(f64, f64)>,
    stats: &'a Stats,
    /// Axis name, e.g. `ATE (m)`.
    name: &'static str,
    /// Unit for the legend, e.g. `m`.
    unit: &'static str,
}

/// Writes the top view of `gt` (cropped to the span of `errors`) and `est` beside the ATE
/// over time, `2 PANEL_SIZE` x `PANEL_SIZE` pixels. `errors` holds `(ground-truth timestamp
/// s, translation error m)` and `est` the aligned estimate, e.g. [`AteResult::errors`] and
/// [`AteResult::aligned`]; `.svg` writes SVG, any other extension PNG.
pub fn write_plot(
    path: &Path,
    gt: &Trajectory,
    est: &Trajectory,
    errors: &[(f64, f64)],
) -> Result<(), PlotError> {
    let stats = check(gt, est, errors)?;
    let gt = crop(gt, errors);
    let ate = ate_series(errors, &stats);
    save(
        path,
        &[Panel::Trajectory(&gt, est, View::Top), Panel::Errors(&ate)],
    )
}

/// The picture of [`write_plot`] as an RGB image.
pub fn render_plot(
    gt: &Trajectory,
    est: &Trajectory,
    errors: &[(f64, f64)],
) -> Result<RgbImage, PlotError> {
    let stats = check(gt, est, errors)?;
    let gt = crop(gt, errors);
    let ate = ate_series(errors, &stats);
    render(&[Panel::Trajectory(&gt, est, View::Top), Panel::Errors(&ate)])
}

/// Picture format of [`write_eval_plots`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlotFormat {
    /// PNG raster.
    #[default]
    Png,
    /// SVG vector graphics.
    Svg,
}

/// Writes the figures of an evaluation into `dir` (created if needed) and returns their
/// paths: `trajectory_top`, `trajectory_side`, `ate` (over time), `rpe` (translation and
/// rotation over time) and `rpe_histogram`, each `.png` or `.svg`.
pub fn write_eval_plots(
    dir: &Path,
    format: PlotFormat,
    gt: &Trajectory,
    ate: &AteResult,
    rpe: &RpeResult,
) -> Result<Vec<PathBuf>, PlotError> {
    check(gt, &ate.aligned, &ate.errors)?;
    create_dir(dir)?;
    let ext = match format {
        PlotFormat::Png => "png",
        PlotFormat::Svg => "svg",
    };
    let file = |name: &str| dir.join(format!("{name}.{ext}"));
    let gt = crop(gt, &ate.errors);
    let ate_s = ate_series(&ate.errors, &ate.stats);
    let trans = Series {
        points: rpe
            .times
            .iter()
            .copied()
            .zip(rpe.translation_errors.iter().copied())
            .collect(),
        stats: &rpe.translation,
        name: "RPE translation (m)",
        unit: "m",
    };
    let rot = Series {
        points: rpe
            .times
            .iter()
            .copied()
            .zip(rpe.rotation_errors_deg.iter().copied())
            .collect(),
        stats: &rpe.rotation_deg,
        name: "RPE rotation (deg)",
        unit: "deg",
    };
    let paths = vec![
        file("trajectory_top"),
        file("trajectory_side"),
        file("ate"),
        file("rpe"),
        file("rpe_histogram"),
    ];
    let figures: [&[Panel]; 5] = [
        &[Panel::Trajectory(&gt, &ate.aligned, View::Top)],
        &[Panel::Trajectory(&gt, &ate.aligned, View::Side)],
        &[Panel::Errors(&ate_s)],
        &[Panel::Errors(&trans), Panel::Errors(&rot)],
        &[Panel::Histogram(&trans), Panel::Histogram(&rot)],
    ];
    for (path, panels) in paths.iter().zip(figures) {
        save(path, panels)?;
    }
    Ok(paths)
}

fn create_dir(dir: &Path) -> Result<(), PlotError> {
    std::fs::create_dir_all(dir).map_err(|source| PlotError::Io {
        path: dir.to_path_buf(),
        source,
    })
}

fn ate_series<'a>(errors: &[(f64, f64)], stats: &'a Stats) -> Series<'a> {
    Series {
        points: errors.to_vec(),
        stats,
        name: "ATE (m)",
        unit: "m",
    }
}

/// Validates the inputs of a trajectory-and-error figure; the statistics of the errors.
fn check(gt: &Trajectory, est: &Trajectory, errors: &[(f64, f64)]) -> Result<Stats, PlotError> {
    if gt.poses.is_empty() && est.poses.is_empty() {
        return Err(PlotError::Empty("both trajectories are empty"));
    }
    if errors.is_empty() {
        return Err(PlotError::Empty("no error values"));
    }
    let finite = |p: &nalgebra::Isometry3<f64>| p.translation.vector.iter().all(|v| v.is_finite());
    let poses_ok = gt
        .poses
        .iter()
        .chain(&est.poses)
        .all(|(t, p)| t.is_finite() && finite(p));
    let errors_ok = errors.iter().all(|(t, e)| t.is_finite() && e.is_finite());
    if !poses_ok || !errors_ok {
        return Err(PlotError::NotFinite);
    }
    let values: Vec<f64> = errors.iter().map(|e| e.1).collect();
    Stats::from_errors(&values).ok_or(PlotError::NotFinite)
}

/// The poses of `gt` within the time span of `errors` (the evaluated span).
fn crop(gt: &Trajectory, errors: &[(f64, f64)]) -> Trajectory {
    let (t0, t1) = min_max(errors.iter().map(|e| e.0));
    Trajectory::new(
        gt.poses
            .iter()
            .filter(|(t, _)| *t >= t0 && *t <= t1)
            .copied()
            .collect(),
    )
}

fn min_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    })
}

/// One panel of a figure.
enum Panel<'a> {
    /// Ground truth and estimate in one view.
    Trajectory(&'a Trajectory, &'a Trajectory, View),
    /// An error series over time.
    Errors(&'a Series<'a>),
    /// The distribution of an error series.
    Histogram(&'a Series<'a>),
}

/// Draws `panels` side by side, each `PANEL_SIZE` square.
fn draw_panels<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    panels: &[Panel],
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let areas = root.split_evenly((1, panels.len()));
    for (area, panel) in areas.iter().zip(panels) {
        match panel {
            Panel::Trajectory(gt, est, view) => trajectory_panel(area, gt, est, *view)?,
            Panel::Errors(series) => error_panel(area, series)?,
            Panel::Histogram(series) => histogram_panel(area, series)?,
        }
    }
    root.present()?;
    Ok(())
}

fn figure_size(panels: &[Panel]) -> (u32, u32) {
    (PANEL_SIZE * panels.len() as u32, PANEL_SIZE)
}

/// Writes `panels` as a PNG or SVG file at `path` (by its extension), creating its folder.
fn save(path: &Path, panels: &[Panel]) -> Result<(), PlotError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        create_dir(dir)?;
    }
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
    {
        register_plot_font();
        draw_panels(
            &SVGBackend::new(path, figure_size(panels)).into_drawing_area(),
            panels,
        )
    } else {
        render(panels)?.save(path)?;
        Ok(())
    }
}

/// Draws `panels` into an RGB image.
fn render(panels: &[Panel]) -> Result<RgbImage, PlotError> {
    register_plot_font();
    let (w, h) = figure_size(panels);
    let mut buffer = vec![0u8; w as usize * h as usize * 3];
    draw_panels(
        &BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area(),
        panels,
    )?;
    Ok(RgbImage::from_raw(w, h, buffer).expect("the buffer holds width x height RGB pixels"))
}

/// A colour for `plotters`.
fn rgb(c: Rgb<u8>) -> RGBColor {
    RGBColor(c.0[0], c.0[1], c.0[2])
}

/// Caption, label and tick fonts.
fn caption_font() -> TextStyle<'static> {
    (PLOT_FAMILY, 20).into_font().into()
}

fn label_font() -> TextStyle<'static> {
    (PLOT_FAMILY, 15).into_font().into()
}

/// A top or side view of `gt` and `est` with metric axes at equal scale and a legend.
fn trajectory_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    gt: &Trajectory,
    est: &Trajectory,
    view: View,
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    let gt_pts: Vec<(f64, f64)> = gt.poses.iter().map(|(_, p)| view.project(p)).collect();
    let est_pts: Vec<(f64, f64)> = est.poses.iter().map(|(_, p)| view.project(p)).collect();
    let (x0, x1) = min_max(gt_pts.iter().chain(&est_pts).map(|p| p.0));
    let (y0, y1) = min_max(gt_pts.iter().chain(&est_pts).map(|p| p.1));
    // Plot area in pixels: the panel minus margins (10), label areas (55 left, 45 below)
    // and the caption (~30); the ranges get the same metres per pixel on both axes.
    let (w, h) = area.dim_in_pixel();
    let (pw, ph) = ((w as f64 - 75.0).max(1.0), (h as f64 - 95.0).max(1.0));
    let scale = ((x1 - x0) / pw).max((y1 - y0) / ph).max(1e-6) * 1.1;
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (hx, hy) = (0.5 * scale * pw, 0.5 * scale * ph);
    let title = match view {
        View::Top => "Trajectory, top view",
        View::Side => "Trajectory, side view",
    };
    let mut chart = ChartBuilder::on(area)
        .caption(title, caption_font())
        .margin(10)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d(cx - hx..cx + hx, cy - hy..cy + hy)?;
    let (x_name, y_name) = view.axis_names();
    chart
        .configure_mesh()
        .x_desc(x_name)
        .y_desc(y_name)
        .label_style(label_font())
        .axis_desc_style(label_font())
        .light_line_style(WHITE.mix(0.0))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .draw()?;
    chart
        .draw_series(LineSeries::new(gt_pts, rgb(GT_COLOUR).stroke_width(1)))?
        .label("ground truth")
        .legend(|(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], rgb(GT_COLOUR).stroke_width(2))
        });
    chart
        .draw_series(LineSeries::new(est_pts, rgb(EST_COLOUR).stroke_width(1)))?
        .label("estimate (aligned)")
        .legend(|(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], rgb(EST_COLOUR).stroke_width(2))
        });
    legend(&mut chart)
}

/// An error series against seconds from its first sample, with mean and median lines.
fn error_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    series: &Series,
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    let (t0, t1) = min_max(series.points.iter().map(|p| p.0));
    let e_max = series.stats.max.max(1e-12) * 1.15;
    let mut chart = ChartBuilder::on(area)
        .caption(format!("{} over time", series.name), caption_font())
        .margin(10)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(0.0..(t1 - t0).max(1e-9), 0.0..e_max)?;
    chart
        .configure_mesh()
        .x_desc("time since first pose (s)")
        .y_desc(series.name)
        .label_style(label_font())
        .axis_desc_style(label_font())
        .light_line_style(WHITE.mix(0.0))
        .x_label_formatter(&|v| tick(*v))
        .y_label_formatter(&|v| tick(*v))
        .draw()?;
    let pts = series.points.iter().map(|&(t, e)| (t - t0, e));
    chart
        .draw_series(LineSeries::new(pts, rgb(ERROR_COLOUR).stroke_width(1)))?
        .label(series.name)
        .legend(|(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], rgb(ERROR_COLOUR).stroke_width(2))
        });
    let span = (t1 - t0).max(1e-9);
    for (value, name, colour) in [
        (series.stats.mean, "mean", MEAN_COLOUR),
        (series.stats.median, "median", MEDIAN_COLOUR),
    ] {
        chart
            .draw_series(LineSeries::new(
                [(0.0, value), (span, value)],
                colour.stroke_width(2),
            ))?
            .label(format!("{name} {}", short(value, series.unit)))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
    }
    legend(&mut chart)
}

/// The distribution of a series in [`HISTOGRAM_BINS`] bins from 0 to its maximum.
fn histogram_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    series: &Series,
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    let top = series.stats.max.max(1e-12);
    let width = top / HISTOGRAM_BINS as f64;
    let mut counts = [0u32; HISTOGRAM_BINS];
    for &(_, e) in &series.points {
        counts[((e / width) as usize).min(HISTOGRAM_BINS - 1)] += 1;
    }
    let highest = counts.iter().copied().max().unwrap_or(0).max(1);
    let mut chart = ChartBuilder::on(area)
        .caption(format!("{} histogram", series.name), caption_font())
        .margin(10)
        .margin_top(30)
        .x_label_area_size(45)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..top, 0u32..highest + highest / 10 + 1)?;
    chart
        .configure_mesh()
        .x_desc(series.name)
        .y_desc("pose pairs")
        .label_style(label_font())
        .axis_desc_style(label_font())
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    chart.draw_series(counts.iter().enumerate().map(|(k, &c)| {
        let a = k as f64 * width;
        Rectangle::new(
            [(a, 0), (a + width, c)],
            rgb(ERROR_COLOUR).mix(0.7).filled(),
        )
    }))?;
    let s = series.stats;
    let summary = format!(
        "n {}  mean {}  median {}",
        s.count,
        short(s.mean, series.unit),
        short(s.median, series.unit)
    );
    area.draw(&Text::new(summary, (70, 36), label_font()))?;
    Ok(())
}

fn legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .label_font(label_font())
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    Ok(())
}

/// An axis tick label: the value rounded to 1e-9 in its shortest form, never `-0`.
fn tick(v: f64) -> String {
    format!("{}", (v * 1e9).round() / 1e9 + 0.0)
}

/// A value with four significant digits and its unit.
fn short(v: f64, unit: &str) -> String {
    let digits = if v == 0.0 {
        3
    } else {
        (3 - v.abs().log10().floor() as i32).clamp(0, 9) as usize
    };
    format!("{v:.digits$} {unit}")
}
