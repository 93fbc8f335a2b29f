//! The tracker registry and the wiring shared by the application front-ends (`vofront
//! odometry`, Python's `Odometry` and `run_odometry`): which trackers exist and what they need
//! ([`TrackerKind`]), which camera a dataset is tracked with ([`choose_camera`]), the depth
//! check, the run, and the evaluation against the camera ground truth ([`Session`]).
//!
//! Adding a tracker is one [`TrackerKind`] variant (its arms in the `match`es below) and its
//! module; every front-end then offers it under its [`TrackerKind::name`].
//!
//! ```
//! use vofront::dataset::Dataset;
//! use vofront::odometry::registry::{Session, TrackerKind, TrackerOptions};
//! use vofront::odometry::run::{FrameRecord, RunControl};
//! use vofront_fixtures::scene::{default_camera, room_trajectory, Scene};
//! use vofront_fixtures::tum::write_tum_sequence;
//!
//! let dir = std::env::temp_dir().join(format!("vofront-doc-registry-{}", std::process::id()));
//! let poses = room_trajectory(6);
//! write_tum_sequence(&dir, &Scene::box_room(2), &default_camera(), (640, 480), &poses).unwrap();
//! let kind: TrackerKind = "direct".parse().unwrap();
//! let session = Session::new(Dataset::open(&dir).unwrap(), kind, None).unwrap();
//! assert_eq!(session.camera_origin.to_string(), "default: tum-ros");
//! let mut tracker = session.tracker(&TrackerOptions::default()).unwrap();
//! let mut sink = |_: &FrameRecord| Ok::<(), std::io::Error>(());
//! let out = session.run(tracker.as_mut(), &RunControl::default(), &mut sink).unwrap();
//! let evaluation = session.evaluate(&out.trajectory).unwrap(); // TUM: ground truth present
//! assert!(evaluation.ate.unwrap().stats.rmse < 0.005); // metres, SE(3)-aligned
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;

use thiserror::Error;
use vofront_core::rig::Rig;
use vofront_core::Camera;
use vofront_features::FeatureError;

use super::direct::{DirectTracker, DirectTrackerConfig};
use super::direct_mono::{DirectMonoConfig, DirectMonoError, DirectMonoTracker};
use super::direct_stereo::{DirectStereoConfig, DirectStereoError, DirectStereoTracker};
use super::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
use super::mono::{MonoConfig, MonoTracker};
use super::observe::FrameObserver;
use super::run::{run_observed, run_with, FrameSink, RunControl, RunError, RunOutput};
use super::stereo::{StereoTracker, StereoTrackerConfig, StereoTrackerError};
use super::Tracker;
use crate::dataset::{CameraSource, Dataset};
use crate::eval::{ate, rpe, Alignment, AteResult, EvalConfig, EvalError, RpeResult};
use crate::trajectory::Trajectory;

/// The library's sequence trackers, by the name every front-end uses (`vofront odometry
/// --method NAME`, Python `Odometry(NAME, K)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TrackerKind {
    /// `direct`: RGB-D photometric SE(3) alignment to keyframes
    /// ([`super::direct::DirectTracker`]).
    Direct,
    /// `feature-rgbd`: ORB matched to keyframes with depth, PnP RANSAC and robust refinement
    /// ([`super::feature_rgbd::FeatureRgbdTracker`]).
    FeatureRgbd,
    /// `mono` (alias `feature`): monocular ORB, two-view initialisation, triangulated points,
    /// PnP; the trajectory's scale is arbitrary ([`super::mono::MonoTracker`]).
    Mono,
    /// `stereo`: ORB on a rectified stereo pair, metric map points at once, PnP tracking
    /// against the local map; metric poses ([`super::stereo::StereoTracker`]). Needs a stereo
    /// rig ([`Dataset::rig`]).
    Stereo,
    /// `direct-stereo`: photometric SE(3) alignment with affine brightness to keyframes whose
    /// depth comes from the semi-dense stereo disparity; metric poses
    /// ([`super::direct_stereo::DirectStereoTracker`]). Needs a stereo rig.
    DirectStereo,
    /// `direct-mono` (alias `direct_mono`): sparse photometric SE(3) alignment with affine
    /// brightness to keyframes whose points carry inverse-depth filters refined by epipolar
    /// search, started from a two-view feature estimate; the trajectory's scale is arbitrary
    /// ([`super::direct_mono::DirectMonoTracker`]).
    DirectMono,
}

