//! The noise a 3D point's own uncertainty adds to its reprojection: the whitening of one
//! residual for the refinement ([`point_whitening`]) and the covariance it adds to a pose
//! refined without it ([`add_point_covariances`]).
//!
//! A point `P` with covariance `C` (world frame, metres^2) seen by `T_cw` moves its pixel by
//! `G dP`, `G = jpix R_cw` (`jpix` the projection's Jacobian at `x = T_cw P`, pixels per
//! metre): its residual's covariance is `sigma_px^2 s^2 I + G C G^T` for a pixel of relative
//! noise scale `s` at the nominal noise `sigma_px`.

use nalgebra::{Isometry3, Matrix2, Matrix3, Matrix6, Point3, Vector2};

use super::{pnp_uncertainty, project_in_front, reprojection, PnpConfig, PnpResult};
use crate::camera::Camera;
use crate::lie::point_jacobian;
use vofront_robust::{at_least, Reason};

/// The whitening `W = L^-1` of one residual, `L L^T = s^2 I + G C G^T / sigma_px^2` (the
/// residual's covariance in units of `sigma_px^2`; module documentation), at the pose `t`
/// (`T_cw`): `|W r|` is the residual's Mahalanobis length in units of `sigma_px`. `I / s` for a
/// point without a covariance, one behind the camera or outside the lens's range at `t`, or one
/// whose noise is not positive definite.
pub(super) fn point_whitening(
    camera: &Camera,
    t: &Isometry3<f64>,
    p: &Point3<f64>,
    s: f64,
    covariance: Option<&Matrix3<f64>>,
    sigma_px: f64,
) -> Matrix2<f64> {
    let isotropic = Matrix2::identity() / s;
    let Some(c) = covariance else {
        return isotropic;
    };
    let Some((_, jpix)) = project_in_front(camera, &(t * p).coords) else {
        return isotropic;
    };
    let g = jpix * t.rotation.to_rotation_matrix().matrix();
    let noise = Matrix2::identity() * (s * s) + g * c * g.transpose() / (sigma_px * sigma_px);
    // Lower Cholesky factor `[[a, 0], [b, d]]` of the 2x2 noise and its inverse.
    let a = noise[(0, 0)].sqrt();
    let b = noise[(1, 0)] / a;
    let d = (noise[(1, 1)] - b * b).sqrt();
    let whitening = Matrix2::new(1.0 / a, 0.0, -b / (a * d), 1.0 / d);
    if whitening.iter().all(|v| v.is_finite()) {
        whitening
    } else {
        isotropic
    }
}

/// `|W (pi(T_cw P) - u)|`, the whitened reprojection error of the world point `p` observed at
/// `u`; infinite behind the camera.
pub(super) fn whitened_error(
    camera: &Camera,
    t: &Isometry3<f64>,
    p: &Point3<f64>,
    u: &Vector2<f64>,
    whitening: &Matrix2<f64>,
) -> f64 {
    reprojection(camera, t, p, u).map_or(f64::INFINITY, |r| (whitening * r).norm())
}

