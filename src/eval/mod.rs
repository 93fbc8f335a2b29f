//! Trajectory evaluation as the `evo` package computes it: absolute trajectory error (ATE,
//! `evo_ape`, translation part) after optional Umeyama alignment, relative pose error over
//! pose pairs `delta` frames, metres or seconds apart (RPE, `evo_rpe --delta D --delta_unit
//! f|m [--all_pairs]`), and plots ([`plot`]).
//!
//! Both start by associating timestamps with [`associate`] (evo's nearest-time rule,
//! default `max_dt = 0.01` s). With `Q_k` the ground truth and `P_k` the estimate of the
//! `k`-th associated pair (both camera-to-world):
//!
//! - alignment: [`umeyama()`] on the positions, estimate onto ground truth, giving `S`
//!   (identity for [`Alignment::None`], rigid for [`Alignment::Se3`], similarity for
//!   [`Alignment::Sim3`]); `P_k <- S P_k` (positions scaled, rotated and shifted);
//! - ATE: `e_k = |trans(Q_k) - trans(P_k)|` metres (evo `--pose_relation trans_part`);
//! - RPE: for each pose pair `(i, j)` chosen by [`RpeConfig`] (`delta` frames, metres of
//!   travelled path or seconds, consecutive or all pairs), `E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`,
//!   translation error `|trans(E)|` metres (`trans_part`), rotation error `angle(rot(E))`
//!   degrees (`angle_deg`); see [`rpe_with`].
//!
//! Statistics ([`Stats`]) are evo's: RMSE, mean, median (mean of the two middle values for
//! an even count), population standard deviation, min and max.
//!
//! Conventions shared with evo (v1.38.1 checked to 1e-12 in `tests/eval.rs`): the ground
//! truth is the reference (first argument), alignment uses positions only, and the RPE pairs
//! are counted in *associated* poses, so where the estimate skips frames a pair spans
//! several ground-truth frames; evo picks metre pairs on the (aligned) estimate unless
//! `--pairs_from_reference` ([`RpeConfig::pairs_from_reference`]). Differences: [`associate`] drops the farther of two poses
//! that pick the same partner (evo keeps both; only possible when two stamps are less than
//! `2 max_dt` apart); alignment needs at least 3 associated poses (evo fails later, on the
//! rank test, with fewer).
//!
//! ```
//! use nalgebra::{Isometry3, Vector3};
//! use vofront::eval::{ate, Alignment, EvalConfig};
//! use vofront::trajectory::Trajectory;
//! let gt = Trajectory::new((0..10).map(|i| {
//!     let t: f64 = i as f64 * 0.1;
//!     (t, Isometry3::translation(t, (3.0 * t).sin(), 0.2 * t * t))
//! }).collect());
//! let shifted = Trajectory::new(gt.poses.iter().map(|(t, p)| {
//!     (*t, Isometry3::translation(1.0, 2.0, 3.0) * p)
//! }).collect());
//! let aligned = ate(&gt, &shifted, &EvalConfig { alignment: Alignment::Se3, ..Default::default() }).unwrap();
//! assert!(aligned.stats.rmse < 1e-9);
//! let raw = ate(&gt, &shifted, &EvalConfig::default()).unwrap();
//! assert!((raw.stats.rmse - Vector3::new(1.0f64, 2.0, 3.0).norm()).abs() < 1e-9);
//! ```

pub mod plot;
mod rpe;
pub mod umeyama;

use nalgebra::Isometry3;
use thiserror::Error;

pub use rpe::{rpe, rpe_with, DeltaUnit, RotationScale, RpeConfig, RpeResult};
pub use umeyama::{umeyama, Sim3};

use crate::trajectory::{associate, Trajectory};

/// Errors of trajectory evaluation.
#[derive(Debug, Error, PartialEq)]
pub enum EvalError {
    /// Too few associated poses for the requested evaluation.
    #[error("{0} associated poses, too few to evaluate")]
    TooFewPoses(usize),
    /// Point sets of different lengths.
    #[error("point sets of different lengths: {0} and {1}")]
    LengthMismatch(usize, usize),
    /// A position is NaN or infinite.
    #[error("a position is not finite")]
    NotFinite,
    /// The positions are collinear or coincident: the alignment is not unique.
    #[error("degenerate point configuration: Umeyama alignment is not possible")]
    Degenerate,
    /// The association tolerance is negative or not a number.
    #[error("largest timestamp difference {0} s is invalid: it must be zero or positive")]
    BadMaxDt(f64),
    /// The RPE delta is not positive (or not a whole number of frames).
    #[error("RPE delta {0} is invalid: it must be positive, and a whole number for frames")]
    BadDelta(f64),
    /// No pose pair is `delta` apart (evo: "produced an empty index list").
    #[error("no pose pair is {0} apart: try a smaller delta or a larger tolerance")]
    NoPairs(String),
}

/// How the estimate is aligned to the ground truth before computing errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Alignment {
    /// No alignment (evo without `--align`).
    #[default]
    None,
    /// Rigid Umeyama alignment of the positions (evo `--align`).
    Se3,
    /// Similarity Umeyama alignment of the positions (evo `--align --correct_scale`).
    Sim3,
}

/// Options of [`ate`] and [`rpe`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvalConfig {
    /// Maximum timestamp difference (s) for associating poses (evo `--t_max_diff`, 0.01).
    pub max_dt: f64,
    /// Alignment of the estimate (default none, as evo without `--align`).
    pub alignment: Alignment,
}

