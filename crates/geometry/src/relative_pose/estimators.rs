//! RANSAC estimators of the two-view pipeline on normalized coordinates (SoA arrays).

use nalgebra::{Matrix3, Vector2, Vector3};

use super::refine::refine_relative_pose;
use crate::essential::{
    decompose_essential, essential_5pt, essential_8pt, select_by_chirality, RecoverConfig,
};
use crate::homography::homography_dlt;
use crate::lie::hat;
use crate::ransac::Estimator;
use vofront_robust::Loss;

/// Normalized coordinates of the correspondences, one array per coordinate; built with
/// [`Correspondences::push`].
///
/// Invariant: the five arrays have the same length (the fields are private so that
/// [`Correspondences::push`] is the only way in and the packed copy stays in step).
#[derive(Debug, Clone, Default)]
pub struct Correspondences {
    /// `x` of image 1.
    u1: Vec<f64>,
    /// `y` of image 1.
    v1: Vec<f64>,
    /// `x` of image 2.
    u2: Vec<f64>,
    /// `y` of image 2.
    v2: Vec<f64>,
    /// The four coordinates in `f32`, interleaved per correspondence `[u1, v1, u2, v2]`, for
    /// the vectorised scoring loop (kept in step with the other arrays by [`Self::push`]).
    packed: Vec<[f32; 4]>,
}

impl Correspondences {
    /// `x` of image 1, one per correspondence.
    #[inline]
    pub fn u1(&self) -> &[f64] {
        &self.u1
    }

    /// `y` of image 1, one per correspondence.
    #[inline]
    pub fn v1(&self) -> &[f64] {
        &self.v1
    }

    /// `x` of image 2, one per correspondence.
    #[inline]
    pub fn u2(&self) -> &[f64] {
        &self.u2
    }

    /// `y` of image 2, one per correspondence.
    #[inline]
    pub fn v2(&self) -> &[f64] {
        &self.v2
    }

    /// Number of correspondences.
    pub fn len(&self) -> usize {
        self.u1.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.u1.is_empty()
    }

    /// Adds one correspondence.
    pub fn push(&mut self, a: &Vector2<f64>, b: &Vector2<f64>) {
        self.u1.push(a.x);
        self.v1.push(a.y);
        self.u2.push(b.x);
        self.v2.push(b.y);
        self.packed
            .push([a.x as f32, a.y as f32, b.x as f32, b.y as f32]);
    }

    /// Homogeneous ray `(x, y, 1)` of correspondence `i` in image 1.
    #[inline]
    pub fn ray1(&self, i: usize) -> Vector3<f64> {
        Vector3::new(self.u1[i], self.v1[i], 1.0)
    }

    /// Homogeneous ray `(x, y, 1)` of correspondence `i` in image 2.
    #[inline]
    pub fn ray2(&self, i: usize) -> Vector3<f64> {
        Vector3::new(self.u2[i], self.v2[i], 1.0)
    }

    /// Point `i` of image 1.
    #[inline]
    pub fn p1(&self, i: usize) -> Vector2<f64> {
        Vector2::new(self.u1[i], self.v1[i])
    }

    /// Point `i` of image 2.
    #[inline]
    pub fn p2(&self, i: usize) -> Vector2<f64> {
        Vector2::new(self.u2[i], self.v2[i])
    }
}

/// Squared Sampson error of `E` at the normalized correspondence `(u1, v1) <-> (u2, v2)`.
#[inline(always)]
fn sampson_sq(e: &[f64; 9], u1: f64, v1: f64, u2: f64, v2: f64) -> f64 {
    let l2x = e[0] * u1 + e[1] * v1 + e[2];
    let l2y = e[3] * u1 + e[4] * v1 + e[5];
    let l2z = e[6] * u1 + e[7] * v1 + e[8];
    let l1x = e[0] * u2 + e[3] * v2 + e[6];
    let l1y = e[1] * u2 + e[4] * v2 + e[7];
    let c = u2 * l2x + v2 * l2y + l2z;
    c * c / (l2x * l2x + l2y * l2y + l1x * l1x + l1y * l1y)
}

