//! The quality record of a relative pose: support, the a-contrario chance test and the
//! covariance of `(R, t)` from the Sampson refinement's Hessian (widened where the cost is
//! flatter than its quadratic model, `super::refine::sampson_covariance`).
//!
//! Chance test: `p0`, the probability that a random correspondence falls inside the final
//! model's inlier region, is measured by applying the model's own inlier test to the data with
//! the frame-2 points re-paired by cyclic shifts (correspondences that carry no information
//! about the motion but keep the image distribution of the features). The consensus is then
//! scored by [`log10_nfa`] with the number of hypotheses RANSAC tried.

use nalgebra::{Matrix3, Matrix5, Vector3};
use vofront_robust::quality::{block_rows, laplace_rate, log10_nfa, repairing_shifts, rms_of};
use vofront_robust::{Quality, QualityConfig, Reason, Support, Uncertainty};

use super::correspondences::Correspondences;

/// Essential-matrix hypotheses per five-point sample (the solver's largest root count).
pub(super) const ESSENTIAL_SOLUTIONS: usize = 10;

/// `p0`: the share of re-paired correspondences `(x1_i, x2_{i+s})`
/// ([`vofront_robust::quality::repairing_shifts`]) that `is_inlier` accepts, with a Laplace
/// correction so that it is never exactly zero.
pub(super) fn chance_rate(
    data: &Correspondences,
    is_inlier: impl Fn(&Correspondences, usize) -> bool,
) -> f64 {
    let n = data.len();
    if n < 2 {
        return 1.0;
    }
    let (mut hits, mut total) = (0usize, 0usize);
    for s in repairing_shifts(n) {
        let mut shuffled = Correspondences::default();
        for i in 0..n {
            shuffled.push(&data.p1(i), &data.p2((i + s) % n));
        }
        hits += (0..n).filter(|&i| is_inlier(&shuffled, i)).count();
        total += n;
    }
    laplace_rate(hits, total)
}

/// Largest `lambda_3 / lambda_2` of the ray scatter at which the rays count as coplanar.
///
/// `lambda_3 / lambda_2` is the mean squared out-of-plane angle over the in-plane spread: 1e-3
/// is rays within about 0.03 of their spread from one plane (3 px over a 60 degree field of
/// view at a 300 px focal length).
const COPLANAR_RAYS: f64 = 1e-3;

/// Whether the rays `f_i` (unit or not) lie nearly in one plane through the camera centre:
/// the eigenvalues `lambda_1 >= lambda_2 >= lambda_3` of the scatter `sum f_i f_i^T / |f_i|^2`
/// have `lambda_3 <= COPLANAR_RAYS lambda_2`. Such rays (points on a line in the image, on a
/// plane through the centre) leave the epipolar geometry undetermined: a family of motions
/// fits them exactly.
pub(super) fn rays_are_coplanar<'a>(rays: impl Iterator<Item = &'a Vector3<f64>>) -> bool {
    let scatter: Matrix3<f64> = rays
        .filter(|f| f.norm_squared() > 0.0)
        .map(|f| f * f.transpose() / f.norm_squared())
        .sum();
    let mut eigen: [f64; 3] = scatter.symmetric_eigenvalues().into();
    eigen.sort_by(|a, b| b.total_cmp(a));
    eigen[2] <= COPLANAR_RAYS * eigen[1]
}

/// Standard scores of the derotated disparity above its noise level at which a translation is
/// seen: 3 (a motion without translation exceeds it with probability 0.13%).
const TRANSLATION_SEEN_Z: f64 = 3.0;

