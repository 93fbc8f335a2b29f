//! RGB-D reference frames: a grey image with metric depth, brought to a pinhole camera.
//!
//! Lens distortion is removed once per image by a remap: output pixel `u` of the pinhole image
//! (same intrinsics `K`) takes the input value at `K D(K^-1 u)` (bilinear for grey levels,
//! nearest for depth (the tap closest to the source point), so that depth edges are not blurred). The depth `Z` of a surface point
//! does not change under undistortion, so the remapped depth stays metric. Outside the input
//! image the grey level is NaN and the depth 0 (both invalid).

use std::borrow::Cow;
use std::sync::Arc;

use nalgebra::Vector2;
use rayon::prelude::*;
use vofront_core::{Camera, Pinhole};

use crate::error::DirectError;
use crate::plane::{Bilinear, Plane};

/// Smallest image side accepted for an RGB-D frame, pixels.
pub const MIN_RGBD_SIDE: usize = 16;

/// Output pixels per parallel task of a remap.
const REMAP_BLOCK: usize = 32 * 1024;

/// The undistortion remap of one camera at one image size.
#[derive(Debug, Clone, PartialEq)]
pub struct Undistorter {
    /// Image width, pixels.
    width: usize,
    /// Image height, pixels.
    height: usize,
    /// Bilinear taps of every output pixel: top-left index (`u32::MAX` outside) and fractions.
    taps: Vec<(u32, f32, f32)>,
}

impl Undistorter {
    /// The map `u -> K D(K^-1 u)` for a `width x height` image of `camera`.
    pub fn new(camera: &Camera, width: usize, height: usize) -> Result<Self, DirectError> {
        camera.validate()?;
        let mut map_x = vec![0f32; width * height];
        let mut map_y = vec![0f32; width * height];
        map_x
            .par_chunks_mut(width.max(1))
            .zip(map_y.par_chunks_mut(width.max(1)))
            .enumerate()
            .for_each(|(y, (mx, my))| {
                for (x, (ox, oy)) in mx.iter_mut().zip(my.iter_mut()).enumerate() {
                    let n = camera
                        .pinhole
                        .to_normalized(&Vector2::new(x as f64, y as f64));
                    let src = camera.normalized_to_pixel(&n);
                    *ox = src.x as f32;
                    *oy = src.y as f32;
                }
            });
        let taps = map_x
            .par_iter()
            .zip(map_y.par_iter())
            .map(|(&x, &y)| match Bilinear::new(x, y, width, height) {
                Some(t) => (t.index as u32, t.fx, t.fy),
                None => (u32::MAX, 0.0, 0.0),
            })
            .collect();
        Ok(Self {
            width,
            height,
            taps,
        })
    }

    /// `(width, height)` of the images this remap applies to, pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// `value(tap)` of every output pixel, in parallel blocks of rows.
    fn remap<F>(&self, value: F) -> Vec<f32>
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
        out
    }

    fn check(&self, img: &Plane) -> Result<(), DirectError> {
        if img.size() == (self.width, self.height) {
            Ok(())
        } else {
            Err(DirectError::SizeMismatch {
                expected: (self.width, self.height),
                found: img.size(),
            })
        }
    }

    /// The pinhole image of `img` (bilinear, NaN where the source is outside).
    pub fn undistort_image(&self, img: &Plane) -> Result<Plane, DirectError> {
        self.check(img)?;
        let (w, d) = (img.width(), img.data());
        let data = self.remap(|&(index, fx, fy)| {
            if index == u32::MAX {
                return f32::NAN;
            }
            let i = index as usize;
            let top = d[i] + fx * (d[i + 1] - d[i]);
            let bottom = d[i + w] + fx * (d[i + w + 1] - d[i + w]);
            top + fy * (bottom - top)
        });
        Plane::new(self.width, self.height, data)
    }

    /// The pinhole depth map of `depth` (nearest neighbour, 0 where the source is outside).
    pub fn undistort_depth(&self, depth: &Plane) -> Result<Plane, DirectError> {
        self.check(depth)?;
        let (w, d) = (depth.width(), depth.data());
        let data = self.remap(|&(index, fx, fy)| {
            if index == u32::MAX {
                return 0.0;
            }
            let i = index as usize + usize::from(fx >= 0.5) + w * usize::from(fy >= 0.5);
            d[i]
        });
        Plane::new(self.width, self.height, data)
    }
}

