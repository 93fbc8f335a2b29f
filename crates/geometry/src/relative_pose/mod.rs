//! Two-view relative pose from pixel correspondences.
//!
//! Pipeline of [`estimate_relative_pose`], one module per step:
//! 1. `prepare`: validation and undistortion of the pixels into normalized coordinates `x_n`;
//! 2. `select`, model selection: LO-MSAC of the essential matrix (five-point samples, Sampson error, threshold
//!    `ransac.threshold / f` with `f = (fx + fy) / 2`) and of a homography (four-point DLT,
//!    symmetric transfer error), the latter with the iteration budget that would find it if it
//!    explained as many correspondences as the essential matrix;
//!    then the choice as in ORB-SLAM's initialiser: with `sigma = ransac.threshold`,
//!    `S_H = sum_i sum_{images} max(0, 5.99 - d^2 / sigma^2)` over transfer errors and
//!    `S_E = sum_i sum_{images} [d^2 / sigma^2 < 3.84] (5.99 - d^2 / sigma^2)` over distances to
//!    the epipolar lines; the homography is used when `S_H / (S_H + S_E) > homography_ratio`;
//! 3. `recover`, pose recovery: the four factorisations of `E` (or up to eight of `H`) are triangulated and
//!    the one with most points in front of both cameras and closer than the far limit kept;
//! 4. `choose`, refinement of `(R, t)` (`t` on the unit sphere) on the inliers by Huber IRLS on the
//!    Sampson distance; when the homography was selected, the essential matrix's own motion is
//!    refined too and the lower MSAC Sampson cost wins; the chosen motion then gets a
//!    maximum-likelihood refit ([`refine_maximum_likelihood`]: Huber on the Sampson distance at
//!    a noise scale estimated from its own residuals, `3 sigma` gate, re-selection until the
//!    gated set is stable); final inliers and points from the refined pose (here);
//! 5. `low_parallax` flags a translation direction undetermined at its stated uncertainty
//!    (its sigma above `quality.max_direction_sigma_deg`, no translation seen above the noise
//!    in the derotated disparities, or a median parallax under the optional
//!    `min_parallax_deg`); when a rotation alone explains at least 90% of the model's inliers
//!    the motion is a pure rotation (`rotation`, the rotation-only case): least-squares
//!    rotation of the rays, zero translation; inlier rays of either view that lie in one plane
//!    through its centre (points on an image line: a family of motions fits them) flag
//!    `degenerate`;
//! 6. the quality record ([`RelativePose::quality`]): fewer than five final inliers is
//!    [`GeometryError::NoModel`]; otherwise support, the a-contrario chance test and the
//!    covariance `sigma^2 (J^T J)^-1` of `(R, t)` from the Sampson Jacobian on the refit's
//!    gated correspondences (widened along any axis where the cost rises less than its
//!    quadratic model, [`sampson_covariance`]; raised where the errors of neighbouring
//!    keypoints are correlated; plus the intrinsics' uncertainty through
//!    [`intrinsics_sensitivity`]) decide `ok`, `unreliable` or `failed`.
//!
//! Module layers (each imports only those above it): `correspondences`, `types` and
//! [`crate::residual`] (the one place each error is written); `refine` (the Sampson
//! least-squares problem) and `quality`; `estimators` (RANSAC models); `prepare`; `select`;
//! `rotation`; `recover`; `choose`; this file.

mod choose;
mod correspondences;
mod estimators;
mod prepare;
mod quality;
mod recover;
mod refine;
mod rotation;
mod select;
mod types;

pub use correspondences::Correspondences;
pub use estimators::{EssentialEstimator, HomographyEstimator, HomographyModel};
pub use refine::{
    intrinsics_sensitivity, refine_maximum_likelihood, refine_relative_pose,
    refine_relative_pose_fit, sampson_covariance, sampson_information, tangent_basis,
    MlRefineConfig, RelRefinement, RelState, KEYPOINT_CELL_PX,
};
pub use types::{Model, RansacIterations, RelativePose, RelativePoseConfig, LO_MAX_INLIERS};

