//! Sequences: the stateful `Odometry` tracker and `run_odometry` over a dataset folder.

use std::path::PathBuf;
use std::sync::Mutex;

use nalgebra::Isometry3;
use numpy::PyArray2;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use vofront::core::rig::Rig;
use vofront::dataset::{Dataset, Frame};
use vofront::odometry::registry::{OdometryError, Session, TrackerKind, TrackerOptions};
use vofront::odometry::run::{FrameRecord, RunControl};
use vofront::odometry::{FrameEstimate, Tracker};
use vofront::trajectory::Trajectory;

use crate::convert::{array2, bad, camera, depth, gray8, json_to_py, pose, pose_matrix};
use crate::errors::{dataset_error, failed, release};
use crate::eval::{stats_dict, tum_rows};

/// A registry error: `ValueError` for a bad name, a dataset without the depth or the stereo
/// rig the method needs, `VofrontError` otherwise.
fn odometry_error(e: OdometryError) -> PyErr {
    match e {
        OdometryError::UnknownTracker(_)
        | OdometryError::NoDepth { .. }
        | OdometryError::NoStereo { .. } => PyValueError::new_err(e.to_string()),
        _ => failed(e),
    }
}

/// The tracker `method` names (`direct`, `feature-rgbd`, `mono`, `stereo`, `direct-stereo`,
/// `direct-mono`, or an alias).
pub fn tracker_kind(method: &str) -> PyResult<TrackerKind> {
    method.parse().map_err(odometry_error)
}

/// `a` unless it is absent or Python's None.
fn given<'a, 'py>(a: Option<&'a Bound<'py, PyAny>>) -> Option<&'a Bound<'py, PyAny>> {
    a.filter(|a| !a.is_none())
}

/// A frame estimate as a dict: `timestamp`, `pose_wc` (4x4 camera-to-world), `status`
/// (`ok`, `unreliable`, `lost`, `reinitialised`), `quality` {`inliers`, `inlier_ratio`, `rmse`,
/// `iterations`, `covariance_trace`, `keyframe`, `ms`}, `message` (why it was lost, or None),
/// `pose_quality`: the quality record of the estimate behind the pose (`verdict`, `reasons`,
/// support, `sigma`, covariance and sigmas, as in `two_view`), None without one.
fn estimate_dict<'py>(
    py: Python<'py>,
    timestamp: f64,
    e: &FrameEstimate,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("timestamp", timestamp)?;
    out.set_item("pose_wc", pose_matrix(py, &e.pose_wc))?;
    out.set_item("status", e.status.as_str())?;
    let q = &e.quality;
    let quality = PyDict::new(py);
    quality.set_item("inliers", q.inliers)?;
    quality.set_item("inlier_ratio", q.inlier_ratio)?;
    quality.set_item("rmse", q.rmse)?;
    quality.set_item("iterations", q.iterations)?;
    quality.set_item("covariance_trace", q.covariance_trace)?;
    quality.set_item("keyframe", q.keyframe)?;
    quality.set_item("ms", q.ms)?;
    out.set_item("quality", quality)?;
    out.set_item("message", e.message.as_deref())?;
    let pose_quality = match &e.pose_quality {
        Some(q) => Some(json_to_py(
            py,
            &serde_json::to_value(q).map_err(|e| bad(e.to_string()))?,
        )?),
        None => None,
    };
    out.set_item("pose_quality", pose_quality)?;
    Ok(out)
}

/// Frame-by-frame visual odometry with one of the library's trackers.
///
/// `method`: `direct` (RGB-D photometric SE(3) to the keyframe), `feature-rgbd` (ORB + depth
/// + PnP RANSAC), `mono` (monocular ORB, scale arbitrary; `feature` is its former name,
/// still accepted), `stereo` (ORB on a stereo pair, metric), `direct-stereo` (photometric
/// SE(3) with depth from the stereo disparity, metric) or `direct-mono` (sparse photometric
/// SE(3) to keyframes with inverse-depth filters, scale arbitrary), as
/// `vofront odometry --method`. `K`
/// 3x3 pixels, `dist` OpenCV `(k1, k2, p1, p2, k3)`; `depth_scale` divides uint16 depth maps
/// into metres. The stereo methods need the rig: the right camera `K_right`, `dist_right`
/// (the left camera's when None) and its pose in the left camera frame, `T_left_right` (4x4,
/// metres) or, for a rectified pair, `baseline` (metres: the right camera `baseline` along
/// the left camera's x axis).
#[pyclass(module = "vofront")]
pub struct Odometry {
    method: TrackerKind,
    /// Locked while a frame is tracked (the GIL is released then).
    tracker: Mutex<Box<dyn Tracker + Send>>,
    depth_scale: f64,
    /// Timestamp of every frame tracked, in order.
    timestamps: Vec<f64>,
}

