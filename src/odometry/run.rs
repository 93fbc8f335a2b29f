//! Drives a [`Tracker`] over a dataset and collects the trajectory and per-frame scores.

use std::io::{self, Write};
use std::path::Path;

use super::{FrameEstimate, TrackStatus, Tracker};
use crate::dataset::Dataset;
use crate::trajectory::Trajectory;

/// What happened to one frame of the dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    /// Index in the dataset.
    pub index: usize,
    /// Timestamp, seconds.
    pub timestamp: f64,
    /// The tracker's estimate, or why the frame could not be read.
    pub estimate: Result<FrameEstimate, String>,
}

/// Counts over a run.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RunSummary {
    /// Frames attempted.
    pub frames: usize,
    /// Frames that could not be read (skipped).
    pub unreadable: usize,
    /// Frames lost.
    pub lost: usize,
    /// Frames where tracking restarted.
    pub reinitialised: usize,
    /// Keyframes taken.
    pub keyframes: usize,
    /// Mean tracking time of the frames that were read, milliseconds.
    pub mean_ms: f64,
}

impl RunSummary {
    /// True when tracking ended lost: the last quarter of the frames (at least one) were all
    /// lost or unreadable.
    pub fn lost_for_good(records: &[FrameRecord]) -> bool {
        let tail = (records.len() / 4).max(1);
        !records.is_empty()
            && records[records.len().saturating_sub(tail)..]
                .iter()
                .all(|r| !matches!(&r.estimate, Ok(e) if e.status != TrackStatus::Lost))
    }
}

/// The result of [`run`].
#[derive(Debug, Clone, Default)]
pub struct RunOutput {
    /// Poses of the frames that were tracked (ok or reinitialised), camera-to-world.
    pub trajectory: Trajectory,
    /// Every frame attempted, in order.
    pub records: Vec<FrameRecord>,
    /// Counts.
    pub summary: RunSummary,
}

/// Tracks the first `max_frames` frames of `dataset` (all when `None`), calling
/// `progress(done, total)` after each. Unreadable frames are recorded and skipped.
pub fn run(
    dataset: &Dataset,
    tracker: &mut dyn Tracker,
    max_frames: Option<usize>,
    mut progress: impl FnMut(usize, usize),
) -> RunOutput {
    let total = max_frames.map_or(dataset.len(), |m| m.min(dataset.len()));
    let mut out = RunOutput::default();
    let mut ms_sum = 0.0;
    for index in 0..total {
        let timestamp = dataset.frames[index].timestamp;
        let estimate = dataset
            .load(index)
            .map_err(|e| e.to_string())
            .map(|frame| tracker.track(&frame));
        match &estimate {
            Ok(e) => {
                ms_sum += e.quality.ms;
                out.summary.keyframes += usize::from(e.quality.keyframe);
                match e.status {
                    TrackStatus::Lost => out.summary.lost += 1,
                    TrackStatus::Reinitialised => out.summary.reinitialised += 1,
                    TrackStatus::Ok => {}
                }
                if e.status != TrackStatus::Lost {
                    out.trajectory.push(timestamp, e.pose_wc);
                }
            }
            Err(_) => out.summary.unreadable += 1,
        }
        out.records.push(FrameRecord {
            index,
            timestamp,
            estimate,
        });
        progress(index + 1, total);
    }
    out.summary.frames = total;
    let read = total - out.summary.unreadable;
    out.summary.mean_ms = if read > 0 { ms_sum / read as f64 } else { 0.0 };
    out
}

/// Writes one CSV line per frame:
/// `index,timestamp,status,keyframe,inliers,inlier_ratio,rmse,iterations,covariance_trace,ms,message`
/// (status `unreadable` for frames that could not be read; an empty `covariance_trace` when the
/// covariance is unknown).
pub fn write_metrics_csv(path: &Path, records: &[FrameRecord]) -> io::Result<()> {
    let mut f = io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(f, "index,timestamp,status,keyframe,inliers,inlier_ratio,rmse,iterations,covariance_trace,ms,message")?;
    for r in records {
        match &r.estimate {
            Ok(e) => {
                let q = &e.quality;
                let message = e.message.as_deref().unwrap_or("").replace([',', '\n'], ";");
                writeln!(
                    f,
                    "{},{:.6},{},{},{},{:.4},{:.4},{},{},{:.3},{}",
                    r.index,
                    r.timestamp,
                    e.status.as_str(),
                    u8::from(q.keyframe),
                    q.inliers,
                    q.inlier_ratio,
                    q.rmse,
                    q.iterations,
                    q.covariance_trace
                        .map_or(String::new(), |t| format!("{t:.6e}")),
                    q.ms,
                    message
                )?;
            }
            Err(why) => writeln!(
                f,
                "{},{:.6},unreadable,0,0,0,0,0,0,0,{}",
                r.index,
                r.timestamp,
                why.replace([',', '\n'], ";")
            )?,
        }
    }
    f.flush()
}
