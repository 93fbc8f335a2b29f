//! Two-view and pose geometry for vofront.
//!
//! - [`lie`], [`camera`], [`undistort_map`]: re-exported from `vofront-core` (SO(3) / SE(3),
//!   camera models), so `vofront_geometry::camera::Camera` and friends keep their paths;
//! - [`essential`]: five-point and eight-point solvers, Sampson error, pose recovery;
//! - [`homography`]: four-point DLT and decomposition into `(R, t, n)`;
//! - [`ransac`]: LO-MSAC driver generic over an [`ransac::Estimator`];
//! - [`residual`]: Sampson, symmetric transfer and reprojection errors, one answer for a
//!   degenerate denominator (infinite: an outlier);
//! - [`relative_pose`]: the full two-view pipeline [`estimate_relative_pose`];
//! - [`triangulate`]: DLT and midpoint triangulation;
//! - [`pnp`]: P3P in RANSAC with robust motion-only refinement, [`solve_pnp_ransac`];
//! - [`bundle`]: windowed bundle adjustment of keyframe poses and points, [`bundle_adjust`].
//!
//! Pose convention everywhere: `T_21: Isometry3<f64>` maps points of frame 1 into frame 2,
//! `x2 = R x1 + t`.
//!
//! Every result type ([`RelativePose`], [`PnpResult`], [`BundleReport`],
//! [`homography::HomographyDecomposition`], [`essential::PoseRecovery`],
//! [`ransac::RansacResult`], [`relative_pose::RelRefinement`]) derives
//! `serde::Serialize`, fields under their Rust names, with nalgebra's own layouts: an
//! `Isometry3` is `{"rotation": [qi, qj, qk, qw], "translation": [x, y, z]}` (the unit
//! quaternion's vector part first, then its scalar), a `Point3` or `Vector3` is `[x, y, z]`, and a
//! fixed-size matrix (`Matrix3`, `Rotation3`, `Matrix6` covariances) is one flat array in
//! column-major order. The [`vofront_robust::Quality`] inside is the record the `vofront` JSON
//! prints.
//!
//! The main entry point, two pixel point lists in, the relative pose out:
//!
//! ```
//! use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2};
//! use vofront_geometry::relative_pose::{estimate_relative_pose, RelativePoseConfig};
//! use vofront_geometry::{Camera, Pinhole};
//! let camera = Camera::pinhole(Pinhole { fx: 500.0, fy: 500.0, cx: 320.0, cy: 240.0 });
//! let t_21 = Isometry3::from_parts(
//!     Translation3::new(0.2, 0.0, 0.02),
//!     UnitQuaternion::from_euler_angles(0.01, -0.03, 0.02),
//! );
//! let pixel = |p: Point3<f64>| Vector2::new(500.0 * p.x / p.z + 320.0, 500.0 * p.y / p.z + 240.0);
//! let (mut x1, mut x2) = (Vec::new(), Vec::new());
//! for i in 0..100 {
//!     let k = i as f64;
//!     let p = Point3::new(2.0 * (1.7 * k).sin(), 1.5 * (2.3 * k).cos(), 4.0 + (0.9 * k).sin());
//!     x1.push(pixel(p));
//!     x2.push(pixel(t_21 * p));
//! }
//! let fit = estimate_relative_pose(&x1, &x2, &camera, &RelativePoseConfig::default()).unwrap();
//! assert!(fit.rotation().angle_to(&t_21.rotation) < 1e-6);
//! assert!((fit.translation() - t_21.translation.vector.normalize()).norm() < 1e-6);
//! ```
#![warn(missing_docs)]

pub mod bundle;
pub mod error;
pub mod essential;
pub mod homography;
pub mod p3p;
pub mod pnp;
pub mod ransac;
pub mod relative_pose;
pub mod residual;
pub mod triangulate;

pub use vofront_core::{camera, lie, undistort_map};
pub use vofront_core::{
    Camera, CameraError, Distortion, KannalaBrandt, Lens, Pinhole, UndistortMap,
};

pub use bundle::{bundle_adjust, BundleConfig, BundleProblem, BundleReport, Observation};
pub use error::GeometryError;
pub use pnp::{
    add_point_covariances, pnp_quality, solve_pnp_ransac, solve_pnp_ransac_with_point_covariances,
    solve_pnp_ransac_with_sigmas, PnpConfig, PnpEvidence, PnpResult,
};
pub use ransac::RansacConfig;
pub use relative_pose::{estimate_relative_pose, Model, RelativePose, RelativePoseConfig};
pub use triangulate::{triangulate_dlt, triangulate_midpoint};
