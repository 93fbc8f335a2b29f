//! Kannala-Brandt equidistant fisheye model (OpenCV `fisheye`, Kalibr / TUM-VI `equidistant`).
//!
//! A camera-frame point `P = (X, Y, Z)` (metres) makes the angle `theta = atan2(r, Z)` with the
//! optical axis, `r = sqrt(X^2 + Y^2)`. The lens maps it to the distorted radius
//! `theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)` (radians) and the
//! distorted normalized point `x_d = theta_d (X, Y) / r`, which the intrinsics map to pixels.
//! On normalized coordinates `x_n = (X/Z, Y/Z)` (what every vofront model distorts) this is
//! `x_d = theta_d(atan |x_n|) / |x_n| x_n`.
//!
//! Validity range: the model is used for `0 <= theta < theta_max`, where `theta_max <= pi/2`
//! is the first angle at which `theta_d` stops increasing ([`KannalaBrandt::theta_max`]).
//! Beyond it two rays share a pixel, and rays at or beyond 90 degrees have no normalized
//! coordinates; [`KannalaBrandt::undistort`] returns `None` there instead of a wrong ray.

use nalgebra::{Matrix2, Vector2};

use super::CameraError;

/// Below this radius (normalized units) the model is the identity to rounding.
const TINY_RADIUS: f64 = 1e-12;
/// Steps of the scan that finds where `theta_d` stops increasing on `[0, pi/2]`.
const MONOTONIC_SCAN_STEPS: usize = 512;
/// Newton iterations allowed when inverting `theta_d(theta)`.
const NEWTON_ITERATIONS: usize = 30;
/// Newton stops when `|theta_d(theta) - theta_d|` is below this, radians.
const NEWTON_TOLERANCE: f64 = 1e-13;

/// Kannala-Brandt equidistant coefficients `k1..k4` with their validity range.
///
/// Built by [`KannalaBrandt::new`], which checks the coefficients and computes `theta_max`
/// once (hence private fields).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KannalaBrandt {
    /// `[k1, k2, k3, k4]`.
    k: [f64; 4],
    /// First angle (radians, at most `pi/2`) where `theta_d` stops increasing.
    theta_max: f64,
}

impl KannalaBrandt {
    /// The model with coefficients `[k1, k2, k3, k4]`; [`CameraError::NotFinite`] when one is
    /// not finite. (`theta_d` always increases at the axis, `theta_d'(0) = 1`, so the range is
    /// never empty.)
    pub fn new(k: [f64; 4]) -> Result<Self, CameraError> {
        if !k.iter().all(|v| v.is_finite()) {
            return Err(CameraError::NotFinite);
        }
        let mut model = Self { k, theta_max: 0.0 };
        model.theta_max = model.monotonic_limit();
        Ok(model)
    }

    /// `[k1, k2, k3, k4]`.
    pub fn coefficients(&self) -> [f64; 4] {
        self.k
    }

    /// Largest angle to the optical axis (radians, at most `pi/2`) inside the validity range.
    pub fn theta_max(&self) -> f64 {
        self.theta_max
    }

    /// `theta_d(theta) = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)`.
    #[inline]
    pub fn theta_d(&self, theta: f64) -> f64 {
        let [k1, k2, k3, k4] = self.k;
        let t2 = theta * theta;
        theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    }

