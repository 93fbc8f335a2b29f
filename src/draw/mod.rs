//! Pictures a person can check at a glance: keypoints, matches side by side, difference images
//! and residual maps, each with a caption or a colour bar. Shapes and text are drawn with
//! `imageproc` (text in the embedded DejaVu Sans, [`font`]).

pub mod font;

use ab_glyph::PxScale;
use image::{Rgb, RgbImage};
use imageproc::drawing::{
    draw_filled_rect_mut, draw_hollow_circle_mut, draw_hollow_rect_mut, draw_line_segment_mut,
    draw_text_mut, text_size,
};
use imageproc::rect::Rect;
use vofront_image::Image;

/// Green: inliers and keypoints.
pub const GREEN: Rgb<u8> = Rgb([40, 220, 60]);
/// Red: outliers.
pub const RED: Rgb<u8> = Rgb([230, 40, 40]);
/// Yellow: highlights.
pub const YELLOW: Rgb<u8> = Rgb([250, 220, 40]);
/// Dark blue: pixels of a heat map without data (NaN).
pub const NO_DATA: Rgb<u8> = Rgb([0, 0, 60]);
const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
const BLACK: Rgb<u8> = Rgb([0, 0, 0]);
const BAND: Rgb<u8> = Rgb([30, 30, 30]);
/// Text height of captions and colour-bar labels, pixels.
const TEXT_PX: f32 = 16.0;
/// Width of the legend strip right of a heat map, pixels.
const BAR_STRIP: u32 = 150;

/// A grey image as RGB (the grey level in all three channels).
pub fn to_rgb(img: &Image<u8>) -> RgbImage {
    RgbImage::from_fn(img.width() as u32, img.height() as u32, |x, y| {
        let g = img.at(x as usize, y as usize);
        Rgb([g, g, g])
    })
}

/// A one-pixel line from `a` to `b` (pixel positions), clipped to the image.
pub fn line(img: &mut RgbImage, a: (f32, f32), b: (f32, f32), c: Rgb<u8>) {
    draw_line_segment_mut(img, a, b, c);
}

/// A circle outline of radius `r` pixels around `center`.
pub fn circle(img: &mut RgbImage, center: (f32, f32), r: f32, c: Rgb<u8>) {
    let centre = (center.0.round() as i32, center.1.round() as i32);
    draw_hollow_circle_mut(img, centre, r.round().max(1.0) as i32, c);
}

/// Writes `text` in DejaVu Sans, `height` pixels high, with its top-left corner at `(x, y)`.
pub fn text(img: &mut RgbImage, (x, y): (i32, i32), text: &str, height: f32, c: Rgb<u8>) {
    draw_text_mut(img, c, x, y, PxScale::from(height), &font::font(), text);
}

/// `img` below a dark band holding `lines` of white text (one caption line each).
pub fn with_caption(img: &RgbImage, lines: &[String]) -> RgbImage {
    let line_h = TEXT_PX as u32 + 6;
    let band = 6 + line_h * lines.len() as u32;
    let mut out = RgbImage::from_pixel(img.width(), img.height() + band, BAND);
    image::imageops::replace(&mut out, img, 0, band as i64);
    for (k, l) in lines.iter().enumerate() {
        text(
            &mut out,
            (6, 4 + (k as u32 * line_h) as i32),
            l,
            TEXT_PX,
            WHITE,
        );
    }
    out
}

/// Keypoints drawn as circles (radius grows with the pyramid scale) on a grey image, with a
/// caption giving their number.
pub fn keypoints(img: &Image<u8>, points: &[(f32, f32, f32)]) -> RgbImage {
    let mut out = to_rgb(img);
    for &(x, y, scale) in points {
        circle(&mut out, (x, y), 3.0 * scale, GREEN);
    }
    let caption = format!(
        "{} ORB keypoints (green circles, radius 3 px x pyramid scale)",
        points.len()
    );
    with_caption(&out, &[caption])
}

/// A match to draw: position in image 1, position in image 2 (pixels), inlier or not.
pub type MatchLine = ((f32, f32), (f32, f32), bool);

