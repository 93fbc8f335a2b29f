//! Where [`super::run::run_with`] streams each frame's record: the [`FrameSink`] trait and the
//! file sinks, [`TumSink`] or [`KittiSink`] (the trajectory) and [`MetricsCsvSink`] (one
//! [`MetricsRow`] of [`METRICS_COLUMNS`] per frame), all flushed per frame.

use std::io::{self, Write};

use serde::Serialize;
use vofront_robust::Verdict;

use super::reasons_text;
use super::run::FrameRecord;
use crate::trajectory::Trajectory;

/// Receives each frame's record as soon as the frame has been tracked (or found unreadable),
/// in frame order, before the next frame is read. Implemented for closures
/// `FnMut(&FrameRecord) -> io::Result<()>`, for `Option<S>` (nothing when `None`) and for
/// pairs, so sinks compose: `(tum, (metrics, progress))`.
pub trait FrameSink {
    /// Takes one record; an error stops the run ([`super::run::RunError::Sink`]).
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()>;
}

impl<F: FnMut(&FrameRecord) -> io::Result<()>> FrameSink for F {
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()> {
        self(record)
    }
}

impl<S: FrameSink> FrameSink for Option<S> {
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()> {
        self.as_mut().map_or(Ok(()), |s| s.frame(record))
    }
}

impl<A: FrameSink, B: FrameSink> FrameSink for (A, B) {
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()> {
        self.0.frame(record)?;
        self.1.frame(record)
    }
}

/// Writes the tracked frames as TUM trajectory lines (`t tx ty tz qx qy qz qw`, see
/// [`Trajectory::to_tum_string`]), flushed after every line: what is on disk is always a
/// valid TUM file of every tracked frame so far.
#[derive(Debug)]
pub struct TumSink<W: Write> {
    out: W,
}

impl<W: Write> TumSink<W> {
    /// A sink writing into `out` (typically a `BufWriter<File>`).
    pub fn new(out: W) -> Self {
        Self { out }
    }
}

impl<W: Write> FrameSink for TumSink<W> {
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()> {
        if let Some(pose) = record.trajectory_pose() {
            let line = Trajectory::new(vec![(record.timestamp, pose)]).to_tum_string();
            self.out.write_all(line.as_bytes())?;
            self.out.flush()?;
        }
        Ok(())
    }
}

/// Writes the tracked frames as KITTI pose lines (12 numbers, the row-major 3x4 `[R | t]` of
/// `T_wc`, see [`Trajectory::to_kitti_string`]) and their timestamps, one `%.6f` second stamp
/// per line as KITTI's `times.txt`, into a second writer; both flushed after every frame.
/// KITTI files have no timestamps and only tracked frames are written, so after lost frames
/// the pose file is shorter than the sequence: the times file says which frames it holds.
#[derive(Debug)]
pub struct KittiSink<W: Write> {
    poses: W,
    times: W,
}

impl<W: Write> KittiSink<W> {
    /// A sink writing the poses into `poses` and their timestamps into `times`.
    pub fn new(poses: W, times: W) -> Self {
        Self { poses, times }
    }
}

impl<W: Write> FrameSink for KittiSink<W> {
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()> {
        if let Some(pose) = record.trajectory_pose() {
            let one = Trajectory::new(vec![(record.timestamp, pose)]);
            self.poses.write_all(one.to_kitti_string().as_bytes())?;
            self.times.write_all(one.to_times_string().as_bytes())?;
            self.poses.flush()?;
            self.times.flush()?;
        }
        Ok(())
    }
}

/// The columns of the per-frame metrics CSV, in order ([`MetricsRow`] gives the values).
/// `status` is `ok`, `unreliable`, `lost`, `reinitialised` or `unreadable`; `message` says why
/// a frame was lost, reinitialised, unreliable or unreadable; `verdict` is the verdict of the
/// estimate behind the pose (`ok`, `unreliable`, `failed`; empty without one) and `reasons`
/// its reasons joined by `;`. `covariance_trace` is empty when unknown.
pub const METRICS_COLUMNS: [&str; 13] = [
    "index",
    "timestamp",
    "status",
    "keyframe",
    "inliers",
    "inlier_ratio",
    "rmse",
    "iterations",
    "covariance_trace",
    "ms",
    "message",
    "verdict",
    "reasons",
];

