//! RGB-D feature tracker: ORB matched to the keyframe, whose features carry 3D points from its
//! depth map, then PnP RANSAC with robust motion-only refinement.
//!
//! The keyframe's points `P_kf` (metres, keyframe camera frame) are predicted in the current
//! image at `pi(K T_cur_kf' P_kf)` with the constant-velocity guess `T_cur_kf'`; each is
//! matched only to current features within `window_px` of that prediction (brute force when
//! too few are found, after a jump), and PnP estimates `T_cur_kf` from the matches, so that
//! `T_wc = T_w_kf T_cur_kf^-1`. The matching and PnP are then repeated once around that
//! estimate: when the guess is several frames off (dropped frames make the constant velocity
//! overshoot), the first window picks wrong neighbours and PnP can settle 10 cm away with
//! hundreds of consistent-looking inliers; matching around the estimate removes them.

use std::time::Instant;

use nalgebra::{Isometry3, Point3};
use vofront_core::Camera;
use vofront_features::{Features, MatchConfig, Orb, OrbConfig};
use vofront_geometry::pnp::PnpConfig;

use super::keyframe::{KeyframePolicy, KeyframeView};
use super::observe::FrameDetails;
use super::{
    feature_pixel, ms_since, FrameEstimate, FrameQuality, KeyframeSlot, Located, PointLocator,
    TrackStatus, Tracker,
};
use crate::dataset::Frame;
use crate::error::VoError;

/// Settings of [`FeatureRgbdTracker`].
#[derive(Debug, Clone)]
pub struct FeatureRgbdConfig {
    /// ORB settings (1000 features by default, enough for tracking).
    pub orb: OrbConfig,
    /// Matching filters.
    pub matching: MatchConfig,
    /// Search radius around each predicted position, pixels.
    pub window_px: f32,
    /// PnP RANSAC and refinement.
    pub pnp: PnpConfig,
    /// When to take a new keyframe.
    pub keyframe: KeyframePolicy,
    /// Fewest PnP inliers for a frame to count as tracked.
    pub min_inliers: usize,
    /// Depth range accepted for keyframe points, metres.
    pub depth_range: (f64, f64),
}

impl Default for FeatureRgbdConfig {
    fn default() -> Self {
        Self {
            orb: OrbConfig {
                n_features: 1000,
                ..OrbConfig::default()
            },
            matching: MatchConfig {
                ratio: Some(0.8),
                ..MatchConfig::default()
            },
            window_px: 24.0,
            pnp: PnpConfig::default(),
            keyframe: KeyframePolicy::default(),
            min_inliers: 25,
            depth_range: (0.1, 12.0),
        }
    }
}

struct Keyframe {
    features: Features,
    points: Vec<Option<Point3<f64>>>,
    with_depth: usize,
    t_wc: Isometry3<f64>,
    median_depth: f64,
    first_residual: Option<f64>,
}

/// Frame-to-keyframe ORB + PnP tracker for RGB-D sequences.
///
/// ```
/// use vofront::dataset::Frame;
/// use vofront::fixtures::image2d::to_gray8;
/// use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
/// use vofront::geometry::Pinhole;
/// use vofront::odometry::{TrackStatus, Tracker};
/// use vofront::odometry::feature_rgbd::{FeatureRgbdConfig, FeatureRgbdTracker};
///
/// // Four 320x240 RGB-D frames of a rendered room along a known camera path (T_wc).
/// let mut camera = default_camera();
/// camera.pinhole = Pinhole::new(262.5, 262.5, 159.5, 119.5).unwrap();
/// let (room, poses) = (Scene::box_room(5), room_trajectory(4));
/// let frames: Vec<Frame> = poses
///     .iter()
///     .enumerate()
///     .map(|(i, pose)| {
///         let view = room.render(&camera, 320, 240, pose);
///         Frame::new(i as f64 / 30.0, to_gray8(&view.image), Some(view.depth)).unwrap()
///     })
///     .collect();
///
/// let mut tracker = FeatureRgbdTracker::new(camera, FeatureRgbdConfig::default()).unwrap();
/// let last = frames.iter().map(|f| tracker.track(f)).last().unwrap();
/// assert_eq!(last.status, TrackStatus::Ok);
/// // The first frame is the origin: compare with the true motion since frame 0.
/// let truth = poses[0].inverse() * poses[3];
/// let error = (last.pose_wc.translation.vector - truth.translation.vector).norm();
/// assert!(error < 0.01, "{error} m off after {:.3} m", truth.translation.vector.norm());
/// ```
pub struct FeatureRgbdTracker {
    cfg: FeatureRgbdConfig,
    orb: Orb,
    camera: Camera,
    slot: KeyframeSlot<Keyframe>,
    /// The last frame's details, kept while an observer asks ([`Tracker::keep_details`]).
    details: Option<FrameDetails>,
}

impl FeatureRgbdTracker {
    /// A tracker for frames of `camera`; fails on an invalid ORB configuration.
    pub fn new(
        camera: Camera,
        cfg: FeatureRgbdConfig,
    ) -> Result<Self, vofront_features::FeatureError> {
        let orb = Orb::new(cfg.orb.clone())?;
        Ok(Self {
            cfg,
            orb,
            camera,
            slot: KeyframeSlot::default(),
            details: None,
        })
    }

