//! Bilinear sampling: the four taps of a sub-pixel position, shared by [`Image::sample`] and
//! [`crate::remap::Remap`]; and a pattern of whole-pixel offsets around one sub-pixel position
//! ([`Image::sample_pattern`]), whose samples share one set of fractions.
//!
//! `I(x, y) = (1-fy) ((1-fx) I00 + fx I10) + fy ((1-fx) I01 + fx I11)` with `(x0, y0)` the
//! top-left tap and `(fx, fy)` the fractions.

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

impl Image<f32> {
    /// Bilinear samples at `(x + dx_k, y + dy_k)` for whole-pixel `offsets`: equal to
    /// [`Image::sample`] at each (up to the rounding of `x + dx_k` in `f32`), with one bounds
    /// test for the whole pattern and the fractions `(fx, fy)` computed once. `None` when a
    /// sample's four taps are not all inside the image (a pattern touching the last row or
    /// column included) or `(x, y)` is NaN.
    #[inline]
    pub fn sample_pattern<const N: usize>(
        &self,
        x: f32,
        y: f32,
        offsets: &[(i32, i32); N],
    ) -> Option<[f32; N]> {
        let (w, h) = self.size();
        let (mut lo_x, mut hi_x, mut lo_y, mut hi_y) = (0, 0, 0, 0);
        for &(dx, dy) in offsets {
            (lo_x, hi_x) = (lo_x.min(dx), hi_x.max(dx));
            (lo_y, hi_y) = (lo_y.min(dy), hi_y.max(dy));
        }
        // Every tap (x0 + dx .. x0 + dx + 1) inside: x + lo_x >= 0 and x + hi_x < w - 1.
        let inside = x + lo_x as f32 >= 0.0
            && y + lo_y as f32 >= 0.0
            && x + (hi_x as f32) < w as f32 - 1.0
            && y + (hi_y as f32) < h as f32 - 1.0;
        if !inside {
            return None;
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as isize, y0 as isize);
        let data = self.data();
        let mut out = [0f32; N];
        for (o, &(dx, dy)) in out.iter_mut().zip(offsets) {
            let i = ((y0 + dy as isize) * w as isize + x0 + dx as isize) as usize;
            let top = data[i] + fx * (data[i + 1] - data[i]);
            let j = i + w;
            let bottom = data[j] + fx * (data[j + 1] - data[j]);
            *o = top + fy * (bottom - top);
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use crate::buffer::Image;

    const CROSS: [(i32, i32); 5] = [(0, -2), (-1, 0), (0, 0), (2, 0), (0, 1)];

    fn textured() -> Image<f32> {
        let data = (0..13 * 9)
            .map(|i| ((i * 37) % 23) as f32 + 0.25 * (i % 13) as f32)
            .collect();
        Image::new(13, 9, data).unwrap()
    }

    /// Each sample equals the one-pixel sampler's at the offset position.
    #[test]
    fn a_pattern_samples_as_the_pixels_do_one_by_one() {
        let img = textured();
        for &(x, y) in &[(3.3, 2.7), (1.0, 2.0), (9.99, 6.5), (5.5, 4.0)] {
            let pattern = img.sample_pattern(x, y, &CROSS).unwrap();
            for (s, &(dx, dy)) in pattern.iter().zip(&CROSS) {
                let one = img.sample(x + dx as f32, y + dy as f32).unwrap();
                assert!(
                    (s - one).abs() < 1e-4,
                    "({x}, {y}) + ({dx}, {dy}): {s} vs {one}"
                );
            }
        }
    }

    /// A pattern reaching the last column or row, or outside, or at NaN, gives nothing.
    #[test]
    fn a_pattern_leaving_the_image_gives_none() {
        let img = textured();
        assert!(img.sample_pattern(10.0, 4.0, &CROSS).is_none());
        assert!(img.sample_pattern(9.999, 6.99, &CROSS).is_some());
        assert!(img.sample_pattern(5.0, 7.0, &CROSS).is_none());
        assert!(img.sample_pattern(0.5, 4.0, &CROSS).is_none());
        assert!(img.sample_pattern(5.0, 1.9, &CROSS).is_none());
        assert!(img.sample_pattern(f32::NAN, 4.0, &CROSS).is_none());
    }
}
