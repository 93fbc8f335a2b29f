//! The bundle-adjustment normal equations and their Schur-complement solve.
//!
//! With free pose increments `c` (6 per pose) and point increments `p` (3 per point) the
//! damped normal equations are
//!
//! ```text
//! [ U   W ] [dc]     [g_c]
//! [ W^T V ] [dp] = - [g_p]
//! ```
//!
//! with `U = diag(U_i)` (6x6 per pose), `V = diag(V_j)` (3x3 per point) and one 6x3 block
//! `W_ij = sum w J_pose^T J_point` per observation of point `j` from pose `i`. Eliminating the
//! points gives the reduced camera system
//! `(U - W V^-1 W^T) dc = -g_c + W V^-1 g_p`, a dense `6k x 6k` Cholesky for `k` free poses, and
//! back-substitution `dp_j = V_j^-1 (-g_p,j - sum_i W_ij^T dc_i)`. The damping
//! `lambda D` is added to `U_i` and `V_j` before the elimination. A point whose damped `V_j` is
//! not positive definite (no active observation) keeps `dp_j = 0`.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Matrix6x3, Vector3, Vector6};
use rayon::prelude::*;
use vofront_robust::{Damping, LinearSystem, SolveError};

/// The increment of a bundle: one 6-vector per free pose, one 3-vector per point.
#[derive(Debug, Clone, PartialEq)]
pub struct BundleStep {
    /// `(rho, phi)` left increments of the free poses, oldest free pose first.
    pub poses: Vec<Vector6<f64>>,
    /// World-frame point increments, metres.
    pub points: Vec<Vector3<f64>>,
}

impl BundleStep {
    /// Euclidean norm of the whole increment.
    pub fn norm(&self) -> f64 {
        let sq: f64 = self.poses.iter().map(|d| d.norm_squared()).sum::<f64>()
            + self.points.iter().map(|d| d.norm_squared()).sum::<f64>();
        sq.sqrt()
    }
}

/// One off-diagonal block: observation of `point` from free pose `pose`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Coupling {
    /// Index among the free poses.
    pub pose: usize,
    /// `W_ij = sum w J_pose^T J_point`.
    pub w: Matrix6x3<f64>,
}

/// The rows of one point: `V_j`, `g_p,j` and its couplings with the free poses observing it.
#[derive(Debug, Clone)]
pub(crate) struct PointBlock {
    /// `V_j = sum w J_point^T J_point`.
    pub v: Matrix3<f64>,
    /// `g_p,j = sum w J_point^T r`.
    pub gp: Vector3<f64>,
    /// One per observation from a free pose.
    pub couplings: Vec<Coupling>,
}

/// The normal equations of a bundle at one state, in block form.
#[derive(Debug, Clone)]
pub struct SchurSystem {
    /// `U_i` per free pose.
    pub(crate) u: Vec<Matrix6<f64>>,
    /// `g_c,i` per free pose.
    pub(crate) gc: Vec<Vector6<f64>>,
    /// One block per point.
    pub(crate) points: Vec<PointBlock>,
}

/// `M + lambda D` for a square block, `D` as `damping` says.
fn damped<const N: usize>(
    m: &nalgebra::SMatrix<f64, N, N>,
    lambda: f64,
    damping: Damping,
) -> nalgebra::SMatrix<f64, N, N> {
    let mut out = *m;
    for i in 0..N {
        out[(i, i)] += match damping {
            Damping::Identity => lambda,
            Damping::Diagonal => lambda * m[(i, i)],
        };
    }
    out
}

/// Points per parallel task of the reduced camera system.
const CHUNK: usize = 256;

impl SchurSystem {
    /// `V_j + lambda D` inverted, zero when not positive definite (the point is held).
    fn point_inverses(&self, lambda: f64, damping: Damping) -> Vec<Matrix3<f64>> {
        self.points
            .par_iter()
            .map(|p| {
                damped(&p.v, lambda, damping)
                    .cholesky()
                    .map_or_else(Matrix3::zeros, |c| c.inverse())
            })
            .collect()
    }

    /// The reduced camera system `S dc = b` (damped), `S` of size `6k`.
    fn reduced(
        &self,
        inverses: &[Matrix3<f64>],
        lambda: f64,
        damping: Damping,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let n = 6 * self.u.len();
        let point_terms = |(mut s, mut b): (DMatrix<f64>, DVector<f64>), j: usize| {
            let (vinv, point) = (&inverses[j], &self.points[j]);
            for a in &point.couplings {
                let wv = a.w * vinv;
                let mut rb = b.fixed_rows_mut::<6>(6 * a.pose);
                rb += wv * point.gp;
                // Upper block triangle only; mirrored below.
                for c in point.couplings.iter().filter(|c| c.pose >= a.pose) {
                    let mut block = s.fixed_view_mut::<6, 6>(6 * a.pose, 6 * c.pose);
                    block -= wv * c.w.transpose();
                }
            }
            (s, b)
        };
        let zero = || (DMatrix::zeros(n, n), DVector::zeros(n));
        // Fixed chunks summed in order: the same sums whatever the thread count or scheduling
        // (rayon's fold/reduce would split adaptively, and a tracker would not be repeatable).
        let n_points = self.points.len();
        let partial: Vec<_> = (0..n_points.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| (c * CHUNK..n_points.min((c + 1) * CHUNK)).fold(zero(), point_terms))
            .collect();
        let (mut s, mut b) = partial
            .into_iter()
            .fold(zero(), |(s1, b1), (s2, b2)| (s1 + s2, b1 + b2));
        s.fill_lower_triangle_with_upper_triangle();
        for (i, (u, g)) in self.u.iter().zip(&self.gc).enumerate() {
            let mut block = s.fixed_view_mut::<6, 6>(6 * i, 6 * i);
            block += damped(u, lambda, damping);
            let mut rb = b.fixed_rows_mut::<6>(6 * i);
            rb -= g;
        }
        (s, b)
    }
}

