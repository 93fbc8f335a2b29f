//! SE(3) direct image alignment of an RGB-D reference frame to a current grey image.
//!
//! For a selected reference pixel `p` with depth `d` and pinhole intrinsics `K`, the warp is
//! `w(p, T) = pi(K (R pi^-1(p, d) + t))` with `T = T_cur_ref` (reference-frame points into the
//! current frame) and the residual is `r = I_cur(w(p, T)) - (a I_ref(p) + b)`.
//! Parameters: a left pose increment `T <- exp(delta) T`, `delta = (rho, phi)`, and the
//! brightness `(a, b)` (`N = 8`, brightness optionally held at `a = 1, b = 0`). With
//! `P' = T P = (X, Y, Z)` and `g = grad I_cur(w)`, the Jacobian row is
//! `dr/d delta = g^T d pi/dP' [I | -hat(P')]`, i.e. translation part
//! `c = (g_x f_x / Z, g_y f_y / Z, -(c_x X + c_y Y) / Z)` and rotation part `P' x c`;
//! `dr/da = -I_ref(p)`, `dr/db = -1`.
//!
//! Pixels are chosen per pyramid level, DSO-style (module `select`), or given with their
//! inverse depths (module `sparse`); level `l` uses `f / 2^l`, `c / 2^l`. Each level runs robust Levenberg-Marquardt (Huber or Student-t weights, MAD scale
//! re-estimated every iteration, normal equations reduced in parallel), coarse to fine, from the
//! prior pose, with `(a, b)` estimated only at the `brightness_levels` finest levels. Module
//! `level` holds the residuals and Jacobian rows of one level; the result's covariance is the
//! robust crate's sandwich covariance plus the calibration's share (module `calibration`).
//! [`Se3Reference::halves_disagreement`] checks that two halves of the pixels agree on the
//! motion (module `halves`).

use std::sync::Arc;

use nalgebra::{Isometry3, Matrix6, SVector, Vector3};
use rayon::prelude::*;
use vofront_image::Image;
use vofront_robust::{sandwich_covariance, Convergence, Loss, Quality, QualityConfig};

use crate::error::DirectError;
use crate::lm::{run_level, LevelProblem, LmSettings, SERIAL_MAX};
use crate::plane::Bilinear;
use crate::quality::{intensity_variance, se3_quality, Se3Stats};
use crate::rgbd::{pinhole_image, RgbdFrame, Undistorter};

mod calibration;
mod halves;
mod level;
mod residuals;
mod select;
mod sparse;

use calibration::calibration_covariance;
pub use calibration::CalibrationPrior;
pub use halves::HALF_CELL_PX;
use level::{Se3Level, Se3State};
pub use residuals::PixelResidual;
use select::{level_intrinsics, select_level, RefLevel};
pub use sparse::InverseDepthPoint;

/// Smallest side of the coarsest pyramid level, pixels.
const MIN_LEVEL_SIDE: usize = 20;
/// Fewest valid residuals for a level to be solved (a few per parameter).
const MIN_VALID: usize = 64;
/// A level's points are those its starting pose projects at least this far (pixels of the
/// level) inside the current image; the set is then fixed for the level (see
/// [`level::Se3Level::new`]; the 2D warps do the same).
const LEVEL_MARGIN_PX: f32 = 2.0;

