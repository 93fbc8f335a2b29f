//! Direct monocular tracker (`--method direct-mono`): sparse photometric SE(3) tracking with
//! affine brightness against keyframes whose points carry inverse-depth filters (SVO/DSO-style;
//! the parts are `vofront_direct::mono`); the trajectory's scale is arbitrary.
//!
//! 1. Start (`init`): the first frame is the reference; later frames are matched to it by
//!    ORB until the two-view pose ([`vofront_geometry::estimate_relative_pose`]) has the
//!    parallax and points to be trusted; its scale makes the median point depth 1. The
//!    reference becomes the first keyframe: the triangulated points are active at once, and
//!    one point per free block (by gradient, `vofront_direct::mono::select_points`) is an
//!    immature point with the prior `N(rho_median, rho_median^2)`, searched once along its
//!    epipolar segment in the current frame. The frames waited through are located late
//!    (`late`), by alignment from the pose their index puts between the two views.
//! 2. Each frame: `Se3Reference::align` (coarse to fine, robust, affine brightness) of the
//!    keyframe's active points from the constant-velocity prediction `T_cur_kf =
//!    T_wc'^-1 T_w_kf`; when it fails or its RMSE exceeds `retry_residual_growth` times the
//!    keyframe's first one, again from zero motion and from the prediction turned by
//!    `retry_turn_deg` about x and about y (and, when the mean grey level changed by more
//!    than `retry_gain_change`, from the prediction with that gain), keeping the lowest RMSE. `T_wc = T_w_kf T_cur_kf^-1`.
//! 3. Every point of the keyframe is then searched in the frame along its epipolar segment
//!    over `rho +- 2.5 sigma` and its filter updated; converged points become active, and the
//!    reference is rebuilt when they grew by `rebuild_growth`.
//! 4. A new keyframe (translation over the median depth, rotation, tracked ratio, residual
//!    growth: [`KeyframePolicy`](super::keyframe::KeyframePolicy)) is first refined with the
//!    window (`bundle`): the outgoing keyframe's active points, its pose and brightness, those
//!    of the `bundle_window` keyframes before it and of the new one are adjusted jointly by
//!    the photometric bundle ([`vofront_direct::mono::photometric_bundle`], the oldest two
//!    frames holding the gauge), the points it finds to be outliers dropped. The new
//!    keyframe, at its refined pose, takes the active points carried in (moved, projected,
//!    their filters transferred) and immature points in the blocks they leave free. The
//!    previous keyframe keeps its immature points in a window of `window` keyframes (and of
//!    those made fewer than `seed_frames` frames ago): they are still searched in each frame
//!    (from `T_cur_kf = T_wc^-1 T_w_kf`), and each that converges is carried into the newest
//!    keyframe (SVO's seeds).
//! 5. A frame whose position jumps away from the constant-velocity prediction (by more than
//!    `max_motion_jump` of the recent step length, when that step is at least
//!    `min_judged_step` of the median depth) has broken the map's scale: it and every later
//!    frame of the map are flagged [`Reason::Inconsistent`] (`unreliable`) until a new map.
//! 6. A frame that cannot be aligned is lost (the motion model coasts); it becomes the
//!    reference of a new start, placed at the coasted pose with the baseline the motion
//!    model's step length gives, and the frames until then are located late.
//!
//! The bundle is DSO's windowed optimisation without marginalisation: keyframes leaving the
//! window are dropped, not folded into a prior, and the frames between keyframes are not in
//! it (their poses, already reported, are not revised).

mod align;
mod bundle;
mod config;
mod init;
mod keyframe;

use std::collections::VecDeque;
use std::time::Instant;

use nalgebra::Isometry3;
use thiserror::Error;
use vofront_core::{Camera, Pinhole};
use vofront_direct::{Se3Config, Se3Result, Undistorter};
use vofront_features::{FeatureError, Features, Orb};
use vofront_image::Image;
use vofront_robust::Reason;

