//! Pyramidal Lucas-Kanade (KLT) point tracking.
//!
//! Tracking a point `p` from `I` to `J`: at each pyramid level `l`, from the coarsest, the
//! template `T(w) = I_l(p / 2^l + w)` and its gradients over a `window x window` patch are
//! sampled once, `G = sum grad T grad T^T`, and the position `q` is refined by
//! `q <- q - G^-1 sum grad T (J_l(q + w) - T(w))` until the step is below `epsilon` pixels;
//! the flow is doubled when going one level down. The flow starts at zero, or at
//! `(g - p) / 2^(L-1)` on the coarsest level `L - 1` when an initial position `g` (a
//! prediction) is given. A track fails when `q` leaves the image, when
//! `lambda_min(G) / window^2 < min_eigenvalue` (a flat or edge-only window), or when tracking
//! back from `J` to `I` (from `q`, seeded with `p` when the forward track was seeded) does not
//! land within `forward_backward` pixels of `p`.
//!
//! Pyramids are [`KltPyramid`]s: built once per frame and passed to [`track_klt_pyramids`]
//! (a sequence tracks frame `k` into `k + 1`, then `k + 1` into `k + 2` with the same pyramid);
//! [`track_klt`] builds both for a single pair.

use std::borrow::Cow;

use nalgebra::Vector2;
use rayon::prelude::*;

use crate::buffer::Image;
use crate::error::ImageError;

/// Smallest side of a KLT pyramid level, pixels.
const MIN_LEVEL_SIDE: usize = 8;

/// Settings of [`track_klt`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KltConfig {
    /// Side of the square window, pixels (odd, at least 3).
    pub window: usize,
    /// Pyramid levels as factor-2 octaves (each level half the size of the one below; ORB's 1.2-ratio levels are
    /// `OrbConfig::scale_levels`), including full resolution (OpenCV's
    /// `maxLevel + 1`).
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

impl KltConfig {
    /// [`ImageError::InvalidConfig`] unless `window` is odd and at least 3 and `levels` and
    /// `max_iterations` are positive.
    pub fn validate(&self) -> Result<(), ImageError> {
        if self.window < 3
            || self.window.is_multiple_of(2)
            || self.levels == 0
            || self.max_iterations == 0
        {
            return Err(ImageError::InvalidConfig(
                "window must be odd and >= 3, levels and max_iterations positive",
            ));
        }
        Ok(())
    }
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

/// Outcome of one KLT-tracked point (not the per-frame status of the sequential trackers,
/// `vofront::odometry::TrackStatus`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KltStatus {
    /// Tracked (and consistent backwards when checked).
    Tracked,
    /// The point left the image.
    OutOfBounds,
    /// The window has too little texture in some direction.
    SmallEigenvalue,
    /// Tracking back did not return to the start.
    ForwardBackward,
}

/// The former name of [`KltStatus`].
#[deprecated(note = "renamed `KltStatus` (`TrackStatus` is the odometry trackers' status)")]
pub type TrackStatus = KltStatus;

/// A tracked point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KltTrack {
    /// Position in the next image, pixels.
    pub position: Vector2<f32>,
    /// Whether the track is usable.
    pub status: KltStatus,
    /// Mean absolute residual over the window at the end, grey levels.
    pub error: f32,
}

/// The pyramid of one image for KLT, built once and reused for every track into or out of it.
///
/// Level 0 is the image itself (borrowed, or owned with [`KltPyramid::from_image`]); each level
/// `l > 0` is [`Image::pyr_down`] of the one below, padded by `window / 2 + 2` replicated pixels
/// on each side so that windows near the border take the fast sampling path (pixel `(x, y)` of
/// level `l > 0` is stored at `(x + pad, y + pad)`). A pyramid serves the [`KltConfig`]s with
/// its `window` and at most its `levels`; results are identical to building it per call.
#[derive(Debug, Clone)]
pub struct KltPyramid<'a> {
    base: Cow<'a, Image<f32>>,
    /// Levels `1..`, each padded by `pad` pixels on every side.
    coarse: Vec<Image<f32>>,
    /// Window side the padding was chosen for, pixels.
    window: usize,
    /// Levels asked for at build time (more than [`KltPyramid::levels`] when the image ran out).
    requested: usize,
    pad: usize,
}

impl<'a> KltPyramid<'a> {
    /// The pyramid of `img` (borrowed) for `cfg.window` and up to `cfg.levels` levels.
    ///
    /// Errors: [`ImageError::InvalidConfig`] for a bad `cfg`, [`ImageError::ImageTooSmall`]
    /// below 8 pixels on a side.
    pub fn new(img: &'a Image<f32>, cfg: &KltConfig) -> Result<Self, ImageError> {
        Self::build(Cow::Borrowed(img), cfg)
    }

