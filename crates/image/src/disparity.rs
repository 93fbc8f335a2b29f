//! Semi-dense disparity of a rectified stereo pair at selected high-gradient pixels.
//!
//! A left pixel `(x, y)` is seen in the right image at `(x - d, y)`, `d >= 0` the disparity in
//! pixels; with focal length `f` (pixels) and baseline `b` (metres) its depth is `Z = f b / d`.
//!
//! - [`select_pixels`]: the image is cut into square cells (about `budget` of them) and each
//!   keeps its pixel of largest horizontal gradient `|gx| >= min_gradient` (DSO-style spread;
//!   a row search needs texture across the row, an edge along the row is ambiguous);
//! - [`match_pixels`]: block matching along the row: the zero-mean sum of squared differences
//!   `C(d) = sum_w ((L - mean L) - (R(. - d) - mean R))^2` over a `(2r + 1)^2` window for
//!   every integer `d` in `[min_disparity, max_disparity]`, then
//!   - rejection of ambiguous minima (another disparity more than one pixel away costs less
//!     than `uniqueness` times the best),
//!   - sub-pixel refinement by the parabola through `C(d - 1), C(d), C(d + 1)`:
//!     `d* = d + (C(d-1) - C(d+1)) / (2 (C(d-1) - 2 C(d) + C(d+1)))`,
//!   - the left-right check: the right pixel `x - d` searched back in the left row must come
//!     back within `max_lr_difference` pixels (occlusions and repeated texture fail it),
//!   - the disparity's standard deviation from the cost's curvature: for the SSD,
//!     `C'' = 2 sum gx^2` and `var(d) = 2 s^2 / sum gx^2` with `s^2 = C(d*) / N` the
//!     per-pixel residual variance (floored at `min_noise^2`), i.e.
//!     `sigma_d = sqrt(4 s^2 / C'')`.
//!
//! The images are `f32` rows (contiguous, so the window sums vectorise); rows of pixels are
//! matched in parallel with rayon.

use rayon::prelude::*;

use crate::{Image, ImageError};

/// Settings of [`select_pixels`] and [`match_pixels`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DisparityConfig {
    /// About this many selected pixels (one per cell).
    pub budget: usize,
    /// Smallest `|gx|` of a selected pixel, grey levels per pixel.
    pub min_gradient: f32,
    /// Half size `r` of the `(2r + 1)^2` matching window, pixels.
    pub radius: usize,
    /// Smallest disparity searched, pixels (at least 1: the parabola needs `d - 1`).
    pub min_disparity: usize,
    /// Largest disparity searched, pixels.
    pub max_disparity: usize,
    /// The best cost must be below this fraction of every cost more than one pixel away.
    pub uniqueness: f32,
    /// Largest difference of the left-right check, pixels.
    pub max_lr_difference: f32,
    /// Largest mean squared residual per window pixel at the best disparity, grey levels^2.
    pub max_mean_cost: f32,
    /// Floor of the per-pixel residual deviation in the disparity's sigma, grey levels.
    pub min_noise: f32,
}

impl Default for DisparityConfig {
    fn default() -> Self {
        Self {
            budget: 12_000,
            min_gradient: 6.0,
            radius: 2,
            min_disparity: 1,
            max_disparity: 128,
            uniqueness: 0.8,
            max_lr_difference: 1.0,
            max_mean_cost: 400.0,
            min_noise: 1.0,
        }
    }
}

impl DisparityConfig {
    /// [`ImageError::InvalidConfig`] unless `budget >= 1`, `radius >= 1`,
    /// `1 <= min_disparity < max_disparity`, `0 < uniqueness <= 1` and the thresholds are
    /// finite and non-negative.
    pub fn validate(&self) -> Result<(), ImageError> {
        let finite = [
            self.min_gradient,
            self.max_lr_difference,
            self.max_mean_cost,
            self.min_noise,
        ]
        .iter()
        .all(|v| v.is_finite() && *v >= 0.0);
        if self.budget == 0 || self.radius == 0 {
            return Err(ImageError::InvalidConfig(
                "budget and radius must be positive",
            ));
        }
        if self.min_disparity == 0 || self.min_disparity >= self.max_disparity {
            return Err(ImageError::InvalidConfig(
                "disparities must satisfy 1 <= min_disparity < max_disparity",
            ));
        }
        if !(self.uniqueness > 0.0 && self.uniqueness <= 1.0 && finite) {
            return Err(ImageError::InvalidConfig(
                "uniqueness must be in (0, 1], thresholds finite and non-negative",
            ));
        }
        Ok(())
    }
}

/// The disparity of one left pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disparity {
    /// Left pixel column.
    pub x: u32,
    /// Left (and right) pixel row.
    pub y: u32,
    /// Sub-pixel disparity `d`, pixels: the pixel is at `x - d` in the right image.
    pub disparity: f32,
    /// Standard deviation of `d`, pixels.
    pub sigma: f32,
}

