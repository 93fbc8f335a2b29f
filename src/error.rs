//! The facade's typed failures: [`VoError`], what the two-view estimator and the sequential
//! trackers fail with.

use thiserror::Error;
use vofront_direct::DirectError;
use vofront_features::FeatureError;
use vofront_geometry::GeometryError;

/// Anything the facade's pipelines and trackers can fail with.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum VoError {
    /// Feature detection or matching failed.
    #[error("features: {0}")]
    Features(#[from] FeatureError),
    /// Geometry estimation failed (too few or degenerate correspondences).
    #[error("geometry: {0}")]
    Geometry(#[from] GeometryError),
    /// Direct alignment failed.
    #[error("direct: {0}")]
    Direct(#[from] DirectError),
    /// The frame has no depth map and the tracker needs one.
    #[error("frame has no depth")]
    NoDepth,
    /// Too few of something (PnP inliers, features with depth) for the estimate to count.
    #[error("{got} {what}, {need} needed")]
    TooFew {
        /// What was counted.
        what: &'static str,
        /// How many there were.
        got: usize,
        /// How many the tracker needs.
        need: usize,
    },
    /// The direct alignment's inlier ratio is below the tracker's minimum.
    #[error("inlier ratio {ratio:.2} below {min:.2}")]
    LowInlierRatio {
        /// Inliers over valid pixels.
        ratio: f64,
        /// The tracker's minimum.
        min: f64,
    },
    /// The stereo pair could not be prepared (no right image, a size other than the
    /// rectification's, a failed remap): the stereo trackers' frame error, as text.
    #[error("stereo frame: {0}")]
    StereoFrame(String),
    /// The estimate exists but its quality verdict is `failed`.
    #[error("{what} failed: {reasons}")]
    Rejected {
        /// Which estimate ("SE(3)", "PnP", ...).
        what: &'static str,
        /// The verdict's reasons, `;`-separated names.
        reasons: String,
    },
}
