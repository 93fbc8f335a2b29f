//! Point selection for a monocular keyframe, DSO-style: the image is cut into square blocks of
//! `block` pixels, and each block keeps its pixel of largest squared gradient
//! `|grad I|^2 = g_x^2 + g_y^2` (central differences) among those with
//! `|grad I| >= gradient_threshold`. A block with no such pixel looks at the coarser pyramid
//! levels (factor 2, pixel `x_l` at level-0 pixel `2^l x_l`), where smooth gradients are
//! steeper per pixel, so that weakly textured regions still get a point: the spread over the
//! image is kept where level 0 alone would leave holes.

use nalgebra::Vector2;
use vofront_image::Image;

use crate::error::DirectError;

/// Settings of [`select_points`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectConfig {
    /// Side of a block at full resolution, pixels (one point per block at most).
    pub block: usize,
    /// Smallest gradient magnitude of a selected pixel, grey levels per pixel (at each level).
    pub gradient_threshold: f32,
    /// Pyramid levels looked at (1: full resolution only).
    pub levels: usize,
    /// Pixels closer than this to the border are not selected, pixels of level 0.
    pub border: usize,
}

impl Default for SelectConfig {
    fn default() -> Self {
        Self {
            block: 12,
            gradient_threshold: 6.0,
            levels: 3,
            border: 4,
        }
    }
}

/// A selected pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Pixel at full resolution.
    pub pixel: Vector2<f32>,
    /// Gradient at the level it was selected at, grey levels per pixel of that level.
    pub gradient: Vector2<f32>,
    /// The pyramid level it was selected at.
    pub level: usize,
}

/// The best pixel of level image `img` in the level-0 block `[x0, x0 + side) x [y0, y0 +
/// side)` (with `border` level-0 pixels kept clear), by squared gradient above `t2`.
fn best_in_block(
    img: &Image<f32>,
    level: usize,
    (x0, y0, side): (usize, usize, usize),
    border: usize,
    t2: f32,
) -> Option<Candidate> {
    let s = 1usize << level;
    let (w, h) = img.size();
    let lo = |v: usize| (v.max(border)).div_ceil(s).max(1);
    let hi = |v: usize, n: usize, full: usize| ((v.min(full - border)) / s).min(n - 1);
    let (fw, fh) = (w * s, h * s);
    let (xa, xb) = (lo(x0), hi(x0 + side, w, fw));
    let (ya, yb) = (lo(y0), hi(y0 + side, h, fh));
    let mut best: Option<(f32, Candidate)> = None;
    for y in ya..yb {
        for x in xa..xb {
            let gx = 0.5 * (img.at(x + 1, y) - img.at(x - 1, y));
            let gy = 0.5 * (img.at(x, y + 1) - img.at(x, y - 1));
            let g2 = gx * gx + gy * gy;
            if g2 >= t2 && best.is_none_or(|b| g2 > b.0) {
                let pixel = Vector2::new((x * s) as f32, (y * s) as f32);
                let gradient = Vector2::new(gx, gy);
                best = Some((
                    g2,
                    Candidate {
                        pixel,
                        gradient,
                        level,
                    },
                ));
            }
        }
    }
    best.map(|b| b.1)
}

/// One point per block (module documentation), row-major over the blocks.
///
/// Errors: [`DirectError::InvalidConfig`] for a zero block or level count,
/// [`DirectError::ImageTooSmall`] for an image with a side under `2 block`.
pub fn select_points(img: &Image<f32>, cfg: &SelectConfig) -> Result<Vec<Candidate>, DirectError> {
    if cfg.block == 0 || cfg.levels == 0 {
        return Err(DirectError::InvalidConfig(
            "block and levels must be positive",
        ));
    }
    img.check_min_size(2 * cfg.block.max(cfg.border + 2))?;
    let coarse = img.coarser_levels(cfg.levels, 8);
    let levels: Vec<&Image<f32>> = std::iter::once(img).chain(&coarse).collect();
    let t2 = cfg.gradient_threshold * cfg.gradient_threshold;
    let (w, h) = img.size();
    let mut out = Vec::new();
    for y0 in (0..h).step_by(cfg.block) {
        for x0 in (0..w).step_by(cfg.block) {
            let found = levels.iter().enumerate().find_map(|(l, level)| {
                best_in_block(level, l, (x0, y0, cfg.block), cfg.border, t2)
            });
            out.extend(found.filter(|c| c.gradient.iter().all(|g| g.is_finite())));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vertical step edge at x = 20 and a flat rest: each block row crossing the edge keeps
    /// one point on it; flat blocks keep none.
    #[test]
    fn each_block_keeps_its_strongest_pixel() {
        let data = (0..64 * 48)
            .map(|i| if i % 64 < 20 { 50.0 } else { 150.0 })
            .collect();
        let img = Image::new(64, 48, data).unwrap();
        let cfg = SelectConfig {
            levels: 1,
            ..SelectConfig::default()
        };
        let points = select_points(&img, &cfg).unwrap();
        assert_eq!(points.len(), 4, "{points:?}");
        for p in &points {
            assert!(p.pixel.x == 19.0 || p.pixel.x == 20.0, "{p:?}");
            assert!(p.gradient.x > 40.0 && p.gradient.y == 0.0);
        }
    }

    /// A gentle ramp (1.2 grey levels per pixel along x and y) is under the threshold at full
    /// resolution and at level 1, and above it at level 2: the coarse levels fill the blocks.
    #[test]
    fn weak_gradients_are_found_at_coarser_levels() {
        let data = (0..96 * 96)
            .map(|i| ((i % 96) + (i / 96)) as f32 * 1.2)
            .collect();
        let img = Image::new(96, 96, data).unwrap();
        let points = select_points(&img, &SelectConfig::default()).unwrap();
        assert!(!points.is_empty());
        assert!(points.iter().all(|p| p.level > 0), "{points:?}");
        let err = select_points(
            &img,
            &SelectConfig {
                block: 0,
                ..SelectConfig::default()
            },
        );
        assert!(matches!(err, Err(DirectError::InvalidConfig(_))));
    }
}
