//! Shi-Tomasi corners and pyramidal Lucas-Kanade (KLT) point tracking.
//!
//! Corners: the structure tensor `G = sum_window [gx^2, gx gy; gx gy, gy^2]` over a 3x3 block,
//! response `lambda_min(G)`, kept when at least `quality` times the strongest response and a
//! 3x3 local maximum, then greedily by decreasing response at least `min_distance` apart.
//!
//! Tracking a point `p` from `I` to `J`: at each pyramid level `l`, from the coarsest, the
//! template `T(w) = I_l(p / 2^l + w)` and its gradients over a `window x window` patch are
//! sampled once, `G = sum grad T grad T^T`, and the position `q` is refined by
//! `q <- q - G^-1 sum grad T (J_l(q + w) - T(w))` until the step is below `epsilon` pixels;
//! the flow is doubled when going one level down. A track fails when `q` leaves the image, when
//! `lambda_min(G) / window^2 < min_eigenvalue` (a flat or edge-only window), or when tracking
//! back from `J` to `I` does not land within `forward_backward` pixels of `p`.

use nalgebra::Vector2;
use rayon::prelude::*;

use crate::error::DirectError;
use crate::plane::{Gradients, Plane, Pyramid};

/// Smallest side of a KLT pyramid level, pixels.
const MIN_LEVEL_SIDE: usize = 8;

/// Settings of [`track_klt`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KltConfig {
    /// Side of the square window, pixels (odd, at least 3).
    pub window: usize,
    /// Pyramid levels including full resolution (OpenCV's `maxLevel + 1`).
    pub levels: usize,
    /// Iteration limit per level.
    pub max_iterations: usize,
    /// Stop when the step is below this, pixels.
    pub epsilon: f32,
    /// Smallest acceptable `lambda_min(G) / window^2`, (grey levels per pixel)^2.
    pub min_eigenvalue: f32,
    /// When set, tracks are checked backwards and rejected beyond this distance, pixels.
    pub forward_backward: Option<f32>,
}

impl Default for KltConfig {
    fn default() -> Self {
        Self {
            window: 21,
            levels: 4,
            max_iterations: 30,
            epsilon: 0.01,
            min_eigenvalue: 1e-3,
            forward_backward: Some(1.0),
        }
    }
}

/// Outcome of one tracked point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackStatus {
    /// Tracked (and consistent backwards when checked).
    Tracked,
    /// The point left the image.
    OutOfBounds,
    /// The window has too little texture in some direction.
    SmallEigenvalue,
    /// Tracking back did not return to the start.
    ForwardBackward,
}

/// A tracked point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KltTrack {
    /// Position in the next image, pixels.
    pub position: Vector2<f32>,
    /// Whether the track is usable.
    pub status: TrackStatus,
    /// Mean absolute residual over the window at the end, grey levels.
    pub error: f32,
}

