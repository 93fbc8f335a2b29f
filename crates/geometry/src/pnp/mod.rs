//! Absolute pose from 3D-2D correspondences: P3P inside LO-MSAC, then motion-only refinement.
//!
//! The refinement minimises `sum_i rho(|u_i - pi(T P_i)| / s_i)` over `T = T_cw` with
//! `pi(X) = K D(X_xy / X_z)` (the full camera model, distortion included), a Huber loss and
//! the left perturbation `T <- exp(delta) T`, `delta = (rho, phi)`, through
//! [`vofront_robust::irls()`]. Its `sigma^2 H^-1` covariance of `delta` (metres, radians) is
//! returned as a quality score (`None` when unknown: not refined, or the refinement failed),
//! with the full [`Quality`] record ([`pnp_quality`]): support, the a-contrario chance test on
//! re-paired correspondences, the residual scale and the sigmas in metres and degrees.
//!
//! `s_i` is the relative noise scale of measurement `i` ([`solve_pnp_ransac_with_sigmas`]; 1
//! for every one in [`solve_pnp_ransac`]): an ORB keypoint found at pyramid level `k` is
//! located to about `1.2^k` pixels, so its residual is divided by that before the loss, the
//! inlier threshold and the chance test apply. The covariance is then of the whitened
//! residuals, in units where `s_i = 1` has the noise `sigma_px`.
//!
//! Points with a covariance of their own (a stereo point's depth noise along its ray,
//! [`solve_pnp_ransac_with_point_covariances`]) widen their residual's noise to the 2x2
//! `s_i^2 I + G_i C_i G_i^T / sigma_px^2` (`pnp/point_noise.rs`): a far point then constrains the
//! pose across the direction its depth error moves its image, and hardly along it.

mod point_noise;
mod quality;

pub use point_noise::add_point_covariances;
use point_noise::{point_whitening, whitened_error};
use quality::pnp_uncertainty;
pub use quality::{pnp_quality, PnpEvidence};

use nalgebra::{
    Isometry3, Matrix2, Matrix2x3, Matrix3, Matrix6, Point3, SVector, Vector2, Vector3,
};
use vofront_robust::quality::repaired_chance_rate;
use vofront_robust::{
    irls, Convergence, IrlsConfig, LmConfig, Loss, Problem, Quality, QualityConfig, Rows, ScaleMode,
};

use crate::camera::Camera;
use crate::error::GeometryError;
use crate::lie::{point_jacobian, retract_left};
use crate::p3p::p3p;
use crate::ransac::{ransac_from, Estimator, RansacConfig};

/// Minimum correspondences: three for P3P plus one to choose among its solutions.
const MIN_POINTS: usize = 4;

/// Settings of [`solve_pnp_ransac`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnpConfig {
    /// RANSAC settings; `ransac.threshold` is the inlier threshold on the reprojection error
    /// in pixels (default 2 px, at most 1000 iterations).
    pub ransac: RansacConfig,
    /// Huber IRLS refinement on the inliers.
    pub refine: bool,
    /// Residual scale of the Huber loss (pixels); the Huber corner is at `1.345` of it.
    pub sigma_px: f64,
    /// Fewer inliers than this is [`GeometryError::NoModel`].
    pub min_inliers: usize,
    /// Minimum support of an `ok` pose ([`PnpResult::quality`]).
    pub quality: QualityConfig,
}

impl Default for PnpConfig {
    fn default() -> Self {
        Self {
            ransac: RansacConfig {
                threshold: 2.0,
                max_iterations: 1000,
                ..RansacConfig::default()
            },
            refine: true,
            sigma_px: 1.0,
            min_inliers: 6,
            quality: QualityConfig::default(),
        }
    }
}

/// Result of [`solve_pnp_ransac`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PnpResult {
    /// `T_cw`: world (reference) points into the camera frame.
    pub pose: Isometry3<f64>,
    /// Reprojection error under the threshold at the final pose, per correspondence.
    pub inliers: Vec<bool>,
    /// Covariance of the left increment `delta = (rho, phi)` at the solution; `None`
    /// (unknown) when not refined or when the refinement's normal equations are singular.
    pub covariance: Option<Matrix6<f64>>,
    /// Root mean square reprojection error of the inliers, pixels.
    pub rmse_px: f64,
    /// RANSAC iterations.
    pub iterations: usize,
    /// Verdict, support, chance test and uncertainty of the pose ([`pnp_quality`]).
    pub quality: Quality,
}

