//! Logging a run to the [Rerun](https://rerun.io) viewer (feature `rerun`): a
//! [`FrameObserver`] that writes each frame to an `.rrd` file or streams it to a running viewer.
//!
//! Entities (the world frame is the first camera's, `x` right, `y` down, `z` forward, as
//! [`FrameEstimate::pose_wc`]):
//!
//! | entity | what | when |
//! | --- | --- | --- |
//! | [`CAMERA`] | `Transform3D`: the pose `T_wc` | each frame that is not lost |
//! | [`IMAGE`] | `Pinhole` (static: `fx`, `fy`, `cx`, `cy`, the frame size) and the grey `Image` | each frame |
//! | [`KEYPOINTS`] | `Points2D` in pixels: the feature trackers' keypoints, inliers green, outliers red, unmatched grey ([`role_colour`]); the direct trackers' keyframe pixels warped into the frame, green to red by their photometric residual ([`residual_colour`]) | each frame with details (every tracker) |
//! | [`TRAJECTORY`] | `LineStrips3D`: the camera centres tracked so far | each frame that is not lost |
//! | [`GROUND_TRUTH`] | `LineStrips3D` (static): the ground-truth centres, relative to the pose at the first frame | once, when known |
//! | [`MAP_POINTS`] | `Points3D`: the local map's points (map units; the direct trackers' keyframe pixels with depth) | each frame with details |
//! | [`INLIERS`], [`RESIDUAL`], [`VERDICT`], [`TIME`] | `Scalars`: inliers, residual RMSE, verdict (0 ok, 1 unreliable, 2 failed), tracking time in ms | each frame (the verdict when the pose has one) |
//! | [`STATUS`] | `TextLog`: the status and the message | each frame |
//!
//! Timelines: `frame` (the dataset index) and `time` (the frame's timestamp, seconds). A
//! monocular trajectory has an arbitrary scale: the ground truth beside it shows its shape,
//! not its size.

use std::io;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3};
use rerun::{
    Color, Image, LineStrips3D, Pinhole, Points2D, Points3D, Quaternion, RecordingStream,
    RecordingStreamBuilder, Scalars, TextLog, Transform3D,
};
use thiserror::Error;
use vofront_core::Camera;
use vofront_robust::Verdict;

use super::observe::{FrameObserver, KeypointRole, Observed};
use super::{FrameEstimate, TrackStatus};
use crate::trajectory::Trajectory;

/// The camera's pose.
pub const CAMERA: &str = "world/camera";
/// The camera's intrinsics and its image.
pub const IMAGE: &str = "world/camera/image";
/// The frame's keypoints coloured by role.
pub const KEYPOINTS: &str = "world/camera/image/keypoints";
/// The estimated camera centres.
pub const TRAJECTORY: &str = "world/trajectory";
/// The ground-truth camera centres.
pub const GROUND_TRUTH: &str = "world/ground_truth";
/// The local map's points.
pub const MAP_POINTS: &str = "world/map/points";
/// Inlier count.
pub const INLIERS: &str = "metrics/inliers";
/// Residual RMSE (grey levels for the direct tracker, pixels for the feature trackers).
pub const RESIDUAL: &str = "metrics/residual";
/// Verdict of the pose's estimate: 0 ok, 1 unreliable, 2 failed.
pub const VERDICT: &str = "metrics/verdict";
/// Tracking time, milliseconds.
pub const TIME: &str = "metrics/time_ms";
/// Status and message.
pub const STATUS: &str = "status";

/// The address [`RerunSink::connect`] uses when none is given: a viewer started with
/// `rerun` on this machine.
pub const DEFAULT_VIEWER: &str = "rerun+http://127.0.0.1:9876/proxy";

/// Why a recording could not be started.
#[derive(Debug, Error)]
pub enum RerunLogError {
    /// The `.rrd` file could not be created.
    #[error("{}: cannot write the Rerun recording: {source}", path.display())]
    File {
        /// The file asked for.
        path: PathBuf,
        /// Rerun's error.
        source: rerun::RecordingStreamError,
    },
    /// The viewer address is not a Rerun proxy address.
    #[error("{address}: cannot connect to a Rerun viewer: {source}")]
    Connect {
        /// The address asked for.
        address: String,
        /// Rerun's error.
        source: rerun::RecordingStreamError,
    },
}

