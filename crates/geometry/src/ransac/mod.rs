//! LO-MSAC: RANSAC with truncated-quadratic scoring and local optimisation.
//!
//! For `k` iterations a minimal sample (drawn with a seeded [`StdRng`]) gives hypotheses from
//! [`Estimator::fit_minimal`]; each is scored by MSAC, `C = sum_i min(r_i^2, t^2)` (lower is
//! better), so that a model with many marginal inliers (`r` close to `t`) loses to one whose
//! inliers fit tightly. Every hypothesis that beats the best *minimal-sample* score so far is
//! refined by local optimisation ([`Estimator::refine`] on its inliers and rescore, repeated
//! while the score improves) and competes with the best refined model. Comparing raw
//! hypotheses with raw ones matters: a wrong model polished early would otherwise set a bar
//! that noisy minimal models of the true one never clear, so they would never be polished.
//! With [`RansacConfig::lo_skip_shared`] below 1, a hypothesis that scores no better than the
//! best refined model, has no more inliers and shares nearly all of them with it is not
//! polished, on the premise that local optimisation, starting from nearly the same inliers,
//! would find that model again. The premise fails when two distinct models share most
//! inliers (in forward motion the distant points lie near the epipolar lines of a wrong
//! motion too): the better model is then never polished. No default turns it on.
//! [`RansacConfig::lo_max_inliers`] bounds the cost of each polish instead: the refit uses at
//! most that many of the hypothesis's inliers, evenly spread, and its models are scored on all
//! the data.
//!
//! Stopping: the iteration count adapts to the inlier ratio `w` of the best *confirmed* model,
//! `k = log(1 - p) / log(1 - w^s)` for confidence `p` and sample size `s`. A model is confirmed
//! when local optimisation refitted it on its own inliers without losing score; a lucky minimal
//! model that local optimisation cannot reproduce (typically a near-degenerate one with many
//! marginal inliers) may stay the best, but never shortens the search. At least
//! `min_iterations` samples are drawn whatever the ratio says, so that one early, wrong but
//! well-supported model cannot end the search before the true one had a chance to be sampled.

use std::collections::VecDeque;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::error::GeometryError;

mod local;
#[cfg(test)]
mod tests;

use local::{LocalOptimisation, Polished, Scored};

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
    /// Local optimisation of `model` on its inliers `indices`: appends refitted models to
    /// `out` (cleared). Defaults to [`Self::fit_nonminimal`], which ignores the start; an
    /// estimator without a closed-form refit can iterate from `model` instead. Leaving `out`
    /// empty means the model cannot be confirmed (see the module documentation).
    fn refine(&self, _model: &Self::Model, indices: &[usize], out: &mut Vec<Self::Model>) {
        self.fit_nonminimal(indices, out);
    }
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

/// Settings of [`ransac`], embedded as the `ransac` field of every configuration whose
/// estimator runs it ([`crate::RelativePoseConfig`], [`crate::PnpConfig`]; there the threshold
/// is in pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RansacConfig {
    /// Inlier threshold on the residual (not squared), in the estimator's units.
    pub threshold: f64,
    /// Probability of drawing at least one all-inlier sample.
    pub confidence: f64,
    /// Upper bound on iterations.
    pub max_iterations: usize,
    /// Lower bound on iterations, whatever the inlier ratio of the best model.
    pub min_iterations: usize,
    /// Seed of the sampler.
    pub seed: u64,
    /// Rounds of local optimisation per new best model (0 disables LO, and then every best
    /// model counts as confirmed for the stopping rule).
    pub lo_rounds: usize,
    /// Local optimisation skips a hypothesis whose score is no lower than the best refined
    /// model's, with no more inliers than it, at least this share of them being that model's
    /// inliers (see the module documentation: faster, but it can miss a better model that
    /// shares most inliers); above 1 (the default) nothing is skipped.
    pub lo_skip_shared: f64,
    /// Local optimisation refits on at most this many of a hypothesis's inliers, evenly
    /// spread over their list; the refitted models are still scored on every data point.
    /// Local optimisation only has to reach the basin of the best model (the caller's final
    /// refinement uses every inlier), and a refit's cost grows with its inliers: bounding them
    /// bounds the cost of each polish. `usize::MAX` (the default) refits on all of them.
    pub lo_max_inliers: usize,
}

impl RansacConfig {
    /// [`GeometryError::InvalidConfig`] unless `threshold > 0` and `confidence` is in
    /// `(0, 1)`.
    pub fn validate(&self) -> Result<(), GeometryError> {
        if self.threshold > 0.0 && self.confidence > 0.0 && self.confidence < 1.0 {
            Ok(())
        } else {
            Err(GeometryError::InvalidConfig(
                "RANSAC threshold must be > 0 and confidence in (0, 1)",
            ))
        }
    }

    /// The same settings with the threshold converted from pixels to normalized coordinates
    /// (`threshold / focal`, focal length in pixels).
    pub fn in_normalized_units(&self, focal: f64) -> Self {
        Self {
            threshold: self.threshold / focal,
            ..*self
        }
    }
}

impl Default for RansacConfig {
    fn default() -> Self {
        Self {
            threshold: 1.0,
            confidence: 0.999,
            max_iterations: 10_000,
            min_iterations: 100,
            seed: 0,
            lo_rounds: 3,
            lo_skip_shared: f64::INFINITY,
            lo_max_inliers: usize::MAX,
        }
    }
}