/// Settings of [`align_se3`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Se3Config {
    /// Pyramid levels as factor-2 octaves (each level half the size of the one below; ORB's 1.2-ratio levels are
    /// `OrbConfig::scale_levels`), fewer on small images, at least 1.
    pub levels: usize,
    /// About this many reference pixels per level (fewer when the level is small).
    pub pixel_budget: usize,
    /// Reference pixels with `|grad I_ref|` below this (grey levels per pixel) are not used.
    pub gradient_threshold: f32,
    /// Robust loss on residuals in sigmas: `Loss::Huber(1.345)` or `Loss::StudentT(5.0)`.
    pub loss: Loss,
    /// Estimate `(a, b)` of `I_cur = a I_ref + b`; otherwise they stay `1, 0`.
    pub affine_brightness: bool,
    /// With `affine_brightness`, `(a, b)` are estimated at this many of the finest levels and
    /// held at `(1, 0)` above them. At a coarse level the pose is still far off, and a joint
    /// fit there drives the gain towards 0 (a misaligned image is "explained" by a flat one),
    /// from which the pose does not recover.
    pub brightness_levels: usize,
    /// With `affine_brightness`, a final gain outside `[1 / max_gain, max_gain]` is reported as
    /// [`DirectError::ImplausibleGain`]: the alignment failed.
    pub max_gain: f64,
    /// Iteration limit per level.
    pub max_iterations: usize,
    /// Stop when `|delta|` (metres and radians) is below this.
    pub min_step: f64,
    /// Stop when the step is below this many of its own standard deviations (Mahalanobis
    /// length under the level's Gauss-Newton covariance): finer steps are below the noise of
    /// the estimate. 0 disables the test.
    pub min_step_sigmas: f64,
    /// Stop when an accepted step lowers the mean robust cost by less than this fraction.
    pub min_relative_decrease: f64,
    /// Floor of the residual scale, grey levels.
    pub min_sigma: f32,
    /// Depths outside `[min_depth, max_depth]` metres are treated as invalid.
    pub min_depth: f32,
    /// See `min_depth`.
    pub max_depth: f32,
    /// Largest acceptable Jacobi-scaled condition number of the 8x8 normal matrix.
    pub max_condition: f64,
    /// A residual within this many scales `s` counts as an inlier in `inlier_ratio`.
    pub inlier_sigmas: f32,
    /// Thresholds of the result's [`Se3Result::quality`] verdict.
    pub quality: QualityConfig,
    /// How well the intrinsics and the depth scale are known; the covariance includes what
    /// their errors move ([`CalibrationPrior`]). [`CalibrationPrior::exact`] for rendered
    /// scenes.
    pub calibration: CalibrationPrior,
}

impl Default for Se3Config {
    fn default() -> Self {
        Self {
            levels: 4,
            pixel_budget: 12_000,
            gradient_threshold: 3.0,
            loss: Loss::Huber(1.345),
            affine_brightness: true,
            brightness_levels: 2,
            max_gain: 2.0,
            max_iterations: 30,
            min_step: 1e-6,
            min_step_sigmas: 0.2,
            min_relative_decrease: 1e-6,
            min_sigma: 0.5,
            min_depth: 0.1,
            max_depth: 20.0,
            max_condition: 1e10,
            inlier_sigmas: 3.0,
            quality: QualityConfig::default(),
            calibration: CalibrationPrior::default(),
        }
    }
}

/// Result of [`align_se3`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Se3Result {
    /// `T_cur_ref`: maps points of the reference camera frame into the current one.
    pub pose: Isometry3<f64>,
    /// Brightness gain, `I_cur = a I_ref + b`.
    pub a: f64,
    /// Brightness offset, grey levels.
    pub b: f64,
    /// Iterations per pyramid level, index = level (0 = full resolution).
    pub iterations: Vec<usize>,
    /// Final mean robust cost `s^2 mean rho(r / s)` at full resolution, grey levels^2.
    pub cost: f64,
    /// Root-mean-square residual at full resolution, grey levels.
    pub rmse: f64,
    /// Fraction of the valid residuals within `inlier_sigmas` scales `sigma`. The scale follows
    /// the residuals, so a failed alignment can still score high here: judge it by `sigma` and
    /// `rmse` against the image noise (a few grey levels when aligned).
    pub inlier_ratio: f64,
    /// Robust residual scale at full resolution (`1.4826 median |r|`, floored at
    /// `min_sigma`), grey levels.
    pub sigma: f64,
    /// Valid residuals at full resolution.
    pub valid_pixels: usize,
    /// Covariance of the left pose increment `(rho, phi)`, metres and radians, marginal over
    /// the brightness: the M-estimator's sandwich `B^-1 M B^-1` at full resolution (the
    /// robust crate's `sandwich`), for independent residuals, plus what the calibration's
    /// uncertainty moves, `V S V^T` ([`Se3Config::calibration`], [`CalibrationPrior`]). The error is `T_est = exp(e) T_true`,
    /// `e ~ N(0, covariance)`. `None` (unknown) when the final normal equations are singular or
    /// ill-conditioned, or the robust Hessian `B` is not positive definite.
    pub covariance: Option<Matrix6<f64>>,
    /// Why the full-resolution level stopped.
    pub reason: Convergence,
    /// Verdict, support, 6x6 covariance of `(rho, phi)` and sigmas, judged with
    /// [`Se3Config::quality`]: support out of the reference's candidate pixels (see
    /// [`Se3Reference`]), the chance test on `var(I_ref) + var(I_cur)` (`I_ref` in the pinhole
    /// geometry, `I_cur` as given), `sigma` the robust residual scale, grey levels.
    pub quality: Quality,
}