/// Shi-Tomasi corners of `img`: at most `max_corners`, response at least `quality` times the
/// best, at least `min_distance` pixels apart, strongest first.
///
/// ```
/// use vofront_direct::{good_features_to_track, Plane};
/// let mut img = Plane::filled(40, 40, 0.0);
/// for y in 10..30 {
///     for x in 10..30 {
///         img.data[y * 40 + x] = 200.0;
///     }
/// }
/// let corners = good_features_to_track(&img, 10, 0.1, 5.0);
/// assert_eq!(corners.len(), 4);
/// ```
pub fn good_features_to_track(
    img: &Plane,
    max_corners: usize,
    quality: f32,
    min_distance: f32,
) -> Vec<Vector2<f32>> {
    let (w, h) = img.size();
    if w < 5 || h < 5 || max_corners == 0 {
        return Vec::new();
    }
    let response = min_eigenvalue_map(img);
    let best = response.iter().copied().fold(0.0f32, f32::max);
    if best <= 0.0 || !best.is_finite() {
        return Vec::new();
    }
    let threshold = quality.max(0.0) * best;
    let mut candidates = Vec::new();
    for y in 2..h - 2 {
        for x in 2..w - 2 {
            let v = response[y * w + x];
            if v < threshold || v <= 0.0 {
                continue;
            }
            let is_max =
                (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| response[yy * w + xx] <= v));
            if is_max {
                candidates.push((v, x, y));
            }
        }
    }
    candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
    let cell = min_distance.max(1.0);
    let (gw, gh) = (
        (w as f32 / cell).ceil() as usize,
        (h as f32 / cell).ceil() as usize,
    );
    let mut grid: Vec<Vec<Vector2<f32>>> = vec![Vec::new(); gw * gh];
    let mut out = Vec::new();
    let d2 = min_distance * min_distance;
    for (_, x, y) in candidates {
        let p = Vector2::new(x as f32, y as f32);
        let (cx, cy) = ((p.x / cell) as usize, (p.y / cell) as usize);
        let near = (cy.saturating_sub(1)..(cy + 2).min(gh)).any(|gy| {
            (cx.saturating_sub(1)..(cx + 2).min(gw)).any(|gx| {
                grid[gy * gw + gx]
                    .iter()
                    .any(|q| (q - p).norm_squared() < d2)
            })
        });
        if near {
            continue;
        }
        grid[cy * gw + cx].push(p);
        out.push(p);
        if out.len() == max_corners {
            break;
        }
    }
    out
}

/// `lambda_min` of the 3x3-block structure tensor at every pixel (0 on the border).
fn min_eigenvalue_map(img: &Plane) -> Vec<f32> {
    let (w, h) = img.size();
    let g = img.gradients();
    let products = |f: &dyn Fn(f32, f32) -> f32| -> Vec<f32> {
        g.gx.data
            .iter()
            .zip(&g.gy.data)
            .map(|(&a, &b)| f(a, b))
            .collect()
    };
    let box3 = |src: Vec<f32>| -> Vec<f32> {
        let mut horiz = vec![0f32; w * h];
        for (s, d) in src.chunks_exact(w).zip(horiz.chunks_exact_mut(w)) {
            for ((o, a), (b, c)) in d[1..w - 1]
                .iter_mut()
                .zip(&s[..w - 2])
                .zip(s[1..w - 1].iter().zip(&s[2..]))
            {
                *o = a + b + c;
            }
        }
        let mut out = vec![0f32; w * h];
        for y in 1..h - 1 {
            let (a, b, c) = (
                &horiz[(y - 1) * w..y * w],
                &horiz[y * w..(y + 1) * w],
                &horiz[(y + 1) * w..(y + 2) * w],
            );
            for (((o, a), b), c) in out[y * w..(y + 1) * w].iter_mut().zip(a).zip(b).zip(c) {
                *o = a + b + c;
            }
        }
        out
    };
    let sxx = box3(products(&|a, _| a * a));
    let sxy = box3(products(&|a, b| a * b));
    let syy = box3(products(&|_, b| b * b));
    sxx.iter()
        .zip(&sxy)
        .zip(&syy)
        .map(|((&a, &b), &c)| {
            let half = 0.5 * (a - c);
            (0.5 * (a + c) - (half * half + b * b).sqrt()).max(0.0)
        })
        .collect()
}

/// An image pyramid with the gradients of every level.
struct GradPyramid {
    images: Vec<Plane>,
    grads: Vec<Gradients>,
}

impl GradPyramid {
    /// The pyramid, with gradients only when `with_gradients`.
    fn new(img: &Plane, levels: usize, with_gradients: bool) -> Self {
        let images = Pyramid::new(img.clone(), levels, MIN_LEVEL_SIDE).levels;
        let grads = if with_gradients {
            images.par_iter().map(Plane::gradients).collect()
        } else {
            Vec::new()
        };
        Self { images, grads }
    }
}

