//! Stereo feature tracker: metric poses of the left camera of a stereo rig.
//!
//! 1. The rig is rectified once, for the first frame's size (`rectified`: Bouguet's
//!    rectification; a rig rectified already, such as KITTI's, is used as it is). Each frame:
//!    both images in the rectified geometry, ORB on each, the left features matched along
//!    their rows in the right image, and every matched left feature's metric point
//!    `P = Z K^-1 [u, v, 1]`, `Z = f b / d`, in the rectified left camera, when its relative
//!    depth uncertainty `sigma_d / d` is at most `max_relative_depth_sigma`.
//! 2. The first frame is a keyframe at the origin whose stereo points start the map at once:
//!    no initialisation, the scale is the baseline's. A keyframe makes every stereo point of a
//!    feature that has no map point yet a map point. (ORB-SLAM2's rule, every point nearer
//!    than 40 baselines and farther ones only up to 100 new points, lost frames on the KITTI
//!    clips, whose close points leave the view within a few frames at 10 m/s.)
//! 3. Tracking: the local map's points (every point a window keyframe observes) are projected
//!    with the constant-velocity prediction and matched around their predicted pixels at the
//!    predicted pyramid level, each by its representative descriptor and by the one of the
//!    last frame that found it (near points change their look within a frame or two at
//!    driving speed); PnP RANSAC with Huber refinement (motion-only, each residual
//!    divided by its keypoint's level scale) gives `T_cw` (the shared local map and its
//!    search: `odometry::local_map`).
//! 4. A new keyframe is taken when the tracked ratio (inliers over those of the first frame
//!    tracked after the newest keyframe) falls under the policy's `min_overlap`, or on its
//!    rotation and residual tests; it
//!    observes the points it tracked, adds its own stereo points, refines the structure and
//!    culls points (the map's `maintain`) and, when
//!    `local_ba` is set (off by default), adjusts the window with stereo observations
//!    (`LocalMap::adjust_window`).
//! 5. When PnP fails the frame is lost and the map kept (`odometry::lost`); the motion model
//!    coasts (`odometry::coast`). The next frame is first relocated in the lost map from the
//!    coasted prediction (wide window, `min_keyframe_inliers` inliers), else it starts a new
//!    map at the motion model's pose: metric like the first, so no segment break in scale.
//!
//! The trajectory is the raw left camera's `T_wc`, first frame at the origin (the rectified
//! camera's poses turned back by the rectifying rotation).

mod config;
pub(crate) mod rectified;

use std::time::Instant;

use nalgebra::{Isometry3, Matrix3, Point3};
use thiserror::Error;
use vofront_core::rig::Rig;
use vofront_core::Camera;
use vofront_features::{FeatureError, Features, Orb};
use vofront_geometry::add_point_covariances;

use super::coast::Coasting;
use super::keyframe::KeyframeView;
use super::local_map::{LocalMap, MapRules, MapSearch, WIDE_WINDOW_FACTOR};
use super::lost::LostMap;
use super::mono::KEYPOINT_QUANTISATION_PX;
use super::observe::FrameDetails;
use super::{ms_since, FrameEstimate, FrameQuality, Located, PointLocator, TrackStatus, Tracker};
use crate::dataset::Frame;
use crate::error::VoError;
pub use config::StereoTrackerConfig;
pub use rectified::StereoFrameError;
use rectified::{DepthRule, Rectified, StereoView};

