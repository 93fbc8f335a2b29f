//! Do two halves of an alignment's pixels agree on the motion?
//!
//! An alignment that starts far from the motion (a tracker's first frame, with no motion model)
//! can settle between two motions when part of the image moves on its own (a vehicle beside
//! the camera): its covariance describes the noise about that compromise, not the distance to
//! either motion. Seen on a highway clip (KITTI 01, first frame): the whole image gave a 0.86 m
//! step at a residual scale of 11 grey levels; aligned separately, the two colours of a
//! checkerboard of 64-pixel cells gave 1.03 m (scale 6.3, the true step is 1.00 m) and
//! 0.63 m (13.5).
//!
//! [`Se3Reference::halves_disagreement`] aligns each colour of a checkerboard of
//! [`HALF_CELL_PX`]-pixel cells on its own, coarse to fine from the whole's fit, with the
//! photometric covariance alone (an error of the calibration moves both halves alike), and
//! returns the distance of their poses in combined sigmas,
//! `sqrt(d^T (C_A + C_B)^-1 d)`, `d = log(T_A T_B^-1)`: a few sigmas when the image moves as
//! one (its square is chi-square with 6 degrees of freedom for independent pixel errors; on the
//! real KITTI clips the squared distance per degree of freedom has a median of 1.3-3.2 by
//! block, `examples/se3_consistency`, and the first frames read 2.9 and 123, the second with
//! a vehicle in half of the view).

use nalgebra::Isometry3;
use vofront_core::lie::se3_log;
use vofront_image::Image;

use super::select::RefLevel;
use super::{CalibrationPrior, Se3Config, Se3Reference};

/// Side of the checkerboard cells, full-resolution pixels: a cell holds the residuals that
/// interpolation and blur correlate.
pub const HALF_CELL_PX: f32 = 64.0;

impl Se3Reference {
    /// The reference split into the two colours of the checkerboard of [`HALF_CELL_PX`]-pixel
    /// cells, `[even, odd]` (`col + row` even or odd for the cell `(col, row)` of the
    /// full-resolution pixel), at every level: two references over disjoint pixels that each span the
    /// image.
    pub fn halves(&self) -> [Self; 2] {
        [self.half(true), self.half(false)]
    }

    /// One colour of [`Se3Reference::halves`] (a level-`l` pixel `u` is the full-resolution
    /// `2^l u`).
    fn half(&self, even: bool) -> Self {
        let levels: Vec<RefLevel> = self
            .levels
            .iter()
            .enumerate()
            .map(|(l, level)| {
                let scale = (1u32 << l) as f32;
                // Pixel centres are integers: a cell holds the pixels whose centre lies in
                // `[c k - 1/2, c (k + 1) - 1/2)`, which the pixel's recomputed position keeps
                // however it rounds.
                let cell_of = |x: f32| ((x * scale + 0.5) / HALF_CELL_PX).floor() as i64;
                level.filtered(|u, v| ((cell_of(u) + cell_of(v)).rem_euclid(2) == 0) == even)
            })
            .collect();
        Self {
            candidates: levels[0].x.len(),
            levels,
            size: self.size,
            variance: self.variance,
            undistorter: self.undistorter.clone(),
        }
    }

    /// How far apart the two halves of the reference's pixels put `current` when each is
    /// aligned on its own from `fit` (`T_cur_ref`, this reference's alignment of `current`),
    /// in their combined sigmas (module documentation). `None` when a half cannot be aligned
    /// or has no covariance: too few pixels, a failed alignment.
    pub fn halves_disagreement(
        &self,
        current: &Image<f32>,
        fit: &Isometry3<f64>,
        cfg: &Se3Config,
    ) -> Option<f64> {
        let cfg = Se3Config {
            calibration: CalibrationPrior::exact(),
            ..*cfg
        };
        let [a, b] = self.halves();
        let aligned = |half: Self| {
            let result = half.align(current, fit, &cfg).ok()?;
            Some((result.pose, result.covariance?))
        };
        let (pose_a, cov_a) = aligned(a)?;
        let (pose_b, cov_b) = aligned(b)?;
        let d = se3_log(&(pose_a * pose_b.inverse()));
        let t = d.dot(&((cov_a + cov_b).cholesky()?.solve(&d)));
        t.is_finite().then(|| t.max(0.0).sqrt())
    }
}
