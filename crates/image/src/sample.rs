//! Bilinear sampling: the four taps of a sub-pixel position, shared by [`Image::sample`] and
//! [`crate::remap::Remap`].
//!
//! `I(x, y) = (1-fy) ((1-fx) I00 + fx I10) + fy ((1-fx) I01 + fx I11)` with `(x0, y0)` the
//! top-left tap and `(fx, fy)` the fractions.

#[cfg(doc)]
use crate::buffer::Image;

/// The four taps of a bilinear interpolation: top-left index and fractional offsets.
#[derive(Debug, Clone, Copy)]
pub struct Bilinear {
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
