//! The damped normal-equation step with degeneracy detection.
//!
//! Solves `(H + lambda D) d = -g` where `D` is the identity (Levenberg) or `diag(H)`
//! (Marquardt); `lambda = 0` is the Gauss-Newton step. Before solving, the conditioning of `H`
//! itself is checked after Jacobi scaling `S H S`, `S = diag(H)^-1/2`, so that parameters with
//! different units (radians, metres, grey levels) do not fake a bad condition number. A direction
//! that the residuals do not constrain (the aperture problem, a planar scene's depth, too few
//! points) shows up as a huge condition number and is reported as
//! [`SolveError::Degenerate`], never as a huge step.

use nalgebra::{SMatrix, SVector};
use thiserror::Error;

/// How the damping term `lambda D` is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Damping {
    /// `D = I` (Levenberg).
    Identity,
    /// `D = diag(H)` (Marquardt): invariant to the units of each parameter.
    #[default]
    Diagonal,
}

/// Why a step could not be computed.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum SolveError {
    /// `H` does not constrain every parameter: its scaled condition number exceeds the limit.
    #[error("degenerate normal equations: condition number {condition:.3e} exceeds {limit:.1e}")]
    Degenerate {
        /// Estimated condition number of the Jacobi-scaled `H` (`inf` when a column is zero).
        condition: f64,
        /// The limit it was checked against.
        limit: f64,
    },
    /// `H` or `g` holds NaN or infinity.
    #[error("normal equations contain NaN or infinite values")]
    NotFinite,
}

/// Condition number of the Jacobi-scaled `H` (ratio of extreme eigenvalues of `S H S`).
///
/// Returns infinity when a diagonal entry is not positive (a parameter with no information).
pub fn scaled_condition<const N: usize>(h: &SMatrix<f64, N, N>) -> f64 {
    let mut scaled = *h;
    for i in 0..N {
        if h[(i, i)] <= 0.0 || !h[(i, i)].is_finite() {
            return f64::INFINITY;
        }
    }
    for r in 0..N {
        for c in 0..N {
            scaled[(r, c)] = h[(r, c)] / (h[(r, r)] * h[(c, c)]).sqrt();
        }
    }
    let eig = symmetric_eigenvalues(scaled);
    let max = eig.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = eig.iter().copied().fold(f64::INFINITY, f64::min);
    if min <= max * f64::EPSILON {
        f64::INFINITY
    } else {
        max / min
    }
}

/// Solves `(H + lambda D) d = -g` after checking that `H` is not degenerate.
///
/// `max_condition` bounds the scaled condition number of `H` (1e10 is a sensible default:
/// a well-posed 6-DoF pose has 1e2..1e5); `f64::INFINITY` skips the check (its eigenvalue
/// sweep), leaving only the Cholesky factorisation to fail.
///
/// ```
/// use nalgebra::{Matrix2, Vector2};
/// use vofront_robust::{solve_damped, Damping, SolveError};
/// let h = Matrix2::new(4.0, 0.0, 0.0, 1.0);
/// let d = solve_damped(&h, &Vector2::new(-4.0, 2.0), 0.0, Damping::Diagonal, 1e10).unwrap();
/// assert_eq!(d, Vector2::new(1.0, -2.0));
/// // Gradients along one direction only: the other parameter is unconstrained.
/// let aperture = Matrix2::new(1.0, 1.0, 1.0, 1.0);
/// let err = solve_damped(&aperture, &Vector2::new(1.0, 1.0), 0.0, Damping::Diagonal, 1e10);
/// assert!(matches!(err, Err(SolveError::Degenerate { .. })));
/// ```
pub fn solve_damped<const N: usize>(
    h: &SMatrix<f64, N, N>,
    g: &SVector<f64, N>,
    lambda: f64,
    damping: Damping,
    max_condition: f64,
) -> Result<SVector<f64, N>, SolveError> {
    if h.iter().chain(g.iter()).any(|v| !v.is_finite()) {
        return Err(SolveError::NotFinite);
    }
    // An infinite bound asks for no check: the eigenvalues are then computed only to report a
    // failed factorisation.
    if max_condition.is_finite() {
        let condition = scaled_condition(h);
        if condition.is_nan() || condition > max_condition {
            return Err(SolveError::Degenerate {
                condition,
                limit: max_condition,
            });
        }
    }
    let mut damped = *h;
    for i in 0..N {
        damped[(i, i)] += match damping {
            Damping::Identity => lambda,
            Damping::Diagonal => lambda * h[(i, i)],
        };
    }
    let chol = damped.cholesky().ok_or_else(|| SolveError::Degenerate {
        condition: scaled_condition(h),
        limit: max_condition,
    })?;
    Ok(-chol.solve(g))
}

/// Eigenvalues of a small symmetric matrix by cyclic Jacobi rotations.
///
/// Each rotation zeroes `a_pq` with `tan(2 theta) = 2 a_pq / (a_qq - a_pp)`; sweeps repeat until
/// the off-diagonal mass is negligible, which takes a handful of sweeps for `N <= 8`.
fn symmetric_eigenvalues<const N: usize>(mut a: SMatrix<f64, N, N>) -> [f64; N] {
    for _sweep in 0..30 {
        let off: f64 = (0..N)
            .flat_map(|r| ((r + 1)..N).map(move |c| (r, c)))
            .map(|(r, c)| a[(r, c)] * a[(r, c)])
            .sum();
        let diag: f64 = (0..N).map(|i| a[(i, i)] * a[(i, i)]).sum();
        if off <= 1e-30 * diag {
            break;
        }
        for p in 0..N {
            for q in (p + 1)..N {
                let apq = a[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                let theta = 0.5 * (a[(q, q)] - a[(p, p)]) / apq;
                let t = theta.signum() / (theta.abs() + theta.hypot(1.0));
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / t.hypot(1.0);
                let s = t * c;
                for k in 0..N {
                    let akp = a[(k, p)];
                    let akq = a[(k, q)];
                    a[(k, p)] = c * akp - s * akq;
                    a[(k, q)] = s * akp + c * akq;
                }
                for k in 0..N {
                    let apk = a[(p, k)];
                    let aqk = a[(q, k)];
                    a[(p, k)] = c * apk - s * aqk;
                    a[(q, k)] = s * apk + c * aqk;
                }
            }
        }
    }
    std::array::from_fn(|i| a[(i, i)])
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    #[test]
    fn jacobi_eigenvalues_match_a_known_spectrum() {
        // Q diag(1, 4, 9) Q^T for a rotation Q has eigenvalues 1, 4, 9.
        let q = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1).into_inner();
        let m = q * Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 4.0, 9.0)) * q.transpose();
        let mut eig = symmetric_eigenvalues(m);
        eig.sort_by(f64::total_cmp);
        for (got, want) in eig.iter().zip([1.0, 4.0, 9.0]) {
            assert!((got - want).abs() < 1e-10, "{eig:?}");
        }
    }
}
