//! RGB-D reference frames: a grey image with metric depth, brought to a pinhole camera.
//!
//! Lens distortion is removed once per image by a remap: output pixel `u` of the pinhole image
//! (same intrinsics `K`) takes the input value at `K D(K^-1 u)` (bilinear for grey levels,
//! nearest for depth (the tap closest to the source point), so that depth edges are not blurred). The depth `Z` of a surface point
//! does not change under undistortion, so the remapped depth stays metric. Outside the input
//! image the grey level is NaN and the depth 0 (both invalid).

use std::borrow::Cow;
use std::sync::Arc;

use vofront_core::{Camera, Pinhole, UndistortMap};
use vofront_image::{Image, Remap};
use vofront_robust::median_in_place;

use crate::error::DirectError;

/// Smallest image side accepted for an RGB-D frame, pixels.
pub const MIN_RGBD_SIDE: usize = 16;

/// The undistortion remap of one camera at one image size: the map `u -> K D(K^-1 u)`
/// (`vofront_core::UndistortMap`, same intrinsics `K`) applied by the image crate's
/// [`Remap`]. Build it once per camera and image size and share it (`Arc`).
#[derive(Debug, Clone, PartialEq)]
pub struct Undistorter {
    remap: Remap,
}

impl Undistorter {
    /// The map `u -> K D(K^-1 u)` for a `width x height` image of `camera`.
    pub fn new(camera: &Camera, width: usize, height: usize) -> Result<Self, DirectError> {
        let map = UndistortMap::new(camera, &camera.pinhole, width, height)?;
        let remap = Remap::new((width, height), (width, height), &map.map_x, &map.map_y)?;
        Ok(Self { remap })
    }

    /// `(width, height)` of the images this remap applies to, pixels.
    pub fn size(&self) -> (usize, usize) {
        self.remap.size()
    }

    /// The pinhole image of `img` (bilinear, NaN where the source is outside).
    pub fn undistort_image(&self, img: &Image<f32>) -> Result<Image<f32>, DirectError> {
        Ok(self.remap.bilinear(img, f32::NAN)?)
    }

    /// The pinhole depth map of `depth` (nearest neighbour, 0 where the source is outside).
    pub fn undistort_depth(&self, depth: &Image<f32>) -> Result<Image<f32>, DirectError> {
        Ok(self.remap.nearest(depth, 0.0)?)
    }
}

/// `img` in the pinhole geometry: remapped by `undistorter`, or borrowed as it is without one.
pub(crate) fn pinhole_image<'a>(
    undistorter: Option<&Undistorter>,
    img: &'a Image<f32>,
) -> Result<Cow<'a, Image<f32>>, DirectError> {
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
    image: Image<f32>,
    /// Depth `Z` in metres along the optical axis, undistorted; `0` or NaN = unknown.
    depth: Image<f32>,
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
    pub fn new(image: Image<f32>, depth: Image<f32>, camera: &Camera) -> Result<Self, DirectError> {
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
        image: Image<f32>,
        depth: Image<f32>,
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
    pub fn image(&self) -> &Image<f32> {
        &self.image
    }

    /// Depth `Z` in metres along the optical axis, undistorted; `0` or NaN = unknown.
    pub fn depth(&self) -> &Image<f32> {
        &self.depth
    }

    /// Median of the known depths, metres (a frame always has one: [`RgbdFrame::new`]).
    pub fn median_depth(&self) -> f64 {
        let mut known: Vec<f64> = self
            .depth
            .data()
            .iter()
            .filter(|z| **z > 0.0 && z.is_finite())
            .map(|&z| f64::from(z))
            .collect();
        median_in_place(&mut known).unwrap_or(f64::NAN)
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
    pub fn prepare_current(&self, img: &Image<f32>) -> Result<Image<f32>, DirectError> {
        self.image.check_same_size(img)?;
        Ok(pinhole_image(self.undistorter.as_deref(), img)?.into_owned())
    }
}