/// Per-thread buffers of one window.
struct Scratch {
    template: Vec<f32>,
    tgx: Vec<f32>,
    tgy: Vec<f32>,
    target: Vec<f32>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Self {
            template: vec![0.0; n],
            tgx: vec![0.0; n],
            tgy: vec![0.0; n],
            target: vec![0.0; n],
        }
    }
}

/// Samples the `win x win` patch of `plane` centred at `(cx, cy)` into `out`, bilinearly; the
/// bilinear weights are shared by the whole patch. Pixels beyond the border are replicated.
fn sample_patch(plane: &Plane, cx: f32, cy: f32, win: usize, out: &mut [f32]) {
    let half = (win / 2) as f32;
    let (x0f, y0f) = ((cx - half).floor(), (cy - half).floor());
    let (fx, fy) = (cx - half - x0f, cy - half - y0f);
    let (w, h) = plane.size();
    let inside = x0f >= 0.0
        && y0f >= 0.0
        && x0f + win as f32 + 1.0 <= w as f32
        && y0f + win as f32 + 1.0 <= h as f32;
    if inside {
        let (x0, y0) = (x0f as usize, y0f as usize);
        for (j, o) in out.chunks_exact_mut(win).enumerate() {
            let r0 = &plane.row(y0 + j)[x0..x0 + win + 1];
            let r1 = &plane.row(y0 + j + 1)[x0..x0 + win + 1];
            for (i, v) in o.iter_mut().enumerate() {
                let top = r0[i] + fx * (r0[i + 1] - r0[i]);
                let bottom = r1[i] + fx * (r1[i + 1] - r1[i]);
                *v = top + fy * (bottom - top);
            }
        }
    } else {
        let cl = |v: f32, n: usize| v.clamp(0.0, (n - 1) as f32);
        for (j, o) in out.chunks_exact_mut(win).enumerate() {
            for (i, v) in o.iter_mut().enumerate() {
                let x = cl(cx - half + i as f32, w);
                let y = cl(cy - half + j as f32, h);
                *v = plane.sample(x, y).unwrap_or(0.0);
            }
        }
    }
}

/// Tracks `start` from pyramid `from` into pyramid `to`; returns position, status and error.
fn track_point(
    from: &GradPyramid,
    to: &[Plane],
    start: Vector2<f32>,
    cfg: &KltConfig,
    s: &mut Scratch,
) -> (Vector2<f32>, TrackStatus, f32) {
    let win = cfg.window;
    let npix = (win * win) as f32;
    let levels = from.images.len().min(to.len());
    let mut flow = Vector2::<f32>::zeros();
    let mut error = 0.0;
    for level in (0..levels).rev() {
        let scale = 0.5f32.powi(level as i32);
        let p = start * scale;
        let (img, grad, next) = (&from.images[level], &from.grads[level], &to[level]);
        sample_patch(img, p.x, p.y, win, &mut s.template);
        sample_patch(&grad.gx, p.x, p.y, win, &mut s.tgx);
        sample_patch(&grad.gy, p.x, p.y, win, &mut s.tgy);
        let (mut gxx, mut gxy, mut gyy) = (0.0f32, 0.0f32, 0.0f32);
        for (&a, &b) in s.tgx.iter().zip(&s.tgy) {
            gxx += a * a;
            gxy += a * b;
            gyy += b * b;
        }
        let det = gxx * gyy - gxy * gxy;
        let half = 0.5 * (gxx - gyy);
        let min_eig = 0.5 * (gxx + gyy) - (half * half + gxy * gxy).sqrt();
        if min_eig.is_nan() || min_eig / npix < cfg.min_eigenvalue || det <= 0.0 {
            return (start + flow / scale, TrackStatus::SmallEigenvalue, 0.0);
        }
        let mut q = p + flow;
        for _ in 0..cfg.max_iterations {
            sample_patch(next, q.x, q.y, win, &mut s.target);
            let (mut bx, mut by) = (0.0f32, 0.0f32);
            for ((&j, &t), (&a, &b)) in s
                .target
                .iter()
                .zip(&s.template)
                .zip(s.tgx.iter().zip(&s.tgy))
            {
                let e = j - t;
                bx += e * a;
                by += e * b;
            }
            let dx = -(gyy * bx - gxy * by) / det;
            let dy = -(gxx * by - gxy * bx) / det;
            q += Vector2::new(dx, dy);
            let (w, h) = next.size();
            if !(q.x >= 0.0 && q.y >= 0.0 && q.x <= (w - 1) as f32 && q.y <= (h - 1) as f32) {
                return (q / scale, TrackStatus::OutOfBounds, 0.0);
            }
            if dx * dx + dy * dy < cfg.epsilon * cfg.epsilon {
                break;
            }
        }
        flow = q - p;
        if level == 0 {
            sample_patch(next, q.x, q.y, win, &mut s.target);
            error = s
                .target
                .iter()
                .zip(&s.template)
                .map(|(a, b)| (a - b).abs())
                .sum::<f32>()
                / npix;
        } else {
            flow *= 2.0;
        }
    }
    (start + flow, TrackStatus::Tracked, error)
}

