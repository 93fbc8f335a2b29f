//! When to start a new keyframe.
//!
//! Trackers align each frame to the current keyframe. A new keyframe is taken when the camera
//! has moved far from it (translation relative to the scene depth, or rotation), when too little
//! of the keyframe is still seen (overlap), or when the alignment residual has grown well past
//! what it was just after the keyframe was taken (appearance change). A feature tracker also
//! forecasts how many of the keyframe's points the next frame will track ([`forecast_tracked`]).

use nalgebra::Isometry3;

/// Thresholds of the keyframe decision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeyframePolicy {
    /// Largest `|t| / median depth` of the keyframe before a new one is taken.
    pub max_relative_translation: f64,
    /// Largest rotation from the keyframe, degrees.
    pub max_rotation_deg: f64,
    /// Smallest fraction of the keyframe's points still usable (inliers over selected).
    pub min_overlap: f64,
    /// Largest ratio of the current residual RMSE to the first one against this keyframe.
    pub max_residual_growth: f64,
}

impl Default for KeyframePolicy {
    fn default() -> Self {
        Self {
            max_relative_translation: 0.025,
            max_rotation_deg: 4.0,
            min_overlap: 0.6,
            max_residual_growth: 1.8,
        }
    }
}

/// What a tracker measured for the current frame against its keyframe.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeyframeView {
    /// `T_cur_kf`: keyframe points into the current frame.
    pub t_cur_kf: Isometry3<f64>,
    /// Median scene depth of the keyframe, metres (or the map's unit in monocular).
    pub median_depth: f64,
    /// Fraction of the keyframe's points still usable.
    pub overlap: f64,
    /// Residual RMSE of this frame's alignment.
    pub residual: f64,
    /// Residual RMSE of the first frame aligned to this keyframe.
    pub first_residual: f64,
}

impl KeyframePolicy {
    /// True when the current frame should become the new keyframe.
    pub fn needs_keyframe(&self, view: &KeyframeView) -> bool {
        let moved = view.t_cur_kf.translation.vector.norm() / view.median_depth.max(1e-6);
        let turned = view.t_cur_kf.rotation.angle().to_degrees();
        let grew = view.first_residual > 0.0
            && view.residual > self.max_residual_growth * view.first_residual;
        moved > self.max_relative_translation
            || turned > self.max_rotation_deg
            || view.overlap < self.min_overlap
            || grew
    }
}

/// The keyframe's points the next frame is expected to track if the tracked share keeps
/// falling at its mean rate since the keyframe: `n (o - (1 - o) / k)` for a share `o` of the
/// keyframe's `n` points tracked `k >= 1` frames after it (negative when the trend runs out
/// before the next frame).
///
/// A fast camera (a low frame rate, a sharp turn) can lose half of the keyframe's points in one
/// frame: the overlap test still passes, and the next frame finds too few to be located. A
/// tracker that takes a keyframe when this forecast falls below what it needs takes it while
/// the map can still be extended.
pub fn forecast_tracked(points: usize, overlap: f64, frames_since: usize) -> f64 {
    let k = frames_since.max(1) as f64;
    points as f64 * (overlap - (1.0 - overlap) / k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn view(t: Vector3<f64>, angle: f64, overlap: f64, residual: f64) -> KeyframeView {
        KeyframeView {
            t_cur_kf: Isometry3::new(t, Vector3::new(0.0, angle.to_radians(), 0.0)),
            median_depth: 2.0,
            overlap,
            residual,
            first_residual: 4.0,
        }
    }

    #[test]
    fn each_threshold_triggers_alone() {
        let p = KeyframePolicy::default();
        assert!(!p.needs_keyframe(&view(Vector3::new(0.03, 0.0, 0.0), 2.0, 0.9, 5.0)));
        assert!(p.needs_keyframe(&view(Vector3::new(0.2, 0.0, 0.0), 2.0, 0.9, 5.0)));
        assert!(p.needs_keyframe(&view(Vector3::new(0.03, 0.0, 0.0), 8.0, 0.9, 5.0)));
        assert!(p.needs_keyframe(&view(Vector3::new(0.03, 0.0, 0.0), 2.0, 0.4, 5.0)));
        assert!(p.needs_keyframe(&view(Vector3::new(0.03, 0.0, 0.0), 2.0, 0.9, 9.0)));
    }

    #[test]
    fn the_forecast_extends_the_mean_loss_since_the_keyframe() {
        // 200 points, 60% tracked one frame after the keyframe: 40% more lost by the next.
        assert!((forecast_tracked(200, 0.6, 1) - 40.0).abs() < 1e-9);
        // The same share after four frames falls by 10% a frame.
        assert!((forecast_tracked(200, 0.6, 4) - 100.0).abs() < 1e-9);
        // A share that would run out is forecast below zero; zero frames count as one.
        assert!(forecast_tracked(200, 0.4, 1) < 0.0);
        assert_eq!(forecast_tracked(200, 0.6, 0), forecast_tracked(200, 0.6, 1));
        // Every point still tracked forecasts every point.
        assert_eq!(forecast_tracked(150, 1.0, 3), 150.0);
    }
}
