//! Windowed bundle adjustment: keyframe poses and world points refined together on robust
//! pixel reprojection errors, through the robust crate's Levenberg-Marquardt driver.
//!
//! Unknowns: poses `T_i = T_cw` of the keyframes (left increments
//! `T_i <- exp(delta_i) T_i`, [`crate::lie::retract_left`]) and world points `P_j` (additive).
//! Residual of observation `o` (keyframe `i`, point `j`, observed pixel `u_o`):
//! `r_o = (pi(T_i P_j) - u_o) / s_o` in pixels through the full [`Camera`] model, with `s_o`
//! the observation's relative noise scale ([`Observation::sigma`]: 1 at the finest keypoint
//! level, `1.2^k` for an ORB keypoint of level `k`), so that the loss, the gate and the report
//! are in pixels of a scale-1 observation.
//!
//! **Stereo observations.** An observation of a rectified stereo rig also carries the column
//! `u_r` at which the right camera saw the point ([`Observation::right`]); its residual gains
//! a third row, ORB-SLAM2's stereo residual `(u_l, v_l, u_r)`:
//! `r_o,3 = (pi(T_i P_j - b e_x)_x - u_r) / s_o` with `b` the rig's baseline
//! ([`BundleProblem::baseline`], metres, the right camera at `x = +b` in the left one's frame):
//! for a pinhole `u_r = u_l - f b / Z`, so the third row pins the depth. A monocular
//! observation has the first two rows only. Cost
//! `sum_o s^2 rho(|r_o| / s)` with `rho` a robust loss of `vofront_robust` and `s` its scale in
//! pixels ([`BundleConfig::sigma_px`]). Each step eliminates the points (Schur complement on
//! their 3x3 blocks, [`vofront_robust::schur`] with 6-dof pose and 3-dof point blocks) and
//! solves the dense reduced camera system by Cholesky; the normal equations are accumulated in
//! parallel (module `problem`).
//!
//! **Gauge.** The oldest [`BundleConfig::fixed_poses`] keyframes (the first entries of
//! [`BundleProblem::poses`]) are held. One fixed keyframe removes the six rigid degrees of
//! freedom, which is enough when the scale is observable (stereo, RGB-D points). A monocular
//! window also has a free scale: hold **two** keyframes (the default), whose baseline then
//! fixes the scale; with one, the scale direction is only held by the damping and drifts.
//!
//! **Culling.** After convergence the residual scale is estimated over every observation in
//! front of its camera, culled ones included (so that the gate does not truncate its own
//! sample), from residuals standardised by the share `1 - h_o` of the noise the solve left
//! in them (one minus the leverage: a point seen twice absorbs three quarters of its four
//! coordinates' noise): `sigma = max(min_sigma_px, 1.4826 median |r_o,c|)` over every
//! coordinate `c` (two per monocular observation, three per stereo one) of the standardised
//! `r_o / sqrt(1 - h_o)`. Observations with
//! `|r_o|^2 > gate_chi2 (1 - h_o) sigma^2` (5.99: the 95% quantile of chi-square with two
//! degrees of freedom; [`BundleConfig::gate_chi2_stereo`], 7.81, for three) are culled, whether or not they took part in the solve; the window is
//! solved again without them, up to [`BundleConfig::max_rounds`] solves. Observations behind
//! a camera are culled too. Points left with fewer than two usable observations are not moved.
//!
//! ```
//! use nalgebra::{Isometry3, Point3, Vector2, Vector3};
//! use vofront_geometry::bundle::{bundle_adjust, BundleConfig, BundleProblem, Observation};
//! use vofront_geometry::{Camera, Pinhole};
//! let camera = Camera::pinhole(Pinhole::new(500.0, 500.0, 320.0, 240.0).unwrap());
//! let poses: Vec<Isometry3<f64>> = (0..3)
//!     .map(|k| Isometry3::translation(-0.2 * k as f64, 0.0, 0.0))
//!     .collect();
//! let points: Vec<Point3<f64>> = (0..40)
//!     .map(|j| {
//!         let f = j as f64;
//!         Point3::new((f * 0.7).sin() * 2.0, (f * 1.3).cos(), 5.0 + (f * 0.37).sin())
//!     })
//!     .collect();
//! let mut observations = Vec::new();
//! for (i, pose) in poses.iter().enumerate() {
//!     for (j, p) in points.iter().enumerate() {
//!         let pixel = camera.project(&(pose * p).coords).unwrap();
//!         observations.push(Observation { pose: i, point: j, pixel, sigma: 1.0, right: None });
//!     }
//! }
//! let truth = poses[2];
//! let mut problem = BundleProblem { camera, poses, points, observations, baseline: None };
//! problem.poses[2] = Isometry3::new(Vector3::new(-0.43, 0.02, 0.01), Vector3::new(0.0, 0.01, 0.0));
//! let report = bundle_adjust(&mut problem, &BundleConfig::default()).unwrap();
//! assert!((problem.poses[2].translation.vector - truth.translation.vector).norm() < 1e-6);
//! assert!(report.final_cost < report.initial_cost);
//! ```

