//! Monocular feature tracker: two-view initialisation, a local map of keyframes and points,
//! PnP tracking against it, local bundle adjustment.
//!
//! 1. Initialisation (`init`): the first frame with enough features is the reference; later
//!    frames are matched to it until the parallax allows a two-view map. A frame with too few
//!    features is skipped (never made the reference), and a reference that no longer matches
//!    the current frame is replaced by it. The frames waited through are reported lost and
//!    pending ([`Tracker::pending`]); once the map exists each is located in it from the pose
//!    its index places between the two views (`locate`, `odometry::late`), and handed over as
//!    a late estimate ([`Tracker::revised`]).
//! 2. Tracking: every point of the local map (`map`: the points observed by the window of
//!    recent keyframes) is projected with the constant-velocity prediction `pi(K T_cw' P_w)`
//!    and matched to the current features around it, among those of the pyramid level it is
//!    expected at from the predicted distance; PnP RANSAC, the prediction its first
//!    hypothesis, with Huber refinement (motion-only; each residual divided by its keypoint's
//!    level scale `1.2^k`) gives `T_cw`, `T_wc = T_cw^-1`. When that pose moved the points by
//!    half the window or more from the prediction (the start of a turn: the window let
//!    through only a part of the right matches), they are matched again within the window
//!    around it. The points are then matched again in a narrow window (`relocate_window_px`)
//!    around the pose and PnP repeated from it; each time the pose with more inliers is kept.
//! 3. Keyframes are decided without metric units: a new one is taken when the median parallax
//!    of the tracked points between the last keyframe's and the current camera centres,
//!    `angle(P - C_kf, P - C_cur)`, reaches `keyframe_parallax_deg`, when the tracked ratio
//!    (inliers over the last keyframe's points) falls under the policy's `min_overlap`, when
//!    the next frame is forecast to track fewer than `min_keyframe_inliers` of those points
//!    at the ratio's mean fall since the keyframe (`keyframe::forecast_tracked`: a fast camera
//!    at a low frame rate loses half of them in one frame), or on the policy's rotation and
//!    residual tests, and only from a pose with at least
//!    `min_keyframe_inliers` inliers or a clean consensus (`keyframe_clean_ratio`): a weakly
//!    supported pose may be wrong, and points built on it would make later frames agree
//!    with the error. A keyframe adds observations, triangulates new points against its
//!    neighbours, refines the structure, culls points and runs the local bundle adjustment
//!    (`adjust`).
//! 4. When PnP fails, the frame first tries to start a new map at once with the newest window
//!    keyframe that initialises with it (enough parallax and points): the map is placed at
//!    that keyframe's pose, its scale joined to the lost map's, and the frame is tracked
//!    (`reinitialised`). Otherwise the frame is lost; the motion model coasts through lost
//!    frames (`odometry::coast`). Each later frame is first located against the lost map
//!    (`odometry::lost`) from that prediction (wide window, `min_keyframe_inliers` inliers):
//!    after a short fault the map is tracked again with its scale. Meanwhile initialisation
//!    starts again (from that frame if it has enough features), placed at the motion model's
//!    pose, with the new map's scale joined to the lost one where they overlap; where they do
//!    not (a segment break, said in the reinitialised frame's message), the new baseline is the
//!    motion model's median step length times the frames it spans, so that the trajectory
//!    keeps its speed.

mod adjust;
pub(crate) mod config;
mod init;
mod locate;
#[cfg(test)]
mod tests;

use std::time::Instant;

use nalgebra::{Isometry3, Point3};
use vofront_core::Camera;
use vofront_features::{Features, Orb};

use super::coast::Coasting;
use super::keyframe::{forecast_tracked, KeyframeView};
use super::late::{LateEstimates, Waiting};
use super::local_map::{LocalMap, MapRules, WIDE_WINDOW_FACTOR};
use super::lost::LostMap;
use super::observe::FrameDetails;
use super::{ms_since, FrameEstimate, FrameQuality, Located, PointLocator, TrackStatus, Tracker};
use crate::dataset::Frame;
pub use config::{MonoConfig, KEYPOINT_QUANTISATION_PX};
use init::{initialise, rescale, scale_from_motion, scale_to, InitRules};

