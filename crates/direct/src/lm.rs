//! The robust Levenberg-Marquardt loop shared by every direct aligner, one pyramid level at a
//! time.
//!
//! A [`LevelProblem`] evaluates residuals `r_i` (NaN for invalid pixels) into its own buffers
//! and accumulates `H = sum w_i J_i^T J_i`, `g = sum w_i J_i^T r_i` in parallel. Each iteration:
//! scale `s = 1.4826 median |r_i|` (floored), weights `w_i = psi(r_i/s) / (r_i/s)`, step
//! `(H + lambda diag H) delta = -g` (with parameters held fixed replaced by identity rows),
//! acceptance when the mean robust cost `s^2 mean rho(r_i / s)` decreases, `lambda` divided by
//! 10 on success and multiplied by 10 on failure; a few failures in a row end the level, and so
//! does a step that is small in metric terms or small against its own uncertainty
//! (`delta^T H delta / s^2`, the squared step in standard deviations).

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;
use vofront_robust::{
    mad_sigma_about_zero, solve_damped, Convergence, Damping, Loss, NormalEquations, RobustLoss,
};

use crate::error::DirectError;

/// Residuals per rayon task in the parallel reductions.
pub(crate) const CHUNK: usize = 4096;

/// Up to this many residuals the evaluations and reductions of a level run on the calling
/// thread: handing a few thousand rows to the pool costs more (thread wake-ups) than it saves.
pub(crate) const SERIAL_MAX: usize = 4 * CHUNK;

/// Consecutive rejected steps (each with ten times more damping) that end a level: the
/// linearisation no longer predicts the cost, which happens at the noise floor of the minimum.
const MAX_REJECTIONS: usize = 4;

/// At most this many residuals feed the median of the scale estimate (a strided subset).
const SCALE_SAMPLES: usize = 20_000;

/// One level of a robust nonlinear least-squares problem with `M` parameters.
pub(crate) trait LevelProblem<const M: usize> {
    /// The estimate (warp, pose, brightness...).
    type State: Clone;
    /// Evaluates residuals and Jacobians at `state` into internal buffers; returns the valid count.
    fn evaluate(&mut self, state: &Self::State) -> usize;
    /// Residuals of the last evaluation, NaN where invalid.
    fn residuals(&self) -> &[f32];
    /// Weighted normal equations of the last evaluation.
    fn normal_equations(&self, loss: &Loss, scale: f32) -> NormalEquations<M>;
    /// `state` moved by `delta`.
    fn retract(&self, state: &Self::State, delta: &SVector<f64, M>) -> Self::State;
    /// Called before a trial evaluation: a problem that keeps a second set of buffers saves
    /// the current evaluation (at the accepted state) here.
    fn save(&mut self) {}
    /// Called after a rejected trial: brings back the evaluation at `state` (the one before
    /// the trial), by default by evaluating again.
    fn restore(&mut self, state: &Self::State) {
        self.evaluate(state);
    }
}

/// Settings of [`run_level`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct LmSettings<const M: usize> {
    /// Robust loss on `r / s`.
    pub loss: Loss,
    /// Floor of the residual scale, in residual units.
    pub min_sigma: f32,
    /// Iteration limit (accepted and rejected steps both count).
    pub max_iterations: usize,
    /// Convergence when `step_norm(delta) <` this.
    pub min_step: f64,
    /// Convergence when the step is shorter than this many of its own standard deviations:
    /// `delta^T H delta / s^2 < min_step_sigmas^2`, with `s^2 H^-1` the Gauss-Newton covariance
    /// (0 disables the test).
    pub min_step_sigmas: f64,
    /// Per-parameter weights of the step norm `|diag(step_weights) delta|`.
    pub step_weights: SVector<f64, M>,
    /// Convergence when the relative cost decrease of an accepted step is below this.
    pub min_relative_decrease: f64,
    /// Largest acceptable Jacobi-scaled condition number of `H`.
    pub max_condition: f64,
    /// Parameters held at their current value.
    pub fixed: [bool; M],
    /// Fewest valid residuals accepted.
    pub min_valid: usize,
    /// Up to this many residuals the reductions run on the calling thread (at least one chunk).
    pub serial_max: usize,
}

