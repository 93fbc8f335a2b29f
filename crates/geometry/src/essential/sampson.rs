//! First-order geometric errors of an essential (or fundamental) matrix.

use nalgebra::{Matrix3, Vector2};

/// Squared Sampson error of `x2^T E x1 = 0` for normalized coordinates `x1 = (u1, v1, 1)`,
/// `x2 = (u2, v2, 1)`:
/// `(x2^T E x1)^2 / ((E x1)_1^2 + (E x1)_2^2 + (E^T x2)_1^2 + (E^T x2)_2^2)`,
/// in squared normalized units (multiply by `f^2` for squared pixels).
#[inline]
pub fn sampson_error_sq(e: &Matrix3<f64>, x1: &Vector2<f64>, x2: &Vector2<f64>) -> f64 {
    let (u1, v1, u2, v2) = (x1.x, x1.y, x2.x, x2.y);
    let l2x = e[(0, 0)] * u1 + e[(0, 1)] * v1 + e[(0, 2)];
    let l2y = e[(1, 0)] * u1 + e[(1, 1)] * v1 + e[(1, 2)];
    let l2z = e[(2, 0)] * u1 + e[(2, 1)] * v1 + e[(2, 2)];
    let l1x = e[(0, 0)] * u2 + e[(1, 0)] * v2 + e[(2, 0)];
    let l1y = e[(0, 1)] * u2 + e[(1, 1)] * v2 + e[(2, 1)];
    let c = u2 * l2x + v2 * l2y + l2z;
    let den = l2x * l2x + l2y * l2y + l1x * l1x + l1y * l1y;
    if den > 0.0 {
        c * c / den
    } else {
        f64::INFINITY
    }
}

/// Squared distances `(d1^2, d2^2)` of `x1` to its epipolar line `E^T x2` in image 1 and of
/// `x2` to `E x1` in image 2, normalized units (ORB-SLAM's per-image model score).
#[inline]
pub fn epipolar_distances_sq(e: &Matrix3<f64>, x1: &Vector2<f64>, x2: &Vector2<f64>) -> (f64, f64) {
    let a1 = x1.push(1.0);
    let a2 = x2.push(1.0);
    let l2 = e * a1;
    let l1 = e.transpose() * a2;
    let c = a2.dot(&l2);
    let c2 = c * c;
    let d2 = c2 / (l2.x * l2.x + l2.y * l2.y).max(f64::MIN_POSITIVE);
    let d1 = c2 / (l1.x * l1.x + l1.y * l1.y).max(f64::MIN_POSITIVE);
    (d1, d2)
}