/// How a tracker measures a frame against its reference: by matched features (its
/// [`super::FrameQuality`] counts correspondences and its `rmse` is a reprojection error in
/// pixels) or directly on the pixels (`inliers` counts pixels and `rmse` is the photometric
/// residual in grey levels).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Paradigm {
    /// Keypoints matched and located (ORB, PnP).
    Feature,
    /// Photometric alignment of pixels.
    Direct,
}

impl Paradigm {
    /// Lower-case name (`feature`, `direct`), the JSON spelling.
    pub fn name(self) -> &'static str {
        match self {
            Self::Feature => "feature",
            Self::Direct => "direct",
        }
    }

    /// Unit of [`super::FrameQuality::rmse`] for trackers of this paradigm.
    pub fn residual_unit(self) -> &'static str {
        match self {
            Self::Feature => "px",
            Self::Direct => "grey levels",
        }
    }
}

/// Options a front-end may set on any tracker; `None` keeps the tracker's default.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrackerOptions {
    /// ORB feature budget per frame of the feature trackers (ignored by `direct` and `direct-stereo`).
    pub features: Option<usize>,
}

impl TrackerKind {
    /// Every tracker, in the order front-ends list them.
    pub const ALL: &'static [TrackerKind] = &[
        Self::Direct,
        Self::FeatureRgbd,
        Self::Mono,
        Self::Stereo,
        Self::DirectStereo,
        Self::DirectMono,
    ];

    /// The name front-ends use (`--method NAME`, JSON `method`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Direct => "direct",
            Self::FeatureRgbd => "feature-rgbd",
            Self::Mono => "mono",
            Self::Stereo => "stereo",
            Self::DirectStereo => "direct-stereo",
            Self::DirectMono => "direct-mono",
        }
    }

    /// Other spellings accepted by [`TrackerKind::from_str`] (`feature` is the former name of
    /// `mono`).
    pub fn aliases(self) -> &'static [&'static str] {
        match self {
            Self::Direct => &[],
            Self::FeatureRgbd => &["feature_rgbd"],
            Self::Mono => &["feature"],
            Self::Stereo => &[],
            Self::DirectStereo => &["direct_stereo"],
            Self::DirectMono => &["direct_mono"],
        }
    }

    /// One line saying what the tracker does and needs.
    pub fn description(self) -> &'static str {
        match self {
            Self::Direct => "RGB-D photometric SE(3) alignment to keyframes",
            Self::FeatureRgbd => {
                "RGB-D: ORB matched to keyframes with depth, PnP RANSAC and robust refinement"
            }
            Self::Mono => {
                "Monocular ORB: two-view initialisation, triangulated points, PnP; arbitrary \
                 scale (alias: feature)"
            }
            Self::Stereo => {
                "Stereo ORB: metric map points from the rectified pair, PnP against the local \
                 map; needs a stereo rig"
            }
            Self::DirectStereo => {
                "Stereo direct: photometric SE(3) alignment to keyframes with depth from the \
                 stereo disparity; needs a stereo rig"
            }
            Self::DirectMono => {
                "Monocular direct: sparse photometric SE(3) alignment to keyframes with \
                 inverse-depth filters; arbitrary scale (alias: direct_mono)"
            }
        }
    }

    /// True when every frame must carry a depth map.
    pub fn needs_depth(self) -> bool {
        match self {
            Self::Direct | Self::FeatureRgbd => true,
            Self::Mono | Self::Stereo | Self::DirectStereo | Self::DirectMono => false,
        }
    }

    /// True when every frame must carry its right image: the tracker is built from the
    /// dataset's stereo rig ([`TrackerKind::build_for_rig`]) and frames are loaded with
    /// [`Dataset::load_stereo`].
    pub fn needs_right(self) -> bool {
        matches!(self, Self::Stereo | Self::DirectStereo)
    }

    /// The alignment its trajectory is evaluated with: Sim(3) when the scale is unobservable
    /// (monocular), SE(3) otherwise.
    pub fn alignment(self) -> Alignment {
        match self {
            Self::Direct | Self::FeatureRgbd | Self::Stereo | Self::DirectStereo => Alignment::Se3,
            Self::Mono | Self::DirectMono => Alignment::Sim3,
        }
    }

    /// Whether it matches features or aligns pixels ([`Paradigm`]).
    pub fn paradigm(self) -> Paradigm {
        match self {
            Self::Direct | Self::DirectStereo | Self::DirectMono => Paradigm::Direct,
            Self::FeatureRgbd | Self::Mono | Self::Stereo => Paradigm::Feature,
        }
    }

    /// Checks that `dataset` holds what this kind needs: [`OdometryError::NoDepth`] when it
    /// needs depth and no frame has any, [`OdometryError::NoStereo`] when it needs a stereo
    /// rig and the dataset has none.
    pub fn check(self, dataset: &Dataset) -> Result<(), OdometryError> {
        if self.needs_depth() && dataset.frames.iter().all(|f| f.depth.is_none()) {
            return Err(OdometryError::NoDepth {
                dataset: dataset.root.clone(),
                kind: self,
            });
        }
        if self.needs_right() && !dataset.rig.as_ref().is_some_and(Rig::is_stereo) {
            return Err(OdometryError::NoStereo {
                dataset: dataset.root.clone(),
                kind: self,
            });
        }
        Ok(())
    }

    /// A tracker of this kind for frames of `camera`, its default configuration with
    /// `options` applied; a kind that needs a stereo rig ([`TrackerKind::needs_right`]) fails
    /// with [`OdometryError::NeedsStereoRig`] (use [`TrackerKind::build_for_rig`]).
    pub fn build(
        self,
        camera: Camera,
        options: &TrackerOptions,
    ) -> Result<Box<dyn Tracker + Send>, OdometryError> {
        Ok(match self {
            Self::Direct => Box::new(DirectTracker::new(camera, DirectTrackerConfig::default())),
            Self::FeatureRgbd => {
                let mut cfg = FeatureRgbdConfig::default();
                cfg.orb.n_features = options.features.unwrap_or(cfg.orb.n_features);
                Box::new(FeatureRgbdTracker::new(camera, cfg)?)
            }
            Self::Mono => {
                let mut cfg = MonoConfig::default();
                cfg.orb.n_features = options.features.unwrap_or(cfg.orb.n_features);
                Box::new(MonoTracker::new(camera, cfg)?)
            }
            Self::DirectMono => {
                let mut cfg = DirectMonoConfig::default();
                cfg.orb.n_features = options.features.unwrap_or(cfg.orb.n_features);
                Box::new(DirectMonoTracker::new(camera, cfg)?)
            }
            Self::Stereo | Self::DirectStereo => {
                return Err(OdometryError::NeedsStereoRig { kind: self })
            }
        })
    }

    /// A tracker of this kind for frames of `rig`: the stereo tracker from the whole rig,
    /// every other kind from its left camera ([`TrackerKind::build`]); a kind that needs a
    /// stereo rig fails with [`OdometryError::NeedsStereoRig`] on a mono one.
    pub fn build_for_rig(
        self,
        rig: &Rig,
        options: &TrackerOptions,
    ) -> Result<Box<dyn Tracker + Send>, OdometryError> {
        if !self.needs_right() {
            return self.build(*rig.left(), options);
        }
        if !rig.is_stereo() {
            return Err(OdometryError::NeedsStereoRig { kind: self });
        }
        if self == Self::DirectStereo {
            let cfg = DirectStereoConfig::default();
            return Ok(Box::new(DirectStereoTracker::new(*rig, cfg)?));
        }
        let mut cfg = StereoTrackerConfig::default();
        cfg.orb.n_features = options.features.unwrap_or(cfg.orb.n_features);
        Ok(Box::new(StereoTracker::new(*rig, cfg)?))
    }

    /// `name` as listed for an unknown one: every name, then the aliases.
    fn known() -> String {
        let names: Vec<&str> = Self::ALL.iter().map(|k| k.name()).collect();
        let aliases: Vec<&str> = Self::ALL
            .iter()
            .flat_map(|k| k.aliases())
            .copied()
            .collect();
        format!("{}; aliases {}", names.join(", "), aliases.join(", "))
    }
}