/// A reference frame with its pixels selected per level, reusable for several current images.
///
/// The support of an alignment's [`Se3Result::quality`] counts against the reference's
/// candidate pixels: those selected at full resolution (or the usable given points), and for
/// the one-off [`align_se3`] every pixel of the frame.
#[derive(Debug, Clone)]
pub struct Se3Reference {
    levels: Vec<RefLevel>,
    /// Size of the reference image.
    size: (usize, usize),
    /// Candidate pixels of the quality's support.
    candidates: usize,
    /// `var(I_ref)` of the pinhole reference image, grey levels^2, for the chance test.
    variance: f64,
    /// The remap that brings current images to the pinhole geometry.
    undistorter: Option<Arc<Undistorter>>,
}

impl Se3Reference {
    /// Builds the pyramid of `frame` and selects pixels per level as `cfg` says.
    pub fn new(frame: &RgbdFrame, cfg: &Se3Config) -> Result<Self, DirectError> {
        if cfg.levels == 0 || cfg.pixel_budget == 0 || cfg.max_iterations == 0 {
            return Err(DirectError::InvalidConfig(
                "levels, pixel_budget and max_iterations must be positive",
            ));
        }
        let coarse = frame.image().coarser_levels(cfg.levels, MIN_LEVEL_SIDE);
        let levels: Vec<RefLevel> = std::iter::once(frame.image())
            .chain(&coarse)
            .enumerate()
            .map(|(l, img)| {
                let k = level_intrinsics(frame.pinhole(), l);
                select_level(img, frame.depth(), 1 << l, k, cfg)
            })
            .collect();
        if levels[0].x.is_empty() {
            let any_depth = frame
                .depth()
                .data()
                .iter()
                .any(|&z| z >= cfg.min_depth && z <= cfg.max_depth);
            return Err(if any_depth {
                DirectError::NoTexture {
                    pixels: 0,
                    required: MIN_VALID,
                }
            } else {
                DirectError::NoValidDepth
            });
        }
        Ok(Self {
            candidates: levels[0].x.len(),
            levels,
            size: frame.image().size(),
            variance: intensity_variance(frame.image()),
            undistorter: frame.undistorter().cloned(),
        })
    }

