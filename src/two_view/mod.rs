//! Feature and direct estimates of one frame pair: [`estimate`] runs the estimators an
//! [`Inputs`] asks for, each failing on its own, and [`Outcome::recommend`] says which estimate
//! to trust. The public report of an outcome (the JSON of `vofront two-view`) is
//! [`crate::report::two_view::TwoViewReport`]. With frame 1's right image ([`Inputs::stereo`])
//! the pair's estimates are metric ([`stereo`]).

pub mod basin;
pub mod stereo;

use std::fmt;
use std::str::FromStr;
use std::time::Instant;

use serde::Serialize;
use thiserror::Error;
use vofront_core::Camera;
use vofront_direct::{
    align_translation, CalibrationPrior, DirectError, RgbdFrame, Se3Config, Se3Reference,
    Se3Result, TranslationConfig, TranslationResult,
};
use vofront_image::Image;
use vofront_robust::Quality;

use crate::error::VoError;
use crate::pipeline::{FeaturePose, TwoViewEstimator};
use crate::report::two_view::TwoViewReport;
use crate::timing::ms_since;
use stereo::{
    check_against_epipolar, epipolar_disagreement_sigmas, flag_if_inconsistent, stereo_depth,
    stereo_pose, StereoFirst, StereoPose,
};

/// Which estimators [`estimate`] runs (`vofront two-view --method`, Python
/// `two_view(method=...)`), parsed from and shown as [`Method::name`].
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

impl Method {
    /// Every method, in the order the command line lists them.
    pub const ALL: [Method; 3] = [Method::Feature, Method::Direct, Method::All];

    /// The public name: `feature`, `direct` or `all`.
    pub fn name(self) -> &'static str {
        match self {
            Method::Feature => "feature",
            Method::Direct => "direct",
            Method::All => "all",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A method name that is not `feature`, `direct` or `all`.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("method must be 'feature', 'direct' or 'all', got '{0}'")]
pub struct UnknownMethod(pub String);

impl FromStr for Method {
    type Err = UnknownMethod;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| UnknownMethod(s.to_string()))
    }
}

/// What the estimators get.
pub struct Inputs {
    /// Frame 1, grey.
    pub img1: Image<u8>,
    /// Frame 2, grey.
    pub img2: Image<u8>,
    /// Metric depth of frame 1 (metres, 0 = unknown), enabling SE(3) direct alignment.
    pub depth1: Option<Image<f32>>,
    /// Camera of both frames.
    pub camera: Camera,
    /// Which estimators run.
    pub method: Method,
    /// ORB budget per image.
    pub features: usize,
    /// Frame 1's right image of a rectified stereo pair with its baseline: the feature
    /// estimators add the metric `feature_stereo` pose, and the direct SE(3) alignment runs
    /// with frame 1's stereo depth when `depth1` is `None`.
    pub stereo: Option<StereoFirst>,
}

/// A direct estimate with its wall-clock time in milliseconds.
pub type Timed<T> = (T, f64);

/// Why a direct estimator of [`estimate`] gave no estimate; the message is the `error` of its
/// JSON entry.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DirectPairError {
    /// Frame 2 or the depth map is not the size of frame 1.
    #[error("image size {}x{} differs from {what} size {}x{}", .image.0, .image.1, .other.0, .other.1)]
    SizeMismatch {
        /// `frame 2` or `depth`.
        what: &'static str,
        /// `(width, height)` of frame 1, pixels.
        image: (usize, usize),
        /// `(width, height)` of the other, pixels.
        other: (usize, usize),
    },
    /// The aligner failed.
    #[error(transparent)]
    Direct(#[from] DirectError),
    /// Frame 1's stereo depth could not be computed ([`stereo::stereo_depth`]).
    #[error("stereo depth: {0}")]
    StereoDepth(String),
}

/// Each estimator's result or error; `None` where it did not run. The direct results carry
/// their own verdicts (`quality`).
pub struct Outcome {
    /// Feature-based relative pose.
    pub feature: Option<Result<FeaturePose, VoError>>,
    /// Metric pose of frame 2 against frame 1's stereo points (with [`Inputs::stereo`]).
    pub feature_stereo: Option<Result<StereoPose, VoError>>,
    /// Direct 2D translation.
    pub translation: Option<Result<Timed<TranslationResult>, DirectPairError>>,
    /// Direct SE(3) alignment with the depth of frame 1.
    pub se3: Option<Result<Timed<Se3Result>, DirectPairError>>,
    /// The reference frame (undistorted image and depth of frame 1) `se3` was aligned against.
    pub se3_reference: Option<RgbdFrame>,
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

/// Which estimate of a pair to trust, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Recommendation {
    /// Key of the estimate (`direct_se3`, `feature`, `direct_translation`), `null` when none
    /// is `ok`.
    pub estimate: Option<&'static str>,
    /// One line: its verdict and what it gives, or every verdict when none is `ok`.
    pub why: String,
}

impl Outcome {
    /// True when at least one estimator produced an estimate.
    pub fn any_estimate(&self) -> bool {
        matches!(self.feature, Some(Ok(_)))
            || matches!(self.feature_stereo, Some(Ok(_)))
            || matches!(self.translation, Some(Ok(_)))
            || matches!(self.se3, Some(Ok(_)))
    }

