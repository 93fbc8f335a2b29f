//! The block normal equations of a bundle adjustment and their Schur-complement solve.
//!
//! The unknowns are `k` free *pose* blocks of `P` parameters each (a 6-dof pose; an 8-dof
//! frame of a photometric bundle, pose and affine brightness `a, b`) and `m` *point* blocks of
//! `Q` parameters each (a 3-dof point; a 1-dof inverse depth). With pose increments `c` and
//! point increments `p` the damped normal equations are
//!
//! ```text
//! [ U   W ] [dc]     [g_c]
//! [ W^T V ] [dp] = - [g_p]
//! ```
//!
//! with `U` block-diagonal (`U_i`, `P x P` per pose) except for the pose pairs that share a
//! residual (a photometric residual depends on the point's host frame and on the frame it is
//! seen in: `U_ik = sum w J_i^T J_k`, given in [`SchurSystem::pairs`]), `V = diag(V_j)`
//! (`Q x Q` per point) and one `P x Q` block `W_ij = sum w J_pose^T J_point` per observation
//! of point `j` from pose `i`.
//! Eliminating the points gives the reduced camera system
//! `(U - W V^-1 W^T) dc = -g_c + W V^-1 g_p`, a dense `Pk x Pk` Cholesky, and
//! back-substitution `dp_j = V_j^-1 (-g_p,j - sum_i W_ij^T dc_i)`. The damping `lambda D` is
//! added to `U_i` and `V_j` before the elimination. A point whose damped `V_j` is not positive
//! definite (no active observation) keeps `dp_j = 0`. With `Q = 1` every `V_j` is a scalar
//! and the elimination is a division.
//!
//! [`SchurSystem`] is a [`LinearSystem`], so the one Levenberg-Marquardt loop
//! ([`crate::lm::levenberg_marquardt`]) drives it; the problem fills its blocks in
//! [`LmProblem::linearize`](crate::lm::LmProblem::linearize).

use nalgebra::{DMatrix, DVector, SMatrix, SVector};
use rayon::prelude::*;

use crate::lm::LinearSystem;
use crate::solve::{Damping, SolveError};

/// The increment of a bundle: one `P`-vector per free pose, one `Q`-vector per point.
#[derive(Debug, Clone, PartialEq)]
pub struct SchurStep<const P: usize, const Q: usize> {
    /// Increments of the free poses, in the order of [`SchurSystem::u`].
    pub poses: Vec<SVector<f64, P>>,
    /// Increments of the points, in the order of [`SchurSystem::points`].
    pub points: Vec<SVector<f64, Q>>,
}

impl<const P: usize, const Q: usize> SchurStep<P, Q> {
    /// Euclidean norm of the whole increment.
    pub fn norm(&self) -> f64 {
        let sq: f64 = self.poses.iter().map(|d| d.norm_squared()).sum::<f64>()
            + self.points.iter().map(|d| d.norm_squared()).sum::<f64>();
        sq.sqrt()
    }
}

/// One off-diagonal block: an observation of a point from free pose `pose`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coupling<const P: usize, const Q: usize> {
    /// Index among the free poses (into [`SchurSystem::u`]).
    pub pose: usize,
    /// `W_ij = sum w J_pose^T J_point` (`P x Q`).
    pub w: SMatrix<f64, P, Q>,
}

/// The rows of one point: `V_j`, `g_p,j` and its couplings with the free poses observing it.
#[derive(Debug, Clone, PartialEq)]
pub struct PointBlock<const P: usize, const Q: usize> {
    /// `V_j = sum w J_point^T J_point` (`Q x Q`).
    pub v: SMatrix<f64, Q, Q>,
    /// `g_p,j = sum w J_point^T r`.
    pub gp: SVector<f64, Q>,
    /// One per observation from a free pose (several observations from one pose may be
    /// given separately or summed).
    pub couplings: Vec<Coupling<P, Q>>,
}

impl<const P: usize, const Q: usize> PointBlock<P, Q> {
    /// A point with no rows yet: `V_j = 0`, `g_p,j = 0`, no couplings.
    pub fn zeros() -> Self {
        Self {
            v: SMatrix::zeros(),
            gp: SVector::zeros(),
            couplings: Vec::new(),
        }
    }
}

/// An off-diagonal pose block: residuals that depend on both free poses `i != k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PosePair<const P: usize> {
    /// One of the two free poses.
    pub i: usize,
    /// The other free pose (`k != i`).
    pub k: usize,
    /// `U_ik = sum w J_i^T J_k` (`P x P`); several blocks of one pair are summed.
    pub u: SMatrix<f64, P, P>,
}

