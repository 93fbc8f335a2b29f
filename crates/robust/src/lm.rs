//! The one Levenberg-Marquardt driver of vofront.
//!
//! Every nonlinear least-squares estimator (IRLS on residual rows, the direct aligners, the
//! geometric refiners, bundle adjustment) runs this loop. The problem, an [`LmProblem`],
//! evaluates its residuals at a state, gives their cost, accumulates `H = J^T W J` and
//! `g = J^T W r` into a [`LinearSystem`] and retracts a step; it may do any of that in
//! parallel. The linear system is pluggable: [`NormalEquations`] for small dense problems, a
//! Schur-complement system ([`crate::schur::SchurSystem`]) for bundle adjustment. Each iteration:
//!
//! 1. `delta` solves `(H + lambda D) delta = -g` ([`LinearSystem::solve`]);
//! 2. the step is *small* when `|delta| < min_step` in the problem's metric
//!    ([`LmProblem::step_norm`]) or when it is shorter than `min_step_sigmas` of its own
//!    standard deviations, `delta^T H delta / s^2 < min_step_sigmas^2` (`s` the residual scale);
//! 3. the trial state `retract(x, delta)` is evaluated; it is **accepted when its cost is not
//!    larger** (`C' <= C`, the cost at the current scale, infinite with fewer than `min_valid`
//!    residuals); then `lambda <- lambda / 10`, the scale is re-estimated
//!    ([`LmProblem::update_scale`]) and the problem linearised again;
//! 4. a rejected trial restores the previous evaluation and sets
//!    `lambda <- max(10 lambda, lambda_floor)`;
//! 5. stop reasons ([`Convergence`]): a small step (accepted or not), an accepted relative cost
//!    decrease below `min_relative_decrease`, `max_rejections` rejections in a row (no
//!    decrease even with strong damping: a local minimum at the noise floor), or
//!    `max_iterations` (accepted and rejected steps both count).

use nalgebra::SVector;
use serde::Serialize;
use thiserror::Error;

use crate::normal::NormalEquations;
use crate::solve::{solve_damped, Damping, SolveError};

/// The linearised problem `H delta = -g` at the current state.
pub trait LinearSystem {
    /// The increment type (a fixed vector, or pose and point blocks).
    type Step;
    /// Solves `(H + lambda D) delta = -g`, `D` as `damping` says; a system whose (scaled)
    /// condition exceeds `max_condition` is [`SolveError::Degenerate`].
    fn solve(
        &self,
        lambda: f64,
        damping: Damping,
        max_condition: f64,
    ) -> Result<Self::Step, SolveError>;
    /// `delta^T H delta` with the undamped `H`: the squared step length in the metric of the
    /// information (in units of `s^2`, the squared residual scale).
    fn information_norm2(&self, step: &Self::Step) -> f64;
}

impl<const N: usize> LinearSystem for NormalEquations<N> {
    type Step = SVector<f64, N>;

    fn solve(
        &self,
        lambda: f64,
        damping: Damping,
        max_condition: f64,
    ) -> Result<SVector<f64, N>, SolveError> {
        solve_damped(&self.hessian(), &self.g, lambda, damping, max_condition)
    }

    fn information_norm2(&self, step: &SVector<f64, N>) -> f64 {
        (step.transpose() * self.hessian() * step)[(0, 0)]
    }
}