impl PnpResult {
    /// Number of `true` in [`Self::inliers`].
    pub fn inlier_count(&self) -> usize {
        self.inliers.iter().filter(|&&b| b).count()
    }
}

/// P3P hypotheses scored by the squared reprojection error in normalized coordinates; local
/// optimisation runs a few Huber IRLS steps on the pixel reprojection error of the inliers.
struct PnpEstimator<'a> {
    world: &'a [Point3<f64>],
    bearings: &'a [Vector3<f64>],
    normalized: &'a [Vector2<f64>],
    /// Observed pixels, index-aligned with `world`.
    pixels: &'a [Vector2<f64>],
    /// Relative noise scale of each pixel, index-aligned with `world`.
    sigmas: &'a [f64],
    /// `I / sigmas[i]`, the refinement's whitening of each residual.
    whitening: &'a [Matrix2<f64>],
    camera: &'a Camera,
    /// Residual scale of the Huber loss, pixels.
    sigma_px: f64,
}

/// IRLS iterations of one local-optimisation round of the PnP RANSAC.
const LO_IRLS_ITERATIONS: usize = 4;

/// The Huber IRLS settings of PnP refinement at the residual scale `sigma_px`.
fn huber_irls(sigma_px: f64, max_iterations: usize) -> IrlsConfig {
    IrlsConfig {
        loss: Loss::Huber(1.345),
        scale: ScaleMode::Fixed(sigma_px),
        lm: LmConfig {
            max_iterations,
            ..LmConfig::default()
        },
        covariance: true,
    }
}

impl Estimator for PnpEstimator<'_> {
    type Model = Isometry3<f64>;

    fn sample_size(&self) -> usize {
        3
    }

    fn len(&self) -> usize {
        self.world.len()
    }

    fn fit_minimal(&self, s: &[usize], out: &mut Vec<Isometry3<f64>>) {
        let w = [self.world[s[0]], self.world[s[1]], self.world[s[2]]];
        let f = [
            self.bearings[s[0]],
            self.bearings[s[1]],
            self.bearings[s[2]],
        ];
        p3p(&w, &f, out);
    }

    fn fit_nonminimal(&self, _indices: &[usize], out: &mut Vec<Isometry3<f64>>) {
        // No closed-form refit: local optimisation iterates from the hypothesis (`refine`).
        out.clear();
    }

    fn refine(&self, start: &Isometry3<f64>, indices: &[usize], out: &mut Vec<Isometry3<f64>>) {
        out.clear();
        let mut problem = Reprojection {
            camera: self.camera,
            world: self.world,
            pixels: self.pixels,
            whitening: self.whitening,
            indices,
        };
        // Only the pose is kept: the covariance's extra pass over the rows is skipped.
        let cfg = IrlsConfig {
            covariance: false,
            ..huber_irls(self.sigma_px, LO_IRLS_ITERATIONS)
        };
        if let Ok(res) = irls(&mut problem, *start, &cfg) {
            out.push(res.state);
        }
    }

    fn residual_sq(&self, t: &Isometry3<f64>, i: usize) -> f64 {
        crate::residual::reprojection_sq(&(t * self.world[i]).coords, &self.normalized[i])
            / (self.sigmas[i] * self.sigmas[i])
    }
}

/// Reprojection problem over the inliers, each residual whitened: `W_i (pi(T P_i) - u_i)` with
/// `W_i^T W_i` the inverse of its noise covariance in units of `sigma_px^2` (`I / s_i` for a
/// pixel noise alone).
struct Reprojection<'a> {
    camera: &'a Camera,
    world: &'a [Point3<f64>],
    pixels: &'a [Vector2<f64>],
    whitening: &'a [Matrix2<f64>],
    indices: &'a [usize],
}

impl Problem<6> for Reprojection<'_> {
    type State = Isometry3<f64>;

    fn evaluate(&mut self, t: &Isometry3<f64>, rows: &mut Rows<6>) {
        for &i in self.indices {
            let x = (t * self.world[i]).coords;
            let Some((pixel, jpix)) = project_in_front(self.camera, &x) else {
                continue;
            };
            let w = &self.whitening[i];
            let j = w * (jpix * point_jacobian(&x));
            let r = w * (pixel - self.pixels[i]);
            rows.push(j.row(0).transpose(), r.x);
            rows.push(j.row(1).transpose(), r.y);
        }
    }

    fn retract(&self, t: &Isometry3<f64>, delta: &SVector<f64, 6>) -> Isometry3<f64> {
        retract_left(t, delta)
    }
}

