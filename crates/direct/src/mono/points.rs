//! The points of a monocular keyframe: a selected pixel with its depth filter, refined by
//! epipolar search in each later frame of known pose until converged (then active: used for
//! tracking), and carried into the next keyframe once converged.

use nalgebra::{Isometry3, Vector2, Vector3};
use rayon::prelude::*;
use vofront_core::Pinhole;
use vofront_image::Image;

use super::epipolar::{EpipolarConfig, EpipolarPair};
use super::filter::DepthFilter;
use super::select::Candidate;
use crate::se3::InverseDepthPoint;

/// A keyframe point: its pixel (pinhole geometry of the keyframe), gradient and depth filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonoPoint {
    /// Pixel in the keyframe, pixels.
    pub pixel: Vector2<f32>,
    /// Image gradient there, grey levels per pixel (its direction sets the aperture noise).
    pub gradient: Vector2<f32>,
    /// Inverse depth belief.
    pub filter: DepthFilter,
}

impl MonoPoint {
    /// An immature point at `candidate` with the prior `N(rho, var)`.
    pub fn immature(candidate: &Candidate, rho: f64, var: f64) -> Self {
        Self {
            pixel: candidate.pixel,
            gradient: candidate.gradient,
            filter: DepthFilter::new(rho, var),
        }
    }
}

/// How points are refined and judged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthRules {
    /// The epipolar search.
    pub epipolar: EpipolarConfig,
    /// Outlier gate of the filter, standard deviations.
    pub gate: f64,
    /// The search covers `rho +- range_sigmas sigma`.
    pub range_sigmas: f64,
    /// Converged when `sigma <= relative rho + absolute`.
    pub converged_relative: f64,
    /// See `converged_relative`, 1 / map units.
    pub converged_absolute: f64,
    /// Fewest measurements fused before a point may converge (one wrong match alone cannot
    /// activate it, nor two agreeing ones from nearly the same view: with two, KITTI's
    /// highway turn, at 2.6 degrees and 1 m per frame, activated points whose wrong depths
    /// shrank the map's scale in six of eight starts).
    pub min_updates: u32,
    /// A point with more outliers than this, and more outliers than updates, is dropped.
    pub max_outliers: u32,
}

impl Default for DepthRules {
    fn default() -> Self {
        Self {
            epipolar: EpipolarConfig::default(),
            gate: 3.0,
            range_sigmas: 2.5,
            converged_relative: 0.08,
            converged_absolute: 0.005,
            min_updates: 3,
            max_outliers: 3,
        }
    }
}

impl DepthRules {
    /// True when the point's filter has converged after at least `min_updates` measurements.
    pub fn is_active(&self, p: &MonoPoint) -> bool {
        p.filter.updates >= self.min_updates
            && p.filter
                .converged(self.converged_relative, self.converged_absolute)
    }
}

/// Searches every point of `points` (pixels of `pair.reference`) in `pair.current` over its
/// `rho +- range_sigmas sigma` and fuses what is measured; then drops points that gathered
/// too many outliers. Returns the number of measurements fused.
pub fn refine_points(
    points: &mut Vec<MonoPoint>,
    pair: &EpipolarPair,
    rules: &DepthRules,
) -> usize {
    let fused = points
        .par_iter_mut()
        .map(|p| {
            let f = &p.filter;
            let reach = rules.range_sigmas * f.sigma();
            let range = ((f.rho - reach).max(0.0), f.rho + reach);
            let pixel = p.pixel.cast::<f64>();
            let gradient = p.gradient.cast::<f64>();
            match pair.search(pixel, gradient, range, &rules.epipolar) {
                Ok(m) => usize::from(p.filter.update(m.inverse_depth, m.variance, rules.gate)),
                Err(super::EpipolarError::NoMatch { .. } | super::EpipolarError::Ambiguous) => {
                    p.filter.outliers += 1;
                    0
                }
                Err(_) => 0,
            }
        })
        .sum();
    points.retain(|p| {
        let f = &p.filter;
        !(f.outliers > rules.max_outliers && f.outliers > f.updates)
    });
    fused
}

/// The active points as the SE(3) aligner's sparse reference points.
pub fn active_points(points: &[MonoPoint], rules: &DepthRules) -> Vec<InverseDepthPoint> {
    points
        .iter()
        .filter(|p| rules.is_active(p))
        .map(|p| InverseDepthPoint {
            pixel: p.pixel,
            inverse_depth: p.filter.rho as f32,
        })
        .collect()
}

/// The active points of a keyframe carried into a new keyframe `image` at `t_new_old`: each
/// point `P = K^-1 (x, 1) / rho` is moved to `T_new_old P`, projected to its new pixel
/// (kept `border` pixels inside), and its filter transferred ([`DepthFilter::transferred`]);
/// the gradient is the new image's there. Outlier counts restart.
pub fn transfer_points(
    points: &[MonoPoint],
    rules: &DepthRules,
    pinhole: &Pinhole,
    t_new_old: &Isometry3<f64>,
    image: &Image<f32>,
    border: f32,
) -> Vec<MonoPoint> {
    let rot = t_new_old.rotation.to_rotation_matrix().into_inner();
    let t = t_new_old.translation.vector;
    let (w, h) = image.size();
    let k = pinhole;
    points
        .iter()
        .filter(|p| rules.is_active(p))
        .filter_map(|p| {
            let x = p.pixel.cast::<f64>();
            let rf = rot * Vector3::new((x.x - k.cx) / k.fx, (x.y - k.cy) / k.fy, 1.0);
            let mut filter = p.filter.transferred(rf.z, t.z)?;
            let q = rf + t * p.filter.rho;
            let (u, v) = (k.fx * q.x / q.z + k.cx, k.fy * q.y / q.z + k.cy);
            let (u, v) = (u as f32, v as f32);
            let inside = u >= border
                && v >= border
                && u <= w as f32 - 1.0 - border
                && v <= h as f32 - 1.0 - border;
            if !inside {
                return None;
            }
            let gx = 0.5 * (image.sample(u + 1.0, v)? - image.sample(u - 1.0, v)?);
            let gy = 0.5 * (image.sample(u, v + 1.0)? - image.sample(u, v - 1.0)?);
            filter.outliers = 0;
            Some(MonoPoint {
                pixel: Vector2::new(u, v),
                gradient: Vector2::new(gx, gy),
                filter,
            })
        })
        .collect()
}
