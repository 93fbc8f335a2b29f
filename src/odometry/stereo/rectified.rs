//! The stereo front of a frame: both images in the rectified geometry, ORB on each, the left
//! features matched along their rows, and the metric point of every matched left feature.

use nalgebra::{Isometry3, Matrix3, Point3, UnitQuaternion, Vector2, Vector3};
use thiserror::Error;
use vofront_core::rectify::{RectifyError, StereoRectification};
use vofront_core::rig::Rig;
use vofront_core::Camera;
use vofront_features::{match_stereo, FeatureError, Features, Orb, StereoConfig, StereoMatch};
use vofront_image::{Image, ImageError, Remap};

/// Largest rotation (radians) and pinhole difference (pixels) under which a rig counts as
/// rectified already: its images are used as they are.
const RECTIFIED_TOLERANCE: f64 = 1e-9;

/// Why a stereo frame could not be prepared.
#[derive(Debug, Error)]
pub enum StereoFrameError {
    /// The frame has no right image (load it with `Dataset::load_stereo`).
    #[error("the frame has no right image")]
    NoRightImage,
    /// The rig cannot be rectified for images of this size.
    #[error("rectification: {0}")]
    Rectify(#[from] RectifyError),
    /// A remap could not be built or applied.
    #[error("rectification remap: {0}")]
    Image(#[from] ImageError),
    /// ORB or stereo matching failed.
    #[error("features: {0}")]
    Features(#[from] FeatureError),
    /// The images are not the size the rectification was built for.
    #[error("image is {got:?}, the rig was rectified for {want:?}")]
    Size {
        /// This frame's `(width, height)`.
        got: (usize, usize),
        /// The size of the first frame.
        want: (usize, usize),
    },
}

/// One frame seen by the rectified rig.
pub(crate) struct StereoView {
    /// ORB features of the rectified left image.
    pub features: Features,
    /// The metric point `P = Z K^-1 [u, v, 1]` (left rectified camera, metres) of each left
    /// feature matched in the right image, `Z = f b / d`.
    pub points: Vec<Option<Point3<f64>>>,
    /// The covariance of each point (same camera, metres^2), its depth noise along its ray:
    /// `(sigma_d / d)^2 P P^T`.
    pub covariances: Vec<Option<Matrix3<f64>>>,
    /// The column in the rectified right image of each matched left feature, pixels.
    pub right: Vec<Option<f64>>,
    /// `(width, height)` of the rectified images, pixels.
    pub size: (usize, usize),
}

/// Which stereo matches make points: those whose relative depth uncertainty
/// `sigma_Z / Z = sigma_d / d` (`Z = f b / d`, `sigma_d` the disparity's noise) is at most
/// `max_relative_sigma`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct DepthRule {
    /// Disparity noise of a level-0 keypoint, pixels (times the keypoint's level scale).
    pub disparity_sigma_px: f64,
    /// Largest `sigma_d / d`.
    pub max_relative_sigma: f64,
}

/// The rig's rectification, built once for the first frame's size.
pub(crate) struct Rectified {
    /// The common pinhole of the rectified images (no distortion).
    pub camera: Camera,
    /// Focal length times baseline, pixel metres.
    pub fb: f64,
    /// Baseline, metres: the rectified right camera sits at `x = +baseline` in the left one.
    pub baseline: f64,
    /// `T_raw_rect`: rectified left-camera points into the raw left camera (`R_left^-1`).
    pub t_raw_rect: Isometry3<f64>,
    /// The remaps of the left and right images; `None` for a rig rectified already.
    pub(crate) remaps: Option<[Remap; 2]>,
    pub(crate) size: (usize, usize),
    /// The raw left camera.
    raw: Camera,
}

/// ORB features of `image`.
fn detect(orb: &Orb, image: &Image<u8>) -> Result<Features, StereoFrameError> {
    Ok(orb.detect_and_describe(image)?)
}

impl Rectified {
    /// The rectification of `rig` for `width x height` images: Bouguet's
    /// ([`StereoRectification`]), its remaps skipped when both cameras have no distortion, the
    /// same pinhole and parallel axes and the rectification is the identity.
    pub fn new(rig: &Rig, (width, height): (usize, usize)) -> Result<Self, StereoFrameError> {
        let rect = StereoRectification::new(rig, width, height)?;
        let left = rig.left();
        let same = |a: &Camera| {
            let (p, q) = (a.pinhole, *rect.pinhole());
            a.distortion.is_identity()
                && [p.fx - q.fx, p.fy - q.fy, p.cx - q.cx, p.cy - q.cy]
                    .iter()
                    .all(|d| d.abs() < RECTIFIED_TOLERANCE)
        };
        let identity = rect.rotation_left().angle() < RECTIFIED_TOLERANCE
            && rect.rotation_right().angle() < RECTIFIED_TOLERANCE;
        let already = identity && same(left) && rig.right().is_some_and(same);
        let remaps = if already {
            None
        } else {
            let remap = |m: &vofront_core::UndistortMap| {
                Remap::new((width, height), (m.width, m.height), &m.map_x, &m.map_y)
            };
            Some([remap(rect.map_left())?, remap(rect.map_right())?])
        };
        let rotation = UnitQuaternion::from_rotation_matrix(rect.rotation_left());
        Ok(Self {
            camera: Camera::pinhole(*rect.pinhole()),
            fb: rect.pinhole().fx * rect.baseline(),
            baseline: rect.baseline(),
            t_raw_rect: Isometry3::from_parts(Default::default(), rotation.inverse()),
            remaps,
            size: (width, height),
            raw: *left,
        })
    }

    /// Where pixel `px` of the rectified left image is in the raw left image:
    /// `pi_raw(R_raw_rect K_rect^-1 (u, v, 1))`, the same pixel for a rig rectified already;
    /// `None` when the ray has no raw pixel.
    pub fn raw_pixel(&self, px: [f32; 2]) -> Option<[f32; 2]> {
        if self.remaps.is_none() {
            return Some(px);
        }
        let x = self
            .camera
            .pinhole
            .to_normalized(&Vector2::new(f64::from(px[0]), f64::from(px[1])));
        let ray = self.t_raw_rect.rotation * Vector3::new(x.x, x.y, 1.0);
        self.raw.project(&ray).map(|u| [u.x as f32, u.y as f32])
    }

    /// The frame's `left` and `right` images in the rectified geometry (bilinear, black where
    /// the source is outside), ORB features of both, the left ones matched along their rows
    /// ([`match_stereo`]) and given their metric points (those `depth` accepts).
    pub fn view(
        &self,
        orb: &Orb,
        stereo: &StereoConfig,
        depth: DepthRule,
        left: &Image<u8>,
        right: &Image<u8>,
    ) -> Result<StereoView, StereoFrameError> {
        for image in [left, right] {
            if image.size() != self.size {
                return Err(StereoFrameError::Size {
                    got: image.size(),
                    want: self.size,
                });
            }
        }
        let remapped;
        let (left, right) = match &self.remaps {
            None => (left, right),
            Some([ml, mr]) => {
                remapped = (
                    ml.bilinear(&left.to_f32(), 0.0)?.to_u8(),
                    mr.bilinear(&right.to_f32(), 0.0)?.to_u8(),
                );
                (&remapped.0, &remapped.1)
            }
        };
        let (features, right_features) = rayon::join(|| detect(orb, left), || detect(orb, right));
        let (features, right_features) = (features?, right_features?);
        let matches = match_stereo(&features, &right_features, left, right, stereo)?;
        let mut points = vec![None; features.len()];
        let mut covariances = vec![None; features.len()];
        let mut right = vec![None; features.len()];
        let k = &self.camera.pinhole;
        let sigma_of = |m: &StereoMatch| depth.disparity_sigma_px * f64::from(m.noise_scale);
        for m in matches
            .iter()
            .filter(|m| sigma_of(m) <= depth.max_relative_sigma * f64::from(m.disparity))
        {
            let (u, v) = (
                f64::from(features.xs()[m.left as usize]),
                f64::from(features.ys()[m.left as usize]),
            );
            let z = m.depth(self.fb);
            let p = Point3::new((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
            let relative = sigma_of(m) / f64::from(m.disparity);
            right[m.left as usize] = Some(f64::from(m.right_x));
            points[m.left as usize] = Some(p);
            covariances[m.left as usize] =
                Some(relative * relative * p.coords * p.coords.transpose());
        }
        Ok(StereoView {
            features,
            points,
            covariances,
            right,
            size: left.size(),
        })
    }
}
