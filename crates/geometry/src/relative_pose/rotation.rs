//! The rotation-only case of the two-view pipeline: a motion explained by `f2 ~ R f1` alone
//! (pure rotation, or a homography at infinity), fitted on the unit rays.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::estimators::{Correspondences, HomographyEstimator, HomographyModel};
use crate::ransac::Estimator;

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
    let est = HomographyEstimator(data);
    let inliers_of = |r: &Rotation3<f64>| -> Vec<usize> {
        let rm = HomographyModel {
            h: *r.matrix(),
            h_inv: r.matrix().transpose(),
        };
        (0..data.len())
            .filter(|&i| est.residual_sq(&rm, i) < threshold * threshold)
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
