//! The covariance an SE(3) alignment inherits from its calibration: intrinsics and depth scale
//! known only to a few per mille, which no number of pixels averages out.
//!
//! The photometric covariance (the sandwich of [`super::Se3Result::covariance`]) describes the
//! image noise at exact intrinsics and depths. A calibration error `k` moves every warped pixel
//! alike, so the estimate moves by `V k` whatever the number of pixels, with `V` the
//! sensitivity of the M-estimate (implicit differentiation of its score equation
//! `sum_i psi(u_i) J_i = 0` at the solution):
//!
//! `V = -B^-1 sum_i psi'(u_i) J_i^T dr_i/dk`,  `B = sum_i psi'(u_i) J_i^T J_i`,
//!
//! and the estimate carries `V S V^T` beyond its noise covariance, `S` the prior covariance of
//! `k` ([`CalibrationPrior`]). The errors `k` (the same intrinsics for both frames):
//!
//! - `s`, a relative focal error (`f -> (1 + s) f`): the reference ray `x = (u - c) / f`
//!   shrinks, `dP/ds = -Z (x, y, 0)`, and the projection grows, `dw/ds = w - c`; with depths
//!   from a disparity (`Z = f b / d`) the depth grows too, `dP/ds = (0, 0, Z)`;
//! - `c_x`, `c_y`, a principal-point error in pixels: `dP/dc_x = -Z (1 / f_x, 0, 0)` and
//!   `dw/dc_x = (1, 0)` (likewise `c_y`);
//! - `beta`, a relative depth-scale error (a depth sensor's scale, a stereo baseline):
//!   `dP/dbeta = P`.
//!
//! With `P' = R P + t` and the image gradient `g` at the warped pixel, `dr/dk = g^T dw/dk`,
//! `dw/dk = dpi/dP' R dP/dk + (the direct term)`; `g^T dpi/dP'` is the translation part
//! `(a_x, a_y, a_z)` of the residual's Jacobian row and `g = (a_x, a_y) Z' / f`, so the rows
//! already computed give every derivative.

use nalgebra::{Matrix3, Matrix4, Matrix6, SMatrix, SVector, Vector3};
use rayon::prelude::*;
use vofront_robust::{Loss, NormalEquations, RobustLoss};

use super::level::{Se3Level, Se3State};
use crate::lm::{CHUNK, SERIAL_MAX};

/// Prior uncertainty (one sigma) of the calibration behind an SE(3) alignment; all zero for
/// exact calibration (rendered scenes). The defaults are those of the two-view pose
/// (`RelativePoseConfig::focal_uncertainty`, `principal_point_uncertainty_px`) and a depth scale
/// known to 1% (a depth camera's scale, a stereo rig's baseline).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationPrior {
    /// Relative sigma of the focal length (both axes alike).
    pub focal: f64,
    /// Sigma of each principal-point coordinate, pixels.
    pub principal_point_px: f64,
    /// Relative sigma of the depth scale.
    pub depth_scale: f64,
    /// The depths come from a disparity, `Z = f b / d`, and so scale with the focal length
    /// (stereo); otherwise they are measured (a depth sensor) or estimated.
    pub depth_from_disparity: bool,
}

impl Default for CalibrationPrior {
    fn default() -> Self {
        Self {
            focal: 0.005,
            principal_point_px: 2.0,
            depth_scale: 0.01,
            depth_from_disparity: false,
        }
    }
}

impl CalibrationPrior {
    /// No calibration uncertainty.
    pub fn exact() -> Self {
        Self {
            focal: 0.0,
            principal_point_px: 0.0,
            depth_scale: 0.0,
            depth_from_disparity: false,
        }
    }

    /// Whether every sigma is zero.
    pub fn is_exact(&self) -> bool {
        self.focal == 0.0 && self.principal_point_px == 0.0 && self.depth_scale == 0.0
    }

    /// `S = diag(focal^2, c^2, c^2, depth_scale^2)` over `(s, c_x, c_y, beta)`.
    fn covariance(&self) -> Matrix4<f64> {
        let c = self.principal_point_px;
        Matrix4::from_diagonal(&nalgebra::Vector4::new(
            self.focal * self.focal,
            c * c,
            c * c,
            self.depth_scale * self.depth_scale,
        ))
    }
}

