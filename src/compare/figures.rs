//! The pictures of a comparison as SVG text (for the inline figures of [`super::html`]),
//! drawn with `plotters`, one colour per tracker:
//!
//! - [`trajectories`]: the top view (world `x` right, `z` up the page, equal scale) of the
//!   ground truth and each tracker's trajectory after its ATE alignment;
//! - [`errors`]: each posed frame's distance from the ground truth after that alignment
//!   (metres) against the frame index; lines break where a tracker has no pose;
//! - [`support`]: the feature trackers' inliers (correspondences) beside the direct
//!   trackers' photometric residual RMSE (grey levels), against the frame index.

use plotters::coord::Shift;
use plotters::prelude::*;

use super::{CompareReport, TrackerResult};
use crate::draw::font::{register_plot_font, PLOT_FAMILY};
use crate::eval::plot::PlotError;
use crate::odometry::registry::Paradigm;

/// Width and height of one panel, pixels.
const PANEL: (u32, u32) = (640, 420);

/// Tracker colours, in the order of the report (repeated beyond ten).
const PALETTE: [RGBColor; 10] = [
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(31, 119, 180),
];

/// Ground-truth colour.
const GT: RGBColor = RGBColor(0, 0, 0);

/// The colour of the `i`-th tracker of a report.
pub fn colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// One named line of a panel: its colour and its pieces (a break between pieces where the
/// tracker has no value).
struct Line {
    name: String,
    colour: RGBColor,
    pieces: Vec<Vec<(f64, f64)>>,
}

/// A panel: a caption, axis names and its lines.
struct Panel {
    caption: &'static str,
    x_desc: &'static str,
    y_desc: &'static str,
    lines: Vec<Line>,
    /// Same metres per pixel on both axes (a map view).
    equal_scale: bool,
}

/// Consecutive runs of `Some` values of `points` as pieces.
fn pieces(points: impl Iterator<Item = Option<(f64, f64)>>) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    let mut current = Vec::new();
    for p in points {
        match p {
            Some(p) => current.push(p),
            None if !current.is_empty() => out.push(std::mem::take(&mut current)),
            None => {}
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// The trackers that ran, with their colour.
fn ran(report: &CompareReport) -> impl Iterator<Item = (RGBColor, &TrackerResult)> {
    report
        .trackers
        .iter()
        .enumerate()
        .map(|(i, t)| (colour(i), t))
}

/// The top view of the ground truth and every aligned trajectory.
pub fn trajectories(report: &CompareReport) -> Result<String, PlotError> {
    let top = |p: &nalgebra::Isometry3<f64>| (p.translation.vector.x, p.translation.vector.z);
    let mut lines: Vec<Line> = report
        .ground_truth_trajectory
        .iter()
        .map(|gt| Line {
            name: "ground truth".into(),
            colour: GT,
            pieces: vec![gt.poses.iter().map(|(_, p)| top(p)).collect()],
        })
        .collect();
    for (colour, t) in ran(report) {
        if let Some(aligned) = &t.aligned {
            lines.push(Line {
                name: format!("{} ({})", t.method.name(), t.alignment),
                colour,
                pieces: vec![aligned.poses.iter().map(|(_, p)| top(p)).collect()],
            });
        }
    }
    svg(&[Panel {
        caption: "Trajectories, top view (aligned)",
        x_desc: "x (m)",
        y_desc: "z (m)",
        lines,
        equal_scale: true,
    }])
}

/// Each tracker's per-frame error after its alignment against the frame index.
pub fn errors(report: &CompareReport) -> Result<String, PlotError> {
    let lines = ran(report)
        .filter_map(|(colour, t)| {
            let run = t.run.as_ref()?;
            let points = run
                .series
                .iter()
                .map(|p| p.error_m.map(|e| (p.index as f64, e)));
            Some(Line {
                name: t.method.name().into(),
                colour,
                pieces: pieces(points),
            })
        })
        .collect();
    svg(&[Panel {
        caption: "Error against the ground truth (aligned)",
        x_desc: "frame",
        y_desc: "error (m)",
        lines,
        equal_scale: false,
    }])
}

/// The feature trackers' inliers beside the direct trackers' photometric residual.
pub fn support(report: &CompareReport) -> Result<String, PlotError> {
    let of = |paradigm: Paradigm, value: fn(&super::FramePoint) -> f64| {
        ran(report)
            .filter(|(_, t)| t.paradigm == paradigm)
            .filter_map(|(colour, t)| {
                let run = t.run.as_ref()?;
                let points = run.series.iter().map(|p| {
                    let posed = p.status != "lost" && p.status != "unreadable";
                    posed.then(|| (p.index as f64, value(p)))
                });
                Some(Line {
                    name: t.method.name().into(),
                    colour,
                    pieces: pieces(points),
                })
            })
            .collect::<Vec<Line>>()
    };
    svg(&[
        Panel {
            caption: "Feature trackers: inliers",
            x_desc: "frame",
            y_desc: "inlier correspondences",
            lines: of(Paradigm::Feature, |p| p.inliers as f64),
            equal_scale: false,
        },
        Panel {
            caption: "Direct trackers: photometric residual",
            x_desc: "frame",
            y_desc: "residual RMSE (grey levels)",
            lines: of(Paradigm::Direct, |p| p.residual),
            equal_scale: false,
        },
    ])
}

/// `panels` side by side as SVG text.
fn svg(panels: &[Panel]) -> Result<String, PlotError> {
    let all = || {
        panels
            .iter()
            .flat_map(|p| &p.lines)
            .flat_map(|l| &l.pieces)
            .flatten()
    };
    if all().next().is_none() {
        return Err(PlotError::Empty("no tracker has a value to draw"));
    }
    if !all().all(|(x, y)| x.is_finite() && y.is_finite()) {
        return Err(PlotError::NotFinite);
    }
    register_plot_font();
    let mut text = String::new();
    {
        let size = (PANEL.0 * panels.len() as u32, PANEL.1);
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        root.fill(&WHITE)?;
        for (area, panel) in root.split_evenly((1, panels.len())).iter().zip(panels) {
            draw(area, panel)?;
        }
        root.present()?;
    }
    Ok(text)
}

fn min_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    })
}

