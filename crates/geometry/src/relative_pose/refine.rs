//! Robust refinement of `(R, t)` on the unit sphere by the Sampson error, through
//! [`vofront_robust::irls()`].
//!
//! State: `R` and a unit `t`; increment `delta = (phi, a, b)` (5 DoF) applied as
//! `R <- exp(phi) R`, `t <- normalize(t + a b1 + b b2)` with `(b1, b2)` an orthonormal basis
//! of the tangent plane at `t`. Residual of correspondence `i`: the signed Sampson distance in
//! pixels, `f x2^T E x1 / sqrt((E x1)_1^2 + (E x1)_2^2 + (E^T x2)_1^2 + (E^T x2)_2^2)` with
//! `E = [t]_x R`; Jacobians by central differences.

use nalgebra::{Matrix3, Rotation3, SVector, Vector3};
use vofront_robust::{irls, IrlsConfig, Loss, Problem, Rows, ScaleMode};

use super::estimators::Correspondences;
use crate::lie::{hat, so3_exp};

/// Orthonormal basis `(b1, b2)` of the plane orthogonal to the unit vector `t`.
pub fn tangent_basis(t: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let a = if t.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let b1 = t.cross(&a).normalize();
    let b2 = t.cross(&b1);
    (b1, b2)
}

/// `(R, t)` with unit `t`.
pub type RelState = (Rotation3<f64>, Vector3<f64>);

/// Sampson refinement problem over selected correspondences.
struct SampsonProblem<'a> {
    data: &'a Correspondences,
    indices: &'a [usize],
    focal: f64,
}

impl SampsonProblem<'_> {
    fn residual(&self, e: &Matrix3<f64>, i: usize) -> f64 {
        let x1 = self.data.ray1(i);
        let x2 = self.data.ray2(i);
        let l2 = e * x1;
        let l1 = e.transpose() * x2;
        let den = (l2.x * l2.x + l2.y * l2.y + l1.x * l1.x + l1.y * l1.y).sqrt();
        self.focal * x2.dot(&l2) / den.max(f64::MIN_POSITIVE)
    }
}

impl Problem<5> for SampsonProblem<'_> {
    type State = RelState;

    fn evaluate(&mut self, state: &RelState, rows: &mut Rows<5>) {
        const H: f64 = 1e-6;
        let e0 = hat(&state.1) * state.0.matrix();
        let perturbed: [(Matrix3<f64>, Matrix3<f64>); 5] = std::array::from_fn(|k| {
            let mut d = SVector::<f64, 5>::zeros();
            d[k] = H;
            let p = self.retract(state, &d);
            let m = self.retract(state, &(-d));
            (hat(&p.1) * p.0.matrix(), hat(&m.1) * m.0.matrix())
        });
        for &i in self.indices {
            let r = self.residual(&e0, i);
            if !r.is_finite() {
                continue;
            }
            let j = SVector::<f64, 5>::from_fn(|k, _| {
                (self.residual(&perturbed[k].0, i) - self.residual(&perturbed[k].1, i)) / (2.0 * H)
            });
            rows.push(j, r);
        }
    }

    fn retract(&self, state: &RelState, delta: &SVector<f64, 5>) -> RelState {
        let r = so3_exp(&Vector3::new(delta[0], delta[1], delta[2])) * state.0;
        let (b1, b2) = tangent_basis(&state.1);
        let t = (state.1 + b1 * delta[3] + b2 * delta[4]).normalize();
        (r, t)
    }
}

/// Refines `(R, t)` on the correspondences `indices` with `loss` on the Sampson distance in
/// pixels divided by `sigma_px`; returns the input when the solve fails.
pub fn refine_relative_pose(
    data: &Correspondences,
    indices: &[usize],
    focal: f64,
    sigma_px: f64,
    loss: Loss,
    init: RelState,
) -> RelState {
    let mut problem = SampsonProblem {
        data,
        indices,
        focal,
    };
    let cfg = IrlsConfig {
        loss,
        scale: ScaleMode::Fixed(sigma_px),
        max_iterations: 20,
        min_step: 1e-9,
        min_relative_decrease: 1e-8,
        ..IrlsConfig::default()
    };
    match irls(&mut problem, init, &cfg) {
        Ok(res) => res.state,
        Err(_) => init,
    }
}
