//! Relative pose error over pose pairs a fixed distance apart, as `evo_rpe` computes it.
//!
//! The pairs `(i, j)` are indices into the associated (and aligned) pose lists, chosen on the
//! estimate's poses (evo's default) or on the ground truth's
//! ([`RpeConfig::pairs_from_reference`]):
//!
//! - [`DeltaUnit::Frames`], consecutive: `i = 0, d, 2d, ...`, pairs of neighbours in that
//!   list; all pairs: every `(i, i + d)`.
//! - [`DeltaUnit::Meters`] (travelled path) and [`DeltaUnit::Seconds`] (elapsed time),
//!   consecutive: starting at 0, the next index is the first one at which the path (time)
//!   accumulated since the previous index reaches `d`; all pairs: for every `i`, the later
//!   `j` whose accumulated path (time) from `i` is nearest to `d`, kept when within
//!   `delta_tol * d` of it. evo v1.38.1 has no seconds unit; here it follows the metre rule
//!   with time in place of path.

use nalgebra::{Isometry3, Vector3};

use super::{associate_and_align, Alignment, EvalConfig, EvalError, Stats};
use crate::trajectory::Trajectory;

/// Unit of [`RpeConfig::delta`] (evo `--delta_unit`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DeltaUnit {
    /// Associated poses (evo `f`).
    #[default]
    Frames,
    /// Metres of travelled path (evo `m`).
    Meters,
    /// Seconds of elapsed time (not in evo v1.38.1).
    Seconds,
}

impl DeltaUnit {
    /// Short unit name for messages: `frames`, `m`, `s`.
    pub fn symbol(self) -> &'static str {
        match self {
            DeltaUnit::Frames => "frames",
            DeltaUnit::Meters => "m",
            DeltaUnit::Seconds => "s",
        }
    }
}

/// Which pose pairs [`rpe_with`] compares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RpeConfig {
    /// Distance between the two poses of a pair, in [`RpeConfig::unit`] (evo `--delta`, 1).
    pub delta: f64,
    /// Unit of `delta` (evo `--delta_unit`, frames).
    pub unit: DeltaUnit,
    /// Every pose starts a pair instead of only the previous pair's end (evo `--all_pairs`).
    pub all_pairs: bool,
    /// All-pairs acceptance: `|distance - delta| <= delta_tol * delta` for metres and seconds
    /// (evo `--delta_tol`, 0.1).
    pub delta_tol: f64,
    /// Choose the pairs on the ground truth instead of the estimate (evo
    /// `--pairs_from_reference`, off).
    pub pairs_from_reference: bool,
}

impl Default for RpeConfig {
    /// Consecutive associated poses: `--delta 1 --delta_unit f`, tolerance 0.1.
    fn default() -> Self {
        Self {
            delta: 1.0,
            unit: DeltaUnit::Frames,
            all_pairs: false,
            delta_tol: 0.1,
            pairs_from_reference: false,
        }
    }
}

/// Result of [`rpe_with`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RpeResult {
    /// Associated index pairs `(ground-truth index, estimate index)`.
    pub pairs: Vec<(usize, usize)>,
    /// The compared pose pairs `(i, j)`, indices into [`RpeResult::pairs`].
    pub delta_pairs: Vec<(usize, usize)>,
    /// Ground-truth timestamp (s) of the second pose of each compared pair.
    pub times: Vec<f64>,
    /// `|trans(E)|` metres, one per compared pair.
    pub translation_errors: Vec<f64>,
    /// `angle(rot(E))` degrees, one per compared pair.
    pub rotation_errors_deg: Vec<f64>,
    /// Statistics of the translation errors (metres).
    pub translation: Stats,
    /// Statistics of the rotation errors (degrees).
    pub rotation_deg: Stats,
    /// How the estimate's relative rotations compare in size with the ground truth's over
    /// the compared pairs (`None` when the ground truth does not rotate or there are fewer
    /// than two pairs).
    pub rotation_scale: Option<RotationScale>,
}

