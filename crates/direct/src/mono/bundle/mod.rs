//! The windowed photometric bundle adjustment of the direct monocular tracker (DSO's
//! windowed optimisation, without marginalisation): keyframe poses, per-frame affine
//! brightness and the inverse depths of the points are refined jointly.
//!
//! Frames `i` carry `T_i = T_cw` and a brightness `(a_i, b_i)`: a scene radiance `L` is seen
//! as `I_i = exp(a_i) L + b_i`. A point `j` is hosted in frame `h` at pixel `x` with inverse
//! depth `rho`. For each pattern pixel `x_k = x + o_k` ([`PATTERN`]) with bearing
//! `f_k = K^-1 (x_k, 1)` and each other frame `t` that sees it:
//!
//! ```text
//! X_t = R_th f_k / rho + t_th,            T_th = T_t T_h^-1
//! r   = I_t(pi(X_t)) - exp(a_t - a_h) (I_h(x_k) - b_h) - b_t      grey levels
//! ```
//!
//! With `g = grad I_t . d pi / d X` (1 x 3, at `X_t`), `e = exp(a_t - a_h)` and
//! `c = I_h(x_k) - b_h`, for left increments `T <- exp(delta) T` (`delta` = translation,
//! rotation):
//!
//! ```text
//! dr/d delta_t = g [I | -hat(X_t)]          dr/d a_t = -e c     dr/d b_t = -1
//! dr/d delta_h = -g R_th [I | -hat(X_h)]    dr/d a_h =  e c     dr/d b_h = e
//! dr/d rho     = -g R_th f_k / rho^2        (X_h = f_k / rho)
//! ```
//!
//! Each residual is weighted by the Huber loss at `huber` grey levels; the cost is
//! `sum s^2 rho(r / s)` ([`vofront_robust::levenberg_marquardt`] on a
//! [`vofront_robust::SchurSystem`] with 8 parameters per free frame, one per point, and the
//! host-target pose pairs off the diagonal). The first `fixed` frames (pose and brightness)
//! fix the gauge: with two of them, seven degrees of freedom of a monocular map (pose and
//! scale) are held. A frame that sees no point is held too.
//!
//! Gain and offset trade against each other where the points' grey levels vary little, so
//! each free frame's brightness has a Gaussian prior at its starting value (the tracker's
//! alignment measures it): `((a - a_0) / sigma_a)^2 + ((b - b_0) / sigma_b)^2` in the units
//! of a squared grey level, added to the cost's `r^2 / 2` terms as `/ 2`.
//!
//! Which residuals take part is decided once, at the starting state: an observation (a point
//! in a frame) whose pattern stays inside the frame with a root-mean-square residual of at
//! most `max_start_rmse`. After the optimisation each observed point's root-mean-square
//! residual over its observations says whether it is an outlier (over `max_point_rmse`); a
//! point without observations is not judged.

mod blocks;
mod problem;

use nalgebra::{Isometry3, Vector2, Vector3};
use vofront_core::Pinhole;
use vofront_image::Image;
use vofront_robust::{levenberg_marquardt, Convergence, Damping, LmConfig, LmError, LmProblem};

use super::epipolar::PATTERN;
use crate::error::DirectError;
use problem::{BundleState, Observation, Photometric};

/// A frame of the window: its grey image in the pinhole geometry, pose and brightness.
#[derive(Debug, Clone, Copy)]
pub struct BundleFrame<'a> {
    /// Grey levels.
    pub image: &'a Image<f32>,
    /// The frame's state.
    pub state: FrameState,
}

/// Pose and affine brightness of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameState {
    /// `T_cw`: world points into the camera frame.
    pub t_cw: Isometry3<f64>,
    /// Log gain `a`: `I = exp(a) L + b`.
    pub a: f64,
    /// Offset `b`, grey levels.
    pub b: f64,
}

