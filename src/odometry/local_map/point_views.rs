//! The structure-only refinement of one map point: its reprojection errors in the views that
//! observe it, poses fixed, as an [`LmProblem`] for the one LM loop.

use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use vofront_core::Camera;
use vofront_robust::{Damping, LmConfig, LmProblem, NormalEquations};

/// The structure-only refinement of one point: Gauss-Newton first (`lambda = 0`), at most 4
/// iterations, stopping on a step under `1e-9` of the point's distance from the origin (at
/// least 1 map unit, [`PointViews::step_norm`]) and on no cost test (no relative decrease
/// limit); any invertible system is solved (no condition limit). A step that raises the cost
/// is retried with Marquardt damping of at least `1e-2 diag(H)` (a weaker floor retries
/// nearly the same step; 36 KITTI seeds put the tracker back on its Gauss-Newton figures with
/// this one). `min_valid` is set per point to its number of views.
pub(super) const POINT_LM: LmConfig = LmConfig {
    max_iterations: 4,
    min_step: 1e-9,
    min_step_sigmas: 0.0,
    min_relative_decrease: 0.0,
    initial_lambda: 0.0,
    lambda_floor: 1e-2,
    max_rejections: 4,
    damping: Damping::Diagonal,
    max_condition: f64::INFINITY,
    min_valid: 2,
};
/// A view sees a point only beyond this depth, map units.
pub(super) const POINT_MIN_DEPTH: f64 = 1e-6;

/// The reprojection errors of one map point in its views (`T_cw`, pixel `u_k`, noise scale
/// `s_k`), poses fixed, as an [`LmProblem`]: residual `r_k = (pi(T_k P) - u_k) / s_k` (pixels
/// of a scale-1 observation) through the full camera model, Jacobian
/// `dr_k / dP = (du/dx) R_k / s_k` ([`Camera::project_with_jacobian`]), cost `sum |r_k|^2 / 2`.
/// A view in which the point is not at least [`POINT_MIN_DEPTH`] in front, or outside the
/// lens, is not valid and adds no rows.
pub(super) struct PointViews<'a> {
    camera: &'a Camera,
    views: &'a [(Isometry3<f64>, Vector2<f64>, f64)],
    /// The point of the current evaluation.
    pub(super) at: Point3<f64>,
    /// The normal equations of the current evaluation.
    system: NormalEquations<3>,
    /// Set when an evaluated point was not seen by every view.
    pub(super) lost: bool,
}

impl<'a> PointViews<'a> {
    pub(super) fn new(
        camera: &'a Camera,
        views: &'a [(Isometry3<f64>, Vector2<f64>, f64)],
    ) -> Self {
        Self {
            camera,
            views,
            at: Point3::origin(),
            system: NormalEquations::new(),
            lost: false,
        }
    }
}

impl LmProblem for PointViews<'_> {
    type State = Point3<f64>;
    type System = NormalEquations<3>;

    fn evaluate(&mut self, x: &Point3<f64>) -> usize {
        self.at = *x;
        self.system = NormalEquations::new();
        let mut valid = 0;
        for (t_cw, u, sigma) in self.views {
            let c = (t_cw * x).coords;
            let seen = (c.z > POINT_MIN_DEPTH)
                .then(|| self.camera.project_with_jacobian(&c))
                .flatten();
            let Some((q, d_pi)) = seen else {
                continue;
            };
            let j = d_pi * t_cw.rotation.to_rotation_matrix().matrix() / *sigma;
            let r = (q - u) / *sigma;
            self.system.add(&j.row(0).transpose(), r.x, 1.0);
            self.system.add(&j.row(1).transpose(), r.y, 1.0);
            valid += 1;
        }
        self.lost |= valid < self.views.len();
        valid
    }

    fn cost(&self) -> f64 {
        self.system.cost
    }

    fn linearize(&mut self) -> NormalEquations<3> {
        self.system.clone()
    }

    fn retract(&self, x: &Point3<f64>, step: &Vector3<f64>) -> Point3<f64> {
        x + step
    }

    /// The step relative to the point's distance from the origin, at least 1 map unit.
    fn step_norm(&self, step: &Vector3<f64>) -> f64 {
        step.norm() / self.at.coords.norm().max(1.0)
    }
}
