//! Typed failures of the image operations.

use thiserror::Error;

/// Everything the image type and its operations refuse to do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ImageError {
    /// A pixel buffer whose length is not `width * height` (or whose `width * height`
    /// overflows `usize`).
    #[error("buffer holds {len} values, a {width}x{height} image needs {}", width.saturating_mul(*height))]
    BadBuffer {
        /// Values in the buffer.
        len: usize,
        /// Declared width.
        width: usize,
        /// Declared height.
        height: usize,
    },
    /// Two images (or an image and a map) that must have the same size do not.
    #[error("size mismatch: expected {expected:?}, found {found:?} (width, height)")]
    SizeMismatch {
        /// `(width, height)` required.
        expected: (usize, usize),
        /// `(width, height)` given.
        found: (usize, usize),
    },
    /// The image is too small for the operation.
    #[error("image of {width}x{height} pixels is smaller than the minimum {min}x{min}")]
    ImageTooSmall {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
        /// Minimum side, pixels.
        min: usize,
    },
    /// A per-point input has the wrong length.
    #[error("expected {expected} entries (one per point), got {got}")]
    LengthMismatch {
        /// Number of points.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A configuration value out of its domain.
    #[error("invalid configuration: {0}")]
    InvalidConfig(&'static str),
}