    /// Number of selected pixels per level (index = level).
    pub fn selected(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.x.len()).collect()
    }

    /// Aligns `current` (same camera and size as the reference, still distorted if the camera
    /// is) starting from `prior` (`T_cur_ref`, e.g. from a motion model; identity if unknown)
    /// and unchanged brightness (`a = 1`, `b = 0`).
    pub fn align(
        &self,
        current: &Image<f32>,
        prior: &Isometry3<f64>,
        cfg: &Se3Config,
    ) -> Result<Se3Result, DirectError> {
        self.align_from(current, prior, (1.0, 0.0), cfg)
    }

    /// [`Se3Reference::align`] from the brightness `(a, b)` (`I_cur = a I_ref + b`), e.g. the
    /// ratio of the two images' mean grey levels after an exposure change: started at `a = 1`
    /// the coarse levels can explain a 2x jump by the offset and walk the gain away.
    pub fn align_from(
        &self,
        current: &Image<f32>,
        prior: &Isometry3<f64>,
        (a, b): (f64, f64),
        cfg: &Se3Config,
    ) -> Result<Se3Result, DirectError> {
        if !(a.is_finite() && b.is_finite() && a > 0.0) {
            return Err(DirectError::InvalidConfig(
                "the starting gain must be positive and the offset finite",
            ));
        }
        let prior_ok = prior.translation.vector.iter().all(|v| v.is_finite())
            && prior.rotation.coords.iter().all(|v| v.is_finite());
        if !prior_ok {
            return Err(DirectError::NotFinite);
        }
        if cfg.max_gain.is_nan() || cfg.max_gain < 1.0 {
            return Err(DirectError::InvalidConfig("max_gain must be at least 1"));
        }
        if current.size() != self.size {
            return Err(DirectError::SizeMismatch {
                expected: self.size,
                found: current.size(),
            });
        }
        let variances = self.variance + intensity_variance(current);
        let current = &*pinhole_image(self.undistorter.as_deref(), current)?;
        let coarse = current.coarser_levels(self.levels.len(), MIN_LEVEL_SIDE);
        let mut state = Se3State {
            pose: vofront_core::lie::normalized(prior),
            a,
            b,
        };
        let mut iterations = vec![0; self.levels.len()];
        let step_weights = SVector::<f64, 8>::from([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1e-2, 1e-4]);
        let settings = LmSettings {
            loss: cfg.loss,
            min_sigma: cfg.min_sigma,
            max_iterations: cfg.max_iterations,
            min_step: cfg.min_step,
            min_step_sigmas: cfg.min_step_sigmas,
            step_weights,
            min_relative_decrease: cfg.min_relative_decrease,
            max_condition: cfg.max_condition,
            fixed: [false; 8],
            min_valid: MIN_VALID,
            serial_max: SERIAL_MAX,
        };
        for level in (0..=coarse.len()).rev() {
            let reference = &self.levels[level];
            if reference.x.len() < MIN_VALID && level > 0 {
                continue;
            }
            let img = if level == 0 {
                current
            } else {
                &coarse[level - 1]
            };
            let mut problem = Se3Level::new(
                reference,
                img.size(),
                img.data(),
                &state.pose,
                LEVEL_MARGIN_PX,
            );
            let brightness = cfg.affine_brightness && level < cfg.brightness_levels;
            let mut level_settings = settings;
            level_settings.fixed[6..].fill(!brightness);
            let out = run_level(&mut problem, state, &level_settings)?;
            iterations[level] = out.iterations;
            state = out.state;
            if level == 0 {
                let res = LevelProblem::<8>::residuals(&problem);
                let limit = cfg.inlier_sigmas * out.scale;
                let (sum_sq, inliers) = res
                    .iter()
                    .filter(|r| !r.is_nan())
                    .fold((0.0f64, 0usize), |(s, n), &r| {
                        (s + f64::from(r * r), n + usize::from(r.abs() <= limit))
                    });
                let valid = out.valid.max(1) as f64;
                // The M-estimate's sandwich covariance (`vofront_robust::sandwich`), marginal
                // over the brightness, for a well-conditioned problem only (the Gauss-Newton
                // test).
                let rows = res
                    .iter()
                    .zip(&problem.jacobians)
                    .filter(|(r, _)| !r.is_nan())
                    .map(|(&r, j)| (SVector::<f64, 8>::from(j.map(f64::from)), f64::from(r)));
                let cov = out.system.covariance(cfg.max_condition).and_then(|_| {
                    sandwich_covariance(
                        rows,
                        &cfg.loss,
                        f64::from(out.scale),
                        &level_settings.fixed,
                    )
                    .map(|c| {
                        c.fixed_view::<6, 6>(0, 0).into_owned()
                            + calibration_covariance(
                                &problem,
                                &state,
                                &cfg.loss,
                                f64::from(out.scale),
                                &level_settings.fixed,
                                &cfg.calibration,
                            )
                    })
                });
                let gain_ok = state.a >= 1.0 / cfg.max_gain && state.a <= cfg.max_gain;
                if cfg.affine_brightness && !gain_ok {
                    return Err(DirectError::ImplausibleGain {
                        a: state.a,
                        max_gain: cfg.max_gain,
                    });
                }
                let stats = Se3Stats {
                    covariance: cov.as_ref(),
                    valid_pixels: out.valid,
                    inlier_ratio: inliers as f64 / valid,
                    sigma: f64::from(out.scale),
                    rmse: (sum_sq / valid).sqrt(),
                    iterations: iterations.iter().sum(),
                    reason: out.reason,
                };
                let quality = se3_quality(&stats, self.candidates, variances, &cfg.quality);
                return Ok(Se3Result {
                    pose: state.pose,
                    a: state.a,
                    b: state.b,
                    iterations,
                    cost: out.cost,
                    rmse: stats.rmse,
                    inlier_ratio: stats.inlier_ratio,
                    sigma: stats.sigma,
                    valid_pixels: out.valid,
                    covariance: cov,
                    reason: out.reason,
                    quality,
                });
            }
        }
        // The loop returns at level 0, which every pyramid has.
        Err(DirectError::InvalidConfig(
            "the pyramid has no full-resolution level",
        ))
    }
}