impl LinearSystem for SchurSystem {
    type Step = BundleStep;

    /// Eliminates the points, solves the reduced camera system by Cholesky and
    /// back-substitutes. `max_condition` is not estimated on this large system: a reduced
    /// system that is not positive definite is [`SolveError::Degenerate`].
    fn solve(
        &self,
        lambda: f64,
        damping: Damping,
        max_condition: f64,
    ) -> Result<BundleStep, SolveError> {
        let finite = self.u.iter().all(|m| m.iter().all(|v| v.is_finite()))
            && self.gc.iter().all(|g| g.iter().all(|v| v.is_finite()))
            && self
                .points
                .iter()
                .all(|p| p.v.iter().chain(p.gp.iter()).all(|v| v.is_finite()));
        if !finite {
            return Err(SolveError::NotFinite);
        }
        let inverses = self.point_inverses(lambda, damping);
        let (s, b) = self.reduced(&inverses, lambda, damping);
        let dc = if b.is_empty() {
            b
        } else {
            s.cholesky()
                .ok_or(SolveError::Degenerate {
                    condition: f64::INFINITY,
                    limit: max_condition,
                })?
                .solve(&b)
        };
        let poses: Vec<Vector6<f64>> = (0..self.u.len())
            .map(|i| dc.fixed_rows::<6>(6 * i).into_owned())
            .collect();
        let points = self
            .points
            .par_iter()
            .zip(inverses.par_iter())
            .map(|(p, vinv)| {
                let rhs = p
                    .couplings
                    .iter()
                    .fold(-p.gp, |acc, a| acc - a.w.transpose() * poses[a.pose]);
                vinv * rhs
            })
            .collect();
        Ok(BundleStep { poses, points })
    }

    fn information_norm2(&self, step: &BundleStep) -> f64 {
        let poses: f64 = self
            .u
            .iter()
            .zip(&step.poses)
            .map(|(u, d)| (d.transpose() * u * d)[(0, 0)])
            .sum();
        let points: f64 = self
            .points
            .iter()
            .zip(&step.points)
            .map(|(p, dp)| {
                let cross: f64 = p
                    .couplings
                    .iter()
                    .map(|a| 2.0 * (step.poses[a.pose].transpose() * a.w * dp)[(0, 0)])
                    .sum();
                (dp.transpose() * p.v * dp)[(0, 0)] + cross
            })
            .sum();
        poses + points
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// A random symmetric positive definite system in block form and its dense equivalent.
    #[test]
    fn schur_solve_matches_the_dense_solve() {
        // Two free poses, three points, every point seen by both poses.
        let f = |k: usize| ((k as f64) * 0.7391).sin();
        let (k, m) = (2, 3);
        let n = 6 * k + 3 * m;
        // A = J^T J + I for a random J: positive definite, with the BA sparsity forced by
        // building J from per-observation rows.
        let mut a = DMatrix::<f64>::identity(n, n);
        let mut idx = 0;
        for j in 0..m {
            for i in 0..k {
                for _ in 0..2 {
                    let mut row = DVector::<f64>::zeros(n);
                    for c in 0..6 {
                        row[6 * i + c] = f(idx);
                        idx += 1;
                    }
                    for c in 0..3 {
                        row[6 * k + 3 * j + c] = f(idx);
                        idx += 1;
                    }
                    a += &row * row.transpose();
                }
            }
        }
        let g = DVector::<f64>::from_fn(n, |r, _| f(1000 + r));
        let system = SchurSystem {
            u: (0..k)
                .map(|i| a.fixed_view::<6, 6>(6 * i, 6 * i).into_owned())
                .collect(),
            gc: (0..k)
                .map(|i| g.fixed_rows::<6>(6 * i).into_owned())
                .collect(),
            points: (0..m)
                .map(|j| PointBlock {
                    v: a.fixed_view::<3, 3>(6 * k + 3 * j, 6 * k + 3 * j)
                        .into_owned(),
                    gp: g.fixed_rows::<3>(6 * k + 3 * j).into_owned(),
                    couplings: (0..k)
                        .map(|i| Coupling {
                            pose: i,
                            w: a.fixed_view::<6, 3>(6 * i, 6 * k + 3 * j).into_owned(),
                        })
                        .collect(),
                })
                .collect(),
        };
        let lambda = 0.1;
        let step = system.solve(lambda, Damping::Diagonal, 1e10).unwrap();
        let mut damped_a = a.clone();
        for i in 0..n {
            damped_a[(i, i)] += lambda * a[(i, i)];
        }
        let dense = damped_a.cholesky().unwrap().solve(&(-&g));
        for i in 0..k {
            let want = dense.fixed_rows::<6>(6 * i).into_owned();
            assert!((step.poses[i] - want).norm() < 1e-10, "pose {i}");
        }
        for j in 0..m {
            let want = dense.fixed_rows::<3>(6 * k + 3 * j).into_owned();
            assert!((step.points[j] - want).norm() < 1e-10, "point {j}");
        }
        // delta^T A delta from the blocks equals the dense quadratic form (undamped A).
        let mut full = DVector::<f64>::zeros(n);
        for i in 0..k {
            full.fixed_rows_mut::<6>(6 * i).copy_from(&step.poses[i]);
        }
        for j in 0..m {
            full.fixed_rows_mut::<3>(6 * k + 3 * j)
                .copy_from(&step.points[j]);
        }
        let quad = (full.transpose() * &a * &full)[(0, 0)];
        assert!((system.information_norm2(&step) - quad).abs() < 1e-9 * quad.abs());
    }
}
