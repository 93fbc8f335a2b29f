//! The parts of a sparse direct monocular tracker (SVO/DSO-style) that are checked against
//! their equations one by one:
//!
//! - [`select`]: one point per image block by gradient, coarser pyramid levels filling the
//!   blocks level 0 leaves empty;
//! - [`filter`]: the Gaussian inverse-depth filter of a point;
//! - [`epipolar`]: the search of a reference pixel along its epipolar segment in a later image
//!   and the inverse depth it measures, with the geometric variance;
//! - [`bundle`]: the windowed photometric bundle adjustment of keyframe poses, brightness and
//!   inverse depths;
//! - [`points`]: keyframe points (pixel, gradient, filter), their refinement in each tracked
//!   frame, activation, and their transfer into the next keyframe.
//!
//! Frame tracking uses the SE(3) aligner with the active points as a sparse reference
//! ([`crate::Se3Reference::from_inverse_depths`]); the sequential tracker is the facade's
//! `odometry::direct_mono`.

pub mod bundle;
pub mod epipolar;
pub mod filter;
pub mod points;
pub mod select;

pub use bundle::{
    photometric_bundle, BundleConfig, BundleFrame, BundlePoint, BundleResult, FrameState,
};
pub use epipolar::{EpipolarConfig, EpipolarError, EpipolarMatch, EpipolarPair};
pub use filter::DepthFilter;
pub use points::{active_points, refine_points, transfer_points, DepthRules, MonoPoint};
pub use select::{select_points, Candidate, SelectConfig};

#[cfg(test)]
mod tests;
