//! Feature and direct estimates of one frame pair ([`estimate`]) and their public report
//! ([`TwoViewReport`], the JSON of `vofront two-view`).

use std::time::Instant;

use image::GrayImage;
use nalgebra::Isometry3;
use serde::Serialize;
use vofront_direct::quality::intensity_variance;
use vofront_direct::{
    align_se3, align_translation, DirectError, RgbdFrame, Se3Config, Se3Result, TranslationConfig,
    TranslationResult,
};
use vofront_geometry::{Camera, Model, RelativePose};
use vofront_robust::{Quality, QualityConfig};

use super::{rotation_rows, Entry, Rows3};
use crate::input::DepthMap;
use crate::pipeline::{
    depth_plane, gray_plane, ms_since, FeaturePose, FeatureTimings, TwoViewEstimator,
};

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
    /// Quality of `translation` when it succeeded.
    pub translation_quality: Option<Quality>,
    /// Quality of `se3` when it succeeded.
    pub se3_quality: Option<Quality>,
}

/// How a run of [`estimate`] ended, the `two-view` exit status.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// At least one estimate is `ok` (exit 0).
    Ok,
    /// Estimates exist but none is `ok` (exit 4).
    NoneOk,
    /// No estimator produced an estimate (exit 1).
    NoEstimate,
}

impl Outcome {
    /// True when at least one estimator produced an estimate.
    pub fn any_estimate(&self) -> bool {
        matches!(self.feature, Some(Ok(_)))
            || matches!(self.translation, Some(Ok(_)))
            || matches!(self.se3, Some(Ok(_)))
    }

    /// The verdict of each estimate that exists, in the order of preference of
    /// [`Outcome::recommend`]: `direct_se3` (metric 6-DoF), `feature` (6-DoF, unit
    /// translation), `direct_translation` (an image shift only).
    pub fn verdicts(&self) -> Vec<(&'static str, &Quality)> {
        let mut out = Vec::new();
        if let (Some(Ok(_)), Some(q)) = (&self.se3, &self.se3_quality) {
            out.push(("direct_se3", q));
        }
        if let Some(Ok(f)) = &self.feature {
            out.push(("feature", &f.estimate.quality));
        }
        if let (Some(Ok(_)), Some(q)) = (&self.translation, &self.translation_quality) {
            out.push(("direct_translation", q));
        }
        out
    }

    /// Exit status: see [`Status`].
    pub fn status(&self) -> Status {
        let verdicts = self.verdicts();
        if verdicts.iter().any(|(_, q)| q.is_ok()) {
            Status::Ok
        } else if verdicts.is_empty() {
            Status::NoEstimate
        } else {
            Status::NoneOk
        }
    }

    /// The estimate to trust: the first `ok` one in the order of [`Outcome::verdicts`] (the
    /// most complete motion), else none, with the reason either way.
    pub fn recommend(&self) -> Recommendation {
        let verdicts = self.verdicts();
        let describe = |(name, q): &(&str, &Quality)| {
            let reasons: Vec<&str> = q.reasons.iter().map(|r| r.name()).collect();
            if reasons.is_empty() {
                format!("{name} {}", q.verdict)
            } else {
                format!("{name} {} ({})", q.verdict, reasons.join(", "))
            }
        };
        match verdicts.iter().find(|(_, q)| q.is_ok()) {
            Some(best @ (name, q)) => {
                let what = match *name {
                    "direct_se3" => "the metric 6-DoF pose",
                    "feature" => "the 6-DoF pose with unit translation",
                    _ => "an image shift only",
                };
                let sigma = q
                    .uncertainty
                    .rotation_sigma_deg
                    .map_or(String::new(), |s| format!(", rotation sigma {s:.3} deg"));
                Recommendation {
                    estimate: Some(name),
                    why: format!("{}: {what}{sigma}", describe(best)),
                }
            }
            None if verdicts.is_empty() => Recommendation {
                estimate: None,
                why: "no estimator produced an estimate".into(),
            },
            None => Recommendation {
                estimate: None,
                why: format!(
                    "no estimate is ok: {}",
                    verdicts.iter().map(describe).collect::<Vec<_>>().join("; ")
                ),
            },
        }
    }

