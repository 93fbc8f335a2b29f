//! Direct stereo tracker: photometric SE(3) alignment to keyframes whose depth comes from the
//! stereo disparity; metric poses of the left camera of a stereo rig.
//!
//! 1. The rig is rectified once, for the first frame's size (the stereo tracker's
//!    `Rectified`: Bouguet's rectification; a rig rectified already, such as KITTI's, is used
//!    as it is). Every left image is brought to the rectified pinhole `K`.
//! 2. A keyframe: the high-gradient pixels of its rectified left image
//!    ([`vofront_image::disparity::select_pixels`]) matched along their rows in the rectified
//!    right image ([`vofront_image::disparity::match_pixels`]: zero-mean SSD, parabola,
//!    uniqueness and left-right checks); each kept pixel has the depth `Z = f b / d` and
//!    `sigma_Z = Z^2 sigma_d / (f b)`, and is kept when `sigma_Z / Z` is at most
//!    [`DirectStereoConfig::max_relative_depth_sigma`]. These pixels with their inverse depths
//!    are the keyframe's [`Se3Reference`] ([`Se3Reference::from_inverse_depths`]).
//! 3. Each frame starts from the constant-velocity guess `T_wc'`, `T_cur_kf = T_wc'^-1 T_w_kf`
//!    (without a velocity, the first frame and the first after a loss, from the last pose, and
//!    its fit is then also checked by two halves of the pixels: more than 10 combined sigmas
//!    apart flags it `inconsistent`, see `Se3Reference::halves_disagreement`), and minimises `I_cur(pi(K T_cur_kf pi^-1(p, Z_p))) - (a I_kf(p) + b)` (affine
//!    brightness, coarse to fine, robust); its pose is `T_wc = T_w_kf T_cur_kf^-1`. A failed
//!    alignment, a `failed` verdict or too few inliers loses the frame, which then starts a
//!    new keyframe at the prediction: metric like the first, so the scale never breaks.
//! 4. A new keyframe is taken by the RGB-D direct tracker's policy (translation relative to
//!    the median depth, rotation, overlap, residual growth).
//!
//! The trajectory is the raw left camera's `T_wc`, first frame at the origin (the rectified
//! camera's poses turned back by the rectifying rotation, as the stereo tracker does).

use std::time::Instant;

use nalgebra::{Isometry3, Vector2};
use thiserror::Error;
use vofront_core::rig::Rig;
use vofront_direct::{CalibrationPrior, InverseDepthPoint, Se3Config, Se3Reference};
use vofront_image::disparity::{match_pixels, select_pixels, DisparityConfig};
use vofront_image::{Image, ImageError};
use vofront_robust::{QualityConfig, Verdict};

use super::keyframe::{KeyframePolicy, KeyframeView};
use super::observe::FrameDetails;
use super::stereo::rectified::Rectified;
use super::stereo::StereoFrameError;
use super::{ms_since, FrameEstimate, FrameQuality, KeyframeSlot, TrackStatus, Tracker};
use crate::dataset::Frame;
use crate::error::VoError;
use crate::two_view::stereo::flag_if_inconsistent;

