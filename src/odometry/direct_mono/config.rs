//! Settings of the direct monocular tracker.

use vofront_direct::mono::{BundleConfig, DepthRules, SelectConfig};
use vofront_direct::{CalibrationPrior, Se3Config};
use vofront_features::{MatchConfig, OrbConfig};
use vofront_geometry::RelativePoseConfig;
use vofront_robust::QualityConfig;

use crate::odometry::keyframe::KeyframePolicy;
use crate::odometry::mono::config::{monocular_matching, monocular_orb};

/// Settings of [`super::DirectMonoTracker`].
#[derive(Debug, Clone)]
pub struct DirectMonoConfig {
    /// SE(3) frame alignment (affine brightness; depths in map units, so wide bounds).
    pub se3: Se3Config,
    /// Point selection of a keyframe.
    pub select: SelectConfig,
    /// Epipolar search, depth filter and activation of the points.
    pub depth: DepthRules,
    /// ORB of the two-view initialisation.
    pub orb: OrbConfig,
    /// Descriptor matching of the initialisation.
    pub matching: MatchConfig,
    /// Two-view pose of the initialisation.
    pub relative: RelativePoseConfig,
    /// Fewest matches and triangulated points of an initialisation.
    pub min_init_points: usize,
    /// Smallest median parallax of an initialisation, degrees.
    pub min_init_parallax_deg: f64,
    /// Frames an initialisation waits for parallax before taking a newer reference.
    pub max_init_frames: usize,
    /// Prior standard deviation of a new point's inverse depth, in units of the keyframe's
    /// median inverse depth (its mean): wide, so that near points are found too.
    pub prior_sigma: f64,
    /// Fewest active points of a keyframe (else the previous keyframe is kept).
    pub min_active_points: usize,
    /// The tracking reference is rebuilt when the active points grew by this factor.
    pub rebuild_growth: f64,
    /// Previous keyframes whose immature points are still refined and handed over.
    pub window: usize,
    /// A keyframe also stays in that window, beyond `window`, while it was made fewer than
    /// this many frames ago: its immature points are then searched in at least this many
    /// frames even when every frame is a keyframe (a fast turn, a low frame rate), so that they
    /// can gather `depth.min_updates` measurements.
    pub seed_frames: usize,
    /// Keyframes before the outgoing one that take part in the photometric bundle adjustment
    /// run at each new keyframe (`bundle`); 0 runs none.
    pub bundle_window: usize,
    /// The windowed photometric bundle adjustment (its first `fixed` frames hold the gauge).
    pub bundle: BundleConfig,
    /// Most points the bundle refines: above it, an even share of the outgoing keyframe's
    /// active points (every k-th in selection order, so spread as the selection is) takes
    /// part; the others keep their filtered depths. The bundle's time grows with its points.
    pub bundle_points: usize,
    /// When to take a new keyframe (translation relative to the median depth, rotation,
    /// tracked ratio, residual growth).
    pub keyframe: KeyframePolicy,
    /// Smallest inlier ratio of a tracked frame.
    pub min_inlier_ratio: f64,
    /// An alignment whose RMSE exceeds this multiple of the keyframe's first one is retried
    /// from the other starts (zero motion, turned by `retry_turn_deg` about x and y).
    pub retry_residual_growth: f64,
    /// Rotation of the perturbed starts, degrees.
    pub retry_turn_deg: f64,
    /// When the frame's mean grey level differs from the keyframe's by more than this
    /// fraction (an exposure change), the retries also start from the prediction with the
    /// gain of the two means.
    pub retry_gain_change: f64,
    /// A tracked frame whose position differs from the constant-velocity prediction by more
    /// than this fraction of the recent step length breaks the trust in the map's scale: it
    /// and every later frame of the map are flagged `inconsistent` (a vehicle or a hand does
    /// not halve or reverse its speed between two frames; a map whose translation collapsed
    /// keeps tracking at its collapsed scale).
    pub max_motion_jump: f64,
    /// The jump is judged only when the recent step is at least this fraction of the
    /// keyframe's median depth (slower motion is within the alignment's noise).
    pub min_judged_step: f64,
    /// Thresholds of the alignment's verdict, used in place of `se3.quality`.
    pub quality: QualityConfig,
}

impl Default for DirectMonoConfig {
    fn default() -> Self {
        Self {
            se3: Se3Config {
                min_depth: 1e-3,
                max_depth: 1e6,
                // An auto-exposure step of 2x must pass (the default bound sits on it).
                max_gain: 3.0,
                // The depths are the map's own, scale-free: no depth-scale error of a sensor.
                calibration: CalibrationPrior {
                    depth_scale: 0.0,
                    ..CalibrationPrior::default()
                },
                ..Se3Config::default()
            },
            select: SelectConfig::default(),
            depth: DepthRules::default(),
            orb: monocular_orb(),
            matching: monocular_matching(),
            relative: RelativePoseConfig::default(),
            min_init_points: 80,
            min_init_parallax_deg: 1.0,
            max_init_frames: 30,
            prior_sigma: 3.0,
            min_active_points: 100,
            rebuild_growth: 1.1,
            // Immature points of the previous keyframe keep converging: in a turn keyframes come
            // every second frame, too soon for a point to be measured three times in one.
            window: 1,
            seed_frames: 3,
            bundle_window: 4,
            // Five iterations: the cost falls little after them, and the bundle runs at every
            // keyframe on the tracking thread.
            bundle: BundleConfig {
                max_iterations: 5,
                ..BundleConfig::default()
            },
            bundle_points: 800,
            keyframe: KeyframePolicy {
                max_relative_translation: 0.15,
                max_rotation_deg: 5.0,
                min_overlap: 0.5,
                max_residual_growth: 1.8,
            },
            min_inlier_ratio: 0.4,
            retry_residual_growth: 3.0,
            retry_turn_deg: 2.0,
            retry_gain_change: 0.2,
            max_motion_jump: 0.5,
            min_judged_step: 0.01,
            // A sparse reference has hundreds of points, not a dense one's thousands of pixels.
            quality: QualityConfig {
                min_pixels: 100,
                ..QualityConfig::default()
            },
        }
    }
}
