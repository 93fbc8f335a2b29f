//! Iteratively reweighted least squares on residual rows, through the one
//! [`levenberg_marquardt`] driver.
//!
//! Minimises the robust cost `C(x) = s^2 mean_i rho(r_i(x) / s)` over a state `x` (a vector or
//! a manifold element such as a pose) given a [`Problem`] that evaluates residual rows
//! `r_i(x)` and their Jacobians `J_i = dr_i/d delta` with respect to a local increment
//! `delta` applied by [`Problem::retract`]. The rows are weighted by `w_i = psi(u_i) / u_i`,
//! `u_i = r_i / s`, and accumulated into [`NormalEquations`]; the scale `s` is re-estimated
//! from the accepted residuals when [`ScaleMode::Mad`] is used. The accept/reject rule, the
//! damping and the stop reasons are those of [`crate::lm`].
//!
//! The mean cost (cost over the number of rows) is compared. A mean over rows that come and go
//! with `x` (pixels leaving the image) is not one cost function: a step can lower it by dropping
//! badly fitting rows, so such problems keep their set of rows fixed during a solve (as the
//! direct aligners do per pyramid level). The covariance returned is the
//! M-estimate's sandwich covariance at the solution ([`crate::sandwich`]; for least squares
//! White's estimator, for Huber about 20% larger than the fixed-weight `sigma^2 (J^T W J)^-1`,
//! which is too small), `None` when `H` is singular or badly conditioned.

use nalgebra::{SMatrix, SVector};
use serde::Serialize;

use crate::lm::{levenberg_marquardt, Convergence, LmConfig, LmError, LmProblem};
use crate::loss::{Loss, RobustLoss};
use crate::normal::NormalEquations;
use crate::sandwich::sandwich_covariance;
use crate::scale::mad_sigma_about_zero;

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

/// A nonlinear least-squares problem given as residual rows: residuals and Jacobians at a
/// state, and the update rule.
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
    /// The driver's settings; `min_valid` below `N` is raised to `N`.
    pub lm: LmConfig,
    /// Whether to compute [`IrlsResult::covariance`] (one more pass over the final rows);
    /// `false` for inner solves whose covariance nobody reads, which then get `None`.
    pub covariance: bool,
}

impl Default for IrlsConfig {
    /// The default loss, a MAD scale floored at 1e-9, the default [`LmConfig`] and the
    /// covariance on.
    fn default() -> Self {
        Self {
            loss: Loss::default(),
            scale: ScaleMode::Mad { min_sigma: 1e-9 },
            lm: LmConfig::default(),
            covariance: true,
        }
    }
}

/// What [`irls`] could not do: the driver's errors.
pub type IrlsError = LmError;

/// The estimate and how it was reached (`Serialize` when the state is; matrices as nalgebra
/// writes them, a flat column-major array).
#[derive(Debug, Clone, Serialize)]
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
    /// Sandwich covariance of the increment ([`crate::sandwich_covariance`]); `None` (unknown)
    /// when `H` is singular or worse conditioned than `max_condition`, or not asked for
    /// ([`IrlsConfig::covariance`]).
    pub covariance: Option<SMatrix<f64, N, N>>,
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

/// A [`Problem`] seen by the driver: its rows at the current state, weighted by `loss`.
struct RowsProblem<'a, P, const N: usize> {
    problem: &'a mut P,
    loss: Loss,
    mode: ScaleMode,
    scale: f64,
    rows: Rows<N>,
    /// The rows at the accepted state while a trial is evaluated.
    saved: Rows<N>,
}

impl<P: Problem<N>, const N: usize> LmProblem for RowsProblem<'_, P, N> {
    type State = P::State;
    type System = NormalEquations<N>;

    fn evaluate(&mut self, state: &P::State) -> usize {
        self.rows.clear();
        self.problem.evaluate(state, &mut self.rows);
        self.rows.len()
    }

    fn cost(&self) -> f64 {
        mean_cost(&self.loss, self.scale, &self.rows.residuals)
    }

    fn update_scale(&mut self) {
        self.scale = estimate_scale(self.mode, &self.rows.residuals);
    }

    fn scale(&self) -> f64 {
        self.scale
    }

    fn linearize(&mut self) -> NormalEquations<N> {
        accumulate(&self.loss, self.scale, &self.rows)
    }

    fn retract(&self, state: &P::State, step: &SVector<f64, N>) -> P::State {
        self.problem.retract(state, step)
    }

    fn step_norm(&self, step: &SVector<f64, N>) -> f64 {
        step.norm()
    }

    fn save(&mut self) {
        std::mem::swap(&mut self.rows, &mut self.saved);
    }

    fn restore(&mut self, _state: &P::State) {
        std::mem::swap(&mut self.rows, &mut self.saved);
    }
}

/// Runs iteratively reweighted Levenberg-Marquardt from `x0`; see the module documentation.
pub fn irls<P: Problem<N>, const N: usize>(
    problem: &mut P,
    x0: P::State,
    cfg: &IrlsConfig,
) -> Result<IrlsResult<P::State, N>, IrlsError> {
    let mut rows_problem = RowsProblem {
        problem,
        loss: cfg.loss,
        mode: cfg.scale,
        scale: 1.0,
        rows: Rows::default(),
        saved: Rows::default(),
    };
    let lm = LmConfig {
        min_valid: cfg.lm.min_valid.max(N),
        ..cfg.lm
    };
    let out = levenberg_marquardt(&mut rows_problem, x0, &lm)?;
    let (loss, scale) = (cfg.loss, rows_problem.scale);
    let residuals = std::mem::take(&mut rows_problem.rows.residuals);
    let weights = residuals.iter().map(|r| loss.weight(r / scale)).collect();
    let wanted = cfg.covariance.then_some(());
    let covariance = wanted
        .and_then(|_| out.system.covariance(lm.max_condition))
        .and_then(|_| {
            let rows = rows_problem
                .rows
                .jacobians
                .iter()
                .copied()
                .zip(residuals.iter().copied());
            sandwich_covariance(rows, &loss, scale, &[false; N])
        });
    Ok(IrlsResult {
        state: out.state,
        weights,
        residuals,
        costs: out.costs,
        iterations: out.iterations,
        reason: out.reason,
        scale,
        hessian: out.system.hessian(),
        covariance,
    })
}
