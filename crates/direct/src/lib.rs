//! Direct photometric alignment and sparse optical flow.
//!
//! - [`plane`]: what the aligners take from `vofront_image`, whose [`vofront_image::Image<f32>`]
//!   is every image and depth map here (pyramids, gradients, bilinear sampling, remap);
//! - [`translation`]: robust coarse-to-fine 2D translation `I2(x + d) = I1(x)`;
//! - [`warp2d`]: affine and homography Lucas-Kanade with optional brightness `a I + b`;
//! - [`rgbd`]: reference frames (grey image + metric depth), undistortion, pixel selection;
//! - [`se3`]: SE(3) direct image alignment `I_cur(pi(K T_cur_ref pi^-1(p, d))) = a I_ref(p) + b`,
//!   from a dense RGB-D reference or from given pixels with inverse depths;
//! - [`mono`]: the parts of the sparse direct monocular tracker: point selection, inverse-depth
//!   filters, epipolar search;
//!
//! Shi-Tomasi corners and pyramidal KLT live in `vofront_image` and are re-exported here.
//!
//! Every aligner runs a robust (Huber or Student-t with MAD scale) Levenberg-Marquardt loop
//! (module `lm`) whose normal equations are accumulated in parallel with rayon, and returns typed
//! [`DirectError`]s for bad input (size mismatch, flat images, degenerate geometry).
//!
//! The results ([`TranslationResult`], [`WarpResult`], [`Se3Result`]) derive `serde::Serialize`,
//! fields under their Rust names, in nalgebra's layouts: [`Se3Result::pose`] is
//! `{"rotation": [qi, qj, qk, qw], "translation": [x, y, z]}` (the unit quaternion's vector part,
//! then its scalar), vectors are arrays, fixed-size matrices (the 6x6 covariance of `(rho, phi)`)
//! one flat column-major array, and [`Se3Result::reason`] the snake_case stop reason.
//!
//! ```
//! use vofront_direct::translation::{align_translation, TranslationConfig};
//! use vofront_image::Image;
//! // A smooth pattern and the same pattern moved by (3, -2) pixels: I2(x + d) = I1(x).
//! let f = |x: f32, y: f32| 128.0 + 50.0 * (x / 7.0).sin() * (y / 9.0).cos() + 30.0 * ((x + y) / 13.0).sin();
//! let (w, h) = (160, 120);
//! let grid = |dx: f32, dy: f32| -> Vec<f32> {
//!     (0..w * h).map(|i| f((i % w) as f32 - dx, (i / w) as f32 - dy)).collect()
//! };
//! let img1 = Image::new(w, h, grid(0.0, 0.0)).unwrap();
//! let img2 = Image::new(w, h, grid(3.0, -2.0)).unwrap();
//! let fit = align_translation(&img1, &img2, &TranslationConfig::default()).unwrap();
//! assert!((fit.d.x - 3.0).abs() < 0.05 && (fit.d.y + 2.0).abs() < 0.05, "{:?}", fit.d);
//! ```
#![warn(missing_docs)]

pub mod error;
mod lm;
pub mod mono;
pub mod plane;
pub mod quality;
pub mod rgbd;
pub mod se3;
pub mod translation;
pub mod warp2d;

pub use error::DirectError;
#[allow(deprecated)]
pub use plane::Plane;
pub use plane::{Gradients, Pyramid};
pub use rgbd::{RgbdFrame, Undistorter};
pub use se3::{
    align_se3, photometric_residual_map, CalibrationPrior, InverseDepthPoint, PixelResidual,
    Se3Config, Se3Reference, Se3Result, HALF_CELL_PX,
};
pub use translation::{align_translation, TranslationConfig, TranslationResult};
#[allow(deprecated)]
pub use vofront_image::TrackStatus;
pub use vofront_image::{good_features_to_track, track_klt, KltConfig, KltStatus, KltTrack};
pub use warp2d::{
    align_affine, align_homography, TranslationMethod, WarpConfig, WarpKind, WarpResult,
};
