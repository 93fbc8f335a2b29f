//! The quality record every vofront estimate carries: a [`Verdict`], the [`Reason`]s for it,
//! the support, the residual scale, convergence and the covariance with one-number summaries.
//!
//! Each estimator family fills a [`Quality`] with [`Quality::judge`] from its [`Support`], its
//! own flags and the [`QualityConfig`] minimums; the chance test is
//! [`log10_nfa`], an a-contrario bound: the expected number of models, among all the
//! estimator tried, that random data would support as well as the observed consensus.

use std::fmt;

use serde::Serialize;

/// How far an estimate can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Enough support, clearly better than chance, well conditioned: use it.
    Ok,
    /// An estimate exists but part of it is poorly determined or weakly supported (e.g. the
    /// translation direction at low parallax): use with its covariance, or not at all.
    Unreliable,
    /// The numbers do not describe the scene (no consensus, random-level support, degenerate).
    Failed,
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Verdict::Ok => "ok",
            Verdict::Unreliable => "unreliable",
            Verdict::Failed => "failed",
        })
    }
}

/// Why an estimate is not [`Verdict::Ok`]; the JSON spelling is the snake_case name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reason {
    /// Fewer inliers than [`QualityConfig::min_inliers`] (failed).
    TooFewInliers,
    /// Inliers over candidates below [`QualityConfig::min_inlier_ratio`] (unreliable).
    LowInlierRatio,
    /// The consensus is within what random correspondences reach at the same threshold:
    /// `log10 NFA > QualityConfig::max_log10_nfa` (failed).
    NotBetterThanChance,
    /// The translation direction is undetermined at the stated uncertainty: its predicted
    /// standard deviation exceeds [`QualityConfig::max_direction_sigma_deg`] (the rays of the
    /// two views are too nearly parallel for the noise), or no translation is seen at all
    /// (unreliable).
    LowParallax,
    /// A rotation alone explains the data: the translation is reported as zero (unreliable).
    PureRotation,
    /// Two motions explain the data about equally, e.g. the twins of a plane (unreliable).
    PlanarAmbiguous,
    /// The iterative refinement stopped before its convergence test held (unreliable).
    NotConverged,
    /// The fitted brightness gain is outside the plausible range (failed).
    ImplausibleGain,
    /// Fewer usable pixels than [`QualityConfig::min_pixels`] (failed).
    TooFewPixels,
    /// The problem is degenerate: singular normal equations, collapsed geometry (failed).
    Degenerate,
    /// A photometric fit leaves a residual far above what aligned images leave: the motion
    /// model (e.g. a 2D shift for a 3D motion) explains the pair only in part (unreliable).
    HighResidual,
    /// The predicted rotation standard deviation exceeds
    /// [`QualityConfig::max_rotation_sigma_deg`] (unreliable).
    LargeUncertainty,
    /// Another estimate of the same motion from the same images, made with another model or
    /// by the same estimator from another start, disagrees with this one far beyond their
    /// stated uncertainties (unreliable): one of the two is wrong, and the data alone do not
    /// say which.
    Inconsistent,
}

impl Reason {
    /// The verdict this reason alone forces.
    pub fn severity(self) -> Verdict {
        match self {
            Reason::TooFewInliers
            | Reason::NotBetterThanChance
            | Reason::ImplausibleGain
            | Reason::TooFewPixels
            | Reason::Degenerate => Verdict::Failed,
            Reason::LowInlierRatio
            | Reason::LowParallax
            | Reason::PureRotation
            | Reason::PlanarAmbiguous
            | Reason::NotConverged
            | Reason::HighResidual
            | Reason::LargeUncertainty
            | Reason::Inconsistent => Verdict::Unreliable,
        }
    }

    /// The public (JSON) name.
    pub fn name(self) -> &'static str {
        match self {
            Reason::TooFewInliers => "too_few_inliers",
            Reason::LowInlierRatio => "low_inlier_ratio",
            Reason::NotBetterThanChance => "not_better_than_chance",
            Reason::LowParallax => "low_parallax",
            Reason::PureRotation => "pure_rotation",
            Reason::PlanarAmbiguous => "planar_ambiguous",
            Reason::NotConverged => "not_converged",
            Reason::ImplausibleGain => "implausible_gain",
            Reason::TooFewPixels => "too_few_pixels",
            Reason::Degenerate => "degenerate",
            Reason::HighResidual => "high_residual",
            Reason::LargeUncertainty => "large_uncertainty",
            Reason::Inconsistent => "inconsistent",
        }
    }
}

