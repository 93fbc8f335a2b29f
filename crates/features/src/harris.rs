//! Harris corner response used to rank FAST corners.
//!
//! With Sobel gradients `gx, gy` summed over a 7x7 block around the pixel,
//! `M = [[sum gx^2, sum gx gy], [sum gx gy, sum gy^2]]` and `R = det M - k (trace M)^2`, `k = 0.04`.
//! Gradients are scaled by `1 / (4 * 7 * 255)` as in OpenCV, so `R` is independent of the
//! block size and comparable across pyramid levels.

use crate::fast::Corner;
use vofront_image::Image;

/// Harris `k`.
pub(crate) const HARRIS_K: f32 = 0.04;
/// Half side of the summation block (7x7).
pub(crate) const HALF_BLOCK: usize = 3;

/// Lanes of the per-row gradient computation: the 7 block columns plus one unused lane, so
/// each row is one 8-lane vector operation.
const LANES: usize = 8;

/// Harris responses of `corners` (each at least `HALF_BLOCK + 2` px inside), in order.
pub(crate) fn responses(img: &Image<u8>, corners: &[Corner]) -> Vec<f32> {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { responses_avx2(img, corners) };
        }
    }
    responses_generic(img, corners)
}

/// [`responses`] with AVX2: the 7 block columns of a row in one 8 x 32-bit register.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn responses_avx2(img: &Image<u8>, corners: &[Corner]) -> Vec<f32> {
    let mut out = Vec::with_capacity(corners.len());
    for c in corners {
        out.push(response_avx2(img, c.x as usize, c.y as usize));
    }
    out
}

/// [`response`] with AVX2 intrinsics, the same integer sums.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn response_avx2(img: &Image<u8>, x: usize, y: usize) -> f32 {
    use std::arch::x86_64::*;
    let w = img.width();
    // Every read is 8 bytes at row r in y - 4..=y + 4, column x - 4 + dx, dx in 0..=2: the
    // window below covers them all, so one bounds check guards the raw loads.
    let first = (y - HALF_BLOCK - 1) * w + x - HALF_BLOCK - 1;
    let last = (y + HALF_BLOCK + 1) * w + x - HALF_BLOCK - 1 + 2 + LANES;
    let win = &img.data()[first..last];
    let taps = |row: usize, dx: usize| -> __m256i {
        let off = row * w + dx;
        debug_assert!(off + LANES <= win.len());
        // SAFETY: `off + LANES <= win.len()` by the window bounds above; AVX2 is enabled.
        unsafe { _mm256_cvtepu8_epi32(_mm_loadl_epi64(win.as_ptr().add(off) as *const __m128i)) }
    };
    let (mut a, mut b, mut c) = (
        _mm256_setzero_si256(),
        _mm256_setzero_si256(),
        _mm256_setzero_si256(),
    );
    for row in 1..=2 * HALF_BLOCK + 1 {
        let (ul, uc, ur) = (taps(row - 1, 0), taps(row - 1, 1), taps(row - 1, 2));
        let (ml, mr) = (taps(row, 0), taps(row, 2));
        let (dl, dc, dr) = (taps(row + 1, 0), taps(row + 1, 1), taps(row + 1, 2));
        let mid = _mm256_slli_epi32(_mm256_sub_epi32(mr, ml), 1);
        let gx = _mm256_add_epi32(
            _mm256_add_epi32(_mm256_sub_epi32(ur, ul), mid),
            _mm256_sub_epi32(dr, dl),
        );
        let centre = _mm256_slli_epi32(_mm256_sub_epi32(dc, uc), 1);
        let gy = _mm256_add_epi32(
            _mm256_add_epi32(_mm256_sub_epi32(dl, ul), centre),
            _mm256_sub_epi32(dr, ur),
        );
        a = _mm256_add_epi32(a, _mm256_mullo_epi32(gx, gx));
        b = _mm256_add_epi32(b, _mm256_mullo_epi32(gy, gy));
        c = _mm256_add_epi32(c, _mm256_mullo_epi32(gx, gy));
    }
    let lanes = |v: __m256i| -> [i32; LANES] {
        let mut o = [0i32; LANES];
        // SAFETY: `o` is 32 writable bytes; AVX2 is enabled.
        unsafe { _mm256_storeu_si256(o.as_mut_ptr() as *mut __m256i, v) };
        o
    };
    finish(lanes(a), lanes(b), lanes(c))
}

/// The portable body of [`responses`]; inlined into each target-feature variant.
#[inline(always)]
fn responses_generic(img: &Image<u8>, corners: &[Corner]) -> Vec<f32> {
    // A plain loop rather than `map().collect()`, whose fold would not be inlined here and
    // so would miss the target features.
    let mut out = Vec::with_capacity(corners.len());
    for c in corners {
        out.push(response(img, c.x as usize, c.y as usize));
    }
    out
}