/// Raises `fit`'s covariance to what the uncertainty of its 3D points implies where that is
/// wider. PnP's own covariance is the empirical sandwich of its residuals: it sees a point's
/// error only through the residual it leaves, not through the part the pose absorbs, and not
/// at all when the points' errors are shared (a keyframe's stereo depths, its pose). With `J_i`
/// the whitened Jacobian of inlier `i`'s residual in the pose (`jpix [I | -hat(T P)] / s_i`),
/// `G_i = jpix R / s_i` its Jacobian in the point and `C_i` the point's covariance (world
/// frame, metres^2), the model covariance at the nominal pixel noise `cfg.sigma_px` is
///
/// `Sigma_model = H^-1 (sum_i J_i^T (sigma_px^2 I + G_i C_i G_i^T) J_i) H^-1`,  `H = sum_i J_i^T J_i`
///
/// (the Gauss-Newton step's response to both noises), and the result is
/// [`at_least`]`(Sigma, Sigma_model)`. `world`, `sigmas` (each pixel's relative noise scale)
/// and `covariances` are index-aligned with `fit.inliers`; points without a covariance add
/// no point term. The quality's uncertainty follows, and a rotation sigma now above
/// `cfg.quality.max_rotation_sigma_deg` adds [`Reason::LargeUncertainty`]. Nothing changes
/// without a covariance in `fit` or when `H` is singular.
pub fn add_point_covariances(
    fit: &mut PnpResult,
    camera: &Camera,
    world: &[Point3<f64>],
    sigmas: &[f64],
    covariances: &[Option<Matrix3<f64>>],
    cfg: &PnpConfig,
) {
    let Some(covariance) = fit.covariance else {
        return;
    };
    let rotation = fit.pose.rotation.to_rotation_matrix();
    let mut h = Matrix6::zeros();
    let mut from_points = Matrix6::zeros();
    for (i, _) in fit.inliers.iter().enumerate().filter(|(_, &inlier)| inlier) {
        let (Some(p), Some(&s)) = (world.get(i), sigmas.get(i)) else {
            continue;
        };
        let x = (fit.pose * p).coords;
        let Some((_, jpix)) = project_in_front(camera, &x) else {
            continue;
        };
        let j = jpix * point_jacobian(&x) / s;
        h += j.transpose() * j;
        if let Some(c) = covariances.get(i).copied().flatten() {
            let g = jpix * rotation.matrix() / s;
            from_points += j.transpose() * (g * c * g.transpose()) * j;
        }
    }
    let Some(h_inv) = h.try_inverse() else {
        return;
    };
    let model = h_inv * (h * cfg.sigma_px.powi(2) + from_points) * h_inv;
    let total = at_least(&covariance, &model);
    fit.covariance = Some(total);
    fit.quality.uncertainty = pnp_uncertainty(&total);
    if fit
        .quality
        .uncertainty
        .rotation_sigma_deg
        .is_some_and(|s| s > cfg.quality.max_rotation_sigma_deg)
    {
        fit.quality.flag(Reason::LargeUncertainty);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Pinhole;
    use nalgebra::{Matrix3, Vector3};

    /// `W` whitens the residual's noise: `W (s^2 I + G C G^T / sigma^2) W^T = I` for a point
    /// in front with a covariance; `I / s` without one and behind the camera.
    #[test]
    fn whitening_inverts_the_residual_noise() {
        let camera = Camera::pinhole(Pinhole::new(718.9, 718.9, 607.2, 185.2).unwrap());
        let t = Isometry3::new(
            Vector3::new(0.1, -0.05, 1.5),
            Vector3::new(0.02, -0.1, 0.03),
        );
        let (s, sigma_px) = (1.2, 0.7);
        for (k, depth) in [4.0, 15.0, 60.0].into_iter().enumerate() {
            let p = t.inverse() * Point3::new(2.0 - k as f64, 0.5, depth);
            let ray = p.coords - t.inverse().translation.vector;
            let c = ray * ray.transpose() * 0.03f64.powi(2) + Matrix3::identity() * 1e-4;
            let w = point_whitening(&camera, &t, &p, s, Some(&c), sigma_px);
            let (_, jpix) = project_in_front(&camera, &(t * p).coords).unwrap();
            let g = jpix * t.rotation.to_rotation_matrix().matrix();
            let noise = Matrix2::identity() * (s * s) + g * c * g.transpose() / sigma_px.powi(2);
            assert!((w * noise * w.transpose() - Matrix2::identity()).norm() < 1e-9);
            let isotropic = Matrix2::identity() / s;
            assert_eq!(
                point_whitening(&camera, &t, &p, s, None, sigma_px),
                isotropic
            );
            let behind = t.inverse() * Point3::new(0.0, 0.0, -depth);
            let w_behind = point_whitening(&camera, &t, &behind, s, Some(&c), sigma_px);
            assert_eq!(w_behind, isotropic);
        }
    }
}
