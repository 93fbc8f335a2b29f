//! ORB's scale-factor pyramid: level `l` is the image resized to `round(w / s^l) x
//! round(h / s^l)` by bilinear resampling with pixel centres aligned, each level from the
//! previous one (8-bit fixed-point weights, AVX2 where the CPU has it).

use rayon::prelude::*;

use crate::buffer::Image;

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

/// Bilinear resize of `src` to `width x height`: vertical pass on contiguous rows into 16-bit
/// sums, then horizontal taps; bands of rows in parallel. An empty source or target gives a
/// `width x height` image of zeros.
pub fn resize_bilinear(src: &Image<u8>, width: usize, height: usize) -> Image<u8> {
    if width == 0 || height == 0 || src.width() == 0 || src.height() == 0 {
        return Image::filled(width, height, 0);
    }
    let xt = taps(src.width(), width);
    let yt = taps(src.height(), height);
    let mut data = vec![0u8; width * height];
    data.par_chunks_mut(width * RESIZE_BAND)
        .zip(yt.par_chunks(RESIZE_BAND))
        .for_each(|(out, yt)| resize_rows(src, &xt, yt, out));
    Image::from_sized(width, height, data)
}

/// The output rows `out` (one per vertical tap of `yt`) of [`resize_bilinear`].
fn resize_rows(src: &Image<u8>, xt: &[Tap], yt: &[Tap], out: &mut [u8]) {
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
unsafe fn resize_rows_avx2(src: &Image<u8>, xt: &[Tap], yt: &[Tap], out: &mut [u8]) {
    resize_rows_generic(src, xt, yt, out)
}

/// The portable body of [`resize_rows`]; inlined into each target-feature variant.
#[inline(always)]
fn resize_rows_generic(src: &Image<u8>, xt: &[Tap], yt: &[Tap], out: &mut [u8]) {
    let mut tmp = vec![0u16; src.width()];
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

/// One pyramid level: the image at scale `scale` (level-0 pixels per level pixel).
#[derive(Debug, Clone)]
pub struct ScaleLevel {
    /// The resampled image.
    pub image: Image<u8>,
    /// Nominal scale `scale_factor^level`.
    pub scale: f32,
    /// Exact level-0 pixels per level pixel along x and y (`w0 / w_l`, `h0 / h_l`).
    pub ratio: (f32, f32),
}

/// The levels `1..levels` above `base` (level 0), level `l` of size
/// `round(w / s^l) x round(h / s^l)`, each resized from the previous one; stops before a
/// level smaller than `min_size` on a side.
pub fn build_above(
    base: &Image<u8>,
    levels: usize,
    scale_factor: f32,
    min_size: usize,
) -> Vec<ScaleLevel> {
    let (w0, h0) = base.size();
    let mut out: Vec<ScaleLevel> = Vec::with_capacity(levels.saturating_sub(1));
    for l in 1..levels {
        let scale = scale_factor.powi(l as i32);
        let w = (w0 as f32 / scale).round() as usize;
        let h = (h0 as f32 / scale).round() as usize;
        if w < min_size || h < min_size {
            break;
        }
        let prev = out.last().map_or(base, |p| &p.image);
        let image = resize_bilinear(prev, w, h);
        out.push(ScaleLevel {
            image,
            scale,
            ratio: (w0 as f32 / w as f32, h0 as f32 / h as f32),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, f: impl Fn(usize, usize) -> u8) -> Image<u8> {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Image::new(w, h, data).unwrap()
    }

    #[test]
    fn resize_keeps_constants_and_linear_ramps() {
        let flat = resize_bilinear(&image(50, 40, |_, _| 77), 41, 33);
        assert!(flat.data().iter().all(|&v| v == 77));
        // A ramp I = 2x + 10 resampled with aligned centers stays a ramp in level-0 units.
        let ramp = image(120, 10, |x, _| (2 * x + 10) as u8);
        let small = resize_bilinear(&ramp, 100, 10);
        for x in 2..98 {
            let s = (x as f64 + 0.5) * 1.2 - 0.5;
            let want = 2.0 * s + 10.0;
            assert!(
                (small.data()[5 * 100 + x] as f64 - want).abs() <= 1.0,
                "x {x}"
            );
        }
    }

    #[test]
    fn levels_follow_the_scale_factor_and_stop_at_the_minimum_size() {
        let base = image(200, 100, |x, y| ((x * 7 + y * 3) % 256) as u8);
        let levels = build_above(&base, 8, 1.2, 31);
        // 100 / 1.2^l >= 31 for l <= 6.
        assert_eq!(levels.len(), 6);
        for (l, level) in levels.iter().enumerate() {
            let s = 1.2f32.powi(l as i32 + 1);
            assert!((level.scale - s).abs() < 1e-5 * s);
            assert_eq!(
                level.image.size(),
                ((200.0 / s).round() as usize, (100.0 / s).round() as usize)
            );
        }
    }
}
