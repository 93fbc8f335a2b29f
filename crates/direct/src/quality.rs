//! The quality record ([`vofront_robust::Quality`]) of each direct estimate.
//!
//! A photometric fit is better than chance when it explains the images: its residual variance
//! `rmse^2` must stay under [`CHANCE_RESIDUAL_SHARE`] of `var(I1) + var(I2)`, the residual
//! variance of two unrelated images with the same statistics, and under
//! [`FIT_RESIDUAL_SHARE`] of it for the fit to count as explaining the pair. Support is the number of valid pixels;
//! the covariance is the aligner's Gauss-Newton `sigma^2 H^-1`.

use vofront_robust::quality::{block_rows, rms_of};
use vofront_robust::{Convergence, Quality, QualityConfig, Reason, Support, Uncertainty};

use crate::plane::Plane;
use crate::se3::Se3Result;
use crate::translation::TranslationResult;
use crate::warp2d::WarpResult;

/// Share of `var(I1) + var(I2)` above which a photometric residual variance is what two
/// unrelated images give ([`Reason::NotBetterThanChance`]).
pub const CHANCE_RESIDUAL_SHARE: f64 = 0.5;
/// Share above which the fit leaves too much unexplained ([`Reason::HighResidual`]): aligned
/// frames leave a few grey levels of noise against tens of grey levels of texture (a share
/// near 0.01).
pub const FIT_RESIDUAL_SHARE: f64 = 0.1;

/// Variance of a plane's finite values, grey levels^2 (0 for an empty plane).
pub fn intensity_variance(p: &Plane) -> f64 {
    let (w, h) = p.size();
    let (mut n, mut sum, mut sum_sq) = (0usize, 0.0f64, 0.0f64);
    for v in (0..h).flat_map(|y| p.row(y)[..w].iter().copied()) {
        if !v.is_finite() {
            continue;
        }
        n += 1;
        sum += v as f64;
        sum_sq += (v as f64) * (v as f64);
    }
    if n == 0 {
        return 0.0;
    }
    let mean = sum / n as f64;
    (sum_sq / n as f64 - mean * mean).max(0.0)
}

/// `NotBetterThanChance` when `rmse^2 > CHANCE_RESIDUAL_SHARE * variances`, else
/// `HighResidual` when `rmse^2 > FIT_RESIDUAL_SHARE * variances`.
fn photometric_flags(rmse: f64, variances: f64) -> Vec<Reason> {
    let share = rmse * rmse / variances;
    if !(share <= CHANCE_RESIDUAL_SHARE) {
        vec![Reason::NotBetterThanChance]
    } else if share > FIT_RESIDUAL_SHARE {
        vec![Reason::HighResidual]
    } else {
        Vec::new()
    }
}

/// Support of `pixels` valid residuals out of `candidates` pixels.
fn pixel_support(pixels: usize, candidates: usize) -> Support {
    Support {
        pixels: Some(pixels),
        ..Support::new(pixels, candidates)
    }
}

impl TranslationResult {
    /// Quality of a 2D shift over images of `image_pixels` pixels whose intensity variances
    /// sum to `variances` ([`intensity_variance`]); `sigma` is the RMS residual, grey levels.
    pub fn quality(&self, image_pixels: usize, variances: f64, cfg: &QualityConfig) -> Quality {
        let pixels = (self.used_fraction * image_pixels as f64).round() as usize;
        let uncertainty = match &self.covariance {
            Some(cov) => Uncertainty {
                covariance: Some(block_rows(|r, c| cov[(r, c)], 0, 2)),
                shift_sigma_px: Some((cov[(0, 0)] + cov[(1, 1)]).max(0.0).sqrt()),
                ..Uncertainty::default()
            },
            None => Uncertainty::default(),
        };
        Quality::judge(
            pixel_support(pixels, image_pixels),
            self.rmse,
            self.iterations.iter().sum(),
            self.converged,
            uncertainty,
            &photometric_flags(self.rmse, variances),
            cfg,
        )
    }
}

impl WarpResult {
    /// Quality of an affine or homography warp, as [`TranslationResult::quality`].
    pub fn quality(&self, image_pixels: usize, variances: f64, cfg: &QualityConfig) -> Quality {
        let pixels = (self.used_fraction * image_pixels as f64).round() as usize;
        let uncertainty = Uncertainty {
            covariance: self
                .covariance
                .as_ref()
                .map(|cov| block_rows(|r, c| cov[(r, c)], 0, cov.nrows())),
            ..Uncertainty::default()
        };
        Quality::judge(
            pixel_support(pixels, image_pixels),
            self.rmse,
            self.iterations.iter().sum(),
            self.converged,
            uncertainty,
            &photometric_flags(self.rmse, variances),
            cfg,
        )
    }
}

impl Se3Result {
    /// Quality of an SE(3) alignment of a reference with `reference_pixels` usable pixels;
    /// `variances` is `var(I_ref) + var(I_cur)`. Covariance of `(rho, phi)` (metres, radians);
    /// `sigma` is the robust residual scale, grey levels.
    pub fn quality(&self, reference_pixels: usize, variances: f64, cfg: &QualityConfig) -> Quality {
        let uncertainty = match &self.covariance {
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
            pixels: Some(self.valid_pixels),
            ..Support::new(
                (self.inlier_ratio * self.valid_pixels as f64).round() as usize,
                reference_pixels.max(self.valid_pixels),
            )
        };
        Quality::judge(
            support,
            self.sigma,
            self.iterations.iter().sum(),
            self.reason != Convergence::MaxIterations,
            uncertainty,
            &photometric_flags(self.rmse, variances),
            cfg,
        )
    }
}
