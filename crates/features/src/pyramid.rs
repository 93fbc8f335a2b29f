//! Image pyramid (bilinear downscaling chain) and the 7x7 Gaussian smoothing used by BRIEF.

use rayon::prelude::*;

/// A contiguous 8-bit grey plane, row-major, stride = `width`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Plane {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

impl Plane {
    /// Row `y` as a slice.
    #[inline]
    pub fn row(&self, y: usize) -> &[u8] {
        &self.data[y * self.width..(y + 1) * self.width]
    }
}

/// Fixed-point precision of interpolation weights: weights are in `0..=WEIGHT_ONE`.
const WEIGHT_BITS: u32 = 8;
const WEIGHT_ONE: u32 = 1 << WEIGHT_BITS;

/// A bilinear tap `(i0, i1, w1)`, see [`taps`].
type Tap = (usize, usize, u32);

/// Bilinear taps for resampling `src` samples onto `dst` samples with pixel centers aligned:
/// `s = (d + 0.5) * src / dst - 0.5`, clamped to the source. Each tap is
/// `(i0, i1, w1)` with value `((WEIGHT_ONE - w1) I[i0] + w1 I[i1]) / WEIGHT_ONE`.
fn taps(src: usize, dst: usize) -> Vec<Tap> {
    let ratio = src as f64 / dst as f64;
    (0..dst)
        .map(|d| {
            let s = ((d as f64 + 0.5) * ratio - 0.5).clamp(0.0, (src - 1) as f64);
            let i0 = s.floor() as usize;
            let w1 = ((s - i0 as f64) * WEIGHT_ONE as f64).round() as u32;
            (i0, (i0 + 1).min(src - 1), w1)
        })
        .collect()
}

/// Output rows per parallel band of [`resize_bilinear`].
const RESIZE_BAND: usize = 32;

/// Bilinear resize of `src` to `width x height` (both at least 1): vertical pass on
/// contiguous rows into 16-bit sums, then horizontal taps; bands of rows in parallel.
pub(crate) fn resize_bilinear(src: &Plane, width: usize, height: usize) -> Plane {
    let xt = taps(src.width, width);
    let yt = taps(src.height, height);
    let mut data = vec![0u8; width * height];
    data.par_chunks_mut(width * RESIZE_BAND)
        .zip(yt.par_chunks(RESIZE_BAND))
        .for_each(|(out, yt)| resize_rows(src, &xt, yt, out));
    Plane {
        width,
        height,
        data,
    }
}

/// The output rows `out` (one per vertical tap of `yt`) of [`resize_bilinear`].
fn resize_rows(src: &Plane, xt: &[Tap], yt: &[Tap], out: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { resize_rows_avx2(src, xt, yt, out) };
        }
    }
    resize_rows_generic(src, xt, yt, out)
}

/// [`resize_rows`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn resize_rows_avx2(src: &Plane, xt: &[Tap], yt: &[Tap], out: &mut [u8]) {
    resize_rows_generic(src, xt, yt, out)
}

/// The portable body of [`resize_rows`]; inlined into each target-feature variant.
#[inline(always)]
fn resize_rows_generic(src: &Plane, xt: &[Tap], yt: &[Tap], out: &mut [u8]) {
    let mut tmp = vec![0u16; src.width];
    for (out, &(y0, y1, wy)) in out.chunks_exact_mut(xt.len()).zip(yt) {
        let (r0, r1) = (src.row(y0), src.row(y1));
        let w0 = (WEIGHT_ONE - wy) as u16;
        let w1 = wy as u16;
        for ((t, &a), &b) in tmp.iter_mut().zip(r0).zip(r1) {
            *t = a as u16 * w0 + b as u16 * w1;
        }
        for (o, &(x0, x1, wx)) in out.iter_mut().zip(xt) {
            let v = tmp[x0] as u32 * (WEIGHT_ONE - wx) + tmp[x1] as u32 * wx;
            *o = ((v + (1 << (2 * WEIGHT_BITS - 1))) >> (2 * WEIGHT_BITS)) as u8;
        }
    }
}

/// 7-tap Gaussian, sigma = 2 px (as OpenCV's ORB), in 1/256 units: `round(256 g_i / sum g)`
/// with `g_i = exp(-i^2 / 8)`, `i = -3..=3`, centre adjusted so the taps sum to 256.
const GAUSS7: [u32; 7] = [18, 34, 49, 54, 49, 34, 18];