/// Whether the correspondences `used` show a translation at all: their disparity after
/// derotation by `rotation`, `d_i = pi(R x1_i) - x2_i` (normalized coordinates, `pi` the
/// perspective division), exceeds what pixel noise alone leaves. Without translation,
/// `S = sum_i f^2 |d_i|^2 / (2 sigma^2)` is chi-square with `k = 2 n - 3` degrees of freedom
/// (two coordinates per correspondence, the noise `sigma` pixels of the Sampson distance in
/// each image, three fitted rotation parameters): a translation is seen when
/// `(S - k) / sqrt(2 k) > 3`. Below that the epipolar geometry fits noise: the Sampson cost
/// of a direction is then a quadratic form of noise vectors whose curvature states a finite,
/// meaningless precision, and no widening of its covariance can tell.
pub(super) fn translation_is_seen(
    data: &Correspondences,
    used: &[usize],
    rotation: &Matrix3<f64>,
    focal: f64,
    sigma_px: f64,
) -> bool {
    let n = used.len();
    if n < 2 || sigma_px.is_nan() || sigma_px <= 0.0 {
        return false;
    }
    let sum: f64 = used
        .iter()
        .filter_map(|&i| {
            let p = rotation * data.ray1(i);
            (p.z > 0.0).then(|| (p.xy() / p.z - data.p2(i)).norm_squared())
        })
        .sum();
    let k = (2 * n).saturating_sub(3).max(1) as f64;
    let s = sum * focal * focal / (2.0 * sigma_px * sigma_px);
    (s - k) / (2.0 * k).sqrt() > TRANSLATION_SEEN_Z
}

/// What [`judge`] needs beyond the estimator's flags.
pub(super) struct Evidence {
    /// Input correspondences.
    pub candidates: usize,
    /// Inliers of the final pose among them.
    pub inliers: usize,
    /// Correspondences the chance test ran on (the usable ones).
    pub tested: usize,
    /// Chance rate of the final model ([`chance_rate`]).
    pub p0: f64,
    /// Hypotheses RANSAC scored.
    pub hypotheses: f64,
    /// Minimal sample size of the final model.
    pub sample: usize,
    /// Noise scale of the Sampson distance, pixels.
    pub sigma_px: f64,
    /// A translation was estimated (its covariance is then expected).
    pub translation: bool,
    /// Covariance of `(phi, a, b)` at the final pose (`super::refine::sampson_covariance`);
    /// `None` when no translation was estimated or its information is singular.
    pub covariance: Option<Matrix5<f64>>,
    /// RANSAC iterations (essential + homography).
    pub iterations: usize,
}

/// The quality record of a relative pose with the estimator's own `flags` (parallax, pure
/// rotation, ambiguity). Covariance over `(phi, a, b)` ([`Evidence::covariance`]): rotation
/// block `phi` (rad^2) and the translation direction's tangent block `(a, b)` (rad^2); an
/// estimated translation without one (singular information) adds [`Reason::Degenerate`].
pub(super) fn judge(ev: &Evidence, flags: &[Reason], cfg: &QualityConfig) -> Quality {
    let log10 = log10_nfa(ev.tested, ev.inliers, ev.sample, ev.p0, ev.hypotheses);
    let support = Support {
        log10_nfa: Some(log10),
        ..Support::new(ev.inliers, ev.candidates)
    };
    let mut flags = flags.to_vec();
    if ev.translation && ev.covariance.is_none() {
        flags.push(Reason::Degenerate);
    }
    let uncertainty = ev.covariance.map_or_else(Uncertainty::default, |c| {
        let rotation = block_rows(|r, k| c[(r, k)], 0, 3);
        let direction = block_rows(|r, k| c[(r, k)], 3, 2);
        Uncertainty {
            rotation_sigma_deg: Some(rms_of(&rotation, 1f64.to_degrees())),
            translation_direction_sigma_deg: Some(rms_of(&direction, 1f64.to_degrees())),
            rotation_covariance: Some(rotation),
            translation_direction_covariance: Some(direction),
            ..Uncertainty::default()
        }
    });
    Quality::judge(
        support,
        ev.sigma_px,
        ev.iterations,
        true,
        uncertainty,
        &flags,
        cfg,
    )
}
