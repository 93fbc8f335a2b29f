//! The residuals of two-view and pose geometry, written once: the Sampson distance of an
//! essential matrix (and its per-image epipolar distances), the symmetric transfer error of a
//! homography and the reprojection error of a 3D point, all in normalized coordinates
//! (multiply a distance by the focal length `f` for pixels).
//!
//! A leaf module: it depends on nothing else in the crate, and every estimator, refiner,
//! quality test and triangulation that needs one of these errors calls it.
//!
//! # Degenerate denominators: one answer
//! A residual whose denominator vanishes (the Sampson norm `D = 0`, e.g. at the epipole of a
//! rank-deficient `E`; the homogeneous scale `w = 0` of a point mapped to infinity; a point
//! at or behind the camera) or whose value is not finite is **`f64::INFINITY`: the
//! correspondence is an outlier**. Consequences, the same everywhere: an inlier test
//! `r^2 < t^2` rejects it, RANSAC's truncated score charges it the full `t^2`, a least-squares
//! fit leaves it out (no row), and a gate `|r| < k sigma` drops it. The branch-free `f32`
//! scoring loop computes [`Epipolar::ratio`] without the check; its NaN or infinity fails
//! `r < t` there, which is the same answer.

use std::ops::{Add, Div, Mul};

use nalgebra::{Matrix3, Vector2, Vector3};

/// Points at depth `z <= MIN_DEPTH` (camera units) are behind or on the camera plane.
pub const MIN_DEPTH: f64 = 1e-9;

/// The arithmetic the residual formulas need: `f64` for the estimators, `f32` for the
/// vectorised RANSAC score.
pub trait Real: Copy + Add<Output = Self> + Mul<Output = Self> + Div<Output = Self> {}

impl Real for f64 {}

impl Real for f32 {}

/// Row-major entries of a 3x3 matrix (the layout [`Epipolar::new`] reads).
#[inline]
pub fn row_major(m: &Matrix3<f64>) -> [f64; 9] {
    std::array::from_fn(|k| m[(k / 3, k % 3)])
}

/// The epipolar terms of one normalized correspondence `x1 = (u1, v1, 1)`,
/// `x2 = (u2, v2, 1)` under `E` (row-major `e`): the epipolar lines `l2 = E x1` (in image 2)
/// and `l1 = E^T x2` (in image 1, first two components), the algebraic error
/// `c = x2^T E x1` and the Sampson norm `D = l2_x^2 + l2_y^2 + l1_x^2 + l1_y^2`.
///
/// The Sampson distance is `c / sqrt(D)`; its Jacobian, the first-order correction of
/// [`crate::triangulate::triangulate_corrected`] and ORB-SLAM's per-image distances are all
/// read from these terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Epipolar<T> {
    /// `(E x1)_x`, `(E x1)_y`.
    pub l2: [T; 2],
    /// `(E^T x2)_x`, `(E^T x2)_y`.
    pub l1: [T; 2],
    /// `c = x2^T E x1`.
    pub c: T,
    /// `D = l2_x^2 + l2_y^2 + l1_x^2 + l1_y^2`.
    pub d: T,
}

impl<T: Real> Epipolar<T> {
    /// The terms of `(u1, v1) <-> (u2, v2)` under the row-major `e`.
    #[inline(always)]
    pub fn new(e: &[T; 9], u1: T, v1: T, u2: T, v2: T) -> Self {
        let l2x = e[0] * u1 + e[1] * v1 + e[2];
        let l2y = e[3] * u1 + e[4] * v1 + e[5];
        let l2z = e[6] * u1 + e[7] * v1 + e[8];
        let l1x = e[0] * u2 + e[3] * v2 + e[6];
        let l1y = e[1] * u2 + e[4] * v2 + e[7];
        Self {
            l2: [l2x, l2y],
            l1: [l1x, l1y],
            c: u2 * l2x + v2 * l2y + l2z,
            d: l2x * l2x + l2y * l2y + l1x * l1x + l1y * l1y,
        }
    }

    /// `c^2 / D` without the degeneracy check (NaN or infinite when `D = 0`), for branch-free
    /// loops whose inlier test `r < t` rejects those values.
    #[inline(always)]
    pub fn ratio(&self) -> T {
        self.c * self.c / self.d
    }
}

