//! Drives a [`Tracker`] over a dataset, streaming each frame's record to a [`FrameSink`] as
//! soon as its estimate is final, and stopping cleanly between frames when asked.
//!
//! [`run_with`] is the full form: a [`RunControl`] (frame limit, stop flag) and a sink that
//! sees every final record before the next frame is read, so that an interrupted or crashed
//! run leaves every completed frame on disk ([`TumSink`], [`MetricsCsvSink`], flushed per
//! frame). A frame the tracker may still revise ([`Tracker::pending`]: the frames a monocular
//! initialisation waits through) is held back until its late estimate or the initialisation's
//! failure settles it; a stop or the end of the dataset sends held frames as they are.
//! [`run`] is the simple form: everything in memory, with a progress callback.

use std::collections::VecDeque;
use std::convert::Infallible;
use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use serde::Serialize;
use thiserror::Error;

use super::observe::{FrameObserver, Observed};
pub use super::sink::{FrameSink, MetricsCsvSink, MetricsRow, TumSink, METRICS_COLUMNS};
use super::{FrameEstimate, TrackStatus, Tracker};
use crate::dataset::{Dataset, DatasetError};
use crate::trajectory::Trajectory;

/// What happened to one frame of the dataset (`Serialize`: `estimate` is `{"Ok": {...}}` or
/// `{"Err": "why"}`, serde's spelling of a `Result`, the error as its message).
#[derive(Debug, Clone, serde::Serialize)]
pub struct FrameRecord {
    /// Index in the dataset.
    pub index: usize,
    /// Timestamp, seconds.
    pub timestamp: f64,
    /// The tracker's estimate, or why the frame could not be read (shared, so that a record
    /// stays cheap to clone).
    #[serde(serialize_with = "estimate_or_message")]
    pub estimate: Result<FrameEstimate, Arc<DatasetError>>,
}

/// Serialises a frame's `Result` with the error as its message.
fn estimate_or_message<S: serde::Serializer>(
    estimate: &Result<FrameEstimate, Arc<DatasetError>>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    estimate
        .as_ref()
        .map_err(|why| why.to_string())
        .serialize(serializer)
}

impl FrameRecord {
    /// The camera-to-world pose `T_wc` that belongs in the trajectory: tracked frames only
    /// (ok, unreliable or reinitialised), `None` for lost and unreadable frames.
    pub fn trajectory_pose(&self) -> Option<nalgebra::Isometry3<f64>> {
        match &self.estimate {
            Ok(e) if e.status != TrackStatus::Lost => Some(e.pose_wc),
            _ => None,
        }
    }
}

/// Counts over a run.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct RunSummary {
    /// Frames attempted.
    pub frames: usize,
    /// Frames that could not be read (skipped).
    pub unreadable: usize,
    /// Frames lost.
    pub lost: usize,
    /// Frames where tracking restarted.
    pub reinitialised: usize,
    /// Frames tracked with an `unreliable` verdict ([`TrackStatus::Unreliable`]).
    pub unreliable: usize,
    /// Keyframes taken.
    pub keyframes: usize,
    /// Mean tracking time of the frames that were read, milliseconds (0 when none was read).
    pub mean_ms: f64,
    /// The stop flag ended the run before the last frame.
    pub interrupted: bool,
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

    /// Counts `record` in.
    fn count(&mut self, record: &FrameRecord) {
        self.frames += 1;
        match &record.estimate {
            Ok(e) => {
                self.keyframes += usize::from(e.quality.keyframe);
                match e.status {
                    TrackStatus::Lost => self.lost += 1,
                    TrackStatus::Reinitialised => self.reinitialised += 1,
                    TrackStatus::Unreliable => self.unreliable += 1,
                    TrackStatus::Ok => {}
                }
            }
            Err(_) => self.unreadable += 1,
        }
    }

    /// Sets `mean_ms` from the frames of `records` that were read.
    fn set_mean_ms(&mut self, records: &[FrameRecord]) {
        let (sum, read) = records
            .iter()
            .filter_map(|r| r.estimate.as_ref().ok())
            .fold((0.0, 0usize), |(sum, n), e| (sum + e.quality.ms, n + 1));
        self.mean_ms = if read > 0 { sum / read as f64 } else { 0.0 };
    }

    /// Frames per second of tracking time (`1000 / mean_ms`), `None` when no frame was read.
    pub fn frames_per_second(&self) -> Option<f64> {
        (self.frames > self.unreadable && self.mean_ms > 0.0).then(|| 1e3 / self.mean_ms)
    }
}

/// The result of [`run`] and [`run_with`].
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct RunOutput {
    /// Poses of the frames that were tracked (ok or reinitialised), camera-to-world.
    pub trajectory: Trajectory,
    /// Every frame attempted, in order.
    pub records: Vec<FrameRecord>,
    /// Counts.
    pub summary: RunSummary,
}

