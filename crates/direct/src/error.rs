//! Typed failures of the direct methods.

use thiserror::Error;
use vofront_core::CameraError;
use vofront_image::ImageError;
use vofront_robust::SolveError;

/// Everything the direct aligners and the KLT tracker refuse to do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DirectError {
    /// Two images (or an image and a depth map) that must have the same size do not.
    #[error("size mismatch: expected {expected:?}, found {found:?} (width, height)")]
    SizeMismatch {
        /// `(width, height)` required.
        expected: (usize, usize),
        /// `(width, height)` given.
        found: (usize, usize),
    },
    /// A pixel buffer whose length is not `width * height`.
    #[error("buffer holds {len} values, a {width}x{height} plane needs {}", width * height)]
    BadBuffer {
        /// Values in the buffer.
        len: usize,
        /// Declared width.
        width: usize,
        /// Declared height.
        height: usize,
    },
    /// The image is too small for the method.
    #[error("image of {width}x{height} pixels is smaller than the minimum {min}x{min}")]
    ImageTooSmall {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
        /// Minimum side, pixels.
        min: usize,
    },
    /// No reference pixel has a usable (finite, positive, in range) depth.
    #[error("no reference pixel has a valid depth")]
    NoValidDepth,
    /// Too few pixels with a usable gradient (a flat or nearly flat image).
    #[error("not enough texture: {pixels} usable pixels, at least {required} needed")]
    NoTexture {
        /// Usable pixels found.
        pixels: usize,
        /// Minimum needed.
        required: usize,
    },
    /// Too few residuals remained valid during the optimisation (the warp left the image).
    #[error("only {valid} residuals stayed valid, at least {required} needed")]
    TooFewValid {
        /// Valid residuals.
        valid: usize,
        /// Minimum needed.
        required: usize,
    },
    /// The normal equations are degenerate (aperture problem, collinear gradients) or not finite.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// Invalid camera parameters.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// A configuration value out of its domain.
    #[error("invalid configuration: {0}")]
    InvalidConfig(&'static str),
    /// The estimated brightness gain `a` left `[1 / max_gain, max_gain]`: the alignment failed
    /// (a wrong pose "explains" the current image by flattening the reference, `a -> 0`).
    #[error("implausible brightness gain {a:.3} (accepted range [1/{max_gain}, {max_gain}]): alignment failed")]
    ImplausibleGain {
        /// The gain found.
        a: f64,
        /// The accepted bound.
        max_gain: f64,
    },
    /// Any other failure of an image operation.
    #[error(transparent)]
    Image(ImageError),
    /// An input value (pose, brightness) is NaN or infinite.
    #[error("input contains NaN or infinite values")]
    NotFinite,
}

impl From<ImageError> for DirectError {
    /// The image crate's failures under the direct methods' names (the variants they had before
    /// the image type moved), so that callers keep matching the same errors.
    fn from(e: ImageError) -> Self {
        match e {
            ImageError::BadBuffer { len, width, height } => {
                DirectError::BadBuffer { len, width, height }
            }
            ImageError::SizeMismatch { expected, found } => {
                DirectError::SizeMismatch { expected, found }
            }
            ImageError::ImageTooSmall { width, height, min } => {
                DirectError::ImageTooSmall { width, height, min }
            }
            ImageError::InvalidConfig(what) => DirectError::InvalidConfig(what),
            other => DirectError::Image(other),
        }
    }
}