    /// The public report of every estimator that ran, with a recommendation when more than
    /// one did.
    pub fn report(&self) -> TwoViewReport {
        let ran = [
            self.feature.is_some(),
            self.translation.is_some(),
            self.se3.is_some(),
        ];
        let quality_of = |q: &Option<Quality>| {
            q.clone()
                .expect("a successful direct estimate has its quality")
        };
        TwoViewReport {
            feature: self
                .feature
                .as_ref()
                .map(|r| Entry::of(r, FeatureReport::new)),
            direct_translation: self.translation.as_ref().map(|r| {
                Entry::of(r, |(d, ms)| {
                    TranslationReport::new(d, *ms, quality_of(&self.translation_quality))
                })
            }),
            direct_se3: self.se3.as_ref().map(|r| {
                Entry::of(r, |(s, ms)| {
                    Se3Report::new(s, *ms, quality_of(&self.se3_quality))
                })
            }),
            recommended: (ran.iter().filter(|&&r| r).count() > 1).then(|| self.recommend()),
        }
    }
}

/// Which estimate of a pair to trust, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Recommendation {
    /// Key of the estimate (`direct_se3`, `feature`, `direct_translation`), `null` when none
    /// is `ok`.
    pub estimate: Option<&'static str>,
    /// One line: its verdict and what it gives, or every verdict when none is `ok`.
    pub why: String,
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
        TwoViewEstimator::with_features(inputs.features)
            .relative_pose(&inputs.img1, &inputs.img2, &inputs.camera)
            .map_err(|e| e.to_string())
    });
    let quality_cfg = QualityConfig::default();
    let pixels = (inputs.img1.width() * inputs.img1.height()) as usize;
    let variances = || {
        intensity_variance(&gray_plane(&inputs.img1))
            + intensity_variance(&gray_plane(&inputs.img2))
    };
    let translation = run_direct.then(|| {
        check_same_size(&inputs.img1, inputs.img2.dimensions(), "frame 2")?;
        let (p1, p2) = (gray_plane(&inputs.img1), gray_plane(&inputs.img2));
        timed(|| align_translation(&p1, &p2, &TranslationConfig::default()))
    });
    let translation_quality = match &translation {
        Some(Ok((d, _))) => Some(d.quality(
            &gray_plane(&inputs.img1),
            &gray_plane(&inputs.img2),
            &quality_cfg,
        )),
        _ => None,
    };
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
    let se3_quality = match &se3 {
        Some(Ok((s, _))) => Some(s.quality(pixels, variances(), &quality_cfg)),
        _ => None,
    };
    Outcome {
        feature,
        translation,
        se3,
        se3_reference,
        translation_quality,
        se3_quality,
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
    /// The estimate to trust, when more than one estimator ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recommended: Option<Recommendation>,
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
    pub fn new(d: &TranslationResult, ms: f64, quality: Quality) -> Self {
        Self {
            d: [d.d.x, d.d.y],
            iterations: d.iterations.iter().sum(),
            rmse: d.rmse,
            ms,
            quality,
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
    pub fn new(s: &Se3Result, ms: f64, quality: Quality) -> Self {
        let t = s.pose.translation.vector;
        Self {
            r: rotation_rows(&s.pose),
            t: [t.x, t.y, t.z],
            a: s.a,
            b: s.b,
            inlier_ratio: s.inlier_ratio,
            rmse: s.rmse,
            ms,
            quality,
        }
    }
}

/// The JSON of `vofront two-view`, from [`Outcome::report`].
pub fn to_json(outcome: &Outcome) -> serde_json::Value {
    serde_json::to_value(outcome.report()).expect("a report of numbers and strings serialises")
}
