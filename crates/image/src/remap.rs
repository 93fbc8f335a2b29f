//! Precomputed resampling ("remap"): output pixel `i` takes the source image at
//! `(map_x[i], map_y[i])`, source pixels.
//!
//! The bilinear taps of every output pixel are computed once ([`Remap::new`]) and applied to
//! every image of that geometry: undistortion (the map `u -> K D(K^-1 u)` of a camera, built
//! once per camera and image size), rectification, any fixed warp. Grey levels are
//! interpolated bilinearly ([`Remap::bilinear`]); depth takes the nearest tap
//! ([`Remap::nearest`]) so that depth edges are not blurred. Output pixels whose source lies
//! outside `[0, w-1] x [0, h-1]` of the source get the caller's `outside` value.

use rayon::prelude::*;

use crate::buffer::Image;
use crate::error::ImageError;
use crate::sample::Bilinear;

/// Output pixels per parallel task of a remap.
const REMAP_BLOCK: usize = 32 * 1024;

/// Marks an output pixel whose source is outside the source image.
const OUTSIDE: u32 = u32::MAX;

/// A resampling of `source_size` images onto `size` images, with its taps precomputed.
#[derive(Debug, Clone, PartialEq)]
pub struct Remap {
    /// `(width, height)` of the images it applies to.
    source: (usize, usize),
    /// `(width, height)` of the images it produces.
    size: (usize, usize),
    /// Bilinear taps of every output pixel: top-left source index ([`OUTSIDE`] outside) and
    /// fractions along `x` and `y`.
    taps: Vec<(u32, f32, f32)>,
}

impl Remap {
    /// The remap taking output pixel `(x, y)` of a `width x height` image from source position
    /// `(map_x[i], map_y[i])`, `i = y * width + x`, of a `source_width x source_height` image.
    ///
    /// Errors: [`ImageError::BadBuffer`] when a map does not hold `width * height` values,
    /// [`ImageError::InvalidConfig`] when the source has `u32::MAX` pixels or more.
    pub fn new(
        (source_width, source_height): (usize, usize),
        (width, height): (usize, usize),
        map_x: &[f32],
        map_y: &[f32],
    ) -> Result<Self, ImageError> {
        for map in [map_x, map_y] {
            if width.checked_mul(height) != Some(map.len()) {
                return Err(ImageError::BadBuffer {
                    len: map.len(),
                    width,
                    height,
                });
            }
        }
        if source_width
            .checked_mul(source_height)
            .is_none_or(|n| n >= OUTSIDE as usize)
        {
            return Err(ImageError::InvalidConfig(
                "remap source must have fewer than u32::MAX pixels",
            ));
        }
        let taps = map_x
            .par_iter()
            .zip(map_y.par_iter())
            .map(
                |(&x, &y)| match Bilinear::new(x, y, source_width, source_height) {
                    Some(t) => (t.index as u32, t.fx, t.fy),
                    None => (OUTSIDE, 0.0, 0.0),
                },
            )
            .collect();
        Ok(Self {
            source: (source_width, source_height),
            size: (width, height),
            taps,
        })
    }

    /// `(width, height)` of the images this remap applies to, pixels.
    pub fn source_size(&self) -> (usize, usize) {
        self.source
    }

    /// `(width, height)` of the images it produces, pixels.
    pub fn size(&self) -> (usize, usize) {
        self.size
    }

    /// `img` resampled bilinearly, `outside` where the source position is outside `img`.
    ///
    /// Error: [`ImageError::SizeMismatch`] unless `img` is of [`Remap::source_size`].
    pub fn bilinear(&self, img: &Image<f32>, outside: f32) -> Result<Image<f32>, ImageError> {
        self.check(img)?;
        let (w, d) = (img.width(), img.data());
        Ok(self.apply(|&(index, fx, fy)| {
            if index == OUTSIDE {
                return outside;
            }
            let i = index as usize;
            let top = d[i] + fx * (d[i + 1] - d[i]);
            let bottom = d[i + w] + fx * (d[i + w + 1] - d[i + w]);
            top + fy * (bottom - top)
        }))
    }