impl Default for EvalConfig {
    fn default() -> Self {
        Self {
            max_dt: 0.01,
            alignment: Alignment::None,
        }
    }
}

impl EvalConfig {
    /// The settings for [`rpe`] that go with these ATE settings: RPE is invariant to a rigid
    /// alignment, so only a similarity (which rescales its translation part) is kept.
    pub fn for_rpe(self) -> Self {
        Self {
            alignment: if self.alignment == Alignment::Sim3 {
                Alignment::Sim3
            } else {
                Alignment::None
            },
            ..self
        }
    }
}

/// Summary statistics of a list of errors, as evo prints them (serialised with evo's key names).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Stats {
    /// `sqrt(mean(e^2))`.
    pub rmse: f64,
    /// Mean.
    pub mean: f64,
    /// Median (mean of the two middle values for an even count).
    pub median: f64,
    /// Population standard deviation `sqrt(mean((e - mean)^2))`.
    pub std: f64,
    /// Minimum.
    pub min: f64,
    /// Maximum.
    pub max: f64,
    /// Sum of squares `sum(e^2)`.
    pub sse: f64,
    /// Number of errors.
    pub count: usize,
}

impl Stats {
    /// Statistics of `errors`; `None` when empty or when a value is not finite.
    pub fn from_errors(errors: &[f64]) -> Option<Self> {
        if errors.is_empty() || !errors.iter().all(|e| e.is_finite()) {
            return None;
        }
        let n = errors.len() as f64;
        let sse: f64 = errors.iter().map(|e| e * e).sum();
        let mean = errors.iter().sum::<f64>() / n;
        let var = errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n;
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let mid = sorted.len() / 2;
        let median = if sorted.len().is_multiple_of(2) {
            0.5 * (sorted[mid - 1] + sorted[mid])
        } else {
            sorted[mid]
        };
        Some(Self {
            rmse: (sse / n).sqrt(),
            mean,
            median,
            std: var.sqrt(),
            min: sorted[0],
            max: sorted[sorted.len() - 1],
            sse,
            count: errors.len(),
        })
    }
}

/// Result of [`ate`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AteResult {
    /// Associated index pairs `(ground-truth index, estimate index)`.
    pub pairs: Vec<(usize, usize)>,
    /// The alignment applied to the estimate (identity for [`Alignment::None`]).
    pub alignment: Sim3,
    /// The associated estimate poses after alignment, stamped with the estimate's times.
    pub aligned: Trajectory,
    /// `(ground-truth timestamp, translation error in metres)` per associated pair.
    pub errors: Vec<(f64, f64)>,
    /// Statistics of the translation errors (metres).
    pub stats: Stats,
}

/// The associated, aligned pose pairs `(t_gt, Q_k, t_est, P_k)` and the alignment.
pub(crate) struct Associated {
    pub(crate) pairs: Vec<(usize, usize)>,
    pub(crate) gt: Vec<(f64, Isometry3<f64>)>,
    pub(crate) est: Vec<(f64, Isometry3<f64>)>,
    pub(crate) alignment: Sim3,
}

pub(crate) fn associate_and_align(
    gt: &Trajectory,
    est: &Trajectory,
    config: &EvalConfig,
    min_pairs: usize,
) -> Result<Associated, EvalError> {
    if config.max_dt.is_nan() || config.max_dt < 0.0 {
        return Err(EvalError::BadMaxDt(config.max_dt));
    }
    let pairs = associate(gt, est, config.max_dt);
    if pairs.len() < min_pairs {
        return Err(EvalError::TooFewPoses(pairs.len()));
    }
    let q: Vec<_> = pairs.iter().map(|&(i, _)| gt.poses[i]).collect();
    let p: Vec<_> = pairs.iter().map(|&(_, j)| est.poses[j]).collect();
    let alignment = match config.alignment {
        Alignment::None => Sim3::default(),
        Alignment::Se3 | Alignment::Sim3 => {
            let xs: Vec<_> = p.iter().map(|(_, pose)| pose.translation.vector).collect();
            let ys: Vec<_> = q.iter().map(|(_, pose)| pose.translation.vector).collect();
            umeyama(&xs, &ys, config.alignment == Alignment::Sim3)?
        }
    };
    let est = p
        .into_iter()
        .map(|(t, pose)| (t, alignment.transform_pose(&pose)))
        .collect();
    Ok(Associated {
        pairs,
        gt: q,
        est,
        alignment,
    })
}

/// Absolute trajectory error of `est` against `gt` (translation part, metres), as
/// `evo_ape tum gt est [--align [--correct_scale]]`. Needs one associated pair without
/// alignment, three with.
pub fn ate(gt: &Trajectory, est: &Trajectory, config: &EvalConfig) -> Result<AteResult, EvalError> {
    let min_pairs = if config.alignment == Alignment::None {
        1
    } else {
        3
    };
    let a = associate_and_align(gt, est, config, min_pairs)?;
    let errors: Vec<(f64, f64)> =
        a.gt.iter()
            .zip(&a.est)
            .map(|((t, q), (_, p))| (*t, (q.translation.vector - p.translation.vector).norm()))
            .collect();
    let values: Vec<f64> = errors.iter().map(|e| e.1).collect();
    let stats = Stats::from_errors(&values).ok_or(EvalError::NotFinite)?;
    Ok(AteResult {
        pairs: a.pairs,
        alignment: a.alignment,
        aligned: Trajectory::new(a.est),
        errors,
        stats,
    })
}