/// A point hosted by a frame of the window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BundlePoint {
    /// Index of the host frame.
    pub host: usize,
    /// Pixel in the host frame.
    pub pixel: Vector2<f32>,
    /// Inverse depth in the host frame, 1 / map units.
    pub rho: f64,
}

/// Settings of [`photometric_bundle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BundleConfig {
    /// The first `fixed` frames are held (the gauge; 2 for a monocular map).
    pub fixed: usize,
    /// Huber threshold of a pixel residual, grey levels.
    pub huber: f64,
    /// An observation joins when its pattern's RMS residual at the start is at most this,
    /// grey levels.
    pub max_start_rmse: f64,
    /// A point whose RMS residual over its observations ends above this is an outlier, grey
    /// levels.
    pub max_point_rmse: f64,
    /// Pattern pixels kept this far from the image border, pixels.
    pub border: f32,
    /// Prior standard deviation of a free frame's log gain `a` around its start.
    pub sigma_a: f64,
    /// Prior standard deviation of a free frame's offset `b` around its start, grey levels.
    pub sigma_b: f64,
    /// Levenberg-Marquardt iterations.
    pub max_iterations: usize,
}

impl Default for BundleConfig {
    /// Two frames held, Huber at 9 grey levels (DSO's), observations within 20 grey levels
    /// at the start, outliers above 15 at the end, 4 pixels from the border, brightness
    /// priors of 0.01 (log gain) and 1 grey level, 10 iterations.
    fn default() -> Self {
        Self {
            fixed: 2,
            huber: 9.0,
            max_start_rmse: 20.0,
            max_point_rmse: 15.0,
            border: 4.0,
            sigma_a: 0.01,
            sigma_b: 1.0,
            max_iterations: 10,
        }
    }
}

/// The refined window.
#[derive(Debug, Clone, PartialEq)]
pub struct BundleResult {
    /// Every frame's state (held frames as given).
    pub frames: Vec<FrameState>,
    /// Every point's inverse depth (unchanged for a point without observations).
    pub rhos: Vec<f64>,
    /// Per point: RMS residual over its observations at the end, grey levels (NaN without any).
    pub point_rmse: Vec<f64>,
    /// Per point: true when it is an outlier (observed, and over `max_point_rmse`).
    pub outlier: Vec<bool>,
    /// Observations that took part.
    pub observations: usize,
    /// RMS residual over the observations at the start and at the end, grey levels.
    pub rmse: (f64, f64),
    /// Iterations run.
    pub iterations: usize,
    /// Why the optimisation stopped.
    pub reason: Convergence,
}

/// The pattern's bearings `K^-1 (x_k, 1)` and host grey levels around `pixel`; `None` when a
/// pattern pixel is outside the host image.
fn host_pattern(
    image: &Image<f32>,
    k: &Pinhole,
    pixel: Vector2<f32>,
) -> Option<([Vector3<f64>; 8], [f64; 8])> {
    let samples = image.sample_pattern(pixel.x, pixel.y, &PATTERN)?;
    let mut bearings = [Vector3::zeros(); 8];
    let mut grey = [0.0; 8];
    for (((b, g), &(dx, dy)), &s) in bearings
        .iter_mut()
        .zip(grey.iter_mut())
        .zip(&PATTERN)
        .zip(&samples)
    {
        let (x, y) = (pixel.x + dx as f32, pixel.y + dy as f32);
        *g = f64::from(s);
        *b = Vector3::new(
            (f64::from(x) - k.cx) / k.fx,
            (f64::from(y) - k.cy) / k.fy,
            1.0,
        );
    }
    Some((bearings, grey))
}

