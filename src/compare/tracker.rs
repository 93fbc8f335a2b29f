//! One tracker's part of a comparison: its run through [`Session`] on the dataset, scored
//! against the camera ground truth ([`TrackerResult`]).

use std::collections::HashMap;
use std::time::Instant;

use serde::Serialize;

use super::CompareConfig;
use crate::dataset::Dataset;
use crate::eval::AteResult;
use crate::odometry::registry::{Evaluation, OdometryError, Paradigm, Session, TrackerKind};
use crate::odometry::run::{FrameRecord, FrameSink, RunControl, RunOutput, RunSummary};
use crate::odometry::TrackStatus;
use crate::report::odometry::{AteReport, RpeReport};
use crate::report::Entry;
use crate::timing::ms_since;
use crate::trajectory::Trajectory;

/// One tracker's result: its run, or the typed error that kept it from running (a dataset
/// without the depth or the stereo rig it needs, an invalid configuration, a sink that
/// refused a record).
#[derive(Debug, Serialize)]
pub struct TrackerResult {
    /// The tracker ([`TrackerKind::name`]).
    #[serde(serialize_with = "kind_name")]
    pub method: TrackerKind,
    /// Feature or direct ([`TrackerKind::paradigm`]).
    pub paradigm: Paradigm,
    /// Unit of each frame's `residual`: `px` (reprojection) or `grey levels` (photometric).
    pub residual_unit: &'static str,
    /// The ATE alignment, `se3` (metric trackers) or `sim3` (arbitrary scale).
    pub alignment: String,
    /// The run; `None` when the tracker could not run (see `error`).
    #[serde(flatten)]
    pub run: Option<TrackerRun>,
    /// Why the tracker did not run (or stopped); `None` when it ran to the end.
    #[serde(serialize_with = "error_message")]
    pub error: Option<OdometryError>,
    /// The trajectory `T_wc` of the posed frames (written as a TUM file, not in the JSON).
    #[serde(skip)]
    pub trajectory: Trajectory,
    /// The posed frames after the ATE alignment onto the ground truth (for the figures).
    #[serde(skip)]
    pub aligned: Option<Trajectory>,
}

/// What a tracker did on the frames of a comparison and how far from the truth it was.
#[derive(Debug, Clone, Serialize)]
pub struct TrackerRun {
    /// Frames attempted.
    pub frames: usize,
    /// Frames tracked with an `ok` status.
    pub tracked: usize,
    /// Frames with a pose in the trajectory (`ok`, `unreliable` or `reinitialised`).
    pub posed: usize,
    /// Frames lost (no pose).
    pub lost: usize,
    /// Frames posed with an `unreliable` verdict.
    pub unreliable: usize,
    /// Frames that could not be read.
    pub unreadable: usize,
    /// Keyframes taken.
    pub keyframes: usize,
    /// Segment breaks: frames where tracking restarted at a guess after a failure
    /// (`reinitialised`); the trajectory may jump there, and a monocular one's scale too.
    pub segment_breaks: usize,
    /// Each run of consecutive frames without a pose (lost or unreadable): `[first, last]`
    /// frame indices.
    pub lost_spans: Vec<[usize; 2]>,
    /// Mean tracking time of the frames read, milliseconds (`FrameQuality::ms`).
    pub ms_mean: Option<f64>,
    /// Median tracking time of the frames read, milliseconds.
    pub ms_median: Option<f64>,
    /// Wall time of the whole run (decoding the frames included), milliseconds.
    pub wall_ms: f64,
    /// The run was stopped before the last frame.
    pub interrupted: bool,
    /// The last quarter of the frames were all without a pose.
    pub lost_for_good: bool,
    /// Length of the ground-truth path over the evaluated span, metres.
    pub path_length_m: Option<f64>,
    /// ATE against the camera ground truth; `None` without ground truth.
    pub ate: Option<Entry<AteReport>>,
    /// ATE RMSE over the path length, percent.
    pub ate_percent: Option<f64>,
    /// RPE between consecutive poses; `None` without ground truth.
    pub rpe: Option<Entry<RpeReport>>,
    /// One point per frame attempted, in order.
    pub series: Vec<FramePoint>,
}

