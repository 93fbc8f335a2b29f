//! Robust refinement of `(R, t)` on the unit sphere by the Sampson error, through
//! [`vofront_robust::irls()`].
//!
//! State: `R` and a unit `t`; increment `delta = (phi, a, b)` (5 DoF) applied as
//! `R <- exp(phi) R`, `t <- normalize(t + a b1 + b b2)` with `(b1, b2)` an orthonormal basis
//! of the tangent plane at `t`. Residual of correspondence `i`: the signed Sampson distance in
//! pixels, `f x2^T E x1 / sqrt((E x1)_1^2 + (E x1)_2^2 + (E^T x2)_1^2 + (E^T x2)_2^2)` with
//! `E = [t]_x R` ([`crate::residual::Epipolar`]); analytic Jacobians. A correspondence with a
//! degenerate denominator is an outlier (no row), as everywhere in [`crate::residual`].

use std::collections::HashMap;

use nalgebra::{Matrix5, Rotation3, SMatrix, SVector, Vector2, Vector3};
use vofront_robust::{
    at_least, clustered_sandwich_covariance, irls, Convergence, IrlsConfig, LmConfig, Loss,
    NormalEquations, Problem, Rows, ScaleMode,
};

use super::correspondences::Correspondences;
use crate::lie::{hat, so3_exp};
use crate::residual::row_major;

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

impl Problem<5> for SampsonProblem<'_> {
    type State = RelState;

    /// With `y = R x1`, `u = [t]x^T x2 = x2 x t`, `p = ((E x1)_1, (E x1)_2, 0)` and
    /// `q = ((E^T x2)_1, (E^T x2)_2, 0)`, the derivatives of `c = x2^T E x1` and of
    /// `D / 2 = p . (dE x1) + q . (dE^T x2)` are dot products with cross products:
    /// `dE = [t]x [phi]x R` gives `dc = phi . (y x u)`, `dD / 2 = phi . (y x (p x t) + Rq x u)`;
    /// `dE = [b]x R` gives `dc = b . (y x x2)`, `dD / 2 = b . (y x p + Rq x x2)`. Then
    /// `dr = f / sqrt(D) (dc - c / D dD / 2)`.
    fn evaluate(&mut self, state: &RelState, rows: &mut Rows<5>) {
        let (r, t) = (state.0.matrix(), state.1);
        let e_rm = row_major(&(hat(&t) * r));
        let (b1, b2) = tangent_basis(&t);
        for &i in self.indices {
            let ep = self.data.epipolar(&e_rm, i);
            if !ep.is_regular() {
                continue;
            }
            let (x1, x2) = (self.data.ray1(i), self.data.ray2(i));
            let (p, q) = (
                Vector3::new(ep.l2[0], ep.l2[1], 0.0),
                Vector3::new(ep.l1[0], ep.l1[1], 0.0),
            );
            let (y, rq, u) = (r * x1, r * q, x2.cross(&t));
            let c_over_d = ep.c / ep.d;
            let rotation = y.cross(&u) - (y.cross(&p.cross(&t)) + rq.cross(&u)) * c_over_d;
            let translation = y.cross(&x2) - (y.cross(&p) + rq.cross(&x2)) * c_over_d;
            let scale = self.focal / ep.d.sqrt();
            let j = SVector::<f64, 5>::new(
                rotation.x,
                rotation.y,
                rotation.z,
                b1.dot(&translation),
                b2.dot(&translation),
            );
            rows.push(j * scale, scale * ep.c);
        }
    }

    fn retract(&self, state: &RelState, delta: &SVector<f64, 5>) -> RelState {
        let r = so3_exp(&Vector3::new(delta[0], delta[1], delta[2])) * state.0;
        let (b1, b2) = tangent_basis(&state.1);
        let t = (state.1 + b1 * delta[3] + b2 * delta[4]).normalize();
        (r, t)
    }
}

/// A converged refinement of `(R, t)` and its uncertainty.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RelRefinement {
    /// The refined `(R, t)`, unit `t`.
    pub state: RelState,
    /// `H = J^T W J` of the Sampson residuals (pixels) at the solution, in the increment
    /// `delta = (phi, a, b)` (radians, and unit-sphere tangent coordinates of `t`).
    pub hessian: Matrix5<f64>,
    /// Gauss-Newton covariance `sigma^2 H^-1` of `delta`; `None` (unknown) when `H` is
    /// singular.
    pub covariance: Option<Matrix5<f64>>,
    /// Iterations run.
    pub iterations: usize,
    /// Why the refinement stopped.
    pub reason: Convergence,
}

