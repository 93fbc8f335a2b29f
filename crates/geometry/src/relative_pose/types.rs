//! The settings and the result of [`super::estimate_relative_pose`]. A leaf module.

use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use vofront_robust::{Quality, QualityConfig};

use crate::ransac::RansacConfig;

/// Settings of [`super::estimate_relative_pose`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativePoseConfig {
    /// RANSAC settings of both models; `ransac.threshold` is the inlier threshold on the
    /// Sampson distance in pixels (the homography's transfer threshold is derived from it),
    /// `ransac.max_iterations` caps each model, and results are reproducible for a given
    /// `ransac.seed`. `ransac.lo_max_inliers` bounds the essential matrix's local optimisation
    /// only ([`LO_MAX_INLIERS`] by default): the homography's refit, one linear fit, uses every
    /// inlier.
    pub ransac: RansacConfig,
    /// Nonlinear refinement of `(R, t)` on the inliers.
    pub refine: bool,
    /// Median parallax (degrees) below which `low_parallax` flags the translation direction as
    /// poorly determined regardless of its uncertainty (0, no such cut: the flag follows the
    /// direction's predicted sigma, [`QualityConfig::max_direction_sigma_deg`]); a caller that
    /// needs parallax for its own reasons (triangulating a map) may set it.
    pub min_parallax_deg: f64,
    /// Relative standard deviation of the camera's focal length (0.005: a calibration good to
    /// half a percent, as checkerboard calibrations and published dataset calibrations are;
    /// the KITTI calibration and its ground truth disagree by 0.9%). A focal error scales the
    /// rotation's pan and tilt and moves the epipole for every correspondence alike, so it is
    /// added to the covariance of `(R, t)` as `focal_uncertainty^2 v v^T` with `v` the
    /// estimate's sensitivity to it ([`super::intrinsics_sensitivity`]). 0 for exact
    /// intrinsics.
    pub focal_uncertainty: f64,
    /// Standard deviation of the principal point, pixels, each axis (2: calibration toolboxes
    /// state 0.5-1 px for it, and independent calibrations of one camera differ by a few
    /// pixels). It moves the epipole, hence the translation direction by about
    /// `principal_point_uncertainty / f` radians in forward motion, and is added to the
    /// covariance as the focal term is. 0 for exact intrinsics.
    pub principal_point_uncertainty_px: f64,
    /// `S_H / (S_H + S_E)` above which the homography is used.
    pub homography_ratio: f64,
    /// Points farther than this many baselines are not counted by the chirality test.
    pub far_distance: f64,
    /// Minimum support of an `ok` pose ([`RelativePose::quality`]).
    pub quality: QualityConfig,
}

/// Most inliers a local optimisation of the relative pose refits on
/// ([`RansacConfig::lo_max_inliers`]). Local optimisation only has to reach the basin of the
/// best model, and an eight-point fit with four Sampson IRLS steps on 512 evenly spread inliers
/// does (on the 199 shared real pairs every verdict is unchanged); the final refinement uses
/// every inlier. Each polish then costs at most that many rows: on TUM `case_1` (1134 inliers)
/// the relative pose takes 0.72x the time of refitting on all of them.
pub const LO_MAX_INLIERS: usize = 512;

impl Default for RelativePoseConfig {
    fn default() -> Self {
        Self {
            // Every hypothesis that beats the best raw score is polished
            // ([`RansacConfig::lo_skip_shared`] off): in forward motion the distant points fit
            // a wrong motion as well as the true one, and skipping the true motion's
            // hypotheses for sharing them ended on the wrong one.
            ransac: RansacConfig {
                lo_max_inliers: LO_MAX_INLIERS,
                ..RansacConfig::default()
            },
            refine: true,
            min_parallax_deg: 0.0,
            focal_uncertainty: 0.005,
            principal_point_uncertainty_px: 2.0,
            homography_ratio: 0.45,
            far_distance: 50.0,
            quality: QualityConfig::default(),
        }
    }
}

/// Which model produced the pose; the JSON spelling is the lower-case name (`essential`,
/// `homography`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Model {
    /// The essential matrix (general scene).
    Essential,
    /// The homography (planar scene or pure rotation).
    Homography,
}

