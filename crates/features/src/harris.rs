//! Harris corner response used to rank FAST corners.
//!
//! With Sobel gradients `gx, gy` summed over a 7x7 block around the pixel,
//! `M = [[sum gx^2, sum gx gy], [sum gx gy, sum gy^2]]` and `R = det M - k (trace M)^2`, `k = 0.04`.
//! Gradients are scaled by `1 / (4 * 7 * 255)` as in OpenCV, so `R` is independent of the
//! block size and comparable across pyramid levels.

use crate::pyramid::Plane;

/// Harris `k`.
pub(crate) const HARRIS_K: f32 = 0.04;
/// Half side of the summation block (7x7).
pub(crate) const HALF_BLOCK: usize = 3;

/// Harris response at `(x, y)`; the pixel must be at least `HALF_BLOCK + 1` px inside.
pub(crate) fn response(img: &Plane, x: usize, y: usize) -> f32 {
    let w = img.width;
    let d = &img.data;
    // |g| <= 4 * 255, so 49 products stay below 2^26: i32 sums are exact.
    let (mut a, mut b, mut c) = (0i32, 0i32, 0i32);
    for yy in y - HALF_BLOCK..=y + HALF_BLOCK {
        let up = &d[(yy - 1) * w..yy * w];
        let mid = &d[yy * w..(yy + 1) * w];
        let down = &d[(yy + 1) * w..(yy + 2) * w];
        for xx in x - HALF_BLOCK..=x + HALF_BLOCK {
            let p = |r: &[u8], i: usize| r[i] as i32;
            let gx = (p(up, xx + 1) - p(up, xx - 1))
                + 2 * (p(mid, xx + 1) - p(mid, xx - 1))
                + (p(down, xx + 1) - p(down, xx - 1));
            let gy = (p(down, xx - 1) - p(up, xx - 1))
                + 2 * (p(down, xx) - p(up, xx))
                + (p(down, xx + 1) - p(up, xx + 1));
            a += gx * gx;
            b += gy * gy;
            c += gx * gy;
        }
    }
    let scale = 1.0 / (4.0 * (2 * HALF_BLOCK + 1) as f64 * 255.0);
    let s2 = scale * scale;
    let (a, b, c) = (a as f64 * s2, b as f64 * s2, c as f64 * s2);
    (a * b - c * c - HARRIS_K as f64 * (a + b) * (a + b)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corner_beats_edge_beats_flat() {
        let w = 30;
        let img = |f: &dyn Fn(usize, usize) -> bool| Plane {
            width: w,
            height: w,
            data: (0..w * w)
                .map(|i| if f(i % w, i / w) { 200 } else { 30 })
                .collect(),
        };
        let corner = img(&|x, y| x >= 15 && y >= 15);
        let edge = img(&|x, _| x >= 15);
        let flat = img(&|_, _| true);
        let rc = response(&corner, 15, 15);
        let re = response(&edge, 15, 15);
        let rf = response(&flat, 15, 15);
        assert!(rc > 0.0 && re < 0.0 && rf == 0.0, "{rc} {re} {rf}");
    }
}
