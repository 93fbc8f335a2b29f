//! A camera rig: one (mono) or two (stereo) calibrated cameras and where each sits on the body.
//!
//! Frames and units: every camera has its own frame (metres, `Z` forward, `X` right, `Y` down,
//! see [`crate::camera`]); the rig's **body frame** is the frame the extrinsics are given in
//! (EuRoC: the IMU; KITTI: the left camera). Each camera carries `T_BS`, its pose in the body
//! frame: `x_body = T_BS x_camera` (EuRoC's `T_BS` of `sensor.yaml`; identity when unknown).
//! The left camera is the reference one (the camera a monocular tracker uses).
//!
//! ```
//! use nalgebra::{Isometry3, Translation3};
//! use vofront_core::camera::{Camera, Pinhole};
//! use vofront_core::rig::Rig;
//! let cam = Camera::pinhole(Pinhole::new(700.0, 700.0, 600.0, 180.0).unwrap());
//! let right_in_body = Isometry3::from_parts(Translation3::new(0.54, 0.0, 0.0), Default::default());
//! let rig = Rig::stereo(cam, Isometry3::identity(), cam, right_in_body).unwrap();
//! assert!((rig.baseline().unwrap() - 0.54).abs() < 1e-12);
//! // The left camera's centre is 0.54 m to the left of the right camera.
//! assert!((rig.t_right_left().unwrap().translation.vector.x + 0.54).abs() < 1e-12);
//! assert!(Rig::stereo(cam, Isometry3::identity(), cam, Isometry3::identity()).is_err());
//! ```

use nalgebra::Isometry3;
use thiserror::Error;

use crate::camera::{Camera, CameraError};

/// Smallest stereo baseline accepted, metres (a rig whose two centres coincide has no depth).
pub const MIN_BASELINE: f64 = 1e-6;

/// Why a [`Rig`] was refused.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum RigError {
    /// A camera's intrinsics or lens are invalid.
    #[error("camera {index}: {source}")]
    Camera {
        /// 0 for the left camera, 1 for the right one.
        index: usize,
        /// Why the camera is invalid.
        source: CameraError,
    },
    /// A `T_BS` has a non-finite entry.
    #[error("camera {index}: T_BS is not finite")]
    NotFinite {
        /// 0 for the left camera, 1 for the right one.
        index: usize,
    },
    /// The two camera centres (nearly) coincide.
    #[error("stereo baseline {baseline} m is below {MIN_BASELINE} m")]
    ZeroBaseline {
        /// Distance between the two camera centres, metres.
        baseline: f64,
    },
}

/// One camera of a [`Rig`] with its pose in the body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigCamera {
    /// Intrinsics and lens.
    pub camera: Camera,
    /// `T_BS`: the camera's pose in the body frame, `x_body = T_BS x_camera` (metres).
    pub t_bs: Isometry3<f64>,
}

impl RigCamera {
    fn checked(index: usize, camera: Camera, t_bs: Isometry3<f64>) -> Result<Self, RigError> {
        camera
            .validate()
            .map_err(|source| RigError::Camera { index, source })?;
        let finite = t_bs.translation.vector.iter().all(|v| v.is_finite())
            && t_bs.rotation.coords.iter().all(|v| v.is_finite());
        if !finite {
            return Err(RigError::NotFinite { index });
        }
        Ok(Self { camera, t_bs })
    }
}

/// A mono or stereo camera rig (see the module documentation for frames).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rig {
    left: RigCamera,
    right: Option<RigCamera>,
}

impl Rig {
    /// A single camera at the body origin (`T_BS = I`).
    pub fn mono(camera: Camera) -> Result<Self, RigError> {
        Self::mono_in_body(camera, Isometry3::identity())
    }

    /// A single camera with its pose `t_bs` in the body frame.
    pub fn mono_in_body(camera: Camera, t_bs: Isometry3<f64>) -> Result<Self, RigError> {
        Ok(Self {
            left: RigCamera::checked(0, camera, t_bs)?,
            right: None,
        })
    }

