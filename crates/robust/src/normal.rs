//! Accumulation of weighted normal equations for a fixed number of parameters `N`.
//!
//! For residual rows `r_i(x)` with Jacobians `J_i = dr_i/dx` (a `1 x N` row) and weights
//! `w_i`, the Gauss-Newton step `d` solves `H d = -g` with
//!
//! `H = sum_i w_i J_i^T J_i`, `g = sum_i w_i J_i^T r_i`, and the weighted cost is
//! `sum_i w_i r_i^2 / 2`.
//!
//! Only the upper triangle of `H` is accumulated (`N (N + 1) / 2` multiply-adds a row); it is
//! mirrored when read. Two accumulators over disjoint rows [`merge`](NormalEquations::merge)
//! into the accumulator over all rows, which is how rayon reductions use it.

use nalgebra::{SMatrix, SVector};

use crate::solve::scaled_condition;

/// Running sums `H = J^T W J`, `g = J^T W r`, weighted cost and row count.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalEquations<const N: usize> {
    /// Upper triangle of `H` (row-major pairs `i <= j`); the lower part is not maintained.
    upper: SMatrix<f64, N, N>,
    /// `g = sum w_i J_i^T r_i`.
    pub g: SVector<f64, N>,
    /// `sum w_i r_i^2 / 2`.
    pub cost: f64,
    /// Sum of the weights `sum w_i`.
    pub weight_sum: f64,
    /// Number of rows added.
    pub count: usize,
}

impl<const N: usize> Default for NormalEquations<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> NormalEquations<N> {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self {
            upper: SMatrix::zeros(),
            g: SVector::zeros(),
            cost: 0.0,
            weight_sum: 0.0,
            count: 0,
        }
    }

    /// Adds one residual row `r` with Jacobian `j` and weight `w`.
    #[inline]
    pub fn add(&mut self, j: &SVector<f64, N>, r: f64, w: f64) {
        for c in 0..N {
            let wjc = w * j[c];
            for rr in 0..=c {
                self.upper[(rr, c)] += wjc * j[rr];
            }
            self.g[c] += wjc * r;
        }
        self.cost += 0.5 * w * r * r;
        self.weight_sum += w;
        self.count += 1;
    }

    /// Adds the rows of `other` (accumulated over different residuals) to `self`.
    pub fn merge(mut self, other: &Self) -> Self {
        self.upper += other.upper;
        self.g += other.g;
        self.cost += other.cost;
        self.weight_sum += other.weight_sum;
        self.count += other.count;
        self
    }

    /// The full symmetric `H = J^T W J`.
    pub fn hessian(&self) -> SMatrix<f64, N, N> {
        let mut h = self.upper;
        for c in 0..N {
            for r in (c + 1)..N {
                h[(r, c)] = h[(c, r)];
            }
        }
        h
    }

    /// Holds parameter `i` fixed: its row and column of `H` become those of the identity and
    /// `g_i = 0`, so that a solve gives `delta_i = 0` and leaves the others unaffected.
    pub fn fix(&mut self, i: usize) {
        self.upper.row_mut(i).fill(0.0);
        self.upper.column_mut(i).fill(0.0);
        self.upper[(i, i)] = 1.0;
        self.g[i] = 0.0;
    }

    /// Gauss-Newton covariance `sigma^2 H^-1` with `sigma^2 = 2 cost / (count - N)` (the
    /// weighted residual variance per degree of freedom, floored at one degree).
    ///
    /// `None` (unknown, never a zero matrix) when `H` is not invertible or its Jacobi-scaled
    /// condition number exceeds `max_condition`.
    pub fn covariance(&self, max_condition: f64) -> Option<SMatrix<f64, N, N>> {
        let h = self.hessian();
        let condition = scaled_condition(&h);
        if condition.is_nan() || condition > max_condition {
            return None;
        }
        let dof = self.count.saturating_sub(N).max(1) as f64;
        h.try_inverse().map(|inv| inv * (2.0 * self.cost / dof))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_row_gives_outer_product() {
        let mut ne = NormalEquations::<3>::new();
        let j = SVector::<f64, 3>::new(1.0, 2.0, 3.0);
        ne.add(&j, 0.5, 2.0);
        assert_eq!(ne.hessian(), 2.0 * j * j.transpose());
        assert_eq!(ne.g, j);
        assert_eq!(ne.cost, 0.25);
        assert_eq!(ne.count, 1);
    }

    #[test]
    fn fixed_parameter_gets_a_zero_step_and_the_others_their_own() {
        // Two coupled parameters; with the second fixed the first solves h00 d0 = -g0.
        let mut ne = NormalEquations::<2>::new();
        ne.add(&SVector::from([1.0, 1.0]), 2.0, 1.0);
        ne.add(&SVector::from([1.0, -1.0]), 0.0, 1.0);
        ne.fix(1);
        let h = ne.hessian();
        assert_eq!(h, SMatrix::<f64, 2, 2>::new(2.0, 0.0, 0.0, 1.0));
        assert_eq!(ne.g, SVector::from([2.0, 0.0]));
    }

    #[test]
    fn covariance_of_a_singular_system_is_unknown() {
        let mut ne = NormalEquations::<2>::new();
        for _ in 0..5 {
            ne.add(&SVector::from([1.0, 1.0]), 0.5, 1.0);
        }
        assert_eq!(ne.covariance(1e10), None);
    }
}