impl Disparity {
    /// Depth `Z = f b / d`, metres, for `fb` = focal length (pixels) times baseline (metres).
    pub fn depth(&self, fb: f64) -> f64 {
        fb / f64::from(self.disparity)
    }

    /// Standard deviation of the depth, `sigma_Z = Z^2 sigma_d / (f b)`, metres.
    pub fn depth_sigma(&self, fb: f64) -> f64 {
        let z = self.depth(fb);
        z * z * f64::from(self.sigma) / fb
    }
}

/// Pixels worth matching along their row: per cell of a grid of about `cfg.budget` square
/// cells, the pixel of largest `|gx|` at least `cfg.min_gradient`, away from the border by the
/// window radius plus one; in row-major order.
pub fn select_pixels(left: &Image<f32>, cfg: &DisparityConfig) -> Vec<(u32, u32)> {
    let (w, h) = left.size();
    let m = cfg.radius + 1;
    if w <= 2 * m || h <= 2 * m || cfg.budget == 0 {
        return Vec::new();
    }
    let cell = (((w * h) as f64 / cfg.budget as f64).sqrt().ceil() as usize).max(1);
    let bands: Vec<usize> = (m..h - m).step_by(cell).collect();
    bands
        .into_par_iter()
        .flat_map_iter(|y0| {
            let cells = (w - 2 * m).div_ceil(cell);
            let mut best: Vec<Option<(f32, u32, u32)>> = vec![None; cells];
            for y in y0..(y0 + cell).min(h - m) {
                let row = left.row(y);
                for (x, (r, l)) in row[m + 1..w - m + 1].iter().zip(&row[m - 1..]).enumerate() {
                    let g = 0.5 * (r - l).abs();
                    let slot = &mut best[x / cell];
                    if g >= cfg.min_gradient && slot.is_none_or(|b| g > b.0) {
                        *slot = Some((g, (x + m) as u32, y as u32));
                    }
                }
            }
            best.into_iter().flatten().map(|(_, x, y)| (x, y))
        })
        .collect()
}

/// Costs `C(d)` of one left window against the right row band, index `d - d0`.
struct Costs {
    d0: usize,
    c: Vec<f32>,
}

impl Costs {
    /// Zero-mean SSD of the left window centred at `(x, y)` (its zero-mean values `l`, `n`
    /// pixels, `sum l^2 = ll`) against the right windows at `x - d`, `d` in `d0..=d1`.
    fn new(right: &Image<f32>, window: &Window, x: usize, y: usize, d0: usize, d1: usize) -> Self {
        let r = window.radius;
        let side = 2 * r + 1;
        let n = (side * side) as f32;
        let c = (d0..=d1)
            .map(|d| {
                let (mut lr, mut sr, mut srr) = (0f32, 0f32, 0f32);
                for (j, lrow) in window.values.chunks_exact(side).enumerate() {
                    let row = &right.row(y + j - r)[x - d - r..x - d + r + 1];
                    for (a, b) in lrow.iter().zip(row) {
                        lr += a * b;
                        sr += b;
                        srr += b * b;
                    }
                }
                (window.ll - 2.0 * lr + srr - sr * sr / n).max(0.0)
            })
            .collect();
        Self { d0, c }
    }

    /// Index of the smallest cost.
    fn best(&self) -> Option<usize> {
        (0..self.c.len()).min_by(|&a, &b| self.c[a].total_cmp(&self.c[b]))
    }
}

/// A zero-mean window of one image.
struct Window {
    radius: usize,
    values: Vec<f32>,
    /// `sum values^2`.
    ll: f32,
}

impl Window {
    fn new(img: &Image<f32>, x: usize, y: usize, radius: usize) -> Self {
        let mut values = Vec::with_capacity((2 * radius + 1).pow(2));
        for yy in y - radius..=y + radius {
            values.extend_from_slice(&img.row(yy)[x - radius..=x + radius]);
        }
        let mean = values.iter().sum::<f32>() / values.len() as f32;
        values.iter_mut().for_each(|v| *v -= mean);
        let ll = values.iter().map(|v| v * v).sum();
        Self { radius, values, ll }
    }
}