/// Result of one level.
#[derive(Debug, Clone)]
pub(crate) struct LevelOutcome<S, const M: usize> {
    /// Final state.
    pub state: S,
    /// Iterations run.
    pub iterations: usize,
    /// Why it stopped.
    pub reason: Convergence,
    /// Scale at the end.
    pub scale: f32,
    /// Mean robust cost at the end.
    pub cost: f64,
    /// Normal equations at the final state (with fixed parameters replaced by identity rows).
    pub hessian: SMatrix<f64, M, M>,
    /// Weighted cost `sum w r^2 / 2` at the final state.
    pub weighted_cost: f64,
    /// Valid residuals at the end.
    pub valid: usize,
}

/// Robust scale `max(min_sigma, 1.4826 median |r|)` over the valid residuals.
pub(crate) fn robust_scale(residuals: &[f32], min_sigma: f32) -> f32 {
    let valid = residuals.iter().filter(|r| !r.is_nan()).count();
    let stride = valid.div_ceil(SCALE_SAMPLES).max(1);
    let sample: Vec<f64> = residuals
        .iter()
        .filter(|r| !r.is_nan())
        .step_by(stride)
        .map(|&r| f64::from(r))
        .collect();
    mad_sigma_about_zero(&sample)
        .map(|s| (s as f32).max(min_sigma))
        .unwrap_or(min_sigma)
}