/// Why a direct stereo tracker could not be built.
#[derive(Debug, Error)]
pub enum DirectStereoError {
    /// The rig has one camera.
    #[error("the direct stereo tracker needs a stereo rig (a left and a right camera)")]
    MonoRig,
    /// The disparity configuration is invalid.
    #[error("invalid direct stereo configuration: {0}")]
    Disparity(#[from] ImageError),
}

/// Settings of [`DirectStereoTracker`].
#[derive(Debug, Clone)]
pub struct DirectStereoConfig {
    /// SE(3) alignment settings (affine brightness on; depths up to 200 m).
    pub se3: Se3Config,
    /// Pixel selection and block matching of a keyframe.
    pub disparity: DisparityConfig,
    /// Largest `sigma_Z / Z` of a keyframe pixel (`= sigma_d / d`).
    pub max_relative_depth_sigma: f64,
    /// When to take a new keyframe.
    pub keyframe: KeyframePolicy,
    /// Smallest inlier ratio for a frame to count as tracked.
    pub min_inlier_ratio: f64,
    /// Thresholds of the alignment's verdict, used in place of `se3.quality`.
    pub quality: QualityConfig,
}

impl Default for DirectStereoConfig {
    fn default() -> Self {
        Self {
            se3: Se3Config {
                max_depth: 200.0,
                // Z = f b / d: the depths follow the focal length and the baseline.
                calibration: CalibrationPrior {
                    depth_from_disparity: true,
                    ..CalibrationPrior::default()
                },
                ..Se3Config::default()
            },
            disparity: DisparityConfig::default(),
            max_relative_depth_sigma: 0.1,
            keyframe: KeyframePolicy::default(),
            min_inlier_ratio: 0.4,
            quality: QualityConfig::default(),
        }
    }
}

struct Keyframe {
    reference: Se3Reference,
    /// Rectified left camera's `T_wc`.
    t_wc: Isometry3<f64>,
    median_depth: f64,
    selected: usize,
    first_residual: Option<f64>,
}

/// Frame-to-keyframe SE(3) photometric tracker of a stereo rig (see the module documentation).
///
/// ```
/// use nalgebra::{Isometry3, Translation3};
/// use vofront::dataset::Frame;
/// use vofront::fixtures::driving::{DrivingSequence, FRAME_RATE};
/// use vofront::fixtures::image2d::to_gray8;
/// use vofront::odometry::direct_stereo::{DirectStereoConfig, DirectStereoTracker};
/// use vofront::odometry::{TrackStatus, Tracker};
/// use vofront_core::rig::Rig;
///
/// // A rendered street drive seen by a rectified rig with a 0.5 m baseline.
/// let drive = DrivingSequence::new(3, 6);
/// let right_in_left = Isometry3::from(Translation3::new(0.5, 0.0, 0.0));
/// let rig = Rig::stereo(drive.camera, Isometry3::identity(), drive.camera, right_in_left).unwrap();
/// let mut tracker = DirectStereoTracker::new(rig, DirectStereoConfig::default()).unwrap();
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
pub struct DirectStereoTracker {
    cfg: DirectStereoConfig,
    rig: Rig,
    /// The rectification, built for the first frame's size.
    rectified: Option<Rectified>,
    slot: KeyframeSlot<Keyframe>,
    /// The last frame's details, kept while an observer asks ([`Tracker::keep_details`]).
    details: Option<FrameDetails>,
}

impl DirectStereoTracker {
    /// A tracker for the frames of the stereo `rig`; [`DirectStereoError::MonoRig`] for a
    /// one-camera rig, [`DirectStereoError::Disparity`] for an invalid disparity configuration.
    pub fn new(rig: Rig, cfg: DirectStereoConfig) -> Result<Self, DirectStereoError> {
        if !rig.is_stereo() {
            return Err(DirectStereoError::MonoRig);
        }
        cfg.disparity.validate()?;
        Ok(Self {
            cfg,
            rig,
            rectified: None,
            slot: KeyframeSlot::default(),
            details: None,
        })
    }

    /// The rectification for `size` images (built at the first frame).
    fn rectified(&mut self, size: (usize, usize)) -> Result<&Rectified, VoError> {
        let r = match self.rectified.take() {
            Some(r) => r,
            None => Rectified::new(&self.rig, size).map_err(frame_error)?,
        };
        let r = self.rectified.insert(r);
        if r.size != size {
            return Err(frame_error(StereoFrameError::Size {
                got: size,
                want: r.size,
            }));
        }
        Ok(r)
    }

    /// `image` (left when `side` is 0, right when 1) in the rectified geometry, as `f32`.
    fn rectify(&mut self, image: &Image<u8>, side: usize) -> Result<Image<f32>, VoError> {
        let r = self.rectified(image.size())?;
        let grey = image.to_f32();
        match &r.remaps {
            None => Ok(grey),
            Some(maps) => maps[side]
                .bilinear(&grey, 0.0)
                .map_err(|e| frame_error(StereoFrameError::Image(e))),
        }
    }

    /// A keyframe at `t_wc` (rectified) from the frame's rectified `left` and its right image.
    fn make_keyframe(
        &mut self,
        frame: &Frame,
        left: &Image<f32>,
        t_wc: Isometry3<f64>,
    ) -> Result<Keyframe, VoError> {
        let right = frame
            .right()
            .ok_or_else(|| frame_error(StereoFrameError::NoRightImage))?;
        let right = self.rectify(right, 1)?;
        let r = self.rectified(left.size())?;
        let (pinhole, fb) = (r.camera.pinhole, r.fb);
        let points = stereo_points(left, &right, fb, &self.cfg)?;
        let mut depths: Vec<f64> = points
            .iter()
            .map(|p| 1.0 / f64::from(p.inverse_depth))
            .collect();
        let reference =
            Se3Reference::from_inverse_depths(left, pinhole, None, &points, &self.cfg.se3)?;
        let selected = reference.selected().first().copied().unwrap_or(0);
        Ok(Keyframe {
            reference,
            t_wc,
            median_depth: crate::robust::median_in_place(&mut depths).unwrap_or(1.0),
            selected,
            first_residual: None,
        })
    }

