//! Coarse-to-fine robust Lucas-Kanade for 2D warps: translation, affine and homography, each
//! optionally with an affine brightness change.
//!
//! Model: a warp `W` maps pixel `x` of image 1 to its position in image 2 and
//! `I2(W(x)) = a I1(x) + b`. `W` is kept as a 3x3 matrix `H` (`x' ~ H (x, y, 1)`). The residual
//! of reference pixel `x` is `r = I2(W(x)) - a I1(x) - b`, over the pixels of image 1 whose
//! gradient magnitude is at least `gradient_threshold` (the others carry no information and
//! only add noise).
//!
//! Update (inverse-compositional style): `H <- H H(delta)` with `H(delta) = I + P(delta)`, whose
//! Jacobian at `delta = 0` uses the gradient of the *reference*, `d r / d delta =
//! a grad I1(x) dW/d delta (x)` (valid at convergence, where `I2 o W = a I1 + b`), computed once
//! per level; `d r / d a = -I1(x)`, `d r / d b = -1`. For translation a forward-additive variant
//! samples `grad I2` at `x + d` instead (exact Jacobian; value and gradient interpolated
//! together from the 4x4 neighbourhood in `I2`, no gradient images, so the pixels within one
//! pixel of the border are invalid). Steps are damped Gauss-Newton on Huber (by default) IRLS
//! weights (module `lm`).
//!
//! Across pyramid levels the warp is rescaled, `H_l = D H_0 D^-1`, `D = diag(2^-l, 2^-l, 1)`.

use nalgebra::{DMatrix, Matrix3, SVector};
use rayon::prelude::*;
use vofront_image::Image;
use vofront_robust::{Convergence, Loss, NormalEquations, QualityConfig};

use crate::error::DirectError;
use crate::lm::{accumulate, run_level, LevelProblem, LmSettings, CHUNK, SERIAL_MAX};
use crate::plane::{interpolate_with_gradient, Bilinear, Pyramid};
use crate::quality::warp_quality;

mod result;
mod select;

pub(crate) use result::Fit2d;
pub use result::WarpResult;

use select::{maps_inside, RefPixels};

/// Smallest side of the coarsest pyramid level, pixels.
const MIN_LEVEL_SIDE: usize = 16;
/// A level's reference pixels are those its starting warp maps at least this far (pixels of
/// the level) inside image 2. The set is then fixed for the level: the cost that the LM loop
/// compares between steps is a mean over the same pixels, and a step cannot lower it by
/// pushing badly fitting pixels out of the image (which biased warps near the border, e.g.
/// by 0.025 px on a 4 px shift). The steps within a level stay below this after the coarser
/// levels' start.
const LEVEL_MARGIN_PX: f64 = 2.0;
/// Reference pixels needed per parameter for a level to be used.
const PIXELS_PER_PARAMETER: usize = 8;
/// Coarse levels keep at least this many pixels (when that many qualify), whatever their
/// share of [`WarpConfig::max_pixels`]: they must still find the warp reliably.
const MIN_LEVEL_PIXELS: usize = 2000;

/// The family of 2D warps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WarpKind {
    /// `x' = x + d` (2 parameters).
    Translation,
    /// `x' = A x + t` (6 parameters).
    Affine,
    /// `x' ~ H x` with `H[2][2] = 1` (8 parameters).
    Homography,
}

impl WarpKind {
    /// Number of geometric parameters.
    pub fn parameters(self) -> usize {
        match self {
            WarpKind::Translation => 2,
            WarpKind::Affine => 6,
            WarpKind::Homography => 8,
        }
    }
}

/// How the Jacobian of a translation is formed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TranslationMethod {
    /// Reference gradients computed once per level (the faster one, and equally accurate).
    #[default]
    InverseCompositional,
    /// Gradients of image 2 sampled at `x + d` every iteration.
    ForwardAdditive,
}