    /// The verdict of each estimate that exists, in the order of preference of
    /// [`Outcome::recommend`]: `feature_stereo` (metric 6-DoF from stereo points and PnP),
    /// `direct_se3` (metric 6-DoF), `feature` (6-DoF, unit translation), `direct_translation`
    /// (an image shift only).
    pub fn verdicts(&self) -> Vec<(&'static str, &Quality)> {
        let mut out = Vec::new();
        if let Some(Ok(s)) = &self.feature_stereo {
            out.push(("feature_stereo", &s.pnp.quality));
        }
        if let Some(Ok((s, _))) = &self.se3 {
            out.push(("direct_se3", &s.quality));
        }
        if let Some(Ok(f)) = &self.feature {
            out.push(("feature", &f.estimate.quality));
        }
        if let Some(Ok((d, _))) = &self.translation {
            out.push(("direct_translation", &d.quality));
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
                    "direct_se3" | "feature_stereo" => "the metric 6-DoF pose",
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

    /// The public report of every estimator that ran ([`TwoViewReport::new`]).
    pub fn report(&self) -> TwoViewReport {
        TwoViewReport::new(self)
    }
}

fn timed<T, E>(f: impl FnOnce() -> Result<T, E>) -> Result<Timed<T>, E> {
    let start = Instant::now();
    let out = f()?;
    Ok((out, ms_since(start)))
}

fn check_same_size(
    a: &Image<u8>,
    other: (usize, usize),
    what: &'static str,
) -> Result<(), DirectPairError> {
    if a.size() == other {
        Ok(())
    } else {
        Err(DirectPairError::SizeMismatch {
            what,
            image: a.size(),
            other,
        })
    }
}

/// Runs the estimators `inputs.method` asks for; each fails on its own. The direct aligners
/// run with their default configurations (their verdicts with the default
/// [`vofront_robust::QualityConfig`]).
pub fn estimate(inputs: &Inputs) -> Outcome {
    let run_feature = inputs.method != Method::Direct;
    let run_direct = inputs.method != Method::Feature;
    let feature = run_feature.then(|| {
        TwoViewEstimator::with_features(inputs.features).relative_pose(
            &inputs.img1,
            &inputs.img2,
            &inputs.camera,
        )
    });
    let mut feature_stereo = run_feature
        .then_some(())
        .and(inputs.stereo.as_ref())
        .map(|first| {
            stereo_pose(
                &inputs.img1,
                first,
                &inputs.img2,
                &inputs.camera,
                inputs.features,
            )
        });
    if let (Some(Ok(stereo)), Some(Ok(epipolar))) = (&mut feature_stereo, &feature) {
        check_against_epipolar(stereo, &epipolar.estimate);
    }
    let translation = run_direct.then(|| {
        check_same_size(&inputs.img1, inputs.img2.size(), "frame 2")?;
        let (p1, p2) = (inputs.img1.to_f32(), inputs.img2.to_f32());
        Ok(timed(|| {
            align_translation(&p1, &p2, &TranslationConfig::default())
        })?)
    });
    let mut se3_reference = None;
    let depth1 = match (&inputs.depth1, &inputs.stereo) {
        (Some(depth), _) => Some(Ok(depth.clone())),
        (None, Some(first)) if run_direct => Some(
            stereo_depth(&inputs.img1, first, &inputs.camera)
                .map_err(|e| DirectPairError::StereoDepth(e.to_string())),
        ),
        (None, _) => None,
    };
    // Depth from frame 1's disparity follows the focal length (`Z = f b / d`).
    let cfg = Se3Config {
        calibration: CalibrationPrior {
            depth_from_disparity: inputs.depth1.is_none(),
            ..CalibrationPrior::default()
        },
        ..Se3Config::default()
    };
    let mut se3 = run_direct.then_some(()).and(depth1).map(|depth| {
        let depth = depth?;
        check_same_size(&inputs.img1, inputs.img2.size(), "frame 2")?;
        check_same_size(&inputs.img1, depth.size(), "depth")?;
        let current = inputs.img2.to_f32();
        let ((fit, reference), ms) = timed(|| {
            let reference = RgbdFrame::new(inputs.img1.to_f32(), depth, &inputs.camera)?;
            let selected = Se3Reference::new(&reference, &cfg)?;
            let median_depth = reference.median_depth();
            let fit = basin::align_from_identity(&selected, &current, median_depth, &cfg)?;
            Ok::<_, DirectError>((fit, reference))
        })?;
        se3_reference = Some(reference);
        Ok((fit, ms))
    });
    // The metric direct pose answers to the epipolar one as `feature_stereo` does: from the
    // identity start a long forward step can leave the alignment in a nearby minimum that fits
    // the images as well as the truth would (a highway's road and sky).
    if let (Some(Ok((fit, _))), Some(Ok(epipolar))) = (&mut se3, &feature) {
        let sigmas = epipolar_disagreement_sigmas(
            &fit.pose,
            &fit.quality,
            fit.covariance.as_ref(),
            &epipolar.estimate,
        );
        flag_if_inconsistent(&mut fit.quality, sigmas);
    }
    Outcome {
        feature,
        feature_stereo,
        translation,
        se3,
        se3_reference,
    }
}
