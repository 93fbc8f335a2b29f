//! Stereo rectification of a calibrated two-camera [`Rig`] (Bouguet's method, as OpenCV's
//! `stereoRectify` followed by `initUndistortRectifyMap`).
//!
//! With `T_RL = (R, t)` the left-to-right transform of the rig (`x_R = R x_L + t`, metres):
//!
//! 1. split the relative rotation in half, `Q = R^(1/2)` (same axis, half the angle), and turn
//!    the left camera by `Q` and the right camera by `Q^-1`: both now look the same way and
//!    `x_R' = x_L' + Q^-1 t`;
//! 2. turn both by the smallest rotation `W` taking the direction of `Q^-1 t` onto `-x`, so
//!    that the baseline lies along the new `x` axis: `x_R'' = x_L'' + (-b, 0, 0)`, `b = |t|`.
//!
//! The rectifying rotations are `R_left = W Q` and `R_right = W Q^-1`; each maps points of its
//! raw camera into its rectified camera. Both rectified images share one distortion-free
//! [`Pinhole`] of the raw image size, so a point at depth `Z` (rectified left frame) lies on
//! the same row `v` in both images at disparity `u_L - u_R = fx b / Z`.
//!
//! Choice of the common pinhole (OpenCV's `alpha = 0`): every raw border pixel of each camera
//! is undistorted and rotated into its rectified frame; the innermost point of each raw edge
//! bounds an axis-aligned rectangle of rectified normalized coordinates that both raw images
//! see. The focal length is the smallest one (aspect `fy / fx` of the left camera kept) for
//! which the whole `width x height` rectified image fits in that rectangle, centred on it:
//! every rectified pixel has a raw source pixel, and the wider side of the rectangle is
//! cropped evenly. An already rectified rig (KITTI: one pinhole, pure `x` translation, no
//! distortion) keeps its rotations (identity) and its pinhole.
//!
//! The per-pixel maps are [`UndistortMap`]s built with the rectifying rotations
//! ([`UndistortMap::rotated`]); the image crates resample the raw images with them.

use nalgebra::{Isometry3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector2, Vector3};
use thiserror::Error;

use crate::camera::{Camera, CameraError, Pinhole};
use crate::rig::Rig;
use crate::undistort_map::UndistortMap;

/// Why a rig cannot be rectified.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum RectifyError {
    /// The rig has one camera.
    #[error("rectification needs a stereo rig, the rig has one camera")]
    Mono,
    /// A camera or the common pinhole is invalid.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The images are smaller than 2 x 2 pixels.
    #[error("images of {width}x{height} pixels cannot be rectified")]
    ImageTooSmall {
        /// Image width, pixels.
        width: usize,
        /// Image height, pixels.
        height: usize,
    },
    /// The baseline does not run mostly along the cameras' `x` axis (vertical or
    /// forward-looking pairs are not supported).
    #[error("baseline direction {direction:?} (half-rotated left camera) is not mostly along x")]
    NotSideBySide {
        /// Unit baseline direction `Q^-1 t / |t|`.
        direction: [f64; 3],
    },
    /// The right camera is on the left of the left camera (swap them).
    #[error("the right camera is on the left of the left camera")]
    CamerasSwapped,
    /// A raw border pixel cannot be undistorted or its rectified ray leaves the front half
    /// space.
    #[error("camera {camera}: border pixel {pixel:?} has no rectified position")]
    BorderOutOfView {
        /// 0 for the left camera, 1 for the right one.
        camera: usize,
        /// The raw pixel.
        pixel: [f64; 2],
    },
    /// The two rectified views share no rectangle.
    #[error("the rectified views of the two cameras do not overlap")]
    NoCommonView,
}

/// Rectification of a stereo rig: rotations, common pinhole, baseline and resampling maps.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoRectification {
    cameras: [Camera; 2],
    rotations: [Rotation3<f64>; 2],
    pinhole: Pinhole,
    baseline: f64,
    maps: [UndistortMap; 2],
}