/// Sensitivity `V` (8x4: pose increment `(rho, phi)`, brightness `(a, b)` by `(s, c_x, c_y,
/// beta)`) of the estimate `state` of the level's valid residuals, robust `loss` at `scale`;
/// parameters in `fixed` do not move. `None` when `B` is not invertible.
fn calibration_sensitivity(
    level: &Se3Level<'_>,
    state: &Se3State,
    loss: &Loss,
    scale: f64,
    fixed: &[bool; 8],
    depth_from_disparity: bool,
) -> Option<SMatrix<f64, 8, 4>> {
    let rot: Matrix3<f64> = state.pose.rotation.to_rotation_matrix().into_inner();
    let t = state.pose.translation.vector;
    let r = level.reference;
    let [fx, fy, _, _] = r.k.map(f64::from);
    let mask = SVector::<f64, 8>::from_fn(|i, _| if fixed[i] { 0.0 } else { 1.0 });
    let n = level.residuals.len();
    // One pair of accumulators per chunk of rows, as the normal equations are reduced.
    let chunk = |c: usize| {
        let mut bread = NormalEquations::<8>::new();
        let mut cross = SMatrix::<f64, 8, 4>::zeros();
        for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
            let res = level.residuals[i];
            if res.is_nan() {
                continue;
            }
            let weight = loss.psi_prime(f64::from(res) / scale);
            let j = SVector::<f64, 8>::from(level.jacobians[i].map(f64::from)).component_mul(&mask);
            let p = Vector3::new(r.x[i], r.y[i], r.z[i]).cast::<f64>();
            let pc = rot * p + t;
            let a = Vector3::new(j[0], j[1], j[2]);
            let focal_ray = if depth_from_disparity {
                Vector3::new(0.0, 0.0, p.z)
            } else {
                -Vector3::new(p.x, p.y, 0.0)
            };
            // g^T (w - c) = a_x X' + a_y Y' = -a_z Z'; g_x = a_x Z' / f_x.
            let dr = [
                a.dot(&(rot * focal_ray)) - a.z * pc.z,
                (a.x * pc.z - a.dot(&rot.column(0)) * p.z) / fx,
                (a.y * pc.z - a.dot(&rot.column(1)) * p.z) / fy,
                a.dot(&(rot * p)),
            ];
            bread.add(&j, 0.0, weight);
            for (k, d) in dr.iter().enumerate() {
                cross.set_column(k, &(cross.column(k) + j * (weight * d)));
            }
        }
        (bread, cross)
    };
    let merge =
        |(b1, c1): (NormalEquations<8>, SMatrix<f64, 8, 4>),
         (b2, c2): (NormalEquations<8>, SMatrix<f64, 8, 4>)| { (b1.merge(&b2), c1 + c2) };
    let empty = || (NormalEquations::<8>::new(), SMatrix::<f64, 8, 4>::zeros());
    let (mut bread, cross) = if n <= SERIAL_MAX {
        (0..n.div_ceil(CHUNK)).map(chunk).fold(empty(), merge)
    } else {
        (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(chunk)
            .reduce(empty, merge)
    };
    for (i, _) in fixed.iter().enumerate().filter(|(_, f)| **f) {
        bread.fix(i);
    }
    bread
        .hessian()
        .try_inverse()
        .map(|inv| -(inv * cross))
        .filter(|v| v.iter().all(|x| x.is_finite()))
}

/// The covariance of `(rho, phi)` that `prior` adds, `V S V^T` (rows of the pose), zero when
/// the sensitivity is unknown or the prior is exact.
pub(super) fn calibration_covariance(
    level: &Se3Level<'_>,
    state: &Se3State,
    loss: &Loss,
    scale: f64,
    fixed: &[bool; 8],
    prior: &CalibrationPrior,
) -> Matrix6<f64> {
    if prior.is_exact() {
        return Matrix6::zeros();
    }
    calibration_sensitivity(level, state, loss, scale, fixed, prior.depth_from_disparity)
        .map_or_else(Matrix6::zeros, |v| {
            let pose = v.fixed_rows::<6>(0).into_owned();
            pose * prior.covariance() * pose.transpose()
        })
}