mod problem;

use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use rayon::prelude::*;
use vofront_robust::{
    levenberg_marquardt, mad_sigma_about_zero, Convergence, Damping, LmConfig, LmError, Loss,
};

use crate::camera::Camera;
use crate::error::GeometryError;
use problem::{BundleState, Linearized, Reprojection};

/// The increment of a bundle: `poses` holds the `(rho, phi)` left increments of the free
/// poses (oldest free pose first), `points` the world-frame point increments (metres).
pub type BundleStep = vofront_robust::SchurStep<6, 3>;

/// The normal equations of a bundle at one state in block form: 6x6 pose blocks, 3x3 point
/// blocks ([`vofront_robust::SchurSystem`]).
pub type SchurSystem = vofront_robust::SchurSystem<6, 3>;

/// One observation: keyframe `pose` saw world point `point` at the (distorted) `pixel`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Index into [`BundleProblem::poses`].
    pub pose: usize,
    /// Index into [`BundleProblem::points`].
    pub point: usize,
    /// Observed pixel, `(0, 0)` the centre of the top-left pixel.
    pub pixel: Vector2<f64>,
    /// Relative noise scale of `pixel` (finite, positive; 1 for a keypoint of the finest
    /// pyramid level): its residual is divided by it.
    pub sigma: f64,
    /// Column at which the right camera of a rectified stereo rig saw the point, pixels
    /// (`None` for a monocular observation); needs [`BundleProblem::baseline`].
    pub right: Option<f64>,
}

impl Observation {
    /// Residual coordinates: 2 for a monocular observation, 3 for a stereo one.
    pub fn dims(&self) -> usize {
        if self.right.is_some() {
            3
        } else {
            2
        }
    }
}

/// A window of keyframes and the points they observe; [`bundle_adjust`] refines `poses` and
/// `points` in place.
#[derive(Debug, Clone, PartialEq)]
pub struct BundleProblem {
    /// The camera of every keyframe.
    pub camera: Camera,
    /// `T_cw` of each keyframe (world points into the camera frame), oldest first.
    pub poses: Vec<Isometry3<f64>>,
    /// World points, metres.
    pub points: Vec<Point3<f64>>,
    /// The observations.
    pub observations: Vec<Observation>,
    /// Baseline of the rectified stereo rig, metres: the right camera sits at `x = +b` in the
    /// left camera's frame, with the same camera model (`None`: no stereo observations).
    pub baseline: Option<f64>,
}

/// Settings of [`bundle_adjust`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BundleConfig {
    /// Robust loss on `|r| / sigma_px`.
    pub loss: Loss,
    /// Scale of the loss, pixels (the expected reprojection noise per coordinate).
    pub sigma_px: f64,
    /// The oldest this many keyframes are held (the gauge, see the module documentation): 2
    /// for monocular windows, at least 1.
    pub fixed_poses: usize,
    /// Iteration limit of each solve.
    pub max_iterations: usize,
    /// A solve stops when an accepted step lowers the cost by less than this fraction.
    pub min_relative_decrease: f64,
    /// A solve stops when the whole step (metres and radians) is shorter than this.
    pub min_step: f64,
    /// Observations with `|r|^2 > gate_chi2 (1 - h) sigma^2` (`h` the observation's
    /// leverage, see the module documentation) are culled after convergence (monocular
    /// observations: two coordinates).
    pub gate_chi2: f64,
    /// The same gate for stereo observations (three coordinates).
    pub gate_chi2_stereo: f64,
    /// Floor of the estimated residual scale, pixels.
    pub min_sigma_px: f64,
    /// At most this many (solve, cull) rounds.
    pub max_rounds: usize,
}