/// A nonlinear least-squares problem as the driver sees it.
///
/// The problem owns its current evaluation (residuals, Jacobians, weights' scale): the driver
/// asks for an evaluation at a state, its cost, and its linearisation.
pub trait LmProblem {
    /// The estimated quantity (a vector, a pose, poses and points...).
    type State: Clone;
    /// The linear system the problem accumulates.
    type System: LinearSystem;
    /// Evaluates the residuals at `state`, which becomes the current evaluation; returns the
    /// number of valid residuals.
    fn evaluate(&mut self, state: &Self::State) -> usize;
    /// Cost of the current evaluation at the current residual scale (e.g. the mean robust
    /// cost `s^2 mean rho(r_i / s)`).
    fn cost(&self) -> f64;
    /// Re-estimates the residual scale from the current evaluation; called at the start and
    /// after every accepted step. The default keeps a fixed scale.
    fn update_scale(&mut self) {}
    /// Residual scale `s` of the step-sigmas test; 1 by default.
    fn scale(&self) -> f64 {
        1.0
    }
    /// `H = J^T W J`, `g = J^T W r` of the current evaluation at the current scale.
    fn linearize(&mut self) -> Self::System;
    /// `state` moved by the local increment `step`.
    fn retract(
        &self,
        state: &Self::State,
        step: &<Self::System as LinearSystem>::Step,
    ) -> Self::State;
    /// Length of `step` in the problem's metric, compared with [`LmConfig::min_step`].
    fn step_norm(&self, step: &<Self::System as LinearSystem>::Step) -> f64;
    /// Called before a trial evaluation: a problem with a second set of buffers saves the
    /// current evaluation here.
    fn save(&mut self) {}
    /// Called after a rejected trial: brings back the evaluation at `state` (the one before
    /// the trial), by default by evaluating again.
    fn restore(&mut self, state: &Self::State) {
        self.evaluate(state);
    }
}

/// Settings of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmConfig {
    /// Upper bound on iterations (accepted and rejected steps both count).
    pub max_iterations: usize,
    /// A step with [`LmProblem::step_norm`] below this is small.
    pub min_step: f64,
    /// A step shorter than this many of its own standard deviations
    /// (`delta^T H delta / s^2 < min_step_sigmas^2`) is small; 0 disables the test.
    pub min_step_sigmas: f64,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub min_relative_decrease: f64,
    /// Starting `lambda`; 0 starts as Gauss-Newton.
    pub initial_lambda: f64,
    /// A rejected step raises `lambda` to at least this.
    pub lambda_floor: f64,
    /// This many rejected steps in a row end the run ([`Convergence::NoDecrease`]).
    pub max_rejections: usize,
    /// Form of the damping matrix `D`.
    pub damping: Damping,
    /// Largest acceptable scaled condition number of `H`.
    pub max_condition: f64,
    /// Fewest valid residuals for a state to be usable.
    pub min_valid: usize,
}

impl Default for LmConfig {
    /// 50 iterations, `min_step` 1e-10, no step-sigmas test, `min_relative_decrease` 1e-10,
    /// `lambda` from 1e-4 (floor 1e-4), 10 rejections in a row, Marquardt damping
    /// `D = diag(H)`, condition limit 1e10, at least one valid residual.
    fn default() -> Self {
        Self {
            max_iterations: 50,
            min_step: 1e-10,
            min_step_sigmas: 0.0,
            min_relative_decrease: 1e-10,
            initial_lambda: 1e-4,
            lambda_floor: 1e-4,
            max_rejections: 10,
            damping: Damping::Diagonal,
            max_condition: 1e10,
            min_valid: 1,
        }
    }
}

/// Why [`levenberg_marquardt`] stopped; the JSON spelling is the snake_case name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Convergence {
    /// The step was small (see [`LmConfig::min_step`], [`LmConfig::min_step_sigmas`]).
    SmallStep,
    /// The relative cost decrease fell below `min_relative_decrease`.
    SmallCostChange,
    /// `max_iterations` was reached.
    MaxIterations,
    /// `max_rejections` steps in a row did not lower the cost: a (local) minimum.
    NoDecrease,
}

/// What [`levenberg_marquardt`] could not do.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum LmError {
    /// The starting state has fewer valid residuals than [`LmConfig::min_valid`].
    #[error("{rows} valid residuals, at least {required} needed")]
    TooFewResiduals {
        /// Valid residuals at the starting state.
        rows: usize,
        /// The minimum required.
        required: usize,
    },
    /// The step could not be computed (degenerate or non-finite normal equations).
    #[error(transparent)]
    Solve(#[from] SolveError),
}