/// Pixel and Jacobian `du/dx` (pixels per metre) of the camera-frame point `x` through the
/// full camera model ([`Camera::project_with_jacobian`]); `None` at or behind the camera plane
/// (`z <= MIN_DEPTH`, [`crate::residual::MIN_DEPTH`]) or outside the lens's validity range.
pub(crate) fn project_in_front(
    camera: &Camera,
    x: &Vector3<f64>,
) -> Option<(Vector2<f64>, Matrix2x3<f64>)> {
    if x.z <= crate::residual::MIN_DEPTH {
        return None;
    }
    camera.project_with_jacobian(x)
}

/// Reprojection residual `pi(T_cw P) - u` (pixels) of the world point `p` observed at `u`;
/// `None` behind the camera or outside the lens's range.
fn reprojection(
    camera: &Camera,
    t: &Isometry3<f64>,
    p: &Point3<f64>,
    u: &Vector2<f64>,
) -> Option<Vector2<f64>> {
    camera.project(&(t * p).coords).map(|q| q - u)
}

/// Estimates the camera pose `T_cw` from world points and their observed (distorted) pixels:
/// P3P in LO-MSAC (threshold `ransac.threshold / f` in normalized coordinates; local optimisation
/// by a few Huber IRLS steps on the inliers), an optional prior pose as its first hypothesis
/// ([`ransac_from`]), then Huber IRLS on the pixel reprojection error of the inliers.
///
/// ```
/// use nalgebra::{Isometry3, Point3, Vector3};
/// use vofront_geometry::{Camera, Pinhole};
/// use vofront_geometry::pnp::{solve_pnp_ransac, PnpConfig};
/// let cam = Camera::pinhole(Pinhole::new(520.0, 520.0, 320.0, 240.0).unwrap());
/// let t_cw = Isometry3::new(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.05, 0.1, -0.02));
/// let world: Vec<Point3<f64>> = (0..30)
///     .map(|i| { let f = i as f64; Point3::new((f * 0.7).sin() * 2.0, (f * 1.3).cos(), 4.0 + (f * 0.37).sin()) })
///     .collect();
/// let pixels: Vec<_> = world.iter().map(|p| cam.project(&(t_cw * p).coords).unwrap()).collect();
/// let res = solve_pnp_ransac(&world, &pixels, &cam, None, &PnpConfig::default()).unwrap();
/// assert!((res.pose.to_homogeneous() - t_cw.to_homogeneous()).norm() < 1e-6);
/// ```
pub fn solve_pnp_ransac(
    points_world: &[Point3<f64>],
    pixels: &[Vector2<f64>],
    camera: &Camera,
    prior: Option<Isometry3<f64>>,
    cfg: &PnpConfig,
) -> Result<PnpResult, GeometryError> {
    let sigmas = vec![1.0; pixels.len()];
    solve_pnp_ransac_with_sigmas(points_world, pixels, &sigmas, camera, prior, cfg)
}

/// [`solve_pnp_ransac`] with a relative noise scale `sigmas[i] > 0` for each pixel (see the
/// module documentation): correspondence `i` is an inlier when its reprojection error is
/// under `ransac.threshold * sigmas[i]` pixels, and its residual is divided by `sigmas[i]` in
/// the refinement. [`PnpResult::rmse_px`] stays in plain pixels.
pub fn solve_pnp_ransac_with_sigmas(
    points_world: &[Point3<f64>],
    pixels: &[Vector2<f64>],
    sigmas: &[f64],
    camera: &Camera,
    prior: Option<Isometry3<f64>>,
    cfg: &PnpConfig,
) -> Result<PnpResult, GeometryError> {
    solve(points_world, pixels, sigmas, None, camera, prior, cfg)
}

