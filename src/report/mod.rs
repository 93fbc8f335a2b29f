//! What the command line prints, as library types: every report here derives
//! `serde::Serialize`, and the `vofront` program's JSON is exactly their serialisation, so a
//! library user gets the same record as a shell user. Where a report carries a library record
//! it embeds it rather than copying fields: the `quality` objects are the estimates' own
//! [`vofront_robust::Quality`], `model` the geometry crate's `Model` and the feature `ms` the
//! pipeline's [`crate::pipeline::FeatureTimings`]. The raw results themselves
//! (`RelativePose`, `Se3Result`, `FrameEstimate`, ...) derive `Serialize` as well.
//!
//! - [`odometry`]: the summary of one sequence run ([`odometry::OdometryReport`], the
//!   `odometry --json` object) from the run's session, output and evaluation;
//! - [`two_view`]: the report of one frame pair's feature and direct estimates
//!   ([`two_view::TwoViewReport`], the `two-view` command's JSON) from the
//!   [`crate::two_view::Outcome`] of [`crate::two_view::estimate`].

pub mod odometry;
pub mod two_view;

use nalgebra::{Isometry3, Matrix3};
use serde::Serialize;

/// A 3x3 matrix as three rows, the JSON layout of every rotation `R`.
pub type Rows3 = [[f64; 3]; 3];

/// Rows of `m`: `rows(m)[i][j] = m[(i, j)]`.
pub fn rows(m: &Matrix3<f64>) -> Rows3 {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

/// Rotation matrix `R` of `x2 = R x1 + t`, as rows.
pub fn rotation_rows(pose: &Isometry3<f64>) -> Rows3 {
    rows(&pose.rotation.to_rotation_matrix().into_inner())
}

/// One estimator's entry: its report, or `{"error": "..."}` when it failed.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Entry<T> {
    /// The estimator produced an estimate.
    Ok(T),
    /// The estimator failed; the message says why.
    Failed {
        /// One-line reason.
        error: String,
    },
}

impl<T> Entry<T> {
    /// The report of `r`, built by `f`, or the error's message (its `Display`).
    pub fn of<V, E: std::fmt::Display>(r: &Result<V, E>, f: impl FnOnce(&V) -> T) -> Self {
        match r {
            Ok(v) => Entry::Ok(f(v)),
            Err(e) => Entry::Failed {
                error: e.to_string(),
            },
        }
    }
}
