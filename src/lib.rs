//! vofront: a pure-Rust visual-odometry front-end.
//!
//! Two camera frames in, a relative pose `T_21` (points of frame 1 into frame 2,
//! `x2 = R x1 + t`) and quality scores out. The workspace crates are re-exported here:
//!
//! - [`core`]: SO(3)/SE(3) and camera models, shared by every crate;
//! - [`robust`]: losses, IRLS, damped normal equations shared by every estimator;
//! - [`geometry`]: two-view and PnP geometry (re-exports `core`'s camera and Lie modules);
//! - [`features`]: ORB detection, description and Hamming matching;
//! - [`direct`]: photometric alignment and KLT;
//! - `fixtures` (feature `fixtures`, on with the default `cli`): the synthetic scenes of
//!   `vofront-fixtures`, with exact ground truth.
//!
//! Features: `cli` (default) builds the `vofront` program (command-line parsing, progress bar,
//! signal handling, the synthetic demo); a library user needs none of it:
//! `vofront = { version = "0.1", default-features = false }`.
#![warn(missing_docs)]

pub mod compare;
pub mod dataset;
pub mod draw;
pub mod error;
pub mod eval;
pub mod input;
pub mod odometry;
pub mod pipeline;
pub mod presets;
pub mod report;
pub mod timing;
pub mod trajectory;
pub mod two_view;

pub use vofront_core as core;
pub use vofront_direct as direct;
pub use vofront_features as features;
#[cfg(feature = "fixtures")]
pub use vofront_fixtures as fixtures;
pub use vofront_geometry as geometry;
pub use vofront_image as image;
pub use vofront_robust as robust;