/// Row-major entries of a 3x3 matrix.
#[inline]
fn row_major(m: &Matrix3<f64>) -> [f64; 9] {
    std::array::from_fn(|k| m[(k / 3, k % 3)])
}

/// Essential matrix hypotheses from the five-point solver, scored by the Sampson error
/// (normalized units; the threshold is `threshold_px / f`). The second field is the noise
/// scale (normalized units) of the local optimisation, which refits on the inliers by the
/// eight-point algorithm followed by Huber IRLS on the Sampson distance.
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
            let (r, t) =
                refine_relative_pose(self.0, indices, 1.0, self.1, Loss::Huber(1.345), init);
            out.push(hat(&t) * r.matrix());
        }
    }

    fn residual_sq(&self, e: &Matrix3<f64>, i: usize) -> f64 {
        let c = self.0;
        sampson_sq(&row_major(e), c.u1[i], c.v1[i], c.u2[i], c.v2[i])
    }

    fn score(&self, e: &Matrix3<f64>, threshold_sq: f64, bound: f64) -> (f64, usize) {
        // Branch-free f32 loop over blocks (vectorises); early exit between blocks once the
        // truncated cost exceeds the best score.
        let m: [f32; 9] = row_major(e).map(|v| v as f32);
        let t = threshold_sq as f32;
        let mut cost = 0.0f64;
        let mut inliers = 0usize;
        for block in self.0.packed.chunks(128) {
            let mut acc = 0.0f32;
            let mut count = 0u32;
            for p in block {
                let [u1, v1, u2, v2] = *p;
                let l2x = m[0] * u1 + m[1] * v1 + m[2];
                let l2y = m[3] * u1 + m[4] * v1 + m[5];
                let l2z = m[6] * u1 + m[7] * v1 + m[8];
                let l1x = m[0] * u2 + m[3] * v2 + m[6];
                let l1y = m[1] * u2 + m[4] * v2 + m[7];
                let c = u2 * l2x + v2 * l2y + l2z;
                let r = c * c / (l2x * l2x + l2y * l2y + l1x * l1x + l1y * l1y);
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
#[derive(Debug, Clone, Copy, PartialEq)]
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
}

/// Homography hypotheses from the four-point DLT, scored by the mean of the forward and
/// backward squared transfer errors (normalized units).
pub struct HomographyEstimator<'a>(pub &'a Correspondences);

impl HomographyEstimator<'_> {
    fn fit(&self, indices: &[usize], out: &mut Vec<HomographyModel>) {
        out.clear();
        let a: Vec<Vector2<f64>> = indices.iter().map(|&i| self.0.p1(i)).collect();
        let b: Vec<Vector2<f64>> = indices.iter().map(|&i| self.0.p2(i)).collect();
        out.extend(homography_dlt(&a, &b).and_then(HomographyModel::new));
    }
}

/// `(|x2 - H x1|^2, |x1 - H^-1 x2|^2)` for one correspondence.
#[inline(always)]
pub fn transfer_sq(m: &HomographyModel, c: &Correspondences, i: usize) -> (f64, f64) {
    let (h, g) = (&m.h, &m.h_inv);
    let (x, y, u, v) = (c.u1[i], c.v1[i], c.u2[i], c.v2[i]);
    let w = h[(2, 0)] * x + h[(2, 1)] * y + h[(2, 2)];
    let fx = (h[(0, 0)] * x + h[(0, 1)] * y + h[(0, 2)]) / w - u;
    let fy = (h[(1, 0)] * x + h[(1, 1)] * y + h[(1, 2)]) / w - v;
    let w2 = g[(2, 0)] * u + g[(2, 1)] * v + g[(2, 2)];
    let bx = (g[(0, 0)] * u + g[(0, 1)] * v + g[(0, 2)]) / w2 - x;
    let by = (g[(1, 0)] * u + g[(1, 1)] * v + g[(1, 2)]) / w2 - y;
    (fx * fx + fy * fy, bx * bx + by * by)
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
        let (a, b) = transfer_sq(m, self.0, i);
        let r = 0.5 * (a + b);
        if r.is_nan() {
            f64::INFINITY
        } else {
            r
        }
    }
}