    fn build(base: Cow<'a, Image<f32>>, cfg: &KltConfig) -> Result<Self, ImageError> {
        cfg.validate()?;
        base.check_min_size(MIN_LEVEL_SIDE)?;
        let pad = cfg.window / 2 + 2;
        let coarse = base.coarser_levels(cfg.levels, MIN_LEVEL_SIDE);
        Ok(Self {
            coarse: coarse.iter().map(|level| padded(level, pad)).collect(),
            base,
            window: cfg.window,
            requested: cfg.levels,
            pad,
        })
    }

    /// Levels built, including full resolution.
    pub fn levels(&self) -> usize {
        self.coarse.len() + 1
    }

    /// Whether the pyramid holds every level that `levels` would build: tracking with it then
    /// equals tracking with a pyramid built for `levels`.
    fn serves(&self, levels: usize) -> bool {
        levels <= self.requested || self.levels() < self.requested
    }

    /// The full-resolution image.
    pub fn image(&self) -> &Image<f32> {
        &self.base
    }

    /// The stored (padded above level 0) plane of level `l`.
    fn level(&self, l: usize) -> &Image<f32> {
        if l == 0 {
            &self.base
        } else {
            &self.coarse[l - 1]
        }
    }

    /// Padding of level `l`, pixels.
    fn pad(&self, l: usize) -> usize {
        if l == 0 {
            0
        } else {
            self.pad
        }
    }

    /// Unpadded `(width, height)` of level `l`.
    fn size(&self, l: usize) -> (usize, usize) {
        let (w, h) = self.level(l).size();
        (w - 2 * self.pad(l), h - 2 * self.pad(l))
    }
}

impl KltPyramid<'static> {
    /// The pyramid of `img`, owning it (to keep a frame's pyramid for the next frame).
    pub fn from_image(img: Image<f32>, cfg: &KltConfig) -> Result<Self, ImageError> {
        Self::build(Cow::Owned(img), cfg)
    }
}

/// `img` with `pad` replicated border pixels on every side.
fn padded(img: &Image<f32>, pad: usize) -> Image<f32> {
    let (w, h) = img.size();
    let pw = w + 2 * pad;
    let mut data = Vec::with_capacity(pw * (h + 2 * pad));
    for y in 0..h + 2 * pad {
        let row = img.row(y.saturating_sub(pad).min(h - 1));
        data.extend(std::iter::repeat_n(row[0], pad));
        data.extend_from_slice(row);
        data.extend(std::iter::repeat_n(row[w - 1], pad));
    }
    Image::new(pw, h + 2 * pad, data).expect("one padded row of pw values per padded row")
}

/// Per-thread buffers of one window.
struct Scratch {
    /// The template with a one-pixel ring, `(window + 2)^2`.
    ring: Vec<f32>,
    template: Vec<f32>,
    tgx: Vec<f32>,
    tgy: Vec<f32>,
    target: Vec<f32>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        let side = (n as f64).sqrt() as usize + 2;
        Self {
            ring: vec![0.0; side * side],
            template: vec![0.0; n],
            tgx: vec![0.0; n],
            tgy: vec![0.0; n],
            target: vec![0.0; n],
        }
    }
}