use nalgebra::Vector2;
use vofront_robust::Reason;

use crate::camera::Camera;
use crate::error::GeometryError;
use crate::essential::select_by_chirality;
use crate::lie::hat;
use crate::ransac::Estimator;
use crate::residual::row_major;
use choose::{refine_and_choose, Chosen};
use prepare::{TwoView, MIN_CORRESPONDENCES};
use select::Selection;
use types::isometry;

/// Estimates `T_21` (unit translation) from pixel correspondences `x1[i] <-> x2[i]` of a
/// calibrated camera; see the module documentation for the pipeline.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector2, Vector3};
/// use vofront_geometry::{Camera, Pinhole};
/// use vofront_geometry::relative_pose::{estimate_relative_pose, RelativePoseConfig};
/// let cam = Camera::pinhole(Pinhole::new(520.0, 520.0, 320.0, 240.0).unwrap());
/// let t21 = Isometry3::new(Vector3::new(0.3, 0.05, 0.1), Vector3::new(0.05, 0.1, 0.02));
/// let (mut x1, mut x2) = (vec![], vec![]);
/// for i in 0..100 {
///     let f = i as f64;
///     let p = Point3::new((f * 0.37).sin() * 2.0, (f * 0.73).cos() * 1.5, 2.0 + (f * 0.51).sin().abs() * 6.0);
///     x1.push(cam.project(&p.coords).unwrap());
///     x2.push(cam.project(&(t21 * p).coords).unwrap());
/// }
/// let rel = estimate_relative_pose(&x1, &x2, &cam, &RelativePoseConfig::default()).unwrap();
/// assert!(rel.rotation().angle_to(&t21.rotation) < 1e-6);
/// assert!((rel.translation() - t21.translation.vector.normalize()).norm() < 1e-6);
/// ```
pub fn estimate_relative_pose(
    x1: &[Vector2<f64>],
    x2: &[Vector2<f64>],
    camera: &Camera,
    cfg: &RelativePoseConfig,
) -> Result<RelativePose, GeometryError> {
    let tv = TwoView::new(x1, x2, camera, cfg)?;
    let selection = select::select_model(&tv);
    let recovery = recover::recover_motion(&tv, &selection)?;
    if rotation::is_pure_rotation(&tv, &selection, recovery.model) || recovery.has_no_motion() {
        let parallax_deg = recovery.selected().map_or(0.0, |r| r.median_parallax_deg);
        let starts = recovery.rotation_starts(&selection);
        return rotation::rotation_only_pose(
            &tv,
            &selection,
            recovery.model,
            &starts,
            parallax_deg,
        );
    }
    let chosen = refine_and_choose(&tv, &selection, &recovery)?;
    general_pose(&tv, &selection, chosen)
}

/// The covariance of `(phi, a, b)` that the intrinsics' uncertainty adds,
/// `V diag(sigma_f^2, sigma_c^2, sigma_c^2) V^T` ([`intrinsics_sensitivity`],
/// [`RelativePoseConfig::focal_uncertainty`],
/// [`RelativePoseConfig::principal_point_uncertainty_px`]); zero when the sensitivity is
/// unknown.
fn intrinsics_covariance(
    tv: &TwoView,
    indices: &[usize],
    state: &refine::RelState,
) -> nalgebra::Matrix5<f64> {
    let prior = nalgebra::Vector3::new(
        tv.cfg.focal_uncertainty,
        tv.cfg.principal_point_uncertainty_px,
        tv.cfg.principal_point_uncertainty_px,
    )
    .map(|s| s * s);
    intrinsics_sensitivity(&tv.data, indices, tv.focal, state)
        .map_or_else(nalgebra::Matrix5::zeros, |v| {
            v * nalgebra::Matrix3::from_diagonal(&prior) * v.transpose()
        })
}

