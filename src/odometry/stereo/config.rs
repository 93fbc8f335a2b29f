//! Settings of the stereo tracker.

use vofront_features::{MatchConfig, OrbConfig, StereoConfig};
use vofront_geometry::bundle::BundleConfig;
use vofront_geometry::pnp::PnpConfig;
use vofront_geometry::RansacConfig;

use crate::odometry::keyframe::KeyframePolicy;

/// Settings of [`StereoTracker`](super::StereoTracker).
#[derive(Debug, Clone)]
pub struct StereoTrackerConfig {
    /// ORB settings (both images).
    pub orb: OrbConfig,
    /// Matching of the left features along their rows in the right image.
    pub stereo: StereoConfig,
    /// Matching filters of the map points against a frame.
    pub matching: MatchConfig,
    /// Search radius around predicted positions, pixels.
    pub window_px: f32,
    /// Search radius of the second matching pass around the first located pose, pixels
    /// (`None`: one pass).
    pub relocate_window_px: Option<f32>,
    /// PnP RANSAC and refinement.
    pub pnp: PnpConfig,
    /// Fewest PnP inliers for a tracked frame.
    pub min_inliers: usize,
    /// Fewest PnP inliers for a frame to become a keyframe (and extend the map), and for a
    /// relocation into a lost map.
    pub min_keyframe_inliers: usize,
    /// Tracked-ratio (`min_overlap`: inliers over those of the first frame tracked after the
    /// newest keyframe), rotation and residual tests of the keyframe decision (its translation
    /// test is off by default).
    pub keyframe: KeyframePolicy,
    /// Fewest stereo points for a frame to start a map.
    pub min_map_points: usize,
    /// Keyframes in the local map.
    pub window: usize,
    /// Largest reprojection error of a point in any of its observations, pixels (times the
    /// observation's level scale).
    pub max_reprojection_px: f64,
    /// Local bundle adjustment after each keyframe, with stereo observations `(u_l, v_l, u_r)`
    /// (`None`: off, the default); its `fixed_poses` oldest keyframes are held (one is enough
    /// for the gauge: the stereo baseline fixes the scale). For example
    /// `Some(BundleConfig { fixed_poses: 1, min_sigma_px: KEYPOINT_QUANTISATION_PX,
    /// ..BundleConfig::default() })`.
    pub local_ba: Option<BundleConfig>,
    /// Largest relative depth uncertainty `sigma_Z / Z = sigma_d / d` of a stereo point
    /// (`sigma_d` = [`KEYPOINT_QUANTISATION_PX`](crate::odometry::mono::KEYPOINT_QUANTISATION_PX) times the keypoint's level scale): farther
    /// matches, whose depth is mostly noise, make no points.
    pub max_relative_depth_sigma: f64,
}

impl Default for StereoTrackerConfig {
    fn default() -> Self {
        Self {
            orb: OrbConfig {
                n_features: 2000,
                ..OrbConfig::default()
            },
            stereo: StereoConfig::default(),
            matching: MatchConfig {
                ratio: Some(0.8),
                ..MatchConfig::default()
            },
            window_px: 24.0,
            relocate_window_px: Some(4.0),
            // As the monocular tracker: keypoints of level k are uncertain by about 1.2^k px.
            pnp: PnpConfig {
                ransac: RansacConfig {
                    threshold: 3.0,
                    ..PnpConfig::default().ransac
                },
                ..PnpConfig::default()
            },
            min_inliers: 25,
            min_keyframe_inliers: 50,
            // ORB-SLAM2's stereo ratio; no translation test: a driving camera moves a
            // tenth of the median depth per frame, and the tracked ratio tells when the view
            // has changed.
            keyframe: KeyframePolicy {
                max_relative_translation: f64::INFINITY,
                min_overlap: 0.75,
                ..KeyframePolicy::default()
            },
            min_map_points: 50,
            window: 5,
            max_reprojection_px: 2.0,
            // Off: measured on 2026-12-04 with one to four fixed keyframes, the adjusted
            // window gave a larger ATE and per-frame rotation error than PnP against the
            // stereo points alone on both KITTI clips (see README "Stereo").
            local_ba: None,
            // A match at disparity d has sigma_Z / Z = 0.5 px / d: 10% at 5 px (about 70 m
            // at KITTI's 0.54 m baseline). Farther points bias the scale: on `kitti_01` every
            // match down to 0.5 px made the path 13% too long.
            max_relative_depth_sigma: 0.1,
        }
    }
}