/// One line of the metrics CSV, serialised by the `csv` crate in [`METRICS_COLUMNS`] order
/// (quoting commas and newlines in the message as CSV does).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MetricsRow {
    /// Index in the dataset.
    pub index: usize,
    /// Timestamp, seconds.
    pub timestamp: f64,
    /// [`super::TrackStatus::as_str`], or `unreadable`.
    pub status: &'static str,
    /// 1 when the frame became a keyframe.
    pub keyframe: u8,
    /// [`super::FrameQuality::inliers`].
    pub inliers: usize,
    /// [`super::FrameQuality::inlier_ratio`].
    pub inlier_ratio: f64,
    /// [`super::FrameQuality::rmse`].
    pub rmse: f64,
    /// [`super::FrameQuality::iterations`].
    pub iterations: usize,
    /// [`super::FrameQuality::covariance_trace`], empty when unknown.
    pub covariance_trace: Option<f64>,
    /// Milliseconds spent on the frame.
    pub ms: f64,
    /// Why the frame is not plainly tracked (empty when it is), newlines replaced by spaces so
    /// that every frame is one line.
    pub message: String,
    /// Verdict of the pose's estimate, empty without one.
    pub verdict: Option<Verdict>,
    /// Its reasons joined by `;`.
    pub reasons: String,
}

impl MetricsRow {
    /// The row of `record`.
    pub fn of(record: &FrameRecord) -> Self {
        match &record.estimate {
            Ok(e) => {
                let q = &e.quality;
                Self {
                    index: record.index,
                    timestamp: record.timestamp,
                    status: e.status.as_str(),
                    keyframe: u8::from(q.keyframe),
                    inliers: q.inliers,
                    inlier_ratio: q.inlier_ratio,
                    rmse: q.rmse,
                    iterations: q.iterations,
                    covariance_trace: q.covariance_trace,
                    ms: q.ms,
                    message: one_line(e.message.as_deref().unwrap_or("")),
                    verdict: e.pose_quality.as_ref().map(|p| p.verdict),
                    reasons: e.pose_quality.as_ref().map_or(String::new(), reasons_text),
                }
            }
            Err(why) => Self {
                index: record.index,
                timestamp: record.timestamp,
                status: "unreadable",
                keyframe: 0,
                inliers: 0,
                inlier_ratio: 0.0,
                rmse: 0.0,
                iterations: 0,
                covariance_trace: None,
                ms: 0.0,
                message: one_line(&why.to_string()),
                verdict: None,
                reasons: String::new(),
            },
        }
    }
}

/// `text` with line breaks replaced by spaces.
fn one_line(text: &str) -> String {
    text.replace(['\n', '\r'], " ")
}

/// Writes the metrics CSV ([`METRICS_COLUMNS`]) with the `csv` crate, one flushed row per
/// frame; the header is written by [`MetricsCsvSink::new`].
pub struct MetricsCsvSink<W: Write> {
    out: csv::Writer<W>,
}

impl<W: Write> std::fmt::Debug for MetricsCsvSink<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("MetricsCsvSink")
    }
}

impl<W: Write> MetricsCsvSink<W> {
    /// Writes the header line into `out` and returns the sink.
    pub fn new(out: W) -> io::Result<Self> {
        let mut out = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(out);
        out.write_record(METRICS_COLUMNS)?;
        out.flush()?;
        Ok(Self { out })
    }
}

impl<W: Write> FrameSink for MetricsCsvSink<W> {
    fn frame(&mut self, record: &FrameRecord) -> io::Result<()> {
        self.out
            .serialize(MetricsRow::of(record))
            .map_err(io::Error::other)?;
        self.out.flush()
    }
}