impl StereoRectification {
    /// Rectifies the stereo `rig` whose raw images are `width x height` pixels (both cameras);
    /// the rectified images have the same size (see the module documentation).
    ///
    /// Errors: [`RectifyError::Mono`] for a one-camera rig, [`RectifyError::ImageTooSmall`],
    /// [`RectifyError::NotSideBySide`] / [`RectifyError::CamerasSwapped`] for a baseline not
    /// pointing from left to right along `x`, [`RectifyError::BorderOutOfView`] /
    /// [`RectifyError::NoCommonView`] when the rectified views cannot be framed.
    pub fn new(rig: &Rig, width: usize, height: usize) -> Result<Self, RectifyError> {
        let (Some(right), Some(t_rl)) = (rig.right(), rig.t_right_left()) else {
            return Err(RectifyError::Mono);
        };
        if width < 2 || height < 2 {
            return Err(RectifyError::ImageTooSmall { width, height });
        }
        let cameras = [*rig.left(), *right];
        let rotations = rectifying_rotations(&t_rl)?;
        let mut view = ViewRect::everything();
        for (index, (camera, rotation)) in cameras.iter().zip(&rotations).enumerate() {
            view = view.intersect(&ViewRect::of(index, camera, rotation, width, height)?);
        }
        let pinhole = view.framing(cameras[0].pinhole.fy / cameras[0].pinhole.fx, width, height)?;
        let maps = [
            UndistortMap::rotated(&cameras[0], &rotations[0], &pinhole, width, height)?,
            UndistortMap::rotated(&cameras[1], &rotations[1], &pinhole, width, height)?,
        ];
        Ok(Self {
            cameras,
            rotations,
            pinhole,
            baseline: t_rl.translation.vector.norm(),
            maps,
        })
    }

    /// `R_left`: maps raw left-camera points into the rectified left camera.
    pub fn rotation_left(&self) -> &Rotation3<f64> {
        &self.rotations[0]
    }

    /// `R_right`: maps raw right-camera points into the rectified right camera.
    pub fn rotation_right(&self) -> &Rotation3<f64> {
        &self.rotations[1]
    }

    /// The distortion-free intrinsics of both rectified images, pixels.
    pub fn pinhole(&self) -> &Pinhole {
        &self.pinhole
    }

    /// Distance between the camera centres, metres.
    pub fn baseline(&self) -> f64 {
        self.baseline
    }

    /// `(width, height)` of the raw and rectified images, pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.maps[0].width, self.maps[0].height)
    }

    /// The rectified-left to rectified-right transform: a pure translation `(-b, 0, 0)`.
    pub fn t_right_left(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(-self.baseline, 0.0, 0.0),
            UnitQuaternion::identity(),
        )
    }

    /// Depth `Z = fx b / d` (metres, rectified left frame) of disparity `d = u_L - u_R`
    /// (pixels); `None` unless `d > 0`.
    pub fn depth_of_disparity(&self, disparity: f64) -> Option<f64> {
        (disparity > 0.0).then(|| self.pinhole.fx * self.baseline / disparity)
    }

    /// For each rectified left pixel, its source position in the raw left image.
    pub fn map_left(&self) -> &UndistortMap {
        &self.maps[0]
    }

    /// For each rectified right pixel, its source position in the raw right image.
    pub fn map_right(&self) -> &UndistortMap {
        &self.maps[1]
    }

    /// The rectified pixel of a raw left pixel (`None` when it cannot be undistorted or its
    /// ray leaves the rectified camera's front).
    pub fn rectify_left(&self, raw: &Vector2<f64>) -> Option<Vector2<f64>> {
        self.rectify(0, raw)
    }

    /// The rectified pixel of a raw right pixel (see [`StereoRectification::rectify_left`]).
    pub fn rectify_right(&self, raw: &Vector2<f64>) -> Option<Vector2<f64>> {
        self.rectify(1, raw)
    }

    fn rectify(&self, side: usize, raw: &Vector2<f64>) -> Option<Vector2<f64>> {
        let ray = rectified_ray(&self.cameras[side], &self.rotations[side], raw)?;
        self.pinhole.project(&ray)
    }
}