/// Two images side by side with a line per match, green for inliers and red for outliers
/// (add a caption with [`with_caption`]).
pub fn matches(img1: &Image<u8>, img2: &Image<u8>, pairs: &[MatchLine]) -> RgbImage {
    let (w1, w2) = (img1.width() as u32, img2.width() as u32);
    let h = img1.height().max(img2.height()) as u32;
    let mut out = RgbImage::new(w1 + w2, h);
    image::imageops::replace(&mut out, &to_rgb(img1), 0, 0);
    image::imageops::replace(&mut out, &to_rgb(img2), w1 as i64, 0);
    // Outliers first so that inliers stay visible on top.
    for inlier_pass in [false, true] {
        for &(a, b, inlier) in pairs.iter().filter(|p| p.2 == inlier_pass) {
            let colour = if inlier { GREEN } else { RED };
            line(&mut out, a, (b.0 + w1 as f32, b.1), colour);
        }
    }
    out
}

/// The grey level of `v` on a scale from 0 (black) to `max` (white), saturating.
fn grey(v: f32, max: f32) -> Rgb<u8> {
    let g = (v / max.max(f32::MIN_POSITIVE) * 255.0).clamp(0.0, 255.0) as u8;
    Rgb([g, g, g])
}

/// A heat map of non-negative intensity differences (grey levels, row-major `width x
/// height` values): black at 0, white at `max` and above, [`NO_DATA`] where a value is NaN.
/// A strip on the right holds the colour bar with its scale and the "no data" legend.
///
/// ```
/// let img = vofront::draw::heat(4, 2, &[0.0, 8.0, 16.0, f32::NAN, 0.0, 0.0, 0.0, 0.0], 16.0);
/// assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
/// assert_eq!(img.get_pixel(2, 0).0, [255, 255, 255]);
/// assert_eq!(*img.get_pixel(3, 0), vofront::draw::NO_DATA);
/// ```
pub fn heat(width: u32, height: u32, values: &[f32], max: f32) -> RgbImage {
    let mut out = RgbImage::from_pixel(width + BAR_STRIP, height.max(200), WHITE);
    for (i, v) in values.iter().take((width * height) as usize).enumerate() {
        let (x, y) = (i as u32 % width, i as u32 / width);
        let c = if v.is_nan() { NO_DATA } else { grey(*v, max) };
        out.put_pixel(x, y, c);
    }
    colour_bar(&mut out, width + 12, max);
    out
}

/// The colour bar of [`heat`] at column `x0`: a vertical gradient from `max` (top) to 0 with
/// five labelled ticks, its quantity, and a [`NO_DATA`] swatch.
fn colour_bar(img: &mut RgbImage, x0: u32, max: f32) {
    let (top, bar_w) = (60u32, 18u32);
    let bar_h = img.height().saturating_sub(top + 50).max(40);
    text(img, (x0 as i32, 6), "|difference|", TEXT_PX, BLACK);
    text(img, (x0 as i32, 26), "(grey levels)", TEXT_PX, BLACK);
    for dy in 0..bar_h {
        let v = max * (1.0 - dy as f32 / (bar_h - 1) as f32);
        for dx in 0..bar_w {
            img.put_pixel(x0 + dx, top + dy, grey(v, max));
        }
    }
    draw_hollow_rect_mut(
        img,
        Rect::at(x0 as i32, top as i32).of_size(bar_w, bar_h),
        BLACK,
    );
    for k in 0..=4 {
        let y = top + (bar_h - 1) * k / 4;
        let v = max * (1.0 - k as f32 / 4.0);
        let label = if k == 0 {
            format!(">= {v:.0}")
        } else {
            format!("{v:.0}")
        };
        line(
            img,
            ((x0 + bar_w) as f32, y as f32),
            ((x0 + bar_w + 4) as f32, y as f32),
            BLACK,
        );
        let (_, th) = text_size(PxScale::from(TEXT_PX), &font::font(), &label);
        text(
            img,
            ((x0 + bar_w + 7) as i32, y as i32 - th as i32 / 2 - 2),
            &label,
            TEXT_PX,
            BLACK,
        );
    }
    let legend_y = top + bar_h + 16;
    draw_filled_rect_mut(
        img,
        Rect::at(x0 as i32, legend_y as i32).of_size(bar_w, 14),
        NO_DATA,
    );
    text(
        img,
        ((x0 + bar_w + 7) as i32, legend_y as i32 - 2),
        "no data",
        TEXT_PX,
        BLACK,
    );
}
