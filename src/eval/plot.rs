//! A two-panel PNG of an evaluated trajectory, drawn with the `image` crate only.
//!
//! Left: top view of the ground truth (blue) and the aligned estimate (orange) in the world
//! `x`-`z` plane (`x` to the right, `z` up the page, equal scale on both axes; cameras move
//! in `x`/`z` with `y` down). Right: the ATE translation error (red) against time, with axes
//! from `(t_first, 0 m)` and five ticks each. Two coloured boxes in the top-left corner give
//! the colour key (`GT`, `EST`). Labels in a 5x7 bitmap font give the side of the top-view
//! square, the largest error and the time span.

use std::path::Path;

use image::{Rgb, RgbImage};
use thiserror::Error;

use crate::draw::{metres_label, text};
use crate::trajectory::Trajectory;

/// Width and height of one panel, pixels.
pub const PANEL_SIZE: u32 = 500;
/// Margin between a panel border and its plot area, pixels.
const MARGIN: f64 = 40.0;
const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const GREY: Rgb<u8> = Rgb([160, 160, 160]);
const BLACK: Rgb<u8> = Rgb([0, 0, 0]);
/// Ground-truth colour.
pub const GT_COLOUR: Rgb<u8> = Rgb([31, 119, 180]);
/// Estimate colour.
pub const EST_COLOUR: Rgb<u8> = Rgb([255, 127, 14]);
/// Error-curve colour.
pub const ERROR_COLOUR: Rgb<u8> = Rgb([214, 39, 40]);