/// Separable 7x7 Gaussian blur (sigma 2 px), borders replicated. Both passes use 8-bit
/// fixed-point taps; the horizontal result is rounded to 8 bits so the vertical pass
/// accumulates in 16-bit lanes (at most 255 * 256).
pub(crate) fn gaussian_blur7(src: &Plane) -> Plane {
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
unsafe fn gaussian_blur7_avx2(src: &Plane) -> Plane {
    gaussian_blur7_generic(src)
}

/// The portable body of [`gaussian_blur7`]; inlined into each target-feature variant.
#[inline(always)]
fn gaussian_blur7_generic(src: &Plane) -> Plane {
    let (w, h) = (src.width, src.height);
    let mut tmp = vec![0u8; w * h];
    let mut acc = vec![0u16; w];
    for (t, s) in tmp.chunks_exact_mut(w).zip(src.data.chunks_exact(w)) {
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
    Plane {
        width: w,
        height: h,
        data,
    }
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

/// One pyramid level: the image at scale `scale` (level-0 pixels per level pixel).
#[derive(Debug, Clone)]
pub(crate) struct Level {
    pub image: Plane,
    /// Nominal scale `scale_factor^level`.
    pub scale: f32,
    /// Exact level-0 pixels per level pixel along x and y (`w0 / w_l`, `h0 / h_l`).
    pub ratio: (f32, f32),
}

/// The levels `1..levels` above `base` (level 0), level `l` of size
/// `round(w / s^l) x round(h / s^l)`, each resized from the previous one; stops before a
/// level smaller than `min_size` on a side.
pub(crate) fn build_above(
    base: &Plane,
    levels: usize,
    scale_factor: f32,
    min_size: usize,
) -> Vec<Level> {
    let (w0, h0) = (base.width, base.height);
    let mut out: Vec<Level> = Vec::with_capacity(levels.saturating_sub(1));
    for l in 1..levels {
        let scale = scale_factor.powi(l as i32);
        let w = (w0 as f32 / scale).round() as usize;
        let h = (h0 as f32 / scale).round() as usize;
        if w < min_size || h < min_size {
            break;
        }
        let prev = out.last().map_or(base, |p| &p.image);
        let image = resize_bilinear(prev, w, h);
        out.push(Level {
            image,
            scale,
            ratio: (w0 as f32 / w as f32, h0 as f32 / h as f32),
        });
    }
    out
}

/// A `w x w` plane of pseudo-random grey levels (LCG from `seed`), for tests.
#[cfg(test)]
pub(crate) fn noise_plane(w: usize, seed: u32) -> Plane {
    let mut s = seed;
    let data = (0..w * w)
        .map(|_| {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (s >> 24) as u8
        })
        .collect();
    Plane {
        width: w,
        height: w,
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(w: usize, h: usize, f: impl Fn(usize, usize) -> u8) -> Plane {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Plane {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn resize_keeps_constants_and_linear_ramps() {
        let flat = resize_bilinear(&plane(50, 40, |_, _| 77), 41, 33);
        assert!(flat.data.iter().all(|&v| v == 77));
        // A ramp I = 2x + 10 resampled with aligned centers stays a ramp in level-0 units.
        let ramp = plane(120, 10, |x, _| (2 * x + 10) as u8);
        let small = resize_bilinear(&ramp, 100, 10);
        for x in 2..98 {
            let s = (x as f64 + 0.5) * 1.2 - 0.5;
            let want = 2.0 * s + 10.0;
            assert!(
                (small.data[5 * 100 + x] as f64 - want).abs() <= 1.0,
                "x {x}"
            );
        }
    }

    #[test]
    fn blur_keeps_constants_and_smooths_an_impulse_symmetrically() {
        let flat = gaussian_blur7(&plane(20, 15, |_, _| 200));
        assert!(flat.data.iter().all(|&v| v == 200));
        let imp = gaussian_blur7(&plane(
            21,
            21,
            |x, y| if (x, y) == (10, 10) { 255 } else { 0 },
        ));
        let at = |x: usize, y: usize| imp.data[y * 21 + x];
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
