//! Robust reprojection residuals of a bundle and their Jacobians, as an
//! [`LmProblem`] with a [`SchurSystem`].
//!
//! Observation `o` of world point `P_j` from keyframe `i` with pose `T_i = T_cw`:
//! `x = T_i P_j` (camera frame), residual `r_o = (pi(x) - u_o) / s_o` in pixels (`s_o` the
//! observation's relative noise scale, which divides the Jacobians too) with `pi` the full
//! camera model ([`Camera`], distortion included). Jacobians, with `A = d pi / d x` (2x3):
//! `dr/d delta_i = A [I | -hat(x)]` for the left increment `T_i <- exp(delta_i) T_i` and
//! `dr/d P_j = A R_i`. Each observation is weighted by the robust loss on its norm in units of
//! the scale `s` (pixels): `w_o = psi(|r_o| / s) / (|r_o| / s)`, and the cost is
//! `sum_o s^2 rho(|r_o| / s)` over the active observations.

use nalgebra::{Isometry3, Matrix2x3, Matrix2x6, Matrix3, Matrix6, Point3, Vector2, Vector6};
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
    /// `r_o`, pixels; NaN when the point is behind the camera.
    pub residual: Vector2<f64>,
    /// `dr / d delta_i`.
    pub pose: Matrix2x6<f64>,
    /// `dr / d P_j`.
    pub point: Matrix2x3<f64>,
}

/// The reprojection problem over the active observations.
pub(crate) struct Reprojection<'a> {
    pub camera: &'a Camera,
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
        self.rows.resize(
            self.active.len(),
            Linearized {
                residual: Vector2::zeros(),
                pose: Matrix2x6::zeros(),
                point: Matrix2x3::zeros(),
            },
        );
        self.rows
            .par_iter_mut()
            .zip(self.active.par_iter())
            .map(|(row, &o)| {
                let obs = &observations[o];
                let pose = &state.poses[obs.pose];
                let x = (pose * state.points[obs.point]).coords;
                match project_in_front(camera, &x) {
                    Some((pixel, a)) => {
                        let rotation: Matrix3<f64> =
                            pose.rotation.to_rotation_matrix().into_inner();
                        let a = a / obs.sigma;
                        *row = Linearized {
                            residual: (pixel - obs.pixel) / obs.sigma,
                            pose: a * point_jacobian(&x),
                            point: a * rotation,
                        };
                        usize::from(row.residual.iter().all(|v| v.is_finite()))
                    }
                    None => {
                        row.residual = Vector2::repeat(f64::NAN);
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
        SchurSystem { u, gc, points }
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