impl Default for BundleConfig {
    /// Huber at 1.345 of a 1-pixel scale, two fixed keyframes, 50 iterations, relative
    /// decrease 1e-8, step 1e-10, chi-square gate 5.99 (7.81 for a stereo observation: the 95%
    /// quantiles of two and three degrees of freedom) at an estimated sigma floored at 0.05
    /// pixel, three rounds.
    fn default() -> Self {
        Self {
            loss: Loss::Huber(1.345),
            sigma_px: 1.0,
            fixed_poses: 2,
            max_iterations: 50,
            min_relative_decrease: 1e-8,
            min_step: 1e-10,
            gate_chi2: 5.99,
            gate_chi2_stereo: 7.815,
            min_sigma_px: 0.05,
            max_rounds: 3,
        }
    }
}

/// What [`bundle_adjust`] did.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BundleReport {
    /// Iterations over all rounds (accepted and rejected steps).
    pub iterations: usize,
    /// Solves run (rounds).
    pub rounds: usize,
    /// Robust cost `sum s^2 rho(|r| / s)` at the start of the first solve, pixels^2.
    pub initial_cost: f64,
    /// Robust cost at the end of the last solve (over the observations it used), pixels^2.
    pub final_cost: f64,
    /// Indices into [`BundleProblem::observations`] of the culled observations (beyond the
    /// gate, or behind a camera), ascending. Those culled after the last round took part in
    /// the final solve.
    pub culled: Vec<usize>,
    /// Estimated noise scale at the end (from the leverage-standardised residuals), pixels
    /// per coordinate.
    pub sigma_px: f64,
    /// Root mean square of `|r|` over the observations of the last solve, pixels.
    pub rmse_px: f64,
    /// Why the last solve stopped.
    pub reason: Convergence,
}

/// Checks indices, finiteness and the configuration.
fn validate(problem: &BundleProblem, cfg: &BundleConfig) -> Result<(), GeometryError> {
    problem.camera.validate()?;
    if cfg.fixed_poses == 0 || cfg.fixed_poses > problem.poses.len() {
        return Err(GeometryError::InvalidConfig(
            "fixed_poses must be in 1..=keyframes (the gauge needs a fixed keyframe)",
        ));
    }
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(positive(cfg.sigma_px)
        && positive(cfg.gate_chi2)
        && positive(cfg.gate_chi2_stereo)
        && positive(cfg.min_sigma_px))
        || cfg.max_rounds == 0
        || cfg.max_iterations == 0
    {
        return Err(GeometryError::InvalidConfig(
            "sigma_px, the gates, min_sigma_px, max_rounds and max_iterations must be positive",
        ));
    }
    let stereo = problem.observations.iter().any(|o| o.right.is_some());
    if stereo && !problem.baseline.is_some_and(positive) {
        return Err(GeometryError::InvalidConfig(
            "stereo observations need a finite, positive baseline",
        ));
    }
    let (n_poses, n_points) = (problem.poses.len(), problem.points.len());
    if problem
        .observations
        .iter()
        .any(|o| o.pose >= n_poses || o.point >= n_points)
    {
        return Err(GeometryError::InvalidConfig(
            "an observation's point or keyframe index is out of range",
        ));
    }
    if problem.observations.iter().any(|o| o.sigma <= 0.0) {
        return Err(GeometryError::InvalidConfig(
            "an observation's noise scale must be positive",
        ));
    }
    let finite_poses = problem
        .poses
        .iter()
        .all(|t| t.to_homogeneous().iter().all(|v| v.is_finite()));
    let finite_points = problem
        .points
        .iter()
        .all(|p| p.iter().all(|v| v.is_finite()));
    let finite_pixels = problem.observations.iter().all(|o| {
        o.pixel.iter().all(|v| v.is_finite())
            && o.sigma.is_finite()
            && o.right.is_none_or(f64::is_finite)
    });
    if finite_poses && finite_points && finite_pixels {
        Ok(())
    } else {
        Err(GeometryError::NonFinite)
    }
}