/// Median over points `P` of the parallax angle `angle(P - c1, P - c2)`, degrees (0 without
/// points).
fn median_parallax_deg<'a>(
    c1: &Point3<f64>,
    c2: &Point3<f64>,
    points: impl Iterator<Item = &'a Point3<f64>>,
) -> f64 {
    let mut angles: Vec<f64> = points
        .map(|p| (p - c1).angle(&(p - c2)).to_degrees())
        .collect();
    crate::robust::median_in_place(&mut angles).unwrap_or(0.0)
}

enum State {
    /// Nothing seen yet, or just lost on a frame that could not serve as a reference.
    Empty,
    /// Waiting for enough parallax against `reference` at `t_wc`; `waiting`: from the
    /// reference's index, the later frames that could not initialise with it, located once a
    /// map exists.
    Initialising {
        reference: Features,
        t_wc: Isometry3<f64>,
        waiting: Waiting<Features>,
    },
    /// Tracking against the local map; the residual of the first frame after its keyframe.
    Tracking {
        map: LocalMap,
        first_residual: Option<f64>,
    },
}

/// Monocular ORB tracker with an arbitrary but consistent scale (per initialisation).
///
/// ```
/// use vofront::dataset::Frame;
/// use vofront::fixtures::driving::{DrivingSequence, FRAME_RATE};
/// use vofront::fixtures::image2d::to_gray8;
/// use vofront::core::lie::direction_angle_deg;
/// use vofront::odometry::mono::{MonoConfig, MonoTracker};
/// use vofront::odometry::{TrackStatus, Tracker};
///
/// // Eight grey frames of a rendered street drive with exact camera poses (T_wc).
/// let drive = DrivingSequence::new(3, 8);
/// let mut tracker = MonoTracker::new(drive.camera, MonoConfig::default()).unwrap();
/// let mut last = None;
/// for i in 0..8 {
///     let frame = Frame::new(i as f64 / FRAME_RATE, to_gray8(&drive.render(i).image), None).unwrap();
///     last = Some(tracker.track(&frame));
/// }
/// let last = last.unwrap();
/// assert_eq!(last.status, TrackStatus::Ok);
/// // The scale is arbitrary; the direction travelled since frame 0 is not.
/// let truth = drive.poses_wc[0].inverse() * drive.poses_wc[7];
/// let angle = direction_angle_deg(&last.pose_wc.translation.vector, &truth.translation.vector);
/// assert!(angle < 5.0, "{angle} deg");
/// ```
pub struct MonoTracker {
    cfg: MonoConfig,
    orb: Orb,
    camera: Camera,
    state: State,
    /// The motion model, coasting through lost frames.
    coast: Coasting,
    initialised_once: bool,
    /// The map before tracking was lost (frames are relocated in it, its points set the scale
    /// of the next map) and the step length then (the scale of a new map that shares no
    /// points with the lost one).
    lost: LostMap<LocalMap>,
    /// The frame count, and the late estimates of waited frames made by the last `track`
    /// call ([`Tracker::revised`]).
    late: LateEstimates,
    /// The last frame's details, kept while an observer asks ([`Tracker::keep_details`]).
    details: Option<FrameDetails>,
}

impl MonoTracker {
    /// A tracker for frames of `camera`; fails on an invalid ORB configuration.
    pub fn new(camera: Camera, cfg: MonoConfig) -> Result<Self, vofront_features::FeatureError> {
        let orb = Orb::new(cfg.orb.clone())?;
        Ok(Self {
            cfg,
            orb,
            camera,
            state: State::Empty,
            coast: Coasting::default(),
            initialised_once: false,
            lost: LostMap::default(),
            late: LateEstimates::default(),
            details: None,
        })
    }

    fn estimate(
        pose_wc: Isometry3<f64>,
        status: TrackStatus,
        quality: FrameQuality,
        message: Option<String>,
        start: Instant,
    ) -> FrameEstimate {
        FrameEstimate {
            pose_wc,
            status,
            quality: FrameQuality {
                ms: ms_since(start),
                ..quality
            },
            message,
            pose_quality: None,
        }
    }

    fn map_rules(&self) -> MapRules {
        MapRules {
            window: self.cfg.window.max(2),
            triangulation_neighbours: self.cfg.triangulation_neighbours.max(1),
            max_reprojection_px: self.cfg.max_reprojection_px,
            min_point_parallax_deg: self.cfg.min_point_parallax_deg,
        }
    }