/// One frame of a tracker's run.
#[derive(Debug, Clone, Serialize)]
pub struct FramePoint {
    /// Index in the dataset.
    pub index: usize,
    /// Timestamp, seconds.
    pub timestamp: f64,
    /// `ok`, `unreliable`, `reinitialised`, `lost` or `unreadable`.
    pub status: &'static str,
    /// Distance from the ground truth after the ATE alignment, metres; `None` for a frame
    /// without a pose or without ground truth.
    pub error_m: Option<f64>,
    /// Inliers: correspondences (feature) or pixels (direct).
    pub inliers: usize,
    /// Inliers over the candidates.
    pub inlier_ratio: f64,
    /// Residual RMSE in `residual_unit`: reprojection (px) or photometric (grey levels).
    pub residual: f64,
    /// Tracking time, milliseconds.
    pub ms: f64,
    /// The frame became a keyframe.
    pub keyframe: bool,
}

impl FramePoint {
    /// A frame with `status` and no scores (no estimate, or one not scored): no error, no
    /// inliers, no residual or time.
    fn without_estimate(index: usize, timestamp: f64, status: &'static str) -> Self {
        Self {
            index,
            timestamp,
            status,
            error_m: None,
            inliers: 0,
            inlier_ratio: 0.0,
            residual: 0.0,
            ms: 0.0,
            keyframe: false,
        }
    }
}

fn kind_name<S: serde::Serializer>(kind: &TrackerKind, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(kind.name())
}

fn error_message<S: serde::Serializer>(
    error: &Option<OdometryError>,
    s: S,
) -> Result<S::Ok, S::Error> {
    error.as_ref().map(ToString::to_string).serialize(s)
}

/// Runs `kind` on `dataset` as [`CompareConfig`] says (the camera, options and frame limit
/// shared by every tracker of the comparison), each record handed to `sink` as it finishes.
pub fn run_tracker(
    dataset: &Dataset,
    kind: TrackerKind,
    config: &CompareConfig,
    control: &RunControl<'_>,
    sink: &mut dyn FrameSink,
) -> TrackerResult {
    let start = Instant::now();
    let mut result = TrackerResult {
        method: kind,
        paradigm: kind.paradigm(),
        residual_unit: kind.paradigm().residual_unit(),
        alignment: format!("{:?}", kind.alignment()).to_lowercase(),
        run: None,
        error: None,
        trajectory: Trajectory::default(),
        aligned: None,
    };
    let given = config.camera.as_ref().map(|(c, how)| (*c, how.as_str()));
    let session = match Session::new(dataset.clone(), kind, given) {
        Ok(s) => s,
        Err(e) => {
            result.error = Some(e);
            return result;
        }
    };
    let control = RunControl {
        max_frames: config.max_frames,
        ..*control
    };
    let out = session
        .tracker(&config.options)
        .and_then(|mut t| session.run(t.as_mut(), &control, sink));
    let out = match out {
        Ok(out) => out,
        Err(e) => {
            result.error = Some(e);
            return result;
        }
    };
    let evaluation = (out.summary.frames > 0)
        .then(|| session.evaluate(&out.trajectory))
        .flatten();
    result.aligned = evaluation
        .as_ref()
        .and_then(|e| e.ate.as_ref().ok())
        .map(|a| a.aligned.clone());
    result.run = Some(summarise(&out, evaluation.as_ref(), ms_since(start)));
    result.trajectory = out.trajectory;
    result
}

/// The [`TrackerRun`] of `out`, scored by `evaluation`.
fn summarise(out: &RunOutput, evaluation: Option<&Evaluation>, wall_ms: f64) -> TrackerRun {
    let s = &out.summary;
    let ate = evaluation.and_then(|e| e.ate.as_ref().ok());
    let errors = ate
        .map(|a| frame_errors(a, &out.trajectory))
        .unwrap_or_default();
    let series: Vec<FramePoint> = out
        .records
        .iter()
        .map(|r| frame_point(r, &errors))
        .collect();
    let times: Vec<f64> = out
        .records
        .iter()
        .filter_map(|r| r.estimate.as_ref().ok())
        .map(|e| e.quality.ms)
        .collect();
    let path_length_m = evaluation
        .zip(ate)
        .map(|(e, a)| path_length(&e.ground_truth, a));
    let alignment = evaluation.map(|e| format!("{:?}", e.alignment).to_lowercase());
    TrackerRun {
        frames: s.frames,
        tracked: series.iter().filter(|p| p.status == "ok").count(),
        posed: out.trajectory.len(),
        lost: s.lost,
        unreliable: s.unreliable,
        unreadable: s.unreadable,
        keyframes: s.keyframes,
        segment_breaks: s.reinitialised,
        lost_spans: lost_spans(&series),
        ms_mean: (!times.is_empty()).then_some(s.mean_ms),
        ms_median: median(&times),
        wall_ms,
        interrupted: s.interrupted,
        lost_for_good: RunSummary::lost_for_good(&out.records),
        path_length_m,
        ate_percent: ate
            .zip(path_length_m)
            .filter(|(_, len)| *len > 0.0)
            .map(|(a, len)| 100.0 * a.stats.rmse / len),
        ate: evaluation.map(|e| {
            Entry::of(&e.ate, |a| {
                AteReport::new(a, alignment.clone().unwrap_or_default())
            })
        }),
        rpe: evaluation.map(|e| Entry::of(&e.rpe, RpeReport::new)),
        series,
    }
}