    /// `img` resampled at the tap nearest to each source position, `outside` where the
    /// source position is outside `img` (for depth maps: no blur across depth edges).
    ///
    /// Error: [`ImageError::SizeMismatch`] unless `img` is of [`Remap::source_size`].
    pub fn nearest(&self, img: &Image<f32>, outside: f32) -> Result<Image<f32>, ImageError> {
        self.check(img)?;
        let (w, d) = (img.width(), img.data());
        Ok(self.apply(|&(index, fx, fy)| {
            if index == OUTSIDE {
                return outside;
            }
            d[index as usize + usize::from(fx >= 0.5) + w * usize::from(fy >= 0.5)]
        }))
    }

    fn check(&self, img: &Image<f32>) -> Result<(), ImageError> {
        if img.size() == self.source {
            Ok(())
        } else {
            Err(ImageError::SizeMismatch {
                expected: self.source,
                found: img.size(),
            })
        }
    }

    /// The image of `value(tap)` of every output pixel, in parallel blocks.
    fn apply<F>(&self, value: F) -> Image<f32>
    where
        F: Fn(&(u32, f32, f32)) -> f32 + Sync,
    {
        let mut out = vec![0f32; self.taps.len()];
        out.par_chunks_mut(REMAP_BLOCK)
            .zip(self.taps.par_chunks(REMAP_BLOCK))
            .for_each(|(out, taps)| {
                for (o, tap) in out.iter_mut().zip(taps) {
                    *o = value(tap);
                }
            });
        Image::from_sized(self.size.0, self.size.1, out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> Image<f32> {
        let data = (0..w * h)
            .map(|i| 3.0 * (i % w) as f32 - 2.0 * (i / w) as f32)
            .collect();
        Image::new(w, h, data).unwrap()
    }

    #[test]
    fn a_shift_map_moves_a_ramp_and_marks_the_outside() {
        let (w, h) = (12, 9);
        let src = ramp(w, h);
        // Output (x, y) takes the source at (x + 0.25, y - 0.5).
        let map_x: Vec<f32> = (0..w * h).map(|i| (i % w) as f32 + 0.25).collect();
        let map_y: Vec<f32> = (0..w * h).map(|i| (i / w) as f32 - 0.5).collect();
        let remap = Remap::new((w, h), (w, h), &map_x, &map_y).unwrap();
        let out = remap.bilinear(&src, f32::NAN).unwrap();
        for y in 1..h {
            for x in 0..w - 1 {
                let want = 3.0 * (x as f32 + 0.25) - 2.0 * (y as f32 - 0.5);
                assert!((out.at(x, y) - want).abs() < 1e-4, "({x}, {y})");
            }
        }
        assert!(out.at(3, 0).is_nan() && out.at(w - 1, 4).is_nan());
        let near = remap.nearest(&src, -1.0).unwrap();
        // (x + 0.25, y - 0.5) rounds to (x, y) (fractions below one half go down).
        assert_eq!(near.at(4, 3), src.at(4, 3));
        assert_eq!(near.at(4, 0), -1.0);
    }

    #[test]
    fn sizes_are_checked() {
        assert!(matches!(
            Remap::new((4, 4), (2, 2), &[0.0; 3], &[0.0; 4]),
            Err(ImageError::BadBuffer { len: 3, .. })
        ));
        let remap = Remap::new((4, 4), (2, 1), &[0.0; 2], &[0.0; 2]).unwrap();
        assert_eq!(remap.size(), (2, 1));
        assert!(matches!(
            remap.bilinear(&Image::filled(3, 4, 0.0), 0.0),
            Err(ImageError::SizeMismatch { .. })
        ));
    }
}
