//! RGB-D direct tracker: each frame is aligned photometrically to the keyframe.
//!
//! With the keyframe pose `T_w_kf` and the constant-velocity guess `T_wc'`, the alignment
//! starts from `T_cur_kf = T_wc'^-1 T_w_kf` and minimises
//! `I_cur(pi(K T_cur_kf pi^-1(p, d_p))) - (a I_kf(p) + b)` over the keyframe's selected pixels
//! ([`vofront_direct::Se3Reference`]); the frame's pose is then `T_wc = T_w_kf T_cur_kf^-1`.
//! A result is rejected (frame lost) when the alignment fails (including a brightness gain
//! outside `Se3Config::max_gain`: a flat image can be "explained" by `a = 0`) or when too few
//! residuals are inliers, or when the fit's verdict ([`vofront_direct::Se3Result::quality`]) is `failed`.

use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Isometry3, Vector2};
use vofront_core::Camera;
use vofront_direct::{DirectError, RgbdFrame, Se3Config, Se3Reference, Undistorter};
use vofront_image::Image;
use vofront_robust::{QualityConfig, Verdict};

use super::keyframe::{KeyframePolicy, KeyframeView};
use super::observe::FrameDetails;
use super::{ms_since, FrameEstimate, FrameQuality, KeyframeSlot, TrackStatus, Tracker};
use crate::dataset::Frame;
use crate::error::VoError;

/// Settings of [`DirectTracker`].
#[derive(Debug, Clone)]
pub struct DirectTrackerConfig {
    /// SE(3) alignment settings (affine brightness on by default).
    pub se3: Se3Config,
    /// When to take a new keyframe.
    pub keyframe: KeyframePolicy,
    /// Smallest inlier ratio for a frame to count as tracked.
    pub min_inlier_ratio: f64,
    /// Thresholds of the alignment's verdict ([`vofront_direct::Se3Result::quality`]), used in
    /// place of `se3.quality`.
    pub quality: QualityConfig,
}

impl Default for DirectTrackerConfig {
    fn default() -> Self {
        Self {
            se3: Se3Config::default(),
            keyframe: KeyframePolicy::default(),
            min_inlier_ratio: 0.4,
            quality: QualityConfig::default(),
        }
    }
}

struct Keyframe {
    reference: Se3Reference,
    t_wc: Isometry3<f64>,
    median_depth: f64,
    selected: usize,
    first_residual: Option<f64>,
}

/// Frame-to-keyframe SE(3) photometric tracker for RGB-D sequences.
///
/// ```
/// use vofront::dataset::Frame;
/// use vofront::fixtures::image2d::to_gray8;
/// use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
/// use vofront::geometry::Pinhole;
/// use vofront::odometry::{TrackStatus, Tracker};
/// use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
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
/// let mut tracker = DirectTracker::new(camera, DirectTrackerConfig::default());
/// let last = frames.iter().map(|f| tracker.track(f)).last().unwrap();
/// assert_eq!(last.status, TrackStatus::Ok);
/// // The first frame is the origin: compare with the true motion since frame 0.
/// let truth = poses[0].inverse() * poses[3];
/// let error = (last.pose_wc.translation.vector - truth.translation.vector).norm();
/// assert!(error < 0.005, "{error} m off after {:.3} m", truth.translation.vector.norm());
/// ```
pub struct DirectTracker {
    cfg: DirectTrackerConfig,
    camera: Camera,
    /// The camera's undistortion remap, built at the first frame's size and reused for every
    /// keyframe (`None` without lens distortion).
    undistorter: Option<Arc<Undistorter>>,
    slot: KeyframeSlot<Keyframe>,
    /// The last frame's details, kept while an observer asks ([`Tracker::keep_details`]).
    details: Option<FrameDetails>,
}

impl DirectTracker {
    /// A tracker for frames of `camera` (with lens distortion, frames are undistorted once).
    pub fn new(camera: Camera, cfg: DirectTrackerConfig) -> Self {
        Self {
            cfg,
            camera,
            undistorter: None,
            slot: KeyframeSlot::default(),
            details: None,
        }
    }

    /// A keyframe from a frame's grey levels `image` (already `f32`) and its depth, at `t_wc`.
    fn make_keyframe(
        &mut self,
        frame: &Frame,
        image: Image<f32>,
        t_wc: Isometry3<f64>,
    ) -> Result<Keyframe, VoError> {
        let depth = frame.depth().ok_or(VoError::NoDepth)?.clone();
        let undistorter = self.undistorter_for(image.size())?;
        let rgbd = RgbdFrame::with_undistorter(image, depth, self.camera.pinhole, undistorter)?;
        let reference = Se3Reference::new(&rgbd, &self.cfg.se3)?;
        let selected = reference.selected().first().copied().unwrap_or(0);
        Ok(Keyframe {
            reference,
            t_wc,
            median_depth: rgbd.median_depth(),
            selected,
            first_residual: None,
        })
    }
}

