//! Epipolar search of one reference pixel in a later image of known relative pose, and the
//! inverse depth it measures with its geometric uncertainty (SVO, LSD/DSO-style).
//!
//! A reference pixel `x` has the bearing `f = K^-1 (x, 1)`; at inverse depth `rho` its point
//! `f / rho` maps to `T_cur_ref (f / rho)`, which projects like the homogeneous
//! `h(rho) = K (R f + rho t)`: as `rho` runs over `[rho_min, rho_max]` the pixel runs along the
//! epipolar segment from `pi(h(rho_min))` (far; `rho = 0` is the point at infinity) to
//! `pi(h(rho_max))`. The segment is sampled at steps of at most one pixel; at each sample the
//! 8-pixel pattern around it is compared with the one around `x` in the reference by the SSD of
//! both patterns made zero-mean and unit-norm (`0` equal, `2` uncorrelated, `4` inverted; an
//! affine brightness change leaves it unchanged). The best sample must cost at most
//! `max_cost` and at most `uniqueness` times the best sample more than two steps away; a
//! parabola through it and its neighbours gives the sub-pixel position `x'`.
//!
//! The inverse depth of `x'` is the least-squares solution of `f' x (R f + rho t) = 0`
//! (`f' = K^-1 (x', 1)`): `rho = -(f' x R f) . (f' x t) / |f' x t|^2`. Its variance is that of
//! a `sigma_px` pixel error along the segment: `var = (sigma_px (rho(x' + e) - rho(x' - e)) /
//! 2)^2` (`e` the unit direction of the segment), where the matching error grows when the
//! image gradient is across the segment: `sigma_px = pixel_sigma / max(|cos(g, e)|,
//! min_gradient_cos)` (the aperture problem).

use nalgebra::{Isometry3, Matrix3, Vector2, Vector3};
use thiserror::Error;
use vofront_core::Pinhole;
use vofront_image::Image;

/// Offsets of the compared pattern around a pixel (DSO's 8-pixel pattern), pixels.
pub const PATTERN: [(i32, i32); 8] = [
    (0, -2),
    (-1, -1),
    (1, -1),
    (-2, 0),
    (0, 0),
    (2, 0),
    (-1, 1),
    (0, 2),
];

/// Settings of [`EpipolarPair::search`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpipolarConfig {
    /// Matching noise along the segment, pixels (one standard deviation).
    pub pixel_sigma: f64,
    /// Longest segment searched, pixels; a longer one waits for a narrower depth range.
    pub max_length_px: f64,
    /// Largest accepted cost of the best sample (zero-mean unit-norm SSD, `[0, 4]`).
    pub max_cost: f32,
    /// The best cost must be at most this fraction of the best one more than two steps away.
    pub uniqueness: f32,
    /// Floor of `|cos(g, e)|` in the pixel noise (bounds the aperture problem's growth).
    pub min_gradient_cos: f64,
    /// Samples closer than this to the current image border are not compared, pixels.
    pub margin_px: f32,
}

impl Default for EpipolarConfig {
    fn default() -> Self {
        Self {
            pixel_sigma: 1.0,
            max_length_px: 300.0,
            max_cost: 0.6,
            uniqueness: 0.8,
            min_gradient_cos: 0.3,
            margin_px: 3.0,
        }
    }
}

/// Why a search measured nothing.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum EpipolarError {
    /// The inverse-depth range is empty or not finite.
    #[error("the inverse-depth range is empty or not finite")]
    BadRange,
    /// No part of the range is in front of the current camera.
    #[error("the depth range lies behind the current camera")]
    Behind,
    /// The reference pattern leaves the image or has no texture.
    #[error("the reference pattern is flat or leaves the image")]
    FlatPatch,
    /// The segment is longer than [`EpipolarConfig::max_length_px`].
    #[error("the epipolar segment is {length:.0} px long, more than the limit")]
    TooLong {
        /// Its length, pixels.
        length: f64,
    },
    /// Every sample of the segment is outside the current image.
    #[error("the epipolar segment leaves the current image")]
    OutOfImage,
    /// The best sample costs more than [`EpipolarConfig::max_cost`].
    #[error("no sample matches the pattern (best cost {cost:.2})")]
    NoMatch {
        /// The best cost.
        cost: f32,
    },
    /// A sample further away matches almost as well.
    #[error("the best match is not unique")]
    Ambiguous,
    /// The segment is a point (no translation across the ray) or the match gives no
    /// positive inverse depth.
    #[error("the match measures no depth (at the epipole or behind the camera)")]
    Degenerate,
}

/// An inverse depth measured by [`EpipolarPair::search`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpipolarMatch {
    /// Sub-pixel position in the current image, pixels.
    pub pixel: Vector2<f64>,
    /// Inverse depth in the reference camera, 1 / map units.
    pub inverse_depth: f64,
    /// Its variance (module documentation).
    pub variance: f64,
    /// Cost of the best sample.
    pub cost: f32,
}

