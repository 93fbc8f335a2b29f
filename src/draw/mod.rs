//! Pictures a person can check at a glance: keypoints, matches side by side, difference images
//! and residual maps. Plain raster drawing on `image::RgbImage`, nothing more.

mod font;

use image::{GrayImage, Rgb, RgbImage};

/// Green: inliers and keypoints.
pub const GREEN: Rgb<u8> = Rgb([40, 220, 60]);
/// Red: outliers.
pub const RED: Rgb<u8> = Rgb([230, 40, 40]);
/// Yellow: highlights.
pub const YELLOW: Rgb<u8> = Rgb([250, 220, 40]);

/// A grey image as RGB.
pub fn to_rgb(img: &GrayImage) -> RgbImage {
    RgbImage::from_fn(img.width(), img.height(), |x, y| {
        let g = img.get_pixel(x, y)[0];
        Rgb([g, g, g])
    })
}

fn put(img: &mut RgbImage, x: i64, y: i64, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, c);
    }
}

/// A one-pixel line from `a` to `b` (Bresenham), clipped to the image.
pub fn line(img: &mut RgbImage, a: (f32, f32), b: (f32, f32), c: Rgb<u8>) {
    let (mut x0, mut y0) = (a.0.round() as i64, a.1.round() as i64);
    let (x1, y1) = (b.0.round() as i64, b.1.round() as i64);
    let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
    let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
    let mut err = dx + dy;
    loop {
        put(img, x0, y0, c);
        if x0 == x1 && y0 == y1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x0 += sx;
        }
        if e2 <= dx {
            err += dx;
            y0 += sy;
        }
    }
}

/// A circle outline of radius `r` pixels around `center`.
pub fn circle(img: &mut RgbImage, center: (f32, f32), r: f32, c: Rgb<u8>) {
    let steps = (r * 8.0).max(12.0) as usize;
    for k in 0..steps {
        let (s0, c0) = (k as f32 / steps as f32 * std::f32::consts::TAU).sin_cos();
        let (s1, c1) = ((k + 1) as f32 / steps as f32 * std::f32::consts::TAU).sin_cos();
        line(
            img,
            (center.0 + r * c0, center.1 + r * s0),
            (center.0 + r * c1, center.1 + r * s1),
            c,
        );
    }
}

/// Keypoints drawn as circles (radius grows with the pyramid scale) on a grey image.
pub fn keypoints(img: &GrayImage, points: &[(f32, f32, f32)]) -> RgbImage {
    let mut out = to_rgb(img);
    for &(x, y, scale) in points {
        circle(&mut out, (x, y), 3.0 * scale, GREEN);
    }
    out
}

/// A match to draw: position in image 1, position in image 2 (pixels), inlier or not.
pub type MatchLine = ((f32, f32), (f32, f32), bool);

/// Two images side by side with a line per match, green for inliers and red for outliers.
pub fn matches(img1: &GrayImage, img2: &GrayImage, pairs: &[MatchLine]) -> RgbImage {
    let (w1, w2) = (img1.width(), img2.width());
    let h = img1.height().max(img2.height());
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

/// A heat image of non-negative values: black at 0, white at `max` and above, and a dark blue
/// where the value is NaN (no data).
pub fn heat(width: u32, height: u32, values: &[f32], max: f32) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        let v = values[(y * width + x) as usize];
        if v.is_nan() {
            Rgb([0, 0, 60])
        } else {
            let g = (v / max.max(f32::MIN_POSITIVE) * 255.0).clamp(0.0, 255.0) as u8;
            Rgb([g, g, g])
        }
    })
}

/// Writes `text` with its top-left corner at `(x, y)` in the 5x7 font, each font pixel drawn
/// as a `scale x scale` block; characters the font lacks are left blank. Upper-case labels only.
pub fn text(img: &mut RgbImage, (x, y): (i64, i64), text: &str, scale: i64, c: Rgb<u8>) {
    for (k, ch) in text.chars().enumerate() {
        let Some(rows) = font::glyph(ch) else {
            continue;
        };
        let x0 = x + k as i64 * 6 * scale;
        for (r, bits) in rows.iter().enumerate() {
            for col in 0..5 {
                if bits & (0x10 >> col) != 0 {
                    for (dy, dx) in (0..scale).flat_map(|dy| (0..scale).map(move |dx| (dy, dx))) {
                        put(img, x0 + col * scale + dx, y + r as i64 * scale + dy, c);
                    }
                }
            }
        }
    }
}

/// A length in metres as a short upper-case label: millimetres below 10 cm.
pub fn metres_label(v: f64) -> String {
    if v.abs() < 0.1 {
        format!("{:.2} MM", v * 1e3)
    } else {
        format!("{v:.3} M")
    }
}