/// The observations a round uses: not culled, in front of their camera, of points seen at
/// least twice that way. The others in front of nobody are added to `culled`.
fn active_set(problem: &BundleProblem, culled: &mut [bool]) -> Vec<usize> {
    let mut usable: Vec<bool> = problem
        .observations
        .iter()
        .zip(culled.iter_mut())
        .map(|(o, culled)| {
            let z = (problem.poses[o.pose] * problem.points[o.point]).z;
            if z <= 1e-9 {
                *culled = true;
            }
            !*culled
        })
        .collect();
    let mut seen = vec![0usize; problem.points.len()];
    for (o, _) in problem
        .observations
        .iter()
        .zip(&usable)
        .filter(|(_, u)| **u)
    {
        seen[o.point] += 1;
    }
    for (o, u) in problem.observations.iter().zip(usable.iter_mut()) {
        *u &= seen[o.point] >= 2;
    }
    (0..usable.len()).filter(|&k| usable[k]).collect()
}

/// Refines the poses (all but the `fixed_poses` oldest) and points of `problem` in place; see
/// the module documentation.
///
/// Errors: [`GeometryError::InvalidConfig`] for a bad configuration or an observation index
/// out of range, [`GeometryError::NonFinite`] for NaN inputs,
/// [`GeometryError::TooFewCorrespondences`] when no point has two usable observations,
/// [`GeometryError::Degenerate`] when a free keyframe has fewer than three usable
/// observations or the reduced camera system is not positive definite.
pub fn bundle_adjust(
    problem: &mut BundleProblem,
    cfg: &BundleConfig,
) -> Result<BundleReport, GeometryError> {
    validate(problem, cfg)?;
    let mut culled = vec![false; problem.observations.len()];
    let mut report = BundleReport {
        iterations: 0,
        rounds: 0,
        initial_cost: f64::NAN,
        final_cost: f64::NAN,
        culled: Vec::new(),
        sigma_px: cfg.sigma_px,
        rmse_px: f64::NAN,
        reason: Convergence::MaxIterations,
    };
    while report.rounds < cfg.max_rounds {
        let active = active_set(problem, &mut culled);
        let rows = solve_round(problem, cfg, &active, &mut report)?;
        let sum_sq: f64 = rows.iter().map(|r| r.residual.norm_squared()).sum();
        report.rmse_px = (sum_sq / rows.len().max(1) as f64).sqrt();
        // Scale over every observation in front of its camera (culled ones included, so that
        // gating does not truncate the sample it is estimated from), then the gate.
        // Each residual is standardised by the share of the noise the solve left in it.
        let residuals = reprojection_errors(problem);
        let shares = residual_shares(problem, cfg.fixed_poses, &active);
        let coordinates: Vec<f64> = residuals
            .iter()
            .zip(&shares)
            .filter_map(|(r, share)| r.map(|r| r / share.sqrt()))
            .zip(&problem.observations)
            .flat_map(|(r, o)| r.iter().take(o.dims()).copied().collect::<Vec<_>>())
            .collect();
        let sigma = mad_sigma_about_zero(&coordinates)
            .unwrap_or(cfg.min_sigma_px)
            .max(cfg.min_sigma_px);
        report.sigma_px = sigma;
        let limit = |o: &Observation| {
            let chi2 = if o.right.is_some() {
                cfg.gate_chi2_stereo
            } else {
                cfg.gate_chi2
            };
            chi2 * sigma * sigma
        };
        // Every observation is gated (those of points too weakly observed to be moved
        // included); only culls among the solved ones call for another solve.
        let was_active = {
            let mut flags = vec![false; culled.len()];
            active.iter().for_each(|&o| flags[o] = true);
            flags
        };
        let mut new_culls = 0;
        for (o, r) in residuals.iter().enumerate() {
            let limit = limit(&problem.observations[o]);
            if !culled[o] && !r.is_some_and(|r| r.norm_squared() <= limit * shares[o]) {
                culled[o] = true;
                new_culls += usize::from(was_active[o]);
            }
        }
        if new_culls == 0 {
            break;
        }
    }
    report.culled = (0..culled.len()).filter(|&k| culled[k]).collect();
    Ok(report)
}

/// Smallest share of the noise variance an observation's residual is credited with, so that
/// a nearly fully fitted residual is not blown up by its standardisation.
const MIN_RESIDUAL_SHARE: f64 = 0.1;

