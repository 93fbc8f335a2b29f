//! Iteratively reweighted Levenberg-Marquardt.
//!
//! Minimises the robust cost `C(x) = s^2 sum_i rho(r_i(x) / s)` over a state `x` (a vector or
//! a manifold element such as a pose) given a [`Problem`] that evaluates residual rows
//! `r_i(x)` and their Jacobians `J_i = dr_i/d delta` with respect to a local increment
//! `delta` applied by [`Problem::retract`]. Each iteration:
//!
//! 1. weights `w_i = psi(u_i) / u_i` with `u_i = r_i / s` (reweight);
//! 2. `(H + lambda D) delta = -g` with `H = J^T W J`, `g = J^T W r` (solve, see [`crate::solve`]);
//! 3. `x' = retract(x, delta)`, accepted when the mean robust cost decreases (update), with
//!    `lambda` divided by 10 on success and multiplied by 10 on failure;
//! 4. the scale `s` is re-estimated from the accepted residuals when [`ScaleMode::Mad`] is used;
//! 5. stop on a small step, a small relative cost change, or the iteration limit.
//!
//! The mean cost (cost over the number of rows) is compared so that problems whose valid rows
//! change with `x` (pixels leaving the image) are judged fairly. The covariance returned is the
//! Gauss-Newton approximation `sigma^2 H^-1` with
//! `sigma^2 = sum w_i r_i^2 / (n - N)` at the solution.

use nalgebra::{SMatrix, SVector};
use thiserror::Error;

use crate::loss::{Loss, RobustLoss};
use crate::normal::NormalEquations;
use crate::scale::mad_sigma_about_zero;
use crate::solve::{scaled_condition, solve_damped, Damping, SolveError};

/// Residual rows and their Jacobians, stored as two parallel arrays.
#[derive(Debug, Clone, Default)]
pub struct Rows<const N: usize> {
    /// `J_i = dr_i / d delta`, one per row.
    pub jacobians: Vec<SVector<f64, N>>,
    /// `r_i`, one per row.
    pub residuals: Vec<f64>,
}

impl<const N: usize> Rows<N> {
    /// Appends a row with Jacobian `j` and residual `r`.
    #[inline]
    pub fn push(&mut self, j: SVector<f64, N>, r: f64) {
        self.jacobians.push(j);
        self.residuals.push(r);
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.residuals.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.residuals.is_empty()
    }

    /// Removes every row, keeping the allocations.
    pub fn clear(&mut self) {
        self.jacobians.clear();
        self.residuals.clear();
    }
}

/// A nonlinear least-squares problem: residuals and Jacobians at a state, and the update rule.
pub trait Problem<const N: usize> {
    /// The estimated quantity (a vector, a pose, a pose plus brightness...).
    type State: Clone;
    /// Pushes every valid residual row at `state` into `rows` (which arrives empty).
    fn evaluate(&mut self, state: &Self::State, rows: &mut Rows<N>);
    /// The state moved by the local increment `delta` (`x + delta` for vectors,
    /// `exp(delta) * T` for a pose with a left perturbation).
    fn retract(&self, state: &Self::State, delta: &SVector<f64, N>) -> Self::State;
}

/// How the residual scale `s` is obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScaleMode {
    /// A known residual sigma, in the units of the residuals.
    Fixed(f64),
    /// `1.4826 median |r_i|` re-estimated after every accepted step, never below `min_sigma`.
    Mad {
        /// Floor on the estimate, so that a perfect fit does not divide by zero.
        min_sigma: f64,
    },
}

/// Settings of [`irls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IrlsConfig {
    /// Loss applied to residuals divided by the scale.
    pub loss: Loss,
    /// Where the scale comes from.
    pub scale: ScaleMode,
    /// Upper bound on iterations (accepted and rejected steps both count).
    pub max_iterations: usize,
    /// Stop when `|delta| <` this.
    pub min_step: f64,
    /// Stop when an accepted step lowers the mean cost by less than this fraction.
    pub min_relative_decrease: f64,
    /// Starting `lambda`; `0` starts as Gauss-Newton.
    pub initial_lambda: f64,
    /// Form of the damping matrix.
    pub damping: Damping,
    /// Largest acceptable scaled condition number of `H`.
    pub max_condition: f64,
}

impl Default for IrlsConfig {
    fn default() -> Self {
        Self {
            loss: Loss::default(),
            scale: ScaleMode::Mad { min_sigma: 1e-9 },
            max_iterations: 50,
            min_step: 1e-10,
            min_relative_decrease: 1e-10,
            initial_lambda: 1e-4,
            damping: Damping::Diagonal,
            max_condition: 1e10,
        }
    }
}

/// Why [`irls`] stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convergence {
    /// The step fell below `min_step`.
    SmallStep,
    /// The relative cost decrease fell below `min_relative_decrease`.
    SmallCostChange,
    /// `max_iterations` was reached.
    MaxIterations,
    /// No step lowered the cost even with very strong damping: a (local) minimum.
    NoDecrease,
}

/// What [`irls`] could not do.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum IrlsError {
    /// Fewer residual rows than parameters.
    #[error("{rows} residuals cannot determine {params} parameters")]
    TooFewResiduals {
        /// Valid rows at the state.
        rows: usize,
        /// Number of parameters.
        params: usize,
    },
    /// The step could not be computed (degenerate or non-finite normal equations).
    #[error(transparent)]
    Solve(#[from] SolveError),
}