impl fmt::Display for TrackerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for TrackerKind {
    type Err = OdometryError;

    /// The tracker named `name` or one of its aliases (exact spelling).
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .iter()
            .copied()
            .find(|k| k.name() == name || k.aliases().contains(&name))
            .ok_or_else(|| OdometryError::UnknownTracker(name.to_string()))
    }
}

/// `--method NAME` of the `vofront` program: the names, aliases and descriptions above.
#[cfg(feature = "cli")]
impl clap::ValueEnum for TrackerKind {
    fn value_variants<'a>() -> &'a [Self] {
        Self::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(
            clap::builder::PossibleValue::new(self.name())
                .aliases(self.aliases().iter().copied())
                .help(self.description()),
        )
    }
}

/// Errors of the registry and of a [`Session`].
#[derive(Debug, Error)]
pub enum OdometryError {
    /// No tracker has this name or alias.
    #[error("unknown tracker method '{0}' (known: {known})", known = TrackerKind::known())]
    UnknownTracker(String),
    /// The tracker's ORB configuration is invalid (e.g. a feature budget of 0).
    #[error("invalid tracker configuration: {0}")]
    Features(#[from] FeatureError),
    /// The tracker needs depth and no frame of the dataset has any.
    #[error("{}: the {kind} method needs depth, and this dataset has none", dataset.display())]
    NoDepth {
        /// The dataset folder.
        dataset: PathBuf,
        /// The tracker asked for.
        kind: TrackerKind,
    },
    /// The tracker needs a stereo rig and the dataset has one camera (or none known).
    #[error("{}: the {kind} method needs a stereo rig (KITTI image_1/ with P1, EuRoC cam1/), and this dataset has one camera", dataset.display())]
    NoStereo {
        /// The dataset folder.
        dataset: PathBuf,
        /// The tracker asked for.
        kind: TrackerKind,
    },
    /// The tracker needs a stereo rig and was given one camera.
    #[error("the {kind} method needs a stereo rig, not a single camera")]
    NeedsStereoRig {
        /// The tracker asked for.
        kind: TrackerKind,
    },
    /// The stereo tracker could not be built.
    #[error(transparent)]
    Stereo(#[from] StereoTrackerError),
    /// The direct stereo tracker could not be built.
    #[error(transparent)]
    DirectStereo(#[from] DirectStereoError),
    /// The direct monocular tracker could not be built.
    #[error(transparent)]
    DirectMono(#[from] DirectMonoError),
    /// The run ended early: a sink refused a record.
    #[error(transparent)]
    Run(#[from] RunError),
}

/// The camera of the `tum-ros` preset (ROS default for a Kinect, 640x480):
/// `fx = fy = 525`, `(cx, cy) = (319.5, 239.5)` pixels, no distortion.
pub fn default_camera() -> Camera {
    crate::presets::PRESETS[0].camera
}

/// Where the camera of a [`Session`] came from; [`fmt::Display`] says so in one phrase.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CameraOrigin {
    /// Given by the caller; the text says how (e.g. `command-line flags`).
    Given(String),
    /// The dataset's own calibration ([`Dataset::camera`], from [`Dataset::camera_source`]).
    Dataset(Option<CameraSource>),
    /// Neither: [`default_camera`], the `tum-ros` preset.
    Default,
}

impl fmt::Display for CameraOrigin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Given(how) => f.write_str(how),
            Self::Dataset(Some(source)) => source.fmt(f),
            Self::Dataset(None) => f.write_str("dataset calibration"),
            Self::Default => f.write_str("default: tum-ros"),
        }
    }
}

/// The camera to track `dataset` with: `given` (a camera and how it was given) first, then
/// the camera the dataset names (KITTI `calib.txt`, EuRoC `sensor.yaml`, a TUM folder name or
/// list header), then [`default_camera`].
pub fn choose_camera(given: Option<(Camera, &str)>, dataset: &Dataset) -> (Camera, CameraOrigin) {
    match (given, dataset.camera) {
        (Some((camera, how)), _) => (camera, CameraOrigin::Given(how.to_string())),
        (None, Some(camera)) => (camera, CameraOrigin::Dataset(dataset.camera_source.clone())),
        (None, None) => (default_camera(), CameraOrigin::Default),
    }
}

/// A dataset, the tracker kind chosen for it and the camera it is tracked with: what a
/// front-end needs to run a sequence and evaluate it the same way as every other front-end.
#[derive(Debug, Clone)]
pub struct Session {
    /// The sequence.
    pub dataset: Dataset,
    /// The tracker kind.
    pub kind: TrackerKind,
    /// The camera the frames are tracked with.
    pub camera: Camera,
    /// Where [`Session::camera`] came from.
    pub camera_origin: CameraOrigin,
}

/// ATE and RPE of a trajectory against the camera ground truth.
#[derive(Debug)]
pub struct Evaluation {
    /// The ground truth as camera poses `T_wc` ([`Dataset::camera_ground_truth`]: EuRoC body
    /// poses times `T_BS`).
    pub ground_truth: Trajectory,
    /// The alignment used, [`TrackerKind::alignment`].
    pub alignment: Alignment,
    /// Absolute trajectory error (metres), `alignment`-aligned.
    pub ate: Result<AteResult, EvalError>,
    /// Relative pose error between consecutive poses (metres, degrees), with the alignment of
    /// [`EvalConfig::for_rpe`].
    pub rpe: Result<RpeResult, EvalError>,
}

impl Session {
    /// The session of `kind` on `dataset`, the camera chosen by [`choose_camera`]; fails with
    /// [`OdometryError::NoDepth`] when `kind` needs depth and no frame has any, with
    /// [`OdometryError::NoStereo`] when it needs a stereo rig and the dataset has none
    /// ([`TrackerKind::check`]).
    pub fn new(
        dataset: Dataset,
        kind: TrackerKind,
        given: Option<(Camera, &str)>,
    ) -> Result<Self, OdometryError> {
        kind.check(&dataset)?;
        let (camera, camera_origin) = choose_camera(given, &dataset);
        Ok(Self {
            dataset,
            kind,
            camera,
            camera_origin,
        })
    }