/// Relative pose `T_21` between two views: the pose, the model it comes from, the inlier set
/// with its triangulated points, the flags and the quality record (each stored once; the
/// rotation, translation and counts are accessors).
///
/// Serialised field by field (see the crate documentation for nalgebra's layouts):
/// `{"pose": {"rotation": [qi, qj, qk, qw], "translation": [x, y, z]}, "model": "essential",
/// "inliers": [true, ...], "points": [[x, y, z] or null, ...], "parallax_deg", "low_parallax",
/// "pure_rotation", "ambiguous", "alternative": pose or null, "homography_score_ratio",
/// "iterations": {"essential", "homography"}, "quality": {...}}`, `quality` being the
/// [`Quality`] record the `vofront relpose` and `two-view` JSON print.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RelativePose {
    /// `T_21 = (R_21, t_21)`, unit translation direction `t_21` (zero for a pure rotation).
    pub pose: Isometry3<f64>,
    /// Model used.
    pub model: Model,
    /// Per input correspondence: consistent with the final pose (Sampson distance under the
    /// threshold; for a pure rotation, transfer error under the threshold).
    pub inliers: Vec<bool>,
    /// Per input correspondence: the triangulated point in camera 1, in baseline units, for
    /// inliers in front of both cameras and closer than the far limit.
    pub points: Vec<Option<Point3<f64>>>,
    /// Median parallax angle of the triangulated points, degrees.
    pub parallax_deg: f64,
    /// The translation direction is undetermined at its stated uncertainty: its sigma exceeds
    /// [`QualityConfig::max_direction_sigma_deg`], the derotated disparities show no
    /// translation above the pixel noise (a chi-square test at 3 standard scores), the median
    /// parallax is under
    /// `min_parallax_deg`, or the motion is a pure rotation ([`vofront_robust::Reason::LowParallax`] in the
    /// quality's reasons).
    pub low_parallax: bool,
    /// A rotation alone explains the correspondences: the translation is reported as zero and
    /// the rotation is the least-squares rotation of the rays.
    pub pure_rotation: bool,
    /// Two motions explain the data about equally (planar two-fold ambiguity).
    pub ambiguous: bool,
    /// The other motion when `ambiguous`.
    pub alternative: Option<Isometry3<f64>>,
    /// `S_H / (S_H + S_E)`.
    pub homography_score_ratio: f64,
    /// RANSAC iterations of the two models.
    pub iterations: RansacIterations,
    /// Verdict, reasons, support (with the a-contrario chance test), Sampson noise scale and
    /// the covariance of the rotation and of the translation direction; `iterations` there is
    /// the RANSAC total and `converged` is always true (the refit stops at a stable inlier set
    /// or its round limit).
    pub quality: Quality,
}

impl RelativePose {
    /// `R_21`.
    pub fn rotation(&self) -> UnitQuaternion<f64> {
        self.pose.rotation
    }

    /// Unit translation direction `t_21`, zero for a pure rotation.
    pub fn translation(&self) -> Vector3<f64> {
        self.pose.translation.vector
    }

    /// Number of `true` in [`Self::inliers`].
    pub fn inlier_count(&self) -> usize {
        self.inliers.iter().filter(|&&b| b).count()
    }

    /// Number of `Some` in [`Self::points`].
    pub fn triangulated(&self) -> usize {
        self.points.iter().filter(|p| p.is_some()).count()
    }
}

/// RANSAC iterations of the two models fitted by [`super::estimate_relative_pose`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct RansacIterations {
    /// Iterations of the essential matrix's LO-MSAC.
    pub essential: usize,
    /// Iterations of the homography's LO-MSAC.
    pub homography: usize,
}

impl RansacIterations {
    /// Both together.
    pub fn total(&self) -> usize {
        self.essential + self.homography
    }
}

/// `T_21` from a rotation and a translation.
pub(super) fn isometry(r: &Rotation3<f64>, t: &Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(*t),
        UnitQuaternion::from_rotation_matrix(r),
    )
}
