//! Typed errors of the geometry estimators.

use thiserror::Error;

use crate::camera::CameraError;

/// Why a geometric estimate could not be produced.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GeometryError {
    /// Fewer correspondences than the minimal solver needs.
    #[error("too few correspondences: got {got}, need at least {need}")]
    TooFewCorrespondences {
        /// Correspondences given (or left after removing invalid ones).
        got: usize,
        /// Minimum required.
        need: usize,
    },
    /// The two input slices have different lengths.
    #[error("mismatched input lengths: {0} vs {1}")]
    LengthMismatch(usize, usize),
    /// A coordinate is NaN or infinite.
    #[error("non-finite coordinate in the input")]
    NonFinite,
    /// The configuration does not determine the model (identical points, collinear points,
    /// no parallax, a solver returned nothing sensible...).
    #[error("degenerate configuration: {0}")]
    Degenerate(String),
    /// The camera parameters are invalid.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// RANSAC found no model with enough inliers.
    #[error("no model found with at least {need} inliers (best had {best})")]
    NoModel {
        /// Inliers of the best hypothesis.
        best: usize,
        /// Inliers required.
        need: usize,
    },
    /// A configuration value (or an index into the input) is out of range; the payload names
    /// the rule, as in every vofront crate's `InvalidConfig`.
    #[error("invalid configuration: {0}")]
    InvalidConfig(&'static str),
}
