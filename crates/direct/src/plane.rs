//! Float image planes, image pyramids, gradients and bilinear sampling.
//!
//! Pixel `(x, y)` is the center of column `x`, row `y`; `(0, 0)` is the top-left pixel.
//! A [`Pyramid`] halves the resolution at each level with the binomial kernel
//! `[1 4 6 4 1] / 16` (separable, borders replicated) followed by keeping every other pixel,
//! so that pixel `x_l` of level `l` sits at `x_0 = 2^l x_l` of level 0 (no half-pixel shift):
//! intrinsics scale as `f_l = f / 2^l`, `c_l = c / 2^l`.
//!
//! Every per-pixel loop walks contiguous rows with slice iterators so that it vectorizes.

use image::{GrayImage, ImageBuffer, Luma};

use crate::error::DirectError;

/// A row-major `width x height` image of `f32` values (grey levels 0..255 for 8-bit content).
///
/// Invariant: `data().len() == width() * height()`; the fields are private so that every
/// plane is built by a constructor that checks it, and values are changed in place through
/// [`Plane::data_mut`], which cannot change the length.
#[derive(Debug, Clone, PartialEq)]
pub struct Plane {
    /// Columns.
    width: usize,
    /// Rows.
    height: usize,
    /// `data[y * width + x]`, `width * height` values.
    data: Vec<f32>,
}