/// The least-squares factor between estimated and true relative rotations: with
/// `g_k = log(rot(Q_i^-1 Q_j))` and `e_k = log(rot(P_i^-1 P_j))` the rotation vectors (radians,
/// in camera `i`'s frame) of the compared pairs, `scale = sum_k g_k . e_k / sum_k |g_k|^2`
/// minimises `sum_k |e_k - scale g_k|^2`, and `sigma = sqrt(sum_k |e_k - scale g_k|^2 /
/// (3n - 1) / sum_k |g_k|^2)` is its standard deviation from the scatter of the residuals when
/// the pairs are independent (overlapping pairs, as `all_pairs` picks them for a delta above one
/// frame, share their errors and make it too small).
///
/// Noise with zero mean leaves `scale` at 1. A pinhole focal length off by a factor `k` shrinks
/// a feature tracker's pan and tilt (rotations about axes in the image plane) to about `1 / k`
/// of the truth, so a `scale` several `sigma` from 1 on a turning sequence points at the
/// calibration (or at the ground truth's heading), which no tracker setting can repair.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RotationScale {
    /// Estimated over true rotation, dimensionless.
    pub scale: f64,
    /// Standard deviation of `scale`.
    pub sigma: f64,
}

impl RotationScale {
    /// The factor of `(true, estimated)` rotation-vector pairs; `None` with fewer than two
    /// pairs, no true rotation or a non-finite input.
    pub fn fit(pairs: &[(Vector3<f64>, Vector3<f64>)]) -> Option<Self> {
        let n = pairs.len();
        let gg: f64 = pairs.iter().map(|(g, _)| g.norm_squared()).sum();
        if n < 2 || gg <= 0.0 {
            return None;
        }
        let scale = pairs.iter().map(|(g, e)| g.dot(e)).sum::<f64>() / gg;
        let residual: f64 = pairs
            .iter()
            .map(|(g, e)| (e - g * scale).norm_squared())
            .sum();
        let sigma = (residual / (3 * n - 1) as f64 / gg).sqrt();
        (scale.is_finite() && sigma.is_finite()).then_some(Self { scale, sigma })
    }
}

/// Relative pose error over consecutive associated poses, as
/// `evo_rpe tum gt est --delta 1 --delta_unit f`; [`rpe_with`] with [`RpeConfig::default`].
pub fn rpe(gt: &Trajectory, est: &Trajectory, config: &EvalConfig) -> Result<RpeResult, EvalError> {
    rpe_with(gt, est, config, &RpeConfig::default())
}

/// Relative pose error of `est` against `gt` over the pose pairs that `pairs` selects, as
/// `evo_rpe tum gt est --delta D --delta_unit f|m [--all_pairs] --pose_relation
/// trans_part|angle_deg`. `config.alignment` only matters for [`Alignment::Sim3`] (a rigid
/// alignment leaves relative poses and path lengths unchanged). Needs two associated pairs
/// (three with alignment) and at least one selected pose pair.
pub fn rpe_with(
    gt: &Trajectory,
    est: &Trajectory,
    config: &EvalConfig,
    pairs: &RpeConfig,
) -> Result<RpeResult, EvalError> {
    let d = pairs.delta;
    let whole = d.fract() == 0.0;
    if !(d.is_finite() && d > 0.0) || (pairs.unit == DeltaUnit::Frames && !whole) {
        return Err(EvalError::BadDelta(d));
    }
    let min_pairs = if config.alignment == Alignment::None {
        2
    } else {
        3
    };
    let a = associate_and_align(gt, est, config, min_pairs)?;
    let chosen = if pairs.pairs_from_reference {
        &a.gt
    } else {
        &a.est
    };
    let delta_pairs = select_pairs(chosen, pairs);
    if delta_pairs.is_empty() {
        return Err(EvalError::NoPairs(format!("{d} {}", pairs.unit.symbol())));
    }
    let (mut trans, mut rot, mut times) = (Vec::new(), Vec::new(), Vec::new());
    let mut rotation_vectors = Vec::with_capacity(delta_pairs.len());
    for &(i, j) in &delta_pairs {
        let q_rel = a.gt[i].1.inverse() * a.gt[j].1;
        let p_rel = a.est[i].1.inverse() * a.est[j].1;
        let e = q_rel.inverse() * p_rel;
        trans.push(e.translation.vector.norm());
        let quat = e.rotation.coords;
        let angle = 2.0 * quat.xyz().norm().atan2(quat.w.abs());
        rot.push(angle.to_degrees());
        times.push(a.gt[j].0);
        rotation_vectors.push((q_rel.rotation.scaled_axis(), p_rel.rotation.scaled_axis()));
    }
    Ok(RpeResult {
        pairs: a.pairs,
        delta_pairs,
        times,
        translation: Stats::from_errors(&trans).ok_or(EvalError::NotFinite)?,
        rotation_deg: Stats::from_errors(&rot).ok_or(EvalError::NotFinite)?,
        translation_errors: trans,
        rotation_errors_deg: rot,
        rotation_scale: RotationScale::fit(&rotation_vectors),
    })
}