impl Epipolar<f64> {
    /// The terms of normalized points `x1`, `x2` under `E`.
    #[inline]
    pub fn of(e: &Matrix3<f64>, x1: &Vector2<f64>, x2: &Vector2<f64>) -> Self {
        Self::new(&row_major(e), x1.x, x1.y, x2.x, x2.y)
    }

    /// `D > 0` and everything finite: the Sampson distance is defined.
    #[inline]
    pub fn is_regular(&self) -> bool {
        self.d > 0.0 && self.d.is_finite() && self.c.is_finite()
    }

    /// Squared Sampson distance `c^2 / D`; infinite when degenerate (module documentation).
    #[inline]
    pub fn sampson_sq(&self) -> f64 {
        if self.is_regular() {
            self.ratio()
        } else {
            f64::INFINITY
        }
    }

    /// Signed Sampson distance `c / sqrt(D)`; infinite when degenerate.
    #[inline]
    pub fn sampson(&self) -> f64 {
        if self.is_regular() {
            self.c / self.d.sqrt()
        } else {
            f64::INFINITY
        }
    }

    /// Squared distances `(d1^2, d2^2)` of `x1` to its epipolar line `E^T x2` in image 1 and
    /// of `x2` to `E x1` in image 2: `c^2 / (l1_x^2 + l1_y^2)` and `c^2 / (l2_x^2 + l2_y^2)`;
    /// each infinite when its line is degenerate.
    #[inline]
    pub fn line_distances_sq(&self) -> (f64, f64) {
        let c2 = self.c * self.c;
        let n1 = self.l1[0] * self.l1[0] + self.l1[1] * self.l1[1];
        let n2 = self.l2[0] * self.l2[0] + self.l2[1] * self.l2[1];
        (regular_ratio(c2, n1), regular_ratio(c2, n2))
    }
}

/// `num / den`, infinite unless `den > 0` and the result is finite.
#[inline]
fn regular_ratio(num: f64, den: f64) -> f64 {
    let r = num / den;
    if den > 0.0 && r.is_finite() {
        r
    } else {
        f64::INFINITY
    }
}

/// Squared Sampson error of `x2^T E x1 = 0` for normalized coordinates:
/// `(x2^T E x1)^2 / ((E x1)_1^2 + (E x1)_2^2 + (E^T x2)_1^2 + (E^T x2)_2^2)`, squared
/// normalized units; infinite when degenerate.
#[inline]
pub fn sampson_sq(e: &Matrix3<f64>, x1: &Vector2<f64>, x2: &Vector2<f64>) -> f64 {
    Epipolar::of(e, x1, x2).sampson_sq()
}

/// Squared distances `(d1^2, d2^2)` of `x1` to its epipolar line `E^T x2` in image 1 and of
/// `x2` to `E x1` in image 2 (ORB-SLAM's per-image model score); see
/// [`Epipolar::line_distances_sq`].
#[inline]
pub fn epipolar_distances_sq(e: &Matrix3<f64>, x1: &Vector2<f64>, x2: &Vector2<f64>) -> (f64, f64) {
    Epipolar::of(e, x1, x2).line_distances_sq()
}

/// `H x` dehomogenised (non-finite when `H` maps `x` to infinity).
#[inline]
pub fn transfer(h: &Matrix3<f64>, x: &Vector2<f64>) -> Vector2<f64> {
    let p = h * x.push(1.0);
    Vector2::new(p.x / p.z, p.y / p.z)
}

/// Squared distance of `H x` to `y`, infinite when `H x` is not finite.
#[inline]
fn transfer_error_sq(h: &Matrix3<f64>, x: &Vector2<f64>, y: &Vector2<f64>) -> f64 {
    let r = (transfer(h, x) - y).norm_squared();
    if r.is_finite() {
        r
    } else {
        f64::INFINITY
    }
}

/// Squared transfer errors `(|x2 - H x1|^2, |x1 - H^-1 x2|^2)`, normalized units; each
/// infinite when its transfer is degenerate.
#[inline]
pub fn transfer_sq(
    h: &Matrix3<f64>,
    h_inv: &Matrix3<f64>,
    x1: &Vector2<f64>,
    x2: &Vector2<f64>,
) -> (f64, f64) {
    (
        transfer_error_sq(h, x1, x2),
        transfer_error_sq(h_inv, x2, x1),
    )
}