    /// Tracks `current` against the local map from the prediction; a failure loses the map.
    fn track_map(
        &mut self,
        mut map: LocalMap,
        first_residual: Option<f64>,
        current: Features,
        size: (usize, usize),
        predicted: Isometry3<f64>,
        start: Instant,
    ) -> FrameEstimate {
        let scale_factor = self.cfg.orb.scale_factor;
        let (query, positions, ids) =
            map.local_points(&self.camera, &predicted.inverse(), size, scale_factor);
        let located = self.locate_in_map(&query, &positions, &current, predicted);
        let Located {
            matches,
            points: world,
            fit,
            ..
        } = located;
        let fit = match fit {
            Ok(fit) => fit,
            Err(why) => {
                self.lost.lose(map, self.coast.motion.step_length());
                if let Some(estimate) = self.restart_from_window(&current, start) {
                    return estimate;
                }
                if current.len() >= self.cfg.min_init_points {
                    self.state = self.initialising(current, predicted);
                }
                return FrameEstimate::lost(predicted, why.to_string(), start);
            }
        };
        if let Some(details) = &mut self.details {
            details.mark(&matches, &fit.inliers);
        }
        let mut t_wc = fit.pose.inverse();
        let tracked = map.keep_inliers(&current, &matches, &world, &fit.inliers, &ids);
        let Some(last) = map.last() else {
            return FrameEstimate::lost(predicted, "empty map".into(), start);
        };
        let last_points = last.point_of.iter().flatten().count();
        let t_kf_w = last.t_wc.inverse();
        let mut depths: Vec<f64> = tracked.iter().map(|(_, _, p)| (t_kf_w * p).z).collect();
        let first_residual = first_residual.unwrap_or(fit.rmse_px);
        let view = KeyframeView {
            t_cur_kf: fit.pose * last.t_wc,
            median_depth: crate::robust::median_in_place(&mut depths).unwrap_or(1.0),
            overlap: tracked.len() as f64 / last_points.max(1) as f64,
            residual: fit.rmse_px,
            first_residual,
        };
        let parallax = median_parallax_deg(
            &last.centre(),
            &Point3::from(t_wc.translation.vector),
            tracked.iter().map(|(_, _, p)| p),
        );
        // A weakly supported pose may be wrong; as a keyframe it would build new points on
        // that error, and later frames would agree with them: it only tracks.
        let pnp_quality = FrameQuality::of_pnp(&fit, matches.len());
        let supported = pnp_quality.inliers >= self.cfg.min_keyframe_inliers
            || pnp_quality.inlier_ratio >= self.cfg.keyframe_clean_ratio;
        // The tracked share falling so fast that the next frame would be left with fewer points
        // than a keyframe needs: a keyframe now, while the map can still be extended.
        let since = self.late.frame().saturating_sub(last.frame);
        let collapsing = forecast_tracked(last_points, view.overlap, since)
            < self.cfg.min_keyframe_inliers as f64;
        let keyframe = supported
            && (collapsing
                || parallax >= self.cfg.keyframe_parallax_deg
                || self.cfg.keyframe.needs_keyframe(&view));
        let quality = FrameQuality {
            keyframe,
            ..pnp_quality
        };
        let first_residual = if keyframe {
            let rules = self.map_rules();
            let k = map.push_keyframe(t_wc, current, self.late.frame());
            for (m, id, _) in &tracked {
                map.observe(*id, k, m.train);
            }
            map.triangulate_new(&self.camera, &self.cfg.matching, &rules);
            map.maintain(&self.camera, &rules);
            if let Some(ba) = &self.cfg.local_ba {
                map.adjust(&self.camera, ba);
            }
            t_wc = map.last().map_or(t_wc, |kf| kf.t_wc);
            None
        } else {
            Some(first_residual)
        };
        self.coast.motion.update(t_wc);
        self.state = State::Tracking {
            map,
            first_residual,
        };
        Self::estimate(t_wc, TrackStatus::Ok, quality, None, start).judged(fit.quality)
    }

