//! The sandwich (Huber-White) covariance of an M-estimate, shared by [`crate::irls()`] and the
//! direct SE(3) aligner.
//!
//! The estimate minimises `sum_i s^2 rho(r_i / s)` over the parameters `x` , so it solves the score equation `sum_i s psi(u_i) J_i^T = 0`, `u_i = r_i / s`.
//! Expanding the score about the true parameters, whose derivative is
//! `B = sum_i psi'(u_i) J_i^T J_i` (the Hessian of the robust cost in the Gauss-Newton
//! approximation), the error is `delta = -B^-1 sum_i s psi(u_i) J_i^T` to first order, and with
//! independent residuals
//!
//! `Cov(delta) = n / (n - p) B^-1 M B^-1`, `M = s^2 sum_i psi(u_i)^2 J_i^T J_i`,
//!
//! with `n` valid residuals and `p` free parameters (the small-sample factor). For plain least
//! squares (`psi(u) = u`, `psi' = 1`) this is White's heteroscedasticity-consistent estimator,
//! whose expectation under a common variance `sigma^2` is `sigma^2 (J^T J)^-1`. The IRLS form
//! `(sum_i w_i r_i^2 / (n - p)) (J^T W J)^-1` holds the weights fixed and is too small: for
//! Huber at 1.345 sigmas on Gaussian residuals its variance factor
//! `E[u psi(u)] / E[w(u)] = 0.86` against the correct `E[psi^2] / E[psi']^2 = 1.05`.

use nalgebra::{SMatrix, SVector};

use crate::loss::{Loss, RobustLoss};
use crate::normal::NormalEquations;

/// Sandwich covariance `n / (n - p) B^-1 M B^-1` of the parameters from the residual rows
/// `(J_i, r_i)` at the estimate, the robust `loss` at scale `scale` (the residuals' units);
/// parameters in `fixed` carry no uncertainty (zero rows and columns). `None` when `B` is not
/// positive definite (a redescending loss with many residuals on its falling part) or there
/// are no more rows than free parameters.
pub fn sandwich_covariance<const N: usize>(
    rows: impl IntoIterator<Item = (SVector<f64, N>, f64)>,
    loss: &Loss,
    scale: f64,
    fixed: &[bool; N],
) -> Option<SMatrix<f64, N, N>> {
    let mask = SVector::<f64, N>::from_fn(|i, _| if fixed[i] { 0.0 } else { 1.0 });
    let (mut bread, mut meat) = (NormalEquations::<N>::new(), NormalEquations::<N>::new());
    for (j, r) in rows {
        let u = r / scale;
        let j = j.component_mul(&mask);
        bread.add(&j, 0.0, loss.psi_prime(u));
        meat.add(&j, 0.0, (scale * loss.psi(u)).powi(2));
    }
    let free = fixed.iter().filter(|f| !**f).count();
    let n = bread.count;
    if n <= free {
        return None;
    }
    for (i, _) in fixed.iter().enumerate().filter(|(_, f)| **f) {
        bread.fix(i);
    }
    let inverse = bread.hessian().cholesky()?.inverse();
    Some(inverse * meat.hessian() * inverse * (n as f64 / (n - free) as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Plain least squares on five basis functions of `t` (rows `J_i`): the sandwich equals
    /// White's estimator `(J^T J)^-1 (sum r_i^2 J_i^T J_i) (J^T J)^-1 n / (n - p)`.
    #[test]
    fn least_squares_sandwich_is_whites_estimator() {
        let n = 40;
        let rows: Vec<[f32; 8]> = (0..n)
            .map(|i| {
                let t = i as f32 / 10.0;
                [
                    1.0,
                    t,
                    t * t,
                    (1.7 * t).sin(),
                    (2.3 * t).cos(),
                    0.0,
                    0.0,
                    0.0,
                ]
            })
            .collect();
        let residuals: Vec<f32> = (0..n)
            .map(|i| ((i * 7919) % 13) as f32 / 6.0 - 1.0)
            .collect();
        // Five free parameters, the last three held.
        let mut fixed = [false; 8];
        fixed[5..].fill(true);
        let cov = sandwich_covariance(
            rows.iter()
                .zip(&residuals)
                .map(|(j, &r)| (SVector::<f64, 8>::from(j.map(f64::from)), f64::from(r))),
            &Loss::Squared,
            1.0,
            &fixed,
        )
        .expect("well-posed");
        let j = nalgebra::DMatrix::<f64>::from_fn(n, 5, |r, c| f64::from(rows[r][c]));
        let jtj_inv = (j.transpose() * &j).try_inverse().expect("invertible");
        let mut meat = nalgebra::DMatrix::<f64>::zeros(5, 5);
        for (i, &r) in residuals.iter().enumerate() {
            let row = j.row(i).transpose();
            meat += &row * row.transpose() * f64::from(r).powi(2);
        }
        let white = &jtj_inv * meat * &jtj_inv * (n as f64 / (n - 5) as f64);
        for r in 0..5 {
            for c in 0..5 {
                let scale = (white[(r, r)] * white[(c, c)]).sqrt();
                assert!(
                    (cov[(r, c)] - white[(r, c)]).abs() < 1e-6 * scale,
                    "{r} {c}"
                );
            }
        }
    }
}