/// Symmetric transfer error `(|x2 - H x1|^2 + |x1 - H^-1 x2|^2) / 2`, the residual of the
/// homography and rotation-only models; infinite when either transfer is degenerate.
#[inline]
pub fn symmetric_transfer_sq(
    h: &Matrix3<f64>,
    h_inv: &Matrix3<f64>,
    x1: &Vector2<f64>,
    x2: &Vector2<f64>,
) -> f64 {
    let (a, b) = transfer_sq(h, h_inv, x1, x2);
    0.5 * (a + b)
}

/// Squared reprojection error `|(x / z, y / z) - observed|^2` of the camera-frame point `x`
/// against its normalized observation; infinite for `z <= MIN_DEPTH`.
#[inline]
pub fn reprojection_sq(x: &Vector3<f64>, observed: &Vector2<f64>) -> f64 {
    if x.z <= MIN_DEPTH {
        return f64::INFINITY;
    }
    (Vector2::new(x.x / x.z, x.y / x.z) - observed).norm_squared()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampson_of_a_consistent_pair_is_zero_and_grows_off_the_line() {
        // Pure x-translation: E = [t]x, epipolar lines are rows y = const.
        let e = Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0);
        let x1 = Vector2::new(0.1, 0.2);
        assert_eq!(sampson_sq(&e, &x1, &Vector2::new(0.4, 0.2)), 0.0);
        let off = sampson_sq(&e, &x1, &Vector2::new(0.4, 0.3));
        // c = 0.1, D = 1 + 1: Sampson distance^2 = 0.01 / 2.
        assert!((off - 0.005).abs() < 1e-15, "{off}");
        let (d1, d2) = Epipolar::of(&e, &x1, &Vector2::new(0.4, 0.3)).line_distances_sq();
        assert!((d1 - 0.01).abs() < 1e-15 && (d2 - 0.01).abs() < 1e-15);
    }

    #[test]
    fn degenerate_denominators_are_infinite_everywhere() {
        let zero = Matrix3::zeros();
        let (a, b) = (Vector2::new(0.1, 0.2), Vector2::new(0.3, 0.4));
        let ep = Epipolar::of(&zero, &a, &b);
        assert!(!ep.is_regular());
        assert_eq!(ep.sampson_sq(), f64::INFINITY);
        assert_eq!(ep.sampson(), f64::INFINITY);
        assert_eq!(ep.line_distances_sq(), (f64::INFINITY, f64::INFINITY));
        // A homography sending x1 to infinity (w = 0) in one direction only.
        let h = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        let (fwd, _) = transfer_sq(&h, &Matrix3::identity(), &a, &b);
        assert_eq!(fwd, f64::INFINITY);
        assert_eq!(
            symmetric_transfer_sq(&h, &Matrix3::identity(), &a, &b),
            f64::INFINITY
        );
        assert_eq!(
            reprojection_sq(&Vector3::new(1.0, 1.0, 0.0), &a),
            f64::INFINITY
        );
        // The unchecked f32 ratio is rejected by the inlier test.
        let ep32 = Epipolar::new(&[0.0f32; 9], 0.1, 0.2, 0.3, 0.4);
        assert!(ep32.ratio().partial_cmp(&1.0) != Some(std::cmp::Ordering::Less));
    }

    #[test]
    fn symmetric_transfer_is_the_mean_of_both_directions() {
        let h = Matrix3::new(1.0, 0.0, 0.1, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        let h_inv = h.try_inverse().expect("invertible");
        let (a, b) = (Vector2::new(0.0, 0.0), Vector2::new(0.2, 0.0));
        // Forward: H a = (0.1, 0) is 0.1 from b; backward: H^-1 b = (0.1, 0) is 0.1 from a.
        let r = symmetric_transfer_sq(&h, &h_inv, &a, &b);
        assert!((r - 0.01).abs() < 1e-15, "{r}");
        let x = Vector3::new(0.2, 0.4, 2.0);
        assert!((reprojection_sq(&x, &Vector2::new(0.1, 0.1)) - 0.01).abs() < 1e-15);
    }
}