impl fmt::Display for Reason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Minimum support of an `ok` estimate. The defaults are the documented public thresholds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QualityConfig {
    /// Fewest inliers of an `ok` feature estimate (15: well above the 5- or 6-point minimal
    /// sample, so the refinement is overdetermined three times over).
    pub min_inliers: usize,
    /// Smallest inlier ratio (inliers / candidates) of an `ok` feature estimate (0.25).
    pub min_inlier_ratio: f64,
    /// Largest `log10 NFA` of an `ok` consensus (-4: random data would reach it in fewer than
    /// one of ten thousand such estimations; the margin covers the local optimisation, which
    /// searches beyond the hypotheses counted).
    pub max_log10_nfa: f64,
    /// Fewest valid pixels of an `ok` direct estimate (1000).
    pub min_pixels: usize,
    /// Largest predicted rotation standard deviation of an `ok` estimate, degrees (2).
    pub max_rotation_sigma_deg: f64,
    /// Largest predicted translation-direction standard deviation (`sqrt(trace)` of its 2x2
    /// covariance) of an `ok` two-view estimate, degrees (5). At 5 degrees RMS (3.5 per axis)
    /// a direction is 20 degrees off with probability `exp(-16)`, if its covariance is right:
    /// above it the direction is flagged [`Reason::LowParallax`].
    pub max_direction_sigma_deg: f64,
}

impl Default for QualityConfig {
    fn default() -> Self {
        Self {
            min_inliers: 15,
            min_inlier_ratio: 0.25,
            max_log10_nfa: -4.0,
            min_pixels: 1000,
            max_rotation_sigma_deg: 2.0,
            max_direction_sigma_deg: 5.0,
        }
    }
}

/// What an estimate rests on.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Support {
    /// Correspondences (or pixels) consistent with the estimate.
    pub inliers: usize,
    /// Correspondences (or valid pixels) it was estimated from.
    pub candidates: usize,
    /// `inliers / candidates`.
    pub inlier_ratio: f64,
    /// Pixels used by a direct estimate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pixels: Option<usize>,
    /// `log10` of the number of false alarms of the consensus ([`log10_nfa`]); feature
    /// estimates only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub log10_nfa: Option<f64>,
}

impl Support {
    /// Support of `inliers` out of `candidates` correspondences.
    pub fn new(inliers: usize, candidates: usize) -> Self {
        Self {
            inliers,
            candidates,
            inlier_ratio: inliers as f64 / candidates.max(1) as f64,
            pixels: None,
            log10_nfa: None,
        }
    }
}

/// A matrix as rows, the JSON layout of covariances.
pub type MatrixRows = Vec<Vec<f64>>;

/// The uncertainty of an estimate, from its refinement's Gauss-Newton Hessian at the estimated
/// noise (`Sigma = sigma^2 H^-1`), with summaries in the units people read.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct Uncertainty {
    /// Full covariance of the estimator's tangent increment: SE(3) and PnP `(rho, phi)`
    /// (metres, radians; 6x6), a 2D shift (pixels^2; 2x2), a warp's parameters.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub covariance: Option<MatrixRows>,
    /// Two-view: covariance of the left rotation increment `phi` (`R <- exp(phi) R`), rad^2.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rotation_covariance: Option<MatrixRows>,
    /// Two-view: covariance of the unit translation direction in the tangent basis `(b1, b2)`
    /// at `t` (`t <- normalize(t + a b1 + b b2)`), rad^2.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub translation_direction_covariance: Option<MatrixRows>,
    /// `sqrt(trace)` of the rotation covariance: the RMS rotation error, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rotation_sigma_deg: Option<f64>,
    /// `sqrt(trace)` of the translation-direction covariance: RMS angle error, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub translation_direction_sigma_deg: Option<f64>,
    /// `sqrt(trace)` of the metric translation covariance, metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub translation_sigma_m: Option<f64>,
    /// RMS of a 2D shift's error, pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shift_sigma_px: Option<f64>,
}

/// `sqrt(trace)` of a square block given as rows, in `scale` units per covariance unit.
pub fn rms_of(rows: &[Vec<f64>], scale: f64) -> f64 {
    (0..rows.len())
        .map(|i| rows[i][i])
        .sum::<f64>()
        .max(0.0)
        .sqrt()
        * scale
}

