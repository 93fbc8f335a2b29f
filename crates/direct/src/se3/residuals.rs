//! What an alignment looks like pixel by pixel, for viewers: the reference's selected
//! full-resolution pixels warped into the current image with their photometric residuals, and
//! their 3D points.

use nalgebra::{Isometry3, Point3, Vector3};
use serde::Serialize;
use vofront_image::Image;

use super::Se3Reference;
use crate::error::DirectError;
use crate::plane::Bilinear;
use crate::rgbd::pinhole_image;

/// One selected full-resolution reference pixel as the current image sees it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PixelResidual {
    /// Its position in the current image, pixels of the pinhole (undistorted) geometry:
    /// `pi(K T_cur_ref P)`.
    pub pixel: [f32; 2],
    /// The photometric residual there, `I_cur(pixel) - a I_ref(p) - b`, grey levels.
    pub residual: f32,
}

impl Se3Reference {
    /// The selected full-resolution pixels' points `P = z K^-1 (u, v, 1)`, reference camera
    /// frame, metres.
    pub fn points(&self) -> impl Iterator<Item = Point3<f64>> + '_ {
        let level = &self.levels[0];
        level
            .x
            .iter()
            .zip(&level.y)
            .zip(&level.z)
            .map(|((&x, &y), &z)| Point3::new(f64::from(x), f64::from(y), f64::from(z)))
    }

    /// Each selected full-resolution pixel that `pose` (`T_cur_ref`) warps into `current`
    /// (same size as the reference, still distorted if the camera is), with its residual under
    /// the brightness `I_cur = a I_ref + b` (an [`Se3Result`](super::Se3Result)'s `pose`, `a`,
    /// `b`); pixels that leave the image or fall behind the camera are left out.
    pub fn residuals(
        &self,
        current: &Image<f32>,
        pose: &Isometry3<f64>,
        a: f64,
        b: f64,
    ) -> Result<Vec<PixelResidual>, DirectError> {
        if current.size() != self.size {
            return Err(DirectError::SizeMismatch {
                expected: self.size,
                found: current.size(),
            });
        }
        let current = pinhole_image(self.undistorter.as_deref(), current)?;
        let (w, h) = current.size();
        let level = &self.levels[0];
        let [fx, fy, cx, cy] = level.k;
        let rotation = pose
            .rotation
            .to_rotation_matrix()
            .into_inner()
            .cast::<f32>();
        let t = pose.translation.vector.cast::<f32>();
        let (a, b) = (a as f32, b as f32);
        let mut out = Vec::with_capacity(level.x.len());
        let points = level.x.iter().zip(&level.y).zip(&level.z);
        for (((&x, &y), &z), &value) in points.zip(&level.value) {
            let p = rotation * Vector3::new(x, y, z) + t;
            if p.z <= 1e-3 {
                continue;
            }
            let (u, v) = (fx * p.x / p.z + cx, fy * p.y / p.z + cy);
            if let Some(tap) = Bilinear::new(u, v, w, h) {
                out.push(PixelResidual {
                    pixel: [u, v],
                    residual: tap.apply(current.data()) - a * value - b,
                });
            }
        }
        Ok(out)
    }
}
