//! Map initialisation from two views, and joining a new map's scale to a lost one.
//!
//! The reference frame (pose `T_w1`) and the current frame are matched and
//! [`estimate_relative_pose`] gives `T_21` with unit baseline; once the median parallax and
//! the number of triangulated points suffice, the two-view pose is judged `ok` and other
//! RANSAC draws do not contradict it ([`crate::odometry::redraw`]), both frames become
//! keyframes and the points (in units of that baseline, which fixes the arbitrary
//! scale) the map. A rotation-dominant start, or a pose judged `unreliable`, keeps waiting for
//! parallax; a reference that no longer matches is given up.
//!
//! After a loss the new map is placed at the motion model's pose `T_w1` and scaled about the
//! reference camera centre `C_1` by `s = median(|P_old - C_1| / |P_new - C_1|)` over old
//! points matched by descriptor to the new map's points.

use nalgebra::{Isometry3, Point3};
use vofront_core::Camera;
use vofront_features::{match_descriptors, Features, MatchConfig};
use vofront_geometry::{estimate_relative_pose, RelativePoseConfig};

use crate::odometry::local_map::LocalMap;
use crate::odometry::redraw;
use crate::odometry::{reasons_text, FrameQuality};
use crate::pipeline::matched_pixels;
use crate::robust::{Quality, Verdict};

/// Settings of [`initialise`].
pub(super) struct InitRules<'a> {
    pub camera: &'a Camera,
    pub matching: &'a MatchConfig,
    pub relative: &'a RelativePoseConfig,
    /// Fewest matches and triangulated points.
    pub min_points: usize,
    /// Smallest median parallax, degrees.
    pub min_parallax_deg: f64,
}

/// Why an initialisation attempt failed, and whether its reference is still worth waiting on.
pub(super) struct InitFailure {
    pub why: String,
    /// False when the reference no longer matches the current frame well enough to ever
    /// initialise: it is then replaced.
    pub keep_reference: bool,
}

/// A two-keyframe map from `reference` (at `t_w1`) and `current`, frames `frames.0` and
/// `frames.1`, with the frame's quality and the two-view pose's quality record.
pub(super) fn initialise(
    rules: &InitRules,
    reference: &Features,
    t_w1: &Isometry3<f64>,
    current: &Features,
    frames: (usize, usize),
) -> Result<(LocalMap, FrameQuality, Quality), InitFailure> {
    let give_up = |why: String| InitFailure {
        why,
        keep_reference: false,
    };
    let wait = |why: String| InitFailure {
        why,
        keep_reference: true,
    };
    let matches = match_descriptors(
        reference.descriptors(),
        current.descriptors(),
        rules.matching,
    );
    if matches.len() < rules.min_points {
        return Err(give_up(format!(
            "initialising: {} matches to the reference, {} needed",
            matches.len(),
            rules.min_points
        )));
    }
    let (x1, x2) = matched_pixels(reference, current, &matches);
    let rel = estimate_relative_pose(&x1, &x2, rules.camera, rules.relative)
        .map_err(|e| give_up(format!("initialising: {e}")))?;
    // A two-view pose judged failed (no support beyond chance, degenerate) makes no map.
    if rel.quality.verdict == Verdict::Failed {
        return Err(give_up(format!(
            "initialising: two-view pose failed: {}",
            reasons_text(&rel.quality)
        )));
    }
    if rel.low_parallax || rel.parallax_deg < rules.min_parallax_deg {
        return Err(wait(format!(
            "initialising: parallax {:.2} deg",
            rel.parallax_deg
        )));
    }
    // A pose judged unreliable for another reason (its rotation uncertain by degrees, a
    // planar twin as likely, few inliers among the matches) would build a distorted map that
    // every later frame agrees with; more parallax may settle it, so the reference is kept.
    if rel.quality.verdict == Verdict::Unreliable {
        return Err(wait(format!(
            "initialising: two-view pose unreliable: {}",
            reasons_text(&rel.quality)
        )));
    }
    if rel.triangulated() < rules.min_points {
        return Err(wait(format!(
            "initialising: {} points triangulated, {} needed",
            rel.triangulated(),
            rules.min_points
        )));
    }
    if let Some(redrawn) = redraw::contradicted(&x1, &x2, rules.camera, rules.relative, &rel) {
        return Err(wait(format!(
            "initialising: another RANSAC draw gives a pose {redrawn:.1} sigmas away"
        )));
    }
    let mut map = LocalMap::default();
    let k1 = map.push_keyframe(*t_w1, reference.clone(), frames.0);
    let k2 = map.push_keyframe(t_w1 * rel.pose.inverse(), current.clone(), frames.1);
    for (m, p) in matches.iter().zip(&rel.points) {
        if let Some(p) = p {
            map.add_point(t_w1 * p, &[(k1, m.query), (k2, m.train)]);
        }
    }
    let quality = FrameQuality {
        inliers: rel.inlier_count(),
        inlier_ratio: rel.inlier_count() as f64 / matches.len().max(1) as f64,
        keyframe: true,
        ..FrameQuality::default()
    };
    Ok((map, quality, rel.quality))
}

/// Scale `s` that brings `new` (initialised from the reference camera at `t_w1`) to the units
/// of `old`: the median of `|P_old - C_1| / |P_new - C_1|` over old points matched by
/// descriptor to points of `new`'s newest keyframe; `None` with fewer than `min_matches`.
pub(super) fn scale_to(
    old: &LocalMap,
    new: &LocalMap,
    t_w1: &Isometry3<f64>,
    matching: &MatchConfig,
    min_matches: usize,
) -> Option<f64> {
    let kf = new.last()?;
    let old_points: Vec<_> = old.points.values().collect();
    let descriptors: Vec<_> = old_points.iter().map(|p| p.descriptor).collect();
    let c = Point3::from(t_w1.translation.vector);
    let mut ratios: Vec<f64> = match_descriptors(&descriptors, kf.features.descriptors(), matching)
        .iter()
        .filter_map(|m| {
            let p_new = new.points.get(&kf.point_of[m.train as usize]?)?.position;
            let r = (old_points[m.query as usize].position - c).norm() / (p_new - c).norm();
            r.is_finite().then_some(r)
        })
        .collect();
    if ratios.len() < min_matches {
        return None;
    }
    crate::robust::median_in_place(&mut ratios).filter(|s| *s > 0.0)
}

/// Scale that makes the baseline of `map` (its two newest keyframes, `elapsed` frames
/// apart) `elapsed` steps of the motion model's typical `step` (map units per frame); `None`
/// without a positive step or baseline.
pub(super) fn scale_from_motion(map: &LocalMap, step: Option<f64>, elapsed: usize) -> Option<f64> {
    let step = step.filter(|v| v.is_finite() && *v > 0.0)?;
    let baseline = map.baseline().filter(|b| *b > 0.0)?;
    Some(step * elapsed as f64 / baseline)
}

/// Scales `map` by `s` about the reference camera `t_w1`: `P <- T_w1 (s T_w1^-1 P)` for the
/// points, and the translation of `T_w1^-1 T_wc` times `s` for the keyframes.
pub(super) fn rescale(map: &mut LocalMap, t_w1: &Isometry3<f64>, s: f64) {
    let t_1w = t_w1.inverse();
    for p in map.points.values_mut() {
        p.position = t_w1 * Point3::from((t_1w * p.position).coords * s);
        p.distance *= s;
    }
    for kf in map.keyframes.iter_mut() {
        let mut t_1c = t_1w * kf.t_wc;
        t_1c.translation.vector *= s;
        kf.t_wc = t_w1 * t_1c;
    }
}