use bundle::{frame_state, refine_window, WindowFrame};
pub use config::DirectMonoConfig;
use init::two_view;
use keyframe::{prune_window, MonoKeyframe};

use super::coast::Coasting;
use super::keyframe::KeyframeView;
use super::late::{LateEstimates, Waiting};
use super::{ms_since, FrameEstimate, FrameQuality, TrackStatus, Tracker};
use crate::dataset::Frame;
use crate::error::VoError;

/// Why a direct monocular tracker could not be built.
#[derive(Debug, Error)]
pub enum DirectMonoError {
    /// The initialisation's ORB configuration is invalid.
    #[error(transparent)]
    Features(#[from] FeatureError),
    /// A setting out of its domain.
    #[error("invalid direct-mono configuration: {0}")]
    InvalidConfig(&'static str),
}

enum State {
    /// Nothing to start from.
    Empty,
    /// Waiting for a two-view start against `reference` (its pinhole `image`, at `t_wc`).
    Initialising {
        features: Features,
        image: Image<f32>,
        t_wc: Isometry3<f64>,
        waiting: Waiting<Image<f32>>,
    },
    /// Tracking the keyframe; `T_cur_kf` of the last frame; the previous keyframes whose
    /// immature points are still refined (oldest first); those of the bundle (oldest first).
    Tracking {
        kf: Box<MonoKeyframe>,
        last: Isometry3<f64>,
        window: VecDeque<MonoKeyframe>,
        bundle: VecDeque<WindowFrame>,
        /// The frame at which the map's scale was broken (a motion jump), if any.
        scale_broken: Option<usize>,
    },
}

/// Sparse direct monocular tracker (see the module documentation).
///
/// ```
/// use vofront::dataset::Frame;
/// use vofront::fixtures::driving::{DrivingSequence, FRAME_RATE};
/// use vofront::fixtures::image2d::to_gray8;
/// use vofront::core::lie::direction_angle_deg;
/// use vofront::odometry::direct_mono::{DirectMonoConfig, DirectMonoTracker};
/// use vofront::odometry::{TrackStatus, Tracker};
///
/// let drive = DrivingSequence::new(3, 10);
/// let mut tracker = DirectMonoTracker::new(drive.camera, DirectMonoConfig::default()).unwrap();
/// let mut last = None;
/// for i in 0..10 {
///     let frame = Frame::new(i as f64 / FRAME_RATE, to_gray8(&drive.render(i).image), None).unwrap();
///     last = Some(tracker.track(&frame));
/// }
/// let last = last.unwrap();
/// // Posed (`ok`, or `unreliable` with its reasons), not lost.
/// assert_ne!(last.status, TrackStatus::Lost);
/// let truth = drive.poses_wc[0].inverse() * drive.poses_wc[9];
/// let angle = direction_angle_deg(&last.pose_wc.translation.vector, &truth.translation.vector);
/// assert!(angle < 5.0, "{angle} deg");
/// ```
pub struct DirectMonoTracker {
    cfg: DirectMonoConfig,
    camera: Camera,
    /// The pinhole camera every image is brought to.
    pinhole: Camera,
    orb: Orb,
    undistorter: Option<Undistorter>,
    state: State,
    coast: Coasting,
    late: LateEstimates,
    /// A map has been started (a later start is a reinitialisation).
    started: bool,
    /// The world frame is defined (the first reference frame was taken): lost frames coast.
    origin: bool,
}

impl DirectMonoTracker {
    /// A tracker for frames of `camera`; fails on an invalid ORB or selection configuration.
    pub fn new(camera: Camera, cfg: DirectMonoConfig) -> Result<Self, DirectMonoError> {
        if cfg.select.block == 0 || cfg.select.levels == 0 || cfg.min_active_points == 0 {
            return Err(DirectMonoError::InvalidConfig(
                "select.block, select.levels and min_active_points must be positive",
            ));
        }
        let orb = Orb::new(cfg.orb.clone())?;
        Ok(Self {
            cfg,
            camera,
            pinhole: Camera::pinhole(camera.pinhole),
            orb,
            undistorter: None,
            state: State::Empty,
            coast: Coasting::default(),
            late: LateEstimates::default(),
            started: false,
            origin: false,
        })
    }

    fn k(&self) -> Pinhole {
        self.camera.pinhole
    }

    /// The frame's grey image in the pinhole geometry (the undistorter built at the first
    /// frame of a distorted camera).
    fn pinhole_image(&mut self, frame: &Frame) -> Result<Image<f32>, VoError> {
        let grey = frame.image().to_f32();
        if self.camera.distortion.is_identity() {
            return Ok(grey);
        }
        let (w, h) = grey.size();
        let u = match self.undistorter.take() {
            Some(u) if u.size() == (w, h) => u,
            _ => Undistorter::new(&self.camera, w, h)?,
        };
        let out = u.undistort_image(&grey)?;
        self.undistorter = Some(u);
        // Outside the source the remap gives NaN; ORB and the searches want grey levels.
        Ok(out.map(|v| if v.is_finite() { *v } else { 0.0 }))
    }

    fn se3(&self) -> Se3Config {
        Se3Config {
            quality: self.cfg.quality,
            ..self.cfg.se3
        }
    }

    /// A located frame's estimate: `fit` against a keyframe at `t_w_kf`.
    fn located(
        fit: &Se3Result,
        t_w_kf: &Isometry3<f64>,
        keyframe: bool,
        start: Instant,
    ) -> FrameEstimate {
        let quality = FrameQuality::of_se3(fit, keyframe, ms_since(start));
        FrameEstimate {
            pose_wc: t_w_kf * fit.pose.inverse(),
            status: TrackStatus::Ok,
            quality,
            message: None,
            pose_quality: None,
        }
        .judged(fit.quality.clone())
    }

    /// Starts waiting on `image` at `t_wc` as a new reference (none when it has too few
    /// features).
    fn new_reference(&self, image: Image<f32>, t_wc: Isometry3<f64>) -> State {
        match self.orb.detect_and_describe(&image.to_u8()) {
            Ok(features) if features.len() >= self.cfg.min_init_points => State::Initialising {
                features,
                image,
                t_wc,
                waiting: Waiting::from(self.late.frame()),
            },
            _ => State::Empty,
        }
    }

    /// Tries the two-view start of `image` against the reference; its estimate.
    fn initialise(
        &mut self,
        (features, reference, t_w1, mut waiting): (
            Features,
            Image<f32>,
            Isometry3<f64>,
            Waiting<Image<f32>>,
        ),
        image: Image<f32>,
        predicted: Isometry3<f64>,
        start: Instant,
    ) -> FrameEstimate {
        let now = self.late.frame();
        let since = waiting.since();
        let current = match self.orb.detect_and_describe(&image.to_u8()) {
            Ok(f) => f,
            Err(e) => {
                self.state = State::Initialising {
                    features,
                    image: reference,
                    t_wc: t_w1,
                    waiting,
                };
                return FrameEstimate::lost(predicted, e.to_string(), start);
            }
        };
        let baseline = if self.started {
            self.coast
                .motion
                .step_length()
                .map(|s| s * (now - since) as f64)
        } else {
            None
        };
        let started =
            two_view(&self.cfg, &self.pinhole, &features, &current, baseline).and_then(|tv| {
                MonoKeyframe::first(
                    reference.clone(),
                    t_w1,
                    &tv.points,
                    (&image, &tv.t_21),
                    self.k(),
                    &self.cfg,
                )
                .map(|kf| (tv, kf))
                .map_err(|e| init::InitFailure {
                    why: format!("initialising: {e}"),
                    keep_reference: true,
                })
            });
        let (tv, kf) = match started {
            Ok(s) => s,
            Err(failure) => {
                let waited = now - since;
                self.state = if failure.keep_reference && waited < self.cfg.max_init_frames {
                    waiting.push(now, image);
                    State::Initialising {
                        features,
                        image: reference,
                        t_wc: t_w1,
                        waiting,
                    }
                } else {
                    self.new_reference(image, predicted)
                };
                return FrameEstimate::lost(predicted, failure.why, start);
            }
        };
        let t_wc = t_w1 * tv.t_21.inverse();
        self.coast.motion.restart(&t_w1, &t_wc, now - since);
        let revised = waiting.locate(&t_w1, (now, &t_wc), |img, pose, start| {
            let prior = pose.inverse() * kf.t_wc;
            let fit = self.align_once(&kf, img, &prior).ok()?;
            Some(Self::located(&fit, &kf.t_wc, false, start))
        });
        self.late.hand_over(revised);
        let status = if self.started {
            TrackStatus::Reinitialised
        } else {
            TrackStatus::Ok
        };
        self.started = true;
        let mut kf = kf;
        kf.frame = since;
        self.state = State::Tracking {
            kf: Box::new(kf),
            last: tv.t_21,
            window: VecDeque::new(),
            bundle: VecDeque::new(),
            scale_broken: None,
        };
        let quality = FrameQuality {
            inliers: tv.inliers.0,
            inlier_ratio: tv.inliers.0 as f64 / tv.inliers.1.max(1) as f64,
            keyframe: true,
            ms: ms_since(start),
            ..FrameQuality::default()
        };
        let message = (status == TrackStatus::Reinitialised).then(|| "new map".to_string());
        FrameEstimate {
            pose_wc: t_wc,
            status,
            quality,
            message,
            pose_quality: None,
        }
        .judged(tv.quality)
    }

    /// Tracks `image` against `kf`; on failure the frame is lost and becomes a new reference.
    /// A frame that becomes a keyframe is first refined with the bundle window.
    fn track_keyframe(
        &mut self,
        mut kf: Box<MonoKeyframe>,
        (last, mut window, mut bundle, mut scale_broken): (
            Isometry3<f64>,
            VecDeque<MonoKeyframe>,
            VecDeque<WindowFrame>,
            Option<usize>,
        ),
        image: Image<f32>,
        predicted: Isometry3<f64>,
        start: Instant,
    ) -> FrameEstimate {
        let prior = predicted.inverse() * kf.t_wc;
        let mut fit = match self.align(&kf, &image, prior, last) {
            Ok(fit) => fit,
            Err(e) => {
                self.state = self.new_reference(image, predicted);
                return FrameEstimate::lost(predicted, format!("tracking lost: {e}"), start);
            }
        };
        let mut t_wc = kf.t_wc * fit.pose.inverse();
        let first_residual = *kf.first_residual.get_or_insert(fit.rmse);
        let k = self.k();
        let t_cw = t_wc.inverse();
        for old in window.iter_mut() {
            old.hand_over(&mut kf, &image, &(t_cw * old.t_wc), k, &self.cfg);
        }
        // A refinement failure (the reference could not be rebuilt) keeps the old reference.
        let refined = kf.refine(&image, &fit.pose, k, &self.cfg);
        let view = KeyframeView {
            t_cur_kf: fit.pose,
            median_depth: kf.median_depth(&self.cfg),
            overlap: fit.inlier_ratio * fit.valid_pixels as f64 / kf.built_with.max(1) as f64,
            residual: fit.rmse,
            first_residual,
        };
        if scale_broken.is_none() && self.motion_jump(&t_wc, &predicted, view.median_depth) {
            scale_broken = Some(self.late.frame());
        }
        let mut keyframe = false;
        let mut last = fit.pose;
        if refined.is_err() || self.cfg.keyframe.needs_keyframe(&view) {
            let mut state = frame_state(&kf, &t_wc, &fit);
            if self.cfg.bundle_window > 0 {
                // A failed bundle (degenerate window) keeps the tracked poses.
                if let Ok(s) = refine_window(&mut bundle, &mut kf, (&image, state), k, &self.cfg) {
                    state = s;
                    t_wc = s.t_cw.inverse();
                    fit.pose = s.t_cw * kf.t_wc;
                }
            }
            let at = (t_wc, state.a, state.b);
            if let Ok(next) = kf.next(image, at, &fit.pose, k, &self.cfg) {
                let mut old = std::mem::replace(&mut kf, Box::new(next));
                if self.cfg.bundle_window > 0 {
                    bundle.push_back(WindowFrame {
                        image: old.image.clone(),
                        state: old.state(),
                    });
                    while bundle.len() > self.cfg.bundle_window {
                        bundle.pop_front();
                    }
                }
                old.keep_immature(&self.cfg);
                window.push_back(*old);
                kf.frame = self.late.frame();
                let (keep, young) = (self.cfg.window, self.cfg.seed_frames);
                prune_window(&mut window, |w| w.frame, kf.frame, (keep, young));
                keyframe = true;
                last = Isometry3::identity();
            }
        }
        self.coast.motion.update(t_wc);
        self.state = State::Tracking {
            kf,
            last,
            window,
            bundle,
            scale_broken,
        };
        let mut estimate = Self::located(&fit, &(t_wc * fit.pose), keyframe, start);
        if let Some(at) = scale_broken {
            estimate = estimate.flagged(
                Reason::Inconsistent,
                format!("the map's scale is suspect since a motion jump at frame {at}"),
            );
        }
        estimate
    }

    /// Whether `t_wc` jumps away from the constant-velocity prediction `predicted` (module
    /// documentation, step 5), for a keyframe at `median_depth`.
    fn motion_jump(
        &self,
        t_wc: &Isometry3<f64>,
        predicted: &Isometry3<f64>,
        median_depth: f64,
    ) -> bool {
        let motion = &self.coast.motion;
        let Some(step) = motion.step_length().filter(|_| motion.has_velocity()) else {
            return false;
        };
        let gap = (t_wc.translation.vector - predicted.translation.vector).norm();
        step >= self.cfg.min_judged_step * median_depth && gap > self.cfg.max_motion_jump * step
    }
}

impl Tracker for DirectMonoTracker {
    fn track(&mut self, frame: &Frame) -> FrameEstimate {
        self.late.begin_frame();
        let start = Instant::now();
        let predicted = self.coast.predict();
        let estimate = match self.pinhole_image(frame) {
            Err(e) => FrameEstimate::lost(predicted, e.to_string(), start),
            Ok(image) => match std::mem::replace(&mut self.state, State::Empty) {
                State::Empty => {
                    self.state = self.new_reference(image, predicted);
                    if !self.origin && matches!(self.state, State::Initialising { .. }) {
                        // The first frame with features defines the world frame.
                        self.origin = true;
                        self.coast.motion.update(predicted);
                        let quality = FrameQuality {
                            keyframe: true,
                            ms: ms_since(start),
                            ..FrameQuality::default()
                        };
                        FrameEstimate {
                            pose_wc: predicted,
                            status: TrackStatus::Ok,
                            quality,
                            message: None,
                            pose_quality: None,
                        }
                    } else {
                        FrameEstimate::lost(predicted, "initialising: new reference".into(), start)
                    }
                }
                State::Initialising {
                    features,
                    image: reference,
                    t_wc,
                    waiting,
                } => self.initialise(
                    (features, reference, t_wc, waiting),
                    image,
                    predicted,
                    start,
                ),
                State::Tracking {
                    kf,
                    last,
                    window,
                    bundle,
                    scale_broken,
                } => self.track_keyframe(
                    kf,
                    (last, window, bundle, scale_broken),
                    image,
                    predicted,
                    start,
                ),
            },
        };
        if self.origin {
            self.coast
                .end_frame(estimate.status == TrackStatus::Lost, predicted);
        }
        self.late.end_frame();
        estimate
    }

    fn pending(&self) -> usize {
        match &self.state {
            State::Initialising { waiting, .. } => self.late.pending(Some(waiting)),
            _ => 0,
        }
    }

    fn revised(&mut self) -> Vec<(usize, FrameEstimate)> {
        self.late.take()
    }
}