/// Why a stereo tracker could not be built.
#[derive(Debug, Error)]
pub enum StereoTrackerError {
    /// The rig has one camera.
    #[error("the stereo tracker needs a stereo rig (a left and a right camera)")]
    MonoRig,
    /// The ORB or stereo matching configuration is invalid.
    #[error("invalid stereo tracker configuration: {0}")]
    Features(#[from] FeatureError),
}

/// The first frame tracked against the newest keyframe: what later frames' keyframe tests
/// compare with.
#[derive(Debug, Clone, Copy)]
struct Reference {
    /// Its PnP inliers.
    inliers: usize,
    /// Its PnP residual RMSE, pixels.
    residual: f64,
}

/// Metric ORB tracker of a stereo rig (see the module documentation).
///
/// ```
/// use nalgebra::{Isometry3, Translation3};
/// use vofront::dataset::Frame;
/// use vofront::fixtures::driving::{DrivingSequence, FRAME_RATE};
/// use vofront::fixtures::image2d::to_gray8;
/// use vofront::odometry::stereo::{StereoTracker, StereoTrackerConfig};
/// use vofront::odometry::{TrackStatus, Tracker};
/// use vofront_core::rig::Rig;
///
/// // A rendered street drive seen by a rectified rig with a 0.5 m baseline.
/// let drive = DrivingSequence::new(3, 6);
/// let right_in_left = Isometry3::from(Translation3::new(0.5, 0.0, 0.0));
/// let rig = Rig::stereo(drive.camera, Isometry3::identity(), drive.camera, right_in_left).unwrap();
/// let mut tracker = StereoTracker::new(rig, StereoTrackerConfig::default()).unwrap();
/// let mut last = None;
/// for i in 0..6 {
///     let (w, h) = drive.size;
///     let right = drive.scene.render(&drive.camera, w, h, &(drive.poses_wc[i] * right_in_left));
///     let frame = Frame::new(i as f64 / FRAME_RATE, to_gray8(&drive.render(i).image), None)
///         .unwrap()
///         .with_right(to_gray8(&right.image))
///         .unwrap();
///     last = Some(tracker.track(&frame));
/// }
/// let last = last.unwrap();
/// assert_eq!(last.status, TrackStatus::Ok);
/// // Metric: the distance travelled since frame 0, in metres.
/// let truth = drive.poses_wc[0].inverse() * drive.poses_wc[5];
/// let error = (last.pose_wc.translation.vector - truth.translation.vector).norm();
/// assert!(error < 0.05, "{error} m");
/// ```
pub struct StereoTracker {
    cfg: StereoTrackerConfig,
    orb: Orb,
    rig: Rig,
    /// The rectification, built for the first frame's size.
    rectified: Option<Rectified>,
    /// The tracked map and the first frame tracked after its newest keyframe.
    map: Option<(LocalMap, Option<Reference>)>,
    /// The motion model, coasting through lost frames.
    coast: Coasting,
    /// The map tracking was lost on, for relocation.
    lost: LostMap<LocalMap>,
    /// A map has been started once (a later start is a reinitialisation).
    started: bool,
    /// Frames given to `track` before the current one.
    frame: usize,
    /// The last frame's details, kept while an observer asks ([`Tracker::keep_details`]).
    details: Option<FrameDetails>,
}

impl StereoTracker {
    /// A tracker for the frames of the stereo `rig`; [`StereoTrackerError::MonoRig`] for a
    /// one-camera rig, [`StereoTrackerError::Features`] for an invalid configuration.
    pub fn new(rig: Rig, cfg: StereoTrackerConfig) -> Result<Self, StereoTrackerError> {
        if !rig.is_stereo() {
            return Err(StereoTrackerError::MonoRig);
        }
        cfg.stereo.validate()?;
        let orb = Orb::new(cfg.orb.clone())?;
        Ok(Self {
            cfg,
            orb,
            rig,
            rectified: None,
            map: None,
            coast: Coasting::default(),
            lost: LostMap::default(),
            started: false,
            frame: 0,
            details: None,
        })
    }

    fn map_rules(&self) -> MapRules {
        MapRules {
            window: self.cfg.window.max(2),
            triangulation_neighbours: 0,
            max_reprojection_px: self.cfg.max_reprojection_px,
            min_point_parallax_deg: 0.0,
        }
    }

    /// The rectified view of `frame`, the rectification built at the first frame.
    fn view(&mut self, frame: &Frame) -> Result<(StereoView, Camera), StereoFrameError> {
        let right = frame.right().ok_or(StereoFrameError::NoRightImage)?;
        let rectified = match self.rectified.take() {
            Some(r) => r,
            None => Rectified::new(&self.rig, frame.image().size())?,
        };
        let depth = DepthRule {
            disparity_sigma_px: KEYPOINT_QUANTISATION_PX,
            max_relative_sigma: self.cfg.max_relative_depth_sigma,
        };
        let view = rectified.view(&self.orb, &self.cfg.stereo, depth, frame.image(), right);
        let camera = rectified.camera;
        self.rectified = Some(rectified);
        Ok((view?, camera))
    }

    /// One frame from the motion model's prediction `predicted` (rectified `T_wc`).
    fn track_from(&mut self, frame: &Frame, predicted: Isometry3<f64>) -> FrameEstimate {
        let start = Instant::now();
        let (view, camera) = match self.view(frame) {
            Ok(v) => v,
            Err(e) => return FrameEstimate::lost(predicted, e.to_string(), start),
        };
        if let Some(details) = &mut self.details {
            details.detected(&view.features);
        }
        if let Some((map, reference)) = self.map.take() {
            return self.track_map(map, reference, view, &camera, predicted, start);
        }
        if let Some(map) = self.relocalised(&view, &camera, predicted) {
            let estimate = self.track_map(map, None, view, &camera, predicted, start);
            return FrameEstimate {
                message: Some("relocalised against the lost map".into()),
                ..estimate
            };
        }
        self.start_map(view, predicted, start)
    }

