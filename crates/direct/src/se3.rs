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
//! Pixels are chosen per pyramid level DSO-style: the image is cut into square cells sized so
//! that there are about `pixel_budget` of them, and each cell keeps its pixel of largest
//! gradient among those with a valid depth and `|grad I_ref| >= gradient_threshold`.
//! Level `l` uses `f / 2^l`, `c / 2^l` and depth sampled at level-0 pixel `2^l p`.
//! Each level runs robust Levenberg-Marquardt (Huber or Student-t weights, MAD scale
//! re-estimated every iteration, normal equations reduced in parallel), coarse to fine, from the
//! prior pose.

use std::sync::Arc;

use nalgebra::{Isometry3, Matrix6, SVector, Vector3};
use rayon::prelude::*;
use vofront_geometry::lie::retract_left;
use vofront_robust::{Convergence, Loss, NormalEquations};

use crate::error::DirectError;
use crate::lm::{
    accumulate, covariance, run_level, LevelProblem, LmSettings, CHUNK, SERIAL_MAX_SE3,
};
use crate::plane::{Bilinear, Plane};
use crate::rgbd::{RgbdFrame, Undistorter};

/// Smallest side of the coarsest pyramid level, pixels.
const MIN_LEVEL_SIDE: usize = 20;
/// Fewest valid residuals for a level to be solved (a few per parameter).
const MIN_VALID: usize = 64;

/// Settings of [`align_se3`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Se3Config {
    /// Pyramid levels (fewer on small images), at least 1.
    pub levels: usize,
    /// About this many reference pixels per level (fewer when the level is small).
    pub pixel_budget: usize,
    /// Reference pixels with `|grad I_ref|` below this (grey levels per pixel) are not used.
    pub gradient_threshold: f32,
    /// Robust loss on residuals in sigmas: `Loss::Huber(1.345)` or `Loss::StudentT(5.0)`.
    pub loss: Loss,
    /// Estimate `(a, b)` of `I_cur = a I_ref + b`; otherwise they stay `1, 0`.
    pub affine_brightness: bool,
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
}

impl Default for Se3Config {
    fn default() -> Self {
        Self {
            levels: 4,
            pixel_budget: 12_000,
            gradient_threshold: 3.0,
            loss: Loss::Huber(1.345),
            affine_brightness: true,
            max_iterations: 30,
            min_step: 1e-6,
            min_step_sigmas: 0.2,
            min_relative_decrease: 1e-6,
            min_sigma: 0.5,
            min_depth: 0.1,
            max_depth: 20.0,
            max_condition: 1e10,
            inlier_sigmas: 3.0,
        }
    }
}

/// Result of [`align_se3`].
#[derive(Debug, Clone, PartialEq)]
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
    /// Fraction of the valid residuals within `inlier_sigmas` scales.
    pub inlier_ratio: f64,
    /// Valid residuals at full resolution.
    pub valid_pixels: usize,
    /// Gauss-Newton covariance of the left pose increment `(rho, phi)`, metres and radians.
    pub covariance: Matrix6<f64>,
    /// Why the full-resolution level stopped.
    pub reason: Convergence,
}

/// Selected reference pixels of one level, structure of arrays.
#[derive(Debug, Clone, Default)]
struct RefLevel {
    /// Camera-frame points, metres.
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    /// Grey level of the reference pixel.
    value: Vec<f32>,
    /// Intrinsics of the level `(fx, fy, cx, cy)`.
    k: [f32; 4],
}