/// The pose of a general (translating) motion from the chosen refined state: the final
/// inliers (Sampson distance under the threshold) and their points from the chirality test,
/// the flags, and the quality record with the covariance ([`sampson_covariance`]) on the
/// maximum-likelihood refit's gated correspondences.
fn general_pose(
    tv: &TwoView,
    sel: &Selection,
    chosen: Chosen,
) -> Result<RelativePose, GeometryError> {
    let (data, state) = (&tv.data, chosen.state);
    let thr_sq = tv.threshold * tv.threshold;
    let est = EssentialEstimator(data, 0.5 * tv.threshold);
    let e = hat(&state.1) * state.0.matrix();
    let mask: Vec<bool> = (0..data.len())
        .map(|k| est.residual_sq(&e, k) < thr_sq)
        .collect();
    let (b1, b2) = tv.rays();
    let final_rec =
        select_by_chirality(&[(state.0, state.1)], &b1, &b2, &mask, &tv.recover_config())
            .ok_or_else(|| GeometryError::Degenerate("refined pose lost chirality".into()))?;
    let used: Vec<usize> = (0..data.len()).filter(|&k| mask[k]).collect();
    if used.len() < MIN_CORRESPONDENCES {
        return Err(GeometryError::NoModel {
            best: used.len(),
            need: MIN_CORRESPONDENCES,
        });
    }
    // The information comes from the correspondences the maximum-likelihood refit used (its
    // `3 sigma` gate), not from the inlier threshold, which may cut into the noise.
    let gate_sq = (MlRefineConfig::default().gate_sigmas * chosen.sigma_px / tv.focal).powi(2);
    let gated: Vec<usize> = (0..data.len())
        .filter(|&k| est.residual_sq(&e, k) < gate_sq.max(thr_sq))
        .collect();
    let e_rm = row_major(&e);
    // The covariance's two parts are independent: computed at once.
    let (covariance, intrinsics) = rayon::join(
        || sampson_covariance(data, &gated, tv.focal, &state, chosen.sigma_px),
        || intrinsics_covariance(tv, &gated, &state),
    );
    let evidence = quality::Evidence {
        candidates: tv.n_in,
        inliers: used.len(),
        tested: data.len(),
        p0: quality::chance_rate(data, |c, k| c.epipolar(&e_rm, k).sampson_sq() < thr_sq),
        hypotheses: sel.hypotheses(),
        sample: MIN_CORRESPONDENCES,
        sigma_px: chosen.sigma_px,
        translation: true,
        covariance: covariance.map(|c| c + intrinsics),
        iterations: sel.iterations.total(),
    };
    let direction_unseen = final_rec.median_parallax_deg < tv.cfg.min_parallax_deg
        || !quality::translation_is_seen(data, &used, state.0.matrix(), tv.focal, chosen.sigma_px);
    let coplanar = quality::rays_are_coplanar(used.iter().map(|&k| &b1[k]))
        || quality::rays_are_coplanar(used.iter().map(|&k| &b2[k]));
    let flags: Vec<Reason> = [
        (direction_unseen, Reason::LowParallax),
        (chosen.ambiguous, Reason::PlanarAmbiguous),
        (coplanar, Reason::Degenerate),
    ]
    .into_iter()
    .filter_map(|(on, r)| on.then_some(r))
    .collect();
    let mut points = vec![None; tv.n_in];
    for (k, &i) in tv.index.iter().enumerate() {
        points[i] = final_rec.points[k];
    }
    let inliers = tv.input_mask(&used);
    let pose = isometry(&state.0, &state.1);
    let quality = quality::judge(&evidence, &flags, &tv.cfg.quality);
    Ok(RelativePose {
        pose,
        model: chosen.model,
        inliers,
        points,
        parallax_deg: final_rec.median_parallax_deg,
        low_parallax: quality.reasons.contains(&Reason::LowParallax),
        pure_rotation: false,
        ambiguous: chosen.ambiguous,
        alternative: chosen.alternative,
        homography_score_ratio: sel.ratio,
        iterations: sel.iterations,
        quality,
    })
}