    /// A new map whose first keyframe is `view` at `t_wc` (the origin for the first frame,
    /// else the motion model's pose); lost when the frame has fewer than `min_map_points`
    /// stereo points.
    fn start_map(
        &mut self,
        view: StereoView,
        t_wc: Isometry3<f64>,
        start: Instant,
    ) -> FrameEstimate {
        let mut map = LocalMap::default();
        let StereoView {
            features,
            points,
            covariances,
            right,
            ..
        } = view;
        let k = map.push_keyframe(t_wc, features, self.frame);
        map.keyframes[k].right = right;
        let made = Self::add_stereo_points(&mut map, k, &points, &covariances);
        if made < self.cfg.min_map_points {
            let why = VoError::TooFew {
                what: "stereo points to start a map",
                got: made,
                need: self.cfg.min_map_points,
            };
            return FrameEstimate::lost(t_wc, why.to_string(), start);
        }
        let status = if self.started {
            TrackStatus::Reinitialised
        } else {
            TrackStatus::Ok
        };
        self.started = true;
        self.coast.motion.update(t_wc);
        self.map = Some((map, None));
        let why = "tracking lost: new metric map at the motion model's pose".to_string();
        FrameEstimate::started(t_wc, status, why, start)
    }

    /// Makes the stereo `points` (keyframe camera) of the features of keyframe `k` that have
    /// no map point yet map points, with their `covariances` (same camera) turned into the
    /// world frame (`R C R^T`); returns their count.
    fn add_stereo_points(
        map: &mut LocalMap,
        k: usize,
        points: &[Option<Point3<f64>>],
        covariances: &[Option<Matrix3<f64>>],
    ) -> usize {
        let kf = &map.keyframes[k];
        let t_wc = kf.t_wc;
        let free: Vec<(u32, Point3<f64>)> = points
            .iter()
            .enumerate()
            .filter_map(|(f, p)| Some((f as u32, (*p)?)))
            .filter(|(f, _)| kf.point_of[*f as usize].is_none())
            .collect();
        let r = t_wc.rotation.to_rotation_matrix();
        for (f, p) in &free {
            let id = map.add_point(t_wc * p, &[(k, *f)]);
            let covariance = covariances[*f as usize].map(|c| r * c * r.transpose());
            if let Some(point) = id.and_then(|id| map.points.get_mut(&id)) {
                point.covariance = covariance;
            }
        }
        free.len()
    }