/// Refines the window's free frames and the points' inverse depths (module documentation).
///
/// Errors: [`DirectError::InvalidConfig`] for a point whose host is not a frame, a
/// non-positive inverse depth or a non-positive threshold; [`DirectError::NotFinite`] for a
/// non-finite input; [`DirectError::SizeMismatch`] for frames of different sizes;
/// [`DirectError::Solve`] when the normal equations are degenerate.
pub fn photometric_bundle(
    pinhole: &Pinhole,
    frames: &[BundleFrame],
    points: &[BundlePoint],
    cfg: &BundleConfig,
) -> Result<BundleResult, DirectError> {
    let positive = [
        cfg.huber,
        cfg.max_start_rmse,
        cfg.max_point_rmse,
        cfg.sigma_a,
        cfg.sigma_b,
    ];
    if !positive.iter().all(|v| *v > 0.0) {
        return Err(DirectError::InvalidConfig(
            "huber, max_start_rmse, max_point_rmse and the brightness sigmas must be positive",
        ));
    }
    if points.iter().any(|p| p.host >= frames.len()) {
        return Err(DirectError::InvalidConfig("a point's host is not a frame"));
    }
    let finite_frame = |f: &BundleFrame| {
        f.state.a.is_finite()
            && f.state.b.is_finite()
            && f.state
                .t_cw
                .translation
                .vector
                .iter()
                .all(|v| v.is_finite())
            && f.state.t_cw.rotation.coords.iter().all(|v| v.is_finite())
    };
    let finite_point = |p: &BundlePoint| p.rho.is_finite() && p.pixel.iter().all(|v| v.is_finite());
    if !frames.iter().all(finite_frame) || !points.iter().all(finite_point) {
        return Err(DirectError::NotFinite);
    }
    if points.iter().any(|p| p.rho <= 0.0) {
        return Err(DirectError::InvalidConfig(
            "inverse depths must be positive",
        ));
    }
    if let Some(first) = frames.first() {
        let size = first.image.size();
        if let Some(f) = frames.iter().find(|f| f.image.size() != size) {
            return Err(DirectError::SizeMismatch {
                expected: size,
                found: f.image.size(),
            });
        }
    }
    let patterns: Vec<_> = points
        .iter()
        .map(|p| host_pattern(frames[p.host].image, pinhole, p.pixel))
        .collect();
    let state = BundleState {
        frames: frames.iter().map(|f| f.state).collect(),
        rhos: points.iter().map(|p| p.rho).collect(),
    };
    let mut problem = Photometric::new(pinhole, frames, points, &patterns, cfg);
    let candidates: Vec<Observation> = (0..points.len())
        .filter(|&j| patterns[j].is_some())
        .flat_map(|j| {
            (0..frames.len())
                .filter(move |&t| t != points[j].host)
                .map(move |t| Observation {
                    point: j,
                    target: t,
                })
        })
        .collect();
    let observations = problem.admit(&state, candidates);
    // `admit` leaves the evaluation at the start.
    let before = problem.rmse();
    let lm = LmConfig {
        max_iterations: cfg.max_iterations,
        damping: Damping::Diagonal,
        min_relative_decrease: 1e-6,
        ..LmConfig::default()
    };
    let (state, iterations, reason) = if observations == 0 {
        (state, 0, Convergence::SmallStep)
    } else {
        match levenberg_marquardt(&mut problem, state.clone(), &lm) {
            Ok(out) => (out.state, out.iterations, out.reason),
            Err(LmError::Solve(e)) => return Err(DirectError::Solve(e)),
            Err(LmError::TooFewResiduals { rows, required }) => {
                return Err(DirectError::TooFewValid {
                    valid: rows,
                    required,
                })
            }
        }
    };
    problem.evaluate(&state);
    let point_rmse = problem.point_rmse();
    let outlier = point_rmse.iter().map(|r| *r > cfg.max_point_rmse).collect();
    Ok(BundleResult {
        rmse: (before, problem.rmse()),
        frames: state.frames,
        rhos: state.rhos,
        point_rmse,
        outlier,
        observations,
        iterations,
        reason,
    })
}

#[cfg(test)]
mod tests;