/// The estimate and how it was reached.
#[derive(Debug, Clone)]
pub struct LmOutcome<S, Y> {
    /// The final state.
    pub state: S,
    /// The linear system at the final state.
    pub system: Y,
    /// Cost at the start and after each accepted step (the last one is the final cost).
    pub costs: Vec<f64>,
    /// Iterations run (accepted and rejected steps).
    pub iterations: usize,
    /// Why it stopped.
    pub reason: Convergence,
    /// Valid residuals at the final state.
    pub valid: usize,
}

impl<S, Y> LmOutcome<S, Y> {
    /// The final cost.
    pub fn cost(&self) -> f64 {
        self.costs.last().copied().unwrap_or(f64::INFINITY)
    }
}

/// Runs Levenberg-Marquardt on `problem` from `x0`; see the module documentation.
///
/// ```
/// use nalgebra::{SVector, Vector2};
/// use vofront_robust::{levenberg_marquardt, Convergence, LmConfig, LmProblem, NormalEquations};
///
/// /// Exponential decay `y = a exp(-b x)` through samples: state `(a, b)`, one residual
/// /// `r_i = a exp(-b x_i) - y_i` per sample.
/// struct Decay {
///     samples: Vec<(f64, f64)>,
///     at: Vector2<f64>,
/// }
/// impl LmProblem for Decay {
///     type State = Vector2<f64>;
///     type System = NormalEquations<2>;
///     fn evaluate(&mut self, state: &Vector2<f64>) -> usize {
///         self.at = *state;
///         self.samples.len()
///     }
///     fn cost(&self) -> f64 {
///         let r = |&(x, y): &(f64, f64)| self.at[0] * (-self.at[1] * x).exp() - y;
///         self.samples.iter().map(|s| r(s).powi(2)).sum::<f64>() / 2.0
///     }
///     fn linearize(&mut self) -> NormalEquations<2> {
///         let mut system = NormalEquations::new();
///         for &(x, y) in &self.samples {
///             let e = (-self.at[1] * x).exp();
///             let jacobian = SVector::from([e, -self.at[0] * x * e]);
///             system.add(&jacobian, self.at[0] * e - y, 1.0);
///         }
///         system
///     }
///     fn retract(&self, state: &Vector2<f64>, step: &SVector<f64, 2>) -> Vector2<f64> {
///         state + step
///     }
///     fn step_norm(&self, step: &SVector<f64, 2>) -> f64 {
///         step.norm()
///     }
/// }
///
/// let samples = (0..20).map(|i| (0.2 * i as f64, 3.0 * (-0.14 * i as f64).exp())).collect();
/// let mut problem = Decay { samples, at: Vector2::zeros() };
/// let fit = levenberg_marquardt(&mut problem, Vector2::new(1.0, 0.1), &LmConfig::default()).unwrap();
/// assert!((fit.state - Vector2::new(3.0, 0.7)).norm() < 1e-6, "{}", fit.state);
/// assert!(fit.cost() < 1e-12 && fit.reason != Convergence::MaxIterations);
/// ```
pub fn levenberg_marquardt<P: LmProblem>(
    problem: &mut P,
    x0: P::State,
    cfg: &LmConfig,
) -> Result<LmOutcome<P::State, P::System>, LmError> {
    let mut state = x0;
    let mut valid = problem.evaluate(&state);
    if valid < cfg.min_valid {
        return Err(LmError::TooFewResiduals {
            rows: valid,
            required: cfg.min_valid,
        });
    }
    problem.update_scale();
    let mut cost = problem.cost();
    let mut system = problem.linearize();
    let mut costs = vec![cost];
    let mut lambda = cfg.initial_lambda;
    let mut rejections = 0;
    let mut reason = Convergence::MaxIterations;
    let mut iterations = 0;
    while iterations < cfg.max_iterations {
        iterations += 1;
        let step = system.solve(lambda, cfg.damping, cfg.max_condition)?;
        let small = problem.step_norm(&step) < cfg.min_step
            || (cfg.min_step_sigmas > 0.0 && {
                let s = problem.scale();
                system.information_norm2(&step) / (s * s) < cfg.min_step_sigmas.powi(2)
            });
        let candidate = problem.retract(&state, &step);
        problem.save();
        let trial_valid = problem.evaluate(&candidate);
        let trial_cost = if trial_valid >= cfg.min_valid {
            problem.cost()
        } else {
            f64::INFINITY
        };
        if trial_cost <= cost {
            let relative = (cost - trial_cost) / cost.max(f64::MIN_POSITIVE);
            state = candidate;
            valid = trial_valid;
            rejections = 0;
            lambda *= 0.1;
            problem.update_scale();
            cost = problem.cost();
            system = problem.linearize();
            costs.push(cost);
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
            lambda = (lambda * 10.0).max(cfg.lambda_floor);
            rejections += 1;
            if rejections >= cfg.max_rejections {
                reason = Convergence::NoDecrease;
                break;
            }
        }
    }
    Ok(LmOutcome {
        state,
        system,
        costs,
        iterations,
        reason,
        valid,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    /// Rosenbrock's valley as least squares: `r = (10 (y - x^2), 1 - x)`, minimum at `(1, 1)`.
    /// With `wrong_sign` the Jacobian is negated, so that every step climbs.
    struct Rosenbrock {
        wrong_sign: bool,
        residuals: Vector2<f64>,
        at: Vector2<f64>,
    }

    impl LmProblem for Rosenbrock {
        type State = Vector2<f64>;
        type System = NormalEquations<2>;

        fn evaluate(&mut self, p: &Vector2<f64>) -> usize {
            self.at = *p;
            self.residuals = Vector2::new(10.0 * (p.y - p.x * p.x), 1.0 - p.x);
            2
        }

        fn cost(&self) -> f64 {
            0.5 * self.residuals.norm_squared()
        }

        fn linearize(&mut self) -> NormalEquations<2> {
            let sign = if self.wrong_sign { -1.0 } else { 1.0 };
            let mut ne = NormalEquations::new();
            let x = self.at.x;
            ne.add(
                &(sign * SVector::from([-20.0 * x, 10.0])),
                self.residuals.x,
                1.0,
            );
            ne.add(&(sign * SVector::from([-1.0, 0.0])), self.residuals.y, 1.0);
            ne
        }

        fn retract(&self, p: &Vector2<f64>, d: &SVector<f64, 2>) -> Vector2<f64> {
            p + d
        }

        fn step_norm(&self, d: &SVector<f64, 2>) -> f64 {
            d.norm()
        }
    }

    fn rosenbrock(wrong_sign: bool) -> Rosenbrock {
        Rosenbrock {
            wrong_sign,
            residuals: Vector2::zeros(),
            at: Vector2::zeros(),
        }
    }

    #[test]
    fn rosenbrock_valley_is_followed_to_its_minimum_with_monotone_costs() {
        let start = Vector2::new(-1.2, 1.0);
        let out = levenberg_marquardt(&mut rosenbrock(false), start, &LmConfig::default())
            .expect("a well-posed problem");
        assert!(
            (out.state - Vector2::new(1.0, 1.0)).norm() < 1e-6,
            "{}",
            out.state
        );
        assert!(
            out.costs.windows(2).all(|c| c[1] <= c[0]),
            "{:?}",
            out.costs
        );
        assert_ne!(out.reason, Convergence::MaxIterations);
    }

    #[test]
    fn uphill_steps_are_all_rejected_and_the_start_is_kept() {
        let start = Vector2::new(-1.2, 1.0);
        let cfg = LmConfig {
            max_rejections: 5,
            ..LmConfig::default()
        };
        let out = levenberg_marquardt(&mut rosenbrock(true), start, &cfg).expect("solvable");
        assert_eq!(out.reason, Convergence::NoDecrease);
        assert_eq!(out.iterations, 5);
        assert_eq!(out.state, start);
        assert_eq!(out.costs.len(), 1);
    }

    #[test]
    fn too_few_residuals_at_the_start_is_an_error() {
        let cfg = LmConfig {
            min_valid: 3,
            ..LmConfig::default()
        };
        let err = levenberg_marquardt(&mut rosenbrock(false), Vector2::zeros(), &cfg).unwrap_err();
        assert_eq!(
            err,
            LmError::TooFewResiduals {
                rows: 2,
                required: 3
            }
        );
    }
}