/// Mean robust cost `s^2 mean rho(r / s)` over the valid residuals (parallel).
pub(crate) fn mean_robust_cost(
    loss: &Loss,
    scale: f32,
    residuals: &[f32],
    serial_max: usize,
) -> f64 {
    let s = f64::from(scale);
    let chunk_cost = |chunk: &[f32]| {
        chunk
            .iter()
            .filter(|r| !r.is_nan())
            .fold((0.0f64, 0usize), |(acc, n), &r| {
                (acc + loss.rho(f64::from(r) / s), n + 1)
            })
    };
    let (sum, n) = if residuals.len() <= serial_max.max(CHUNK) {
        residuals
            .chunks(CHUNK)
            .map(chunk_cost)
            .fold((0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    } else {
        residuals
            .par_chunks(CHUNK)
            .map(chunk_cost)
            .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    };
    if n == 0 {
        f64::INFINITY
    } else {
        s * s * sum / n as f64
    }
}

/// `H` and `g` with the fixed parameters' rows and columns replaced by the identity and zero.
fn with_fixed<const M: usize>(
    ne: &NormalEquations<M>,
    fixed: &[bool; M],
) -> (SMatrix<f64, M, M>, SVector<f64, M>) {
    let mut h = ne.hessian();
    let mut g = ne.g;
    for (i, _) in fixed.iter().enumerate().filter(|(_, f)| **f) {
        h.row_mut(i).fill(0.0);
        h.column_mut(i).fill(0.0);
        h[(i, i)] = 1.0;
        g[i] = 0.0;
    }
    (h, g)
}

/// Runs the robust Levenberg-Marquardt loop from `state`; see the module documentation.
pub(crate) fn run_level<P: LevelProblem<M>, const M: usize>(
    problem: &mut P,
    state: P::State,
    cfg: &LmSettings<M>,
) -> Result<LevelOutcome<P::State, M>, DirectError> {
    let mut state = state;
    let mut valid = problem.evaluate(&state);
    if valid < cfg.min_valid {
        return Err(DirectError::TooFewValid {
            valid,
            required: cfg.min_valid,
        });
    }
    let mut scale = robust_scale(problem.residuals(), cfg.min_sigma);
    let mut cost = mean_robust_cost(&cfg.loss, scale, problem.residuals(), cfg.serial_max);
    let mut ne = problem.normal_equations(&cfg.loss, scale);
    let mut lambda = 0.0;
    let mut rejections = 0;
    let mut reason = Convergence::MaxIterations;
    let mut iterations = 0;
    while iterations < cfg.max_iterations {
        iterations += 1;
        let (h, g) = with_fixed(&ne, &cfg.fixed);
        let delta = solve_damped(&h, &g, lambda, Damping::Diagonal, cfg.max_condition)?;
        let sigmas2 = (delta.transpose() * h * delta)[(0, 0)] / f64::from(scale * scale);
        let small = delta.component_mul(&cfg.step_weights).norm() < cfg.min_step
            || sigmas2 < cfg.min_step_sigmas * cfg.min_step_sigmas;
        let candidate = problem.retract(&state, &delta);
        problem.save();
        let trial_valid = problem.evaluate(&candidate);
        let trial_cost = if trial_valid >= cfg.min_valid {
            mean_robust_cost(&cfg.loss, scale, problem.residuals(), cfg.serial_max)
        } else {
            f64::INFINITY
        };
        if trial_cost <= cost {
            let relative = (cost - trial_cost) / cost.max(f64::MIN_POSITIVE);
            state = candidate;
            valid = trial_valid;
            rejections = 0;
            lambda *= 0.1;
            scale = robust_scale(problem.residuals(), cfg.min_sigma);
            cost = mean_robust_cost(&cfg.loss, scale, problem.residuals(), cfg.serial_max);
            ne = problem.normal_equations(&cfg.loss, scale);
            if small {
                reason = Convergence::SmallStep;
                break;
            }
            if relative < cfg.min_relative_decrease {
                reason = Convergence::SmallCostChange;
                break;
            }
        } else {
            problem.restore(&state);
            if small {
                reason = Convergence::SmallStep;
                break;
            }
            lambda = (lambda * 10.0).max(1e-3);
            rejections += 1;
            if rejections >= MAX_REJECTIONS {
                reason = Convergence::NoDecrease;
                break;
            }
        }
    }
    let (hessian, _) = with_fixed(&ne, &cfg.fixed);
    Ok(LevelOutcome {
        state,
        iterations,
        reason,
        scale,
        cost,
        hessian,
        weighted_cost: ne.cost,
        valid,
    })
}

/// Parallel fold of per-residual rows into normal equations: `rows(i)` yields
/// `(J_i, r_i)` for valid residual `i`, weighted by `loss` at `scale`; on the calling thread
/// up to `serial_max` rows (at least one chunk).
pub(crate) fn accumulate<const M: usize, F>(
    n: usize,
    loss: &Loss,
    scale: f32,
    serial_max: usize,
    row: F,
) -> NormalEquations<M>
where
    F: Fn(usize) -> Option<(SVector<f64, M>, f64)> + Sync,
{
    let s = f64::from(scale);
    // One accumulator per chunk, filled in place (a fold over single rows would move the
    // `N x N` accumulator at every row).
    let chunk = |c: usize| {
        let mut ne = NormalEquations::<M>::new();
        for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
            if let Some((j, r)) = row(i) {
                ne.add(&j, r, loss.weight(r / s));
            }
        }
        ne
    };
    if n <= serial_max.max(CHUNK) {
        return (0..n.div_ceil(CHUNK))
            .map(chunk)
            .fold(NormalEquations::new(), |a, b| a.merge(&b));
    }
    (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(chunk)
        .reduce(NormalEquations::new, |a, b| a.merge(&b))
}

/// Covariance `sigma^2 H^-1` with `sigma^2 = 2 cost_w / (n - M)`; zero matrix when singular.
pub(crate) fn covariance<const M: usize>(
    hessian: &SMatrix<f64, M, M>,
    weighted_cost: f64,
    valid: usize,
) -> SMatrix<f64, M, M> {
    let dof = valid.saturating_sub(M).max(1) as f64;
    hessian
        .try_inverse()
        .map(|inv| inv * (2.0 * weighted_cost / dof))
        .unwrap_or_else(SMatrix::zeros)
}