/// Gauss-Newton information `J^T J` of the Sampson distances (pixels) of `indices` at
/// `state`, in the increment `delta = (phi, a, b)` of [`refine_relative_pose`]: the Hessian
/// [`RelRefinement::hessian`] with unit weights, from the same rows and the same accumulator
/// ([`NormalEquations`]). The covariance of the estimate is `sigma_px^2 (J^T J)^-1`.
pub fn sampson_information(
    data: &Correspondences,
    indices: &[usize],
    focal: f64,
    state: &RelState,
) -> Matrix5<f64> {
    let mut problem = SampsonProblem {
        data,
        indices,
        focal,
    };
    let mut rows = Rows::default();
    problem.evaluate(state, &mut rows);
    let mut normal = NormalEquations::<5>::new();
    for (j, &r) in rows.jacobians.iter().zip(&rows.residuals) {
        normal.add(j, r, 1.0);
    }
    normal.hessian()
}

/// Side (pixels) of the image cells whose keypoints' errors the covariance takes as
/// correlated: 64 px, twice the 31 px patch an ORB keypoint's position and descriptor rest on
/// at the finest level and more than that patch at the next three levels (1.2^3 x 31 = 54
/// px). Keypoints closer than a patch share pixels, blur and the structure they sit on; lens
/// and calibration errors vary smoothly across the image.
pub const KEYPOINT_CELL_PX: f64 = 64.0;

/// The cluster-robust covariance of `delta` ([`vofront_robust::clustered_sandwich_covariance`]:
/// least squares on the Sampson distances of `indices` at `state`, clusters the
/// [`KEYPOINT_CELL_PX`] cells of the points' positions in image 1). Its meat weighs each
/// correspondence by its own squared residual, so that keypoints of coarse pyramid levels
/// (noise `1.2^k` px at level `k`) count with their larger noise, and sums the scores within
/// a cell before squaring, so that errors shared by neighbouring keypoints do not average out.
fn clustered_sampson_covariance(
    data: &Correspondences,
    indices: &[usize],
    focal: f64,
    state: &RelState,
    sigma_px: f64,
) -> Option<Matrix5<f64>> {
    let mut cells: HashMap<(i64, i64), usize> = HashMap::new();
    let mut rows = Vec::with_capacity(indices.len());
    let mut one = Rows::default();
    for &i in indices {
        one.clear();
        SampsonProblem {
            data,
            indices: &[i],
            focal,
        }
        .evaluate(state, &mut one);
        let (Some(j), Some(&r)) = (one.jacobians.first(), one.residuals.first()) else {
            continue;
        };
        let p = data.p1(i) * (focal / KEYPOINT_CELL_PX);
        let key = (p.x.floor() as i64, p.y.floor() as i64);
        let next = cells.len();
        rows.push((*j, r, *cells.entry(key).or_insert(next)));
    }
    clustered_sandwich_covariance(rows, cells.len(), &Loss::Squared, sigma_px, &[false; 5])
}

/// Covariance of `delta = (phi, a, b)` (radians and tangent coordinates) of the estimate
/// `state` from the Sampson distances (pixels) of `indices` at noise scale `sigma_px`:
/// `sigma_px^2 (J^T J)^-1` ([`sampson_information`]), raised to the cluster-robust covariance
/// where that is wider ([`vofront_robust::at_least`], [`KEYPOINT_CELL_PX`]: correlated and
/// level-dependent keypoint errors), then widened along each principal axis where
/// the least-squares Sampson cost `sum_i r_i^2 / sigma_px^2` rises less than its quadratic
/// model ([`vofront_robust::secant_covariance`]; at low parallax the residuals of points near
/// the epipole are far from linear in the translation direction). `None` when `J^T J` is
/// singular.
pub fn sampson_covariance(
    data: &Correspondences,
    indices: &[usize],
    focal: f64,
    state: &RelState,
    sigma_px: f64,
) -> Option<Matrix5<f64>> {
    let local = sampson_information(data, indices, focal, state)
        .try_inverse()
        .map(|inv| inv * (sigma_px * sigma_px))
        .filter(|c| c.iter().all(|v| v.is_finite()) && (0..5).all(|i| c[(i, i)] >= 0.0))?;
    let local = clustered_sampson_covariance(data, indices, focal, state, sigma_px)
        .filter(|c| c.iter().all(|v| v.is_finite()))
        .map_or(local, |c| at_least(&local, &c));
    let problem = SampsonProblem {
        data,
        indices,
        focal,
    };
    // The rows of `SampsonProblem::evaluate` (regular denominators only), without Jacobians.
    let cost = |s: &RelState| {
        let e = row_major(&(hat(&s.1) * s.0.matrix()));
        let sum_sq: f64 = indices
            .iter()
            .map(|&i| data.epipolar(&e, i))
            .filter(|ep| ep.is_regular())
            .map(|ep| (focal * ep.sampson()).powi(2))
            .sum();
        sum_sq / (sigma_px * sigma_px)
    };
    let at_estimate = cost(state);
    Some(vofront_robust::secant_covariance(&local, |delta| {
        cost(&problem.retract(state, delta)) - at_estimate
    }))
}