/// Draws one panel (an empty one says so in its caption).
fn draw<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, panel: &Panel) -> Result<(), PlotError>
where
    DB::ErrorType: 'static,
{
    let points = || panel.lines.iter().flat_map(|l| &l.pieces).flatten();
    let (mut x0, mut x1) = min_max(points().map(|p| p.0));
    let (mut y0, mut y1) = min_max(points().map(|p| p.1));
    let caption = if x0.is_finite() {
        panel.caption.to_string()
    } else {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        format!("{} (none)", panel.caption)
    };
    if panel.equal_scale {
        let (w, h) = area.dim_in_pixel();
        let (pw, ph) = (
            (f64::from(w) - 75.0).max(1.0),
            (f64::from(h) - 95.0).max(1.0),
        );
        let scale = ((x1 - x0) / pw).max((y1 - y0) / ph).max(1e-6) * 1.1;
        let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        (x0, x1, y0, y1) = (
            cx - 0.5 * scale * pw,
            cx + 0.5 * scale * pw,
            cy - 0.5 * scale * ph,
            cy + 0.5 * scale * ph,
        );
    } else {
        y0 = y0.min(0.0);
        y1 = y1.max(y0 + 1e-9) * 1.1;
        x1 = x1.max(x0 + 1.0);
    }
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (PLOT_FAMILY, 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_desc)
        .y_desc(panel.y_desc)
        .label_style((PLOT_FAMILY, 13))
        .axis_desc_style((PLOT_FAMILY, 14))
        .light_line_style(WHITE.mix(0.0))
        .draw()?;
    for line in &panel.lines {
        let colour = line.colour;
        for (k, piece) in line.pieces.iter().enumerate() {
            let series = chart.draw_series(LineSeries::new(
                piece.iter().copied(),
                colour.stroke_width(2),
            ))?;
            if k == 0 {
                series.label(line.name.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                });
            }
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((PLOT_FAMILY, 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_break_where_values_are_missing() {
        let points = [
            Some((0.0, 1.0)),
            Some((1.0, 2.0)),
            None,
            None,
            Some((4.0, 0.5)),
            None,
        ];
        assert_eq!(
            pieces(points.into_iter()),
            vec![vec![(0.0, 1.0), (1.0, 2.0)], vec![(4.0, 0.5)]]
        );
        assert!(pieces([None, None].into_iter()).is_empty());
    }
}