impl DirectTracker {
    /// The undistortion remap for `(width, height)` images: built once, rebuilt only if the
    /// image size changes; `None` for a camera without distortion (validated here instead).
    fn undistorter_for(
        &mut self,
        (width, height): (usize, usize),
    ) -> Result<Option<Arc<Undistorter>>, VoError> {
        if self.camera.distortion.is_identity() {
            self.camera.validate().map_err(DirectError::from)?;
            return Ok(None);
        }
        match &self.undistorter {
            Some(u) if u.size() == (width, height) => {}
            _ => {
                let u = Undistorter::new(&self.camera, width, height)?;
                self.undistorter = Some(Arc::new(u));
            }
        }
        Ok(self.undistorter.clone())
    }
}

impl Tracker for DirectTracker {
    /// The keyframe's selected pixels warped into the frame with their photometric residuals
    /// (inliers within the aligner's `inlier_sigmas` robust sigmas), and their points.
    fn keep_details(&mut self, keep: bool) {
        self.details = keep.then(FrameDetails::default);
    }

    fn details(&self) -> Option<&FrameDetails> {
        self.details.as_ref()
    }

    fn track(&mut self, frame: &Frame) -> FrameEstimate {
        let start = Instant::now();
        if let Some(details) = &mut self.details {
            details.clear();
        }
        let predicted = self.slot.predict();
        let current = frame.image().to_f32();
        let Some(kf) = &mut self.slot.keyframe else {
            let made = self.make_keyframe(frame, current, predicted);
            return self
                .slot
                .restart(made, predicted, "no keyframe".into(), start);
        };
        let prior = predicted.inverse() * kf.t_wc;
        let fit = kf
            .reference
            .align(
                &current,
                &prior,
                &Se3Config {
                    quality: self.cfg.quality,
                    ..self.cfg.se3
                },
            )
            .map_err(VoError::from)
            .and_then(|r| {
                let q = r.quality.clone();
                if q.verdict == Verdict::Failed {
                    Err(VoError::Rejected {
                        what: "SE(3)",
                        reasons: super::reasons_text(&q),
                    })
                } else if r.inlier_ratio < self.cfg.min_inlier_ratio {
                    Err(VoError::LowInlierRatio {
                        ratio: r.inlier_ratio,
                        min: self.cfg.min_inlier_ratio,
                    })
                } else {
                    Ok((r, q))
                }
            });
        let (fit, pose_quality) = match fit {
            Ok(fit) => fit,
            Err(why) => {
                let made = self.make_keyframe(frame, current, predicted);
                return self.slot.restart(made, predicted, why.to_string(), start);
            }
        };
        let t_wc = kf.t_wc * fit.pose.inverse();
        self.slot.motion.update(t_wc);
        let first_residual = *kf.first_residual.get_or_insert(fit.rmse);
        if let Some(details) = &mut self.details {
            let camera = &self.camera;
            // The aligner's pixels are pinhole ones: drawn where the lens puts them.
            let to_image = |px: [f32; 2]| {
                let x = camera
                    .pinhole
                    .to_normalized(&Vector2::new(f64::from(px[0]), f64::from(px[1])));
                let u = camera.normalized_to_pixel(&x);
                Some([u.x as f32, u.y as f32])
            };
            let limit = self.cfg.se3.inlier_sigmas * fit.sigma as f32;
            if let Ok(pixels) = kf.reference.residuals(&current, &fit.pose, fit.a, fit.b) {
                details.photometric(&pixels, limit, to_image);
            }
            let points = kf.reference.points().map(|p| kf.t_wc * p);
            details.map_points.extend(points);
        }
        let view = KeyframeView {
            t_cur_kf: fit.pose,
            median_depth: kf.median_depth,
            overlap: fit.inlier_ratio * fit.valid_pixels as f64 / kf.selected.max(1) as f64,
            residual: fit.rmse,
            first_residual,
        };
        let mut keyframe = false;
        if self.cfg.keyframe.needs_keyframe(&view) {
            if let Ok(new_kf) = self.make_keyframe(frame, current, t_wc) {
                self.slot.keyframe = Some(new_kf);
                keyframe = true;
            }
        }
        let quality = FrameQuality::of_se3(&fit, keyframe, ms_since(start));
        FrameEstimate {
            pose_wc: t_wc,
            status: TrackStatus::Ok,
            quality,
            message: None,
            pose_quality: None,
        }
        .judged(pose_quality)
    }
}