/// Sensitivity of the least-squares estimate `state` on the Sampson distances of `indices` to
/// errors of the intrinsics, as the columns of a 5x3 matrix `V`: `d delta / d s` for a
/// relative focal-length error `s` (the normalized coordinates of both views scaled by
/// `1 + s`, as the focal length `f / (1 + s)` would give) and `d delta / d c_x`,
/// `d delta / d c_y` for a principal-point error in pixels (both views' normalized coordinates
/// shifted by `-c / f`). Implicit differentiation of the normal equations,
/// `dV = -(J^T J)^-1 J^T dr/dk`, with `dr/dk` by central differences. `None` when `J^T J` is
/// singular.
///
/// With intrinsics known to the covariance `S` (3x3 over `(s, c_x, c_y)`), the estimate
/// carries the covariance `V S V^T` beyond its noise covariance: an intrinsics error scales or
/// shifts every ray alike (the rotation's pan and tilt, the epipole), so that no number of
/// correspondences averages it out.
pub fn intrinsics_sensitivity(
    data: &Correspondences,
    indices: &[usize],
    focal: f64,
    state: &RelState,
) -> Option<SMatrix<f64, 5, 3>> {
    /// Steps of the central differences: relative focal error, principal point (pixels).
    const STEPS: [f64; 3] = [1e-4, 0.05, 0.05];
    let perturbed = |k: usize, sign: f64| {
        let h = sign * STEPS[k];
        let map = |p: Vector2<f64>| match k {
            0 => p * (1.0 + h),
            1 => p - Vector2::new(h / focal, 0.0),
            _ => p - Vector2::new(0.0, h / focal),
        };
        let mut out = Correspondences::default();
        for &i in indices {
            out.push(&map(data.p1(i)), &map(data.p2(i)));
        }
        out
    };
    let at = perturbed(0, 0.0);
    let sets: Vec<(Correspondences, Correspondences)> = (0..3)
        .map(|k| (perturbed(k, 1.0), perturbed(k, -1.0)))
        .collect();
    let mut one = Rows::default();
    let mut row = |set: &Correspondences, k: usize| {
        one.clear();
        SampsonProblem {
            data: set,
            indices: &[k],
            focal,
        }
        .evaluate(state, &mut one);
        one.jacobians
            .first()
            .copied()
            .zip(one.residuals.first().copied())
    };
    let mut normal = NormalEquations::<5>::new();
    let mut cross = SMatrix::<f64, 5, 3>::zeros();
    'rows: for k in 0..indices.len() {
        let Some((j, _)) = row(&at, k) else {
            continue;
        };
        let mut dr = [0.0; 3];
        for (c, (plus, minus)) in sets.iter().enumerate() {
            let (Some((_, rp)), Some((_, rm))) = (row(plus, k), row(minus, k)) else {
                continue 'rows;
            };
            dr[c] = (rp - rm) / (2.0 * STEPS[c]);
        }
        normal.add(&j, 0.0, 1.0);
        for (c, d) in dr.iter().enumerate() {
            cross.set_column(c, &(cross.column(c) + j * *d));
        }
    }
    normal
        .hessian()
        .try_inverse()
        .map(|inv| -(inv * cross))
        .filter(|v| v.iter().all(|x| x.is_finite()))
}

/// Refines `(R, t)` on the correspondences `indices` with `loss` on the Sampson distance in
/// pixels divided by `sigma_px`, keeping the final Hessian and covariance; `None` when the
/// solve fails (too few correspondences, degenerate normal equations).
pub fn refine_relative_pose_fit(
    data: &Correspondences,
    indices: &[usize],
    focal: f64,
    sigma_px: f64,
    loss: Loss,
    init: RelState,
) -> Option<RelRefinement> {
    refine_fit(
        data,
        indices,
        focal,
        &sampson_irls(sigma_px, loss, REFINE_ITERATIONS, true),
        init,
    )
}

/// Iterations of a full refinement ([`refine_relative_pose_fit`]).
const REFINE_ITERATIONS: usize = 20;