/// A reference frame with its pixels selected per level, reusable for several current images.
#[derive(Debug, Clone)]
pub struct Se3Reference {
    levels: Vec<RefLevel>,
    /// Size of the reference image.
    size: (usize, usize),
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
        let coarse = coarse_levels(&frame.image, cfg.levels);
        let p = frame.pinhole;
        let mut levels = Vec::with_capacity(coarse.len() + 1);
        for (l, img) in std::iter::once(&frame.image).chain(&coarse).enumerate() {
            let s = 0.5f32.powi(l as i32);
            let k = [
                p.fx as f32 * s,
                p.fy as f32 * s,
                p.cx as f32 * s,
                p.cy as f32 * s,
            ];
            levels.push(select_level(img, &frame.depth, 1 << l, k, cfg));
        }
        if levels[0].x.is_empty() {
            let any_depth = frame
                .depth
                .data
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
            levels,
            size: frame.image.size(),
            undistorter: frame.undistorter.clone(),
        })
    }

    /// Number of selected pixels per level (index = level).
    pub fn selected(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.x.len()).collect()
    }

    /// Aligns `current` (same camera and size as the reference, still distorted if the camera
    /// is) starting from `prior` (`T_cur_ref`, e.g. from a motion model; identity if unknown).
    pub fn align(
        &self,
        current: &Plane,
        prior: &Isometry3<f64>,
        cfg: &Se3Config,
    ) -> Result<Se3Result, DirectError> {
        let prior_ok = prior.translation.vector.iter().all(|v| v.is_finite())
            && prior.rotation.coords.iter().all(|v| v.is_finite());
        if !prior_ok {
            return Err(DirectError::NotFinite);
        }
        if current.size() != self.size {
            return Err(DirectError::SizeMismatch {
                expected: self.size,
                found: current.size(),
            });
        }
        let undistorted;
        let current = match &self.undistorter {
            Some(u) => {
                undistorted = u.undistort_image(current)?;
                &undistorted
            }
            None => current,
        };
        let coarse = coarse_levels(current, self.levels.len());
        let mut state = Se3State {
            pose: vofront_geometry::lie::normalized(prior),
            a: 1.0,
            b: 0.0,
        };
        let mut iterations = vec![0; self.levels.len()];
        let mut fixed = [false; 8];
        fixed[6] = !cfg.affine_brightness;
        fixed[7] = !cfg.affine_brightness;
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
            fixed,
            min_valid: MIN_VALID,
            serial_max: SERIAL_MAX_SE3,
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
            let mut problem = Se3Level {
                reference,
                size: img.size(),
                image: &img.data,
                residuals: Vec::new(),
                jacobians: Vec::new(),
                saved: (Vec::new(), Vec::new()),
            };
            let out = run_level(&mut problem, state, &settings)?;
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
                let cov = covariance(&out.hessian, out.weighted_cost, out.valid);
                return Ok(Se3Result {
                    pose: state.pose,
                    a: state.a,
                    b: state.b,
                    iterations,
                    cost: out.cost,
                    rmse: (sum_sq / valid).sqrt(),
                    inlier_ratio: inliers as f64 / valid,
                    valid_pixels: out.valid,
                    covariance: cov.fixed_view::<6, 6>(0, 0).into_owned(),
                    reason: out.reason,
                });
            }
        }
        // The loop returns at level 0, which every pyramid has.
        Err(DirectError::InvalidConfig(
            "the pyramid has no full-resolution level",
        ))
    }
}

/// Levels `1..levels` of the pyramid of `base` (as [`crate::plane::Pyramid::new`] builds them),
/// without copying `base`.
fn coarse_levels(base: &Plane, levels: usize) -> Vec<Plane> {
    let mut out: Vec<Plane> = Vec::with_capacity(levels.saturating_sub(1));
    while out.len() + 1 < levels.max(1) {
        let last = out.last().unwrap_or(base);
        if last.width.div_ceil(2) < MIN_LEVEL_SIDE || last.height.div_ceil(2) < MIN_LEVEL_SIDE {
            break;
        }
        out.push(last.pyr_down());
    }
    out
}

