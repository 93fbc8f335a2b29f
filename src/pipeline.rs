//! One obvious entry point per job, on the images a user has.
//!
//! - [`TwoViewEstimator::relative_pose`]: ORB on both frames, kNN-2 Hamming matching with the
//!   ratio test, essential / homography RANSAC with model selection, chirality and refinement;
//!   the pose `T_21` has a unit translation (monocular scale is unknown).
//! - Direct alignment lives in [`crate::direct`]: `align_translation(&Image<f32>, &Image<f32>,
//!   &cfg)` and `align_se3(&RgbdFrame, &Image<f32>, &prior, &cfg)`; an 8-bit grey image becomes
//!   their `f32` grey levels by [`Image::to_f32`], a depth map already is an `Image<f32>`.
//! - Running the feature and direct estimators on one pair, each failing on its own, with a
//!   recommendation: [`crate::two_view::estimate`].
//!
//! [`VoError`] lives in [`crate::error`] (re-exported here for the old path).

use std::time::Instant;

use vofront_core::Camera;
use vofront_features::{match_descriptors, Features, Match, MatchConfig, Orb, OrbConfig};
use vofront_geometry::{estimate_relative_pose, RelativePose, RelativePoseConfig};
use vofront_image::Image;

pub use crate::error::VoError;
use crate::timing::ms_since;

/// Wall-clock time of each stage of [`TwoViewEstimator::relative_pose`], milliseconds; the
/// `ms` object of the `two-view` JSON (`matching` spelt `match` there).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct FeatureTimings {
    /// ORB on both images.
    pub detect: f64,
    /// Descriptor matching.
    #[serde(rename = "match")]
    pub matching: f64,
    /// RANSAC, model selection, pose recovery and refinement.
    pub estimate: f64,
    /// Everything.
    pub total: f64,
}

/// The feature-based relative pose and everything it was computed from.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FeaturePose {
    /// Pose `T_21` (unit translation), inliers, model, parallax.
    pub estimate: RelativePose,
    /// ORB features of frame 1 and frame 2.
    pub features: [Features; 2],
    /// Ratio-test matches, query = frame 1, train = frame 2; `estimate.inliers[i]` refers to
    /// `matches[i]`.
    pub matches: Vec<Match>,
    /// Time per stage.
    pub timings: FeatureTimings,
}

/// The feature-based two-view estimator (two images in, one relative pose out; the
/// sequential trackers are [`crate::odometry::Tracker`]): configuration of each stage.
///
/// ```
/// use vofront::fixtures::image2d::to_gray8;
/// use vofront::fixtures::scene::{default_camera, pose_wc, Scene};
/// use vofront::pipeline::TwoViewEstimator;
/// let room = Scene::box_room(3);
/// let (t_w1, t_w2) = (pose_wc([0.0; 3], 0.0, 0.0, 0.0), pose_wc([0.15, 0.0, 0.05], -0.04, 0.0, 0.0));
/// let cam = default_camera();
/// let img1 = to_gray8(&room.render(&cam, 640, 480, &t_w1).image);
/// let img2 = to_gray8(&room.render(&cam, 640, 480, &t_w2).image);
/// let fit = TwoViewEstimator::default().relative_pose(&img1, &img2, &cam).unwrap();
/// let truth = t_w2.inverse() * t_w1;
/// assert!(fit.estimate.rotation().angle_to(&truth.rotation).to_degrees() < 0.5);
/// ```
#[derive(Debug, Clone, Default)]
pub struct TwoViewEstimator {
    /// ORB detector and descriptor.
    pub orb: OrbConfig,
    /// Matching filters (ratio 0.75 by default).
    pub matching: MatchConfig,
    /// Robust relative-pose estimation.
    pub geometry: RelativePoseConfig,
}

/// Level-0 pixel of feature `i` (the `f32` detector coordinates widened to the `f64` of the
/// geometry crate).
pub(crate) fn feature_pixel(f: &Features, i: u32) -> nalgebra::Vector2<f64> {
    nalgebra::Vector2::new(f64::from(f.xs()[i as usize]), f64::from(f.ys()[i as usize]))
}

/// The pixels `(x1, x2)` of `matches` from the features `f1` (queries) to `f2` (train).
pub(crate) fn matched_pixels(
    f1: &Features,
    f2: &Features,
    matches: &[Match],
) -> (Vec<nalgebra::Vector2<f64>>, Vec<nalgebra::Vector2<f64>>) {
    matches
        .iter()
        .map(|m| (feature_pixel(f1, m.query), feature_pixel(f2, m.train)))
        .unzip()
}

impl TwoViewEstimator {
    /// A tracker keeping at most `n_features` ORB features per image, other settings default.
    pub fn with_features(n_features: usize) -> Self {
        Self {
            orb: OrbConfig {
                n_features,
                ..OrbConfig::default()
            },
            ..Self::default()
        }
    }

    /// Relative pose `T_21` of two frames from the same `camera` (pixels through its lens model).
    pub fn relative_pose(
        &self,
        img1: &Image<u8>,
        img2: &Image<u8>,
        camera: &Camera,
    ) -> Result<FeaturePose, VoError> {
        let start = Instant::now();
        let orb = Orb::new(self.orb.clone())?;
        let (f1, f2) = rayon::join(
            || orb.detect_and_describe(img1),
            || orb.detect_and_describe(img2),
        );
        let (f1, f2) = (f1?, f2?);
        let detect = ms_since(start);
        let t_match = Instant::now();
        let matches = match_descriptors(f1.descriptors(), f2.descriptors(), &self.matching);
        let matching = ms_since(t_match);
        let t_estimate = Instant::now();
        let (x1, x2) = matched_pixels(&f1, &f2, &matches);
        let estimate = estimate_relative_pose(&x1, &x2, camera, &self.geometry)?;
        let timings = FeatureTimings {
            detect,
            matching,
            estimate: ms_since(t_estimate),
            total: ms_since(start),
        };
        Ok(FeaturePose {
            estimate,
            features: [f1, f2],
            matches,
            timings,
        })
    }
}
