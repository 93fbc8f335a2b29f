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
}
