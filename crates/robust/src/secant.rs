//! Widening a Gauss-Newton covariance where the cost is flatter than its quadratic model.
//!
//! A covariance `C = sigma^2 (J^T J)^-1` describes the cost by its local quadratic model: a
//! step `delta = c sqrt(lambda_k) u_k` along an eigenvector `u_k` of `C` (eigenvalue
//! `lambda_k`) should raise the cost by `c^2` in chi-square units (cost over `sigma^2`). Where
//! the residuals are far from linear in the parameters, the real rise can be much smaller: the
//! two-view Sampson distance of points near the epipole is such a case at low parallax, where
//! a translation direction 15 local sigmas away raises the cost by only 5. The local `C` then
//! claims a precision the data do not have.
//!
//! [`secant_covariance`] probes each principal axis at `c` = 1, 2, 4, 8 and 16 local sigmas on
//! both sides, takes the symmetric rise `q(c) = (rise(+delta) + rise(-delta)) / 2` (the
//! linear term cancels) and widens the axis to its largest secant variance
//!
//! `lambda_k' = lambda_k max(1, max_c c^2 / max(q(c), 1))`,
//!
//! the variance of the quadratic that rises as little as the cost does. The floor of 1 on
//! `q` keeps the widening finite (a cost that rises by less than one unit at `c` sigmas says
//! that the one-sigma region reaches at least that far); the outer `max(1, .)` never lets
//! the probes narrow the local covariance.

use nalgebra::{DMatrix, SMatrix, SVector};

/// Probe distances along each principal axis, in local sigmas.
pub const SECANT_PROBES: [f64; 5] = [1.0, 2.0, 4.0, 8.0, 16.0];

/// The covariance `covariance` widened along each principal axis to its secant variance (see
/// the module documentation). `rise(delta)` is the cost increase, in chi-square units, of the
/// state moved by the increment `delta` from the estimate; a non-finite rise leaves its axis
/// unchanged. Axes with a non-positive eigenvalue are left as they are.
pub fn secant_covariance<const N: usize>(
    covariance: &SMatrix<f64, N, N>,
    mut rise: impl FnMut(&SVector<f64, N>) -> f64,
) -> SMatrix<f64, N, N> {
    // The dynamic decomposition: nalgebra's fixed-size one needs `N - 1` as a type.
    let eigen = DMatrix::from_fn(N, N, |r, c| covariance[(r, c)]).symmetric_eigen();
    let axes = SMatrix::<f64, N, N>::from_fn(|r, c| eigen.eigenvectors[(r, c)]);
    let mut variances = SVector::<f64, N>::from_fn(|k, _| eigen.eigenvalues[k]);
    for k in 0..N {
        if variances[k] <= 0.0 {
            continue;
        }
        let axis: SVector<f64, N> = axes.column(k) * variances[k].sqrt();
        let widening = SECANT_PROBES
            .iter()
            .map(|&c| {
                let q = 0.5 * (rise(&(axis * c)) + rise(&(axis * -c)));
                if q.is_finite() {
                    c * c / q.max(1.0)
                } else {
                    1.0
                }
            })
            .fold(1.0, f64::max);
        variances[k] *= widening;
    }
    axes * SMatrix::from_diagonal(&variances) * axes.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    /// A correlated 2x2 covariance with axes `u0 = (1, 1) / sqrt 2` (variance 4) and
    /// `u1 = (1, -1) / sqrt 2` (variance 0.25).
    fn covariance() -> Matrix2<f64> {
        let u0 = Vector2::new(1.0, 1.0) / 2f64.sqrt();
        let u1 = Vector2::new(1.0, -1.0) / 2f64.sqrt();
        u0 * u0.transpose() * 4.0 + u1 * u1.transpose() * 0.25
    }

    /// The chi-square rise `delta^T C^-1 delta` of the quadratic model itself.
    fn quadratic(c: &Matrix2<f64>) -> impl Fn(&Vector2<f64>) -> f64 {
        let inv = c.try_inverse().expect("invertible");
        move |d| (d.transpose() * inv * d)[0]
    }

    fn assert_close(a: &Matrix2<f64>, b: &Matrix2<f64>) {
        assert!((a - b).norm() < 1e-9 * b.norm(), "{a} vs {b}");
    }

    #[test]
    fn a_quadratic_cost_keeps_the_covariance() {
        let c = covariance();
        assert_close(&secant_covariance(&c, quadratic(&c)), &c);
    }

    #[test]
    fn a_steeper_cost_never_narrows_the_covariance() {
        let c = covariance();
        let q = quadratic(&c);
        assert_close(&secant_covariance(&c, |d| 10.0 * q(d)), &c);
    }

    /// Along `u1` the cost rises quadratically to one sigma and then only linearly,
    /// `2 |s| - 1` at `s` sigmas (at 8 sigmas by 15 where the model says 64), so the axis
    /// widens by the largest `c^2 / (2 c - 1)` over the probes; `u0` and the axes' directions
    /// stay.
    #[test]
    fn a_cost_flatter_than_its_model_widens_that_axis_only() {
        let c = covariance();
        let u0 = Vector2::new(1.0, 1.0) / 2f64.sqrt();
        let u1 = Vector2::new(1.0, -1.0) / 2f64.sqrt();
        let rise = |d: &Vector2<f64>| {
            let (s0, s1) = (d.dot(&u0) / 2.0, d.dot(&u1) / 0.5);
            let along_u1 = if s1.abs() <= 1.0 {
                s1 * s1
            } else {
                2.0 * s1.abs() - 1.0
            };
            s0 * s0 + along_u1
        };
        let widened = secant_covariance(&c, rise);
        let widening = SECANT_PROBES
            .iter()
            .map(|c| c * c / (2.0 * c - 1.0))
            .fold(1.0, f64::max);
        assert!(widening > 8.0, "the 16-sigma probe sees 256 / 31");
        let expected = u0 * u0.transpose() * 4.0 + u1 * u1.transpose() * 0.25 * widening;
        assert_close(&widened, &expected);
    }

    #[test]
    fn a_flat_cost_widens_by_at_most_the_largest_probe_squared() {
        let c = covariance();
        let widened = secant_covariance(&c, |_| 0.0);
        let factor = SECANT_PROBES[SECANT_PROBES.len() - 1].powi(2);
        assert_close(&widened, &(c * factor));
    }
}