impl Plane {
    /// A plane from a row-major buffer; [`DirectError::BadBuffer`] when `data.len() != w * h`
    /// (or when `w * h` overflows).
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Result<Self, DirectError> {
        if width.checked_mul(height) != Some(data.len()) {
            return Err(DirectError::BadBuffer {
                len: data.len(),
                width,
                height,
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// A plane filled with `value`.
    ///
    /// Panics when `width * height` overflows `usize` (like `vec![value; n]` beyond memory);
    /// sizes that come from input should go through [`Plane::new`].
    pub fn filled(width: usize, height: usize, value: f32) -> Self {
        let len = width
            .checked_mul(height)
            .expect("Plane::filled: width * height overflows usize");
        Self {
            width,
            height,
            data: vec![value; len],
        }
    }

    /// Grey levels of an 8-bit image, as `0.0..=255.0`.
    pub fn from_gray8(img: &GrayImage) -> Self {
        Self {
            width: img.width() as usize,
            height: img.height() as usize,
            data: img.as_raw().iter().map(|&v| f32::from(v)).collect(),
        }
    }

    /// The values of a float image (for example `vofront_fixtures::GrayF32`).
    pub fn from_gray_f32(img: &ImageBuffer<Luma<f32>, Vec<f32>>) -> Self {
        Self {
            width: img.width() as usize,
            height: img.height() as usize,
            data: img.as_raw().clone(),
        }
    }

    /// Columns.
    #[inline]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    #[inline]
    pub fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)`.
    #[inline]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The row-major values, `data()[y * width + x]`, `width * height` of them.
    #[inline]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The values, writable in place (the length, hence the invariant, cannot change).
    #[inline]
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// The row-major buffer, consuming the plane.
    pub fn into_data(self) -> Vec<f32> {
        self.data
    }

    /// Row `y` as a slice of `width` values.
    #[inline]
    pub fn row(&self, y: usize) -> &[f32] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// Value of pixel `(x, y)` (panics outside, like slice indexing).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// [`DirectError::SizeMismatch`] unless `other` has the size of `self`.
    pub fn check_same_size(&self, other: &Plane) -> Result<(), DirectError> {
        if self.size() == other.size() {
            Ok(())
        } else {
            Err(DirectError::SizeMismatch {
                expected: self.size(),
                found: other.size(),
            })
        }
    }

    /// [`DirectError::ImageTooSmall`] unless both sides are at least `min` pixels.
    pub fn check_min_size(&self, min: usize) -> Result<(), DirectError> {
        if self.width >= min && self.height >= min {
            Ok(())
        } else {
            Err(DirectError::ImageTooSmall {
                width: self.width,
                height: self.height,
                min,
            })
        }
    }

    /// Bilinear interpolation at `(x, y)`; `None` outside `[0, w-1] x [0, h-1]` or for NaN.
    ///
    /// `I(x, y) = (1-fy) ((1-fx) I00 + fx I10) + fy ((1-fx) I01 + fx I11)`.
    #[inline]
    pub fn sample(&self, x: f32, y: f32) -> Option<f32> {
        let tap = Bilinear::new(x, y, self.width, self.height)?;
        Some(tap.apply(&self.data))
    }

    /// Levels `1..levels` of the pyramid of `self` (as [`Pyramid::new`] builds them, without
    /// copying `self`): each level is [`Plane::pyr_down`] of the previous one, stopping before a
    /// side would drop below `min_side`.
    pub fn coarser_levels(&self, levels: usize, min_side: usize) -> Vec<Plane> {
        let mut out: Vec<Plane> = Vec::with_capacity(levels.saturating_sub(1));
        while out.len() + 1 < levels.max(1) {
            let last = out.last().unwrap_or(self);
            if last.width.div_ceil(2) < min_side || last.height.div_ceil(2) < min_side {
                break;
            }
            out.push(last.pyr_down());
        }
        out
    }

    /// Half-resolution plane: `[1 4 6 4 1] / 16` blur in both directions, then every even
    /// pixel; the result is `ceil(w / 2) x ceil(h / 2)`.
    pub fn pyr_down(&self) -> Plane {
        let (w, h) = (self.width, self.height);
        let (w2, h2) = (w.div_ceil(2), h.div_ceil(2));
        if w == 0 || h == 0 {
            return Plane::filled(w2, h2, 0.0);
        }
        let mut out = vec![0f32; w2 * h2];
        let mut column = vec![0f32; w];
        for (y2, dst) in out.chunks_exact_mut(w2).enumerate() {
            // Vertical pass over whole rows (vectorizes), then the decimated horizontal pass.
            self.vertical_tap5(2 * y2, &mut column);
            horizontal_tap5(&column, dst, 2);
        }
        Plane {
            width: w2,
            height: h2,
            data: out,
        }
    }

    /// Row `y` of the vertical `[1 4 6 4 1] / 16` filter (rows replicated at the borders).
    fn vertical_tap5(&self, y: usize, out: &mut [f32]) {
        let h = self.height as isize;
        let row = |k: isize| self.row((y as isize + k).clamp(0, h - 1) as usize);
        let (a, b, m, d, e) = (row(-2), row(-1), row(0), row(1), row(2));
        for (i, o) in out.iter_mut().enumerate() {
            *o = tap5(a[i], b[i], m[i], d[i], e[i]);
        }
    }

    /// The plane blurred by the binomial kernel `[1 4 6 4 1] / 16` in both directions (a
    /// Gaussian of sigma 1 pixel), borders replicated.
    pub fn blur(&self) -> Plane {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return self.clone();
        }
        let mut out = vec![0f32; w * h];
        let mut column = vec![0f32; w];
        for (y, dst) in out.chunks_exact_mut(w).enumerate() {
            self.vertical_tap5(y, &mut column);
            horizontal_tap5(&column, dst, 1);
        }
        Plane {
            width: w,
            height: h,
            data: out,
        }
    }

    /// Central-difference gradients `gx = (I(x+1) - I(x-1)) / 2`, `gy = (I(y+1) - I(y-1)) / 2`
    /// in grey levels per pixel; the one-pixel border is 0.
    pub fn gradients(&self) -> Gradients {
        let (w, h) = (self.width, self.height);
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
            gx: Plane {
                width: w,
                height: h,
                data: gx,
            },
            gy: Plane {
                width: w,
                height: h,
                data: gy,
            },
        }
    }
}

/// The binomial kernel `(a + 4b + 6c + 4d + e) / 16`.
#[inline]
fn tap5(a: f32, b: f32, c: f32, d: f32, e: f32) -> f32 {
    (a + e + 4.0 * (b + d) + 6.0 * c) * 0.0625
}

/// `dst[x] = tap5` of `src` around `step * x` (borders replicated); `step` 1 or 2.
fn horizontal_tap5(src: &[f32], dst: &mut [f32], step: usize) {
    let w = src.len();
    let at = |x: isize| src[x.clamp(0, w as isize - 1) as usize];
    // Outputs whose five taps are all inside need no clamping.
    let first = 2usize.div_ceil(step);
    let last = if w >= 5 { (w - 3) / step } else { 0 };
    if step == 1 && w >= 5 {
        for (o, t) in dst[2..w - 2].iter_mut().zip(src.windows(5)) {
            *o = tap5(t[0], t[1], t[2], t[3], t[4]);
        }
    } else if w >= 5 {
        for (x, o) in dst.iter_mut().enumerate().take(last + 1).skip(first) {
            let t = &src[step * x - 2..step * x + 3];
            *o = tap5(t[0], t[1], t[2], t[3], t[4]);
        }
    }
    for x in (0..dst.len()).filter(|&x| x < first || x > last || w < 5) {
        let c = (step * x) as isize;
        dst[x] = tap5(at(c - 2), at(c - 1), at(c), at(c + 1), at(c + 2));
    }
}

/// Horizontal and vertical image gradients, grey levels per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Gradients {
    /// `dI/dx`.
    pub gx: Plane,
    /// `dI/dy`.
    pub gy: Plane,
}

/// A Gaussian-like image pyramid: `levels[0]` is the input, each next level half the size.
#[derive(Debug, Clone, PartialEq)]
pub struct Pyramid {
    /// Finest first.
    pub levels: Vec<Plane>,
}

impl Pyramid {
    /// Up to `levels` levels (at least 1), stopping before a side would drop below `min_side`.
    pub fn new(base: Plane, levels: usize, min_side: usize) -> Self {
        let coarse = base.coarser_levels(levels, min_side);
        Self {
            levels: std::iter::once(base).chain(coarse).collect(),
        }
    }
}

/// The four taps of a bilinear interpolation: top-left index and fractional offsets.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bilinear {
    /// Row-major index of the top-left tap.
    pub index: usize,
    /// Row stride.
    pub stride: usize,
    /// Fraction along `x`.
    pub fx: f32,
    /// Fraction along `y`.
    pub fy: f32,
}

impl Bilinear {
    /// Taps for `(x, y)` in a `w x h` plane; `None` outside `[0, w-1] x [0, h-1]` (and NaN).
    #[inline]
    pub fn new(x: f32, y: f32, w: usize, h: usize) -> Option<Self> {
        if !(x >= 0.0 && y >= 0.0 && x <= (w as f32 - 1.0) && y <= (h as f32 - 1.0))
            || w < 2
            || h < 2
        {
            return None;
        }
        let x0 = (x as usize).min(w - 2);
        let y0 = (y as usize).min(h - 2);
        Some(Self {
            index: y0 * w + x0,
            stride: w,
            fx: x - x0 as f32,
            fy: y - y0 as f32,
        })
    }

    /// The interpolated value of `data` (a plane of the size given to [`Bilinear::new`]).
    #[inline]
    pub fn apply(&self, data: &[f32]) -> f32 {
        let i = self.index;
        let top = data[i] + self.fx * (data[i + 1] - data[i]);
        let j = i + self.stride;
        let bottom = data[j] + self.fx * (data[j + 1] - data[j]);
        top + self.fy * (bottom - top)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> Plane {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| 3.0 * x as f32 - 2.0 * y as f32))
            .collect();
        Plane::new(w, h, data).unwrap()
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

    #[test]
    fn blur_keeps_a_ramp_and_sums_to_one() {
        let p = ramp(12, 9);
        let b = p.blur();
        assert!((b.at(5, 4) - p.at(5, 4)).abs() < 1e-4);
        let c = Plane::filled(7, 6, 3.0).blur();
        assert!(c.data.iter().all(|v| (v - 3.0).abs() < 1e-6));
    }

    #[test]
    fn bad_buffer_is_an_error() {
        assert!(matches!(
            Plane::new(3, 3, vec![0.0; 8]),
            Err(DirectError::BadBuffer { .. })
        ));
    }
}
