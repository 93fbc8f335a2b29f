//! Umeyama's closed-form least-squares similarity between two point sets (IEEE PAMI 1991).
//!
//! Given pairs `(x_i, y_i)`, finds `(s, R, t)` minimising `sum |y_i - (s R x_i + t)|^2`:
//! with means `mx, my`, variance `sx = 1/n sum |x_i - mx|^2`, covariance
//! `C = 1/n sum (y_i - my)(x_i - mx)^T = U D V^T`, `S = diag(1, 1, det(U) det(V) < 0 ? -1 : 1)`:
//! `R = U S V^T`, `s = tr(D S) / sx` (or 1 without scale), `t = my - s R mx`.
//! The same equations as evo's `umeyama_alignment`, including its degeneracy test.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3, SVD};

use super::EvalError;

/// A similarity transform `y = s R x + t` (for `s = 1` a rigid motion; `Serialize`:
/// `rotation` as `[qi, qj, qk, qw]`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Sim3 {
    /// Rotation `R`.
    pub rotation: UnitQuaternion<f64>,
    /// Translation `t` (units of `y`).
    pub translation: Vector3<f64>,
    /// Scale `s` (units of `y` per unit of `x`).
    pub scale: f64,
}

impl Default for Sim3 {
    /// The identity.
    fn default() -> Self {
        Self {
            rotation: UnitQuaternion::identity(),
            translation: Vector3::zeros(),
            scale: 1.0,
        }
    }
}

impl Sim3 {
    /// `s R x + t`.
    pub fn transform_point(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.scale * (self.rotation * x) + self.translation
    }

    /// Moves a pose `T_wc` of the `x` world into the `y` world: position
    /// `s R p + t`, orientation `R R_wc` (as evo's `scale` then `transform`).
    pub fn transform_pose(&self, pose: &Isometry3<f64>) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.transform_point(&pose.translation.vector)),
            self.rotation * pose.rotation,
        )
    }
}

/// The similarity (`with_scale`) or rigid motion mapping the points `x` onto `y` in the
/// least-squares sense. Errors: different lengths, fewer than 3 points, non-finite input,
/// or a covariance of rank below 2 (collinear or coincident points).
pub fn umeyama(
    x: &[Vector3<f64>],
    y: &[Vector3<f64>],
    with_scale: bool,
) -> Result<Sim3, EvalError> {
    if x.len() != y.len() {
        return Err(EvalError::LengthMismatch(x.len(), y.len()));
    }
    if x.len() < 3 {
        return Err(EvalError::TooFewPoses(x.len()));
    }
    if x.iter().chain(y).any(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(EvalError::NotFinite);
    }
    let n = x.len() as f64;
    let mx = x.iter().sum::<Vector3<f64>>() / n;
    let my = y.iter().sum::<Vector3<f64>>() / n;
    let sigma_x = x.iter().map(|p| (p - mx).norm_squared()).sum::<f64>() / n;
    let cov = x.iter().zip(y).fold(Matrix3::zeros(), |acc, (a, b)| {
        acc + (b - my) * (a - mx).transpose()
    }) / n;
    let svd = SVD::new(cov, true, true);
    let (u, v_t) = (svd.u.expect("requested U"), svd.v_t.expect("requested V^T"));
    let d = svd.singular_values;
    if d.iter().filter(|&&s| s > f64::EPSILON).count() < 2 {
        return Err(EvalError::Degenerate);
    }
    let mut s = Vector3::new(1.0, 1.0, 1.0);
    if u.determinant() * v_t.determinant() < 0.0 {
        s.z = -1.0;
    }
    let r = u * Matrix3::from_diagonal(&s) * v_t;
    let scale = if with_scale { d.dot(&s) / sigma_x } else { 1.0 };
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Sim3 {
        rotation,
        translation: my - scale * (r * mx),
        scale,
    })
}
