//! Precomputed undistortion (and rectification) lookup for images.
//!
//! For every pixel `(x, y)` of the ideal pinhole image (intrinsics `K_new`, no distortion),
//! the map stores the source position in the distorted image:
//! `(map_x, map_y) = K D(K_new^-1 (x, y, 1))`, with `K` and `D` the camera's intrinsics and
//! distortion. With a rotation `R` (a rectifying rotation, mapping raw-camera points into the
//! new camera frame, see [`crate::rectify`]) the ray is first rotated back into the raw camera:
//! `(map_x, map_y) = K D(pi(R^T K_new^-1 (x, y, 1)))`, `pi(X, Y, Z) = (X/Z, Y/Z)` (OpenCV's
//! `initUndistortRectifyMap`). Resampling the image at those positions (done by the image
//! crates, the geometry crate never touches pixels) gives the undistorted image.

use nalgebra::{Rotation3, Vector2, Vector3};

use crate::camera::{Camera, CameraError, Pinhole};

/// Source pixel in the distorted image for each pixel of the ideal pinhole image, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct UndistortMap {
    /// Width of the ideal image, pixels.
    pub width: usize,
    /// Height of the ideal image, pixels.
    pub height: usize,
    /// Source column for each ideal pixel (`width * height`, row-major).
    pub map_x: Vec<f32>,
    /// Source row for each ideal pixel.
    pub map_y: Vec<f32>,
}

impl UndistortMap {
    /// Builds the map for `camera` onto an ideal image of `width x height` with intrinsics
    /// `target` (use `camera.pinhole` to keep the same intrinsics).
    ///
    /// ```
    /// use vofront_core::camera::{Camera, Distortion, Pinhole};
    /// use vofront_core::undistort_map::UndistortMap;
    /// let cam = Camera::new(Pinhole::new(517.3, 516.5, 318.6, 255.3).unwrap(), Distortion::from_array([0.26, -0.95, 0.0, 0.0, 1.16]));
    /// let map = UndistortMap::new(&cam, &cam.pinhole, 640, 480).unwrap();
    /// // The principal point does not move.
    /// let i = 255 * 640 + 319;
    /// assert!((map.map_x[i] - 319.0).abs() < 0.5 && (map.map_y[i] - 255.0).abs() < 0.5);
    /// ```
    pub fn new(
        camera: &Camera,
        target: &Pinhole,
        width: usize,
        height: usize,
    ) -> Result<Self, CameraError> {
        Self::rotated(camera, &Rotation3::identity(), target, width, height)
    }

    /// Builds the map for `camera` seen through the rotation `rotation` (maps raw-camera points
    /// into the new camera frame) onto an ideal image of `width x height` with intrinsics
    /// `target`: `K D(pi(R^T K_new^-1 (x, y, 1)))`. A new pixel whose ray points behind the
    /// raw camera gets `NaN` (outside every image). The identity rotation gives
    /// [`UndistortMap::new`].
    pub fn rotated(
        camera: &Camera,
        rotation: &Rotation3<f64>,
        target: &Pinhole,
        width: usize,
        height: usize,
    ) -> Result<Self, CameraError> {
        camera.validate()?;
        target.validate()?;
        let n = width * height;
        let mut map_x = vec![0.0f32; n];
        let mut map_y = vec![0.0f32; n];
        if width > 0 {
            for (y, (row_x, row_y)) in map_x
                .chunks_exact_mut(width)
                .zip(map_y.chunks_exact_mut(width))
                .enumerate()
            {
                let yn = (y as f64 - target.cy) / target.fy;
                for (x, (mx, my)) in row_x.iter_mut().zip(row_y.iter_mut()).enumerate() {
                    let xn = (x as f64 - target.cx) / target.fx;
                    let ray = rotation.inverse_transform_vector(&Vector3::new(xn, yn, 1.0));
                    if ray.z > 0.0 {
                        let src =
                            camera.normalized_to_pixel(&Vector2::new(ray.x / ray.z, ray.y / ray.z));
                        *mx = src.x as f32;
                        *my = src.y as f32;
                    } else {
                        *mx = f32::NAN;
                        *my = f32::NAN;
                    }
                }
            }
        }
        Ok(Self {
            width,
            height,
            map_x,
            map_y,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Distortion;

    #[test]
    fn map_inverts_undistortion() {
        let cam = Camera::new(
            Pinhole::new(517.3, 516.5, 318.6, 255.3).unwrap(),
            Distortion::from_array([0.2624, -0.9531, -0.0054, 0.0026, 1.1633]),
        );
        let map = UndistortMap::new(&cam, &cam.pinhole, 64, 48).unwrap();
        for (i, (&sx, &sy)) in map.map_x.iter().zip(&map.map_y).enumerate() {
            let ideal = Vector2::new((i % 64) as f64, (i / 64) as f64);
            // Undistorting the source pixel lands on the ideal pixel (f32 storage precision).
            let xn = cam
                .pixel_to_normalized(&Vector2::new(sx as f64, sy as f64))
                .unwrap();
            assert!((cam.pinhole.to_pixel(&xn) - ideal).norm() < 1e-3);
        }
    }

    #[test]
    fn zero_focal_is_rejected() {
        let cam = Camera::pinhole(Pinhole {
            fx: 0.0,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
        });
        assert!(UndistortMap::new(&cam, &cam.pinhole, 4, 4).is_err());
    }
}