    /// A fresh tracker of the session's kind and camera; a kind that needs a stereo rig is
    /// built from the dataset's rig (its calibration, not a given camera).
    pub fn tracker(
        &self,
        options: &TrackerOptions,
    ) -> Result<Box<dyn Tracker + Send>, OdometryError> {
        match (&self.dataset.rig, self.kind.needs_right()) {
            (Some(rig), true) => self.kind.build_for_rig(rig, options),
            _ => self.kind.build(self.camera, options),
        }
    }

    /// Tracks the dataset with `tracker` ([`run_with`]: bounded by `control`, every record
    /// handed to `sink` as it finishes).
    pub fn run(
        &self,
        tracker: &mut dyn Tracker,
        control: &RunControl<'_>,
        sink: &mut dyn FrameSink,
    ) -> Result<RunOutput, OdometryError> {
        Ok(run_with(&self.dataset, tracker, control, sink)?)
    }

    /// [`Session::run`] with an `observer` that sees every frame as it is tracked
    /// ([`run_observed`]).
    pub fn run_observed(
        &self,
        tracker: &mut dyn Tracker,
        control: &RunControl<'_>,
        sink: &mut dyn FrameSink,
        observer: &mut dyn FrameObserver,
    ) -> Result<RunOutput, OdometryError> {
        Ok(run_observed(
            &self.dataset,
            tracker,
            control,
            sink,
            observer,
        )?)
    }

    /// ATE and RPE of `trajectory` against the camera ground truth, associated within the
    /// dataset's [`Dataset::ground_truth_tolerance`] and aligned by [`TrackerKind::alignment`];
    /// `None` when the dataset has no ground truth.
    pub fn evaluate(&self, trajectory: &Trajectory) -> Option<Evaluation> {
        let ground_truth = self.dataset.camera_ground_truth()?;
        let alignment = self.kind.alignment();
        let cfg = EvalConfig {
            alignment,
            max_dt: self.dataset.ground_truth_tolerance,
        };
        Some(Evaluation {
            ate: ate(&ground_truth, trajectory, &cfg),
            rpe: rpe(&ground_truth, trajectory, &cfg.for_rpe()),
            ground_truth,
            alignment,
        })
    }
}

#[cfg(test)]
mod tests;
