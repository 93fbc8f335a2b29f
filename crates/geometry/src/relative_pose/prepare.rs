//! Step 1 of the pipeline: validation and undistortion of the pixels into normalized
//! coordinates, and the [`TwoView`] context (data, thresholds, settings) every later step reads.

use nalgebra::{Vector2, Vector3};

use super::correspondences::Correspondences;
use super::types::RelativePoseConfig;
use crate::camera::Camera;
use crate::error::GeometryError;
use crate::essential::RecoverConfig;

/// Minimum correspondences: the five-point solver's sample; fewer final inliers is
/// [`GeometryError::NoModel`].
pub(super) const MIN_CORRESPONDENCES: usize = 5;
/// Homography inlier threshold over the Sampson one: the transfer error carries the noise of
/// both images in two dimensions (`2 sigma^2` per axis, 95% chi-square 5.99) where the Sampson
/// distance is one-dimensional with variance `sigma^2` (95% chi-square 3.84).
const H_THRESHOLD_FACTOR: f64 = 1.766; // sqrt(2 * 5.99 / 3.84)

/// The validated input of one estimate and the quantities derived from its settings.
pub(super) struct TwoView<'a> {
    /// The usable correspondences, normalized.
    pub data: Correspondences,
    /// Input index of each usable correspondence.
    pub index: Vec<usize>,
    /// Number of input correspondences (usable or not).
    pub n_in: usize,
    /// Mean focal length `f = (fx + fy) / 2`, pixels.
    pub focal: f64,
    /// Sampson inlier threshold, normalized units (`ransac.threshold / f`).
    pub threshold: f64,
    /// Assumed noise scale of the Sampson distance, pixels (`ransac.threshold / 2`).
    pub sigma_px: f64,
    /// The settings.
    pub cfg: &'a RelativePoseConfig,
}

impl<'a> TwoView<'a> {
    /// Checks the settings and the input and undistorts the pixels; the correspondences a
    /// camera cannot undistort are left out.
    pub fn new(
        x1: &[Vector2<f64>],
        x2: &[Vector2<f64>],
        camera: &Camera,
        cfg: &'a RelativePoseConfig,
    ) -> Result<Self, GeometryError> {
        camera.validate()?;
        cfg.ransac.validate()?;
        if x1.len() != x2.len() {
            return Err(GeometryError::LengthMismatch(x1.len(), x2.len()));
        }
        enough(x1.len())?;
        if x1
            .iter()
            .chain(x2)
            .any(|p| !p.iter().all(|v| v.is_finite()))
        {
            return Err(GeometryError::NonFinite);
        }
        let mut data = Correspondences::default();
        let mut index = Vec::with_capacity(x1.len());
        for (i, (a, b)) in x1.iter().zip(x2).enumerate() {
            if let (Some(p), Some(q)) =
                (camera.pixel_to_normalized(a), camera.pixel_to_normalized(b))
            {
                data.push(&p, &q);
                index.push(i);
            }
        }
        enough(data.len())?;
        let spread = |u: &[f64], v: &[f64]| {
            let (u0, v0) = (u[0], v[0]);
            u.iter()
                .zip(v)
                .map(|(a, b)| (a - u0).abs().max((b - v0).abs()))
                .fold(0.0, f64::max)
        };
        if spread(data.u1(), data.v1()) < 1e-12 || spread(data.u2(), data.v2()) < 1e-12 {
            return Err(GeometryError::Degenerate("all points are identical".into()));
        }
        let focal = 0.5 * (camera.pinhole.fx + camera.pinhole.fy);
        Ok(Self {
            data,
            index,
            n_in: x1.len(),
            focal,
            threshold: cfg.ransac.threshold / focal,
            sigma_px: 0.5 * cfg.ransac.threshold,
            cfg,
        })
    }

    /// Transfer threshold of the homography and rotation-only models, normalized units.
    pub fn transfer_threshold(&self) -> f64 {
        self.threshold * H_THRESHOLD_FACTOR
    }

    /// Settings of the chirality test.
    pub fn recover_config(&self) -> RecoverConfig {
        RecoverConfig {
            far_distance: self.cfg.far_distance,
        }
    }

    /// Rays `(x, y, 1)` of both images.
    pub fn rays(&self) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
        let data = &self.data;
        (
            (0..data.len()).map(|i| data.ray1(i)).collect(),
            (0..data.len()).map(|i| data.ray2(i)).collect(),
        )
    }

    /// A per-input mask from the indices `used` of usable correspondences.
    pub fn input_mask(&self, used: &[usize]) -> Vec<bool> {
        let mut mask = vec![false; self.n_in];
        for &k in used {
            mask[self.index[k]] = true;
        }
        mask
    }
}

/// [`GeometryError::TooFewCorrespondences`] below the five-point sample.
fn enough(got: usize) -> Result<(), GeometryError> {
    if got < MIN_CORRESPONDENCES {
        return Err(GeometryError::TooFewCorrespondences {
            got,
            need: MIN_CORRESPONDENCES,
        });
    }
    Ok(())
}