    /// The map initialised from the reference at `t_w1`, `elapsed` frames before the current
    /// one, becomes the tracked map, its scale joined to the lost map's where they overlap;
    /// where they do not (a segment break), the baseline is set to `elapsed` steps of the
    /// motion model before the loss, so that the trajectory keeps its speed.
    fn start_map(
        &mut self,
        mut map: LocalMap,
        t_w1: &Isometry3<f64>,
        elapsed: usize,
        quality: FrameQuality,
        start: Instant,
    ) -> FrameEstimate {
        let (status, message) = if self.initialised_once {
            let joined = self.lost.take().and_then(|old| {
                scale_to(
                    &old,
                    &map,
                    t_w1,
                    &self.cfg.matching,
                    self.cfg.min_scale_matches,
                )
            });
            let message = match joined {
                Some(s) => {
                    rescale(&mut map, t_w1, s);
                    format!("new map, scale {s:.3} joined to the lost one")
                }
                None => match scale_from_motion(&map, self.lost.step(), elapsed) {
                    Some(s) => {
                        rescale(&mut map, t_w1, s);
                        "new map, scale not joined to the lost one (segment break), baseline \
                         from the motion model"
                            .into()
                    }
                    None => "new map, scale not joined to the lost one (segment break)".into(),
                },
            };
            (TrackStatus::Reinitialised, Some(message))
        } else {
            (TrackStatus::Ok, None)
        };
        self.initialised_once = true;
        let pose = map.last().map_or(*t_w1, |kf| kf.t_wc);
        // The initialising pair's motion, spread over the frames between them, predicts the
        // next frame.
        self.coast.motion.restart(t_w1, &pose, elapsed);
        self.state = State::Tracking {
            map,
            first_residual: None,
        };
        Self::estimate(pose, status, quality, message, start)
    }

    /// After a failed tracking attempt, a new map from `current` and the newest keyframe of
    /// the lost map with enough parallax (newest first), at once: the frame is not lost, and
    /// the new map starts at that keyframe's pose with its scale joined to the lost map's
    /// (`start_map`). `None` when no keyframe initialises.
    fn restart_from_window(&mut self, current: &Features, start: Instant) -> Option<FrameEstimate> {
        let rules = self.init_rules();
        let now = self.late.frame();
        let (new, t_w1, elapsed, quality, pose_quality) =
            self.lost.map()?.keyframes.iter().rev().find_map(|kf| {
                let (new, quality, pose_quality) =
                    initialise(&rules, &kf.features, &kf.t_wc, current, (kf.frame, now)).ok()?;
                Some((new, kf.t_wc, now - kf.frame, quality, pose_quality))
            })?;
        let estimate = self.start_map(new, &t_w1, elapsed, quality, start);
        Some(estimate.judged(pose_quality))
    }

    /// Waiting for an initialisation with `reference`, the current frame, at `t_wc`.
    fn initialising(&self, reference: Features, t_wc: Isometry3<f64>) -> State {
        State::Initialising {
            reference,
            t_wc,
            waiting: Waiting::from(self.late.frame()),
        }
    }

    /// The rules of a two-view initialisation.
    fn init_rules(&self) -> InitRules<'_> {
        InitRules {
            camera: &self.camera,
            matching: &self.cfg.matching,
            relative: &self.cfg.relative,
            min_points: self.cfg.min_init_points,
            min_parallax_deg: self.cfg.min_init_parallax_deg,
        }
    }

    /// The lost map, taken back, when `current` locates against it from the coasting
    /// prediction (the wide search window) with at least `min_keyframe_inliers` inliers: a
    /// short fault (a dark, blurred or corrupt frame) then costs no new map and no scale.
    fn relocalised(
        &mut self,
        current: &Features,
        size: (usize, usize),
        predicted: Isometry3<f64>,
    ) -> Option<LocalMap> {
        let scale_factor = self.cfg.orb.scale_factor;
        let locator = PointLocator {
            camera: &self.camera,
            matching: &self.cfg.matching,
            window_px: self.cfg.window_px * WIDE_WINDOW_FACTOR,
            pnp: &self.cfg.pnp,
            min_inliers: self.cfg.min_keyframe_inliers,
        };
        self.lost.relocate(|map| {
            let (query, positions, _) =
                map.project_points(locator.camera, &predicted.inverse(), size, scale_factor);
            let located = locator.locate(&query, &positions, None, current, predicted.inverse());
            located.fit.is_ok()
        })
    }
}