/// The IRLS settings of a Sampson refinement: `loss` on the residuals over `sigma_px`, at
/// most `max_iterations` iterations, with the covariance when `covariance`.
fn sampson_irls(sigma_px: f64, loss: Loss, max_iterations: usize, covariance: bool) -> IrlsConfig {
    IrlsConfig {
        loss,
        scale: ScaleMode::Fixed(sigma_px),
        lm: LmConfig {
            max_iterations,
            min_step: 1e-9,
            min_relative_decrease: 1e-8,
            ..LmConfig::default()
        },
        covariance,
    }
}

/// [`refine_relative_pose_fit`] under the IRLS settings `cfg`.
fn refine_fit(
    data: &Correspondences,
    indices: &[usize],
    focal: f64,
    cfg: &IrlsConfig,
    init: RelState,
) -> Option<RelRefinement> {
    let mut problem = SampsonProblem {
        data,
        indices,
        focal,
    };
    irls(&mut problem, init, cfg).ok().map(|res| RelRefinement {
        state: res.state,
        hessian: res.hessian,
        covariance: res.covariance,
        iterations: res.iterations,
        reason: res.reason,
    })
}

/// Refines `(R, t)` on the correspondences `indices` with `loss` on the Sampson distance in
/// pixels divided by `sigma_px`; returns the input when the solve fails (see
/// [`refine_relative_pose_fit`]).
pub fn refine_relative_pose(
    data: &Correspondences,
    indices: &[usize],
    focal: f64,
    sigma_px: f64,
    loss: Loss,
    init: RelState,
) -> RelState {
    let cfg = sampson_irls(sigma_px, loss, REFINE_ITERATIONS, false);
    refine_fit(data, indices, focal, &cfg, init).map_or(init, |r| r.state)
}

/// A few Huber IRLS steps (at most `max_iterations`) of [`refine_relative_pose`] on the Sampson
/// distance in units of `sigma` (normalized coordinates at `focal` 1): the local optimisation
/// of a RANSAC hypothesis, which only has to gather its inliers; the chosen model is refined
/// in full afterwards. The input when the solve fails.
pub(crate) fn local_refinement(
    data: &Correspondences,
    indices: &[usize],
    sigma: f64,
    init: RelState,
    max_iterations: usize,
) -> RelState {
    let cfg = sampson_irls(sigma, Loss::Huber(1.345), max_iterations, false);
    refine_fit(data, indices, 1.0, &cfg, init).map_or(init, |r| r.state)
}

/// Settings of [`refine_maximum_likelihood`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MlRefineConfig {
    /// Starting noise scale of the Sampson distance, pixels.
    pub initial_sigma_px: f64,
    /// Correspondences with `|r| < gate_sigmas * sigma` take part in a fit.
    pub gate_sigmas: f64,
    /// Loss on `r / sigma` of the fit.
    pub loss: Loss,
    /// Upper bound on (re-selection, fit) rounds.
    pub max_rounds: usize,
}

impl Default for MlRefineConfig {
    fn default() -> Self {
        Self {
            initial_sigma_px: 0.5,
            gate_sigmas: 3.0,
            loss: Loss::Huber(1.345),
            max_rounds: 6,
        }
    }
}

