//! Robust least-squares core shared by every vofront estimator.
//!
//! Estimators elsewhere in vofront only say "here are my residuals `r_i` and Jacobians
//! `J_i = dr_i/dx`"; this crate does the rest:
//!
//! - [`loss`]: robust losses `rho(r)` with influence `psi = rho'` and IRLS weight
//!   `w = psi(r) / r` (Huber, Cauchy, Tukey, Student-t, plain squares);
//! - [`scale`]: robust scale (median absolute deviation scaled to a Gaussian sigma), so a loss
//!   threshold can be given in sigmas;
//! - [`normal`]: accumulation of the normal equations `H = J^T W J`, `g = J^T W r` for a fixed
//!   parameter count, mergeable so that rayon can reduce partial sums;
//! - [`solve`]: the damped step `(H + lambda D) d = -g` with degeneracy detection;
//! - [`lm`]: the one Levenberg-Marquardt driver, generic over the problem and its linear
//!   system ([`NormalEquations`] or a [`SchurSystem`]), with one accept/reject rule, one
//!   damping update and one set of stop reasons;
//! - [`schur`]: the block normal equations of a bundle adjustment (pose blocks of `P`
//!   parameters, point blocks of `Q`) and their Schur-complement solve;
//! - [`quality`]: the quality record (verdict, reasons, support, covariance) of every estimate;
//! - [`secant`]: a Gauss-Newton covariance widened where the cost is flatter than its
//!   quadratic model;
//! - [`irls`](mod@irls): iteratively reweighted least squares on residual rows through that driver,
//!   with a covariance output (`None` when unknown).
//!
//! ```
//! use nalgebra::{SVector, Vector2};
//! use vofront_robust::{irls, IrlsConfig, Loss, Problem, Rows};
//!
//! /// Fit y = m x + c to points, one residual per point: r_i = m x_i + c - y_i.
//! struct Line(Vec<(f64, f64)>);
//! impl Problem<2> for Line {
//!     type State = Vector2<f64>;
//!     fn evaluate(&mut self, p: &Vector2<f64>, rows: &mut Rows<2>) {
//!         for &(x, y) in &self.0 {
//!             rows.push(SVector::from([x, 1.0]), p[0] * x + p[1] - y);
//!         }
//!     }
//!     fn retract(&self, p: &Vector2<f64>, d: &SVector<f64, 2>) -> Vector2<f64> {
//!         p + d
//!     }
//! }
//! let mut pts: Vec<(f64, f64)> = (0..20).map(|i| (i as f64, 2.0 * i as f64 + 1.0)).collect();
//! pts[3].1 = 500.0; // a gross outlier
//! let cfg = IrlsConfig { loss: Loss::Huber(1.345), ..IrlsConfig::default() };
//! let fit = irls(&mut Line(pts), Vector2::zeros(), &cfg).unwrap();
//! assert!((fit.state[0] - 2.0).abs() < 1e-3 && (fit.state[1] - 1.0).abs() < 1e-2);
//! ```
#![warn(missing_docs)]

pub mod irls;
pub mod lm;
pub mod loss;
pub mod normal;
pub mod quality;
pub mod sandwich;
pub mod scale;
pub mod schur;
pub mod secant;
pub mod solve;

pub use irls::{irls, IrlsConfig, IrlsError, IrlsResult, Problem, Rows, ScaleMode};
pub use lm::{
    levenberg_marquardt, Convergence, LinearSystem, LmConfig, LmError, LmOutcome, LmProblem,
};
pub use loss::{Cauchy, Huber, Loss, RobustLoss, Squared, StudentT, Tukey};
pub use normal::NormalEquations;
pub use quality::{Quality, QualityConfig, Reason, Support, Uncertainty, Verdict};
pub use sandwich::{at_least, clustered_sandwich_covariance, sandwich_covariance};
pub use scale::{mad_sigma, mad_sigma_about_zero, median_in_place};
pub use schur::{Coupling, PointBlock, PosePair, SchurStep, SchurSystem};
pub use secant::secant_covariance;
pub use solve::{scaled_condition, solve_damped, Damping, SolveError};