/// Rows of the `n x n` block of `m` (a `k x k` matrix in row-major `m(r, c)`) starting at
/// `(start, start)`.
pub fn block_rows(m: impl Fn(usize, usize) -> f64, start: usize, n: usize) -> MatrixRows {
    (0..n)
        .map(|r| (0..n).map(|c| m(start + r, start + c)).collect())
        .collect()
}

/// The quality record of one estimate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Quality {
    /// The overall verdict: the most severe of the reasons' ([`Reason::severity`]), `ok` when
    /// there are none.
    pub verdict: Verdict,
    /// Why the verdict is not `ok` (empty when it is), sorted, without repeats.
    pub reasons: Vec<Reason>,
    /// What the estimate rests on.
    #[serde(flatten)]
    pub support: Support,
    /// Robust residual scale of the final fit (pixels for features and shifts, grey levels for
    /// photometric estimates).
    pub sigma: f64,
    /// Iterations of the refinement (summed over levels for pyramids).
    pub iterations: usize,
    /// The refinement's convergence test held.
    pub converged: bool,
    /// Covariance and its summaries.
    #[serde(flatten)]
    pub uncertainty: Uncertainty,
}

impl Quality {
    /// The record of an estimate with this support and the estimator's own `flags`; adds the
    /// support checks of `cfg` ([`Reason::TooFewInliers`], [`Reason::LowInlierRatio`],
    /// [`Reason::NotBetterThanChance`], [`Reason::TooFewPixels`], [`Reason::NotConverged`],
    /// [`Reason::LargeUncertainty`], [`Reason::LowParallax`] from the direction sigma) and
    /// sets the verdict.
    pub fn judge(
        support: Support,
        sigma: f64,
        iterations: usize,
        converged: bool,
        uncertainty: Uncertainty,
        flags: &[Reason],
        cfg: &QualityConfig,
    ) -> Self {
        let mut reasons = flags.to_vec();
        if support.pixels.is_none() {
            if support.inliers < cfg.min_inliers {
                reasons.push(Reason::TooFewInliers);
            }
            if support.inlier_ratio < cfg.min_inlier_ratio {
                reasons.push(Reason::LowInlierRatio);
            }
        }
        if support.pixels.is_some_and(|p| p < cfg.min_pixels) {
            reasons.push(Reason::TooFewPixels);
        }
        if support
            .log10_nfa
            .is_some_and(|l| l.is_nan() || l > cfg.max_log10_nfa)
        {
            reasons.push(Reason::NotBetterThanChance);
        }
        if !converged {
            reasons.push(Reason::NotConverged);
        }
        if uncertainty
            .rotation_sigma_deg
            .is_some_and(|s| s.is_nan() || s > cfg.max_rotation_sigma_deg)
        {
            reasons.push(Reason::LargeUncertainty);
        }
        if uncertainty
            .translation_direction_sigma_deg
            .is_some_and(|s| s.is_nan() || s > cfg.max_direction_sigma_deg)
        {
            reasons.push(Reason::LowParallax);
        }
        let mut quality = Self {
            verdict: Verdict::Ok,
            reasons,
            support,
            sigma,
            iterations,
            converged,
            uncertainty,
        };
        quality.settle();
        quality
    }

    /// Adds `reason` (found by a check outside the estimator, such as
    /// [`Reason::Inconsistent`]) and sets the verdict again.
    pub fn flag(&mut self, reason: Reason) {
        self.reasons.push(reason);
        self.settle();
    }

    /// Sorts the reasons, drops repeats and sets the verdict from them.
    fn settle(&mut self) {
        self.reasons.sort();
        self.reasons.dedup();
        self.verdict = self
            .reasons
            .iter()
            .map(|r| r.severity())
            .max()
            .unwrap_or(Verdict::Ok);
    }

    /// True when the verdict is [`Verdict::Ok`].
    pub fn is_ok(&self) -> bool {
        self.verdict == Verdict::Ok
    }
}

