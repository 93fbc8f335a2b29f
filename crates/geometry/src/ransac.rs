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
//! polished: local optimisation starts from the inliers, so it would find that model again.
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
    /// inliers (see the module documentation); above 1 (the default) nothing is skipped.
    pub lo_skip_shared: f64,
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

/// A scored hypothesis: model, MSAC score, inlier count.
type Scored<M> = (M, f64, usize);

/// Relative margin within which a refit's score reproduces the score of the model it started
/// from: a model already at the refit's optimum (a guess that is a previous estimate) comes
/// back with its score changed only by rounding (measured: 2e-10 relative), and is confirmed.
const REPRODUCED: f64 = 1e-6;

/// Scratch buffers of the local optimisation.
struct LocalOptimisation<M> {
    inliers: Vec<usize>,
    models: Vec<M>,
}

/// The inliers of the best refined model, to tell when polishing a hypothesis would only find
/// it again ([`RansacConfig::lo_skip_shared`]).
struct Polished {
    mask: Vec<bool>,
    count: usize,
    score: f64,
    /// Scratch: a hypothesis's inliers.
    candidate: Vec<usize>,
}

impl Polished {
    /// Remembers `model` (scored `score`) as the best refined one.
    fn set<E: Estimator>(&mut self, est: &E, model: &E::Model, score: f64, threshold_sq: f64) {
        inlier_indices(est, model, threshold_sq, &mut self.candidate);
        self.mask.clear();
        self.mask.resize(est.len(), false);
        for &i in &self.candidate {
            self.mask[i] = true;
        }
        self.count = self.candidate.len();
        self.score = score;
    }

    /// Whether polishing `model` (scored `score`) would only find the best refined model again:
    /// it scores no lower, has no more inliers and at least `shared` of them are that model's.
    fn covers<E: Estimator>(
        &mut self,
        est: &E,
        model: &E::Model,
        score: f64,
        threshold_sq: f64,
        shared: f64,
    ) -> bool {
        if shared > 1.0 || self.mask.is_empty() || score < self.score {
            return false;
        }
        inlier_indices(est, model, threshold_sq, &mut self.candidate);
        let common = self.candidate.iter().filter(|&&i| self.mask[i]).count();
        self.candidate.len() <= self.count && common as f64 >= shared * self.candidate.len() as f64
    }
}

