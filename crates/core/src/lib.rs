//! The vocabulary every vofront crate shares: Lie groups, camera models and camera rigs.
//!
//! - [`lie`]: SO(3) / SE(3) hat, exp, log, Jacobians, adjoint and pose normalisation;
//! - [`camera`]: pinhole intrinsics with a lens model ([`Lens`]: radial-tangential or
//!   Kannala-Brandt equidistant), one [`Camera`] type for every model;
//! - [`undistort_map`]: the per-pixel source positions that bring an image to the pinhole
//!   geometry, optionally rotated (the image crates do the resampling);
//! - [`rig`]: a mono or stereo [`Rig`] of cameras with their poses in the body frame;
//! - [`rectify`]: stereo rectification of a rig ([`StereoRectification`], Bouguet).
//!
//! Pose convention everywhere: `T_21: Isometry3<f64>` maps points of frame 1 into frame 2,
//! `x2 = R x1 + t`. This crate depends on nothing but `nalgebra` and `thiserror`.
#![warn(missing_docs)]

pub mod camera;
pub mod lie;
pub mod rectify;
pub mod rig;
pub mod undistort_map;

pub use camera::{Camera, CameraError, Distortion, KannalaBrandt, Lens, Pinhole};
pub use rectify::{RectifyError, StereoRectification};
pub use rig::{Rig, RigCamera, RigError};
pub use undistort_map::UndistortMap;
