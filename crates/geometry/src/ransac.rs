//! LO-MSAC: RANSAC with truncated-quadratic scoring and local optimisation.
//!
//! For `k` iterations a minimal sample (drawn with a seeded [`StdRng`]) gives hypotheses from
//! [`Estimator::fit_minimal`]; each is scored by MSAC, `C = sum_i min(r_i^2, t^2)` (lower is
//! better). A new best hypothesis is refined by local optimisation: refit on its inliers with
//! [`Estimator::fit_nonminimal`] and rescore, repeated while the score improves. The iteration
//! count adapts to the best inlier ratio `w`: `k = log(1 - p) / log(1 - w^s)` for confidence
//! `p` and sample size `s`.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// A model family estimated from correspondences, with squared residuals in the units of the
/// threshold.
pub trait Estimator {
    /// The estimated model.
    type Model: Clone;
    /// Size of a minimal sample.
    fn sample_size(&self) -> usize;
    /// Number of data points.
    fn len(&self) -> usize;
    /// True when there is no data.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Appends the models consistent with the minimal sample (indices) to `out` (cleared).
    fn fit_minimal(&self, sample: &[usize], out: &mut Vec<Self::Model>);
    /// Appends models fitted to a larger set (least squares); used by local optimisation.
    fn fit_nonminimal(&self, indices: &[usize], out: &mut Vec<Self::Model>);
    /// Squared residual of data point `i` under `model`.
    fn residual_sq(&self, model: &Self::Model, i: usize) -> f64;
    /// MSAC score `sum_i min(r_i^2, t^2)` and inlier count; may stop early and return
    /// `f64::INFINITY` once the partial score exceeds `bound`.
    fn score(&self, model: &Self::Model, threshold_sq: f64, bound: f64) -> (f64, usize) {
        let mut cost = 0.0;
        let mut inliers = 0;
        for i in 0..self.len() {
            let r = self.residual_sq(model, i);
            if r < threshold_sq {
                cost += r;
                inliers += 1;
            } else {
                cost += threshold_sq;
            }
            if cost > bound {
                return (f64::INFINITY, inliers);
            }
        }
        (cost, inliers)
    }
}

/// Settings of [`ransac`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RansacConfig {
    /// Inlier threshold on the residual (not squared), in the estimator's units.
    pub threshold: f64,
    /// Probability of drawing at least one all-inlier sample.
    pub confidence: f64,
    /// Upper bound on iterations.
    pub max_iterations: usize,
    /// Lower bound on iterations.
    pub min_iterations: usize,
    /// Seed of the sampler.
    pub seed: u64,
    /// Rounds of local optimisation per new best model (0 disables LO).
    pub lo_rounds: usize,
}

impl Default for RansacConfig {
    fn default() -> Self {
        Self {
            threshold: 1.0,
            confidence: 0.999,
            max_iterations: 10_000,
            min_iterations: 10,
            seed: 0,
            lo_rounds: 3,
        }
    }
}

/// Best model and its support.
#[derive(Debug, Clone)]
pub struct RansacResult<M> {
    /// The best model.
    pub model: M,
    /// `residual^2 < threshold^2` per data point.
    pub inliers: Vec<bool>,
    /// Number of inliers.
    pub inlier_count: usize,
    /// MSAC score of the model.
    pub score: f64,
    /// Iterations run.
    pub iterations: usize,
}

/// Iterations needed for confidence `p` with inlier ratio `w` and sample size `s`.
pub fn required_iterations(p: f64, w: f64, s: usize) -> usize {
    let ws = w.powi(s as i32);
    if ws >= 1.0 {
        return 1;
    }
    if ws <= 0.0 {
        return usize::MAX;
    }
    let k = (1.0 - p).ln() / (1.0 - ws).ln();
    if k.is_finite() {
        k.ceil().max(1.0) as usize
    } else {
        usize::MAX
    }
}

/// Draws `k` distinct indices in `0..n` into `out` (partial Fisher-Yates over `pool`).
fn draw_sample(rng: &mut StdRng, pool: &mut [usize], k: usize, out: &mut Vec<usize>) {
    out.clear();
    let n = pool.len();
    for j in 0..k {
        let i = rng.random_range(j..n);
        pool.swap(j, i);
        out.push(pool[j]);
    }
}

/// Indices with `residual^2 < threshold_sq`.
fn inlier_indices<E: Estimator>(
    est: &E,
    model: &E::Model,
    threshold_sq: f64,
    out: &mut Vec<usize>,
) {
    out.clear();
    out.extend((0..est.len()).filter(|&i| est.residual_sq(model, i) < threshold_sq));
}