    /// A stereo pair: `left` and `right` cameras with their poses `T_BS` in the body frame.
    ///
    /// Errors: an invalid camera or non-finite pose; [`RigError::ZeroBaseline`] when the two
    /// centres are less than [`MIN_BASELINE`] apart.
    pub fn stereo(
        left: Camera,
        t_bs_left: Isometry3<f64>,
        right: Camera,
        t_bs_right: Isometry3<f64>,
    ) -> Result<Self, RigError> {
        let rig = Self {
            left: RigCamera::checked(0, left, t_bs_left)?,
            right: Some(RigCamera::checked(1, right, t_bs_right)?),
        };
        let baseline = (t_bs_right.translation.vector - t_bs_left.translation.vector).norm();
        if baseline < MIN_BASELINE {
            return Err(RigError::ZeroBaseline { baseline });
        }
        Ok(rig)
    }

    /// True for a two-camera rig.
    pub fn is_stereo(&self) -> bool {
        self.right.is_some()
    }

    /// The left (reference) camera.
    pub fn left(&self) -> &Camera {
        &self.left.camera
    }

    /// The right camera of a stereo rig.
    pub fn right(&self) -> Option<&Camera> {
        self.right.as_ref().map(|r| &r.camera)
    }

    /// The left camera with its `T_BS`.
    pub fn left_in_body(&self) -> &RigCamera {
        &self.left
    }

    /// The right camera with its `T_BS`, stereo rigs only.
    pub fn right_in_body(&self) -> Option<&RigCamera> {
        self.right.as_ref()
    }

    /// `T_RL = T_BS_right^-1 T_BS_left`: maps left-camera points into the right camera,
    /// `x_right = T_RL x_left` (metres). `None` for a mono rig.
    pub fn t_right_left(&self) -> Option<Isometry3<f64>> {
        self.right.map(|r| r.t_bs.inverse() * self.left.t_bs)
    }

    /// Distance between the two camera centres, metres (`|t_RL|`). `None` for a mono rig.
    pub fn baseline(&self) -> Option<f64> {
        self.t_right_left().map(|t| t.translation.vector.norm())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Pinhole;
    use nalgebra::Vector3;

    fn cam() -> Camera {
        Camera::pinhole(Pinhole::new(500.0, 500.0, 320.0, 240.0).unwrap())
    }

    #[test]
    fn t_right_left_maps_the_left_centre_to_minus_the_right_offset() {
        let t_bl = Isometry3::new(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.0, 0.2, 0.0));
        let t_br = t_bl * Isometry3::translation(0.11, 0.0, 0.0);
        let rig = Rig::stereo(cam(), t_bl, cam(), t_br).unwrap();
        let t = rig.t_right_left().unwrap();
        assert!((t.translation.vector - Vector3::new(-0.11, 0.0, 0.0)).norm() < 1e-12);
        assert!(t.rotation.angle() < 1e-12);
        assert!((rig.baseline().unwrap() - 0.11).abs() < 1e-12);
        assert!(Rig::mono(cam()).unwrap().t_right_left().is_none());
    }

    #[test]
    fn invalid_rigs_are_typed_errors() {
        let bad = Camera::pinhole(Pinhole {
            fx: -1.0,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
        });
        let i = Isometry3::identity();
        assert!(matches!(
            Rig::stereo(cam(), i, bad, Isometry3::translation(0.1, 0.0, 0.0)),
            Err(RigError::Camera { index: 1, .. })
        ));
        assert!(matches!(
            Rig::stereo(cam(), i, cam(), i),
            Err(RigError::ZeroBaseline { .. })
        ));
        assert!(matches!(
            Rig::stereo(cam(), i, cam(), Isometry3::translation(f64::NAN, 0.0, 0.0)),
            Err(RigError::NotFinite { index: 1 })
        ));
    }
}