    /// One frame from the prediction `predicted` (rectified `T_wc`).
    fn track_rectified(&mut self, frame: &Frame, predicted: Isometry3<f64>) -> FrameEstimate {
        let start = Instant::now();
        let current = match self.rectify(frame.image(), 0) {
            Ok(c) => c,
            Err(e) => return FrameEstimate::lost(predicted, e.to_string(), start),
        };
        let Some(kf) = &self.slot.keyframe else {
            let made = self.make_keyframe(frame, &current, predicted);
            return self
                .slot
                .restart(made, predicted, "no keyframe".into(), start);
        };
        let se3 = Se3Config {
            quality: self.cfg.quality,
            ..self.cfg.se3
        };
        // Without a velocity the prior is the last pose, possibly far from the motion: the
        // fit is also checked by its two halves (`Se3Reference::halves_disagreement`).
        let check_halves = !self.slot.motion.has_velocity();
        let fit = kf
            .reference
            .align(&current, &(predicted.inverse() * kf.t_wc), &se3)
            .map_err(VoError::from)
            .and_then(|r| {
                let mut q = r.quality.clone();
                if check_halves {
                    let sigmas = kf.reference.halves_disagreement(&current, &r.pose, &se3);
                    flag_if_inconsistent(&mut q, sigmas);
                }
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
                let made = self.make_keyframe(frame, &current, predicted);
                return self.slot.restart(made, predicted, why.to_string(), start);
            }
        };
        let t_wc = kf.t_wc * fit.pose.inverse();
        let view = KeyframeView {
            t_cur_kf: fit.pose,
            median_depth: kf.median_depth,
            overlap: fit.inlier_ratio * fit.valid_pixels as f64 / kf.selected.max(1) as f64,
            residual: fit.rmse,
            first_residual: kf.first_residual.unwrap_or(fit.rmse),
        };
        if let Some(kf) = &mut self.slot.keyframe {
            kf.first_residual.get_or_insert(fit.rmse);
        }
        if let (Some(details), Some(kf), Some(r)) =
            (&mut self.details, &self.slot.keyframe, &self.rectified)
        {
            let limit = self.cfg.se3.inlier_sigmas * fit.sigma as f32;
            if let Ok(pixels) = kf.reference.residuals(&current, &fit.pose, fit.a, fit.b) {
                details.photometric(&pixels, limit, |px| r.raw_pixel(px));
            }
            let points = kf.reference.points().map(|p| r.t_raw_rect * (kf.t_wc * p));
            details.map_points.extend(points);
        }
        self.slot.motion.update(t_wc);
        let mut keyframe = false;
        if self.cfg.keyframe.needs_keyframe(&view) {
            if let Ok(new_kf) = self.make_keyframe(frame, &current, t_wc) {
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

/// The pixels of a keyframe of a rectified stereo pair (step 2 of the module documentation):
/// the high-gradient pixels of `left` matched along their rows in `right`, each kept when
/// `sigma_d / d <= cfg.max_relative_depth_sigma`, with the inverse depth `d / (f b)`, 1/metres
/// (`fb`: the focal length in pixels times the baseline in metres). They make the keyframe's
/// reference with [`Se3Reference::from_inverse_depths`] and `cfg.se3`.
///
/// Errors: [`VoError::StereoFrame`] when the two images differ in size, the disparity
/// settings are invalid or `fb` is not a positive number.
pub fn stereo_points(
    left: &Image<f32>,
    right: &Image<f32>,
    fb: f64,
    cfg: &DirectStereoConfig,
) -> Result<Vec<InverseDepthPoint>, VoError> {
    if !(fb.is_finite() && fb > 0.0) {
        return Err(VoError::StereoFrame(format!(
            "focal length times baseline must be positive, got {fb}"
        )));
    }
    let pixels = select_pixels(left, &cfg.disparity);
    let found = match_pixels(left, right, &pixels, &cfg.disparity)
        .map_err(|e| frame_error(StereoFrameError::Image(e)))?;
    Ok(found
        .iter()
        .flatten()
        .filter(|m| f64::from(m.sigma / m.disparity) <= cfg.max_relative_depth_sigma)
        .map(|m| InverseDepthPoint {
            pixel: Vector2::new(m.x as f32, m.y as f32),
            inverse_depth: (1.0 / m.depth(fb)) as f32,
        })
        .collect())
}

/// A stereo frame error as the trackers' [`VoError`].
fn frame_error(e: StereoFrameError) -> VoError {
    VoError::StereoFrame(e.to_string())
}

impl Tracker for DirectStereoTracker {
    fn track(&mut self, frame: &Frame) -> FrameEstimate {
        if let Some(details) = &mut self.details {
            details.clear();
        }
        let predicted = self.slot.predict();
        let mut estimate = self.track_rectified(frame, predicted);
        // The rectified left camera is the raw one turned by R_left: T_wc = T_rr T_wc' T_rr^-1.
        if let Some(r) = &self.rectified {
            estimate.pose_wc = r.t_raw_rect * estimate.pose_wc * r.t_raw_rect.inverse();
        }
        estimate
    }

    fn needs_right(&self) -> bool {
        true
    }

    /// The keyframe's selected pixels warped into the frame (rectified, drawn in the raw
    /// left image) with their photometric residuals (inliers within the aligner's
    /// `inlier_sigmas` robust sigmas), and their stereo points.
    fn keep_details(&mut self, keep: bool) {
        self.details = keep.then(FrameDetails::default);
    }

    fn details(&self) -> Option<&FrameDetails> {
        self.details.as_ref()
    }
}
