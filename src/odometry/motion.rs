//! Constant-velocity motion prior.
//!
//! With camera-to-world poses `T_wc(k)`, the motion of the last step expressed in the camera
//! frame is `V = T_wc(k-1)^-1 T_wc(k)`; assuming it repeats, `T_wc(k+1) ~ T_wc(k) V`.
//! Every stored and predicted pose is renormalised ([`normalized`]): this feedback loop would
//! otherwise compound rounding until the rotation quaternion visibly shrinks.

use std::collections::VecDeque;

use nalgebra::Isometry3;
use vofront_core::lie::normalized;

/// Remembers the last two camera poses and extrapolates the next one.
#[derive(Debug, Clone, Default)]
pub struct ConstantVelocity {
    last: Option<Isometry3<f64>>,
    velocity: Option<Isometry3<f64>>,
    /// Lengths of the last [`RECENT_STEPS`] steps, oldest first.
    recent: VecDeque<f64>,
}

/// Steps over which [`ConstantVelocity::step_length`] takes its median.
const RECENT_STEPS: usize = 5;

impl ConstantVelocity {
    /// Records the pose `T_wc` of the newest frame.
    pub fn update(&mut self, t_wc: Isometry3<f64>) {
        let t_wc = normalized(&t_wc);
        self.velocity = self.last.map(|prev| normalized(&(prev.inverse() * t_wc)));
        self.last = Some(t_wc);
        if let Some(v) = self.velocity {
            if self.recent.len() == RECENT_STEPS {
                self.recent.pop_front();
            }
            self.recent.push_back(v.translation.vector.norm());
        }
    }

    /// Whether a velocity is known: [`ConstantVelocity::predict`] extrapolates a motion rather
    /// than repeating the last pose.
    pub fn has_velocity(&self) -> bool {
        self.velocity.is_some()
    }

    /// Forgets the velocity (after tracking was lost), keeping the last pose.
    pub fn reset_velocity(&mut self) {
        self.velocity = None;
    }

    /// Restarts at `t_w2` with the motion from `t_w1` spread evenly over `frames` steps:
    /// velocity `(exp(log(R_12) / n), t_12 / n)` with `T_12 = T_w1^-1 T_w2`, `n = frames`
    /// (at least 1).
    pub fn restart(&mut self, t_w1: &Isometry3<f64>, t_w2: &Isometry3<f64>, frames: usize) {
        let n = frames.max(1) as f64;
        let t_12 = t_w1.inverse() * t_w2;
        let step = Isometry3::new(t_12.translation.vector / n, t_12.rotation.scaled_axis() / n);
        self.last = Some(normalized(t_w2));
        self.velocity = Some(normalized(&step));
        self.recent.clear();
        self.recent.push_back(step.translation.vector.norm());
    }

    /// Typical step length: the median of `|t(T_prev^-1 T_next)|` over the last
    /// five updates (map units per frame; one poorly located frame does not set
    /// it); `None` before any step.
    pub fn step_length(&self) -> Option<f64> {
        let mut steps: Vec<f64> = self.recent.iter().copied().collect();
        crate::robust::median_in_place(&mut steps)
    }

    /// Predicted `T_wc` of the next frame: the last pose moved by the last step, or the last
    /// pose itself when there is no velocity yet; `None` before any pose.
    pub fn predict(&self) -> Option<Isometry3<f64>> {
        self.last.map(|last| match self.velocity {
            Some(v) => normalized(&(last * v)),
            None => last,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn predictions_stay_unit_over_long_runs() {
        // A tracker feeds the prediction back as the next pose; without renormalisation the
        // quaternion norm drifts geometrically.
        let mut model = ConstantVelocity::default();
        let step = Isometry3::new(
            Vector3::new(0.01, 0.002, 0.01),
            Vector3::new(0.003, 0.011, -0.002),
        );
        model.update(Isometry3::identity());
        model.update(step);
        for _ in 0..5000 {
            let next = model.predict().unwrap();
            model.update(next);
        }
        assert!((model.predict().unwrap().rotation.norm() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn restart_spreads_the_pair_motion_over_its_frames() {
        // Three steps of a screw motion between the pair: the velocity is one step, so the
        // prediction is the fourth pose; the step length is one step's translation.
        let step = Isometry3::new(Vector3::new(0.02, 0.0, 0.3), Vector3::new(0.0, 0.02, 0.0));
        let t_w1 = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, 0.0, 0.0));
        let t_w2 = t_w1 * step * step * step;
        let mut model = ConstantVelocity::default();
        model.restart(&t_w1, &t_w2, 3);
        let predicted = model.predict().unwrap();
        let truth = t_w2 * step;
        // The chord of three screw steps is not three steps: within (R - I) t of one.
        assert!((predicted.translation.vector - truth.translation.vector).norm() < 0.01);
        assert!(predicted.rotation.angle_to(&truth.rotation) < 1e-9);
        assert!((model.step_length().unwrap() - step.translation.vector.norm()).abs() < 0.01);
    }

    #[test]
    fn extrapolates_a_constant_screw_motion() {
        let step = Isometry3::new(Vector3::new(0.01, 0.0, 0.02), Vector3::new(0.0, 0.01, 0.0));
        let mut model = ConstantVelocity::default();
        assert!(model.predict().is_none());
        let mut pose = Isometry3::identity();
        model.update(pose);
        assert_eq!(model.predict(), Some(pose));
        for _ in 0..3 {
            pose *= step;
            model.update(pose);
        }
        let predicted = model.predict().unwrap();
        let truth = pose * step;
        assert!(
            (predicted.to_homogeneous() - truth.to_homogeneous())
                .abs()
                .max()
                < 1e-12
        );
        model.reset_velocity();
        assert_eq!(model.predict(), Some(pose));
    }
}