/// The ATE error of each posed frame, by the bits of its timestamp.
fn frame_errors(ate: &AteResult, trajectory: &Trajectory) -> HashMap<u64, f64> {
    ate.pairs
        .iter()
        .zip(&ate.errors)
        .filter_map(|(&(_, j), &(_, e))| Some((trajectory.poses.get(j)?.0.to_bits(), e)))
        .collect()
}

/// The [`FramePoint`] of `r`.
fn frame_point(r: &FrameRecord, errors: &HashMap<u64, f64>) -> FramePoint {
    let error_m = r
        .trajectory_pose()
        .and_then(|_| errors.get(&r.timestamp.to_bits()).copied());
    match &r.estimate {
        Ok(e) => FramePoint {
            index: r.index,
            timestamp: r.timestamp,
            status: e.status.as_str(),
            error_m,
            inliers: e.quality.inliers,
            inlier_ratio: e.quality.inlier_ratio,
            residual: e.quality.rmse,
            ms: e.quality.ms,
            keyframe: e.quality.keyframe,
        },
        Err(_) => FramePoint::without_estimate(r.index, r.timestamp, "unreadable"),
    }
}

/// `[first, last]` of each run of consecutive frames without a pose.
fn lost_spans(series: &[FramePoint]) -> Vec<[usize; 2]> {
    let mut spans: Vec<[usize; 2]> = Vec::new();
    let unposed =
        |p: &FramePoint| p.status == TrackStatus::Lost.as_str() || p.status == "unreadable";
    for p in series.iter().filter(|p| unposed(p)) {
        match spans.last_mut() {
            Some(span) if span[1] + 1 == p.index => span[1] = p.index,
            _ => spans.push([p.index, p.index]),
        }
    }
    spans
}

/// Median of `values` (mean of the two middle ones for an even count); `None` when empty.
fn median(values: &[f64]) -> Option<f64> {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let mid = v.len() / 2;
    match v.len() {
        0 => None,
        n if n % 2 == 0 => Some(0.5 * (v[mid - 1] + v[mid])),
        _ => Some(v[mid]),
    }
}

/// Length of the ground-truth path between the first and the last pose the ATE associated,
/// metres.
fn path_length(gt: &Trajectory, ate: &AteResult) -> f64 {
    let first = ate.pairs.iter().map(|p| p.0).min().unwrap_or(0);
    let last = ate.pairs.iter().map(|p| p.0).max().unwrap_or(0);
    gt.poses
        .get(first..=last)
        .unwrap_or_default()
        .windows(2)
        .map(|w| (w[1].1.translation.vector - w[0].1.translation.vector).norm())
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(index: usize, status: &'static str) -> FramePoint {
        FramePoint::without_estimate(index, index as f64, status)
    }

    #[test]
    fn lost_spans_join_consecutive_frames_without_a_pose() {
        let series: Vec<FramePoint> = [
            "ok",
            "lost",
            "lost",
            "reinitialised",
            "unreadable",
            "ok",
            "lost",
        ]
        .iter()
        .enumerate()
        .map(|(i, s)| point(i, s))
        .collect();
        assert_eq!(lost_spans(&series), vec![[1, 2], [4, 4], [6, 6]]);
        assert!(lost_spans(&series[..1]).is_empty());
    }

    #[test]
    fn median_of_odd_even_and_empty_lists() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&[]), None);
    }
}