impl<M> LocalOptimisation<M> {
    /// Refines `current` for up to `rounds` rounds (refit on the inliers, keep a lower score);
    /// returns the result and whether it is confirmed: some refit on its inliers scored no
    /// worse than the model it started from (within [`REPRODUCED`]).
    fn run<E: Estimator<Model = M>>(
        &mut self,
        est: &E,
        mut current: Scored<M>,
        threshold_sq: f64,
        rounds: usize,
    ) -> (Scored<M>, bool) {
        if rounds == 0 {
            return (current, true);
        }
        let mut confirmed = false;
        for _ in 0..rounds {
            inlier_indices(est, &current.0, threshold_sq, &mut self.inliers);
            if self.inliers.len() <= est.sample_size() {
                break;
            }
            est.refine(&current.0, &self.inliers, &mut self.models);
            let mut improved = false;
            let reproduced = current.1 * (1.0 + REPRODUCED);
            for m in self.models.drain(..) {
                let (score, count) = est.score(&m, threshold_sq, reproduced);
                if score <= reproduced {
                    confirmed = true;
                    if score < current.1 {
                        current = (m, score, count);
                        improved = true;
                    }
                }
            }
            if !improved {
                break;
            }
        }
        (current, confirmed)
    }
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
    };
    let mut best: Option<Scored<E::Model>> = None;
    let mut polished = Polished {
        mask: Vec::new(),
        count: 0,
        score: f64::INFINITY,
        candidate: Vec::new(),
    };
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
            if polished.covers(est, &m, score, threshold_sq, cfg.lo_skip_shared) {
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
                polished.set(est, &current.0, current.1, threshold_sq);
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
        assert!(a.inlier_count() >= 60 && a.inlier_count() <= 62);
        // The ratio asks for ~30 samples: the search stops at the minimum, far below the cap.
        assert_eq!(a.iterations, cfg.min_iterations);
        let b = ransac(&d, &cfg).expect("a model");
        assert_eq!((a.model, a.iterations), (b.model, b.iterations));
    }

    /// The line data with a local optimisation that never reproduces a model.
    struct Unconfirmable(Line);

    impl Estimator for Unconfirmable {
        type Model = (f64, f64);
        fn sample_size(&self) -> usize {
            2
        }
        fn len(&self) -> usize {
            self.0.len()
        }
        fn fit_minimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
            self.0.fit_minimal(s, out);
        }
        fn fit_nonminimal(&self, _s: &[usize], out: &mut Vec<(f64, f64)>) {
            out.clear();
        }
        fn residual_sq(&self, m: &(f64, f64), i: usize) -> f64 {
            self.0.residual_sq(m, i)
        }
    }

    #[test]
    fn an_unconfirmed_model_never_shortens_the_search() {
        let cfg = RansacConfig {
            threshold: 0.1,
            max_iterations: 700,
            ..Default::default()
        };
        let res = ransac(&Unconfirmable(data()), &cfg).expect("a model");
        // Still the right line (the best minimal model), but found without confirmation, so
        // the search ran to the cap.
        assert!((res.model.0 - 2.0).abs() < 0.05);
        assert_eq!(res.iterations, cfg.max_iterations);
        // With local optimisation disabled every model counts as confirmed.
        let no_lo = RansacConfig {
            lo_rounds: 0,
            ..cfg
        };
        let res = ransac(&Unconfirmable(data()), &no_lo).expect("a model");
        assert_eq!(res.iterations, cfg.min_iterations);
    }

    #[test]
    fn a_guess_is_polished_first_and_a_wrong_one_is_beaten() {
        let d = data();
        let cfg = RansacConfig {
            threshold: 0.1,
            ..Default::default()
        };
        // With no sample drawn, a guess near the line comes back refitted on its inliers.
        let none_drawn = RansacConfig {
            min_iterations: 0,
            max_iterations: 0,
            ..cfg
        };
        let guess = (2.02, 0.95);
        let polished = ransac_from(&d, &none_drawn, Some(guess)).expect("the guess");
        assert_eq!(polished.iterations, 0);
        assert_ne!(polished.model, guess);
        assert!((polished.model.0 - 2.0).abs() < 0.01 && (polished.model.1 - 1.0).abs() < 0.05);
        assert!(polished.inlier_count() >= 60);
        assert!(ransac(&d, &none_drawn).is_none());
        // A wrong guess loses to the sampled line.
        let beaten = ransac_from(&d, &cfg, Some((-1.0, 30.0))).expect("a model");
        let plain = ransac(&d, &cfg).expect("a model");
        assert!((beaten.model.0 - 2.0).abs() < 0.01 && (beaten.model.1 - 1.0).abs() < 0.05);
        assert_eq!(beaten.inlier_count(), plain.inlier_count());
        assert_eq!(beaten.iterations, cfg.min_iterations);
    }

    #[test]
    fn the_minimum_holds_even_when_every_point_is_an_inlier() {
        let exact = Line((0..50).map(|i| (i as f64, 3.0 * i as f64 - 2.0)).collect());
        for min_iterations in [1, 37, 250] {
            let cfg = RansacConfig {
                threshold: 0.01,
                min_iterations,
                ..Default::default()
            };
            let res = ransac(&exact, &cfg).expect("a model");
            assert_eq!(res.iterations, min_iterations);
            assert_eq!(res.inlier_count(), 50);
        }
    }

    #[test]
    fn too_few_points_give_none() {
        let d = Line(vec![(0.0, 0.0)]);
        assert!(ransac(&d, &RansacConfig::default()).is_none());
    }

    #[test]
    fn a_run_capped_at_its_least_budget_is_the_start_of_a_longer_one() {
        // The two-view selection relies on this: the homography's least budget runs first,
        // and a larger budget re-runs it from the same seed.
        let est = data();
        let at = |max_iterations| {
            ransac(
                &est,
                &RansacConfig {
                    threshold: 0.2,
                    min_iterations: 30,
                    max_iterations,
                    ..Default::default()
                },
            )
            .expect("a model")
        };
        let (capped, longer) = (at(30), at(10_000));
        assert_eq!(capped.iterations, 30);
        assert_eq!(
            longer.iterations, 30,
            "the inlier ratio asks for fewer than 30"
        );
        assert_eq!((capped.model, capped.score), (longer.model, longer.score));
        assert_eq!(capped.inliers, longer.inliers);
    }

    /// [`Line`] counting its local optimisations.
    struct Counting(Line, std::sync::atomic::AtomicUsize);

    impl Estimator for Counting {
        type Model = (f64, f64);
        fn sample_size(&self) -> usize {
            self.0.sample_size()
        }
        fn len(&self) -> usize {
            self.0.len()
        }
        fn fit_minimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
            self.0.fit_minimal(s, out);
        }
        fn fit_nonminimal(&self, s: &[usize], out: &mut Vec<(f64, f64)>) {
            self.1.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            self.0.fit_nonminimal(s, out);
        }
        fn residual_sq(&self, m: &(f64, f64), i: usize) -> f64 {
            self.0.residual_sq(m, i)
        }
    }

    #[test]
    fn hypotheses_that_share_the_polished_inliers_are_not_polished_again() {
        let est = Counting(data(), std::sync::atomic::AtomicUsize::new(0));
        let run = |lo_skip_shared| {
            est.1.store(0, std::sync::atomic::Ordering::Relaxed);
            let cfg = RansacConfig {
                threshold: 0.1,
                lo_skip_shared,
                ..Default::default()
            };
            let result = ransac(&est, &cfg).expect("a model");
            (result, est.1.load(std::sync::atomic::Ordering::Relaxed))
        };
        let (every, refits_every) = run(f64::INFINITY);
        let (skipping, refits_skipping) = run(0.9);
        assert!(
            refits_skipping < refits_every,
            "{refits_skipping} refits against {refits_every}"
        );
        assert_eq!(skipping.inliers, every.inliers);
        assert!((skipping.model.0 - every.model.0).abs() < 1e-9);
        assert!((skipping.model.1 - every.model.1).abs() < 1e-9);
        // A share above 1 can never be met: nothing is skipped.
        assert_eq!(run(1.0 + 1e-9).1, refits_every);
    }
}