/// `log10` of the binomial tail `P[Bin(n, p) >= k]`, summed in log space so that tails far
/// below `f64::MIN_POSITIVE` stay exact; `0` (probability 1) for `k = 0`.
pub fn log10_binomial_tail(n: usize, k: usize, p: f64) -> f64 {
    if k == 0 {
        return 0.0;
    }
    if k > n {
        return f64::NEG_INFINITY;
    }
    let p = p.clamp(f64::MIN_POSITIVE, 1.0 - f64::EPSILON);
    let (lp, lq) = (p.ln(), (1.0 - p).ln());
    // ln C(n, j) by the recurrence C(n, j+1) = C(n, j) (n - j) / (j + 1), starting at j = k.
    let ln_choose_k: f64 = (0..k)
        .map(|j| ((n - j) as f64).ln() - ((j + 1) as f64).ln())
        .sum();
    let mut terms = Vec::with_capacity(n - k + 1);
    let mut ln_c = ln_choose_k;
    for j in k..=n {
        terms.push(ln_c + j as f64 * lp + (n - j) as f64 * lq);
        if j < n {
            ln_c += ((n - j) as f64).ln() - ((j + 1) as f64).ln();
        }
    }
    let top = terms.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let sum: f64 = terms.iter().map(|t| (t - top).exp()).sum();
    (top + sum.ln()) / std::f64::consts::LN_10
}

/// `log10` of the number of false alarms of a consensus (Moisan & Stival's a-contrario
/// RANSAC): `NFA = tests * P[Bin(n - s, p0) >= k - s]`, the expected number of the `tests`
/// models tried that random correspondences would let reach `k` inliers of `n`, where `s` is
/// the minimal sample (its points are inliers by construction) and `p0` the probability that a
/// random correspondence falls inside a model's inlier region at the threshold used.
/// `NFA < 1` means better than chance; vofront asks for `NFA <= 10^max_log10_nfa`.
pub fn log10_nfa(n: usize, k: usize, sample: usize, p0: f64, tests: f64) -> f64 {
    if k <= sample || n <= sample {
        return tests.max(1.0).log10();
    }
    tests.max(1.0).log10() + log10_binomial_tail(n - sample, k - sample, p0)
}

/// Largest number of re-paired correspondences [`repaired_chance_rate`] measures (about).
pub const CHANCE_SAMPLES: usize = 20_000;

/// The cyclic shifts `s` (spread over `1..n-1`) under which correspondence `i` is re-paired with
/// the second half of `(i + s) mod n`: about [`CHANCE_SAMPLES`] pairs in all, none of them an
/// original pair. Empty for `n < 2`.
pub fn repairing_shifts(n: usize) -> impl Iterator<Item = usize> {
    let shifts = if n < 2 {
        0
    } else {
        CHANCE_SAMPLES.div_ceil(n).clamp(1, n - 1)
    };
    (0..shifts).map(move |k| 1 + k * (n - 1) / shifts)
}

/// `p0` of [`log10_nfa`] from `hits` accepted among `total` re-paired correspondences, with a
/// Laplace correction `(hits + 1) / (total + 2)` so that it is never exactly 0 or 1.
pub fn laplace_rate(hits: usize, total: usize) -> f64 {
    (hits as f64 + 1.0) / (total as f64 + 2.0)
}

