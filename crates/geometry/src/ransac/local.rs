//! Local optimisation of LO-MSAC: polishing a hypothesis on its inliers
//! ([`LocalOptimisation`]), and telling when polishing would only find the best refined model
//! again ([`Polished`], [`super::RansacConfig::lo_skip_shared`]).

use super::Estimator;

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
pub(super) type Scored<M> = (M, f64, usize);

/// Relative margin within which a refit's score reproduces the score of the model it started
/// from: a model already at the refit's optimum (a guess that is a previous estimate) comes
/// back with its score changed only by rounding (measured: 2e-10 relative), and is confirmed.
const REPRODUCED: f64 = 1e-6;

/// Scratch buffers of the local optimisation.
pub(super) struct LocalOptimisation<M> {
    pub inliers: Vec<usize>,
    pub models: Vec<M>,
    /// Most inliers a refit uses ([`super::RansacConfig::lo_max_inliers`]).
    pub max_inliers: usize,
}

/// Keeps at most `max` (at least 1) of `indices`, evenly spread over the list: entry
/// `floor(k n / max)` for `k = 0..max`, so that a list ordered by position or by pyramid
/// level keeps its proportions.
pub(super) fn thin_evenly(indices: &mut Vec<usize>, max: usize) {
    let (n, max) = (indices.len(), max.max(1));
    if n <= max {
        return;
    }
    // `k n / max >= k`: each entry is read before it is overwritten.
    for k in 0..max {
        indices[k] = indices[k * n / max];
    }
    indices.truncate(max);
}

/// The inliers of the best refined model, to tell when polishing a hypothesis would only find
/// it again ([`super::RansacConfig::lo_skip_shared`]).
#[derive(Default)]
pub(super) struct Polished {
    /// Whether each data point is an inlier of the best refined model (empty before one).
    mask: Vec<bool>,
    /// Number of `true` in `mask`.
    count: usize,
    /// Scratch: a hypothesis's inliers.
    candidate: Vec<usize>,
}

impl Polished {
    /// Remembers the inliers of `model`, the best refined one.
    pub fn set<E: Estimator>(&mut self, est: &E, model: &E::Model, threshold_sq: f64) {
        inlier_indices(est, model, threshold_sq, &mut self.candidate);
        self.mask.clear();
        self.mask.resize(est.len(), false);
        for &i in &self.candidate {
            self.mask[i] = true;
        }
        self.count = self.candidate.len();
    }

    /// Whether polishing `model` (scored `score`) would only find the best refined model
    /// (scored `best`) again: it scores no lower, has no more inliers and at least `shared` of
    /// them are that model's.
    pub fn covers<E: Estimator>(
        &mut self,
        est: &E,
        (model, score): (&E::Model, f64),
        best: Option<f64>,
        threshold_sq: f64,
        shared: f64,
    ) -> bool {
        if shared > 1.0 || self.mask.is_empty() || best.is_none_or(|b| score < b) {
            return false;
        }
        inlier_indices(est, model, threshold_sq, &mut self.candidate);
        let common = self.candidate.iter().filter(|&&i| self.mask[i]).count();
        self.candidate.len() <= self.count && common as f64 >= shared * self.candidate.len() as f64
    }
}

impl<M> LocalOptimisation<M> {
    /// Refines `current` for up to `rounds` rounds (refit on the inliers, at most
    /// `max_inliers` of them, evenly spread; keep a lower score);
    /// returns the result and whether it is confirmed: some refit on its inliers scored no
    /// worse than the model it started from (within [`REPRODUCED`]).
    pub fn run<E: Estimator<Model = M>>(
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
            thin_evenly(&mut self.inliers, self.max_inliers);
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
