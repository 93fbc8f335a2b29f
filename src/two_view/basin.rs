//! Whether the direct SE(3) pose of a pair is the alignment's only answer.
//!
//! A pair has no motion model to start from: its alignment starts at the identity and settles
//! in the minimum whose basin holds that start. When the true motion lies beyond the basin (a
//! metre of forward motion on a highway, against depths of tens of metres), the nearest minimum
//! can fit the images about as well as the truth and pass every test of the fit. Aligning again
//! from the identity displaced by `+-` [`START_STEP_OF_DEPTH`] of the median depth along the
//! optical axis tells the two cases apart: in one basin every start reaches the same pose (on
//! the TUM pairs, the same to 0.1 mm); where a displaced start ends elsewhere, beyond
//! [`MAX_DISAGREEMENT_SIGMAS`] of the pose's stated sigmas, with a fit that is not `failed`,
//! the images admit more than one answer and the pose is flagged [`Reason::Inconsistent`].
//!
//! [`MAX_DISAGREEMENT_SIGMAS`]: super::stereo::MAX_DISAGREEMENT_SIGMAS
//! [`Reason::Inconsistent`]: vofront_robust::Reason::Inconsistent

use nalgebra::Isometry3;
use vofront_core::lie::se3_log;
use vofront_direct::{DirectError, Se3Config, Se3Reference, Se3Result};
use vofront_image::Image;
use vofront_robust::Verdict;

use super::stereo::flag_if_inconsistent;

/// Displacement of the extra starts along the optical axis, as a fraction of the reference's
/// median depth: within the basin of a well-posed pair (a few percent of the depth is a few
/// pixels of flow at the image's edge), beyond the nearest wrong minimum of one that is not.
pub const START_STEP_OF_DEPTH: f64 = 0.05;

/// `T_21` starts displaced by `+-START_STEP_OF_DEPTH * median_depth` along the optical axis.
pub fn displaced_starts(median_depth: f64) -> [Isometry3<f64>; 2] {
    let step = START_STEP_OF_DEPTH * median_depth;
    [
        Isometry3::translation(0.0, 0.0, step),
        Isometry3::translation(0.0, 0.0, -step),
    ]
}

/// The largest disagreement of `fit` with the fits `others` of the same pair from other
/// starts that are not `failed`, in the larger of rotation angle and translation distance
/// divided by `sqrt 2` times `fit`'s RMS sigma of each (both fits' sigmas alike). `None` when no
/// other fit counts or `fit` states no sigmas.
pub fn basin_disagreement_sigmas(fit: &Se3Result, others: &[Se3Result]) -> Option<f64> {
    let u = &fit.quality.uncertainty;
    let (rot_sigma, t_sigma) = (u.rotation_sigma_deg?, u.translation_sigma_m?);
    others
        .iter()
        .filter(|o| o.quality.verdict != Verdict::Failed)
        .map(|o| {
            let d = se3_log(&(o.pose * fit.pose.inverse()));
            let rotation = d.fixed_rows::<3>(3).norm().to_degrees() / (rot_sigma * 2f64.sqrt());
            let translation = d.fixed_rows::<3>(0).norm() / (t_sigma * 2f64.sqrt());
            rotation.max(translation)
        })
        .filter(|s| s.is_finite())
        .reduce(f64::max)
}

/// Aligns `current` to `reference` from the identity and, when that fit is `ok`, again from
/// [`displaced_starts`] of `median_depth` (the two at once); flags the fit inconsistent when
/// the others disagree with it too far ([`basin_disagreement_sigmas`],
/// [`flag_if_inconsistent`]). Errors of the identity start only.
pub fn align_from_identity(
    reference: &Se3Reference,
    current: &Image<f32>,
    median_depth: f64,
    cfg: &Se3Config,
) -> Result<Se3Result, DirectError> {
    let mut fit = reference.align(current, &Isometry3::identity(), cfg)?;
    if !fit.quality.is_ok() || !median_depth.is_finite() || median_depth <= 0.0 {
        return Ok(fit);
    }
    let [ahead, behind] = displaced_starts(median_depth);
    let (a, b) = rayon::join(
        || reference.align(current, &ahead, cfg),
        || reference.align(current, &behind, cfg),
    );
    let others: Vec<Se3Result> = [a, b].into_iter().filter_map(Result::ok).collect();
    let sigmas = basin_disagreement_sigmas(&fit, &others);
    flag_if_inconsistent(&mut fit.quality, sigmas);
    Ok(fit)
}
