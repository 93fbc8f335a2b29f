//! The one image type: a row-major `width x height` grid of `u8` or `f32` values.
//!
//! Pixel `(x, y)` is the center of column `x`, row `y`; `(0, 0)` is the top-left pixel. Rows are
//! contiguous (stride = width), so that per-pixel loops walk slices and vectorize.

use image::{GrayImage, ImageBuffer, Luma};

use crate::error::ImageError;

/// A row-major `width x height` image of `T` (`u8` grey levels, or `f32`: grey levels
/// `0.0..=255.0` for 8-bit content, metres for depth, NaN for unknown).
///
/// Invariant: `data().len() == width() * height()`; the fields are private so that every image
/// is built by a constructor that checks it, and values are changed in place through
/// [`Image::data_mut`], which cannot change the length.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image<T> {
    /// Columns.
    width: usize,
    /// Rows.
    height: usize,
    /// `data[y * width + x]`, `width * height` values.
    data: Vec<T>,
}

impl<T> Image<T> {
    /// An image from a row-major buffer; [`ImageError::BadBuffer`] when `data.len() != w * h`
    /// (or when `w * h` overflows).
    pub fn new(width: usize, height: usize, data: Vec<T>) -> Result<Self, ImageError> {
        if width.checked_mul(height) != Some(data.len()) {
            return Err(ImageError::BadBuffer {
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

    /// An image from parts the caller has sized (`data.len() == width * height`): for the
    /// crate's own operations, which compute their output sizes.
    #[inline]
    pub(crate) fn from_sized(width: usize, height: usize, data: Vec<T>) -> Self {
        debug_assert_eq!(data.len(), width * height);
        Self {
            width,
            height,
            data,
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
    pub fn data(&self) -> &[T] {
        &self.data
    }

    /// The values, writable in place (the length, hence the invariant, cannot change).
    #[inline]
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// The row-major buffer, consuming the image.
    pub fn into_data(self) -> Vec<T> {
        self.data
    }

    /// Row `y` as a slice of `width` values (panics for `y >= height`, like slice indexing).
    #[inline]
    pub fn row(&self, y: usize) -> &[T] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// The value at `(x, y)`, `None` outside the image.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Option<&T> {
        if x < self.width && y < self.height {
            self.data.get(y * self.width + x)
        } else {
            None
        }
    }

    /// [`ImageError::SizeMismatch`] unless `other` has the size of `self`.
    pub fn check_same_size<U>(&self, other: &Image<U>) -> Result<(), ImageError> {
        if self.size() == other.size() {
            Ok(())
        } else {
            Err(ImageError::SizeMismatch {
                expected: self.size(),
                found: other.size(),
            })
        }
    }

    /// [`ImageError::ImageTooSmall`] unless both sides are at least `min` pixels.
    pub fn check_min_size(&self, min: usize) -> Result<(), ImageError> {
        if self.width >= min && self.height >= min {
            Ok(())
        } else {
            Err(ImageError::ImageTooSmall {
                width: self.width,
                height: self.height,
                min,
            })
        }
    }

    /// The image of `f(value)` for every pixel, same size.
    pub fn map<U>(&self, f: impl Fn(&T) -> U) -> Image<U> {
        Image {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }
}

impl<T: Copy> Image<T> {
    /// An image filled with `value`.
    ///
    /// Panics when `width * height` overflows `usize` (like `vec![value; n]` beyond memory);
    /// sizes that come from input should go through [`Image::new`].
    pub fn filled(width: usize, height: usize, value: T) -> Self {
        let len = width
            .checked_mul(height)
            .expect("Image::filled: width * height overflows usize");
        Self {
            width,
            height,
            data: vec![value; len],
        }
    }

    /// Value of pixel `(x, y)` (panics outside, like slice indexing; [`Image::get`] is the
    /// checked form).
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> T {
        self.data[y * self.width + x]
    }
}

impl Image<u8> {
    /// The grey levels of an 8-bit image (copied).
    pub fn from_gray(img: &GrayImage) -> Self {
        Self::from_gray_owned(img.clone())
    }

    /// The grey levels of an 8-bit image, taking its buffer without a copy.
    pub fn from_gray_owned(img: GrayImage) -> Self {
        Self {
            width: img.width() as usize,
            height: img.height() as usize,
            data: img.into_raw(),
        }
    }

    /// The `image` crate's 8-bit image of the same values; `None` when a side exceeds `u32`.
    pub fn to_gray(&self) -> Option<GrayImage> {
        let (w, h) = (
            u32::try_from(self.width).ok()?,
            u32::try_from(self.height).ok()?,
        );
        GrayImage::from_raw(w, h, self.data.clone())
    }

    /// The same grey levels as `f32`, `0.0..=255.0`.
    pub fn to_f32(&self) -> Image<f32> {
        self.map(|&v| f32::from(v))
    }
}

impl Image<f32> {
    /// Grey levels of an 8-bit image, as `0.0..=255.0`.
    pub fn from_gray8(img: &GrayImage) -> Self {
        Self {
            width: img.width() as usize,
            height: img.height() as usize,
            data: img.as_raw().iter().map(|&v| f32::from(v)).collect(),
        }
    }

    /// The values of a float image of the `image` crate (`ImageBuffer<Luma<f32>, Vec<f32>>`).
    pub fn from_gray_f32(img: &ImageBuffer<Luma<f32>, Vec<f32>>) -> Self {
        Self {
            width: img.width() as usize,
            height: img.height() as usize,
            data: img.as_raw().clone(),
        }
    }

    /// The `image` crate's float image of the same values; `None` when a side exceeds `u32`.
    pub fn to_gray_f32(&self) -> Option<ImageBuffer<Luma<f32>, Vec<f32>>> {
        let (w, h) = (
            u32::try_from(self.width).ok()?,
            u32::try_from(self.height).ok()?,
        );
        ImageBuffer::from_raw(w, h, self.data.clone())
    }

    /// 8-bit grey levels: each value rounded and clamped to `0..=255`, NaN as 0.
    pub fn to_u8(&self) -> Image<u8> {
        // `as` saturates and maps NaN to 0.
        self.map(|&v| v.round() as u8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_buffer_and_overflow_are_errors() {
        assert!(matches!(
            Image::new(3, 3, vec![0.0f32; 8]),
            Err(ImageError::BadBuffer { len: 8, .. })
        ));
        assert!(matches!(
            Image::<u8>::new(usize::MAX, 2, vec![]),
            Err(ImageError::BadBuffer { .. })
        ));
    }

    #[test]
    fn checked_access_and_sizes() {
        let img = Image::new(3, 2, vec![1u8, 2, 3, 4, 5, 6]).unwrap();
        assert_eq!(img.get(2, 1), Some(&6));
        assert_eq!(img.get(3, 0), None);
        assert_eq!(img.get(0, 2), None);
        assert_eq!(img.row(1), &[4, 5, 6]);
        assert!(img.check_same_size(&Image::filled(3, 2, 0.0f32)).is_ok());
        assert!(matches!(
            img.check_same_size(&Image::filled(2, 3, 0u8)),
            Err(ImageError::SizeMismatch {
                expected: (3, 2),
                found: (2, 3)
            })
        ));
        assert!(matches!(
            img.check_min_size(3),
            Err(ImageError::ImageTooSmall { min: 3, .. })
        ));
    }

    #[test]
    fn conversions_round_trip() {
        let gray = GrayImage::from_fn(5, 4, |x, y| Luma([(x * 50 + y) as u8]));
        let img = Image::from_gray(&gray);
        assert_eq!(img.to_gray().unwrap(), gray);
        let f = img.to_f32();
        assert_eq!(f, Image::from_gray8(&gray));
        assert_eq!(f.to_u8(), img);
        assert_eq!(
            Image::from_gray_f32(&f.to_gray_f32().unwrap()),
            f,
            "f32 round trip"
        );
        let odd = Image::new(4, 1, vec![-3.0f32, 254.6, 300.0, f32::NAN]).unwrap();
        assert_eq!(odd.to_u8().data(), &[0, 255, 255, 0]);
    }
}
