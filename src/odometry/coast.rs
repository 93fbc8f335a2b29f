//! Coasting: the motion model of a sequential tracker that can lose frames and find them again.
//!
//! Every frame is predicted by the constant-velocity model ([`ConstantVelocity`]):
//! `T_wc' = T_wc(k) V`. A tracker that keeps a map across a loss does not stop the camera at
//! the first lost frame: the prediction is taken as that frame's pose, so that later frames
//! are predicted (and a new map placed) where the camera has gone. After
//! [`MAX_COAST_FRAMES`] consecutive lost frames the velocity is no longer trusted and the
//! model holds still at its last pose until a frame is tracked again.

use nalgebra::Isometry3;

use super::motion::ConstantVelocity;

/// Lost frames through which the motion model keeps its velocity.
pub(crate) const MAX_COAST_FRAMES: usize = 10;

/// The motion model, with the count of lost frames it has coasted through.
#[derive(Debug, Clone, Default)]
pub(crate) struct Coasting {
    /// The constant-velocity model behind the predictions.
    pub motion: ConstantVelocity,
    /// Consecutive lost frames coasted through.
    coasted: usize,
}

impl Coasting {
    /// The model's `T_wc` for the next frame (the origin before any pose).
    pub fn predict(&self) -> Isometry3<f64> {
        self.motion.predict().unwrap_or_else(Isometry3::identity)
    }

    /// Ends a frame that was predicted at `predicted`: a `lost` frame (of a tracker that has
    /// started: its first pose defined) is recorded at the prediction while fewer than
    /// [`MAX_COAST_FRAMES`] frames were coasted through, after that the velocity is dropped;
    /// any other frame (already recorded by the tracker) ends the coasting.
    pub fn end_frame(&mut self, lost: bool, predicted: Isometry3<f64>) {
        if !lost {
            self.coasted = 0;
        } else if self.coasted < MAX_COAST_FRAMES {
            self.motion.update(predicted);
            self.coasted += 1;
        } else {
            self.motion.reset_velocity();
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Vector3};

    use super::{Coasting, MAX_COAST_FRAMES};

    /// Lost frames continue the motion for `MAX_COAST_FRAMES` steps, then the model holds
    /// still; a tracked frame starts the count again.
    #[test]
    fn lost_frames_coast_then_hold_still() {
        let step = Isometry3::new(Vector3::new(0.0, 0.0, 1.0), Vector3::zeros());
        let mut coast = Coasting::default();
        coast.motion.update(Isometry3::identity());
        coast.motion.update(step);
        coast.end_frame(false, Isometry3::identity());
        for k in 0..MAX_COAST_FRAMES {
            let predicted = coast.predict();
            assert!((predicted.translation.z - (k + 2) as f64).abs() < 1e-12);
            coast.end_frame(true, predicted);
        }
        // The next lost frame drops the velocity: the model holds at the last coasted pose.
        let beyond = coast.predict();
        coast.end_frame(true, beyond);
        let held = coast.predict();
        assert!((held.translation.z - (MAX_COAST_FRAMES + 1) as f64).abs() < 1e-12);
        coast.end_frame(true, held);
        assert_eq!(coast.predict(), held);
        // Tracked again: the next loss coasts anew.
        coast.motion.update(held * step);
        coast.end_frame(false, held);
        let predicted = coast.predict();
        coast.end_frame(true, predicted);
        assert!((coast.predict().translation.z - held.translation.z - 3.0).abs() < 1e-12);
    }
}