/// The disparity of the left pixel `(x, y)`, or `None` when rejected (see the module).
fn match_one(
    left: &Image<f32>,
    right: &Image<f32>,
    x: usize,
    y: usize,
    cfg: &DisparityConfig,
) -> Option<Disparity> {
    let (w, h) = left.size();
    let r = cfg.radius;
    if x < r + 1 || y < r || x + r >= w || y + r >= h {
        return None;
    }
    // Right windows must fit: x - d - r >= 0, and d - 1 is needed by the parabola.
    let d1 = cfg.max_disparity.min(x - r);
    let d0 = cfg.min_disparity;
    if d1 < d0 + 2 {
        return None;
    }
    let window = Window::new(left, x, y, r);
    let costs = Costs::new(right, &window, x, y, d0 - 1, d1);
    let i = costs.best()?;
    let best = costs.c[i];
    let n = ((2 * r + 1) * (2 * r + 1)) as f32;
    if i == 0 || i + 1 == costs.c.len() || best / n > cfg.max_mean_cost {
        return None;
    }
    let unique = costs
        .c
        .iter()
        .enumerate()
        .filter(|(j, _)| j.abs_diff(i) > 1)
        .all(|(_, &c)| best < cfg.uniqueness * c);
    if !unique {
        return None;
    }
    let (cm, cp) = (costs.c[i - 1], costs.c[i + 1]);
    let curvature = cm - 2.0 * best + cp;
    if curvature <= 0.0 {
        return None;
    }
    let offset = (0.5 * (cm - cp) / curvature).clamp(-0.5, 0.5);
    let disparity = (costs.d0 + i) as f32 + offset;
    // Left-right check: the right pixel searched back along the left row.
    let xr = x - (costs.d0 + i);
    let back = Window::new(right, xr, y, r);
    let b1 = cfg.max_disparity.min(w - 1 - r - xr);
    if b1 < d0 {
        return None;
    }
    let back_costs = left_costs(left, &back, xr, y, d0 - 1, b1);
    let j = back_costs.best()?;
    if ((back_costs.d0 + j) as f32 - (costs.d0 + i) as f32).abs() > cfg.max_lr_difference {
        return None;
    }
    let noise = (best / n).max(cfg.min_noise * cfg.min_noise);
    // C'' = (2 sum gx^2) per disparity pixel squared; var(d) = 4 s^2 / C''.
    let sigma = (4.0 * noise / curvature).sqrt();
    Some(Disparity {
        x: x as u32,
        y: y as u32,
        disparity,
        sigma,
    })
}

/// Costs of a right window (at `xr`) against the left windows at `xr + d`, `d` in `d0..=d1`.
fn left_costs(
    left: &Image<f32>,
    window: &Window,
    xr: usize,
    y: usize,
    d0: usize,
    d1: usize,
) -> Costs {
    let r = window.radius;
    let side = 2 * r + 1;
    let n = (side * side) as f32;
    let c = (d0..=d1)
        .map(|d| {
            let (mut lr, mut sl, mut sll) = (0f32, 0f32, 0f32);
            for (j, rrow) in window.values.chunks_exact(side).enumerate() {
                let row = &left.row(y + j - r)[xr + d - r..xr + d + r + 1];
                for (a, b) in rrow.iter().zip(row) {
                    lr += a * b;
                    sl += b;
                    sll += b * b;
                }
            }
            (window.ll - 2.0 * lr + sll - sl * sl / n).max(0.0)
        })
        .collect();
    Costs { d0, c }
}

/// The disparity of each of `pixels` (left image) in the rectified pair `left`/`right`, in the
/// same order, `None` where the match is rejected (out of the search range, too costly,
/// ambiguous, failing the left-right check or without curvature); see the module.
///
/// Errors: [`ImageError::SizeMismatch`] between the images, [`ImageError::InvalidConfig`].
///
/// ```
/// use vofront_image::disparity::{match_pixels, DisparityConfig};
/// use vofront_image::Image;
/// // A hashed pixel texture and the same texture moved 7 pixels left: disparity 7 everywhere.
/// let (w, h) = (96, 32);
/// let tex = |x: i64, y: i64| (((x * 73_856_093) ^ (y * 19_349_663)).rem_euclid(1009) % 256) as f32;
/// let left = Image::new(w, h, (0..w * h).map(|i| tex((i % w) as i64, (i / w) as i64)).collect()).unwrap();
/// let right = Image::new(w, h, (0..w * h).map(|i| tex((i % w) as i64 + 7, (i / w) as i64)).collect()).unwrap();
/// let found = match_pixels(&left, &right, &[(50, 16)], &DisparityConfig::default()).unwrap();
/// // (On pixel noise the cost is a V rather than a parabola: the sub-pixel part is off by a few
/// // hundredths; on smooth rendered texture the median error is under 0.1 px.)
/// assert!((found[0].unwrap().disparity - 7.0).abs() < 0.1);
/// ```
pub fn match_pixels(
    left: &Image<f32>,
    right: &Image<f32>,
    pixels: &[(u32, u32)],
    cfg: &DisparityConfig,
) -> Result<Vec<Option<Disparity>>, ImageError> {
    cfg.validate()?;
    left.check_same_size(right)?;
    Ok(pixels
        .par_chunks(64)
        .flat_map_iter(|chunk| {
            chunk
                .iter()
                .map(|&(x, y)| match_one(left, right, x as usize, y as usize, cfg))
        })
        .collect())
}
