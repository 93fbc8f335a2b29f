//! One pyramid level of the SE(3) problem: warp `w(p, T) = pi(K (R P + t))` of the selected
//! reference points, residuals `I_cur(w) - (a I_ref(p) + b)` and their Jacobian rows (see the
//! parent module for the equations), in structure-of-arrays buffers.

use nalgebra::{Isometry3, SVector, Vector3};
use rayon::prelude::*;
use vofront_core::lie::retract_left;
use vofront_robust::{Loss, NormalEquations};

use super::select::RefLevel;
use crate::lm::{accumulate, LevelProblem, CHUNK, SERIAL_MAX};
use crate::plane::sample_with_gradient;

/// Pose and brightness.
#[derive(Debug, Clone, Copy)]
pub(super) struct Se3State {
    pub(super) pose: Isometry3<f64>,
    pub(super) a: f64,
    pub(super) b: f64,
}

/// One level of the SE(3) problem: residuals and Jacobian rows in SoA buffers.
pub(super) struct Se3Level<'a> {
    pub(super) reference: &'a RefLevel,
    /// `(width, height)` of the current level.
    pub(super) size: (usize, usize),
    /// Grey levels of the current level, row-major.
    pub(super) image: &'a [f32],
    /// Per reference point: whether it takes part at this level ([`Se3Level::new`]).
    pub(super) active: Vec<bool>,
    pub(super) residuals: Vec<f32>,
    pub(super) jacobians: Vec<[f32; 8]>,
    /// The evaluation at the accepted state while a trial is evaluated.
    pub(super) saved: (Vec<f32>, Vec<[f32; 8]>),
}

impl<'a> Se3Level<'a> {
    /// The level's problem on the points that `start` projects at least `margin` pixels
    /// inside the sampled area (`1 <= u <= width - 2`, the same for `v`) and in front of the
    /// camera. The set is fixed for the level, so that the mean cost the LM loop compares
    /// between steps is over the same points: a step cannot lower it by pushing badly fitting
    /// points out of the image.
    pub(super) fn new(
        reference: &'a RefLevel,
        size: (usize, usize),
        image: &'a [f32],
        start: &Isometry3<f64>,
        margin: f32,
    ) -> Self {
        let rot = start
            .rotation
            .to_rotation_matrix()
            .into_inner()
            .cast::<f32>();
        let t = start.translation.vector.cast::<f32>();
        let [fx, fy, cx, cy] = reference.k;
        let (w, h) = (size.0 as f32, size.1 as f32);
        let active = (0..reference.x.len())
            .map(|i| {
                let p = rot * Vector3::new(reference.x[i], reference.y[i], reference.z[i]) + t;
                let (u, v) = (fx * p.x / p.z + cx, fy * p.y / p.z + cy);
                p.z > 1e-3
                    && u >= 1.0 + margin
                    && v >= 1.0 + margin
                    && u <= w - 2.0 - margin
                    && v <= h - 2.0 - margin
            })
            .collect();
        Self {
            reference,
            size,
            image,
            active,
            residuals: Vec::new(),
            jacobians: Vec::new(),
            saved: (Vec::new(), Vec::new()),
        }
    }
}

impl LevelProblem<8> for Se3Level<'_> {
    type State = Se3State;

    fn evaluate(&mut self, s: &Se3State) -> usize {
        let rot = s
            .pose
            .rotation
            .to_rotation_matrix()
            .into_inner()
            .cast::<f32>();
        let t = s.pose.translation.vector.cast::<f32>();
        let (a, b) = (s.a as f32, s.b as f32);
        let r = self.reference;
        let [fx, fy, cx, cy] = r.k;
        let (w, h) = self.size;
        let image = self.image;
        let active = &self.active;
        let n = r.x.len();
        self.residuals.resize(n, f32::NAN);
        self.jacobians.resize(n, [0.0; 8]);
        // Fills one chunk starting at reference pixel `start`; returns its valid residuals.
        let fill = |start: usize, res: &mut [f32], jac: &mut [[f32; 8]]| {
            let end = start + res.len();
            let points = r.x[start..end]
                .iter()
                .zip(&r.y[start..end])
                .zip(&r.z[start..end])
                .zip(&r.value[start..end])
                .zip(&active[start..end]);
            let mut valid = 0;
            for ((o, j), ((((&x, &y), &z), &reference), &on)) in res.iter_mut().zip(jac).zip(points)
            {
                *o = f32::NAN;
                if !on {
                    continue;
                }
                let p = rot * Vector3::new(x, y, z) + t;
                if p.z <= 1e-3 {
                    continue;
                }
                let iz = 1.0 / p.z;
                let u = fx * p.x * iz + cx;
                let v = fy * p.y * iz + cy;
                // Stay one pixel inside, where the gradients are defined.
                if !(u >= 1.0 && v >= 1.0 && u <= (w - 2) as f32 && v <= (h - 2) as f32) {
                    continue;
                }
                let [value, dx, dy] = sample_with_gradient(image, w, h, u, v);
                let resid = value - a * reference - b;
                if !(resid.is_finite() && dx.is_finite() && dy.is_finite()) {
                    continue;
                }
                let ax = dx * fx * iz;
                let ay = dy * fy * iz;
                let az = -(ax * p.x + ay * p.y) * iz;
                *j = [
                    ax,
                    ay,
                    az,
                    p.y * az - p.z * ay,
                    p.z * ax - p.x * az,
                    p.x * ay - p.y * ax,
                    -reference,
                    -1.0,
                ];
                *o = resid;
                valid += 1;
            }
            valid
        };
        if n <= SERIAL_MAX {
            self.residuals
                .chunks_mut(CHUNK)
                .zip(self.jacobians.chunks_mut(CHUNK))
                .enumerate()
                .map(|(c, (res, jac))| fill(c * CHUNK, res, jac))
                .sum()
        } else {
            self.residuals
                .par_chunks_mut(CHUNK)
                .zip(self.jacobians.par_chunks_mut(CHUNK))
                .enumerate()
                .map(|(c, (res, jac))| fill(c * CHUNK, res, jac))
                .sum()
        }
    }

    fn residuals(&self) -> &[f32] {
        &self.residuals
    }

    fn normal_equations(&self, loss: &Loss, scale: f32) -> NormalEquations<8> {
        accumulate(self.residuals.len(), loss, scale, SERIAL_MAX, |i| {
            let r = self.residuals[i];
            (!r.is_nan()).then(|| {
                let j = SVector::<f64, 8>::from(self.jacobians[i].map(f64::from));
                (j, f64::from(r))
            })
        })
    }

    fn save(&mut self) {
        std::mem::swap(&mut self.residuals, &mut self.saved.0);
        std::mem::swap(&mut self.jacobians, &mut self.saved.1);
    }

    fn restore(&mut self, _state: &Se3State) {
        self.save();
    }

    fn retract(&self, s: &Se3State, delta: &SVector<f64, 8>) -> Se3State {
        let xi = delta.fixed_rows::<6>(0).into_owned();
        Se3State {
            pose: retract_left(&s.pose, &xi),
            a: s.a + delta[6],
            b: s.b + delta[7],
        }
    }
}
