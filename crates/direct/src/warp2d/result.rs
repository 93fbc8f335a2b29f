//! What the 2D aligners return: [`WarpResult`] (affine, homography) with its verdict, and
//! [`Fit2d`], the common fit of every 2D warp before it is judged.

use nalgebra::{DMatrix, Matrix3};
use vofront_robust::Quality;

/// Result of [`super::align_affine`] and [`super::align_homography`] (`Serialize`: `h` as a flat
/// column-major array, the dynamic `covariance` as nalgebra writes it, `[data, rows, cols]`
/// with column-major `data`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct WarpResult {
    /// `H` with `I2(H x) = a I1(x) + b` (pixels of image 1 to pixels of image 2).
    pub h: Matrix3<f64>,
    /// Brightness gain.
    pub a: f64,
    /// Brightness offset, grey levels.
    pub b: f64,
    /// Iterations per pyramid level, index = level (0 = full resolution; 0 for skipped levels).
    pub iterations: Vec<usize>,
    /// Root-mean-square residual at full resolution, grey levels.
    pub rmse: f64,
    /// Valid residuals at full resolution over the number of pixels.
    pub used_fraction: f64,
    /// Covariance of the geometric parameters of the last `H(delta)` (Gauss-Newton
    /// `sigma^2 H^-1` restricted to them), `k x k` for `k` geometric parameters; `None`
    /// (unknown) when the final normal equations are singular.
    pub covariance: Option<DMatrix<f64>>,
    /// False when the full-resolution level hit its iteration limit.
    pub converged: bool,
    /// Verdict, support and covariance, judged with [`super::WarpConfig::quality`] (see
    /// [`crate::quality`]).
    pub quality: Quality,
}

/// What `align_2d` found: a [`WarpResult`] before its verdict (the translation aligner
/// judges it differently, [`crate::quality`]).
pub(crate) struct Fit2d {
    pub h: Matrix3<f64>,
    pub a: f64,
    pub b: f64,
    pub iterations: Vec<usize>,
    pub rmse: f64,
    pub used_fraction: f64,
    pub covariance: Option<DMatrix<f64>>,
    pub converged: bool,
}
