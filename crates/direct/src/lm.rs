//! The direct aligners' side of the robust Levenberg-Marquardt driver
//! ([`vofront_robust::levenberg_marquardt`]), one pyramid level at a time.
//!
//! A [`LevelProblem`] evaluates residuals `r_i` (NaN for invalid pixels) into its own buffers
//! and accumulates `H = sum w_i J_i^T J_i`, `g = sum w_i J_i^T r_i` in parallel. Around it,
//! this module supplies what is specific to images: the scale `s = 1.4826 median |r_i|`
//! (floored, from a strided subset), re-estimated after every accepted step; the cost, the
//! mean robust cost `s^2 mean rho(r_i / s)` over the valid residuals; parameters held fixed
//! (identity rows in `H`); and a step norm with per-parameter weights. The driver starts as
//! Gauss-Newton (`lambda = 0`, raised to at least 1e-3 by a rejection), and a few rejections
//! in a row end the level, as does a step that is small in metric terms or small against its
//! own uncertainty (`delta^T H delta / s^2`, the squared step in standard deviations).

use nalgebra::SVector;
use rayon::prelude::*;
use vofront_robust::{
    levenberg_marquardt, mad_sigma_about_zero, Convergence, Damping, LmConfig, LmError, LmProblem,
    Loss, NormalEquations, RobustLoss,
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

/// A rejected step raises `lambda` to at least this (the level starts as Gauss-Newton).
const LAMBDA_FLOOR: f64 = 1e-3;

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
    /// Normal equations at the final state (with fixed parameters replaced by identity rows);
    /// [`NormalEquations::covariance`] gives the Gauss-Newton covariance.
    pub system: NormalEquations<M>,
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

/// A [`LevelProblem`] with the image-specific scale, cost, fixed parameters and step norm.
struct Robust<'a, P, const M: usize> {
    problem: &'a mut P,
    cfg: &'a LmSettings<M>,
    scale: f32,
}

impl<P: LevelProblem<M>, const M: usize> LmProblem for Robust<'_, P, M> {
    type State = P::State;
    type System = NormalEquations<M>;

    fn evaluate(&mut self, state: &P::State) -> usize {
        self.problem.evaluate(state)
    }

    fn cost(&self) -> f64 {
        let residuals = self.problem.residuals();
        mean_robust_cost(&self.cfg.loss, self.scale, residuals, self.cfg.serial_max)
    }

    fn update_scale(&mut self) {
        self.scale = robust_scale(self.problem.residuals(), self.cfg.min_sigma);
    }

    fn scale(&self) -> f64 {
        f64::from(self.scale)
    }

    fn linearize(&mut self) -> NormalEquations<M> {
        let mut ne = self.problem.normal_equations(&self.cfg.loss, self.scale);
        for (i, _) in self.cfg.fixed.iter().enumerate().filter(|(_, f)| **f) {
            ne.fix(i);
        }
        ne
    }

    fn retract(&self, state: &P::State, step: &SVector<f64, M>) -> P::State {
        self.problem.retract(state, step)
    }

    fn step_norm(&self, step: &SVector<f64, M>) -> f64 {
        step.component_mul(&self.cfg.step_weights).norm()
    }

    fn save(&mut self) {
        self.problem.save();
    }

    fn restore(&mut self, state: &P::State) {
        self.problem.restore(state);
    }
}

/// Runs the robust Levenberg-Marquardt driver on one level from `state`; see the module
/// documentation.
pub(crate) fn run_level<P: LevelProblem<M>, const M: usize>(
    problem: &mut P,
    state: P::State,
    cfg: &LmSettings<M>,
) -> Result<LevelOutcome<P::State, M>, DirectError> {
    let lm = LmConfig {
        max_iterations: cfg.max_iterations,
        min_step: cfg.min_step,
        min_step_sigmas: cfg.min_step_sigmas,
        min_relative_decrease: cfg.min_relative_decrease,
        initial_lambda: 0.0,
        lambda_floor: LAMBDA_FLOOR,
        max_rejections: MAX_REJECTIONS,
        damping: Damping::Diagonal,
        max_condition: cfg.max_condition,
        min_valid: cfg.min_valid,
    };
    let mut robust = Robust {
        problem,
        cfg,
        scale: cfg.min_sigma,
    };
    let out = levenberg_marquardt(&mut robust, state, &lm).map_err(|e| match e {
        LmError::TooFewResiduals { rows, required } => DirectError::TooFewValid {
            valid: rows,
            required,
        },
        LmError::Solve(e) => DirectError::Solve(e),
    })?;
    Ok(LevelOutcome {
        cost: out.cost(),
        state: out.state,
        iterations: out.iterations,
        reason: out.reason,
        scale: robust.scale,
        system: out.system,
        valid: out.valid,
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