/// Settings shared by every 2D aligner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarpConfig {
    /// Pyramid levels as factor-2 octaves (each level half the size of the one below; ORB's 1.2-ratio levels are
    /// `OrbConfig::scale_levels`), fewer when the image is small, at least 1.
    pub levels: usize,
    /// Iteration limit per level.
    pub max_iterations: usize,
    /// Stop when the step moves any image corner by less than this many pixels.
    pub min_step: f64,
    /// Stop when an accepted step lowers the mean robust cost by less than this fraction.
    pub min_relative_decrease: f64,
    /// Reference pixels with `|grad I1| <` this (grey levels per pixel) are not used.
    pub gradient_threshold: f32,
    /// At most about this many reference pixels at full resolution (the largest gradients are
    /// kept; 0 = no limit); level `l` keeps at most `max_pixels / 4^l`, the same density, but
    /// not fewer than 2000 (when that many qualify).
    pub max_pixels: usize,
    /// Robust loss on residuals in sigmas.
    pub loss: Loss,
    /// Floor of the robust residual scale, grey levels.
    pub min_sigma: f32,
    /// Estimate the brightness change `(a, b)` jointly; otherwise `a = 1`, `b = 0`.
    pub affine_brightness: bool,
    /// Largest acceptable Jacobi-scaled condition number of the normal equations.
    pub max_condition: f64,
    /// Blur both images with [`Image<f32>::blur`] (sigma 1 pixel) first: the bilinear interpolant
    /// and the central-difference gradients then agree, which removes a bias of a few
    /// hundredths of a pixel on sharp real images.
    pub presmooth: bool,
    /// Thresholds of the result's [`WarpResult::quality`] verdict.
    pub quality: QualityConfig,
}

impl Default for WarpConfig {
    fn default() -> Self {
        Self {
            levels: 4,
            max_iterations: 50,
            min_step: 1e-3,
            min_relative_decrease: 1e-7,
            gradient_threshold: 2.0,
            max_pixels: 60_000,
            loss: Loss::Huber(1.345),
            min_sigma: 0.5,
            affine_brightness: false,
            max_condition: 1e12,
            presmooth: true,
            quality: QualityConfig::default(),
        }
    }
}

/// Warp and brightness.
#[derive(Debug, Clone, Copy)]
pub(crate) struct State2d {
    h: Matrix3<f64>,
    a: f64,
    b: f64,
}

/// `I + P(delta)` for the geometric part of `delta`.
fn increment(kind: WarpKind, d: &[f64]) -> Matrix3<f64> {
    match kind {
        WarpKind::Translation => Matrix3::new(1.0, 0.0, d[0], 0.0, 1.0, d[1], 0.0, 0.0, 1.0),
        WarpKind::Affine => Matrix3::new(
            1.0 + d[0],
            d[1],
            d[2],
            d[3],
            1.0 + d[4],
            d[5],
            0.0,
            0.0,
            1.0,
        ),
        WarpKind::Homography => Matrix3::new(
            1.0 + d[0],
            d[1],
            d[2],
            d[3],
            1.0 + d[4],
            d[5],
            d[6],
            d[7],
            1.0,
        ),
    }
}

/// `a grad I dW/d delta` at `(x, y)` for the warp kind, then `-I1` and `-1`.
#[inline]
fn jacobian_row<const M: usize>(
    kind: WarpKind,
    x: f32,
    y: f32,
    gx: f32,
    gy: f32,
    value: f32,
) -> SVector<f64, M> {
    let (x, y, gx, gy) = (f64::from(x), f64::from(y), f64::from(gx), f64::from(gy));
    let mut j = SVector::<f64, M>::zeros();
    match kind {
        WarpKind::Translation => {
            j[0] = gx;
            j[1] = gy;
        }
        WarpKind::Affine | WarpKind::Homography => {
            j[0] = gx * x;
            j[1] = gx * y;
            j[2] = gx;
            j[3] = gy * x;
            j[4] = gy * y;
            j[5] = gy;
            if kind == WarpKind::Homography {
                let s = gx * x + gy * y;
                j[6] = -s * x;
                j[7] = -s * y;
            }
        }
    }
    j[M - 2] = -f64::from(value);
    j[M - 1] = -1.0;
    j
}

/// One pyramid level of a 2D alignment problem.
struct Level2d<'a> {
    kind: WarpKind,
    reference: &'a RefPixels,
    target: &'a Image<f32>,
    /// Forward-additive translation: the Jacobian from the target's gradients at the warped
    /// pixels, interpolated from the target's values (no gradient images).
    forward: bool,
    residuals: Vec<f32>,
    /// Target gradients sampled at the warped pixels (forward-additive only).
    sampled_gx: Vec<f32>,
    sampled_gy: Vec<f32>,
    /// Brightness gain at the last evaluation.
    gain: f32,
}

