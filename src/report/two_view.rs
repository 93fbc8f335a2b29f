//! The public report of one frame pair's estimates ([`TwoViewReport`], the JSON of
//! `vofront two-view`), built from the [`Outcome`] of [`crate::two_view::estimate`].

use serde::Serialize;
use vofront_direct::{Se3Result, TranslationResult};
use vofront_geometry::{Model, RelativePose};
use vofront_robust::Quality;

use super::{rotation_rows, Entry, Rows3};
use crate::pipeline::{FeaturePose, FeatureTimings};
use crate::two_view::stereo::StereoPose;
use crate::two_view::{Outcome, Recommendation};

/// The JSON object of `vofront two-view`: keys `feature`, `feature_stereo`,
/// `direct_translation`, `direct_se3`, each present when its estimator ran.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TwoViewReport {
    /// Feature-based relative pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feature: Option<Entry<FeatureReport>>,
    /// Metric pose against frame 1's stereo points (`--right1`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feature_stereo: Option<Entry<StereoReport>>,
    /// Direct 2D shift.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direct_translation: Option<Entry<TranslationReport>>,
    /// Direct SE(3) pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direct_se3: Option<Entry<Se3Report>>,
    /// The estimate to trust, when more than one estimator ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recommended: Option<Recommendation>,
}

impl TwoViewReport {
    /// The report of every estimator that ran in `outcome`, with a recommendation when more
    /// than one did.
    pub fn new(outcome: &Outcome) -> Self {
        let ran = [
            outcome.feature.is_some(),
            outcome.feature_stereo.is_some(),
            outcome.translation.is_some(),
            outcome.se3.is_some(),
        ];
        Self {
            feature: outcome
                .feature
                .as_ref()
                .map(|r| Entry::of(r, FeatureReport::new)),
            feature_stereo: outcome
                .feature_stereo
                .as_ref()
                .map(|r| Entry::of(r, StereoReport::new)),
            direct_translation: outcome
                .translation
                .as_ref()
                .map(|r| Entry::of(r, |(d, ms)| TranslationReport::new(d, *ms))),
            direct_se3: outcome
                .se3
                .as_ref()
                .map(|r| Entry::of(r, |(s, ms)| Se3Report::new(s, *ms))),
            recommended: (ran.iter().filter(|&&r| r).count() > 1).then(|| outcome.recommend()),
        }
    }
}

/// Wall-clock time per stage of the feature pipeline, milliseconds: the pipeline's own
/// [`FeatureTimings`] record (keys `detect`, `match`, `estimate`, `total`).
pub type FeatureMs = FeatureTimings;

/// A relative pose `T_21` (unit translation) from correspondences: the keys `relpose` prints
/// and two-view's `feature` object starts with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PoseReport {
    /// Rotation `R` of `x2 = R x1 + t`, rows.
    #[serde(rename = "R")]
    pub r: Rows3,
    /// Unit translation direction `t` in frame 2 (zero for a pure rotation).
    pub t: [f64; 3],
    /// Correspondences the pose was estimated from.
    pub matches: usize,
    /// Correspondences consistent with the pose.
    pub inliers: usize,
    /// Selected model, serialised `essential` or `homography` (the library's [`Model`]).
    pub model: Model,
    /// Median parallax angle of the inliers, degrees.
    pub parallax_deg: f64,
    /// Verdict, reasons, support, noise scale, covariance and sigmas: the estimate's own
    /// [`RelativePose::quality`] record.
    pub quality: Quality,
}

impl PoseReport {
    /// The report of a pose estimated from `matches` correspondences.
    pub fn new(e: &RelativePose, matches: usize) -> Self {
        let t = e.translation();
        Self {
            r: rotation_rows(&e.pose),
            t: [t.x, t.y, t.z],
            matches,
            inliers: e.inlier_count(),
            model: e.model,
            parallax_deg: e.parallax_deg,
            quality: e.quality.clone(),
        }
    }
}

/// Feature-based relative pose: [`PoseReport`] plus the detector's keypoints and timings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeatureReport {
    /// Pose, support and quality.
    #[serde(flatten)]
    pub pose: PoseReport,
    /// ORB keypoints in frame 1 and frame 2.
    pub keypoints: [usize; 2],
    /// Time per stage.
    pub ms: FeatureMs,
}

/// The public name of a two-view model.
pub fn model_name(model: Model) -> &'static str {
    match model {
        Model::Essential => "essential",
        Model::Homography => "homography",
    }
}

impl FeatureReport {
    /// The report of a feature pose.
    pub fn new(f: &FeaturePose) -> Self {
        Self {
            pose: PoseReport::new(&f.estimate, f.matches.len()),
            keypoints: [f.features[0].len(), f.features[1].len()],
            ms: f.timings,
        }
    }
}