/// Tracks `points` of `prev` into `next` with pyramidal Lucas-Kanade (see the module
/// documentation). One [`KltTrack`] per input point, in order.
///
/// ```
/// use nalgebra::Vector2;
/// use vofront_direct::{track_klt, KltConfig, Plane, TrackStatus};
/// let img = |dx: f32| {
///     let data = (0..96 * 80)
///         .map(|i| {
///             let (x, y) = ((i % 96) as f32 - dx, (i / 96) as f32);
///             100.0 + 40.0 * (x * 0.3).sin() * (y * 0.25).cos() + 30.0 * ((x + y) * 0.17).sin()
///         })
///         .collect();
///     Plane::new(96, 80, data).unwrap()
/// };
/// let tracks = track_klt(&img(0.0), &img(1.5), &[Vector2::new(48.0, 40.0)], &KltConfig::default()).unwrap();
/// assert_eq!(tracks[0].status, TrackStatus::Tracked);
/// assert!((tracks[0].position.x - 49.5).abs() < 0.05);
/// ```
pub fn track_klt(
    prev: &Plane,
    next: &Plane,
    points: &[Vector2<f32>],
    cfg: &KltConfig,
) -> Result<Vec<KltTrack>, DirectError> {
    prev.check_same_size(next)?;
    prev.check_min_size(MIN_LEVEL_SIDE)?;
    if cfg.window < 3 || cfg.window % 2 == 0 || cfg.levels == 0 || cfg.max_iterations == 0 {
        return Err(DirectError::InvalidConfig(
            "window must be odd and >= 3, levels and max_iterations positive",
        ));
    }
    let with_backward = cfg.forward_backward.is_some();
    let (from, to) = rayon::join(
        || GradPyramid::new(prev, cfg.levels, true),
        || GradPyramid::new(next, cfg.levels, with_backward),
    );
    let to_images = &to.images;
    let n = cfg.window * cfg.window;
    Ok(points
        .par_iter()
        .map_init(
            || Scratch::new(n),
            |s, &p| {
                if !(p.x.is_finite() && p.y.is_finite()) {
                    return KltTrack {
                        position: p,
                        status: TrackStatus::OutOfBounds,
                        error: 0.0,
                    };
                }
                let (q, mut status, error) = track_point(&from, to_images, p, cfg, s);
                if let (TrackStatus::Tracked, Some(limit)) = (status, cfg.forward_backward) {
                    let (back, back_status, _) = track_point(&to, &from.images, q, cfg, s);
                    if back_status != TrackStatus::Tracked || (back - p).norm() > limit {
                        status = TrackStatus::ForwardBackward;
                    }
                }
                KltTrack {
                    position: q,
                    status,
                    error,
                }
            },
        )
        .collect())
}