impl<const M: usize> LevelProblem<M> for Level2d<'_> {
    type State = State2d;

    fn evaluate(&mut self, s: &State2d) -> usize {
        let h = s.h.cast::<f32>();
        let (a, b) = (s.a as f32, s.b as f32);
        self.gain = a;
        let (w, hgt) = self.target.size();
        let img = self.target.data();
        let r = self.reference;
        let n = r.len();
        let taps = WarpTaps::new(&h, self.kind == WarpKind::Translation, w, hgt);
        let warp = move |i: usize| taps.at(r.x[i], r.y[i]);
        self.residuals.resize(n, f32::NAN);
        let serial = n <= SERIAL_MAX;
        if !self.forward {
            // Fills the chunk of residuals starting at reference pixel `start`.
            let fill = |start: usize, out: &mut [f32]| {
                for (i, o) in (start..).zip(out.iter_mut()) {
                    *o = warp(i).map_or(f32::NAN, |t| t.apply(img) - a * r.value[i] - b);
                }
            };
            if serial {
                fill(0, &mut self.residuals);
            } else {
                self.residuals
                    .par_chunks_mut(CHUNK)
                    .enumerate()
                    .for_each(|(c, out)| fill(c * CHUNK, out));
            }
        } else {
            let (_, _, fx, fy) = taps.shift.expect("forward-additive is a translation");
            self.sampled_gx.resize(n, 0.0);
            self.sampled_gy.resize(n, 0.0);
            // Fills residuals and sampled target gradients from reference pixel `start`; the
            // pixels whose taps touch the border, where the gradients are undefined, are invalid.
            let fill = |start: usize, out: &mut [f32], ogx: &mut [f32], ogy: &mut [f32]| {
                for (k, i) in (start..start + out.len()).enumerate() {
                    out[k] = match taps.top_left(r.x[i], r.y[i], 1) {
                        Some((x0, y0)) => {
                            let [value, gx, gy] = interpolate_with_gradient(img, w, x0, y0, fx, fy);
                            (ogx[k], ogy[k]) = (gx, gy);
                            value - a * r.value[i] - b
                        }
                        None => f32::NAN,
                    };
                }
            };
            if serial {
                fill(
                    0,
                    &mut self.residuals,
                    &mut self.sampled_gx,
                    &mut self.sampled_gy,
                );
            } else {
                self.residuals
                    .par_chunks_mut(CHUNK)
                    .zip(self.sampled_gx.par_chunks_mut(CHUNK))
                    .zip(self.sampled_gy.par_chunks_mut(CHUNK))
                    .enumerate()
                    .for_each(|(c, ((out, ogx), ogy))| fill(c * CHUNK, out, ogx, ogy));
            }
        }
        self.residuals.iter().filter(|v| !v.is_nan()).count()
    }

    fn residuals(&self) -> &[f32] {
        &self.residuals
    }

    fn normal_equations(&self, loss: &Loss, scale: f32) -> NormalEquations<M> {
        let r = self.reference;
        let forward = self.forward;
        accumulate(r.len(), loss, scale, SERIAL_MAX, |i| {
            let res = self.residuals[i];
            if res.is_nan() {
                return None;
            }
            let (gx, gy) = if forward {
                (self.sampled_gx[i], self.sampled_gy[i])
            } else {
                (self.gain * r.gx[i], self.gain * r.gy[i])
            };
            let j = jacobian_row::<M>(self.kind, r.x[i], r.y[i], gx, gy, r.value[i]);
            Some((j, f64::from(res)))
        })
    }

    fn retract(&self, s: &State2d, delta: &SVector<f64, M>) -> State2d {
        State2d {
            h: s.h * increment(self.kind, delta.as_slice()),
            a: s.a + delta[M - 2],
            b: s.b + delta[M - 1],
        }
    }
}

/// Bilinear taps of warped reference pixels in a `w x h` target image.
#[derive(Debug, Clone, Copy)]
struct WarpTaps {
    h: Matrix3<f32>,
    /// For a pure translation `t`: `floor(t)` and the fraction `t - floor(t)`, shared by every
    /// pixel (`floor(x + t) = x + floor(t)` for integer `x`), so no per-pixel division or floor.
    shift: Option<(isize, isize, f32, f32)>,
    w: usize,
    h_px: usize,
}

impl WarpTaps {
    fn new(h: &Matrix3<f32>, translation: bool, w: usize, h_px: usize) -> Self {
        let shift = translation.then(|| {
            let (tx, ty) = (h[(0, 2)].floor(), h[(1, 2)].floor());
            (tx as isize, ty as isize, h[(0, 2)] - tx, h[(1, 2)] - ty)
        });
        Self {
            h: *h,
            shift,
            w,
            h_px,
        }
    }

    /// For a translation `t`: the top-left tap `(x0, y0)` of `(x, y) + t`; `None` unless the
    /// four taps are at least `border` pixels inside the image (and for the other warps).
    #[inline(always)]
    fn top_left(&self, x: f32, y: f32, border: isize) -> Option<(usize, usize)> {
        let (ox, oy, _, _) = self.shift?;
        let (xi, yi) = (x as isize + ox, y as isize + oy);
        let (w, h) = (self.w as isize, self.h_px as isize);
        let inside = xi >= border && yi >= border && xi + 1 + border < w && yi + 1 + border < h;
        inside.then_some((xi as usize, yi as usize))
    }