/// Runs LO-MSAC; `None` when there are fewer points than a minimal sample or no hypothesis.
///
/// ```
/// use vofront_geometry::ransac::{ransac, Estimator, RansacConfig};
/// /// 1-D location model: residual `x_i - m`.
/// struct Mean(Vec<f64>);
/// impl Estimator for Mean {
///     type Model = f64;
///     fn sample_size(&self) -> usize { 1 }
///     fn len(&self) -> usize { self.0.len() }
///     fn fit_minimal(&self, s: &[usize], out: &mut Vec<f64>) { out.clear(); out.push(self.0[s[0]]); }
///     fn fit_nonminimal(&self, s: &[usize], out: &mut Vec<f64>) {
///         out.clear();
///         out.push(s.iter().map(|&i| self.0[i]).sum::<f64>() / s.len() as f64);
///     }
///     fn residual_sq(&self, m: &f64, i: usize) -> f64 { (self.0[i] - m).powi(2) }
/// }
/// let data = Mean(vec![1.0, 1.1, 0.9, 1.05, 50.0, -30.0]);
/// let res = ransac(&data, &RansacConfig { threshold: 0.5, ..Default::default() }).unwrap();
/// assert_eq!(res.inlier_count, 4);
/// assert!((res.model - 1.0125).abs() < 1e-9);
/// ```
pub fn ransac<E: Estimator>(est: &E, cfg: &RansacConfig) -> Option<RansacResult<E::Model>> {
    let n = est.len();
    let s = est.sample_size();
    if n < s || s == 0 {
        return None;
    }
    let threshold_sq = cfg.threshold * cfg.threshold;
    let mut rng = StdRng::seed_from_u64(cfg.seed);
    let mut pool: Vec<usize> = (0..n).collect();
    let mut sample = Vec::with_capacity(s);
    let mut models = Vec::new();
    let mut lo_models = Vec::new();
    let mut lo_inliers = Vec::new();
    let mut best: Option<(E::Model, f64, usize)> = None;
    let mut needed = cfg.max_iterations;
    let mut iterations = 0;
    while iterations < needed.max(cfg.min_iterations).min(cfg.max_iterations) {
        iterations += 1;
        draw_sample(&mut rng, &mut pool, s, &mut sample);
        est.fit_minimal(&sample, &mut models);
        for m in models.drain(..) {
            let bound = best.as_ref().map_or(f64::INFINITY, |b| b.1);
            let (score, count) = est.score(&m, threshold_sq, bound);
            if score >= bound {
                continue;
            }
            let mut current = (m, score, count);
            // Local optimisation: refit on the inliers while the score improves.
            for _ in 0..cfg.lo_rounds {
                inlier_indices(est, &current.0, threshold_sq, &mut lo_inliers);
                if lo_inliers.len() <= s {
                    break;
                }
                est.fit_nonminimal(&lo_inliers, &mut lo_models);
                let mut improved = false;
                for lm in lo_models.drain(..) {
                    let (sc, c) = est.score(&lm, threshold_sq, current.1);
                    if sc < current.1 {
                        current = (lm, sc, c);
                        improved = true;
                    }
                }
                if !improved {
                    break;
                }
            }
            needed = required_iterations(cfg.confidence, current.2 as f64 / n as f64, s);
            best = Some(current);
        }
    }
    let (model, score, _) = best?;
    let inliers: Vec<bool> = (0..n)
        .map(|i| est.residual_sq(&model, i) < threshold_sq)
        .collect();
    let inlier_count = inliers.iter().filter(|&&b| b).count();
    Some(RansacResult {
        model,
        inliers,
        inlier_count,
        score,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Line `y = a x + b` through two points; residual is the vertical distance.
    struct Line(Vec<(f64, f64)>);

    impl Estimator for Line {
        type Model = (f64, f64);
        fn sample_size(&self) -> usize {
            2
        }
        fn len(&self) -> usize {
            self.0.len()
        }
        fn fit_minimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
            out.clear();
            let ((x0, y0), (x1, y1)) = (self.0[s[0]], self.0[s[1]]);
            if (x1 - x0).abs() > 1e-12 {
                let a = (y1 - y0) / (x1 - x0);
                out.push((a, y0 - a * x0));
            }
        }
        fn fit_nonminimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
            out.clear();
            let n = s.len() as f64;
            let (mx, my) = s
                .iter()
                .fold((0.0, 0.0), |(a, b), &i| (a + self.0[i].0, b + self.0[i].1));
            let (mx, my) = (mx / n, my / n);
            let sxy: f64 = s
                .iter()
                .map(|&i| (self.0[i].0 - mx) * (self.0[i].1 - my))
                .sum();
            let sxx: f64 = s.iter().map(|&i| (self.0[i].0 - mx).powi(2)).sum();
            let a = sxy / sxx;
            out.push((a, my - a * mx));
        }
        fn residual_sq(&self, m: &(f64, f64), i: usize) -> f64 {
            let (x, y) = self.0[i];
            (m.0 * x + m.1 - y).powi(2)
        }
    }

    fn data() -> Line {
        // 60 points on y = 2x + 1 with +-0.05 deterministic noise, 60 gross outliers.
        let mut pts = Vec::new();
        for i in 0..120 {
            let x = i as f64 * 0.1;
            let noise = 0.05 * ((i * 7919 % 13) as f64 / 6.0 - 1.0);
            let y = if i % 2 == 0 {
                2.0 * x + 1.0 + noise
            } else {
                ((i * 104_729) % 97) as f64 - 40.0
            };
            pts.push((x, y));
        }
        Line(pts)
    }

    #[test]
    fn adaptive_iteration_count_matches_the_formula() {
        // log(1 - 0.99) / log(1 - 0.5^2) = 16.0078...
        assert_eq!(required_iterations(0.99, 0.5, 2), 17);
        assert_eq!(required_iterations(0.99, 1.0, 2), 1);
        assert_eq!(required_iterations(0.99, 0.0, 2), usize::MAX);
    }

    #[test]
    fn finds_the_line_among_half_outliers_reproducibly() {
        let d = data();
        let cfg = RansacConfig {
            threshold: 0.1,
            ..Default::default()
        };
        let a = ransac(&d, &cfg).expect("a model");
        assert!((a.model.0 - 2.0).abs() < 0.01 && (a.model.1 - 1.0).abs() < 0.05);
        assert!(a.inlier_count >= 60 && a.inlier_count <= 62);
        // Stops long before the cap once the inlier ratio is known.
        assert!(a.iterations < 100);
        let b = ransac(&d, &cfg).expect("a model");
        assert_eq!((a.model, a.iterations), (b.model, b.iterations));
    }

    #[test]
    fn too_few_points_give_none() {
        let d = Line(vec![(0.0, 0.0)]);
        assert!(ransac(&d, &RansacConfig::default()).is_none());
    }
}
