//! Filters of `f32` images: the binomial blur, factor-2 decimation (one pyramid level),
//! central-difference gradients, and bilinear sampling.
//!
//! [`Image::pyr_down`] halves the resolution with the binomial kernel `[1 4 6 4 1] / 16`
//! (separable, borders replicated) followed by keeping every other pixel, so that pixel `x_l`
//! of level `l` sits at `x_0 = 2^l x_l` of level 0 (no half-pixel shift): intrinsics scale as
//! `f_l = f / 2^l`, `c_l = c / 2^l`.
//!
//! Every per-pixel loop walks contiguous rows with slice iterators so that it vectorizes.

use crate::buffer::Image;
use crate::sample::Bilinear;

impl Image<f32> {
    /// Bilinear interpolation at `(x, y)`; `None` outside `[0, w-1] x [0, h-1]` or for NaN.
    ///
    /// `I(x, y) = (1-fy) ((1-fx) I00 + fx I10) + fy ((1-fx) I01 + fx I11)`.
    #[inline]
    pub fn sample(&self, x: f32, y: f32) -> Option<f32> {
        let tap = Bilinear::new(x, y, self.width(), self.height())?;
        Some(tap.apply(self.data()))
    }

    /// Half-resolution plane: `[1 4 6 4 1] / 16` blur in both directions, then every even
    /// pixel; the result is `ceil(w / 2) x ceil(h / 2)`.
    pub fn pyr_down(&self) -> Image<f32> {
        let (w, h) = self.size();
        let (w2, h2) = (w.div_ceil(2), h.div_ceil(2));
        if w == 0 || h == 0 {
            return Image::filled(w2, h2, 0.0);
        }
        let mut out = vec![0f32; w2 * h2];
        let mut column = vec![0f32; w];
        for (y2, dst) in out.chunks_exact_mut(w2).enumerate() {
            // Vertical pass over whole rows (vectorizes), then the decimated horizontal pass.
            self.vertical_tap5(2 * y2, &mut column);
            horizontal_tap5::<2>(&column, dst);
        }
        Image::from_sized(w2, h2, out)
    }

    /// Row `y` of the vertical `[1 4 6 4 1] / 16` filter (rows replicated at the borders).
    fn vertical_tap5(&self, y: usize, out: &mut [f32]) {
        let h = self.height() as isize;
        let row = |k: isize| self.row((y as isize + k).clamp(0, h - 1) as usize);
        let (a, b, m, d, e) = (row(-2), row(-1), row(0), row(1), row(2));
        for (i, o) in out.iter_mut().enumerate() {
            *o = tap5(a[i], b[i], m[i], d[i], e[i]);
        }
    }

    /// The plane blurred by the binomial kernel `[1 4 6 4 1] / 16` in both directions (a
    /// Gaussian of sigma 1 pixel), borders replicated.
    pub fn blur(&self) -> Image<f32> {
        let (w, h) = self.size();
        if w == 0 || h == 0 {
            return self.clone();
        }
        let mut out = vec![0f32; w * h];
        let mut column = vec![0f32; w];
        for (y, dst) in out.chunks_exact_mut(w).enumerate() {
            self.vertical_tap5(y, &mut column);
            horizontal_tap5::<1>(&column, dst);
        }
        Image::from_sized(w, h, out)
    }

    /// Central-difference gradients `gx = (I(x+1) - I(x-1)) / 2`, `gy = (I(y+1) - I(y-1)) / 2`
    /// in grey levels per pixel; the one-pixel border is 0.
    pub fn gradients(&self) -> Gradients {
        let (w, h) = self.size();
        let mut gx = vec![0f32; w * h];
        let mut gy = vec![0f32; w * h];
        if w >= 3 && h >= 3 {
            for y in 1..h - 1 {
                let row = self.row(y);
                let out = &mut gx[y * w + 1..(y + 1) * w - 1];
                for ((o, a), b) in out.iter_mut().zip(&row[2..]).zip(&row[..w - 2]) {
                    *o = 0.5 * (a - b);
                }
                let (up, down) = (self.row(y - 1), self.row(y + 1));
                let out = &mut gy[y * w + 1..(y + 1) * w - 1];
                for ((o, a), b) in out.iter_mut().zip(&down[1..w - 1]).zip(&up[1..w - 1]) {
                    *o = 0.5 * (a - b);
                }
            }
        }
        Gradients {
            gx: Image::from_sized(w, h, gx),
            gy: Image::from_sized(w, h, gy),
        }
    }
}

/// The binomial kernel `(a + 4b + 6c + 4d + e) / 16`.
#[inline]
fn tap5(a: f32, b: f32, c: f32, d: f32, e: f32) -> f32 {
    (a + e + 4.0 * (b + d) + 6.0 * c) * 0.0625
}

