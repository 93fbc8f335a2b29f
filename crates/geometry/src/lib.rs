//! Two-view and pose geometry for vofront.
//!
//! - [`lie`]: SO(3) / SE(3) exp, log and Jacobians used by every vofront crate;
//! - [`camera`]: pinhole intrinsics with radial-tangential distortion.
//!
//! Pose convention everywhere: `T_21: Isometry3<f64>` maps points of frame 1 into frame 2,
//! `x2 = R x1 + t`.
#![warn(missing_docs)]

pub mod camera;
pub mod lie;

pub use camera::{Camera, CameraError, Distortion, Pinhole};