    fn make_keyframe(
        &self,
        frame: &Frame,
        features: Features,
        t_wc: Isometry3<f64>,
    ) -> Result<Keyframe, VoError> {
        let depth = frame.depth().ok_or(VoError::NoDepth)?;
        let (lo, hi) = self.cfg.depth_range;
        let points: Vec<Option<Point3<f64>>> = (0..features.len())
            .map(|i| {
                let (x, y) = (features.xs()[i].round(), features.ys()[i].round());
                let z = depth.get(x as usize, y as usize).map_or(0.0, |&d| d as f64);
                if !(z > lo && z < hi) {
                    return None;
                }
                let n = self
                    .camera
                    .pixel_to_normalized(&feature_pixel(&features, i as u32))?;
                Some(Point3::new(n.x * z, n.y * z, z))
            })
            .collect();
        let mut depths: Vec<f64> = points.iter().flatten().map(|p| p.z).collect();
        let with_depth = depths.len();
        if with_depth < self.cfg.min_inliers {
            return Err(VoError::TooFew {
                what: "features with depth",
                got: with_depth,
                need: self.cfg.min_inliers,
            });
        }
        let median_depth = crate::robust::median_in_place(&mut depths).unwrap_or(1.0);
        Ok(Keyframe {
            features,
            points,
            with_depth,
            t_wc,
            median_depth,
            first_residual: None,
        })
    }
}

impl Tracker for FeatureRgbdTracker {
    fn track(&mut self, frame: &Frame) -> FrameEstimate {
        if let Some(details) = &mut self.details {
            details.clear();
        }
        let estimate = self.track_frame(frame);
        if let (Some(details), Some(kf)) = (&mut self.details, &self.slot.keyframe) {
            details
                .map_points
                .extend(kf.points.iter().flatten().map(|p| kf.t_wc * p));
        }
        estimate
    }

    fn keep_details(&mut self, keep: bool) {
        self.details = keep.then(FrameDetails::default);
    }

    fn details(&self) -> Option<&FrameDetails> {
        self.details.as_ref()
    }
}

impl FeatureRgbdTracker {
    /// One frame against the keyframe (a new keyframe when there is none or tracking failed).
    fn track_frame(&mut self, frame: &Frame) -> FrameEstimate {
        let start = Instant::now();
        let predicted = self.slot.predict();
        let features = match self.orb.detect_and_describe(frame.image()) {
            Ok(f) => f,
            Err(e) => {
                return self.slot.restart(
                    Err(VoError::from(e)),
                    predicted,
                    "no features".into(),
                    start,
                )
            }
        };
        if let Some(details) = &mut self.details {
            details.detected(&features);
        }
        let Some(kf) = self.slot.keyframe.as_mut() else {
            let made = self.make_keyframe(frame, features, predicted);
            return self
                .slot
                .restart(made, predicted, "no keyframe".into(), start);
        };
        let prior = predicted.inverse() * kf.t_wc;
        let locator = PointLocator {
            camera: &self.camera,
            matching: &self.cfg.matching,
            window_px: self.cfg.window_px,
            pnp: &self.cfg.pnp,
            min_inliers: self.cfg.min_inliers,
        };
        let first = locator.locate(&kf.features, &kf.points, None, &features, prior);
        // Second pass around the first estimate (see the module documentation).
        let Located { matches, fit, .. } = match &first.fit {
            Ok(f) => locator.locate(&kf.features, &kf.points, None, &features, f.pose),
            Err(_) => first,
        };
        let fit = match fit {
            Ok(fit) => fit,
            Err(why) => {
                let made = self.make_keyframe(frame, features, predicted);
                return self.slot.restart(made, predicted, why.to_string(), start);
            }
        };
        if let Some(details) = &mut self.details {
            details.mark(&matches, &fit.inliers);
        }
        let t_wc = kf.t_wc * fit.pose.inverse();
        let first_residual = *kf.first_residual.get_or_insert(fit.rmse_px);
        let view = KeyframeView {
            t_cur_kf: fit.pose,
            median_depth: kf.median_depth,
            overlap: fit.inlier_count() as f64 / kf.with_depth.max(1) as f64,
            residual: fit.rmse_px,
            first_residual,
        };
        self.slot.motion.update(t_wc);
        let quality = FrameQuality::of_pnp(&fit, matches.len());
        let keyframe = if self.cfg.keyframe.needs_keyframe(&view) {
            match self.make_keyframe(frame, features, t_wc) {
                Ok(new_kf) => {
                    self.slot.keyframe = Some(new_kf);
                    true
                }
                Err(_) => false,
            }
        } else {
            false
        };
        let quality = FrameQuality {
            keyframe,
            ms: ms_since(start),
            ..quality
        };
        FrameEstimate {
            pose_wc: t_wc,
            status: TrackStatus::Ok,
            quality,
            message: None,
            pose_quality: None,
        }
        .judged(fit.quality)
    }
}
