//! Robust reprojection residuals of a bundle and their Jacobians, as an
//! [`LmProblem`] with a [`SchurSystem`].
//!
//! Observation `o` of world point `P_j` from keyframe `i` with pose `T_i = T_cw`:
//! `x = T_i P_j` (camera frame), residual `r_o = (pi(x) - u_o) / s_o` in pixels (`s_o` the
//! observation's relative noise scale, which divides the Jacobians too) with `pi` the full
//! camera model ([`Camera`], distortion included). Jacobians, with `A = d pi / d x` (2x3):
//! `dr/d delta_i = A [I | -hat(x)]` for the left increment `T_i <- exp(delta_i) T_i` and
//! `dr/d P_j = A R_i`. A stereo observation has the third row
//! `r_o,3 = (pi(x - b e_x)_x - u_r) / s_o` with the first row `a_r` of `A` at `x - b e_x`:
//! `dr_3/d delta_i = a_r [I | -hat(x)]`, `dr_3/d P_j = a_r R_i`; a monocular observation's third
//! row is zero (it adds nothing to the cost or the normal equations). Each observation is weighted by the robust loss on its norm in units of
//! the scale `s` (pixels): `w_o = psi(|r_o| / s) / (|r_o| / s)`, and the cost is
//! `sum_o s^2 rho(|r_o| / s)` over the active observations.

use nalgebra::{Isometry3, Matrix3, Matrix3x6, Matrix6, Point3, Vector3, Vector6};
use rayon::prelude::*;
use vofront_robust::{Coupling, LmProblem, Loss, PointBlock, RobustLoss};

use super::{BundleStep, Observation, SchurSystem};
use crate::camera::Camera;
use crate::lie::{point_jacobian, retract_left};
use crate::pnp::project_in_front;

/// Keyframe poses `T_cw` (oldest first) and world points.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BundleState {
    pub poses: Vec<Isometry3<f64>>,
    pub points: Vec<Point3<f64>>,
}

/// Residual and Jacobians of one observation at the current state.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Linearized {
    /// `r_o`, pixels (third row 0 for a monocular observation); NaN when the point is behind
    /// a camera.
    pub residual: Vector3<f64>,
    /// `dr / d delta_i`.
    pub pose: Matrix3x6<f64>,
    /// `dr / d P_j`.
    pub point: Matrix3<f64>,
}

/// The reprojection problem over the active observations.
pub(crate) struct Reprojection<'a> {
    pub camera: &'a Camera,
    /// Stereo baseline, metres (unused without stereo observations).
    pub baseline: f64,
    pub observations: &'a [Observation],
    /// Indices of the active observations.
    pub active: &'a [usize],
    /// Active observations of each point (indices into `active`).
    pub by_point: &'a [Vec<usize>],
    /// Active observations of each free pose (indices into `active`).
    pub by_pose: &'a [Vec<usize>],
    /// Poses `0..fixed` are held (the gauge).
    pub fixed: usize,
    pub loss: Loss,
    /// Loss scale, pixels.
    pub scale: f64,
    /// The evaluation of each active observation.
    pub rows: Vec<Linearized>,
    /// `rows` at the accepted state while a trial is evaluated.
    pub saved: Vec<Linearized>,
}

/// Residual rows per parallel task of the cost.
const COST_CHUNK: usize = 1024;

impl Reprojection<'_> {
    /// Loss weight of an evaluated row.
    fn weight(&self, row: &Linearized) -> f64 {
        self.loss.weight(row.residual.norm() / self.scale)
    }
}