/// `1 - h_o` for every observation: the share of the per-coordinate noise variance left in
/// its residual after a solve on `active` (one minus its leverage `h_o`). An active
/// observation of a point whose active observations have `m` residual coordinates in all
/// gives `3 / m` of its variance to the point's three coordinates, and `6 / n` to its
/// keyframe's pose when that keyframe (not among the `fixed` oldest) has `n` active residual
/// coordinates; an observation the solve did not use keeps all of it. A point seen twice thus keeps a quarter: its residuals are half
/// the noise, and a scale read from them unscaled would gate out good observations.
fn residual_shares(problem: &BundleProblem, fixed: usize, active: &[usize]) -> Vec<f64> {
    let mut per_point = vec![0usize; problem.points.len()];
    let mut per_pose = vec![0usize; problem.poses.len()];
    for &o in active {
        let obs = &problem.observations[o];
        per_point[obs.point] += obs.dims();
        per_pose[obs.pose] += obs.dims();
    }
    let mut shares = vec![1.0; problem.observations.len()];
    for &o in active {
        let obs = &problem.observations[o];
        let mut leverage = 3.0 / per_point[obs.point] as f64;
        if obs.pose >= fixed {
            leverage += 6.0 / per_pose[obs.pose] as f64;
        }
        shares[o] = (1.0 - leverage).max(MIN_RESIDUAL_SHARE);
    }
    shares
}

/// `r_o` of every observation (third coordinate 0 for a monocular one), `None` behind the
/// camera.
fn reprojection_errors(problem: &BundleProblem) -> Vec<Option<Vector3<f64>>> {
    let baseline = problem.baseline.unwrap_or(0.0);
    problem
        .observations
        .par_iter()
        .map(|o| {
            let x = (problem.poses[o.pose] * problem.points[o.point]).coords;
            let u = problem.camera.project(&x)? - o.pixel;
            let right = match o.right {
                Some(ur) => {
                    let xr = x - Vector3::new(baseline, 0.0, 0.0);
                    problem.camera.project(&xr)?.x - ur
                }
                None => 0.0,
            };
            Some(Vector3::new(u.x, u.y, right) / o.sigma)
        })
        .collect()
}

/// One solve over the observations `active`; writes the state back into `problem`, updates
/// the counters of `report` and returns the final residual rows.
fn solve_round(
    problem: &mut BundleProblem,
    cfg: &BundleConfig,
    active: &[usize],
    report: &mut BundleReport,
) -> Result<Vec<Linearized>, GeometryError> {
    if active.is_empty() {
        return Err(GeometryError::TooFewCorrespondences { got: 0, need: 2 });
    }
    let fixed = cfg.fixed_poses;
    let mut by_point = vec![Vec::new(); problem.points.len()];
    let mut by_pose = vec![Vec::new(); problem.poses.len() - fixed];
    for (k, &o) in active.iter().enumerate() {
        let obs = &problem.observations[o];
        by_point[obs.point].push(k);
        if let Some(i) = obs.pose.checked_sub(fixed) {
            by_pose[i].push(k);
        }
    }
    if let Some(i) = by_pose.iter().position(|list| list.len() < 3) {
        return Err(GeometryError::Degenerate(format!(
            "keyframe {} has {} usable observations, at least 3 needed",
            i + fixed,
            by_pose[i].len()
        )));
    }
    let mut reprojection = Reprojection {
        camera: &problem.camera,
        baseline: problem.baseline.unwrap_or(0.0),
        observations: &problem.observations,
        active,
        by_point: &by_point,
        by_pose: &by_pose,
        fixed,
        loss: cfg.loss,
        scale: cfg.sigma_px,
        rows: Vec::new(),
        saved: Vec::new(),
    };
    let lm = LmConfig {
        max_iterations: cfg.max_iterations,
        min_step: cfg.min_step,
        min_relative_decrease: cfg.min_relative_decrease,
        damping: Damping::Diagonal,
        // Every active observation must stay in front of its camera.
        min_valid: active.len(),
        ..LmConfig::default()
    };
    let start = BundleState {
        poses: problem.poses.clone(),
        points: problem.points.clone(),
    };
    let out = levenberg_marquardt(&mut reprojection, start, &lm).map_err(|e| match e {
        LmError::TooFewResiduals { rows, required } => GeometryError::TooFewCorrespondences {
            got: rows,
            need: required,
        },
        LmError::Solve(e) => GeometryError::Degenerate(format!("bundle adjustment: {e}")),
    })?;
    if report.rounds == 0 {
        report.initial_cost = out.costs[0];
    }
    report.rounds += 1;
    report.iterations += out.iterations;
    report.final_cost = out.cost();
    report.reason = out.reason;
    let rows = std::mem::take(&mut reprojection.rows);
    problem.poses = out.state.poses;
    problem.points = out.state.points;
    Ok(rows)
}