/// Grey level and central-difference gradient of `img` at `(u, v)`, bilinearly interpolated
/// from the four surrounding pixels (the same values as interpolating [`Plane::gradients`]),
/// without building gradient planes. Needs `1 <= u, v` and `u <= w - 2`, `v <= h - 2`.
#[inline]
fn sample_with_gradient(img: &[f32], w: usize, h: usize, u: f32, v: f32) -> [f32; 3] {
    // Top-left tap in [1, w - 3] so that the 4x4 neighbourhood stays inside the plane.
    let x0 = (u as usize).min(w - 3).max(1);
    let y0 = (v as usize).min(h - 3).max(1);
    let (fx, fy) = (u - x0 as f32, v - y0 as f32);
    let i = y0 * w + x0;
    // Rows y0 - 1 ..= y0 + 2: `r0`, `r1` cover columns x0 - 1 ..= x0 + 2, `up`, `down` x0 ..= x0 + 1
    // (fixed-size copies: one bounds check per row).
    let taps = |start: usize| -> [f32; 4] {
        img[start..start + 4]
            .try_into()
            .expect("a slice of four elements")
    };
    let pair = |start: usize| -> [f32; 2] {
        img[start..start + 2]
            .try_into()
            .expect("a slice of two elements")
    };
    let (up, r0, r1, down) = (pair(i - w), taps(i - 1), taps(i + w - 1), pair(i + 2 * w));
    let (a, b, c, d) = (r0[1], r0[2], r1[1], r1[2]);
    let (w0, w1, w2, w3) = (
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    );
    let value = w0 * a + w1 * b + w2 * c + w3 * d;
    let gx = 0.5
        * (w0 * (r0[2] - r0[0])
            + w1 * (r0[3] - r0[1])
            + w2 * (r1[2] - r1[0])
            + w3 * (r1[3] - r1[1]));
    let gy = 0.5
        * (w0 * (r1[1] - up[0])
            + w1 * (r1[2] - up[1])
            + w2 * (down[0] - r0[1])
            + w3 * (down[1] - r0[2]));
    [value, gx, gy]
}

/// Pixels of one level: per grid cell, the largest gradient with a valid depth.
fn select_level(
    img: &Plane,
    depth0: &Plane,
    step: usize,
    k: [f32; 4],
    cfg: &Se3Config,
) -> RefLevel {
    let (w, h) = img.size();
    let cell = ((w * h) as f64 / cfg.pixel_budget as f64)
        .sqrt()
        .ceil()
        .max(1.0) as usize;
    let t2 = cfg.gradient_threshold * cfg.gradient_threshold;
    let depth_at = |x: usize, y: usize| {
        let z = depth0.data[(y * step) * depth0.width + x * step];
        (z >= cfg.min_depth && z <= cfg.max_depth).then_some(z)
    };
    let bands: Vec<RefLevel> = (1..h.saturating_sub(1))
        .step_by(cell)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|cy| {
            let mut out = RefLevel::default();
            // Per cell of the band: (g2, x, y, z) of the best pixel so far.
            let cells = (w.saturating_sub(2)).div_ceil(cell);
            let mut best: Vec<Option<(f32, usize, usize, f32)>> = vec![None; cells];
            let mut g2 = vec![0f32; w];
            for y in cy..(cy + cell).min(h - 1) {
                let (up, row, down) = (img.row(y - 1), img.row(y), img.row(y + 1));
                // Central differences, as in `Plane::gradients`; g2[x] for x in 1..w-1.
                for (((o, (r, l)), d), u) in g2[1..w - 1]
                    .iter_mut()
                    .zip(row[2..].iter().zip(&row[..w - 2]))
                    .zip(&down[1..w - 1])
                    .zip(&up[1..w - 1])
                {
                    let (gx, gy) = (0.5 * (r - l), 0.5 * (d - u));
                    *o = gx * gx + gy * gy;
                }
                for (ci, b) in best.iter_mut().enumerate() {
                    let x0 = 1 + ci * cell;
                    for (x, &g) in g2.iter().enumerate().take((x0 + cell).min(w - 1)).skip(x0) {
                        if g >= t2 && b.map_or(true, |b| g > b.0) {
                            if let Some(z) = depth_at(x, y) {
                                *b = Some((g, x, y, z));
                            }
                        }
                    }
                }
            }
            for (_, x, y, z) in best.into_iter().flatten() {
                let value = img.at(x, y);
                if value.is_finite() {
                    out.x.push((x as f32 - k[2]) / k[0] * z);
                    out.y.push((y as f32 - k[3]) / k[1] * z);
                    out.z.push(z);
                    out.value.push(value);
                }
            }
            out
        })
        .collect();
    let mut out = RefLevel {
        k,
        ..RefLevel::default()
    };
    for band in bands {
        out.x.extend(band.x);
        out.y.extend(band.y);
        out.z.extend(band.z);
        out.value.extend(band.value);
    }
    out
}