/// [`solve_pnp_ransac_with_sigmas`] for world points that carry a covariance `C_i` (world
/// frame, metres^2; `None` for an exact point), such as stereo points with their depth noise.
/// RANSAC is as without; then the inliers are selected and refined under each residual's
/// noise `sigma_px^2 (s_i^2 I + G_i C_i G_i^T / sigma_px^2)`, `G_i = jpix R_cw` the pixel's
/// Jacobian in the point, evaluated at the current pose and re-evaluated after each of
/// [`POINT_NOISE_ROUNDS`] refinements. A point is an inlier when its whitened error
/// `|W_i (pi(T P_i) - u_i)|` is under `ransac.threshold`; the chance test keeps the pixel
/// noise alone. Errors: as [`solve_pnp_ransac_with_sigmas`], and
/// [`GeometryError::LengthMismatch`] when `covariances` is not index-aligned with `pixels`,
/// [`GeometryError::NonFinite`] for a covariance that is not finite.
pub fn solve_pnp_ransac_with_point_covariances(
    points_world: &[Point3<f64>],
    pixels: &[Vector2<f64>],
    sigmas: &[f64],
    covariances: &[Option<Matrix3<f64>>],
    camera: &Camera,
    prior: Option<Isometry3<f64>>,
    cfg: &PnpConfig,
) -> Result<PnpResult, GeometryError> {
    if covariances.len() != pixels.len() {
        return Err(GeometryError::LengthMismatch(
            covariances.len(),
            pixels.len(),
        ));
    }
    if covariances
        .iter()
        .flatten()
        .any(|c| !c.iter().all(|v| v.is_finite()))
    {
        return Err(GeometryError::NonFinite);
    }
    solve(
        points_world,
        pixels,
        sigmas,
        Some(covariances),
        camera,
        prior,
        cfg,
    )
}

/// Refinements of [`solve_pnp_ransac_with_point_covariances`], each from the whitening at the
/// pose the previous one reached.
pub const POINT_NOISE_ROUNDS: usize = 2;

