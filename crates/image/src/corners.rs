//! Shi-Tomasi corners ("good features to track").
//!
//! The structure tensor `G = sum_window [gx^2, gx gy; gx gy, gy^2]` over a 3x3 block of
//! central-difference gradients, response `lambda_min(G)`, kept when at least `quality` times
//! the strongest response and a 3x3 local maximum, then greedily by decreasing response at
//! least `min_distance` apart.

use nalgebra::Vector2;

use crate::buffer::Image;

/// Shi-Tomasi corners of `img`: at most `max_corners`, response at least `quality` times the
/// best, at least `min_distance` pixels apart, strongest first.
///
/// ```
/// use vofront_image::{good_features_to_track, Image};
/// let mut img = Image::filled(40, 40, 0.0f32);
/// for y in 10..30 {
///     for x in 10..30 {
///         img.data_mut()[y * 40 + x] = 200.0;
///     }
/// }
/// let corners = good_features_to_track(&img, 10, 0.1, 5.0);
/// assert_eq!(corners.len(), 4);
/// ```
pub fn good_features_to_track(
    img: &Image<f32>,
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
    let mut candidates = local_maxima(&response, w, quality.max(0.0) * best);
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

/// `(response, x, y)` of the pixels at least two from the border whose response is positive,
/// at least `threshold` and a 3x3 local maximum (ties kept), in row-major order.
///
/// Each row walks the 3-wide windows of itself and of its two neighbours (without their first
/// and last pixels) in step, so that the 3x3 test needs no index arithmetic or bounds checks.
fn local_maxima(response: &[f32], w: usize, threshold: f32) -> Vec<(f32, usize, usize)> {
    let h = response.len() / w;
    let mut candidates = Vec::new();
    for y in 2..h - 2 {
        let [up, row, down] =
            [y - 1, y, y + 1].map(|r| response[r * w + 1..(r + 1) * w - 1].windows(3));
        for (x, ((u, m), d)) in (2..).zip(up.zip(row).zip(down)) {
            let v = m[1];
            if v < threshold || v <= 0.0 {
                continue;
            }
            if [u, m, d]
                .iter()
                .all(|n| n[0] <= v && n[1] <= v && n[2] <= v)
            {
                candidates.push((v, x, y));
            }
        }
    }
    candidates
}

/// `lambda_min` of the 3x3-block structure tensor at every pixel (0 on the border).
fn min_eigenvalue_map(img: &Image<f32>) -> Vec<f32> {
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
