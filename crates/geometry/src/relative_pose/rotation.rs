//! The rotation-only case of the two-view pipeline: a motion explained by `f2 ~ R f1` alone
//! (pure rotation, or a homography at infinity), fitted on the unit rays.
//!
//! The motion is a pure rotation when the rotation-only model explains at least 90% of the
//! selected model's inliers, or when no motion has five points in front of both cameras. Its
//! pose is the least-squares rotation of the rays with a zero translation, flagged
//! `pure_rotation` and `low_parallax`.

use nalgebra::{Matrix3, Rotation3, Vector3};
use vofront_robust::Reason;

use super::correspondences::Correspondences;
use super::estimators::HomographyModel;
use super::prepare::{TwoView, MIN_CORRESPONDENCES};
use super::quality;
use super::select::Selection;
use super::types::{isometry, Model, RelativePose};
use crate::error::GeometryError;

/// Fraction of the selected model's inliers that a rotation alone must explain for the motion
/// to be declared a pure rotation.
const ROTATION_SUPPORT: f64 = 0.9;
/// Minimal sample of a rotation-only model (two rays fix a rotation).
const ROTATION_SAMPLE: usize = 2;

/// The rotation nearest to the homography, when one was found.
pub(super) fn homography_rotation(sel: &Selection) -> Option<Rotation3<f64>> {
    sel.homography
        .as_ref()
        .map(|h| nearest_rotation(&h.model.h))
}

/// The rotation-only model refined from the homography explains at least
/// [`ROTATION_SUPPORT`] of the inliers of `model`'s fit.
pub(super) fn is_pure_rotation(tv: &TwoView, sel: &Selection, model: Model) -> bool {
    let explained = homography_rotation(sel).map_or(0, |r| {
        refine_rotation(&tv.data, r, tv.transfer_threshold())
            .1
            .len()
    });
    explained as f64 >= ROTATION_SUPPORT * sel.support(model) as f64
}

/// The pose of a pure rotation: of the `starts`, the rotation whose refinement
/// ([`refine_rotation`]) explains most correspondences, with a zero translation and its
/// quality record (noise scale from the transfer errors, no covariance).
pub(super) fn rotation_only_pose(
    tv: &TwoView,
    sel: &Selection,
    model: Model,
    starts: &[Rotation3<f64>],
    parallax_deg: f64,
) -> Result<RelativePose, GeometryError> {
    let (data, threshold) = (&tv.data, tv.transfer_threshold());
    let (rotation, inl) = starts
        .iter()
        .map(|r| refine_rotation(data, *r, threshold))
        .max_by_key(|(_, inl)| inl.len())
        .ok_or_else(|| GeometryError::Degenerate("no motion in front of both cameras".into()))?;
    if inl.len() < MIN_CORRESPONDENCES {
        return Err(GeometryError::NoModel {
            best: inl.len(),
            need: MIN_CORRESPONDENCES,
        });
    }
    let rotation_model = HomographyModel::rotation(&rotation);
    let residuals: Vec<f64> = inl
        .iter()
        .map(|&k| rotation_model.residual_sq(data, k).sqrt() * tv.focal)
        .collect();
    let evidence = quality::Evidence {
        candidates: tv.n_in,
        inliers: inl.len(),
        tested: data.len(),
        p0: quality::chance_rate(data, |c, k| {
            rotation_model.residual_sq(c, k) < threshold * threshold
        }),
        hypotheses: sel.hypotheses(),
        sample: ROTATION_SAMPLE,
        sigma_px: vofront_robust::mad_sigma_about_zero(&residuals).unwrap_or(tv.sigma_px),
        translation: false,
        covariance: None,
        iterations: sel.iterations.total(),
    };
    let flags = [Reason::PureRotation, Reason::LowParallax];
    let pose = isometry(&rotation, &Vector3::zeros());
    Ok(RelativePose {
        pose,
        model,
        inliers: tv.input_mask(&inl),
        points: vec![None; tv.n_in],
        parallax_deg,
        low_parallax: true,
        pure_rotation: true,
        ambiguous: false,
        alternative: None,
        homography_score_ratio: sel.ratio,
        iterations: sel.iterations,
        quality: quality::judge(&evidence, &flags, &tv.cfg.quality),
    })
}

/// Least-squares rotation of a pure rotation `f2 ~ R f1` over the correspondences `indices`
/// (orthogonal Procrustes on the unit rays): `R = U diag(1, 1, det(U V^T)) V^T` from the SVD of
/// `sum f2 f1^T`.
pub(super) fn rotation_from_rays(data: &Correspondences, indices: &[usize]) -> Rotation3<f64> {
    let m: Matrix3<f64> = indices
        .iter()
        .map(|&i| data.ray2(i).normalize() * data.ray1(i).normalize().transpose())
        .sum();
    nearest_rotation(&m)
}

/// Alternates rotation-only inliers (transfer error under `threshold`) and the least-squares
/// rotation on them, a few rounds from `r`; returns the rotation and its inliers.
pub(super) fn refine_rotation(
    data: &Correspondences,
    mut r: Rotation3<f64>,
    threshold: f64,
) -> (Rotation3<f64>, Vec<usize>) {
    let inliers_of = |r: &Rotation3<f64>| -> Vec<usize> {
        let rm = HomographyModel::rotation(r);
        (0..data.len())
            .filter(|&i| rm.residual_sq(data, i) < threshold * threshold)
            .collect()
    };
    let mut inl = inliers_of(&r);
    for _ in 0..3 {
        if inl.len() < 3 {
            break;
        }
        r = rotation_from_rays(data, &inl);
        inl = inliers_of(&r);
    }
    (r, inl)
}

/// The rotation nearest (Frobenius) to `H` scaled to `det > 0`: `U V^T` of its SVD.
pub(super) fn nearest_rotation(h: &Matrix3<f64>) -> Rotation3<f64> {
    let m = if h.determinant() < 0.0 { -h } else { *h };
    let svd = m.svd(true, true);
    match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => {
            let d = (u * v_t).determinant().signum();
            let fix = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d));
            Rotation3::from_matrix_unchecked(u * fix * v_t)
        }
        _ => Rotation3::identity(),
    }
}