    /// Taps at `H (x, y, 1)`; `None` outside the image.
    #[inline(always)]
    fn at(&self, x: f32, y: f32) -> Option<Bilinear> {
        let (w, h_px, h) = (self.w, self.h_px, &self.h);
        if let Some((_, _, fx, fy)) = self.shift {
            return self.top_left(x, y, 0).map(|(x0, y0)| Bilinear {
                index: y0 * w + x0,
                stride: w,
                fx,
                fy,
            });
        }
        let z = h[(2, 0)] * x + h[(2, 1)] * y + h[(2, 2)];
        let u = (h[(0, 0)] * x + h[(0, 1)] * y + h[(0, 2)]) / z;
        let v = (h[(1, 0)] * x + h[(1, 1)] * y + h[(1, 2)]) / z;
        Bilinear::new(u, v, w, h_px)
    }
}

/// The pixel budget of pyramid level `level`; see [`WarpConfig::max_pixels`].
fn level_budget(cfg: &WarpConfig, level: usize) -> usize {
    if cfg.max_pixels == 0 {
        return 0;
    }
    let scaled = cfg.max_pixels.checked_shr(2 * level as u32).unwrap_or(0);
    scaled.max(MIN_LEVEL_PIXELS.min(cfg.max_pixels))
}

/// `D H D^-1` with `D = diag(f, f, 1)`: the same warp in coordinates scaled by `f`.
fn rescale(h: &Matrix3<f64>, f: f64) -> Matrix3<f64> {
    let d = Matrix3::new(f, 0.0, 0.0, 0.0, f, 0.0, 0.0, 0.0, 1.0);
    let d_inv = Matrix3::new(1.0 / f, 0.0, 0.0, 0.0, 1.0 / f, 0.0, 0.0, 0.0, 1.0);
    d * h * d_inv
}

