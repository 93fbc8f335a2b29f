//! The frame alignment of the direct monocular tracker: one judged SE(3) alignment to the
//! keyframe's active points, and the retries from other starts when it fails or its residual
//! grew (module documentation of [`super`], step 2).

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use vofront_direct::quality::intensity_mean;
use vofront_direct::Se3Result;
use vofront_image::Image;
use vofront_robust::Verdict;

use super::keyframe::MonoKeyframe;
use super::DirectMonoTracker;
use crate::error::VoError;
use crate::odometry::reasons_text;

impl DirectMonoTracker {
    /// One alignment of `image` to `kf` from `prior` and unchanged brightness, judged
    /// ([`Self::align_once_from`]).
    pub(super) fn align_once(
        &self,
        kf: &MonoKeyframe,
        image: &Image<f32>,
        prior: &Isometry3<f64>,
    ) -> Result<Se3Result, VoError> {
        self.align_once_from(kf, image, prior, (1.0, 0.0))
    }

    /// One alignment of `image` to `kf` from `prior` and the brightness `(a, b)`
    /// (`I = a I_kf + b`), judged: a failed verdict or a low inlier ratio is an error.
    fn align_once_from(
        &self,
        kf: &MonoKeyframe,
        image: &Image<f32>,
        prior: &Isometry3<f64>,
        brightness: (f64, f64),
    ) -> Result<Se3Result, VoError> {
        let r = kf
            .reference
            .align_from(image, prior, brightness, &self.se3())?;
        if r.quality.verdict == Verdict::Failed {
            return Err(VoError::Rejected {
                what: "SE(3)",
                reasons: reasons_text(&r.quality),
            });
        }
        if r.inlier_ratio < self.cfg.min_inlier_ratio {
            return Err(VoError::LowInlierRatio {
                ratio: r.inlier_ratio,
                min: self.cfg.min_inlier_ratio,
            });
        }
        Ok(r)
    }

    /// The alignment from `prior`, retried from zero motion (`last`), turned starts and, after
    /// an exposure change, the gain of the mean grey levels, when it fails or its residual grew
    /// (module documentation); the lowest RMSE wins.
    pub(super) fn align(
        &self,
        kf: &MonoKeyframe,
        image: &Image<f32>,
        prior: Isometry3<f64>,
        last: Isometry3<f64>,
    ) -> Result<Se3Result, VoError> {
        let first = self.align_once(kf, image, &prior);
        let limit = kf
            .first_residual
            .map_or(f64::INFINITY, |r| self.cfg.retry_residual_growth * r);
        if matches!(&first, Ok(r) if r.rmse <= limit) {
            return first;
        }
        let turn = self.cfg.retry_turn_deg.to_radians();
        let turned = |axis: Vector3<f64>| {
            let r = UnitQuaternion::from_scaled_axis(axis * turn);
            Isometry3::from_parts(prior.translation, r * prior.rotation)
        };
        let same = (1.0, 0.0);
        let mut starts = vec![
            (last, same),
            (turned(Vector3::x()), same),
            (turned(-Vector3::x()), same),
            (turned(Vector3::y()), same),
            (turned(-Vector3::y()), same),
        ];
        // An exposure change: the prediction with the gain of the mean grey levels.
        let gain = intensity_mean(image) / kf.mean_grey;
        if gain.is_finite() && gain > 0.0 && gain.ln().abs() > self.cfg.retry_gain_change.ln_1p() {
            starts.push((prior, (gain, 0.0)));
        }
        starts
            .iter()
            .map(|(s, brightness)| self.align_once_from(kf, image, s, *brightness))
            .fold(first, |best, next| match (best, next) {
                (Ok(b), Ok(n)) => Ok(if n.rmse < b.rmse { n } else { b }),
                (Err(_), Ok(n)) => Ok(n),
                (best, Err(_)) => best,
            })
    }
}
