//! Constant-velocity motion prior.
//!
//! With camera-to-world poses `T_wc(k)`, the motion of the last step expressed in the camera
//! frame is `V = T_wc(k-1)^-1 T_wc(k)`; assuming it repeats, `T_wc(k+1) ~ T_wc(k) V`.
//! Every stored and predicted pose is renormalised ([`normalized`]): this feedback loop would
//! otherwise compound rounding until the rotation quaternion visibly shrinks.

use nalgebra::Isometry3;
use vofront_geometry::lie::normalized;

/// Remembers the last two camera poses and extrapolates the next one.
#[derive(Debug, Clone, Default)]
pub struct ConstantVelocity {
    last: Option<Isometry3<f64>>,
    velocity: Option<Isometry3<f64>>,
}

impl ConstantVelocity {
    /// Records the pose `T_wc` of the newest frame.
    pub fn update(&mut self, t_wc: Isometry3<f64>) {
        let t_wc = normalized(&t_wc);
        self.velocity = self.last.map(|prev| normalized(&(prev.inverse() * t_wc)));
        self.last = Some(t_wc);
    }

    /// Forgets the velocity (after tracking was lost), keeping the last pose.
    pub fn reset_velocity(&mut self) {
        self.velocity = None;
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
