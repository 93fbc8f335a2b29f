//! The image type of the direct methods: the image crate's `f32` image, its factor-2 pyramid,
//! gradients and bilinear taps (see `vofront_image`).

pub(crate) use vofront_image::Bilinear;
pub use vofront_image::{Gradients, Pyramid};

/// A row-major `f32` image (grey levels 0..255 for 8-bit content, metres for depth):
/// [`vofront_image::Image<f32>`].
pub type Plane = vofront_image::Image<f32>;