#[pymethods]
impl Odometry {
    #[new]
    #[pyo3(signature = (
        method, K, dist = None, depth_scale = 5000.0, baseline = None, K_right = None,
        dist_right = None, T_left_right = None
    ))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn new(
        method: &str,
        K: &Bound<'_, PyAny>,
        dist: Option<&Bound<'_, PyAny>>,
        depth_scale: f64,
        baseline: Option<f64>,
        K_right: Option<&Bound<'_, PyAny>>,
        dist_right: Option<&Bound<'_, PyAny>>,
        T_left_right: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let method = tracker_kind(method)?;
        let camera = camera(K, dist)?;
        let options = TrackerOptions::default();
        let tracker = if method.needs_right() {
            let right = match K_right {
                Some(k) => self::camera(k, dist_right)?,
                None => camera,
            };
            let right_in_left = match (T_left_right, baseline) {
                (Some(t), None) => pose(t, "T_left_right")?,
                (None, Some(b)) if b.is_finite() && b != 0.0 => Isometry3::translation(b, 0.0, 0.0),
                _ => {
                    return Err(bad(format!(
                        "the {method} method needs the rig: give either T_left_right (4x4) or a \
                         non-zero baseline (metres)"
                    )))
                }
            };
            let rig = Rig::stereo(camera, Isometry3::identity(), right, right_in_left)
                .map_err(|e| bad(e.to_string()))?;
            method.build_for_rig(&rig, &options)
        } else {
            method.build(camera, &options)
        }
        .map_err(odometry_error)?;
        Ok(Self {
            method,
            tracker: Mutex::new(tracker),
            depth_scale,
            timestamps: Vec::new(),
        })
    }

    /// Tracks the next frame: grey `image` (uint8 or float32; the left image of a stereo
    /// pair), `depth` (uint16 raw units or float metres; required by `direct` and
    /// `feature-rgbd`), `timestamp` in seconds (the frame number when None). For `stereo` and
    /// `direct-stereo` the second argument is the grey right image: `track(left, right,
    /// timestamp)` (or `right=`). Returns the frame estimate dict (`pose_wc` is `T_wc` of the
    /// (left) camera, the first frame at the origin).
    #[pyo3(signature = (image, depth = None, timestamp = None, right = None))]
    fn track<'py>(
        &mut self,
        py: Python<'py>,
        image: &Bound<'py, PyAny>,
        depth: Option<&Bound<'py, PyAny>>,
        timestamp: Option<f64>,
        right: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let img = gray8(image, "image")?;
        let (depth, right) = if self.method.needs_right() {
            let right = match (given(depth), given(right)) {
                (Some(r), None) | (None, Some(r)) => gray8(r, "right")?,
                _ => return Err(bad("right: this method needs one right image per frame")),
            };
            (None, Some(right))
        } else {
            (depth, None)
        };
        let depth = match depth.filter(|d| !d.is_none()) {
            Some(d) => Some(self::depth(d, self.depth_scale, "depth")?),
            None if self.method.needs_depth() => {
                return Err(bad("depth: this method needs a depth map for every frame"))
            }
            None => None,
        };
        let timestamp = timestamp.unwrap_or(self.timestamps.len() as f64);
        let mut frame = Frame::new(timestamp, img, depth).map_err(|e| bad(e.to_string()))?;
        if let Some(right) = right {
            frame = frame.with_right(right).map_err(|e| bad(e.to_string()))?;
        }
        let tracker = &self.tracker;
        let estimate = release(py, || {
            let mut tracker = tracker
                .lock()
                .map_err(|_| failed("the tracker failed on an earlier frame"))?;
            Ok(tracker.track(&frame))
        })?;
        self.timestamps.push(timestamp);
        estimate_dict(py, timestamp, &estimate)
    }

    /// Late estimates made by the last `track` call for earlier frames: the monocular tracker
    /// reports the frames its initialisation waits through lost, then locates them in the map
    /// once it exists. A list of `(frame, estimate dict)`, `frame` the index of the replaced
    /// frame (0: the first tracked), oldest first; each list is handed over once.
    fn revised<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<(usize, Bound<'py, PyDict>)>> {
        let revised = self
            .tracker
            .lock()
            .map_err(|_| failed("the tracker failed on an earlier frame"))?
            .revised();
        let newest = self.timestamps.len().saturating_sub(1);
        revised
            .into_iter()
            .filter_map(|(back, e)| Some((newest.checked_sub(back)?, e)))
            .map(|(frame, e)| Ok((frame, estimate_dict(py, self.timestamps[frame], &e)?)))
            .collect()
    }

    /// How many of the most recent frames may still be revised (a caller writing estimates as
    /// it goes holds them back until `revised` settles them or this falls to 0).
    #[getter]
    fn pending(&self) -> PyResult<usize> {
        Ok(self
            .tracker
            .lock()
            .map_err(|_| failed("the tracker failed on an earlier frame"))?
            .pending())
    }

    /// Number of frames tracked so far.
    #[getter]
    fn frames(&self) -> usize {
        self.timestamps.len()
    }
}