/// Best model and its support (`Serialize` when the model is).
#[derive(Debug, Clone, serde::Serialize)]
pub struct RansacResult<M> {
    /// The best model.
    pub model: M,
    /// `residual^2 < threshold^2` per data point.
    pub inliers: Vec<bool>,
    /// MSAC score of the model.
    pub score: f64,
    /// Iterations run.
    pub iterations: usize,
}

impl<M> RansacResult<M> {
    /// Number of `true` in [`Self::inliers`].
    pub fn inlier_count(&self) -> usize {
        self.inliers.iter().filter(|&&b| b).count()
    }
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

/// Minimal samples drawn and fitted at once, the fits in parallel, then scored one by one in
/// the order drawn: the search is the one that fits one sample at a time, with the fitting
/// spread over the threads (samples fitted beyond where the search stops are discarded).
const FIT_BATCH: usize = 16;

/// Draws `count` minimal samples in order and fits each ([`Estimator::fit_minimal`], in
/// parallel); their model lists in the order drawn.
fn fit_batch<E: Estimator + Sync>(
    est: &E,
    rng: &mut StdRng,
    pool: &mut [usize],
    count: usize,
) -> VecDeque<Vec<E::Model>>
where
    E::Model: Send,
{
    let s = est.sample_size();
    let samples: Vec<Vec<usize>> = (0..count)
        .map(|_| {
            let mut sample = Vec::with_capacity(s);
            draw_sample(rng, pool, s, &mut sample);
            sample
        })
        .collect();
    samples
        .par_iter()
        .with_min_len(FIT_BATCH / 2)
        .map(|sample| {
            let mut models = Vec::new();
            est.fit_minimal(sample, &mut models);
            models
        })
        .collect::<Vec<_>>()
        .into()
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
/// assert_eq!(res.inlier_count(), 4);
/// assert!((res.model - 1.0125).abs() < 1e-9);
/// ```
pub fn ransac<E: Estimator + Sync>(est: &E, cfg: &RansacConfig) -> Option<RansacResult<E::Model>>
where
    E::Model: Send,
{
    ransac_from(est, cfg, None)
}

/// [`ransac`] with a first hypothesis `guess` (a predicted or previously found model), scored
/// and polished as a minimal-sample model drawn before the first sample: a good guess sets
/// the bar that later minimal models must beat to be polished, so fewer are; a wrong one is
/// beaten like any wrong hypothesis. `min_iterations` samples are still drawn.
pub fn ransac_from<E: Estimator + Sync>(
    est: &E,
    cfg: &RansacConfig,
    guess: Option<E::Model>,
) -> Option<RansacResult<E::Model>>
where
    E::Model: Send,
{
    let n = est.len();
    let s = est.sample_size();
    if n < s || s == 0 {
        return None;
    }
    let threshold_sq = cfg.threshold * cfg.threshold;
    let mut rng = StdRng::seed_from_u64(cfg.seed);
    let mut pool: Vec<usize> = (0..n).collect();
    let mut fitted: VecDeque<Vec<E::Model>> = VecDeque::new();
    let mut models = Vec::new();
    let mut lo = LocalOptimisation {
        inliers: Vec::new(),
        models: Vec::new(),
        max_inliers: cfg.lo_max_inliers,
    };
    let mut best: Option<Scored<E::Model>> = None;
    let mut polished = Polished::default();
    // Best score of a minimal-sample model: local optimisation runs on every minimal model
    // that beats it, so that a polished wrong model cannot keep raw (noisy) hypotheses of
    // the true one from ever being polished.
    let mut best_minimal = f64::INFINITY;
    // Iterations the best confirmed model asks for; the cap until one is confirmed.
    let mut needed = cfg.max_iterations;
    let mut iterations = 0;
    models.extend(guess);
    loop {
        for m in models.drain(..) {
            let (score, count) = est.score(&m, threshold_sq, best_minimal);
            if score >= best_minimal {
                continue;
            }
            best_minimal = score;
            let best_score = best.as_ref().map(|b| b.1);
            if polished.covers(
                est,
                (&m, score),
                best_score,
                threshold_sq,
                cfg.lo_skip_shared,
            ) {
                continue;
            }
            let (current, confirmed) = lo.run(est, (m, score, count), threshold_sq, cfg.lo_rounds);
            if best.as_ref().is_some_and(|b| b.1 <= current.1) {
                continue;
            }
            if confirmed {
                needed = required_iterations(cfg.confidence, current.2 as f64 / n as f64, s);
            }
            if cfg.lo_skip_shared <= 1.0 {
                polished.set(est, &current.0, threshold_sq);
            }
            best = Some(current);
        }
        let limit = needed.max(cfg.min_iterations).min(cfg.max_iterations);
        if iterations >= limit {
            break;
        }
        if fitted.is_empty() {
            let count = (limit - iterations).min(FIT_BATCH);
            fitted = fit_batch(est, &mut rng, &mut pool, count);
        }
        iterations += 1;
        models = fitted.pop_front().unwrap_or_default();
    }
    let (model, score, _) = best?;
    let inliers: Vec<bool> = (0..n)
        .map(|i| est.residual_sq(&model, i) < threshold_sq)
        .collect();
    Some(RansacResult {
        model,
        inliers,
        score,
        iterations,
    })
}