/// The pose pairs of `poses` (stamped, in order) that `config` selects (module docs).
fn select_pairs(poses: &[(f64, Isometry3<f64>)], config: &RpeConfig) -> Vec<(usize, usize)> {
    let n = poses.len();
    let d = config.delta;
    if config.unit == DeltaUnit::Frames {
        let step = d as usize;
        return if config.all_pairs {
            (0..n.saturating_sub(step)).map(|i| (i, i + step)).collect()
        } else {
            let ids: Vec<usize> = (0..n).step_by(step).collect();
            ids.windows(2).map(|w| (w[0], w[1])).collect()
        };
    }
    // Increment from pose k-1 to pose k: path length or elapsed time.
    let increments: Vec<f64> = poses
        .windows(2)
        .map(|w| match config.unit {
            DeltaUnit::Seconds => w[1].0 - w[0].0,
            _ => (w[1].1.translation.vector - w[0].1.translation.vector).norm(),
        })
        .collect();
    if config.all_pairs {
        nearest_pairs(&increments, d, config.delta_tol * d)
    } else {
        consecutive_pairs(&increments, d)
    }
}

/// evo's consecutive rule: index 0, then each index at which the sum of increments since the
/// previous chosen index reaches `delta` (the sum restarts there); pairs of neighbours.
fn consecutive_pairs(increments: &[f64], delta: f64) -> Vec<(usize, usize)> {
    let mut ids = vec![0];
    let mut accumulated = 0.0;
    for (k, inc) in increments.iter().enumerate() {
        accumulated += inc;
        if accumulated >= delta {
            ids.push(k + 1);
            accumulated = 0.0;
        }
    }
    ids.windows(2).map(|w| (w[0], w[1])).collect()
}

/// evo's all-pairs rule: with `s_k` the running sum of increments (`s_0 = 0`), for every `i`
/// the first `j > i` minimising `|s_j - s_i - delta|`, kept when that is at most `tol`.
fn nearest_pairs(increments: &[f64], delta: f64, tol: f64) -> Vec<(usize, usize)> {
    let mut sums = Vec::with_capacity(increments.len() + 1);
    sums.push(0.0);
    let mut s = 0.0;
    for inc in increments {
        s += inc;
        sums.push(s);
    }
    let mut pairs = Vec::new();
    for i in 0..sums.len().saturating_sub(1) {
        let mut best = (i + 1, f64::INFINITY);
        for (j, &sj) in sums.iter().enumerate().skip(i + 1) {
            let miss = (sj - sums[i] - delta).abs();
            if miss < best.1 {
                best = (j, miss);
            }
        }
        if best.1 <= tol {
            pairs.push((i, best.0));
        }
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::{consecutive_pairs, nearest_pairs};

    #[test]
    fn consecutive_restarts_the_sum_at_each_chosen_index() {
        // Sums since the last chosen index: 0.4, 0.8, 1.2 -> 3; 0.4, 0.8, 1.2 -> 6.
        let inc = [0.4; 7];
        assert_eq!(consecutive_pairs(&inc, 1.0), vec![(0, 3), (3, 6)]);
    }

    #[test]
    fn nearest_keeps_only_pairs_within_the_tolerance() {
        let inc = [0.5, 0.5, 2.0, 0.5];
        // From 0: sums 0.5, 1.0 (exact), 3.0, 3.5 -> (0, 2). From 1: 0.5, 2.5, 3.0 -> miss 0.5 > 0.1.
        // From 2: 2.0, 2.5 -> miss 1.0. From 3: 0.5 -> miss 0.5.
        assert_eq!(nearest_pairs(&inc, 1.0, 0.1), vec![(0, 2)]);
    }
}