/// Coarse-to-fine robust alignment of `img2` to `img1` for `kind` with `M = k + 2` parameters.
pub(crate) fn align_2d<const M: usize>(
    kind: WarpKind,
    img1: &Image<f32>,
    img2: &Image<f32>,
    initial: &Matrix3<f64>,
    cfg: &WarpConfig,
    forward_additive: bool,
) -> Result<Fit2d, DirectError> {
    debug_assert_eq!(M, kind.parameters() + 2);
    debug_assert!(!forward_additive || kind == WarpKind::Translation);
    img1.check_same_size(img2)?;
    img1.check_min_size(MIN_LEVEL_SIDE)?;
    if cfg.levels == 0
        || cfg.max_iterations == 0
        || cfg.gradient_threshold.is_nan()
        || cfg.gradient_threshold < 0.0
    {
        return Err(DirectError::InvalidConfig(
            "levels and max_iterations must be positive, gradient_threshold non-negative",
        ));
    }
    if initial.iter().any(|v| !v.is_finite()) || initial[(2, 2)].abs() < 1e-12 {
        return Err(DirectError::NotFinite);
    }
    if img1
        .data()
        .iter()
        .chain(img2.data())
        .any(|v| !v.is_finite())
    {
        return Err(DirectError::NotFinite);
    }
    let (base1, base2) = if cfg.presmooth {
        rayon::join(|| img1.blur(), || img2.blur())
    } else {
        (img1.clone(), img2.clone())
    };
    let (pyr1, pyr2) = rayon::join(
        || Pyramid::new(base1, cfg.levels, MIN_LEVEL_SIDE),
        || Pyramid::new(base2, cfg.levels, MIN_LEVEL_SIDE),
    );
    let levels = pyr1.levels.len();
    let min_pixels = PIXELS_PER_PARAMETER * M;
    let k = kind.parameters();
    let mut fixed = [false; M];
    fixed[M - 2] = !cfg.affine_brightness;
    fixed[M - 1] = !cfg.affine_brightness;

    let initial = initial / initial[(2, 2)];
    let top = levels - 1;
    let mut state = State2d {
        h: rescale(&initial, 0.5f64.powi(top as i32)),
        a: 1.0,
        b: 0.0,
    };
    let mut iterations = vec![0; levels];
    let mut last = None;
    for level in (0..levels).rev() {
        let (p1, p2) = (&pyr1.levels[level], &pyr2.levels[level]);
        let reference = RefPixels::select(
            p1,
            cfg.gradient_threshold,
            level_budget(cfg, level),
            maps_inside(&state.h, p2.width(), p2.height(), LEVEL_MARGIN_PX),
        );
        if reference.len() < min_pixels {
            if level == 0 {
                return Err(DirectError::NoTexture {
                    pixels: reference.len(),
                    required: min_pixels,
                });
            }
            state.h = rescale(&state.h, 2.0);
            continue;
        }
        let mut problem = Level2d {
            kind,
            reference: &reference,
            target: p2,
            forward: forward_additive,
            residuals: Vec::new(),
            sampled_gx: Vec::new(),
            sampled_gy: Vec::new(),
            gain: 1.0,
        };
        let radius = p1.width().max(p1.height()) as f64 / 2.0;
        let mut step_weights = SVector::<f64, M>::repeat(1.0);
        if kind != WarpKind::Translation {
            for i in [0, 1, 3, 4] {
                step_weights[i] = radius;
            }
        }
        if kind == WarpKind::Homography {
            step_weights[6] = radius * radius;
            step_weights[7] = radius * radius;
        }
        step_weights[M - 2] = 0.0;
        step_weights[M - 1] = 0.0;
        let settings = LmSettings {
            loss: cfg.loss,
            min_sigma: cfg.min_sigma,
            max_iterations: cfg.max_iterations,
            min_step: cfg.min_step,
            min_step_sigmas: 0.0,
            step_weights,
            min_relative_decrease: cfg.min_relative_decrease,
            max_condition: cfg.max_condition,
            fixed,
            min_valid: min_pixels,
            serial_max: SERIAL_MAX,
        };
        let out = run_level(&mut problem, state, &settings)?;
        iterations[level] = out.iterations;
        state = out.state;
        if level > 0 {
            state.h = rescale(&state.h, 2.0);
        } else {
            let res = LevelProblem::<M>::residuals(&problem);
            let sum_sq: f64 = res
                .iter()
                .filter(|r| !r.is_nan())
                .map(|&r| f64::from(r) * f64::from(r))
                .sum();
            let rmse = (sum_sq / out.valid.max(1) as f64).sqrt();
            last = Some((out, rmse));
        }
    }
    let (out, rmse) = last.expect("level 0 is always run or returns an error");
    let cov = out.system.covariance(cfg.max_condition);
    Ok(Fit2d {
        h: state.h / state.h[(2, 2)],
        a: state.a,
        b: state.b,
        iterations,
        rmse,
        used_fraction: out.valid as f64 / (img1.width() * img1.height()) as f64,
        covariance: cov.map(|cov| DMatrix::from_fn(k, k, |r, c| cov[(r, c)])),
        converged: out.reason != Convergence::MaxIterations,
    })
}

/// Affine warp `I2(A x + t) = a I1(x) + b` from the initial guess `initial` (the identity when
/// unknown; its last row must be `0 0 1`).
///
/// ```
/// use nalgebra::Matrix3;
/// use vofront_direct::{align_affine, WarpConfig};
/// use vofront_image::Image;
/// let img = |dx: f32| {
///     let data = (0..64 * 64)
///         .map(|i| {
///             let (x, y) = ((i % 64) as f32 - dx, (i / 64) as f32);
///             100.0 + 40.0 * (x * 0.3).sin() * (y * 0.25).cos() + 30.0 * ((x + y) * 0.17).sin()
///         })
///         .collect();
///     Image::new(64, 64, data).unwrap()
/// };
/// let fit = align_affine(&img(0.0), &img(0.7), &Matrix3::identity(), &WarpConfig::default()).unwrap();
/// assert!((fit.h[(0, 2)] - 0.7).abs() < 0.05);
/// ```
pub fn align_affine(
    img1: &Image<f32>,
    img2: &Image<f32>,
    initial: &Matrix3<f64>,
    cfg: &WarpConfig,
) -> Result<WarpResult, DirectError> {
    let fit = align_2d::<8>(WarpKind::Affine, img1, img2, initial, cfg, false)?;
    Ok(warp_quality(fit, img1, img2, &cfg.quality))
}

/// Homography `I2(H x) = a I1(x) + b` from the initial guess `initial` (the identity when
/// unknown); `H` is returned with `H[2][2] = 1`.
pub fn align_homography(
    img1: &Image<f32>,
    img2: &Image<f32>,
    initial: &Matrix3<f64>,
    cfg: &WarpConfig,
) -> Result<WarpResult, DirectError> {
    let fit = align_2d::<10>(WarpKind::Homography, img1, img2, initial, cfg, false)?;
    Ok(warp_quality(fit, img1, img2, &cfg.quality))
}
