//! The summary of one sequence run: the `vofront odometry --json` object, as a library type
//! built from the [`Session`], the [`RunOutput`] and the [`Evaluation`] against the camera
//! ground truth.

use serde::Serialize;
use vofront_core::Camera;

use super::Entry;
use crate::eval::{AteResult, RotationScale, RpeResult, Stats};
use crate::odometry::registry::{CameraOrigin, Evaluation, Session};
use crate::odometry::run::{RunOutput, RunSummary};

/// The summary of a run (`vofront odometry --json`; keys documented in the README).
#[derive(Debug, Clone, Serialize)]
pub struct OdometryReport {
    /// The folder that was opened.
    pub dataset: String,
    /// Its format, lower case (`tum`, `kitti`, `euroc`, `images`).
    pub format: String,
    /// The camera the frames were tracked with and where it came from.
    pub camera: CameraReport,
    /// The tracker's name ([`crate::odometry::registry::TrackerKind::name`]).
    pub method: &'static str,
    /// Frames attempted.
    pub frames: usize,
    /// Frames in the trajectory.
    pub tracked: usize,
    /// Frames lost.
    pub lost: usize,
    /// Frames where tracking restarted.
    pub reinitialised: usize,
    /// Frames tracked with an `unreliable` verdict.
    pub unreliable: usize,
    /// Frames that could not be read.
    pub unreadable: usize,
    /// Keyframes taken.
    pub keyframes: usize,
    /// Mean time per read frame, milliseconds; `None` when no frame was read.
    pub ms_per_frame: Option<f64>,
    /// Frames per second; `None` when nothing was tracked.
    pub fps: Option<f64>,
    /// The run was stopped before the last frame.
    pub interrupted: bool,
    /// Tracking was lost and never recovered.
    pub lost_for_good: bool,
    /// ATE against the camera ground truth; `None` without ground truth.
    pub ate: Option<Entry<AteReport>>,
    /// RPE between consecutive poses; `None` without ground truth.
    pub rpe: Option<Entry<RpeReport>>,
    /// The files the run wrote.
    pub outputs: Outputs,
}

/// The camera of a run: its source and its intrinsics.
#[derive(Debug, Clone, Serialize)]
pub struct CameraReport {
    /// Where the camera came from (flags, the dataset's calibration, the default).
    pub source: String,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Lens coefficients in the model's order.
    pub distortion: Vec<f64>,
    /// `radial-tangential` or `equidistant`.
    pub distortion_model: &'static str,
}

impl CameraReport {
    /// The report of `camera`, which came from `origin`.
    pub fn new(camera: &Camera, origin: &CameraOrigin) -> Self {
        let (k, d) = (camera.pinhole, camera.distortion);
        Self {
            source: origin.to_string(),
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            distortion: d.coefficients(),
            distortion_model: d.model_name(),
        }
    }
}

/// ATE statistics (metres) with the number of associated poses and the alignment.
#[derive(Debug, Clone, Serialize)]
pub struct AteReport {
    /// evo's statistics of the translation errors.
    #[serde(flatten)]
    pub stats: Stats,
    /// Associated poses.
    pub pairs: usize,
    /// `se3`, `sim3` or `none`.
    pub alignment: String,
}

impl AteReport {
    /// The report of `ate`, computed after `alignment` (`se3`, `sim3` or `none`).
    pub fn new(ate: &AteResult, alignment: String) -> Self {
        Self {
            stats: ate.stats,
            pairs: ate.pairs.len(),
            alignment,
        }
    }
}

/// RPE statistics of consecutive poses.
#[derive(Debug, Clone, Serialize)]
pub struct RpeReport {
    /// Translation errors, metres.
    pub translation: Stats,
    /// Rotation errors, degrees.
    pub rotation_deg: Stats,
    /// Estimated over true rotation; `None` when the ground truth does not rotate.
    pub rotation_scale: Option<RotationScale>,
}

impl RpeReport {
    /// The report of `rpe`.
    pub fn new(rpe: &RpeResult) -> Self {
        Self {
            translation: rpe.translation,
            rotation_deg: rpe.rotation_deg,
            rotation_scale: rpe.rotation_scale,
        }
    }
}

/// The files a run wrote (paths as given).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Outputs {
    /// The TUM trajectory.
    pub trajectory: String,
    /// The per-frame metrics CSV.
    pub metrics: String,
    /// The g2o pose graph, if asked for.
    pub graph: Option<String>,
    /// The trajectory plot, if asked for.
    pub plot: Option<String>,
}

impl OdometryReport {
    /// The summary of `out`, the run of `session`, with its `evaluation` (if the dataset has
    /// ground truth) and the files written.
    pub fn new(
        session: &Session,
        out: &RunOutput,
        evaluation: Option<&Evaluation>,
        outputs: Outputs,
    ) -> Self {
        let s = &out.summary;
        let alignment = evaluation.map(|e| format!("{:?}", e.alignment).to_lowercase());
        Self {
            dataset: session.dataset.root.display().to_string(),
            format: format!("{:?}", session.dataset.kind).to_lowercase(),
            camera: CameraReport::new(&session.camera, &session.camera_origin),
            method: session.kind.name(),
            frames: s.frames,
            tracked: out.trajectory.len(),
            lost: s.lost,
            reinitialised: s.reinitialised,
            unreliable: s.unreliable,
            unreadable: s.unreadable,
            keyframes: s.keyframes,
            ms_per_frame: (s.frames > s.unreadable).then_some(s.mean_ms),
            fps: s.frames_per_second(),
            interrupted: s.interrupted,
            lost_for_good: RunSummary::lost_for_good(&out.records),
            ate: evaluation.map(|e| {
                Entry::of(&e.ate, |a| {
                    AteReport::new(a, alignment.clone().unwrap_or_default())
                })
            }),
            rpe: evaluation.map(|e| Entry::of(&e.rpe, RpeReport::new)),
            outputs,
        }
    }
}
