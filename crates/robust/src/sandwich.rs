//! The sandwich (Huber-White) covariance of an M-estimate, shared by [`crate::irls()`] and the
//! direct SE(3) aligner, and its cluster-robust form (the two-view pose's).
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
//!
//! **Correlated residuals.** Real residuals are not independent: neighbouring pixels share
//! interpolation, blur, depth-sensor and model errors; neighbouring keypoints share lens,
//! calibration and matching errors. With residuals correlated within groups `g` (clusters,
//! e.g. cells of the image) and independent between them, the score is a sum of independent
//! cluster scores `S_g = sum_{i in g} s psi(u_i) J_i^T`, and the cluster-robust meat (Liang
//! and Zeger 1986; the "CR1" small-sample factor `G / (G - 1) (n - 1) / (n - p)` over `G`
//! clusters) is
//!
//! `M_c = sum_g S_g S_g^T`,
//!
//! which equals `M` in expectation when the residuals are independent and grows by the
//! design effect `1 + (m - 1) rho` (cluster size `m`, intra-cluster correlation `rho`) when
//! they are not. [`clustered_sandwich_covariance`] uses the larger of the two in every
//! direction: `M + [M_c - M]_+` (the positive part of the difference), so that the
//! covariance is never narrower than the independent-residual one.

use nalgebra::{DMatrix, SMatrix, SVector};

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

/// `A + [B - A]_+`: the symmetric matrix `a` raised to `b` along every direction where `b` is
/// larger (the positive eigen-directions of `b - a`), so that `x^T result x >= max(x^T a x,
/// x^T b x)` for every `x`. The covariance of two models of the same error that never claims
/// more precision than either.
pub fn at_least<const N: usize>(
    a: &SMatrix<f64, N, N>,
    b: &SMatrix<f64, N, N>,
) -> SMatrix<f64, N, N> {
    // The dynamic decomposition: nalgebra's fixed-size one needs `N - 1` as a type.
    let eigen = DMatrix::from_fn(N, N, |r, c| b[(r, c)] - a[(r, c)]).symmetric_eigen();
    (0..N)
        .filter(|&k| eigen.eigenvalues[k] > 0.0)
        .fold(*a, |m, k| {
            let v = SVector::<f64, N>::from_fn(|r, _| eigen.eigenvectors[(r, k)]);
            m + v * v.transpose() * eigen.eigenvalues[k]
        })
}

/// The sandwich covariance with residuals correlated within clusters (module documentation):
/// `B^-1 (M + [M_c - M]_+) B^-1` from rows `(J_i, r_i, g_i)` with cluster `g_i < clusters`,
/// ([`at_least`]), where `M` is [`sandwich_covariance`]'s meat with its factor `n / (n - p)` and `M_c` the
/// cluster-robust meat with the factor `G / (G - 1) (n - 1) / (n - p)` over the `G` non-empty
/// clusters. `None` as [`sandwich_covariance`], or when rows name a cluster out of range.
pub fn clustered_sandwich_covariance<const N: usize>(
    rows: impl IntoIterator<Item = (SVector<f64, N>, f64, usize)>,
    clusters: usize,
    loss: &Loss,
    scale: f64,
    fixed: &[bool; N],
) -> Option<SMatrix<f64, N, N>> {
    let mask = SVector::<f64, N>::from_fn(|i, _| if fixed[i] { 0.0 } else { 1.0 });
    let (mut bread, mut meat) = (NormalEquations::<N>::new(), NormalEquations::<N>::new());
    let mut scores = vec![SVector::<f64, N>::zeros(); clusters];
    let mut members = vec![0usize; clusters];
    for (j, r, g) in rows {
        let u = r / scale;
        let j = j.component_mul(&mask);
        let psi = scale * loss.psi(u);
        bread.add(&j, 0.0, loss.psi_prime(u));
        meat.add(&j, 0.0, psi * psi);
        *scores.get_mut(g)? += j * psi;
        members[g] += 1;
    }
    let free = fixed.iter().filter(|f| !**f).count();
    let (n, groups) = (bread.count, members.iter().filter(|&&m| m > 0).count());
    if n <= free || groups < 2 {
        return None;
    }
    for (i, _) in fixed.iter().enumerate().filter(|(_, f)| **f) {
        bread.fix(i);
    }
    let independent = meat.hessian() * (n as f64 / (n - free) as f64);
    let clustered = scores
        .iter()
        .fold(SMatrix::<f64, N, N>::zeros(), |m, s| m + s * s.transpose())
        * (groups as f64 / (groups - 1) as f64 * (n - 1) as f64 / (n - free) as f64);
    let inverse = bread.hessian().cholesky()?.inverse();
    Some(inverse * at_least(&independent, &clustered) * inverse)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows `(J, r)` of a straight line `y = a + b t` fitted to residuals that share one
    /// offset per cluster of ten (perfectly correlated within a cluster): the clustered
    /// covariance of the offset `a` is about ten times the independent one, and equal to it
    /// when each row is its own cluster.
    #[test]
    fn clusters_of_correlated_residuals_widen_the_covariance() {
        let n = 200;
        let rows: Vec<(SVector<f64, 2>, f64, usize)> = (0..n)
            .map(|i| {
                let t = i as f64 / n as f64;
                let g = i / 10;
                let r = ((g * 7919) % 13) as f64 / 6.0 - 1.0;
                (SVector::<f64, 2>::new(1.0, t), r, g)
            })
            .collect();
        let fixed = [false; 2];
        let plain = sandwich_covariance(
            rows.iter().map(|&(j, r, _)| (j, r)),
            &Loss::Squared,
            1.0,
            &fixed,
        )
        .expect("well-posed");
        let own = clustered_sandwich_covariance(
            rows.iter().enumerate().map(|(i, &(j, r, _))| (j, r, i)),
            n,
            &Loss::Squared,
            1.0,
            &fixed,
        )
        .expect("well-posed");
        let clustered = clustered_sandwich_covariance(
            rows.iter().copied(),
            n / 10,
            &Loss::Squared,
            1.0,
            &fixed,
        )
        .expect("well-posed");
        // Singleton clusters: `M_c = M` up to the small-sample factors (a fraction of a percent).
        assert!((own[(0, 0)] / plain[(0, 0)] - 1.0).abs() < 0.02);
        let ratio = clustered[(0, 0)] / plain[(0, 0)];
        assert!(ratio > 5.0 && ratio < 20.0, "{ratio}");
        // Never narrower than the independent covariance.
        assert!((clustered - plain).symmetric_eigenvalues().min() > -1e-12);
    }

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
