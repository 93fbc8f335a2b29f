//! Essential matrix solvers, the Sampson error and the decomposition into poses.
//!
//! Every solver works on rays in the camera frames (unit bearings or homogeneous normalized
//! coordinates `(x, y, 1)`), never on pixels, and satisfies `x2^T E x1 = 0` with
//! `E = [t]_x R` for `x2 = R x1 + t`.

mod decompose;
mod eight_point;
mod five_point;

/// The Sampson error and the per-image epipolar distances, from [`crate::residual`] (their
/// one implementation).
pub use crate::residual::{epipolar_distances_sq, sampson_sq as sampson_error_sq};
pub use decompose::{
    best_by_chirality, decompose_essential, recover_pose, select_by_chirality, PoseRecovery,
    RecoverConfig,
};
pub use eight_point::{essential_8pt, project_to_essential};
pub use five_point::essential_5pt;
