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
use crate::plane::Plane;

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
///         img.data_mut()[y * 40 + x] = 200.0;
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
    let (gx, gy) = (g.gx.data(), g.gy.data());
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
    let sxx = box3(gx.iter().map(|a| a * a).collect());
    let sxy = box3(gx.iter().zip(gy).map(|(a, b)| a * b).collect());
    let syy = box3(gy.iter().map(|b| b * b).collect());
    sxx.iter()
        .zip(&sxy)
        .zip(&syy)
        .map(|((&a, &b), &c)| {
            let half = 0.5 * (a - c);
            (0.5 * (a + c) - (half * half + b * b).sqrt()).max(0.0)
        })
        .collect()
}

/// An image pyramid whose coarse levels are padded by replicated pixels.
///
/// Level `l > 0` is padded by `pad` pixels on each side (level 0 is the caller's image, not
/// copied), so that windows near the border take the fast sampling path; pixel `(x, y)` of
/// level `l` is stored at `(x + pad(l), y + pad(l))`.
struct PaddedPyramid<'a> {
    base: &'a Plane,
    /// Levels `1..`, each padded by `pad` pixels on every side.
    coarse: Vec<Plane>,
    pad: usize,
}

impl<'a> PaddedPyramid<'a> {
    fn new(img: &'a Plane, levels: usize, pad: usize) -> Self {
        let coarse = img.coarser_levels(levels, MIN_LEVEL_SIDE);
        Self {
            base: img,
            coarse: coarse.iter().map(|level| padded(level, pad)).collect(),
            pad,
        }
    }

    fn levels(&self) -> usize {
        self.coarse.len() + 1
    }

    /// The stored (padded above level 0) plane of level `l`.
    fn level(&self, l: usize) -> &Plane {
        if l == 0 {
            self.base
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

/// `img` with `pad` replicated border pixels on every side.
fn padded(img: &Plane, pad: usize) -> Plane {
    let (w, h) = img.size();
    let pw = w + 2 * pad;
    let mut data = Vec::with_capacity(pw * (h + 2 * pad));
    for y in 0..h + 2 * pad {
        let row = img.row(y.saturating_sub(pad).min(h - 1));
        data.extend(std::iter::repeat(row[0]).take(pad));
        data.extend_from_slice(row);
        data.extend(std::iter::repeat(row[w - 1]).take(pad));
    }
    Plane::new(pw, h + 2 * pad, data).expect("one padded row of pw values per padded row")
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

/// Tracks `start` from pyramid `from` into pyramid `to`; returns position, status and error.
fn track_point(
    from: &PaddedPyramid,
    to: &PaddedPyramid,
    start: Vector2<f32>,
    cfg: &KltConfig,
    s: &mut Scratch,
) -> (Vector2<f32>, TrackStatus, f32) {
    let win = cfg.window;
    let npix = (win * win) as f32;
    let levels = from.levels().min(to.levels());
    let mut flow = Vector2::<f32>::zeros();
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
            return (start + flow / scale, TrackStatus::SmallEigenvalue, 0.0);
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
                return (q / scale, TrackStatus::OutOfBounds, 0.0);
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
    let pad = cfg.window / 2 + 2;
    let (from, to) = rayon::join(
        || PaddedPyramid::new(prev, cfg.levels, pad),
        || PaddedPyramid::new(next, cfg.levels, pad),
    );
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
                let (q, mut status, error) = track_point(&from, &to, p, cfg, s);
                if let (TrackStatus::Tracked, Some(limit)) = (status, cfg.forward_backward) {
                    let (back, back_status, _) = track_point(&to, &from, q, cfg, s);
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