/// The body of [`solve_pnp_ransac_with_sigmas`] and
/// [`solve_pnp_ransac_with_point_covariances`] (`covariances` validated, index-aligned with
/// `pixels`).
fn solve(
    points_world: &[Point3<f64>],
    pixels: &[Vector2<f64>],
    sigmas: &[f64],
    covariances: Option<&[Option<Matrix3<f64>>]>,
    camera: &Camera,
    prior: Option<Isometry3<f64>>,
    cfg: &PnpConfig,
) -> Result<PnpResult, GeometryError> {
    camera.validate()?;
    if points_world.len() != pixels.len() {
        return Err(GeometryError::LengthMismatch(
            points_world.len(),
            pixels.len(),
        ));
    }
    if sigmas.len() != pixels.len() {
        return Err(GeometryError::LengthMismatch(sigmas.len(), pixels.len()));
    }
    if sigmas.iter().any(|s| !s.is_finite()) {
        return Err(GeometryError::NonFinite);
    }
    if sigmas.iter().any(|s| *s <= 0.0) {
        return Err(GeometryError::InvalidConfig(
            "every pixel noise scale must be positive",
        ));
    }
    if points_world.len() < MIN_POINTS {
        return Err(GeometryError::TooFewCorrespondences {
            got: points_world.len(),
            need: MIN_POINTS,
        });
    }
    if points_world
        .iter()
        .any(|p| !p.iter().all(|v| v.is_finite()))
        || pixels.iter().any(|p| !p.iter().all(|v| v.is_finite()))
    {
        return Err(GeometryError::NonFinite);
    }
    cfg.ransac.validate()?;
    let mut world = Vec::with_capacity(pixels.len());
    let mut bearings = Vec::with_capacity(pixels.len());
    let mut normalized = Vec::with_capacity(pixels.len());
    let mut index = Vec::with_capacity(pixels.len());
    for (i, (p, u)) in points_world.iter().zip(pixels).enumerate() {
        if let Some(x) = camera.pixel_to_normalized(u) {
            world.push(*p);
            bearings.push(Vector3::new(x.x, x.y, 1.0).normalize());
            normalized.push(x);
            index.push(i);
        }
    }
    if world.len() < MIN_POINTS {
        return Err(GeometryError::TooFewCorrespondences {
            got: world.len(),
            need: MIN_POINTS,
        });
    }
    let spread = world
        .iter()
        .map(|p| (p - world[0]).norm())
        .fold(0.0, f64::max);
    if spread < 1e-12 {
        return Err(GeometryError::Degenerate(
            "all world points are identical".into(),
        ));
    }
    let focal = 0.5 * (camera.pinhole.fx + camera.pinhole.fy);
    let px: Vec<Vector2<f64>> = index.iter().map(|&i| pixels[i]).collect();
    let sg: Vec<f64> = index.iter().map(|&i| sigmas[i]).collect();
    let isotropic: Vec<Matrix2<f64>> = sg.iter().map(|s| Matrix2::identity() / *s).collect();
    let est = PnpEstimator {
        world: &world,
        bearings: &bearings,
        normalized: &normalized,
        pixels: &px,
        sigmas: &sg,
        whitening: &isotropic,
        camera,
        sigma_px: cfg.sigma_px,
    };
    let rcfg = cfg.ransac.in_normalized_units(focal);
    let guess = prior.filter(|p| p.to_homogeneous().iter().all(|v| v.is_finite()));
    let found = ransac_from(&est, &rcfg, guess);
    let iterations = found.as_ref().map_or(0, |r| r.iterations);
    let mut pose = found.map(|r| r.model).ok_or(GeometryError::NoModel {
        best: 0,
        need: cfg.min_inliers,
    })?;
    let mut covariance = None;
    let (mut converged, mut refine_iterations) = (true, 0);
    // The whitening at `t`: the pixel noise alone, or with each point's own noise (and then
    // re-evaluated after each refinement).
    let covariances = covariances.filter(|c| c.iter().any(Option::is_some));
    let whiten = |t: &Isometry3<f64>| -> Vec<Matrix2<f64>> {
        let Some(covariances) = covariances else {
            return isotropic.clone();
        };
        (0..world.len())
            .map(|k| {
                let c = covariances[index[k]].as_ref();
                point_whitening(camera, t, &world[k], sg[k], c, cfg.sigma_px)
            })
            .collect()
    };
    let inliers_of = |t: &Isometry3<f64>, whitening: &[Matrix2<f64>]| -> Vec<usize> {
        (0..world.len())
            .filter(|&k| {
                whitened_error(camera, t, &world[k], &px[k], &whitening[k]) < cfg.ransac.threshold
            })
            .collect()
    };
    let mut whitening = whiten(&pose);
    let mut used = inliers_of(&pose, &whitening);
    if used.len() < cfg.min_inliers.max(MIN_POINTS) {
        return Err(GeometryError::NoModel {
            best: used.len(),
            need: cfg.min_inliers.max(MIN_POINTS),
        });
    }
    let mut refined = !cfg.refine;
    let rounds = match (cfg.refine, covariances) {
        (false, _) => 0,
        (true, Some(_)) => POINT_NOISE_ROUNDS,
        (true, None) => 1,
    };
    for _ in 0..rounds {
        let mut problem = Reprojection {
            camera,
            world: &world,
            pixels: &px,
            whitening: &whitening,
            indices: &used,
        };
        if let Ok(res) = irls(&mut problem, pose, &huber_irls(cfg.sigma_px, 20)) {
            pose = res.state;
            covariance = res.covariance;
            converged = res.reason != Convergence::MaxIterations;
            refine_iterations = res.iterations;
            refined = true;
        }
        if covariances.is_some() {
            whitening = whiten(&pose);
        }
        used = inliers_of(&pose, &whitening);
    }
    // Each point is projected once, for the inliers' errors and the chance rate.
    let projected: Vec<Option<Vector2<f64>>> = world
        .iter()
        .map(|p| camera.project(&(pose * p).coords))
        .collect();
    let mut inliers = vec![false; pixels.len()];
    // Plain and whitened squared reprojection errors.
    let (mut sq, mut sq_white) = (0.0, 0.0);
    for &k in &used {
        inliers[index[k]] = true;
        sq += projected[k]
            .map_or(f64::INFINITY, |q| (q - px[k]).norm())
            .powi(2);
        sq_white += whitened_error(camera, &pose, &world[k], &px[k], &whitening[k]).powi(2);
    }
    let inlier_count = used.len();
    if inlier_count < cfg.min_inliers.max(MIN_POINTS) {
        return Err(GeometryError::NoModel {
            best: inlier_count,
            need: cfg.min_inliers.max(MIN_POINTS),
        });
    }
    // A re-paired correspondence costs one distance.
    let p0 = repaired_chance_rate(world.len(), |k, j| {
        projected[k].is_some_and(|q| (q - px[j]).norm() < cfg.ransac.threshold * sg[j])
    });
    let evidence = PnpEvidence {
        candidates: pixels.len(),
        tested: world.len(),
        inliers: inlier_count,
        p0,
        hypotheses: (iterations * P3P_SOLUTIONS + 1) as f64,
        sigma_px: (sq_white / (2 * inlier_count).saturating_sub(6).max(1) as f64).sqrt(),
        iterations: refine_iterations,
        converged,
        // A refinement that ran but left no covariance met singular normal equations.
        degenerate: cfg.refine && refined && covariance.is_none(),
    };
    Ok(PnpResult {
        pose,
        inliers,
        covariance,
        rmse_px: (sq / inlier_count as f64).sqrt(),
        iterations,
        quality: pnp_quality(&evidence, covariance.as_ref(), &cfg.quality),
    })
}

/// P3P solutions per minimal sample (the quartic's largest root count).
const P3P_SOLUTIONS: usize = 4;
