//! The pose blocks of the bundle's normal equations, accumulated from the observations'
//! Jacobian rows (the point blocks are built per point in [`super::problem`]).

use super::problem::{Matrix8, Vector8, N};

/// Observations whose pose blocks one task accumulates.
pub(super) const OBSERVATIONS_PER_CHUNK: usize = 512;

/// The pose blocks of the normal equations: per free frame `J^T W J` and `J^T W r`, and per
/// (host, target) pair of free frames the off-diagonal `J_h^T W J_t` (row-major over pairs).
pub(super) struct PoseBlocks {
    pub u: Vec<Matrix8>,
    pub gc: Vec<Vector8>,
    pub pairs: Vec<Matrix8>,
}

impl PoseBlocks {
    /// Zero blocks for `n_free` free frames.
    pub fn zeros(n_free: usize) -> Self {
        Self {
            u: vec![Matrix8::zeros(); n_free],
            gc: vec![Vector8::zeros(); n_free],
            pairs: vec![Matrix8::zeros(); n_free * n_free],
        }
    }

    /// Adds one observation's Jacobian rows for its host and target frames, with Huber
    /// weights `w` and residuals `r`, of free host and target indices `(h, t)` (`None`: held).
    pub fn add(
        &mut self,
        (host, target): (&Matrix8, &Matrix8),
        (w, r): &(Vector8, Vector8),
        (h, t): (Option<usize>, Option<usize>),
    ) {
        // Rows scaled by sqrt(w): J^T W J = Js^T Js, J^T W r = Js^T rs.
        let sw = w.map(f64::sqrt);
        let rs = r.component_mul(&sw);
        let (mut jh, mut jt) = (*host, *target);
        for i in 0..N {
            jh.row_mut(i).scale_mut(sw[i]);
            jt.row_mut(i).scale_mut(sw[i]);
        }
        if let Some(h) = h {
            self.u[h] += jh.tr_mul(&jh);
            self.gc[h] += jh.tr_mul(&rs);
        }
        if let Some(t) = t {
            self.u[t] += jt.tr_mul(&jt);
            self.gc[t] += jt.tr_mul(&rs);
        }
        if let (Some(h), Some(t)) = (h, t) {
            let n = self.u.len();
            self.pairs[h * n + t] += jh.tr_mul(&jt);
        }
    }

    /// The sum of two accumulations.
    pub fn merged(mut self, other: Self) -> Self {
        let sums = [(&mut self.u, &other.u), (&mut self.pairs, &other.pairs)];
        for (mine, theirs) in sums {
            mine.iter_mut().zip(theirs).for_each(|(m, t)| *m += t);
        }
        self.gc.iter_mut().zip(&other.gc).for_each(|(m, t)| *m += t);
        self
    }
}
