//! RANSAC estimators of the two-view pipeline on normalized coordinates (SoA arrays).

use nalgebra::{Matrix3, Vector2, Vector3};

use super::correspondences::Correspondences;
use super::refine::local_refinement;
use crate::essential::{
    decompose_essential, essential_5pt, essential_8pt, select_by_chirality, RecoverConfig,
};
use crate::homography::homography_dlt;
use crate::lie::hat;
use crate::ransac::Estimator;
use crate::residual::{row_major, symmetric_transfer_sq, Epipolar};

/// IRLS iterations of one local optimisation: enough to gather a hypothesis's inliers (as in
/// PnP's RANSAC); the chosen model is refined to convergence afterwards.
pub const LO_ITERATIONS: usize = 4;

/// Essential matrix hypotheses from the five-point solver, scored by the Sampson error
/// (normalized units; the threshold is `ransac.threshold / f`). The second field is the noise
/// scale (normalized units) of the local optimisation, which refits on the inliers by the
/// eight-point algorithm followed by a few (`LO_ITERATIONS`) Huber IRLS steps on the Sampson
/// distance.
pub struct EssentialEstimator<'a>(pub &'a Correspondences, pub f64);

impl Estimator for EssentialEstimator<'_> {
    type Model = Matrix3<f64>;

    fn sample_size(&self) -> usize {
        5
    }

    fn len(&self) -> usize {
        self.0.len()
    }

    fn fit_minimal(&self, sample: &[usize], out: &mut Vec<Matrix3<f64>>) {
        let a: [Vector3<f64>; 5] = std::array::from_fn(|k| self.0.ray1(sample[k]));
        let b: [Vector3<f64>; 5] = std::array::from_fn(|k| self.0.ray2(sample[k]));
        essential_5pt(&a, &b, out);
    }

    fn fit_nonminimal(&self, indices: &[usize], out: &mut Vec<Matrix3<f64>>) {
        let a: Vec<Vector3<f64>> = indices.iter().map(|&i| self.0.ray1(i)).collect();
        let b: Vec<Vector3<f64>> = indices.iter().map(|&i| self.0.ray2(i)).collect();
        essential_8pt(&a, &b, out);
        let Some(e8) = out.first().copied() else {
            return;
        };
        let used = vec![true; a.len()];
        let rec = select_by_chirality(
            &decompose_essential(&e8),
            &a,
            &b,
            &used,
            &RecoverConfig::default(),
        );
        if let Some(rec) = rec.filter(|r| r.good >= 5) {
            let init = (
                rec.pose.rotation.to_rotation_matrix(),
                rec.pose.translation.vector,
            );
            let (r, t) = local_refinement(self.0, indices, self.1, init, LO_ITERATIONS);
            out.push(hat(&t) * r.matrix());
        }
    }

    fn residual_sq(&self, e: &Matrix3<f64>, i: usize) -> f64 {
        self.0.epipolar(&row_major(e), i).sampson_sq()
    }

    fn score(&self, e: &Matrix3<f64>, threshold_sq: f64, bound: f64) -> (f64, usize) {
        // Branch-free f32 loop over blocks (vectorises); early exit between blocks once the
        // truncated cost exceeds the best score.
        let m: [f32; 9] = row_major(e).map(|v| v as f32);
        let t = threshold_sq as f32;
        let mut cost = 0.0f64;
        let mut inliers = 0usize;
        for block in self.0.packed().chunks(128) {
            let mut acc = 0.0f32;
            let mut count = 0u32;
            for p in block {
                let [u1, v1, u2, v2] = *p;
                // Unchecked `c^2 / D`: a degenerate one is NaN or infinite and fails `r < t`
                // (an outlier, as `crate::residual` decides).
                let r = Epipolar::new(&m, u1, v1, u2, v2).ratio();
                let inside = r < t;
                acc += if inside { r } else { t };
                count += inside as u32;
            }
            cost += acc as f64;
            inliers += count as usize;
            if cost > bound {
                return (f64::INFINITY, inliers);
            }
        }
        (cost, inliers)
    }
}

/// A homography and its inverse.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct HomographyModel {
    /// `x2 ~ H x1`.
    pub h: Matrix3<f64>,
    /// `H^-1`.
    pub h_inv: Matrix3<f64>,
}

impl HomographyModel {
    fn new(h: Matrix3<f64>) -> Option<Self> {
        h.try_inverse().map(|h_inv| Self { h, h_inv })
    }

    /// The rotation-only model `x2 ~ R x1` (`H = R`, `H^-1 = R^T`).
    pub fn rotation(r: &nalgebra::Rotation3<f64>) -> Self {
        Self {
            h: *r.matrix(),
            h_inv: r.matrix().transpose(),
        }
    }

    /// Symmetric transfer error of correspondence `i` ([`symmetric_transfer_sq`]).
    #[inline]
    pub fn residual_sq(&self, data: &Correspondences, i: usize) -> f64 {
        symmetric_transfer_sq(&self.h, &self.h_inv, &data.p1(i), &data.p2(i))
    }
}

/// Homography hypotheses from the four-point DLT, scored by the symmetric transfer error
/// ([`symmetric_transfer_sq`], normalized units).
pub struct HomographyEstimator<'a>(pub &'a Correspondences);

impl HomographyEstimator<'_> {
    fn fit(&self, indices: &[usize], out: &mut Vec<HomographyModel>) {
        out.clear();
        let a: Vec<Vector2<f64>> = indices.iter().map(|&i| self.0.p1(i)).collect();
        let b: Vec<Vector2<f64>> = indices.iter().map(|&i| self.0.p2(i)).collect();
        out.extend(homography_dlt(&a, &b).and_then(HomographyModel::new));
    }
}

impl Estimator for HomographyEstimator<'_> {
    type Model = HomographyModel;

    fn sample_size(&self) -> usize {
        4
    }

    fn len(&self) -> usize {
        self.0.len()
    }

    fn fit_minimal(&self, sample: &[usize], out: &mut Vec<HomographyModel>) {
        self.fit(sample, out);
    }

    fn fit_nonminimal(&self, indices: &[usize], out: &mut Vec<HomographyModel>) {
        self.fit(indices, out);
    }

    fn residual_sq(&self, m: &HomographyModel, i: usize) -> f64 {
        m.residual_sq(self.0, i)
    }
}
