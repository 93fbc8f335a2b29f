//! The quality record ([`vofront_robust::Quality`]) of each direct estimate, computed by the
//! aligner itself with the `quality` thresholds of its configuration and returned in the
//! result's `quality` field ([`crate::TranslationResult::quality`],
//! [`crate::WarpResult::quality`], [`crate::Se3Result::quality`]).
//!
//! A photometric fit is better than chance when it explains the images: for a 2D shift, the
//! mean squared difference at the shift must stay under [`CHANCE_RESIDUAL_SHARE`] of its value
//! at shifts that carry no alignment ([`shift_chance_share`]); for SE(3) and warps, the
//! residual variance `rmse^2` under that share of `var(I1) + var(I2)` (the residual variance
//! of two unrelated images with the same statistics). Under [`FIT_RESIDUAL_SHARE`] the fit
//! explains the pair; between the two it is [`Reason::HighResidual`]. Support is the number of valid pixels;
//! the covariance is the aligner's Gauss-Newton `sigma^2 H^-1` for the 2D warps and the M-estimator's
//! sandwich `B^-1 M B^-1` for SE(3) (see [`crate::Se3Result::covariance`]).

use nalgebra::Matrix6;
use vofront_image::Image;
use vofront_robust::quality::{block_rows, rms_of};
use vofront_robust::{Convergence, Quality, QualityConfig, Reason, Support, Uncertainty};

use crate::warp2d::{Fit2d, WarpResult};

/// Share of `var(I1) + var(I2)` above which a photometric residual variance is what two
/// unrelated images give ([`Reason::NotBetterThanChance`]).
pub const CHANCE_RESIDUAL_SHARE: f64 = 0.5;
/// Share above which the fit leaves too much unexplained ([`Reason::HighResidual`]): aligned
/// frames leave a few grey levels of noise against tens of grey levels of texture (a share
/// near 0.01).
pub const FIT_RESIDUAL_SHARE: f64 = 0.1;

/// Count, sum and sum of squares of an image's finite values.
fn intensity_moments(p: &Image<f32>) -> (usize, f64, f64) {
    let (w, h) = p.size();
    (0..h)
        .flat_map(|y| p.row(y)[..w].iter().copied())
        .filter(|v| v.is_finite())
        .fold((0, 0.0, 0.0), |(n, sum, sum_sq), v| {
            let v = f64::from(v);
            (n + 1, sum + v, sum_sq + v * v)
        })
}

/// Mean of an image's finite values, grey levels (0 for an empty image).
pub fn intensity_mean(p: &Image<f32>) -> f64 {
    let (n, sum, _) = intensity_moments(p);
    if n == 0 {
        return 0.0;
    }
    sum / n as f64
}

/// Variance of an image's finite values, grey levels^2 (0 for an empty image).
pub fn intensity_variance(p: &Image<f32>) -> f64 {
    let (n, sum, sum_sq) = intensity_moments(p);
    if n == 0 {
        return 0.0;
    }
    let mean = sum / n as f64;
    (sum_sq / n as f64 - mean * mean).max(0.0)
}

/// `NotBetterThanChance` when `rmse^2 > CHANCE_RESIDUAL_SHARE * variances`, else
/// `HighResidual` when `rmse^2 > FIT_RESIDUAL_SHARE * variances`.
fn photometric_flags(rmse: f64, variances: f64) -> Vec<Reason> {
    share_flags(rmse * rmse / variances)
}

/// Support of `pixels` valid residuals out of `candidates` pixels.
fn pixel_support(pixels: usize, candidates: usize) -> Support {
    Support {
        pixels: Some(pixels),
        ..Support::new(pixels, candidates)
    }
}

/// Grid step of [`shift_chance_share`], pixels.
const CHANCE_GRID: usize = 4;

/// Mean squared difference `I1(x) - I2(x + d)` over a grid of `x` whose `x + d` falls inside
/// `I2` (bilinear), `None` without overlap.
fn mean_sq_difference(p1: &Image<f32>, p2: &Image<f32>, d: (f32, f32)) -> Option<f64> {
    let (w, h) = p1.size();
    let (mut sum, mut n) = (0.0f64, 0usize);
    for y in (0..h).step_by(CHANCE_GRID) {
        for x in (0..w).step_by(CHANCE_GRID) {
            if let Some(v) = p2.sample(x as f32 + d.0, y as f32 + d.1) {
                let r = (p1.at(x, y) - v) as f64;
                sum += r * r;
                n += 1;
            }
        }
    }
    (n > 0).then(|| sum / n as f64)
}

/// The mean squared difference of `I1(x)` and `I2(x + d)` over its median at eight shifts of
/// a quarter image (placements that carry no alignment): near 0 for an aligned pair, near 1
/// for a shift no better than chance.
pub fn shift_chance_share(p1: &Image<f32>, p2: &Image<f32>, d: (f64, f64)) -> f64 {
    let (w, h) = p1.size();
    let (qx, qy) = (w as f32 / 4.0, h as f32 / 4.0);
    let mut chance: Vec<f64> = [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
    ]
    .iter()
    .filter_map(|&(i, j)| mean_sq_difference(p1, p2, (i as f32 * qx, j as f32 * qy)))
    .collect();
    chance.sort_by(f64::total_cmp);
    match (
        mean_sq_difference(p1, p2, (d.0 as f32, d.1 as f32)),
        chance.get(chance.len() / 2),
    ) {
        (Some(at_d), Some(&c)) if c > 0.0 => at_d / c,
        _ => f64::INFINITY,
    }
}

