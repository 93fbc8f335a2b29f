//! Robust coarse-to-fine 2D translation: the shift `d` with `I2(x + d) = I1(x)`.
//!
//! Pixels of image 1 with `|grad I1| < gradient_threshold` are rejected; the others give
//! residuals `r = I2(x + d) - a I1(x) - b` (`a = 1`, `b = 0` unless affine brightness is on),
//! minimised by damped Gauss-Newton on Huber IRLS weights at each pyramid level, stopping when
//! the step is below `min_step` pixels. See [`crate::warp2d`] for the two Jacobians
//! ([`TranslationMethod`]). Collinear gradients (the aperture problem) make the 2x2 normal
//! matrix singular and are reported as [`DirectError::Solve`] with
//! [`vofront_robust::SolveError::Degenerate`]; a flat image is [`DirectError::NoTexture`].

use nalgebra::{Matrix2, Matrix3, Vector2};
use vofront_image::Image;
use vofront_robust::{Loss, Quality, QualityConfig};

use crate::error::DirectError;
use crate::quality::shift_quality;
use crate::warp2d::{align_2d, TranslationMethod, WarpConfig, WarpKind};

/// Settings of [`align_translation`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TranslationConfig {
    /// Pyramid levels as factor-2 octaves (each level half the size of the one below; ORB's 1.2-ratio levels are
    /// `OrbConfig::scale_levels`), fewer on small images; a shift of up to about `2^(levels-1)` times the
    /// texture scale is recovered.
    pub levels: usize,
    /// Iteration limit per level.
    pub max_iterations: usize,
    /// Stop when the step is below this, pixels.
    pub min_step: f64,
    /// Pixels of image 1 with a smaller gradient magnitude (grey levels per pixel) are unused.
    pub gradient_threshold: f32,
    /// At most about this many pixels at full resolution, those with the largest gradients
    /// (0 = no limit); coarser levels keep the same density (see
    /// [`crate::WarpConfig::max_pixels`]).
    pub max_pixels: usize,
    /// Robust loss on residuals in sigmas (MAD scale re-estimated every iteration).
    pub loss: Loss,
    /// Floor of the residual scale, grey levels.
    pub min_sigma: f32,
    /// Jacobian formulation.
    pub method: TranslationMethod,
    /// Estimate a brightness change `I2(x + d) = a I1(x) + b` as well.
    pub affine_brightness: bool,
    /// Largest acceptable Jacobi-scaled condition number of the 2x2 normal matrix; above it
    /// the gradients are treated as collinear (aperture problem).
    pub max_condition: f64,
    /// Blur both images by a sigma-1 binomial kernel first (see [`WarpConfig::presmooth`]).
    pub presmooth: bool,
    /// Thresholds of the result's [`TranslationResult::quality`] verdict.
    pub quality: QualityConfig,
}

impl Default for TranslationConfig {
    fn default() -> Self {
        Self {
            levels: 4,
            max_iterations: 30,
            min_step: 1e-3,
            gradient_threshold: 2.0,
            max_pixels: 20_000,
            loss: Loss::Huber(1.345),
            min_sigma: 0.5,
            method: TranslationMethod::InverseCompositional,
            affine_brightness: false,
            max_condition: 1e4,
            presmooth: true,
            quality: QualityConfig::default(),
        }
    }
}

/// Result of [`align_translation`] (`Serialize`: `d` as `[x, y]`, `covariance` as a flat
/// column-major array).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TranslationResult {
    /// The shift `d`, pixels, with `I2(x + d) = I1(x)`.
    pub d: Vector2<f64>,
    /// Iterations per pyramid level, index = level (0 = full resolution).
    pub iterations: Vec<usize>,
    /// Final root-mean-square residual at full resolution, grey levels.
    pub rmse: f64,
    /// Fraction of the image's pixels that gave a valid residual at full resolution.
    pub used_fraction: f64,
    /// Gauss-Newton covariance `sigma^2 H^-1` of `d`, pixels^2; `None` (unknown) when the
    /// final normal equations are singular.
    pub covariance: Option<Matrix2<f64>>,
    /// Brightness gain (1 unless `affine_brightness`).
    pub a: f64,
    /// Brightness offset (0 unless `affine_brightness`).
    pub b: f64,
    /// False when the full-resolution level hit its iteration limit.
    pub converged: bool,
    /// Verdict, pixels used and covariance of `d`, judged with [`TranslationConfig::quality`];
    /// the chance test is [`crate::quality::shift_chance_share`] on the two input images and
    /// `sigma` the RMS residual, grey levels.
    pub quality: Quality,
}

/// Finds `d` with `I2(x + d) = I1(x)` (the content of `img1` moved by `d` in `img2`).
///
/// ```
/// use vofront_direct::{align_translation, TranslationConfig};
/// use vofront_image::Image;
/// let img = |dx: f32, dy: f32| {
///     let data = (0..96 * 80)
///         .map(|i| {
///             let (x, y) = ((i % 96) as f32 - dx, (i / 96) as f32 - dy);
///             100.0 + 40.0 * (x * 0.3).sin() * (y * 0.25).cos() + 30.0 * ((x + y) * 0.17).sin()
///         })
///         .collect();
///     Image::new(96, 80, data).unwrap()
/// };
/// let fit = align_translation(&img(0.0, 0.0), &img(1.3, -0.6), &TranslationConfig::default()).unwrap();
/// assert!((fit.d.x - 1.3).abs() < 0.01 && (fit.d.y + 0.6).abs() < 0.01);
/// ```
pub fn align_translation(
    img1: &Image<f32>,
    img2: &Image<f32>,
    cfg: &TranslationConfig,
) -> Result<TranslationResult, DirectError> {
    let warp_cfg = WarpConfig {
        levels: cfg.levels,
        max_iterations: cfg.max_iterations,
        min_step: cfg.min_step,
        min_relative_decrease: 1e-9,
        gradient_threshold: cfg.gradient_threshold,
        max_pixels: cfg.max_pixels,
        loss: cfg.loss,
        min_sigma: cfg.min_sigma,
        affine_brightness: cfg.affine_brightness,
        max_condition: cfg.max_condition,
        presmooth: cfg.presmooth,
        quality: cfg.quality,
    };
    let forward = cfg.method == TranslationMethod::ForwardAdditive;
    let fit = align_2d::<4>(
        WarpKind::Translation,
        img1,
        img2,
        &Matrix3::identity(),
        &warp_cfg,
        forward,
    )?;
    let quality = shift_quality(&fit, img1, img2, &cfg.quality);
    Ok(TranslationResult {
        d: Vector2::new(fit.h[(0, 2)], fit.h[(1, 2)]),
        iterations: fit.iterations,
        rmse: fit.rmse,
        used_fraction: fit.used_fraction,
        covariance: fit
            .covariance
            .map(|cov| Matrix2::from_fn(|r, c| cov[(r, c)])),
        a: fit.a,
        b: fit.b,
        converged: fit.converged,
        quality,
    })
}