/// The normal equations of a bundle at one state, in block form (see the module
/// documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct SchurSystem<const P: usize, const Q: usize> {
    /// `U_i = sum w J_pose^T J_pose` per free pose (`P x P`).
    pub u: Vec<SMatrix<f64, P, P>>,
    /// `g_c,i = sum w J_pose^T r` per free pose.
    pub gc: Vec<SVector<f64, P>>,
    /// One block per point.
    pub points: Vec<PointBlock<P, Q>>,
    /// The off-diagonal pose blocks (none when every residual depends on one pose).
    pub pairs: Vec<PosePair<P>>,
}

/// `M + lambda D` for a square block, `D` as `damping` says.
fn damped<const N: usize>(
    m: &SMatrix<f64, N, N>,
    lambda: f64,
    damping: Damping,
) -> SMatrix<f64, N, N> {
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

impl<const P: usize, const Q: usize> SchurSystem<P, Q> {
    /// `V_j + lambda D` inverted, zero when not positive definite (the point is held).
    fn point_inverses(&self, lambda: f64, damping: Damping) -> Vec<SMatrix<f64, Q, Q>> {
        self.points
            .par_iter()
            .map(|p| {
                damped(&p.v, lambda, damping)
                    .cholesky()
                    .map_or_else(SMatrix::zeros, |c| c.inverse())
            })
            .collect()
    }

    /// The reduced camera system `S dc = b` (damped), `S` of size `Pk`.
    fn reduced(
        &self,
        inverses: &[SMatrix<f64, Q, Q>],
        lambda: f64,
        damping: Damping,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let n = P * self.u.len();
        let point_terms = |(mut s, mut b): (DMatrix<f64>, DVector<f64>), j: usize| {
            let (vinv, point) = (&inverses[j], &self.points[j]);
            for a in &point.couplings {
                let wv = a.w * vinv;
                let mut rb = b.fixed_rows_mut::<P>(P * a.pose);
                rb += wv * point.gp;
                // Upper block triangle only; mirrored below.
                for c in point.couplings.iter().filter(|c| c.pose >= a.pose) {
                    let mut block = s.fixed_view_mut::<P, P>(P * a.pose, P * c.pose);
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
        for pair in &self.pairs {
            // Upper block triangle (a pair given as `i > k` is transposed into it).
            let (i, k, u) = if pair.i < pair.k {
                (pair.i, pair.k, pair.u)
            } else {
                (pair.k, pair.i, pair.u.transpose())
            };
            let mut block = s.fixed_view_mut::<P, P>(P * i, P * k);
            block += u;
        }
        s.fill_lower_triangle_with_upper_triangle();
        for (i, (u, g)) in self.u.iter().zip(&self.gc).enumerate() {
            let mut block = s.fixed_view_mut::<P, P>(P * i, P * i);
            block += damped(u, lambda, damping);
            let mut rb = b.fixed_rows_mut::<P>(P * i);
            rb -= g;
        }
        (s, b)
    }
}

impl<const P: usize, const Q: usize> LinearSystem for SchurSystem<P, Q> {
    type Step = SchurStep<P, Q>;

    /// Eliminates the points, solves the reduced camera system by Cholesky and
    /// back-substitutes. `max_condition` is not estimated on this large system: a reduced
    /// system that is not positive definite is [`SolveError::Degenerate`].
    fn solve(
        &self,
        lambda: f64,
        damping: Damping,
        max_condition: f64,
    ) -> Result<SchurStep<P, Q>, SolveError> {
        let finite = self.u.iter().all(|m| m.iter().all(|v| v.is_finite()))
            && self.pairs.iter().all(|p| p.u.iter().all(|v| v.is_finite()))
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
        let poses: Vec<SVector<f64, P>> = (0..self.u.len())
            .map(|i| dc.fixed_rows::<P>(P * i).into_owned())
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
        Ok(SchurStep { poses, points })
    }

    fn information_norm2(&self, step: &SchurStep<P, Q>) -> f64 {
        let poses: f64 = self
            .u
            .iter()
            .zip(&step.poses)
            .map(|(u, d)| (d.transpose() * u * d)[(0, 0)])
            .sum::<f64>()
            + self
                .pairs
                .iter()
                .map(|p| 2.0 * (step.poses[p.i].transpose() * p.u * step.poses[p.k])[(0, 0)])
                .sum::<f64>();
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
mod tests;
