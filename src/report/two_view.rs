//! Feature and direct estimates of one frame pair ([`estimate`]) and their public report
//! ([`TwoViewReport`], the JSON of `vofront two-view`).

use std::time::Instant;

use image::GrayImage;
use nalgebra::Isometry3;
use serde::Serialize;
use vofront_direct::{
    align_se3, align_translation, DirectError, RgbdFrame, Se3Config, Se3Result, TranslationConfig,
    TranslationResult,
};
use vofront_geometry::{Camera, Model};

use super::{rotation_rows, Entry, Rows3};
use crate::input::DepthMap;
use crate::pipeline::{depth_plane, gray_plane, ms_since, FeaturePose, FeatureTracker};

/// Which estimators [`estimate`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// ORB + essential/homography RANSAC + refinement.
    Feature,
    /// Direct 2D translation, plus SE(3) when a depth of frame 1 is given.
    Direct,
    /// Both.
    #[default]
    All,
}

/// What the estimators get.
pub struct Inputs {
    /// Frame 1, grey.
    pub img1: GrayImage,
    /// Frame 2, grey.
    pub img2: GrayImage,
    /// Metric depth of frame 1, enabling SE(3) direct alignment.
    pub depth1: Option<DepthMap>,
    /// Camera of both frames.
    pub camera: Camera,
    /// Which estimators run.
    pub method: Method,
    /// ORB budget per image.
    pub features: usize,
}

/// A direct estimate with its wall-clock time in milliseconds.
pub type Timed<T> = (T, f64);

/// Each estimator's result or error message; `None` where it did not run.
pub struct Outcome {
    /// Feature-based relative pose.
    pub feature: Option<Result<FeaturePose, String>>,
    /// Direct 2D translation.
    pub translation: Option<Result<Timed<TranslationResult>, String>>,
    /// Direct SE(3) alignment with the depth of frame 1.
    pub se3: Option<Result<Timed<Se3Result>, String>>,
    /// The reference frame (undistorted image and depth of frame 1) `se3` was aligned against.
    pub se3_reference: Option<RgbdFrame>,
}

impl Outcome {
    /// True when at least one estimator produced an estimate.
    pub fn any_estimate(&self) -> bool {
        matches!(self.feature, Some(Ok(_)))
            || matches!(self.translation, Some(Ok(_)))
            || matches!(self.se3, Some(Ok(_)))
    }

    /// The public report of every estimator that ran.
    pub fn report(&self) -> TwoViewReport {
        TwoViewReport {
            feature: self
                .feature
                .as_ref()
                .map(|r| Entry::of(r, FeatureReport::new)),
            direct_translation: self
                .translation
                .as_ref()
                .map(|r| Entry::of(r, |(d, ms)| TranslationReport::new(d, *ms))),
            direct_se3: self
                .se3
                .as_ref()
                .map(|r| Entry::of(r, |(s, ms)| Se3Report::new(s, *ms))),
        }
    }
}

fn timed<T, E: std::fmt::Display>(f: impl FnOnce() -> Result<T, E>) -> Result<Timed<T>, String> {
    let start = Instant::now();
    let out = f().map_err(|e| e.to_string())?;
    Ok((out, ms_since(start)))
}

fn check_same_size(a: &GrayImage, b: (u32, u32), what: &str) -> Result<(), String> {
    if a.dimensions() == b {
        Ok(())
    } else {
        Err(format!(
            "image size {}x{} differs from {what} size {}x{}",
            a.width(),
            a.height(),
            b.0,
            b.1
        ))
    }
}

