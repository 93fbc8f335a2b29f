//! Two-view and pose geometry for vofront.
//!
//! - [`lie`]: SO(3) / SE(3) exp, log and Jacobians used by every vofront crate;
//! - [`camera`]: pinhole intrinsics with radial-tangential distortion, [`undistort_map`];
//! - [`essential`]: five-point and eight-point solvers, Sampson error, pose recovery;
//! - [`homography`]: four-point DLT and decomposition into `(R, t, n)`;
//! - [`ransac`]: LO-MSAC driver generic over an [`ransac::Estimator`];
//! - [`relative_pose`]: the full two-view pipeline [`estimate_relative_pose`];
//! - [`triangulate`]: DLT and midpoint triangulation;
//! - [`pnp`]: P3P in RANSAC with robust motion-only refinement, [`solve_pnp_ransac`];
//! - [`bundle`]: windowed bundle adjustment of keyframe poses and points, [`bundle_adjust`].
//!
//! Pose convention everywhere: `T_21: Isometry3<f64>` maps points of frame 1 into frame 2,
//! `x2 = R x1 + t`.
#![warn(missing_docs)]

pub mod bundle;
pub mod camera;
pub mod error;
pub mod essential;
pub mod homography;
pub mod lie;
pub mod p3p;
pub mod pnp;
pub mod ransac;
pub mod relative_pose;
pub mod triangulate;
pub mod undistort_map;

pub use bundle::{bundle_adjust, BundleConfig, BundleProblem, BundleReport, Observation};
pub use camera::{Camera, CameraError, Distortion, Pinhole};
pub use error::GeometryError;
pub use pnp::{solve_pnp_ransac, PnpConfig, PnpResult};
pub use relative_pose::{estimate_relative_pose, Model, RelativePose, RelativePoseConfig};
pub use triangulate::{triangulate_dlt, triangulate_midpoint};
pub use undistort_map::UndistortMap;
