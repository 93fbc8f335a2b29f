//! ORB's pyramid (the scale-factor resampling lives in `vofront_image::scale_pyramid`) and the
//! 7x7 Gaussian smoothing used by BRIEF.

pub(crate) use vofront_image::scale_pyramid::{build_above, ScaleLevel as Level};
use vofront_image::Image;

/// 7-tap Gaussian, sigma = 2 px (as OpenCV's ORB), in 1/256 units: `round(256 g_i / sum g)`
/// with `g_i = exp(-i^2 / 8)`, `i = -3..=3`, centre adjusted so the taps sum to 256.
const GAUSS7: [u32; 7] = [18, 34, 49, 54, 49, 34, 18];

/// Separable 7x7 Gaussian blur (sigma 2 px), borders replicated. Both passes use 8-bit
/// fixed-point taps; the horizontal result is rounded to 8 bits so the vertical pass
/// accumulates in 16-bit lanes (at most 255 * 256).
pub(crate) fn gaussian_blur7(src: &Image<u8>) -> Image<u8> {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { gaussian_blur7_avx2(src) };
        }
    }
    gaussian_blur7_generic(src)
}

/// [`gaussian_blur7`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn gaussian_blur7_avx2(src: &Image<u8>) -> Image<u8> {
    gaussian_blur7_generic(src)
}

/// The portable body of [`gaussian_blur7`]; inlined into each target-feature variant.
#[inline(always)]
fn gaussian_blur7_generic(src: &Image<u8>) -> Image<u8> {
    let (w, h) = src.size();
    let mut tmp = vec![0u8; w * h];
    let mut acc = vec![0u16; w];
    for (t, s) in tmp.chunks_exact_mut(w).zip(src.data().chunks_exact(w)) {
        horizontal_row(s, &mut acc);
        for (o, &a) in t.iter_mut().zip(&acc) {
            *o = ((a as u32 + 128) >> 8) as u8;
        }
    }
    let mut data = vec![0u8; w * h];
    for (y, out) in data.chunks_exact_mut(w).enumerate() {
        let rows: [&[u8]; 7] = std::array::from_fn(|k| {
            let sy = (y + k).saturating_sub(3).min(h - 1);
            &tmp[sy * w..(sy + 1) * w]
        });
        vertical_row(&rows, out);
    }
    Image::new(w, h, data).expect("w * h blurred values")
}

/// Vertical pass of one output row, `out[x] = round(sum_k GAUSS7[k] rows[k][x] / 256)`, in
/// fixed blocks whose 16-bit accumulators stay in vector registers.
#[inline(always)]
fn vertical_row(rows: &[&[u8]; 7], out: &mut [u8]) {
    const B: usize = 16;
    let w = out.len();
    let blocks = w / B * B;
    for (bi, o) in out[..blocks].chunks_exact_mut(B).enumerate() {
        let x = bi * B;
        let mut acc = [128u16; B];
        for (r, &g) in rows.iter().zip(&GAUSS7) {
            let r: &[u8; B] = r[x..x + B].try_into().expect("block of B pixels");
            for i in 0..B {
                acc[i] += g as u16 * r[i] as u16;
            }
        }
        for i in 0..B {
            o[i] = (acc[i] >> 8) as u8;
        }
    }
    for x in blocks..w {
        let acc: u32 = rows
            .iter()
            .zip(&GAUSS7)
            .map(|(r, &g)| g * r[x] as u32)
            .sum();
        out[x] = ((acc + 128) >> 8) as u8;
    }
}

/// One row of the horizontal pass: `t[x] = sum_k GAUSS7[k] s[clamp(x + k - 3)]`.
#[inline(always)]
fn horizontal_row(s: &[u8], t: &mut [u16]) {
    let w = s.len();
    let clamped = |x: isize| s[x.clamp(0, w as isize - 1) as usize] as u32;
    let at = |x: usize| -> u16 {
        GAUSS7
            .iter()
            .enumerate()
            .map(|(k, g)| g * clamped(x as isize + k as isize - 3))
            .sum::<u32>() as u16
    };
    if w <= 6 {
        for (x, v) in t.iter_mut().enumerate() {
            *v = at(x);
        }
        return;
    }
    let n = w - 6;
    let interior = &mut t[3..3 + n];
    interior.iter_mut().for_each(|v| *v = 0);
    for (k, &g) in GAUSS7.iter().enumerate() {
        let g = g as u16;
        for (v, &p) in interior.iter_mut().zip(&s[k..k + n]) {
            *v += g * p as u16;
        }
    }
    for x in (0..3).chain(w - 3..w) {
        t[x] = at(x);
    }
}

/// A `w x w` plane of pseudo-random grey levels (LCG from `seed`), for tests.
#[cfg(test)]
pub(crate) fn noise_plane(w: usize, seed: u32) -> Image<u8> {
    let mut s = seed;
    let data = (0..w * w)
        .map(|_| {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (s >> 24) as u8
        })
        .collect();
    Image::new(w, w, data).expect("w * w values")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(w: usize, h: usize, f: impl Fn(usize, usize) -> u8) -> Image<u8> {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Image::new(w, h, data).expect("w * h values")
    }

    #[test]
    fn blur_keeps_constants_and_smooths_an_impulse_symmetrically() {
        let flat = gaussian_blur7(&plane(20, 15, |_, _| 200));
        assert!(flat.data().iter().all(|&v| v == 200));
        let imp = gaussian_blur7(&plane(
            21,
            21,
            |x, y| if (x, y) == (10, 10) { 255 } else { 0 },
        ));
        let at = |x: usize, y: usize| imp.data()[y * 21 + x];
        assert!(at(10, 10) > at(11, 10) && at(11, 10) > at(12, 10) && at(12, 10) > at(13, 10));
        assert_eq!(at(9, 10), at(11, 10));
        assert_eq!(at(10, 8), at(10, 12));
        assert_eq!(at(15, 10), 0);
    }

    #[test]
    fn dispatched_and_portable_blur_agree() {
        let img = plane(83, 29, |x, y| ((x * 37 + y * 91) % 256) as u8);
        assert_eq!(gaussian_blur7(&img), gaussian_blur7_generic(&img));
    }
}
