//! RANSAC estimators of the two-view pipeline on normalized coordinates (SoA arrays).

use nalgebra::{Matrix3, Vector2, Vector3};

use super::correspondences::Correspondences;
use super::refine::local_refinement;
use crate::essential::{
    best_by_chirality, decompose_essential, essential_5pt, essential_8pt, RecoverConfig,
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
        let best = best_by_chirality(
            &decompose_essential(&e8),
            &a,
            &b,
            &used,
            &RecoverConfig::default(),
        );
        if let Some((pose, _)) = best.filter(|&(_, good)| good >= 5) {
            let init = (pose.rotation.to_rotation_matrix(), pose.translation.vector);
            let (r, t) = local_refinement(self.0, indices, self.1, init, LO_ITERATIONS);
            out.push(hat(&t) * r.matrix());
        }
    }

    fn residual_sq(&self, e: &Matrix3<f64>, i: usize) -> f64 {
        self.0.epipolar(&row_major(e), i).sampson_sq()
    }

    fn score(&self, e: &Matrix3<f64>, threshold_sq: f64, bound: f64) -> (f64, usize) {
        let m: [f32; 9] = row_major(e).map(|v| v as f32);
        truncated_sampson(self.0.packed(), &m, threshold_sq as f32, bound)
    }
}

/// The truncated Sampson cost `sum_i min(c_i^2 / D_i, t)` of the packed `[u1, v1, u2, v2]`
/// correspondences under the row-major `m` and the number of them with `c_i^2 / D_i < t`;
/// `(inf, count so far)` as soon as the cost exceeds `bound`. Runs the AVX2 + FMA compilation of
/// [`truncated_sampson_portable`] when the CPU has them (the same arithmetic, so the same result).
fn truncated_sampson(packed: &[[f32; 4]], m: &[f32; 9], t: f32, bound: f64) -> (f64, usize) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA, checked just above.
            return unsafe { truncated_sampson_avx2(packed, m, t, bound) };
        }
    }
    truncated_sampson_portable(packed, m, t, bound)
}

/// [`truncated_sampson_portable`] compiled for AVX2 and FMA (8 correspondences per register).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn truncated_sampson_avx2(
    packed: &[[f32; 4]],
    m: &[f32; 9],
    t: f32,
    bound: f64,
) -> (f64, usize) {
    truncated_sampson_portable(packed, m, t, bound)
}

/// Correspondences per group of [`truncated_sampson_portable`]: one AVX2 register of `f32`.
const LANES: usize = 8;

/// The portable body of [`truncated_sampson`]: branch-free `f32` sums in `LANES` independent
/// lanes (a single running sum would be a sequential chain the compiler may not reorder, so it
/// would not vectorise), with the early exit between blocks of 128.
#[inline(always)]
fn truncated_sampson_portable(
    packed: &[[f32; 4]],
    m: &[f32; 9],
    t: f32,
    bound: f64,
) -> (f64, usize) {
    // Unchecked `c^2 / D`: a degenerate one is NaN or infinite and fails `r < t` (an outlier,
    // as `crate::residual` decides); returns `(min(r, t), r < t)`.
    let truncated = |p: &[f32; 4]| {
        let r = Epipolar::new(m, p[0], p[1], p[2], p[3]).ratio();
        let inside = r < t;
        (if inside { r } else { t }, inside as u32)
    };
    let mut cost = 0.0f64;
    let mut inliers = 0usize;
    for block in packed.chunks(128) {
        let mut acc = [0.0f32; LANES];
        let mut count = [0u32; LANES];
        let mut groups = block.chunks_exact(LANES);
        for group in &mut groups {
            for i in 0..LANES {
                let (r, inside) = truncated(&group[i]);
                acc[i] += r;
                count[i] += inside;
            }
        }
        for (i, p) in groups.remainder().iter().enumerate() {
            let (r, inside) = truncated(p);
            acc[i] += r;
            count[i] += inside;
        }
        cost += acc.iter().map(|&a| f64::from(a)).sum::<f64>();
        inliers += count.iter().sum::<u32>() as usize;
        if cost > bound {
            return (f64::INFINITY, inliers);
        }
    }
    (cost, inliers)
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, Rng, SeedableRng};

    /// Random correspondences (a few exactly degenerate, `D = 0` under `m`) and a random `E`.
    fn problem(n: usize, seed: u64) -> (Vec<[f32; 4]>, [f32; 9]) {
        let mut rng = StdRng::seed_from_u64(seed);
        let m: [f32; 9] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let packed = (0..n)
            .map(|i| {
                if i % 97 == 0 {
                    [0.0; 4]
                } else {
                    std::array::from_fn(|_| rng.random_range(-0.5..0.5))
                }
            })
            .collect();
        (packed, [m[0], m[1], 0.0, m[3], m[4], 0.0, 0.0, 0.0, 0.0])
    }

    #[test]
    fn dispatched_and_portable_scores_agree_with_a_plain_sum() {
        for (n, seed) in [(0, 1), (5, 2), (131, 3), (1000, 4)] {
            let (packed, m) = problem(n, seed);
            let t = 1e-3f32;
            let dispatched = truncated_sampson(&packed, &m, t, f64::INFINITY);
            let portable = truncated_sampson_portable(&packed, &m, t, f64::INFINITY);
            assert_eq!(dispatched, portable);
            let (mut plain, mut count) = (0.0f64, 0usize);
            for p in &packed {
                let r = Epipolar::new(&m, p[0], p[1], p[2], p[3]).ratio();
                if r < t {
                    plain += f64::from(r);
                    count += 1;
                } else {
                    plain += f64::from(t);
                }
            }
            assert_eq!(dispatched.1, count);
            assert!((dispatched.0 - plain).abs() <= 1e-5 * plain.max(1.0));
            if n == 1000 {
                assert!(count > 100 && count < 900, "a mix of inliers and outliers");
                let stopped = truncated_sampson(&packed, &m, t, 0.25 * plain);
                assert_eq!(stopped.0, f64::INFINITY);
                assert!(stopped.1 < count);
            }
        }
    }
}