/// SE(3) direct alignment of `current` to `reference` from `prior` (`T_cur_ref`); see the
/// module documentation. Prepare an [`Se3Reference`] once to align several images to it. The
/// support of the result's quality counts against every pixel of `reference`.
///
/// ```
/// use nalgebra::{Isometry3, Translation3, UnitQuaternion};
/// use vofront_direct::{align_se3, RgbdFrame, Se3Config};
/// use vofront_image::Image;
/// use vofront_core::{Camera, Pinhole};
/// // A textured fronto-parallel wall 2 m away, seen before and after a 2 cm sideways move.
/// let cam = Camera::pinhole(Pinhole::new(100.0, 100.0, 39.5, 29.5).unwrap());
/// let wall = |dx: f32| {
///     let data = (0..80 * 60)
///         .map(|i| {
///             let x = ((i % 80) as f32 - 39.5) / 100.0 * 2.0 + dx; // metres on the wall
///             let y = ((i / 80) as f32 - 29.5) / 100.0 * 2.0;
///             100.0 + 50.0 * (x * 20.0).sin() * (y * 17.0).cos() + 30.0 * ((x - y) * 11.0).sin()
///         })
///         .collect();
///     Image::new(80, 60, data).unwrap()
/// };
/// let depth = Image::filled(80, 60, 2.0);
/// let reference = RgbdFrame::new(wall(0.0), depth, &cam).unwrap();
/// let fit = align_se3(&reference, &wall(0.02), &Isometry3::identity(), &Se3Config::default()).unwrap();
/// // The camera moved by +2 cm in x, so reference points move by -2 cm in the current frame.
/// assert!((fit.pose.translation.x + 0.02).abs() < 1e-3, "{}", fit.pose.translation.x);
/// ```
pub fn align_se3(
    reference: &RgbdFrame,
    current: &Image<f32>,
    prior: &Isometry3<f64>,
    cfg: &Se3Config,
) -> Result<Se3Result, DirectError> {
    let (w, h) = reference.image().size();
    Se3Reference {
        candidates: w * h,
        ..Se3Reference::new(reference, cfg)?
    }
    .align(current, prior, cfg)
}

/// `|I_cur(w(p, T)) - a I_ref(p) - b|` for every reference pixel (pinhole geometry of
/// `reference`), NaN where the depth is invalid or the warp leaves the current image.
pub fn photometric_residual_map(
    reference: &RgbdFrame,
    current: &Image<f32>,
    pose: &Isometry3<f64>,
    a: f64,
    b: f64,
) -> Result<Image<f32>, DirectError> {
    reference.image().check_same_size(current)?;
    let current = pinhole_image(reference.undistorter().map(AsRef::as_ref), current)?;
    let (w, h) = current.size();
    let k = reference.pinhole();
    let rot = pose
        .rotation
        .to_rotation_matrix()
        .into_inner()
        .cast::<f32>();
    let t = pose.translation.vector.cast::<f32>();
    let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
    let mut out = Image::filled(w, h, f32::NAN);
    out.data_mut()
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let z = reference.depth().at(x, y);
                if !(z > 0.0 && z.is_finite()) {
                    continue;
                }
                let pr = Vector3::new((x as f32 - cx) / fx * z, (y as f32 - cy) / fy * z, z);
                let p = rot * pr + t;
                if p.z <= 1e-3 {
                    continue;
                }
                let u = fx * p.x / p.z + cx;
                let v = fy * p.y / p.z + cy;
                if let Some(tap) = Bilinear::new(u, v, w, h) {
                    let r = tap.apply(current.data())
                        - a as f32 * reference.image().at(x, y)
                        - b as f32;
                    *o = r.abs();
                }
            }
        });
    Ok(out)
}