/// Samples the `win x win` patch of `plane` centred at `(cx, cy)` into `out`, bilinearly; the
/// bilinear weights are shared by the whole patch. Pixels beyond the border are replicated.
fn sample_patch(plane: &Image<f32>, cx: f32, cy: f32, win: usize, out: &mut [f32]) {
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
            let (w0, w1) = ((1.0 - fx) * (1.0 - fy), fx * (1.0 - fy));
            let (w2, w3) = ((1.0 - fx) * fy, fx * fy);
            for ((v, (a, b)), (c, d)) in o
                .iter_mut()
                .zip(r0.iter().zip(&r0[1..]))
                .zip(r1.iter().zip(&r1[1..]))
            {
                *v = w0 * a + w1 * b + w2 * c + w3 * d;
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

/// Number of independent partial sums, so that the reductions vectorize.
const LANES: usize = 8;

/// `sum_i f(a_i, b_i, c_i)` for a 3-component `f`, in [`LANES`] partial sums.
#[inline]
fn lane_sums(a: &[f32], b: &[f32], c: &[f32], f: impl Fn(f32, f32, f32) -> [f32; 3]) -> [f32; 3] {
    let mut acc = [[0f32; LANES]; 3];
    let chunks = a.len() / LANES * LANES;
    for ((ca, cb), cc) in a[..chunks]
        .chunks_exact(LANES)
        .zip(b[..chunks].chunks_exact(LANES))
        .zip(c[..chunks].chunks_exact(LANES))
    {
        for k in 0..LANES {
            let v = f(ca[k], cb[k], cc[k]);
            acc[0][k] += v[0];
            acc[1][k] += v[1];
            acc[2][k] += v[2];
        }
    }
    let mut out = acc.map(|lane| lane.iter().sum::<f32>());
    for i in chunks..a.len() {
        let v = f(a[i], b[i], c[i]);
        out[0] += v[0];
        out[1] += v[1];
        out[2] += v[2];
    }
    out
}

/// `(sum (j - t) gx, sum (j - t) gy)` in [`LANES`] partial sums.
#[inline]
fn lane_sums2(j: &[f32], t: &[f32], gx: &[f32], gy: &[f32]) -> [f32; 2] {
    let mut bx = [0f32; LANES];
    let mut by = [0f32; LANES];
    let chunks = j.len() / LANES * LANES;
    for (((cj, ct), cx), cy) in j[..chunks]
        .chunks_exact(LANES)
        .zip(t[..chunks].chunks_exact(LANES))
        .zip(gx[..chunks].chunks_exact(LANES))
        .zip(gy[..chunks].chunks_exact(LANES))
    {
        for k in 0..LANES {
            let e = cj[k] - ct[k];
            bx[k] += e * cx[k];
            by[k] += e * cy[k];
        }
    }
    let mut out = [bx.iter().sum::<f32>(), by.iter().sum::<f32>()];
    for i in chunks..j.len() {
        let e = j[i] - t[i];
        out[0] += e * gx[i];
        out[1] += e * gy[i];
    }
    out
}

/// Tracks `start` from pyramid `from` into pyramid `to`, from `guess` (a full-resolution
/// position) or zero flow; returns position, status and error.
fn track_point(
    from: &KltPyramid,
    to: &KltPyramid,
    start: Vector2<f32>,
    guess: Option<Vector2<f32>>,
    cfg: &KltConfig,
    s: &mut Scratch,
) -> (Vector2<f32>, KltStatus, f32) {
    let win = cfg.window;
    let npix = (win * win) as f32;
    let levels = from.levels().min(to.levels()).min(cfg.levels);
    let mut flow = guess.map_or_else(Vector2::<f32>::zeros, |g| {
        (g - start) * 0.5f32.powi(levels as i32 - 1)
    });
    let mut error = 0.0;
    for level in (0..levels).rev() {
        let scale = 0.5f32.powi(level as i32);
        let p = start * scale;
        let (img, next) = (from.level(level), to.level(level));
        let (pad_from, pad) = (from.pad(level) as f32, to.pad(level) as f32);
        // The template with a one-pixel ring; its central differences are the bilinearly
        // sampled gradients (both operations are linear and share the bilinear weights).
        sample_patch(img, p.x + pad_from, p.y + pad_from, win + 2, &mut s.ring);
        let side = win + 2;
        for j in 0..win {
            let (up, mid, down) = (
                &s.ring[j * side..(j + 1) * side],
                &s.ring[(j + 1) * side..(j + 2) * side],
                &s.ring[(j + 2) * side..(j + 3) * side],
            );
            let row = j * win..(j + 1) * win;
            s.template[row.clone()].copy_from_slice(&mid[1..side - 1]);
            for ((g, a), b) in s.tgx[row.clone()]
                .iter_mut()
                .zip(&mid[2..])
                .zip(&mid[..side - 2])
            {
                *g = 0.5 * (a - b);
            }
            for ((g, c), d) in s.tgy[row]
                .iter_mut()
                .zip(&down[1..side - 1])
                .zip(&up[1..side - 1])
            {
                *g = 0.5 * (c - d);
            }
        }
        let [gxx, gxy, gyy] = lane_sums(&s.tgx, &s.tgy, &s.tgy, |a, b, _| [a * a, a * b, b * b]);
        let det = gxx * gyy - gxy * gxy;
        let half = 0.5 * (gxx - gyy);
        let min_eig = 0.5 * (gxx + gyy) - (half * half + gxy * gxy).sqrt();
        if min_eig.is_nan() || min_eig / npix < cfg.min_eigenvalue || det <= 0.0 {
            return (start + flow / scale, KltStatus::SmallEigenvalue, 0.0);
        }
        let mut q = p + flow;
        let (w, h) = to.size(level);
        for _ in 0..cfg.max_iterations {
            sample_patch(next, q.x + pad, q.y + pad, win, &mut s.target);
            let [bx, by] = lane_sums2(&s.target, &s.template, &s.tgx, &s.tgy);
            let dx = -(gyy * bx - gxy * by) / det;
            let dy = -(gxx * by - gxy * bx) / det;
            q += Vector2::new(dx, dy);
            if !(q.x >= 0.0 && q.y >= 0.0 && q.x <= (w - 1) as f32 && q.y <= (h - 1) as f32) {
                return (q / scale, KltStatus::OutOfBounds, 0.0);
            }
            if dx * dx + dy * dy < cfg.epsilon * cfg.epsilon {
                break;
            }
        }
        flow = q - p;
        if level == 0 {
            sample_patch(next, q.x + pad, q.y + pad, win, &mut s.target);
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
    (start + flow, KltStatus::Tracked, error)
}

/// Tracks `points` of `prev` into `next` with pyramidal Lucas-Kanade (see the module
/// documentation), building both pyramids; one [`KltTrack`] per input point, in order.
///
/// ```
/// use nalgebra::Vector2;
/// use vofront_image::{track_klt, Image, KltConfig, KltStatus};
/// let img = |dx: f32| {
///     let data = (0..96 * 80)
///         .map(|i| {
///             let (x, y) = ((i % 96) as f32 - dx, (i / 96) as f32);
///             100.0 + 40.0 * (x * 0.3).sin() * (y * 0.25).cos() + 30.0 * ((x + y) * 0.17).sin()
///         })
///         .collect();
///     Image::new(96, 80, data).unwrap()
/// };
/// let tracks = track_klt(&img(0.0), &img(1.5), &[Vector2::new(48.0, 40.0)], &KltConfig::default()).unwrap();
/// assert_eq!(tracks[0].status, KltStatus::Tracked);
/// assert!((tracks[0].position.x - 49.5).abs() < 0.05);
/// ```
///
/// Errors: [`ImageError::SizeMismatch`], [`ImageError::ImageTooSmall`] (below 8 pixels),
/// [`ImageError::InvalidConfig`].
pub fn track_klt(
    prev: &Image<f32>,
    next: &Image<f32>,
    points: &[Vector2<f32>],
    cfg: &KltConfig,
) -> Result<Vec<KltTrack>, ImageError> {
    prev.check_same_size(next)?;
    prev.check_min_size(MIN_LEVEL_SIDE)?;
    cfg.validate()?;
    let (from, to) = rayon::join(|| KltPyramid::new(prev, cfg), || KltPyramid::new(next, cfg));
    track_klt_pyramids(&from?, &to?, points, None, cfg)
}

/// Tracks `points` of `from`'s image into `to`'s with pyramidal Lucas-Kanade, each from its
/// `initial` position in `to` when given (a prediction; zero flow otherwise); one [`KltTrack`]
/// per input point, in order. A point or initial position that is not finite is
/// [`KltStatus::OutOfBounds`].
///
/// Errors: [`ImageError::SizeMismatch`] for pyramids of different image sizes,
/// [`ImageError::InvalidConfig`] for a bad `cfg` or pyramids built for another window or with
/// fewer than `cfg.levels` levels available from the image, [`ImageError::LengthMismatch`]
/// when `initial` does not have one position per point.
pub fn track_klt_pyramids(
    from: &KltPyramid,
    to: &KltPyramid,
    points: &[Vector2<f32>],
    initial: Option<&[Vector2<f32>]>,
    cfg: &KltConfig,
) -> Result<Vec<KltTrack>, ImageError> {
    from.image().check_same_size(to.image())?;
    cfg.validate()?;
    if from.window != cfg.window || to.window != cfg.window {
        return Err(ImageError::InvalidConfig(
            "KLT pyramid built for another window size",
        ));
    }
    if !from.serves(cfg.levels) || !to.serves(cfg.levels) {
        return Err(ImageError::InvalidConfig(
            "KLT pyramid built with fewer levels than the configuration asks for",
        ));
    }
    if let Some(initial) = initial {
        if initial.len() != points.len() {
            return Err(ImageError::LengthMismatch {
                expected: points.len(),
                got: initial.len(),
            });
        }
    }
    let guess = |i: usize| initial.map(|g| g[i]);
    let n = cfg.window * cfg.window;
    Ok(points
        .par_iter()
        .enumerate()
        .map_init(
            || Scratch::new(n),
            |s, (i, &p)| {
                let g = guess(i);
                let finite = |v: Vector2<f32>| v.x.is_finite() && v.y.is_finite();
                if !finite(p) || !g.is_none_or(finite) {
                    return KltTrack {
                        position: p,
                        status: KltStatus::OutOfBounds,
                        error: 0.0,
                    };
                }
                let (q, mut status, error) = track_point(from, to, p, g, cfg, s);
                if let (KltStatus::Tracked, Some(limit)) = (status, cfg.forward_backward) {
                    let (back, back_status, _) = track_point(to, from, q, g.map(|_| p), cfg, s);
                    if back_status != KltStatus::Tracked || (back - p).norm() > limit {
                        status = KltStatus::ForwardBackward;
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
