//! The two-view start of a direct monocular map, from the feature path (as the monocular
//! feature tracker starts): ORB matched between the reference and the current frame,
//! [`estimate_relative_pose`] (E or H, unit baseline) with its triangulated points, accepted
//! once the median parallax and the points suffice, the pose is judged `ok` and other RANSAC
//! draws do not contradict it ([`crate::odometry::redraw`]).
//!
//! Scale: the first map has median point depth 1 in the reference camera (`s = 1 / median
//! Z`); a map started after a loss takes the baseline `step * frames` from the motion model's
//! step length, so that the trajectory keeps its speed. The translation and the points are
//! multiplied by `s`.

use nalgebra::{Isometry3, Vector2};
use vofront_core::Camera;
use vofront_features::{match_descriptors, Features};
use vofront_geometry::estimate_relative_pose;
use vofront_robust::{Quality, Verdict};

use super::config::DirectMonoConfig;
use crate::odometry::reasons_text;
use crate::odometry::redraw;
use crate::pipeline::matched_pixels;

/// An accepted two-view start.
pub(super) struct TwoView {
    /// `T_21` (reference points into the current camera), in map units.
    pub t_21: Isometry3<f64>,
    /// Triangulated points: their pixel in the reference and inverse depth there.
    pub points: Vec<(Vector2<f32>, f64)>,
    /// The two-view pose's quality record.
    pub quality: Quality,
    /// Inlier matches, and matches.
    pub inliers: (usize, usize),
}

/// Why a start failed: keep waiting on the reference (`true`) or give it up.
pub(super) struct InitFailure {
    pub why: String,
    pub keep_reference: bool,
}

/// The two-view start between `reference` and `current` (features of the pinhole images of
/// `camera`), with the baseline `baseline` (map units) or, when `None`, median depth 1.
pub(super) fn two_view(
    cfg: &DirectMonoConfig,
    camera: &Camera,
    reference: &Features,
    current: &Features,
    baseline: Option<f64>,
) -> Result<TwoView, InitFailure> {
    let fail = |why: String, keep_reference: bool| InitFailure {
        why: format!("initialising: {why}"),
        keep_reference,
    };
    let matches = match_descriptors(
        reference.descriptors(),
        current.descriptors(),
        &cfg.matching,
    );
    if matches.len() < cfg.min_init_points {
        let why = format!("{} matches, {} needed", matches.len(), cfg.min_init_points);
        return Err(fail(why, false));
    }
    let (x1, x2) = matched_pixels(reference, current, &matches);
    let rel = estimate_relative_pose(&x1, &x2, camera, &cfg.relative)
        .map_err(|e| fail(e.to_string(), false))?;
    if rel.quality.verdict == Verdict::Failed {
        let why = format!("two-view pose failed: {}", reasons_text(&rel.quality));
        return Err(fail(why, false));
    }
    if rel.low_parallax || rel.parallax_deg < cfg.min_init_parallax_deg {
        return Err(fail(format!("parallax {:.2} deg", rel.parallax_deg), true));
    }
    if rel.quality.verdict == Verdict::Unreliable {
        let why = format!("two-view pose unreliable: {}", reasons_text(&rel.quality));
        return Err(fail(why, true));
    }
    if rel.triangulated() < cfg.min_init_points {
        let why = format!("{} points triangulated", rel.triangulated());
        return Err(fail(why, true));
    }
    if let Some(redrawn) = redraw::contradicted(&x1, &x2, camera, &cfg.relative, &rel) {
        let why = format!("another RANSAC draw gives a pose {redrawn:.1} sigmas away");
        return Err(fail(why, true));
    }
    let mut depths: Vec<f64> = rel.points.iter().flatten().map(|p| p.z).collect();
    let median = crate::robust::median_in_place(&mut depths).unwrap_or(1.0);
    let unit = rel.pose.translation.vector.norm();
    let s = match baseline.filter(|b| b.is_finite() && *b > 0.0) {
        Some(b) if unit > 0.0 => b / unit,
        _ => 1.0 / median,
    };
    if !(s.is_finite() && s > 0.0) {
        return Err(fail("degenerate scale".into(), false));
    }
    let mut t_21 = rel.pose;
    t_21.translation.vector *= s;
    let points = x1
        .iter()
        .zip(&rel.points)
        .filter_map(|(x, p)| {
            let p = (*p)?;
            (p.z > 0.0).then(|| (x.cast::<f32>(), 1.0 / (p.z * s)))
        })
        .collect();
    Ok(TwoView {
        t_21,
        points,
        inliers: (rel.inlier_count(), matches.len()),
        quality: rel.quality,
    })
}