/// How [`run_with`] is bounded.
#[derive(Debug, Clone, Copy, Default)]
pub struct RunControl<'a> {
    /// Track only the first `n` frames (all when `None`).
    pub max_frames: Option<usize>,
    /// Checked before each frame: once `true`, the run ends after the frame in progress, with
    /// [`RunSummary::interrupted`] set (e.g. set from a SIGINT/SIGTERM handler).
    pub stop: Option<&'a AtomicBool>,
}

/// Why [`run_with`] ended early.
#[derive(Debug, Error)]
pub enum RunError {
    /// The sink could not take the record of frame `index` (e.g. the disk is full); every
    /// earlier record was taken.
    #[error("frame {index}: cannot write the result: {source}")]
    Sink {
        /// The frame whose record was refused.
        index: usize,
        /// The sink's error.
        source: io::Error,
    },
    /// The observer of [`run_observed`] could not take frame `index` (e.g. the viewer's file
    /// could not be written); every earlier frame was taken.
    #[error("frame {index}: cannot log the frame: {source}")]
    Observer {
        /// The frame the observer refused.
        index: usize,
        /// The observer's error.
        source: io::Error,
    },
}

/// Tracks the frames of `dataset` allowed by `control`, handing each record to `sink`, in
/// frame order, before the next frame is read (pending frames once settled, see the module
/// documentation). Unreadable frames are recorded (and sent) and skipped.
///
/// ```
/// use std::sync::atomic::{AtomicBool, Ordering};
/// use vofront::dataset::Dataset;
/// use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
/// use vofront::fixtures::tum::write_tum_sequence;
/// use vofront::geometry::Pinhole;
/// use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
/// use vofront::odometry::run::{run_with, FrameRecord, RunControl, TumSink};
///
/// // A six-frame TUM RGB-D folder of a rendered room (160x120).
/// let dir = std::env::temp_dir().join(format!("vofront-doc-run-with-{}", std::process::id()));
/// let mut camera = default_camera();
/// camera.pinhole = Pinhole::new(131.25, 131.25, 79.5, 59.5).unwrap();
/// write_tum_sequence(&dir, &Scene::box_room(5), &camera, (160, 120), &room_trajectory(6)).unwrap();
/// let dataset = Dataset::open(&dir).unwrap();
///
/// // Every tracked frame becomes a TUM line as it finishes; the closure raises the stop flag
/// // after frame 3, so the run ends there (as a SIGINT handler would).
/// let stop = AtomicBool::new(false);
/// let mut tum_text = Vec::new();
/// let mut stop_after_3 = |r: &FrameRecord| {
///     stop.store(r.index == 3, Ordering::Relaxed);
///     Ok(())
/// };
/// let mut sinks = (TumSink::new(&mut tum_text), &mut stop_after_3);
/// let control = RunControl { max_frames: None, stop: Some(&stop) };
/// let mut tracker = DirectTracker::new(camera, DirectTrackerConfig::default());
/// let out = run_with(&dataset, &mut tracker, &control, &mut sinks).unwrap();
/// drop(sinks);
/// assert!(out.summary.interrupted);
/// assert_eq!((out.records.len(), out.trajectory.len()), (4, 4));
/// assert_eq!(String::from_utf8(tum_text).unwrap().lines().count(), 4);
/// std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn run_with(
    dataset: &Dataset,
    tracker: &mut dyn Tracker,
    control: &RunControl<'_>,
    sink: &mut dyn FrameSink,
) -> Result<RunOutput, RunError> {
    drive(
        dataset,
        tracker,
        control,
        |_| Ok(()),
        |r| {
            sink.frame(r).map_err(|source| RunError::Sink {
                index: r.index,
                source,
            })
        },
    )
}

/// [`run_with`] with an `observer` that sees every frame right after it was tracked: the
/// frame, the tracker's estimate and its [`FrameDetails`](super::observe::FrameDetails)
/// (the tracker is asked to keep them, [`Tracker::keep_details`], for this run only).
pub fn run_observed(
    dataset: &Dataset,
    tracker: &mut dyn Tracker,
    control: &RunControl<'_>,
    sink: &mut dyn FrameSink,
    observer: &mut dyn FrameObserver,
) -> Result<RunOutput, RunError> {
    tracker.keep_details(true);
    let out = drive(
        dataset,
        tracker,
        control,
        |o| {
            observer.frame(o).map_err(|source| RunError::Observer {
                index: o.index,
                source,
            })
        },
        |r| {
            sink.frame(r).map_err(|source| RunError::Sink {
                index: r.index,
                source,
            })
        },
    );
    tracker.keep_details(false);
    out
}

