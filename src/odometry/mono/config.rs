//! Settings of the monocular tracker, with the defaults it is measured with.

use vofront_features::{MatchConfig, OrbConfig};
use vofront_geometry::bundle::BundleConfig;
use vofront_geometry::pnp::PnpConfig;
use vofront_geometry::{RansacConfig, RelativePoseConfig};

use crate::odometry::keyframe::KeyframePolicy;

/// Half-width of the quantisation of an ORB keypoint position, pixels of its level: the
/// smallest noise scale the local bundle adjustment's gate assumes.
///
/// ORB keypoints lie on whole pixels of their level (no sub-pixel refinement), and a
/// window's residuals are not Gaussian: a peak of corners re-detected on the same pixel
/// beside a spread of one-pixel steps. Their median absolute deviation (0.13 to 0.24 px on
/// KITTI) understates that spread: gated at it (`5.99 sigma^2`), the adjustment culled a
/// fifth of all observations and two fifths of the new keyframe's. The map thinned until
/// tracking failed, and with keyframes taken a few frames apart the emptied window drifted
/// by degrees.
pub const KEYPOINT_QUANTISATION_PX: f64 = 0.5;

/// Settings of [`MonoTracker`](super::MonoTracker).
#[derive(Debug, Clone)]
pub struct MonoConfig {
    /// ORB settings.
    pub orb: OrbConfig,
    /// Matching filters.
    pub matching: MatchConfig,
    /// Search radius around predicted positions, pixels.
    pub window_px: f32,
    /// Two-view estimation used for initialisation.
    pub relative: RelativePoseConfig,
    /// PnP RANSAC and refinement.
    pub pnp: PnpConfig,
    /// Fewest triangulated points to accept an initialisation (and fewest features for a
    /// frame to serve one).
    pub min_init_points: usize,
    /// Smallest median parallax to accept an initialisation, degrees.
    pub min_init_parallax_deg: f64,
    /// Fewest PnP inliers for a tracked frame.
    pub min_inliers: usize,
    /// Fewest PnP inliers for a frame to become a keyframe (and extend the map), unless its
    /// consensus is clean (`keyframe_clean_ratio`).
    pub min_keyframe_inliers: usize,
    /// Inlier ratio (inliers over matches) from which a pose with fewer than
    /// `min_keyframe_inliers` inliers may still become a keyframe.
    pub keyframe_clean_ratio: f64,
    /// Rotation, tracked-ratio (`min_overlap`) and residual tests of the keyframe decision;
    /// its metric translation test is off by default (map units mean nothing in monocular).
    pub keyframe: KeyframePolicy,
    /// Largest reprojection error of a point in any of its observations, pixels.
    pub max_reprojection_px: f64,
    /// Smallest parallax of a new point, degrees.
    pub min_point_parallax_deg: f64,
    /// Median parallax of the tracked points against the last keyframe that triggers a new
    /// keyframe, degrees.
    pub keyframe_parallax_deg: f64,
    /// Keyframes in the local map.
    pub window: usize,
    /// Earlier keyframes a new keyframe triangulates new points against.
    pub triangulation_neighbours: usize,
    /// Frames an initialisation waits for parallax before taking a newer reference.
    pub max_init_frames: usize,
    /// Fewest old-map points matched to the new map to join their scales after a loss.
    pub min_scale_matches: usize,
    /// Search radius of the second matching pass around the first located pose, pixels
    /// (`None`: one pass).
    pub relocate_window_px: Option<f32>,
    /// Local bundle adjustment of the window after each keyframe (module `adjust`; its
    /// `fixed_poses` is always the three oldest keyframes); `None` turns it off. By default its
    /// gate's noise scale is floored at [`KEYPOINT_QUANTISATION_PX`].
    pub local_ba: Option<BundleConfig>,
}

/// ORB of the monocular trackers (`mono`, and `direct-mono`'s start): 1500 features per frame.
pub(crate) fn monocular_orb() -> OrbConfig {
    OrbConfig {
        n_features: 1500,
        ..OrbConfig::default()
    }
}

/// Descriptor matching of the monocular trackers: the ratio test at 0.8.
pub(crate) fn monocular_matching() -> MatchConfig {
    MatchConfig {
        ratio: Some(0.8),
        ..MatchConfig::default()
    }
}

impl Default for MonoConfig {
    fn default() -> Self {
        Self {
            orb: monocular_orb(),
            matching: monocular_matching(),
            window_px: 24.0,
            relative: RelativePoseConfig::default(),
            // ORB positions at pyramid level k are uncertain by about 1.2^k pixels: on real
            // footage a third of the right matches lie 2-4 px from the located pose, and a
            // 2 px gate drops them.
            pnp: PnpConfig {
                ransac: RansacConfig {
                    threshold: 3.0,
                    ..PnpConfig::default().ransac
                },
                ..PnpConfig::default()
            },
            min_init_points: 80,
            min_init_parallax_deg: 1.0,
            min_inliers: 25,
            min_keyframe_inliers: 50,
            keyframe_clean_ratio: 0.8,
            keyframe: KeyframePolicy {
                max_relative_translation: f64::INFINITY,
                min_overlap: 0.5,
                ..KeyframePolicy::default()
            },
            max_reprojection_px: 2.0,
            min_point_parallax_deg: 0.5,
            keyframe_parallax_deg: 1.0,
            window: 5,
            triangulation_neighbours: 2,
            max_init_frames: 30,
            min_scale_matches: 12,
            relocate_window_px: Some(4.0),
            local_ba: Some(BundleConfig {
                min_sigma_px: KEYPOINT_QUANTISATION_PX,
                ..BundleConfig::default()
            }),
        }
    }
}