/// Errors of [`write_plot`].
#[derive(Debug, Error)]
pub enum PlotError {
    /// Nothing to draw: both trajectories or the error series are empty.
    #[error("nothing to plot: {0}")]
    Empty(&'static str),
    /// A coordinate is NaN or infinite.
    #[error("a plotted value is not finite")]
    NotFinite,
    /// The PNG could not be written.
    #[error(transparent)]
    Image(#[from] image::ImageError),
}

/// Draws the plot (see the module documentation) and saves it as a PNG at `path`.
/// `errors` holds `(timestamp seconds, translation error metres)`, e.g.
/// [`AteResult::errors`](super::AteResult::errors); `est` should be the aligned estimate
/// ([`AteResult::aligned`](super::AteResult::aligned)).
pub fn write_plot(
    path: &Path,
    gt: &Trajectory,
    est: &Trajectory,
    errors: &[(f64, f64)],
) -> Result<(), PlotError> {
    render_plot(gt, est, errors)?.save(path)?;
    Ok(())
}

/// The plot of [`write_plot`] as an image, `2 PANEL_SIZE` x `PANEL_SIZE` pixels.
pub fn render_plot(
    gt: &Trajectory,
    est: &Trajectory,
    errors: &[(f64, f64)],
) -> Result<RgbImage, PlotError> {
    let top = |t: &Trajectory| -> Vec<(f64, f64)> {
        t.poses
            .iter()
            .map(|(_, p)| (p.translation.vector.x, p.translation.vector.z))
            .collect()
    };
    let (gt_xz, est_xz) = (top(gt), top(est));
    if gt_xz.is_empty() && est_xz.is_empty() {
        return Err(PlotError::Empty("both trajectories are empty"));
    }
    if errors.is_empty() {
        return Err(PlotError::Empty("no error values"));
    }
    let all = gt_xz.iter().chain(&est_xz).chain(errors);
    if all.clone().any(|(a, b)| !a.is_finite() || !b.is_finite()) {
        return Err(PlotError::NotFinite);
    }
    let mut img = RgbImage::from_pixel(2 * PANEL_SIZE, PANEL_SIZE, WHITE);
    let size = PANEL_SIZE as f64;
    let plot_span = size - 2.0 * MARGIN;

    // Left panel: equal-scale top view.
    let bounds = Bounds::of(gt_xz.iter().chain(&est_xz));
    let span = bounds.width().max(bounds.height()).max(1e-9);
    let (cx, cz) = bounds.centre();
    let to_px = |(x, z): (f64, f64)| {
        (
            size / 2.0 + (x - cx) / span * plot_span,
            size / 2.0 - (z - cz) / span * plot_span,
        )
    };
    frame(&mut img, 0.0);
    polyline(&mut img, gt_xz.iter().map(|&p| to_px(p)), GT_COLOUR);
    polyline(&mut img, est_xz.iter().map(|&p| to_px(p)), EST_COLOUR);
    fill_box(&mut img, 10, 10, 14, GT_COLOUR);
    text(&mut img, (28, 13), "GT", 1, BLACK);
    fill_box(&mut img, 50, 10, 14, EST_COLOUR);
    text(&mut img, (68, 13), "EST", 1, BLACK);
    let side = format!("X-Z SIDE {}", metres_label(span));
    text(&mut img, (10, PANEL_SIZE as i64 - 20), &side, 1, BLACK);

    // Right panel: error against time, axes from (t_first, 0).
    let eb = Bounds::of(errors.iter());
    let (t0, t_span) = (eb.min.0, eb.width().max(1e-9));
    let e_max = eb.max.1.max(1e-12);
    let (left, bottom) = (size + MARGIN, size - MARGIN);
    let to_px = |(t, e): (f64, f64)| {
        (
            left + (t - t0) / t_span * plot_span,
            bottom - e / e_max * plot_span,
        )
    };
    frame(&mut img, size);
    line(&mut img, (left, bottom), (left + plot_span, bottom), BLACK);
    line(&mut img, (left, bottom), (left, bottom - plot_span), BLACK);
    for k in 0..=5 {
        let f = k as f64 / 5.0 * plot_span;
        line(
            &mut img,
            (left + f, bottom),
            (left + f, bottom + 6.0),
            BLACK,
        );
        line(
            &mut img,
            (left, bottom - f),
            (left - 6.0, bottom - f),
            BLACK,
        );
    }
    polyline(&mut img, errors.iter().map(|&p| to_px(p)), ERROR_COLOUR);
    let top = (left as i64, (bottom - plot_span) as i64 - 14);
    text(
        &mut img,
        top,
        &format!("ATE MAX {}", metres_label(e_max)),
        1,
        BLACK,
    );
    text(
        &mut img,
        ((left - 14.0) as i64, bottom as i64 - 3),
        "0",
        1,
        BLACK,
    );
    let time = format!("T {t_span:.1} S");
    text(
        &mut img,
        (
            (left + plot_span) as i64 - 6 * time.len() as i64,
            bottom as i64 + 12,
        ),
        &time,
        1,
        BLACK,
    );
    Ok(img)
}

/// Axis-aligned bounds of 2D points.
struct Bounds {
    min: (f64, f64),
    max: (f64, f64),
}

impl Bounds {
    fn of<'a>(points: impl Iterator<Item = &'a (f64, f64)>) -> Self {
        points.fold(
            Self {
                min: (f64::INFINITY, f64::INFINITY),
                max: (f64::NEG_INFINITY, f64::NEG_INFINITY),
            },
            |b, &(x, y)| Self {
                min: (b.min.0.min(x), b.min.1.min(y)),
                max: (b.max.0.max(x), b.max.1.max(y)),
            },
        )
    }

    fn width(&self) -> f64 {
        self.max.0 - self.min.0
    }

    fn height(&self) -> f64 {
        self.max.1 - self.min.1
    }

    fn centre(&self) -> (f64, f64) {
        (
            0.5 * (self.min.0 + self.max.0),
            0.5 * (self.min.1 + self.max.1),
        )
    }
}

/// A grey border around the panel starting at column `x0`.
fn frame(img: &mut RgbImage, x0: f64) {
    let s = PANEL_SIZE as f64 - 1.0;
    let corners = [(x0, 0.0), (x0 + s, 0.0), (x0 + s, s), (x0, s), (x0, 0.0)];
    polyline(img, corners.into_iter(), GREY);
}

fn fill_box(img: &mut RgbImage, x: u32, y: u32, side: u32, colour: Rgb<u8>) {
    for yy in y..y + side {
        for xx in x..x + side {
            img.put_pixel(xx, yy, colour);
        }
    }
}

fn polyline(img: &mut RgbImage, points: impl Iterator<Item = (f64, f64)>, colour: Rgb<u8>) {
    let mut prev = None;
    for p in points {
        if let Some(q) = prev {
            line(img, q, p, colour);
        }
        prev = Some(p);
    }
}

/// A line between pixel positions, clipped to the image ([`crate::draw::line`]).
fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), colour: Rgb<u8>) {
    crate::draw::line(
        img,
        (a.0 as f32, a.1 as f32),
        (b.0 as f32, b.1 as f32),
        colour,
    );
}