/// `img` in the pinhole geometry: remapped by `undistorter`, or borrowed as it is without one.
pub(crate) fn pinhole_image<'a>(
    undistorter: Option<&Undistorter>,
    img: &'a Plane,
) -> Result<Cow<'a, Plane>, DirectError> {
    match undistorter {
        Some(u) => Ok(Cow::Owned(u.undistort_image(img)?)),
        None => Ok(Cow::Borrowed(img)),
    }
}

/// A reference frame for SE(3) alignment: grey image and depth in a pinhole camera.
///
/// Invariants (checked by [`RgbdFrame::new`] / [`RgbdFrame::with_undistorter`], hence private
/// fields): image and depth have the same size, both sides at least [`MIN_RGBD_SIDE`], valid
/// intrinsics, at least one valid depth, and the remap (if any) is for that size.
#[derive(Debug, Clone)]
pub struct RgbdFrame {
    /// Grey levels, undistorted (NaN where unknown).
    image: Plane,
    /// Depth `Z` in metres along the optical axis, undistorted; `0` or NaN = unknown.
    depth: Plane,
    /// Intrinsics of `image` and `depth`.
    pinhole: Pinhole,
    /// The remap applied to the inputs, reused for the current images (`None` without
    /// distortion).
    undistorter: Option<Arc<Undistorter>>,
}

impl RgbdFrame {
    /// A frame from a grey image and a depth map (metres, `0`/NaN invalid) of the same size
    /// taken by `camera`; both are undistorted once when the camera has lens distortion.
    ///
    /// Errors: [`DirectError::SizeMismatch`], [`DirectError::ImageTooSmall`],
    /// [`DirectError::Camera`], [`DirectError::NoValidDepth`].
    pub fn new(image: Plane, depth: Plane, camera: &Camera) -> Result<Self, DirectError> {
        let undistorter = if camera.distortion.is_identity() {
            camera.validate()?;
            None
        } else {
            Some(Arc::new(Undistorter::new(
                camera,
                image.width(),
                image.height(),
            )?))
        };
        Self::with_undistorter(image, depth, camera.pinhole, undistorter)
    }

    /// Like [`RgbdFrame::new`] but reusing a remap built once for the camera (a video stream).
    pub fn with_undistorter(
        image: Plane,
        depth: Plane,
        pinhole: Pinhole,
        undistorter: Option<Arc<Undistorter>>,
    ) -> Result<Self, DirectError> {
        image.check_same_size(&depth)?;
        image.check_min_size(MIN_RGBD_SIDE)?;
        pinhole.validate()?;
        let (image, depth) = match &undistorter {
            Some(u) => (u.undistort_image(&image)?, u.undistort_depth(&depth)?),
            None => (image, depth),
        };
        if !depth.data().iter().any(|&z| z > 0.0 && z.is_finite()) {
            return Err(DirectError::NoValidDepth);
        }
        Ok(Self {
            image,
            depth,
            pinhole,
            undistorter,
        })
    }

    /// Grey levels, undistorted (NaN where unknown).
    pub fn image(&self) -> &Plane {
        &self.image
    }

    /// Depth `Z` in metres along the optical axis, undistorted; `0` or NaN = unknown.
    pub fn depth(&self) -> &Plane {
        &self.depth
    }

    /// Intrinsics of [`RgbdFrame::image`] and [`RgbdFrame::depth`].
    pub fn pinhole(&self) -> &Pinhole {
        &self.pinhole
    }

    /// The remap applied to the inputs, reused for the current images (`None` without
    /// distortion).
    pub fn undistorter(&self) -> Option<&Arc<Undistorter>> {
        self.undistorter.as_ref()
    }

    /// `img` (a current image from the same camera) brought to the pinhole geometry.
    pub fn prepare_current(&self, img: &Plane) -> Result<Plane, DirectError> {
        self.image.check_same_size(img)?;
        Ok(pinhole_image(self.undistorter.as_deref(), img)?.into_owned())
    }
}