/// `(R_left, R_right) = (W Q, W Q^-1)` of the module documentation.
fn rectifying_rotations(t_rl: &Isometry3<f64>) -> Result<[Rotation3<f64>; 2], RectifyError> {
    let q = t_rl.rotation.into_inner();
    // The same rotation with a non-negative scalar part, so that `1 + w > 0` below.
    let q = if q.w < 0.0 { -q } else { q };
    // Half rotation: `R^(1/2) = (1 + q) / |1 + q|` for a unit quaternion `q` with `w >= 0`.
    let half = UnitQuaternion::new_normalize(Quaternion::new(1.0 + q.w, q.i, q.j, q.k));
    let t = half.inverse_transform_vector(&t_rl.translation.vector);
    let direction = t.normalize();
    if direction.x.abs() < direction.y.abs().max(direction.z.abs()) {
        return Err(RectifyError::NotSideBySide {
            direction: direction.into(),
        });
    }
    if direction.x > 0.0 {
        return Err(RectifyError::CamerasSwapped);
    }
    // Smallest rotation taking unit `a` onto unit `b`: `(1 + a.b, a x b)` normalised (here
    // `a.b = -direction.x > 0`).
    let target = -Vector3::x();
    let axis = direction.cross(&target);
    let w = UnitQuaternion::new_normalize(Quaternion::new(
        1.0 + direction.dot(&target),
        axis.x,
        axis.y,
        axis.z,
    ));
    Ok([
        (w * half).to_rotation_matrix(),
        (w * half.inverse()).to_rotation_matrix(),
    ])
}

/// The ray `R (x_n, 1)` of a raw pixel in the rectified camera, `None` when the pixel cannot be
/// undistorted or the ray does not point forwards.
fn rectified_ray(
    camera: &Camera,
    rotation: &Rotation3<f64>,
    raw: &Vector2<f64>,
) -> Option<Vector3<f64>> {
    let xn = camera.pixel_to_normalized(raw)?;
    let ray = rotation * Vector3::new(xn.x, xn.y, 1.0);
    (ray.z > 0.0).then_some(ray)
}

/// An axis-aligned rectangle of rectified normalized coordinates `[x0, x1] x [y0, y1]`.
#[derive(Debug, Clone, Copy)]
struct ViewRect {
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
}

impl ViewRect {
    fn everything() -> Self {
        Self {
            x0: f64::NEG_INFINITY,
            x1: f64::INFINITY,
            y0: f64::NEG_INFINITY,
            y1: f64::INFINITY,
        }
    }

    /// The rectangle bounded by the innermost rectified point of each raw image edge.
    fn of(
        index: usize,
        camera: &Camera,
        rotation: &Rotation3<f64>,
        width: usize,
        height: usize,
    ) -> Result<Self, RectifyError> {
        let (w, h) = ((width - 1) as f64, (height - 1) as f64);
        let point = |u: f64, v: f64| {
            rectified_ray(camera, rotation, &Vector2::new(u, v))
                .map(|r| Vector2::new(r.x / r.z, r.y / r.z))
                .ok_or(RectifyError::BorderOutOfView {
                    camera: index,
                    pixel: [u, v],
                })
        };
        let mut rect = Self::everything();
        for y in 0..height {
            let v = y as f64;
            rect.x0 = rect.x0.max(point(0.0, v)?.x);
            rect.x1 = rect.x1.min(point(w, v)?.x);
        }
        for x in 0..width {
            let u = x as f64;
            rect.y0 = rect.y0.max(point(u, 0.0)?.y);
            rect.y1 = rect.y1.min(point(u, h)?.y);
        }
        Ok(rect)
    }

    fn intersect(&self, other: &Self) -> Self {
        Self {
            x0: self.x0.max(other.x0),
            x1: self.x1.min(other.x1),
            y0: self.y0.max(other.y0),
            y1: self.y1.min(other.y1),
        }
    }

    /// The pinhole with `fy = aspect fx` whose `width x height` image is the largest one
    /// centred in the rectangle.
    fn framing(&self, aspect: f64, width: usize, height: usize) -> Result<Pinhole, RectifyError> {
        let (span_x, span_y) = (self.x1 - self.x0, self.y1 - self.y0);
        if !(span_x > 0.0 && span_y > 0.0) {
            return Err(RectifyError::NoCommonView);
        }
        let (w, h) = ((width - 1) as f64, (height - 1) as f64);
        let fx = (w / span_x).max(h / (aspect * span_y));
        let fy = aspect * fx;
        let cx = 0.5 * w - fx * 0.5 * (self.x0 + self.x1);
        let cy = 0.5 * h - fy * 0.5 * (self.y0 + self.y1);
        Ok(Pinhole::new(fx, fy, cx, cy)?)
    }
}
