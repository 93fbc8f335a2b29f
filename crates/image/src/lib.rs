//! Image processing for vofront: one image type and the operations on it (kornia-imgproc's
//! role). Depends on no other vofront crate.
//!
//! - [`Image<T>`](Image): a row-major `u8` or `f32` image with private fields, validating
//!   constructors, checked accessors and conversions from and to the `image` crate's types;
//! - [`filter`]: the binomial blur, factor-2 decimation, central-difference gradients,
//!   bilinear sampling ([`sample`]);
//! - [`pyramid`]: factor-2 pyramids ([`Pyramid`]); [`scale_pyramid`]: ORB's scale-factor
//!   pyramid (bilinear resampling of 8-bit images);
//! - [`remap`]: precomputed resampling maps (undistortion built once per camera);
//! - [`disparity`]: semi-dense block-matching disparity of a rectified stereo pair;
//! - [`corners`]: Shi-Tomasi corners; [`klt`]: pyramidal Lucas-Kanade tracking on reusable
//!   pyramids, optionally seeded with predicted positions.
//!
//! Pixel `(x, y)` is the center of column `x`, row `y`; `(0, 0)` is the top-left pixel.
//!
//! ```
//! use vofront_image::{Image, ImageError};
//! let img = Image::new(3, 2, vec![0u8, 10, 20, 30, 40, 50]).unwrap();
//! assert_eq!(img.get(1, 1), Some(&40));
//! assert_eq!(img.to_f32().sample(0.5, 0.5), Some(20.0));
//! assert!(matches!(Image::new(3, 2, vec![0u8; 5]), Err(ImageError::BadBuffer { .. })));
//! ```
#![warn(missing_docs)]

pub mod buffer;
pub mod corners;
pub mod disparity;
pub mod error;
pub mod filter;
pub mod klt;
pub mod pyramid;
pub mod remap;
pub mod sample;
pub mod scale_pyramid;

pub use buffer::Image;
pub use corners::good_features_to_track;
pub use error::ImageError;
pub use filter::Gradients;
#[allow(deprecated)]
pub use klt::TrackStatus;
pub use klt::{track_klt, track_klt_pyramids, KltConfig, KltPyramid, KltStatus, KltTrack};
pub use pyramid::Pyramid;
pub use remap::Remap;
pub use sample::Bilinear;