/// `dst[x] = tap5` of `src` around `STEP * x` (borders replicated); `STEP` is 1 ([`Image::blur`])
/// or 2 ([`Image::pyr_down`]), a constant so that each pass compiles to its own loop.
fn horizontal_tap5<const STEP: usize>(src: &[f32], dst: &mut [f32]) {
    let w = src.len();
    // Outputs `first..end` have all five taps inside (`2 <= STEP x <= w - 3`): no clamping.
    let (first, end) = if w >= 5 {
        (2usize.div_ceil(STEP), (w - 3) / STEP + 1)
    } else {
        (0, 0)
    };
    let interior = dst[first..end].iter_mut();
    if STEP == 1 {
        for (o, t) in interior.zip(src.windows(5)) {
            *o = tap5(t[0], t[1], t[2], t[3], t[4]);
        }
    } else {
        for (o, t) in interior.zip(src.windows(5).step_by(STEP)) {
            *o = tap5(t[0], t[1], t[2], t[3], t[4]);
        }
    }
    // The few outputs at the borders (all of them on a row narrower than five), taps clamped.
    let at = |x: isize| src[x.clamp(0, w as isize - 1) as usize];
    let n = dst.len();
    for x in (0..first).chain(end..n) {
        let c = (STEP * x) as isize;
        dst[x] = tap5(at(c - 2), at(c - 1), at(c), at(c + 1), at(c + 2));
    }
}

/// Horizontal and vertical image gradients, grey levels per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Gradients {
    /// `dI/dx`.
    pub gx: Image<f32>,
    /// `dI/dy`.
    pub gy: Image<f32>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> Image<f32> {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| 3.0 * x as f32 - 2.0 * y as f32))
            .collect();
        Image::new(w, h, data).unwrap()
    }

    #[test]
    fn bilinear_is_exact_on_a_ramp_and_rejects_outside() {
        let p = ramp(10, 8);
        let v = p.sample(4.25, 3.5).unwrap();
        assert!((v - (3.0 * 4.25 - 2.0 * 3.5)).abs() < 1e-5);
        assert_eq!(p.sample(9.0, 7.0), Some(27.0 - 14.0));
        assert_eq!(p.sample(-0.01, 2.0), None);
        assert_eq!(p.sample(9.01, 2.0), None);
        assert_eq!(p.sample(f32::NAN, 2.0), None);
    }

    #[test]
    fn gradients_of_a_ramp_are_its_slopes() {
        let g = ramp(10, 8).gradients();
        assert_eq!(g.gx.at(5, 4), 3.0);
        assert_eq!(g.gy.at(5, 4), -2.0);
        assert_eq!(g.gx.at(0, 4), 0.0);
    }

    #[test]
    fn pyr_down_keeps_a_ramp_aligned_at_even_pixels() {
        // Away from the borders the binomial blur reproduces a linear ramp, and level-1 pixel x
        // samples level-0 position 2x.
        let p = ramp(20, 16);
        let d = p.pyr_down();
        assert_eq!(d.size(), (10, 8));
        assert!((d.at(4, 3) - p.at(8, 6)).abs() < 1e-4);
    }

    /// The interior loops and the clamped border outputs together give the clamped kernel at
    /// every output, for rows narrower than the kernel too.
    #[test]
    fn horizontal_taps_are_the_clamped_kernel_at_every_width() {
        for w in 1..12 {
            let src: Vec<f32> = (0..w).map(|i| ((i * 37) % 11) as f32).collect();
            let at = |x: isize| src[x.clamp(0, w as isize - 1) as usize];
            let kernel = |c: isize| tap5(at(c - 2), at(c - 1), at(c), at(c + 1), at(c + 2));
            let mut full = vec![f32::NAN; w];
            horizontal_tap5::<1>(&src, &mut full);
            let mut half = vec![f32::NAN; w.div_ceil(2)];
            horizontal_tap5::<2>(&src, &mut half);
            assert!(full
                .iter()
                .enumerate()
                .all(|(x, &v)| v == kernel(x as isize)));
            assert!(half
                .iter()
                .enumerate()
                .all(|(x, &v)| v == kernel(2 * x as isize)));
        }
    }

    #[test]
    fn blur_keeps_a_ramp_and_sums_to_one() {
        let p = ramp(12, 9);
        let b = p.blur();
        assert!((b.at(5, 4) - p.at(5, 4)).abs() < 1e-4);
        let c = Image::filled(7, 6, 3.0).blur();
        assert!(c.data().iter().all(|v| (v - 3.0).abs() < 1e-6));
    }
}
