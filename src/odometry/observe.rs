//! Watching a run frame by frame: the [`FrameObserver`] hook that
//! [`run_observed`](super::run::run_observed) calls after every frame with the frame itself,
//! its estimate and what the tracker can show of it ([`FrameDetails`]: keypoints with their
//! role in the estimate, the local map's points).
//!
//! Trackers keep their details only when asked ([`Tracker::keep_details`](super::Tracker)),
//! so a run without an observer does no extra work. The observer depends on nothing but these
//! types: a viewer's sink (the `rerun` feature's `odometry::rerun_log`) lives outside the
//! trackers.

use std::io;

use nalgebra::Point3;
use vofront_direct::PixelResidual;
use vofront_features::{Features, Match};

use super::FrameEstimate;
use crate::dataset::Frame;

/// The part a keypoint played in the frame's estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeypointRole {
    /// Detected, not matched to the map (or not used by the estimate).
    Unmatched,
    /// Matched and an inlier of the pose.
    Inlier,
    /// Matched, rejected by the pose's robust fit.
    Outlier,
}

/// What a tracker shows of the last frame it tracked.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameDetails {
    /// Keypoint positions in the frame's image, pixels (`x` right, `y` down, from the
    /// centre of the top-left pixel).
    pub keypoints: Vec<[f32; 2]>,
    /// The role of each keypoint (as many as `keypoints`).
    pub roles: Vec<KeypointRole>,
    /// The points of the tracker's local map after this frame, world frame (map units: metres
    /// for the RGB-D and stereo trackers, the arbitrary scale of a monocular map; the direct
    /// trackers' keyframe pixels with depth).
    pub map_points: Vec<Point3<f64>>,
    /// The direct trackers' photometric residual of each keypoint (their keyframe's selected
    /// pixels warped into this frame), `I_cur - a I_ref - b` in grey levels; empty for the
    /// feature trackers. A keypoint is an inlier when `|r| <= residual_limit`.
    pub residuals: Vec<f32>,
    /// The inlier bound on `|residuals|` (the aligner's `inlier_sigmas` times its robust
    /// scale), grey levels; 0 without residuals.
    pub residual_limit: f32,
}

impl FrameDetails {
    /// Empties the record for the next frame, keeping its allocations.
    pub(crate) fn clear(&mut self) {
        self.keypoints.clear();
        self.roles.clear();
        self.map_points.clear();
        self.residuals.clear();
        self.residual_limit = 0.0;
    }

    /// Records the direct aligner's warped pixels (`to_image` takes a pixel of the aligner's
    /// geometry to the frame's image, `None` when it has no place there) with their residuals;
    /// inliers within `limit` grey levels, outliers beyond.
    pub(crate) fn photometric(
        &mut self,
        pixels: &[PixelResidual],
        limit: f32,
        to_image: impl Fn([f32; 2]) -> Option<[f32; 2]>,
    ) {
        self.keypoints.clear();
        self.roles.clear();
        self.residuals.clear();
        self.residual_limit = limit;
        for p in pixels {
            let Some(at) = to_image(p.pixel) else {
                continue;
            };
            self.keypoints.push(at);
            self.residuals.push(p.residual);
            self.roles.push(if p.residual.abs() <= limit {
                KeypointRole::Inlier
            } else {
                KeypointRole::Outlier
            });
        }
    }

    /// Moves every keypoint through `to_image` (one of another geometry, such as a rectified
    /// one, to the frame's image); a keypoint without a place there stays as it was.
    pub(crate) fn map_keypoints(&mut self, to_image: impl Fn([f32; 2]) -> Option<[f32; 2]>) {
        for k in &mut self.keypoints {
            if let Some(at) = to_image(*k) {
                *k = at;
            }
        }
    }

    /// Records the keypoints of `features`, all [`KeypointRole::Unmatched`].
    pub(crate) fn detected(&mut self, features: &Features) {
        self.keypoints.clear();
        self.keypoints.extend(
            features
                .xs()
                .iter()
                .zip(features.ys())
                .map(|(&x, &y)| [x, y]),
        );
        self.roles.clear();
        self.roles
            .resize(self.keypoints.len(), KeypointRole::Unmatched);
    }

    /// Marks the current-frame keypoint of each match (`train`) as an inlier or outlier of
    /// the pose (`inliers[i]` for `matches[i]`).
    pub(crate) fn mark(&mut self, matches: &[Match], inliers: &[bool]) {
        for (m, &inlier) in matches.iter().zip(inliers) {
            if let Some(role) = self.roles.get_mut(m.train as usize) {
                *role = if inlier {
                    KeypointRole::Inlier
                } else {
                    KeypointRole::Outlier
                };
            }
        }
    }

    /// Counts the keypoints of each role: `(inliers, outliers, unmatched)`.
    pub fn role_counts(&self) -> (usize, usize, usize) {
        self.roles
            .iter()
            .fold((0, 0, 0), |(i, o, u), role| match role {
                KeypointRole::Inlier => (i + 1, o, u),
                KeypointRole::Outlier => (i, o + 1, u),
                KeypointRole::Unmatched => (i, o, u + 1),
            })
    }
}

/// One tracked frame as an observer sees it.
#[derive(Debug, Clone, Copy)]
pub struct Observed<'a> {
    /// Index in the dataset.
    pub index: usize,
    /// The frame as the tracker got it.
    pub frame: &'a Frame,
    /// The tracker's first answer for it (a pending frame's late estimate, see
    /// [`Tracker::revised`](super::Tracker::revised), reaches the run's sinks only).
    pub estimate: &'a FrameEstimate,
    /// What the tracker shows of it; `None` for a tracker that keeps no details.
    pub details: Option<&'a FrameDetails>,
}

/// Sees every frame right after it was tracked (unreadable frames are skipped), in frame
/// order. Implemented for closures `FnMut(&Observed) -> io::Result<()>`.
pub trait FrameObserver {
    /// Takes one frame; an error stops the run
    /// ([`RunError::Observer`](super::run::RunError::Observer)).
    fn frame(&mut self, observed: &Observed<'_>) -> io::Result<()>;
}

impl<F: FnMut(&Observed<'_>) -> io::Result<()>> FrameObserver for F {
    fn frame(&mut self, observed: &Observed<'_>) -> io::Result<()> {
        self(observed)
    }
}