/// Harris response at `(x, y)`; the pixel must be at least `HALF_BLOCK + 2` px inside (the
/// unused eighth lane reads one pixel further right).
#[inline(always)]
pub(crate) fn response(img: &Image<u8>, x: usize, y: usize) -> f32 {
    let w = img.width();
    let d = img.data();
    // Lane i is block column xx = x - HALF_BLOCK + i; `taps(r, dx)` holds I(xx + dx, r).
    let taps = |r: usize, dx: usize| -> [i32; LANES] {
        let start = r * w + x + dx - HALF_BLOCK - 1;
        let s: &[u8; LANES] = d[start..start + LANES].try_into().expect("LANES pixels");
        s.map(i32::from)
    };
    // |g| <= 4 * 255, so 49 products stay below 2^26: i32 sums are exact.
    let (mut a, mut b, mut c) = ([0i32; LANES], [0i32; LANES], [0i32; LANES]);
    for yy in y - HALF_BLOCK..=y + HALF_BLOCK {
        let (ul, uc, ur) = (taps(yy - 1, 0), taps(yy - 1, 1), taps(yy - 1, 2));
        let (ml, mr) = (taps(yy, 0), taps(yy, 2));
        let (dl, dc, dr) = (taps(yy + 1, 0), taps(yy + 1, 1), taps(yy + 1, 2));
        for i in 0..LANES {
            let gx = (ur[i] - ul[i]) + 2 * (mr[i] - ml[i]) + (dr[i] - dl[i]);
            let gy = (dl[i] - ul[i]) + 2 * (dc[i] - uc[i]) + (dr[i] - ur[i]);
            a[i] += gx * gx;
            b[i] += gy * gy;
            c[i] += gx * gy;
        }
    }
    finish(a, b, c)
}

/// `R = det M - k trace(M)^2` from the per-column sums of `gx^2`, `gy^2`, `gx gy` (lanes
/// past the block ignored), gradients scaled by `1 / (4 * 7 * 255)`.
#[inline(always)]
fn finish(a: [i32; LANES], b: [i32; LANES], c: [i32; LANES]) -> f32 {
    let block = 2 * HALF_BLOCK + 1;
    let sum = |v: [i32; LANES]| v[..block].iter().sum::<i32>();
    let scale = 1.0 / (4.0 * block as f64 * 255.0);
    let s2 = scale * scale;
    let (a, b, c) = (sum(a) as f64 * s2, sum(b) as f64 * s2, sum(c) as f64 * s2);
    (a * b - c * c - HARRIS_K as f64 * (a + b) * (a + b)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The response straight from the definition: Sobel gradients pixel by pixel.
    fn reference(img: &Image<u8>, x: usize, y: usize) -> f32 {
        let p = |x: usize, y: usize| img.data()[y * img.width() + x] as f64;
        let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
        for yy in y - HALF_BLOCK..=y + HALF_BLOCK {
            for xx in x - HALF_BLOCK..=x + HALF_BLOCK {
                let gx = (p(xx + 1, yy - 1) - p(xx - 1, yy - 1))
                    + 2.0 * (p(xx + 1, yy) - p(xx - 1, yy))
                    + (p(xx + 1, yy + 1) - p(xx - 1, yy + 1));
                let gy = (p(xx - 1, yy + 1) - p(xx - 1, yy - 1))
                    + 2.0 * (p(xx, yy + 1) - p(xx, yy - 1))
                    + (p(xx + 1, yy + 1) - p(xx + 1, yy - 1));
                a += gx * gx;
                b += gy * gy;
                c += gx * gy;
            }
        }
        let s2 = (1.0 / (4.0 * 7.0 * 255.0f64)).powi(2);
        let (a, b, c) = (a * s2, b * s2, c * s2);
        (a * b - c * c - HARRIS_K as f64 * (a + b) * (a + b)) as f32
    }

    #[test]
    fn lane_sums_equal_the_definition() {
        let w = 24;
        let img = crate::pyramid::noise_plane(w, 99);
        for (x, y) in [(5, 5), (12, 9), (18, 18), (7, 15)] {
            assert_eq!(response(&img, x, y), reference(&img, x, y), "({x}, {y})");
        }
        let corners: Vec<Corner> = (5..19)
            .map(|i| Corner {
                x: i,
                y: 23 - i,
                score: 1,
            })
            .collect();
        let want: Vec<f32> = corners
            .iter()
            .map(|c| reference(&img, c.x as usize, c.y as usize))
            .collect();
        assert_eq!(responses(&img, &corners), want);
    }

    #[test]
    fn corner_beats_edge_beats_flat() {
        let w = 30;
        let img = |f: &dyn Fn(usize, usize) -> bool| {
            Image::new(
                w,
                w,
                (0..w * w)
                    .map(|i| if f(i % w, i / w) { 200 } else { 30 })
                    .collect(),
            )
            .unwrap()
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
