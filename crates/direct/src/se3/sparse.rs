//! A sparse SE(3) reference: given pixels with inverse depths (as a monocular direct system
//! keeps them, DSO-style) instead of a dense depth map.
//!
//! Point `i` at pinhole pixel `p_i = (u, v)` with inverse depth `rho_i` (1/metres) is the
//! reference-camera point `P_i = K^-1 (u, v, 1) / rho_i`. At pyramid level `l` its grey level is
//! the level-`l` image bilinearly sampled at `p_i / 2^l` (the level's intrinsics are `K / 2^l`,
//! as for dense references), so that it matches the current image's pyramid.

use std::sync::Arc;

use nalgebra::Vector2;
use vofront_core::Pinhole;
use vofront_image::Image;

use super::select::{level_intrinsics, RefLevel};
use super::{Se3Config, Se3Reference, MIN_LEVEL_SIDE};
use crate::error::DirectError;
use crate::quality::intensity_variance;
use crate::rgbd::{pinhole_image, Undistorter, MIN_RGBD_SIDE};

/// A reference pixel with its inverse depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseDepthPoint {
    /// Pixel in the pinhole (undistorted) geometry of the reference, `(u, v)`; `(0, 0)` is the
    /// centre of the top-left pixel.
    pub pixel: Vector2<f32>,
    /// `1 / Z`, 1/metres (`Z` along the optical axis).
    pub inverse_depth: f32,
}

impl Se3Reference {
    /// A reference from `image` (as captured, distorted if the camera is; `undistorter` brings
    /// it to the pinhole geometry `pinhole`, `None` without distortion) and sparse `points`.
    /// Points with a non-finite or non-positive inverse depth, a depth outside
    /// `[cfg.min_depth, cfg.max_depth]` or a pixel outside the image are skipped; the pixel
    /// selection settings of `cfg` do not apply (the points are the selection).
    ///
    /// Errors: [`DirectError::ImageTooSmall`], [`DirectError::Camera`],
    /// [`DirectError::SizeMismatch`] (image vs `undistorter`), [`DirectError::InvalidConfig`],
    /// [`DirectError::NoValidDepth`] when no point is usable.
    ///
    /// ```
    /// use nalgebra::{Isometry3, Vector2};
    /// use vofront_direct::{InverseDepthPoint, Se3Config, Se3Reference};
    /// use vofront_image::Image;
    /// use vofront_core::Pinhole;
    /// // A textured wall 2 m away; every 3rd pixel becomes a reference point.
    /// let wall = |dx: f32| {
    ///     let data = (0..80 * 60)
    ///         .map(|i| {
    ///             let x = ((i % 80) as f32 - 39.5) / 100.0 * 2.0 + dx;
    ///             let y = ((i / 80) as f32 - 29.5) / 100.0 * 2.0;
    ///             100.0 + 50.0 * (x * 20.0).sin() * (y * 17.0).cos() + 30.0 * ((x - y) * 11.0).sin()
    ///         })
    ///         .collect();
    ///     Image::new(80, 60, data).unwrap()
    /// };
    /// let points: Vec<InverseDepthPoint> = (0..80 * 60)
    ///     .step_by(3)
    ///     .map(|i| InverseDepthPoint {
    ///         pixel: Vector2::new((i % 80) as f32, (i / 80) as f32),
    ///         inverse_depth: 0.5,
    ///     })
    ///     .collect();
    /// let k = Pinhole::new(100.0, 100.0, 39.5, 29.5).unwrap();
    /// let cfg = Se3Config::default();
    /// let reference = Se3Reference::from_inverse_depths(&wall(0.0), k, None, &points, &cfg).unwrap();
    /// let fit = reference.align(&wall(0.02), &Isometry3::identity(), &cfg).unwrap();
    /// assert!((fit.pose.translation.x + 0.02).abs() < 1e-3, "{}", fit.pose.translation.x);
    /// ```
    pub fn from_inverse_depths(
        image: &Image<f32>,
        pinhole: Pinhole,
        undistorter: Option<Arc<Undistorter>>,
        points: &[InverseDepthPoint],
        cfg: &Se3Config,
    ) -> Result<Self, DirectError> {
        if cfg.levels == 0 || cfg.max_iterations == 0 {
            return Err(DirectError::InvalidConfig(
                "levels and max_iterations must be positive",
            ));
        }
        image.check_min_size(MIN_RGBD_SIDE)?;
        pinhole.validate()?;
        let base = &*pinhole_image(undistorter.as_deref(), image)?;
        let usable: Vec<(Vector2<f32>, f32)> = points
            .iter()
            .filter(|p| p.pixel.iter().all(|v| v.is_finite()))
            .filter_map(|p| {
                let z = 1.0 / p.inverse_depth;
                (p.inverse_depth > 0.0 && z >= cfg.min_depth && z <= cfg.max_depth)
                    .then_some((p.pixel, z))
            })
            .collect();
        let coarse = base.coarser_levels(cfg.levels, MIN_LEVEL_SIDE);
        let levels: Vec<RefLevel> = std::iter::once(base)
            .chain(&coarse)
            .enumerate()
            .map(|(l, img)| {
                let mut level = RefLevel::with_intrinsics(level_intrinsics(&pinhole, l));
                let s = 0.5f32.powi(l as i32);
                for &(p, z) in &usable {
                    let (u, v) = (p.x * s, p.y * s);
                    if let Some(value) = img.sample(u, v).filter(|v| v.is_finite()) {
                        level.push(u, v, z, value);
                    }
                }
                level
            })
            .collect();
        if levels[0].x.is_empty() {
            return Err(DirectError::NoValidDepth);
        }
        Ok(Self {
            candidates: levels[0].x.len(),
            levels,
            size: image.size(),
            variance: intensity_variance(base),
            undistorter,
        })
    }
}
