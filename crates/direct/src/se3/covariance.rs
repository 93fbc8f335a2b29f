//! Covariance of the SE(3) estimate: the sandwich (Huber-White) covariance of an M-estimate.
//!
//! The estimate minimises `sum_i s^2 rho(r_i / s)` over the parameters `x` (pose increment and
//! brightness), so it solves the score equation `sum_i s psi(u_i) J_i^T = 0`, `u_i = r_i / s`.
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

use nalgebra::{Matrix6, SVector};
use vofront_robust::{Loss, NormalEquations, RobustLoss};

/// Sandwich covariance of the left pose increment `(rho, phi)` (metres, radians), marginal
/// over the brightness, from the residuals `residuals` (NaN where invalid) and Jacobian rows
/// `jacobians` at the estimate, the robust `loss` at scale `scale`; parameters in `fixed` carry
/// no uncertainty. `None` when `B` is not positive definite (a redescending loss with many
/// residuals on its falling part) or there are no more residuals than free parameters.
pub(super) fn sandwich_covariance(
    residuals: &[f32],
    jacobians: &[[f32; 8]],
    loss: &Loss,
    scale: f32,
    fixed: &[bool; 8],
) -> Option<Matrix6<f64>> {
    let s = f64::from(scale);
    let mask = SVector::<f64, 8>::from(fixed.map(|f| if f { 0.0 } else { 1.0 }));
    let (mut bread, mut meat) = (NormalEquations::<8>::new(), NormalEquations::<8>::new());
    for (&r, j) in residuals.iter().zip(jacobians) {
        if r.is_nan() {
            continue;
        }
        let u = f64::from(r) / s;
        let j = SVector::<f64, 8>::from(j.map(f64::from)).component_mul(&mask);
        bread.add(&j, 0.0, loss.psi_prime(u));
        meat.add(&j, 0.0, (s * loss.psi(u)).powi(2));
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
    let cov = inverse * meat.hessian() * inverse * (n as f64 / (n - free) as f64);
    Some(cov.fixed_view::<6, 6>(0, 0).into_owned())
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
        let cov = sandwich_covariance(&residuals, &rows, &Loss::Squared, 1.0, &fixed)
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