/// The loop of [`run_with`] for any error type `E` of the observer and the sink.
///
/// Records wait in `held` while the tracker may still revise them ([`Tracker::pending`]),
/// take its revisions there, and go to the summary, the trajectory and the sink in frame
/// order; a stop or the end of the dataset sends the held ones as they are. `observe` sees
/// each frame read as soon as it was tracked.
fn drive<E>(
    dataset: &Dataset,
    tracker: &mut dyn Tracker,
    control: &RunControl<'_>,
    mut observe: impl FnMut(&Observed<'_>) -> Result<(), E>,
    mut sink: impl FnMut(&FrameRecord) -> Result<(), E>,
) -> Result<RunOutput, E> {
    let total = control
        .max_frames
        .map_or(dataset.len(), |m| m.min(dataset.len()));
    let mut out = RunOutput::default();
    let mut held = VecDeque::new();
    let mut send = |record: FrameRecord, out: &mut RunOutput| {
        out.summary.count(&record);
        if let Some(pose) = record.trajectory_pose() {
            out.trajectory.push(record.timestamp, pose);
        }
        sink(&record)?;
        out.records.push(record);
        Ok(())
    };
    for index in 0..total {
        if control.stop.is_some_and(|s| s.load(Ordering::SeqCst)) {
            out.summary.interrupted = true;
            break;
        }
        let loaded = if tracker.needs_right() {
            dataset.load_stereo(index)
        } else {
            dataset.load(index)
        };
        let estimate = match loaded {
            Ok(frame) => {
                let estimate = tracker.track(&frame);
                observe(&Observed {
                    index,
                    frame: &frame,
                    estimate: &estimate,
                    details: tracker.details(),
                })?;
                Ok(estimate)
            }
            Err(why) => Err(Arc::new(why)),
        };
        let tracked = estimate.is_ok();
        held.push_back(FrameRecord {
            index,
            timestamp: dataset.frames[index].timestamp,
            estimate,
        });
        if tracked {
            revise(&mut held, tracker.revised());
        }
        while let Some(record) = take_settled(&mut held, tracker.pending()) {
            send(record, &mut out)?;
        }
    }
    while let Some(record) = held.pop_front() {
        send(record, &mut out)?;
    }
    out.summary.set_mean_ms(&out.records);
    Ok(out)
}

/// Puts each revised estimate (counted back from the newest tracked record, 1 the one before
/// it) into its held record, its time added to the first answer's; revisions of records no
/// longer held are ignored.
fn revise(held: &mut VecDeque<FrameRecord>, revised: Vec<(usize, FrameEstimate)>) {
    for (back, mut estimate) in revised {
        let record = held
            .iter_mut()
            .rev()
            .filter(|r| r.estimate.is_ok())
            .nth(back);
        if let Some(Ok(first)) = record.map(|r| &mut r.estimate) {
            estimate.quality.ms += first.quality.ms;
            *first = estimate;
        }
    }
}

/// The oldest held record when it can no longer change: an unreadable one, or a tracked one
/// older than the `pending` newest tracked records.
fn take_settled(held: &mut VecDeque<FrameRecord>, pending: usize) -> Option<FrameRecord> {
    let front_tracked = held.front()?.estimate.is_ok();
    let tracked = held.iter().filter(|r| r.estimate.is_ok()).count();
    (!front_tracked || tracked > pending)
        .then(|| held.pop_front())
        .flatten()
}

/// Tracks the first `max_frames` frames of `dataset` (all when `None`) in memory, calling
/// `progress(done, total)` after each: [`run_with`] without sink or stop flag.
///
/// ```
/// use vofront::dataset::Dataset;
/// use vofront::fixtures::scene::{default_camera, room_trajectory, Scene};
/// use vofront::fixtures::tum::write_tum_sequence;
/// use vofront::geometry::Pinhole;
/// use vofront::odometry::direct::{DirectTracker, DirectTrackerConfig};
/// use vofront::odometry::run::run;
///
/// // A five-frame TUM RGB-D folder of a rendered room (160x120) with its ground truth.
/// let dir = std::env::temp_dir().join(format!("vofront-doc-run-{}", std::process::id()));
/// let mut camera = default_camera();
/// camera.pinhole = Pinhole::new(131.25, 131.25, 79.5, 59.5).unwrap();
/// write_tum_sequence(&dir, &Scene::box_room(5), &camera, (160, 120), &room_trajectory(5)).unwrap();
/// let dataset = Dataset::open(&dir).unwrap();
///
/// let mut tracker = DirectTracker::new(camera, DirectTrackerConfig::default());
/// let out = run(&dataset, &mut tracker, None, |done, total| assert!(done <= total));
/// assert_eq!((out.summary.frames, out.summary.lost), (5, 0));
/// assert_eq!(out.trajectory.len(), 5); // camera-to-world, first frame at the origin
/// std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn run(
    dataset: &Dataset,
    tracker: &mut dyn Tracker,
    max_frames: Option<usize>,
    mut progress: impl FnMut(usize, usize),
) -> RunOutput {
    let total = max_frames.map_or(dataset.len(), |m| m.min(dataset.len()));
    let control = RunControl {
        max_frames,
        stop: None,
    };
    let done = drive(
        dataset,
        tracker,
        &control,
        |_| Ok(()),
        |r| {
            progress(r.index + 1, total);
            Ok::<(), Infallible>(())
        },
    );
    match done {
        Ok(out) => out,
        Err(never) => match never {},
    }
}