/// Runs the estimators `inputs.method` asks for; each fails on its own.
pub fn estimate(inputs: &Inputs) -> Outcome {
    let run_feature = inputs.method != Method::Direct;
    let run_direct = inputs.method != Method::Feature;
    let feature = run_feature.then(|| {
        FeatureTracker::with_features(inputs.features)
            .relative_pose(&inputs.img1, &inputs.img2, &inputs.camera)
            .map_err(|e| e.to_string())
    });
    let translation = run_direct.then(|| {
        check_same_size(&inputs.img1, inputs.img2.dimensions(), "frame 2")?;
        let (p1, p2) = (gray_plane(&inputs.img1), gray_plane(&inputs.img2));
        timed(|| align_translation(&p1, &p2, &TranslationConfig::default()))
    });
    let mut se3_reference = None;
    let se3 = run_direct
        .then_some(())
        .and(inputs.depth1.as_ref())
        .map(|depth| {
            check_same_size(&inputs.img1, inputs.img2.dimensions(), "frame 2")?;
            check_same_size(&inputs.img1, depth.dimensions(), "depth")?;
            let current = gray_plane(&inputs.img2);
            let ((fit, reference), ms) = timed(|| {
                let reference =
                    RgbdFrame::new(gray_plane(&inputs.img1), depth_plane(depth), &inputs.camera)?;
                let prior = Isometry3::identity();
                let fit = align_se3(&reference, &current, &prior, &Se3Config::default())?;
                Ok::<_, DirectError>((fit, reference))
            })?;
            se3_reference = Some(reference);
            Ok((fit, ms))
        });
    Outcome {
        feature,
        translation,
        se3,
        se3_reference,
    }
}

/// The JSON object of `vofront two-view`: keys `feature`, `direct_translation`, `direct_se3`,
/// each present when its estimator ran.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TwoViewReport {
    /// Feature-based relative pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub feature: Option<Entry<FeatureReport>>,
    /// Direct 2D shift.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direct_translation: Option<Entry<TranslationReport>>,
    /// Direct SE(3) pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direct_se3: Option<Entry<Se3Report>>,
}

/// Wall-clock time per stage of the feature pipeline, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FeatureMs {
    /// ORB on both images.
    pub detect: f64,
    /// Descriptor matching.
    #[serde(rename = "match")]
    pub matching: f64,
    /// RANSAC, model selection, pose recovery and refinement.
    pub estimate: f64,
    /// Everything.
    pub total: f64,
}

/// Feature-based relative pose `T_21` (unit translation) and its support.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FeatureReport {
    /// Rotation `R` of `x2 = R x1 + t`, rows.
    #[serde(rename = "R")]
    pub r: Rows3,
    /// Unit translation direction `t` in frame 2.
    pub t: [f64; 3],
    /// ORB keypoints in frame 1 and frame 2.
    pub keypoints: [usize; 2],
    /// Ratio-test matches.
    pub matches: usize,
    /// Matches consistent with the pose.
    pub inliers: usize,
    /// Selected model: `essential` or `homography`.
    pub model: &'static str,
    /// Median parallax angle of the inliers, degrees.
    pub parallax_deg: f64,
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
        let e = &f.estimate;
        let t = e.translation;
        Self {
            r: rotation_rows(&e.pose),
            t: [t.x, t.y, t.z],
            keypoints: [f.features[0].len(), f.features[1].len()],
            matches: f.matches.len(),
            inliers: e.inlier_count,
            model: model_name(e.model),
            parallax_deg: e.parallax_deg,
            ms: FeatureMs {
                detect: f.timings.detect,
                matching: f.timings.matching,
                estimate: f.timings.estimate,
                total: f.timings.total,
            },
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
}

impl TranslationReport {
    /// The report of a 2D shift that took `ms` milliseconds.
    pub fn new(d: &TranslationResult, ms: f64) -> Self {
        Self {
            d: [d.d.x, d.d.y],
            iterations: d.iterations.iter().sum(),
            rmse: d.rmse,
            ms,
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
        }
    }
}

/// The JSON of `vofront two-view`, from [`Outcome::report`].
pub fn to_json(outcome: &Outcome) -> serde_json::Value {
    serde_json::to_value(outcome.report()).expect("a report of numbers and strings serialises")
}
