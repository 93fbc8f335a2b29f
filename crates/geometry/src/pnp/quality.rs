//! The quality record of a PnP pose: support, the chance test and the uncertainty of `T_cw`.

use nalgebra::Matrix6;
use vofront_robust::quality::{block_rows, log10_nfa, rms_of};
use vofront_robust::{Quality, QualityConfig, Reason, Support, Uncertainty};

/// What [`pnp_quality`] rests on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnpEvidence {
    /// Input correspondences.
    pub candidates: usize,
    /// Correspondences with a valid bearing (the chance test's population).
    pub tested: usize,
    /// Inliers of the final pose.
    pub inliers: usize,
    /// Share of re-paired correspondences `(P_i, u_j)` within the inlier threshold of the final
    /// pose ([`repaired_chance_rate`](vofront_robust::quality::repaired_chance_rate)).
    pub p0: f64,
    /// Hypotheses scored: RANSAC iterations times the P3P solutions, plus the prior.
    pub hypotheses: f64,
    /// Per-coordinate whitened reprojection residual scale of the inliers,
    /// `sqrt(sum |W (u - pi(T P))|^2 / (2 n - 6))` (`W = I / s` for a pixel of noise scale `s`
    /// and an exact point; see [`super::solve_pnp_ransac_with_point_covariances`]), pixels.
    pub sigma_px: f64,
    /// Iterations of the Huber refinement.
    pub iterations: usize,
    /// The refinement met its convergence test (true when not refined).
    pub converged: bool,
    /// The refinement's normal equations were singular.
    pub degenerate: bool,
}

/// The quality record of a PnP pose: support `inliers` of `candidates`, the chance test
/// `log10 NFA` of the consensus with a minimal sample of 3 ([`log10_nfa`]), the covariance of
/// the left increment `(rho, phi)` of `T_cw` (metres, radians; 6x6) with
/// `translation_sigma_m = sqrt(tr Sigma_rho)` and `rotation_sigma_deg = sqrt(tr Sigma_phi)`.
pub fn pnp_quality(
    ev: &PnpEvidence,
    covariance: Option<&Matrix6<f64>>,
    cfg: &QualityConfig,
) -> Quality {
    let support = Support {
        log10_nfa: Some(log10_nfa(ev.tested, ev.inliers, 3, ev.p0, ev.hypotheses)),
        ..Support::new(ev.inliers, ev.candidates)
    };
    let uncertainty = covariance.map_or_else(Uncertainty::default, pnp_uncertainty);
    let flags: &[Reason] = if ev.degenerate {
        &[Reason::Degenerate]
    } else {
        &[]
    };
    Quality::judge(
        support,
        ev.sigma_px,
        ev.iterations,
        ev.converged,
        uncertainty,
        flags,
        cfg,
    )
}

/// The uncertainty record of a PnP covariance of `(rho, phi)`: the 6x6 matrix,
/// `translation_sigma_m = sqrt(tr Sigma_rho)` and `rotation_sigma_deg = sqrt(tr Sigma_phi)`.
pub(super) fn pnp_uncertainty(c: &Matrix6<f64>) -> Uncertainty {
    Uncertainty {
        translation_sigma_m: Some(rms_of(&block_rows(|r, k| c[(r, k)], 0, 3), 1.0)),
        rotation_sigma_deg: Some(rms_of(
            &block_rows(|r, k| c[(r, k)], 3, 3),
            1f64.to_degrees(),
        )),
        covariance: Some(block_rows(|r, k| c[(r, k)], 0, 6)),
        ..Uncertainty::default()
    }
}