/// `NotBetterThanChance` when a residual share (see [`photometric_flags`]) exceeds
/// [`CHANCE_RESIDUAL_SHARE`], `HighResidual` when it exceeds [`FIT_RESIDUAL_SHARE`].
fn share_flags(share: f64) -> Vec<Reason> {
    if share.is_nan() || share > CHANCE_RESIDUAL_SHARE {
        vec![Reason::NotBetterThanChance]
    } else if share > FIT_RESIDUAL_SHARE {
        vec![Reason::HighResidual]
    } else {
        Vec::new()
    }
}

/// The verdict of a 2D shift `fit` of `p1` to `p2` ([`crate::align_translation`]): the chance
/// test is [`shift_chance_share`] on the two images; `sigma` is the RMS residual, grey levels;
/// the covariance that of `d`, pixels^2.
pub(crate) fn shift_quality(
    fit: &Fit2d,
    p1: &Image<f32>,
    p2: &Image<f32>,
    cfg: &QualityConfig,
) -> Quality {
    let (w, h) = p1.size();
    let image_pixels = w * h;
    let pixels = (fit.used_fraction * image_pixels as f64).round() as usize;
    let uncertainty = match &fit.covariance {
        Some(cov) => Uncertainty {
            covariance: Some(block_rows(|r, c| cov[(r, c)], 0, 2)),
            shift_sigma_px: Some((cov[(0, 0)] + cov[(1, 1)]).max(0.0).sqrt()),
            ..Uncertainty::default()
        },
        None => Uncertainty::default(),
    };
    let d = (fit.h[(0, 2)], fit.h[(1, 2)]);
    Quality::judge(
        pixel_support(pixels, image_pixels),
        fit.rmse,
        fit.iterations.iter().sum(),
        fit.converged,
        uncertainty,
        &share_flags(shift_chance_share(p1, p2, d)),
        cfg,
    )
}

/// An affine or homography `fit` of `p1` to `p2` with its verdict: support out of the image's
/// pixels, the chance test on `var(I1) + var(I2)`, the covariance of the geometric parameters.
pub(crate) fn warp_quality(
    fit: Fit2d,
    p1: &Image<f32>,
    p2: &Image<f32>,
    cfg: &QualityConfig,
) -> WarpResult {
    let (w, h) = p1.size();
    let image_pixels = w * h;
    let variances = intensity_variance(p1) + intensity_variance(p2);
    let pixels = (fit.used_fraction * image_pixels as f64).round() as usize;
    let uncertainty = Uncertainty {
        covariance: fit
            .covariance
            .as_ref()
            .map(|cov| block_rows(|r, c| cov[(r, c)], 0, cov.nrows())),
        ..Uncertainty::default()
    };
    let quality = Quality::judge(
        pixel_support(pixels, image_pixels),
        fit.rmse,
        fit.iterations.iter().sum(),
        fit.converged,
        uncertainty,
        &photometric_flags(fit.rmse, variances),
        cfg,
    );
    WarpResult {
        h: fit.h,
        a: fit.a,
        b: fit.b,
        iterations: fit.iterations,
        rmse: fit.rmse,
        used_fraction: fit.used_fraction,
        covariance: fit.covariance,
        converged: fit.converged,
        quality,
    }
}

/// The full-resolution statistics of an SE(3) alignment that its verdict rests on (the fields
/// of the same names in [`crate::Se3Result`]).
pub(crate) struct Se3Stats<'a> {
    pub covariance: Option<&'a Matrix6<f64>>,
    pub valid_pixels: usize,
    pub inlier_ratio: f64,
    pub sigma: f64,
    pub rmse: f64,
    pub iterations: usize,
    pub reason: Convergence,
}

/// The verdict of an SE(3) alignment against a reference of `reference_pixels` candidate
/// pixels; `variances` is `var(I_ref) + var(I_cur)`. Covariance of `(rho, phi)` (metres,
/// radians); `sigma` is the robust residual scale, grey levels.
pub(crate) fn se3_quality(
    s: &Se3Stats<'_>,
    reference_pixels: usize,
    variances: f64,
    cfg: &QualityConfig,
) -> Quality {
    let uncertainty = match s.covariance {
        Some(cov) => Uncertainty {
            translation_sigma_m: Some(rms_of(&block_rows(|r, c| cov[(r, c)], 0, 3), 1.0)),
            rotation_sigma_deg: Some(rms_of(
                &block_rows(|r, c| cov[(r, c)], 3, 3),
                1f64.to_degrees(),
            )),
            covariance: Some(block_rows(|r, c| cov[(r, c)], 0, 6)),
            ..Uncertainty::default()
        },
        None => Uncertainty::default(),
    };
    let support = Support {
        pixels: Some(s.valid_pixels),
        ..Support::new(
            (s.inlier_ratio * s.valid_pixels as f64).round() as usize,
            reference_pixels.max(s.valid_pixels),
        )
    };
    Quality::judge(
        support,
        s.sigma,
        s.iterations,
        s.reason != Convergence::MaxIterations,
        uncertainty,
        &photometric_flags(s.rmse, variances),
        cfg,
    )
}
