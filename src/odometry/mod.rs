//! Sequence odometry: trackers that follow a camera through a dataset, frame by frame.
//!
//! Every tracker aligns each new frame to its current keyframe, starting from the
//! constant-velocity prediction ([`motion`]), decides when to take a new keyframe
//! ([`keyframe`]), and reports the camera pose `T_wc` (camera-to-world, first frame at the
//! origin) with a [`TrackStatus`] and [`FrameQuality`] scores. [`run`] drives a tracker over a
//! [`crate::dataset::Dataset`] and collects the trajectory.
//!
//! - [`direct`]: RGB-D photometric SE(3) alignment to the keyframe;
//! - [`feature_rgbd`]: ORB matched to the keyframe, 3D points from its depth, PnP RANSAC;
//! - [`mono`]: monocular ORB: two-view initialisation, triangulated points, PnP tracking.

pub mod direct;
pub mod feature_rgbd;
pub mod keyframe;
pub mod mono;
pub mod motion;
pub mod run;

use nalgebra::Isometry3;

use crate::dataset::Frame;

/// How tracking of one frame went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackStatus {
    /// Aligned to the keyframe.
    Ok,
    /// Could not be aligned; the pose is the motion model's guess and is not part of the
    /// trajectory.
    Lost,
    /// Tracking restarted at this frame after being lost: a new keyframe placed at the motion
    /// model's guess, so the trajectory continues but may have jumped.
    Reinitialised,
}

impl TrackStatus {
    /// Lower-case name used in the per-frame CSV.
    pub fn as_str(self) -> &'static str {
        match self {
            TrackStatus::Ok => "ok",
            TrackStatus::Lost => "lost",
            TrackStatus::Reinitialised => "reinitialised",
        }
    }
}

/// Quality scores of one frame's estimate.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameQuality {
    /// Inlier residuals (pixels for direct, correspondences for feature trackers).
    pub inliers: usize,
    /// Inliers over valid residuals.
    pub inlier_ratio: f64,
    /// Residual RMSE (grey levels for direct, pixels for feature trackers).
    pub rmse: f64,
    /// Optimisation iterations (all levels).
    pub iterations: usize,
    /// Trace of the 6x6 pose covariance (m^2 + rad^2); smaller is more certain.
    pub covariance_trace: f64,
    /// This frame became a keyframe.
    pub keyframe: bool,
    /// Time spent on the frame, milliseconds.
    pub ms: f64,
}

/// A tracker's answer for one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameEstimate {
    /// Camera-to-world pose `T_wc`.
    pub pose_wc: Isometry3<f64>,
    /// How tracking went.
    pub status: TrackStatus,
    /// Quality scores.
    pub quality: FrameQuality,
    /// Why the frame was lost, if it was.
    pub message: Option<String>,
}

/// Follows a camera through consecutive frames.
pub trait Tracker {
    /// Estimates the pose of the next frame.
    fn track(&mut self, frame: &Frame) -> FrameEstimate;
}