impl LmProblem for Reprojection<'_> {
    type State = BundleState;
    type System = SchurSystem;

    fn evaluate(&mut self, state: &BundleState) -> usize {
        let (camera, observations) = (self.camera, self.observations);
        let right_offset = Vector3::new(self.baseline, 0.0, 0.0);
        self.rows.resize(
            self.active.len(),
            Linearized {
                residual: Vector3::zeros(),
                pose: Matrix3x6::zeros(),
                point: Matrix3::zeros(),
            },
        );
        // Each pose's rotation matrix once, not once per observation.
        let rotations: Vec<Matrix3<f64>> = state
            .poses
            .iter()
            .map(|pose| pose.rotation.to_rotation_matrix().into_inner())
            .collect();
        self.rows
            .par_iter_mut()
            .zip(self.active.par_iter())
            .map(|(row, &o)| {
                let obs = &observations[o];
                let pose = &state.poses[obs.pose];
                let x = (pose * state.points[obs.point]).coords;
                let left = project_in_front(camera, &x);
                let right = match obs.right {
                    Some(ur) => project_in_front(camera, &(x - right_offset))
                        .map(|(pixel, a)| Some((pixel.x - ur, a.row(0).into_owned()))),
                    None => Some(None),
                };
                match (left, right) {
                    (Some((pixel, a)), Some(right)) => {
                        let mut a3 = Matrix3::zeros();
                        a3.fixed_view_mut::<2, 3>(0, 0).copy_from(&a);
                        let mut residual = Vector3::zeros();
                        residual
                            .fixed_rows_mut::<2>(0)
                            .copy_from(&(pixel - obs.pixel));
                        if let Some((r, ar)) = right {
                            a3.set_row(2, &ar);
                            residual.z = r;
                        }
                        let a3 = a3 / obs.sigma;
                        *row = Linearized {
                            residual: residual / obs.sigma,
                            pose: a3 * point_jacobian(&x),
                            point: a3 * rotations[obs.pose],
                        };
                        usize::from(row.residual.iter().all(|v| v.is_finite()))
                    }
                    _ => {
                        row.residual = Vector3::repeat(f64::NAN);
                        0
                    }
                }
            })
            .sum()
    }

    fn cost(&self) -> f64 {
        let s = self.scale;
        let rho = |row: &Linearized| {
            let u = row.residual.norm() / s;
            if u.is_finite() {
                s * s * self.loss.rho(u)
            } else {
                0.0
            }
        };
        // Fixed chunks summed in order, so that the cost is repeatable (see `schur`).
        let partial: Vec<f64> = self
            .rows
            .par_chunks(COST_CHUNK)
            .map(|chunk| chunk.iter().map(rho).sum())
            .collect();
        partial.iter().sum()
    }

    fn scale(&self) -> f64 {
        self.scale
    }

    fn linearize(&mut self) -> SchurSystem {
        let free = self.by_pose.len();
        let fixed = self.fixed;
        let observations = self.observations;
        let rows = &self.rows;
        let valid = |k: usize| rows[k].residual.x.is_finite();
        let points = self
            .by_point
            .par_iter()
            .map(|list| {
                let mut block = PointBlock::zeros();
                for &k in list.iter().filter(|&&k| valid(k)) {
                    let row = &rows[k];
                    let wj = self.weight(row) * row.point.transpose();
                    block.v += wj * row.point;
                    block.gp += wj * row.residual;
                    if let Some(pose) = observations[self.active[k]].pose.checked_sub(fixed) {
                        block.couplings.push(Coupling {
                            pose,
                            w: row.pose.transpose() * wj.transpose(),
                        });
                    }
                }
                block
            })
            .collect();
        let (u, gc): (Vec<_>, Vec<_>) = (0..free)
            .into_par_iter()
            .map(|i| {
                let mut u = Matrix6::zeros();
                let mut g = Vector6::zeros();
                for &k in self.by_pose[i].iter().filter(|&&k| valid(k)) {
                    let row = &rows[k];
                    let wj = self.weight(row) * row.pose.transpose();
                    u += wj * row.pose;
                    g += wj * row.residual;
                }
                (u, g)
            })
            .unzip();
        SchurSystem {
            u,
            gc,
            points,
            pairs: Vec::new(),
        }
    }

    fn retract(&self, state: &BundleState, step: &BundleStep) -> BundleState {
        let mut poses = state.poses.clone();
        for (pose, delta) in poses.iter_mut().skip(self.fixed).zip(&step.poses) {
            *pose = retract_left(pose, delta);
        }
        let points = state
            .points
            .iter()
            .zip(&step.points)
            .map(|(p, d)| p + d)
            .collect();
        BundleState { poses, points }
    }

    fn step_norm(&self, step: &BundleStep) -> f64 {
        step.norm()
    }

    fn save(&mut self) {
        std::mem::swap(&mut self.rows, &mut self.saved);
    }

    fn restore(&mut self, _state: &BundleState) {
        std::mem::swap(&mut self.rows, &mut self.saved);
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Point3, Vector2, Vector3};
    use vofront_core::{Camera, Distortion, Pinhole};
    use vofront_robust::{LmProblem, Loss};

    use super::{BundleState, Reprojection};
    use crate::bundle::Observation;
    use crate::lie::retract_left;

    /// The stereo residual's analytic Jacobians (pose left increment and point) agree with
    /// central finite differences of the residual, all three rows, on a distorted camera.
    #[test]
    fn stereo_residual_jacobians_match_finite_differences() {
        let camera = Camera::new(
            Pinhole::new(700.0, 690.0, 600.0, 180.0).unwrap(),
            Distortion::from_array([-0.1, 0.02, 0.001, -0.002, 0.0]),
        );
        let observations = [
            Observation {
                pose: 1,
                point: 0,
                pixel: Vector2::new(610.0, 170.0),
                sigma: 1.2,
                right: Some(580.0),
            },
            Observation {
                pose: 1,
                point: 0,
                pixel: Vector2::new(605.0, 175.0),
                sigma: 1.0,
                right: None,
            },
        ];
        let state = BundleState {
            poses: vec![
                Isometry3::identity(),
                Isometry3::new(
                    Vector3::new(0.1, -0.05, 0.3),
                    Vector3::new(0.02, -0.03, 0.01),
                ),
            ],
            points: vec![Point3::new(0.8, -0.4, 9.0)],
        };
        let by_point = [vec![0, 1]];
        let by_pose = [vec![0, 1]];
        let mut problem = Reprojection {
            camera: &camera,
            baseline: 0.54,
            observations: &observations,
            active: &[0, 1],
            by_point: &by_point,
            by_pose: &by_pose,
            fixed: 1,
            loss: Loss::Huber(1.345),
            scale: 1.0,
            rows: Vec::new(),
            saved: Vec::new(),
        };
        assert_eq!(problem.evaluate(&state), 2);
        let rows = problem.rows.clone();
        assert_eq!(rows[1].residual.z, 0.0);
        assert!(rows[0].residual.z.abs() > 1.0);
        let residuals = |problem: &mut Reprojection, s: &BundleState| {
            assert_eq!(problem.evaluate(s), 2);
            [problem.rows[0].residual, problem.rows[1].residual]
        };
        let h = 1e-6;
        for c in 0..6 {
            let mut delta = nalgebra::Vector6::zeros();
            delta[c] = h;
            let at = |d: nalgebra::Vector6<f64>| {
                let mut s = state.clone();
                s.poses[1] = retract_left(&s.poses[1], &d);
                s
            };
            let plus = residuals(&mut problem, &at(delta));
            let minus = residuals(&mut problem, &at(-delta));
            for (k, row) in rows.iter().enumerate() {
                let numeric = (plus[k] - minus[k]) / (2.0 * h);
                let analytic = row.pose.column(c);
                assert!(
                    (numeric - analytic).norm() < 1e-4 * (1.0 + analytic.norm()),
                    "pose column {c}, row {k}: {numeric} vs {analytic}"
                );
            }
        }
        for c in 0..3 {
            let mut s = (state.clone(), state.clone());
            s.0.points[0][c] += h;
            s.1.points[0][c] -= h;
            let plus = residuals(&mut problem, &s.0);
            let minus = residuals(&mut problem, &s.1);
            for (k, row) in rows.iter().enumerate() {
                let numeric = (plus[k] - minus[k]) / (2.0 * h);
                let analytic = row.point.column(c);
                assert!(
                    (numeric - analytic).norm() < 1e-4 * (1.0 + analytic.norm()),
                    "point column {c}, row {k}: {numeric} vs {analytic}"
                );
            }
        }
    }
}