/// Metric pose `T_21` of frame 2 located by PnP against frame 1's stereo points
/// ([`crate::two_view::stereo::stereo_pose`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StereoReport {
    /// Rotation `R` of `x2 = R x1 + t`, rows.
    #[serde(rename = "R")]
    pub r: Rows3,
    /// Translation `t`, metres.
    pub t: [f64; 3],
    /// ORB keypoints in frame 1's left image and in frame 2.
    pub keypoints: [usize; 2],
    /// Frame-1 features with a metric stereo point.
    pub stereo_points: usize,
    /// Stereo points matched in frame 2 (PnP's correspondences).
    pub matches: usize,
    /// Correspondences consistent with the pose.
    pub inliers: usize,
    /// Root-mean-square reprojection error of the inliers, pixels.
    pub rmse_px: f64,
    /// Wall-clock time, milliseconds.
    pub ms: f64,
    /// Its rotation and direction disagreements with the `feature` estimate, judged together
    /// (`hypot` of the two), in combined stated sigmas (`null`: not compared); above
    /// [`MAX_DISAGREEMENT_SIGMAS`](crate::two_view::stereo::MAX_DISAGREEMENT_SIGMAS) the
    /// quality has the reason `inconsistent`.
    pub epipolar_disagreement_sigmas: Option<f64>,
    /// Verdict, reasons, support, 6x6 covariance of `(rho, phi)` and sigmas (PnP's record).
    pub quality: Quality,
}

impl StereoReport {
    /// The report of a stereo pose.
    pub fn new(s: &StereoPose) -> Self {
        let t = s.pnp.pose.translation.vector;
        Self {
            r: rotation_rows(&s.pnp.pose),
            t: [t.x, t.y, t.z],
            keypoints: s.keypoints,
            stereo_points: s.stereo_points,
            matches: s.matches,
            inliers: s.pnp.inliers.iter().filter(|&&i| i).count(),
            rmse_px: s.pnp.rmse_px,
            ms: s.ms,
            epipolar_disagreement_sigmas: s.epipolar_disagreement_sigmas,
            quality: s.pnp.quality.clone(),
        }
    }
}

/// Direct 2D shift `d` with `I2(x + d) = I1(x)`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TranslationReport {
    /// Shift, pixels.
    pub d: [f64; 2],
    /// Gauss-Newton iterations over all pyramid levels.
    pub iterations: usize,
    /// Root-mean-square photometric residual, grey levels.
    pub rmse: f64,
    /// Wall-clock time, milliseconds.
    pub ms: f64,
    /// Verdict, reasons, pixels used, covariance of `d`.
    pub quality: Quality,
}

impl TranslationReport {
    /// The report of a 2D shift that took `ms` milliseconds.
    pub fn new(d: &TranslationResult, ms: f64) -> Self {
        Self {
            d: [d.d.x, d.d.y],
            iterations: d.iterations.iter().sum(),
            rmse: d.rmse,
            ms,
            quality: d.quality.clone(),
        }
    }
}

/// Direct SE(3) pose `T_21` (metric) with the brightness model `I2 = a I1 + b`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Se3Report {
    /// Rotation `R` of `x2 = R x1 + t`, rows.
    #[serde(rename = "R")]
    pub r: Rows3,
    /// Translation `t`, metres.
    pub t: [f64; 3],
    /// Brightness gain.
    pub a: f64,
    /// Brightness offset, grey levels.
    pub b: f64,
    /// Share of valid pixels the robust loss kept.
    pub inlier_ratio: f64,
    /// Root-mean-square photometric residual, grey levels.
    pub rmse: f64,
    /// Wall-clock time, milliseconds.
    pub ms: f64,
    /// Verdict, reasons, pixels used, 6x6 covariance of `(rho, phi)` and sigmas.
    pub quality: Quality,
}

impl Se3Report {
    /// The report of an SE(3) alignment that took `ms` milliseconds.
    pub fn new(s: &Se3Result, ms: f64) -> Self {
        let t = s.pose.translation.vector;
        Self {
            r: rotation_rows(&s.pose),
            t: [t.x, t.y, t.z],
            a: s.a,
            b: s.b,
            inlier_ratio: s.inlier_ratio,
            rmse: s.rmse,
            ms,
            quality: s.quality.clone(),
        }
    }
}

/// The JSON of `vofront two-view`: [`TwoViewReport::new`] serialised.
pub fn to_json(outcome: &Outcome) -> serde_json::Value {
    serde_json::to_value(TwoViewReport::new(outcome))
        .expect("a report of numbers and strings serialises")
}