/// A reference image and a current image of the same pinhole camera with their relative pose
/// `T_cur_ref` (reference points into the current camera).
#[derive(Debug, Clone, Copy)]
pub struct EpipolarPair<'a> {
    /// Reference image (pinhole geometry).
    pub reference: &'a Image<f32>,
    /// Current image (pinhole geometry, same size).
    pub current: &'a Image<f32>,
    /// Intrinsics of both.
    pub pinhole: &'a Pinhole,
    /// `T_cur_ref`.
    pub t_cur_ref: &'a Isometry3<f64>,
}

/// The zero-mean, unit-norm pattern of `img` around `(x, y)`; `None` outside the image or
/// when flat (norm under `min_norm` grey levels).
fn pattern(img: &Image<f32>, x: f32, y: f32, min_norm: f32) -> Option<[f32; 8]> {
    let mut v = img.sample_pattern(x, y, &PATTERN)?;
    if !v.iter().all(|s| s.is_finite()) {
        return None;
    }
    let mean = v.iter().sum::<f32>() / 8.0;
    v.iter_mut().for_each(|s| *s -= mean);
    let norm = v.iter().map(|s| s * s).sum::<f32>().sqrt();
    if norm < min_norm {
        return None;
    }
    v.iter_mut().for_each(|s| *s /= norm);
    Some(v)
}

/// The zero-mean unit-norm SSD between the pattern of `img` around `(x, y)` and `reference`
/// (zero-mean, unit-norm): `2 - 2 corr`, with `corr = sum p_i r_i / sqrt(sum p_i^2 - (sum
/// p_i)^2 / 8)` (the mean drops out of the product since `sum r_i = 0`); 2 (uncorrelated)
/// for a flat or non-finite sample, `None` outside the image.
fn pattern_cost(img: &Image<f32>, x: f32, y: f32, reference: &[f32; 8]) -> Option<f32> {
    let v = img.sample_pattern(x, y, &PATTERN)?;
    // Relative to the centre sample (the cost is offset-invariant), so that the sums of
    // squares do not cancel.
    let pivot = v[4];
    let (mut sum, mut squares, mut dot) = (0f32, 0f32, 0f32);
    for (v, r) in v.iter().zip(reference) {
        let v = v - pivot;
        sum += v;
        squares += v * v;
        dot += v * r;
    }
    let norm2 = squares - sum * sum / 8.0;
    if !(dot.is_finite() && norm2.is_finite() && norm2 >= 1e-6) {
        return Some(2.0);
    }
    Some((2.0 - 2.0 * dot / norm2.sqrt()).max(0.0))
}