/// Pose and brightness.
#[derive(Debug, Clone, Copy)]
struct Se3State {
    pose: Isometry3<f64>,
    a: f64,
    b: f64,
}

/// One level of the SE(3) problem: residuals and Jacobian rows in SoA buffers.
struct Se3Level<'a> {
    reference: &'a RefLevel,
    /// `(width, height)` of the current level.
    size: (usize, usize),
    /// Grey levels of the current level, row-major.
    image: &'a [f32],
    residuals: Vec<f32>,
    jacobians: Vec<[f32; 8]>,
    /// The evaluation at the accepted state while a trial is evaluated.
    saved: (Vec<f32>, Vec<[f32; 8]>),
}

impl LevelProblem<8> for Se3Level<'_> {
    type State = Se3State;

    fn evaluate(&mut self, s: &Se3State) -> usize {
        let rot = s
            .pose
            .rotation
            .to_rotation_matrix()
            .into_inner()
            .cast::<f32>();
        let t = s.pose.translation.vector.cast::<f32>();
        let (a, b) = (s.a as f32, s.b as f32);
        let r = self.reference;
        let [fx, fy, cx, cy] = r.k;
        let (w, h) = self.size;
        let image = self.image;
        let n = r.x.len();
        self.residuals.resize(n, f32::NAN);
        self.jacobians.resize(n, [0.0; 8]);
        // Fills one chunk starting at reference pixel `start`; returns its valid residuals.
        let fill = |start: usize, res: &mut [f32], jac: &mut [[f32; 8]]| {
            let end = start + res.len();
            let points = r.x[start..end]
                .iter()
                .zip(&r.y[start..end])
                .zip(&r.z[start..end])
                .zip(&r.value[start..end]);
            let mut valid = 0;
            for ((o, j), (((&x, &y), &z), &reference)) in res.iter_mut().zip(jac).zip(points) {
                let p = rot * Vector3::new(x, y, z) + t;
                *o = f32::NAN;
                if p.z <= 1e-3 {
                    continue;
                }
                let iz = 1.0 / p.z;
                let u = fx * p.x * iz + cx;
                let v = fy * p.y * iz + cy;
                // Stay one pixel inside, where the gradients are defined.
                if !(u >= 1.0 && v >= 1.0 && u <= (w - 2) as f32 && v <= (h - 2) as f32) {
                    continue;
                }
                let [value, dx, dy] = sample_with_gradient(image, w, h, u, v);
                let resid = value - a * reference - b;
                if !(resid.is_finite() && dx.is_finite() && dy.is_finite()) {
                    continue;
                }
                let ax = dx * fx * iz;
                let ay = dy * fy * iz;
                let az = -(ax * p.x + ay * p.y) * iz;
                *j = [
                    ax,
                    ay,
                    az,
                    p.y * az - p.z * ay,
                    p.z * ax - p.x * az,
                    p.x * ay - p.y * ax,
                    -reference,
                    -1.0,
                ];
                *o = resid;
                valid += 1;
            }
            valid
        };
        if n <= SERIAL_MAX_SE3 {
            self.residuals
                .chunks_mut(CHUNK)
                .zip(self.jacobians.chunks_mut(CHUNK))
                .enumerate()
                .map(|(c, (res, jac))| fill(c * CHUNK, res, jac))
                .sum()
        } else {
            self.residuals
                .par_chunks_mut(CHUNK)
                .zip(self.jacobians.par_chunks_mut(CHUNK))
                .enumerate()
                .map(|(c, (res, jac))| fill(c * CHUNK, res, jac))
                .sum()
        }
    }

    fn residuals(&self) -> &[f32] {
        &self.residuals
    }

    fn normal_equations(&self, loss: &Loss, scale: f32) -> NormalEquations<8> {
        accumulate(self.residuals.len(), loss, scale, SERIAL_MAX_SE3, |i| {
            let r = self.residuals[i];
            (!r.is_nan()).then(|| {
                let j = SVector::<f64, 8>::from(self.jacobians[i].map(f64::from));
                (j, f64::from(r))
            })
        })
    }

    fn save(&mut self) {
        std::mem::swap(&mut self.residuals, &mut self.saved.0);
        std::mem::swap(&mut self.jacobians, &mut self.saved.1);
    }

    fn restore(&mut self, _state: &Se3State) {
        self.save();
    }

    fn retract(&self, s: &Se3State, delta: &SVector<f64, 8>) -> Se3State {
        let xi = delta.fixed_rows::<6>(0).into_owned();
        Se3State {
            pose: retract_left(&s.pose, &xi),
            a: s.a + delta[6],
            b: s.b + delta[7],
        }
    }
}