    /// `d theta_d / d theta = 1 + 3 k1 theta^2 + 5 k2 theta^4 + 7 k3 theta^6 + 9 k4 theta^8`.
    #[inline]
    fn theta_d_derivative(&self, theta: f64) -> f64 {
        let [k1, k2, k3, k4] = self.k;
        let t2 = theta * theta;
        1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))
    }

    /// First zero of `d theta_d / d theta` on `(0, pi/2]` (scan of [`MONOTONIC_SCAN_STEPS`]
    /// steps, then bisection), or `pi/2` when it stays positive.
    fn monotonic_limit(&self) -> f64 {
        let end = std::f64::consts::FRAC_PI_2;
        let step = end / MONOTONIC_SCAN_STEPS as f64;
        for i in 1..=MONOTONIC_SCAN_STEPS {
            let (mut lo, mut hi) = ((i - 1) as f64 * step, i as f64 * step);
            if self.theta_d_derivative(hi) > 0.0 {
                continue;
            }
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if self.theta_d_derivative(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return lo;
        }
        end
    }

    /// True when the ray of normalized point `x` (`theta = atan |x|`) is inside the validity
    /// range.
    #[inline]
    pub fn contains(&self, x: &Vector2<f64>) -> bool {
        x.norm().atan() < self.theta_max
    }

    /// Distorted normalized coordinates `x_d = theta_d(atan r) / r x_n`, `r = |x_n|`.
    #[inline]
    pub fn distort(&self, x: &Vector2<f64>) -> Vector2<f64> {
        let r = x.norm();
        if r < TINY_RADIUS {
            return *x;
        }
        x * (self.theta_d(r.atan()) / r)
    }

    /// Jacobian `d x_d / d x_n` of [`KannalaBrandt::distort`]: with `s(r) = theta_d(atan r)/r`,
    /// `J = s I + s'(r) x_n x_n^T / r`, `s'(r) = (theta_d'(theta) r / (1 + r^2) - theta_d) / r^2`.
    pub fn distort_jacobian(&self, x: &Vector2<f64>) -> Matrix2<f64> {
        let r = x.norm();
        if r < TINY_RADIUS {
            return Matrix2::identity();
        }
        let theta = r.atan();
        let theta_d = self.theta_d(theta);
        let s = theta_d / r;
        let ds = (self.theta_d_derivative(theta) * r / (1.0 + r * r) - theta_d) / (r * r);
        Matrix2::identity() * s + (x * x.transpose()) * (ds / r)
    }

    /// Inverts [`KannalaBrandt::distort`]: Newton on `theta_d(theta) = |x_d|` from
    /// `theta = |x_d|`, then `x_n = tan(theta) x_d / |x_d|`.
    ///
    /// `None` when the solution is not inside `[0, theta_max)` (see the module documentation)
    /// or Newton does not reach `1e-13` rad within 30 iterations.
    pub fn undistort(&self, xd: &Vector2<f64>) -> Option<Vector2<f64>> {
        let target = xd.norm();
        if target < TINY_RADIUS {
            return Some(*xd);
        }
        if target >= self.theta_d(self.theta_max) {
            return None;
        }
        let mut theta = target.min(self.theta_max);
        for _ in 0..NEWTON_ITERATIONS {
            let err = self.theta_d(theta) - target;
            if err.abs() < NEWTON_TOLERANCE {
                return (0.0..self.theta_max)
                    .contains(&theta)
                    .then(|| xd * (theta.tan() / target));
            }
            // theta_d is increasing on [0, theta_max): the derivative is positive there.
            theta = (theta - err / self.theta_d_derivative(theta)).clamp(0.0, self.theta_max);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lens_that_folds_back_has_a_smaller_range() {
        // theta_d' = 1 - 0.9 theta^2 vanishes at theta = 1/sqrt(0.9).
        let lens = KannalaBrandt::new([-0.3, 0.0, 0.0, 0.0]).unwrap();
        assert!((lens.theta_max() - (1.0f64 / 0.9).sqrt()).abs() < 1e-9);
        // Beyond the fold there is no unique ray.
        let past = Vector2::new(lens.theta_d(lens.theta_max()) * 1.01, 0.0);
        assert_eq!(lens.undistort(&past), None);
    }

    #[test]
    fn bad_coefficients_are_rejected() {
        assert_eq!(
            KannalaBrandt::new([f64::NAN, 0.0, 0.0, 0.0]),
            Err(CameraError::NotFinite)
        );
        // The range of a valid lens never exceeds 90 degrees.
        let lens = KannalaBrandt::new([0.0; 4]).unwrap();
        assert_eq!(lens.theta_max(), std::f64::consts::FRAC_PI_2);
    }
}