/// `p0`: the share of re-paired correspondences `(first_i, second_{(i + s) mod n})`
/// ([`repairing_shifts`]) that the final model's inlier test `is_inlier(i, j)` accepts: pairs
/// that carry no information about the model but keep the distribution of the data.
/// `1` for fewer than two correspondences.
pub fn repaired_chance_rate(n: usize, is_inlier: impl Fn(usize, usize) -> bool) -> f64 {
    if n < 2 {
        return 1.0;
    }
    let (mut hits, mut total) = (0usize, 0usize);
    for s in repairing_shifts(n) {
        hits += (0..n).filter(|&i| is_inlier(i, (i + s) % n)).count();
        total += n;
    }
    laplace_rate(hits, total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binomial_tail_matches_direct_sums() {
        // P[Bin(10, 0.3) >= 3] by the complement of the first three terms.
        let (n, p) = (10usize, 0.3f64);
        let pmf = |j: usize| {
            let c: f64 = (0..j).map(|i| (n - i) as f64 / (i + 1) as f64).product();
            c * p.powi(j as i32) * (1.0 - p).powi((n - j) as i32)
        };
        let tail = 1.0 - pmf(0) - pmf(1) - pmf(2);
        assert!((10f64.powf(log10_binomial_tail(n, 3, p)) - tail).abs() < 1e-12);
        assert_eq!(log10_binomial_tail(n, 0, p), 0.0);
        assert_eq!(log10_binomial_tail(n, 11, p), f64::NEG_INFINITY);
        // Tails below f64's range stay finite in log space: P[Bin(1000, 0.01) >= 1000] = 1e-2000.
        assert!((log10_binomial_tail(1000, 1000, 0.01) + 2000.0).abs() < 1e-6);
    }

    #[test]
    fn nfa_separates_chance_from_consensus() {
        // 300 random correspondences, 1% land in a model's band: 14 inliers after 1e5 models
        // is what chance gives; 60 is not.
        let chance = log10_nfa(300, 14, 5, 0.01, 1e5);
        let real = log10_nfa(300, 60, 5, 0.01, 1e5);
        assert!(chance > -4.0, "{chance}");
        assert!(real < -20.0, "{real}");
    }

    #[test]
    fn verdict_is_the_most_severe_reason() {
        let cfg = QualityConfig::default();
        let judge = |support: Support, flags: &[Reason]| {
            Quality::judge(support, 1.0, 3, true, Uncertainty::default(), flags, &cfg)
        };
        let good = Support {
            log10_nfa: Some(-50.0),
            ..Support::new(200, 300)
        };
        assert_eq!(judge(good, &[]).verdict, Verdict::Ok);
        let q = judge(good, &[Reason::LowParallax, Reason::LowParallax]);
        assert_eq!(
            (q.verdict, q.reasons),
            (Verdict::Unreliable, vec![Reason::LowParallax])
        );
        let q = judge(Support::new(10, 300), &[Reason::LowParallax]);
        assert_eq!(q.verdict, Verdict::Failed);
        assert_eq!(
            q.reasons,
            vec![
                Reason::TooFewInliers,
                Reason::LowInlierRatio,
                Reason::LowParallax
            ]
        );
        let chance = Support {
            log10_nfa: Some(0.5),
            ..good
        };
        assert_eq!(
            judge(chance, &[]).reasons,
            vec![Reason::NotBetterThanChance]
        );
        let pixels = Support {
            pixels: Some(10),
            ..Support::new(10, 10)
        };
        assert_eq!(judge(pixels, &[]).reasons, vec![Reason::TooFewPixels]);
    }

    /// A reason found after the estimate was judged lowers an `ok` verdict, keeps a `failed`
    /// one, and is listed once.
    #[test]
    fn a_flag_added_later_sets_the_verdict_again() {
        let cfg = QualityConfig::default();
        let good = Support {
            log10_nfa: Some(-50.0),
            ..Support::new(200, 300)
        };
        let mut q = Quality::judge(good, 1.0, 3, true, Uncertainty::default(), &[], &cfg);
        q.flag(Reason::Inconsistent);
        q.flag(Reason::Inconsistent);
        assert_eq!(
            (q.verdict, q.reasons.clone()),
            (Verdict::Unreliable, vec![Reason::Inconsistent])
        );
        let few = Support::new(3, 300);
        let mut q = Quality::judge(few, 1.0, 3, true, Uncertainty::default(), &[], &cfg);
        q.flag(Reason::Inconsistent);
        assert_eq!(q.verdict, Verdict::Failed);
        assert!(q.reasons.contains(&Reason::Inconsistent));
    }

    #[test]
    fn an_undetermined_direction_is_low_parallax() {
        let cfg = QualityConfig::default();
        let good = Support {
            log10_nfa: Some(-50.0),
            ..Support::new(200, 300)
        };
        let with_sigma = |deg: f64| {
            let u = Uncertainty {
                translation_direction_sigma_deg: Some(deg),
                ..Uncertainty::default()
            };
            Quality::judge(good, 1.0, 3, true, u, &[], &cfg)
        };
        assert_eq!(
            with_sigma(0.5 * cfg.max_direction_sigma_deg).verdict,
            Verdict::Ok
        );
        let q = with_sigma(2.0 * cfg.max_direction_sigma_deg);
        assert_eq!(
            (q.verdict, q.reasons),
            (Verdict::Unreliable, vec![Reason::LowParallax])
        );
        assert_eq!(with_sigma(f64::NAN).reasons, vec![Reason::LowParallax]);
    }

    #[test]
    fn serialises_with_the_documented_names() {
        let q = Quality::judge(
            Support::new(3, 4),
            0.5,
            2,
            false,
            Uncertainty::default(),
            &[Reason::PlanarAmbiguous],
            &QualityConfig::default(),
        );
        let json = serde_json::to_value(&q).expect("serialises");
        assert_eq!(json["verdict"], "failed");
        assert_eq!(
            json["reasons"],
            serde_json::json!(["too_few_inliers", "planar_ambiguous", "not_converged"])
        );
        assert_eq!(json["inliers"], 3);
        assert_eq!(json["candidates"], 4);
        for r in &q.reasons {
            assert_eq!(serde_json::to_value(r).expect("serialises"), r.name());
        }
    }
}