/// The estimate and how it was reached.
#[derive(Debug, Clone)]
pub struct IrlsResult<S, const N: usize> {
    /// The final state.
    pub state: S,
    /// IRLS weight of each final residual row.
    pub weights: Vec<f64>,
    /// Final residuals, in the problem's units.
    pub residuals: Vec<f64>,
    /// Mean robust cost at the start and after each accepted step.
    pub costs: Vec<f64>,
    /// Iterations run (accepted and rejected steps).
    pub iterations: usize,
    /// Why it stopped.
    pub reason: Convergence,
    /// Residual scale `s` at the end.
    pub scale: f64,
    /// `H = J^T W J` at the final state.
    pub hessian: SMatrix<f64, N, N>,
    /// `sigma^2 H^-1` with `sigma^2 = sum w r^2 / (n - N)`.
    pub covariance: SMatrix<f64, N, N>,
}

/// Robust scale of `residuals` under `mode`.
fn estimate_scale(mode: ScaleMode, residuals: &[f64]) -> f64 {
    match mode {
        ScaleMode::Fixed(s) => s,
        ScaleMode::Mad { min_sigma } => mad_sigma_about_zero(residuals)
            .unwrap_or(min_sigma)
            .max(min_sigma),
    }
}

/// Mean robust cost `s^2 mean rho(r / s)`.
fn mean_cost(loss: &Loss, scale: f64, residuals: &[f64]) -> f64 {
    let sum: f64 = residuals.iter().map(|r| loss.rho(r / scale)).sum();
    scale * scale * sum / residuals.len().max(1) as f64
}

/// Normal equations of `rows` weighted by `loss` at `scale`.
fn accumulate<const N: usize>(loss: &Loss, scale: f64, rows: &Rows<N>) -> NormalEquations<N> {
    let mut ne = NormalEquations::new();
    for (j, &r) in rows.jacobians.iter().zip(&rows.residuals) {
        ne.add(j, r, loss.weight(r / scale));
    }
    ne
}

/// Runs iteratively reweighted Levenberg-Marquardt from `x0`; see the module documentation.
pub fn irls<P: Problem<N>, const N: usize>(
    problem: &mut P,
    x0: P::State,
    cfg: &IrlsConfig,
) -> Result<IrlsResult<P::State, N>, IrlsError> {
    let mut state = x0;
    let mut rows = Rows::default();
    let mut trial = Rows::default();
    problem.evaluate(&state, &mut rows);
    if rows.len() < N {
        return Err(IrlsError::TooFewResiduals {
            rows: rows.len(),
            params: N,
        });
    }
    let mut scale = estimate_scale(cfg.scale, &rows.residuals);
    let mut cost = mean_cost(&cfg.loss, scale, &rows.residuals);
    let mut ne = accumulate(&cfg.loss, scale, &rows);
    let mut costs = vec![cost];
    let mut lambda = cfg.initial_lambda;
    let mut reason = Convergence::MaxIterations;
    let mut iterations = 0;

    while iterations < cfg.max_iterations {
        iterations += 1;
        let delta = solve_damped(&ne.hessian(), &ne.g, lambda, cfg.damping, cfg.max_condition)?;
        let candidate = problem.retract(&state, &delta);
        trial.clear();
        problem.evaluate(&candidate, &mut trial);
        let trial_cost = if trial.len() >= N {
            mean_cost(&cfg.loss, scale, &trial.residuals)
        } else {
            f64::INFINITY
        };
        let small_step = delta.norm() < cfg.min_step;
        if trial_cost < cost {
            let relative = (cost - trial_cost) / cost.max(f64::MIN_POSITIVE);
            state = candidate;
            std::mem::swap(&mut rows, &mut trial);
            lambda /= 10.0;
            scale = estimate_scale(cfg.scale, &rows.residuals);
            cost = mean_cost(&cfg.loss, scale, &rows.residuals);
            ne = accumulate(&cfg.loss, scale, &rows);
            costs.push(cost);
            if small_step {
                reason = Convergence::SmallStep;
                break;
            }
            if relative < cfg.min_relative_decrease {
                reason = Convergence::SmallCostChange;
                break;
            }
        } else {
            if small_step {
                reason = Convergence::SmallStep;
                break;
            }
            lambda = (lambda * 10.0).max(1e-4);
            if lambda > 1e12 {
                reason = Convergence::NoDecrease;
                break;
            }
        }
    }

    let hessian = ne.hessian();
    let condition = scaled_condition(&hessian);
    let inverse = match hessian.try_inverse() {
        Some(inv) if condition <= cfg.max_condition => inv,
        _ => {
            return Err(IrlsError::Solve(SolveError::Degenerate {
                condition,
                limit: cfg.max_condition,
            }))
        }
    };
    let weights: Vec<f64> = rows
        .residuals
        .iter()
        .map(|r| cfg.loss.weight(r / scale))
        .collect();
    let dof = rows.len().saturating_sub(N).max(1) as f64;
    let sigma2 = 2.0 * ne.cost / dof;
    Ok(IrlsResult {
        state,
        weights,
        residuals: rows.residuals,
        costs,
        iterations,
        reason,
        scale,
        hessian,
        covariance: inverse * sigma2,
    })
}
