//! ORB features and Hamming matching for vofront.
//!
//! - [`Orb`]: image pyramid (`scale_levels` levels, ratio `scale_factor`), FAST-9 corners with a
//!   per-cell threshold fallback and non-maximum suppression, Harris ranking, a quadtree
//!   spread of `n_features` split across levels in proportion to their area, orientation by
//!   intensity centroid and steered BRIEF with the learned ORB pattern ([`pattern`]), so the
//!   256-bit [`Descriptor`]s compare with OpenCV's ORB;
//! - [`match_descriptors`]: brute-force Hamming kNN-2 with ratio test, cross-check and maximum
//!   distance, parallel with rayon;
//! - [`match_windowed`]: the same restricted to a radius around predicted positions, for
//!   frame-to-frame tracking;
//! - [`match_stereo`]: left features matched along their rows in the right image of a
//!   rectified pair, with sub-pixel disparities.
//!
//! Positions are level-0 pixels, x right, y down, `(0, 0)` the centre of the top-left pixel.
//!
//! ```
//! use vofront_features::{match_descriptors, MatchConfig, Orb, OrbConfig};
//! use vofront_image::Image;
//! // A checkerboard of 12-px squares with a gradient: plenty of corners.
//! let data = (0..120usize)
//!     .flat_map(|y| (0..160usize).map(move |x| (x, y)))
//!     .map(|(x, y)| if (x / 12 + y / 12) % 2 == 0 { 40 + (x / 2) as u8 } else { 210 - (y / 2) as u8 })
//!     .collect();
//! let img = Image::new(160, 120, data).unwrap();
//! let orb = Orb::new(OrbConfig { n_features: 200, ..OrbConfig::default() }).unwrap();
//! let f = orb.detect_and_describe(&img).unwrap();
//! assert!(f.len() > 20 && f.len() <= 200);
//! let m = match_descriptors(f.descriptors(), f.descriptors(), &MatchConfig { ratio: None, ..MatchConfig::default() });
//! assert!(m.iter().all(|m| m.distance == 0));
//! ```
#![warn(missing_docs)]

mod describe;
pub mod descriptor;
mod distribute;
mod fast;
mod harris;
pub mod matching;
pub mod orb;
pub mod pattern;
mod pyramid;
pub mod stereo;
pub mod windowed;

pub use descriptor::Descriptor;
pub use matching::{knn2, match_descriptors, Knn2, Match, MatchConfig};
pub use orb::{Feature, Features, Orb, OrbConfig};
pub use stereo::{match_stereo, StereoConfig, StereoMatch};
pub use windowed::match_windowed;

/// Errors of feature detection and matching.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeatureError {
    /// A configuration value is out of range.
    #[error("invalid configuration: {0}")]
    InvalidConfig(&'static str),
    /// A per-feature input has the wrong length.
    #[error("expected {expected} entries (one per query feature), got {got}")]
    LengthMismatch {
        /// Number of query features.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A search radius that is negative or not finite.
    #[error("invalid search radius {0}")]
    InvalidRadius(f32),
}