impl Tracker for MonoTracker {
    fn track(&mut self, frame: &Frame) -> FrameEstimate {
        self.late.begin_frame();
        if let Some(details) = &mut self.details {
            details.clear();
        }
        let predicted = self.coast.predict();
        let estimate = self.track_from(frame, predicted);
        self.late.end_frame();
        if let (Some(details), State::Tracking { map, .. }) = (&mut self.details, &self.state) {
            details.map_points.extend(map.world_points());
        }
        // A lost frame coasts on the motion model for a while (so that a new map is placed
        // where the camera has gone), then the model holds still.
        let lost = estimate.status == TrackStatus::Lost && self.initialised_once;
        self.coast.end_frame(lost, predicted);
        estimate
    }

    /// While initialising: the frames after the reference (located late once a map exists).
    fn pending(&self) -> usize {
        let waiting = match &self.state {
            State::Initialising { waiting, .. } => Some(waiting),
            _ => None,
        };
        self.late.pending(waiting)
    }

    fn revised(&mut self) -> Vec<(usize, FrameEstimate)> {
        self.late.take()
    }

    fn keep_details(&mut self, keep: bool) {
        self.details = keep.then(FrameDetails::default);
    }

    fn details(&self) -> Option<&FrameDetails> {
        self.details.as_ref()
    }
}

impl MonoTracker {
    /// One frame from the motion model's prediction `predicted` (`T_wc`).
    fn track_from(&mut self, frame: &Frame, predicted: Isometry3<f64>) -> FrameEstimate {
        let start = Instant::now();
        let current = match self.orb.detect_and_describe(frame.image()) {
            Ok(f) => f,
            Err(e) => return FrameEstimate::lost(predicted, e.to_string(), start),
        };
        if let Some(details) = &mut self.details {
            details.detected(&current);
        }
        let tracking = matches!(self.state, State::Tracking { .. });
        if !tracking && current.len() < self.cfg.min_init_points {
            // A featureless frame can neither start nor serve an initialisation: skip it.
            let why = format!(
                "initialising: {} features, {} needed (frame skipped)",
                current.len(),
                self.cfg.min_init_points
            );
            return FrameEstimate::lost(predicted, why, start);
        }
        if !tracking {
            if let Some(map) = self.relocalised(&current, frame.image().size(), predicted) {
                let size = frame.image().size();
                let estimate = self.track_map(map, None, current, size, predicted, start);
                return FrameEstimate {
                    message: Some("relocalised against the lost map (its scale kept)".into()),
                    ..estimate
                };
            }
        }
        match std::mem::replace(&mut self.state, State::Empty) {
            State::Empty => {
                let first = !self.initialised_once && self.coast.motion.predict().is_none();
                self.state = self.initialising(current, predicted);
                if first {
                    // The first frame defines the world frame: it is tracked by definition.
                    self.coast.motion.update(predicted);
                    let quality = FrameQuality {
                        keyframe: true,
                        ..FrameQuality::default()
                    };
                    Self::estimate(predicted, TrackStatus::Ok, quality, None, start)
                } else {
                    FrameEstimate::lost(predicted, "initialising: new reference".into(), start)
                }
            }
            State::Initialising {
                reference,
                t_wc,
                mut waiting,
            } => {
                let rules = self.init_rules();
                let (since, now) = (waiting.since(), self.late.frame());
                match initialise(&rules, &reference, &t_wc, &current, (since, now)) {
                    Ok((map, quality, pose_quality)) => {
                        let estimate = self
                            .start_map(map, &t_wc, now - since, quality, start)
                            .judged(pose_quality);
                        if let State::Tracking { map, .. } = &self.state {
                            let size = frame.image().size();
                            let at = (now, &estimate.pose_wc);
                            let revised = self.locate_waited(map, &waiting, &t_wc, at, size);
                            self.late.hand_over(revised);
                        }
                        estimate
                    }
                    Err(failure) => {
                        let keep =
                            failure.keep_reference && now - since <= self.cfg.max_init_frames;
                        self.state = if keep {
                            waiting.push(now, current);
                            State::Initialising {
                                reference,
                                t_wc,
                                waiting,
                            }
                        } else {
                            self.initialising(current, predicted)
                        };
                        FrameEstimate::lost(predicted, failure.why, start)
                    }
                }
            }
            State::Tracking {
                map,
                first_residual,
            } => {
                let size = frame.image().size();
                self.track_map(map, first_residual, current, size, predicted, start)
            }
        }
    }
}