/// Tracks a TUM RGB-D, KITTI or EuRoC folder as `vofront odometry` does (the same camera
/// choice, tracker and evaluation).
///
/// Returns a dict: `trajectory` (N, 8) TUM rows `t tx ty tz qx qy qz qw` of the tracked
/// frames (camera-to-world), `frames` (one estimate dict per frame; an unreadable frame has
/// `status` `unreadable` and its `message`), `summary` counts, `camera` (its `source`), and with
/// ground truth `ground_truth` (M, 8) of the CAMERA (EuRoC body poses times `T_BS`, what the
/// trajectory is compared with) and `ate` (statistics in metres, aligned as the CLI aligns:
/// SE(3), Sim(3) for `mono` and `direct-mono`; None with an `ate_error` message when it cannot
/// be computed).
/// `stereo` and `direct-stereo` need a folder with a stereo rig (KITTI `image_1/`, EuRoC
/// `cam1/`) and are built from its calibration.
#[pyfunction]
#[pyo3(signature = (dataset_path, method = "direct", K = None, dist = None, max_frames = None))]
#[allow(non_snake_case)]
pub fn run_odometry<'py>(
    py: Python<'py>,
    dataset_path: PathBuf,
    method: &str,
    K: Option<&Bound<'py, PyAny>>,
    dist: Option<&Bound<'py, PyAny>>,
    max_frames: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let method = tracker_kind(method)?;
    let dataset = release(py, || Dataset::open(&dataset_path).map_err(dataset_error))?;
    let given = match K.filter(|k| !k.is_none()) {
        Some(k) => Some((camera(k, dist)?, "K argument")),
        None => None,
    };
    let session = Session::new(dataset, method, given).map_err(odometry_error)?;
    let mut tracker = session
        .tracker(&TrackerOptions::default())
        .map_err(odometry_error)?;
    let (out, evaluation) = release(py, || {
        let control = RunControl {
            max_frames,
            stop: None,
        };
        let mut no_sink = |_: &FrameRecord| Ok::<(), std::io::Error>(());
        let out = session
            .run(tracker.as_mut(), &control, &mut no_sink)
            .map_err(odometry_error)?;
        let evaluation = session.evaluate(&out.trajectory);
        Ok((out, evaluation))
    })?;
    let result = PyDict::new(py);
    result.set_item("trajectory", trajectory_array(py, &out.trajectory))?;
    let frames = PyList::empty(py);
    for r in &out.records {
        let d = match &r.estimate {
            Ok(e) => estimate_dict(py, r.timestamp, e)?,
            Err(why) => {
                let d = PyDict::new(py);
                d.set_item("timestamp", r.timestamp)?;
                d.set_item("status", "unreadable")?;
                d.set_item("message", why.to_string())?;
                d
            }
        };
        d.set_item("index", r.index)?;
        frames.append(d)?;
    }
    result.set_item("frames", frames)?;
    let s = &out.summary;
    let summary = PyDict::new(py);
    summary.set_item("frames", s.frames)?;
    summary.set_item("tracked", out.trajectory.len())?;
    summary.set_item("lost", s.lost)?;
    summary.set_item("reinitialised", s.reinitialised)?;
    summary.set_item("unreliable", s.unreliable)?;
    summary.set_item("unreadable", s.unreadable)?;
    summary.set_item("keyframes", s.keyframes)?;
    summary.set_item("mean_ms", s.mean_ms)?;
    result.set_item("summary", summary)?;
    let camera = PyDict::new(py);
    camera.set_item("source", session.camera_origin.to_string())?;
    result.set_item("camera", camera)?;
    if let Some(evaluation) = evaluation {
        result.set_item(
            "ground_truth",
            trajectory_array(py, &evaluation.ground_truth),
        )?;
        match evaluation.ate {
            Ok(a) => result.set_item("ate", stats_dict(py, &a.stats)?)?,
            Err(e) => {
                result.set_item("ate", py.None())?;
                result.set_item("ate_error", e.to_string())?;
            }
        }
    }
    Ok(result)
}

/// A trajectory as (N, 8) TUM rows.
pub fn trajectory_array<'py>(py: Python<'py>, t: &Trajectory) -> Bound<'py, PyArray2<f64>> {
    array2(py, t.len(), 8, tum_rows(t))
}
