//! Does a monocular map's two-view start depend on which samples RANSAC drew?
//!
//! A scene seen far away along the direction of travel lets the epipolar cost trade a turn for
//! a sideways step (the bas-relief ambiguity): it can hold two minima with nearly the same
//! support, and RANSAC lands in either depending on its samples. The covariance at a minimum
//! describes that minimum only, so a wrong start is stated as precisely as a right one
//! (`kitti_01` played backwards, frames 0 and 14: seeds 0 and 1 give a pose 3.95 deg and 30
//! deg off with sigmas of 0.45 and 2.6 deg, `ok`, six other seeds one within 1.1 and 3.3 deg;
//! README). A map inherits its start, and every later frame agrees with it.
//!
//! So a start the initialiser would accept is estimated again from [`REDRAWS`] other RANSAC
//! seeds; when a redraw that is not `failed` lies more than
//! [`MAX_DISAGREEMENT_SIGMAS`] combined
//! stated sigmas from it (the stereo two-view's bound against the epipolar estimate; rotation
//! and direction of travel judged together, [`disagreement_sigmas`]), the data admit two
//! starts and the initialiser waits for more motion. It costs three more two-view estimates once per accepted start.

use nalgebra::Vector2;
use rayon::prelude::*;
use vofront_core::Camera;
use vofront_geometry::{estimate_relative_pose, RelativePose, RelativePoseConfig};
use vofront_robust::Verdict;

use crate::two_view::stereo::{combined_sigmas, MAX_DISAGREEMENT_SIGMAS};

/// Further RANSAC draws a start is checked against.
pub const REDRAWS: u64 = 3;

/// Odd stride between the seeds of the redraws (`seed + k * stride`), so that they share no
/// random sequence with the start's own seed.
const SEED_STRIDE: u64 = 0x9E37_79B9_7F4A_7C15;

/// How far two relative poses of the same pair are apart, in their combined stated sigmas:
/// `hypot(z_rot, z_dir)`, `z_rot = angle(R_a R_b^T) / hypot(sigma_a, sigma_b)` over the RMS
/// rotation sigmas and `z_dir = angle(t_a, t_b) / hypot(sigma_a, sigma_b)` over the direction
/// sigmas (degrees, [`combined_sigmas`]); `None` when a sigma is unknown or a translation is
/// zero.
pub fn disagreement_sigmas(a: &RelativePose, b: &RelativePose) -> Option<f64> {
    let (ua, ub) = (&a.quality.uncertainty, &b.quality.uncertainty);
    let (ta, tb) = (a.pose.translation.vector, b.pose.translation.vector);
    if ta.norm() == 0.0 || tb.norm() == 0.0 {
        return None;
    }
    let rotation = (a.pose.rotation * b.pose.rotation.inverse())
        .angle()
        .to_degrees();
    combined_sigmas(&[
        Some((rotation, ua.rotation_sigma_deg?, ub.rotation_sigma_deg?)),
        Some((
            ta.angle(&tb).to_degrees(),
            ua.translation_direction_sigma_deg?,
            ub.translation_direction_sigma_deg?,
        )),
    ])
}

/// The largest disagreement ([`disagreement_sigmas`]) of `start` (estimated from `x1`, `x2`
/// with `cfg`) with the redraws of the same correspondences from [`REDRAWS`] other seeds that
/// are not `failed`; 0 when none compares.
pub fn redraw_disagreement_sigmas(
    x1: &[Vector2<f64>],
    x2: &[Vector2<f64>],
    camera: &Camera,
    cfg: &RelativePoseConfig,
    start: &RelativePose,
) -> f64 {
    (1..=REDRAWS)
        .into_par_iter()
        .filter_map(|k| {
            let mut redraw = *cfg;
            redraw.ransac.seed = cfg.ransac.seed.wrapping_add(k.wrapping_mul(SEED_STRIDE));
            let other = estimate_relative_pose(x1, x2, camera, &redraw).ok()?;
            (other.quality.verdict != Verdict::Failed)
                .then(|| disagreement_sigmas(start, &other))
                .flatten()
        })
        .reduce(|| 0.0, f64::max)
}

/// [`redraw_disagreement_sigmas`] when it exceeds [`MAX_DISAGREEMENT_SIGMAS`]: `start` is one
/// of two starts the data admit; `None` when the redraws agree with it.
pub fn contradicted(
    x1: &[Vector2<f64>],
    x2: &[Vector2<f64>],
    camera: &Camera,
    cfg: &RelativePoseConfig,
    start: &RelativePose,
) -> Option<f64> {
    let sigmas = redraw_disagreement_sigmas(x1, x2, camera, cfg, start);
    (sigmas > MAX_DISAGREEMENT_SIGMAS).then_some(sigmas)
}