    /// Tracks `view` against the local map from the prediction; a failure loses the frame
    /// and keeps the map for relocation.
    fn track_map(
        &mut self,
        mut map: LocalMap,
        reference: Option<Reference>,
        view: StereoView,
        camera: &Camera,
        predicted: Isometry3<f64>,
        start: Instant,
    ) -> FrameEstimate {
        let scale_factor = self.cfg.orb.scale_factor;
        let (query, positions, ids) =
            map.local_points(camera, &predicted.inverse(), view.size, scale_factor);
        let search = MapSearch {
            camera,
            matching: &self.cfg.matching,
            pnp: &self.cfg.pnp,
            window_px: self.cfg.window_px,
            relocate_window_px: self.cfg.relocate_window_px,
            min_inliers: self.cfg.min_inliers,
        };
        let Located {
            matches,
            points: world,
            sigmas,
            covariances,
            fit,
        } = search.locate(
            &query,
            &positions,
            Some(&map.covariances(&ids)),
            &view.features,
            predicted,
        );
        let mut fit = match fit {
            Ok(fit) => fit,
            Err(why) => {
                self.lost.lose(map, self.coast.motion.step_length());
                return FrameEstimate::lost(predicted, why.to_string(), start);
            }
        };
        // The map points' own depth noise, shared by the frames that see them (which the
        // residuals' sandwich cannot see), widens the covariance.
        add_point_covariances(
            &mut fit,
            camera,
            &world,
            &sigmas,
            &covariances,
            &self.cfg.pnp,
        );
        if let Some(details) = &mut self.details {
            details.mark(&matches, &fit.inliers);
        }
        let t_wc = fit.pose.inverse();
        let tracked = map.keep_inliers(&view.features, &matches, &world, &fit.inliers, &ids);
        let Some(last) = map.last() else {
            return FrameEstimate::lost(predicted, "empty map".into(), start);
        };
        let t_kf_w = last.t_wc.inverse();
        let mut depths: Vec<f64> = tracked.iter().map(|(_, _, p)| (t_kf_w * p).z).collect();
        let reference = reference.unwrap_or(Reference {
            inliers: tracked.len(),
            residual: fit.rmse_px,
        });
        let keyframe_view = KeyframeView {
            t_cur_kf: fit.pose * last.t_wc,
            median_depth: crate::robust::median_in_place(&mut depths).unwrap_or(1.0),
            overlap: tracked.len() as f64 / reference.inliers.max(1) as f64,
            residual: fit.rmse_px,
            first_residual: reference.residual,
        };
        let keyframe = self.cfg.keyframe.needs_keyframe(&keyframe_view);
        let quality = FrameQuality {
            keyframe,
            ms: 0.0,
            ..FrameQuality::of_pnp(&fit, matches.len())
        };
        let mut t_wc = t_wc;
        let reference = if keyframe {
            let StereoView {
                features,
                points,
                covariances,
                right,
                ..
            } = view;
            let k = map.push_keyframe(t_wc, features, self.frame);
            map.keyframes[k].right = right;
            for (m, id, _) in &tracked {
                map.observe(*id, k, m.train);
            }
            Self::add_stereo_points(&mut map, k, &points, &covariances);
            map.maintain(camera, &self.map_rules());
            if let (Some(ba), Some(r)) = (&self.cfg.local_ba, &self.rectified) {
                map.adjust_window(camera, Some(r.baseline), ba);
            }
            t_wc = map.last().map_or(t_wc, |kf| kf.t_wc);
            None
        } else {
            Some(reference)
        };
        self.coast.motion.update(t_wc);
        self.map = Some((map, reference));
        let estimate = FrameEstimate {
            pose_wc: t_wc,
            status: TrackStatus::Ok,
            quality: FrameQuality {
                ms: ms_since(start),
                ..quality
            },
            message: None,
            pose_quality: None,
        };
        estimate.judged(fit.quality)
    }

    /// The lost map, taken back, when `view` locates in it from the coasting prediction (the
    /// wide search window) with at least `min_keyframe_inliers` inliers.
    fn relocalised(
        &mut self,
        view: &StereoView,
        camera: &Camera,
        predicted: Isometry3<f64>,
    ) -> Option<LocalMap> {
        let scale_factor = self.cfg.orb.scale_factor;
        let locator = PointLocator {
            camera,
            matching: &self.cfg.matching,
            window_px: self.cfg.window_px * WIDE_WINDOW_FACTOR,
            pnp: &self.cfg.pnp,
            min_inliers: self.cfg.min_keyframe_inliers,
        };
        let current: &Features = &view.features;
        self.lost.relocate(|map| {
            let t_cw = predicted.inverse();
            let (query, positions, ids) =
                map.project_points(camera, &t_cw, view.size, scale_factor);
            locator
                .locate(
                    &query,
                    &positions,
                    Some(&map.covariances(&ids)),
                    current,
                    t_cw,
                )
                .fit
                .is_ok()
        })
    }
}

impl Tracker for StereoTracker {
    fn track(&mut self, frame: &Frame) -> FrameEstimate {
        if let Some(details) = &mut self.details {
            details.clear();
        }
        let predicted = self.coast.predict();
        let mut estimate = self.track_from(frame, predicted);
        self.frame += 1;
        let lost = estimate.status == TrackStatus::Lost && self.started;
        self.coast.end_frame(lost, predicted);
        // The rectified left camera is the raw one turned by R_left: T_wc = T_rr T_wc' T_rr^-1.
        if let Some(r) = &self.rectified {
            estimate.pose_wc = r.t_raw_rect * estimate.pose_wc * r.t_raw_rect.inverse();
        }
        if let (Some(details), Some(r)) = (&mut self.details, &self.rectified) {
            details.map_keypoints(|px| r.raw_pixel(px));
            if let Some((map, _)) = &self.map {
                let points = map.world_points().map(|p| r.t_raw_rect * p);
                details.map_points.extend(points);
            }
        }
        estimate
    }

    fn needs_right(&self) -> bool {
        true
    }

    /// Left keypoints (rectified, drawn in the raw left image) as PnP inliers, outliers or
    /// unmatched, and the local map's points.
    fn keep_details(&mut self, keep: bool) {
        self.details = keep.then(FrameDetails::default);
    }

    fn details(&self) -> Option<&FrameDetails> {
        self.details.as_ref()
    }
}