impl EpipolarPair<'_> {
    /// Searches reference pixel `pixel` (gradient `gradient`, grey levels per pixel) along the
    /// epipolar segment of inverse depths `range` (module documentation).
    pub fn search(
        &self,
        pixel: Vector2<f64>,
        gradient: Vector2<f64>,
        range: (f64, f64),
        cfg: &EpipolarConfig,
    ) -> Result<EpipolarMatch, EpipolarError> {
        let k = self.pinhole;
        let kinv = |x: &Vector2<f64>| Vector3::new((x.x - k.cx) / k.fx, (x.y - k.cy) / k.fy, 1.0);
        let rot: Matrix3<f64> = self.t_cur_ref.rotation.to_rotation_matrix().into_inner();
        let t = self.t_cur_ref.translation.vector;
        let rf = rot * kinv(&pixel);
        let (mut lo, mut hi) = (range.0.max(0.0), range.1);
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return Err(EpipolarError::BadRange);
        }
        // Keep the depth along the current optical axis, rf_z + rho t_z, above 1e-6.
        const MIN_Z: f64 = 1e-6;
        if t.z < 0.0 {
            hi = hi.min((rf.z - MIN_Z) / -t.z);
        } else if t.z > 0.0 {
            lo = lo.max((MIN_Z - rf.z) / t.z);
        } else if rf.z <= MIN_Z {
            return Err(EpipolarError::Behind);
        }
        if hi <= lo {
            return Err(EpipolarError::Behind);
        }
        let project = |rho: f64| {
            let h = rf + t * rho;
            Vector2::new(k.fx * h.x / h.z + k.cx, k.fy * h.y / h.z + k.cy)
        };
        let (far, near) = (project(lo), project(hi));
        let segment = near - far;
        let length = segment.norm();
        if !length.is_finite() {
            return Err(EpipolarError::Degenerate);
        }
        if length > cfg.max_length_px {
            return Err(EpipolarError::TooLong { length });
        }
        let reference = pattern(self.reference, pixel.x as f32, pixel.y as f32, 2.0)
            .ok_or(EpipolarError::FlatPatch)?;
        let steps = (length.ceil() as usize).max(1);
        let step = segment / steps as f64;
        let (w, h) = self.current.size();
        let (xmax, ymax) = (
            w as f32 - 1.0 - cfg.margin_px,
            h as f32 - 1.0 - cfg.margin_px,
        );
        let costs: Vec<f32> = (0..=steps)
            .map(|i| {
                let c = far + step * i as f64;
                let (x, y) = (c.x as f32, c.y as f32);
                if !(x >= cfg.margin_px && y >= cfg.margin_px && x <= xmax && y <= ymax) {
                    return f32::INFINITY;
                }
                pattern_cost(self.current, x, y, &reference).unwrap_or(2.0)
            })
            .collect();
        let (best, &cost) = costs
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .ok_or(EpipolarError::OutOfImage)?;
        if !cost.is_finite() {
            return Err(EpipolarError::OutOfImage);
        }
        if cost > cfg.max_cost {
            return Err(EpipolarError::NoMatch { cost });
        }
        let second = costs
            .iter()
            .enumerate()
            .filter(|(i, _)| i.abs_diff(best) > 2)
            .map(|(_, c)| *c)
            .fold(f32::INFINITY, f32::min);
        if second.is_finite() && cost > cfg.uniqueness * second {
            return Err(EpipolarError::Ambiguous);
        }
        let mut offset = 0.0;
        if best > 0 && best < steps {
            let (l, r) = (costs[best - 1], costs[best + 1]);
            let den = l - 2.0 * cost + r;
            if l.is_finite() && r.is_finite() && den > 0.0 {
                offset = f64::from((0.5 * (l - r) / den).clamp(-0.5, 0.5));
            }
        }
        let at = far + step * (best as f64 + offset);
        if length < 1e-9 {
            return Err(EpipolarError::Degenerate);
        }
        let e = segment / length;
        let rho_at = |x: &Vector2<f64>| {
            let f2 = kinv(x);
            let n = f2.cross(&t);
            let n2 = n.norm_squared();
            (n2 > 1e-18).then(|| -f2.cross(&rf).dot(&n) / n2)
        };
        let rho = rho_at(&at)
            .filter(|r| r.is_finite() && *r > 0.0)
            .ok_or(EpipolarError::Degenerate)?;
        let g = gradient.norm();
        let cos = if g > 0.0 {
            (gradient.dot(&e) / g).abs()
        } else {
            0.0
        };
        let sigma_px = cfg.pixel_sigma / cos.max(cfg.min_gradient_cos);
        let (plus, minus) = (rho_at(&(at + e)), rho_at(&(at - e)));
        let half_span = match (plus, minus) {
            (Some(p), Some(m)) => 0.5 * (p - m).abs(),
            (Some(p), None) => (p - rho).abs(),
            (None, Some(m)) => (rho - m).abs(),
            (None, None) => return Err(EpipolarError::Degenerate),
        };
        let variance = (sigma_px * half_span).powi(2);
        if !(variance.is_finite() && variance > 0.0) {
            return Err(EpipolarError::Degenerate);
        }
        Ok(EpipolarMatch {
            pixel: at,
            inverse_depth: rho,
            variance,
            cost,
        })
    }
}

#[cfg(test)]
mod tests {
    use vofront_image::Image;

    use super::{pattern, pattern_cost};

    /// The correlation form of the cost equals the SSD of the two normalised patterns, on
    /// bright, dark and low-contrast texture, and a flat sample costs 2.
    #[test]
    fn the_correlation_cost_is_the_ssd_of_normalised_patterns() {
        let (w, h) = (40, 30);
        for (offset, contrast) in [(200.0f32, 30.0f32), (10.0, 5.0), (128.0, 0.5)] {
            let data = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f32, (i / w) as f32);
                    offset + contrast * ((0.7 * x).sin() + (0.45 * y + 0.3 * x).cos())
                })
                .collect();
            let img = Image::new(w, h, data).unwrap();
            let reference = pattern(&img, 12.0, 11.0, 1e-3).unwrap();
            for (x, y) in [(12.0, 11.0), (20.3, 14.6), (7.5, 20.25)] {
                let p = pattern(&img, x, y, 1e-3).unwrap();
                let ssd: f32 = p
                    .iter()
                    .zip(&reference)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum();
                let cost = pattern_cost(&img, x, y, &reference).unwrap();
                assert!(
                    (cost - ssd).abs() < 1e-3,
                    "{offset} {contrast} ({x}, {y}): {cost} vs {ssd}"
                );
            }
            assert!(pattern_cost(&img, 0.5, 0.5, &reference).is_none());
        }
        let flat = Image::filled(w, h, 90.0f32);
        let reference = [0.5, -0.5, 0.0, 0.0, 0.0, 0.0, 0.5, -0.5];
        assert_eq!(pattern_cost(&flat, 10.0, 10.0, &reference), Some(2.0));
    }
}