/// SE(3) direct alignment of `current` to `reference` from `prior` (`T_cur_ref`); see the
/// module documentation. Prepare an [`Se3Reference`] once to align several images to it.
///
/// ```
/// use nalgebra::{Isometry3, Translation3, UnitQuaternion};
/// use vofront_direct::{align_se3, Plane, RgbdFrame, Se3Config};
/// use vofront_geometry::{Camera, Pinhole};
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
///     Plane::new(80, 60, data).unwrap()
/// };
/// let depth = Plane::filled(80, 60, 2.0);
/// let reference = RgbdFrame::new(wall(0.0), depth, &cam).unwrap();
/// let fit = align_se3(&reference, &wall(0.02), &Isometry3::identity(), &Se3Config::default()).unwrap();
/// // The camera moved by +2 cm in x, so reference points move by -2 cm in the current frame.
/// assert!((fit.pose.translation.x + 0.02).abs() < 1e-3, "{}", fit.pose.translation.x);
/// ```
pub fn align_se3(
    reference: &RgbdFrame,
    current: &Plane,
    prior: &Isometry3<f64>,
    cfg: &Se3Config,
) -> Result<Se3Result, DirectError> {
    Se3Reference::new(reference, cfg)?.align(current, prior, cfg)
}

/// `|I_cur(w(p, T)) - a I_ref(p) - b|` for every reference pixel (pinhole geometry of
/// `reference`), NaN where the depth is invalid or the warp leaves the current image.
pub fn photometric_residual_map(
    reference: &RgbdFrame,
    current: &Plane,
    pose: &Isometry3<f64>,
    a: f64,
    b: f64,
) -> Result<Plane, DirectError> {
    let current = reference.prepare_current(current)?;
    let (w, h) = current.size();
    let k = reference.pinhole;
    let rot = pose
        .rotation
        .to_rotation_matrix()
        .into_inner()
        .cast::<f32>();
    let t = pose.translation.vector.cast::<f32>();
    let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
    let mut out = Plane::filled(w, h, f32::NAN);
    out.data.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let z = reference.depth.at(x, y);
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
                let r = tap.apply(&current.data) - a as f32 * reference.image.at(x, y) - b as f32;
                *o = r.abs();
            }
        }
    });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Float tolerance: the same products summed in a different order.
    const TOLERANCE: f32 = 1e-3;

    #[test]
    fn on_the_fly_gradient_matches_interpolated_gradient_planes() {
        let (w, h) = (23, 17);
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                100.0 + 40.0 * (0.7 * x).sin() * (0.45 * y).cos() + 3.0 * x - 2.0 * y
            })
            .collect();
        let img = Plane::new(w, h, data).expect("valid plane");
        let g = img.gradients();
        // Interior points, the lowest and highest allowed coordinates included.
        let (hi_u, hi_v) = ((w - 2) as f32, (h - 2) as f32);
        let mut points = vec![(1.0, 1.0), (hi_u, hi_v), (hi_u, 1.0), (1.0, hi_v)];
        points.extend((0..50).map(|k| {
            let t = k as f32 / 49.0;
            (1.0 + t * (hi_u - 1.0), 1.0 + (1.0 - t * t) * (hi_v - 1.0))
        }));
        for (u, v) in points {
            let [value, gx, gy] = sample_with_gradient(&img.data, w, h, u, v);
            let expected = [
                img.sample(u, v).expect("inside"),
                g.gx.sample(u, v).expect("inside"),
                g.gy.sample(u, v).expect("inside"),
            ];
            for (got, want) in [value, gx, gy].into_iter().zip(expected) {
                assert!(
                    (got - want).abs() < TOLERANCE,
                    "({u}, {v}): {got} vs {want}"
                );
            }
        }
    }
}