/// Logs every observed frame to a Rerun recording (see the module documentation for the
/// entities).
pub struct RerunSink {
    rec: RecordingStream,
    camera: Camera,
    /// The ground truth `T_wc`, drawn once the first frame fixes its anchor.
    ground_truth: Option<Trajectory>,
    /// The image size the pinhole was logged for.
    logged_size: Option<(usize, usize)>,
    /// Camera centres tracked so far.
    centres: Vec<[f32; 3]>,
}

impl RerunSink {
    /// A sink writing the recording to `path` (created at once, so that a bad path fails
    /// before any frame is tracked); `camera` gives the pinhole drawn with the images.
    pub fn save(path: &Path, camera: Camera) -> Result<Self, RerunLogError> {
        let rec = RecordingStreamBuilder::new("vofront")
            .save(path)
            .map_err(|source| RerunLogError::File {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(Self::new(rec, camera))
    }

    /// A sink streaming to the viewer at `address` (e.g. [`DEFAULT_VIEWER`]); frames logged
    /// before the viewer answers are buffered.
    pub fn connect(address: &str, camera: Camera) -> Result<Self, RerunLogError> {
        let rec = RecordingStreamBuilder::new("vofront")
            .connect_grpc_opts(address)
            .map_err(|source| RerunLogError::Connect {
                address: address.to_string(),
                source,
            })?;
        Ok(Self::new(rec, camera))
    }

    fn new(rec: RecordingStream, camera: Camera) -> Self {
        Self {
            rec,
            camera,
            ground_truth: None,
            logged_size: None,
            centres: Vec::new(),
        }
    }

    /// Draws `ground_truth` (camera poses `T_wc` in its own world frame) beside the estimate,
    /// moved so that its pose at the first frame logged is the origin, as the estimate's.
    pub fn with_ground_truth(mut self, ground_truth: Trajectory) -> Self {
        self.ground_truth = Some(ground_truth).filter(|g| !g.is_empty());
        self
    }

    /// Sends everything logged so far and closes the recording (the file is complete once
    /// this returns).
    pub fn finish(self) -> io::Result<()> {
        self.rec.flush_blocking().map_err(io::Error::other)
    }

    /// Logs the ground truth relative to its pose nearest `timestamp`, once.
    fn log_ground_truth(&mut self, timestamp: f64) -> rerun::RecordingStreamResult<()> {
        let Some(gt) = self.ground_truth.take() else {
            return Ok(());
        };
        let anchor = gt
            .nearest(timestamp, f64::INFINITY)
            .map_or_else(Isometry3::identity, |(_, t_wc)| t_wc.inverse());
        let centres: Vec<[f32; 3]> = gt
            .poses
            .iter()
            .map(|(_, t_wc)| point_f32(&Point3::from((anchor * t_wc).translation.vector)))
            .collect();
        self.rec.log_static(
            GROUND_TRUTH,
            &LineStrips3D::new([centres]).with_colors([Color::from_rgb(120, 120, 255)]),
        )
    }

    /// The intrinsics for frames of `size`, logged (static) when the size is new.
    fn log_pinhole(&mut self, size: (usize, usize)) -> rerun::RecordingStreamResult<()> {
        if self.logged_size == Some(size) {
            return Ok(());
        }
        self.logged_size = Some(size);
        let k = self.camera.pinhole;
        let pinhole = Pinhole::from_focal_length_and_resolution(
            [k.fx as f32, k.fy as f32],
            [size.0 as f32, size.1 as f32],
        )
        .with_principal_point([k.cx as f32, k.cy as f32]);
        self.rec.log_static(IMAGE, &pinhole)
    }

    /// Logs one frame.
    fn log(&mut self, o: &Observed<'_>) -> rerun::RecordingStreamResult<()> {
        let (rec, estimate) = (&self.rec, o.estimate);
        rec.set_time_sequence("frame", i64::try_from(o.index).unwrap_or(i64::MAX));
        rec.set_duration_secs("time", o.frame.timestamp());
        if self.centres.is_empty() && estimate.status != TrackStatus::Lost {
            self.log_ground_truth(o.frame.timestamp())?;
        }
        let image = o.frame.image();
        let (width, height) = image.size();
        self.log_pinhole((width, height))?;
        let rec = &self.rec;
        rec.log(
            IMAGE,
            &Image::from_l8(image.data().to_vec(), [width as u32, height as u32]),
        )?;
        if estimate.status != TrackStatus::Lost {
            rec.log(CAMERA, &transform(&estimate.pose_wc))?;
            self.centres.push(point_f32(&Point3::from(
                estimate.pose_wc.translation.vector,
            )));
            rec.log(
                TRAJECTORY,
                &LineStrips3D::new([self.centres.as_slice()])
                    .with_colors([Color::from_rgb(255, 170, 0)]),
            )?;
        }
        if let Some(details) = o.details {
            let colours: Vec<Color> = if details.residuals.is_empty() {
                details
                    .roles
                    .iter()
                    .map(|&role| role_colour(role))
                    .collect()
            } else {
                let limit = details.residual_limit;
                details
                    .residuals
                    .iter()
                    .map(|&r| residual_colour(r, limit))
                    .collect()
            };
            rec.log(
                KEYPOINTS,
                &Points2D::new(details.keypoints.iter().copied())
                    .with_colors(colours)
                    .with_radii([2.0f32]),
            )?;
            rec.log(
                MAP_POINTS,
                &Points3D::new(details.map_points.iter().map(point_f32)),
            )?;
        }
        log_scalars(rec, estimate)
    }
}

/// The colour of a keypoint's role: inliers green, outliers red, unmatched grey.
pub fn role_colour(role: KeypointRole) -> Color {
    match role {
        KeypointRole::Inlier => Color::from_rgb(40, 220, 40),
        KeypointRole::Outlier => Color::from_rgb(230, 40, 40),
        KeypointRole::Unmatched => Color::from_rgb(150, 150, 150),
    }
}

/// The colour of a direct tracker's pixel of residual `r` (grey levels) under the inlier
/// bound `limit`: from green at `r = 0` through yellow at `|r| = limit` (the last inlier) to
/// red at `|r| >= 2 limit`.
pub fn residual_colour(r: f32, limit: f32) -> Color {
    let t = if limit > 0.0 {
        (r.abs() / (2.0 * limit)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    let ramp = |from: f32, to: f32, t: f32| (from + (to - from) * t).round() as u8;
    if t <= 0.5 {
        let t = 2.0 * t;
        Color::from_rgb(ramp(40.0, 230.0, t), ramp(220.0, 210.0, t), 40)
    } else {
        let t = 2.0 * t - 1.0;
        Color::from_rgb(230, ramp(210.0, 40.0, t), 40)
    }
}

/// The per-frame scalars and the status line of `estimate`.
fn log_scalars(
    rec: &RecordingStream,
    estimate: &FrameEstimate,
) -> rerun::RecordingStreamResult<()> {
    let q = &estimate.quality;
    rec.log(INLIERS, &Scalars::single(q.inliers as f64))?;
    rec.log(RESIDUAL, &Scalars::single(q.rmse))?;
    rec.log(TIME, &Scalars::single(q.ms))?;
    if let Some(pose_quality) = &estimate.pose_quality {
        let code = match pose_quality.verdict {
            Verdict::Ok => 0.0,
            Verdict::Unreliable => 1.0,
            Verdict::Failed => 2.0,
        };
        rec.log(VERDICT, &Scalars::single(code))?;
    }
    let text = match &estimate.message {
        Some(message) => format!("{}: {message}", estimate.status.as_str()),
        None => estimate.status.as_str().to_string(),
    };
    let level = match estimate.status {
        TrackStatus::Ok => "INFO",
        TrackStatus::Unreliable | TrackStatus::Reinitialised => "WARN",
        TrackStatus::Lost => "ERROR",
    };
    rec.log(STATUS, &TextLog::new(text).with_level(level))
}

/// Rerun's rigid transform of `t_wc` (the camera's pose in its parent, the world).
fn transform(t_wc: &Isometry3<f64>) -> Transform3D {
    let q = t_wc.rotation.quaternion();
    Transform3D::from_translation_rotation(
        point_f32(&Point3::from(t_wc.translation.vector)),
        Quaternion::from_xyzw([q.i as f32, q.j as f32, q.k as f32, q.w as f32]),
    )
}

/// A point in single precision, as Rerun stores positions.
fn point_f32(p: &Point3<f64>) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

impl FrameObserver for RerunSink {
    fn frame(&mut self, observed: &Observed<'_>) -> io::Result<()> {
        self.log(observed).map_err(io::Error::other)
    }
}