/// Maximum-likelihood refit of `(R, t)` with a noise scale estimated from the data.
///
/// Alternates: residuals `r_i` (Sampson, pixels) of all correspondences; the gated set
/// `|r_i| < gate * sigma`; `sigma = 1.4826 median |r_i|` over that set (a fixed-point
/// iteration that converges to the inlier noise level from above or below, since a
/// `3 sigma` gate keeps nearly all of a Gaussian); a robust fit (`loss` on `r / sigma`) on the
/// gated set. Stops when the gated set no longer changes or after `max_rounds`. Returns the
/// state and the final `sigma` in pixels.
pub fn refine_maximum_likelihood(
    data: &Correspondences,
    focal: f64,
    cfg: &MlRefineConfig,
    init: RelState,
) -> (RelState, f64) {
    let mut state = init;
    let mut sigma = cfg.initial_sigma_px;
    let mut previous: Vec<usize> = Vec::new();
    let mut gated: Vec<f64> = Vec::with_capacity(data.len());
    for _ in 0..cfg.max_rounds {
        let e = row_major(&(hat(&state.1) * state.0.matrix()));
        // Signed Sampson distances in pixels (infinite, so never gated in, when degenerate).
        let residuals: Vec<f64> = (0..data.len())
            .map(|i| focal * data.epipolar(&e, i).sampson())
            .collect();
        // Scale from the residuals inside the current gate, then the gate of that scale.
        gated.clear();
        gated.extend(
            residuals
                .iter()
                .copied()
                .filter(|r| r.abs() < cfg.gate_sigmas * sigma),
        );
        if let Some(s) = vofront_robust::mad_sigma_about_zero(&gated).filter(|s| *s > 0.0) {
            sigma = s;
        }
        let indices: Vec<usize> = (0..data.len())
            .filter(|&i| residuals[i].abs() < cfg.gate_sigmas * sigma)
            .collect();
        if indices.len() < 5 || indices == previous {
            break;
        }
        state = refine_relative_pose(data, &indices, focal, sigma, cfg.loss, state);
        previous = indices;
    }
    (state, sigma)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;
    use rand::{Rng, SeedableRng};

    /// Correspondences of a random scene under `(R, t)`, Gaussian pixel noise `noise_px` at
    /// focal `focal`, and a fraction `outliers` replaced by uniform points.
    fn scene(
        r: &Rotation3<f64>,
        t: &Vector3<f64>,
        focal: f64,
        noise_px: f64,
        outliers: f64,
    ) -> Correspondences {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut gauss = || vofront_fixtures::noise::gauss(&mut rng);
        let mut rng2 = rand::rngs::StdRng::seed_from_u64(8);
        let mut data = Correspondences::default();
        for _ in 0..600 {
            let p = Vector3::new(
                rng2.random_range(-2.0..2.0),
                rng2.random_range(-1.5..1.5),
                rng2.random_range(2.0..8.0),
            );
            let q = r * p + t;
            let n = noise_px / focal;
            let a = Vector2::new(p.x / p.z + n * gauss(), p.y / p.z + n * gauss());
            let mut b = Vector2::new(q.x / q.z + n * gauss(), q.y / q.z + n * gauss());
            if rng2.random_range(0.0..1.0) < outliers {
                b = Vector2::new(rng2.random_range(-0.6..0.6), rng2.random_range(-0.45..0.45));
            }
            data.push(&a, &b);
        }
        data
    }

    #[test]
    fn analytic_jacobian_matches_central_differences() {
        let r = so3_exp(&Vector3::new(0.05, 0.1, 0.02));
        let t = Vector3::new(0.3, 0.05, 0.1).normalize();
        let data = scene(&r, &t, 520.0, 1.0, 0.0);
        let indices: Vec<usize> = (0..data.len()).collect();
        let mut problem = SampsonProblem {
            data: &data,
            indices: &indices,
            focal: 520.0,
        };
        let mut rows = Rows::default();
        problem.evaluate(&(r, t), &mut rows);
        const H: f64 = 1e-6;
        /// Central differences of pixel residuals at `H` agree to this (pixels per radian).
        const TOLERANCE: f64 = 1e-4;
        for k in 0..5 {
            let mut d = SVector::<f64, 5>::zeros();
            d[k] = H;
            let (mut plus, mut minus) = (Rows::default(), Rows::default());
            problem.evaluate(&problem.retract(&(r, t), &d), &mut plus);
            problem.evaluate(&problem.retract(&(r, t), &(-d)), &mut minus);
            for i in 0..rows.len() {
                let numeric = (plus.residuals[i] - minus.residuals[i]) / (2.0 * H);
                let analytic = rows.jacobians[i][k];
                assert!(
                    (numeric - analytic).abs() < TOLERANCE * (1.0 + analytic.abs()),
                    "row {i} param {k}: {numeric} vs {analytic}"
                );
            }
        }
    }

    #[test]
    fn ml_refit_recovers_the_noise_scale_from_a_wrong_guess() {
        let r = so3_exp(&Vector3::new(0.05, 0.1, 0.02));
        let t = Vector3::new(0.3, 0.05, 0.1).normalize();
        const NOISE_PX: f64 = 1.0;
        // Sampson distance of noise sigma in all four coordinates has sigma ~ NOISE_PX; 600
        // correspondences (half outliers) estimate it within 15%.
        const SCALE_TOLERANCE: f64 = 0.15;
        let data = scene(&r, &t, 520.0, NOISE_PX, 0.5);
        for guess in [0.3, 3.0] {
            let cfg = MlRefineConfig {
                initial_sigma_px: guess,
                ..MlRefineConfig::default()
            };
            let ((r_est, t_est), sigma) = refine_maximum_likelihood(&data, 520.0, &cfg, (r, t));
            assert!(
                (sigma / NOISE_PX - 1.0).abs() < SCALE_TOLERANCE,
                "guess {guess}: sigma {sigma}"
            );
            // Still at the truth: within the few-hundredths-of-a-degree spread of an ML fit.
            assert!((r_est.inverse() * r).angle() < 0.2f64.to_radians());
            assert!(t_est.dot(&t) > 3f64.to_radians().cos());
        }
    }
}
